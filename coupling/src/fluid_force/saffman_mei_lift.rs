//! Shear lift of Saffman (J. Fluid Mech. 22, 1965) with the finite-Reynolds correction of
//! Mei (Int. J. Multiphase Flow 18, 1992), as OpenFOAM's `SaffmanMeiLiftForce` and Lethe's
//! Saffman–Mei lift write it:
//!
//!   F = 1.615 d² √(ρ μ / |ω|) C_m (w × ω),   w = u − v, ω = ∇ × u,
//!   C_m = (1 − 0.3314 √β) e^(−Re_p/10) + 0.3314 √β   (Re_p ≤ 40),
//!   C_m = 0.0524 √(β Re_p)                             (Re_p > 40),
//!   β = Re_ω / (2 Re_p),  Re_p = ρ d |w| / μ,  Re_ω = ρ d² |ω| / μ.
//!
//! At Re_p → 0, C_m → 1 and F is Saffman's 6.46 μ a² |w| √(|ω|/ν) (a = d/2), pointing
//! towards the faster gas for a grain that lags it. u here is the interstitial gas velocity
//! the `simple` gas carries.

use super::{FluidForce, FluidForceEntry};
use crate::drag::GrainInFluid;
use crate::{Real, Vec3};

/// The registry's entry (`"saffman_mei_lift"` in `coupling.fluid_forces`).
pub(super) const ENTRY: FluidForceEntry = FluidForceEntry {
    name: "saffman_mei_lift",
    needs_gas_velocity: true,
    needs_vorticity: true,
    build: |s| {
        std::sync::Arc::new(SaffmanMeiLift {
            viscosity: s.viscosity,
        })
    },
};

/// The Saffman–Mei lift with the gas's viscosity.
#[derive(Debug, Clone, Copy)]
pub struct SaffmanMeiLift {
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
}

impl SaffmanMeiLift {
    /// Mei's correction C_m at the grain and shear Reynolds numbers.
    pub fn mei_factor(re_p: Real, re_w: Real) -> Real {
        let beta = 0.5 * re_w / re_p;
        if re_p <= 40.0 {
            let a = 0.3314 * beta.sqrt();
            (1.0 - a) * (-0.1 * re_p).exp() + a
        } else {
            0.0524 * (beta * re_p).sqrt()
        }
    }
}

impl FluidForce for SaffmanMeiLift {
    fn name(&self) -> &'static str {
        "saffman_mei_lift"
    }

    fn needs_vorticity(&self) -> bool {
        true
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        let (w, slip) = g.slip();
        let o = g.vorticity;
        let omega = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
        // No shear or no slip, no lift (and no 0/0 in β).
        if omega == 0.0 || slip == 0.0 {
            return [0.0; 3];
        }
        let (rho, mu, d) = (g.gas_density, self.viscosity, g.diameter);
        let re_p = rho * d * slip / mu;
        let re_w = rho * d * d * omega / mu;
        let c = 1.615 * d * d * (rho * mu / omega).sqrt() * Self::mei_factor(re_p, re_w);
        [
            c * (w[1] * o[2] - w[2] * o[1]),
            c * (w[2] * o[0] - w[0] * o[2]),
            c * (w[0] * o[1] - w[1] * o[0]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grain at rest in the simple shear u = (G y, 0, 0) at its centre height y0: slip
    /// (G y0, 0, 0), ω = (0, 0, −G).
    fn in_shear(d: Real, g: Real, y0: Real, rho: Real) -> GrainInFluid {
        GrainInFluid {
            volume: std::f64::consts::PI / 6.0 * d * d * d,
            diameter: d,
            velocity: [0.0; 3],
            porosity: 1.0,
            pressure_gradient: [0.0; 3],
            gas_velocity: [g * y0, 0.0, 0.0],
            gas_density: rho,
            vorticity: [0.0, 0.0, -g],
        }
    }

    #[test]
    fn creeping_shear_gives_saffmans_force_towards_the_faster_gas() {
        // Air, a 10 µm grain, G = 10/s, slip 1 mm/s: Re_p = 6.7e-4, β = d G/(2 U) = 0.05, where
        // C_m = 1 − (1 − 0.3314√β)(1 − e^(−Re_p/10)) = 1 − 6.2e-5; Saffman's creeping-flow
        // result 6.46 μ a² U √(G/ν) then holds to that (tolerance 1e-4).
        let (mu, rho, d, g, y0) = (1.8e-5, 1.2, 1e-5, 10.0, 1e-4);
        let lift = SaffmanMeiLift { viscosity: mu };
        let f = lift.force(&in_shear(d, g, y0, rho));
        let (a, u, nu) = (0.5 * d, g * y0, mu / rho);
        let saffman = 6.46 * mu * a * a * u * (g / nu).sqrt();
        assert!(f[0] == 0.0 && f[2] == 0.0, "{f:?}");
        assert!(f[1] > 0.0, "lift towards the faster gas: {f:?}");
        assert!(
            (f[1] - saffman).abs() < 1e-4 * saffman,
            "{} vs Saffman {saffman}",
            f[1]
        );
    }

    /// One case at finite Reynolds number worked by hand: d = 1 mm, air, G = 50/s, slip
    /// 0.075 m/s: Re_p = 5, Re_ω = 3.333, β = 1/3, C_m = (1 − 0.19133) e^(−0.5) + 0.19133 =
    /// 0.68181, F = 1.615 d² √(ρμ/G) C_m U G = 2.7140e-9 N.
    #[test]
    fn finite_reynolds_case_worked_by_hand() {
        let lift = SaffmanMeiLift { viscosity: 1.8e-5 };
        let f = lift.force(&in_shear(1e-3, 50.0, 0.075 / 50.0, 1.2));
        assert!((f[1] / 2.7140e-9 - 1.0).abs() < 1e-4, "{f:?}");
    }

    #[test]
    fn mei_factor_follows_each_branch() {
        // Mei's fit has a jump at Re_p = 40 (two correlations meet there); both sides are
        // what the formula says.
        let beta: Real = 0.2;
        let below = SaffmanMeiLift::mei_factor(40.0, 2.0 * beta * 40.0);
        let a = 0.3314 * beta.sqrt();
        assert!((below - ((1.0 - a) * (-4.0f64).exp() + a)).abs() < 1e-15);
        let above = SaffmanMeiLift::mei_factor(40.0 + 1e-9, 2.0 * beta * (40.0 + 1e-9));
        assert!((above - 0.0524 * (beta * 40.0).sqrt()).abs() < 1e-9);
        // No slip or no shear: no lift.
        let lift = SaffmanMeiLift { viscosity: 1.8e-5 };
        let mut g = in_shear(1e-3, 100.0, 0.0, 1.2);
        assert_eq!(lift.force(&g), [0.0; 3]);
        g.vorticity = [0.0; 3];
        g.gas_velocity = [1.0, 0.0, 0.0];
        assert_eq!(lift.force(&g), [0.0; 3]);
    }
}
