//! Profiles averaged over plugs (seed 000 §4, seed 002 §5): along the tube relative to each
//! plug's centre (porosity, axial granular velocity, granular temperature, wall normal
//! stress, drag), radially inside plugs (rings 0.25 d wide in a section 1.5 d high around
//! the centre: the layering of seed 000 fig. 13, row V13), and across the tube for
//! horizontal conveying (porosity against height, inside slugs and between them: the
//! resting layer of row H9).
//!
//! Volumes inside rings and layers are measured by sampling each grain with a fixed set of
//! points spread evenly through the sphere (stratified in radius and direction), so a
//! grain cut by a ring boundary counts with the fraction inside it; the sampling error of
//! one grain's split is ~1/√N_points and averages out over the thousands of grains in a
//! profile.

use crate::analysis::plugs::{sphere_slab_volume, PlugObservation};
use crate::{Real, Vec3};

/// Points per grain for ring and layer volumes.
const POINTS: usize = 200;

/// Unit-ball points of equal volume share (radius by cube root, directions by a
/// Fibonacci spiral), the same for every grain.
fn ball_points() -> Vec<Vec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..POINTS)
        .map(|k| {
            let u = (k as Real + 0.5) / POINTS as Real;
            let rad = u.cbrt();
            // Direction: spiral index decorrelated from the radius index.
            let j = (k * 37) % POINTS;
            let z = 1.0 - 2.0 * (j as Real + 0.5) / POINTS as Real;
            let s = (1.0 - z * z).sqrt();
            let phi = golden * j as Real;
            [rad * s * phi.cos(), rad * s * phi.sin(), rad * z]
        })
        .collect()
}

/// The elastic normal force of a grain pressed δ into the tube wall, which turns the grains'
/// overlaps with the wall into the wall normal stress profile (the dashpot is left out: the
/// profile is dominated by grains resting on the wall).
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub enum WallSpring {
    /// F = k_n δ (Hooke), k_n of the grain–wall pair, N/m.
    Linear { kn: Real },
    /// F = 4/3 Y* √(r δ) δ (Hertz against a flat wall: r* = r), Y* in Pa.
    Hertz { y_star: Real },
}

impl WallSpring {
    /// Force of a grain of radius `r` overlapping the wall by `overlap` ≥ 0, N.
    pub fn force(&self, r: Real, overlap: Real) -> Real {
        match *self {
            WallSpring::Linear { kn } => kn * overlap,
            WallSpring::Hertz { y_star } => 4.0 / 3.0 * y_star * (r * overlap).sqrt() * overlap,
        }
    }
}

/// Which plugs enter the profiles.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct PlugWindow {
    /// Plug length range, m.
    pub length: (Real, Real),
    /// Tracked plug velocity range, m/s (plugs not yet tracked are left out).
    pub velocity: (Real, Real),
    /// Plug centre range along the tube as fractions of its length (mid tube).
    pub centre: (Real, Real),
}

impl Default for PlugWindow {
    fn default() -> Self {
        Self {
            length: (0.01, 0.06),
            velocity: (0.0, 1.0),
            centre: (0.4, 0.6),
        }
    }
}

/// The tube in the frame of the profiles.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct TubeFrame {
    pub origin: Vec3,
    pub axis: Vec3,
    /// Unit vector "up" across the tube (against gravity's cross-axis part), for the
    /// cross-section porosity of horizontal tubes.
    pub up: Vec3,
    pub radius: Real,
    pub length: Real,
}

/// Accumulated profiles.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Profiles {
    pub window: PlugWindow,
    tube: TubeFrame,
    diameter: Real,
    /// Grain–wall normal stiffness for the wall stress estimate, N/m.
    wall: WallSpring,
    points: Vec<Vec3>,
    /// Axial bin width, m, and half range, m.
    pub axial_bin: Real,
    pub axial_half: Real,
    // Axial sums per bin.
    solid: Vec<Real>,
    momentum: Vec<Real>,
    sq: Vec<Real>,
    wall_force: Vec<Real>,
    drag: Vec<Real>,
    particle_force: Vec<Real>,
    /// Contact forces were given with the frames.
    has_particle_force: bool,
    /// Plug-frames entered.
    pub plugs_used: u64,
    // Radial sums per ring.
    ring_solid: Vec<Real>,
    // Cross-section sums per layer: inside plugs, between plugs.
    layer_solid_plug: Vec<Real>,
    layer_solid_gap: Vec<Real>,
    layer_len_plug: Real,
    layer_len_gap: Real,
    layer_edges: Vec<Real>,
    /// Volume-weighted axial velocity sums per layer inside plugs (seed 002 fig. 19: the
    /// layers of a slug shear, the upper ones fastest). Not in the fixed part of a
    /// checkpoint: it travels in its extension ([`Profiles::layer_momentum`]), so a
    /// checkpoint written before it still resumes (counted from the resume on).
    #[serde(skip)]
    layer_momentum_plug: Vec<Real>,
}

/// Finished profiles (means), ready for output.
#[derive(Debug, Clone, Default)]
pub struct ProfileResult {
    /// Axial positions relative to the plug centre (bin centres), m.
    pub xi: Vec<Real>,
    pub porosity: Vec<Real>,
    /// Volume-weighted axial granular velocity, m/s.
    pub velocity: Vec<Real>,
    /// Granular temperature ⟨(v_z − ⟨v_z⟩)²⟩ along the axis, m²/s².
    pub temperature: Vec<Real>,
    /// Wall normal stress from the grains' elastic overlap with the tube, Pa.
    pub wall_stress: Vec<Real>,
    /// Axial drag per volume of tube, N/m³.
    pub drag: Vec<Real>,
    /// Axial contact force (grain–grain and wall) per volume of tube, N/m³: what the grains
    /// pass on to each other and the wall, beside the drag that drives them (empty when the
    /// engine does not expose per-grain contact forces).
    pub particle_force: Vec<Real>,
    /// Ring centres r/d and porosity in each ring (section 1.5 d high around plug centres).
    pub ring_r_over_d: Vec<Real>,
    pub ring_porosity: Vec<Real>,
    /// Layer centres (height across the tube / d, from the bottom) and porosity inside
    /// plugs and between them.
    pub layer_h_over_d: Vec<Real>,
    pub layer_porosity_plug: Vec<Real>,
    pub layer_porosity_gap: Vec<Real>,
    /// Volume-weighted axial granular velocity in each layer inside plugs, m/s (NaN: no
    /// grain there).
    pub layer_velocity_plug: Vec<Real>,
    /// Mean axial velocity of the grains in the upper half of the plugs' cross-section over
    /// that of the lower half (row H10: above 1 when the upper layers are faster).
    pub upper_over_lower_velocity_plug: Real,
    pub plugs_used: u64,
}

fn dot(a: Vec3, b: Vec3) -> Real {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Profiles {
    /// Profiles for grains of diameter `diameter` in `tube`.
    pub fn new(tube: TubeFrame, diameter: Real, wall: WallSpring, window: PlugWindow) -> Self {
        let axial_bin: Real = 1.75e-3;
        let axial_half: Real = 0.04;
        let nb = (2.0 * axial_half / axial_bin).round() as usize;
        let rings = (tube.radius / (0.25 * diameter)).ceil() as usize;
        let layers = (2.0 * tube.radius / (0.25 * diameter)).ceil() as usize;
        let layer_edges = (0..=layers)
            .map(|k| -tube.radius + k as Real * 2.0 * tube.radius / layers as Real)
            .collect();
        Self {
            window,
            tube,
            diameter,
            wall,
            points: ball_points(),
            axial_bin,
            axial_half,
            solid: vec![0.0; nb],
            momentum: vec![0.0; nb],
            sq: vec![0.0; nb],
            wall_force: vec![0.0; nb],
            drag: vec![0.0; nb],
            particle_force: vec![0.0; nb],
            has_particle_force: false,
            plugs_used: 0,
            ring_solid: vec![0.0; rings],
            layer_solid_plug: vec![0.0; layers],
            layer_solid_gap: vec![0.0; layers],
            layer_len_plug: 0.0,
            layer_len_gap: 0.0,
            layer_edges,
            layer_momentum_plug: vec![0.0; layers],
        }
    }

    /// The layer velocity sums, for a checkpoint's extension.
    pub fn layer_momentum(&self) -> &[Real] {
        &self.layer_momentum_plug
    }

    /// Take back the sums [`Profiles::layer_momentum`] gave (a checkpoint's extension).
    pub fn set_layer_momentum(&mut self, sums: Vec<Real>) {
        if sums.len() == self.layer_solid_plug.len() {
            self.layer_momentum_plug = sums;
        }
    }

    fn selected(&self, p: &PlugObservation) -> bool {
        let w = &self.window;
        let c = p.centre / self.tube.length;
        c >= w.centre.0
            && c <= w.centre.1
            && p.length >= w.length.0
            && p.length <= w.length.1
            && p.velocity
                .is_some_and(|v| v >= w.velocity.0 && v <= w.velocity.1)
    }

    /// Add one frame: the grains (centre, velocity, radius, axial fluid force) and the plugs
    /// observed in it (all of them: the cross-section profile needs to know where plugs
    /// are, the axial and radial ones use the selected).
    pub fn add_frame(
        &mut self,
        x: &[Vec3],
        v: &[Vec3],
        r: &[Real],
        fluid_axial: Option<&[Real]>,
        contact_axial: Option<&[Real]>,
        plugs: &[PlugObservation],
    ) {
        if contact_axial.is_some() {
            self.has_particle_force = true;
        }
        let t = self.tube;
        let (e1, e2) = plugflow_coupling::grid::perpendicular_basis(t.axis);
        // Axial position, cross-section coordinates of every grain.
        let s: Vec<Real> = x
            .iter()
            .map(|p| {
                dot(
                    [p[0] - t.origin[0], p[1] - t.origin[1], p[2] - t.origin[2]],
                    t.axis,
                )
            })
            .collect();
        let cross = |p: &Vec3| {
            let d = [p[0] - t.origin[0], p[1] - t.origin[1], p[2] - t.origin[2]];
            (dot(d, e1), dot(d, e2), dot(d, t.up))
        };
        let nb = self.solid.len();
        let chosen: Vec<PlugObservation> =
            plugs.iter().filter(|p| self.selected(p)).copied().collect();
        for p in &chosen {
            self.plugs_used += 1;
            // Mean axial velocity of the plug's grains (for the temperature).
            let (mut m0, mut m1) = (0.0, 0.0);
            for i in 0..x.len() {
                if (s[i] - p.centre).abs() <= 0.5 * p.length {
                    let vol = r[i].powi(3);
                    m0 += vol;
                    m1 += vol * dot(v[i], t.axis);
                }
            }
            let v_plug = if m0 > 0.0 { m1 / m0 } else { 0.0 };
            for i in 0..x.len() {
                let xi = s[i] - p.centre;
                if xi.abs() > self.axial_half + r[i] {
                    continue;
                }
                let vz = dot(v[i], t.axis);
                let k0 = (((xi - r[i]) + self.axial_half) / self.axial_bin)
                    .floor()
                    .max(0.0) as usize;
                let k1 = ((((xi + r[i]) + self.axial_half) / self.axial_bin).floor() as usize)
                    .min(nb - 1);
                let (a, b, _) = cross(&x[i]);
                let rho = (a * a + b * b).sqrt();
                let overlap = (rho + r[i] - t.radius).max(0.0);
                let kc = ((xi + self.axial_half) / self.axial_bin).floor();
                for k in k0..=k1 {
                    let lo = -self.axial_half + k as Real * self.axial_bin;
                    let vol = sphere_slab_volume(xi, r[i], lo, lo + self.axial_bin);
                    self.solid[k] += vol;
                    self.momentum[k] += vol * vz;
                    self.sq[k] += vol * (vz - v_plug) * (vz - v_plug);
                }
                if kc >= 0.0 && (kc as usize) < nb {
                    let kc = kc as usize;
                    self.wall_force[kc] += self.wall.force(r[i], overlap);
                    if let Some(f) = fluid_axial {
                        self.drag[kc] += f[i];
                    }
                    if let Some(c) = contact_axial {
                        self.particle_force[kc] += c[i];
                    }
                }
                // Rings: the section 1.5 d high around the centre.
                let half = 0.75 * self.diameter;
                if xi.abs() <= half + r[i] {
                    let ring_w = 0.25 * self.diameter;
                    for q in &self.points {
                        let pz = xi + r[i] * dot(*q, t.axis);
                        if pz.abs() > half {
                            continue;
                        }
                        let pa = a + r[i] * dot(*q, e1);
                        let pb = b + r[i] * dot(*q, e2);
                        let k = ((pa * pa + pb * pb).sqrt() / ring_w) as usize;
                        if k < self.ring_solid.len() {
                            self.ring_solid[k] += 1.0;
                        }
                    }
                }
            }
        }
        // Cross-section layers over the middle 60 % of the tube, split into plug and gap.
        let (lo, hi) = (0.2 * t.length, 0.8 * t.length);
        let in_plug = |z: Real| plugs.iter().any(|p| (z - p.centre).abs() <= 0.5 * p.length);
        // Length of the middle section inside plugs (sampled on a fine axial grid).
        let n_z = 400;
        let dz = (hi - lo) / n_z as Real;
        let plug_len = (0..n_z)
            .filter(|k| in_plug(lo + (*k as Real + 0.5) * dz))
            .count() as Real
            * dz;
        self.layer_len_plug += plug_len;
        self.layer_len_gap += (hi - lo) - plug_len;
        let nl = self.layer_solid_plug.len();
        // (A checkpoint from before the layer velocities: counted from here on.)
        self.layer_momentum_plug.resize(nl, 0.0);
        let h = 2.0 * t.radius / nl as Real;
        for i in 0..x.len() {
            if s[i] < lo - r[i] || s[i] > hi + r[i] {
                continue;
            }
            let (_, _, up) = cross(&x[i]);
            let vz = dot(v[i], t.axis);
            let share = 1.0 / POINTS as Real;
            for q in &self.points {
                let pz = s[i] + r[i] * dot(*q, t.axis);
                if pz < lo || pz > hi {
                    continue;
                }
                let py = up + r[i] * dot(*q, t.up);
                let k = ((py + t.radius) / h).floor();
                if k < 0.0 || k as usize >= nl {
                    continue;
                }
                let vol = share * 4.0 / 3.0 * std::f64::consts::PI * r[i].powi(3);
                if in_plug(pz) {
                    self.layer_solid_plug[k as usize] += vol;
                    self.layer_momentum_plug[k as usize] += vol * vz;
                } else {
                    self.layer_solid_gap[k as usize] += vol;
                }
            }
        }
    }

    /// Means over everything added.
    pub fn result(&self) -> ProfileResult {
        let t = self.tube;
        let n = self.plugs_used.max(1) as Real;
        let nb = self.solid.len();
        let bin_volume = std::f64::consts::PI * t.radius * t.radius * self.axial_bin;
        let wall_area = 2.0 * std::f64::consts::PI * t.radius * self.axial_bin;
        let xi = (0..nb)
            .map(|k| -self.axial_half + (k as Real + 0.5) * self.axial_bin)
            .collect();
        let per = |v: &[Real], k: usize| {
            if self.solid[k] > 0.0 {
                v[k] / self.solid[k]
            } else {
                0.0
            }
        };
        // Rings: sampled points → volume share of the ring's annulus × section height.
        let ring_w = 0.25 * self.diameter;
        let grain_volume = std::f64::consts::PI / 6.0 * self.diameter.powi(3);
        let section = 1.5 * self.diameter;
        let rings = self.ring_solid.len();
        let ring_porosity = (0..rings)
            .map(|k| {
                let r0 = k as Real * ring_w;
                let r1 = ((k + 1) as Real * ring_w).min(t.radius);
                let area = std::f64::consts::PI * (r1 * r1 - r0 * r0);
                let solid = self.ring_solid[k] / POINTS as Real * grain_volume / n;
                1.0 - solid / (area * section)
            })
            .collect();
        // Layers: chord areas.
        let nl = self.layer_solid_plug.len();
        let chord = |y: Real| {
            // Area of the disc below height y (from the centre), radius R.
            let rr = t.radius;
            let y = y.clamp(-rr, rr);
            rr * rr * (y / rr).acos().mul_add(-1.0, std::f64::consts::PI)
                + y * (rr * rr - y * y).sqrt()
        };
        let layer_area: Vec<Real> = (0..nl)
            .map(|k| chord(self.layer_edges[k + 1]) - chord(self.layer_edges[k]))
            .collect();
        let porosity_of = |solid: &[Real], len: Real| -> Vec<Real> {
            (0..nl)
                .map(|k| {
                    if len > 0.0 && layer_area[k] > 0.0 {
                        1.0 - solid[k] / (layer_area[k] * len)
                    } else {
                        Real::NAN
                    }
                })
                .collect()
        };
        ProfileResult {
            xi,
            porosity: (0..nb)
                .map(|k| 1.0 - self.solid[k] / n / bin_volume)
                .collect(),
            velocity: (0..nb).map(|k| per(&self.momentum, k)).collect(),
            temperature: (0..nb).map(|k| per(&self.sq, k)).collect(),
            wall_stress: (0..nb)
                .map(|k| self.wall_force[k] / n / wall_area)
                .collect(),
            drag: (0..nb).map(|k| self.drag[k] / n / bin_volume).collect(),
            particle_force: if self.has_particle_force {
                (0..nb)
                    .map(|k| self.particle_force[k] / n / bin_volume)
                    .collect()
            } else {
                Vec::new()
            },
            ring_r_over_d: (0..rings).map(|k| (k as Real + 0.5) * 0.25).collect(),
            ring_porosity,
            layer_h_over_d: (0..nl)
                .map(|k| {
                    (0.5 * (self.layer_edges[k] + self.layer_edges[k + 1]) + t.radius)
                        / self.diameter
                })
                .collect(),
            layer_porosity_plug: porosity_of(&self.layer_solid_plug, self.layer_len_plug),
            layer_porosity_gap: porosity_of(&self.layer_solid_gap, self.layer_len_gap),
            layer_velocity_plug: (0..nl)
                .map(|k| match self.layer_solid_plug[k] > 0.0 {
                    true => {
                        self.layer_momentum_plug
                            .get(k)
                            .copied()
                            .unwrap_or(Real::NAN)
                            / self.layer_solid_plug[k]
                    }
                    false => Real::NAN,
                })
                .collect(),
            upper_over_lower_velocity_plug: {
                // Layers split at the axis (their edges are symmetric about it).
                let half = |range: std::ops::Range<usize>| {
                    let solid: Real = range.clone().map(|k| self.layer_solid_plug[k]).sum();
                    let momentum: Real = range
                        .map(|k| self.layer_momentum_plug.get(k).copied().unwrap_or(0.0))
                        .sum();
                    momentum / solid
                };
                half(nl / 2..nl) / half(0..nl / 2)
            },
            plugs_used: self.plugs_used,
        }
    }
}

/// Interior local minima of a profile (index), ignoring NaN.
pub fn local_minima(v: &[Real]) -> Vec<usize> {
    (1..v.len().saturating_sub(1))
        .filter(|&k| v[k].is_finite() && v[k] < v[k - 1] && v[k] <= v[k + 1])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sampled points split a sphere between two half-spaces like the exact cap
    /// volume (sphere–slab formula), within the stratified sampling error.
    #[test]
    fn ball_points_measure_caps() {
        let pts = ball_points();
        for cut in [-0.8, -0.3, 0.0, 0.25, 0.6] {
            let inside = pts.iter().filter(|p| p[2] < cut).count() as Real / POINTS as Real;
            let exact =
                sphere_slab_volume(0.0, 1.0, -2.0, cut) / (4.0 / 3.0 * std::f64::consts::PI);
            assert!(
                (inside - exact).abs() < 0.02,
                "cut {cut}: {inside} vs {exact}"
            );
        }
        // And along x, y too (directions spread evenly).
        for d in 0..2 {
            let inside = pts.iter().filter(|p| p[d] < 0.3).count() as Real / POINTS as Real;
            let exact =
                sphere_slab_volume(0.0, 1.0, -2.0, 0.3) / (4.0 / 3.0 * std::f64::consts::PI);
            assert!(
                (inside - exact).abs() < 0.03,
                "axis {d}: {inside} vs {exact}"
            );
        }
    }

    /// A tube packed with grains on a lattice at the axis only: the ring profile shows
    /// solid at r/d < 0.5 and none beyond; the layer profile is symmetric.
    #[test]
    fn rings_see_an_axial_column() {
        let tube = TubeFrame {
            origin: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            up: [0.0, 1.0, 0.0],
            radius: 3.5e-3,
            length: 0.5,
        };
        let d = 1.4e-3;
        let mut p = Profiles::new(
            tube,
            d,
            WallSpring::Linear { kn: 1e3 },
            PlugWindow::default(),
        );
        let x: Vec<Vec3> = (0..40).map(|k| [0.0, 0.0, 0.23 + k as Real * d]).collect();
        let v = vec![[0.0, 0.0, 0.2]; x.len()];
        let r = vec![0.5 * d; x.len()];
        let plug = PlugObservation {
            time: 0.0,
            track: 0,
            centre: 0.23 + 20.0 * d,
            length: 0.03,
            min_porosity: 0.5,
            max_velocity: 0.2,
            grains: 40.0,
            velocity: Some(0.2),
        };
        // Every grain presses 1 µN up on its neighbours' side: the profile binned per tube
        // volume integrates back to the total of the grains within its range.
        let contact = vec![1e-6; x.len()];
        p.add_frame(&x, &v, &r, None, Some(&contact), &[plug]);
        let res = p.result();
        assert_eq!(res.plugs_used, 1);
        let bin_volume = std::f64::consts::PI * tube.radius * tube.radius * p.axial_bin;
        let total: Real = res.particle_force.iter().sum::<Real>() * bin_volume;
        let inside = x
            .iter()
            .filter(|q| ((q[2] - plug.centre + p.axial_half) / p.axial_bin).floor() >= 0.0)
            .filter(|q| {
                (((q[2] - plug.centre + p.axial_half) / p.axial_bin).floor() as usize)
                    < res.xi.len()
            })
            .count() as Real;
        assert!(
            (total - 1e-6 * inside).abs() < 1e-15,
            "{total} vs {}",
            1e-6 * inside
        );
        assert!(res.drag.iter().all(|d| *d == 0.0));
        assert!(res.ring_porosity[0] < 0.5, "{:?}", res.ring_porosity);
        assert!(res
            .ring_porosity
            .iter()
            .skip(2)
            .all(|q| (*q - 1.0).abs() < 1e-12));
        // Velocity inside the column is the grains' velocity; no temperature.
        let mid = res.xi.len() / 2;
        assert!((res.velocity[mid] - 0.2).abs() < 1e-12);
        assert!(res.temperature[mid].abs() < 1e-20);
    }

    /// Two columns of grains along a horizontal tube inside one long slug, one 1.5 mm above
    /// the axis moving at 0.3 m/s, one 1.5 mm below at 0.1 m/s: each layer holding grains
    /// has its column's velocity, and upper / lower is 3 (row H10's measure).
    #[test]
    fn slug_layers_carry_their_grains_velocity() {
        let tube = TubeFrame {
            origin: [0.0; 3],
            axis: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            radius: 3.5e-3,
            length: 0.5,
        };
        let d = 1.4e-3;
        let mut p = Profiles::new(
            tube,
            d,
            WallSpring::Linear { kn: 1e3 },
            PlugWindow::default(),
        );
        let (mut x, mut v) = (Vec::new(), Vec::new());
        for k in 0..200 {
            let s = 0.1 + k as Real * d;
            x.push([s, 0.0, 1.5e-3]);
            v.push([0.3, 0.0, 0.0]);
            x.push([s, 0.0, -1.5e-3]);
            v.push([0.1, 0.0, 0.0]);
        }
        let r = vec![0.5 * d; x.len()];
        let slug = PlugObservation {
            time: 0.0,
            track: 0,
            centre: 0.25,
            length: 0.4,
            min_porosity: 0.5,
            max_velocity: 0.3,
            grains: 400.0,
            velocity: Some(0.2),
        };
        p.add_frame(&x, &v, &r, None, None, &[slug]);
        let res = p.result();
        for (h, u) in res.layer_h_over_d.iter().zip(&res.layer_velocity_plug) {
            let height = h * d - tube.radius;
            if u.is_nan() {
                continue;
            }
            let want = if height > 0.0 { 0.3 } else { 0.1 };
            assert!((u - want).abs() < 1e-12, "layer at {height} m: {u}");
        }
        assert!(
            res.layer_velocity_plug
                .iter()
                .filter(|u| u.is_finite())
                .count()
                >= 4
        );
        let ratio = res.upper_over_lower_velocity_plug;
        assert!((ratio - 3.0).abs() < 1e-12, "{ratio}");
    }

    /// The wall spring gives the engine's own elastic wall force: Hertz against a flat wall
    /// (r* = r, no velocity) and Hooke.
    #[test]
    fn wall_spring_matches_the_contact_laws() {
        use crate::dem::contact::{Hertz, Hooke, NormalLaw};
        let (r, overlap) = (0.7e-3, 2e-6);
        let h = Hertz::new(5e6, 0.45, 0.5);
        let engine = h.evaluate(1e-3, r, overlap, 0.0).force;
        let spring = WallSpring::Hertz { y_star: h.y_star }.force(r, overlap);
        assert!(
            (engine - spring).abs() <= 1e-12 * engine,
            "{engine} vs {spring}"
        );
        let k = Hooke::new(350.0, 0.5, 2.0 / 7.0);
        let engine = k.evaluate(1e-3, r, overlap, 0.0).force;
        let spring = WallSpring::Linear { kn: 350.0 }.force(r, overlap);
        assert!((engine - spring).abs() <= 1e-12 * engine);
    }
}
