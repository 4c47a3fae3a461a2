//! What becomes of the visible truth corners of a day drive in the vertex detector.
//!
//! `cargo run --release -p vgps-camera --example vertex_reasons -- DRIVE [STEP] [MAX_RANGE_M]`
//!
//! DRIVE is a folder written by `vgps simulate --images --time-of-day day` (with
//! `calibration.json`, `frames.csv` and `images_truth.csv`). For every STEP-th frame (default
//! 3) and each unclipped truth corner within MAX_RANGE_M (default 80 m, the matcher's
//! visibility range), prints a tally of: found (a detection within 3 px), or the fate of
//! the nearest candidate within 3 px (its `Rejection`), or no candidate within 3 px.
//! With a fourth argument OUT.csv it writes instead the detections of those frames as a
//! detections CSV (`VERTEX_MIN_EXTENT_PX`, `VERTEX_MIN_RESPONSE` and
//! `VERTEX_MIN_OPEN_SIDE_DN` set those fields of `VertexConfig`).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use vgps_camera::calibration::load;
use vgps_camera::imaging::{DecodeLimits, Mask, VertexCandidate, VertexDetector, read_image};

/// A truth corner: `(u, v, range_m)`.
type TruthCorner = (f64, f64, f64);

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(drive) = args.get(1).map(Path::new) else {
        eprintln!("usage: vertex_reasons DRIVE [STEP] [MAX_RANGE_M]");
        std::process::exit(2);
    };
    let step: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(3).max(1);
    let max_range: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(80.0);
    let rig = load(&drive.join("calibration.json"), None, None).expect("calibration");
    let frames = std::fs::read_to_string(drive.join("frames.csv")).expect("frames.csv");
    let truth = std::fs::read_to_string(drive.join("images_truth.csv")).expect("truth");
    let corners = truth_corners(&truth, step, max_range);
    let mut detector = VertexDetector::default();
    let c = &mut detector.config;
    env_override("VERTEX_MIN_EXTENT_PX", &mut c.min_edge_extent_px);
    env_override("VERTEX_MIN_RESPONSE", &mut c.min_response);
    env_override("VERTEX_MIN_OPEN_SIDE_DN", &mut c.min_open_side_dn);
    env_override("VERTEX_MIN_ANGLE_DEG", &mut c.min_angle_deg);
    env_override("VERTEX_MIN_PEAK_SHARE", &mut c.min_peak_share);
    env_override("VERTEX_MAX_CANDIDATES", &mut c.max_candidates);
    // VERTEX_TABLE=PATH: one row per truth corner with its nearest candidate (any
    // response: run with a low VERTEX_MIN_RESPONSE to see the ones below the default),
    // the local contrast (p95 − p5 of the 15 × 15 px around it) and its fate.
    // The response a candidate needs to count as found in the table (default 40, the
    // detector's default threshold).
    let found_response: f32 = std::env::var("VERTEX_FOUND_RESPONSE")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(40.0);
    let mut table = std::env::var("VERTEX_TABLE").ok().map(|p| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(p).expect("table file"));
        writeln!(
            f,
            "frame,camera,u,v,range_m,cand_dist,response,outcome,contrast,p5,p95,found,error_px"
        )
        .expect("write");
        f
    });
    let mut out = args.get(4).map(|p| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(p).expect("output file"));
        writeln!(f, "frame,camera,u,v,strength,class").expect("write");
        f
    });
    let masks: Vec<Option<Mask>> = (0..rig.len())
        .map(|k| rig.mask(k).map(Mask::from_camera_mask))
        .collect();
    let mut tally: BTreeMap<String, usize> = BTreeMap::new();
    let mut by_range: BTreeMap<(u32, String), usize> = BTreeMap::new();
    for line in frames.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let Ok(frame) = f[0].parse::<usize>() else {
            continue;
        };
        if frame % step != 0 {
            continue;
        }
        for cam in 0..rig.len() {
            let none = Vec::new();
            let truths = corners.get(&(frame, cam)).unwrap_or(&none);
            if truths.is_empty() && out.is_none() {
                continue;
            }
            let image =
                read_image(&drive.join(f[2 + cam]), &DecodeLimits::default()).expect("image");
            let model = &rig.cameras()[cam].model;
            if let Some(f) = out.as_mut() {
                for d in detector.detect(&image, Some(model), masks[cam].as_ref()) {
                    writeln!(f, "{frame},{cam},{},{},{},corner", d.u, d.v, d.strength)
                        .expect("write");
                }
            }
            if out.is_some() {
                continue;
            }
            let explained = detector.explain(&image, Some(model), masks[cam].as_ref());
            if let Some(t) = table.as_mut() {
                write_table_rows(t, &image, &explained, truths, (frame, cam), found_response);
            }
            for &(u, v, r) in truths {
                let found = explained.iter().any(|c| {
                    c.outcome.as_ref().is_ok_and(|d| {
                        c.rank < detector.config.max_candidates && (d.u - u).hypot(d.v - v) <= 3.0
                    })
                });
                let reason = if found {
                    "found".to_string()
                } else {
                    let near = nearest_within_3px(&explained, u, v);
                    match near {
                        None => "no candidate within 3 px".to_string(),
                        Some(c) => match c.outcome {
                            Ok(_) => "candidate's corner > 3 px off".to_string(),
                            Err(e) => format!("{e:?}"),
                        },
                    }
                };
                eprintln!("{frame},{cam},{u},{v},{r},{reason}");
                *by_range
                    .entry(((r / 20.0) as u32 * 20, reason.clone()))
                    .or_default() += 1;
                *tally.entry(reason).or_default() += 1;
            }
        }
    }
    let total: usize = tally.values().sum();
    println!("{total} truth corners within {max_range} m, every {step}th frame");
    for (k, n) in &tally {
        println!(
            "{n:6} ({:5.1} %)  {k}",
            100.0 * *n as f64 / total.max(1) as f64
        );
    }
    println!("by range bucket (m):");
    for ((b, k), n) in &by_range {
        println!("{b:4} {n:6}  {k}");
    }
}

/// The unclipped truth corners of every `step`-th frame within `max_range` m, by
/// `(frame, camera)`, from the text of `images_truth.csv`.
fn truth_corners(
    truth: &str,
    step: usize,
    max_range: f64,
) -> BTreeMap<(usize, usize), Vec<TruthCorner>> {
    let mut corners: BTreeMap<(usize, usize), Vec<TruthCorner>> = BTreeMap::new();
    for line in truth.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() < 9 || f[2] != "corner" || f[8] == "true" {
            continue;
        }
        let (Ok(frame), Ok(cam), Ok(u), Ok(v), Ok(r)) = (
            f[0].parse(),
            f[1].parse(),
            f[4].parse(),
            f[5].parse(),
            f[6].parse::<f64>(),
        ) else {
            continue;
        };
        if frame % step == 0 && r <= max_range {
            corners.entry((frame, cam)).or_default().push((u, v, r));
        }
    }
    corners
}

/// One row of the `VERTEX_TABLE` per truth corner: its nearest candidate, the local
/// contrast (p95 − p5 of the 15 × 15 px around it) and its fate.
fn write_table_rows(
    t: &mut impl Write,
    image: &image::GrayImage,
    explained: &[VertexCandidate],
    truths: &[TruthCorner],
    (frame, cam): (usize, usize),
    found_response: f32,
) {
    for &(u, v, r) in truths {
        let near = nearest_within_3px(explained, u, v);
        let mut vals = Vec::new();
        for dv in -7i64..=7 {
            for du in -7i64..=7 {
                let (x, y) = (u.round() as i64 + du, v.round() as i64 + dv);
                if x >= 0 && y >= 0 && x < image.width() as i64 && y < image.height() as i64 {
                    vals.push(image.get_pixel(x as u32, y as u32).0[0]);
                }
            }
        }
        vals.sort_unstable();
        let (p5, p95) = if vals.is_empty() {
            (0, 0)
        } else {
            (vals[vals.len() / 20], vals[vals.len() * 19 / 20])
        };
        let (dist, resp, outcome) = match near {
            None => (f64::NAN, f32::NAN, "none".to_string()),
            Some(c) => (
                (c.u as f64 - u).hypot(c.v as f64 - v),
                c.response,
                match c.outcome {
                    Ok(d) if (d.u - u).hypot(d.v - v) <= 3.0 => "found".to_string(),
                    Ok(_) => "off".to_string(),
                    Err(e) => format!("{e:?}"),
                },
            ),
        };
        let error = explained
            .iter()
            .filter(|c| c.response >= found_response)
            .filter_map(|c| c.outcome.as_ref().ok())
            .map(|d| (d.u - u).hypot(d.v - v))
            .fold(f64::INFINITY, f64::min);
        let found = error <= 3.0;
        writeln!(
            t,
            "{frame},{cam},{u},{v},{r},{dist},{resp},{outcome},{},{p5},{p95},{found},{error}",
            i32::from(p95) - i32::from(p5)
        )
        .expect("write");
    }
}

/// Sets `value` from the environment variable `name` when it is set and parses.
fn env_override<T: std::str::FromStr>(name: &str, value: &mut T) {
    if let Some(x) = std::env::var(name).ok().and_then(|x| x.parse().ok()) {
        *value = x;
    }
}

/// The candidate nearest to `(u, v)` within 3 px, if any.
fn nearest_within_3px(explained: &[VertexCandidate], u: f64, v: f64) -> Option<&VertexCandidate> {
    let distance = |c: &VertexCandidate| (c.u as f64 - u).hypot(c.v as f64 - v);
    explained
        .iter()
        .filter(|c| distance(c) <= 3.0)
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
}
