//! `vgps simulate`: write a simulated drive directory (see `docs/simulate.md`).

use super::{CliError, SimulateSettings};
use std::io::Write;
use std::path::PathBuf;
use vgps_geometry::geo::Geodetic;
use vgps_sim::simulate::{Scenario, simulate};

/// The presets on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PresetArg {
    /// 2.4 km at 15 frames/s (the demo and benchmark scenario).
    Reference,
    /// 900 m at 5 frames/s (tests).
    Short,
}

/// The times of day of `--time-of-day`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TimeOfDayArg {
    /// Street lamps on a dark background.
    Night,
    /// Buildings, streets and clutter in sunlight.
    Day,
}

/// The night renderers of `--night-scene`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum NightSceneArg {
    /// Lamps and clutter spots on a flat dark background (fast).
    Flat,
    /// The city's buildings at night: sky glow, lit windows, car head- and taillights,
    /// wet-road reflections, bloom, vignetting.
    Realistic,
}

/// Arguments of `vgps simulate`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// The drive directory to write (created if missing; its files are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Random seed (the same seed gives byte-identical files).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The scenario preset.
    #[arg(long, value_enum, default_value = "reference")]
    pub preset: PresetArg,
    /// Route length in metres (overrides the preset's).
    #[arg(long)]
    pub length_m: Option<f64>,
    /// Rig calibration (any format `vgps calib` reads; default: the bundled Ladybug2).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// World origin `LAT,LON` in degrees (default 37.7793,-122.4193, San Francisco).
    #[arg(long, value_parser = parse_origin, allow_hyphen_values = true)]
    pub origin: Option<Geodetic>,
    /// Also render every camera's night image of every frame (PNG under `images/`, image
    /// columns in `frames.csv`, sidecar `images_truth.csv`).
    #[arg(long)]
    pub images: bool,
    /// What `--images` shows: `night` (street lamps) or `day` (buildings lit by the sun of
    /// the drive's time and place; the truth is the visible corner landmarks).
    #[arg(long, value_enum, default_value = "night")]
    pub time_of_day: TimeOfDayArg,
    /// Which renderer draws night images: `flat` (lamps and clutter spots on a dark
    /// background) or `realistic` (the city's buildings at night with lit windows, car
    /// lights, wet-road reflections, bloom and vignetting; its truth names each spot).
    #[arg(long, value_enum, default_value = "flat")]
    pub night_scene: NightSceneArg,
    /// Write the images as JPEG at this quality (1–100) instead of PNG.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: Option<u8>,
    /// Threads rendering and encoding the images (default: all cores; the files do not
    /// depend on it).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn parse_origin(text: &str) -> Result<Geodetic, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [lat, lon] = parts.as_slice() else {
        return Err(format!("`{text}` is not LAT,LON"));
    };
    let lat: f64 = lat
        .parse()
        .map_err(|_| format!("latitude `{lat}` is not a number"))?;
    let lon: f64 = lon
        .parse()
        .map_err(|_| format!("longitude `{lon}` is not a number"))?;
    if lat.abs() > 85.0 || lon.abs() > 180.0 {
        return Err(format!(
            "origin {lat},{lon} is outside |lat| ≤ 85, |lon| ≤ 180"
        ));
    }
    Geodetic::try_new(lat, lon, 0.0).map_err(|e| e.to_string())
}

/// Runs `vgps simulate`: builds the scenario, simulates, writes the directory and prints
/// a one-line summary to `out`.
///
/// # Errors
/// [`CliError::Calibration`] for an unreadable calibration or an invalid scenario (exit
/// code 2), [`CliError::Output`] when a file cannot be written (exit code 1).
pub fn run(settings: &SimulateSettings, out: &mut dyn Write) -> Result<(), CliError> {
    let mut scenario = Scenario::preset(settings.preset, settings.seed);
    if let Some(l) = settings.length_m {
        scenario.length_m = l;
    }
    if let Some(o) = settings.origin {
        scenario.origin = o;
    }
    if let Some(path) = &settings.calibration {
        scenario.rig = vgps_camera::calibration::load(path, None, None)
            .map_err(|e| CliError::Calibration(e.to_string()))?;
        scenario.calibration_name = path.display().to_string();
    }
    let started = std::time::Instant::now();
    let drive =
        simulate(&scenario).map_err(|e| CliError::Calibration(format!("vgps simulate: {e}")))?;
    drive
        .write(&settings.out)
        .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())))?;
    let images = if settings.images {
        Some(write_images(&drive, settings)?)
    } else {
        None
    };
    let (true_det, false_det, _) = drive.detection_counts();
    let surveyed = drive.world.landmarks.iter().filter(|l| l.surveyed).count();
    writeln!(
        out,
        "{}: {} frames, {:.0} m, {} landmarks ({} surveyed), {} detections ({} false), {} GNSS epochs, {:.0} % of the route without GPS fix; {:.2} s",
        settings.out.display(),
        drive.frames.len(),
        drive.route.length_m,
        drive.world.landmarks.len(),
        surveyed,
        true_det + false_det,
        false_det,
        drive.gnss.len(),
        100.0 * drive.outage_fraction(),
        started.elapsed().as_secs_f64()
    )?;
    if let Some(s) = images {
        writeln!(
            out,
            "{}: {} images, {:.1} MB ({} lamp, {} transient, {} clutter spots, {} corners{})",
            settings
                .out
                .join(vgps_sim::simulate::images::IMAGES_DIR)
                .display(),
            s.images,
            s.bytes as f64 / 1e6,
            s.lamps,
            s.transients,
            s.clutter,
            s.corners,
            if settings.night_scene == NightSceneArg::Realistic {
                format!(
                    "; {} lit windows, {} car lights, {} reflections",
                    s.windows, s.car_lights, s.reflections
                )
            } else {
                String::new()
            }
        )?;
    }
    Ok(())
}

/// Renders and writes the images of `drive` (`--images`), with a progress bar on a terminal.
fn write_images(
    drive: &vgps_sim::simulate::SimulatedDrive,
    settings: &SimulateSettings,
) -> Result<vgps_sim::simulate::images::ImagesSummary, CliError> {
    use std::io::IsTerminal;
    let threads = settings.threads;
    let bar = (!settings.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(drive.frames.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} images [{bar:40}] {pos}/{len} frames {per_sec} ETA {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let progress = |n: u64| {
        if let Some(bar) = &bar {
            bar.inc(n);
        }
    };
    let result = vgps_sim::simulate::images::write_images(
        drive,
        &settings.out,
        &vgps_sim::simulate::images::ImageOptions {
            time_of_day: match settings.time_of_day {
                TimeOfDayArg::Night => vgps_sim::simulate::images::TimeOfDay::Night,
                TimeOfDayArg::Day => vgps_sim::simulate::images::TimeOfDay::Day,
            },
            jpeg_quality: settings.jpeg_quality,
            night_scene: match settings.night_scene {
                NightSceneArg::Flat => vgps_sim::simulate::images::NightScene::Flat,
                NightSceneArg::Realistic => vgps_sim::simulate::images::NightScene::Realistic,
            },
            ..vgps_sim::simulate::images::ImageOptions::default()
        },
        threads,
        &progress,
    )
    .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())));
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    result
}
