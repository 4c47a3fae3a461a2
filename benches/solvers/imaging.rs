//! The image pipeline on one full Ladybug2 frame (6 × 1024×768 night images with street lamps
//! and clutter): PNG decode, lamp detection, and both; plus rendering and PNG encoding of
//! one image.
use criterion::{Criterion, Throughput};
use std::hint::black_box;
use vgps::imaging::{DecodeLimits, LampDetector, RenderOptions, Renderer, decode_png, encode_png};
use vgps::synthetic::calibration_files::ladybug2_rig;
use vgps::synthetic::night::{StreetConfig, lights_in_camera, street_lamps};

/// Benchmarks of `vgps::imaging`.
pub fn benches(c: &mut Criterion) {
    let rig = ladybug2_rig();
    let renderer = Renderer::new(RenderOptions {
        clutter_lights: 6,
        ..RenderOptions::default()
    });
    let mut rng = vgps::synthetic::rng(5);
    let lamps = street_lamps(&mut rng, &StreetConfig::default());
    let lights: Vec<_> = rig
        .cameras()
        .iter()
        .map(|c| lights_in_camera(c, &lamps))
        .collect();
    let images: Vec<_> = rig
        .cameras()
        .iter()
        .zip(&lights)
        .enumerate()
        .map(|(k, (c, l))| renderer.render(&c.model, l, k as u64).image)
        .collect();
    let pngs: Vec<Vec<u8>> = images.iter().map(|i| encode_png(i).unwrap()).collect();
    let limits = DecodeLimits::default();
    let detector = LampDetector::default();

    let mut group = c.benchmark_group("imaging/frame6");
    group.throughput(Throughput::Elements(1));
    group.bench_function("decode", |b| {
        b.iter(|| {
            for png in &pngs {
                black_box(decode_png(black_box(png), &limits).unwrap());
            }
        })
    });
    group.bench_function("detect", |b| {
        b.iter(|| {
            for image in &images {
                black_box(detector.detect(black_box(image), None).unwrap());
            }
        })
    });
    group.bench_function("decode_detect", |b| {
        b.iter(|| {
            for png in &pngs {
                let image = decode_png(black_box(png), &limits).unwrap();
                black_box(detector.detect(&image, None).unwrap());
            }
        })
    });
    group.finish();

    let camera = &rig.cameras()[0].model;
    let mut seed = 0;
    c.bench_function("imaging/render_one", |b| {
        b.iter(|| {
            seed += 1;
            renderer.render(black_box(camera), black_box(&lights[0]), seed)
        })
    });
    c.bench_function("imaging/encode_png_one", |b| {
        b.iter(|| encode_png(black_box(&images[0])).unwrap())
    });
}

/// The vertex (building-corner) detector on one full Ladybug2 frame by day: six 1024×768
/// images of the `short` preset's frame 10 rendered by the day renderer and encoded as
/// JPEG at quality 90 (as `vgps simulate --time-of-day day --jpeg-quality 90` writes
/// them), detected with the camera models as `vgps detect --detector vertex` does: JPEG
/// decode, detection, and both.
pub fn day_benches(c: &mut Criterion) {
    use vgps::imaging::{VertexDetector, decode_image};
    use vgps::simulate::images::encode_image;
    use vgps::simulate::{Preset, Scenario, simulate};
    use vgps_sim::day::{DayOptions, DayRenderer, DayScene, sun_position};

    let sc = Scenario::preset(Preset::Short, 1);
    let drive = simulate(&sc).unwrap();
    let scene = DayScene::from_world(&drive.world, sc.block_m, sc.seed);
    let renderer = DayRenderer::new(DayOptions::default(), &sc.rig);
    let f = &drive.frames[10.min(drive.frames.len() - 1)];
    let sun = sun_position(f.time_s, sc.origin.lat_deg, sc.origin.lon_deg).direction_in_enu();
    let jpegs: Vec<Vec<u8>> = (0..sc.rig.len())
        .map(|k| {
            let frame = renderer
                .render(&scene, &f.world_from_rig, k, &sun, f.frame * 7 + k as u64)
                .unwrap();
            encode_image(&frame.image, Some(90)).unwrap()
        })
        .collect();
    let limits = DecodeLimits::default();
    let images: Vec<_> = jpegs
        .iter()
        .map(|j| decode_image(j, &limits).unwrap())
        .collect();
    let models: Vec<_> = sc.rig.cameras().iter().map(|c| c.model.clone()).collect();
    let detector = VertexDetector::default();

    let mut group = c.benchmark_group("imaging/frame6_day");
    group.throughput(Throughput::Elements(1));
    group.bench_function("decode", |b| {
        b.iter(|| {
            for jpeg in &jpegs {
                black_box(decode_image(black_box(jpeg), &limits).unwrap());
            }
        })
    });
    group.bench_function("vertex", |b| {
        b.iter(|| {
            for (image, model) in images.iter().zip(&models) {
                black_box(detector.detect(black_box(image), Some(model), None));
            }
        })
    });
    group.bench_function("decode_vertex", |b| {
        b.iter(|| {
            for (jpeg, model) in jpegs.iter().zip(&models) {
                let image = decode_image(black_box(jpeg), &limits).unwrap();
                black_box(detector.detect(&image, Some(model), None));
            }
        })
    });
    group.finish();
}
