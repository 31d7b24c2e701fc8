//! The subcommands of the `plugflow` command line, one file each, and what they share.

/// `println!` that does not panic: a failed write to standard output (a closed pipe, a full
/// disk: `plugflow validate … > /dev/full`) is remembered, and the command still finishes its
/// work and then exits 1 saying so (`println!` exits 101 with a panic).
macro_rules! say {
    () => {
        $crate::cli::say(format_args!(""))
    };
    ($($t:tt)*) => {
        $crate::cli::say(format_args!($($t)*))
    };
}

pub mod crosscheck;
pub mod run;
pub mod study;
pub mod sweep;
pub mod validate;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

/// Some write to standard output failed.
static STDOUT_FAILED: AtomicBool = AtomicBool::new(false);

/// One line to standard output (see `say!`).
pub fn say(line: std::fmt::Arguments<'_>) {
    use std::io::Write;
    if writeln!(std::io::stdout(), "{line}").is_err() {
        STDOUT_FAILED.store(true, Ordering::Relaxed);
    }
}

/// The command's exit code, made a failure when some of its output could not be written.
pub fn finish(code: ExitCode) -> ExitCode {
    use std::io::Write;
    let flushed = std::io::stdout().flush().is_ok();
    if STDOUT_FAILED.load(Ordering::Relaxed) || !flushed {
        eprintln!("error: could not write to standard output (closed or full)");
        return ExitCode::FAILURE;
    }
    code
}

/// The exit code of a command whose child runs were stopped by Ctrl-C or SIGTERM: 130
/// (as `plugflow run`), after its table of what finished was written.
pub fn stopped_or(code: ExitCode, what: &str) -> ExitCode {
    if plugflow::children::stop_requested() {
        eprintln!("interrupted: the running {what} were stopped; the table holds what finished");
        ExitCode::from(130)
    } else {
        code
    }
}

pub use plugflow::scene::Scene;

/// The scene with its overrides and a positive `--duration`, or exit code 2 after saying
/// what is wrong.
pub fn checked_scene(
    scene: &std::path::Path,
    set: &[String],
    duration: Option<f64>,
) -> Result<Scene, ExitCode> {
    if let Some(d) = duration {
        if !(d.is_finite() && d > 0.0) {
            eprintln!("error: --duration must be a positive number of seconds");
            return Err(ExitCode::from(2));
        }
    }
    // A scene passes with its own duration (so a short trial run of a long case is fine) or
    // with `--duration`'s (so `--set output.settling_time=…` may point past the scene's end
    // when the run goes that far); when neither passes, the error is the one for the run.
    let loaded = match (Scene::load(scene, set), duration) {
        (Ok(s), _) => Ok(s),
        (Err(e), None) => Err(e),
        (Err(_), Some(d)) => Scene::load(scene, &[set, &[format!("duration={d}")]].concat()),
    };
    loaded.map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

/// This executable, which sweeps, studies and crosschecks start once per variant.
pub fn plugflow_exe() -> Result<PathBuf, ExitCode> {
    std::env::current_exe().map_err(|e| {
        eprintln!("error: cannot find the plugflow executable: {e}");
        ExitCode::FAILURE
    })
}

/// Every `--vary PATH=V1,V2,…`, or exit code 2 after saying which is malformed.
pub fn parse_varies(vary: &[String]) -> Result<Vec<plugflow::sweep::Vary>, ExitCode> {
    vary.iter()
        .map(|v| plugflow::sweep::parse_vary(v))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| {
            eprintln!("error: {e}");
            ExitCode::from(2)
        })
}
