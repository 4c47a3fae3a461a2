//! `vgps demo`: a small built-in `locate` example on synthetic data.
//!
//! The demo drive (a replayed or simulated run) arrives with the simulation and replay
//! issues; until then the demo says so and runs the `locate` pipeline on a synthetic scene:
//! eight landmarks around a rig in San Francisco, two frames, bearings with 0.05° noise and
//! one observation labelled with the wrong landmark (an outlier the fix must reject).

use super::CliError;
use crate::attitude::HeadingPitchRoll;
use crate::geo::{Geodetic, LocalFrame};
use crate::geometry::{Pose, bearing_in_rig};
use crate::io::{Landmark, Measurement, Observation};
use crate::synthetic::{perturb_bearing, rng};
use nalgebra::{Rotation3, Translation3, Vector3};
use rand::RngExt;
use std::io::Write;
use std::path::Path;

/// Seed of the demo scene.
pub const DEMO_SEED: u64 = 2006;
/// Bearing noise of the demo, degrees per tangent axis.
pub const DEMO_SIGMA_DEG: f64 = 0.05;
/// Number of landmarks of the demo scene.
pub const DEMO_LANDMARKS: usize = 8;

/// The local origin of the demo scene (near the San Francisco Ferry Building).
fn demo_origin() -> Result<Geodetic, CliError> {
    Geodetic::try_new(37.7955, -122.3937, 5.0)
        .map_err(|e| CliError::Internal(format!("demo origin: {e}")))
}

/// `enu_from_rig` of heading, pitch and roll in degrees.
fn attitude_deg(heading: f64, pitch: f64, roll: f64) -> Rotation3<f64> {
    HeadingPitchRoll {
        heading_rad: heading.to_radians(),
        pitch_rad: pitch.to_radians(),
        roll_rad: roll.to_radians(),
    }
    .to_enu_from_rig()
}

/// A synthetic scene for the demo: landmarks, observations and the true poses (ENU at
/// `demo_origin`) of each frame.
pub struct DemoScene {
    /// The local frame of the scene.
    pub local: LocalFrame,
    /// The landmarks, as read from a landmarks file.
    pub landmarks: Vec<Landmark>,
    /// The observations, as read from an observations file.
    pub observations: Vec<Observation>,
    /// The true `world_from_rig` (ENU at the origin) of each frame.
    pub truth: Vec<Pose>,
}

/// Builds the demo scene.
///
/// # Errors
/// [`CliError::Internal`] if a geodetic conversion of the built-in scene fails.
pub fn demo_scene() -> Result<DemoScene, CliError> {
    let local = LocalFrame::new(demo_origin()?);
    let mut r = rng(DEMO_SEED);
    let points: Vec<Vector3<f64>> = (0..DEMO_LANDMARKS)
        .map(|k| {
            let azimuth = (k as f64 + r.random_range(0.0..0.8)) * std::f64::consts::TAU
                / DEMO_LANDMARKS as f64;
            let range = r.random_range(15.0..80.0);
            let up = r.random_range(2.0..12.0);
            Vector3::new(range * azimuth.cos(), range * azimuth.sin(), up)
        })
        .collect();
    let mut landmarks = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let g = local
            .try_to_geodetic(p)
            .map_err(|e| CliError::Internal(format!("demo landmark: {e}")))?;
        landmarks.push(Landmark {
            id: format!("lamp{}", k + 1),
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_m: g.alt_m,
            sigma_m: Some(0.02),
            class: Some("streetlight".to_string()),
            line: k as u64 + 2,
        });
    }
    let truth = vec![
        Pose::from_parts(
            Translation3::new(4.0, -3.0, 1.8),
            attitude_deg(35.0, 2.0, -1.5),
        ),
        Pose::from_parts(
            Translation3::new(8.1, 2.9, 1.7),
            attitude_deg(41.0, 1.0, 0.5),
        ),
    ];
    let sigma = DEMO_SIGMA_DEG.to_radians();
    let mut observations = Vec::new();
    for (frame, pose) in truth.iter().enumerate() {
        for (k, p) in points.iter().enumerate() {
            let Some(b) = bearing_in_rig(pose, p) else {
                continue;
            };
            // Frame 0, landmark 5 is labelled as landmark 2: a wrong correspondence.
            let id = if frame == 0 && k == 4 { 1 } else { k };
            observations.push(Observation {
                frame: frame as u64,
                measurement: Measurement::Bearing(perturb_bearing(&mut r, &b, sigma)),
                landmark: Some(landmarks[id].id.clone()),
                line: observations.len() as u64 + 2,
            });
        }
    }
    Ok(DemoScene {
        local,
        landmarks,
        observations,
        truth,
    })
}

/// Runs the demo: explains what it is, prints the JSON line of each frame and its error
/// against the truth.
///
/// # Errors
/// [`CliError::Output`] when writing fails.
pub fn run(out: &mut dyn Write) -> Result<(), CliError> {
    writeln!(
        out,
        "vgps demo: the demo drive arrives with the simulation and replay issues.\n\
         Meanwhile, `vgps locate` on a built-in synthetic scene: {DEMO_LANDMARKS} surveyed \
         landmarks (sigma 0.02 m),\ntwo frames, bearings with {DEMO_SIGMA_DEG} deg noise, and \
         in frame 0 one observation labelled with the wrong landmark.\n"
    )?;
    let scene = demo_scene()?;
    let mut notes = Vec::new();
    let input = super::locate::LocateInput {
        landmarks: &scene.landmarks,
        landmarks_path: Path::new("<demo landmarks>"),
        observations: &scene.observations,
        observations_path: Path::new("<demo observations>"),
        rig: None,
        prior: None,
        region: None,
        up_tolerance_rad: None,
        sigma_rad: DEMO_SIGMA_DEG.to_radians(),
    };
    let reports = super::locate::locate(&input, &mut notes)?;
    for (report, truth) in reports.iter().zip(&scene.truth) {
        let json = serde_json::to_string(report).map_err(std::io::Error::from)?;
        writeln!(out, "{json}")?;
        let hpr = HeadingPitchRoll::from_enu_from_rig(&truth.rotation);
        let (Some(lat), Some(lon), Some(alt), Some(heading)) =
            (report.lat, report.lon, report.alt, report.heading_deg)
        else {
            writeln!(
                out,
                "  frame {}: no fix ({})\n",
                report.frame, report.status
            )?;
            continue;
        };
        let estimate = Geodetic::try_new(lat, lon, alt)
            .map_err(|e| CliError::Internal(format!("demo estimate: {e}")))?;
        let error = scene.local.to_enu(&estimate) - truth.translation.vector;
        let sigma_e = report.cov_enu_m2.map_or(0.0, |c| c[0].sqrt());
        writeln!(
            out,
            "  frame {}: {} of {} observations used; position error {:.3} m (1-sigma east \
             {:.3} m); heading {:.3} deg, true {:.3} deg\n",
            report.frame,
            report.inliers.unwrap_or(0),
            report.observations,
            error.norm(),
            sigma_e,
            heading,
            hpr.heading_rad.to_degrees().rem_euclid(360.0),
        )?;
    }
    Ok(())
}
