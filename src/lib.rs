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
pub mod crosscheck;
pub mod dem;
pub mod gas;
pub mod output;
pub mod png;
pub mod rng;
pub mod run;
pub mod scene;
pub mod setup;
pub mod study;
pub mod summary;
pub mod sweep;

pub use plugflow_coupling::{Real, Vec3};
