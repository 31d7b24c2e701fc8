//! Buoyancy F = −ρ_f V_p g: Archimedes' force in the hydrostatic pressure gradient ρ_f g,
//! which plugflow's gas solvers leave out of their pressure (they solve without gravity), so
//! `pressure_gradient` does not contain it. Lethe's CFD–DEM adds it as its "buoyancy force".
//! For air on a polymer grain it is ρ_f/ρ_p ≈ 0.1 % of the weight.

use super::{FluidForce, FluidForceEntry};
use crate::drag::GrainInFluid;
use crate::Vec3;

/// The registry's entry (`"buoyancy"` in `coupling.fluid_forces`).
pub(super) const ENTRY: FluidForceEntry = FluidForceEntry {
    name: "buoyancy",
    needs_gas_velocity: true,
    needs_vorticity: false,
    build: |s| std::sync::Arc::new(Buoyancy { gravity: s.gravity }),
};

/// −ρ_f V_p g.
#[derive(Debug, Clone, Copy)]
pub struct Buoyancy {
    /// Gravity, m/s².
    pub gravity: Vec3,
}

impl FluidForce for Buoyancy {
    fn name(&self) -> &'static str {
        "buoyancy"
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        let m = g.gas_density * g.volume;
        [
            -(m * self.gravity[0]),
            -(m * self.gravity[1]),
            -(m * self.gravity[2]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Archimedes: the weight of the gas the grain displaces, upwards.
    #[test]
    fn a_grain_is_lifted_by_the_weight_of_the_gas_it_displaces() {
        let g = crate::drag::grain_at_rest_in_stream(2e-3, 0.5, 1.0, 1.2);
        let f = Buoyancy {
            gravity: [0.0, 0.0, -9.81],
        }
        .force(&g);
        let displaced = 1.2 * std::f64::consts::PI / 6.0 * 8e-9 * 9.81;
        assert_eq!(f[0], 0.0);
        assert!((f[2] - displaced).abs() < 1e-15 * displaced, "{f:?}");
    }
}
