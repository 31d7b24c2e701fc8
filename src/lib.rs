//! plugflow: gas–grain co-simulation for dense-phase pneumatic conveying.
//!
//! Where to look first: [`run::run`] is the step loop of a whole run; [`dem::NativeDem`] is
//! the built-in DEM and its [`plugflow_coupling::DemBackend::advance`] the DEM step; scenes
//! are read and checked in [`scene`].

// Index loops over several structure-of-arrays columns at once read better than zips.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod cosim;
pub mod crosscheck;
pub mod dem;
pub mod engine;
pub mod gas;
pub mod output;
pub mod png;
pub mod rng;
pub mod run;
pub mod scene;
pub mod study;
pub mod sweep;

pub use plugflow_coupling::{Real, Vec3};
