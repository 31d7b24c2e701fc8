//! Room to write: a run stops before its disk (or its file-size limit) is full, not when
//! HDF5 fails part-way through a flush. A flush cut short leaves `run.h5` with a superblock
//! that names more bytes than the file holds, and HDF5 then refuses to open it at all
//! ("truncated file"); stopping while there is room keeps it readable up to the last sample
//! and leaves space for the summary and the figures.

use std::path::{Path, PathBuf};

use super::OutputError;

/// Bytes kept free for the end of a run (summary, figures, the last flush of `run.h5`):
/// the vertical case's summary and figures together are ~0.2 MB.
pub const RESERVE_BYTES: u64 = 1 << 20;

/// Watches the free space beside a growing file.
pub struct RoomGuard {
    file: PathBuf,
    last_size: u64,
    /// The largest growth of the file between two looks, bytes.
    growth: u64,
}

impl RoomGuard {
    pub fn new(file: &Path) -> Self {
        Self {
            file: file.to_path_buf(),
            last_size: size_of(file),
            growth: 0,
        }
    }

    /// Ok while the next sample (as large as the largest so far, twice over) and the reserve
    /// fit both on the disk and under the process's file-size limit (`ulimit -f`).
    pub fn check(&mut self) -> Result<(), OutputError> {
        let size = size_of(&self.file);
        self.growth = self.growth.max(size.saturating_sub(self.last_size));
        self.last_size = size;
        let need = RESERVE_BYTES + 2 * self.growth;
        let dir = self.file.parent().unwrap_or(Path::new("."));
        if let Some(free) = free_bytes(dir) {
            if free < need {
                return Err(OutputError::new(
                    self.file.display(),
                    format!(
                        "the disk is nearly full ({free} bytes free, {need} needed for the next \
                         sample and the end of the run): the run stops here so that the file \
                         stays readable and the summary fits"
                    ),
                ));
            }
        }
        if let Some(limit) = file_size_limit() {
            if size + need > limit {
                return Err(OutputError::new(
                    self.file.display(),
                    format!(
                        "the file would outgrow the file-size limit (ulimit -f: {limit} bytes; it \
                         holds {size}): the run stops here so that it stays readable"
                    ),
                ));
            }
        }
        Ok(())
    }
}

fn size_of(p: &Path) -> u64 {
    std::fs::metadata(p).map_or(0, |m| m.len())
}

/// Bytes an unprivileged writer may still use on the file system holding `dir`.
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut st = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: a NUL-terminated path and a buffer statvfs fills on success.
    let ok = unsafe { libc::statvfs(c.as_ptr(), st.as_mut_ptr()) } == 0;
    ok.then(|| {
        // SAFETY: filled by the successful call above.
        let st = unsafe { st.assume_init() };
        st.f_bavail * st.f_frsize
    })
}

/// The process's file-size limit, bytes (None: unlimited).
fn file_size_limit() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit fills the struct.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_FSIZE, &mut r) } == 0;
    (ok && r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur)
}
