//! Ladybug INI dumps as the SDK tools write them (issue 23): informational keys, the dotted
//! spelling with `#` comment lines, the global rotation, the image size from the camera
//! model name.

use nalgebra::{Point3, Rotation3};
use std::path::Path;
use vgps::calibration::CameraModel;
use vgps::calibration::formats::ladybug_ini::{
    self, head_from_camera_rotation, parse_with_info, size_from_camera_model,
};

/// A Ladybug5-like head: per camera (rotX, rotY, rotZ, tx, ty, tz, f, cx, cy), portrait
/// rectified images (principal points near (1024, 1224)).
fn cameras() -> Vec<[f64; 9]> {
    (0..6)
        .map(|i| {
            let yaw = f64::from(i) * 72f64.to_radians();
            let (rx, ry) = if i == 5 {
                (0.0, 0.0)
            } else {
                (-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2)
            };
            [
                rx + 0.01 * f64::from(i),
                ry,
                yaw,
                0.04 * yaw.cos(),
                0.04 * yaw.sin(),
                if i == 5 { 0.06 } else { 0.0 },
                1230.0 + f64::from(i),
                1020.0 + f64::from(i),
                1226.5 - f64::from(i),
            ]
        })
        .collect()
}

const KEYS: [&str; 9] = [
    "rotX",
    "rotY",
    "rotZ",
    "transX",
    "transY",
    "transZ",
    "FocalLen",
    "CameraCenterX",
    "CameraCenterY",
];

/// The first spelling with the informational keys and the global rotation.
fn equals_spelling(rotation: [f64; 3]) -> String {
    let mut s = String::from(
        "camera_model = Ladybug5 LD5-U3-51S5C-44\ncamera_serialBase = 17300001\n\
         camera_serialHead = 17300002\n",
    );
    for (i, c) in cameras().iter().enumerate() {
        for (k, v) in KEYS.iter().zip(c) {
            s += &format!("camera{i}_{k} = {v}\n");
        }
    }
    s += &format!(
        "rotation_dRx = {}\nrotation_dRy = {}\nrotation_dRz = {}\n",
        rotation[0], rotation[1], rotation[2]
    );
    s
}

/// The second spelling: dotted keys, value after whitespace, `#` comments.
fn dotted_spelling(rotation: [f64; 3]) -> String {
    let mut s = String::from(
        "# Ladybug calibration dump\n#camera_model  Ladybug5 LD5-U3-51S5C-44\n\
         #camera_serialHead 17300002\n",
    );
    for (i, c) in cameras().iter().enumerate() {
        for (k, v) in KEYS.iter().zip(c) {
            s += &format!("camera{i}.{k} {v}\n");
        }
    }
    s += &format!(
        "rotation.dRx {}\nrotation.dRy {}\nrotation.dRz {}\n",
        rotation[0], rotation[1], rotation[2]
    );
    s
}

const ROTATION: [f64; 3] = [0.0123, -0.0087, 0.2501];

#[test]
fn both_spellings_give_the_same_rig_and_keep_the_informational_keys() {
    let path = Path::new("dump.ini");
    let (a, ia) = parse_with_info(&equals_spelling(ROTATION), path, None).expect("first");
    let (b, ib) = parse_with_info(&dotted_spelling(ROTATION), path, None).expect("second");
    assert_eq!(a, b);
    assert_eq!(ia.camera_model.as_deref(), Some("Ladybug5 LD5-U3-51S5C-44"));
    assert_eq!(ib.camera_model.as_deref(), Some("Ladybug5 LD5-U3-51S5C-44"));
    assert_eq!(ia.serial_base.as_deref(), Some("17300001"));
    assert_eq!(ib.serial_head.as_deref(), Some("17300002"));
    assert_eq!(ia.global_rotation, Some(ROTATION));
    assert!(ia.warnings.is_empty() && ib.warnings.is_empty());
    // The image size from the model name: Ladybug5, portrait (principal points near
    // (1023.5, 1223.5)).
    let (size, source) = ia.image_size.expect("size from the camera model");
    assert_eq!(size, (2048, 2448));
    assert!(source.contains("camera model"), "{source}");
    assert_eq!(a.cameras()[0].model.image_size(), (2048, 2448));
}

/// The documented direction: the pixel of head-frame point `P` with the global rotation
/// `G` is the pixel of `G⁻¹ P` without it.
#[test]
fn global_rotation_applies_its_inverse_to_head_points() {
    let path = Path::new("dump.ini");
    let with = ladybug_ini::parse(&equals_spelling(ROTATION), path, None).expect("with");
    let without = ladybug_ini::parse(&equals_spelling([0.0; 3]), path, None).expect("without");
    let g: Rotation3<f64> = head_from_camera_rotation(ROTATION[0], ROTATION[1], ROTATION[2]);
    let mut seen = 0;
    for k in 0..200 {
        let t = f64::from(k);
        let p = Point3::new(
            10.0 * (0.37 * t).cos(),
            10.0 * (0.37 * t).sin(),
            6.0 * (0.11 * t).sin(),
        );
        let q = Point3::from(g.inverse() * p.coords);
        for (cw, co) in with.cameras().iter().zip(without.cameras()) {
            let a = cw
                .model
                .try_pixel(&cw.rig_from_camera.inverse_transform_point(&p).coords);
            let b = co
                .model
                .try_pixel(&co.rig_from_camera.inverse_transform_point(&q).coords);
            match (a, b) {
                (Some(a), Some(b)) => {
                    assert!((a - b).norm() < 1e-9, "{a} vs {b}");
                    seen += 1;
                }
                (None, None) => {}
                _ => panic!("seen by one rig only"),
            }
        }
    }
    assert!(seen > 100, "{seen}");
    // And the rotation is not a no-op: without it the pixels move by pixels.
    let p = Point3::new(10.0, 0.5, 0.3);
    let moved = with
        .cameras()
        .iter()
        .zip(without.cameras())
        .filter_map(|(cw, co)| {
            let a = cw
                .model
                .try_pixel(&cw.rig_from_camera.inverse_transform_point(&p).coords)?;
            let b = co
                .model
                .try_pixel(&co.rig_from_camera.inverse_transform_point(&p).coords)?;
            Some((a - b).norm())
        })
        .fold(0.0, f64::max);
    assert!(moved > 10.0, "{moved}");
}

#[test]
fn an_unknown_key_is_a_warning_and_partial_rotation_an_error() {
    let path = Path::new("dump.ini");
    let text = format!(
        "{}camera0_Skew = 0\nfirmware = 1.2.3\n",
        equals_spelling(ROTATION)
    );
    let (_, info) = parse_with_info(&text, path, None).expect("warnings only");
    assert_eq!(info.warnings.len(), 2, "{:?}", info.warnings);
    assert!(info.warnings[0].contains("camera0_Skew"));
    let partial = equals_spelling(ROTATION).replace("rotation_dRy = -0.0087\n", "");
    let e = ladybug_ini::parse(&partial, path, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("dump.ini") && e.contains("key rotation_dRy") && e.contains("missing key"),
        "{e}"
    );
    // A required key still missing: as before.
    let missing = equals_spelling(ROTATION).replace("camera3_FocalLen = 1233\n", "");
    let e = ladybug_ini::parse(&missing, path, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("key camera3_FocalLen") && e.contains("missing key"),
        "{e}"
    );
}

#[test]
fn image_size_sources_in_order() {
    let path = Path::new("dump.ini");
    // Given size wins over the model name.
    let (_, info) =
        parse_with_info(&equals_spelling(ROTATION), path, Some((2048, 2448))).expect("given");
    assert_eq!(info.image_size, Some(((2048, 2448), "given".to_string())));
    // Unknown model: unbounded.
    let text = equals_spelling(ROTATION).replace("Ladybug5 LD5-U3-51S5C-44", "Spherical X");
    let (rig, info) = parse_with_info(&text, path, None).expect("unknown model");
    assert_eq!(info.image_size, None);
    assert_eq!(rig.cameras()[0].model.image_size(), (0, 0));
    // Orientation by the principal points; ambiguous or off-centre gives none.
    assert_eq!(
        size_from_camera_model("Ladybug5+ LD5P-U3-51S5C-B", &[(1231.5, 1023.5)]),
        Some((2464, 2048))
    );
    assert_eq!(
        size_from_camera_model("LD5-U3-51S5C-44", &[(1023.5, 1023.5)]),
        None
    );
    assert_eq!(
        size_from_camera_model("LD5-U3-51S5C-44", &[(100.0, 100.0)]),
        None
    );
}
