//! An IMU's attitude prior (vertical and heading) in the localizer: frames without any
//! position prior (no recent fix, no satellite GPS) are fixed on every frame through the
//! heading-pruned whole-map search, where without the IMU they wait for the cold start
//! (at most one every `cold_start_interval_s`).

use nalgebra::Vector3;
use std::sync::Arc;
use vgps_core::localizer::{
    AttitudePrior, Frame, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus,
};
use vgps_sim::simulate::{Preset, Scenario, SimulatedDrive, simulate};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// A 100 m drive (about 60 frames at 5 Hz): its map is small enough for the whole-map
/// searches to take a fraction of a second each in release.
fn small_drive() -> SimulatedDrive {
    let mut scenario = Scenario::preset(Preset::Short, 7);
    scenario.length_m = 100.0;
    simulate(&scenario).unwrap()
}

#[test]
fn frames_with_an_imu_are_fixed_where_they_otherwise_wait_for_the_cold_start() {
    let drive = small_drive();
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map =
        Arc::new(LandmarkMap::from_landmarks(&landmarks, Some(drive.scenario.origin)).unwrap());
    let rig = Arc::new(drive.scenario.rig.clone());
    // Frames 2 s apart, beyond the motion model's reach (4 × 0.4 s), and no satellite GPS:
    // without the IMU only the first and the one 10 s later (the cold-start interval) are
    // searched.
    let frames: Vec<_> = drive.frames.iter().step_by(10).take(6).collect();
    assert_eq!(frames.len(), 6, "{} frames", drive.frames.len());
    let options = LocalizerOptions {
        max_tracking_gap_s: 0.4,
        ..LocalizerOptions::default()
    };
    let run = |imu: bool| {
        let mut localizer = Localizer::new(Arc::clone(&rig), Arc::clone(&map), options).unwrap();
        frames
            .iter()
            .map(|f| {
                let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
                let r = f.world_from_rig.rotation;
                let x = r * Vector3::x();
                let attitude = imu.then(|| AttitudePrior {
                    up_in_rig: r.inverse_transform_vector(&Vector3::z()),
                    up_tolerance_rad: 1.0 * DEG,
                    heading: Some((x.y.atan2(x.x), 3.0 * DEG)),
                });
                let frame = Frame::from_detections(f.time_s, &detections, &map, None)
                    .with_attitude(attitude);
                let start = std::time::Instant::now();
                let fix = localizer.process(&frame);
                let seconds = start.elapsed().as_secs_f64();
                let error = fix.estimate.as_ref().map(|e| {
                    (e.world_from_rig.translation.vector - f.world_from_rig.translation.vector)
                        .norm()
                });
                eprintln!(
                    "imu {imu} t {:.1} s: {:?} error {error:?} m, {seconds:.3} s",
                    f.time_s, fix.status
                );
                (fix.status, error)
            })
            .collect::<Vec<_>>()
    };
    let without = run(false);
    let with = run(true);
    eprintln!("without IMU: {without:?}\nwith IMU: {with:?}");
    // Without the IMU, the cold start is due on the first and the sixth frame only.
    let waiting: Vec<usize> = (0..frames.len())
        .filter(|&k| without[k].0 == LocalizerStatus::NoPrior)
        .collect();
    assert!(waiting.len() >= 2, "{without:?}");
    // With it, those frames are fixed, and right.
    let fixed_where_waiting = waiting
        .iter()
        .filter(|&&k| with[k].0 == LocalizerStatus::Ok)
        .count();
    assert!(fixed_where_waiting * 3 >= waiting.len() * 2, "{with:?}");
    for (status, error) in &with {
        if *status == LocalizerStatus::Ok {
            assert!(error.is_some_and(|e| e < 0.5), "{with:?}");
        }
    }
    let ok = |v: &[(LocalizerStatus, Option<f64>)]| {
        v.iter().filter(|(s, _)| *s == LocalizerStatus::Ok).count()
    };
    assert!(ok(&with) > ok(&without));
}

#[test]
fn a_wrong_heading_prior_finds_no_wrong_fix() {
    // The heading gate drops the true poses: the frame is not fixed (or, if other poses
    // pass, not wrongly: every fix is checked against the truth).
    let drive = small_drive();
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map =
        Arc::new(LandmarkMap::from_landmarks(&landmarks, Some(drive.scenario.origin)).unwrap());
    let rig = Arc::new(drive.scenario.rig.clone());
    let mut localizer = Localizer::new(rig, Arc::clone(&map), LocalizerOptions::default()).unwrap();
    let f = &drive.frames[0];
    let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
    let r = f.world_from_rig.rotation;
    let x = r * Vector3::x();
    let attitude = AttitudePrior {
        up_in_rig: r.inverse_transform_vector(&Vector3::z()),
        up_tolerance_rad: 1.0 * DEG,
        heading: Some((x.y.atan2(x.x) + 90.0 * DEG, 3.0 * DEG)),
    };
    let fix = localizer.process(
        &Frame::from_detections(f.time_s, &detections, &map, None).with_attitude(Some(attitude)),
    );
    if let Some(e) = &fix.estimate {
        let error =
            (e.world_from_rig.translation.vector - f.world_from_rig.translation.vector).norm();
        assert!(error < 0.5, "{fix:?}");
    }
}
