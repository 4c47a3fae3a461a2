//! A pinhole camera on an undistorted image with its lens distortion given as dense pixel
//! tables (the NCLT / Ladybug3 `D2U` / `U2D` tables), or with no distortion and an optional
//! image size (a Ladybug SDK rectified camera).

use super::{
    CalibrationError, CameraModel, Pixel, check_finite, check_positive, in_image_rectangle,
};
use nalgebra::{Matrix2, Matrix2x3, Matrix3x2, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Newton's inversion of the raw → undistorted table stops when its step is below this
/// (pixels).
pub const TABLE_INVERSE_TOLERANCE: f64 = 1e-11;

/// Most Newton iterations of the table inversion.
pub const MAX_TABLE_INVERSE_ITERATIONS: usize = 60;

/// The converged raw pixel must map to the asked undistorted position within this (pixels).
pub const TABLE_INVERSE_RESIDUAL: f64 = 1e-8;

/// Largest Newton step of the table inversion (pixels): keeps the iteration local.
pub const TABLE_MAX_NEWTON_STEP: f64 = 4.0;

/// Smallest `z` of a direction accepted by the projection (the pinhole sees `z > 0`).
pub const MIN_FORWARD_Z: f64 = 1e-12;

/// A dense `width × height` table: node `(c, r)` (column, row; integer = pixel centre) of
/// one image holds the sub-pixel position `(u', v')` = (column, row) of the same point in
/// the other image. Interpolated bilinearly between nodes and extrapolated linearly from
/// the border cells over the half-pixel rim `[−½, 0)` and `(W − 1, W − ½]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionTable {
    /// Number of node columns (the image width, ≥ 2).
    pub width: u32,
    /// Number of node rows (the image height, ≥ 2).
    pub height: u32,
    /// `(u', v')` per node, row-major: node `(c, r)` at index `r · width + c`.
    pub positions: Vec<[f64; 2]>,
}

impl DistortionTable {
    /// Checks the size (≥ 2 × 2), the number of entries and that every entry is finite; the
    /// reason when invalid.
    pub fn validate(&self) -> Result<(), String> {
        if self.width < 2 || self.height < 2 {
            return Err(format!(
                "table size {}×{} is smaller than 2×2",
                self.width, self.height
            ));
        }
        let expected = self.width as usize * self.height as usize;
        if self.positions.len() != expected {
            return Err(format!(
                "{} entries, but a {}×{} table needs {expected}",
                self.positions.len(),
                self.width,
                self.height
            ));
        }
        for (k, p) in self.positions.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) {
                let (c, r) = (k % self.width as usize, k / self.width as usize);
                return Err(format!(
                    "entry of pixel (u {c}, v {r}) is not finite: {p:?}"
                ));
            }
        }
        Ok(())
    }

    #[inline]
    fn node(&self, c: usize, r: usize) -> Vector2<f64> {
        let p = self.positions[r * self.width as usize + c];
        Vector2::new(p[0], p[1])
    }

    /// The interpolated position at `pixel` and its 2×2 Jacobian (columns d/du, d/dv).
    /// Outside the node range the border cells are extrapolated linearly. The table must
    /// be valid ([`validate`](Self::validate)).
    #[inline]
    pub fn interpolate(&self, pixel: &Pixel) -> (Vector2<f64>, Matrix2<f64>) {
        let cell = |x: f64, n: u32| {
            // `as usize` saturates (negative and NaN → 0).
            let i = (x.floor().max(0.0) as usize).min(n as usize - 2);
            (i, x - i as f64)
        };
        let (i, t) = cell(pixel.x, self.width);
        let (j, s) = cell(pixel.y, self.height);
        let p00 = self.node(i, j);
        let p10 = self.node(i + 1, j);
        let p01 = self.node(i, j + 1);
        let p11 = self.node(i + 1, j + 1);
        let top = p00 + (p10 - p00) * t;
        let bottom = p01 + (p11 - p01) * t;
        let value = top + (bottom - top) * s;
        let du = (p10 - p00) * (1.0 - s) + (p11 - p01) * s;
        let dv = bottom - top;
        (value, Matrix2::from_columns(&[du, dv]))
    }

    /// The smallest determinant of the table's Jacobian over the corners of every cell (a
    /// bilinear cell's determinant is extreme at its corners along each edge; this is the
    /// figure of the monotonicity check: it must be > 0 for an invertible table).
    /// NaN for an invalid table.
    pub fn min_jacobian_determinant(&self) -> f64 {
        if self.validate().is_err() {
            return f64::NAN;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let mut min = f64::INFINITY;
        for j in 0..h - 1 {
            for i in 0..w - 1 {
                let p00 = self.node(i, j);
                let p10 = self.node(i + 1, j);
                let p01 = self.node(i, j + 1);
                let p11 = self.node(i + 1, j + 1);
                // Jacobian at each corner of the cell.
                for (du, dv) in [
                    (p10 - p00, p01 - p00),
                    (p10 - p00, p11 - p10),
                    (p11 - p01, p01 - p00),
                    (p11 - p01, p11 - p10),
                ] {
                    min = min.min(du.x * dv.y - du.y * dv.x);
                }
            }
        }
        min
    }
}

/// The parameters of a [`TabulatedPinhole`] (serde form, tables inline).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TabulatedPinholeParams {
    /// Raw image width in pixels; `None` (with `height`) for an unbounded image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Raw image height in pixels; `None` (with `width`) for an unbounded image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// Focal length along u of the undistorted image (pixels).
    pub fx: f64,
    /// Focal length along v of the undistorted image (pixels).
    pub fy: f64,
    /// Skew `K[0][1]` of the undistorted image (pixels; usually 0).
    #[serde(default)]
    pub skew: f64,
    /// Principal point column of the undistorted image (integer = pixel centre).
    pub cx: f64,
    /// Principal point row of the undistorted image.
    pub cy: f64,
    /// Raw → undistorted table (NCLT `D2U`): node = raw pixel, value = undistorted
    /// position. `None` (with `undistorted_to_raw`) when the image has no distortion.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw_to_undistorted: Option<DistortionTable>,
    /// Undistorted → raw table (NCLT `U2D`): node = undistorted pixel, value = raw
    /// position. Only seeds the inversion of `raw_to_undistorted`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub undistorted_to_raw: Option<DistortionTable>,
}

/// A pinhole camera `K = [fx skew cx; 0 fy cy; 0 0 1]` on an undistorted image, with the
/// lens distortion given by two dense tables between the raw and the undistorted image
/// (the NCLT Ladybug3 `D2U` / `U2D` layout), or with no distortion.
///
/// # Model
/// Pixel → bearing (raw pixel `p`): `q = D2U(p)` (bilinear), `r = K⁻¹ (q, 1)`, bearing
/// `r / |r|` in the camera frame (x right, y down, z forward). Bearing → pixel: `q = K b/b_z`
/// (`b_z > 0`), a first guess `p₀ = U2D(q)`, then Newton's method on `D2U(p) = q` with the
/// bilinear Jacobian to a step below [`TABLE_INVERSE_TOLERANCE`]; accepted when the
/// residual is below [`TABLE_INVERSE_RESIDUAL`] and `p` is inside the image. So the
/// pixel → bearing → pixel round trip is exact to ~1e-10 px whatever the consistency of the
/// two tables (reported by `vgps calib check`).
///
/// Without tables the raw image is the undistorted image. Without an image size
/// ([`image_size`](CameraModel::image_size) is then `(0, 0)`) every pixel is valid (a
/// Ladybug SDK rectified camera whose export names no image size).
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use vgps_camera::calibration::{CameraModel, TabulatedPinhole, TabulatedPinholeParams};
/// let camera = TabulatedPinhole::new(TabulatedPinholeParams {
///     width: None, height: None, fx: 400.0, fy: 400.0, skew: 0.0, cx: 320.0, cy: 240.0,
///     raw_to_undistorted: None, undistorted_to_raw: None,
/// })?;
/// // Unbounded: a pixel left of the image still has a bearing (45° to the left).
/// let b = camera.try_bearing(&Vector2::new(-80.0, 240.0)).unwrap();
/// assert!((b.x + std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "TabulatedPinholeParams", into = "TabulatedPinholeParams")]
pub struct TabulatedPinhole {
    params: TabulatedPinholeParams,
}

const MODEL: &str = "tabulated_pinhole";

fn invalid(reason: String) -> CalibrationError {
    CalibrationError::InvalidParameters {
        model: MODEL,
        reason,
    }
}

impl TabulatedPinhole {
    /// Validates: finite positive focal lengths, finite skew and principal point, width and
    /// height both given (non-zero) or both absent, both tables or none, tables of the
    /// image's size, finite and monotonic (positive Jacobian determinant in every cell).
    pub fn new(params: TabulatedPinholeParams) -> Result<Self, CalibrationError> {
        let p = &params;
        check_positive(MODEL, "fx", p.fx)?;
        check_positive(MODEL, "fy", p.fy)?;
        for (name, value) in [("skew", p.skew), ("cx", p.cx), ("cy", p.cy)] {
            check_finite(MODEL, name, value)?;
        }
        let size = match (p.width, p.height) {
            (Some(w), Some(h)) if w > 0 && h > 0 => {
                super::check_size(MODEL, w, h)?;
                Some((w, h))
            }
            (None, None) => None,
            (w, h) => {
                return Err(invalid(format!(
                    "image size {w:?}×{h:?}: give both width and height (non-zero) or neither"
                )));
            }
        };
        match (&p.raw_to_undistorted, &p.undistorted_to_raw) {
            (None, None) => {}
            (Some(d2u), Some(u2d)) => {
                let Some((w, h)) = size else {
                    return Err(invalid("distortion tables need an image size".into()));
                };
                for (name, table) in [("raw_to_undistorted", d2u), ("undistorted_to_raw", u2d)] {
                    table
                        .validate()
                        .map_err(|e| invalid(format!("{name}: {e}")))?;
                    if (table.width, table.height) != (w, h) {
                        return Err(invalid(format!(
                            "{name}: table size {}×{} contradicts the image size {w}×{h}",
                            table.width, table.height
                        )));
                    }
                    let det = table.min_jacobian_determinant();
                    if !(det > 0.0) {
                        return Err(invalid(format!(
                            "{name}: the table is not monotonic (smallest cell Jacobian \
                             determinant {det:e} ≤ 0)"
                        )));
                    }
                }
            }
            _ => {
                return Err(invalid(
                    "give both tables (raw_to_undistorted and undistorted_to_raw) or neither"
                        .into(),
                ));
            }
        }
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &TabulatedPinholeParams {
        &self.params
    }

    /// True when the image has a size (pixels are bounds-checked).
    pub fn is_bounded(&self) -> bool {
        self.params.width.is_some()
    }

    /// Raw pixel → undistorted position and its Jacobian (identity without tables).
    #[inline]
    fn undistort(&self, pixel: &Pixel) -> (Vector2<f64>, Matrix2<f64>) {
        match &self.params.raw_to_undistorted {
            Some(t) => t.interpolate(pixel),
            None => (*pixel, Matrix2::identity()),
        }
    }

    /// Undistorted position → raw pixel (Newton on the raw → undistorted table).
    fn distort(&self, q: &Vector2<f64>) -> Option<Pixel> {
        let (Some(d2u), Some(u2d)) = (
            &self.params.raw_to_undistorted,
            &self.params.undistorted_to_raw,
        ) else {
            return Some(*q);
        };
        newton_inverse(
            |p| d2u.interpolate(p),
            u2d.interpolate(q).0,
            q,
            &NewtonLimits {
                max_iterations: MAX_TABLE_INVERSE_ITERATIONS,
                max_step: TABLE_MAX_NEWTON_STEP,
                tolerance: TABLE_INVERSE_TOLERANCE,
                residual: TABLE_INVERSE_RESIDUAL,
            },
        )
    }

    #[inline]
    fn inside(&self, pixel: &Pixel) -> bool {
        match (self.params.width, self.params.height) {
            (Some(w), Some(h)) => in_image_rectangle(w, h, pixel),
            _ => pixel.x.is_finite() && pixel.y.is_finite(),
        }
    }

    /// `K⁻¹ (q, 1)` and its derivative with respect to `q` (3×2).
    #[inline]
    fn ray(&self, q: &Vector2<f64>) -> (Vector3<f64>, Matrix3x2<f64>) {
        let p = &self.params;
        let y = (q.y - p.cy) / p.fy;
        let x = (q.x - p.cx - p.skew * y) / p.fx;
        let jac = Matrix3x2::new(
            1.0 / p.fx,
            -p.skew / (p.fx * p.fy),
            0.0,
            1.0 / p.fy,
            0.0,
            0.0,
        );
        (Vector3::new(x, y, 1.0), jac)
    }
}

impl TryFrom<TabulatedPinholeParams> for TabulatedPinhole {
    type Error = CalibrationError;
    fn try_from(params: TabulatedPinholeParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<TabulatedPinhole> for TabulatedPinholeParams {
    fn from(model: TabulatedPinhole) -> Self {
        model.params
    }
}

impl CameraModel for TabulatedPinhole {
    /// `(width, height)`, or `(0, 0)` for an unbounded image.
    fn image_size(&self) -> (u32, u32) {
        (
            self.params.width.unwrap_or(0),
            self.params.height.unwrap_or(0),
        )
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        self.inside(pixel)
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        if !self.inside(pixel) {
            return None;
        }
        let (q, _) = self.undistort(pixel);
        vgps_geometry::geometry::try_unit(&self.ray(&q).0)
    }

    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        if !(bearing.z > MIN_FORWARD_Z * bearing.norm())
            || !vgps_geometry::geometry::is_finite(bearing)
        {
            return None;
        }
        let p = &self.params;
        let (x, y) = (bearing.x / bearing.z, bearing.y / bearing.z);
        let q = Vector2::new(p.fx * x + p.skew * y + p.cx, p.fy * y + p.cy);
        let pixel = self.distort(&q)?;
        self.inside(&pixel).then_some(pixel)
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        if !self.inside(pixel) {
            return None;
        }
        let (q, jq) = self.undistort(pixel);
        let (r, jr) = self.ray(&q);
        super::unit_bearing_with_jacobian(&r, &jr, &jq)
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        super::pixel_with_inverted_jacobian(self, self.try_pixel(bearing)?, bearing)
    }
}

/// Limits of [`newton_inverse`] (pixels).
pub(crate) struct NewtonLimits {
    /// Most iterations.
    pub max_iterations: usize,
    /// Longest step (a damped Newton step).
    pub max_step: f64,
    /// A step this short ends the iteration.
    pub tolerance: f64,
    /// Largest accepted |map(p) − target| at the end.
    pub residual: f64,
}

/// The point `p` with `map(p) = target`, by damped Newton from `start`, where `map` returns a
/// value and its Jacobian: the inverse of the distortion tables and of the Ladybug warps.
/// `None` when a Jacobian is singular, a step is not finite, or it does not converge within
/// `limits`.
pub(crate) fn newton_inverse(
    map: impl Fn(&Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>),
    start: Vector2<f64>,
    target: &Vector2<f64>,
    limits: &NewtonLimits,
) -> Option<Vector2<f64>> {
    let mut p = start;
    for _ in 0..limits.max_iterations {
        let (value, jac) = map(&p);
        let inv = jac.try_inverse()?;
        let mut step = inv * (value - target);
        let n = step.norm();
        if !n.is_finite() {
            return None;
        }
        if n > limits.max_step {
            step *= limits.max_step / n;
        }
        p -= step;
        if n <= limits.tolerance {
            let residual = (map(&p).0 - target).norm();
            return (residual <= limits.residual).then_some(p);
        }
    }
    None
}
