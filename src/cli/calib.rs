//! `vgps calib …`: inspect, check, use and convert calibration files.
//!
//! - `show FILE`: cameras, models, fields of view, sphere coverage and overlaps.
//! - `check FILE`: validation with figures; exit code 2 when a check fails.
//! - `bearings --calibration FILE`: CSV `camera,u,v` on stdin → `camera,u,v,ox,oy,oz,bx,by,bz`.
//! - `pixels --calibration FILE`: CSV `bx,by,bz[,ox,oy,oz]` on stdin → `index,camera,u,v`.
//! - `convert IN --to native|lut OUT`: rewrite a calibration (atomically).
//!
//! Every error (unreadable or invalid file, bad input line) is printed on stderr naming the
//! file and line, and exits with code 2.

use nalgebra::{Vector2, Vector3};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vgps_camera::calibration::formats::{self, Format, LoadError, to_lut_rig};
use vgps_camera::calibration::inspect::{
    CHECK_ROUND_TRIP_PX, Coverage, MAX_COVERAGE_CAMERAS, TableCheck, azimuth_deg, check_camera,
    elevation_deg, field_of_view,
};
use vgps_camera::calibration::{Camera, CameraModel, ROTATION_TOLERANCE, Rig};
use vgps_geometry::geometry::try_unit;

/// Exit code of every failure (bad input, invalid calibration, failed check).
pub const EXIT_FAILURE: u8 = 2;

/// Elevation (degrees) above which `show` reports the coverage (the spec's "most of the
/// sphere above ~−30°").
pub const COVERAGE_ELEVATION_DEG: f64 = -30.0;

/// Arguments of `vgps calib`.
#[derive(Debug, clap::Args)]
pub struct CalibArgs {
    /// The calib subcommand.
    #[command(subcommand)]
    pub command: CalibCommand,
}

/// The `vgps calib` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum CalibCommand {
    /// Cameras, models, fields of view, fraction of the sphere covered and overlaps.
    Show(FileArgs),
    /// Validate with figures (round trips, table monotonicity, rotations, coverage);
    /// exit code 2 on failure.
    Check(FileArgs),
    /// Read CSV `camera,u,v` on stdin, write `camera,u,v,ox,oy,oz,bx,by,bz` (ray origin in
    /// metres and unit bearing, rig frame).
    Bearings(UseArgs),
    /// Read CSV `bx,by,bz` (a direction) or `bx,by,bz,ox,oy,oz` (the point o + b, metres)
    /// in the rig frame on stdin, write `index,camera,u,v` for every camera that sees it.
    Pixels(UseArgs),
    /// Convert a calibration to the native JSON, or to native JSON with LUT cameras.
    Convert(ConvertArgs),
}

/// How to read a calibration.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct SourceArgs {
    /// Calibration format (default: detected from the file): native, ladybug-ini, nclt,
    /// ladybug-conf.
    #[arg(long, value_parser = parse_format)]
    pub format: Option<Format>,
    /// Image size WxH (pixels) for a Ladybug INI export that names none.
    #[arg(long, value_parser = super::image_size::parse_image_size)]
    pub image_size: Option<(u32, u32)>,
}

/// Arguments of `show` and `check`.
#[derive(Debug, clap::Args)]
pub struct FileArgs {
    /// The calibration file (or NCLT directory).
    pub file: PathBuf,
    /// Format and image size.
    #[command(flatten)]
    pub source: SourceArgs,
}

/// Arguments of `bearings` and `pixels`.
#[derive(Debug, clap::Args)]
pub struct UseArgs {
    /// The calibration file (or NCLT directory).
    #[arg(long)]
    pub calibration: PathBuf,
    /// Format and image size.
    #[command(flatten)]
    pub source: SourceArgs,
}

/// The output format of `convert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ConvertTarget {
    /// Native JSON with the same models.
    Native,
    /// Native JSON whose cameras are LUTs sampled from the input (side files
    /// `<stem>.cam<i>.lut`).
    Lut,
}

/// Arguments of `convert`.
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {
    /// The input calibration.
    pub input: PathBuf,
    /// The output format.
    #[arg(long, value_enum)]
    pub to: ConvertTarget,
    /// The output JSON file.
    pub output: PathBuf,
    /// LUT grid step in pixels (`--to lut`).
    #[arg(long, default_value_t = 4)]
    pub step: u32,
    /// Format and image size of the input.
    #[command(flatten)]
    pub source: SourceArgs,
}

fn parse_format(s: &str) -> Result<Format, String> {
    s.parse()
}

/// Validated settings of `vgps calib …` ([`super::Settings::Calib`]): what to read and
/// what to do with it.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibSettings {
    /// `show FILE`.
    Show {
        /// The calibration file (or NCLT directory).
        file: PathBuf,
        /// Format and image size.
        source: SourceArgs,
    },
    /// `check FILE`.
    Check {
        /// The calibration file (or NCLT directory).
        file: PathBuf,
        /// Format and image size.
        source: SourceArgs,
    },
    /// `bearings --calibration FILE`.
    Bearings {
        /// The calibration file (or NCLT directory).
        calibration: PathBuf,
        /// Format and image size.
        source: SourceArgs,
    },
    /// `pixels --calibration FILE`.
    Pixels {
        /// The calibration file (or NCLT directory).
        calibration: PathBuf,
        /// Format and image size.
        source: SourceArgs,
    },
    /// `convert IN --to native|lut OUT`.
    Convert {
        /// The input calibration.
        input: PathBuf,
        /// Format and image size of the input.
        source: SourceArgs,
        /// The output format.
        to: ConvertTo,
        /// The output JSON file.
        output: PathBuf,
    },
}

/// The validated output format of `convert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConvertTo {
    /// Native JSON with the same models.
    Native,
    /// Native JSON with LUT cameras sampled every `step` pixels.
    Lut {
        /// The LUT grid step in pixels.
        step: std::num::NonZeroU32,
    },
}

impl TryFrom<CalibArgs> for CalibSettings {
    type Error = super::CliError;

    /// # Errors
    /// [`super::CliError::Calibration`] (exit 2) when `convert --to lut` has `--step 0`.
    fn try_from(a: CalibArgs) -> Result<Self, Self::Error> {
        Ok(match a.command {
            CalibCommand::Show(a) => Self::Show {
                file: a.file,
                source: a.source,
            },
            CalibCommand::Check(a) => Self::Check {
                file: a.file,
                source: a.source,
            },
            CalibCommand::Bearings(a) => Self::Bearings {
                calibration: a.calibration,
                source: a.source,
            },
            CalibCommand::Pixels(a) => Self::Pixels {
                calibration: a.calibration,
                source: a.source,
            },
            CalibCommand::Convert(a) => Self::Convert {
                to: match a.to {
                    ConvertTarget::Native => ConvertTo::Native,
                    ConvertTarget::Lut => ConvertTo::Lut {
                        step: std::num::NonZeroU32::new(a.step).ok_or_else(|| {
                            super::CliError::Calibration("--step must be at least 1".into())
                        })?,
                    },
                },
                input: a.input,
                source: a.source,
                output: a.output,
            },
        })
    }
}

/// Runs `vgps calib …` and returns the process exit code (0; 1 when `convert` cannot write
/// its output; 2 on any other failure).
pub fn run(settings: &CalibSettings) -> ExitCode {
    let result = match settings {
        CalibSettings::Show { file, source } => load(file, source)
            .and_then(|rig| show(file, &rig))
            .and_then(|()| file_info(file, source, false)),
        CalibSettings::Check { file, source } => load(file, source)
            .and_then(|rig| check(file, &rig))
            .and_then(|()| file_info(file, source, true)),
        CalibSettings::Bearings {
            calibration,
            source,
        } => load(calibration, source).and_then(|rig| bearings(&rig)),
        CalibSettings::Pixels {
            calibration,
            source,
        } => load(calibration, source).and_then(|rig| pixels(&rig)),
        CalibSettings::Convert {
            input,
            source,
            to,
            output,
        } => match convert(input, source, *to, output) {
            Err(ConvertError::Output(message)) => {
                eprintln!("vgps calib: {message}");
                return ExitCode::from(super::EXIT_OUTPUT);
            }
            Err(ConvertError::Input(message)) => Err(message),
            Ok(()) => Ok(()),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("vgps calib: {message}");
            ExitCode::from(EXIT_FAILURE)
        }
    }
}

/// Prints [`super::calib_file_info::file_info`]; with `check`, fails when a file check
/// fails.
fn file_info(path: &Path, source: &SourceArgs, check: bool) -> Result<(), String> {
    let (text, ok) = super::calib_file_info::file_info(path, source)?;
    std::io::stdout()
        .write_all(text.as_bytes())
        .map_err(io_error)?;
    if check && !ok {
        return Err(format!(
            "{}: a stored pair is off by more than the limit",
            path.display()
        ));
    }
    Ok(())
}

fn load(path: &Path, source: &SourceArgs) -> Result<Rig, String> {
    formats::load(path, source.format, source.image_size).map_err(|e| e.to_string())
}

fn io_error(e: std::io::Error) -> String {
    format!("<stdout>: {e}")
}

fn show(path: &Path, rig: &Rig) -> Result<(), String> {
    let mut text = format!("{}: {} camera(s)\n", path.display(), rig.len());
    for (i, c) in rig.cameras().iter().enumerate() {
        let (w, h) = c.model.image_size();
        let axis = c.rig_from_camera.rotation * Vector3::z();
        let t = c.rig_from_camera.translation.vector;
        text += &format!(
            "camera {i}: {} {}\n  centre ({:.4}, {:.4}, {:.4}) m, optical axis azimuth {:.1}° elevation {:.1}°\n",
            c.model.model_name(),
            if w == 0 {
                "unbounded image".to_string()
            } else {
                format!("{w}×{h} px")
            },
            t.x,
            t.y,
            t.z,
            azimuth_deg(&axis),
            elevation_deg(&axis),
        );
        if let Some(fov) = field_of_view(&c.model) {
            let deg = |f: Option<f64>| f.map_or_else(|| "n/a".to_string(), |f| format!("{f:.1}°"));
            text += &format!(
                "  field of view: {} across (u), {} down (v), {} diagonal\n",
                deg(fov.across_deg),
                deg(fov.down_deg),
                deg(fov.diagonal_deg),
            );
        }
    }
    let Some(cov) = Coverage::try_new(rig) else {
        text += "coverage: not computed (unbounded images; give --image-size)\n";
        return write_stdout(&text);
    };
    text += &format!(
        "sphere covered: {:.2} % (by two or more cameras: {:.2} %)\n",
        100.0 * cov.seen_by_at_least(1),
        100.0 * cov.seen_by_at_least(2)
    );
    text += &format!(
        "above {COVERAGE_ELEVATION_DEG}° elevation: {:.2} % covered\n",
        100.0 * cov.seen_above(COVERAGE_ELEVATION_DEG)
    );
    match cov.covered_above() {
        Some(e) => text += &format!("every direction above {e:.1}° elevation is covered\n"),
        None => text += "the zenith is not covered\n",
    }
    let n = rig.len().min(MAX_COVERAGE_CAMERAS);
    let mut pairs = String::new();
    for i in 0..n {
        for j in i + 1..n {
            let f = cov.overlap(i, j);
            if f > 0.0 {
                pairs += &format!("  cameras {i} and {j}: {:.2} % of the sphere\n", 100.0 * f);
            }
        }
    }
    if pairs.is_empty() {
        text += "overlaps: none\n";
    } else {
        text += "overlaps (directions seen by both):\n";
        text += &pairs;
    }
    write_stdout(&text)
}

fn write_stdout(text: &str) -> Result<(), String> {
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .map_err(io_error)
}

fn check(path: &Path, rig: &Rig) -> Result<(), String> {
    let ok_or_fail = |ok: bool| if ok { "ok" } else { "FAIL" };
    let mut text = format!("{}: {} camera(s)\n", path.display(), rig.len());
    let mut failures = Vec::new();
    for (i, c) in rig.cameras().iter().enumerate() {
        text += &format!("camera {i} ({}):\n", c.model.model_name());
        let r = check_camera(c);
        text += &format!(
            "  rotation orthonormality: max |RᵀR − I|, |det R − 1| = {:.2e} (limit {ROTATION_TOLERANCE:.0e}) {}\n",
            r.rotation_deviation,
            ok_or_fail(r.rotation_passed())
        );
        if !r.rotation_passed() {
            failures.push(format!("camera {i}: rotation not orthonormal"));
        }
        text += &format!(
            "  round trip pixel → bearing → pixel over {} valid of {} probes: max {:.2e} px \
             (limit {CHECK_ROUND_TRIP_PX:.0e}), bearing {:.2e} rad, {} without a pixel {}\n",
            r.valid,
            r.probes,
            r.worst_round_trip_px,
            r.worst_round_trip_rad,
            r.lost,
            ok_or_fail(r.round_trip_passed())
        );
        if !r.round_trip_passed() {
            failures.push(format!("camera {i}: round trip"));
        }
        match &r.tables {
            Some(t @ TableCheck::Lut { min_orientation }) => {
                text += &format!(
                    "  LUT monotonicity: min cell orientation {min_orientation:.2e} (must be > 0) {}\n",
                    ok_or_fail(t.passed())
                );
                if !t.passed() {
                    failures.push(format!("camera {i}: LUT not monotonic"));
                }
            }
            Some(
                t @ TableCheck::Distortion {
                    min_jacobian_d2u,
                    min_jacobian_u2d,
                    worst_inconsistency_px,
                },
            ) => {
                text += &format!(
                    "  table monotonicity: min cell Jacobian determinant D2U {min_jacobian_d2u:.3}, U2D {min_jacobian_u2d:.3} (must be > 0) {}\n",
                    ok_or_fail(t.passed())
                );
                if !t.passed() {
                    failures.push(format!("camera {i}: table not monotonic"));
                }
                text += &format!(
                    "  table consistency: max |U2D(D2U(p)) − p| = {worst_inconsistency_px:.2e} px (information: only D2U defines the model)\n"
                );
            }
            None if matches!(c.model, Camera::TabulatedPinhole(_)) => {
                text += "  no distortion table\n";
            }
            None => {}
        }
    }
    if let Some(cov) = Coverage::try_new(rig) {
        let gaps = 1.0 - cov.seen_by_at_least(1);
        text += &format!(
            "coverage: {:.2} % of the sphere seen, gaps {:.2} %",
            100.0 * (1.0 - gaps),
            100.0 * gaps
        );
        match cov.covered_above() {
            Some(e) => text += &format!("; no gap above {e:.1}° elevation\n"),
            None => text += "; the zenith is not covered\n",
        }
        text += &format!(
            "horizon: {:.1}° of 360° azimuth not seen by any camera (information)\n",
            cov.horizon_gap_deg()
        );
    } else {
        text += "coverage: not computed (unbounded images)\n";
    }
    if failures.is_empty() {
        text += "check: ok\n";
        write_stdout(&text)
    } else {
        text += &format!("check: FAILED ({})\n", failures.join("; "));
        let _ = write_stdout(&text);
        Err(format!("{}: check failed", path.display()))
    }
}

/// CSV records of stdin: `(line number, fields)`, blank lines skipped; the header (a first
/// record whose first field is not a number) is returned separately.
type Records = (Option<Vec<String>>, Vec<(usize, Vec<String>)>);

fn read_stdin_records() -> Result<Records, String> {
    let stdin = std::io::stdin();
    let mut header = None;
    let mut records = Vec::new();
    for (k, line) in stdin.lock().lines().enumerate() {
        let line = line.map_err(|e| format!("<stdin>: {e}"))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let fields: Vec<String> = t.split(',').map(|s| s.trim().to_string()).collect();
        if header.is_none() && records.is_empty() && fields[0].parse::<f64>().is_err() {
            header = Some(fields);
            continue;
        }
        records.push((k + 1, fields));
    }
    Ok((header, records))
}

/// Column indices of `names` in the header (or `0..names.len()` without one).
fn columns(header: &Option<Vec<String>>, names: &[&str]) -> Result<Vec<Option<usize>>, String> {
    Ok(match header {
        Some(h) => names
            .iter()
            .map(|n| h.iter().position(|x| x.eq_ignore_ascii_case(n)))
            .collect(),
        None => (0..names.len()).map(Some).collect(),
    })
}

fn number(fields: &[String], index: usize, line: usize, name: &str) -> Result<f64, String> {
    let s = fields
        .get(index)
        .ok_or_else(|| format!("<stdin> line {line}: missing field {name}"))?;
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!(
            "<stdin> line {line}: field {name} = `{s}` is not a finite number"
        )),
    }
}

fn bearings(rig: &Rig) -> Result<(), String> {
    let (header, records) = read_stdin_records()?;
    let cols = columns(&header, &["camera", "u", "v"])?;
    let idx: Vec<usize> = cols
        .iter()
        .zip(["camera", "u", "v"])
        .map(|(c, n)| c.ok_or_else(|| format!("<stdin> line 1: the header has no column {n}")))
        .collect::<Result<_, _>>()?;
    let mut out = String::from("camera,u,v,ox,oy,oz,bx,by,bz\n");
    for (line, f) in records {
        let cam = f
            .get(idx[0])
            .ok_or_else(|| format!("<stdin> line {line}: missing field camera"))?;
        let camera: usize = cam
            .parse()
            .map_err(|_| format!("<stdin> line {line}: camera `{cam}` is not a camera index"))?;
        let u = number(&f, idx[1], line, "u")?;
        let v = number(&f, idx[2], line, "v")?;
        let ray = rig
            .ray(camera, &Vector2::new(u, v))
            .map_err(|e| format!("<stdin> line {line}: {e}"))?;
        let (o, b) = (ray.origin, ray.direction);
        out += &format!(
            "{camera},{u},{v},{},{},{},{},{},{}\n",
            o.x, o.y, o.z, b.x, b.y, b.z
        );
    }
    std::io::stdout()
        .lock()
        .write_all(out.as_bytes())
        .map_err(io_error)
}

fn pixels(rig: &Rig) -> Result<(), String> {
    let (header, records) = read_stdin_records()?;
    let names = ["bx", "by", "bz", "ox", "oy", "oz"];
    let cols = columns(&header, &names)?;
    for (c, n) in cols.iter().zip(names).take(3) {
        if c.is_none() {
            return Err(format!("<stdin> line 1: the header has no column {n}"));
        }
    }
    let mut out = String::from("index,camera,u,v\n");
    for (index, (line, f)) in records.iter().enumerate() {
        let get = |k: usize| -> Result<Option<f64>, String> {
            match cols[k] {
                Some(i) if header.is_some() || i < f.len() => {
                    number(f, i, *line, names[k]).map(Some)
                }
                _ => Ok(None),
            }
        };
        let b = Vector3::new(
            get(0)?.unwrap_or(0.0),
            get(1)?.unwrap_or(0.0),
            get(2)?.unwrap_or(0.0),
        );
        let o = [get(3)?, get(4)?, get(5)?];
        let seen = match o {
            [None, None, None] => {
                if try_unit(&b).is_none() {
                    return Err(format!("<stdin> line {line}: the direction is zero"));
                }
                rig.project_direction(&b)
            }
            [Some(x), Some(y), Some(z)] => rig.project_point(&(Vector3::new(x, y, z) + b)),
            _ => {
                return Err(format!(
                    "<stdin> line {line}: give all of ox, oy, oz or none"
                ));
            }
        };
        for p in seen {
            out += &format!("{index},{},{},{}\n", p.camera, p.pixel.x, p.pixel.y);
        }
    }
    std::io::stdout()
        .lock()
        .write_all(out.as_bytes())
        .map_err(io_error)
}

/// Why `calib convert` failed: the input (exit 2) or writing the output (exit 1).
enum ConvertError {
    Input(String),
    Output(String),
}

fn convert(
    input: &Path,
    source: &SourceArgs,
    to: ConvertTo,
    output: &Path,
) -> Result<(), ConvertError> {
    let rig = load(input, source).map_err(ConvertError::Input)?;
    let rig = match to {
        ConvertTo::Native => rig,
        ConvertTo::Lut { step } => to_lut_rig(&rig, step.get(), input)
            .map_err(|e: LoadError| ConvertError::Input(e.to_string()))?,
    };
    formats::save_native(&rig, output).map_err(|e| ConvertError::Output(e.to_string()))?;
    eprintln!(
        "wrote {} ({} camera(s), {})",
        output.display(),
        rig.len(),
        match to {
            ConvertTo::Native => "native".to_string(),
            ConvertTo::Lut { step } => format!("LUT step {step} px"),
        }
    );
    Ok(())
}
