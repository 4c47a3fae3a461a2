//! Lamps seen ahead ([`LocalizerOptions::surrogates_seen_ahead`]) on the `short` preset's
//! lamps-only detections (5 frames/s, a survey gap): mapped lamps that the surrogate
//! criteria still refuse, but that are placed well enough as seen from the rig, carry the
//! fix where the surveyed lamps leave the view. The same drive without them: fewer fixes;
//! with them: no fix far off and the reported covariance still honest.

#[path = "support/drive_tally.rs"]
mod drive_tally;

use vgps::localizer::LocalizerOptions;
use vgps::simulate::{Preset, Scenario, simulate};

/// Worst horizontal error of an `ok` fix (metres): 0.99 m measured with lamps seen ahead
/// (0.27 m without), on surrogates only.
const MAX_OK_ERROR_M: f64 = 2.0;
/// Fewest fixes inside their 95 % ellipse.
const MIN_CONTAINMENT: f64 = 0.9;

/// Replays the drive's lamps.
fn replay(seen_ahead: bool) -> drive_tally::Tally {
    let drive = simulate(&Scenario::preset(Preset::Short, 1)).unwrap();
    let options = LocalizerOptions {
        surrogates_seen_ahead: seen_ahead,
        ..LocalizerOptions::default()
    };
    drive_tally::replay(&drive, options, &|d| {
        d.class.as_deref() == Some("streetlight")
    })
}

#[test]
fn lamps_seen_ahead_carry_a_lamps_only_drive_further_and_stay_honest() {
    let off = replay(false);
    let on = replay(true);
    for (name, t) in [("without", &off), ("with", &on)] {
        eprintln!(
            "short, lamps only, {name} lamps seen ahead: {}/{} fixes, worst {:.2} m (frame {}), {:.1} % inside their 95 % ellipse",
            t.ok,
            t.frames,
            t.worst_m,
            t.worst_frame,
            100.0 * t.containment
        );
    }
    assert!(
        on.ok >= off.ok + 40,
        "{} → {} of {}",
        off.ok,
        on.ok,
        on.frames
    );
    assert!(
        on.worst_m <= MAX_OK_ERROR_M,
        "an ok fix {:.2} m off at frame {}",
        on.worst_m,
        on.worst_frame
    );
    assert!(
        on.containment >= MIN_CONTAINMENT,
        "containment {:.3}",
        on.containment
    );
}
