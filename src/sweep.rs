//! `plugflow sweep`: every combination of the `--vary` lists, run as separate `plugflow run`
//! processes (as many at once as asked, default one per core), gathered into `sweep.csv`
//! and drawn as characteristic curves (pressure drop and grains in the tube against the
//! first varied field, one curve per value of the second) beside the papers' points.
//!
//! Each variant is an ordinary run in `<out>/<k>/` with its own summary.json and run.h5, so
//! a sweep that stops part-way keeps every finished variant.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use crate::analysis::characteristic::{characteristic_targets, fed_as_asked, SweepRows};
use crate::summary::{Number, Summary, TargetRow};

use crate::output::figures::{self, Curve, Panel};
use crate::scene::{Scene, SceneError};
use crate::Real;

/// One `--vary path=v1,v2,…`, or fields varied together,
/// `--vary "path|other=v1|w1,v2|w2"` (the feed and the injection velocity that keeps its
/// porosity: seed 002 fig. 5's mass flows at the paper's porosity 0.51).
#[derive(Debug, Clone)]
pub struct Vary {
    /// Scene path, e.g. `gas.superficial_velocity`: the curves' axis.
    pub path: String,
    /// Values as written (units allowed).
    pub values: Vec<String>,
    /// Fields set together with `path`, each with one value per value of `path`.
    pub paired: Vec<(String, Vec<String>)>,
}

/// What can stop a sweep before it starts.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `--vary` is malformed.
    #[error("--vary `{arg}`: {reason}")]
    Vary { arg: String, reason: String },
    /// A variant's scene is wrong (checked for every variant before any runs).
    #[error("variant {variant}: {source}")]
    Scene { variant: String, source: SceneError },
    /// The checkpoint every variant should start from does not fit one (`--from`).
    #[error("variant {variant}: {reason}")]
    Start { variant: String, reason: String },
    /// Files.
    #[error("sweep output `{path}`: {reason}")]
    Io { path: String, reason: String },
}

/// Parse `path=v1,v2,…`.
pub fn parse_vary(arg: &str) -> Result<Vary, SweepError> {
    let bad = |reason: &str| SweepError::Vary {
        arg: arg.to_string(),
        reason: reason.to_string(),
    };
    let (path, list) = arg
        .split_once('=')
        .ok_or_else(|| bad("expected PATH=V1,V2,…"))?;
    // Commas inside brackets belong to an array value: gas.grid=[75, 2, 2],[150, 2, 2].
    let mut values: Vec<String> = Vec::new();
    let (mut depth, mut current) = (0i32, String::new());
    for c in list.chars() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            _ => {}
        }
        if c == ',' && depth == 0 {
            values.push(std::mem::take(&mut current));
        } else {
            current.push(c);
        }
    }
    values.push(current);
    if depth != 0 {
        return Err(bad("unbalanced brackets"));
    }
    let values: Vec<String> = values
        .into_iter()
        .map(|v| v.trim().to_string())
        .filter(|v| !v.is_empty())
        .collect();
    if path.trim().is_empty() || values.is_empty() {
        return Err(bad("expected PATH=V1,V2,… with at least one value"));
    }
    let paths: Vec<String> = path.split('|').map(|p| p.trim().to_string()).collect();
    if paths.iter().any(String::is_empty) {
        return Err(bad("empty path among PATH|PATH…"));
    }
    // Column k holds the values of paths[k].
    let mut columns: Vec<Vec<String>> = vec![Vec::new(); paths.len()];
    for v in &values {
        let parts: Vec<&str> = v.split('|').map(str::trim).collect();
        if parts.len() != paths.len() || parts.iter().any(|p| p.is_empty()) {
            return Err(bad(&format!(
                "value `{v}` gives {} of the {} fields {} (one value each, separated by `|`)",
                parts.iter().filter(|p| !p.is_empty()).count(),
                paths.len(),
                paths.join("|")
            )));
        }
        for (c, p) in columns.iter_mut().zip(parts) {
            c.push(p.to_string());
        }
    }
    let mut columns = columns.into_iter();
    let values = columns.next().unwrap_or_default();
    Ok(Vary {
        path: paths[0].clone(),
        values,
        paired: paths[1..].iter().cloned().zip(columns).collect(),
    })
}

/// Every combination, first `--vary` slowest: `[(path, value)]` per variant (a `--vary`'s
/// paired fields right after its own, with the value of the same index).
pub fn combinations(varies: &[Vary]) -> Vec<Vec<(String, String)>> {
    let mut out: Vec<Vec<(String, String)>> = vec![Vec::new()];
    for v in varies {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                v.values.iter().enumerate().map(move |(k, x)| {
                    let mut p = prefix.clone();
                    p.push((v.path.clone(), x.clone()));
                    for (path, values) in &v.paired {
                        p.push((path.clone(), values[k].clone()));
                    }
                    p
                })
            })
            .collect();
    }
    out
}

/// How to sweep.
#[derive(Debug, Clone)]
pub struct SweepOptions {
    /// Output folder.
    pub out_dir: PathBuf,
    /// Processes at once.
    pub jobs: usize,
    /// Simulated time per variant (None: the scene's).
    pub duration: Option<Real>,
    /// Fixed overrides applied to every variant.
    pub set: Vec<String>,
    /// Threads per variant process (`dem.threads`); 1 by default so that `jobs` processes
    /// fill the cores without oversubscribing them.
    pub threads: usize,
    /// Start every variant from this checkpoint (a filled tube; `plugflow run --from`).
    pub from: Option<PathBuf>,
}

/// The value of `--set` for one (path, value): quoted unless it parses as TOML already.
fn set_arg(path: &str, value: &str) -> String {
    let needs_quotes = value.parse::<f64>().is_err()
        && !matches!(value, "true" | "false")
        && !value.starts_with(['"', '[', '{']);
    if needs_quotes {
        format!("{path}=\"{value}\"")
    } else {
        format!("{path}={value}")
    }
}

/// One finished variant.
#[derive(Debug, Clone)]
pub struct VariantRun {
    /// `(path, value)` of each varied field.
    pub settings: Vec<(String, String)>,
    /// Its summary.json (None when the run wrote none, or one that does not parse).
    pub summary: Option<Summary>,
    /// Exit code of its process.
    pub exit: Option<i32>,
}

/// Run every combination of `varies` (each variant validated as `plugflow validate` does
/// before the first starts), `opts.jobs` processes at a time, each into `<out>/<k>/` with its log in
/// `<out>/<k>.log`; the variants in combination order.
pub fn run_variants(
    exe: &Path,
    scene_path: &Path,
    varies: &[Vary],
    opts: &SweepOptions,
) -> Result<Vec<VariantRun>, SweepError> {
    let io = |p: &Path, e: &dyn std::fmt::Display| SweepError::Io {
        path: p.display().to_string(),
        reason: e.to_string(),
    };
    let variants = combinations(varies);
    // Check every variant before the first one starts.
    let mut sets = Vec::new();
    for v in &variants {
        let mut set = opts.set.clone();
        set.push(format!("dem.threads={}", opts.threads));
        set.extend(v.iter().map(|(p, x)| set_arg(p, x)));
        let label: Vec<String> = v.iter().map(|(p, x)| format!("{p}={x}")).collect();
        // Through the setup layer, as `plugflow validate`: the coupling checks and the
        // chosen engine's refusals too, not only the scene's own.
        let scene = Scene::load(scene_path, &set)
            .and_then(|s| crate::setup::validate(&s).map(|_| s))
            .map_err(|source| SweepError::Scene {
                variant: label.join(" "),
                source,
            })?;
        // The common start must fit every variant (its tube, grains, gas grid).
        if let Some(from) = &opts.from {
            use crate::run::checkpoint;
            checkpoint::locate(from)
                .and_then(|p| checkpoint::read(&p, &scene, checkpoint::Use::Start))
                .map_err(|e| SweepError::Start {
                    variant: label.join(" "),
                    reason: e.to_string(),
                })?;
        }
        sets.push((set, label, scene.text));
    }
    std::fs::create_dir_all(&opts.out_dir).map_err(|e| io(&opts.out_dir, &e))?;
    let mut running: Vec<(usize, Child)> = Vec::new();
    let mut exit: Vec<Option<i32>> = vec![None; sets.len()];
    let mut next = 0;
    let mut stopping = false;
    while next < sets.len() || !running.is_empty() {
        // A stop (Ctrl-C, SIGTERM): no new variant starts, the running ones are asked to
        // stop and waited for, so their outputs and this sweep's table are written.
        if !stopping && crate::children::stop_requested() {
            stopping = true;
            for (k, c) in running.iter_mut() {
                eprintln!("stop  {k:03}: asked to stop");
                crate::children::ask_to_stop(c);
            }
            next = sets.len();
        }
        while running.len() < opts.jobs.max(1) && next < sets.len() {
            let dir = opts.out_dir.join(format!("{next:03}"));
            // What this variant runs, recorded beside it: a later sweep into this folder
            // skips it when it finished, and resumes it from its checkpoint when stopped.
            let mut args: Vec<String> = Vec::new();
            if let Some(d) = opts.duration {
                args.extend(["--duration".to_string(), d.to_string()]);
            }
            for s in &sets[next].0 {
                args.extend(["--set".to_string(), s.clone()]);
            }
            if let Some(from) = &opts.from {
                args.extend(["--from".to_string(), from.display().to_string()]);
            }
            // The scene as run (after the settings) is part of the record: a scene file
            // edited since is another variant.
            let record = opts.out_dir.join(format!("{next:03}.variant"));
            let recorded = format!("{}\n# scene as run:\n{}", args.join("\n"), sets[next].2);
            let same = std::fs::read_to_string(&record).is_ok_and(|r| r == recorded);
            let finished = Summary::read(&dir.join("summary.json")).is_ok_and(|s| s.completed());
            if same && finished {
                eprintln!(
                    "skip  {next:03}: {} (finished already)",
                    sets[next].1.join(" ")
                );
                exit[next] = Some(0);
                next += 1;
                continue;
            }
            let resume = same && crate::run::checkpoint::locate(&dir).is_ok();
            // A summary left by an earlier sweep into this folder must not stand for this
            // variant: only the child started here may write the one read below.
            let stale = dir.join("summary.json");
            if stale.exists() {
                std::fs::remove_file(&stale).map_err(|e| io(&stale, &e))?;
            }
            std::fs::write(&record, &recorded).map_err(|e| io(&record, &e))?;
            let log = std::fs::OpenOptions::new()
                .create(true)
                .write(true)
                .append(resume)
                .truncate(!resume)
                .open(opts.out_dir.join(format!("{next:03}.log")))
                .map_err(|e| io(&opts.out_dir, &e))?;
            let log2 = log.try_clone().map_err(|e| io(&opts.out_dir, &e))?;
            let mut cmd = Command::new(exe);
            cmd.arg("run")
                .arg(scene_path)
                .arg("--out")
                .arg(&dir)
                .arg("--quiet");
            if resume {
                // (Its own checkpoint, not the common start: `--from` is left out.)
                let own = args.iter().position(|a| a == "--from");
                cmd.args(own.map_or(&args[..], |k| &args[..k]));
                cmd.arg("--resume").arg(&dir);
                eprintln!("resume {next:03}: {}", sets[next].1.join(" "));
            } else {
                cmd.args(&args);
                eprintln!("start {next:03}: {}", sets[next].1.join(" "));
            }
            let child = cmd
                .stdout(Stdio::from(log))
                .stderr(Stdio::from(log2))
                .spawn()
                .map_err(|e| io(exe, &e))?;
            running.push((next, child));
            next += 1;
        }
        std::thread::sleep(crate::children::POLL);
        let mut still = Vec::new();
        for (k, mut c) in running {
            match c.try_wait() {
                Ok(Some(status)) => {
                    exit[k] = Some(status.code().unwrap_or(-1));
                    eprintln!(
                        "done  {k:03}: {} (exit {})",
                        sets[k].1.join(" "),
                        exit[k].unwrap_or(-1)
                    );
                }
                Ok(None) => still.push((k, c)),
                Err(e) => return Err(io(exe, &e)),
            }
        }
        running = still;
    }
    Ok(variants
        .into_iter()
        .enumerate()
        .map(|(k, settings)| {
            let summary =
                Summary::read(&opts.out_dir.join(format!("{k:03}")).join("summary.json")).ok();
            // A run that exits with an error never counts as completed, whatever it wrote.
            let summary = summary.filter(|s| exit[k] == Some(0) || !s.completed());
            VariantRun {
                settings,
                summary,
                exit: exit[k],
            }
        })
        .collect())
}

/// Run the sweep; returns the rows written to sweep.csv and the rows of TARGETS.md measured.
pub fn sweep(
    exe: &Path,
    scene_path: &Path,
    varies: &[Vary],
    opts: &SweepOptions,
) -> Result<SweepResult, SweepError> {
    let io = |p: &Path, e: &dyn std::fmt::Display| SweepError::Io {
        path: p.display().to_string(),
        reason: e.to_string(),
    };
    let runs = run_variants(exe, scene_path, varies, opts)?;
    let variants: Vec<Vec<(String, String)>> = runs.iter().map(|r| r.settings.clone()).collect();
    // The scene as the sweep's common settings give it (every variant was loaded and checked
    // before the first ran), and each variant's place on the x axis, read once for the
    // figure and the rows alike.
    let scene = Scene::load(scene_path, &opts.set).map_err(|source| SweepError::Scene {
        variant: "(the sweep's common settings)".to_string(),
        source,
    })?;
    let reproduces = &scene.file.output.reproduces;
    let axis = varies.first().map(|first| Axis {
        scene_path,
        set: &opts.set,
        first,
    });
    let xs: Vec<Option<Real>> = variants
        .iter()
        .map(|v| axis.as_ref().and_then(|a| a.x(&v[0].1)))
        .collect();
    // Gather.
    const COLUMNS: [Number; 9] = [
        Number::PressureDrop,
        Number::ParticlesInTube,
        Number::MassOutflow,
        Number::PlugVelocity,
        Number::PlugLength,
        Number::PlugMinPorosity,
        Number::PlugRate,
        Number::SimulatedTime,
        Number::WallTime,
    ];
    let mut csv = String::new();
    for v in varies {
        for path in std::iter::once(&v.path).chain(v.paired.iter().map(|(p, _)| p)) {
            csv.push_str(path);
            csv.push(',');
        }
    }
    csv.push_str("variant,status,");
    csv.push_str(&COLUMNS.map(Number::key).join(","));
    csv.push('\n');
    let mut rows = Vec::new();
    for (k, run) in runs.into_iter().enumerate() {
        let summary = run.summary;
        for (_, x) in &variants[k] {
            csv.push_str(&format!("\"{x}\","));
        }
        let status = summary
            .as_ref()
            .map(|s| s.status.clone())
            .unwrap_or_else(|| match run.exit {
                None => "not started (the sweep was stopped)".to_string(),
                Some(code) => format!("no summary (exit {code})"),
            });
        csv.push_str(&format!("{k:03},\"{}\"", status.replace('"', "'")));
        for c in COLUMNS {
            csv.push(',');
            if let Some(x) = summary.as_ref().and_then(|s| c.of(s)) {
                csv.push_str(&format!("{x}"));
            }
        }
        csv.push('\n');
        rows.push(summary);
    }
    let csv_path = opts.out_dir.join("sweep.csv");
    std::fs::write(&csv_path, csv).map_err(|e| io(&csv_path, &e))?;
    if let Some(axis) = &axis {
        draw_curves(
            &opts.out_dir,
            axis,
            reproduces,
            varies,
            &variants,
            &xs,
            &rows,
        )
        .map_err(|e| io(&opts.out_dir, &e))?;
    }
    // The rows only a sweep measures (V6, V7, V9–V11 on the vertical case, H7 on the
    // horizontal one), from a sweep of one setting.
    let targets = match (varies, &axis) {
        ([_], Some(axis)) => {
            let points: Vec<(Real, &Summary)> = xs
                .iter()
                .zip(&rows)
                .filter_map(|(x, r)| Some(((*x)?, r.as_ref()?)))
                .filter(|(_, r)| r.completed())
                .collect();
            characteristic_targets(axis.path(), &points, SweepRows::of(reproduces))
        }
        _ => Vec::new(),
    };
    let path = opts.out_dir.join("targets.json");
    if !targets.is_empty() {
        let text = serde_json::to_string_pretty(&targets).map_err(|e| io(&path, &e))?;
        std::fs::write(&path, text).map_err(|e| io(&path, &e))?;
    } else if path.exists() {
        // (An earlier gathering's rows, from variants this one leaves out.)
        std::fs::remove_file(&path).map_err(|e| io(&path, &e))?;
    }
    Ok(SweepResult { rows, targets })
}

/// What a sweep measured: one summary per variant (None: no summary), and the TARGETS.md
/// rows measured across its variants (also in `DIR/targets.json`).
pub struct SweepResult {
    pub rows: Vec<Option<Summary>>,
    pub targets: Vec<TargetRow>,
}

/// The papers' characteristic points (superficial velocity m/s, hPa/m, grains in tube):
/// seed 000 simulations (V1, V6, V7) and the experiment of Table 1 (air flows through the
/// 7 mm tube: v_s = 4 V̇ / (π D²)); seed 002 (H1).
fn paper_points(reproduces: &[String]) -> Vec<Curve> {
    let vs = |lpm: Real| 4.0 * lpm / 60_000.0 / (std::f64::consts::PI * 0.007 * 0.007);
    let has = |id: &str| reproduces.iter().any(|r| r == id);
    let mut out = Vec::new();
    if has("V1") {
        out.push(Curve {
            label: "seed 000 simulation".into(),
            points: vec![(0.75, 62.0), (1.0, 39.0), (4.0, 13.0)],
            markers: true,
            band: Vec::new(),
        });
        out.push(Curve {
            label: "experiment (Table 1)".into(),
            points: vec![(vs(2.0), 42.0), (vs(2.2), 45.0), (vs(2.4), 44.5)],
            markers: true,
            band: Vec::new(),
        });
    }
    if has("H1") {
        out.push(Curve {
            label: "seed 002 simulation".into(),
            points: vec![(1.0, 10.0)],
            markers: true,
            band: Vec::new(),
        });
    }
    out
}

/// The number a value starts with ("2.3 l/min" → 2.3).
pub fn leading_number(s: &str) -> Option<Real> {
    let t = s.trim().trim_matches('"');
    let end = t
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .unwrap_or(t.len());
    t[..end].parse().ok()
}

/// A sweep's x axis: the first varied field's values as numbers, for the figure and the
/// rows alike. A sweep over `gas.flow` reads as the superficial velocity each value gives
/// in the scene's tube ([`Scene::superficial_velocity`]): the papers' axis, with their
/// points beside it and the rows of a `gas.superficial_velocity` sweep.
struct Axis<'a> {
    scene_path: &'a Path,
    /// The sweep's common `--set`s, under each variant's value.
    set: &'a [String],
    first: &'a Vary,
}

impl Axis<'_> {
    fn by_flow(&self) -> bool {
        self.first.path == "gas.flow"
    }

    /// The field the numbers are values of.
    fn path(&self) -> &str {
        if self.by_flow() {
            "gas.superficial_velocity"
        } else {
            &self.first.path
        }
    }

    fn label(&self) -> String {
        if self.by_flow() {
            "superficial velocity from gas.flow, m/s".to_string()
        } else {
            self.first.path.clone()
        }
    }

    /// The number a value of the first field stands for (None: not a number).
    fn x(&self, value: &str) -> Option<Real> {
        if self.by_flow() {
            let mut set = self.set.to_vec();
            set.push(set_arg(&self.first.path, value));
            Scene::load(self.scene_path, &set)
                .ok()?
                .superficial_velocity()
        } else {
            leading_number(value)
        }
    }
}

fn draw_curves(
    dir: &Path,
    axis: &Axis,
    reproduces: &[String],
    varies: &[Vary],
    variants: &[Vec<(String, String)>],
    xs: &[Option<Real>],
    rows: &[Option<Summary>],
) -> Result<(), crate::output::OutputError> {
    let second = varies.get(1);
    let groups: Vec<Option<&String>> = match second {
        Some(s) => s.values.iter().map(Some).collect(),
        None => vec![None],
    };
    let mut dp_curves = Vec::new();
    let mut n_curves = Vec::new();
    for g in groups {
        let (mut dp, mut n) = (Vec::new(), Vec::new());
        for ((v, r), x) in variants.iter().zip(rows).zip(xs) {
            if let (Some(gv), Some(s)) = (g, second) {
                if !v.iter().any(|(p, x)| p == &s.path && x == gv) {
                    continue;
                }
            }
            let Some(x) = *x else {
                continue;
            };
            // A variant whose inlet fell behind ran another feed: not a point of this
            // curve (as for the rows; sweep.csv keeps it).
            if r.as_ref().is_some_and(|r| !fed_as_asked(r)) {
                continue;
            }
            if let Some(y) = r.as_ref().and_then(|r| Number::PressureDrop.of(r)) {
                dp.push((x, y));
            }
            if let Some(y) = r.as_ref().and_then(|r| Number::ParticlesInTube.of(r)) {
                n.push((x, y));
            }
        }
        let label = match (g, second) {
            (Some(gv), Some(s)) => format!("{} = {gv}", s.path),
            _ => "plugflow".to_string(),
        };
        // Drawn along x whatever order the values were given in (a point added to a
        // finished sweep goes last, so that the earlier variants keep their folders).
        dp.sort_by(|a, b| a.0.total_cmp(&b.0));
        n.sort_by(|a, b| a.0.total_cmp(&b.0));
        dp_curves.push(Curve::line(label.clone(), dp));
        n_curves.push(Curve::line(label, n));
    }
    if axis.path().ends_with("superficial_velocity") {
        dp_curves.extend(paper_points(reproduces));
    }
    figures::panels(
        &dir.join("characteristic.png"),
        &[
            Panel {
                title: "pressure drop".into(),
                x_label: axis.label(),
                y_label: "hPa/m".into(),
                curves: dp_curves,
            },
            Panel {
                title: "grains in the tube".into(),
                x_label: axis.label(),
                y_label: "mean count".into(),
                curves: n_curves,
            },
        ],
        1300,
        480,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seeds' 7 mm tube: 2.309 l/min is 1 m/s (4 × 3.848e-5 m³/s / (π × 4.9e-5 m²)).
    #[test]
    fn a_flow_sweep_is_drawn_against_superficial_velocity() {
        let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/horizontal_slug.toml");
        let first = parse_vary("gas.flow=2.309 l/min").unwrap();
        let axis = Axis {
            scene_path: &scene_path,
            set: &[],
            first: &first,
        };
        assert_eq!(axis.path(), "gas.superficial_velocity");
        let v = axis.x("\"2.309 l/min\"").unwrap();
        assert!((v - 0.99996).abs() < 1e-4, "{v}");
        assert!(axis.x("fast").is_none());
    }

    #[test]
    fn combinations_cover_the_product_first_slowest() {
        let v = [
            parse_vary("a=1,2").unwrap(),
            parse_vary("b=x, y ,z").unwrap(),
        ];
        let c = combinations(&v);
        assert_eq!(c.len(), 6);
        assert_eq!(
            c[0],
            vec![("a".into(), "1".into()), ("b".into(), "x".into())]
        );
        assert_eq!(
            c[5],
            vec![("a".into(), "2".into()), ("b".into(), "z".into())]
        );
        assert!(parse_vary("a=").is_err());
    }

    /// Fields varied together: one variant per value, the paired field's value of the same
    /// index beside it; a value that does not give every field is refused.
    #[test]
    fn paired_fields_vary_together() {
        let v = [
            parse_vary("m|v=1 kg/h|0.1 m/s, 2 kg/h | 0.2 m/s").unwrap(),
            parse_vary("s=1,2").unwrap(),
        ];
        assert_eq!(v[0].path, "m");
        assert_eq!(v[0].values, vec!["1 kg/h", "2 kg/h"]);
        let c = combinations(&v);
        assert_eq!(c.len(), 4);
        let pair = |a: &str, b: &str| (a.to_string(), b.to_string());
        assert_eq!(
            c[2],
            vec![pair("m", "2 kg/h"), pair("v", "0.2 m/s"), pair("s", "1")]
        );
        for bad in ["m|v=1|2,3", "m|=1|2", "m|v=1|"] {
            let e = parse_vary(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
        let g = parse_vary("gas.grid=[75, 2, 2],[150,2,2]").unwrap();
        assert_eq!(g.values, vec!["[75, 2, 2]", "[150,2,2]"]);
        assert!(parse_vary("gas.grid=[75, 2").is_err());
        assert!(parse_vary("novalue").is_err());
    }

    #[test]
    fn set_arguments_quote_quantities_only() {
        assert_eq!(set_arg("gas.x", "0.5"), "gas.x=0.5");
        assert_eq!(set_arg("gas.flow", "2.3 l/min"), "gas.flow=\"2.3 l/min\"");
        assert_eq!(leading_number("2.3 l/min"), Some(2.3));
    }
}
