//! LIGGGHTS as a user meets it: from the command line, with their own input file, in a
//! child process (`plugflow crosscheck` on all three engines: tests/yade_engine.rs). The engine comparisons (bounce, settled
//! bed, frozen bed with gas, the vertical case's first second) on all three engines are in
//! tests/cross_code.rs. The README's test command builds the shim
//! (`--features plugflow-dem-liggghts/liggghts`) after installing LIGGGHTS.

mod common;
use common::plugflow;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

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

/// `--set dem.engine=liggghts` runs a case on LIGGGHTS from the command line; the summary
/// names the engine and its version, and LIGGGHTS's own log is kept in the run's folder.
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
    let s: serde_json::Value = common::read_summary(&out);
    assert_eq!(s["engine"], "liggghts");
    assert!(s["engine_version"]
        .as_str()
        .unwrap()
        .starts_with("LIGGGHTS-PUBLIC"));
    // 0.3 s at 514 grains/s: about 150 grains fed, all still in the tube.
    let fed = s["grains_fed"].as_f64().unwrap();
    assert!((100.0..=200.0).contains(&fed), "{fed} grains fed");
    // LIGGGHTS's own log is kept beside plugflow's (issue 23): its banner, and the
    // thermo output of the run's steps in the second file.
    let log = std::fs::read_to_string(out.join("log.liggghts")).unwrap();
    assert!(log.contains("LIGGGHTS (Version"), "{log}");
    let log2 = std::fs::read_to_string(out.join("log2.liggghts")).unwrap();
    assert!(log2.contains("run "), "{log2}");
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
    let s: serde_json::Value = common::read_summary(&out);
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
    let s: serde_json::Value = common::read_summary(&out);
    assert!(s["status"].as_str().unwrap().starts_with("failed"), "{s}");
    assert!(s["simulated_time_s"].as_f64().unwrap() > 0.0);
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let t: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    assert!(!t.is_empty());
    std::fs::remove_dir_all(&out).ok();
}

/// `plugflow validate` asks the chosen engine without starting it (`pf_dem_check`): a scene
/// LIGGGHTS cannot take (a feed valve closing, `inlet.until`) is refused by `validate` with
/// the field and reason; the case itself validates on LIGGGHTS.
#[test]
fn h_validate_runs_liggghts_s_own_refusals() {
    shim();
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/vertical_plug.toml");
    let (code, text) = plugflow(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "dem.engine=liggghts",
        "--set",
        "inlet.until=1 s",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("`liggghts` engine refuses") && text.contains("inlet.until"),
        "{text}"
    );
    let (code, text) = plugflow(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "dem.engine=liggghts",
    ]);
    assert_eq!(code, 0, "{text}");
}
