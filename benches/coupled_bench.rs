//! The whole coupled run on each engine: `cases/vertical_plug.toml` (the d'Arcy gas, the
//! inlet feeding from t = 0; the tangential law `history`, which all three engines have) for
//! 1 s simulated on `native`, `liggghts` and `yade`, one thread
//! each, the same scene through the same coupler (`setup::build` → `Coupler::advance`). Prints
//! per engine the particle-steps per second of the coupled run (grains × DEM steps summed over
//! the coupling intervals, over the wall time), the share of the wall spent in the engine's
//! calls (all but the coupler's own stages), and last the ratios native/liggghts and
//! native/yade: the number a user compares when choosing an engine. Not a test: numbers depend
//! on the machine.
//!
//! cargo bench --bench coupled_bench [-- --duration S] [--repeat R] [--engines a,b,c]
//! [--set path=value ...] (overrides of the scene for every engine, e.g.
//! `--set inlet.mode=slab` to time the slab inlet against the case's conveyor)
//! (`--repeat R`: each engine R times, interleaved, medians reported; the ABI engines need
//! their shims: `cargo build --release --workspace --features
//! plugflow-dem-liggghts/liggghts,plugflow-dem-yade/yade`)

use std::path::Path;
use std::time::Instant;

use plugflow::scene::Scene;

mod common;
use common::flag;

/// One coupled run of one engine.
struct Timing {
    /// Particle-steps per second of the coupled run.
    rate: f64,
    /// Share of the wall time spent in the engine's calls.
    engine_share: f64,
    /// Wall time, s.
    wall: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let duration: f64 = flag("--duration").unwrap_or(1.0);
    let repeat: usize = flag("--repeat").unwrap_or(1).max(1);
    let engines: Vec<String> = flag::<String>("--engines")
        .unwrap_or_else(|| "native,liggghts,yade".into())
        .split(',')
        .map(str::to_owned)
        .collect();
    let sets: Vec<String> = args
        .windows(2)
        .filter(|w| w[0] == "--set")
        .map(|w| w[1].clone())
        .collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene_path = root.join("cases/vertical_plug.toml");
    // Timings interleaved (engine after engine, round after round), so a shared machine's
    // slow spells fall on all engines alike.
    let mut rates: Vec<Vec<Timing>> = engines.iter().map(|_| Vec::new()).collect();
    let mut failed: Vec<Option<String>> = engines.iter().map(|_| None).collect();
    for _ in 0..repeat {
        for (k, engine) in engines.iter().enumerate() {
            if failed[k].is_some() {
                continue;
            }
            match coupled_once(&scene_path, engine, duration, &sets) {
                Ok(t) => {
                    eprintln!(
                        "  {engine}: {:.3e} particle-steps/s, engine {:.0} % of {:.2} s",
                        t.rate,
                        100.0 * t.engine_share,
                        t.wall
                    );
                    rates[k].push(t);
                }
                Err(e) => failed[k] = Some(e),
            }
        }
    }
    let mut medians = Vec::new();
    for (k, engine) in engines.iter().enumerate() {
        if let Some(e) = &failed[k] {
            println!("{engine:8}: not measured ({e})");
            medians.push(None);
            continue;
        }
        let rate = median(rates[k].iter().map(|t| t.rate).collect());
        let share = median(rates[k].iter().map(|t| t.engine_share).collect());
        let wall = median(rates[k].iter().map(|t| t.wall).collect());
        println!(
            "{engine:8}: {rate:.3e} particle-steps/s (median of {}), {:.0} % of the wall in the \
             engine, {wall:.2} s wall for {duration} s simulated",
            rates[k].len(),
            100.0 * share
        );
        medians.push(Some(rate));
    }
    let native = engines
        .iter()
        .position(|e| e == "native")
        .and_then(|k| medians[k]);
    for (k, engine) in engines.iter().enumerate() {
        if engine == "native" {
            continue;
        }
        match (native, medians[k]) {
            (Some(n), Some(o)) => println!("ratio native/{engine}: {:.2}", n / o),
            _ => println!("ratio native/{engine}: unavailable"),
        }
    }
}

/// The vertical case on `engine` for `duration` simulated seconds, one thread.
fn coupled_once(
    scene_path: &Path,
    engine: &str,
    duration: f64,
    sets: &[String],
) -> Result<Timing, String> {
    let scene = Scene::load(
        scene_path,
        &[
            format!("dem.engine=\"{engine}\""),
            "dem.threads=1".into(),
            format!("duration=\"{duration} s\""),
            // (The scene's settling time, 6 s, would outlast a short benchmark; no means
            // are taken here.)
            "output.settling_time=\"0 s\"".into(),
            // The law every engine has (YADE has no regularised Coulomb law).
            "contact.tangential=\"history\"".into(),
        ]
        .into_iter()
        .chain(sets.iter().cloned())
        .collect::<Vec<_>>(),
    )
    .map_err(|e| e.to_string())?;
    let setup = plugflow::setup::build(&scene, false).map_err(|e| e.to_string())?;
    let mut dem = setup.engine;
    let mut coupler = setup.coupler.ok_or("the scene has no gas")?;
    let steps = (duration / dem.time_step()).round() as u64;
    let interval = coupler.substeps;
    let mut particle_steps = 0.0;
    let mut done = 0;
    let t = Instant::now();
    while done < steps {
        let k = interval.min(steps - done);
        coupler
            .advance(dem.as_mut(), k)
            .map_err(|e| e.to_string())?;
        // The grains of the interval (counted at its end: the feed adds a few per interval).
        particle_steps += dem.particles().len() as f64 * k as f64;
        done += k;
    }
    let wall = t.elapsed().as_secs_f64();
    let coupling: f64 = coupler.timer.entries().iter().map(|(_, s)| s).sum();
    Ok(Timing {
        rate: particle_steps / wall,
        engine_share: ((wall - coupling) / wall).max(0.0),
        wall,
    })
}

/// The median of some timings.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
