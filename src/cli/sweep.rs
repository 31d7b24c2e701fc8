//! `plugflow sweep`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use plugflow::sweep;

use super::*;

/// The arguments of `plugflow sweep` (documented on the subcommand).
#[derive(Args)]
pub struct SweepArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// A field and its values: --vary gas.superficial_velocity=0.5,0.75,1,2,4 (repeatable;
    /// every combination runs). Fields that vary together: --vary
    /// "inlet.mass_flow|inlet.velocity=2.49 kg/h|0.04 m/s,9.95 kg/h|0.16 m/s" (the first is
    /// the curves' axis).
    #[arg(long = "vary", value_name = "PATH=V1,V2,...", required = true)]
    pub vary: Vec<String>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated time per variant, s.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Variants run at once (default: one per core).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// DEM threads per variant (default 1, so that the jobs fill the cores).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Override a scene field in every variant (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Start every variant from this checkpoint (a run folder or a `.pfc` file: a filled
    /// tube), as `plugflow run --from` does. A sweep re-run into the same folder skips the
    /// variants that finished and resumes stopped ones from their own checkpoints.
    #[arg(long, value_name = "CHECKPOINT")]
    pub from: Option<PathBuf>,
}

pub fn main(a: SweepArgs) -> ExitCode {
    let SweepArgs {
        scene,
        vary,
        out,
        duration,
        jobs,
        threads,
        set,
        from,
    } = a;
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
        out_dir: out
            .unwrap_or_else(|| PathBuf::from("results").join(format!("{}_sweep", base.file.name))),
        jobs: jobs.unwrap_or(cores).max(1),
        duration,
        set,
        threads: threads.max(1),
        from,
    };
    let exe = match plugflow_exe() {
        Ok(e) => e,
        Err(code) => return code,
    };
    plugflow::children::install_stop_handler();
    match sweep::sweep(&exe, &scene, &varies, &opts) {
        Ok(sweep::SweepResult { rows, targets }) => {
            for t in &targets {
                say!(
                    "{:<4} {:<50} measured {} band {}–{}: {}",
                    t.id,
                    t.what,
                    t.measured
                        .map(|m| format!("{m:.4}"))
                        .unwrap_or_else(|| "—".into()),
                    t.band[0],
                    t.band[1],
                    if t.inside { "inside" } else { "outside" }
                );
            }
            let failed = rows
                .iter()
                .filter(|r| !r.as_ref().is_some_and(|r| r.completed()))
                .count();
            say!(
                "sweep: {} variants ({} failed); {}",
                rows.len(),
                failed,
                opts.out_dir.join("sweep.csv").display()
            );
            if failed == 0 {
                stopped_or(ExitCode::SUCCESS, "variants")
            } else {
                stopped_or(ExitCode::FAILURE, "variants")
            }
        }
        Err(
            e @ (sweep::SweepError::Vary { .. }
            | sweep::SweepError::Scene { .. }
            | sweep::SweepError::Start { .. }),
        ) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
