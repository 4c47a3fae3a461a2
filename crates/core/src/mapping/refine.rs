//! Per-landmark refinement: the weighted projector sum with the pose covariance of every
//! frame propagated into its ray.

use nalgebra::{Matrix2, Matrix3, Matrix6, Vector2, Vector3, Vector6};
use vgps_geometry::geometry::tangent_basis;
use vgps_geometry::geometry::{Ray, is_finite};
use vgps_geometry::triangulation::{
    MIN_RAYS, MIN_RECIPROCAL_CONDITION, RayObservation, TriangulatedPoint, TriangulationError,
    reciprocal_condition,
};

/// One ray of a landmark in the world frame, with what is needed to propagate the pose
/// uncertainty of its frame.
///
/// # Units
/// Metres (world ENU), radians; the pose covariance in m², m·rad, rad².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapRay {
    /// Origin = camera centre in the world, direction = unit bearing in the world.
    pub ray: Ray,
    /// The rig origin (the pose's translation) in the world.
    pub rig_origin: Vector3<f64>,
    /// The pose covariance of the frame, `[δp (m, world), δθ (rad, world)]`.
    pub pose_covariance: Matrix6<f64>,
    /// Standard deviation of the bearing measured by the camera (radians, per axis).
    pub sigma_rad: f64,
}

impl MapRay {
    /// The ray of a rig observation seen from a pose (world = `world_from_rig · rig`).
    pub fn from_rig(
        world_from_rig: &vgps_geometry::geometry::Pose,
        pose_covariance: &Matrix6<f64>,
        ray_in_rig: &Ray,
        sigma_rad: f64,
    ) -> Self {
        let origin = world_from_rig * nalgebra::Point3::from(ray_in_rig.origin);
        Self {
            ray: Ray {
                origin: origin.coords,
                direction: world_from_rig.rotation * ray_in_rig.direction,
            },
            rig_origin: world_from_rig.translation.vector,
            pose_covariance: *pose_covariance,
            sigma_rad,
        }
    }

    /// A conservative isotropic bound of this ray's noise, for the online accumulator
    /// ([`vgps_geometry::triangulation::RaySum`]) and the association gates: `σ_pos²` = the largest
    /// variance, over directions perpendicular to the ray, of the position error (`P Σ_pp P`),
    /// and `σ_ang² = σ_cam² +` the largest variance of the direction error `δθ × u` that the
    /// attitude adds (`[u]× Σ_θθ [u]×ᵀ`). The lever arm and the position–attitude correlation
    /// are left out (they are in [`ray_residual_covariance`]).
    pub fn effective_observation(&self) -> RayObservation {
        let u = self.ray.direction;
        let (e1, e2) = vgps_geometry::geometry::tangent_basis(&u);
        let max_perp = |m: Matrix3<f64>| {
            let (a, b, c) = (e1.dot(&(m * e1)), e1.dot(&(m * e2)), e2.dot(&(m * e2)));
            let mean = 0.5 * (a + c);
            let dev = (0.25 * (a - c) * (a - c) + b * b).sqrt();
            (mean + dev).max(0.0)
        };
        let spp = self.pose_covariance.fixed_view::<3, 3>(0, 0).into_owned();
        let stt = self.pose_covariance.fixed_view::<3, 3>(3, 3).into_owned();
        // [u]× Σθθ [u]×ᵀ restricted to the plane ⊥ u has the same eigenvalues as P Σθθ P
        // (a rotation by 90° about u).
        let sp2 = max_perp(spp);
        let sa2 = self.sigma_rad * self.sigma_rad + max_perp(stt);
        RayObservation {
            ray: self.ray,
            sigma_pos_m: sp2.sqrt(),
            sigma_ang_rad: sa2.sqrt(),
        }
    }
}

/// The skew matrix `[v]×` (`[v]× w = v × w`).
#[inline]
fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Covariance (3×3, rank 2, m²) of the residual `P(point − x)` of a ray at a landmark
/// position `point`, with `P = I − uuᵀ`.
///
/// A pose error `(δp, δθ)` moves where the rig sees a fixed world point by
/// `e = δp + δθ × (point − t)` (`t` the rig origin): the attitude error acts through the
/// lever from the rig origin to the landmark, which contains both the camera offset and the
/// range. With `J = [I₃ | −[point − t]×]`, `Σ_e = J Σ_pose Jᵀ` (correlations included), and
/// the camera's own angular error `σ_cam` at range `d = |point − x|`:
///
/// ```text
/// S = P Σ_e P + d² σ_cam² P.
/// ```
///
/// # Units
/// Metres for `point`; m² for the result.
pub fn ray_residual_covariance(ray: &MapRay, point: &Vector3<f64>) -> Matrix3<f64> {
    let u = ray.ray.direction;
    let se = pose_error_covariance(&ray.pose_covariance, &(point - ray.rig_origin));
    // P Σ_e P = Σ_e − u sᵀ − s uᵀ + (uᵀs) u uᵀ with s = Σ_e u (P = I − uuᵀ).
    let s = se * u;
    let q = u.dot(&s);
    let d2s2 = (point - ray.ray.origin).norm_squared() * ray.sigma_rad * ray.sigma_rad;
    let uu = u * u.transpose();
    let us = u * s.transpose();
    let out = se - us - us.transpose() + uu * q + (Matrix3::identity() - uu) * d2s2;
    (out + out.transpose()) * 0.5
}

/// `Σ_e = J Σ_pose Jᵀ` with `J = [I₃ | −[l]×]` (`l` the lever from the rig origin to the
/// point): the covariance of the displacement `δp + δθ × l` of a world point seen from a
/// pose with covariance `c` (see [`ray_residual_covariance`]).
#[inline]
fn pose_error_covariance(c: &Matrix6<f64>, l: &Vector3<f64>) -> Matrix3<f64> {
    let k = -skew(l);
    let spp = c.fixed_view::<3, 3>(0, 0);
    let stp = c.fixed_view::<3, 3>(3, 0);
    let stt = c.fixed_view::<3, 3>(3, 3);
    // Σ_pose is symmetric: Σ_pθ Kᵀ = (K Σ_θp)ᵀ.
    let x = k * stp;
    spp + x + x.transpose() + k * stt * k.transpose()
}

/// `aᵀ Σ_e b` for the `Σ_e` of [`pose_error_covariance`], without forming it:
/// `Jᵀa = [a; l × a]`, so `aᵀ J Σ Jᵀ b = [a; l×a]ᵀ Σ [b; l×b]`.
#[inline]
fn pose_error_bilinear(
    c: &Matrix6<f64>,
    l: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
) -> f64 {
    let la = l.cross(a);
    let lb = l.cross(b);
    let za = Vector6::new(a.x, a.y, a.z, la.x, la.y, la.z);
    let zb = Vector6::new(b.x, b.y, b.z, lb.x, lb.y, lb.z);
    za.dot(&(c * zb))
}

/// `vᵀ S v` for the residual covariance `S` of [`ray_residual_covariance`] at `point`,
/// without forming `S`: with `w = P v`, `vᵀ S v = wᵀ Σ_e w + d² σ_cam² |w|²`.
#[inline]
pub(crate) fn ray_residual_variance(ray: &MapRay, point: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    let u = ray.ray.direction;
    let w = v - u * u.dot(v);
    let l = point - ray.rig_origin;
    let d2s2 = (point - ray.ray.origin).norm_squared() * ray.sigma_rad * ray.sigma_rad;
    pose_error_bilinear(&ray.pose_covariance, &l, &w, &w) + d2s2 * w.norm_squared()
}

/// `Eᵀ S E` (2×2) for the residual covariance `S` of [`ray_residual_covariance`] at `point`
/// and two unit vectors `e1`, `e2` perpendicular to the ray (`P E = E`):
/// `Eᵀ Σ_e E + d² σ_cam² I₂`, returned as `(s11, s12, s22)`.
#[inline]
pub(crate) fn ray_residual_tangent(
    ray: &MapRay,
    point: &Vector3<f64>,
    e1: &Vector3<f64>,
    e2: &Vector3<f64>,
) -> (f64, f64, f64) {
    let l = point - ray.rig_origin;
    let d2s2 = (point - ray.ray.origin).norm_squared() * ray.sigma_rad * ray.sigma_rad;
    let c = &ray.pose_covariance;
    let (l1, l2) = (l.cross(e1), l.cross(e2));
    let z1 = Vector6::new(e1.x, e1.y, e1.z, l1.x, l1.y, l1.z);
    let z2 = Vector6::new(e2.x, e2.y, e2.z, l2.x, l2.y, l2.z);
    let cz1 = c * z1;
    let cz2 = c * z2;
    (z1.dot(&cz1) + d2s2, z2.dot(&cz1), z2.dot(&cz2) + d2s2)
}

/// The squared Mahalanobis distance (2 dof) of `point` from `ray`: its offset across the
/// ray against the ray's residual covariance (see `ray_residual_tangent`); `None` when
/// that 2×2 covariance is singular.
pub fn ray_chi2(ray: &MapRay, point: &Vector3<f64>) -> Option<f64> {
    let (e1, e2) = tangent_basis(&ray.ray.direction);
    let d = point - ray.ray.origin;
    let v = Vector2::new(e1.dot(&d), e2.dot(&d));
    let (s11, s12, s22) = ray_residual_tangent(ray, point, &e1, &e2);
    let inv = Matrix2::new(s11, s12, s12, s22).try_inverse()?;
    Some(v.dot(&(inv * v)))
}

/// Solves `A q = b` after the conditioning check of [`vgps_geometry::triangulation`].
fn solve3(
    a: &Matrix3<f64>,
    b: &Vector3<f64>,
) -> Result<(Matrix3<f64>, Vector3<f64>), TriangulationError> {
    let rc = reciprocal_condition(a);
    if rc < MIN_RECIPROCAL_CONDITION {
        return Err(TriangulationError::IllConditioned {
            reciprocal_condition: rc,
        });
    }
    let inv = a.try_inverse().ok_or(TriangulationError::IllConditioned {
        reciprocal_condition: rc,
    })?;
    Ok((inv, inv * b))
}

/// The refined estimate of one landmark from all its rays: the projector sum weighted by
/// each ray's residual variance, with a covariance that carries every frame's full pose
/// covariance.
///
/// ```text
/// p₀ = (Σ Pᵢ)⁻¹ Σ Pᵢxᵢ                                 (Ku et al. eq. (2))
/// wᵢ = 1 / (½ tr Sᵢ(p₀)),   A = Σ wᵢPᵢ,   p = A⁻¹ Σ wᵢPᵢxᵢ
/// Σ_p = A⁻¹ [ Σ wᵢ² Sᵢ(p) ] A⁻¹
/// ```
///
/// with `Sᵢ` the residual covariance of [`ray_residual_covariance`] (pose position and
/// attitude, their correlation, the lever arm, the camera's angular noise). The sandwich is
/// the exact first-order covariance of this linear estimator for any weights, so the
/// weights only need to be sensible; the pose errors of different frames are assumed
/// independent. The paper's eq. (9) is the unweighted case with isotropic position noise
/// (and a world-origin-dependent angular term, see `docs/triangulation.md`).
///
/// # Errors
/// As [`vgps_geometry::triangulation::triangulate_rays()`]: [`TriangulationError::TooFewRays`],
/// [`TriangulationError::InvalidRay`], [`TriangulationError::IllConditioned`],
/// [`TriangulationError::BehindRay`], [`TriangulationError::NonFinite`].
///
/// # Units
/// Metres, m², radians.
///
/// # Example
/// ```
/// use nalgebra::{Matrix6, Vector3};
/// use vgps_geometry::geometry::Ray;
/// use vgps_core::mapping::{MapRay, refine_landmark};
/// let lamp = Vector3::new(20.0, -6.0, 7.0);
/// // Rig 2 m above the road every metre, GPS σ 0.5 m, heading σ 0.5°, level σ 1°.
/// let mut cov = Matrix6::zeros();
/// for (k, s) in [0.5, 0.5, 0.8, 0.0175, 0.0175, 0.0087].iter().enumerate() {
///     cov[(k, k)] = s * s;
/// }
/// let rays: Vec<MapRay> = (10..30)
///     .map(|x| {
///         let o = Vector3::new(x as f64, 0.0, 2.0);
///         MapRay { ray: Ray::try_new(o, lamp - o).unwrap(), rig_origin: o, pose_covariance: cov, sigma_rad: 1e-3 }
///     })
///     .collect();
/// let est = refine_landmark(&rays).unwrap();
/// assert!((est.point - lamp).norm() < 1e-9);
/// let sd: Vec<f64> = (0..3).map(|k| est.covariance[(k, k)].sqrt()).collect();
/// assert!(sd.iter().all(|&s| s > 0.05 && s < 0.6), "{sd:?}");
/// ```
///
/// # References
/// - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", eq. (2), (9).
pub fn refine_landmark(rays: &[MapRay]) -> Result<TriangulatedPoint, TriangulationError> {
    if rays.len() < MIN_RAYS {
        return Err(TriangulationError::TooFewRays(rays.len()));
    }
    let reference = rays[0].ray.origin;
    let u0 = rays[0].ray.direction;
    let mut far = (1.0, u0);
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (index, r) in rays.iter().enumerate() {
        let u = r.ray.direction;
        let valid = is_finite(&r.ray.origin)
            && (u.norm_squared() - 1.0).abs() <= vgps_geometry::triangulation::UNIT_DIRECTION_TOLERANCE
            // A sum of finite values is finite unless it overflows; any NaN or ±∞ entry
            // makes it non-finite (one pass instead of 36 tests).
            && r.pose_covariance.sum().is_finite()
            && r.sigma_rad >= 0.0
            && r.sigma_rad.is_finite();
        if !valid {
            return Err(TriangulationError::InvalidRay { index });
        }
        let cos = u.dot(&u0);
        if cos < far.0 {
            far = (cos, u);
        }
        let p = Matrix3::identity() - u * u.transpose();
        a += p;
        b += p * (r.ray.origin - reference);
    }
    let (_, q0) = solve3(&a, &b)?;
    let p0 = reference + q0;
    // Weighted pass.
    let mut weights = Vec::with_capacity(rays.len());
    let mut aw = Matrix3::zeros();
    let mut bw = Vector3::zeros();
    for r in rays {
        let s = 0.5 * ray_residual_covariance(r, &p0).trace();
        let w = if s > 0.0 && s.is_finite() {
            1.0 / s
        } else {
            1.0
        };
        weights.push(w);
        let u = r.ray.direction;
        let p = (Matrix3::identity() - u * u.transpose()) * w;
        aw += p;
        bw += p * (r.ray.origin - reference);
    }
    let (a_inv, q) = solve3(&aw, &bw)?;
    let point = reference + q;
    let mut m = Matrix3::zeros();
    for (index, (r, w)) in rays.iter().zip(&weights).enumerate() {
        let range_m = (point - r.ray.origin).dot(&r.ray.direction);
        if range_m.is_nan() || range_m <= 0.0 {
            return Err(TriangulationError::BehindRay { index, range_m });
        }
        m += ray_residual_covariance(r, &point) * (w * w);
    }
    let cov = a_inv * m * a_inv;
    let cov = (cov + cov.transpose()) * 0.5;
    if !(is_finite(&point) && cov.iter().all(|v| v.is_finite())) {
        return Err(TriangulationError::NonFinite);
    }
    Ok(TriangulatedPoint {
        point,
        covariance: cov,
        n_obs: rays.len(),
        max_parallax_sin_cos: (u0.cross(&far.1).norm(), u0.dot(&far.1)),
    })
}
