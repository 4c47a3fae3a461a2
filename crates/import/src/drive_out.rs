//! What every import shares: frames assembled from per-camera image streams by time stamp,
//! the import's warnings and counts, and the writing of a drive folder (version 1 of
//! `docs/drive-format.md`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vgps_replay::drive::{
    self, FrameRecord, GnssRecord, MAX_IMAGE_COLUMNS, Manifest, TruthRecord, nmea::write_nmea,
};

/// Default tolerance between the stamps of one frame's images, seconds.
pub const DEFAULT_STAMP_TOLERANCE_S: f64 = 0.010;
/// How many warnings [`ImportReport::warnings`] keeps (the rest are counted).
pub const MAX_WARNINGS: usize = 100;

/// Errors that stop an import.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A file or directory cannot be read.
    #[error("{}: cannot read: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// An input is unusable as a whole (names the file and, where there is one, the line).
    #[error("{0}")]
    Input(String),
    /// The MCAP file cannot be read at all.
    #[error(transparent)]
    Mcap(#[from] crate::mcap_read::McapFileError),
    /// A drive file could not be written.
    #[error(transparent)]
    Drive(#[from] drive::DriveError),
}

/// One image of one camera with its time stamp.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct StampedImage {
    /// Time stamp, nanoseconds since the Unix epoch.
    pub time_ns: i64,
    /// Camera index in the rig.
    pub camera: usize,
    /// The image file, relative to the drive directory (or absolute).
    pub path: String,
}

/// Seconds (Unix time, `f64`) of a nanosecond stamp: whole seconds plus the fraction, so
/// that a time written in decimal with up to nanosecond digits reads back the same.
pub fn seconds_of_ns(ns: i64) -> f64 {
    ns.div_euclid(1_000_000_000) as f64 + ns.rem_euclid(1_000_000_000) as f64 * 1e-9
}

/// Groups images into frames: images sorted by time; a frame starts at its earliest stamp
/// and takes the following images stamped within `tolerance_ns` of it, one per camera (a
/// second image of a camera starts a new frame). The frame's time is its earliest stamp; a
/// camera without an image in the window is left empty (the frame is still localized with
/// the others). Frames are numbered from 0.
///
/// # Example
/// ```
/// use vgps_import::drive_out::{StampedImage, assemble_frames};
/// let img = |t, c: usize| StampedImage { time_ns: t, camera: c, path: format!("{t}_{c}") };
/// let frames = assemble_frames(vec![img(0, 0), img(3, 1), img(100, 0), img(200, 1)], 5);
/// assert_eq!(frames.len(), 3);
/// assert_eq!(frames[0].images, vec![Some("0_0".to_string()), Some("3_1".to_string())]);
/// assert_eq!(frames[1].images, vec![Some("100_0".to_string()), None]);
/// ```
pub fn assemble_frames(mut images: Vec<StampedImage>, tolerance_ns: i64) -> Vec<FrameRecord> {
    images.sort();
    let cameras = images.iter().map(|i| i.camera + 1).max().unwrap_or(0);
    let mut frames: Vec<FrameRecord> = Vec::new();
    let mut start = i64::MIN;
    for image in images {
        let fits = frames.last().is_some_and(|f: &FrameRecord| {
            image.time_ns.saturating_sub(start) <= tolerance_ns
                && f.images.get(image.camera).is_some_and(Option::is_none)
        });
        if !fits {
            start = image.time_ns;
            frames.push(FrameRecord {
                frame: frames.len() as u64,
                time_s: seconds_of_ns(image.time_ns),
                images: vec![None; cameras],
            });
        }
        if let Some(f) = frames.last_mut()
            && let Some(slot) = f.images.get_mut(image.camera)
        {
            *slot = Some(image.path);
        }
    }
    frames
}

/// Counts and warnings of one import.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImportReport {
    /// Frames written.
    pub frames: usize,
    /// Images referenced by the frames.
    pub images: usize,
    /// Frames with at least one camera without an image.
    pub frames_missing_cameras: usize,
    /// Satellite GPS epochs written.
    pub gnss_epochs: usize,
    /// Of which without a fix.
    pub gnss_no_fix: usize,
    /// IMU samples written.
    pub imu_samples: usize,
    /// Truth records written.
    pub truth: usize,
    /// Inputs (messages, files, rows) skipped.
    pub skipped: u64,
    /// The first [`MAX_WARNINGS`] warnings (each names the file and the record or line).
    pub warnings: Vec<String>,
    /// Warnings not kept.
    pub more_warnings: u64,
}

impl ImportReport {
    /// Adds a warning (kept if fewer than [`MAX_WARNINGS`]).
    pub fn warn(&mut self, message: String) {
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings.push(message);
        } else {
            self.more_warnings += 1;
        }
    }

    /// A one-line summary.
    pub fn summary(&self) -> String {
        format!(
            "{} frames ({} images, {} frames missing a camera), {} GNSS epochs ({} without fix), {} IMU samples, {} truth records, {} inputs skipped",
            self.frames,
            self.images,
            self.frames_missing_cameras,
            self.gnss_epochs,
            self.gnss_no_fix,
            self.imu_samples,
            self.truth,
            self.skipped
        )
    }
}

/// One `sensor_msgs/NavSatFix` as kept in `navsatfix.csv` (status and covariance included).
#[derive(Clone, Debug, PartialEq)]
pub struct NavSatRow {
    /// Unix time, seconds.
    pub time_s: f64,
    /// −1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// Service bit mask.
    pub service: u16,
    /// Latitude, longitude (degrees), ellipsoidal height (m).
    pub lat_lon_alt: [f64; 3],
    /// Covariance type (0 unknown … 3 known).
    pub covariance_type: u8,
    /// Position covariance, m², ENU, row-major.
    pub covariance: [f64; 9],
}

/// One IMU sample as kept in `imu.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuRow {
    /// Unix time, seconds.
    pub time_s: f64,
    /// Orientation quaternion `(x, y, z, w)`.
    pub orientation: [f64; 4],
    /// Orientation covariance diagonal, rad² (first −1: no orientation).
    pub orientation_variance: [f64; 3],
    /// Angular velocity, rad/s.
    pub angular_velocity: [f64; 3],
    /// Linear acceleration, m/s².
    pub linear_acceleration: [f64; 3],
}

/// Everything an import writes besides the calibration and the landmarks.
#[derive(Clone, Debug, Default)]
pub struct DriveContent {
    /// Frames.
    pub frames: Vec<FrameRecord>,
    /// Satellite GPS epochs (written as `gnss.nmea`), when any.
    pub gnss: Vec<GnssRecord>,
    /// A satellite GPS file to copy as it is instead (`gps.csv` of NCLT), when given.
    pub gnss_file: Option<PathBuf>,
    /// NavSatFix rows (`navsatfix.csv`), when any.
    pub navsat: Vec<NavSatRow>,
    /// IMU samples (`imu.csv`), when any.
    pub imu: Vec<ImuRow>,
    /// Truth (`truth.csv`), when any.
    pub truth: Vec<TruthRecord>,
}

/// The name of the side file of NavSatFix messages (not in the manifest).
pub const NAVSAT_FILE: &str = "navsatfix.csv";
/// The name of the side file of IMU samples (not in the manifest).
pub const IMU_FILE: &str = "imu.csv";

fn write(path: &Path, bytes: &[u8]) -> Result<(), ImportError> {
    vgps_io::write_atomic(path, bytes).map_err(|source| ImportError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Creates `dir` (and parents).
///
/// # Errors
/// [`ImportError::Write`].
pub fn create_dir(dir: &Path) -> Result<(), ImportError> {
    std::fs::create_dir_all(dir).map_err(|source| ImportError::Write {
        path: dir.to_path_buf(),
        source,
    })
}

/// Writes a drive into `out`: the calibration (a file is copied; a directory, such as an
/// NCLT calibration, is referenced by its absolute path), the landmarks (copied, or an empty
/// table), the frames, the satellite GPS, the side files and the manifest. The frames must
/// have at most [`MAX_IMAGE_COLUMNS`] cameras.
///
/// # Errors
/// [`ImportError`] naming the file that cannot be read or written.
pub fn write_drive(
    out: &Path,
    rig: &Path,
    landmarks: Option<&Path>,
    content: &DriveContent,
    report: &mut ImportReport,
) -> Result<Manifest, ImportError> {
    // Every input is read before anything is written: an unreadable input leaves no
    // partial drive.
    let read = |p: &Path| {
        std::fs::read(p).map_err(|source| ImportError::Read {
            path: p.to_path_buf(),
            source,
        })
    };
    let (calibration, rig_bytes) = if rig.is_dir() {
        let abs = rig.canonicalize().map_err(|source| ImportError::Read {
            path: rig.to_path_buf(),
            source,
        })?;
        (abs.display().to_string(), None)
    } else {
        let name = rig.file_name().map_or("calibration.json".into(), |n| {
            n.to_string_lossy().into_owned()
        });
        (format!("calibration_{name}"), Some(read(rig)?))
    };
    let landmark_bytes = match landmarks {
        Some(p) => read(p)?,
        None => b"id,lat,lon,alt\n".to_vec(),
    };
    let gnss_bytes = content.gnss_file.as_deref().map(read).transpose()?;
    let frames = &content.frames;
    if let Some(f) = frames.iter().find(|f| f.images.len() > MAX_IMAGE_COLUMNS) {
        return Err(ImportError::Input(format!(
            "frame {} has {} cameras; a drive holds at most {MAX_IMAGE_COLUMNS}",
            f.frame,
            f.images.len()
        )));
    }
    create_dir(out)?;
    if let Some(bytes) = rig_bytes {
        write(&out.join(&calibration), &bytes)?;
    }
    let landmarks_name = "landmarks.csv";
    write(&out.join(landmarks_name), &landmark_bytes)?;
    drive::write_text(&out.join("frames.csv"), &drive::frames_to_csv(frames))?;
    report.frames = frames.len();
    report.images = frames
        .iter()
        .map(|f| f.images.iter().flatten().count())
        .sum();
    let cameras = frames.iter().map(|f| f.images.len()).max().unwrap_or(0);
    report.frames_missing_cameras = frames
        .iter()
        .filter(|f| f.images.iter().flatten().count() < cameras)
        .count();
    let gnss = if let (Some(file), Some(bytes)) = (&content.gnss_file, &gnss_bytes) {
        let name = file
            .file_name()
            .map_or("gps.csv".into(), |n| n.to_string_lossy().into_owned());
        write(&out.join(&name), bytes)?;
        Some(name)
    } else if !content.gnss.is_empty() {
        drive::write_text(&out.join("gnss.nmea"), &write_nmea(&content.gnss, 0.0))?;
        report.gnss_epochs = content.gnss.len();
        report.gnss_no_fix = content.gnss.iter().filter(|r| r.fix.is_none()).count();
        Some("gnss.nmea".to_string())
    } else {
        None
    };
    if !content.navsat.is_empty() {
        drive::write_text(&out.join(NAVSAT_FILE), &navsat_to_csv(&content.navsat))?;
    }
    if !content.imu.is_empty() {
        drive::write_text(&out.join(IMU_FILE), &imu_to_csv(&content.imu))?;
        report.imu_samples = content.imu.len();
    }
    let truth = (!content.truth.is_empty()).then(|| "truth.csv".to_string());
    if truth.is_some() {
        drive::write_text(&out.join("truth.csv"), &drive::truth_to_csv(&content.truth))?;
        report.truth = content.truth.len();
    }
    let manifest = Manifest {
        version: drive::FORMAT_VERSION,
        calibration,
        landmarks: landmarks_name.into(),
        frames: "frames.csv".into(),
        detections: None,
        gnss,
        truth,
    };
    drive::write_manifest(out, &manifest)?;
    Ok(manifest)
}

/// CSV text of NavSatFix rows:
/// `time_s,status,service,lat,lon,alt,covariance_type,c0,…,c8`.
pub fn navsat_to_csv(rows: &[NavSatRow]) -> String {
    let mut out = String::from("time_s,status,service,lat,lon,alt,covariance_type");
    for k in 0..9 {
        let _ = write!(out, ",c{k}");
    }
    out.push('\n');
    for r in rows {
        let [lat, lon, alt] = r.lat_lon_alt;
        let _ = write!(
            out,
            "{},{},{},{lat},{lon},{alt},{}",
            r.time_s, r.status, r.service, r.covariance_type
        );
        for c in r.covariance {
            let _ = write!(out, ",{c}");
        }
        out.push('\n');
    }
    out
}

/// CSV text of IMU rows: `time_s,qx,qy,qz,qw,var_roll,var_pitch,var_yaw,wx,wy,wz,ax,ay,az`.
pub fn imu_to_csv(rows: &[ImuRow]) -> String {
    let mut out = String::from("time_s,qx,qy,qz,qw,var_roll,var_pitch,var_yaw,wx,wy,wz,ax,ay,az\n");
    for r in rows {
        let _ = write!(out, "{}", r.time_s);
        for v in r
            .orientation
            .iter()
            .chain(&r.orientation_variance)
            .chain(&r.angular_velocity)
            .chain(&r.linear_acceleration)
        {
            let _ = write!(out, ",{v}");
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_keep_decimal_times() {
        assert_eq!(seconds_of_ns(1_778_794_200_200_000_000), 1778794200.2);
        assert_eq!(seconds_of_ns(-500_000_000), -0.5);
    }

    #[test]
    fn a_second_image_of_a_camera_starts_a_frame() {
        let img = |t, c: usize| StampedImage {
            time_ns: t,
            camera: c,
            path: format!("{t}"),
        };
        let f = assemble_frames(vec![img(10, 1), img(0, 0), img(2, 0), img(4, 1)], 5);
        assert_eq!(f.len(), 3);
        assert_eq!(f[0].images, vec![Some("0".into()), None]);
        assert_eq!(f[1].images, vec![Some("2".into()), Some("4".into())]);
        assert_eq!(f[2].images, vec![None, Some("10".into())]);
        assert_eq!((f[1].frame, f[1].time_s), (1, 2e-9));
    }
}
