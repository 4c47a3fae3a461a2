//! Synthetic triangulation problems: one landmark seen by `n` observers, with the truth.

use super::{normal, perturb_bearing, random_unit_vector};
use crate::geometry::{Ray, try_unit};
use crate::triangulation::RayObservation;
use nalgebra::Vector3;
use rand::{Rng, RngExt};

/// A vehicle driving past a landmark on its right, as in Ku, Ho & Sarma's streetlight survey:
/// the road is the world x axis (ENU: driving east), the camera looks right (−y), the landmark
/// stands beside the road.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveBy {
    /// Horizontal distance of the landmark from the road's centre line, to the right (m).
    pub lateral_offset_m: f64,
    /// Height of the landmark above the road (m).
    pub landmark_height_m: f64,
    /// Height of the camera above the road (m).
    pub camera_height_m: f64,
    /// Horizontal half field of view of the right-looking camera (radians): the landmark is
    /// observed while its bearing is within this angle of the camera axis.
    pub half_fov_rad: f64,
}

impl DriveBy {
    /// The paper's field setting: a lamp 6 m right of the road and 7 m high, a camera 2 m
    /// high with an 80° horizontal field of view (half 40°).
    pub fn streetlight() -> Self {
        Self {
            lateral_offset_m: 6.0,
            landmark_height_m: 7.0,
            camera_height_m: 2.0,
            half_fov_rad: 40f64.to_radians(),
        }
    }
}

/// One landmark, its observers and the noise levels of their observations (the truth).
#[derive(Clone, Debug, PartialEq)]
pub struct RayProblem {
    /// True landmark position (metres).
    pub landmark: Vector3<f64>,
    /// True observer positions (metres), none at the landmark.
    pub observers: Vec<Vector3<f64>>,
    /// Standard deviation of the observer position noise, per axis (metres).
    pub sigma_pos_m: f64,
    /// Standard deviation of the angular noise, per tangent axis (radians).
    pub sigma_ang_rad: f64,
}

impl RayProblem {
    /// `n` observers in uniformly random directions all around a landmark (uniform in a cube
    /// of half-width 100 m about the origin), at ranges uniform in `[range_min_m, range_max_m]`.
    ///
    /// # Panics
    /// If `range_min_m` is not positive or exceeds `range_max_m` (generator misuse).
    pub fn around<R: Rng + ?Sized>(
        rng: &mut R,
        n: usize,
        range_min_m: f64,
        range_max_m: f64,
        sigma_pos_m: f64,
        sigma_ang_rad: f64,
    ) -> Self {
        assert!(
            range_min_m > 0.0 && range_min_m <= range_max_m,
            "bad range interval"
        );
        let landmark = Vector3::from_fn(|_, _| rng.random_range(-100.0..=100.0));
        let observers = (0..n)
            .map(|_| {
                let r = rng.random_range(range_min_m..=range_max_m);
                landmark + random_unit_vector(rng) * r
            })
            .collect();
        Self {
            landmark,
            observers,
            sigma_pos_m,
            sigma_ang_rad,
        }
    }

    /// `n` observers evenly spaced along the stretch of road from which a [`DriveBy`] camera
    /// sees the landmark — a vehicle at constant speed sampling at a fixed rate (its speed
    /// sets `n`) — with a random sampling phase; the landmark is at a random position along
    /// the road (`x` uniform in ±100 m).
    pub fn drive_by<R: Rng + ?Sized>(
        rng: &mut R,
        n: usize,
        setting: &DriveBy,
        sigma_pos_m: f64,
        sigma_ang_rad: f64,
    ) -> Self {
        let x0 = rng.random_range(-100.0..=100.0);
        let landmark = Vector3::new(x0, -setting.lateral_offset_m, setting.landmark_height_m);
        let half_span = setting.lateral_offset_m * setting.half_fov_rad.tan();
        let spacing = 2.0 * half_span / n.max(1) as f64;
        let phase: f64 = rng.random();
        let observers = (0..n)
            .map(|k| {
                let x = x0 - half_span + (k as f64 + phase) * spacing;
                Vector3::new(x, 0.0, setting.camera_height_m)
            })
            .collect();
        Self {
            landmark,
            observers,
            sigma_pos_m,
            sigma_ang_rad,
        }
    }

    /// Distances from each observer to the landmark (metres).
    pub fn ranges(&self) -> Vec<f64> {
        self.observers
            .iter()
            .map(|x| (self.landmark - x).norm())
            .collect()
    }

    /// Noise-free observations (true origins and directions) carrying the noise levels.
    ///
    /// # Panics
    /// If an observer coincides with the landmark (generator misuse).
    pub fn exact_observations(&self) -> Vec<RayObservation> {
        self.observers
            .iter()
            .map(|x| self.observation(*x, self.direction_from(x)))
            .collect()
    }

    /// Observations with the noise of the model of [`RayObservation`]: each origin moved by
    /// isotropic Gaussian noise `sigma_pos_m`, each direction perturbed by
    /// [`super::perturb_bearing`] with `sigma_ang_rad`.
    pub fn noisy_observations<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<RayObservation> {
        self.observers
            .iter()
            .map(|x| {
                let d = perturb_bearing(rng, &self.direction_from(x), self.sigma_ang_rad);
                let noise = Vector3::new(normal(rng), normal(rng), normal(rng)) * self.sigma_pos_m;
                self.observation(x + noise, d)
            })
            .collect()
    }

    /// The same problem with everything moved by `offset` (metres).
    pub fn translated(&self, offset: &Vector3<f64>) -> Self {
        Self {
            landmark: self.landmark + offset,
            observers: self.observers.iter().map(|x| x + offset).collect(),
            ..self.clone()
        }
    }

    fn direction_from(&self, x: &Vector3<f64>) -> Vector3<f64> {
        try_unit(&(self.landmark - x)).expect("synthetic observer at the landmark")
    }

    fn observation(&self, origin: Vector3<f64>, direction: Vector3<f64>) -> RayObservation {
        RayObservation {
            ray: Ray { origin, direction },
            sigma_pos_m: self.sigma_pos_m,
            sigma_ang_rad: self.sigma_ang_rad,
        }
    }
}
