//! A whole run: build the engine from the scene, advance it sample interval by sample
//! interval, sample the tube, show progress, and write `summary.json` (also when the run
//! fails part-way, with what it computed up to then).

use std::path::{Path, PathBuf};
use std::time::Instant;

use plugflow_coupling::{BackendError, DemBackend};
use serde_json::{json, Map, Value};

use crate::dem::{DemConfig, NativeDem};
use crate::scene::{Scene, SceneError};
use crate::Real;

/// What can end a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The scene is wrong.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The engine stopped (NaN, blow-up, engine failure).
    #[error("run stopped at t = {time:.6} s: {source}")]
    Backend { time: Real, source: BackendError },
    /// Output could not be written.
    #[error("cannot write `{path}`: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

/// How to run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder (default `results/<scene name>/`).
    pub out_dir: Option<PathBuf>,
    /// Simulated time overriding the scene's, s.
    pub duration: Option<Real>,
    /// Show a progress bar on the terminal.
    pub progress: bool,
}

/// Headline numbers of a finished run (also written to `summary.json`).
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The summary as written.
    pub summary: Value,
    /// Where it was written.
    pub out_dir: PathBuf,
}

/// Build the engine a scene asks for.
pub fn build_engine(scene: &Scene) -> Result<NativeDem, SceneError> {
    let cfg = DemConfig::from_scene(scene)?;
    NativeDem::new(cfg)
}

/// Run a scene to its end.
pub fn run(scene: &Scene, opts: &RunOptions) -> Result<RunOutcome, RunError> {
    let mut dem = build_engine(scene)?;
    let out_dir = opts
        .out_dir
        .clone()
        .unwrap_or_else(|| scene.default_output_dir());
    std::fs::create_dir_all(&out_dir).map_err(|source| RunError::Io {
        path: out_dir.display().to_string(),
        source,
    })?;
    let f = &scene.file;
    let duration = opts.duration.unwrap_or(f.duration.si);
    let dt = dem.time_step();
    let total_steps = (duration / dt).round().max(1.0) as u64;
    let per_sample = ((f.output.sample_interval.si / dt).round() as u64).max(1);
    let settle = f.output.settling_time.map(|q| q.si).unwrap_or(0.0);

    let bar = if opts.progress {
        let b = indicatif::ProgressBar::new(total_steps);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% ETA {eta} {msg}",
            )
            .expect("static template"),
        );
        Some(b)
    } else {
        None
    };
    let wall = Instant::now();
    let mut in_tube_sum = 0.0;
    let mut in_tube_n = 0u64;
    let mut outflow_at_settle = None;
    let mut failure = None;
    let mut done = 0u64;
    while done < total_steps {
        let n = per_sample.min(total_steps - done);
        if let Err(source) = dem.advance(n) {
            failure = Some(RunError::Backend {
                time: dem.time(),
                source,
            });
            break;
        }
        done += n;
        let in_tube = dem.particles_in_tube();
        if dem.time() >= settle - 0.5 * dt {
            if outflow_at_settle.is_none() {
                outflow_at_settle = Some((dem.time(), dem.flow.outflow_mass));
            }
            in_tube_sum += in_tube as Real;
            in_tube_n += 1;
        }
        if let Some(b) = &bar {
            b.set_position(done);
            b.set_message(format!(
                "t = {:.3}/{:.3} s, {} grains in tube",
                dem.time(),
                duration,
                in_tube
            ));
        }
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let wall_time = wall.elapsed().as_secs_f64();
    let mut stages = Map::new();
    for (name, secs) in dem.stage_times() {
        stages.insert(name, json!(secs));
    }
    let (t_settle, m_settle) = outflow_at_settle.unwrap_or((dem.time(), dem.flow.outflow_mass));
    let span = dem.time() - t_settle;
    let outflow_rate = if span > 0.0 {
        (dem.flow.outflow_mass - m_settle) / span * 3600.0
    } else {
        0.0
    };
    let cfg = dem.config();
    let summary = json!({
        "status": match &failure { None => "completed".to_string(), Some(e) => format!("failed: {e}") },
        "scene": f.name,
        "engine": dem.engine_name(),
        "engine_version": dem.engine_version(),
        "simulated_time_s": dem.time(),
        "wall_time_s": wall_time,
        "steps": dem.step_count(),
        "dt_s": dt,
        "dt_limit_s": cfg.dt_report.limit,
        "dt_limit_reason": cfg.dt_report.limit_reason,
        "contact_time_s": cfg.dt_report.contact_time,
        "dt_fraction_of_limit": dt / cfg.dt_report.limit,
        "stage_times_s": Value::Object(stages),
        "neighbor_builds": dem.neighbor_builds(),
        "settling_time_s": settle,
        "particles_in_tube_mean": if in_tube_n > 0 { in_tube_sum / in_tube_n as Real } else { 0.0 },
        "particles_final": dem.state.len(),
        "mass_outflow_kg_per_h": outflow_rate,
        "mass_inflow_kg_per_h": if dem.time() > 0.0 { dem.flow.fed_mass / dem.time() * 3600.0 } else { 0.0 },
        "grains_fed": dem.flow.fed_count,
        "grains_out": dem.flow.outflow_count,
        "grains_lost": dem.flow.lost_count,
        "inlet_backlog_grains": dem.flow.inlet_backlog,
        "inlet_blocked_time_s": dem.flow.inlet_blocked_time,
        "threads": cfg.threads,
    });
    write_json(&out_dir.join("summary.json"), &summary)?;
    match failure {
        Some(e) => Err(e),
        None => Ok(RunOutcome { summary, out_dir }),
    }
}

fn write_json(path: &Path, v: &Value) -> Result<(), RunError> {
    let text = serde_json::to_string_pretty(v).expect("json values serialise");
    std::fs::write(path, text).map_err(|source| RunError::Io {
        path: path.display().to_string(),
        source,
    })
}
