//! The built-in DEM behind the plugflow DEM C ABI (`bindings/include/plugflow_dem.h`), as a
//! shared library `libplugflow_dem_native.so`. It exists so that the ABI path itself is
//! tested with no external code: a scene run native-direct and native-through-ABI must
//! agree bit for bit.
//!
//! Every exported body runs inside `catch_unwind`: a panic becomes `PF_ERR_PANIC` and a
//! message in `pf_dem_last_error`, never an unwind across C.

#![allow(clippy::missing_safety_doc)] // the safety contract is the C header's

use std::cell::RefCell;
use std::ffi::c_char;
use std::panic::catch_unwind;

use plugflow::dem::{DemConfig, NativeDem};
use plugflow::scene::Scene;
use plugflow_coupling::abi::{self, status, PfDem, PfDemFlow, PfDemInfo};
use plugflow_coupling::abi_export::{
    self, backend_failure, copy_text, fill, input, panic_text, triples, ExportedEngine, Failure,
};
use plugflow_coupling::{DemBackend, NewParticle, Vec3};

/// The engine and its last error.
pub struct Handle {
    dem: NativeDem,
    last_error: String,
    wall_names: Vec<String>,
}

thread_local! {
    /// Why the last pf_dem_create on this thread failed.
    static CREATE_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

impl ExportedEngine for Handle {
    fn last_error_mut(&mut self) -> &mut String {
        &mut self.last_error
    }
    fn last_error(&self) -> &str {
        &self.last_error
    }
}

unsafe fn with_handle(
    dem: *const PfDem,
    body: impl FnOnce(&mut Handle) -> Result<(), Failure>,
) -> i32 {
    abi_export::with_handle::<Handle>(dem, body)
}

#[no_mangle]
pub extern "C" fn pf_dem_abi_version() -> u32 {
    abi::ABI_VERSION
}

fn build(json: &str) -> Result<NativeDem, String> {
    let value: toml::Value = serde_json::from_str(json).map_err(|e| format!("scene JSON: {e}"))?;
    let text = toml::to_string(&value).map_err(|e| format!("scene JSON: {e}"))?;
    let scene = Scene::parse(&text, &[]).map_err(|e| e.to_string())?;
    let cfg = DemConfig::from_scene(&scene).map_err(|e| e.to_string())?;
    NativeDem::new(cfg).map_err(|e| e.to_string())
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_create(
    scene_json: *const c_char,
    len: usize,
    out: *mut *mut PfDem,
) -> i32 {
    let fail = |code: i32, msg: String| {
        CREATE_ERROR.with(|e| *e.borrow_mut() = msg);
        code
    };
    if out.is_null() {
        return fail(status::NULL, "`out` is NULL".into());
    }
    *out = std::ptr::null_mut();
    if scene_json.is_null() {
        return fail(status::NULL, "`scene_json` is NULL".into());
    }
    let bytes = std::slice::from_raw_parts(scene_json as *const u8, len);
    let Ok(json) = std::str::from_utf8(bytes) else {
        return fail(status::SCENE, "scene JSON is not UTF-8".into());
    };
    match catch_unwind(|| build(json)) {
        Ok(Ok(dem)) => {
            let wall_names = dem.wall_forces().into_iter().map(|w| w.wall).collect();
            let h = Box::new(Handle {
                dem,
                last_error: String::new(),
                wall_names,
            });
            *out = Box::into_raw(h) as *mut PfDem;
            status::OK
        }
        Ok(Err(msg)) => fail(status::SCENE, msg),
        Err(p) => fail(status::PANIC, format!("internal error: {}", panic_text(p))),
    }
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_destroy(dem: *mut PfDem) {
    if !dem.is_null() {
        let _ = catch_unwind(|| drop(Box::from_raw(dem as *mut Handle)));
    }
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_last_error(
    dem: *const PfDem,
    buf: *mut c_char,
    len: usize,
) -> usize {
    let create = CREATE_ERROR.with(|e| e.borrow().clone());
    abi_export::last_error::<Handle>(dem, &create, buf, len)
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_info_get(dem: *const PfDem, info: *mut PfDemInfo) -> i32 {
    with_handle(dem, |h| {
        if info.is_null() {
            return Err((status::NULL, "`info` is NULL".into()));
        }
        let mut i = PfDemInfo {
            time_step: h.dem.time_step(),
            time: h.dem.time(),
            step_count: h.dem.step_count(),
            particle_count: h.dem.state.len() as u64,
            wall_count: h.wall_names.len() as u64,
            ..PfDemInfo::default()
        };
        fill(&mut i.name, h.dem.engine_name());
        fill(&mut i.version, &h.dem.engine_version());
        *info = i;
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_advance(dem: *mut PfDem, steps: u64) -> i32 {
    with_handle(dem, |h| h.dem.advance(steps).map_err(backend_failure))
}

unsafe fn write_vec3(dst: *mut f64, src: &[Vec3]) {
    if !dst.is_null() {
        for (i, v) in src.iter().enumerate() {
            std::ptr::copy_nonoverlapping(v.as_ptr(), dst.add(3 * i), 3);
        }
    }
}

unsafe fn write_slice<T: Copy>(dst: *mut T, src: &[T]) {
    if !dst.is_null() {
        std::ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len());
    }
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_read_particles(
    dem: *const PfDem,
    capacity: usize,
    id: *mut u64,
    x: *mut f64,
    v: *mut f64,
    omega: *mut f64,
    radius: *mut f64,
    mass: *mut f64,
) -> i32 {
    with_handle(dem, |h| {
        let p = h.dem.particles();
        if capacity < p.len() {
            return Err((
                status::BUFFER_TOO_SMALL,
                format!("capacity {capacity} < {} grains", p.len()),
            ));
        }
        write_slice(id, p.id);
        write_vec3(x, p.position);
        write_vec3(v, p.velocity);
        write_vec3(omega, p.angular_velocity);
        write_slice(radius, p.radius);
        write_slice(mass, p.mass);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_set_fluid_forces(
    dem: *mut PfDem,
    n: usize,
    force: *const f64,
) -> i32 {
    with_handle(dem, |h| {
        let f = triples(input(force, 3 * n, "force")?);
        h.dem.set_fluid_forces(&f, None).map_err(backend_failure)
    })
}

// pf_dem_set_implicit_drag (optional) is not exported: the built-in engine takes the drag
// as an explicit force, and a loader binds the call only where it exists.

#[no_mangle]
pub unsafe extern "C" fn pf_dem_insert(
    dem: *mut PfDem,
    n: usize,
    x: *const f64,
    v: *const f64,
    radius: *const f64,
    density: *const f64,
    ids_out: *mut u64,
) -> i32 {
    with_handle(dem, |h| {
        let x = input(x, 3 * n, "x")?;
        let v = input(v, 3 * n, "v")?;
        let r = input(radius, n, "radius")?;
        let rho = input(density, n, "density")?;
        let grains: Vec<NewParticle> = (0..n)
            .map(|i| NewParticle {
                position: [x[3 * i], x[3 * i + 1], x[3 * i + 2]],
                velocity: [v[3 * i], v[3 * i + 1], v[3 * i + 2]],
                radius: r[i],
                density: rho[i],
            })
            .collect();
        let ids = h.dem.insert(&grains).map_err(backend_failure)?;
        write_slice(ids_out, &ids);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_remove_past_outlet(dem: *mut PfDem, removed_mass: *mut f64) -> i32 {
    with_handle(dem, |h| {
        let m = h.dem.remove_past_outlet().map_err(backend_failure)?;
        if !removed_mass.is_null() {
            *removed_mass = m;
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_read_wall_forces(
    dem: *const PfDem,
    capacity: usize,
    force: *mut f64,
) -> i32 {
    with_handle(dem, |h| {
        let w = h.dem.wall_forces();
        if capacity < w.len() {
            return Err((
                status::BUFFER_TOO_SMALL,
                format!("capacity {capacity} < {} walls", w.len()),
            ));
        }
        if force.is_null() {
            return Err((status::NULL, "`force` is NULL".into()));
        }
        let f: Vec<Vec3> = w.iter().map(|w| w.force).collect();
        write_vec3(force, &f);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_wall_name(
    dem: *const PfDem,
    index: usize,
    buf: *mut c_char,
    len: usize,
) -> i32 {
    with_handle(dem, |h| {
        let name = h.wall_names.get(index).ok_or_else(|| {
            (
                status::INVALID_ARGUMENT,
                format!("wall index {index} ≥ {} walls", h.wall_names.len()),
            )
        })?;
        copy_text(name, buf, len);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_flow_get(dem: *const PfDem, flow: *mut PfDemFlow) -> i32 {
    with_handle(dem, |h| {
        if flow.is_null() {
            return Err((status::NULL, "`flow` is NULL".into()));
        }
        let f = &h.dem.flow;
        *flow = PfDemFlow {
            fed_count: f.fed_count,
            fed_mass: f.fed_mass,
            outflow_count: f.outflow_count,
            outflow_mass: f.outflow_mass,
            lost_count: f.lost_count,
        };
        Ok(())
    })
}

/// The exports have exactly the loader's pointer types (checked when this crate compiles).
const _: () = {
    let _: abi::AbiVersionFn = pf_dem_abi_version;
    let _: abi::CreateFn = pf_dem_create;
    let _: abi::DestroyFn = pf_dem_destroy;
    let _: abi::LastErrorFn = pf_dem_last_error;
    let _: abi::InfoGetFn = pf_dem_info_get;
    let _: abi::AdvanceFn = pf_dem_advance;
    let _: abi::ReadParticlesFn = pf_dem_read_particles;
    let _: abi::SetFluidForcesFn = pf_dem_set_fluid_forces;
    let _: abi::InsertFn = pf_dem_insert;
    let _: abi::RemovePastOutletFn = pf_dem_remove_past_outlet;
    let _: abi::ReadWallForcesFn = pf_dem_read_wall_forces;
    let _: abi::WallNameFn = pf_dem_wall_name;
    let _: abi::FlowGetFn = pf_dem_flow_get;
};
