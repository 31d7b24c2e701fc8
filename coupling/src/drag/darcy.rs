//! The d'Arcy volume force (seed 000 eq. 6, seed 002 eq. 6).

use super::{DragLaw, DragLawEntry, GrainInFluid};
use crate::Vec3;

/// The registry's entry (`coupling.drag = "darcy"`, the d'Arcy gas's law).
pub(super) const ENTRY: DragLawEntry = DragLawEntry {
    name: "darcy",
    needs_gas_velocity: false,
    takes_voidage_factor: false,
    build: |_| std::sync::Arc::new(DarcyVolumeForce),
};

/// The d'Arcy volume force of seed 000 eq. 6 with the factor m restored:
/// F_i = −V_i ∇P_i / (1 − φ_i). Summed over the grains of a region it returns the whole
/// pressure drop across it: the gas carries no other momentum in this model.
#[derive(Debug, Clone, Copy, Default)]
pub struct DarcyVolumeForce;

impl DragLaw for DarcyVolumeForce {
    fn name(&self) -> &'static str {
        "darcy"
    }

    fn force(&self, g: &GrainInFluid) -> Vec3 {
        let s = -g.volume / (1.0 - g.porosity);
        [
            s * g.pressure_gradient[0],
            s * g.pressure_gradient[1],
            s * g.pressure_gradient[2],
        ]
    }
}
