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
/// use vgps::geometry::Ray;
/// use vgps::triangulation::{triangulate_rays, RayObservation};
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
    let first = validate_count(obs)?;
    let reference = first.ray.origin;
    let u0 = first.ray.direction;
    // Pass 1: A = Σ Pᵢ = nI − Σ uᵢuᵢᵀ and b = Σ Pᵢyᵢ = Σ yᵢ − Σ uᵢ(uᵢ·yᵢ) with yᵢ = xᵢ − x₀,
    // and the ray farthest from the first. Validity is accumulated as a flag (no branch per
    // ray); the first offender is found on the cold path.
    let mut uu = Sym3::default();
    let mut b = Vector3::zeros();
    let mut far_cos = 1.0;
    let mut far = u0;
    let mut rays_ok = true;
    for o in obs {
        let u = o.ray.direction;
        rays_ok &= ray_is_valid(&o.ray);
        let cos = u.dot(&u0);
        if cos < far_cos {
            far_cos = cos;
            far = u;
        }
        let y = o.ray.origin - reference;
        uu.add_outer(1.0, &u);
        b += y - u * u.dot(&y);
    }
    if !rays_ok {
        return Err(first_invalid_ray(obs));
    }
    let n = obs.len() as f64;
    let a = Sym3::diagonal(n).minus(&uu);
    let (a_inv, q) = solve(&a, &b)?;
    // Pass 2: ranges at the estimate, in-front check, middle term of the sandwich
    // M = Σ sᵢPᵢ = (Σ sᵢ) I − Σ sᵢuᵢuᵢᵀ, the largest σ_ang, and what validates the noise
    // levels (the smallest σ and a scaled sum of σ², tested after the loop).
    let mut m_uu = Sym3::default();
    let mut s_sum = 0.0;
    let mut in_front = true;
    let (mut sp_min, mut sa_min, mut sa_max): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let mut noise_sum = 0.0;
    for o in obs {
        let u = o.ray.direction;
        let r = q - (o.ray.origin - reference);
        let (sp, sa) = (o.sigma_pos_m, o.sigma_ang_rad);
        sp_min = if sp < sp_min { sp } else { sp_min };
        sa_min = if sa < sa_min { sa } else { sa_min };
        sa_max = if sa > sa_max { sa } else { sa_max };
        let (sp2, sa2) = (sp * sp, sa * sa);
        noise_sum += (sp2 + sa2) * NOISE_SUM_SCALE;
        let s = sp2 + sa2 * r.norm_squared();
        // False for NaN.
        in_front &= r.dot(&u) > 0.0;
        s_sum += s;
        m_uu.add_outer(s, &u);
    }
    // Every σ ≥ 0 and every σ_pos² + σ_ang² finite ([`check_noise`]): a NaN σ is missed by
    // the minima but makes the sum NaN; the scaled sum cannot overflow on its own.
    let noise_ok = sp_min >= 0.0 && sa_min >= 0.0 && noise_sum < f64::INFINITY;
    if !(noise_ok && in_front) {
        return Err(first_noise_or_behind(obs, &reference, &q));
    }
    let m = Sym3::diagonal(s_sum).minus(&m_uu);
    let parallax = sin_cos_between(&u0, &far);
    check_parallax_sigma(
        sa_max,
        finish(reference, q, &a_inv, &m, obs.len(), parallax)?,
    )
}

/// True for a ray with a finite origin and a unit direction (see [`check_ray`]).
#[inline(always)]
fn ray_is_valid(ray: &Ray) -> bool {
    let uu = ray.direction.norm_squared();
    // False for NaN.
    ((uu - 1.0).abs() <= UNIT_DIRECTION_TOLERANCE) & is_finite(&ray.origin)
}

/// Scale (2⁻⁶⁴) of the running sum of `σ_pos² + σ_ang²` that validates the noise levels in
/// [`triangulate_rays`]: each term is finite exactly when the unscaled one is, and fewer than
/// 2⁶⁴ finite terms cannot overflow the sum.
const NOISE_SUM_SCALE: f64 = 1.0 / 18_446_744_073_709_551_616.0;

/// The error for the first invalid ray (the cold path of [`triangulate_rays`]).
#[cold]
#[inline(never)]
fn first_invalid_ray(obs: &[RayObservation]) -> TriangulationError {
    for (index, o) in obs.iter().enumerate() {
        if let Err(e) = check_ray(index, &o.ray) {
            return e;
        }
    }
    TriangulationError::NonFinite
}

/// The error for the first observation, in order, with invalid noise or with the point at
/// `q` (relative to `reference`) not in front of it (the cold path of [`triangulate_rays`]).
#[cold]
#[inline(never)]
fn first_noise_or_behind(
    obs: &[RayObservation],
    reference: &Vector3<f64>,
    q: &Vector3<f64>,
) -> TriangulationError {
    for (index, o) in obs.iter().enumerate() {
        if let Err(e) = residual_variance(index, o, reference, q) {
            return e;
        }
    }
    TriangulationError::NonFinite
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
/// use vgps::geometry::Ray;
/// use vgps::triangulation::{triangulate_rays, triangulate_rays_weighted, RayObservation};
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
/// use vgps::geometry::Ray;
/// use vgps::triangulation::{RayObservation, RaySum};
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
