//! The child runs of `sweep`, `study` and `crosscheck`: a Ctrl-C or SIGTERM to the parent
//! reaches every running child, which stops as `plugflow run` does (outputs written), and the
//! parent waits for them and then writes the table of what finished, instead of dying and
//! leaving orphans that run on.

use std::process::{Child, ExitStatus};
use std::sync::atomic::Ordering;
use std::time::Duration;

use crate::run::INTERRUPT;

/// How often the parent looks at its children and at the stop flag.
pub const POLL: Duration = Duration::from_millis(50);

/// Make Ctrl-C and SIGTERM set the stop flag of this process (the parent of child runs).
/// Failing to install it only loses the orderly stop, so it is a warning.
pub fn install_stop_handler() {
    if let Err(e) = ctrlc::set_handler(|| INTERRUPT.store(true, Ordering::Relaxed)) {
        eprintln!("warning: no Ctrl-C handler ({e}); an interrupt will orphan the child runs");
    }
}

/// Whether a stop was asked for.
pub fn stop_requested() -> bool {
    INTERRUPT.load(Ordering::Relaxed)
}

/// Ask a child run to stop (SIGTERM: it ends at its next check, every 500 steps, with its
/// outputs written). A child that already exited is left alone.
pub fn ask_to_stop(child: &mut Child) {
    if let Ok(None) = child.try_wait() {
        // SAFETY: kill(2) on the pid of a child not yet reaped, so not reused.
        unsafe {
            libc::kill(child.id() as libc::pid_t, libc::SIGTERM);
        }
    }
}

/// Wait for one child, passing a stop on to it.
pub fn wait_passing_stop(child: &mut Child) -> std::io::Result<ExitStatus> {
    let mut asked = false;
    loop {
        if let Some(status) = child.try_wait()? {
            return Ok(status);
        }
        if !asked && stop_requested() {
            ask_to_stop(child);
            asked = true;
        }
        std::thread::sleep(POLL);
    }
}
