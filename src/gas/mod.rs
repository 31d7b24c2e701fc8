//! Gas solvers, one file each behind [`plugflow_coupling::GasSolver`]:
//! `darcy` (McNamara–Flekkøy pressure diffusion, seeds 000 and 002).

pub mod darcy;

pub use darcy::{carman_kozeny, DarcyGas, DarcyParams, Scheme, SolvePath};
