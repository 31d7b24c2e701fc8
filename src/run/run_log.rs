//! `log.plugflow`: what a run said, kept in its output folder for batch runs (the checks
//! made before it started, plain progress lines, warnings, how it ended). Each line is
//! flushed as written, so `tail -f` follows a run and a killed run's log ends where it did.

use std::fs::File;
use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use crate::output::OutputError;

/// Wall time between two progress lines, in the log and (off a terminal) on stderr.
const PROGRESS_EVERY: Duration = Duration::from_secs(5);

/// The run's log file, and its progress lines on stderr when stderr is not a terminal
/// (a terminal gets the progress bar instead).
pub struct RunLog {
    path: String,
    /// None on a rank other than 0 of a run under MPI (rank 0 keeps the log).
    file: Option<File>,
    /// Progress lines go to stderr as well (asked for, and stderr is not a terminal).
    plain_progress: bool,
    last_progress: Option<Instant>,
    /// The simulated time of the last progress line.
    last_at: Option<f64>,
    /// The first line that could not be written (the run reports it at its end).
    failed: Option<OutputError>,
}

impl RunLog {
    /// A new `log.plugflow` in `dir` (an older run's is replaced), or, for a resumed run
    /// (`append`), the older run's log gone on.
    pub fn create(dir: &Path, progress: bool, append: bool) -> Result<Self, OutputError> {
        let path = dir.join("log.plugflow");
        let shown = path.display().to_string();
        let file = std::fs::OpenOptions::new()
            .create(true)
            .write(true)
            .append(append)
            .truncate(!append)
            .open(&path)
            .map_err(|e| OutputError::new(&shown, e))?;
        Ok(Self {
            path: shown,
            file: Some(file),
            plain_progress: progress && !std::io::stderr().is_terminal(),
            last_progress: None,
            last_at: None,
            failed: None,
        })
    }

    /// The log of a rank other than 0 under MPI: says nothing (rank 0 says it all).
    pub fn silent() -> Self {
        Self {
            path: String::new(),
            file: None,
            plain_progress: false,
            last_progress: None,
            last_at: None,
            failed: None,
        }
    }

    /// Whether the terminal shows a progress bar (progress asked for, stderr a terminal).
    pub fn wants_bar(progress: bool) -> bool {
        progress && std::io::stderr().is_terminal()
    }

    /// One line into the log.
    pub fn line(&mut self, text: &str) {
        let Some(file) = self.file.as_mut().filter(|_| self.failed.is_none()) else {
            return;
        };
        if let Err(e) = writeln!(file, "{text}").and_then(|_| file.flush()) {
            self.failed = Some(OutputError::new(&self.path, e));
        }
    }

    /// A progress line for simulated time `at`, at most every few seconds unless `now`
    /// (the first and last ones; never twice for one time: a one-sample run's first line
    /// is its last): into the log, and onto stderr off a terminal.
    pub fn progress(&mut self, at: f64, text: impl FnOnce() -> String, now: bool) {
        let due = now
            || self
                .last_progress
                .is_none_or(|t| t.elapsed() >= PROGRESS_EVERY);
        if !due || self.last_at == Some(at) {
            return;
        }
        self.last_progress = Some(Instant::now());
        self.last_at = Some(at);
        let text = text();
        if self.plain_progress {
            eprintln!("{text}");
        }
        self.line(&text);
    }

    /// The first write that failed, if any.
    pub fn take_failure(&mut self) -> Option<OutputError> {
        self.failed.take()
    }
}

/// `1h02m03s`, `4m05s`, `6s`: a duration for a progress line.
pub fn human_duration(seconds: f64) -> String {
    if !seconds.is_finite() || seconds < 0.0 {
        return "?".to_string();
    }
    let s = seconds.round() as u64;
    match (s / 3600, (s / 60) % 60, s % 60) {
        (0, 0, sec) => format!("{sec}s"),
        (0, m, sec) => format!("{m}m{sec:02}s"),
        (h, m, sec) => format!("{h}h{m:02}m{sec:02}s"),
    }
}

#[cfg(test)]
mod tests {
    use super::human_duration;

    #[test]
    fn durations_read_as_hours_minutes_seconds() {
        assert_eq!(human_duration(6.4), "6s");
        assert_eq!(human_duration(245.0), "4m05s");
        assert_eq!(human_duration(3723.0), "1h02m03s");
        assert_eq!(human_duration(f64::INFINITY), "?");
    }
    /// The end's progress line is not written again when the last sample's was for the
    /// same simulated time (a one-sample run printed its only line twice).
    #[test]
    fn one_line_per_simulated_time() {
        let dir = std::env::temp_dir().join(format!("plugflow-runlog-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut log = super::RunLog::create(&dir, false, false).unwrap();
        log.progress(0.01, || "t = 0.01 first".into(), true);
        log.progress(0.01, || "t = 0.01 again".into(), true);
        log.progress(0.02, || "t = 0.02".into(), true);
        drop(log);
        let text = std::fs::read_to_string(dir.join("log.plugflow")).unwrap();
        assert_eq!(text.lines().count(), 2, "{text}");
        assert!(text.contains("first") && !text.contains("again"), "{text}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
