//! Coupling checks made before a run starts, in the manner of CFDEM's
//! `checkCouplingInterval`: whether the coupling interval Δt_c, the cell size and the grain
//! travel fit together ([`check_drag_relaxation`], [`check_cell_volume`], [`check_travel`]).
//! A refused check stops the run before its first step ([`first_refusal`]).

use crate::Real;

/// Outcome of one coupling check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Inside the limit.
    Ok,
    /// Outside the recommended limit: results lose accuracy.
    Warning,
    /// The run would be unstable: refused.
    Refused,
}

/// One coupling check: value, limit, verdict and what to change.
#[derive(Debug, Clone)]
pub struct CouplingCheck {
    pub name: &'static str,
    pub value: Real,
    pub limit: Real,
    pub verdict: Verdict,
    pub advice: String,
}

/// Coupling interval against the drag relaxation time τ of a grain in a dense plug: the
/// drag is held explicitly over Δt_c and overshoots beyond 2τ (refused); up to τ is fine.
pub fn check_drag_relaxation(tau: Real, phi: Real, interval: Real) -> CouplingCheck {
    let ratio = interval / tau;
    CouplingCheck {
        name: "coupling interval / drag relaxation time in a plug",
        value: ratio,
        limit: 1.0,
        verdict: if ratio <= 1.0 {
            Verdict::Ok
        } else if ratio <= 2.0 {
            Verdict::Warning
        } else {
            Verdict::Refused
        },
        advice: format!(
            "τ = {tau:.3e} s at φ = {phi}; the drag is held explicitly over Δt_c = \
             {interval:.3e} s and overshoots beyond 2τ: shorten coupling.interval to ≤ {tau:.3e} s"
        ),
    }
}

/// Smallest gas cell against the grain volume: below 3 grains per cell the deposited
/// porosity is dominated by single grains.
pub fn check_cell_volume(smallest_cell: Real, grain_volume: Real) -> CouplingCheck {
    let ratio = smallest_cell / grain_volume;
    CouplingCheck {
        name: "smallest gas cell volume / grain volume",
        value: ratio,
        limit: 3.0,
        verdict: if ratio >= 3.0 {
            Verdict::Ok
        } else {
            Verdict::Warning
        },
        advice: "below 3 grains per cell the deposited porosity is dominated by single grains: \
                 use fewer nodes (gas.grid)"
            .into(),
    }
}

/// Distance a grain at `speed` travels in one interval against the smallest cell size.
pub fn check_travel(speed: Real, interval: Real, cell: Real) -> CouplingCheck {
    let travel = speed * interval / cell;
    CouplingCheck {
        name: "grain travel per coupling interval / cell size",
        value: travel,
        limit: 0.1,
        verdict: if travel <= 0.1 {
            Verdict::Ok
        } else {
            Verdict::Warning
        },
        advice: format!(
            "at {speed} m/s (dem.max_impact_velocity) a grain crosses a tenth of a cell in \
             {:.3e} s: shorten coupling.interval",
            0.1 * cell / speed
        ),
    }
}

/// The first refused check, if any: the run must not start.
pub fn first_refusal(checks: &[CouplingCheck]) -> Option<&CouplingCheck> {
    checks.iter().find(|c| c.verdict == Verdict::Refused)
}
