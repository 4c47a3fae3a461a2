//! The NCLT import on a session built around a real slice of NCLT's `gps.csv`
//! (`tests/data/nclt`, ODbL): frames from `lb3/Cam*/<utime>.tiff`, the consumer GPS as the
//! drive's satellite GPS, the ground truth interpolated into `truth.csv`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vgps_import::nclt::{NcltImportOptions, enu_from_rig_of_rpy, geodetic_of_local, import_nclt};
use vgps_replay::drive::{Drive, Strictness};

const T0_US: i64 = 1_353_099_827_000_000;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data")
}

/// A session: 10 frames 200 ms apart (camera 5 lacks frame 3), the real gps.csv under
/// `sensor_data/`, a ground truth moving north at 1 m/s with a NaN first row and a bad row.
fn session(root: &Path) {
    for cam in 0..6 {
        let dir = root.join("2012-11-16/lb3").join(format!("Cam{cam}"));
        std::fs::create_dir_all(&dir).unwrap();
        for k in 0..10 {
            if cam == 5 && k == 3 {
                continue;
            }
            std::fs::write(dir.join(format!("{}.tiff", T0_US + k * 200_000)), b"").unwrap();
        }
    }
    let sensors = root.join("sensor_data/2012-11-16");
    std::fs::create_dir_all(&sensors).unwrap();
    std::fs::copy(data().join("nclt/gps.csv"), sensors.join("gps.csv")).unwrap();
    std::fs::write(
        sensors.join("gps_rtk.csv"),
        "1353099827000000,3,9,0.7381,-1.4609,270,0,0\n",
    )
    .unwrap();
    let mut gt = String::from("1353099826400000,nan,nan,nan,nan,nan,nan\n");
    for k in 0..40 {
        let t = T0_US - 500_000 + k * 100_000;
        let dt = (t - T0_US) as f64 * 1e-6;
        writeln!(gt, "{t},{},-5,-2,0,0,0.5", 10.0 + dt).unwrap();
        if k == 20 {
            gt.push_str("oops,1,2\n");
        }
    }
    let gt_dir = root.join("ground_truth");
    std::fs::create_dir_all(&gt_dir).unwrap();
    std::fs::write(gt_dir.join("groundtruth_2012-11-16.csv"), gt).unwrap();
}

#[test]
fn an_nclt_session_becomes_a_drive() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("session");
    session(&root);
    let out = dir.path().join("drive");
    let options = NcltImportOptions {
        rig: data().join("mcap/small_rig.json"),
        landmarks: None,
        stamp_tolerance_s: 0.01,
        origin_alt_m: 270.0,
    };
    let (manifest, report) = import_nclt(&root, &out, &options).unwrap();
    assert_eq!(manifest.gnss.as_deref(), Some("gps.csv"));
    assert_eq!(report.frames, 10);
    assert_eq!(report.images, 59);
    assert_eq!(report.frames_missing_cameras, 1);
    let w = report.warnings.join("\n");
    assert!(
        w.contains("groundtruth_2012-11-16.csv:23: 3 fields, expected 7"),
        "{w}"
    );
    assert!(out.join("gps_rtk.csv").is_file());
    let drive = Drive::open(&out, Strictness::Strict).unwrap();
    let frames = drive.frames();
    assert_eq!(frames[3].images[5], None);
    assert!((frames[9].time_s - 1_353_099_828.8).abs() < 1e-6);
    // The real consumer GPS, read by the drive's NCLT reader.
    let stats = drive.gnss_stats().unwrap();
    assert_eq!(stats.entries, 60);
    assert!(stats.fixes > 20, "{stats:?}");
    // Truth: the ground truth at each frame's time, in the drive's conventions.
    assert_eq!(drive.truth().len(), 10);
    let want_q = enu_from_rig_of_rpy([0.0, 0.0, 0.5]);
    for (t, f) in drive.truth().iter().zip(frames) {
        let dt = f.time_s - T0_US as f64 * 1e-6;
        let want = geodetic_of_local([10.0 + dt, -5.0, -2.0], 270.0).unwrap();
        assert!((t.position.lat_deg - want.lat_deg).abs() < 1e-9, "{t:?}");
        assert!((t.position.lon_deg - want.lon_deg).abs() < 1e-9);
        assert!((t.position.alt_m - 272.0).abs() < 1e-9);
        assert!(t.enu_from_rig.angle_to(&want_q) < 1e-6);
    }
}

#[test]
fn a_session_without_lb3_is_an_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("drive");
    let options = NcltImportOptions {
        rig: data().join("mcap/small_rig.json"),
        landmarks: None,
        stamp_tolerance_s: 0.01,
        origin_alt_m: 0.0,
    };
    let e = import_nclt(dir.path(), &out, &options).unwrap_err();
    assert!(e.to_string().contains("no `lb3` folder"), "{e}");
    assert!(!out.exists());
}
