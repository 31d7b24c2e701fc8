//! The TARGETS.md rows that only a sweep measures (seed 000 §4.1): the pressure drop along
//! the superficial velocity (V6, V7), against the grains in the tube (V9), along the
//! Coulomb friction (V10) and the restitution (V11); on the horizontal case, against the
//! granular mass flow (H7). Each compares variants of one sweep,
//! all else equal, so a row is read from one `--vary` and its variants' summaries.

use crate::summary::{Number, Summary, TargetRow};
use crate::Real;

/// Seed 000's reference point, V1: v_s = 1 m/s.
const REFERENCE_VELOCITY: Real = 1.0;

/// Whose sweep rows a scene's sweep measures: those of the seed whose reference scene it is,
/// by the rows its `output.reproduces` names (V1: seed 000's vertical tube; H1: seed 002's
/// horizontal pipe). The V-rows are not measured on the horizontal pipe (seed 002 fig. 7:
/// there Δp peaks at μ = 0.1 rather than rising with μ, so V10's "rises with μ" is no
/// horizontal row), nor H7 on the vertical tube, nor either on a scene that is neither
/// seed's (its curve is drawn, but the papers' rows describe other scenes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepRows {
    /// Seed 000's vertical tube: V6, V7, V9, V10, V11.
    Vertical,
    /// Seed 002's horizontal pipe: H7.
    Horizontal,
    /// Neither seed's scene: no rows.
    None,
}

impl SweepRows {
    /// From the scene's `output.reproduces`.
    pub fn of(reproduces: &[String]) -> Self {
        let has = |id: &str| reproduces.iter().any(|r| r == id);
        if has("V1") {
            SweepRows::Vertical
        } else if has("H1") {
            SweepRows::Horizontal
        } else {
            SweepRows::None
        }
    }
}

/// The rows a sweep over `path` measures, from `(value of path, summary)` of its variants
/// (variants without a pressure drop left out), for a scene whose rows are `family`. Empty
/// when the path is none of the above or the points needed are missing (e.g. no v_s = 1 m/s
/// variant for V6/V7).
pub fn characteristic_targets(
    path: &str,
    points: &[(Real, &Summary)],
    family: SweepRows,
) -> Vec<TargetRow> {
    let mut pts: Vec<(Real, Real, Real)> = points
        .iter()
        // A variant whose inlet fell behind (more than 1 % of the grains asked for still
        // owed: a blocked inlet slab) ran a smaller feed than the scene's: not a point of
        // this curve.
        .filter(|(_, s)| fed_as_asked(s))
        .filter_map(|(x, s)| {
            let dp = Number::PressureDrop.of(s)?;
            let n = Number::ParticlesInTube.of(s)?;
            Some((*x, dp, n))
        })
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let dp_at = |x: Real| pts.iter().find(|p| (p.0 - x).abs() < 1e-9).map(|p| p.1);
    let vertical = family == SweepRows::Vertical;
    let horizontal = family == SweepRows::Horizontal;
    let mut rows = Vec::new();
    if vertical && path.ends_with("superficial_velocity") {
        if let Some(dp1) = dp_at(REFERENCE_VELOCITY) {
            // V6, V7: the paper's 62 and 13 hPa/m against its 39 at 1 m/s; the rows ask only
            // for the direction (higher at 0.75 m/s, lower at 4 m/s).
            if let Some(dp) = dp_at(0.75) {
                rows.push(row(
                    "V6",
                    "Δp(v_s = 0.75) / Δp(v_s = 1)",
                    dp / dp1,
                    62.0 / 39.0,
                    (1.0, Real::INFINITY),
                ));
            }
            if let Some(dp) = dp_at(4.0) {
                rows.push(row(
                    "V7",
                    "Δp(v_s = 4) / Δp(v_s = 1)",
                    dp / dp1,
                    13.0 / 39.0,
                    (0.0, 1.0),
                ));
            }
        }
        // V9: over the plug regime (0.75–4 m/s, seed 000 §4.1), Δp against grains in the
        // tube, straight-line fit.
        let plug: Vec<(Real, Real)> = pts
            .iter()
            .filter(|p| (0.75 - 1e-9..=4.0 + 1e-9).contains(&p.0))
            .map(|p| (p.2, p.1))
            .collect();
        if plug.len() >= 3 {
            rows.push(row(
                "V9",
                "R² of Δp against grains in the tube, 0.75–4 m/s",
                r_squared(&plug),
                Real::NAN,
                (0.9, 1.0),
            ));
        }
    }
    if horizontal && path.ends_with("mass_flow") && pts.len() >= 3 {
        // H7: seed 002 fig. 3's two characteristic curves (2.49 and 9.95 kg/h) imply a
        // pressure drop linear in the granular mass flow; straight-line fit.
        let by_feed: Vec<(Real, Real)> = pts.iter().map(|p| (p.0, p.1)).collect();
        rows.push(row(
            "H7",
            "R² of Δp against the granular mass flow",
            r_squared(&by_feed),
            Real::NAN,
            (0.9, 1.0),
        ));
    }
    if vertical && path.ends_with("friction") && pts.len() >= 2 {
        // V10: "pressure drop rises with μ": the smallest ratio of neighbours along μ.
        let min_ratio = pts
            .windows(2)
            .map(|w| w[1].1 / w[0].1)
            .fold(Real::INFINITY, Real::min);
        rows.push(row(
            "V10",
            "smallest Δp(μ_next) / Δp(μ) along μ",
            min_ratio,
            Real::NAN,
            (1.0, Real::INFINITY),
        ));
    }
    if vertical && path.ends_with("restitution") && pts.len() >= 2 {
        // V11: restitution 0.5 → 0.99 leaves Δp within 15 %: the highest e against the lowest.
        let (lo, hi) = (pts[0], pts[pts.len() - 1]);
        rows.push(row(
            "V11",
            &format!("Δp(e = {}) / Δp(e = {})", hi.0, lo.0),
            hi.1 / lo.1,
            1.0,
            (0.85, 1.15),
        ));
    }
    rows
}

/// The run fed what its inlet asked for, within 1 % (or has no inlet).
pub fn fed_as_asked(s: &Summary) -> bool {
    match (s.grains_asked, s.feed_backlog_grains) {
        (Some(asked), Some(owed)) => owed as Real <= 0.01 * asked as Real,
        _ => true,
    }
}

fn row(id: &str, what: &str, measured: Real, paper: Real, band: (Real, Real)) -> TargetRow {
    let finite = measured.is_finite().then_some(measured);
    TargetRow {
        id: id.to_string(),
        what: what.to_string(),
        measured: finite,
        paper,
        band: [band.0, band.1],
        ratio: finite.map(|m| m / paper).filter(|r| r.is_finite()),
        inside: finite.is_some_and(|m| m >= band.0 && m <= band.1),
    }
}

/// Coefficient of determination of the least-squares line through `(x, y)`.
fn r_squared(p: &[(Real, Real)]) -> Real {
    let n = p.len() as Real;
    let (mx, my) = (
        p.iter().map(|q| q.0).sum::<Real>() / n,
        p.iter().map(|q| q.1).sum::<Real>() / n,
    );
    let sxy: Real = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    let sxx: Real = p.iter().map(|q| (q.0 - mx).powi(2)).sum();
    let syy: Real = p.iter().map(|q| (q.1 - my).powi(2)).sum();
    if sxx <= 0.0 || syy <= 0.0 {
        return Real::NAN;
    }
    sxy * sxy / (sxx * syy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::summary::test_summary;

    fn at(dp: Real, n: Real) -> Summary {
        let mut s = test_summary("completed", 1.0, Some(dp));
        s.particles_in_tube_mean = n;
        s
    }

    /// The paper's own three points (seed 000: 62, 39, 13 hPa/m with 4900, 3600, 850 grains
    /// at 0.75, 1, 4 m/s) pass V6, V7 and V9 (R² of those three: 0.9718 by hand).
    #[test]
    fn the_papers_points_pass_their_rows() {
        let s = [at(62.0, 4900.0), at(39.0, 3600.0), at(13.0, 850.0)];
        let pts = [(0.75, &s[0]), (1.0, &s[1]), (4.0, &s[2])];
        let rows = characteristic_targets("gas.superficial_velocity", &pts, SweepRows::Vertical);
        let ids: Vec<&str> = rows.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(ids, ["V6", "V7", "V9"]);
        assert!(rows.iter().all(|r| r.inside), "{rows:?}");
        assert!((rows[0].measured.unwrap() - 62.0 / 39.0).abs() < 1e-12);
        assert!((rows[0].ratio.unwrap() - 1.0).abs() < 1e-12);
        let r2 = rows[2].measured.unwrap();
        assert!((r2 - 0.9718).abs() < 1e-4, "{r2}");
    }

    /// A drop that falls where it should rise fails V10; restitution 20 % apart fails V11;
    /// a sweep without the reference velocity measures no V6/V7.
    #[test]
    fn wrong_directions_fail_and_missing_points_measure_nothing() {
        let s = [at(30.0, 3000.0), at(40.0, 3000.0), at(35.0, 3000.0)];
        let pts = [(0.2, &s[0]), (0.5, &s[1]), (0.8, &s[2])];
        let v10 = characteristic_targets("contact.friction", &pts, SweepRows::Vertical);
        assert_eq!(v10.len(), 1);
        assert!((v10[0].measured.unwrap() - 35.0 / 40.0).abs() < 1e-12);
        assert!(!v10[0].inside);
        let e = [(0.5, &s[1]), (0.99, &s[0])];
        let v11 = characteristic_targets("contact.restitution", &e, SweepRows::Vertical);
        assert!((v11[0].measured.unwrap() - 0.75).abs() < 1e-12);
        assert!(!v11[0].inside);
        // A variant whose inlet was blocked (fed 9 % of what it asked) is no point of the
        // curve: V11 is then not measured.
        let mut blocked = at(12.0, 1800.0);
        blocked.grains_asked = Some(5137);
        blocked.feed_backlog_grains = Some(4680);
        let e2 = [(0.5, &s[1]), (0.99, &blocked)];
        assert!(characteristic_targets("contact.restitution", &e2, SweepRows::Vertical).is_empty());
        let v = [(0.5, &s[0]), (2.0, &s[1])];
        assert!(
            characteristic_targets("gas.superficial_velocity", &v, SweepRows::Vertical).is_empty()
        );
        // The feed: H7 on the horizontal case only.
        let feed = [(0.75, &s[0]), (1.25, &s[1]), (2.49, &s[2])];
        assert!(characteristic_targets("inlet.mass_flow", &feed, SweepRows::Vertical).is_empty());
        let h7 = characteristic_targets("inlet.mass_flow", &feed, SweepRows::Horizontal);
        assert_eq!(h7[0].id, "H7");
        // Δp 30, 40, 35 against 0.75, 1.25, 2.49: R² by hand 0.0779.
        assert!((h7[0].measured.unwrap() - 0.0779).abs() < 1e-4, "{h7:?}");
        assert!(!h7[0].inside);
        // The V-rows are the vertical tube's: a horizontal sweep of friction, restitution or
        // v_s measures none of them.
        let v = [(0.75, &s[0]), (1.0, &s[1]), (4.0, &s[2])];
        for path in [
            "contact.friction",
            "contact.restitution",
            "gas.superficial_velocity",
        ] {
            assert!(
                !characteristic_targets(path, &v, SweepRows::Vertical).is_empty(),
                "{path}"
            );
            assert!(
                characteristic_targets(path, &v, SweepRows::Horizontal).is_empty(),
                "{path}"
            );
            assert!(
                characteristic_targets(path, &v, SweepRows::None).is_empty(),
                "{path}"
            );
        }
        // H7 is the horizontal pipe's: not measured on a scene of neither seed.
        assert!(characteristic_targets("inlet.mass_flow", &feed, SweepRows::None).is_empty());
    }

    /// The shipped cases name their family through the rows they reproduce: the vertical
    /// tube (d'Arcy and SIMPLE gas) seed 000's, the horizontal pipe seed 002's, the
    /// experiment series (seed 000's Table 1, other feeds than its simulations) neither.
    #[test]
    fn the_cases_sweep_rows_follow_what_they_reproduce() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
        for (case, family) in [
            ("vertical_plug.toml", SweepRows::Vertical),
            ("vertical_plug_simple.toml", SweepRows::Vertical),
            ("horizontal_slug.toml", SweepRows::Horizontal),
            ("experiment_series_a.toml", SweepRows::None),
            ("vertical_dry_feed.toml", SweepRows::None),
        ] {
            let scene = crate::scene::Scene::load(&root.join(case), &[]).unwrap();
            assert_eq!(
                SweepRows::of(&scene.file.output.reproduces),
                family,
                "{case}"
            );
        }
    }
}
