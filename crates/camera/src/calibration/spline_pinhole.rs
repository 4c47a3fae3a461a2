//! A camera whose raw (distorted) image is mapped to a rectified pinhole image by a pair of
//! B-spline warps: the Ladybug SDK's model of each camera of a head (`.conf` file).
//!
//! # Model
//! Both images are `width × height` pixels and the warps work on *normalised* coordinates
//! `n = ((u + ½) / width, (v + ½) / height)` (so `[0, 1]²` is the image rectangle and an
//! integer pixel is a pixel centre, the convention of the `.conf` file's stored pairs).
//! - raw pixel `p` → `n = N(p)` → rectified `m = (D_u(n), D_v(n))` (the raw → rectified
//!   warp, the file's `DistortedSpline`) → rectified pixel `q = N⁻¹(m)` →
//!   `r = ((q_u − cx) / fx, (q_v − cy) / fy, 1)`, bearing `r / |r|` (x right, y down,
//!   z forward);
//! - bearing → `q = (fx b_x / b_z + cx, fy b_y / b_z + cy)` → first guess
//!   `p₀ = N⁻¹(R(N(q)))` by the rectified → raw warp (the file's `RectifiedSpline`), then
//!   Newton's method on `D(N(p)) = N(q)` with the spline Jacobian, so that
//!   pixel → bearing → pixel is exact to ~1e-9 px whatever the consistency of the two
//!   fitted warps (reported by `vgps calib check`).
//!
//! The valid image is the raw image rectangle `[−½, W − ½] × [−½, H − ½]`; the raw → rectified
//! warp must be orientation preserving there (its Jacobian determinant is checked positive
//! on a grid when the model is built).

use super::bspline::BSplineSurface;
use super::{
    CalibrationError, CameraModel, Pixel, check_finite, check_positive, in_image_rectangle,
};
use nalgebra::{Matrix2, Matrix2x3, Matrix3x2, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Newton's inversion of the raw → rectified warp stops when its step is below this
/// (pixels).
pub const SPLINE_INVERSE_TOLERANCE: f64 = 1e-10;

/// Most Newton iterations of the warp inversion.
pub const MAX_SPLINE_INVERSE_ITERATIONS: usize = 40;

/// The converged raw pixel must map to the asked rectified position within this (pixels).
pub const SPLINE_INVERSE_RESIDUAL: f64 = 1e-8;

/// Largest Newton step of the warp inversion (pixels): keeps the iteration local.
pub const SPLINE_MAX_NEWTON_STEP: f64 = 64.0;

/// Nodes per side of the grid on which the raw → rectified warp's Jacobian determinant is
/// checked positive when a model is built.
pub const SPLINE_CHECK_GRID: usize = 65;

/// Smallest `z` of a direction accepted by the projection.
const MIN_FORWARD_Z: f64 = 1e-12;

/// A warp between two normalised images: one spline per output coordinate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplineWarp {
    /// The output's normalised u (column) coordinate.
    pub u: BSplineSurface,
    /// The output's normalised v (row) coordinate.
    pub v: BSplineSurface,
}

impl SplineWarp {
    /// The warped normalised position of `n` and its 2×2 Jacobian (rows: u, v output;
    /// columns: d/dx, d/dy).
    #[inline]
    pub fn apply(&self, n: &Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>) {
        let (a, ga) = self.u.value_and_gradient(n.x, n.y);
        let (b, gb) = self.v.value_and_gradient(n.x, n.y);
        (Vector2::new(a, b), Matrix2::new(ga[0], ga[1], gb[0], gb[1]))
    }
}

/// The parameters of a [`SplinePinhole`] (serde form, splines inline).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplinePinholeParams {
    /// Image width in pixels (raw and rectified); the u normalisation.
    pub width: u32,
    /// Image height in pixels (raw and rectified); the v normalisation.
    pub height: u32,
    /// Focal length along u of the rectified image (pixels).
    pub fx: f64,
    /// Focal length along v of the rectified image (pixels).
    pub fy: f64,
    /// Principal point column of the rectified image (integer = pixel centre).
    pub cx: f64,
    /// Principal point row of the rectified image.
    pub cy: f64,
    /// Raw → rectified warp on normalised coordinates (the `.conf` `DistortedSpline`).
    pub raw_to_rectified: SplineWarp,
    /// Rectified → raw warp on normalised coordinates (the `.conf` `RectifiedSpline`); only
    /// seeds the inversion of `raw_to_rectified`.
    pub rectified_to_raw: SplineWarp,
}

/// A raw camera image rectified to a pinhole by B-spline warps (see the module
/// documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SplinePinholeParams", into = "SplinePinholeParams")]
pub struct SplinePinhole {
    params: SplinePinholeParams,
}

const MODEL: &str = "spline_pinhole";

impl SplinePinhole {
    /// Validates the sizes, finite positive focal lengths, a finite principal point and a
    /// raw → rectified warp with a positive Jacobian determinant on a
    /// [`SPLINE_CHECK_GRID`]² grid over the raw image.
    pub fn new(params: SplinePinholeParams) -> Result<Self, CalibrationError> {
        let p = &params;
        super::check_size(MODEL, p.width, p.height)?;
        check_positive(MODEL, "fx", p.fx)?;
        check_positive(MODEL, "fy", p.fy)?;
        check_finite(MODEL, "cx", p.cx)?;
        check_finite(MODEL, "cy", p.cy)?;
        let model = Self { params };
        let det = model.min_warp_determinant(SPLINE_CHECK_GRID);
        if !(det > 0.0) {
            return Err(CalibrationError::InvalidParameters {
                model: MODEL,
                reason: format!(
                    "the raw → rectified warp is not orientation preserving over the image \
                     (smallest Jacobian determinant {det:e})"
                ),
            });
        }
        Ok(model)
    }

    /// The parameters.
    pub fn params(&self) -> &SplinePinholeParams {
        &self.params
    }

    /// The smallest Jacobian determinant of the raw → rectified warp (normalised units) on
    /// an `n × n` grid over the raw image (NaN when a value is not finite).
    pub fn min_warp_determinant(&self, n: usize) -> f64 {
        let n = n.max(2);
        let mut min = f64::INFINITY;
        for a in 0..n {
            for b in 0..n {
                let x = a as f64 / (n - 1) as f64;
                let y = b as f64 / (n - 1) as f64;
                let (_, j) = self.params.raw_to_rectified.apply(&Vector2::new(x, y));
                let det = j.determinant();
                if !det.is_finite() {
                    return f64::NAN;
                }
                min = min.min(det);
            }
        }
        min
    }

    #[inline]
    fn scale(&self) -> Vector2<f64> {
        Vector2::new(f64::from(self.params.width), f64::from(self.params.height))
    }

    /// Pixel → normalised coordinates.
    #[inline]
    pub fn normalise(&self, pixel: &Pixel) -> Vector2<f64> {
        (pixel + Vector2::new(0.5, 0.5)).component_div(&self.scale())
    }

    /// Normalised coordinates → pixel.
    #[inline]
    pub fn denormalise(&self, n: &Vector2<f64>) -> Pixel {
        n.component_mul(&self.scale()) - Vector2::new(0.5, 0.5)
    }

    /// Raw pixel → rectified pixel and its Jacobian (pixels per pixel).
    #[inline]
    pub fn rectify(&self, pixel: &Pixel) -> (Pixel, Matrix2<f64>) {
        let s = self.scale();
        let (m, j) = self.params.raw_to_rectified.apply(&self.normalise(pixel));
        let jac = Matrix2::from_diagonal(&s) * j * Matrix2::from_diagonal(&s.map(|v| 1.0 / v));
        (self.denormalise(&m), jac)
    }

    /// Rectified pixel → raw pixel by the file's rectified → raw warp alone (no Newton
    /// refinement: the figure of the two warps' consistency).
    pub fn unrectify_by_warp(&self, rectified: &Pixel) -> Pixel {
        let (n, _) = self
            .params
            .rectified_to_raw
            .apply(&self.normalise(rectified));
        self.denormalise(&n)
    }

    /// Rectified pixel → the raw pixel that [`rectify`](Self::rectify) maps onto it
    /// (Newton's method seeded by the rectified → raw warp), when it converges and lies in
    /// the image.
    pub fn unrectify(&self, rectified: &Pixel) -> Option<Pixel> {
        if !(rectified.x.is_finite() && rectified.y.is_finite()) {
            return None;
        }
        super::tabulated_pinhole::newton_inverse(
            |p| self.rectify(p),
            self.unrectify_by_warp(rectified),
            rectified,
            &super::tabulated_pinhole::NewtonLimits {
                max_iterations: MAX_SPLINE_INVERSE_ITERATIONS,
                max_step: SPLINE_MAX_NEWTON_STEP,
                tolerance: SPLINE_INVERSE_TOLERANCE,
                residual: SPLINE_INVERSE_RESIDUAL,
            },
        )
    }

    /// The rectified pinhole's pixel of a direction (`z > 0`), not bounded to any image.
    #[inline]
    pub fn rectified_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        if !(bearing.z > MIN_FORWARD_Z * bearing.norm())
            || !vgps_geometry::geometry::is_finite(bearing)
        {
            return None;
        }
        let p = &self.params;
        Some(Vector2::new(
            p.fx * bearing.x / bearing.z + p.cx,
            p.fy * bearing.y / bearing.z + p.cy,
        ))
    }

    #[inline]
    fn inside(&self, pixel: &Pixel) -> bool {
        in_image_rectangle(self.params.width, self.params.height, pixel)
    }

    #[inline]
    fn ray(&self, q: &Pixel) -> (Vector3<f64>, Matrix3x2<f64>) {
        let p = &self.params;
        let jac = Matrix3x2::new(1.0 / p.fx, 0.0, 0.0, 1.0 / p.fy, 0.0, 0.0);
        (
            Vector3::new((q.x - p.cx) / p.fx, (q.y - p.cy) / p.fy, 1.0),
            jac,
        )
    }
}

impl TryFrom<SplinePinholeParams> for SplinePinhole {
    type Error = CalibrationError;
    fn try_from(params: SplinePinholeParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<SplinePinhole> for SplinePinholeParams {
    fn from(model: SplinePinhole) -> Self {
        model.params
    }
}

impl CameraModel for SplinePinhole {
    fn image_size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        self.inside(pixel)
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        if !self.inside(pixel) {
            return None;
        }
        let (q, _) = self.rectify(pixel);
        vgps_geometry::geometry::try_unit(&self.ray(&q).0)
    }

    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        let q = self.rectified_pixel(bearing)?;
        let pixel = self.unrectify(&q)?;
        super::clamp_to_image(self.params.width, self.params.height, &pixel)
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        if !self.inside(pixel) {
            return None;
        }
        let (q, jq) = self.rectify(pixel);
        let (r, jr) = self.ray(&q);
        super::unit_bearing_with_jacobian(&r, &jr, &jq)
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        super::pixel_with_inverted_jacobian(self, self.try_pixel(bearing)?, bearing)
    }
}
