//! Synthetic many-point pose problems (PnP) for central and non-central (Ladybug-like) rigs,
//! with angular noise and outliers.
//!
//! A [`PnpProblem`] is a true pose, `n` world points all around it and one observed ray per
//! point. For a non-central rig each point is seen by the camera whose optical axis is
//! nearest its bearing (from the rig origin), and the ray starts at that camera's centre.
//! Inlier rays are perturbed by isotropic angular noise ([`super::perturb_bearing`]);
//! outlier rays get a uniformly random direction. The inlier mask is returned with the
//! problem.
//!
//! # Example
//! ```
//! use vgps_geometry::synthetic::{self, PnpConfig, PnpProblem, RigModel};
//! let mut rng = synthetic::rng(3);
//! let config = PnpConfig {
//!     n_points: 30,
//!     rig: RigModel::Ladybug,
//!     sigma_rad: 1e-3,
//!     outlier_fraction: 0.2,
//!     ..PnpConfig::default()
//! };
//! let problem = PnpProblem::generate(&mut rng, &config);
//! assert_eq!(problem.rays_in_rig.len(), 30);
//! assert_eq!(problem.inliers.iter().filter(|&&i| !i).count(), 6);
//! // Ray origins are camera centres about 4 cm from the rig origin.
//! assert!(problem.rays_in_rig.iter().all(|r| (r.origin.norm() - 0.04).abs() < 1e-12));
//! ```

use super::{perturb_bearing, random_pose, random_unit_vector};
use crate::geometry::{Pose, Ray, try_unit};
use nalgebra::{Matrix6, Rotation3, Translation3, Vector3, Vector6};
use rand::seq::SliceRandom;
use rand::{Rng, RngExt};

/// Distance of each Ladybug-like camera centre from the rig origin (metres). A Ladybug2 head
/// is about 13 cm across; this is an illustrative figure, not a calibration.
pub const LADYBUG_CAMERA_RADIUS_M: f64 = 0.04;

/// Number of side cameras of a Ladybug-like head (72° apart).
pub const LADYBUG_SIDE_CAMERAS: usize = 5;

/// Where one camera of a synthetic multi-camera rig sits and looks, in the rig frame (x
/// forward, y left, z up); the calibrated camera (model and placement) is
/// `vgps_camera::calibration::RigCamera`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraAxis {
    /// Optical centre (metres, rig frame).
    pub centre_in_rig: Vector3<f64>,
    /// Unit optical axis (rig frame).
    pub axis_in_rig: Vector3<f64>,
}

/// The six cameras of a Ladybug-like head: five side cameras with horizontal optical axes
/// at azimuths 0°, 72°, …, 288° (counter-clockwise from rig +x, seen from above) with their
/// centres [`LADYBUG_CAMERA_RADIUS_M`] out along their axes, and a top camera looking up
/// (+z) with its centre [`LADYBUG_CAMERA_RADIUS_M`] above the rig origin.
pub fn ladybug_cameras() -> [CameraAxis; LADYBUG_SIDE_CAMERAS + 1] {
    std::array::from_fn(|i| {
        let axis_in_rig = if i < LADYBUG_SIDE_CAMERAS {
            let azimuth = i as f64 * std::f64::consts::TAU / LADYBUG_SIDE_CAMERAS as f64;
            Vector3::new(azimuth.cos(), azimuth.sin(), 0.0)
        } else {
            Vector3::z()
        };
        CameraAxis {
            centre_in_rig: axis_in_rig * LADYBUG_CAMERA_RADIUS_M,
            axis_in_rig,
        }
    })
}

/// The centres of the cameras of [`ladybug_cameras`] (metres, rig frame).
pub fn ladybug_camera_centres() -> [Vector3<f64>; LADYBUG_SIDE_CAMERAS + 1] {
    ladybug_cameras().map(|c| c.centre_in_rig)
}

/// Index of the camera whose optical axis is nearest to `bearing_in_rig` (largest cosine);
/// `None` for an empty rig.
pub fn nearest_camera(cameras: &[CameraAxis], bearing_in_rig: &Vector3<f64>) -> Option<usize> {
    cameras
        .iter()
        .enumerate()
        .max_by(|a, b| {
            let ca = a.1.axis_in_rig.dot(bearing_in_rig);
            let cb = b.1.axis_in_rig.dot(bearing_in_rig);
            ca.total_cmp(&cb)
        })
        .map(|(i, _)| i)
}

/// Which rig observes the points.
#[derive(Clone, Debug, PartialEq)]
pub enum RigModel {
    /// A central camera: every ray starts at the rig origin.
    Central,
    /// The six-camera head of [`ladybug_cameras`].
    Ladybug,
    /// Any set of cameras (each point goes to the camera with the nearest axis). An empty
    /// list means a central camera.
    Cameras(Vec<CameraAxis>),
}

impl RigModel {
    /// The cameras of this rig (empty for a central camera).
    pub fn cameras(&self) -> Vec<CameraAxis> {
        match self {
            Self::Central => Vec::new(),
            Self::Ladybug => ladybug_cameras().to_vec(),
            Self::Cameras(c) => c.clone(),
        }
    }
}

/// Parameters of [`PnpProblem::generate`].
#[derive(Clone, Debug, PartialEq)]
pub struct PnpConfig {
    /// Number of points (and rays).
    pub n_points: usize,
    /// Smallest distance of a point from the rig origin (metres).
    pub min_range_m: f64,
    /// Largest distance of a point from the rig origin (metres); ranges are uniform in
    /// `[min_range_m, max_range_m]`.
    pub max_range_m: f64,
    /// Elevation band of the points in the rig frame (radians, from −π/2 to π/2): directions
    /// are uniform on the sphere zone between these elevations (the whole sphere by
    /// default).
    pub elevation_range_rad: (f64, f64),
    /// The true pose is uniform in a cube of this half-width about the world origin, with a
    /// uniformly random attitude (metres).
    pub pose_half_width_m: f64,
    /// The rig.
    pub rig: RigModel,
    /// Angular noise on inlier rays, per tangent axis (radians).
    pub sigma_rad: f64,
    /// Fraction of rays replaced by uniformly random directions, in `[0, 1]`; the number of
    /// outliers is `round(outlier_fraction · n_points)`, at random indices.
    pub outlier_fraction: f64,
}

impl Default for PnpConfig {
    /// 20 points at 5–50 m all around a central camera placed within 100 m of the origin,
    /// no noise, no outliers.
    fn default() -> Self {
        Self {
            n_points: 20,
            min_range_m: 5.0,
            max_range_m: 50.0,
            elevation_range_rad: (-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
            pose_half_width_m: 100.0,
            rig: RigModel::Central,
            sigma_rad: 0.0,
            outlier_fraction: 0.0,
        }
    }
}

/// A synthetic pose problem with many points: the truth, the observations and the mask of
/// inliers.
#[derive(Clone, Debug)]
pub struct PnpProblem {
    /// The true `world_from_rig`.
    pub world_from_rig: Pose,
    /// The world points (metres).
    pub points_in_world: Vec<Vector3<f64>>,
    /// Observed rays in the rig frame (origin = centre of the observing camera, unit
    /// direction with noise; random for outliers).
    pub rays_in_rig: Vec<Ray>,
    /// Noise-free rays towards the points (the same origins).
    pub true_rays_in_rig: Vec<Ray>,
    /// `inliers[i]` is false when ray `i` is an outlier.
    pub inliers: Vec<bool>,
    /// Index of the observing camera in [`RigModel::cameras`] (0 for a central rig).
    pub camera_of_point: Vec<usize>,
}

impl PnpProblem {
    /// Draws a problem.
    ///
    /// # Panics
    /// On an invalid configuration (a generator misuse, not input data): ranges not
    /// `0 < min ≤ max` finite, the minimum range not larger than twice the farthest camera
    /// centre, an elevation band outside `[−π/2, π/2]` or reversed, a negative or non-finite
    /// σ, an outlier fraction outside `[0, 1]`.
    pub fn generate<R: Rng + ?Sized>(rng: &mut R, config: &PnpConfig) -> Self {
        let cameras = config.rig.cameras();
        let max_offset = cameras
            .iter()
            .map(|c| c.centre_in_rig.norm())
            .fold(0.0, f64::max);
        assert!(
            config.min_range_m.is_finite()
                && config.max_range_m.is_finite()
                && config.min_range_m > 2.0 * max_offset
                && config.min_range_m > 0.0
                && config.min_range_m <= config.max_range_m,
            "invalid ranges in {config:?}"
        );
        let (el_lo, el_hi) = config.elevation_range_rad;
        let half_pi = std::f64::consts::FRAC_PI_2;
        assert!(
            -half_pi <= el_lo && el_lo <= el_hi && el_hi <= half_pi,
            "invalid elevation band"
        );
        assert!(
            config.sigma_rad.is_finite() && config.sigma_rad >= 0.0,
            "invalid sigma"
        );
        assert!(
            (0.0..=1.0).contains(&config.outlier_fraction),
            "invalid outlier fraction"
        );

        let world_from_rig = random_pose(rng, config.pose_half_width_m);
        let n = config.n_points;
        let mut points_in_world = Vec::with_capacity(n);
        let mut true_rays_in_rig = Vec::with_capacity(n);
        let mut camera_of_point = Vec::with_capacity(n);
        let (z_lo, z_hi) = (el_lo.sin(), el_hi.sin());
        for _ in 0..n {
            // Uniform on the zone: z uniform in [sin lo, sin hi], azimuth uniform.
            let z = if z_lo < z_hi {
                rng.random_range(z_lo..=z_hi)
            } else {
                z_lo
            };
            let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
            let horizontal = (1.0 - z * z).max(0.0).sqrt();
            let bearing = Vector3::new(horizontal * azimuth.cos(), horizontal * azimuth.sin(), z);
            let range = rng.random_range(config.min_range_m..=config.max_range_m);
            let point_in_rig = bearing * range;
            let camera = nearest_camera(&cameras, &bearing).unwrap_or(0);
            let origin = cameras
                .get(camera)
                .map_or_else(Vector3::zeros, |c| c.centre_in_rig);
            let direction =
                try_unit(&(point_in_rig - origin)).expect("range exceeds twice the camera offset");
            points_in_world.push(world_from_rig * nalgebra::Point3::from(point_in_rig));
            true_rays_in_rig.push(Ray { origin, direction });
            camera_of_point.push(camera);
        }
        let points_in_world = points_in_world.into_iter().map(|p| p.coords).collect();

        // Exactly round(f·n) outliers at distinct random indices.
        let n_outliers = (config.outlier_fraction * n as f64).round() as usize;
        let mut order: Vec<usize> = (0..n).collect();
        let mut inliers = vec![true; n];
        for &i in order.partial_shuffle(rng, n_outliers.min(n)).0.iter() {
            inliers[i] = false;
        }
        let rays_in_rig = true_rays_in_rig
            .iter()
            .zip(&inliers)
            .map(|(ray, &inlier)| Ray {
                origin: ray.origin,
                direction: if inlier {
                    perturb_bearing(rng, &ray.direction, config.sigma_rad)
                } else {
                    random_unit_vector(rng)
                },
            })
            .collect();
        Self {
            world_from_rig,
            points_in_world,
            rays_in_rig,
            true_rays_in_rig,
            inliers,
            camera_of_point,
        }
    }

    /// The observed rays with their origins moved to the rig origin: what a model that
    /// wrongly treats the rig as central would use.
    pub fn central_rays(&self) -> Vec<Ray> {
        self.rays_in_rig
            .iter()
            .map(|r| Ray {
                origin: Vector3::zeros(),
                direction: r.direction,
            })
            .collect()
    }

    /// Number of inlier rays.
    pub fn inlier_count(&self) -> usize {
        self.inliers.iter().filter(|&&i| i).count()
    }
}

/// `pose` moved by exactly `position_m` metres in a uniformly random direction and rotated
/// by exactly `angle_rad` radians about a uniformly random world axis (left-multiplied).
pub fn perturb_pose<R: Rng + ?Sized>(
    rng: &mut R,
    pose: &Pose,
    position_m: f64,
    angle_rad: f64,
) -> Pose {
    let dp = random_unit_vector(rng) * position_m;
    let axis = random_unit_vector(rng);
    Pose::from_parts(
        Translation3::from(pose.translation.vector + dp),
        Rotation3::from_scaled_axis(axis * angle_rad) * pose.rotation,
    )
}

/// The error of `estimate` against `truth` in the project's covariance convention:
/// `[δp, δθ]` (world frame) with `estimate = (exp(δθ)·R_truth, p_truth + δp)`.
pub fn pose_error_vector(estimate: &Pose, truth: &Pose) -> Vector6<f64> {
    let dp = estimate.translation.vector - truth.translation.vector;
    let dtheta = rotation_log(&(estimate.rotation * truth.rotation.inverse()));
    Vector6::new(dp.x, dp.y, dp.z, dtheta.x, dtheta.y, dtheta.z)
}

/// The rotation vector (axis × angle, radians) of a rotation, accurate to rounding at small
/// angles: the angle is `atan2(|vee(M − Mᵀ)|/2, (tr M − 1)/2)`, not an `acos` of the trace
/// (which loses half the digits, ~1e-8 rad, near zero, as `Rotation3::angle` does).
pub fn rotation_log(rotation: &Rotation3<f64>) -> Vector3<f64> {
    let m = rotation.matrix();
    let sin_axis = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) * 0.5;
    let sin = sin_axis.norm();
    let cos = 0.5 * (m.trace() - 1.0);
    let angle = sin.atan2(cos);
    if sin == 0.0 && cos > 0.0 {
        return Vector3::zeros();
    }
    if angle < 3.0 {
        // Away from π the skew part gives the axis with full precision, and
        // atan2(sin, cos)/sin is accurate down to the smallest angles.
        return sin_axis * (angle / sin);
    }
    // Near π the skew part vanishes: nalgebra's axis from the symmetric part.
    rotation.scaled_axis()
}

/// Normalised estimation error squared `eᵀ Σ⁻¹ e` of an error vector against its
/// covariance; `None` if the covariance is not positive definite. Its mean over trials is
/// the dimension (6) for a consistent estimator.
pub fn nees(error: &Vector6<f64>, covariance: &Matrix6<f64>) -> Option<f64> {
    let chol = nalgebra::Cholesky::new(*covariance)?;
    let x = chol.solve(error);
    let value = error.dot(&x);
    value.is_finite().then_some(value)
}

/// NEES of the position block (first three components) alone; its mean is 3 for a
/// consistent estimator.
pub fn position_nees(error: &Vector6<f64>, covariance: &Matrix6<f64>) -> Option<f64> {
    let e = error.fixed_rows::<3>(0).into_owned();
    let c = covariance.fixed_view::<3, 3>(0, 0).into_owned();
    let chol = nalgebra::Cholesky::new(c)?;
    let value = e.dot(&chol.solve(&e));
    value.is_finite().then_some(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::rng;

    #[test]
    fn ladybug_cameras_are_spread_and_offset() {
        let cams = ladybug_cameras();
        for (i, a) in cams.iter().enumerate() {
            assert!((a.axis_in_rig.norm() - 1.0).abs() < 1e-15);
            assert!((a.centre_in_rig.norm() - LADYBUG_CAMERA_RADIUS_M).abs() < 1e-15);
            for b in &cams[i + 1..] {
                // Side cameras are 72° apart, the top one 90° from each.
                let angle = crate::geometry::angle_between(&a.axis_in_rig, &b.axis_in_rig);
                assert!(angle > 72f64.to_radians() - 1e-12);
            }
        }
    }

    #[test]
    fn rays_point_at_their_points_and_cameras_are_nearest() {
        let config = PnpConfig {
            n_points: 200,
            rig: RigModel::Ladybug,
            min_range_m: 2.0,
            ..PnpConfig::default()
        };
        let p = PnpProblem::generate(&mut rng(5), &config);
        let cams = ladybug_cameras();
        let mut used = [0usize; 6];
        for ((ray, x), &cam) in p
            .true_rays_in_rig
            .iter()
            .zip(&p.points_in_world)
            .zip(&p.camera_of_point)
        {
            let in_rig = p
                .world_from_rig
                .inverse_transform_point(&(*x).into())
                .coords;
            assert!((ray.origin - cams[cam].centre_in_rig).norm() < 1e-15);
            let expected = (in_rig - ray.origin).normalize();
            assert!((ray.direction - expected).norm() < 1e-12);
            assert_eq!(nearest_camera(&cams, &in_rig.normalize()), Some(cam));
            used[cam] += 1;
        }
        assert!(used.iter().all(|&k| k > 0), "{used:?}");
        assert_eq!(p.rays_in_rig, p.true_rays_in_rig);
    }

    #[test]
    fn outliers_and_noise_follow_the_config() {
        let config = PnpConfig {
            n_points: 1000,
            sigma_rad: 1e-3,
            outlier_fraction: 0.25,
            ..PnpConfig::default()
        };
        let p = PnpProblem::generate(&mut rng(6), &config);
        assert_eq!(p.inlier_count(), 750);
        let mut sum_sq = 0.0;
        let mut far_outliers = 0;
        for ((obs, truth), &inlier) in p
            .rays_in_rig
            .iter()
            .zip(&p.true_rays_in_rig)
            .zip(&p.inliers)
        {
            let angle = crate::geometry::angle_between(&obs.direction, &truth.direction);
            if inlier {
                sum_sq += angle * angle;
            } else if angle > 0.1 {
                far_outliers += 1;
            }
        }
        let ratio = sum_sq / 750.0 / (2.0 * 1e-6);
        assert!((ratio - 1.0).abs() < 0.15, "{ratio}");
        assert!(far_outliers > 240, "{far_outliers}");
    }

    #[test]
    fn elevation_band_and_ranges_are_respected() {
        let config = PnpConfig {
            n_points: 500,
            elevation_range_rad: (0.0, 0.3),
            min_range_m: 10.0,
            max_range_m: 30.0,
            ..PnpConfig::default()
        };
        let p = PnpProblem::generate(&mut rng(8), &config);
        for x in &p.points_in_world {
            let v = p
                .world_from_rig
                .inverse_transform_point(&(*x).into())
                .coords;
            let el = (v.z / v.norm()).asin();
            assert!((-1e-12..=0.3 + 1e-12).contains(&el));
            assert!((10.0 - 1e-9..=30.0 + 1e-9).contains(&v.norm()));
        }
    }

    #[test]
    fn error_vector_inverts_the_perturbation() {
        let mut r = rng(9);
        let truth = random_pose(&mut r, 10.0);
        let e = Vector6::new(0.3, -0.2, 0.1, 0.02, -0.01, 0.03);
        let moved = Pose::from_parts(
            Translation3::from(truth.translation.vector + e.fixed_rows::<3>(0)),
            Rotation3::from_scaled_axis(e.fixed_rows::<3>(3).into_owned()) * truth.rotation,
        );
        assert!((pose_error_vector(&moved, &truth) - e).norm() < 1e-15);
        for angle in [1e-13, 1e-9, 1e-4, 1.0, 2.9, 3.1] {
            let axis = crate::synthetic::random_unit_vector(&mut r);
            let log = rotation_log(&Rotation3::from_scaled_axis(axis * angle));
            assert!(
                (log - axis * angle).norm()
                    < 1e-15 * (1.0 + angle) + 1e-9 * (angle > 3.0) as u8 as f64,
                "{angle}"
            );
        }
        let p = perturb_pose(&mut r, &truth, 1.0, 0.1);
        let (dp, dr) = crate::synthetic::pose_error(&p, &truth);
        assert!((dp - 1.0).abs() < 1e-12 && (dr - 0.1).abs() < 1e-12);
        let cov = Matrix6::identity() * 4.0;
        assert!((nees(&e, &cov).unwrap() - e.norm_squared() / 4.0).abs() < 1e-15);
    }
}
