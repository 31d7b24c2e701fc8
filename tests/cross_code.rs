//! The same scenes on the built-in DEM, on LIGGGHTS and on YADE (Debian's packages, each
//! behind the DEM ABI: `libplugflow_dem_liggghts.so`, `libplugflow_dem_yade.so`). The
//! README's test command installs both engines and builds both shims.
//!
//! Every engine gets the same contact constants (the shims map the built-in laws, see
//! bindings/liggghts/src/input.rs and bindings/yade/src/input.rs) and the same initial
//! grains (placed by plugflow). Each test prints one table with all three engines; a failing
//! comparison names the engine and both numbers.

mod common;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;
use plugflow::setup::coupling_from_scene;
use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::{DemBackend, NewParticle};

/// One external engine at a time per test (LIGGGHTS shares MPI's process state, YADE is a
/// singleton per process), and the tests are long enough that running them side by side
/// would only make each slower.
static SERIAL: Mutex<()> = Mutex::new(());

/// The external engines, in table order.
const EXTERNAL: [&str; 2] = ["liggghts", "yade"];

fn shim(engine: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let lib = exe
        .parent()
        .unwrap()
        .parent()
        .unwrap()
        .join(format!("libplugflow_dem_{engine}.so"));
    assert!(
        lib.exists(),
        "{} is not built: run the README's test command (bash scripts/test-all.sh), or \
         cargo build --release -p plugflow-dem-{engine} --features {engine}",
        lib.display()
    );
    lib
}

fn load(engine: &str, s: &Scene) -> AbiBackend {
    let e = AbiBackend::load(&shim(engine), &s.to_json()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(e.engine_name(), engine);
    let version = e.engine_version();
    match engine {
        "liggghts" => assert!(version.starts_with("LIGGGHTS-PUBLIC 3."), "{version}"),
        _ => assert!(version.starts_with("YADE 20"), "{version}"),
    }
    e
}

fn scene(text: &str) -> Scene {
    Scene::parse(text, &[]).unwrap_or_else(|e| panic!("test scene: {e}"))
}

/// A table row: quantity, then one value per engine (native first).
fn row(quantity: &str, values: &[f64]) {
    let cells: Vec<String> = values.iter().map(|v| format!("{v:>12.5}")).collect();
    println!("| {quantity:<34} | {} |", cells.join(" | "));
}

fn header() {
    println!(
        "| {:<34} | {:>12} | {:>12} | {:>12} |",
        "quantity", "native", "liggghts", "yade"
    );
}

const TUBE: &str = r#"
schema_version = 1
name = "cross"
duration = "1 s"
seed = 3
gravity = [0, 0, -9.81]
[tube]
diameter = "7 mm"
length = "LENGTH"
inlet_end = "closed"
outlet_end = "OUTLET"
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
normal = "hooke"
tangential = "TANGENTIAL"
contact_time = "CONTACT"
friction = 0.5
restitution = 0.5
[dem]
threads = 1
# The step these comparisons' bands were measured at (t_c/50, the default until session 35).
# At t_c/30 one grain of YADE's bed of (b) still moved at 0.25-0.37 m/s on top of the bed
# from 0.25 s to the end of the 0.35 s settle (its 799 others at rest; a grain rolling there
# would keep its speed: this scene has no rolling resistance), failing the settle check.
dt_fraction = 50
"#;

fn tube(length: &str, outlet: &str, tangential: &str, contact: &str, extra: &str) -> String {
    TUBE.replace("LENGTH", length)
        .replace("OUTLET", outlet)
        .replace("TANGENTIAL", tangential)
        .replace("CONTACT", contact)
        + extra
}

/// (a) One grain dropped ~5 mm onto the closed end, Hooke and Hertz.
///
/// Free fall: the built-in engine and LIGGGHTS both integrate with velocity Verlet, so
/// their heights agree to rounding (1e-9 relative, ~1e6 ulps for ~8000 steps of
/// differently ordered arithmetic). YADE's NewtonIntegrator is a leapfrog that takes the
/// initial velocity as the one at t − dt/2: its height runs ahead of Verlet's by exactly
/// g·dt·t/2, so YADE is held to that offset within 1e-9 relative.
///
/// Restitution, from the velocities just before and just after the contact: within 2 %
/// of the built-in engine's (all apply the same spring–dashpot or Hertz–Tsuji law; the
/// difference is where within a step each engine resolves the contact's start and end).
#[test]
fn a_single_grain_bounce() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let drop = "[initial]\ncount = 1\nfrom = \"4 mm\"\nto = \"6 mm\"\n";
    header();
    bounce(
        &tube("0.05 m", "closed", "history", "1e-4 s", drop),
        "hooke",
    );
    // Hertz: LIGGGHTS's `model hertz` and YADE's Mindlin law, given the restitution whose
    // β reproduces the built-in engine's Tsuji damping exactly.
    let hertz = tube("0.05 m", "closed", "history", "1e-4 s", drop).replace(
        "normal = \"hooke\"\ntangential = \"history\"\ncontact_time = \"1e-4 s\"",
        "normal = \"hertz\"\ntangential = \"history\"\nyoungs_modulus = \"5e6 Pa\"\npoisson_ratio = 0.45",
    );
    assert!(hertz.contains("hertz"));
    bounce(&hertz, "hertz");
}

fn bounce(text: &str, law: &str) {
    let s = scene(text);
    let mut n = NativeDem::new(plugflow::setup::dem_config(&s).unwrap()).unwrap();
    let r = 0.7e-3;
    let chunk = 5;
    let dt = n.time_step();
    let total = (0.06 / dt) as u64;
    let trace = |e: &mut dyn DemBackend| {
        let (mut z, mut v) = (vec![], vec![]);
        for _ in 0..total / chunk {
            e.advance(chunk).unwrap();
            z.push(e.particles().position[0][2]);
            v.push(e.particles().velocity[0][2]);
        }
        (z, v)
    };
    let (zn, vn) = trace(&mut n);
    let free = zn
        .iter()
        .position(|z| *z < r)
        .expect("the grain reaches the cap");
    assert!(free > 100);
    let restitution = |z: &[f64], v: &[f64]| {
        let start = z.iter().position(|z| *z < r).unwrap();
        let end = start + z[start..].iter().position(|z| *z >= r).unwrap();
        // Velocities one chunk outside the contact (gravity changes them by g·5 dt).
        -v[end] / v[start - 1]
    };
    let en = restitution(&zn, &vn);
    assert!((en - 0.5).abs() < 0.05, "{law}: native restitution {en}");
    let mut values = vec![en];
    for engine in EXTERNAL {
        let mut e = load(engine, &s);
        assert_eq!(e.time_step(), dt);
        let (ze, ve) = trace(&mut e);
        for k in 0..free {
            let t = ((k + 1) as u64 * chunk) as f64 * dt;
            let offset = if engine == "yade" {
                -0.5 * 9.81 * dt * t
            } else {
                0.0
            };
            let rel = (ze[k] - zn[k] - offset).abs() / zn[k].abs();
            assert!(
                rel < 1e-9,
                "{law}: sample {k}: native z {} vs {engine} z {} (expected offset {offset:e}, \
                 rel {rel:e})",
                zn[k],
                ze[k]
            );
        }
        let ee = restitution(&ze, &ve);
        assert!(
            (en - ee).abs() / en < 0.02,
            "{law}: restitution native {en}, {engine} {ee}"
        );
        values.push(ee);
    }
    row(&format!("{law}: restitution"), &values);
}

/// Porosity of a bed in a tube of radius `rt` between `lo` and `hi` along z (grain
/// volume inside the slab, exact sphere–slab caps).
fn porosity(x: &[[f64; 3]], r: f64, rt: f64, lo: f64, hi: f64) -> f64 {
    let solid: f64 = x
        .iter()
        .map(|p| plugflow::analysis::plugs::sphere_slab_volume(p[2], r, lo, hi))
        .sum();
    1.0 - solid / (std::f64::consts::PI * rt * rt * (hi - lo))
}

/// Overlaps of a grain of radius `r` at `p` with the tube wall, as each engine builds
/// the tube: a true cylinder (built-in, LIGGGHTS), or YADE's regular polygon of 96 faces
/// with vertices at angles 2πk/96 on the radius 2R/(1 + cos π/96)
/// (bindings/yade/src/input.rs), where a grain near a vertex presses on both faces.
fn wall_overlaps(engine: &str, p: &[f64; 3], r: f64, rt: f64) -> Vec<f64> {
    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
    if engine != "yade" {
        return vec![rho + r - rt];
    }
    let half = std::f64::consts::PI / 96.0;
    let apothem = 2.0 * rt / (1.0 + half.cos()) * half.cos();
    let theta = p[1].atan2(p[0]).rem_euclid(2.0 * std::f64::consts::PI);
    let face = (theta / (2.0 * half)).floor();
    [face - 1.0, face, face + 1.0]
        .iter()
        .map(|k| rho * (theta - (2.0 * k + 1.0) * half).cos() + r - apothem)
        .collect()
}

/// Wall normal stress profile from the grains' elastic overlap with the tube (a settled
/// bed moves too slowly for the dashpot to matter): σ_k = Σ k_n δ_i / (2π R Δz) per slice.
fn wall_stress(
    engine: &str,
    x: &[[f64; 3]],
    r: f64,
    rt: f64,
    kn: f64,
    dz: f64,
    slices: usize,
) -> Vec<f64> {
    let mut s = vec![0.0; slices];
    for p in x {
        let k = (p[2] / dz) as usize;
        for overlap in wall_overlaps(engine, p, r, rt) {
            if overlap > 0.0 && k < slices {
                s[k] += kn * overlap / (2.0 * std::f64::consts::PI * rt * dz);
            }
        }
    }
    s
}

/// (b) 800 grains poured into the tube (the same random places in all engines) and
/// settled. Porosity of the bed's middle within 2 % and the wall normal stress, averaged
/// over 2 cm slices of the lower bed, within 10 %: the engines build different random
/// packings from the same start, so the comparison is statistical; the bands are those of
/// the LIGGGHTS issue, wider than the slice-to-slice scatter of one engine (~5 %).
///
/// The cap carries what wall friction does not (Janssen). How much friction is mobilised
/// depends on the packing history: the built-in engine alone over seeds 1–6 of this scene
/// gives 0.0052–0.0069 N (s.d. 11 %), so two independent beds differ by up to
/// 2σ·√2 ≈ 30 % with no error in either engine. Beyond that, wall forces differ.
#[test]
fn b_settled_bed() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let s = scene(&tube(
        "0.2 m",
        "closed",
        "history",
        "2e-4 s",
        "[initial]\ncount = 800\nfrom = \"0 m\"\nto = \"0.19 m\"\n",
    ));
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let kn = match &cfg.laws {
        plugflow::dem::config::LawSet::Hooke(t) => t.normal().1.kn,
        _ => unreachable!(),
    };
    let (r, rt) = (0.7e-3, 3.5e-3);
    let settle = |e: &mut dyn DemBackend, name: &str| {
        e.advance((0.35 / e.time_step()) as u64).unwrap();
        let x = e.particles().position.to_vec();
        let vmax = e
            .particles()
            .velocity
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(0.0, f64::max);
        assert!(
            vmax < 0.05,
            "{name}: bed not settled (fastest grain {vmax} m/s)"
        );
        let cap = e
            .wall_forces()
            .iter()
            .find(|w| w.wall == "inlet_cap")
            .map(|w| w.force[2])
            .unwrap();
        (x, cap)
    };
    let mut n = NativeDem::new(cfg.clone()).unwrap();
    let mut beds = vec![("native", settle(&mut n, "native"))];
    for engine in EXTERNAL {
        let mut e = load(engine, &s);
        beds.push((engine, settle(&mut e, engine)));
    }
    let top = |x: &[[f64; 3]]| x.iter().map(|p| p[2]).fold(0.0, f64::max);
    let h = beds
        .iter()
        .map(|b| top(&b.1 .0))
        .fold(f64::INFINITY, f64::min);
    assert!(h > 0.05, "bed height {h}");
    let dz = 0.02;
    let slices = ((0.8 * h) / dz) as usize;
    let measured: Vec<(f64, f64, f64)> = beds
        .iter()
        .map(|(name, (x, cap))| {
            let stress = wall_stress(name, x, r, rt, kn, dz, slices);
            println!("{name}: wall stress (Pa) per 2 cm {stress:.1?}");
            (
                porosity(x, r, rt, 0.2 * h, 0.8 * h),
                stress.iter().sum::<f64>() / slices as f64,
                *cap,
            )
        })
        .collect();
    header();
    row(
        "bed porosity",
        &measured.iter().map(|m| m.0).collect::<Vec<_>>(),
    );
    row(
        "mean wall stress, Pa",
        &measured.iter().map(|m| m.1).collect::<Vec<_>>(),
    );
    row(
        "force on the closed end, N",
        &measured.iter().map(|m| m.2).collect::<Vec<_>>(),
    );
    let (pn, sn, cn) = measured[0];
    assert!(cn < 0.0, "native cap force {cn}");
    for (k, engine) in EXTERNAL.iter().enumerate() {
        let (pe, se, ce) = measured[k + 1];
        assert!(
            (pn - pe).abs() / pn < 0.02,
            "porosity native {pn} vs {engine} {pe}"
        );
        assert!(
            (sn - se).abs() / sn < 0.10,
            "mean wall stress native {sn} vs {engine} {se}"
        );
        assert!(
            (cn - ce).abs() / cn.abs() < 0.30,
            "cap force native {cn} vs {engine} {ce}"
        );
    }
}

/// (c) A frozen bed with gas: the native engine's settled bed inserted into each external
/// engine, then the gas solved to steady state over each engine's grains without moving
/// them. The deposit sees the same grains, so Δp agrees to rounding; 1 % (the issue's band)
/// would catch a single grain missing or misplaced (each grain is ~0.3 % of the bed).
#[test]
fn c_frozen_bed_with_gas() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let gas = "[gas]\nmodel = \"darcy\"\nviscosity = \"0.0673 cP\"\npressure = \"1013.25 hPa\"\nsuperficial_velocity = \"0.5 m/s\"\ngrid = [40, 2, 2]\n";
    let bed = scene(&tube(
        "0.14 m",
        "closed",
        "history",
        "2e-4 s",
        &format!("[initial]\ncount = 400\nfrom = \"0 m\"\nto = \"0.13 m\"\n{gas}"),
    ));
    let mut n = NativeDem::new(plugflow::setup::dem_config(&bed).unwrap()).unwrap();
    n.advance((0.3 / n.time_step()) as u64).unwrap();
    let empty = scene(&tube("0.14 m", "closed", "history", "2e-4 s", gas));
    let p = n.particles();
    let grains: Vec<NewParticle> = (0..p.len())
        .map(|i| NewParticle {
            position: p.position[i],
            velocity: [0.0; 3],
            radius: p.radius[i],
            density: 937.0,
        })
        .collect();
    let cfg = plugflow::setup::dem_config(&bed).unwrap();
    // 0.2 s of gas (≫ the diffusion time of the bed) without advancing the grains.
    let solve = |e: &mut dyn DemBackend| {
        let mut g = coupling_from_scene(&bed, &cfg).unwrap().unwrap();
        for _ in 0..2000 {
            g.exchange(e).unwrap();
        }
        g.pressure_drop()
    };
    let dn = solve(&mut n);
    let mut values = vec![dn];
    for engine in EXTERNAL {
        let mut e = load(engine, &empty);
        let ids = e.insert(&grains).unwrap();
        assert_eq!(ids.len(), grains.len());
        assert_eq!(e.particles().len(), grains.len());
        let de = solve(&mut e);
        assert!(
            dn > 0.0 && (dn - de).abs() / dn < 0.01,
            "Δp native {dn} vs {engine} {de}"
        );
        values.push(de);
    }
    header();
    row("frozen bed Δp, Pa/m", &values);
}

/// (d) The vertical plug case for 1 s on every engine (each with its own inlet at the same
/// mass flow: random insertion in the lowest 2 cm). After 1 s the tube holds the first
/// ~500 grains resting on the closed end under gas drag. Grains in the tube within 2 %
/// (below); Δp averaged over the last 0.2 s within 30 %: the built-in engine's own
/// seed-to-seed scatter of this number, seeds 1–8 of this run (native, one thread, history
/// law; measured 2026-12-03): mean 388 Pa/m, s.d. 10.5 % (346–447 Pa/m). Two independent
/// runs differ by up to 2σ√2 ≈ 30 % with no error in either engine. (The band was 15 %, set
/// from the feed, not from this scatter: seed 1 at 359 Pa/m, low in its own spread, then
/// fell outside it against YADE's 445 after a change of summation order alone.) The case's
/// regularised Coulomb law has no YADE counterpart (its viscous shear is never capped by
/// μ|F_n|), so all three run it with the history law here.
#[test]
fn d_vertical_plug_first_second() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(
        &root.join("cases/vertical_plug.toml"),
        &[
            "dem.threads=1".to_string(),
            "contact.tangential=history".to_string(),
            // The scatter below was measured at the porosity clamp 0.99 and the step t_c/50,
            // the case's values then (0.95 since session 34, t_c/30 since session 35); the
            // engines share the gas and the step either way.
            "gas.porosity_max=0.99".to_string(),
            "dem.dt_fraction=50".to_string(),
        ],
    )
    .unwrap();
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let run = |e: &mut dyn DemBackend| {
        let mut g = coupling_from_scene(&s, &cfg).unwrap().unwrap();
        let exchanges = (1.0 / g.interval).round() as usize;
        let (mut dp, mut k) = (0.0, 0);
        let t0 = std::time::Instant::now();
        for x in 0..exchanges {
            e.advance(g.substeps).unwrap();
            e.remove_past_outlet().unwrap();
            g.exchange(e).unwrap();
            if x >= exchanges * 4 / 5 {
                dp += g.pressure_drop();
                k += 1;
            }
        }
        (
            e.particles().len() as f64,
            dp / k as f64,
            t0.elapsed().as_secs_f64(),
        )
    };
    let mut n = NativeDem::new(cfg.clone()).unwrap();
    let mut results = vec![run(&mut n)];
    for engine in EXTERNAL {
        let mut e = load(engine, &s);
        results.push(run(&mut e));
    }
    header();
    row(
        "grains in the tube after 1 s",
        &results.iter().map(|r| r.0).collect::<Vec<_>>(),
    );
    row(
        "Δp over the last 0.2 s, Pa/m",
        &results.iter().map(|r| r.1).collect::<Vec<_>>(),
    );
    row(
        "wall time, s",
        &results.iter().map(|r| r.2).collect::<Vec<_>>(),
    );
    let (nn, dn, _) = results[0];
    assert!(dn > 0.0, "native Δp {dn}");
    for (k, engine) in EXTERNAL.iter().enumerate() {
        let (ne, de, _) = results[k + 1];
        // No grain leaves in the first second: the grains in the tube are the grains fed,
        // and every engine must feed what the scene asks. 2 %: LIGGGHTS inserts a batch
        // every 5 ms (2.6 grains at 514/s) and drops what its placement misses in the
        // filling slab (510 of 513 here); it fed 7 % (vertical) and 32 % (horizontal) less
        // while its region was one radius too narrow and it tried 50 times per grain, which
        // the old 15 % let through.
        assert!(
            (nn - ne).abs() / nn < 0.02,
            "grains fed: native {nn} vs {engine} {ne}"
        );
        assert!(
            (dn - de).abs() / dn < 0.30,
            "Δp native {dn} vs {engine} {de}"
        );
    }
}

/// (e) The horizontal slug case for 1 s on every engine (history law, as in (d)): grains
/// fed at the closed end of the horizontal tube, gravity across it, the gas pushing along.
/// Tolerances from the built-in engine's own seed-to-seed scatter over seeds 1–8 of this
/// run (`plugflow sweep cases/horizontal_slug.toml --vary seed=1,…,8 --duration 1 --set
/// contact.tangential=history`, measured on this machine): grains fed 513 in every seed;
/// the grains' mean position along the axis over the last 0.2 s 2.66 cm, s.d. 3.2 %; Δp
/// over the last 0.2 s 0.82 hPa/m, s.d. 13 %. Measured again 2026-12-03 after the cells
/// were numbered along the pipe (the same physics in another summation order): position
/// 2.71 cm, s.d. 4.2 % (2.59–2.90 cm); Δp 0.78 hPa/m, s.d. 10 %. Two independent runs
/// differ by up to 2σ√2 with no error in either engine; with the larger σ of each: 12 %
/// and 37 %, the bands; grains fed as in (d), 2 %.
#[test]
fn e_horizontal_slug_first_second() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(
        &root.join("cases/horizontal_slug.toml"),
        &[
            "dem.threads=1".to_string(),
            "contact.tangential=history".to_string(),
            // The bands below were measured with the slab inlet, the porosity clamp 0.99
            // and the step t_c/50, which the case had then.
            "inlet.mode=slab".to_string(),
            "gas.porosity_max=0.99".to_string(),
            "dem.dt_fraction=50".to_string(),
        ],
    )
    .unwrap();
    let cfg = plugflow::setup::dem_config(&s).unwrap();
    let tube = cfg.tube.unwrap();
    let run = |e: &mut dyn DemBackend| {
        let mut g = coupling_from_scene(&s, &cfg).unwrap().unwrap();
        let exchanges = (1.0 / g.interval).round() as usize;
        let (mut dp, mut along, mut k) = (0.0, 0.0, 0);
        for x in 0..exchanges {
            e.advance(g.substeps).unwrap();
            e.remove_past_outlet().unwrap();
            g.exchange(e).unwrap();
            if x >= exchanges * 4 / 5 {
                dp += g.pressure_drop();
                let p = e.particles();
                let s: f64 = p
                    .position
                    .iter()
                    .map(|q| {
                        (0..3)
                            .map(|c| (q[c] - tube.origin[c]) * tube.axis[c])
                            .sum::<f64>()
                    })
                    .sum();
                along += s / p.len().max(1) as f64;
                k += 1;
            }
        }
        (e.particles().len() as f64, dp / k as f64, along / k as f64)
    };
    let mut n = NativeDem::new(cfg.clone()).unwrap();
    let mut results = vec![run(&mut n)];
    for engine in EXTERNAL {
        let mut e = load(engine, &s);
        results.push(run(&mut e));
    }
    header();
    row(
        "grains in the tube after 1 s",
        &results.iter().map(|r| r.0).collect::<Vec<_>>(),
    );
    row(
        "Δp over the last 0.2 s, Pa/m",
        &results.iter().map(|r| r.1).collect::<Vec<_>>(),
    );
    row(
        "mean position along the axis, m",
        &results.iter().map(|r| r.2).collect::<Vec<_>>(),
    );
    let (nn, dn, an) = results[0];
    assert!(dn > 0.0 && an > 0.0, "native Δp {dn}, position {an}");
    for (k, engine) in EXTERNAL.iter().enumerate() {
        let (ne, de, ae) = results[k + 1];
        assert!(
            (nn - ne).abs() / nn < 0.02,
            "grains fed: native {nn} vs {engine} {ne}"
        );
        assert!(
            (an - ae).abs() / an < 0.12,
            "mean position along the axis: native {an} vs {engine} {ae} m"
        );
        assert!(
            (dn - de).abs() / dn < 0.37,
            "Δp native {dn} vs {engine} {de}"
        );
    }
}

/// (f) Rolling resistance (constant directional torque, LIGGGHTS's `rolling_friction cdt`):
/// a grain launched along a floor slides, then rolls, then stops; after 10 ms it rolls
/// without slip and stops 7 v²/(10 μ_r g) further on. LIGGGHTS is held to that distance
/// from its own speed within 5e-5 (measured 6e-6; the built-in engine meets it to 3e-11, see
/// tests/dem_analytic.rs; a torque off by 1e-4 or a lever arm of R*/2 would be outside). The speeds once rolling agree within 1e-4:
/// the engines differ by 1e-5 even with μ_r = 0 (measured), in how the history spring
/// settles as sliding ends. YADE refuses the law (not mapped, see its shim; the bad-input
/// corpus checks the refusal).
#[test]
fn f_rolling_resistance_stops_a_grain_alike() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let text = r#"
schema_version = 1
name = "cross"
duration = "1 s"
gravity = [0, 0, -9.81]
[domain]
min = [-0.05, -0.01, -0.001]
max = [0.05, 0.01, 0.01]
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
contact_time = "1e-4 s"
friction = 0.5
restitution = 0.5
rolling = "constant_torque"
rolling_friction = 0.3
wall_rolling_friction = 0.1
[[walls]]
name = "floor"
point = [0, 0, 0]
normal = [0, 0, 1]
[dem]
threads = 1
"#;
    let s = scene(text);
    let r = 0.7e-3;
    let roll = |e: &mut dyn DemBackend| -> (f64, f64) {
        e.insert(&[NewParticle {
            position: [-0.04, 0.0, r - 1e-7],
            velocity: [0.05, 0.0, 0.0],
            radius: r,
            density: 937.0,
        }])
        .unwrap();
        let dt = e.time_step();
        e.advance((0.01 / dt) as u64).unwrap();
        let (x1, v1) = (e.particles().position[0][0], e.particles().velocity[0][0]);
        for _ in 0..200_000 {
            e.advance(1).unwrap();
            if e.particles().velocity[0][0] <= 0.0 {
                break;
            }
        }
        assert!(e.particles().velocity[0][0] <= 0.0, "still rolling");
        (v1, e.particles().position[0][0] - x1)
    };
    let mut native = NativeDem::new(plugflow::setup::dem_config(&s).unwrap()).unwrap();
    let (vn, sn) = roll(&mut native);
    let expect = 7.0 * vn * vn / (10.0 * 0.1 * 9.81);
    assert!(
        (sn - expect).abs() < 1e-6 * expect,
        "native: {sn} vs {expect}"
    );
    let mut lg = load("liggghts", &s);
    let (vl, sl) = roll(&mut lg);
    header();
    row("rolling: speed once rolling, m/s", &[vn, vl, f64::NAN]);
    row(
        "rolling: distance to stop, mm",
        &[sn * 1e3, sl * 1e3, f64::NAN],
    );
    let expect = 7.0 * vl * vl / (10.0 * 0.1 * 9.81);
    assert!(
        (sl - expect).abs() < 5e-5 * expect,
        "liggghts rolled {sl} m, expected {expect} m from its speed {vl} m/s"
    );
    assert!(
        (vl - vn).abs() < 1e-4 * vn,
        "speed: native {vn}, liggghts {vl}"
    );
}

/// (g) A periodic box (LIGGGHTS's `boundary p f f`): two grains meet obliquely across the
/// seam, with friction (sliding, spin, shear history), and the same two grains meet in the
/// middle of the box. In each engine the collision across the seam equals the one in the
/// middle: velocities and spins within 1e-9 of their scale (the runs differ in the rounding
/// of positions of other magnitude; the built-in engine's tests/periodic.rs measures 1e-13).
/// Between the engines the oblique collision itself differs under `history` (mid-box as
/// across the seam: exit v_x −0.0256 vs −0.0232 m/s, spin 157 vs 147 rad/s; the head-on
/// bounce of (a) agrees to 2 %): `history` keeps LAMMPS's conventions for the shear spring,
/// LIGGGHTS's `tangential history` its own; under `liggghts_history` they agree (below).
/// YADE refuses periodic boxes.
#[test]
fn g_periodic_seam_collision_as_mid_box() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let text = r#"
schema_version = 1
name = "cross"
duration = "1 s"
gravity = [0, 0, 0]
[domain]
min = [0, -0.01, -0.01]
max = [0.01, 0.01, 0.01]
periodic = [true, false, false]
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
threads = 1
# The step the engines' gaps below were measured at (t_c/50, the default until session 35):
# at t_c/30 the liggghts_history gap in exit v_x is 11 % (−0.0232 vs −0.0261 m/s).
dt_fraction = 50
"#;
    let s = scene(text);
    let (r, gap, offset) = (0.7e-3, 2e-4, 0.4e-3);
    // Velocities and spins of the two grains (in insertion order) after they met at
    // `centre` (0: across the seam).
    let collide = |e: &mut dyn DemBackend, centre: f64| -> Vec<[f64; 6]> {
        let at = |x: f64| x.rem_euclid(0.01);
        e.insert(&[
            NewParticle {
                position: [at(centre - r - gap), -offset, 0.0],
                velocity: [0.2, 0.0, 0.0],
                radius: r,
                density: 937.0,
            },
            NewParticle {
                position: [at(centre + r + gap), offset, 0.0],
                velocity: [-0.2, 0.0, 0.0],
                radius: r,
                density: 937.0,
            },
        ])
        .unwrap();
        let steps = (0.01 / e.time_step()).round() as u64;
        e.advance(steps).unwrap();
        let p = e.particles();
        let first = *p.id.iter().min().unwrap();
        let mut out = vec![[0.0; 6]; 2];
        for k in 0..2 {
            let (v, w) = (p.velocity[k], p.angular_velocity[k]);
            out[(p.id[k] - first) as usize] = [v[0], v[1], v[2], w[0], w[1], w[2]];
        }
        out
    };
    let native = |centre| {
        let mut e = NativeDem::new(plugflow::setup::dem_config(&s).unwrap()).unwrap();
        collide(&mut e, centre)
    };
    let liggghts = |centre| collide(&mut load("liggghts", &s), centre);
    let (na, nb, la, lb) = (native(0.0), native(0.005), liggghts(0.0), liggghts(0.005));
    header();
    row("seam: grain 0 v_x, across", &[na[0][0], la[0][0], f64::NAN]);
    row(
        "seam: grain 0 v_x, mid-box",
        &[nb[0][0], lb[0][0], f64::NAN],
    );
    row("seam: grain 0 ω_z, across", &[na[0][5], la[0][5], f64::NAN]);
    row(
        "seam: grain 0 ω_z, mid-box",
        &[nb[0][5], lb[0][5], f64::NAN],
    );
    assert!(na[0][0] < 0.1 && la[0][0] < 0.1, "they collided");
    let scale = [0.2, 0.2, 0.2, 300.0, 300.0, 300.0];
    for (engine, a, b) in [("native", &na, &nb), ("liggghts", &la, &lb)] {
        for g in 0..2 {
            for c in 0..6 {
                assert!(
                    (a[g][c] - b[g][c]).abs() < 1e-9 * scale[c],
                    "{engine}: grain {g}, entry {c}: across the seam {} vs mid-box {}",
                    a[g][c],
                    b[g][c]
                );
            }
        }
    }
    // The same collision under `liggghts_history`, the built-in engine keeping LIGGGHTS's
    // conventions (the cap on the spring alone, no dashpot while sliding): the 10 % gap in
    // exit velocity and the 7 % in spin close to what the head-on bounce of (a) leaves
    // between the engines' normal forces (2 %): measured 2.4 % and 0.7 %; within 5 %.
    let s = scene(&text.replace(
        "tangential = \"history\"",
        "tangential = \"liggghts_history\"",
    ));
    let native = {
        let mut e = NativeDem::new(plugflow::setup::dem_config(&s).unwrap()).unwrap();
        collide(&mut e, 0.005)
    };
    let liggghts = collide(&mut load("liggghts", &s), 0.005);
    row(
        "liggghts_history: grain 0 v_x",
        &[native[0][0], liggghts[0][0], f64::NAN],
    );
    row(
        "liggghts_history: grain 0 ω_z",
        &[native[0][5], liggghts[0][5], f64::NAN],
    );
    for (c, what) in [(0, "v_x"), (5, "ω_z")] {
        let (a, b) = (native[0][c], liggghts[0][c]);
        assert!(
            (a - b).abs() < 0.05 * b.abs(),
            "liggghts_history: {what} native {a} vs LIGGGHTS {b}"
        );
    }
    // (Under `history` they part by more than that: the laws differ, not the seam.)
    assert!((nb[0][0] - lb[0][0]).abs() > 0.05 * lb[0][0].abs());
}
