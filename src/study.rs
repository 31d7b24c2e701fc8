//! `plugflow study SCENE --vary dem.dt=… --vary gas.grid=… --vary coupling.interval=…`:
//! error against run time. Every combination runs as in a sweep (separate processes); each
//! observable's error is measured against a reference — an exact value given with
//! `--exact KEY=VALUE` (an analytic answer), otherwise the finest variant, which the report
//! names — and written as a table (`study.csv`, `study.md`: variant, wall time, time per
//! stage, error of each observable) and a log–log figure of error against wall time with
//! the Pareto front marked (`study.png`). With `--target-error E` the report names the
//! cheapest variant whose largest error is at most E.
//!
//! The finest variant: per varied field, the smallest value of a time step or interval
//! (`…dt`, `…interval`), the largest grid (product of an array's entries), otherwise the
//! value listed last.

use std::path::Path;

use crate::output::figures::{self, Curve, Panel};
use crate::summary::Number;
use crate::sweep::{leading_number, run_variants, SweepError, SweepOptions, VariantRun, Vary};
use crate::Real;

/// Observables compared when none are named: the run's headline numbers.
pub const DEFAULT_OBSERVABLES: [Number; 3] = [
    Number::PressureDrop,
    Number::ParticlesInTube,
    Number::MassOutflow,
];

/// How to study.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    /// How to run the variants (folder, jobs, duration, fixed overrides, threads).
    pub runs: SweepOptions,
    /// Summary numbers to measure errors of.
    pub observables: Vec<Number>,
    /// Exact values (number, value) that replace the finest variant as reference.
    pub exact: Vec<(Number, Real)>,
    /// Largest acceptable relative error, for naming the cheapest variant that meets it.
    pub target_error: Option<Real>,
}

/// One row of the study table.
#[derive(Debug, Clone)]
pub struct StudyRow {
    /// `path=value` of each varied field.
    pub settings: Vec<(String, String)>,
    /// Run status from the summary.
    pub status: String,
    /// Wall time, s.
    pub wall_time: Option<Real>,
    /// Wall time per stage, s.
    pub stages: Vec<(String, Real)>,
    /// Relative error per observable (None where either value is missing).
    pub errors: Vec<Option<Real>>,
    /// Largest of the errors (None if any is missing).
    pub max_error: Option<Real>,
    /// This row is the reference (its errors are zero by construction).
    pub is_reference: bool,
}

/// What the study found.
#[derive(Debug, Clone)]
pub struct StudyResult {
    pub rows: Vec<StudyRow>,
    /// Index of the finest variant (the reference where no exact value is given).
    pub finest: usize,
    /// Reference value per observable and where it came from.
    pub references: Vec<(Number, Option<Real>, String)>,
    /// Indices of the Pareto-optimal rows (no other row is both faster and more accurate).
    pub pareto: Vec<usize>,
    /// Cheapest row meeting the target error, if asked and found.
    pub cheapest: Option<usize>,
}

/// Fineness of one value of a varied field: larger is finer.
fn fineness(path: &str, value: &str, index: usize) -> Real {
    let last = path.rsplit('.').next().unwrap_or(path);
    let v = value.trim();
    if v.starts_with('[') {
        // A grid: more cells is finer.
        return v
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .filter_map(|x| x.trim().parse::<Real>().ok())
            .product();
    }
    if last == "dt" || last == "interval" {
        if let Some(x) = leading_number(v) {
            if x > 0.0 {
                return 1.0 / x;
            }
        }
    }
    index as Real
}

/// The finest combination among `runs`: per field the finest value.
fn finest_variant(varies: &[Vary], runs: &[VariantRun]) -> usize {
    let best: Vec<&String> = varies
        .iter()
        .map(|v| {
            let (mut bi, mut bf) = (0, Real::NEG_INFINITY);
            for (i, x) in v.values.iter().enumerate() {
                let f = fineness(&v.path, x, i);
                if f > bf {
                    (bi, bf) = (i, f);
                }
            }
            &v.values[bi]
        })
        .collect();
    runs.iter()
        .position(|r| r.settings.iter().zip(&best).all(|((_, x), b)| x == *b))
        .unwrap_or(runs.len().saturating_sub(1))
}

/// Errors, Pareto front and cheapest choice from finished runs (no files).
pub fn evaluate(varies: &[Vary], runs: &[VariantRun], opts: &StudyOptions) -> StudyResult {
    let finest = finest_variant(varies, runs);
    let references: Vec<(Number, Option<Real>, String)> = opts
        .observables
        .iter()
        .map(|&key| match opts.exact.iter().find(|(k, _)| *k == key) {
            Some((_, v)) => (key, Some(*v), "exact value (--exact)".to_string()),
            None => (
                key,
                runs[finest].summary.as_ref().and_then(|s| key.of(s)),
                format!("finest variant {finest:03}"),
            ),
        })
        .collect();
    let uses_finest = references.iter().any(|r| r.2.starts_with("finest"));
    let rows: Vec<StudyRow> = runs
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let s = r.summary.as_ref();
            let errors: Vec<Option<Real>> = references
                .iter()
                .map(|(key, reference, _)| {
                    let x = key.of(s?)?;
                    let reference = (*reference)?;
                    Some(if reference != 0.0 {
                        (x - reference).abs() / reference.abs()
                    } else {
                        (x - reference).abs()
                    })
                })
                .collect();
            let max_error = errors.iter().try_fold(0.0_f64, |m, e| e.map(|e| m.max(e)));
            let stages = s
                .map(|s| {
                    s.stage_times_s
                        .iter()
                        .map(|(k, v)| (k.clone(), *v))
                        .collect()
                })
                .unwrap_or_default();
            StudyRow {
                settings: r.settings.clone(),
                status: s
                    .map(|s| s.status.clone())
                    .unwrap_or_else(|| format!("no summary (exit {:?})", r.exit)),
                wall_time: s.and_then(|s| Number::WallTime.of(s)),
                stages,
                errors,
                max_error,
                is_reference: uses_finest && k == finest,
            }
        })
        .collect();
    // Candidates: completed, with an error and a wall time; the reference itself only
    // when every observable has an exact value (otherwise its zero error is by definition).
    let candidate = |r: &StudyRow| {
        r.status == "completed" && r.max_error.is_some() && r.wall_time.is_some() && !r.is_reference
    };
    let pareto: Vec<usize> = (0..rows.len())
        .filter(|&i| candidate(&rows[i]))
        .filter(|&i| {
            let (ti, ei) = (rows[i].wall_time.unwrap(), rows[i].max_error.unwrap());
            !(0..rows.len()).any(|j| {
                j != i && candidate(&rows[j]) && {
                    let (tj, ej) = (rows[j].wall_time.unwrap(), rows[j].max_error.unwrap());
                    tj <= ti && ej <= ei && (tj < ti || ej < ei)
                }
            })
        })
        .collect();
    let cheapest = opts.target_error.and_then(|target| {
        (0..rows.len())
            .filter(|&i| candidate(&rows[i]) && rows[i].max_error.unwrap() <= target)
            .min_by(|&a, &b| {
                rows[a]
                    .wall_time
                    .unwrap()
                    .total_cmp(&rows[b].wall_time.unwrap())
            })
    });
    StudyResult {
        rows,
        finest,
        references,
        pareto,
        cheapest,
    }
}

fn fmt(x: Option<Real>) -> String {
    x.map_or("—".into(), |v| format!("{v:.4}"))
}

/// Run the study and write study.csv, study.md and study.png.
pub fn study(
    exe: &Path,
    scene_path: &Path,
    varies: &[Vary],
    opts: &StudyOptions,
) -> Result<StudyResult, SweepError> {
    let runs = run_variants(exe, scene_path, varies, &opts.runs)?;
    let result = evaluate(varies, &runs, opts);
    let dir = &opts.runs.out_dir;
    let io = |p: &Path, e: &dyn std::fmt::Display| SweepError::Io {
        path: p.display().to_string(),
        reason: e.to_string(),
    };
    let (csv, md) = tables(scene_path, varies, opts, &result);
    let csv_path = dir.join("study.csv");
    std::fs::write(&csv_path, csv).map_err(|e| io(&csv_path, &e))?;
    let md_path = dir.join("study.md");
    std::fs::write(&md_path, md).map_err(|e| io(&md_path, &e))?;
    draw(dir, opts, &result).map_err(|e| io(dir, &e))?;
    Ok(result)
}

/// study.csv and study.md.
fn tables(
    scene_path: &Path,
    varies: &[Vary],
    opts: &StudyOptions,
    result: &StudyResult,
) -> (String, String) {
    // Stage names present in any row, in first-seen order.
    let mut stage_names: Vec<String> = Vec::new();
    for r in &result.rows {
        for (s, _) in &r.stages {
            if !stage_names.contains(s) {
                stage_names.push(s.clone());
            }
        }
    }
    let mut csv = String::new();
    for v in varies {
        csv.push_str(&format!("{},", v.path));
    }
    csv.push_str("variant,status,wall_time_s,");
    for s in &stage_names {
        csv.push_str(&format!("stage_{s}_s,"));
    }
    for o in &opts.observables {
        csv.push_str(&format!("error_{},", o.key()));
    }
    csv.push_str("max_error,reference,pareto\n");
    let mut md = format!(
        "# Study of `{}`: error against run time\n\nReferences: {}.\n\n| variant | {} | wall time, s | {} | largest error | |\n|{}\n",
        scene_path.display(),
        result
            .references
            .iter()
            .map(|(k, v, from)| format!("`{}` = {} ({from})", k.key(), fmt(*v)))
            .collect::<Vec<_>>()
            .join(", "),
        varies.iter().map(|v| v.path.clone()).collect::<Vec<_>>().join(" | "),
        opts.observables
            .iter()
            .map(|o| format!("error of {}", o.key()))
            .collect::<Vec<_>>()
            .join(" | "),
        " --- |".repeat(varies.len() + opts.observables.len() + 4)
    );
    for (k, r) in result.rows.iter().enumerate() {
        for (_, x) in &r.settings {
            csv.push_str(&format!("\"{x}\","));
        }
        csv.push_str(&format!(
            "{k:03},\"{}\",{},",
            r.status.replace('"', "'"),
            r.wall_time.map_or(String::new(), |t| format!("{t}"))
        ));
        for s in &stage_names {
            let t = r.stages.iter().find(|(n, _)| n == s).map(|(_, t)| *t);
            csv.push_str(&format!("{},", t.map_or(String::new(), |t| format!("{t}"))));
        }
        for e in &r.errors {
            csv.push_str(&format!("{},", e.map_or(String::new(), |e| format!("{e}"))));
        }
        let pareto = result.pareto.contains(&k);
        csv.push_str(&format!(
            "{},{},{}\n",
            r.max_error.map_or(String::new(), |e| format!("{e}")),
            r.is_reference,
            pareto
        ));
        let mark = if r.is_reference {
            "reference"
        } else if Some(k) == result.cheapest {
            "cheapest meeting the target (Pareto)"
        } else if pareto {
            "Pareto"
        } else if r.status != "completed" {
            r.status.as_str()
        } else {
            ""
        };
        md.push_str(&format!(
            "| {k:03} | {} | {} | {} | {} | {mark} |\n",
            r.settings
                .iter()
                .map(|(_, x)| x.clone())
                .collect::<Vec<_>>()
                .join(" | "),
            fmt(r.wall_time),
            r.errors
                .iter()
                .map(|e| fmt(*e))
                .collect::<Vec<_>>()
                .join(" | "),
            fmt(r.max_error)
        ));
    }
    md.push_str(&format!(
        "\nStage times (s) per variant are in `study.csv`. Largest error = the largest relative \
         error over the observables.\n\n{}\n",
        match (opts.target_error, result.cheapest) {
            (Some(t), Some(k)) => format!(
                "Cheapest setting with largest error ≤ {t}: variant {k:03} ({}), {} s.",
                result.rows[k]
                    .settings
                    .iter()
                    .map(|(p, x)| format!("{p} = {x}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                fmt(result.rows[k].wall_time)
            ),
            (Some(t), None) => format!(
                "No variant other than the reference reaches a largest error ≤ {t}: refine further."
            ),
            (None, _) => "No target error given (`--target-error`).".to_string(),
        }
    ));
    (csv, md)
}

/// study.png: log10 error against log10 wall time, the Pareto front and the target.
fn draw(
    dir: &Path,
    opts: &StudyOptions,
    result: &StudyResult,
) -> Result<(), crate::output::OutputError> {
    // log10 error against log10 wall time (zero errors cannot be drawn on log axes).
    let point = |i: usize| -> Option<(Real, Real)> {
        let r = &result.rows[i];
        let (t, e) = (r.wall_time?, r.max_error?);
        (t > 0.0 && e > 0.0).then(|| (t.log10(), e.log10()))
    };
    let all: Vec<(Real, Real)> = (0..result.rows.len()).filter_map(point).collect();
    let mut front: Vec<(Real, Real)> = result.pareto.iter().filter_map(|&i| point(i)).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut curves = vec![
        Curve {
            label: "variants".into(),
            points: all,
            markers: true,
            band: Vec::new(),
        },
        Curve::line("Pareto front", front),
    ];
    if let Some(t) = opts.target_error.filter(|t| *t > 0.0) {
        let xs: Vec<Real> = curves[0].points.iter().map(|p| p.0).collect();
        if let (Some(lo), Some(hi)) = (
            xs.iter().copied().reduce(Real::min),
            xs.iter().copied().reduce(Real::max),
        ) {
            curves.push(Curve::line(
                "target error",
                vec![(lo, t.log10()), (hi, t.log10())],
            ));
        }
    }
    figures::panels(
        &dir.join("study.png"),
        &[Panel {
            title: "largest relative error against wall time".into(),
            x_label: "log10(wall time / s)".into(),
            y_label: "log10(largest relative error)".into(),
            curves,
        }],
        800,
        560,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::parse_vary;

    fn run(settings: &[(&str, &str)], wall: Real, dp: Real) -> VariantRun {
        VariantRun {
            settings: settings
                .iter()
                .map(|(p, x)| (p.to_string(), x.to_string()))
                .collect(),
            summary: Some(crate::summary::test_summary("completed", wall, Some(dp))),
            exit: Some(0),
        }
    }

    fn opts(target: Option<Real>, exact: Vec<(Number, Real)>) -> StudyOptions {
        StudyOptions {
            runs: SweepOptions {
                out_dir: std::env::temp_dir(),
                jobs: 1,
                duration: None,
                set: Vec::new(),
                threads: 1,
                from: None,
            },
            observables: vec![Number::PressureDrop],
            exact,
            target_error: target,
        }
    }

    /// The finest variant is the smallest dt with the largest grid, whatever the listing
    /// order; errors are relative to it; the Pareto front drops dominated variants; the
    /// cheapest variant meeting the target is named.
    #[test]
    fn finest_reference_pareto_and_cheapest() {
        let varies = [
            parse_vary("dem.dt=4e-6,1e-6,2e-6").unwrap(),
            parse_vary("gas.grid=[150, 2, 2],[75, 2, 2]").unwrap(),
        ];
        let runs = vec![
            run(
                &[("dem.dt", "4e-6"), ("gas.grid", "[150, 2, 2]")],
                10.0,
                41.0,
            ),
            run(&[("dem.dt", "4e-6"), ("gas.grid", "[75, 2, 2]")], 5.0, 44.0),
            run(
                &[("dem.dt", "1e-6"), ("gas.grid", "[150, 2, 2]")],
                40.0,
                40.0,
            ),
            run(
                &[("dem.dt", "1e-6"), ("gas.grid", "[75, 2, 2]")],
                20.0,
                43.0,
            ),
            run(
                &[("dem.dt", "2e-6"), ("gas.grid", "[150, 2, 2]")],
                20.0,
                40.4,
            ),
            run(
                &[("dem.dt", "2e-6"), ("gas.grid", "[75, 2, 2]")],
                12.0,
                45.0,
            ),
        ];
        let r = evaluate(&varies, &runs, &opts(Some(0.05), Vec::new()));
        assert_eq!(r.finest, 2);
        assert!(r.rows[2].is_reference);
        assert!((r.rows[0].max_error.unwrap() - 0.025).abs() < 1e-12);
        // 0 (10 s, 2.5 %), 1 (5 s, 10 %), 4 (20 s, 1 %) are optimal; 3 and 5 are dominated.
        assert_eq!(r.pareto, vec![0, 1, 4]);
        assert_eq!(r.cheapest, Some(0));
        // An exact value replaces the finest variant: then every variant is a candidate.
        let r = evaluate(
            &varies,
            &runs,
            &opts(Some(0.001), vec![(Number::PressureDrop, 40.0)]),
        );
        assert!(!r.rows[2].is_reference);
        assert_eq!(r.cheapest, Some(2));
        assert!(r.references[0].2.contains("exact"));
    }
}
