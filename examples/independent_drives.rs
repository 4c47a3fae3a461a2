//! Surrogates on drives vgps did not generate (issue #25): an independent generator
//! (`tests/support/independent_drive.rs`, no code shared with `vgps::simulate`) builds loops
//! with other landmark spacings, speeds, frame rates and rigs, each with a stretch of
//! `--unsurveyed` metres (default 120) along which no surveyed landmark is in view, and the
//! localizer replays them. Prints availability, CEP50/95 (horizontal, `ok` fixes), the
//! fixes inside the unsurveyed stretch and the longest distance carried by surrogates.
//!
//! Run: `cargo run --release --example independent_drives [-- --seeds 3 --unsurveyed 120]`
#[path = "../tests/support/independent_drive.rs"]
mod independent_drive;

use independent_drive::{DriveSpec, RigKind, generate, replay};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str, default: f64| {
        args.iter()
            .position(|a| a == name)
            .and_then(|k| args.get(k + 1))
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(default)
    };
    let seeds = arg("--seeds", 1.0) as u64;
    let unsurveyed = arg("--unsurveyed", 120.0);
    let only = args
        .iter()
        .position(|a| a == "--variant")
        .and_then(|k| args.get(k + 1))
        .cloned();
    let variants = variants(unsurveyed);
    println!(
        "| variant | seed | frames | availability | CEP50 (cm) | CEP95 (cm) | max (cm) | unsurveyed stretch: run (m), fixed | carried by surrogates (m) | frames/s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, base) in &variants {
        if only.as_deref().is_some_and(|o| o != *name) {
            continue;
        }
        for seed in 0..seeds {
            let spec = DriveSpec {
                seed: 1000 + seed,
                ..*base
            };
            let drive = generate(&spec);
            let o = replay(&drive);
            println!(
                "| {name} | {} | {} | {:.2} % | {:.1} | {:.1} | {:.1} | {:.0} m, {}/{} | {:.0} | {:.0} |",
                spec.seed,
                o.frames,
                100.0 * o.availability(),
                100.0 * o.cep(0.5),
                100.0 * o.cep(0.95),
                100.0 * o.errors_m.last().copied().unwrap_or(f64::NAN),
                o.unsurveyed_run_m,
                o.stretch_frames.1,
                o.stretch_frames.0,
                o.carried_m,
                o.frames_per_s,
            );
        }
    }
}

/// The drive variants: the issue's drive and others that differ in spacing, speed, frame
/// rate and rig.
fn variants(unsurveyed: f64) -> Vec<(&'static str, DriveSpec)> {
    let issue = DriveSpec {
        unsurveyed_length_m: unsurveyed,
        ..DriveSpec::issue(0)
    };
    vec![
        ("issue: 25 m lamps, 8 m/s, 10 Hz, Ladybug", issue),
        (
            "sparse: 40 m lamps, 80 m corners, 12 m/s, 5 Hz, Ladybug yawed 36°",
            DriveSpec {
                lamp_spacing_m: 40.0,
                corner_spacing_m: 80.0,
                speed_m_s: 12.0,
                frame_rate_hz: 5.0,
                rig: RigKind::LadybugIni {
                    yaw_deg: 36.0,
                    focal_px: 950.0,
                },
                ..issue
            },
        ),
        (
            "dense: 15 m lamps, 30 m corners, 5 m/s, 20 Hz, panorama 4096",
            DriveSpec {
                lamp_spacing_m: 15.0,
                corner_spacing_m: 30.0,
                speed_m_s: 5.0,
                frame_rate_hz: 20.0,
                lamp_offset_m: 5.5,
                corner_offset_m: 11.0,
                rig: RigKind::Panorama { width: 4096 },
                ..issue
            },
        ),
        (
            "fast: 30 m lamps, 60 m corners, 15 m/s, 15 Hz, Ladybug, 40 m range",
            DriveSpec {
                unsurveyed_length_m: unsurveyed,
                ..DriveSpec::fast(0)
            },
        ),
    ]
}
