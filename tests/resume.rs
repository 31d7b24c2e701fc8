//! Checkpoints and `plugflow run --resume` (issue 23, item 1): a run resumed from a
//! checkpoint is bit for bit the uninterrupted run (built-in engine, fixed threads) —
//! `summary.json` (all but wall times) and every dataset of `run.h5` — whether the first
//! part ended normally or was killed with SIGKILL between checkpoints; and a checkpoint of
//! another scene, a truncated one and one of another format are refused, naming why.

mod common;
use common::{plugflow, read_summary};
use std::path::{Path, PathBuf};

const INTERVAL: &str = "output.checkpoint_interval=0.05 s";
/// Snapshots in both formats every 0.05 s, so the resumed run must also cut back and go on
/// with the snapshot groups of `run.h5` and the `.pvd` series.
const SNAPSHOTS: &str = r#"output.snapshots={interval="0.05 s", formats=["hdf5","vtk"]}"#;
/// The plug statistics and means start at once, so the accumulators are exercised.
const SETTLE: &str = "output.settling_time=0.02 s";

fn case(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases")
        .join(name)
        .display()
        .to_string()
}

fn fresh(tag: &str) -> PathBuf {
    let out = std::env::temp_dir().join(format!("plugflow_resume_{tag}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    out
}

/// `plugflow run SCENE --out OUT --quiet --duration D --set …` plus `extra`.
fn run(scene: &str, out: &Path, duration: &str, sets: &[&str], extra: &[&str]) -> (i32, String) {
    let mut args = vec![
        "run",
        scene,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--duration",
        duration,
    ];
    for s in sets {
        args.extend(["--set", s]);
    }
    args.extend_from_slice(extra);
    plugflow(&args)
}

/// The summary without what depends on the wall clock.
fn physics(out: &Path) -> serde_json::Value {
    let mut s = read_summary(out);
    let m = s.as_object_mut().unwrap();
    for key in WALL_CLOCK {
        m.remove(key);
    }
    s
}

/// Summary keys measured by the wall clock (the only ones a resumed run may change).
const WALL_CLOCK: [&str; 2] = ["wall_time_s", "stage_times_s"];

/// Every dataset of `run.h5` (path → raw bits), attributes of the snapshot groups too.
fn h5_bits(path: &Path) -> Vec<(String, Vec<u64>)> {
    fn walk(g: &hdf5::Group, prefix: &str, out: &mut Vec<(String, Vec<u64>)>) {
        let mut names = g.member_names().unwrap();
        names.sort();
        for n in names {
            let p = format!("{prefix}/{n}");
            if let Ok(sub) = g.group(&n) {
                for a in ["time", "step"] {
                    if let Ok(attr) = sub.attr(a) {
                        let v: f64 = attr.read_scalar().unwrap();
                        out.push((format!("{p}@{a}"), vec![v.to_bits()]));
                    }
                }
                walk(&sub, &p, out);
            } else {
                let d = g.dataset(&n).unwrap();
                let bits = match d.read_raw::<f64>() {
                    Ok(v) => v.iter().map(|x| x.to_bits()).collect(),
                    Err(_) => d.read_raw::<u64>().unwrap(),
                };
                out.push((p, bits));
            }
        }
    }
    let f = hdf5::File::open(path).unwrap();
    let mut out = Vec::new();
    walk(&f, "", &mut out);
    out
}

/// The checkpoint files of a run folder, oldest first.
fn checkpoints(out: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(out.join("checkpoints"))
        .map(|d| {
            d.flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "pfc"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn assert_same_run(straight: &Path, resumed: &Path, what: &str) {
    assert_eq!(
        physics(straight),
        physics(resumed),
        "{what}: summaries differ"
    );
    let (a, b) = (
        h5_bits(&straight.join("run.h5")),
        h5_bits(&resumed.join("run.h5")),
    );
    let names = |v: &[(String, Vec<u64>)]| v.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&a), names(&b), "{what}: run.h5 layouts differ");
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(
            x == y,
            "{what}: run.h5 `{name}` differs ({} vs {} values)",
            x.len(),
            y.len()
        );
    }
    let text = |d: &Path, f: &str| std::fs::read_to_string(d.join(f)).unwrap();
    for f in [
        "timeseries.csv",
        "particles.pvd",
        "gas.pvd",
        "run.xdmf",
        "slug.csv",
    ] {
        // (`gas.pvd` only for a run with gas, `slug.csv` for a periodic section: then both
        // have it.)
        if (f == "gas.pvd" || f == "slug.csv") && !straight.join(f).exists() {
            assert!(!resumed.join(f).exists(), "{what}: {f} in one run only");
            continue;
        }
        assert_eq!(text(straight, f), text(resumed, f), "{what}: {f} differs");
    }
    for k in 0..4 {
        let f = format!("particles_{k:06}.vtp");
        assert!(
            std::fs::read(straight.join(&f)).unwrap() == std::fs::read(resumed.join(&f)).unwrap(),
            "{what}: {f} differs"
        );
    }
}

/// The coupled vertical case (d'Arcy gas, inlet, two threads) for 0.2 s: straight; 0.1 s
/// then resumed to 0.2 s; and killed (SIGKILL) after its first checkpoint, then resumed.
#[test]
fn a_resumed_run_is_the_uninterrupted_run_bit_for_bit() {
    let scene = case("vertical_plug.toml");
    let sets = [INTERVAL, SNAPSHOTS, SETTLE];
    let straight = fresh("straight");
    let (code, text) = run(&scene, &straight, "0.2", &sets, &[]);
    assert_eq!(code, 0, "{text}");

    // Stopped at its end (0.1 s), then taken on to 0.2 s in the same folder.
    let parts = fresh("parts");
    let (code, text) = run(&scene, &parts, "0.1", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let resume = ["--resume", parts.to_str().unwrap()];
    let (code, text) = run(&scene, &parts, "0.2", &sets, &resume);
    assert_eq!(code, 0, "{text}");
    assert_same_run(&straight, &parts, "0.1 s + resumed 0.1 s");
    let log = std::fs::read_to_string(parts.join("log.plugflow")).unwrap();
    assert!(log.contains("resumed from"), "{log}");

    // Killed between checkpoints: the outputs hold samples past the checkpoint, which the
    // resumed run cuts off.
    let killed = fresh("killed");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .args(["run", &scene, "--out", killed.to_str().unwrap(), "--quiet"])
        .args(["--duration", "0.2"])
        .args(sets.iter().flat_map(|s| ["--set", s]))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while checkpoints(&killed).is_empty() {
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        assert!(
            started.elapsed().as_secs() < 300,
            "no checkpoint after 300 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    // (Past the first sample after it: the outputs then hold more than the checkpoint.)
    let csv = killed.join("timeseries.csv");
    while std::fs::read_to_string(&csv).unwrap().lines().count() < 7 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(
        !killed.join("summary.json").exists(),
        "the run was not killed part-way"
    );
    let resume = ["--resume", killed.to_str().unwrap()];
    let (code, text) = run(&scene, &killed, "0.2", &sets, &resume);
    assert_eq!(code, 0, "{text}");
    assert_same_run(
        &straight,
        &killed,
        "killed after its first checkpoint, resumed",
    );

    // The last two checkpoints are kept: 0.15 s and the end's 0.2 s (named by step).
    let steps = read_summary(&straight)["steps"].as_u64().unwrap();
    let kept = checkpoints(&straight);
    let names: Vec<String> = kept
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            format!("checkpoint_{:012}.pfc", steps / 4 * 3),
            format!("checkpoint_{steps:012}.pfc")
        ]
    );
    for d in [straight, parts, killed] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// The SIMPLE gas (its velocities, densities and mass memory) resumes to the same bits.
#[test]
fn a_resumed_simple_gas_run_is_the_uninterrupted_run_bit_for_bit() {
    let scene = case("vertical_plug_simple.toml");
    let sets = [INTERVAL, SNAPSHOTS, SETTLE, "dem.threads=1"];
    let straight = fresh("simple_straight");
    let (code, text) = run(&scene, &straight, "0.2", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let parts = fresh("simple_parts");
    let (code, text) = run(&scene, &parts, "0.1", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let resume = ["--resume", parts.to_str().unwrap()];
    let (code, text) = run(&scene, &parts, "0.2", &sets, &resume);
    assert_eq!(code, 0, "{text}");
    assert_same_run(&straight, &parts, "SIMPLE gas, 0.1 s + resumed 0.1 s");
    for d in [straight, parts] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// What cannot be resumed is refused (exit 2) with the reason: another scene (naming the
/// field that differs), a truncated file, another format, a damaged one, a folder without
/// the run's outputs, no checkpoint at all.
#[test]
fn checkpoints_that_do_not_fit_are_refused_naming_why() {
    let scene = case("vertical_plug.toml");
    let out = fresh("refusals");
    let (code, text) = run(
        &scene,
        &out,
        "0.02",
        &["output.checkpoint_interval=0.01 s"],
        &[],
    );
    assert_eq!(code, 0, "{text}");
    let latest = checkpoints(&out).pop().expect("a checkpoint at the end");
    let resume_from = |file: &Path, sets: &[&str]| {
        let mut all = vec!["output.checkpoint_interval=0.01 s"];
        all.extend_from_slice(sets);
        let again = fresh("refusals_again");
        let r = run(
            &scene,
            &again,
            "0.04",
            &all,
            &["--resume", file.to_str().unwrap()],
        );
        std::fs::remove_dir_all(again).ok();
        r
    };
    let (code, text) = resume_from(&out, &["particles.density=950 kg/m^3"]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("another scene") && text.contains("particles.density"),
        "{text}"
    );

    // A conveyor-fed run (the case's inlet) is not resumed by the slab inlet (its column
    // would be dropped).
    let (code, text) = resume_from(&out, &[r#"inlet.mode="slab""#]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("inlet.mode"), "{text}");

    let bytes = std::fs::read(&latest).unwrap();
    let cut = out.join("cut.pfc");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let (code, text) = resume_from(&cut, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("truncated"), "{text}");

    let mut other = bytes.clone();
    other[8..12].copy_from_slice(&99u32.to_le_bytes());
    let old = out.join("other_format.pfc");
    std::fs::write(&old, &other).unwrap();
    let (code, text) = resume_from(&old, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("format 99"), "{text}");

    let mut damaged = bytes;
    let k = damaged.len() - 10;
    damaged[k] ^= 0xff;
    let bad = out.join("damaged.pfc");
    std::fs::write(&bad, &damaged).unwrap();
    let (code, text) = resume_from(&bad, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("checksum"), "{text}");

    // Into another folder, which does not hold the run's outputs to go on with.
    let (code, text) = resume_from(&latest, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("are not in") && text.contains("--from"),
        "{text}"
    );

    let empty = fresh("refusals_empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (code, text) = resume_from(&empty, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("no checkpoint there"), "{text}");
    for d in [out, empty] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// `run --from`: a new run starts from another run's grains and gas at t = 0 with its own
/// settings. Nothing is lost or made on the way: the grains it ends with are the ones it
/// took over plus its own feed less its own outflow. A checkpoint from another tube is
/// refused naming the field.
#[test]
fn a_run_starts_from_another_runs_filled_tube() {
    let scene = case("vertical_plug.toml");
    let filled = fresh("filled");
    let (code, text) = run(&scene, &filled, "0.1", &[INTERVAL], &[]);
    assert_eq!(code, 0, "{text}");
    let taken = read_summary(&filled)["particles_final"].as_u64().unwrap();
    assert!(taken > 20, "{taken} grains");

    let next = fresh("from_filled");
    let from = ["--from", filled.to_str().unwrap()];
    let (code, text) = run(&scene, &next, "0.05", &["contact.friction=0.3"], &from);
    assert_eq!(code, 0, "{text}");
    let s = read_summary(&next);
    let n = |k: &str| s[k].as_u64().unwrap_or_else(|| panic!("{k}: {s}"));
    assert!(
        (s["simulated_time_s"].as_f64().unwrap() - 0.05).abs() < 1e-9,
        "{s}"
    );
    assert_eq!(
        n("particles_final"),
        taken + n("grains_fed") - n("grains_out") - n("grains_lost"),
        "{s}"
    );
    // Its own feed only: the case's conveyor starts a fresh column below the inlet, whose
    // grains enter once their centre is one radius in: 12 850 grains per m of column ×
    // (0.04 m/s × 0.05 s − 0.7 mm) ≈ 17, within 3σ (25) of the Poisson count of the
    // 4-diameter block the entry line crosses (~72 grains); its first layer may meet the
    // held grains the tube already had there (counted as owed, not fed).
    assert!((1..45).contains(&n("grains_fed")), "{s}");
    let log = std::fs::read_to_string(next.join("log.plugflow")).unwrap();
    assert!(log.contains(&format!("{taken} grains")), "{log}");
    // The list's counts are this run's own: every append joins at least one fed grain, so
    // appends ≤ grains fed (the filled run's 30-odd appends carried over would break it),
    // and its first build is counted.
    let f = |k: &str| s[k].as_f64().unwrap_or_else(|| panic!("{k}: {s}"));
    assert!(f("neighbor_appends") <= f("grains_fed"), "{s}");
    assert!(f("neighbor_builds") >= 1.0, "{s}");

    let other = fresh("from_other_tube");
    let (code, text) = run(&scene, &other, "0.05", &["tube.diameter=\"8 mm\""], &from);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("tube.diameter"), "{text}");
    for d in [filled, next, other] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// A sweep re-run into its folder skips the variants that finished and resumes the others
/// from their own checkpoints (here one whose summary is gone, as after a kill: it resumes
/// at its end and writes the same summary); `sweep --from` starts every variant from one
/// filled tube.
#[test]
fn a_sweep_rerun_skips_finished_variants_and_resumes_the_rest() {
    let scene = case("vertical_plug.toml");
    let out = fresh("sweep");
    let sweep_of = |scene: &str, extra: &[&str]| {
        let mut args = vec![
            "sweep",
            scene,
            "--vary",
            "contact.friction=0.3,0.5",
            "--duration",
            "0.05",
            "--set",
            INTERVAL,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        plugflow(&args)
    };
    let sweep = |extra: &[&str]| sweep_of(&scene, extra);
    let (code, text) = sweep(&[]);
    assert_eq!(code, 0, "{text}");
    let before = physics(&out.join("001"));
    std::fs::remove_file(out.join("001/summary.json")).unwrap();
    let (code, text) = sweep(&[]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("skip  000"), "{text}");
    assert!(text.contains("resume 001"), "{text}");
    assert_eq!(
        physics(&out.join("001")),
        before,
        "the resumed variant's summary"
    );
    // The same settings on an edited scene file are other variants: none is skipped.
    let edited = out.with_extension("edited.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&edited, text.replacen("seed = 1", "seed = 2", 1)).unwrap();
    let (code, text) = sweep_of(edited.to_str().unwrap(), &[]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("start 000") && text.contains("start 001"),
        "{text}"
    );
    std::fs::remove_file(&edited).ok();

    let filled = fresh("sweep_filled");
    let (code, text) = run(&scene, &filled, "0.1", &[INTERVAL], &[]);
    assert_eq!(code, 0, "{text}");
    let (code, text) = sweep(&["--from", filled.to_str().unwrap()]);
    assert_eq!(code, 0, "{text}");
    for k in ["000", "001"] {
        assert!(
            text.contains(&format!("start {k}")),
            "another start: {text}"
        );
        let log = std::fs::read_to_string(out.join(k).join("log.plugflow")).unwrap();
        assert!(log.contains("started from"), "{log}");
    }
    for d in [out, filled] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// Periodic tube sections (grains across the seam with their image shifts and contact
/// histories, rolling resistance; and one with the d'Arcy gas under its flow controller,
/// whose driving gradient the checkpoint keeps) resume to the same bits.
#[test]
fn a_resumed_periodic_section_is_the_uninterrupted_run_bit_for_bit() {
    for (name, tag) in [
        ("periodic_tube_section.toml", "dem"),
        ("periodic_vertical_section_gas.toml", "gas"),
    ] {
        let scene = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/scenes/good")
            .join(name)
            .display()
            .to_string();
        let sets = [INTERVAL, SNAPSHOTS, SETTLE, "dem.threads=2"];
        let straight = fresh(&format!("periodic_{tag}_straight"));
        let (code, text) = run(&scene, &straight, "0.2", &sets, &[]);
        assert_eq!(code, 0, "{text}");
        let parts = fresh(&format!("periodic_{tag}_parts"));
        let (code, text) = run(&scene, &parts, "0.1", &sets, &[]);
        assert_eq!(code, 0, "{text}");
        let resume = ["--resume", parts.to_str().unwrap()];
        let (code, text) = run(&scene, &parts, "0.2", &sets, &resume);
        assert_eq!(code, 0, "{text}");
        assert_same_run(&straight, &parts, &format!("{name}, 0.1 s + resumed 0.1 s"));
        for d in [straight, parts] {
            std::fs::remove_dir_all(d).ok();
        }
    }
}

/// The conveyor inlet (`inlet.mode = "conveyor"`): its column below the tube and the grains
/// it holds come back from a checkpoint, so a resumed run feeds the same grains; and a
/// conveyor run started from a tube a slab inlet filled takes the grains in its slab into
/// the column and loses none.
#[test]
fn a_resumed_conveyor_run_is_the_uninterrupted_run_bit_for_bit() {
    let scene = case("vertical_plug.toml");
    let conveyor = r#"inlet.mode="conveyor""#;
    let sets = [INTERVAL, SNAPSHOTS, SETTLE, conveyor];
    let straight = fresh("conveyor_straight");
    let (code, text) = run(&scene, &straight, "0.2", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let parts = fresh("conveyor_parts");
    let (code, text) = run(&scene, &parts, "0.1", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let resume = ["--resume", parts.to_str().unwrap()];
    let (code, text) = run(&scene, &parts, "0.2", &sets, &resume);
    assert_eq!(code, 0, "{text}");
    assert_same_run(&straight, &parts, "conveyor, 0.1 s + resumed 0.1 s");

    // A slab-fed tube taken on by the conveyor.
    let filled = fresh("conveyor_filled");
    let (code, text) = run(&scene, &filled, "0.1", &[INTERVAL], &[]);
    assert_eq!(code, 0, "{text}");
    let taken = read_summary(&filled)["particles_final"].as_u64().unwrap();
    let next = fresh("conveyor_from_filled");
    let from = ["--from", filled.to_str().unwrap()];
    let (code, text) = run(&scene, &next, "0.1", &[conveyor], &from);
    assert_eq!(code, 0, "{text}");
    let s = read_summary(&next);
    let n = |k: &str| s[k].as_u64().unwrap_or_else(|| panic!("{k}: {s}"));
    assert_eq!(
        n("particles_final"),
        taken + n("grains_fed") - n("grains_out") - n("grains_lost"),
        "{s}"
    );
    // 0.1 s of 2.49 kg/h of 1.35e-6 kg grains is 51.4 grains; the column's grains enter
    // as its packing brings them to the inlet end, ±3σ of a block's Poisson count (72
    // grains per 4-diameter block at 12 850 grains per metre: ±25).
    assert!((26..77).contains(&n("grains_fed")), "{s}");
    for d in [straight, parts, filled, next] {
        std::fs::remove_dir_all(d).ok();
    }
}

/// A checkpoint written before the built-in engine kept the list's upkeep counts (its
/// format 1: `tests/scenes/format1/checkpoint_format1.pfc`, the vertical case at 0.01 s,
/// written by build 41c6c18) is still read. Resumed, the run goes on and its summary leaves
/// the counts out (what they were before the resume is unknown: not reported as the part
/// since), also when resumed again from its own later checkpoint; started from with
/// `--from`, the counts are the new run's own.
#[test]
fn a_format_1_checkpoint_is_resumed_and_started_from() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/format1");
    let scene = dir.join("vertical_plug.toml").display().to_string();
    let old = dir.join("checkpoint_format1.pfc");
    let sets = ["output.checkpoint_interval=0.01 s"];

    // The run's outputs up to 0.01 s, written by this build, with its checkpoint there
    // replaced by the format-1 one of the same state.
    let parts = fresh("format1_parts");
    let (code, text) = run(&scene, &parts, "0.01", &sets, &[]);
    assert_eq!(code, 0, "{text}");
    let ours = checkpoints(&parts).pop().expect("a checkpoint at 0.01 s");
    assert!(ours.ends_with("checkpoint_000000003000.pfc"), "{ours:?}");
    std::fs::copy(&old, &ours).unwrap();
    let resume = ["--resume", parts.to_str().unwrap()];
    // Resumed to `until` s: the run reaches it, builds are counted, the upkeep counts are
    // left out (unknown before the format-1 part).
    let resumed_without_counts = |until: &str, what: &str| {
        let (code, text) = run(&scene, &parts, until, &sets, &resume);
        assert_eq!(code, 0, "{what}: {text}");
        let s = read_summary(&parts);
        let t: f64 = until.parse().unwrap();
        assert!(
            (s["simulated_time_s"].as_f64().unwrap() - t).abs() < 1e-9,
            "{what}: {s}"
        );
        assert!(s["neighbor_builds"].as_f64().is_some(), "{what}: {s}");
        for key in ["neighbor_refreshes", "neighbor_appends"] {
            assert!(s.get(key).is_none(), "{key} reported after {what}: {s}");
        }
    };
    resumed_without_counts("0.03", "a format-1 resume");
    // Resumed once more, from its own checkpoint at 0.03 s (this build's format): still
    // unknown, not the part since the first resume.
    resumed_without_counts("0.04", "a second resume");

    let next = fresh("format1_from");
    let from = ["--from", old.to_str().unwrap()];
    let (code, text) = run(&scene, &next, "0.02", &[], &from);
    assert_eq!(code, 0, "{text}");
    let s = read_summary(&next);
    let f = |k: &str| s[k].as_f64().unwrap_or_else(|| panic!("{k}: {s}"));
    assert!(f("neighbor_appends") <= f("grains_fed"), "{s}");
    assert!(f("neighbor_builds") >= 1.0, "{s}");
    for d in [parts, next] {
        std::fs::remove_dir_all(d).ok();
    }
}
