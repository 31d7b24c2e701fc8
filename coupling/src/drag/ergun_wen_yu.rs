//! Ergun below ε = 0.8 and Wen–Yu above: the Gidaspow switch of seed 004 (eqs. 12–13).
//!
//! As an interphase coefficient per volume of mixture, with w = u − v the slip between the
//! interstitial gas velocity and the grains:
//!
//!   ε < 0.8:  β = 150 (1 − ε)² μ / (ε d²) + 1.75 (1 − ε) ρ |w| / d            (Ergun)
//!   ε ≥ 0.8:  β = ¾ C_D ε (1 − ε) ρ |w| / d · ε^(−2.65),                       (Wen–Yu)
//!             C_D = 24/Re (1 + 0.15 Re^0.687) for Re < 1000, else 0.44,  Re = ε ρ d |w| / μ,
//!
//! and the drag on one grain F = V_p β w / (1 − ε); the pressure gradient the grain sits in
//! (its share of the (1 − ε)∇p the gas momentum's −ε∇p leaves to the solids) is the fluid
//! force `pressure_gradient` beside it (`crate::fluid_force`). With the gas momentum written
//! with −ε∇p, a fixed bed then carries exactly the Ergun pressure drop: ε ∇p = β u with the
//! superficial velocity U = ε u gives Δp/L = 150 μ (1−ε)² U/(ε³ d²) + 1.75 ρ (1−ε) U²/(ε³ d).
//! Seed 004 prints eq. 12 per grain as ½ π R² ρ C_D |w| w with C_D = (200 (1 − ε)/Re + 7/3)/ε,
//! which is this β divided by ε: with its −ε∇p momentum equation (eq. 10) a fixed bed would
//! carry the Ergun drop divided by ε, so we keep Gidaspow's form, which the seed cites.
//!
//! Seed 004 eq. 11: a two-dimensional model (cells one grain thick) sees a larger voidage than
//! the three-dimensional bed it stands for, so the drag takes ε' = C_V ε in place of ε, in the
//! switch, the coefficient and Re alike; C_V compares the model's voidage with the
//! experiment's. C_V = 1 (the default) is the law as written above.

use super::{slip_force, DragLaw, DragLawEntry, GrainInFluid};
use crate::{Real, Vec3};

/// The registry's entry (`coupling.drag = "ergun_wen_yu"`).
pub(super) const ENTRY: DragLawEntry = DragLawEntry {
    name: "ergun_wen_yu",
    needs_gas_velocity: true,
    takes_voidage_factor: true,
    build: |s| {
        std::sync::Arc::new(ErgunWenYu {
            viscosity: s.viscosity,
            voidage_factor: s.voidage_factor,
        })
    },
};

/// Porosity where Ergun hands over to Wen–Yu.
pub const SWITCH_POROSITY: Real = 0.8;

/// Single-sphere drag coefficient (Schiller–Naumann below Re = 1000, Newton's 0.44 above).
pub fn schiller_naumann(re: Real) -> Real {
    if re < 1000.0 {
        24.0 / re * (1.0 + 0.15 * re.powf(0.687))
    } else {
        0.44
    }
}

/// β / (1 − ε), kg/(m³ s): the Gidaspow coefficient per volume of solid, finite as ε → 1
/// (a lone grain), for porosity `eps`, slip speed `w`, grain diameter `d`, gas density `rho`
/// and viscosity `mu`.
pub fn gidaspow_beta_per_solid(eps: Real, w: Real, d: Real, rho: Real, mu: Real) -> Real {
    if eps < SWITCH_POROSITY {
        150.0 * (1.0 - eps) * mu / (eps * d * d) + 1.75 * rho * w / d
    } else {
        let re = eps * rho * d * w / mu;
        if re <= 0.0 {
            // Stokes limit of C_D Re → 24: 18 μ ε^(−2.65) / d².
            return 18.0 * mu * eps.powf(-2.65) / (d * d);
        }
        0.75 * schiller_naumann(re) * eps * rho * w / d * eps.powf(-2.65)
    }
}

/// The Gidaspow interphase coefficient β, kg/(m³ s) (zero without grains, ε = 1).
pub fn gidaspow_beta(eps: Real, w: Real, d: Real, rho: Real, mu: Real) -> Real {
    (1.0 - eps) * gidaspow_beta_per_solid(eps, w, d, rho, mu)
}

/// The Ergun / Wen–Yu drag law with the gas's density and viscosity.
#[derive(Debug, Clone, Copy)]
pub struct ErgunWenYu {
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
    /// C_V of seed 004 eq. 11, in (0, 1]: the drag sees the voidage C_V ε (1: as it is).
    pub voidage_factor: Real,
}

impl ErgunWenYu {
    /// The law as written (C_V = 1).
    pub fn new(viscosity: Real) -> Self {
        Self {
            viscosity,
            voidage_factor: 1.0,
        }
    }

    /// β/(1 − ε) at the voidage C_V ε: finite for a lone grain (ε = 1).
    fn coefficient(&self, eps: Real, w: Real, d: Real, rho: Real) -> Real {
        gidaspow_beta_per_solid(self.voidage_factor * eps, w, d, rho, self.viscosity)
    }
}

impl DragLaw for ErgunWenYu {
    fn name(&self) -> &'static str {
        "ergun_wen_yu"
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        slip_force(g, |eps, w, d, rho| self.coefficient(eps, w, d, rho))
    }

    fn slip_coefficient(&self, eps: Real, w: Real, d: Real, rho: Real) -> Option<Real> {
        Some(self.coefficient(eps, w, d, rho))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lone grain (ε → 1) feels the single-sphere drag ½ C_D ρ A w² of Schiller–Naumann.
    #[test]
    fn wen_yu_tends_to_the_single_sphere_drag() {
        let (d, rho, mu) = (1e-3, 1.2, 1.8e-5);
        let law = ErgunWenYu::new(mu);
        let w = 0.5;
        let eps = 1.0;
        let g = crate::drag::grain_at_rest_in_stream(d, eps, w, rho);
        let f = law.force(&g)[0];
        let re = rho * d * w / mu;
        let single = 0.5 * schiller_naumann(re) * rho * std::f64::consts::PI * d * d / 4.0 * w * w;
        assert!((f / single - 1.0).abs() < 1e-6, "{f} vs {single}");
    }

    /// In a fixed bed, ε∇p = β u with U = ε u is the Ergun equation, term by term.
    #[test]
    fn ergun_branch_is_the_ergun_equation() {
        let (d, rho, mu, eps) = (1e-3, 1.2, 1.8e-5, 0.4);
        for big_u in [1e-3, 1.0] {
            let u = big_u / eps;
            let dpdx = gidaspow_beta(eps, u, d, rho, mu) * u / eps;
            let ergun = 150.0 * mu * (1.0 - eps).powi(2) * big_u / (eps.powi(3) * d * d)
                + 1.75 * rho * (1.0 - eps) * big_u * big_u / (eps.powi(3) * d);
            assert!((dpdx / ergun - 1.0).abs() < 1e-12);
        }
    }

    /// Eq. 11: with C_V the law is the plain law at the voidage C_V ε, in both branches
    /// (ε = 0.5 → 0.4 stays Ergun; ε = 0.95 → 0.76 moves from Wen–Yu to Ergun), and the
    /// grain's force and the gas's coefficient are one number (bitwise: the same function).
    #[test]
    fn voidage_factor_is_the_law_at_the_scaled_voidage() {
        let (d, rho, mu) = (3e-3, 1.2, 1.81e-5);
        let scaled = ErgunWenYu {
            viscosity: mu,
            voidage_factor: 0.8,
        };
        let plain = ErgunWenYu::new(mu);
        for (eps, w) in [(0.5, 0.7), (0.95, 2.0)] {
            let got = scaled.slip_coefficient(eps, w, d, rho).unwrap();
            let want = plain.slip_coefficient(0.8 * eps, w, d, rho).unwrap();
            assert_eq!(got, want);
            let g = crate::drag::grain_at_rest_in_stream(d, eps, w, rho);
            assert_eq!(scaled.force(&g)[0], g.volume * got * w);
        }
        // Denser voidage, more drag: C_V < 1 only ever raises it.
        assert!(
            scaled.slip_coefficient(0.5, 0.7, d, rho) > plain.slip_coefficient(0.5, 0.7, d, rho)
        );
    }
}
