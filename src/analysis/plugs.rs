//! Plug statistics as seeds 000 §4.2 and 002 §3.2 define them: the tube cut into slices
//! (3.5 mm) sampled every 0.01 s, each grain counted by its exact volume inside a slice
//! (sphere–slab intersection); a plug is a connected run of slices with porosity < 0.6.
//! Plugs are followed from frame to frame, so their velocity comes from their motion.

use crate::{Real, Vec3};

/// Volume of a sphere of radius r centred at axial position c inside the slab [a, b], m³.
pub fn sphere_slab_volume(c: Real, r: Real, a: Real, b: Real) -> Real {
    let lo = (a - c).max(-r);
    let hi = (b - c).min(r);
    if hi <= lo {
        return 0.0;
    }
    let f = |z: Real| std::f64::consts::PI * (r * r * z - z * z * z / 3.0);
    f(hi) - f(lo)
}

/// Porosity and mean axial granular velocity of every slice of one frame.
#[derive(Debug, Clone)]
pub struct SliceFrame {
    /// Time of the frame, s.
    pub time: Real,
    /// Porosity per slice.
    pub porosity: Vec<Real>,
    /// Volume-weighted mean axial velocity per slice (0 where empty), m/s.
    pub velocity: Vec<Real>,
}

/// Slices of a tube.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct Slicer {
    /// Inlet centre, m.
    pub origin: Vec3,
    /// Unit axis.
    pub axis: Vec3,
    /// Cross-section area, m².
    pub area: Real,
    /// Slice length, m.
    pub slice: Real,
    /// Number of slices.
    pub count: usize,
}

impl Slicer {
    /// Slices of length `slice` over a tube of `length`.
    pub fn new(origin: Vec3, axis: Vec3, radius: Real, length: Real, slice: Real) -> Self {
        Self {
            origin,
            axis,
            area: std::f64::consts::PI * radius * radius,
            slice,
            count: (length / slice).floor().max(1.0) as usize,
        }
    }

    /// One frame from grain centres, velocities and radii.
    pub fn frame(&self, time: Real, x: &[Vec3], v: &[Vec3], r: &[Real]) -> SliceFrame {
        let n = self.count;
        let mut solid = vec![0.0; n];
        let mut momentum = vec![0.0; n];
        for i in 0..x.len() {
            let d = [
                x[i][0] - self.origin[0],
                x[i][1] - self.origin[1],
                x[i][2] - self.origin[2],
            ];
            let s = d[0] * self.axis[0] + d[1] * self.axis[1] + d[2] * self.axis[2];
            let vs = v[i][0] * self.axis[0] + v[i][1] * self.axis[1] + v[i][2] * self.axis[2];
            if s + r[i] <= 0.0 {
                continue;
            }
            let k0 = ((s - r[i]) / self.slice).floor().max(0.0) as usize;
            let k1 = (((s + r[i]) / self.slice).floor() as usize).min(n - 1);
            for k in k0..=k1 {
                let a = k as Real * self.slice;
                let vol = sphere_slab_volume(s, r[i], a, a + self.slice);
                solid[k] += vol;
                momentum[k] += vol * vs;
            }
        }
        let cell = self.area * self.slice;
        SliceFrame {
            time,
            porosity: solid.iter().map(|s| 1.0 - s / cell).collect(),
            velocity: solid
                .iter()
                .zip(&momentum)
                .map(|(s, m)| if *s > 0.0 { m / s } else { 0.0 })
                .collect(),
        }
    }
}

/// One plug in one frame.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct PlugObservation {
    /// Frame time, s.
    pub time: Real,
    /// Track the plug belongs to.
    pub track: u64,
    /// Volume-weighted centre along the axis, m.
    pub centre: Real,
    /// Length (slices × slice length), m.
    pub length: Real,
    /// Lowest slice porosity in the plug.
    pub min_porosity: Real,
    /// Largest slice granular velocity in the plug, m/s.
    pub max_velocity: Real,
    /// Grains in the plug (solid volume / mean grain volume).
    pub grains: Real,
    /// Velocity of the centre since the previous frame, m/s (None for a new track).
    pub velocity: Option<Real>,
}

/// Finds plugs in frames and follows them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct PlugTracker {
    /// Porosity below which a slice belongs to a plug (0.6 in the seeds).
    pub threshold: Real,
    slicer: Slicer,
    grain_volume: Real,
    previous: Vec<(u64, Real, Real, Real)>, // (track, centre, lo, hi)
    previous_time: Real,
    next_track: u64,
    /// Every plug seen, in frame order.
    pub observations: Vec<PlugObservation>,
}

impl PlugTracker {
    /// Tracker over the slices of `slicer`; `grain_volume` converts solid volume to grains.
    pub fn new(slicer: Slicer, grain_volume: Real) -> Self {
        Self {
            threshold: 0.6,
            slicer,
            grain_volume,
            previous: Vec::new(),
            previous_time: 0.0,
            next_track: 0,
            observations: Vec::new(),
        }
    }

    /// The slices the tracker works on.
    pub fn slicer(&self) -> Slicer {
        self.slicer
    }

    /// Find the plugs of a frame and link them to those of the previous frame: a plug
    /// continues the previous plug it overlaps most (after that one's own displacement
    /// bound of one plug length); otherwise it starts a new track.
    pub fn push(&mut self, f: &SliceFrame) {
        let h = self.slicer.slice;
        let cell = self.slicer.area * h;
        let mut plugs = Vec::new();
        let mut k = 0;
        let n = f.porosity.len();
        while k < n {
            if f.porosity[k] < self.threshold {
                let start = k;
                while k < n && f.porosity[k] < self.threshold {
                    k += 1;
                }
                plugs.push((start, k)); // slices start..k
            } else {
                k += 1;
            }
        }
        let dt = f.time - self.previous_time;
        let mut current = Vec::with_capacity(plugs.len());
        for (a, b) in plugs {
            let (mut solid, mut moment) = (0.0, 0.0);
            let mut min_phi: Real = 1.0;
            let mut max_v = Real::NEG_INFINITY;
            for k in a..b {
                let s = (1.0 - f.porosity[k]) * cell;
                solid += s;
                moment += s * (k as Real + 0.5) * h;
                min_phi = min_phi.min(f.porosity[k]);
                max_v = max_v.max(f.velocity[k]);
            }
            let centre = moment / solid;
            let (lo, hi) = (a as Real * h, b as Real * h);
            // Overlap with a previous plug, allowing it to have moved up to a plug length.
            let matched = self
                .previous
                .iter()
                .filter(|p| p.2 - (hi - lo) < hi && lo < p.3 + (hi - lo))
                .min_by(|p, q| {
                    (p.1 - centre)
                        .abs()
                        .partial_cmp(&(q.1 - centre).abs())
                        .expect("finite centres")
                })
                .copied();
            let (track, velocity) = match matched {
                Some(p) if dt > 0.0 => (p.0, Some((centre - p.1) / dt)),
                _ => {
                    self.next_track += 1;
                    (self.next_track, None)
                }
            };
            current.push((track, centre, lo, hi));
            self.observations.push(PlugObservation {
                time: f.time,
                track,
                centre,
                length: hi - lo,
                min_porosity: min_phi,
                max_velocity: max_v,
                grains: solid / self.grain_volume,
                velocity,
            });
        }
        // A track continues in at most one plug: keep the first, renumber later ones.
        let mut seen = std::collections::HashSet::new();
        let start = self.observations.len() - current.len();
        for (c, o) in current.iter_mut().zip(&mut self.observations[start..]) {
            if !seen.insert(c.0) {
                self.next_track += 1;
                c.0 = self.next_track;
                o.track = self.next_track;
                o.velocity = None;
            }
        }
        self.previous = current;
        self.previous_time = f.time;
    }
}

/// Median of a list (None when empty).
pub fn median(mut v: Vec<Real>) -> Option<Real> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.partial_cmp(b).expect("finite values"));
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

/// Plugs passing each height, as seed 000 fig. 9 counts them ("number of plugs per time as a
/// function of height"): a tracked plug passes z when its centre goes from below z to z or
/// above between two frames (upward along the axis, the conveying direction); each plug
/// counts once per height.
#[derive(Debug, Clone, PartialEq)]
pub struct PassageRates {
    /// Heights along the axis, m, and the plugs passing each per second.
    pub rates: Vec<[Real; 2]>,
    /// Relative change of the count from the lowest height to the highest, over the mean
    /// count: (n_top − n_bottom) / n̄.
    pub change: Real,
    /// Standard error of `change`. Between two neighbouring heights the count changes only
    /// by the plugs that end between them (merged into the next, or dissolved: D) and those
    /// that begin there (B): n_{k+1} − n_k = B_k − D_k exactly. Taking each of these events
    /// as a Poisson count, var(n_top − n_bottom) = Σ (B_k + D_k), an upper bound (a plug
    /// that begins and ends between the two ends counts twice and changes nothing).
    pub change_se: Real,
}

/// The passage rates through `heights` (m along the axis, ascending, at most 64) of the
/// plugs in `observations` (frame order) over `span` seconds; None with fewer than two
/// heights, an empty span or no passage at all (nothing measured).
pub fn passage_rates(
    observations: &[PlugObservation],
    heights: &[Real],
    span: Real,
) -> Option<PassageRates> {
    if heights.len() < 2 || heights.len() > 64 || span <= 0.0 {
        return None;
    }
    // Per track: its last centre and the heights it passed (one bit each).
    let mut tracks: std::collections::BTreeMap<u64, (Real, u64)> = Default::default();
    for o in observations {
        let entry = tracks.entry(o.track).or_insert((o.centre, 0));
        let prev = entry.0;
        for (k, &z) in heights.iter().enumerate() {
            if prev < z && o.centre >= z {
                entry.1 |= 1 << k;
            }
        }
        entry.0 = o.centre;
    }
    let m = heights.len();
    let passed = |k: usize| tracks.values().filter(|t| t.1 >> k & 1 == 1).count() as Real;
    let counts: Vec<Real> = (0..m).map(passed).collect();
    let mean_n = counts.iter().sum::<Real>() / m as Real;
    if mean_n <= 0.0 {
        return None;
    }
    // Births and deaths between neighbouring heights.
    let events: Real = (0..m - 1)
        .map(|k| {
            tracks
                .values()
                .filter(|t| (t.1 >> k & 1) != (t.1 >> (k + 1) & 1))
                .count() as Real
        })
        .sum();
    Some(PassageRates {
        rates: heights
            .iter()
            .zip(&counts)
            .map(|(&z, &n)| [z, n / span])
            .collect(),
        change: (counts[m - 1] - counts[0]) / mean_n,
        change_se: events.sqrt() / mean_n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(time: Real, track: u64, centre: Real) -> PlugObservation {
        PlugObservation {
            time,
            track,
            centre,
            length: 0.02,
            min_porosity: 0.47,
            max_velocity: 0.2,
            grains: 100.0,
            velocity: None,
        }
    }

    /// Four plugs enter at the bottom, two merge into others half-way (their tracks end at
    /// 0.25 m), a fifth begins at 0.35 m: the counts are 4, 4, 2, 3 and the events between
    /// neighbouring heights two deaths and one birth.
    #[test]
    fn passage_rates_count_each_plug_once_per_height() {
        let mut o = Vec::new();
        for k in 0..10 {
            let t = k as Real * 0.1;
            for track in 0..4u64 {
                let c = 0.05 * k as Real + 0.01 * track as Real;
                if track < 2 || c <= 0.25 {
                    o.push(obs(t, track, c));
                }
            }
            if k >= 7 {
                // Born at 0.35 m, passing 0.4 m once.
                o.push(obs(t, 9, 0.35 + 0.03 * (k - 7) as Real));
            }
        }
        // A plug that goes up through 0.1 m, back down and up again counts once there.
        for (k, c) in [0.05, 0.12, 0.08, 0.13].iter().enumerate() {
            o.push(obs(2.0 + k as Real * 0.1, 20, *c));
        }
        let heights = [0.1, 0.2, 0.3, 0.4];
        let r = passage_rates(&o, &heights, 2.0).unwrap();
        let rates: Vec<Real> = r.rates.iter().map(|x| x[1]).collect();
        assert_eq!(rates, vec![2.5, 2.0, 1.0, 1.5]);
        // Counts 5, 4, 2, 3 (mean 3.5): change (3 − 5) / 3.5; events 1 + 2 + 1 = 4.
        assert!((r.change + 2.0 / 3.5).abs() < 1e-12, "{}", r.change);
        assert!((r.change_se - 2.0 / 3.5).abs() < 1e-12, "{}", r.change_se);
        // A plug going down does not pass; nothing passing is not a rate of zero.
        let down = [obs(0.0, 7, 0.35), obs(0.1, 7, 0.15)];
        assert!(passage_rates(&down, &heights, 2.0).is_none());
        assert!(passage_rates(&o, &heights[..1], 2.0).is_none());
    }

    #[test]
    fn slab_volumes_add_up_to_the_sphere() {
        let r = 0.7e-3;
        let total: Real = (0..10)
            .map(|k| sphere_slab_volume(0.0012, r, k as Real * 3.5e-4, (k + 1) as Real * 3.5e-4))
            .sum();
        let sphere = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((total / sphere - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_plug_moving_at_constant_speed_is_tracked_with_its_speed() {
        // Synthetic frames: a block of slices at porosity 0.45 moving 0.2 m/s.
        let slicer = Slicer::new([0.0; 3], [0.0, 0.0, 1.0], 3.5e-3, 0.525, 3.5e-3);
        let mut t = PlugTracker::new(slicer, 1.0e-9);
        for step in 0..20 {
            let time = step as Real * 0.01;
            let mut porosity = vec![0.95; slicer.count];
            let start = 10 + (0.2 * time / 3.5e-3).round() as usize;
            for p in porosity.iter_mut().skip(start).take(8) {
                *p = 0.45;
            }
            t.push(&SliceFrame {
                time,
                velocity: vec![0.2; slicer.count],
                porosity,
            });
        }
        let v: Vec<Real> = t.observations.iter().filter_map(|o| o.velocity).collect();
        assert_eq!(t.observations.iter().map(|o| o.track).max(), Some(1));
        // Centres move in whole slices: the mean speed is exact, single frames ±0.35 m/s/2.
        let mean = v.iter().sum::<Real>() / v.len() as Real;
        assert!((mean - 0.2).abs() < 0.02, "mean {mean}");
        assert!((t.observations[0].length - 8.0 * 3.5e-3).abs() < 1e-12);
    }
}
