//! What a run measures at each sample: grains in the tube, the gas's profiles, pressure
//! taps, plug tracking, profiles over plugs, and the sums the summary's means come from.
//! It reads the engine and the coupler; it changes neither.

use plugflow_coupling::{Coupler, DemBackend, ParticleView};

use crate::analysis::plugs::{PlugTracker, Slicer};
use crate::analysis::profiles::{PlugWindow, Profiles, TubeFrame, WallSpring};
use crate::analysis::slug::SlugTrace;
use crate::analysis::taps::{PressureTap, TapTrace};
use crate::dem::{DemConfig, LawSet};
use crate::output::{GasSnapshot, OutputError, RunOutput, Sample};
use crate::scene::Scene;
use crate::{Real, Vec3};

/// The run's measurements so far (kept whole in a checkpoint).
#[derive(Clone, serde::Serialize, serde::Deserialize)]
pub struct Sampling {
    /// Means are taken from this time on, s.
    pub settle: Real,
    pub in_tube_sum: Real,
    pub in_tube_n: u64,
    /// A periodic section: the sum over samples after the settling time of the solids mass
    /// flow through a cross-section, Σ m_i v_i·axis / L, kg/s.
    #[serde(default)]
    pub mass_flow_sum: Real,
    pub dp_sum: Real,
    /// Time and outflow mass at the first sample after the settling time.
    pub outflow_at_settle: Option<(Real, Real)>,
    /// Plug statistics on the tube's slices, from the settling time on.
    pub tracker: Option<PlugTracker>,
    pub profiles: Option<Profiles>,
    /// Deposited porosity along the axis, one row per sample (the spatio-temporal figure).
    pub porosity_rows: Vec<Vec<Real>>,
    /// (time, pressure drop Pa/m) per sample.
    pub dp_trace: Vec<(Real, Real)>,
    pub taps: TapTrace,
    /// The walls the engine reports forces on (names, in its order; fixed at the first
    /// sample) and the sums of their forces after the settling time, N.
    pub walls: Vec<String>,
    pub wall_force_sums: Vec<Vec3>,
    /// A periodic section's slug, measured at every sample as Lethe does (a checkpoint
    /// carries it after the rest: see `checkpoint.rs`).
    #[serde(skip)]
    pub slug: Option<SlugTrace>,
    /// What the last sample saw (nothing before the first).
    last: Seen,
}

/// What one sample saw, for the progress line.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Seen {
    pub in_tube: usize,
    pub pressure_drop: Option<Real>,
}

impl Sampling {
    /// Empty measurements for a scene.
    pub fn new(scene: &Scene, cfg: &DemConfig) -> Self {
        let f = &scene.file;
        let tracker = cfg.tube.map(|t| {
            let slice = f.output.slice_length.map(|q| q.si).unwrap_or(3.5e-3);
            let r = 0.5 * (cfg.radius_min + cfg.radius_max);
            PlugTracker::new(
                Slicer::new(t.origin, t.axis, t.radius, t.length, slice),
                4.0 / 3.0 * std::f64::consts::PI * r * r * r,
            )
        });
        let profiles = cfg.tube.map(|t| {
            Profiles::new(
                TubeFrame {
                    origin: t.origin,
                    axis: t.axis,
                    up: up_across(cfg.gravity, t.axis),
                    radius: t.radius,
                    length: t.length,
                },
                cfg.radius_min + cfg.radius_max,
                wall_spring(&cfg.laws),
                plug_window(&f.output),
            )
        });
        let taps = TapTrace::new(
            f.output
                .pressure_taps
                .iter()
                .map(|t| PressureTap {
                    name: t.name.clone(),
                    from: t.from.si,
                    to: t.to.si,
                })
                .collect(),
        );
        Sampling {
            settle: f.output.settling_time.map(|q| q.si).unwrap_or(0.0),
            in_tube_sum: 0.0,
            in_tube_n: 0,
            mass_flow_sum: 0.0,
            dp_sum: 0.0,
            outflow_at_settle: None,
            tracker,
            profiles,
            porosity_rows: Vec::new(),
            dp_trace: Vec::new(),
            taps,
            walls: Vec::new(),
            wall_force_sums: Vec::new(),
            slug: slug_trace(cfg),
            last: Seen::default(),
        }
    }

    /// The engine's walls, named once (before the first sample: `run.h5` lays out a series
    /// for each).
    pub fn name_walls(&mut self, dem: &dyn DemBackend) -> &[String] {
        if self.walls.is_empty() {
            self.walls = dem.wall_forces().into_iter().map(|w| w.wall).collect();
            self.wall_force_sums = vec![[0.0; 3]; self.walls.len()];
        }
        &self.walls
    }

    /// The force on each named wall now, N (zero for a wall the engine stopped reporting:
    /// an engine that reports none after a failed read reports no force, not another wall's).
    fn wall_forces(&mut self, dem: &dyn DemBackend) -> Vec<Vec3> {
        self.name_walls(dem);
        let now = dem.wall_forces();
        self.walls
            .iter()
            .map(|name| {
                now.iter()
                    .find(|w| &w.wall == name)
                    .map_or([0.0; 3], |w| w.force)
            })
            .collect()
    }

    /// Mean force on each wall after the settling time, N (None before a sample in it).
    pub fn wall_force_means(&self) -> Option<Vec<(String, Vec3)>> {
        (self.in_tube_n > 0).then(|| {
            let n = self.in_tube_n as Real;
            self.walls
                .iter()
                .zip(&self.wall_force_sums)
                .map(|(w, s)| (w.clone(), s.map(|c| c / n)))
                .collect()
        })
    }

    /// Slice centres along the tube, m (None without a tube).
    pub fn slice_centres(&self) -> Option<Vec<Real>> {
        self.tracker.as_ref().map(|t| {
            let s = t.slicer();
            (0..s.count).map(|k| (k as Real + 0.5) * s.slice).collect()
        })
    }

    /// Measure the present state and hand the sample to every output.
    pub fn sample(
        &mut self,
        cfg: &DemConfig,
        dem: &dyn DemBackend,
        gas: Option<&Coupler>,
        dt: Real,
        outputs: &mut [Box<dyn RunOutput>],
        snapshot_due: bool,
    ) -> Result<Seen, OutputError> {
        let time = dem.time();
        let in_tube = particles_in_tube(cfg, &dem.particles());
        let wall_forces = self.wall_forces(dem);
        let dp = gas.map(|g| g.pressure_drop());
        let gas_porosity = gas.map(|g| g.porosity_profile());
        let gas_pressure = gas.map(|g| g.pressure_profile());
        if let (Some(p), Some(d)) = (&gas_porosity, dp) {
            self.porosity_rows.push(p.clone());
            self.dp_trace.push((time, d));
        }
        if let (Some(g), Some(profile)) = (gas, &gas_pressure) {
            self.taps
                .push(time, &g.axial_positions(), profile, g.gas.grid().length);
        }
        let frame = self.tracker.as_ref().map(|tr| {
            let p = dem.particles();
            tr.slicer().frame(time, p.position, p.velocity, p.radius)
        });
        let plugs_before = self.tracker.as_ref().map_or(0, |t| t.observations.len());
        if self.slug.is_none() {
            // (A checkpoint written before the slug was measured: from here on.)
            self.slug = slug_trace(cfg);
        }
        if let Some(sl) = self.slug.as_mut() {
            let p = dem.particles();
            let gas_velocity = gas.and_then(|g| g.gas.mean_superficial_velocity());
            sl.push(time, p.position, p.velocity, p.radius, gas_velocity);
        }
        if time >= self.settle - 0.5 * dt {
            if self.outflow_at_settle.is_none() {
                self.outflow_at_settle = Some((time, outflow_mass(dem)));
            }
            self.in_tube_sum += in_tube as Real;
            if let Some(t) = cfg.tube.filter(|t| t.periodic) {
                self.mass_flow_sum += section_mass_flow(cfg, &t, &dem.particles());
            }
            self.dp_sum += dp.unwrap_or(0.0);
            self.in_tube_n += 1;
            for (sum, f) in self.wall_force_sums.iter_mut().zip(&wall_forces) {
                for k in 0..3 {
                    sum[k] += f[k];
                }
            }
            if let (Some(tr), Some(fr)) = (self.tracker.as_mut(), &frame) {
                tr.push(fr);
            }
            if let (Some(pr), Some(tr), Some(t)) =
                (self.profiles.as_mut(), self.tracker.as_ref(), cfg.tube)
            {
                let p = dem.particles();
                // The fluid forces of the exchange that ended this interval, in this order.
                let axial: Option<Vec<Real>> = gas.and_then(|g| {
                    let f = g.fluid_forces();
                    (f.len() == p.len()).then(|| {
                        f.iter()
                            .map(|f| (0..3).map(|k| f[k] * t.axis[k]).sum())
                            .collect()
                    })
                });
                // The grains' contact forces (grain–grain and wall) along the axis, where
                // the engine gives them.
                let contact: Option<Vec<Real>> = dem.contact_forces().map(|c| {
                    c.iter()
                        .map(|f| (0..3).map(|k| f[k] * t.axis[k]).sum())
                        .collect()
                });
                pr.add_frame(
                    p.position,
                    p.velocity,
                    p.radius,
                    axial.as_deref(),
                    contact.as_deref(),
                    &tr.observations[plugs_before..],
                );
            }
        }
        let sample = Sample {
            time,
            particles_in_tube: in_tube,
            pressure_drop: dp,
            slices: frame.as_ref(),
            gas_porosity: gas_porosity.as_deref(),
            gas_pressure: gas_pressure.as_deref(),
            new_plugs: self
                .tracker
                .as_ref()
                .map_or(&[][..], |t| &t.observations[plugs_before..]),
            wall_forces: &wall_forces,
        };
        let gas_snapshot = gas.filter(|_| snapshot_due).map(|g| GasSnapshot {
            grid: g.gas.grid(),
            pressure: g.gas.pressure(),
            porosity: g.gas.porosity(),
            granular_velocity: &g.granular_fields().velocity,
            gas_velocity: g.gas.gas_velocity(),
        });
        for o in outputs.iter_mut() {
            o.sample(&sample)?;
            if snapshot_due {
                o.snapshot(
                    time,
                    dem.step_count(),
                    &dem.particles(),
                    gas_snapshot.as_ref(),
                )?;
            }
        }
        self.last = Seen {
            in_tube,
            pressure_drop: dp,
        };
        Ok(self.last)
    }

    /// What the last sample saw.
    pub fn last_seen(&self) -> Seen {
        self.last
    }
}

/// A periodic section's slug measurement (slices one mean grain diameter long).
fn slug_trace(cfg: &DemConfig) -> Option<SlugTrace> {
    cfg.tube.filter(|t| t.periodic).map(|t| {
        SlugTrace::new(
            t.origin,
            t.axis,
            t.radius,
            t.length,
            cfg.radius_min + cfg.radius_max,
        )
    })
}

/// "Up" across the tube: against gravity's part across the axis (any cross direction for a
/// vertical tube, where the layer profile means nothing special).
fn up_across(g: [Real; 3], axis: [Real; 3]) -> [Real; 3] {
    let ga: Real = (0..3).map(|k| g[k] * axis[k]).sum();
    let cross = [
        g[0] - ga * axis[0],
        g[1] - ga * axis[1],
        g[2] - ga * axis[2],
    ];
    let norm = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
    if norm > 1e-9 {
        [-cross[0] / norm, -cross[1] / norm, -cross[2] / norm]
    } else {
        plugflow_coupling::grid::perpendicular_basis(axis).1
    }
}

/// The grain–wall spring that turns overlaps into the wall stress profile.
fn wall_spring(laws: &LawSet) -> WallSpring {
    match laws {
        LawSet::Hooke(t) => WallSpring::Linear {
            kn: t.normal().1.kn,
        },
        LawSet::Hertz(t) => WallSpring::Hertz {
            y_star: t.normal().1.y_star,
        },
    }
}

/// The plugs the profiles average over: the scene's windows, each defaulting to
/// [`PlugWindow::default`]'s.
fn plug_window(o: &crate::scene::schema::OutputSpec) -> PlugWindow {
    let d = PlugWindow::default();
    let Some(p) = &o.profiles else {
        return d;
    };
    PlugWindow {
        length: p.plug_length.map_or(d.length, |r| (r[0].si, r[1].si)),
        velocity: p.plug_velocity.map_or(d.velocity, |r| (r[0].si, r[1].si)),
        centre: p.centre.map_or(d.centre, |r| (r[0].0, r[1].0)),
    }
}

/// Grains whose centre lies inside the tube (all grains without a tube, or in a periodic
/// section: between neighbour builds a grain may sit up to a skin past its seam, still in it).
fn particles_in_tube(cfg: &DemConfig, p: &ParticleView) -> usize {
    match &cfg.tube {
        Some(t) if t.periodic => p.len(),
        Some(t) => p
            .position
            .iter()
            .filter(|x| {
                let s: Real = (0..3).map(|k| (x[k] - t.origin[k]) * t.axis[k]).sum();
                (0.0..=t.length).contains(&s)
            })
            .count(),
        None => p.len(),
    }
}

/// The solids mass flow through a cross-section of a periodic section, kg/s: in a period
/// of length L every grain crosses a given section v·axis/L times per second, so the mean
/// flow through any section is Σ m_i v_i·axis / L.
fn section_mass_flow(cfg: &DemConfig, t: &crate::dem::TubeGeometry, p: &ParticleView) -> Real {
    let momentum: Real = p
        .velocity
        .iter()
        .zip(p.radius)
        .map(|(v, &r)| {
            let m = cfg.density * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            m * (v[0] * t.axis[0] + v[1] * t.axis[1] + v[2] * t.axis[2])
        })
        .sum();
    momentum / t.length
}

/// Mass that has left through the outlet so far, kg (0 without the engine's counters).
pub fn outflow_mass(dem: &dyn DemBackend) -> Real {
    dem.flow().map_or(0.0, |f| f.outflow_mass)
}
