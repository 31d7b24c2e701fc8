//! `plugflow-model`: what a scene is and what the built-in engine makes of it — the scene
//! files ([`scene`]), the built-in DEM ([`dem`]) and its configuration from a scene
//! ([`dem_config`]), the random numbers, and the run summary ([`summary`], with the TARGETS.md
//! rows in [`targets`]). No gas, outputs or analysis: the engines' shims (bindings/) depend on
//! this crate and `plugflow-coupling` only; the `plugflow` crate re-exports it.

// Index loops over several structure-of-arrays columns at once read better than zips.
#![allow(clippy::needless_range_loop)]

pub mod dem;
pub mod dem_config;
pub mod rng;
pub mod scene;
pub mod summary;
pub mod targets;

pub use dem_config::dem_config;
pub use plugflow_coupling::{Real, Vec3};
