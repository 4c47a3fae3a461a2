//! Atomic file writes, shared by every writer of vgps: a temporary file in the target's
//! directory, flushed to disk, then renamed over the target.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes the temporary files of concurrent writes within one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: the bytes go to a hidden temporary file in the same
/// directory (`.NAME.tmp-PID-N`), are flushed to disk, and the file is renamed over `path`.
/// A reader sees either the old file whole or the new one whole; on failure the temporary
/// file is removed and an existing `path` is left untouched.
///
/// # Errors
/// The I/O error of the failed step (`InvalidInput` when `path` has no file name). Callers
/// wrap it in their module's error, naming `path`.
///
/// # Example
/// ```
/// let dir = std::env::temp_dir().join(format!("vgps-atomic-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("fixes.csv");
/// vgps_io::write_atomic(&path, b"frame,status\n0,ok\n").unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"frame,status\n0,ok\n");
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name"))?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.tmp-{}-{n}", std::process::id()));
    let result = std::fs::File::create(&tmp)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            f.sync_all()
        })
        .and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
