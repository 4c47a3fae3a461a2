//! `vgps simulate`: the written drive reads back, is deterministic, has the promised GPS
//! outages, and its detections agree with the truth.

mod common;

use common::vgps;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use vgps::drive::{Drive, Strictness};
use vgps::geo::{Geodetic, LocalFrame};

fn simulate_short(dir: &Path, seed: &str) {
    let out = vgps(&[
        "simulate",
        "--preset",
        "short",
        "--seed",
        seed,
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(" frames, 900 m, "), "{text}");
}

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

fn geodetic(row: &BTreeMap<String, String>) -> Geodetic {
    let f = |k: &str| row[k].parse::<f64>().unwrap();
    Geodetic::try_new(f("lat"), f("lon"), f("alt")).unwrap()
}

#[test]
fn short_drive_reads_back_and_is_deterministic() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    simulate_short(a.path(), "9");
    simulate_short(b.path(), "9");
    for name in [
        "drive.json",
        "calibration.json",
        "landmarks.csv",
        "frames.csv",
        "detections.csv",
        "gnss.nmea",
        "truth.csv",
        "world_landmarks.csv",
        "detections_truth.csv",
        "simulation.json",
    ] {
        let (x, y) = (
            std::fs::read(a.path().join(name)).unwrap(),
            std::fs::read(b.path().join(name)).unwrap(),
        );
        assert!(x == y, "{name} differs between two runs with the same seed");
    }
    let drive = Drive::open(a.path(), Strictness::Strict).unwrap();
    let s = drive.summary();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.path().join("simulation.json")).unwrap()).unwrap();
    assert_eq!(s.frames as u64, json["frames"].as_u64().unwrap());
    assert!((300..700).contains(&s.frames));
    let det = &json["detections"];
    assert_eq!(
        s.detections as u64,
        det["true"].as_u64().unwrap() + det["false"].as_u64().unwrap()
    );
    assert_eq!((s.bad_rows, s.truth), (0, s.frames));
    assert_eq!(drive.nmea_stats().unwrap().skipped(), 0);
    assert_eq!(s.gnss_fixes as u64, json["gnss"]["fixes"].as_u64().unwrap());
    // landmarks.csv is what `vgps locate` reads.
    let landmarks = vgps::io::read_landmarks(&a.path().join("landmarks.csv")).unwrap();
    assert_eq!(landmarks.len(), s.landmarks);
    let world = read_csv(&a.path().join("world_landmarks.csv"));
    assert_eq!(
        world.iter().filter(|r| r["surveyed"] == "true").count(),
        landmarks.len()
    );
    assert!(
        world.iter().any(|r| r["class"] == "corner")
            && world.iter().any(|r| r["class"] == "streetlight")
    );
}

#[test]
fn outages_and_reprojection_from_the_files() {
    let dir = tempfile::tempdir().unwrap();
    simulate_short(dir.path(), "4");
    let drive = Drive::open(dir.path(), Strictness::Strict).unwrap();
    let surveyed: BTreeSet<String> = drive.landmarks().iter().map(|l| l.id.clone()).collect();
    let world: BTreeMap<String, Geodetic> = read_csv(&dir.path().join("world_landmarks.csv"))
        .iter()
        .map(|r| (r["id"].clone(), geodetic(r)))
        .collect();
    let labels = read_csv(&dir.path().join("detections_truth.csv"));
    assert_eq!(labels.len(), drive.all_detections().len());

    // Distance driven, from the truth positions.
    let mut arc = vec![0.0];
    let origin = LocalFrame::new(drive.truth()[0].position);
    for w in drive.truth().windows(2) {
        let d = (origin.to_enu(&w[1].position) - origin.to_enu(&w[0].position)).norm();
        arc.push(arc.last().unwrap() + d);
    }
    let length = *arc.last().unwrap();
    let arc_at = |t: f64| {
        arc[drive
            .frames()
            .partition_point(|f| f.time_s < t)
            .min(arc.len() - 1)]
    };
    // Runs of epochs without a fix.
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut open = false;
    for r in drive.gnss() {
        if r.fix.is_none() {
            if open {
                runs.last_mut().unwrap().1 = r.time_s;
            } else {
                runs.push((r.time_s, r.time_s));
            }
        }
        open = r.fix.is_none();
    }
    let total: f64 = runs.iter().map(|&(a, b)| arc_at(b) - arc_at(a)).sum();
    assert!(total >= 0.15 * length, "outages {total} m of {length} m");
    // Surveyed landmarks detected per frame, from the truth labels.
    let mut per_frame: BTreeMap<u64, BTreeSet<&str>> = BTreeMap::new();
    for l in &labels {
        if surveyed.contains(&l["landmark"]) {
            per_frame
                .entry(l["frame"].parse().unwrap())
                .or_default()
                .insert(&l["landmark"]);
        }
    }
    let long_blind = runs.iter().any(|&(a, b)| {
        arc_at(b) - arc_at(a) >= 300.0
            && drive
                .frames()
                .iter()
                .filter(|f| f.time_s >= a && f.time_s <= b)
                .all(|f| per_frame.get(&f.frame).map_or(0, BTreeSet::len) < 3)
    });
    assert!(
        long_blind,
        "no outage of 300 m with fewer than 3 surveyed landmarks in view: {runs:?}"
    );

    // True detections reproject onto their landmarks within the pixel noise.
    let rig = drive.rig();
    let (mut sum2, mut n, mut false_count) = (0.0, 0.0, 0);
    for (d, l) in drive.all_detections().iter().zip(&labels) {
        assert_eq!(d.frame.to_string(), l["frame"]);
        let Some(p) = world.get(&l["landmark"]) else {
            assert_eq!(l["landmark"], "false");
            false_count += 1;
            continue;
        };
        let t = drive.truth_of(d.frame).unwrap();
        let point_in_rig = t.enu_from_rig.inverse() * LocalFrame::new(t.position).to_enu(p);
        let seen = rig.project_point(&point_in_rig);
        let pixel = seen
            .iter()
            .find(|s| s.camera == d.camera)
            .expect("the camera sees its landmark")
            .pixel;
        let r = (pixel - nalgebra::Vector2::new(d.u, d.v)).norm();
        assert!(r < 3.0, "frame {} camera {}: {r} px", d.frame, d.camera);
        sum2 += r * r;
        n += 2.0;
    }
    let rms = (sum2 / n).sqrt();
    assert!((rms - 0.5).abs() < 0.03, "per-axis rms {rms} px");
    let share = f64::from(false_count) / labels.len() as f64;
    assert!((share - 0.2).abs() < 0.03, "false share {share}");
}

#[test]
fn bad_arguments_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    for args in [
        vec!["simulate", "--out", d, "--night-scene", "bright"],
        vec!["simulate", "--out", d, "--origin", "91,0"],
        vec!["simulate", "--out", d, "--origin", "abc"],
        vec!["simulate", "--out", d, "--length-m", "-5"],
        vec!["simulate", "--out", d, "--calibration", "/nonexistent.json"],
    ] {
        let out = vgps(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn realistic_night_images_and_their_truth() {
    let dir = tempfile::tempdir().unwrap();
    let out = vgps(&[
        "simulate",
        "--preset",
        "short",
        "--length-m",
        "6",
        "--images",
        "--night-scene",
        "realistic",
        "--jpeg-quality",
        "90",
        "--quiet",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(" lit windows, "), "{text}");
    let truth = read_csv(&dir.path().join("images_truth.csv"));
    let kinds: BTreeSet<&str> = truth.iter().map(|r| r["kind"].as_str()).collect();
    assert!(
        kinds.contains("lamp") && kinds.contains("window"),
        "{kinds:?}"
    );
    assert!(!kinds.contains("clutter") && !kinds.contains("transient"));
    let frames = read_csv(&dir.path().join("frames.csv"));
    assert!(frames[0]["image_0"].ends_with(".jpg"), "{:?}", frames[0]);
}
