//! Per-camera masks in a rig's calibration (pixels that never see the world): read from a
//! calibration directory, checked against the image size, and applied to detections.

use image::GrayImage;
use nalgebra::Vector2;
use std::path::Path;
use vgps::calibration::{
    Camera, CameraMask, Equirectangular, EquirectangularParams, Rig, formats::nclt,
};
use vgps::drive::FrameRecord;
use vgps::imaging::{DetectorKind, ImageDetector, detect_frame_images, encode_png};

fn manifest(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("dir") {
        let p = e.expect("entry").path();
        std::fs::copy(&p, to.join(p.file_name().expect("name"))).expect("copy");
    }
}

#[test]
fn nclt_directory_masks_are_read_and_checked() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path().join("nclt");
    copy_dir(&manifest("tests/fixtures/calibration/nclt_16x12"), &d);
    // Camera 2: the bottom three rows see the vehicle (black).
    let img = GrayImage::from_fn(16, 12, |_, v| image::Luma([if v >= 9 { 0 } else { 255 }]));
    std::fs::write(d.join("mask_cam2.png"), encode_png(&img).expect("png")).expect("write");
    let rig = nclt::read(&d).expect("read");
    assert!(rig.mask(0).is_none());
    let m = rig.mask(2).expect("mask of camera 2");
    assert_eq!(m.dimensions(), (16, 12));
    assert_eq!(m.count(), 16 * 3);
    assert!(rig.is_masked(2, &Vector2::new(4.0, 9.2)));
    assert!(!rig.is_masked(2, &Vector2::new(4.0, 8.4)));
    assert!(!rig.is_masked(1, &Vector2::new(4.0, 10.0)));
    // A mask of another size is an error naming the file.
    let small = GrayImage::from_fn(8, 6, |_, _| image::Luma([0]));
    std::fs::write(d.join("mask_cam3.png"), encode_png(&small).expect("png")).expect("write");
    let e = nclt::read(&d).unwrap_err().to_string();
    assert!(e.contains("mask_cam3.png") && e.contains("8×6"), "{e}");
}

/// The real NCLT masks (ethz-asl/nclt_tools, Apache-2.0): 616 × 808, black where the
/// half-resolution upright *undistorted* image has no data (its pincushion border).
#[test]
fn real_nclt_masks_read() {
    for i in 0..6 {
        let m = CameraMask::read_png(&manifest(&format!("tests/data/nclt_masks/cam_{i}.png")))
            .expect("mask");
        assert_eq!(m.dimensions(), (616, 808));
        let fraction = m.count() as f64 / (616.0 * 808.0);
        assert!((0.3..0.6).contains(&fraction), "camera {i}: {fraction}");
        // Corners are outside the undistorted image's data, the centre inside.
        assert!(m.is_masked(0, 0) && m.is_masked(615, 807) && m.is_masked(0, 404));
        assert!(
            !m.is_masked(308, 404) && !m.is_masked(308, 250),
            "camera {i}"
        );
    }
}

#[test]
fn detections_on_masked_pixels_are_dropped() {
    let dir = tempfile::tempdir().expect("tmp");
    // A dark 64 × 32 panorama with two bright lamps.
    let lamp = |u: u32, v: u32, cu: u32, cv: u32| u.abs_diff(cu) <= 1 && v.abs_diff(cv) <= 1;
    let img = GrayImage::from_fn(64, 32, |u, v| {
        image::Luma([if lamp(u, v, 12, 10) || lamp(u, v, 48, 20) {
            250
        } else {
            10
        }])
    });
    std::fs::write(dir.path().join("f.png"), encode_png(&img).expect("png")).expect("write");
    let pano = Equirectangular::new(EquirectangularParams {
        width: 64,
        height: 32,
    })
    .expect("pano");
    let rig = Rig::panorama(Camera::from(pano));
    let frame = FrameRecord {
        frame: 0,
        time_s: 0.0,
        images: vec![Some("f.png".into())],
    };
    for kind in [DetectorKind::Point, DetectorKind::Street] {
        let all = detect_frame_images(dir.path(), &frame, &rig, &ImageDetector::new(kind, &rig));
        assert_eq!(all.detections.len(), 2, "{kind:?}: {all:?}");
        assert!(
            all.detections
                .iter()
                .all(|d| d.class.as_deref() == Some("streetlight"))
        );
        // Mask the right half: the lamp at (48, 20) is dropped.
        let mask = CameraMask::from_fn(64, 32, |u, _| u >= 32).expect("mask");
        let masked_rig = rig.clone().with_mask(0, mask).expect("same size");
        let detector = ImageDetector::new(kind, &masked_rig);
        let kept = detect_frame_images(dir.path(), &frame, &masked_rig, &detector);
        assert_eq!(kept.detections.len(), 1, "{kind:?}");
        assert!((kept.detections[0].u - 12.0).abs() < 0.5);
        assert!(kept.problems.is_empty());
    }
}

#[test]
fn the_mask_is_applied_before_detection() {
    // A saturated car body along the bottom sets the street detector's white level, which
    // hides the dimmer lamp above it (and the body is no lamp: too long). With the body
    // masked before detection, the lamp is the brightest core left and is found.
    let dir = tempfile::tempdir().expect("tmp");
    let img = GrayImage::from_fn(64, 32, |u, v| {
        let lamp = u.abs_diff(20) <= 1 && v.abs_diff(8) <= 1;
        image::Luma([if v >= 26 {
            255
        } else if lamp {
            200
        } else {
            10
        }])
    });
    std::fs::write(dir.path().join("f.png"), encode_png(&img).expect("png")).expect("write");
    let pano = Equirectangular::new(EquirectangularParams {
        width: 64,
        height: 32,
    })
    .expect("pano");
    let rig = Rig::panorama(Camera::from(pano));
    let frame = FrameRecord {
        frame: 0,
        time_s: 0.0,
        images: vec![Some("f.png".into())],
    };
    let street = ImageDetector::new(DetectorKind::Street, &rig);
    let unmasked = detect_frame_images(dir.path(), &frame, &rig, &street);
    assert!(
        unmasked.detections.iter().all(|d| (d.u - 20.0).abs() > 2.0),
        "{unmasked:?}"
    );
    let body = CameraMask::from_fn(64, 32, |_, v| v >= 26).expect("mask");
    let masked_rig = rig.with_mask(0, body).expect("same size");
    let street = ImageDetector::new(DetectorKind::Street, &masked_rig);
    let found = detect_frame_images(dir.path(), &frame, &masked_rig, &street);
    assert_eq!(found.detections.len(), 1, "{found:?}");
    assert!(
        (found.detections[0].u - 20.0).abs() < 1e-9 && (found.detections[0].v - 8.0).abs() < 1e-9
    );
}

/// `vgps calib convert` of an NCLT directory with masks to the native JSON keeps every
/// mask (a PNG side file per masked camera), the JSON reads back to the same rig, a second
/// conversion JSON → JSON and a conversion to LUTs keep them too, and a broken mask side
/// file is an error naming the JSON, the camera's `mask` field and the PNG.
#[test]
fn masks_survive_convert_to_native_and_back() {
    use vgps::calibration::formats::{Format, load};
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path().join("nclt");
    copy_dir(&manifest("tests/fixtures/calibration/nclt_16x12"), &d);
    let mask2 = GrayImage::from_fn(16, 12, |u, v| {
        image::Luma([if v >= 9 || (u < 2 && v < 3) { 0 } else { 255 }])
    });
    let mask5 = GrayImage::from_fn(16, 12, |u, _| image::Luma([if u == 15 { 0 } else { 200 }]));
    std::fs::write(d.join("mask_cam2.png"), encode_png(&mask2).expect("png")).expect("write");
    std::fs::write(d.join("mask_cam5.png"), encode_png(&mask5).expect("png")).expect("write");
    let original = nclt::read(&d).expect("read");
    assert_eq!(original.mask(2).expect("mask 2").count(), 16 * 3 + 2 * 3);
    assert_eq!(original.mask(5).expect("mask 5").count(), 12);

    let convert = |input: &Path, to: &str, output: &Path, extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_vgps"))
            .args(["calib", "convert"])
            .arg(input)
            .args(["--to", to])
            .args(extra)
            .arg(output)
            .output()
            .expect("run vgps");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let json = dir.path().join("rig.json");
    convert(&d, "native", &json, &[]);
    let text = std::fs::read_to_string(&json).expect("json");
    assert!(text.contains("\"mask\": \"rig.cam2.mask.png\""), "{text}");
    assert!(text.contains("\"mask\": \"rig.cam5.mask.png\""), "{text}");
    assert_eq!(text.matches("\"mask\"").count(), 2, "{text}");
    let back = load(&json, Some(Format::Native), None).expect("native");
    assert_eq!(back, original);
    assert!(back.mask(0).is_none());

    // JSON → JSON (into another directory) and JSON → LUTs keep the masks.
    std::fs::create_dir(dir.path().join("again")).expect("mkdir");
    let json2 = dir.path().join("again/rig2.json");
    convert(&json, "native", &json2, &[]);
    assert_eq!(load(&json2, None, None).expect("native"), original);
    let lut_json = dir.path().join("lut.json");
    convert(&json, "lut", &lut_json, &["--step", "4"]);
    let luts = load(&lut_json, None, None).expect("lut rig");
    for i in 0..6 {
        assert_eq!(luts.mask(i), original.mask(i), "camera {i}");
    }

    // A mask side file of the wrong size, or missing: the JSON, the field and the PNG.
    let small = GrayImage::from_fn(8, 6, |_, _| image::Luma([0]));
    std::fs::write(
        dir.path().join("rig.cam5.mask.png"),
        encode_png(&small).expect("png"),
    )
    .expect("write");
    let e = load(&json, None, None).unwrap_err().to_string();
    assert!(
        e.contains("rig.json") && e.contains("cameras[5].mask") && e.contains("8×6"),
        "{e}"
    );
    std::fs::remove_file(dir.path().join("rig.cam2.mask.png")).expect("rm");
    let e = load(&json, None, None).unwrap_err().to_string();
    assert!(
        e.contains("cameras[2].mask") && e.contains("rig.cam2.mask.png"),
        "{e}"
    );
}
