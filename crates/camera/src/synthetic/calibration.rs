//! Example cameras and rigs for the calibration tests and benchmarks.
//!
//! [`example_cameras`] is the table every calibration test runs over; [`ladybug_rig`] is a
//! Ladybug2-like rig of five side cameras and one top camera.

use crate::calibration::{
    Camera, Equirectangular, EquirectangularParams, KannalaBrandt, KannalaBrandtParams, Lut,
    Pinhole, PinholeParams, RadialTangential, Rig, RigCamera,
};
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};

/// Focal length (pixels) of the Ladybug2-like camera: one pixel at the image centre subtends
/// 0.00167557 rad, the figure of the Visual GPS proposal.
pub const LADYBUG2_FOCAL: f64 = 1.0 / 0.00167557;

/// Grid step (pixels) of the example LUTs: the largest step that keeps every example LUT
/// within 0.01 px of its source model (measured in `tests/calibration_models.rs`).
pub const EXAMPLE_LUT_STEP: u32 = 3;

/// A 1024×768 Ladybug2-like wide-angle pinhole (f ≈ 596.8 px, ~55° from the axis at the
/// corners) with barrel radial and small tangential distortion.
pub fn ladybug2_pinhole() -> Pinhole {
    let params = PinholeParams::ideal(1024, 768, LADYBUG2_FOCAL, LADYBUG2_FOCAL, 511.5, 383.5)
        .with_distortion(RadialTangential {
            k1: -0.25,
            k2: 0.06,
            p1: 2e-4,
            p2: -1.5e-4,
            k3: -0.003,
        });
    // The parameters are constants checked by the tests.
    Pinhole::new(params).unwrap_or_else(|e| unreachable!("{e}"))
}

/// A 1280×1024 Kannala-Brandt fisheye with OpenCV-like coefficients (~117° from the axis at
/// the corners).
pub fn opencv_fisheye() -> KannalaBrandt {
    KannalaBrandt::new(KannalaBrandtParams {
        width: 1280,
        height: 1024,
        fx: 420.0,
        fy: 421.5,
        cx: 640.3,
        cy: 511.7,
        k1: -0.02,
        k2: 0.004,
        k3: -0.001,
        k4: 0.0001,
    })
    .unwrap_or_else(|e| unreachable!("{e}"))
}

/// The 2048×1024 equirectangular panorama.
pub fn panorama() -> Equirectangular {
    Equirectangular::new(EquirectangularParams {
        width: 2048,
        height: 1024,
    })
    .unwrap_or_else(|e| unreachable!("{e}"))
}

/// The table of example cameras (name, model) that the calibration tests run over:
/// pinholes with and without distortion (incl. the Ladybug2-like one), fisheyes, the
/// panorama, and LUTs built from three of them at [`EXAMPLE_LUT_STEP`].
pub fn example_cameras() -> Vec<(&'static str, Camera)> {
    let ideal = Pinhole::new(PinholeParams::ideal(640, 480, 500.0, 500.0, 319.5, 239.5))
        .unwrap_or_else(|e| unreachable!("{e}"));
    let asymmetric = Pinhole::new(
        PinholeParams::ideal(1280, 960, 900.0, 905.0, 641.2, 478.9).with_distortion(
            RadialTangential {
                k1: 0.12,
                k2: -0.25,
                p1: -5e-4,
                p2: 3e-4,
                k3: 0.1,
            },
        ),
    )
    .unwrap_or_else(|e| unreachable!("{e}"));
    let equidistant = KannalaBrandt::new(KannalaBrandtParams {
        width: 1280,
        height: 960,
        fx: 350.0,
        fy: 350.0,
        cx: 639.5,
        cy: 479.5,
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
    })
    .unwrap_or_else(|e| unreachable!("{e}"));
    let lut = |m: &(dyn crate::calibration::CameraModel + Sync)| {
        Lut::from_model(m, EXAMPLE_LUT_STEP).unwrap_or_else(|e| unreachable!("{e}"))
    };
    let ladybug = ladybug2_pinhole();
    let fisheye = opencv_fisheye();
    let pano = panorama();
    vec![
        ("pinhole_ideal_640x480", Camera::from(ideal)),
        ("pinhole_ladybug2_1024x768", Camera::from(ladybug.clone())),
        ("pinhole_distorted_1280x960", Camera::from(asymmetric)),
        ("fisheye_equidistant_1280x960", Camera::from(equidistant)),
        ("fisheye_opencv_1280x1024", Camera::from(fisheye.clone())),
        ("equirectangular_2048x1024", Camera::from(pano.clone())),
        ("lut_ladybug2", Camera::from(lut(&ladybug))),
        ("lut_fisheye_opencv", Camera::from(lut(&fisheye))),
        ("lut_equirectangular", Camera::from(lut(&pano))),
    ]
}

/// Yaw (radians, anticlockwise from rig +x about rig +z) of side camera `k` of five.
fn side_yaw(k: usize) -> f64 {
    std::f64::consts::TAU * (k as f64) / 5.0
}

/// `rig_from_camera` of the Ladybug2-like rig: five side cameras every 72° of yaw on a
/// circle of radius 0.04 m (camera `k` looks along yaw `72° k`, image up = rig +z), and a
/// top camera 0.06 m above the origin looking up (camera x → rig −y, image down → rig +x).
pub fn ladybug_placements() -> Vec<IsometryMatrix3<f64>> {
    let mut out = Vec::with_capacity(6);
    for k in 0..5 {
        let (s, c) = side_yaw(k).sin_cos();
        // Columns: camera x (right), y (down), z (forward) in the rig frame.
        let r = Matrix3::new(s, 0.0, c, -c, 0.0, s, 0.0, -1.0, 0.0);
        out.push(IsometryMatrix3::from_parts(
            Translation3::from(Vector3::new(0.04 * c, 0.04 * s, 0.0)),
            Rotation3::from_matrix_unchecked(r),
        ));
    }
    let top = Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    out.push(IsometryMatrix3::from_parts(
        Translation3::from(Vector3::new(0.0, 0.0, 0.06)),
        Rotation3::from_matrix_unchecked(top),
    ));
    out
}

/// A Ladybug2-like rig of six copies of `model` at [`ladybug_placements`].
pub fn ladybug_rig(model: &Camera) -> Rig {
    let cameras = ladybug_placements()
        .into_iter()
        .map(|rig_from_camera| RigCamera {
            model: model.clone(),
            rig_from_camera,
        })
        .collect();
    Rig::new(cameras).unwrap_or_else(|e| unreachable!("{e}"))
}
