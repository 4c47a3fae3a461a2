//! The Kannala-Brandt fisheye camera (OpenCV `cv::fisheye`).

use super::{
    CalibrationError, CameraModel, Pixel, bearing_jacobian_from_pixel_jacobian, check_finite,
    check_positive, check_size, clamp_to_image, first_non_positive, in_image_rectangle,
};
use nalgebra::{Matrix2x3, Matrix3x2, RowVector3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Newton's method on `θ_d(θ) = ρ` stops when its step is below this (radians).
pub const FISHEYE_TOLERANCE: f64 = 1e-12;

/// Most iterations of the safeguarded Newton inversion of `θ_d(θ)`.
pub const MAX_FISHEYE_ITERATIONS: usize = 60;

/// Below this angle from the optical axis (radians), `θ_d(θ) / sin θ` and its derivative
/// are evaluated by their Taylor series (the closed forms cancel catastrophically there).
pub const FISHEYE_SMALL_ANGLE: f64 = 1e-4;

/// The parameters of a [`KannalaBrandt`] camera (serde: the native JSON form), OpenCV
/// `cv::fisheye` conventions (`K = [fx 0 cx; 0 fy cy]`, `D = [k1, k2, k3, k4]`, no skew).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KannalaBrandtParams {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along u, pixels per radian of `θ_d`.
    pub fx: f64,
    /// Focal length along v, pixels per radian of `θ_d`.
    pub fy: f64,
    /// Principal point column (integer = pixel centre, as OpenCV).
    pub cx: f64,
    /// Principal point row.
    pub cy: f64,
    /// Coefficient of `θ³`.
    #[serde(default)]
    pub k1: f64,
    /// Coefficient of `θ⁵`.
    #[serde(default)]
    pub k2: f64,
    /// Coefficient of `θ⁷`.
    #[serde(default)]
    pub k3: f64,
    /// Coefficient of `θ⁹`.
    #[serde(default)]
    pub k4: f64,
}

/// A validated Kannala-Brandt (equidistant-polynomial) fisheye camera.
///
/// # Model
/// A direction `(X, Y, Z)` at angle `θ = atan2(√(X² + Y²), Z)` from the optical axis maps to
/// ```text
/// θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)
/// (x_d, y_d) = θ_d · (X, Y) / √(X² + Y²)
/// u = fx x_d + cx,   v = fy y_d + cy
/// ```
/// which is OpenCV's `cv::fisheye` model for `Z > 0`, extended to `θ ≥ 90°` (fields of
/// view beyond 180°). Pixel → bearing solves `θ_d(θ) = ρ = |(x_d, y_d)|` by a safeguarded
/// Newton iteration to [`FISHEYE_TOLERANCE`] and returns `(sin θ x_d/ρ, sin θ y_d/ρ, cos θ)`.
///
/// # Validity domain
/// `θ < θ_max`, the first angle where `θ_d'(θ) = 1 + 3k1θ² + 5k2θ⁴ + 7k3θ⁶ + 9k4θ⁸` is no
/// longer positive, or π; pixels inside the image with `ρ < θ_d(θ_max)`.
///
/// # References
/// J. Kannala, S. S. Brandt, "A generic camera model and calibration method for conventional,
/// wide-angle, and fish-eye lenses", IEEE TPAMI 28(8), 2006.
///
/// # Example
/// ```
/// use nalgebra::{Vector2, Vector3};
/// use vgps_camera::calibration::{CameraModel, KannalaBrandt, KannalaBrandtParams};
/// let camera = KannalaBrandt::new(KannalaBrandtParams {
///     width: 1280, height: 960, fx: 350.0, fy: 350.0, cx: 639.5, cy: 479.5,
///     k1: 0.0, k2: 0.0, k3: 0.0, k4: 0.0,
/// })?;
/// // Equidistant: 90° off axis lands f·π/2 ≈ 549.8 px right of the centre.
/// let pixel = camera.try_pixel(&Vector3::new(1.0, 0.0, 0.0)).unwrap();
/// assert!((pixel.x - (639.5 + 350.0 * std::f64::consts::FRAC_PI_2)).abs() < 1e-9);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "KannalaBrandtParams", into = "KannalaBrandtParams")]
pub struct KannalaBrandt {
    params: KannalaBrandtParams,
    inv_fx: f64,
    inv_fy: f64,
    theta_max: f64,
    rho_max: f64,
}

const MODEL: &str = "kannala_brandt";

impl KannalaBrandt {
    /// Validates the parameters (non-zero size, finite positive focal lengths, finite rest)
    /// and computes the validity domain.
    pub fn new(params: KannalaBrandtParams) -> Result<Self, CalibrationError> {
        let p = params;
        check_size(MODEL, p.width, p.height)?;
        check_positive(MODEL, "fx", p.fx)?;
        check_positive(MODEL, "fy", p.fy)?;
        for (name, value) in [
            ("cx", p.cx),
            ("cy", p.cy),
            ("k1", p.k1),
            ("k2", p.k2),
            ("k3", p.k3),
            ("k4", p.k4),
        ] {
            check_finite(MODEL, name, value)?;
        }
        let mut model = Self {
            params,
            inv_fx: 1.0 / p.fx,
            inv_fy: 1.0 / p.fy,
            theta_max: std::f64::consts::PI,
            rho_max: 0.0,
        };
        if let Some(t) = first_non_positive(|t| model.theta_d_slope(t), std::f64::consts::PI) {
            model.theta_max = t;
        }
        model.rho_max = model.theta_d(model.theta_max);
        if !(model.rho_max > 0.0) || !model.rho_max.is_finite() {
            return Err(CalibrationError::InvalidParameters {
                model: MODEL,
                reason: "the distortion polynomial has no valid domain".into(),
            });
        }
        Ok(model)
    }

    /// The parameters.
    pub fn params(&self) -> &KannalaBrandtParams {
        &self.params
    }

    /// The largest valid angle from the optical axis `θ_max` (radians, ≤ π).
    pub fn max_angle(&self) -> f64 {
        self.theta_max
    }

    /// `θ_d(θ) = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`.
    #[inline]
    pub fn theta_d(&self, theta: f64) -> f64 {
        let p = &self.params;
        let t2 = theta * theta;
        theta * (1.0 + t2 * (p.k1 + t2 * (p.k2 + t2 * (p.k3 + t2 * p.k4))))
    }

    /// `dθ_d / dθ`.
    #[inline]
    fn theta_d_slope(&self, theta: f64) -> f64 {
        let p = &self.params;
        let t2 = theta * theta;
        1.0 + t2 * (3.0 * p.k1 + t2 * (5.0 * p.k2 + t2 * (7.0 * p.k3 + t2 * 9.0 * p.k4)))
    }

    /// `h(θ) = θ_d(θ) / sin θ` and `h'(θ) / (N sin θ)` times `N` (i.e. `h'(θ) / sin θ`).
    #[inline]
    fn h_and_slope_over_sin(&self, theta: f64) -> (f64, f64) {
        if theta < FISHEYE_SMALL_ANGLE {
            let c = self.params.k1 + 1.0 / 6.0;
            (1.0 + c * theta * theta, 2.0 * c)
        } else {
            let (s, c) = theta.sin_cos();
            let td = self.theta_d(theta);
            let h = td / s;
            let dh = (self.theta_d_slope(theta) * s - td * c) / (s * s);
            (h, dh / s)
        }
    }

    /// `θ` with `θ_d(θ) = rho` in `[0, θ_max)`, by Newton safeguarded with bisection.
    #[inline]
    fn solve_theta(&self, rho: f64) -> Option<f64> {
        let (mut lo, mut hi) = (0.0, self.theta_max);
        let mut theta = rho.min(hi);
        for _ in 0..MAX_FISHEYE_ITERATIONS {
            let f = self.theta_d(theta) - rho;
            if f == 0.0 {
                return (theta < self.theta_max).then_some(theta);
            }
            if f > 0.0 {
                hi = theta;
            } else {
                lo = theta;
            }
            let slope = self.theta_d_slope(theta);
            let mut next = theta - f / slope;
            if !(next >= lo && next <= hi) {
                next = 0.5 * (lo + hi);
            }
            if (next - theta).abs() <= FISHEYE_TOLERANCE {
                return (next < self.theta_max).then_some(next);
            }
            theta = next;
        }
        None
    }
}

impl TryFrom<KannalaBrandtParams> for KannalaBrandt {
    type Error = CalibrationError;
    fn try_from(params: KannalaBrandtParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<KannalaBrandt> for KannalaBrandtParams {
    fn from(model: KannalaBrandt) -> Self {
        model.params
    }
}

impl CameraModel for KannalaBrandt {
    fn image_size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        self.try_bearing(pixel).is_some()
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        let p = &self.params;
        if !in_image_rectangle(p.width, p.height, pixel) {
            return None;
        }
        let xd = (pixel.x - p.cx) * self.inv_fx;
        let yd = (pixel.y - p.cy) * self.inv_fy;
        let rho = (xd * xd + yd * yd).sqrt();
        if !(rho < self.rho_max) {
            return None;
        }
        let theta = self.solve_theta(rho)?;
        let (h, _) = self.h_and_slope_over_sin(theta);
        Some(Vector3::new(xd / h, yd / h, theta.cos()))
    }

    #[inline]
    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        self.try_pixel_with_jacobian(bearing).map(|(p, _)| p)
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        let bearing = self.try_bearing(pixel)?;
        let (_, jp) = self.try_pixel_with_jacobian(&bearing)?;
        Some((bearing, bearing_jacobian_from_pixel_jacobian(&jp)?))
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        let (x, y, z) = (bearing.x, bearing.y, bearing.z);
        let n2 = x * x + y * y + z * z;
        let n = n2.sqrt();
        if !(n > 0.0) || !n.is_finite() {
            return None;
        }
        let r3 = (x * x + y * y).sqrt();
        let theta = r3.atan2(z);
        if !(theta < self.theta_max) {
            return None;
        }
        let (h, q) = self.h_and_slope_over_sin(theta);
        let p = &self.params;
        let (xd, yd) = (h * x / n, h * y / n);
        let pixel = clamp_to_image(
            p.width,
            p.height,
            &Vector2::new(p.fx * xd + p.cx, p.fy * yd + p.cy),
        )?;
        // h'(θ) ∂θ/∂B = (h'/sinθ)/N · (Z X, Z Y, -r3²) / N².
        let dtheta_term = RowVector3::new(z * x, z * y, -r3 * r3) * (q / (n * n2));
        let inv_n = 1.0 / n;
        let b = RowVector3::new(x, y, z);
        let row_x = (RowVector3::new(1.0, 0.0, 0.0) - b * (x / n2)) * (h * inv_n)
            + dtheta_term * (x * inv_n);
        let row_y = (RowVector3::new(0.0, 1.0, 0.0) - b * (y / n2)) * (h * inv_n)
            + dtheta_term * (y * inv_n);
        let jac = Matrix2x3::from_rows(&[row_x * p.fx, row_y * p.fy]);
        jac.iter().all(|v| v.is_finite()).then_some((pixel, jac))
    }
}
