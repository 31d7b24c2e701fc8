//! The rows of shared/TARGETS.md a case can reproduce: paper value and accepted band.

use crate::summary::{Number, Summary, TargetRow};
use crate::Real;

/// One target row.
#[derive(Debug, Clone, Copy)]
pub struct Target {
    /// Row id in TARGETS.md.
    pub id: &'static str,
    /// The summary's number holding the measured value.
    pub key: Number,
    /// What it is.
    pub what: &'static str,
    /// The paper's value (in the summary key's unit).
    pub paper: Real,
    /// Accepted band [lo, hi].
    pub band: (Real, Real),
}

/// Rows with a single measured number (the others need sweeps or profiles).
pub const TARGETS: &[Target] = &[
    Target {
        id: "V1",
        key: Number::PressureDrop,
        what: "pressure drop at v_s = 1 m/s, hPa/m",
        paper: 39.0,
        band: (30.0, 50.0),
    },
    Target {
        id: "V2",
        key: Number::ParticlesInTube,
        what: "mean grains in the tube",
        paper: 3600.0,
        band: (2700.0, 4500.0),
    },
    // The seeds' plug-velocity statistic (0.16 ± 0.02 m/s, seed 000 fig. 11) is the
    // maximal granular velocity found in each plug; the plug's own (tracked) motion is the
    // fig. 3 reading (0.24 m/s), a wave that gains grains at its front and sheds them at its
    // back and so outruns the grains. Both are reported against the same band.
    Target {
        id: "V3",
        key: Number::PlugMaxGranularVelocity,
        what: "plug velocity (max granular, fig. 11), m/s",
        paper: 0.16,
        band: (0.12, 0.30),
    },
    Target {
        id: "V3.tracked",
        key: Number::PlugVelocity,
        what: "plug velocity (tracked plugs, fig. 3), m/s",
        paper: 0.24,
        band: (0.12, 0.30),
    },
    Target {
        id: "V4",
        key: Number::PlugLength,
        what: "plug length at mid tube, m",
        paper: 0.024,
        band: (0.01, 0.06),
    },
    Target {
        id: "V5",
        key: Number::PlugMinPorosity,
        what: "minimum porosity in plugs at mid tube",
        paper: 0.47,
        band: (0.43, 0.52),
    },
    // Seed 000 fig. 9: "the merging of plugs reduces the plug rate along the tube", a
    // smooth decrease (no number in the text, hence NaN). Measured: the relative change of
    // the plugs passing from the lowest to the highest of six heights across the middle
    // 60 %, plus two standard errors of the plugs beginning and ending between them, so the
    // row is inside only when the fall is larger than the counting noise.
    Target {
        id: "V12",
        key: Number::PlugRateChangeUpperBound,
        what: "plug rate change up the middle 60 %, + 2 s.e.",
        paper: Real::NAN,
        band: (-1.0, 0.0),
    },
    Target {
        id: "H1",
        key: Number::PressureDrop,
        what: "pressure drop at v_s = 1 m/s, hPa/m",
        paper: 10.0,
        band: (6.0, 15.0),
    },
    Target {
        id: "H2",
        key: Number::ParticlesInTube,
        what: "mean grains in the tube",
        paper: 3200.0,
        band: (2400.0, 4000.0),
    },
    // As V3: the statistic (seed 002 fig. 10) is the maximal granular velocity in slugs;
    // the tracked slug motion is the fig. 1 reading (0.42 m/s).
    Target {
        id: "H3",
        key: Number::PlugMaxGranularVelocity,
        what: "slug velocity (max granular, fig. 10), m/s",
        paper: 0.29,
        band: (0.2, 0.5),
    },
    Target {
        id: "H3.tracked",
        key: Number::PlugVelocity,
        what: "slug velocity (tracked slugs, fig. 1), m/s",
        paper: 0.42,
        band: (0.2, 0.5),
    },
    Target {
        id: "H4",
        key: Number::PlugLength,
        what: "slug length at mid tube, m",
        paper: 0.05,
        band: (0.02, 0.10),
    },
    Target {
        id: "H5",
        key: Number::PlugMinPorosity,
        what: "minimum porosity in slugs",
        paper: 0.49,
        band: (0.44, 0.54),
    },
    // Seed 002 §5, fig. 19: "within the slug the lower particle layers are slower than the
    // upper ones" (no number in the text, hence NaN). Measured: the mean axial velocity of
    // the grains in the upper half of the slugs' cross-section over the lower half's, in the
    // middle 60 % of the tube.
    Target {
        id: "H10",
        key: Number::UpperOverLowerVelocityInPlugs,
        what: "slug velocity, upper half / lower half",
        paper: Real::NAN,
        band: (1.0, Real::INFINITY),
    },
    // Experiment series A (TARGETS.md, seed 000 Table 1): the band is the measured
    // range (pressure drop ± its error; plug velocity and length as tabulated), the
    // "paper" value its middle.
    Target {
        id: "A.dp",
        key: Number::PressureDrop,
        what: "series A: pressure drop, hPa/m",
        paper: 42.0,
        band: (40.0, 44.0),
    },
    Target {
        id: "A.velocity",
        key: Number::PlugVelocity,
        what: "series A: plug velocity, m/s",
        paper: 0.13,
        band: (0.09, 0.17),
    },
    Target {
        id: "A.length",
        key: Number::PlugLength,
        what: "series A: plug length, m",
        paper: 0.023,
        band: (0.006, 0.04),
    },
    // Experiment series B (TARGETS.md, seed 000 Table 1): the band is the measured
    // range (pressure drop ± its error; plug velocity and length as tabulated), the
    // "paper" value its middle.
    Target {
        id: "B.dp",
        key: Number::PressureDrop,
        what: "series B: pressure drop, hPa/m",
        paper: 45.0,
        band: (43.0, 47.0),
    },
    Target {
        id: "B.velocity",
        key: Number::PlugVelocity,
        what: "series B: plug velocity, m/s",
        paper: 0.155,
        band: (0.12, 0.19),
    },
    Target {
        id: "B.length",
        key: Number::PlugLength,
        what: "series B: plug length, m",
        paper: 0.053,
        band: (0.017, 0.09),
    },
    // Experiment series C (TARGETS.md, seed 000 Table 1): the band is the measured
    // range (pressure drop ± its error; plug velocity and length as tabulated), the
    // "paper" value its middle.
    Target {
        id: "C.dp",
        key: Number::PressureDrop,
        what: "series C: pressure drop, hPa/m",
        paper: 44.5,
        band: (42.5, 46.5),
    },
    Target {
        id: "C.velocity",
        key: Number::PlugVelocity,
        what: "series C: plug velocity, m/s",
        paper: 0.255,
        band: (0.18, 0.33),
    },
    Target {
        id: "C.length",
        key: Number::PlugLength,
        what: "series C: plug length, m",
        paper: 0.0225,
        band: (0.005, 0.04),
    },
];

/// The target with this id.
pub fn find(id: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.id == id)
}

/// `targets` entries for the summary: measured beside paper, band and verdict.
pub fn evaluate(ids: &[String], summary: &Summary) -> Vec<TargetRow> {
    ids.iter()
        .filter_map(|id| find(id))
        .map(|t| {
            let measured = t.key.of(summary);
            TargetRow {
                id: t.id.to_string(),
                what: t.what.to_string(),
                measured,
                paper: t.paper,
                band: [t.band.0, t.band.1],
                ratio: measured.map(|m| m / t.paper),
                inside: measured.is_some_and(|m| m >= t.band.0 && m <= t.band.1),
            }
        })
        .collect()
}
