//! The built-in DEM against analytic answers. Each tolerance says why it is what it is.

mod common;
use common::*;
use plugflow_coupling::DemBackend;

/// The `[dem]` table of the collision scenes: no rotation (head-on), dt = t_c / `steps`.
fn collision_dem_table(steps: f64) -> String {
    format!("[dem]\nrotation = false\ndt_fraction = {steps}\n")
}

/// Head-on collision of two grains at dt = t_c / `steps`; returns (restitution, contact
/// duration, dt).
fn binary_collision(contact: &str, v: f64, steps: f64) -> (f64, f64, f64) {
    let mut dem = engine(&box_scene(
        "[0, 0, 0]",
        contact,
        &collision_dem_table(steps),
    ));
    let r = 0.7e-3;
    let dt = dem.time_step();
    // First touch 5.37 steps in. A touch that falls within ~1e-3 of a step boundary makes
    // the discrete contact one step longer and e 3 % low at t_c/50 (seen at phase 0 and
    // 0.999, not at 1e-6 … 0.99): a measure-small set that a real packing never aligns to.
    let half_gap = v * dt * 5.37;
    dem.insert(&[
        grain([-r - half_gap, 0.0, 0.0], [v, 0.0, 0.0]),
        grain([r + half_gap, 0.0, 0.0], [-v, 0.0, 0.0]),
    ])
    .unwrap();
    let mut steps_in_contact = 0u64;
    let mut touched = false;
    for _ in 0..200_000 {
        dem.advance(1).unwrap();
        let p = dem.particles();
        let gap = (p.position[1][0] - p.position[0][0]).abs() - 2.0 * r;
        if gap < 0.0 {
            touched = true;
            steps_in_contact += 1;
        } else if touched {
            break;
        }
    }
    let p = dem.particles();
    let vout = (p.velocity[1][0] - p.velocity[0][0]).abs() / 2.0;
    (vout / v, steps_in_contact as f64 * dt, dt)
}

/// Grain hitting a plane wall head-on at dt = t_c / `steps`; returns (restitution, contact
/// duration, dt).
fn wall_collision(contact: &str, v: f64, steps: f64) -> (f64, f64, f64) {
    // First touch 5.37 steps in (see `binary_collision` on step-aligned touches).
    wall_collision_from(contact, v, steps, |dt| v * dt * 5.37)
}

/// [`wall_collision`] from a gap of `gap(dt)` metres.
fn wall_collision_from(
    contact: &str,
    v: f64,
    steps: f64,
    gap: impl Fn(f64) -> f64,
) -> (f64, f64, f64) {
    let walls = collision_dem_table(steps)
        + "[[walls]]\nname = \"floor\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]";
    let mut dem = engine(&box_scene("[0, 0, 0]", contact, &walls));
    let r = 0.7e-3;
    let dt = dem.time_step();
    dem.insert(&[grain([0.0, 0.0, r + gap(dt)], [0.0, 0.0, -v])])
        .unwrap();
    let (mut n, mut touched) = (0u64, false);
    for _ in 0..200_000 {
        dem.advance(1).unwrap();
        let z = dem.particles().position[0][2];
        if z < r {
            touched = true;
            n += 1;
        } else if touched {
            break;
        }
    }
    (dem.particles().velocity[0][2] / v, n as f64 * dt, dt)
}

#[test]
fn hooke_restitution_and_contact_time_grain_grain_and_wall() {
    // Analytic: e exactly as set; duration π/ω_d = the scene's contact time (1e-4 s) for a
    // grain pair and √2 × that against a wall (m* = m instead of m/2).
    // Tolerance on e: 1 % (the issue's), at t_c/50. The discrete contact ends at a step
    // boundary, so e carries an error of first order in dt/t_c whose sign depends on where
    // within a step the contact ends (measured e, grain–grain / grain–wall, Hooke: t_c/20
    // 0.4950 / 0.5045, t_c/30 0.4978 / 0.5058, t_c/40 0.4988 / 0.5063, t_c/50 0.4992 /
    // 0.4967, t_c/100 0.4998 / 0.5020; Hertz within 0.4 % at t_c/30). At the default step
    // (t_c/30, since session 35) the wall's Hooke e is 1.2 % high: README, "Choosing
    // accuracy". Duration is counted in whole steps: ± 2 dt.
    let (e, tc, dt) = binary_collision(HOOKE, 0.5, 50.0);
    assert!((e - 0.5).abs() < 0.005, "grain-grain e = {e}");
    assert!((tc - 1e-4).abs() <= 2.0 * dt, "grain-grain t_c = {tc}");
    // Grain–grain at the default step, too (−0.44 % measured).
    let (e, _, _) = binary_collision(HOOKE, 0.5, 30.0);
    assert!((e - 0.5).abs() < 0.005, "grain-grain e at t_c/30 = {e}");
    let (e, tc, dt) = wall_collision(HOOKE, 0.5, 50.0);
    assert!((e - 0.5).abs() < 0.005, "grain-wall e = {e}");
    let expect = 1e-4 * 2f64.sqrt();
    assert!(
        (tc - expect).abs() <= 2.0 * dt,
        "grain-wall t_c = {tc} vs {expect}"
    );
}

#[test]
fn a_grain_from_many_skins_away_still_meets_the_wall() {
    // A wall is asked only about grains within one skin of it at the last neighbour build
    // (NeighborList::near_wall); a grain launched from 5 mm away (many skins, 25 000 steps)
    // must be picked up on the way by a rebuild and bounce with the set restitution and
    // contact time, within the near-start test's tolerances (1 %, ± 2 dt). The gap is
    // 5 mm plus 0.37 of a step's travel, to keep the touch off a step boundary.
    let (e, tc, dt) = wall_collision_from(HOOKE, 0.1, 50.0, |dt| 5e-3 + 0.1 * dt * 0.37);
    assert!((e - 0.5).abs() < 0.005, "grain-wall e = {e}");
    let expect = 1e-4 * 2f64.sqrt();
    assert!(
        (tc - expect).abs() <= 2.0 * dt,
        "grain-wall t_c = {tc} vs {expect}"
    );
}

#[test]
fn hertz_restitution_is_the_set_value_at_any_speed() {
    // Tsuji damping makes e independent of the impact speed; α is chosen so that the
    // continuous-time e is exactly the set one. 1 % as the issue asks, at t_c/50 and at the
    // default t_c/30 (time discretisation changes it by a fraction of that, see the Hooke
    // test).
    for steps in [50.0, 30.0] {
        for v in [0.1, 0.5, 1.0] {
            let (e, _, _) = binary_collision(HERTZ, v, steps);
            assert!(
                (e - 0.5).abs() < 0.005,
                "t_c/{steps} grain-grain v={v}: e = {e}"
            );
            let (e, _, _) = wall_collision(HERTZ, v, steps);
            assert!(
                (e - 0.5).abs() < 0.005,
                "t_c/{steps} grain-wall v={v}: e = {e}"
            );
        }
    }
}

#[test]
fn hertz_elastic_contact_time_matches_hertz_theory() {
    // Elastic Hertz collision: t_c = 2.868 (m*² / (r* Y*² v))^{1/5}. Counting whole steps
    // gives ± 1 step; the 2.868 constant is given to 4 digits (0.03 %).
    let elastic = HERTZ.replace("restitution = 0.5", "restitution = 1.0");
    let v = 0.5;
    let (e, tc, dt) = binary_collision(&elastic, v, 50.0);
    let m = 937.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.7e-3f64.powi(3);
    let (m_eff, r_eff) = (m / 2.0, 0.35e-3);
    let y_star = 1e7 / (2.0 * (1.0 - 0.09));
    // Impact speed is the relative speed 2v.
    let expect = 2.868 * (m_eff * m_eff / (r_eff * y_star * y_star * 2.0 * v)).powf(0.2);
    assert!(
        (tc - expect).abs() <= 2.0 * dt + 1e-3 * expect,
        "t_c = {tc} vs {expect}"
    );
    assert!((e - 1.0).abs() < 0.01, "elastic e = {e}");
}

#[test]
fn free_flight_conserves_energy_to_round_off() {
    // Velocity-Verlet integrates constant gravity exactly; only round-off remains.
    let mut dem = engine(&box_scene("[0, 0, -9.81]", HOOKE, ""));
    dem.insert(&[grain([0.0, 0.0, 0.0], [0.01, 0.0, 0.2])])
        .unwrap();
    let energy = |d: &plugflow::dem::NativeDem| {
        let p = d.particles();
        0.5 * p.mass[0] * (p.velocity[0].iter().map(|v| v * v).sum::<f64>())
            + p.mass[0] * 9.81 * p.position[0][2]
    };
    let e0 = energy(&dem);
    dem.advance(20_000).unwrap(); // 0.04 s: stays inside the box
    let e1 = energy(&dem);
    assert!(((e1 - e0) / e0).abs() < 1e-12, "drift {}", (e1 - e0) / e0);
}

/// Energy error of an elastic (e = 1) Hooke wall impact at dt = t_c / steps: the worst
/// over four phases of the first touch within a step, so the error does not depend on one
/// lucky alignment.
fn elastic_energy_error(steps: f64) -> f64 {
    let contact = HOOKE.replace("restitution = 0.5", "restitution = 1.0");
    let walls = format!(
        "[dem]\nrotation = false\ndt = \"{}\"\n[[walls]]\nname = \"floor\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]",
        1e-4 / steps
    );
    let mut worst: f64 = 0.0;
    for phase in [0.13, 0.37, 0.61, 0.89] {
        let v = 0.3;
        let r = 0.7e-3;
        let mut d = engine(&box_scene("[0, 0, 0]", &contact, &walls));
        let start_gap = v * d.time_step() * (5.0 + phase);
        d.insert(&[grain([0.0, 0.0, r + start_gap], [0.0, 0.0, -v])])
            .unwrap();
        let mut touched = false;
        for _ in 0..100_000 {
            d.advance(1).unwrap();
            let z = d.particles().position[0][2];
            if z < r {
                touched = true;
            } else if touched {
                break;
            }
        }
        let vout = d.particles().velocity[0][2];
        worst = worst.max(((vout / v).powi(2) - 1.0).abs());
    }
    worst
}

#[test]
fn elastic_impact_energy_error_converges_with_dt() {
    // The velocity-Verlet error of a collision that starts and ends between steps: the
    // force switches on with a kink at δ = 0, so the energy error is bounded by C (dt/t_c)^p.
    // Observed here: p ≈ 2 (the kink is in the force's derivative, not the force). We
    // require the bound at t_c/30 (the default) to be below 1 % and the observed order over
    // dt/t_c = 1/25 … 1/200 to be at least 1.5 — a first-order error would fail it.
    let errs: Vec<f64> = [25.0, 30.0, 50.0, 100.0, 200.0]
        .iter()
        .map(|&s| elastic_energy_error(s))
        .collect();
    let order = (errs[0] / errs[4]).log2() / 3.0;
    eprintln!("elastic energy errors {errs:?}, observed order {order:.2}");
    assert!(errs[1] < 0.01, "energy error at t_c/30 = {}", errs[1]);
    assert!(order > 1.5, "observed order {order:.2} from {errs:?}");
}

/// Overlap of a grain (d = 1.4 mm, 937 kg/m³) resting under 1 g on a wall with the HOOKE
/// contact (t_c = 1e-4 s, e = 0.5; the wall's m* is the grain's mass), m.
fn hooke_resting_overlap() -> f64 {
    let r: f64 = 0.7e-3;
    let m = 937.0 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let kn = m / 2.0 * (std::f64::consts::PI.powi(2) + 0.5f64.ln().powi(2)) / 1e-8;
    m * 9.81 / kn
}

#[test]
fn sliding_grain_decelerates_at_mu_g() {
    // A sliding block without rotation: dv/dt = −μ g exactly while it slides. The history
    // spring saturates at μ F_n within a few steps; 1 % covers that start-up.
    let walls = "[dem]\nrotation = false\n[[walls]]\nname = \"floor\"\npoint = [0, 0, -0.005]\nnormal = [0, 0, 1]";
    let mut dem = engine(&box_scene("[0, 0, -9.81]", HOOKE, walls));
    let (r, rest) = (0.7e-3, hooke_resting_overlap());
    dem.insert(&[grain([-0.008, 0.0, -0.005 + r - rest], [0.05, 0.0, 0.0])])
        .unwrap();
    let t = 0.005;
    let steps = (t / dem.time_step()).round() as u64;
    dem.advance(steps).unwrap();
    let v = dem.particles().velocity[0][0];
    let expect = 0.05 - 0.5 * 9.81 * t;
    assert!(
        (v - expect).abs() < 0.01 * 0.05,
        "v = {v}, expected {expect}"
    );
}

#[test]
fn sphere_rolls_down_incline_at_five_sevenths_g_sin_theta() {
    // Rolling without slip needs tan θ < 7/2 μ (here 0.36 < 1.75): a = 5/7 g sin θ. Tilt
    // gravity instead of the plane. The history spring oscillates at first and is damped
    // (e = 0.5); the mean acceleration over 0.1 s matches to 1 %.
    let theta: f64 = 20f64.to_radians();
    let g = format!("[{}, 0, {}]", 9.81 * theta.sin(), -9.81 * theta.cos());
    let walls = "[[walls]]\nname = \"incline\"\npoint = [0, 0, -0.009]\nnormal = [0, 0, 1]";
    let mut scene = box_scene(&g, HOOKE, walls);
    scene = scene
        .replace("min = [-0.01, -0.01, -0.01]", "min = [-0.5, -0.01, -0.01]")
        .replace("max = [0.01, 0.01, 0.01]", "max = [0.5, 0.01, 0.01]");
    let mut dem = engine(&scene);
    let r = 0.7e-3;
    dem.insert(&[grain([-0.45, 0.0, -0.009 + r - 1e-7], [0.0; 3])])
        .unwrap();
    let dt = dem.time_step();
    dem.advance((0.02 / dt) as u64).unwrap();
    let (t0, v0) = (dem.time(), dem.particles().velocity[0][0]);
    dem.advance((0.1 / dt) as u64).unwrap();
    let (t1, v1) = (dem.time(), dem.particles().velocity[0][0]);
    let a = (v1 - v0) / (t1 - t0);
    let expect = 5.0 / 7.0 * 9.81 * theta.sin();
    assert!(
        (a - expect).abs() < 0.01 * expect,
        "a = {a}, expected {expect}"
    );
    // And it rolls: ω r equals v (no slip) within 1 %.
    let w = dem.particles().angular_velocity[0][1];
    assert!(
        (w * r - v1).abs() < 0.01 * v1,
        "ω r = {} vs v = {v1}",
        w * r
    );
}

/// A grain pressed by gravity against the quasi-2D slab's back plane, sliding along the
/// tube axis at 0.05 m/s; returns its axial speed after 5 ms.
fn slab_slide(slab_friction: Option<f64>) -> f64 {
    // Tube along x: the slab's first cross direction is y (the grid's basis), planes at
    // y = ±0.8 mm; gravity along −y presses the grain on the back plane, nothing else
    // touches it (the cylinder is 20 mm across, the grain mid-tube).
    let friction = slab_friction.map_or(String::new(), |m| format!("slab_friction = {m}"));
    let text = format!(
        r#"
schema_version = 1
name = "test"
duration = "1 s"
gravity = [0, -9.81, 0]
[tube]
diameter = "20 mm"
length = "0.1 m"
axis = [1, 0, 0]
slab = "1.6 mm"
{friction}
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
{HOOKE}
[dem]
rotation = false
"#
    );
    let mut dem = engine(&text);
    let (r, rest) = (0.7e-3, hooke_resting_overlap());
    dem.insert(&[grain([0.05, -0.8e-3 + r - rest, 0.0], [0.05, 0.0, 0.0])])
        .unwrap();
    let steps = (0.005 / dem.time_step()).round() as u64;
    dem.advance(steps).unwrap();
    dem.particles().velocity[0][0]
}

#[test]
fn slab_planes_rub_only_with_their_own_friction() {
    // Default: the slab's planes stand in for the missing dimension of a 2D model and are
    // frictionless, so the grain keeps its speed (to round-off: nothing acts along x).
    let v = slab_slide(None);
    assert!((v - 0.05).abs() < 1e-12, "frictionless slab: v = {v}");
    // With `tube.slab_friction = 0.3` (not the contact's 0.5): dv/dt = −0.3 g, 1 % as in
    // `sliding_grain_decelerates_at_mu_g` (the history spring's start-up).
    let v = slab_slide(Some(0.3));
    let expect = 0.05 - 0.3 * 9.81 * 0.005;
    assert!(
        (v - expect).abs() < 0.01 * 0.05,
        "v = {v}, expected {expect}"
    );
}

/// A grain launched along a floor with the constant-torque rolling law of coefficient
/// `mu_r` against the floor: slides, then rolls; returns (speed once it rolls without slip,
/// distance it rolls from there until it stops), m/s and m.
fn rolling_stop(contact: &str, mu_r: f64) -> (f64, f64) {
    let walls = "[[walls]]\nname = \"floor\"\npoint = [0, 0, -0.009]\nnormal = [0, 0, 1]";
    let contact = format!(
        "{contact}\nrolling = \"constant_torque\"\nrolling_friction = 0.9\nwall_rolling_friction = {mu_r}"
    );
    let mut scene = box_scene("[0, 0, -9.81]", &contact, walls);
    scene = scene
        .replace("min = [-0.01, -0.01, -0.01]", "min = [-0.05, -0.01, -0.01]")
        .replace("max = [0.01, 0.01, 0.01]", "max = [0.05, 0.01, 0.01]");
    let mut dem = engine(&scene);
    let r = 0.7e-3;
    dem.insert(&[grain([-0.04, 0.0, -0.009 + r - 1e-7], [0.05, 0.0, 0.0])])
        .unwrap();
    let dt = dem.time_step();
    // Sliding ends within 2 v0/(7 μ g) = 3 ms (μ = 0.5); start the clock after 10 ms.
    dem.advance((0.01 / dt) as u64).unwrap();
    let p = dem.particles();
    let (x1, v1) = (p.position[0][0], p.velocity[0][0]);
    let w1 = p.angular_velocity[0][1];
    assert!(
        (w1 * r - v1).abs() < 1e-3 * v1,
        "rolls without slip before the measurement: ω r = {} vs v = {v1}",
        w1 * r
    );
    for _ in 0..2_000_000 {
        dem.advance(1).unwrap();
        if dem.particles().velocity[0][0] <= 0.0 {
            break;
        }
    }
    let p = dem.particles();
    assert!(p.velocity[0][0] <= 0.0, "still rolling");
    (v1, p.position[0][0] - x1)
}

#[test]
fn rolling_resistance_stops_a_rolling_sphere_where_the_torque_predicts() {
    // A sphere rolling without slip under a constant torque M = μ_r R m g against its
    // rotation decelerates at a = M / (R (m + I/R²)) = 5/7 μ_r g, so it stops after
    // s = v² / (2 a) = 7 v² / (10 μ_r g). The elastic normal force is m g once the resting
    // overlap's oscillation has died out (e = 0.5: within a few contact times, long before
    // the measurement starts); the step integrates a constant deceleration exactly but for
    // the last step, whose overshoot is below a dt² (~1e-11 m, 1e-8 of s). Measured: 3e-11
    // relative; the tolerance, 1e-6, is the last step with a hundredfold margin.
    for mu_r in [0.05, 0.2] {
        let (v1, s) = rolling_stop(HOOKE, mu_r);
        let expect = 7.0 * v1 * v1 / (10.0 * mu_r * 9.81);
        assert!(
            (s - expect).abs() < 1e-6 * expect,
            "μ_r = {mu_r}: rolled {s} m, expected {expect} m (from v = {v1} m/s)"
        );
    }
}

/// Slope of the heap a square column of 396 grains (6 × 6 × 11 on a 1.45 mm lattice,
/// jittered) leaves when it collapses on a rough floor, with grain–grain and grain–wall
/// rolling friction `mu_r`: atan(H / R), H the heap's height (the fifth-highest grain top)
/// and R the median distance from the axis of the grains on the floor, degrees.
fn heap_slope(mu_r: f64) -> f64 {
    let contact = format!(
        "normal = \"hooke\"\ntangential = \"history\"\ncontact_time = \"4e-4 s\"\nfriction = 0.5\nrestitution = 0.5\nrolling = \"constant_torque\"\nrolling_friction = {mu_r}"
    );
    let walls = "[[walls]]\nname = \"floor\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]";
    let scene = box_scene("[0, 0, -9.81]", &contact, walls)
        .replace(
            "min = [-0.01, -0.01, -0.01]",
            "min = [-0.06, -0.06, -0.001]",
        )
        .replace("max = [0.01, 0.01, 0.01]", "max = [0.06, 0.06, 0.03]");
    let mut dem = engine(&scene);
    let (r, a) = (0.7e-3, 1.45e-3);
    let mut grains = vec![];
    for k in 0..11 {
        for j in 0..6 {
            for i in 0..6 {
                // A fixed jitter (no random source): ±0.02 mm, different per grain.
                let h = ((i * 7 + j * 13 + k * 29) % 11) as f64 / 10.0 - 0.5;
                grains.push(grain(
                    [
                        (i as f64 - 2.5) * a + 4e-5 * h,
                        (j as f64 - 2.5) * a - 4e-5 * h,
                        r + 2e-5 + k as f64 * a,
                    ],
                    [0.0; 3],
                ));
            }
        }
    }
    dem.insert(&grains).unwrap();
    dem.advance((0.6 / dem.time_step()) as u64).unwrap();
    let p = dem.particles();
    let mut tops: Vec<f64> = p.position.iter().map(|x| x[2] + r).collect();
    tops.sort_by(f64::total_cmp);
    let height = tops[tops.len() - 5];
    let mut spread: Vec<f64> = p
        .position
        .iter()
        .filter(|x| x[2] < 1.5 * r)
        .map(|x| x[0].hypot(x[1]))
        .collect();
    spread.sort_by(f64::total_cmp);
    let reach = spread[spread.len() / 2];
    (height / reach).atan().to_degrees()
}

#[test]
fn the_heap_steepens_with_rolling_friction() {
    // Without rolling friction spheres roll off a heap (the slope is the few grains left
    // near the axis); the constant torque holds them. Measured with three jitter patterns:
    // μ_r = 0: 2.4–2.8°, 0.1: 12.8–13.4°, 0.4: 24.0–25.4° (largest spread 1.4°); each
    // step must rise by 6°, four times that spread.
    let slopes: Vec<f64> = [0.0, 0.1, 0.4].iter().map(|&m| heap_slope(m)).collect();
    assert!(
        slopes[1] > slopes[0] + 6.0 && slopes[2] > slopes[1] + 6.0,
        "heap slopes (degrees) at μ_r = 0, 0.1, 0.4: {slopes:?}"
    );
}
