//! `vgps import mcap|nclt|folders`: logs of other tools into a drive folder
//! (`docs/import.md`), and the MCAP input of `vgps replay run.mcap`.

use super::CliError;
use clap::{Args, Subcommand};
use std::io::Write;
use std::path::{Path, PathBuf};
use vgps_import::drive_out::{DEFAULT_STAMP_TOLERANCE_S, ImportError, ImportReport};
use vgps_import::folders::{FolderImportOptions, import_folders};
use vgps_import::mcap_import::{
    ImageOutput, McapImportOptions, RecordingImages, import_mcap, read_topic_map,
};
use vgps_import::nclt::{NcltImportOptions, import_nclt};

fn parse_tolerance(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=10.0).contains(&v) => Ok(v),
        _ => Err(format!("`{text}` is not a tolerance in seconds in [0, 10]")),
    }
}

fn parse_finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("`{text}` is not a finite number")),
    }
}

/// Arguments of `vgps import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The source format.
    #[command(subcommand)]
    pub source: ImportSource,
}

/// What every import takes.
#[derive(Debug, Clone, Args)]
pub struct CommonImportArgs {
    /// The drive directory to write (created if missing; its files are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Rig calibration (any format `vgps calib` reads); copied into the drive (a directory
    /// is referenced by its absolute path).
    #[arg(long, value_name = "CAL")]
    pub rig: PathBuf,
    /// Surveyed landmarks CSV copied into the drive (default: an empty table).
    #[arg(long, value_name = "L.csv")]
    pub landmarks: Option<PathBuf>,
    /// Largest spread of the time stamps of one frame's images, seconds.
    #[arg(long, value_name = "S", default_value_t = DEFAULT_STAMP_TOLERANCE_S, value_parser = parse_tolerance)]
    pub stamp_tolerance_s: f64,
    /// No summary line.
    #[arg(long)]
    pub quiet: bool,
}

/// The sources `vgps import` reads.
#[derive(Debug, Subcommand)]
pub enum ImportSource {
    /// A rosbag2 recording in MCAP (CompressedImage/Image per camera, NavSatFix, Imu).
    Mcap {
        /// The MCAP file.
        file: PathBuf,
        /// Topic → camera mapping CSV `topic,camera` (default: the last number in the
        /// topic name is the camera).
        #[arg(long, value_name = "MAP.csv")]
        topics: Option<PathBuf>,
        /// The options every import takes.
        #[command(flatten)]
        common: CommonImportArgs,
    },
    /// An NCLT session directory (`lb3/Cam0…Cam5`, `gps.csv`, `gps_rtk.csv`, `groundtruth_<date>.csv`).
    Nclt {
        /// The session directory.
        session: PathBuf,
        /// Ellipsoidal height of the origin of NCLT's local frame, metres (truth heights).
        #[arg(long, value_name = "M", default_value_t = 0.0, value_parser = parse_finite, allow_hyphen_values = true)]
        origin_alt_m: f64,
        /// The options every import takes.
        #[command(flatten)]
        common: CommonImportArgs,
    },
    /// Per-camera folders of timestamped images (ROOT/cam0, ROOT/cam1, …).
    Folders {
        /// The folder holding one sub-folder per camera.
        root: PathBuf,
        /// Satellite GPS file copied into the drive (NMEA, GPX or NCLT gps.csv).
        #[arg(long, value_name = "FILE")]
        gnss: Option<PathBuf>,
        /// The options every import takes.
        #[command(flatten)]
        common: CommonImportArgs,
    },
}

/// The options of `vgps replay run.mcap` (ignored for a drive directory).
#[derive(Debug, Clone, Default, Args)]
pub struct McapInputArgs {
    /// For an MCAP recording as DRIVE: the rig calibration (any format `vgps calib` reads).
    #[arg(long, value_name = "CAL")]
    pub rig: Option<PathBuf>,
    /// For an MCAP recording as DRIVE: the surveyed landmarks CSV.
    #[arg(long, value_name = "L.csv")]
    pub landmarks: Option<PathBuf>,
    /// For an MCAP recording as DRIVE: the topic → camera mapping CSV.
    #[arg(long, value_name = "MAP.csv")]
    pub topics: Option<PathBuf>,
    /// For an MCAP recording as DRIVE: the largest spread of one frame's stamps, seconds.
    #[arg(long, value_name = "S", value_parser = parse_tolerance)]
    pub stamp_tolerance_s: Option<f64>,
}

/// Whether `path` names an MCAP recording rather than a drive directory.
pub fn is_mcap(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
        && !path.is_dir()
}

fn input_error(e: ImportError) -> CliError {
    match e {
        ImportError::Write { .. } => CliError::Output(std::io::Error::other(e.to_string())),
        e => CliError::Calibration(e.to_string()),
    }
}

fn print_warnings(report: &ImportReport, err: &mut dyn Write) {
    for w in &report.warnings {
        let _ = writeln!(err, "vgps: warning: {w}");
    }
    if report.more_warnings > 0 {
        let _ = writeln!(
            err,
            "vgps: warning: {} more warning(s)",
            report.more_warnings
        );
    }
}

fn mcap_options(
    rig: PathBuf,
    landmarks: Option<PathBuf>,
    topics: Option<&Path>,
    stamp_tolerance_s: f64,
    images: ImageOutput,
) -> Result<McapImportOptions, CliError> {
    Ok(McapImportOptions {
        rig,
        landmarks,
        topics: topics
            .map(read_topic_map)
            .transpose()
            .map_err(input_error)?,
        stamp_tolerance_s,
        images,
    })
}

/// A recording opened for `vgps replay run.mcap`: a temporary drive of its small files
/// (manifest, calibration, landmarks, frames, `gnss.nmea`, `imu.csv`), removed when this
/// drops, and where each frame's images are in the recording (no image file is written).
pub struct McapInput {
    /// The temporary drive directory.
    pub dir: tempfile::TempDir,
    /// The frames' images in the recording.
    pub images: RecordingImages,
}

/// Reads `file` into an [`McapInput`] for `vgps replay run.mcap`.
///
/// # Errors
/// [`CliError::Calibration`] (exit 2) without `--rig` or when the file cannot be read.
pub fn mcap_to_temp_drive(
    file: &Path,
    args: &McapInputArgs,
    err: &mut dyn Write,
) -> Result<McapInput, CliError> {
    let rig = args.rig.clone().ok_or_else(|| {
        CliError::Calibration(format!(
            "{}: an MCAP recording needs --rig CAL (the rig calibration)",
            file.display()
        ))
    })?;
    let options = mcap_options(
        rig,
        args.landmarks.clone(),
        args.topics.as_deref(),
        args.stamp_tolerance_s.unwrap_or(DEFAULT_STAMP_TOLERANCE_S),
        // The replay reads the images from the recording: none is written.
        ImageOutput::InRecording,
    )?;
    let dir = tempfile::Builder::new()
        .prefix("vgps-mcap-")
        .tempdir()
        .map_err(CliError::Output)?;
    let imported = import_mcap(file, dir.path(), &options).map_err(input_error)?;
    print_warnings(&imported.report, err);
    let images = imported
        .recording_images
        .ok_or_else(|| CliError::Internal("the MCAP import gave no image places".to_string()))?;
    Ok(McapInput { dir, images })
}

/// Runs `vgps import`.
///
/// # Errors
/// [`CliError::Calibration`] (exit 2) for an unusable input, [`CliError::Output`] when the
/// drive cannot be written. Damaged records and skipped inputs are warnings on `err`.
pub fn run(args: &ImportArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<(), CliError> {
    let (common, report, extra) = match &args.source {
        ImportSource::Mcap {
            file,
            topics,
            common,
        } => {
            let options = mcap_options(
                common.rig.clone(),
                common.landmarks.clone(),
                topics.as_deref(),
                common.stamp_tolerance_s,
                ImageOutput::Files,
            )?;
            let imported = import_mcap(file, &common.out, &options).map_err(input_error)?;
            let m = &imported.mcap;
            let ignored: Vec<String> = imported
                .ignored_types
                .iter()
                .map(|(t, n)| format!("{t} ×{n}"))
                .collect();
            let extra = format!(
                "; MCAP: {} bytes, {} records, {} chunks ({} skipped), {} messages{}{}",
                m.bytes,
                m.records,
                m.chunks,
                m.bad_chunks,
                m.messages,
                if m.truncated { ", cut short" } else { "" },
                if ignored.is_empty() {
                    String::new()
                } else {
                    format!("; ignored: {}", ignored.join(", "))
                }
            );
            (common, imported.report, extra)
        }
        ImportSource::Nclt {
            session,
            origin_alt_m,
            common,
        } => {
            let options = NcltImportOptions {
                rig: common.rig.clone(),
                landmarks: common.landmarks.clone(),
                stamp_tolerance_s: common.stamp_tolerance_s,
                origin_alt_m: *origin_alt_m,
            };
            let (_, report) = import_nclt(session, &common.out, &options).map_err(input_error)?;
            (common, report, String::new())
        }
        ImportSource::Folders { root, gnss, common } => {
            let options = FolderImportOptions {
                rig: common.rig.clone(),
                landmarks: common.landmarks.clone(),
                gnss: gnss.clone(),
                stamp_tolerance_s: common.stamp_tolerance_s,
            };
            let (_, report) = import_folders(root, &common.out, &options).map_err(input_error)?;
            (common, report, String::new())
        }
    };
    print_warnings(&report, err);
    if !common.quiet {
        writeln!(out, "{}: {}{extra}", common.out.display(), report.summary())?;
    }
    Ok(())
}
