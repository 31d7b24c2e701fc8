//! plugflow: gas–grain co-simulation for dense-phase pneumatic conveying.
//!
//! Where to look first: the coupled step is [`plugflow_coupling::Coupler::advance`] (DEM
//! advance → deposit → gas → interpolate → drag → set forces); [`setup`] turns a scene into
//! engine + coupler; [`run::run`] is a run's lifecycle (sampling, outputs, signals) and
//! [`summary::Summary`] what it writes; [`dem::NativeDem`] is the built-in DEM; scenes are
//! read and checked in [`scene`].

// Index loops over several structure-of-arrays columns at once read better than zips.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod children;
pub mod crosscheck;
pub mod gas;
pub mod output;
pub mod run;
pub mod setup;
pub mod study;
pub mod sweep;

pub use plugflow_coupling::{Real, Vec3};
// The scene, the built-in DEM and the summary live in `plugflow-model` (what the engines'
// shims depend on); here under their usual paths.
pub use plugflow_model::{dem, rng, scene, summary};
