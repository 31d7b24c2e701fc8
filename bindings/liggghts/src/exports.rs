//! The ABI calls over [`Liggghts`]. Every body runs behind `catch_unwind`
//! (`abi_export::with_handle`); LIGGGHTS's C++ exceptions stop in shim.cpp.

#![allow(clippy::missing_safety_doc)] // the safety contract is the C header's

use std::cell::RefCell;
use std::ffi::c_char;
use std::panic::catch_unwind;

use plugflow::scene::Scene;
use plugflow_coupling::abi::{self, status, PfDem, PfDemFlow, PfDemInfo};
use plugflow_coupling::abi_export::{
    self, copy_text, fill, input, panic_text, triples, ExportedEngine, Failure,
};

use crate::engine::Liggghts;

struct Handle {
    engine: Liggghts,
    last_error: String,
}

impl ExportedEngine for Handle {
    fn last_error_mut(&mut self) -> &mut String {
        &mut self.last_error
    }
    fn last_error(&self) -> &str {
        &self.last_error
    }
}

thread_local! {
    static CREATE_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

fn engine_failure(m: String) -> Failure {
    if m.starts_with("non-finite") {
        (status::NON_FINITE, m)
    } else {
        (status::ENGINE, m)
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

fn build(json: &str) -> Result<Liggghts, String> {
    let value: toml::Value = serde_json::from_str(json).map_err(|e| format!("scene JSON: {e}"))?;
    let text = toml::to_string(&value).map_err(|e| format!("scene JSON: {e}"))?;
    let scene = Scene::parse(&text, &[]).map_err(|e| e.to_string())?;
    Liggghts::new(&scene)
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
        Ok(Ok(engine)) => {
            let h = Box::new(Handle {
                engine,
                last_error: String::new(),
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
        let e = &h.engine;
        let mut i = PfDemInfo {
            time_step: e.cfg.dt,
            time: e.time,
            step_count: e.steps,
            particle_count: e.ids.len() as u64,
            wall_count: e.mapped.walls.len() as u64,
            ..PfDemInfo::default()
        };
        fill(&mut i.name, "liggghts");
        fill(&mut i.version, &e.version);
        *info = i;
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_advance(dem: *mut PfDem, steps: u64) -> i32 {
    with_handle(dem, |h| h.engine.advance(steps).map_err(engine_failure))
}

unsafe fn write_rows(dst: *mut f64, src: &[[f64; 3]]) {
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
        let e = &h.engine;
        if capacity < e.ids.len() {
            return Err((
                status::BUFFER_TOO_SMALL,
                format!("capacity {capacity} < {} grains", e.ids.len()),
            ));
        }
        write_slice(id, &e.ids);
        write_rows(x, &e.x);
        write_rows(v, &e.v);
        write_rows(omega, &e.omega);
        write_slice(radius, &e.radius);
        write_slice(mass, &e.mass);
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
        if let Some(i) = f.iter().position(|v| v.iter().any(|c| !c.is_finite())) {
            return Err((
                status::NON_FINITE,
                format!(
                    "fluid force on particle id {} is {:?}",
                    h.engine.ids[i], f[i]
                ),
            ));
        }
        h.engine
            .set_fluid(&f)
            .map_err(|m| (status::INVALID_ARGUMENT, m))
    })
}

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
        let x = triples(input(x, 3 * n, "x")?);
        let v = triples(input(v, 3 * n, "v")?);
        let r = input(radius, n, "radius")?;
        let rho = input(density, n, "density")?;
        let ids = h
            .engine
            .insert(&x, &v, r, rho)
            .map_err(|m| (status::INVALID_ARGUMENT, m))?;
        write_slice(ids_out, &ids);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn pf_dem_remove_past_outlet(dem: *mut PfDem, removed_mass: *mut f64) -> i32 {
    with_handle(dem, |h| {
        let m = h.engine.remove_past_outlet().map_err(engine_failure)?;
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
        let w = h.engine.wall_forces().map_err(engine_failure)?;
        if capacity < w.len() {
            return Err((
                status::BUFFER_TOO_SMALL,
                format!("capacity {capacity} < {} walls", w.len()),
            ));
        }
        if force.is_null() {
            return Err((status::NULL, "`force` is NULL".into()));
        }
        write_rows(force, &w);
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
        let walls = &h.engine.mapped.walls;
        let (name, _) = walls.get(index).ok_or_else(|| {
            (
                status::INVALID_ARGUMENT,
                format!("wall index {index} ≥ {} walls", walls.len()),
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
        *flow = h.engine.flow;
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
