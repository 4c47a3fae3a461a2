//! IMU samples of a drive (`imu.csv`, written by `vgps import mcap` from
//! `sensor_msgs/msg/Imu`) and the attitude prior they give the localizer: the vertical and,
//! with a referenced yaw, the heading ([`vgps_core::localizer::AttitudePrior`]).
//!
//! # Conventions
//! As `sensor_msgs/Imu` (REP-103, REP-145): the orientation is the IMU's attitude in ENU
//! (`enu_from_imu`, quaternion `x, y, z, w`), its covariance in rad² about the fixed axes; a
//! first orientation variance of −1 means "no orientation". The linear acceleration is the
//! specific force (gravity included: +9.81 m/s² along up at rest). The IMU is taken as
//! mounted with the rig's axes (x forward, y left, z up, ROS's body frame and vgps's rig
//! frame alike); its `frame_id` is not read.
//!
//! # The prior at a frame
//! The sample nearest the frame time within [`MAX_IMU_TIME_GAP_S`]; its attitude may have
//! turned by `|ω|·Δt` since, added to both tolerances.
//! - **Vertical**: from the orientation, `up_in_rig = q⁻¹·ẑ`, tolerance 3σ of the larger of
//!   the roll and pitch variances (at least [`MIN_UP_TOLERANCE_RAD`]); without an
//!   orientation, the direction of the specific force when its norm is within
//!   [`ACCELERATION_NORM_TOLERANCE`] of gravity, tolerance [`ACCELERATION_UP_TOLERANCE_RAD`].
//!   A vertical whose tolerance exceeds [`MAX_UP_TOLERANCE_RAD`] (the level assumption of a
//!   vehicle's rig) is not a prior: the sample gives none.
//! - **Heading**: the ENU yaw of the rig's x axis, tolerance 3σ of the yaw variance (at
//!   least [`MIN_HEADING_TOLERANCE_RAD`]), only when that is at most
//!   [`MAX_HEADING_TOLERANCE_RAD`]: an IMU without a magnetometer reports its yaw from an
//!   arbitrary start, and says so with a large (or −1) variance.
//!
//! # Bad rows
//! A non-finite value, a zero quaternion, a quaternion whose norm is off by more than
//! [`super::QUATERNION_NORM_TOLERANCE`], or a negative variance make a row an error naming
//! the file, line and field ([`ImuError`]); the other rows are used.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::path::Path;
use vgps_core::localizer::AttitudePrior;

/// The name of the IMU file of a drive (beside `drive.json`; not in the manifest).
pub const IMU_FILE: &str = "imu.csv";
/// The header of `imu.csv`.
pub const IMU_HEADER: &str = "time_s,qx,qy,qz,qw,var_roll,var_pitch,var_yaw,wx,wy,wz,ax,ay,az";
/// Farthest an IMU sample may be from a frame time to give its prior (seconds).
pub const MAX_IMU_TIME_GAP_S: f64 = 0.1;
/// Smallest tolerance of an IMU vertical (radians, 0.5°).
pub const MIN_UP_TOLERANCE_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;
/// Largest tolerance of an IMU vertical (radians, 5°: the level tolerance the localizer
/// assumes of a vehicle's rig without an IMU).
pub const MAX_UP_TOLERANCE_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Tolerance of a vertical from the accelerometer alone (radians, 5°: ≈ 0.09 g of
/// horizontal acceleration).
pub const ACCELERATION_UP_TOLERANCE_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// The accelerometer gives the vertical only when the specific force's norm is within this
/// fraction of standard gravity.
pub const ACCELERATION_NORM_TOLERANCE: f64 = 0.05;
/// Standard gravity, m/s².
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;
/// Smallest tolerance of an IMU heading (radians, 1°).
pub const MIN_HEADING_TOLERANCE_RAD: f64 = std::f64::consts::PI / 180.0;
/// Largest tolerance of an IMU heading that is used (radians, 30°).
pub const MAX_HEADING_TOLERANCE_RAD: f64 = 30.0 * std::f64::consts::PI / 180.0;

/// A bad IMU sample.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{context}: field `{field}`: {reason}")]
pub struct ImuError {
    /// Where: `FILE:LINE`, or a record of a recording.
    pub context: String,
    /// The field.
    pub field: &'static str,
    /// What is wrong.
    pub reason: String,
}

/// One IMU sample, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSample {
    /// Time, seconds (Unix time in drives).
    pub time_s: f64,
    /// `enu_from_rig` and the roll, pitch, yaw variances (rad²), when the IMU gives an
    /// orientation.
    pub orientation: Option<(UnitQuaternion<f64>, [f64; 3])>,
    /// Angular velocity, rad/s, rig frame.
    pub angular_velocity: Vector3<f64>,
    /// Specific force, m/s², rig frame.
    pub linear_acceleration: Vector3<f64>,
}

impl ImuSample {
    /// Checks the fields of a sample as `sensor_msgs/Imu` gives them (`orientation` as
    /// `x, y, z, w`; `orientation_variance[0] == -1`: no orientation).
    ///
    /// # Errors
    /// [`ImuError`] (with an empty context) naming the first bad field.
    pub fn try_new(
        time_s: f64,
        orientation: [f64; 4],
        orientation_variance: [f64; 3],
        angular_velocity: [f64; 3],
        linear_acceleration: [f64; 3],
    ) -> Result<Self, ImuError> {
        let bad = |field, reason: String| ImuError {
            context: String::new(),
            field,
            reason,
        };
        if !time_s.is_finite() {
            return Err(bad("time_s", format!("{time_s} is not a time")));
        }
        let finite3 = |v: [f64; 3], field| {
            v.iter()
                .all(|x| x.is_finite())
                .then(|| Vector3::from(v))
                .ok_or_else(|| bad(field, format!("{v:?} is not finite")))
        };
        let angular_velocity = finite3(angular_velocity, "angular_velocity")?;
        let linear_acceleration = finite3(linear_acceleration, "linear_acceleration")?;
        let orientation = if orientation_variance[0] == -1.0 {
            None
        } else {
            let [x, y, z, w] = orientation;
            if !orientation.iter().all(|v| v.is_finite()) {
                return Err(bad("orientation", format!("{orientation:?} is not finite")));
            }
            let q = Quaternion::new(w, x, y, z);
            let norm = q.norm();
            if norm < 1e-9 {
                return Err(bad(
                    "orientation",
                    "is the zero quaternion (no rotation); a driver without an orientation sets its first covariance to -1".into(),
                ));
            }
            if (norm - 1.0).abs() > super::QUATERNION_NORM_TOLERANCE {
                return Err(bad(
                    "orientation",
                    format!("quaternion norm {norm} is not 1"),
                ));
            }
            if !orientation_variance
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0)
            {
                return Err(bad(
                    "orientation_covariance",
                    format!("{orientation_variance:?} are not variances"),
                ));
            }
            Some((UnitQuaternion::from_quaternion(q), orientation_variance))
        };
        Ok(Self {
            time_s,
            orientation,
            angular_velocity,
            linear_acceleration,
        })
    }

    /// The attitude prior of this sample `dt_s` seconds away (see the module documentation),
    /// or `None` when it gives no usable vertical.
    pub fn attitude_prior(&self, dt_s: f64) -> Option<AttitudePrior> {
        let turned = self.angular_velocity.norm() * dt_s.abs();
        let (up_in_rig, up_tolerance_rad, heading) = match self.orientation {
            Some((q, [var_roll, var_pitch, var_yaw])) => {
                let up = q.inverse_transform_vector(&Vector3::z());
                let tol = (3.0 * var_roll.max(var_pitch).sqrt()).max(MIN_UP_TOLERANCE_RAD);
                let x = q.transform_vector(&Vector3::x());
                let heading_tol = (3.0 * var_yaw.sqrt()).max(MIN_HEADING_TOLERANCE_RAD);
                let heading = (heading_tol <= MAX_HEADING_TOLERANCE_RAD && x.x.hypot(x.y) > 1e-6)
                    .then(|| (x.y.atan2(x.x), heading_tol + turned));
                (up, tol, heading)
            }
            None => {
                let a = self.linear_acceleration;
                let g = a.norm();
                if ((g - STANDARD_GRAVITY_M_S2) / STANDARD_GRAVITY_M_S2).abs()
                    > ACCELERATION_NORM_TOLERANCE
                {
                    return None;
                }
                (a / g, ACCELERATION_UP_TOLERANCE_RAD, None)
            }
        };
        (up_tolerance_rad <= MAX_UP_TOLERANCE_RAD).then_some(AttitudePrior {
            up_in_rig,
            up_tolerance_rad: up_tolerance_rad + turned,
            heading,
        })
    }
}

/// The attitude prior at `time_s` from `samples` (sorted by time): the nearest sample within
/// [`MAX_IMU_TIME_GAP_S`].
pub fn attitude_at(samples: &[ImuSample], time_s: f64) -> Option<AttitudePrior> {
    let k = samples.partition_point(|s| s.time_s < time_s);
    let nearest = [k.checked_sub(1), Some(k)]
        .into_iter()
        .flatten()
        .filter_map(|i| samples.get(i))
        .min_by(|a, b| {
            (a.time_s - time_s)
                .abs()
                .total_cmp(&(b.time_s - time_s).abs())
        })?;
    let dt = time_s - nearest.time_s;
    (dt.abs() <= MAX_IMU_TIME_GAP_S)
        .then(|| nearest.attitude_prior(dt))
        .flatten()
}

/// Reads `imu.csv` text ([`IMU_HEADER`]): the good samples sorted by time, and an error per
/// bad line (naming `path`, the line and the field).
pub fn imu_from_text(path: &Path, text: &str) -> (Vec<ImuSample>, Vec<ImuError>) {
    let (mut samples, mut errors) = (Vec::new(), Vec::new());
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("time_s") {
            continue;
        }
        let context = format!("{}:{}", path.display(), n + 1);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let names: Vec<&'static str> = IMU_HEADER.split(',').collect();
        if fields.len() != names.len() {
            errors.push(ImuError {
                context,
                field: "(row)",
                reason: format!("{} fields, expected {}", fields.len(), names.len()),
            });
            continue;
        }
        let mut v = [0.0; 14];
        let mut parse_error = None;
        for (k, f) in fields.iter().enumerate() {
            match f.parse::<f64>() {
                Ok(x) => v[k] = x,
                Err(_) => {
                    parse_error = Some(ImuError {
                        context: context.clone(),
                        field: names[k],
                        reason: format!("`{f}` is not a number"),
                    });
                    break;
                }
            }
        }
        if let Some(e) = parse_error {
            errors.push(e);
            continue;
        }
        match ImuSample::try_new(
            v[0],
            [v[1], v[2], v[3], v[4]],
            [v[5], v[6], v[7]],
            [v[8], v[9], v[10]],
            [v[11], v[12], v[13]],
        ) {
            Ok(s) => samples.push(s),
            Err(e) => errors.push(ImuError { context, ..e }),
        }
    }
    samples.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    (samples, errors)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEG: f64 = std::f64::consts::PI / 180.0;

    fn sample(q: UnitQuaternion<f64>, var: [f64; 3]) -> ImuSample {
        let q = q.quaternion();
        ImuSample::try_new(1.0, [q.i, q.j, q.k, q.w], var, [0.0; 3], [0.0, 0.0, 9.81]).unwrap()
    }

    #[test]
    fn orientation_gives_the_vertical_and_the_heading() {
        // Heading 30° from east (ENU yaw), pitched 2° nose up, rolled 1°.
        let q = UnitQuaternion::from_euler_angles(1.0 * DEG, -2.0 * DEG, 30.0 * DEG);
        let s = sample(q, [1e-6, 1e-4, 1e-4]);
        let prior = s.attitude_prior(0.0).unwrap();
        let true_up = q.inverse_transform_vector(&Vector3::z());
        assert!((prior.up_in_rig - true_up).norm() < 1e-12);
        assert!((prior.up_tolerance_rad - 0.03).abs() < 1e-12);
        // A tight variance: the smallest tolerance.
        let tight = sample(q, [1e-8, 1e-8, 1e-4]).attitude_prior(0.0).unwrap();
        assert_eq!(tight.up_tolerance_rad, MIN_UP_TOLERANCE_RAD);
        let (h, tol) = prior.heading.unwrap();
        assert!((h - 30.0 * DEG).abs() < 1e-3, "{h}");
        assert!((tol - 0.03).abs() < 1e-12);
        // A yaw from an arbitrary start (variance -1 is not allowed; a large one): no heading.
        let prior = sample(q, [1e-6, 1e-6, 1.0]).attitude_prior(0.0).unwrap();
        assert!(prior.heading.is_none());
        // A vertical worse than the level assumption: no prior.
        assert!(sample(q, [0.01, 0.01, 1e-4]).attitude_prior(0.0).is_none());
    }

    #[test]
    fn accelerometer_alone_gives_the_vertical() {
        let s =
            ImuSample::try_new(0.0, [0.0; 4], [-1.0, 0.0, 0.0], [0.0; 3], [0.0, 0.5, 9.8]).unwrap();
        let prior = s.attitude_prior(0.0).unwrap();
        assert!((prior.up_in_rig - Vector3::new(0.0, 0.5, 9.8).normalize()).norm() < 1e-12);
        assert!(prior.heading.is_none());
        // Braking hard: the norm is off, no vertical.
        let s =
            ImuSample::try_new(0.0, [0.0; 4], [-1.0, 0.0, 0.0], [0.0; 3], [4.0, 0.0, 9.8]).unwrap();
        assert!(s.attitude_prior(0.0).is_none());
    }

    #[test]
    fn bad_rows_are_errors_naming_line_and_field() {
        let text = format!(
            "{IMU_HEADER}\n\
             0.0,0,0,0,1,1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.1,0,0,0,0,1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.2,NaN,0,0,1,1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.3,0,0,0,1,1e-6,1e-6,1e-4,0,0,0,0,inf,9.81\n\
             0.4,0,0,0,1,-1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.5,0,0,0,1.1,1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.6,0,0,0,1\n\
             0.7,0,0,0,x,1e-6,1e-6,1e-4,0,0,0,0,0,9.81\n\
             0.05,0,0,0,1,-1,0,0,0,0,1,0,0,9.81\n"
        );
        let (samples, errors) = imu_from_text(Path::new("d/imu.csv"), &text);
        assert_eq!(samples.len(), 2);
        let got: Vec<String> = errors.iter().map(ToString::to_string).collect();
        assert_eq!(got.len(), 7, "{got:#?}");
        assert!(got[0].starts_with("d/imu.csv:3: field `orientation`: is the zero quaternion"));
        assert!(got[1].starts_with("d/imu.csv:4: field `orientation`"));
        assert!(got[2].starts_with("d/imu.csv:5: field `linear_acceleration`"));
        assert!(got[3].starts_with("d/imu.csv:6: field `orientation_covariance`"));
        assert!(got[4].contains(":7: field `orientation`: quaternion norm"));
        assert!(got[5].contains(":8: field `(row)`"));
        assert!(got[6].contains(":9: field `qw`: `x` is not a number"));
        // The nearest sample within 0.1 s, its turn rate added to the tolerances.
        let p = attitude_at(&samples, 0.04).unwrap();
        assert!((p.up_tolerance_rad - (ACCELERATION_UP_TOLERANCE_RAD + 0.01)).abs() < 1e-12);
        assert!(attitude_at(&samples, 0.3).is_none());
        assert!(attitude_at(&[], 0.0).is_none());
    }
}
