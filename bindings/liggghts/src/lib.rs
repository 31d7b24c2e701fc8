//! LIGGGHTS behind the plugflow DEM C ABI (`bindings/include/plugflow_dem.h`), as the shared
//! library `libplugflow_dem_liggghts.so`, built only with the `liggghts` feature (it links
//! Debian's libliggghts, GPL-2.0-or-later, and so is this crate).
//!
//! `pf_dem_create` checks the scene with plugflow's own parser, refuses what it cannot map
//! (naming the field and why) and only then writes a LIGGGHTS input (see [`input`]): LIGGGHTS
//! ends the process on any input error, so nothing unchecked reaches it. The contact laws are
//! mapped so that LIGGGHTS computes the same forces as the built-in engine: Hooke springs
//! with `hooke/stiffness` and absolute damping, per material pair (grain–grain type 1–1,
//! grain–wall 1–2), k_n, k_t, γ_n, γ_t and μ taken from the built-in engine's laws.

#[cfg(feature = "liggghts")]
mod engine;
#[cfg(feature = "liggghts")]
mod exports;
#[cfg(feature = "liggghts")]
pub mod input;
