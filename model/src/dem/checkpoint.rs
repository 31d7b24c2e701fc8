//! The built-in engine's checkpoint: everything [`NativeDem`] carries from one `advance`
//! call to the next, as exact bits (postcard keeps every f64 as its 8 bytes). Restored into an
//! engine built from the same scene, the next steps are bit for bit those of the engine
//! that never stopped: the grains keep their order, the neighbour list its pairs and
//! shear histories, the threads their chunks, the inlet its RNG and backlog. Scratch
//! (contact lists, predicted velocities, the sort's buffers) is filled again by the next
//! step before anything reads it.

use plugflow_coupling::{BackendError, StageTimer};

use super::neighbor::{ListUpkeep, NeighborKeep};
use super::state::ParticleState;
use super::{cut_by_cost, FlowCounters, NativeDem, MIN_GRAINS_PER_CHUNK};
use crate::dem::conveyor::Conveyor;
use crate::dem::inlet::Feeder;
use crate::rng::Rng;
use crate::{Real, Vec3};

/// Bumped whenever [`Saved`] or what follows it changes: an older checkpoint is refused,
/// not misread. Format 3 writes the list's upkeep counts after [`Saved`], as an option
/// (None: unknown since a resume from a checkpoint without them, so that they stay left
/// out however often the run is resumed again). Format 1 (without them) is still read,
/// and so is format 2 (the counts alone, written by development builds that did not keep
/// whether they covered the whole run: taken as unknown).
const FORMAT: u32 = 3;
/// The oldest format this build reads.
const OLDEST_READ: u32 = 1;

#[derive(serde::Serialize, serde::Deserialize)]
struct Saved {
    format: u32,
    walls: usize,
    threads: usize,
    time: Real,
    step: u64,
    next_id: u64,
    rng: Rng,
    rebuild_pending: bool,
    feeder: Feeder,
    flow: FlowCounters,
    wall_force: Vec<Vec3>,
    /// The pair constants were dropped (a grain unlike the scene's was inserted).
    mixed_grains: bool,
    bounds: Vec<usize>,
    may_leave: Vec<u32>,
    state: ParticleState,
    nlist: NeighborKeep,
    timer: Vec<(String, f64)>,
}

fn refused(message: String) -> BackendError {
    BackendError::Engine {
        engine: "native".to_string(),
        message: format!("checkpoint refused: {message}"),
    }
}

/// The engine's state as bytes.
pub(super) fn save(dem: &NativeDem) -> Result<Vec<u8>, BackendError> {
    let saved = Saved {
        format: FORMAT,
        walls: dem.cfg.walls.len(),
        threads: dem.cfg.threads,
        time: dem.time,
        step: dem.step,
        next_id: dem.next_id,
        rng: dem.rng.clone(),
        rebuild_pending: dem.rebuild_pending,
        feeder: dem.feeder.clone(),
        flow: dem.flow.clone(),
        wall_force: dem.wall_force.clone(),
        mixed_grains: dem.uniform.is_none(),
        bounds: dem.bounds.clone(),
        may_leave: dem.may_leave.clone(),
        state: dem.state.clone(),
        nlist: dem.nlist.keep(),
        timer: dem.timer.entries(),
    };
    let mut bytes = postcard::to_allocvec(&saved)
        .map_err(|e| refused(format!("cannot encode the grains: {e}")))?;
    let counts = (!dem.upkeep_unknown_before_resume).then_some(dem.nlist.upkeep);
    let upkeep = postcard::to_allocvec(&counts)
        .map_err(|e| refused(format!("cannot encode the list's upkeep counts: {e}")))?;
    bytes.extend(upkeep);
    // The conveyor's column follows as a trailer (checkpoints of runs without one, and
    // those written before it existed, end with the grains).
    if let Some(column) = &dem.conveyor {
        let trailer = postcard::to_allocvec(column)
            .map_err(|e| refused(format!("cannot encode the conveyor's column: {e}")))?;
        bytes.extend(trailer);
    }
    Ok(bytes)
}

/// Go on from `bytes` ([`save`]'s) in an engine built from the same scene.
pub(super) fn restore(dem: &mut NativeDem, bytes: &[u8]) -> Result<(), BackendError> {
    let column = restore_grains(dem, bytes)?;
    match (&dem.conveyor, column) {
        (Some(_), Some(c)) => dem.conveyor = Some(c),
        (None, None) => {}
        (Some(_), None) => {
            return Err(refused(
                "`inlet.mode`: the scene feeds through a conveyor, the checkpoint has no \
                 conveyor column (its run fed through the slab); start from it with `--from` \
                 instead of resuming"
                    .to_string(),
            ))
        }
        (None, Some(_)) => {
            return Err(refused(
                "`inlet.mode`: the checkpoint's run fed through a conveyor, the scene does not"
                    .to_string(),
            ))
        }
    }
    Ok(())
}

/// [`restore`] but for the conveyor's column, returned as read (None: the checkpoint has
/// none).
fn restore_grains(dem: &mut NativeDem, bytes: &[u8]) -> Result<Option<Conveyor>, BackendError> {
    let (s, rest): (Saved, &[u8]) = postcard::take_from_bytes(bytes)
        .map_err(|e| refused(format!("the engine's part cannot be read: {e}")))?;
    if !(OLDEST_READ..=FORMAT).contains(&s.format) {
        return Err(refused(format!(
            "written in the engine's format {}, this build reads formats {OLDEST_READ} to \
             {FORMAT}",
            s.format
        )));
    }
    let unreadable =
        |e: postcard::Error| refused(format!("the list's upkeep counts cannot be read: {e}"));
    let (upkeep, trailer) = match s.format {
        1 => (None, rest),
        2 => {
            let (_, t): (ListUpkeep, &[u8]) =
                postcard::take_from_bytes(rest).map_err(unreadable)?;
            (None, t)
        }
        _ => postcard::take_from_bytes::<Option<ListUpkeep>>(rest).map_err(unreadable)?,
    };
    let column = if trailer.is_empty() {
        None
    } else {
        Some(
            postcard::from_bytes::<Conveyor>(trailer)
                .map_err(|e| refused(format!("the conveyor's column cannot be read: {e}")))?,
        )
    };
    let nw = dem.cfg.walls.len();
    if s.walls != nw || s.wall_force.len() != nw {
        return Err(refused(format!(
            "written for {} walls, the scene has {nw}",
            s.walls
        )));
    }
    let n = s.state.id.len();
    let st = &s.state;
    let columns = [
        st.position.len(),
        st.velocity.len(),
        st.angular_velocity.len(),
        st.force.len(),
        st.torque.len(),
        st.external_force.len(),
        st.radius.len(),
        st.mass.len(),
        st.inv_mass.len(),
        st.inv_inertia.len(),
    ];
    if columns.iter().any(|&c| c != n) || st.wall_history.len() != n * nw {
        return Err(refused(format!(
            "the grain columns do not all hold {n} grains"
        )));
    }
    dem.nlist.restore(s.nlist, n).map_err(refused)?;
    dem.nlist.upkeep = upkeep.unwrap_or_default();
    dem.upkeep_unknown_before_resume = upkeep.is_none();
    if s.may_leave.iter().any(|&i| i as usize >= n) || s.bounds.last().is_some_and(|&b| b > n) {
        return Err(refused(
            "a grain index lies past the last grain".to_string(),
        ));
    }
    dem.time = s.time;
    dem.step = s.step;
    dem.next_id = s.next_id;
    dem.rng = s.rng;
    dem.rebuild_pending = s.rebuild_pending;
    dem.feeder = s.feeder;
    dem.flow = s.flow;
    dem.wall_force = s.wall_force;
    if s.mixed_grains {
        dem.uniform = None;
    }
    dem.may_leave = s.may_leave;
    dem.state = s.state;
    // Scratch the integration pass writes before any read, sized as a build sizes it.
    dem.velocity_pred = vec![[0.0; 3]; n];
    dem.angular_velocity_pred = vec![[0.0; 3]; n];
    dem.timer = StageTimer::from_entries(&s.timer);
    // The threads' chunks: as saved for the same thread count (bit for bit); cut again
    // by the list's costs for another (the same physics, another summation order).
    let cost = dem.nlist.cost.len();
    if s.threads == dem.cfg.threads {
        dem.bounds = s.bounds;
    } else if cost == n && n > 0 {
        let chunks = dem.cfg.threads.min((n / MIN_GRAINS_PER_CHUNK).max(1));
        if chunks > 1 {
            cut_by_cost(&dem.nlist.cost, chunks, &mut dem.bounds);
        } else {
            dem.bounds = vec![0, n];
        }
    } else {
        dem.bounds.clear();
        dem.rebuild_pending = true;
    }
    Ok(column)
}

/// Start from another run's grains ([`save`]'s bytes) at time zero with this engine's own
/// settings: refused when a grain's size or density is not the scene's (their masses were
/// computed for another material), naming the field.
pub(super) fn start_from(dem: &mut NativeDem, bytes: &[u8]) -> Result<(), BackendError> {
    // A conveyor of the other run is not this one's: the column starts afresh below the
    // grains (those in the slab join it at the first feed).
    let theirs = restore_grains(dem, bytes)?;
    if let Some(column) = theirs {
        // Its held grains go free, as they would have on leaving its slab.
        for i in 0..dem.state.len() {
            if column.holds(dem.state.id[i]) {
                dem.state.release(i);
            }
        }
    }
    let cfg = &dem.cfg;
    let s = &dem.state;
    let (lo, hi) = (cfg.radius_min, cfg.radius_max);
    if let Some(i) = (0..s.len()).find(|&i| {
        let r = s.radius[i];
        r < lo * (1.0 - 1e-12) || r > hi * (1.0 + 1e-12)
    }) {
        return Err(refused(format!(
            "`particles.diameter`: grain {} has d = {} m, outside the scene's [{}, {}] m",
            s.id[i],
            2.0 * s.radius[i],
            2.0 * lo,
            2.0 * hi
        )));
    }
    if let Some(i) = (0..s.len()).find(|&i| {
        let m = cfg.density * 4.0 / 3.0 * std::f64::consts::PI * s.radius[i].powi(3);
        (s.mass[i] - m).abs() > 1e-12 * m
    }) {
        return Err(refused(format!(
            "`particles.density`: grain {} was made of another density than the scene's {} \
             kg/m^3",
            s.id[i], cfg.density
        )));
    }
    dem.time = 0.0;
    dem.step = 0;
    // The new run's randomness is its own scene's seed (variants of a sweep from one
    // filled tube over `seed` differ as runs should).
    dem.rng = Rng::new(dem.cfg.seed);
    dem.flow = FlowCounters::default();
    dem.feeder = Feeder::default();
    if dem.conveyor.is_some() {
        let column = Conveyor::primed(&dem.cfg, &mut dem.rng)
            .map_err(|why| refused(format!("`inlet.porosity`: {why}")))?;
        dem.conveyor = Some(column);
    }
    dem.timer = StageTimer::new();
    // The list's counts are this run's (its first build below is one of them).
    dem.nlist.builds = 0;
    dem.nlist.upkeep = ListUpkeep::default();
    dem.upkeep_unknown_before_resume = false;
    // The skin may be the scene's own: the list is built again at the first step (the
    // shear histories carry over through the rebuild, as at every build).
    dem.rebuild_pending = true;
    Ok(())
}
