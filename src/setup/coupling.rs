//! Building the coupling a scene asks for: the gas solver, the drag law (from the registry
//! in `plugflow_coupling::drag`), the coupling interval and the checks. The step itself is
//! `plugflow_coupling::Coupler::advance`.

use plugflow_coupling::checks::{
    check_cell_volume, check_drag_relaxation, check_travel, first_refusal,
};
use plugflow_coupling::drag::{drag_law, DragSettings};
use plugflow_coupling::fluid_force::{fluid_force, FluidForce, FluidForceSettings};
use plugflow_coupling::{Coupler, CouplingCheck, DragLaw, GasSolver, TubeGrid, Verdict};

use crate::dem::DemConfig;
use crate::gas::{carman_kozeny, DarcyGas, DarcyParams, Scheme, SimpleTubeGas, SolvePath};
use crate::scene::{GasScheme, GasSolverPath, PorosityVolume, Scene, SceneError};
use crate::summary::CheckRow;
use crate::Real;
use std::sync::Arc;

/// A check as the summary reports it.
pub fn check_row(c: &CouplingCheck) -> CheckRow {
    CheckRow {
        name: c.name.to_string(),
        value: c.value,
        limit: c.limit,
        verdict: format!("{:?}", c.verdict).to_lowercase(),
        advice: c.advice.clone(),
    }
}

/// The coupling a scene asks for (`None` without `[gas]`).
pub fn coupling_from_scene(scene: &Scene, dem: &DemConfig) -> Result<Option<Coupler>, SceneError> {
    let mut coupler = gas_coupler(scene, dem)?;
    let smoothing = scene
        .file
        .coupling
        .as_ref()
        .and_then(|c| c.smoothing_length);
    if let (Some(c), Some(length)) = (coupler.as_mut(), smoothing) {
        c.set_smoothing(length.si);
    }
    Ok(coupler)
}

/// The gas, drag and checks of a scene's coupling, unsmoothed.
fn gas_coupler(scene: &Scene, dem: &DemConfig) -> Result<Option<Coupler>, SceneError> {
    {
        let f = &scene.file;
        let Some(g) = &f.gas else {
            return Ok(None);
        };
        let tube = dem
            .tube
            .ok_or_else(|| SceneError::field("gas", "the gas needs a [tube]"))?;
        let v_s = scene
            .superficial_velocity()
            .expect("checked in scene::check_gas: a tube and v_s or a flow");
        let [nz, nx, ny] = g.grid;
        let mut grid = TubeGrid::new_in_slab(
            tube.origin,
            tube.axis,
            tube.radius,
            tube.length,
            [nz, nx, ny],
            tube.slab_half,
        );
        grid.periodic = tube.periodic;
        grid.whole_cell_porosity = f
            .coupling
            .as_ref()
            .is_some_and(|c| c.porosity_volume == PorosityVolume::WholeCell);
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
        if g.model == "simple" {
            let rho = g
                .density
                .map(|d| d.si)
                .expect("checked: simple has a density");
            let mut gas = SimpleTubeGas::new(
                grid.clone(),
                rho,
                g.viscosity.si,
                v_s,
                d_mean,
                g.porosity_min.0,
                (g.equation_of_state.as_deref() == Some("ideal_gas")).then_some(g.pressure.si),
            );
            let voidage_factor = f
                .coupling
                .as_ref()
                .and_then(|c| c.voidage_factor)
                .map_or(1.0, |c| c.0);
            // One law for both sides: the grains' drag and the gas's interphase term.
            let drag = build_drag(scene, g.viscosity.si, voidage_factor)?;
            gas.set_drag_law(drag.clone())
                .map_err(|e| SceneError::field("coupling.drag", e))?;
            gas.gas.control_interstitial = g.controlled_velocity.as_deref() == Some("interstitial");
            // Drag relaxation of a grain in a dense bed under the viscous Ergun term:
            // τ = m / (V β/(1−ε)) = ρ_s ε d² / (150 (1 − ε) μ) at ε = 0.4, the voidage the
            // drag sees (C_V ε, seed 004 eq. 11).
            let phi = voidage_factor * g.porosity_min.0.max(0.4);
            let tau = dem.density * phi * d_mean * d_mean / (150.0 * (1.0 - phi) * g.viscosity.si);
            let checks = checks_for(tau, phi, &grid, dem, interval);
            let forces = build_fluid_forces(scene, g.viscosity.si)?;
            return coupler(Box::new(gas), drag, forces, substeps, dem.dt, checks);
        }
        let checks = coupling_checks(&params, &grid, dem, interval);
        let drag = build_drag(scene, g.viscosity.si, 1.0)?;
        let forces = build_fluid_forces(scene, g.viscosity.si)?;
        coupler(
            Box::new(DarcyGas::new(grid, params)),
            drag,
            forces,
            substeps,
            dem.dt,
            checks,
        )
    }
}

/// The scene's drag law from the registry (the scene check has refused names it lacks).
fn build_drag(
    scene: &Scene,
    viscosity: Real,
    voidage_factor: Real,
) -> Result<Arc<dyn DragLaw>, SceneError> {
    let name = scene
        .file
        .coupling
        .as_ref()
        .map_or("darcy", |c| c.drag.as_str());
    let entry = drag_law(name)
        .ok_or_else(|| SceneError::field("coupling.drag", format!("unknown drag law `{name}`")))?;
    Ok((entry.build)(&DragSettings {
        viscosity,
        voidage_factor,
    }))
}

/// The scene's further fluid forces from the registry, in its order (the scene check has
/// refused names it lacks and forces its gas cannot feed).
fn build_fluid_forces(
    scene: &Scene,
    viscosity: Real,
) -> Result<Vec<Arc<dyn FluidForce>>, SceneError> {
    let f = &scene.file;
    let settings = FluidForceSettings {
        viscosity,
        gravity: [f.gravity[0].si, f.gravity[1].si, f.gravity[2].si],
    };
    f.fluid_forces()
        .iter()
        .map(|name| {
            fluid_force(name)
                .map(|entry| (entry.build)(&settings))
                .ok_or_else(|| {
                    SceneError::field(
                        "coupling.fluid_forces",
                        format!("unknown fluid force `{name}`"),
                    )
                })
        })
        .collect()
}

/// The coupler, unless a check refuses the run (one place for every gas model).
fn coupler(
    gas: Box<dyn GasSolver>,
    drag: Arc<dyn DragLaw>,
    fluid_forces: Vec<Arc<dyn FluidForce>>,
    substeps: u64,
    dem_dt: Real,
    checks: Vec<CouplingCheck>,
) -> Result<Option<Coupler>, SceneError> {
    if let Some(bad) = first_refusal(&checks) {
        return Err(SceneError::field(
            "coupling.interval",
            format!(
                "coupling check `{}` fails: {:.4} > {:.4}; {}",
                bad.name, bad.value, bad.limit, bad.advice
            ),
        ));
    }
    Ok(Some(Coupler::new(
        gas,
        drag,
        fluid_forces,
        substeps,
        dem_dt,
        checks,
    )))
}

/// The checks of a coupled run, in the manner of CFDEM's `checkCouplingInterval`.
pub fn coupling_checks(
    params: &DarcyParams,
    grid: &TubeGrid,
    dem: &DemConfig,
    interval: Real,
) -> Vec<CouplingCheck> {
    let d = dem.radius_min + dem.radius_max;
    // Drag relaxation time of a grain in a dense plug: m / β with β = V η φ / ((1 − φ) κ),
    // i.e. τ = ρ_s (1 − φ) κ(φ) / (η φ). Evaluated at φ = 0.4 (dense random packing) or
    // the clamp's lower bound if that is looser.
    let phi = params.porosity_min.max(0.4);
    let tau = dem.density * (1.0 - phi) * carman_kozeny(d, phi) / (params.viscosity * phi);
    let mut checks = checks_for(tau, phi, grid, dem, interval);
    checks.push(check_darcy_range(params.superficial_velocity));
    checks
}

/// The checks every gas model makes, given its drag relaxation time `tau` (s) in a plug at
/// porosity `phi`: interval against τ, smallest cell against the smallest grain, travel per
/// interval against the smallest cell size.
fn checks_for(
    tau: Real,
    phi: Real,
    grid: &TubeGrid,
    dem: &DemConfig,
    interval: Real,
) -> Vec<CouplingCheck> {
    let smallest = grid.smallest_open_volume();
    let grain = 4.0 / 3.0 * std::f64::consts::PI * dem.radius_min.powi(3);
    vec![
        check_drag_relaxation(tau, phi, interval),
        check_cell_volume(smallest, grain),
        check_travel(
            dem.max_impact_velocity,
            interval,
            grid.dz.min(grid.dx).min(grid.dy),
        ),
    ]
}

/// Highest superficial gas velocity of the d'Arcy model's range, m/s: above it "the
/// simulation method underestimates the pressure drop, because it does not consider the
/// increasing drag force on single particles" (seed 000 §4.1, v_s > 4 m/s).
pub const DARCY_MAX_SUPERFICIAL_VELOCITY: Real = 4.0;

/// The d'Arcy drag outside its range is a warning, not a refusal: the run is stable, its
/// pressure drop a lower bound.
fn check_darcy_range(v_s: Real) -> CouplingCheck {
    let over = v_s > DARCY_MAX_SUPERFICIAL_VELOCITY;
    CouplingCheck {
        name: "superficial gas velocity in the d'Arcy model's range, m/s",
        value: v_s,
        limit: DARCY_MAX_SUPERFICIAL_VELOCITY,
        verdict: if over { Verdict::Warning } else { Verdict::Ok },
        advice: if over {
            "above ~4 m/s the drag on single grains dominates and the d'Arcy model \
             underestimates the pressure drop (seed 000 §4.1); a drag law with an inertial \
             term (Ergun / Wen–Yu) is needed there"
                .into()
        } else {
            String::new()
        },
    }
}
