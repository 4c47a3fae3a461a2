//! End-to-end tests of `vgps triangulate`: the built binary on synthetic rays with a known
//! truth, and on the committed fixtures (valid and malformed).

use nalgebra::{Matrix3, Vector3};
use rand::RngExt;
use std::fmt::Write as _;
use std::process::Output;
use vgps::geo::{Geodetic, LocalFrame};
use vgps::synthetic::{normal, perturb_bearing, rng};

mod common;
use common::{fixture, vgps};

/// The output rows as maps from column name to text.
fn rows(output: &Output) -> Vec<std::collections::HashMap<String, String>> {
    let mut reader = csv::Reader::from_reader(&output.stdout[..]);
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(
        header,
        [
            "id", "lat", "lon", "alt", "n_obs", "cov_ee", "cov_en", "cov_eu", "cov_nn", "cov_nu",
            "cov_uu", "status"
        ]
    );
    reader
        .records()
        .map(|r| {
            header
                .iter()
                .cloned()
                .zip(r.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

fn num(row: &std::collections::HashMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap()
}

/// Landmarks seen from observers spread over 2 km (so the ENU frames at the observers differ
/// by about 1°): each estimate must fall within its reported covariance of the truth.
#[test]
fn triangulate_recovers_the_synthetic_truth() {
    let mut r = rng(201);
    let local = LocalFrame::new(Geodetic::try_new(48.8584, 2.2945, 35.0).unwrap());
    let (sigma_pos, sigma_ang_deg) = (0.05, 0.05);
    let mut text = "id,lat,lon,alt,de,dn,du,sigma_pos_m,sigma_ang_deg\n".to_string();
    let mut truth = Vec::new();
    for k in 0..12 {
        let centre = Vector3::new(
            r.random_range(-1000.0..1000.0),
            r.random_range(-1000.0..1000.0),
            0.0,
        );
        let landmark = centre + Vector3::new(0.0, 0.0, r.random_range(3.0..30.0));
        let id = format!("t{k}");
        for _ in 0..r.random_range(2..6) {
            let observer_true = centre
                + Vector3::new(
                    r.random_range(-40.0..40.0),
                    r.random_range(-40.0..40.0),
                    2.0,
                );
            let observer = observer_true
                + Vector3::new(normal(&mut r), normal(&mut r), normal(&mut r)) * sigma_pos;
            let g = local.try_to_geodetic(&observer).unwrap();
            let d_local = perturb_bearing(
                &mut r,
                &(landmark - observer_true).normalize(),
                f64::to_radians(sigma_ang_deg),
            );
            // Into the ENU frame at the observer.
            let d = LocalFrame::new(g).enu_here_from_enu_at(&local.origin()) * d_local;
            writeln!(
                text,
                "{id},{},{},{},{},{},{},{sigma_pos},{sigma_ang_deg}",
                g.lat_deg, g.lon_deg, g.alt_m, d.x, d.y, d.z
            )
            .unwrap();
        }
        truth.push((id, local.try_to_geodetic(&landmark).unwrap()));
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("R.csv");
    std::fs::write(&path, text).unwrap();
    let out = vgps(&["triangulate", "--rays", path.to_str().unwrap()]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = rows(&out);
    assert_eq!(rows.len(), truth.len());
    let mut nees_sum = 0.0;
    for (row, (id, g)) in rows.iter().zip(&truth) {
        assert_eq!(&row["id"], id, "first-seen order");
        assert_eq!(row["status"], "ok");
        let estimate =
            Geodetic::try_new(num(row, "lat"), num(row, "lon"), num(row, "alt")).unwrap();
        // Error in the ENU frame at the truth (the covariance is in ENU at the estimate,
        // which differs by micro-radians).
        let error = LocalFrame::new(*g).to_enu(&estimate);
        let c = |k: &str| num(row, k);
        let cov = Matrix3::new(
            c("cov_ee"),
            c("cov_en"),
            c("cov_eu"),
            c("cov_en"),
            c("cov_nn"),
            c("cov_nu"),
            c("cov_eu"),
            c("cov_nu"),
            c("cov_uu"),
        );
        let nees = (error.transpose() * cov.try_inverse().unwrap() * error)[(0, 0)];
        assert!(nees < 25.0, "{id}: error {error:?} m, NEES {nees}");
        nees_sum += nees;
    }
    // 12 landmarks × 3 dof: the mean NEES is 3 in expectation; allow wide sampling spread.
    let mean = nees_sum / rows.len() as f64;
    eprintln!(
        "triangulation NEES mean over {} landmarks: {mean:.2}",
        rows.len()
    );
    assert!((1.0..6.0).contains(&mean), "mean NEES {mean}");
}

/// Without the rotation of each direction from the ENU frame at its observer, rays 2 km
/// apart would miss each other by metres: a landmark seen from both ends of the span.
#[test]
fn directions_are_taken_in_the_enu_frame_at_each_observer() {
    let local = LocalFrame::new(Geodetic::try_new(60.0, 10.0, 0.0).unwrap());
    let landmark = Vector3::new(1000.0, 0.0, 50.0);
    let mut text = "id,lat,lon,alt,de,dn,du\n".to_string();
    for observer in [Vector3::new(0.0, 0.0, 0.0), Vector3::new(2000.0, 0.0, 0.0)] {
        let g = local.try_to_geodetic(&observer).unwrap();
        let d = LocalFrame::new(g).enu_here_from_enu_at(&local.origin())
            * (landmark - observer).normalize();
        writeln!(
            text,
            "far,{},{},{},{},{},{}",
            g.lat_deg, g.lon_deg, g.alt_m, d.x, d.y, d.z
        )
        .unwrap();
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("R.csv");
    std::fs::write(&path, text).unwrap();
    let out = vgps(&["triangulate", "--rays", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0));
    let row = &rows(&out)[0];
    let estimate = Geodetic::try_new(num(row, "lat"), num(row, "lon"), num(row, "alt")).unwrap();
    let error = (local.to_enu(&estimate) - landmark).norm();
    assert!(error < 1e-4, "{error} m");
}

#[test]
fn the_documented_fixture_example_works_and_reports_the_failed_id() {
    let out = vgps(&["triangulate", "--rays", &fixture("rays.csv")]);
    assert_eq!(out.status.code(), Some(0));
    let rows = rows(&out);
    let ids: Vec<&str> = rows.iter().map(|r| r["id"].as_str()).collect();
    assert_eq!(ids, ["sign1", "lamp9", "tree3"]);
    // The fixture was generated with these landmark positions and 0.05° direction noise.
    let truth = [
        (37.795725240, -122.393563754, 9.0),
        (37.795364856, -122.393359386, 11.0),
    ];
    for (row, (lat, lon, alt)) in rows.iter().zip(truth) {
        assert_eq!(row["status"], "ok");
        assert_eq!(row["n_obs"], "3");
        let estimate =
            Geodetic::try_new(num(row, "lat"), num(row, "lon"), num(row, "alt")).unwrap();
        let at = LocalFrame::new(Geodetic::try_new(lat, lon, alt).unwrap());
        assert!(at.to_enu(&estimate).norm() < 0.3);
    }
    // A single ray: a row with n_obs, empty numbers and the reason, and a line on stderr.
    let failed = &rows[2];
    assert_eq!(failed["status"], "too_few_rays");
    assert_eq!(failed["n_obs"], "1");
    for key in ["lat", "lon", "alt", "cov_ee", "cov_uu"] {
        assert_eq!(failed[key], "", "{key}");
    }
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("id `tree3` (line 9): not triangulated"),
        "{stderr}"
    );
}

#[test]
fn malformed_rays_exit_2_naming_file_line_and_field() {
    let out = vgps(&[
        "triangulate",
        "--rays",
        &fixture("bad_rays_not_a_number.csv"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad_rays_not_a_number.csv:3: field `dn`: `north` is not a number"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
    let out = vgps(&[
        "triangulate",
        "--rays",
        &fixture("rays.csv"),
        "--sigma-deg",
        "-1",
    ]);
    assert_eq!(out.status.code(), Some(2));
}
