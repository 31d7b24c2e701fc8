//! The DEM backend trait: what the coupling driver asks of any discrete-element engine.
//!
//! The built-in DEM implements it directly; external engines (LIGGGHTS, YADE) implement it
//! through the versioned C ABI in `bindings/include/plugflow_dem.h`. The calls mirror that
//! ABI one to one so that a backend behind the ABI and one in-process behave the same.

use crate::{Real, Vec3};

/// Borrowed, structure-of-arrays view of the grains (no copy for the native engine).
///
/// All slices have the same length, the number of grains currently in the domain.
#[derive(Debug, Clone, Copy)]
pub struct ParticleView<'a> {
    /// Stable particle identifiers (never reused within a run).
    pub id: &'a [u64],
    /// Centre positions, m.
    pub position: &'a [Vec3],
    /// Translational velocities, m/s.
    pub velocity: &'a [Vec3],
    /// Angular velocities, rad/s (all zero when the scene switches rotation off).
    pub angular_velocity: &'a [Vec3],
    /// Radii, m.
    pub radius: &'a [Real],
    /// Masses, kg.
    pub mass: &'a [Real],
}

impl ParticleView<'_> {
    /// Number of grains in the view.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// True when no grain is in the domain.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }
}

/// A grain to be inserted by the coupling layer (the engine assigns its id).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewParticle {
    /// Centre position, m.
    pub position: Vec3,
    /// Velocity, m/s.
    pub velocity: Vec3,
    /// Radius, m.
    pub radius: Real,
    /// Material density, kg/m³.
    pub density: Real,
}

/// Implicit drag: F_i = β_i (u_f,i − v_i) evaluated by the engine at every DEM step, so
/// the stiff drag inside a dense plug does not restrict the coupling interval.
#[derive(Debug, Clone, Copy)]
pub struct ImplicitDrag<'a> {
    /// Drag coefficient β_i per grain, kg/s.
    pub coefficient: &'a [Real],
    /// Fluid velocity at each grain, m/s.
    pub fluid_velocity: &'a [Vec3],
}

/// Net force the grains exert on one wall, N.
#[derive(Debug, Clone, PartialEq)]
pub struct WallForce {
    /// Name of the wall ("tube", "inlet_cap", a plane's name, ...).
    pub wall: String,
    /// Force on the wall, N.
    pub force: Vec3,
}

/// Grains an engine fed and removed on its own (scene inlets and outlets).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GrainFlow {
    /// Grains fed by the inlet.
    pub fed_count: u64,
    /// Mass fed, kg.
    pub fed_mass: Real,
    /// Grains that left through the outlet.
    pub outflow_count: u64,
    /// Mass that left through the outlet, kg.
    pub outflow_mass: Real,
    /// Grains that left elsewhere.
    pub lost_count: u64,
}

/// Where this process stands among the processes one engine runs on (MPI ranks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ranks {
    /// This process's rank, 0-based.
    pub rank: usize,
    /// Number of ranks (1: an engine in one process).
    pub size: usize,
}

impl Ranks {
    /// One process.
    pub const SINGLE: Ranks = Ranks { rank: 0, size: 1 };

    /// The rank that writes the run's files.
    pub fn leads(&self) -> bool {
        self.rank == 0
    }
}

/// A reduction over all ranks ([`DemBackend::all_reduce`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reduce {
    Sum,
    Max,
}

/// Errors a backend reports to the driver; each names where it happened.
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// A grain's state became NaN or infinite, or blew up.
    #[error("non-finite or blown-up state at step {step}: particle id {particle_id} ({what})")]
    NonFinite {
        step: u64,
        particle_id: u64,
        what: String,
    },
    /// An argument does not fit the engine's state (wrong length, bad value).
    #[error("invalid argument `{argument}`: {reason}")]
    InvalidArgument { argument: String, reason: String },
    /// The engine itself failed (external engines: their message).
    #[error("engine `{engine}` failed: {message}")]
    Engine { engine: String, message: String },
}

/// A discrete-element engine the co-simulation can drive.
pub trait DemBackend {
    /// Engine name as a scene names it ("native", "liggghts", "yade").
    fn engine_name(&self) -> &str;
    /// Engine version string for the run summary.
    fn engine_version(&self) -> String;
    /// DEM time step, s.
    fn time_step(&self) -> Real;
    /// Simulated time, s.
    fn time(&self) -> Real;
    /// Steps taken so far.
    fn step_count(&self) -> u64;
    /// Advance `steps` DEM steps with the fluid forces held as last set.
    fn advance(&mut self, steps: u64) -> Result<(), BackendError>;
    /// Borrow the grains.
    fn particles(&self) -> ParticleView<'_>;
    /// Set the per-grain fluid force (N), in the order of [`DemBackend::particles`];
    /// optionally an implicit drag coefficient and fluid velocity.
    fn set_fluid_forces(
        &mut self,
        force: &[Vec3],
        implicit: Option<ImplicitDrag<'_>>,
    ) -> Result<(), BackendError>;
    /// Insert grains; returns the ids given to them.
    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError>;
    /// Remove grains past the outlet; returns the removed mass, kg.
    fn remove_past_outlet(&mut self) -> Result<Real, BackendError>;
    /// Forces on the walls, N.
    fn wall_forces(&self) -> Vec<WallForce>;
    /// Wall-clock seconds spent in each named stage so far.
    fn stage_times(&self) -> Vec<(String, f64)>;
    /// The engine's worker team, if it has one: the coupler's per-grain stages run on it
    /// between the engine's own phases (on cores that would otherwise wait), each member
    /// over a fixed range of grains, so results stay reproducible for a thread count.
    /// Engines in another process or library (LIGGGHTS, YADE) have none.
    fn team(&self) -> Option<std::sync::Arc<crate::team::Team>> {
        None
    }
    /// Engine-specific figures for the run summary (name, value), e.g. neighbour builds.
    fn diagnostics(&self) -> Vec<(String, f64)> {
        Vec::new()
    }
    /// The engine's feed and outflow counters; None when the engine keeps none.
    fn flow(&self) -> Option<GrainFlow> {
        None
    }
    /// Per-grain contact force (grain–grain and walls) of the last step, N, in the order
    /// of [`DemBackend::particles`]; None when the engine does not expose it.
    fn contact_forces(&self) -> Option<Vec<Vec3>> {
        None
    }
    /// Keep the engine's own log (LIGGGHTS's `log.liggghts`) in `dir`, the run's folder,
    /// when the engine closes, instead of deleting it with its working files. Engines
    /// without a log of their own have nothing to keep.
    fn keep_log(&mut self, _dir: &std::path::Path) -> Result<(), BackendError> {
        Ok(())
    }
    /// The engine's whole state between two `advance` calls, as bytes only this engine
    /// reads back (a checkpoint): restoring it and advancing gives bit for bit what
    /// advancing without the detour gives (engines that restart through files of their own,
    /// as LIGGGHTS does, go on with the same physics, not the same bits). `&mut`: writing
    /// it may be a command to the engine. Engines that cannot refuse, saying why.
    fn save_state(&mut self) -> Result<Vec<u8>, BackendError> {
        Err(BackendError::Engine {
            engine: self.engine_name().to_string(),
            message: "this engine cannot write checkpoints (`output.checkpoint_interval`)"
                .to_string(),
        })
    }
    /// Start from the grains of a state [`DemBackend::save_state`] wrote (another run's,
    /// with the same walls and grains) at this engine's time zero, with its own settings
    /// (friction, feed, ...): the grains, their contacts and histories are taken; the
    /// clock, the step count and the feed and outflow counters start again.
    fn start_from_state(&mut self, _state: &[u8]) -> Result<(), BackendError> {
        Err(BackendError::Engine {
            engine: self.engine_name().to_string(),
            message: "this engine cannot start a new run from a checkpoint's grains \
                      (`--from`; the built-in engine can); resume the run that wrote it with \
                      `--resume`"
                .to_string(),
        })
    }
    /// The ranks this engine runs on: an engine under MPI (LIGGGHTS launched by `mpirun`)
    /// owns a share of the grains in each process, and [`DemBackend::particles`],
    /// `set_fluid_forces`, `wall_forces` are that rank's. One process by default.
    fn ranks(&self) -> Ranks {
        Ranks::SINGLE
    }
    /// Replace `data` on every rank by its sum or maximum over all ranks, on the engine's
    /// own communicator (collective: every rank calls it with the same length). The
    /// coupler needs no MPI: the gas is replicated on every rank and only its deposited
    /// node fields travel. A no-op for an engine in one process.
    fn all_reduce(&self, _data: &mut [f64], _op: Reduce) -> Result<(), BackendError> {
        Ok(())
    }
    /// Take back a state [`DemBackend::save_state`] wrote (an engine built from the same
    /// scene); refused, naming why, when the bytes are not such a state.
    fn restore_state(&mut self, _state: &[u8]) -> Result<(), BackendError> {
        Err(BackendError::Engine {
            engine: self.engine_name().to_string(),
            message: "this engine cannot resume from checkpoints".to_string(),
        })
    }
}
