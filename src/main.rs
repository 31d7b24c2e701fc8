//! The `plugflow` command line: `run`, `sweep`, `study`, `crosscheck`, `validate`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use plugflow::dem::DemConfig;
use plugflow::run::{run, RunError, RunOptions};
use plugflow::scene::Scene;
use plugflow::{crosscheck, study, sweep};

#[derive(Parser)]
#[command(
    name = "plugflow",
    version,
    about = "Gas–grain co-simulation of dense-phase pneumatic conveying"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write results/<name>/summary.json.
    Run {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output folder (default results/<scene name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Simulated time, s (overrides the scene's `duration`).
        #[arg(long)]
        duration: Option<f64>,
        /// Override a scene field: --set dem.dt=5e-6 (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Run every combination of the --vary lists as parallel processes; write sweep.csv and
    /// characteristic.png into the output folder (default results/<scene name>_sweep/).
    Sweep {
        /// Scene file (TOML).
        scene: PathBuf,
        /// A field and its values: --vary gas.superficial_velocity=0.5,0.75,1,2,4 (repeatable;
        /// every combination runs).
        #[arg(long = "vary", value_name = "PATH=V1,V2,...", required = true)]
        vary: Vec<String>,
        /// Output folder.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Simulated time per variant, s.
        #[arg(long)]
        duration: Option<f64>,
        /// Variants run at once (default: one per core).
        #[arg(long)]
        jobs: Option<usize>,
        /// DEM threads per variant (default 1, so that the jobs fill the cores).
        #[arg(long, default_value_t = 1)]
        threads: usize,
        /// Override a scene field in every variant (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
    /// Run a scene on several DEM engines and write a side-by-side report (crosscheck.md,
    /// crosscheck.png) into the output folder (default results/<scene name>_crosscheck/).
    Crosscheck {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Engines, comma-separated: native, native_abi, liggghts, yade.
        #[arg(long, value_delimiter = ',', default_value = "native,liggghts")]
        engines: Vec<String>,
        /// Output folder.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Simulated time, s.
        #[arg(long)]
        duration: Option<f64>,
        /// Override a scene field on every engine (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
    /// Error against run time: run every combination of the --vary lists, measure each
    /// observable's error against an exact value (--exact) or the finest variant, and write
    /// study.csv, study.md and study.png (error vs wall time, Pareto front) into the output
    /// folder (default results/<scene name>_study/).
    Study {
        /// Scene file (TOML).
        scene: PathBuf,
        /// A field and its values: --vary dem.dt=1e-6,2e-6 (repeatable; any scene path).
        #[arg(long = "vary", value_name = "PATH=V1,V2,...", required = true)]
        vary: Vec<String>,
        /// Summary keys whose error is measured (default: pressure drop, grains in the
        /// tube, outflow).
        #[arg(long, value_delimiter = ',')]
        observables: Vec<String>,
        /// An exact (analytic) value of an observable, used as its reference instead of the
        /// finest variant (repeatable): --exact pressure_drop_hpa_per_m=14.92.
        #[arg(long = "exact", value_name = "KEY=VALUE")]
        exact: Vec<String>,
        /// Name the cheapest variant whose largest relative error is at most this.
        #[arg(long)]
        target_error: Option<f64>,
        /// Output folder.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Simulated time per variant, s.
        #[arg(long)]
        duration: Option<f64>,
        /// Variants run at once (default 1, so that the wall times compare).
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        /// DEM threads per variant.
        #[arg(long, default_value_t = 1)]
        threads: usize,
        /// Override a scene field in every variant (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
    /// Check a scene without running it; exit code 2 and the field at fault when wrong.
    Validate {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Override a scene field (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
}

/// The scene with its overrides and a positive `--duration`, or exit code 2 after saying
/// what is wrong.
fn checked_scene(
    scene: &std::path::Path,
    set: &[String],
    duration: Option<f64>,
) -> Result<Scene, ExitCode> {
    if let Some(d) = duration {
        if !(d.is_finite() && d > 0.0) {
            eprintln!("error: --duration must be a positive number of seconds");
            return Err(ExitCode::from(2));
        }
    }
    // A scene passes with its own duration (so a short trial run of a long case is fine) or
    // with `--duration`'s (so `--set output.settling_time=…` may point past the scene's end
    // when the run goes that far); when neither passes, the error is the one for the run.
    let loaded = match (Scene::load(scene, set), duration) {
        (Ok(s), _) => Ok(s),
        (Err(e), None) => Err(e),
        (Err(_), Some(d)) => Scene::load(scene, &[set, &[format!("duration={d}")]].concat()),
    };
    loaded.map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

/// This executable, which sweeps, studies and crosschecks start once per variant.
fn plugflow_exe() -> Result<PathBuf, ExitCode> {
    std::env::current_exe().map_err(|e| {
        eprintln!("error: cannot find the plugflow executable: {e}");
        ExitCode::FAILURE
    })
}

/// Every `--vary PATH=V1,V2,…`, or exit code 2 after saying which is malformed.
fn parse_varies(vary: &[String]) -> Result<Vec<sweep::Vary>, ExitCode> {
    vary.iter()
        .map(|v| sweep::parse_vary(v))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| {
            eprintln!("error: {e}");
            ExitCode::from(2)
        })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Crosscheck {
            scene,
            engines,
            out,
            duration,
            set,
        } => {
            let base = match checked_scene(&scene, &set, duration) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let out = out.unwrap_or_else(|| {
                PathBuf::from("results").join(format!("{}_crosscheck", base.file.name))
            });
            let exe = match plugflow_exe() {
                Ok(e) => e,
                Err(code) => return code,
            };
            match crosscheck::crosscheck(&exe, &scene, &engines, &set, duration, &out) {
                Ok(s) => {
                    let ok = s.iter().filter(|v| v["status"] == "completed").count();
                    println!(
                        "crosscheck: {ok} of {} engines completed; {}",
                        s.len(),
                        out.join("crosscheck.md").display()
                    );
                    if ok == s.len() {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::FAILURE
                    }
                }
                Err(e @ crosscheck::CrosscheckError::Scene { .. }) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::Sweep {
            scene,
            vary,
            out,
            duration,
            jobs,
            threads,
            set,
        } => {
            let varies = match parse_varies(&vary) {
                Ok(v) => v,
                Err(code) => return code,
            };
            let base = match checked_scene(&scene, &set, duration) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let opts = sweep::SweepOptions {
                out_dir: out.unwrap_or_else(|| {
                    PathBuf::from("results").join(format!("{}_sweep", base.file.name))
                }),
                jobs: jobs.unwrap_or(cores).max(1),
                duration,
                set,
                threads: threads.max(1),
            };
            let exe = match plugflow_exe() {
                Ok(e) => e,
                Err(code) => return code,
            };
            match sweep::sweep(&exe, &scene, &varies, &opts) {
                Ok(rows) => {
                    let failed = rows
                        .iter()
                        .filter(|r| r["status"].as_str() != Some("completed"))
                        .count();
                    println!(
                        "sweep: {} variants ({} failed); {}",
                        rows.len(),
                        failed,
                        opts.out_dir.join("sweep.csv").display()
                    );
                    if failed == 0 {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::FAILURE
                    }
                }
                Err(e @ sweep::SweepError::Vary { .. })
                | Err(e @ sweep::SweepError::Scene { .. }) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::Study {
            scene,
            vary,
            observables,
            exact,
            target_error,
            out,
            duration,
            jobs,
            threads,
            set,
        } => {
            let varies = match parse_varies(&vary) {
                Ok(v) => v,
                Err(code) => return code,
            };
            let mut exact_values = Vec::new();
            for e in &exact {
                match e
                    .split_once('=')
                    .map(|(k, v)| (k.trim(), v.trim().parse::<f64>()))
                {
                    Some((k, Ok(v))) if !k.is_empty() && v.is_finite() => {
                        exact_values.push((k.to_string(), v))
                    }
                    _ => {
                        eprintln!("error: --exact `{e}`: expected KEY=NUMBER");
                        return ExitCode::from(2);
                    }
                }
            }
            if let Some(t) = target_error {
                if !(t.is_finite() && t > 0.0) {
                    eprintln!("error: --target-error must be a positive number");
                    return ExitCode::from(2);
                }
            }
            let base = match checked_scene(&scene, &set, duration) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let opts = study::StudyOptions {
                runs: sweep::SweepOptions {
                    out_dir: out.unwrap_or_else(|| {
                        PathBuf::from("results").join(format!("{}_study", base.file.name))
                    }),
                    jobs: jobs.max(1),
                    duration,
                    set,
                    threads: threads.max(1),
                },
                observables: if observables.is_empty() {
                    study::DEFAULT_OBSERVABLES
                        .iter()
                        .map(|s| s.to_string())
                        .collect()
                } else {
                    observables
                },
                exact: exact_values,
                target_error,
            };
            let exe = match plugflow_exe() {
                Ok(e) => e,
                Err(code) => return code,
            };
            match study::study(&exe, &scene, &varies, &opts) {
                Ok(r) => {
                    let failed = r.rows.iter().filter(|x| x.status != "completed").count();
                    println!(
                        "study: {} variants ({failed} failed), reference: {}; {}",
                        r.rows.len(),
                        r.references
                            .iter()
                            .map(|(k, _, from)| format!("{k} from {from}"))
                            .collect::<Vec<_>>()
                            .join(", "),
                        opts.runs.out_dir.join("study.md").display()
                    );
                    match (target_error, r.cheapest) {
                        (Some(t), Some(k)) => println!(
                            "cheapest variant with largest error ≤ {t}: {k:03} ({}), {:.1} s",
                            r.rows[k]
                                .settings
                                .iter()
                                .map(|(p, x)| format!("{p}={x}"))
                                .collect::<Vec<_>>()
                                .join(" "),
                            r.rows[k].wall_time.unwrap_or(0.0)
                        ),
                        (Some(t), None) => {
                            println!("no variant but the reference reaches an error ≤ {t}")
                        }
                        _ => {}
                    }
                    if failed == 0 {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::FAILURE
                    }
                }
                Err(e @ sweep::SweepError::Vary { .. })
                | Err(e @ sweep::SweepError::Scene { .. }) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::Validate { scene, set } => {
            // Build the engine too: initial placement can fail on a valid-looking scene.
            let checked = Scene::load(&scene, &set).and_then(|s| {
                let c = DemConfig::from_scene(&s)?;
                plugflow::dem::NativeDem::new(c.clone())?;
                let gas = plugflow::cosim::coupling_from_scene(&s, &c)?;
                Ok((s, c, gas))
            });
            match checked {
                Ok((s, c, gas)) => {
                    if let Some(g) = &gas {
                        for ch in &g.checks {
                            println!(
                                "coupling check: {}: {:.4} (limit {:.4}) {:?}",
                                ch.name, ch.value, ch.limit, ch.verdict
                            );
                        }
                    }
                    println!(
                        "ok: scene `{}`: dt = {:.3e} s ({}; limit {:.3e} s: {}), {} walls",
                        s.file.name,
                        c.dt,
                        if c.dt_report.derived {
                            "derived"
                        } else {
                            "given"
                        },
                        c.dt_report.limit,
                        c.dt_report.limit_reason,
                        c.walls.len()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Command::Run {
            scene,
            out,
            duration,
            set,
            quiet,
        } => {
            let s = match checked_scene(&scene, &set, duration) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let opts = RunOptions {
                out_dir: out,
                duration,
                progress: !quiet,
            };
            // Ctrl-C / SIGTERM: end at the next sample with every output written. (A second
            // signal while it finishes changes nothing; failing to install it only loses this.)
            if let Err(e) = ctrlc::set_handler(|| {
                plugflow::run::INTERRUPT.store(true, std::sync::atomic::Ordering::Relaxed)
            }) {
                eprintln!("warning: no Ctrl-C handler ({e}); an interrupt will lose the summary");
            }
            match run(&s, &opts) {
                Ok(outcome) => {
                    let sm = &outcome.summary;
                    println!(
                        "done: {} s simulated in {:.1} s wall; {:.1} grains in tube (mean); \
                         outflow {:.3} kg/h; summary in {}",
                        sm["simulated_time_s"],
                        sm["wall_time_s"].as_f64().unwrap_or(0.0),
                        sm["particles_in_tube_mean"].as_f64().unwrap_or(0.0),
                        sm["mass_outflow_kg_per_h"].as_f64().unwrap_or(0.0),
                        outcome.out_dir.join("summary.json").display()
                    );
                    if let Some(dp) = sm.get("pressure_drop_hpa_per_m").and_then(|v| v.as_f64()) {
                        println!("pressure drop {dp:.2} hPa/m (mean after the settling time)");
                    }
                    for tap in sm
                        .get("pressure_taps")
                        .and_then(|t| t.as_array())
                        .into_iter()
                        .flatten()
                    {
                        let mbar = |k: &str| {
                            tap[k]
                                .as_f64()
                                .map_or_else(|| "—".to_string(), |v| format!("{:.2}", v / 100.0))
                        };
                        println!(
                            "{} ({}–{} m): max {} mbar, min {} mbar, {} peaks (median {} mbar), \
                             troughs median {} mbar (after the settling time)",
                            tap["name"].as_str().unwrap_or("?"),
                            tap["from_m"],
                            tap["to_m"],
                            mbar("max_pa"),
                            mbar("min_pa"),
                            tap["peaks"],
                            mbar("peak_median_pa"),
                            mbar("trough_median_pa"),
                        );
                    }
                    if let Some(targets) = sm.get("targets").and_then(|t| t.as_array()) {
                        println!(
                            "{:<4} {:<42} {:>10} {:>8} {:>16}  inside",
                            "row", "what", "measured", "paper", "band"
                        );
                        for t in targets {
                            let band = t["band"].as_array().cloned().unwrap_or_default();
                            println!(
                                "{:<4} {:<42} {:>10} {:>8} {:>16}  {}",
                                t["id"].as_str().unwrap_or("?"),
                                t["what"].as_str().unwrap_or(""),
                                t["measured"]
                                    .as_f64()
                                    .map(|m| format!("{m:.4}"))
                                    .unwrap_or_else(|| "—".into()),
                                t["paper"]
                                    .as_f64()
                                    .map(|p| format!("{p}"))
                                    .unwrap_or_default(),
                                format!(
                                    "{}–{}",
                                    band.first().cloned().unwrap_or_default(),
                                    band.get(1).cloned().unwrap_or_default()
                                ),
                                if t["inside"].as_bool() == Some(true) {
                                    "yes"
                                } else {
                                    "no"
                                }
                            );
                        }
                    }
                    ExitCode::SUCCESS
                }
                Err(RunError::Scene(e)) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Err(e @ RunError::Interrupted { .. }) => {
                    eprintln!("{e}");
                    ExitCode::from(130)
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
