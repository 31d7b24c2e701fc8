//! An ABI engine in a child process (`plugflow-dem-host`), for engines that may end their
//! process (LIGGGHTS calls `exit(1)` on its errors): the child loads the library; this side
//! talks to it over its stdin/stdout. If the child dies, the call returns an error with its
//! exit status and last words, and the run that drove it stops cleanly with what it has.
//!
//! Protocol (little-endian): a request is an opcode byte and its arguments; the reply is a
//! status byte (0 ok, 1 error + message) and, after every successful request, a [`Payload`]
//! (inserted ids, a saved state) and the engine's whole state (time step, time, steps, name, version, grains, flow, walls), which this
//! side mirrors like [`crate::abi::AbiBackend`] does.

use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use crate::backend::{
    BackendError, DemBackend, GrainFlow, ImplicitDrag, NewParticle, ParticleView, WallForce,
};
use crate::{Real, Vec3};

/// Request opcodes.
pub mod op {
    pub const CREATE: u8 = 1;
    pub const ADVANCE: u8 = 2;
    pub const SET_FORCES: u8 = 3;
    pub const INSERT: u8 = 4;
    pub const REMOVE: u8 = 5;
    pub const QUIT: u8 = 6;
    /// The engine's state (a checkpoint): the ok reply carries its bytes.
    pub const SAVE: u8 = 7;
    pub const RESTORE: u8 = 8;
    pub const KEEP_LOG: u8 = 9;
}

/// What an ok reply carries before the engine's state (flag 0, 1, 2 on the wire).
#[derive(Debug)]
pub enum Payload {
    Nothing,
    /// The ids an INSERT gave.
    Ids(Vec<u64>),
    /// The engine's state a SAVE wrote.
    Bytes(Vec<u8>),
}

/// Little-endian writer helpers.
pub trait WireWrite: Write {
    fn u8(&mut self, v: u8) -> std::io::Result<()> {
        self.write_all(&[v])
    }
    fn u64(&mut self, v: u64) -> std::io::Result<()> {
        self.write_all(&v.to_le_bytes())
    }
    fn f64(&mut self, v: f64) -> std::io::Result<()> {
        self.write_all(&v.to_le_bytes())
    }
    fn text(&mut self, s: &str) -> std::io::Result<()> {
        self.u64(s.len() as u64)?;
        self.write_all(s.as_bytes())
    }
    fn f64s(&mut self, v: &[f64]) -> std::io::Result<()> {
        self.u64(v.len() as u64)?;
        for x in v {
            self.f64(*x)?;
        }
        Ok(())
    }
    fn blob(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.u64(b.len() as u64)?;
        self.write_all(b)
    }
}
impl<W: Write> WireWrite for W {}

/// Little-endian reader helpers.
pub trait WireRead: Read {
    fn u8(&mut self) -> std::io::Result<u8> {
        let mut b = [0u8; 1];
        self.read_exact(&mut b)?;
        Ok(b[0])
    }
    fn u64(&mut self) -> std::io::Result<u64> {
        let mut b = [0u8; 8];
        self.read_exact(&mut b)?;
        Ok(u64::from_le_bytes(b))
    }
    fn f64(&mut self) -> std::io::Result<f64> {
        let mut b = [0u8; 8];
        self.read_exact(&mut b)?;
        Ok(f64::from_le_bytes(b))
    }
    fn text(&mut self) -> std::io::Result<String> {
        let n = self.u64()? as usize;
        let mut b = vec![0u8; n];
        self.read_exact(&mut b)?;
        Ok(String::from_utf8_lossy(&b).into_owned())
    }
    fn f64s(&mut self) -> std::io::Result<Vec<f64>> {
        let n = self.u64()? as usize;
        (0..n).map(|_| self.f64()).collect()
    }
    fn blob(&mut self) -> std::io::Result<Vec<u8>> {
        let n = self.u64()? as usize;
        let mut b = vec![0u8; n];
        self.read_exact(&mut b)?;
        Ok(b)
    }
}
impl<R: Read> WireRead for R {}

fn flat(v: &[Vec3]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

fn tri(v: &[f64]) -> Vec<Vec3> {
    v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Write the whole state of `e` (the host's side of every ok reply).
pub fn write_state(w: &mut impl Write, e: &dyn DemBackend) -> std::io::Result<()> {
    w.f64(e.time_step())?;
    w.f64(e.time())?;
    w.u64(e.step_count())?;
    w.text(e.engine_name())?;
    w.text(&e.engine_version())?;
    let p = e.particles();
    w.u64(p.len() as u64)?;
    for id in p.id {
        w.u64(*id)?;
    }
    w.f64s(&flat(p.position))?;
    w.f64s(&flat(p.velocity))?;
    w.f64s(&flat(p.angular_velocity))?;
    w.f64s(p.radius)?;
    w.f64s(p.mass)?;
    match e.flow() {
        Some(f) => {
            w.u8(1)?;
            w.u64(f.fed_count)?;
            w.f64(f.fed_mass)?;
            w.u64(f.outflow_count)?;
            w.f64(f.outflow_mass)?;
            w.u64(f.lost_count)?;
        }
        None => w.u8(0)?,
    }
    let walls = e.wall_forces();
    w.u64(walls.len() as u64)?;
    for wf in &walls {
        w.text(&wf.wall)?;
        w.f64s(&wf.force)?;
    }
    Ok(())
}

/// The engine in the child, mirrored.
pub struct IsolatedBackend {
    child: Child,
    to: BufWriter<ChildStdin>,
    from: BufReader<ChildStdout>,
    stderr_path: std::path::PathBuf,
    dt: Real,
    time: Real,
    steps: u64,
    name: String,
    version: String,
    ids: Vec<u64>,
    position: Vec<Vec3>,
    velocity: Vec<Vec3>,
    angular_velocity: Vec<Vec3>,
    radius: Vec<Real>,
    mass: Vec<Real>,
    flow: Option<GrainFlow>,
    walls: Vec<WallForce>,
    dead: Option<String>,
    /// Wall time of the requests (the engine's work plus the pipe), by call.
    timer: crate::timing::StageTimer,
}

impl IsolatedBackend {
    /// Start `host`, have it load `library` and create the engine from the scene JSON.
    pub fn spawn(host: &Path, library: &Path, scene_json: &str) -> Result<Self, BackendError> {
        let stderr_path = std::env::temp_dir().join(format!(
            "plugflow-dem-host-{}-{}.err",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos())
        ));
        let err_file = std::fs::File::create(&stderr_path).map_err(|e| BackendError::Engine {
            engine: "isolated".into(),
            message: format!("{}: {e}", stderr_path.display()),
        })?;
        let mut child = Command::new(host)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::from(err_file))
            .spawn()
            .map_err(|e| BackendError::Engine {
                engine: "isolated".into(),
                message: format!("cannot start the engine host `{}`: {e}", host.display()),
            })?;
        let to = BufWriter::new(child.stdin.take().expect("piped"));
        let from = BufReader::new(child.stdout.take().expect("piped"));
        let mut me = Self {
            child,
            to,
            from,
            stderr_path,
            dt: 0.0,
            time: 0.0,
            steps: 0,
            name: "isolated".into(),
            version: String::new(),
            ids: Vec::new(),
            position: Vec::new(),
            velocity: Vec::new(),
            angular_velocity: Vec::new(),
            radius: Vec::new(),
            mass: Vec::new(),
            flow: None,
            walls: Vec::new(),
            dead: None,
            timer: crate::timing::StageTimer::new(),
        };
        let lib = library.display().to_string();
        me.request(|w| {
            w.u8(op::CREATE)?;
            w.text(&lib)?;
            w.text(scene_json)
        })?;
        Ok(me)
    }

    /// Process id of the child (tests kill it to show what a dying engine does).
    pub fn child_id(&self) -> u32 {
        self.child.id()
    }

    /// The child died: its exit status and last lines of stderr.
    fn death(&mut self, io: std::io::Error) -> BackendError {
        let status = self
            .child
            .wait()
            .map(|s| s.to_string())
            .unwrap_or_else(|e| format!("unknown ({e})"));
        let said = std::fs::read_to_string(&self.stderr_path).unwrap_or_default();
        let tail: Vec<&str> = said.lines().rev().take(3).collect();
        let message = format!(
            "the engine process died ({status}; pipe: {io}){}",
            if tail.is_empty() {
                String::new()
            } else {
                format!(
                    "; its last words: {}",
                    tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                )
            }
        );
        self.dead = Some(message.clone());
        BackendError::Engine {
            engine: self.name.clone(),
            message,
        }
    }

    fn request(
        &mut self,
        write: impl FnOnce(&mut BufWriter<ChildStdin>) -> std::io::Result<()>,
    ) -> Result<Payload, BackendError> {
        if let Some(m) = &self.dead {
            return Err(BackendError::Engine {
                engine: self.name.clone(),
                message: m.clone(),
            });
        }
        let sent = write(&mut self.to).and_then(|_| self.to.flush());
        if let Err(e) = sent {
            return Err(self.death(e));
        }
        match self.read_reply() {
            Ok(r) => r,
            Err(e) => Err(self.death(e)),
        }
    }

    /// Ok(Ok(what the reply carried)) / Ok(Err(engine error)) / Err(pipe broken).
    fn read_reply(&mut self) -> std::io::Result<Result<Payload, BackendError>> {
        let r = &mut self.from;
        if r.u8()? != 0 {
            let kind = r.u8()?;
            let message = r.text()?;
            return Ok(Err(match kind {
                1 => BackendError::InvalidArgument {
                    argument: "engine call".into(),
                    reason: message,
                },
                _ => BackendError::Engine {
                    engine: self.name.clone(),
                    message,
                },
            }));
        }
        let payload = match r.u8()? {
            1 => {
                let n = r.u64()? as usize;
                Payload::Ids(
                    (0..n)
                        .map(|_| r.u64())
                        .collect::<std::io::Result<Vec<_>>>()?,
                )
            }
            2 => Payload::Bytes(r.blob()?),
            _ => Payload::Nothing,
        };
        self.dt = r.f64()?;
        self.time = r.f64()?;
        self.steps = r.u64()?;
        self.name = r.text()?;
        self.version = r.text()?;
        let n = r.u64()? as usize;
        self.ids = (0..n).map(|_| r.u64()).collect::<std::io::Result<_>>()?;
        self.position = tri(&r.f64s()?);
        self.velocity = tri(&r.f64s()?);
        self.angular_velocity = tri(&r.f64s()?);
        self.radius = r.f64s()?;
        self.mass = r.f64s()?;
        self.flow = match r.u8()? {
            1 => Some(GrainFlow {
                fed_count: r.u64()?,
                fed_mass: r.f64()?,
                outflow_count: r.u64()?,
                outflow_mass: r.f64()?,
                lost_count: r.u64()?,
            }),
            _ => None,
        };
        let nw = r.u64()? as usize;
        let mut walls = Vec::with_capacity(nw);
        for _ in 0..nw {
            let wall = r.text()?;
            let f = r.f64s()?;
            walls.push(WallForce {
                wall,
                force: [f[0], f[1], f[2]],
            });
        }
        self.walls = walls;
        Ok(Ok(payload))
    }
}

impl Drop for IsolatedBackend {
    fn drop(&mut self) {
        if self.dead.is_none() {
            let _ = self.to.u8(op::QUIT).and_then(|_| self.to.flush());
        }
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.stderr_path);
    }
}

impl DemBackend for IsolatedBackend {
    fn engine_name(&self) -> &str {
        &self.name
    }
    fn engine_version(&self) -> String {
        format!("{} (in a child process)", self.version)
    }
    fn time_step(&self) -> Real {
        self.dt
    }
    fn time(&self) -> Real {
        self.time
    }
    fn step_count(&self) -> u64 {
        self.steps
    }
    fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
        let t0 = std::time::Instant::now();
        let r = self
            .request(|w| {
                w.u8(op::ADVANCE)?;
                w.u64(steps)
            })
            .map(|_| ());
        self.timer.add("dem_advance", t0.elapsed().as_secs_f64());
        r
    }
    fn particles(&self) -> ParticleView<'_> {
        ParticleView {
            id: &self.ids,
            position: &self.position,
            velocity: &self.velocity,
            angular_velocity: &self.angular_velocity,
            radius: &self.radius,
            mass: &self.mass,
        }
    }
    fn set_fluid_forces(
        &mut self,
        force: &[Vec3],
        implicit: Option<ImplicitDrag<'_>>,
    ) -> Result<(), BackendError> {
        if implicit.is_some() {
            return Err(BackendError::InvalidArgument {
                argument: "implicit".into(),
                reason: "an isolated engine takes the drag as an explicit force".into(),
            });
        }
        let f = flat(force);
        self.request(|w| {
            w.u8(op::SET_FORCES)?;
            w.f64s(&f)
        })
        .map(|_| ())
    }
    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        let grains: Vec<f64> = particles
            .iter()
            .flat_map(|p| {
                [
                    p.position[0],
                    p.position[1],
                    p.position[2],
                    p.velocity[0],
                    p.velocity[1],
                    p.velocity[2],
                    p.radius,
                    p.density,
                ]
            })
            .collect();
        self.request(|w| {
            w.u8(op::INSERT)?;
            w.f64s(&grains)
        })
        .map(|p| match p {
            Payload::Ids(ids) => ids,
            _ => Vec::new(),
        })
    }
    fn remove_past_outlet(&mut self) -> Result<Real, BackendError> {
        let before = self.flow.map_or(0.0, |f| f.outflow_mass);
        self.request(|w| w.u8(op::REMOVE))?;
        Ok(self.flow.map_or(0.0, |f| f.outflow_mass) - before)
    }
    fn wall_forces(&self) -> Vec<WallForce> {
        self.walls.clone()
    }
    fn stage_times(&self) -> Vec<(String, f64)> {
        self.timer.entries()
    }
    fn flow(&self) -> Option<GrainFlow> {
        self.flow
    }
    fn save_state(&mut self) -> Result<Vec<u8>, BackendError> {
        match self.request(|w| w.u8(op::SAVE))? {
            Payload::Bytes(bytes) => Ok(bytes),
            other => Err(BackendError::Engine {
                engine: self.name.clone(),
                message: format!("the engine host answered SAVE without a state ({other:?})"),
            }),
        }
    }
    fn keep_log(&mut self, dir: &Path) -> Result<(), BackendError> {
        let dir = dir.display().to_string();
        self.request(|w| {
            w.u8(op::KEEP_LOG)?;
            w.text(&dir)
        })
        .map(|_| ())
    }
    fn restore_state(&mut self, state: &[u8]) -> Result<(), BackendError> {
        self.request(|w| {
            w.u8(op::RESTORE)?;
            w.blob(state)
        })
        .map(|_| ())
    }
}

/// The host's loop: serve requests on stdin/stdout for an engine made by `create`.
pub fn serve(
    create: impl FnOnce(&str, &str) -> Result<Box<dyn DemBackend>, String>,
) -> std::io::Result<()> {
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let mut r = BufReader::new(stdin.lock());
    let mut w = BufWriter::new(stdout.lock());
    let fail = |w: &mut BufWriter<_>, kind: u8, m: &str| -> std::io::Result<()> {
        w.u8(1)?;
        w.u8(kind)?;
        w.text(m)?;
        w.flush()
    };
    // CREATE first.
    if r.u8()? != op::CREATE {
        return fail(&mut w, 2, "the first request must create the engine");
    }
    let lib = r.text()?;
    let json = r.text()?;
    let mut engine = match create(&lib, &json) {
        Ok(e) => e,
        Err(m) => return fail(&mut w, 2, &m),
    };
    let ok = |w: &mut BufWriter<_>, e: &dyn DemBackend, payload: &Payload| {
        w.u8(0)?;
        match payload {
            Payload::Nothing => w.u8(0)?,
            Payload::Ids(ids) => {
                w.u8(1)?;
                w.u64(ids.len() as u64)?;
                for id in ids {
                    w.u64(*id)?;
                }
            }
            Payload::Bytes(bytes) => {
                w.u8(2)?;
                w.blob(bytes)?;
            }
        }
        write_state(w, e)?;
        w.flush()
    };
    ok(&mut w, engine.as_ref(), &Payload::Nothing)?;
    let kind = |e: &BackendError| match e {
        BackendError::InvalidArgument { .. } => 1,
        _ => 2,
    };
    loop {
        let code = match r.u8() {
            Ok(c) => c,
            Err(_) => return Ok(()), // the parent went away
        };
        let result: Result<Payload, BackendError> = match code {
            op::ADVANCE => {
                let n = r.u64()?;
                engine.advance(n).map(|_| Payload::Nothing)
            }
            op::SET_FORCES => {
                let f = tri(&r.f64s()?);
                engine.set_fluid_forces(&f, None).map(|_| Payload::Nothing)
            }
            op::INSERT => {
                let g = r.f64s()?;
                let grains: Vec<NewParticle> = g
                    .chunks_exact(8)
                    .map(|c| NewParticle {
                        position: [c[0], c[1], c[2]],
                        velocity: [c[3], c[4], c[5]],
                        radius: c[6],
                        density: c[7],
                    })
                    .collect();
                engine.insert(&grains).map(Payload::Ids)
            }
            op::REMOVE => engine.remove_past_outlet().map(|_| Payload::Nothing),
            op::SAVE => engine.save_state().map(Payload::Bytes),
            op::RESTORE => {
                let bytes = r.blob()?;
                engine.restore_state(&bytes).map(|_| Payload::Nothing)
            }
            op::KEEP_LOG => {
                let dir = r.text()?;
                engine.keep_log(Path::new(&dir)).map(|_| Payload::Nothing)
            }
            op::QUIT => return Ok(()),
            other => {
                return fail(&mut w, 2, &format!("unknown request {other}"));
            }
        };
        match result {
            Ok(payload) => ok(&mut w, engine.as_ref(), &payload)?,
            Err(e) => fail(&mut w, kind(&e), &e.to_string())?,
        }
    }
}
