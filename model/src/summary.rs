//! `summary.json`, typed: one struct written by `run` and read by `sweep`, `study`,
//! `crosscheck` and the targets, so a key is spelled once and a typo does not compile.
//! The headline numbers that reports tabulate are named by [`Number`].
//!
//! Keys that do not apply to a run are absent (no gas: no `pressure_drop_hpa_per_m`); a
//! key that applies but was not measured is `null` (an engine without flow counters: no
//! `mass_outflow_kg_per_h`), never 0.

use std::collections::BTreeMap;

use serde::{Deserialize, Deserializer, Serialize};
use serde_json::Value;

use crate::Real;

/// A number that JSON may hold as `null` (serde_json writes NaN and infinities as `null`):
/// read back as NaN, so a failed run's summary still parses.
fn nullable<'de, D: Deserializer<'de>>(d: D) -> Result<Real, D::Error> {
    Ok(Option::<Real>::deserialize(d)?.unwrap_or(Real::NAN))
}

/// Two numbers of which JSON may hold either as `null` (read back as NaN).
fn nullable_pair<'de, D: Deserializer<'de>>(d: D) -> Result<[Real; 2], D::Error> {
    let [a, b] = <[Option<Real>; 2]>::deserialize(d)?;
    Ok([a.unwrap_or(Real::NAN), b.unwrap_or(Real::NAN)])
}

/// The whole summary of a run.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    /// `completed`, `interrupted at t = …`, or `failed: …` naming the step and grain.
    pub status: String,
    /// The scene's name.
    pub scene: String,
    pub engine: String,
    pub engine_version: String,
    #[serde(deserialize_with = "nullable")]
    pub simulated_time_s: Real,
    #[serde(deserialize_with = "nullable")]
    pub wall_time_s: Real,
    pub steps: u64,
    #[serde(deserialize_with = "nullable")]
    pub dt_s: Real,
    #[serde(deserialize_with = "nullable")]
    pub dt_limit_s: Real,
    pub dt_limit_reason: String,
    #[serde(deserialize_with = "nullable")]
    pub contact_time_s: Real,
    #[serde(deserialize_with = "nullable")]
    pub dt_fraction_of_limit: Real,
    /// Wall time of each timed stage (the engine's and the coupler's), s.
    pub stage_times_s: BTreeMap<String, Real>,
    #[serde(deserialize_with = "nullable")]
    pub settling_time_s: Real,
    /// Mean grains in the tube after the settling time.
    #[serde(deserialize_with = "nullable")]
    pub particles_in_tube_mean: Real,
    pub particles_final: usize,
    /// None: the engine keeps no flow counters, or a periodic section (no outlet).
    pub mass_outflow_kg_per_h: Option<Real>,
    /// A periodic section: the mean solids mass flow through any cross-section after the
    /// settling time, Σ m_i v_i·axis / L, kg/h (absent for open tubes: see the outflow).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solids_mass_flow_kg_per_h: Option<Real>,
    pub mass_inflow_kg_per_h: Option<Real>,
    pub grains_fed: Option<u64>,
    pub grains_out: Option<u64>,
    pub grains_lost: Option<u64>,
    /// Grains the scene's inlet asked for up to the end (rate × feeding time; scenes with an
    /// inlet), and what it still owed: asked − fed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grains_asked: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_backlog_grains: Option<i64>,
    pub threads: usize,
    /// MPI ranks the engine ran on (LIGGGHTS under `mpirun`; 1 for one process).
    #[serde(default = "one_rank")]
    pub ranks: usize,
    /// Mean force of the grains on each wall the engine reports, after the settling time, N
    /// (absent: no sample in the window, or an engine without wall forces).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub wall_forces_mean_n: BTreeMap<String, [Real; 3]>,
    /// The tube wall's mean force split along and across its axis (scenes with a tube).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tube_wall_force_mean_n: Option<TubeWallForce>,
    /// What the numbers are worth.
    pub accuracy: Accuracy,
    /// Plug statistics at mid tube (scenes with a tube).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub plugs: Option<PlugSummary>,
    /// The gas (scenes with `[gas]`).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub gas: Option<GasSummary>,
    /// A periodic section's slug, measured as Lethe measures it (`analysis/slug.rs`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slug: Option<SlugSummary>,
    /// Profiles averaged over the selected plugs (scenes with a tube).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub profiles: Option<Value>,
    /// TARGETS.md rows the scene reproduces: measured beside paper, band and verdict.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<Vec<TargetRow>>,
    /// What a reader of the numbers must know (an empty averaging window, a feed that fell
    /// behind, grains lost): also printed at the end of the run.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The engine's own diagnostics (neighbour builds, inlet backlog, …): every key not
    /// named above (last, so that the named groups take theirs first when read).
    #[serde(flatten)]
    pub diagnostics: BTreeMap<String, Value>,
}

/// The grains' force on the tube wall: along the axis (+ in the flow direction: the
/// friction by which the wall holds the grains back) and the magnitude across it, N.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct TubeWallForce {
    pub axial: Real,
    pub cross_axis: Real,
}

/// The accuracy block.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Accuracy {
    #[serde(deserialize_with = "nullable")]
    pub dem_dt_s: Real,
    #[serde(deserialize_with = "nullable")]
    pub dem_dt_limit_s: Real,
    pub dem_dt_limit_reason: String,
    #[serde(deserialize_with = "nullable")]
    pub dem_dt_fraction_of_limit: Real,
    /// With gas: step doubling, mass balance, clamps, coupling checks.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub gas: Option<GasAccuracy>,
}

/// The gas's part of the accuracy block.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GasAccuracy {
    pub gas_step_doubling_checks: u64,
    /// None: no estimate was taken (a run of fewer than 100 exchanges).
    pub gas_step_doubling_rel_max: Option<Real>,
    pub gas_step_doubling_rel_mean: Option<Real>,
    #[serde(deserialize_with = "nullable")]
    pub gas_mass_error_rel_max: Real,
    pub porosity_clamped_node_steps: u64,
    pub porosity_clamped_low_node_steps: u64,
    pub porosity_clamped_high_node_steps: u64,
    #[serde(deserialize_with = "nullable")]
    pub porosity_clamped_fraction: Real,
    pub coupling_checks: Vec<CheckRow>,
}

/// One coupling check as reported.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CheckRow {
    pub name: String,
    #[serde(deserialize_with = "nullable")]
    pub value: Real,
    #[serde(deserialize_with = "nullable")]
    pub limit: Real,
    /// `ok`, `warning` or `refused`.
    pub verdict: String,
    pub advice: String,
}

/// Plug statistics: medians over the plugs seen at mid tube (None: no plug seen).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PlugSummary {
    /// Tracked plug velocity, m/s.
    pub plug_velocity_m_s: Option<Real>,
    /// The largest granular velocity in a plug (the seeds' reading), m/s.
    pub plug_max_granular_velocity_m_s: Option<Real>,
    pub plug_length_m: Option<Real>,
    pub plug_min_porosity: Option<Real>,
    #[serde(deserialize_with = "nullable")]
    pub plug_rate_per_s: Real,
    pub plugs_observed_mid_tube: usize,
    /// Plugs passing upward through six heights across the middle 60 % of the tube, per
    /// second, as [height m, rate] (seed 000 fig. 9); empty where none passed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub plug_passages_by_height: Vec<[Real; 2]>,
    /// Relative change of that count from the lowest height to the highest, over the mean
    /// count, and its standard error (the plugs that begin or end between neighbouring
    /// heights taken as Poisson counts: an upper bound); absent where nothing passed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plug_rate_change_middle: Option<Real>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plug_rate_change_middle_se: Option<Real>,
}

/// The gas's headline numbers.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GasSummary {
    /// Mean after the settling time of the gas solver's pressure drop per length
    /// (P'(z₁)/(L − z₁), z₁ the first gas node plane), hPa/m.
    #[serde(deserialize_with = "nullable")]
    pub pressure_drop_hpa_per_m: Real,
    #[serde(deserialize_with = "nullable")]
    pub gas_mass_error_rel: Real,
    #[serde(deserialize_with = "nullable")]
    pub porosity_clamped_fraction: Real,
    pub coupling_checks: Vec<CheckRow>,
    #[serde(deserialize_with = "nullable")]
    pub coupling_interval_s: Real,
    /// Differential pressure transducers (scenes with `output.pressure_taps`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressure_taps: Option<Value>,
    pub gas_model: String,
}

/// One TARGETS.md row as measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TargetRow {
    pub id: String,
    pub what: String,
    pub measured: Option<Real>,
    /// NaN (`null`) where the paper states a direction, not a number (V12).
    #[serde(deserialize_with = "nullable")]
    pub paper: Real,
    /// An open end is infinite (`null` in JSON, read back as NaN).
    #[serde(deserialize_with = "nullable_pair")]
    pub band: [Real; 2],
    pub ratio: Option<Real>,
    pub inside: bool,
}

/// The headline numbers reports tabulate, each one key of the summary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Number {
    PressureDrop,
    ParticlesInTube,
    MassOutflow,
    PlugVelocity,
    PlugMaxGranularVelocity,
    PlugLength,
    PlugMinPorosity,
    PlugRate,
    PlugRateChangeUpperBound,
    UpperOverLowerVelocityInPlugs,
    SimulatedTime,
    WallTime,
}

impl Number {
    /// Every number, in the order of the summary.
    pub const ALL: [Number; 12] = [
        Number::PressureDrop,
        Number::ParticlesInTube,
        Number::MassOutflow,
        Number::PlugVelocity,
        Number::PlugMaxGranularVelocity,
        Number::PlugLength,
        Number::PlugMinPorosity,
        Number::PlugRate,
        Number::PlugRateChangeUpperBound,
        Number::UpperOverLowerVelocityInPlugs,
        Number::SimulatedTime,
        Number::WallTime,
    ];

    /// Its key in `summary.json` (and the column name in sweep.csv, study.csv).
    pub const fn key(self) -> &'static str {
        match self {
            Number::PressureDrop => "pressure_drop_hpa_per_m",
            Number::ParticlesInTube => "particles_in_tube_mean",
            Number::MassOutflow => "mass_outflow_kg_per_h",
            Number::PlugVelocity => "plug_velocity_m_s",
            Number::PlugMaxGranularVelocity => "plug_max_granular_velocity_m_s",
            Number::PlugLength => "plug_length_m",
            Number::PlugMinPorosity => "plug_min_porosity",
            Number::PlugRate => "plug_rate_per_s",
            Number::PlugRateChangeUpperBound => "plug_rate_change_middle_upper_2se",
            Number::UpperOverLowerVelocityInPlugs => "upper_over_lower_granular_velocity_in_plugs",
            Number::SimulatedTime => "simulated_time_s",
            Number::WallTime => "wall_time_s",
        }
    }

    /// The number named by `key`, or an error listing the known keys.
    pub fn from_key(key: &str) -> Result<Number, String> {
        Number::ALL
            .into_iter()
            .find(|n| n.key() == key)
            .ok_or_else(|| {
                format!(
                    "`{key}` is not a number of the summary (known: {})",
                    Number::ALL.map(|n| n.key()).join(", ")
                )
            })
    }

    /// Its value in `s`; None where the run did not measure it (no gas, no plug, no flow
    /// counters) or it is not finite.
    pub fn of(self, s: &Summary) -> Option<Real> {
        let plugs = s.plugs.as_ref();
        let v = match self {
            Number::PressureDrop => s.gas.as_ref().map(|g| g.pressure_drop_hpa_per_m),
            Number::ParticlesInTube => Some(s.particles_in_tube_mean),
            Number::MassOutflow => s.mass_outflow_kg_per_h,
            Number::PlugVelocity => plugs.and_then(|p| p.plug_velocity_m_s),
            Number::PlugMaxGranularVelocity => plugs.and_then(|p| p.plug_max_granular_velocity_m_s),
            Number::PlugLength => plugs.and_then(|p| p.plug_length_m),
            Number::PlugMinPorosity => plugs.and_then(|p| p.plug_min_porosity),
            Number::PlugRate => plugs.map(|p| p.plug_rate_per_s),
            // The change of the plug rate along the tube plus two standard errors: below
            // zero, the rate falls with height beyond the counting noise.
            Number::PlugRateChangeUpperBound => plugs.and_then(|p| {
                Some(p.plug_rate_change_middle? + 2.0 * p.plug_rate_change_middle_se?)
            }),
            // (In the profiles block, averaged over the run's slugs.)
            Number::UpperOverLowerVelocityInPlugs => s
                .profiles
                .as_ref()
                .and_then(|p| p.get(self.key()))
                .and_then(Value::as_f64),
            Number::SimulatedTime => Some(s.simulated_time_s),
            Number::WallTime => Some(s.wall_time_s),
        };
        v.filter(|x| x.is_finite())
    }
}

impl std::fmt::Display for Number {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// Errors of reading a summary back.
#[derive(Debug, thiserror::Error)]
pub enum SummaryError {
    #[error("cannot read `{path}`: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("`{path}` is not a plugflow summary: {source}")]
    Parse {
        path: String,
        source: serde_json::Error,
    },
}

impl Summary {
    /// Read `summary.json`.
    pub fn read(path: &std::path::Path) -> Result<Summary, SummaryError> {
        let text = std::fs::read_to_string(path).map_err(|source| SummaryError::Io {
            path: path.display().to_string(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|source| SummaryError::Parse {
            path: path.display().to_string(),
            source,
        })
    }

    /// The summary as JSON text (as written to `summary.json`).
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).expect("a summary serialises")
    }

    /// True for a run that went to its end.
    pub fn completed(&self) -> bool {
        self.status == "completed"
    }
}

/// A summary of a run that took `wall_time_s` and measured only `pressure_drop` (hPa/m),
/// spending half its time in the gas: for the unit tests of the summary's readers (the
/// study's, here and in `plugflow`).
#[doc(hidden)]
pub fn test_summary(status: &str, wall_time_s: Real, pressure_drop: Option<Real>) -> Summary {
    Summary {
        status: status.into(),
        scene: "test".into(),
        engine: "native".into(),
        engine_version: String::new(),
        simulated_time_s: 1.0,
        wall_time_s,
        steps: 1,
        dt_s: 1e-6,
        dt_limit_s: 1e-5,
        dt_limit_reason: String::new(),
        contact_time_s: 1e-4,
        dt_fraction_of_limit: 0.1,
        stage_times_s: [("gas".to_string(), wall_time_s / 2.0)].into(),
        settling_time_s: 0.0,
        particles_in_tube_mean: 0.0,
        particles_final: 0,
        mass_outflow_kg_per_h: None,
        solids_mass_flow_kg_per_h: None,
        mass_inflow_kg_per_h: None,
        grains_fed: None,
        grains_out: None,
        grains_lost: None,
        grains_asked: None,
        feed_backlog_grains: None,
        threads: 1,
        ranks: 1,
        wall_forces_mean_n: BTreeMap::new(),
        tube_wall_force_mean_n: None,
        accuracy: Accuracy {
            dem_dt_s: 1e-6,
            dem_dt_limit_s: 1e-5,
            dem_dt_limit_reason: String::new(),
            dem_dt_fraction_of_limit: 0.1,
            gas: None,
        },
        plugs: None,
        slug: None,
        gas: pressure_drop.map(|dp| GasSummary {
            pressure_drop_hpa_per_m: dp,
            gas_mass_error_rel: 0.0,
            porosity_clamped_fraction: 0.0,
            coupling_checks: Vec::new(),
            coupling_interval_s: 1e-5,
            pressure_taps: None,
            gas_model: "darcy".into(),
        }),
        profiles: None,
        targets: None,
        warnings: Vec::new(),
        diagnostics: BTreeMap::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A summary with every optional group present (a tube, gas, taps, profiles, targets).
    fn full() -> Summary {
        let mut s = test_summary("completed", 1.0, Some(30.0));
        if let Some(g) = s.gas.as_mut() {
            g.pressure_taps = Some(serde_json::json!([]));
        }
        s.plugs = Some(PlugSummary {
            plug_velocity_m_s: Some(0.2),
            plug_max_granular_velocity_m_s: Some(0.3),
            plug_length_m: Some(0.02),
            plug_min_porosity: Some(0.45),
            plug_rate_per_s: 1.0,
            plugs_observed_mid_tube: 3,
            plug_passages_by_height: vec![[0.1, 2.0], [0.2, 1.0]],
            plug_rate_change_middle: Some(-0.5),
            plug_rate_change_middle_se: Some(0.1),
        });
        s.profiles = Some(serde_json::json!({}));
        s.targets = Some(Vec::new());
        s.solids_mass_flow_kg_per_h = Some(1.0);
        s.slug = Some(SlugSummary {
            samples: 1,
            slug_seen_fraction: 1.0,
            slug_velocity_m_s: None,
            slug_grain_velocity_m_s: None,
            slug_length_m: None,
            gas_mean_superficial_velocity_m_s: None,
            lavrinec_slug_velocity_m_s: None,
        });
        s.grains_asked = Some(10);
        s.feed_backlog_grains = Some(1);
        s.wall_forces_mean_n = [("tube".to_string(), [0.0, 0.0, 1e-3])].into();
        s.tube_wall_force_mean_n = Some(TubeWallForce {
            axial: 1e-3,
            cross_axis: 0.0,
        });
        s
    }

    /// README's key table lists exactly the summary's top-level keys (the engine's
    /// diagnostics aside, which the paragraph under the table names).
    #[test]
    fn readme_lists_every_summary_key() {
        let readme = include_str!("../../README.md");
        let start = readme
            .find("### summary.json")
            .expect("README has the section");
        let section = &readme[start..];
        let end = section[4..].find("\n#").map_or(section.len(), |e| e + 4);
        let mut listed: Vec<String> = section[..end]
            .lines()
            .filter(|l| l.starts_with("| `"))
            .flat_map(|l| {
                let first = l.split('|').nth(1).unwrap_or("");
                first
                    .split('`')
                    .enumerate()
                    .filter(|(k, _)| k % 2 == 1)
                    .map(|(_, key)| key.to_string())
                    .collect::<Vec<_>>()
            })
            .collect();
        listed.sort();
        let value = serde_json::to_value(full()).unwrap();
        let mut keys: Vec<String> = value.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        assert_eq!(
            listed, keys,
            "README's summary.json table against the struct"
        );
    }

    /// What is written reads back as the same summary; NaN (written as null) reads as NaN.
    #[test]
    fn a_summary_reads_back_and_null_numbers_read_as_nan() {
        let s = full();
        let text = s.to_json_pretty();
        let back: Summary = serde_json::from_str(&text).unwrap();
        assert_eq!(
            serde_json::to_value(&back).unwrap(),
            serde_json::to_value(&s).unwrap()
        );
        let mut failed = s.clone();
        failed.particles_in_tube_mean = Real::NAN;
        let back: Summary = serde_json::from_str(&failed.to_json_pretty()).unwrap();
        assert!(back.particles_in_tube_mean.is_nan());
        assert_eq!(Number::ParticlesInTube.of(&back), None);
        assert_eq!(Number::PressureDrop.of(&back), Some(30.0));
        // Every number's key names itself, and only itself.
        for n in Number::ALL {
            assert_eq!(Number::from_key(n.key()), Ok(n));
        }
        assert!(Number::from_key("pressure_drop").is_err());
    }
}

/// Mean and standard deviation of a quantity over the samples that have it.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct MeanStd {
    pub mean: Real,
    pub std: Real,
    pub samples: usize,
}

impl MeanStd {
    /// None for no values.
    pub fn of(values: &[Real]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let n = values.len() as Real;
        let mean = values.iter().sum::<Real>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<Real>() / n;
        Some(Self {
            mean,
            std: var.sqrt(),
            samples: values.len(),
        })
    }
}

/// The summary's slug numbers (Lethe's five quantities and Lavrinec's correlation).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SlugSummary {
    pub samples: usize,
    /// Share of the samples that saw a slug.
    pub slug_seen_fraction: Real,
    pub slug_velocity_m_s: Option<MeanStd>,
    pub slug_grain_velocity_m_s: Option<MeanStd>,
    pub slug_length_m: Option<MeanStd>,
    pub gas_mean_superficial_velocity_m_s: Option<MeanStd>,
    /// Lavrinec et al. (2020): 0.967 ū_p + 0.5 √(g D), from the grains' mean speed, m/s.
    pub lavrinec_slug_velocity_m_s: Option<Real>,
}

/// A summary written before runs on several ranks existed ran on one.
fn one_rank() -> usize {
    1
}
