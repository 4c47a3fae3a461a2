//! A landmark field with no streets: landmarks scattered uniformly at random over a square
//! at random heights (masts, trees, roof corners of an irregular town), a rig anywhere in it,
//! and frames that see the nearest landmarks within range (issue #25's "random layout").
//!
//! # Example
//! ```
//! use vgps_core::synthetic::scatter::{ScatterConfig, ScatterWorld};
//! use vgps_core::synthetic::matcher::FrameConfig;
//! let mut rng = vgps_geometry::synthetic::rng(1);
//! let world = ScatterWorld::generate(&mut rng, &ScatterConfig::default());
//! assert_eq!(world.landmarks.len(), 2000);
//! let trial = world.prior_trial(&mut rng, &FrameConfig::default());
//! assert_eq!(trial.frame.detections.len(), 20);
//! ```

use super::matcher::{
    FrameConfig, RIG_HEIGHT_M, SyntheticFrame, TRIAL_PRIOR_HALF_HEIGHT_M, TRIAL_PRIOR_RADIUS_M,
    Trial, landmark_db, rig_pose_at,
};
use crate::matcher::{LandmarkDb, MatchError, SearchArea};
use nalgebra::Vector3;
use rand::{Rng, RngExt};
use vgps_geometry::geometry::{Pose, bearing_in_rig};
use vgps_geometry::synthetic::{perturb_bearing, random_unit_vector};

/// Layout of a scattered field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScatterConfig {
    /// Landmarks in the square.
    pub landmarks: usize,
    /// Edge of the square, metres.
    pub side_m: f64,
    /// Range of landmark heights above the ground, metres.
    pub height_m: (f64, f64),
}

impl Default for ScatterConfig {
    /// 2,000 landmarks over 1 km², 3–30 m high (issue #25).
    fn default() -> Self {
        Self {
            landmarks: 2000,
            side_m: 1000.0,
            height_m: (3.0, 30.0),
        }
    }
}

/// A scattered field of landmarks (true positions = surveyed positions).
#[derive(Clone, Debug)]
pub struct ScatterWorld {
    /// The layout.
    pub config: ScatterConfig,
    /// Landmark positions, ENU metres (ground at z = 0).
    pub landmarks: Vec<Vector3<f64>>,
}

impl ScatterWorld {
    /// Draws the field.
    pub fn generate<R: Rng + ?Sized>(rng: &mut R, config: &ScatterConfig) -> Self {
        let (lo, hi) = config.height_m;
        let landmarks = (0..config.landmarks)
            .map(|_| {
                Vector3::new(
                    rng.random_range(0.0..=config.side_m),
                    rng.random_range(0.0..=config.side_m),
                    rng.random_range(lo..=hi.max(lo)),
                )
            })
            .collect();
        Self {
            config: *config,
            landmarks,
        }
    }

    /// The matcher's database ([`landmark_db`]).
    ///
    /// # Errors
    /// Those of [`LandmarkDb::new`] (not for a generated field).
    pub fn landmark_db(&self) -> Result<LandmarkDb, MatchError> {
        landmark_db(&self.landmarks)
    }

    /// Where the rig may be: the square, rig heights within 1 m of [`RIG_HEIGHT_M`] (the
    /// area of a cold start).
    pub fn rig_region(&self) -> Option<SearchArea> {
        SearchArea::try_new(
            Vector3::new(0.0, 0.0, RIG_HEIGHT_M - 1.0),
            Vector3::new(self.config.side_m, self.config.side_m, RIG_HEIGHT_M + 1.0),
        )
    }

    /// A rig anywhere in the square, [`RIG_HEIGHT_M`] up, random heading, pitch and roll
    /// within ±3°.
    pub fn random_rig_pose<R: Rng + ?Sized>(&self, rng: &mut R) -> Pose {
        let s = self.config.side_m;
        let p = Vector3::new(
            rng.random_range(0.0..=s),
            rng.random_range(0.0..=s),
            RIG_HEIGHT_M,
        );
        rig_pose_at(rng, p)
    }

    /// A frame: the `true_detections` nearest landmarks within `visibility_m` (no
    /// occlusion), plus `false_detections` random directions, all with bearing noise, in
    /// random order.
    pub fn frame<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        pose: &Pose,
        config: &FrameConfig,
    ) -> SyntheticFrame {
        let c = pose.translation.vector;
        let mut near: Vec<(f64, usize)> = self
            .landmarks
            .iter()
            .enumerate()
            .map(|(k, p)| ((p - c).norm(), k))
            .filter(|(d, _)| *d <= config.visibility_m)
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        near.truncate(config.true_detections);
        let mut items: Vec<(Vector3<f64>, Option<usize>)> = Vec::new();
        for &(_, k) in &near {
            if let Some(b) = bearing_in_rig(pose, &self.landmarks[k]) {
                items.push((perturb_bearing(rng, &b, config.sigma_rad), Some(k)));
            }
        }
        for _ in 0..config.false_detections {
            items.push((random_unit_vector(rng), None));
        }
        for i in (1..items.len()).rev() {
            let j = rng.random_range(0..=i);
            items.swap(i, j);
        }
        SyntheticFrame {
            detections: items.iter().map(|i| i.0).collect(),
            classes: vec![None; items.len()],
            truth: items.iter().map(|i| i.1).collect(),
        }
    }

    /// A trial with a prior: a random pose, its frame, and a cylinder of
    /// [`TRIAL_PRIOR_RADIUS_M`] (± [`TRIAL_PRIOR_HALF_HEIGHT_M`]) around a point uniform in
    /// the disc of that radius around the truth.
    pub fn prior_trial<R: Rng + ?Sized>(&self, rng: &mut R, config: &FrameConfig) -> Trial {
        let pose = self.random_rig_pose(rng);
        let frame = self.frame(rng, &pose, config);
        let angle = rng.random_range(-std::f64::consts::PI..=std::f64::consts::PI);
        let radius = TRIAL_PRIOR_RADIUS_M * rng.random_range(0.0..1.0f64).sqrt();
        let centre = pose.translation.vector + Vector3::new(angle.cos(), angle.sin(), 0.0) * radius;
        let area = SearchArea::around(&centre, TRIAL_PRIOR_RADIUS_M, TRIAL_PRIOR_HALF_HEIGHT_M)
            .unwrap_or(SearchArea {
                min_in_world: centre,
                max_in_world: centre,
                horizontal_radius_m: None,
            });
        Trial { pose, frame, area }
    }

    /// A cold-start trial: a random pose, its frame, and the whole square
    /// ([`Self::rig_region`]).
    pub fn cold_trial<R: Rng + ?Sized>(&self, rng: &mut R, config: &FrameConfig) -> Trial {
        let pose = self.random_rig_pose(rng);
        let frame = self.frame(rng, &pose, config);
        let c = pose.translation.vector;
        let area = self.rig_region().unwrap_or(SearchArea {
            min_in_world: c,
            max_in_world: c,
            horizontal_radius_m: None,
        });
        Trial { pose, frame, area }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_see_the_nearest_landmarks_within_range() {
        let mut r = vgps_geometry::synthetic::rng(3);
        let world = ScatterWorld::generate(&mut r, &ScatterConfig::default());
        assert!(world.landmarks.iter().all(|p| (0.0..=1000.0).contains(&p.x)
            && (0.0..=1000.0).contains(&p.y)
            && (3.0..=30.0).contains(&p.z)));
        let config = FrameConfig {
            sigma_rad: 0.0,
            ..FrameConfig::default()
        };
        for _ in 0..20 {
            let trial = world.cold_trial(&mut r, &config);
            let c = trial.pose.translation.vector;
            let seen: Vec<usize> = trial.frame.truth.iter().flatten().copied().collect();
            assert!(seen.len() <= 14);
            assert_eq!(trial.frame.truth.iter().filter(|t| t.is_none()).count(), 6);
            let farthest = seen
                .iter()
                .map(|&k| (world.landmarks[k] - c).norm())
                .fold(0.0, f64::max);
            assert!(farthest <= 80.0);
            // No unseen landmark is nearer than the farthest seen one (when 14 are seen).
            if seen.len() == 14 {
                let nearer = world
                    .landmarks
                    .iter()
                    .enumerate()
                    .filter(|(k, p)| !seen.contains(k) && (*p - c).norm() < farthest)
                    .count();
                assert_eq!(nearer, 0);
            }
            assert!(trial.area.contains(&c));
        }
    }
}
