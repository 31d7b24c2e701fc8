//! A whole run: build the engine from the scene, advance it sample interval by sample
//! interval, sample the tube, show progress, and write `summary.json` (also when the run
//! fails part-way, with what it computed up to then).

use crate::analysis::taps::{PressureTap, TapTrace};
use std::path::{Path, PathBuf};
use std::time::Instant;

use plugflow_coupling::{BackendError, DemBackend, ParticleView};
use serde_json::{json, Map, Value};

use crate::analysis::plugs::{median, PlugObservation, PlugTracker, Slicer};
use crate::analysis::profiles::{local_minima, PlugWindow, Profiles, TubeFrame, WallSpring};
use crate::analysis::targets;
use crate::cosim::{check_json, coupling_from_scene};
use crate::dem::config::LawSet;
use crate::dem::DemConfig;
use crate::engine::build_backend;
use crate::output::figures::{self, Curve, Panel};
use crate::output::hdf5::{Hdf5Output, RunMeta};
use crate::output::vtk::VtkOutput;
use crate::output::{RunOutput, Sample};
use crate::scene::schema::SnapshotFormat;
use crate::scene::{Scene, SceneError};
use crate::Real;
use plugflow_coupling::{ExchangeError, Verdict};

/// Set (by the CLI's SIGINT/SIGTERM handler) to end the running run at its next sample,
/// with every output written as for a finished run and the summary's status saying so.
pub static INTERRUPT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// What can end a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Stopped on request (Ctrl-C, SIGTERM); the outputs hold the run up to then.
    #[error("interrupted at t = {time:.6} s; outputs hold the run up to then")]
    Interrupted { time: Real },
    /// The scene is wrong.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The engine stopped (NaN, blow-up, engine failure).
    #[error("run stopped at t = {time:.6} s: {source}")]
    Backend { time: Real, source: BackendError },
    /// The gas or the exchange failed (NaN pressure, drag).
    #[error("run stopped at t = {time:.6} s: {source}")]
    Exchange { time: Real, source: ExchangeError },
    /// An output file (run.h5, VTK, figure) could not be written.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
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

/// Run a scene to its end.
pub fn run(scene: &Scene, opts: &RunOptions) -> Result<RunOutcome, RunError> {
    let cfg = DemConfig::from_scene(scene)?;
    let mut dem = build_backend(scene, &cfg)?;
    let mut gas = coupling_from_scene(scene, &cfg)?;
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
    let mut per_sample = ((f.output.sample_interval.si / dt).round() as u64).max(1);
    if let Some(g) = &gas {
        // Sample on coupling boundaries.
        per_sample = per_sample.div_ceil(g.substeps) * g.substeps;
        if opts.progress {
            for c in &g.checks {
                eprintln!(
                    "coupling check: {}: {:.4} (limit {:.4}) {:?}{}",
                    c.name,
                    c.value,
                    c.limit,
                    c.verdict,
                    if c.verdict == Verdict::Ok {
                        String::new()
                    } else {
                        format!(" — {}", c.advice)
                    }
                );
            }
        }
    }
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
    let mut dp_sum = 0.0;
    // Plug statistics on the tube's slices, from the settling time on.
    let mut tracker = cfg.tube.map(|t| {
        let slice = f.output.slice_length.map(|q| q.si).unwrap_or(3.5e-3);
        let r = 0.5 * (cfg.radius_min + cfg.radius_max);
        PlugTracker::new(
            Slicer::new(t.origin, t.axis, t.radius, t.length, slice),
            4.0 / 3.0 * std::f64::consts::PI * r * r * r,
        )
    });
    let mut profiles = cfg.tube.map(|t| {
        // "Up" across the tube: against gravity's part across the axis (any cross
        // direction for a vertical tube, where the layer profile means nothing special).
        let g = cfg.gravity;
        let ga: Real = (0..3).map(|k| g[k] * t.axis[k]).sum();
        let cross = [
            g[0] - ga * t.axis[0],
            g[1] - ga * t.axis[1],
            g[2] - ga * t.axis[2],
        ];
        let norm = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        let up = if norm > 1e-9 {
            [-cross[0] / norm, -cross[1] / norm, -cross[2] / norm]
        } else {
            plugflow_coupling::grid::perpendicular_basis(t.axis).1
        };
        // The grain–wall spring that turns overlaps into the wall stress profile.
        let wall_spring = match &cfg.laws {
            LawSet::HookeHistory(l) => WallSpring::Linear { kn: l.pw_normal.kn },
            LawSet::HookeCoulomb(l) => WallSpring::Linear { kn: l.pw_normal.kn },
            LawSet::HertzHistory(l) => WallSpring::Hertz {
                y_star: l.pw_normal.y_star,
            },
            LawSet::HertzCoulomb(l) => WallSpring::Hertz {
                y_star: l.pw_normal.y_star,
            },
        };
        Profiles::new(
            TubeFrame {
                origin: t.origin,
                axis: t.axis,
                up,
                radius: t.radius,
                length: t.length,
            },
            cfg.radius_min + cfg.radius_max,
            wall_spring,
            plug_window(&f.output),
        )
    });
    let mut porosity_rows: Vec<Vec<Real>> = Vec::new();
    let mut dp_trace: Vec<(Real, Real)> = Vec::new();
    let mut taps = TapTrace::new(
        f.output
            .pressure_taps
            .iter()
            .map(|t| PressureTap {
                name: t.name.clone(),
                from: t.from.si,
                to: t.to.si,
            })
            .collect(),
    );
    let snapshot_spec = f.output.snapshots.as_ref();
    let wants = |fmt: SnapshotFormat| snapshot_spec.is_some_and(|s| s.formats.contains(&fmt));
    let mut outputs: Vec<Box<dyn RunOutput>> = Vec::new();
    outputs.push(Box::new(Hdf5Output::create(
        &out_dir.join("run.h5"),
        &RunMeta {
            scene_text: &scene.text,
            engine: dem.engine_name(),
            engine_version: &dem.engine_version(),
            z_slices: tracker.as_ref().map(|t| {
                let s = t.slicer();
                (0..s.count).map(|k| (k as Real + 0.5) * s.slice).collect()
            }),
            z_gas: gas.as_ref().map(|g| g.axial_positions()),
            snapshots: wants(SnapshotFormat::Hdf5),
        },
    )?));
    if wants(SnapshotFormat::Vtk) {
        outputs.push(Box::new(VtkOutput::new(&out_dir)));
    }
    let samples_per_snapshot =
        snapshot_spec.map(|s| ((s.interval.si / (per_sample as Real * dt)).round() as u64).max(1));
    let mut samples_taken = 0u64;
    'run: while done < total_steps {
        let n = per_sample.min(total_steps - done);
        match gas.as_mut() {
            None => {
                if let Err(source) = dem.advance(n) {
                    failure = Some(RunError::Backend {
                        time: dem.time(),
                        source,
                    });
                    break 'run;
                }
            }
            Some(g) => {
                let mut left = n;
                while left > 0 {
                    let k = g.substeps.min(left);
                    if let Err(source) = dem.advance(k) {
                        failure = Some(RunError::Backend {
                            time: dem.time(),
                            source,
                        });
                        break 'run;
                    }
                    if let Err(source) = g.exchange(dem.as_mut()) {
                        failure = Some(RunError::Exchange {
                            time: dem.time(),
                            source,
                        });
                        break 'run;
                    }
                    left -= k;
                }
            }
        }
        done += n;
        let in_tube = particles_in_tube(&cfg, &dem.particles());
        let dp = gas.as_ref().map(|g| g.pressure_drop());
        let gas_porosity = gas.as_ref().map(|g| g.porosity_profile());
        let gas_pressure = gas.as_ref().map(|g| g.pressure_profile());
        if let (Some(p), Some(d)) = (&gas_porosity, dp) {
            porosity_rows.push(p.clone());
            dp_trace.push((dem.time(), d));
        }
        if let (Some(g), Some(profile)) = (&gas, &gas_pressure) {
            taps.push(
                dem.time(),
                &g.axial_positions(),
                profile,
                g.gas.grid().length,
            );
        }
        let frame = tracker.as_ref().map(|tr| {
            let p = dem.particles();
            tr.slicer()
                .frame(dem.time(), p.position, p.velocity, p.radius)
        });
        let plugs_before = tracker.as_ref().map_or(0, |t| t.observations.len());
        if dem.time() >= settle - 0.5 * dt {
            if outflow_at_settle.is_none() {
                outflow_at_settle = Some((dem.time(), outflow_mass(dem.as_ref())));
            }
            in_tube_sum += in_tube as Real;
            dp_sum += dp.unwrap_or(0.0);
            in_tube_n += 1;
            if let (Some(tr), Some(fr)) = (tracker.as_mut(), &frame) {
                tr.push(fr);
            }
            if let (Some(pr), Some(tr), Some(t)) = (profiles.as_mut(), tracker.as_ref(), cfg.tube) {
                let p = dem.particles();
                // The fluid forces of the exchange that ended this interval, in this order.
                let axial: Option<Vec<Real>> = gas.as_ref().and_then(|g| {
                    let f = g.fluid_forces();
                    (f.len() == p.len()).then(|| {
                        f.iter()
                            .map(|f| (0..3).map(|k| f[k] * t.axis[k]).sum())
                            .collect()
                    })
                });
                // The grains' contact forces (grain–grain and wall) along the axis, where the
                // engine gives them.
                let contact: Option<Vec<Real>> = dem.contact_forces().map(|c| {
                    c.iter()
                        .map(|f| (0..3).map(|k| f[k] * t.axis[k]).sum())
                        .collect()
                });
                pr.add_frame(
                    p.position,
                    p.velocity,
                    p.radius,
                    axial.as_deref(),
                    contact.as_deref(),
                    &tr.observations[plugs_before..],
                );
            }
        }
        let sample = Sample {
            time: dem.time(),
            particles_in_tube: in_tube,
            pressure_drop: dp,
            slices: frame.as_ref(),
            gas_porosity: gas_porosity.as_deref(),
            gas_pressure: gas_pressure.as_deref(),
            new_plugs: tracker
                .as_ref()
                .map_or(&[][..], |t| &t.observations[plugs_before..]),
        };
        let snapshot_due = samples_per_snapshot.is_some_and(|k| samples_taken.is_multiple_of(k));
        for o in outputs.iter_mut() {
            let written = o.sample(&sample).and_then(|_| {
                if snapshot_due {
                    o.snapshot(dem.time(), dem.step_count(), &dem.particles())
                } else {
                    Ok(())
                }
            });
            if let Err(e) = written {
                failure = Some(RunError::Output(e));
                break 'run;
            }
        }
        samples_taken += 1;
        if INTERRUPT.load(std::sync::atomic::Ordering::Relaxed) {
            failure = Some(RunError::Interrupted { time: dem.time() });
            break 'run;
        }
        if let Some(b) = &bar {
            b.set_position(done);
            b.set_message(format!(
                "t = {:.3}/{:.3} s, {} grains in tube{}",
                dem.time(),
                duration,
                in_tube,
                dp.map(|d| format!(", Δp {:.1} hPa/m", d / 100.0))
                    .unwrap_or_default()
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
    if let Some(g) = &gas {
        for (name, secs) in g.timer.entries() {
            stages.insert(name, json!(secs));
        }
    }
    let flow = dem.flow();
    let (t_settle, m_settle) =
        outflow_at_settle.unwrap_or((dem.time(), outflow_mass(dem.as_ref())));
    let span = dem.time() - t_settle;
    // Without the engine's counters there is no outflow figure (null in the summary).
    let outflow_rate = flow.map(|f| {
        if span > 0.0 {
            (f.outflow_mass - m_settle) / span * 3600.0
        } else {
            0.0
        }
    });
    let summary = json!({
        "status": match &failure {
            None => "completed".to_string(),
            Some(e @ RunError::Interrupted { .. }) => e.to_string(),
            Some(e) => format!("failed: {e}"),
        },
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
        "settling_time_s": settle,
        "particles_in_tube_mean": if in_tube_n > 0 { in_tube_sum / in_tube_n as Real } else { 0.0 },
        "particles_final": dem.particles().len(),
        "mass_outflow_kg_per_h": outflow_rate,
        "mass_inflow_kg_per_h": flow.map(|f| if dem.time() > 0.0 { f.fed_mass / dem.time() * 3600.0 } else { 0.0 }),
        "grains_fed": flow.map(|f| f.fed_count),
        "grains_out": flow.map(|f| f.outflow_count),
        "grains_lost": flow.map(|f| f.lost_count),
        "threads": cfg.threads,
    });
    let mut summary = summary;
    // What the numbers are worth: the DEM step against its stability limit and, with gas,
    // the gas step's time error (step doubling), the coupling checks and the clamps.
    let mut accuracy = json!({
        "dem_dt_s": dt,
        "dem_dt_limit_s": cfg.dt_report.limit,
        "dem_dt_limit_reason": cfg.dt_report.limit_reason,
        "dem_dt_fraction_of_limit": dt / cfg.dt_report.limit,
    });
    if let Some(g) = &gas {
        let a = accuracy.as_object_mut().expect("accuracy is an object");
        a.insert("gas_step_doubling_checks".into(), json!(g.doubling_checks));
        a.insert(
            "gas_step_doubling_rel_max".into(),
            json!((g.doubling_checks > 0).then_some(g.doubling_max)),
        );
        a.insert(
            "gas_step_doubling_rel_mean".into(),
            json!((g.doubling_checks > 0).then(|| g.doubling_sum / g.doubling_checks as Real)),
        );
        a.insert("gas_mass_error_rel_max".into(), json!(g.mass_error_max));
        // Clamped up to φ_min: nodes more solid than the model allows (over-packed); down to
        // φ_max: nearly empty nodes (harmless: the gas barely feels them).
        a.insert("porosity_clamped_node_steps".into(), json!(g.clamped));
        a.insert(
            "porosity_clamped_low_node_steps".into(),
            json!(g.clamped_low),
        );
        a.insert(
            "porosity_clamped_high_node_steps".into(),
            json!(g.clamped - g.clamped_low),
        );
        a.insert(
            "porosity_clamped_fraction".into(),
            json!(if g.node_steps > 0 {
                g.clamped as Real / g.node_steps as Real
            } else {
                0.0
            }),
        );
        a.insert(
            "coupling_checks".into(),
            Value::Array(g.checks.iter().map(check_json).collect()),
        );
    }
    summary
        .as_object_mut()
        .expect("summary is an object")
        .insert("accuracy".into(), accuracy);
    for (name, value) in dem.diagnostics() {
        summary
            .as_object_mut()
            .expect("summary is an object")
            .insert(name, json!(value));
    }
    if let (Some(tr), Some(tube)) = (&tracker, cfg.tube) {
        let o = summary.as_object_mut().expect("summary is an object");
        // Mid tube: plug centres within ±10 % of the tube length around its middle (the
        // seeds' statistics at z = 0.26 m of 0.525 m).
        let mid = |c: Real| (c / tube.length - 0.5).abs() <= 0.1;
        let at_mid: Vec<&PlugObservation> =
            tr.observations.iter().filter(|p| mid(p.centre)).collect();
        let tracks: std::collections::HashSet<u64> = at_mid.iter().map(|p| p.track).collect();
        let span = (dem.time() - settle).max(1e-12);
        o.insert(
            "plug_velocity_m_s".into(),
            json!(median(at_mid.iter().filter_map(|p| p.velocity).collect())),
        );
        o.insert(
            "plug_max_granular_velocity_m_s".into(),
            json!(median(at_mid.iter().map(|p| p.max_velocity).collect())),
        );
        o.insert(
            "plug_length_m".into(),
            json!(median(at_mid.iter().map(|p| p.length).collect())),
        );
        o.insert(
            "plug_min_porosity".into(),
            json!(median(at_mid.iter().map(|p| p.min_porosity).collect())),
        );
        o.insert("plug_rate_per_s".into(), json!(tracks.len() as Real / span));
        o.insert("plugs_observed_mid_tube".into(), json!(tracks.len()));
    }
    if let Some(g) = &gas {
        let o = summary.as_object_mut().expect("summary is an object");
        o.insert(
            "pressure_drop_hpa_per_m".into(),
            json!(if in_tube_n > 0 {
                dp_sum / in_tube_n as Real / 100.0
            } else {
                0.0
            }),
        );
        o.insert("gas_mass_error_rel".into(), json!(g.mass_error_max));
        o.insert(
            "porosity_clamped_fraction".into(),
            json!(if g.node_steps > 0 {
                g.clamped as Real / g.node_steps as Real
            } else {
                0.0
            }),
        );
        o.insert(
            "coupling_checks".into(),
            Value::Array(g.checks.iter().map(check_json).collect()),
        );
        o.insert("coupling_interval_s".into(), json!(g.interval));
        if !taps.taps.is_empty() {
            // Peaks and troughs: swings of at least 1 mbar (100 Pa).
            o.insert("pressure_taps".into(), taps.summary(settle, 100.0));
            let csv_path = out_dir.join("pressure_taps.csv");
            std::fs::write(&csv_path, taps.csv()).map_err(|source| RunError::Io {
                path: csv_path.display().to_string(),
                source,
            })?;
            figures::panels(
                &out_dir.join("pressure_taps.png"),
                &[Panel {
                    title: "differential pressure".into(),
                    x_label: "time t (s)".into(),
                    y_label: "p(from) − p(to) (mbar)".into(),
                    curves: taps
                        .taps
                        .iter()
                        .enumerate()
                        .map(|(k, t)| {
                            Curve::line(
                                format!("{} ({}–{} m)", t.name, t.from, t.to),
                                taps.rows.iter().map(|r| (r.0, r.1[k] / 100.0)).collect(),
                            )
                        })
                        .collect(),
                }],
                900,
                420,
            )?;
        }
        o.insert("gas_model".into(), json!(g.gas.name()));
        write_porosity_image(&out_dir, &porosity_rows)?;
        figures::panels(
            &out_dir.join("pressure_drop.png"),
            &[Panel {
                title: "pressure drop".into(),
                x_label: "time t (s)".into(),
                y_label: "−dP/dz (hPa/m)".into(),
                curves: vec![Curve::line(
                    "",
                    dp_trace.iter().map(|(t, d)| (*t, d / 100.0)).collect(),
                )],
            }],
            900,
            420,
        )?;
    }
    if let (Some(tr), Some(tube)) = (&tracker, cfg.tube) {
        if !tr.observations.is_empty() {
            figures::plug_statistics(
                &out_dir.join("plug_statistics.png"),
                &tr.observations,
                tube.length,
                (dem.time() - settle).max(1e-12),
                0.025,
            )?;
        }
    }
    if let Some(pr) = &profiles {
        let res = pr.result();
        let mut rings_min: Vec<Real> = local_minima(&res.ring_porosity)
            .into_iter()
            .map(|k| res.ring_r_over_d[k])
            .collect();
        if res.ring_porosity.len() > 1 && res.ring_porosity[0] < res.ring_porosity[1] {
            rings_min.insert(0, res.ring_r_over_d[0]);
        }
        summary
            .as_object_mut()
            .expect("summary is an object")
            .insert(
                "profiles".into(),
                json!({
                    "plugs_used": res.plugs_used,
                    "selection": {
                        "length_m": [pr.window.length.0, pr.window.length.1],
                        "velocity_m_s": [pr.window.velocity.0, pr.window.velocity.1],
                        "centre_fraction_of_tube": [pr.window.centre.0, pr.window.centre.1],
                    },
                    "xi_m": res.xi,
                    "porosity": res.porosity,
                    "granular_velocity_m_s": res.velocity,
                    "granular_temperature_m2_s2": res.temperature,
                    "wall_normal_stress_pa": res.wall_stress,
                    "drag_n_m3": res.drag,
                    "particle_force_n_m3": res.particle_force,
                    "ring_r_over_d": res.ring_r_over_d,
                    "ring_porosity": res.ring_porosity,
                    "ring_porosity_minima_r_over_d": rings_min,
                    "layer_height_over_d": res.layer_h_over_d,
                    "layer_porosity_in_plugs": res.layer_porosity_plug,
                    "layer_porosity_between_plugs": res.layer_porosity_gap,
                }),
            );
        if res.plugs_used > 0 {
            figures::profiles(&out_dir.join("profiles.png"), &res)?;
        }
        for o in outputs.iter_mut() {
            o.finish(Some(&res))?;
        }
    }
    if !f.output.reproduces.is_empty() {
        let t = targets::evaluate(&f.output.reproduces, &summary);
        summary
            .as_object_mut()
            .expect("summary is an object")
            .insert("targets".into(), t);
    }
    write_json(&out_dir.join("summary.json"), &summary)?;
    match failure {
        Some(e) => Err(e),
        None => Ok(RunOutcome { summary, out_dir }),
    }
}

/// The plugs the profiles average over: the scene's windows, each defaulting to
/// [`PlugWindow::default`]'s.
fn plug_window(o: &crate::scene::schema::OutputSpec) -> PlugWindow {
    let d = PlugWindow::default();
    let Some(p) = &o.profiles else {
        return d;
    };
    PlugWindow {
        length: p.plug_length.map_or(d.length, |r| (r[0].si, r[1].si)),
        velocity: p.plug_velocity.map_or(d.velocity, |r| (r[0].si, r[1].si)),
        centre: p.centre.map_or(d.centre, |r| (r[0].0, r[1].0)),
    }
}

/// Grains whose centre lies inside the tube (all grains without a tube).
fn particles_in_tube(cfg: &DemConfig, p: &ParticleView) -> usize {
    match &cfg.tube {
        Some(t) => p
            .position
            .iter()
            .filter(|x| {
                let s: Real = (0..3).map(|k| (x[k] - t.origin[k]) * t.axis[k]).sum();
                (0.0..=t.length).contains(&s)
            })
            .count(),
        None => p.len(),
    }
}

/// Mass that has left through the outlet so far, kg (0 without the engine's counters).
fn outflow_mass(dem: &dyn DemBackend) -> Real {
    dem.flow().map_or(0.0, |f| f.outflow_mass)
}

fn write_json(path: &Path, v: &Value) -> Result<(), RunError> {
    let text = serde_json::to_string_pretty(v).expect("json values serialise");
    std::fs::write(path, text).map_err(|source| RunError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// The spatio-temporal porosity of seed 000 fig. 3: `porosity_tz.csv` (one row per sample,
/// one column per slice) and `porosity_tz.png` (time across, tube axis up, dark = dense).
fn write_porosity_image(dir: &Path, rows: &[Vec<Real>]) -> Result<(), RunError> {
    let io = |path: &Path, source| RunError::Io {
        path: path.display().to_string(),
        source,
    };
    let csv_path = dir.join("porosity_tz.csv");
    let mut csv = String::new();
    for r in rows {
        let line: Vec<String> = r.iter().map(|v| format!("{v:.4}")).collect();
        csv.push_str(&line.join(","));
        csv.push('\n');
    }
    std::fs::write(&csv_path, csv).map_err(|e| io(&csv_path, e))?;
    if rows.is_empty() {
        return Ok(());
    }
    let (w, h) = (rows.len(), rows[0].len());
    // Porosity 0.4 → black, 1.0 → white.
    let pixels: Vec<u8> = (0..h)
        .rev()
        .flat_map(|z| {
            rows.iter().map(move |r| {
                let v = ((r[z] - 0.4) / 0.6).clamp(0.0, 1.0);
                (v * 255.0).round() as u8
            })
        })
        .collect();
    let png = crate::png::grey(w as u32, h as u32, &pixels);
    let png_path = dir.join("porosity_tz.png");
    std::fs::write(&png_path, png).map_err(|e| io(&png_path, e))
}
