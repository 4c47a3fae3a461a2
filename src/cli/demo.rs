//! `vgps demo [--out DIR]`: the main job end to end on the bundled reference drive.
//!
//! Simulates the reference drive (`vgps simulate --preset reference --seed 1`: deterministic,
//! under a second) into `DIR/reference`, replays it (`vgps replay`) into `DIR/replay`, and prints
//! the summary table and where the report is. The drive is written anew each time (the same
//! seed gives the same bytes), so the demo never depends on a stale copy.
//!
//! Then the image pipeline: a night drive of [`DEMO_IMAGES_LENGTH_M`] with every camera's
//! image rendered into `DIR/night` (every landmark surveyed, no survey gap), replayed from
//! the pixels (`vgps replay --from-images`: PNG decoding, lamp detection, localization)
//! into `DIR/night-replay`. Rendering the whole reference drive would write about 6 GB and
//! take longer than the demo's minute on two cores, so the image stage uses a shorter
//! drive. `--no-images` skips it (and its 0.3 GB of PNGs).

use super::CliError;
use super::replay::OutputFormat;
use super::settings::{DemoSettings, ReplaySettings, strictness, thread_count};
use std::io::Write;
use std::path::PathBuf;
use vgps_sim::simulate::{Preset, Scenario, simulate};

/// Default output directory of the demo (relative to the working directory).
pub const DEFAULT_DEMO_DIR: &str = "vgps-demo";
/// Seed of the demo's reference drive.
pub const DEMO_SEED: u64 = 1;

/// Length of the demo's night drive with rendered images (metres): 300 m of the short
/// preset, about 130 frames of 6 PNGs (≈ 0.3 GB).
pub const DEMO_IMAGES_LENGTH_M: f64 = 300.0;

/// Arguments of `vgps demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Output directory: the drive goes to `DIR/reference`, the report to `DIR/replay`.
    #[arg(long, default_value = DEFAULT_DEMO_DIR)]
    pub out: PathBuf,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: OutputFormat,
    /// Skip the image stage (rendering a 300 m night drive, 0.3 GB of PNGs, and replaying
    /// it from its pixels).
    #[arg(long)]
    pub no_images: bool,
}

/// Runs `vgps demo`.
///
/// # Errors
/// [`CliError::Output`] when the drive or the report cannot be written; the replay's errors.
pub fn run(
    settings: &DemoSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let drive_dir = settings.out.join("reference");
    let started = std::time::Instant::now();
    let drive = simulate(&Scenario::preset(Preset::Reference, DEMO_SEED))
        .map_err(|e| CliError::Internal(format!("the reference drive: {e}")))?;
    drive.write(&drive_dir).map_err(drive_write_error)?;
    if settings.format == OutputFormat::Text {
        writeln!(
            out,
            "vgps demo: simulated the reference drive ({} frames, {:.0} m) into {} in {:.1} s; replaying…",
            drive.frames.len(),
            drive.frames.last().map_or(0.0, |f| f.arc_m),
            drive_dir.display(),
            started.elapsed().as_secs_f64()
        )?;
    }
    let replay = replay_settings(
        drive_dir,
        settings.out.join("replay"),
        settings.format,
        false,
    );
    super::replay::run(&replay, out, err)?;
    if settings.images {
        run_images(settings, out, err)?;
    }
    if settings.format == OutputFormat::Text {
        writeln!(
            out,
            "vgps demo: done in {:.1} s",
            started.elapsed().as_secs_f64()
        )?;
    }
    Ok(())
}

/// The image stage: renders a short night drive and replays it from the pixels.
///
/// At night only the lamps are visible (building corners are not rendered), so this drive
/// surveys every landmark and has no survey gap: with the short preset's 75 % survey and
/// its gap, too few surveyed lamps are in view to map surrogates from lamps alone before
/// the gap.
fn run_images(
    settings: &DemoSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let night = settings.out.join("night");
    let started = std::time::Instant::now();
    let mut scenario = Scenario::preset(Preset::Short, DEMO_SEED);
    scenario.length_m = DEMO_IMAGES_LENGTH_M;
    scenario.surveyed_fraction = 1.0;
    scenario.survey_gap_m = 0.0;
    let drive =
        simulate(&scenario).map_err(|e| CliError::Internal(format!("the night drive: {e}")))?;
    drive.write(&night).map_err(drive_write_error)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let images = vgps_sim::simulate::images::write_images(
        &drive,
        &night,
        &vgps_sim::simulate::images::ImageOptions::default(),
        threads,
        &|_| {},
    )
    .map_err(drive_write_error)?;
    let mut sink = std::io::sink();
    let summary: &mut dyn Write = if settings.format == OutputFormat::Text {
        out
    } else {
        &mut sink
    };
    writeln!(
        summary,
        "vgps demo: rendered a {:.0} m night drive ({} frames, {} images) into {} in {:.1} s; replaying it from the images…",
        DEMO_IMAGES_LENGTH_M,
        drive.frames.len(),
        images.images,
        night.display(),
        started.elapsed().as_secs_f64()
    )?;
    let replay = replay_settings(
        night,
        settings.out.join("night-replay"),
        settings.format,
        true,
    );
    super::replay::run(&replay, summary, err)
}

/// `vgps replay` with its defaults and `--strict`, as the demo runs it.
fn replay_settings(
    drive: PathBuf,
    out_dir: PathBuf,
    format: OutputFormat,
    from_images: bool,
) -> ReplaySettings {
    ReplaySettings {
        drive,
        out_dir,
        threads: thread_count(None),
        quiet: false,
        format,
        strictness: strictness(true),
        pixel_sigma_px: vgps_core::localizer::DEFAULT_PIXEL_SIGMA_PX,
        surrogates: true,
        gnss_prior: true,
        imu: true,
        up_tolerance_rad: None,
        visibility_range_m: None,
        from_images,
        image_size: None,
        detector: vgps_replay::frame_images::DetectorKind::Point,
        gnss: Default::default(),
        mcap: Default::default(),
        robot: Default::default(),
    }
}

/// A drive that cannot be written is an output error (exit code 1).
fn drive_write_error(e: vgps_replay::drive::DriveError) -> CliError {
    CliError::Output(std::io::Error::other(e.to_string()))
}
