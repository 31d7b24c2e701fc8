//! Generated input (issue 26): a few hundred seeded mutations of the shipped cases, each one
//! value replaced by something a user might type (zero, negative, huge, tiny, NaN, a wrong
//! unit or type, an empty array) or a key removed. Every mutant is either refused naming a
//! field (`plugflow validate` exit 2, "field `…`"), or it runs briefly to a summary (exit 0,
//! or 1 with a `failed: …` status): no panic, no abort, no crash, no hang (a run still busy
//! after its time is sent SIGTERM and must stop).
//!
//! The seed and every mutant's text are in the failure message, so a failure reproduces with
//! `plugflow validate` / `run` on the printed scene.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use toml::Value;

/// Mutants per run of the test (~10 s on two cores: most are refused in milliseconds) and
/// their seed; `PLUGFLOW_MUTANTS=N` and `PLUGFLOW_MUTANTS_SEED=S` explore further.
const MUTANTS: usize = 500;
const SEED: u64 = 0x5eed_2026;

fn from_env(key: &str, default: u64) -> u64 {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
/// Simulated time of an accepted mutant's run, s: a few hundred steps, setup included.
const RUN_S: &str = "0.002";
/// Wall time after which a run is asked to stop (SIGTERM), and the time it then has.
const BUSY: Duration = Duration::from_secs(30);
const STOP_GRACE: Duration = Duration::from_secs(15);

/// The shipped cases the mutants come from (every engine-independent feature: tube and
/// box, inlet and fill, both gas models, taps, profiles).
const CASES: [&str; 5] = [
    "cases/vertical_plug.toml",
    "cases/horizontal_slug.toml",
    "cases/vertical_plug_simple.toml",
    "cases/vertical_dry_feed.toml",
    "cases/bench_bed.toml",
];

/// splitmix64: a seeded stream, the same on every machine.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn pick(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Every leaf of a table (scalars and arrays), as paths of keys and indices.
fn leaves(v: &Value, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        Value::Table(t) => {
            for (k, x) in t {
                path.push(k.clone());
                leaves(x, path, out);
                path.pop();
            }
        }
        Value::Array(a) if a.iter().all(|x| x.is_table()) && !a.is_empty() => {
            for (k, x) in a.iter().enumerate() {
                path.push(format!("#{k}"));
                leaves(x, path, out);
                path.pop();
            }
        }
        _ => out.push(path.clone()),
    }
}

fn slot<'a>(v: &'a mut Value, path: &[String]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match k.strip_prefix('#') {
        Some(i) => &mut v.as_array_mut().unwrap()[i.parse::<usize>().unwrap()],
        None => v.as_table_mut().unwrap().get_mut(k).unwrap(),
    })
}

/// A replacement for `old` a user might type by mistake (None: remove the key).
fn mutation(old: &Value, rng: &mut Rng) -> Option<Value> {
    let number = |x: f64| Value::Float(x);
    let scaled = |f: f64| match old {
        Value::Integer(i) => Value::Float(*i as f64 * f),
        Value::Float(x) => Value::Float(x * f),
        Value::String(s) => {
            let (num, unit) = s.split_once(' ').unwrap_or((s, ""));
            match num.parse::<f64>() {
                Ok(x) => Value::String(format!("{:e} {unit}", x * f).trim().to_string()),
                Err(_) => Value::String(format!("{s}{s}")),
            }
        }
        other => other.clone(),
    };
    let unit_of = |s: &Value| {
        s.as_str()
            .and_then(|s| s.split_once(' ').map(|(_, u)| u.to_string()))
            .unwrap_or_default()
    };
    let with_unit = |x: &str| Value::String(format!("{x} {}", unit_of(old)).trim().to_string());
    let choices: Vec<Option<Value>> = vec![
        None,
        Some(number(0.0)),
        Some(Value::Integer(-1)),
        Some(number(1e300)),
        Some(number(1e-300)),
        Some(number(f64::NAN)),
        Some(number(f64::INFINITY)),
        Some(scaled(1e6)),
        Some(scaled(1e-6)),
        Some(scaled(-1.0)),
        Some(scaled(10.0)),
        Some(scaled(0.1)),
        Some(with_unit("0")),
        Some(with_unit("-1")),
        Some(with_unit("1e300")),
        Some(with_unit("1e-300")),
        Some(with_unit("nan")),
        Some(Value::String(format!("1 parsec{}", unit_of(old)))),
        Some(Value::String(String::new())),
        Some(Value::Boolean(true)),
        Some(Value::Array(Vec::new())),
        Some(Value::Array(vec![number(0.0); 3])),
        Some(Value::Array(vec![number(1e300), number(0.0), number(0.0)])),
        Some(Value::Integer(i64::MAX)),
    ];
    choices[rng.pick(choices.len())].clone()
}

/// One mutant: the case it came from, what changed, its text.
struct Mutant {
    case: &'static str,
    change: String,
    text: String,
}

fn mutants(root: &Path, count: usize, seed: u64) -> Vec<Mutant> {
    let mut rng = Rng(seed);
    let bases: Vec<(Value, Vec<Vec<String>>)> = CASES
        .iter()
        .map(|c| {
            let v: Value = toml::from_str(&std::fs::read_to_string(root.join(c)).unwrap())
                .unwrap_or_else(|e| panic!("{c}: {e}"));
            let mut out = Vec::new();
            leaves(&v, &mut Vec::new(), &mut out);
            // The version and the name are what `validate` checks first; mutating them
            // says nothing about the rest.
            out.retain(|p| p[0] != "schema_version");
            (v, out)
        })
        .collect();
    (0..count)
        .map(|_| {
            let c = rng.pick(CASES.len());
            let (base, paths) = &bases[c];
            let mut v = base.clone();
            // One change, or two at once (a third of the mutants): pairs of options that
            // are fine alone can fail together (crank_nicolson with splitting did).
            let changes = if rng.pick(3) == 0 { 2 } else { 1 };
            let mut said = Vec::new();
            for _ in 0..changes {
                let mut now = Vec::new();
                leaves(&v, &mut Vec::new(), &mut now);
                now.retain(|p| p[0] != "schema_version" && paths.contains(p));
                if now.is_empty() {
                    break;
                }
                let path = now[rng.pick(now.len())].clone();
                let old = slot(&mut v, &path).clone();
                let new = mutation(&old, &mut rng);
                said.push(format!(
                    "{} = {}",
                    path.join("."),
                    new.as_ref()
                        .map_or("(removed)".to_string(), |n| n.to_string())
                ));
                match new {
                    Some(n) => *slot(&mut v, &path) = n,
                    None => {
                        let (last, parent) = path.split_last().unwrap();
                        let p = slot(&mut v, parent);
                        match last.strip_prefix('#') {
                            Some(i) => {
                                p.as_array_mut().unwrap().remove(i.parse().unwrap());
                            }
                            None => {
                                p.as_table_mut().unwrap().remove(last);
                            }
                        }
                    }
                }
            }
            let change = said.join("; ");
            Mutant {
                case: CASES[c],
                change,
                text: toml::to_string(&v).unwrap(),
            }
        })
        .collect()
}

/// What became of a mutant, or why that is a defect.
fn verdict(exe: &Path, dir: &Path, k: usize, m: &Mutant) -> Result<&'static str, String> {
    let scene = dir.join(format!("mutant_{k:03}.toml"));
    std::fs::write(&scene, &m.text).unwrap();
    let fail = |what: String| {
        Err(format!(
            "mutant {k} of {} ({}): {what}\n--- scene ---\n{}",
            m.case, m.change, m.text
        ))
    };
    let v = Command::new(exe)
        .args(["validate", scene.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&v.stderr).to_string();
    match v.status.code() {
        Some(2) if err.contains("field `") => return Ok("refused"),
        Some(2) => return fail(format!("refused without naming a field: {err}")),
        Some(0) => {}
        other => return fail(format!("validate exit {other:?}: {err}")),
    }
    let out = dir.join(format!("mutant_{k:03}"));
    let mut child = Command::new(exe)
        .args([
            "run",
            scene.to_str().unwrap(),
            "--quiet",
            "--duration",
            RUN_S,
        ])
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut asked = false;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if !asked && start.elapsed() > BUSY {
            unsafe_sigterm(child.id());
            asked = true;
        }
        if start.elapsed() > BUSY + STOP_GRACE {
            child.kill().ok();
            child.wait().ok();
            return fail("hung: SIGTERM did not stop it".into());
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().unwrap().read_to_string(&mut err).ok();
    let summary = std::fs::read_to_string(out.join("summary.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    let result = match (status.code(), &summary) {
        (Some(0), Some(s)) if s["status"] == "completed" => Ok("ran"),
        (Some(1), Some(s))
            if s["status"]
                .as_str()
                .is_some_and(|t| t.starts_with("failed: ")) =>
        {
            Ok("failed with a summary")
        }
        (Some(130), Some(_)) if asked => Ok("slow, stopped by SIGTERM"),
        (Some(2), _) if err.contains("field `") => Ok("refused at run time"),
        (code, _) => fail(format!(
            "run exit {code:?} (signal {:?}), summary {}: {err}",
            std::os::unix::process::ExitStatusExt::signal(&status),
            if summary.is_some() {
                "written"
            } else {
                "missing"
            }
        )),
    };
    std::fs::remove_dir_all(&out).ok();
    result
}

fn unsafe_sigterm(pid: u32) {
    Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status()
        .ok();
}

#[test]
fn generated_scenes_are_refused_naming_a_field_or_run_to_a_summary() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let exe = PathBuf::from(env!("CARGO_BIN_EXE_plugflow"));
    let dir = std::env::temp_dir().join(format!("plugflow-mutants-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let count = from_env("PLUGFLOW_MUTANTS", MUTANTS as u64) as usize;
    let seed = from_env("PLUGFLOW_MUTANTS_SEED", SEED);
    let all = mutants(&root, count, seed);
    // Two at a time (two cores); results in mutant order, whatever finishes first.
    let results: Vec<Result<&str, String>> = std::thread::scope(|s| {
        let halves: Vec<_> = (0..2)
            .map(|h| {
                let (exe, dir, all) = (&exe, &dir, &all);
                s.spawn(move || {
                    (h..all.len())
                        .step_by(2)
                        .map(|k| (k, verdict(exe, dir, k, &all[k])))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        let mut r: Vec<(usize, Result<&str, String>)> =
            halves.into_iter().flat_map(|h| h.join().unwrap()).collect();
        r.sort_by_key(|(k, _)| *k);
        r.into_iter().map(|(_, v)| v).collect()
    });
    let mut tally = std::collections::BTreeMap::new();
    for r in results.iter().flatten() {
        *tally.entry(*r).or_insert(0) += 1;
    }
    eprintln!("mutants (seed {seed:#x}): {tally:?}");
    let defects: Vec<&String> = results.iter().filter_map(|r| r.as_ref().err()).collect();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        defects.is_empty(),
        "{} of {count} mutants (seed {seed:#x}) are defects:\n\n{}",
        defects.len(),
        defects
            .iter()
            .map(|d| d.as_str())
            .collect::<Vec<_>>()
            .join("\n\n")
    );
    // Both outcomes occur (a generator whose mutants were all refused, or all ran, would
    // test only half of the promise).
    assert!(tally.get("refused").is_some_and(|&n| n > 0), "{tally:?}");
    assert!(
        tally.get("ran").is_some_and(|&n| n > 0),
        "no mutant ran: {tally:?}"
    );
}
