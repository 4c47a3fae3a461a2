//! Drive logs: a directory holding a manifest (`drive.json`), the rig calibration, the
//! surveyed landmarks, the frames, and optionally detections, satellite GPS (NMEA) and the
//! true poses of a simulation. `docs/drive-format.md` is the full description (version 1).
//!
//! - [`Drive::open`] reads and checks it all. A bad row of `detections.csv` does not stop
//!   the reading: its frame gets the status [`FrameStatus::BadRows`] and the other frames go
//!   on; bad NMEA lines are skipped and counted ([`nmea::NmeaStats`]). Every other problem
//!   is a [`DriveError`] naming the file, the line and the field.
//! - The writers ([`write_manifest`], [`write_text`] with [`frames_to_csv`],
//!   [`detections_to_csv`], [`truth_to_csv`], [`landmarks_to_csv`], [`nmea::write_nmea`])
//!   write each file atomically (a temporary file in the same directory, then a rename).
//!
//! # Example
//! ```
//! use vgps_replay::drive::{Drive, Strictness};
//! use vgps_sim::simulate::{simulate, Preset, Scenario};
//! let dir = tempfile::tempdir()?;
//! let mut scenario = Scenario::preset(Preset::Short, 7);
//! scenario.length_m = 150.0;
//! simulate(&scenario)?.write(dir.path())?;
//! let drive = Drive::open(dir.path(), Strictness::Strict)?;
//! assert!(drive.frames().len() > 50);
//! assert_eq!(drive.rig().len(), 6);
//! let first = drive.frames()[0].frame;
//! assert!(!drive.detections(first).is_empty());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod gnss;
pub mod gpx;
pub mod imu;
pub mod nclt_gps;
pub mod nmea;
pub mod sirf;
mod tables;
pub mod truth_formats;
pub mod ubx;

pub use nmea::{GnssFix, GnssRecord, NmeaStats};
pub use tables::{
    FrameRecord, MAX_IMAGE_COLUMNS, PixelDetection, QUATERNION_NORM_TOLERANCE, TruthRecord,
    detections_to_csv, frames_from_text, frames_to_csv, landmarks_to_csv, truth_from_text,
    truth_to_csv,
};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
pub use tables::{DetectionRow, detections_from_text};
use vgps_camera::calibration::{LoadError, Rig};
use vgps_io::{InputError, Landmark};

/// The manifest's file name inside a drive directory.
pub const MANIFEST_NAME: &str = "drive.json";
/// The drive format version this library reads and writes.
pub const FORMAT_VERSION: u64 = 1;
/// The manifest keys of version 1.
pub const MANIFEST_KEYS: [&str; 7] = [
    "version",
    "calibration",
    "landmarks",
    "frames",
    "detections",
    "gnss",
    "truth",
];

/// How to treat unknown keys in the manifest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strictness {
    /// An unknown key is an error.
    Strict,
    /// An unknown key is a warning ([`Drive::warnings`]).
    Lenient,
}

/// Errors of reading or writing a drive.
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    /// A file cannot be read.
    #[error("{}: cannot read the file: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The manifest is invalid.
    #[error("{}:{line}: field `{field}`: {reason}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// The 1-based line.
        line: u64,
        /// The key.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A CSV file of the drive is invalid (names file, line and field).
    #[error(transparent)]
    Input(#[from] InputError),
    /// The calibration cannot be loaded (names the file and the location).
    #[error(transparent)]
    Calibration(#[from] LoadError),
    /// A GPX or NCLT satellite GPS file is invalid (names the file and the line).
    #[error(transparent)]
    Gnss(#[from] gnss::GnssFileError),
    /// A file cannot be written.
    #[error("{}: cannot write the file: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// The manifest `drive.json`: the files of the drive, relative to its directory.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    /// Format version ([`FORMAT_VERSION`]).
    pub version: u64,
    /// The rig calibration (any format [`vgps_camera::calibration::load`] detects).
    pub calibration: String,
    /// The surveyed landmarks (`id,lat,lon,alt[,sigma_m][,class]`).
    pub landmarks: String,
    /// The frames (`frame,time_s[,image_k…]`).
    pub frames: String,
    /// The detections (`frame,camera,u,v[,strength][,class]`), optional.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detections: Option<String>,
    /// Satellite GPS as NMEA 0183, optional.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gnss: Option<String>,
    /// True poses (`frame,lat,lon,alt,qw,qx,qy,qz`), optional.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
}

impl Manifest {
    /// The manifest with the standard file names, every optional file present.
    pub fn standard() -> Self {
        Self {
            version: FORMAT_VERSION,
            calibration: "calibration.json".into(),
            landmarks: "landmarks.csv".into(),
            frames: "frames.csv".into(),
            detections: Some("detections.csv".into()),
            gnss: Some("gnss.nmea".into()),
            truth: Some("truth.csv".into()),
        }
    }

    /// Parses a manifest's text; unknown keys are errors (`Strict`) or returned as warnings.
    ///
    /// # Errors
    /// [`DriveError::Manifest`] naming the line and key: not JSON, not an object, a missing
    /// or mistyped key, an unsupported version, an unknown key in strict mode.
    pub fn parse(
        path: &Path,
        text: &str,
        strictness: Strictness,
    ) -> Result<(Self, Vec<String>), DriveError> {
        let err = |line: u64, field: &str, reason: String| DriveError::Manifest {
            path: path.to_path_buf(),
            line,
            field: field.to_string(),
            reason,
        };
        let line_of = |key: &str| -> u64 {
            text.find(&format!("\"{key}\"")).map_or(1, |at| {
                1 + text[..at].bytes().filter(|&b| b == b'\n').count() as u64
            })
        };
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| err(e.line() as u64, "json", e.to_string()))?;
        let Some(object) = value.as_object() else {
            return Err(err(1, "json", "the manifest is not a JSON object".into()));
        };
        let mut warnings = Vec::new();
        for key in object.keys() {
            if !MANIFEST_KEYS.contains(&key.as_str()) {
                let reason = format!("unknown key (known keys: {})", MANIFEST_KEYS.join(", "));
                match strictness {
                    Strictness::Strict => return Err(err(line_of(key), key, reason)),
                    Strictness::Lenient => warnings.push(format!(
                        "{}:{}: field `{key}`: {reason}; ignored",
                        path.display(),
                        line_of(key)
                    )),
                }
            }
        }
        let version = match object.get("version") {
            Some(v) => v.as_u64().ok_or_else(|| {
                err(
                    line_of("version"),
                    "version",
                    format!("`{v}` is not an integer"),
                )
            })?,
            None => return Err(err(1, "version", "required key is missing".into())),
        };
        if version != FORMAT_VERSION {
            return Err(err(
                line_of("version"),
                "version",
                format!("version {version} is not supported (this reader knows {FORMAT_VERSION})"),
            ));
        }
        let string = |key: &str, required: bool| -> Result<Option<String>, DriveError> {
            match object.get(key) {
                None | Some(serde_json::Value::Null) if !required => Ok(None),
                None | Some(serde_json::Value::Null) => {
                    Err(err(1, key, "required key is missing".into()))
                }
                Some(serde_json::Value::String(s)) if !s.is_empty() => Ok(Some(s.clone())),
                Some(v) => Err(err(line_of(key), key, format!("`{v}` is not a file name"))),
            }
        };
        let req = |key: &str| -> Result<String, DriveError> {
            string(key, true)?.ok_or_else(|| err(1, key, "required key is missing".into()))
        };
        let manifest = Manifest {
            version,
            calibration: req("calibration")?,
            landmarks: req("landmarks")?,
            frames: req("frames")?,
            detections: string("detections", false)?,
            gnss: string("gnss", false)?,
            truth: string("truth", false)?,
        };
        Ok((manifest, warnings))
    }
}

/// The state of one frame's detections.
#[derive(Clone, Debug, PartialEq)]
pub enum FrameStatus {
    /// Every detections row of the frame was read.
    Ok,
    /// Some rows of the frame could not be read (the messages name file, line, field);
    /// the frame's other detections are available.
    BadRows(Vec<String>),
}

/// Counts over a drive.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveSummary {
    /// Frames.
    pub frames: usize,
    /// Surveyed landmarks.
    pub landmarks: usize,
    /// Valid detections.
    pub detections: usize,
    /// Unreadable detections rows (all kinds).
    pub bad_rows: usize,
    /// Frames with at least one unreadable row.
    pub frames_with_bad_rows: usize,
    /// Unreadable rows or rows of unknown frames (not attributable to a frame of the drive).
    pub orphan_rows: usize,
    /// GNSS epochs.
    pub gnss_records: usize,
    /// GNSS epochs with a fix.
    pub gnss_fixes: usize,
    /// Truth records.
    pub truth: usize,
}

/// A drive read from its directory.
#[derive(Debug)]
pub struct Drive {
    dir: PathBuf,
    manifest: Manifest,
    rig: Rig,
    landmarks: Vec<Landmark>,
    frames: Vec<FrameRecord>,
    detections: Vec<PixelDetection>,
    ranges: BTreeMap<u64, (usize, usize)>,
    bad_rows: BTreeMap<u64, Vec<String>>,
    orphans: Vec<String>,
    gnss: Vec<GnssRecord>,
    nmea_stats: Option<NmeaStats>,
    gnss_stats: Option<gnss::GnssFileStats>,
    truth: Vec<TruthRecord>,
    imu: Vec<imu::ImuSample>,
    warnings: Vec<String>,
}

fn read_text(path: &Path) -> Result<String, DriveError> {
    let bytes = std::fs::read(path).map_err(|source| DriveError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(match String::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
    })
}

impl Drive {
    /// Opens a drive directory: the manifest, the calibration, the landmarks and frames,
    /// and the optional detections, GNSS and truth.
    ///
    /// # Errors
    /// [`DriveError`] naming the file, line and field of the first fatal problem. Bad
    /// detections rows and bad NMEA lines are not fatal (see [`Drive::status`],
    /// [`Drive::nmea_stats`]).
    pub fn open(dir: &Path, strictness: Strictness) -> Result<Drive, DriveError> {
        let manifest_path = dir.join(MANIFEST_NAME);
        let (manifest, warnings) =
            Manifest::parse(&manifest_path, &read_text(&manifest_path)?, strictness)?;
        let rig = vgps_camera::calibration::load(&dir.join(&manifest.calibration), None, None)?;
        let landmarks = vgps_io::read_landmarks(&dir.join(&manifest.landmarks))?;
        let frames_path = dir.join(&manifest.frames);
        let frames = frames_from_text(&frames_path, &read_text(&frames_path)?)?;
        let mut drive = Drive {
            dir: dir.to_path_buf(),
            manifest: manifest.clone(),
            rig,
            landmarks,
            frames,
            detections: Vec::new(),
            ranges: BTreeMap::new(),
            bad_rows: BTreeMap::new(),
            orphans: Vec::new(),
            gnss: Vec::new(),
            nmea_stats: None,
            gnss_stats: None,
            truth: Vec::new(),
            imu: Vec::new(),
            warnings,
        };
        if let Some(name) = &manifest.detections {
            let path = dir.join(name);
            let rows = tables::detections_from_text(&path, &read_text(&path)?, drive.rig.len())?;
            drive.index_detections(rows);
        }
        if let Some(name) = &manifest.gnss {
            let path = dir.join(name);
            let bytes = std::fs::read(&path).map_err(|source| DriveError::Read {
                path: path.clone(),
                source,
            })?;
            let format = gnss::GnssFormat::detect_bytes(&path, &bytes);
            if format != gnss::GnssFormat::Nmea {
                drive.replace_gnss(gnss::read_gnss_file(&path, Some(format), 0.0)?);
            }
        }
        if let Some(name) = &manifest.gnss
            && drive.gnss_stats.is_none()
        {
            let (records, stats) = nmea::read_nmea(&read_text(&dir.join(name))?);
            if stats.skipped() > 0 {
                drive.warnings.push(format!(
                    "{}: {} of {} lines skipped ({} bad checksum, {} garbage, {} truncated, {} unsupported, {} invalid)",
                    dir.join(name).display(),
                    stats.skipped(),
                    stats.lines,
                    stats.bad_checksum,
                    stats.garbage,
                    stats.truncated,
                    stats.unsupported,
                    stats.invalid
                ));
            }
            drive.gnss_stats = Some(gnss::GnssFileStats::from_nmea(&stats, &records));
            drive.gnss = records;
            drive.nmea_stats = Some(stats);
        }
        if let Some(name) = &manifest.truth {
            // The truth is optional: a file that cannot be used is a warning, a broken row
            // is refused alone, and the drive is read on.
            let path = dir.join(name);
            let read = read_text(&path)
                .map_err(|e| e.to_string())
                .and_then(|text| truth_formats::read_truth(&path, &text, &drive.frames));
            match read {
                Ok(read) => {
                    drive.warnings.extend(read.warning(&path));
                    drive.truth = read.records;
                }
                Err(message) => drive
                    .warnings
                    .push(format!("{message}; the drive is read without truth")),
            }
        }
        // IMU samples (`imu.csv` beside the manifest, as `vgps import mcap` writes them) are
        // optional: a bad row is a warning naming its line and field.
        let imu_path = dir.join(imu::IMU_FILE);
        if imu_path.is_file() {
            let (samples, errors) = imu::imu_from_text(&imu_path, &read_text(&imu_path)?);
            for e in errors.iter().take(gnss::MAX_GNSS_MESSAGES) {
                drive.warnings.push(format!("{e}; sample skipped"));
            }
            if errors.len() > gnss::MAX_GNSS_MESSAGES {
                drive.warnings.push(format!(
                    "{}: {} bad IMU samples in all",
                    imu_path.display(),
                    errors.len()
                ));
            }
            drive.imu = samples;
        }
        Ok(drive)
    }

    fn index_detections(&mut self, rows: Vec<DetectionRow>) {
        let mut good: Vec<PixelDetection> = Vec::with_capacity(rows.len());
        for row in rows {
            match row {
                DetectionRow::Ok(d) if self.frame_index(d.frame).is_some() => good.push(d),
                DetectionRow::Ok(d) => self.orphans.push(format!(
                    "detection of frame {} which is not in the frames file",
                    d.frame
                )),
                DetectionRow::Bad { frame, message } if self.frame_index(frame).is_some() => {
                    self.bad_rows.entry(frame).or_default().push(message);
                }
                DetectionRow::Bad { message, .. } | DetectionRow::Orphan(message) => {
                    self.orphans.push(message);
                }
            }
        }
        good.sort_by_key(|d| d.frame); // stable: file order within a frame
        let mut start = 0;
        while start < good.len() {
            let frame = good[start].frame;
            let end = start + good[start..].partition_point(|d| d.frame == frame);
            self.ranges.insert(frame, (start, end));
            start = end;
        }
        self.detections = good;
    }

    fn frame_index(&self, frame: u64) -> Option<usize> {
        self.frames.binary_search_by_key(&frame, |f| f.frame).ok()
    }

    /// The drive directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The rig calibration.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// Reloads the rig calibration with an image size for the cameras whose calibration
    /// names none (a Ladybug INI dump; see [`vgps_camera::calibration::load`]).
    ///
    /// # Errors
    /// [`DriveError`] naming the calibration file when it cannot be loaded with that size.
    pub fn reload_calibration(&mut self, image_size: (u32, u32)) -> Result<(), DriveError> {
        self.rig = vgps_camera::calibration::load(
            &self.dir.join(&self.manifest.calibration),
            None,
            Some(image_size),
        )?;
        Ok(())
    }

    /// The surveyed landmarks.
    pub fn landmarks(&self) -> &[Landmark] {
        &self.landmarks
    }

    /// The frames, in increasing frame number.
    pub fn frames(&self) -> &[FrameRecord] {
        &self.frames
    }

    /// Every valid detection, grouped by frame (file order within a frame).
    pub fn all_detections(&self) -> &[PixelDetection] {
        &self.detections
    }

    /// The valid detections of one frame (empty for a frame without any).
    pub fn detections(&self, frame: u64) -> &[PixelDetection] {
        self.ranges
            .get(&frame)
            .map_or(&[], |&(a, b)| &self.detections[a..b])
    }

    /// The status of one frame's detections rows.
    pub fn status(&self, frame: u64) -> FrameStatus {
        match self.bad_rows.get(&frame) {
            Some(m) => FrameStatus::BadRows(m.clone()),
            None => FrameStatus::Ok,
        }
    }

    /// Messages about detections rows that belong to no frame of the drive.
    pub fn orphan_rows(&self) -> &[String] {
        &self.orphans
    }

    /// The IMU samples (`imu.csv`), in time order; empty without the file.
    pub fn imu(&self) -> &[imu::ImuSample] {
        &self.imu
    }

    /// The IMU's attitude prior at `time_s` ([`imu::attitude_at`]), if any.
    pub fn attitude_at(&self, time_s: f64) -> Option<vgps_core::localizer::AttitudePrior> {
        imu::attitude_at(&self.imu, time_s)
    }

    /// Every GNSS epoch, in time order.
    pub fn gnss(&self) -> &[GnssRecord] {
        &self.gnss
    }

    /// The GNSS epochs with `t0 < time_s ≤ t1` (seconds, Unix time).
    pub fn gnss_between(&self, t0: f64, t1: f64) -> &[GnssRecord] {
        let a = self.gnss.partition_point(|r| r.time_s <= t0);
        let b = self.gnss.partition_point(|r| r.time_s <= t1);
        &self.gnss[a..b.max(a)]
    }

    /// Replaces the drive's satellite GPS by `log` (a file read with
    /// [`gnss::read_gnss_file`], e.g. `vgps replay --gnss FILE`); its warning, if any, is
    /// added to [`Drive::warnings`].
    pub fn replace_gnss(&mut self, log: gnss::GnssLog) {
        if let Some(w) = log.stats.warning(&log.path) {
            self.warnings.push(w);
        }
        self.gnss = log.records;
        self.nmea_stats = log.nmea;
        self.gnss_stats = Some(log.stats);
    }

    /// What the GNSS reader read and skipped, in any format (`None` without a GNSS file).
    pub fn gnss_stats(&self) -> Option<&gnss::GnssFileStats> {
        self.gnss_stats.as_ref()
    }

    /// What the NMEA reader skipped (`None` without a GNSS file).
    pub fn nmea_stats(&self) -> Option<&NmeaStats> {
        self.nmea_stats.as_ref()
    }

    /// Every truth record, in frame order (empty without a truth file).
    pub fn truth(&self) -> &[TruthRecord] {
        &self.truth
    }

    /// The truth of one frame.
    pub fn truth_of(&self, frame: u64) -> Option<&TruthRecord> {
        self.truth
            .binary_search_by_key(&frame, |t| t.frame)
            .ok()
            .map(|k| &self.truth[k])
    }

    /// Warnings (unknown manifest keys in lenient mode, skipped NMEA lines).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Counts over the drive.
    pub fn summary(&self) -> DriveSummary {
        let in_frames: usize = self.bad_rows.values().map(Vec::len).sum();
        DriveSummary {
            frames: self.frames.len(),
            landmarks: self.landmarks.len(),
            detections: self.detections.len(),
            bad_rows: in_frames + self.orphans.len(),
            frames_with_bad_rows: self.bad_rows.len(),
            orphan_rows: self.orphans.len(),
            gnss_records: self.gnss.len(),
            gnss_fixes: self.gnss.iter().filter(|r| r.fix.is_some()).count(),
            truth: self.truth.len(),
        }
    }
}

/// Writes `text` to `path` atomically (a temporary file in the same directory, then a
/// rename).
///
/// # Errors
/// [`DriveError::Write`] naming `path`.
pub fn write_text(path: &Path, text: &str) -> Result<(), DriveError> {
    vgps_io::write_atomic(path, text.as_bytes()).map_err(|source| DriveError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes the manifest as `dir/drive.json` (pretty JSON, atomically).
///
/// # Errors
/// [`DriveError::Write`] naming the file.
pub fn write_manifest(dir: &Path, manifest: &Manifest) -> Result<(), DriveError> {
    let path = dir.join(MANIFEST_NAME);
    let text = serde_json::to_string_pretty(manifest).map_err(|e| DriveError::Write {
        path: path.clone(),
        source: std::io::Error::other(e),
    })?;
    write_text(&path, &(text + "\n"))
}
