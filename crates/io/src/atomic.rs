//! Atomic file writes, shared by every writer of vgps: a temporary file in the target's
//! directory, flushed to disk, then renamed over the target.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Random characters in a temporary file's name.
const TEMP_RANDOM_CHARS: usize = 8;

/// Writes `bytes` to `path` atomically: the bytes go to a temporary file with an
/// unpredictable name in the same directory (`.NAME.tmp-PID-XXXXXXXX`, created exclusively
/// by `tempfile`), are flushed to disk, the file is renamed over `path`, and the directory is
/// synced so that the rename survives a crash. A reader sees either the old file whole or
/// the new one whole; on failure the temporary file is removed and an existing `path` is
/// left untouched. On Unix the file gets the permissions `File::create` would give it
/// (0o666 less the umask), not the owner-only mode of a temporary file.
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
    // `.NAME.tmp-PID-XXXXXXXX`: which write it was stays visible after a crash, the random
    // part makes the name unpredictable. Dropping `tmp` on an error path removes the file.
    let prefix = format!(".{name}.tmp-{}-", std::process::id());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).rand_bytes(TEMP_RANDOM_CHARS);
    #[cfg(unix)]
    builder.permissions(created_file_permissions());
    let mut tmp = builder.tempfile_in(&dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    sync_dir(&dir)
}

/// The mode an ordinary new file is created with, before the umask: outputs are meant to
/// be read by others (a report served over HTTP, a drive shared with a team).
#[cfg(unix)]
fn created_file_permissions() -> std::fs::Permissions {
    use std::os::unix::fs::PermissionsExt;
    std::fs::Permissions::from_mode(0o666)
}

/// Flushes a directory's entries (the rename) to disk. Not every platform can open a
/// directory for syncing; where it cannot, the rename is still atomic, only its durability
/// is the file system's.
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    match std::fs::File::open(dir) {
        Ok(d) => match d.sync_all() {
            Ok(()) => Ok(()),
            // Some file systems refuse fsync on a directory (EINVAL): nothing more to do.
            Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Ok(()),
            Err(e) => Err(e),
        },
        Err(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::write_atomic;

    fn temp_names(dir: &std::path::Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(".tmp-"))
            .collect()
    }

    #[test]
    fn writes_then_replaces_whole_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fixes.csv");
        write_atomic(&path, b"first version, longer than the second\n").unwrap();
        write_atomic(&path, b"second\n").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second\n");
        assert!(temp_names(dir.path()).is_empty());
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.json");
        write_atomic(&path, b"old").unwrap();
        // A directory in the way of the rename: the persist fails.
        let blocked = dir.path().join("blocked");
        std::fs::create_dir(&blocked).unwrap();
        std::fs::write(blocked.join("inside"), b"x").unwrap();
        assert!(write_atomic(&blocked, b"new").is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(temp_names(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn the_file_has_the_mode_of_an_ordinary_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let atomic = dir.path().join("atomic");
        write_atomic(&atomic, b"x").unwrap();
        let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&atomic), mode(&plain));
    }
}
