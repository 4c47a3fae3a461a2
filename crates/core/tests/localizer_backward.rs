//! `Localizer::process_backward`: a drive localized in reverse order, as the second pass of
//! an offline replay (`vgps replay --direction combined`). With a satellite position on
//! the last frame only and no cold start, a forward pass can fix only that frame; the
//! backward pass starts there and tracks the drive back to its first frame.

use std::sync::Arc;
use vgps_core::localizer::{Frame, GnssPosition, Localizer, LocalizerOptions, LocalizerStatus};

mod common;

#[test]
fn a_backward_pass_tracks_a_drive_back_from_its_last_frame() {
    let common::TestDrive { drive, map, rig } = common::short_drive(7, 100.0);
    let n = drive.frames.len();
    assert!(n >= 40, "{n} frames");
    let last = &drive.frames[n - 1];
    let prior = GnssPosition {
        position: map
            .frame()
            .try_to_geodetic(&last.world_from_rig.translation.vector)
            .unwrap(),
    };
    let frames: Vec<Frame> = drive
        .frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
            Frame::from_detections(f.time_s, &detections, &map, (k == n - 1).then_some(prior))
        })
        .collect();
    let options = LocalizerOptions {
        cold_start: false,
        ..LocalizerOptions::default()
    };

    // Forward: nothing to search around before the last frame.
    let mut forward = Localizer::new(Arc::clone(&rig), Arc::clone(&map), options).unwrap();
    let forward_ok: Vec<bool> = frames
        .iter()
        .map(|f| forward.process(f).status == LocalizerStatus::Ok)
        .collect();
    assert_eq!(forward_ok.iter().filter(|&&ok| ok).count(), 1);
    assert!(forward_ok[n - 1]);

    // Backward: from the last frame to the first.
    let mut backward = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let mut fixed = 0;
    let mut worst_m: f64 = 0.0;
    for (f, truth) in frames.iter().zip(&drive.frames).rev() {
        let fix = backward.process_backward(f);
        // The fix carries the frame's own time, not the negated one the pass runs in.
        assert_eq!(fix.time_s, f.time_s);
        if let Some(e) = &fix.estimate {
            fixed += 1;
            let error = (e.world_from_rig.translation.vector
                - truth.world_from_rig.translation.vector)
                .norm();
            worst_m = worst_m.max(error);
        }
    }
    eprintln!("backward: {fixed}/{n} fixed, worst error {worst_m:.3} m");
    assert!(fixed * 100 >= n * 95, "{fixed}/{n}");
    assert!(worst_m < 0.5, "worst error {worst_m} m");
}
