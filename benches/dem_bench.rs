//! Built-in DEM vs LIGGGHTS on one settled bed (cases/bench_bed.toml): same grains, same
//! Hertz + history parameters, same dt, same step count, same starting positions (at rest,
//! no contact history). Prints particle-steps per second for each and, last,
//! `ratio native/liggghts: X` (one core each). Not a test: numbers depend on the machine.
//!
//! cargo bench --bench dem_bench [-- --steps N] [--repeat R] [--native-only | --bridge-only]
//! (`--repeat R`: R interleaved rounds, each timing one thread, two threads and LIGGGHTS once;
//! the medians over the rounds; `--native-only`: the built-in DEM's one-thread timing alone,
//! for profiling it; `--bridge-only`: only the engines through the ABI, one advance against
//! exchanges of `--chunk` steps, default 50)

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;
use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::{DemBackend, NewParticle};

mod common;
use common::flag;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let steps: u64 = flag::<u64>("--steps").unwrap_or(20_000);
    // Timings of the built-in DEM and of LIGGGHTS repeated this often; medians are reported
    // (a shared machine's neighbours slow single runs by 5–20 %).
    let repeat = flag::<u64>("--repeat").unwrap_or(1).max(1) as usize;
    // Steps per exchange in the ABI bridge timing (a coupled run's coupling interval;
    // fewer steps per exchange weigh the exchange's own cost more).
    let chunk: u64 = flag::<u64>("--chunk").unwrap_or(50).max(1);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene_path = root.join("cases/bench_bed.toml");
    let scene = Scene::load(&scene_path, &[]).expect("bench scene");
    let work = root.join("target/bench_bed");
    std::fs::create_dir_all(&work).unwrap();

    // 1. Settle the bed once with the built-in DEM.
    let mut dem = NativeDem::new(plugflow::setup::dem_config(&scene).unwrap()).unwrap();
    let settle_steps = (scene.file.duration.si / dem.time_step()).round() as u64;
    eprintln!(
        "settling {} grains for {settle_steps} steps ...",
        dem.particles().len()
    );
    dem.advance(settle_steps).unwrap();
    let p = dem.particles();
    let bed: Vec<([f64; 3], f64)> = p
        .position
        .iter()
        .copied()
        .zip(p.radius.iter().copied())
        .collect();
    let top = bed.iter().map(|b| b.0[2]).fold(0.0, f64::max);
    eprintln!("bed: {} grains, height {:.4} m", bed.len(), top);

    // 2. The same bed, at rest, in a fresh native engine (no initial fill).
    let native_once = |threads: usize| -> f64 {
        let s = Scene::load(
            &scene_path,
            &["initial.count=0".into(), format!("dem.threads={threads}")],
        )
        .unwrap();
        let mut d = NativeDem::new(plugflow::setup::dem_config(&s).unwrap()).unwrap();
        let grains: Vec<NewParticle> = bed
            .iter()
            .map(|&(x, r)| NewParticle {
                position: x,
                velocity: [0.0; 3],
                radius: r,
                density: 937.0,
            })
            .collect();
        d.insert(&grains).unwrap();
        d.advance(1).unwrap(); // first neighbour build outside the timing
        let t = Instant::now();
        d.advance(steps).unwrap();
        let secs = t.elapsed().as_secs_f64();
        eprintln!(
            "  stages ({threads} threads): {:?}; {} pairs in the neighbour list, {} builds",
            d.stage_times(),
            d.neighbor_pairs(),
            d.neighbor_builds()
        );
        bed.len() as f64 * steps as f64 / secs
    };
    // Interleaved rounds: each times every side once (one thread, two threads, LIGGGHTS), so
    // the host's drift over the run falls on all sides alike; medians over the rounds.
    let bridge_only = args.iter().any(|a| a == "--bridge-only");
    let native_only = args.iter().any(|a| a == "--native-only");
    let (mut one, mut two, mut lig) = (Vec::new(), Vec::new(), Vec::new());
    let mut liggghts_error: Option<String> = None;
    if !bridge_only {
        for _ in 0..repeat {
            one.push(native_once(1));
            if native_only {
                continue;
            }
            two.push(native_once(2));
            // 3. LIGGGHTS from Debian's package on the same bed.
            if liggghts_error.is_none() {
                match liggghts(&work, &bed, steps) {
                    Ok(rate) => lig.push(rate),
                    Err(e) => liggghts_error = Some(e),
                }
            }
        }
    }
    let n1 = if bridge_only {
        f64::NAN
    } else {
        median("1 threads", one)
    };
    if !bridge_only {
        println!("native 1 thread : {:.3e} particle-steps/s", n1);
    }
    if native_only {
        return;
    }
    let ratio = if bridge_only {
        None
    } else {
        let n2 = median("2 threads", two);
        println!(
            "native 2 threads: {:.3e} particle-steps/s ({:.2}x its one-thread speed)",
            n2,
            n2 / n1
        );
        match liggghts_error {
            None => {
                let l = median("liggghts", lig);
                println!("liggghts 1 proc : {:.3e} particle-steps/s", l);
                Some(n1 / l)
            }
            Some(e) => {
                println!("liggghts: not measured ({e})");
                None
            }
        }
    };

    // 4. The bridge: each engine through the C ABI, advanced in coupling-sized chunks with
    // a fluid force set after each (as a coupled run does), against one uninterrupted
    // advance, on the same bed and laws.
    let bed_scene = Scene::load(&scene_path, &["initial.count=0".into()]).unwrap();
    let release = root.join("target/release");
    for (engine, lib, build) in [
        (
            "native",
            "libplugflow_dem_native.so",
            "cargo build --release -p plugflow-dem-native",
        ),
        (
            "liggghts",
            "libplugflow_dem_liggghts.so",
            "cargo build --release -p plugflow-dem-liggghts --features liggghts",
        ),
    ] {
        let lib = release.join(lib);
        if !lib.exists() {
            println!(
                "{engine} through the ABI: not measured ({} missing: {build})",
                lib.display()
            );
            continue;
        }
        // `repeat` pairs (one advance, then the same steps in exchanges), each pair's
        // overhead from its own two timings; medians of the pairs.
        let pairs: Result<Vec<(f64, f64, u64)>, String> = (0..repeat)
            .map(|_| bridge(&lib, &bed_scene, &bed, steps / 2, chunk))
            .collect();
        let pairs = match pairs {
            Ok(t) => t,
            Err(e) => {
                println!("{engine} through the ABI: not measured ({e}; {build})");
                continue;
            }
        };
        let exchanges = pairs[0].2;
        let work_done = bed.len() as f64 * (steps / 2) as f64;
        let single = median(
            &format!("{engine} one advance"),
            pairs.iter().map(|p| work_done / p.0).collect(),
        );
        let chunked = median(
            &format!("{engine} in exchanges"),
            pairs.iter().map(|p| work_done / p.1).collect(),
        );
        let overhead = median(
            &format!("{engine} overhead µs"),
            pairs
                .iter()
                .map(|p| (p.1 - p.0) / exchanges as f64 * 1e6)
                .collect(),
        );
        println!(
            "{engine} through the ABI: {single:.3e} particle-steps/s in one advance; \
             {chunked:.3e} in {exchanges} exchanges of {chunk} steps; overhead {overhead:.1} µs \
             per exchange"
        );
    }
    match ratio {
        Some(r) => println!("ratio native/liggghts: {r:.2}"),
        None => println!("ratio native/liggghts: unavailable"),
    }
}

/// The median of repeated timings (each listed on stderr when there are several).
fn median(label: &str, mut rates: Vec<f64>) -> f64 {
    rates.sort_by(f64::total_cmp);
    if rates.len() > 1 {
        let list: Vec<String> = rates.iter().map(|r| format!("{r:.4e}")).collect();
        eprintln!("  {label}, {} runs: {}", rates.len(), list.join(" "));
    }
    rates[rates.len() / 2]
}

/// Time `steps` steps of the bed through an ABI library: once in one advance, once in
/// chunks of `chunk` steps with a fluid force set after each. Returns (one advance s,
/// chunked s, number of exchanges), or why the library could not be loaded (one built
/// without its engine's feature lacks the ABI calls).
fn bridge(
    lib: &Path,
    scene: &Scene,
    bed: &[([f64; 3], f64)],
    steps: u64,
    chunk: u64,
) -> Result<(f64, f64, u64), String> {
    let grains: Vec<NewParticle> = bed
        .iter()
        .map(|&(x, r)| NewParticle {
            position: x,
            velocity: [0.0; 3],
            radius: r,
            density: 937.0,
        })
        .collect();
    let run = |chunked: bool| -> Result<f64, String> {
        let mut e = AbiBackend::load(lib, &scene.to_json()).map_err(|e| e.to_string())?;
        e.insert(&grains).unwrap();
        e.advance(1).unwrap();
        let t = Instant::now();
        if chunked {
            let mut done = 0;
            while done < steps {
                e.advance(chunk).unwrap();
                let f = vec![[0.0, 0.0, 1e-7]; e.particles().len()];
                e.set_fluid_forces(&f, None).unwrap();
                done += chunk;
            }
        } else {
            e.advance(steps).unwrap();
        }
        Ok(t.elapsed().as_secs_f64())
    };
    Ok((run(false)?, run(true)?, steps.div_ceil(chunk)))
}

/// Run the `liggghts` binary on the bed; returns particle-steps/s from its loop time.
fn liggghts(work: &Path, bed: &[([f64; 3], f64)], steps: u64) -> Result<f64, String> {
    let mut data = String::new();
    data.push_str("plugflow bench bed\n\n");
    data.push_str(&format!("{} atoms\n1 atom types\n\n", bed.len()));
    data.push_str("-0.004 0.004 xlo xhi\n-0.004 0.004 ylo yhi\n-0.001 0.401 zlo zhi\n\nAtoms\n\n");
    for (k, (x, r)) in bed.iter().enumerate() {
        data.push_str(&format!(
            "{} 1 {:.17e} 937 {:.17e} {:.17e} {:.17e}\n",
            k + 1,
            2.0 * r,
            x[0],
            x[1],
            x[2]
        ));
    }
    std::fs::write(work.join("bed.data"), data).map_err(|e| e.to_string())?;
    let input = format!(
        "atom_style granular
atom_modify map array
boundary f f f
newton off
communicate single vel yes
units si
read_data bed.data
neighbor 0.00014 bin
neigh_modify delay 0
fix m1 all property/global youngsModulus peratomtype 5e6
fix m2 all property/global poissonsRatio peratomtype 0.45
fix m3 all property/global coefficientRestitution peratomtypepair 1 0.5
fix m4 all property/global coefficientFriction peratomtypepair 1 0.5
pair_style gran model hertz tangential history
pair_coeff * *
timestep 5e-6
fix gravi all gravity 9.81 vector 0.0 0.0 -1.0
fix bottom all wall/gran model hertz tangential history primitive type 1 zplane 0.0
fix top all wall/gran model hertz tangential history primitive type 1 zplane 0.4
fix tube all wall/gran model hertz tangential history primitive type 1 zcylinder 0.0035 0.0 0.0
fix integr all nve/sphere
thermo 5000
run 1
run {steps}
"
    );
    std::fs::write(work.join("in.bench"), input).map_err(|e| e.to_string())?;
    let out = Command::new("liggghts")
        .current_dir(work)
        .env("OMP_NUM_THREADS", "1")
        .args([
            "-in",
            "in.bench",
            "-echo",
            "none",
            "-screen",
            "screen.txt",
            "-log",
            "log.txt",
        ])
        .output()
        .map_err(|e| format!("cannot start `liggghts` ({e}); run scripts/setup-system.sh"))?;
    let log = std::fs::read_to_string(work.join("log.txt")).unwrap_or_default();
    if !out.status.success() {
        return Err(format!(
            "liggghts exited with {}; see {}",
            out.status,
            work.join("log.txt").display()
        ));
    }
    // "Loop time of 3.2 on 1 procs for 20000 steps with 1902 atoms" (the last run).
    let line = log
        .lines()
        .rfind(|l| l.starts_with("Loop time of"))
        .ok_or("no loop time in the LIGGGHTS log")?;
    let words: Vec<&str> = line.split_whitespace().collect();
    let secs: f64 = words[3]
        .parse()
        .map_err(|_| format!("cannot read `{line}`"))?;
    let atoms: f64 = words
        .iter()
        .position(|w| *w == "with")
        .and_then(|k| words.get(k + 1))
        .and_then(|w| w.parse().ok())
        .ok_or_else(|| format!("cannot read `{line}`"))?;
    Ok(atoms * steps as f64 / secs)
}
