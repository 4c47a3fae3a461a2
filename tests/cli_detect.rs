//! The image pipeline from the command line: `vgps simulate --images` → `vgps detect` →
//! `vgps replay --from-images`, with bad images reported per frame and counted.

mod common;

use common::vgps;
use std::collections::BTreeMap;
use std::path::Path;

fn read_csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

fn num(row: &BTreeMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap()
}

fn ok(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Copies the first `n` frames of a drive (frames, truth, images) into `to`, without the
/// simulator's detections.
fn trimmed_copy(from: &Path, to: &Path, n: usize) {
    std::fs::create_dir_all(to.join("images")).unwrap();
    for name in ["calibration.json", "landmarks.csv", "gnss.nmea"] {
        std::fs::copy(from.join(name), to.join(name)).unwrap();
    }
    for name in ["frames.csv", "truth.csv"] {
        let text = std::fs::read_to_string(from.join(name)).unwrap();
        let kept: Vec<&str> = text.lines().take(n + 1).collect();
        std::fs::write(to.join(name), kept.join("\n") + "\n").unwrap();
    }
    for row in read_csv(&to.join("frames.csv")) {
        for k in 0..6 {
            let image = &row[&format!("image_{k}")];
            std::fs::copy(from.join(image), to.join(image)).unwrap();
        }
    }
    std::fs::write(
        to.join("drive.json"),
        r#"{"version": 1, "calibration": "calibration.json", "landmarks": "landmarks.csv",
            "frames": "frames.csv", "gnss": "gnss.nmea", "truth": "truth.csv"}"#,
    )
    .unwrap();
}

#[test]
fn simulate_images_detect_and_replay() {
    let tmp = tempfile::tempdir().unwrap();
    let drive = tmp.path().join("drive");
    let d = drive.to_str().unwrap();
    let text = ok(&vgps(&[
        "simulate",
        "--preset",
        "short",
        "--length-m",
        "150",
        "--images",
        "--quiet",
        "--threads",
        "2",
        "--out",
        d,
    ]));
    assert!(text.contains(" images, "), "{text}");
    let frames = read_csv(&drive.join("frames.csv"));
    assert!(frames.len() > 50);
    for row in &frames {
        for k in 0..6 {
            assert!(drive.join(&row[&format!("image_{k}")]).is_file());
        }
    }

    // The simulator's detections.csv is kept: the detector writes detections_detected.csv.
    let before = std::fs::read(drive.join("detections.csv")).unwrap();
    let out = vgps(&["detect", d, "--threads", "2"]);
    let summary = ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("detections_detected.csv"));
    assert_eq!(std::fs::read(drive.join("detections.csv")).unwrap(), before);
    assert!(
        summary.contains(&format!("{} frames, ", frames.len())),
        "{summary}"
    );
    let detected = read_csv(&drive.join("detections_detected.csv"));
    let mut by_image: BTreeMap<(String, String), Vec<(f64, f64)>> = BTreeMap::new();
    for r in &detected {
        by_image
            .entry((r["frame"].clone(), r["camera"].clone()))
            .or_default()
            .push((num(r, "u"), num(r, "v")));
    }

    // Recall and accuracy on the lamps the simulator says are in range and in view.
    let mut errors = Vec::new();
    let mut lamps = 0;
    for r in read_csv(&drive.join("detections_truth.csv")) {
        if !r["landmark"].starts_with('L') {
            continue; // corners are not lights, transient lights are not lamps
        }
        lamps += 1;
        let (u, v) = (num(&r, "u_true"), num(&r, "v_true"));
        let nearest = by_image
            .get(&(r["frame"].clone(), r["camera"].clone()))
            .into_iter()
            .flatten()
            .map(|(a, b)| (a - u).hypot(b - v))
            .fold(f64::INFINITY, f64::min);
        if nearest < 2.0 {
            errors.push(nearest);
        }
    }
    errors.sort_by(f64::total_cmp);
    let recall = errors.len() as f64 / lamps as f64;
    let median = errors[errors.len() / 2];
    println!("lamps {lamps}, recall {recall:.4}, median error {median:.4} px");
    assert!(lamps > 500, "{lamps} lamps");
    assert!(recall >= 0.95, "recall {recall}");
    assert!(median < 0.1, "median error {median} px");

    // Replay from the images of a 20-frame copy (the localizer runs, one report per frame).
    let short = tmp.path().join("short");
    trimmed_copy(&drive, &short, 20);
    let report = tmp.path().join("report");
    let json = ok(&vgps(&[
        "replay",
        short.to_str().unwrap(),
        "--from-images",
        "--threads",
        "2",
        "--quiet",
        "--format",
        "json",
        "--out",
        report.to_str().unwrap(),
    ]));
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(value["frames"], 20, "{json}");
    // The first 20 frames are in the route's surveyed lead-in: lamps alone, found in the
    // pixels, fix them (before the lead-in, the survey gap's zone covered this whole drive
    // and no frame after the first had a fix).
    assert!(value["visual_fixes"].as_u64().unwrap_or(0) >= 19, "{json}");
    assert!(!json.contains("bad_image"), "{json}");
    assert!(report.join("report.json").is_file());

    // The whole drive (87 frames: two batches) on one thread and, pipelined, on three (the
    // second batch's images detected while the first is localized): the same fixes, and the
    // time per frame of each stage reported.
    let mut fixes = Vec::new();
    for threads in ["1", "3"] {
        let out_dir = tmp.path().join(format!("replay{threads}"));
        let out = vgps(&[
            "replay",
            d,
            "--from-images",
            "--threads",
            threads,
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        ok(&out);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("ms per frame of thread time") && stderr.contains("localizer "),
            "{stderr}"
        );
        // One thread: the localizer is all serial; more: its serial part and the wait for
        // the searches run ahead.
        let localizer_line = if threads == "1" {
            "(serial: one thread, frames in order)".to_string()
        } else {
            format!("searches run ahead on {threads} threads")
        };
        assert!(stderr.contains(&localizer_line), "{stderr}");
        assert_eq!(
            stderr.contains("the next batch's while this one is localized"),
            threads != "1",
            "{stderr}"
        );
        fixes.push(std::fs::read(out_dir.join("fixes.csv")).unwrap());
    }
    assert!(fixes[0] == fixes[1], "fixes differ between 1 and 3 threads");

    // A truncated PNG, a missing PNG and a wrong-size PNG: reported, counted, not fatal.
    let image = |k: usize, cam: usize| short.join(&frames[k][&format!("image_{cam}")]);
    let bytes = std::fs::read(image(2, 1)).unwrap();
    std::fs::write(image(2, 1), &bytes[..bytes.len() / 2]).unwrap();
    std::fs::remove_file(image(5, 3)).unwrap();
    let small = vgps::imaging::encode_png(&image::GrayImage::new(64, 48)).unwrap();
    std::fs::write(image(7, 0), small).unwrap();
    let out_csv = tmp.path().join("det.csv");
    let out = vgps(&[
        "detect",
        short.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
    ]);
    let summary = ok(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    for k in [2, 5, 7] {
        assert!(
            stderr.contains(&format!("frame {}: ", frames[k]["frame"])),
            "{stderr}"
        );
    }
    assert!(
        summary.contains("3 frame(s) with an unusable image, 0 without any usable image"),
        "{summary}"
    );
    assert!(
        summary.contains("unusable images: missing 1, unreadable 1, wrong_size 1"),
        "{summary}"
    );
    let rows = read_csv(&out_csv);
    assert!(rows.iter().any(|r| r["frame"] == frames[2]["frame"]));

    // A drive whose frames name no image is unusable for detection: exit 2.
    std::fs::write(short.join("frames.csv"), "frame,time_s\n0,1778794200\n").unwrap();
    std::fs::write(short.join("truth.csv"), "frame,lat,lon,alt,qw,qx,qy,qz\n").unwrap();
    let out = vgps(&["detect", short.to_str().unwrap()]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A tiny drive rendered by day: `detect --detector vertex` writes building corners, all of
/// class `corner` (the class of the corner landmarks, so the matcher pairs them only with
/// corners), and finds rendered corners to within a pixel.
#[test]
fn detect_vertex_on_a_tiny_day_drive_writes_corners() {
    let tmp = tempfile::tempdir().unwrap();
    let drive = tmp.path().join("day");
    let d = drive.to_str().unwrap();
    ok(&vgps(&[
        "simulate",
        "--preset",
        "short",
        "--length-m",
        "3",
        "--images",
        "--time-of-day",
        "day",
        "--quiet",
        "--threads",
        "2",
        "--out",
        d,
    ]));
    let out = drive.join("corners.csv");
    let summary = ok(&vgps(&[
        "detect",
        d,
        "--detector",
        "vertex",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(summary.contains(" detections "), "{summary}");
    let rows = read_csv(&out);
    assert!(!rows.is_empty());
    assert!(rows.iter().all(|r| r["class"] == "corner"), "{rows:?}");
    let truth: Vec<_> = read_csv(&drive.join("images_truth.csv"))
        .into_iter()
        .filter(|r| r["kind"] == "corner" && r["clipped"] == "false")
        .collect();
    assert!(!truth.is_empty());
    let within_a_pixel = truth
        .iter()
        .filter(|t| {
            rows.iter().any(|r| {
                r["frame"] == t["frame"]
                    && r["camera"] == t["camera"]
                    && (num(r, "u") - num(t, "u")).hypot(num(r, "v") - num(t, "v")) < 1.0
            })
        })
        .count();
    assert!(
        within_a_pixel * 5 >= truth.len(),
        "{within_a_pixel} of {} visible corners found within 1 px",
        truth.len()
    );
}
