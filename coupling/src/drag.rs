//! Drag laws: the force of the gas on one grain from the fields at its position. One law
//! per type behind [`DragLaw`]; the d'Arcy volume force is the seeds' (000, 002).

use crate::{Real, Vec3};

/// What a drag law knows about a grain and the gas around it.
#[derive(Debug, Clone, Copy)]
pub struct GrainInFluid {
    /// Grain volume, m³.
    pub volume: Real,
    /// Grain diameter, m.
    pub diameter: Real,
    /// Grain velocity, m/s.
    pub velocity: Vec3,
    /// Porosity at the grain (eq. 9), clamped as the gas solver clamps it.
    pub porosity: Real,
    /// Pressure gradient at the grain, Pa/m.
    pub pressure_gradient: Vec3,
    /// Gas velocity at the grain, m/s (solvers that carry one).
    pub gas_velocity: Vec3,
}

/// A drag law.
pub trait DragLaw: Send + Sync {
    /// Name as the scene writes it.
    fn name(&self) -> &'static str;
    /// Force of the gas on the grain, N.
    fn force(&self, grain: &GrainInFluid) -> Vec3;
}

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
