//! `vgps map DRIVE`: survey mode from the command line (Ku, Ho & Sarma's landmark inventory).
//!
//! The satellite GPS of a drive (GGA/RMC position, HDT heading) gives every camera frame a
//! level pose with covariance; the detections become rays through the rig calibration; the
//! mapper associates them and refines every landmark ([`vgps_core::mapping::survey`]); the
//! inventory is written as a landmarks.csv that `vgps locate --landmarks` and the localizer
//! read. `--gps-offset auto` first estimates the GPS latency
//! ([`vgps_core::mapping::calibrate_gps_offset`]).
//!
//! # Frames
//! The survey works in the local ENU frame at the **first GNSS fix** of the drive (the
//! drive's surveyed landmarks are not used at all: survey mode needs none). The written
//! file is in WGS84, so the frame is only internal.
//!
//! # Gaps
//! [`vgps_core::mapping::gps_pose_at`] interpolates linearly between any two samples; across an
//! outage that would invent poses. A frame is used only when the GPS track covers
//! `[t − m, t + m]` (`m` = the largest offset that may be applied) with epochs at most
//! [`MAX_GNSS_GAP_S`] apart ([`vgps_core::mapping::track_covers`]).
//!
//! The track's smoothing and coverage, the χ² and frame-coverage checks of a landmark live
//! in [`vgps_core::mapping`] and [`vgps_core::stats`]; this module only orchestrates them.

use super::args::{parse_non_negative, parse_positive};
use super::replay::OutputFormat;
use super::{CliError, MapSettings};
use serde::Serialize;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use vgps_camera::calibration::{Pixel, Rig};
use vgps_core::mapping::{
    CameraFrame, GpsSample, MAX_GPS_OFFSET_S, MIN_LANDMARK_RAYS, MappedLandmark, OffsetSearch,
    RigObservation, Survey, SurveyOptions, calibrate_gps_offset, frame_coverage, landmark_chi2,
    median_speed, smooth_track, survey, track_covers, write_landmarks_csv,
};
use vgps_core::stats::median;
use vgps_geometry::geo::LocalFrame;
use vgps_geometry::geometry::Ray;
use vgps_replay::drive::{Drive, GnssRecord};

// Kept at their former paths: the track's constants and the statistics now live in
// `vgps_core::mapping` and `vgps_core::stats`.
pub use vgps_core::mapping::{MAX_GNSS_GAP_S, MIN_SMOOTH_FIXES};
pub use vgps_core::stats::{chi2_quantile, pearson};

/// Default horizontal σ of a GNSS fix per axis (metres). The white part of a consumer
/// receiver's error (the simulator's CEP 2 m receiver: 22 % of 1.7² m²  ⇒ ≈ 0.8 m); the slow
/// bias is common to the frames that see a landmark and moves it as a whole.
pub const DEFAULT_GNSS_SIGMA_M: f64 = 0.8;
/// Vertical σ of a fix as a multiple of the horizontal σ (dimensionless).
pub const VERTICAL_SIGMA_FACTOR: f64 = 1.5;
/// Default σ of the GNSS heading (degrees).
pub const DEFAULT_HEADING_SIGMA_DEG: f64 = 0.5;
/// Standard-normal quantile of the ray-consistency test (99.9 %): a landmark whose rays'
/// χ² exceeds the χ²(dof) quantile at this level is not written. Two to five random
/// transient lights (headlights, windows) pass the mapper's per-ray gates now and then; the
/// χ² of all their rays together rarely does.
pub const CONSISTENCY_Z: f64 = 3.090_232_306_167_813;
/// Default of `--min-coverage`: a landmark in view is detected in most frames (the
/// simulator misses 10 %); a track whose rays come from fewer than this fraction of the
/// frames of its time span is a chance alignment of transient lights.
pub const DEFAULT_MIN_COVERAGE: f64 = 0.5;
/// Default of `--min-obs`: tracks of 3–4 rays are mostly chance alignments of transient
/// lights (measured on the short simulated drive); the surrogate criterion
/// ([`vgps_core::mapping::MIN_SURROGATE_RAYS`]).
pub const DEFAULT_MIN_OBS: usize = vgps_core::mapping::MIN_SURROGATE_RAYS;
/// Default of `--smooth-s` (seconds): ±1 s of a 5 Hz receiver is 11 fixes, which a
/// quadratic fits to within the vehicle's jerk (≈ 0.1 m at 1.5 m/s³) while dividing the white
/// noise's σ by ≈ 2.
pub const DEFAULT_SMOOTH_S: f64 = 1.0;
/// File name of the inventory in the drive directory when `--out` is not given.
pub const DEFAULT_OUTPUT_NAME: &str = "mapped_landmarks.csv";

/// The GPS time offset to apply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GpsOffset {
    /// Estimate it ([`calibrate_gps_offset`]) and apply the estimate.
    Auto,
    /// This offset (seconds; positive when the GPS lags the camera).
    Seconds(f64),
}

fn parse_offset(text: &str) -> Result<GpsOffset, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(GpsOffset::Auto);
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 10.0 => Ok(GpsOffset::Seconds(v)),
        _ => Err(format!(
            "`{text}` is neither `auto` nor a number of seconds in [-10, 10]"
        )),
    }
}

fn parse_min_obs(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= MIN_LANDMARK_RAYS => Ok(n),
        _ => Err(format!(
            "`{text}` is not an integer ≥ {MIN_LANDMARK_RAYS} (3 rays leave one degree of freedom)"
        )),
    }
}

/// Arguments of `vgps map`.
#[derive(Debug, Clone, clap::Args)]
pub struct MapArgs {
    /// The drive directory (with `drive.json` and GNSS with heading; see
    /// docs/drive-format.md).
    pub drive: PathBuf,
    /// The landmarks file to write (default: `DRIVE/mapped_landmarks.csv`), replaced
    /// atomically.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// GPS time offset: `auto` (estimate and apply it) or seconds (positive: the GPS lags).
    #[arg(long, value_name = "auto|SECONDS", default_value = "0", value_parser = parse_offset, allow_hyphen_values = true)]
    pub gps_offset: GpsOffset,
    /// Pixel σ of a detection (pixels), turned into an angle by the camera model's Jacobian.
    #[arg(long, value_name = "S", default_value_t = vgps_core::localizer::DEFAULT_PIXEL_SIGMA_PX, value_parser = parse_positive)]
    pub pixel_sigma_px: f64,
    /// Horizontal σ of a GNSS fix per axis (metres); vertical = 1.5 ×.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_GNSS_SIGMA_M, value_parser = parse_positive)]
    pub gnss_sigma_m: f64,
    /// σ of the GNSS heading (degrees).
    #[arg(long, value_name = "D", default_value_t = DEFAULT_HEADING_SIGMA_DEG, value_parser = parse_positive)]
    pub heading_sigma_deg: f64,
    /// Fewest observations (rays) of a written landmark (≥ 3).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MIN_OBS, value_parser = parse_min_obs)]
    pub min_obs: usize,
    /// Fewest frames with an observation of a landmark, as a fraction of the frames of
    /// its time span (0–1).
    #[arg(long, value_name = "F", default_value_t = DEFAULT_MIN_COVERAGE, value_parser = parse_fraction)]
    pub min_coverage: f64,
    /// Half-width of the window of the local quadratic fit that smooths the GNSS positions
    /// (seconds; 0 = raw fixes).
    #[arg(long, value_name = "S", default_value_t = DEFAULT_SMOOTH_S, value_parser = parse_non_negative)]
    pub smooth_s: f64,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: OutputFormat,
    /// Unknown keys in drive.json are an error (default: a warning).
    #[arg(long)]
    pub strict: bool,
    /// Satellite GPS from another file (survey mode needs a heading: NMEA with `HDT`).
    #[command(flatten)]
    pub gnss: super::gnss_input::GnssInputArgs,
}

fn parse_fraction(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("`{text}` is not a number in [0, 1]")),
    }
}

/// The GPS offset part of the summary.
#[derive(Clone, Debug, Serialize)]
pub struct OffsetSummary {
    /// `auto` or `given`.
    pub mode: &'static str,
    /// The applied offset (seconds).
    pub offset_s: f64,
    /// Its standard deviation (seconds), when estimated and observable.
    pub sigma_s: Option<f64>,
    /// The offset times the median speed (metres along track).
    pub along_track_m: f64,
    /// Median speed over the GNSS track (m/s).
    pub median_speed_m_s: f64,
    /// χ² of the rays at offset 0 and at the estimate, with its degrees of freedom (auto).
    pub chi2_at_zero: Option<f64>,
    /// χ² at the estimate (auto).
    pub chi2_at_offset: Option<f64>,
    /// Degrees of freedom of the χ² (auto).
    pub dof: Option<usize>,
}

/// Distribution of the number of observations per landmark.
#[derive(Clone, Debug, Serialize)]
pub struct NobsSummary {
    /// Fewest.
    pub min: usize,
    /// Median.
    pub median: usize,
    /// 90th percentile.
    pub p90: usize,
    /// Most.
    pub max: usize,
    /// Landmarks with 3–4, 5–9, 10–19, 20–49, ≥ 50 observations.
    pub histogram: [usize; 5],
}

/// The summary of `vgps map`.
#[derive(Clone, Debug, Serialize)]
pub struct MapSummary {
    /// The written file.
    pub output: String,
    /// Origin of the internal ENU frame (first GNSS fix): lat, lon (degrees), height (m).
    pub origin: [f64; 3],
    /// Frames of the drive.
    pub frames: usize,
    /// Frames inside the GNSS track (used).
    pub frames_used: usize,
    /// GNSS epochs with a fix and a heading.
    pub gps_samples: usize,
    /// Rays given to the mapper.
    pub rays: usize,
    /// Detections whose pixel has no ray (outside the camera model).
    pub detections_without_ray: usize,
    /// Landmarks written.
    pub landmarks: usize,
    /// Tracks with enough observations whose rays fail the χ² consistency test (not
    /// written).
    pub inconsistent: usize,
    /// Landmarks per class name (`""` = no class).
    pub landmarks_by_class: Vec<(String, usize)>,
    /// Observations per landmark.
    pub n_obs: Option<NobsSummary>,
    /// Median of the landmarks' worst-axis σ (metres).
    pub median_sigma_m: Option<f64>,
    /// Pearson correlation of `1/λ_max(Σ)` with `n_obs` over the landmarks (Ku et al.
    /// Fig. 7), when there are at least 3 landmarks.
    pub information_nobs_correlation: Option<f64>,
    /// The GPS time offset.
    pub gps_offset: OffsetSummary,
    /// Wall time (seconds).
    pub time_s: f64,
}

/// Runs `vgps map`.
///
/// # Errors
/// [`CliError::Calibration`] when the drive cannot be opened or has no usable GNSS track
/// (exit 2); [`CliError::Output`] when the file or the summary cannot be written.
pub fn run(
    settings: &MapSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let start = Instant::now();
    let mut drive = Drive::open(&settings.drive, settings.strictness)
        .map_err(|e| CliError::Calibration(e.to_string()))?;
    settings.gnss.apply(&mut drive, err)?;
    for w in drive.warnings() {
        let _ = writeln!(err, "vgps: warning: {w}");
    }
    let unusable =
        |what: &str| CliError::Calibration(format!("{}: {what}", settings.drive.display()));
    let Some(origin) = drive.gnss().iter().find_map(|r| r.fix.map(|f| f.position)) else {
        return Err(unusable("no GNSS fix: survey mode needs GPS with heading"));
    };
    let frame = LocalFrame::new(origin);
    // The offset is calibrated on the raw fixes (the smoothed track biased it: 0.33 s for a
    // true 0.1 s on the precise short drive), the inventory mapped on the smoothed one.
    let raw_gps = gps_samples(drive.gnss(), &frame, settings);
    let gps = smooth_track(&raw_gps, settings.smooth_s);
    if gps.len() < 2 {
        return Err(unusable(
            "fewer than two GNSS epochs with both a fix and a heading (GGA + HDT)",
        ));
    }
    let margin = match settings.gps_offset {
        GpsOffset::Auto => MAX_GPS_OFFSET_S,
        GpsOffset::Seconds(s) => s.abs(),
    };
    let rays = collect_rays(&drive, &gps, margin, settings.pixel_sigma_px);
    let mut options = SurveyOptions::default();
    options.mapper.min_landmark_rays = settings.min_obs;
    let mapping_error = |e: vgps_core::mapping::MappingError| {
        CliError::Calibration(format!("{}: {e}", settings.drive.display()))
    };
    let gps_offset = offset_summary(settings.gps_offset, &raw_gps, &gps, &rays.frames, &options)
        .map_err(mapping_error)?;
    options.gps_time_offset_s = gps_offset.offset_s;
    let inventory = survey(&gps, &rays.frames, &options).map_err(mapping_error)?;
    let (landmarks, inconsistent) =
        consistent_landmarks(&inventory, &gps, &rays.frames, &options, settings);
    let path = &settings.out;
    write_landmarks_csv(path, &landmarks, &frame, &rays.classes)
        .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())))?;
    let summary = MapSummary {
        output: path.display().to_string(),
        origin: [origin.lat_deg, origin.lon_deg, origin.alt_m],
        frames: drive.frames().len(),
        frames_used: rays.frames.len(),
        gps_samples: gps.len(),
        rays: rays.rays,
        detections_without_ray: rays.without_ray,
        landmarks: landmarks.len(),
        inconsistent,
        landmarks_by_class: by_class(&landmarks, &rays.classes),
        n_obs: nobs_summary(&landmarks),
        median_sigma_m: median(landmarks.iter().map(MappedLandmark::sigma_m).collect()),
        information_nobs_correlation: information_correlation(&landmarks),
        gps_offset,
        time_s: start.elapsed().as_secs_f64(),
    };
    write_summary(&summary, settings.format, out)
}

/// The camera frames of a drive as rays in the rig frame, with the class names met.
struct DriveRays {
    /// The frames inside the GNSS track, in drive order.
    frames: Vec<CameraFrame>,
    /// Class names, indexed by the observations' class.
    classes: Vec<String>,
    /// Rays given to the mapper.
    rays: usize,
    /// Detections whose pixel has no ray.
    without_ray: usize,
}

/// The rays of every frame whose time ± `margin` the track covers ([`track_covers`]).
fn collect_rays(drive: &Drive, gps: &[GpsSample], margin: f64, pixel_sigma_px: f64) -> DriveRays {
    let mut classes: Vec<String> = Vec::new();
    let mut class_of: HashMap<String, u32> = HashMap::new();
    let mut frames = Vec::new();
    let mut without_ray = 0;
    let mut rays = 0;
    for f in drive.frames() {
        if !track_covers(gps, f.time_s, margin) {
            continue;
        }
        let mut observations = Vec::new();
        for d in drive.detections(f.frame) {
            let class = d.class.as_ref().map(|name| {
                *class_of.entry(name.clone()).or_insert_with(|| {
                    classes.push(name.clone());
                    u32::try_from(classes.len() - 1).unwrap_or(u32::MAX)
                })
            });
            match pixel_ray(drive.rig(), d.camera, d.u, d.v, pixel_sigma_px) {
                Some((ray_in_rig, sigma_rad)) => observations.push(RigObservation {
                    ray_in_rig,
                    sigma_rad,
                    class,
                }),
                None => without_ray += 1,
            }
        }
        rays += observations.len();
        frames.push(CameraFrame {
            time_s: f.time_s,
            observations,
        });
    }
    DriveRays {
        frames,
        classes,
        rays,
        without_ray,
    }
}

/// The GPS offset to apply: the given one, or the estimate of [`calibrate_gps_offset`] on
/// the raw track (`gps` is the smoothed track, for the median speed).
fn offset_summary(
    offset: GpsOffset,
    raw_gps: &[GpsSample],
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
) -> Result<OffsetSummary, vgps_core::mapping::MappingError> {
    let speed = median_speed(gps);
    Ok(match offset {
        GpsOffset::Seconds(s) => OffsetSummary {
            mode: "given",
            offset_s: s,
            sigma_s: None,
            along_track_m: s * speed,
            median_speed_m_s: speed,
            chi2_at_zero: None,
            chi2_at_offset: None,
            dof: None,
        },
        GpsOffset::Auto => {
            let c = calibrate_gps_offset(raw_gps, frames, options, &OffsetSearch::default())?;
            OffsetSummary {
                mode: "auto",
                offset_s: c.offset_s,
                sigma_s: c.sigma_s,
                along_track_m: c.offset_s * speed,
                median_speed_m_s: speed,
                chi2_at_zero: Some(c.chi2_at_zero),
                chi2_at_offset: Some(c.chi2_at_offset),
                dof: Some(c.dof),
            }
        }
    })
}

/// The inventory's landmarks with at least `--min-obs` rays that pass the frame-coverage
/// test and whose rays meet within their covariance (χ² at [`CONSISTENCY_Z`]), and how
/// many failed those two tests.
fn consistent_landmarks(
    inventory: &Survey,
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
    settings: &MapSettings,
) -> (Vec<MappedLandmark>, usize) {
    let sources: HashMap<u64, &[(usize, usize)]> = inventory
        .sources
        .iter()
        .map(|(id, v)| (*id, v.as_slice()))
        .collect();
    let mut inconsistent = 0;
    let landmarks = inventory
        .landmarks
        .iter()
        .filter(|l| l.n_obs >= settings.min_obs)
        .filter(|l| {
            let src = sources.get(&l.id).copied().unwrap_or(&[]);
            let ok = frame_coverage(src) >= settings.min_coverage
                && landmark_chi2(gps, frames, src, options)
                    .is_some_and(|(chi2, dof)| chi2 <= chi2_quantile(dof, CONSISTENCY_Z));
            inconsistent += usize::from(!ok);
            ok
        })
        .cloned()
        .collect();
    (landmarks, inconsistent)
}

/// GNSS epochs with a fix and a heading, in the ENU `frame`, with the σ of the settings
/// (vertical = [`VERTICAL_SIGMA_FACTOR`] × horizontal).
fn gps_samples(
    records: &[GnssRecord],
    frame: &LocalFrame,
    settings: &MapSettings,
) -> Vec<GpsSample> {
    let mut gps: Vec<GpsSample> = Vec::new();
    for r in records {
        let (Some(fix), Some(heading_deg)) = (r.fix, r.heading_deg) else {
            continue;
        };
        if !(r.time_s.is_finite() && heading_deg.is_finite())
            || gps.last().is_some_and(|g| r.time_s <= g.time_s)
        {
            continue;
        }
        gps.push(GpsSample {
            time_s: r.time_s,
            position_enu: frame.to_enu(&fix.position),
            heading_rad: heading_deg.to_radians(),
            sigma_horizontal_m: settings.gnss_sigma_m,
            sigma_vertical_m: VERTICAL_SIGMA_FACTOR * settings.gnss_sigma_m,
            sigma_heading_rad: settings.heading_sigma_rad,
        });
    }
    gps
}

/// The rig-frame ray of a pixel and its angular σ, as the localizer computes it.
fn pixel_ray(rig: &Rig, camera: usize, u: f64, v: f64, pixel_sigma_px: f64) -> Option<(Ray, f64)> {
    rig.try_ray_with_sigma(camera, &Pixel::new(u, v), pixel_sigma_px)
}

fn nobs_summary(landmarks: &[MappedLandmark]) -> Option<NobsSummary> {
    let mut n: Vec<usize> = landmarks.iter().map(|l| l.n_obs).collect();
    n.sort_unstable();
    let (&min, &max) = (n.first()?, n.last()?);
    let mut histogram = [0; 5];
    for &k in &n {
        let bin = match k {
            0..5 => 0,
            5..10 => 1,
            10..20 => 2,
            20..50 => 3,
            _ => 4,
        };
        histogram[bin] += 1;
    }
    Some(NobsSummary {
        min,
        median: n[n.len() / 2],
        p90: n[(n.len() * 9 / 10).min(n.len() - 1)],
        max,
        histogram,
    })
}

fn by_class(landmarks: &[MappedLandmark], classes: &[String]) -> Vec<(String, usize)> {
    let mut counts: Vec<(String, usize)> = Vec::new();
    for l in landmarks {
        let name = l
            .class
            .and_then(|c| classes.get(c as usize).cloned())
            .unwrap_or_default();
        match counts.iter_mut().find(|(n, _)| *n == name) {
            Some((_, k)) => *k += 1,
            None => counts.push((name, 1)),
        }
    }
    counts
}

/// Pearson correlation of `1/λ_max(Σ)` (the paper's ‖Σ‖⁻¹) with `n_obs`.
fn information_correlation(landmarks: &[MappedLandmark]) -> Option<f64> {
    let pairs: Vec<(f64, f64)> = landmarks
        .iter()
        .filter_map(|l| {
            let s = l.sigma_m();
            (s > 0.0 && s.is_finite()).then(|| (l.n_obs as f64, 1.0 / (s * s)))
        })
        .collect();
    pearson(&pairs)
}

fn write_summary(
    s: &MapSummary,
    format: OutputFormat,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    match format {
        OutputFormat::Json => {
            let text =
                serde_json::to_string_pretty(s).map_err(|e| CliError::Internal(e.to_string()))?;
            writeln!(out, "{text}")?;
        }
        OutputFormat::Text => {
            writeln!(
                out,
                "landmarks mapped:   {} ({} inconsistent tracks dropped)",
                s.landmarks, s.inconsistent
            )?;
            for (class, n) in &s.landmarks_by_class {
                let name = if class.is_empty() { "(none)" } else { class };
                writeln!(out, "  {name:<16} {n}")?;
            }
            if let Some(n) = &s.n_obs {
                writeln!(
                    out,
                    "observations:       min {} median {} p90 {} max {}  (3-4: {}, 5-9: {}, 10-19: {}, 20-49: {}, 50+: {})",
                    n.min,
                    n.median,
                    n.p90,
                    n.max,
                    n.histogram[0],
                    n.histogram[1],
                    n.histogram[2],
                    n.histogram[3],
                    n.histogram[4]
                )?;
            }
            if let Some(m) = s.median_sigma_m {
                writeln!(out, "median sigma:       {m:.3} m")?;
            }
            if let Some(r) = s.information_nobs_correlation {
                writeln!(out, "corr(1/sigma², n):  {r:.4}")?;
            }
            let o = &s.gps_offset;
            let sigma = o.sigma_s.map_or_else(String::new, |x| format!(" ± {x:.4}"));
            writeln!(
                out,
                "gps offset ({}):    {:.4}{sigma} s = {:.2} m along track at {:.1} m/s",
                o.mode, o.offset_s, o.along_track_m, o.median_speed_m_s
            )?;
            writeln!(
                out,
                "frames used:        {} of {} ({} GNSS epochs with fix and heading, {} rays)",
                s.frames_used, s.frames, s.gps_samples, s.rays
            )?;
            writeln!(out, "written:            {}", s.output)?;
            writeln!(out, "time:               {:.2} s", s.time_s)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_and_min_obs_parse() {
        assert_eq!(parse_offset("auto"), Ok(GpsOffset::Auto));
        assert_eq!(parse_offset("-0.1"), Ok(GpsOffset::Seconds(-0.1)));
        assert!(parse_offset("NaN").is_err() && parse_offset("11").is_err());
        assert_eq!(parse_min_obs("5"), Ok(5));
        assert!(parse_min_obs("2").is_err());
    }
}
