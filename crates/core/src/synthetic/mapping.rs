//! Synthetic mapping drives: a vehicle driving a polyline route past landmarks, with
//! noisy rays, GPS-like noisy and lagging positions, and noisy headings.

use crate::mapping::{CameraFrame, GpsSample, MappingFrame, RigObservation, gps_pose_at};
use nalgebra::{Rotation3, Translation3, Vector3};
use rand::{Rng, RngExt};
use vgps_geometry::geometry::{Pose, Ray};
use vgps_geometry::synthetic::{normal, perturb_bearing};

/// The drive and its sensors.
///
/// # Units
/// Metres, seconds, radians (ENU world; heading clockwise from north).
#[derive(Clone, Debug, PartialEq)]
pub struct DriveConfig {
    /// The route, as ground points in ENU (z is ignored); driven from first to last.
    pub waypoints: Vec<Vector3<f64>>,
    /// Constant speed (m/s).
    pub speed_mps: f64,
    /// Camera frame rate = GPS rate (Hz); GPS samples and frames share time stamps.
    pub frame_rate_hz: f64,
    /// Height of the rig origin (= camera centre) above the road (m).
    pub rig_height_m: f64,
    /// Landmarks are observed between these ranges from the camera (m).
    pub min_range_m: f64,
    /// See `min_range_m`.
    pub max_range_m: f64,
    /// Bearing noise per tangent axis (rad).
    pub sigma_bearing_rad: f64,
    /// GPS horizontal noise per axis (m), white.
    pub sigma_gps_horizontal_m: f64,
    /// GPS vertical noise (m), white.
    pub sigma_gps_vertical_m: f64,
    /// Heading noise (rad), white.
    pub sigma_heading_rad: f64,
    /// True pitch and roll are drawn N(0, σ²) per frame (rad); the survey assumes level.
    pub sigma_level_rad: f64,
    /// The GPS sample stamped `t` reports the true position at `t − gps_lag_s` (s).
    pub gps_lag_s: f64,
}

impl DriveConfig {
    /// A straight eastward road of `length_m` at 10 m/s and 10 Hz (one frame per metre), a
    /// rig 2 m high, landmarks seen from 3 to 40 m, 2 mrad bearings, GPS σ 0.3 m horizontal
    /// and 0.5 m vertical, heading σ 0.5° (the paper's IMU), level σ 0.3°, no lag. All noise
    /// is white (independent per frame), as the paper's analysis assumes.
    pub fn straight(length_m: f64) -> Self {
        Self {
            waypoints: vec![Vector3::zeros(), Vector3::new(length_m, 0.0, 0.0)],
            speed_mps: 10.0,
            frame_rate_hz: 10.0,
            rig_height_m: 2.0,
            min_range_m: 3.0,
            max_range_m: 40.0,
            sigma_bearing_rad: 2e-3,
            sigma_gps_horizontal_m: 0.3,
            sigma_gps_vertical_m: 0.5,
            sigma_heading_rad: 0.5f64.to_radians(),
            sigma_level_rad: 0.3f64.to_radians(),
            gps_lag_s: 0.0,
        }
    }

    /// Length of the route (m).
    pub fn length_m(&self) -> f64 {
        self.waypoints
            .windows(2)
            .map(|w| (w[1] - w[0]).xy().norm())
            .sum()
    }

    /// Ground position and heading (clockwise from north, rad) at distance `s` along the
    /// route; extrapolated along the first/last segment outside `[0, length]`.
    pub fn at_distance(&self, s: f64) -> (Vector3<f64>, f64) {
        let segs: Vec<(Vector3<f64>, Vector3<f64>, f64)> = self
            .waypoints
            .windows(2)
            .map(|w| {
                let mut d = w[1] - w[0];
                d.z = 0.0;
                let len = d.norm();
                (Vector3::new(w[0].x, w[0].y, 0.0), d / len.max(1e-12), len)
            })
            .collect();
        let mut rest = s;
        for (i, (start, dir, len)) in segs.iter().enumerate() {
            if rest <= *len || i + 1 == segs.len() {
                let heading = dir.x.atan2(dir.y);
                return (start + dir * rest, heading);
            }
            rest -= len;
        }
        (Vector3::zeros(), 0.0)
    }
}

/// Streetlights every `spacing_m` along the route, `lateral_m` to the right of it (and also
/// to the left when `both_sides`, staggered by half a spacing), `height_m` high.
pub fn streetlights_along(
    config: &DriveConfig,
    spacing_m: f64,
    lateral_m: f64,
    height_m: f64,
    both_sides: bool,
) -> Vec<Vector3<f64>> {
    let len = config.length_m();
    let mut out = Vec::new();
    let mut s = 0.5 * spacing_m;
    while s < len {
        let (p, heading) = config.at_distance(s);
        // Heading h: forward = (sin h, cos h), right = (cos h, −sin h).
        let right = Vector3::new(heading.cos(), -heading.sin(), 0.0);
        out.push(p + right * lateral_m + Vector3::z() * height_m);
        if both_sides {
            let (q, hq) = config.at_distance(s + 0.5 * spacing_m);
            if s + 0.5 * spacing_m < len {
                let left = Vector3::new(-hq.cos(), hq.sin(), 0.0);
                out.push(q + left * lateral_m + Vector3::z() * height_m);
            }
        }
        s += spacing_m;
    }
    out
}

/// A generated drive with its truth.
#[derive(Clone, Debug, PartialEq)]
pub struct MappingScenario {
    /// True landmark positions (ENU, m).
    pub landmarks: Vec<Vector3<f64>>,
    /// True rig poses, one per frame.
    pub true_poses: Vec<Pose>,
    /// The GPS track (noisy, possibly lagging), one sample per frame.
    pub gps: Vec<GpsSample>,
    /// The camera frames (noisy rays in the rig frame).
    pub frames: Vec<CameraFrame>,
    /// For each frame and observation, the index of the landmark it sees.
    pub truth: Vec<Vec<usize>>,
}

impl MappingScenario {
    /// Drives `config` past `landmarks`; landmark `j` is detected in each frame where it is in
    /// range with probability `detection[j]` (1 when `detection` is `None`).
    pub fn generate<R: Rng + ?Sized>(
        rng: &mut R,
        config: &DriveConfig,
        landmarks: &[Vector3<f64>],
        detection: Option<&[f64]>,
    ) -> Self {
        let duration = config.length_m() / config.speed_mps;
        let n = (duration * config.frame_rate_hz).floor() as usize + 1;
        let mut out = Self {
            landmarks: landmarks.to_vec(),
            true_poses: Vec::with_capacity(n),
            gps: Vec::with_capacity(n),
            frames: Vec::with_capacity(n),
            truth: Vec::with_capacity(n),
        };
        for k in 0..n {
            let t = k as f64 / config.frame_rate_hz;
            let (ground, heading) = config.at_distance(config.speed_mps * t);
            let position = ground + Vector3::z() * config.rig_height_m;
            let yaw = std::f64::consts::FRAC_PI_2 - heading;
            let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
                * Rotation3::from_axis_angle(
                    &Vector3::y_axis(),
                    config.sigma_level_rad * normal(rng),
                )
                * Rotation3::from_axis_angle(
                    &Vector3::x_axis(),
                    config.sigma_level_rad * normal(rng),
                );
            let pose = Pose::from_parts(Translation3::from(position), rotation);
            let (lag_ground, _) = config.at_distance(config.speed_mps * (t - config.gps_lag_s));
            let reported = lag_ground
                + Vector3::z() * config.rig_height_m
                + Vector3::new(
                    config.sigma_gps_horizontal_m * normal(rng),
                    config.sigma_gps_horizontal_m * normal(rng),
                    config.sigma_gps_vertical_m * normal(rng),
                );
            out.gps.push(GpsSample {
                time_s: t,
                position_enu: reported,
                heading_rad: heading + config.sigma_heading_rad * normal(rng),
                sigma_horizontal_m: config.sigma_gps_horizontal_m,
                sigma_vertical_m: config.sigma_gps_vertical_m,
                sigma_heading_rad: config.sigma_heading_rad,
            });
            let mut observations = Vec::new();
            let mut truth = Vec::new();
            for (j, p) in landmarks.iter().enumerate() {
                let d = p - position;
                let range = d.norm();
                if range < config.min_range_m || range > config.max_range_m {
                    continue;
                }
                let prob = detection.and_then(|v| v.get(j)).copied().unwrap_or(1.0);
                if prob < 1.0 && rng.random::<f64>() >= prob {
                    continue;
                }
                let in_rig = rotation.inverse() * (d / range);
                let noisy = perturb_bearing(rng, &in_rig, config.sigma_bearing_rad);
                if let Some(ray) = Ray::try_new(Vector3::zeros(), noisy) {
                    observations.push(RigObservation {
                        ray_in_rig: ray,
                        sigma_rad: config.sigma_bearing_rad,
                        class: None,
                    });
                    truth.push(j);
                }
            }
            out.true_poses.push(pose);
            out.frames.push(CameraFrame {
                time_s: t,
                observations,
            });
            out.truth.push(truth);
        }
        out
    }

    /// The frames as mapper input, with the poses and covariances of the GPS track at the
    /// frame times (offset 0) and level σ `sigma_level_rad`.
    pub fn mapping_frames(&self, sigma_level_rad: f64) -> Vec<MappingFrame> {
        self.frames
            .iter()
            .filter_map(|f| {
                let (pose, cov) = gps_pose_at(&self.gps, f.time_s, sigma_level_rad)?;
                Some(MappingFrame {
                    time_s: f.time_s,
                    world_from_rig: pose,
                    pose_covariance: cov,
                    observations: f.observations.clone(),
                })
            })
            .collect()
    }
}
