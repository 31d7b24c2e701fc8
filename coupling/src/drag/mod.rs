//! Drag laws: the force of the gas on one grain from the fields at its position. One file
//! per law behind [`DragLaw`]: `darcy` (the seeds' volume force, 000 and 002),
//! `ergun_wen_yu` (seed 004 eqs. 12–13, the Gidaspow switch) and `di_felice`; the last two
//! need a gas velocity, which the SIMPLE solver (src/gas/simple.rs) carries.

mod darcy;
mod di_felice;
pub mod ergun_wen_yu;

pub use darcy::DarcyVolumeForce;
pub use di_felice::DiFelice;
pub use ergun_wen_yu::ErgunWenYu;

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
    /// Gas density at the grain, kg/m³ (solvers that carry one; the d'Arcy law needs none).
    pub gas_density: Real,
}

impl GrainInFluid {
    /// Slip w = u − v of the gas past the grain, m/s, and its magnitude.
    pub fn slip(&self) -> (Vec3, Real) {
        let w = [
            self.gas_velocity[0] - self.velocity[0],
            self.gas_velocity[1] - self.velocity[1],
            self.gas_velocity[2] - self.velocity[2],
        ];
        (w, (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt())
    }
}

/// A drag law.
pub trait DragLaw: Send + Sync {
    /// Name as the scene writes it.
    fn name(&self) -> &'static str;
    /// Force of the gas on the grain, N.
    fn force(&self, grain: &GrainInFluid) -> Vec3;
}
