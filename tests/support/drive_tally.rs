//! Replays a simulated drive frame by frame through the library's localizer and tallies its
//! `ok` fixes against the truth (shared by the localizer's integration tests).

use std::sync::Arc;
use vgps::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus,
};
use vgps::simulate::SimulatedDrive;

/// What a replay gave.
pub struct Tally {
    /// Frames with an `ok` fix.
    pub ok: usize,
    /// Frames.
    pub frames: usize,
    /// Worst horizontal error of an `ok` fix (metres) and its frame.
    pub worst_m: f64,
    pub worst_frame: u64,
    /// Share of the `ok` fixes whose horizontal error is inside their 95 % ellipse.
    pub containment: f64,
}

/// Replays `drive` with `options`, each frame's detections filtered by `keep`, with the
/// drive's satellite GPS.
pub fn replay(
    drive: &SimulatedDrive,
    options: LocalizerOptions,
    keep: &dyn Fn(&vgps::imaging::PixelDetection) -> bool,
) -> Tally {
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map = Arc::new(LandmarkMap::from_landmarks(&landmarks, None).unwrap());
    let scenario = vgps::geo::LocalFrame::new(drive.scenario.origin);
    let rig = Arc::new(drive.scenario.rig.clone());
    let mut localizer = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let (mut ok, mut inside, mut worst_m, mut worst_frame) = (0, 0, 0.0f64, 0);
    for f in &drive.frames {
        let detections: Vec<_> = f
            .detections
            .iter()
            .map(|d| d.detection.clone())
            .filter(|d| keep(d))
            .collect();
        let gnss = vgps::drive::gnss::gnss_at(&drive.gnss, f.time_s)
            .map(|position| GnssPosition { position });
        let fix = localizer.process(&Frame::from_detections(f.time_s, &detections, &map, gnss));
        if fix.status != LocalizerStatus::Ok {
            continue;
        }
        let Some(e) = fix.estimate else { continue };
        ok += 1;
        let truth = scenario
            .try_to_geodetic(&f.world_from_rig.translation.vector)
            .unwrap();
        let d = (e.world_from_rig.translation.vector - map.frame().to_enu(&truth)).xy();
        if d.norm() > worst_m {
            (worst_m, worst_frame) = (d.norm(), f.frame);
        }
        let c = e.covariance.fixed_view::<2, 2>(0, 0).into_owned();
        // χ²(2 dof) at 95 %: 5.991.
        if c.try_inverse().is_some_and(|ci| d.dot(&(ci * d)) <= 5.991) {
            inside += 1;
        }
    }
    Tally {
        ok,
        frames: drive.frames.len(),
        worst_m,
        worst_frame,
        containment: inside as f64 / ok.max(1) as f64,
    }
}
