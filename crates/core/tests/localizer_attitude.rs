//! An IMU's attitude prior (vertical and heading) in the localizer: frames without any
//! position prior (no recent fix, no satellite GPS) are fixed on every frame through the
//! heading-pruned whole-map search, where without the IMU they wait for the cold start
//! (at most one every `cold_start_interval_s`, or every second on a map no larger than the
//! largest search around the last place known).

use nalgebra::Vector3;
use std::sync::Arc;
use vgps_core::localizer::{
    AttitudePrior, DEFAULT_COLD_START_INTERVAL_S, Frame, LAST_KNOWN_SEARCH_INTERVAL_S, LandmarkMap,
    Localizer, LocalizerError, LocalizerOptions, LocalizerStatus,
};

mod common;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// A 100 m drive (about 60 frames at 5 Hz): its map is small enough for the whole-map
/// searches to take a fraction of a second each in release.
fn small_drive() -> common::TestDrive {
    common::short_drive(7, 100.0)
}

#[test]
fn frames_with_an_imu_are_fixed_where_they_otherwise_wait_for_the_cold_start() {
    let common::TestDrive { drive, map, rig } = small_drive();
    // Frames 0.4 s apart, each without a prior (the localizer is reset) and no satellite
    // GPS: without the IMU only the first and the first a second later (the cold-start
    // interval on a map this small) are searched.
    let frames: Vec<_> = drive.frames.iter().step_by(2).take(6).collect();
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
                // No position prior at all: neither the last fix nor the place it was at
                // (which a search around the last place known would use).
                localizer.reset();
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
    // Without the IMU, the cold start is due on the first and the fourth frame only.
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
    let common::TestDrive { drive, map, rig } = small_drive();
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

/// A few seconds without a prior (a canyon: satellite GPS lost, the motion model's horizon
/// passed) and no cold start: the frames are searched around the last place known (the last
/// satellite position), within the distance the vehicle can have travelled since, and fixed
/// right. Before, they had `no_prior` until the cold start was due (issue #24 item 6: the
/// short preset's canyon, frames 349–386, 3–10 surveyed lamps in view, not fixed).
#[test]
fn frames_after_an_outage_are_searched_around_the_last_place_known() {
    let common::TestDrive { drive, map, rig } = small_drive();
    let options = LocalizerOptions {
        max_tracking_gap_s: 0.4,
        cold_start: false,
        ..LocalizerOptions::default()
    };
    let mut localizer = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let frames: Vec<_> = drive.frames.iter().step_by(10).take(4).collect();
    assert_eq!(frames.len(), 4, "{} frames", drive.frames.len());
    // The first frame: no detections, only its satellite position (the true one plus 3 m).
    let first = Frame {
        time_s: frames[0].time_s,
        observations: Vec::new(),
        gnss: Some(vgps_core::localizer::GnssPosition {
            position: map
                .frame()
                .try_to_geodetic(
                    &(frames[0].world_from_rig.translation.vector + Vector3::new(3.0, 0.0, 0.0)),
                )
                .unwrap(),
        }),
        attitude: None,
    };
    assert_eq!(
        localizer.process(&first).status,
        LocalizerStatus::TooFewObservations
    );
    // Then frames 2 s apart, none with satellite GPS.
    for f in &frames[1..] {
        let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
        let fix = localizer.process(&Frame::from_detections(f.time_s, &detections, &map, None));
        assert_eq!(fix.status, LocalizerStatus::Ok, "{fix:?}");
        let e = fix.estimate.as_ref().unwrap();
        let error =
            (e.world_from_rig.translation.vector - f.world_from_rig.translation.vector).norm();
        assert!(error < 0.5, "{error} m: {fix:?}");
    }
}

#[test]
fn searches_around_the_last_place_known_are_at_most_one_a_second() {
    let common::TestDrive { drive, map, rig } = small_drive();
    let options = LocalizerOptions {
        cold_start: false,
        ..LocalizerOptions::default()
    };
    let mut localizer = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let frame = |k: usize, n: usize| {
        let f = &drive.frames[k];
        let detections: Vec<_> = f
            .detections
            .iter()
            .take(n)
            .map(|d| d.detection.clone())
            .collect();
        (
            f.time_s,
            Frame::from_detections(f.time_s, &detections, &map, None),
        )
    };
    // The last place known: a satellite position (the true one) on a frame without
    // detections; no fix, so no prediction for the frames after it.
    let f0 = &drive.frames[0];
    let first = Frame {
        time_s: f0.time_s,
        observations: Vec::new(),
        gnss: Some(vgps_core::localizer::GnssPosition {
            position: map
                .frame()
                .try_to_geodetic(&f0.world_from_rig.translation.vector)
                .unwrap(),
        }),
        attitude: None,
    };
    localizer.process(&first);
    // A search around it on too few detections to decide: no fix.
    let (t1, few) = frame(1, 5);
    let fix = localizer.process(&few);
    assert_ne!(fix.status, LocalizerStatus::Ok, "{fix:?}");
    // Every detection, less than the interval after that search: no search, no prior.
    let (t2, too_soon) = frame(3, usize::MAX);
    assert!(t2 - t1 < LAST_KNOWN_SEARCH_INTERVAL_S, "{t1} {t2}");
    let fix = localizer.process(&too_soon);
    assert_eq!(fix.status, LocalizerStatus::NoPrior, "{fix:?}");
    // The interval after the search: searched and fixed.
    let (t3, again) = frame(7, usize::MAX);
    assert!(t3 - t1 >= LAST_KNOWN_SEARCH_INTERVAL_S, "{t1} {t3}");
    let fix = localizer.process(&again);
    assert_eq!(fix.status, LocalizerStatus::Ok, "{fix:?}");
}

#[test]
fn drift_rates_out_of_range_are_refused() {
    let common::TestDrive { map, rig, .. } = small_drive();
    for bad in [-0.001, f64::NAN, f64::INFINITY] {
        let surrogate = LocalizerOptions {
            surrogate_drift_per_m: bad,
            ..LocalizerOptions::default()
        };
        let seen = LocalizerOptions {
            seen_ahead_drift_per_m: bad,
            ..LocalizerOptions::default()
        };
        assert_eq!(
            Localizer::new(Arc::clone(&rig), Arc::clone(&map), surrogate).err(),
            Some(LocalizerError::InvalidOption("surrogate_drift_per_m"))
        );
        assert_eq!(
            Localizer::new(Arc::clone(&rig), Arc::clone(&map), seen).err(),
            Some(LocalizerError::InvalidOption("seen_ahead_drift_per_m"))
        );
    }
}

/// Frames without any prior, 0.4 s apart: over the 100 m drive's map a cold start is due
/// every second (it costs no more than a search around the last place known); over the
/// same map stretched over more than 1.5 km² by one more landmark, every `cold_start_interval_s`.
#[test]
fn cold_starts_are_due_every_second_on_a_small_map_only() {
    let common::TestDrive { drive, map, rig } = small_drive();
    let mut landmarks = drive.surveyed_landmarks().unwrap();
    let mut far = landmarks[0].clone();
    far.id = "far".into();
    far.lat_deg += 0.0135; // 1.5 km north
    far.lon_deg += 0.02; // and at least 1.1 km east (below 60° of latitude)
    landmarks.push(far);
    let large =
        Arc::new(LandmarkMap::from_landmarks(&landmarks, Some(drive.scenario.origin)).unwrap());
    let frames: Vec<_> = drive.frames.iter().step_by(2).take(8).collect();
    let searched = |map: &Arc<LandmarkMap>| {
        let mut localizer = Localizer::new(
            Arc::clone(&rig),
            Arc::clone(map),
            LocalizerOptions::default(),
        )
        .unwrap();
        frames
            .iter()
            .filter_map(|f| {
                let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
                localizer.reset();
                let fix =
                    localizer.process(&Frame::from_detections(f.time_s, &detections, map, None));
                (fix.status != LocalizerStatus::NoPrior).then_some(f.time_s)
            })
            .collect::<Vec<_>>()
    };
    let small = searched(&map);
    let t0 = frames[0].time_s;
    let span = frames[frames.len() - 1].time_s - t0;
    assert!((2.0 * LAST_KNOWN_SEARCH_INTERVAL_S..DEFAULT_COLD_START_INTERVAL_S).contains(&span));
    // The first frame, then the first frame at least a second after each search.
    let mut expected = vec![t0];
    for f in &frames {
        if f.time_s - expected[expected.len() - 1] >= LAST_KNOWN_SEARCH_INTERVAL_S {
            expected.push(f.time_s);
        }
    }
    assert!(expected.len() >= 3, "{expected:?}");
    assert_eq!(small, expected);
    assert_eq!(searched(&large), vec![t0]);
}
