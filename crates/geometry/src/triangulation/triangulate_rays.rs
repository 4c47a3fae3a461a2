//! Ku, Ho & Sarma's projector-sum triangulation of n ≥ 2 rays, with an origin-invariant
//! first-order covariance; its inverse-variance weighted form; its online accumulator.

use super::{
    MIN_PARALLAX_SIGMAS, MIN_RAYS, MIN_RECIPROCAL_CONDITION, Sym3, TriangulationError,
    UNIT_DIRECTION_TOLERANCE,
};
use crate::geometry::{Ray, is_finite};
use nalgebra::{Matrix3, Vector3};

/// One bearing observation of a landmark: a ray and its noise levels.
///
/// # Noise model
/// The true observer position is `ray.origin − δ` with `δ ~ N(0, σ_pos² I₃)` (isotropic), and
/// the true direction is `ray.direction` rotated by a small angle whose two components
/// perpendicular to the ray are independent `N(0, σ_ang²)` — the model of
/// [`crate::synthetic::perturb_bearing`]. Position and angular errors are independent, and
/// independent between observations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayObservation {
    /// Observer position (origin, metres) and unit direction towards the landmark.
    pub ray: Ray,
    /// Standard deviation of the observer position, per axis (metres, ≥ 0).
    pub sigma_pos_m: f64,
    /// Standard deviation of the direction, per axis perpendicular to it (radians, ≥ 0).
    pub sigma_ang_rad: f64,
}

/// A triangulated landmark with its first-order covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangulatedPoint {
    /// The estimated landmark position (metres, the rays' frame).
    pub point: Vector3<f64>,
    /// Covariance of `point` (m², the rays' frame), to first order in the noise; independent
    /// of where the frame's origin is.
    pub covariance: Matrix3<f64>,
    /// Number of rays used.
    pub n_obs: usize,
    /// Sine and cosine of the largest angle between the first ray and any other ray (the
    /// angle itself: [`max_parallax_rad`](Self::max_parallax_rad)).
    pub max_parallax_sin_cos: (f64, f64),
}

impl TriangulatedPoint {
    /// The largest angle between the first ray and any other ray (radians, `[0, π]`). The
    /// largest angle between any two rays lies between this and twice this.
    ///
    /// Computed on demand from [`max_parallax_sin_cos`](Self::max_parallax_sin_cos): the
    /// `atan2` would otherwise be a large share of a small triangulation's cost.
    #[inline]
    pub fn max_parallax_rad(&self) -> f64 {
        self.max_parallax_sin_cos
            .0
            .atan2(self.max_parallax_sin_cos.1)
    }
}

/// The sine and cosine of an angle.
type SinCos = (f64, f64);

/// Sine and cosine of the angle between two unit vectors.
#[inline]
fn sin_cos_between(a: &Vector3<f64>, b: &Vector3<f64>) -> SinCos {
    (a.cross(b).norm(), a.dot(b))
}

/// The projector-sum landmark estimate of Ku, Ho & Sarma (eq. (2)), with an origin-invariant
/// first-order covariance.
///
/// With `Pᵢ = I − uᵢuᵢᵀ` (`xᵢ` the ray origin = observer, `uᵢ` its unit direction):
///
/// ```text
/// A = Σ Pᵢ,    p = A⁻¹ Σ Pᵢ xᵢ,
/// Σ_p = A⁻¹ [ Σ (σ_pos,ᵢ² + σ_ang,ᵢ² dᵢ²) Pᵢ ] A⁻¹,    dᵢ = |p − xᵢ|.
/// ```
///
/// `p` minimises the sum of squared distances `Σ |Pᵢ(p − xᵢ)|²` to the lines. A position
/// error `δᵢ` and a direction error `εᵢ ⊥ uᵢ` move the residual of ray `i` by
/// `Pᵢδᵢ + dᵢεᵢ`: the angular error acts through the *range* `dᵢ`, so `Σ_p` does not change
/// when the frame is translated. The paper's eq. (7)/(9) put `xᵢᵀΣ(γᵢ)xᵢ` there instead — a
/// term that grows with the distance of the observer from the world origin (see
/// `docs/triangulation.md`). Each ray's weight is 1; [`triangulate_rays_weighted()`] weights
/// by the inverse residual variance, which is better when the ranges differ a lot.
///
/// Cost: two passes over the rays and one 3×3 inverse (see the
/// `triangulation/` criterion benchmarks). Computed about the first ray's origin, so ECEF
/// coordinates lose no precision.
///
/// # Errors
/// - [`TriangulationError::TooFewRays`] for fewer than [`MIN_RAYS`] observations.
/// - [`TriangulationError::InvalidRay`] / [`TriangulationError::InvalidNoise`] for a
///   non-finite origin, a non-unit direction, or a negative or non-finite σ.
/// - [`TriangulationError::IllConditioned`] when `A` is singular or nearly so (all rays
///   parallel, see [`MIN_RECIPROCAL_CONDITION`]).
/// - [`TriangulationError::BehindRay`] when the point is not in front of every ray.
/// - [`TriangulationError::NonFinite`] on overflow.
///
/// # Units
/// Metres for positions and `sigma_pos_m`, radians for `sigma_ang_rad`, m² for the
/// covariance.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::Ray;
/// use vgps_geometry::triangulation::{triangulate_rays, RayObservation};
/// let lamp = Vector3::new(3.0, 9.0, 7.0);
/// let obs: Vec<RayObservation> = [0.0, 4.0, 8.0, 12.0]
///     .iter()
///     .map(|&x| {
///         let o = Vector3::new(x, 0.0, 2.0);
///         RayObservation {
///             ray: Ray::try_new(o, lamp - o).unwrap(),
///             sigma_pos_m: 0.05,
///             sigma_ang_rad: 1e-3,
///         }
///     })
///     .collect();
/// let est = triangulate_rays(&obs).unwrap();
/// assert!((est.point - lamp).norm() < 1e-9);
/// assert_eq!(est.n_obs, 4);
/// // Standard deviations of a few centimetres, largest along the line of sight.
/// let sd: Vec<f64> = (0..3).map(|k| est.covariance[(k, k)].sqrt()).collect();
/// assert!(sd.iter().all(|&s| s > 0.01 && s < 0.2), "{sd:?}");
/// ```
///
/// # References
/// - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", eq. (2) (the
///   estimator), eq. (4) (position noise); the angular term is re-derived here.
pub fn triangulate_rays(obs: &[RayObservation]) -> Result<TriangulatedPoint, TriangulationError> {
    // Two rays, the commonest small case, in closed form.
    match <&[RayObservation; 2]>::try_from(obs) {
        Ok(pair) => two_rays(pair),
        Err(_) => projector_sum::<false>(obs),
    }
}

/// Largest `||u|² − 1|` of a direction for which two rays are triangulated in closed form
/// ([`two_rays`]); a direction from [`Ray::try_new`] is within a few `f64::EPSILON`.
const CLOSED_FORM_MAX_UNIT_DEVIATION: f64 = 1e-14;

/// [`triangulate_rays`] for exactly two rays, in closed form (no 3×3 inverse).
///
/// With unit directions `u₀, u₁`, `c = u₀·u₁`, `n = u₀ × u₁` (`|n|² = 1 − c²`) and the
/// second origin relative to the first, `y = x₁ − x₀`, the normal matrix
/// `A = P₀ + P₁ = 2I − u₀u₀ᵀ − u₁u₁ᵀ` has the eigenvalues `1 − c`, `1 + c` (in the plane of
/// the directions) and `2` (along `n`), and
///
/// ```text
/// A⁻¹ = (u₀u₀ᵀ + u₁u₁ᵀ + ½ nnᵀ) / |n|²,
/// q = A⁻¹ P₁ y = [ u₀ (u₀·y − c u₁·y) + ½ n (n·y) ] / |n|²      (u₁·P₁y = 0),
/// A⁻¹ P₀ A⁻¹ = (u₁u₁ᵀ + ¼ nnᵀ) / |n|²,   A⁻¹ P₁ A⁻¹ = (u₀u₀ᵀ + ¼ nnᵀ) / |n|²,
/// Σ_p = A⁻¹ (s₀P₀ + s₁P₁) A⁻¹ = [ s₀ u₁u₁ᵀ + s₁ u₀u₀ᵀ + ¼ (s₀ + s₁) nnᵀ ] / |n|²,
/// ```
///
/// (`A⁻¹P₀A⁻¹ = (A⁻¹v)(A⁻¹v)ᵀ + (A⁻¹n̂)(A⁻¹n̂)ᵀ` with `v = (u₁ − c u₀)/|n|`, the unit
/// vector of the plane perpendicular to `u₀`, `A⁻¹v = u₁/|n|` and `A⁻¹n̂ = n̂/2`), `q` being
/// the midpoint of the common perpendicular of the two lines and `sᵢ` as in
/// [`triangulate_rays`]. The closed form needs unit directions: it is taken when both are
/// unit to within [`CLOSED_FORM_MAX_UNIT_DEVIATION`] in `|uᵢ|²` (as [`Ray::try_new`] makes
/// them), after which the factor `1 − εᵢ/2 + 3εᵢ²/8` (`|uᵢ|² = 1 + εᵢ`; the series of
/// `(1 + εᵢ)^(−1/2)`) makes them unit to rounding without a square root. Directions merely
/// within the accepted [`UNIT_DIRECTION_TOLERANCE`] go to the general code, which uses them
/// as given, so that both paths treat every input alike. The result is the general code's to
/// rounding: relative differences of about 10⁻¹⁶ times the condition number of `A`, tested
/// against a plain implementation and against 50-digit arithmetic.
///
/// Any input this path does not accept outright (an invalid ray or σ, a point behind a
/// ray, near-parallel rays, overflow) goes to the general code's exact path, which reports
/// the first offender exactly as for any other number of rays.
#[inline(always)]
fn two_rays(obs: &[RayObservation; 2]) -> Result<TriangulatedPoint, TriangulationError> {
    let [o0, o1] = obs;
    let (u0, u1) = (o0.ray.direction, o1.ray.direction);
    let (e0, e1) = (u0.norm_squared() - 1.0, u1.norm_squared() - 1.0);
    // Finite only when both origins are finite (and their difference does not overflow).
    let y = o1.ray.origin - o0.ray.origin;
    if !(e0.abs() <= CLOSED_FORM_MAX_UNIT_DEVIATION
        && e1.abs() <= CLOSED_FORM_MAX_UNIT_DEVIATION
        && (y.x + y.y + y.z).is_finite())
    {
        return projector_sum_exact(obs);
    }
    let unit = |u: Vector3<f64>, e: f64| u * (1.0 + e * (0.375 * e - 0.5));
    let (v0, v1) = (unit(u0, e0), unit(u1, e1));
    let c = v0.dot(&v1);
    let n = v0.cross(&v1);
    let nn = n.norm_squared();
    // The general solver's conditioning test `det A ≥ MIN_RECIPROCAL_CONDITION · tr A · e₂(A)`
    // with `det A = 2|n|²`, `tr A = 4`, `e₂(A) = |n|² + 4` (sums of the eigenvalues' products).
    // (False for a NaN `nn`.)
    let conditioned = nn >= 2.0 * MIN_RECIPROCAL_CONDITION * (nn + 4.0);
    if !conditioned {
        return projector_sum_exact(obs);
    }
    let inv = 1.0 / nn;
    let (a0, a1, an) = (v0.dot(&y), v1.dot(&y), n.dot(&y));
    let q = (v0 * (a0 - c * a1) + n * (0.5 * an)) * inv;
    let r1 = q - y;
    let (sp0, sa0, sp1, sa1) = (
        o0.sigma_pos_m,
        o0.sigma_ang_rad,
        o1.sigma_pos_m,
        o1.sigma_ang_rad,
    );
    let s0 = sp0 * sp0 + sa0 * sa0 * q.norm_squared();
    let s1 = sp1 * sp1 + sa1 * sa1 * r1.norm_squared();
    // What `check_noise` and the in-front test require of each observation.
    if !(sp0 >= 0.0
        && sa0 >= 0.0
        && sp1 >= 0.0
        && sa1 >= 0.0
        && sp0 * sp0 + sa0 * sa0 < f64::INFINITY
        && sp1 * sp1 + sa1 * sa1 < f64::INFINITY
        && s0 + s1 < f64::INFINITY
        && q.dot(&u0) > 0.0
        && r1.dot(&u1) > 0.0)
    {
        return projector_sum_exact(obs);
    }
    // Σ_p = a v₁ᵀ + b v₀ᵀ + d nᵀ with a = (s₀/|n|²) v₁, b = (s₁/|n|²) v₀, d = ((s₀ + s₁)/(4|n|²)) n.
    let (a, b, d) = (
        v1 * (s0 * inv),
        v0 * (s1 * inv),
        n * (0.25 * (s0 + s1) * inv),
    );
    let entry = |i: usize, j: usize| a[i] * v1[j] + b[i] * v0[j] + d[i] * n[j];
    let (xx, xy, xz, yy, yz, zz) = (
        entry(0, 0),
        entry(0, 1),
        entry(0, 2),
        entry(1, 1),
        entry(1, 2),
        entry(2, 2),
    );
    let point = o0.ray.origin + q;
    if !((point.x + point.y + point.z) + (xx + xy + xz + yy + yz + zz)).is_finite() {
        return projector_sum_exact(obs);
    }
    check_parallax_sigma(
        sa0.max(sa1),
        TriangulatedPoint {
            point,
            covariance: Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz),
            n_obs: 2,
            max_parallax_sin_cos: (nn.sqrt(), c),
        },
    )
}

/// [`triangulate_rays`] itself. With `EXACT = false` (the hot path) the inputs are validated
/// by a few running extrema and sums that hold for every valid input; when one of those tests
/// fails, the whole computation is redone by [`projector_sum_exact`] with `EXACT = true`,
/// which checks every observation in order instead and so returns the first offender (or,
/// when none offends, the same result as the hot path would have).
#[inline(always)]
fn projector_sum<const EXACT: bool>(
    obs: &[RayObservation],
) -> Result<TriangulatedPoint, TriangulationError> {
    let first = validate_count(obs)?;
    let reference = first.ray.origin;
    let u0 = first.ray.direction;
    // Pass 1: A = Σ Pᵢ = nI − Σ uᵢuᵢᵀ and b = Σ Pᵢyᵢ = Σ yᵢ − Σ uᵢ(uᵢ·yᵢ) with yᵢ = xᵢ − x₀
    // (six and three scalars in locals), the ray farthest from the first (by index), and
    // the largest deviation of |uᵢ|² from 1.
    let (r0x, r0y, r0z) = (reference.x, reference.y, reference.z);
    let (u0x, u0y, u0z) = (u0.x, u0.y, u0.z);
    let (mut axx, mut axy, mut axz, mut ayy, mut ayz, mut azz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut bx, mut by, mut bz) = (0.0, 0.0, 0.0);
    let mut far_cos = 1.0;
    let mut far = 0;
    let mut unit_deviation: f64 = 0.0;
    for (index, o) in obs.iter().enumerate() {
        let (ux, uy, uz) = (o.ray.direction.x, o.ray.direction.y, o.ray.direction.z);
        let (xx, yy, zz) = (ux * ux, uy * uy, uz * uz);
        let deviation = ((xx + yy + zz) - 1.0).abs();
        unit_deviation = if deviation > unit_deviation {
            deviation
        } else {
            unit_deviation
        };
        let cos = ux * u0x + uy * u0y + uz * u0z;
        if cos < far_cos {
            far_cos = cos;
            far = index;
        }
        let (dx, dy, dz) = (
            o.ray.origin.x - r0x,
            o.ray.origin.y - r0y,
            o.ray.origin.z - r0z,
        );
        axx += xx;
        axy += ux * uy;
        axz += ux * uz;
        ayy += yy;
        ayz += uy * uz;
        azz += zz;
        let t = ux * dx + uy * dy + uz * dz;
        bx += dx - ux * t;
        by += dy - uy * t;
        bz += dz - uz * t;
    }
    if EXACT {
        if let Some(e) = first_invalid_ray(obs) {
            return Err(e);
        }
    } else if !(unit_deviation <= UNIT_DIRECTION_TOLERANCE
        && ((bx + by + bz) + (axx + ayy + azz)).is_finite())
    {
        // Both tests pass only when every ray is valid ([`check_ray`]): a non-unit direction
        // raises the deviation (a NaN one, which the maximum skips, makes a diagonal of A
        // NaN), a non-finite origin makes its offset yᵢ, then uᵢ·yᵢ and b non-finite. Valid
        // rays fail them only when the sums overflow: the exact path then finds no invalid
        // ray and carries on.
        return projector_sum_exact(obs);
    }
    let uu = Sym3 {
        xx: axx,
        xy: axy,
        xz: axz,
        yy: ayy,
        yz: ayz,
        zz: azz,
    };
    let a = Sym3::diagonal(obs.len() as f64).minus(&uu);
    let (a_inv, q) = solve(&a, &Vector3::new(bx, by, bz))?;
    // Pass 2: ranges at the estimate, middle term of the sandwich
    // M = Σ sᵢPᵢ = (Σ sᵢ) I − Σ sᵢuᵢuᵢᵀ, the extreme σs and the smallest range along a ray.
    let mut m_uu = Sym3::default();
    let mut s_sum = 0.0;
    let mut range_min = f64::INFINITY;
    let (mut sp_min, mut sa_min, mut sp_max, mut sa_max): (f64, f64, f64, f64) =
        (0.0, 0.0, 0.0, 0.0);
    for o in obs {
        let u = o.ray.direction;
        let r = q - (o.ray.origin - reference);
        let (sp, sa) = (o.sigma_pos_m, o.sigma_ang_rad);
        sp_min = if sp < sp_min { sp } else { sp_min };
        sa_min = if sa < sa_min { sa } else { sa_min };
        sp_max = if sp > sp_max { sp } else { sp_max };
        sa_max = if sa > sa_max { sa } else { sa_max };
        let s = sp * sp + sa * sa * r.norm_squared();
        let range = r.dot(&u);
        range_min = if range < range_min { range } else { range_min };
        s_sum += s;
        m_uu.add_outer(s, &u);
    }
    if EXACT {
        if let Some(e) = first_noise_or_behind(obs, &reference, &q) {
            return Err(e);
        }
    } else if !(sp_min >= 0.0
        && sa_min >= 0.0
        && sp_max * sp_max + sa_max * sa_max < f64::INFINITY
        && s_sum < f64::INFINITY
        && range_min > 0.0)
    {
        // These tests pass only when every σ ≥ 0 with σ_pos² + σ_ang² finite
        // ([`check_noise`]) and every range > 0: a NaN σ, which the extrema skip, makes its
        // sᵢ and the sum NaN; a NaN range comes from a non-finite offset, which makes sᵢ NaN
        // or infinite. Valid input fails them only when the largest σs, or Σ sᵢ, overflow:
        // the exact path then finds no offender and carries on.
        return projector_sum_exact(obs);
    }
    let m = Sym3::diagonal(s_sum).minus(&m_uu);
    let far_direction = obs.get(far).map_or(u0, |o| o.ray.direction);
    let parallax = sin_cos_between(&u0, &far_direction);
    check_parallax_sigma(
        sa_max,
        finish(reference, q, &a_inv, &m, obs.len(), parallax)?,
    )
}

/// [`projector_sum`] with every observation checked in order (the cold path of
/// [`triangulate_rays`]).
#[cold]
#[inline(never)]
fn projector_sum_exact(obs: &[RayObservation]) -> Result<TriangulatedPoint, TriangulationError> {
    projector_sum::<true>(obs)
}

/// The error for the first invalid ray, if any.
fn first_invalid_ray(obs: &[RayObservation]) -> Option<TriangulationError> {
    obs.iter()
        .enumerate()
        .find_map(|(index, o)| check_ray(index, &o.ray).err())
}

/// The error for the first observation, in order, with invalid noise or with the point at
/// `q` (relative to `reference`) not in front of it, if any.
fn first_noise_or_behind(
    obs: &[RayObservation],
    reference: &Vector3<f64>,
    q: &Vector3<f64>,
) -> Option<TriangulationError> {
    obs.iter()
        .enumerate()
        .find_map(|(index, o)| residual_variance(index, o, reference, q).err())
}

/// The inverse-variance weighted projector sum: one re-weighting step of
/// [`triangulate_rays()`].
///
/// The residual of ray `i` has covariance `sᵢPᵢ` with `sᵢ = σ_pos,ᵢ² + σ_ang,ᵢ²dᵢ²`, so the
/// best linear unbiased estimate weights ray `i` by `wᵢ = 1/sᵢ`:
///
/// ```text
/// p₀ = triangulate_rays (weights 1),   dᵢ = |p₀ − xᵢ|,   wᵢ = 1 / (σ_pos,ᵢ² + σ_ang,ᵢ² dᵢ²),
/// A_w = Σ wᵢPᵢ,   p = A_w⁻¹ Σ wᵢPᵢxᵢ,   Σ_p = A_w⁻¹ [ Σ wᵢ² sᵢ(p) Pᵢ ] A_w⁻¹  (≈ A_w⁻¹).
/// ```
///
/// Estimating the ranges from `p₀` changes `p` only at second order. The weights make no
/// difference when every ray has the same `sᵢ`; with angular noise and ranges from 5 m to
/// 80 m the weighted estimate is markedly tighter (see `docs/triangulation.md`).
///
/// # Errors
/// As [`triangulate_rays()`], plus [`TriangulationError::InvalidNoise`] when an observation
/// has `σ_pos = σ_ang = 0` (an infinite weight).
///
/// # Units
/// As [`triangulate_rays()`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::Ray;
/// use vgps_geometry::triangulation::{triangulate_rays, triangulate_rays_weighted, RayObservation};
/// let lamp = Vector3::new(0.0, 10.0, 6.0);
/// let obs: Vec<RayObservation> = [-60.0, -5.0, 5.0, 60.0]
///     .iter()
///     .map(|&x| {
///         let o = Vector3::new(x, 0.0, 2.0);
///         RayObservation { ray: Ray::try_new(o, lamp - o).unwrap(), sigma_pos_m: 0.02, sigma_ang_rad: 2e-3 }
///     })
///     .collect();
/// let plain = triangulate_rays(&obs).unwrap();
/// let weighted = triangulate_rays_weighted(&obs).unwrap();
/// assert!((weighted.point - lamp).norm() < 1e-9);
/// // Down-weighting the two far rays shrinks the uncertainty.
/// assert!(weighted.covariance.trace() < plain.covariance.trace());
/// ```
///
/// # References
/// - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", eq. (2); the
///   weighting is the Gauss–Markov estimate for the re-derived residual covariance.
pub fn triangulate_rays_weighted(
    obs: &[RayObservation],
) -> Result<TriangulatedPoint, TriangulationError> {
    let first = validate_count(obs)?;
    let reference = first.ray.origin;
    let (a0, b0, parallax) = accumulate_normal(obs, &reference)?;
    let (_, q0) = solve(&a0, &b0)?;
    // Pass 2: weights from the ranges at the unweighted estimate.
    let mut a = Sym3::default();
    let mut b = Vector3::zeros();
    for (index, o) in obs.iter().enumerate() {
        let w = weight(index, o, &reference, &q0)?;
        let y = o.ray.origin - reference;
        let p = Sym3::projector(&o.ray.direction, w);
        a.add_assign(&p);
        b += p.mul_vec(&y);
    }
    let (a_inv, q) = solve(&a, &b)?;
    // Pass 3: the sandwich with the weights used and the variances at the final estimate.
    let mut m = Sym3::default();
    for (index, o) in obs.iter().enumerate() {
        let w = weight(index, o, &reference, &q0)?;
        let s = residual_variance(index, o, &reference, &q)?;
        m.add_assign(&Sym3::projector(&o.ray.direction, w * w * s));
    }
    check_parallax(obs, finish(reference, q, &a_inv, &m, obs.len(), parallax)?)
}

/// Refuses a point whose parallax is below [`MIN_PARALLAX_SIGMAS`] times the largest
/// angular σ of the observations.
#[inline(always)]
fn check_parallax(
    obs: &[RayObservation],
    point: TriangulatedPoint,
) -> Result<TriangulatedPoint, TriangulationError> {
    let sigma_rad = obs.iter().map(|o| o.sigma_ang_rad).fold(0.0, f64::max);
    check_parallax_sigma(sigma_rad, point)
}

/// Relative margin of the `atan2`-free parallax test over rounding.
const PARALLAX_TEST_MARGIN: f64 = 1e-12;

/// [`check_parallax`] with the largest angular σ given. The parallax θ = atan2(s, c) (from
/// the sine and cosine of [`TriangulatedPoint::max_parallax_sin_cos`]) is at least
/// `s/√(s² + c²)` (θ ≥ sin θ) and at least π/2 when `c ≤ 0`: either bound clearing the
/// threshold accepts the point without the `atan2`, which is only evaluated near the
/// threshold (where its exact value decides) and for the error.
#[inline(always)]
fn check_parallax_sigma(
    sigma_rad: f64,
    point: TriangulatedPoint,
) -> Result<TriangulatedPoint, TriangulationError> {
    // (A NaN σ, impossible after validation, fails every comparison below: accepted, as
    // before.)
    if sigma_rad <= 0.0 {
        return Ok(point);
    }
    let threshold = MIN_PARALLAX_SIGMAS * sigma_rad;
    let (s, c) = point.max_parallax_sin_cos;
    let clearly_wide = if c <= 0.0 {
        threshold <= std::f64::consts::FRAC_PI_2
    } else {
        s * s >= threshold * threshold * (s * s + c * c) * (1.0 + PARALLAX_TEST_MARGIN)
    };
    if clearly_wide {
        return Ok(point);
    }
    let parallax_rad = point.max_parallax_rad();
    if parallax_rad < threshold {
        return Err(TriangulationError::WeakParallax {
            parallax_rad,
            sigma_rad,
        });
    }
    Ok(point)
}

/// Online form of [`triangulate_rays()`]: add rays one at a time in O(1) and solve at any
/// time, without storing the rays.
///
/// Accumulates, about the first ray's origin `x₀` (`yᵢ = xᵢ − x₀`), the normal matrix
/// `A = Σ Pᵢ`, `b = Σ Pᵢyᵢ`, and the moments that give the covariance's middle term at any
/// point `q` in closed form:
///
/// ```text
/// Σ (σ_pos² + σ_ang² |q − yᵢ|²) Pᵢ
///   = Σ (σ_pos² + σ_ang²|yᵢ|²) Pᵢ + |q|² Σ σ_ang² Pᵢ − 2 Σₖ qₖ Σ σ_ang² yᵢₖ Pᵢ .
/// ```
///
/// [`RaySum::solve`] gives the same point and covariance as [`triangulate_rays()`] on the same
/// rays (to rounding), except that it cannot check that the point is in front of *every*
/// ray (it keeps no rays): check new rays against the current estimate as you associate them.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::Ray;
/// use vgps_geometry::triangulation::{RayObservation, RaySum};
/// let lamp = Vector3::new(2.0, 7.0, 5.0);
/// let mut sum = RaySum::new();
/// for x in [0.0, 3.0, 6.0] {
///     let o = Vector3::new(x, 0.0, 2.0);
///     let ray = Ray::try_new(o, lamp - o).unwrap();
///     sum.add(&RayObservation { ray, sigma_pos_m: 0.1, sigma_ang_rad: 1e-3 }).unwrap();
/// }
/// let est = sum.solve().unwrap();
/// assert!((est.point - lamp).norm() < 1e-9);
/// assert_eq!(est.n_obs, 3);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RaySum {
    n: usize,
    reference: Vector3<f64>,
    first_direction: Vector3<f64>,
    /// The direction making the largest angle with `first_direction` so far, and its cosine.
    far_direction: Vector3<f64>,
    far_cos: f64,
    a: Sym3,
    b: Vector3<f64>,
    m0: Sym3,
    m_ang: Sym3,
    m_lin: [Sym3; 3],
}

impl RaySum {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of rays added.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when no ray has been added.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Adds one observation in O(1).
    ///
    /// # Errors
    /// [`TriangulationError::InvalidRay`] / [`TriangulationError::InvalidNoise`] (with
    /// `index` = the number of rays added before) for a non-finite origin, a non-unit
    /// direction or a negative or non-finite σ; the accumulator is then left unchanged.
    pub fn add(&mut self, o: &RayObservation) -> Result<(), TriangulationError> {
        let index = self.n;
        check_ray(index, &o.ray)?;
        let (sp2, sa2) = check_noise(index, o)?;
        let u = o.ray.direction;
        if self.n == 0 {
            self.reference = o.ray.origin;
            self.first_direction = u;
            self.far_direction = u;
            self.far_cos = 1.0;
        }
        let y = o.ray.origin - self.reference;
        let cos = u.dot(&self.first_direction);
        if cos < self.far_cos {
            self.far_cos = cos;
            self.far_direction = u;
        }
        let p = Sym3::projector(&u, 1.0);
        self.a.add_assign(&p);
        self.b += p.mul_vec(&y);
        self.m0.add_scaled(sp2 + sa2 * y.norm_squared(), &p);
        self.m_ang.add_scaled(sa2, &p);
        for k in 0..3 {
            self.m_lin[k].add_scaled(sa2 * y[k], &p);
        }
        self.n += 1;
        Ok(())
    }

    /// The projector-sum estimate and its covariance from the rays added so far.
    ///
    /// # Errors
    /// [`TriangulationError::TooFewRays`], [`TriangulationError::IllConditioned`] or
    /// [`TriangulationError::NonFinite`], as [`triangulate_rays()`] (no in-front check).
    pub fn solve(&self) -> Result<TriangulatedPoint, TriangulationError> {
        if self.n < MIN_RAYS {
            return Err(TriangulationError::TooFewRays(self.n));
        }
        let (a_inv, q) = solve(&self.a, &self.b)?;
        let mut m = self.m0;
        m.add_scaled(q.norm_squared(), &self.m_ang);
        for k in 0..3 {
            m.add_scaled(-2.0 * q[k], &self.m_lin[k]);
        }
        let parallax = sin_cos_between(&self.first_direction, &self.far_direction);
        finish(self.reference, q, &a_inv, &m, self.n, parallax)
    }
}

/// At least [`MIN_RAYS`] observations; returns the first.
#[inline]
fn validate_count(obs: &[RayObservation]) -> Result<&RayObservation, TriangulationError> {
    match obs {
        [first, _, ..] => Ok(first),
        _ => Err(TriangulationError::TooFewRays(obs.len())),
    }
}

#[inline(always)]
fn check_ray(index: usize, ray: &Ray) -> Result<(), TriangulationError> {
    let uu = ray.direction.norm_squared();
    if (uu - 1.0).abs() <= UNIT_DIRECTION_TOLERANCE && is_finite(&ray.origin) {
        Ok(())
    } else {
        Err(TriangulationError::InvalidRay { index })
    }
}

/// `(σ_pos², σ_ang²)` of a valid observation.
#[inline(always)]
fn check_noise(index: usize, o: &RayObservation) -> Result<(f64, f64), TriangulationError> {
    let (sp, sa) = (o.sigma_pos_m, o.sigma_ang_rad);
    if sp >= 0.0 && sa >= 0.0 && (sp * sp + sa * sa) < f64::INFINITY {
        Ok((sp * sp, sa * sa))
    } else {
        Err(TriangulationError::InvalidNoise { index })
    }
}

/// Pass 1: `A = Σ Pᵢ`, `b = Σ Pᵢyᵢ` and the largest angle to the first ray; validates
/// every ray.
#[inline(always)]
fn accumulate_normal(
    obs: &[RayObservation],
    reference: &Vector3<f64>,
) -> Result<(Sym3, Vector3<f64>, SinCos), TriangulationError> {
    let u0 = obs[0].ray.direction;
    let mut far_cos = 1.0;
    let mut far = u0;
    let mut a = Sym3::default();
    let mut b = Vector3::zeros();
    for (index, o) in obs.iter().enumerate() {
        check_ray(index, &o.ray)?;
        let u = o.ray.direction;
        let cos = u.dot(&u0);
        if cos < far_cos {
            far_cos = cos;
            far = u;
        }
        let y = o.ray.origin - reference;
        let p = Sym3::projector(&u, 1.0);
        a.add_assign(&p);
        b += p.mul_vec(&y);
    }
    Ok((a, b, sin_cos_between(&u0, &far)))
}

/// `(A⁻¹, A⁻¹b)` after the conditioning check.
#[inline(always)]
fn solve(a: &Sym3, b: &Vector3<f64>) -> Result<(Sym3, Vector3<f64>), TriangulationError> {
    let (cof, det, e2) = a.cofactors();
    // det / (tr A · e₂) ≥ MIN_RECIPROCAL_CONDITION without the division (the ratio is only
    // formed on the error path); false for NaN, and a finite positive det is required.
    let bound = a.trace() * e2;
    if !(det > 0.0 && det < f64::INFINITY && det >= MIN_RECIPROCAL_CONDITION * bound) {
        let reciprocal_condition = det / bound;
        if !a.is_finite() || !(b.x + b.y + b.z).is_finite() {
            return Err(TriangulationError::NonFinite);
        }
        return Err(TriangulationError::IllConditioned {
            reciprocal_condition: if reciprocal_condition.is_finite() {
                reciprocal_condition
            } else {
                0.0
            },
        });
    }
    let a_inv = cof.scale(1.0 / det);
    let q = a_inv.mul_vec(b);
    Ok((a_inv, q))
}

/// The offset `q − yᵢ` from ray `i`'s origin to a local point `q`, and the residual variance
/// `sᵢ = σ_pos² + σ_ang² |q − yᵢ|²` there, after the noise check.
#[inline(always)]
fn offset_and_variance(
    index: usize,
    o: &RayObservation,
    reference: &Vector3<f64>,
    q: &Vector3<f64>,
) -> Result<(Vector3<f64>, f64), TriangulationError> {
    let (sp2, sa2) = check_noise(index, o)?;
    let r = q - (o.ray.origin - reference);
    Ok((r, sp2 + sa2 * r.norm_squared()))
}

/// `sᵢ` at a local point `q` ([`offset_and_variance`]), after the in-front check.
#[inline(always)]
fn residual_variance(
    index: usize,
    o: &RayObservation,
    reference: &Vector3<f64>,
    q: &Vector3<f64>,
) -> Result<f64, TriangulationError> {
    let (r, s) = offset_and_variance(index, o, reference, q)?;
    let range_m = r.dot(&o.ray.direction);
    if range_m.is_nan() || range_m <= 0.0 {
        return Err(TriangulationError::BehindRay { index, range_m });
    }
    Ok(s)
}

/// The inverse-variance weight `1/sᵢ` at the local point `q` (no in-front check).
#[inline(always)]
fn weight(
    index: usize,
    o: &RayObservation,
    reference: &Vector3<f64>,
    q: &Vector3<f64>,
) -> Result<f64, TriangulationError> {
    let (_, s) = offset_and_variance(index, o, reference, q)?;
    if s > 0.0 && s < f64::INFINITY {
        Ok(1.0 / s)
    } else {
        Err(TriangulationError::InvalidNoise { index })
    }
}

/// Assembles the result: point back in the world frame, sandwich covariance, finiteness.
#[inline(always)]
fn finish(
    reference: Vector3<f64>,
    q: Vector3<f64>,
    a_inv: &Sym3,
    m: &Sym3,
    n_obs: usize,
    max_parallax_sin_cos: (f64, f64),
) -> Result<TriangulatedPoint, TriangulationError> {
    let point = reference + q;
    let cov = a_inv.sandwich(m);
    if !((point.x + point.y + point.z).is_finite() && cov.is_finite()) {
        return Err(TriangulationError::NonFinite);
    }
    Ok(TriangulatedPoint {
        point,
        covariance: cov.to_matrix(),
        n_obs,
        max_parallax_sin_cos,
    })
}

#[cfg(test)]
mod tests {
    //! [`triangulate_rays`] against a straightforward implementation of its doc comment.
    use super::*;
    use crate::synthetic::rays::RayProblem;
    use crate::synthetic::{random_unit_vector, rng};
    use crate::triangulation::{MIN_PARALLAX_SIGMAS, reciprocal_condition};
    use rand::RngExt;

    /// The estimator written out plainly: projectors as matrices, one check per observation
    /// in the documented order, `A⁻¹` by nalgebra, the parallax by `atan2`.
    fn reference(obs: &[RayObservation]) -> Result<TriangulatedPoint, TriangulationError> {
        if obs.len() < MIN_RAYS {
            return Err(TriangulationError::TooFewRays(obs.len()));
        }
        for (index, o) in obs.iter().enumerate() {
            let u = o.ray.direction;
            if !((u.norm_squared() - 1.0).abs() <= UNIT_DIRECTION_TOLERANCE
                && is_finite(&o.ray.origin))
            {
                return Err(TriangulationError::InvalidRay { index });
            }
        }
        let x0 = obs[0].ray.origin;
        let projector = |u: &Vector3<f64>| Matrix3::identity() - u * u.transpose();
        let mut a = Matrix3::zeros();
        let mut b = Vector3::zeros();
        for o in obs {
            let p = projector(&o.ray.direction);
            a += p;
            b += p * (o.ray.origin - x0);
        }
        let rc = reciprocal_condition(&a);
        // The conditioning test first; what fails it is a singular A or overflow (on which
        // the sum of b's entries is not finite).
        if rc < MIN_RECIPROCAL_CONDITION {
            return Err(if b.sum().is_finite() {
                TriangulationError::IllConditioned {
                    reciprocal_condition: rc,
                }
            } else {
                TriangulationError::NonFinite
            });
        }
        let a_inv = a.try_inverse().ok_or(TriangulationError::NonFinite)?;
        let q = a_inv * b;
        let mut m = Matrix3::zeros();
        for (index, o) in obs.iter().enumerate() {
            let (sp, sa) = (o.sigma_pos_m, o.sigma_ang_rad);
            if !(sp >= 0.0 && sa >= 0.0 && (sp * sp + sa * sa).is_finite()) {
                return Err(TriangulationError::InvalidNoise { index });
            }
            let r = q - (o.ray.origin - x0);
            let range_m = r.dot(&o.ray.direction);
            if range_m.is_nan() || range_m <= 0.0 {
                return Err(TriangulationError::BehindRay { index, range_m });
            }
            m += projector(&o.ray.direction) * (sp * sp + sa * sa * r.norm_squared());
        }
        let covariance = a_inv * m * a_inv;
        let point = x0 + q;
        if !(point.iter().all(|v| v.is_finite()) && covariance.iter().all(|v| v.is_finite())) {
            return Err(TriangulationError::NonFinite);
        }
        let u0 = obs[0].ray.direction;
        let parallax_rad = obs
            .iter()
            .map(|o| {
                u0.cross(&o.ray.direction)
                    .norm()
                    .atan2(u0.dot(&o.ray.direction))
            })
            .fold(0.0, f64::max);
        let sigma_rad = obs.iter().map(|o| o.sigma_ang_rad).fold(0.0, f64::max);
        if sigma_rad > 0.0 && parallax_rad < MIN_PARALLAX_SIGMAS * sigma_rad {
            return Err(TriangulationError::WeakParallax {
                parallax_rad,
                sigma_rad,
            });
        }
        Ok(TriangulatedPoint {
            point,
            covariance,
            n_obs: obs.len(),
            max_parallax_sin_cos: (parallax_rad.sin(), parallax_rad.cos()),
        })
    }

    /// Largest relative difference of the point (about the first observer) and of the
    /// covariance (Frobenius) between two estimates; panics on different parallaxes.
    fn relative_difference(
        obs: &[RayObservation],
        a: &TriangulatedPoint,
        b: &TriangulatedPoint,
    ) -> f64 {
        let x0 = obs[0].ray.origin;
        assert_eq!(a.n_obs, b.n_obs);
        assert!((a.max_parallax_rad() - b.max_parallax_rad()).abs() < 1e-12);
        let dp = (a.point - b.point).norm() / (a.point - x0).norm();
        let dc = (a.covariance - b.covariance).norm() / a.covariance.norm();
        dp.max(dc)
    }

    /// Same variant, same index; the reported values agree to rounding.
    fn assert_same_error(a: TriangulationError, b: TriangulationError) {
        use TriangulationError::*;
        let close = |x: f64, y: f64| x == y || (x - y).abs() <= 1e-9 * x.abs().max(y.abs());
        let same = match (a, b) {
            (TooFewRays(i), TooFewRays(j)) => i == j,
            (InvalidRay { index: i }, InvalidRay { index: j })
            | (InvalidNoise { index: i }, InvalidNoise { index: j }) => i == j,
            (
                BehindRay {
                    index: i,
                    range_m: x,
                },
                BehindRay {
                    index: j,
                    range_m: y,
                },
            ) => i == j && (close(x, y) || (x.is_nan() && y.is_nan()) || x.abs() < 1e-6),
            (IllConditioned { .. }, IllConditioned { .. }) | (NonFinite, NonFinite) => true,
            (
                WeakParallax {
                    parallax_rad: p,
                    sigma_rad: s,
                },
                WeakParallax {
                    parallax_rad: q,
                    sigma_rad: t,
                },
            ) => close(p, q) && s == t,
            _ => false,
        };
        assert!(same, "{a:?} != {b:?}");
    }

    fn noisy(seed: u64, n: usize) -> Vec<RayObservation> {
        let mut r = rng(seed);
        RayProblem::around(&mut r, n, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut r)
    }

    #[test]
    fn matches_the_reference_on_random_problems() {
        let mut r = rng(20_261_122);
        let mut worst: f64 = 0.0;
        let mut solved = 0;
        for k in 0..3_000 {
            let n = 2 + k % 11;
            let mut obs =
                RayProblem::around(&mut r, n, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut r);
            if k % 3 == 0 {
                // Far from the frame's origin (ECEF-like) and with per-ray noise levels.
                let offset = Vector3::new(4.2e6, 1.1e6, 4.6e6);
                for o in &mut obs {
                    o.ray.origin += offset;
                    o.sigma_pos_m = r.random_range(0.0..0.5);
                    o.sigma_ang_rad = r.random_range(0.0..4e-3);
                }
            }
            match (triangulate_rays(&obs), reference(&obs)) {
                (Ok(a), Ok(b)) => {
                    solved += 1;
                    // The general code evaluates the reference's formulas in the same order;
                    // the two-ray closed form rounds differently, by about ε · cond(A).
                    let d = relative_difference(&obs, &a, &b);
                    let scale = if n == 2 {
                        let a_matrix: Matrix3<f64> = obs
                            .iter()
                            .map(|o| {
                                Matrix3::identity() - o.ray.direction * o.ray.direction.transpose()
                            })
                            .sum();
                        (1e-3 / reciprocal_condition(&a_matrix)).max(1.0)
                    } else {
                        1.0
                    };
                    worst = worst.max(d / scale);
                }
                (Err(a), Err(b)) => assert_same_error(a, b),
                (a, b) => panic!("problem {k}: {a:?} vs {b:?}"),
            }
        }
        assert!(worst <= 1e-12, "largest relative difference {worst:e}");
        assert!(solved > 2_900, "{solved} of 3000 solved");
    }

    /// Corrupts observation fields with special values: every validation path, in order.
    #[test]
    fn same_errors_as_the_reference_on_corrupted_inputs() {
        const SPECIAL: [f64; 12] = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1.0,
            0.0,
            -0.0,
            1e308,
            -1e308,
            1.3e154,
            1e-310,
            2.0,
            0.5,
        ];
        let mut r = rng(7);
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..20_000 {
            let n = r.random_range(1..7);
            let mut obs =
                RayProblem::around(&mut r, n, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut r);
            for _ in 0..r.random_range(1..4) {
                let i = r.random_range(0..n);
                let v = SPECIAL[r.random_range(0..SPECIAL.len())];
                let k = r.random_range(0..3);
                match r.random_range(0..9) {
                    0 => obs[i].ray.origin[k] = v,
                    1 => obs[i].ray.direction[k] = v,
                    2 => obs[i].sigma_pos_m = v,
                    3 => obs[i].sigma_ang_rad = v,
                    4 => obs[i].ray.direction = obs[r.random_range(0..n)].ray.direction,
                    5 => obs[i].ray.direction = -obs[r.random_range(0..n)].ray.direction,
                    6 => obs[i].ray.direction *= 1.0 + r.random_range(-2e-6..2e-6),
                    7 => obs[i].ray.origin *= v,
                    _ => obs[i].sigma_ang_rad = r.random_range(0.0..0.3),
                }
            }
            match (triangulate_rays(&obs), reference(&obs)) {
                (Ok(a), Ok(b)) => {
                    seen.insert("Ok");
                    // Rounding differences grow with the condition number (near-parallel
                    // rays are accepted down to MIN_RECIPROCAL_CONDITION).
                    let a_matrix: Matrix3<f64> = obs
                        .iter()
                        .map(|o| {
                            Matrix3::identity() - o.ray.direction * o.ray.direction.transpose()
                        })
                        .sum();
                    let tolerance = 1e-13 / reciprocal_condition(&a_matrix);
                    let d = relative_difference(&obs, &a, &b);
                    assert!(d <= tolerance, "{d:e} > {tolerance:e}: {obs:?}");
                }
                (Err(a), Err(b)) => {
                    seen.insert(
                        format!("{a:?}")
                            .split([' ', '('])
                            .next()
                            .unwrap_or("")
                            .to_owned()
                            .leak(),
                    );
                    assert_same_error(a, b);
                }
                // Near overflow, the sandwich's evaluation order decides whether an
                // intermediate product overflows.
                (Ok(p), Err(TriangulationError::NonFinite))
                | (Err(TriangulationError::NonFinite), Ok(p))
                    if p.covariance.amax() > 1e300 => {}
                (a, b) => panic!("{obs:?}: {a:?} vs {b:?}"),
            }
        }
        // Every outcome was exercised.
        assert_eq!(seen.len(), 8, "{seen:?}");
    }

    #[test]
    fn first_offender_is_reported() {
        use TriangulationError::*;
        let obs = noisy(1, 5);
        assert_eq!(triangulate_rays(&obs[..1]), Err(TooFewRays(1)));
        assert_eq!(triangulate_rays(&[]), Err(TooFewRays(0)));
        let with = |f: &dyn Fn(&mut Vec<RayObservation>)| {
            let mut o = obs.clone();
            f(&mut o);
            triangulate_rays(&o)
        };
        assert_eq!(
            with(&|o| o[3].ray.origin.y = f64::NAN),
            Err(InvalidRay { index: 3 })
        );
        assert_eq!(
            with(&|o| o[0].ray.origin.x = f64::INFINITY),
            Err(InvalidRay { index: 0 })
        );
        assert_eq!(
            with(&|o| o[2].ray.direction *= 1.01),
            Err(InvalidRay { index: 2 })
        );
        assert_eq!(
            with(&|o| {
                o[4].ray.direction.z = f64::NAN;
                o[1].ray.direction.x = f64::NAN;
            }),
            Err(InvalidRay { index: 1 })
        );
        // A bad ray is reported before bad noise at a lower index.
        assert_eq!(
            with(&|o| {
                o[0].sigma_pos_m = -1.0;
                o[4].ray.origin.z = f64::NEG_INFINITY;
            }),
            Err(InvalidRay { index: 4 })
        );
        assert_eq!(
            with(&|o| o[1].sigma_pos_m = -0.1),
            Err(InvalidNoise { index: 1 })
        );
        assert_eq!(
            with(&|o| o[2].sigma_ang_rad = f64::NAN),
            Err(InvalidNoise { index: 2 })
        );
        assert_eq!(
            with(&|o| o[4].sigma_pos_m = f64::INFINITY),
            Err(InvalidNoise { index: 4 })
        );
        assert_eq!(
            with(&|o| {
                o[3].sigma_pos_m = 1e200;
                o[3].sigma_ang_rad = 1e200;
            }),
            Err(InvalidNoise { index: 3 })
        );
        assert!(matches!(
            with(&|o| {
                let u = o[0].ray.direction;
                o.iter_mut().for_each(|x| x.ray.direction = u);
            }),
            Err(IllConditioned { .. })
        ));
        // Ray 2 turned around: the point is behind it (and, the estimate moving, maybe
        // behind no other), and that is reported unless noise is bad before it.
        let behind = with(&|o| o[2].ray.direction = -o[2].ray.direction);
        assert!(matches!(behind, Err(BehindRay { .. })), "{behind:?}");
        assert_same_error(
            behind.unwrap_err(),
            reference(&{
                let mut o = obs.clone();
                o[2].ray.direction = -o[2].ray.direction;
                o
            })
            .unwrap_err(),
        );
    }

    /// The hot path's validation by extrema and sums also fails on some valid inputs; the
    /// exact path must then carry on and give the reference's outcome.
    #[test]
    fn overflowing_extrema_take_the_exact_path() {
        let landmark = Vector3::new(0.0, 0.0, 0.0);
        let mut r = rng(3);
        let mut obs: Vec<RayObservation> = (0..3)
            .map(|_| {
                let u = random_unit_vector(&mut r);
                RayObservation {
                    ray: Ray::try_new(landmark - u * 0.5, u).unwrap(),
                    sigma_pos_m: 0.0,
                    sigma_ang_rad: 0.0,
                }
            })
            .collect();
        // Each σ_pos² + σ_ang² is finite, the largest σ_pos² + the largest σ_ang² is not.
        obs[0].sigma_pos_m = 1.3e154;
        obs[1].sigma_ang_rad = 4e153;
        let (a, b) = (triangulate_rays(&obs), reference(&obs));
        assert!(
            matches!(a, Err(TriangulationError::WeakParallax { .. })),
            "{a:?}"
        );
        assert_same_error(a.unwrap_err(), b.unwrap_err());
        // Observers so far apart that the normal equations' sums overflow.
        let mut far = noisy(5, 3);
        far[1].ray.origin = Vector3::new(1.2e308, 1.2e308, 0.0);
        far[1].ray.direction = Vector3::new(-0.5, -0.5, std::f64::consts::FRAC_1_SQRT_2);
        let (a, b) = (triangulate_rays(&far), reference(&far));
        assert!(a.is_err(), "{a:?}");
        assert_same_error(a.unwrap_err(), b.unwrap_err());
    }

    #[test]
    fn two_ray_closed_form_is_as_accurate_as_the_general_code() {
        // Noise-free rays through a known point, from nearly parallel (1e-4 rad) to wide:
        // the estimate's error is rounding amplified by the condition of A. Sum of squared
        // relative errors of each path over the same problems.
        let mut r = rng(20_261_123);
        let (mut closed, mut general) = (0.0, 0.0);
        let mut count = 0;
        for _ in 0..2_000 {
            let point = Vector3::new(
                r.random_range(-50.0..50.0),
                r.random_range(-50.0..50.0),
                r.random_range(0.0..20.0),
            );
            let x0 = point - random_unit_vector(&mut r) * r.random_range(5.0..80.0);
            let angle: f64 = 10f64.powf(r.random_range(-4.0..0.4));
            let axis = random_unit_vector(&mut r);
            let x1 = point
                + nalgebra::Rotation3::new(axis * angle)
                    * ((x0 - point) * r.random_range(0.5..2.0));
            let obs: Vec<RayObservation> = [x0, x1]
                .iter()
                .filter_map(|&x| Ray::try_new(x, point - x))
                .map(|ray| RayObservation {
                    ray,
                    sigma_pos_m: 0.1,
                    sigma_ang_rad: 0.0,
                })
                .collect();
            let (Ok(a), Ok(b)) = (triangulate_rays(&obs), projector_sum::<false>(&obs[..])) else {
                continue;
            };
            let scale = (point - x0).norm();
            closed += ((a.point - point).norm() / scale).powi(2);
            general += ((b.point - point).norm() / scale).powi(2);
            count += 1;
        }
        assert!(count > 1_900, "{count} of 2000 solved");
        assert!(
            closed <= 1.5 * general,
            "rms relative error: closed form {:e}, general {:e}",
            (closed / count as f64).sqrt(),
            (general / count as f64).sqrt()
        );
    }

    #[test]
    fn two_ray_path_equals_the_general_path() {
        // The two-ray case is the general code with a constant length; a third ray equal to
        // the second changes A and M by a known amount, so compare against the reference.
        for seed in 0..200 {
            let obs = noisy(seed, 2);
            match (triangulate_rays(&obs), reference(&obs)) {
                (Ok(a), Ok(b)) => assert!(relative_difference(&obs, &a, &b) <= 1e-12),
                (Err(a), Err(b)) => assert_same_error(a, b),
                (a, b) => panic!("seed {seed}: {a:?} vs {b:?}"),
            }
        }
    }
}
