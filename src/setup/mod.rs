//! The setup layer: a checked [`Scene`] becomes the engine's configuration, the engine and
//! the coupler. `validate`, `run`, `crosscheck`, `sweep` and `study` all go through here,
//! so a scene that validates is a scene that runs.
//!
//! - [`dem_config`] (crate `plugflow-model`): the built-in engine's configuration (laws, time step and its
//!   limit, walls, inlet); the external engines map the same configuration.
//! - [`coupling_from_scene`] (`coupling.rs`): gas solver, drag law (from the registry in
//!   `plugflow_coupling::drag`), coupling interval and the checks made before a run.
//! - [`build_backend`], [`check_engine`] (`engine.rs`): the engine `dem.engine` names, built,
//!   or asked whether it takes the scene without starting it.

pub mod coupling;
pub mod engine;
pub mod ranks;

pub use coupling::{check_row, coupling_checks, coupling_from_scene};
pub use engine::{build_backend, check_engine};
pub use plugflow_model::dem_config;

use plugflow_coupling::{Coupler, DemBackend};

use crate::dem::DemConfig;
use crate::scene::{Scene, SceneError};

/// What a scene sets up, before any engine starts: the configuration and the coupler.
pub struct Prepared {
    /// The built-in engine's configuration (what the external engines map).
    pub config: DemConfig,
    /// The gas coupling (None without `[gas]`).
    pub coupler: Option<Coupler>,
}

/// A scene set up to run: the engine started, the coupler beside it.
pub struct Setup {
    pub config: DemConfig,
    pub engine: Box<dyn DemBackend>,
    pub coupler: Option<Coupler>,
}

/// The configuration and the coupler of a scene (no engine started).
pub fn prepare(scene: &Scene) -> Result<Prepared, SceneError> {
    let config = dem_config(scene)?;
    let coupler = coupling_from_scene(scene, &config)?;
    Ok(Prepared { config, coupler })
}

/// Everything `plugflow validate` checks: the scene's own checks (done by loading it), the
/// configuration, the coupling checks, and the chosen engine's refusals.
pub fn validate(scene: &Scene) -> Result<Prepared, SceneError> {
    ranks::check_ranks(scene, ranks::launched())?;
    let prepared = prepare(scene)?;
    check_engine(scene, &prepared.config)?;
    Ok(prepared)
}

/// A scene ready to run: configuration, engine, coupler. `restoring`: the engine's state
/// comes from a checkpoint next (`--resume`, `--from`), so its initial grains are not
/// settled first (`dem.settle`: minutes of steps whose result the checkpoint replaces).
pub fn build(scene: &Scene, restoring: bool) -> Result<Setup, SceneError> {
    let Prepared {
        mut config,
        coupler,
    } = prepare(scene)?;
    if restoring {
        config.settle = None;
    }
    let launched = ranks::launched();
    ranks::check_ranks(scene, launched)?;
    let engine = build_backend(scene, &config)?;
    if engine.ranks() != launched {
        let r = engine.ranks();
        return Err(SceneError::field(
            "dem.engine",
            format!(
                "mpirun started rank {} of {}, the engine runs as rank {} of {}: {}",
                launched.rank,
                launched.size,
                r.rank,
                r.size,
                match launched.size > r.size {
                    true => "it was built without MPI (rebuild the LIGGGHTS shim)",
                    false => "the launcher's environment and the engine's MPI disagree",
                }
            ),
        ));
    }
    Ok(Setup {
        config,
        engine,
        coupler,
    })
}
