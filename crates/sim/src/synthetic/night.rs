//! Night street scenes for the image pipeline: street lamps along a road around the rig,
//! expressed in each camera's frame for [`Renderer`](crate::render::Renderer).

use crate::render::LightSource;
use nalgebra::{Point3, Vector3};
use rand::{Rng, RngExt};
use vgps_camera::calibration::RigCamera;

/// A street lamp in the rig frame (x forward, y left, z up; metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreetLamp {
    /// The lamp's centre in the rig frame (metres).
    pub point_in_rig: Vector3<f64>,
    /// Radius of the glowing part (metres).
    pub radius_m: f64,
    /// Relative intensity (1 = typical).
    pub intensity: f64,
}

/// The shape of a random street scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreetConfig {
    /// Number of lamps.
    pub lamps: usize,
    /// Lamps lie at `x ∈ [−half_length, half_length]` metres along the road.
    pub half_length_m: f64,
    /// Lateral offset range `|y|` of the lamps (metres, either side of the road).
    pub lateral_m: (f64, f64),
    /// Height range of the lamps above the rig (metres).
    pub height_m: (f64, f64),
    /// Radius range of the lamps (metres).
    pub radius_m: (f64, f64),
    /// Intensity range of the lamps.
    pub intensity: (f64, f64),
}

impl Default for StreetConfig {
    fn default() -> Self {
        Self {
            lamps: 40,
            half_length_m: 100.0,
            lateral_m: (4.0, 9.0),
            height_m: (2.0, 7.0),
            radius_m: (0.1, 0.25),
            intensity: (0.5, 2.0),
        }
    }
}

/// Random street lamps (uniform in the ranges of `config`), either side of a road along rig +x.
pub fn street_lamps<R: Rng + ?Sized>(rng: &mut R, config: &StreetConfig) -> Vec<StreetLamp> {
    let mut uniform = |(a, b): (f64, f64)| a + rng.random_range(0.0..1.0) * (b - a);
    (0..config.lamps)
        .map(|_| {
            let x = uniform((-config.half_length_m, config.half_length_m));
            let side = if uniform((0.0, 1.0)) < 0.5 { -1.0 } else { 1.0 };
            let y = side * uniform(config.lateral_m);
            let z = uniform(config.height_m);
            StreetLamp {
                point_in_rig: Vector3::new(x, y, z),
                radius_m: uniform(config.radius_m),
                intensity: uniform(config.intensity),
            }
        })
        .collect()
}

/// The lamps as seen from one camera of the rig (points in that camera's frame).
pub fn lights_in_camera(camera: &RigCamera, lamps: &[StreetLamp]) -> Vec<LightSource> {
    let camera_from_rig = camera.rig_from_camera.inverse();
    lamps
        .iter()
        .map(|l| LightSource {
            point_in_camera: (camera_from_rig * Point3::from(l.point_in_rig)).coords,
            radius_m: l.radius_m,
            intensity: l.intensity,
        })
        .collect()
}
