//! YADE behind the plugflow DEM C ABI (`bindings/include/plugflow_dem.h`), as the shared
//! library `libplugflow_dem_yade.so`, built only with the `yade` feature. Debian packages
//! YADE without C++ headers, so the shim embeds Debian's CPython 3.11 and drives YADE
//! through its Python API (`src/driver.py`); YADE is GPL-2.0-or-later, and so is this crate.
//!
//! `pf_dem_create` checks the scene with plugflow's parser and maps it (see [`input`]):
//! the same geometry, grains, contact constants and inlet as the other two engines, or a
//! refusal naming the field and why. plugflow places the initial grains and runs the inlet
//! and the open ends itself between YADE's steps (the code the built-in engine uses).

pub mod input;

#[cfg(feature = "yade")]
pub mod engine;
#[cfg(feature = "yade")]
mod exports;
