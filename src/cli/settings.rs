//! The validated settings of every subcommand, built once from the parsed command line
//! ([`Settings::try_from`]); the commands only orchestrate on them.
//!
//! clap's value parsers check each value's own range (a positive σ, a latitude); this
//! module resolves defaults (output paths, thread counts), converts units (degrees to
//! radians) and maps flags to the library's types (`--strict` to [`Strictness`]), so that
//! no command repeats a check or a conversion.

use super::CliError;
use super::args::{Cli, Command, PriorArg};
pub use super::calib::CalibSettings;
use super::gnss_input::GnssInputArgs;
pub use super::landmarks::LandmarksSettings;
use super::map::{GpsOffset, MapArgs};
use super::replay::{OutputFormat, ReplayArgs};
use super::simulate::{PresetArg, SimulateArgs};
use std::path::PathBuf;
use vgps_geometry::geo::Geodetic;
use vgps_replay::drive::Strictness;
use vgps_sim::simulate::Preset;

/// Validated settings of `vgps locate`.
#[derive(Clone, Debug, PartialEq)]
pub struct LocateSettings {
    /// The landmarks file.
    pub landmarks: PathBuf,
    /// The observations file.
    pub observations: PathBuf,
    /// The rig calibration, if any (turns pixel observations into rays).
    pub calibration: Option<PathBuf>,
    /// The position prior, if any.
    pub prior: Option<PriorArg>,
    /// The matcher's cold-start region, if any.
    pub region: Option<PriorArg>,
    /// The matcher's known-vertical tolerance, radians, if any.
    pub up_tolerance_rad: Option<f64>,
    /// Bearing standard deviation per tangent axis, radians.
    pub sigma_rad: f64,
}

/// Validated settings of `vgps triangulate`.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangulateSettings {
    /// The rays file.
    pub rays: PathBuf,
    /// Default direction standard deviation per tangent axis, radians.
    pub sigma_ang_rad: f64,
    /// Default observer position standard deviation per axis, metres.
    pub sigma_pos_m: f64,
}

/// Validated settings of `vgps demo`.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoSettings {
    /// Output directory: the drive goes to `DIR/reference`, the report to `DIR/replay`.
    pub out: PathBuf,
    /// Summary format on stdout.
    pub format: OutputFormat,
    /// Run the image stage (render a night drive and replay it from its pixels).
    pub images: bool,
}

/// Validated settings of `vgps simulate`.
#[derive(Clone, Debug)]
pub struct SimulateSettings {
    /// The drive directory to write.
    pub out: PathBuf,
    /// Random seed.
    pub seed: u64,
    /// The scenario preset.
    pub preset: Preset,
    /// Route length in metres, overriding the preset's.
    pub length_m: Option<f64>,
    /// Rig calibration file, overriding the bundled Ladybug2.
    pub calibration: Option<PathBuf>,
    /// World origin, overriding the preset's.
    pub origin: Option<Geodetic>,
    /// Also render every camera's night image of every frame.
    pub images: bool,
    /// Night or day images.
    pub time_of_day: super::simulate::TimeOfDayArg,
    /// JPEG quality of the images (PNG when `None`).
    pub jpeg_quality: Option<u8>,
    /// Which night renderer (flat or realistic).
    pub night_scene: super::simulate::NightSceneArg,
    /// Threads rendering and encoding the images (at least 1).
    pub threads: usize,
    /// No progress bar.
    pub quiet: bool,
}

/// Validated settings of `vgps replay`.
#[derive(Clone, Debug)]
pub struct ReplaySettings {
    /// The drive directory.
    pub drive: PathBuf,
    /// Output directory (`DRIVE/replay` unless given).
    pub out_dir: PathBuf,
    /// Threads for image decoding and lamp detection (at least 1).
    pub threads: usize,
    /// No progress bar and no summary table.
    pub quiet: bool,
    /// Summary format on stdout.
    pub format: OutputFormat,
    /// How unknown keys in drive.json are treated.
    pub strictness: Strictness,
    /// Pixel σ of a detection (pixels, positive and finite).
    pub pixel_sigma_px: f64,
    /// Map secondary landmarks and use them as surrogates.
    pub surrogates: bool,
    /// Use satellite GPS as a prior.
    pub gnss_prior: bool,
    /// Use the drive's IMU as an attitude prior.
    pub imu: bool,
    /// `--up-tolerance-deg`, radians: the rig's +z is within it of up (overrides the
    /// calibration's `level_within_deg`).
    pub up_tolerance_rad: Option<f64>,
    /// `--visibility-range-m`: the matcher's visibility range (default: by detector).
    pub visibility_range_m: Option<f64>,
    /// `--matcher-memory-mib` in bytes: the matcher's cache budget per search.
    pub matcher_memory_bytes: usize,
    /// `--surrogate-drift-percent` as a fraction: the drift of a pose carried on
    /// surrogates per metre (1σ), added to the reported covariance.
    pub surrogate_drift_per_m: f64,
    /// `--max-turn-rate-change-deg-s`, rad/s: the turn rate change tracking recovers.
    pub max_turn_rate_change_rad_s: f64,
    /// Detect lamps in the images even when the drive has a detections file.
    pub from_images: bool,
    /// The image size of cameras whose calibration has none (`--image-size WxH`).
    pub image_size: Option<(u32, u32)>,
    /// The lamp detector of `--from-images`.
    pub detector: vgps_replay::frame_images::DetectorKind,
    /// Forward only, or forward then backward (`--direction`).
    pub direction: super::replay::Direction,
    /// Satellite GPS from another file.
    pub gnss: GnssInputArgs,
    /// The options of an MCAP recording given as the drive.
    pub mcap: super::import::McapInputArgs,
    /// The live NMEA stream and the MCAP file.
    pub robot: super::robot_out::RobotOutputArgs,
}

/// Validated settings of `vgps detect`.
#[derive(Clone, Debug)]
pub struct DetectSettings {
    /// The drive directory.
    pub drive: PathBuf,
    /// Output detections file, if given (else chosen from the drive, see `vgps detect`).
    pub out: Option<PathBuf>,
    /// Threads for decoding and detection (at least 1; at most one per frame is used).
    pub threads: usize,
    /// No progress bar and no summary.
    pub quiet: bool,
    /// How unknown keys in drive.json are treated.
    pub strictness: Strictness,
    /// The image size of cameras whose calibration has none (`--image-size WxH`).
    pub image_size: Option<(u32, u32)>,
    /// The lamp detector.
    pub detector: vgps_replay::frame_images::DetectorKind,
}

/// Validated settings of `vgps map`.
#[derive(Clone, Debug)]
pub struct MapSettings {
    /// The drive directory.
    pub drive: PathBuf,
    /// The landmarks file to write (`DRIVE/mapped_landmarks.csv` unless given).
    pub out: PathBuf,
    /// The GPS time offset to apply.
    pub gps_offset: GpsOffset,
    /// Pixel σ of a detection (pixels).
    pub pixel_sigma_px: f64,
    /// Horizontal σ of a GNSS fix per axis (metres).
    pub gnss_sigma_m: f64,
    /// σ of the GNSS heading (radians).
    pub heading_sigma_rad: f64,
    /// Fewest observations (rays) of a written landmark.
    pub min_obs: usize,
    /// Fewest frames with an observation of a landmark, as a fraction of its time span.
    pub min_coverage: f64,
    /// Half-width of the GNSS smoothing window (seconds; 0 = raw fixes).
    pub smooth_s: f64,
    /// Summary format on stdout.
    pub format: OutputFormat,
    /// How unknown keys in drive.json are treated.
    pub strictness: Strictness,
    /// Satellite GPS from another file.
    pub gnss: GnssInputArgs,
}

/// What to run, with validated settings.
#[derive(Debug)]
pub enum Settings {
    /// `vgps locate`.
    Locate(LocateSettings),
    /// `vgps triangulate`.
    Triangulate(TriangulateSettings),
    /// `vgps demo`.
    Demo(DemoSettings),
    /// `vgps calib …` (run by [`super::calib::run`], which reports on the process's own
    /// streams).
    Calib(CalibSettings),
    /// `vgps landmarks …`.
    Landmarks(LandmarksSettings),
    /// `vgps simulate`.
    Simulate(SimulateSettings),
    /// `vgps replay`.
    Replay(ReplaySettings),
    /// `vgps detect`.
    Detect(DetectSettings),
    /// `vgps map`.
    Map(MapSettings),
    /// `vgps import …` (every value is checked by its clap value parser; nothing is left
    /// to resolve).
    Import(super::import::ImportArgs),
}

/// The strictness of reading a drive's manifest for the `--strict` flag (the one place
/// this mapping is written).
pub fn strictness(strict: bool) -> Strictness {
    if strict {
        Strictness::Strict
    } else {
        Strictness::Lenient
    }
}

/// The thread count for `--threads` (all cores when not given; at least 1).
pub fn thread_count(threads: Option<usize>) -> usize {
    threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1)
}

impl TryFrom<Cli> for Settings {
    type Error = CliError;

    fn try_from(cli: Cli) -> Result<Self, CliError> {
        Ok(match cli.command {
            Command::Locate(a) => Settings::Locate(LocateSettings {
                landmarks: a.landmarks,
                observations: a.observations,
                calibration: a.calibration,
                prior: a.prior,
                region: a.region,
                up_tolerance_rad: a.up_tolerance_deg.map(f64::to_radians),
                sigma_rad: a.sigma_deg.to_radians(),
            }),
            Command::Triangulate(a) => Settings::Triangulate(TriangulateSettings {
                rays: a.rays,
                sigma_ang_rad: a.sigma_deg.to_radians(),
                sigma_pos_m: a.sigma_pos_m,
            }),
            Command::Demo(a) => Settings::Demo(DemoSettings {
                out: a.out,
                format: a.format,
                images: !a.no_images,
            }),
            Command::Calib(a) => Settings::Calib(CalibSettings::try_from(a)?),
            Command::Landmarks(a) => Settings::Landmarks(LandmarksSettings::try_from(a)?),
            Command::Simulate(a) => Settings::Simulate(SimulateSettings::from(a)),
            Command::Replay(a) => Settings::Replay(ReplaySettings::try_from(a)?),
            Command::Detect(a) => Settings::Detect(DetectSettings {
                out: a.out,
                threads: thread_count(a.threads),
                quiet: a.quiet,
                strictness: strictness(a.strict),
                image_size: a.image_size,
                detector: a.detector.into(),
                drive: a.drive,
            }),
            Command::Map(a) => Settings::Map(MapSettings::from(a)),
            Command::Import(a) => Settings::Import(a),
        })
    }
}

impl From<SimulateArgs> for SimulateSettings {
    fn from(a: SimulateArgs) -> Self {
        Self {
            out: a.out,
            seed: a.seed,
            preset: match a.preset {
                PresetArg::Reference => Preset::Reference,
                PresetArg::Short => Preset::Short,
            },
            length_m: a.length_m,
            calibration: a.calibration,
            origin: a.origin,
            images: a.images,
            time_of_day: a.time_of_day,
            jpeg_quality: a.jpeg_quality,
            night_scene: a.night_scene,
            threads: thread_count(a.threads),
            quiet: a.quiet,
        }
    }
}

impl TryFrom<ReplayArgs> for ReplaySettings {
    type Error = CliError;

    /// # Errors
    /// [`CliError::Calibration`] (exit 2) naming `--pixel-sigma-px` when it is not a
    /// positive finite number.
    fn try_from(a: ReplayArgs) -> Result<Self, CliError> {
        if !(a.pixel_sigma_px.is_finite() && a.pixel_sigma_px > 0.0) {
            return Err(CliError::Calibration(format!(
                "--pixel-sigma-px {} is not a positive number",
                a.pixel_sigma_px
            )));
        }
        Ok(Self {
            out_dir: a.out.unwrap_or_else(|| {
                if super::import::is_mcap(&a.drive) {
                    a.drive.with_extension("replay")
                } else {
                    a.drive.join("replay")
                }
            }),
            drive: a.drive,
            threads: thread_count(a.threads),
            quiet: a.quiet,
            format: a.format,
            strictness: strictness(a.strict),
            pixel_sigma_px: a.pixel_sigma_px,
            surrogates: !a.no_surrogates,
            gnss_prior: !a.no_gnss_prior,
            imu: !a.no_imu,
            up_tolerance_rad: a.up_tolerance_deg.map(f64::to_radians),
            visibility_range_m: a.visibility_range_m,
            matcher_memory_bytes: (a.matcher_memory_mib as usize).saturating_mul(1 << 20),
            surrogate_drift_per_m: a.surrogate_drift_percent / 100.0,
            max_turn_rate_change_rad_s: a.max_turn_rate_change_deg_s.to_radians(),
            from_images: a.from_images,
            image_size: a.image_size,
            detector: a.detector.into(),
            direction: a.direction,
            gnss: a.gnss,
            mcap: a.mcap,
            robot: a.robot,
        })
    }
}

impl From<MapArgs> for MapSettings {
    fn from(a: MapArgs) -> Self {
        Self {
            out: a
                .out
                .unwrap_or_else(|| a.drive.join(super::map::DEFAULT_OUTPUT_NAME)),
            drive: a.drive,
            gps_offset: a.gps_offset,
            pixel_sigma_px: a.pixel_sigma_px,
            gnss_sigma_m: a.gnss_sigma_m,
            heading_sigma_rad: a.heading_sigma_deg.to_radians(),
            min_obs: a.min_obs,
            min_coverage: a.min_coverage,
            smooth_s: a.smooth_s,
            format: a.format,
            strictness: strictness(a.strict),
            gnss: a.gnss,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[test]
    fn settings_are_validated_once() {
        let cli = Cli::try_parse_from([
            "vgps",
            "locate",
            "--landmarks",
            "L.csv",
            "--observations",
            "O.csv",
            "--sigma-deg",
            "0.5",
        ])
        .unwrap();
        let Settings::Locate(s) = Settings::try_from(cli).unwrap() else {
            panic!("not locate")
        };
        assert!((s.sigma_rad - 0.5_f64.to_radians()).abs() < 1e-15);
        assert_eq!(s.prior, None);
        let cli = Cli::try_parse_from([
            "vgps",
            "locate",
            "--landmarks",
            "L",
            "--observations",
            "O",
            "--calibration",
            "c",
        ])
        .unwrap();
        let Settings::Locate(s) = Settings::try_from(cli).unwrap() else {
            panic!("not locate")
        };
        assert_eq!(s.calibration, Some(PathBuf::from("c")));
        assert!(
            Cli::try_parse_from(["vgps", "triangulate", "--rays", "R", "--sigma-deg", "-1"])
                .is_err()
        );
    }

    #[test]
    fn drive_commands_resolve_defaults_and_strictness() {
        let cli = Cli::try_parse_from(["vgps", "replay", "D", "--strict"]).unwrap();
        let Settings::Replay(s) = Settings::try_from(cli).unwrap() else {
            panic!("not replay")
        };
        assert_eq!(s.out_dir, PathBuf::from("D").join("replay"));
        assert_eq!(s.strictness, Strictness::Strict);
        assert!(s.threads >= 1 && s.surrogates && s.gnss_prior);
        let cli = Cli::try_parse_from(["vgps", "replay", "D", "--pixel-sigma-px", "0"]).unwrap();
        let e = Settings::try_from(cli).unwrap_err();
        assert_eq!(e.exit_code(), super::super::EXIT_INPUT);
        assert!(e.to_string().contains("--pixel-sigma-px 0"));
        let cli = Cli::try_parse_from(["vgps", "map", "D"]).unwrap();
        let Settings::Map(s) = Settings::try_from(cli).unwrap() else {
            panic!("not map")
        };
        assert_eq!(
            s.out,
            PathBuf::from("D").join(super::super::map::DEFAULT_OUTPUT_NAME)
        );
        assert_eq!(s.strictness, Strictness::Lenient);
    }

    #[test]
    fn calib_is_validated_once() {
        use super::super::calib::ConvertTo;
        let parse = |args: &[&str]| {
            let mut all = vec!["vgps", "calib"];
            all.extend_from_slice(args);
            Settings::try_from(Cli::try_parse_from(all).unwrap())
        };
        let Settings::Calib(CalibSettings::Show { file, source }) =
            parse(&["show", "c.ini", "--image-size", "1024x768"]).unwrap()
        else {
            panic!("not calib show")
        };
        assert_eq!(file, PathBuf::from("c.ini"));
        assert_eq!(source.image_size, Some((1024, 768)));
        let Settings::Calib(CalibSettings::Convert { to, output, .. }) =
            parse(&["convert", "a.json", "--to", "lut", "--step", "8", "b.json"]).unwrap()
        else {
            panic!("not calib convert")
        };
        assert_eq!(output, PathBuf::from("b.json"));
        assert_eq!(
            to,
            ConvertTo::Lut {
                step: std::num::NonZeroU32::new(8).unwrap()
            }
        );
        // The default step is 4; `--step` does not matter for `--to native`.
        let Settings::Calib(CalibSettings::Convert { to, .. }) =
            parse(&["convert", "a.json", "--to", "lut", "b.json"]).unwrap()
        else {
            panic!("not calib convert")
        };
        assert_eq!(
            to,
            ConvertTo::Lut {
                step: std::num::NonZeroU32::new(4).unwrap()
            }
        );
        let Settings::Calib(CalibSettings::Convert { to, .. }) = parse(&[
            "convert", "a.json", "--to", "native", "--step", "0", "b.json",
        ])
        .unwrap() else {
            panic!("not calib convert")
        };
        assert_eq!(to, ConvertTo::Native);
        // A LUT step of 0 is refused before anything is read, with exit code 2.
        let e = parse(&["convert", "a.json", "--to", "lut", "--step", "0", "b.json"]).unwrap_err();
        assert_eq!(e.exit_code(), super::super::EXIT_INPUT);
        assert_eq!(e.to_string(), "--step must be at least 1");
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = super::super::run(
            [
                "vgps",
                "calib",
                "convert",
                "missing.json",
                "--to",
                "lut",
                "--step",
                "0",
                "o.json",
            ],
            &mut out,
            &mut err,
        );
        assert_eq!(code, std::process::ExitCode::from(super::super::EXIT_INPUT));
        assert_eq!(
            String::from_utf8(err).unwrap(),
            "vgps: error: --step must be at least 1\n"
        );
        // Values clap's parsers refuse never reach the settings.
        for bad in [
            &["show", "c.ini", "--image-size", "0x768"][..],
            &["show", "c.ini", "--format", "yaml"],
            &["convert", "a", "--to", "png", "b"],
        ] {
            let mut all = vec!["vgps", "calib"];
            all.extend_from_slice(bad);
            assert!(Cli::try_parse_from(all).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn landmarks_is_validated_once() {
        let parse = |extra: &[&str]| {
            let mut all = vec!["vgps", "landmarks", "import", "l.geojson", "--out", "L.csv"];
            all.extend_from_slice(extra);
            Settings::try_from(Cli::try_parse_from(all).unwrap())
        };
        let Settings::Landmarks(s) =
            parse(&["--ground-height", "-3.5", "--heights", "ellipsoid"]).unwrap()
        else {
            panic!("not landmarks")
        };
        let crate::cli::landmarks::LandmarksJob::Inventory(options) = s.job else {
            panic!("`landmarks import` is not an inventory job")
        };
        assert_eq!(options.ground_height_m, Some(-3.5));
        assert_eq!(options.reference, vgps_io::gis::GroundReference::Ellipsoid);
        assert_eq!((options.default_lamp_height_m, options.sigma_m), (6.0, 0.5));
        for (args, message) in [
            (
                &["--sigma=-1"][..],
                "command line:1: field `--sigma`: -1 is not a non-negative number",
            ),
            (
                &["--default-lamp-height", "NaN"],
                "command line:1: field `--default-lamp-height`: NaN is not a non-negative number",
            ),
            (
                &["--default-height-sigma", "inf"],
                "command line:1: field `--default-height-sigma`: inf is not a non-negative number",
            ),
            (
                &["--ground-height", "-inf"],
                "command line:1: field `--ground-height`: -inf is not a finite number",
            ),
        ] {
            let e = parse(args).unwrap_err();
            assert_eq!(e.exit_code(), super::super::EXIT_INPUT, "{args:?}");
            assert_eq!(e.to_string(), message, "{args:?}");
        }
    }
}
