//! The built-in DEM behind the plugflow DEM C ABI (`bindings/include/plugflow_dem.h`), as a
//! shared library `libplugflow_dem_native.so`. It exists so that the ABI path itself is
//! tested with no external code: a scene run native-direct and native-through-ABI must
//! agree bit for bit. The exports themselves come from `plugflow_coupling::export_dem_abi!`
//! (every body behind `catch_unwind`, errors as status codes and last-error text).

use plugflow_coupling::DemBackend;
use plugflow_model::dem::NativeDem;
use plugflow_model::scene::Scene;

/// The scene JSON of `pf_dem_create` → the built-in engine.
fn build(json: &str) -> Result<Box<dyn DemBackend>, String> {
    let scene = Scene::from_json(json).map_err(|e| e.to_string())?;
    let cfg = plugflow_model::dem_config(&scene).map_err(|e| e.to_string())?;
    Ok(Box::new(NativeDem::new(cfg).map_err(|e| e.to_string())?))
}

/// The scene JSON of `pf_dem_check` → the built-in engine's refusals (its configuration and
/// the initial placement; the engine is built and dropped, which is all it takes).
fn check(json: &str) -> Result<(), String> {
    build(json).map(drop)
}

plugflow_coupling::export_dem_abi!(build, check);
