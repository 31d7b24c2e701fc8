//! `plugflow run`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use plugflow::run::{run, RunError, RunOptions};
use plugflow::summary::Summary;

use super::*;

/// The arguments of `plugflow run` (documented on the subcommand).
#[derive(Args)]
pub struct RunArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output folder (default results/<scene name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated time, s (overrides the scene's `duration`).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Override a scene field: --set dem.dt=5e-6 (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Go on from a checkpoint: a run folder (its latest in `checkpoints/`) or a `.pfc`
    /// file. The scene must be the run's; its duration, checkpoint interval and threads
    /// may differ. The run writes into that run's folder unless --out says otherwise.
    #[arg(long, value_name = "DIR")]
    pub resume: Option<PathBuf>,
    /// Start from another run's checkpoint (a run folder or a `.pfc` file): its grains,
    /// contacts and gas at t = 0, with this scene's other settings (gas velocity, friction,
    /// feed...). Its tube, grains and gas grid must be this scene's.
    #[arg(long, value_name = "CHECKPOINT", conflicts_with = "resume")]
    pub from: Option<PathBuf>,
}

pub fn main(a: RunArgs) -> ExitCode {
    let RunArgs {
        scene,
        out,
        duration,
        set,
        quiet,
        resume,
        from,
    } = a;
    let s = match checked_scene(&scene, &set, duration) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let opts = RunOptions {
        out_dir: out,
        duration,
        progress: !quiet,
        resume,
        from,
    };
    // Ctrl-C / SIGTERM: end at the next sample with every output written. (A second
    // signal while it finishes changes nothing; failing to install it only loses this.)
    if let Err(e) = ctrlc::set_handler(|| {
        plugflow::run::INTERRUPT.store(true, std::sync::atomic::Ordering::Relaxed);
        // Under MPI a rank may wait for a dead one for ever: the summary now, as failed.
        plugflow::run::last_words::on_stop_signal();
    }) {
        eprintln!("warning: no Ctrl-C handler ({e}); an interrupt will lose the summary");
    }
    match run(&s, &opts) {
        Ok(outcome) => {
            // (Under MPI rank 0 speaks for the run.)
            if plugflow::setup::ranks::launched().leads() {
                print_outcome(&outcome.summary, &outcome.out_dir);
            }
            ExitCode::SUCCESS
        }
        Err(RunError::Scene(e)) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
        Err(RunError::Checkpoint(e)) => {
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

/// The run's headline numbers on the terminal.
fn print_outcome(sm: &Summary, out_dir: &std::path::Path) {
    for w in &sm.warnings {
        eprintln!("warning: {w}");
    }
    say!(
        "done: {} s simulated in {:.1} s wall; {} grains in tube (mean); {}; summary in {}",
        sm.simulated_time_s,
        sm.wall_time_s,
        if sm.particles_in_tube_mean.is_finite() {
            format!("{:.1}", sm.particles_in_tube_mean)
        } else {
            "not measured".into()
        },
        match (sm.solids_mass_flow_kg_per_h, sm.mass_outflow_kg_per_h) {
            (Some(m), _) => format!("solids mass flow {m:.3} kg/h through a section"),
            (None, Some(m)) => format!("outflow {m:.3} kg/h"),
            (None, None) => "outflow not measured".into(),
        },
        out_dir.join("summary.json").display()
    );
    if let Some(g) = &sm.gas {
        if g.pressure_drop_hpa_per_m.is_finite() {
            say!(
                "pressure drop {:.2} hPa/m (mean after the settling time)",
                g.pressure_drop_hpa_per_m
            );
        }
    }
    if let Some(sl) = &sm.slug {
        let f = |m: &Option<plugflow_model::summary::MeanStd>| {
            m.map_or_else(
                || "—".to_string(),
                |m| format!("{:.3} ± {:.3}", m.mean, m.std),
            )
        };
        say!(
            "slug (after the settling time, {} samples, seen in {:.0} %): velocity {} m/s, \
             its grains {} m/s, length {} m; gas mean superficial velocity {} m/s; \
             Lavrinec's 0.967 ū_p + 0.5 √(gD) = {} m/s",
            sl.samples,
            100.0 * sl.slug_seen_fraction,
            f(&sl.slug_velocity_m_s),
            f(&sl.slug_grain_velocity_m_s),
            f(&sl.slug_length_m),
            f(&sl.gas_mean_superficial_velocity_m_s),
            sl.lavrinec_slug_velocity_m_s
                .map_or_else(|| "—".to_string(), |v| format!("{v:.3}"))
        );
    }
    let taps = sm.gas.as_ref().and_then(|g| g.pressure_taps.as_ref());
    for tap in taps.and_then(|t| t.as_array()).into_iter().flatten() {
        let mbar = |k: &str| {
            tap[k]
                .as_f64()
                .map_or_else(|| "—".to_string(), |v| format!("{:.2}", v / 100.0))
        };
        say!(
            "{} ({}–{} m): max {} mbar, min {} mbar, {} peaks (median {} mbar), troughs \
             median {} mbar (after the settling time)",
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
    if let Some(targets) = &sm.targets {
        say!(
            "{:<4} {:<42} {:>10} {:>8} {:>16}  inside",
            "row",
            "what",
            "measured",
            "paper",
            "band"
        );
        for t in targets {
            say!(
                "{:<4} {:<42} {:>10} {:>8} {:>16}  {}",
                t.id,
                t.what,
                t.measured
                    .map(|m| format!("{m:.4}"))
                    .unwrap_or_else(|| "—".into()),
                if t.paper.is_nan() {
                    "falls".to_string()
                } else {
                    format!("{}", t.paper)
                },
                format!("{}–{}", t.band[0], t.band[1]),
                if t.inside { "yes" } else { "no" }
            );
        }
    }
}
