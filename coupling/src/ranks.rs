//! Collectives over the ranks of an engine run under MPI, built on the one reduction the
//! ABI offers ([`DemBackend::all_reduce`]): a gather of variable-length pieces and the
//! agreement on a failure. With one rank each is the identity, at no cost.
//!
//! A gather through a sum: every rank writes its piece at its own offset of a zeroed
//! buffer and the buffer is summed over the ranks; x + 0 = x exactly, so the pieces arrive
//! bit for bit (a −0.0 arrives as +0.0). It moves the whole buffer on every rank, as an
//! all-gather does; it runs at samples and for the grains leaving, not at every exchange.

use crate::backend::{BackendError, DemBackend, Ranks, Reduce};

/// This process's rank and the rank count when an MPI launcher started it (OpenMPI's
/// `mpirun` sets `OMPI_COMM_WORLD_RANK`/`_SIZE`, MPICH's and Slurm's `PMI_RANK`/`PMI_SIZE`),
/// read from the environment: plugflow knows its rank before any engine starts, without
/// linking MPI. None without a launcher.
pub fn launcher() -> Option<Ranks> {
    let read = |k: &str| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
    };
    [
        ("OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"),
        ("PMI_RANK", "PMI_SIZE"),
    ]
    .into_iter()
    .find_map(|(rank, size)| match (read(rank), read(size)) {
        (Some(rank), Some(size)) if size >= 1 && rank < size => Some(Ranks { rank, size }),
        _ => None,
    })
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{ImplicitDrag, NewParticle, ParticleView, WallForce};
    use crate::Vec3;
    use std::sync::{Arc, Barrier, Mutex};

    /// Ranks as threads: an all-reduce through a shared buffer between two barriers (the
    /// sum in rank order, as a fixed reduction order gives).
    struct Hub {
        barrier: Barrier,
        parts: Mutex<Vec<Vec<f64>>>,
    }

    struct ThreadRank {
        ranks: Ranks,
        hub: Arc<Hub>,
    }

    impl DemBackend for ThreadRank {
        fn engine_name(&self) -> &str {
            "threads"
        }
        fn engine_version(&self) -> String {
            String::new()
        }
        fn time_step(&self) -> f64 {
            1.0
        }
        fn time(&self) -> f64 {
            0.0
        }
        fn step_count(&self) -> u64 {
            0
        }
        fn advance(&mut self, _: u64) -> Result<(), BackendError> {
            Ok(())
        }
        fn particles(&self) -> ParticleView<'_> {
            ParticleView {
                id: &[],
                position: &[],
                velocity: &[],
                angular_velocity: &[],
                radius: &[],
                mass: &[],
            }
        }
        fn set_fluid_forces(
            &mut self,
            _: &[Vec3],
            _: Option<ImplicitDrag<'_>>,
        ) -> Result<(), BackendError> {
            Ok(())
        }
        fn insert(&mut self, _: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
            Ok(Vec::new())
        }
        fn remove_past_outlet(&mut self) -> Result<f64, BackendError> {
            Ok(0.0)
        }
        fn wall_forces(&self) -> Vec<WallForce> {
            Vec::new()
        }
        fn stage_times(&self) -> Vec<(String, f64)> {
            Vec::new()
        }
        fn ranks(&self) -> Ranks {
            self.ranks
        }
        fn all_reduce(&self, data: &mut [f64], op: Reduce) -> Result<(), BackendError> {
            self.hub.parts.lock().unwrap()[self.ranks.rank] = data.to_vec();
            self.hub.barrier.wait();
            {
                let parts = self.hub.parts.lock().unwrap();
                for (k, v) in data.iter_mut().enumerate() {
                    let column = parts.iter().map(|p| p[k]);
                    *v = match op {
                        Reduce::Sum => column.sum(),
                        Reduce::Max => column.fold(f64::NEG_INFINITY, f64::max),
                    };
                }
            }
            self.hub.barrier.wait();
            Ok(())
        }
    }

    /// Run `body` on `size` thread-ranks; their results in rank order.
    fn on_ranks<T: Send + 'static>(
        size: usize,
        body: impl Fn(&ThreadRank) -> T + Send + Sync + 'static,
    ) -> Vec<T> {
        let hub = Arc::new(Hub {
            barrier: Barrier::new(size),
            parts: Mutex::new(vec![Vec::new(); size]),
        });
        let body = Arc::new(body);
        let handles: Vec<_> = (0..size)
            .map(|rank| {
                let (hub, body) = (hub.clone(), body.clone());
                std::thread::spawn(move || {
                    body(&ThreadRank {
                        ranks: Ranks { rank, size },
                        hub,
                    })
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    }

    #[test]
    fn a_gather_puts_every_rank_s_piece_in_rank_order_bit_for_bit() {
        // Rank r holds r + 1 values (rank 1 none at all: a rank may own no grain).
        let got = on_ranks(3, |me| {
            let r = me.ranks.rank;
            let local: Vec<f64> = match r {
                1 => Vec::new(),
                _ => (0..=r).map(|k| 0.1 * (r * 10 + k) as f64 + 1e-17).collect(),
                // (the same values as `value` below)
            };
            all_gather(me, &local).unwrap()
        });
        let value = |r: usize, k: usize| 0.1 * (r * 10 + k) as f64 + 1e-17;
        let want = [value(0, 0), value(2, 0), value(2, 1), value(2, 2)];
        for g in &got {
            assert_eq!(g.len(), 4);
            for (a, b) in g.iter().zip(&want) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
        }
        let ids = on_ranks(2, |me| {
            all_gather_u64(me, &[(1 << 52) + me.ranks.rank as u64]).unwrap()
        });
        assert_eq!(ids[0], vec![1 << 52, (1 << 52) + 1]);
        assert_eq!(ids[0], ids[1]);
    }

    #[test]
    fn a_failure_on_one_rank_is_every_rank_s_with_its_words() {
        let got = on_ranks(3, |me| {
            let mine = match me.ranks.rank {
                2 => Some("non-finite position of grain 17"),
                _ => None,
            };
            first_failure(me, mine).unwrap()
        });
        for g in got {
            assert_eq!(g, Some((2, "non-finite position of grain 17".to_string())));
        }
        // Two failing: the first rank's words; none failing: none.
        let got = on_ranks(2, |me| {
            first_failure(me, Some(&format!("rank {} broke", me.ranks.rank))).unwrap()
        });
        assert!(got
            .iter()
            .all(|g| g == &Some((0, "rank 0 broke".to_string()))));
        let got = on_ranks(2, |me| first_failure(me, None).unwrap());
        assert!(got.iter().all(|g| g.is_none()));
    }
}
