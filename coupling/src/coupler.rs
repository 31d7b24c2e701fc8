//! The coupled step of shared/DESIGN.md, whole, in one place: [`Coupler::advance`] takes
//! the DEM forward by any number of steps, one coupling interval Δt_c = n_sub · Δt_dem at a
//! time, and around each interval runs the stages in this order:
//!
//! ```text
//!   DEM advance (n_sub steps, fluid force held)      Stage::DemAdvance (the engine's own timers)
//!   → deposit φ_j, u_j on the gas nodes               Stage::Deposit
//!     (under MPI: node sums added over the ranks)     Stage::ReduceRanks
//!   → gas step over the interval just advanced        Stage::Gas  (+ Stage::AccuracyCheck)
//!   → interpolate ∇P_i, φ_i, u_i and the drag law     Stage::InterpolateDrag
//!   → fluid forces to the DEM                         Stage::SetForces
//! ```
//!
//! A run whose length is not a whole number of intervals ends with a shorter one: the DEM
//! advances the remaining steps and the gas steps over exactly that time.

use crate::checks::CouplingCheck;
use crate::fluid_force::{vorticity::vorticity, FluidForce};
use crate::grid::{
    deposit_part, finish_deposit, interpolate_scalar, interpolate_vec3, GranularFields, NodeSums,
    Stencil, TubeGrid,
};
use crate::team::{share, Shared, Team};
use crate::{
    BackendError, DemBackend, DragLaw, GasError, GasSolver, GrainInFluid, Ranks, Real, Reduce,
    StageTimer, Vec3,
};
use std::sync::Arc;

/// The timed stages of the coupled step, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Grains' volume and velocity onto the gas nodes.
    Deposit,
    /// Under MPI: the deposited node sums (and the fed grains' volume) added over the ranks.
    ReduceRanks,
    /// The step-doubling estimate of the gas time error (every [`DOUBLING_EVERY`] exchanges).
    AccuracyCheck,
    /// The gas solver over one interval.
    Gas,
    /// Fields back to the grains and the drag law on each.
    InterpolateDrag,
    /// The fluid forces handed to the DEM engine.
    SetForces,
}

impl Stage {
    /// The stage's name in `summary.json`'s `stage_times_s`.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Deposit => "deposit",
            Stage::ReduceRanks => "reduce_ranks",
            Stage::AccuracyCheck => "accuracy_check",
            Stage::Gas => "gas",
            Stage::InterpolateDrag => "interpolate_drag",
            Stage::SetForces => "set_forces",
        }
    }
}

/// Errors of the exchange.
#[derive(Debug, thiserror::Error)]
pub enum ExchangeError {
    #[error(transparent)]
    Gas(#[from] GasError),
    #[error(transparent)]
    Backend(#[from] BackendError),
    /// A drag force became NaN or infinite.
    #[error("drag force not finite on grain id {particle_id} at t = {time:.6} s (porosity {porosity}, ∇P {gradient:?})")]
    Drag {
        particle_id: u64,
        time: Real,
        porosity: Real,
        gradient: Vec3,
    },
    /// Another rank of an engine under MPI failed in this exchange (its own words).
    #[error("rank {rank} of the engine failed: {message}")]
    OtherRank { rank: usize, message: String },
}

/// What stopped a coupled advance, with the simulated time it stopped at.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    /// The DEM engine failed (NaN, blow-up, engine failure).
    #[error("run stopped at t = {time:.6} s: {source}")]
    Backend { time: Real, source: BackendError },
    /// The gas or the exchange failed (NaN pressure, drag).
    #[error("run stopped at t = {time:.6} s: {source}")]
    Exchange { time: Real, source: ExchangeError },
}

/// Every this many exchanges the gas step is also taken as two half steps (from the same
/// state, discarded) to estimate its time error: three extra gas steps per hundred.
pub const DOUBLING_EVERY: u64 = 100;

/// Sums of what the exchanges saw, for the run's accuracy report.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct CouplingStats {
    /// Node-steps whose porosity was clamped, and node-steps in all.
    pub clamped: u64,
    pub node_steps: u64,
    /// Node-steps clamped up to φ_min (over-packed nodes).
    pub clamped_low: u64,
    /// Largest relative gas-mass imbalance of any step.
    pub mass_error_max: Real,
    /// Step-doubling estimates of the gas time error: how many, their largest and sum.
    pub doubling_checks: u64,
    pub doubling_max: Real,
    pub doubling_sum: Real,
}

/// What a coupler carries from one exchange to the next, for a checkpoint (taken between
/// exchanges: the deposited fields and forces are made again by the next one).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct CouplerState {
    pub exchanges: u64,
    pub stats: CouplingStats,
    pub first_new_id: Option<u64>,
    /// The stages' wall times so far, s.
    pub timer: Vec<(String, f64)>,
    /// The gas solver's own state ([`GasSolver::save_state`]).
    pub gas: Vec<u8>,
}

/// A gas solver and a drag law coupled to a DEM backend.
pub struct Coupler {
    /// The gas solver.
    pub gas: Box<dyn GasSolver>,
    drag: Arc<dyn DragLaw>,
    /// The fluid forces besides the drag the scene switched on (`coupling.fluid_forces`).
    fluid_forces: Vec<Arc<dyn FluidForce>>,
    fields: GranularFields,
    /// DEM steps per coupling interval.
    pub substeps: u64,
    /// DEM time step, s.
    dem_dt: Real,
    /// Coupling interval, s.
    pub interval: Real,
    /// Checks made before the run.
    pub checks: Vec<CouplingCheck>,
    /// Time of each coupling stage.
    pub timer: StageTimer,
    /// What the exchanges saw so far.
    pub stats: CouplingStats,
    /// Exchanges so far.
    exchanges: u64,
    forces: Vec<Vec3>,
    /// Scratch of the deposit: each member's node sums.
    sums: Vec<NodeSums>,
    /// Scratch of the deposit under MPI: the node sums in one buffer for the reduction.
    reduce_buffer: Vec<f64>,
    /// The deposit spread over a length (`coupling.smoothing_length`); None: as deposited.
    smoothing: Option<crate::grid::Smoothing>,
    /// Scratch of the interpolation: each member's first grain whose drag is not finite.
    bad: Vec<Option<usize>>,
    /// Grains with ids from this one on are new since the last exchange (None before the
    /// first): engines number grains in the order they create them.
    first_new_id: Option<u64>,
}

impl Coupler {
    /// Couple `gas` and `drag` (and the further `fluid_forces`) with `substeps` DEM steps of
    /// `dem_dt` per exchange.
    pub fn new(
        gas: Box<dyn GasSolver>,
        drag: Arc<dyn DragLaw>,
        fluid_forces: Vec<Arc<dyn FluidForce>>,
        substeps: u64,
        dem_dt: Real,
        checks: Vec<CouplingCheck>,
    ) -> Self {
        Self {
            gas,
            drag,
            fluid_forces,
            fields: GranularFields::default(),
            substeps,
            dem_dt,
            interval: substeps as Real * dem_dt,
            checks,
            timer: StageTimer::new(),
            stats: CouplingStats::default(),
            exchanges: 0,
            forces: Vec::new(),
            sums: Vec::new(),
            reduce_buffer: Vec::new(),
            smoothing: None,
            bad: Vec::new(),
            first_new_id: None,
        }
    }

    /// Spread every deposit over `length` (m) before the gas and the drag read it.
    pub fn set_smoothing(&mut self, length: Real) {
        self.smoothing = Some(crate::grid::Smoothing::new(self.gas.grid(), length));
    }

    /// Diffusion passes per exchange of the deposit's smoothing (None: not smoothed).
    pub fn smoothing_passes(&self) -> Option<usize> {
        self.smoothing.as_ref().map(|s| s.passes())
    }

    /// The state a checkpoint keeps (see [`CouplerState`]).
    pub fn save_state(&self) -> Result<CouplerState, GasError> {
        Ok(CouplerState {
            exchanges: self.exchanges,
            stats: self.stats.clone(),
            first_new_id: self.first_new_id,
            timer: self.timer.entries(),
            gas: self.gas.save_state()?,
        })
    }

    /// Go on from a checkpoint's state (a coupler built from the same scene).
    pub fn restore_state(&mut self, state: &CouplerState) -> Result<(), GasError> {
        self.gas.restore_state(&state.gas)?;
        self.exchanges = state.exchanges;
        self.stats = state.stats.clone();
        self.first_new_id = state.first_new_id;
        self.timer = StageTimer::from_entries(&state.timer);
        Ok(())
    }

    /// Start from the gas of a checkpoint (another run's, the same grid) with this
    /// coupler's own settings: its inlet velocity, no exchanges yet, fresh statistics.
    pub fn start_from_state(&mut self, state: &CouplerState) -> Result<(), GasError> {
        let inlet = self.gas.superficial_velocity();
        self.gas.restore_state(&state.gas)?;
        self.gas.set_superficial_velocity(inlet);
        Ok(())
    }

    /// Advance the coupled system by `steps` DEM steps: whole coupling intervals, then a
    /// shorter last one if `steps` is not a multiple of [`Coupler::substeps`].
    pub fn advance(&mut self, dem: &mut dyn DemBackend, steps: u64) -> Result<(), StepError> {
        let mut left = steps;
        while left > 0 {
            let k = self.substeps.min(left);
            dem.advance(k).map_err(|source| StepError::Backend {
                time: dem.time(),
                source,
            })?;
            self.exchange_over(dem, k as Real * self.dem_dt)
                .map_err(|source| StepError::Exchange {
                    time: dem.time(),
                    source,
                })?;
            left -= k;
        }
        Ok(())
    }

    /// One exchange after the DEM has advanced one whole coupling interval.
    pub fn exchange(&mut self, dem: &mut dyn DemBackend) -> Result<(), ExchangeError> {
        self.exchange_over(dem, self.interval)
    }

    /// One exchange after the DEM has advanced `span` seconds: the stages of the step.
    fn exchange_over(&mut self, dem: &mut dyn DemBackend, span: Real) -> Result<(), ExchangeError> {
        let ranks = dem.ranks();
        let t = std::time::Instant::now();
        let reduced = self.deposit(dem, ranks)?;
        self.timer
            .add(Stage::Deposit.name(), t.elapsed().as_secs_f64() - reduced);
        if ranks.size > 1 {
            self.timer.add(Stage::ReduceRanks.name(), reduced);
        }
        self.gas_step(span)?;
        let t = std::time::Instant::now();
        let drag = self.interpolate_drag(dem);
        if ranks.size > 1 {
            // A rank whose drag failed stops every rank here, with its words.
            let mine = drag.as_ref().err().map(|e| e.to_string());
            if let Some((rank, message)) = crate::ranks::first_failure(dem, mine.as_deref())? {
                return Err(match drag {
                    Err(e) => e,
                    Ok(()) => ExchangeError::OtherRank { rank, message },
                });
            }
        }
        drag?;
        self.timer
            .add(Stage::InterpolateDrag.name(), t.elapsed().as_secs_f64());
        let t = std::time::Instant::now();
        dem.set_fluid_forces(&self.forces, None)?;
        self.timer
            .add(Stage::SetForces.name(), t.elapsed().as_secs_f64());
        Ok(())
    }

    /// Deposit: solid fraction and granular velocity on the nodes, and the volume of the
    /// grains fed since the last exchange (their gas enters with them). Under MPI each
    /// rank deposits its own grains and the node sums are added over the ranks (one
    /// reduction of 5 values per node): every rank then steps the same gas.
    /// Returns the seconds spent adding over the ranks.
    fn deposit(&mut self, dem: &dyn DemBackend, ranks: Ranks) -> Result<f64, ExchangeError> {
        let mut reduced = 0.0;
        let grid: &TubeGrid = self.gas.grid();
        let p = dem.particles();
        let (x, v, r) = (p.position, p.velocity, p.radius);
        let n = x.len();
        let team = dem.team();
        let members = members_for(team.as_deref(), n);
        self.fields.stencils.resize(n, None);
        self.sums.resize_with(members, NodeSums::default);
        match team {
            Some(team) if members > 1 => {
                let stencils = Shared::new(&mut self.fields.stencils);
                let sums = Shared::new(&mut self.sums[..members]);
                team.run(members, &|m| {
                    let (lo, hi) = share(n, members, m);
                    // SAFETY: member m alone writes stencils lo..hi and sums slot m.
                    let (stencils, sums) =
                        unsafe { (stencils.range(lo, hi), &mut sums.range(m, m + 1)[0]) };
                    deposit_part(grid, &x[lo..hi], &v[lo..hi], &r[lo..hi], stencils, sums);
                });
            }
            _ => deposit_part(grid, x, v, r, &mut self.fields.stencils, &mut self.sums[0]),
        }
        let members = match ranks.size {
            1 => members,
            _ => {
                let t = std::time::Instant::now();
                sum_over_ranks(dem, &mut self.sums[..members], &mut self.reduce_buffer)?;
                reduced += t.elapsed().as_secs_f64();
                1
            }
        };
        finish_deposit(grid, &self.sums[..members], &mut self.fields);
        // The grains fed since the last exchange, on the nodes (their stencils are the
        // deposit's).
        let fed = &mut self.fields.fed_solid;
        fed.clear();
        if ranks.size > 1 && self.first_new_id.is_some() {
            // Every rank holds the same node list (a rank may have fed none).
            fed.resize(grid.len(), 0.0);
        }
        if let Some(first_new) = self.first_new_id {
            // (The ids first: contiguous, and most grains are not new, so their 100-byte
            // stencils are not read.)
            for (i, &id) in p.id.iter().enumerate() {
                if id < first_new {
                    continue;
                }
                let Some(st) = &self.fields.stencils[i] else {
                    continue;
                };
                if fed.is_empty() {
                    fed.resize(grid.len(), 0.0);
                }
                let v = 4.0 / 3.0 * std::f64::consts::PI * p.radius[i].powi(3);
                for k in 0..st.len as usize {
                    fed[st.node[k] as usize] += v * st.weight[k];
                }
            }
            if ranks.size > 1 {
                let t = std::time::Instant::now();
                dem.all_reduce(fed, Reduce::Sum)?;
                reduced += t.elapsed().as_secs_f64();
            }
            for (f, vol) in fed.iter_mut().zip(&grid.volume) {
                *f /= vol.max(1e-300);
            }
        }
        let floor = self.first_new_id.unwrap_or(0);
        let mut next = p.id.iter().map(|&id| id + 1).fold(floor, u64::max);
        if ranks.size > 1 {
            // (Ids below 2⁵³ pass through an f64 exactly.)
            let t = std::time::Instant::now();
            let mut m = [next as f64];
            dem.all_reduce(&mut m, Reduce::Max)?;
            next = m[0] as u64;
            reduced += t.elapsed().as_secs_f64();
        }
        self.first_new_id = Some(next);
        if let Some(smoothing) = self.smoothing.as_mut() {
            smoothing.apply(self.gas.grid(), &mut self.fields);
        }
        Ok(reduced)
    }

    /// The gas over `span` seconds, with its step-doubling error estimate every
    /// [`DOUBLING_EVERY`] exchanges.
    fn gas_step(&mut self, span: Real) -> Result<(), ExchangeError> {
        let nodes = self.gas.grid().len();
        // (Not at the first exchange: the gas starts there from rest, an impulsive start
        // whose error says nothing about the run's.)
        if self.exchanges > 0 && self.exchanges.is_multiple_of(DOUBLING_EVERY) {
            let t = std::time::Instant::now();
            if let Some(e) = self.gas.step_doubling_error(&self.fields, span)? {
                let s = &mut self.stats;
                s.doubling_checks += 1;
                s.doubling_max = s.doubling_max.max(e);
                s.doubling_sum += e;
            }
            self.timer
                .add(Stage::AccuracyCheck.name(), t.elapsed().as_secs_f64());
        }
        self.exchanges += 1;
        let t = std::time::Instant::now();
        let report = self.gas.step(&self.fields, span)?;
        self.timer.add(Stage::Gas.name(), t.elapsed().as_secs_f64());
        let s = &mut self.stats;
        s.clamped += report.clamped_nodes as u64;
        s.clamped_low += report.clamped_low_nodes as u64;
        s.node_steps += nodes as u64;
        s.mass_error_max = s.mass_error_max.max(report.mass_error_rel);
        Ok(())
    }

    /// Interpolate the gas fields to each grain and evaluate the drag law on it (on the
    /// engine's team when it lends one: each member over its own grains).
    fn interpolate_drag(&mut self, dem: &dyn DemBackend) -> Result<(), ExchangeError> {
        let time = dem.time();
        let grad = self.gas.pressure_gradient();
        let gas_u = self.gas.gas_velocity();
        let gas_density = self.gas.gas_density();
        // The curl of the gas velocity only for a scene whose forces read it.
        let vort = match &gas_u {
            Some(u) if self.fluid_forces.iter().any(|f| f.needs_vorticity()) => {
                Some(vorticity(self.gas.grid(), u))
            }
            _ => None,
        };
        let fields = GasAtNodes {
            porosity: self.gas.porosity(),
            pressure_gradient: &grad,
            gas_velocity: gas_u.as_deref(),
            gas_density: gas_density.as_deref(),
            vorticity: vort.as_deref(),
        };
        let p = dem.particles();
        let (v, r) = (p.velocity, p.radius);
        let n = v.len();
        let team = dem.team();
        let members = members_for(team.as_deref(), n);
        self.forces.resize(n, [0.0; 3]);
        self.bad.clear();
        self.bad.resize(members, None);
        let forces_of = FluidForcesOf {
            drag: &*self.drag,
            more: &self.fluid_forces,
        };
        let stencils = &self.fields.stencils[..];
        match team {
            Some(team) if members > 1 => {
                let forces = Shared::new(&mut self.forces);
                let bad = Shared::new(&mut self.bad);
                team.run(members, &|m| {
                    let (lo, hi) = share(n, members, m);
                    // SAFETY: member m alone writes forces lo..hi and slot m.
                    let (forces, bad) =
                        unsafe { (forces.range(lo, hi), &mut bad.range(m, m + 1)[0]) };
                    *bad = drag_on(
                        &forces_of,
                        &fields,
                        &stencils[lo..hi],
                        &v[lo..hi],
                        &r[lo..hi],
                        forces,
                    )
                    .map(|k| lo + k);
                });
            }
            _ => self.bad[0] = drag_on(&forces_of, &fields, stencils, v, r, &mut self.forces),
        }
        if let Some(i) = self.bad.iter().flatten().copied().min() {
            let st = self.fields.stencils[i].expect("only grains with a stencil get a drag");
            return Err(ExchangeError::Drag {
                particle_id: p.id[i],
                time,
                porosity: interpolate_scalar(&st, fields.porosity),
                gradient: interpolate_vec3(&st, &grad),
            });
        }
        Ok(())
    }

    /// The fluid force on every grain from the last exchange, N (in the particle order of
    /// that exchange).
    pub fn fluid_forces(&self) -> &[Vec3] {
        &self.forces
    }

    /// Pressure drop per length, Pa/m.
    pub fn pressure_drop(&self) -> Real {
        self.gas.pressure_drop_per_length()
    }

    /// The granular fields of the last exchange (porosity, velocity on the nodes).
    pub fn granular_fields(&self) -> &GranularFields {
        &self.fields
    }

    /// Deposited porosity along the axis (cross-section mean by accessible volume).
    pub fn porosity_profile(&self) -> Vec<Real> {
        self.section_means(&self.fields.porosity, 1.0)
    }

    /// Gas pressure P − P0 along the axis, Pa (cross-section mean by accessible volume).
    pub fn pressure_profile(&self) -> Vec<Real> {
        self.section_means(self.gas.pressure(), 0.0)
    }

    /// Node positions along the axis, m (cell centres from the inlet end).
    pub fn axial_positions(&self) -> Vec<Real> {
        let g = self.gas.grid();
        (0..g.nz).map(|k| (k as Real + 0.5) * g.dz).collect()
    }

    /// Volume-weighted cross-section means of a node field (`missing` where the field is
    /// not yet filled).
    fn section_means(&self, field: &[Real], missing: Real) -> Vec<Real> {
        let g = self.gas.grid();
        (0..g.nz)
            .map(|k| {
                let (mut s, mut v) = (0.0, 0.0);
                for j in 0..g.ny {
                    for i in 0..g.nx {
                        let n = g.node(k, i, j);
                        s += field.get(n).copied().unwrap_or(missing) * g.volume[n];
                        v += g.volume[n];
                    }
                }
                s / v
            })
            .collect()
    }
}

/// Members of the engine's team worth using for `n` grains (1: no team, or too few grains
/// for the sync to pay).
/// Add the members' node sums and then the ranks' into `sums[0]` (members in member
/// order, ranks in the reduction's fixed order: reproducible for a rank and thread count).
fn sum_over_ranks(
    dem: &dyn DemBackend,
    sums: &mut [NodeSums],
    buffer: &mut Vec<f64>,
) -> Result<(), BackendError> {
    let n = sums[0].node.len();
    buffer.clear();
    buffer.resize(4 * n, 0.0);
    for part in sums.iter() {
        for (b, add) in buffer.iter_mut().zip(part.node.iter().flatten()) {
            *b += add;
        }
    }
    dem.all_reduce(buffer, Reduce::Sum)?;
    for (sum, b) in sums[0].node.iter_mut().zip(buffer.chunks_exact(4)) {
        sum.copy_from_slice(b);
    }
    Ok(())
}

fn members_for(team: Option<&Team>, n: usize) -> usize {
    /// Fewest grains per member worth a share of their own.
    const MIN_GRAINS_PER_MEMBER: usize = 512;
    team.map_or(1, |t| t.members_for(n, MIN_GRAINS_PER_MEMBER))
}

/// The gas fields on the nodes that the drag law reads.
struct GasAtNodes<'a> {
    porosity: &'a [Real],
    pressure_gradient: &'a [Vec3],
    gas_velocity: Option<&'a [Vec3]>,
    gas_density: Option<&'a [Real]>,
    vorticity: Option<&'a [Vec3]>,
}

/// Everything the gas does to a grain: the drag and the further fluid forces.
struct FluidForcesOf<'a> {
    drag: &'a dyn DragLaw,
    more: &'a [Arc<dyn FluidForce>],
}

/// The fluid force (drag, then each further force in the scene's order) on each grain with
/// a stencil (zero on the others) into `forces`; the index of the first grain whose force
/// is not finite, if any.
fn drag_on(
    of: &FluidForcesOf<'_>,
    gas: &GasAtNodes<'_>,
    stencils: &[Option<Stencil>],
    velocity: &[Vec3],
    radius: &[Real],
    forces: &mut [Vec3],
) -> Option<usize> {
    for i in 0..forces.len() {
        // The grains have not moved since the deposit: reuse its stencils.
        // (By reference: a stencil is 100 bytes.)
        let Some(st) = &stencils[i] else {
            forces[i] = [0.0; 3];
            continue;
        };
        let r = radius[i];
        let grain = GrainInFluid {
            volume: 4.0 / 3.0 * std::f64::consts::PI * r * r * r,
            diameter: 2.0 * r,
            velocity: velocity[i],
            porosity: interpolate_scalar(st, gas.porosity),
            pressure_gradient: interpolate_vec3(st, gas.pressure_gradient),
            gas_velocity: gas
                .gas_velocity
                .map_or([0.0; 3], |u| interpolate_vec3(st, u)),
            gas_density: gas
                .gas_density
                .map_or(0.0, |rho| interpolate_scalar(st, rho)),
            vorticity: gas.vorticity.map_or([0.0; 3], |w| interpolate_vec3(st, w)),
        };
        let mut f = of.drag.force(&grain);
        for more in of.more {
            let g = more.force(&grain);
            f = [f[0] + g[0], f[1] + g[1], f[2] + g[2]];
        }
        if !(f[0].is_finite() && f[1].is_finite() && f[2].is_finite()) {
            return Some(i);
        }
        forces[i] = f;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DarcyVolumeForce, GasStepReport, ImplicitDrag, NewParticle, ParticleView};

    /// An engine without grains that counts its steps.
    struct Steps {
        dt: Real,
        steps: u64,
    }

    impl DemBackend for Steps {
        fn engine_name(&self) -> &str {
            "steps"
        }
        fn engine_version(&self) -> String {
            String::new()
        }
        fn time_step(&self) -> Real {
            self.dt
        }
        fn time(&self) -> Real {
            self.steps as Real * self.dt
        }
        fn step_count(&self) -> u64 {
            self.steps
        }
        fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
            self.steps += steps;
            Ok(())
        }
        fn particles(&self) -> ParticleView<'_> {
            ParticleView {
                id: &[],
                position: &[],
                velocity: &[],
                angular_velocity: &[],
                radius: &[],
                mass: &[],
            }
        }
        fn set_fluid_forces(
            &mut self,
            _: &[Vec3],
            _: Option<ImplicitDrag<'_>>,
        ) -> Result<(), BackendError> {
            Ok(())
        }
        fn insert(&mut self, _: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
            Ok(Vec::new())
        }
        fn remove_past_outlet(&mut self) -> Result<Real, BackendError> {
            Ok(0.0)
        }
        fn wall_forces(&self) -> Vec<crate::WallForce> {
            Vec::new()
        }
        fn stage_times(&self) -> Vec<(String, f64)> {
            Vec::new()
        }
    }

    /// A gas that records the span of every step it is asked to take.
    struct Spans {
        grid: TubeGrid,
        spans: std::rc::Rc<std::cell::RefCell<Vec<Real>>>,
        zeros: Vec<Real>,
    }

    impl GasSolver for Spans {
        fn name(&self) -> &'static str {
            "spans"
        }
        fn grid(&self) -> &TubeGrid {
            &self.grid
        }
        fn set_superficial_velocity(&mut self, _: Real) {}
        fn superficial_velocity(&self) -> Real {
            0.0
        }
        fn step(&mut self, _: &GranularFields, dt: Real) -> Result<GasStepReport, GasError> {
            self.spans.borrow_mut().push(dt);
            Ok(GasStepReport::default())
        }
        fn pressure(&self) -> &[Real] {
            &self.zeros
        }
        fn porosity(&self) -> &[Real] {
            &self.zeros
        }
        fn pressure_gradient(&self) -> Vec<Vec3> {
            vec![[0.0; 3]; self.zeros.len()]
        }
        fn pressure_drop_per_length(&self) -> Real {
            0.0
        }
    }

    /// 25 steps at 10 per interval: two whole intervals, then the gas steps over exactly
    /// the 5 steps the DEM advanced (it used to step a whole interval after them).
    #[test]
    fn a_last_partial_interval_steps_the_gas_over_what_the_dem_advanced() {
        let grid = TubeGrid::new([0.0; 3], [0.0, 0.0, 1.0], 0.01, 0.1, 10, 1, 1);
        let zeros = vec![0.0; grid.len()];
        let spans = std::rc::Rc::new(std::cell::RefCell::new(Vec::new()));
        let gas = Spans {
            grid,
            spans: spans.clone(),
            zeros,
        };
        let dt = 1e-5;
        let mut c = Coupler::new(
            Box::new(gas),
            Arc::new(DarcyVolumeForce),
            Vec::new(),
            10,
            dt,
            Vec::new(),
        );
        let mut dem = Steps { dt, steps: 0 };
        c.advance(&mut dem, 25).unwrap();
        assert_eq!(dem.step_count(), 25);
        let spans = spans.borrow().clone();
        assert_eq!(spans, vec![10.0 * dt, 10.0 * dt, 5.0 * dt]);
        let total: Real = spans.iter().sum();
        assert!((total - dem.time()).abs() <= 1e-15 * dem.time());
    }
}
