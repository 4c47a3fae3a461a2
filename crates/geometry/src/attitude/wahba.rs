//! Wahba's problem: the optimal rotation from weighted direction pairs.

use crate::geometry::{is_finite, try_unit};
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Smallest sine between two directions for them to count as non-parallel in [`wahba`]
/// (the rotation about a single direction is unobservable), and smallest ratio of the middle
/// to the largest singular value of the attitude profile matrix.
pub const MIN_WAHBA_SINE: f64 = 1e-10;

/// The rotation `world_from_rig` minimising Wahba's loss
///
/// ```text
/// L(R) = ½ Σᵢ wᵢ |bᵢ − R aᵢ|²,   aᵢ = in_rig[i] (unit),  bᵢ = in_world[i] (unit)
/// ```
///
/// solved with the singular value decomposition of the attitude profile matrix
/// `B = Σ wᵢ bᵢ aᵢᵀ = U S Vᵀ`: `R = U diag(1, 1, det U · det V) Vᵀ` (Markley, 1988), which is
/// the global minimum among proper rotations, also for two directions or a reflected `B`.
///
/// The weights are inverse relative variances: a direction of weight `w` is modelled with
/// angular noise `σ / √w` per tangent axis (see [`wahba_with_covariance`]). A weight of zero
/// ignores its pair.
///
/// # Units
/// Directions of any non-zero finite length (normalised inside); weights dimensionless.
///
/// # Returns
/// `None` when the slices have different lengths, a weight is negative or not finite, a
/// direction is zero or not finite, or when the directions of positive weight do not
/// contain two non-parallel pairs in each frame (sine ≤ [`MIN_WAHBA_SINE`]).
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// let truth = Rotation3::from_euler_angles(0.3, 0.2, -1.0);
/// let rig = [Vector3::x(), Vector3::y(), Vector3::new(1.0, 1.0, 1.0)];
/// let world: Vec<_> = rig.iter().map(|a| truth * a).collect();
/// let r = vgps_geometry::attitude::wahba(&rig, &world, &[1.0, 1.0, 0.5]).unwrap();
/// assert!((r.matrix() - truth.matrix()).norm() < 1e-14);
/// ```
///
/// # References
/// - G. Wahba, "A least squares estimate of satellite attitude", SIAM Review 7(3), 1965.
/// - F. L. Markley, "Attitude determination using vector observations and the singular
///   value decomposition", Journal of the Astronautical Sciences 36(3), 1988.
pub fn wahba(
    in_rig: &[Vector3<f64>],
    in_world: &[Vector3<f64>],
    weights: &[f64],
) -> Option<Rotation3<f64>> {
    let pairs = unit_pairs(in_rig, in_world, weights)?;
    let mut b = Matrix3::zeros();
    for (a, w, weight) in &pairs {
        b += *weight * w * a.transpose();
    }
    let svd = b.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let s = svd.singular_values;
    // Indices of the largest, middle and smallest singular values.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
    if s[order[1]].is_nan() || s[order[1]] <= MIN_WAHBA_SINE * s[order[0]] {
        return None;
    }
    let mut d = Vector3::repeat(1.0);
    d[order[2]] = u.determinant() * v_t.determinant();
    let m = u * Matrix3::from_diagonal(&d) * v_t;
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    Some(polish(Rotation3::from_matrix_unchecked(m), &pairs))
}

/// One Gauss-Newton step on Wahba's loss, `R ← exp(δ) R` with
/// `δ = (Σ wᵢ (I − cᵢcᵢᵀ))⁻¹ Σ wᵢ cᵢ × bᵢ`, `cᵢ = R aᵢ`. The SVD of the iterative solver
/// leaves errors of order ε·s₁/(s₂ + s₃) or larger; this step brings the rotation back to the rounding
/// level of the loss itself (the step is negligible otherwise). Returns the input rotation if
/// the step is not finite.
fn polish(r: Rotation3<f64>, pairs: &[Pair]) -> Rotation3<f64> {
    let mut information = Matrix3::zeros();
    let mut gradient = Vector3::zeros();
    for (a, b, w) in pairs {
        let c = r * a;
        information += *w * (Matrix3::identity() - c * c.transpose());
        gradient += *w * c.cross(b);
    }
    match information.try_inverse() {
        Some(inv) => {
            let delta = inv * gradient;
            if is_finite(&delta) {
                return Rotation3::from_scaled_axis(delta) * r;
            }
            r
        }
        None => r,
    }
}

/// [`wahba`] together with the covariance of its rotation error.
///
/// The covariance is Shuster's (1989) for the QUEST measurement model: each rig direction
/// `aᵢ` carries isotropic angular noise of standard deviation `σᵢ = sigma_rad / √wᵢ` per
/// tangent axis (the world directions are exact), so that the weights given are the optimal
/// ones (`wᵢ ∝ 1/σᵢ²`). The estimate's error δθ (`world_from_rig = exp(δθ) · R̂`, world
/// frame) then has, to first order,
///
/// ```text
/// P = σ² ( Σᵢ wᵢ (I − bᵢ bᵢᵀ) )⁻¹,   bᵢ = in_world[i] (unit)
/// ```
///
/// If both frames are noisy, pass the root-sum-square of the two per-axis sigmas.
///
/// # Units
/// `sigma_rad`: radians (per tangent axis, for a direction of unit weight). The covariance
/// is in rad², world frame.
///
/// # Returns
/// `None` in every case where [`wahba`] returns `None`, and when `sigma_rad` is negative or
/// not finite.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// let rig = [Vector3::x(), Vector3::y(), Vector3::z()];
/// let (r, p) = vgps_geometry::attitude::wahba_with_covariance(&rig, &rig, &[1.0; 3], 1e-3).unwrap();
/// assert!((r.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-15);
/// // Each axis is seen by the two directions perpendicular to it: variance σ²/2.
/// assert!((p[(0, 0)] - 0.5e-6).abs() < 1e-18 && p[(0, 1)].abs() < 1e-18);
/// ```
///
/// # References
/// - M. D. Shuster, "Maximum likelihood estimation of spacecraft attitude", Journal of the
///   Astronautical Sciences 37(1), 1989.
/// - M. D. Shuster and S. D. Oh, "Three-axis attitude determination from vector
///   observations", Journal of Guidance and Control 4(1), 1981.
pub fn wahba_with_covariance(
    in_rig: &[Vector3<f64>],
    in_world: &[Vector3<f64>],
    weights: &[f64],
    sigma_rad: f64,
) -> Option<(Rotation3<f64>, Matrix3<f64>)> {
    if !(sigma_rad.is_finite() && sigma_rad >= 0.0) {
        return None;
    }
    let rotation = wahba(in_rig, in_world, weights)?;
    let pairs = unit_pairs(in_rig, in_world, weights)?;
    let mut information = Matrix3::zeros();
    for (_, w, weight) in &pairs {
        information += *weight * (Matrix3::identity() - w * w.transpose());
    }
    let p = information.try_inverse()? * (sigma_rad * sigma_rad);
    let p = 0.5 * (p + p.transpose());
    p.iter().all(|x| x.is_finite()).then_some((rotation, p))
}

/// A normalised direction pair with its weight: (in rig, in world, weight).
type Pair = (Vector3<f64>, Vector3<f64>, f64);

/// The normalised (rig, world, weight) triples of positive weight, after validating the
/// input; `None` on any invalid input or when a frame lacks two non-parallel directions.
fn unit_pairs(
    in_rig: &[Vector3<f64>],
    in_world: &[Vector3<f64>],
    weights: &[f64],
) -> Option<Vec<Pair>> {
    if in_rig.len() != in_world.len() || in_rig.len() != weights.len() {
        return None;
    }
    let mut pairs = Vec::with_capacity(in_rig.len());
    for ((a, b), &w) in in_rig.iter().zip(in_world).zip(weights) {
        if !(w.is_finite() && w >= 0.0 && is_finite(a) && is_finite(b)) {
            return None;
        }
        let (a, b) = (try_unit(a)?, try_unit(b)?);
        if w > 0.0 {
            pairs.push((a, b, w));
        }
    }
    let spans_two = |pick: fn(&Pair) -> Vector3<f64>| {
        let first = pick(pairs.first()?);
        pairs
            .iter()
            .any(|p| first.cross(&pick(p)).norm() > MIN_WAHBA_SINE)
            .then_some(())
    };
    spans_two(|p| p.0)?;
    spans_two(|p| p.1)?;
    Some(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{perturb_bearing, random_rotation, random_unit_vector, rng};

    /// λmax/λmin of the information matrix Σ wᵢ (I − bᵢbᵢᵀ). The SVD solution's rounding
    /// error grows like 1/(s₂ + s₃) of the attitude profile matrix, i.e. like this ratio
    /// (for two directions at a small angle γ it is ≈ 4/γ²).
    fn condition(world: &[Vector3<f64>], w: &[f64]) -> f64 {
        let mut f = Matrix3::zeros();
        for (b, wi) in world.iter().zip(w) {
            let b = b.normalize();
            f += *wi * (Matrix3::identity() - b * b.transpose());
        }
        let e = f.symmetric_eigenvalues();
        e.max() / e.min()
    }

    #[test]
    fn noise_free_directions_give_the_truth() {
        let mut r = rng(21);
        for n in 2..12 {
            for _ in 0..500 {
                let truth = random_rotation(&mut r);
                let rig: Vec<_> = (0..n).map(|_| random_unit_vector(&mut r) * 2.5).collect();
                let world: Vec<_> = rig.iter().map(|a| truth * a).collect();
                let w: Vec<f64> = (0..n).map(|i| 0.5 + i as f64).collect();
                let est = wahba(&rig, &world, &w).unwrap();
                // Precision follows the conditioning of the information matrix.
                let e = (est.matrix() - truth.matrix()).norm();
                assert!(
                    e < 1e-14 * condition(&world, &w),
                    "n={n} {e} {}",
                    condition(&world, &w)
                );
                assert!((est.matrix().determinant() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn two_directions_agree_with_triad_when_exact() {
        let mut r = rng(22);
        for _ in 0..1000 {
            let truth = random_rotation(&mut r);
            let a = [random_unit_vector(&mut r), random_unit_vector(&mut r)];
            let b = [truth * a[0], truth * a[1]];
            let w = wahba(&a, &b, &[1.0, 1.0]).unwrap();
            let t = super::super::triad([&a[0], &a[1]], [&b[0], &b[1]]).unwrap();
            let e = (w.matrix() - t.matrix()).norm();
            assert!(
                e < 1e-14 * condition(&b, &[1.0, 1.0]),
                "{e} {}",
                condition(&b, &[1.0, 1.0])
            );
        }
    }

    #[test]
    fn optimal_against_perturbations() {
        // With noise, the SVD solution must have a loss no larger than nearby rotations.
        let mut r = rng(23);
        for _ in 0..200 {
            let truth = random_rotation(&mut r);
            let rig: Vec<_> = (0..6).map(|_| random_unit_vector(&mut r)).collect();
            let world: Vec<_> = rig
                .iter()
                .map(|a| perturb_bearing(&mut r, &(truth * a), 0.05))
                .collect();
            let w = [1.0, 2.0, 0.5, 1.0, 3.0, 1.0];
            let est = wahba(&rig, &world, &w).unwrap();
            let loss = |rot: &Rotation3<f64>| -> f64 {
                rig.iter()
                    .zip(&world)
                    .zip(&w)
                    .map(|((a, b), wi)| wi * (b - rot * a).norm_squared())
                    .sum()
            };
            let l0 = loss(&est);
            for _ in 0..20 {
                let delta = Rotation3::from_scaled_axis(random_unit_vector(&mut r) * 1e-3);
                assert!(loss(&(delta * est)) >= l0 - 1e-12);
            }
        }
    }

    #[test]
    fn degenerate_inputs_give_none() {
        let x = Vector3::x();
        let y = Vector3::y();
        let ok = [x, y];
        assert!(wahba(&ok, &ok, &[1.0, 1.0]).is_some());
        assert!(wahba(&[x], &[x], &[1.0]).is_none());
        assert!(wahba(&[x, 2.0 * x, -x], &[x, x, -x], &[1.0; 3]).is_none());
        assert!(wahba(&ok, &[x, x], &[1.0, 1.0]).is_none());
        assert!(wahba(&ok, &ok, &[1.0]).is_none());
        assert!(wahba(&ok, &ok, &[1.0, -1.0]).is_none());
        assert!(wahba(&ok, &ok, &[1.0, 0.0]).is_none());
        assert!(wahba(&ok, &ok, &[1.0, f64::NAN]).is_none());
        assert!(wahba(&[x, Vector3::zeros()], &ok, &[1.0, 1.0]).is_none());
        assert!(wahba(&[x, Vector3::new(f64::INFINITY, 0.0, 0.0)], &ok, &[1.0; 2]).is_none());
        assert!(wahba_with_covariance(&ok, &ok, &[1.0, 1.0], -1.0).is_none());
        assert!(wahba_with_covariance(&ok, &ok, &[1.0, 1.0], f64::NAN).is_none());
    }

    /// Monte Carlo check of Shuster's covariance: the normalised estimation error squared
    /// (NEES) must average 3 (the dimension) when the covariance is right.
    #[test]
    fn covariance_is_consistent_by_monte_carlo() {
        let mut r = rng(24);
        let sigma = 2e-3;
        let trials = 4000;
        let mut nees_sum = 0.0;
        for t in 0..trials {
            let truth = random_rotation(&mut r);
            let n = 2 + t % 5;
            let world: Vec<_> = (0..n).map(|_| random_unit_vector(&mut r)).collect();
            let w: Vec<f64> = (0..n).map(|i| 0.25 + 0.5 * i as f64).collect();
            let rig: Vec<_> = world
                .iter()
                .zip(&w)
                .map(|(b, wi)| perturb_bearing(&mut r, &(truth.inverse() * b), sigma / wi.sqrt()))
                .collect();
            let (est, p) = wahba_with_covariance(&rig, &world, &w, sigma).unwrap();
            let dtheta = (est * truth.inverse()).scaled_axis();
            let info = p.try_inverse().unwrap();
            nees_sum += dtheta.dot(&(info * dtheta));
        }
        let mean = nees_sum / trials as f64;
        assert!((mean - 3.0).abs() < 0.3, "mean NEES {mean}");
    }
}
