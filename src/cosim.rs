//! The gas side of the step loop of shared/DESIGN.md, once per coupling interval
//! Δt_c = n_sub · Δt_dem:
//!
//!   DEM advance (n_sub steps, fluid force held) → deposit (φ_j, u_j) → gas step over Δt_c →
//!   interpolate (∇P_i, φ_i) → drag law → DEM fluid forces.
//!
//! Before a run, coupling checks in the manner of CFDEM's `checkCouplingInterval` say
//! whether Δt_c, the cell size and the grain travel fit together.

use plugflow_coupling::grid::{interpolate_scalar, interpolate_vec3};
use plugflow_coupling::{
    deposit, BackendError, DarcyVolumeForce, DemBackend, DragLaw, GasError, GasSolver,
    GrainInFluid, GranularFields, StageTimer, TubeGrid,
};
use serde_json::{json, Value};

use crate::dem::DemConfig;
use crate::gas::{carman_kozeny, DarcyGas, DarcyParams, Scheme, SolvePath};
use crate::scene::{GasScheme, GasSolverPath, Scene, SceneError};
use crate::{Real, Vec3};

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

impl CouplingCheck {
    /// JSON for the summary.
    pub fn to_json(&self) -> Value {
        json!({
            "name": self.name,
            "value": self.value,
            "limit": self.limit,
            "verdict": format!("{:?}", self.verdict).to_lowercase(),
            "advice": self.advice,
        })
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

/// The gas, its grid and the drag law, coupled to a DEM backend.
pub struct GasCoupling {
    /// The gas solver.
    pub gas: DarcyGas,
    grid: TubeGrid,
    fields: GranularFields,
    drag: Box<dyn DragLaw>,
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
    /// Largest relative gas-mass imbalance of any step.
    pub mass_error_max: Real,
    forces: Vec<Vec3>,
}

impl GasCoupling {
    /// The coupling a scene asks for (`None` without `[gas]`).
    pub fn from_scene(scene: &Scene, dem: &DemConfig) -> Result<Option<Self>, SceneError> {
        let f = &scene.file;
        let Some(g) = &f.gas else {
            return Ok(None);
        };
        let tube = dem
            .tube
            .ok_or_else(|| SceneError::field("gas", "the gas needs a [tube]"))?;
        let area = std::f64::consts::PI * tube.radius * tube.radius;
        let v_s = match (g.superficial_velocity, g.flow) {
            (Some(v), _) => v.si,
            (None, Some(q)) => q.si / area,
            _ => unreachable!("checked in scene::check_gas"),
        };
        let [nz, nx, ny] = g.grid;
        let grid = TubeGrid::new(tube.origin, tube.axis, tube.radius, tube.length, nz, nx, ny);
        let d_mean = dem.radius_min + dem.radius_max;
        let params = DarcyParams {
            p0: g.pressure.si,
            viscosity: g.viscosity.si,
            grain_diameter: d_mean,
            superficial_velocity: v_s,
            porosity_min: g.porosity_min.0,
            porosity_max: g.porosity_max.0,
            scheme: match g.scheme {
                GasScheme::BackwardEuler => Scheme::Theta(1.0),
                GasScheme::CrankNicolson => Scheme::Theta(0.5),
                GasScheme::Theta => Scheme::Theta(g.theta.map(|t| t.0).unwrap_or(1.0)),
                GasScheme::Bdf2 => Scheme::Bdf2,
            },
            path: match g.solver {
                GasSolverPath::Monolithic => SolvePath::Monolithic,
                GasSolverPath::Splitting => SolvePath::Splitting,
            },
        };
        let (interval, substeps) = match f.coupling.as_ref().and_then(|c| c.interval) {
            Some(i) => {
                let n = (i.si / dem.dt).round();
                if n < 1.0 || (n * dem.dt - i.si).abs() > 1e-6 * i.si {
                    return Err(SceneError::field(
                        "coupling.interval",
                        format!(
                            "{:.4e} s is not a whole number of DEM steps (dt = {:.4e} s); use \
                             e.g. {:.4e} s",
                            i.si,
                            dem.dt,
                            n.max(1.0) * dem.dt
                        ),
                    ));
                }
                (n * dem.dt, n as u64)
            }
            None => (10.0 * dem.dt, 10),
        };
        let checks = coupling_checks(&params, &grid, dem, interval);
        if let Some(bad) = checks.iter().find(|c| c.verdict == Verdict::Refused) {
            return Err(SceneError::field(
                "coupling.interval",
                format!(
                    "coupling check `{}` fails: {:.4} > {:.4}; {}",
                    bad.name, bad.value, bad.limit, bad.advice
                ),
            ));
        }
        Ok(Some(Self {
            gas: DarcyGas::new(grid.clone(), params),
            grid,
            fields: GranularFields::default(),
            drag: Box::new(DarcyVolumeForce),
            substeps,
            interval,
            checks,
            timer: StageTimer::new(),
            clamped: 0,
            node_steps: 0,
            mass_error_max: 0.0,
            forces: Vec::new(),
        }))
    }

    /// One exchange after the DEM has advanced a coupling interval: deposit, gas step,
    /// interpolation, drag, forces to the DEM.
    pub fn exchange(&mut self, dem: &mut dyn DemBackend) -> Result<(), ExchangeError> {
        let time = dem.time();
        {
            let p = dem.particles();
            let t = std::time::Instant::now();
            deposit(
                &self.grid,
                p.position,
                p.velocity,
                p.radius,
                &mut self.fields,
            );
            self.timer.add("deposit", t.elapsed().as_secs_f64());
        }
        let t = std::time::Instant::now();
        let report = self.gas.step(&self.fields, self.interval)?;
        self.timer.add("gas", t.elapsed().as_secs_f64());
        self.clamped += report.clamped_nodes as u64;
        self.node_steps += self.grid.len() as u64;
        self.mass_error_max = self.mass_error_max.max(report.mass_error_rel);
        let t = std::time::Instant::now();
        let grad = self.gas.pressure_gradient();
        let phi = self.gas.porosity();
        let p = dem.particles();
        self.forces.clear();
        for i in 0..p.len() {
            let (s, _, _) = self.grid.local(p.position[i]);
            if !(0.0..=self.grid.length).contains(&s) {
                self.forces.push([0.0; 3]);
                continue;
            }
            let st = self.grid.stencil(p.position[i]);
            let r = p.radius[i];
            let grain = GrainInFluid {
                volume: 4.0 / 3.0 * std::f64::consts::PI * r * r * r,
                diameter: 2.0 * r,
                velocity: p.velocity[i],
                porosity: interpolate_scalar(&st, phi),
                pressure_gradient: interpolate_vec3(&st, &grad),
                gas_velocity: [0.0; 3],
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

    /// Pressure drop per length, Pa/m.
    pub fn pressure_drop(&self) -> Real {
        self.gas.pressure_drop_per_length()
    }

    /// Porosity along the axis (cross-section mean by accessible volume), for figures.
    pub fn porosity_profile(&self) -> Vec<Real> {
        let g = &self.grid;
        (0..g.nz)
            .map(|k| {
                let (mut s, mut v) = (0.0, 0.0);
                for j in 0..g.ny {
                    for i in 0..g.nx {
                        let n = g.node(k, i, j);
                        s += self.fields.porosity.get(n).copied().unwrap_or(1.0) * g.volume[n];
                        v += g.volume[n];
                    }
                }
                s / v
            })
            .collect()
    }
}

/// The checks of a coupled run, in the manner of CFDEM's `checkCouplingInterval`.
pub fn coupling_checks(
    params: &DarcyParams,
    grid: &TubeGrid,
    dem: &DemConfig,
    interval: Real,
) -> Vec<CouplingCheck> {
    let d = dem.radius_min + dem.radius_max;
    let r_min = dem.radius_min;
    let v_grain = 4.0 / 3.0 * std::f64::consts::PI * r_min.powi(3);
    // Drag relaxation time of a grain in a dense plug: m / β with β = V η φ / ((1 − φ) κ),
    // i.e. τ = ρ_s (1 − φ) κ(φ) / (η φ). Evaluated at φ = 0.4 (dense random packing) or
    // the clamp's lower bound if that is looser.
    let phi = params.porosity_min.max(0.4);
    let tau = dem.density * (1.0 - phi) * carman_kozeny(d, phi) / (params.viscosity * phi);
    let ratio = interval / tau;
    let mut checks = vec![CouplingCheck {
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
            "τ = {tau:.3e} s at φ = {phi}; the drag is held explicitly over Δt_c = {interval:.3e} s \
             and overshoots beyond 2τ: shorten coupling.interval to ≤ {:.3e} s",
            tau
        ),
    }];
    let cell = grid.volume.iter().copied().fold(Real::INFINITY, Real::min);
    let cell_ratio = cell / v_grain;
    checks.push(CouplingCheck {
        name: "smallest gas cell volume / grain volume",
        value: cell_ratio,
        limit: 3.0,
        verdict: if cell_ratio >= 3.0 {
            Verdict::Ok
        } else {
            Verdict::Warning
        },
        advice: "below 3 grains per cell the deposited porosity is dominated by single grains: \
                 use fewer nodes (gas.grid)"
            .into(),
    });
    let v = dem.max_impact_velocity;
    let h = grid.dz.min(grid.dx).min(grid.dy);
    let travel = v * interval / h;
    checks.push(CouplingCheck {
        name: "grain travel per coupling interval / cell size",
        value: travel,
        limit: 0.1,
        verdict: if travel <= 0.1 {
            Verdict::Ok
        } else {
            Verdict::Warning
        },
        advice: format!(
            "at {v} m/s (dem.max_impact_velocity) a grain crosses a tenth of a cell in {:.3e} s: \
             shorten coupling.interval",
            0.1 * h / v
        ),
    });
    checks
}
