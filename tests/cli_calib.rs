//! `vgps calib …` end to end: exit codes, figures, CSV round trips, conversion.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use vgps::calibration::load;

fn manifest(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn vgps(args: &[&str], stdin: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vgps"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        .unwrap();
    child.wait_with_output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The number before `suffix` on the line of `out` that contains `key`.
fn figure(out: &str, key: &str, suffix: &str) -> f64 {
    let line = out.lines().find(|l| l.contains(key)).unwrap_or_else(|| {
        panic!("no line with `{key}` in\n{out}");
    });
    let before = line.split(suffix).next().unwrap();
    before
        .rsplit([' ', ':'])
        .find(|s| !s.is_empty())
        .unwrap()
        .parse()
        .unwrap_or_else(|_| panic!("no number before `{suffix}` in `{line}`"))
}

#[test]
fn show_reports_cameras_fields_of_view_coverage_and_overlaps() {
    let out = vgps(&["calib", "show", "calibration/ladybug2.json"], "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let s = text(&out.stdout);
    assert!(s.contains("6 camera(s)"), "{s}");
    assert_eq!(s.matches("kannala_brandt 1024×768 px").count(), 6);
    // Wide-angle: more than 72° across so that neighbours overlap.
    let across = figure(&s, "field of view", "° across");
    assert!(across > 80.0 && across < 140.0, "{across}");
    // Most of the sphere above −30° elevation.
    let above = figure(&s, "above -30° elevation", " %");
    assert!(above >= 99.0, "{above}");
    let overlap = figure(&s, "cameras 0 and 1", " %");
    assert!(overlap > 0.5, "{overlap}");
    let total = figure(&s, "sphere covered", " %");
    assert!(total > 80.0 && total < 100.0, "{total}");
}

#[test]
fn check_passes_on_every_shipped_file_with_figures() {
    for file in [
        "calibration/ladybug2.json",
        "calibration/ladybug2_lut.json",
        "calibration/equirectangular_2048x1024.json",
        "calibration/ladybug5_example.ini",
        "calibration/nclt_example",
    ] {
        let out = vgps(&["calib", "check", file], "");
        let s = text(&out.stdout);
        assert!(out.status.success(), "{file}: {s}{}", text(&out.stderr));
        assert!(s.contains("check: ok"), "{s}");
        let worst = s
            .lines()
            .filter(|l| l.contains("round trip pixel"))
            .map(|l| figure(l, "round trip", " px (limit"))
            .fold(0.0, f64::max);
        assert!(worst <= 1e-6, "{file}: {worst}");
    }
}

#[test]
fn check_fails_with_exit_code_2_on_a_folded_lut() {
    use vgps::calibration::{Camera, Lut, LutParams, Pinhole, PinholeParams, Rig};
    let pinhole = Pinhole::new(PinholeParams::ideal(32, 24, 30.0, 30.0, 15.5, 11.5)).unwrap();
    let lut = Lut::from_model(&pinhole, 4).unwrap();
    // Swap two node columns: the table folds over itself (loads, but is not monotonic).
    let mut params: LutParams = lut.params().clone();
    let (cols, _) = lut.grid_size();
    for row in params.bearings.chunks_mut(cols) {
        row.swap(2, 3);
    }
    let folded = Lut::new(params).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("folded.json");
    vgps::calibration::save_native(&Rig::panorama(Camera::from(folded)), &path).unwrap();
    let out = vgps(&["calib", "check", path.to_str().unwrap()], "");
    assert_eq!(out.status.code(), Some(2));
    let s = text(&out.stdout);
    assert!(s.contains("LUT monotonicity") && s.contains("FAIL"), "{s}");
    assert!(text(&out.stderr).contains("folded.json: check failed"));
}

#[test]
fn bad_files_exit_2_naming_file_location_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let ini =
        std::fs::read_to_string(manifest("tests/fixtures/calibration/ladybug_64x48.ini")).unwrap();
    let native =
        std::fs::read_to_string(manifest("calibration/equirectangular_2048x1024.json")).unwrap();
    let cases: Vec<(&str, String, Vec<&str>, [&str; 3])> = vec![
        (
            "missing.ini",
            ini.replace("camera2_transZ = 0\n", ""),
            vec![],
            ["missing.ini", "key camera2_transZ", "missing key"],
        ),
        (
            "extra.ini",
            format!("{ini}camera0_rotX = 0\n"),
            vec![],
            ["extra.ini", "key camera0_rotX", "repeated key"],
        ),
        (
            "model.json",
            native.replace("equirectangular", "cubemap"),
            vec![],
            ["model.json", "line 7", "unknown variant `cubemap`"],
        ),
        (
            "rotation.json",
            native.replace("[0.0, 0.0, 1.0]", "[0.0, 0.0, 2.0]"),
            vec![],
            [
                "rotation.json",
                "rig_from_camera.rotation",
                "not a rotation",
            ],
        ),
        (
            "size.ini",
            ini.clone(),
            vec!["--image-size", "100x100"],
            ["size.ini", "key image_width", "contradicts"],
        ),
        (
            "format.ini",
            ini.clone(),
            vec!["--format", "native"],
            ["format.ini", "line 1 column", "expected value"],
        ),
    ];
    for (name, content, extra, expected) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        for sub in ["show", "check"] {
            let mut args = vec!["calib", sub, path.to_str().unwrap()];
            args.extend(&extra);
            let out = vgps(&args, "");
            assert_eq!(out.status.code(), Some(2), "{name}");
            let err = text(&out.stderr);
            for part in expected {
                assert!(err.contains(part), "{name}: `{err}` lacks `{part}`");
            }
        }
    }
    // Bad command-line values are usage errors, exit code 2 too.
    let out = vgps(&["calib", "show", "x", "--image-size", "12"], "");
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bearings_then_pixels_round_trips_through_csv() {
    let mut input = String::from("camera,u,v\n");
    for k in 0..6 {
        for (u, v) in [
            (511.5, 383.5),
            (0.0, 0.0),
            (1023.0, 767.0),
            (100.25, 600.75),
        ] {
            input += &format!("{k},{u},{v}\n");
        }
    }
    let cal = ["--calibration", "calibration/ladybug2.json"];
    let out = vgps(&[&["calib", "bearings"][..], &cal[..]].concat(), &input);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let rays = text(&out.stdout);
    let mut lines = rays.lines();
    assert_eq!(lines.next(), Some("camera,u,v,ox,oy,oz,bx,by,bz"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 24);
    for r in &rows {
        let n = (r[6] * r[6] + r[7] * r[7] + r[8] * r[8]).sqrt();
        assert!((n - 1.0).abs() < 1e-12);
    }
    // Camera 0's centre looks along +x from (0.04, 0, 0); the top camera's along +z.
    assert_eq!(&rows[0][3..9], &[0.04, 0.0, 0.0, 1.0, 0.0, 0.0]);
    assert!((rows[20][8] - 1.0).abs() < 1e-12);
    // Feed the rays back: the point o + b lies on the ray, so its camera sees it at the
    // same pixel.
    let out = vgps(&[&["calib", "pixels"][..], &cal[..]].concat(), &rays);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let back = text(&out.stdout);
    assert!(back.starts_with("index,camera,u,v\n"));
    let seen: Vec<Vec<f64>> = back
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    for (i, r) in rows.iter().enumerate() {
        let hit = seen
            .iter()
            .find(|s| s[0] as usize == i && s[1] == r[0])
            .unwrap_or_else(|| panic!("row {i} not seen by its camera"));
        let error = ((hit[2] - r[1]).powi(2) + (hit[3] - r[2]).powi(2)).sqrt();
        assert!(error <= 1e-6, "row {i}: {error}");
    }
    // Directions without a header: +x is seen by camera 0 at its centre (and by no other
    // camera with a pixel there).
    let out = vgps(&[&["calib", "pixels"][..], &cal[..]].concat(), "1,0,0\n");
    let s = text(&out.stdout);
    assert!(s.lines().any(|l| l == "0,0,511.5,383.5"), "{s}");
}

#[test]
fn bearings_of_the_ini_fixture_are_the_known_answers() {
    let out = vgps(
        &[
            "calib",
            "bearings",
            "--calibration",
            "tests/fixtures/calibration/ladybug_no_size.ini",
        ],
        "0,31.5,23.5\n5,31.5,23.5\n0,-8.5,23.5\n",
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let s = text(&out.stdout);
    let rows: Vec<Vec<f64>> = s
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
    assert!(close(&rows[0][6..], &[1.0, 0.0, 0.0]), "{s}");
    assert!(close(&rows[1][6..], &[0.0, 0.0, 1.0]), "{s}");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // 40 px left of the centre (unbounded image): camera x → rig −z, so 45° up.
    assert!(close(&rows[2][6..], &[h, 0.0, h]), "{s}");
}

#[test]
fn bad_csv_lines_exit_2_naming_the_line() {
    let cal = "calibration/ladybug2.json";
    for (sub, input, expected) in [
        (
            "bearings",
            "0,1,2\n7,1,2\n",
            "line 2: unknown camera index 7",
        ),
        ("bearings", "0,1,2\n0,x,2\n", "line 2: field u = `x`"),
        ("bearings", "0,-5,2\n", "line 1: pixel (-5, 2) is outside"),
        (
            "pixels",
            "bx,by,bz\n1,0,0\n0,0,0\n",
            "line 3: the direction is zero",
        ),
        ("pixels", "1,0,nan\n", "line 1: field bz = `nan`"),
    ] {
        let out = vgps(&["calib", sub, "--calibration", cal], input);
        assert_eq!(out.status.code(), Some(2), "{sub} {input}");
        let err = text(&out.stderr);
        assert!(err.contains(expected), "`{err}` lacks `{expected}`");
    }
}

#[test]
fn convert_writes_native_and_lut_atomically() {
    let dir = tempfile::tempdir().unwrap();
    // NCLT → native: the same rig.
    let out_json = dir.path().join("nclt.json");
    let out = vgps(
        &[
            "calib",
            "convert",
            "calibration/nclt_example",
            "--to",
            "native",
            out_json.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let original = load(&manifest("calibration/nclt_example"), None, None).unwrap();
    assert_eq!(load(&out_json, None, None).unwrap(), original);
    // Ladybug2 → LUT (step 16 to keep the test fast): six side files, same placements.
    let out_lut = dir.path().join("lb2_lut.json");
    let out = vgps(
        &[
            "calib",
            "convert",
            "calibration/ladybug2.json",
            "--to",
            "lut",
            "--step",
            "16",
            out_lut.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let rig = load(&out_lut, None, None).unwrap();
    assert_eq!(rig.len(), 6);
    assert!(rig.cameras().iter().all(|c| c.model.model_name() == "lut"));
    for i in 0..6 {
        assert!(dir.path().join(format!("lb2_lut.cam{i}.lut")).is_file());
    }
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "{names:?}");
    // An unbounded INI has no LUT: exit 2, the input named.
    let out = vgps(
        &[
            "calib",
            "convert",
            "tests/fixtures/calibration/ladybug_no_size.ini",
            "--to",
            "lut",
            dir.path().join("x.json").to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("ladybug_no_size.ini: camera 0"));
    assert!(!dir.path().join("x.json").exists());
}
