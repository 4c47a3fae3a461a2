//! `vgps replay --gnss`: the satellite GPS of a simulated drive given as GPX and as NCLT
//! `gps.csv` (converted here from the drive's NMEA) gives the same `gnss_vs_truth` figures
//! as the NMEA itself; and `--from-images` counts frames with unusable images.

mod common;

use common::vgps;
use std::fmt::Write as _;
use std::path::Path;
use vgps::drive::GnssRecord;
use vgps::drive::nmea::read_nmea;

/// Simulates a short drive of `length_m` metres into `dir`.
fn simulate(dir: &Path, length_m: &str, images: bool) {
    let mut args = vec![
        "simulate",
        "--preset",
        "short",
        "--length-m",
        length_m,
        "--quiet",
        "--out",
    ];
    let d = dir.to_str().unwrap();
    args.push(d);
    if images {
        args.push("--images");
    }
    let o = vgps(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn replay(drive: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "replay",
        drive.to_str().unwrap(),
        "--quiet",
        "--format",
        "json",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = vgps(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The drive's NMEA epochs.
fn nmea_records(drive: &Path) -> Vec<GnssRecord> {
    let text = std::fs::read_to_string(drive.join("gnss.nmea")).unwrap();
    let (records, stats) = read_nmea(&text);
    assert_eq!(stats.skipped(), 0);
    records
}

/// A GPX 1.1 track of the records, written with the `gpx` crate.
fn to_gpx(records: &[GnssRecord]) -> String {
    let mut segment = gpx::TrackSegment::new();
    for r in records {
        let (lat, lon, alt) = r.fix.map_or((0.0, 0.0, 0.0), |f| {
            (f.position.lat_deg, f.position.lon_deg, f.position.alt_m)
        });
        let mut p = gpx::Waypoint::new((lon, lat).into());
        p.elevation = Some(alt);
        let nanos = (r.time_s * 1e9).round() as i128;
        p.time = Some(
            time::OffsetDateTime::from_unix_timestamp_nanos(nanos)
                .unwrap()
                .into(),
        );
        match r.fix {
            Some(f) => {
                p.fix = Some(gpx::Fix::ThreeDimensional);
                p.sat = f.num_sats.map(u64::from);
                p.hdop = f.hdop;
            }
            None => p.fix = Some(gpx::Fix::None),
        }
        segment.points.push(p);
    }
    let mut track = gpx::Track::new();
    track.segments.push(segment);
    let doc = gpx::Gpx {
        version: gpx::GpxVersion::Gpx11,
        creator: Some("cli_replay_gnss".into()),
        tracks: vec![track],
        ..gpx::Gpx::default()
    };
    let mut bytes = Vec::new();
    gpx::write(&doc, &mut bytes).unwrap();
    String::from_utf8(bytes).unwrap()
}

/// NCLT `gps.csv` rows of the records (no fix: mode 1 and NaN, as NCLT logs it).
fn to_nclt(records: &[GnssRecord]) -> String {
    let mut s = String::new();
    for r in records {
        let utime = (r.time_s * 1e6).round() as i64;
        match r.fix {
            Some(f) => writeln!(
                s,
                "{utime},3,{},{},{},{},0.0,0.0",
                f.num_sats.unwrap_or(0),
                f.position.lat_deg.to_radians(),
                f.position.lon_deg.to_radians(),
                f.position.alt_m
            ),
            None => writeln!(s, "{utime},1,0,NaN,NaN,NaN,NaN,NaN"),
        }
        .unwrap();
    }
    s
}

fn assert_same_gnss_figures(a: &serde_json::Value, b: &serde_json::Value, what: &str) {
    let (ga, gb) = (&a["gnss_vs_truth"], &b["gnss_vs_truth"]);
    assert!(ga.is_object(), "{what}: {a}");
    assert_eq!(ga["n"], gb["n"], "{what}");
    for key in ["cep50", "cep95", "rms", "max"] {
        let (x, y) = (
            ga["horizontal_m"][key].as_f64().unwrap(),
            gb["horizontal_m"][key].as_f64().unwrap(),
        );
        assert!((x - y).abs() < 1e-4, "{what} {key}: {x} vs {y}");
    }
    let (x, y) = (
        ga["vertical_rms_m"].as_f64().unwrap(),
        gb["vertical_rms_m"].as_f64().unwrap(),
    );
    assert!((x - y).abs() < 1e-4, "{what} vertical: {x} vs {y}");
    assert_eq!(a["blackout"]["frames"], b["blackout"]["frames"], "{what}");
}

#[test]
fn gpx_and_nclt_give_the_figures_of_the_nmea() {
    let dir = tempfile::tempdir().unwrap();
    let drive = dir.path().join("drive");
    simulate(&drive, "120", false);
    let records = nmea_records(&drive);
    assert!(records.len() > 20);
    let gpx_path = dir.path().join("track.gpx");
    std::fs::write(&gpx_path, to_gpx(&records)).unwrap();
    // An extension that says nothing: the content decides.
    let nclt_path = dir.path().join("gps.txt");
    std::fs::write(&nclt_path, to_nclt(&records)).unwrap();

    let base = replay(&drive, &dir.path().join("r0"), &["--no-gnss-prior"]);
    let from_gpx = replay(
        &drive,
        &dir.path().join("r1"),
        &["--no-gnss-prior", "--gnss", gpx_path.to_str().unwrap()],
    );
    let from_nclt = replay(
        &drive,
        &dir.path().join("r2"),
        &[
            "--no-gnss-prior",
            "--gnss",
            nclt_path.to_str().unwrap(),
            "--gnss-format",
            "nclt",
        ],
    );
    assert_same_gnss_figures(&base, &from_gpx, "gpx");
    assert_same_gnss_figures(&base, &from_nclt, "nclt");
    // The visual solution does not use the satellite without the prior: identical.
    assert_eq!(base["visual_vs_truth"], from_gpx["visual_vs_truth"]);
}

#[test]
fn bad_gnss_files_exit_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let drive = dir.path().join("drive");
    simulate(&drive, "40", false);
    let bad = dir.path().join("gps.csv");
    std::fs::write(
        &bad,
        "1326030000000000,3,9,0.73,-1.46,270,0,0\n1326030001000000,3,x,0.73,-1.46,270,0,0\n",
    )
    .unwrap();
    let o = vgps(&[
        "replay",
        drive.to_str().unwrap(),
        "--quiet",
        "--gnss",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("gps.csv:2: field `num_sats`"), "{e}");
    let o = vgps(&["replay", drive.to_str().unwrap(), "--gnss-format", "gpx"]);
    assert_eq!(o.status.code(), Some(2), "--gnss-format needs --gnss");
}

#[test]
fn frames_with_unusable_images_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let drive = dir.path().join("drive");
    simulate(&drive, "25", true);
    let frames = std::fs::read_to_string(drive.join("frames.csv")).unwrap();
    let rows: Vec<Vec<String>> = frames
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert!(rows.len() >= 6, "{} frames", rows.len());
    // Frame row 2: one image missing, one corrupt; frame row 4: every image missing.
    std::fs::remove_file(drive.join(&rows[2][2])).unwrap();
    std::fs::write(drive.join(&rows[2][3]), b"\x89PNG\r\n\x1a\ntruncated").unwrap();
    for name in &rows[4][2..] {
        std::fs::remove_file(drive.join(name)).unwrap();
    }
    let out = dir.path().join("r");
    let report = replay(&drive, &out, &["--from-images", "--threads", "2"]);
    let images = &report["images"];
    assert_eq!(images["frames"], rows.len() as u64);
    assert_eq!(images["frames_with_unusable_images"], 2);
    assert_eq!(images["frames_partially_usable"], 1);
    assert_eq!(images["unusable_images"], 2 + (rows[4].len() as u64 - 2));
    assert_eq!(report["status_counts"]["bad_image"], 1);
    let mut csv = csv::Reader::from_path(out.join("fixes.csv")).unwrap();
    let header: Vec<String> = csv.headers().unwrap().iter().map(String::from).collect();
    let n = header.len();
    assert_eq!(header[n - 2..], ["unusable_images", "message"]);
    let records: Vec<csv::StringRecord> = csv.records().map(Result::unwrap).collect();
    let counts: Vec<&str> = records.iter().map(|r| &r[n - 2]).collect();
    assert_eq!(counts[2], "2");
    assert_eq!(counts[4], (rows[4].len() - 2).to_string());
    // The frame without a usable image says why, naming its missing files.
    assert_eq!(&records[4][2], "bad_image");
    assert!(
        records[4][n - 1].contains(&rows[4][2]),
        "{:?}",
        &records[4][n - 1]
    );
    // Every frame says why it has its status.
    for r in &records {
        assert!(!r[n - 1].is_empty(), "{r:?}");
    }
    assert_eq!(counts[0], "0");
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(
        summary.contains("2 with unusable images (1 localized with the rest)"),
        "{summary}"
    );
}
