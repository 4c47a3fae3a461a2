//! Accuracy and speed of the vertex detector on rendered day frames.
//!
//! `cargo run --release -p vgps-sim --example day_corners -- [FRAMES] [SEED] [JPEG_QUALITY]`
//!
//! Renders FRAMES frames (default 6) spread over the `short` preset by day, runs
//! [`VertexDetector`] on each image clean (the 8-bit render) and after JPEG at
//! JPEG_QUALITY (default 90), with and without the camera model, and prints, for the visible
//! corner landmarks away from the border: the share found within 3 px, the median and p95
//! error (px) of the nearest detection, detections per image, and the milliseconds per
//! 6-camera frame of rendering, of JPEG decoding and of detection (one thread).

use std::time::Instant;
use vgps_camera::imaging::{DecodeLimits, VertexDetection, VertexDetector, decode_image};
use vgps_sim::day::{DayOptions, DayRenderer, DayScene, sun_position};
use vgps_sim::simulate::images::encode_image;
use vgps_sim::simulate::{Preset, Scenario, simulate};

/// A truth corner matches a detection within this distance (pixels).
const MATCH_PX: f64 = 3.0;

#[derive(Default)]
struct Tally {
    errors: Vec<f64>,
    truths: usize,
    detections: usize,
    images: usize,
    seconds: f64,
}

impl Tally {
    fn add(&mut self, found: &[VertexDetection], truth: &[(f64, f64)], seconds: f64) {
        self.images += 1;
        self.detections += found.len();
        self.seconds += seconds;
        for &(u, v) in truth {
            self.truths += 1;
            let best = found
                .iter()
                .map(|d| (d.u - u).hypot(d.v - v))
                .fold(f64::INFINITY, f64::min);
            if best <= MATCH_PX {
                self.errors.push(best);
            }
        }
    }

    fn print(&mut self, name: &str, frames: usize) {
        self.errors.sort_by(f64::total_cmp);
        let q = |p: f64| {
            self.errors
                .get(((self.errors.len() as f64 - 1.0) * p).round() as usize)
                .copied()
                .unwrap_or(f64::NAN)
        };
        println!(
            "{name:<28} found {:>4}/{:<4} ({:5.1} %)  median {:.3} px  p95 {:.3} px  {:6.1} detections/image  {:7.1} ms/frame",
            self.errors.len(),
            self.truths,
            100.0 * self.errors.len() as f64 / self.truths.max(1) as f64,
            q(0.5),
            q(0.95),
            self.detections as f64 / self.images.max(1) as f64,
            1e3 * self.seconds / frames.max(1) as f64
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: u64| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let frames = arg(1, 6) as usize;
    let seed = arg(2, 1);
    let quality = arg(3, 90).clamp(1, 100) as u8;
    let sc = Scenario::preset(Preset::Short, seed);
    let drive = simulate(&sc).expect("the short preset simulates");
    let scene = DayScene::from_world(&drive.world, sc.block_m, sc.seed);
    let started = Instant::now();
    let renderer = DayRenderer::new(DayOptions::default(), &sc.rig);
    println!(
        "renderer set-up (bearing tables of {} cameras): {:.0} ms",
        sc.rig.len(),
        1e3 * started.elapsed().as_secs_f64()
    );
    let detector = VertexDetector::default();
    let (mut render_s, mut decode_s) = (0.0, 0.0);
    let mut tallies: Vec<(String, Tally)> = [
        "clean, image plane",
        "clean, rectified (camera)",
        "JPEG, image plane",
        "JPEG, rectified (camera)",
    ]
    .iter()
    .map(|n| (n.to_string(), Tally::default()))
    .collect();
    let step = (drive.frames.len() / frames.max(1)).max(1);
    let mut used = 0;
    for f in drive.frames.iter().step_by(step).take(frames) {
        used += 1;
        let sun = sun_position(f.time_s, sc.origin.lat_deg, sc.origin.lon_deg).direction_in_enu();
        for (k, camera) in sc.rig.cameras().iter().enumerate() {
            let t = Instant::now();
            let Some(frame) =
                renderer.render(&scene, &f.world_from_rig, k, &sun, f.frame * 7 + k as u64)
            else {
                continue;
            };
            render_s += t.elapsed().as_secs_f64();
            let truth: Vec<(f64, f64)> = frame
                .corners
                .iter()
                .filter(|c| !c.near_border)
                .map(|c| (c.u, c.v))
                .collect();
            let bytes = encode_image(&frame.image, Some(quality)).expect("JPEG encodes");
            let t = Instant::now();
            let jpeg = decode_image(&bytes, &DecodeLimits::default()).expect("JPEG decodes");
            decode_s += t.elapsed().as_secs_f64();
            for (i, (image, cam)) in [
                (&frame.image, None),
                (&frame.image, Some(&camera.model)),
                (&jpeg, None),
                (&jpeg, Some(&camera.model)),
            ]
            .into_iter()
            .enumerate()
            {
                let t = Instant::now();
                let found = detector.detect(image, cam, None);
                let s = t.elapsed().as_secs_f64();
                tallies[i].1.add(&found, &truth, s);
            }
        }
    }
    println!(
        "{used} frames of {} cameras: render {:.0} ms/frame, JPEG {quality} decode {:.1} ms/frame",
        sc.rig.len(),
        1e3 * render_s / used.max(1) as f64,
        1e3 * decode_s / used.max(1) as f64
    );
    for (name, t) in &mut tallies {
        t.print(name, used);
    }
}
