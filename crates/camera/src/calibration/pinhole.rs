//! The pinhole camera with optional OpenCV radial-tangential distortion.

use super::{
    CalibrationError, CameraModel, Pixel, bearing_jacobian_from_pixel_jacobian, check_finite,
    check_positive, check_size, clamp_to_image, first_non_positive, in_image_rectangle,
};
use nalgebra::{Matrix2, Matrix2x3, Matrix3x2, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Newton's method for undistortion stops when its step is below this (normalised image
/// coordinates, i.e. `1e-12 · f` pixels).
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;

/// Most Newton iterations of the undistortion; not converging within them means no bearing.
pub const MAX_UNDISTORT_ITERATIONS: usize = 30;

/// A converged undistortion must reproduce the distorted coordinates to this (normalised).
pub const UNDISTORT_RESIDUAL: f64 = 1e-9;

/// OpenCV radial-tangential distortion coefficients (`distCoeffs = [k1, k2, p1, p2, k3]`).
///
/// With `(x, y)` the undistorted normalised coordinates (`X/Z, Y/Z`) and `r² = x² + y²`:
/// ```text
/// x_d = x (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 x²)
/// y_d = y (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 y²) + 2 p2 x y
/// ```
/// Every field defaults to zero (no distortion).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadialTangential {
    /// Radial coefficient of `r²`.
    pub k1: f64,
    /// Radial coefficient of `r⁴`.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial coefficient of `r⁶`.
    pub k3: f64,
}

impl RadialTangential {
    /// True when every coefficient is exactly zero.
    pub fn is_zero(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0 && self.p1 == 0.0 && self.p2 == 0.0 && self.k3 == 0.0
    }

    /// Distorted normalised coordinates of `(x, y)` and the 2×2 Jacobian `d(x_d, y_d)/d(x, y)`.
    #[inline]
    pub fn distort_with_jacobian(&self, x: f64, y: f64) -> (Vector2<f64>, Matrix2<f64>) {
        let (k1, k2, p1, p2, k3) = (self.k1, self.k2, self.p1, self.p2, self.k3);
        let x2 = x * x;
        let y2 = y * y;
        let xy = x * y;
        let r2 = x2 + y2;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // d radial / d(r²)
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2);
        let yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy;
        let cross = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let j = Matrix2::new(
            radial + 2.0 * x2 * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
            cross,
            cross,
            radial + 2.0 * y2 * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
        );
        (Vector2::new(xd, yd), j)
    }

    /// `d (r · radial(r)) / dr` as a function of `r² = s`: positive where the radial part is
    /// monotonic.
    fn radial_slope(&self, s: f64) -> f64 {
        1.0 + s * (3.0 * self.k1 + s * (5.0 * self.k2 + s * 7.0 * self.k3))
    }
}

/// The parameters of a [`Pinhole`] (serde: the native JSON form).
///
/// `u = fx · x_d + cx`, `v = fy · y_d + cy` with `(x_d, y_d)` the distorted normalised
/// coordinates ([`RadialTangential`]); `(cx, cy)` in the crate's pixel convention (integer =
/// pixel centre), the same numbers as OpenCV's camera matrix.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinholeParams {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along u, pixels.
    pub fx: f64,
    /// Focal length along v, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// Distortion (zero when absent in JSON).
    #[serde(default)]
    pub distortion: RadialTangential,
}

impl PinholeParams {
    /// Parameters without distortion.
    pub fn ideal(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion: RadialTangential::default(),
        }
    }

    /// The same parameters with a distortion.
    pub fn with_distortion(self, distortion: RadialTangential) -> Self {
        Self { distortion, ..self }
    }
}

/// A validated pinhole camera with optional radial-tangential distortion.
///
/// # Model
/// A direction `(X, Y, Z)` with `Z > 0` has normalised coordinates `(x, y) = (X/Z, Y/Z)`,
/// distorted by [`RadialTangential`] and mapped to pixels by `u = fx x_d + cx`,
/// `v = fy y_d + cy`. Pixel → bearing inverts the distortion by Newton's method with the
/// analytic 2×2 Jacobian from `(x_d, y_d)`, to a step below [`UNDISTORT_TOLERANCE`].
///
/// # Validity domain
/// Directions with `Z > 0` whose undistorted radius `r` is below `r_max`, the first radius
/// where the radial map `r (1 + k1 r² + k2 r⁴ + k3 r⁶)` stops increasing (∞ when it never
/// does), and where the distortion Jacobian has a positive determinant; and pixels inside the
/// image whose undistortion converges inside that domain.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use vgps_camera::calibration::{CameraModel, Pinhole, PinholeParams, RadialTangential};
/// let params = PinholeParams::ideal(1024, 768, 596.8, 596.8, 511.5, 383.5)
///     .with_distortion(RadialTangential { k1: -0.3, k2: 0.1, ..Default::default() });
/// let camera = Pinhole::new(params)?;
/// let pixel = Vector2::new(0.0, 0.0);
/// let bearing = camera.try_bearing(&pixel).unwrap();
/// assert!((camera.try_pixel(&bearing).unwrap() - pixel).norm() < 1e-9);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "PinholeParams", into = "PinholeParams")]
pub struct Pinhole {
    params: PinholeParams,
    inv_fx: f64,
    inv_fy: f64,
    distorted: bool,
    /// Square of the largest valid undistorted radius (∞ when unbounded).
    r2_max: f64,
}

const MODEL: &str = "pinhole";

impl Pinhole {
    /// Validates the parameters: non-zero size, finite positive focal lengths, finite
    /// principal point and coefficients.
    pub fn new(params: PinholeParams) -> Result<Self, CalibrationError> {
        check_size(MODEL, params.width, params.height)?;
        check_positive(MODEL, "fx", params.fx)?;
        check_positive(MODEL, "fy", params.fy)?;
        check_finite(MODEL, "cx", params.cx)?;
        check_finite(MODEL, "cy", params.cy)?;
        let d = params.distortion;
        for (name, value) in [
            ("k1", d.k1),
            ("k2", d.k2),
            ("p1", d.p1),
            ("p2", d.p2),
            ("k3", d.k3),
        ] {
            check_finite(MODEL, name, value)?;
        }
        // Scan the angle from the optical axis, r = tan(angle), over (0, π/2).
        let r2_max = first_non_positive(
            |angle| {
                let r = angle.tan();
                d.radial_slope(r * r)
            },
            std::f64::consts::FRAC_PI_2 * (1.0 - 1e-9),
        )
        .map_or(f64::INFINITY, |angle| angle.tan().powi(2));
        Ok(Self {
            params,
            inv_fx: 1.0 / params.fx,
            inv_fy: 1.0 / params.fy,
            distorted: !d.is_zero(),
            r2_max,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &PinholeParams {
        &self.params
    }

    /// The largest valid undistorted normalised radius `r_max` (∞ when unbounded).
    pub fn max_radius(&self) -> f64 {
        self.r2_max.sqrt()
    }

    /// Undistorted normalised coordinates of a pixel inside the image, by Newton's method.
    #[inline]
    fn undistort(&self, pixel: &Pixel) -> Option<Vector2<f64>> {
        let xd = Vector2::new(
            (pixel.x - self.params.cx) * self.inv_fx,
            (pixel.y - self.params.cy) * self.inv_fy,
        );
        if !self.distorted {
            return Some(xd);
        }
        let dist = &self.params.distortion;
        // First guess: undo the radial factor evaluated at the distorted radius (saves about
        // one Newton iteration over starting at x_d for strong barrel distortion).
        let rd2 = xd.norm_squared();
        let radial = 1.0 + rd2 * (dist.k1 + rd2 * (dist.k2 + rd2 * dist.k3));
        let mut x = if radial > 0.0 && radial.is_finite() {
            xd / radial
        } else {
            xd
        };
        for _ in 0..MAX_UNDISTORT_ITERATIONS {
            let (d, j) = dist.distort_with_jacobian(x.x, x.y);
            let r = d - xd;
            let det = j.m11 * j.m22 - j.m12 * j.m21;
            if !(det > 0.0) || !det.is_finite() {
                return None;
            }
            // Solve J δ = r (2×2, Cramer).
            let step = Vector2::new(
                (j.m22 * r.x - j.m12 * r.y) / det,
                (j.m11 * r.y - j.m21 * r.x) / det,
            );
            x -= step;
            if step.x.abs() <= UNDISTORT_TOLERANCE && step.y.abs() <= UNDISTORT_TOLERANCE {
                // Converged: the residual before this last step is |J δ| ≤ ~1e-12 already,
                // and the Jacobian there had a positive determinant.
                if !(x.norm_squared() < self.r2_max) || r.norm() > UNDISTORT_RESIDUAL {
                    return None;
                }
                return Some(x);
            }
        }
        None
    }

    /// Pixel of normalised undistorted `(x, y)` and the Jacobian `d pixel / d (x, y)`.
    #[inline]
    fn project_normalised(&self, x: f64, y: f64) -> Option<(Pixel, Matrix2<f64>)> {
        let p = &self.params;
        if !(x * x + y * y < self.r2_max) {
            return None;
        }
        let (d, j) = if self.distorted {
            let (d, j) = p.distortion.distort_with_jacobian(x, y);
            if !(j.determinant() > 0.0) {
                return None;
            }
            (d, j)
        } else {
            (Vector2::new(x, y), Matrix2::identity())
        };
        let pixel = clamp_to_image(
            p.width,
            p.height,
            &Vector2::new(p.fx * d.x + p.cx, p.fy * d.y + p.cy),
        )?;
        let scale = Matrix2::new(p.fx, 0.0, 0.0, p.fy);
        Some((pixel, scale * j))
    }
}

impl TryFrom<PinholeParams> for Pinhole {
    type Error = CalibrationError;
    fn try_from(params: PinholeParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<Pinhole> for PinholeParams {
    fn from(model: Pinhole) -> Self {
        model.params
    }
}

impl CameraModel for Pinhole {
    fn image_size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        in_image_rectangle(self.params.width, self.params.height, pixel)
            && self.undistort(pixel).is_some()
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        if !in_image_rectangle(self.params.width, self.params.height, pixel) {
            return None;
        }
        let x = self.undistort(pixel)?;
        let inv_norm = 1.0 / (x.x * x.x + x.y * x.y + 1.0).sqrt();
        Some(Vector3::new(x.x * inv_norm, x.y * inv_norm, inv_norm))
    }

    #[inline]
    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        if !(bearing.z > 0.0) || !bearing.x.is_finite() || !bearing.y.is_finite() {
            return None;
        }
        let inv_z = 1.0 / bearing.z;
        let (x, y) = (bearing.x * inv_z, bearing.y * inv_z);
        if !(x * x + y * y < self.r2_max) {
            return None;
        }
        let p = &self.params;
        let d = if self.distorted {
            let (d, j) = p.distortion.distort_with_jacobian(x, y);
            if !(j.determinant() > 0.0) {
                return None;
            }
            d
        } else {
            Vector2::new(x, y)
        };
        clamp_to_image(
            p.width,
            p.height,
            &Vector2::new(p.fx * d.x + p.cx, p.fy * d.y + p.cy),
        )
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        let bearing = self.try_bearing(pixel)?;
        let (_, jp) = self.try_pixel_with_jacobian_unbounded(&bearing)?;
        Some((bearing, bearing_jacobian_from_pixel_jacobian(&jp)?))
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        self.try_pixel_with_jacobian_unbounded(bearing)
    }
}

impl Pinhole {
    /// Projection with Jacobian (image-rectangle check included).
    fn try_pixel_with_jacobian_unbounded(
        &self,
        bearing: &Vector3<f64>,
    ) -> Option<(Pixel, Matrix2x3<f64>)> {
        let (bx, by, bz) = (bearing.x, bearing.y, bearing.z);
        if !(bz > 0.0) || !bx.is_finite() || !by.is_finite() {
            return None;
        }
        let inv_z = 1.0 / bz;
        let (x, y) = (bx * inv_z, by * inv_z);
        let (pixel, j) = self.project_normalised(x, y)?;
        // d(x, y) / d(X, Y, Z)
        let dn = Matrix2x3::new(inv_z, 0.0, -x * inv_z, 0.0, inv_z, -y * inv_z);
        let jac = j * dn;
        jac.iter().all(|v| v.is_finite()).then_some((pixel, jac))
    }
}
