//! Di Felice's drag (Int. J. Multiphase Flow 20, 1994): the single-sphere drag of the
//! superficial slip, corrected by the porosity function ε^(−χ) whose exponent χ depends on
//! the grain Reynolds number:
//!
//!   F = ½ C_D ρ (π d²/4) ε² |w| w ε^(−χ),   C_D = (0.63 + 4.8/√Re)²,
//!   χ = 3.7 − 0.65 exp(−(1.5 − log₁₀ Re)²/2),   Re = ε ρ d |w| / μ,
//!
//! with w = u − v the interstitial slip (ε w the superficial one); the pressure-gradient
//! force −V_p ∇p is the fluid force `pressure_gradient` beside it, as for `ergun_wen_yu`.

use super::{slip_force, DragLaw, DragLawEntry, GrainInFluid};
use crate::{Real, Vec3};

/// The registry's entry (`coupling.drag = "di_felice"`).
pub(super) const ENTRY: DragLawEntry = DragLawEntry {
    name: "di_felice",
    needs_gas_velocity: true,
    takes_voidage_factor: false,
    build: |s| {
        std::sync::Arc::new(DiFelice {
            viscosity: s.viscosity,
        })
    },
};

/// The Di Felice drag law with the gas's viscosity.
#[derive(Debug, Clone, Copy)]
pub struct DiFelice {
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
}

impl DragLaw for DiFelice {
    fn name(&self) -> &'static str {
        "di_felice"
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        slip_force(g, |eps, w, d, rho| self.coefficient(eps, w, d, rho))
    }

    fn slip_coefficient(&self, eps: Real, w: Real, d: Real, rho: Real) -> Option<Real> {
        Some(self.coefficient(eps, w, d, rho))
    }
}

impl DiFelice {
    /// β/(1 − ε) = F / (V_p w) = ¾ C_D ρ ε² |w| ε^(−χ) / d, kg/(m³ s).
    fn coefficient(&self, eps: Real, w: Real, d: Real, rho: Real) -> Real {
        let re = eps * rho * d * w / self.viscosity;
        if re <= 0.0 {
            // Stokes limit: C_D |w| → 4.8² μ/(ε ρ d), χ → 3.7.
            return 0.75 * 4.8 * 4.8 * self.viscosity * eps.powf(1.0 - 3.7) / (d * d);
        }
        let cd = (0.63 + 4.8 / re.sqrt()).powi(2);
        let chi = 3.7 - 0.65 * (-(1.5 - re.log10()).powi(2) / 2.0).exp();
        0.75 * cd * rho * eps * eps * w * eps.powf(-chi) / d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One case worked by hand: d = 1 mm, ρ = 1.2 kg/m³, μ = 1.8e-5 Pa·s, ε = 0.5,
    /// w = 0.5 m/s: Re = 16.667, C_D = (0.63 + 4.8/4.0825)² = 3.2608, χ = 3.7 −
    /// 0.65 exp(−(1.5 − 1.2218)²/2) = 3.0747, F = ½·3.2608·1.2·7.854e-7 m²·0.25·0.5·0.5 m²/s²
    /// ·0.5^(−3.0747) = 8.0911e-7 N.
    #[test]
    fn matches_a_case_worked_by_hand() {
        let law = DiFelice { viscosity: 1.8e-5 };
        let d = 1e-3;
        let g = crate::drag::grain_at_rest_in_stream(d, 0.5, 0.5, 1.2);
        let f = law.force(&g)[0];
        assert!((f / 8.0911e-7 - 1.0).abs() < 1e-4, "{f}");
    }
}
