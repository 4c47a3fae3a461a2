//! Property test: a rig anywhere on Earth, landmarks given by WGS84 coordinates, bearings in
//! the rig frame. Solving in the local ENU frame at the landmarks' centroid and converting
//! back gives the rig's true latitude, longitude, height and heading.
use nalgebra::{Translation3, Vector3};
use proptest::prelude::*;
use vgps::attitude::HeadingPitchRoll;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::solvers::{p3p, p3p_cosines};

/// Position agreement after the geodetic round trips (metres).
const POSITION_TOL_M: f64 = 1e-6;

fn landmark_offsets() -> impl Strategy<Value = [[f64; 3]; 3]> {
    let one = (-80.0..80.0f64, -80.0..80.0f64, -5.0..30.0f64).prop_map(|(e, n, u)| [e, n, u]);
    [one.clone(), one.clone(), one]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
    #[test]
    fn fix_anywhere_on_earth(
        lat in -89.9..89.9f64,
        lon in -180.0..180.0f64,
        alt in -100.0..9000.0f64,
        heading in 0.0..360.0f64,
        pitch in -30.0..30.0f64,
        roll in -30.0..30.0f64,
        offsets in landmark_offsets(),
    ) {
        let rig = Geodetic::try_new(lat, lon, alt).unwrap();
        let at_rig = LocalFrame::new(rig);
        // Landmarks in WGS84, as a survey gives them.
        let landmarks: Vec<Geodetic> = offsets
            .iter()
            .map(|o| at_rig.try_to_geodetic(&Vector3::new(o[0], o[1], o[2])).unwrap())
            .collect();
        let hpr = HeadingPitchRoll {
            heading_rad: heading.to_radians(),
            pitch_rad: pitch.to_radians(),
            roll_rad: roll.to_radians(),
        };
        let enu_from_rig_at_rig = hpr.to_enu_from_rig();
        // Bearings observed in the rig frame.
        let truth_at_rig = Pose::from_parts(Translation3::identity(), enu_from_rig_at_rig);
        let points_at_rig: Vec<Vector3<f64>> = landmarks.iter().map(|g| at_rig.to_enu(g)).collect();
        let bearings: Option<Vec<Vector3<f64>>> =
            points_at_rig.iter().map(|p| bearing_in_rig(&truth_at_rig, p)).collect();
        let Some(bearings) = bearings else { return Ok(()) };
        let bearings = [bearings[0], bearings[1], bearings[2]];
        // Reject nearly collinear landmark triples (degenerate samples are tested elsewhere).
        let [a, b, c] = [points_at_rig[0], points_at_rig[1], points_at_rig[2]];
        prop_assume!((b - a).cross(&(c - a)).norm() > 1.0);
        // Solve in the ENU frame at the first landmark (not at the rig).
        let frame = LocalFrame::new(landmarks[0]);
        let points = [frame.to_enu(&landmarks[0]), frame.to_enu(&landmarks[1]), frame.to_enu(&landmarks[2])];
        for solutions in [p3p(&bearings, &points), p3p_cosines(&bearings, &points)] {
            let best = solutions
                .iter()
                .filter_map(|s| frame.try_to_geodetic(&s.translation.vector).ok().map(|g| (s, g)))
                .map(|(s, g)| (at_rig.to_enu(&g).norm(), s, g))
                .min_by(|x, y| x.0.total_cmp(&y.0));
            let Some((error_m, pose, _)) = best else {
                return Err(TestCaseError::fail("no solution"));
            };
            prop_assert!(error_m < POSITION_TOL_M, "position error {error_m} m");
            // Attitude: rotate enu_from_rig from the solving frame to the ENU frame at the rig.
            let enu_from_rig = at_rig.enu_here_from_enu_at(&landmarks[0]) * pose.rotation;
            let solved = HeadingPitchRoll::from_enu_from_rig(&enu_from_rig);
            let dh = (solved.heading_rad - hpr.heading_rad + std::f64::consts::PI)
                .rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
            prop_assert!(dh.abs() < 1e-7, "heading error {dh} rad");
            prop_assert!((solved.pitch_rad - hpr.pitch_rad).abs() < 1e-7);
            prop_assert!((solved.roll_rad - hpr.roll_rad).abs() < 1e-7);
        }
    }
}
