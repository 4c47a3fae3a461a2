//! Shared geometric types and helpers: poses, rays, solution lists and unit vectors.
//!
//! # Conventions
//! A [`Pose`] is `world_from_rig`: `point_in_world = pose * point_in_rig`, and its
//! translation is the rig origin expressed in the world frame. The world frame is a local
//! Cartesian frame in metres (usually ENU at an origin, see [`crate::geo::LocalFrame`]).

use arrayvec::ArrayVec;
use nalgebra::{IsometryMatrix3, Point3, Rotation3, Vector3};

/// Pose of the rig in a world frame, `world_from_rig` (rotation matrix + rig origin in world).
pub type Pose = IsometryMatrix3<f64>;

/// The most solutions a minimal three-point pose problem can have.
pub const MAX_P3P_SOLUTIONS: usize = 4;

/// Every solution of a minimal pose solver; an empty list means a degenerate sample.
pub type PoseSolutions = ArrayVec<Pose, MAX_P3P_SOLUTIONS>;

/// A ray in some frame: an origin and a unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts (metres).
    pub origin: Vector3<f64>,
    /// Unit direction of the ray.
    pub direction: Vector3<f64>,
}

impl Ray {
    /// A ray from an origin and a direction of any finite, non-zero length.
    ///
    /// Returns `None` when the direction is zero or either vector is not finite.
    pub fn try_new(origin: Vector3<f64>, direction: Vector3<f64>) -> Option<Self> {
        if !is_finite(&origin) {
            return None;
        }
        Some(Self {
            origin,
            direction: try_unit(&direction)?,
        })
    }

    /// The point at distance `t` (metres) along the ray.
    pub fn at(&self, t: f64) -> Vector3<f64> {
        self.origin + self.direction * t
    }
}

/// Smallest vector norm accepted as a direction (anything shorter is treated as zero).
pub const MIN_DIRECTION_NORM: f64 = 1e-300;

/// True when all three components are finite.
#[inline]
pub fn is_finite(v: &Vector3<f64>) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// The unit vector along `v`, or `None` when `v` is zero, too short or not finite.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// let u = vgps_geometry::geometry::try_unit(&Vector3::new(3.0, 0.0, 4.0)).unwrap();
/// assert!((u - Vector3::new(0.6, 0.0, 0.8)).norm() < 1e-15);
/// assert!(vgps_geometry::geometry::try_unit(&Vector3::zeros()).is_none());
/// ```
///
/// Vectors whose squared norm would underflow or overflow (components below about 1e-154 or
/// above 1e154) are rescaled by their largest component first, so the result is a unit
/// vector to rounding for every accepted input (a fuzzer found `|u| = 1.005` from a vector
/// of 1e-160 components).
#[inline]
pub fn try_unit(v: &Vector3<f64>) -> Option<Vector3<f64>> {
    /// Squared norms in this range are computed without underflow or overflow.
    const SAFE_NORM_SQUARED: (f64, f64) = (1e-200, 1e200);
    let n2 = v.norm_squared();
    let u = if n2 > SAFE_NORM_SQUARED.0 && n2 < SAFE_NORM_SQUARED.1 {
        v / n2.sqrt()
    } else {
        let scale = v.amax();
        if !(scale.is_finite() && scale > MIN_DIRECTION_NORM) {
            return None;
        }
        let w = v / scale;
        w / w.norm()
    };
    is_finite(&u).then_some(u)
}

/// Angle between two directions of any non-zero length, in radians, accurate at 0 and π.
///
/// Uses `atan2(|a × b|, a · b)`, which keeps full precision for tiny angles where
/// `acos` of the dot product does not.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// let a = vgps_geometry::geometry::angle_between(&Vector3::x(), &Vector3::new(1.0, 1.0, 0.0));
/// assert!((a - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
/// ```
#[inline]
pub fn angle_between(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

/// The angle (radians, in `[0, π]`) of a rotation, accurate at every angle.
///
/// `atan2(|vee(M − Mᵀ)|/2, (tr M − 1)/2)`: unlike `Rotation3::angle`, an `acos` of the
/// trace, it is never NaN when rounding puts the trace of a near-identity rotation above 3
/// (so two equal rotations compare as equal), and it keeps full precision near zero.
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// let r = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.25);
/// assert!((vgps_geometry::geometry::rotation_angle(&r) - 0.25).abs() < 1e-15);
/// assert_eq!(vgps_geometry::geometry::rotation_angle(&(r.inverse() * r)), 0.0);
/// ```
#[inline]
pub fn rotation_angle(rotation: &Rotation3<f64>) -> f64 {
    let m = rotation.matrix();
    let twice_sin = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    )
    .norm();
    twice_sin.atan2(m.trace() - 1.0)
}

/// The unit bearing in the rig frame from a pose to a world point, or `None` if the point
/// coincides with the rig origin.
#[inline]
pub fn bearing_in_rig(
    world_from_rig: &Pose,
    point_in_world: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let p = world_from_rig.inverse_transform_point(&Point3::from(*point_in_world));
    try_unit(&p.coords)
}

/// Two unit vectors that complete `n` (unit) to a right-handed orthonormal basis
/// `(t1, t2, n)`.
pub fn tangent_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    // Frisvad / Duff et al. 2017 branchless-ish construction.
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t1 = Vector3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t2 = Vector3::new(b, sign + n.y * n.y * a, -n.y);
    (t1, t2)
}
