//! A whole run's lifecycle: set the scene up (`crate::setup`), advance it sample interval
//! by sample interval through the coupled step (`plugflow_coupling::Coupler::advance`),
//! sample (`sampling.rs`), show progress, stop on a signal, and write `summary.json` and the
//! figures (`report.rs`), also when the run fails part-way, with what it computed up to
//! then. No physics lives here.

pub mod checkpoint;
mod gathered;
pub mod last_words;
mod report;
mod run_log;
mod sampling;

use std::path::{Path, PathBuf};
use std::time::Instant;

use plugflow_coupling::{StepError, Verdict};

use crate::output::csv::CsvOutput;
use crate::output::hdf5::{Hdf5Output, RunMeta};
use crate::output::vtk::VtkOutput;
use crate::output::RunOutput;
use crate::scene::schema::SnapshotFormat;
use crate::scene::{Scene, SceneError};
use crate::setup::{self, Setup};
use crate::summary::Summary;
use crate::Real;
use checkpoint::Progress;
use report::{summarize, write_figures, Ending};
use run_log::{human_duration, RunLog};
use sampling::Sampling;

/// Set (by the CLI's SIGINT/SIGTERM handler) to end the running run at its next sample,
/// with every output written as for a finished run and the summary's status saying so.
pub static INTERRUPT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// What can end a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Stopped on request (Ctrl-C, SIGTERM); the outputs hold the run up to then.
    #[error("interrupted at t = {time:.6} s; outputs hold the run up to then")]
    Interrupted { time: Real },
    /// The scene is wrong.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The coupled step stopped: the engine (NaN, blow-up, engine failure) or the gas and
    /// the exchange (NaN pressure, drag), with the time.
    #[error(transparent)]
    Step(#[from] StepError),
    /// An output file (run.h5, VTK, figure) could not be written.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A checkpoint to resume from cannot be used.
    #[error(transparent)]
    Checkpoint(#[from] checkpoint::CheckpointError),
    /// Output could not be written.
    #[error("cannot write `{path}`: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// Under MPI: another rank stopped the run (rank 0's files: no room, run.h5), in its
    /// words.
    #[error("rank {rank}: {message}")]
    OtherRank { rank: usize, message: String },
}

/// How to run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder (default `results/<scene name>/`).
    pub out_dir: Option<PathBuf>,
    /// Simulated time overriding the scene's, s.
    pub duration: Option<Real>,
    /// Show progress: a bar on a terminal, else a plain line every few seconds on stderr
    /// (`log.plugflow` gets the lines either way).
    pub progress: bool,
    /// Go on from a checkpoint: a `.pfc` file, or a run folder (its latest checkpoint).
    /// The run writes into that run's folder unless `out_dir` says otherwise.
    pub resume: Option<PathBuf>,
    /// Start from another run's checkpoint (a `.pfc` file or a run folder): its grains
    /// and gas at t = 0, with this scene's other settings (a filled tube for a sweep).
    pub from: Option<PathBuf>,
}

/// Headline numbers of a finished run (also written to `summary.json`).
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The summary as written.
    pub summary: Summary,
    /// Where it was written.
    pub out_dir: PathBuf,
}

/// Run a scene to its end.
pub fn run(scene: &Scene, opts: &RunOptions) -> Result<RunOutcome, RunError> {
    let world = setup::ranks::launched();
    // The checkpoints it begins from, checked against the scene before anything is touched.
    let beginning =
        checkpoint::Beginning::read(scene, opts.resume.as_deref(), opts.from.as_deref())?;
    let out_dir = opts
        .out_dir
        .clone()
        .or_else(|| beginning.resumed_run_dir())
        .unwrap_or_else(|| scene.default_output_dir());
    // Under MPI (LIGGGHTS on several ranks) rank 0 alone writes the run's files; every
    // rank steps, samples and decides alike.
    let lead = world.leads();
    let mut log = match lead {
        true => {
            std::fs::create_dir_all(&out_dir).map_err(|source| RunError::Io {
                path: out_dir.display().to_string(),
                source,
            })?;
            if !beginning.resumes() {
                clear_previous_outputs(&out_dir)?;
            }
            // A disk too full for the run's end is said before the run starts.
            crate::output::room::RoomGuard::new(&out_dir.join("run.h5")).check()?;
            RunLog::create(&out_dir, opts.progress, beginning.resumes())?
        }
        false => RunLog::silent(),
    };
    log.line(&format!(
        "plugflow {}: scene `{}`",
        env!("CARGO_PKG_VERSION"),
        scene.file.name
    ));
    // An engine that ends the process (or, under MPI, a rank that dies) still leaves the
    // summary of the last sample: armed before the engine is built (see `last_words`),
    // disarmed however this function returns.
    last_words::arm(&out_dir, world.rank, world.size);
    let _disarm = last_words::Disarm;
    let Setup {
        config: cfg,
        engine: mut dem,
        coupler: mut gas,
    } = setup::build(scene, beginning.takes_grains())
        .inspect_err(|e| log.line(&format!("error: {e}")))?;
    // The engine's own log (LIGGGHTS's) is kept beside plugflow's.
    let ranks = dem.ranks();
    // The grains of all ranks, gathered at each sample (None: one process, read directly).
    let mut gathered = (ranks.size > 1).then(gathered::Gathered::default);
    // (Every rank: under MPI rank 0 keeps the logs, and a rank that meets an error alone
    // leaves its last words there.)
    let kept = dem.keep_log(&out_dir);
    if let Err(e) = kept {
        log.line(&format!(
            "warning: the engine's own log cannot be kept: {e}"
        ));
    }
    let (mut sampling, mut at) =
        match beginning.take_over(&out_dir, cfg.threads, dem.as_mut(), gas.as_mut(), &mut log)? {
            Some(resumed) => resumed,
            None => (Sampling::new(scene, &cfg), Progress::default()),
        };
    let f = &scene.file;
    let duration = opts.duration.unwrap_or(f.duration.si);
    let dt = dem.time_step();
    let total_steps = (duration / dt).round().max(1.0) as u64;
    let mut per_sample = ((f.output.sample_interval.si / dt).round() as u64).max(1);
    log.line(&format!(
        "engine {} {}, dt {dt:e} s, {total_steps} steps for {duration} s simulated{}",
        dem.engine_name(),
        dem.engine_version(),
        match ranks.size {
            1 => String::new(),
            n => format!(", on {n} MPI ranks"),
        }
    ));
    if let Some(g) = &gas {
        // Sample on coupling boundaries.
        per_sample = per_sample.div_ceil(g.substeps) * g.substeps;
        for c in &g.checks {
            let text = format!(
                "coupling check: {}: {:.4} (limit {:.4}) {:?}{}",
                c.name,
                c.value,
                c.limit,
                c.verdict,
                if c.verdict == Verdict::Ok {
                    String::new()
                } else {
                    format!(" — {}", c.advice)
                }
            );
            if opts.progress && lead {
                eprintln!("{text}");
            }
            log.line(&text);
        }
    }
    let bar = (lead && RunLog::wants_bar(opts.progress)).then(|| progress_bar(total_steps));
    let wall = Instant::now();
    let start = dem.time();
    let snapshot_spec = f.output.snapshots.as_ref();
    let wants = |fmt: SnapshotFormat| snapshot_spec.is_some_and(|s| s.formats.contains(&fmt));
    let mut outputs: Vec<Box<dyn RunOutput>> = Vec::new();
    let meta = RunMeta {
        scene_text: &scene.text,
        engine: dem.engine_name(),
        engine_version: &dem.engine_version(),
        z_slices: sampling.slice_centres(),
        z_gas: gas.as_ref().map(|g| g.axial_positions()),
        snapshots: wants(SnapshotFormat::Hdf5),
        walls: sampling.name_walls(dem.as_ref()).to_vec(),
        tube_axis: cfg.tube.map(|t| t.axis),
    };
    let (h5, csv) = (out_dir.join("run.h5"), out_dir.join("timeseries.csv"));
    if !lead {
        // (Rank 0 writes them.)
    } else if at.steps_done == 0 {
        outputs.push(Box::new(Hdf5Output::create(&h5, &meta)?));
        outputs.push(Box::new(CsvOutput::create(
            &csv,
            gas.is_some(),
            &sampling.walls,
        )?));
        if wants(SnapshotFormat::Vtk) {
            outputs.push(Box::new(VtkOutput::for_scene(&out_dir, &cfg)?));
        }
    } else {
        // Resumed: what the outputs hold past the checkpoint (the stopped run went on
        // after it) is cut off, then the run appends as the uninterrupted one would.
        let (samples, snaps, time) = (at.samples_taken, &at.snapshot_times, dem.time());
        outputs.push(Box::new(Hdf5Output::reopen(
            &h5,
            &meta,
            samples,
            snaps.len(),
            time,
        )?));
        outputs.push(Box::new(CsvOutput::reopen(
            &csv,
            gas.is_some(),
            &sampling.walls,
            samples,
        )?));
        if wants(SnapshotFormat::Vtk) {
            outputs.push(Box::new(VtkOutput::reopen(
                &out_dir,
                &cfg,
                snaps,
                gas.is_some(),
            )?));
        }
    }
    drop(meta);
    let samples_per_snapshot =
        snapshot_spec.map(|s| ((s.interval.si / (per_sample as Real * dt)).round() as u64).max(1));
    let samples_per_checkpoint = f
        .output
        .checkpoint_interval
        .map(|c| ((c.si / (per_sample as Real * dt)).round() as u64).max(1));
    let mut checkpointed_at = (at.steps_done > 0).then_some(at.steps_done);
    let mut failure = None;
    let mut room = crate::output::room::RoomGuard::new(&out_dir.join("run.h5"));
    let save_checkpoint = |dem: &mut dyn plugflow_coupling::DemBackend,
                           gas: Option<&plugflow_coupling::Coupler>,
                           sampling: &Sampling,
                           at: &Progress| {
        let wall_so_far = at.wall_before + wall.elapsed().as_secs_f64();
        // (Under MPI every rank takes the engine's state, a collective call; rank 0 writes
        // it, and a failure to write stops every rank.)
        let saved = checkpoint::save(&out_dir, scene, dem, gas, sampling, at, wall_so_far, lead);
        agreed(&*dem, saved)
    };
    while at.steps_done < total_steps {
        // Before the steps of the next sample: a run stopped for room ends where run.h5 does.
        // (Rank 0's disk: under MPI every rank stops with it.)
        let room_left = match lead {
            true => room.check().map_err(RunError::Output),
            false => Ok(()),
        };
        if let Err(e) = agreed(dem.as_ref(), room_left) {
            failure = Some(e);
            break;
        }
        let n = per_sample.min(total_steps - at.steps_done);
        // The step: the coupled one with gas, the DEM's alone without. With gas in pieces of
        // whole coupling intervals (the same steps as one call), so that Ctrl-C or SIGTERM is
        // seen within a piece, not only at the next sample; without gas one piece per sample
        // (a DEM-only sample is short: the sample interval's steps of a gas-free scene).
        let piece = match &gas {
            Some(g) => g.substeps * STEPS_PER_PIECE.div_ceil(g.substeps),
            None => n.max(STEPS_PER_PIECE),
        };
        let mut left = n;
        let mut stepped = Ok(());
        while left > 0 && stepped.is_ok() {
            if interrupted(dem.as_ref()) {
                break;
            }
            let k = piece.min(left);
            stepped = match gas.as_mut() {
                Some(g) => g.advance(dem.as_mut(), k),
                None => dem.advance(k).map_err(|source| StepError::Backend {
                    time: dem.time(),
                    source,
                }),
            };
            left -= k;
        }
        if let Err(e) = stepped {
            failure = Some(RunError::Step(e));
            break;
        }
        // (Interrupted inside the sample, `left > 0`: the sample is taken where the run
        // stopped, and the check below ends the run.)
        at.steps_done += n - left;
        let snapshot_due = samples_per_snapshot.is_some_and(|k| at.samples_taken.is_multiple_of(k));
        let view = match viewed(dem.as_ref(), gathered.as_mut()) {
            Ok(v) => v,
            Err(source) => {
                let time = dem.time();
                failure = Some(RunError::Step(StepError::Backend { time, source }));
                break;
            }
        };
        let sampled = sampling
            .sample(&cfg, view, gas.as_ref(), dt, &mut outputs, snapshot_due)
            .map_err(RunError::Output);
        // (Only rank 0 writes outputs: under MPI every rank stops with its failure.)
        let seen = match agreed(dem.as_ref(), sampled) {
            Ok(seen) => seen,
            Err(e) => {
                failure = Some(e);
                break;
            }
        };
        last_words::update(summarize(&Ending {
            scene,
            cfg: &cfg,
            dem: view,
            gas: gas.as_ref(),
            sampling: &sampling,
            profiles: None,
            status: String::new(),
            wall_time: at.wall_before + wall.elapsed().as_secs_f64(),
        }));
        if snapshot_due {
            at.snapshot_times.push(dem.time());
        }
        at.samples_taken += 1;
        if samples_per_checkpoint.is_some_and(|k| at.samples_taken.is_multiple_of(k)) {
            if let Err(e) = save_checkpoint(dem.as_mut(), gas.as_ref(), &sampling, &at) {
                failure = Some(e);
                break;
            }
            checkpointed_at = Some(at.steps_done);
        }
        log.progress(
            dem.time(),
            || {
                progress_line(
                    dem.time(),
                    start,
                    duration,
                    wall.elapsed().as_secs_f64(),
                    &seen,
                )
            },
            at.samples_taken == 1,
        );
        if interrupted(dem.as_ref()) {
            failure = Some(RunError::Interrupted { time: dem.time() });
            break;
        }
        if let Some(b) = &bar {
            b.set_position(at.steps_done);
            b.set_message(format!(
                "t = {:.3}/{:.3} s, {} grains in tube{}",
                dem.time(),
                duration,
                seen.in_tube,
                seen.pressure_drop
                    .map(|d| format!(", Δp {:.1} hPa/m", d / 100.0))
                    .unwrap_or_default()
            ));
        }
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    // The run's end (or its stop on request) is a checkpoint too: a finished run can be
    // taken further, a stopped one resumed. Not after a failure: that state is broken.
    // A stop on request always leaves one where the engine can write it (a sweep re-run
    // resumes its stopped variants from there).
    let interrupted = matches!(failure, Some(RunError::Interrupted { .. }));
    let stopped_cleanly = failure.is_none() || interrupted;
    let asked = samples_per_checkpoint.is_some();
    if (asked || interrupted) && stopped_cleanly && checkpointed_at != Some(at.steps_done) {
        match save_checkpoint(dem.as_mut(), gas.as_ref(), &sampling, &at) {
            Ok(path) => log.line(&format!(
                "checkpoint `{}` at t = {} s",
                path.display(),
                dem.time()
            )),
            // (Not asked for: an engine that cannot write one just has none.)
            Err(e) if !asked => log.line(&format!("no checkpoint at the stop: {e}")),
            Err(e) => failure = failure.or(Some(e)),
        }
    }
    let last = sampling.last_seen();
    log.progress(
        dem.time(),
        || {
            progress_line(
                dem.time(),
                start,
                duration,
                wall.elapsed().as_secs_f64(),
                &last,
            )
        },
        true,
    );
    let profiles = sampling.profiles.as_ref().map(|p| p.result());
    // The end: figures, the profiles into run.h5, then the summary, each attempted whatever
    // failed before (a full disk: whatever still fits is written), the summary last so that
    // its status names the first failure.
    let mut end_errors: Vec<RunError> = Vec::new();
    // (Under MPI the grains of every rank once more, for the summary: every rank stopped
    // at the same call, so every rank takes part.)
    let view = match viewed(dem.as_ref(), gathered.as_mut()) {
        Ok(v) => v,
        Err(e) => {
            end_errors.push(RunError::Step(StepError::Backend {
                time: dem.time(),
                source: e,
            }));
            dem.as_ref()
        }
    };
    let drawn = match lead {
        true => write_figures(
            &out_dir,
            &cfg,
            view,
            gas.as_ref(),
            &sampling,
            profiles.as_ref(),
        ),
        false => Ok(()),
    };
    if let Err(e) = drawn {
        end_errors.push(e);
    }
    if let Some(res) = &profiles {
        for o in outputs.iter_mut() {
            if let Err(e) = o.finish(Some(res)) {
                end_errors.push(RunError::Output(e));
            }
        }
    }
    // Close run.h5 now (and write its ParaView sidecar): what it holds is on disk before
    // the summary says so.
    for o in outputs.iter_mut() {
        if let Err(e) = o.close() {
            end_errors.push(RunError::Output(e));
        }
    }
    drop(outputs);
    let failure = failure.or_else(|| {
        let mut errors = std::mem::take(&mut end_errors).into_iter();
        let first = errors.next();
        end_errors = errors.collect();
        first
    });
    let summary = summarize(&Ending {
        scene,
        cfg: &cfg,
        dem: view,
        gas: gas.as_ref(),
        sampling: &sampling,
        profiles: profiles.as_ref(),
        status: match &failure {
            None => "completed".to_string(),
            Some(e @ RunError::Interrupted { .. }) => e.to_string(),
            Some(e) => format!("failed: {e}"),
        },
        wall_time: at.wall_before + wall.elapsed().as_secs_f64(),
    });
    let written = match lead {
        true => write_summary(&out_dir.join("summary.json"), &summary),
        false => Ok(()),
    };
    if let Err(e) = written {
        end_errors.push(e);
    }
    for w in &summary.warnings {
        log.line(&format!("warning: {w}"));
    }
    log.line(&format!(
        "{}: {:.4} s simulated in {:.1} s wall",
        summary.status, summary.simulated_time_s, summary.wall_time_s
    ));
    for later in &end_errors {
        log.line(&format!("error: {later}"));
    }
    if let Some(e) = log.take_failure() {
        end_errors.push(RunError::Output(e));
    }
    match failure {
        Some(e) => {
            // The first failure is the run's error; the later ones (the same full disk,
            // most likely) are said here.
            for later in &end_errors {
                eprintln!("error (after the first): {later}");
            }
            Err(e)
        }
        None => match end_errors.into_iter().next() {
            Some(e) => Err(e),
            None => Ok(RunOutcome { summary, out_dir }),
        },
    }
}

/// What a sample reads: the engine itself in one process; under MPI the grains of every
/// rank gathered (collective: every rank calls it at the same place).
fn viewed<'a>(
    dem: &'a dyn plugflow_coupling::DemBackend,
    gathered: Option<&'a mut gathered::Gathered>,
) -> Result<&'a dyn plugflow_coupling::DemBackend, plugflow_coupling::BackendError> {
    match gathered {
        None => Ok(dem),
        Some(g) => {
            g.refresh(dem)?;
            Ok(g)
        }
    }
}

/// Under MPI, a failure one rank alone can meet (rank 0's files) stops every rank at the
/// same place, each with the failing rank's words; with one rank, the result as it is.
fn agreed<T>(
    dem: &dyn plugflow_coupling::DemBackend,
    local: Result<T, RunError>,
) -> Result<T, RunError> {
    if dem.ranks().size == 1 {
        return local;
    }
    let words = local.as_ref().err().map(|e| e.to_string());
    match plugflow_coupling::ranks::first_failure(dem, words.as_deref()) {
        Ok(None) => local,
        Ok(Some(_)) if local.is_err() => local,
        Ok(Some((rank, message))) => Err(RunError::OtherRank { rank, message }),
        Err(source) => Err(RunError::Step(StepError::Backend {
            time: dem.time(),
            source,
        })),
    }
}

/// Whether the run was asked to stop (Ctrl-C, SIGTERM). Under MPI the ranks agree (any
/// rank asked: all stop at the same place), so none waits in a collective for a rank
/// that left.
fn interrupted(dem: &dyn plugflow_coupling::DemBackend) -> bool {
    let mine = INTERRUPT.load(std::sync::atomic::Ordering::Relaxed);
    if dem.ranks().size == 1 {
        return mine;
    }
    let mut flag = [mine as u8 as f64];
    // (A reduction that fails leaves this rank's own answer.)
    let _ = dem.all_reduce(&mut flag, plugflow_coupling::Reduce::Max);
    flag[0] > 0.0
}

fn progress_bar(total_steps: u64) -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(total_steps);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% ETA {eta} {msg}",
        )
        .expect("static template"),
    );
    b
}

/// One plain progress line: simulated time, rate (of this process, which began at
/// simulated time `start`), ETA, grains in the tube, Δp.
fn progress_line(
    time: Real,
    start: Real,
    duration: Real,
    wall: f64,
    seen: &sampling::Seen,
) -> String {
    let rate = (time - start) / wall.max(1e-9);
    format!(
        "t = {time:.4}/{duration} s ({:.0} %), {rate:.3e} s simulated per wall second, ETA {}, \
         {} grains in tube{}",
        100.0 * time / duration,
        human_duration((duration - time) / rate),
        seen.in_tube,
        seen.pressure_drop
            .map(|d| format!(", Δp {:.2} hPa/m", d / 100.0))
            .unwrap_or_default()
    )
}

fn write_summary(path: &Path, s: &Summary) -> Result<(), RunError> {
    std::fs::write(path, s.to_json_pretty()).map_err(|source| RunError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// DEM steps between looks at the stop flag within a sample (rounded up to whole coupling
/// intervals): ~0.1 s of wall time for 10 000 grains on one core.
const STEPS_PER_PIECE: u64 = 500;

/// The files a run writes into its folder (besides the numbered snapshots, see
/// [`clear_previous_outputs`]).
const RUN_OUTPUTS: [&str; 17] = [
    "log.plugflow",
    "run.xdmf",
    "log.liggghts",
    "log2.liggghts",
    "timeseries.csv",
    "particles.pvd",
    "gas.pvd",
    "geometry.vtp",
    "summary.json",
    "run.h5",
    "plug_statistics.png",
    "porosity_tz.csv",
    "porosity_tz.png",
    "pressure_drop.png",
    "pressure_taps.csv",
    "pressure_taps.png",
    "profiles.png",
];

/// Remove what an earlier run left in `dir` before this one writes there: a run killed
/// part-way must not leave the old, complete summary beside its own shorter `run.h5`, and
/// the old run's extra snapshots must not join this run's series. Other files stay.
fn clear_previous_outputs(dir: &Path) -> Result<(), RunError> {
    let entries = std::fs::read_dir(dir).map_err(|source| RunError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    // An older run's checkpoints: this run is not that one.
    let old_checkpoints = checkpoint::folder(dir);
    if old_checkpoints.is_dir() {
        std::fs::remove_dir_all(&old_checkpoints).map_err(|source| RunError::Io {
            path: old_checkpoints.display().to_string(),
            source,
        })?;
    }
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        // Numbered snapshots: this version's and the legacy `.vtk` of earlier ones.
        let snapshot = (name.starts_with("particles_")
            && [".vtk", ".vtp"].iter().any(|e| name.ends_with(e)))
            || (name.starts_with("gas_") && name.ends_with(".vts"));
        if snapshot || RUN_OUTPUTS.contains(&name.as_ref()) {
            std::fs::remove_file(entry.path()).map_err(|source| RunError::Io {
                path: entry.path().display().to_string(),
                source,
            })?;
        }
    }
    Ok(())
}
