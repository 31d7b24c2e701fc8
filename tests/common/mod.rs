//! Helpers shared by the integration tests.
#![allow(dead_code)]

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;

/// Engine from scene text (panics with the scene error: test scenes are ours).
pub fn engine(text: &str) -> NativeDem {
    let scene = Scene::parse(text, &[]).unwrap_or_else(|e| panic!("test scene: {e}"));
    NativeDem::new(plugflow::setup::dem_config(&scene).unwrap_or_else(|e| panic!("config: {e}")))
        .unwrap_or_else(|e| panic!("engine: {e}"))
}

/// A box scene without tube; `contact` and `extra` are TOML snippets.
pub fn box_scene(gravity: &str, contact: &str, extra: &str) -> String {
    format!(
        r#"
schema_version = 1
name = "test"
duration = "1 s"
gravity = {gravity}
[domain]
min = [-0.01, -0.01, -0.01]
max = [0.01, 0.01, 0.01]
[particles]
diameter = "1.4 mm"
density = "937 kg/m^3"
[contact]
{contact}
{extra}
"#
    )
}

pub const HOOKE: &str = r#"normal = "hooke"
tangential = "history"
contact_time = "1e-4 s"
friction = 0.5
restitution = 0.5"#;

pub const HERTZ: &str = r#"normal = "hertz"
tangential = "history"
youngs_modulus = "1e7 Pa"
poisson_ratio = 0.3
friction = 0.5
restitution = 0.5"#;

pub fn grain(x: [f64; 3], v: [f64; 3]) -> plugflow_coupling::NewParticle {
    plugflow_coupling::NewParticle {
        position: x,
        velocity: v,
        radius: 0.7e-3,
        density: 937.0,
    }
}

/// Run the `plugflow` binary; (exit code, stdout + stderr).
pub fn plugflow(args: &[&str]) -> (i32, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_plugflow"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
    )
}

/// `summary.json` of a run folder: checked to parse as plugflow's typed
/// [`plugflow::summary::Summary`] (so every summary a test sees keeps to the schema), and
/// returned as JSON for reading by key, as users' scripts read it.
pub fn read_summary(dir: &std::path::Path) -> serde_json::Value {
    let path = dir.join("summary.json");
    plugflow::summary::Summary::read(&path).unwrap_or_else(|e| panic!("{e}"));
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// `plugflow run CASE --out DIR --quiet EXTRA…` into a fresh temporary folder named by
/// `tag`: (exit code, stdout + stderr, the folder, its summary or Null when none was written).
pub fn run_case(
    case: &str,
    tag: &str,
    extra: &[&str],
) -> (i32, String, std::path::PathBuf, serde_json::Value) {
    let out = std::env::temp_dir().join(format!("plugflow_{tag}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut args = vec!["run", case, "--out", out.to_str().unwrap(), "--quiet"];
    args.extend_from_slice(extra);
    let (code, text) = plugflow(&args);
    let summary = if out.join("summary.json").exists() {
        read_summary(&out)
    } else {
        serde_json::Value::Null
    };
    (code, text, out, summary)
}

/// The conveyor inlet's checks on any engine after `seconds` of the vertical case without
/// gas: grains fed = grains per metre of column × (distance moved − one radius), within 3σ of
/// the Poisson count of the 4-diameter block the entry line crosses (as
/// model/src/dem/conveyor.rs's engine test); every grain deeper in the slab than a stride's
/// travel plus a diameter moves at exactly the feed velocity with no spin; some grains above
/// the slab are free. Returns (grains fed, grains held deep, grains free above).
pub fn assert_conveyor_feeds(
    name: &str,
    dem: &dyn plugflow_coupling::DemBackend,
    cfg: &plugflow::dem::DemConfig,
    seconds: f64,
) -> (f64, usize, usize) {
    let (inlet, tube) = (cfg.inlet.unwrap(), cfg.tube.unwrap());
    let per_metre = inlet.rate / inlet.velocity;
    let expected = per_metre * (inlet.velocity * seconds - cfg.radius_max);
    let block = per_metre * 4.0 * 2.0 * cfg.radius_max;
    let feed_v: Vec<f64> = tube.axis.iter().map(|a| a * inlet.velocity).collect();
    let fed = dem.flow().unwrap().fed_count as f64;
    let p = dem.particles();
    let (mut deep, mut above_moving) = (0, 0);
    for i in 0..p.len() {
        let a: f64 = (0..3)
            .map(|k| (p.position[i][k] - tube.origin[k]) * tube.axis[k])
            .sum();
        if a < inlet.slab_length - 4.0 * cfg.radius_max {
            deep += 1;
            for (k, v) in feed_v.iter().enumerate() {
                assert!(
                    (p.velocity[i][k] - v).abs() < 1e-12,
                    "{name}: grain {} at {a} m moves at {:?}",
                    p.id[i],
                    p.velocity[i]
                );
                assert!(p.angular_velocity[i][k].abs() < 1e-12, "{name}");
            }
        } else if a > inlet.slab_length + 2.0 * cfg.radius_max {
            let dv: f64 = (0..3).map(|k| (p.velocity[i][k] - feed_v[k]).powi(2)).sum();
            if dv > 1e-6 {
                above_moving += 1;
            }
        }
    }
    eprintln!(
        "{name}: {fed} fed (expected {expected:.0}), {} grains, {deep} held deep in the slab, \
         {above_moving} free above it",
        p.len()
    );
    assert!(
        (fed - expected).abs() < 3.0 * block.sqrt(),
        "{name}: {fed} grains fed in {seconds} s, expected {expected}"
    );
    assert!(
        deep > 100 && above_moving > 0,
        "{name}: {deep} grains held deep in the slab, {above_moving} free above it"
    );
    (fed, deep, above_moving)
}
