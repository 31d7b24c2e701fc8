//! The DEM engine a scene names (`dem.engine`): the built-in one directly, or any engine
//! behind the C ABI (bindings/include/plugflow_dem.h) loaded from its shared library.

use std::path::PathBuf;

use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::isolated::IsolatedBackend;
use plugflow_coupling::DemBackend;

use plugflow_coupling::abi::{check_scene, CheckOutcome};

use crate::dem::{DemConfig, NativeDem};
use crate::scene::{Scene, SceneError};

/// The library of an ABI engine: the scene's `dem.library`, else
/// `libplugflow_dem_<engine>.so` next to the running executable (where cargo builds it;
/// for test binaries, one folder up).
pub fn library(scene: &Scene) -> Result<PathBuf, SceneError> {
    let d = &scene.file.dem;
    if let Some(p) = &d.library {
        return Ok(PathBuf::from(p));
    }
    let name = format!("libplugflow_dem_{}.so", d.engine.trim_end_matches("_abi"));
    let exe = std::env::current_exe().map_err(|e| {
        SceneError::field("dem.library", format!("cannot locate the executable: {e}"))
    })?;
    let dir = exe.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let candidates = [dir.join(&name), dir.join("..").join(&name)];
    candidates
        .iter()
        .find(|p| p.exists())
        .cloned()
        .ok_or_else(|| {
            let build = match d.engine.as_str() {
                "liggghts" => {
                    "cargo build --release -p plugflow-dem-liggghts --features liggghts \
                     (after bash scripts/setup-system.sh)"
                }
                "yade" => {
                    "cargo build --release -p plugflow-dem-yade --features yade \
                     (after bash scripts/setup-system.sh)"
                }
                _ => "cargo build --release -p plugflow-dem-native",
            };
            SceneError::field(
                "dem.engine",
                format!(
                    "`{}` needs {name}, not found next to {}: build it with `{build}` or set \
                     `dem.library`",
                    d.engine,
                    exe.display()
                ),
            )
        })
}

/// Build the engine of a scene.
pub fn build_backend(scene: &Scene, cfg: &DemConfig) -> Result<Box<dyn DemBackend>, SceneError> {
    match scene.file.dem.engine.as_str() {
        "native" => Ok(Box::new(NativeDem::new(cfg.clone())?)),
        _ if scene.file.dem.isolate => {
            let lib = library(scene)?;
            let exe = std::env::current_exe().map_err(|e| {
                SceneError::field("dem.isolate", format!("cannot locate the executable: {e}"))
            })?;
            let dir = exe.parent().map(|p| p.to_path_buf()).unwrap_or_default();
            let host = [
                dir.join("plugflow-dem-host"),
                dir.join("../plugflow-dem-host"),
            ]
            .into_iter()
            .find(|p| p.exists())
            .ok_or_else(|| {
                SceneError::field(
                    "dem.isolate",
                    format!(
                        "plugflow-dem-host not found next to {}: cargo build --release",
                        exe.display()
                    ),
                )
            })?;
            let engine = IsolatedBackend::spawn(&host, &lib, &scene.to_json())
                .map_err(|e| SceneError::field("dem.engine", e.to_string()))?;
            Ok(Box::new(engine))
        }
        _ => {
            let lib = library(scene)?;
            let engine = AbiBackend::load(&lib, &scene.to_json())
                .map_err(|e| SceneError::field("dem.engine", e.to_string()))?;
            Ok(Box::new(engine))
        }
    }
}

/// The chosen engine's own refusals, without starting it: the built-in engine is built
/// (that is its check: the initial placement), an ABI engine answers `pf_dem_check`.
pub fn check_engine(scene: &Scene, cfg: &DemConfig) -> Result<(), SceneError> {
    if scene.file.dem.engine == "native" {
        // (Placing the grains is the check; settling them, minutes of steps, is the run's.)
        let mut cfg = cfg.clone();
        cfg.settle = None;
        return NativeDem::new(cfg).map(drop);
    }
    let lib = library(scene)?;
    match check_scene(&lib, &scene.to_json()) {
        Ok(CheckOutcome::Accepted) => Ok(()),
        // The engine's message names the field itself (`field `x`: reason`).
        Ok(CheckOutcome::Refused(why)) => Err(SceneError::Engine {
            engine: scene.file.dem.engine.clone(),
            reason: why,
        }),
        Ok(CheckOutcome::NotOffered) => Err(SceneError::field(
            "dem.engine",
            format!(
                "{} predates pf_dem_check (ABI 1.1) and cannot check a scene without \
                 starting: rebuild it",
                lib.display()
            ),
        )),
        Err(e) => Err(SceneError::field("dem.engine", e.to_string())),
    }
}
