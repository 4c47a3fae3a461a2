//! Times PNG decoding and lamp detection on every `*.png` of a directory, for the peer
//! comparison `bench/peers/detect_peers.py` (the criterion benchmark `imaging` is the
//! reference figure).
//!
//! Usage: `cargo run --release --example detect_timing -- DIR [REPEATS]` (default 5).
//! Files are read into memory before timing. Prints one line
//! `vgps images=<N> decode_ms=<median> detect_ms=<median> decode_detect_ms=<median>
//! detections_per_image=<mean>`, the medians over images of the best of REPEATS runs.
use std::hint::black_box;
use std::time::Instant;
use vgps::imaging::{DecodeLimits, LampDetector, decode_png};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args.first().ok_or("usage: detect_timing DIR [REPEATS]")?;
    let repeats: usize = args.get(1).map_or(Ok(5), |s| s.parse())?;
    let mut paths: Vec<_> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    paths.sort();
    let files: Vec<Vec<u8>> = paths.iter().map(std::fs::read).collect::<Result<_, _>>()?;
    let limits = DecodeLimits::default();
    let detector = LampDetector::default();
    let (mut decode, mut detect, mut both) = (Vec::new(), Vec::new(), Vec::new());
    let mut detections = 0usize;
    for bytes in &files {
        let (mut best_decode, mut best_detect, mut best_both) =
            (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for _ in 0..repeats.max(1) {
            let t = Instant::now();
            let image = decode_png(black_box(bytes), &limits)?;
            let t_decode = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let found = detector.detect(black_box(&image), None)?;
            let t_detect = t.elapsed().as_secs_f64();
            black_box(&found);
            best_decode = best_decode.min(t_decode);
            best_detect = best_detect.min(t_detect);
            best_both = best_both.min(t_decode + t_detect);
        }
        let image = decode_png(bytes, &limits)?;
        detections += detector.detect(&image, None)?.lamps.len();
        decode.push(best_decode * 1e3);
        detect.push(best_detect * 1e3);
        both.push(best_both * 1e3);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "vgps images={} decode_ms={:.4} detect_ms={:.4} decode_detect_ms={:.4} detections_per_image={:.2}",
        files.len(),
        median(&mut decode),
        median(&mut detect),
        median(&mut both),
        detections as f64 / files.len().max(1) as f64
    );
    Ok(())
}
