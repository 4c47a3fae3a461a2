//! End-to-end tests of `vgps locate` on observations without landmark ids (the landmark
//! matcher): a matched frame, an ambiguous street, too few detections and a prior outside the
//! landmark region. The small fixture files are written to a temporary directory from a
//! fixed-seed layout.

use nalgebra::Vector3;
use rand::RngExt;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::synthetic::{random_unit_vector, rng};

mod common;
use common::vgps;

fn local() -> LocalFrame {
    LocalFrame::new(Geodetic::try_new(47.3769, 8.5417, 408.0).unwrap())
}

fn write_landmarks(path: &Path, points: &[Vector3<f64>]) {
    let mut text = "id,lat,lon,alt,sigma_m\n".to_string();
    for (k, p) in points.iter().enumerate() {
        let g = local().try_to_geodetic(p).unwrap();
        writeln!(
            text,
            "L{k},{:.10},{:.10},{:.4},0.0",
            g.lat_deg, g.lon_deg, g.alt_m
        )
        .unwrap();
    }
    std::fs::write(path, text).unwrap();
}

/// Observation rows (no landmark column) of `frame`: bearings to `points` and to `stray`.
fn rows(frame: u64, pose: &Pose, points: &[Vector3<f64>], stray: &[Vector3<f64>]) -> String {
    let mut text = String::new();
    for b in points
        .iter()
        .map(|p| bearing_in_rig(pose, p).unwrap())
        .chain(stray.iter().copied())
    {
        writeln!(text, "{frame},{:.10},{:.10},{:.10}", b.x, b.y, b.z).unwrap();
    }
    text
}

fn prior_arg(p: &Vector3<f64>, radius: f64) -> String {
    let g = local().try_to_geodetic(p).unwrap();
    format!(
        "{:.10},{:.10},{:.3},{radius}",
        g.lat_deg, g.lon_deg, g.alt_m
    )
}

fn run(landmarks: &Path, observations: &Path, extra: &[&str]) -> (Option<i32>, Vec<Value>) {
    let mut args = vec![
        "locate",
        "--landmarks",
        landmarks.to_str().unwrap(),
        "--observations",
        observations.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = vgps(&args);
    let lines = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    (out.status.code(), lines)
}

/// Irregular landmarks (a plaza), the rig near the origin, 10 seen and 2 stray lights.
fn plaza(dir: &Path) -> (PathBuf, PathBuf, Pose, Vec<usize>) {
    plaza_seen_from(dir, Vector3::new(0.01, -0.02, 0.6))
}

/// [`plaza`] seen by a rig of attitude `rotation_vector` (axis × angle, radians).
fn plaza_seen_from(
    dir: &Path,
    rotation_vector: Vector3<f64>,
) -> (PathBuf, PathBuf, Pose, Vec<usize>) {
    let mut r = rng(21);
    let points: Vec<Vector3<f64>> = (0..40)
        .map(|_| {
            Vector3::new(
                r.random_range(-70.0..70.0),
                r.random_range(-70.0..70.0),
                r.random_range(4.0..20.0),
            )
        })
        .collect();
    let truth = Pose::new(Vector3::new(3.0, -2.0, 2.0), rotation_vector);
    let seen: Vec<usize> = (0..points.len())
        .filter(|&k| (points[k] - truth.translation.vector).norm() < 60.0)
        .take(10)
        .collect();
    assert_eq!(seen.len(), 10);
    let stray = [random_unit_vector(&mut r), random_unit_vector(&mut r)];
    let seen_points: Vec<Vector3<f64>> = seen.iter().map(|&k| points[k]).collect();
    let mut text = "frame,bx,by,bz\n".to_string();
    text.push_str(&rows(0, &truth, &seen_points, &stray));
    // Frame 1: two detections only.
    text.push_str(&rows(1, &truth, &seen_points[..2], &[]));
    let (l, o) = (dir.join("L.csv"), dir.join("O.csv"));
    write_landmarks(&l, &points);
    std::fs::write(&o, text).unwrap();
    (l, o, truth, seen)
}

#[test]
fn frames_without_ids_are_matched_around_a_prior() {
    let dir = tempfile::tempdir().unwrap();
    let (l, o, truth, seen) = plaza(dir.path());
    let prior = prior_arg(&Vector3::new(-5.0, 4.0, 2.0), 15.0);
    let (code, lines) = run(&l, &o, &["--prior", &prior]);
    assert_eq!(code, Some(0));
    assert_eq!(lines.len(), 2);
    let line = &lines[0];
    assert_eq!(line["status"], "ok", "{line}");
    let g = Geodetic::try_new(
        line["lat"].as_f64().unwrap(),
        line["lon"].as_f64().unwrap(),
        line["alt"].as_f64().unwrap(),
    )
    .unwrap();
    let error = (local().to_enu(&g) - truth.translation.vector).norm();
    assert!(error < 0.05, "{error} m");
    // The assignment: detection k is landmark L{seen[k]}; the two stray lights are null.
    let ids = line["landmarks"].as_array().unwrap();
    assert_eq!(ids.len(), 12);
    for (k, &s) in seen.iter().enumerate() {
        assert_eq!(ids[k], format!("L{s}"), "{line}");
    }
    assert!(ids[10].is_null() && ids[11].is_null());
    assert_eq!(line["best_score"], 10);
    assert_eq!(line["inliers"], 10);
    assert!(line["runner_up_score"].as_u64().is_none_or(|r| r + 3 <= 10));
    // Every link is sure; the stray lights have no probability.
    let probabilities = line["link_probability"].as_array().unwrap();
    assert_eq!(probabilities.len(), 12);
    for p in &probabilities[..10] {
        assert!(
            p.as_f64().is_some_and(|p| (0.999..=1.0).contains(&p)),
            "{line}"
        );
    }
    assert!(probabilities[10].is_null() && probabilities[11].is_null());
    assert_eq!(lines[1]["status"], "too_few_detections");
    assert!(lines[1]["lat"].is_null());

    // The same with a known vertical.
    let (code, lines) = run(&l, &o, &["--prior", &prior, "--up-tolerance-deg", "3"]);
    assert_eq!(code, Some(0));
    assert_eq!(lines[0]["status"], "ok");
    assert_eq!(lines[0]["landmarks"], line["landmarks"]);
}

#[test]
fn a_prior_outside_the_landmarks_is_a_status() {
    let dir = tempfile::tempdir().unwrap();
    let (l, o, _, _) = plaza(dir.path());
    let prior = prior_arg(&Vector3::new(5000.0, 0.0, 2.0), 30.0);
    let (code, lines) = run(&l, &o, &["--prior", &prior]);
    assert_eq!(code, Some(0));
    assert_eq!(lines[0]["status"], "no_landmarks_in_range", "{}", lines[0]);
    assert!(lines[0]["lat"].is_null());
}

#[test]
fn a_regular_street_is_ambiguous_with_a_cold_start_region() {
    let dir = tempfile::tempdir().unwrap();
    let points: Vec<Vector3<f64>> = (0..=20)
        .flat_map(|k| {
            let x = 25.0 * k as f64;
            [Vector3::new(x, 8.0, 6.0), Vector3::new(x, -8.0, 6.0)]
        })
        .collect();
    let truth = Pose::new(Vector3::new(250.0, 1.0, 2.0), Vector3::new(0.0, 0.0, 0.4));
    let visible: Vec<Vector3<f64>> = points
        .iter()
        .filter(|p| (*p - truth.translation.vector).norm() < 60.0)
        .copied()
        .collect();
    let (l, o) = (dir.path().join("L.csv"), dir.path().join("O.csv"));
    write_landmarks(&l, &points);
    std::fs::write(
        &o,
        format!("frame,bx,by,bz\n{}", rows(0, &truth, &visible, &[])),
    )
    .unwrap();
    let region = prior_arg(&Vector3::new(245.0, 0.0, 2.0), 30.0);
    let (code, lines) = run(&l, &o, &["--region", &region]);
    assert_eq!(code, Some(0));
    let line = &lines[0];
    assert_eq!(line["status"], "ambiguous", "{line}");
    assert!(line["lat"].is_null());
    let best = line["best_score"].as_u64().unwrap();
    let runner_up = line["runner_up_score"].as_u64().unwrap();
    assert!(runner_up + 3 > best, "{line}");
}

/// A calibration that declares the rig level (`level_within_deg`) gives the matcher the same
/// vertical as `--up-tolerance-deg`, and the flag overrides it. The rig is tilted 10°: a 3°
/// vertical prunes the true pose (no fix), 15° or none finds it.
#[test]
fn a_calibration_declaring_the_rig_level_acts_as_the_up_tolerance_flag() {
    let dir = tempfile::tempdir().unwrap();
    let (l, o, truth, _) = plaza_seen_from(dir.path(), Vector3::new(10f64.to_radians(), 0.0, 0.6));
    let prior = prior_arg(&Vector3::new(-5.0, 4.0, 2.0), 15.0);
    // A panorama (no side files, so the copy may live in the temporary directory).
    let text = r#"{"format": "vgps-calibration", "version": 1,
  "cameras": [{"camera": {"model": "equirectangular", "width": 64, "height": 32},
    "rig_from_camera": {"rotation": [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], "translation": [0, 0, 0]}}]}"#;
    let plain = dir.path().join("plain.json");
    std::fs::write(&plain, text).unwrap();
    let plain = plain.to_str().unwrap().to_string();
    assert!(text.contains("\"version\": 1,"));
    let declared = dir.path().join("level3.json");
    std::fs::write(
        &declared,
        text.replacen(
            "\"version\": 1,",
            "\"version\": 1, \"level_within_deg\": 3,",
            1,
        ),
    )
    .unwrap();
    let declared = declared.to_str().unwrap();
    let status = |extra: &[&str]| {
        let mut args = vec!["--prior", prior.as_str()];
        args.extend_from_slice(extra);
        let (code, lines) = run(&l, &o, &args);
        assert_eq!(code, Some(0));
        lines[0].clone()
    };
    let none = status(&["--calibration", &plain]);
    assert_eq!(none["status"], "ok", "{none}");
    let g = Geodetic::try_new(
        none["lat"].as_f64().unwrap(),
        none["lon"].as_f64().unwrap(),
        none["alt"].as_f64().unwrap(),
    )
    .unwrap();
    assert!((local().to_enu(&g) - truth.translation.vector).norm() < 0.05);
    let flag = status(&["--calibration", &plain, "--up-tolerance-deg", "3"]);
    assert_ne!(flag["status"], "ok", "{flag}");
    let from_calibration = status(&["--calibration", declared]);
    assert_eq!(from_calibration, flag);
    // The flag overrides the declaration.
    let overridden = status(&["--calibration", declared, "--up-tolerance-deg", "15"]);
    assert_eq!(overridden["status"], "ok", "{overridden}");
    assert_eq!(
        overridden,
        status(&["--calibration", &plain, "--up-tolerance-deg", "15"])
    );
}
