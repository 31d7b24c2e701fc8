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

/// Steps beyond which `validate` warns that the scene likely asks for more than was meant.
const LIKELY_MEANT_STEPS: f64 = 1e9;

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
            let steps = s.file.duration.si / c.dt;
            say!(
                "steps: {steps:.3e} for {} s simulated (the shipped cases need 1e5–2e7)",
                s.file.duration.si
            );
            // Refused beyond 1e10 (scene check); far past the shipped cases (the 40 s
            // steady-state run is 2e7 steps) a step or a duration was likely mistyped.
            if steps > LIKELY_MEANT_STEPS {
                eprintln!(
                    "warning: {steps:.3e} steps is far beyond what a run here usually needs \
                     (a 40 s steady-state run of the vertical case is 2e7): days of wall time; \
                     check duration and dem.dt / dem.dt_fraction"
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
