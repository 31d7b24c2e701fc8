//! `plugflow study`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use plugflow::summary::Number;

use plugflow::{study, sweep};

use super::*;

/// The arguments of `plugflow study` (documented on the subcommand).
#[derive(Args)]
pub struct StudyArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// A field and its values: --vary dem.dt=1e-6,2e-6 (repeatable; any scene path).
    #[arg(long = "vary", value_name = "PATH=V1,V2,...", required = true)]
    pub vary: Vec<String>,
    /// Summary keys whose error is measured (default: pressure drop, grains in the
    /// tube, outflow).
    #[arg(long, value_delimiter = ',')]
    pub observables: Vec<String>,
    /// An exact (analytic) value of an observable, used as its reference instead of the
    /// finest variant (repeatable): --exact pressure_drop_hpa_per_m=14.92.
    #[arg(long = "exact", value_name = "KEY=VALUE")]
    pub exact: Vec<String>,
    /// Name the cheapest variant whose largest relative error is at most this.
    #[arg(long)]
    pub target_error: Option<f64>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated time per variant, s.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Variants run at once (default 1, so that the wall times compare).
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// DEM threads per variant.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Override a scene field in every variant (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Start every variant from this checkpoint (a run folder or a `.pfc` file: the tube
    /// at steady state), as `plugflow run --from` does; a re-run skips finished variants.
    #[arg(long, value_name = "CHECKPOINT")]
    pub from: Option<PathBuf>,
}

pub fn main(a: StudyArgs) -> ExitCode {
    let StudyArgs {
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
        from,
    } = a;
    let varies = match parse_varies(&vary) {
        Ok(v) => v,
        Err(code) => return code,
    };
    // A study ranks each field's values by fineness (dt, grid): fields that vary together
    // have no one order.
    if let Some(v) = varies.iter().find(|v| !v.paired.is_empty()) {
        eprintln!(
            "error: --vary `{}|…`: a study varies one field per --vary (fields varied together \
             are for `plugflow sweep`)",
            v.path
        );
        return ExitCode::from(2);
    }
    let mut exact_values = Vec::new();
    for e in &exact {
        match e
            .split_once('=')
            .map(|(k, v)| (k.trim(), v.trim().parse::<f64>()))
        {
            Some((k, Ok(v))) if !k.is_empty() && v.is_finite() => match Number::from_key(k) {
                Ok(n) => exact_values.push((n, v)),
                Err(why) => {
                    eprintln!("error: --exact `{e}`: {why}");
                    return ExitCode::from(2);
                }
            },
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
            from,
        },
        observables: if observables.is_empty() {
            study::DEFAULT_OBSERVABLES.to_vec()
        } else {
            match observables.iter().map(|k| Number::from_key(k)).collect() {
                Ok(o) => o,
                Err(why) => {
                    eprintln!("error: --observables: {why}");
                    return ExitCode::from(2);
                }
            }
        },
        exact: exact_values,
        target_error,
    };
    let exe = match plugflow_exe() {
        Ok(e) => e,
        Err(code) => return code,
    };
    plugflow::children::install_stop_handler();
    match study::study(&exe, &scene, &varies, &opts) {
        Ok(r) => {
            let failed = r.rows.iter().filter(|x| x.status != "completed").count();
            say!(
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
                (Some(t), Some(k)) => say!(
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
                    say!("no variant but the reference reaches an error ≤ {t}")
                }
                _ => {}
            }
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
