//! `vgps detect DRIVE`: lamp or corner detection in every image of a drive, written as a detections
//! file of the drive format (see `docs/cli.md`, `docs/lamp-detection.md`).
//!
//! # Output file
//! `--out FILE` when given (replaced atomically). Otherwise `DRIVE/detections.csv` when the
//! manifest names no detections file and no file of that name exists; else
//! `DRIVE/detections_detected.csv`, so that a simulator's or a logger's `detections.csv` is
//! never replaced silently. The manifest is not modified.
//!
//! # Order and parallelism
//! Frames are decoded and detected on `--threads` scoped threads taking frames in turn;
//! the file lists the frames in the drive's order whatever the number of threads.

use super::{CliError, DetectSettings};
use crate::imaging::{
    DetectorKind, FrameImageResult, ImageDetector, ImageProblemKind, detect_frame_images,
};
use std::collections::BTreeMap;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use vgps_replay::drive::{Drive, PixelDetection, detections_to_csv, write_text};

/// The default output file name when the drive has no detections file yet.
pub const DEFAULT_OUT_NAME: &str = "detections.csv";
/// The default output file name when the drive already has a detections file.
pub const FALLBACK_OUT_NAME: &str = "detections_detected.csv";

/// Arguments of `vgps detect`.
#[derive(Debug, Clone, clap::Args)]
pub struct DetectArgs {
    /// The drive directory (with `drive.json` and image columns in its frames file).
    pub drive: PathBuf,
    /// Output detections CSV (default: `DRIVE/detections.csv` when the drive has no
    /// detections file, else `DRIVE/detections_detected.csv`); replaced atomically.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Threads for decoding and detection (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar and no summary.
    #[arg(long)]
    pub quiet: bool,
    /// Unknown keys in drive.json are an error (default: a warning).
    #[arg(long)]
    pub strict: bool,
    /// Image size WxH of cameras whose calibration names none (a Ladybug INI dump); by
    /// default taken from the images (all images of those cameras must agree).
    #[arg(long, value_parser = super::image_size::parse_image_size)]
    pub image_size: Option<(u32, u32)>,
    /// The detector: `point` (every spot above the noise: rendered night frames),
    /// `street` (bright cores against their local background, windows, reflections,
    /// vehicle lights and ghosts rejected: real night photos) or `vertex` (building corners
    /// by day, class `corner`).
    #[arg(long, value_enum, default_value = "point")]
    pub detector: DetectorArg,
}

/// The detectors of `--detector`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DetectorArg {
    /// Every spot above a noise-based threshold (point lights on a dark background).
    Point,
    /// The night-street detector (real photos: JPEG, bloom, windows, reflections).
    Street,
    /// Building corners by day: the intersection of sub-pixel straight edges (class
    /// `corner`).
    Vertex,
}

impl From<DetectorArg> for DetectorKind {
    fn from(a: DetectorArg) -> Self {
        match a {
            DetectorArg::Point => DetectorKind::Point,
            DetectorArg::Street => DetectorKind::Street,
            DetectorArg::Vertex => DetectorKind::Vertex,
        }
    }
}

/// Counts of one `vgps detect` run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DetectSummary {
    /// Frames of the drive.
    pub frames: usize,
    /// Images named by the frames.
    pub images: usize,
    /// Detections written.
    pub detections: usize,
    /// Frames with at least one unusable image.
    pub frames_with_problems: usize,
    /// Frames of which no image could be used (or naming no image).
    pub unusable_frames: usize,
    /// Unusable images by kind.
    pub problems: BTreeMap<ImageProblemKind, usize>,
}

/// Runs `vgps detect`.
///
/// # Errors
/// [`CliError::Calibration`] (exit 2) when the drive cannot be opened or names no image;
/// [`CliError::Output`] (exit 1) when the output cannot be written. Bad images are reported
/// per frame on `err` and counted, not errors.
pub fn run(
    settings: &DetectSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    let mut drive = Drive::open(&settings.drive, settings.strictness)
        .map_err(|e| CliError::Calibration(e.to_string()))?;
    if let Some(note) = super::image_size::resolve(&mut drive, settings.image_size)? {
        let _ = writeln!(err, "vgps: {note}");
    }
    for w in drive.warnings() {
        let _ = writeln!(err, "vgps: warning: {w}");
    }
    let frames = drive.frames();
    if !frames.iter().any(|f| f.images.iter().any(Option::is_some)) {
        return Err(CliError::Calibration(format!(
            "{}: no frame names an image (the frames file `{}` has no image columns)",
            settings.drive.display(),
            drive.manifest().frames
        )));
    }
    let out_path = match &settings.out {
        Some(p) => p.clone(),
        None => {
            let default = settings.drive.join(DEFAULT_OUT_NAME);
            if drive.manifest().detections.is_none() && !default.exists() {
                default
            } else {
                let fallback = settings.drive.join(FALLBACK_OUT_NAME);
                let _ = writeln!(
                    err,
                    "vgps: note: {} already has a detections file; writing {} (use --out to choose)",
                    settings.drive.display(),
                    fallback.display()
                );
                fallback
            }
        }
    };
    let threads = settings.threads.clamp(1, frames.len().max(1));
    let bar = (!settings.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(frames.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} detect [{bar:40}] {pos}/{len} frames {per_sec} ETA {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let detector = ImageDetector::new(settings.detector, drive.rig());
    let next = AtomicUsize::new(0);
    let worker = || {
        let mut done = Vec::new();
        while let Some(frame) = frames.get(next.fetch_add(1, Ordering::Relaxed)) {
            done.push(detect_frame_images(
                drive.dir(),
                frame,
                drive.rig(),
                &detector,
            ));
            if let Some(bar) = &bar {
                bar.inc(1);
            }
        }
        done
    };
    let mut results: Vec<FrameImageResult> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(worker)).collect();
        let mut all = Vec::with_capacity(frames.len());
        for h in handles {
            all.extend(
                h.join()
                    .map_err(|_| CliError::Internal("a detection thread panicked".into()))?,
            );
        }
        Ok::<_, CliError>(all)
    })?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    // Frame numbers are unique and increasing in a drive: sorting restores the file order.
    results.sort_by_key(|r| r.frame);
    let mut summary = DetectSummary {
        frames: frames.len(),
        ..DetectSummary::default()
    };
    let mut detections: Vec<PixelDetection> = Vec::new();
    for r in &mut results {
        summary.images += r.images;
        if r.is_unusable() {
            summary.unusable_frames += 1;
        }
        if !r.problems.is_empty() || r.images == 0 {
            summary.frames_with_problems += 1;
            let _ = writeln!(err, "vgps: frame {}: {}", r.frame, r.problem_text());
        }
        for p in &r.problems {
            *summary.problems.entry(p.kind).or_default() += 1;
        }
        detections.append(&mut r.detections);
    }
    summary.detections = detections.len();
    write_text(&out_path, &detections_to_csv(&detections))
        .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())))?;
    if !settings.quiet {
        let seconds = started.elapsed().as_secs_f64();
        writeln!(
            out,
            "{}: {} frames, {} images, {} detections ({:.1} per image); {} frame(s) with an unusable image, {} without any usable image; {:.2} s ({:.1} frames/s)",
            out_path.display(),
            summary.frames,
            summary.images,
            summary.detections,
            summary.detections as f64 / summary.images.max(1) as f64,
            summary.frames_with_problems,
            summary.unusable_frames,
            seconds,
            summary.frames as f64 / seconds.max(1e-9)
        )?;
        if !summary.problems.is_empty() {
            let kinds: Vec<String> = summary
                .problems
                .iter()
                .map(|(k, n)| format!("{} {n}", k.as_str()))
                .collect();
            writeln!(out, "unusable images: {}", kinds.join(", "))?;
        }
    }
    Ok(())
}
