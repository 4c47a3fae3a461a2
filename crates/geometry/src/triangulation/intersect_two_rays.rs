//! Two-ray intersection: the midpoint of the common perpendicular.

use super::{TriangulationError, UNIT_DIRECTION_TOLERANCE};
use crate::geometry::Ray;
use nalgebra::Vector3;

/// The intersection of two rays (see [`intersect_two_rays()`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoRayIntersection {
    /// The midpoint of the common perpendicular of the two rays (metres, the rays' frame).
    pub point: Vector3<f64>,
    /// Distances (metres, > 0) along ray `a` and ray `b` from their origins to their points of
    /// closest approach.
    pub ranges: [f64; 2],
    /// Distance between the rays at closest approach (metres, ≥ 0): the length of the common
    /// perpendicular, 0 for rays that truly intersect. The point is `gap_m / 2` from each ray.
    pub gap_m: f64,
    /// Sine of the angle between the two ray directions (`|a × b|`, in `[0, 1]`).
    pub sin_parallax: f64,
    /// Cosine of the angle between the two ray directions (`a · b`, in `[-1, 1]`).
    pub cos_parallax: f64,
}

impl TwoRayIntersection {
    /// Angle between the two ray directions, in `[0, π]` radians: the parallax the landmark
    /// subtends between the two observers.
    ///
    /// Computed on demand from [`sin_parallax`](Self::sin_parallax) and
    /// [`cos_parallax`](Self::cos_parallax): the `atan2` would otherwise be most of the cost of
    /// an intersection.
    #[inline]
    pub fn parallax_rad(&self) -> f64 {
        self.sin_parallax.atan2(self.cos_parallax)
    }
}

/// `sin(`[`super::MIN_PARALLAX_RAD`]`)`: the check is made on `|a × b|` without a trigonometric call.
const SIN_MIN_PARALLAX: f64 = 9.999_998_333_333_417e-4;

/// Intersects two rays: the midpoint of their common perpendicular, with parallax and
/// in-front checks.
///
/// With unit directions `u` (ray `a`, origin `xa`) and `v` (ray `b`, origin `xb`),
/// `w = xa − xb`, `c = u·v`, `n = u × v` (`|n|² = 1 − c²`), the closest points are `xa + s·u`
/// and `xb + t·v` with
///
/// ```text
/// s = (c·(v·w) − u·w) / |n|²,    t = (v·w − c·(u·w)) / |n|²,
/// point = (xa + s·u + xb + t·v) / 2,    gap = |w·n| / |n|.
/// ```
///
/// The point minimises the sum of squared distances to the two lines, so it equals Ku, Ho &
/// Sarma's projector-sum estimate (see [`super::triangulate_rays()`]) for two rays. It is
/// invariant under translation and rotation of the frame and symmetric in `a`, `b`.
///
/// # Errors
/// - [`TriangulationError::InvalidRay`] if an origin is not finite or a direction is not a
///   finite unit vector (`| |u|² − 1 | > UNIT_DIRECTION_TOLERANCE`).
/// - [`TriangulationError::NoParallax`] if the angle between the two *lines* (`asin |u × v|`,
///   so nearly opposite rays count as parallel too) is below [`super::MIN_PARALLAX_RAD`].
/// - [`TriangulationError::BehindRay`] if `s ≤ 0` or `t ≤ 0`: the closest approach is not in
///   front of both observers.
/// - [`TriangulationError::NonFinite`] if the result overflowed.
///
/// # Units
/// Origins and the returned point, ranges and gap in metres (any Cartesian frame);
/// parallax in radians.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::Ray;
/// use vgps_geometry::triangulation::intersect_two_rays;
/// // Two observers 10 m apart on a road both see a lamp at (5, 8, 6).
/// let lamp = Vector3::new(5.0, 8.0, 6.0);
/// let a = Ray::try_new(Vector3::new(0.0, 0.0, 2.0), lamp - Vector3::new(0.0, 0.0, 2.0)).unwrap();
/// let b = Ray::try_new(Vector3::new(10.0, 0.0, 2.0), lamp - Vector3::new(10.0, 0.0, 2.0)).unwrap();
/// let hit = intersect_two_rays(&a, &b).unwrap();
/// assert!((hit.point - lamp).norm() < 1e-12);
/// assert!(hit.gap_m < 1e-12);
/// assert!((hit.ranges[0] - 105f64.sqrt()).abs() < 1e-12); // |(5, 8, 4)|
/// assert!((hit.parallax_rad() - 1.019479357663014).abs() < 1e-12);
/// ```
///
/// # References
/// - Visual GPS proposal: mapping of unknown vertices by ray intersection from two poses.
/// - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations" (eq. (2), n = 2).
#[inline]
pub fn intersect_two_rays(a: &Ray, b: &Ray) -> Result<TwoRayIntersection, TriangulationError> {
    let u = a.direction;
    let v = b.direction;
    let w = a.origin - b.origin;
    // One sum detects any NaN or infinity among the twelve inputs: a non-finite origin
    // component makes that component of `w` non-finite, and NaN and ±∞ propagate.
    if !(w.x + w.y + w.z + u.x + u.y + u.z + v.x + v.y + v.z).is_finite() {
        return Err(invalid_ray(a, b));
    }
    let uu = u.norm_squared();
    let vv = v.norm_squared();
    if (uu - 1.0).abs() > UNIT_DIRECTION_TOLERANCE {
        return Err(TriangulationError::InvalidRay { index: 0 });
    }
    if (vv - 1.0).abs() > UNIT_DIRECTION_TOLERANCE {
        return Err(TriangulationError::InvalidRay { index: 1 });
    }
    let n = u.cross(&v);
    let nn = n.norm_squared();
    let sin_angle = nn.sqrt();
    if sin_angle < SIN_MIN_PARALLAX {
        return Err(TriangulationError::NoParallax {
            line_angle_rad: sin_angle.min(1.0).asin(),
        });
    }
    let c = u.dot(&v);
    let d = u.dot(&w);
    let e = v.dot(&w);
    let inv = 1.0 / nn;
    let s = (c * e - d) * inv;
    let t = (e - c * d) * inv;
    if s.is_nan() || s <= 0.0 {
        return Err(TriangulationError::BehindRay {
            index: 0,
            range_m: s,
        });
    }
    if t.is_nan() || t <= 0.0 {
        return Err(TriangulationError::BehindRay {
            index: 1,
            range_m: t,
        });
    }
    let point = 0.5 * (a.origin + b.origin + u * s + v * t);
    let gap_m = w.dot(&n).abs() / sin_angle;
    if !(point.x + point.y + point.z + gap_m).is_finite() {
        return Err(TriangulationError::NonFinite);
    }
    Ok(TwoRayIntersection {
        point,
        ranges: [s, t],
        gap_m,
        sin_parallax: sin_angle,
        cos_parallax: c,
    })
}

/// The error for non-finite input, naming the first offending ray (cold path).
#[cold]
fn invalid_ray(a: &Ray, b: &Ray) -> TriangulationError {
    let ok =
        |r: &Ray| crate::geometry::is_finite(&r.origin) && crate::geometry::is_finite(&r.direction);
    if ok(a) && ok(b) {
        // Finite inputs whose difference overflowed.
        TriangulationError::NonFinite
    } else {
        TriangulationError::InvalidRay {
            index: if ok(a) { 1 } else { 0 },
        }
    }
}
