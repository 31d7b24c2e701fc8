//! Named stage timers: every stage of a step accumulates its wall time here so a run can
//! print where the time went (shared/DESIGN.md: "each stage is a named, timed stage").

use std::borrow::Cow;
use std::time::Instant;

/// Accumulated wall time per named stage, in the order the stages were first seen.
#[derive(Debug, Default, Clone)]
pub struct StageTimer {
    /// Stage names: the code's own, or read back from a checkpoint.
    names: Vec<Cow<'static, str>>,
    seconds: Vec<f64>,
}

impl StageTimer {
    /// An empty timer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add `seconds` to stage `name`.
    pub fn add(&mut self, name: &'static str, seconds: f64) {
        match self.names.iter().position(|n| *n == name) {
            Some(k) => self.seconds[k] += seconds,
            None => {
                self.names.push(Cow::Borrowed(name));
                self.seconds.push(seconds);
            }
        }
    }

    /// A timer holding `entries` (as [`StageTimer::entries`] gave them): a resumed run's
    /// stage times go on from the checkpoint's.
    pub fn from_entries(entries: &[(String, f64)]) -> Self {
        Self {
            names: entries.iter().map(|(n, _)| Cow::Owned(n.clone())).collect(),
            seconds: entries.iter().map(|(_, s)| *s).collect(),
        }
    }

    /// Time `f` as stage `name` and return its result.
    pub fn time<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(name, start.elapsed().as_secs_f64());
        out
    }

    /// (stage, seconds) pairs in first-seen order.
    pub fn entries(&self) -> Vec<(String, f64)> {
        self.names
            .iter()
            .map(|n| n.to_string())
            .zip(self.seconds.iter().copied())
            .collect()
    }

    /// Total of all stages, s.
    pub fn total(&self) -> f64 {
        self.seconds.iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accumulates_per_stage_in_first_seen_order() {
        let mut t = StageTimer::new();
        t.add("contacts", 1.0);
        t.add("integrate", 0.5);
        t.add("contacts", 2.0);
        let e = t.entries();
        assert_eq!(e[0], ("contacts".to_string(), 3.0));
        assert_eq!(e[1], ("integrate".to_string(), 0.5));
        assert_eq!(t.total(), 3.5);
    }
}
