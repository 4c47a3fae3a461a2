//! Camera models, the multi-camera rig and the pixel → bearing lookup table.
//!
//! Every model implements one trait, [`CameraModel`]: a pixel gives a unit bearing in the
//! camera frame, a bearing gives the pixel that sees it (when one does), with the analytic
//! Jacobians of both maps. The models are
//! - [`Pinhole`]: a perspective camera with optional OpenCV radial-tangential distortion
//!   (`k1, k2, p1, p2, k3`), inverted by Newton's method;
//! - [`KannalaBrandt`]: the OpenCV fisheye model (`k1 … k4`), inverted by Newton's method;
//! - [`Equirectangular`]: a full 360° × 180° panorama;
//! - [`Lut`]: a dense pixel → bearing table with bilinear interpolation, built from any model
//!   and stored in a documented binary file.
//!
//! [`Camera`] wraps them in one enum (static dispatch, serde-tagged by `"model"`), and a
//! [`Rig`] places N cameras in the rig frame: `(camera, pixel)` → [`Ray`](vgps_geometry::geometry::Ray)
//! in the rig frame, and a direction or a point → every camera and pixel that sees it.
//!
//! # Conventions
//! - **Camera frame**: x right, y down, z forward (optical axis).
//! - **Pixels** `(u, v)` = (column, row); integer coordinates are pixel *centres*; `(0, 0)`
//!   is the centre of the top-left pixel. An image of `width × height` pixels covers the
//!   closed rectangle `[-½, width - ½] × [-½, height - ½]` ([`in_image_rectangle`]).
//! - The principal point `(cx, cy)` of the pinhole and fisheye models is in these same pixel
//!   coordinates, which are OpenCV's (OpenCV's `cameraMatrix` also puts integer coordinates at
//!   pixel centres). COLMAP puts `(0, 0)` at the top-left *corner* of the image: a COLMAP
//!   principal point is `(cx - ½, cy - ½)` here.
//! - A bearing is a unit vector. Projection functions accept any finite non-zero vector and
//!   are invariant to its length, so `d pixel / d bearing · bearing = 0`.
//!
//! # Example
//! ```
//! use nalgebra::Vector2;
//! use vgps_camera::calibration::{CameraModel, Pinhole, PinholeParams};
//! let camera = Pinhole::new(PinholeParams::ideal(1024, 768, 400.0, 400.0, 511.5, 383.5))?;
//! // 400 px right of the principal point at f = 400 px: 45° to the right.
//! let bearing = camera.try_bearing(&Vector2::new(911.5, 383.5)).unwrap();
//! let expected = std::f64::consts::FRAC_1_SQRT_2;
//! assert!((bearing.x - expected).abs() < 1e-12 && bearing.y.abs() < 1e-12);
//! let pixel = camera.try_pixel(&bearing).unwrap();
//! assert!((pixel - Vector2::new(911.5, 383.5)).norm() < 1e-9);
//! // Behind the camera: no pixel.
//! assert!(camera.try_pixel(&-bearing).is_none());
//! # Ok::<(), vgps_camera::calibration::CalibrationError>(())
//! ```

// `!(x < limit)` is used on purpose throughout: it rejects NaN along with out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod bspline;
mod camera;
mod equirectangular;
pub mod formats;
pub mod inspect;
mod kannala_brandt;
mod lut;
mod mask;
mod pinhole;
mod rig;
mod spline_pinhole;
mod tabulated_pinhole;

pub use bspline::{BSplineSurface, BSplineSurfaceParams};
pub use camera::Camera;
pub use equirectangular::*;
pub use formats::{Format, LoadError, load, save_native};
pub use kannala_brandt::*;
pub use lut::*;
pub use mask::CameraMask;
pub use pinhole::*;
pub use rig::*;
pub use spline_pinhole::*;
pub use tabulated_pinhole::{
    DistortionTable, TABLE_INVERSE_RESIDUAL, TABLE_INVERSE_TOLERANCE, TabulatedPinhole,
    TabulatedPinholeParams,
};

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Matrix3x2, Vector2, Vector3};
use thiserror::Error;

/// A pixel position `(u, v)` = (column, row), integer = pixel centre, `(0, 0)` top-left.
pub type Pixel = Vector2<f64>;

/// Errors of the calibration module: invalid parameters, rig look-ups and LUT files.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CalibrationError {
    /// A model parameter is out of its domain (non-finite, non-positive focal length, …).
    #[error("invalid {model} parameters: {reason}")]
    InvalidParameters {
        /// Which model (`"pinhole"`, `"kannala_brandt"`, …).
        model: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A camera index that the rig does not have.
    #[error("unknown camera index {index}: the rig has {count} cameras")]
    UnknownCamera {
        /// The index asked for.
        index: usize,
        /// How many cameras the rig has.
        count: usize,
    },
    /// A pixel outside the camera's valid image (or not finite).
    #[error("pixel ({u}, {v}) is outside the valid image of camera {camera}")]
    PixelOutside {
        /// The camera index.
        camera: usize,
        /// Column of the pixel.
        u: f64,
        /// Row of the pixel.
        v: f64,
    },
    /// A `rig_from_camera` rotation that is not orthonormal with determinant +1.
    #[error(
        "camera {camera}: rig_from_camera rotation is not a rotation \
         (max |RᵀR - I| or |det R - 1| = {deviation:e} > {tolerance:e})"
    )]
    NonOrthonormalRotation {
        /// The camera index.
        camera: usize,
        /// The largest deviation found.
        deviation: f64,
        /// The tolerance ([`ROTATION_TOLERANCE`]).
        tolerance: f64,
    },
    /// A translation that is not finite.
    #[error("camera {camera}: rig_from_camera translation is not finite")]
    NonFiniteTranslation {
        /// The camera index.
        camera: usize,
    },
    /// A LUT cannot be built from a source model.
    #[error("cannot build a LUT: {reason}")]
    LutBuild {
        /// Why (e.g. a grid node where the source model has no bearing).
        reason: String,
    },
    /// A LUT file (or byte buffer) that cannot be read, written or is invalid.
    #[error("LUT file {path}: {reason}")]
    LutFile {
        /// The file (or `"<bytes>"` for an in-memory buffer).
        path: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// A central camera model: pixels ↔ unit bearings in the camera frame (x right, y down,
/// z forward), with analytic Jacobians.
///
/// # Units
/// Pixels in pixels (see the module's pixel convention), bearings unitless unit vectors.
pub trait CameraModel {
    /// Image size `(width, height)` in pixels.
    fn image_size(&self) -> (u32, u32);

    /// True when `pixel` is finite, inside the image rectangle `[-½, w - ½] × [-½, h - ½]`
    /// and inside the model's validity domain (where pixel → bearing is defined).
    fn is_inside(&self, pixel: &Pixel) -> bool;

    /// The unit bearing (camera frame) of a pixel, or `None` outside the valid image.
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>>;

    /// Pixel → bearing for many pixels: `out[k]` becomes
    /// [`try_bearing`](Self::try_bearing)`(&pixels[k])`, for `k` below the shorter of the two
    /// lengths (the rest of the longer slice is left as it is). Returns how many of those
    /// pixels have a bearing.
    ///
    /// The results are those of `try_bearing`, bit for bit; a loop over one model is cheaper
    /// per pixel than calls through [`Camera`] (one dispatch per batch, and successive
    /// pixels' table reads overlap).
    ///
    /// # Example
    /// ```
    /// use nalgebra::Vector2;
    /// use vgps_camera::calibration::{CameraModel, Pinhole, PinholeParams};
    /// let camera = Pinhole::new(PinholeParams::ideal(640, 480, 500.0, 500.0, 319.5, 239.5))?;
    /// let pixels = [Vector2::new(319.5, 239.5), Vector2::new(-3.0, 0.0)];
    /// let mut bearings = [None; 2];
    /// assert_eq!(camera.bearings_into(&pixels, &mut bearings), 1);
    /// assert_eq!(bearings[0], camera.try_bearing(&pixels[0]));
    /// assert_eq!(bearings[1], None); // outside the image
    /// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
    /// ```
    #[inline]
    fn bearings_into(&self, pixels: &[Pixel], out: &mut [Option<Vector3<f64>>]) -> usize {
        let mut found = 0;
        for (pixel, bearing) in pixels.iter().zip(out.iter_mut()) {
            *bearing = self.try_bearing(pixel);
            found += usize::from(bearing.is_some());
        }
        found
    }

    /// The pixel that sees a direction (any finite non-zero length), or `None` when the
    /// direction is outside the model's domain or its pixel is outside the valid image.
    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel>;

    /// The bearing of a pixel and `d bearing / d pixel` (3×2, columns tangent to the
    /// bearing), or `None` where [`try_bearing`](Self::try_bearing) is `None`.
    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)>;

    /// The pixel of a direction and `d pixel / d direction` (2×3, with
    /// `J · direction = 0`), or `None` where [`try_pixel`](Self::try_pixel) is `None` or the
    /// map is singular (e.g. the poles of a panorama).
    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)>;
}

/// True when `pixel` is finite and inside the closed rectangle `[-½, width - ½] × [-½,
/// height - ½]` covered by a `width × height` image (integer coordinates = pixel centres).
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use vgps_camera::calibration::in_image_rectangle;
/// assert!(in_image_rectangle(4, 3, &Vector2::new(-0.5, 2.5)));
/// assert!(!in_image_rectangle(4, 3, &Vector2::new(3.6, 1.0)));
/// ```
#[inline]
pub fn in_image_rectangle(width: u32, height: u32, pixel: &Pixel) -> bool {
    pixel.x >= -0.5
        && pixel.x <= f64::from(width) - 0.5
        && pixel.y >= -0.5
        && pixel.y <= f64::from(height) - 0.5
}

/// A projected pixel up to this far (pixels) outside the image rectangle is clamped onto its
/// edge instead of rejected, so that pixels on the edge survive a round trip's rounding.
pub const IMAGE_EDGE_TOLERANCE: f64 = 1e-9;

/// `pixel` clamped onto the image rectangle when it lies inside it or within
/// [`IMAGE_EDGE_TOLERANCE`] of it; `None` otherwise (or when not finite).
#[inline]
pub fn clamp_to_image(width: u32, height: u32, pixel: &Pixel) -> Option<Pixel> {
    let (w, h) = (f64::from(width) - 0.5, f64::from(height) - 0.5);
    let t = IMAGE_EDGE_TOLERANCE;
    if pixel.x >= -0.5 - t && pixel.x <= w + t && pixel.y >= -0.5 - t && pixel.y <= h + t {
        Some(Vector2::new(pixel.x.clamp(-0.5, w), pixel.y.clamp(-0.5, h)))
    } else {
        None
    }
}

/// Number of scan steps of the validity-domain search (over an angle range, e.g. `(0, π/2)`
/// for the pinhole: a resolution of 0.02°).
pub const DOMAIN_SCAN_STEPS: usize = 4096;

/// Smallest `|det|` of a 2×2 Jacobian product accepted as invertible.
pub const MIN_JACOBIAN_DETERMINANT: f64 = 1e-300;

/// `d bearing / d pixel` from `d pixel / d direction` at a unit bearing.
///
/// The bearing map is the inverse of the projection restricted to the unit sphere; the rows
/// of `pixel_jacobian` lie in the tangent plane (projection is scale invariant), so
/// `Jᵀ (J Jᵀ)⁻¹` is the unique 3×2 matrix with tangent columns and `J · B = I₂`.
pub(crate) fn bearing_jacobian_from_pixel_jacobian(
    pixel_jacobian: &Matrix2x3<f64>,
) -> Option<Matrix3x2<f64>> {
    let jjt: Matrix2<f64> = pixel_jacobian * pixel_jacobian.transpose();
    if jjt.determinant().abs() <= MIN_JACOBIAN_DETERMINANT {
        return None;
    }
    let inv = jjt.try_inverse()?;
    let b = pixel_jacobian.transpose() * inv;
    b.iter().all(|x| x.is_finite()).then_some(b)
}

/// `d pixel / d direction` from `d bearing / d pixel` at a direction of length `norm`
/// whose unit vector is `bearing`.
///
/// The inverse on the tangent plane is `(BᵀB)⁻¹ Bᵀ`; composing with the derivative of the
/// normalisation `(I - b bᵀ) / norm` makes it scale invariant.
pub(crate) fn pixel_jacobian_from_bearing_jacobian(
    bearing_jacobian: &Matrix3x2<f64>,
    bearing: &Vector3<f64>,
    norm: f64,
) -> Option<Matrix2x3<f64>> {
    let btb: Matrix2<f64> = bearing_jacobian.transpose() * bearing_jacobian;
    if btb.determinant().abs() <= MIN_JACOBIAN_DETERMINANT {
        return None;
    }
    let inv = btb.try_inverse()?;
    let projector = (Matrix3::identity() - bearing * bearing.transpose()) / norm;
    let j = inv * bearing_jacobian.transpose() * projector;
    j.iter().all(|x| x.is_finite()).then_some(j)
}

/// The projection with its Jacobian for a model whose Jacobian is the inverse of its
/// unprojection's: `pixel` (the model's projection of `bearing`) and `d pixel / d direction`
/// from the model's `d bearing / d pixel` at `pixel`
/// ([`pixel_jacobian_from_bearing_jacobian`]). `None` where the unprojection has no
/// Jacobian or it is singular.
pub(crate) fn pixel_with_inverted_jacobian<M: CameraModel + ?Sized>(
    model: &M,
    pixel: Pixel,
    bearing: &Vector3<f64>,
) -> Option<(Pixel, Matrix2x3<f64>)> {
    let (_, jb) = model.try_bearing_with_jacobian(&pixel)?;
    let norm = bearing.norm();
    let unit = bearing / norm;
    let jp = pixel_jacobian_from_bearing_jacobian(&jb, &unit, norm)?;
    Some((pixel, jp))
}

/// The unit bearing of the ray direction `ray` and its Jacobian `d bearing / d pixel` =
/// `N · d ray / d q · d q / d pixel` (`N` the [`normalisation_jacobian`]), for a model that
/// maps a pixel to an intermediate point `q` (undistorted or rectified) and `q` to a ray.
/// `None` for a zero ray or a Jacobian that is not finite.
pub(crate) fn unit_bearing_with_jacobian(
    ray: &Vector3<f64>,
    dray_dq: &Matrix3x2<f64>,
    dq_dpixel: &Matrix2<f64>,
) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
    let norm = ray.norm();
    let unit = vgps_geometry::geometry::try_unit(ray)?;
    let jac = normalisation_jacobian(&unit, norm) * dray_dq * dq_dpixel;
    jac.iter().all(|v| v.is_finite()).then_some((unit, jac))
}

/// `d (v / |v|) / d v` = `(I - b bᵀ) / |v|` with `b = v / |v|`.
#[inline]
pub(crate) fn normalisation_jacobian(bearing: &Vector3<f64>, norm: f64) -> Matrix3<f64> {
    (Matrix3::identity() - bearing * bearing.transpose()) / norm
}

/// Checks a value is finite, else an [`CalibrationError::InvalidParameters`].
pub(crate) fn check_finite(
    model: &'static str,
    name: &str,
    value: f64,
) -> Result<(), CalibrationError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(CalibrationError::InvalidParameters {
            model,
            reason: format!("{name} = {value} is not finite"),
        })
    }
}

/// Checks a value is finite and strictly positive.
pub(crate) fn check_positive(
    model: &'static str,
    name: &str,
    value: f64,
) -> Result<(), CalibrationError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(CalibrationError::InvalidParameters {
            model,
            reason: format!("{name} = {value} must be finite and > 0"),
        })
    }
}

/// Largest accepted image width or height of a camera model, pixels (65,536: larger than
/// any camera or panorama of the project; an absurd size in a calibration file would
/// otherwise make the per-pixel tables of `vgps calib` allocate gigabytes).
pub const MAX_IMAGE_SIDE_PX: u32 = 1 << 16;

/// Checks an image size is non-zero and at most [`MAX_IMAGE_SIDE_PX`] per side.
pub(crate) fn check_size(
    model: &'static str,
    width: u32,
    height: u32,
) -> Result<(), CalibrationError> {
    if width == 0 || height == 0 {
        Err(CalibrationError::InvalidParameters {
            model,
            reason: format!("image size {width}×{height} must be non-zero"),
        })
    } else if width > MAX_IMAGE_SIDE_PX || height > MAX_IMAGE_SIDE_PX {
        Err(CalibrationError::InvalidParameters {
            model,
            reason: format!(
                "image size {width}×{height} exceeds {MAX_IMAGE_SIDE_PX} pixels per side"
            ),
        })
    } else {
        Ok(())
    }
}

/// The first `t` in `(0, upper]` where `f(t) <= 0` (found by a uniform scan of
/// [`DOMAIN_SCAN_STEPS`] steps and bisection), given `f(0) > 0`; `None` when `f > 0` at every
/// scanned point.
///
/// Used for the validity domains: where a distortion polynomial stops being monotonic.
pub(crate) fn first_non_positive(f: impl Fn(f64) -> f64, upper: f64) -> Option<f64> {
    const SCAN_STEPS: usize = DOMAIN_SCAN_STEPS;
    const BISECTIONS: usize = 80;
    let mut lo = 0.0;
    for i in 1..=SCAN_STEPS {
        let x = upper * (i as f64) / (SCAN_STEPS as f64);
        if f(x) <= 0.0 {
            let mut hi = x;
            for _ in 0..BISECTIONS {
                let mid = 0.5 * (lo + hi);
                if f(mid) <= 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return Some(lo);
        }
        lo = x;
    }
    None
}
