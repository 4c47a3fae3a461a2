//! Lamps seen ahead ([`LocalizerOptions::surrogates_seen_ahead`]) on the `short` preset's
//! lamps-only detections (5 frames/s, a survey gap): mapped lamps that the surrogate
//! criteria still refuse, but that are placed well enough as seen from the rig, carry the
//! fix where the surveyed lamps leave the view. The same drive without them: fewer fixes;
//! with them: no fix far off and the reported covariance still honest.

use std::sync::Arc;
use vgps::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus,
};
use vgps::simulate::{Preset, Scenario, simulate};

/// Worst horizontal error of an `ok` fix (metres): 0.99 m measured with lamps seen ahead
/// (0.27 m without), on surrogates only.
const MAX_OK_ERROR_M: f64 = 2.0;
/// Fewest fixes inside their 95 % ellipse.
const MIN_CONTAINMENT: f64 = 0.9;

/// Replays the drive: (fixes, frames, worst ok error (m), share inside the 95 % ellipse).
fn replay(seen_ahead: bool) -> (usize, usize, f64, f64) {
    let drive = simulate(&Scenario::preset(Preset::Short, 1)).unwrap();
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map = Arc::new(LandmarkMap::from_landmarks(&landmarks, None).unwrap());
    let scenario = vgps::geo::LocalFrame::new(drive.scenario.origin);
    let options = LocalizerOptions {
        surrogates_seen_ahead: seen_ahead,
        ..LocalizerOptions::default()
    };
    let rig = Arc::new(drive.scenario.rig.clone());
    let mut localizer = Localizer::new(rig, Arc::clone(&map), options).unwrap();
    let (mut ok, mut inside, mut worst) = (0, 0, 0.0f64);
    for f in &drive.frames {
        let lamps: Vec<_> = f
            .detections
            .iter()
            .map(|d| d.detection.clone())
            .filter(|d| d.class.as_deref() == Some("streetlight"))
            .collect();
        let gnss = vgps::drive::gnss::gnss_at(&drive.gnss, f.time_s)
            .map(|position| GnssPosition { position });
        let fix = localizer.process(&Frame::from_detections(f.time_s, &lamps, &map, gnss));
        if fix.status != LocalizerStatus::Ok {
            continue;
        }
        let Some(e) = fix.estimate else { continue };
        ok += 1;
        let truth = scenario
            .try_to_geodetic(&f.world_from_rig.translation.vector)
            .unwrap();
        let d = (e.world_from_rig.translation.vector - map.frame().to_enu(&truth)).xy();
        worst = worst.max(d.norm());
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
        inside as f64 / ok.max(1) as f64,
    )
}

#[test]
fn lamps_seen_ahead_carry_a_lamps_only_drive_further_and_stay_honest() {
    let (ok_off, n, worst_off, inside_off) = replay(false);
    let (ok_on, _, worst_on, inside_on) = replay(true);
    eprintln!(
        "short, lamps only: without lamps seen ahead {ok_off}/{n} fixes (worst {worst_off:.2} m, {:.1} % inside), with {ok_on}/{n} (worst {worst_on:.2} m, {:.1} % inside)",
        100.0 * inside_off,
        100.0 * inside_on
    );
    assert!(ok_on >= ok_off + 40, "{ok_off} → {ok_on} of {n}");
    assert!(worst_on <= MAX_OK_ERROR_M, "an ok fix {worst_on:.2} m off");
    assert!(inside_on >= MIN_CONTAINMENT, "containment {inside_on:.3}");
}
