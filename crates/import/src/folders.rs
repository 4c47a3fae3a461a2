//! Folders of timestamped images (one per camera, as Ladybug export tools and dataset
//! layouts such as NCLT's `lb3/Cam0…Cam5` write them) into a drive.
//!
//! # Cameras
//! Every sub-folder of the root whose name holds a number is a camera, the last number of
//! its name the camera index (`Cam0`, `cam_3`, `camera5`); other entries are ignored.
//!
//! # Times
//! A folder with a `times.csv` (`file,time_s`: the image's file name and its Unix time in
//! seconds) takes its times from it; otherwise each image's time is the last number in its
//! file name: with a decimal point, seconds (`1352589620.125.jpg`); an integer of up to 11
//! digits is seconds, 12–14 milliseconds, 15–17 microseconds (NCLT's `utime`), 18–19
//! nanoseconds. Images are `.png`, `.jpg`/`.jpeg`, `.tif`/`.tiff` or `.bmp`; an image
//! without a usable time is skipped with a warning. Frames are assembled by stamp
//! ([`crate::drive_out::assemble_frames`]); images are referenced by their absolute paths, not copied.

use crate::drive_out::{ImportError, ImportReport, StampedImage};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use vgps_replay::drive::MAX_IMAGE_COLUMNS;

/// The side file of a camera folder giving each image's time.
pub const TIMES_FILE: &str = "times.csv";
/// Image file extensions read (lower case).
pub const IMAGE_EXTENSIONS: [&str; 6] = ["png", "jpg", "jpeg", "tif", "tiff", "bmp"];

/// The time in nanoseconds of an image from its file name (see the module documentation).
///
/// # Example
/// ```
/// use vgps_import::folders::time_ns_of_name;
/// assert_eq!(time_ns_of_name("1326030975726043.tiff"), Some(1_326_030_975_726_043_000));
/// assert_eq!(time_ns_of_name("cam0_1352589620.125.jpg"), Some(1_352_589_620_125_000_000));
/// assert_eq!(time_ns_of_name("frame.png"), None);
/// assert_eq!(time_ns_of_name("prise_à_1352589620.5.jpg"), Some(1_352_589_620_500_000_000));
/// ```
pub fn time_ns_of_name(name: &str) -> Option<i64> {
    let stem = name.rsplit_once('.').map_or(name, |(s, _)| s);
    let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
    // The start of the run of digits and dots ending at `end` (a byte index on a character
    // boundary whatever precedes the run).
    let start = stem[..end]
        .trim_end_matches(|c: char| c.is_ascii_digit() || c == '.')
        .len();
    let number = stem[start..end].trim_start_matches('.');
    if let Some((int, frac)) = number.split_once('.') {
        if frac.contains('.') || int.is_empty() || frac.len() > 9 {
            return None;
        }
        let sec: i64 = int.parse().ok()?;
        let frac_ns: i64 = format!("{frac:0<9}").parse().ok()?;
        return sec.checked_mul(1_000_000_000)?.checked_add(frac_ns);
    }
    let value: i64 = number.parse().ok()?;
    let scale = match number.trim_start_matches('0').len() {
        0..=11 => 1_000_000_000,
        12..=14 => 1_000_000,
        15..=17 => 1_000,
        18..=19 => 1,
        _ => return None,
    };
    value.checked_mul(scale)
}

fn read_dir(dir: &Path) -> Result<Vec<PathBuf>, ImportError> {
    let entries = std::fs::read_dir(dir).map_err(|source| ImportError::Read {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut out: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    out.sort();
    Ok(out)
}

/// The camera folders of `root`: (camera index, folder), by index.
///
/// # Errors
/// [`ImportError`] when `root` cannot be read, has no camera folder, or two folders give
/// the same index.
pub fn camera_folders(root: &Path) -> Result<Vec<(usize, PathBuf)>, ImportError> {
    let mut out: Vec<(usize, PathBuf)> = Vec::new();
    for path in read_dir(root)? {
        if !path.is_dir() {
            continue;
        }
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let Some(camera) = name
            .as_deref()
            .and_then(crate::mcap_import::camera_of_topic)
        else {
            continue;
        };
        if camera >= MAX_IMAGE_COLUMNS {
            return Err(ImportError::Input(format!(
                "{}: camera {camera} is beyond the {MAX_IMAGE_COLUMNS} cameras a drive holds",
                path.display()
            )));
        }
        if let Some((_, other)) = out.iter().find(|(c, _)| *c == camera) {
            return Err(ImportError::Input(format!(
                "{} and {} are both camera {camera}",
                other.display(),
                path.display()
            )));
        }
        out.push((camera, path));
    }
    if out.is_empty() {
        return Err(ImportError::Input(format!(
            "{}: no camera folder (a sub-folder whose name holds the camera number, e.g. cam0)",
            root.display()
        )));
    }
    out.sort();
    Ok(out)
}

/// Reads a `times.csv` (`file,time_s`).
fn read_times(path: &Path, report: &mut ImportReport) -> Result<HashMap<String, i64>, ImportError> {
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(times_from_str(&text, path, report))
}

/// The times of a `times.csv` (`file,time_s`, an optional header; time in seconds) from its
/// text: file name → time in nanoseconds. A bad row is skipped and counted in `report`, with
/// a warning naming `path` and the line.
///
/// # Example
/// ```
/// use std::path::Path;
/// use vgps_import::{drive_out::ImportReport, folders::times_from_str};
/// let mut report = ImportReport::default();
/// let times = times_from_str("file,time_s\na.jpg,12.5\nb.jpg,soon\n", Path::new("times.csv"), &mut report);
/// assert_eq!(times["a.jpg"], 12_500_000_000);
/// assert_eq!(report.skipped, 1);
/// ```
pub fn times_from_str(text: &str, path: &Path, report: &mut ImportReport) -> HashMap<String, i64> {
    let mut out = HashMap::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || (n == 0 && line.replace(' ', "") == "file,time_s") {
            continue;
        }
        let parsed = line.split_once(',').and_then(|(file, t)| {
            let ns = time_ns_of_name(&format!("{}.x", t.trim()))
                .filter(|_| t.trim().chars().all(|c| c.is_ascii_digit() || c == '.'))
                .filter(|_| t.contains('.') || t.trim().len() <= 11)?;
            Some((file.trim().to_string(), ns))
        });
        match parsed {
            Some((file, ns)) => {
                out.insert(file, ns);
            }
            None => {
                report.skipped += 1;
                report.warn(format!(
                    "{}:{}: expected `file,time_s` (time in seconds); skipped",
                    path.display(),
                    n + 1
                ));
            }
        }
    }
    out
}

/// The stamped images of the camera folders of `root`.
///
/// # Errors
/// [`ImportError`] when a folder cannot be read (see [`camera_folders`]).
pub fn scan_folders(
    root: &Path,
    report: &mut ImportReport,
) -> Result<Vec<StampedImage>, ImportError> {
    let mut images = Vec::new();
    for (camera, dir) in camera_folders(root)? {
        let dir = dir.canonicalize().map_err(|source| ImportError::Read {
            path: dir.clone(),
            source,
        })?;
        let times_path = dir.join(TIMES_FILE);
        let times = if times_path.is_file() {
            Some(read_times(&times_path, report)?)
        } else {
            None
        };
        for path in read_dir(&dir)? {
            let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
                continue;
            };
            let ext = name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
            if !ext.is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.as_str())) {
                continue;
            }
            let time = match &times {
                Some(t) => t.get(&name).copied(),
                None => time_ns_of_name(&name),
            };
            let text = path.display().to_string();
            let Some(time_ns) = time.filter(|_| !text.contains([',', '"', '\n'])) else {
                report.skipped += 1;
                report.warn(format!(
                    "{text}: {}; skipped",
                    if times.is_some() {
                        "not in times.csv"
                    } else if time.is_some() {
                        "a comma or quote in the path"
                    } else {
                        "no time in the file name"
                    }
                ));
                continue;
            };
            images.push(StampedImage {
                time_ns,
                camera,
                path: text,
            });
        }
    }
    Ok(images)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_from_names() {
        assert_eq!(
            time_ns_of_name("1700000000.png"),
            Some(1_700_000_000_000_000_000)
        );
        assert_eq!(
            time_ns_of_name("1700000000123.png"),
            Some(1_700_000_000_123_000_000)
        );
        assert_eq!(
            time_ns_of_name("x_1700000000123456789.png"),
            Some(1_700_000_000_123_456_789)
        );
        assert_eq!(time_ns_of_name("1.2.3.png"), None);
        assert_eq!(time_ns_of_name("99999999999999999999.png"), None);
    }

    #[test]
    fn scans_camera_folders_with_and_without_times_csv() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir(root.join("Cam0")).unwrap();
        std::fs::create_dir(root.join("Cam1")).unwrap();
        std::fs::create_dir(root.join("notes")).unwrap();
        for n in [
            "1326030975726043.tiff",
            "1326030975926043.tiff",
            "readme.txt",
            "x.png",
        ] {
            std::fs::write(root.join("Cam0").join(n), b"").unwrap();
        }
        std::fs::write(root.join("Cam1").join("a.jpg"), b"").unwrap();
        std::fs::write(root.join("Cam1").join("b.jpg"), b"").unwrap();
        std::fs::write(
            root.join("Cam1").join(TIMES_FILE),
            "file,time_s\na.jpg,1326030975.7265\nb.jpg,oops\n",
        )
        .unwrap();
        let mut report = ImportReport::default();
        let images = scan_folders(root, &mut report).unwrap();
        let got: Vec<(usize, i64)> = images.iter().map(|i| (i.camera, i.time_ns)).collect();
        assert_eq!(
            got,
            vec![
                (0, 1_326_030_975_726_043_000),
                (0, 1_326_030_975_926_043_000),
                (1, 1_326_030_975_726_500_000)
            ]
        );
        assert_eq!(report.skipped, 3, "{:?}", report.warnings);
        assert!(report.warnings.iter().any(|w| w.contains("times.csv:3")));
        assert!(report.warnings.iter().any(|w| w.contains("x.png: no time")));
    }
}

/// Options of a folders import.
#[derive(Clone, Debug)]
pub struct FolderImportOptions {
    /// The rig calibration.
    pub rig: PathBuf,
    /// The surveyed landmarks, if any (an empty table otherwise).
    pub landmarks: Option<PathBuf>,
    /// A satellite GPS file (NMEA, GPX or NCLT `gps.csv`) copied into the drive, if any.
    pub gnss: Option<PathBuf>,
    /// Largest spread of the stamps of one frame, seconds.
    pub stamp_tolerance_s: f64,
}

/// Imports the camera folders of `root` into the drive folder `out`.
///
/// # Errors
/// [`ImportError`] when a folder cannot be read or a drive file cannot be written.
pub fn import_folders(
    root: &Path,
    out: &Path,
    options: &FolderImportOptions,
) -> Result<(vgps_replay::drive::Manifest, ImportReport), ImportError> {
    let mut report = ImportReport::default();
    let images = scan_folders(root, &mut report)?;
    let content = crate::drive_out::DriveContent {
        frames: crate::drive_out::assemble_frames(
            images,
            (options.stamp_tolerance_s * 1e9).round() as i64,
        ),
        gnss_file: options.gnss.clone(),
        ..Default::default()
    };
    let manifest = crate::drive_out::write_drive(
        out,
        &options.rig,
        options.landmarks.as_deref(),
        &content,
        &mut report,
    )?;
    Ok((manifest, report))
}
