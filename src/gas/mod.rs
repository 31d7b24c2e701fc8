//! Gas solvers, one file each behind [`plugflow_coupling::GasSolver`]:
//! `darcy` (McNamara–Flekkøy pressure diffusion, seeds 000 and 002) and `simple`
//! (volume-averaged Navier–Stokes, seed 004; 2D).

pub mod darcy;
pub mod simple;

pub use darcy::{carman_kozeny, DarcyGas, DarcyParams, Scheme, SolvePath};
pub use simple::{SimpleGas, SimpleParams, SimpleTubeGas};
