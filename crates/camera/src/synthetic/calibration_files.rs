//! The synthetic calibrations behind the shipped files in `calibration/` and the test
//! fixtures in `tests/fixtures/calibration/` (regenerate them with
//! `cargo run --example generate_calibration`). Every number is a constant: the files are
//! reproducible bit for bit.

use crate::calibration::{
    Camera, DistortionTable, KannalaBrandt, KannalaBrandtParams, Rig, RigCamera, TabulatedPinhole,
    TabulatedPinholeParams,
};
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};
use std::f64::consts::{FRAC_PI_2, TAU};

/// Focal length (pixels) of the Ladybug2-like camera: one pixel at the image centre
/// subtends 0.00167557 rad (≈ 596.8 px).
pub const LADYBUG2_FOCAL_PX: f64 = 1.0 / 0.00167557;

/// Ladybug2-like image width (pixels).
pub const LADYBUG2_WIDTH: u32 = 1024;

/// Ladybug2-like image height (pixels).
pub const LADYBUG2_HEIGHT: u32 = 768;

/// Kannala-Brandt `k1` of the Ladybug2-like lens (a wide-angle lens compressing the
/// periphery relative to the equidistant projection).
pub const LADYBUG2_K1: f64 = -0.2;

/// Kannala-Brandt `k2` of the Ladybug2-like lens.
pub const LADYBUG2_K2: f64 = 0.1;

/// Distance (metres) of the side camera centres from the head axis.
pub const LADYBUG2_SIDE_RADIUS_M: f64 = 0.04;

/// Height (metres) of the top camera centre above the head centre.
pub const LADYBUG2_TOP_HEIGHT_M: f64 = 0.04;

/// The Ladybug2-like lens: 1024×768, f ≈ 596.8 px, principal point at the image centre,
/// Kannala-Brandt `k1 = −0.2, k2 = 0.1` (≈ 40° from the axis at the middle of the long
/// edges, ≈ 55° at the short edges, ≈ 69° at the corners).
pub fn ladybug2_lens() -> KannalaBrandt {
    KannalaBrandt::new(KannalaBrandtParams {
        width: LADYBUG2_WIDTH,
        height: LADYBUG2_HEIGHT,
        fx: LADYBUG2_FOCAL_PX,
        fy: LADYBUG2_FOCAL_PX,
        cx: 511.5,
        cy: 383.5,
        k1: LADYBUG2_K1,
        k2: LADYBUG2_K2,
        k3: 0.0,
        k4: 0.0,
    })
    .unwrap_or_else(|e| unreachable!("constant parameters are valid: {e}"))
}

/// `rig_from_camera` rotation of side camera `k` (yaw `α = 72° k` anticlockwise from
/// rig +x): optical axis `(cos α, sin α, 0)`, image columns (camera x) pointing down
/// (rig −z, the sensor mounted in portrait as in a Ladybug), rows (camera y) to the left.
pub fn side_rotation(k: usize) -> Rotation3<f64> {
    let (s, c) = (TAU * k as f64 / 5.0).sin_cos();
    // Columns: camera x, y, z in the rig frame.
    Rotation3::from_matrix_unchecked(Matrix3::new(0.0, -s, c, 0.0, c, s, -1.0, 0.0, 0.0))
}

/// `rig_from_camera` rotation of the top camera: optical axis rig +z, camera x → rig −y,
/// camera y (image down) → rig +x.
pub fn top_rotation() -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0))
}

/// Placements of a Ladybug-like head: five side cameras on a circle of `radius` metres
/// ([`side_rotation`]) and a top camera `top_height` metres above the centre
/// ([`top_rotation`]).
pub fn ladybug_placements(radius: f64, top_height: f64) -> Vec<IsometryMatrix3<f64>> {
    let mut out: Vec<_> = (0..5)
        .map(|k| {
            let (s, c) = (TAU * k as f64 / 5.0).sin_cos();
            IsometryMatrix3::from_parts(
                Translation3::new(radius * c, radius * s, 0.0),
                side_rotation(k),
            )
        })
        .collect();
    out.push(IsometryMatrix3::from_parts(
        Translation3::new(0.0, 0.0, top_height),
        top_rotation(),
    ));
    out
}

/// The Ladybug2-like rig of `calibration/ladybug2.json`: six [`ladybug2_lens`] cameras at
/// [`ladybug_placements`]`(0.04, 0.04)`.
pub fn ladybug2_rig() -> Rig {
    let lens = Camera::from(ladybug2_lens());
    rig_of(&lens, LADYBUG2_SIDE_RADIUS_M, LADYBUG2_TOP_HEIGHT_M)
}

fn rig_of(model: &Camera, radius: f64, top_height: f64) -> Rig {
    let cameras = ladybug_placements(radius, top_height)
        .into_iter()
        .map(|rig_from_camera| RigCamera {
            model: model.clone(),
            rig_from_camera,
        })
        .collect();
    Rig::new(cameras).unwrap_or_else(|e| unreachable!("constant placements are valid: {e}"))
}

/// Ladybug INI values `[rotX, rotY, rotZ, transX, transY, transZ, FocalLen, CameraCenterX,
/// CameraCenterY]` of a head whose cameras sit at [`ladybug_placements`]`(radius,
/// top_height)`: side camera `k` is `rotX = 0, rotY = π/2, rotZ = 72° k` (so
/// `Rz·Ry·Rx` = [`side_rotation`]`(k)`), the top camera `rotX = rotY = 0, rotZ = −π/2`
/// ([`top_rotation`]). `tweak` (radians) is added to `rotX` of camera `k` as `tweak · k`
/// to make an example less regular.
pub fn ladybug_ini_values(
    focal: f64,
    centre: (f64, f64),
    radius: f64,
    top_height: f64,
    tweak: f64,
) -> [[f64; 9]; 6] {
    let mut out = [[0.0; 9]; 6];
    for (k, row) in out.iter_mut().enumerate() {
        let (rx, ry, rz, t) = if k < 5 {
            let yaw = TAU * k as f64 / 5.0;
            let (s, c) = yaw.sin_cos();
            (
                tweak * k as f64,
                FRAC_PI_2,
                yaw,
                [radius * c, radius * s, 0.0],
            )
        } else {
            (tweak * k as f64, 0.0, -FRAC_PI_2, [0.0, 0.0, top_height])
        };
        *row = [rx, ry, rz, t[0], t[1], t[2], focal, centre.0, centre.1];
    }
    out
}

/// Rounds to 1e-6 (six decimals), as a table file would store it.
fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// A [`TabulatedPinhole`] with synthetic radial distortion tables: `K = [f 0 cx; 0 f cy;
/// 0 0 1]` with the principal point at the image centre, raw = `K · d(K⁻¹ undistorted)`
/// with `d(x) = x (1 + k1 r² + k2 r⁴)`, tabulated at every pixel of a `width × height`
/// image (`U2D`: undistorted → raw, `D2U`: raw → undistorted by inverting `d`), each value
/// rounded to 1e-6 px.
pub fn radial_table_camera(width: u32, height: u32, f: f64, k1: f64, k2: f64) -> TabulatedPinhole {
    let (cx, cy) = (f64::from(width - 1) / 2.0, f64::from(height - 1) / 2.0);
    let distort = |r: f64| r * (1.0 + k1 * r * r + k2 * r.powi(4));
    let undistort = |rd: f64| {
        let mut r = rd;
        for _ in 0..50 {
            let slope = 1.0 + 3.0 * k1 * r * r + 5.0 * k2 * r.powi(4);
            r -= (distort(r) - rd) / slope;
        }
        r
    };
    let table = |map: &dyn Fn(f64) -> f64| {
        let mut positions = Vec::with_capacity((width * height) as usize);
        for r in 0..height {
            for c in 0..width {
                let (x, y) = ((f64::from(c) - cx) / f, (f64::from(r) - cy) / f);
                let rho = x.hypot(y);
                let scale = if rho > 0.0 { map(rho) / rho } else { 1.0 };
                positions.push([round6(cx + f * x * scale), round6(cy + f * y * scale)]);
            }
        }
        DistortionTable {
            width,
            height,
            positions,
        }
    };
    TabulatedPinhole::new(TabulatedPinholeParams {
        width: Some(width),
        height: Some(height),
        fx: f,
        fy: f,
        skew: 0.0,
        cx,
        cy,
        raw_to_undistorted: Some(table(&undistort)),
        undistorted_to_raw: Some(table(&distort)),
    })
    .unwrap_or_else(|e| unreachable!("monotonic synthetic tables are valid: {e}"))
}

/// An NCLT-style Ladybug3 rig: six [`radial_table_camera`]`(width, height, f, −0.12, 0.02)`
/// at [`ladybug_placements`]`(0.042, 0.06)`.
pub fn nclt_rig(width: u32, height: u32, f: f64) -> Rig {
    let camera = Camera::from(radial_table_camera(width, height, f, -0.12, 0.02));
    rig_of(&camera, 0.042, 0.06)
}

/// The optical axis of camera `index` of a rig, in the rig frame.
pub fn optical_axis(rig: &Rig, index: usize) -> Option<Vector3<f64>> {
    rig.cameras()
        .get(index)
        .map(|c| c.rig_from_camera.rotation * Vector3::z())
}
