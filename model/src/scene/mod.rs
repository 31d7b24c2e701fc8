//! Scene files: TOML with a schema version, quantities with units, `--set` overrides, and
//! errors that name the field path and the reason.

mod check;
pub mod schema;
pub mod units;

pub use schema::*;

use std::path::Path;

/// An error in a scene: which field and why (or an I/O or syntax error).
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene `{path}`: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// TOML syntax error.
    #[error("scene is not valid TOML: {0}")]
    Syntax(String),
    /// A field has a bad value; `field` is the TOML path (`contact.restitution`).
    #[error("field `{field}`: {reason}")]
    Field { field: String, reason: String },
    /// A `--set` override could not be applied.
    #[error("override `{0}`: {1}")]
    Override(String, String),
    /// The chosen DEM engine refuses the scene (its own mapping; the reason names the field).
    #[error("the `{engine}` engine refuses the scene: {reason}")]
    Engine { engine: String, reason: String },
}

/// DEM engines a scene may name (`dem.engine`); the `plugflow` crate's setup layer builds them.
pub const ENGINES: [&str; 4] = ["native", "native_abi", "liggghts", "yade"];

impl SceneError {
    /// Shorthand for a field error.
    pub fn field(field: impl Into<String>, reason: impl Into<String>) -> Self {
        SceneError::Field {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// A parsed scene whose values have passed the range checks.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The scene as written (after overrides).
    pub file: SceneFile,
    /// The scene text after overrides, re-serialised (stored with results).
    pub text: String,
}

impl Scene {
    /// Read `path`, apply `overrides` (`path.to.field=value`), parse and check.
    pub fn load(path: &Path, overrides: &[String]) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let scene = Self::parse(&text, overrides)?;
        // Files named relative to the scene file (a LIGGGHTS input, the initial grains): made
        // absolute, so the scene (and the JSON handed to the engine) means the same from any
        // folder.
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut all = overrides.to_vec();
        for (field, name) in [
            ("dem.liggghts_input", scene.file.dem.liggghts_input.as_ref()),
            (
                "initial.file",
                scene.file.initial.as_ref().and_then(|i| i.file.as_ref()),
            ),
        ] {
            if let Some(name) = name.filter(|n| Path::new(n).is_relative()) {
                let abs = std::path::absolute(dir.join(name)).unwrap_or(dir.join(name));
                all.push(format!(
                    "{field}={}",
                    toml::Value::String(abs.display().to_string())
                ));
            }
        }
        if all.len() == overrides.len() {
            Ok(scene)
        } else {
            Self::parse(&text, &all)
        }
    }

    /// Parse scene text, apply overrides and check ranges.
    pub fn parse(text: &str, overrides: &[String]) -> Result<Scene, SceneError> {
        let mut table: toml::Table =
            toml::from_str(text).map_err(|e| SceneError::Syntax(e.to_string()))?;
        for o in overrides {
            apply_override(&mut table, o)?;
            // An override of one way of giving a quantity replaces the scene's other way
            // (a sweep over `gas.superficial_velocity` of a scene that gives `gas.flow`).
            let path = o.split_once('=').map_or("", |(p, _)| p.trim());
            for (a, b) in ALTERNATIVES {
                let other = if path == a {
                    b
                } else if path == b {
                    a
                } else {
                    continue;
                };
                let (section, key) = other.split_once('.').expect("dotted");
                if let Some(toml::Value::Table(t)) = table.get_mut(section) {
                    t.remove(key);
                }
            }
        }
        let value = toml::Value::Table(table.clone());
        let file: SceneFile = serde_path_to_error::deserialize(value).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner().to_string();
            let reason = inner.lines().next().unwrap_or_default().trim().to_string();
            SceneError::field(
                if path == "." {
                    "(top level)".into()
                } else {
                    path
                },
                reason,
            )
        })?;
        check::check(&file)?;
        Ok(Scene {
            file,
            text: toml::to_string(&table).unwrap_or_default(),
        })
    }

    /// A scene from the JSON text `pf_dem_create` receives (the inverse of [`Scene::to_json`]).
    pub fn from_json(json: &str) -> Result<Scene, SceneError> {
        let value: toml::Value = serde_json::from_str(json)
            .map_err(|e| SceneError::Syntax(format!("scene JSON: {e}")))?;
        let text =
            toml::to_string(&value).map_err(|e| SceneError::Syntax(format!("scene JSON: {e}")))?;
        Self::parse(&text, &[])
    }

    /// The scene (after overrides) as JSON text: what the DEM ABI's `pf_dem_create` takes.
    pub fn to_json(&self) -> String {
        let value: toml::Value = toml::from_str(&self.text).expect("re-serialised scene parses");
        serde_json::to_string(&value).expect("TOML values serialise to JSON")
    }

    /// The gas's superficial velocity v_s, m/s, however the scene gives it: as such, or as a
    /// volume flow through the tube's section, v_s = 4 V̇ / (π D²). None without a gas or a
    /// tube (or with neither way given: `check` refuses that).
    pub fn superficial_velocity(&self) -> Option<crate::Real> {
        let g = self.file.gas.as_ref()?;
        if let Some(v) = g.superficial_velocity {
            return Some(v.si);
        }
        // (As the DEM's tube radius and the coupler's section: the same roundings.)
        let r = 0.5 * self.file.tube.as_ref()?.diameter.si;
        Some(g.flow?.si / (std::f64::consts::PI * r * r))
    }

    /// The folder a run writes to when no `--out` is given.
    pub fn default_output_dir(&self) -> std::path::PathBuf {
        Path::new("results").join(&self.file.name)
    }
}

/// Fields that say the same thing two ways; a scene gives one, an override of either
/// replaces it.
const ALTERNATIVES: [(&str, &str); 1] = [("gas.superficial_velocity", "gas.flow")];

/// Apply one `a.b.c=value` override; the value is read as TOML (number, string, bool,
/// array) and, failing that, as a bare string (so `dem.dt=5e-6 s` works unquoted).
fn apply_override(table: &mut toml::Table, spec: &str) -> Result<(), SceneError> {
    let (path, raw) = spec
        .split_once('=')
        .ok_or_else(|| SceneError::Override(spec.into(), "expected path.to.field=value".into()))?;
    let path = path.trim();
    if path.is_empty() || path.split('.').any(|p| p.is_empty()) {
        return Err(SceneError::Override(
            spec.into(),
            "empty path segment".into(),
        ));
    }
    let raw = raw.trim();
    let value: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {raw}")) {
        Ok(mut t) => t.remove("v").expect("key v was just parsed"),
        Err(_) => toml::Value::String(raw.to_string()),
    };
    let parts: Vec<&str> = path.split('.').collect();
    let mut cur = table;
    for (k, part) in parts.iter().enumerate() {
        if k + 1 == parts.len() {
            cur.insert(part.to_string(), value);
            return Ok(());
        }
        let entry = cur
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = entry.as_table_mut().ok_or_else(|| {
            SceneError::Override(
                spec.into(),
                format!("`{}` is not a table", parts[..=k].join(".")),
            )
        })?;
    }
    Ok(())
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn field_err(field: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::field(field, reason)
}
