//! The same scenes on the built-in DEM and on LIGGGHTS (Debian's libliggghts through
//! `libplugflow_dem_liggghts.so` and the DEM ABI). The README's test command builds the
//! shim (`--features plugflow-dem-liggghts/liggghts`) after installing LIGGGHTS.
//!
//! Both engines get the same contact constants (Hooke k_n, k_t, γ_n, γ_t, μ per material
//! pair: the shim maps the built-in engine's laws onto `hooke/stiffness` with absolute
//! damping) and the same initial grains (placed by plugflow, inserted into LIGGGHTS).
//! A failing comparison prints both engines' numbers.

mod common;
use common::plugflow;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use plugflow::cosim::coupling_from_scene;
use plugflow::dem::{DemConfig, NativeDem};
use plugflow::scene::Scene;
use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::{DemBackend, NewParticle};

/// LIGGGHTS instances run one at a time (they share MPI's process state, and the tests
/// are long enough that running them side by side only makes each slower).
static SERIAL: Mutex<()> = Mutex::new(());

fn shim() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let lib = exe
        .parent()
        .unwrap()
        .parent()
        .unwrap()
        .join("libplugflow_dem_liggghts.so");
    assert!(
        lib.exists(),
        "{} is not built: run the README's test command (bash scripts/test-all.sh), or \
         cargo build --release -p plugflow-dem-liggghts --features liggghts",
        lib.display()
    );
    lib
}

fn scene(text: &str) -> Scene {
    Scene::parse(text, &[]).unwrap_or_else(|e| panic!("test scene: {e}"))
}

fn engines(s: &Scene) -> (NativeDem, AbiBackend) {
    let native = NativeDem::new(DemConfig::from_scene(s).unwrap()).unwrap();
    let liggghts = AbiBackend::load(&shim(), &s.to_json()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(liggghts.engine_name(), "liggghts");
    assert!(liggghts.engine_version().starts_with("LIGGGHTS-PUBLIC 3."));
    assert_eq!(native.time_step(), liggghts.time_step());
    (native, liggghts)
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
"#;

fn tube(length: &str, outlet: &str, tangential: &str, contact: &str, extra: &str) -> String {
    TUBE.replace("LENGTH", length)
        .replace("OUTLET", outlet)
        .replace("TANGENTIAL", tangential)
        .replace("CONTACT", contact)
        + extra
}

/// (a) One grain dropped ~5 mm onto the closed end. Before contact both integrate the
/// same free fall with velocity Verlet: positions agree to rounding (1e-9 relative is
/// ~1e6 ulps of slack for ~8000 steps of accumulated rounding differences in the order
/// of operations). The restitution of the bounce, from the velocities just before and
/// just after the contact, agrees within 2 % (both apply the same linear spring–dashpot;
/// the difference is where within a step each engine resolves the contact's start/end).
#[test]
fn a_single_grain_bounce() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let drop = "[initial]\ncount = 1\nfrom = \"4 mm\"\nto = \"6 mm\"\n";
    bounce(
        &tube("0.05 m", "closed", "history", "1e-4 s", drop),
        "hooke",
    );
    // Hertz: LIGGGHTS's own `model hertz`, given the restitution whose β reproduces the
    // built-in engine's Tsuji damping exactly (see bindings/liggghts/src/input.rs).
    let hertz = tube("0.05 m", "closed", "history", "1e-4 s", drop).replace(
        "normal = \"hooke\"\ntangential = \"history\"\ncontact_time = \"1e-4 s\"",
        "normal = \"hertz\"\ntangential = \"history\"\nyoungs_modulus = \"5e6 Pa\"\npoisson_ratio = 0.45",
    );
    assert!(hertz.contains("hertz"));
    bounce(&hertz, "hertz");
}

fn bounce(text: &str, law: &str) {
    let s = scene(text);
    let (mut n, mut l) = engines(&s);
    let r = 0.7e-3;
    let chunk = 5;
    let (mut zn, mut zl, mut vn, mut vl) = (vec![], vec![], vec![], vec![]);
    let total = (0.06 / n.time_step()) as u64;
    for _ in 0..total / chunk {
        n.advance(chunk).unwrap();
        l.advance(chunk).unwrap();
        zn.push(n.particles().position[0][2]);
        zl.push(l.particles().position[0][2]);
        vn.push(n.particles().velocity[0][2]);
        vl.push(l.particles().velocity[0][2]);
    }
    // Before contact (centre more than one radius above the cap).
    let free = zn
        .iter()
        .position(|z| *z < r)
        .expect("the grain reaches the cap");
    assert!(free > 100);
    for k in 0..free {
        let rel = (zn[k] - zl[k]).abs() / zn[k].abs();
        assert!(
            rel < 1e-9,
            "{law}: sample {k}: native z {} vs LIGGGHTS z {} (rel {rel:e})",
            zn[k],
            zl[k]
        );
    }
    let bounce = |z: &[f64], v: &[f64]| {
        let start = z.iter().position(|z| *z < r).unwrap();
        let end = start + z[start..].iter().position(|z| *z >= r).unwrap();
        // Velocities one chunk outside the contact (gravity changes them by g·5 dt).
        -v[end] / v[start - 1]
    };
    let (en, el) = (bounce(&zn, &vn), bounce(&zl, &vl));
    println!("{law}: restitution native {en:.4}, LIGGGHTS {el:.4}");
    assert!(
        (en - el).abs() / en < 0.02,
        "{law}: restitution native {en}, LIGGGHTS {el}"
    );
    assert!((en - 0.5).abs() < 0.05, "{law}: native restitution {en}");
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

/// Wall normal stress profile from the grains' elastic overlap with the tube (a settled
/// bed moves too slowly for the dashpot to matter): σ_k = Σ k_n δ_i / (2π R Δz) per slice.
fn wall_stress(x: &[[f64; 3]], r: f64, rt: f64, kn: f64, dz: f64, slices: usize) -> Vec<f64> {
    let mut s = vec![0.0; slices];
    for p in x {
        let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let overlap = rho + r - rt;
        let k = (p[2] / dz) as usize;
        if overlap > 0.0 && k < slices {
            s[k] += kn * overlap / (2.0 * std::f64::consts::PI * rt * dz);
        }
    }
    s
}

/// (b) 800 grains poured into the tube (the same random places in both) and settled.
/// Porosity of the bed's middle within 2 % and the wall normal stress, averaged over
/// 2 cm slices of the lower bed, within 10 %: the two engines build different random
/// packings from the same start, so the comparison is statistical; the bands are those
/// of the issue, wider than the slice-to-slice scatter of one engine (~5 %).
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
    let cfg = DemConfig::from_scene(&s).unwrap();
    let kn = match &cfg.laws {
        plugflow::dem::config::LawSet::HookeHistory(l) => l.pw_normal.kn,
        _ => unreachable!(),
    };
    let (mut n, mut l) = engines(&s);
    let steps = (0.35 / n.time_step()) as u64;
    n.advance(steps).unwrap();
    l.advance(steps).unwrap();
    let (r, rt) = (0.7e-3, 3.5e-3);
    let top = |x: &[[f64; 3]]| x.iter().map(|p| p[2]).fold(0.0, f64::max);
    let (xn, xl) = (
        n.particles().position.to_vec(),
        l.particles().position.to_vec(),
    );
    // Both beds at rest.
    let vmax = |e: &dyn DemBackend| {
        e.particles()
            .velocity
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(0.0, f64::max)
    };
    assert!(vmax(&n) < 0.05 && vmax(&l) < 0.05, "beds not settled");
    let h = top(&xn).min(top(&xl));
    assert!(h > 0.05, "bed height {h}");
    let (pn, pl) = (
        porosity(&xn, r, rt, 0.2 * h, 0.8 * h),
        porosity(&xl, r, rt, 0.2 * h, 0.8 * h),
    );
    println!("bed porosity: native {pn:.4}, LIGGGHTS {pl:.4}; height {h:.4} m");
    assert!(
        (pn - pl).abs() / pn < 0.02,
        "porosity native {pn} vs LIGGGHTS {pl}"
    );
    let dz = 0.02;
    let slices = ((0.8 * h) / dz) as usize;
    let (sn, sl) = (
        wall_stress(&xn, r, rt, kn, dz, slices),
        wall_stress(&xl, r, rt, kn, dz, slices),
    );
    println!(
        "wall stress (Pa) per 2 cm: native {sn:.1?}\n                        LIGGGHTS {sl:.1?}"
    );
    let (mn, ml) = (
        sn.iter().sum::<f64>() / slices as f64,
        sl.iter().sum::<f64>() / slices as f64,
    );
    assert!(
        (mn - ml).abs() / mn < 0.10,
        "mean wall stress native {mn} vs LIGGGHTS {ml}"
    );
    // The cap carries what wall friction does not (Janssen). How much friction is
    // mobilised depends on the packing history: the built-in engine alone over seeds 1–6
    // of this scene gives 0.0052–0.0069 N (s.d. 11 %), so two independent beds differ by
    // up to 2σ·√2 ≈ 30 % with no error in either engine. Beyond that, wall forces differ.
    let cap = |e: &dyn DemBackend| {
        e.wall_forces()
            .iter()
            .find(|w| w.wall == "inlet_cap")
            .map(|w| w.force[2])
            .unwrap()
    };
    let (cn, cl) = (cap(&n), cap(&l));
    println!("force on the closed end: native {cn:.5} N, LIGGGHTS {cl:.5} N");
    assert!(
        cn < 0.0 && (cn - cl).abs() / cn.abs() < 0.30,
        "cap force {cn} vs {cl}"
    );
}

/// (c) A frozen bed with gas: the native engine's settled bed inserted into LIGGGHTS, then
/// the gas solved to steady state over each engine's grains without moving them. The
/// deposit sees the same grains, so Δp agrees to rounding; 1 % (the issue's band) would
/// catch a single grain missing or misplaced (each grain is ~0.3 % of the bed).
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
    let mut n = NativeDem::new(DemConfig::from_scene(&bed).unwrap()).unwrap();
    n.advance((0.3 / n.time_step()) as u64).unwrap();
    let empty = scene(&tube("0.14 m", "closed", "history", "2e-4 s", gas));
    let mut l = AbiBackend::load(&shim(), &empty.to_json()).unwrap_or_else(|e| panic!("{e}"));
    let p = n.particles();
    let grains: Vec<NewParticle> = (0..p.len())
        .map(|i| NewParticle {
            position: p.position[i],
            velocity: [0.0; 3],
            radius: p.radius[i],
            density: 937.0,
        })
        .collect();
    let ids = l.insert(&grains).unwrap();
    assert_eq!(ids.len(), grains.len());
    assert_eq!(l.particles().len(), grains.len());
    let cfg = DemConfig::from_scene(&bed).unwrap();
    let mut gn = coupling_from_scene(&bed, &cfg).unwrap().unwrap();
    let mut gl = coupling_from_scene(&bed, &cfg).unwrap().unwrap();
    // 0.2 s of gas (≫ the diffusion time of the bed) without advancing the grains.
    for _ in 0..2000 {
        gn.exchange(&mut n).unwrap();
        gl.exchange(&mut l).unwrap();
    }
    let (dn, dl) = (gn.pressure_drop(), gl.pressure_drop());
    println!("frozen bed Δp: native {dn:.3} Pa/m, LIGGGHTS {dl:.3} Pa/m");
    assert!(
        dn > 0.0 && (dn - dl).abs() / dn < 0.01,
        "Δp native {dn} vs LIGGGHTS {dl}"
    );
}

/// (d) The vertical plug case for 1 s on both engines (each with its own inlet: random
/// insertion in the lowest 2 cm at the same mass flow). After 1 s the tube holds the
/// first ~500 grains resting on the closed end under gas drag; Δp (averaged over the
/// last 0.2 s) and grains in the tube within 15 %, the issue's band for two engines'
/// different random feeds.
#[test]
fn d_vertical_plug_first_second() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(
        &root.join("cases/vertical_plug.toml"),
        &["dem.threads=1".to_string()],
    )
    .unwrap();
    let (mut n, mut l) = engines(&s);
    let cfg = DemConfig::from_scene(&s).unwrap();
    let mut gn = coupling_from_scene(&s, &cfg).unwrap().unwrap();
    let mut gl = coupling_from_scene(&s, &cfg).unwrap().unwrap();
    let exchanges = (1.0 / gn.interval).round() as usize;
    let (mut dn, mut dl, mut k) = (0.0, 0.0, 0);
    for e in 0..exchanges {
        n.advance(gn.substeps).unwrap();
        gn.exchange(&mut n).unwrap();
        l.advance(gl.substeps).unwrap();
        l.remove_past_outlet().unwrap();
        gl.exchange(&mut l).unwrap();
        if e >= exchanges * 4 / 5 {
            dn += gn.pressure_drop();
            dl += gl.pressure_drop();
            k += 1;
        }
    }
    let (dn, dl) = (dn / k as f64, dl / k as f64);
    let (nn, nl) = (n.particles().len() as f64, l.particles().len() as f64);
    println!(
        "after 1 s: native {nn} grains, Δp {dn:.1} Pa/m; LIGGGHTS {nl} grains, Δp {dl:.1} Pa/m"
    );
    assert!(
        (nn - nl).abs() / nn < 0.15,
        "grains native {nn} vs LIGGGHTS {nl}"
    );
    assert!(
        dn > 0.0 && (dn - dl).abs() / dn < 0.15,
        "Δp native {dn} vs LIGGGHTS {dl}"
    );
}

/// `--set dem.engine=liggghts` runs a case on LIGGGHTS from the command line; the summary
/// names the engine and its version.
#[test]
fn e_cli_runs_a_case_on_liggghts() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    shim();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-lg-cli-{}", std::process::id()));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .args([
            "run",
            root.join("cases/vertical_plug.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--duration",
            "0.3",
            "--set",
            "dem.engine=liggghts",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["engine"], "liggghts");
    assert!(s["engine_version"]
        .as_str()
        .unwrap()
        .starts_with("LIGGGHTS-PUBLIC"));
    // 0.3 s at 514 grains/s: about 150 grains fed, all still in the tube.
    let fed = s["grains_fed"].as_f64().unwrap();
    assert!((100.0..=200.0).contains(&fed), "{fed} grains fed");
    std::fs::remove_dir_all(&out).ok();
}

/// A LIGGGHTS user's own input (cases/liggghts_user) runs coupled with the gas; inputs
/// plugflow cannot couple are refused with the line and the reason, and an input LIGGGHTS
/// itself rejects (which would end LIGGGHTS's process) comes back as LIGGGHTS's ERROR
/// line, found by a child process, while ours goes on.
#[test]
fn f_user_liggghts_input() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    shim();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("cases/liggghts_user/scene.toml");
    let dir = std::env::temp_dir().join(format!("plugflow-lg-user-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("run");
    let (code, text) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.4",
        "--set",
        "output.settling_time=0.2 s",
        "--quiet",
    ]);
    assert_eq!(code, 0, "{text}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["engine"], "liggghts");
    // The input feeds 6.9e-4 kg/s of 1.35e-6 kg beads: ~200 grains in 0.4 s, all in the
    // tube, under a pressure drop from the gas.
    let fed = s["grains_fed"].as_f64().unwrap();
    assert!((120.0..=260.0).contains(&fed), "{fed} grains fed");
    assert!(s["pressure_drop_hpa_per_m"].as_f64().unwrap() > 0.0);

    let bad = dir.join("include.in");
    std::fs::write(&bad, "atom_style granular\ninclude more.in\n").unwrap();
    let (code, text) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--set",
        &format!("dem.liggghts_input={}", bad.display()),
        "--quiet",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("dem.liggghts_input") && text.contains("line 2: `include`"),
        "{text}"
    );

    let wrong = dir.join("wrong.in");
    std::fs::write(
        &wrong,
        "atom_style granular\natom_modify map array\nboundary f f f\nunits si\n\
         region d block -0.005 0.005 -0.005 0.005 -0.002 0.53 units box\ncreate_box 1 d\n\
         fix x all nosuchfix 1 2\ntimestep 5e-6\nfix i all nve/sphere\n",
    )
    .unwrap();
    let (code, text) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--set",
        &format!("dem.liggghts_input={}", wrong.display()),
        "--quiet",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("child process") && text.contains("nosuchfix"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `dem.isolate = true`: LIGGGHTS runs in a child process. When that process dies (here
/// killed; in practice LIGGGHTS's exit(1) on an error), the run stops with the engine's
/// death as its error, writes its summary as failed and keeps run.h5 readable.
#[test]
fn g_isolated_engine_death_is_an_error_not_a_crash() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    shim();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-lg-iso-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .args([
            "run",
            root.join("cases/vertical_plug.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "dem.engine=liggghts",
            "--set",
            "dem.isolate=true",
            "--quiet",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Let it run a little, then kill the engine's process (not plugflow's).
    std::thread::sleep(std::time::Duration::from_secs(3));
    let host = std::process::Command::new("pgrep")
        .args(["-P", &run.id().to_string(), "-f", "plugflow-dem-host"])
        .output()
        .unwrap();
    let pid = String::from_utf8_lossy(&host.stdout).trim().to_string();
    assert!(!pid.is_empty(), "no engine host process under plugflow");
    std::process::Command::new("kill")
        .args(["-9", &pid])
        .status()
        .unwrap();
    let o = run.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("engine process died"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(s["status"].as_str().unwrap().starts_with("failed"), "{s}");
    assert!(s["simulated_time_s"].as_f64().unwrap() > 0.0);
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let t: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    assert!(!t.is_empty());
    std::fs::remove_dir_all(&out).ok();
}

/// `plugflow crosscheck` runs a scene on each engine and writes the side-by-side report;
/// an engine this build does not know stops it before anything runs.
#[test]
fn h_crosscheck_report() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    shim();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("cases/vertical_plug.toml");
    let out = std::env::temp_dir().join(format!("plugflow-crosscheck-{}", std::process::id()));
    let (code, text) = plugflow(&[
        "crosscheck",
        scene.to_str().unwrap(),
        "--engines",
        "native,liggghts",
        "--duration",
        "0.5",
        "--set",
        "output.settling_time=0.3 s",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{text}");
    let md = std::fs::read_to_string(out.join("crosscheck.md")).unwrap();
    assert!(
        md.contains("| quantity | native | liggghts | spread |"),
        "{md}"
    );
    assert!(md.contains("LIGGGHTS-PUBLIC"), "{md}");
    // Grains in the tube after 0.5 s: both engines feed 2.49 kg/h (see test d: within 15 %).
    let row = md
        .lines()
        .find(|l| l.starts_with("| grains in the tube"))
        .unwrap();
    let spread: f64 = row
        .rsplit('|')
        .nth(1)
        .unwrap()
        .trim()
        .trim_end_matches(" %")
        .parse()
        .unwrap();
    assert!(spread < 15.0, "{row}");
    assert!(out.join("crosscheck.png").exists());
    let (code, text) = plugflow(&[
        "crosscheck",
        scene.to_str().unwrap(),
        "--engines",
        "native,nosuchengine",
        "--out",
        out.join("bad").to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("nosuchengine"), "{text}");
    std::fs::remove_dir_all(&out).ok();
}
