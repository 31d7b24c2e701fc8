//! A persistent team of worker threads for the DEM step, lent to the coupler's per-grain
//! stages (deposit, interpolation) by an engine that has one ([`crate::DemBackend::team`]).
//!
//! A DEM step of a few thousand grains lasts ~100 µs; waking a sleeping pool thread for each
//! of its parallel phases costs a good part of that (rayon measured 1.1–1.5× on two cores).
//! The team's workers live as long as the engine and spin between phases, so a phase starts
//! within a cache-line transfer; after ~10 ms without work they fall back to short sleeps.
//! Chunk `c` of a phase always runs on member `c` and the chunk boundaries are fixed between
//! neighbour builds, so results are bitwise reproducible for a given thread count.

use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicUsize, Ordering};

type Job<'a> = &'a (dyn Fn(usize) + Sync);

/// Shared control block of a team; the calling thread is member 0.
pub struct Team {
    members: usize,
    epoch: AtomicUsize,
    /// Written by the workers as they finish: on its own cache line, away from what they
    /// poll, so a finishing worker does not steal the line the others spin on.
    remaining: Padded<AtomicUsize>,
    /// Members taking part in the current job (the rest sit it out).
    active: AtomicUsize,
    job: AtomicPtr<()>,
    stop: AtomicBool,
    worker_panicked: AtomicBool,
}

impl Team {
    /// Control block for `members` threads (including the caller).
    pub fn new(members: usize) -> Self {
        Self {
            members: members.max(1),
            epoch: AtomicUsize::new(0),
            remaining: Padded(AtomicUsize::new(0)),
            active: AtomicUsize::new(0),
            job: AtomicPtr::new(std::ptr::null_mut()),
            stop: AtomicBool::new(false),
            worker_panicked: AtomicBool::new(false),
        }
    }

    /// Number of members (chunks per phase).
    pub fn members(&self) -> usize {
        self.members
    }

    /// Members worth using for `n` items when each should get at least `min_each` (below,
    /// the sync costs more than the share saves): 1 to [`Team::members`].
    pub fn members_for(&self, n: usize, min_each: usize) -> usize {
        self.members.min((n / min_each.max(1)).max(1))
    }

    /// Run `f(c)` for members c < `active` (the caller runs c = 0) and wait for them.
    pub fn run(&self, active: usize, f: &(dyn Fn(usize) + Sync)) {
        let active = active.clamp(1, self.members);
        if active == 1 {
            f(0);
            return;
        }
        let job: Job<'_> = f;
        // The workers read the job through this pointer only between the epoch bump below
        // and their decrement of `remaining`; we do not return (so `f` stays alive) until
        // `remaining` is zero.
        self.job
            .store(&job as *const Job<'_> as *mut (), Ordering::Relaxed);
        self.active.store(active, Ordering::Relaxed);
        self.remaining.store(active - 1, Ordering::Relaxed);
        self.epoch.fetch_add(1, Ordering::Release);
        // Even if our own chunk panics, the workers must be done with `f` before it dies.
        let own = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(0)));
        let mut spins = 0u32;
        while self.remaining.load(Ordering::Acquire) != 0 {
            spin(&mut spins);
        }
        if let Err(payload) = own {
            std::panic::resume_unwind(payload);
        }
        if self.worker_panicked.load(Ordering::Relaxed) {
            panic!("a DEM worker thread panicked");
        }
    }

    /// The loop of worker `member` (1..members); returns when [`Team::stop`] is called.
    pub fn work(&self, member: usize) {
        let mut seen = 0usize;
        let mut spins = 0u32;
        loop {
            let e = self.epoch.load(Ordering::Acquire);
            if e == seen {
                if self.stop.load(Ordering::Relaxed) {
                    return;
                }
                spin(&mut spins);
                continue;
            }
            seen = e;
            spins = 0;
            if member >= self.active.load(Ordering::Relaxed) {
                continue;
            }
            let ptr = self.job.load(Ordering::Relaxed) as *const Job<'_>;
            // SAFETY: `run` published a pointer to a live `&dyn Fn` before bumping the epoch
            // (Release, paired with our Acquire) and keeps it alive until we decrement
            // `remaining` below.
            let job: Job<'_> = unsafe { *ptr };
            if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(member))).is_err() {
                self.worker_panicked.store(true, Ordering::Relaxed);
            }
            self.remaining.fetch_sub(1, Ordering::Release);
        }
    }

    /// Let the workers return.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Spin politely: pause instructions first (2000 of them, ~40 µs: balanced chunks finish
/// within that of each other), then yield the core (a neighbour rebuild or the gas step runs
/// serially on member 0; on a busy machine the partner we wait for may need this core),
/// then, idle for long, sleep in 100 µs naps.
fn spin(spins: &mut u32) {
    *spins = spins.saturating_add(1);
    if *spins < 2_000 {
        std::hint::spin_loop();
    } else if *spins < 12_000 {
        std::thread::yield_now();
    } else {
        std::thread::sleep(std::time::Duration::from_micros(100));
    }
}

/// A value alone on its cache line (128 bytes: adjacent-line prefetch pairs lines).
#[repr(align(128))]
struct Padded<T>(T);

impl<T> std::ops::Deref for Padded<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

/// A team with its worker threads; dropping it stops and joins them.
pub struct TeamThreads {
    team: std::sync::Arc<Team>,
    handles: Vec<std::thread::JoinHandle<()>>,
}

impl TeamThreads {
    /// Start `members − 1` workers (none for one member).
    pub fn start(members: usize) -> Self {
        let team = std::sync::Arc::new(Team::new(members));
        let handles = (1..team.members())
            .map(|m| {
                let t = team.clone();
                std::thread::spawn(move || t.work(m))
            })
            .collect();
        Self { team, handles }
    }

    /// The control block.
    pub fn team(&self) -> std::sync::Arc<Team> {
        self.team.clone()
    }
}

impl Drop for TeamThreads {
    fn drop(&mut self) {
        self.team.stop();
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// Items [lo, hi) of member m when `members` share n items in equal contiguous ranges.
pub fn share(n: usize, members: usize, m: usize) -> (usize, usize) {
    (n * m / members, n * (m + 1) / members)
}

/// A raw view of a slice whose disjoint index ranges are handed to different members.
#[derive(Clone, Copy)]
pub struct Shared<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: a `Shared` is only turned into slices over disjoint ranges, one per member, while
// the owner of the underlying Vec waits in `Team::run`.
unsafe impl<T: Send> Sync for Shared<T> {}
unsafe impl<T: Send> Send for Shared<T> {}

impl<T> Shared<T> {
    /// View of `v` for the duration of one phase.
    pub fn new(v: &mut [T]) -> Self {
        Self {
            ptr: v.as_mut_ptr(),
            len: v.len(),
        }
    }

    /// The elements `lo..hi`.
    ///
    /// # Safety
    /// No two members may hold overlapping ranges at once, and the source slice must
    /// outlive the use (both hold inside one `Team::run`).
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn range(&self, lo: usize, hi: usize) -> &mut [T] {
        assert!(
            lo <= hi && hi <= self.len,
            "range {lo}..{hi} of {}",
            self.len
        );
        std::slice::from_raw_parts_mut(self.ptr.add(lo), hi - lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_member_runs_its_chunk_every_phase() {
        let team = Team::new(3);
        let mut data = vec![0u64; 30];
        std::thread::scope(|s| {
            for m in 1..3 {
                let t = &team;
                s.spawn(move || t.work(m));
            }
            for round in 0..1000u64 {
                let shared = Shared::new(&mut data);
                team.run(3, &|c| {
                    // SAFETY: chunks 0..10, 10..20, 20..30 are disjoint.
                    let part = unsafe { shared.range(10 * c, 10 * c + 10) };
                    for x in part.iter_mut() {
                        *x += round + c as u64;
                    }
                });
            }
            team.stop();
        });
        let per_round: u64 = (0..1000u64).sum();
        for (k, x) in data.iter().enumerate() {
            assert_eq!(*x, per_round + 1000 * (k as u64 / 10));
        }
    }
}
