//! The DEM ABI of `bindings/include/plugflow_dem.h` on the Rust side: its constants, its
//! `#[repr(C)]` structs, one function-pointer type per call (the native library checks at
//! compile time that its exports have exactly these types; a test checks them against the
//! header), and [`AbiBackend`], the loader that turns any library implementing the ABI
//! into a [`DemBackend`].

use std::ffi::{c_char, CStr};
use std::path::Path;

use crate::backend::{
    BackendError, DemBackend, ImplicitDrag, NewParticle, ParticleView, WallForce,
};
use crate::{Real, Vec3};

/// ABI major version: a loader refuses a library with another major.
pub const ABI_MAJOR: u32 = 1;
/// ABI minor version: minors only add optional calls.
pub const ABI_MINOR: u32 = 4;
/// `abi_version()` of this build: major << 16 | minor.
pub const ABI_VERSION: u32 = (ABI_MAJOR << 16) | ABI_MINOR;

/// Status codes (fixed numbers).
pub mod status {
    pub const OK: i32 = 0;
    pub const NULL: i32 = 1;
    pub const INVALID_ARGUMENT: i32 = 2;
    pub const SCENE: i32 = 3;
    pub const NON_FINITE: i32 = 4;
    pub const ENGINE: i32 = 5;
    pub const BUFFER_TOO_SMALL: i32 = 6;
    pub const PANIC: i32 = 7;
    pub const UNSUPPORTED: i32 = 8;
}

/// Reductions of `pf_dem_all_reduce` (fixed numbers).
pub mod reduce {
    pub const SUM: i32 = 0;
    pub const MAX: i32 = 1;
}

/// Opaque engine instance.
#[repr(C)]
pub struct PfDem {
    _private: [u8; 0],
}

/// `pf_dem_info`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct PfDemInfo {
    pub time_step: f64,
    pub time: f64,
    pub step_count: u64,
    pub particle_count: u64,
    pub wall_count: u64,
    pub name: [c_char; 32],
    pub version: [c_char; 96],
}

impl Default for PfDemInfo {
    fn default() -> Self {
        Self {
            time_step: 0.0,
            time: 0.0,
            step_count: 0,
            particle_count: 0,
            wall_count: 0,
            name: [0; 32],
            version: [0; 96],
        }
    }
}

/// `pf_dem_flow`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PfDemFlow {
    pub fed_count: u64,
    pub fed_mass: f64,
    pub outflow_count: u64,
    pub outflow_mass: f64,
    pub lost_count: u64,
}

pub type AbiVersionFn = unsafe extern "C" fn() -> u32;
pub type CreateFn = unsafe extern "C" fn(*const c_char, usize, *mut *mut PfDem) -> i32;
pub type CheckFn = unsafe extern "C" fn(*const c_char, usize) -> i32;
pub type DestroyFn = unsafe extern "C" fn(*mut PfDem);
pub type LastErrorFn = unsafe extern "C" fn(*const PfDem, *mut c_char, usize) -> usize;
pub type InfoGetFn = unsafe extern "C" fn(*const PfDem, *mut PfDemInfo) -> i32;
pub type AdvanceFn = unsafe extern "C" fn(*mut PfDem, u64) -> i32;
pub type ReadParticlesFn = unsafe extern "C" fn(
    *const PfDem,
    usize,
    *mut u64,
    *mut f64,
    *mut f64,
    *mut f64,
    *mut f64,
    *mut f64,
) -> i32;
pub type SetFluidForcesFn = unsafe extern "C" fn(*mut PfDem, usize, *const f64) -> i32;
pub type SetImplicitDragFn =
    unsafe extern "C" fn(*mut PfDem, usize, *const f64, *const f64, *const f64) -> i32;
pub type InsertFn = unsafe extern "C" fn(
    *mut PfDem,
    usize,
    *const f64,
    *const f64,
    *const f64,
    *const f64,
    *mut u64,
) -> i32;
pub type RemovePastOutletFn = unsafe extern "C" fn(*mut PfDem, *mut f64) -> i32;
pub type ReadWallForcesFn = unsafe extern "C" fn(*const PfDem, usize, *mut f64) -> i32;
pub type WallNameFn = unsafe extern "C" fn(*const PfDem, usize, *mut c_char, usize) -> i32;
pub type FlowGetFn = unsafe extern "C" fn(*const PfDem, *mut PfDemFlow) -> i32;
pub type KeepLogFn = unsafe extern "C" fn(*mut PfDem, *const c_char, usize) -> i32;
pub type SaveStateFn = unsafe extern "C" fn(*mut PfDem, *mut *const u8, *mut usize) -> i32;
pub type RestoreStateFn = unsafe extern "C" fn(*mut PfDem, *const u8, usize) -> i32;
pub type RanksFn = unsafe extern "C" fn(*const PfDem, *mut u32, *mut u32) -> i32;
pub type AllReduceFn = unsafe extern "C" fn(*const PfDem, *mut f64, usize, i32) -> i32;

/// Every call of the ABI: (symbol, Rust type name of its pointer type, optional).
/// The header test compares these with the prototypes of plugflow_dem.h.
pub fn declarations() -> Vec<(&'static str, &'static str, bool)> {
    use std::any::type_name;
    vec![
        ("pf_dem_abi_version", type_name::<AbiVersionFn>(), false),
        ("pf_dem_create", type_name::<CreateFn>(), false),
        ("pf_dem_check", type_name::<CheckFn>(), true),
        ("pf_dem_destroy", type_name::<DestroyFn>(), false),
        ("pf_dem_last_error", type_name::<LastErrorFn>(), false),
        ("pf_dem_info_get", type_name::<InfoGetFn>(), false),
        ("pf_dem_advance", type_name::<AdvanceFn>(), false),
        (
            "pf_dem_read_particles",
            type_name::<ReadParticlesFn>(),
            false,
        ),
        (
            "pf_dem_set_fluid_forces",
            type_name::<SetFluidForcesFn>(),
            false,
        ),
        (
            "pf_dem_set_implicit_drag",
            type_name::<SetImplicitDragFn>(),
            true,
        ),
        ("pf_dem_insert", type_name::<InsertFn>(), false),
        (
            "pf_dem_remove_past_outlet",
            type_name::<RemovePastOutletFn>(),
            false,
        ),
        (
            "pf_dem_read_wall_forces",
            type_name::<ReadWallForcesFn>(),
            false,
        ),
        ("pf_dem_wall_name", type_name::<WallNameFn>(), false),
        ("pf_dem_flow_get", type_name::<FlowGetFn>(), true),
        ("pf_dem_keep_log", type_name::<KeepLogFn>(), true),
        ("pf_dem_save_state", type_name::<SaveStateFn>(), true),
        ("pf_dem_restore_state", type_name::<RestoreStateFn>(), true),
        ("pf_dem_ranks", type_name::<RanksFn>(), true),
        ("pf_dem_all_reduce", type_name::<AllReduceFn>(), true),
    ]
}

/// Errors of loading a library.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The library cannot be opened.
    #[error("cannot load DEM library `{path}`: {reason}")]
    Open { path: String, reason: String },
    /// A required call is missing.
    #[error("DEM library `{path}` lacks the required call `{symbol}`")]
    Missing { path: String, symbol: String },
    /// Incompatible major version.
    #[error(
        "DEM library `{path}` implements ABI {major}.{minor}; this plugflow speaks {ABI_MAJOR}.x"
    )]
    Version {
        path: String,
        major: u32,
        minor: u32,
    },
    /// The library refused the scene.
    #[error("DEM library `{path}` refused the scene: {message}")]
    Create { path: String, message: String },
}

struct Calls {
    destroy: DestroyFn,
    last_error: LastErrorFn,
    info: InfoGetFn,
    advance: AdvanceFn,
    read: ReadParticlesFn,
    set_forces: SetFluidForcesFn,
    set_implicit: Option<SetImplicitDragFn>,
    insert: InsertFn,
    remove: RemovePastOutletFn,
    walls: ReadWallForcesFn,
    wall_name: WallNameFn,
    flow: Option<FlowGetFn>,
    keep_log: Option<KeepLogFn>,
    save_state: Option<SaveStateFn>,
    restore_state: Option<RestoreStateFn>,
    ranks: Option<RanksFn>,
    all_reduce: Option<AllReduceFn>,
}

/// A DEM engine behind the C ABI, loaded at run time.
pub struct AbiBackend {
    // Field order: the handle is destroyed (Drop) before the library unloads.
    handle: *mut PfDem,
    calls: Calls,
    name: String,
    version: String,
    info: PfDemInfo,
    ids: Vec<u64>,
    position: Vec<Vec3>,
    velocity: Vec<Vec3>,
    angular_velocity: Vec<Vec3>,
    radius: Vec<Real>,
    mass: Vec<Real>,
    flat: Vec<f64>,
    /// Wall time in the engine's calls: stepping, reading the grains back, setting forces.
    timer: crate::timing::StageTimer,
    _lib: libloading::Library,
}

fn c_text(raw: &[c_char]) -> String {
    let bytes: Vec<u8> = raw
        .iter()
        .take_while(|c| **c != 0)
        .map(|c| *c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// What an engine's library said of a scene it was asked to check.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CheckOutcome {
    /// The engine would take the scene.
    Accepted,
    /// The engine refuses it, saying why.
    Refused(String),
    /// The library predates `pf_dem_check` (ABI 1.0): only creating the engine would tell.
    NotOffered,
}

/// Ask the engine in `library` whether it takes the scene (JSON text), without starting it
/// (`pf_dem_check`, ABI 1.1).
pub fn check_scene(library: &Path, scene_json: &str) -> Result<CheckOutcome, LoadError> {
    let path = library.display().to_string();
    // SAFETY: as in `AbiBackend::load`: plugflow's own shims, built for this ABI.
    let lib = unsafe { libloading::Library::new(library) }.map_err(|e| LoadError::Open {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    // SAFETY: the symbols have the ABI's types (the header test keeps both sides equal).
    let version: AbiVersionFn = unsafe { lib.get::<AbiVersionFn>(b"pf_dem_abi_version\0") }
        .map(|s| *s)
        .map_err(|_| LoadError::Missing {
            path: path.clone(),
            symbol: "pf_dem_abi_version".into(),
        })?;
    // SAFETY: no arguments.
    let v = unsafe { version() };
    if v >> 16 != ABI_MAJOR {
        return Err(LoadError::Version {
            path,
            major: v >> 16,
            minor: v & 0xffff,
        });
    }
    let (Ok(check), Ok(last_error)) = (
        // SAFETY: as above.
        unsafe { lib.get::<CheckFn>(b"pf_dem_check\0") },
        unsafe { lib.get::<LastErrorFn>(b"pf_dem_last_error\0") },
    ) else {
        return Ok(CheckOutcome::NotOffered);
    };
    // SAFETY: the text pointer and length describe `scene_json`.
    let st = unsafe { check(scene_json.as_ptr() as *const c_char, scene_json.len()) };
    if st == status::OK {
        Ok(CheckOutcome::Accepted)
    } else {
        Ok(CheckOutcome::Refused(read_error(
            *last_error,
            std::ptr::null(),
        )))
    }
}

impl AbiBackend {
    /// Load `library`, check its ABI version, bind its calls and create an engine from the
    /// scene (JSON text).
    pub fn load(library: &Path, scene_json: &str) -> Result<Self, LoadError> {
        let path = library.display().to_string();
        // SAFETY: loading a library runs its initialisers; the libraries we load are
        // plugflow's own shims, built for this ABI.
        let lib = unsafe { libloading::Library::new(library) }.map_err(|e| LoadError::Open {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        macro_rules! required {
            ($sym:literal, $ty:ty) => {{
                // SAFETY: the symbol has the ABI's type (the header test and the native
                // library's compile-time check keep both sides equal).
                let s: libloading::Symbol<$ty> = unsafe { lib.get(concat!($sym, "\0").as_bytes()) }
                    .map_err(|_| LoadError::Missing {
                        path: path.clone(),
                        symbol: $sym.into(),
                    })?;
                *s
            }};
        }
        macro_rules! optional {
            ($sym:literal, $ty:ty) => {{
                // SAFETY: as above.
                unsafe { lib.get::<$ty>(concat!($sym, "\0").as_bytes()) }
                    .ok()
                    .map(|s| *s)
            }};
        }
        let version_fn = required!("pf_dem_abi_version", AbiVersionFn);
        // SAFETY: no arguments.
        let v = unsafe { version_fn() };
        if v >> 16 != ABI_MAJOR {
            return Err(LoadError::Version {
                path,
                major: v >> 16,
                minor: v & 0xffff,
            });
        }
        let create = required!("pf_dem_create", CreateFn);
        let calls = Calls {
            destroy: required!("pf_dem_destroy", DestroyFn),
            last_error: required!("pf_dem_last_error", LastErrorFn),
            info: required!("pf_dem_info_get", InfoGetFn),
            advance: required!("pf_dem_advance", AdvanceFn),
            read: required!("pf_dem_read_particles", ReadParticlesFn),
            set_forces: required!("pf_dem_set_fluid_forces", SetFluidForcesFn),
            set_implicit: optional!("pf_dem_set_implicit_drag", SetImplicitDragFn),
            insert: required!("pf_dem_insert", InsertFn),
            remove: required!("pf_dem_remove_past_outlet", RemovePastOutletFn),
            walls: required!("pf_dem_read_wall_forces", ReadWallForcesFn),
            wall_name: required!("pf_dem_wall_name", WallNameFn),
            flow: optional!("pf_dem_flow_get", FlowGetFn),
            keep_log: optional!("pf_dem_keep_log", KeepLogFn),
            save_state: optional!("pf_dem_save_state", SaveStateFn),
            restore_state: optional!("pf_dem_restore_state", RestoreStateFn),
            ranks: optional!("pf_dem_ranks", RanksFn),
            all_reduce: optional!("pf_dem_all_reduce", AllReduceFn),
        };
        let mut handle: *mut PfDem = std::ptr::null_mut();
        // SAFETY: the text pointer and length describe `scene_json`; `handle` is writable.
        let st = unsafe {
            create(
                scene_json.as_ptr() as *const c_char,
                scene_json.len(),
                &mut handle,
            )
        };
        if st != status::OK || handle.is_null() {
            let message = read_error(calls.last_error, std::ptr::null());
            return Err(LoadError::Create { path, message });
        }
        let mut me = Self {
            handle,
            calls,
            name: String::new(),
            version: String::new(),
            info: PfDemInfo::default(),
            ids: Vec::new(),
            position: Vec::new(),
            velocity: Vec::new(),
            angular_velocity: Vec::new(),
            radius: Vec::new(),
            mass: Vec::new(),
            flat: Vec::new(),
            timer: crate::timing::StageTimer::new(),
            _lib: lib,
        };
        me.refresh().map_err(|e| LoadError::Create {
            path: library.display().to_string(),
            message: e.to_string(),
        })?;
        me.name = c_text(&me.info.name);
        me.version = c_text(&me.info.version);
        Ok(me)
    }

    fn error(&self, code: i32, call: &str) -> BackendError {
        let message = read_error(self.calls.last_error, self.handle);
        match code {
            status::INVALID_ARGUMENT | status::BUFFER_TOO_SMALL | status::NULL => {
                BackendError::InvalidArgument {
                    argument: call.into(),
                    reason: message,
                }
            }
            _ => BackendError::Engine {
                engine: if self.name.is_empty() {
                    "abi".into()
                } else {
                    self.name.clone()
                },
                message: format!("{call}: {message} (status {code})"),
            },
        }
    }

    fn check(&self, code: i32, call: &str) -> Result<(), BackendError> {
        if code == status::OK {
            Ok(())
        } else {
            Err(self.error(code, call))
        }
    }

    /// Re-read the info and every grain into the mirror buffers.
    fn refresh(&mut self) -> Result<(), BackendError> {
        // SAFETY: handle is live; info is a valid out-pointer.
        let st = unsafe { (self.calls.info)(self.handle, &mut self.info) };
        self.check(st, "pf_dem_info_get")?;
        let n = self.info.particle_count as usize;
        self.ids.resize(n, 0);
        self.radius.resize(n, 0.0);
        self.mass.resize(n, 0.0);
        let mut x = vec![0.0; 3 * n];
        let mut v = vec![0.0; 3 * n];
        let mut w = vec![0.0; 3 * n];
        // SAFETY: every buffer holds `n` grains.
        let st = unsafe {
            (self.calls.read)(
                self.handle,
                n,
                self.ids.as_mut_ptr(),
                x.as_mut_ptr(),
                v.as_mut_ptr(),
                w.as_mut_ptr(),
                self.radius.as_mut_ptr(),
                self.mass.as_mut_ptr(),
            )
        };
        self.check(st, "pf_dem_read_particles")?;
        let tri = |a: &[f64]| a.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        self.position = tri(&x);
        self.velocity = tri(&v);
        self.angular_velocity = tri(&w);
        Ok(())
    }

    /// The engine does not offer an optional call.
    fn unsupported(&self, what: &str) -> BackendError {
        BackendError::Engine {
            engine: self.name.clone(),
            message: format!("this engine's library cannot {what}"),
        }
    }

    /// The engine's own feed and outflow counters, when it offers them.
    pub fn flow(&self) -> Option<PfDemFlow> {
        let f = self.calls.flow?;
        let mut out = PfDemFlow::default();
        // SAFETY: live handle, valid out-pointer.
        let st = unsafe { f(self.handle, &mut out) };
        (st == status::OK).then_some(out)
    }
}

fn read_error(f: LastErrorFn, handle: *const PfDem) -> String {
    let mut buf = vec![0 as c_char; 1024];
    // SAFETY: buf holds 1024 chars.
    let n = unsafe { f(handle, buf.as_mut_ptr(), buf.len()) };
    if n >= buf.len() {
        buf = vec![0 as c_char; n + 1];
        // SAFETY: resized to the reported length + NUL.
        unsafe { f(handle, buf.as_mut_ptr(), buf.len()) };
    }
    // SAFETY: the library NUL-terminates within len.
    unsafe { CStr::from_ptr(buf.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

impl Drop for AbiBackend {
    fn drop(&mut self) {
        // SAFETY: the handle came from create and is destroyed once.
        unsafe { (self.calls.destroy)(self.handle) };
    }
}

impl DemBackend for AbiBackend {
    fn engine_name(&self) -> &str {
        &self.name
    }

    fn engine_version(&self) -> String {
        self.version.clone()
    }

    fn time_step(&self) -> Real {
        self.info.time_step
    }

    fn time(&self) -> Real {
        self.info.time
    }

    fn step_count(&self) -> u64 {
        self.info.step_count
    }

    fn advance(&mut self, steps: u64) -> Result<(), BackendError> {
        let t0 = std::time::Instant::now();
        // SAFETY: live handle.
        let st = unsafe { (self.calls.advance)(self.handle, steps) };
        self.timer.add("dem_advance", t0.elapsed().as_secs_f64());
        if st == status::NON_FINITE {
            // Keep the engine's own words: they name the step and the grain.
            let message = read_error(self.calls.last_error, self.handle);
            let _ = self.refresh();
            return Err(BackendError::Engine {
                engine: self.name.clone(),
                message,
            });
        }
        self.check(st, "pf_dem_advance")?;
        // Grains past the outlet leave after every advance, as the built-in engine removes
        // them within its steps; the engine counts them in its flow.
        let mut m = 0.0;
        // SAFETY: live handle, valid out-pointer.
        let st = unsafe { (self.calls.remove)(self.handle, &mut m) };
        self.check(st, "pf_dem_remove_past_outlet")?;
        let t1 = std::time::Instant::now();
        let r = self.refresh();
        self.timer.add("dem_read", t1.elapsed().as_secs_f64());
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
        let t0 = std::time::Instant::now();
        let n = force.len();
        self.flat.clear();
        self.flat.extend(force.iter().flatten());
        let r = match implicit {
            None => {
                // SAFETY: flat holds 3 n values.
                let st = unsafe { (self.calls.set_forces)(self.handle, n, self.flat.as_ptr()) };
                self.check(st, "pf_dem_set_fluid_forces")
            }
            Some(d) => {
                let Some(f) = self.calls.set_implicit else {
                    return Err(BackendError::Engine {
                        engine: self.name.clone(),
                        message: "this engine has no implicit drag (pf_dem_set_implicit_drag)"
                            .into(),
                    });
                };
                if d.coefficient.len() != n || d.fluid_velocity.len() != n {
                    return Err(BackendError::InvalidArgument {
                        argument: "implicit drag".into(),
                        reason: format!("{n} forces but {} coefficients", d.coefficient.len()),
                    });
                }
                let u: Vec<f64> = d.fluid_velocity.iter().flatten().copied().collect();
                // SAFETY: all buffers hold n grains.
                let st = unsafe {
                    f(
                        self.handle,
                        n,
                        self.flat.as_ptr(),
                        d.coefficient.as_ptr(),
                        u.as_ptr(),
                    )
                };
                self.check(st, "pf_dem_set_implicit_drag")
            }
        };
        self.timer.add("dem_set_forces", t0.elapsed().as_secs_f64());
        r
    }

    fn insert(&mut self, particles: &[NewParticle]) -> Result<Vec<u64>, BackendError> {
        let n = particles.len();
        let x: Vec<f64> = particles.iter().flat_map(|p| p.position).collect();
        let v: Vec<f64> = particles.iter().flat_map(|p| p.velocity).collect();
        let r: Vec<f64> = particles.iter().map(|p| p.radius).collect();
        let rho: Vec<f64> = particles.iter().map(|p| p.density).collect();
        let mut ids = vec![0u64; n];
        // SAFETY: all buffers hold n grains.
        let st = unsafe {
            (self.calls.insert)(
                self.handle,
                n,
                x.as_ptr(),
                v.as_ptr(),
                r.as_ptr(),
                rho.as_ptr(),
                ids.as_mut_ptr(),
            )
        };
        self.check(st, "pf_dem_insert")?;
        self.refresh()?;
        Ok(ids)
    }

    fn remove_past_outlet(&mut self) -> Result<Real, BackendError> {
        let mut m = 0.0;
        // SAFETY: live handle, valid out-pointer.
        let st = unsafe { (self.calls.remove)(self.handle, &mut m) };
        self.check(st, "pf_dem_remove_past_outlet")?;
        self.refresh()?;
        Ok(m)
    }

    fn wall_forces(&self) -> Vec<WallForce> {
        let n = self.info.wall_count as usize;
        let mut f = vec![0.0; 3 * n];
        // SAFETY: f holds n walls.
        let st = unsafe { (self.calls.walls)(self.handle, n, f.as_mut_ptr()) };
        if st != status::OK {
            return Vec::new();
        }
        (0..n)
            .map(|i| {
                let mut buf = [0 as c_char; 64];
                // SAFETY: buf holds 64 chars.
                unsafe { (self.calls.wall_name)(self.handle, i, buf.as_mut_ptr(), buf.len()) };
                WallForce {
                    wall: c_text(&buf),
                    force: [f[3 * i], f[3 * i + 1], f[3 * i + 2]],
                }
            })
            .collect()
    }

    /// Wall time in the engine's calls, as seen from this side of the ABI.
    fn stage_times(&self) -> Vec<(String, f64)> {
        self.timer.entries()
    }

    fn keep_log(&mut self, dir: &std::path::Path) -> Result<(), BackendError> {
        let Some(f) = self.calls.keep_log else {
            return Ok(()); // an engine of ABI 1.1 or one without a log of its own
        };
        let text = dir.display().to_string();
        // SAFETY: live handle; the pointer and length describe `text`.
        let st = unsafe { f(self.handle, text.as_ptr() as *const c_char, text.len()) };
        self.check(st, "pf_dem_keep_log")
    }

    fn save_state(&mut self) -> Result<Vec<u8>, BackendError> {
        let Some(f) = self.calls.save_state else {
            return Err(self.unsupported("write checkpoints (pf_dem_save_state, ABI 1.3)"));
        };
        let (mut data, mut len) = (std::ptr::null::<u8>(), 0usize);
        // SAFETY: live handle, valid out-pointers.
        let st = unsafe { f(self.handle, &mut data, &mut len) };
        self.check(st, "pf_dem_save_state")?;
        if len == 0 {
            return Ok(Vec::new());
        }
        if data.is_null() {
            return Err(self.error(status::NULL, "pf_dem_save_state"));
        }
        // SAFETY: the engine owns `len` bytes at `data` until the next call on the handle.
        Ok(unsafe { std::slice::from_raw_parts(data, len) }.to_vec())
    }

    fn restore_state(&mut self, state: &[u8]) -> Result<(), BackendError> {
        let Some(f) = self.calls.restore_state else {
            return Err(self.unsupported("resume from checkpoints (pf_dem_restore_state, ABI 1.3)"));
        };
        // SAFETY: live handle; the pointer and length describe `state`.
        let st = unsafe { f(self.handle, state.as_ptr(), state.len()) };
        self.check(st, "pf_dem_restore_state")?;
        self.refresh()
    }

    fn ranks(&self) -> crate::backend::Ranks {
        let Some(f) = self.calls.ranks else {
            return crate::backend::Ranks::SINGLE;
        };
        let (mut rank, mut size) = (0u32, 1u32);
        // SAFETY: live handle, valid out-pointers.
        let st = unsafe { f(self.handle, &mut rank, &mut size) };
        if st != status::OK || size == 0 || rank >= size {
            return crate::backend::Ranks::SINGLE;
        }
        crate::backend::Ranks {
            rank: rank as usize,
            size: size as usize,
        }
    }

    fn all_reduce(&self, data: &mut [f64], op: crate::backend::Reduce) -> Result<(), BackendError> {
        let Some(f) = self.calls.all_reduce else {
            return Ok(()); // one process: the sum over ranks is this rank's
        };
        let op = match op {
            crate::backend::Reduce::Sum => reduce::SUM,
            crate::backend::Reduce::Max => reduce::MAX,
        };
        // SAFETY: live handle; the pointer and length describe `data`.
        let st = unsafe { f(self.handle, data.as_mut_ptr(), data.len(), op) };
        self.check(st, "pf_dem_all_reduce")
    }

    fn flow(&self) -> Option<crate::backend::GrainFlow> {
        AbiBackend::flow(self).map(|f| crate::backend::GrainFlow {
            fed_count: f.fed_count,
            fed_mass: f.fed_mass,
            outflow_count: f.outflow_count,
            outflow_mass: f.outflow_mass,
            lost_count: f.lost_count,
        })
    }
}
