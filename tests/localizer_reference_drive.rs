//! Integrity of the localizer on the demo's reference drive (`vgps demo`): no `ok` fix far
//! from the truth, with the matcher's links kept as they are (`min_link_probability` 0) and
//! with the doubtful ones dropped (0.999). The second setting moves one matcher pose by ~5 mm
//! near frame 621; before surrogates were gated with the pose error independent from frame
//! to frame (and checked for consistency), that was enough for phantom surrogates (tracks
//! mixing rays of several landmarks) to pull the fix 25–60 m off ~1,100 frames later,
//! with σ ≈ 0.2 m reported (docs/localizer.md, "Phantom surrogates"). Two more seeds of the
//! same preset had `ok` fixes 4.3 m (a minimal set of 3 surveyed landmarks and 1 surrogate,
//! σ 3 cm) and 4.1 m off (4–6 surrogates, no surveyed landmark, σ 0.27 m) before the
//! innovation gate and the redundancy rule for surrogate fixes.

use std::sync::Arc;
use vgps::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus,
};
use vgps::matcher::MatchOptions;
use vgps::simulate::{Preset, Scenario, simulate};

/// Worst horizontal error of an `ok` fix allowed on the reference drive (metres): before
/// the fix the two settings gave 2.23 m and 60.7 m (seeds 3 and 4: 4.3 m and 4.1 m), after
/// it 0.23 m and 0.54 m (0.97 m and 0.18 m).
const MAX_OK_ERROR_M: f64 = 2.0;
/// Fewest fixes (fraction of the frames).
const MIN_FIX_RATE: f64 = 0.99;
/// Fewest fixes whose horizontal error is inside their 95 % ellipse.
const MIN_CONTAINMENT: f64 = 0.90;

/// Replays the reference preset's drive of `seed`: (fixes, frames, worst ok error (m) and its
/// frame, fraction of the fixes inside their 95 % ellipse).
fn replay(seed: u64, min_link_probability: f64) -> (usize, usize, f64, u64, f64) {
    let drive = simulate(&Scenario::preset(Preset::Reference, seed)).unwrap();
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map = Arc::new(LandmarkMap::from_landmarks(&landmarks, None).unwrap());
    let scenario = vgps::geo::LocalFrame::new(drive.scenario.origin);
    let options = LocalizerOptions {
        matcher: MatchOptions {
            min_link_probability,
            ..LocalizerOptions::default().matcher
        },
        ..LocalizerOptions::default()
    };
    let rig = Arc::new(drive.scenario.rig.clone());
    let mut localizer = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let (mut ok, mut inside, mut worst, mut worst_frame) = (0, 0, 0.0f64, 0);
    for f in &drive.frames {
        let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
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
        if d.norm() > worst {
            (worst, worst_frame) = (d.norm(), f.frame);
        }
        let c = e.covariance.fixed_view::<2, 2>(0, 0).into_owned();
        // χ²(2 dof) at 95 %: 5.991.
        if c.try_inverse().is_some_and(|ci| d.dot(&(ci * d)) <= 5.991) {
            inside += 1;
        }
    }
    (
        ok,
        drive.frames.len(),
        worst,
        worst_frame,
        inside as f64 / ok.max(1) as f64,
    )
}

fn check(seed: u64, min_link_probability: f64) {
    let (ok, n, worst, frame, containment) = replay(seed, min_link_probability);
    eprintln!(
        "seed {seed}, min_link_probability {min_link_probability}: {ok}/{n} fixes, worst ok error {worst:.2} m \
         (frame {frame}), {:.1} % inside the 95 % ellipse",
        100.0 * containment
    );
    assert!(
        worst <= MAX_OK_ERROR_M,
        "an ok fix {worst:.2} m off at frame {frame}"
    );
    assert!(ok as f64 >= MIN_FIX_RATE * n as f64, "{ok}/{n} fixes");
    assert!(
        containment >= MIN_CONTAINMENT,
        "containment {containment:.3}"
    );
}

#[test]
fn reference_drive_has_no_far_ok_fix_keeping_every_matcher_link() {
    check(1, 0.0);
}

#[test]
fn reference_drive_has_no_far_ok_fix_dropping_doubtful_matcher_links() {
    check(1, 0.999);
}

#[test]
fn other_reference_drives_have_no_far_ok_fix() {
    check(3, 0.0);
    check(4, 0.0);
}
