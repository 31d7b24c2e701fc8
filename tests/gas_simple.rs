//! The SIMPLE gas coupled to the DEM (`gas.model = "simple"`, `coupling.drag =
//! "ergun_wen_yu"`): one grain settling through still gas reaches the Schiller–Naumann
//! terminal velocity, and the CFDEM Ergun test's bed follows Ergun, then carries its weight.
//! (The solver alone — plane Poiseuille, packed bed against Ergun — is
//! tested in src/gas/simple/tests.rs.)

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;
use plugflow::setup::coupling_from_scene;
use plugflow_coupling::drag::ergun_wen_yu::schiller_naumann;
use plugflow_coupling::DemBackend;

/// d = 1 mm, ρ_p = 300 kg/m³ in air (ρ = 1.2 kg/m³, μ = 1.8e-5 Pa·s) at rest in a closed
/// 2.5 m tube of 20 mm: terminal velocity where m g = ½ C_D(Re) ρ (π d²/4) v², C_D of
/// Schiller–Naumann (Wen–Yu at ε → 1): v_t ≈ 1.8 m/s, Re ≈ 120, reached within ~5 v_t/g ≈
/// 0.9 s. Within 2 % (the issue's band): the grain drags its cell's gas along by ~0.3 % of
/// its speed (the impulse it leaves in a cell while crossing it over that cell's gas mass),
/// its cell's porosity differs from 1 by 2e-4, and the model leaves out the gas's weight, so
/// the comparison is without buoyancy (which would be ρ/ρ_p = 0.4 %).
#[test]
fn single_grain_reaches_the_schiller_naumann_terminal_velocity() {
    let text = r#"
schema_version = 1
name = "settling"
duration = "1.2 s"
gravity = [0, 0, -9.81]
[tube]
diameter = "20 mm"
length = "2.5 m"
inlet_end = "closed"
outlet_end = "closed"
[particles]
diameter = "1 mm"
density = "300 kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
contact_time = "1e-4 s"
friction = 0.5
restitution = 0.5
[initial]
count = 1
from = "2.43 m"
to = "2.45 m"
[gas]
model = "simple"
density = "1.2 kg/m^3"
viscosity = "1.8e-5 Pa s"
pressure = "1013.25 hPa"
superficial_velocity = "0 m/s"
grid = [50, 1, 2]
[coupling]
interval = "1e-3 s"
drag = "ergun_wen_yu"
[dem]
threads = 1
"#;
    let s = Scene::parse(text, &[]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let mut e = NativeDem::new(cfg.clone()).unwrap();
    let mut c = coupling_from_scene(&s, &cfg).unwrap().unwrap();
    assert_eq!(c.gas.name(), "simple");
    let n = (1.2 / c.interval).round() as usize;
    let mut speeds = Vec::new();
    for _ in 0..n {
        e.advance(c.substeps).unwrap();
        c.exchange(&mut e).unwrap();
        speeds.push((e.time(), -e.particles().velocity[0][2]));
    }
    // The last 0.2 s.
    let tail: Vec<f64> = speeds
        .iter()
        .filter(|(t, _)| *t > 1.0)
        .map(|x| x.1)
        .collect();
    let measured = tail.iter().sum::<f64>() / tail.len() as f64;
    let (d, rho_p, rho, mu) = (1e-3, 300.0, 1.2, 1.8e-5);
    let weight = rho_p * std::f64::consts::PI / 6.0 * d * d * d * 9.81;
    let drag = |v: f64| {
        0.5 * schiller_naumann(rho * d * v / mu) * rho * std::f64::consts::PI * d * d / 4.0 * v * v
    };
    let (mut lo, mut hi) = (0.01, 20.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if drag(mid) < weight {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let exact = 0.5 * (lo + hi);
    println!(
        "terminal velocity: SIMPLE + Ergun/Wen–Yu {measured:.4} m/s, Schiller–Naumann {exact:.4} m/s"
    );
    assert!(
        (measured / exact - 1.0).abs() < 0.02,
        "{measured} vs {exact} m/s"
    );
    // Still there and steady: the grain has not reached the bottom, its speed no longer rises.
    assert!(e.particles().position[0][2] > 0.1);
    let spread = tail
        .iter()
        .fold(0.0_f64, |m, v| m.max((v - measured).abs()));
    assert!(
        spread < 0.01 * exact,
        "speed still changing by {spread} m/s"
    );
}

/// The CFDEM Ergun test conditions (CFDEMcoupling's ErgunTestMPI, as the issue gives them):
/// 10 000 grains d = 1 mm, ρ = 2000 kg/m³, a bed ≈ 15.6 mm high at ε ≈ 0.45, gas ρ = 10 kg/m³,
/// μ = 1.5e-3 Pa·s, the superficial velocity ramped from 0.002 to 0.02 m/s. The bed sits in a
/// tube of the CFDEM box's cross-section (6.1e-4 m², D = 27.9 mm) on the gas-permeable inlet
/// cap; the walls are frictionless so that they carry none of the bed (as in the d'Arcy
/// fluidisation test, tests/coupled.rs), leaving the gas and the grains' weight to balance.
///
/// Below minimum fluidisation (U < 0.8 U_mf) Δp follows the Ergun equation with the settled
/// bed's porosity and height; above it (U > 1.2 U_mf) Δp levels at the bed's weight per area.
/// Both within 5 % (the issue's band). What separates them from the formulas: the bed's
/// height is read from its ragged top (±½ grain of 15 mm: ±3 % in h, and (1−ε)² ∝ 1/h² moves
/// the other way, so ±3 % in Ergun's Δp), the porosity deposited on a 2.5 mm grid smears the
/// top layer over a cell, and above U_mf the lifted bed accelerates with the ramp (Δp A = W +
/// M a), and the gas the creeping bed displaces (continuity keeps ∂ε/∂t) shows at the
/// smallest Δp. Measured: Ergun to 2.7 % at U = 0.002 m/s (Δp 25 Pa) and 1–2.5 % above,
/// plateau 167–170 Pa against 168.0 Pa.
#[test]
fn cfdem_ergun_test_pressure_drop_follows_ergun_then_levels_at_the_bed_weight() {
    cfdem_ergun_test([20, 1, 2]);
}

/// The same in the 3D cut-cell tube (4 × 4 cells across the 27.9 mm tube, whose corner
/// cells are cut away), same bands: the bed's Δp is the gas crossing it, whatever the grid.
/// Measured: Ergun to 0.5 % at U = 0.002 m/s, 2–4 % below it at 0.005–0.012 m/s (the wall
/// columns resolve the looser packing against the wall, ε ≈ 0.5 within a grain of it, and
/// the gas takes that path; the 2D grid's two half-disc rows average it away), plateau
/// 168–170 Pa against 168.0 Pa.
#[test]
fn cfdem_ergun_test_in_the_3d_tube() {
    cfdem_ergun_test([20, 4, 4]);
}

fn cfdem_ergun_test(grid: [usize; 3]) {
    let text = r#"
schema_version = 1
name = "ergun_test"
duration = "1 s"
seed = 3
gravity = [0, 0, -9.81]
[tube]
diameter = "27.9 mm"
length = "0.05 m"
inlet_end = "closed"
outlet_end = "closed"
[particles]
diameter = "1 mm"
density = "2000 kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
contact_time = "4e-4 s"
friction = 0.5
wall_friction = 0.0
restitution = 0.5
[initial]
count = 10000
from = "0 m"
to = "0.045 m"
[gas]
model = "simple"
density = "10 kg/m^3"
viscosity = "1.5e-3 Pa s"
pressure = "1013.25 hPa"
superficial_velocity = "0 m/s"
[coupling]
interval = "1e-4 s"
drag = "ergun_wen_yu"
[dem]
threads = 2
dt = "1e-5 s"
"#;
    let grid_set = format!("gas.grid=[{}, {}, {}]", grid[0], grid[1], grid[2]);
    let s = Scene::parse(text, &[grid_set]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let mut e = NativeDem::new(cfg.clone()).unwrap();
    let mut c = coupling_from_scene(&s, &cfg).unwrap().unwrap();
    // Settle with the gas at rest (the gas still exchanges: the gas the grains displace has
    // to escape through the bed, which slows its last compaction); the grains fall 45 mm in
    // 0.1 s and the bed has consolidated by 0.3 s. Then 0.02 s at the ramp's first
    // velocity, for the gas's own start-up transient (an impulsive start) to pass.
    for k in 0..(0.32 / c.interval).round() as usize {
        if k == (0.3 / c.interval).round() as usize {
            c.gas.set_superficial_velocity(0.002);
        }
        e.advance(c.substeps).unwrap();
        c.exchange(&mut e).unwrap();
    }
    let (n, d, rho_p, rho, mu) = (10_000.0, 1e-3, 2000.0, 10.0, 1.5e-3);
    let area = std::f64::consts::PI * (0.5 * 27.9e-3f64).powi(2);
    let v_grain = std::f64::consts::PI / 6.0 * d * d * d;
    let weight_per_area = n * v_grain * rho_p * 9.81 / area;
    // The bed: height from the grains' top (mean of the highest 2 %, plus a radius).
    let bed = |e: &NativeDem| {
        let mut z: Vec<f64> = e.particles().position.iter().map(|x| x[2]).collect();
        z.sort_by(|a, b| a.total_cmp(b));
        let top = z[z.len() - z.len() / 50..].iter().sum::<f64>() / (z.len() / 50) as f64;
        let h = top + 0.5 * d;
        (h, 1.0 - n * v_grain / (area * h))
    };
    let (h0, eps0) = bed(&e);
    println!("settled bed: height {:.2} mm, porosity {eps0:.3}", h0 * 1e3);
    let ergun = |u: f64, eps: f64, h: f64| {
        h * (150.0 * mu * (1.0 - eps).powi(2) * u / (eps.powi(3) * d * d)
            + 1.75 * rho * (1.0 - eps) * u * u / (eps.powi(3) * d))
    };
    // Pressure at the inlet cap: the first two slices' centres (volume-weighted over the
    // open cells) extrapolated to the face.
    let inlet_pressure = |c: &plugflow_coupling::Coupler| {
        let (p, g) = (c.gas.pressure(), c.gas.grid());
        let per_slice = g.nx * g.ny;
        let col = |k: usize| {
            let nodes = (k * per_slice..(k + 1) * per_slice).filter(|&n| g.is_open(n));
            let (s, v) = nodes.fold((0.0, 0.0), |(s, v), n| {
                (s + p[n] * g.volume[n], v + g.volume[n])
            });
            s / v
        };
        1.5 * col(0) - 0.5 * col(1)
    };
    let u_mf = {
        // Where Ergun at the settled bed carries the weight.
        let (mut lo, mut hi) = (1e-4, 0.1);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if ergun(mid, eps0, h0) < weight_per_area {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    println!(
        "bed weight per area {weight_per_area:.1} Pa; Ergun's minimum fluidisation {u_mf:.4} m/s"
    );
    // Ramp 0.002 → 0.02 m/s over 0.6 s (0.03 m/s²: the bed's response time, ρ_p d²/(150 μ)
    // ε³/(1−ε) ≈ 1 ms, is far shorter, so every point is quasi-steady).
    let (u0, u1, ramp) = (0.002, 0.02, 0.6);
    let steps = (ramp / c.interval).round() as usize;
    let mut below = Vec::new();
    let mut above = Vec::new();
    for k in 0..=steps {
        let u = u0 + (u1 - u0) * k as f64 / steps as f64;
        c.gas.set_superficial_velocity(u);
        e.advance(c.substeps).unwrap();
        c.exchange(&mut e).unwrap();
        if k % 200 == 0 {
            let dp = inlet_pressure(&c);
            let (h, eps) = bed(&e);
            println!(
                "U {u:.4} m/s: Δp {dp:7.2} Pa, Ergun {:7.2} Pa, weight {weight_per_area:.1} Pa; bed {:.2} mm, ε {eps:.3}",
                ergun(u, eps0, h0),
                h * 1e3
            );
            if u < 0.8 * u_mf {
                below.push((u, dp));
            } else if u > 1.2 * u_mf {
                above.push((u, dp));
            }
        }
    }
    assert!(below.len() >= 4 && above.len() >= 4, "{below:?} {above:?}");
    for (u, dp) in below {
        let expect = ergun(u, eps0, h0);
        assert!(
            (dp / expect - 1.0).abs() < 0.05,
            "U {u}: Δp {dp} Pa vs Ergun {expect} Pa"
        );
    }
    for (u, dp) in above {
        assert!(
            (dp / weight_per_area - 1.0).abs() < 0.05,
            "U {u}: Δp {dp} Pa vs bed weight {weight_per_area} Pa"
        );
    }
}
