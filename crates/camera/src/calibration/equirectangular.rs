//! The equirectangular (longitude-latitude) panorama.

use super::{CalibrationError, CameraModel, Pixel, check_size, in_image_rectangle};
use nalgebra::{Matrix2x3, Matrix3, Matrix3x2, Rotation3, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// The parameters of an [`Equirectangular`] panorama (serde: the native JSON form).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EquirectangularParams {
    /// Panorama width in pixels (360° of longitude).
    pub width: u32,
    /// Panorama height in pixels (180° of latitude).
    pub height: u32,
}

/// A full-sphere equirectangular panorama of `W × H` pixels.
///
/// # Model
/// With the crate's pixel convention (integer = pixel centre), longitude θ and latitude φ
/// are
/// ```text
/// θ = 2π ((u + ½) / W − ½)      ∈ [−π, π]   (u = −½ … W − ½)
/// φ = π (½ − (v + ½) / H)       ∈ [−π/2, π/2] (v = −½ … H − ½, top = +π/2)
/// ```
/// (COLMAP/OpenSfM's `θ = 2π(u'/W − ½)` with `u' = u + ½` measured from the image's left
/// edge). The bearing is in the **camera frame** of the panorama (x right, y down,
/// z forward = image centre), as OpenSfM's spherical camera:
/// ```text
/// b = (cos φ sin θ, −sin φ, cos φ cos θ)
/// ```
/// so the image centre looks along camera +z, `u` increasing turns right and the top row is
/// camera −y (up). Placed in a rig with [`rig_from_panorama`] (the rotation that maps camera
/// z → rig x, camera x → rig −y, camera y → rig −z), the same bearing in the rig frame
/// (x forward, y left, z up) is `(cos φ cos θ, −cos φ sin θ, sin φ)`: the panorama centre
/// looks along rig +x and its top row is rig +z.
///
/// Pixel → bearing uses tables of (sin, cos) at the column and row centres and the
/// angle-addition formulas with a Taylor series for the sub-pixel offset (≤ 1 ulp-level
/// difference from calling `sin_cos`, several times faster).
///
/// Every pixel of the rectangle is valid. Bearing → pixel maps the seam θ = ±π to
/// `u = −½` / `W − ½` (the same column), and is defined everywhere; its Jacobian is
/// singular at the poles (`None` from
/// [`try_pixel_with_jacobian`](CameraModel::try_pixel_with_jacobian)).
///
/// # Example
/// ```
/// use nalgebra::{Vector2, Vector3};
/// use vgps_camera::calibration::{CameraModel, Equirectangular, EquirectangularParams};
/// let pano = Equirectangular::new(EquirectangularParams { width: 2048, height: 1024 })?;
/// // The image centre (between the four middle pixels) looks forward along camera +z.
/// let b = pano.try_bearing(&Vector2::new(1023.5, 511.5)).unwrap();
/// assert!((b - Vector3::z()).norm() < 1e-12);
/// // A quarter turn to the right is a quarter of the width further right.
/// let p = pano.try_pixel(&Vector3::x()).unwrap();
/// assert!((p - Vector2::new(1023.5 + 512.0, 511.5)).norm() < 1e-9);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "EquirectangularParams", into = "EquirectangularParams")]
pub struct Equirectangular {
    params: EquirectangularParams,
    /// dθ/du = 2π / W.
    theta_per_u: f64,
    /// dφ/dv = −π / H.
    phi_per_v: f64,
    /// (sin θ, cos θ) at every column centre u = 0 … W − 1.
    column_sin_cos: Vec<(f64, f64)>,
    /// (sin φ, cos φ) at every row centre v = 0 … H − 1.
    row_sin_cos: Vec<(f64, f64)>,
    /// Largest valid pixel coordinates `(W − ½, H − ½)`, kept to spare a conversion per call.
    max_pixel: (f64, f64),
}

/// Largest angular offset (radians) from a tabulated pixel centre for which the
/// panorama's pixel → bearing uses the table and a Taylor series (truncation below 10⁻¹⁷);
/// beyond it (panoramas narrower than 63 pixels) it calls `sin_cos`.
pub const EQUIRECTANGULAR_TABLE_MAX_OFFSET: f64 = 0.05;

/// sin and cos of a small angle by their Taylor series (|δ| ≤
/// [`EQUIRECTANGULAR_TABLE_MAX_OFFSET`]: error < 10⁻¹⁷).
#[inline]
fn small_sin_cos(d: f64) -> (f64, f64) {
    // Horner form with reciprocal factorials: multiplications only (a division by a constant
    // that is not a power of two cannot be turned into a multiplication by the compiler).
    const S3: f64 = -1.0 / 6.0;
    const S5: f64 = 1.0 / 120.0;
    const S7: f64 = -1.0 / 5040.0;
    const C2: f64 = -0.5;
    const C4: f64 = 1.0 / 24.0;
    const C6: f64 = -1.0 / 720.0;
    const C8: f64 = 1.0 / 40320.0;
    let d2 = d * d;
    let s = d + d * d2 * (S3 + d2 * (S5 + d2 * S7));
    let c = 1.0 + d2 * (C2 + d2 * (C4 + d2 * (C6 + d2 * C8)));
    (s, c)
}

/// (sin, cos) of `table[k] + delta` by the angle-addition formulas, where `k` is the
/// nearest tabulated centre to `coordinate` and `delta = (coordinate − k) · per_pixel`.
#[inline]
fn table_sin_cos(table: &[(f64, f64)], coordinate: f64, per_pixel: f64, angle: f64) -> (f64, f64) {
    // Nearest centre without `f64::round` (a libm call on baseline x86-64); `as usize`
    // truncates towards zero and saturates, and the coordinate is ≥ −½ here.
    // `as u32` (tables have fewer than 2³² entries) compiles to one conversion on x86-64,
    // where `as usize` needs a slower unsigned 64-bit sequence.
    let k = (((coordinate + 0.5) as u32) as usize).min(table.len() - 1);
    let delta = (coordinate - k as f64) * per_pixel;
    if delta.abs() > EQUIRECTANGULAR_TABLE_MAX_OFFSET {
        return angle.sin_cos();
    }
    let (sk, ck) = table[k];
    let (sd, cd) = small_sin_cos(delta);
    (sk * cd + ck * sd, ck * cd - sk * sd)
}

/// The rotation `rig_from_camera` that places a panorama's camera frame in the rig frame:
/// camera z (image centre) → rig x (forward), camera x (right) → rig −y, camera y (down) →
/// rig −z.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// let r = vgps_camera::calibration::rig_from_panorama();
/// assert!((r * Vector3::z() - Vector3::x()).norm() < 1e-15);
/// assert!((r * Vector3::y() + Vector3::z()).norm() < 1e-15);
/// ```
pub fn rig_from_panorama() -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, //
        -1.0, 0.0, 0.0, //
        0.0, -1.0, 0.0,
    ))
}

impl Equirectangular {
    /// A panorama of `width × height` pixels (both non-zero).
    pub fn new(params: EquirectangularParams) -> Result<Self, CalibrationError> {
        check_size("equirectangular", params.width, params.height)?;
        let mut model = Self {
            params,
            theta_per_u: TAU / f64::from(params.width),
            phi_per_v: -PI / f64::from(params.height),
            column_sin_cos: Vec::new(),
            row_sin_cos: Vec::new(),
            max_pixel: (
                f64::from(params.width) - 0.5,
                f64::from(params.height) - 0.5,
            ),
        };
        model.column_sin_cos = (0..params.width)
            .map(|u| model.angles(&Vector2::new(f64::from(u), 0.0)).0.sin_cos())
            .collect();
        model.row_sin_cos = (0..params.height)
            .map(|v| model.angles(&Vector2::new(0.0, f64::from(v))).1.sin_cos())
            .collect();
        Ok(model)
    }

    /// The parameters.
    pub fn params(&self) -> &EquirectangularParams {
        &self.params
    }

    /// The test of [`in_image_rectangle`], against the stored bounds.
    #[inline]
    fn contains(&self, pixel: &Pixel) -> bool {
        pixel.x >= -0.5
            && pixel.x <= self.max_pixel.0
            && pixel.y >= -0.5
            && pixel.y <= self.max_pixel.1
    }

    /// Longitude θ and latitude φ (radians) of a pixel.
    #[inline]
    pub fn angles(&self, pixel: &Pixel) -> (f64, f64) {
        let theta = (pixel.x + 0.5) * self.theta_per_u - PI;
        let phi = (pixel.y + 0.5) * self.phi_per_v + std::f64::consts::FRAC_PI_2;
        (theta, phi)
    }
}

impl TryFrom<EquirectangularParams> for Equirectangular {
    type Error = CalibrationError;
    fn try_from(params: EquirectangularParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<Equirectangular> for EquirectangularParams {
    fn from(model: Equirectangular) -> Self {
        model.params
    }
}

impl CameraModel for Equirectangular {
    fn image_size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        self.contains(pixel)
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        if !self.contains(pixel) {
            return None;
        }
        let (theta, phi) = self.angles(pixel);
        let (st, ct) = table_sin_cos(&self.column_sin_cos, pixel.x, self.theta_per_u, theta);
        let (sp, cp) = table_sin_cos(&self.row_sin_cos, pixel.y, self.phi_per_v, phi);
        Some(Vector3::new(cp * st, -sp, cp * ct))
    }

    #[inline]
    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        let (x, y, z) = (bearing.x, bearing.y, bearing.z);
        let rho = x.hypot(z);
        if !(rho > 0.0 || y != 0.0) || !rho.is_finite() || !y.is_finite() {
            return None;
        }
        let theta = x.atan2(z);
        let phi = (-y).atan2(rho);
        let pixel = Vector2::new(
            (theta + PI) / self.theta_per_u - 0.5,
            (phi - std::f64::consts::FRAC_PI_2) / self.phi_per_v - 0.5,
        );
        // Rounding can step a hair outside at the seam or the poles: clamp to the rectangle.
        let w = f64::from(self.params.width) - 0.5;
        let h = f64::from(self.params.height) - 0.5;
        Some(Vector2::new(pixel.x.clamp(-0.5, w), pixel.y.clamp(-0.5, h)))
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        if !in_image_rectangle(self.params.width, self.params.height, pixel) {
            return None;
        }
        let (theta, phi) = self.angles(pixel);
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        let bearing = Vector3::new(cp * st, -sp, cp * ct);
        let db_dtheta = Vector3::new(cp * ct, 0.0, -cp * st) * self.theta_per_u;
        let db_dphi = Vector3::new(-sp * st, -cp, -sp * ct) * self.phi_per_v;
        Some((bearing, Matrix3x2::from_columns(&[db_dtheta, db_dphi])))
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        let pixel = self.try_pixel(bearing)?;
        let (x, y, z) = (bearing.x, bearing.y, bearing.z);
        let rho2 = x * x + z * z;
        let rho = rho2.sqrt();
        let n2 = rho2 + y * y;
        if !(rho > 0.0) {
            return None;
        }
        // dθ = (z dx − x dz) / ρ²;  dφ = (−ρ dy + y dρ) / N², dρ = (x dx + z dz) / ρ.
        let dtheta = [z / rho2, 0.0, -x / rho2];
        let dphi = [y * x / (rho * n2), -rho / n2, y * z / (rho * n2)];
        let su = 1.0 / self.theta_per_u;
        let sv = 1.0 / self.phi_per_v;
        let jac = Matrix2x3::new(
            dtheta[0] * su,
            dtheta[1] * su,
            dtheta[2] * su,
            dphi[0] * sv,
            dphi[1] * sv,
            dphi[2] * sv,
        );
        jac.iter().all(|v| v.is_finite()).then_some((pixel, jac))
    }
}
