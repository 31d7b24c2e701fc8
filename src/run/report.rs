//! The end of a run: its [`Summary`] from the measurements, and the figures.

use std::path::Path;

use plugflow_coupling::{Coupler, DemBackend};
use serde_json::json;

use super::sampling::{outflow_mass, Sampling};
use super::RunError;
use crate::analysis::plugs::{median, passage_rates, PlugObservation};
use crate::analysis::profiles::{local_minima, ProfileResult, Profiles};
use crate::analysis::targets;
use crate::dem::DemConfig;
use crate::output::figures::{self, Curve, Panel};
use crate::scene::Scene;
use crate::setup::check_row;
use crate::summary::{Accuracy, GasAccuracy, GasSummary, PlugSummary, Summary, TubeWallForce};
use crate::Real;

/// Everything the summary is made from.
pub struct Ending<'a> {
    pub scene: &'a Scene,
    pub cfg: &'a DemConfig,
    pub dem: &'a dyn DemBackend,
    pub gas: Option<&'a Coupler>,
    pub sampling: &'a Sampling,
    /// The profiles over the selected plugs, averaged once at the end (scenes with a tube).
    pub profiles: Option<&'a ProfileResult>,
    pub status: String,
    pub wall_time: Real,
}

/// The summary of a run (also of one that stopped part-way: what it computed up to then).
pub fn summarize(e: &Ending) -> Summary {
    let (dem, cfg, s) = (e.dem, e.cfg, e.sampling);
    let dt = dem.time_step();
    let mut stage_times = std::collections::BTreeMap::new();
    for (name, secs) in dem.stage_times() {
        stage_times.insert(name, secs);
    }
    if let Some(g) = e.gas {
        for (name, secs) in g.timer.entries() {
            stage_times.insert(name, secs);
        }
    }
    let flow = dem.flow();
    let periodic = cfg.tube.is_some_and(|t| t.periodic);
    let feed = feed_account(cfg, dem);
    let wall_means = s.wall_force_means().unwrap_or_default();
    let (t_settle, m_settle) = s
        .outflow_at_settle
        .unwrap_or((dem.time(), outflow_mass(dem)));
    let span = dem.time() - t_settle;
    // Without the engine's counters there is no outflow figure (null in the summary).
    let outflow_rate = flow.map(|f| {
        if span > 0.0 {
            (f.outflow_mass - m_settle) / span * 3600.0
        } else {
            0.0
        }
    });
    let clamped_fraction = |g: &Coupler| {
        if g.stats.node_steps > 0 {
            g.stats.clamped as Real / g.stats.node_steps as Real
        } else {
            0.0
        }
    };
    let checks = |g: &Coupler| g.checks.iter().map(check_row).collect::<Vec<_>>();
    // What the numbers are worth: the DEM step against its stability limit and, with gas,
    // the gas step's time error (step doubling), the coupling checks and the clamps.
    let accuracy = Accuracy {
        dem_dt_s: dt,
        dem_dt_limit_s: cfg.dt_report.limit,
        dem_dt_limit_reason: cfg.dt_report.limit_reason.clone(),
        dem_dt_fraction_of_limit: dt / cfg.dt_report.limit,
        gas: e.gas.map(|g| {
            let st = &g.stats;
            GasAccuracy {
                gas_step_doubling_checks: st.doubling_checks,
                gas_step_doubling_rel_max: (st.doubling_checks > 0).then_some(st.doubling_max),
                gas_step_doubling_rel_mean: (st.doubling_checks > 0)
                    .then(|| st.doubling_sum / st.doubling_checks as Real),
                gas_mass_error_rel_max: st.mass_error_max,
                // Clamped up to φ_min: nodes more solid than the model allows (over-packed);
                // down to φ_max: nearly empty nodes (harmless: the gas barely feels them).
                porosity_clamped_node_steps: st.clamped,
                porosity_clamped_low_node_steps: st.clamped_low,
                porosity_clamped_high_node_steps: st.clamped - st.clamped_low,
                porosity_clamped_fraction: clamped_fraction(g),
                coupling_checks: checks(g),
            }
        }),
    };
    let plugs = match (&s.tracker, cfg.tube) {
        (Some(tr), Some(tube)) => {
            // Mid tube: plug centres within ±10 % of the tube length around its middle (the
            // seeds' statistics at z = 0.26 m of 0.525 m).
            let mid = |c: Real| (c / tube.length - 0.5).abs() <= 0.1;
            let at_mid: Vec<&PlugObservation> =
                tr.observations.iter().filter(|p| mid(p.centre)).collect();
            let tracks: std::collections::HashSet<u64> = at_mid.iter().map(|p| p.track).collect();
            let span = (dem.time() - s.settle).max(1e-12);
            // Seed 000 fig. 9: passages through six heights across the middle 60 %.
            let heights: Vec<Real> = (0..6)
                .map(|k| tube.length * (0.25 + 0.1 * k as Real))
                .collect();
            let passages = passage_rates(&tr.observations, &heights, dem.time() - s.settle);
            Some(PlugSummary {
                plug_velocity_m_s: median(at_mid.iter().filter_map(|p| p.velocity).collect()),
                plug_max_granular_velocity_m_s: median(
                    at_mid.iter().map(|p| p.max_velocity).collect(),
                ),
                plug_length_m: median(at_mid.iter().map(|p| p.length).collect()),
                plug_min_porosity: median(at_mid.iter().map(|p| p.min_porosity).collect()),
                plug_rate_per_s: tracks.len() as Real / span,
                plugs_observed_mid_tube: tracks.len(),
                plug_passages_by_height: passages
                    .as_ref()
                    .map(|p| p.rates.clone())
                    .unwrap_or_default(),
                plug_rate_change_middle: passages.as_ref().map(|p| p.change),
                plug_rate_change_middle_se: passages.as_ref().map(|p| p.change_se),
            })
        }
        _ => None,
    };
    let gas = e.gas.map(|g| GasSummary {
        // No sample after the settling time: not measured, `null` in summary.json (NaN is
        // written as null and read back as NaN), never 0.
        pressure_drop_hpa_per_m: if s.in_tube_n > 0 {
            s.dp_sum / s.in_tube_n as Real / 100.0
        } else {
            Real::NAN
        },
        gas_mass_error_rel: g.stats.mass_error_max,
        porosity_clamped_fraction: clamped_fraction(g),
        coupling_checks: checks(g),
        coupling_interval_s: g.interval,
        // Peaks and troughs: swings of at least 1 mbar (100 Pa).
        pressure_taps: (!s.taps.taps.is_empty()).then(|| s.taps.summary(s.settle, 100.0)),
        gas_model: g.gas.name().to_string(),
    });
    let mut summary = Summary {
        status: e.status.clone(),
        scene: e.scene.file.name.clone(),
        engine: dem.engine_name().to_string(),
        engine_version: dem.engine_version(),
        simulated_time_s: dem.time(),
        wall_time_s: e.wall_time,
        steps: dem.step_count(),
        dt_s: dt,
        dt_limit_s: cfg.dt_report.limit,
        dt_limit_reason: cfg.dt_report.limit_reason.clone(),
        contact_time_s: cfg.dt_report.contact_time,
        dt_fraction_of_limit: dt / cfg.dt_report.limit,
        stage_times_s: stage_times,
        settling_time_s: s.settle,
        particles_in_tube_mean: if s.in_tube_n > 0 {
            s.in_tube_sum / s.in_tube_n as Real
        } else {
            Real::NAN
        },
        particles_final: dem.particles().len(),
        mass_outflow_kg_per_h: outflow_rate.filter(|_| !periodic),
        solids_mass_flow_kg_per_h: (periodic && s.in_tube_n > 0)
            .then(|| s.mass_flow_sum / s.in_tube_n as Real * 3600.0),
        mass_inflow_kg_per_h: flow.map(|f| {
            if dem.time() > 0.0 {
                f.fed_mass / dem.time() * 3600.0
            } else {
                0.0
            }
        }),
        grains_fed: flow.map(|f| f.fed_count),
        grains_out: flow.map(|f| f.outflow_count),
        grains_lost: flow.map(|f| f.lost_count),
        grains_asked: feed.map(|(asked, _)| asked),
        feed_backlog_grains: feed.map(|(_, owed)| owed),
        threads: cfg.threads,
        ranks: dem.ranks().size,
        wall_forces_mean_n: wall_means.iter().cloned().collect(),
        tube_wall_force_mean_n: cfg.tube.and_then(|t| {
            let (_, f) = wall_means.iter().find(|(w, _)| w == "tube")?;
            let (axial, cross_axis) = crate::output::hdf5::axial_split(*f, t.axis);
            Some(TubeWallForce { axial, cross_axis })
        }),
        accuracy,
        plugs,
        gas,
        slug: s.slug.as_ref().and_then(|sl| {
            let g = (0..3)
                .map(|k| cfg.gravity[k] * cfg.gravity[k])
                .sum::<Real>()
                .sqrt();
            sl.summary(s.settle, g, 2.0 * cfg.tube.map_or(0.0, |t| t.radius))
        }),
        profiles: s
            .profiles
            .as_ref()
            .zip(e.profiles)
            .map(|(pr, res)| profiles_json(pr, res)),
        targets: None,
        warnings: run_warnings(e, feed),
        diagnostics: dem
            .diagnostics()
            .into_iter()
            .map(|(k, v)| (k, json!(v)))
            .collect(),
    };
    let reproduces = &e.scene.file.output.reproduces;
    if !reproduces.is_empty() {
        summary.targets = Some(targets::evaluate(reproduces, &summary));
    }
    summary
}

/// What the scene's inlet asked for up to now (rate × feeding time, whole grains) and what
/// the engine still owes (asked − fed; negative: fed ahead of the rate, as a batch may): the
/// same account for every engine with flow counters, whatever its feeder.
fn feed_account(cfg: &DemConfig, dem: &dyn DemBackend) -> Option<(u64, i64)> {
    let (inlet, flow) = (cfg.inlet?, dem.flow()?);
    let feeding = dem
        .time()
        .min(inlet.until.unwrap_or(Real::INFINITY))
        .max(0.0);
    let asked = (inlet.rate * feeding).floor() as u64;
    Some((asked, asked as i64 - flow.fed_count as i64))
}

/// The warnings a reader of the summary must see beside its numbers.
fn run_warnings(e: &Ending, feed: Option<(u64, i64)>) -> Vec<String> {
    let (dem, s) = (e.dem, e.sampling);
    let mut warnings = Vec::new();
    if s.in_tube_n == 0 {
        warnings.push(format!(
            "no sample after the settling time ({} s; the run ended at {} s): the means \
             (grains in the tube, pressure drop) are not measured (null); run longer or \
             lower output.settling_time",
            s.settle,
            dem.time()
        ));
    }
    if let (Some((asked, owed)), Some(inlet)) = (feed, e.cfg.inlet) {
        // Within one batch (a full inlet slab) and 1 % of the feed, the feed is what the
        // scene asked; beyond, the numbers belong to a smaller feed than the scene's.
        let allowed = (inlet.batch_target as f64)
            .max(0.01 * asked as f64)
            .max(2.0);
        if owed as f64 > allowed {
            warnings.push(format!(
                "the {} engine fed {} of the {asked} grains the inlet asked for ({owed} owed, \
                 {:.1} %): the inlet slab was blocked or the engine could not place them; the \
                 flow is that of a smaller feed than inlet.rate says",
                dem.engine_name(),
                asked as i64 - owed,
                100.0 * owed as f64 / asked.max(1) as f64
            ));
        }
    }
    if let Some(f) = dem.flow() {
        // Grains escaping the tube (not through its outlet) are a leak in the geometry or
        // an explosion, not transport: most of the feed lost means no conveying was measured.
        // Every grain the run held: those still in, out through the outlet, and lost.
        let held = dem.particles().len() as u64 + f.outflow_count + f.lost_count;
        if f.lost_count > 0 && 2 * f.lost_count > held {
            warnings.push(format!(
                "the {} engine lost {} of the {held} grains the run held (not through the \
                 outlet; {} fed): most grains escaped the tube or the domain; check the \
                 geometry, walls and time step",
                dem.engine_name(),
                f.lost_count,
                f.fed_count
            ));
        }
    }
    warnings
}

/// The profiles block of the summary.
fn profiles_json(pr: &Profiles, res: &ProfileResult) -> serde_json::Value {
    let mut rings_min: Vec<Real> = local_minima(&res.ring_porosity)
        .into_iter()
        .map(|k| res.ring_r_over_d[k])
        .collect();
    if res.ring_porosity.len() > 1 && res.ring_porosity[0] < res.ring_porosity[1] {
        rings_min.insert(0, res.ring_r_over_d[0]);
    }
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
        "layer_granular_velocity_in_plugs_m_s": res.layer_velocity_plug,
        "upper_over_lower_granular_velocity_in_plugs": res.upper_over_lower_velocity_plug,
    })
}

/// The figures and tables beside the summary: pressure taps, the spatio-temporal porosity,
/// the pressure drop, plug statistics, profiles.
pub fn write_figures(
    out_dir: &Path,
    cfg: &DemConfig,
    dem: &dyn DemBackend,
    gas: Option<&Coupler>,
    s: &Sampling,
    profiles: Option<&ProfileResult>,
) -> Result<(), RunError> {
    if gas.is_some() {
        if !s.taps.taps.is_empty() {
            let csv_path = out_dir.join("pressure_taps.csv");
            std::fs::write(&csv_path, s.taps.csv()).map_err(|source| RunError::Io {
                path: csv_path.display().to_string(),
                source,
            })?;
            figures::panels(
                &out_dir.join("pressure_taps.png"),
                &[Panel {
                    title: "differential pressure".into(),
                    x_label: "time t (s)".into(),
                    y_label: "p(from) − p(to) (mbar)".into(),
                    curves: s
                        .taps
                        .taps
                        .iter()
                        .enumerate()
                        .map(|(k, t)| {
                            Curve::line(
                                format!("{} ({}–{} m)", t.name, t.from, t.to),
                                s.taps.rows.iter().map(|r| (r.0, r.1[k] / 100.0)).collect(),
                            )
                        })
                        .collect(),
                }],
                900,
                420,
            )?;
        }
        let times: Vec<Real> = s.dp_trace.iter().map(|d| d.0).collect();
        let z = gas.map(|g| g.axial_positions()).unwrap_or_default();
        write_porosity_image(out_dir, &times, &z, &s.porosity_rows)?;
        figures::panels(
            &out_dir.join("pressure_drop.png"),
            &[Panel {
                title: "pressure drop".into(),
                x_label: "time t (s)".into(),
                y_label: "−dP/dz (hPa/m)".into(),
                curves: vec![Curve::line(
                    "",
                    s.dp_trace.iter().map(|(t, d)| (*t, d / 100.0)).collect(),
                )],
            }],
            900,
            420,
        )?;
    }
    if let (Some(tr), Some(tube)) = (&s.tracker, cfg.tube) {
        if !tr.observations.is_empty() {
            figures::plug_statistics(
                &out_dir.join("plug_statistics.png"),
                &tr.observations,
                tube.length,
                (dem.time() - s.settle).max(1e-12),
                0.025,
            )?;
        }
    }
    if let Some(sl) = &s.slug {
        let csv_path = out_dir.join("slug.csv");
        std::fs::write(&csv_path, sl.csv()).map_err(|source| RunError::Io {
            path: csv_path.display().to_string(),
            source,
        })?;
    }
    if let Some(res) = profiles.filter(|r| r.plugs_used > 0) {
        figures::profiles(&out_dir.join("profiles.png"), res)?;
    }
    Ok(())
}

/// The spatio-temporal porosity of seed 000 fig. 3: `porosity_tz.csv` (one row per sample,
/// one column per gas node plane) and `porosity_tz.png` (time across, tube axis up, dark =
/// dense, with axes and a colour bar).
fn write_porosity_image(
    dir: &Path,
    times: &[Real],
    z: &[Real],
    rows: &[Vec<Real>],
) -> Result<(), RunError> {
    let csv_path = dir.join("porosity_tz.csv");
    let mut csv = String::new();
    for r in rows {
        let line: Vec<String> = r.iter().map(|v| format!("{v:.4}")).collect();
        csv.push_str(&line.join(","));
        csv.push('\n');
    }
    std::fs::write(&csv_path, csv).map_err(|source| RunError::Io {
        path: csv_path.display().to_string(),
        source,
    })?;
    if rows.is_empty() {
        return Ok(());
    }
    // Porosity 0.4 (denser than any packing here) → black, 1.0 → white.
    figures::spacetime(
        &dir.join("porosity_tz.png"),
        "porosity",
        times,
        z,
        rows,
        (0.4, 1.0),
    )?;
    Ok(())
}
