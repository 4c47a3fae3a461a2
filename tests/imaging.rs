//! Accuracy, recall and precision of the lamp detector on rendered Ladybug2 night frames, and
//! the decoder's robustness on hostile files.

use vgps::imaging::{
    CentroidWeight, DecodeLimits, Detections, DetectorConfig, ImagingError, LampDetector,
    RenderOptions, RenderedSpot, Renderer, SpotKind, decode_png, encode_png,
};
use vgps::synthetic::calibration_files::ladybug2_rig;
use vgps::synthetic::night::{StreetConfig, lights_in_camera, street_lamps};

/// Lamps within this range (metres) must be found.
const MAX_RANGE_M: f64 = 80.0;

/// A detection matches a spot within this distance (pixels) or two blob sigmas.
const MATCH_RADIUS_PX: f64 = 3.0;

/// Two spots closer than this many summed sigmas (plus a margin) are crowded (their blobs
/// merge): excluded from the accuracy statistics.
const CROWDING_SIGMAS: f64 = 4.0;
const CROWDING_MARGIN_PX: f64 = 4.0;

#[derive(Default, Debug)]
struct Stats {
    eligible: usize,
    found: usize,
    errors: Vec<f64>,
    detections: usize,
    matched_lamp: usize,
    matched_any: usize,
}

fn evaluate(spots: &[RenderedSpot], found: &Detections, stats: &mut Stats) {
    let crowded = |i: usize| {
        let a = &spots[i];
        spots.iter().enumerate().any(|(j, b)| {
            j != i
                && ((a.u - b.u).powi(2) + (a.v - b.v).powi(2)).sqrt()
                    < CROWDING_SIGMAS * (a.sigma_major_px + b.sigma_major_px) + CROWDING_MARGIN_PX
        })
    };
    let near = |d: &vgps::imaging::LampDetection, s: &RenderedSpot| {
        let e = ((d.u - s.u).powi(2) + (d.v - s.v).powi(2)).sqrt();
        (e <= MATCH_RADIUS_PX.max(2.0 * s.sigma_major_px)).then_some(e)
    };
    for (i, s) in spots.iter().enumerate() {
        let in_range = s.range_m.is_some_and(|r| r <= MAX_RANGE_M);
        let eligible = matches!(s.kind, SpotKind::Lamp(_)) && in_range && !s.clipped_by_border;
        if !eligible || crowded(i) {
            continue;
        }
        stats.eligible += 1;
        let best = found
            .lamps
            .iter()
            .filter_map(|d| near(d, s))
            .min_by(f64::total_cmp);
        if let Some(e) = best {
            stats.found += 1;
            stats.errors.push(e);
        }
    }
    for d in &found.lamps {
        stats.detections += 1;
        let lamp = spots
            .iter()
            .any(|s| matches!(s.kind, SpotKind::Lamp(_)) && near(d, s).is_some());
        let any = spots.iter().any(|s| near(d, s).is_some());
        stats.matched_lamp += usize::from(lamp);
        stats.matched_any += usize::from(any);
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run(detector: &LampDetector) -> Stats {
    let rig = ladybug2_rig();
    let renderer = Renderer::new(RenderOptions {
        clutter_lights: 6,
        ..RenderOptions::default()
    });
    let mut rng = vgps::synthetic::rng(2024);
    let mut stats = Stats::default();
    for frame in 0..16u64 {
        let lamps = street_lamps(&mut rng, &StreetConfig::default());
        for (c, camera) in rig.cameras().iter().enumerate() {
            let lights = lights_in_camera(camera, &lamps);
            let rendered = renderer.render(&camera.model, &lights, frame * 16 + c as u64);
            let found = detector.detect(&rendered.image, None).unwrap();
            evaluate(&rendered.spots, &found, &mut stats);
        }
    }
    stats
}

fn summary(label: &str, mut stats: Stats) -> (f64, f64, f64) {
    let recall = stats.found as f64 / stats.eligible as f64;
    let med = median(&mut stats.errors);
    let p95 = stats.errors[stats.errors.len() * 95 / 100];
    let precision_any = stats.matched_any as f64 / stats.detections as f64;
    let precision_lamp = stats.matched_lamp as f64 / stats.detections as f64;
    println!(
        "{label}: eligible lamps {}, recall {:.4}, median error {:.4} px, p95 {:.4} px, detections {}, \
         precision (lamp or clutter) {:.4}, precision (lamps only) {:.4}",
        stats.eligible, recall, med, p95, stats.detections, precision_any, precision_lamp
    );
    assert!(stats.eligible > 300, "{} eligible lamps", stats.eligible);
    (recall, med, precision_any)
}

#[test]
fn detector_accuracy_recall_and_precision_on_rendered_street_scenes() {
    // 16 frames × 6 cameras, 40 lamps per frame and 6 clutter lights per image.
    let (recall, med, precision_any) =
        summary("threshold-subtracted", run(&LampDetector::default()));
    assert!(recall >= 0.98, "recall {recall}");
    assert!(med <= 0.1, "median centroid error {med} px");
    assert!(
        precision_any >= 0.99,
        "precision against lamps or clutter {precision_any}"
    );
    // The background-subtracted weight also meets the target, with a larger error.
    let background = LampDetector::new(DetectorConfig {
        centroid_weight: CentroidWeight::BackgroundSubtracted,
        ..DetectorConfig::default()
    });
    let (recall_b, med_b, _) = summary("background-subtracted", run(&background));
    assert_eq!(recall_b, recall);
    assert!(
        med_b <= 0.1 && med_b >= med,
        "median centroid error {med_b} px vs {med} px"
    );
}

#[test]
fn decoder_rejects_hostile_files_with_typed_errors() {
    let rig = ladybug2_rig();
    let camera = &rig.cameras()[0].model;
    let frame = Renderer::new(RenderOptions::default()).render(camera, &[], 1);
    let bytes = encode_png(&frame.image).unwrap();
    let limits = DecodeLimits::for_camera(camera);
    assert_eq!(decode_png(&bytes, &limits).unwrap(), frame.image);
    // Truncated.
    assert!(matches!(
        decode_png(&bytes[..bytes.len() / 3], &limits),
        Err(ImagingError::Decode { .. })
    ));
    // Not a PNG.
    assert!(matches!(
        decode_png(b"\xff\xd8\xff\xe0 JFIF", &limits),
        Err(ImagingError::NotPng { .. })
    ));
    // Huge header.
    let mut huge = bytes.clone();
    huge[16..20].copy_from_slice(&1_000_000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&1_000_000u32.to_be_bytes());
    assert!(matches!(
        decode_png(&huge, &DecodeLimits::default()),
        Err(ImagingError::TooLarge { .. })
    ));
    // Wrong dimensions (a smaller frame passes the limits, fails the calibration check).
    let small = encode_png(&image::GrayImage::new(640, 480)).unwrap();
    let decoded = decode_png(&small, &limits).unwrap();
    let e = vgps::imaging::check_dimensions(&decoded, camera, std::path::Path::new("cam0.png"));
    assert!(matches!(
        e,
        Err(ImagingError::WrongDimensions {
            width: 640,
            height: 480,
            ..
        })
    ));
}
