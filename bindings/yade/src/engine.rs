//! One YADE simulation driven through its Python API (Debian's CPython 3.11 embedded, see
//! driver.py), with plugflow's inlet, outlet and bookkeeping around it.
//!
//! YADE's `Omega` is a process-wide singleton: one YADE engine lives in a process at a
//! time (a second create is refused; `dem.isolate = true` runs each in its own process).

use std::ffi::CString;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

use plugflow_coupling::timing::StageTimer;
use plugflow_coupling::{
    BackendError, DemBackend, GrainFlow, ImplicitDrag, NewParticle, ParticleView, WallForce,
};
use plugflow_model::dem::config::InletMode;
use plugflow_model::dem::conveyor::Conveyor;
use plugflow_model::dem::inlet::{leave_verdict, Feeder, Leave};
use plugflow_model::dem::{DemConfig, NativeDem};
use plugflow_model::rng::Rng;
use plugflow_model::scene::Scene;
use pyo3::prelude::*;
use pyo3::types::PyModule;

use crate::input::map;

/// Where Debian's YADE keeps its Python modules (its dist-packages link is broken).
pub const YADE_PY_PATH: &str = "/usr/lib/x86_64-linux-gnu/yade-double/py";

/// Speed above which a grain is taken to have blown up, m/s (as the built-in engine).
const BLOWUP_SPEED: f64 = 1.0e4;

/// Most steps between two looks at the inlet and the open ends.
const FEED_STRIDE: u64 = 50;

/// True while a YADE engine exists in this process.
static ALIVE: AtomicBool = AtomicBool::new(false);

/// The driver module and YADE's version, once per process.
static DRIVER: OnceLock<Result<(Py<PyModule>, String), String>> = OnceLock::new();

fn py_err(e: PyErr) -> String {
    Python::attach(|py| {
        let tb = e
            .traceback(py)
            .and_then(|t| t.format().ok())
            .unwrap_or_default();
        format!(
            "YADE (Python): {e}{}",
            if tb.is_empty() { "" } else { "\n" }
        ) + &tb
    })
}

/// Start the embedded interpreter as Debian's `/usr/bin/python3`, whatever the user's PATH
/// and environment. Left to itself an embedded CPython takes its prefix from the first
/// `python3` on PATH: a venv or pyenv there gives it a library without YADE's dependencies
/// ("No module named 'future'", issue 26). Isolated: PYTHONPATH, PYTHONHOME and the user's
/// site-packages are ignored too; Debian's dist-packages still come from `site`.
fn start_debian_python() -> Result<(), String> {
    use pyo3::ffi;
    // SAFETY: the documented PyConfig sequence (init, set, initialize, clear) on a config
    // owned here, once, before any other use of Python in this process; the GIL is then
    // released as pyo3's own initialisation does, for `Python::attach` to take it.
    unsafe {
        if ffi::Py_IsInitialized() != 0 {
            return Ok(());
        }
        let mut config = std::mem::MaybeUninit::<ffi::PyConfig>::uninit();
        let cfg = config.as_mut_ptr();
        ffi::PyConfig_InitIsolatedConfig(cfg);
        let named = ffi::PyConfig_SetBytesString(
            cfg,
            &raw mut (*cfg).program_name,
            c"/usr/bin/python3".as_ptr(),
        );
        let status = if ffi::PyStatus_Exception(named) != 0 {
            named
        } else {
            ffi::Py_InitializeFromConfig(cfg)
        };
        ffi::PyConfig_Clear(cfg);
        if ffi::PyStatus_Exception(status) != 0 {
            let why = if status.err_msg.is_null() {
                "unknown".to_string()
            } else {
                std::ffi::CStr::from_ptr(status.err_msg)
                    .to_string_lossy()
                    .into_owned()
            };
            return Err(format!(
                "could not start Debian's Python 3.11 for YADE: {why}"
            ));
        }
        ffi::PyEval_SaveThread();
    }
    Ok(())
}

/// Start Python, import YADE and load driver.py (first call only).
fn driver(threads: usize) -> Result<&'static (Py<PyModule>, String), String> {
    DRIVER
        .get_or_init(|| {
            if !std::path::Path::new(YADE_PY_PATH).join("yade").exists() {
                return Err(format!(
                    "YADE is not installed ({YADE_PY_PATH}/yade missing): run `bash \
                     scripts/setup-system.sh` (apt-get install yade python3-yade)"
                ));
            }
            start_debian_python()?;
            // Loaded by a local dlopen (libloading), libpython's symbols are not global and
            // YADE's extension modules would fail with undefined Python symbols: promote
            // the copy already mapped (this library links it) to global.
            // SAFETY: plain dlopen of a library already loaded; the handle is kept.
            let h = unsafe {
                libc::dlopen(
                    c"libpython3.11.so.1.0".as_ptr(),
                    libc::RTLD_NOW | libc::RTLD_GLOBAL | libc::RTLD_NOLOAD,
                )
            };
            if h.is_null() {
                return Err("libpython3.11.so.1.0 is not loaded (the YADE shim links it)".into());
            }
            Python::attach(|py| -> PyResult<(Py<PyModule>, String)> {
                let code = CString::new(include_str!("driver.py")).expect("no NUL in driver.py");
                let m = PyModule::from_code(
                    py,
                    &code,
                    c"plugflow_yade_driver.py",
                    c"plugflow_yade_driver",
                )?;
                let version: String = m
                    .getattr("boot")?
                    .call1((threads, YADE_PY_PATH))?
                    .extract()?;
                Ok((m.unbind(), version))
            })
            .map_err(py_err)
        })
        .as_ref()
        .map_err(|e| e.clone())
}

/// A YADE simulation with the scene mapped into it.
pub struct Yade {
    cfg: DemConfig,
    scene: Py<PyAny>,
    version: String,
    time: f64,
    steps: u64,
    feeder: Feeder,
    /// The conveyor inlet's column (`inlet.mode = "conveyor"`): its grains in the slab are
    /// held in YADE with every degree of freedom blocked (YADE then moves them at the
    /// velocity they were given, deaf to forces and gravity, as the built-in engine's 1/m = 0).
    conveyor: Option<Conveyor>,
    rng: Rng,
    flow: GrainFlow,
    wall_names: Vec<String>,
    timer: StageTimer,
    ids: Vec<u64>,
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    omega: Vec<[f64; 3]>,
    radius: Vec<f64>,
    mass: Vec<f64>,
}

impl Yade {
    /// Check and map the scene, build it in YADE, insert the scene's initial grains
    /// (placed by plugflow, so every engine starts from the same bed).
    pub fn new(scene: &Scene) -> Result<Self, String> {
        let cfg = plugflow_model::dem_config(scene).map_err(|e| e.to_string())?;
        let setup = map(scene, &cfg).map_err(|e| e.to_string())?;
        let json = serde_json::to_string(&setup).map_err(|e| e.to_string())?;
        let initial = if cfg.initial.is_some() {
            let mut native_cfg = cfg.clone();
            native_cfg.inlet = None;
            let n = NativeDem::new(native_cfg).map_err(|e| e.to_string())?;
            let p = n.particles();
            Some((p.position.to_vec(), p.velocity.to_vec()))
        } else {
            None
        };
        let (module, version) = driver(cfg.threads)?;
        if ALIVE.swap(true, Ordering::SeqCst) {
            return Err(
                "YADE keeps one simulation per process (its Omega is a singleton) and \
                 one is open: destroy it first, or set `dem.isolate = true` to run each YADE \
                 engine in its own process"
                    .into(),
            );
        }
        let built = Python::attach(|py| -> PyResult<(Py<PyAny>, Vec<String>)> {
            let s = module.bind(py).getattr("create")?.call1((json,))?;
            let names: Vec<String> = s.getattr("wall_names")?.call0()?.extract()?;
            Ok((s.unbind(), names))
        });
        let (scene_obj, wall_names) = match built {
            Ok(b) => b,
            Err(e) => {
                ALIVE.store(false, Ordering::SeqCst);
                return Err(py_err(e));
            }
        };
        let mut rng = Rng::new(cfg.seed);
        let conveyor = if cfg.inlet.is_some_and(|i| i.mode == InletMode::Conveyor) {
            match Conveyor::primed(&cfg, &mut rng) {
                Ok(c) => Some(c),
                Err(e) => {
                    ALIVE.store(false, Ordering::SeqCst);
                    return Err(format!("inlet.mode: {e}"));
                }
            }
        } else {
            None
        };
        let mut me = Self {
            rng,
            conveyor,
            cfg,
            scene: scene_obj,
            version: format!("YADE {version}"),
            time: 0.0,
            steps: 0,
            feeder: Feeder::default(),
            flow: GrainFlow::default(),
            wall_names,
            timer: StageTimer::new(),
            ids: Vec::new(),
            x: Vec::new(),
            v: Vec::new(),
            omega: Vec::new(),
            radius: Vec::new(),
            mass: Vec::new(),
        };
        if let Some((x, v)) = initial {
            let (r, rho) = (me.cfg.radius_min, me.cfg.density);
            me.insert_grains(x.iter().zip(&v).map(|(x, v)| (*x, *v, r, rho)))?;
        }
        me.refresh()?;
        Ok(me)
    }

    fn call<T>(&self, f: impl FnOnce(&Bound<'_, PyAny>) -> PyResult<T>) -> Result<T, String> {
        Python::attach(|py| f(self.scene.bind(py))).map_err(py_err)
    }

    /// Re-read every grain.
    fn refresh(&mut self) -> Result<(), String> {
        let flat: Vec<f64> = self.call(|s| s.getattr("state")?.call0()?.extract())?;
        let n = flat.len() / 12;
        self.ids.clear();
        self.x.clear();
        self.v.clear();
        self.omega.clear();
        self.radius.clear();
        self.mass.clear();
        for g in flat.chunks_exact(12) {
            self.ids.push(g[0] as u64);
            self.x.push([g[1], g[2], g[3]]);
            self.v.push([g[4], g[5], g[6]]);
            self.omega.push([g[7], g[8], g[9]]);
            self.radius.push(g[10]);
            self.mass.push(g[11]);
        }
        debug_assert_eq!(self.ids.len(), n);
        Ok(())
    }

    /// Create grains (position, velocity, radius, density); their plugflow ids.
    fn insert_grains(
        &mut self,
        grains: impl Iterator<Item = ([f64; 3], [f64; 3], f64, f64)>,
    ) -> Result<Vec<u64>, String> {
        let (lo, hi) = (self.cfg.box_lo, self.cfg.box_hi);
        let mut flat = Vec::new();
        for (i, (x, v, r, rho)) in grains.enumerate() {
            if (0..3).any(|k| !(x[k] > lo[k] && x[k] < hi[k])) {
                return Err(format!("grain {i} at {x:?} lies outside the domain"));
            }
            if !(r > 0.0 && rho > 0.0) || x.iter().chain(&v).any(|c| !c.is_finite()) {
                return Err(format!(
                    "grain {i}: radius and density must be positive, position and velocity finite"
                ));
            }
            flat.extend_from_slice(&[x[0], x[1], x[2], v[0], v[1], v[2], r, rho]);
        }
        if flat.is_empty() {
            return Ok(Vec::new());
        }
        let ids: Vec<u64> = self.call(|s| s.getattr("insert")?.call1((flat,))?.extract())?;
        self.refresh()?;
        Ok(ids)
    }

    /// Remove grains past the open ends (outlet mass returned), feed the inlet.
    fn inlet_outlet(&mut self, elapsed: f64) -> Result<f64, String> {
        let mut gone = Vec::new();
        let mut out_mass = 0.0;
        for i in 0..self.ids.len() {
            match leave_verdict(&self.cfg, self.x[i], self.radius[i]) {
                Leave::Stay => {}
                Leave::Outlet => {
                    out_mass += self.mass[i];
                    self.flow.outflow_count += 1;
                    gone.push(self.ids[i]);
                }
                Leave::Lost => {
                    self.flow.lost_count += 1;
                    gone.push(self.ids[i]);
                }
            }
        }
        self.flow.outflow_mass += out_mass;
        if !gone.is_empty() {
            self.call(|s| s.getattr("remove")?.call1((gone,)).map(|_| ()))?;
            self.refresh()?;
        }
        if self.conveyor.is_some() {
            self.convey(elapsed)?;
            return Ok(out_mass);
        }
        let placed = self.feeder.feed(
            &self.cfg,
            self.time,
            elapsed,
            self.x.iter().zip(&self.radius).map(|(x, r)| (*x, *r)),
            &mut self.rng,
        );
        if !placed.is_empty() {
            let v = Feeder::velocity(&self.cfg);
            let rho = self.cfg.density;
            let n = placed.len();
            self.insert_grains(placed.into_iter().map(|(x, r)| (x, v, r, rho)))?;
            self.flow.fed_count += n as u64;
            let m: f64 = self.mass[self.mass.len() - n..].iter().sum();
            self.flow.fed_mass += m;
        }
        Ok(out_mass)
    }

    /// The conveyor's part of a feed (see [`Conveyor::feed`]): hold, release and add held
    /// grains in YADE.
    fn convey(&mut self, elapsed: f64) -> Result<(), String> {
        let Some(mut column) = self.conveyor.take() else {
            return Ok(());
        };
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
        let result = (|| -> Result<(), String> {
            let hold: Vec<u64> = feed.hold.iter().map(|&i| self.ids[i]).collect();
            let release: Vec<u64> = feed.release.iter().map(|&i| self.ids[i]).collect();
            if !hold.is_empty() || !release.is_empty() {
                self.call(|s| {
                    s.getattr("hold")?.call1((hold, v.to_vec()))?;
                    s.getattr("release")?.call1((release,)).map(|_| ())
                })?;
            }
            if !feed.enter.is_empty() {
                let rho = self.cfg.density;
                let n = feed.enter.len();
                let ids = self.insert_grains(feed.enter.iter().map(|&(x, r)| (x, v, r, rho)))?;
                self.call(|s| {
                    s.getattr("hold")?
                        .call1((ids.clone(), v.to_vec()))
                        .map(|_| ())
                })?;
                for id in ids {
                    column.hold(id);
                }
                self.flow.fed_count += n as u64;
                self.flow.fed_mass += self.mass[self.mass.len() - n..].iter().sum::<f64>();
            }
            self.refresh()
        })();
        self.conveyor = Some(column);
        result
    }

    fn advance_steps(&mut self, steps: u64) -> Result<(), String> {
        let edges = self.cfg.inlet.is_some() || self.cfg.removes_grains;
        let mut left = steps;
        while left > 0 {
            let k = if edges { left.min(FEED_STRIDE) } else { left };
            let t0 = Instant::now();
            self.call(|s| s.getattr("step")?.call1((k,)).map(|_| ()))?;
            self.timer.add("yade_step", t0.elapsed().as_secs_f64());
            self.steps += k;
            self.time = self.steps as f64 * self.cfg.dt;
            left -= k;
            let t1 = Instant::now();
            self.refresh()?;
            self.timer.add("exchange", t1.elapsed().as_secs_f64());
            if let Some(i) = self.x.iter().zip(&self.v).position(|(x, v)| {
                x.iter().chain(v).any(|c| !c.is_finite())
                    || v.iter().map(|c| c * c).sum::<f64>() > BLOWUP_SPEED * BLOWUP_SPEED
            }) {
                return Err(format!(
                    "non-finite or blown-up state at step {}: particle id {} (x {:?}, v {:?})",
                    self.steps, self.ids[i], self.x[i], self.v[i]
                ));
            }
            if edges {
                let t2 = Instant::now();
                self.inlet_outlet(k as f64 * self.cfg.dt)?;
                self.timer.add("inlet_outlet", t2.elapsed().as_secs_f64());
            }
        }
        Ok(())
    }
}

impl Drop for Yade {
    fn drop(&mut self) {
        if let Some(Ok((module, _))) = DRIVER.get() {
            let _ = Python::attach(|py| module.bind(py).getattr("destroy")?.call0().map(|_| ()));
        }
        ALIVE.store(false, Ordering::SeqCst);
    }
}

fn engine_error(message: String) -> BackendError {
    BackendError::Engine {
        engine: "yade".into(),
        message,
    }
}

impl DemBackend for Yade {
    fn engine_name(&self) -> &str {
        "yade"
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
    fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
        self.advance_steps(steps).map_err(engine_error)
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
                reason: "the YADE shim takes the drag as an explicit force".into(),
            });
        }
        if force.len() != self.ids.len() {
            return Err(BackendError::InvalidArgument {
                argument: "force".into(),
                reason: format!("{} forces for {} grains", force.len(), self.ids.len()),
            });
        }
        if let Some(i) = force.iter().position(|f| f.iter().any(|c| !c.is_finite())) {
            return Err(BackendError::NonFinite {
                step: self.steps,
                particle_id: self.ids[i],
                what: format!("fluid force {:?}", force[i]),
            });
        }
        let flat: Vec<f64> = force.iter().flatten().copied().collect();
        let t0 = Instant::now();
        let r = self
            .call(|s| s.getattr("set_forces")?.call1((flat,)).map(|_| ()))
            .map_err(engine_error);
        self.timer.add("exchange", t0.elapsed().as_secs_f64());
        r
    }
    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        self.insert_grains(
            particles
                .iter()
                .map(|p| (p.position, p.velocity, p.radius, p.density)),
        )
        .map_err(|reason| BackendError::InvalidArgument {
            argument: "grains".into(),
            reason,
        })
    }
    /// The engine removes grains past the open ends itself after every stride; nothing
    /// is left to remove between advances.
    fn remove_past_outlet(&mut self) -> Result<f64, BackendError> {
        Ok(0.0)
    }
    fn wall_forces(&self) -> Vec<WallForce> {
        let flat: Vec<f64> = self
            .call(|s| s.getattr("wall_forces")?.call0()?.extract())
            .unwrap_or_default();
        self.wall_names
            .iter()
            .zip(flat.chunks_exact(3))
            .map(|(name, f)| WallForce {
                wall: name.clone(),
                force: [f[0], f[1], f[2]],
            })
            .collect()
    }
    fn stage_times(&self) -> Vec<(String, f64)> {
        self.timer.entries()
    }
    fn flow(&self) -> Option<GrainFlow> {
        Some(self.flow)
    }
}
