//! Position and attitude from three surveyed landmarks: the core of vgps in a few lines.
//!
//! Run: `cargo run --release --example three_landmarks`
use nalgebra::{Translation3, Vector3};
use vgps::attitude::HeadingPitchRoll;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::solvers::p3p;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Three surveyed streetlights (WGS84 degrees, ellipsoidal metres), in a local ENU frame.
    let lamps = [
        Geodetic::try_new(37.79550, -122.39370, 7.0)?,
        Geodetic::try_new(37.79560, -122.39340, 6.5)?,
        Geodetic::try_new(37.79530, -122.39345, 8.0)?,
    ];
    let frame = LocalFrame::new(lamps[0]);
    let points_in_enu = lamps.map(|g| frame.to_enu(&g));

    // Bearings in the rig frame (x forward, y left, z up). Here they are made from a known
    // pose; on a robot they come from the calibration (`vgps::calibration::Rig::ray`).
    let truth = HeadingPitchRoll {
        heading_rad: 30f64.to_radians(),
        pitch_rad: 2f64.to_radians(),
        roll_rad: -1f64.to_radians(),
    };
    let true_pose = Pose::from_parts(
        Translation3::new(-5.0, -20.0, -4.5),
        truth.to_enu_from_rig(),
    );
    let bearings_in_rig: [Vector3<f64>; 3] =
        points_in_enu.map(|p| bearing_in_rig(&true_pose, &p).expect("landmark away from rig"));

    // Every pose consistent with the three bearings (up to four: P3P is ambiguous).
    for enu_from_rig in p3p(&bearings_in_rig, &points_in_enu) {
        let position = frame.try_to_geodetic(&enu_from_rig.translation.vector)?;
        let [heading, pitch, roll] =
            HeadingPitchRoll::from_enu_from_rig(&enu_from_rig.rotation).to_degrees();
        println!(
            "lat {:.7} lon {:.7} alt {:.3} m  heading {heading:.3} pitch {pitch:.3} roll {roll:.3} deg",
            position.lat_deg, position.lon_deg, position.alt_m
        );
    }
    Ok(())
}
