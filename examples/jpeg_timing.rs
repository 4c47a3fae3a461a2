//! JPEG decoding and night-street detection speed on rig frames (6 × 1024×768 colour JPEGs).
//!
//! Usage: `cargo run --release --example jpeg_timing -- DIR [FRAMES] [REPEATS]`
//! (defaults 5 frames, 7 repeats). Renders FRAMES Ladybug2-rig night frames (street lamps
//! and 6 clutter lights per image, the renderer's grey replicated to RGB) as JPEG quality 90
//! with 4:2:0 chroma (the `image` crate's encoder) into `DIR/frameNNNN_camC.jpg` — kept
//! for `bench/peers/jpeg_peers.py` — then, single-threaded, on every `*.jpg` of DIR:
//! - `zune_luma`: `vgps::imaging::decode_image` (zune-jpeg, luma output: the Y plane only);
//! - `zune_rgb`: zune-jpeg to RGB, then Rec. 601 luma (what a colour decode costs);
//! - `image_crate`: `image`'s `JpegDecoder` → `DynamicImage` → Rec. 601 luma;
//! - `detect`: `StreetLampDetector::detect` on the decoded frame;
//! - `decode_detect`: `decode_image` + `StreetLampDetector::detect`.
//!
//! Each figure is the per-image median over images of the best of REPEATS runs (ms);
//! `frames_per_s` = 1000 / (6 × median decode_detect), one core. With FRAMES 0 nothing is
//! rendered and the JPEGs already in DIR are timed, e.g. a Ladybug5 drive's
//! (`vgps simulate --preset short --length-m 6 --images --night-scene realistic
//! --jpeg-quality 90 --calibration calibration/ladybug5_example.ini --out D`, then
//! `jpeg_timing D/images 0 5`: 6 × 2448×2048 per frame).
use image::ImageDecoder;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;
use vgps::imaging::formats::to_luma8;
use vgps::imaging::{DecodeLimits, RenderOptions, Renderer, StreetLampDetector, decode_image};
use vgps::synthetic::calibration_files::ladybug2_rig;
use vgps::synthetic::night::{StreetConfig, lights_in_camera, street_lamps};

fn render(dir: &std::path::Path, frames: usize) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let rig = ladybug2_rig();
    let renderer = Renderer::new(RenderOptions {
        clutter_lights: 6,
        ..RenderOptions::default()
    });
    let mut rng = vgps::synthetic::rng(1);
    for frame in 0..frames {
        let lamps = street_lamps(&mut rng, &StreetConfig::default());
        for (c, camera) in rig.cameras().iter().enumerate() {
            let lights = lights_in_camera(camera, &lamps);
            let grey = renderer
                .render(&camera.model, &lights, (frame * 8 + c) as u64)
                .image;
            let rgb = image::RgbImage::from_fn(grey.width(), grey.height(), |x, y| {
                let g = grey.get_pixel(x, y)[0];
                image::Rgb([g, g, g])
            });
            let mut bytes = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
                .encode_image(&rgb)?;
            std::fs::write(dir.join(format!("frame{frame:04}_cam{c}.jpg")), bytes)?;
        }
    }
    Ok(())
}

fn zune_rgb(bytes: &[u8]) -> Result<image::GrayImage, Box<dyn std::error::Error>> {
    use zune_jpeg::zune_core::{bytestream::ZCursor, colorspace::ColorSpace, options::*};
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
    let mut d = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let pixels = d.decode().map_err(|e| format!("{e}"))?;
    let (w, h) = d.dimensions().ok_or("no size")?;
    let rgb = image::RgbImage::from_raw(w as u32, h as u32, pixels).ok_or("size")?;
    Ok(to_luma8(&rgb.into()))
}

fn image_crate(bytes: &[u8]) -> Result<image::GrayImage, Box<dyn std::error::Error>> {
    let d = image::codecs::jpeg::JpegDecoder::new(std::io::Cursor::new(bytes))?;
    let _ = d.dimensions();
    Ok(to_luma8(&image::DynamicImage::from_decoder(d)?))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(
        args.first()
            .ok_or("usage: jpeg_timing DIR [FRAMES] [REPEATS]")?,
    );
    let frames: usize = args.get(1).map_or(Ok(5), |s| s.parse())?;
    let repeats: usize = args.get(2).map_or(Ok(7), |s| s.parse())?;
    render(&dir, frames)?;
    let mut paths: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    paths.sort();
    let files: Vec<Vec<u8>> = paths.iter().map(std::fs::read).collect::<Result<_, _>>()?;
    let limits = DecodeLimits::default();
    let detector = StreetLampDetector::default();
    let mut t: [Vec<f64>; 5] = Default::default();
    let mut detections = 0usize;
    let best = |f: &mut dyn FnMut() -> Result<(), Box<dyn std::error::Error>>| -> Result<f64, Box<dyn std::error::Error>> {
        let mut b = f64::INFINITY;
        for _ in 0..repeats.max(1) {
            let s = Instant::now();
            f()?;
            b = b.min(s.elapsed().as_secs_f64() * 1e3);
        }
        Ok(b)
    };
    for bytes in &files {
        let image = decode_image(bytes, &limits)?;
        detections += detector.detect(&image)?.lamps.len();
        t[0].push(best(&mut || {
            black_box(decode_image(black_box(bytes), &limits)?);
            Ok(())
        })?);
        t[1].push(best(&mut || {
            black_box(zune_rgb(black_box(bytes))?);
            Ok(())
        })?);
        t[2].push(best(&mut || {
            black_box(image_crate(black_box(bytes))?);
            Ok(())
        })?);
        t[3].push(best(&mut || {
            black_box(detector.detect(black_box(&image))?);
            Ok(())
        })?);
        t[4].push(best(&mut || {
            let image = decode_image(black_box(bytes), &limits)?;
            black_box(detector.detect(&image)?);
            Ok(())
        })?);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let m: Vec<f64> = t.iter_mut().map(median).collect();
    println!(
        "vgps images={} zune_luma_ms={:.3} zune_rgb_ms={:.3} image_crate_ms={:.3} detect_ms={:.3} \
         decode_detect_ms={:.3} frames_per_s={:.1} detections_per_image={:.2}",
        files.len(),
        m[0],
        m[1],
        m[2],
        m[3],
        m[4],
        1000.0 / (6.0 * m[4]),
        detections as f64 / files.len().max(1) as f64
    );
    Ok(())
}
