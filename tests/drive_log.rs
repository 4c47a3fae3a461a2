//! Drive logs: the manifest, the tables and their errors, on drives written by the simulator.
use nalgebra::UnitQuaternion;
use std::fmt::Write as _;
use std::path::Path;
use vgps::drive::gnss::GnssFormat;
use vgps::drive::*;
use vgps::geo::Geodetic;
use vgps::io::Landmark;
use vgps::simulate::{Preset, Scenario, simulate};

fn small_drive() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut sc = Scenario::preset(Preset::Short, 11);
    sc.length_m = 120.0;
    simulate(&sc).unwrap().write(dir.path()).unwrap();
    dir
}

fn manifest(text: &str, strictness: Strictness) -> Result<(Manifest, Vec<String>), DriveError> {
    Manifest::parse(Path::new("d/drive.json"), text, strictness)
}

#[test]
fn manifest_strict_and_lenient() {
    let good =
        r#"{"version": 1, "calibration": "c.json", "landmarks": "l.csv", "frames": "f.csv"}"#;
    let (m, w) = manifest(good, Strictness::Strict).unwrap();
    assert_eq!(
        (m.detections, m.gnss, m.truth, w.len()),
        (None, None, None, 0)
    );
    let extra = "{\"version\": 1, \"calibration\": \"c.json\", \"landmarks\": \"l.csv\",\n\"frames\": \"f.csv\",\n \"camera_model\": 3}";
    let e = manifest(extra, Strictness::Strict).unwrap_err().to_string();
    assert!(
        e.starts_with("d/drive.json:3: field `camera_model`: unknown key"),
        "{e}"
    );
    let (m, w) = manifest(extra, Strictness::Lenient).unwrap();
    assert_eq!(m.frames, "f.csv");
    assert_eq!(w.len(), 1);
    assert!(w[0].contains("d/drive.json:3: field `camera_model`") && w[0].ends_with("ignored"));
    let cases = [
        (
            r#"{"version": 2, "calibration": "c", "landmarks": "l", "frames": "f"}"#,
            "d/drive.json:1: field `version`: version 2 is not supported",
        ),
        (
            r#"{"version": 1, "calibration": "c", "landmarks": "l"}"#,
            "d/drive.json:1: field `frames`: required key is missing",
        ),
        (
            r#"{"version": 1, "calibration": "c", "landmarks": 5, "frames": "f"}"#,
            "d/drive.json:1: field `landmarks`: `5` is not a file name",
        ),
        (
            "[1, 2]",
            "d/drive.json:1: field `json`: the manifest is not a JSON object",
        ),
        ("{\n\"version\": 1,,", "d/drive.json:2: field `json`"),
    ];
    for (text, expected) in cases {
        let e = manifest(text, Strictness::Lenient).unwrap_err().to_string();
        assert!(e.starts_with(expected), "{e}");
    }
    // The standard manifest round-trips through its writer.
    let dir = tempfile::tempdir().unwrap();
    write_manifest(dir.path(), &Manifest::standard()).unwrap();
    let text = std::fs::read_to_string(dir.path().join(MANIFEST_NAME)).unwrap();
    assert_eq!(
        manifest(&text, Strictness::Strict).unwrap().0,
        Manifest::standard()
    );
}

#[test]
fn frames_detections_truth_landmarks_round_trip() {
    let p = Path::new("f.csv");
    let frames = vec![
        FrameRecord {
            frame: 0,
            time_s: 1_778_794_200.0666666,
            images: vec![Some("a/0.jpg".into()), None, Some("a/2.jpg".into())],
        },
        FrameRecord {
            frame: 3,
            time_s: 1_778_794_200.2,
            images: vec![None, None, None],
        },
    ];
    assert_eq!(
        frames_from_text(p, &frames_to_csv(&frames)).unwrap(),
        frames
    );
    let pano = vec![FrameRecord {
        frame: 1,
        time_s: 0.5,
        images: vec![Some("p.jpg".into())],
    }];
    let text = frames_to_csv(&pano);
    assert!(text.starts_with("frame,time_s,image\n"));
    assert_eq!(frames_from_text(p, &text).unwrap(), pano);

    let detections = vec![
        PixelDetection {
            frame: 0,
            camera: 5,
            u: 12.345,
            v: -0.5,
            strength: Some(0.25),
            class: Some("streetlight".into()),
        },
        PixelDetection {
            frame: 3,
            camera: 0,
            u: 1023.5,
            v: 767.499,
            strength: None,
            class: None,
        },
    ];
    let rows =
        detections_from_text(Path::new("d.csv"), &detections_to_csv(&detections), 6).unwrap();
    let back: Vec<PixelDetection> = rows
        .into_iter()
        .map(|r| match r {
            DetectionRow::Ok(d) => d,
            _ => panic!("bad row"),
        })
        .collect();
    assert_eq!(back, detections);

    let truth = vec![TruthRecord {
        frame: 3,
        position: Geodetic::try_new(37.7793, -122.4193, -12.5).unwrap(),
        enu_from_rig: UnitQuaternion::from_euler_angles(0.01, -0.02, 1.2),
    }];
    let back = truth_from_text(Path::new("t.csv"), &truth_to_csv(&truth), &frames).unwrap();
    assert_eq!(back[0].position, truth[0].position);
    assert!(back[0].enu_from_rig.angle_to(&truth[0].enu_from_rig) < 1e-15);

    let landmarks = vec![Landmark {
        id: "L1".into(),
        lat_deg: 37.123456789012345,
        lon_deg: -122.5,
        alt_m: 7.25,
        sigma_m: Some(0.02),
        class: Some("streetlight".into()),
        line: 2,
    }];
    let back =
        vgps_io::landmarks_from_reader(Path::new("l.csv"), landmarks_to_csv(&landmarks).as_bytes())
            .unwrap();
    assert_eq!(back, landmarks);
}

#[test]
fn csv_errors_name_file_line_and_field() {
    let f = |t: &str| {
        frames_from_text(Path::new("f.csv"), t)
            .unwrap_err()
            .to_string()
    };
    assert_eq!(
        f("frame,time_s\n0,1\n0,2\n"),
        "f.csv:3: field `frame`: frame 0 does not follow frame 0 (frames must increase)"
    );
    assert_eq!(
        f("frame,time_s\n0,x\n"),
        "f.csv:2: field `time_s`: `x` is not a number"
    );
    assert_eq!(
        f("frame,time_s\n-1,0\n"),
        "f.csv:2: field `frame`: `-1` is not a non-negative integer"
    );
    assert!(f("frame,time_s,image,image_0\n").starts_with("f.csv:1: field `image_0`: give either"));
    let frames = frames_from_text(Path::new("f.csv"), "frame,time_s\n0,1\n").unwrap();
    let t = |text: &str| {
        truth_from_text(Path::new("t.csv"), text, &frames)
            .unwrap_err()
            .to_string()
    };
    let h = "frame,lat,lon,alt,qw,qx,qy,qz\n";
    assert_eq!(
        t(&format!("{h}0,37,-122,0,2,0,0,0\n")),
        "t.csv:2: field `qw`: quaternion norm 2 is not 1 within 0.001"
    );
    assert_eq!(
        t(&format!("{h}5,37,-122,0,1,0,0,0\n")),
        "t.csv:2: field `frame`: frame 5 is not in the frames file"
    );
    assert_eq!(
        t(&format!("{h}0,91,-122,0,1,0,0,0\n")),
        "t.csv:2: field `lat`: latitude 91 is outside [-90, 90] degrees"
    );
}

#[test]
fn opens_a_written_drive_and_survives_bad_detection_rows() {
    let dir = small_drive();
    let drive = Drive::open(dir.path(), Strictness::Strict).unwrap();
    let s = drive.summary();
    assert!(s.frames > 30 && s.detections > 10 * s.frames, "{s:?}");
    assert_eq!((s.bad_rows, s.truth), (0, s.frames));
    assert!(s.gnss_fixes > 0 && s.gnss_records >= s.gnss_fixes);
    assert!(drive.warnings().is_empty());
    let t0 = drive.frames()[0].time_s;
    assert_eq!(drive.gnss_between(t0 - 1e-3, t0 + 0.3).len(), 2);
    assert!(drive.truth_of(drive.frames()[1].frame).is_some());

    // Break some rows: a bad pixel in frame 2, invalid UTF-8 in frame 4, an unknown frame,
    // an unreadable frame number, a camera not in the rig.
    let path = dir.path().join("detections.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let row_of = |frame: u64, lines: &[String]| {
        lines
            .iter()
            .position(|l| l.starts_with(&format!("{frame},")))
            .unwrap()
    };
    let k2 = row_of(2, &lines);
    lines[k2] = "2,0,abc,5,,corner".into();
    let k3 = row_of(3, &lines);
    lines[k3] = "3,9,1,5,,corner".into();
    lines.push("99999,0,1,1,,".into());
    lines.push("x,0,1,1,,".into());
    let mut bytes = lines.join("\n").into_bytes();
    bytes.extend_from_slice(b"\n4,0,1\xff,2,,\n");
    std::fs::write(&path, &bytes).unwrap();
    let broken = Drive::open(dir.path(), Strictness::Strict).unwrap();
    let b = broken.summary();
    assert_eq!(
        (b.bad_rows, b.frames_with_bad_rows, b.orphan_rows),
        (5, 3, 2),
        "{b:?}"
    );
    assert_eq!(b.detections, s.detections - 2);
    match broken.status(2) {
        FrameStatus::BadRows(m) => assert_eq!(
            m,
            vec![format!(
                "{}:{}: field `u`: `abc` is not a number",
                path.display(),
                k2 + 1
            )]
        ),
        FrameStatus::Ok => panic!("frame 2 should be flagged"),
    }
    match broken.status(3) {
        FrameStatus::BadRows(m) => {
            assert!(m[0].ends_with("field `camera`: camera 9 is not in the rig (it has 6)"))
        }
        FrameStatus::Ok => panic!("frame 3 should be flagged"),
    }
    assert!(matches!(broken.status(4), FrameStatus::BadRows(_)));
    assert_eq!(broken.status(1), FrameStatus::Ok);
    assert_eq!(broken.detections(1), drive.detections(1));
}

#[test]
fn lenient_drive_keeps_warnings_and_strict_names_the_key() {
    let dir = small_drive();
    let path = dir.path().join(MANIFEST_NAME);
    let text =
        std::fs::read_to_string(&path)
            .unwrap()
            .replacen("{", "{\n  \"weather\": \"fog\",", 1);
    std::fs::write(&path, text).unwrap();
    let e = Drive::open(dir.path(), Strictness::Strict)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("drive.json:2: field `weather`: unknown key"),
        "{e}"
    );
    let drive = Drive::open(dir.path(), Strictness::Lenient).unwrap();
    assert_eq!(drive.warnings().len(), 1);
    // A corrupted NMEA file is read with its bad lines counted, never fatal.
    let nmea = dir.path().join("gnss.nmea");
    let mut text = std::fs::read_to_string(&nmea).unwrap();
    text.insert_str(0, "garbage line\n");
    text.push_str("$GPGGA,2130");
    std::fs::write(&nmea, text).unwrap();
    let drive = Drive::open(dir.path(), Strictness::Lenient).unwrap();
    let stats = drive.nmea_stats().unwrap();
    assert_eq!((stats.garbage, stats.truncated), (1, 1));
    assert_eq!(drive.warnings().len(), 2);
}

#[test]
fn missing_files_are_named() {
    let dir = small_drive();
    std::fs::remove_file(dir.path().join("frames.csv")).unwrap();
    let e = Drive::open(dir.path(), Strictness::Strict)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frames.csv: cannot read the file"), "{e}");
}

#[test]
fn a_manifest_naming_an_nclt_file_reads_the_same_epochs_as_the_nmea() {
    let dir = tempfile::tempdir().unwrap();
    let mut scenario = Scenario::preset(Preset::Short, 3);
    scenario.length_m = 120.0;
    simulate(&scenario).unwrap().write(dir.path()).unwrap();
    let nmea = Drive::open(dir.path(), Strictness::Strict).unwrap();
    assert!(nmea.gnss().len() > 20);
    let mut csv = String::new();
    for r in nmea.gnss() {
        let utime = (r.time_s * 1e6).round() as i64;
        match r.fix {
            Some(f) => writeln!(
                csv,
                "{utime},3,{},{},{},{}",
                f.num_sats.unwrap_or(0),
                f.position.lat_rad(),
                f.position.lon_rad(),
                f.position.alt_m
            ),
            None => writeln!(csv, "{utime},0,0,nan,nan,nan"),
        }
        .unwrap();
    }
    std::fs::write(dir.path().join("gps.csv"), csv).unwrap();
    let manifest = Manifest {
        gnss: Some("gps.csv".into()),
        ..Manifest::standard()
    };
    write_manifest(dir.path(), &manifest).unwrap();
    let nclt = Drive::open(dir.path(), Strictness::Strict).unwrap();
    let stats = nclt.gnss_stats().unwrap();
    assert_eq!(stats.format, GnssFormat::Nclt);
    assert!(nclt.nmea_stats().is_none());
    assert_eq!(nclt.gnss().len(), nmea.gnss().len());
    for (a, b) in nmea.gnss().iter().zip(nclt.gnss()) {
        assert!((a.time_s - b.time_s).abs() < 1e-6);
        assert_eq!(a.fix.is_some(), b.fix.is_some());
        if let (Some(x), Some(y)) = (a.fix, b.fix) {
            assert!((x.position.lat_deg - y.position.lat_deg).abs() < 1e-9);
            assert!((x.position.lon_deg - y.position.lon_deg).abs() < 1e-9);
            assert!((x.position.alt_m - y.position.alt_m).abs() < 1e-9);
        }
    }
    assert_eq!(
        stats.no_fix,
        nmea.gnss().iter().filter(|r| r.fix.is_none()).count()
    );
}
