//! Gas solvers, one file each behind [`plugflow_coupling::GasSolver`]:
//! `darcy` (McNamara–Flekkøy pressure diffusion, seeds 000 and 002) and `simple`
//! (volume-averaged Navier–Stokes, seed 004; 2D).

pub mod banded;
pub mod darcy;
pub mod simple;

pub use darcy::{carman_kozeny, DarcyGas, DarcyParams, Scheme, SolvePath};
pub use simple::{SimpleGas, SimpleParams, SimpleTubeGas};

use plugflow_coupling::GasError;

/// A gas solver's state for a checkpoint, encoded (`what` names the solver in the error).
pub(crate) fn encode_state<T: serde::Serialize>(
    state: &T,
    what: &str,
) -> Result<Vec<u8>, GasError> {
    postcard::to_allocvec(state).map_err(|e| GasError::State {
        reason: format!("cannot encode the {what} gas: {e}"),
    })
}

/// A checkpoint's gas state, decoded and checked against the scene's grid: `misfit` says
/// why the state does not fit (`None` when it does).
pub(crate) fn decode_state<T: serde::de::DeserializeOwned>(
    bytes: &[u8],
    what: &str,
    misfit: impl FnOnce(&T) -> Option<String>,
) -> Result<T, GasError> {
    let state: T = postcard::from_bytes(bytes).map_err(|e| GasError::State {
        reason: format!("not a {what} gas state: {e}"),
    })?;
    match misfit(&state) {
        None => Ok(state),
        Some(reason) => Err(GasError::State { reason }),
    }
}
