//! Periodic boxes and periodic tube sections (issue 22): grains cross the seam with their
//! momentum, touch across it with their contact history, and a periodic bed moves as the
//! middle of its tripled copy does.

mod common;
use common::*;
use plugflow_coupling::DemBackend;

/// A box periodic along x, [0, L) with L = 10 mm, 1.4 mm grains, walls as `extra` gives.
fn periodic_box(gravity: &str, contact: &str, extra: &str) -> String {
    box_scene(gravity, contact, extra)
        .replace("min = [-0.01, -0.01, -0.01]", "min = [0, -0.01, -0.01]")
        .replace(
            "max = [0.01, 0.01, 0.01]",
            "max = [0.01, 0.01, 0.01]\nperiodic = [true, false, false]",
        )
}

/// x wrapped into [0, L).
fn wrap(x: f64, l: f64) -> f64 {
    x.rem_euclid(l)
}

#[test]
fn a_grain_crossing_the_seam_keeps_its_momentum() {
    // Free flight at 0.37 m/s along x through the 10 mm period for 0.1 s (3.7 crossings):
    // the velocity is untouched, the position is the straight line wrapped into the box.
    let mut dem = engine(&periodic_box("[0, 0, 0]", HOOKE, ""));
    dem.insert(&[grain([0.002, 0.0, 0.0], [0.37, 0.01, 0.0])])
        .unwrap();
    let steps = (0.1 / dem.time_step()).round() as u64;
    dem.advance(steps).unwrap();
    let p = dem.particles();
    assert_eq!(p.len(), 1, "the grain is never lost at the seam");
    assert_eq!(p.velocity[0], [0.37, 0.01, 0.0]);
    let t = dem.time();
    let expect = wrap(0.002 + 0.37 * t, 0.01);
    // Wrapped at each neighbour build: between builds a grain may lie up to a skin past
    // the end, so compare on the circle. 1e-12 m: rounding of ~5e4 position updates.
    let got = p.position[0][0];
    let d = (got - expect).abs().min(0.01 - (got - expect).abs());
    assert!(d < 1e-12, "x = {got}, expected {expect} (mod 0.01)");
    assert!((p.position[0][1] - 0.01 * t).abs() < 1e-12);
}

/// Two grains meeting obliquely with friction, once across the seam and once in the middle
/// of the box; returns their velocities and spins after the collision, by id.
fn oblique_collision(across_seam: bool) -> Vec<[f64; 9]> {
    let mut dem = engine(&periodic_box("[0, 0, 0]", HOOKE, ""));
    let (r, gap, offset) = (0.7e-3, 2e-4, 0.4e-3);
    // The pair straddles x = 0 (≡ L) or sits at x = L/2; grain 0 moves +x, grain 1 −x, with
    // a sideways offset that makes the contact slide and roll (history, torques).
    let centre = if across_seam { 0.0 } else { 0.005 };
    let at = |x: f64| if across_seam { wrap(x, 0.01) } else { x };
    dem.insert(&[
        grain([at(centre - r - gap), -offset, 0.0], [0.2, 0.0, 0.0]),
        grain([at(centre + r + gap), offset, 0.0], [-0.2, 0.0, 0.0]),
    ])
    .unwrap();
    let steps = (0.01 / dem.time_step()).round() as u64;
    dem.advance(steps).unwrap();
    let p = dem.particles();
    let mut out = vec![[0.0; 9]; 2];
    for k in 0..2 {
        let id = p.id[k] as usize;
        let (x, v, w) = (p.position[k], p.velocity[k], p.angular_velocity[k]);
        // Positions relative to the collision's centre, on the circle.
        let dx = x[0] - centre;
        let dx = dx - 0.01 * (dx / 0.01).round();
        out[id] = [dx, x[1], x[2], v[0], v[1], v[2], w[0], w[1], w[2]];
    }
    out
}

#[test]
fn a_collision_across_the_seam_equals_one_in_the_middle() {
    // The contact across the seam is found through the partner's image and keeps its
    // tangential history as any other: velocities, spins and positions after an oblique,
    // sliding collision equal those of the same collision mid-box. The two differ only in
    // the rounding of positions of different magnitude (x_j + L − x_i against x_j − x_i),
    // carried through the contact: measured 3e-15 m in position (3e-12 of the 1 mm scale),
    // 8e-14 relative in velocity and spin. Tolerance 1e-10 of each quantity's scale; a
    // contact that lost its history or missed its image would be off at the 1e-2 level.
    let (a, b) = (oblique_collision(true), oblique_collision(false));
    let scale = [1e-3, 1e-3, 1e-3, 0.2, 0.2, 0.2, 300.0, 300.0, 300.0];
    for g in 0..2 {
        for c in 0..9 {
            assert!(
                (a[g][c] - b[g][c]).abs() < 1e-10 * scale[c],
                "grain {g}, entry {c}: across the seam {} vs mid-box {}",
                a[g][c],
                b[g][c]
            );
        }
        assert!(
            a[g][7] != 0.0 || a[g][6] != 0.0 || a[g][8] != 0.0,
            "spins up"
        );
    }
    assert!(a[0][3] < 0.2 && a[0][4] != 0.0, "it collided: {:?}", a[0]);
}

/// Grains of a loose lattice falling onto a floor between side walls in y, in a box
/// periodic along x: `copies` periods side by side (ids copy after copy), each grain nudged
/// along x by up to `nudge` m.
fn falling_bed(copies: usize, nudge: f64) -> plugflow::dem::NativeDem {
    let walls = r#"
[[walls]]
name = "floor"
point = [0, 0, 0]
normal = [0, 0, 1]
[[walls]]
name = "front"
point = [0, -0.0035, 0]
normal = [0, 1, 0]
[[walls]]
name = "back"
point = [0, 0.0035, 0]
normal = [0, -1, 0]"#;
    let l = 0.01;
    let length = l * copies as f64;
    let text = box_scene("[0, 0, -9.81]", HOOKE, walls)
        .replace("min = [-0.01, -0.01, -0.01]", "min = [0, -0.004, -0.001]")
        .replace(
            "max = [0.01, 0.01, 0.01]",
            &format!("max = [{length}, 0.004, 0.03]\nperiodic = [true, false, false]"),
        );
    let mut dem = engine(&text);
    let mut grains = vec![];
    for c in 0..copies {
        for k in 0..8 {
            for j in 0..4 {
                for i in 0..6 {
                    // A lattice 1.66 mm apart along x (its rows straddle x = 0, so grains
                    // meet across the seam), 1.6 mm across, with a fixed jitter.
                    let h = ((i * 7 + j * 13 + k * 29) % 11) as f64 / 10.0 - 0.5;
                    let x = wrap(-0.0008 + i as f64 * 0.00166 + 1e-4 * h, l) + c as f64 * l;
                    grains.push(grain(
                        [
                            x,
                            -0.0024 + j as f64 * 0.0016 + 5e-5 * h,
                            0.001 + k as f64 * 0.0016,
                        ],
                        [0.02 * h, 0.0, 0.0],
                    ));
                }
            }
        }
    }
    // Rounding-sized noise in every grain (a pattern of ±nudge).
    for (k, g) in grains.iter_mut().enumerate() {
        g.position[0] += nudge * (((k * 37) % 19) as f64 / 9.0 - 1.0);
    }
    dem.insert(&grains).unwrap();
    dem
}

/// Largest distance (on the circle along x) between grain `id` of `a` and grain
/// `id + shift_id` of `b` moved back by `shift_x`, over the grains of `a`.
fn worst_apart(a: &dyn DemBackend, b: &dyn DemBackend, shift_id: u64, shift_x: f64) -> f64 {
    let (p, q) = (a.particles(), b.particles());
    let mut worst: f64 = 0.0;
    for k in 0..p.len() {
        let m =
            q.id.iter()
                .position(|&i| i == p.id[k] + shift_id)
                .expect("the same grain");
        let (x, y) = (p.position[k], q.position[m]);
        let dx = (x[0] - (y[0] - shift_x)).rem_euclid(0.01);
        worst = worst
            .max(dx.min(0.01 - dx))
            .max((x[1] - y[1]).abs())
            .max((x[2] - y[2]).abs());
    }
    worst
}

#[test]
fn a_periodic_bed_moves_as_the_middle_of_its_tripled_copy() {
    // 192 grains fall onto a floor and pile up across the seam, in a box periodic along x;
    // the same grains three times over in a box three periods long move alike, the middle
    // copy's grains where the single period's are (by symmetry the tripled bed stays
    // periodic with the short period). The two runs order their arithmetic differently
    // (sort orders, rebuild steps), so they part at rounding level (4e-15 m at 5 ms), and
    // the flow's chaos amplifies that once the grains touch. Measured: 1.3e-12 m at 20 ms,
    // then about ×100 per 5 ms. Two checks: (1) up to 20 ms, when the bed has formed
    // across the seam, within 1e-10 m (a contact across the seam missed, or its history
    // lost, parts the runs by the contact's own scale, ~1e-6 m, within one contact time);
    // (2) later, within 50 times the divergence of the same chaos seeded on purpose: the
    // single period again with every grain nudged by up to 4e-15 m (ratio measured ≤ 10).
    let (mut one, mut three) = (falling_bed(1, 0.0), falling_bed(3, 0.0));
    let mut twin = falling_bed(1, 4e-15);
    let n = one.particles().len() as u64;
    let steps = (0.05 / one.time_step()).round() as u64;
    for _ in 0..10 {
        one.advance(steps / 10).unwrap();
        three.advance(steps / 10).unwrap();
        twin.advance(steps / 10).unwrap();
        let tripled = worst_apart(&one, &three, n, 0.01);
        let chaos = worst_apart(&one, &twin, 0, 0.0);
        let t = one.time();
        if t < 0.0201 {
            assert!(
                tripled < 1e-10,
                "t = {t:.3} s: the copies part by {tripled:e} m"
            );
        } else {
            assert!(
                tripled < 50.0 * chaos + 1e-13,
                "t = {t:.3} s: the copies part by {tripled:e} m, seeded chaos by {chaos:e} m"
            );
        }
    }
}

#[test]
fn a_periodic_tube_section_keeps_its_grains_and_their_drift() {
    // A horizontal periodic section (x, 20 mm long, 7 mm across) with 150 grains given an
    // axial drift of 0.3 m/s, settling under gravity against the wall: no grain is lost at
    // the seam, every one stays inside the tube and within the period after a build, and
    // the section's axial momentum falls in size (wall friction brakes it; nothing feeds
    // it). It may be gone by 0.1 s: a grain sliding on the wall stops in 0.3 / (μ g) =
    // 0.06 s, and the tangential springs' recoil can leave a trace of either sign (t_c/50:
    // +0.60 of 45 kept; t_c/30: −0.24).
    let text = r#"
schema_version = 1
name = "periodic-tube"
duration = "1 s"
gravity = [0, 0, -9.81]
[tube]
diameter = "7 mm"
length = "20 mm"
axis = [1, 0, 0]
periodic = true
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
from = "0 mm"
to = "20 mm"
velocity = ["0.3 m/s", "0 m/s", "0 m/s"]
"#;
    let mut dem = engine(text);
    let n = dem.particles().len();
    assert_eq!(n, 150);
    let momentum = |d: &plugflow::dem::NativeDem| -> f64 {
        d.particles().velocity.iter().map(|v| v[0]).sum::<f64>()
    };
    let start = momentum(&dem);
    let steps = (0.02 / dem.time_step()).round() as u64;
    for _ in 0..5 {
        dem.advance(steps).unwrap();
        let p = dem.particles();
        assert_eq!(p.len(), n, "grains lost at t = {}", dem.time());
        for x in p.position {
            let radial = x[1].hypot(x[2]);
            assert!(radial < 3.5e-3 - 0.7e-3 + 1e-5, "outside the tube: {x:?}");
            // Within the period up to the skin's stray since the last build.
            assert!(x[0] > -0.2e-3 && x[0] < 0.0202, "x = {}", x[0]);
        }
    }
    let end = momentum(&dem);
    assert!(end.abs() < start, "axial momentum {start} → {end}");
}

#[test]
fn a_periodic_section_reports_its_solids_mass_flow_through_a_section() {
    // A frictionless tube wall takes no axial momentum, and contacts between grains
    // conserve it: the section's solids mass flow stays N m v0 / L exactly (to rounding) —
    // 150 grains of 1.347e-6 kg at 0.3 m/s in 20 mm. The summary reports it as the mean
    // through a section (kg/h) and no outflow (a periodic section has no outlet).
    let dir = std::env::temp_dir().join(format!("plugflow_periodic_flow_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scenes/good/periodic_tube_section.toml");
    let (code, text) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
        "--duration",
        "0.1",
        "--set",
        "contact.wall_friction=0",
        "--set",
        "output.settling_time=0.02 s",
    ]);
    assert_eq!(code, 0, "{text}");
    let s = read_summary(&dir);
    let m = 937.0 * std::f64::consts::PI / 6.0 * 1.4e-3f64.powi(3);
    let expect = 150.0 * m * 0.3 / 0.02 * 3600.0;
    let got = s["solids_mass_flow_kg_per_h"].as_f64().unwrap();
    assert!(
        (got - expect).abs() < 1e-9 * expect,
        "{got} vs {expect} kg/h"
    );
    assert!(
        s["mass_outflow_kg_per_h"].is_null(),
        "{}",
        s["mass_outflow_kg_per_h"]
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_periodic_section_with_gas_runs_under_its_flow_controller() {
    // A vertical periodic section with a plug of 100 grains and no wall friction: without
    // gas the grains fall freely through the seam; with the d'Arcy gas held at 0.3 m/s
    // upwards by the flow controller the drag brakes their fall. The summary's pressure
    // drop is the controller's driving gradient, above the empty tube's η U / κ(φ_max)
    // (the plug resists the gas) and finite; the solids flow through a section is downwards
    // in both runs and slower with gas.
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scenes/good/periodic_vertical_section_gas.toml");
    let run = |tag: &str, text: &str| {
        let dir = std::env::temp_dir().join(format!("plugflow_pgas_{tag}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("scene.toml");
        std::fs::write(&path, text).unwrap();
        let out = dir.join("out");
        let (code, log) = plugflow(&[
            "run",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        assert_eq!(code, 0, "{log}");
        let s = read_summary(&out);
        std::fs::remove_dir_all(&dir).ok();
        s
    };
    let text = std::fs::read_to_string(&scene).unwrap();
    let (head, tail) = text.split_at(text.find("[gas]").expect("the scene has gas"));
    let without_gas = format!(
        "{head}{}",
        &tail[tail.find("[output]").expect("and output")..]
    );
    let with_gas = run("gas", &text);
    let no_gas = run("none", &without_gas);
    let flow = |s: &serde_json::Value| s["solids_mass_flow_kg_per_h"].as_f64().unwrap();
    let dp = with_gas["pressure_drop_hpa_per_m"].as_f64().unwrap() * 100.0;
    let empty = 1.81e-5 * 0.3 / plugflow::gas::carman_kozeny(1.4e-3, 0.99);
    assert!(
        dp.is_finite() && dp > 10.0 * empty,
        "G = {dp} Pa/m, empty tube {empty}"
    );
    assert!(flow(&no_gas) < 0.0 && flow(&with_gas) < 0.0);
    assert!(
        flow(&with_gas) > flow(&no_gas),
        "with gas {} kg/h, without {} kg/h",
        flow(&with_gas),
        flow(&no_gas)
    );
}

#[test]
fn a_periodic_section_with_the_simple_gas_holds_its_flow_and_drives_the_grains() {
    // A horizontal periodic section (20 mm pipe, 0.1 m) with a loose plug of 600 grains
    // under the SIMPLE gas held at 1.5 m/s by the flow controller: the controller holds
    // the mean superficial velocity at every sample (each gas step converges it to the
    // solver's tolerance, 1e-7 relative); the driving gradient, the summary's pressure drop,
    // exceeds the empty pipe's Hagen–Poiseuille 8 μ U / R² (the grains resist the gas); and
    // the gas pushes the grains along the axis (they start at rest with gravity across the
    // axis, so without the gas their axial flow is nil).
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scenes/good/periodic_horizontal_section_simple.toml");
    let dir = std::env::temp_dir().join(format!("plugflow_psimple_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.join("out");
    let (code, log) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{log}");
    let s = read_summary(&out);
    let held = &s["slug"]["gas_mean_superficial_velocity_m_s"];
    let (mean, std) = (
        held["mean"].as_f64().unwrap(),
        held["std"].as_f64().unwrap(),
    );
    assert!(
        (mean / 1.5 - 1.0).abs() < 1e-6 && std < 1e-6,
        "mean superficial velocity {mean} ± {std} m/s"
    );
    let dp = s["pressure_drop_hpa_per_m"].as_f64().unwrap() * 100.0;
    let empty = 8.0 * 1.81e-5 * 1.5 / (0.01f64 * 0.01);
    assert!(
        dp.is_finite() && dp > 2.0 * empty,
        "G {dp} Pa/m, empty pipe {empty}"
    );
    let flow = s["solids_mass_flow_kg_per_h"].as_f64().unwrap();
    assert!(flow > 0.1, "solids flow {flow} kg/h");
    assert_eq!(s["gas_model"], "simple");
    assert!(out.join("slug.csv").exists());
    std::fs::remove_dir_all(&dir).ok();
}
