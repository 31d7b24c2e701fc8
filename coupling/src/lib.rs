//! `plugflow-coupling`: the seams of the co-simulation.
//!
//! This crate owns the interfaces every engine and solver plugs into and nothing engine
//! specific: the [`DemBackend`] trait that the built-in DEM (and, through the C ABI, LIGGGHTS
//! and YADE) implements, the borrowed [`ParticleView`] the coupling reads grains through, the
//! [`GasSolver`] and [`DragLaw`] traits, the grid with its deposit/interpolation kernels
//! ([`grid`]), the whole coupled step ([`coupler`]: [`Coupler::advance`]) and the checks made before a run
//! ([`checks`]), and the
//! [`StageTimer`] that times each named stage of a step (shared/DESIGN.md, "The step").

pub mod abi;
pub mod abi_export;
pub mod backend;
pub mod checks;
pub mod coupler;
pub mod drag;
pub mod fluid_force;
pub mod gas;
pub mod grid;
pub mod isolated;
pub mod ranks;
pub mod team;
pub mod timing;

pub use backend::{
    BackendError, DemBackend, GrainFlow, ImplicitDrag, NewParticle, ParticleView, Ranks, Reduce,
    WallForce,
};
pub use checks::{CouplingCheck, Verdict};
pub use coupler::{Coupler, CouplerState, CouplingStats, ExchangeError, Stage, StepError};
pub use drag::{DarcyVolumeForce, DragLaw, GrainInFluid};
pub use gas::{GasError, GasSolver, GasStepReport};
pub use grid::{deposit, GranularFields, Stencil, TubeGrid};
pub use timing::StageTimer;

/// The one floating-point type of the project (SI units throughout).
pub type Real = f64;

/// A 3-vector in SI units; plain arrays keep the state containers `Copy` and FFI friendly.
pub type Vec3 = [Real; 3];
