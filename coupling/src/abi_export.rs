//! Helpers for libraries that export the DEM ABI from Rust (bindings/native,
//! bindings/liggghts): the panic guard that every exported body runs in, last-error
//! bookkeeping, and checked views of C buffers.

use std::ffi::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::abi::{status, PfDem};
use crate::backend::BackendError;

/// A status code and the message `pf_dem_last_error` will return.
pub type Failure = (i32, String);

/// An engine handle that remembers its last error.
pub trait ExportedEngine {
    /// Where the last error message goes.
    fn last_error_mut(&mut self) -> &mut String;
    /// The last error message.
    fn last_error(&self) -> &str;
}

/// The status and message of a backend error.
pub fn backend_failure(e: BackendError) -> Failure {
    let code = match &e {
        BackendError::NonFinite { .. } => status::NON_FINITE,
        BackendError::InvalidArgument { .. } => status::INVALID_ARGUMENT,
        BackendError::Engine { .. } => status::ENGINE,
    };
    (code, e.to_string())
}

/// The text of a caught panic.
pub fn panic_text(p: Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Run `body` on the engine behind `dem` (a `Box<H>` turned into a handle), catching
/// panics and recording errors.
///
/// # Safety
/// `dem` is NULL or a handle made from a `Box<H>` by the same library.
pub unsafe fn with_handle<H: ExportedEngine>(
    dem: *const PfDem,
    body: impl FnOnce(&mut H) -> Result<(), Failure>,
) -> i32 {
    if dem.is_null() {
        return status::NULL;
    }
    let h = &mut *(dem as *mut H);
    match catch_unwind(AssertUnwindSafe(|| body(h))) {
        Ok(Ok(())) => status::OK,
        Ok(Err((code, msg))) => {
            *h.last_error_mut() = msg;
            code
        }
        Err(p) => {
            *h.last_error_mut() = format!("internal error: {}", panic_text(p));
            status::PANIC
        }
    }
}

/// A slice from a C pointer of `n` values, or a NULL error naming the argument.
///
/// # Safety
/// A non-NULL `p` points to `n` readable values.
pub unsafe fn input<'a, T>(p: *const T, n: usize, name: &str) -> Result<&'a [T], Failure> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err((status::NULL, format!("`{name}` is NULL")));
    }
    Ok(std::slice::from_raw_parts(p, n))
}

/// Copy text into a C buffer of `len` chars, NUL-terminated and truncated.
///
/// # Safety
/// A non-NULL `buf` holds `len` writable chars.
pub unsafe fn copy_text(text: &str, buf: *mut c_char, len: usize) {
    if buf.is_null() || len == 0 {
        return;
    }
    let bytes = text.as_bytes();
    let n = bytes.len().min(len - 1);
    std::ptr::copy_nonoverlapping(bytes.as_ptr() as *const c_char, buf, n);
    *buf.add(n) = 0;
}

/// Fill a fixed C char array (NUL-terminated, truncated).
pub fn fill(dst: &mut [c_char], text: &str) {
    let room = dst.len().saturating_sub(1);
    for (d, b) in dst.iter_mut().zip(text.bytes().take(room)) {
        *d = b as c_char;
    }
}

/// The message for `pf_dem_last_error`: the handle's, or with NULL the thread's last
/// failed create.
///
/// # Safety
/// `dem` is NULL or a live handle made from a `Box<H>`.
pub unsafe fn last_error<H: ExportedEngine>(
    dem: *const PfDem,
    create_error: &str,
    buf: *mut c_char,
    len: usize,
) -> usize {
    let text = if dem.is_null() {
        create_error.to_string()
    } else {
        (*(dem as *const H)).last_error().to_string()
    };
    copy_text(&text, buf, len);
    text.len()
}

/// Triples of an interleaved x, y, z buffer.
pub fn triples(flat: &[f64]) -> Vec<[f64; 3]> {
    flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Export the whole DEM ABI (`bindings/include/plugflow_dem.h`) from a crate, over any
/// engine implementing [`crate::DemBackend`]: `export_dem_abi!(build, check)` with
/// `fn build(scene_json: &str) -> Result<Box<dyn DemBackend>, String>` and `fn check(scene_json:
/// &str) -> Result<(), String>` (the engine's refusals without starting it). Every body runs
/// behind `catch_unwind`; errors become status codes and `pf_dem_last_error` text. The
/// exports are checked at compile time against the loader's pointer types.
#[macro_export]
macro_rules! export_dem_abi {
    ($build:ident, $check:ident) => {
        mod __pf_dem_abi {
            #![allow(clippy::missing_safety_doc)] // the safety contract is the C header's

            use std::cell::RefCell;
            use std::ffi::c_char;
            use std::panic::catch_unwind;

            use $crate::abi::{self, status, PfDem, PfDemFlow, PfDemInfo};
            use $crate::abi_export::{
                self, backend_failure, copy_text, fill, input, panic_text, triples, ExportedEngine,
                Failure,
            };
            use $crate::{DemBackend, NewParticle, Vec3};

            struct Handle {
                engine: Box<dyn DemBackend>,
                last_error: String,
                /// The bytes of the last pf_dem_save_state (the caller reads them before
                /// its next call).
                saved: Vec<u8>,
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
                /// Why the last pf_dem_create on this thread failed.
                static CREATE_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
            }

            unsafe fn with_handle(
                dem: *const PfDem,
                body: impl FnOnce(&mut Handle) -> Result<(), Failure>,
            ) -> i32 {
                abi_export::with_handle::<Handle>(dem, body)
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
            pub extern "C" fn pf_dem_abi_version() -> u32 {
                abi::ABI_VERSION
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
                match catch_unwind(|| super::$build(json)) {
                    Ok(Ok(engine)) => {
                        let h = Box::new(Handle {
                            engine,
                            last_error: String::new(),
                            saved: Vec::new(),
                        });
                        *out = Box::into_raw(h) as *mut PfDem;
                        status::OK
                    }
                    Ok(Err(msg)) => fail(status::SCENE, msg),
                    Err(p) => fail(status::PANIC, format!("internal error: {}", panic_text(p))),
                }
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_check(scene_json: *const c_char, len: usize) -> i32 {
                let fail = |code: i32, msg: String| {
                    CREATE_ERROR.with(|e| *e.borrow_mut() = msg);
                    code
                };
                if scene_json.is_null() {
                    return fail(status::NULL, "`scene_json` is NULL".into());
                }
                let bytes = std::slice::from_raw_parts(scene_json as *const u8, len);
                let Ok(json) = std::str::from_utf8(bytes) else {
                    return fail(status::SCENE, "scene JSON is not UTF-8".into());
                };
                match catch_unwind(|| super::$check(json)) {
                    Ok(Ok(())) => status::OK,
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
            pub unsafe extern "C" fn pf_dem_info_get(
                dem: *const PfDem,
                info: *mut PfDemInfo,
            ) -> i32 {
                with_handle(dem, |h| {
                    if info.is_null() {
                        return Err((status::NULL, "`info` is NULL".into()));
                    }
                    let e = &h.engine;
                    let mut i = PfDemInfo {
                        time_step: e.time_step(),
                        time: e.time(),
                        step_count: e.step_count(),
                        particle_count: e.particles().len() as u64,
                        wall_count: e.wall_forces().len() as u64,
                        ..PfDemInfo::default()
                    };
                    fill(&mut i.name, e.engine_name());
                    fill(&mut i.version, &e.engine_version());
                    *info = i;
                    Ok(())
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_advance(dem: *mut PfDem, steps: u64) -> i32 {
                with_handle(dem, |h| h.engine.advance(steps).map_err(backend_failure))
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
                    let p = h.engine.particles();
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
                    h.engine.set_fluid_forces(&f, None).map_err(backend_failure)
                })
            }

            // pf_dem_set_implicit_drag (optional) is not exported: these engines take the
            // drag as an explicit force, and a loader binds the call only where it exists.

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
                    let ids = h.engine.insert(&grains).map_err(backend_failure)?;
                    write_slice(ids_out, &ids);
                    Ok(())
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_remove_past_outlet(
                dem: *mut PfDem,
                removed_mass: *mut f64,
            ) -> i32 {
                with_handle(dem, |h| {
                    let m = h.engine.remove_past_outlet().map_err(backend_failure)?;
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
                    let w = h.engine.wall_forces();
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
                    let w = h.engine.wall_forces();
                    let wall = w.get(index).ok_or_else(|| {
                        (
                            status::INVALID_ARGUMENT,
                            format!("wall index {index} ≥ {} walls", w.len()),
                        )
                    })?;
                    copy_text(&wall.wall, buf, len);
                    Ok(())
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_flow_get(
                dem: *const PfDem,
                flow: *mut PfDemFlow,
            ) -> i32 {
                with_handle(dem, |h| {
                    if flow.is_null() {
                        return Err((status::NULL, "`flow` is NULL".into()));
                    }
                    let f = h.engine.flow().ok_or_else(|| {
                        (
                            status::UNSUPPORTED,
                            "this engine keeps no feed/outflow counters".to_string(),
                        )
                    })?;
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

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_keep_log(
                dem: *mut PfDem,
                dir: *const c_char,
                len: usize,
            ) -> i32 {
                with_handle(dem, |h| {
                    if dir.is_null() {
                        return Err((status::NULL, "`dir` is NULL".into()));
                    }
                    // SAFETY: the caller passes `len` readable bytes.
                    let bytes = std::slice::from_raw_parts(dir as *const u8, len);
                    let dir = std::str::from_utf8(bytes).map_err(|e| {
                        (status::INVALID_ARGUMENT, format!("`dir` is not UTF-8: {e}"))
                    })?;
                    h.engine
                        .keep_log(std::path::Path::new(dir))
                        .map_err(backend_failure)
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_save_state(
                dem: *mut PfDem,
                data: *mut *const u8,
                len: *mut usize,
            ) -> i32 {
                with_handle(dem, |h| {
                    if data.is_null() || len.is_null() {
                        return Err((status::NULL, "`data` or `len` is NULL".into()));
                    }
                    h.saved = h.engine.save_state().map_err(backend_failure)?;
                    *data = h.saved.as_ptr();
                    *len = h.saved.len();
                    Ok(())
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_restore_state(
                dem: *mut PfDem,
                data: *const u8,
                len: usize,
            ) -> i32 {
                with_handle(dem, |h| {
                    let bytes = input(data, len, "data")?;
                    h.engine.restore_state(bytes).map_err(backend_failure)
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_ranks(
                dem: *const PfDem,
                rank: *mut u32,
                size: *mut u32,
            ) -> i32 {
                with_handle(dem, |h| {
                    if rank.is_null() || size.is_null() {
                        return Err((status::NULL, "`rank` or `size` is NULL".into()));
                    }
                    let r = h.engine.ranks();
                    *rank = r.rank as u32;
                    *size = r.size as u32;
                    Ok(())
                })
            }

            #[no_mangle]
            pub unsafe extern "C" fn pf_dem_all_reduce(
                dem: *const PfDem,
                data: *mut f64,
                n: usize,
                op: i32,
            ) -> i32 {
                with_handle(dem, |h| {
                    if data.is_null() && n > 0 {
                        return Err((status::NULL, "`data` is NULL".into()));
                    }
                    let op = match op {
                        abi::reduce::SUM => $crate::Reduce::Sum,
                        abi::reduce::MAX => $crate::Reduce::Max,
                        other => {
                            return Err((
                                status::INVALID_ARGUMENT,
                                format!("`op` {other} is neither PF_REDUCE_SUM nor PF_REDUCE_MAX"),
                            ))
                        }
                    };
                    if n == 0 {
                        return h.engine.all_reduce(&mut [], op).map_err(backend_failure);
                    }
                    // SAFETY: the caller passes n writable doubles.
                    let data = std::slice::from_raw_parts_mut(data, n);
                    h.engine.all_reduce(data, op).map_err(backend_failure)
                })
            }

            /// The exports have exactly the loader's pointer types.
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
                let _: abi::KeepLogFn = pf_dem_keep_log;
                let _: abi::SaveStateFn = pf_dem_save_state;
                let _: abi::RestoreStateFn = pf_dem_restore_state;
                let _: abi::CheckFn = pf_dem_check;
                let _: abi::RanksFn = pf_dem_ranks;
                let _: abi::AllReduceFn = pf_dem_all_reduce;
            };
        }
    };
}
