//! Non-linear pose refinement on angular residuals, for central and non-central rigs.
//!
//! [`refine_pose`] minimises the angular misfit between observed rays and the directions to
//! known world points, over all correspondences, by Levenberg–Marquardt (damped
//! Gauss–Newton) with analytic Jacobians, optional robust losses (iteratively reweighted)
//! and a 6×6 covariance of the result.
//!
//! # Model
//! Observation `i` is a ray in the rig frame with origin `oᵢ` (the centre of the camera that
//! saw it; zero for a central camera) and unit direction `dᵢ`, towards the world point
//! `Xᵢ`. With `world_from_rig = (R, p)` the predicted direction is
//!
//! ```text
//! vᵢ = Rᵀ (Xᵢ − p) − oᵢ,      uᵢ = vᵢ / |vᵢ|.
//! ```
//!
//! # Residual
//! Let `(t₁, t₂, dᵢ)` be the right-handed basis of [`crate::geometry::tangent_basis`],
//! `sᵢ = (t₁·uᵢ, t₂·uᵢ)` (so `|sᵢ| = sin θᵢ`) and `cᵢ = dᵢ·uᵢ = cos θᵢ`, with `θᵢ` the angle
//! between the observed and predicted directions. The residual is the logarithm map of the
//! sphere at `dᵢ`, expressed in that basis:
//!
//! ```text
//! θᵢ = atan2(|sᵢ|, cᵢ),      rᵢ = θᵢ · sᵢ / |sᵢ|,      |rᵢ| = θᵢ exactly.
//! ```
//!
//! It is smooth on the whole sphere except the antipode of `dᵢ`, equal to the tangent-plane
//! projection `sᵢ` to first order, and its magnitude is the angle itself on `[0, π]`. That
//! last property is what makes the robust losses work: the cost `ρ(θᵢ)` has a gradient of
//! magnitude `ρ'(θᵢ)` per unit angle, bounded for Huber and vanishing for Cauchy. (The
//! plain projection `sᵢ`, of magnitude `sin θᵢ`, makes a bearing pointing backwards look
//! like a perfect fit; the stereographic `2sᵢ/(1 + cᵢ)`, of magnitude `2 tan(θᵢ/2)`, has a
//! derivative `sec²(θᵢ/2)` that hands far outliers an unbounded influence.) Within
//! [`ANTIPODAL_MARGIN_RAD`] of the antipode, where the residual's direction is undefined,
//! the tangential part of its Jacobian is dropped.
//!
//! # Parameterisation and covariance
//! The update is `world_from_rig ← (exp(δθ)·R, p + δp)` with the state ordered `[δp, δθ]`
//! (metres and radians, both in the world frame): the project convention of the 6×6 pose
//! covariance. The covariance reported is `(Σᵢ ωᵢ Jᵢᵀ Jᵢ / σᵢ²)⁻¹` at the solution, with
//! `ωᵢ` the robust weight (1 without a robust loss, so it is `σ² (JᵀJ)⁻¹` for one common
//! `σ`). See `docs/refine_pose.md` for the derivation.
//!
//! # References
//! - K. Levenberg (1944), D. Marquardt (1963): damped least squares.
//! - R. Hartley, A. Zisserman, *Multiple View Geometry*, 2nd ed., appendix A6 (sparse/robust
//!   Levenberg–Marquardt, covariance of the estimate).
//! - P. J. Huber (1964), *Robust estimation of a location parameter*; the Cauchy (Lorentzian)
//!   loss and IRLS weights as in B. Triggs et al., *Bundle adjustment — a modern synthesis*
//!   (2000): robust cost models and the second-order (robustified Gauss–Newton) correction.

use crate::geometry::MIN_DIRECTION_NORM;
use crate::geometry::tangent_basis;
use crate::geometry::{Pose, Ray, is_finite};
use nalgebra::{
    Cholesky, Matrix2x3, Matrix3, Matrix6, Rotation3, RowVector6, SMatrix, Translation3,
    UnitQuaternion, Vector2, Vector3, Vector6,
};

/// A 2×6 Jacobian of one angular residual with respect to `[δp, δθ]`.
pub type Matrix2x6 = SMatrix<f64, 2, 6>;
use thiserror::Error;

/// Angular size of one pixel of a Ladybug2 camera head (radians), the figure of the Visual
/// GPS proposal (`Δθ pixel resolution = 0.00167557 rad`, about 0.096°).
pub const LADYBUG2_PIXEL_RAD: f64 = 0.001_675_57;

/// Default standard deviation of the angular noise per tangent axis (radians): the
/// workspace's one default bearing σ, [`crate::DEFAULT_BEARING_SIGMA_RAD`] (0.1°, about one
/// Ladybug2 pixel, [`LADYBUG2_PIXEL_RAD`]). Set [`RefineOptions::sigma_rad`] to your own
/// figure; the fix, the matcher and the localizer pass theirs.
pub const DEFAULT_SIGMA_RAD: f64 = crate::DEFAULT_BEARING_SIGMA_RAD;

/// Fewest correspondences accepted (three give six residuals for six unknowns).
pub const MIN_CORRESPONDENCES: usize = 3;

/// Default iteration budget of [`RefineOptions::max_iterations`]. Started within a few
/// degrees and a few percent of the range, the solver needs about five.
pub const DEFAULT_MAX_ITERATIONS: usize = 50;

/// Default [`RefineOptions::step_tolerance_rad`]: iteration stops when the step moves the
/// attitude by less than this angle and the position by less than this angle times the RMS
/// range of the points (1e-10 rad ≈ 6e-8 Ladybug2 pixels).
pub const DEFAULT_STEP_TOLERANCE_RAD: f64 = 1e-10;

/// A world point closer than this to the origin of its ray (metres) has no direction: it is
/// an input error at the initial pose and a rejected step during the iterations.
pub const MIN_POINT_DISTANCE_M: f64 = 1e-6;

/// Within this angle of π (the antipode of the observed bearing) the tangential part of the
/// residual Jacobian, which grows as `θ / sin θ`, is dropped: the direction of the residual
/// is undefined at the antipode. The gradient of the cost is unaffected (it depends on the
/// angle only), so only the Gauss–Newton curvature of such a gross outlier changes.
pub const ANTIPODAL_MARGIN_RAD: f64 = 1e-2;

/// Where `sin θ` is below this with `θ` near π, the direction of growth of θ is lost to
/// rounding (its error is ~1e-16 / sin θ): the Jacobian is zero.
const ANTIPODE_SIN_TOLERANCE: f64 = 1e-8;
/// Below this `sin θ` (with `cos θ > 0`) the angle is the series of `asin` to the 7th
/// power, exact to rounding, instead of `atan2`.
const ASIN_SERIES_LIMIT: f64 = 1e-2;
/// Below this angle the residual Jacobian is written as `φ·T + φ'·s·dᵀ` (no division by the
/// residual's direction); above it as a radial plus a tangential part.
const SMALL_ANGLE_RAD: f64 = 0.5;
/// Below this angle `θ/sin θ` and its derivative use their Taylor series (truncation error
/// below 1e-12 relative; the closed form would lose digits to cancellation).
const SERIES_ANGLE_RAD: f64 = 1e-3;

/// Smallest reciprocal condition number (of the normal matrix scaled to unit diagonal)
/// accepted at the solution; below it the geometry does not determine the pose (e.g. all
/// points on one line) and [`RefineError::RankDeficient`] is returned.
pub const MIN_RECIPROCAL_CONDITION: f64 = 1e-12;

/// Distance, in standard deviations, at which [`refine_pose`] checks its covariance against
/// the cost (see [`RefineError::WeaklyDetermined`]).
pub const LINEARITY_CHECK_SIGMAS: f64 = 2.0;

/// Smallest accepted ratio of the actual rise of χ² to the rise `k²` the covariance predicts,
/// `k` = [`LINEARITY_CHECK_SIGMAS`] standard deviations along the worst-determined position
/// direction. Below it the cost is much flatter than the covariance says (two solutions
/// about to merge) and the covariance would understate the error.
pub const MIN_LINEARITY_RATIO: f64 = 0.5;

/// Largest accepted ratio of the actual rise of χ² to the predicted `k²` (see
/// [`MIN_LINEARITY_RATIO`]). Above it the cost is far from quadratic within the stated
/// uncertainty: the solution sits near a degenerate configuration, where the error is not
/// Gaussian and a nearby second solution can take over. Measured at σ = 1 mrad: on random
/// three-point problems 93 % have a ratio of 0.5–1.5 (the 99 % ellipsoid covers 99.0 % of
/// their errors), those at 4–30 are covered 90 %, those above 30 only 53 %; three
/// landmarks on a 20 m circle with the rig 2 m off the P3P danger cylinder give 1.3–2.2
/// (covered 97 %), 0.2 m off it 37 and more (covered 23 % before this check); landmarks
/// 10 km away give 0.999.
pub const MAX_LINEARITY_RATIO: f64 = 30.0;

/// Initial Levenberg–Marquardt damping (relative to the diagonal of the normal matrix).
const INITIAL_DAMPING: f64 = 1e-4;
/// Smallest damping: below this the step is pure Gauss–Newton to rounding.
const MIN_DAMPING: f64 = 1e-12;
/// Largest damping before the iteration gives up on finding a decrease.
const MAX_DAMPING: f64 = 1e12;
/// Factor by which the damping shrinks after an accepted step and grows after a rejection.
const DAMPING_FACTOR: f64 = 10.0;
/// Relative change of the cost treated as rounding noise when accepting a step (the cost is
/// a sum of many terms; near the minimum a good step can look like a 1e-16 increase).
const COST_ROUNDING: f64 = 1e-13;
/// Floor of a diagonal entry used for damping, relative to the largest diagonal entry, so a
/// zero diagonal entry still gets damped.
const MIN_DAMPING_DIAGONAL_RATIO: f64 = 1e-12;

/// Robust loss applied to the angular residual magnitude `x = |rᵢ|` (radians).
///
/// The solver minimises `Σᵢ ρ(xᵢ)/σᵢ²` by iteratively reweighted Gauss–Newton with the
/// weights `ω(x) = ρ'(x)/x`; once the steps are smaller than the loss scale it switches to
/// the curvature-corrected matrix (`ρ''` along each residual, clamped at zero) for
/// quadratic final convergence. See `docs/refine_pose.md`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RobustLoss {
    /// Least squares: `ρ(x) = x²/2`, `ω = 1`.
    None,
    /// Huber: quadratic up to `scale_rad`, linear beyond (`ω = min(1, k/x)`, `k` the
    /// scale). Convex; outliers keep a bounded influence.
    Huber {
        /// Where the loss turns linear (radians), typically 2–3 σ.
        scale_rad: f64,
    },
    /// Cauchy: `ρ(x) = (k²/2)·ln(1 + x²/k²)`, `ω = 1/(1 + x²/k²)`. Redescending: the
    /// influence of gross outliers vanishes, but the cost is not convex, so start near the
    /// solution.
    Cauchy {
        /// Scale of the loss (radians), typically 1–3 σ.
        scale_rad: f64,
    },
}

impl RobustLoss {
    /// The loss `ρ(x)`, the IRLS weight `ω(x) = ρ'(x)/x` and the clamped curvature
    /// `max(ρ''(x), 0)` of a residual magnitude `x ≥ 0`.
    #[inline]
    fn evaluate(&self, x: f64) -> (f64, f64, f64) {
        match *self {
            Self::None => (0.5 * x * x, 1.0, 1.0),
            Self::Huber { scale_rad: k } => {
                if x <= k {
                    (0.5 * x * x, 1.0, 1.0)
                } else {
                    (k * (x - 0.5 * k), k / x, 0.0)
                }
            }
            Self::Cauchy { scale_rad: k } => {
                let z = (x / k) * (x / k);
                let weight = 1.0 / (1.0 + z);
                let curvature = ((1.0 - z) * weight * weight).max(0.0);
                (0.5 * k * k * z.ln_1p(), weight, curvature)
            }
        }
    }

    /// The scale of the loss (radians), `None` for least squares.
    fn scale_rad(&self) -> Option<f64> {
        match *self {
            Self::None => None,
            Self::Huber { scale_rad } | Self::Cauchy { scale_rad } => Some(scale_rad),
        }
    }

    /// True when the scale (if any) is finite and positive.
    fn is_valid(&self) -> bool {
        match *self {
            Self::None => true,
            Self::Huber { scale_rad } | Self::Cauchy { scale_rad } => {
                scale_rad.is_finite() && scale_rad > 0.0
            }
        }
    }
}

/// Options of [`refine_pose`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineOptions {
    /// Standard deviation of the angular noise per tangent axis (radians), for observations
    /// without their own σ. Scales the covariance; does not change the solution without a
    /// robust loss. Default [`DEFAULT_SIGMA_RAD`].
    pub sigma_rad: f64,
    /// Robust loss. Default [`RobustLoss::None`].
    pub loss: RobustLoss,
    /// Iteration budget (linear solves, rejected steps included). Zero evaluates the
    /// covariance at the initial pose without moving it (then `converged` is false).
    /// Default [`DEFAULT_MAX_ITERATIONS`].
    pub max_iterations: usize,
    /// Convergence threshold on the step (radians): attitude change and position change
    /// divided by the RMS range of the points. Default [`DEFAULT_STEP_TOLERANCE_RAD`].
    pub step_tolerance_rad: f64,
    /// When the budget runs out before convergence: return the best pose found with
    /// `converged: false` (true) or fail with [`RefineError::NoConvergence`] (false, the
    /// default).
    pub accept_unconverged: bool,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            sigma_rad: DEFAULT_SIGMA_RAD,
            loss: RobustLoss::None,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            step_tolerance_rad: DEFAULT_STEP_TOLERANCE_RAD,
            accept_unconverged: false,
        }
    }
}

/// The result of [`refine_pose`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefinedPose {
    /// The refined `world_from_rig`.
    pub world_from_rig: Pose,
    /// Covariance of `[δp (m), δθ (rad)]`, world frame, with the perturbation
    /// `world_from_rig = (exp(δθ)·R̂, p̂ + δp)`: `(Σᵢ ωᵢ Jᵢᵀ Jᵢ / σᵢ²)⁻¹` at the solution.
    pub covariance: Matrix6<f64>,
    /// Iterations used (linear solves, rejected steps included).
    pub iterations: usize,
    /// Root mean square of the exact angles between observed and predicted directions over
    /// all observations, outliers included (radians, unweighted).
    pub rms_residual_rad: f64,
    /// True when the step tolerance was met within the budget.
    pub converged: bool,
}

/// Why [`refine_pose`] failed.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum RefineError {
    /// Fewer than [`MIN_CORRESPONDENCES`] correspondences.
    #[error("need at least {MIN_CORRESPONDENCES} correspondences, got {0}")]
    TooFewCorrespondences(usize),
    /// The input slices have different lengths.
    #[error("mismatched lengths: {rays} rays, {points} points, {sigmas} sigmas")]
    LengthMismatch {
        /// Number of rays.
        rays: usize,
        /// Number of points.
        points: usize,
        /// Number of per-observation σ (equal to `rays` when none were given).
        sigmas: usize,
    },
    /// The initial pose has a non-finite entry.
    #[error("the initial pose is not finite")]
    NonFiniteInitialPose,
    /// A ray has a non-finite origin or direction.
    #[error("ray {0} is not finite")]
    NonFiniteRay(usize),
    /// A world point is not finite.
    #[error("point {0} is not finite")]
    NonFinitePoint(usize),
    /// A ray has a zero direction.
    #[error("ray {0} has a zero direction")]
    ZeroDirection(usize),
    /// A per-observation σ is not finite and positive.
    #[error("sigma {value} of observation {index} is not finite and positive")]
    InvalidSigma {
        /// Index of the observation.
        index: usize,
        /// The offending value (radians).
        value: f64,
    },
    /// An option is out of range (`sigma_rad` and loss scales must be finite and positive,
    /// the step tolerance finite and non-negative).
    #[error("invalid option: {0}")]
    InvalidOptions(&'static str),
    /// A world point is at (within [`MIN_POINT_DISTANCE_M`] of) the origin of its ray at the
    /// initial pose.
    #[error("point {0} is at the origin of its ray")]
    PointAtRayOrigin(usize),
    /// The normal equations are rank-deficient at the solution: the geometry does not
    /// determine the pose (e.g. all points on one line), the covariance is undefined.
    #[error("rank-deficient normal equations: the geometry does not determine the pose")]
    RankDeficient,
    /// The covariance does not describe the cost: `k` = [`LINEARITY_CHECK_SIGMAS`] standard
    /// deviations from the solution along the worst-determined position direction, χ²
    /// rises by `rise_ratio · k²` (the covariance predicts `k²`) with `rise_ratio` outside
    /// [[`MIN_LINEARITY_RATIO`], [`MAX_LINEARITY_RATIO`]]. The geometry nearly fails to
    /// determine the pose (for three points: the rig near the P3P danger cylinder) and a
    /// first-order covariance would be dishonest.
    #[error(
        "weakly determined pose: χ² rises by {rise_ratio:.2} × the k² the covariance predicts (near a degenerate configuration)"
    )]
    WeaklyDetermined {
        /// The smaller of the two rises (either side), divided by `k²`.
        rise_ratio: f64,
    },
    /// The iteration budget ran out before the step tolerance was met (and
    /// [`RefineOptions::accept_unconverged`] is false).
    #[error("no convergence after {iterations} iterations (rms residual {rms_residual_rad} rad)")]
    NoConvergence {
        /// Iterations used.
        iterations: usize,
        /// RMS angular residual of the best pose found (radians).
        rms_residual_rad: f64,
    },
}

/// Refines `world_from_rig` by minimising angular residuals over all correspondences, every
/// observation with the σ of the options.
///
/// `rays_in_rig[i]` is the observation of `points_in_world[i]`: its origin is the centre of
/// the camera that saw it in the rig frame (all zero for a central camera) and its direction
/// the observed bearing (normalised here, so any non-zero length will do). See the
/// [module documentation](self) for the residual, the parameterisation and the covariance.
///
/// # Units
/// Metres for points, ray origins and positions; radians for σ, loss scales and residuals.
///
/// # Errors
/// See [`RefineError`]: too few or mismatched inputs, non-finite values, a point at its ray
/// origin, degenerate geometry (rank-deficient normal equations) or no convergence.
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Translation3, Vector3};
/// use vgps_geometry::geometry::{Pose, Ray};
/// use vgps_geometry::solvers::refine_pose::{refine_pose, RefineOptions};
///
/// let truth = Pose::from_parts(
///     Translation3::new(10.0, -4.0, 1.5),
///     Rotation3::from_euler_angles(0.1, -0.2, 1.0),
/// );
/// let points = [
///     Vector3::new(40.0, 5.0, 3.0),
///     Vector3::new(-20.0, 30.0, 8.0),
///     Vector3::new(15.0, -35.0, 0.0),
///     Vector3::new(-30.0, -25.0, 12.0),
///     Vector3::new(12.0, 2.0, 25.0),
/// ];
/// // A central camera: rays from the rig origin towards the points.
/// let rays: Vec<Ray> = points
///     .iter()
///     .map(|x| Ray::try_new(Vector3::zeros(), truth.inverse_transform_vector(&(x - truth.translation.vector))).unwrap())
///     .collect();
/// // Start 0.5 m and about 3° away.
/// let start = Pose::from_parts(
///     Translation3::new(10.3, -4.4, 1.5),
///     Rotation3::from_euler_angles(0.13, -0.2, 1.03),
/// );
/// let refined = refine_pose(&start, &rays, &points, &RefineOptions::default()).unwrap();
/// assert!(refined.converged);
/// assert!((refined.world_from_rig.translation.vector - truth.translation.vector).norm() < 1e-9);
/// assert!(refined.rms_residual_rad < 1e-12);
/// // One-pixel bearings from five points 30 m away: centimetre-to-decimetre position σ.
/// let sigma_east = refined.covariance[(0, 0)].sqrt();
/// assert!(sigma_east > 0.005 && sigma_east < 0.5);
/// ```
pub fn refine_pose(
    initial: &Pose,
    rays_in_rig: &[Ray],
    points_in_world: &[Vector3<f64>],
    options: &RefineOptions,
) -> Result<RefinedPose, RefineError> {
    refine(initial, rays_in_rig, points_in_world, None, options)
}

/// [`refine_pose`] with one angular standard deviation per observation (radians, per
/// tangent axis), for rays of unequal quality (sub-pixel corners next to hand-picked
/// vertices, cameras of different resolution). `options.sigma_rad` is not used.
///
/// # Errors
/// As [`refine_pose`], plus [`RefineError::InvalidSigma`] and a length mismatch of
/// `sigmas_rad`.
pub fn refine_pose_with_sigmas(
    initial: &Pose,
    rays_in_rig: &[Ray],
    points_in_world: &[Vector3<f64>],
    sigmas_rad: &[f64],
    options: &RefineOptions,
) -> Result<RefinedPose, RefineError> {
    refine(
        initial,
        rays_in_rig,
        points_in_world,
        Some(sigmas_rad),
        options,
    )
}

/// The cost, gradient and Gauss–Newton normal matrix at one pose.
struct Linearization {
    /// `Σ ωᵢ Jᵢᵀ Jᵢ / σᵢ²`: the information matrix whose inverse is the covariance.
    normal: Matrix6<f64>,
    /// The Gauss–Newton matrix of the robust cost used for the steps:
    /// `Σ Jᵢᵀ (ωᵢ (I − r̂r̂ᵀ) + max(ρ''ᵢ, 0) r̂r̂ᵀ) Jᵢ / σᵢ²` (equal to `normal` without a robust
    /// loss).
    step_normal: Matrix6<f64>,
    /// `Σ ωᵢ Jᵢᵀ rᵢ / σᵢ²`.
    gradient: Vector6<f64>,
    /// `Σ ρ(|rᵢ|) / σᵢ²`.
    cost: f64,
    /// `Σ θᵢ²` of the exact angles.
    sum_sq_angle: f64,
}

/// The first steps shared by [`residual`] and [`residual_value`]: the unit direction
/// `u = v/|v|`, its tangent coordinates `s = T·u` at `direction`, and the angle θ between
/// them.
struct ResidualParts {
    len: f64,
    u: Vector3<f64>,
    tangent: Matrix2x3<f64>,
    s: Vector2<f64>,
    sin: f64,
    c: f64,
    angle: f64,
}

#[inline(always)]
fn residual_parts(direction: &Vector3<f64>, v: &Vector3<f64>) -> Option<ResidualParts> {
    let len = v.norm();
    if !(len > MIN_POINT_DISTANCE_M && len.is_finite()) {
        return None;
    }
    let u = v / len;
    let (t1, t2) = tangent_basis(direction);
    let tangent = Matrix2x3::from_rows(&[t1.transpose(), t2.transpose()]);
    let s = tangent * u;
    let sin = s.norm();
    let c = direction.dot(&u);
    let angle = if c > 0.0 && sin < ASIN_SERIES_LIMIT {
        // asin series (error below 1e-18 relative here): avoids atan2 for the common case.
        let s2 = sin * sin;
        sin * (1.0 + s2 * (1.0 / 6.0 + s2 * (3.0 / 40.0 + s2 * (5.0 / 112.0))))
    } else {
        sin.atan2(c)
    };
    Some(ResidualParts {
        len,
        u,
        tangent,
        s,
        sin,
        c,
        angle,
    })
}

/// The residual of one observation and its Jacobian with respect to `vᵢ` (rig frame), or
/// `None` when `vᵢ` is too short (the point sits on the ray origin) or not finite.
///
/// Returns `(r, ∂r/∂v, θ)` with `r = θ·ŝ`, the log map of `u` at `d` in the tangent basis.
#[inline]
fn residual(
    direction: &Vector3<f64>,
    v: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x3<f64>, f64)> {
    let ResidualParts {
        len,
        u,
        tangent,
        s,
        sin,
        c,
        angle,
    } = residual_parts(direction, v)?;
    let (r, dr_du) = if angle <= SMALL_ANGLE_RAD {
        // r = φ(c)·s with φ = θ/sin θ: ∂r/∂u = φ·T + φ'(c)·s·dᵀ,
        // φ'(c) = −(sin θ − θ cos θ)/sin³ θ = −(1/3 + 2θ²/15 + …).
        let (phi, dphi_dc) = if angle < SERIES_ANGLE_RAD {
            let a2 = angle * angle;
            (1.0 + a2 / 6.0, -(1.0 / 3.0 + 2.0 * a2 / 15.0))
        } else {
            (angle / sin, -(sin - angle * c) / (sin * sin * sin))
        };
        (s * phi, tangent * phi + s * direction.transpose() * dphi_dc)
    } else if sin > ANTIPODE_SIN_TOLERANCE {
        // r = θ·ŝ: ∂r/∂u = ŝ·eᵀ + (θ/sin θ)·(I − ŝŝᵀ)·T, with e = (c·u − d)/sin θ the unit
        // direction in which θ grows. The tangential part (second term) is dropped within
        // ANTIPODAL_MARGIN_RAD of π, where θ/sin θ diverges.
        let s_hat = s / sin;
        let grow = (u * c - direction) / sin;
        let mut dr_du = s_hat * grow.transpose();
        if angle < std::f64::consts::PI - ANTIPODAL_MARGIN_RAD {
            let perpendicular = nalgebra::Matrix2::identity() - s_hat * s_hat.transpose();
            dr_du += perpendicular * tangent * (angle / sin);
        }
        (s_hat * angle, dr_du)
    } else {
        // At the antipode (to rounding) the residual direction is undefined and θ = π is a
        // maximum: no useful derivative.
        let along = s.try_normalize(0.0).unwrap_or_else(Vector2::x);
        (along * angle, Matrix2x3::zeros())
    };
    // ∂u/∂v = (I − u uᵀ)/|v|.
    let dr_du_u = dr_du * u;
    let dr_dv = (dr_du - dr_du_u * u.transpose()) / len;
    Some((r, dr_dv, angle))
}

/// The residual of [`residual`] alone (same operations, bit for bit), without its
/// Jacobian: for [`linearity_ratio`], which evaluates three poses per observation.
#[inline]
fn residual_value(direction: &Vector3<f64>, v: &Vector3<f64>) -> Option<Vector2<f64>> {
    let ResidualParts { s, sin, angle, .. } = residual_parts(direction, v)?;
    Some(if angle <= SMALL_ANGLE_RAD {
        let phi = if angle < SERIES_ANGLE_RAD {
            1.0 + angle * angle / 6.0
        } else {
            angle / sin
        };
        s * phi
    } else if sin > ANTIPODE_SIN_TOLERANCE {
        (s / sin) * angle
    } else {
        s.try_normalize(0.0).unwrap_or_else(Vector2::x) * angle
    })
}

/// The ray's direction scaled to unit length, or `None` when its norm is too small or not
/// finite.
#[inline]
fn unit_direction(ray: &Ray) -> Option<Vector3<f64>> {
    let norm = ray.direction.norm();
    (norm > MIN_DIRECTION_NORM && norm.is_finite()).then(|| ray.direction / norm)
}

/// The residual of [`observation`] alone (see [`residual_value`]).
#[inline]
fn observation_residual(
    rig_from_world: &Matrix3<f64>,
    position: &Vector3<f64>,
    ray: &Ray,
    point: &Vector3<f64>,
) -> Option<Vector2<f64>> {
    let direction = unit_direction(ray)?;
    let v = rig_from_world * (point - position) - ray.origin;
    residual_value(&direction, &v)
}

/// Residual, Jacobian (2×6, w.r.t. `[δp, δθ]`) and exact angle of one observation, given
/// `rig_from_world = Rᵀ` and the rig position; `None` if the point is on the ray origin.
#[inline]
fn observation(
    rig_from_world: &Matrix3<f64>,
    position: &Vector3<f64>,
    ray: &Ray,
    point: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x6, f64)> {
    let direction = unit_direction(ray)?;
    let q = point - position;
    let v = rig_from_world * q - ray.origin;
    let (r, dr_dv, angle) = residual(&direction, &v)?;
    // v = Rᵀ·exp(−δθ)·(q − δp) − o  ⇒  ∂v/∂δp = −Rᵀ,  ∂v/∂δθ = Rᵀ·[q]×.
    // With B = ∂r/∂v·Rᵀ (rows bₖᵀ): bₖᵀ·[q]×·δθ = (bₖ × q)·δθ, so J = [−B | rows (bₖ × q)ᵀ].
    let b = dr_dv * rig_from_world;
    let b0 = b.row(0).transpose();
    let b1 = b.row(1).transpose();
    let c0 = b0.cross(&q);
    let c1 = b1.cross(&q);
    let jacobian = Matrix2x6::from_rows(&[
        RowVector6::new(-b0.x, -b0.y, -b0.z, c0.x, c0.y, c0.z),
        RowVector6::new(-b1.x, -b1.y, -b1.z, c1.x, c1.y, c1.z),
    ]);
    Some((r, jacobian, angle))
}

/// The angular residual of one observation at a pose and its Jacobian with respect to the
/// perturbation `[δp, δθ]` of `world_from_rig = (exp(δθ)·R, p + δp)`.
///
/// The residual is `r = θ·s/|s|` in the tangent basis [`crate::geometry::tangent_basis`]
/// of the observed direction (see the [module documentation](self)); its norm is `θ`, the
/// angle between the observed and predicted directions. Returns `None` when the point is within
/// [`MIN_POINT_DISTANCE_M`] of the ray origin, the direction is zero, or a value is not
/// finite.
///
/// # Units
/// Residual in radians; Jacobian in rad/m (first three columns) and
/// rad/rad (last three).
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::{Pose, Ray};
/// use vgps_geometry::solvers::refine_pose::angular_residual;
/// // Rig at the origin looking along +x; the point is 1 mrad off the ray, sideways.
/// let ray = Ray::try_new(Vector3::zeros(), Vector3::x()).unwrap();
/// let (r, j) = angular_residual(&Pose::identity(), &ray, &Vector3::new(10.0, 0.01, 0.0)).unwrap();
/// assert!((r.norm() - 1e-3).abs() < 1e-9);
/// // Moving the rig 1 cm along +y cancels it: the residual derivative is −1/range per metre.
/// assert!(((j * nalgebra::Vector6::new(0.0, 0.01, 0.0, 0.0, 0.0, 0.0)).norm() - 1e-3).abs() < 1e-8);
/// ```
pub fn angular_residual(
    world_from_rig: &Pose,
    ray: &Ray,
    point_in_world: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x6)> {
    let rig_from_world = world_from_rig.rotation.matrix().transpose();
    let (r, j, _) = observation(
        &rig_from_world,
        &world_from_rig.translation.vector,
        ray,
        point_in_world,
    )?;
    (r.iter().all(|x| x.is_finite()) && j.iter().all(|x| x.is_finite())).then_some((r, j))
}

/// Adds `w·JᵀJ` to the lower triangle of `m` (the upper one is filled once at the end).
#[inline]
fn accumulate_lower(m: &mut Matrix6<f64>, j: &Matrix2x6, w: f64) {
    for col in 0..6 {
        let a0 = j[(0, col)] * w;
        let a1 = j[(1, col)] * w;
        for row in col..6 {
            m[(row, col)] += a0 * j[(0, row)] + a1 * j[(1, row)];
        }
    }
}

/// Evaluates the cost and linearises at `pose` (rotation given as a unit quaternion).
/// Returns `None` when a point sits on its ray origin or the cost is not finite.
fn linearize(
    rotation: &UnitQuaternion<f64>,
    position: &Vector3<f64>,
    rays: &[Ray],
    points: &[Vector3<f64>],
    sigmas: Option<&[f64]>,
    options: &RefineOptions,
) -> Option<Linearization> {
    let rig_from_world = rotation.to_rotation_matrix().into_inner().transpose();
    let mut normal = Matrix6::zeros();
    let mut step_normal = Matrix6::zeros();
    let mut gradient = Vector6::zeros();
    let mut cost = 0.0;
    let mut sum_sq_angle = 0.0;
    for (i, (ray, point)) in rays.iter().zip(points).enumerate() {
        let sigma = sigmas.map_or(options.sigma_rad, |s| s[i]);
        let information = 1.0 / (sigma * sigma);
        let (r, jacobian, angle) = observation(&rig_from_world, position, ray, point)?;
        let x = r.norm();
        let (rho, weight, curvature) = options.loss.evaluate(x);
        cost += information * rho;
        sum_sq_angle += angle * angle;
        let w = weight * information;
        accumulate_lower(&mut normal, &jacobian, w);
        gradient += jacobian.tr_mul(&r) * w;
        // Second-order correction of the robust loss along the residual: the Hessian of
        // ρ(|r|) w.r.t. r is ω·(I − r̂r̂ᵀ) + ρ''·r̂r̂ᵀ. IRLS alone (ρ'' replaced by ω)
        // converges only linearly once residuals sit beyond the loss scale.
        let correction = (curvature - weight) * information;
        if x > 0.0 && correction != 0.0 {
            let jr = jacobian.tr_mul(&(r / x));
            for col in 0..6 {
                let a = jr[col] * correction;
                for row in col..6 {
                    step_normal[(row, col)] += a * jr[row];
                }
            }
        }
    }
    normal.fill_upper_triangle_with_lower_triangle();
    step_normal.fill_upper_triangle_with_lower_triangle();
    step_normal += normal;
    if cost.is_finite() && sum_sq_angle.is_finite() {
        Some(Linearization {
            normal,
            step_normal,
            gradient,
            cost,
            sum_sq_angle,
        })
    } else {
        None
    }
}

/// Checks the inputs; returns the RMS range of the points from the initial rig position
/// (metres), the scale that turns a position step into an angle.
fn validate(
    initial: &Pose,
    rays: &[Ray],
    points: &[Vector3<f64>],
    sigmas: Option<&[f64]>,
    options: &RefineOptions,
) -> Result<f64, RefineError> {
    let n_sigmas = sigmas.map_or(rays.len(), <[f64]>::len);
    if rays.len() != points.len() || n_sigmas != rays.len() {
        return Err(RefineError::LengthMismatch {
            rays: rays.len(),
            points: points.len(),
            sigmas: n_sigmas,
        });
    }
    if rays.len() < MIN_CORRESPONDENCES {
        return Err(RefineError::TooFewCorrespondences(rays.len()));
    }
    if sigmas.is_none() && !(options.sigma_rad.is_finite() && options.sigma_rad > 0.0) {
        return Err(RefineError::InvalidOptions(
            "sigma_rad must be finite and positive",
        ));
    }
    if !options.loss.is_valid() {
        return Err(RefineError::InvalidOptions(
            "the robust loss scale must be finite and positive",
        ));
    }
    if !(options.step_tolerance_rad.is_finite() && options.step_tolerance_rad >= 0.0) {
        return Err(RefineError::InvalidOptions(
            "step_tolerance_rad must be finite and non-negative",
        ));
    }
    let position = initial.translation.vector;
    if !is_finite(&position) || initial.rotation.matrix().iter().any(|x| !x.is_finite()) {
        return Err(RefineError::NonFiniteInitialPose);
    }
    let rig_from_world = initial.rotation.inverse();
    let mut sum_sq_range = 0.0;
    for (i, (ray, point)) in rays.iter().zip(points).enumerate() {
        if !is_finite(&ray.origin) || !is_finite(&ray.direction) {
            return Err(RefineError::NonFiniteRay(i));
        }
        if !is_finite(point) {
            return Err(RefineError::NonFinitePoint(i));
        }
        let norm = ray.direction.norm();
        if !(norm > MIN_DIRECTION_NORM && norm.is_finite()) {
            return Err(RefineError::ZeroDirection(i));
        }
        if let Some(s) = sigmas
            && !(s[i].is_finite() && s[i] > 0.0)
        {
            return Err(RefineError::InvalidSigma {
                index: i,
                value: s[i],
            });
        }
        let q = point - position;
        let v = rig_from_world * q - ray.origin;
        // Written to also reject a NaN length.
        if v.norm().partial_cmp(&MIN_POINT_DISTANCE_M) != Some(std::cmp::Ordering::Greater) {
            return Err(RefineError::PointAtRayOrigin(i));
        }
        sum_sq_range += q.norm_squared();
    }
    let rms_range = (sum_sq_range / rays.len() as f64).sqrt();
    Ok(rms_range.max(MIN_POINT_DISTANCE_M))
}

/// The covariance `normal⁻¹`, or `None` when `normal` is numerically rank-deficient.
///
/// The matrix is first scaled to unit diagonal, `C = D^{-1/2}·N·D^{-1/2}`; its smallest
/// eigenvalue (≤ 1) lies within a factor 6 of `1 / trace(C⁻¹)`, which is the reciprocal
/// condition estimate compared to [`MIN_RECIPROCAL_CONDITION`].
fn covariance_of(normal: &Matrix6<f64>) -> Option<Matrix6<f64>> {
    let mut inv_sqrt_diag = Vector6::zeros();
    for i in 0..6 {
        let d = normal[(i, i)];
        if !(d.is_finite() && d > 0.0) {
            return None;
        }
        inv_sqrt_diag[i] = 1.0 / d.sqrt();
    }
    let scaled = Matrix6::from_fn(|i, j| normal[(i, j)] * inv_sqrt_diag[i] * inv_sqrt_diag[j]);
    let inverse = Cholesky::new(scaled)?.inverse();
    let trace = inverse.trace();
    if !(trace.is_finite() && trace > 0.0 && 1.0 / trace >= MIN_RECIPROCAL_CONDITION) {
        return None;
    }
    let covariance = Matrix6::from_fn(|i, j| inverse[(i, j)] * inv_sqrt_diag[i] * inv_sqrt_diag[j]);
    covariance
        .iter()
        .all(|x| x.is_finite())
        .then_some(covariance)
}

/// The rise of χ² (with the loss weights frozen at the solution: the quadratic model whose
/// Hessian is the inverse covariance) at `k` = [`LINEARITY_CHECK_SIGMAS`] standard
/// deviations along the worst-determined position direction, divided by the `k²` the
/// covariance predicts; the smaller of the two sides. `0` when a perturbed pose cannot be
/// evaluated.
///
/// The displacement is the profile direction: the position moves by `k·σ` along the
/// largest eigenvector `v` of the position block `C_pp`, the attitude follows its
/// conditional mean, `δ = (k/√λ)·C[:, 0..3]·v`, so that `δᵀC⁻¹δ = k²` exactly.
fn linearity_ratio(
    rotation: &UnitQuaternion<f64>,
    position: &Vector3<f64>,
    covariance: &Matrix6<f64>,
    rays: &[Ray],
    points: &[Vector3<f64>],
    sigmas: Option<&[f64]>,
    options: &RefineOptions,
) -> f64 {
    let position_block = covariance.fixed_view::<3, 3>(0, 0).into_owned();
    let eigen = position_block.symmetric_eigen();
    let worst = eigen.eigenvalues.imax();
    let lambda = eigen.eigenvalues[worst];
    if !(lambda > 0.0 && lambda.is_finite()) {
        return 0.0;
    }
    let v = eigen.eigenvectors.column(worst).into_owned();
    let delta: Vector6<f64> =
        covariance.fixed_view::<6, 3>(0, 0) * v * (LINEARITY_CHECK_SIGMAS / lambda.sqrt());
    // One pass: each residual at the solution (its loss weight, frozen) and at ±δ.
    let poses = [1.0, -1.0].map(|sign: f64| {
        let step = delta * sign;
        let moved =
            UnitQuaternion::from_scaled_axis(Vector3::new(step[3], step[4], step[5])) * rotation;
        (
            moved.to_rotation_matrix().into_inner().transpose(),
            position + Vector3::new(step[0], step[1], step[2]),
        )
    });
    let rig_from_world = rotation.to_rotation_matrix().into_inner().transpose();
    let mut rise = [0.0; 2];
    for (i, (ray, point)) in rays.iter().zip(points).enumerate() {
        let sigma = sigmas.map_or(options.sigma_rad, |s| s[i]);
        let Some(r) = observation_residual(&rig_from_world, position, ray, point) else {
            return 0.0;
        };
        let base = r.norm_squared();
        let information = options.loss.evaluate(base.sqrt()).1 / (sigma * sigma);
        for (rise, (moved_rig_from_world, moved_position)) in rise.iter_mut().zip(&poses) {
            let Some(r) = observation_residual(moved_rig_from_world, moved_position, ray, point)
            else {
                return 0.0;
            };
            *rise += information * (r.norm_squared() - base);
        }
    }
    let ratio = rise[0].min(rise[1]) / (LINEARITY_CHECK_SIGMAS * LINEARITY_CHECK_SIGMAS);
    if ratio.is_finite() { ratio } else { 0.0 }
}

/// The damped Gauss–Newton step `−(M + λ·diag(N))⁻¹ g`, with `M` the IRLS matrix `N` or,
/// with `second_order`, the curvature-corrected one; `None` if the damped matrix is not
/// positive definite.
fn damped_step(lin: &Linearization, damping: f64, second_order: bool) -> Option<Vector6<f64>> {
    // Damping on the diagonal of the (positive definite) information matrix: the corrected
    // matrix may have lost curvature along residuals beyond the loss scale.
    let max_diagonal = lin.normal.diagonal().max();
    let floor = MIN_DAMPING_DIAGONAL_RATIO * max_diagonal;
    let mut damped = if second_order {
        lin.step_normal
    } else {
        lin.normal
    };
    for i in 0..6 {
        damped[(i, i)] += damping * lin.normal[(i, i)].max(floor);
    }
    let step = Cholesky::new(damped)?.solve(&(-lin.gradient));
    step.iter().all(|x| x.is_finite()).then_some(step)
}

fn refine(
    initial: &Pose,
    rays: &[Ray],
    points: &[Vector3<f64>],
    sigmas: Option<&[f64]>,
    options: &RefineOptions,
) -> Result<RefinedPose, RefineError> {
    let range_scale = validate(initial, rays, points, sigmas, options)?;
    let mut rotation = UnitQuaternion::from_rotation_matrix(&initial.rotation);
    let mut position = initial.translation.vector;
    // Validation checked every point against its ray origin at this pose; only a
    // non-finite cost (overflowing inputs) can fail here.
    let mut lin = linearize(&rotation, &position, rays, points, sigmas, options)
        .ok_or(RefineError::NonFiniteInitialPose)?;
    let mut damping = INITIAL_DAMPING;
    let mut iterations = 0;
    let mut converged = false;
    let mut moved = false;
    // Robust losses start with IRLS steps (the set of residuals beyond the loss scale is
    // still changing, and the corrected matrix can be nearly singular far from the
    // solution) and switch to the curvature-corrected matrix once an accepted step changes
    // the residuals by less than the loss scale.
    let switch_below = options.loss.scale_rad().unwrap_or(0.0);
    let mut second_order = false;
    while iterations < options.max_iterations {
        iterations += 1;
        let Some(step) = damped_step(&lin, damping, second_order) else {
            damping *= DAMPING_FACTOR;
            if damping > MAX_DAMPING {
                break;
            }
            continue;
        };
        let delta_p = Vector3::new(step[0], step[1], step[2]);
        let delta_theta = Vector3::new(step[3], step[4], step[5]);
        let step_rad = delta_theta.norm().max(delta_p.norm() / range_scale);
        let small = step_rad <= options.step_tolerance_rad;
        let mut candidate_rotation = UnitQuaternion::from_scaled_axis(delta_theta) * rotation;
        candidate_rotation.renormalize_fast();
        let candidate_position = position + delta_p;
        match linearize(
            &candidate_rotation,
            &candidate_position,
            rays,
            points,
            sigmas,
            options,
        ) {
            // Accept any step that does not raise the cost beyond its rounding error.
            Some(candidate) if candidate.cost <= lin.cost * (1.0 + COST_ROUNDING) => {
                rotation = candidate_rotation;
                position = candidate_position;
                lin = candidate;
                moved = true;
                second_order |= step_rad < switch_below;
                damping = (damping / DAMPING_FACTOR).max(MIN_DAMPING);
            }
            _ if !small => {
                damping *= DAMPING_FACTOR;
                if damping > MAX_DAMPING {
                    break;
                }
            }
            _ => {}
        }
        if small {
            converged = true;
            break;
        }
    }
    let covariance = covariance_of(&lin.normal).ok_or(RefineError::RankDeficient)?;
    let rise_ratio = linearity_ratio(
        &rotation,
        &position,
        &covariance,
        rays,
        points,
        sigmas,
        options,
    );
    if !(MIN_LINEARITY_RATIO..=MAX_LINEARITY_RATIO).contains(&rise_ratio) {
        return Err(RefineError::WeaklyDetermined { rise_ratio });
    }
    let rms_residual_rad = (lin.sum_sq_angle / rays.len() as f64).sqrt();
    if !converged && !options.accept_unconverged {
        return Err(RefineError::NoConvergence {
            iterations,
            rms_residual_rad,
        });
    }
    let world_from_rig = if moved {
        Pose::from_parts(Translation3::from(position), Rotation3::from(rotation))
    } else {
        *initial
    };
    Ok(RefinedPose {
        world_from_rig,
        covariance,
        iterations,
        rms_residual_rad,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{random_unit_vector, rng};
    use rand::RngExt;

    /// The residual and ∂r/∂v agree with central differences, including large angles.
    #[test]
    fn residual_jacobian_matches_finite_differences() {
        let mut r = rng(11);
        let h = 1e-6;
        for _ in 0..500 {
            let d = random_unit_vector(&mut r);
            // Small angles (series), the closed form, the radial/tangential form.
            let angle =
                [1e-5, 5e-4, 2e-3, 0.3, 1.0, 3.0][r.random_range(0..6)] * r.random_range(0.5..1.0);
            let axis = d.cross(&random_unit_vector(&mut r)).normalize();
            let v = Rotation3::from_scaled_axis(axis * angle) * d * r.random_range(0.5..50.0);
            let (res, jac, theta) = residual(&d, &v).unwrap();
            assert!((theta - angle).abs() < 1e-9);
            assert!((res.norm() - angle).abs() < 1e-9);
            for k in 0..3 {
                let mut e = Vector3::zeros();
                e[k] = h * v.norm();
                let plus = residual(&d, &(v + e)).unwrap().0;
                let minus = residual(&d, &(v - e)).unwrap().0;
                let numeric = (plus - minus) / (2.0 * h * v.norm());
                let analytic = jac.column(k);
                assert!(
                    (numeric - analytic).norm() < 1e-6 * (1.0 + analytic.norm()),
                    "column {k}: {numeric} vs {analytic}"
                );
            }
        }
    }

    #[test]
    fn losses_have_consistent_weights() {
        // ω(x) = ρ'(x)/x, checked by central differences.
        for loss in [
            RobustLoss::None,
            RobustLoss::Huber { scale_rad: 0.01 },
            RobustLoss::Cauchy { scale_rad: 0.01 },
        ] {
            for x in [1e-4, 5e-3, 0.02, 0.3] {
                let h = 1e-7;
                let d = (loss.evaluate(x + h).0 - loss.evaluate(x - h).0) / (2.0 * h);
                let w = loss.evaluate(x).1;
                assert!(
                    (d / x - w).abs() < 1e-5,
                    "{loss:?} at {x}: {} vs {w}",
                    d / x
                );
            }
        }
    }

    #[test]
    fn antipodal_residual_is_finite() {
        let d = random_unit_vector(&mut rng(3));
        let (res, jac, theta) = residual(&d, &(-d * 5.0)).unwrap();
        assert!((res.norm() - std::f64::consts::PI).abs() < 1e-12);
        assert!(jac.iter().all(|x| *x == 0.0));
        assert!((theta - std::f64::consts::PI).abs() < 1e-12);
        // Just inside the margin: finite, radial part only (unit gradient of θ).
        let (t1, _) = tangent_basis(&d);
        let near = -d + t1 * 1e-3;
        let (res, jac, theta) = residual(&d, &near).unwrap();
        assert!(res.iter().chain(jac.iter()).all(|x| x.is_finite()));
        assert!((res.norm() - theta).abs() < 1e-15);
        let gradient_of_theta = jac.transpose() * (res / res.norm()) * near.norm();
        assert!((gradient_of_theta.norm() - 1.0).abs() < 1e-6);
    }
}
