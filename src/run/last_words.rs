//! A run that its process cannot finish still leaves its summary. Two ways a process ends
//! without returning to the run: LIGGGHTS's `error->all` (an error in a user's input met at
//! run time, e.g. a thermo variable dividing by zero) prints `ERROR: …` and calls `exit(1)`
//! on every rank; under `mpirun`, a rank that dies outright (killed, or LIGGGHTS's
//! `error->one`, which calls `MPI_Abort`) makes mpirun end the others with SIGTERM, and a
//! survivor blocked in a collective call with the dead rank never reaches its next check.
//!
//! So the run keeps, at every sample, the summary it would write if it failed there (a
//! provisional one: what it computed up to that sample). An `atexit` hook writes it with the
//! engine's last words when the process exits inside the run; under MPI, the stop signal
//! writes it at once from the signal thread (every surviving rank holds the same
//! measurements; the first to write wins, and rank 0's orderly end, if it gets there,
//! replaces it). HDF5 closes `run.h5` on exit by its own hook, and it is flushed at every
//! sample, so what it holds stays readable.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

use crate::summary::Summary;

/// The run in progress in this process.
struct Armed {
    out_dir: PathBuf,
    /// The summary as it stood at the last sample.
    summary: Option<Summary>,
    /// Under MPI: this process's rank and the rank count.
    rank: usize,
    ranks: usize,
}

static ARMED: Mutex<Option<Armed>> = Mutex::new(None);
static HOOK: Once = Once::new();

/// From now until [`disarm`], an exit of this process writes the run's provisional summary.
/// Called before the engine is built, so that the hook runs after the engine's own (hooks
/// run last-registered first), which keeps the engine's logs in `out_dir`.
pub fn arm(out_dir: &Path, rank: usize, ranks: usize) {
    HOOK.call_once(|| {
        // SAFETY: registers a plain extern "C" function; it takes no lock it could wait on.
        unsafe {
            libc::atexit(on_exit);
        }
    });
    // An earlier run's dead rank speaks no more (a resumed run keeps its folder).
    if rank == 0 {
        if let Ok(entries) = std::fs::read_dir(out_dir) {
            for e in entries.flatten() {
                let name = e.file_name();
                let name = name.to_string_lossy();
                if name.starts_with("last_words_rank") && name.ends_with(".txt") {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
    }
    *lock() = Some(Armed {
        out_dir: out_dir.to_path_buf(),
        summary: None,
        rank,
        ranks,
    });
}

/// The summary to write if the process ends before the next sample.
pub fn update(summary: Summary) {
    if let Some(a) = lock().as_mut() {
        a.summary = Some(summary);
    }
}

/// The run ended in order (its own summary written, or its error returned): nothing to add.
pub fn disarm() {
    *lock() = None;
}

/// Disarms when dropped: at every return from the run, not at an exit inside it.
pub struct Disarm;

impl Drop for Disarm {
    fn drop(&mut self) {
        disarm();
    }
}

/// A stop signal under MPI: write the provisional summary now, as failed unless the run
/// then ends in order (see the module's note). Nothing on one process, where the orderly
/// stop is always reached.
pub fn on_stop_signal() {
    // (The signal handler runs on its own thread: it may wait for the run's brief update.)
    let guard = lock();
    let Some(a) = guard.as_ref().filter(|a| a.ranks > 1) else {
        return;
    };
    let why = match dead_ranks_words(&a.out_dir) {
        Some(words) => format!(
            "{words} (rank {} wrote this: mpirun ended every rank when that one aborted)",
            a.rank
        ),
        None => format!(
            "stopped by a signal on {} ranks (rank {} wrote this): mpirun ends every rank \
             with SIGTERM when one dies (its last words, if any, are in mpirun's output), or \
             the run was asked to stop and the ranks did not reach its end together",
            a.ranks, a.rank
        ),
    };
    write_failed(a, &why, a.rank != 0);
}

fn lock() -> std::sync::MutexGuard<'static, Option<Armed>> {
    ARMED.lock().unwrap_or_else(|p| p.into_inner())
}

extern "C" fn on_exit() {
    // (A panic must not unwind out of an atexit hook.)
    let _ = std::panic::catch_unwind(|| {
        let Ok(mut guard) = ARMED.try_lock() else {
            return;
        };
        let Some(a) = guard.take() else {
            return;
        };
        let words = dead_ranks_words(&a.out_dir)
            .or_else(|| engine_last_words(&a.out_dir))
            .unwrap_or_else(|| "no `ERROR` line in the engine's log".to_string());
        let why = format!("the engine ended the process ({words})");
        eprintln!(
            "error: the run did not finish: {why}; the summary holds the run up to its last sample"
        );
        // Under MPI every rank exits alike: rank 0 writes, and says it in the run's log.
        if a.rank == 0 {
            write_failed(&a, &why, false);
            let log = a.out_dir.join("log.plugflow");
            if let Ok(mut f) = std::fs::OpenOptions::new().append(true).open(log) {
                use std::io::Write;
                let _ = writeln!(f, "error: the run did not finish: {why}");
            }
        }
    });
}

/// The words a rank left before it aborted the job (the LIGGGHTS shim's `MPI_Abort`).
fn dead_ranks_words(out_dir: &Path) -> Option<String> {
    let mut words: Vec<String> = std::fs::read_dir(out_dir)
        .ok()?
        .filter_map(|e| {
            let e = e.ok()?;
            let name = e.file_name();
            let name = name.to_str()?;
            (name.starts_with("last_words_rank") && name.ends_with(".txt"))
                .then(|| std::fs::read_to_string(e.path()).ok())
                .flatten()
                .map(|t| t.trim().to_string())
        })
        .collect();
    words.sort();
    (!words.is_empty()).then(|| words.join("; "))
}

/// The engine's `ERROR` line in the logs it keeps beside the run's outputs.
fn engine_last_words(out_dir: &Path) -> Option<String> {
    ["log2.liggghts", "log.liggghts"].iter().find_map(|f| {
        // (Lossy: LIGGGHTS's last lines under MPI may hold stray bytes.)
        let bytes = std::fs::read(out_dir.join(f)).ok()?;
        let text = String::from_utf8_lossy(&bytes);
        text.lines()
            .rev()
            .find(|l| l.starts_with("ERROR"))
            .map(|l| l.trim().to_string())
    })
}

/// Write the provisional summary with status `failed: …`; `only_if_none` leaves a summary
/// another rank wrote (rename over it otherwise, so a reader never sees half a file).
fn write_failed(a: &Armed, why: &str, only_if_none: bool) {
    let Some(s) = &a.summary else {
        // No sample yet: nothing was measured; the run's log says what happened.
        return;
    };
    let mut s = s.clone();
    s.status = format!(
        "failed: {why}; the summary holds the run up to t = {} s",
        s.simulated_time_s
    );
    let Ok(text) = serde_json::to_string_pretty(&s) else {
        return;
    };
    let path = a.out_dir.join("summary.json");
    let tmp = a.out_dir.join(format!(".summary.json.{}", a.rank));
    if std::fs::write(&tmp, text).is_err() {
        return;
    }
    let _ = match only_if_none {
        true => std::fs::hard_link(&tmp, &path),
        false => std::fs::rename(&tmp, &path),
    };
    let _ = std::fs::remove_file(&tmp);
}
