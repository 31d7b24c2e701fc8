//! The grains of every rank in one place, for what a run measures and writes (samples,
//! figures, the summary), when the engine runs under MPI: gathered once per sample (all
//! ranks take part; each then holds the same copy, so every rank takes the same decisions),
//! then read like an engine. The step itself never gathers: the coupler reduces node sums.

use plugflow_coupling::ranks::all_gather;
use plugflow_coupling::{
    BackendError, DemBackend, GrainFlow, ImplicitDrag, NewParticle, ParticleView, Ranks, Reduce,
    WallForce,
};

use crate::{Real, Vec3};

/// Values per grain in the gather: id, position, velocity, angular velocity, radius, mass.
const PER_GRAIN: usize = 12;

/// A read-only copy of an engine's state over all its ranks.
#[derive(Default)]
pub struct Gathered {
    name: String,
    version: String,
    dt: Real,
    time: Real,
    steps: u64,
    ranks: Option<Ranks>,
    id: Vec<u64>,
    position: Vec<Vec3>,
    velocity: Vec<Vec3>,
    angular_velocity: Vec<Vec3>,
    radius: Vec<Real>,
    mass: Vec<Real>,
    walls: Vec<WallForce>,
    flow: Option<GrainFlow>,
    stages: Vec<(String, f64)>,
    diagnostics: Vec<(String, f64)>,
}

impl Gathered {
    /// Take the engine's state over all ranks (collective: every rank calls it).
    pub fn refresh(&mut self, dem: &dyn DemBackend) -> Result<(), BackendError> {
        let p = dem.particles();
        let mut local = Vec::with_capacity(PER_GRAIN * p.len());
        for i in 0..p.len() {
            local.push(p.id[i] as f64);
            local.extend_from_slice(&p.position[i]);
            local.extend_from_slice(&p.velocity[i]);
            local.extend_from_slice(&p.angular_velocity[i]);
            local.push(p.radius[i]);
            local.push(p.mass[i]);
        }
        let all = all_gather(dem, &local)?;
        let n = all.len() / PER_GRAIN;
        let v3 = |g: &[f64], k: usize| [g[k], g[k + 1], g[k + 2]];
        self.id.clear();
        self.position.clear();
        self.velocity.clear();
        self.angular_velocity.clear();
        self.radius.clear();
        self.mass.clear();
        for g in all.chunks_exact(PER_GRAIN).take(n) {
            self.id.push(g[0] as u64);
            self.position.push(v3(g, 1));
            self.velocity.push(v3(g, 4));
            self.angular_velocity.push(v3(g, 7));
            self.radius.push(g[10]);
            self.mass.push(g[11]);
        }
        // The wall forces summed over the ranks (each rank's grains push on the walls).
        let mut walls = dem.wall_forces();
        let mut flat: Vec<f64> = walls.iter().flat_map(|w| w.force).collect();
        dem.all_reduce(&mut flat, Reduce::Sum)?;
        for (w, f) in walls.iter_mut().zip(flat.chunks_exact(3)) {
            w.force = [f[0], f[1], f[2]];
        }
        self.walls = walls;
        self.name = dem.engine_name().to_string();
        self.version = dem.engine_version();
        self.dt = dem.time_step();
        self.time = dem.time();
        self.steps = dem.step_count();
        self.ranks = Some(dem.ranks());
        // (The engine's counters are over all ranks already; stage times are this rank's.)
        self.flow = dem.flow();
        self.stages = dem.stage_times();
        self.diagnostics = dem.diagnostics();
        Ok(())
    }
}

fn read_only(what: &str) -> BackendError {
    BackendError::InvalidArgument {
        argument: what.to_string(),
        reason: "a gathered copy of the grains is read, not stepped".to_string(),
    }
}

impl DemBackend for Gathered {
    fn engine_name(&self) -> &str {
        &self.name
    }
    fn engine_version(&self) -> String {
        self.version.clone()
    }
    fn time_step(&self) -> Real {
        self.dt
    }
    fn time(&self) -> Real {
        self.time
    }
    fn step_count(&self) -> u64 {
        self.steps
    }
    fn advance(&mut self, _steps: u64) -> Result<(), BackendError> {
        Err(read_only("steps"))
    }
    fn particles(&self) -> ParticleView<'_> {
        ParticleView {
            id: &self.id,
            position: &self.position,
            velocity: &self.velocity,
            angular_velocity: &self.angular_velocity,
            radius: &self.radius,
            mass: &self.mass,
        }
    }
    fn set_fluid_forces(
        &mut self,
        _force: &[Vec3],
        _implicit: Option<ImplicitDrag<'_>>,
    ) -> Result<(), BackendError> {
        Err(read_only("force"))
    }
    fn insert(&mut self, _particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        Err(read_only("grains"))
    }
    fn remove_past_outlet(&mut self) -> Result<Real, BackendError> {
        Err(read_only("outlet"))
    }
    fn wall_forces(&self) -> Vec<WallForce> {
        self.walls.clone()
    }
    fn stage_times(&self) -> Vec<(String, f64)> {
        self.stages.clone()
    }
    fn diagnostics(&self) -> Vec<(String, f64)> {
        self.diagnostics.clone()
    }
    fn flow(&self) -> Option<GrainFlow> {
        self.flow
    }
    fn ranks(&self) -> Ranks {
        self.ranks.unwrap_or(Ranks::SINGLE)
    }
}
