//! Analysis of a run: plug statistics (seed 000 §4.2, seed 002 §3.2) and the comparison
//! with the papers' numbers (shared/TARGETS.md).

pub mod characteristic;
pub mod plugs;
pub mod profiles;
pub mod slug;
pub mod taps;
pub use plugflow_model::targets;
