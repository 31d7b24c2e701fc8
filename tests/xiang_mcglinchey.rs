//! Seed 004's horizontal dense-phase pipe, CI-sized (`cases/xiang_mcglinchey_short.toml`: the
//! 80 mm pipe's first 2 m for 2 s, quasi-2D slab, SIMPLE + Ergun/Wen–Yu, ideal gas), run
//! end to end through the CLI. The paper describes what happens (§4): fed grains pile up at
//! the pipe's bottom into dunes; a dune that reaches the pipe's top is pushed on by the gas as
//! a plug; later (5.2 s, 4.2 m along its pipe) a plug collapses into a stationary layer. The
//! first test reads the particle snapshots of run.h5 and checks the first two, the slab holding
//! the grains, and the pressure transducers' output; the second closes the feeder valve early
//! and checks the third, a plug collapsing into a stationary layer. (The full case, 8 m and
//! 18 s, is cases/xiang_mcglinchey.toml; its DP1 trace against the paper's 25 mbar peaks is in
//! cases/README.md.)

mod common;

use std::path::PathBuf;

use ndarray::Array2;

/// Pipe diameter and grain diameter of the case, m.
const PIPE_D: f64 = 0.08;
const GRAIN_D: f64 = 3e-3;
/// The pipe is looked at in 16 mm stretches (a gas cell's length) ...
const STRETCH: f64 = 0.016;
const STRETCHES: usize = 125;
/// ... past the first 10 cm (7 stretches), where the inlet places grains across the section.
const FEED_ZONE: usize = 7;

/// Run the short case with extra CLI arguments into a fresh directory named by `tag`; checks
/// it completed without losing a grain and returns the directory and summary.json.
fn run_short_case(tag: &str, extra: &[&str]) -> (PathBuf, serde_json::Value) {
    let case = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/cases/xiang_mcglinchey_short.toml"
    );
    let (code, text, out, summary) = common::run_case(case, tag, extra);
    assert_eq!(code, 0, "{text}");
    assert_eq!(summary["status"], "completed", "{summary}");
    assert_eq!(summary["grains_lost"].as_f64().unwrap(), 0.0, "{summary}");
    (out, summary)
}

/// The particle snapshots of run.h5 in time order: (time, positions, velocities).
fn snapshots(out: &std::path::Path) -> Vec<(f64, Array2<f64>, Array2<f64>)> {
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let mut names = f.group("particles").unwrap().member_names().unwrap();
    names.sort();
    names
        .iter()
        .map(|name| {
            let g = f.group(&format!("particles/{name}")).unwrap();
            (
                g.attr("time").unwrap().read_scalar().unwrap(),
                g.dataset("position").unwrap().read_2d().unwrap(),
                g.dataset("velocity").unwrap().read_2d().unwrap(),
            )
        })
        .collect()
}

/// Height of the pile's top above the pipe's bottom in each stretch (0 where empty), m.
fn pile_heights(x: &Array2<f64>) -> Vec<f64> {
    let mut height = vec![0.0_f64; STRETCHES];
    for row in x.rows() {
        let k = (row[0] / STRETCH) as usize;
        if k < STRETCHES {
            height[k] = height[k].max(row[2] + 0.5 * GRAIN_D + 0.5 * PIPE_D);
        }
    }
    height
}

/// The first stretch past the feed zone that starts three in a row (48 mm) piled to at
/// least `fill` m.
fn filled_run(height: &[f64], fill: f64) -> Option<usize> {
    (FEED_ZONE..STRETCHES - 2).find(|&k| height[k..k + 3].iter().all(|&h| h >= fill))
}

#[test]
fn dunes_grow_at_the_bottom_into_plugs_the_gas_pushes_on() {
    let (out, summary) = run_short_case("xm", &[]);
    // The feed is never blocked: 0.0677 kg/s of 3 mm nylon is 4221 grains/s for 2 s.
    let fed = summary["grains_fed"].as_f64().unwrap();
    assert!((fed / (2.0 * 4221.0) - 1.0).abs() < 0.01, "fed {fed}");

    let (d, slab) = (GRAIN_D, 3.3e-3);
    let frames = snapshots(&out);
    // Snapshots every 0.05 s: a dune stands at the top (three stretches in a row within a
    // grain of it) for about one such interval before the gas moves it on, so snapshots
    // 0.1 s apart caught it in one frame of the run or in none, as the chaos of the flow
    // fell (session 22: seed 1 caught it at 1.2 s on one build and not on the next, whose
    // gas differs only within the SIMPLE tolerance; every 0.05 s, seeds 1 and 2 at one
    // thread and seed 1 at two caught it at 1.15–1.4 s).
    assert_eq!(frames.len(), 40, "snapshots every 0.05 s");
    let mut plug_seen = None;
    let mut dune_frames = 0;
    let mut last = None;
    for (t, x, v) in frames {
        // The slab holds every grain: |y| ≤ (slab − d)/2, plus a contact's overlap (the
        // Hertz overlap under a plug's load is well under 1 % of d).
        for row in x.rows() {
            assert!(
                row[1].abs() <= 0.5 * (slab - d) + 0.01 * d,
                "t = {t}: grain at y = {} outside the slab",
                row[1]
            );
        }
        // A plug: three stretches in a row filled to within a grain of the top.
        if let Some(k) = filled_run(&pile_heights(&x), PIPE_D - d) {
            plug_seen.get_or_insert((t, k as f64 * STRETCH));
        }
        // Until then the grains past the feed zone lie at the bottom, a dune: more than
        // two thirds in the pipe's lower half (a suspension would fill both halves alike;
        // two thirds leaves room for the dune's crest above the axis).
        if plug_seen.is_none() {
            let past: Vec<f64> = x
                .rows()
                .into_iter()
                .filter(|r| r[0] > 0.1)
                .map(|r| r[2])
                .collect();
            if past.len() >= 100 {
                let low = past.iter().filter(|&&z| z < 0.0).count() as f64 / past.len() as f64;
                assert!(
                    low > 2.0 / 3.0,
                    "t = {t}: {low:.2} of the grains past 0.1 m in the lower half"
                );
                dune_frames += 1;
            }
        }
        last = Some((t, x, v));
    }
    assert!(
        dune_frames >= 3,
        "{dune_frames} snapshots of the dune phase"
    );
    let (t_plug, x_plug) = plug_seen.expect("no dune ever reached the pipe's top");
    println!("first plug past the feed zone: t = {t_plug:.2} s at x = {x_plug:.3} m");
    // In the last snapshot the grains on the whole are conveyed. (The paper's stationary
    // layer, left by a slug that collapses: the next test.)
    let (t, x, v) = last.unwrap();
    let n = x.nrows();
    let mean_vx = (0..n).map(|i| v[[i, 0]]).sum::<f64>() / n as f64;
    println!("t = {t:.2} s: {n} grains, mean v_x {mean_vx:.2} m/s");
    assert!(mean_vx > 0.2, "mean axial velocity {mean_vx} m/s");

    // The transducers: one row per sample, Δp falling downstream on average, the plugs
    // passing as peaks.
    let csv = std::fs::read_to_string(out.join("pressure_taps.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "time_s,first_metre_pa,pipe_pa");
    assert_eq!(lines.count(), 200);
    assert!(out.join("pressure_taps.png").exists());
    let taps = summary["pressure_taps"].as_array().unwrap();
    for tap in taps {
        assert!(tap["mean_pa"].as_f64().unwrap() > 0.0, "{tap}");
        assert!(tap["peaks"].as_u64().unwrap() >= 1, "{tap}");
    }
    println!(
        "{}",
        serde_json::to_string_pretty(&summary["pressure_taps"]).unwrap()
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// The paper's stationary layer: a plug the gas can no longer drive collapses, its grains
/// settle at the pipe's bottom and stay there under the gas stream. In the paper a plug
/// collapses while the feed runs (5.2 s, 4.2 m along its 8 m pipe); in ours the whole layer
/// keeps moving while fed (cases/README.md), and the collapse comes when the feeder valve
/// closes: the short case with the valve closed at 1.2 s, run to 3 s. Measured (one thread):
/// a slug filled to 75.6 mm of the 80 mm pipe over ≥ 48 mm (not quite closed: a gap of about
/// a grain and a half stays at the top) at 0.5–0.8 m at 1.1–1.4 s, carried on (mean grain
/// position 0.44 → 0.81 m), gone by 1.6 s; at 3 s 99.9 % of the grains below 0.02 m/s, the
/// layer 22 mm deep on average and nowhere above 39 mm.
#[test]
fn a_slug_left_without_feed_collapses_into_a_stationary_layer() {
    let valve_closes = 1.2;
    let (out, _) = run_short_case(
        "xm_layer",
        &[
            "--duration",
            "3",
            "--set",
            "inlet.until=1.2 s",
            // One thread: the dune test above runs beside this one on two.
            "--set",
            "dem.threads=1",
        ],
    );
    let pipe_d = PIPE_D;
    let mut slug_after_valve = None;
    let mut mean_x_at_valve = None;
    let mut last = None;
    for (t, x, v) in snapshots(&out) {
        let height = pile_heights(&x);
        let mean_x = x.column(0).mean().unwrap_or(0.0);
        if t >= valve_closes - 1e-9 {
            mean_x_at_valve.get_or_insert(mean_x);
            // A slug: three stretches in a row (48 mm) filled to 90 % of the pipe's height
            // (measured 75.6 mm = 0.945 D).
            if filled_run(&height, 0.9 * pipe_d).is_some() {
                slug_after_valve = Some(t);
            }
        }
        last = Some((t, height, mean_x, v));
    }
    let t_slug = slug_after_valve.expect("no slug after the valve closed");
    let (t, height, mean_x, v) = last.unwrap();
    println!("last slug seen at {t_slug:.2} s; state at {t:.2} s:");
    assert!(t > 2.8, "last snapshot at {t} s");
    // The slug collapsed: nothing past the feed zone stands higher than 0.6 D (the slug
    // filled 0.9 D and more; measured 39 mm = 0.49 D) ...
    let highest = height[FEED_ZONE..].iter().cloned().fold(0.0, f64::max);
    println!("  highest pile {:.1} mm", highest * 1e3);
    assert!(highest < 0.6 * pipe_d, "a pile {highest} m high remains");
    // ... into a layer that covers the bottom (at least 0.1 D deep on average from the feed
    // zone to the farthest grain; measured 22 mm) ...
    let front = height.iter().rposition(|&h| h > 0.0).unwrap();
    let layer = &height[FEED_ZONE..=front];
    let depth = layer.iter().sum::<f64>() / layer.len() as f64;
    println!(
        "  layer {:.1} mm deep on average to {:.2} m",
        depth * 1e3,
        front as f64 * STRETCH
    );
    assert!(depth > 0.1 * pipe_d, "layer {depth} m deep");
    // ... after the gas carried the slug on (the grains' mean position moved ≥ 0.2 m;
    // measured 0.38 m) ...
    let moved = mean_x - mean_x_at_valve.unwrap();
    println!("  mean grain position moved {moved:.2} m after the valve closed");
    assert!(moved > 0.2, "the grains moved {moved} m");
    // ... and the layer is stationary: ≥ 95 % of the grains slower than 0.02 m/s (half a
    // percent of the gas speed, a grain diameter in 0.15 s; measured 99.9 %).
    let n = v.nrows();
    let resting = v
        .rows()
        .into_iter()
        .filter(|r| (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt() < 0.02)
        .count() as f64
        / n as f64;
    println!("  {resting:.3} of {n} grains at rest");
    assert!(resting >= 0.95, "{resting} of the grains at rest");
    let _ = std::fs::remove_dir_all(&out);
}
