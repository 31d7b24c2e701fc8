//! `plugflow crosscheck`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use plugflow::crosscheck;

use super::*;

/// The arguments of `plugflow crosscheck` (documented on the subcommand).
#[derive(Args)]
pub struct CrosscheckArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Engines, comma-separated: native, native_abi, liggghts, yade.
    #[arg(long, value_delimiter = ',', default_value = "native,liggghts")]
    pub engines: Vec<String>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated time, s.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Override a scene field on every engine (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
}

pub fn main(a: CrosscheckArgs) -> ExitCode {
    let CrosscheckArgs {
        scene,
        engines,
        out,
        duration,
        set,
    } = a;
    let base = match checked_scene(&scene, &set, duration) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let out = out
        .unwrap_or_else(|| PathBuf::from("results").join(format!("{}_crosscheck", base.file.name)));
    let exe = match plugflow_exe() {
        Ok(e) => e,
        Err(code) => return code,
    };
    plugflow::children::install_stop_handler();
    match crosscheck::crosscheck(&exe, &scene, &engines, &set, duration, &out) {
        Ok(s) => {
            let ok = s
                .iter()
                .filter(|v| v.as_ref().is_some_and(|v| v.completed()))
                .count();
            say!(
                "crosscheck: {ok} of {} engines completed; {}",
                s.len(),
                out.join("crosscheck.md").display()
            );
            let departures = crosscheck::feed_departures(&engines, &s);
            for d in &departures {
                eprintln!("crosscheck: {d}");
            }
            if ok == s.len() && departures.is_empty() {
                stopped_or(ExitCode::SUCCESS, "engines")
            } else {
                stopped_or(ExitCode::FAILURE, "engines")
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
