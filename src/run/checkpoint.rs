//! Checkpoints: the whole run between two samples in one file, so that `plugflow run
//! --resume DIR` goes on bit for bit as if it had never stopped (built-in engine, same
//! thread count). A checkpoint holds the engine's state (its own bytes, see
//! `DemBackend::save_state`), the coupler's and the gas's, the analysis accumulators
//! (`Sampling`), the step and sample counters and the snapshot times; the outputs written
//! so far stay in the folder and are cut back to the checkpoint on resume.
//!
//! File: `checkpoints/checkpoint_<step>.pfc` =
//! `MAGIC (8 bytes) | format (u32 LE) | payload length (u64 LE) | FNV-1a 64 of the payload
//! (u64 LE) | payload (postcard)`, the payload being the [`Checkpoint`] followed by the
//! measurements added since format 1 was fixed (today: a periodic section's slug trace, then
//! the layer velocities inside slugs), so
//! that a checkpoint written before them still resumes (they start at the resume). Written to a temporary name, synced, then renamed: a
//! run killed while writing leaves the previous checkpoint whole. The last two are kept.

use std::io::Write;
use std::path::{Path, PathBuf};

use plugflow_coupling::CouplerState;

use super::sampling::Sampling;
use super::RunError;
use crate::scene::Scene;
use crate::Real;

const MAGIC: &[u8; 8] = b"PLUGFCK\n";
/// Bumped whenever [`Checkpoint`] or an engine's part changes meaning.
pub const FORMAT: u32 = 1;
/// Checkpoints kept in `checkpoints/` (older ones are removed).
const KEPT: usize = 2;
const HEADER: usize = 8 + 4 + 8 + 8;

/// The run at one sample.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Checkpoint {
    /// plugflow's version that wrote it (for the message when a format differs).
    pub plugflow_version: String,
    /// The scene as it matters for the physics and the measurements: its text without the
    /// fields a resumed run may change (see [`scene_identity`]).
    pub scene_identity: String,
    pub engine: String,
    pub threads: usize,
    /// Simulated time and DEM steps at the checkpoint.
    pub time: Real,
    pub steps_done: u64,
    pub samples_taken: u64,
    /// The times of the snapshots written so far, s.
    pub snapshot_times: Vec<Real>,
    /// Wall time of the run up to the checkpoint, s (a resumed run's summary adds it).
    pub wall_time_s: f64,
    pub dem: Vec<u8>,
    pub coupler: Option<CouplerState>,
    pub sampling: Sampling,
}

/// Why a checkpoint cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("checkpoint `{path}` refused: {reason}")]
pub struct CheckpointError {
    pub path: String,
    pub reason: String,
}

fn refuse(path: &Path, reason: impl Into<String>) -> CheckpointError {
    CheckpointError {
        path: path.display().to_string(),
        reason: reason.into(),
    }
}

/// FNV-1a, 64 bits: enough to tell a truncated or damaged file from a whole one.
fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The folder of a run's checkpoints.
pub fn folder(out_dir: &Path) -> PathBuf {
    out_dir.join("checkpoints")
}

/// Write `c` atomically into `out_dir/checkpoints/`, keeping the last [`KEPT`].
pub fn write(out_dir: &Path, c: &Checkpoint) -> Result<PathBuf, RunError> {
    let dir = folder(out_dir);
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| RunError::Io { path, source }
    };
    std::fs::create_dir_all(&dir).map_err(io(&dir))?;
    let encode_err = |e: postcard::Error| RunError::Io {
        path: dir.display().to_string(),
        source: std::io::Error::other(format!("cannot encode the checkpoint: {e}")),
    };
    let mut payload = postcard::to_allocvec(c).map_err(encode_err)?;
    payload.extend(postcard::to_allocvec(&c.sampling.slug).map_err(encode_err)?);
    let layers: Option<&[Real]> = c.sampling.profiles.as_ref().map(|p| p.layer_momentum());
    payload.extend(postcard::to_allocvec(&layers).map_err(encode_err)?);
    let path = dir.join(format!("checkpoint_{:012}.pfc", c.steps_done));
    let tmp = dir.join(format!(".checkpoint_{:012}.pfc.part", c.steps_done));
    {
        let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(MAGIC)
            .and_then(|_| f.write_all(&FORMAT.to_le_bytes()))
            .and_then(|_| f.write_all(&(payload.len() as u64).to_le_bytes()))
            .and_then(|_| f.write_all(&checksum(&payload).to_le_bytes()))
            .and_then(|_| f.write_all(&payload))
            .and_then(|_| f.sync_all())
            .map_err(io(&tmp))?;
    }
    std::fs::rename(&tmp, &path).map_err(io(&path))?;
    let mut all = list(&dir);
    while all.len() > KEPT {
        let old = all.remove(0);
        std::fs::remove_file(&old).map_err(io(&old))?;
    }
    Ok(path)
}

/// The checkpoints in `dir`, oldest first.
fn list(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("checkpoint_") && n.ends_with(".pfc"))
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The checkpoint `--resume` names: a `.pfc` file, or the latest in a run folder (or in
/// its `checkpoints/`).
pub fn locate(arg: &Path) -> Result<PathBuf, CheckpointError> {
    if arg.is_file() {
        return Ok(arg.to_path_buf());
    }
    let dir = if folder(arg).is_dir() {
        folder(arg)
    } else {
        arg.to_path_buf()
    };
    list(&dir).pop().ok_or_else(|| {
        refuse(
            arg,
            "no checkpoint there (a run writes them into `checkpoints/` when the scene sets \
             `output.checkpoint_interval`)",
        )
    })
}

/// What a run wants of a checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Use {
    /// Go on with the run that wrote it: the same scene (but [`MAY_CHANGE`]).
    Resume,
    /// Start a new run from its grains and gas: the same geometry, grains and gas grid
    /// ([`MUST_MATCH_TO_START`]); anything else is the new scene's.
    Start,
}

/// The fields a run started from another run's checkpoint must share with it: the grains
/// and the walls they lie in, and the gas grid the pressures live on.
const MUST_MATCH_TO_START: [&str; 7] = [
    "tube.",
    "domain.",
    "particles.",
    "walls",
    "dem.engine",
    "gas.model",
    "gas.grid",
];

/// Read and check a checkpoint file for `scene`.
pub fn read(path: &Path, scene: &Scene, to: Use) -> Result<Checkpoint, CheckpointError> {
    let bytes = std::fs::read(path).map_err(|e| refuse(path, format!("cannot read it: {e}")))?;
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return Err(refuse(path, "not a plugflow checkpoint (no header)"));
    }
    let word = |k: usize| u64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
    let format = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if format != FORMAT {
        return Err(refuse(
            path,
            format!(
                "written in checkpoint format {format}; this plugflow ({}) reads format \
                 {FORMAT}",
                env!("CARGO_PKG_VERSION")
            ),
        ));
    }
    let (len, sum) = (word(12), word(20));
    let payload = &bytes[HEADER..];
    if payload.len() as u64 != len {
        return Err(refuse(
            path,
            format!(
                "truncated: {} of {len} bytes after the header",
                payload.len()
            ),
        ));
    }
    if checksum(payload) != sum {
        return Err(refuse(path, "damaged: its checksum does not match"));
    }
    let (mut c, extension): (Checkpoint, &[u8]) = postcard::take_from_bytes(payload)
        .map_err(|e| refuse(path, format!("cannot be decoded: {e}")))?;
    if !extension.is_empty() {
        let rest;
        (c.sampling.slug, rest) = postcard::take_from_bytes(extension)
            .map_err(|e| refuse(path, format!("its slug trace cannot be decoded: {e}")))?;
        if !rest.is_empty() {
            let layers: Option<Vec<Real>> = postcard::from_bytes(rest).map_err(|e| {
                refuse(
                    path,
                    format!("its slugs' layer velocities cannot be decoded: {e}"),
                )
            })?;
            if let (Some(p), Some(sums)) = (c.sampling.profiles.as_mut(), layers) {
                p.set_layer_momentum(sums);
            }
        }
    }
    let here = scene_identity(scene);
    match to {
        Use::Resume if c.scene_identity != here => {
            return Err(refuse(
                path,
                format!(
                    "written for another scene: {} (to start a new run from its grains, \
                     use --from)",
                    first_difference(&c.scene_identity, &here, &[])
                ),
            ))
        }
        Use::Start => {
            let differs = first_difference(&c.scene_identity, &here, &MUST_MATCH_TO_START);
            if !differs.is_empty() {
                return Err(refuse(
                    path,
                    format!("its grains lie in another geometry or gas grid: {differs}"),
                ));
            }
        }
        Use::Resume => {}
    }
    let engine = &scene.file.dem.engine;
    if &c.engine != engine {
        return Err(refuse(
            path,
            format!(
                "written by engine `{}`, the scene runs `{engine}`",
                c.engine
            ),
        ));
    }
    Ok(c)
}

/// Put a checkpoint's engine and gas state into a run's freshly built engine and coupler:
/// all of it to resume, the grains and the gas fields to start a new run from it.
pub fn take_over(
    path: &Path,
    c: &Checkpoint,
    dem: &mut dyn plugflow_coupling::DemBackend,
    gas: Option<&mut plugflow_coupling::Coupler>,
    to: Use,
) -> Result<(), CheckpointError> {
    let refused = |reason: String| refuse(path, reason);
    match to {
        Use::Resume => dem.restore_state(&c.dem),
        Use::Start => dem.start_from_state(&c.dem),
    }
    .map_err(|e| refused(e.to_string()))?;
    match (gas, &c.coupler, to) {
        (Some(g), Some(state), Use::Resume) => g.restore_state(state),
        (Some(g), Some(state), Use::Start) => g.start_from_state(state),
        (None, None, _) | (None, Some(_), Use::Start) => Ok(()),
        (Some(_), None, _) => return Err(refused("it holds no gas, the scene has one".into())),
        (None, Some(_), Use::Resume) => {
            return Err(refused("it holds a gas, the scene has none".into()))
        }
    }
    .map_err(|e| refused(e.to_string()))
}

/// Fields a resumed run may set differently from the run that wrote the checkpoint: how
/// long it runs, how often it checkpoints, and its threads (another thread count goes on
/// with the same physics, not the same bits).
const MAY_CHANGE: [(&str, &str); 3] = [
    ("", "duration"),
    ("output", "checkpoint_interval"),
    ("dem", "threads"),
];

/// The scene's text (after overrides) without the fields of [`MAY_CHANGE`].
pub fn scene_identity(scene: &Scene) -> String {
    let mut table: toml::Table = toml::from_str(&scene.text).unwrap_or_default();
    for (section, key) in MAY_CHANGE {
        if section.is_empty() {
            table.remove(key);
        } else if let Some(toml::Value::Table(t)) = table.get_mut(section) {
            t.remove(key);
        }
    }
    toml::to_string(&table).unwrap_or_default()
}

/// The first field whose value differs between two scene identities, said for a user;
/// among the fields starting with one of `only` when it is not empty ("" when none does).
fn first_difference(then: &str, now: &str, only: &[&str]) -> String {
    let flat = |text: &str| {
        let mut out = Vec::new();
        let table: toml::Table = toml::from_str(text).unwrap_or_default();
        flatten("", &toml::Value::Table(table), &mut out);
        out.retain(|(k, _)| only.is_empty() || only.iter().any(|p| k.starts_with(p)));
        out
    };
    let (a, b) = (flat(then), flat(now));
    for (k, v) in &a {
        match b.iter().find(|(k2, _)| k2 == k) {
            None => return format!("`{k}` = {v} there, not set here"),
            Some((_, w)) if w != v => return format!("`{k}` = {v} there, {w} here"),
            _ => {}
        }
    }
    match b.iter().find(|(k, _)| !a.iter().any(|(k2, _)| k2 == k)) {
        Some((k, w)) => format!("`{k}` not set there, {w} here"),
        None if only.is_empty() => "the scenes differ".to_string(),
        None => String::new(),
    }
}

fn flatten(prefix: &str, v: &toml::Value, out: &mut Vec<(String, String)>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&key, v, out);
            }
        }
        other => out.push((prefix.to_string(), other.to_string())),
    }
}

/// Where a run stands between two samples: at zero, or where its checkpoint left off.
#[derive(Default)]
pub(super) struct Progress {
    pub steps_done: u64,
    pub samples_taken: u64,
    /// The times of the snapshots written so far, s.
    pub snapshot_times: Vec<Real>,
    /// Wall time of the run before this process, s.
    pub wall_before: f64,
}

/// The checkpoints a run begins from (`--resume`, `--from`), read and checked against the
/// scene before anything is touched.
pub(super) struct Beginning {
    resume: Option<(PathBuf, Checkpoint)>,
    from: Option<(PathBuf, Checkpoint)>,
}

impl Beginning {
    pub fn read(
        scene: &Scene,
        resume: Option<&Path>,
        from: Option<&Path>,
    ) -> Result<Self, CheckpointError> {
        let open = |arg: Option<&Path>, to: Use| -> Result<_, CheckpointError> {
            arg.map(|a| {
                let path = locate(a)?;
                let c = read(&path, scene, to)?;
                Ok((path, c))
            })
            .transpose()
        };
        Ok(Self {
            resume: open(resume, Use::Resume)?,
            from: open(from, Use::Start)?,
        })
    }

    /// The grains come from a checkpoint (`--resume` or `--from`).
    pub fn takes_grains(&self) -> bool {
        self.resume.is_some() || self.from.is_some()
    }

    pub fn resumes(&self) -> bool {
        self.resume.is_some()
    }

    /// The folder a resumed run writes into by default: the one its checkpoint lies in
    /// (`<run>/checkpoints/<file>`).
    pub fn resumed_run_dir(&self) -> Option<PathBuf> {
        let (path, _) = self.resume.as_ref()?;
        path.parent().and_then(Path::parent).map(Path::to_path_buf)
    }

    /// Hand the checkpoints' states to the freshly built engine and gas (`--from`: grains
    /// and gas fields; `--resume`: all of it, and the sampling and counters returned), each
    /// said in the run's log.
    pub fn take_over(
        self,
        out_dir: &Path,
        threads: usize,
        dem: &mut dyn plugflow_coupling::DemBackend,
        mut gas: Option<&mut plugflow_coupling::Coupler>,
        log: &mut super::run_log::RunLog,
    ) -> Result<Option<(Sampling, Progress)>, CheckpointError> {
        if let Some((path, c)) = self.from {
            take_over(&path, &c, dem, gas.as_deref_mut(), Use::Start)?;
            log.line(&format!(
                "started from `{}` (t = {} s of the run that wrote it): {} grains",
                path.display(),
                c.time,
                dem.particles().len()
            ));
        }
        let Some((path, c)) = self.resume else {
            return Ok(None);
        };
        log.line(&format!(
            "resumed from `{}` at t = {} s (step {}, sample {})",
            path.display(),
            c.time,
            c.steps_done,
            c.samples_taken
        ));
        if !out_dir.join("run.h5").exists() {
            return Err(refuse(
                &path,
                format!(
                    "the outputs of the run that wrote it are not in `{}`: resume into that \
                     run's folder (without --out), or start a new run from it with --from",
                    out_dir.display()
                ),
            ));
        }
        take_over(&path, &c, dem, gas, Use::Resume)?;
        if c.threads != threads {
            log.line(&format!(
                "warning: the checkpoint ran on {} threads, this run on {threads}: the same \
                 physics, not the same bits",
                c.threads
            ));
        }
        let at = Progress {
            steps_done: c.steps_done,
            samples_taken: c.samples_taken,
            snapshot_times: c.snapshot_times,
            wall_before: c.wall_time_s,
        };
        Ok(Some((c.sampling, at)))
    }
}

/// Write a checkpoint of the run as it stands (between samples: no advance is under way).
/// Under MPI every rank calls it (the engine's state is taken collectively) and only the
/// rank that `writes` does: the other ranks' sampling, gas and counters are the same.
#[allow(clippy::too_many_arguments)]
pub(super) fn save(
    out_dir: &Path,
    scene: &Scene,
    dem: &mut dyn plugflow_coupling::DemBackend,
    gas: Option<&plugflow_coupling::Coupler>,
    sampling: &Sampling,
    at: &Progress,
    wall_time_s: f64,
    writes: bool,
) -> Result<PathBuf, RunError> {
    let failed = |reason: String| RunError::Io {
        path: folder(out_dir).display().to_string(),
        source: std::io::Error::other(format!("cannot take a checkpoint: {reason}")),
    };
    let c = Checkpoint {
        plugflow_version: env!("CARGO_PKG_VERSION").to_string(),
        scene_identity: scene_identity(scene),
        engine: dem.engine_name().to_string(),
        threads: scene.file.dem.threads,
        time: dem.time(),
        steps_done: at.steps_done,
        samples_taken: at.samples_taken,
        snapshot_times: at.snapshot_times.clone(),
        wall_time_s,
        dem: dem.save_state().map_err(|e| failed(e.to_string()))?,
        coupler: gas
            .map(|g| g.save_state())
            .transpose()
            .map_err(|e| failed(e.to_string()))?,
        sampling: sampling.clone(),
    };
    match writes {
        true => write(out_dir, &c),
        false => Ok(folder(out_dir).join(format!("checkpoint_{:012}.pfc", c.steps_done))),
    }
}
