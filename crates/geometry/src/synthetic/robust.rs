//! The robust-estimation benchmark problems: many bearings with known correspondences, a
//! large share of them wrong, in the two scenes the peer comparison uses.
//!
//! - [`RansacScene::AllAround`]: a Ladybug-like rig ([`super::pnp::ladybug_cameras`]) with
//!   points all around the sphere; every ray, outliers included, starts at the centre of
//!   the camera whose optical axis is nearest its observed direction (so every ray is
//!   visible to a camera, as a generalized-camera peer needs).
//! - [`RansacScene::FrontHemisphere`]: a central camera whose optical axis is rig +z, points
//!   and outlier directions uniform on the spherical cap within
//!   [`FRONT_HEMISPHERE_MAX_OFF_AXIS_DEG`] of the axis (what a pinhole peer can project).
//!
//! Inliers get isotropic angular noise ([`super::perturb_bearing`]); outliers a uniformly
//! random direction (within the cap for the front hemisphere). The default
//! [`RansacProblemConfig`] is the target problem of `docs/robust.md`: 100 bearings, 50 %
//! outliers, 0.1° noise, ranges [`TARGET_MIN_RANGE_M`]–[`TARGET_MAX_RANGE_M`].
//!
//! # Example
//! ```
//! use vgps_geometry::synthetic::{self, RansacProblemConfig, RansacScene, ransac_problem};
//! let config = RansacProblemConfig::default();
//! let problem = ransac_problem(&mut synthetic::rng(1), &config);
//! assert_eq!(problem.rays_in_rig.len(), 100);
//! assert_eq!(problem.inlier_count(), 50);
//! ```

use super::pnp::{PnpConfig, PnpProblem, RigModel, nearest_camera};
use nalgebra::Vector3;
use rand::{Rng, RngExt};

/// Smallest range of the target problem's points (metres).
pub const TARGET_MIN_RANGE_M: f64 = 5.0;

/// Largest range of the target problem's points (metres).
pub const TARGET_MAX_RANGE_M: f64 = 50.0;

/// The front-hemisphere scene keeps points within this angle of the camera axis (degrees),
/// so that a pinhole camera can project them.
pub const FRONT_HEMISPHERE_MAX_OFF_AXIS_DEG: f64 = 80.0;

/// The scene of a robust-estimation problem.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RansacScene {
    /// Ladybug-like non-central rig, points all around the sphere.
    AllAround,
    /// Central camera looking along rig +z, points within
    /// [`FRONT_HEMISPHERE_MAX_OFF_AXIS_DEG`] of its axis.
    FrontHemisphere,
}

/// Parameters of [`ransac_problem`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacProblemConfig {
    /// The scene.
    pub scene: RansacScene,
    /// Number of bearings.
    pub n_points: usize,
    /// Fraction of wrong bearings, in `[0, 1]`.
    pub outlier_fraction: f64,
    /// Angular noise of the inliers per tangent axis (radians).
    pub sigma_rad: f64,
    /// Smallest range (metres).
    pub min_range_m: f64,
    /// Largest range (metres).
    pub max_range_m: f64,
}

impl Default for RansacProblemConfig {
    /// The target problem: all around, 100 bearings, 50 % outliers, 0.1° noise.
    fn default() -> Self {
        Self {
            scene: RansacScene::AllAround,
            n_points: 100,
            outlier_fraction: 0.5,
            sigma_rad: 0.1_f64.to_radians(),
            min_range_m: TARGET_MIN_RANGE_M,
            max_range_m: TARGET_MAX_RANGE_M,
        }
    }
}

/// Draws a problem (see the [module documentation](self)).
///
/// # Panics
/// On an invalid configuration, as [`PnpProblem::generate`].
pub fn ransac_problem<R: Rng + ?Sized>(rng: &mut R, config: &RansacProblemConfig) -> PnpProblem {
    let max_off_axis = FRONT_HEMISPHERE_MAX_OFF_AXIS_DEG.to_radians();
    let (rig, elevation_range_rad) = match config.scene {
        RansacScene::AllAround => (
            RigModel::Ladybug,
            (-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
        ),
        RansacScene::FrontHemisphere => (
            RigModel::Central,
            (
                std::f64::consts::FRAC_PI_2 - max_off_axis,
                std::f64::consts::FRAC_PI_2,
            ),
        ),
    };
    let pnp = PnpConfig {
        n_points: config.n_points,
        min_range_m: config.min_range_m,
        max_range_m: config.max_range_m,
        elevation_range_rad,
        rig: rig.clone(),
        sigma_rad: config.sigma_rad,
        outlier_fraction: config.outlier_fraction,
        ..PnpConfig::default()
    };
    let mut problem = PnpProblem::generate(rng, &pnp);
    let cameras = rig.cameras();
    let min_z = max_off_axis.cos();
    for i in 0..problem.rays_in_rig.len() {
        if problem.inliers[i] {
            continue;
        }
        let ray = &mut problem.rays_in_rig[i];
        match config.scene {
            RansacScene::AllAround => {
                if let Some(c) = nearest_camera(&cameras, &ray.direction) {
                    ray.origin = cameras[c].centre_in_rig;
                    problem.camera_of_point[i] = c;
                }
            }
            RansacScene::FrontHemisphere => {
                // Uniform on the cap z ≥ cos(max off-axis).
                let z = rng.random_range(min_z..=1.0);
                let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
                let h = (1.0 - z * z).max(0.0).sqrt();
                ray.direction = Vector3::new(h * azimuth.cos(), h * azimuth.sin(), z);
            }
        }
    }
    problem
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{pnp::ladybug_cameras, rng};

    #[test]
    fn all_around_rays_start_at_the_nearest_camera() {
        let p = ransac_problem(&mut rng(1), &RansacProblemConfig::default());
        let cams = ladybug_cameras();
        assert_eq!(p.inlier_count(), 50);
        for (ray, &c) in p.rays_in_rig.iter().zip(&p.camera_of_point) {
            assert_eq!(ray.origin, cams[c].centre_in_rig);
            // The nearest camera of the observed direction (exactly for outliers; for
            // inliers of the true bearing from the rig origin, so within the noise and the
            // parallax of the 4 cm offset).
            let best = cams
                .iter()
                .map(|k| k.axis_in_rig.dot(&ray.direction))
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(cams[c].axis_in_rig.dot(&ray.direction) > best - 0.02);
        }
    }

    #[test]
    fn front_hemisphere_rays_are_within_the_cap() {
        let config = RansacProblemConfig {
            scene: RansacScene::FrontHemisphere,
            ..RansacProblemConfig::default()
        };
        let p = ransac_problem(&mut rng(2), &config);
        let min_z = FRONT_HEMISPHERE_MAX_OFF_AXIS_DEG.to_radians().cos();
        assert!(p.rays_in_rig.iter().all(|r| r.origin == Vector3::zeros()));
        assert!(p.rays_in_rig.iter().all(|r| r.direction.z > min_z - 0.01));
        assert_eq!(p.inlier_count(), 50);
    }
}
