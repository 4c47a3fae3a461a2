//! The Ladybug SDK `.conf` reader against a real Ladybug5+ file (tests/data/ladybug5p,
//! BEAMRobotics/libbeam, MIT): the SDK's own stored 3-D ↔ 2-D pairs, round trips through the
//! spline warps, the warp conventions, the LUT.

use nalgebra::{Point3, Vector2, Vector3};
use std::path::{Path, PathBuf};
use vgps::calibration::formats::ladybug_conf::{self, LadybugConf};
use vgps::calibration::{CameraModel, Format, Lut, SplinePinhole, load};

fn conf_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ladybug5p/ladybug5p.conf")
}

fn conf() -> LadybugConf {
    ladybug_conf::read_conf(&conf_path()).expect("the real file parses")
}

#[test]
fn header_and_blocks_of_the_real_file() {
    let c = conf();
    assert_eq!(c.version, "Ladybug 2.0");
    assert_eq!(c.serial_number.as_deref(), Some("18408834"));
    assert_eq!(c.part_id.as_deref(), Some("LD5P-U3-51S5C-B"));
    assert_eq!(c.resolution, (2464, 2048));
    assert_eq!(c.surface_parameter, Some(20.0));
    assert_eq!(c.cameras.len(), 6);
    assert_eq!(c.warps.len(), 48);
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    assert_eq!(c.cameras[1].rectified_spline, [8, 9]);
    assert_eq!(c.cameras[1].distorted_spline, [10, 11]);
    assert_eq!(c.cameras[0].pairs.len(), 5);
    assert_eq!(c.warps[&7].size(), (53, 53));
    // Detected by content and loaded as a rig of six raw cameras.
    let path = conf_path();
    assert_eq!(
        vgps::calibration::formats::detect::detect(&path).expect("detect"),
        Format::LadybugConf
    );
    let rig = load(&path, None, None).expect("load");
    assert_eq!(rig.len(), 6);
    assert_eq!(rig.cameras()[0].model.image_size(), (2464, 2048));
    assert_eq!(rig.cameras()[0].model.model_name(), "spline_pinhole");
}

/// Every stored pair (the SDK's own projections) reproduced by the rectified pinhole within
/// 0.05 px; the four corners of each camera are independent of the parameters (the
/// principal point is taken from `Center`).
#[test]
fn stored_pairs_are_reproduced_within_five_hundredths_of_a_pixel() {
    let c = conf();
    let mut worst_all: f64 = 0.0;
    for cam in &c.cameras {
        let residuals = c.pair_residuals(cam);
        assert_eq!(residuals.len(), 5);
        let mut worst: f64 = 0.0;
        for ((name, line, r), seen) in &residuals {
            assert!(seen, "camera {} pair {name} (line {line}) not seen", cam.id);
            worst = worst.max(r.norm());
        }
        println!("camera {}: largest pair residual {worst:.4} px", cam.id);
        assert!(worst < 0.05, "camera {}: {worst} px", cam.id);
        worst_all = worst_all.max(worst);
    }
    // The real file does far better than the target.
    assert!(worst_all < 0.006, "{worst_all}");
}

/// The same pairs through the rig of raw cameras: the stored point's raw pixel, rectified
/// by the raw → rectified warp, lands on the stored rectified position.
#[test]
fn stored_pairs_through_the_raw_cameras() {
    let c = conf();
    let rig = c.raw_rig().expect("rig");
    let (w, h) = (2464.0, 2048.0);
    for (cam, rc) in c.cameras.iter().zip(rig.cameras()) {
        let vgps::calibration::Camera::SplinePinhole(model) = &rc.model else {
            panic!("raw cameras are spline pinholes");
        };
        for p in &cam.pairs {
            let local = rc
                .rig_from_camera
                .inverse_transform_point(&Point3::from(p.point))
                .coords;
            let stored = Vector2::new(p.normalised.x * w - 0.5, p.normalised.y * h - 0.5);
            let Some(raw) = model.try_pixel(&local) else {
                // The rectified corners lie outside the raw image (the rectified image
                // is wider than the lens' field of view at its corners).
                assert_ne!(p.name, "Center");
                continue;
            };
            let rectified = model.rectify(&raw).0;
            assert!(
                (rectified - stored).norm() < 0.05,
                "camera {} {}",
                cam.id,
                p.name
            );
        }
    }
}

/// raw → rectified → raw over each whole image (a 101 × 101 grid including the edges and
/// corners): ≤ 0.01 px (Newton on the raw → rectified warp makes it ~1e-9 px).
#[test]
fn raw_rectified_raw_round_trip_over_each_image() {
    let c = conf();
    for cam in &c.cameras {
        let model = c.raw_model(cam).expect("model");
        let mut worst: f64 = 0.0;
        let n = 101;
        for a in 0..n {
            for b in 0..n {
                let p = Vector2::new(
                    -0.5 + 2464.0 * f64::from(a) / f64::from(n - 1),
                    -0.5 + 2048.0 * f64::from(b) / f64::from(n - 1),
                );
                let q = model.rectify(&p).0;
                let Some(back) = model.unrectify(&q) else {
                    panic!(
                        "camera {} p {p} q {q} seed {}",
                        cam.id,
                        model.unrectify_by_warp(&q)
                    )
                };
                worst = worst.max((back - p).norm());
                // And through the bearings.
                let bearing = model.try_bearing(&p).expect("bearing");
                let again = model.try_pixel(&bearing).expect("pixel");
                worst = worst.max((again - p).norm());
            }
        }
        println!(
            "camera {}: raw → rectified → raw max {worst:.2e} px",
            cam.id
        );
        assert!(worst <= 0.01, "camera {}: {worst}", cam.id);
        assert!(worst < 1e-6, "camera {}: {worst}", cam.id);
    }
}

/// The evidence for the warp conventions: `3DSurfaceSpline` is defined on the raw image, and
/// projecting its sphere point by the rectified pinhole lands on `DistortedSpline` of the
/// same raw point. With the warps swapped the discrepancy is hundreds of pixels.
#[test]
fn surface_spline_confirms_distorted_spline_maps_raw_to_rectified() {
    let c = conf();
    let (w, h) = (2464.0, 2048.0);
    for cam in &c.cameras {
        let ids = cam.surface_spline.expect("3DSurfaceSpline");
        let iso = c.rig_from_camera(cam);
        let rect = c.rectified_model(cam).expect("rectified");
        let [du, dv] = cam.distorted_spline.map(|id| &c.warps[&id]);
        let [ru, rv] = cam.rectified_spline.map(|id| &c.warps[&id]);
        let (mut right, mut swapped): (f64, f64) = (0.0, 0.0);
        for a in 1..10 {
            for b in 1..10 {
                let (x, y) = (f64::from(a) / 10.0, f64::from(b) / 10.0);
                let point = Vector3::new(
                    c.warps[&ids[0]].value(x, y),
                    c.warps[&ids[1]].value(x, y),
                    c.warps[&ids[2]].value(x, y),
                );
                let local = iso.inverse_transform_point(&Point3::from(point)).coords;
                let q = rect.try_pixel(&local).expect("in front");
                let d = Vector2::new(du.value(x, y) * w - 0.5, dv.value(x, y) * h - 0.5);
                let r = Vector2::new(ru.value(x, y) * w - 0.5, rv.value(x, y) * h - 0.5);
                right = right.max((q - d).norm());
                swapped = swapped.max((q - r).norm());
            }
        }
        println!(
            "camera {}: surface vs DistortedSpline max {right:.4} px",
            cam.id
        );
        assert!(right < 0.1, "camera {}: {right}", cam.id);
        assert!(swapped > 100.0, "camera {}: {swapped}", cam.id);
    }
}

/// The two fitted warps agree to a few hundredths of a pixel (the figure `calib check`
/// reports); vgps does not depend on it (the inverse is solved by Newton's method).
#[test]
fn the_two_warps_are_consistent_to_a_tenth_of_a_pixel() {
    let c = conf();
    for cam in &c.cameras {
        let w = c.warp_consistency(cam, 41).expect("consistency");
        println!(
            "camera {}: RectifiedSpline vs inverse DistortedSpline {w:.4} px",
            cam.id
        );
        assert!(w < 0.5, "camera {}: {w}", cam.id);
    }
}

/// Geometry of the head: six cameras, five around the horizon and one looking up; each
/// side camera's image u axis points down in the world and v to the left.
#[test]
fn head_geometry_is_the_rig_frame() {
    let c = conf();
    let rig = c.raw_rig().expect("rig");
    let axes: Vec<Vector3<f64>> = rig
        .cameras()
        .iter()
        .map(|rc| rc.rig_from_camera.rotation * Vector3::z())
        .collect();
    assert!(axes[0].x > 0.999, "camera 0 looks forward: {}", axes[0]);
    assert!(axes[5].z > 0.99, "camera 5 looks up: {}", axes[5]);
    for a in &axes[..5] {
        assert!(a.z.abs() < 0.02);
    }
    let r0 = rig.cameras()[0].rig_from_camera.rotation;
    assert!((r0 * Vector3::x()).z < -0.999, "u runs down");
    assert!((r0 * Vector3::y()).y > 0.999, "v runs left");
}

/// A LUT of the raw cameras reproduces the spline model within 0.01 px-equivalent.
#[test]
fn lut_of_a_raw_camera_matches_the_model() {
    let c = conf();
    let model: SplinePinhole = c.raw_model(&c.cameras[0]).expect("model");
    let lut = Lut::from_model(&model, 8).expect("lut");
    let mut worst: f64 = 0.0;
    for a in 0..37 {
        for b in 0..31 {
            let p = Vector2::new(3.3 + 66.1 * f64::from(a), 2.7 + 66.3 * f64::from(b));
            let exact = model.try_bearing(&p).expect("bearing");
            let table = lut.try_bearing(&p).expect("lut bearing");
            worst = worst.max(exact.angle(&table));
        }
    }
    // 1 px of the raw image is about 1/1232 rad at its centre.
    let px = worst * 1232.0;
    println!("LUT step 8 vs model: {worst:.2e} rad ≈ {px:.4} px");
    assert!(px < 0.01, "{px}");
}
