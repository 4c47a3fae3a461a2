//! The night-street lamp detector (`vgps::imaging::StreetLampDetector`): the labelled real
//! photo, known answers on constructed scenes (one detection per bloomed lamp, windows,
//! reflections, ghosts, vehicle pairs, light trails) and invariants.
use image::{GrayImage, Luma};
use std::path::Path;
use vgps::imaging::{DecodeLimits, LampClass, StreetLampDetector, read_image};

/// A dark street with mild texture (≤ 30 DN).
fn street(w: u32, h: u32) -> GrayImage {
    GrayImage::from_fn(w, h, |x, y| Luma([((x * 7 + y * 13) % 11 + 10) as u8]))
}

/// Adds a lamp: a saturated disc of `radius` px with a Gaussian halo (σ = 2·radius, peak
/// 160 DN) clipped at 255.
fn add_lamp(image: &mut GrayImage, u: f64, v: f64, radius: f64) {
    let reach = (8.0 * radius).ceil() as i64;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let (x, y) = (u.round() as i64 + dx, v.round() as i64 + dy);
            if x < 0 || y < 0 || x >= image.width() as i64 || y >= image.height() as i64 {
                continue;
            }
            let d = (x as f64 - u).hypot(y as f64 - v);
            let p = image.get_pixel_mut(x as u32, y as u32);
            let halo = 160.0 * (-(d * d) / (8.0 * radius * radius)).exp();
            let value = if d <= radius {
                255.0
            } else {
                f64::from(p[0]) + halo
            };
            p[0] = value.min(255.0).max(f64::from(p[0])) as u8;
        }
    }
}

fn fill(image: &mut GrayImage, u0: u32, v0: u32, u1: u32, v1: u32, value: u8) {
    for y in v0..=v1 {
        for x in u0..=u1 {
            image.put_pixel(x, y, Luma([value]));
        }
    }
}

#[test]
fn labelled_real_photo_meets_recall_and_precision() {
    let image = read_image(
        Path::new("tests/data/night/unsplash_street_lamps.jpg"),
        &DecodeLimits::default(),
    )
    .expect("decode");
    let labels = std::fs::read_to_string("tests/data/night/unsplash_labels.csv").expect("labels");
    let lamps: Vec<(f64, f64, f64, bool)> = labels
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[1].parse().expect("u"),
                f[2].parse().expect("v"),
                f[3].parse().expect("r"),
                f[4] == "1",
            )
        })
        .collect();
    assert_eq!(lamps.len(), 13);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    let reach = |r: f64| (1.5 * r).max(3.0);
    let certain = lamps.iter().filter(|l| l.3).count();
    let hit = lamps
        .iter()
        .filter(|l| l.3)
        .filter(|l| {
            found
                .lamps
                .iter()
                .any(|d| (d.u - l.0).hypot(d.v - l.1) <= reach(l.2))
        })
        .count();
    let on_certain = found
        .lamps
        .iter()
        .filter(|d| {
            lamps
                .iter()
                .any(|l| l.3 && (d.u - l.0).hypot(d.v - l.1) <= reach(l.2))
        })
        .count();
    let on_uncertain = found
        .lamps
        .iter()
        .filter(|d| {
            lamps
                .iter()
                .any(|l| !l.3 && (d.u - l.0).hypot(d.v - l.1) <= reach(l.2))
        })
        .count();
    let counted = found.lamps.len() - on_uncertain;
    // Recall ≥ 90 %, precision ≥ 80 % (the issue's targets); 12/12 and 12/14 today.
    assert!(10 * hit >= 9 * certain, "recall {hit}/{certain}");
    assert!(
        10 * on_certain >= 8 * counted,
        "precision {on_certain}/{counted}: {:?}",
        found.lamps
    );
    // The star-burst lamps give one detection each: no labelled lamp has two.
    for l in &lamps {
        let n = found
            .lamps
            .iter()
            .filter(|d| (d.u - l.0).hypot(d.v - l.1) <= reach(l.2))
            .count();
        assert!(n <= 1, "{n} detections on the lamp at ({}, {})", l.0, l.1);
    }
    // The centroid of the largest lamp lies on its labelled core.
    let big = found
        .lamps
        .iter()
        .find(|d| (d.u - 141.9).hypot(d.v - 933.9) <= 33.0)
        .expect("the large lamp");
    assert!((big.u - 141.9).hypot(big.v - 933.9) < 5.0, "{big:?}");
}

#[test]
fn one_detection_per_bloomed_lamp_at_its_core() {
    let mut image = street(200, 150);
    add_lamp(&mut image, 60.3, 40.6, 4.0);
    add_lamp(&mut image, 140.0, 50.0, 2.0);
    // Star-burst spikes: saturated rays from the first lamp's core, broken into fragments.
    for k in 5..14 {
        if k % 3 != 0 {
            image.put_pixel(60 + k, 41, Luma([255]));
            image.put_pixel(60 - k, 41, Luma([255]));
        }
    }
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 2, "{:?}", found.lamps);
    let a = found.lamps.iter().find(|d| d.u < 100.0).expect("first");
    assert!(
        (a.u - 60.3).abs() < 0.5 && (a.v - 40.6).abs() < 0.5,
        "{a:?}"
    );
    let b = found.lamps.iter().find(|d| d.u > 100.0).expect("second");
    assert!(
        (b.u - 140.0).abs() < 0.3 && (b.v - 50.0).abs() < 0.3,
        "{b:?}"
    );
    assert!(a.strength > b.strength && b.strength > 0.0);
    assert!(found.lamps.iter().all(|d| d.class == LampClass::Lamp));
}

#[test]
fn two_close_lamps_with_sky_between_stay_two() {
    let mut image = street(120, 80);
    add_lamp(&mut image, 50.0, 40.0, 2.0);
    add_lamp(&mut image, 62.0, 40.0, 3.0);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 2, "{:?}", found.lamps);
}

#[test]
fn lit_window_grid_is_labelled_windows() {
    let mut image = street(240, 160);
    // A 3 × 4 grid of lit windows (8 × 6 px) on a dark facade.
    for row in 0..3 {
        for col in 0..4 {
            let (u0, v0) = (20 + col * 16, 20 + row * 14);
            fill(&mut image, u0, v0, u0 + 7, v0 + 5, 250);
        }
    }
    add_lamp(&mut image, 180.0, 40.0, 3.0);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 1, "{:?}", found.lamps);
    assert!((found.lamps[0].u - 180.0).abs() < 0.3);
    let windows = found
        .others
        .iter()
        .filter(|d| d.class == LampClass::Window)
        .count();
    assert_eq!(windows, 12, "{:?}", found.others);
}

#[test]
fn road_reflection_below_a_lamp_is_labelled() {
    let mut image = street(160, 200);
    add_lamp(&mut image, 80.0, 40.0, 4.0);
    // A vertical streak on the wet road below the lamp, 3 px wide and 24 px tall.
    fill(&mut image, 79, 140, 81, 163, 245);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 1, "{:?}", found.lamps);
    assert_eq!(found.others.len(), 1, "{:?}", found.others);
    assert_eq!(found.others[0].class, LampClass::Reflection);
}

#[test]
fn lens_ghost_opposite_a_bright_lamp_is_labelled() {
    let (w, h) = (200u32, 150u32);
    let mut image = street(w, h);
    add_lamp(&mut image, 40.0, 30.0, 6.0);
    // Point reflection of (40, 30) about the centre (99.5, 74.5): (159, 119); a faint core.
    fill(&mut image, 158, 118, 159, 119, 240);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 1, "{:?}", found.lamps);
    assert_eq!(found.others.len(), 1, "{:?}", found.others);
    assert_eq!(found.others[0].class, LampClass::Ghost);
    // The same faint core is a lamp when no bright lamp faces it.
    let mut alone = street(w, h);
    add_lamp(&mut alone, 40.0, 120.0, 6.0);
    fill(&mut alone, 158, 118, 159, 119, 240);
    let found = StreetLampDetector::default()
        .detect(&alone)
        .expect("detect");
    assert_eq!(found.lamps.len(), 2, "{:?}", found);
}

#[test]
fn vehicle_pair_below_the_horizon_is_labelled() {
    let mut image = street(240, 160);
    add_lamp(&mut image, 100.0, 120.0, 2.0);
    add_lamp(&mut image, 118.0, 120.0, 2.0);
    add_lamp(&mut image, 60.0, 30.0, 3.0);
    let with_horizon = StreetLampDetector {
        horizon_v: Some(80.0),
        ..StreetLampDetector::default()
    };
    let found = with_horizon.detect(&image).expect("detect");
    assert_eq!(found.lamps.len(), 1, "{:?}", found);
    assert!((found.lamps[0].v - 30.0).abs() < 0.3);
    assert_eq!(
        found
            .others
            .iter()
            .filter(|d| d.class == LampClass::Vehicle)
            .count(),
        2
    );
    // Without a horizon nothing is called a vehicle.
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert_eq!(found.lamps.len(), 3);
}

#[test]
fn light_trails_and_bright_facades_are_not_lamps() {
    let mut image = street(200, 120);
    // A light trail: 80 × 3 px saturated streak.
    fill(&mut image, 20, 90, 99, 92, 255);
    // A lit facade: 60 × 40 px at 200 DN with a brighter 2 × 2 spot (low local contrast).
    fill(&mut image, 120, 10, 179, 49, 200);
    fill(&mut image, 150, 30, 151, 31, 250);
    let found = StreetLampDetector::default()
        .detect(&image)
        .expect("detect");
    assert!(found.lamps.is_empty(), "{:?}", found.lamps);
    assert!(found.rejected >= 2);
}

#[test]
fn mirrored_image_gives_mirrored_detections() {
    let image = read_image(
        Path::new("tests/data/night/unsplash_street_lamps.jpg"),
        &DecodeLimits::default(),
    )
    .expect("decode");
    let mirrored = image::imageops::flip_horizontal(&image);
    let detector = StreetLampDetector::default();
    let a = detector.detect(&image).expect("detect");
    let b = detector.detect(&mirrored).expect("detect");
    assert_eq!(a.lamps.len(), b.lamps.len());
    let w = f64::from(image.width()) - 1.0;
    for d in &a.lamps {
        let closest = b
            .lamps
            .iter()
            .map(|e| (w - e.u - d.u).hypot(e.v - d.v))
            .fold(f64::INFINITY, f64::min);
        assert!(closest < 1e-6, "{d:?}: {closest}");
    }
}

#[test]
fn empty_flat_and_tiny_images() {
    let detector = StreetLampDetector::default();
    for image in [
        GrayImage::new(0, 0),
        GrayImage::new(1, 1),
        GrayImage::from_pixel(50, 40, Luma([255])),
        GrayImage::from_pixel(50, 40, Luma([0])),
    ] {
        let found = detector.detect(&image).expect("detect");
        assert!(found.lamps.len() <= 1, "{:?}", found.lamps);
    }
    // A white frame is one saturated blob with no background around it: not a lamp.
    let white = detector
        .detect(&GrayImage::from_pixel(50, 40, Luma([255])))
        .expect("detect");
    assert!(white.lamps.is_empty());
}
