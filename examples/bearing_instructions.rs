//! Deterministic cost figure for a camera model's pixel → bearing (`try_bearing`) of the
//! LUT, the equirectangular panorama or the pinhole: runs it through the `Camera` enum in one non-inlined wrapper so that an instruction counter can
//! attribute every instruction of the call to it.
//!
//! Usage (instructions per call = inclusive Ir of `solve` / N):
//! ```text
//! cargo build --release --example bearing_instructions
//! valgrind --tool=callgrind --toggle-collect='*bearing_instructions::solve*' \
//!     target/release/examples/bearing_instructions 20000 1 lut
//! ```
//! Arguments: `[N] [SEED] [lut|equirectangular|pinhole] [batch]` (defaults 20000, 1, lut).
//! With `batch`, the N pixels go through one non-inlined `CameraModel::bearings_into` call
//! (`solve_batch`; instructions per pixel = its inclusive Ir / N) instead of N calls. The LUT
//! is built from the Ladybug2-like pinhole of `vgps::synthetic::calibration` at
//! `EXAMPLE_LUT_STEP`; the panorama is its 2048×1024 example; pixels are uniform over the
//! image rectangle, as in the `calibration/bearing/*` benchmarks.
use nalgebra::{Vector2, Vector3};
use rand::RngExt;
use std::hint::black_box;
use vgps::calibration::{Camera, CameraModel, Lut};
use vgps::synthetic::calibration::{EXAMPLE_LUT_STEP, ladybug2_pinhole, panorama};
use vgps::synthetic::rng;

/// One pixel → bearing, never inlined: the unit the instruction counter measures.
#[inline(never)]
fn solve(camera: &Camera, pixel: &Vector2<f64>) -> Option<Vector3<f64>> {
    black_box(camera).try_bearing(black_box(pixel))
}

/// All pixels → bearings in one batched call, never inlined.
#[inline(never)]
fn solve_batch(
    camera: &Camera,
    pixels: &[Vector2<f64>],
    out: &mut [Option<Vector3<f64>>],
) -> usize {
    black_box(camera).bearings_into(black_box(pixels), out)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let camera = match args.get(3).map(String::as_str).unwrap_or("lut") {
        "equirectangular" => Camera::from(panorama()),
        "pinhole" => Camera::from(ladybug2_pinhole()),
        _ => Camera::from(
            Lut::from_model(&ladybug2_pinhole(), EXAMPLE_LUT_STEP)
                .unwrap_or_else(|e| unreachable!("{e}")),
        ),
    };
    let (w, h) = camera.image_size();
    let mut r = rng(seed);
    let pixels: Vec<Vector2<f64>> = (0..n)
        .map(|_| {
            Vector2::new(
                r.random_range(-0.5..f64::from(w) - 0.5),
                r.random_range(-0.5..f64::from(h) - 0.5),
            )
        })
        .collect();
    let mut sum = Vector3::zeros();
    let mut found = 0usize;
    if args.get(4).map(String::as_str) == Some("batch") {
        let mut out = vec![None; n];
        solve_batch(&camera, &pixels, &mut out);
        for b in out.iter().flatten() {
            sum += b;
            found += 1;
        }
    } else {
        for p in &pixels {
            if let Some(b) = solve(&camera, p) {
                sum += b;
                found += 1;
            }
        }
    }
    println!("calls={n} found={found} sum={:.6?}", sum.as_slice());
}
