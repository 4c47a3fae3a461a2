//! Calibration file formats: round trips, known geometry, detection and bad input.

use nalgebra::{Vector2, Vector3};
use std::f64::consts::{FRAC_1_SQRT_2, TAU};
use std::path::{Path, PathBuf};
use vgps::calibration::formats::{detect::detect, native};
use vgps::calibration::{Camera, CameraModel, Format, LoadError, load};
use vgps::synthetic::calibration_files as synth;

/// Pixel → bearing → pixel round-trip tolerance of every format (pixels).
const ROUND_TRIP_PX: f64 = 1e-6;

fn manifest(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn fixture(name: &str) -> PathBuf {
    manifest(&format!("tests/fixtures/calibration/{name}"))
}

/// Every shipped file and fixture, with its format.
fn all_calibrations() -> Vec<(PathBuf, Format)> {
    vec![
        (manifest("calibration/ladybug2.json"), Format::Native),
        (manifest("calibration/ladybug2_lut.json"), Format::Native),
        (
            manifest("calibration/equirectangular_2048x1024.json"),
            Format::Native,
        ),
        (
            manifest("calibration/ladybug5_example.ini"),
            Format::LadybugIni,
        ),
        (manifest("calibration/nclt_example"), Format::Nclt),
        (fixture("native_mixed.json"), Format::Native),
        (fixture("ladybug_64x48.ini"), Format::LadybugIni),
        (fixture("ladybug_no_size.ini"), Format::LadybugIni),
        (fixture("nclt_16x12"), Format::Nclt),
    ]
}

/// A deterministic grid of pixels over the valid image of a camera (inset by 0.01 px, with
/// irrational offsets); for an unbounded image a wide area around the principal point.
fn probe_pixels(model: &Camera, n: usize) -> Vec<Vector2<f64>> {
    let (w, h) = match model.image_size() {
        (0, _) => (400.0, 300.0),
        (w, h) => (f64::from(w), f64::from(h)),
    };
    let offset = if model.image_size().0 == 0 {
        -150.0
    } else {
        0.0
    };
    let mut out = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let fu = ((i as f64 + 0.3819 * (j % 3) as f64) / (n - 1) as f64).min(1.0);
            let fv = ((j as f64 + 0.618 * (i % 2) as f64) / (n - 1) as f64).min(1.0);
            out.push(Vector2::new(
                offset - 0.49 + fu * (w - 0.98),
                offset - 0.49 + fv * (h - 0.98),
            ));
        }
    }
    out
}

#[test]
fn every_format_round_trips_pixel_bearing_pixel() {
    for (path, format) in all_calibrations() {
        let rig = load(&path, Some(format), None).unwrap();
        let mut probes = 0;
        for (index, camera) in rig.cameras().iter().enumerate() {
            let mut valid = 0;
            for p in probe_pixels(&camera.model, 41) {
                let Some(b) = camera.model.try_bearing(&p) else {
                    continue;
                };
                valid += 1;
                let q = camera.model.try_pixel(&b).unwrap_or_else(|| {
                    panic!(
                        "{}: camera {index} pixel {p:?} has no way back",
                        path.display()
                    )
                });
                let error = (q - p).norm();
                assert!(
                    error <= ROUND_TRIP_PX,
                    "{}: camera {index} pixel {p:?} round trip error {error:e} px",
                    path.display()
                );
                // The same through the rig: the ray's direction projects back to the pixel.
                let ray = rig.ray(index, &p).unwrap();
                let seen = rig.project_direction(&ray.direction);
                let back = seen.iter().find(|s| s.camera == index).unwrap();
                assert!((back.pixel - p).norm() <= ROUND_TRIP_PX);
            }
            // Every probe of these images is valid (no fisheye circle here).
            assert_eq!(valid, 41 * 41, "{}: camera {index}", path.display());
            probes += valid;
        }
        assert!(probes >= 41 * 41, "{}", path.display());
    }
}

#[test]
fn native_write_then_read_is_exact_for_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for (k, (path, format)) in all_calibrations().into_iter().enumerate() {
        let rig = load(&path, Some(format), None).unwrap();
        let out = dir.path().join(format!("copy{k}.json"));
        native::write(&rig, &out).unwrap();
        let back = load(&out, None, None).unwrap();
        assert_eq!(back, rig, "{}", path.display());
        // Writing again gives the same bytes.
        let first = std::fs::read(&out).unwrap();
        native::write(&back, &out).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), first);
    }
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn shipped_ladybug2_is_the_documented_generator_output() {
    let shipped = load(&manifest("calibration/ladybug2.json"), None, None).unwrap();
    assert_eq!(shipped, synth::ladybug2_rig());
    // 0.00167557 rad per pixel at the image centre.
    let c = &shipped.cameras()[0].model;
    let a = c.try_bearing(&Vector2::new(511.0, 383.5)).unwrap();
    let b = c.try_bearing(&Vector2::new(512.0, 383.5)).unwrap();
    let per_pixel = vgps::geometry::angle_between(&a, &b);
    assert!((per_pixel - 0.00167557).abs() < 1e-8, "{per_pixel}");
}

#[test]
fn shipped_lut_matches_ladybug2_within_a_hundredth_of_a_pixel() {
    let exact = load(&manifest("calibration/ladybug2.json"), None, None).unwrap();
    let lut = load(&manifest("calibration/ladybug2_lut.json"), None, None).unwrap();
    let mut worst: f64 = 0.0;
    for (e, l) in exact.cameras().iter().zip(lut.cameras()) {
        assert_eq!(e.rig_from_camera, l.rig_from_camera);
        for p in probe_pixels(&e.model, 61) {
            let b = l.model.try_bearing(&p).unwrap();
            let q = e.model.try_pixel(&b).unwrap();
            worst = worst.max((q - p).norm());
        }
    }
    assert!(worst <= 0.01, "worst LUT error {worst} px");
    let bytes: u64 = (0..6)
        .map(|i| {
            std::fs::metadata(manifest(&format!("calibration/ladybug2_lut.cam{i}.lut")))
                .unwrap()
                .len()
        })
        .sum();
    assert!(bytes <= 5 << 20, "{bytes} bytes");
}

fn assert_close(a: &Vector3<f64>, b: &Vector3<f64>, tol: f64) {
    assert!((a - b).norm() <= tol, "{a:?} vs {b:?}");
}

#[test]
fn ladybug_ini_fixture_has_the_expected_geometry() {
    let rig = load(&fixture("ladybug_64x48.ini"), None, None).unwrap();
    assert_eq!(rig.len(), 6);
    // Principal point of camera 0: rig +x, from (0.04, 0, 0).
    let ray = rig.ray(0, &Vector2::new(31.5, 23.5)).unwrap();
    assert_close(&ray.direction, &Vector3::x(), 1e-12);
    assert_close(&ray.origin, &Vector3::new(0.04, 0.0, 0.0), 1e-15);
    // Top camera: rig +z.
    let top = rig.ray(5, &Vector2::new(31.5, 23.5)).unwrap();
    assert_close(&top.direction, &Vector3::z(), 1e-12);
    // 20 px right of the centre of camera 0 (f = 40 px) is atan(½) off axis towards camera
    // x; camera 0 has rotY = π/2 (Ry maps camera x to rig −z): below the horizon, ahead.
    let ray = rig.ray(0, &Vector2::new(51.5, 23.5)).unwrap();
    assert_close(
        &ray.direction,
        &Vector3::new(40.0, 0.0, -20.0).normalize(),
        1e-12,
    );
    // Outside the 64×48 image: no ray.
    assert!(rig.ray(0, &Vector2::new(71.5, 23.5)).is_err());
    // 20 px below the centre: camera y → rig +y (left).
    let ray = rig.ray(0, &Vector2::new(31.5, 43.5)).unwrap();
    let expected = Vector3::new(40.0, 20.0, 0.0).normalize();
    assert_close(&ray.direction, &expected, 1e-12);
    // Camera k looks along yaw 72° k.
    for k in 1..5 {
        let a = TAU * k as f64 / 5.0;
        let ray = rig.ray(k, &Vector2::new(31.5, 23.5)).unwrap();
        assert_close(&ray.direction, &Vector3::new(a.cos(), a.sin(), 0.0), 1e-12);
    }
}

#[test]
fn ladybug_ini_without_size_is_unbounded_unless_a_size_is_given() {
    let path = fixture("ladybug_no_size.ini");
    let rig = load(&path, None, None).unwrap();
    assert_eq!(rig.cameras()[0].model.image_size(), (0, 0));
    // Far outside any plausible image, still a bearing (45° left of camera 0's axis... in
    // camera coordinates: 40 px left of centre).
    let ray = rig.ray(0, &Vector2::new(-8.5, 23.5)).unwrap();
    assert_close(
        &ray.direction,
        &Vector3::new(FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2),
        1e-12,
    );
    let bounded = load(&path, None, Some((64, 48))).unwrap();
    assert!(bounded.ray(0, &Vector2::new(-8.5, 23.5)).is_err());
    assert_eq!(
        bounded,
        load(&fixture("ladybug_64x48.ini"), None, None).unwrap()
    );
}

#[test]
fn nclt_fixture_has_the_expected_geometry() {
    let rig = load(&fixture("nclt_16x12"), None, None).unwrap();
    assert_eq!(rig.len(), 6);
    // The principal point (7.5, 5.5) is undistorted: camera 0 looks along rig +x, the top
    // camera along rig +z.
    assert_close(
        &rig.ray(0, &Vector2::new(7.5, 5.5)).unwrap().direction,
        &Vector3::x(),
        1e-12,
    );
    assert_close(
        &rig.ray(5, &Vector2::new(7.5, 5.5)).unwrap().direction,
        &Vector3::z(),
        1e-12,
    );
    assert_close(
        &rig.ray(0, &Vector2::new(7.5, 5.5)).unwrap().origin,
        &Vector3::new(0.042, 0.0, 0.0),
        1e-15,
    );
    // Raw pixel (u 12, v 5) of camera 0: distorted normalised point (0.45, −0.05); the
    // synthetic lens d(r) = r (1 − 0.12 r² + 0.02 r⁴) inverted by bisection gives the
    // undistorted point, then camera (x, y, z) → rig (z, y, −x).
    let (xd, yd) = ((12.0 - 7.5) / 10.0, (5.0 - 5.5) / 10.0);
    let rho: f64 = f64::hypot(xd, yd);
    let (mut lo, mut hi) = (0.0f64, 2.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid * (1.0 - 0.12 * mid * mid + 0.02 * mid.powi(4)) < rho {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let s = lo / rho;
    let cam = Vector3::new(xd * s, yd * s, 1.0).normalize();
    let expected = Vector3::new(cam.z, cam.y, -cam.x);
    let got = rig.ray(0, &Vector2::new(12.0, 5.0)).unwrap().direction;
    // The table stores 1e-6 px: 1e-7 rad at f = 10 px.
    assert_close(&got, &expected, 2e-7);
}

#[test]
fn tabulated_pinhole_jacobians_match_finite_differences() {
    let rig = load(&fixture("nclt_16x12"), None, None).unwrap();
    let model = &rig.cameras()[0].model;
    let h = 1e-6;
    for p in probe_pixels(model, 9) {
        // Stay off the cell edges, where the bilinear map has kinks.
        let p = p.map(|x| x.floor().max(0.0) + 0.37);
        let (b, jb) = model.try_bearing_with_jacobian(&p).unwrap();
        for (axis, d) in [(0, Vector2::new(h, 0.0)), (1, Vector2::new(0.0, h))] {
            let numeric = (model.try_bearing(&(p + d)).unwrap()
                - model.try_bearing(&(p - d)).unwrap())
                / (2.0 * h);
            assert_close(&jb.column(axis).into_owned(), &numeric, 1e-7);
        }
        let (q, jp) = model.try_pixel_with_jacobian(&b).unwrap();
        assert!((q - p).norm() < 1e-9);
        // J_pixel · J_bearing = I on the tangent plane.
        let product = jp * jb;
        assert!((product - nalgebra::Matrix2::identity()).abs().max() < 1e-8);
    }
}

#[test]
fn detection_finds_every_format() {
    for (path, format) in all_calibrations() {
        assert_eq!(detect(&path).unwrap(), format, "{}", path.display());
    }
    let dir = tempfile::tempdir().unwrap();
    let odd = dir.path().join("notes.txt");
    std::fs::write(&odd, "hello\n").unwrap();
    assert!(matches!(
        load(&odd, None, None),
        Err(LoadError::UnknownFormat { .. })
    ));
    assert!(matches!(
        load(dir.path(), None, None),
        Err(LoadError::UnknownFormat { .. })
    ));
}

/// Copies a fixture file or directory into `dir`, returns the copy's path.
fn copy_fixture(name: &str, dir: &Path) -> PathBuf {
    let src = fixture(name);
    let dst = dir.join(name);
    if src.is_dir() {
        std::fs::create_dir_all(&dst).unwrap();
        for e in std::fs::read_dir(&src).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dst.join(e.file_name())).unwrap();
        }
    } else {
        std::fs::copy(&src, &dst).unwrap();
        // Native side files.
        let stem = name.trim_end_matches(".json");
        for e in std::fs::read_dir(src.parent().unwrap()).unwrap() {
            let e = e.unwrap();
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with(&format!("{stem}.cam")) {
                std::fs::copy(e.path(), dir.join(&n)).unwrap();
            }
        }
    }
    dst
}

fn edit(path: &Path, f: impl Fn(String) -> String) {
    let text = std::fs::read_to_string(path).unwrap();
    let new = f(text.clone());
    assert_ne!(new, text, "the edit of {} changed nothing", path.display());
    std::fs::write(path, new).unwrap();
}

/// A bad-input case: the fixture to copy, how to break it (given the copy's path), the
/// image size to pass, and what the error must name: file, location, reason.
pub struct BadCase {
    /// Case name.
    pub name: &'static str,
    /// Fixture to start from.
    pub fixture: &'static str,
    /// Breaks the copy; returns the path to load.
    pub breaker: fn(&Path) -> PathBuf,
    /// Image size given to `load`.
    pub image_size: Option<(u32, u32)>,
    /// Substrings the error must contain: file name, location, reason.
    pub expected: [&'static str; 3],
}

/// The table of bad inputs (shared with `tests/cli_calib.rs`).
pub fn bad_cases() -> Vec<BadCase> {
    fn same(p: &Path) -> PathBuf {
        p.to_path_buf()
    }
    vec![
        BadCase {
            name: "native unknown model",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| {
                    t.replacen("\"model\": \"pinhole\"", "\"model\": \"fisheye9\"", 1)
                });
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "line 7", "unknown variant `fisheye9`"],
        },
        BadCase {
            name: "native extra key",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| {
                    t.replacen("\"fx\": 50.0,", "\"fx\": 50.0, \"focal\": 1.0,", 1)
                });
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "line 10", "unknown field `focal`"],
        },
        BadCase {
            name: "native missing key",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| t.replacen("\"fx\": 50.0,", "", 1));
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "line", "missing field `fx`"],
        },
        BadCase {
            name: "native non-finite number",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| t.replacen("\"fx\": 50.0,", "\"fx\": 1e999,", 1));
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "line 10", "number out of range"],
        },
        BadCase {
            name: "native negative focal length",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| t.replacen("\"fx\": 50.0,", "\"fx\": -50.0,", 1));
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "cameras[0].camera", "fx = -50"],
        },
        BadCase {
            name: "native non-orthonormal rotation",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| t.replacen("[0.0, 1.0, 0.0]", "[0.0, 1.01, 0.0]", 1));
                same(p)
            },
            image_size: None,
            expected: [
                "native_mixed.json",
                "cameras[0].rig_from_camera.rotation",
                "not a rotation",
            ],
        },
        BadCase {
            name: "native unsupported version",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(p, |t| t.replacen("\"version\": 1", "\"version\": 7", 1));
                same(p)
            },
            image_size: None,
            expected: ["native_mixed.json", "key version", "unsupported version 7"],
        },
        BadCase {
            name: "native missing LUT side file",
            fixture: "native_mixed.json",
            breaker: |p| {
                std::fs::remove_file(p.with_file_name("native_mixed.cam3.lut")).unwrap();
                same(p)
            },
            image_size: None,
            expected: [
                "native_mixed.json",
                "cameras[3].camera.file",
                "native_mixed.cam3.lut",
            ],
        },
        BadCase {
            name: "native table side file of the wrong size",
            fixture: "native_mixed.json",
            breaker: |p| {
                edit(&p.with_file_name("native_mixed.cam4.d2u.txt"), |t| {
                    t.replacen("16 12", "16 13", 1)
                });
                same(p)
            },
            image_size: None,
            expected: [
                "native_mixed.cam4.d2u.txt",
                "end of file",
                "a 16×13 table needs 208",
            ],
        },
        BadCase {
            name: "ini missing key",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| t.replace("camera3_rotY = 1.5707963267948966\n", ""));
                same(p)
            },
            image_size: None,
            expected: ["ladybug_64x48.ini", "key camera3_rotY", "missing key"],
        },
        BadCase {
            // An unknown key (`camera6_rotX`) is only a warning since issue 23; a repeated
            // one is an error.
            name: "ini repeated key",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| format!("{t}camera1_rotX = 0\n"));
                same(p)
            },
            image_size: None,
            expected: [
                "ladybug_64x48.ini",
                "line 58, key camera1_rotX",
                "repeated key",
            ],
        },
        BadCase {
            name: "ini NaN",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| {
                    t.replace("camera1_FocalLen = 40", "camera1_FocalLen = NaN")
                });
                same(p)
            },
            image_size: None,
            expected: [
                "ladybug_64x48.ini",
                "line 19, key camera1_FocalLen",
                "not finite",
            ],
        },
        BadCase {
            name: "ini not a number",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| {
                    t.replace("camera1_FocalLen = 40", "camera1_FocalLen = 40px")
                });
                same(p)
            },
            image_size: None,
            expected: [
                "ladybug_64x48.ini",
                "line 19, key camera1_FocalLen",
                "not a number",
            ],
        },
        BadCase {
            name: "ini repeated key",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| format!("{t}camera1_FocalLen = 41\n"));
                same(p)
            },
            image_size: None,
            expected: ["ladybug_64x48.ini", "key camera1_FocalLen", "repeated key"],
        },
        BadCase {
            name: "ini non-positive focal length",
            fixture: "ladybug_64x48.ini",
            breaker: |p| {
                edit(p, |t| {
                    t.replace("camera1_FocalLen = 40", "camera1_FocalLen = 0")
                });
                same(p)
            },
            image_size: None,
            expected: [
                "ladybug_64x48.ini",
                "line 19, key camera1_FocalLen",
                "fx = 0",
            ],
        },
        BadCase {
            name: "ini image size contradicting --image-size",
            fixture: "ladybug_64x48.ini",
            breaker: same,
            image_size: Some((640, 480)),
            expected: [
                "ladybug_64x48.ini",
                "key image_width",
                "contradicts the given 640×480",
            ],
        },
        BadCase {
            name: "nclt table with a missing line",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("D2U_Cam1_16X12.txt"), |t| {
                    t.replacen("\n11 15 ", "\n#11 15 ", 1)
                        .lines()
                        .filter(|l| !l.starts_with('#'))
                        .collect::<Vec<_>>()
                        .join("\n")
                });
                same(p)
            },
            image_size: None,
            expected: ["D2U_Cam1_16X12.txt", "end of file", "191 entries"],
        },
        BadCase {
            name: "nclt header contradicting the file name",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("U2D_Cam2_16X12.txt"), |t| {
                    t.replacen("16 12", "12 16", 1)
                });
                same(p)
            },
            image_size: None,
            expected: [
                "U2D_Cam2_16X12.txt",
                "line 1",
                "contradicts the expected size 16×12",
            ],
        },
        BadCase {
            name: "nclt image size contradicting the table",
            fixture: "nclt_16x12",
            breaker: same,
            image_size: Some((64, 48)),
            expected: [
                "nclt_16x12",
                "camera 0",
                "contradicts the given image size 64×48",
            ],
        },
        BadCase {
            name: "nclt NaN in a table",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("D2U_Cam0_16X12.txt"), |t| {
                    t.replacen("0 1 -0.541812 0.359677", "0 1 NaN 0.359677", 1)
                });
                same(p)
            },
            image_size: None,
            expected: ["D2U_Cam0_16X12.txt", "line 3", "NaN is not finite"],
        },
        BadCase {
            name: "nclt duplicate pixel",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("D2U_Cam0_16X12.txt"), |t| {
                    t.replacen("0 1 -0.541812", "0 0 -0.541812", 1)
                });
                same(p)
            },
            image_size: None,
            expected: ["D2U_Cam0_16X12.txt", "line 3", "given twice"],
        },
        BadCase {
            name: "nclt non-monotonic table",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("D2U_Cam0_16X12.txt"), |t| {
                    t.replacen("0 1 -0.541812 0.359677", "0 1 -0.541812 -2.0", 1)
                });
                same(p)
            },
            image_size: None,
            expected: ["nclt_16x12", "camera 0", "not monotonic"],
        },
        BadCase {
            name: "nclt K not upper triangular",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("K_cam3.csv"), |t| t.replacen("\n0,", "\n0.5,", 1));
                same(p)
            },
            image_size: None,
            expected: ["K_cam3.csv", "line 2", "K[1][0] = 0.5 must be 0"],
        },
        BadCase {
            name: "nclt NaN in K",
            fixture: "nclt_16x12",
            breaker: |p| {
                edit(&p.join("K_cam3.csv"), |t| t.replacen("10,", "NaN,", 1));
                same(p)
            },
            image_size: None,
            expected: ["K_cam3.csv", "line 1", "NaN is not finite"],
        },
        BadCase {
            name: "nclt extrinsics with five numbers",
            fixture: "nclt_16x12",
            breaker: |p| {
                std::fs::write(p.join("x_lb3_c4.csv"), "0.01,0,0,0,90\n").unwrap();
                same(p)
            },
            image_size: None,
            expected: ["x_lb3_c4.csv", "line 1", "expected 6 numbers"],
        },
        BadCase {
            name: "nclt missing extrinsics file",
            fixture: "nclt_16x12",
            breaker: |p| {
                std::fs::remove_file(p.join("x_lb3_c2.csv")).unwrap();
                same(p)
            },
            image_size: None,
            expected: ["nclt_16x12", "x_lb3_c2.csv", "missing file"],
        },
    ]
}

#[test]
fn bad_inputs_name_file_location_and_reason() {
    let cases = bad_cases();
    assert!(cases.len() >= 20);
    for case in cases {
        let dir = tempfile::tempdir().unwrap();
        let copy = copy_fixture(case.fixture, dir.path());
        // The unbroken copy loads.
        assert!(load(&copy, None, None).is_ok(), "{}", case.name);
        let path = (case.breaker)(&copy);
        let error = load(&path, None, case.image_size)
            .expect_err(case.name)
            .to_string();
        for part in case.expected {
            assert!(
                error.contains(part),
                "{}: `{error}` does not contain `{part}`",
                case.name
            );
        }
    }
}
