//! The shared synthetic-problem generator, used by the tests and the benchmarks alike.
//!
//! Every generator takes a caller-owned random number generator so that a fixed seed gives
//! a fixed problem. Use [`rng`] for the project's reproducible generator (ChaCha8).
//!
//! # Example
//! ```
//! let mut rng = vgps_geometry::synthetic::rng(7);
//! let problem = vgps_geometry::synthetic::P3pProblem::random_omni(&mut rng, 50.0);
//! for (b, p) in problem.bearings_in_rig.iter().zip(&problem.points_in_world) {
//!     let expected = vgps_geometry::geometry::bearing_in_rig(&problem.world_from_rig, p).unwrap();
//!     assert!((b - expected).norm() < 1e-12);
//! }
//! ```

pub mod pnp;
pub mod rays;
pub mod robust;
pub use pnp::{PnpConfig, PnpProblem, RigModel, ladybug_camera_centres, perturb_pose};
pub use robust::{RansacProblemConfig, RansacScene, ransac_problem};

pub use crate::geometry::tangent_basis;

use crate::geometry::{Pose, bearing_in_rig, try_unit};
use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// The reproducible random number generator of the project's tests and benchmarks.
pub type TestRng = rand_chacha::ChaCha8Rng;

/// A reproducible random number generator from a seed.
pub fn rng(seed: u64) -> TestRng {
    TestRng::seed_from_u64(seed)
}

/// A standard normal sample.
pub fn normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    StandardNormal.sample(rng)
}

/// A direction drawn uniformly on the unit sphere.
pub fn random_unit_vector<R: Rng + ?Sized>(rng: &mut R) -> Vector3<f64> {
    loop {
        let v = Vector3::new(normal(rng), normal(rng), normal(rng));
        if let Some(u) = try_unit(&v) {
            return u;
        }
    }
}

/// A rotation drawn uniformly (Haar measure) from SO(3).
pub fn random_rotation<R: Rng + ?Sized>(rng: &mut R) -> Rotation3<f64> {
    loop {
        let q = nalgebra::Quaternion::new(normal(rng), normal(rng), normal(rng), normal(rng));
        if q.norm() > 1e-6 {
            return UnitQuaternion::from_quaternion(q).to_rotation_matrix();
        }
    }
}

/// A pose with a uniformly random attitude and a position uniform in a cube of half-width
/// `half_width` metres about the world origin.
pub fn random_pose<R: Rng + ?Sized>(rng: &mut R, half_width: f64) -> Pose {
    let t = Vector3::new(
        rng.random_range(-half_width..=half_width),
        rng.random_range(-half_width..=half_width),
        rng.random_range(-half_width..=half_width),
    );
    Pose::from_parts(Translation3::from(t), random_rotation(rng))
}

/// Perturbs a unit bearing by isotropic angular noise of standard deviation `sigma_rad` per
/// tangent axis (so the angular error is Rayleigh-distributed with scale `sigma_rad`).
pub fn perturb_bearing<R: Rng + ?Sized>(
    rng: &mut R,
    bearing: &Vector3<f64>,
    sigma_rad: f64,
) -> Vector3<f64> {
    if sigma_rad == 0.0 {
        return *bearing;
    }
    let (t1, t2) = tangent_basis(bearing);
    let a = normal(rng) * sigma_rad;
    let b = normal(rng) * sigma_rad;
    let rot = Rotation3::from_scaled_axis(t1 * b - t2 * a);
    rot * bearing
}

/// A noise-free minimal problem: three world points seen from a pose.
#[derive(Clone, Debug)]
pub struct P3pProblem {
    /// The true pose.
    pub world_from_rig: Pose,
    /// The three landmarks in the world frame (metres).
    pub points_in_world: [Vector3<f64>; 3],
    /// Unit bearings to the landmarks in the rig frame.
    pub bearings_in_rig: [Vector3<f64>; 3],
}

impl P3pProblem {
    /// Three landmarks in random directions all around the rig (the whole sphere, as a
    /// spherical camera sees), at ranges uniform in `[0.1, 1] × scene_size` metres, from a
    /// random pose within `scene_size` of the origin.
    pub fn random_omni<R: Rng + ?Sized>(rng: &mut R, scene_size: f64) -> Self {
        let world_from_rig = random_pose(rng, scene_size);
        let points_in_world = std::array::from_fn(|_| {
            let d = random_unit_vector(rng);
            let r = rng.random_range(0.1 * scene_size..=scene_size);
            world_from_rig.translation.vector + d * r
        });
        Self::from_points(world_from_rig, points_in_world)
    }

    /// The problem of a given pose and three points (noise-free bearings).
    ///
    /// # Panics
    /// If a point coincides with the rig origin (a generator misuse, not input data).
    pub fn from_points(world_from_rig: Pose, points_in_world: [Vector3<f64>; 3]) -> Self {
        let bearings_in_rig = std::array::from_fn(|i| {
            bearing_in_rig(&world_from_rig, &points_in_world[i])
                .expect("synthetic point at the rig origin")
        });
        Self {
            world_from_rig,
            points_in_world,
            bearings_in_rig,
        }
    }

    /// The same problem with angular noise `sigma_rad` on each bearing.
    pub fn with_noise<R: Rng + ?Sized>(&self, rng: &mut R, sigma_rad: f64) -> Self {
        let mut out = self.clone();
        for b in &mut out.bearings_in_rig {
            *b = perturb_bearing(rng, b, sigma_rad);
        }
        out
    }
}

/// Position and rotation error of an estimated pose against the truth:
/// (position error in metres, rotation error angle in radians).
pub fn pose_error(estimate: &Pose, truth: &Pose) -> (f64, f64) {
    let dp = (estimate.translation.vector - truth.translation.vector).norm();
    // `Rotation3::angle` takes an acos of the trace, which loses precision below ~1e-8 rad
    // and is NaN when rounding puts the trace above 3; the log map is exact at any angle.
    let dr = pnp::rotation_log(&(estimate.rotation.inverse() * truth.rotation)).norm();
    (dp, dr)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangent_basis_is_orthonormal_and_right_handed() {
        let mut r = rng(1);
        for _ in 0..1000 {
            let n = random_unit_vector(&mut r);
            let (t1, t2) = tangent_basis(&n);
            assert!((t1.norm() - 1.0).abs() < 1e-12);
            assert!((t2.norm() - 1.0).abs() < 1e-12);
            assert!(t1.dot(&t2).abs() < 1e-12 && t1.dot(&n).abs() < 1e-12);
            assert!((t1.cross(&t2) - n).norm() < 1e-12);
        }
    }

    #[test]
    fn perturbation_has_the_requested_spread() {
        let mut r = rng(2);
        let sigma = 1e-3;
        let n = 20_000;
        let mut sum_sq = 0.0;
        for _ in 0..n {
            let b = random_unit_vector(&mut r);
            let p = perturb_bearing(&mut r, &b, sigma);
            sum_sq += crate::geometry::angle_between(&b, &p).powi(2);
        }
        // E[angle²] = 2σ² for two tangent axes.
        let ratio = sum_sq / n as f64 / (2.0 * sigma * sigma);
        assert!((ratio - 1.0).abs() < 0.03, "ratio {ratio}");
    }

    #[test]
    fn pose_error_is_finite_and_exact_for_tiny_rotations() {
        let mut r = rng(3);
        for _ in 0..10_000 {
            let pose = random_pose(&mut r, 10.0);
            let (dp, dr) = pose_error(&pose, &pose);
            assert_eq!(dp, 0.0);
            assert!(dr.is_finite() && dr < 1e-15, "{dr}");
            let tiny = Rotation3::from_scaled_axis(random_unit_vector(&mut r) * 1e-10);
            let turned = Pose::from_parts(pose.translation, tiny * pose.rotation);
            let (_, dr) = pose_error(&turned, &pose);
            assert!((dr - 1e-10).abs() < 1e-14, "{dr}");
        }
    }

    #[test]
    fn fixed_seed_is_reproducible() {
        let a = P3pProblem::random_omni(&mut rng(9), 10.0);
        let b = P3pProblem::random_omni(&mut rng(9), 10.0);
        assert_eq!(a.points_in_world, b.points_in_world);
    }
}
