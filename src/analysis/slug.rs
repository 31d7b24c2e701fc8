//! Slugs in a periodic section, measured as Lethe's dense pneumatic conveying example
//! measures them (its `pyvista_utilities.py`), so the numbers stand beside Lethe's:
//!
//! - the section is cut into slices one grain diameter long; each slice's porosity is
//!   1 − (solid volume in it)/(slice volume) (here the grains' exact volume inside each
//!   slice, where Lethe counts centres: the same after smoothing), smoothed by a moving
//!   average over 5 slices (periodic: Lethe pads its ends by hand);
//! - slices at or below porosity 0.55 are the slug; its front and rear are the inner edges
//!   of its end slices ("towards the centre": Lethe's convention, the length tends to be
//!   overestimated otherwise); with several runs of slug slices (Lethe assumes one), the
//!   longest is the slug;
//! - the grains between rear and front are the slug's grains; their velocity is the
//!   magnitude of their mean velocity vector (Lethe's, nearly its axial component);
//! - the slug velocity is the front's displacement, unwrapped across the seam, over ±3
//!   samples (Lethe's `sample_step = 3`), a central difference.

use crate::{Real, Vec3};
use serde::{Deserialize, Serialize};

use super::plugs::sphere_slab_volume;
pub use plugflow_model::summary::{MeanStd, SlugSummary};

/// Porosity at or below which a smoothed slice belongs to the slug (Lethe's 0.55).
pub const SLUG_POROSITY: Real = 0.55;
/// Slices in the moving average (Lethe's `period = 5`).
const SMOOTHING: usize = 5;
/// Samples on each side of the central difference of the front (Lethe's `sample_step`).
const STRIDE: usize = 3;

/// What one sample saw.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct SlugSample {
    pub time: Real,
    /// The front's position along the axis, unwrapped (the number of laps it made added),
    /// m; None: no slug.
    pub front: Option<Real>,
    /// Slug length, m.
    pub length: Option<Real>,
    /// Speed of the slug's grains (magnitude of their mean velocity), m/s.
    pub grain_velocity: Option<Real>,
    /// The gas's mean superficial velocity along the axis (∫ ε u dV / V), m/s.
    pub gas_velocity: Option<Real>,
}

/// The slug measurements of a run (kept whole in a checkpoint).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SlugTrace {
    origin: Vec3,
    axis: Vec3,
    length: Real,
    area: Real,
    /// Slices and their length, m.
    slices: usize,
    slice: Real,
    pub samples: Vec<SlugSample>,
    /// The last wrapped front and the laps counted, for unwrapping.
    last_front: Option<Real>,
    laps: i64,
}

impl SlugTrace {
    /// Slices one grain diameter (`grain_diameter`) long over a periodic section.
    pub fn new(origin: Vec3, axis: Vec3, radius: Real, length: Real, grain_diameter: Real) -> Self {
        let slices = ((length / grain_diameter).floor() as usize).max(SMOOTHING);
        Self {
            origin,
            axis,
            length,
            area: std::f64::consts::PI * radius * radius,
            slices,
            slice: length / slices as Real,
            samples: Vec::new(),
            last_front: None,
            laps: 0,
        }
    }

    /// Smoothed porosity of every slice from the grains' centres and radii.
    pub fn porosity(&self, x: &[Vec3], r: &[Real]) -> Vec<Real> {
        let n = self.slices;
        let mut solid = vec![0.0; n];
        for (xi, &ri) in x.iter().zip(r) {
            let s = self.wrapped(xi);
            let k0 = ((s - ri) / self.slice).floor() as i64;
            let k1 = ((s + ri) / self.slice).floor() as i64;
            for k in k0..=k1 {
                let a = k as Real * self.slice;
                solid[k.rem_euclid(n as i64) as usize] +=
                    sphere_slab_volume(s, ri, a, a + self.slice);
            }
        }
        let cell = self.area * self.slice;
        let raw: Vec<Real> = solid.iter().map(|v| 1.0 - v / cell).collect();
        let half = (SMOOTHING / 2) as i64;
        (0..n as i64)
            .map(|k| {
                (-half..=half)
                    .map(|o| raw[(k + o).rem_euclid(n as i64) as usize])
                    .sum::<Real>()
                    / SMOOTHING as Real
            })
            .collect()
    }

    /// Position of a grain along the axis, wrapped into [0, L), m.
    fn wrapped(&self, x: &Vec3) -> Real {
        let s: Real = (0..3).map(|k| (x[k] - self.origin[k]) * self.axis[k]).sum();
        s.rem_euclid(self.length)
    }

    /// The slug's (rear, front) positions in [0, L) (front < rear when it spans the seam),
    /// m; None without a slice in the slug or with every slice in it.
    pub fn find(&self, porosity: &[Real]) -> Option<(Real, Real)> {
        let n = porosity.len();
        let dense: Vec<bool> = porosity.iter().map(|&p| p <= SLUG_POROSITY).collect();
        // Runs of dense slices around the ring, from a slice that is not dense.
        let start = dense.iter().position(|d| !d)?;
        // (first slice, slices) of the longest run so far and of the current one.
        let mut best: Option<(usize, usize)> = None;
        let mut run: Option<(usize, usize)> = None;
        for o in 1..=n {
            let k = (start + o) % n;
            if dense[k] {
                run = Some(run.map_or((k, 1), |(first, len)| (first, len + 1)));
            } else if let Some(r) = run.take() {
                if best.is_none_or(|b| r.1 > b.1) {
                    best = Some(r);
                }
            }
        }
        let (first, len) = best?;
        let last = (first + len - 1) % n;
        // Inner edges of the end slices (Lethe's convention).
        let rear = (first + 1) as Real * self.slice;
        let front = last as Real * self.slice;
        Some((rear % self.length, front))
    }

    /// Measure one sample: the slug, its grains' speed, the gas's mean velocity.
    pub fn push(
        &mut self,
        time: Real,
        x: &[Vec3],
        v: &[Vec3],
        r: &[Real],
        gas_velocity: Option<Real>,
    ) {
        let found = self.find(&self.porosity(x, r));
        let (mut front, mut length, mut grain_velocity) = (None, None, None);
        if let Some((rear, f)) = found {
            let span = (f - rear).rem_euclid(self.length);
            let (mut sum, mut count) = ([0.0; 3], 0usize);
            for (xi, vi) in x.iter().zip(v) {
                if (self.wrapped(xi) - rear).rem_euclid(self.length) < span {
                    for k in 0..3 {
                        sum[k] += vi[k];
                    }
                    count += 1;
                }
            }
            if count > 0 {
                let m = sum.map(|c| c / count as Real);
                grain_velocity = Some((m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt());
            }
            // Unwrap: a front that jumps back by more than half the section went round.
            if let Some(last) = self.last_front {
                if f - last < -0.5 * self.length {
                    self.laps += 1;
                } else if f - last > 0.5 * self.length {
                    self.laps -= 1;
                }
            }
            self.last_front = Some(f);
            front = Some(f + self.laps as Real * self.length);
            length = Some(span);
        }
        self.samples.push(SlugSample {
            time,
            front,
            length,
            grain_velocity,
            gas_velocity,
        });
    }

    /// The slug velocity at each sample with a front ±STRIDE samples away, (time, m/s).
    pub fn slug_velocities(&self) -> Vec<(Real, Real)> {
        let s = &self.samples;
        (STRIDE..s.len().saturating_sub(STRIDE))
            .filter_map(|i| {
                let (a, b) = (&s[i - STRIDE], &s[i + STRIDE]);
                Some((s[i].time, (b.front? - a.front?) / (b.time - a.time)))
            })
            .collect()
    }

    /// Means and spreads over the samples from `from` on (None before any).
    pub fn summary(&self, from: Real, gravity: Real, diameter: Real) -> Option<SlugSummary> {
        let window: Vec<&SlugSample> = self.samples.iter().filter(|s| s.time >= from).collect();
        if window.is_empty() {
            return None;
        }
        let pick = |f: fn(&SlugSample) -> Option<Real>| -> Vec<Real> {
            window.iter().filter_map(|s| f(s)).collect()
        };
        let slug: Vec<Real> = self
            .slug_velocities()
            .into_iter()
            .filter(|(t, _)| *t >= from)
            .map(|(_, v)| v)
            .collect();
        let grains = MeanStd::of(&pick(|s| s.grain_velocity));
        Some(SlugSummary {
            samples: window.len(),
            slug_seen_fraction: pick(|s| s.front).len() as Real / window.len() as Real,
            slug_velocity_m_s: MeanStd::of(&slug),
            slug_grain_velocity_m_s: grains,
            slug_length_m: MeanStd::of(&pick(|s| s.length)),
            gas_mean_superficial_velocity_m_s: MeanStd::of(&pick(|s| s.gas_velocity)),
            lavrinec_slug_velocity_m_s: grains
                .map(|g| 0.967 * g.mean + 0.5 * (gravity * diameter).sqrt()),
        })
    }

    /// The samples as CSV (time, front, length, grains' speed, slug velocity, gas velocity).
    pub fn csv(&self) -> String {
        let slug: std::collections::HashMap<u64, Real> = self
            .slug_velocities()
            .into_iter()
            .map(|(t, v)| (t.to_bits(), v))
            .collect();
        let opt = |v: Option<Real>| v.map_or(String::new(), |v| format!("{v:.6}"));
        let mut out = String::from(
            "time_s,front_m,length_m,slug_grain_velocity_m_s,slug_velocity_m_s,gas_mean_superficial_velocity_m_s\n",
        );
        for s in &self.samples {
            out.push_str(&format!(
                "{:.6},{},{},{},{},{}\n",
                s.time,
                opt(s.front),
                opt(s.length),
                opt(s.grain_velocity),
                opt(slug.get(&s.time.to_bits()).copied()),
                opt(s.gas_velocity)
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A section 1 m long and 84 mm across with 5 mm slices (Lethe's case).
    fn trace() -> SlugTrace {
        SlugTrace::new([0.0; 3], [1.0, 0.0, 0.0], 0.042, 1.0, 0.005)
    }

    /// Every slice's solid is the grains' whole volume, also for a grain across the seam
    /// (smoothing keeps the sum): Σ (1 − ε_k) A Δs = Σ V to round-off.
    #[test]
    fn slices_hold_the_grains_volume_across_the_seam() {
        let t = trace();
        let x = [[0.999, 0.0, 0.0], [0.5012, 0.01, 0.0], [1.0021, 0.0, 0.01]];
        let r = [0.0025; 3];
        let solid: Real = t
            .porosity(&x, &r)
            .iter()
            .map(|p| (1.0 - p) * t.area * t.slice)
            .sum();
        let exact = 3.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.0025f64.powi(3);
        assert!((solid / exact - 1.0).abs() < 1e-12, "{solid} vs {exact}");
    }

    /// The slug is the longest run of dense slices; its ends are the inner edges of its
    /// end slices (Lethe's convention), also when it spans the seam.
    #[test]
    fn the_slug_is_the_longest_dense_run_with_lethes_edges() {
        let t = trace();
        let mut p = vec![0.9; 200];
        p[10..30].iter_mut().for_each(|v| *v = 0.4);
        p[100..104].iter_mut().for_each(|v| *v = 0.5);
        let (rear, front) = t.find(&p).unwrap();
        assert!((rear - 11.0 * 0.005).abs() < 1e-12 && (front - 29.0 * 0.005).abs() < 1e-12);
        let mut q = vec![0.9; 200];
        q[190..].iter_mut().for_each(|v| *v = 0.4);
        q[..10].iter_mut().for_each(|v| *v = 0.4);
        let (rear, front) = t.find(&q).unwrap();
        assert!((rear - 191.0 * 0.005).abs() < 1e-12 && (front - 9.0 * 0.005).abs() < 1e-12);
        assert!(t.find(&[0.9; 200]).is_none());
        assert!(t.find(&[0.4; 200]).is_none());
    }

    /// A block of grains (a cubic lattice of spacing d, 40 slices long, porosity 0.54 over
    /// the pipe's section) moving one slice per sample round the section: the unwrapped
    /// front gains a slice at every sample across the seam, so the slug velocity is the
    /// block's to round-off; its grains' speed is the block's; its length is the block's
    /// less Lethe's edges (the 5-slice smoothing of a 0.54 block is above 0.55 in two
    /// slices at each end, the inner-edge convention drops one more: 34 slices).
    #[test]
    fn a_block_going_round_has_its_velocity_length_and_speed() {
        let mut t = trace();
        let (d, dt) = (0.005, 0.005);
        let speed = d / dt;
        let mut grains = Vec::new();
        for i in 0..40 {
            for j in -7..=7 {
                for k in -7..=7 {
                    let (y, z) = (j as Real * d, k as Real * d);
                    if (y * y + z * z).sqrt() < 0.042 - 0.0025 {
                        grains.push([(i as Real + 0.5) * d, y, z]);
                    }
                }
            }
        }
        let r = vec![0.0025; grains.len()];
        let v = vec![[speed, 0.0, 0.0]; grains.len()];
        for step in 0..400 {
            let shift = step as Real * d + 0.9;
            let x: Vec<Vec3> = grains
                .iter()
                .map(|g| [(g[0] + shift).rem_euclid(1.0), g[1], g[2]])
                .collect();
            t.push(step as Real * dt, &x, &v, &r, Some(3.0));
        }
        let velocities = t.slug_velocities();
        assert_eq!(velocities.len(), 400 - 2 * STRIDE);
        for (time, u) in &velocities {
            assert!((u - speed).abs() < 1e-9 * speed, "t {time}: {u}");
        }
        let s = t.summary(0.0, 9.81, 0.084).unwrap();
        let length = s.slug_length_m.unwrap();
        assert!(
            (length.mean - 34.0 * d).abs() < 1e-9 && length.std < 1e-9,
            "{length:?}"
        );
        let grains_speed = s.slug_grain_velocity_m_s.unwrap();
        assert!((grains_speed.mean - speed).abs() < 1e-12);
        assert_eq!(s.slug_seen_fraction, 1.0);
        assert!((s.gas_mean_superficial_velocity_m_s.unwrap().mean - 3.0).abs() < 1e-15);
    }
}
