//! End-to-end tests of `vgps locate` (and `vgps demo`): the built binary on synthetic files
//! with a known truth, and on the committed fixtures (valid and malformed).

use nalgebra::{Matrix3, Vector3};
use rand::RngExt;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Output;
use vgps::attitude::HeadingPitchRoll;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::synthetic::{perturb_bearing, rng};

mod common;
use common::{fixture, vgps};

fn json_lines(output: &Output) -> Vec<Value> {
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("each stdout line is JSON"))
        .collect()
}

fn geodetic_of(v: &Value) -> Geodetic {
    Geodetic::try_new(
        v["lat"].as_f64().unwrap(),
        v["lon"].as_f64().unwrap(),
        v["alt"].as_f64().unwrap(),
    )
    .unwrap()
}

fn angle_diff_deg(a: f64, b: f64) -> f64 {
    (a - b + 180.0).rem_euclid(360.0) - 180.0
}

/// A synthetic drive: landmarks around an origin in Zurich, frames along a street.
struct Scene {
    dir: tempfile::TempDir,
    local: LocalFrame,
    truth: Vec<Pose>,
    ids: Vec<String>,
}

impl Scene {
    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
}

const SIGMA_DEG: f64 = 0.05;
const SIGMA_M: f64 = 0.03;

fn synthetic_scene(seed: u64, n_landmarks: usize, n_frames: usize) -> Scene {
    let mut r = rng(seed);
    let local = LocalFrame::new(Geodetic::try_new(47.3769, 8.5417, 408.0).unwrap());
    let mut landmarks = "id,lat,lon,alt,sigma_m,class\n".to_string();
    let mut points = Vec::new();
    let mut ids = Vec::new();
    for k in 0..n_landmarks {
        let azimuth = r.random_range(0.0..std::f64::consts::TAU);
        let range = r.random_range(15.0..90.0);
        let p = Vector3::new(
            range * azimuth.cos(),
            range * azimuth.sin(),
            r.random_range(-1.0..20.0),
        );
        let g = local.try_to_geodetic(&p).unwrap();
        let id = format!("lm{k}");
        writeln!(
            landmarks,
            "{id},{:.10},{:.10},{:.4},{SIGMA_M},streetlight",
            g.lat_deg, g.lon_deg, g.alt_m
        )
        .unwrap();
        points.push(p);
        ids.push(id);
    }
    let mut observations = "frame,bx,by,bz,landmark\n".to_string();
    let mut truth = Vec::new();
    for frame in 0..n_frames {
        let hpr = HeadingPitchRoll {
            heading_rad: r.random_range(0.0..std::f64::consts::TAU),
            pitch_rad: r.random_range(-0.1..0.1),
            roll_rad: r.random_range(-0.1..0.1),
        };
        let position = Vector3::new(frame as f64 * 4.0 - 10.0, r.random_range(-3.0..3.0), 2.0);
        let pose = Pose::from_parts(position.into(), hpr.to_enu_from_rig());
        for (id, p) in ids.iter().zip(&points) {
            let b = perturb_bearing(
                &mut r,
                &bearing_in_rig(&pose, p).unwrap(),
                SIGMA_DEG.to_radians(),
            );
            // Bearings of arbitrary length: the reader normalises them.
            let b = b * r.random_range(0.5..3.0);
            writeln!(observations, "{frame},{},{},{},{id}", b.x, b.y, b.z).unwrap();
        }
        truth.push(pose);
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("L.csv"), landmarks).unwrap();
    std::fs::write(dir.path().join("O.csv"), observations).unwrap();
    Scene {
        dir,
        local,
        truth,
        ids,
    }
}

#[test]
fn locate_recovers_the_synthetic_truth() {
    let scene = synthetic_scene(101, 10, 6);
    let out = vgps(&[
        "locate",
        "--landmarks",
        scene.path("L.csv").to_str().unwrap(),
        "--observations",
        scene.path("O.csv").to_str().unwrap(),
        "--sigma-deg",
        &SIGMA_DEG.to_string(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines = json_lines(&out);
    assert_eq!(lines.len(), scene.truth.len());
    for (k, (line, truth)) in lines.iter().zip(&scene.truth).enumerate() {
        assert_eq!(line["frame"], k as u64);
        assert_eq!(line["status"], "ok", "{line}");
        assert_eq!(line["inliers"], 10);
        assert_eq!(line["observations"], 10);
        let used: Vec<&str> = line["landmarks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(used, scene.ids);
        // Position: compare in ENU at the true position, against the reported covariance.
        let true_g = scene
            .local
            .try_to_geodetic(&truth.translation.vector)
            .unwrap();
        let at_truth = LocalFrame::new(true_g);
        let error = at_truth.to_enu(&geodetic_of(line));
        let cov: Vec<f64> = line["cov_enu_m2"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let cov = Matrix3::from_row_slice(&cov);
        assert!((cov - cov.transpose()).norm() < 1e-12 * cov.norm());
        let nees = (error.transpose() * cov.try_inverse().unwrap() * error)[(0, 0)];
        assert!(nees < 20.0, "frame {k}: error {error:?}, NEES {nees}");
        assert!(error.norm() < 0.3, "frame {k}: error {} m", error.norm());
        // Attitude.
        let hpr = HeadingPitchRoll::from_enu_from_rig(&truth.rotation);
        let [h, p, r] = hpr.to_degrees();
        assert!(angle_diff_deg(line["heading_deg"].as_f64().unwrap(), h).abs() < 0.2);
        assert!((line["pitch_deg"].as_f64().unwrap() - p).abs() < 0.2);
        assert!(angle_diff_deg(line["roll_deg"].as_f64().unwrap(), r).abs() < 0.2);
        let q: Vec<f64> = line["enu_from_rig_wxyz"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-12 && q[0] >= 0.0);
        let q_truth = nalgebra::UnitQuaternion::from_rotation_matrix(&truth.rotation);
        let dot = (q[0] * q_truth.w + q[1] * q_truth.i + q[2] * q_truth.j + q[3] * q_truth.k).abs();
        assert!(
            dot > (0.2f64.to_radians() / 2.0).cos(),
            "frame {k}: quaternion {q:?}"
        );
    }
}

#[test]
fn frames_without_a_fix_are_reported_and_the_others_go_on() {
    let scene = synthetic_scene(102, 8, 1);
    // Frame 0 from the scene; frame 5 has two observations; frame 3 lacks landmark ids.
    let mut text = std::fs::read_to_string(scene.path("O.csv")).unwrap();
    text.push_str("5,1,0,0,lm0\n5,0,1,0,lm1\n3,1,0,0,\n3,0,1,0,lm2\n3,0,0,1,lm3\n");
    std::fs::write(scene.path("O.csv"), text).unwrap();
    let out = vgps(&[
        "locate",
        "--landmarks",
        scene.path("L.csv").to_str().unwrap(),
        "--observations",
        scene.path("O.csv").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let lines = json_lines(&out);
    let frames: Vec<u64> = lines.iter().map(|l| l["frame"].as_u64().unwrap()).collect();
    assert_eq!(frames, [0, 3, 5]);
    assert_eq!(lines[0]["status"], "ok");
    assert_eq!(lines[1]["status"], "needs_matcher");
    assert_eq!(lines[2]["status"], "too_few_observations");
    for line in &lines[1..] {
        for key in [
            "lat",
            "lon",
            "alt",
            "enu_from_rig_wxyz",
            "heading_deg",
            "pitch_deg",
            "roll_deg",
            "cov_enu_m2",
            "inliers",
        ] {
            assert!(line[key].is_null(), "{key} of {line}");
        }
        assert!(line["message"].is_string());
        assert!(
            line["landmarks"]
                .as_array()
                .unwrap()
                .iter()
                .all(Value::is_null)
        );
    }
    assert_eq!(lines[1]["observations"], 3);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("frame 3") && stderr.contains("matcher"),
        "{stderr}"
    );
}

#[test]
fn a_prior_resolves_the_three_landmark_ambiguity() {
    // Find a fixed-seed three-landmark view with several P3P solutions.
    let local = LocalFrame::new(Geodetic::try_new(-33.8568, 151.2153, 20.0).unwrap());
    let mut r = rng(103);
    let (truth, points, separation) = (0..500)
        .find_map(|_| {
            let truth = vgps::synthetic::random_pose(&mut r, 10.0);
            let points: [Vector3<f64>; 3] = std::array::from_fn(|_| {
                truth.translation.vector
                    + vgps::synthetic::random_unit_vector(&mut r) * r.random_range(10.0..50.0)
            });
            let bearings = points.map(|p| bearing_in_rig(&truth, &p).unwrap());
            let solutions = vgps::solvers::p3p(&bearings, &points);
            let separation = solutions
                .iter()
                .map(|s| (s.translation.vector - truth.translation.vector).norm())
                .filter(|&d| d > 1e-3)
                .fold(f64::INFINITY, f64::min);
            (solutions.len() >= 2 && separation > 1.0 && separation.is_finite())
                .then_some((truth, points, separation))
        })
        .expect("a multi-solution configuration within 500 draws");
    let dir = tempfile::tempdir().unwrap();
    let mut landmarks = "id,lat,lon,alt\n".to_string();
    let mut observations = "bx,by,bz,landmark\n".to_string();
    for (k, p) in points.iter().enumerate() {
        let g = local.try_to_geodetic(p).unwrap();
        writeln!(landmarks, "p{k},{},{},{}", g.lat_deg, g.lon_deg, g.alt_m).unwrap();
        let b = bearing_in_rig(&truth, p).unwrap();
        writeln!(observations, "{},{},{},p{k}", b.x, b.y, b.z).unwrap();
    }
    let l = dir.path().join("L.csv");
    let o = dir.path().join("O.csv");
    std::fs::write(&l, landmarks).unwrap();
    std::fs::write(&o, observations).unwrap();
    let base = [
        "locate",
        "--landmarks",
        l.to_str().unwrap(),
        "--observations",
        o.to_str().unwrap(),
    ];
    let out = vgps(&base);
    assert_eq!(out.status.code(), Some(0));
    let line = &json_lines(&out)[0];
    assert_eq!(line["status"], "ambiguous", "{line}");
    assert!(line["lat"].is_null());

    let g = local.try_to_geodetic(&truth.translation.vector).unwrap();
    let prior = format!(
        "{},{},{},{}",
        g.lat_deg,
        g.lon_deg,
        g.alt_m,
        0.5 * separation
    );
    let mut args = base.to_vec();
    args.extend(["--prior", prior.as_str()]);
    let out = vgps(&args);
    assert_eq!(out.status.code(), Some(0));
    let line = &json_lines(&out)[0];
    assert_eq!(line["status"], "ok", "{line}");
    assert_eq!(line["inliers"], 3);
    let error = LocalFrame::new(g).to_enu(&geodetic_of(line)).norm();
    assert!(error < 1e-3, "{error} m");
}

#[test]
fn the_documented_fixture_example_works() {
    let out = vgps(&[
        "locate",
        "--landmarks",
        &fixture("landmarks.csv"),
        "--observations",
        &fixture("observations.csv"),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let lines = json_lines(&out);
    let statuses: Vec<&str> = lines
        .iter()
        .map(|l| l["status"].as_str().unwrap())
        .collect();
    assert_eq!(statuses, ["ok", "ok", "needs_matcher"]);
    // The fixture was generated at these positions with 0.05° bearing noise.
    let truth = [
        (37.795481981, -122.393665938, 6.8),
        (37.795518019, -122.393609169, 6.7),
    ];
    for (line, (lat, lon, alt)) in lines.iter().zip(truth) {
        let at = LocalFrame::new(Geodetic::try_new(lat, lon, alt).unwrap());
        let error = at.to_enu(&geodetic_of(line)).norm();
        assert!(error < 0.2, "{error} m");
    }
    assert!((lines[0]["heading_deg"].as_f64().unwrap() - 30.0).abs() < 0.2);
    assert!((lines[1]["heading_deg"].as_f64().unwrap() - 38.0).abs() < 0.2);
}

/// Each malformed fixture: exit code 2 and a message naming the file, the line and the field.
#[test]
fn malformed_inputs_exit_2_naming_file_line_and_field() {
    let cases = [
        (
            "bad_landmarks_duplicate.csv",
            "observations.csv",
            "bad_landmarks_duplicate.csv:4: field `id`",
        ),
        (
            "bad_landmarks_nan.csv",
            "observations.csv",
            "bad_landmarks_nan.csv:3: field `alt`",
        ),
        (
            "landmarks.csv",
            "bad_observations_fields.csv",
            "bad_observations_fields.csv:3: field `landmark`",
        ),
        (
            "landmarks.csv",
            "bad_observations_unknown_landmark.csv",
            "bad_observations_unknown_landmark.csv:5: field `landmark`: unknown landmark id `lamp33`",
        ),
        (
            "landmarks.csv",
            "bad_observations_zero_bearing.csv",
            "bad_observations_zero_bearing.csv:3: field `bx`",
        ),
        (
            "landmarks.csv",
            "bad_observations_pixels.csv",
            "bad_observations_pixels.csv:2: field `camera`: pixel observations need --calibration",
        ),
    ];
    for (l, o, expected) in cases {
        let out = vgps(&[
            "locate",
            "--landmarks",
            &fixture(l),
            "--observations",
            &fixture(o),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{l} {o}: {stderr}");
        assert!(stderr.contains(expected), "{l} {o}: {stderr}");
        assert!(
            out.stdout.is_empty(),
            "no partial output before an input error"
        );
    }
}

#[test]
fn usage_errors_exit_2() {
    let l = fixture("landmarks.csv");
    let o = fixture("observations.csv");
    for args in [
        vec!["locate", "--landmarks", l.as_str()],
        vec![
            "locate",
            "--landmarks",
            &l,
            "--observations",
            &o,
            "--sigma-deg",
            "0",
        ],
        vec![
            "locate",
            "--landmarks",
            &l,
            "--observations",
            &o,
            "--prior",
            "1,2,3",
        ],
        vec![
            "locate",
            "--landmarks",
            &l,
            "--observations",
            &o,
            "--calibration",
            "cam.yaml",
        ],
        vec!["frobnicate"],
    ] {
        let out = vgps(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty());
    }
    let out = vgps(&[
        "locate",
        "--landmarks",
        "/nonexistent/L.csv",
        "--observations",
        &o,
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/L.csv: cannot read"));
    assert_eq!(vgps(&["--help"]).status.code(), Some(0));
}

#[test]
fn demo_simulates_and_replays_the_reference_drive_and_the_night_and_day_images() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("demo");
    let out = vgps(&[
        "demo",
        "--out",
        out_dir.to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["frames"], 3255);
    // The localizer issue's targets on the reference drive, as the demo shows them.
    assert!(report["visual_fix_rate"].as_f64().unwrap() >= 0.99);
    let h = &report["visual_vs_truth"]["horizontal_m"];
    assert!(h["cep50"].as_f64().unwrap() <= 0.05, "{h}");
    for name in [
        "fixes.csv",
        "report.json",
        "report.html",
        "track.geojson",
        "track.kml",
        "track.gpx",
        "fixes.nmea",
    ] {
        assert!(out_dir.join("replay").join(name).is_file(), "{name}");
    }
    assert!(out_dir.join("reference/drive.json").is_file());
    // The image stage: a night drive rendered and replayed from its pixels.
    let night: Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("night-replay/report.json")).unwrap())
            .unwrap();
    assert_eq!(night["images"]["frames"], night["frames"], "{night}");
    assert_eq!(night["images"]["unusable_images"], 0, "{night}");
    assert!(
        night["visual_fix_rate"].as_f64().unwrap() >= 0.99,
        "{night}"
    );
    let h = &night["visual_vs_truth"]["horizontal_m"];
    assert!(h["cep50"].as_f64().unwrap() <= 0.05, "{h}");
    // One JSON document: each image stage's report under its own key.
    assert_eq!(report["night_replay"], night);
    // The day stage: building corners found in JPEG images, the vertex detector.
    let day: Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("day-replay/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["day_replay"], day);
    assert_eq!(day["frames"], 56, "{day}");
    assert_eq!(day["images"]["frames"], day["frames"], "{day}");
    assert_eq!(day["images"]["unusable_images"], 0, "{day}");
    let jpegs = std::fs::read_dir(out_dir.join("day/images"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "jpg"))
        })
        .count();
    assert_eq!(jpegs, 56 * 6);
    // Issue 26's targets for day drives from images: ≥ 95 % of the frames fixed, CEP50
    // ≤ 5 cm, CEP95 ≤ 25 cm, no `ok` fix more than 5 m off.
    let (ok, frames, worst_ok_m) = ok_fixes(&out_dir.join("day-replay/fixes.csv"));
    assert_eq!(frames, 56);
    assert!(ok as f64 >= 0.95 * frames as f64, "{ok} of {frames} ok");
    assert!(worst_ok_m <= 5.0, "an ok fix {worst_ok_m} m off");
    let h = &day["visual_vs_truth"]["horizontal_m"];
    assert!(h["cep50"].as_f64().unwrap() <= 0.05, "{h}");
    assert!(h["cep95"].as_f64().unwrap() <= 0.25, "{h}");
}

/// The `ok` rows of a `fixes.csv`, its rows, and the largest horizontal error of an `ok` row
/// against the truth (metres).
fn ok_fixes(path: &Path) -> (usize, usize, f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (status, err_h) = (column("status"), column("err_h_m"));
    let (mut ok, mut frames, mut worst) = (0, 0, 0.0f64);
    for line in lines {
        let fields: Vec<&str> = line.split(',').collect();
        frames += 1;
        if fields[status] == "ok" {
            ok += 1;
            worst = worst.max(fields[err_h].parse().unwrap());
        }
    }
    (ok, frames, worst)
}

/// Pixel observations through the shipped Ladybug2 calibration: the rays start at the
/// camera centres (a non-central rig), and the fix must still recover the truth.
#[test]
fn pixel_observations_through_a_calibration() {
    let calibration = Path::new(env!("CARGO_MANIFEST_DIR")).join("calibration/ladybug2.json");
    let rig = vgps::calibration::formats::load(&calibration, None, None).unwrap();
    let scene = synthetic_scene(104, 10, 2);
    let text = std::fs::read_to_string(scene.path("L.csv")).unwrap();
    let landmarks = vgps::io::landmarks_from_reader(Path::new("L.csv"), text.as_bytes()).unwrap();
    let mut observations = "frame,camera,u,v,landmark\n".to_string();
    for (frame, pose) in scene.truth.iter().enumerate() {
        for l in &landmarks {
            let g = Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m).unwrap();
            let in_rig = pose.inverse_transform_point(&scene.local.to_enu(&g).into());
            let Some(seen) = rig.project_point(&in_rig.coords).into_iter().next() else {
                continue;
            };
            writeln!(
                observations,
                "{frame},{},{},{},{}",
                seen.camera, seen.pixel.x, seen.pixel.y, l.id
            )
            .unwrap();
        }
    }
    std::fs::write(scene.path("P.csv"), observations).unwrap();
    let (l, p) = (scene.path("L.csv"), scene.path("P.csv"));
    let args = [
        "locate",
        "--landmarks",
        l.to_str().unwrap(),
        "--observations",
        p.to_str().unwrap(),
        "--calibration",
        calibration.to_str().unwrap(),
    ];
    let out = vgps(&args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines = json_lines(&out);
    assert_eq!(lines.len(), 2);
    for (line, truth) in lines.iter().zip(&scene.truth) {
        assert_eq!(line["status"], "ok", "{line}");
        assert!(line["inliers"].as_u64().unwrap() >= 8, "{line}");
        let g = scene
            .local
            .try_to_geodetic(&truth.translation.vector)
            .unwrap();
        let error = LocalFrame::new(g).to_enu(&geodetic_of(line)).norm();
        assert!(error < 0.01, "{error} m");
    }
    // Without the calibration the same file is an input error naming line 2, `camera`.
    let out = vgps(&args[..5]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("P.csv:2: field `camera`"));
}
