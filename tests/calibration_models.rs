//! Camera models, LUTs and rigs over the table of example cameras
//! (`vgps::synthetic::calibration::example_cameras`).

use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector2, Vector3};
use rand::RngExt;
use vgps::calibration::{
    CalibrationError, Camera, CameraModel, Equirectangular, EquirectangularParams,
    KannalaBrandtParams, LUT_HEADER_BYTES, Lut, Pinhole, PinholeParams, RadialTangential, Rig,
    RigCamera, rig_from_panorama,
};
use vgps::synthetic::calibration::{
    EXAMPLE_LUT_STEP, LADYBUG2_FOCAL, example_cameras, ladybug_placements, ladybug_rig,
    ladybug2_pinhole, opencv_fisheye, panorama,
};

/// Round trip pixel → bearing → pixel tolerance (pixels).
const ROUND_TRIP_PX: f64 = 1e-6;
/// LUT vs its source model (pixels).
const LUT_ACCURACY_PX: f64 = 0.01;

/// True for the models whose first and last pixel rows are the poles (u undefined there).
fn is_panorama(name: &str) -> bool {
    name.contains("equirectangular")
}

/// A dense grid over the closed image rectangle (edges and corners included), plus for
/// panoramas the pole rows left out (longitude is undefined there).
fn dense_grid(camera: &Camera, name: &str, nu: usize, nv: usize) -> Vec<Vector2<f64>> {
    let (w, h) = camera.image_size();
    let (w, h) = (f64::from(w), f64::from(h));
    let (v_lo, v_hi) = if is_panorama(name) {
        (0.0, h - 1.0)
    } else {
        (-0.5, h - 0.5)
    };
    let mut out = Vec::with_capacity(nu * nv);
    for j in 0..nv {
        let v = v_lo + (v_hi - v_lo) * (j as f64) / ((nv - 1) as f64);
        for i in 0..nu {
            let u = -0.5 + w * (i as f64) / ((nu - 1) as f64);
            out.push(Vector2::new(u, v));
        }
    }
    out
}

/// Pixel distance, wrapping u for panoramas (u = −½ and u = W − ½ are the same seam).
fn pixel_distance(camera: &Camera, name: &str, a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    let mut d = a - b;
    if is_panorama(name) {
        let w = f64::from(camera.image_size().0);
        d.x -= w * (d.x / w).round();
    }
    d.norm()
}

#[test]
fn example_table_is_valid_everywhere_on_its_grid() {
    // Every example camera's whole rectangle is inside its validity domain.
    for (name, camera) in example_cameras() {
        for p in dense_grid(&camera, name, 65, 49) {
            assert!(camera.is_inside(&p), "{name}: {p:?} not inside");
        }
        let (w, h) = camera.image_size();
        for p in [
            Vector2::new(-0.51, 0.0),
            Vector2::new(0.0, f64::from(h) - 0.49),
            Vector2::new(f64::from(w) - 0.49, 0.0),
            Vector2::new(f64::NAN, 1.0),
        ] {
            assert!(!camera.is_inside(&p), "{name}: {p:?} inside");
            assert!(
                camera.try_bearing(&p).is_none(),
                "{name}: {p:?} has a bearing"
            );
        }
    }
}

#[test]
fn pixel_bearing_pixel_round_trip_over_the_whole_image() {
    let mut rng = vgps::synthetic::rng(11);
    for (name, camera) in example_cameras() {
        let (w, h) = camera.image_size();
        let mut pixels = dense_grid(&camera, name, 129, 97);
        let v_range = if is_panorama(name) {
            0.0..=f64::from(h) - 1.0
        } else {
            -0.5..=f64::from(h) - 0.5
        };
        for _ in 0..2000 {
            pixels.push(Vector2::new(
                rng.random_range(-0.5..=f64::from(w) - 0.5),
                rng.random_range(v_range.clone()),
            ));
        }
        let mut worst: f64 = 0.0;
        for p in &pixels {
            let b = camera
                .try_bearing(p)
                .unwrap_or_else(|| panic!("{name}: no bearing at {p:?}"));
            assert!((b.norm() - 1.0).abs() < 1e-12, "{name}: bearing not unit");
            let q = camera
                .try_pixel(&b)
                .unwrap_or_else(|| panic!("{name}: no pixel for {p:?}"));
            // Length invariance.
            let q2 = camera
                .try_pixel(&(b * 3.7))
                .unwrap_or_else(|| panic!("{name}: scaled"));
            worst = worst
                .max(pixel_distance(&camera, name, p, &q))
                .max(pixel_distance(&camera, name, p, &q2));
        }
        println!(
            "{name}: {} pixels, worst round trip {worst:.2e} px",
            pixels.len()
        );
        assert!(worst <= ROUND_TRIP_PX, "{name}: round trip {worst:e} px");
    }
}

/// Central finite difference of the bearing along pixel axis `k`.
fn fd_bearing(camera: &Camera, p: &Vector2<f64>, k: usize, h: f64) -> Vector3<f64> {
    let mut plus = *p;
    let mut minus = *p;
    plus[k] += h;
    minus[k] -= h;
    let bp = camera.try_bearing(&plus).expect("bearing +h");
    let bm = camera.try_bearing(&minus).expect("bearing -h");
    (bp - bm) / (2.0 * h)
}

/// Central finite difference of the pixel along direction axis `k`.
fn fd_pixel(camera: &Camera, d: &Vector3<f64>, k: usize, h: f64) -> Vector2<f64> {
    let mut plus = *d;
    let mut minus = *d;
    plus[k] += h;
    minus[k] -= h;
    let pp = camera.try_pixel(&plus).expect("pixel +h");
    let pm = camera.try_pixel(&minus).expect("pixel -h");
    (pp - pm) / (2.0 * h)
}

#[test]
fn analytic_jacobians_match_finite_differences() {
    let mut rng = vgps::synthetic::rng(12);
    for (name, camera) in example_cameras() {
        let lut = name.starts_with("lut");
        let (w, h) = camera.image_size();
        let step = f64::from(EXAMPLE_LUT_STEP);
        let mut checked = 0;
        for _ in 0..300 {
            // Stay 2 px inside the image (and away from the panorama's poles); for LUTs stay
            // inside one cell (the bilinear map is only C⁰ across cell borders).
            let mut p = Vector2::new(
                rng.random_range(2.0..f64::from(w) - 3.0),
                rng.random_range(2.0..f64::from(h) - 3.0),
            );
            if lut {
                for k in 0..2 {
                    let a = p[k] + 0.5;
                    p[k] = (a / step).floor() * step + rng.random_range(0.2..0.8) * step - 0.5;
                }
            }
            let (b, jb) = camera
                .try_bearing_with_jacobian(&p)
                .expect("bearing jacobian");
            assert!(
                (b - camera.try_bearing(&p).unwrap()).norm() < 1e-15,
                "{name}"
            );
            let hp = if lut { 1e-3 } else { 1e-4 };
            for k in 0..2 {
                let fd = fd_bearing(&camera, &p, k, hp);
                let err = (jb.column(k) - fd).norm();
                assert!(
                    err <= 1e-6 * jb.column(k).norm().max(1e-6),
                    "{name}: d bearing/d pixel col {k} at {p:?}: {:?} vs {fd:?}",
                    jb.column(k).into_owned()
                );
                // Columns tangent to the bearing.
                assert!(
                    jb.column(k).dot(&b).abs() < 1e-12,
                    "{name}: column not tangent"
                );
            }
            let Some((q, jp)) = camera.try_pixel_with_jacobian(&b) else {
                panic!("{name}: pixel jacobian at {p:?}");
            };
            assert!(
                pixel_distance(&camera, name, &p, &q) < ROUND_TRIP_PX,
                "{name}"
            );
            // J_p · b = 0 (length invariance) and J_p · J_b = I.
            assert!((jp * b).norm() < 1e-9 * jp.norm(), "{name}: J_p b != 0");
            let identity = jp * jb;
            assert!(
                (identity - nalgebra::Matrix2::identity()).abs().max() < 1e-8,
                "{name}: J_p J_b = {identity}"
            );
            // Scaled direction: the Jacobian scales by 1/length; test at length 2.
            let d = b * 2.0;
            let (_, jp2) = camera.try_pixel_with_jacobian(&d).expect("scaled");
            for k in 0..3 {
                let fd = fd_pixel(&camera, &d, k, 1e-7);
                let err = (jp2.column(k) - fd).norm();
                assert!(
                    err <= 1e-5 * jp2.norm(),
                    "{name}: d pixel/d bearing col {k} at {p:?}: {:?} vs {fd:?}",
                    jp2.column(k).into_owned()
                );
            }
            checked += 1;
        }
        assert_eq!(checked, 300);
    }
}

/// Worst pixel-equivalent error of a LUT of `step` against its source model, over a grid of
/// quarter-step spacing covering the whole image (cell centres and edge midpoints, where
/// bilinear interpolation is worst, included). The pixel equivalent is the bearing error
/// through the source model's projection Jacobian at the exact bearing (the LUT's bearing
/// may fall a hair outside the image at its edges, where the source model has no pixel).
fn lut_worst_error(name: &str, source: &Camera, step: u32) -> (f64, Vector2<f64>) {
    let lut = Lut::from_model(source, step).expect("lut");
    let (w, h) = source.image_size();
    let mut worst: f64 = 0.0;
    let mut worst_at = Vector2::zeros();
    let quarter = f64::from(step) / 4.0;
    let nu = (f64::from(w) / quarter) as usize;
    let nv = (f64::from(h) / quarter) as usize;
    for j in 0..=nv {
        let v = -0.5 + quarter * j as f64;
        if is_panorama(name) && (v < 0.0 || v > f64::from(h) - 1.0) {
            continue;
        }
        for i in 0..=nu {
            let p = Vector2::new(-0.5 + quarter * i as f64, v);
            let b = lut.try_bearing(&p).expect("lut bearing");
            let exact = source.try_bearing(&p).expect("source bearing");
            let (_, jp) = source
                .try_pixel_with_jacobian(&exact)
                .expect("source jacobian");
            let e = (jp * (b - exact)).norm();
            if e > worst {
                worst = e;
                worst_at = p;
            }
        }
    }
    (worst, worst_at)
}

fn lut_sources() -> Vec<(&'static str, Camera)> {
    vec![
        ("ladybug2", ladybug2_pinhole().into()),
        ("fisheye_opencv", opencv_fisheye().into()),
        ("equirectangular", panorama().into()),
    ]
}

#[test]
fn luts_match_their_source_models_within_a_hundredth_of_a_pixel() {
    for (name, source) in lut_sources() {
        let (worst, at) = lut_worst_error(name, &source, EXAMPLE_LUT_STEP);
        println!(
            "LUT {name} step {EXAMPLE_LUT_STEP}: worst {worst:.5} px at ({}, {})",
            at.x, at.y
        );
        assert!(worst <= LUT_ACCURACY_PX, "{name}: LUT error {worst} px");
        // A real approximation, with f32 storage well below the target.
        assert!(worst > 1e-4, "{name}: suspiciously exact {worst}");
    }
}

#[test]
fn the_next_coarser_lut_step_misses_the_target_for_the_ladybug2() {
    // Guards the choice of EXAMPLE_LUT_STEP: one pixel coarser is too coarse somewhere.
    let (name, source) = lut_sources().swap_remove(0);
    let (worst, at) = lut_worst_error(name, &source, EXAMPLE_LUT_STEP + 1);
    println!(
        "LUT {name} step {}: worst {worst:.5} px at ({}, {})",
        EXAMPLE_LUT_STEP + 1,
        at.x,
        at.y
    );
    assert!(worst > LUT_ACCURACY_PX, "{worst}");
}

#[test]
fn equirectangular_conventions() {
    let pano = panorama();
    let (w, h) = (2048.0, 1024.0);
    // Longitude/latitude of pixel centres and edges.
    let (theta, phi) = pano.angles(&Vector2::new(-0.5, -0.5));
    assert!((theta + std::f64::consts::PI).abs() < 1e-15);
    assert!((phi - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    let (theta, phi) = pano.angles(&Vector2::new(0.0, 0.0));
    assert!((theta - (std::f64::consts::TAU * (0.5 / w) - std::f64::consts::PI)).abs() < 1e-15);
    assert!((phi - std::f64::consts::PI * (0.5 - 0.5 / h)).abs() < 1e-15);
    // Camera frame: centre forward (+z), right (+x) a quarter turn right, top row up (−y).
    let b = pano
        .try_bearing(&Vector2::new(w / 2.0 - 0.5, h / 2.0 - 0.5))
        .unwrap();
    assert!((b - Vector3::z()).norm() < 1e-15);
    let b = pano
        .try_bearing(&Vector2::new(0.75 * w - 0.5, h / 2.0 - 0.5))
        .unwrap();
    assert!((b - Vector3::x()).norm() < 1e-15);
    let b = pano.try_bearing(&Vector2::new(17.0, -0.5)).unwrap();
    assert!((b + Vector3::y()).norm() < 1e-15);
    // Rig frame via Rig::panorama: (cos φ cos θ, −cos φ sin θ, sin φ).
    let rig = Rig::panorama(pano.clone().into());
    let mut rng = vgps::synthetic::rng(13);
    for _ in 0..200 {
        let p = Vector2::new(
            rng.random_range(-0.5..w - 0.5),
            rng.random_range(-0.5..h - 0.5),
        );
        let (theta, phi) = pano.angles(&p);
        let expected = Vector3::new(phi.cos() * theta.cos(), -phi.cos() * theta.sin(), phi.sin());
        let ray = rig.ray(0, &p).unwrap();
        assert!((ray.direction - expected).norm() < 1e-14);
        assert_eq!(ray.origin, Vector3::zeros());
    }
    // Left (rig +y) is a quarter width left of centre; up (rig +z) is the top edge.
    let seen = rig.project_direction(&Vector3::y());
    assert!((seen[0].pixel - Vector2::new(w / 4.0 - 0.5, h / 2.0 - 0.5)).norm() < 1e-9);
    let seen = rig.project_direction(&Vector3::z());
    assert!((seen[0].pixel.y + 0.5).abs() < 1e-9);
    // The poles have no pixel Jacobian; the seam maps to u = −½ (or W − ½).
    assert!(pano.try_pixel_with_jacobian(&Vector3::y()).is_none());
    let seam = pano.try_pixel(&Vector3::new(0.0, 0.3, -1.0)).unwrap();
    assert!((seam.x + 0.5).abs() < 1e-9 || (seam.x - (w - 0.5)).abs() < 1e-9);
}

#[test]
fn pinhole_known_answers_and_domain() {
    // Ideal pinhole: 45° right of the axis at f px right of the principal point.
    let cam = Pinhole::new(PinholeParams::ideal(
        1024, 768, 400.0, 410.0, 500.25, 380.75,
    ))
    .unwrap();
    let b = cam.try_bearing(&Vector2::new(900.25, 380.75)).unwrap();
    assert!((b - Vector3::new(1.0, 0.0, 1.0).normalize()).norm() < 1e-15);
    let b = cam
        .try_bearing(&Vector2::new(500.25, 380.75 - 300.0))
        .unwrap();
    assert!((b - Vector3::new(0.0, -300.0 / 410.0, 1.0).normalize()).norm() < 1e-15);
    assert!(cam.try_pixel(&Vector3::new(0.0, 0.0, -1.0)).is_none());
    assert!(cam.try_pixel(&Vector3::new(1.0, 0.0, 0.0)).is_none());
    assert!(cam.try_pixel(&Vector3::zeros()).is_none());
    assert!(cam.try_pixel(&Vector3::new(f64::NAN, 0.0, 1.0)).is_none());
    // Ladybug2-like: one pixel at the centre subtends 0.00167557 rad.
    let lb = ladybug2_pinhole();
    let b0 = lb.try_bearing(&Vector2::new(511.5, 383.5)).unwrap();
    let b1 = lb.try_bearing(&Vector2::new(512.5, 383.5)).unwrap();
    let angle = vgps::geometry::angle_between(&b0, &b1);
    assert!((angle - 0.00167557).abs() < 1e-8, "{angle}");
    assert!((LADYBUG2_FOCAL - 596.8).abs() < 0.1);
    // A distortion whose radial map folds back: r (1 + k1 r²) peaks at r² = −1/(3 k1).
    let folded = Pinhole::new(
        PinholeParams::ideal(1000, 1000, 300.0, 300.0, 499.5, 499.5).with_distortion(
            RadialTangential {
                k1: -0.3,
                ..Default::default()
            },
        ),
    )
    .unwrap();
    let r_max = (1.0f64 / 0.9).sqrt();
    assert!(
        (folded.max_radius() - r_max).abs() < 1e-9,
        "{}",
        folded.max_radius()
    );
    // Directions beyond r_max have no pixel; pixels beyond the peak distorted radius none.
    assert!(
        folded
            .try_pixel(&Vector3::new(1.1 * r_max, 0.0, 1.0))
            .is_none()
    );
    assert!(
        folded
            .try_pixel(&Vector3::new(0.9 * r_max, 0.0, 1.0))
            .is_some()
    );
    let rd_peak = r_max * (1.0 - 0.3 * r_max * r_max);
    assert!(
        folded
            .try_bearing(&Vector2::new(499.5 + 300.0 * rd_peak * 1.01, 499.5))
            .is_none()
    );
    assert!(!folded.is_inside(&Vector2::new(499.5 + 300.0 * rd_peak * 1.01, 499.5)));
    assert!(folded.is_inside(&Vector2::new(499.5 + 300.0 * rd_peak * 0.99, 499.5)));
}

#[test]
fn fisheye_known_answers_and_domain() {
    let fe = opencv_fisheye();
    let p = fe.params();
    // θ_d(θ) polynomial at 60°.
    let theta = std::f64::consts::FRAC_PI_3;
    let td = theta
        * (1.0
            + p.k1 * theta.powi(2)
            + p.k2 * theta.powi(4)
            + p.k3 * theta.powi(6)
            + p.k4 * theta.powi(8));
    let b = Vector3::new(theta.sin(), 0.0, theta.cos());
    let px = fe.try_pixel(&b).unwrap();
    assert!((px - Vector2::new(p.cx + p.fx * td, p.cy)).norm() < 1e-9);
    // Beyond 90°: 100° off axis towards the top-right corner.
    let t = 100f64.to_radians();
    let a = (-p.cy).atan2(1279.5 - p.cx);
    let b = Vector3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos());
    let px = fe.try_pixel(&b).unwrap();
    let back = fe.try_bearing(&px).unwrap();
    assert!((back - b).norm() < 1e-12);
    // A polynomial with a fold: θ_d' = 1 − 0.9 θ² vanishes at θ = 1/√0.9... (k1 = −0.3).
    let folded = vgps::calibration::KannalaBrandt::new(KannalaBrandtParams {
        width: 800,
        height: 800,
        fx: 200.0,
        fy: 200.0,
        cx: 399.5,
        cy: 399.5,
        k1: -0.3,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
    })
    .unwrap();
    let theta_max = (1.0f64 / 0.9).sqrt();
    assert!((folded.max_angle() - theta_max).abs() < 1e-9);
    let beyond = 1.05 * theta_max;
    assert!(
        folded
            .try_pixel(&Vector3::new(beyond.sin(), 0.0, beyond.cos()))
            .is_none()
    );
    // Straight behind is never valid.
    assert!(fe.try_pixel(&Vector3::new(0.0, 0.0, -1.0)).is_none());
}

#[test]
fn invalid_parameters_are_typed_errors() {
    let bad = [
        PinholeParams::ideal(0, 480, 500.0, 500.0, 1.0, 1.0),
        PinholeParams::ideal(640, 480, -500.0, 500.0, 1.0, 1.0),
        PinholeParams::ideal(640, 480, 500.0, f64::NAN, 1.0, 1.0),
        PinholeParams::ideal(640, 480, 500.0, 500.0, f64::INFINITY, 1.0),
        PinholeParams::ideal(640, 480, 500.0, 500.0, 1.0, 1.0).with_distortion(RadialTangential {
            k2: f64::NAN,
            ..Default::default()
        }),
    ];
    for params in bad {
        assert!(matches!(
            Pinhole::new(params),
            Err(CalibrationError::InvalidParameters {
                model: "pinhole",
                ..
            })
        ));
    }
    assert!(
        Equirectangular::new(EquirectangularParams {
            width: 10,
            height: 0
        })
        .is_err()
    );
    // Serde goes through the same validation.
    let json = r#"{"model": "pinhole", "width": 640, "height": 480, "fx": -1.0, "fy": 500.0,
                   "cx": 319.5, "cy": 239.5}"#;
    let err = serde_json::from_str::<Camera>(json)
        .unwrap_err()
        .to_string();
    assert!(err.contains("fx"), "{err}");
}

#[test]
fn serde_round_trips_every_example_camera() {
    for (name, camera) in example_cameras() {
        if name.starts_with("lut") {
            // The JSON form of a LUT is its whole table: check one small LUT instead below.
            continue;
        }
        let json = serde_json::to_string(&camera).unwrap();
        assert!(json.contains("\"model\""), "{json}");
        let back: Camera = serde_json::from_str(&json).unwrap();
        assert_eq!(back, camera, "{name}");
    }
    let json = r#"{"model": "pinhole", "width": 640, "height": 480, "fx": 500.0, "fy": 500.0,
                   "cx": 319.5, "cy": 239.5, "distortion": {"k1": -0.1}}"#;
    let camera: Camera = serde_json::from_str(json).unwrap();
    let Camera::Pinhole(p) = &camera else {
        panic!("not a pinhole")
    };
    assert_eq!(p.params().distortion.k1, -0.1);
    assert_eq!(p.params().distortion.k2, 0.0);
    let small = Lut::from_model(
        &Pinhole::new(PinholeParams::ideal(16, 12, 20.0, 20.0, 7.5, 5.5)).unwrap(),
        4,
    )
    .unwrap();
    let camera = Camera::from(small);
    let back: Camera = serde_json::from_str(&serde_json::to_string(&camera).unwrap()).unwrap();
    assert_eq!(back, camera);
    // An unknown model tag is an error.
    assert!(serde_json::from_str::<Camera>(r#"{"model": "omni", "width": 1}"#).is_err());
}

#[test]
fn lut_file_round_trip_and_strict_validation() {
    let dir = tempfile::tempdir().unwrap();
    let lut = Lut::from_model(&opencv_fisheye(), 16).unwrap();
    let path = dir.path().join("fisheye.lut");
    lut.write(&path).unwrap();
    let back = Lut::read(&path).unwrap();
    assert_eq!(back, lut);
    let bytes = std::fs::read(&path).unwrap();
    let (cols, rows) = lut.grid_size();
    assert_eq!((cols, rows), (1280 / 16 + 1, 1024 / 16 + 1));
    assert_eq!(bytes.len(), LUT_HEADER_BYTES + 12 * cols * rows);
    assert_eq!(&bytes[..8], b"VGPSLUT\0");
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 1);
    assert_eq!(u32::from_le_bytes(bytes[12..16].try_into().unwrap()), 1280);
    assert_eq!(u32::from_le_bytes(bytes[20..24].try_into().unwrap()), 16);
    // First node = the source model's bearing at the top-left corner (-0.5, -0.5), as f32.
    let b = opencv_fisheye()
        .try_bearing(&Vector2::new(-0.5, -0.5))
        .unwrap();
    let x = f32::from_le_bytes(bytes[32..36].try_into().unwrap());
    assert_eq!(x, b.x as f32);

    let corrupt = |name: &str, edit: &dyn Fn(&mut Vec<u8>), expect: &str| {
        let mut b = bytes.clone();
        edit(&mut b);
        let p = dir.path().join(name);
        std::fs::write(&p, &b).unwrap();
        let err = Lut::read(&p).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, CalibrationError::LutFile { .. }), "{msg}");
        assert!(msg.contains(name), "{msg} should name the file");
        assert!(msg.contains(expect), "{msg} should say {expect}");
    };
    corrupt("magic.lut", &|b| b[0] = b'X', "magic");
    corrupt("version.lut", &|b| b[8] = 2, "version 2");
    corrupt("short.lut", &|b| b.truncate(20), "header");
    corrupt("truncated.lut", &|b| b.truncate(b.len() - 4), "bytes");
    corrupt("longer.lut", &|b| b.extend_from_slice(&[0; 12]), "bytes");
    corrupt("width.lut", &|b| b[12] = 0x01, "needs");
    corrupt(
        "step0.lut",
        &|b| b[20..24].copy_from_slice(&0u32.to_le_bytes()),
        "step 0",
    );
    corrupt(
        "nan.lut",
        &|b| b[32 + 12 * 5..36 + 12 * 5].copy_from_slice(&f32::NAN.to_le_bytes()),
        "node (5, 0)",
    );
    corrupt(
        "nonunit.lut",
        &|b| {
            let o = 32 + 12 * (cols + 2) + 8;
            let z = f32::from_le_bytes(b[o..o + 4].try_into().unwrap());
            b[o..o + 4].copy_from_slice(&(z * 1.001).to_le_bytes());
        },
        "norm",
    );
    let missing = dir.path().join("missing.lut");
    let msg = Lut::read(&missing).unwrap_err().to_string();
    assert!(msg.contains("missing.lut"), "{msg}");
}

#[test]
fn lut_rejects_sources_without_bearings_and_directions_outside() {
    // A fisheye whose image circle is smaller than the image: corners are outside θ_max.
    let small_circle = vgps::calibration::KannalaBrandt::new(KannalaBrandtParams {
        width: 800,
        height: 800,
        fx: 200.0,
        fy: 200.0,
        cx: 399.5,
        cy: 399.5,
        k1: -0.3,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
    })
    .unwrap();
    assert!(matches!(
        Lut::from_model(&small_circle, 8),
        Err(CalibrationError::LutBuild { .. })
    ));
    assert!(Lut::from_model(&ladybug2_pinhole(), 0).is_err());
    // Directions the LUT does not see: behind the Ladybug2 camera, far off axis, zero.
    let lut = Lut::from_model(&ladybug2_pinhole(), EXAMPLE_LUT_STEP).unwrap();
    assert!(lut.try_pixel(&Vector3::new(0.0, 0.0, -1.0)).is_none());
    assert!(lut.try_pixel(&Vector3::new(1.0, 0.0, 0.05)).is_none());
    assert!(lut.try_pixel(&Vector3::zeros()).is_none());
    assert!(lut.try_pixel(&Vector3::new(f64::NAN, 0.0, 1.0)).is_none());
}

#[test]
fn rig_rays_round_trip_through_points_and_directions() {
    let mut rng = vgps::synthetic::rng(14);
    for model in [
        Camera::from(ladybug2_pinhole()),
        Camera::from(Lut::from_model(&ladybug2_pinhole(), EXAMPLE_LUT_STEP).unwrap()),
    ] {
        let rig = ladybug_rig(&model);
        assert_eq!(rig.len(), 6);
        for _ in 0..300 {
            let camera = rng.random_range(0..6);
            let pixel = Vector2::new(
                rng.random_range(-0.5..1023.5),
                rng.random_range(-0.5..767.5),
            );
            let ray = rig.ray(camera, &pixel).unwrap();
            assert!((ray.direction.norm() - 1.0).abs() < 1e-12);
            let centre = ladybug_placements()[camera].translation.vector;
            assert_eq!(ray.origin, centre);
            // A point 20 m along the ray is seen by that camera at that pixel.
            let point = ray.at(20.0);
            let seen = rig.project_point(&point);
            let hit = seen
                .iter()
                .find(|s| s.camera == camera)
                .expect("camera sees its ray");
            assert!(
                (hit.pixel - pixel).norm() < ROUND_TRIP_PX,
                "{:?}",
                hit.pixel - pixel
            );
            // Every other camera that sees it agrees on the point: its ray passes through it.
            for s in seen.iter().filter(|s| s.camera != camera) {
                let other = rig.ray(s.camera, &s.pixel).unwrap();
                let to_point = point - other.origin;
                let miss = to_point.cross(&other.direction).norm();
                assert!(miss < 1e-6, "camera {} misses by {miss} m", s.camera);
            }
            // The direction (point at infinity) from the same camera.
            let seen = rig.project_direction(&ray.direction);
            let hit = seen
                .iter()
                .find(|s| s.camera == camera)
                .expect("sees its direction");
            assert!((hit.pixel - pixel).norm() < ROUND_TRIP_PX);
        }
        // Uniform directions: about every direction below +45° elevation plus the top cap is
        // seen by at least one camera; count coverage (the rig's blind spots are downward).
        let mut seen_count = 0;
        for _ in 0..2000 {
            let d = vgps::synthetic::random_unit_vector(&mut rng);
            if !rig.project_direction(&d).is_empty() {
                seen_count += 1;
            }
        }
        // Five 81°-wide side cameras overlap; the top camera covers the zenith. The coverage
        // of a 1024×768, 55°-corner camera ring is most but not all of the sphere.
        assert!(
            seen_count > 1400 && seen_count < 2000,
            "coverage {seen_count}/2000"
        );
    }
}

#[test]
fn rig_errors() {
    let rig = ladybug_rig(&ladybug2_pinhole().into());
    assert_eq!(
        rig.ray(6, &Vector2::new(1.0, 1.0)).unwrap_err(),
        CalibrationError::UnknownCamera { index: 6, count: 6 }
    );
    assert!(matches!(
        rig.ray(2, &Vector2::new(1024.0, 1.0)),
        Err(CalibrationError::PixelOutside { camera: 2, .. })
    ));
    assert!(matches!(
        rig.ray(2, &Vector2::new(f64::NAN, 1.0)),
        Err(CalibrationError::PixelOutside { camera: 2, .. })
    ));
    let model: Camera = ladybug2_pinhole().into();
    let make = |m: Matrix3<f64>| RigCamera {
        model: model.clone(),
        rig_from_camera: IsometryMatrix3::from_parts(
            Translation3::identity(),
            Rotation3::from_matrix_unchecked(m),
        ),
    };
    let good = make(Matrix3::identity());
    // Scaled by 1 + 1e-6: not orthonormal. A reflection: determinant −1.
    for (bad, expect_camera) in [
        (make(Matrix3::identity() * (1.0 + 1e-6)), 1),
        (
            make(Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0))),
            1,
        ),
    ] {
        match Rig::new(vec![good.clone(), bad]) {
            Err(CalibrationError::NonOrthonormalRotation {
                camera,
                deviation,
                tolerance,
            }) => {
                assert_eq!(camera, expect_camera);
                assert!(deviation > tolerance);
            }
            other => panic!("expected a rotation error, got {other:?}"),
        }
    }
    // Within tolerance is accepted.
    assert!(Rig::new(vec![make(Matrix3::identity() * (1.0 + 1e-12))]).is_ok());
    let mut nan = good.clone();
    nan.rig_from_camera.translation.vector.x = f64::NAN;
    assert!(matches!(
        Rig::new(vec![nan]),
        Err(CalibrationError::NonFiniteTranslation { camera: 0 })
    ));
    assert!(rig.project_direction(&Vector3::zeros()).is_empty());
    assert!(
        rig.project_point(&Vector3::new(f64::INFINITY, 0.0, 0.0))
            .is_empty()
    );
    assert_eq!(
        rig_from_panorama().matrix().determinant(),
        1.0,
        "the panorama placement is a rotation"
    );
}

/// Agreement with OpenCV (`cv2.undistortPoints`, `cv2.fisheye.undistortPoints`) on the
/// stored reference written by `bench/peers/opencv_undistort.py`.
#[test]
fn agrees_with_opencv_undistort_points() {
    const MAX_ANGLE_RAD: f64 = 1e-6;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let json = std::fs::read_to_string(dir.join("opencv_undistort_cameras.json")).unwrap();
    let cameras: std::collections::BTreeMap<String, Camera> = serde_json::from_str(&json).unwrap();
    // The reference cameras are the example ones.
    assert_eq!(cameras["ladybug2"], Camera::from(ladybug2_pinhole()));
    assert_eq!(cameras["fisheye_opencv"], Camera::from(opencv_fisheye()));
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(dir.join("opencv_undistort_reference.csv"))
        .unwrap();
    let mut worst: std::collections::BTreeMap<String, (usize, f64)> = Default::default();
    for record in reader.records() {
        let r = record.unwrap();
        let name = r[0].to_string();
        let f = |k: usize| r[k].parse::<f64>().unwrap();
        let (u, v, x, y) = (f(1), f(2), f(3), f(4));
        let camera = &cameras[&name];
        let ours = camera
            .try_bearing(&Vector2::new(u, v))
            .unwrap_or_else(|| panic!("{name}: no bearing at ({u}, {v})"));
        let opencv = Vector3::new(x, y, 1.0).normalize();
        let angle = vgps::geometry::angle_between(&ours, &opencv);
        let entry = worst.entry(name.clone()).or_default();
        entry.0 += 1;
        entry.1 = entry.1.max(angle);
        assert!(
            angle <= MAX_ANGLE_RAD,
            "{name} ({u}, {v}): {angle:e} rad from OpenCV"
        );
    }
    for (name, (count, angle)) in &worst {
        println!("OpenCV {name}: {count} points, worst {angle:.2e} rad");
        assert!(*count >= 100, "{name}: only {count} reference points");
    }
    assert_eq!(worst.len(), 3);
}
