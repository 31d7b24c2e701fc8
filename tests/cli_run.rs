//! `plugflow run` end to end: the summary has the keys the issue names, and a run that
//! blows up stops with the step and grain and still writes its summary.

mod common;
use common::{box_scene, plugflow, HOOKE};
use std::path::Path;

#[test]
fn run_writes_summary_with_required_keys() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_dry_feed.toml");
    let (code, text, out, s) = common::run_case(
        case.to_str().unwrap(),
        "cli",
        &["--duration", "0.6", "--set", "output.settling_time=0.4 s"],
    );
    assert_eq!(code, 0, "{text}");
    for key in [
        "engine",
        "simulated_time_s",
        "wall_time_s",
        "stage_times_s",
        "particles_in_tube_mean",
        "mass_outflow_kg_per_h",
    ] {
        assert!(s.get(key).is_some(), "summary lacks `{key}`: {s}");
    }
    assert_eq!(s["engine"], "native");
    assert!((s["simulated_time_s"].as_f64().unwrap() - 0.6).abs() < 1e-6);
    let stages = s["stage_times_s"].as_object().unwrap();
    for st in ["forces", "integrate", "neighbor", "inlet_outlet"] {
        assert!(stages.contains_key(st), "stage `{st}` missing: {stages:?}");
    }
    // Grains fall 0.525 m in ~0.3 s, so after 0.4 s the outflow runs at the feed rate.
    // The window is 0.2 s (~100 grains), so ±25 % covers the counting noise.
    let outflow = s["mass_outflow_kg_per_h"].as_f64().unwrap();
    assert!(
        (outflow - 2.49).abs() < 0.25 * 2.49,
        "outflow {outflow} kg/h"
    );
    assert!(s["particles_in_tube_mean"].as_f64().unwrap() > 50.0);
    std::fs::remove_dir_all(&out).ok();
}

/// `--duration` counts in the scene's checks: a settling time past the scene's own duration
/// but inside the one asked for on the command line is accepted (and refused, naming the
/// field, without `--duration`). A `--duration` shorter than a case's settling time (a short
/// trial of a long case) stays accepted: the sweep and ABI tests here run such trials.
#[test]
fn duration_flag_counts_in_the_scene_checks() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-cli-dur-{}", std::process::id()));
    let case = root.join("tests/scenes/good/box_with_planes.toml"); // duration 0.01 s
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "run".to_string(),
            case.to_str().unwrap().to_string(),
            "--out".to_string(),
            out.to_str().unwrap().to_string(),
            "--quiet".to_string(),
            "--set".to_string(),
            "output.settling_time=0.015 s".to_string(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let refused = args(&[]);
    let refused: Vec<&str> = refused.iter().map(String::as_str).collect();
    let (code, text) = plugflow(&refused);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("output.settling_time"), "{text}");

    let accepted = args(&["--duration", "0.02"]);
    let accepted: Vec<&str> = accepted.iter().map(String::as_str).collect();
    let (code, text) = plugflow(&accepted);
    assert_eq!(code, 0, "{text}");
    let s: serde_json::Value = common::read_summary(&out);
    assert!(
        (s["simulated_time_s"].as_f64().unwrap() - 0.02).abs() < 1e-9,
        "{s}"
    );
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn blow_up_stops_with_step_and_grain_and_keeps_the_summary() {
    // A grain moving at 1e5 m/s: above the blow-up speed, caught at the first half kick.
    let dir = std::env::temp_dir().join(format!("plugflow-blowup-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("blowup.toml");
    let text = box_scene(
        "[0, 0, -9.81]",
        HOOKE,
        "[initial]\ncount = 2\nfrom = \"-0.005 m\"\nto = \"0.005 m\"\n\
         velocity = [0, 0, \"-1e5 m/s\"]\n\
         [[walls]]\nname = \"floor\"\npoint = [0, 0, -0.009]\nnormal = [0, 0, 1]",
    );
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let (code, text) = plugflow(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("blown-up state at step 1:") && text.contains("particle id"),
        "{text}"
    );
    let s = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(s.contains("failed: run stopped"), "{s}");
    // The log keeps how the run ended, for a batch job nobody watched.
    let log = std::fs::read_to_string(out.join("log.plugflow")).unwrap();
    assert!(log.contains("failed: run stopped"), "{log}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `plugflow run cases/vertical_plug.toml` for `duration` seconds with the settling time
/// `settle`, into a fresh temporary folder named by `tag`: (exit code, output, folder).
fn vertical_run(
    tag: &str,
    duration: &str,
    settle: &str,
    extra: &[&str],
) -> (i32, String, std::path::PathBuf) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let case = root.join("cases/vertical_plug.toml");
    let settling = format!("output.settling_time={settle}");
    let mut args = vec![
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--duration",
        duration,
        "--set",
        &settling,
    ];
    args.extend_from_slice(extra);
    let (code, text) = plugflow(&args);
    (code, text, out)
}

/// A run whose stderr is not a terminal (here a pipe, as in a batch job) prints plain
/// progress lines instead of a bar, and `log.plugflow` keeps the checks, the progress and
/// the ending.
#[test]
fn a_batch_run_prints_plain_progress_and_keeps_a_log() {
    // Without --quiet: the progress lines are what is tested.
    let (code, text, out) = vertical_run("batch", "0.2", "0.1 s", &[]);
    assert_eq!(code, 0, "{text}");
    // The first sample's line and the last (the run is shorter than the 5 s between lines).
    assert!(text.contains("t = 0.0100/0.2 s (5 %)"), "{text}");
    assert!(text.contains("t = 0.2000/0.2 s (100 %)"), "{text}");
    assert!(text.contains("s simulated per wall second, ETA"), "{text}");
    assert!(text.contains("grains in tube, Δp"), "{text}");
    // No progress bar's redraws (indicatif's carriage returns and cursor codes).
    assert!(!text.contains('\r') && !text.contains('\u{1b}'), "{text:?}");
    let log = std::fs::read_to_string(out.join("log.plugflow")).unwrap();
    for want in [
        "scene `vertical_plug`",
        "engine native",
        "coupling check: ",
        "t = 0.0100/0.2 s (5 %)",
        "t = 0.2000/0.2 s (100 %)",
        "completed: 0.2000 s simulated",
    ] {
        assert!(log.contains(want), "log.plugflow lacks `{want}`:\n{log}");
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn coupled_run_reports_gas_numbers_and_checks() {
    let (code, text, out) = vertical_run("coupled", "0.4", "0.2 s", &["--quiet"]);
    assert_eq!(code, 0, "{text}");
    let s: serde_json::Value = common::read_summary(&out);
    for key in [
        "pressure_drop_hpa_per_m",
        "gas_mass_error_rel",
        "porosity_clamped_fraction",
        "coupling_checks",
    ] {
        assert!(s.get(key).is_some(), "summary lacks `{key}`: {s}");
    }
    // The gas solve conserves mass to round-off (see tests/gas_darcy.rs).
    assert!(s["gas_mass_error_rel"].as_f64().unwrap() < 1e-10, "{s}");
    // After 0.4 s grains lie at the bottom: some pressure drop, none negative.
    assert!(s["pressure_drop_hpa_per_m"].as_f64().unwrap() > 0.0, "{s}");
    let checks = s["coupling_checks"].as_array().unwrap();
    assert_eq!(checks.len(), 4);
    for c in checks {
        assert_eq!(c["verdict"], "ok", "{c}");
        assert!(
            c["value"].as_f64().unwrap() <= c["limit"].as_f64().unwrap()
                || c["name"].as_str().unwrap().contains("volume")
        );
    }
    // The accuracy block: the DEM step within its limit; the gas step's time error from
    // step doubling (4000 exchanges → a check every 100th, the start from rest left out:
    // 39). BDF2 at Δt = 1e-4 s, 400× shorter than the 40 ms relaxation time of a plug, is
    // accurate to well under 0.1 % on average.
    let a = &s["accuracy"];
    let f = a["dem_dt_fraction_of_limit"].as_f64().unwrap();
    assert!(f > 0.0 && f <= 1.0, "{a}");
    assert_eq!(a["gas_step_doubling_checks"].as_u64().unwrap(), 39, "{a}");
    let (max, mean) = (
        a["gas_step_doubling_rel_max"].as_f64().unwrap(),
        a["gas_step_doubling_rel_mean"].as_f64().unwrap(),
    );
    assert!(
        (0.0..0.05).contains(&max) && (0.0..1e-3).contains(&mean),
        "{a}"
    );
    // The loose grains at the bottom are never more solid than φ_min; most of the tube is
    // empty and clamped down to φ_max.
    assert_eq!(
        a["porosity_clamped_low_node_steps"].as_u64().unwrap(),
        0,
        "{a}"
    );
    assert!(
        a["porosity_clamped_high_node_steps"].as_u64().unwrap() > 0,
        "{a}"
    );
    assert_eq!(a["coupling_checks"].as_array().unwrap().len(), 4, "{a}");
    let stages = s["stage_times_s"].as_object().unwrap();
    for st in [
        "deposit",
        "gas",
        "interpolate_drag",
        "set_forces",
        "forces",
        "accuracy_check",
    ] {
        assert!(stages.contains_key(st), "stage `{st}` missing: {stages:?}");
    }
    // The case names TARGETS.md rows V1–V5 (V3 twice: statistic and tracked) and V12: each
    // listed with measured, paper, band, verdict. V12's paper states a direction, not a
    // number: `null` there.
    let targets = s["targets"].as_array().unwrap();
    let ids: Vec<&str> = targets.iter().map(|t| t["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["V1", "V2", "V3", "V3.tracked", "V4", "V5", "V12"]);
    for t in targets {
        let paper_given = t["id"] != "V12";
        assert!(
            t["paper"].as_f64().is_some() == paper_given
                && t["band"].as_array().unwrap().len() == 2,
            "{t}"
        );
        assert!(t["inside"].is_boolean(), "{t}");
    }
    let png = std::fs::read(out.join("porosity_tz.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    std::fs::remove_dir_all(&out).ok();
}

/// A sweep runs each combination as its own `plugflow run` with the variant's overrides:
/// variant 001 must give bit for bit what a direct run with the same `--set` gives. The
/// second `--vary` pairs two fields (`a|b=…`): each variant sets both.
#[test]
fn sweep_runs_every_variant_as_a_direct_run_would() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_dry_feed.toml");
    let out = std::env::temp_dir().join(format!("plugflow-sweep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let (code, text) = plugflow(&[
        "sweep",
        case.to_str().unwrap(),
        "--vary",
        "particles.density=937,1200 kg/m^3",
        "--vary",
        "contact.friction|contact.restitution=0.3|0.6,0.5|0.7",
        "--duration",
        "0.3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{text}");
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 5, "{csv}");
    assert!(
        lines[0]
            .starts_with("particles.density,contact.friction,contact.restitution,variant,status"),
        "{csv}"
    );
    assert!(
        lines[2].starts_with("\"937\",\"0.5\",\"0.7\",001,\"completed\""),
        "{csv}"
    );
    assert!(out.join("characteristic.png").exists());
    let direct = out.join("direct");
    let (code, text) = plugflow(&[
        "run",
        case.to_str().unwrap(),
        "--out",
        direct.to_str().unwrap(),
        "--duration",
        "0.3",
        "--set",
        "dem.threads=1",
        "--set",
        "particles.density=937",
        "--set",
        "contact.friction=0.5",
        "--set",
        "contact.restitution=0.7",
        "--quiet",
    ]);
    assert_eq!(code, 0, "{text}");
    let read = |p: &Path| -> serde_json::Value { common::read_summary(p) };
    let (a, b) = (read(&out.join("001")), read(&direct));
    for key in ["particles_in_tube_mean", "grains_fed", "steps"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    // A variant whose value the scene refuses stops the sweep before anything runs.
    let (code, text) = plugflow(&[
        "sweep",
        case.to_str().unwrap(),
        "--vary",
        "contact.friction=0.3,-1",
        "--out",
        out.join("bad").to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("contact.friction=-1") && text.contains("contact.friction"),
        "{text}"
    );
    assert!(!out.join("bad").exists());
    // A paired value that does not give every field, and pairs in a study: refused, named.
    for (cmd, vary, why) in [
        (
            "sweep",
            "contact.friction|contact.restitution=0.3|0.6,0.5",
            "gives 1 of the 2 fields",
        ),
        (
            "study",
            "contact.friction|contact.restitution=0.3|0.6",
            "a study varies one field",
        ),
    ] {
        let (code, text) = plugflow(&[
            cmd,
            case.to_str().unwrap(),
            "--vary",
            vary,
            "--out",
            out.join("bad").to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{text}");
        assert!(
            text.contains(why) && text.contains("contact.friction"),
            "{text}"
        );
    }
    assert!(!out.join("bad").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// `dem.engine = "native_abi"` runs the built-in engine through the C ABI
/// (libplugflow_dem_native.so loaded at run time): the whole run, gas included, gives bit
/// for bit what the built-in engine gives directly.
#[test]
fn native_through_the_abi_runs_a_case_bit_for_bit() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_plug.toml");
    let base = std::env::temp_dir().join(format!("plugflow-abi-run-{}", std::process::id()));
    let mut csv = Vec::new();
    for engine in ["native", "native_abi"] {
        let out = base.join(engine);
        let (code, text) = plugflow(&[
            "run",
            case.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--duration",
            "0.4",
            "--set",
            &format!("dem.engine={engine}"),
            "--quiet",
        ]);
        assert_eq!(code, 0, "{text}");
        let s: serde_json::Value = common::read_summary(&out);
        assert_eq!(s["engine"], "native");
        csv.push((
            std::fs::read_to_string(out.join("porosity_tz.csv")).unwrap(),
            s["pressure_drop_hpa_per_m"].clone(),
            s["particles_in_tube_mean"].clone(),
        ));
    }
    assert!(csv[0].0.lines().count() == 40);
    assert_eq!(csv[0], csv[1]);
    // A scene naming an engine whose library is missing is refused before it starts.
    let (code, text) = plugflow(&[
        "run",
        case.to_str().unwrap(),
        "--set",
        "dem.engine=liggghts",
        "--set",
        "dem.library=/nonexistent/libplugflow_dem_liggghts.so",
        "--quiet",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("dem.engine") && text.contains("/nonexistent/libplugflow_dem_liggghts.so"),
        "{text}"
    );
    std::fs::remove_dir_all(&base).ok();
}

/// `plugflow study`: every variant runs, the finest (smallest interval, largest grid) is the
/// reference and is named, the table has a wall time, stage times and an error per
/// observable, the figure is written, and the cheapest variant meeting a target is named.
/// An exact value replaces the finest variant as reference for its observable.
#[test]
fn study_measures_error_against_run_time() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-study-{}", std::process::id()));
    let case = root.join("cases/vertical_plug.toml");
    let (code, text) = plugflow(&[
        "study",
        case.to_str().unwrap(),
        "--vary",
        "coupling.interval=5e-5,1e-4",
        "--vary",
        "gas.grid=[150, 2, 2],[75, 2, 2]",
        "--duration",
        "0.3",
        "--set",
        "output.settling_time=0.1 s",
        "--exact",
        "mass_outflow_kg_per_h=0",
        "--target-error",
        "0.5",
        "--jobs",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{text}");
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    // Variant 000 = (5e-5, [150, 2, 2]): the finest of both fields.
    assert!(md.contains("(finest variant 000)"), "{md}");
    assert!(
        md.contains("`mass_outflow_kg_per_h` = 0.0000 (exact value (--exact))"),
        "{md}"
    );
    assert!(
        md.contains("| 000 | 5e-5 | [150, 2, 2] |") && md.contains("reference"),
        "{md}"
    );
    assert!(
        md.contains("Cheapest setting with largest error ≤ 0.5"),
        "{md}"
    );
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    // Fields, with commas inside quotes kept ("[150, 2, 2]").
    let fields = |line: &str| -> Vec<String> {
        let (mut out, mut cur, mut quoted) = (Vec::new(), String::new(), false);
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => out.push(std::mem::take(&mut cur)),
                _ => cur.push(c),
            }
        }
        out.push(cur);
        out
    };
    let header = fields(csv.lines().next().unwrap());
    for col in [
        "wall_time_s",
        "stage_gas_s",
        "error_pressure_drop_hpa_per_m",
        "max_error",
        "pareto",
    ] {
        assert!(header.iter().any(|h| h == col), "{header:?}");
    }
    assert_eq!(csv.lines().count(), 5);
    // The reference's own errors are zero; the coarse grid's pressure-drop error is not.
    let err_col = header
        .iter()
        .position(|c| c == "error_pressure_drop_hpa_per_m")
        .unwrap();
    let errors: Vec<f64> = csv
        .lines()
        .skip(1)
        .map(|l| fields(l)[err_col].parse().unwrap())
        .collect();
    assert_eq!(errors[0], 0.0);
    assert!(errors[1] > 0.0, "{errors:?}");
    let png = std::fs::read(out.join("study.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // A malformed exact value is refused before anything runs.
    let (code, text) = plugflow(&[
        "study",
        case.to_str().unwrap(),
        "--vary",
        "coupling.interval=5e-5,1e-4",
        "--exact",
        "pressure_drop_hpa_per_m",
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("--exact"), "{text}");
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn interrupt_ends_the_run_with_every_output_written() {
    // Ctrl-C (SIGINT) in the middle of a 60 s run: the run ends within a piece of 500 steps
    // (a last sample where it stopped), writes the summary (status "interrupted at t = …",
    // the simulated time so far), the figures and run.h5, and exits with 130 (the shell's
    // code for an interrupt).
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-interrupt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let case = root.join("cases/vertical_plug.toml");
    let (o, _) = signalled_run(
        &case,
        &out,
        &["--duration", "60", "--set", "output.settling_time=0 s"],
        "-INT",
        2,
    );
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(o.status.code(), Some(130), "{text}");
    assert!(text.contains("interrupted at t ="), "{text}");
    let s: serde_json::Value = common::read_summary(&out);
    let status = s["status"].as_str().unwrap();
    assert!(status.starts_with("interrupted at t ="), "{status}");
    let t = s["simulated_time_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 60.0, "simulated {t} s");
    assert!(out.join("pressure_drop.png").exists());
    assert!(out.join("porosity_tz.png").exists());
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    assert!(
        (time.last().unwrap() - t).abs() < 1e-9,
        "{:?} vs {t}",
        time.last()
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// A run that ends before its settling time has no window to average over: its means are
/// `null` (never 0.0, which reads as a measurement), its target rows unmeasured and outside,
/// and the terminal says so naming both times. (Issue 26: `--duration 2` with a 6 s
/// settling time reported Δp 0.0 and 0.0 grains with 1027 grains in the tube.)
#[test]
fn means_over_an_empty_window_are_null_with_a_warning() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_plug.toml");
    let (code, text, out, s) = common::run_case(
        case.to_str().unwrap(),
        "empty_window",
        &["--duration", "0.05"],
    );
    assert_eq!(code, 0, "{text}");
    assert!(s["particles_in_tube_mean"].is_null(), "{s}");
    assert!(s["pressure_drop_hpa_per_m"].is_null(), "{s}");
    assert!(
        s["particles_final"].as_u64().unwrap() > 0,
        "grains were there: {s}"
    );
    for row in s["targets"].as_array().unwrap() {
        if row["id"] == "V1" || row["id"] == "V2" {
            assert!(row["measured"].is_null() && row["inside"] == false, "{row}");
        }
    }
    assert!(
        text.contains("no sample after the settling time (6 s; the run ended at 0.05"),
        "{text}"
    );
    // The same warning in the summary, for readers that never saw the terminal.
    let warnings = s["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .unwrap()
            .starts_with("no sample after the settling time")),
        "{s}"
    );
    // The inlet fed what the scene asked (rate × 0.05 s, within one slab of grains): no
    // feed warning, and the account is in the summary.
    let asked = s["grains_asked"].as_u64().unwrap();
    assert!(asked > 0, "{s}");
    assert!(
        s["feed_backlog_grains"].as_i64().unwrap().abs() < 100,
        "{s}"
    );
    assert_eq!(warnings.len(), 1, "{s}");
    std::fs::remove_dir_all(&out).ok();
}

/// A run into a folder that holds an older run's outputs first removes them: the old
/// summary cannot survive beside the new run's `run.h5` (issue 26: a killed re-run left a
/// complete old summary beside a shorter new file), nor old snapshots join the new series.
/// Files a run does not write stay.
#[test]
fn a_run_clears_the_previous_run_s_outputs_first() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_dry_feed.toml");
    let out = std::env::temp_dir().join(format!("plugflow_rerun_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(
        out.join("summary.json"),
        "{\"status\": \"completed\", \"old\": true}",
    )
    .unwrap();
    std::fs::write(out.join("particles_999999.vtk"), "old").unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let (code, text) = plugflow(&[
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--duration",
        "0.01",
    ]);
    assert_eq!(code, 0, "{text}");
    let s = common::read_summary(&out);
    assert!(s.get("old").is_none(), "the old summary survived: {s}");
    assert!(!out.join("particles_999999.vtk").exists());
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    std::fs::remove_dir_all(&out).ok();
}

/// SIGTERM stops a run within about a second whatever the sample interval (issue 26: the
/// stop flag was read only at the next sample, minutes away on a long interval); the summary
/// and run.h5 end at the time it stopped.
#[test]
fn sigterm_stops_within_a_second_whatever_the_sample_interval() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-sigterm-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let case = root.join("cases/vertical_plug.toml");
    let (o, took) = signalled_run(
        &case,
        &out,
        &[
            "--duration",
            "20",
            // One sample every 10 s simulated: ~40 s of wall time or more on one thread.
            "--set",
            "output.sample_interval=10 s",
            "--set",
            "output.settling_time=0 s",
            "--set",
            "dem.threads=1",
        ],
        "-TERM",
        1,
    );
    let text = String::from_utf8_lossy(&o.stderr).to_string();
    // A piece is 500 steps (~10 ms here); writing the figures and run.h5 takes the rest.
    // 5 s leaves room for a loaded CI machine; the old behaviour took the whole sample.
    assert!(took < 5.0, "stopped {took:.1} s after SIGTERM: {text}");
    let s: serde_json::Value = common::read_summary(&out);
    let t = s["simulated_time_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 10.0, "simulated {t} s: {s}");
    assert!(
        s["status"]
            .as_str()
            .unwrap()
            .starts_with("interrupted at t ="),
        "{s}"
    );
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    assert!(
        (time.last().unwrap() - t).abs() < 1e-9,
        "{:?} vs {t}",
        time.last()
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// `plugflow run CASE --out OUT ARGS --quiet`, sent `signal` `after` seconds once the run
/// has started (run.h5 exists); its output and the seconds from the signal to its end.
fn signalled_run(
    case: &Path,
    out: &Path,
    args: &[&str],
    signal: &str,
    after: u64,
) -> (std::process::Output, f64) {
    let mut all = vec![
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    all.extend_from_slice(args);
    signalled(&all, &out.join("run.h5"), signal, after)
}

/// `plugflow ARGS`, sent `signal` `after` seconds once `started` exists; its output and the
/// seconds from the signal to its end.
fn signalled(
    args: &[&str],
    started: &Path,
    signal: &str,
    after: u64,
) -> (std::process::Output, f64) {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !started.exists() && start.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(std::time::Duration::from_secs(after));
    let signalled = std::time::Instant::now();
    let killed = std::process::Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    (o, signalled.elapsed().as_secs_f64())
}

/// SIGTERM to a sweep reaches its running variant, which stops with its outputs written; no
/// new variant starts; the sweep writes its table of what finished and exits 130; no child
/// is left running (issue 26: the parent died and its children ran on as orphans).
#[test]
fn sigterm_to_a_sweep_stops_its_children_and_writes_the_table() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-sweep-stop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let case = root.join("cases/vertical_dry_feed.toml");
    let (o, took) = signalled(
        &[
            "sweep",
            case.to_str().unwrap(),
            "--vary",
            "seed=1,2,3",
            "--jobs",
            "1",
            "--duration",
            "60",
            "--out",
            out.to_str().unwrap(),
        ],
        &out.join("000").join("run.h5"),
        "-TERM",
        1,
    );
    let text = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(130), "{text}");
    // The child stops within a second (see the run's own test); 10 s for a loaded machine.
    assert!(took < 10.0, "stopped {took:.1} s after SIGTERM: {text}");
    let s = common::read_summary(&out.join("000"));
    assert!(
        s["status"]
            .as_str()
            .unwrap()
            .starts_with("interrupted at t ="),
        "{s}"
    );
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 3, "{csv}");
    assert!(rows[0].contains("interrupted at t ="), "{csv}");
    for r in &rows[1..] {
        assert!(r.contains("not started (the sweep was stopped)"), "{csv}");
    }
    assert!(
        !out.join("001").exists(),
        "a variant started after the stop"
    );
    let orphans = std::process::Command::new("pgrep")
        .args(["-f", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        orphans.stdout.is_empty(),
        "children still running: {}",
        String::from_utf8_lossy(&orphans.stdout)
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// A tube closed at its far end fills up, its inlet slab blocks, and the engine can no longer
/// feed what `inlet.rate` asks: the summary gives the account (asked, owed) and a warning
/// says so, instead of numbers that silently belong to a smaller feed (issue 26).
#[test]
fn a_blocked_inlet_is_reported_with_what_it_owes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_dry_feed.toml");
    let (code, text, out, s) = common::run_case(
        case.to_str().unwrap(),
        "blocked_inlet",
        &[
            "--duration",
            "0.6",
            "--set",
            "tube.length=\"0.03 m\"",
            "--set",
            "tube.outlet_end=\"closed\"",
            "--set",
            "inlet.mass_flow=\"10 kg/h\"",
            "--set",
            // Fast enough for the slab to carry that feed (the scene check's capacity).
            "inlet.velocity=\"0.2 m/s\"",
            "--set",
            "output.settling_time=\"0.1 s\"",
        ],
    );
    assert_eq!(code, 0, "{text}");
    // 10 kg/h of 1.4 mm grains of 937 kg/m³ is ~2060 grains/s: ~1240 asked in 0.6 s, while
    // 3 cm of the 7 mm tube hold ~500 at random close packing.
    let asked = s["grains_asked"].as_u64().unwrap();
    assert!((1200..1280).contains(&asked), "{s}");
    let owed = s["feed_backlog_grains"].as_i64().unwrap();
    let fed = s["grains_fed"].as_u64().unwrap();
    assert_eq!(owed, asked as i64 - fed as i64, "{s}");
    assert!(owed > 500, "the full tube still took the feed: {s}");
    let warned = s["warnings"].as_array().unwrap().iter().any(|w| {
        w.as_str()
            .unwrap()
            .contains(&format!("of the {asked} grains the inlet asked for"))
    });
    assert!(warned, "{s}");
    assert!(text.contains("warning: the native engine fed"), "{text}");
    std::fs::remove_dir_all(&out).ok();
}

/// A bed at rest in a tube closed below: the grains' forces on the walls carry exactly
/// their weight (Newton: nothing accelerates), split between the cap below and the tube's
/// friction (Janssen), with no net force across. The series is in `run.h5` on every sample.
#[test]
fn wall_forces_carry_the_weight_of_a_bed_at_rest() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_dry_feed.toml");
    let (code, text, out, s) = common::run_case(
        case.to_str().unwrap(),
        "bed_at_rest",
        &[
            "--duration",
            "0.4",
            "--set",
            "tube.length=\"0.05 m\"",
            "--set",
            "tube.outlet_end=\"closed\"",
            "--set",
            "inlet.until=\"0 s\"",
            "--set",
            "initial.count=300",
            "--set",
            "initial.from=\"0 m\"",
            "--set",
            "initial.to=\"0.05 m\"",
            // Settled by 0.25 s (300 grains fall 5 cm in ~0.1 s and come to rest).
            "--set",
            "output.settling_time=\"0.25 s\"",
        ],
    );
    assert_eq!(code, 0, "{text}");
    let m = 937.0 * std::f64::consts::PI / 6.0 * 1.4e-3f64.powi(3);
    let weight = 300.0 * m * 9.81;
    let walls = s["wall_forces_mean_n"].as_object().unwrap();
    let sum = |k: usize| -> f64 { walls.values().map(|f| f[k].as_f64().unwrap()).sum() };
    // 1 %: the bed still creeps (the mean over 0.15 s of samples); measured 0.1 %.
    assert!(
        (sum(2) + weight).abs() < 0.01 * weight,
        "{walls:?} vs {weight}"
    );
    assert!(
        sum(0).abs() < 0.01 * weight && sum(1).abs() < 0.01 * weight,
        "{walls:?}"
    );
    // The tube (down its axis, the flow direction) holds part, the cap below the rest.
    let tube = &s["tube_wall_force_mean_n"];
    let axial = tube["axial"].as_f64().unwrap();
    assert!(axial > 0.02 * weight && axial < weight, "{tube}");
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    let series = f.dataset("walls/tube").unwrap();
    assert_eq!(series.shape(), vec![time.len(), 3]);
    let along: Vec<f64> = f.dataset("walls/tube_axial").unwrap().read_raw().unwrap();
    assert_eq!(along.len(), time.len());
    std::fs::remove_dir_all(&out).ok();
}

/// Out of room (here the file-size limit, `ulimit -f`, which needs no root; a full disk is
/// checked the same way with statvfs): the run stops with a message naming the file and why,
/// exit 1, the summary written with status `failed: …` and `run.h5` readable, ending where
/// the summary says (issue 26: a full disk segfaulted in H5D_close and left an unreadable
/// file).
#[test]
fn out_of_room_the_run_stops_with_run_h5_readable() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("plugflow-room-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let case = root.join("cases/vertical_plug.toml");
    // 1.5 MiB: run.h5 reaches ~0.4 MB in ~0.5 s simulated, then the 1 MiB reserve and the
    // next chunk no longer fit. SIGXFSZ ignored (inherited across exec): a write beyond the
    // limit fails with EFBIG, as a write to a full disk fails with ENOSPC.
    let script = format!(
        "trap '' XFSZ; ulimit -f 1536; exec '{}' run '{}' --out '{}' --duration 5 --quiet \
         --set 'output.settling_time=\"0.2 s\"'",
        env!("CARGO_BIN_EXE_plugflow"),
        case.display(),
        out.display()
    );
    let o = std::process::Command::new("bash")
        .args(["-c", &script])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains("file-size limit"), "{text}");
    let s = common::read_summary(&out);
    let status = s["status"].as_str().unwrap();
    assert!(status.starts_with("failed: cannot write"), "{status}");
    let t = s["simulated_time_s"].as_f64().unwrap();
    assert!(t > 0.1 && t < 5.0, "{s}");
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    assert!(
        (time.last().unwrap() - t).abs() < 1e-9,
        "{:?} vs {t}",
        time.last()
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// `validate` prints the steps a scene needs and warns far beyond what the shipped cases
/// need (here 5000 s at the vertical case's 3.33 µs, t_c/30: 1.5e9 steps), still exit 0: it
/// may be meant.
#[test]
fn validate_prints_the_steps_and_warns_far_beyond_reason() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = root.join("cases/vertical_plug.toml");
    let (code, text) = common::plugflow(&["validate", case.to_str().unwrap()]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("steps: 3.600e6 for 12 s simulated"), "{text}");
    assert!(!text.contains("warning"), "{text}");
    let (code, text) = common::plugflow(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "duration=\"5000 s\"",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("steps: 1.500e9"), "{text}");
    assert!(
        text.contains("warning: 1.500e9 steps is far beyond"),
        "{text}"
    );
}
