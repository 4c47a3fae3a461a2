//! `vgps map`: survey mode on simulated drives, compared with the simulator's true landmark
//! positions (`world_landmarks.csv`) and true GNSS lag (`simulation.json`).

mod common;

use common::vgps;
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::simulate::{Preset, Scenario, simulate};

/// Mapped landmarks against the true ones (nearest true landmark of any class).
#[derive(Debug)]
struct Comparison {
    mapped: usize,
    /// Fraction of mapped landmarks within 1 m of a true landmark.
    matched_1m: f64,
    median_m: f64,
    #[allow(dead_code)]
    p95_m: f64,
    /// True landmarks with more than one mapped landmark within 1 m.
    duplicates: usize,
    /// Mean error vector (ENU) of the matched landmarks and its standard error per axis.
    mean_error: Vector3<f64>,
    standard_error: Vector3<f64>,
}

fn compare(drive: &Path, mapped_csv: &Path) -> Comparison {
    let frame = LocalFrame::new(Geodetic::try_new(37.7793, -122.4193, 0.0).unwrap());
    let text = std::fs::read_to_string(drive.join("world_landmarks.csv")).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let truth: Vec<Vector3<f64>> = r
        .records()
        .map(|rec| {
            let rec = rec.unwrap();
            let f = |i: usize| rec[i].parse::<f64>().unwrap();
            frame.to_enu(&Geodetic::try_new(f(1), f(2), f(3)).unwrap())
        })
        .collect();
    // The file must be what `vgps locate --landmarks` and the localizer read.
    let mapped = vgps::io::read_landmarks(mapped_csv).unwrap();
    vgps::localizer::LandmarkMap::from_landmarks(&mapped, None).unwrap();
    let mut errors = Vec::new();
    let mut vectors = Vec::new();
    let mut hits = vec![0usize; truth.len()];
    for l in &mapped {
        let p = frame.to_enu(&Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m).unwrap());
        let (j, d) = truth
            .iter()
            .enumerate()
            .map(|(j, t)| (j, (p - t).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        errors.push(d);
        if d < 1.0 {
            hits[j] += 1;
            vectors.push(p - truth[j]);
        }
    }
    let n = errors.len();
    assert!(n > 0, "no landmark mapped");
    let mut sorted = errors.clone();
    sorted.sort_by(f64::total_cmp);
    let m = vectors.len().max(1) as f64;
    let mean: Vector3<f64> = vectors.iter().sum::<Vector3<f64>>() / m;
    let var = vectors
        .iter()
        .map(|v| (v - mean).component_mul(&(v - mean)))
        .sum::<Vector3<f64>>()
        / (m - 1.0).max(1.0);
    Comparison {
        mapped: n,
        matched_1m: vectors.len() as f64 / n as f64,
        median_m: sorted[n / 2],
        p95_m: sorted[(n * 95 / 100).min(n - 1)],
        duplicates: hits.iter().filter(|&&h| h > 1).count(),
        mean_error: mean,
        standard_error: var.map(|v| (v / m).sqrt()),
    }
}

fn run_map(drive: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["map", drive.to_str().unwrap(), "--format", "json"];
    args.extend_from_slice(extra);
    let out = vgps(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The short preset with a precise receiver (white noise, CEP 0.3 m, no slow bias): what
/// survey mode can do when the GNSS is good; the lag stays the simulator's 0.1 s.
fn precise_gnss_drive(dir: &Path, seed: u64) {
    let mut sc = Scenario::preset(Preset::Short, seed);
    sc.gnss_cep_m = 0.3;
    sc.gnss_bias_share = 0.0;
    simulate(&sc).unwrap().write(dir).unwrap();
}

#[test]
fn precise_gnss_maps_the_landmarks_within_a_metre() {
    let dir = tempfile::tempdir().unwrap();
    precise_gnss_drive(dir.path(), 1);
    let summary = run_map(
        dir.path(),
        &["--gps-offset", "0.1", "--gnss-sigma-m", "0.25"],
    );
    let c = compare(dir.path(), &dir.path().join("mapped_landmarks.csv"));
    eprintln!("precise GNSS: {c:?}\n{summary}");
    assert_eq!(summary["landmarks"].as_u64(), Some(c.mapped as u64));
    // Measured (seed 1): 295 mapped, 64 % within 1 m, median 0.60 m, 36 duplicates: the
    // rest are chance alignments of the simulator's transient lights (20 % of detections).
    assert!(c.mapped >= 200, "{c:?}");
    assert!(c.matched_1m >= 0.55, "{c:?}");
    assert!(c.median_m <= 0.8, "{c:?}");
    assert!(c.duplicates * 6 <= c.mapped, "{c:?}");
    // No bias beyond 3 standard errors on any axis.
    for k in 0..3 {
        assert!(
            c.mean_error[k].abs() <= 3.0 * c.standard_error[k] + 0.02,
            "axis {k}: {c:?}"
        );
    }
    let r = summary["information_nobs_correlation"].as_f64().unwrap();
    assert!(r > 0.3, "correlation of 1/σ² with n_obs {r}");
}

#[test]
fn gps_offset_auto_recovers_the_simulator_lag() {
    let dir = tempfile::tempdir().unwrap();
    precise_gnss_drive(dir.path(), 1);
    let summary = run_map(
        dir.path(),
        &["--gps-offset", "auto", "--gnss-sigma-m", "0.25"],
    );
    let sim: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("simulation.json")).unwrap())
            .unwrap();
    let lag = sim["gnss"]["lag_s"].as_f64().unwrap();
    let o = &summary["gps_offset"];
    let est = o["offset_s"].as_f64().unwrap();
    eprintln!("lag {lag}: {o}");
    assert_eq!(o["mode"], "auto");
    assert!((est - lag).abs() <= 0.03, "estimated {est}, true {lag}");
    let along = o["along_track_m"].as_f64().unwrap();
    let speed = o["median_speed_m_s"].as_f64().unwrap();
    assert!((along - est * speed).abs() < 1e-9 && (5.0..15.0).contains(&speed));
}

#[test]
fn default_short_drive_is_mapped_and_readable_by_locate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    assert!(
        vgps(&["simulate", "--out", d, "--preset", "short"])
            .status
            .success()
    );
    let out = dir.path().join("inventory.csv");
    let summary = run_map(dir.path(), &["--out", out.to_str().unwrap()]);
    let c = compare(dir.path(), &out);
    eprintln!("default short drive (CEP 2 m receiver with a 60 s bias): {c:?}\n{summary}");
    // The simulated receiver's slowly varying bias (1.5 m per axis) moves every landmark
    // seen in the same seconds together: the inventory is only as good as the GPS.
    assert!(c.mapped >= 100 && c.median_m < 10.0, "{c:?}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("id,lat,lon,alt,sigma_m,class,n_obs\n"));
    // `vgps locate --landmarks` reads it: one frame of bearings to four mapped landmarks
    // from a point among them (rig axes = ENU).
    let lms = vgps::io::read_landmarks(&out).unwrap();
    let frame = LocalFrame::new(Geodetic::try_new(37.7793, -122.4193, 0.0).unwrap());
    let pts: Vec<Vector3<f64>> = lms
        .iter()
        .take(6)
        .map(|l| frame.to_enu(&Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m).unwrap()))
        .collect();
    let centre = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64 + Vector3::new(3.0, 2.0, -4.0);
    let mut obs = "frame,bx,by,bz,landmark\n".to_string();
    for (l, p) in lms.iter().zip(&pts) {
        let b = (p - centre).normalize();
        writeln!(obs, "0,{},{},{},{}", b.x, b.y, b.z, l.id).unwrap();
    }
    let obs_path = dir.path().join("obs.csv");
    std::fs::write(&obs_path, obs).unwrap();
    let located = vgps(&[
        "locate",
        "--landmarks",
        out.to_str().unwrap(),
        "--observations",
        obs_path.to_str().unwrap(),
    ]);
    assert!(
        located.status.success(),
        "{}",
        String::from_utf8_lossy(&located.stderr)
    );
}

#[test]
fn unusable_input_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = vgps(&["map", dir.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let out = vgps(&["map", "x", "--gps-offset", "soon"]);
    assert_eq!(out.status.code(), Some(2));
    let out = vgps(&["map", "x", "--min-obs", "2"]);
    assert_eq!(out.status.code(), Some(2));
}
