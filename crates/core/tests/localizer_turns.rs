//! `LocalizerOptions::max_turn_rate_change_rad_s`: the range of turn rate changes over
//! which tracking turns the prediction about the vertical (the sweep itself is tested in
//! the localizer's unit tests, on layouts that read one way and two ways).

use std::sync::Arc;
use vgps_core::localizer::{
    DEFAULT_MAX_TURN_RATE_CHANGE_RAD_S, Frame, GnssPosition, Localizer, LocalizerError,
    LocalizerOptions, LocalizerStatus,
};

mod common;

#[test]
fn turn_rate_changes_out_of_range_are_refused() {
    let drive = common::short_drive(7, 100.0);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let options = LocalizerOptions {
            max_turn_rate_change_rad_s: bad,
            ..LocalizerOptions::default()
        };
        assert_eq!(
            Localizer::new(Arc::clone(&drive.rig), Arc::clone(&drive.map), options).err(),
            Some(LocalizerError::InvalidOption("max_turn_rate_change_rad_s"))
        );
    }
    let off = LocalizerOptions {
        max_turn_rate_change_rad_s: 0.0,
        ..LocalizerOptions::default()
    };
    assert!(Localizer::new(Arc::clone(&drive.rig), Arc::clone(&drive.map), off).is_ok());
}

/// The sweep acts only where tracking from the prediction fails: on the first 100 m of
/// the `short` drive of seed 7 (satellite positions on every frame) the fixes are the same
/// with it and without it.
#[test]
fn where_tracking_holds_the_sweep_changes_nothing() {
    let common::TestDrive { drive, map, rig } = common::short_drive(7, 100.0);
    let frames: Vec<Frame> = drive
        .frames
        .iter()
        .map(|f| {
            let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
            let prior = GnssPosition {
                position: map
                    .frame()
                    .try_to_geodetic(&f.world_from_rig.translation.vector)
                    .unwrap(),
            };
            Frame::from_detections(f.time_s, &detections, &map, Some(prior))
        })
        .collect();
    let run = |rate: f64| {
        let options = LocalizerOptions {
            max_turn_rate_change_rad_s: rate,
            ..LocalizerOptions::default()
        };
        let mut localizer = Localizer::new(Arc::clone(&rig), Arc::clone(&map), options).unwrap();
        frames
            .iter()
            .map(|f| {
                let fix = localizer.process(f);
                (fix.status, fix.estimate.map(|e| e.world_from_rig))
            })
            .collect::<Vec<_>>()
    };
    let on = run(DEFAULT_MAX_TURN_RATE_CHANGE_RAD_S);
    assert!(on.len() >= 40, "{} frames", on.len());
    let fixed = on.iter().filter(|(s, _)| *s == LocalizerStatus::Ok).count();
    assert!(fixed + 2 >= on.len(), "{fixed} of {} fixed", on.len());
    assert_eq!(on, run(0.0));
}
