//! Regenerates the shipped calibration files in `calibration/` and the test fixtures in
//! `tests/fixtures/calibration/` from the constants of `vgps::synthetic::calibration_files`
//! (deterministic: the same bytes every run).
//!
//! ```text
//! cargo run --release --example generate_calibration
//! ```
//!
//! Prints the LUT grid step it picked for `calibration/ladybug2_lut.json` (the largest step
//! whose worst pixel error against `ladybug2.json` over a dense probe is ≤ half of the
//! 0.01 px target) and the file sizes.

use nalgebra::Vector2;
use std::path::Path;
use vgps::calibration::formats::{ladybug_ini, native, nclt, to_lut_rig};
use vgps::calibration::{
    Camera, CameraModel, Equirectangular, EquirectangularParams, KannalaBrandt,
    KannalaBrandtParams, Lut, Pinhole, PinholeParams, RadialTangential, Rig, RigCamera,
};
use vgps::synthetic::calibration_files as synth;

/// The LUT accuracy target (pixels) and the margin kept below it.
const LUT_TARGET_PX: f64 = 0.01;
const LUT_MARGIN: f64 = 0.5;

/// Worst |source pixel of the LUT bearing − pixel| over a probe grid with offsets.
fn lut_error(source: &Camera, lut: &Lut) -> f64 {
    let (w, h) = source.image_size();
    let mut worst: f64 = 0.0;
    let mut v = -0.49;
    while v <= f64::from(h) - 0.5 {
        let mut u = -0.49;
        while u <= f64::from(w) - 0.5 {
            let p = Vector2::new(u, v);
            if let Some(b) = lut.try_bearing(&p) {
                if let Some(q) = source.try_pixel(&b) {
                    worst = worst.max((q - p).norm());
                } else {
                    worst = f64::INFINITY;
                }
            }
            u += 1.37;
        }
        v += 1.61;
    }
    worst
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = root.join("calibration");
    let fixtures = root.join("tests/fixtures/calibration");
    std::fs::create_dir_all(&out)?;
    std::fs::create_dir_all(&fixtures)?;

    // 1. The Ladybug2-like rig, default calibration of `vgps demo`.
    let ladybug2 = synth::ladybug2_rig();
    native::write(&ladybug2, &out.join("ladybug2.json"))?;

    // 2. Its LUT: the largest step meeting the accuracy target with margin.
    let source = &ladybug2.cameras()[0].model;
    let mut chosen = None;
    for step in [16u32, 12, 8, 6, 4, 3, 2, 1] {
        let lut = Lut::from_model(source, step)?;
        let error = lut_error(source, &lut);
        println!("LUT step {step}: worst error {error:.2e} px");
        if error <= LUT_TARGET_PX * LUT_MARGIN {
            chosen = Some((step, error));
            break;
        }
    }
    let (step, error) = chosen.ok_or("no LUT step meets the target")?;
    let lut_rig = to_lut_rig(&ladybug2, step, &out.join("ladybug2.json"))?;
    native::write(&lut_rig, &out.join("ladybug2_lut.json"))?;
    let (cols, rows) = match &lut_rig.cameras()[0].model {
        Camera::Lut(l) => l.grid_size(),
        _ => unreachable!(),
    };
    println!(
        "ladybug2_lut: step {step} px, {cols}×{rows} nodes per camera, worst error {error:.2e} px, \
         {} bytes per LUT file",
        vgps::calibration::LUT_HEADER_BYTES + 12 * cols * rows
    );

    // 3. An equirectangular 2048×1024 panorama.
    let pano = Equirectangular::new(EquirectangularParams {
        width: 2048,
        height: 1024,
    })?;
    native::write(
        &Rig::panorama(Camera::from(pano)),
        &out.join("equirectangular_2048x1024.json"),
    )?;

    // 4. A Ladybug5-style INI export (rectified 2448×2048 images, f = 1230 px).
    let values = synth::ladybug_ini_values(1230.0, (1223.5, 1023.5), 0.042, 0.068, 0.0015);
    std::fs::write(
        out.join("ladybug5_example.ini"),
        ladybug_ini::to_text(&values, Some((2448, 2048))),
    )?;

    // 5. An NCLT-style directory with small 64×48 images.
    nclt::write(&synth::nclt_rig(64, 48, 30.0), &out.join("nclt_example"))?;

    // Test fixtures: small and hand-checkable.
    let exact = synth::ladybug_ini_values(40.0, (31.5, 23.5), 0.04, 0.06, 0.0);
    std::fs::write(
        fixtures.join("ladybug_64x48.ini"),
        ladybug_ini::to_text(&exact, Some((64, 48))),
    )?;
    std::fs::write(
        fixtures.join("ladybug_no_size.ini"),
        ladybug_ini::to_text(&exact, None),
    )?;
    nclt::write(&synth::nclt_rig(16, 12, 10.0), &fixtures.join("nclt_16x12"))?;

    // A native rig holding one camera of every model.
    let pinhole = Pinhole::new(
        PinholeParams::ideal(64, 48, 50.0, 52.0, 31.5, 23.5).with_distortion(RadialTangential {
            k1: -0.1,
            k2: 0.01,
            p1: 1e-3,
            p2: -5e-4,
            k3: 0.0,
        }),
    )?;
    let fisheye = KannalaBrandt::new(KannalaBrandtParams {
        width: 64,
        height: 48,
        fx: 30.0,
        fy: 30.0,
        cx: 31.5,
        cy: 23.5,
        k1: -0.02,
        k2: 0.003,
        k3: 0.0,
        k4: 0.0,
    })?;
    let small_pano = Equirectangular::new(EquirectangularParams {
        width: 64,
        height: 32,
    })?;
    let lut = Lut::from_model(&fisheye, 4)?;
    let table = synth::radial_table_camera(16, 12, 10.0, -0.12, 0.02);
    let placements = synth::ladybug_placements(0.04, 0.06);
    let models = [
        Camera::from(pinhole),
        Camera::from(fisheye),
        Camera::from(small_pano),
        Camera::from(lut),
        Camera::from(table),
    ];
    let mixed = Rig::new(
        models
            .into_iter()
            .zip(placements)
            .map(|(model, rig_from_camera)| RigCamera {
                model,
                rig_from_camera,
            })
            .collect(),
    )?;
    native::write(&mixed, &fixtures.join("native_mixed.json"))?;
    println!("wrote {} and {}", out.display(), fixtures.display());
    Ok(())
}
