//! Collectives over the ranks of an engine run under MPI, built on the one reduction the
//! ABI offers ([`DemBackend::all_reduce`]): a gather of variable-length pieces and the
//! agreement on a failure. With one rank each is the identity, at no cost.
//!
//! A gather through a sum: every rank writes its piece at its own offset of a zeroed
//! buffer and the buffer is summed over the ranks; x + 0 = x exactly, so the pieces arrive
//! bit for bit (a −0.0 arrives as +0.0). It moves the whole buffer on every rank, as an
//! all-gather does; it runs at samples and for the grains leaving, not at every exchange.

use crate::backend::{BackendError, DemBackend, Reduce};

/// Every rank's `local` values, concatenated in rank order, on every rank.
pub fn all_gather(dem: &dyn DemBackend, local: &[f64]) -> Result<Vec<f64>, BackendError> {
    let ranks = dem.ranks();
    if ranks.size <= 1 {
        return Ok(local.to_vec());
    }
    let mut counts = vec![0.0; ranks.size];
    counts[ranks.rank] = local.len() as f64;
    dem.all_reduce(&mut counts, Reduce::Sum)?;
    let offset: usize = counts[..ranks.rank].iter().map(|&c| c as usize).sum();
    let total: usize = counts.iter().map(|&c| c as usize).sum();
    let mut all = vec![0.0; total];
    all[offset..offset + local.len()].copy_from_slice(local);
    dem.all_reduce(&mut all, Reduce::Sum)?;
    Ok(all)
}

/// [`all_gather`] of integers below 2⁵³ (grain ids, counts): exact through an f64.
pub fn all_gather_u64(dem: &dyn DemBackend, local: &[u64]) -> Result<Vec<u64>, BackendError> {
    let as_f64: Vec<f64> = local.iter().map(|&v| v as f64).collect();
    Ok(all_gather(dem, &as_f64)?
        .into_iter()
        .map(|v| v as u64)
        .collect())
}

/// Longest message a failing rank passes on (bytes; longer ones are cut).
const MESSAGE_BYTES: usize = 1024;

/// Agree on a failure: every rank passes its own (`Some(message)` when it failed) and
/// learns the first failing rank and its message, so all ranks stop at the same call
/// instead of the healthy ones waiting forever in the next collective.
pub fn first_failure(
    dem: &dyn DemBackend,
    local: Option<&str>,
) -> Result<Option<(usize, String)>, BackendError> {
    let ranks = dem.ranks();
    if ranks.size <= 1 {
        return Ok(local.map(|m| (0, m.to_string())));
    }
    let mut failed = vec![0.0; ranks.size];
    failed[ranks.rank] = local.is_some() as u8 as f64;
    dem.all_reduce(&mut failed, Reduce::Sum)?;
    let Some(first) = failed.iter().position(|&f| f > 0.0) else {
        return Ok(None);
    };
    let mut text = vec![0.0; MESSAGE_BYTES];
    if ranks.rank == first {
        let bytes = local.unwrap_or_default().as_bytes();
        for (t, &b) in text.iter_mut().zip(bytes) {
            *t = b as f64;
        }
    }
    dem.all_reduce(&mut text, Reduce::Sum)?;
    let bytes: Vec<u8> = text
        .iter()
        .map(|&b| b as u8)
        .take_while(|&b| b != 0)
        .collect();
    Ok(Some((first, String::from_utf8_lossy(&bytes).into_owned())))
}
