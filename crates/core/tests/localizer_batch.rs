//! `Localizer::process_batch`: the matcher's searches of a lost localizer run ahead on
//! worker threads give the fixes of `Localizer::process` frame after frame, bit for bit,
//! whatever the thread count and however the frames are cut into batches.

use std::sync::Arc;
use vgps_core::localizer::{Frame, LandmarkMap, Localizer, LocalizerFix, LocalizerOptions};

mod common;

/// A drive that gets lost and found again: a stretch with 3 detections per frame (tracking
/// fails, searches find nothing), and a stretch whose frames show another part of the route
/// (the track jumps: searches around the last place known, cold starts).
fn lost_and_found() -> (
    Arc<vgps_camera::calibration::Rig>,
    Arc<LandmarkMap>,
    Vec<Frame>,
) {
    let common::TestDrive { drive, map, rig } = common::short_drive(11, 150.0);
    let n = drive.frames.len();
    assert!(n >= 70, "{n} frames");
    let frames = drive
        .frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let seen = if (45..60).contains(&k) {
                &drive.frames[k - 40]
            } else {
                f
            };
            let mut detections: Vec<_> = seen
                .detections
                .iter()
                .map(|d| d.detection.clone())
                .collect();
            if (15..30).contains(&k) {
                detections.truncate(3);
            }
            Frame::from_detections(f.time_s, &detections, &map, None)
        })
        .collect();
    (rig, map, frames)
}

fn localizer(rig: &Arc<vgps_camera::calibration::Rig>, map: &Arc<LandmarkMap>) -> Localizer {
    Localizer::new(
        Arc::clone(rig),
        Arc::clone(map),
        LocalizerOptions::default(),
    )
    .unwrap()
}

#[test]
fn batches_with_searches_run_ahead_give_the_fixes_of_frame_after_frame() {
    let (rig, map, frames) = lost_and_found();
    let mut serial = localizer(&rig, &map);
    let expected: Vec<LocalizerFix> = frames.iter().map(|f| serial.process(f)).collect();
    let fixed = expected.iter().filter(|f| f.estimate.is_some()).count();
    // The drive must exercise both: fixes, and frames without one.
    eprintln!(
        "{fixed}/{} fixed: {:?}",
        frames.len(),
        expected
            .iter()
            .map(|f| f.status.as_str())
            .collect::<Vec<_>>()
    );
    assert!(fixed > frames.len() / 3, "{fixed}/{} fixed", frames.len());
    assert!(fixed < frames.len() - 10, "{fixed}/{} fixed", frames.len());

    for (threads, batch) in [(2, 13), (3, 64), (2, frames.len())] {
        let mut batched = localizer(&rig, &map);
        let chunks: Vec<&[Frame]> = frames.chunks(batch).collect();
        let mut fixes = Vec::new();
        for (k, chunk) in chunks.iter().enumerate() {
            let ahead = chunks.get(k + 1).copied().unwrap_or(&[]);
            fixes.extend(batched.process_batch(chunk, ahead, threads));
        }
        assert_eq!(fixes.len(), expected.len());
        for (k, (got, want)) in fixes.iter().zip(&expected).enumerate() {
            assert_eq!(
                got, want,
                "frame {k}, {threads} threads, batches of {batch}"
            );
        }
        let stats = batched.batch_stats();
        eprintln!("{threads} threads, batches of {batch}: {stats:?}");
        assert!(
            stats.served > 0 && stats.planned >= stats.served,
            "{stats:?}"
        );
    }
}

#[test]
fn a_backward_batch_gives_the_fixes_of_the_backward_pass() {
    let (rig, map, frames) = lost_and_found();
    let reversed: Vec<Frame> = frames.iter().rev().cloned().collect();
    let mut serial = localizer(&rig, &map);
    let expected: Vec<LocalizerFix> = reversed
        .iter()
        .map(|f| serial.process_backward(f))
        .collect();
    let mut batched = localizer(&rig, &map);
    let fixes = batched.process_backward_batch(&reversed, 2);
    assert_eq!(fixes, expected);
    assert!(batched.batch_stats().served > 0);
}

#[test]
fn one_thread_is_process_frame_after_frame() {
    let (rig, map, frames) = lost_and_found();
    let mut serial = localizer(&rig, &map);
    let expected: Vec<LocalizerFix> = frames.iter().map(|f| serial.process(f)).collect();
    let mut batched = localizer(&rig, &map);
    assert_eq!(batched.process_batch(&frames, &[], 1), expected);
    assert_eq!(batched.batch_stats().planned, 0);
}
