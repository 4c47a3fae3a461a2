//! Detection of a calibration file's format from its content.

use super::{Format, LoadError};
use std::io::Read;
use std::path::Path;

/// How many bytes of a file are looked at.
pub const DETECT_BYTES: u64 = 64 * 1024;

/// The format of `path`:
/// - a directory holding `K_cam0.csv` → [`Format::Nclt`];
/// - a file whose first non-blank character is `{` → [`Format::Native`];
/// - a file beginning with `Version "Ladybug` → [`Format::LadybugConf`];
/// - a file with a `camera0_…` or `image_width` key before an `=` → [`Format::LadybugIni`];
/// - otherwise, by extension: `.json` → native, `.ini` → Ladybug INI.
///
/// # Errors
/// [`LoadError::Io`] when the path cannot be read, [`LoadError::UnknownFormat`] when none
/// of the rules applies.
///
/// # Example
/// ```
/// use vgps_camera::calibration::{Format, formats::detect::detect};
/// let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../calibration/");
/// assert_eq!(detect(format!("{dir}ladybug2.json").as_ref())?, Format::Native);
/// assert_eq!(detect(format!("{dir}ladybug5_example.ini").as_ref())?, Format::LadybugIni);
/// assert_eq!(detect(format!("{dir}nclt_example").as_ref())?, Format::Nclt);
/// # Ok::<(), vgps_camera::calibration::LoadError>(())
/// ```
pub fn detect(path: &Path) -> Result<Format, LoadError> {
    let unknown = |reason: &str| LoadError::UnknownFormat {
        path: path.display().to_string(),
        reason: reason.to_string(),
    };
    let meta = std::fs::metadata(path).map_err(|e| LoadError::io(path, &e))?;
    if meta.is_dir() {
        return if path.join("K_cam0.csv").is_file() {
            Ok(Format::Nclt)
        } else {
            Err(unknown("a directory without K_cam0.csv"))
        };
    }
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(DETECT_BYTES).read_to_end(&mut head))
        .map_err(|e| LoadError::io(path, &e))?;
    let text = String::from_utf8_lossy(&head);
    let text = text.trim_start_matches('\u{feff}');
    if text.trim_start().starts_with('{') {
        return Ok(Format::Native);
    }
    if text.trim_start().starts_with("Version \"Ladybug") {
        return Ok(Format::LadybugConf);
    }
    let ini = text.lines().any(|l| {
        l.split_once('=').is_some_and(|(k, _)| {
            let k = k.trim();
            k.starts_with("camera0_") || k == "image_width"
        })
    });
    if ini {
        return Ok(Format::LadybugIni);
    }
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("json") => Ok(Format::Native),
        Some(e) if e.eq_ignore_ascii_case("ini") => Ok(Format::LadybugIni),
        Some(e) if e.eq_ignore_ascii_case("conf") => Ok(Format::LadybugConf),
        _ => Err(unknown(
            "neither JSON, nor `cameraN_…` INI keys, nor an NCLT directory",
        )),
    }
}
