//! `vgps demo [--out DIR]`: the main job end to end on the bundled reference drive.
//!
//! Simulates the reference drive (`vgps simulate --preset reference --seed 1`: deterministic,
//! under a second) into `DIR/reference`, replays it (`vgps replay`) into `DIR/replay`, and prints
//! the summary table and where the report is. The drive is written anew each time (the same
//! seed gives the same bytes), so the demo never depends on a stale copy.
//!
//! Then the image pipeline, by night and by day, on the start of the short preset's route
//! with every landmark surveyed and no survey gap:
//! - a night drive of [`DEMO_IMAGES_LENGTH_M`] with every camera's image rendered into
//!   `DIR/night` (street lamps, PNG), replayed from the pixels (`vgps replay --from-images`:
//!   PNG decoding, lamp detection, localization) into `DIR/night-replay`;
//! - a day drive of [`DEMO_DAY_LENGTH_M`] rendered into `DIR/day` (buildings in sunlight,
//!   JPEG at [`DEMO_DAY_JPEG_QUALITY`]), replayed from the pixels with the building-corner
//!   detector (`--detector vertex`, matched to 150 m) into `DIR/day-replay`.
//!
//! A day frame takes about 50 times as long to render as a night frame (six ray-cast
//! 1024×768 images with anti-aliased edges against a few hundred flat-shaded ones), so the
//! day drive is the shorter one: the whole demo stays within its minute on two cores.
//! Rendering the whole reference drive would write about 6 GB and take far longer, so both
//! image drives are short. `--no-images` skips the image stages.

use super::CliError;
use super::replay::OutputFormat;
use super::settings::{DemoSettings, ReplaySettings, strictness, thread_count};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use vgps_replay::frame_images::DetectorKind;
use vgps_replay::report::Report;
use vgps_sim::simulate::images::{ImageOptions, TimeOfDay, write_images};
use vgps_sim::simulate::{Preset, Scenario, simulate};

/// Default output directory of the demo (relative to the working directory).
pub const DEFAULT_DEMO_DIR: &str = "vgps-demo";
/// Seed of the demo's reference drive.
pub const DEMO_SEED: u64 = 1;

/// Length of the demo's night drive with rendered images (metres): 300 m of the short
/// preset, about 150 frames of 6 PNGs (≈ 0.3 GB).
pub const DEMO_IMAGES_LENGTH_M: f64 = 300.0;

/// Length of the demo's day drive with rendered images (metres): 100 m of the short
/// preset, 56 frames of 6 JPEGs (≈ 0.04 GB). Chosen for time: a day frame costs about
/// 0.8 s of one core to render, and the whole demo must stay within a minute on two cores.
pub const DEMO_DAY_LENGTH_M: f64 = 100.0;

/// JPEG quality of the demo's day images: the quality the vertex detector's accuracy is
/// reported at; as fast to write as PNG and a quarter of the bytes.
pub const DEMO_DAY_JPEG_QUALITY: u8 = 90;

/// Arguments of `vgps demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Output directory: the drive goes to `DIR/reference`, the report to `DIR/replay`.
    #[arg(long, default_value = DEFAULT_DEMO_DIR)]
    pub out: PathBuf,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: OutputFormat,
    /// Skip the image stages (rendering a 300 m night drive, 0.3 GB of PNGs, and a 100 m
    /// day drive, 0.04 GB of JPEGs, and replaying them from their pixels).
    #[arg(long)]
    pub no_images: bool,
}

/// One image stage of the demo: a piece of the short preset rendered and replayed from
/// its pixels.
struct ImageStage {
    /// `night` or `day`: the drive goes to `DIR/NAME`, its replay to `DIR/NAME-replay`.
    name: &'static str,
    /// What the detector finds in the images (for the summary).
    landmarks: &'static str,
    /// Route length (metres).
    length_m: f64,
    /// What the images show and how they are written.
    images: ImageOptions,
    /// The detector of the replay.
    detector: DetectorKind,
}

impl ImageStage {
    fn night() -> Self {
        Self {
            name: "night",
            landmarks: "lamps",
            length_m: DEMO_IMAGES_LENGTH_M,
            images: ImageOptions::default(),
            detector: DetectorKind::Point,
        }
    }

    fn day() -> Self {
        Self {
            name: "day",
            landmarks: "building corners",
            length_m: DEMO_DAY_LENGTH_M,
            images: ImageOptions {
                time_of_day: TimeOfDay::Day,
                jpeg_quality: Some(DEMO_DAY_JPEG_QUALITY),
                ..ImageOptions::default()
            },
            detector: DetectorKind::Vertex,
        }
    }
}

/// What an image stage gave.
struct StageOutcome {
    stage: ImageStage,
    /// Seconds spent simulating and rendering, and replaying.
    render_s: f64,
    replay_s: f64,
    report: Report,
}

/// Runs `vgps demo`.
///
/// With `--format json` the output is one JSON document: the reference replay's report
/// (`report.json`) with the keys `night_replay` and `day_replay` added, each the report of
/// that image stage (absent with `--no-images`).
///
/// # Errors
/// [`CliError::Output`] when the drive or the report cannot be written; the replay's errors.
pub fn run(
    settings: &DemoSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let text = settings.format == OutputFormat::Text;
    let mut sink = std::io::sink();
    // In JSON mode the replays' own documents are dropped: one document is printed at the end.
    let summary: &mut dyn Write = if text { &mut *out } else { &mut sink };
    let drive_dir = settings.out.join("reference");
    let started = Instant::now();
    let drive = simulate(&Scenario::preset(Preset::Reference, DEMO_SEED))
        .map_err(|e| CliError::Internal(format!("the reference drive: {e}")))?;
    drive.write(&drive_dir).map_err(drive_write_error)?;
    let simulate_s = started.elapsed().as_secs_f64();
    let reference_length_m = drive.frames.last().map_or(0.0, |f| f.arc_m);
    writeln!(
        summary,
        "vgps demo: simulated the reference drive ({} frames, {reference_length_m:.0} m) into {} in {simulate_s:.1} s; replaying…",
        drive.frames.len(),
        drive_dir.display(),
    )?;
    let replay = replay_settings(
        drive_dir,
        settings.out.join("replay"),
        settings.format,
        DetectorKind::Point,
        false,
    );
    let reference = super::replay::run_report(&replay, summary, err)?;
    let replay_s = started.elapsed().as_secs_f64() - simulate_s;
    let mut stages = Vec::new();
    if settings.images {
        for stage in [ImageStage::night(), ImageStage::day()] {
            stages.push(run_image_stage(settings, stage, summary, err)?);
        }
    }
    if text {
        write_side_by_side(&reference, reference_length_m, &stages, out)?;
        writeln!(
            out,
            "vgps demo: done in {:.1} s (reference drive {simulate_s:.1} s simulated + {replay_s:.1} s replayed{})",
            started.elapsed().as_secs_f64(),
            stages
                .iter()
                .map(|s| format!(
                    "; {} {:.1} s rendered + {:.1} s replayed",
                    s.stage.name, s.render_s, s.replay_s
                ))
                .collect::<String>()
        )?;
    } else {
        write_json(&reference, &stages, out)?;
    }
    Ok(())
}

/// An image stage: renders a piece of the short preset and replays it from the pixels.
///
/// Every landmark is surveyed and there is no survey gap: at night only the lamps are
/// visible (building corners are not rendered), and with the short preset's 75 % survey
/// and its gap too few surveyed lamps are in view to map surrogates from lamps alone
/// before the gap; the day drive is the same piece of city, seen by its building corners.
fn run_image_stage(
    settings: &DemoSettings,
    stage: ImageStage,
    summary: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<StageOutcome, CliError> {
    let dir = settings.out.join(stage.name);
    let started = Instant::now();
    let mut scenario = Scenario::preset(Preset::Short, DEMO_SEED);
    scenario.length_m = stage.length_m;
    scenario.surveyed_fraction = 1.0;
    scenario.survey_gap_m = 0.0;
    let drive = simulate(&scenario)
        .map_err(|e| CliError::Internal(format!("the {} drive: {e}", stage.name)))?;
    drive.write(&dir).map_err(drive_write_error)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let images =
        write_images(&drive, &dir, &stage.images, threads, &|_| {}).map_err(drive_write_error)?;
    let render_s = started.elapsed().as_secs_f64();
    writeln!(
        summary,
        "vgps demo: rendered a {:.0} m {} drive ({} frames, {} {} images, {:.0} MB) into {} in {render_s:.1} s; replaying it from the images ({})…",
        stage.length_m,
        stage.name,
        drive.frames.len(),
        images.images,
        if stage.images.jpeg_quality.is_some() {
            "JPEG"
        } else {
            "PNG"
        },
        images.bytes as f64 / 1e6,
        dir.display(),
        stage.landmarks,
    )?;
    let replay = replay_settings(
        dir,
        settings.out.join(format!("{}-replay", stage.name)),
        settings.format,
        stage.detector,
        true,
    );
    let report = super::replay::run_report(&replay, summary, err)?;
    Ok(StageOutcome {
        render_s,
        replay_s: started.elapsed().as_secs_f64() - render_s,
        stage,
        report,
    })
}

/// The drives side by side: frames, frames with an `ok` fix, and the horizontal error of
/// the visual fixes against the truth; the reference drive first (detections from the
/// simulator), then each image stage.
fn write_side_by_side(
    reference: &Report,
    reference_length_m: f64,
    stages: &[StageOutcome],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    writeln!(
        out,
        "vgps demo: summary (horizontal error of the visual fixes against the truth)"
    )?;
    writeln!(
        out,
        "  {:<30} {:>6}  {:>6}  {:>11}  {:>8}  {:>8}",
        "drive", "length", "frames", "fixed (ok)", "CEP50 m", "CEP95 m"
    )?;
    let rows = std::iter::once((
        "reference (detections)".to_string(),
        reference_length_m,
        reference,
    ))
    .chain(stages.iter().map(|s| {
        (
            format!("{} images ({})", s.stage.name, s.stage.landmarks),
            s.stage.length_m,
            &s.report,
        )
    }));
    for (label, length_m, r) in rows {
        let ok = r.status_counts.get("ok").copied().unwrap_or(0);
        let horizontal = r.visual_vs_truth.as_ref().map(|c| &c.horizontal_m);
        writeln!(
            out,
            "  {label:<30} {:>4.0} m  {:>6}  {:>5} {:>5}  {:>8}  {:>8}",
            length_m,
            r.frames,
            ok,
            format!("{:.0}%", 100.0 * ok as f64 / r.frames.max(1) as f64),
            metres(horizontal.map(|h| h.cep50)),
            metres(horizontal.map(|h| h.cep95)),
        )?;
    }
    Ok(())
}

/// A distance with millimetres, or `-` when there is none.
fn metres(x: Option<f64>) -> String {
    x.filter(|v| v.is_finite())
        .map_or_else(|| "-".to_string(), |v| format!("{v:.3}"))
}

/// The demo's JSON document: the reference replay's report, its keys in `report.json`'s
/// order, then one key per image stage.
#[derive(serde::Serialize)]
struct DemoJson<'a> {
    #[serde(flatten)]
    reference: &'a Report,
    #[serde(skip_serializing_if = "Option::is_none")]
    night_replay: Option<&'a Report>,
    #[serde(skip_serializing_if = "Option::is_none")]
    day_replay: Option<&'a Report>,
}

/// Writes [`DemoJson`], pretty-printed and ending in a newline like `report.json`.
fn write_json(
    reference: &Report,
    stages: &[StageOutcome],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let stage = |name: &str| {
        stages
            .iter()
            .find(|s| s.stage.name == name)
            .map(|s| &s.report)
    };
    let doc = DemoJson {
        reference,
        night_replay: stage("night"),
        day_replay: stage("day"),
    };
    let text = serde_json::to_string_pretty(&doc)
        .map_err(|e| CliError::Internal(format!("the demo's JSON: {e}")))?;
    writeln!(out, "{text}")?;
    Ok(())
}

/// `vgps replay` with its defaults and `--strict`, as the demo runs it.
fn replay_settings(
    drive: PathBuf,
    out_dir: PathBuf,
    format: OutputFormat,
    detector: DetectorKind,
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
        // The replay's default: 150 m for building corners from the images, else 80 m.
        visibility_range_m: None,
        matcher_memory_bytes: super::replay::DEFAULT_MATCHER_MEMORY_MIB as usize * (1 << 20),
        surrogate_drift_per_m: vgps_core::localizer::DEFAULT_SURROGATE_DRIFT_PER_M,
        max_turn_rate_change_rad_s: vgps_core::localizer::DEFAULT_MAX_TURN_RATE_CHANGE_RAD_S,
        from_images,
        image_size: None,
        detector,
        direction: Default::default(),
        gnss: Default::default(),
        mcap: Default::default(),
        robot: Default::default(),
    }
}

/// A drive that cannot be written is an output error (exit code 1).
fn drive_write_error(e: vgps_replay::drive::DriveError) -> CliError {
    CliError::Output(std::io::Error::other(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use vgps_replay::report::DriveInfo;

    /// The report of a drive without a single frame: no fix, no comparison with the truth.
    fn empty_report(name: &str) -> Report {
        let origin =
            vgps_geometry::geo::Geodetic::try_new(37.78, -122.42, 0.0).expect("a valid origin");
        Report::compute(
            &DriveInfo {
                name: name.to_string(),
                origin,
            },
            &[],
        )
    }

    fn outcome(stage: ImageStage) -> StageOutcome {
        StageOutcome {
            report: empty_report(stage.name),
            stage,
            render_s: 1.0,
            replay_s: 1.0,
        }
    }

    #[test]
    fn a_stage_without_fixes_shows_dashes_and_zero_percent_not_nan() {
        let stages = [outcome(ImageStage::night()), outcome(ImageStage::day())];
        let mut out = Vec::new();
        write_side_by_side(&empty_report("reference"), 2400.0, &stages, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 5, "{text}");
        assert!(!text.contains("NaN"), "{text}");
        let day = lines[4];
        assert!(day.starts_with("  day images (building corners)"), "{text}");
        let fields: Vec<&str> = day.split_whitespace().collect();
        // … 100 m, 0 frames, 0 ok, 0%, no CEP50, no CEP95.
        assert_eq!(
            fields[fields.len() - 7..],
            ["100", "m", "0", "0", "0%", "-", "-"]
        );
        // Every column of the header ends where its figures end.
        let header = lines[1];
        for (title, row) in [
            ("length", lines[2]),
            ("frames", lines[2]),
            ("fixed (ok)", day),
            ("CEP95 m", day),
        ] {
            let end = header.find(title).unwrap() + title.len();
            let (before, after) = row.split_at(end);
            assert!(
                !before.ends_with(' ') && (after.is_empty() || after.starts_with(' ')),
                "`{title}`:\n{text}"
            );
        }
    }

    #[test]
    fn the_json_is_report_json_plus_one_key_per_image_stage() {
        let reference = empty_report("reference");
        // Without the image stages: exactly the reference drive's report.json.
        let mut out = Vec::new();
        write_json(&reference, &[], &mut out).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), reference.to_json());
        // With them: the same keys in the same order, then one key per stage.
        let stages = [outcome(ImageStage::night()), outcome(ImageStage::day())];
        let mut out = Vec::new();
        write_json(&reference, &stages, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(doc["drive"], "reference");
        assert_eq!(doc["night_replay"]["drive"], "night");
        assert_eq!(doc["day_replay"]["drive"], "day");
        assert_eq!(doc["day_replay"]["frames"], 0);
        let (drive, night, day) = (
            text.find("\"drive\"").unwrap(),
            text.find("\"night_replay\"").unwrap(),
            text.find("\"day_replay\"").unwrap(),
        );
        assert!(drive < night && night < day, "{text}");
        let fields = reference.to_json();
        let fields = fields.trim_end().trim_end_matches('}').trim_end();
        assert!(text.starts_with(fields), "{text}");
    }
}
