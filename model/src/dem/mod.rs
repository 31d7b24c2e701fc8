//! The built-in DEM: soft spheres, velocity-Verlet, cell list with Verlet skin.
//!
//! One step (see [`NativeDem::advance`]): half kick + drift → neighbour rebuild when the two
//! largest drifts since the last one add up to the skin (or only the far-drifted few listed
//! again, [`NativeDem::refresh`]; fed grains join the list without one) →
//! forces → half kick. Every few steps
//! the inlet feeds a batch and grains past an open end leave. Each stage is timed.

mod checkpoint;
pub mod config;
pub mod contact;
pub mod conveyor;
pub mod external;
pub mod forces;
pub mod inlet;
pub mod integrate;
pub mod lanes;
pub mod neighbor;
pub mod placement;
pub mod state;
/// The worker team lives in plugflow-coupling: the engine lends it to the coupler's
/// per-grain stages ([`DemBackend::team`]).
pub use plugflow_coupling::team;
pub mod vec3;
pub mod walls;

pub use config::{
    DemConfig, GivenGrain, InitialConfig, LawSet, LawVisitor, RollingSet, TangentialChoice,
    TangentialSet, TubeGeometry,
};

use std::time::Instant;

use plugflow_coupling::{
    BackendError, DemBackend, ImplicitDrag, NewParticle, ParticleView, StageTimer, WallForce,
};

use self::contact::{NoRolling, NormalLaw, RollingLaw, RollingPair, TangentialLaw};
use self::conveyor::Conveyor;
use self::forces::{
    chunk_forces, ChunkOut, ContactScratch, ForceInputs, GrainsIn, Laws, Spill, StepSettings,
    UniformPair,
};
use self::inlet::{draw_radius, leave_margin, leave_verdict, Feeder, Leave};
use self::integrate::{integrate_chunk, ChunkColumns, ChunkVerdict, PassKind, BLOWUP_SPEED};
use self::neighbor::{CellGrid, NeighborList};
use self::placement::place;
use self::state::ParticleState;
use self::team::{Shared, Team, TeamThreads};
use self::vec3::{dot, is_finite, norm2, sub};
use crate::rng::Rng;
use crate::{Real, Vec3};

/// Fewest grains per thread worth a chunk of its own (below, sync costs more than it saves).
const MIN_GRAINS_PER_CHUNK: usize = 256;

/// How often (in steps) the inlet and the open ends are looked at.
const FEED_STRIDE: u64 = 10;

/// A grain that drifted more than this share of the skin since its reference is a
/// "mover" when the drifts call for a neighbour build ([`NativeDem::refresh`]).
const MOVER_DRIFT_OF_SKIN: Real = 0.25;

/// Movers are listed again in place of a build while they are at most one grain in this
/// many (more, and the build's sorted rows pay for themselves).
const MOVER_SHARE: usize = 8;

/// Counters of what entered and left the domain.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
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
    /// Resumed from a checkpoint that did not keep the list's upkeep counts (format 1):
    /// the summary then leaves them out rather than report the part since the resume.
    upkeep_unknown_before_resume: bool,
    /// The inlet's bookkeeping.
    feeder: Feeder,
    /// The conveyor inlet's column (`inlet.mode = "conveyor"` only).
    conveyor: Option<Conveyor>,
    /// Inflow/outflow counters.
    pub flow: FlowCounters,
    wall_force: Vec<Vec3>,
    chunk_wall_force: Vec<Vec<Vec3>>,
    spills: Vec<Vec<Spill>>,
    /// Per chunk: the contacts of the pair phase (scratch kept between steps).
    contact_scratch: Vec<ContactScratch>,
    timer: StageTimer,
    /// Pair constants while every grain has the scene's one size and density.
    uniform: Option<UniformPair>,
    /// Worker threads of the force and integration phases.
    threads: TeamThreads,
    /// Chunk boundaries (active chunks + 1 entries), fixed between neighbour builds.
    bounds: Vec<usize>,
    /// The grains that may leave before the next neighbour build: closer to a leaving
    /// boundary than one skin at the last build (no grain drifts a whole skin between
    /// builds). Valid from a build until grains are added or removed.
    may_leave: Vec<u32>,
    /// Per chunk: the verdict of the last integration pass.
    chunk_result: Vec<ChunkVerdict>,
    /// Scratch: velocities predicted to t + dt for the velocity-dependent forces.
    velocity_pred: Vec<Vec3>,
    /// Scratch: angular velocities predicted to t + dt.
    angular_velocity_pred: Vec<Vec3>,
}

impl NativeDem {
    /// Build the engine from a checked configuration and place the initial grains.
    pub fn new(cfg: DemConfig) -> Result<Self, crate::scene::SceneError> {
        let grid = CellGrid::periodic(
            cfg.box_lo,
            cfg.box_hi,
            2.0 * cfg.radius_max + cfg.skin,
            cfg.periodic,
        )
        .map_err(|why| {
            let field = if cfg.tube.is_some() {
                "tube.length"
            } else {
                "domain.periodic"
            };
            crate::scene::SceneError::field(field, why)
        })?;
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
            upkeep_unknown_before_resume: false,
            feeder: Feeder::default(),
            conveyor: None,
            flow: FlowCounters::default(),
            wall_force: vec![[0.0; 3]; nw],
            chunk_wall_force: vec![vec![[0.0; 3]; nw]; cfg.threads],
            spills: vec![Vec::new(); cfg.threads],
            contact_scratch: vec![ContactScratch::default(); cfg.threads],
            timer: StageTimer::new(),
            uniform: (cfg.radius_min == cfg.radius_max).then(|| {
                let r = cfg.radius_min;
                let m = cfg.density * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
                UniformPair {
                    sqrt_m_eff: (0.5 * m).sqrt(),
                    r_eff: 0.5 * r,
                    sqrt_m: m.sqrt(),
                    radius: r,
                }
            }),
            threads: TeamThreads::start(cfg.threads),
            bounds: Vec::new(),
            may_leave: Vec::new(),
            chunk_result: vec![ChunkVerdict::CLEAN; cfg.threads],
            velocity_pred: Vec::new(),
            angular_velocity_pred: Vec::new(),
            cfg,
        };
        match dem.cfg.initial.clone() {
            Some(InitialConfig::Placed {
                count,
                region,
                velocity,
            }) => {
                let radii: Vec<Real> = (0..count)
                    .map(|_| draw_radius(&dem.cfg, &mut dem.rng))
                    .collect();
                let placed = place(&region, &radii, &[], &mut dem.rng, 20_000);
                if placed.len() < radii.len() {
                    return Err(crate::scene::SceneError::field(
                        "initial.count",
                        format!(
                            "only {} of {} grains fit without overlap in the `[initial]` \
                             region (random placement saturates near 35 % solids); enlarge it \
                             and let `dem.settle` pack them",
                            placed.len(),
                            radii.len()
                        ),
                    ));
                }
                for (x, r) in placed.into_iter().zip(radii) {
                    let id = dem.next_id;
                    dem.next_id += 1;
                    dem.state.push(id, x, velocity, r, dem.cfg.density, nw);
                }
            }
            Some(InitialConfig::Given(grains)) => {
                for g in grains {
                    let id = dem.next_id;
                    dem.next_id += 1;
                    dem.state
                        .push(id, g.position, g.velocity, g.radius, dem.cfg.density, nw);
                    if g.frozen {
                        dem.state.freeze_last();
                        // Pairs with a frozen grain take the other's mass as m*: constants
                        // per pair from now on.
                        dem.uniform = None;
                    }
                }
            }
            None => {}
        }
        if let Some(t) = dem.cfg.settle {
            dem.settle(t)?;
        }
        if dem
            .cfg
            .inlet
            .is_some_and(|i| i.mode == config::InletMode::Conveyor)
        {
            let column = Conveyor::primed(&dem.cfg, &mut dem.rng)
                .map_err(|why| crate::scene::SceneError::field("inlet.porosity", why))?;
            dem.conveyor = Some(column);
        }
        Ok(dem)
    }

    /// Let the grains settle under gravity for `duration` seconds with nothing fed, then
    /// start the clock (time, steps, flow counters and wall forces at zero): the run begins
    /// from the bed at rest. Grains lost meanwhile (a box's open faces) are gone.
    fn settle(&mut self, duration: Real) -> Result<(), crate::scene::SceneError> {
        let inlet = self.cfg.inlet.take();
        let steps = (duration / self.cfg.dt).round().max(1.0) as u64;
        let outcome = DemBackend::advance(self, steps);
        self.cfg.inlet = inlet;
        outcome.map_err(|e| {
            crate::scene::SceneError::field(
                "dem.settle",
                format!("the initial grains did not settle: {e}"),
            )
        })?;
        self.time = 0.0;
        self.step = 0;
        self.flow = FlowCounters::default();
        for w in &mut self.wall_force {
            *w = [0.0; 3];
        }
        Ok(())
    }

    /// The configuration in force.
    pub fn config(&self) -> &DemConfig {
        &self.cfg
    }

    /// Pairs in the neighbour list (within contact distance + skin).
    pub fn neighbor_pairs(&self) -> usize {
        self.nlist.partner.len()
    }

    /// Neighbour-list builds so far.
    pub fn neighbor_builds(&self) -> u64 {
        self.nlist.builds
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
                // From the mass, not 1/I: a held or frozen grain has 1/I = 0.
                let inertia = 0.4 * s.mass[i] * s.radius[i] * s.radius[i];
                let r = 0.5 * inertia * norm2(s.angular_velocity[i]);
                t + r
            })
            .sum()
    }

    fn rebuild(&mut self, team: &Team) {
        let keep = self.cfg.laws.uses_history();
        self.nlist.rebuild(
            &mut self.state,
            &self.grid,
            self.cfg.skin,
            &self.cfg.walls,
            keep,
            team,
        );
        self.rebuild_pending = false;
        let n = self.state.len();
        if self.cfg.inlet.is_some() || self.cfg.removes_grains {
            let (s, skin) = (&self.state, self.cfg.skin);
            self.may_leave.clear();
            self.may_leave.extend(
                (0..n)
                    .filter(|&i| leave_margin(&self.cfg, s.position[i], s.radius[i]) <= skin)
                    .map(|i| i as u32),
            );
        }
        self.cut_chunks();
    }

    /// In place of a build when the drifts call for one: the grains that drifted more than
    /// a quarter of the skin listed again, if they are few
    /// ([`NeighborList::refresh_movers`]), with the outlet's list and the threads' chunks
    /// made to fit. None: a build is needed; else the largest drift of any grain from its
    /// reference left after it (m).
    fn refresh(&mut self, team: &Team) -> Option<Real> {
        let cfg = &self.cfg;
        let refreshed = self.nlist.refresh_movers(
            &mut self.state,
            &self.grid,
            cfg.skin,
            cfg.radius_max,
            &cfg.walls,
            MOVER_DRIFT_OF_SKIN * cfg.skin,
            MOVER_SHARE,
            team,
        )?;
        if cfg.inlet.is_some() || cfg.removes_grains {
            // As a build sets it, from the reference positions (the others' are their
            // build's, the movers' where they are now).
            let (reference, r) = (self.nlist.reference_positions(), &self.state.radius);
            self.may_leave.clear();
            self.may_leave.extend(
                (0..reference.len())
                    .filter(|&i| leave_margin(cfg, reference[i], r[i]) <= cfg.skin)
                    .map(|i| i as u32),
            );
        }
        self.cut_chunks();
        Some(refreshed.largest_drift)
    }

    /// The threads' chunks of the grains, cut by the list's work per grain.
    fn cut_chunks(&mut self) {
        let n = self.state.len();
        let chunks = self.cfg.threads.min((n / MIN_GRAINS_PER_CHUNK).max(1));
        if chunks > 1 {
            cut_by_cost(&self.nlist.cost, chunks, &mut self.bounds);
        } else {
            self.bounds.clear();
            self.bounds.extend([0, n]);
        }
    }

    /// Feed the grains the inlet owes (see [`Feeder::feed`]), or move the conveyor's
    /// column on (see [`NativeDem::convey`]). `max_drift`: the largest drift of any grain
    /// since its reference position (m) when no build is due before the next force pass;
    /// the fed grains then join the list without one ([`NeighborList::append`]).
    fn feed(&mut self, elapsed: Real, max_drift: Option<Real>) {
        if self.conveyor.is_some() {
            self.convey(elapsed, max_drift);
            return;
        }
        let placed = self.feeder.feed(
            &self.cfg,
            self.time,
            elapsed,
            self.state
                .position
                .iter()
                .zip(&self.state.radius)
                .map(|(x, r)| (*x, *r)),
            &mut self.rng,
        );
        if placed.is_empty() {
            return;
        }
        let append = self.before_adding(max_drift);
        let first = self.state.len();
        let v = Feeder::velocity(&self.cfg);
        let nw = self.cfg.walls.len();
        for (x, r) in placed {
            let id = self.next_id;
            self.next_id += 1;
            self.state.push(id, x, v, r, self.cfg.density, nw);
            self.flow.fed_count += 1;
            self.flow.fed_mass += *self.state.mass.last().expect("just pushed");
        }
        self.after_adding(first, append);
    }

    /// Before grains are pushed: the drift to append them with, when the list can take
    /// them without a build; otherwise the histories saved for the build that will.
    fn before_adding(&mut self, max_drift: Option<Real>) -> Option<Real> {
        let append = max_drift.filter(|_| self.nlist.can_append(self.state.len(), &self.grid));
        if append.is_none() && self.cfg.laws.uses_history() {
            self.nlist.stash_history(&self.state);
        }
        append
    }

    /// After grains [first, n) were pushed: their rows appended to the list (with what a
    /// build sets for them: the wall and outlet lists, the dashpot's predicted velocity,
    /// the threads' chunks), or a build called for.
    fn after_adding(&mut self, first: usize, append: Option<Real>) {
        let Some(max_drift) = append else {
            self.rebuild_pending = true;
            return;
        };
        let cfg = &self.cfg;
        self.nlist.append(
            &self.state,
            first,
            &self.grid,
            cfg.skin,
            cfg.radius_max,
            &cfg.walls,
            max_drift,
        );
        let n = self.state.len();
        let s = &self.state;
        if cfg.inlet.is_some() || cfg.removes_grains {
            self.may_leave.extend(
                (first..n)
                    .filter(|&i| leave_margin(cfg, s.position[i], s.radius[i]) <= cfg.skin)
                    .map(|i| i as u32),
            );
        }
        // As `predict_velocities(true)` would set them (a new grain has no force yet).
        self.predict_from(first, true);
        self.cut_chunks();
    }

    /// The conveyor inlet's part of a feed, `elapsed` s after the last: grains of the column
    /// held to the feed motion (1/m = 1/I = 0 and the feed velocity: the integrator moves
    /// them at it, forces and all) until their centre leaves the slab; the column moved on
    /// by the distance they moved; grains of it that came one radius into the tube added,
    /// held. At the first feed the grains already in the slab (a tube filled by another run)
    /// join the column. When the feed stops (`inlet.until`) every held grain is released.
    fn convey(&mut self, elapsed: Real, max_drift: Option<Real>) {
        let Some(mut column) = self.conveyor.take() else {
            return;
        };
        let feed_velocity = Feeder::velocity(&self.cfg);
        let s = &mut self.state;
        let inv_mass = &s.inv_mass;
        let feed = column.feed(
            &self.cfg,
            self.time,
            elapsed,
            &s.id,
            &s.position,
            &s.radius,
            |i| inv_mass[i] > 0.0,
            &mut self.rng,
        );
        for &i in &feed.hold {
            s.hold(i, feed_velocity);
        }
        for &i in &feed.release {
            s.release(i);
        }
        if !feed.enter.is_empty() {
            let append = self.before_adding(max_drift);
            let first = self.state.len();
            let nw = self.cfg.walls.len();
            for (x, r) in feed.enter {
                let id = self.next_id;
                self.next_id += 1;
                self.state
                    .push(id, x, feed_velocity, r, self.cfg.density, nw);
                let last = self.state.len() - 1;
                self.state.hold(last, feed_velocity);
                column.hold(id);
                self.flow.fed_count += 1;
                self.flow.fed_mass += self.state.mass[last];
            }
            self.after_adding(first, append);
        }
        self.conveyor = Some(column);
    }

    /// Remove grains past open ends, outside the box, or escaped from the tube. `near_build`:
    /// every grain is within one skin of where it was at the last neighbour build, and no
    /// grain was added or removed since: then only [`NativeDem::may_leave`]'s can have left.
    fn remove_leaving(&mut self, near_build: bool, team: &Team) -> Real {
        let n = self.state.len();
        let stays = |i: usize| {
            matches!(
                leave_verdict(&self.cfg, self.state.position[i], self.state.radius[i]),
                Leave::Stay
            )
        };
        let none_left = if near_build {
            self.may_leave.iter().all(|&i| stays(i as usize))
        } else {
            (0..n).all(stays)
        };
        if none_left {
            return 0.0;
        }
        let mut keep: Vec<usize> = Vec::with_capacity(n);
        let mut out_mass = 0.0;
        for i in 0..n {
            match leave_verdict(&self.cfg, self.state.position[i], self.state.radius[i]) {
                Leave::Stay => keep.push(i),
                Leave::Outlet => {
                    self.flow.outflow_count += 1;
                    self.flow.outflow_mass += self.state.mass[i];
                    out_mass += self.state.mass[i];
                }
                Leave::Lost => self.flow.lost_count += 1,
            }
        }
        let nw = self.cfg.walls.len();
        // Between builds the list is cut down to the grains that stay (a build re-sorts
        // every grain and searches every cell: grains leave ~1000 times a second at the
        // vertical case's outlet, as often as the drifts call for builds).
        if near_build && self.nlist.retain(&keep, n) {
            self.nlist.reorder_grains(&mut self.state, &keep, nw, team);
            let new_index = self.nlist.retained_index();
            self.may_leave.retain_mut(|i| {
                *i = new_index[*i as usize];
                *i != u32::MAX
            });
            self.cut_chunks();
            // The dashpots' velocities, as after a build (the grains were renumbered).
            self.predict_velocities(true);
            return out_mass;
        }
        if self.cfg.laws.uses_history() {
            self.nlist.stash_history(&self.state);
        }
        self.nlist.reorder_grains(&mut self.state, &keep, nw, team);
        self.rebuild_pending = true;
        out_mass
    }

    /// Forces on all grains for the current positions and predicted velocities.
    fn compute_forces(&mut self, team: &Team) {
        let NativeDem {
            cfg,
            state,
            nlist,
            bounds,
            spills,
            contact_scratch,
            chunk_wall_force,
            wall_force,
            velocity_pred,
            angular_velocity_pred,
            uniform,
            ..
        } = self;
        let job = ForceJob {
            uniform: *uniform,
            cfg,
            state,
            nlist,
            bounds,
            spills,
            contact_scratch,
            chunk_wall_force,
            wall_force,
            velocity_pred,
            angular_velocity_pred,
        };
        cfg.laws.visit(RunForces { job, team });
    }

    /// Velocities the dashpots see. Plain velocity-Verlet would hand them the half-step
    /// velocities, whose lag of dt/2 over-damps every collision by O(dt/t_c) (e = 0.5 came
    /// out as 0.493 at t_c/50); the integration phases predict v(t+dt) ≈ v(t+dt/2) + a(t) dt/2
    /// instead, an O((dt/t_c)²) error. This serial version serves after a neighbour build
    /// (which reorders grains) and at the start of `advance`, where `half_step` is false
    /// because the velocities are already full-step ones.
    fn predict_velocities(&mut self, half_step: bool) {
        self.velocity_pred.clear();
        self.angular_velocity_pred.clear();
        self.predict_from(0, half_step);
    }

    /// [`NativeDem::predict_velocities`] of grains [first, n), appended to the predictions.
    fn predict_from(&mut self, first: usize, half_step: bool) {
        let h = if half_step { 0.5 * self.cfg.dt } else { 0.0 };
        let s = &self.state;
        self.velocity_pred.extend((first..s.len()).map(|i| {
            let a = s.inv_mass[i] * h;
            let (v, f) = (s.velocity[i], s.force[i]);
            [v[0] + f[0] * a, v[1] + f[1] * a, v[2] + f[2] * a]
        }));
        if self.cfg.rotation {
            self.angular_velocity_pred.extend((first..s.len()).map(|i| {
                let b = s.inv_inertia[i] * h;
                let (w, t) = (s.angular_velocity[i], s.torque[i]);
                [w[0] + t[0] * b, w[1] + t[1] * b, w[2] + t[2] * b]
            }));
        } else {
            // No rotation: the force loop never reads these; keep the length right only.
            self.angular_velocity_pred.resize(s.len(), [0.0; 3]);
        }
    }

    /// One integration phase over all chunks: all speeds sane, and the two largest drifts
    /// since the last neighbour build (see [`ChunkVerdict::moved_far`]).
    fn integrate(&mut self, team: &Team, phase: Phase) -> ChunkVerdict {
        let (finish, start) = phase.parts();
        let kind = PassKind {
            dt: self.cfg.dt,
            finish,
            start,
            rotation: self.cfg.rotation,
        };
        let s = &mut self.state;
        let x_ref = self.nlist.reference_positions();
        let track = x_ref.len() == s.len();
        let cols = IntegrateColumns {
            force: Shared::new(&mut s.force),
            torque: Shared::new(&mut s.torque),
            velocity: Shared::new(&mut s.velocity),
            position: Shared::new(&mut s.position),
            angular_velocity: Shared::new(&mut s.angular_velocity),
            velocity_pred: Shared::new(&mut self.velocity_pred),
            angular_velocity_pred: Shared::new(&mut self.angular_velocity_pred),
            result: Shared::new(&mut self.chunk_result),
        };
        let (inv_mass, inv_inertia) = (&s.inv_mass, &s.inv_inertia);
        // The force chunks: each member integrates the grains whose forces it computed (their
        // lines are in its cache; cutting this pass by grain count instead, to balance it,
        // measured slower).
        let bounds = &self.bounds;
        let spills = &self.spills;
        team.run(bounds.len() - 1, &|c| {
            let (lo, hi) = (bounds[c], bounds[c + 1]);
            // SAFETY: the chunks [bounds[c], bounds[c+1]) are disjoint, and so is slot c.
            let (force, torque, result) = unsafe {
                (
                    cols.force.range(lo, hi),
                    cols.torque.range(lo, hi),
                    &mut cols.result.range(c, c + 1)[0],
                )
            };
            // Shares of this chunk's grains from pairs of other chunks (earlier ones for a
            // build's pairs, j > i; later ones too for appended rows, j < i), in chunk
            // order and list order (so the sums do not depend on which thread finished
            // first).
            for (_, spill) in spills.iter().enumerate().filter(|&(k, _)| k != c) {
                for sp in spill {
                    let j = sp.j as usize;
                    if (lo..hi).contains(&j) {
                        vec3::add_assign(&mut force[j - lo], sp.force);
                        if kind.rotation {
                            vec3::add_assign(&mut torque[j - lo], sp.torque);
                        }
                    }
                }
            }
            // SAFETY: as above.
            let chunk = unsafe {
                ChunkColumns {
                    force,
                    torque,
                    inv_mass: &inv_mass[lo..hi],
                    inv_inertia: &inv_inertia[lo..hi],
                    velocity: cols.velocity.range(lo, hi),
                    position: cols.position.range(lo, hi),
                    angular_velocity: cols.angular_velocity.range(lo, hi),
                    velocity_pred: cols.velocity_pred.range(lo, hi),
                    angular_velocity_pred: cols.angular_velocity_pred.range(lo, hi),
                    reference: track.then(|| &x_ref[lo..hi]),
                }
            };
            *result = integrate_chunk(chunk, kind);
        });
        // Applied: the next pass (a half kick with the same force) must not add them again.
        for spill in &mut self.spills {
            spill.clear();
        }
        self.chunk_result[..self.bounds.len() - 1]
            .iter()
            .fold(ChunkVerdict::CLEAN, |a, &b| a.and(b))
    }

    /// The error for the first grain whose state blew up.
    fn blowup_error(&self) -> BackendError {
        let s = &self.state;
        let bad = (0..s.len())
            .find(|&i| {
                let speed2 = norm2(s.velocity[i]);
                speed2.is_nan()
                    || speed2 >= BLOWUP_SPEED * BLOWUP_SPEED
                    || !is_finite(s.position[i])
                    || !is_finite(s.angular_velocity[i])
            })
            .unwrap_or(0);
        BackendError::NonFinite {
            step: self.step,
            particle_id: s.id.get(bad).copied().unwrap_or(0),
            what: format!(
                "blew up (speed above {BLOWUP_SPEED} m/s, or NaN): position {:?}, velocity {:?}, \
                 force {:?} (external {:?})",
                s.position[bad], s.velocity[bad], s.force[bad], s.external_force[bad]
            ),
        }
    }

    /// The steps of one `advance` call, with the team running.
    fn advance_with(&mut self, steps: u64, team: &Team) -> Result<(), BackendError> {
        let dt = self.cfg.dt;
        if self.rebuild_pending {
            let t0 = Instant::now();
            self.rebuild(team);
            self.predict_velocities(false);
            self.timer.add("neighbor", t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            self.compute_forces(team);
            self.timer.add("forces", t0.elapsed().as_secs_f64());
        }
        let t0 = Instant::now();
        let skin = self.cfg.skin;
        let mut verdict = self.integrate(team, Phase::KickDrift);
        let mut moved_far = verdict.moved_far(skin);
        self.timer.add("integrate", t0.elapsed().as_secs_f64());
        for k in 0..steps {
            self.time += dt;
            self.step += 1;
            let t1 = Instant::now();
            let mut t2 = t1;
            let mut refresh_refused = false;
            if self.step.is_multiple_of(FEED_STRIDE)
                && (self.cfg.inlet.is_some() || self.cfg.removes_grains)
            {
                // A build due at a feed: the far-drifted grains listed again first, when
                // they are few, so that the leaving grains are cut from the list and the
                // fed ones join it (a feed into the list due for a build calls one).
                let mut largest_drift = verdict.drift2[0].sqrt();
                if moved_far && !self.rebuild_pending {
                    if let Some(d) = self.refresh(team) {
                        self.predict_velocities(true);
                        (moved_far, largest_drift) = (false, d);
                    } else {
                        // (Refused at these positions: not asked again below.)
                        refresh_refused = true;
                    }
                    t2 = Instant::now();
                    self.timer.add("neighbor", (t2 - t1).as_secs_f64());
                }
                self.remove_leaving(!(moved_far || self.rebuild_pending), team);
                // (No build due: fed grains join the list as they are.)
                let no_build = !(moved_far || self.rebuild_pending);
                self.feed(FEED_STRIDE as Real * dt, no_build.then_some(largest_drift));
            }
            let t3 = Instant::now();
            self.timer.add("inlet_outlet", (t3 - t2).as_secs_f64());
            let t2 = t3;
            if self.rebuild_pending || moved_far {
                if self.rebuild_pending || refresh_refused || self.refresh(team).is_none() {
                    self.rebuild(team);
                }
                self.predict_velocities(true);
            }
            let t3 = Instant::now();
            self.timer.add("neighbor", (t3 - t2).as_secs_f64());
            self.compute_forces(team);
            let t4 = Instant::now();
            self.timer.add("forces", (t4 - t3).as_secs_f64());
            // The last half kick of this step and the first of the next use the same
            // force, so they run as one pass except at the end of the call.
            let phase = if k + 1 == steps {
                Phase::Kick
            } else {
                Phase::KickKickDrift
            };
            verdict = self.integrate(team, phase);
            self.timer.add("integrate", t4.elapsed().as_secs_f64());
            if !verdict.sane {
                return Err(self.blowup_error());
            }
            moved_far = verdict.moved_far(skin);
        }
        Ok(())
    }
}

/// Which half kicks an integration pass does.
#[derive(Clone, Copy)]
enum Phase {
    /// Start a step: half kick, drift, predict.
    KickDrift,
    /// Finish a step: half kick.
    Kick,
    /// Finish a step and start the next.
    KickKickDrift,
}

/// Bounds of `chunks` contiguous ranges of about equal summed `cost` (chunks + 1 entries):
/// a range ends at the first grain whose cost before it reaches its share.
fn cut_by_cost(cost: &[u64], chunks: usize, bounds: &mut Vec<usize>) {
    let total: u64 = cost.iter().sum();
    bounds.clear();
    bounds.push(0);
    let mut below = 0u64;
    for (i, &c) in cost.iter().enumerate() {
        if bounds.len() < chunks && below * chunks as u64 >= total * bounds.len() as u64 {
            bounds.push(i);
        }
        below += c;
    }
    while bounds.len() < chunks {
        bounds.push(cost.len());
    }
    bounds.push(cost.len());
}

impl Phase {
    /// (finishes a step, starts a step)
    fn parts(self) -> (bool, bool) {
        match self {
            Phase::KickDrift => (false, true),
            Phase::Kick => (true, false),
            Phase::KickKickDrift => (true, true),
        }
    }
}

/// Columns the integration phases write, shared over the team by disjoint chunks.
struct IntegrateColumns {
    force: Shared<Vec3>,
    torque: Shared<Vec3>,
    velocity: Shared<Vec3>,
    position: Shared<Vec3>,
    angular_velocity: Shared<Vec3>,
    velocity_pred: Shared<Vec3>,
    angular_velocity_pred: Shared<Vec3>,
    result: Shared<ChunkVerdict>,
}

/// Disjoint borrows of the engine for one force phase.
struct ForceJob<'a> {
    uniform: Option<UniformPair>,
    cfg: &'a DemConfig,
    state: &'a mut ParticleState,
    nlist: &'a mut NeighborList,
    bounds: &'a [usize],
    spills: &'a mut [Vec<Spill>],
    contact_scratch: &'a mut [ContactScratch],
    chunk_wall_force: &'a mut [Vec<Vec3>],
    wall_force: &'a mut [Vec3],
    velocity_pred: &'a [Vec3],
    angular_velocity_pred: &'a [Vec3],
}

/// The force job run on the scene's concrete law pair.
struct RunForces<'a, 't> {
    job: ForceJob<'a>,
    team: &'t Team,
}

impl config::LawVisitor for RunForces<'_, '_> {
    type Out = ();
    fn visit<N: NormalLaw, T: TangentialLaw>(self, laws: &Laws<N, T>) {
        // One arm per rolling law: each compiles its own force loop.
        match &self.job.cfg.rolling {
            RollingSet::None => {
                let free = RollingPair {
                    pp: NoRolling,
                    pw: NoRolling,
                };
                self.job.run(laws, &free, self.team)
            }
            RollingSet::ConstantTorque(r) => self.job.run(laws, r, self.team),
        }
    }
}

impl ForceJob<'_> {
    fn run<N: NormalLaw, T: TangentialLaw, R: RollingLaw>(
        self,
        laws: &Laws<N, T>,
        rolling: &RollingPair<R>,
        team: &Team,
    ) {
        let cfg = self.cfg;
        let nw = cfg.walls.len();
        let set = StepSettings {
            uniform: self.uniform,
            walls: &cfg.walls,
            gravity: cfg.gravity,
            dt: cfg.dt,
            rotation: cfg.rotation,
        };
        let s = self.state;
        let nl = self.nlist;
        if nl.history.len() != nl.partner.len() {
            nl.history.resize(nl.partner.len(), [0.0; 3]);
        }
        let force = Shared::new(&mut s.force);
        let torque = Shared::new(&mut s.torque);
        let wall_history = Shared::new(&mut s.wall_history);
        let history = Shared::new(&mut nl.history);
        let spills = Shared::new(self.spills);
        let scratch = Shared::new(self.contact_scratch);
        let wall_acc = Shared::new(self.chunk_wall_force);
        let g = GrainsIn {
            position: &s.position,
            velocity: self.velocity_pred,
            angular_velocity: self.angular_velocity_pred,
            radius: &s.radius,
            mass: &s.mass,
            external_force: &s.external_force,
        };
        let (start, partner) = (&nl.start[..], &nl.partner[..]);
        let inputs = ForceInputs {
            laws,
            rolling,
            set: &set,
            grains: g,
            start,
            partner,
            offset: &nl.offset,
            near_wall: &nl.near_wall,
        };
        let bounds = self.bounds;
        let active = bounds.len() - 1;
        team.run(active, &|c| {
            let (lo, hi) = (bounds[c], bounds[c + 1]);
            let (hlo, hhi) = (start[lo] as usize, start[hi] as usize);
            // SAFETY: chunk c owns grains [lo, hi), their pair rows [start[lo], start[hi]),
            // their wall histories, and slot c of the spill, scratch and wall-force lists; the chunks
            // are disjoint.
            let out = unsafe {
                let spill = &mut spills.range(c, c + 1)[0];
                spill.clear();
                ChunkOut {
                    lo,
                    force: force.range(lo, hi),
                    torque: torque.range(lo, hi),
                    history: history.range(hlo, hhi),
                    wall_history: wall_history.range(lo * nw, hi * nw),
                    spill,
                    wall_force: &mut wall_acc.range(c, c + 1)[0],
                    scratch: &mut scratch.range(c, c + 1)[0],
                }
            };
            chunk_forces(inputs, out);
        });
        // Partner shares across chunk boundaries wait in the spill lists: the integration
        // pass that follows adds them, each chunk its own grains' in parallel. Wall forces
        // here, in chunk order.
        for w in 0..nw {
            self.wall_force[w] = [0.0; 3];
            for acc in self.chunk_wall_force[..active].iter() {
                vec3::add_assign(&mut self.wall_force[w], acc[w]);
            }
        }
    }
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
        if steps == 0 {
            return Ok(());
        }
        let team = self.threads.team();
        self.advance_with(steps, &team)
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
        // force for the new one in it rather than recomputing all contacts. Each member
        // over its own chunk (the grains whose force it computes: their lines are in its
        // cache).
        let s = &mut self.state;
        let total = Shared::new(&mut s.force);
        let held = Shared::new(&mut s.external_force);
        let bounds = &self.bounds;
        let chunks = if bounds.len() >= 2 && bounds[bounds.len() - 1] == force.len() {
            bounds.len() - 1
        } else {
            1
        };
        let team = self.threads.team();
        team.run(chunks, &|c| {
            let (lo, hi) = if chunks == 1 {
                (0, force.len())
            } else {
                (bounds[c], bounds[c + 1])
            };
            // SAFETY: the chunks are disjoint.
            let (total, held) = unsafe { (total.range(lo, hi), held.range(lo, hi)) };
            for ((t, h), new) in total.iter_mut().zip(held.iter_mut()).zip(&force[lo..hi]) {
                for k in 0..3 {
                    t[k] += new[k] - h[k];
                }
                *h = *new;
            }
        });
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
            if p.radius != self.cfg.radius_min
                || p.radius != self.cfg.radius_max
                || p.density != self.cfg.density
            {
                // A grain unlike the scene's: pair constants must come per pair from now on.
                self.uniform = None;
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
        let team = self.threads.team();
        Ok(self.remove_leaving(false, &team))
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

    fn team(&self) -> Option<std::sync::Arc<Team>> {
        (self.cfg.threads > 1).then(|| self.threads.team())
    }

    fn diagnostics(&self) -> Vec<(String, f64)> {
        let mut d = vec![("neighbor_builds".into(), self.neighbor_builds() as f64)];
        if !self.upkeep_unknown_before_resume {
            let u = self.nlist.upkeep;
            d.push(("neighbor_refreshes".into(), u.refreshes as f64));
            d.push(("neighbor_appends".into(), u.appends as f64));
        }
        d.push((
            "inlet_backlog_grains".into(),
            self.feeder.backlog + self.conveyor.as_ref().map_or(0.0, |c| c.unplaced as Real),
        ));
        d.push(("inlet_blocked_time_s".into(), self.feeder.blocked_time));
        d
    }

    /// The step's total force less gravity and the fluid force: what the contacts gave.
    fn contact_forces(&self) -> Option<Vec<Vec3>> {
        let s = &self.state;
        let g = self.cfg.gravity;
        Some(
            (0..s.len())
                .map(|i| {
                    let (f, e, m) = (s.force[i], s.external_force[i], s.mass[i]);
                    [0, 1, 2].map(|k| f[k] - m * g[k] - e[k])
                })
                .collect(),
        )
    }

    fn save_state(&mut self) -> Result<Vec<u8>, BackendError> {
        checkpoint::save(self)
    }

    fn restore_state(&mut self, state: &[u8]) -> Result<(), BackendError> {
        checkpoint::restore(self, state)
    }

    fn start_from_state(&mut self, state: &[u8]) -> Result<(), BackendError> {
        checkpoint::start_from(self, state)
    }

    fn flow(&self) -> Option<plugflow_coupling::GrainFlow> {
        let f = &self.flow;
        Some(plugflow_coupling::GrainFlow {
            fed_count: f.fed_count,
            fed_mass: f.fed_mass,
            outflow_count: f.outflow_count,
            outflow_mass: f.outflow_mass,
            lost_count: f.lost_count,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::cut_by_cost;

    /// Each range's cost lies within one grain's cost of an equal share, ranges are
    /// contiguous and cover all grains, and more chunks than grains leave empty ranges.
    #[test]
    fn chunks_cut_by_cost_carry_equal_shares() {
        let mut bounds = Vec::new();
        // A dense bottom (heavy grains first), as in a settled bed.
        let cost: Vec<u64> = (0..1000).map(|i| if i < 300 { 30 } else { 10 }).collect();
        let total: u64 = cost.iter().sum();
        for chunks in [1, 2, 3, 7] {
            cut_by_cost(&cost, chunks, &mut bounds);
            assert_eq!(bounds.len(), chunks + 1);
            assert_eq!((bounds[0], bounds[chunks]), (0, cost.len()));
            for c in 0..chunks {
                let share: u64 = cost[bounds[c]..bounds[c + 1]].iter().sum();
                let target = total as f64 / chunks as f64;
                assert!(
                    (share as f64 - target).abs() <= 30.0,
                    "{chunks} chunks: chunk {c} carries {share}, target {target}"
                );
            }
        }
        // 16 000 in all: the cut falls where 8 000 is reached, at grain 267 (30 each before
        // 300). A cut by grain count would have put 11 000 against 5 000.
        cut_by_cost(&cost, 2, &mut bounds);
        assert_eq!(bounds, vec![0, 267, 1000]);
        cut_by_cost(&[5, 5], 4, &mut bounds);
        assert_eq!(bounds, vec![0, 1, 2, 2, 2]);
    }
}
