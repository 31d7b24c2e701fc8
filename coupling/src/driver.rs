//! The co-simulation driver: the gas side of the step loop of shared/DESIGN.md, once per
//! coupling interval Δt_c = n_sub · Δt_dem:
//!
//!   DEM advance (n_sub steps, fluid force held) → deposit (φ_j, u_j) → gas step over Δt_c →
//!   interpolate (∇P_i, φ_i) → drag law → DEM fluid forces.
//!
//! Before a run, coupling checks in the manner of CFDEM's `checkCouplingInterval` say
//! whether Δt_c, the cell size and the grain travel fit together ([`check_drag_relaxation`],
//! [`check_cell_volume`], [`check_travel`]).

use crate::grid::{deposit, interpolate_scalar, interpolate_vec3, GranularFields, TubeGrid};
use crate::{
    BackendError, DemBackend, DragLaw, GasError, GasSolver, GrainInFluid, Real, StageTimer, Vec3,
};

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
}

/// A gas solver and a drag law coupled to a DEM backend.
pub struct Coupler {
    /// The gas solver.
    pub gas: Box<dyn GasSolver>,
    drag: Box<dyn DragLaw>,
    fields: GranularFields,
    /// DEM steps per coupling interval.
    pub substeps: u64,
    /// Coupling interval, s.
    pub interval: Real,
    /// Checks made before the run.
    pub checks: Vec<CouplingCheck>,
    /// Time of each coupling stage.
    pub timer: StageTimer,
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
    /// Exchanges so far.
    exchanges: u64,
    forces: Vec<Vec3>,
    /// Grains with ids from this one on are new since the last exchange (None before the
    /// first): engines number grains in the order they create them.
    first_new_id: Option<u64>,
}

/// Every this many exchanges the gas step is also taken as two half steps (from the same
/// state, discarded) to estimate its time error: three extra gas steps per hundred.
pub const DOUBLING_EVERY: u64 = 100;

impl Coupler {
    /// Couple `gas` and `drag` with `substeps` DEM steps of `dem_dt` per exchange.
    pub fn new(
        gas: Box<dyn GasSolver>,
        drag: Box<dyn DragLaw>,
        substeps: u64,
        dem_dt: Real,
        checks: Vec<CouplingCheck>,
    ) -> Self {
        Self {
            gas,
            drag,
            fields: GranularFields::default(),
            substeps,
            interval: substeps as Real * dem_dt,
            checks,
            timer: StageTimer::new(),
            clamped: 0,
            node_steps: 0,
            clamped_low: 0,
            mass_error_max: 0.0,
            doubling_checks: 0,
            doubling_max: 0.0,
            doubling_sum: 0.0,
            exchanges: 0,
            forces: Vec::new(),
            first_new_id: None,
        }
    }

    /// One exchange after the DEM has advanced a coupling interval: deposit, gas step,
    /// interpolation, drag, forces to the DEM.
    pub fn exchange(&mut self, dem: &mut dyn DemBackend) -> Result<(), ExchangeError> {
        let time = dem.time();
        let grid: &TubeGrid = self.gas.grid();
        {
            let p = dem.particles();
            let t = std::time::Instant::now();
            deposit(grid, p.position, p.velocity, p.radius, &mut self.fields);
            // The grains fed since the last exchange, on the nodes (their stencils are
            // the deposit's).
            let fed = &mut self.fields.fed_solid;
            fed.clear();
            if let Some(first_new) = self.first_new_id {
                for (i, st) in self.fields.stencils.iter().enumerate() {
                    let (Some(st), true) = (st, p.id[i] >= first_new) else {
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
                for (f, vol) in fed.iter_mut().zip(&grid.volume) {
                    *f /= vol.max(1e-300);
                }
            }
            let floor = self.first_new_id.unwrap_or(0);
            self.first_new_id = Some(p.id.iter().map(|&id| id + 1).fold(floor, u64::max));
            self.timer.add("deposit", t.elapsed().as_secs_f64());
        }
        let nodes = grid.len();
        // (Not at the first exchange: the gas starts there from rest, an impulsive start
        // whose error says nothing about the run's.)
        if self.exchanges > 0 && self.exchanges.is_multiple_of(DOUBLING_EVERY) {
            let t = std::time::Instant::now();
            if let Some(e) = self.gas.step_doubling_error(&self.fields, self.interval)? {
                self.doubling_checks += 1;
                self.doubling_max = self.doubling_max.max(e);
                self.doubling_sum += e;
            }
            self.timer.add("accuracy_check", t.elapsed().as_secs_f64());
        }
        self.exchanges += 1;
        let t = std::time::Instant::now();
        let report = self.gas.step(&self.fields, self.interval)?;
        self.timer.add("gas", t.elapsed().as_secs_f64());
        self.clamped += report.clamped_nodes as u64;
        self.clamped_low += report.clamped_low_nodes as u64;
        self.node_steps += nodes as u64;
        self.mass_error_max = self.mass_error_max.max(report.mass_error_rel);
        let t = std::time::Instant::now();
        let grad = self.gas.pressure_gradient();
        let gas_u = self.gas.gas_velocity();
        let gas_density = self.gas.gas_density();
        let phi = self.gas.porosity();
        let p = dem.particles();
        self.forces.clear();
        for i in 0..p.len() {
            // The grains have not moved since the deposit: reuse its stencils.
            let Some(st) = self.fields.stencils[i] else {
                self.forces.push([0.0; 3]);
                continue;
            };
            let r = p.radius[i];
            let grain = GrainInFluid {
                volume: 4.0 / 3.0 * std::f64::consts::PI * r * r * r,
                diameter: 2.0 * r,
                velocity: p.velocity[i],
                porosity: interpolate_scalar(&st, phi),
                pressure_gradient: interpolate_vec3(&st, &grad),
                gas_velocity: gas_u
                    .as_ref()
                    .map_or([0.0; 3], |u| interpolate_vec3(&st, u)),
                gas_density: gas_density
                    .as_ref()
                    .map_or(0.0, |r| interpolate_scalar(&st, r)),
            };
            let f = self.drag.force(&grain);
            if !(f[0].is_finite() && f[1].is_finite() && f[2].is_finite()) {
                return Err(ExchangeError::Drag {
                    particle_id: p.id[i],
                    time,
                    porosity: grain.porosity,
                    gradient: grain.pressure_gradient,
                });
            }
            self.forces.push(f);
        }
        self.timer
            .add("interpolate_drag", t.elapsed().as_secs_f64());
        let t = std::time::Instant::now();
        dem.set_fluid_forces(&self.forces, None)?;
        self.timer.add("set_forces", t.elapsed().as_secs_f64());
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
