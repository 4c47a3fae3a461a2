//! Deterministic cost figure for `vgps::localizer::Localizer::process`: runs the localizer
//! over frames of the reference drive (the workload of `cargo bench --bench solvers --
//! localizer`) through one non-inlined wrapper, so that an instruction counter can attribute
//! every instruction of `process` to it. Also prints the wall-clock frames per second and a
//! checksum of the fixes (to see that a change kept the results).
//!
//! Usage (instructions per frame = inclusive Ir of `run` / frames):
//! ```text
//! cargo build --release --example localizer_instructions
//! valgrind --tool=callgrind --toggle-collect='*localizer_instructions::run*' \
//!     target/release/examples/localizer_instructions 1000
//! ```
//! Arguments: `[FRAMES]` (default: every frame of the drive).
use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;
use vgps::drive::gnss::gnss_at;
use vgps::localizer::{Frame, GnssPosition, LandmarkMap, Localizer, LocalizerStatus};
use vgps::simulate::{Preset, Scenario, simulate};

/// Processes the frames, never inlined: the unit the instruction counter measures.
#[inline(never)]
fn run(localizer: &mut Localizer, frames: &[Frame]) -> (usize, f64) {
    let mut ok = 0;
    let mut checksum = 0.0;
    for f in frames {
        let fix = localizer.process(black_box(f));
        if fix.status == LocalizerStatus::Ok
            && let Some(e) = &fix.estimate
        {
            ok += 1;
            checksum += e.world_from_rig.translation.vector.sum() + e.covariance.trace();
        }
    }
    (ok, checksum)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: Option<usize> = std::env::args().nth(1).and_then(|s| s.parse().ok());
    let drive = simulate(&Scenario::preset(Preset::Reference, 1))?;
    let landmarks = drive.surveyed_landmarks()?;
    let map = Arc::new(LandmarkMap::from_landmarks(&landmarks, None)?);
    let rig = Arc::new(drive.scenario.rig.clone());
    let frames: Vec<Frame> = drive
        .frames
        .iter()
        .take(n.unwrap_or(usize::MAX))
        .map(|f| {
            let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
            let gnss = gnss_at(&drive.gnss, f.time_s).map(|position| GnssPosition { position });
            Frame::from_detections(f.time_s, &detections, &map, gnss)
        })
        .collect();
    let mut localizer = Localizer::new(rig, map, Default::default())?;
    let start = Instant::now();
    let (ok, checksum) = run(&mut localizer, &frames);
    let elapsed = start.elapsed().as_secs_f64();
    println!(
        "{} frames, {ok} fixes, {:.0} frames/s, checksum {checksum:.9}",
        frames.len(),
        frames.len() as f64 / elapsed
    );
    Ok(())
}
