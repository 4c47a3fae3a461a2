//! `vgps locate` with landmark ids on one file whose frames lie on several continents: each
//! frame is solved in a local frame of its own (issue #25), and the bad rows of such a file
//! — a frame whose ids name landmarks thousands of km apart, a prior far from a frame's
//! landmarks, a frame whose bearings are all the same — give a per-frame status, no fix.

use nalgebra::Vector3;
use rand::RngExt;
use serde_json::Value;
use std::fmt::Write as _;
use vgps::attitude::HeadingPitchRoll;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::synthetic::{perturb_bearing, rng};

mod common;
use common::vgps;

const SIGMA_DEG: f64 = 0.05;

/// Zurich, Sydney, São Paulo: (lat, lon, alt).
const PLACES: [(f64, f64, f64); 3] = [
    (47.3769, 8.5417, 408.0),
    (-33.8688, 151.2093, 20.0),
    (-23.5505, -46.6333, 760.0),
];

struct World {
    dir: tempfile::TempDir,
    /// Per place: its local frame and the true pose of its frame.
    truth: Vec<(LocalFrame, Pose)>,
}

/// Eight landmarks around each place (ids `p{place}l{k}`), one frame per place (frame number
/// = place) seeing all of its landmarks; frame 3 names landmarks of Zurich and Sydney; frame
/// 4 has six identical bearings of Zurich's landmarks.
fn world() -> World {
    let mut r = rng(2503);
    let mut landmarks = "id,lat,lon,alt,sigma_m,class\n".to_string();
    let mut observations = "frame,bx,by,bz,landmark\n".to_string();
    let mut truth = Vec::new();
    for (place, &(lat, lon, alt)) in PLACES.iter().enumerate() {
        let local = LocalFrame::new(Geodetic::try_new(lat, lon, alt).unwrap());
        let pose = Pose::from_parts(
            Vector3::new(3.0, -2.0, 2.0).into(),
            HeadingPitchRoll {
                heading_rad: 0.7 * place as f64 + 0.3,
                pitch_rad: 0.02,
                roll_rad: -0.03,
            }
            .to_enu_from_rig(),
        );
        for k in 0..8 {
            let azimuth = k as f64 * std::f64::consts::TAU / 8.0 + r.random_range(0.0..0.5);
            let range = r.random_range(15.0..60.0);
            let p = Vector3::new(
                range * azimuth.cos(),
                range * azimuth.sin(),
                r.random_range(0.0..15.0),
            );
            let g = local.try_to_geodetic(&p).unwrap();
            writeln!(
                landmarks,
                "p{place}l{k},{:.10},{:.10},{:.4},0.01,streetlight",
                g.lat_deg, g.lon_deg, g.alt_m
            )
            .unwrap();
            let b = perturb_bearing(
                &mut r,
                &bearing_in_rig(&pose, &p).unwrap(),
                SIGMA_DEG.to_radians(),
            );
            writeln!(observations, "{place},{},{},{},p{place}l{k}", b.x, b.y, b.z).unwrap();
            if place < 2 && k < 4 {
                // Frame 3: four landmarks of Zurich and four of Sydney.
                writeln!(observations, "3,{},{},{},p{place}l{k}", b.x, b.y, b.z).unwrap();
            }
            if place == 0 && k < 6 {
                writeln!(observations, "4,0.3,0.4,0.1,p0l{k}").unwrap();
            }
        }
        truth.push((local, pose));
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("L.csv"), landmarks).unwrap();
    std::fs::write(dir.path().join("O.csv"), observations).unwrap();
    World { dir, truth }
}

fn locate(world: &World, extra: &[&str]) -> Vec<Value> {
    let l = world.dir.path().join("L.csv");
    let o = world.dir.path().join("O.csv");
    let mut args = vec![
        "locate",
        "--landmarks",
        l.to_str().unwrap(),
        "--observations",
        o.to_str().unwrap(),
        "--sigma-deg",
        "0.05",
    ];
    args.extend_from_slice(extra);
    let out = vgps(&args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn position_error_m(line: &Value, local: &LocalFrame, pose: &Pose) -> f64 {
    let g = Geodetic::try_new(
        line["lat"].as_f64().unwrap(),
        line["lon"].as_f64().unwrap(),
        line["alt"].as_f64().unwrap(),
    )
    .unwrap();
    (local.to_enu(&g) - pose.translation.vector).norm()
}

#[test]
fn frames_on_three_continents_in_one_file_are_each_solved() {
    let world = world();
    let lines = locate(&world, &[]);
    assert_eq!(lines.len(), 5);
    for (place, (local, pose)) in world.truth.iter().enumerate() {
        let line = &lines[place];
        assert_eq!(line["status"], "ok", "{line}");
        assert_eq!(line["inliers"], 8, "{line}");
        let error = position_error_m(line, local, pose);
        assert!(error < 0.2, "frame {place}: {error} m");
    }
    // Landmarks of Zurich and Sydney in one frame: the ids are wrong, and it says so.
    assert_eq!(
        lines[3]["status"], "landmarks_too_far_apart",
        "{}",
        lines[3]
    );
    let message = lines[3]["message"].as_str().unwrap();
    assert!(message.contains("km apart"), "{message}");
    assert!(lines[3]["lat"].is_null());
    // Six identical bearings: no geometry, no fix.
    assert_ne!(lines[4]["status"], "ok", "{}", lines[4]);
    assert!(lines[4]["lat"].is_null());
}

#[test]
fn a_prior_far_from_a_frames_landmarks_is_a_status_of_that_frame() {
    let world = world();
    // A prior around the Zurich frame: Zurich is solved, the other places say how far the
    // prior is from their landmarks.
    let lines = locate(&world, &["--prior", "47.37692,8.54172,410,50"]);
    assert_eq!(lines.len(), 5);
    assert_eq!(lines[0]["status"], "ok", "{}", lines[0]);
    let (local, pose) = &world.truth[0];
    assert!(position_error_m(&lines[0], local, pose) < 0.2);
    for line in &lines[1..3] {
        assert_eq!(line["status"], "no_solution", "{line}");
        let message = line["message"].as_str().unwrap();
        assert!(
            message.contains("km from the nearest landmark"),
            "{message}"
        );
        assert!(line["lat"].is_null());
    }
}
