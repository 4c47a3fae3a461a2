//! `report.html` in a real headless browser (issue #28): Debian's Chromium
//! (`chromium-headless-shell`, or `chromium`) opens a report of 3,255 frames (the size of
//! the reference drive) offline, from a file, with `#selftest`: the page's own script
//! then zooms to the first fix and clicks where it is drawn, and writes what happened into
//! `#vgps-selftest`, which the browser's `--dump-dom` hands back.
//!
//! Checked: no script error, the map's canvas has ink at the whole-drive view, the click
//! shows that fix's frame, the map zooms to millimetres, no request leaves the page, and
//! the browser is done in under 20 s (the page's own time to its map is printed; the
//! target, 2 s, is measured by hand).
//!
//! Without a Chromium the test prints why it is skipped and passes (`.ci/run` installs
//! `chromium-headless-shell` when missing).

use nalgebra::{Matrix2, Matrix6, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::process::Command;
use std::time::{Duration, Instant};
use vgps_geometry::geo::{Geodetic, LocalFrame};
use vgps_replay::report::{
    DriveInfo, FrameOutcome, MapExtras, Report, Truth, VisualFix, report_html_with,
};

/// Frames of the report: as many as the reference drive has.
const FRAMES: u64 = 3_255;

fn origin() -> Geodetic {
    Geodetic::try_new(47.3769, 8.5417, 410.0).unwrap()
}

/// A 3,255-frame drive around a 400 m × 300 m block: truth on the block, satellite 2 m
/// off with blackouts, visual fixes within centimetres with their covariance, every fifth
/// frame without a fix; a landmark every 25 m.
fn drive() -> (DriveInfo, Vec<FrameOutcome>, MapExtras) {
    let local = LocalFrame::new(origin());
    let at = |s: f64| {
        let s = s.rem_euclid(1400.0);
        let (e, n) = if s < 400.0 {
            (s, 0.0)
        } else if s < 700.0 {
            (400.0, s - 400.0)
        } else if s < 1100.0 {
            (1100.0 - s, 300.0)
        } else {
            (0.0, 1400.0 - s)
        };
        Vector3::new(e, n, 0.0)
    };
    let geo = |p: Vector3<f64>| local.try_to_geodetic(&p).unwrap();
    let landmarks: Vec<vgps_io::Landmark> = (0..56)
        .map(|k| {
            let p = at(25.0 * k as f64) + Vector3::new(3.0, 3.0, 5.0);
            let g = geo(p);
            vgps_io::Landmark {
                id: format!("lamp-{k}"),
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: g.alt_m,
                sigma_m: None,
                class: Some("streetlight".into()),
                line: k + 2,
            }
        })
        .collect();
    let mut used = BTreeMap::new();
    let records = (0..FRAMES)
        .map(|k| {
            let s = 0.43 * k as f64;
            let truth = at(s);
            let wobble = Vector3::new((k as f64 * 0.37).sin(), (k as f64 * 0.21).cos(), 0.0);
            let visual = (k % 5 != 3).then(|| {
                let sigma = 0.01 + 0.002 * (k % 40) as f64;
                let cov = Matrix6::from_diagonal(&nalgebra::Vector6::new(
                    sigma * sigma,
                    (1.5 * sigma).powi(2),
                    (2.0 * sigma).powi(2),
                    1e-6,
                    1e-6,
                    1e-6,
                ));
                let lamp = (s / 25.0) as usize % 56;
                used.insert(
                    k,
                    vec![
                        format!("lamp-{lamp}"),
                        format!("lamp-{}", (lamp + 1) % 56),
                        format!("lamp-{}", (lamp + 2) % 56),
                    ],
                );
                VisualFix {
                    geodetic: geo(truth + wobble * sigma),
                    heading_deg: 90.0,
                    pitch_deg: 0.0,
                    roll_deg: 0.0,
                    enu_from_rig: UnitQuaternion::identity(),
                    sigma_e_m: sigma,
                    sigma_n_m: 1.5 * sigma,
                    sigma_u_m: 2.0 * sigma,
                    horizontal_covariance_m2: Matrix2::new(cov[(0, 0)], 0.0, 0.0, cov[(1, 1)]),
                    pose_covariance: cov,
                    n_landmarks: 3 + (k % 3) as usize,
                    n_surrogates: (k % 2) as usize,
                }
            });
            FrameOutcome {
                frame: k,
                time_s: 1_778_794_200.0 + 0.1 * k as f64,
                status: if visual.is_some() { "ok" } else { "no_fix" }.into(),
                visual,
                gnss: (k % 1000 > 150).then(|| geo(truth + 2.0 * wobble)),
                unusable_images: None,
                truth: Some(Truth {
                    geodetic: geo(truth),
                    heading_deg: 90.0,
                }),
                message: String::new(),
            }
        })
        .collect();
    let info = DriveInfo {
        name: "browser <test> & co".into(),
        origin: origin(),
    };
    (info, records, MapExtras { landmarks, used })
}

/// The first Chromium found on PATH.
fn chromium() -> Option<String> {
    [
        "chromium-headless-shell",
        "chromium",
        "chromium-browser",
        "google-chrome",
    ]
    .into_iter()
    .find(|name| {
        Command::new("sh")
            .args(["-c", &format!("command -v {name}")])
            .output()
            .is_ok_and(|o| o.status.success())
    })
    .map(str::to_string)
}

#[test]
fn the_report_loads_draws_its_map_and_shows_a_clicked_frame_in_chromium() {
    let Some(browser) = chromium() else {
        println!(
            "SKIPPED report browser test: no Chromium on PATH (Debian: apt-get install chromium-headless-shell; .ci/run installs it)"
        );
        return;
    };
    let (info, records, extras) = drive();
    let report = Report::compute(&info, &records);
    let started = Instant::now();
    let html = report_html_with(&info, &records, &report, &extras);
    let generated = started.elapsed();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.html");
    std::fs::write(&path, &html).unwrap();
    let url = format!("file://{}#selftest", path.display());
    let started = Instant::now();
    let mut command = Command::new(&browser);
    if browser != "chromium-headless-shell" {
        command.arg("--headless");
    }
    let output = command
        .args([
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            // Offline: no host name resolves.
            "--host-resolver-rules=MAP * ~NOTFOUND",
            "--window-size=1200,900",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg(&url)
        .output()
        .unwrap();
    let browser_time = started.elapsed();
    let dom = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{browser}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let start = dom
        .find("<pre id=\"vgps-selftest\"")
        .and_then(|k| dom[k..].find('>').map(|j| k + j + 1))
        .expect("no #vgps-selftest in the page");
    let end = start + dom[start..].find("</pre>").unwrap();
    let text = dom[start..end]
        .replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    assert!(!text.is_empty(), "the self-test did not run: {dom:.2000}");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();
    println!(
        "report of {FRAMES} frames: {} bytes, generated in {:.3} s; {browser} done in {:.2} s; self-test {got}",
        html.len(),
        generated.as_secs_f64(),
        browser_time.as_secs_f64()
    );
    assert_eq!(got["errors"], serde_json::json!([]), "script errors");
    assert_eq!(
        got["resources"],
        serde_json::json!([]),
        "requests left the page"
    );
    assert_eq!(got["frames"], FRAMES);
    assert!(got["ink_whole_drive"].as_u64().unwrap() > 10_000, "{got}");
    // The first fix is frame 0; the click on it shows frame 0 with its status and σ.
    assert_eq!(got["clicked_frame"], 0);
    assert_eq!(got["panel_frame"], "0");
    let panel = got["panel"].as_str().unwrap();
    for part in [
        "Frame 0",
        "status ok",
        "inliers 3: 3 surveyed + 0 surrogates",
        "σ east / north / up 0.010 / 0.015 / 0.020 m",
        "landmarks used: lamp-0, lamp-1, lamp-2",
        "satellite GPS: none",
        "visual − truth",
    ] {
        assert!(panel.contains(part), "{part:?} not in {panel:?}");
    }
    // Centimetres and below: at the click the map shows a few millimetres per pixel.
    assert!(got["metres_per_pixel"].as_f64().unwrap() < 0.005, "{got}");
    assert_eq!(got["ellipses_drawn"], true);
    // The target is 2 s from navigation to the map built (measured on a quiet machine, see
    // docs/dev/journal.md); the bound here leaves room for a machine shared by builds.
    assert!(got["ready_ms"].as_f64().unwrap() < 6_000.0, "{got}");
    assert!(browser_time < Duration::from_secs(20), "{browser_time:?}");
    // Size: the vendored Leaflet (~160 kB) and ~200 bytes per frame.
    assert!(html.len() < 1_500_000, "{} bytes", html.len());
}
