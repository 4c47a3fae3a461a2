//! Camera models: pixel → bearing per call, bearing → pixel, and building the LUTs of a
//! Ladybug2-like 6 × 1024×768 rig.
use criterion::{Criterion, Throughput};
use nalgebra::Vector2;
use rand::RngExt;
use std::hint::black_box;
use std::time::Duration;
use vgps::calibration::{Camera, CameraModel, Lut, Pinhole};
use vgps::synthetic::calibration::{
    EXAMPLE_LUT_STEP, ladybug_placements, ladybug2_pinhole, opencv_fisheye, panorama,
};

/// Number of distinct random pixels cycled through by the per-call benchmarks.
const PIXELS: usize = 1024;

fn random_pixels(camera: &Camera, seed: u64) -> Vec<Vector2<f64>> {
    let mut rng = vgps::synthetic::rng(seed);
    let (w, h) = camera.image_size();
    (0..PIXELS)
        .map(|_| {
            Vector2::new(
                rng.random_range(-0.5..f64::from(w) - 0.5),
                rng.random_range(-0.5..f64::from(h) - 0.5),
            )
        })
        .collect()
}

/// Benchmarks of the camera models.
pub fn benches(c: &mut Criterion) {
    let ladybug = ladybug2_pinhole();
    let ideal = Pinhole::new(ladybug.params().with_distortion(Default::default()))
        .unwrap_or_else(|e| unreachable!("{e}"));
    let lut = Lut::from_model(&ladybug, EXAMPLE_LUT_STEP).unwrap_or_else(|e| unreachable!("{e}"));
    let cameras: Vec<(&str, Camera)> = vec![
        ("pinhole_ideal", ideal.into()),
        ("pinhole_distorted", ladybug.clone().into()),
        ("kannala_brandt", opencv_fisheye().into()),
        ("equirectangular", panorama().into()),
        ("lut", lut.into()),
    ];
    // The real Ladybug5+ `.conf` (tests/data/ladybug5p, MIT): camera 0's raw image through
    // its B-spline warps, and the LUT `vgps calib convert --to lut` makes of it (step 4).
    let conf = vgps::calibration::formats::ladybug_conf::read_conf(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/ladybug5p/ladybug5p.conf"
        )
        .as_ref(),
    )
    .unwrap_or_else(|e| unreachable!("{e}"));
    let raw = conf
        .raw_model(&conf.cameras[0])
        .unwrap_or_else(|e| unreachable!("{e}"));
    let raw_lut = Lut::from_model(&raw, 4).unwrap_or_else(|e| unreachable!("{e}"));
    let mut cameras = cameras;
    cameras.push(("ladybug5p_conf_raw", raw.into()));
    cameras.push(("ladybug5p_conf_lut", raw_lut.into()));
    let mut group = c.benchmark_group("calibration");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(50);
    for (name, camera) in &cameras {
        let pixels = random_pixels(camera, 21);
        let mut i = 0;
        group.bench_function(format!("bearing/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % PIXELS;
                camera.try_bearing(black_box(&pixels[i]))
            })
        });
    }
    for (name, camera) in &cameras {
        let bearings: Vec<_> = random_pixels(camera, 22)
            .iter()
            .filter_map(|p| camera.try_bearing(p))
            .collect();
        let mut i = 0;
        group.bench_function(format!("pixel/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % bearings.len();
                camera.try_pixel(black_box(&bearings[i]))
            })
        });
    }
    let rig_models: Vec<Camera> = ladybug_placements()
        .iter()
        .map(|_| Camera::from(ladybug.clone()))
        .collect();
    group.sample_size(10);
    group.bench_function("lut_build/ladybug_rig_6x1024x768", |b| {
        b.iter(|| {
            rig_models
                .iter()
                .map(|m| Lut::from_model(black_box(m), EXAMPLE_LUT_STEP))
                .collect::<Result<Vec<_>, _>>()
        })
    });
    // The same pixels through one `bearings_into` call per batch of PIXELS: criterion's
    // time / PIXELS is the time per pixel (last: the throughput setting stays).
    group.sample_size(50);
    for (name, camera) in cameras.iter().filter(|(name, _)| name.ends_with("lut")) {
        let pixels = random_pixels(camera, 21);
        let mut out = vec![None; PIXELS];
        group.throughput(Throughput::Elements(PIXELS as u64));
        group.bench_function(format!("bearings_into_{PIXELS}/{name}"), |b| {
            b.iter(|| camera.bearings_into(black_box(&pixels), &mut out))
        });
    }
    group.finish();
}
