//! The bad-input corpus: every scene in tests/scenes/bad must be refused by
//! `plugflow validate` with exit code 2 and the message fragment of its `# expect:` line;
//! every scene in tests/scenes/good must pass.

use std::path::Path;
use std::process::Command;

fn validate(path: &Path) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .arg("validate")
        .arg(path)
        .output()
        .expect("run plugflow");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn scenes(dir: &str) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

#[test]
fn bad_scenes_are_refused_with_field_and_reason() {
    let bad = scenes("tests/scenes/bad");
    assert!(
        bad.len() >= 25,
        "the corpus needs at least 25 bad scenes, has {}",
        bad.len()
    );
    let mut failures = Vec::new();
    for p in &bad {
        let text = std::fs::read_to_string(p).unwrap();
        let expect = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("# expect: "))
            .unwrap_or_else(|| panic!("{} lacks an `# expect:` first line", p.display()));
        let (code, _, err) = validate(p);
        if code != 2 || !err.contains(expect) {
            failures.push(format!(
                "{}: exit {code}, stderr `{}`, expected `{expect}`",
                p.display(),
                err.trim()
            ));
        }
        assert!(!err.contains("panicked"), "{} panicked: {err}", p.display());
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn good_scenes_and_cases_validate() {
    let mut all = scenes("tests/scenes/good");
    all.extend(scenes("cases"));
    for p in all {
        let (code, out, err) = validate(&p);
        assert_eq!(code, 0, "{}: {out}{err}", p.display());
    }
}

#[test]
fn overrides_reach_any_field_and_are_checked() {
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/vertical_dry_feed.toml");
    let run = |set: &[&str]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_plugflow"));
        c.arg("validate").arg(&case);
        for s in set {
            c.arg("--set").arg(s);
        }
        let o = c.output().unwrap();
        (
            o.status.code().unwrap(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    assert_eq!(run(&["contact.friction=0.3", "dem.dt=2e-6 s"]).0, 0);
    let (code, err) = run(&["contact.restitution=2"]);
    assert_eq!(code, 2);
    assert!(err.contains("contact.restitution"), "{err}");
    let (code, err) = run(&["dem.dt=1e-3 s"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("dem.dt") && err.contains("stability limit"),
        "{err}"
    );
    let (code, err) = run(&["tube.nonsense=1"]);
    assert_eq!(code, 2);
    assert!(err.contains("nonsense"), "{err}");
}

/// A full standard output (`plugflow validate … > /dev/full`) ends with exit 1 and a
/// message, not a panic (exit 101, as `println!` gives); the check itself still ran.
#[test]
fn a_full_stdout_is_an_error_not_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("no /dev/full on this system: nothing to test");
        return;
    };
    let out = Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .arg("validate")
        .arg(root.join("cases/vertical_plug.toml"))
        .stdout(full)
        .output()
        .expect("run plugflow");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("could not write to standard output"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
