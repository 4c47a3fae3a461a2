//! Times decoding and the vertex (building-corner) detector per 6-camera frame of a day
//! drive, for the peer comparison `bench/peers/day_corners_opencv.py` (the criterion
//! benchmark `imaging/frame6_day` is the reference figure).
//!
//! Usage: `cargo run --release --example vertex_timing -- DRIVE FRAMES [REPEATS] [OUT.csv]`.
//! The image files of the first FRAMES frames are read into memory before timing; each
//! frame is decoded and detected REPEATS times (default 3) on this one thread, with the
//! camera models and masks that `vgps detect --detector vertex` uses. Prints one line per
//! frame `frame=<n> decode_ms=<best> detect_ms=<best> decode_detect_ms=<best>` (the best
//! of the repeats: the least disturbed by other processes), then a summary line with the
//! medians over frames. With OUT.csv, writes the detections as `frame,camera,u,v,strength`.
use std::hint::black_box;
use std::io::Write;
use std::path::Path;
use std::time::Instant;
use vgps::drive::{Drive, Strictness};
use vgps::imaging::{DecodeLimits, DetectorKind, ImageDetector, decode_image};

/// One frame's images in memory: `(camera, bytes)`.
type FrameFiles = (u64, Vec<(usize, Vec<u8>)>);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: vertex_timing DRIVE FRAMES [REPEATS] [OUT.csv]";
    let dir = Path::new(args.first().ok_or(usage)?);
    let frames: usize = args.get(1).ok_or(usage)?.parse()?;
    let repeats: usize = args.get(2).map_or(Ok(3), |s| s.parse())?;
    let drive = Drive::open(dir, Strictness::Lenient)?;
    let detector = ImageDetector::new(DetectorKind::Vertex, drive.rig());
    let limits = DecodeLimits::default();
    let mut files: Vec<FrameFiles> = Vec::new();
    for record in drive.frames().iter().take(frames) {
        let mut images = Vec::new();
        for (camera, name) in record.images.iter().enumerate() {
            if let Some(name) = name {
                images.push((camera, std::fs::read(dir.join(name))?));
            }
        }
        files.push((record.frame, images));
    }
    let mut rows = String::from("frame,camera,u,v,strength\n");
    let (mut decode, mut detect, mut both) = (Vec::new(), Vec::new(), Vec::new());
    for (frame, images) in &files {
        let (mut best_decode, mut best_detect) = (f64::INFINITY, f64::INFINITY);
        let mut best_both = f64::INFINITY;
        for _ in 0..repeats.max(1) {
            let (mut t_decode, mut t_detect) = (0.0, 0.0);
            for (camera, bytes) in images {
                let t = Instant::now();
                let image = decode_image(black_box(bytes), &limits)?;
                t_decode += t.elapsed().as_secs_f64();
                let t = Instant::now();
                black_box(detector.detect(*camera, black_box(&image))?);
                t_detect += t.elapsed().as_secs_f64();
            }
            best_decode = best_decode.min(t_decode);
            best_detect = best_detect.min(t_detect);
            best_both = best_both.min(t_decode + t_detect);
        }
        println!(
            "frame={frame} decode_ms={:.3} detect_ms={:.3} decode_detect_ms={:.3}",
            best_decode * 1e3,
            best_detect * 1e3,
            best_both * 1e3
        );
        decode.push(best_decode * 1e3);
        detect.push(best_detect * 1e3);
        both.push(best_both * 1e3);
        for (camera, bytes) in images {
            let image = decode_image(bytes, &limits)?;
            for (u, v, s) in detector.detect(*camera, &image)? {
                rows.push_str(&format!("{frame},{camera},{u},{v},{s}\n"));
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "vgps frames={} decode_ms={:.3} detect_ms={:.3} decode_detect_ms={:.3}",
        files.len(),
        median(&mut decode),
        median(&mut detect),
        median(&mut both)
    );
    if let Some(out) = args.get(3) {
        std::fs::File::create(out)?.write_all(rows.as_bytes())?;
    }
    Ok(())
}
