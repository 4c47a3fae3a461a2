//! `vgps locate`: one fix per frame, written as JSON lines.

use super::{CliError, LocateSettings, PriorArg};
use crate::attitude::HeadingPitchRoll;
use crate::calibration::{Pixel, Rig};
use crate::fix::{Fix, FixOptions, FixStatus, Prior, compute_fix};
use crate::geo::{Geodetic, LocalFrame};
use crate::geometry::Ray;
use crate::io::{InputError, Landmark, Measurement, Observation};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::Path;

/// Status of a frame whose observations carry no landmark ids.
pub const STATUS_NEEDS_MATCHER: &str = "needs_matcher";

/// The result for one frame: one JSON object of the output.
///
/// Numeric fields are `null` unless `status` is `ok`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameReport {
    /// The frame number.
    pub frame: u64,
    /// `ok`, or why there is no fix: a [`FixStatus`] string or `needs_matcher`.
    pub status: String,
    /// A human-readable explanation when `status` is not `ok`.
    pub message: Option<String>,
    /// Latitude of the rig, degrees.
    pub lat: Option<f64>,
    /// Longitude of the rig, degrees.
    pub lon: Option<f64>,
    /// Ellipsoidal height of the rig, metres.
    pub alt: Option<f64>,
    /// Attitude quaternion `enu_from_rig` (w, x, y, z; w ≥ 0) in the ENU frame at the rig.
    pub enu_from_rig_wxyz: Option<[f64; 4]>,
    /// Heading of the rig +x axis, degrees clockwise from true north, in [0, 360).
    pub heading_deg: Option<f64>,
    /// Pitch, degrees (rig +x above the horizon is positive).
    pub pitch_deg: Option<f64>,
    /// Roll, degrees (right side down is positive).
    pub roll_deg: Option<f64>,
    /// Position covariance in the ENU frame at the rig, m², 3×3 row-major.
    pub cov_enu_m2: Option<[f64; 9]>,
    /// Attitude covariance (small rotation δθ about the ENU axes at the rig), rad², 3×3
    /// row-major.
    pub cov_att_enu_rad2: Option<[f64; 9]>,
    /// Root mean square angular residual of the inliers, degrees.
    pub rms_residual_deg: Option<f64>,
    /// Number of observation rows of the frame.
    pub observations: usize,
    /// Number of observations used (inliers).
    pub inliers: Option<usize>,
    /// Per observation row of the frame, in input order: the landmark id used, or `null`.
    pub landmarks: Vec<Option<String>>,
}

impl FrameReport {
    fn without_fix(frame: u64, status: &str, message: String, observations: usize) -> Self {
        Self {
            frame,
            status: status.to_string(),
            message: Some(message),
            lat: None,
            lon: None,
            alt: None,
            enu_from_rig_wxyz: None,
            heading_deg: None,
            pitch_deg: None,
            roll_deg: None,
            cov_enu_m2: None,
            cov_att_enu_rad2: None,
            rms_residual_deg: None,
            observations,
            inliers: None,
            landmarks: vec![None; observations],
        }
    }
}

/// Runs `vgps locate`: reads the files, validates them, writes one JSON line per frame.
///
/// # Errors
/// [`CliError::Input`] for invalid files (including unknown landmark ids and pixel
/// observations, which need a calibration); [`CliError::Output`] when writing fails.
pub fn run(
    settings: &LocateSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let landmarks = crate::io::read_landmarks(&settings.landmarks)?;
    let observations = crate::io::read_observations(&settings.observations)?;
    let rig = match &settings.calibration {
        None => None,
        Some(path) => Some(
            crate::calibration::formats::load(path, None, None)
                .map_err(|e| CliError::Calibration(format!("{}: {e}", path.display())))?,
        ),
    };
    let mut notes = Vec::new();
    let input = LocateInput {
        landmarks: &landmarks,
        landmarks_path: &settings.landmarks,
        observations: &observations,
        observations_path: &settings.observations,
        rig: rig.as_ref(),
        prior: settings.prior.as_ref(),
        sigma_rad: settings.sigma_rad,
    };
    let reports = locate(&input, &mut notes)?;
    for note in notes {
        writeln!(err, "vgps: {note}")?;
    }
    for report in &reports {
        serde_json::to_writer(&mut *out, report).map_err(std::io::Error::from)?;
        writeln!(out)?;
    }
    Ok(())
}

/// The inputs of [`locate`], as read from the files.
#[derive(Clone, Copy, Debug)]
pub struct LocateInput<'a> {
    /// The landmarks.
    pub landmarks: &'a [Landmark],
    /// Their file (for error messages).
    pub landmarks_path: &'a Path,
    /// The observations.
    pub observations: &'a [Observation],
    /// Their file (for error messages).
    pub observations_path: &'a Path,
    /// The rig calibration that turns pixel observations into rays (origin = camera centre
    /// in the rig frame), if any.
    pub rig: Option<&'a Rig>,
    /// The position prior, if any.
    pub prior: Option<&'a PriorArg>,
    /// Bearing standard deviation per tangent axis, radians.
    pub sigma_rad: f64,
}

/// Locates every frame of the observations against the landmarks. Frames are reported in increasing frame number; a frame's rows need not be
/// contiguous. Human-readable notes (e.g. about frames that need the matcher) are appended
/// to `notes`.
///
/// The local ENU frame of the computation is anchored at the prior when one is given,
/// otherwise at the centroid (in ECEF) of all landmarks.
///
/// # Errors
/// [`CliError::Input`] naming the file, line and field for a pixel observation without a
/// rig calibration, a camera the calibration does not have or a pixel outside its image, an
/// unknown landmark id, or a landmark whose coordinates the geodetic conversion rejects.
pub fn locate(
    input: &LocateInput<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<FrameReport>, CliError> {
    let LocateInput {
        landmarks,
        landmarks_path,
        observations,
        observations_path,
        rig,
        prior,
        sigma_rad,
    } = *input;
    let mut geodetic: HashMap<&str, (Geodetic, f64)> = HashMap::new();
    for l in landmarks {
        let g = Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m)
            .map_err(|e| InputError::field(landmarks_path, l.line, "lat", e.to_string()))?;
        geodetic.insert(&l.id, (g, l.sigma_m.unwrap_or(0.0)));
    }
    // Per observation: its ray and its landmark (`None`: no landmark id).
    let mut resolved: Vec<Option<(Ray, Geodetic, f64)>> = Vec::with_capacity(observations.len());
    for o in observations {
        let ray = match (&o.measurement, rig) {
            (Measurement::Bearing(b), _) => {
                Ray::try_new(Vector3::zeros(), *b).ok_or_else(|| {
                    InputError::field(observations_path, o.line, "bx", "zero bearing")
                })?
            }
            (Measurement::Pixel { .. }, None) => {
                return Err(InputError::field(
                    observations_path,
                    o.line,
                    "camera",
                    "pixel observations need --calibration (the rig's camera calibration)",
                )
                .into());
            }
            (Measurement::Pixel { camera, u, v }, Some(rig)) => {
                let index: usize = camera.parse().map_err(|_| {
                    InputError::field(
                        observations_path,
                        o.line,
                        "camera",
                        format!("`{camera}` is not a camera index of the calibration"),
                    )
                })?;
                rig.ray(index, &Pixel::new(*u, *v)).map_err(|e| {
                    InputError::field(observations_path, o.line, "camera", e.to_string())
                })?
            }
        };
        let Some(id) = &o.landmark else {
            resolved.push(None);
            continue;
        };
        let Some((g, sigma_m)) = geodetic.get(id.as_str()) else {
            return Err(InputError::field(
                observations_path,
                o.line,
                "landmark",
                format!(
                    "unknown landmark id `{id}` (not in {})",
                    landmarks_path.display()
                ),
            )
            .into());
        };
        resolved.push(Some((ray, *g, *sigma_m)));
    }
    let origin = match prior {
        Some(p) => Some(p.position),
        None => centroid(geodetic.values().map(|(g, _)| g)),
    };
    let frame = origin.map(LocalFrame::new);
    let fix_options = FixOptions {
        sigma_rad,
        prior: match (prior, &frame) {
            (Some(p), Some(f)) => Some(Prior {
                position_in_world: f.to_enu(&p.position),
                radius_m: p.radius_m,
            }),
            _ => None,
        },
        ..FixOptions::default()
    };

    let mut frames: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (k, o) in observations.iter().enumerate() {
        frames.entry(o.frame).or_default().push(k);
    }
    let mut reports = Vec::with_capacity(frames.len());
    for (number, indices) in frames {
        let rows: Vec<&Observation> = indices.iter().map(|&k| &observations[k]).collect();
        let identified: Option<Vec<(Ray, Geodetic, f64)>> =
            indices.iter().map(|&k| resolved[k]).collect();
        let (Some(identified), Some(local)) = (identified, frame.as_ref()) else {
            let unidentified = indices.iter().filter(|&&k| resolved[k].is_none()).count();
            let message = format!(
                "{unidentified} of {} observations have no landmark id; identifying landmarks \
                 without ids arrives with the matcher issue",
                rows.len()
            );
            notes.push(format!("frame {number}: {message}"));
            reports.push(FrameReport::without_fix(
                number,
                STATUS_NEEDS_MATCHER,
                message,
                rows.len(),
            ));
            continue;
        };
        let rays: Vec<Ray> = identified.iter().map(|(r, _, _)| *r).collect();
        let points: Vec<Vector3<f64>> =
            identified.iter().map(|(_, g, _)| local.to_enu(g)).collect();
        let sigmas: Vec<f64> = identified.iter().map(|(_, _, s)| *s).collect();
        let fix = compute_fix(&rays, &points, &sigmas, &fix_options)
            .map_err(|e| CliError::Internal(format!("frame {number}: invalid fix problem: {e}")))?;
        reports.push(report(number, &rows, &fix, local));
    }
    Ok(reports)
}

/// The ECEF centroid of some positions, as a geodetic position (`None` if there are none
/// or the centroid is at the centre of the Earth).
fn centroid<'a>(positions: impl Iterator<Item = &'a Geodetic>) -> Option<Geodetic> {
    let (sum, n) = positions.fold((Vector3::zeros(), 0usize), |(s, n), g| {
        (s + g.to_ecef(), n + 1)
    });
    if n == 0 {
        return None;
    }
    Geodetic::try_from_ecef(&(sum / n as f64)).ok()
}

/// Converts a fix in the local frame into the output record.
fn report(number: u64, rows: &[&Observation], fix: &Fix, local: &LocalFrame) -> FrameReport {
    let n = rows.len();
    let Some(estimate) = fix
        .estimate
        .as_ref()
        .filter(|_| fix.status == FixStatus::Ok)
    else {
        return FrameReport::without_fix(number, fix.status.as_str(), fix.message.clone(), n);
    };
    let position = estimate.world_from_rig.translation.vector;
    let Ok(here) = local.try_to_geodetic(&position) else {
        return FrameReport::without_fix(
            number,
            FixStatus::NoSolution.as_str(),
            "the fix has no geodetic position".to_string(),
            n,
        );
    };
    // Rotate from ENU at the local origin into ENU at the rig.
    let enu_here_from_enu_origin = local.enu_here_from_enu_at(&here).inverse();
    let r: Matrix3<f64> = *enu_here_from_enu_origin.matrix();
    let enu_from_rig = enu_here_from_enu_origin * estimate.world_from_rig.rotation;
    let q = UnitQuaternion::from_rotation_matrix(&enu_from_rig);
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let hpr = HeadingPitchRoll::from_enu_from_rig(&enu_from_rig);
    let c = &estimate.covariance;
    let cov_p = r * c.fixed_view::<3, 3>(0, 0) * r.transpose();
    let cov_a = r * c.fixed_view::<3, 3>(3, 3) * r.transpose();
    let row_major = |m: &Matrix3<f64>| std::array::from_fn(|k| m[(k / 3, k % 3)]);
    FrameReport {
        frame: number,
        status: FixStatus::Ok.as_str().to_string(),
        message: None,
        lat: Some(here.lat_deg),
        lon: Some(here.lon_deg),
        alt: Some(here.alt_m),
        enu_from_rig_wxyz: Some([sign * q.w, sign * q.i, sign * q.j, sign * q.k]),
        heading_deg: Some(hpr.heading_rad.to_degrees().rem_euclid(360.0)),
        pitch_deg: Some(hpr.pitch_rad.to_degrees()),
        roll_deg: Some(hpr.roll_rad.to_degrees()),
        cov_enu_m2: Some(row_major(&cov_p)),
        cov_att_enu_rad2: Some(row_major(&cov_a)),
        rms_residual_deg: Some(estimate.rms_residual_rad.to_degrees()),
        observations: n,
        inliers: Some(estimate.n_inliers),
        landmarks: rows
            .iter()
            .zip(&fix.inliers)
            .map(|(o, &used)| if used { o.landmark.clone() } else { None })
            .collect(),
    }
}
