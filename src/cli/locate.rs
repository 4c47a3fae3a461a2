//! `vgps locate`: one fix per frame, written as JSON lines.

use super::{CliError, LocateSettings, PriorArg};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::Path;
use vgps_camera::calibration::{Pixel, Rig};
use vgps_core::fix::{Fix, FixOptions, FixStatus, Prior, compute_fix};
use vgps_core::matcher::{
    DbLandmark, Detection, LandmarkDb, MatchError, MatchOptions, MatchStatus, SearchArea,
    match_detections,
};
use vgps_geometry::attitude::HeadingPitchRoll;
use vgps_geometry::geo::{Geodetic, LocalFrame};
use vgps_geometry::geometry::Ray;
use vgps_io::{InputError, Landmark, MeasurementRecord, ObservationRecord};

/// Status of a frame whose observations carry no landmark ids when neither `--prior` nor
/// `--region` says where to search.
pub const STATUS_NEEDS_MATCHER: &str = "needs_matcher";

/// Status of a frame whose matcher search region needs too many cells.
pub const STATUS_REGION_TOO_LARGE: &str = "region_too_large";

/// The matcher searches the rig height within ± this of the prior's (or region's) height,
/// metres.
pub const MATCH_VERTICAL_HALF_RANGE_M: f64 = 1.0;

/// A `--prior` or `--region` whose circle is farther than this from every landmark, metres,
/// is refused (exit 2): no landmark could be seen from it, and such a gap is the signature
/// of coordinates in the wrong unit (radians for degrees) or a swapped latitude/longitude.
pub const MAX_SEARCH_GAP_TO_LANDMARKS_M: f64 = 100_000.0;

/// Status of a frame with landmark ids whose landmarks lie farther apart than
/// [`MAX_FRAME_LANDMARK_SPREAD_M`]: one camera cannot see them all, so some ids are wrong.
pub const STATUS_LANDMARKS_TOO_FAR_APART: &str = "landmarks_too_far_apart";

/// A frame's identified landmarks farther apart than this (metres, 100 km) cannot be seen
/// from one place: the frame gets [`STATUS_LANDMARKS_TOO_FAR_APART`].
pub const MAX_FRAME_LANDMARK_SPREAD_M: f64 = 100_000.0;

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
    /// Per observation row of the frame, in input order: the landmark id used, or `null`
    /// (for a matched frame: the landmark the matcher assigned to the detection).
    pub landmarks: Vec<Option<String>>,
    /// Matched frames (rows without landmark ids): inliers of the best pose hypothesis.
    pub best_score: Option<usize>,
    /// Matched frames: inliers of the best hypothesis distinct from the best (`null` when
    /// there was none, and for frames with landmark ids).
    pub runner_up_score: Option<usize>,
    /// Matched frames with a fix: per observation row, the probability of its link given
    /// the others (`null` where `landmarks` is `null`); `null` for other frames.
    pub link_probability: Option<Vec<Option<f64>>>,
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
            best_score: None,
            runner_up_score: None,
            link_probability: None,
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
    let landmarks = vgps_io::read_landmarks(&settings.landmarks)?;
    let observations = vgps_io::read_observations(&settings.observations)?;
    let rig = match &settings.calibration {
        None => None,
        Some(path) => Some(
            vgps_camera::calibration::formats::load(path, None, None)
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
        region: settings.region.as_ref(),
        // The flag, else the calibration's declaration (`level_within_deg`).
        up_tolerance_rad: settings
            .up_tolerance_rad
            .or(rig.as_ref().and_then(Rig::level_within_rad)),
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
    pub observations: &'a [ObservationRecord],
    /// Their file (for error messages).
    pub observations_path: &'a Path,
    /// The rig calibration that turns pixel observations into rays (origin = camera centre
    /// in the rig frame), if any.
    pub rig: Option<&'a Rig>,
    /// The position prior, if any.
    pub prior: Option<&'a PriorArg>,
    /// The matcher's cold-start region (used when there is no prior), if any.
    pub region: Option<&'a PriorArg>,
    /// The matcher's known-vertical tolerance (the rig's +z is within it of up), radians.
    pub up_tolerance_rad: Option<f64>,
    /// Bearing standard deviation per tangent axis, radians.
    pub sigma_rad: f64,
}

/// Locates every frame of the observations against the landmarks. Frames are reported in increasing frame number; a frame's rows need not be
/// contiguous. Human-readable notes (e.g. about frames that need the matcher) are appended
/// to `notes`.
///
/// A frame with landmark ids is solved in a local ENU frame of its own, anchored at the
/// centroid (in ECEF) of its landmarks, so a file may hold frames anywhere on Earth; a
/// frame without ids is matched in the local frame anchored at the prior (or region).
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
        observations_path: _,
        rig: _,
        prior,
        region,
        up_tolerance_rad,
        sigma_rad,
    } = *input;
    let geodetic = landmark_positions(landmarks, landmarks_path)?;
    for (option, area) in [("--prior", prior), ("--region", region)] {
        if let Some(area) = area {
            check_search_area(option, area, &geodetic, landmarks_path)?;
        }
    }
    let (resolved, rays) = resolve_observations(input, &geodetic)?;
    let search_around = prior.or(region);
    let frame = search_around.map(|p| LocalFrame::new(p.position));

    let mut frames: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (k, o) in observations.iter().enumerate() {
        frames.entry(o.frame).or_default().push(k);
    }
    let mut reports = Vec::with_capacity(frames.len());
    let mut matcher_db: Option<LandmarkDb> = None;
    for (number, indices) in frames {
        let rows: Vec<&ObservationRecord> = indices.iter().map(|&k| &observations[k]).collect();
        let identified: Option<Vec<(Ray, Geodetic, f64)>> =
            indices.iter().map(|&k| resolved[k]).collect();
        let Some(identified) = identified else {
            if let (Some(around), Some(local)) = (search_around, frame.as_ref()) {
                let db = match &matcher_db {
                    Some(db) => db,
                    None => matcher_db.insert(landmark_db(landmarks, &geodetic, local)?),
                };
                let frame_rays: Vec<Ray> = indices.iter().map(|&k| rays[k]).collect();
                let options = MatchOptions {
                    sigma_rad,
                    up_in_rig: up_tolerance_rad.map(|t| (Vector3::z(), t)),
                    ..MatchOptions::default()
                };
                reports.push(matched_report(
                    number,
                    db,
                    &frame_rays,
                    &local.to_enu(&around.position),
                    around.radius_m,
                    &options,
                    local,
                )?);
                continue;
            }
            let unidentified = indices.iter().filter(|&&k| resolved[k].is_none()).count();
            let message = format!(
                "{unidentified} of {} observations have no landmark id; give --prior or \
                 --region to identify them with the landmark matcher",
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
        reports.push(identified_report(
            number,
            &rows,
            &identified,
            prior,
            sigma_rad,
        )?);
    }
    Ok(reports)
}

/// The fix of a frame whose rows all name their landmark, in a local frame at the centroid
/// of those landmarks: a per-frame status when they lie too far apart to be seen from one
/// place, or when the prior is far from all of them.
///
/// # Errors
/// [`CliError::Internal`] when the fix refuses its (validated) input.
fn identified_report(
    number: u64,
    rows: &[&ObservationRecord],
    identified: &[(Ray, Geodetic, f64)],
    prior: Option<&PriorArg>,
    sigma_rad: f64,
) -> Result<FrameReport, CliError> {
    let n = rows.len();
    let ecef: Vec<Vector3<f64>> = identified.iter().map(|(_, g, _)| g.to_ecef()).collect();
    let spread = ecef
        .iter()
        .enumerate()
        .flat_map(|(k, a)| ecef[k + 1..].iter().map(move |b| (a - b).norm()))
        .fold(0.0, f64::max);
    if spread > MAX_FRAME_LANDMARK_SPREAD_M {
        return Ok(FrameReport::without_fix(
            number,
            STATUS_LANDMARKS_TOO_FAR_APART,
            format!(
                "the landmarks named by this frame's rows lie up to {:.0} km apart (at most \
                 {:.0} km): no camera sees them all from one place; check the landmark ids",
                spread / 1000.0,
                MAX_FRAME_LANDMARK_SPREAD_M / 1000.0
            ),
            n,
        ));
    }
    let Some(local) = centroid(identified.iter().map(|(_, g, _)| g)).map(LocalFrame::new) else {
        // Only for no landmark at all (a frame has rows) or landmarks spread round the
        // Earth, which the spread test refuses first.
        return Ok(FrameReport::without_fix(
            number,
            FixStatus::NoSolution.as_str(),
            "the frame's landmarks have no centroid to anchor a local frame at".to_string(),
            n,
        ));
    };
    let points: Vec<Vector3<f64>> = identified.iter().map(|(_, g, _)| local.to_enu(g)).collect();
    let prior = prior.map(|p| Prior {
        position_in_world: local.to_enu(&p.position),
        radius_m: p.radius_m,
    });
    if let Some(p) = &prior {
        let nearest = points
            .iter()
            .map(|q| (q - p.position_in_world).norm())
            .fold(f64::INFINITY, f64::min);
        if nearest > p.radius_m + MAX_FRAME_LANDMARK_SPREAD_M {
            return Ok(FrameReport::without_fix(
                number,
                FixStatus::NoSolution.as_str(),
                format!(
                    "--prior is {:.0} km from the nearest landmark of this frame (RADIUS_M {} \
                     m): the frame was taken elsewhere, or its landmark ids are wrong",
                    nearest / 1000.0,
                    p.radius_m
                ),
                n,
            ));
        }
    }
    let fix_options = FixOptions {
        sigma_rad,
        prior,
        ..FixOptions::default()
    };
    let id_rays: Vec<Ray> = identified.iter().map(|(r, _, _)| *r).collect();
    let sigmas: Vec<f64> = identified.iter().map(|(_, _, s)| *s).collect();
    let fix = compute_fix(&id_rays, &points, &sigmas, &fix_options)
        .map_err(|e| CliError::Internal(format!("frame {number}: invalid fix problem: {e}")))?;
    Ok(report(number, rows, &fix, &local))
}

/// The geodetic position and σ of every landmark, by id.
///
/// # Errors
/// [`CliError::Input`] naming the file, line and column of a position the geodetic
/// conversion rejects.
fn landmark_positions<'a>(
    landmarks: &'a [Landmark],
    landmarks_path: &Path,
) -> Result<HashMap<&'a str, (Geodetic, f64)>, CliError> {
    let mut geodetic: HashMap<&str, (Geodetic, f64)> = HashMap::new();
    for l in landmarks {
        let g = Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m).map_err(|e| {
            InputError::field(
                landmarks_path,
                l.line,
                vgps_io::geodetic_column(&e),
                e.to_string(),
            )
        })?;
        geodetic.insert(&l.id, (g, l.sigma_m.unwrap_or(0.0)));
    }
    Ok(geodetic)
}

/// Refuses a `--prior` or `--region` (named by `option`) farther than
/// [`MAX_SEARCH_GAP_TO_LANDMARKS_M`] beyond its radius from every landmark.
fn check_search_area(
    option: &str,
    area: &PriorArg,
    geodetic: &HashMap<&str, (Geodetic, f64)>,
    landmarks_path: &Path,
) -> Result<(), CliError> {
    let centre = area.position.to_ecef();
    let nearest = geodetic
        .values()
        .map(|(g, _)| (g.to_ecef() - centre).norm())
        .fold(f64::INFINITY, f64::min);
    if nearest.is_finite() && nearest > area.radius_m + MAX_SEARCH_GAP_TO_LANDMARKS_M {
        return Err(CliError::Calibration(format!(
            "{option} LAT,LON {},{}: the nearest landmark of {} is {:.0} km away \
             (more than {:.0} km beyond RADIUS_M {} m); are the coordinates in degrees?",
            area.position.lat_deg,
            area.position.lon_deg,
            landmarks_path.display(),
            nearest / 1000.0,
            MAX_SEARCH_GAP_TO_LANDMARKS_M / 1000.0,
            area.radius_m
        )));
    }
    Ok(())
}

/// One observation resolved: its ray and, when it names one, its landmark's position and σ.
type Resolved = Option<(Ray, Geodetic, f64)>;

/// Per observation, in input order: its landmark (`None`: no landmark id) and its ray.
///
/// # Errors
/// [`CliError::Input`] naming the file, line and field of a zero bearing, a pixel
/// observation without a calibration or outside it, or an unknown landmark id.
fn resolve_observations(
    input: &LocateInput<'_>,
    geodetic: &HashMap<&str, (Geodetic, f64)>,
) -> Result<(Vec<Resolved>, Vec<Ray>), CliError> {
    let observations_path = input.observations_path;
    let mut resolved: Vec<Resolved> = Vec::with_capacity(input.observations.len());
    let mut rays: Vec<Ray> = Vec::with_capacity(input.observations.len());
    for o in input.observations {
        let ray = match (&o.measurement, input.rig) {
            (MeasurementRecord::Bearing(b), _) => {
                Ray::try_new(Vector3::zeros(), *b).ok_or_else(|| {
                    InputError::field(observations_path, o.line, "bx", "zero bearing")
                })?
            }
            (MeasurementRecord::Pixel { .. }, None) => {
                return Err(InputError::field(
                    observations_path,
                    o.line,
                    "camera",
                    "pixel observations need --calibration (the rig's camera calibration)",
                )
                .into());
            }
            (MeasurementRecord::Pixel { camera, u, v }, Some(rig)) => {
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
        rays.push(ray);
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
                    input.landmarks_path.display()
                ),
            )
            .into());
        };
        resolved.push(Some((ray, *g, *sigma_m)));
    }
    Ok((resolved, rays))
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
fn report(number: u64, rows: &[&ObservationRecord], fix: &Fix, local: &LocalFrame) -> FrameReport {
    let n = rows.len();
    let Some(estimate) = fix
        .estimate
        .as_ref()
        .filter(|_| fix.status == FixStatus::Ok)
    else {
        return FrameReport::without_fix(number, fix.status.as_str(), fix.message.clone(), n);
    };
    let landmarks = rows
        .iter()
        .zip(&fix.inliers)
        .map(|(o, &used)| if used { o.landmark.clone() } else { None })
        .collect();
    fix_report(
        number,
        local,
        &estimate.world_from_rig,
        &estimate.covariance,
        estimate.rms_residual_rad,
        estimate.n_inliers,
        landmarks,
    )
}

/// The output record of a pose (in the local frame) with its covariance.
fn fix_report(
    number: u64,
    local: &LocalFrame,
    world_from_rig: &vgps_geometry::geometry::Pose,
    covariance: &nalgebra::Matrix6<f64>,
    rms_residual_rad: f64,
    inliers: usize,
    landmarks: Vec<Option<String>>,
) -> FrameReport {
    let n = landmarks.len();
    let position = world_from_rig.translation.vector;
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
    let enu_from_rig = enu_here_from_enu_origin * world_from_rig.rotation;
    let q = UnitQuaternion::from_rotation_matrix(&enu_from_rig);
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let hpr = HeadingPitchRoll::from_enu_from_rig(&enu_from_rig);
    let c = covariance;
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
        rms_residual_deg: Some(rms_residual_rad.to_degrees()),
        observations: n,
        inliers: Some(inliers),
        landmarks,
        best_score: None,
        runner_up_score: None,
        link_probability: None,
    }
}

/// The matcher's database: every landmark of the file in the local frame, in file order.
fn landmark_db(
    landmarks: &[Landmark],
    geodetic: &HashMap<&str, (Geodetic, f64)>,
    local: &LocalFrame,
) -> Result<LandmarkDb, CliError> {
    let entries = landmarks
        .iter()
        .filter_map(|l| {
            let (g, sigma_m) = geodetic.get(l.id.as_str())?;
            Some(DbLandmark {
                id: l.id.clone(),
                position_in_world: local.to_enu(g),
                class: None,
                sigma_m: *sigma_m,
            })
        })
        .collect();
    LandmarkDb::new(entries).map_err(|e| CliError::Internal(format!("landmark database: {e}")))
}

/// Matches one frame's rays (no landmark ids) against the database, around `centre` (local
/// frame) within `radius_m` horizontally.
fn matched_report(
    number: u64,
    db: &LandmarkDb,
    rays: &[Ray],
    centre: &Vector3<f64>,
    radius_m: f64,
    options: &MatchOptions,
    local: &LocalFrame,
) -> Result<FrameReport, CliError> {
    let n = rays.len();
    let detections: Vec<Detection> = rays.iter().map(|r| Detection::new(*r)).collect();
    let area = SearchArea::around(centre, radius_m, MATCH_VERTICAL_HALF_RANGE_M)
        .ok_or_else(|| CliError::Internal(format!("frame {number}: invalid search area")))?;
    let result = match match_detections(db, &detections, &area, options) {
        Ok(r) => r,
        Err(MatchError::AreaTooLarge(cells)) => {
            return Ok(FrameReport::without_fix(
                number,
                STATUS_REGION_TOO_LARGE,
                format!("the search region needs {cells} cells: give a smaller radius"),
                n,
            ));
        }
        Err(e) => return Err(CliError::Internal(format!("frame {number}: {e}"))),
    };
    let mut report = match (&result.estimate, result.status) {
        (Some(e), MatchStatus::Ok) => {
            let ids = result
                .assignment
                .iter()
                .map(|a| a.and_then(|k| db.get(k)).map(|l| l.id.clone()))
                .collect();
            let mut r = fix_report(
                number,
                local,
                &e.world_from_rig,
                &e.covariance,
                e.rms_residual_rad,
                result.assignment.iter().flatten().count(),
                ids,
            );
            r.link_probability = Some(result.link_probability.clone());
            if r.status != MatchStatus::Ok.as_str() {
                r.status = MatchStatus::NoMatch.as_str().to_string();
            }
            r
        }
        _ => FrameReport::without_fix(number, result.status.as_str(), result.message.clone(), n),
    };
    report.best_score = Some(result.best_score);
    report.runner_up_score = result.runner_up_score;
    Ok(report)
}
