//! Differential pressure transducers along the tube (seed 004's DP1): p(from) − p(to) at
//! every sample, from the gas's cross-section-mean pressure profile. Between node centres
//! the pressure is interpolated linearly; before the first centre it is held; past the
//! last it falls linearly to the outlet's p = 0.

use serde_json::{json, Value};

use crate::Real;

/// One transducer: its name and its two taps' positions along the axis, m.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PressureTap {
    pub name: String,
    pub from: Real,
    pub to: Real,
}

/// Gauge pressure at `s` along the axis from the profile at node centres `positions`
/// (tube `length`, outlet at p = 0), Pa.
pub fn pressure_at(positions: &[Real], profile: &[Real], length: Real, s: Real) -> Real {
    let n = positions.len().min(profile.len());
    if n == 0 {
        return 0.0;
    }
    if s <= positions[0] {
        return profile[0];
    }
    if s >= positions[n - 1] {
        let span = (length - positions[n - 1]).max(1e-300);
        return profile[n - 1] * ((length - s) / span).clamp(0.0, 1.0);
    }
    // positions are sorted, evenly spaced cell centres: find the bracketing pair.
    let k = positions.partition_point(|&x| x <= s).clamp(1, n - 1);
    let (x0, x1) = (positions[k - 1], positions[k]);
    let t = (s - x0) / (x1 - x0);
    profile[k - 1] * (1.0 - t) + profile[k] * t
}

/// The transducers' readings over a run.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct TapTrace {
    pub taps: Vec<PressureTap>,
    /// (time s, one reading per tap in Pa).
    pub rows: Vec<(Real, Vec<Real>)>,
}

impl TapTrace {
    pub fn new(taps: Vec<PressureTap>) -> Self {
        Self {
            taps,
            rows: Vec::new(),
        }
    }

    /// Read every transducer from a pressure profile at `time`.
    pub fn push(&mut self, time: Real, positions: &[Real], profile: &[Real], length: Real) {
        if self.taps.is_empty() {
            return;
        }
        let values = self
            .taps
            .iter()
            .map(|t| {
                pressure_at(positions, profile, length, t.from)
                    - pressure_at(positions, profile, length, t.to)
            })
            .collect();
        self.rows.push((time, values));
    }

    /// CSV: `time_s,<name>_pa,...`, one row per sample.
    pub fn csv(&self) -> String {
        let mut out = String::from("time_s");
        for t in &self.taps {
            out.push_str(&format!(",{}_pa", t.name));
        }
        out.push('\n');
        for (time, v) in &self.rows {
            out.push_str(&format!("{time:.5}"));
            for x in v {
                out.push_str(&format!(",{x:.3}"));
            }
            out.push('\n');
        }
        out
    }

    /// Per transducer after `settle` s: positions, max, min, mean, and the peaks' and
    /// troughs' medians (local extremes of the trace that stand out by `prominence` Pa).
    pub fn summary(&self, settle: Real, prominence: Real) -> Value {
        Value::Array(
            self.taps
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    let trace: Vec<Real> = self
                        .rows
                        .iter()
                        .filter(|r| r.0 >= settle)
                        .map(|r| r.1[k])
                        .collect();
                    let max = trace.iter().copied().fold(Real::NEG_INFINITY, Real::max);
                    let min = trace.iter().copied().fold(Real::INFINITY, Real::min);
                    let mean = trace.iter().sum::<Real>() / trace.len().max(1) as Real;
                    let (peaks, troughs) = extremes(&trace, prominence);
                    json!({
                        "name": t.name,
                        "from_m": t.from,
                        "to_m": t.to,
                        "max_pa": if trace.is_empty() { Value::Null } else { json!(max) },
                        "min_pa": if trace.is_empty() { Value::Null } else { json!(min) },
                        "mean_pa": mean,
                        "peaks": peaks.len(),
                        "peak_median_pa": median(peaks),
                        "trough_median_pa": median(troughs),
                    })
                })
                .collect(),
        )
    }
}

fn median(mut v: Vec<Real>) -> Value {
    if v.is_empty() {
        return Value::Null;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    json!(v[v.len() / 2])
}

/// Alternating peaks and troughs of a trace: a peak is a maximum that the trace falls below
/// by `prominence` on both sides before rising above it (a zig-zag filter), likewise troughs.
pub fn extremes(trace: &[Real], prominence: Real) -> (Vec<Real>, Vec<Real>) {
    let (mut peaks, mut troughs) = (Vec::new(), Vec::new());
    let Some(&first) = trace.first() else {
        return (peaks, troughs);
    };
    // +1 climbing towards a peak, −1 falling towards a trough, 0 undecided.
    let (mut dir, mut hi, mut lo) = (0i8, first, first);
    for &x in &trace[1..] {
        match dir {
            0 => {
                hi = hi.max(x);
                lo = lo.min(x);
                if x <= hi - prominence {
                    dir = -1;
                    lo = x;
                } else if x >= lo + prominence {
                    dir = 1;
                    hi = x;
                }
            }
            1 => {
                if x > hi {
                    hi = x;
                } else if x <= hi - prominence {
                    peaks.push(hi);
                    dir = -1;
                    lo = x;
                }
            }
            _ => {
                if x < lo {
                    lo = x;
                } else if x >= lo + prominence {
                    troughs.push(lo);
                    dir = 1;
                    hi = x;
                }
            }
        }
    }
    (peaks, troughs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pressure_between_centres_is_linear_and_falls_to_the_outlet() {
        let pos = [0.5, 1.5, 2.5];
        let p = [30.0, 20.0, 10.0];
        assert_eq!(pressure_at(&pos, &p, 3.0, 0.2), 30.0);
        assert!((pressure_at(&pos, &p, 3.0, 1.0) - 25.0).abs() < 1e-12);
        assert!((pressure_at(&pos, &p, 3.0, 2.75) - 5.0).abs() < 1e-12);
        assert_eq!(pressure_at(&pos, &p, 3.0, 3.0), 0.0);
    }

    #[test]
    fn zig_zag_finds_the_peaks_and_troughs_of_a_wave() {
        // Three periods of a sine of amplitude 10 about 15, with ripples of 0.5.
        let trace: Vec<Real> = (0..300)
            .map(|i| {
                let t = i as Real / 100.0;
                15.0 + 10.0 * (2.0 * std::f64::consts::PI * t).sin() + 0.5 * (40.0 * t).sin()
            })
            .collect();
        let (peaks, troughs) = extremes(&trace, 5.0);
        assert_eq!(peaks.len(), 3, "{peaks:?}");
        assert_eq!(troughs.len(), 3, "{troughs:?}");
        assert!(peaks.iter().all(|p| (p - 25.0).abs() < 0.6), "{peaks:?}");
        assert!(troughs.iter().all(|p| (p - 5.0).abs() < 0.6), "{troughs:?}");
    }
}
