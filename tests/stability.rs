//! Stiff and extreme cases: each ends with no NaN, bounded energy and pressure, and prints
//! a one-line stability report. The bounds are physical, not tuned:
//! - energy: grains without gas only lose mechanical energy (contacts dissipate; their
//!   elastic energy is ≥ 0), so kinetic + gravitational energy may not exceed its start by
//!   more than the integrator's error, bounded by 1 % (velocity Verlet at dt ≤ t_c/30 returns
//!   an elastic impact's energy within 0.12 %, 0.03 % at t_c/50, tests/dem_analytic.rs);
//! - pressure: with the porosity frozen the gas pressure rises from 0 to its steady state.
//!   Backward Euler is monotone: it may not exceed the steady state (beyond rounding, 1e-9
//!   relative). BDF2 is L-stable but not monotone: on each decaying mode y' = −λ(y − y*) it
//!   overshoots by up to [`bdf2_overshoot`] (2.9 %, at λΔt ≈ 3, computed from its
//!   recursion), so that is its bound. With grains moving, |P'| stays below the background
//!   pressure P0 (a gas compressed to twice its pressure would be a blow-up in these
//!   low-Mach cases);
//! - the SIMPLE gas has inertia: over a frozen bed its pressure may exceed the steady state
//!   by the water-hammer surge of the inflow switched on at once ([`joukowsky_surge`]), not
//!   more.

use std::path::Path;

use plugflow::dem::NativeDem;
use plugflow::gas::{DarcyGas, DarcyParams, Scheme, SolvePath};
use plugflow::scene::Scene;
use plugflow::setup::coupling_from_scene;
use plugflow_coupling::{deposit, DemBackend, GasSolver, GranularFields, TubeGrid, Verdict};

fn scene(text: &str, set: &[&str]) -> Scene {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    Scene::parse(text, &set).unwrap_or_else(|e| panic!("test scene: {e}"))
}

fn vertical(set: &[&str]) -> Scene {
    let mut all = vec!["dem.threads=1".to_string()];
    all.extend(set.iter().map(|s| s.to_string()));
    Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/vertical_plug.toml"),
        &all,
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

const BED: &str = r#"
schema_version = 1
name = "stability"
duration = "1 s"
seed = 5
gravity = [0, 0, -9.81]
[tube]
diameter = "7 mm"
length = "0.06 m"
inlet_end = "closed"
outlet_end = "closed"
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
contact_time = "1e-4 s"
friction = 0.5
restitution = 0.5
[initial]
count = 150
from = "0 m"
to = "0.055 m"
[dem]
threads = 1
"#;

/// Kinetic + gravitational energy of the grains, J.
fn mechanical_energy(e: &dyn DemBackend, g: [f64; 3]) -> f64 {
    let p = e.particles();
    (0..p.len())
        .map(|i| {
            let v = p.velocity[i];
            let x = p.position[i];
            0.5 * p.mass[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                - p.mass[i] * (g[0] * x[0] + g[1] * x[1] + g[2] * x[2])
        })
        .sum()
}

/// Run a gas-free scene for `seconds`, check the energy bound, print the report.
fn dry_case(name: &str, s: &Scene, seconds: f64) {
    let cfg = plugflow::setup::dem_config(s).unwrap();
    let g = cfg.gravity;
    let frac = cfg.dt / cfg.dt_report.limit;
    let mut e = NativeDem::new(cfg.clone()).unwrap();
    let e0 = mechanical_energy(&e, g);
    let scale = e
        .particles()
        .mass
        .iter()
        .map(|m| m * 9.81 * 0.06)
        .sum::<f64>();
    let steps = (seconds / e.time_step()).round() as u64;
    let chunks = 20;
    let mut worst = f64::NEG_INFINITY;
    for _ in 0..chunks {
        e.advance(steps / chunks)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
        worst = worst.max(mechanical_energy(&e, g) - e0);
    }
    println!(
        "stability | {name:<34} | steps {steps:>8} | dt/limit {frac:.3} | energy gain {:+.2e} of \
         m·g·L | grains {} | no NaN",
        worst / scale,
        e.particles().len()
    );
    assert!(
        worst <= 0.01 * scale,
        "{name}: mechanical energy rose by {worst:e} J (bound {:e} J)",
        0.01 * scale
    );
}

/// Contact stiffness raised 1e4× (contact time 1e-6 s instead of 1e-4 s): the time step
/// follows automatically (t_c/30, the default fraction) and the bed falls and settles without gaining energy.
#[test]
fn stiff_contacts_dt_chosen_automatically() {
    let s = scene(BED, &["contact.contact_time=1e-6 s"]);
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    assert!((cfg.dt - 1e-6 / 30.0).abs() < 1e-12, "dt {}", cfg.dt);
    dry_case("contact stiffness ×1e4", &s, 2e-3);
}

/// Restitution 0.99 and 0.01, friction 0 and 2: a bed poured and let fall.
#[test]
fn restitution_and_friction_extremes() {
    for (name, set) in [
        ("restitution 0.99", "contact.restitution=0.99"),
        ("restitution 0.01", "contact.restitution=0.01"),
        ("friction 0", "contact.friction=0"),
        ("friction 2", "contact.friction=2"),
    ] {
        dry_case(name, &scene(BED, &[set]), 0.1);
    }
}

/// A settled bed's granular fields on the gas grid of `s` (or no grains at all).
fn frozen_fields(s: &Scene, grains: Option<&[[f64; 3]]>) -> (TubeGrid, GranularFields, f64) {
    let cfg = plugflow::setup::dem_config(s).unwrap();
    let g = s.file.gas.as_ref().unwrap();
    let t = cfg.tube.unwrap();
    let grid = TubeGrid::new(
        t.origin, t.axis, t.radius, t.length, g.grid[0], g.grid[1], g.grid[2],
    );
    let mut fields = GranularFields::default();
    let x: Vec<[f64; 3]> = match grains {
        Some(x) => x.to_vec(),
        None => {
            let mut e = NativeDem::new(cfg.clone()).unwrap();
            e.advance((0.25 / e.time_step()) as u64).unwrap();
            e.particles().position.to_vec()
        }
    };
    let v = vec![[0.0; 3]; x.len()];
    let r = vec![cfg.radius_min; x.len()];
    deposit(&grid, &x, &v, &r, &mut fields);
    (grid, fields, cfg.radius_min * 2.0)
}

fn darcy(grid: TubeGrid, d: f64, scheme: Scheme, v_s: f64) -> DarcyGas {
    DarcyGas::new(
        grid,
        DarcyParams {
            p0: 101_325.0,
            viscosity: 6.73e-5,
            grain_diameter: d,
            superficial_velocity: v_s,
            porosity_min: 0.3,
            porosity_max: 0.95,
            scheme,
            path: SolvePath::Monolithic,
        },
    )
}

/// Largest overshoot of BDF2 (started with one backward-Euler step, as the solver does) on
/// y' = −λ(y − 1), y(0) = 0, over λΔt in (0, 20]: max over n of y_n − 1.
fn bdf2_overshoot() -> f64 {
    let mut worst: f64 = 0.0;
    for i in 1..=4000 {
        let z = i as f64 * 0.005;
        let (mut y0, mut y1) = (0.0, z / (1.0 + z));
        for _ in 0..400 {
            let y2 = (4.0 * y1 - y0 + 2.0 * z) / (3.0 + 2.0 * z);
            (y0, y1) = (y1, y2);
            worst = worst.max(y2 - 1.0);
        }
    }
    worst
}

/// The largest |P'| a frozen bed may reach under `scheme`, from its steady state.
fn frozen_bound(scheme: Scheme, steady: f64) -> f64 {
    match scheme {
        Scheme::Bdf2 => steady * (1.0 + bdf2_overshoot()),
        Scheme::Theta(_) => steady * (1.0 + 1e-9),
    }
}

/// Step the frozen gas until `t_end` with steps of `dt`; return the largest |P'| seen, the
/// final pressures, and the clamped node count of the last step.
fn march(gas: &mut DarcyGas, f: &GranularFields, dt: f64, t_end: f64) -> (f64, Vec<f64>, usize) {
    let mut worst: f64 = 0.0;
    let mut clamped = 0;
    let n = (t_end / dt).ceil() as usize;
    for _ in 0..n {
        let r = gas.step(f, dt).unwrap_or_else(|e| panic!("{e}"));
        clamped = r.clamped_nodes;
        assert!(gas.pressure().iter().all(|p| p.is_finite()));
        worst = worst.max(gas.pressure().iter().fold(0.0_f64, |m, p| m.max(p.abs())));
    }
    (worst, gas.pressure().to_vec(), clamped)
}

const GAS: &str = "[gas]\nmodel = \"darcy\"\nviscosity = \"0.0673 cP\"\npressure = \"1013.25 hPa\"\nsuperficial_velocity = \"1 m/s\"\ngrid = [40, 2, 2]\n";

/// D·Δt/Δx² = 1, 1e3 and 1e6 in a frozen bed, backward Euler and BDF2: the pressure rises
/// to the steady state (solved with a very long step) without overshoot or NaN.
#[test]
fn diffusion_numbers_1_to_1e6() {
    let s = scene(
        &format!("{BED}{GAS}")
            .replace("0.06 m", "0.14 m")
            .replace("0.055 m", "0.13 m")
            .replace("count = 150", "count = 400"),
        &[],
    );
    let (grid, fields, d) = frozen_fields(&s, None);
    // Diffusivity in the bed: D = P0 κ(φ) / (η φ) at the bed's mean porosity.
    let phi: f64 = {
        let bed: Vec<f64> = fields
            .porosity
            .iter()
            .copied()
            .filter(|p| *p < 0.9)
            .collect();
        bed.iter().sum::<f64>() / bed.len() as f64
    };
    let diff = 101_325.0 * plugflow::gas::carman_kozeny(d, phi) / (6.73e-5 * phi);
    let dx = grid.dz;
    // Steady state: one backward-Euler step of 1e6 diffusion times.
    let mut steady_gas = darcy(grid.clone(), d, Scheme::Theta(1.0), 1.0);
    steady_gas
        .step(&fields, 1e6 * dx * dx / diff * 1e6)
        .unwrap();
    let steady = steady_gas
        .pressure()
        .iter()
        .fold(0.0_f64, |m, p| m.max(p.abs()));
    assert!(steady > 0.0);
    for (scheme, label) in [
        (Scheme::Theta(1.0), "backward Euler"),
        (Scheme::Bdf2, "BDF2"),
    ] {
        for ratio in [1.0, 1e3, 1e6] {
            let dt = ratio * dx * dx / diff;
            let mut gas = darcy(grid.clone(), d, scheme, 1.0);
            // Long enough to reach the steady state (~ L²/D), at least 20 steps.
            let t_end = (20.0 * dt).max(5.0 * grid.dz * grid.dz * 1600.0 / diff);
            let (worst, _, _) = march(&mut gas, &fields, dt, t_end);
            println!(
                "stability | {label:<14} D·dt/dx² = {ratio:<8.0e} | steps {:>6} | max P' {worst:.1} Pa \
                 | steady {steady:.1} Pa | mass error {:.1e} | no NaN",
                (t_end / dt).ceil(),
                gas.step(&fields, dt).unwrap().mass_error_rel
            );
            assert!(
                worst <= frozen_bound(scheme, steady),
                "{label}, ratio {ratio}: P' {worst} overshoots the steady state {steady} \
                 beyond the scheme's bound {}",
                frozen_bound(scheme, steady)
            );
        }
    }
}

/// An over-packed node (grains piled far beyond close packing: φ → 0) and an empty tube
/// (φ = 1): the porosity is clamped into [φ_min, φ_max], the clamp is counted, the
/// pressure stays finite and below its steady state.
#[test]
fn over_packed_node_and_empty_tube() {
    let s = scene(&format!("{BED}{GAS}"), &[]);
    // 300 grains within 1.5 mm of one point: far more solid than the cell holds.
    let pile: Vec<[f64; 3]> = (0..300)
        .map(|k| {
            let a = k as f64 * 2.399;
            let r = 1.5e-3 * ((k % 17) as f64 / 17.0);
            [r * a.cos(), r * a.sin(), 0.03 + 1e-5 * (k % 7) as f64]
        })
        .collect();
    for (label, grains) in [
        ("over-packed node", Some(&pile[..])),
        ("empty tube", Some(&[][..])),
    ] {
        let (grid, fields, d) = frozen_fields(&s, grains);
        let min_phi = fields.porosity.iter().copied().fold(1.0, f64::min);
        let mut steady_gas = darcy(grid.clone(), d, Scheme::Bdf2, 1.0);
        steady_gas.step(&fields, 1e3).unwrap();
        let steady = steady_gas
            .pressure()
            .iter()
            .fold(0.0_f64, |m, p| m.max(p.abs()));
        let mut gas = darcy(grid, d, Scheme::Bdf2, 1.0);
        let (worst, _, clamped) = march(&mut gas, &fields, 1e-4, 0.05);
        println!(
            "stability | {label:<18} | deposited φ_min {min_phi:.3} | clamped nodes {clamped} \
             | max P' {worst:.2} Pa | steady {steady:.2} Pa | no NaN"
        );
        let bound = frozen_bound(Scheme::Bdf2, steady);
        assert!(
            worst <= bound,
            "{label}: {worst} > {bound} (steady {steady})"
        );
        if label == "over-packed node" {
            assert!(
                min_phi < 0.3 && clamped > 0,
                "φ_min {min_phi}, clamped {clamped}"
            );
        } else {
            assert!(clamped > 0, "φ = 1 is clamped to φ_max");
        }
    }
}

/// Run the vertical case coupled for `seconds`, calling `each(time, coupler)` after every
/// exchange; asserts finiteness and |P'| < P0; returns the Δp trace (time, Pa/m) and the
/// coupling checks.
fn coupled(
    name: &str,
    s: &Scene,
    seconds: f64,
    mut each: impl FnMut(f64, &mut plugflow_coupling::Coupler),
    insert: &[[f64; 3]],
    v_s_max: f64,
) -> (Vec<(f64, f64)>, Vec<plugflow_coupling::CouplingCheck>) {
    let cfg = plugflow::setup::dem_config(s).unwrap();
    let mut e = NativeDem::new(cfg.clone()).unwrap();
    if !insert.is_empty() {
        let grains: Vec<plugflow_coupling::NewParticle> = insert
            .iter()
            .map(|x| plugflow_coupling::NewParticle {
                position: *x,
                velocity: [0.0; 3],
                radius: cfg.radius_min,
                density: cfg.density,
            })
            .collect();
        e.insert(&grains).unwrap();
    }
    let mut c = coupling_from_scene(s, &cfg).unwrap().unwrap();
    let p0 = s.file.gas.as_ref().unwrap().pressure.si;
    let n = (seconds / c.interval).round() as usize;
    let mut trace = Vec::new();
    let mut worst: f64 = 0.0;
    let tube = cfg.tube.unwrap();
    let gn = cfg.gravity.iter().map(|x| x * x).sum::<f64>().sqrt();
    let phi_min = s.file.gas.as_ref().unwrap().porosity_min.0;
    let speed_bound = 2.0 * (v_s_max / phi_min).max((2.0 * gn * tube.length).sqrt());
    let mut fastest: f64 = 0.0;
    for _ in 0..n {
        e.advance(c.substeps)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
        c.exchange(&mut e)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
        worst = worst.max(c.gas.pressure().iter().fold(0.0_f64, |m, p| m.max(p.abs())));
        fastest = e
            .particles()
            .velocity
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(fastest, f64::max);
        trace.push((e.time(), c.gas.pressure_drop_per_length()));
        each(e.time(), &mut c);
    }
    let checks = c.checks.clone();
    println!(
        "stability | {name:<34} | {:.2} s | grains {} | max |P'| {:.0} Pa (bound P0 {:.0} Pa) \
         | fastest grain {fastest:.2} m/s (bound {speed_bound:.1}) | final Δp {:.0} Pa/m \
         | warnings {} | no NaN",
        e.time(),
        e.particles().len(),
        worst,
        p0,
        trace.last().map_or(0.0, |t| t.1),
        checks
            .iter()
            .filter(|c| c.verdict == Verdict::Warning)
            .count()
    );
    assert!(worst < p0, "{name}: |P'| {worst} Pa reaches P0");
    assert!(
        fastest < speed_bound,
        "{name}: a grain reached {fastest} m/s (bound {speed_bound} m/s)"
    );
    (trace, checks)
}

/// v_s = 20 m/s: outside the d'Arcy model's range (seed 000 §4.1: above ~4 m/s it
/// underestimates the drag): the run warns, names why, and stays stable.
#[test]
fn superficial_velocity_20_m_s_warns_and_stays_stable() {
    let s = vertical(&["gas.superficial_velocity=20 m/s"]);
    let (_, checks) = coupled("v_s = 20 m/s", &s, 0.3, |_, _| {}, &[], 20.0);
    let w = checks
        .iter()
        .find(|c| c.name.contains("d'Arcy"))
        .expect("a d'Arcy range check");
    assert_eq!(w.verdict, Verdict::Warning);
    assert!(w.advice.contains("§4.1"), "{}", w.advice);
    // At the case's own 1 m/s the check passes.
    let cfg = plugflow::setup::dem_config(&vertical(&[])).unwrap();
    let c = coupling_from_scene(&vertical(&[]), &cfg).unwrap().unwrap();
    assert!(c
        .checks
        .iter()
        .any(|c| c.name.contains("d'Arcy") && c.verdict == Verdict::Ok));
}

/// A blocked tube: the most the inlet can feed (3.2 kg/h; random close packing at the feed
/// speed carries 3.3 kg/h) at 0.3 m/s of gas, below the 0.5 m/s where seed 000 §4.1 sees
/// the drag fail to carry the bulk. The tube fills from the bottom, the pressure drop keeps
/// rising, nothing blows up.
#[test]
fn blocked_tube_pressure_rises_without_blow_up() {
    let s = vertical(&[
        "inlet.mass_flow=3.2 kg/h",
        "gas.superficial_velocity=0.3 m/s",
        // The slab inlet, which places grains where there is room, at its largest feed.
        "inlet.mode=\"slab\"",
    ]);
    let (trace, _) = coupled(
        "blocked tube (3.2 kg/h, 0.3 m/s)",
        &s,
        1.5,
        |_, _| {},
        &[],
        0.3,
    );
    let at = |t: f64| {
        trace
            .iter()
            .filter(|(x, _)| (x - t).abs() < 0.1)
            .map(|(_, d)| *d)
            .sum::<f64>()
            / trace.iter().filter(|(x, _)| (x - t).abs() < 0.1).count() as f64
    };
    // The gas cannot lift the bed, so every grain fed adds to the bed the gas crosses:
    // the pressure drop grows with it (d'Arcy: Δp ∝ bed length at fixed porosity).
    let (early, late) = (at(0.5), at(1.4));
    println!("Δp at 0.5 s {early:.1} Pa/m, at 1.4 s {late:.1} Pa/m");
    assert!(late > early && early > 0.0, "Δp {early} → {late} Pa/m");
}

/// Grains exactly on gas nodes and exactly touching the tube wall: the deposit and the
/// interpolation have no division by a zero distance, the wall contact starts at zero
/// overlap.
#[test]
fn grains_on_grid_nodes_and_on_the_wall() {
    // A trickle (the slab inlet: a conveyor column this sparse is not a packing).
    let s = vertical(&["inlet.mass_flow=0.01 kg/h", "inlet.mode=\"slab\""]);
    let g = s.file.gas.as_ref().unwrap();
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let t = cfg.tube.unwrap();
    let grid = TubeGrid::new(
        t.origin, t.axis, t.radius, t.length, g.grid[0], g.grid[1], g.grid[2],
    );
    let r = cfg.radius_min;
    let mut x: Vec<[f64; 3]> = Vec::new();
    // Nodes sit at s = (k + ½)Δz, u = −R + (i + ½)Δx, w = −R + (j + ½)Δy in the tube frame
    // (coupling/src/grid.rs); every fifth slice, each node at least a radius inside.
    for k in (2..grid.nz).step_by(5) {
        for i in 0..grid.nx {
            for j in 0..grid.ny {
                let (s, u, w) = (
                    (k as f64 + 0.5) * grid.dz,
                    -grid.radius + (i as f64 + 0.5) * grid.dx,
                    -grid.radius + (j as f64 + 0.5) * grid.dy,
                );
                let p = [0, 1, 2]
                    .map(|c| grid.origin[c] + s * grid.axis[c] + u * grid.e1[c] + w * grid.e2[c]);
                if u.hypot(w) <= t.radius - r {
                    x.push(p);
                }
            }
        }
    }
    // Touching the wall: centre at exactly R − r, at heights between those nodes.
    for k in 0..12 {
        let a = k as f64 * std::f64::consts::FRAC_PI_6;
        x.push([
            (t.radius - r) * a.cos(),
            (t.radius - r) * a.sin(),
            0.05 + 0.03 * k as f64,
        ]);
    }
    assert!(x.len() > 20);
    coupled(
        "grains on nodes and on the wall",
        &s,
        0.1,
        |_, _| {},
        &x,
        1.0,
    );
}

/// A step change of the inlet gas flow (1 → 3 m/s after 0.4 s): the pressure drop jumps
/// up with the flow and nothing rings or blows up.
#[test]
fn step_change_of_the_inlet_flow() {
    let s = vertical(&[]);
    let (trace, _) = coupled(
        "inlet flow step 1 → 3 m/s",
        &s,
        0.6,
        |t, c| {
            if (t - 0.4).abs() < 0.5 * c.interval {
                c.gas.set_superficial_velocity(3.0);
            }
        },
        &[],
        3.0,
    );
    // d'Arcy: Δp ∝ v_s through the same grains, so the 20 ms after the step carry a clearly
    // larger pressure drop than the 20 ms before it (the grains barely move in 20 ms).
    let mean = |lo: f64, hi: f64| {
        let v: Vec<f64> = trace
            .iter()
            .filter(|(t, _)| *t > lo && *t <= hi)
            .map(|x| x.1)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (before, after) = (mean(0.38, 0.4), mean(0.401, 0.42));
    println!("Δp 20 ms before the step {before:.1} Pa/m, 20 ms after {after:.1} Pa/m");
    assert!(
        after > 1.5 * before,
        "Δp before {before}, after {after} Pa/m"
    );
}

// ----- The SIMPLE gas (volume-averaged Navier–Stokes, ideal gas), as the d'Arcy one above.

const SIMPLE_GAS: &str = "[gas]\nmodel = \"simple\"\nequation_of_state = \"ideal_gas\"\ndensity = \"1.2 kg/m^3\"\nviscosity = \"0.0181 cP\"\npressure = \"1013.25 hPa\"\nsuperficial_velocity = \"1 m/s\"\ngrid = [40, 4, 4]\n[coupling]\ndrag = \"ergun_wen_yu\"\n";

/// The scene's SIMPLE gas (3D cut cells: `grid = [40, 4, 4]`) over frozen grains.
fn simple_over(s: &Scene, grains: Option<&[[f64; 3]]>) -> (Box<dyn GasSolver>, GranularFields) {
    let cfg = plugflow::setup::dem_config(s).unwrap();
    let c = coupling_from_scene(s, &cfg).unwrap().unwrap();
    let x: Vec<[f64; 3]> = match grains {
        Some(x) => x.to_vec(),
        None => {
            let mut e = NativeDem::new(cfg.clone()).unwrap();
            e.advance((0.25 / e.time_step()) as u64).unwrap();
            e.particles().position.to_vec()
        }
    };
    let mut fields = GranularFields::default();
    deposit(
        c.gas.grid(),
        &x,
        &vec![[0.0; 3]; x.len()],
        &vec![cfg.radius_min; x.len()],
        &mut fields,
    );
    (c.gas, fields)
}

/// Step a gas over frozen grains until `t_end` in steps of `dt`: the largest |P'| seen and
/// the final inlet-to-outlet pressure drop per length.
fn march_any(gas: &mut dyn GasSolver, f: &GranularFields, dt: f64, t_end: f64) -> (f64, f64) {
    let mut worst: f64 = 0.0;
    for _ in 0..(t_end / dt).ceil() as usize {
        gas.step(f, dt).unwrap_or_else(|e| panic!("{e}"));
        assert!(gas.pressure().iter().all(|p| p.is_finite()), "NaN pressure");
        worst = worst.max(gas.pressure().iter().fold(0.0_f64, |m, p| m.max(p.abs())));
    }
    (worst, gas.pressure_drop_per_length())
}

/// The most a compressible gas's pressure may exceed its steady state by when its inflow
/// starts at once (Pa): the water-hammer surge ρ_g c u (Joukowsky), with u the interstitial
/// inflow at the densest clamped porosity φ_min = 0.3 and c = √(P0/ρ_g) (isothermal). The
/// inflow is switched on in one step, so the gas column is hit as by a piston; the drag
/// damps the wave (ρ_g ε/β ≈ 0.4 ms in the bed) but cannot make it higher.
fn joukowsky_surge(v_s: f64) -> f64 {
    let (rho, p0) = (1.2, 101_325.0f64);
    rho * (p0 / rho).sqrt() * v_s / 0.3
}

/// Gas steps from the acoustic limit (Δt = Δz/c, c = √(P0/ρ) ≈ 290 m/s isothermal) to 1e4
/// times past it, over a frozen bed: no NaN, the pressure never above its steady state plus
/// the water-hammer surge of the inflow switched on ([`joukowsky_surge`]), and it settles to
/// the steady pressure drop (reached by long steps; the steady state itself is checked
/// against Ergun's law in src/gas/simple/tests.rs).
#[test]
fn simple_gas_far_past_the_acoustic_limit() {
    let s = scene(
        &format!("{BED}{SIMPLE_GAS}")
            .replace("0.06 m", "0.14 m")
            .replace("0.055 m", "0.13 m")
            .replace("count = 150", "count = 400"),
        &[],
    );
    let (mut steady_gas, fields) = simple_over(&s, None);
    let (_, steady_dp) = march_any(steady_gas.as_mut(), &fields, 1.0, 20.0);
    let steady = steady_gas
        .pressure()
        .iter()
        .fold(0.0_f64, |m, p| m.max(p.abs()));
    assert!(steady > 0.0 && steady_dp > 0.0);
    let dz = steady_gas.grid().dz;
    let acoustic = dz / (101_325.0f64 / 1.2).sqrt();
    for ratio in [1.0, 1e2, 1e4] {
        let dt = ratio * acoustic;
        let (mut gas, _) = simple_over(&s, Some(&[]));
        // The bed's pressure diffuses over its length in ~L²/D ≈ 1 ms (D = P0 κ/(μ ε) ≈
        // 30 m²/s) once the surge has decayed; 50 ms and at least 20 steps.
        let (worst, dp) = march_any(gas.as_mut(), &fields, dt, (20.0 * dt).max(0.05));
        println!(
            "stability | SIMPLE Δt = {ratio:<6.0e} × Δz/c | max P' {worst:.1} Pa | steady \
             {steady:.1} Pa | Δp {dp:.0} (steady {steady_dp:.0}) Pa/m | no NaN"
        );
        let bound = steady + joukowsky_surge(1.0);
        assert!(
            worst <= bound,
            "Δt = {ratio} × the acoustic limit: P' {worst} beyond steady + surge {bound}"
        );
        assert!(
            (dp - steady_dp).abs() < 0.01 * steady_dp,
            "ratio {ratio}: Δp {dp} has not reached the steady {steady_dp} Pa/m"
        );
    }
}

/// ε → 0 and ε → 1 in the cut cells of the 3D SIMPLE tube: a pile far beyond close packing
/// in one spot and an empty tube. The pile's porosity is clamped up to φ_min and counted,
/// ε = 1 needs no clamp; the pressure stays finite and within the steady state (reached with
/// long steps) plus the inflow's surge.
#[test]
fn simple_gas_over_packed_and_empty_cut_cells() {
    let s = scene(&format!("{BED}{SIMPLE_GAS}"), &[]);
    // 300 grains within 1.5 mm of one point, off the axis: cut cells at the wall get them.
    let pile: Vec<[f64; 3]> = (0..300)
        .map(|k| {
            let a = k as f64 * 2.399;
            let r = 1.5e-3 * ((k % 17) as f64 / 17.0);
            [
                1.5e-3 + r * a.cos(),
                r * a.sin(),
                0.03 + 1e-5 * (k % 7) as f64,
            ]
        })
        .collect();
    for (label, grains) in [
        ("over-packed cut cells", &pile[..]),
        ("empty tube", &[][..]),
    ] {
        let (mut steady_gas, fields) = simple_over(&s, Some(grains));
        march_any(steady_gas.as_mut(), &fields, 1.0, 20.0);
        let steady = steady_gas
            .pressure()
            .iter()
            .fold(0.0_f64, |m, p| m.max(p.abs()));
        let (mut gas, _) = simple_over(&s, Some(grains));
        let mut clamped = 0;
        let mut worst: f64 = 0.0;
        for _ in 0..200 {
            clamped = gas.step(&fields, 1e-4).unwrap().clamped_nodes;
            assert!(gas.pressure().iter().all(|p| p.is_finite()));
            worst = worst.max(gas.pressure().iter().fold(0.0_f64, |m, p| m.max(p.abs())));
        }
        let min_phi = fields.porosity.iter().copied().fold(1.0, f64::min);
        println!(
            "stability | SIMPLE {label:<22} | deposited φ_min {min_phi:.3} | clamped {clamped} \
             | max P' {worst:.2} Pa | steady {steady:.2} Pa | no NaN"
        );
        // The same bound as above: the steady state plus the inflow's surge.
        let bound = steady + joukowsky_surge(1.0);
        assert!(worst <= bound, "{label}: {worst} > steady + surge {bound}");
        if grains.is_empty() {
            // ε = 1 is a valid state of the gas equations (no grains, no drag): SIMPLE
            // clamps only from below (src/gas/simple/tube.rs), unlike the d'Arcy model,
            // whose permeability diverges at ε = 1.
            assert_eq!(clamped, 0, "{label}: nothing to clamp");
        } else {
            assert!(min_phi < 0.3, "the pile is over-packed: φ_min {min_phi}");
            assert!(clamped > 0, "{label}: φ = {min_phi} must be clamped");
        }
    }
}

/// The vertical case with the SIMPLE gas (ideal gas, Ergun / Wen–Yu) at v_s = 20 m/s,
/// twenty times the case's flow: nothing blows up, |P'| stays below P0 and every grain
/// below twice the interstitial gas speed (the bounds of [`coupled`]).
#[test]
fn simple_gas_at_20_m_s_stays_bounded() {
    let s = Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/vertical_plug_simple.toml"),
        &[
            "dem.threads=1".to_string(),
            // 20 × the case's 2.3 l/min: v_s = 20 m/s in the 7 mm tube.
            "gas.flow=\"46 l/min\"".to_string(),
        ],
    )
    .unwrap();
    let (trace, _) = coupled("SIMPLE v_s = 20 m/s", &s, 0.2, |_, _| {}, &[], 20.0);
    assert!(trace.iter().all(|(_, d)| d.is_finite() && *d > 0.0));
}

/// A blocked tube with the SIMPLE ideal gas: the most the inlet can feed (3.2 kg/h) at
/// v_s = 0.3 m/s, too little gas to lift the bed: the tube fills from the bottom, the gas
/// compresses under it, the pressure drop keeps rising and nothing blows up.
#[test]
fn simple_gas_blocked_tube_pressure_rises_without_blow_up() {
    let s = Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/vertical_plug_simple.toml"),
        &[
            "dem.threads=1".to_string(),
            "inlet.mass_flow=\"3.2 kg/h\"".to_string(),
            // 0.3 m/s in the 7 mm tube.
            "gas.flow=\"0.69 l/min\"".to_string(),
        ],
    )
    .unwrap();
    let (trace, _) = coupled(
        "SIMPLE blocked tube (3.2 kg/h, 0.3 m/s)",
        &s,
        1.0,
        |_, _| {},
        &[],
        0.3,
    );
    let at = |t: f64| {
        let v: Vec<f64> = trace
            .iter()
            .filter(|(x, _)| (x - t).abs() < 0.05)
            .map(|(_, d)| *d)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (early, late) = (at(0.4), at(0.95));
    println!("SIMPLE blocked tube: Δp at 0.4 s {early:.1} Pa/m, at 0.95 s {late:.1} Pa/m");
    assert!(late > early && early > 0.0, "Δp {early} → {late} Pa/m");
}
