//! The mapper's input: one frame = time, pose with covariance, rays in the rig frame.

use super::MappingError;
use nalgebra::Matrix6;
use vgps_geometry::geometry::{Pose, Ray, is_finite};
use vgps_geometry::triangulation::UNIT_DIRECTION_TOLERANCE;

/// One observation of a landmark: a ray in the rig frame.
///
/// # Units
/// Metres for the ray origin (the camera centre in the rig frame), radians for `sigma_rad`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigObservation {
    /// Origin = the camera centre in the rig frame; direction = unit bearing to the landmark
    /// in the rig frame.
    pub ray_in_rig: Ray,
    /// Standard deviation of the bearing per axis perpendicular to it (radians, ≥ 0).
    pub sigma_rad: f64,
    /// Class label (index into the caller's class names): observations of different classes
    /// are never associated. `None` matches any class.
    pub class: Option<u32>,
}

/// One frame of the mapper's input.
///
/// # Units
/// Seconds for `time_s`; the pose in metres (world ENU); the covariance in m², m·rad, rad².
#[derive(Clone, Debug, PartialEq)]
pub struct MappingFrame {
    /// Time of the frame (seconds, any epoch; used for the track time-outs).
    pub time_s: f64,
    /// The rig pose `world_from_rig` (world = local ENU).
    pub world_from_rig: Pose,
    /// Its covariance, ordered `[δp (m, world), δθ (rad, world)]`.
    pub pose_covariance: Matrix6<f64>,
    /// The observations of this frame.
    pub observations: Vec<RigObservation>,
}

impl MappingFrame {
    /// Checks the pose, its covariance and every observation.
    ///
    /// # Errors
    /// [`MappingError::InvalidPose`] / [`MappingError::InvalidObservation`], with `frame` =
    /// `index`.
    pub fn validate(&self, index: usize) -> Result<(), MappingError> {
        let pose_ok = self.time_s.is_finite()
            && self
                .world_from_rig
                .rotation
                .matrix()
                .iter()
                .all(|v| v.is_finite())
            && is_finite(&self.world_from_rig.translation.vector)
            && self.pose_covariance.iter().all(|v| v.is_finite())
            && (0..6).all(|k| self.pose_covariance[(k, k)] >= 0.0);
        if !pose_ok {
            return Err(MappingError::InvalidPose { frame: index });
        }
        for (k, o) in self.observations.iter().enumerate() {
            let bad = |reason| MappingError::InvalidObservation {
                frame: index,
                observation: k,
                reason,
            };
            if !is_finite(&o.ray_in_rig.origin) || !is_finite(&o.ray_in_rig.direction) {
                return Err(bad("non-finite ray"));
            }
            if (o.ray_in_rig.direction.norm_squared() - 1.0).abs() > UNIT_DIRECTION_TOLERANCE {
                return Err(bad("direction is not a unit vector"));
            }
            if !(o.sigma_rad >= 0.0 && o.sigma_rad.is_finite()) {
                return Err(bad("sigma_rad is negative or not finite"));
            }
        }
        Ok(())
    }
}
