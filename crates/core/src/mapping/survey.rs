//! Survey mode: GPS position + heading → poses with covariance → landmark inventory.

use super::{
    LandmarkMapper, MappedLandmark, MapperOptions, MappingError, MappingFrame, RigObservation,
};
use nalgebra::{Matrix6, Rotation3, Translation3, Vector3};
use std::path::Path;
use vgps_geometry::geo::LocalFrame;
use vgps_geometry::geometry::Pose;

/// Standard deviation assumed for the pitch and the roll of a rig that survey mode treats as
/// level (radians, ≈ 1.1°): a car on a road with a 2 % grade or camber.
pub const SIGMA_LEVEL_RAD: f64 = 0.02;

/// One satellite-GPS fix with a heading (from an IMU/compass or the GPS velocity).
///
/// # Units
/// Seconds; metres in the local ENU frame of the survey; heading in radians, clockwise from
/// true north, of the rig +x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpsSample {
    /// Time of the fix on the camera's clock before any offset (seconds).
    pub time_s: f64,
    /// Position of the rig origin in the survey's ENU frame (metres).
    pub position_enu: Vector3<f64>,
    /// Heading of the rig +x axis, clockwise from true north (radians).
    pub heading_rad: f64,
    /// Horizontal standard deviation per axis (metres).
    pub sigma_horizontal_m: f64,
    /// Vertical standard deviation (metres).
    pub sigma_vertical_m: f64,
    /// Standard deviation of the heading (radians).
    pub sigma_heading_rad: f64,
}

/// The observations of one camera frame (rays in the rig frame).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFrame {
    /// Time of the frame on the camera clock (seconds).
    pub time_s: f64,
    /// The rays of the frame.
    pub observations: Vec<RigObservation>,
}

/// Options of [`survey`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurveyOptions {
    /// The association and surrogate options.
    pub mapper: MapperOptions,
    /// Assumed σ of pitch and roll (radians, [`SIGMA_LEVEL_RAD`]).
    pub sigma_level_rad: f64,
    /// The pose of a camera frame at time `t` is read from the GPS track at
    /// `t + gps_time_offset_s` (seconds; positive when the GPS lags: it reports at `t` where
    /// the rig was at `t − lag`). See [`super::calibrate_gps_offset`].
    pub gps_time_offset_s: f64,
}

impl Default for SurveyOptions {
    fn default() -> Self {
        Self {
            mapper: MapperOptions::default(),
            sigma_level_rad: SIGMA_LEVEL_RAD,
            gps_time_offset_s: 0.0,
        }
    }
}

/// The result of [`survey`].
#[derive(Clone, Debug, PartialEq)]
pub struct Survey {
    /// The landmark inventory (refined, ≥ `min_landmark_rays` rays each).
    pub landmarks: Vec<MappedLandmark>,
    /// Indices of the camera frames outside the GPS track (after the offset): not used.
    pub skipped_frames: Vec<usize>,
    /// For each landmark (by id), the `(camera frame index, observation index)` of its rays.
    pub sources: Vec<(u64, Vec<(usize, usize)>)>,
}

/// Checks a GPS track: at least two samples, strictly increasing finite times, finite
/// values, non-negative σ.
pub(crate) fn validate_gps(gps: &[GpsSample]) -> Result<(), MappingError> {
    if gps.len() < 2 {
        return Err(MappingError::GpsTrack {
            index: gps.len(),
            reason: "at least two samples are needed",
        });
    }
    for (index, g) in gps.iter().enumerate() {
        let finite = g.time_s.is_finite()
            && vgps_geometry::geometry::is_finite(&g.position_enu)
            && g.heading_rad.is_finite();
        if !finite {
            return Err(MappingError::GpsTrack {
                index,
                reason: "non-finite value",
            });
        }
        let sig = [
            g.sigma_horizontal_m,
            g.sigma_vertical_m,
            g.sigma_heading_rad,
        ];
        if !sig.iter().all(|s| *s >= 0.0 && s.is_finite()) {
            return Err(MappingError::GpsTrack {
                index,
                reason: "negative or non-finite sigma",
            });
        }
        if index > 0 && g.time_s <= gps[index - 1].time_s {
            return Err(MappingError::GpsTrack {
                index,
                reason: "times not strictly increasing",
            });
        }
    }
    Ok(())
}

/// The rig pose and its covariance at `time_s`, interpolated linearly in a GPS track
/// (position, heading along the shorter arc, σ), with level pitch and roll.
///
/// The attitude is `Rz(π/2 − heading)` (rig +x along the heading, z up); the covariance is
/// `diag(σ_h², σ_h², σ_v², σ_level², σ_level², σ_heading²)` in the world frame (the heading
/// error is a rotation about up, the level errors about the horizontal axes).
///
/// Returns `None` outside `[first time, last time]` or for a track that is not strictly
/// increasing in time (validate it first with [`survey`]'s checks).
///
/// # Units
/// Seconds, metres, radians.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_core::mapping::{gps_pose_at, GpsSample};
/// let fix = |t: f64, x: f64| GpsSample {
///     time_s: t, position_enu: Vector3::new(x, 0.0, 2.0), heading_rad: std::f64::consts::FRAC_PI_2,
///     sigma_horizontal_m: 1.0, sigma_vertical_m: 2.0, sigma_heading_rad: 0.01,
/// };
/// let (pose, cov) = gps_pose_at(&[fix(0.0, 0.0), fix(1.0, 10.0)], 0.25, 0.02).unwrap();
/// assert!((pose.translation.vector - Vector3::new(2.5, 0.0, 2.0)).norm() < 1e-12);
/// // Heading 90°: the rig looks east.
/// assert!((pose.rotation * Vector3::x() - Vector3::x()).norm() < 1e-12);
/// assert_eq!(cov[(2, 2)], 4.0);
/// ```
pub fn gps_pose_at(
    gps: &[GpsSample],
    time_s: f64,
    sigma_level_rad: f64,
) -> Option<(Pose, Matrix6<f64>)> {
    let first = gps.first()?;
    let last = gps.last()?;
    if !(time_s >= first.time_s && time_s <= last.time_s) {
        return None;
    }
    let i = gps.partition_point(|g| g.time_s <= time_s);
    let (a, b) = if i >= gps.len() {
        (&gps[gps.len() - 2], &gps[gps.len() - 1])
    } else {
        (&gps[i.checked_sub(1)?], &gps[i])
    };
    let dt = b.time_s - a.time_s;
    if dt.is_nan() || dt <= 0.0 {
        return None;
    }
    let f = (time_s - a.time_s) / dt;
    let lerp = |x: f64, y: f64| x + f * (y - x);
    let position = a.position_enu + (b.position_enu - a.position_enu) * f;
    let tau = std::f64::consts::TAU;
    let dh = (b.heading_rad - a.heading_rad + std::f64::consts::PI).rem_euclid(tau)
        - std::f64::consts::PI;
    let heading = a.heading_rad + f * dh;
    let yaw = std::f64::consts::FRAC_PI_2 - heading;
    let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
    let sh = lerp(a.sigma_horizontal_m, b.sigma_horizontal_m);
    let sv = lerp(a.sigma_vertical_m, b.sigma_vertical_m);
    let sy = lerp(a.sigma_heading_rad, b.sigma_heading_rad);
    let sl = sigma_level_rad;
    let cov = Matrix6::from_diagonal(&nalgebra::Vector6::new(
        sh * sh,
        sh * sh,
        sv * sv,
        sl * sl,
        sl * sl,
        sy * sy,
    ));
    Some((
        Pose::from_parts(Translation3::from(position), rotation),
        cov,
    ))
}

/// Survey mode (Ku, Ho & Sarma's inventory): the poses from the GPS track (see
/// [`gps_pose_at`], at each frame's time plus `gps_time_offset_s`), all observations
/// associated by a [`LandmarkMapper`], and the refined landmark inventory.
///
/// Frames outside the GPS track are skipped and listed.
///
/// # Errors
/// [`MappingError::GpsTrack`] for an unusable track, [`MappingError::InvalidOption`],
/// [`MappingError::InvalidObservation`] for a bad ray (naming the camera frame index).
///
/// # Units
/// Seconds, metres (ENU), radians.
///
/// # Example
/// ```
/// use vgps_core::mapping::{survey, SurveyOptions};
/// use vgps_core::synthetic::mapping::{DriveConfig, MappingScenario, streetlights_along};
/// // 200 m of road at 10 m/s, a lamp every 25 m on the right, GPS σ 0.3 m, heading σ 0.5°.
/// let config = DriveConfig::straight(200.0);
/// let lamps = streetlights_along(&config, 25.0, 6.0, 7.0, false);
/// let drive = MappingScenario::generate(&mut vgps_geometry::synthetic::rng(1), &config, &lamps, None);
/// let options = SurveyOptions { sigma_level_rad: config.sigma_level_rad, ..Default::default() };
/// let inventory = survey(&drive.gps, &drive.frames, &options).unwrap();
/// assert_eq!(inventory.landmarks.len(), lamps.len());
/// for l in &inventory.landmarks {
///     let nearest = lamps.iter().map(|p| (p - l.position_enu).norm()).fold(f64::INFINITY, f64::min);
///     assert!(nearest < 4.0 * l.sigma_m() && l.sigma_m() < 0.2, "{nearest} {}", l.sigma_m());
/// }
/// ```
pub fn survey(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
) -> Result<Survey, MappingError> {
    survey_inflated(gps, frames, options, 0.0)
}

/// [`survey`] with `extra_sigma_m²` added to the horizontal position variance of every pose
/// (used to associate before a time offset is known).
pub(crate) fn survey_inflated(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
    extra_sigma_m: f64,
) -> Result<Survey, MappingError> {
    validate_gps(gps)?;
    if !(options.sigma_level_rad >= 0.0 && options.sigma_level_rad.is_finite()) {
        return Err(MappingError::InvalidOption("sigma_level_rad"));
    }
    if !options.gps_time_offset_s.is_finite() {
        return Err(MappingError::InvalidOption("gps_time_offset_s"));
    }
    let mut mapper = LandmarkMapper::new(options.mapper)?;
    let mut skipped = Vec::new();
    let mut input_index = Vec::new();
    for (fi, f) in frames.iter().enumerate() {
        let Some((pose, mut cov)) = gps_pose_at(
            gps,
            f.time_s + options.gps_time_offset_s,
            options.sigma_level_rad,
        ) else {
            skipped.push(fi);
            continue;
        };
        cov[(0, 0)] += extra_sigma_m * extra_sigma_m;
        cov[(1, 1)] += extra_sigma_m * extra_sigma_m;
        let frame = MappingFrame {
            time_s: f.time_s,
            world_from_rig: pose,
            pose_covariance: cov,
            observations: f.observations.clone(),
        };
        mapper.add_frame(&frame).map_err(|e| match e {
            MappingError::InvalidObservation {
                observation,
                reason,
                ..
            } => MappingError::InvalidObservation {
                frame: fi,
                observation,
                reason,
            },
            MappingError::InvalidPose { .. } => MappingError::InvalidPose { frame: fi },
            other => other,
        })?;
        input_index.push(fi);
    }
    let sources = mapper
        .associations()
        .into_iter()
        .map(|(id, s)| {
            (
                id,
                s.into_iter().map(|(f, k)| (input_index[f], k)).collect(),
            )
        })
        .collect();
    Ok(Survey {
        landmarks: mapper.landmarks(),
        skipped_frames: skipped,
        sources,
    })
}

/// The landmarks as the text of a landmarks.csv (`id,lat,lon,alt,sigma_m,class,n_obs`) that
/// [`vgps_io::read_landmarks`] reads: id `m<id>`, WGS84 degrees to 1e-9° (≈ 0.1 mm),
/// height and `sigma_m` (= [`MappedLandmark::sigma_m`], the worst-axis σ) in metres, class
/// = `class_names[class]` (its number when out of range, empty when none), `n_obs` = the
/// number of rays (informational for the reader).
///
/// # Errors
/// [`MappingError::Geo`] when a landmark is outside the supported heights.
pub fn landmarks_csv(
    landmarks: &[MappedLandmark],
    frame: &LocalFrame,
    class_names: &[String],
) -> Result<String, MappingError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let io = |e: csv::Error| MappingError::Io {
        path: "<memory>".into(),
        reason: e.to_string(),
    };
    w.write_record(["id", "lat", "lon", "alt", "sigma_m", "class", "n_obs"])
        .map_err(io)?;
    for l in landmarks {
        let g = l
            .to_geodetic(frame)
            .map_err(|source| MappingError::Geo { id: l.id, source })?;
        let class = match l.class {
            Some(c) => class_names
                .get(c as usize)
                .cloned()
                .unwrap_or_else(|| c.to_string()),
            None => String::new(),
        };
        w.write_record([
            format!("m{}", l.id),
            format!("{:.9}", g.lat_deg),
            format!("{:.9}", g.lon_deg),
            format!("{:.4}", g.alt_m),
            format!("{:.4}", l.sigma_m()),
            class,
            l.n_obs.to_string(),
        ])
        .map_err(io)?;
    }
    let bytes = w.into_inner().map_err(|e| MappingError::Io {
        path: "<memory>".into(),
        reason: e.to_string(),
    })?;
    String::from_utf8(bytes).map_err(|e| MappingError::Io {
        path: "<memory>".into(),
        reason: e.to_string(),
    })
}

/// Writes [`landmarks_csv`] to `path` atomically (a temporary file in the same directory,
/// then a rename).
///
/// # Errors
/// As [`landmarks_csv`], and [`MappingError::Io`] naming the file.
pub fn write_landmarks_csv(
    path: &Path,
    landmarks: &[MappedLandmark],
    frame: &LocalFrame,
    class_names: &[String],
) -> Result<(), MappingError> {
    let text = landmarks_csv(landmarks, frame, class_names)?;
    vgps_camera::calibration::formats::write_atomic(path, text.as_bytes()).map_err(|e| {
        MappingError::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        }
    })
}
