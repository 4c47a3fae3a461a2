//! Robust absolute pose from rays with known correspondences, for central and non-central
//! rigs: [`AbsolutePoseEstimator`] (an [`Estimator`] for [`ransac`]) and the entry point
//! [`estimate_absolute_pose`].
//!
//! # Minimal solver
//! [`p3p`](fn@crate::solvers::p3p) (Lambda Twist) on the directions of three rays: a central
//! approximation for a non-central rig (camera centres a few centimetres apart). The
//! residual and the local optimisation use the ray origins, so the refined pose is exact
//! for non-central rigs.
//!
//! # Residual
//! With `world_from_rig = (R, p)`, ray `i` with origin `oᵢ` and unit direction `dᵢ` (rig
//! frame) and its world point `Xᵢ`, the predicted direction is along
//! `vᵢ = Rᵀ(Xᵢ − p) − oᵢ`. The squared residual is
//!
//! ```text
//! rᵢ² = sin²θᵢ / σᵢ² = |dᵢ × vᵢ|² / (σ² |vᵢ|² + σ_m,ᵢ²)     (dᵢ·vᵢ > 0, otherwise ∞),
//! ```
//!
//! `θᵢ` the angle between observed and predicted directions and `σᵢ² = σ² + σ_m,ᵢ²/|vᵢ|²` the
//! effective angular variance of a bearing of σ (per tangent axis) to a landmark surveyed
//! with σ_m per axis at range `|vᵢ|`. No square root, no trigonometric function: a few
//! multiplications and one division per datum. `sin θ` equals `θ` to 1.3·10⁻⁵ relative at
//! the default threshold of 5 × 0.1°, and a point behind the ray (`dᵢ·vᵢ ≤ 0`) is an
//! outlier, so the measure is the angle wherever it matters.
//!
//! # Local optimisation
//! Gauss–Newton on the chordal residual `eᵢ = uᵢ − dᵢ` (`uᵢ = vᵢ/|vᵢ|`, rotated into the
//! world frame), each inlier weighted by `1/σᵢ²`, with the update
//! `(exp(δθ)·R, p + δp)` and the Jacobian `(I − uuᵀ)/|v| · [−I, [Xᵢ − p]ₓ]` (world frame).
//! [`LO_ITERATIONS`] iterations per local optimisation, [`FINAL_ITERATIONS`] on the final
//! model. No covariance here: see [`crate::solvers::refine_pose`](fn@crate::solvers::refine_pose) (used by
//! `vgps_core::fix::compute_fix`) for the final estimate with its covariance.
//!
//! # Example
//! ```
//! use vgps_geometry::robust::{AbsolutePoseOptions, estimate_absolute_pose};
//! use vgps_geometry::synthetic::{self, PnpConfig, PnpProblem};
//!
//! let config = PnpConfig {
//!     n_points: 100,
//!     sigma_rad: 0.1_f64.to_radians(),
//!     outlier_fraction: 0.5,
//!     ..PnpConfig::default()
//! };
//! let problem = PnpProblem::generate(&mut synthetic::rng(4), &config);
//! let options = AbsolutePoseOptions { sigma_rad: config.sigma_rad, ..Default::default() };
//! let result =
//!     estimate_absolute_pose(&problem.rays_in_rig, &problem.points_in_world, &options).unwrap();
//! let (dp, _) = synthetic::pose_error(&result.model, &problem.world_from_rig);
//! assert!(dp < 0.2, "{dp} m");
//! assert!(result.n_inliers >= 48 && result.n_inliers <= 52);
//! ```

use super::{Estimator, RansacError, RansacOptions, RansacResult, ransac};
use crate::geometry::{Pose, Ray, is_finite};
use crate::solvers::p3p;
use nalgebra::{Matrix3, Matrix6, Rotation3, SMatrix, Translation3, Vector3, Vector6};
use std::cell::Cell;

/// Gauss–Newton iterations of one local optimisation.
pub const LO_ITERATIONS: usize = 2;

/// Gauss–Newton iterations on the final model in [`estimate_absolute_pose`].
pub const FINAL_ITERATIONS: usize = 6;

/// Default [`AbsolutePoseOptions::sigma_rad`]: the workspace's one default,
/// [`crate::DEFAULT_BEARING_SIGMA_RAD`] (0.1°).
pub const DEFAULT_SIGMA_RAD: f64 = crate::DEFAULT_BEARING_SIGMA_RAD;

/// A point closer than this to its ray origin (metres) has no direction: infinite residual.
const MIN_RANGE_M: f64 = 1e-6;

/// A pose prior for the estimator: models farther than `radius_m` from `position_in_world`
/// are discarded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionPrior {
    /// Prior position of the rig in the world frame, metres.
    pub position_in_world: Vector3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
}

/// The absolute-pose problem with known correspondences, as an [`Estimator`] whose model
/// is `world_from_rig` and whose residual is in standard deviations (see the
/// [module documentation](self)).
#[derive(Debug)]
pub struct AbsolutePoseEstimator<'a> {
    rays: &'a [Ray],
    points: &'a [Vector3<f64>],
    sigma2: f64,
    survey_variance: Option<Vec<f64>>,
    prior: Option<PositionPrior>,
    rejected_by_prior: Cell<usize>,
    lo_iterations: usize,
}

impl<'a> AbsolutePoseEstimator<'a> {
    /// The problem of `rays_in_rig[i]` seeing `points_in_world[i]` with angular noise
    /// `sigma_rad` per tangent axis.
    ///
    /// # Errors
    /// [`RansacError::InvalidData`] for mismatched lengths or a non-finite ray or point,
    /// [`RansacError::InvalidOption`] for a non-positive or non-finite `sigma_rad`.
    pub fn try_new(
        rays_in_rig: &'a [Ray],
        points_in_world: &'a [Vector3<f64>],
        sigma_rad: f64,
    ) -> Result<Self, RansacError> {
        if rays_in_rig.len() != points_in_world.len() {
            return Err(RansacError::InvalidData {
                index: rays_in_rig.len().min(points_in_world.len()),
                reason: "the numbers of rays and points differ",
            });
        }
        if !(sigma_rad.is_finite() && sigma_rad > 0.0) {
            return Err(RansacError::InvalidOption {
                name: "sigma_rad",
                value: sigma_rad,
            });
        }
        for (index, (ray, point)) in rays_in_rig.iter().zip(points_in_world).enumerate() {
            if !(is_finite(&ray.origin) && is_finite(&ray.direction) && is_finite(point)) {
                return Err(RansacError::InvalidData {
                    index,
                    reason: "a ray or point is not finite",
                });
            }
        }
        Ok(Self {
            rays: rays_in_rig,
            points: points_in_world,
            sigma2: sigma_rad * sigma_rad,
            survey_variance: None,
            prior: None,
            rejected_by_prior: Cell::new(0),
            lo_iterations: LO_ITERATIONS,
        })
    }

    /// With landmark survey noise: `landmark_sigma_m[i]` per axis (metres, ≥ 0) for point
    /// `i`, which widens the effective angular σ of its ray by `σ_m / range`.
    ///
    /// # Errors
    /// [`RansacError::InvalidData`] for a length mismatch or a negative or non-finite σ.
    pub fn with_landmark_sigmas(mut self, landmark_sigma_m: &[f64]) -> Result<Self, RansacError> {
        if landmark_sigma_m.len() != self.rays.len() {
            return Err(RansacError::InvalidData {
                index: landmark_sigma_m.len().min(self.rays.len()),
                reason: "the numbers of rays and landmark sigmas differ",
            });
        }
        if let Some(index) = landmark_sigma_m
            .iter()
            .position(|s| !(s.is_finite() && *s >= 0.0))
        {
            return Err(RansacError::InvalidData {
                index,
                reason: "a landmark sigma is negative or not finite",
            });
        }
        self.survey_variance = landmark_sigma_m
            .iter()
            .any(|&s| s > 0.0)
            .then(|| landmark_sigma_m.iter().map(|s| s * s).collect());
        Ok(self)
    }

    /// With a position prior: minimal-solver models outside it are discarded.
    pub fn with_prior(mut self, prior: Option<PositionPrior>) -> Self {
        self.prior = prior;
        self
    }

    /// Number of minimal-solver models discarded by the prior so far.
    pub fn rejected_by_prior(&self) -> usize {
        self.rejected_by_prior.get()
    }

    /// `vᵢ` in the world frame (from the ray origin to the point) and the direction of the
    /// ray in the world frame.
    #[inline(always)]
    fn world_vectors(&self, pose: &Pose, i: usize) -> (Vector3<f64>, Vector3<f64>) {
        let r = pose.rotation.matrix();
        let ray = &self.rays[i];
        let v = self.points[i] - pose.translation.vector - r * ray.origin;
        (v, r * ray.direction)
    }

    /// Variance denominator `σ²|v|² + σ_m²` of datum `i` at squared range `len2`.
    #[inline(always)]
    fn variance_times_range2(&self, i: usize, len2: f64) -> f64 {
        let survey = self.survey_variance.as_ref().map_or(0.0, |s| s[i]);
        self.sigma2 * len2 + survey
    }

    /// Gauss–Newton on the data `indices` from `initial` (see the module documentation);
    /// `None` when a step is not finite or the normal matrix is singular.
    pub fn refine_on(&self, initial: &Pose, indices: &[usize], iterations: usize) -> Option<Pose> {
        let mut pose = *initial;
        for _ in 0..iterations {
            let mut h = Matrix6::<f64>::zeros();
            let mut g = Vector6::<f64>::zeros();
            for &i in indices {
                let (v, d) = self.world_vectors(&pose, i);
                let len2 = v.norm_squared();
                if len2 <= MIN_RANGE_M * MIN_RANGE_M || !len2.is_finite() {
                    continue;
                }
                let len = len2.sqrt();
                let u = v / len;
                let weight = len2 / self.variance_times_range2(i, len2);
                let e = u - d;
                let w = self.points[i] - pose.translation.vector;
                // J = (I − uuᵀ)/|v| · [−I, [w]ₓ]
                let p = (Matrix3::identity() - u * u.transpose()) / len;
                let mut j = SMatrix::<f64, 3, 6>::zeros();
                j.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-p));
                j.fixed_view_mut::<3, 3>(0, 3)
                    .copy_from(&(p * w.cross_matrix()));
                let jt = j.transpose();
                h += jt * j * weight;
                g += jt * e * weight;
            }
            let delta = h.cholesky()?.solve(&(-g));
            if !delta.iter().all(|x| x.is_finite()) {
                return None;
            }
            let dp = delta.fixed_rows::<3>(0).into_owned();
            let dtheta = delta.fixed_rows::<3>(3).into_owned();
            pose = Pose::from_parts(
                Translation3::from(pose.translation.vector + dp),
                Rotation3::from_scaled_axis(dtheta) * pose.rotation,
            );
            if delta.norm_squared() < 1e-24 {
                break;
            }
        }
        Some(pose)
    }
}

impl Estimator for AbsolutePoseEstimator<'_> {
    type Model = Pose;

    fn sample_size(&self) -> usize {
        3
    }

    fn num_data(&self) -> usize {
        self.rays.len()
    }

    fn generate_models(&self, sample: &[usize], models: &mut Vec<Pose>) {
        let bearings = [
            self.rays[sample[0]].direction,
            self.rays[sample[1]].direction,
            self.rays[sample[2]].direction,
        ];
        let points = [
            self.points[sample[0]],
            self.points[sample[1]],
            self.points[sample[2]],
        ];
        for pose in p3p(&bearings, &points) {
            let inside = self.prior.is_none_or(|prior| {
                (pose.translation.vector - prior.position_in_world).norm() <= prior.radius_m
            });
            if inside {
                models.push(pose);
            } else {
                self.rejected_by_prior.set(self.rejected_by_prior.get() + 1);
            }
        }
    }

    #[inline]
    fn residual2(&self, pose: &Pose, i: usize) -> f64 {
        // In the rig frame: one rotation per datum.
        let ray = &self.rays[i];
        let v = pose
            .rotation
            .matrix()
            .tr_mul(&(self.points[i] - pose.translation.vector))
            - ray.origin;
        let d = &ray.direction;
        let along = d.dot(&v);
        let len2 = v.norm_squared();
        if !(along > 0.0 && len2 > MIN_RANGE_M * MIN_RANGE_M) {
            return f64::INFINITY;
        }
        let r2 = d.cross(&v).norm_squared() / self.variance_times_range2(i, len2);
        if r2.is_nan() { f64::INFINITY } else { r2 }
    }

    fn refine(&self, pose: &Pose, inliers: &[usize]) -> Option<Pose> {
        self.refine_on(pose, inliers, self.lo_iterations)
    }
}

/// Options of [`estimate_absolute_pose`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AbsolutePoseOptions {
    /// Standard deviation of the bearing noise per tangent axis (radians, positive).
    /// Default [`DEFAULT_SIGMA_RAD`].
    pub sigma_rad: f64,
    /// The robust estimator's options; its threshold is in σ (default 5).
    pub ransac: RansacOptions,
}

impl Default for AbsolutePoseOptions {
    fn default() -> Self {
        Self {
            sigma_rad: DEFAULT_SIGMA_RAD,
            ransac: RansacOptions::default(),
        }
    }
}

/// Robust pose `world_from_rig` from rays in the rig frame (any origins: central or
/// non-central rig) paired with world points, some pairings wrong.
///
/// Runs [`ransac`] on [`AbsolutePoseEstimator`], then [`FINAL_ITERATIONS`] Gauss–Newton
/// iterations on the inliers, which are then re-evaluated.
///
/// # Units
/// Metres for points and ray origins; radians for `sigma_rad`; the threshold of
/// `options.ransac` is in σ.
///
/// # Errors
/// As [`AbsolutePoseEstimator::try_new`] and [`ransac`].
pub fn estimate_absolute_pose(
    rays_in_rig: &[Ray],
    points_in_world: &[Vector3<f64>],
    options: &AbsolutePoseOptions,
) -> Result<RansacResult<Pose>, RansacError> {
    let estimator =
        AbsolutePoseEstimator::try_new(rays_in_rig, points_in_world, options.sigma_rad)?;
    let mut result = ransac(&estimator, &options.ransac)?;
    let indices: Vec<usize> = (0..result.inliers.len())
        .filter(|&i| result.inliers[i])
        .collect();
    if let Some(pose) = estimator.refine_on(&result.model, &indices, FINAL_ITERATIONS) {
        let t2 = options.ransac.inlier_threshold.powi(2);
        let mut score = 0.0;
        let inliers: Vec<bool> = (0..estimator.num_data())
            .map(|i| {
                let r2 = estimator.residual2(&pose, i);
                score += r2.min(t2);
                r2 <= t2
            })
            .collect();
        if score <= result.score {
            result.n_inliers = inliers.iter().filter(|&&b| b).count();
            result.inliers = inliers;
            result.model = pose;
            result.score = score;
        }
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{PnpConfig, PnpProblem, RigModel, pose_error, rng};

    fn config(rig: RigModel, outliers: f64) -> PnpConfig {
        PnpConfig {
            n_points: 100,
            rig,
            sigma_rad: DEFAULT_SIGMA_RAD,
            outlier_fraction: outliers,
            ..PnpConfig::default()
        }
    }

    #[test]
    fn residual_is_the_normalised_sine() {
        let ray = Ray::try_new(Vector3::new(0.0, 0.0, 0.1), Vector3::x()).unwrap();
        let angle = 0.003_f64;
        // From the origin (0, 0, 0.1) to a point 20 m away at `angle` off the ray.
        let point = Vector3::new(20.0 * angle.cos(), 20.0 * angle.sin(), 0.1);
        let (rays, points) = ([ray], [point]);
        let e = AbsolutePoseEstimator::try_new(&rays, &points, 1e-3).unwrap();
        let r2 = e.residual2(&Pose::identity(), 0);
        assert!((r2 - (angle.sin() / 1e-3).powi(2)).abs() < 1e-9, "{r2}");
        // With 0.02 m survey noise at 20 m: σ_eff² = 1e-6 + 1e-6.
        let e = e.with_landmark_sigmas(&[0.02]).unwrap();
        let r2 = e.residual2(&Pose::identity(), 0);
        assert!((r2 - angle.sin().powi(2) / 2e-6).abs() < 1e-9, "{r2}");
        // A point behind the ray is an outlier.
        let behind = [-point];
        let e = AbsolutePoseEstimator::try_new(&rays, &behind, 1e-3).unwrap();
        assert_eq!(e.residual2(&Pose::identity(), 0), f64::INFINITY);
    }

    #[test]
    fn central_and_rig_problems_with_half_outliers_are_solved() {
        let mut r = rng(21);
        for rig in [RigModel::Central, RigModel::Ladybug] {
            let mut errors = Vec::new();
            for _ in 0..40 {
                let problem = PnpProblem::generate(&mut r, &config(rig.clone(), 0.5));
                let result = estimate_absolute_pose(
                    &problem.rays_in_rig,
                    &problem.points_in_world,
                    &AbsolutePoseOptions::default(),
                )
                .unwrap();
                // Every true outlier far from its truth is rejected; nearly all inliers kept.
                let kept = (0..100)
                    .filter(|&i| result.inliers[i] && problem.inliers[i])
                    .count();
                assert!(kept >= 49, "{rig:?}: {kept} of 50 inliers kept");
                errors.push(pose_error(&result.model, &problem.world_from_rig).0);
            }
            errors.sort_by(f64::total_cmp);
            // 50 bearings of 0.1° at 5–50 m: centimetre-level position.
            assert!(errors[20] < 0.05, "{rig:?}: median {} m", errors[20]);
            assert!(errors[39] < 0.3, "{rig:?}: worst {} m", errors[39]);
        }
    }

    #[test]
    fn lo_reaches_the_least_squares_optimum() {
        // Noise-free, no outliers, non-central: the refined pose is exact.
        let mut r = rng(22);
        let problem = PnpProblem::generate(
            &mut r,
            &PnpConfig {
                n_points: 30,
                rig: RigModel::Ladybug,
                ..PnpConfig::default()
            },
        );
        let result = estimate_absolute_pose(
            &problem.rays_in_rig,
            &problem.points_in_world,
            &AbsolutePoseOptions::default(),
        )
        .unwrap();
        let (dp, dr) = pose_error(&result.model, &problem.world_from_rig);
        assert!(dp < 1e-9 && dr < 1e-11, "{dp} {dr}");
        assert_eq!(result.n_inliers, 30);
    }

    #[test]
    fn invalid_input_is_an_error_and_prior_filters_models() {
        let rays = [Ray::try_new(Vector3::zeros(), Vector3::x()).unwrap(); 3];
        let mut points = [Vector3::new(1.0, 2.0, 3.0); 3];
        assert!(matches!(
            AbsolutePoseEstimator::try_new(&rays, &points[..2], 1e-3),
            Err(RansacError::InvalidData { .. })
        ));
        assert!(matches!(
            AbsolutePoseEstimator::try_new(&rays, &points, -1.0),
            Err(RansacError::InvalidOption { .. })
        ));
        points[2].y = f64::INFINITY;
        assert!(matches!(
            AbsolutePoseEstimator::try_new(&rays, &points, 1e-3),
            Err(RansacError::InvalidData { index: 2, .. })
        ));
        // A prior far from the truth leaves no model.
        let mut r = rng(23);
        let problem = PnpProblem::generate(&mut r, &config(RigModel::Central, 0.0));
        let far = PositionPrior {
            position_in_world: problem.world_from_rig.translation.vector
                + Vector3::new(1e4, 0.0, 0.0),
            radius_m: 1.0,
        };
        let e = AbsolutePoseEstimator::try_new(
            &problem.rays_in_rig,
            &problem.points_in_world,
            DEFAULT_SIGMA_RAD,
        )
        .unwrap()
        .with_prior(Some(far));
        let options = RansacOptions {
            max_iterations: 50,
            ..RansacOptions::default()
        };
        assert_eq!(
            ransac(&e, &options),
            Err(RansacError::NoModel { iterations: 50 })
        );
        assert!(e.rejected_by_prior() >= 50);
    }
}
