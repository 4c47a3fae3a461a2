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

use nalgebra::{Matrix3, Vector2, Vector3};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vgps_camera::calibration::formats::{self, Format, LoadError, to_lut_rig};
use vgps_camera::calibration::{Camera, CameraModel, Pixel, Rig};
use vgps_geometry::geometry::{angle_between, try_unit};

/// Exit code of every failure (bad input, invalid calibration, failed check).
pub const EXIT_FAILURE: u8 = 2;

/// Number of directions (a Fibonacci sphere) used for coverage figures.
pub const COVERAGE_SAMPLES: usize = 20_000;

/// Elevation (degrees) above which `show` reports the coverage (the spec's "most of the
/// sphere above ~−30°").
pub const COVERAGE_ELEVATION_DEG: f64 = -30.0;

/// Largest accepted pixel → bearing → pixel round-trip error of `check` (pixels).
pub const CHECK_ROUND_TRIP_PX: f64 = 1e-6;

/// Largest accepted bearing → pixel → bearing round-trip error of `check` (radians).
pub const CHECK_ROUND_TRIP_RAD: f64 = 1e-9;

/// Pixels probed per image side by `check`'s round trip.
pub const CHECK_GRID: usize = 97;

/// Samples along an image line when measuring a field of view.
pub const FOV_SAMPLES: usize = 2000;

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
#[derive(Debug, Clone, clap::Args)]
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

/// Runs `vgps calib …` and returns the process exit code (0; 1 when `convert` cannot write
/// its output; 2 on any other failure).
pub fn run(args: CalibArgs) -> ExitCode {
    let result = match args.command {
        CalibCommand::Show(a) => load(&a.file, &a.source)
            .and_then(|rig| show(&a.file, &rig))
            .and_then(|()| file_info(&a.file, &a.source, false)),
        CalibCommand::Check(a) => load(&a.file, &a.source)
            .and_then(|rig| check(&a.file, &rig))
            .and_then(|()| file_info(&a.file, &a.source, true)),
        CalibCommand::Bearings(a) => load(&a.calibration, &a.source).and_then(|rig| bearings(&rig)),
        CalibCommand::Pixels(a) => load(&a.calibration, &a.source).and_then(|rig| pixels(&rig)),
        CalibCommand::Convert(a) => match convert(&a) {
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

/// `n` directions evenly spread on the unit sphere (Fibonacci lattice).
pub fn fibonacci_sphere(n: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            Vector3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Field of view (degrees) along the image line from `a` to `b` through `centre`: the
/// largest angle from the centre's bearing towards `a` plus towards `b` over valid pixels.
fn fov_along(model: &Camera, centre: &Pixel, a: &Pixel, b: &Pixel) -> Option<f64> {
    let c = model.try_bearing(centre)?;
    let half = |end: &Pixel| {
        (0..=FOV_SAMPLES)
            .filter_map(|k| {
                let t = k as f64 / FOV_SAMPLES as f64;
                model
                    .try_bearing(&(centre + (end - centre) * t))
                    .map(|x| angle_between(&c, &x))
            })
            .fold(0.0, f64::max)
    };
    Some((half(a) + half(b)).to_degrees())
}

/// Coverage statistics over a Fibonacci sphere.
struct Coverage {
    /// Per sample: bit mask of the cameras that see it.
    seen_by: Vec<u64>,
    directions: Vec<Vector3<f64>>,
}

impl Coverage {
    fn new(rig: &Rig) -> Self {
        let directions = fibonacci_sphere(COVERAGE_SAMPLES);
        let seen_by = directions
            .iter()
            .map(|d| {
                rig.project_direction(d)
                    .iter()
                    .filter(|p| p.camera < 64)
                    .fold(0u64, |m, p| m | (1 << p.camera))
            })
            .collect();
        Self {
            seen_by,
            directions,
        }
    }

    fn fraction(&self, keep: impl Fn(u64, &Vector3<f64>) -> bool) -> f64 {
        let n = self
            .seen_by
            .iter()
            .zip(&self.directions)
            .filter(|(m, d)| keep(**m, d))
            .count();
        n as f64 / self.directions.len() as f64
    }

    /// The lowest elevation (degrees) above which every sample is covered, or `None` when
    /// the zenith itself is not covered.
    fn covered_above(&self) -> Option<f64> {
        let mut highest_gap = f64::NEG_INFINITY;
        for (m, d) in self.seen_by.iter().zip(&self.directions) {
            if *m == 0 {
                highest_gap = highest_gap.max(d.z.clamp(-1.0, 1.0).asin().to_degrees());
            }
        }
        if highest_gap == f64::NEG_INFINITY {
            Some(-90.0)
        } else if highest_gap >= 89.0 {
            None
        } else {
            Some(highest_gap)
        }
    }
}

fn elevation_deg(d: &Vector3<f64>) -> f64 {
    d.z.clamp(-1.0, 1.0).asin().to_degrees()
}

fn azimuth_deg(d: &Vector3<f64>) -> f64 {
    d.y.atan2(d.x).to_degrees()
}

fn show(path: &Path, rig: &Rig) -> Result<(), String> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
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
        if w > 0 {
            let (wf, hf) = (f64::from(w) - 0.5, f64::from(h) - 0.5);
            let centre = Vector2::new((wf - 0.5) / 2.0, (hf - 0.5) / 2.0);
            let fov = |a: Pixel, b: Pixel| {
                fov_along(&c.model, &centre, &a, &b)
                    .map_or_else(|| "n/a".to_string(), |f| format!("{f:.1}°"))
            };
            text += &format!(
                "  field of view: {} across (u), {} down (v), {} diagonal\n",
                fov(Vector2::new(-0.5, centre.y), Vector2::new(wf, centre.y)),
                fov(Vector2::new(centre.x, -0.5), Vector2::new(centre.x, hf)),
                fov(Vector2::new(-0.5, -0.5), Vector2::new(wf, hf)),
            );
        }
    }
    if rig.cameras().iter().any(|c| c.model.image_size().0 == 0) {
        text += "coverage: not computed (unbounded images; give --image-size)\n";
        return out.write_all(text.as_bytes()).map_err(io_error);
    }
    let cov = Coverage::new(rig);
    let low = COVERAGE_ELEVATION_DEG.to_radians().sin();
    let above = cov.fraction(|_, d| d.z >= low);
    text += &format!(
        "sphere covered: {:.2} % (by two or more cameras: {:.2} %)\n",
        100.0 * cov.fraction(|m, _| m != 0),
        100.0 * cov.fraction(|m, _| m.count_ones() >= 2)
    );
    text += &format!(
        "above {COVERAGE_ELEVATION_DEG}° elevation: {:.2} % covered\n",
        100.0 * cov.fraction(|m, d| m != 0 && d.z >= low) / above
    );
    match cov.covered_above() {
        Some(e) => text += &format!("every direction above {e:.1}° elevation is covered\n"),
        None => text += "the zenith is not covered\n",
    }
    let n = rig.len().min(64);
    let mut pairs = String::new();
    for i in 0..n {
        for j in i + 1..n {
            let both = (1u64 << i) | (1u64 << j);
            let f = cov.fraction(|m, _| m & both == both);
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
    out.write_all(text.as_bytes()).map_err(io_error)
}

/// Deterministic probe pixels of a camera: a grid over the image rectangle (inset by a
/// hundredth of a pixel) with irrational offsets; for an unbounded image, over
/// `[0, 2 cx] × [0, 2 cy]`.
fn probe_pixels(model: &Camera) -> Vec<Pixel> {
    let (w, h) = model.image_size();
    let (w, h) = if w == 0 {
        match model {
            Camera::TabulatedPinhole(m) => {
                let p = m.params();
                ((2.0 * p.cx + 1.0).max(2.0), (2.0 * p.cy + 1.0).max(2.0))
            }
            _ => (2.0, 2.0),
        }
    } else {
        (f64::from(w), f64::from(h))
    };
    let n = CHECK_GRID;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let fu = (i as f64 + 0.5 * (i % 2) as f64 * 0.618) / (n - 1) as f64;
            let fv = (j as f64 + 0.5 * (j % 2) as f64 * 0.414) / (n - 1) as f64;
            let u = -0.49 + fu.min(1.0) * (w - 0.98);
            let v = -0.49 + fv.min(1.0) * (h - 0.98);
            out.push(Vector2::new(u, v));
        }
    }
    out
}

/// The smallest `((b10 − b00) × (b01 − b00)) · b00` over the cells of a LUT (> 0 when every
/// cell keeps the image's orientation).
fn lut_min_orientation(lut: &vgps_camera::calibration::Lut) -> f64 {
    let (cols, rows) = lut.grid_size();
    let b = &lut.params().bearings;
    let v = |i: usize, j: usize| {
        let x = b[j * cols + i];
        Vector3::new(f64::from(x[0]), f64::from(x[1]), f64::from(x[2]))
    };
    let mut min = f64::INFINITY;
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let b00 = v(i, j);
            min = min.min((v(i + 1, j) - b00).cross(&(v(i, j + 1) - b00)).dot(&b00));
        }
    }
    min
}

fn check(path: &Path, rig: &Rig) -> Result<(), String> {
    let mut text = format!("{}: {} camera(s)\n", path.display(), rig.len());
    let mut failures = Vec::new();
    for (i, c) in rig.cameras().iter().enumerate() {
        text += &format!("camera {i} ({}):\n", c.model.model_name());
        let r: &Matrix3<f64> = c.rig_from_camera.rotation.matrix();
        let dev = (r.transpose() * r - Matrix3::identity())
            .abs()
            .max()
            .max((r.determinant() - 1.0).abs());
        let ok = dev <= vgps_camera::calibration::ROTATION_TOLERANCE;
        text += &format!(
            "  rotation orthonormality: max |RᵀR − I|, |det R − 1| = {dev:.2e} (limit {:.0e}) {}\n",
            vgps_camera::calibration::ROTATION_TOLERANCE,
            if ok { "ok" } else { "FAIL" }
        );
        if !ok {
            failures.push(format!("camera {i}: rotation not orthonormal"));
        }
        let probes = probe_pixels(&c.model);
        let (mut worst_px, mut worst_rad, mut valid, mut lost) = (0.0f64, 0.0f64, 0usize, 0usize);
        for p in &probes {
            let Some(b) = c.model.try_bearing(p) else {
                continue;
            };
            valid += 1;
            match c.model.try_pixel(&b) {
                Some(q) => {
                    worst_px = worst_px.max((q - p).norm());
                    if let Some(b2) = c.model.try_bearing(&q) {
                        worst_rad = worst_rad.max(angle_between(&b, &b2));
                    }
                }
                None => lost += 1,
            }
        }
        let ok = lost == 0 && worst_px <= CHECK_ROUND_TRIP_PX && worst_rad <= CHECK_ROUND_TRIP_RAD;
        text += &format!(
            "  round trip pixel → bearing → pixel over {valid} valid of {} probes: max {worst_px:.2e} px \
             (limit {CHECK_ROUND_TRIP_PX:.0e}), bearing {worst_rad:.2e} rad, {lost} without a pixel {}\n",
            probes.len(),
            if ok { "ok" } else { "FAIL" }
        );
        if !ok {
            failures.push(format!("camera {i}: round trip"));
        }
        match &c.model {
            Camera::Lut(lut) => {
                let m = lut_min_orientation(lut);
                let ok = m > 0.0;
                text += &format!(
                    "  LUT monotonicity: min cell orientation {m:.2e} (must be > 0) {}\n",
                    if ok { "ok" } else { "FAIL" }
                );
                if !ok {
                    failures.push(format!("camera {i}: LUT not monotonic"));
                }
            }
            Camera::TabulatedPinhole(m) => {
                let p = m.params();
                if let (Some(d2u), Some(u2d)) = (&p.raw_to_undistorted, &p.undistorted_to_raw) {
                    let (a, b) = (
                        d2u.min_jacobian_determinant(),
                        u2d.min_jacobian_determinant(),
                    );
                    let ok = a > 0.0 && b > 0.0;
                    text += &format!(
                        "  table monotonicity: min cell Jacobian determinant D2U {a:.3}, U2D {b:.3} (must be > 0) {}\n",
                        if ok { "ok" } else { "FAIL" }
                    );
                    if !ok {
                        failures.push(format!("camera {i}: table not monotonic"));
                    }
                    // Consistency of the two tables at the raw pixel centres.
                    let mut worst: f64 = 0.0;
                    for r in 0..d2u.height {
                        for col in 0..d2u.width {
                            let px = Vector2::new(f64::from(col), f64::from(r));
                            let q = d2u.interpolate(&px).0;
                            worst = worst.max((u2d.interpolate(&q).0 - px).norm());
                        }
                    }
                    text += &format!(
                        "  table consistency: max |U2D(D2U(p)) − p| = {worst:.2e} px (information: only D2U defines the model)\n"
                    );
                } else {
                    text += "  no distortion table\n";
                }
            }
            _ => {}
        }
    }
    if rig.cameras().iter().all(|c| c.model.image_size().0 > 0) {
        let cov = Coverage::new(rig);
        let gaps = cov.fraction(|m, _| m == 0);
        text += &format!(
            "coverage: {:.2} % of the sphere seen, gaps {:.2} %",
            100.0 * (1.0 - gaps),
            100.0 * gaps
        );
        match cov.covered_above() {
            Some(e) => text += &format!("; no gap above {e:.1}° elevation\n"),
            None => text += "; the zenith is not covered\n",
        }
        let horizon_gaps = (0..3600)
            .filter(|k| {
                let a = (*k as f64 / 10.0).to_radians();
                rig.project_direction(&Vector3::new(a.cos(), a.sin(), 0.0))
                    .is_empty()
            })
            .count();
        text += &format!(
            "horizon: {:.1}° of 360° azimuth not seen by any camera (information)\n",
            horizon_gaps as f64 / 10.0
        );
    } else {
        text += "coverage: not computed (unbounded images)\n";
    }
    if failures.is_empty() {
        text += "check: ok\n";
        std::io::stdout()
            .lock()
            .write_all(text.as_bytes())
            .map_err(io_error)
    } else {
        text += &format!("check: FAILED ({})\n", failures.join("; "));
        let _ = std::io::stdout().lock().write_all(text.as_bytes());
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

fn convert(a: &ConvertArgs) -> Result<(), ConvertError> {
    let rig = load(&a.input, &a.source).map_err(ConvertError::Input)?;
    let rig = match a.to {
        ConvertTarget::Native => rig,
        ConvertTarget::Lut => {
            if a.step == 0 {
                return Err(ConvertError::Input("--step must be at least 1".into()));
            }
            to_lut_rig(&rig, a.step, &a.input)
                .map_err(|e: LoadError| ConvertError::Input(e.to_string()))?
        }
    };
    formats::save_native(&rig, &a.output).map_err(|e| ConvertError::Output(e.to_string()))?;
    eprintln!(
        "wrote {} ({} camera(s), {})",
        a.output.display(),
        rig.len(),
        match a.to {
            ConvertTarget::Native => "native".to_string(),
            ConvertTarget::Lut => format!("LUT step {} px", a.step),
        }
    );
    Ok(())
}
