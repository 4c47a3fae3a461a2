//! The vertex (building-corner) detector on real daytime photos (issue #26, part 5).
//!
//! `cargo run --release -p vgps-camera --example day_real -- OUT IMAGE… [--png]`
//!
//! For each IMAGE (JPEG, PNG, TIFF or BMP; colour is converted to the detector's luminance)
//! runs [`VertexDetector`] with its default configuration in the image plane (no camera
//! model: these photos come without a calibration), prints one line (size, corners found,
//! detection time, the strength quartiles) and writes `OUT/<image stem>.jpg`: the
//! luminance, scaled to at most 1,024 px wide, with every corner drawn as a red circle
//! and the fitted edges' count as its radius (two edges: small, three: large).
//!
//! With `--png` the pictures are written as PNG instead.
//!
//! Then, over all images, what became of the detector's candidates (the Shi–Tomasi
//! response maxima, [`VertexDetector::explain`]): corners kept, or the [`Rejection`] that
//! stopped them — where real photos differ from the simulator's. `VERTEX_MAX_CANDIDATES`
//! and `VERTEX_MIN_OPEN_SIDE_DN` set those fields of the configuration.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vgps_camera::imaging::{DecodeLimits, Rejection, VertexDetection, VertexDetector, read_image};

/// Largest width of the pictures written (pixels).
const MAX_WIDTH: u32 = 1024;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().ok_or("usage: day_real OUT IMAGE… [--png]")?);
    let (mut images, mut extension) = (Vec::new(), "jpg");
    for a in args {
        if a == "--png" {
            extension = "png";
        } else {
            images.push(PathBuf::from(a));
        }
    }
    let mut outcomes: BTreeMap<Option<Rejection>, usize> = BTreeMap::new();
    std::fs::create_dir_all(&out)?;
    let mut detector = VertexDetector::default();
    if let Some(n) = env_override("VERTEX_MAX_CANDIDATES") {
        detector.config.max_candidates = n;
    }
    if let Some(dn) = env_override("VERTEX_MIN_OPEN_SIDE_DN") {
        detector.config.min_open_side_dn = dn;
    }
    let limits = DecodeLimits::default();
    println!("image, width x height, corners, ms, strength p25/p50/p75");
    for path in &images {
        let image = read_image(path, &limits)?;
        let t = std::time::Instant::now();
        let corners = detector.detect(&image, None, None);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let name = file_name(path);
        let mut strengths: Vec<f64> = corners.iter().map(|c| c.strength).collect();
        strengths.sort_by(f64::total_cmp);
        let q = |p: f64| {
            strengths
                .get((p * strengths.len() as f64) as usize)
                .copied()
        };
        println!(
            "{name}, {}x{}, {}, {ms:.0}, {:.0}/{:.0}/{:.0}",
            image.width(),
            image.height(),
            corners.len(),
            q(0.25).unwrap_or(f64::NAN),
            q(0.5).unwrap_or(f64::NAN),
            q(0.75).unwrap_or(f64::NAN)
        );
        for candidate in detector.explain(&image, None, None) {
            *outcomes.entry(candidate.outcome.err()).or_default() += 1;
        }
        let stem = path
            .file_stem()
            .map_or("image".into(), |s| s.to_string_lossy());
        draw(&image, &corners).save(out.join(format!("{stem}.{extension}")))?;
    }
    let total: usize = outcomes.values().sum();
    println!("candidates of all images: {total}");
    for (outcome, n) in &outcomes {
        let share = 100.0 * *n as f64 / total.max(1) as f64;
        match outcome {
            None => println!("  corner (kept before duplicates): {n} ({share:.1} %)"),
            Some(r) => println!("  {r:?}: {n} ({share:.1} %)"),
        }
    }
    Ok(())
}

/// The value of the environment variable `name`, if set and parsable.
fn env_override<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The luminance as colour, scaled to at most [`MAX_WIDTH`], with the corners drawn as red
/// circles.
fn draw(image: &image::GrayImage, corners: &[VertexDetection]) -> image::RgbImage {
    let scale = (f64::from(MAX_WIDTH) / f64::from(image.width())).min(1.0);
    let (w, h) = (
        (f64::from(image.width()) * scale).round() as u32,
        (f64::from(image.height()) * scale).round() as u32,
    );
    let grey = image::imageops::resize(image, w, h, image::imageops::FilterType::Triangle);
    let mut rgb = image::RgbImage::from_fn(w, h, |x, y| {
        let g = grey.get_pixel(x, y)[0];
        image::Rgb([g, g, g])
    });
    let mut put = |x: f64, y: f64, colour: [u8; 3]| {
        let (x, y) = (x.round(), y.round());
        if x >= 0.0 && y >= 0.0 && x < f64::from(w) && y < f64::from(h) {
            rgb.put_pixel(x as u32, y as u32, image::Rgb(colour));
        }
    };
    for c in corners {
        let radius = if c.edges >= 3 { 7.0 } else { 4.0 };
        for k in 0..48 {
            let a = f64::from(k) * std::f64::consts::TAU / 48.0;
            put(
                c.u * scale + radius * a.cos(),
                c.v * scale + radius * a.sin(),
                [255, 40, 40],
            );
        }
    }
    rgb
}
