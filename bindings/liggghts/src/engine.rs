//! One LIGGGHTS instance driven through its library interface (via the C++ layer of
//! shim.cpp, which stops exceptions), with plugflow's bookkeeping around it.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::PathBuf;
use std::sync::Mutex;

use plugflow_coupling::abi::PfDemFlow;
use plugflow_coupling::{
    BackendError, DemBackend, GrainFlow, ImplicitDrag, NewParticle, ParticleView, Ranks, Reduce,
    WallForce,
};
use plugflow_model::dem::config::InletMode;
use plugflow_model::dem::conveyor::Conveyor;
use plugflow_model::dem::inlet::Feeder;
use plugflow_model::dem::{DemConfig, NativeDem};
use plugflow_model::rng::Rng;
use plugflow_model::scene::Scene;

use crate::input::{map, map_user, Mapped, Outlet, HELD_GROUP, INSERT_FIX};

extern "C" {
    fn pfl_open(
        log: *const c_char,
        screen: *const c_char,
        out: *mut *mut c_void,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
    fn pfl_close(lmp: *mut c_void, err: *mut c_char, len: usize) -> c_int;
    fn pfl_world(rank: *mut c_int, size: *mut c_int, err: *mut c_char, len: usize) -> c_int;
    fn pfl_open_world(
        log: *const c_char,
        screen: *const c_char,
        out: *mut *mut c_void,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
    fn pfl_all_reduce(data: *mut f64, n: usize, op: c_int, err: *mut c_char, len: usize) -> c_int;
    fn pfl_finalize(err: *mut c_char, len: usize) -> c_int;
    fn pfl_command(lmp: *mut c_void, cmd: *const c_char, err: *mut c_char, len: usize) -> c_int;
    fn pfl_extract_atom(
        lmp: *mut c_void,
        name: *const c_char,
        out: *mut *mut c_void,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
    fn pfl_extract_global(
        lmp: *mut c_void,
        name: *const c_char,
        out: *mut *mut c_void,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
    fn pfl_group_bit(
        lmp: *mut c_void,
        name: *const c_char,
        out: *mut c_int,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
    fn pfl_extract_fix(
        lmp: *mut c_void,
        id: *const c_char,
        kind: c_int,
        out: *mut *mut c_void,
        err: *mut c_char,
        len: usize,
    ) -> c_int;
}

/// Most steps between two feeds of the conveyor's column (as the YADE engine's stride; the
/// column moves 4 µm in 50 steps of the seeds' case).
const CONVEYOR_STRIDE: u64 = 50;

/// LIGGGHTS instances share MPI's process-wide state: open and close one at a time.
static OPEN_CLOSE: Mutex<()> = Mutex::new(());

/// An error of a LIGGGHTS call.
pub type EngineError = String;

/// A LIGGGHTS instance with the scene mapped into it.
pub struct Liggghts {
    lmp: *mut c_void,
    /// The ranks LIGGGHTS runs on (one process unless launched by `mpirun`).
    ranks: Ranks,
    /// Over MPI_COMM_WORLD (launched by `mpirun`, any rank count, 1 included).
    world: bool,
    pub mapped: Mapped,
    pub cfg: DemConfig,
    pub time: f64,
    pub steps: u64,
    /// The next run must set up again (atoms were added or deleted).
    needs_setup: bool,
    /// LIGGGHTS inserts grains itself (the scene's inlet, or the user's input).
    feeds: bool,
    /// The scene's feed has stopped (`inlet.until` passed).
    feed_stopped: bool,
    pub version: String,
    workdir: PathBuf,
    /// Where the engine's log files go when it closes (`DemBackend::keep_log`).
    keep_log: Option<PathBuf>,
    /// The scene runs a user's own input (`dem.liggghts_input`).
    user_input_given: bool,
    pub flow: PfDemFlow,
    /// The conveyor inlet's column (`inlet.mode = "conveyor"`, one process): plugflow
    /// creates its grains and holds those in the slab in [`HELD_GROUP`] (`fix freeze`).
    conveyor: Option<Conveyor>,
    /// The column's random numbers (its packing), seeded as the built-in engine's.
    rng: Rng,
    /// Grains created through pf_dem_insert (not counted as fed).
    inserted: std::collections::HashSet<u64>,
    /// Every grain id seen so far, one bit per id (LIGGGHTS's tags are small integers
    /// counting up from 1): a look per grain and exchange costs a shift, not a hash.
    seen: Vec<u64>,
    /// Local snapshot refreshed after every change.
    pub ids: Vec<u64>,
    pub x: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    pub omega: Vec<[f64; 3]>,
    pub radius: Vec<f64>,
    pub mass: Vec<f64>,
}

fn call(f: impl FnOnce(*mut c_char, usize) -> c_int) -> Result<(), EngineError> {
    let mut buf = vec![0 as c_char; 512];
    if f(buf.as_mut_ptr(), buf.len()) == 0 {
        Ok(())
    } else {
        // SAFETY: the shim NUL-terminates within the buffer.
        Err(unsafe { CStr::from_ptr(buf.as_ptr()) }
            .to_string_lossy()
            .into_owned())
    }
}

impl Liggghts {
    /// Check and map the scene, start LIGGGHTS, feed it the input, insert the scene's
    /// initial grains (placed by plugflow, so both engines start from the same bed).
    pub fn new(scene: &Scene) -> Result<Self, EngineError> {
        let cfg = plugflow_model::dem_config(scene).map_err(|e| e.to_string())?;
        let user_input = scene.file.dem.liggghts_input.clone();
        let mapped = match &user_input {
            Some(path) => map_user(&cfg, path).map_err(|e| e.to_string())?,
            None => map(scene, &cfg).map_err(|e| e.to_string())?,
        };
        // The initial fill exactly as the built-in engine places it.
        let initial = if cfg.initial.is_some() {
            let mut native_cfg = cfg.clone();
            native_cfg.inlet = None;
            let n = NativeDem::new(native_cfg).map_err(|e| e.to_string())?;
            let p = n.particles();
            Some((p.position.to_vec(), p.velocity.to_vec()))
        } else {
            None
        };
        let workdir = std::env::temp_dir().join(format!(
            "plugflow-liggghts-{}-{:p}",
            std::process::id(),
            &cfg as *const _
        ));
        std::fs::create_dir_all(&workdir).map_err(|e| format!("{}: {e}", workdir.display()))?;
        if user_input.is_some() {
            // A user's input is not ours to vouch for, and LIGGGHTS ends the process on any
            // input error: try it first in a child process and report its error instead.
            if let Err(e) = preflight(&workdir, &mapped.commands) {
                let _ = std::fs::remove_dir_all(&workdir);
                return Err(format!("field `dem.liggghts_input`: {e}"));
            }
        }
        // Started by an MPI launcher (`mpirun`, any rank count, 1 included): LIGGGHTS runs
        // over MPI_COMM_WORLD, one instance across all ranks, each owning the grains of
        // its subdomain.
        let world = plugflow_coupling::ranks::launcher().is_some();
        let (lmp, ranks) = Self::open(&workdir, world)?;
        live_files(|live| {
            live.push(LiveFiles {
                workdir: workdir.clone(),
                keep: None,
                rank: ranks.rank,
                alone: ranks.size == 1,
            })
        });
        let mut me = Self {
            lmp,
            ranks,
            world,
            mapped,
            cfg,
            time: 0.0,
            steps: 0,
            needs_setup: true,
            feeds: false,
            feed_stopped: false,
            version: String::new(),
            workdir,
            keep_log: None,
            user_input_given: user_input.is_some(),
            flow: PfDemFlow::default(),
            conveyor: None,
            rng: Rng::new(0),
            inserted: Default::default(),
            seen: Vec::new(),
            ids: Vec::new(),
            x: Vec::new(),
            v: Vec::new(),
            omega: Vec::new(),
            radius: Vec::new(),
            mass: Vec::new(),
        };
        me.feeds = me.lammps_feeds();
        me.rng = Rng::new(me.cfg.seed);
        if me.conveys() {
            if me.ranks.size > 1 {
                return Err(format!(
                    "inlet.mode: the conveyor inlet on LIGGGHTS runs on one process (its \
                     column is fed from every grain near the inlet, which under MPI lie on \
                     several ranks); this run has {} ranks: use inlet.mode = \"slab\" or \
                     one process",
                    me.ranks.size
                ));
            }
            let column =
                Conveyor::primed(&me.cfg, &mut me.rng).map_err(|e| format!("inlet.mode: {e}"))?;
            me.conveyor = Some(column);
        }
        me.start(Start::Fresh(initial))?;
        Ok(me)
    }

    /// Feed the mapped input to the open instance and set it up: a new bed (the scene's
    /// initial grains inserted), or the grains of a restart file in place of `create_box`.
    fn start(&mut self, how: Start) -> Result<(), EngineError> {
        let how_restarted = matches!(how, Start::Restart(_));
        for c in self.mapped.commands.clone() {
            match (&how, c.as_str()) {
                (Start::Restart(path), CREATE_BOX) => {
                    self.command(&format!("read_restart {}", path.display()))?
                }
                _ => self.command(&c)?,
            }
        }
        if let Start::Fresh(Some((x, v))) = how {
            let r = vec![self.mapped.grain_radius; x.len()];
            let rho = vec![self.mapped.grain_density; x.len()];
            self.insert(&x, &v, &r, &rho)?;
        }
        self.refresh()?;
        // The banner LIGGGHTS printed on opening: switching to a second log file closes
        // (and so flushes) the first.
        // (A restored instance goes on with the same file: what it said while reading the
        // restart file, e.g. which fixes took their state back, stays in it.)
        let log2 = self.workdir.join("log2.liggghts").display().to_string();
        match how_restarted {
            true => self.command(&format!("log {log2} append"))?,
            false => self.command(&format!("log {log2}"))?,
        }
        self.version = ["log.liggghts"]
            .iter()
            .filter_map(|f| std::fs::read_to_string(self.workdir.join(f)).ok())
            .find_map(|s| {
                s.lines()
                    .find_map(|l| l.strip_prefix("LIGGGHTS (Version "))
                    .map(|l| l.split(',').next().unwrap_or(l).trim().to_string())
            })
            .unwrap_or_else(|| "unknown version (no banner in LIGGGHTS's output)".into());
        // LIGGGHTS refuses to set up a granular run before it knows a grain type: with
        // no grains and no inlet, setup waits for the first inserted grain.
        if self.global_count()? > 0 || self.feeds {
            self.command("run 0")?;
            self.needs_setup = false;
        }
        Ok(())
    }

    /// Open a LIGGGHTS instance writing its log and screen output into the working folder:
    /// in this process alone, or over MPI_COMM_WORLD (`world`).
    fn open(workdir: &std::path::Path, world: bool) -> Result<(*mut c_void, Ranks), EngineError> {
        let log = CString::new(workdir.join("log.liggghts").display().to_string())
            .map_err(|e| e.to_string())?;
        let screen = CString::new(workdir.join("screen.liggghts").display().to_string())
            .map_err(|e| e.to_string())?;
        let mut lmp = std::ptr::null_mut();
        let _g = OPEN_CLOSE.lock().unwrap_or_else(|p| p.into_inner());
        if !world {
            // SAFETY: valid C strings and out-pointer.
            call(|e, l| unsafe { pfl_open(log.as_ptr(), screen.as_ptr(), &mut lmp, e, l) })?;
            return Ok((lmp, Ranks::SINGLE));
        }
        let (mut rank, mut size) = (0 as c_int, 0 as c_int);
        // SAFETY: valid out-pointers.
        call(|e, l| unsafe { pfl_world(&mut rank, &mut size, e, l) })?;
        // SAFETY: valid C strings and out-pointer; every rank opens together.
        call(|e, l| unsafe { pfl_open_world(log.as_ptr(), screen.as_ptr(), &mut lmp, e, l) })?;
        Ok((
            lmp,
            Ranks {
                rank: rank as usize,
                size: size as usize,
            },
        ))
    }

    /// `data` summed (or its maximum taken) over the ranks; nothing to do on one.
    pub fn reduce(&self, data: &mut [f64], op: Reduce) -> Result<(), EngineError> {
        if !self.world || data.is_empty() {
            return Ok(());
        }
        let op = match op {
            Reduce::Sum => 0,
            Reduce::Max => 1,
        };
        // SAFETY: the pointer and length describe `data`; every rank calls together.
        call(|e, l| unsafe { pfl_all_reduce(data.as_mut_ptr(), data.len(), op, e, l) })
    }

    /// Grains over all ranks.
    fn global_count(&self) -> Result<usize, EngineError> {
        let mut n = [self.ids.len() as f64];
        self.reduce(&mut n, Reduce::Sum)?;
        Ok(n[0] as usize)
    }

    /// The largest grain id over all ranks (0 with none).
    fn global_max_id(&self) -> Result<u64, EngineError> {
        let mut m = [self.ids.iter().copied().max().unwrap_or(0) as f64];
        self.reduce(&mut m, Reduce::Max)?;
        Ok(m[0] as u64)
    }

    /// Every rank's `local` ids, on every rank.
    fn gather_ids(&self, local: &[u64]) -> Result<Vec<u64>, EngineError> {
        plugflow_coupling::ranks::all_gather_u64(self, local).map_err(|e| e.to_string())
    }

    /// Under MPI a failure on one rank is every rank's (the healthy ones would wait in the
    /// next collective call for ever): the first failing rank's words, on all.
    fn agreed<T>(&self, local: Result<T, EngineError>) -> Result<T, EngineError> {
        let words = local.as_ref().err().cloned();
        match plugflow_coupling::ranks::first_failure(self, words.as_deref()) {
            Ok(Some((rank, message))) if local.is_ok() => Err(format!("rank {rank}: {message}")),
            Ok(_) => local,
            Err(e) => Err(e.to_string()),
        }
    }

    /// Close the instance (once: the handle is nulled).
    fn close(&mut self) {
        if self.lmp.is_null() {
            return;
        }
        let _g = OPEN_CLOSE.lock().unwrap_or_else(|p| p.into_inner());
        // SAFETY: a live instance, closed once.
        let _ = call(|e, l| unsafe { pfl_close(self.lmp, e, l) });
        self.lmp = std::ptr::null_mut();
        if self.world {
            // One instance per process under a launcher: MPI ends with it (a process
            // that exits without MPI_Finalize makes mpirun report the job as failed).
            // SAFETY: every rank closes together.
            let _ = call(|e, l| unsafe { pfl_finalize(e, l) });
        }
    }

    /// The state between two advances (see [`SavedState`]): LIGGGHTS's own restart file
    /// (grains, contact and wall histories in the per-atom data of their fixes, the
    /// insertion fix's counters, the fluid force of the last exchange in `pf_extf`) and
    /// plugflow's mirrors of it.
    ///
    /// Under MPI every rank calls it (`write_restart` is collective): LIGGGHTS's rank 0
    /// gathers every rank's grains and histories into one file at rank 0's path, and rank 0
    /// alone writes the run's checkpoint, so the other ranks hand back their mirrors without
    /// the file. The mirrors are the same on every rank there (the ids inserted and the feed
    /// and outflow counters are kept over all ranks). The grains seen under MPI are every tag
    /// up to the largest (see [`Liggghts::count_fed_over_ranks`]): written out as such, so
    /// that the run resumes on one process (or any rank count) counting the feed alike.
    pub fn save(&mut self) -> Result<Vec<u8>, EngineError> {
        self.refuse_user_input()?;
        let path = self.workdir.join("checkpoint.restart");
        self.command(&format!("write_restart {}", path.display()))?;
        let read = match self.ranks.leads() {
            true => std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display())),
            false => Ok(Vec::new()),
        };
        let restart = self.agreed(read)?;
        let _ = std::fs::remove_file(&path);
        if self.world {
            for id in 1..=self.global_max_id()? {
                self.first_sight(id);
            }
        }
        Ok(SavedState {
            steps: self.steps,
            flow: self.flow,
            inserted: {
                let mut v: Vec<u64> = self.inserted.iter().copied().collect();
                v.sort_unstable();
                v
            },
            seen: self.seen.clone(),
            restart,
            column: match &self.conveyor {
                Some(c) => postcard::to_allocvec(c)
                    .map_err(|e| format!("cannot encode the conveyor's column: {e}"))?,
                None => Vec::new(),
            },
        }
        .encode())
    }

    /// Go on from a state [`Liggghts::save`] wrote: this instance is closed and a new one
    /// reads the restart file in place of `create_box`; the scene's other commands (laws,
    /// walls, the inlet's fixes under the same ids, so LIGGGHTS hands them their restart
    /// data) follow as in a new run.
    ///
    /// Under MPI every rank reads the checkpoint rank 0 wrote and calls it: `read_restart`
    /// is collective (LIGGGHTS's rank 0 reads the file and hands each rank its grains), and
    /// the mirrors are the same on every rank.
    pub fn restore(&mut self, bytes: &[u8]) -> Result<(), EngineError> {
        self.refuse_user_input()?;
        let st = self.agreed(SavedState::decode(bytes))?;
        let path = self.workdir.join("resume.restart");
        std::fs::write(&path, &st.restart).map_err(|e| format!("{}: {e}", path.display()))?;
        // `clear` empties the instance (atoms, fixes, settings) but keeps it and its log:
        // a second instance in this process would register LIGGGHTS's styles again and
        // warn about each on stderr.
        self.command("clear")?;
        self.steps = st.steps;
        self.time = st.steps as f64 * self.cfg.dt;
        self.flow = st.flow;
        self.inserted = st.inserted.into_iter().collect();
        self.seen = st.seen;
        self.needs_setup = true;
        // The input makes the insertion fix again: a feed already stopped stops again at
        // the next advance.
        self.feeds = self.lammps_feeds();
        self.feed_stopped = false;
        match (self.conveys(), st.column.is_empty()) {
            (true, false) => {
                self.conveyor = Some(
                    postcard::from_bytes(&st.column)
                        .map_err(|e| format!("the conveyor's column cannot be read: {e}"))?,
                )
            }
            (true, true) => {
                return Err(
                    "`inlet.mode`: the scene feeds through a conveyor, the checkpoint \
                            has no conveyor column (its run fed through the slab)"
                        .into(),
                )
            }
            (false, false) => {
                return Err(
                    "`inlet.mode`: the checkpoint's run fed through a conveyor, the \
                            scene does not"
                        .into(),
                )
            }
            (false, true) => {}
        }
        let started = self.start(Start::Restart(path.clone()));
        let _ = std::fs::remove_file(&path);
        started?;
        // The restart file brings the masks back; set them from the column all the same,
        // which is what the run goes by.
        if let Some(column) = self.conveyor.take() {
            let marked = self.mark_held(&column);
            self.conveyor = Some(column);
            marked?;
        }
        Ok(())
    }

    /// A user's own input builds its box and grains with its own commands (and may read
    /// its own restart files): plugflow cannot put a restart file in their place.
    fn refuse_user_input(&self) -> Result<(), EngineError> {
        if self.user_input_given {
            return Err(
                "field `output.checkpoint_interval`: checkpoints of a user's own \
                        LIGGGHTS input (`dem.liggghts_input`) are not supported; use LIGGGHTS's \
                        own `write_restart` in the input, or the scene's mapping"
                    .into(),
            );
        }
        Ok(())
    }

    /// One input line.
    pub fn command(&mut self, cmd: &str) -> Result<(), EngineError> {
        let c = CString::new(cmd).map_err(|e| e.to_string())?;
        // SAFETY: live instance, valid C string.
        call(|e, l| unsafe { pfl_command(self.lmp, c.as_ptr(), e, l) })
            .map_err(|m| format!("`{cmd}`: {m}"))
    }

    fn atom_ptr(&self, name: &str) -> Result<*mut c_void, EngineError> {
        let c = CString::new(name).expect("static name");
        let mut out = std::ptr::null_mut();
        // SAFETY: live instance.
        call(|e, l| unsafe { pfl_extract_atom(self.lmp, c.as_ptr(), &mut out, e, l) })?;
        if out.is_null() {
            return Err(format!("LIGGGHTS has no per-atom `{name}`"));
        }
        Ok(out)
    }

    fn nlocal(&self) -> Result<usize, EngineError> {
        let c = CString::new("nlocal").expect("static name");
        let mut out = std::ptr::null_mut();
        // SAFETY: live instance.
        call(|e, l| unsafe { pfl_extract_global(self.lmp, c.as_ptr(), &mut out, e, l) })?;
        if out.is_null() {
            return Err("LIGGGHTS has no `nlocal`".into());
        }
        // SAFETY: nlocal is an int.
        Ok(unsafe { *(out as *const c_int) } as usize)
    }

    fn fix_array(&self, id: &str) -> Result<*mut *mut f64, EngineError> {
        let c = CString::new(id).expect("fix ids are ours");
        let mut out = std::ptr::null_mut();
        // SAFETY: live instance; per-atom array (type 2).
        call(|e, l| unsafe { pfl_extract_fix(self.lmp, c.as_ptr(), 2, &mut out, e, l) })?;
        if out.is_null() {
            return Err(format!("LIGGGHTS has no per-atom array of fix `{id}`"));
        }
        Ok(out as *mut *mut f64)
    }

    /// Mark `id` seen; whether it was new.
    fn first_sight(&mut self, id: u64) -> bool {
        let (word, bit) = ((id / 64) as usize, 1u64 << (id % 64));
        if word >= self.seen.len() {
            self.seen.resize(word + 1, 0);
        }
        let new = self.seen[word] & bit == 0;
        self.seen[word] |= bit;
        new
    }

    /// Re-read every local atom; returns how many were seen for the first time.
    pub fn refresh(&mut self) -> Result<usize, EngineError> {
        let n = self.nlocal()?;
        if n == 0 {
            // LIGGGHTS allocates its per-atom arrays with the first atom.
            self.ids.clear();
            self.x.clear();
            self.v.clear();
            self.omega.clear();
            self.radius.clear();
            self.mass.clear();
            // (Under MPI the counting below is collective: a rank without grains joins.)
            return match self.world {
                true => self.count_fed_over_ranks(),
                false => Ok(0),
            };
        }
        let tag = self.atom_ptr("id")? as *const c_int;
        let x = self.atom_ptr("x")? as *const *const f64;
        let v = self.atom_ptr("v")? as *const *const f64;
        let w = self.atom_ptr("omega")? as *const *const f64;
        let r = self.atom_ptr("radius")? as *const f64;
        let m = self.atom_ptr("rmass")? as *const f64;
        // SAFETY: LIGGGHTS's per-atom arrays hold nlocal atoms (3 doubles per row).
        unsafe {
            let row = |p: *const *const f64, i: usize| {
                let q = *p.add(i);
                [*q, *q.add(1), *q.add(2)]
            };
            // Into the buffers of the last read (no allocation once they are large enough).
            self.ids.clear();
            self.ids.extend((0..n).map(|i| *tag.add(i) as u64));
            self.x.clear();
            self.x.extend((0..n).map(|i| row(x, i)));
            self.v.clear();
            self.v.extend((0..n).map(|i| row(v, i)));
            self.omega.clear();
            self.omega.extend((0..n).map(|i| row(w, i)));
            self.radius.clear();
            self.radius.extend((0..n).map(|i| *r.add(i)));
            self.mass.clear();
            self.mass.extend((0..n).map(|i| *m.add(i)));
        }
        if self.world {
            return self.count_fed_over_ranks();
        }
        let mut new = 0;
        for k in 0..self.ids.len() {
            let id = self.ids[k];
            if self.first_sight(id) {
                new += 1;
                if !self.inserted.contains(&id) {
                    self.flow.fed_count += 1;
                }
            }
        }
        let fed = self.flow.fed_count;
        self.flow.fed_mass = fed as f64 * self.mapped.grain_mass;
        Ok(new)
    }

    /// The grains fed so far over all ranks (under MPI); returns how many are new. Tags
    /// count up from 1 without gaps (LIGGGHTS gives new atoms the tags past the largest):
    /// the grains ever seen are the largest tag over all ranks, and a grain that moved to
    /// another rank is not seen twice.
    fn count_fed_over_ranks(&mut self) -> Result<usize, EngineError> {
        let before = self.flow.fed_count + self.inserted.len() as u64;
        let seen = self.global_max_id()?.max(before);
        self.flow.fed_count = seen - self.inserted.len() as u64;
        self.flow.fed_mass = self.flow.fed_count as f64 * self.mapped.grain_mass;
        Ok((seen - before) as usize)
    }

    /// Advance `steps` steps; a feed that stops within them (`inlet.until`) stops at its
    /// step: the run is cut there and the insertion fix removed.
    pub fn advance(&mut self, steps: u64) -> Result<(), EngineError> {
        if let Some(stop) = self.feed_stop_step().filter(|&s| s < self.steps + steps) {
            let before = stop.saturating_sub(self.steps);
            self.advance_fed(before)?;
            self.stop_feed()?;
            return self.advance_fed(steps - before);
        }
        self.advance_fed(steps)
    }

    /// The scene feeds through the conveyor (plugflow's column, not an insertion fix).
    fn conveys(&self) -> bool {
        self.cfg
            .inlet
            .is_some_and(|i| i.mode == InletMode::Conveyor)
    }

    /// LIGGGHTS inserts grains itself: the slab inlet's insertion fix or a user's input.
    fn lammps_feeds(&self) -> bool {
        (self.cfg.inlet.is_some() && !self.conveys()) || self.user_input_given
    }

    /// The conveyor's part of a feed, `elapsed` s after the last (see [`Conveyor::feed`]):
    /// grains to hold get the feed velocity and no spin, the column's new grains are
    /// created at it and counted as fed, and [`HELD_GROUP`]'s mask bit marks the held ones
    /// again (see [`Liggghts::mark_held`]).
    fn convey(&mut self, elapsed: f64) -> Result<(), EngineError> {
        let Some(mut column) = self.conveyor.take() else {
            return Ok(());
        };
        let done = self.convey_column(&mut column, elapsed);
        self.conveyor = Some(column);
        done
    }

    fn convey_column(&mut self, column: &mut Conveyor, elapsed: f64) -> Result<(), EngineError> {
        let feed = column.feed(
            &self.cfg,
            self.time,
            elapsed,
            &self.ids,
            &self.x,
            &self.radius,
            |_| true,
            &mut self.rng,
        );
        let v = Feeder::velocity(&self.cfg);
        if !feed.hold.is_empty() {
            let vel = self.atom_ptr("v")? as *const *mut f64;
            let spin = self.atom_ptr("omega")? as *const *mut f64;
            // SAFETY: per-atom arrays of nlocal rows of 3; the indices are of the last
            // refresh, and nothing changed the atoms since.
            unsafe {
                for &i in &feed.hold {
                    let (a, b) = (*vel.add(i), *spin.add(i));
                    for (k, vk) in v.iter().enumerate() {
                        *a.add(k) = *vk;
                        *b.add(k) = 0.0;
                    }
                }
            }
        }
        let changed = !feed.hold.is_empty() || !feed.release.is_empty() || !feed.enter.is_empty();
        if !feed.enter.is_empty() {
            let n = feed.enter.len();
            let x: Vec<[f64; 3]> = feed.enter.iter().map(|e| e.0).collect();
            let r: Vec<f64> = feed.enter.iter().map(|e| e.1).collect();
            let ids = self.insert(&x, &vec![v; n], &r, &vec![self.mapped.grain_density; n])?;
            // Fed, not inserted: the feed counters take them.
            for id in ids {
                self.inserted.remove(&id);
                column.hold(id);
            }
            self.flow.fed_count += n as u64;
            self.flow.fed_mass = self.flow.fed_count as f64 * self.mapped.grain_mass;
        }
        if changed {
            self.mark_held(column)?;
        }
        Ok(())
    }

    /// Put exactly the column's held grains in [`HELD_GROUP`] by their bit in LIGGGHTS's
    /// per-atom `mask`: `fix freeze` reads the mask every step, so membership changes
    /// need no `group` command and no new set-up (LIGGGHTS 3.8's `group` cannot empty a
    /// group, and remaking one under its fix cost a set-up per release).
    fn mark_held(&mut self, column: &Conveyor) -> Result<(), EngineError> {
        let n = self.nlocal()?;
        if n == 0 {
            return Ok(());
        }
        let name = CString::new(HELD_GROUP).expect("static name");
        let mut bit: c_int = 0;
        // SAFETY: live instance, valid C string.
        call(|e, l| unsafe { pfl_group_bit(self.lmp, name.as_ptr(), &mut bit, e, l) })?;
        let mask = self.atom_ptr("mask")? as *mut c_int;
        let tag = self.atom_ptr("id")? as *const c_int;
        // SAFETY: per-atom arrays of nlocal ints.
        unsafe {
            for i in 0..n {
                let m = mask.add(i);
                if column.holds(*tag.add(i) as u64) {
                    *m |= bit;
                } else {
                    *m &= !bit;
                }
            }
        }
        Ok(())
    }

    /// The step at which the scene's feed stops, while it has not (None: it runs on).
    fn feed_stop_step(&self) -> Option<u64> {
        let until = self.mapped.feed_until?;
        (self.feeds && !self.feed_stopped).then(|| (until / self.cfg.dt).round() as u64)
    }

    /// Remove the insertion fix (the feeder valve closes).
    fn stop_feed(&mut self) -> Result<(), EngineError> {
        self.command(&format!("unfix {INSERT_FIX}"))?;
        self.feed_stopped = true;
        self.feeds = false;
        // (LIGGGHTS sets up again after a fix changes: the next run is not `pre no`.)
        self.needs_setup = true;
        Ok(())
    }

    fn advance_fed(&mut self, steps: u64) -> Result<(), EngineError> {
        if steps == 0 {
            return Ok(());
        }
        if self.global_count()? == 0 && !self.feeds {
            // Nothing to integrate and nothing will arrive: LIGGGHTS would refuse to run.
            self.steps += steps;
            self.time = self.steps as f64 * self.cfg.dt;
            return Ok(());
        }
        let before = self.global_count()?;
        let cmd = if self.needs_setup {
            format!("run {steps}")
        } else {
            format!("run {steps} pre no post no")
        };
        self.command(&cmd)?;
        self.needs_setup = false;
        self.steps += steps;
        self.time = self.steps as f64 * self.cfg.dt;
        let new = self.refresh()?;
        // Atoms LIGGGHTS dropped at the box edge within the run: nothing else removes atoms
        // during a run, and every atom it inserted is new.
        let after = self.global_count()?;
        self.flow.lost_count += (before + new).saturating_sub(after) as u64;
        let found = self.non_finite();
        self.agreed(found)
    }

    /// The first grain of this rank whose position or velocity is not finite.
    fn non_finite(&self) -> Result<(), EngineError> {
        if let Some(i) = self
            .x
            .iter()
            .zip(&self.v)
            .position(|(x, v)| x.iter().chain(v).any(|c| !c.is_finite()))
        {
            return Err(format!(
                "non-finite or blown-up state at step {}: particle id {}",
                self.steps, self.ids[i]
            ));
        }
        Ok(())
    }

    /// Set per-grain fluid forces (in the order of the last refresh). LIGGGHTS keeps them
    /// with their atoms (fix property/atom) until the next call; new grains start at zero.
    pub fn set_fluid(&mut self, f: &[[f64; 3]]) -> Result<(), EngineError> {
        let n = self.nlocal()?;
        if f.len() != n || n != self.ids.len() {
            return Err(format!("{} forces for {} grains", f.len(), n));
        }
        if n == 0 {
            return Ok(());
        }
        let a = self.fix_array("pf_extf")?;
        for (i, fi) in f.iter().enumerate() {
            // SAFETY: the fix's array holds nlocal rows of 3.
            unsafe {
                let row = *a.add(i);
                *row = fi[0];
                *row.add(1) = fi[1];
                *row.add(2) = fi[2];
            }
        }
        Ok(())
    }

    /// Create grains at the given places; returns their ids.
    pub fn insert(
        &mut self,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        r: &[f64],
        rho: &[f64],
    ) -> Result<Vec<u64>, EngineError> {
        let (lo, hi) = (self.cfg.box_lo, self.cfg.box_hi);
        for (i, p) in x.iter().enumerate() {
            if (0..3).any(|k| !(p[k] > lo[k] && p[k] < hi[k])) {
                return Err(format!("grain {i} at {p:?} lies outside the domain"));
            }
            if !(r[i] > 0.0 && rho[i] > 0.0) {
                return Err(format!("grain {i}: radius and density must be positive"));
            }
        }
        // LIGGGHTS gives new atoms the tags after the largest existing one, in order (over
        // all ranks: each rank creates the grains inside its subdomain).
        let first = self.global_max_id()?;
        for p in x {
            self.command(&format!(
                "create_atoms 1 single {:e} {:e} {:e} units box",
                p[0], p[1], p[2]
            ))?;
        }
        // Radius, density, mass and velocity straight into LIGGGHTS's arrays.
        let mut ids = Vec::with_capacity(x.len());
        let n = self.nlocal()?;
        // (Under MPI a rank may hold none of them, nor any grain: LIGGGHTS has no per-atom
        // arrays on it yet.)
        if n > 0 {
            let tag = self.atom_ptr("id")? as *const c_int;
            let rad = self.atom_ptr("radius")? as *mut f64;
            let dens = self.atom_ptr("density")? as *mut f64;
            let rm = self.atom_ptr("rmass")? as *mut f64;
            let vel = self.atom_ptr("v")? as *const *mut f64;
            // SAFETY: arrays of nlocal atoms.
            unsafe {
                let mut k = 0;
                for i in 0..n {
                    let t = *tag.add(i) as u64;
                    if t > first && k < x.len() {
                        let j = (t - first - 1) as usize;
                        let j = j.min(x.len() - 1);
                        *rad.add(i) = r[j];
                        *dens.add(i) = rho[j];
                        *rm.add(i) = rho[j] * 4.0 / 3.0 * std::f64::consts::PI * r[j].powi(3);
                        let row = *vel.add(i);
                        *row = v[j][0];
                        *row.add(1) = v[j][1];
                        *row.add(2) = v[j][2];
                        ids.push(t);
                        k += 1;
                    }
                }
            }
        }
        let mut created = [ids.len() as f64];
        self.reduce(&mut created, Reduce::Sum)?;
        if self.world {
            // The ids of the grains other ranks created, too: all of them, in order.
            ids = (first + 1..=first + created[0] as u64).collect();
        }
        if created[0] as usize != x.len() {
            return Err(format!(
                "LIGGGHTS created {} of {} grains",
                created[0],
                x.len()
            ));
        }
        ids.sort_unstable();
        self.inserted.extend(ids.iter().copied());
        self.needs_setup = true;
        self.refresh()?;
        Ok(ids)
    }

    /// Delete grains past the open ends; returns the mass that left through the outlet.
    pub fn remove_past_outlet(&mut self) -> Result<f64, EngineError> {
        let past = |o: &Option<Outlet>, x: &[f64; 3]| {
            o.is_some_and(|o| (x[o.axis] - o.position) * o.sign > 0.0)
        };
        // [outflow mass, outflow count, lost count] of this rank's grains.
        let mut counted = [0.0; 3];
        let mut gone: Vec<u64> = Vec::new();
        for i in 0..self.ids.len() {
            if past(&self.mapped.outlet, &self.x[i]) {
                counted[0] += self.mass[i];
                counted[1] += 1.0;
                gone.push(self.ids[i]);
            } else if past(&self.mapped.inlet_end_open, &self.x[i]) {
                counted[2] += 1.0;
                gone.push(self.ids[i]);
            }
        }
        // Under MPI every rank deletes the same group (all ranks' ids) and counts all.
        let gone = self.gather_ids(&gone)?;
        self.reduce(&mut counted, Reduce::Sum)?;
        if gone.is_empty() {
            return Ok(0.0);
        }
        // Ids in groups of at most a few hundred per command.
        for chunk in gone.chunks(200) {
            let list: Vec<String> = chunk.iter().map(|i| i.to_string()).collect();
            self.command(&format!("group pf_gone id {}", list.join(" ")))?;
        }
        self.command("delete_atoms group pf_gone compress no")?;
        self.command("group pf_gone delete")?;
        let out_mass = counted[0];
        self.flow.outflow_count += counted[1] as u64;
        self.flow.outflow_mass += out_mass;
        self.flow.lost_count += counted[2] as u64;
        self.needs_setup = true;
        self.refresh()?;
        Ok(out_mass)
    }

    /// Net force of the grains on each wall, N (from `store_force`).
    pub fn wall_forces(&self) -> Result<Vec<[f64; 3]>, EngineError> {
        let n = self.nlocal()?;
        if n == 0 {
            return Ok(vec![[0.0; 3]; self.mapped.walls.len()]);
        }
        let mut out = Vec::new();
        for (_, id) in &self.mapped.walls {
            let a = self.fix_array(&format!("force_{id}"))?;
            let mut s = [0.0; 3];
            for i in 0..n {
                // SAFETY: nlocal rows of 3.
                unsafe {
                    let row = *a.add(i);
                    s[0] -= *row;
                    s[1] -= *row.add(1);
                    s[2] -= *row.add(2);
                }
            }
            out.push(s);
        }
        Ok(out)
    }
}

/// Run the input with `run 0` in the `liggghts` executable, in a child process; its
/// `ERROR:` line when it fails.
fn preflight(dir: &std::path::Path, commands: &[String]) -> Result<(), String> {
    let input = dir.join("preflight.in");
    // (One process checks the input: a `processors` grid for the ranks of an MPI run
    // would be refused here; plugflow checks it against the rank count itself.)
    let one_process: Vec<&str> = commands
        .iter()
        .map(|c| c.as_str())
        .filter(|c| !c.trim_start().starts_with("processors"))
        .collect();
    let mut text = one_process.join("\n");
    text.push_str("\nrun 0\n");
    std::fs::write(&input, text).map_err(|e| format!("{}: {e}", input.display()))?;
    let screen = dir.join("preflight.screen");
    let run = || {
        let _ = std::fs::remove_file(&screen);
        let _ = std::fs::remove_file(dir.join("preflight.log"));
        let mut cmd = std::process::Command::new("liggghts");
        // An MPI already started in this process (a LIGGGHTS engine opened in it, e.g. by
        // another test's thread) leaves OpenMPI/PMIx variables in the environment; a child
        // that inherits them tries to join that singleton and dies without a word. The
        // child is a fresh singleton of its own.
        for (key, _) in std::env::vars_os() {
            let k = key.to_string_lossy();
            if ["OMPI_", "PMIX_", "OPAL_", "PRTE_"]
                .iter()
                .any(|p| k.starts_with(p))
            {
                cmd.env_remove(&key);
            }
        }
        cmd.arg("-in")
            .arg(&input)
            .arg("-log")
            .arg(dir.join("preflight.log"))
            .arg("-screen")
            .arg(&screen)
            .arg("-echo")
            .arg("none")
            .output()
            .map_err(|e| {
                format!(
                    "cannot start the `liggghts` executable to check the input in a child \
                     process ({e}); install it: bash scripts/setup-system.sh"
                )
            })
    };
    // A child that fails without a word (not even LIGGGHTS's banner) never read the input:
    // its launch failed (seen about once in eight under load, exit 1 and empty files, before
    // the MPI variables were cleared). Try it again, up to five times with growing pauses.
    let silent = |out: &std::process::Output| {
        !out.status.success()
            && out.stdout.is_empty()
            && out.stderr.is_empty()
            && std::fs::read_to_string(&screen)
                .unwrap_or_default()
                .trim()
                .is_empty()
    };
    let mut out = run()?;
    for k in 0..5 {
        if !silent(&out) {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(200 << k));
        out = run()?;
    }
    if out.status.success() {
        return Ok(());
    }
    // LIGGGHTS writes its ERROR line to the screen file, the log or its own output,
    // depending on where it failed: look in all of them.
    let said = [
        std::fs::read_to_string(&screen).unwrap_or_default(),
        std::fs::read_to_string(dir.join("preflight.log")).unwrap_or_default(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    ]
    .join("\n");
    let last: Vec<&str> = said.lines().filter(|l| !l.trim().is_empty()).collect();
    let tail = last[last.len().saturating_sub(3)..].join(" | ");
    let fallback = format!("LIGGGHTS stopped without an ERROR line; its last words: {tail}");
    let error = said
        .lines()
        .find(|l| l.contains("ERROR"))
        .unwrap_or(&fallback);
    Err(format!(
        "LIGGGHTS refuses the input (checked in a child process, exit {}): {}",
        out.status.code().unwrap_or(-1),
        error.trim()
    ))
}

impl Drop for Liggghts {
    fn drop(&mut self) {
        self.close();
        live_files(|live| live.retain(|l| l.workdir != self.workdir));
        keep_logs(&self.workdir, self.keep_log.as_deref(), self.ranks.rank);
    }
}

/// The run asked to keep LIGGGHTS's own logs: beside its other outputs (rank 0's: the
/// only rank LIGGGHTS writes a log on). Then the working folder goes.
fn keep_logs(workdir: &std::path::Path, keep: Option<&std::path::Path>, rank: usize) {
    if let Some(dir) = keep.filter(|_| rank == 0) {
        for f in ["log.liggghts", "log2.liggghts"] {
            let _ = std::fs::copy(workdir.join(f), dir.join(f));
        }
    }
    let _ = std::fs::remove_dir_all(workdir);
}

/// An instance alive in this process: its working folder, where its logs (and last words)
/// go, its rank.
struct LiveFiles {
    workdir: PathBuf,
    keep: Option<PathBuf>,
    rank: usize,
    /// On one rank (no mpirun, or `-np 1`): no other process to abort.
    alone: bool,
}

/// The instances alive in this process. LIGGGHTS's `error->all` (an input error met at run
/// time) prints `ERROR: …` and calls `exit(1)`, past every `Drop`: an `atexit` hook then
/// keeps the logs, the `ERROR` line with them, beside the run's outputs (the run's own
/// hook, registered before, reads them after) and removes the folders. Its `error->one`
/// calls `MPI_Abort`: see [`MPI_Abort`].
static LIVE: Mutex<Vec<LiveFiles>> = Mutex::new(Vec::new());

fn live_files(f: impl FnOnce(&mut Vec<LiveFiles>)) {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        // SAFETY: registers a plain extern "C" function (glibc runs it at exit, or when
        // this library is unloaded, by then with no instance left).
        unsafe {
            libc::atexit(keep_logs_on_exit);
        }
    });
    f(&mut LIVE.lock().unwrap_or_else(|p| p.into_inner()));
}

extern "C" fn keep_logs_on_exit() {
    // (Nothing may unwind out of an atexit hook; a lock held mid-update is skipped.)
    let _ = std::panic::catch_unwind(|| {
        if let Ok(live) = LIVE.try_lock() {
            for l in live.iter() {
                keep_logs(&l.workdir, l.keep.as_deref(), l.rank);
            }
        }
    });
}

extern "C" {
    /// MPI's profiling entry to the real `MPI_Finalize`.
    fn PMPI_Finalize() -> c_int;
}

/// LIGGGHTS's `error->one` (an error one rank meets alone, e.g. a per-grain variable
/// dividing by zero) prints `ERROR on proc N: …` into its screen file, unflushed, and calls
/// `MPI_Abort`, which kills every rank: the words would die with the buffer. This
/// definition comes before libmpi's for LIGGGHTS (this library is first in the scope it
/// and its dependencies were loaded in; MPI's profiling interface is made for this): it
/// flushes every stream, leaves the `ERROR` line as `last_words_rank<R>.txt` in the run's
/// folder (where the surviving ranks, ended by mpirun, read it for the summary) and on
/// stderr (which mpirun passes on), keeps the logs as a normal close does, then ends the
/// process with `exit` (on one rank after finalising, as `error->all` does), so that the
/// run's exit hook writes its summary; mpirun ends the other ranks on the non-zero exit. (`MPI_Comm` is a pointer in
/// Open MPI, Debian's MPI.)
///
/// # Safety
/// As `MPI_Abort`.
#[no_mangle]
pub unsafe extern "C" fn MPI_Abort(comm: *mut c_void, errorcode: c_int) -> c_int {
    libc::fflush(std::ptr::null_mut());
    let alone = std::panic::catch_unwind(|| {
        let Ok(live) = LIVE.try_lock() else {
            return false;
        };
        for l in live.iter() {
            let Ok(bytes) = std::fs::read(l.workdir.join("screen.liggghts")) else {
                continue;
            };
            let text = String::from_utf8_lossy(&bytes);
            let Some(words) = text.lines().rev().find(|x| x.starts_with("ERROR")) else {
                continue;
            };
            eprintln!("rank {}: {words}", l.rank);
            if let Some(dir) = &l.keep {
                let path = dir.join(format!("last_words_rank{}.txt", l.rank));
                let _ = std::fs::write(path, format!("rank {}: {}\n", l.rank, words.trim()));
            }
        }
        // The logs kept (rank 0's), the working folders gone, as at a normal close.
        for l in live.iter() {
            keep_logs(&l.workdir, l.keep.as_deref(), l.rank);
        }
        !live.is_empty() && live.iter().all(|l| l.alone)
    });
    if matches!(alone, Ok(true)) {
        // One process: end it as `error->all` does, so that its exit hooks (the run's
        // summary) run; an abort would skip them.
        PMPI_Finalize();
        libc::exit(errorcode);
    }
    // Several ranks: every rank may meet the error at once and abort, leaving no survivor
    // to write the summary. Exiting (without finalising, which would wait for the others)
    // runs this rank's exit hooks, rank 0's writing the summary; mpirun then ends the job
    // on the non-zero exit as it does on an abort. (`comm` unused: the whole job ends.)
    let _ = comm;
    libc::exit(if errorcode == 0 { 1 } else { errorcode })
}

/// The mapped input's `create_box` line, which a restart file takes the place of.
const CREATE_BOX: &str = "create_box 2 pf_box";

/// Grains placed by plugflow: positions and velocities.
type Placed = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// How [`Liggghts::start`] gets its grains.
enum Start {
    /// A new bed: the scene's initial grains, if any.
    Fresh(Option<Placed>),
    /// The grains of a LIGGGHTS restart file.
    Restart(PathBuf),
}

/// What a LIGGGHTS checkpoint holds: the restart file LIGGGHTS wrote and plugflow's side
/// of the engine (its step count, feed and outflow counters, which grains it inserted and
/// which it has seen, so the resumed run counts the feed as the straight one does).
/// Bytes: `MAGIC | steps u64 | flow (u64 f64 u64 f64 u64) | n u64, inserted ids u64 × n |
/// m u64, seen words u64 × m | k u64, restart file k bytes | the conveyor's column (postcard,
/// to the end; none without a conveyor)`, little-endian.
struct SavedState {
    steps: u64,
    flow: PfDemFlow,
    inserted: Vec<u64>,
    seen: Vec<u64>,
    restart: Vec<u8>,
    /// The conveyor's column (postcard, as the built-in engine's), empty without one.
    column: Vec<u8>,
}

impl SavedState {
    const MAGIC: &'static [u8; 8] = b"PFLGHTS1";

    fn encode(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.restart.len() + 8 * (self.seen.len() + 16));
        b.extend_from_slice(Self::MAGIC);
        let u = |v: u64, b: &mut Vec<u8>| b.extend_from_slice(&v.to_le_bytes());
        u(self.steps, &mut b);
        let f = &self.flow;
        u(f.fed_count, &mut b);
        u(f.fed_mass.to_bits(), &mut b);
        u(f.outflow_count, &mut b);
        u(f.outflow_mass.to_bits(), &mut b);
        u(f.lost_count, &mut b);
        for list in [&self.inserted, &self.seen] {
            u(list.len() as u64, &mut b);
            for &v in list {
                u(v, &mut b);
            }
        }
        u(self.restart.len() as u64, &mut b);
        b.extend_from_slice(&self.restart);
        b.extend_from_slice(&self.column);
        b
    }

    fn decode(bytes: &[u8]) -> Result<Self, EngineError> {
        let bad = |what: &str| format!("not a LIGGGHTS engine state: {what}");
        if bytes.len() < 8 || &bytes[..8] != Self::MAGIC {
            return Err(bad("no LIGGGHTS header (written by another engine?)"));
        }
        let mut at = 8;
        let mut u = || -> Result<u64, EngineError> {
            let w = bytes
                .get(at..at + 8)
                .ok_or_else(|| bad("cut short"))?
                .try_into()
                .expect("8 bytes");
            at += 8;
            Ok(u64::from_le_bytes(w))
        };
        let steps = u()?;
        let flow = PfDemFlow {
            fed_count: u()?,
            fed_mass: f64::from_bits(u()?),
            outflow_count: u()?,
            outflow_mass: f64::from_bits(u()?),
            lost_count: u()?,
        };
        let mut list = || -> Result<Vec<u64>, EngineError> {
            let n = u()? as usize;
            if n > bytes.len() / 8 {
                return Err(bad("a list longer than the state"));
            }
            (0..n).map(|_| u()).collect()
        };
        let inserted = list()?;
        let seen = list()?;
        let k = u()? as usize;
        let restart = at
            .checked_add(k)
            .and_then(|end| bytes.get(at..end))
            .ok_or_else(|| bad("the restart file is cut short"))?
            .to_vec();
        let column = bytes[at + k..].to_vec();
        Ok(Self {
            steps,
            flow,
            inserted,
            seen,
            restart,
            column,
        })
    }
}

/// LIGGGHTS's failures (a blow-up message names the step and the grain, see `advance`).
fn engine_error(message: EngineError) -> BackendError {
    BackendError::Engine {
        engine: "liggghts".into(),
        message,
    }
}

impl DemBackend for Liggghts {
    fn keep_log(&mut self, dir: &std::path::Path) -> Result<(), BackendError> {
        self.keep_log = Some(dir.to_path_buf());
        live_files(|live| {
            for l in live.iter_mut().filter(|l| l.workdir == self.workdir) {
                l.keep = Some(dir.to_path_buf());
            }
        });
        Ok(())
    }

    fn engine_name(&self) -> &str {
        "liggghts"
    }
    fn engine_version(&self) -> String {
        self.version.clone()
    }
    fn time_step(&self) -> f64 {
        self.cfg.dt
    }
    fn time(&self) -> f64 {
        self.time
    }
    fn step_count(&self) -> u64 {
        self.steps
    }
    /// With the conveyor, in strides of at most [`CONVEYOR_STRIDE`] steps, the column fed
    /// after each (the coupled run's exchanges are shorter than a stride).
    fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
        if self.conveyor.is_none() {
            return Liggghts::advance(self, steps).map_err(engine_error);
        }
        let mut left = steps;
        while left > 0 {
            let k = left.min(CONVEYOR_STRIDE);
            Liggghts::advance(self, k).map_err(engine_error)?;
            self.convey(k as f64 * self.cfg.dt).map_err(engine_error)?;
            left -= k;
        }
        Ok(())
    }
    fn particles(&self) -> ParticleView<'_> {
        ParticleView {
            id: &self.ids,
            position: &self.x,
            velocity: &self.v,
            angular_velocity: &self.omega,
            radius: &self.radius,
            mass: &self.mass,
        }
    }
    fn set_fluid_forces(
        &mut self,
        force: &[[f64; 3]],
        implicit: Option<ImplicitDrag<'_>>,
    ) -> Result<(), BackendError> {
        if implicit.is_some() {
            return Err(BackendError::InvalidArgument {
                argument: "implicit".into(),
                reason: "the LIGGGHTS shim takes the drag as an explicit force".into(),
            });
        }
        let local = match force.iter().position(|f| f.iter().any(|c| !c.is_finite())) {
            Some(i) => Err(BackendError::NonFinite {
                step: self.steps,
                particle_id: self.ids.get(i).copied().unwrap_or(0),
                what: format!("fluid force {:?}", force[i]),
            }),
            None => self
                .set_fluid(force)
                .map_err(|reason| BackendError::InvalidArgument {
                    argument: "force".into(),
                    reason,
                }),
        };
        // (Under MPI: another rank's refusal is this one's, so all stop together.)
        let words = local.as_ref().err().map(|e| e.to_string());
        match (self.agreed(words.map_or(Ok(()), Err)), local) {
            (Err(other), Ok(())) => Err(engine_error(other)),
            (_, local) => local,
        }
    }
    fn ranks(&self) -> Ranks {
        self.ranks
    }
    fn all_reduce(&self, data: &mut [f64], op: Reduce) -> Result<(), BackendError> {
        self.reduce(data, op).map_err(engine_error)
    }
    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        let x: Vec<[f64; 3]> = particles.iter().map(|p| p.position).collect();
        let v: Vec<[f64; 3]> = particles.iter().map(|p| p.velocity).collect();
        let r: Vec<f64> = particles.iter().map(|p| p.radius).collect();
        let rho: Vec<f64> = particles.iter().map(|p| p.density).collect();
        Liggghts::insert(self, &x, &v, &r, &rho).map_err(|reason| BackendError::InvalidArgument {
            argument: "grains".into(),
            reason,
        })
    }
    fn remove_past_outlet(&mut self) -> Result<f64, BackendError> {
        Liggghts::remove_past_outlet(self).map_err(engine_error)
    }
    /// Forces from LIGGGHTS's `store_force` arrays (none for a user's own input, whose
    /// walls plugflow does not know).
    fn wall_forces(&self) -> Vec<WallForce> {
        match Liggghts::wall_forces(self) {
            Ok(f) => self
                .mapped
                .walls
                .iter()
                .zip(f)
                .map(|((name, _), force)| WallForce {
                    wall: name.clone(),
                    force,
                })
                .collect(),
            Err(_) => Vec::new(),
        }
    }
    fn stage_times(&self) -> Vec<(String, f64)> {
        Vec::new()
    }
    fn save_state(&mut self) -> Result<Vec<u8>, BackendError> {
        self.save().map_err(engine_error)
    }
    fn restore_state(&mut self, state: &[u8]) -> Result<(), BackendError> {
        self.restore(state).map_err(engine_error)
    }
    fn flow(&self) -> Option<GrainFlow> {
        let f = &self.flow;
        Some(GrainFlow {
            fed_count: f.fed_count,
            fed_mass: f.fed_mass,
            outflow_count: f.outflow_count,
            outflow_mass: f.outflow_mass,
            lost_count: f.lost_count,
        })
    }
}
