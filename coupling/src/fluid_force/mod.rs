//! Fluid forces on a grain besides the drag: one file per force behind [`FluidForce`],
//! each registered by name in [`FLUID_FORCES`] (one `ENTRY` in its file, one line here), and
//! switched on by the scene (`coupling.fluid_forces`). The drag law (`crate::drag`) gives the
//! drag alone; what else the gas does to a grain is listed here:
//!
//! - `pressure_gradient`: −V_p ∇p, the grain's share of the gas pressure gradient;
//! - `buoyancy`: −ρ_f V_p g, Archimedes' force in the hydrostatic gradient the gas solvers
//!   leave out (they solve without gravity);
//! - `saffman_mei_lift`: the shear lift of Saffman (1965) with Mei's (1992) correction.
//!
//! A force that needs the gas velocity (or its curl) needs a gas that carries it (`simple`).

mod buoyancy;
mod pressure_gradient;
mod saffman_mei_lift;
pub mod vorticity;

pub use buoyancy::Buoyancy;
pub use pressure_gradient::PressureGradient;
pub use saffman_mei_lift::SaffmanMeiLift;

use crate::drag::GrainInFluid;
use crate::{Real, Vec3};
use std::sync::Arc;

/// What a fluid force is built from: the scene's gas and gravity.
#[derive(Debug, Clone, Copy)]
pub struct FluidForceSettings {
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
    /// Gravity, m/s².
    pub gravity: Vec3,
}

/// A fluid force in the registry: its name in the scene, what it needs, how to build it.
pub struct FluidForceEntry {
    /// The name in `coupling.fluid_forces`.
    pub name: &'static str,
    /// The force reads the gas velocity (or density): only a gas that carries them (`simple`)
    /// can feed it.
    pub needs_gas_velocity: bool,
    /// The force reads the gas vorticity ∇ × u on the grain: the coupler computes it on the
    /// nodes only for a scene that has such a force.
    pub needs_vorticity: bool,
    /// The force with the scene's settings.
    pub build: fn(&FluidForceSettings) -> Arc<dyn FluidForce>,
}

/// Every fluid force a scene may name, in the order the messages list them.
pub static FLUID_FORCES: &[FluidForceEntry] = &[
    pressure_gradient::ENTRY,
    buoyancy::ENTRY,
    saffman_mei_lift::ENTRY,
];

/// The registered force called `name`.
pub fn fluid_force(name: &str) -> Option<&'static FluidForceEntry> {
    FLUID_FORCES.iter().find(|e| e.name == name)
}

/// The names of the registered forces, joined by `sep`.
pub fn fluid_force_names(sep: &str) -> String {
    FLUID_FORCES
        .iter()
        .map(|e| e.name)
        .collect::<Vec<_>>()
        .join(sep)
}

/// A fluid force on one grain from the gas fields at its position.
pub trait FluidForce: Send + Sync {
    /// Name as the scene writes it.
    fn name(&self) -> &'static str;
    /// True when the force reads [`GrainInFluid::vorticity`].
    fn needs_vorticity(&self) -> bool {
        false
    }
    /// Force on the grain, N.
    fn force(&self, grain: &GrainInFluid) -> Vec3;
}
