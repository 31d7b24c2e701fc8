//! A bed settled in the 7 mm tube: porosity, Janssen wall-stress saturation, and bitwise
//! determinism of two runs at the same thread count.

mod common;
use common::*;
use plugflow_coupling::DemBackend;

fn bed_scene(threads: usize) -> String {
    format!(
        r#"
schema_version = 1
name = "bed"
duration = "1 s"
seed = 3
gravity = [0, 0, -9.81]
[tube]
diameter = "7 mm"
length = "0.3 m"
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
contact_time = "1e-4 s"
friction = 0.5
restitution = 0.5
[dem]
threads = {threads}
[initial]
count = 800
from = "0 m"
to = "0.13 m"
"#
    )
}

/// Volume of a sphere of radius r, centre at height c, inside the slab [a, b].
fn sphere_slab_volume(c: f64, r: f64, a: f64, b: f64) -> f64 {
    let lo = (a - c).max(-r);
    let hi = (b - c).min(r);
    if hi <= lo {
        return 0.0;
    }
    let f = |z: f64| std::f64::consts::PI * (r * r * z - z * z * z / 3.0);
    f(hi) - f(lo)
}

#[test]
fn settled_bed_porosity_and_janssen_saturation() {
    let mut dem = engine(&bed_scene(1));
    let dt = dem.time_step();
    dem.advance((0.6 / dt) as u64).unwrap();
    let p = dem.particles();
    let r = 0.7e-3;
    let big_r = 3.5e-3;
    let ke: f64 = (0..p.len())
        .map(|i| 0.5 * p.mass[i] * p.velocity[i].iter().map(|v| v * v).sum::<f64>())
        .sum();
    let pe_scale = p.mass[0] * 9.81 * r * p.len() as f64;
    assert!(ke < 1e-3 * pe_scale, "bed still moving: KE {ke} J");
    let top = p.position.iter().map(|x| x[2]).fold(0.0, f64::max);
    // Porosity of the middle of the bed (away from the floor and the loose top layer), by
    // exact sphere–slab volumes.
    let (a, b) = (0.2 * top, 0.7 * top);
    let solid: f64 = p
        .position
        .iter()
        .map(|x| sphere_slab_volume(x[2], r, a, b))
        .sum();
    let porosity = 1.0 - solid / (std::f64::consts::PI * big_r * big_r * (b - a));
    // Sensible: random packings of frictional spheres lie at 0.36–0.45 in bulk; a tube only
    // five grains wide loosens the packing near its wall (seed 000 fig. 18 and its min plug
    // porosity 0.47), so we accept 0.38–0.55.
    eprintln!("bed height {top:.4} m, porosity {porosity:.3}");
    assert!((0.38..0.55).contains(&porosity), "porosity {porosity}");

    // Wall normal stress per slice from the wall overlaps (elastic Hooke force k δ; the bed
    // is at rest so the dashpot adds nothing).
    let m = p.mass[0];
    let kn = m / 2.0 * (std::f64::consts::PI.powi(2) + 0.5f64.ln().powi(2)) / 1e-8;
    let slice = 2.0 * big_r; // one tube diameter
    let nslices = (top / slice).floor() as usize;
    let mut stress = vec![0.0; nslices];
    for x in p.position {
        let rho = (x[0] * x[0] + x[1] * x[1]).sqrt();
        let overlap = r + rho - big_r;
        let k = (x[2] / slice) as usize;
        if overlap > 0.0 && k < nslices {
            stress[k] += kn * overlap / (2.0 * std::f64::consts::PI * big_r * slice);
        }
    }
    // Depth is measured from the top: slice nslices-1 is the shallowest.
    eprintln!("wall stress by depth (Pa), deep → shallow: {stress:?}");
    // Janssen: σ_w(depth) = ρ_b g D/(4 μ_w) (1 − exp(−4 μ_w K depth/D)), which saturates
    // within a few D. Hydrostatic growth would double the stress from depth 3D to 6D; we
    // require the deep slices to differ by less than 35 % (random packings fluctuate
    // slice to slice by 20–30 % in a tube only five grains wide).
    let deep = stress[0..3].iter().sum::<f64>() / 3.0; // 6–9 D deep for a ~10 D bed
    let mid = stress[nslices - 6..nslices - 3].iter().sum::<f64>() / 3.0; // 3–6 D deep
    assert!(
        (deep / mid - 1.0).abs() < 0.35,
        "no saturation: deep {deep} Pa vs mid {mid} Pa"
    );
    // With fully mobilised wall friction Janssen's saturated stress is ρ_b g D / (4 μ_w);
    // partly mobilised friction (a settled bed) gives more, never less: we require at least
    // 80 % of it (the porosity estimate enters ρ_b).
    let rho_b = (1.0 - porosity) * 937.0;
    let janssen = rho_b * 9.81 * 2.0 * big_r / (4.0 * 0.5);
    assert!(
        deep > 0.8 * janssen,
        "deep stress {deep} Pa below Janssen {janssen} Pa"
    );
    // Measured here: the saturated wall stress is ~10× Janssen's fully mobilised value
    // (≈ 170 Pa vs 17 Pa). The grains rain in at up to 1 m/s onto soft contacts and wedge
    // between the walls (D/d = 5), locking in lateral stress that friction, mobilised only
    // in part, holds; the saturation with depth is the Janssen signature tested above.
}

fn run_positions(threads: usize, steps: u64) -> Vec<[f64; 3]> {
    let mut dem = engine(&bed_scene(threads));
    dem.advance(steps).unwrap();
    let p = dem.particles();
    // Report in id order so the comparison does not depend on the internal sort.
    let mut v: Vec<(u64, [f64; 3])> =
        p.id.iter()
            .copied()
            .zip(p.position.iter().copied())
            .collect();
    v.sort_by_key(|e| e.0);
    v.into_iter().map(|e| e.1).collect()
}

#[test]
fn same_scene_same_threads_gives_bitwise_same_result() {
    // 20 000 steps = 0.04 s: the grains are falling and colliding, the hard case.
    for threads in [1, 2] {
        let a = run_positions(threads, 20_000);
        let b = run_positions(threads, 20_000);
        assert!(a == b, "threads = {threads}: runs differ");
    }
    // Different thread counts sum forces in a different order: equal physics, not bits.
    let one = run_positions(1, 2_000);
    let two = run_positions(2, 2_000);
    let max_diff = one
        .iter()
        .zip(&two)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(
        max_diff < 1e-9,
        "1 vs 2 threads differ by {max_diff} m after 2000 steps"
    );
}
