//! The scene's inlet and open ends in engine-independent form: where new grains go and
//! which grains leave. The built-in engine calls these every few steps; the YADE shim calls
//! the same code between its engine's steps, so both feed and drain a tube alike.

use super::config::DemConfig;
use super::placement::{place, Region};
use super::vec3::{dot, norm2, scale, sub};
use crate::rng::Rng;
use crate::{Real, Vec3};

/// What becomes of a grain at the domain's edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Leave {
    /// It stays.
    Stay,
    /// It left through the open outlet (counted as mass outflow).
    Outlet,
    /// It left through the open inlet end or the box, or escaped the tube.
    Lost,
}

/// Where a grain of radius `r` at `x` goes.
pub fn leave_verdict(cfg: &DemConfig, x: Vec3, r: Real) -> Leave {
    match &cfg.tube {
        Some(t) => {
            let rel = sub(x, t.origin);
            let s = dot(rel, t.axis);
            let radial2 = norm2(sub(rel, scale(t.axis, s)));
            // A periodic section has no ends: along its axis grains only wrap around.
            let beyond_ends = !t.periodic && (s < -t.length || s > 2.0 * t.length);
            if t.outlet_open && s > t.length {
                Leave::Outlet
            } else if (t.inlet_open && s < 0.0)
                || radial2 > (t.radius + 2.0 * r).powi(2)
                || beyond_ends
            {
                Leave::Lost
            } else {
                Leave::Stay
            }
        }
        None => {
            if (0..3).any(|k| !cfg.periodic[k] && (x[k] < cfg.box_lo[k] || x[k] > cfg.box_hi[k])) {
                Leave::Lost
            } else {
                Leave::Stay
            }
        }
    }
}

/// How far a grain is from leaving, m: the distance from its centre to the nearest boundary
/// at which [`leave_verdict`] would remove it (≤ 0: it leaves). Every term is a distance to a
/// plane or to the axis, so the margin changes no faster than the grain moves: a grain whose
/// margin exceeds what it can move before the next look cannot have left by then.
pub fn leave_margin(cfg: &DemConfig, x: Vec3, r: Real) -> Real {
    match &cfg.tube {
        Some(t) => {
            let rel = sub(x, t.origin);
            let s = dot(rel, t.axis);
            let radial = norm2(sub(rel, scale(t.axis, s))).sqrt();
            let mut margin = t.radius + 2.0 * r - radial;
            if !t.periodic {
                margin = margin.min(s + t.length).min(2.0 * t.length - s);
            }
            if t.outlet_open {
                margin = margin.min(t.length - s);
            }
            if t.inlet_open {
                margin = margin.min(s);
            }
            margin
        }
        None => (0..3)
            .filter(|&k| !cfg.periodic[k])
            .map(|k| (x[k] - cfg.box_lo[k]).min(cfg.box_hi[k] - x[k]))
            .fold(Real::INFINITY, Real::min),
    }
}

/// A grain radius from the scene's size range, m.
pub fn draw_radius(cfg: &DemConfig, rng: &mut Rng) -> Real {
    if cfg.radius_max > cfg.radius_min {
        rng.range(cfg.radius_min, cfg.radius_max)
    } else {
        cfg.radius_min
    }
}

/// The inlet's bookkeeping: grains owed, time blocked, next placement attempt.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Feeder {
    /// Grains the inlet owes (rate × time − fed).
    pub backlog: Real,
    /// Simulated time during which the inlet slab was blocked with grains owed, s.
    pub blocked_time: Real,
    /// The slab was full: no new placement attempt before this time, s.
    retry_at: Real,
}

impl Feeder {
    /// The grains owed after `elapsed` more seconds (now `time`), placed in the free space
    /// of the inlet slab without overlapping `grains` (centre, radius) or each other;
    /// (centre, radius) of each, to be given the velocity [`Feeder::velocity`]. A slab
    /// packed full blocks the feed; the backlog carries over and the blocked time is counted.
    pub fn feed(
        &mut self,
        cfg: &DemConfig,
        time: Real,
        elapsed: Real,
        grains: impl Iterator<Item = (Vec3, Real)>,
        rng: &mut Rng,
    ) -> Vec<(Vec3, Real)> {
        let (Some(inlet), Some(tube)) = (cfg.inlet, cfg.tube) else {
            return Vec::new();
        };
        if inlet.until.is_some_and(|u| time > u) {
            return Vec::new();
        }
        self.backlog += inlet.rate * elapsed;
        let owed_much = |b: Real| b > 2.0 * inlet.batch_target as Real;
        if self.backlog < 1.0 || time < self.retry_at {
            if owed_much(self.backlog) {
                self.blocked_time += elapsed;
            }
            return Vec::new();
        }
        let reach = inlet.slab_length + 2.0 * cfg.radius_max;
        let existing: Vec<(Vec3, Real)> = grains
            .filter(|(x, r)| dot(sub(*x, tube.origin), tube.axis) - *r < reach)
            .collect();
        let want = (self.backlog.floor() as usize).min(inlet.batch_target);
        let radii: Vec<Real> = (0..want).map(|_| draw_radius(cfg, rng)).collect();
        let region = Region::TubeStretch {
            origin: tube.origin,
            axis: tube.axis,
            radius: tube.radius,
            slab_half: tube.slab_half,
            from: 0.0,
            to: inlet.slab_length,
        };
        let placed = place(&region, &radii, &existing, rng, 300);
        if placed.len() < want {
            // The slab is full: look again after the grains have had time to move
            // (a hundredth of the slab at the feed velocity, at least 1 ms).
            self.retry_at = time + (0.01 * inlet.slab_length / inlet.velocity).max(1e-3);
            if owed_much(self.backlog) {
                self.blocked_time += elapsed;
            }
        }
        self.backlog -= placed.len() as Real;
        placed.into_iter().zip(radii).collect()
    }

    /// Velocity of fed grains (along the tube at the feed speed), m/s.
    pub fn velocity(cfg: &DemConfig) -> Vec3 {
        match (cfg.inlet, cfg.tube) {
            (Some(i), Some(t)) => scale(t.axis, i.velocity),
            _ => [0.0; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// The margin is ≤ 0 exactly where a grain is removed, and it changes no faster than the
    /// grain moves (what lets the engine look only at grains near a boundary).
    #[test]
    fn leave_margin_is_negative_where_grains_leave_and_moves_with_them() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        for set in [vec![], vec!["tube.inlet_end=\"open\"".to_string()]] {
            let scene = Scene::load(&root.join("cases/vertical_plug.toml"), &set).unwrap();
            let cfg = crate::dem_config::dem_config(&scene).unwrap();
            let mut rng = Rng::new(7);
            let r = cfg.radius_max;
            for _ in 0..20_000 {
                let x: Vec3 = [
                    0.02 * (rng.uniform() - 0.5),
                    0.02 * (rng.uniform() - 0.5),
                    1.2 * rng.uniform() - 0.1,
                ];
                let m = leave_margin(&cfg, x, r);
                let leaves = !matches!(leave_verdict(&cfg, x, r), Leave::Stay);
                assert_eq!(m <= 0.0, leaves, "at {x:?}: margin {m}");
                let step: Vec3 = std::array::from_fn(|_| 1e-4 * (rng.uniform() - 0.5));
                let moved = leave_margin(&cfg, [x[0] + step[0], x[1] + step[1], x[2] + step[2]], r);
                assert!((moved - m).abs() <= norm2(step).sqrt() * (1.0 + 1e-9) + 1e-15);
            }
        }
    }
}
