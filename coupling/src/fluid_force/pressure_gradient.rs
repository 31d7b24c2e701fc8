//! The pressure-gradient force F = −V_p ∇p: the share of the gas pressure gradient a grain
//! takes. With the `simple` gas, whose momentum equation carries −ε∇p, this is the
//! (1 − ε)∇p per volume of mixture the gas leaves to the solids (Anderson & Jackson's
//! "model A"; seed 004 eqs. 12–13 and CFDEM's `gradPForce`): without it the gas–grain pair
//! would not conserve momentum, so the scene check asks for it with the `simple` gas.

use super::{FluidForce, FluidForceEntry};
use crate::drag::GrainInFluid;
use crate::Vec3;

/// The registry's entry (`"pressure_gradient"` in `coupling.fluid_forces`).
pub(super) const ENTRY: FluidForceEntry = FluidForceEntry {
    name: "pressure_gradient",
    needs_gas_velocity: true,
    needs_vorticity: false,
    build: |_| std::sync::Arc::new(PressureGradient),
};

/// −V_p ∇p.
#[derive(Debug, Clone, Copy)]
pub struct PressureGradient;

impl FluidForce for PressureGradient {
    fn name(&self) -> &'static str {
        "pressure_gradient"
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        let gp = g.pressure_gradient;
        [
            -(g.volume * gp[0]),
            -(g.volume * gp[1]),
            -(g.volume * gp[2]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grain in a gradient of 1000 Pa/m along x is pushed down it with V_p × 1000 N.
    #[test]
    fn pushes_down_the_gradient_with_the_grain_volume() {
        let mut g = crate::drag::grain_at_rest_in_stream(1e-3, 0.4, 0.0, 1.2);
        g.pressure_gradient = [1000.0, 0.0, -50.0];
        let f = PressureGradient.force(&g);
        assert_eq!(f, [-g.volume * 1000.0, -0.0, g.volume * 50.0]);
    }
}
