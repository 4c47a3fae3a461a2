//! Landmark positions from rays seen at several poses.
//!
//! Two estimators, one per file:
//! - [`intersect_two_rays()`]: the midpoint of the common perpendicular of two rays, with the
//!   parallax and in-front checks the Visual GPS proposal asks for when it maps an unknown
//!   vertex "using ray intersection from as few as two poses".
//! - [`triangulate_rays()`]: Ku, Ho & Sarma's projector-sum estimator for `n ≥ 2` rays,
//!   `p = (Σ Pᵢ)⁻¹ Σ Pᵢ xᵢ` with `Pᵢ = I − uᵢuᵢᵀ`, with a first-order covariance from
//!   observer-position and angular noise that — unlike the paper's eq. (7)/(9) — does not
//!   depend on where the world origin is; [`triangulate_rays_weighted()`], its
//!   inverse-variance weighted form; and [`RaySum`], the online accumulator (O(1) per ray).
//!
//! The derivation of the covariance and the Monte-Carlo checks are in
//! `docs/triangulation.md`.
//!
//! # Conventions
//! Rays are [`crate::geometry::Ray`]s in one Cartesian world frame in metres (ECEF or local
//! ENU): the origin is the observer (camera centre) position, the direction a unit bearing
//! towards the landmark. Angles are in radians.
//!
//! # References
//! - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", MIT (projector
//!   sum, eq. (2); covariance, eq. (4), (7), (9)).

mod intersect_two_rays;
mod triangulate_rays;

pub use intersect_two_rays::{TwoRayIntersection, intersect_two_rays};
pub use triangulate_rays::{
    RayObservation, RaySum, TriangulatedPoint, triangulate_rays, triangulate_rays_weighted,
};

/// Smallest angle between the two lines of [`intersect_two_rays()`] (radians, about 0.057°).
///
/// The range of a two-ray intersection is uncertain by about `σ_ang / parallax` of itself,
/// so below a milliradian (the bearing accuracy of a good panoramic camera) the point is not
/// determined at all. The reported parallax lets a caller apply a stricter policy.
pub const MIN_PARALLAX_RAD: f64 = 1e-3;

/// Smallest accepted reciprocal condition estimate of the normal matrix `A = Σ wᵢPᵢ` of
/// [`triangulate_rays()`] (dimensionless).
///
/// The estimate is `det A / (tr A · e₂(A))` with `e₂` the sum of the principal 2×2 minors;
/// it lies in `[λ_min/(9λ_max), λ_min/λ_max]` (see [`reciprocal_condition`]). For two
/// rays at parallax `θ` it is `≈ θ²/8`, so this threshold rejects bundles whose directions
/// all lie within about 0.1 mrad of one line: numerically safe (≥ 6 significant digits left)
/// and far below any useful parallax, which the covariance expresses.
pub const MIN_RECIPROCAL_CONDITION: f64 = 1e-9;

/// Smallest accepted ratio of the parallax (the largest angle between the rays, radians) to
/// the largest angular noise `σ_ang` of the observations, for [`triangulate_rays()`] and
/// [`triangulate_rays_weighted()`].
///
/// The range along the rays is uncertain by about `σ_ang / parallax` of itself, and the
/// first-order covariance holds only while that is small. Measured with three rays at
/// σ = 1 mrad (`tests/degenerate_geometry.rs`): at a parallax of 2σ the 99 % ellipsoid
/// covered 47 % of the errors; at 10σ, 96 %; at 20σ, 98 %.
pub const MIN_PARALLAX_SIGMAS: f64 = 10.0;

/// Largest accepted deviation of `|u|²` from 1 for a ray direction `u`.
pub const UNIT_DIRECTION_TOLERANCE: f64 = 1e-6;

/// Fewest rays a triangulation needs.
pub const MIN_RAYS: usize = 2;

/// Why a triangulation failed. No triangulation returns NaN or infinity: it returns one of
/// these instead.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum TriangulationError {
    /// Fewer than [`MIN_RAYS`] rays.
    #[error("at least {MIN_RAYS} rays are needed, got {0}")]
    TooFewRays(usize),
    /// Ray `index` has a non-finite origin or a direction that is not a finite unit vector.
    #[error("ray {index} is invalid: non-finite origin or non-unit direction")]
    InvalidRay {
        /// Index of the offending ray.
        index: usize,
    },
    /// Observation `index` has a negative or non-finite noise level (or, for the weighted
    /// estimator, zero position and angular noise together).
    #[error("observation {index} has an invalid noise level")]
    InvalidNoise {
        /// Index of the offending observation.
        index: usize,
    },
    /// The two lines are (nearly) parallel: their angle is below [`MIN_PARALLAX_RAD`].
    #[error("rays nearly parallel: line angle {line_angle_rad:e} rad < {MIN_PARALLAX_RAD} rad")]
    NoParallax {
        /// The angle between the two lines, in `[0, π/2]` radians.
        line_angle_rad: f64,
    },
    /// The parallax is too small for the noise: below [`MIN_PARALLAX_SIGMAS`] times the
    /// largest angular σ of the observations, the first-order covariance understates the
    /// range error.
    #[error(
        "parallax {parallax_rad:e} rad is below {MIN_PARALLAX_SIGMAS} × the angular noise {sigma_rad:e} rad"
    )]
    WeakParallax {
        /// The largest angle between the rays (radians).
        parallax_rad: f64,
        /// The largest angular σ of the observations (radians).
        sigma_rad: f64,
    },
    /// The normal matrix is singular or ill-conditioned (all rays nearly parallel).
    #[error(
        "normal matrix ill-conditioned: reciprocal condition {reciprocal_condition:e} < {MIN_RECIPROCAL_CONDITION:e}"
    )]
    IllConditioned {
        /// The reciprocal condition estimate (see [`MIN_RECIPROCAL_CONDITION`]).
        reciprocal_condition: f64,
    },
    /// The estimated point is not in front of ray `index` (range along the ray ≤ 0).
    #[error("point behind ray {index} (range {range_m} m)")]
    BehindRay {
        /// Index of the ray.
        index: usize,
        /// The signed distance of the point along the ray (metres), ≤ 0.
        range_m: f64,
    },
    /// The computation overflowed to a non-finite value.
    #[error("non-finite result")]
    NonFinite,
}

/// Reciprocal condition estimate `det A / (tr A · e₂(A))` of a symmetric positive
/// semi-definite 3×3 matrix, `e₂` being the sum of its principal 2×2 minors.
///
/// With eigenvalues `λ₁ ≥ λ₂ ≥ λ₃ ≥ 0`: `tr ≥ λ₁` and `e₂ ≥ λ₁λ₂`, so the estimate is at most
/// `λ₃/λ₁`; and `tr ≤ 3λ₁`, `e₂ ≤ 3λ₁λ₂`, so it is at least `λ₃/(9λ₁)`. Returns 0 for the
/// zero matrix and for non-finite input.
///
/// # Example
/// ```
/// use nalgebra::Matrix3;
/// let r = vgps_geometry::triangulation::reciprocal_condition(&Matrix3::from_diagonal_element(2.0));
/// assert!((r - 1.0 / 9.0).abs() < 1e-15);
/// ```
pub fn reciprocal_condition(a: &nalgebra::Matrix3<f64>) -> f64 {
    let s = Sym3::from_matrix(a);
    let (_, det, e2) = s.cofactors();
    let r = det / (s.trace() * e2);
    if r.is_finite() { r.max(0.0) } else { 0.0 }
}

/// A symmetric 3×3 matrix stored as its upper triangle (internal, for speed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Sym3 {
    pub xx: f64,
    pub xy: f64,
    pub xz: f64,
    pub yy: f64,
    pub yz: f64,
    pub zz: f64,
}

impl Sym3 {
    /// The projector `I − uuᵀ` scaled by `w`.
    #[inline(always)]
    pub fn projector(u: &nalgebra::Vector3<f64>, w: f64) -> Self {
        let (wx, wy, wz) = (w * u.x, w * u.y, w * u.z);
        Self {
            xx: w - wx * u.x,
            xy: -wx * u.y,
            xz: -wx * u.z,
            yy: w - wy * u.y,
            yz: -wy * u.z,
            zz: w - wz * u.z,
        }
    }

    /// `w·I`.
    #[inline(always)]
    pub fn diagonal(w: f64) -> Self {
        Self {
            xx: w,
            yy: w,
            zz: w,
            ..Self::default()
        }
    }

    /// `self += w·uuᵀ`.
    #[inline(always)]
    pub fn add_outer(&mut self, w: f64, u: &nalgebra::Vector3<f64>) {
        let (wx, wy, wz) = (w * u.x, w * u.y, w * u.z);
        self.xx += wx * u.x;
        self.xy += wx * u.y;
        self.xz += wx * u.z;
        self.yy += wy * u.y;
        self.yz += wy * u.z;
        self.zz += wz * u.z;
    }

    /// `self − o`.
    #[inline(always)]
    pub fn minus(&self, o: &Self) -> Self {
        Self {
            xx: self.xx - o.xx,
            xy: self.xy - o.xy,
            xz: self.xz - o.xz,
            yy: self.yy - o.yy,
            yz: self.yz - o.yz,
            zz: self.zz - o.zz,
        }
    }

    #[inline(always)]
    pub fn add_assign(&mut self, o: &Self) {
        self.xx += o.xx;
        self.xy += o.xy;
        self.xz += o.xz;
        self.yy += o.yy;
        self.yz += o.yz;
        self.zz += o.zz;
    }

    /// `self += s · o`.
    #[inline(always)]
    pub fn add_scaled(&mut self, s: f64, o: &Self) {
        self.xx += s * o.xx;
        self.xy += s * o.xy;
        self.xz += s * o.xz;
        self.yy += s * o.yy;
        self.yz += s * o.yz;
        self.zz += s * o.zz;
    }

    #[inline(always)]
    pub fn trace(&self) -> f64 {
        self.xx + self.yy + self.zz
    }

    #[inline(always)]
    pub fn mul_vec(&self, v: &nalgebra::Vector3<f64>) -> nalgebra::Vector3<f64> {
        nalgebra::Vector3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// The cofactor (adjugate) matrix, the determinant and `e₂` (sum of principal minors).
    #[inline(always)]
    pub fn cofactors(&self) -> (Self, f64, f64) {
        let c = Self {
            xx: self.yy * self.zz - self.yz * self.yz,
            xy: self.xz * self.yz - self.xy * self.zz,
            xz: self.xy * self.yz - self.xz * self.yy,
            yy: self.xx * self.zz - self.xz * self.xz,
            yz: self.xy * self.xz - self.xx * self.yz,
            zz: self.xx * self.yy - self.xy * self.xy,
        };
        let det = self.xx * c.xx + self.xy * c.xy + self.xz * c.xz;
        (c, det, c.xx + c.yy + c.zz)
    }

    /// `B·S·B` for symmetric `B` (= `self`) and `S`: the sandwich of a covariance.
    #[inline(always)]
    pub fn sandwich(&self, s: &Self) -> Self {
        // T = B·S (all nine entries), then the upper triangle of T·B: 45 products.
        let b = self;
        let row = |b0: f64, b1: f64, b2: f64| {
            [
                b0 * s.xx + b1 * s.xy + b2 * s.xz,
                b0 * s.xy + b1 * s.yy + b2 * s.yz,
                b0 * s.xz + b1 * s.yz + b2 * s.zz,
            ]
        };
        let [t00, t01, t02] = row(b.xx, b.xy, b.xz);
        let [t10, t11, t12] = row(b.xy, b.yy, b.yz);
        let [t20, t21, t22] = row(b.xz, b.yz, b.zz);
        Self {
            xx: t00 * b.xx + t01 * b.xy + t02 * b.xz,
            xy: t00 * b.xy + t01 * b.yy + t02 * b.yz,
            xz: t00 * b.xz + t01 * b.yz + t02 * b.zz,
            yy: t10 * b.xy + t11 * b.yy + t12 * b.yz,
            yz: t10 * b.xz + t11 * b.yz + t12 * b.zz,
            zz: t20 * b.xz + t21 * b.yz + t22 * b.zz,
        }
    }

    #[inline(always)]
    pub fn scale(&self, k: f64) -> Self {
        Self {
            xx: k * self.xx,
            xy: k * self.xy,
            xz: k * self.xz,
            yy: k * self.yy,
            yz: k * self.yz,
            zz: k * self.zz,
        }
    }

    #[inline(always)]
    pub fn to_matrix(self) -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::new(
            self.xx, self.xy, self.xz, self.xy, self.yy, self.yz, self.xz, self.yz, self.zz,
        )
    }

    /// The upper triangle of `m`, symmetrised.
    #[inline(always)]
    pub fn from_matrix(m: &nalgebra::Matrix3<f64>) -> Self {
        Self {
            xx: m[(0, 0)],
            xy: 0.5 * (m[(0, 1)] + m[(1, 0)]),
            xz: 0.5 * (m[(0, 2)] + m[(2, 0)]),
            yy: m[(1, 1)],
            yz: 0.5 * (m[(1, 2)] + m[(2, 1)]),
            zz: m[(2, 2)],
        }
    }

    #[inline(always)]
    pub fn is_finite(&self) -> bool {
        (self.xx + self.xy + self.xz + self.yy + self.yz + self.zz).is_finite()
    }
}
