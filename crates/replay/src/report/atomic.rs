//! Atomic file writes of the report: [`vgps_io::write_atomic`] with a [`ReportError`].

use super::ReportError;
use std::path::Path;

/// Writes `bytes` to `path` atomically: the bytes go to a hidden temporary file in the same
/// directory (`.NAME.tmp-PID-XXXXXXXX`), are flushed to disk, and the file is renamed over `path`.
/// A reader sees either the old file whole or the new one whole; on failure the temporary
/// file is removed and an existing `path` is left untouched.
///
/// # Errors
/// [`ReportError::Io`] naming `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    vgps_io::write_atomic(path, bytes).map_err(|e| ReportError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}
