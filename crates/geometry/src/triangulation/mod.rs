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

pub(crate) use crate::sym3::Sym3;
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
