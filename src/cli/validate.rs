//! `plugflow validate`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::*;

/// The arguments of `plugflow validate` (documented on the subcommand).
#[derive(Args)]
pub struct ValidateArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Override a scene field (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
}

pub fn main(a: ValidateArgs) -> ExitCode {
    let ValidateArgs { scene, set } = a;
    // Through the setup layer, as a run: the configuration, the coupling checks and the
    // chosen engine's own refusals (the built-in engine's initial placement, the
    // LIGGGHTS and YADE mappings), without starting an external engine.
    let checked = Scene::load(&scene, &set).and_then(|s| {
        let p = plugflow::setup::validate(&s)?;
        Ok((s, p.config, p.coupler))
    });
    match checked {
        Ok((s, c, gas)) => {
            if let Some(g) = &gas {
                for ch in &g.checks {
                    say!(
                        "coupling check: {}: {:.4} (limit {:.4}) {:?}",
                        ch.name,
                        ch.value,
                        ch.limit,
                        ch.verdict
                    );
                }
            }
            say!(
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
