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
