//! The outputs of `vgps replay`: statistics, tables and track files from per-frame records.
//!
//! The replay command runs the localizer over a drive and hands this module one
//! [`FrameOutcome`] per frame (the visual fix if any, the satellite position interpolated at
//! the frame time if any, and the ground truth if the drive has one) plus the drive's
//! metadata ([`DriveInfo`]). This module is a library over that plain data:
//!
//! - [`Report::compute`]: the statistics (CEP50/CEP95/RMS/max horizontal error, vertical RMS,
//!   the same during satellite blackouts, status counts, heading error, covariance
//!   consistency, drift on surrogate-only stretches) → `report.json`;
//! - [`summary_table`]: the same as a text table for stdout;
//! - [`fixes_csv`], [`track_geojson`], [`track_kml`], [`track_gpx`], [`fixes_nmea`]: the
//!   per-frame table and the track formats;
//! - [`report_html`] / [`report_html_with`]: one self-contained interactive page (inline
//!   scripts, CSS and SVG) with a pan-and-zoom map of the fixes, their 95 % ellipses and
//!   the landmarks, the error against time, the error CDFs and the summary;
//! - [`plot_track_png`], [`plot_error_png`]: PNG plots;
//! - [`write_outputs`]: all of them into a directory, each written atomically.
//!
//! Every difference between two positions is computed in the local East-North-Up frame at
//! [`DriveInfo::origin`] ([`LocalFrame`](vgps_geometry::geo::LocalFrame)), never in degrees. Every output is deterministic
//! (the same records give byte-identical files) and free of NaN: a missing or non-finite
//! value is written as an empty field (CSV, NMEA), `null` (JSON) or left out (XML formats).
//!
//! The definitions of every file, column, key and statistic are in `docs/replay-report.md`.
//!
//! # Example
//! ```
//! use vgps_geometry::geo::Geodetic;
//! use vgps_replay::report::{DriveInfo, FrameOutcome, Report, Truth};
//! let origin = Geodetic::try_new(48.0, 11.0, 500.0)?;
//! let drive = DriveInfo { name: "demo".into(), origin };
//! let records: Vec<FrameOutcome> = (0..4)
//!     .map(|i| FrameOutcome {
//!         frame: i,
//!         time_s: 1_700_000_000.0 + i as f64,
//!         status: "no_fix".into(),
//!         visual: None,
//!         gnss: Some(origin),
//!         unusable_images: None,
//!         truth: Some(Truth { geodetic: origin, heading_deg: 0.0 }),
//!         message: "too few detections".into(),
//!     })
//!     .collect();
//! let report = Report::compute(&drive, &records);
//! assert_eq!(report.frames, 4);
//! assert_eq!(report.visual_fix_rate, Some(0.0));
//! // The satellite track sits on the truth: zero error.
//! let g = report.gnss_vs_truth.as_ref().unwrap();
//! assert_eq!((g.n, g.horizontal_m.max), (4, 0.0));
//! # Ok::<(), vgps_geometry::geo::GeoError>(())
//! ```

mod atomic;
mod charts;
mod combine;
mod csv_out;
mod derived;
mod html;
mod nmea;
mod plot;
mod stats;
mod text;
pub(crate) mod time;
mod tracks;

pub use atomic::write_atomic;
pub use combine::{
    BackwardFix, Combination, DISAGREEMENT_CHI2, DISAGREEMENT_FLOOR_M, combine_passes,
};
pub use csv_out::{FIXES_COLUMNS, IMAGE_COLUMNS, MESSAGE_COLUMN, TRUTH_COLUMNS, fixes_csv};
pub use html::{MapExtras, VENDOR_BEGIN, VENDOR_END, report_html, report_html_with};
pub use nmea::{
    GGA_QUALITY_VISUAL, MAX_VELOCITY_GAP_S, NMEA_TALKER, NmeaEpochWriter, error_ellipse,
    fixes_nmea, nmea_checksum,
};
pub use plot::{PLOT_HEIGHT_PX, PLOT_WIDTH_PX, plot_error_png, plot_track_png};
pub use stats::{
    BlackoutSection, Comparison, CovarianceConsistency, DriftStretch, HorizontalStats,
    ImageAccounting, MIN_DRIFT_DISTANCE_M, Report, SurrogateDrift, quantile_nearest_rank,
};
pub use text::summary_table;
pub use time::utc_iso8601;
pub use tracks::{track_geojson, track_gpx, track_kml};

use nalgebra::{Matrix2, Matrix6, UnitQuaternion};
use std::path::{Path, PathBuf};
use vgps_geometry::geo::Geodetic;

/// A fix with fewer surveyed landmarks than this (and at least one surrogate) is
/// "surrogate-only"; a fix with at least this many anchors the drift distance.
pub const MIN_SURVEYED_LANDMARKS: usize = 3;

/// The probability of the horizontal error ellipse used by the covariance-consistency test.
pub const ELLIPSE_PROBABILITY: f64 = 0.95;

/// The χ² quantile with 2 degrees of freedom at [`ELLIPSE_PROBABILITY`]:
/// `−2 ln(1 − 0.95)`. A horizontal error `e` is inside the 95 % ellipse of the covariance
/// `Σ` when `eᵀ Σ⁻¹ e ≤` this value.
pub const CHI2_2DOF_95: f64 = 5.991_464_547_107_979;

/// The visual fix of one frame, as the localizer reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct VisualFix {
    /// The rig position (WGS84).
    pub geodetic: Geodetic,
    /// Heading of the rig +x axis, clockwise from true north (degrees).
    pub heading_deg: f64,
    /// Pitch: rig +x above the horizon is positive (degrees).
    pub pitch_deg: f64,
    /// Roll: right side down is positive (degrees).
    pub roll_deg: f64,
    /// Attitude as the rotation `enu_from_rig` (ENU at the fix).
    pub enu_from_rig: UnitQuaternion<f64>,
    /// Standard deviation of the east position (metres).
    pub sigma_e_m: f64,
    /// Standard deviation of the north position (metres).
    pub sigma_n_m: f64,
    /// Standard deviation of the up position (metres).
    pub sigma_u_m: f64,
    /// Covariance of the horizontal position `[east, north]` (m²), in the drive's ENU frame
    /// (the rotation between the ENU frame at the fix and at the drive origin is below a
    /// milliradian over 10 km and is neglected).
    pub horizontal_covariance_m2: Matrix2<f64>,
    /// Covariance of the pose `[δE, δN, δU (m), δθE, δθN, δθU (rad)]` in the drive's ENU
    /// frame, the attitude error a small rotation about the ENU axes (`world_from_rig`
    /// perturbed on the left, ROS's fixed-axis convention). Its east-north block is
    /// `horizontal_covariance_m2`, its diagonal square roots `sigma_e_m`, `sigma_n_m`,
    /// `sigma_u_m`.
    pub pose_covariance: Matrix6<f64>,
    /// Number of surveyed landmarks among the inliers.
    pub n_landmarks: usize,
    /// Number of surrogate landmarks (mapped, not surveyed) among the inliers.
    pub n_surrogates: usize,
}

impl VisualFix {
    /// The report's view of a localizer fix: `None` unless its status is
    /// [`LocalizerStatus::Ok`](vgps_core::localizer::LocalizerStatus::Ok) with an estimate.
    pub fn from_localizer(fix: &vgps_core::localizer::LocalizerFix) -> Option<Self> {
        let e = fix.estimate.as_ref()?;
        if fix.status != vgps_core::localizer::LocalizerStatus::Ok {
            return None;
        }
        let [heading_deg, pitch_deg, roll_deg] = e.heading_pitch_roll.to_degrees();
        let [sigma_e_m, sigma_n_m, sigma_u_m] = e.sigma_enu_m();
        Some(Self {
            geodetic: e.geodetic,
            heading_deg,
            pitch_deg,
            roll_deg,
            enu_from_rig: e.enu_from_rig,
            sigma_e_m,
            sigma_n_m,
            sigma_u_m,
            horizontal_covariance_m2: e.covariance.fixed_view::<2, 2>(0, 0).into_owned(),
            pose_covariance: e.covariance,
            n_landmarks: e.landmarks.len(),
            n_surrogates: e.surrogates.len(),
        })
    }

    /// True when the fix rests on surrogates only: fewer than [`MIN_SURVEYED_LANDMARKS`]
    /// surveyed landmarks and at least one surrogate.
    pub fn is_surrogate_only(&self) -> bool {
        self.n_landmarks < MIN_SURVEYED_LANDMARKS && self.n_surrogates > 0
    }
}

/// The ground truth of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Truth {
    /// The true rig position (WGS84).
    pub geodetic: Geodetic,
    /// The true heading of the rig +x axis, clockwise from true north (degrees).
    pub heading_deg: f64,
}

/// Everything the report knows about one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameOutcome {
    /// Frame index in the drive.
    pub frame: u64,
    /// Capture time: Unix seconds, UTC.
    pub time_s: f64,
    /// The localizer's status (`ok`, `ambiguous`, `no_fix`, `too_few_observations`,
    /// `bad_image`, …); counted as given.
    pub status: String,
    /// The visual fix, if the localizer produced one.
    pub visual: Option<VisualFix>,
    /// The satellite position interpolated at the frame time; `None` during a blackout or
    /// a gap of the satellite log.
    pub gnss: Option<Geodetic>,
    /// How many of the frame's images could not be used (missing, corrupt, wrong size, …)
    /// when its detections came from the images; `None` when they came from a detections
    /// file. A frame with some unusable images is still localized with the others.
    pub unusable_images: Option<u32>,
    /// The ground truth, if the drive has one.
    pub truth: Option<Truth>,
    /// Why the frame has this status, in the localizer's words (`fixes.csv`'s last column):
    /// for a frame without a fix, what was missing or refused; may be empty.
    pub message: String,
}

/// The drive's metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveInfo {
    /// The drive's name (titles of the page, the track files and the plots).
    pub name: String,
    /// The origin of the ENU frame in which every difference is computed.
    pub origin: Geodetic,
}

/// Errors of the report module.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file could not be written.
    #[error("cannot write {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's message.
        reason: String,
    },
    /// A plot could not be drawn or encoded.
    #[error("cannot draw {what}: {reason}")]
    Plot {
        /// Which plot.
        what: &'static str,
        /// The plotting library's message.
        reason: String,
    },
}

/// The names of the files written by [`write_outputs`], in writing order.
pub const OUTPUT_FILES: [&str; 10] = [
    "fixes.csv",
    "report.json",
    "report.html",
    "track.geojson",
    "track.kml",
    "track.gpx",
    "fixes.nmea",
    "track.png",
    "error.png",
    "summary.txt",
];

/// Computes the report and writes every output into `dir` (created if missing), each file
/// atomically (a temporary file in `dir`, then a rename over the target).
///
/// The files are rendered on up to [`std::thread::available_parallelism`] threads (each
/// file by one thread, so every file is the same as when rendered alone); nothing is
/// written unless every file could be rendered. They are then written, also in parallel:
/// a file that cannot be written does not keep the others from being written, and the
/// error names the first such file in [`OUTPUT_FILES`] order.
///
/// Returns the report and the paths written ([`OUTPUT_FILES`] in order).
///
/// # Errors
/// [`ReportError::Io`] naming the file that could not be written, or
/// [`ReportError::Plot`] if a plot could not be drawn.
pub fn write_outputs(
    dir: &Path,
    drive: &DriveInfo,
    records: &[FrameOutcome],
) -> Result<(Report, Vec<PathBuf>), ReportError> {
    write_outputs_with(dir, drive, records, &MapExtras::default())
}

/// [`write_outputs`] with the landmarks (and the landmarks each fix used) shown on the map
/// of `report.html` ([`report_html_with`]).
///
/// # Errors
/// As [`write_outputs`].
pub fn write_outputs_with(
    dir: &Path,
    drive: &DriveInfo,
    records: &[FrameOutcome],
    extras: &MapExtras,
) -> Result<(Report, Vec<PathBuf>), ReportError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::Io {
        path: dir.display().to_string(),
        reason: e.to_string(),
    })?;
    let report = Report::compute(drive, records);
    let render = |k: usize| -> Result<Vec<u8>, ReportError> {
        Ok(match OUTPUT_FILES[k] {
            "fixes.csv" => fixes_csv(drive, records).into_bytes(),
            "report.json" => report.to_json().into_bytes(),
            "report.html" => report_html_with(drive, records, &report, extras).into_bytes(),
            "track.geojson" => track_geojson(drive, records).into_bytes(),
            "track.kml" => track_kml(drive, records).into_bytes(),
            "track.gpx" => track_gpx(drive, records).into_bytes(),
            "fixes.nmea" => fixes_nmea(records).into_bytes(),
            "track.png" => plot_track_png(drive, records)?,
            "error.png" => plot_error_png(drive, records)?,
            _ => summary_table(&report).into_bytes(),
        })
    };
    let contents = in_parallel(&RENDER_ORDER, render)
        .into_iter()
        .collect::<Result<Vec<Vec<u8>>, ReportError>>()?;
    let paths: Vec<PathBuf> = OUTPUT_FILES.iter().map(|name| dir.join(name)).collect();
    let all: [usize; OUTPUT_FILES.len()] = std::array::from_fn(|k| k);
    in_parallel(&all, |k| write_atomic(&paths[k], &contents[k]))
        .into_iter()
        .collect::<Result<Vec<()>, ReportError>>()?;
    Ok((report, paths))
}

/// The indices of [`OUTPUT_FILES`] in the order they are handed to the rendering threads:
/// the slowest first (the GeoJSON track, then the tables), so that the threads finish
/// together.
const RENDER_ORDER: [usize; OUTPUT_FILES.len()] = [3, 0, 4, 6, 2, 5, 8, 7, 1, 9];

/// Runs `job(k)` for every `k` of `order` on up to `available_parallelism` threads (the
/// calling thread is one of them), each thread taking the next index when it is done;
/// returns the results indexed by `k` (`order` must be a permutation of `0..order.len()`).
fn in_parallel<T: Send>(order: &[usize], job: impl Fn(usize) -> T + Sync) -> Vec<T> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let threads = std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .clamp(1, order.len().max(1));
    let next = AtomicUsize::new(0);
    let work = || {
        let mut done = Vec::new();
        while let Some(&k) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
            done.push((k, job(k)));
        }
        done
    };
    let mut done: Vec<(usize, T)> = std::thread::scope(|scope| {
        let helpers: Vec<_> = (1..threads).map(|_| scope.spawn(work)).collect();
        let mut done = work();
        for helper in helpers {
            // A helper that panicked re-raises its panic here, as the job would have on
            // the calling thread.
            done.extend(
                helper
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p)),
            );
        }
        done
    });
    done.sort_by_key(|&(k, _)| k);
    done.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests;
