//! The built-in DEM: soft spheres, velocity-Verlet, cell list with Verlet skin.
//!
//! One step (see [`NativeDem::advance`]): half kick + drift → neighbour rebuild when a grain
//! moved half the skin (or grains were added/removed) → forces → half kick. Every few steps
//! the inlet feeds a batch and grains past an open end leave. Each stage is timed.

pub mod config;
pub mod contact;
pub mod forces;
pub mod neighbor;
pub mod placement;
pub mod state;
pub mod vec3;
pub mod walls;

pub use config::{DemConfig, LawSet, TubeGeometry};

use std::time::Instant;

use plugflow_coupling::{
    BackendError, DemBackend, ImplicitDrag, NewParticle, ParticleView, StageTimer, WallForce,
};

use self::contact::{NormalLaw, TangentialLaw};
use self::forces::{chunk_forces, ChunkOut, GrainsIn, Laws, Spill, StepSettings};
use self::neighbor::{CellGrid, NeighborList};
use self::placement::{place, Region};
use self::state::ParticleState;
use self::vec3::{dot, is_finite, norm2, scale, sub};
use crate::rng::Rng;
use crate::{Real, Vec3};

/// Speed beyond which a grain is taken to have blown up, m/s: no conveyed grain moves at
/// 10 km/s, and a diverging integration passes it long before reaching infinity or NaN.
const BLOWUP_SPEED: Real = 1.0e4;

/// How often (in steps) the inlet and the open ends are looked at.
const FEED_STRIDE: u64 = 10;

/// Counters of what entered and left the domain.
#[derive(Debug, Clone, Default)]
pub struct FlowCounters {
    /// Grains fed by the inlet.
    pub fed_count: u64,
    /// Mass fed by the inlet, kg.
    pub fed_mass: Real,
    /// Grains that left through the outlet.
    pub outflow_count: u64,
    /// Mass that left through the outlet, kg.
    pub outflow_mass: Real,
    /// Grains that left through the open inlet end or the box, or escaped the tube.
    pub lost_count: u64,
    /// Grains the inlet owes (rate × time − fed).
    pub inlet_backlog: Real,
    /// Simulated time during which the inlet slab was blocked with grains owed, s.
    pub inlet_blocked_time: Real,
}

/// The built-in DEM engine.
pub struct NativeDem {
    cfg: DemConfig,
    /// Grain state (SoA).
    pub state: ParticleState,
    nlist: NeighborList,
    grid: CellGrid,
    time: Real,
    step: u64,
    next_id: u64,
    rng: Rng,
    rebuild_pending: bool,
    /// Inflow/outflow counters.
    pub flow: FlowCounters,
    wall_force: Vec<Vec3>,
    chunk_wall_force: Vec<Vec<Vec3>>,
    spills: Vec<Vec<Spill>>,
    timer: StageTimer,
    pool: Option<rayon::ThreadPool>,
    /// Scratch: velocities predicted to t + dt for the velocity-dependent forces.
    velocity_pred: Vec<Vec3>,
    /// Scratch: angular velocities predicted to t + dt.
    angular_velocity_pred: Vec<Vec3>,
}

impl NativeDem {
    /// Build the engine from a checked configuration and place the initial grains.
    pub fn new(cfg: DemConfig) -> Result<Self, crate::scene::SceneError> {
        let grid = CellGrid::new(cfg.box_lo, cfg.box_hi, 2.0 * cfg.radius_max + cfg.skin);
        let pool = if cfg.threads > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(cfg.threads)
                    .build()
                    .map_err(|e| crate::scene::SceneError::field("dem.threads", e.to_string()))?,
            )
        } else {
            None
        };
        let nw = cfg.walls.len();
        let mut dem = NativeDem {
            rng: Rng::new(cfg.seed),
            grid,
            state: ParticleState::default(),
            nlist: NeighborList::default(),
            time: 0.0,
            step: 0,
            next_id: 0,
            rebuild_pending: true,
            flow: FlowCounters::default(),
            wall_force: vec![[0.0; 3]; nw],
            chunk_wall_force: vec![vec![[0.0; 3]; nw]; cfg.threads],
            spills: vec![Vec::new(); cfg.threads],
            timer: StageTimer::new(),
            pool,
            velocity_pred: Vec::new(),
            angular_velocity_pred: Vec::new(),
            cfg,
        };
        if let Some(init) = dem.cfg.initial.clone() {
            let radii: Vec<Real> = (0..init.count).map(|_| dem.draw_radius()).collect();
            let placed = place(&init.region, &radii, &[], &mut dem.rng, 20_000);
            if placed.len() < radii.len() {
                return Err(crate::scene::SceneError::field(
                    "initial.count",
                    format!(
                        "only {} of {} grains fit without overlap between `initial.from` and \
                         `initial.to` (random placement saturates near 35 % solids); lengthen \
                         the stretch",
                        placed.len(),
                        radii.len()
                    ),
                ));
            }
            for (x, r) in placed.into_iter().zip(radii) {
                let id = dem.next_id;
                dem.next_id += 1;
                dem.state.push(id, x, init.velocity, r, dem.cfg.density, nw);
            }
        }
        Ok(dem)
    }

    /// The configuration in force.
    pub fn config(&self) -> &DemConfig {
        &self.cfg
    }

    /// Neighbour-list builds so far.
    pub fn neighbor_builds(&self) -> u64 {
        self.nlist.builds
    }

    fn draw_radius(&mut self) -> Real {
        if self.cfg.radius_max > self.cfg.radius_min {
            self.rng.range(self.cfg.radius_min, self.cfg.radius_max)
        } else {
            self.cfg.radius_min
        }
    }

    /// Number of grains whose centre lies inside the tube (0 ≤ s ≤ L); all grains without a tube.
    pub fn particles_in_tube(&self) -> usize {
        match &self.cfg.tube {
            Some(t) => self
                .state
                .position
                .iter()
                .filter(|&&x| {
                    let s = dot(sub(x, t.origin), t.axis);
                    (0.0..=t.length).contains(&s)
                })
                .count(),
            None => self.state.len(),
        }
    }

    /// Total kinetic energy (translation + rotation), J.
    pub fn kinetic_energy(&self) -> Real {
        let s = &self.state;
        (0..s.len())
            .map(|i| {
                let t = 0.5 * s.mass[i] * norm2(s.velocity[i]);
                let r = 0.5 / s.inv_inertia[i] * norm2(s.angular_velocity[i]);
                t + r
            })
            .sum()
    }

    fn rebuild(&mut self) {
        let keep = self.cfg.laws.uses_history();
        let nw = self.cfg.walls.len();
        self.nlist
            .rebuild(&mut self.state, &self.grid, self.cfg.skin, nw, keep);
        self.rebuild_pending = false;
    }

    /// Feed a batch when grains are owed and the inlet slab is clear.
    fn feed(&mut self, elapsed: Real) {
        let Some(inlet) = self.cfg.inlet.clone() else {
            return;
        };
        let Some(tube) = self.cfg.tube.clone() else {
            return;
        };
        self.flow.inlet_backlog += inlet.rate * elapsed;
        if self.flow.inlet_backlog < 1.0 {
            return;
        }
        let clear = self
            .state
            .position
            .iter()
            .zip(&self.state.radius)
            .all(|(x, r)| {
                let s = dot(sub(*x, tube.origin), tube.axis);
                s - r >= inlet.slab_length
            });
        if !clear {
            if self.flow.inlet_backlog > 2.0 * inlet.batch_target as Real {
                self.flow.inlet_blocked_time += elapsed;
            }
            return;
        }
        let want = (self.flow.inlet_backlog.floor() as usize).min(inlet.batch_target);
        if self.cfg.laws.uses_history() {
            self.nlist.stash_history(&self.state);
        }
        let radii: Vec<Real> = (0..want).map(|_| self.draw_radius()).collect();
        let region = Region::TubeStretch {
            origin: tube.origin,
            axis: tube.axis,
            radius: tube.radius,
            from: 0.0,
            to: inlet.slab_length,
        };
        let placed = place(&region, &radii, &[], &mut self.rng, 2_000);
        let v = scale(tube.axis, inlet.velocity);
        let nw = self.cfg.walls.len();
        for (x, r) in placed.iter().zip(&radii) {
            let id = self.next_id;
            self.next_id += 1;
            self.state.push(id, *x, v, *r, self.cfg.density, nw);
            self.flow.fed_count += 1;
            self.flow.fed_mass += *self.state.mass.last().expect("just pushed");
        }
        self.flow.inlet_backlog -= placed.len() as Real;
        if !placed.is_empty() {
            self.rebuild_pending = true;
        }
    }

    /// Remove grains past open ends, outside the box, or escaped from the tube.
    fn remove_leaving(&mut self) -> Real {
        let mut keep: Vec<usize> = Vec::with_capacity(self.state.len());
        let mut out_mass = 0.0;
        for i in 0..self.state.len() {
            let x = self.state.position[i];
            let r = self.state.radius[i];
            let verdict = match &self.cfg.tube {
                Some(t) => {
                    let rel = sub(x, t.origin);
                    let s = dot(rel, t.axis);
                    let radial2 = norm2(sub(rel, scale(t.axis, s)));
                    if t.outlet_open && s > t.length {
                        Leave::Outlet
                    } else if (t.inlet_open && s < 0.0)
                        || radial2 > (t.radius + 2.0 * r).powi(2)
                        || s < -t.length
                        || s > 2.0 * t.length
                    {
                        Leave::Lost
                    } else {
                        Leave::Stay
                    }
                }
                None => {
                    let outside =
                        (0..3).any(|k| x[k] < self.cfg.box_lo[k] || x[k] > self.cfg.box_hi[k]);
                    if outside {
                        Leave::Lost
                    } else {
                        Leave::Stay
                    }
                }
            };
            match verdict {
                Leave::Stay => keep.push(i),
                Leave::Outlet => {
                    self.flow.outflow_count += 1;
                    self.flow.outflow_mass += self.state.mass[i];
                    out_mass += self.state.mass[i];
                }
                Leave::Lost => self.flow.lost_count += 1,
            }
        }
        if keep.len() != self.state.len() {
            if self.cfg.laws.uses_history() {
                self.nlist.stash_history(&self.state);
            }
            let nw = self.cfg.walls.len();
            self.state.permute(&keep, nw);
            self.rebuild_pending = true;
        }
        out_mass
    }

    /// Forces on all grains for the current positions (and half-step velocities).
    fn compute_forces(&mut self) {
        match self.cfg.laws.clone() {
            LawSet::HookeHistory(l) => self.forces_with(&l),
            LawSet::HookeCoulomb(l) => self.forces_with(&l),
            LawSet::HertzHistory(l) => self.forces_with(&l),
            LawSet::HertzCoulomb(l) => self.forces_with(&l),
        }
    }

    /// Velocities at t + dt predicted from the half-step ones with the last accelerations,
    /// v(t+dt) ≈ v(t+dt/2) + a(t) dt/2. The dashpots see these rather than the half-step
    /// velocities of plain velocity-Verlet, whose lag of dt/2 over-damps every collision by
    /// O(dt/t_c) (e = 0.5 came out as 0.493 at t_c/50; with the predictor the error is
    /// O((dt/t_c)²)).
    fn predict_velocities(&mut self) {
        let h = 0.5 * self.cfg.dt;
        let s = &self.state;
        self.velocity_pred.clear();
        self.velocity_pred.extend((0..s.len()).map(|i| {
            let a = s.inv_mass[i] * h;
            let (v, f) = (s.velocity[i], s.force[i]);
            [v[0] + f[0] * a, v[1] + f[1] * a, v[2] + f[2] * a]
        }));
        if self.cfg.rotation {
            self.angular_velocity_pred.clear();
            self.angular_velocity_pred.extend((0..s.len()).map(|i| {
                let b = s.inv_inertia[i] * h;
                let (w, t) = (s.angular_velocity[i], s.torque[i]);
                [w[0] + t[0] * b, w[1] + t[1] * b, w[2] + t[2] * b]
            }));
        } else {
            // No rotation: the force loop never reads these; keep the length right only.
            self.angular_velocity_pred.resize(s.len(), [0.0; 3]);
        }
    }

    fn forces_with<N: NormalLaw, T: TangentialLaw>(&mut self, laws: &Laws<N, T>) {
        self.predict_velocities();
        let n = self.state.len();
        let nw = self.cfg.walls.len();
        let set = StepSettings {
            walls: &self.cfg.walls,
            gravity: self.cfg.gravity,
            dt: self.cfg.dt,
            rotation: self.cfg.rotation,
        };
        let s = &mut self.state;
        let g = GrainsIn {
            position: &s.position,
            velocity: &self.velocity_pred,
            angular_velocity: &self.angular_velocity_pred,
            radius: &s.radius,
            mass: &s.mass,
            external_force: &s.external_force,
        };
        let start = &self.nlist.start;
        let partner = &self.nlist.partner;
        if self.nlist.history.len() != partner.len() {
            self.nlist.history.resize(partner.len(), [0.0; 3]);
        }
        let chunks = self.cfg.threads.min(n.max(1));
        // Split at grains so that each chunk gets about the same number of pairs + grains.
        let mut bounds = vec![0usize];
        if chunks > 1 {
            let total = partner.len() + n;
            let mut next = 1;
            for i in 0..n {
                if next < chunks && start[i] as usize + i >= total * next / chunks {
                    bounds.push(i);
                    next += 1;
                }
            }
        }
        while bounds.len() < chunks {
            bounds.push(n);
        }
        bounds.push(n);
        // Carve the writable arrays into per-chunk slices.
        let mut outs: Vec<ChunkOut<'_>> = Vec::with_capacity(chunks);
        let (mut f_rest, mut t_rest) = (&mut s.force[..], &mut s.torque[..]);
        let mut h_rest = &mut self.nlist.history[..];
        let mut wh_rest = &mut s.wall_history[..];
        let mut spill_iter = self.spills.iter_mut();
        let mut wf_iter = self.chunk_wall_force.iter_mut();
        for c in 0..chunks {
            let (lo, hi) = (bounds[c], bounds[c + 1]);
            let (f, fr) = f_rest.split_at_mut(hi - lo);
            let (t, tr) = t_rest.split_at_mut(hi - lo);
            let hlen = (start[hi] - start[lo]) as usize;
            let (h, hr) = h_rest.split_at_mut(hlen);
            let (wh, whr) = wh_rest.split_at_mut((hi - lo) * nw);
            f_rest = fr;
            t_rest = tr;
            h_rest = hr;
            wh_rest = whr;
            let spill = spill_iter.next().expect("one spill list per thread");
            spill.clear();
            outs.push(ChunkOut {
                lo,
                force: f,
                torque: t,
                history: h,
                wall_history: wh,
                spill,
                wall_force: wf_iter.next().expect("one wall accumulator per thread"),
            });
        }
        match (&self.pool, chunks) {
            (Some(pool), c) if c > 1 => pool.install(|| {
                use rayon::prelude::*;
                outs.into_par_iter()
                    .for_each(|out| chunk_forces(laws, &set, g, start, partner, out));
            }),
            _ => {
                for out in outs {
                    chunk_forces(laws, &set, g, start, partner, out);
                }
            }
        }
        // Apply spills in chunk order, then sum the wall forces in chunk order.
        for spill in &self.spills[..chunks] {
            for sp in spill {
                let j = sp.j as usize;
                vec3::add_assign(&mut s.force[j], sp.force);
                if self.cfg.rotation {
                    vec3::add_assign(&mut s.torque[j], sp.torque);
                }
            }
        }
        for w in 0..nw {
            self.wall_force[w] = [0.0; 3];
            for c in 0..chunks {
                vec3::add_assign(&mut self.wall_force[w], self.chunk_wall_force[c][w]);
            }
        }
    }

    /// First half kick and drift; returns nothing, positions now at t + dt.
    fn kick_drift(&mut self) {
        let dt = self.cfg.dt;
        let h = 0.5 * dt;
        let s = &mut self.state;
        for i in 0..s.len() {
            let a = s.inv_mass[i] * h;
            let v = &mut s.velocity[i];
            let f = s.force[i];
            v[0] += f[0] * a;
            v[1] += f[1] * a;
            v[2] += f[2] * a;
            let x = &mut s.position[i];
            x[0] += v[0] * dt;
            x[1] += v[1] * dt;
            x[2] += v[2] * dt;
        }
        if self.cfg.rotation {
            for i in 0..s.len() {
                let b = s.inv_inertia[i] * h;
                let w = &mut s.angular_velocity[i];
                let t = s.torque[i];
                w[0] += t[0] * b;
                w[1] += t[1] * b;
                w[2] += t[2] * b;
            }
        }
    }

    /// Second half kick; reports the first grain whose state stopped being finite.
    fn kick(&mut self) -> Result<(), BackendError> {
        let h = 0.5 * self.cfg.dt;
        let s = &mut self.state;
        let mut finite = true;
        for i in 0..s.len() {
            let a = s.inv_mass[i] * h;
            let v = &mut s.velocity[i];
            let f = s.force[i];
            v[0] += f[0] * a;
            v[1] += f[1] * a;
            v[2] += f[2] * a;
            // NaN compares false, so this also catches NaN and infinity.
            finite &= v[0] * v[0] + v[1] * v[1] + v[2] * v[2] < BLOWUP_SPEED * BLOWUP_SPEED;
        }
        if self.cfg.rotation {
            for i in 0..s.len() {
                let b = s.inv_inertia[i] * h;
                let w = &mut s.angular_velocity[i];
                let t = s.torque[i];
                w[0] += t[0] * b;
                w[1] += t[1] * b;
                w[2] += t[2] * b;
                finite &= (w[0] + w[1] + w[2]).is_finite();
            }
        }
        if finite {
            return Ok(());
        }
        let bad = (0..s.len())
            .find(|&i| {
                let speed2 = norm2(s.velocity[i]);
                speed2.is_nan()
                    || speed2 >= BLOWUP_SPEED * BLOWUP_SPEED
                    || !is_finite(s.position[i])
                    || !is_finite(s.angular_velocity[i])
            })
            .unwrap_or(0);
        Err(BackendError::NonFinite {
            step: self.step,
            particle_id: s.id.get(bad).copied().unwrap_or(0),
            what: format!(
                "blew up (speed above {BLOWUP_SPEED} m/s, or NaN): position {:?}, velocity {:?}, \
                 force {:?} (external {:?})",
                s.position[bad], s.velocity[bad], s.force[bad], s.external_force[bad]
            ),
        })
    }
}

enum Leave {
    Stay,
    Outlet,
    Lost,
}

impl DemBackend for NativeDem {
    fn engine_name(&self) -> &str {
        "native"
    }

    fn engine_version(&self) -> String {
        format!("plugflow {}", env!("CARGO_PKG_VERSION"))
    }

    fn time_step(&self) -> Real {
        self.cfg.dt
    }

    fn time(&self) -> Real {
        self.time
    }

    fn step_count(&self) -> u64 {
        self.step
    }

    fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
        let dt = self.cfg.dt;
        if self.rebuild_pending {
            let t0 = Instant::now();
            self.rebuild();
            self.timer.add("neighbor", t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            self.compute_forces();
            self.timer.add("forces", t0.elapsed().as_secs_f64());
        }
        for _ in 0..steps {
            let t0 = Instant::now();
            self.kick_drift();
            let t1 = Instant::now();
            self.timer.add("integrate", (t1 - t0).as_secs_f64());
            self.time += dt;
            self.step += 1;
            if self.step.is_multiple_of(FEED_STRIDE)
                && (self.cfg.inlet.is_some() || self.cfg.removes_grains)
            {
                self.remove_leaving();
                self.feed(FEED_STRIDE as Real * dt);
            }
            let t2 = Instant::now();
            self.timer.add("inlet_outlet", (t2 - t1).as_secs_f64());
            if self.rebuild_pending || self.nlist.needs_rebuild(&self.state, self.cfg.skin) {
                self.rebuild();
            }
            let t3 = Instant::now();
            self.timer.add("neighbor", (t3 - t2).as_secs_f64());
            self.compute_forces();
            let t4 = Instant::now();
            self.timer.add("forces", (t4 - t3).as_secs_f64());
            self.kick()?;
            self.timer.add("integrate", t4.elapsed().as_secs_f64());
        }
        Ok(())
    }

    fn particles(&self) -> ParticleView<'_> {
        ParticleView {
            id: &self.state.id,
            position: &self.state.position,
            velocity: &self.state.velocity,
            angular_velocity: &self.state.angular_velocity,
            radius: &self.state.radius,
            mass: &self.state.mass,
        }
    }

    fn set_fluid_forces(
        &mut self,
        force: &[Vec3],
        implicit: Option<ImplicitDrag<'_>>,
    ) -> Result<(), BackendError> {
        if force.len() != self.state.len() {
            return Err(BackendError::InvalidArgument {
                argument: "force".into(),
                reason: format!("{} forces for {} grains", force.len(), self.state.len()),
            });
        }
        if implicit.is_some() {
            return Err(BackendError::InvalidArgument {
                argument: "implicit".into(),
                reason: "the native engine takes the drag as an explicit force".into(),
            });
        }
        if let Some(i) = force.iter().position(|f| !is_finite(*f)) {
            return Err(BackendError::NonFinite {
                step: self.step,
                particle_id: self.state.id[i],
                what: format!("fluid force {:?}", force[i]),
            });
        }
        // The total force of the last step feeds the next half kick: swap the old fluid
        // force for the new one in it rather than recomputing all contacts.
        let s = &mut self.state;
        for i in 0..s.len() {
            let old = s.external_force[i];
            let new = force[i];
            for k in 0..3 {
                s.force[i][k] += new[k] - old[k];
            }
            s.external_force[i] = new;
        }
        Ok(())
    }

    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        let nw = self.cfg.walls.len();
        if self.cfg.laws.uses_history() {
            self.nlist.stash_history(&self.state);
        }
        let mut ids = Vec::with_capacity(particles.len());
        for p in particles {
            if !(p.radius > 0.0
                && p.density > 0.0
                && is_finite(p.position)
                && is_finite(p.velocity))
            {
                return Err(BackendError::InvalidArgument {
                    argument: "particles".into(),
                    reason: format!(
                        "grain {p:?} has a non-positive size/density or non-finite state"
                    ),
                });
            }
            let id = self.next_id;
            self.next_id += 1;
            self.state
                .push(id, p.position, p.velocity, p.radius, p.density, nw);
            ids.push(id);
        }
        self.rebuild_pending = true;
        Ok(ids)
    }

    fn remove_past_outlet(&mut self) -> Result<Real, BackendError> {
        Ok(self.remove_leaving())
    }

    fn wall_forces(&self) -> Vec<WallForce> {
        self.cfg
            .walls
            .iter()
            .zip(&self.wall_force)
            .map(|(w, f)| WallForce {
                wall: w.name.clone(),
                force: *f,
            })
            .collect()
    }

    fn stage_times(&self) -> Vec<(String, f64)> {
        self.timer.entries()
    }
}
