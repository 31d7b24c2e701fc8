//! YADE as a user meets it: from the command line, refusing what its laws cannot express,
//! one simulation per process, and in `plugflow crosscheck` beside the other two engines.
//! The engine comparisons themselves are in tests/cross_code.rs. The README's test command
//! installs YADE and builds `libplugflow_dem_yade.so` (`--features plugflow-dem-yade/yade`).

mod common;
use common::plugflow;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use plugflow::scene::Scene;
use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::DemBackend;

/// One YADE per process (its Omega is a singleton): the in-process tests run one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn shim() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let lib = exe
        .parent()
        .unwrap()
        .parent()
        .unwrap()
        .join("libplugflow_dem_yade.so");
    assert!(
        lib.exists(),
        "{} is not built: run the README's test command (bash scripts/test-all.sh), or \
         cargo build --release -p plugflow-dem-yade --features yade",
        lib.display()
    );
    lib
}

fn vertical(extra: &[&str]) -> Scene {
    let mut set = vec!["dem.threads=1".to_string()];
    set.extend(extra.iter().map(|s| s.to_string()));
    Scene::load(&root().join("cases/vertical_plug.toml"), &set).unwrap()
}

/// `--set dem.engine=yade` runs a case on YADE from the command line; the summary names
/// the engine and its version, and the inlet feeds at the scene's rate. It runs in a hostile
/// Python environment: a venv first on PATH (its site-packages lack YADE's dependencies: "No
/// module named 'future'" before issue 26), PYTHONHOME and PYTHONPATH pointing nowhere (a
/// fatal Python start before): the embedded interpreter is Debian's whatever the user's.
#[test]
fn cli_runs_a_case_on_yade() {
    shim();
    let out = std::env::temp_dir().join(format!("plugflow-yade-cli-{}", std::process::id()));
    // A venv's shape without the venv module: bin/python3 beside a pyvenv.cfg.
    let venv = std::env::temp_dir().join(format!("plugflow-venv-{}", std::process::id()));
    std::fs::create_dir_all(venv.join("bin")).unwrap();
    std::fs::write(
        venv.join("pyvenv.cfg"),
        "home = /usr/bin\ninclude-system-site-packages = false\nversion = 3.11.2\n",
    )
    .unwrap();
    let python = venv.join("bin/python3");
    if !python.exists() {
        std::os::unix::fs::symlink("/usr/bin/python3", &python).unwrap();
    }
    let path = format!(
        "{}:{}",
        venv.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .env("PATH", path)
        .env("PYTHONHOME", "/nonexistent")
        .env("PYTHONPATH", "/nonexistent")
        .args([
            "run",
            root().join("cases/vertical_plug.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--duration",
            "0.3",
            "--set",
            "dem.engine=yade",
            "--set",
            "contact.tangential=history",
            // One thread: the case's two would give YADE two OpenMP threads, and two
            // spinning YADE processes on CI's two cores (tests run side by side) crawl.
            "--set",
            "dem.threads=1",
            "--quiet",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(0), "{text}");
    std::fs::remove_dir_all(&venv).ok();
    let s: serde_json::Value = common::read_summary(&out);
    assert_eq!(s["engine"], "yade");
    assert!(
        s["engine_version"].as_str().unwrap().starts_with("YADE 20"),
        "{}",
        s["engine_version"]
    );
    // 0.3 s at 514 grains/s: about 150 grains fed, all still in the tube.
    let fed = s["grains_fed"].as_f64().unwrap();
    assert!((100.0..=200.0).contains(&fed), "{fed} grains fed");
    assert!(
        s["stage_times_s"]["dem_advance"].as_f64().unwrap() > 0.0,
        "{s}"
    );
    std::fs::remove_dir_all(&out).ok();
}

/// The seeds' regularised Coulomb law has no YADE counterpart: the run stops before it
/// starts, naming the field and the reason.
#[test]
fn what_yade_cannot_express_is_refused() {
    shim();
    let (code, text) = plugflow(&[
        "run",
        root().join("cases/vertical_plug.toml").to_str().unwrap(),
        "--set",
        "dem.engine=yade",
        "--quiet",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("contact.tangential") && text.contains("YADE"),
        "{text}"
    );
    // A tube along a skew axis: YADE's polygon tube is built along x, y or z.
    let (code, text) = plugflow(&[
        "run",
        root().join("cases/vertical_plug.toml").to_str().unwrap(),
        "--set",
        "dem.engine=yade",
        "--set",
        "contact.tangential=history",
        "--set",
        "tube.axis=[0, 0.6, 0.8]",
        "--set",
        "gravity=[0, -5.886, -7.848]",
        "--quiet",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("tube.axis"), "{text}");
}

/// YADE's Omega is one per process: a second engine while one is open is refused with the
/// way out (`dem.isolate`), and after the first is closed a new one opens and starts fresh.
#[test]
fn one_yade_per_process() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let s = vertical(&["contact.tangential=history"]);
    let mut first = AbiBackend::load(&shim(), &s.to_json()).unwrap_or_else(|e| panic!("{e}"));
    first.advance(200).unwrap();
    assert!(first.step_count() == 200);
    let second = AbiBackend::load(&shim(), &s.to_json());
    let err = second
        .err()
        .expect("a second YADE in one process is refused");
    assert!(
        err.to_string().contains("one simulation per process")
            && err.to_string().contains("dem.isolate"),
        "{err}"
    );
    drop(first);
    let again = AbiBackend::load(&shim(), &s.to_json()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(again.step_count(), 0);
    assert_eq!(again.particles().len(), 0);
}

/// `plugflow crosscheck --engines native,liggghts,yade` writes the three-engine report;
/// an engine that refuses the scene stops it before anything runs.
#[test]
fn crosscheck_on_three_engines() {
    shim();
    let scene = root().join("cases/vertical_plug.toml");
    let out = std::env::temp_dir().join(format!("plugflow-crosscheck3-{}", std::process::id()));
    let (code, text) = plugflow(&[
        "crosscheck",
        scene.to_str().unwrap(),
        "--engines",
        "native,liggghts,yade",
        "--duration",
        "0.5",
        "--set",
        "output.settling_time=0.3 s",
        "--set",
        "contact.tangential=history",
        // One thread per engine (see cli_runs_a_case_on_yade).
        "--set",
        "dem.threads=1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{text}");
    let md = std::fs::read_to_string(out.join("crosscheck.md")).unwrap();
    assert!(
        md.contains("| quantity | native | liggghts | yade | spread |"),
        "{md}"
    );
    assert!(
        md.contains("LIGGGHTS-PUBLIC") && md.contains("YADE 20"),
        "{md}"
    );
    // Grains in the tube after 0.5 s: all engines feed 2.49 kg/h (cross_code (d): within
    // 15 % after 1 s).
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
    // The case's own regularised Coulomb law: YADE refuses it up front, nothing runs.
    let (code, text) = plugflow(&[
        "crosscheck",
        scene.to_str().unwrap(),
        "--engines",
        "native,yade",
        "--out",
        out.join("refused").to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("contact.tangential"), "{text}");
    assert!(!out.join("refused").join("native").exists());
    // An engine this build does not know.
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

/// `plugflow validate` asks the chosen engine without starting it (`pf_dem_check`): YADE's
/// refusal of the seeds' regularised Coulomb law comes back from `validate` with the field
/// and reason, and the same scene with the history law validates.
#[test]
fn validate_runs_yade_s_own_refusals() {
    shim();
    let case = root().join("cases/vertical_plug.toml");
    let (code, text) = plugflow(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "dem.engine=yade",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("`yade` engine refuses")
            && text.contains("contact.tangential")
            && text.contains("YADE"),
        "{text}"
    );
    let (code, text) = plugflow(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "dem.engine=yade",
        "--set",
        "contact.tangential=history",
    ]);
    assert_eq!(code, 0, "{text}");
}

/// The conveyor inlet on YADE (`inlet.mode = "conveyor"`): the column's grains are held in
/// YADE with every degree of freedom blocked until they leave the slab, as the built-in
/// engine holds them with 1/m = 0. With no gas the grains fed pile up on the inlet, and the
/// conveyor still feeds the scene's rate on both engines: grains entered = grains per metre
/// of column × (distance moved − one radius), within 3σ of the Poisson count of the block
/// the entry line crosses (as model/src/dem/conveyor.rs's engine test); every grain deep in
/// the slab moves at exactly the feed velocity with no spin, and the pile above is free.
#[test]
fn the_conveyor_feeds_yade_as_the_built_in_engine() {
    let _g = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let s = vertical(&["contact.tangential=history", "inlet.mode=\"conveyor\""]);
    let cfg = plugflow_model::dem_config(&s).unwrap();
    let seconds = 0.6;
    let steps = (seconds / cfg.dt).round() as u64;
    let mut native = plugflow_model::dem::NativeDem::new(cfg.clone()).unwrap();
    native.advance(steps).unwrap();
    let mut yade = AbiBackend::load(&shim(), &s.to_json()).unwrap_or_else(|e| panic!("{e}"));
    yade.advance(steps).unwrap();
    for (name, dem) in [("native", &native as &dyn DemBackend), ("yade", &yade)] {
        common::assert_conveyor_feeds(name, dem, &cfg, seconds);
    }
}
