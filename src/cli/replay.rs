//! `vgps replay DRIVE`: visual GPS for every frame of a logged drive, compared with the
//! satellite GPS recorded alongside (and with truth when there is one); writes the report
//! files of `docs/replay-report.md`.
//!
//! # Order and parallelism
//! The localizer's state (motion model, mapped surrogates) forces frames to be localized in
//! time order, on one thread. What does not depend on that state runs in parallel: decoding
//! and lamp detection of the images (`--threads`), in batches of [`BATCH_FRAMES`] frames
//! whose detections are then localized in order; with more than one thread the next batch's
//! images are decoded and detected while this batch is localized. From `detections.csv` the
//! localizer alone runs, on one thread. Unless `--quiet`, the time per frame of each stage is
//! reported on stderr.

use super::{CliError, ReplaySettings};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vgps_camera::imaging::ImagingError;
use vgps_core::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerFix, LocalizerOptions, LocalizerStatus,
};
use vgps_core::matcher::{DEFAULT_VISIBILITY_RANGE_M, MatchOptions};
use vgps_import::mcap_import::{FrameStream, RecordingImages};
use vgps_replay::drive::gnss::gnss_at;
use vgps_replay::drive::{Drive, FrameStatus};
use vgps_replay::frame_images::{DetectorKind, ImageDetector};
use vgps_replay::report::{
    BackwardFix, DriveInfo, FrameOutcome, Report, Truth, VisualFix, combine_passes, summary_table,
};

/// The status of a frame none of whose images could be used.
pub const BAD_IMAGE_STATUS: &str = "bad_image";
/// Frames decoded and detected together before they are localized in order.
pub const BATCH_FRAMES: usize = 64;
/// Default of `--matcher-memory-mib`: 1 GiB, four times the library's default
/// ([`vgps_core::matcher::DEFAULT_CACHE_BUDGET_BYTES`]): a replay runs on a workstation.
pub const DEFAULT_MATCHER_MEMORY_MIB: u32 = 1024;

/// Output formats of the summary on stdout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OutputFormat {
    /// A table for people.
    Text,
    /// The `report.json` summary, for scripts.
    Json,
}

/// The passes of a replay over the drive's frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Direction {
    /// Frames in time order, as a receiver would have localized them live.
    #[default]
    Forward,
    /// A forward pass, then a backward pass (frames in reverse order) that fills the frames
    /// the forward pass left without a fix: after a survey gap or a lost track, the backward
    /// pass arrives tracking from the other side (docs/replay-report.md).
    Combined,
}

/// Arguments of `vgps replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// The drive directory (with `drive.json`; see docs/drive-format.md), or a rosbag2
    /// recording `run.mcap` (with `--rig`; see docs/import.md).
    pub drive: PathBuf,
    /// Output directory (default: `DRIVE/replay`); created if missing, files replaced
    /// atomically.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Threads for image decoding and lamp detection (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar and no summary table.
    #[arg(long)]
    pub quiet: bool,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: OutputFormat,
    /// Image size WxH of cameras whose calibration names none (a Ladybug INI dump), for
    /// `--from-images`; by default taken from the images (all of those cameras must agree).
    #[arg(long, value_parser = super::image_size::parse_image_size)]
    pub image_size: Option<(u32, u32)>,
    /// Unknown keys in drive.json are an error (default: a warning).
    #[arg(long)]
    pub strict: bool,
    /// Pixel σ of a detection (pixels).
    #[arg(long, default_value_t = vgps_core::localizer::DEFAULT_PIXEL_SIGMA_PX)]
    pub pixel_sigma_px: f64,
    /// Do not map secondary landmarks or use them as surrogates.
    #[arg(long)]
    pub no_surrogates: bool,
    /// Do not use satellite GPS as a prior (only to compare with).
    #[arg(long)]
    pub no_gnss_prior: bool,
    /// Do not use the drive's IMU (`imu.csv`) as the matcher's vertical and heading prior.
    #[arg(long)]
    pub no_imu: bool,
    /// The rig's +z axis is within this many degrees of up when no IMU says otherwise: the
    /// matcher's vertical. Overrides the calibration's `level_within_deg`; without either,
    /// 5° (a vehicle rig).
    #[arg(long, value_name = "DEG", value_parser = super::args::parse_non_negative)]
    pub up_tolerance_deg: Option<f64>,
    /// Landmarks farther than this are not expected to be seen (metres; the matcher's
    /// visibility range). Default 80 m, but 150 m when the detections come from the images
    /// through `--detector vertex`: building corners are found by day to 150 m
    /// (docs/dev/journal.md, 2026-11-27).
    #[arg(long, value_name = "M", value_parser = super::args::parse_positive)]
    pub visibility_range_m: Option<f64>,
    /// Memory the matcher may keep per search for its pair tables (MiB). The fixes are the
    /// same for any value; a larger budget rebuilds fewer tables in wide searches (cold
    /// starts, searches around the last place known). 256 (the library's default) lowers the
    /// peak memory of a drive with long searches from about 1.4 to 0.55 GB and takes about
    /// 40 % more time on them (docs/matcher.md, "Memory").
    #[arg(long, value_name = "MIB", default_value_t = DEFAULT_MATCHER_MEMORY_MIB)]
    pub matcher_memory_mib: u32,
    /// Drift of a pose carried on surrogate landmarks, in percent of the distance travelled
    /// since the fix last rested on surveyed landmarks (1σ per axis): added to the reported
    /// covariance, nothing else. The default (0.1 %) covers the detectors measured in
    /// docs/localizer.md ("Honest covariance"); measure your own detector's with truth.
    #[arg(long, value_name = "PERCENT", default_value_t = 100.0 * vgps_core::localizer::DEFAULT_SURROGATE_DRIFT_PER_M, value_parser = super::args::parse_non_negative)]
    pub surrogate_drift_percent: f64,
    /// Largest change of the turn rate between two fixes that tracking recovers by turning
    /// its prediction about the vertical (degrees per second; `0` turns it off). The
    /// motion model keeps the last turn rate, so a turn that starts or ends between two
    /// frames leaves the predicted heading off (docs/localizer.md, "When the turn was
    /// missed").
    #[arg(long, value_name = "DEG_PER_S", default_value_t = vgps_core::localizer::DEFAULT_MAX_TURN_RATE_CHANGE_RAD_S.to_degrees(), value_parser = super::args::parse_non_negative)]
    pub max_turn_rate_change_deg_s: f64,
    /// Detect landmarks in the images even when the drive has `detections.csv`.
    #[arg(long)]
    pub from_images: bool,
    /// The detector of the images: `point`, `street` (lamps, night) or `vertex` (building
    /// corners, day); see `vgps detect --detector`.
    #[arg(long, value_enum, default_value = "point")]
    pub detector: super::detect::DetectorArg,
    /// `forward`: frames in time order, as live; `combined`: then a backward pass fills
    /// the frames left without a fix (offline post-processing).
    #[arg(long, value_enum, default_value = "forward")]
    pub direction: Direction,
    /// Satellite GPS from another file.
    #[command(flatten)]
    pub gnss: super::gnss_input::GnssInputArgs,
    /// An MCAP recording as DRIVE (imported into a temporary drive, removed afterwards).
    #[command(flatten)]
    pub mcap: super::import::McapInputArgs,
    /// Live NMEA for gpsd and ROS 2 messages.
    #[command(flatten)]
    pub robot: super::robot_out::RobotOutputArgs,
}

/// The detections of one frame, or why there are none; `unusable_images` counts the
/// frame's images that could not be used (`None`: the detections came from a file, and are
/// borrowed from the drive).
enum FrameDetections<'a> {
    Ok {
        detections: std::borrow::Cow<'a, [vgps_replay::drive::PixelDetection]>,
        unusable_images: Option<u32>,
        problems: Option<String>,
    },
    Bad {
        message: String,
        unusable_images: Option<u32>,
    },
}

impl<'a> FrameDetections<'a> {
    fn from_file(detections: &'a [vgps_replay::drive::PixelDetection]) -> Self {
        Self::Ok {
            detections: std::borrow::Cow::Borrowed(detections),
            unusable_images: None,
            problems: None,
        }
    }
}

/// Runs `vgps replay`.
///
/// # Errors
/// [`CliError::Input`]/[`CliError::Calibration`] when the drive cannot be used at all;
/// [`CliError::Output`] when an output cannot be written. Frames without a fix are reported
/// in the outputs, not errors.
pub fn run(
    settings: &ReplaySettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    run_report(settings, out, err).map(|_| ())
}

/// [`run`], returning the report's statistics (what `report.json` holds): `vgps demo`
/// builds its own summary from them.
///
/// # Errors
/// As [`run`].
pub fn run_report(
    settings: &ReplaySettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<Report, CliError> {
    // An MCAP recording is imported into a temporary drive, removed when `imported` drops.
    let imported = if super::import::is_mcap(&settings.drive) {
        Some(super::import::mcap_to_temp_drive(
            &settings.drive,
            &settings.mcap,
            err,
        )?)
    } else {
        None
    };
    let drive_dir = imported
        .as_ref()
        .map_or(settings.drive.clone(), |d| d.dir.path().to_path_buf());
    let recording = imported.as_ref().map(|d| &d.images);
    let mut drive = Drive::open(&drive_dir, settings.strictness)
        .map_err(|e| CliError::Calibration(e.to_string()))?;
    if settings.from_images
        || drive.manifest().detections.is_none()
        || settings.image_size.is_some()
    {
        let note = match recording {
            Some(r) => super::image_size::resolve_with(&mut drive, settings.image_size, &|n| {
                (
                    r.contains(n),
                    r.dimensions(n),
                    r.describe(n).display().to_string(),
                )
            })?,
            None => super::image_size::resolve(&mut drive, settings.image_size)?,
        };
        if let Some(note) = note {
            let _ = writeln!(err, "vgps: {note}");
        }
    }
    settings.gnss.apply(&mut drive, err)?;
    warn_about_drive(&drive, &settings.drive, err);
    let map = Arc::new(
        LandmarkMap::from_landmarks(drive.landmarks(), None)
            .map_err(|e| CliError::Calibration(format!("{}: {e}", settings.drive.display())))?,
    );
    let rig = Arc::new(drive.rig().clone());
    let from_images = settings.from_images || drive.manifest().detections.is_none();
    let options = localizer_options(settings, &rig, from_images);
    let mut localizer = Localizer::new(Arc::clone(&rig), Arc::clone(&map), options)
        .map_err(|e| CliError::Internal(e.to_string()))?;
    // An unusable output directory fails now, not after the whole drive is localized.
    let out_dir = &settings.out_dir;
    std::fs::create_dir_all(out_dir).map_err(|e| {
        CliError::Output(std::io::Error::new(
            e.kind(),
            format!("{}: {e}", out_dir.display()),
        ))
    })?;
    let frames = drive.frames();
    let progress = progress_bar(settings, frames.len());
    let mut records = Vec::with_capacity(frames.len());
    // The localizer's input of every frame, for the backward pass.
    let combined = settings.direction == Direction::Combined;
    let mut kept_frames: Vec<Option<Frame>> = Vec::new();
    let detector = ImageDetector::new(settings.detector, drive.rig());
    let mut live = super::robot_out::LiveStream::start(&settings.robot, err);
    let mut used = std::collections::BTreeMap::new();
    // From a recording, a reader thread yields the frames' images in order, a batch ahead.
    let stream = recording
        .filter(|_| from_images)
        .map(|r| std::sync::Mutex::new(r.stream(BATCH_FRAMES)));
    let mut timing = StageTiming::default();
    let image_busy = AtomicU64::new(0);
    // A batch's images, decoded and detected on `settings.threads` threads.
    let detect_images = |batch: &[vgps_replay::drive::FrameRecord]| {
        let started = Instant::now();
        let detections = if let (Some(r), Some(s)) = (recording, &stream) {
            detect_recording_batch(
                &drive,
                batch,
                settings.threads,
                &detector,
                r,
                s,
                &image_busy,
            )
        } else {
            detect_batch(&drive, batch, settings.threads, &detector, &image_busy)
        };
        (detections, started.elapsed())
    };
    let detect_images = &detect_images;
    // With more than one thread, the images of the next batch are decoded and detected
    // while this batch is localized (the localizer's order-bound work overlaps the images').
    let pipelined = from_images && settings.threads > 1;
    let batches: Vec<&[vgps_replay::drive::FrameRecord]> = frames.chunks(BATCH_FRAMES).collect();
    // A batch held back until the next one's detections are known, and whether the localizer
    // was lost at the end of the last batch localized.
    let mut held: Option<Vec<PendingFrame>> = None;
    let mut lost = false;
    std::thread::scope(|scope| {
        let mut next: Option<std::thread::ScopedJoinHandle<'_, _>> = None;
        for (index, &batch) in batches.iter().enumerate() {
            let waited = Instant::now();
            let detections: Vec<FrameDetections> = if from_images {
                let (d, took) = match next.take() {
                    Some(handle) => handle
                        .join()
                        .unwrap_or_else(|_| (failed_batch(batch.len()), Duration::ZERO)),
                    None => detect_images(batch),
                };
                timing.image_wall += took;
                d
            } else {
                file_detections(&drive, batch, err)
            };
            timing.waited += waited.elapsed();
            if pipelined && let Some(&following) = batches.get(index + 1) {
                next = Some(scope.spawn(move || detect_images(following)));
            }
            let localizing = Instant::now();
            let mut step = FrameStep {
                drive: &drive,
                map: &map,
                localizer: &mut localizer,
                gnss_prior: settings.gnss_prior,
                imu: settings.imu,
                threads: settings.threads,
                used: &mut used,
            };
            let current = step.pending_batch(batch, detections, err);
            let mut localized = Vec::new();
            if let Some(previous) = held.take() {
                localized.extend(step.localize(previous, &current));
                lost = localized.last().is_some_and(|(r, _)| r.visual.is_none());
            }
            // A localizer lost at the end of a batch searches on the next frames: with more
            // than one thread, the batch waits for the next one, whose searches may then
            // start while this one is localized.
            if lost && settings.threads > 1 && index + 1 < batches.len() {
                held = Some(current);
            } else {
                localized.extend(step.localize(current, &[]));
                lost = localized.last().is_some_and(|(r, _)| r.visual.is_none());
            }
            for (record, frame) in localized {
                live.send(&record, err);
                records.push(record);
                if combined {
                    kept_frames.push(frame);
                }
            }
            timing.localized += localizing.elapsed();
            if let Some(bar) = &progress {
                bar.inc(batch.len() as u64);
            }
        }
    });
    timing.image_busy = Duration::from_nanos(image_busy.load(Ordering::Relaxed));
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    if !settings.quiet {
        let _ = writeln!(
            err,
            "vgps: {}",
            timing.describe(
                frames.len(),
                from_images,
                settings.threads,
                pipelined,
                &localizer.batch_stats()
            )
        );
    }
    if combined {
        let backward = Localizer::new(Arc::clone(&rig), Arc::clone(&map), options)
            .map_err(|e| CliError::Internal(e.to_string()))?;
        let c = fill_from_backward_pass(
            backward,
            kept_frames,
            settings.threads,
            &mut records,
            &mut used,
        );
        if !settings.quiet {
            let _ = writeln!(
                err,
                "vgps: combined: forward pass {} fixes, backward pass {}, {} frames filled by \
                 the backward pass, {} fixed by both at positions that disagree",
                c.forward, c.backward, c.filled, c.disagreeing
            );
        }
    }
    let info = DriveInfo {
        name: drive_name(&settings.drive),
        origin: map.frame().origin(),
    };
    live.finish(err);
    let extras = vgps_replay::report::MapExtras {
        landmarks: drive.landmarks().to_vec(),
        used,
    };
    let (report, _files) =
        vgps_replay::report::write_outputs_with(out_dir, &info, &records, &extras)
            .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())))?;
    super::robot_out::write_mcap(&settings.robot, &info, &records)?;
    write_summary(&report, settings, out_dir, out)?;
    Ok(report)
}

/// The localizer's options from the command line and the rig.
fn localizer_options(
    settings: &ReplaySettings,
    rig: &vgps_camera::calibration::Rig,
    from_images: bool,
) -> LocalizerOptions {
    LocalizerOptions {
        pixel_sigma_px: settings.pixel_sigma_px,
        surrogates: settings.surrogates,
        surrogate_drift_per_m: settings.surrogate_drift_per_m,
        max_turn_rate_change_rad_s: settings.max_turn_rate_change_rad_s,
        // The flag, else the calibration's declaration, else the default (5°).
        level_tolerance_rad: settings
            .up_tolerance_rad
            .or(rig.level_within_rad())
            .or(LocalizerOptions::default().level_tolerance_rad),
        matcher: MatchOptions {
            visibility_range_m: visibility_range_m(
                settings.visibility_range_m,
                from_images,
                settings.detector,
            ),
            cache_budget_bytes: settings.matcher_memory_bytes,
            ..LocalizerOptions::default().matcher
        },
        ..LocalizerOptions::default()
    }
}

/// A progress bar over `frames` frames on a terminal, unless `--quiet`.
fn progress_bar(settings: &ReplaySettings, frames: usize) -> Option<indicatif::ProgressBar> {
    (!settings.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(frames as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} replay [{bar:40}] {pos}/{len} frames {per_sec} ETA {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    })
}

/// Writes the drive's warnings (manifest, skipped NMEA lines) to `err`.
fn warn_about_drive(drive: &Drive, dir: &Path, err: &mut dyn Write) {
    for w in drive.warnings() {
        let _ = writeln!(err, "vgps: warning: {w}");
    }
    if let Some(stats) = drive.nmea_stats()
        && stats.skipped() > 0
    {
        let _ = writeln!(
            err,
            "vgps: warning: {}: {} NMEA line(s) skipped (bad checksum, garbage or truncated)",
            dir.display(),
            stats.skipped()
        );
    }
}

/// The detections of a batch of frames from the drive's detections file (bad rows are
/// reported on `err`; the frame's readable rows are still used).
fn file_detections<'a>(
    drive: &'a Drive,
    batch: &[vgps_replay::drive::FrameRecord],
    err: &mut dyn Write,
) -> Vec<FrameDetections<'a>> {
    batch
        .iter()
        .map(|f| match drive.status(f.frame) {
            FrameStatus::Ok => FrameDetections::from_file(drive.detections(f.frame)),
            FrameStatus::BadRows(messages) => {
                let _ = writeln!(err, "vgps: warning: {}", messages.join("; "));
                FrameDetections::from_file(drive.detections(f.frame))
            }
        })
        .collect()
}

/// What localizes the frames of a drive, in time order.
struct FrameStep<'d, 'l> {
    drive: &'d Drive,
    map: &'d LandmarkMap,
    localizer: &'l mut Localizer,
    gnss_prior: bool,
    imu: bool,
    /// Threads of the localizer's searches run ahead ([`Localizer::process_batch`]).
    threads: usize,
    /// Frame → ids of the surveyed landmarks its fix used (for the report's map).
    used: &'l mut std::collections::BTreeMap<u64, Vec<String>>,
}

/// A frame before localization: what its record says besides the fix, and the localizer's
/// input (or why the frame has none).
struct PendingFrame {
    frame: u64,
    time_s: f64,
    gnss: Option<vgps_geometry::geo::Geodetic>,
    truth: Option<Truth>,
    unusable_images: Option<u32>,
    input: Result<Frame, String>,
}

impl FrameStep<'_, '_> {
    /// The frames of a batch before localization (a frame without usable images is
    /// reported as [`BAD_IMAGE_STATUS`] on `err`).
    fn pending_batch(
        &self,
        batch: &[vgps_replay::drive::FrameRecord],
        detections: Vec<FrameDetections<'_>>,
        err: &mut dyn Write,
    ) -> Vec<PendingFrame> {
        batch
            .iter()
            .zip(detections)
            .map(|(f, d)| self.pending(f, d, err))
            .collect()
    }

    /// Localizes a batch of frames and returns their report records with the localizer's
    /// inputs; `ahead` is the next batch, when known (its searches may start now).
    fn localize(
        &mut self,
        pending: Vec<PendingFrame>,
        ahead: &[PendingFrame],
    ) -> Vec<(FrameOutcome, Option<Frame>)> {
        let inputs = |p: &[PendingFrame]| -> Vec<Frame> {
            p.iter()
                .filter_map(|p| p.input.as_ref().ok().cloned())
                .collect()
        };
        let mut fixes = self
            .localizer
            .process_batch(&inputs(&pending), &inputs(ahead), self.threads)
            .into_iter();
        pending
            .into_iter()
            .map(|p| {
                let fix = p.input.is_ok().then(|| fixes.next()).flatten();
                self.finish(p, fix)
            })
            .collect()
    }

    fn pending(
        &self,
        f: &vgps_replay::drive::FrameRecord,
        d: FrameDetections<'_>,
        err: &mut dyn Write,
    ) -> PendingFrame {
        let gnss = gnss_at(self.drive.gnss(), f.time_s);
        let truth = self.drive.truth_of(f.frame).map(|t| Truth {
            geodetic: t.position,
            heading_deg: vgps_sim::simulate::heading_deg(&t.enu_from_rig),
        });
        let (unusable_images, input) = match d {
            FrameDetections::Bad {
                message,
                unusable_images,
            } => {
                let _ = writeln!(err, "vgps: frame {}: {message}", f.frame);
                (unusable_images, Err(message))
            }
            FrameDetections::Ok {
                detections: dets,
                unusable_images,
                problems,
            } => {
                if let Some(p) = problems {
                    let _ = writeln!(
                        err,
                        "vgps: warning: frame {}: {} image(s) unusable, localized with the others: {p}",
                        f.frame,
                        unusable_images.unwrap_or(0)
                    );
                }
                let prior = if self.gnss_prior {
                    gnss.map(|position| GnssPosition { position })
                } else {
                    None
                };
                let frame = Frame::from_detections(f.time_s, &dets, self.map, prior)
                    .with_attitude(self.imu.then(|| self.drive.attitude_at(f.time_s)).flatten());
                (unusable_images, Ok(frame))
            }
        };
        PendingFrame {
            frame: f.frame,
            time_s: f.time_s,
            gnss,
            truth,
            unusable_images,
            input,
        }
    }

    /// A frame's record from its localizer fix (`None` for a frame without input).
    fn finish(
        &mut self,
        p: PendingFrame,
        fix: Option<LocalizerFix>,
    ) -> (FrameOutcome, Option<Frame>) {
        let (status, visual, message, localized) = match (p.input, fix) {
            (Ok(frame), Some(fix)) => {
                if let Some(e) = &fix.estimate {
                    self.used.insert(p.frame, e.landmarks.clone());
                }
                (
                    fix.status.as_str().to_string(),
                    visual_of(&fix),
                    fix.message,
                    Some(frame),
                )
            }
            (Ok(frame), None) => (
                LocalizerStatus::NoFix.as_str().to_string(),
                None,
                "not localized".to_string(),
                Some(frame),
            ),
            (Err(message), _) => (BAD_IMAGE_STATUS.to_string(), None, message, None),
        };
        let outcome = FrameOutcome {
            frame: p.frame,
            time_s: p.time_s,
            status,
            visual,
            gnss: p.gnss,
            unusable_images: p.unusable_images,
            truth: p.truth,
            message,
        };
        (outcome, localized)
    }
}

/// Runs the backward pass over `frames` and fills the `records` the forward pass left
/// without a fix ([`combine_passes`]), with their landmarks in `used`.
fn fill_from_backward_pass(
    mut localizer: Localizer,
    frames: Vec<Option<Frame>>,
    threads: usize,
    records: &mut [FrameOutcome],
    used: &mut std::collections::BTreeMap<u64, Vec<String>>,
) -> vgps_replay::report::Combination {
    let fixes = backward_pass(&mut localizer, frames, records, threads);
    let mut backward = Vec::with_capacity(fixes.len());
    for (r, fix) in records.iter().zip(fixes) {
        backward.push(fix.map(|fix| {
            if let (None, Some(e)) = (&r.visual, &fix.estimate) {
                used.insert(r.frame, e.landmarks.clone());
            }
            BackwardFix {
                visual: visual_of(&fix),
                message: fix.message,
            }
        }));
    }
    combine_passes(records, &backward, LocalizerStatus::Ok.as_str())
}

/// The backward pass of `--direction combined`: the frames localized in reverse order by
/// their own localizer ([`Localizer::process_backward`]), in the records' order (`None`
/// for a frame without usable detections).
///
/// A frame the forward pass fixed gives its fix as the backward pass's prior, in place of
/// the satellite position: where the backward track is lost, it is found again at once
/// around the forward fix instead of waiting for a cold start, so the pass costs about what
/// tracking costs. Frames the forward pass did not fix keep their satellite prior, if any.
fn backward_pass(
    localizer: &mut Localizer,
    frames: Vec<Option<Frame>>,
    forward: &[FrameOutcome],
    threads: usize,
) -> Vec<Option<LocalizerFix>> {
    // The frames with input, latest first, each with its seed.
    let (indices, inputs): (Vec<usize>, Vec<Frame>) = frames
        .into_iter()
        .zip(forward)
        .enumerate()
        .rev()
        .filter_map(|(k, (frame, record))| {
            let frame = frame?;
            let seed = record
                .visual
                .as_ref()
                .map(|v| GnssPosition {
                    position: v.geodetic,
                })
                .or(frame.gnss);
            Some((
                k,
                Frame {
                    gnss: seed,
                    ..frame
                },
            ))
        })
        .unzip();
    let mut out = vec![None; forward.len()];
    let fixes = localizer.process_backward_batch(&inputs, threads);
    for (k, fix) in indices.into_iter().zip(fixes) {
        out[k] = Some(fix);
    }
    out
}

fn write_summary(
    report: &Report,
    settings: &ReplaySettings,
    out_dir: &Path,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    match settings.format {
        OutputFormat::Json => write!(out, "{}", report.to_json())?,
        OutputFormat::Text if !settings.quiet => {
            write!(out, "{}", summary_table(report))?;
            writeln!(out, "report: {}", out_dir.join("report.html").display())?;
        }
        OutputFormat::Text => {}
    }
    Ok(())
}

fn drive_name(dir: &Path) -> String {
    dir.canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| dir.display().to_string())
}

/// The report's view of a localizer fix.
fn visual_of(fix: &LocalizerFix) -> Option<VisualFix> {
    VisualFix::from_localizer(fix)
}

/// Where a replay's time went: the images' stage (parallel) and the localizer's (serial).
#[derive(Debug, Default)]
struct StageTiming {
    /// Thread time spent decoding and detecting images, summed over the frames.
    image_busy: Duration,
    /// Wall time of the batches' image stages, summed (overlapping the localizer's when
    /// pipelined).
    image_wall: Duration,
    /// Wall time the localizing thread spent waiting for a batch's detections (or reading
    /// them from `detections.csv`).
    waited: Duration,
    /// Wall time spent localizing frames, in order, on one thread.
    localized: Duration,
}

impl StageTiming {
    /// One line for people: per frame, the images' thread time and the localizer's time.
    fn describe(
        &self,
        frames: usize,
        from_images: bool,
        threads: usize,
        pipelined: bool,
        searches: &vgps_core::localizer::BatchStats,
    ) -> String {
        let per_frame = |d: Duration| d.as_secs_f64() * 1e3 / frames.max(1) as f64;
        let localizer = if threads > 1 {
            format!(
                "localizer {:.2} ms per frame of wall, of which {:.2} serial (frames in order: \
                 tracking, planning, {} unplanned search(es)) and {:.2} waiting for {} of {} \
                 searches run ahead on {threads} threads ({:.2} ms per frame of their thread \
                 time, {:.2} of it in {} searches not used)",
                per_frame(self.localized),
                per_frame(self.localized.saturating_sub(searches.waiting)),
                searches.unplanned,
                per_frame(searches.waiting),
                searches.served,
                searches.planned,
                per_frame(searches.worker_time),
                per_frame(searches.wasted_time),
                searches.wasted,
            )
        } else {
            format!(
                "localizer {:.2} ms per frame (serial: one thread, frames in order)",
                per_frame(self.localized)
            )
        };
        if !from_images {
            return format!("time: {localizer}, detections read from the drive");
        }
        format!(
            "time: images {:.2} ms per frame of thread time, {:.2} ms of wall (decode + detect, \
             {threads} thread{}{}), {localizer}, {:.2} ms per frame waiting for images",
            per_frame(self.image_busy),
            per_frame(self.image_wall),
            if threads == 1 { "" } else { "s" },
            if pipelined {
                ", the next batch's while this one is localized"
            } else {
                ""
            },
            per_frame(self.waited)
        )
    }
}

/// `f()`, its duration added to `busy` (nanoseconds).
fn timed<T>(busy: &AtomicU64, f: impl FnOnce() -> T) -> T {
    let started = Instant::now();
    let value = f();
    let nanos = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
    busy.fetch_add(nanos, Ordering::Relaxed);
    value
}

/// One `Bad` result per frame of a batch whose detection thread failed, so that frames stay
/// aligned with their records.
fn failed_batch(frames: usize) -> Vec<FrameDetections<'static>> {
    (0..frames)
        .map(|_| FrameDetections::Bad {
            message: "detection thread failed".into(),
            unusable_images: None,
        })
        .collect()
}

/// Decodes and detects the images of a batch of frames on `threads` threads.
fn detect_batch(
    drive: &Drive,
    batch: &[vgps_replay::drive::FrameRecord],
    threads: usize,
    detector: &ImageDetector,
    busy: &AtomicU64,
) -> Vec<FrameDetections<'static>> {
    let chunk = batch.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        let handles: Vec<_> = batch
            .chunks(chunk)
            .map(|frames| {
                let handle = scope.spawn(move || {
                    frames
                        .iter()
                        .map(|f| {
                            timed(busy, || {
                                detect_frame(drive, f, detector, &mut |_, name| {
                                    let path = drive.dir().join(name);
                                    match std::fs::read(&path) {
                                        Ok(bytes) => Ok((path, bytes)),
                                        Err(source) => Err(ImagingError::Io { path, source }),
                                    }
                                })
                            })
                        })
                        .collect::<Vec<_>>()
                });
                (handle, frames.len())
            })
            .collect();
        handles
            .into_iter()
            // One result per frame even if the thread failed, so frames stay aligned.
            .flat_map(|(h, n)| h.join().unwrap_or_else(|_| failed_batch(n)))
            .collect()
    })
}

/// [`detect_batch`] with the images read from the recording (`vgps replay run.mcap`):
/// `threads` workers take the batch's frames from `stream` one at a time, in order, so at
/// most a few frames' images are in memory.
fn detect_recording_batch(
    drive: &Drive,
    batch: &[vgps_replay::drive::FrameRecord],
    threads: usize,
    detector: &ImageDetector,
    recording: &RecordingImages,
    stream: &Mutex<FrameStream>,
    busy: &AtomicU64,
) -> Vec<FrameDetections<'static>> {
    let taken = AtomicUsize::new(0);
    let worker = || {
        let mut done = Vec::new();
        loop {
            let (i, images) = {
                let mut stream = match stream.lock() {
                    Ok(s) => s,
                    Err(poisoned) => poisoned.into_inner(),
                };
                let i = taken.fetch_add(1, Ordering::Relaxed);
                if i >= batch.len() {
                    break;
                }
                (i, stream.next())
            };
            let frame = &batch[i];
            let detections = match images {
                Some(mut images) if images.frame == frame.frame => timed(busy, || {
                    detect_frame(drive, frame, detector, &mut |camera, name| {
                        let path = recording.describe(name);
                        match images.images.get_mut(camera).and_then(Option::take) {
                            Some(Ok(bytes)) => Ok((path, bytes)),
                            Some(Err(why)) => Err(ImagingError::Io {
                                path,
                                source: std::io::Error::other(why),
                            }),
                            None => Err(ImagingError::Io {
                                path,
                                source: std::io::ErrorKind::NotFound.into(),
                            }),
                        }
                    })
                }),
                other => FrameDetections::Bad {
                    message: format!(
                        "{}: the images of frame {} could not be read again (got {})",
                        recording.file().display(),
                        frame.frame,
                        other.map_or("none".to_string(), |o| format!("frame {}", o.frame))
                    ),
                    unusable_images: None,
                },
            };
            done.push((i, detections));
        }
        done
    };
    let mut all: Vec<(usize, FrameDetections<'static>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads.clamp(1, batch.len().max(1)))
            .map(|_| scope.spawn(worker))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .collect()
    });
    all.sort_by_key(|(i, _)| *i);
    // One result per frame even if a thread failed, so frames stay aligned.
    let mut out = Vec::with_capacity(batch.len());
    let mut results = all.into_iter().peekable();
    for i in 0..batch.len() {
        match results.next_if(|(j, _)| *j == i) {
            Some((_, d)) => out.push(d),
            None => out.push(FrameDetections::Bad {
                message: "detection thread failed".into(),
                unusable_images: None,
            }),
        }
    }
    out
}

/// Decodes and detects one frame's images, read by `load(camera, name)`.
fn detect_frame(
    drive: &Drive,
    frame: &vgps_replay::drive::FrameRecord,
    detector: &ImageDetector,
    load: &mut vgps_replay::frame_images::ImageLoader<'_>,
) -> FrameDetections<'static> {
    if frame.images.iter().all(Option::is_none) {
        return FrameDetections::Bad {
            message: "no images and no detections".into(),
            unusable_images: Some(0),
        };
    }
    let result =
        vgps_replay::frame_images::detect_frame_images_from(frame, drive.rig(), detector, load);
    let unusable_images = Some(u32::try_from(result.problems.len()).unwrap_or(u32::MAX));
    if result.is_unusable() {
        FrameDetections::Bad {
            message: result.problem_text(),
            unusable_images,
        }
    } else {
        // A frame with some unusable images is localized with the others (even when they
        // show no lamp: the localizer then reports the frame's status), and counted.
        FrameDetections::Ok {
            problems: (!result.problems.is_empty()).then(|| result.problem_text()),
            detections: std::borrow::Cow::Owned(result.detections),
            unusable_images,
        }
    }
}

/// The matcher's visibility range: the flag's, else the image detector's own
/// ([`DetectorKind::visibility_range_m`]: 150 m for building corners) when the detections
/// come from the images, else [`DEFAULT_VISIBILITY_RANGE_M`]. A `detections.csv` replay
/// keeps the default whatever `--detector` says: its detections are not the detector's.
fn visibility_range_m(flag: Option<f64>, from_images: bool, detector: DetectorKind) -> f64 {
    match flag {
        Some(m) => m,
        None if from_images => detector
            .visibility_range_m()
            .unwrap_or(DEFAULT_VISIBILITY_RANGE_M),
        None => DEFAULT_VISIBILITY_RANGE_M,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn building_corners_from_images_are_matched_to_150_m_and_everything_else_to_80_m() {
        use DetectorKind::{Point, Street, Vertex};
        assert_eq!(visibility_range_m(None, true, Vertex), 150.0);
        // Lamps by night, and any detections.csv replay, keep the matcher's default.
        for (from_images, detector) in [(true, Point), (true, Street), (false, Vertex)] {
            assert_eq!(
                visibility_range_m(None, from_images, detector),
                DEFAULT_VISIBILITY_RANGE_M,
                "{from_images} {detector:?}"
            );
        }
        assert_eq!(DEFAULT_VISIBILITY_RANGE_M, 80.0);
        // The flag wins over both.
        assert_eq!(visibility_range_m(Some(60.0), true, Vertex), 60.0);
        assert_eq!(visibility_range_m(Some(120.0), false, Point), 120.0);
    }
}
