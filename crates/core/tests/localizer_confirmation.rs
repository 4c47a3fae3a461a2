//! `LocalizerOptions::confirm_false_alarms`: a pose re-acquired by the matcher on weak
//! evidence (more false alarms than the option) is tracked from but not reported; the
//! first later frame tracked from it is. A pose the next frame contradicts is never
//! reported.

use std::sync::Arc;
use vgps_core::localizer::{
    DEFAULT_CONFIRM_FALSE_ALARMS, FixSource, Frame, GnssPosition, Localizer, LocalizerError,
    LocalizerOptions, LocalizerStatus,
};

mod common;

/// The first frames of the 100 m drive of seed 7, each with a satellite position at its
/// true place (the re-acquisition's prior).
fn frames(drive: &common::TestDrive, count: usize) -> Vec<Frame> {
    drive
        .drive
        .frames
        .iter()
        .take(count)
        .map(|f| {
            let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
            let prior = GnssPosition {
                position: drive
                    .map
                    .frame()
                    .try_to_geodetic(&f.world_from_rig.translation.vector)
                    .unwrap(),
            };
            Frame::from_detections(f.time_s, &detections, &drive.map, Some(prior))
        })
        .collect()
}

fn localizer(drive: &common::TestDrive, confirm_false_alarms: f64) -> Localizer {
    let options = LocalizerOptions {
        confirm_false_alarms,
        ..LocalizerOptions::default()
    };
    Localizer::new(Arc::clone(&drive.rig), Arc::clone(&drive.map), options).unwrap()
}

#[test]
fn a_weak_reacquisition_is_reported_once_the_next_frame_tracks_from_it() {
    let drive = common::short_drive(7, 100.0);
    let frames = frames(&drive, 6);
    // Every re-acquisition counts as weak: its frame waits.
    let mut strict = localizer(&drive, 1e-300);
    let first = strict.process(&frames[0]);
    assert_eq!(first.status, LocalizerStatus::NoFix, "{first:?}");
    assert!(first.estimate.is_none());
    assert!(
        first
            .message
            .contains("awaits confirmation by the next frame"),
        "{}",
        first.message
    );
    // The frames after it wait too while they are re-acquired (at the start the motion
    // model has no velocity yet); the first one tracked from the pose is the fix.
    let mut first_ok = None;
    for (k, f) in frames.iter().enumerate().skip(1) {
        let fix = strict.process(f);
        if fix.status == LocalizerStatus::Ok {
            first_ok = Some((k, fix));
            break;
        }
        assert!(
            fix.message.contains("awaits confirmation"),
            "frame {k}: {fix:?}"
        );
    }
    let (k, fix) = first_ok.expect("a frame tracked from the re-acquired pose");
    assert_eq!(fix.source, Some(FixSource::Tracking), "frame {k}: {fix:?}");
    let e = fix.estimate.as_ref().unwrap();
    let error = (e.world_from_rig.translation.vector
        - drive.drive.frames[k].world_from_rig.translation.vector)
        .norm();
    assert!(error < 0.2, "frame {k}: {error} m");
    // The default: the same first frame's re-acquisition is strong enough to report.
    let mut default = localizer(&drive, DEFAULT_CONFIRM_FALSE_ALARMS);
    assert_eq!(default.process(&frames[0]).status, LocalizerStatus::Ok);
    // Without the confirmation every re-acquired pose is reported at once.
    let mut off = localizer(&drive, f64::INFINITY);
    assert_eq!(off.process(&frames[0]).status, LocalizerStatus::Ok);
}

#[test]
fn a_weak_reacquisition_the_next_frame_contradicts_is_never_reported() {
    let drive = common::short_drive(7, 100.0);
    let frames = frames(&drive, 30);
    // The first frame as seen, then a frame 0.2 s later whose detections are those of a
    // place 20 frames on (about 30 m away): the pose of the first does not track into it.
    let jumped = Frame {
        time_s: frames[0].time_s + 0.2,
        ..frames[20].clone()
    };
    let mut strict = localizer(&drive, 1e-300);
    let first = strict.process(&frames[0]);
    assert_eq!(first.status, LocalizerStatus::NoFix, "{first:?}");
    // The second frame does not track from the first frame's pose, so it confirms
    // nothing; its own re-acquisition (if any) waits in turn.
    let second = strict.process(&jumped);
    assert_ne!(second.status, LocalizerStatus::Ok, "{second:?}");
    assert!(second.estimate.is_none());
    // Reported at once without the confirmation.
    let mut off = localizer(&drive, f64::INFINITY);
    assert_eq!(off.process(&frames[0]).status, LocalizerStatus::Ok);
}

#[test]
fn confirmation_thresholds_out_of_range_are_refused() {
    let drive = common::short_drive(7, 100.0);
    for bad in [0.0, -1.0, f64::NAN] {
        let options = LocalizerOptions {
            confirm_false_alarms: bad,
            ..LocalizerOptions::default()
        };
        assert_eq!(
            Localizer::new(Arc::clone(&drive.rig), Arc::clone(&drive.map), options).err(),
            Some(LocalizerError::InvalidOption("confirm_false_alarms"))
        );
    }
}
