//! TRIAD: the rotation from two directions known in both frames.

use crate::geometry::try_unit;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Smallest sine of the angle between the two directions of a pair accepted by [`triad`]:
/// below it the directions are treated as parallel and the rotation about them is unknown.
pub const MIN_TRIAD_SINE: f64 = 1e-10;

/// The rotation `world_from_rig` that maps two directions seen in the rig frame onto the
/// same two directions known in the world frame.
///
/// This is the "rotational inference" of the Visual GPS proposal (Bierre, 2006), known in
/// spacecraft attitude determination as TRIAD (Black, 1964): each frame builds the
/// orthonormal triad
///
/// ```text
/// T = [ d1 | n | d1 × n ],   n = (d1 × d2) / |d1 × d2|
/// ```
///
/// and `world_from_rig = T_world · T_rigᵀ` (the proposal's `R = R1 · R2⁻¹`).
///
/// The **first** direction is trusted exactly: `R · d1_rig = d1_world` to machine precision,
/// and the second direction only fixes the rotation about the first one (its component
/// along `d1` is ignored). Put the more accurate direction first, or use
/// [`wahba`](super::wahba) to weigh several directions optimally.
///
/// # Units
/// Directions of any non-zero finite length (normalised inside); dimensionless.
///
/// # Returns
/// `None` when a direction is zero or not finite, or when the two directions of a frame are
/// parallel or anti-parallel (sine of their angle ≤ [`MIN_TRIAD_SINE`]).
///
/// # Role in vgps
/// The proposal's rotational inference, kept as the **reference and cross-check**: production
/// attitude comes with the position from [`crate::solvers::refine_pose()`] (jointly optimal over
/// every landmark, with its covariance); [`wahba`](super::wahba) is the optimal attitude from
/// many directions when the position is known.
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// let truth = Rotation3::from_euler_angles(0.1, -0.4, 2.0);
/// let (a, b) = (Vector3::new(1.0, 2.0, 0.5), Vector3::new(-0.3, 0.2, 1.0));
/// let r = vgps_geometry::attitude::triad([&a, &b], [&(truth * a), &(truth * b)]).unwrap();
/// assert!((r.matrix() - truth.matrix()).norm() < 1e-14);
/// assert!(vgps_geometry::attitude::triad([&a, &(2.0 * a)], [&a, &b]).is_none());
/// ```
///
/// # References
/// - P. Bierre, "Position and Attitude Sensing by Directional Triangulation", ION National
///   Technical Meeting, Emerging Technologies Panel, Monterey CA, January 2006.
/// - H. D. Black, "A passive system for determining the attitude of a satellite",
///   AIAA Journal 2(7), 1964.
pub fn triad(in_rig: [&Vector3<f64>; 2], in_world: [&Vector3<f64>; 2]) -> Option<Rotation3<f64>> {
    let rig = orthonormal_triad(in_rig[0], in_rig[1])?;
    let world = orthonormal_triad(in_world[0], in_world[1])?;
    let m = world * rig.transpose();
    m.iter()
        .all(|x| x.is_finite())
        .then(|| Rotation3::from_matrix_unchecked(m))
}

/// The orthonormal, right-handed triad `[d1 | n | d1 × n]` of two directions.
fn orthonormal_triad(first: &Vector3<f64>, second: &Vector3<f64>) -> Option<Matrix3<f64>> {
    let t1 = try_unit(first)?;
    let b = try_unit(second)?;
    let c = t1.cross(&b);
    let n = c.norm();
    if n.is_nan() || n <= MIN_TRIAD_SINE {
        return None;
    }
    let t2 = c / n;
    let t3 = t1.cross(&t2);
    Some(Matrix3::from_columns(&[t1, t2, t3]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{perturb_bearing, random_rotation, random_unit_vector, rng};

    #[test]
    fn recovers_random_rotations_exactly() {
        let mut r = rng(11);
        for _ in 0..10_000 {
            let truth = random_rotation(&mut r);
            let a = random_unit_vector(&mut r) * 3.0;
            let b = random_unit_vector(&mut r) * 0.2;
            let est = triad([&a, &b], [&(truth * a), &(truth * b)]).unwrap();
            assert!((est.matrix() - truth.matrix()).norm() < 1e-12);
            // Orthonormal and proper.
            let m = est.matrix();
            assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-14);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn first_direction_is_trusted_exactly() {
        let mut r = rng(12);
        for _ in 0..1000 {
            let truth = random_rotation(&mut r);
            let a = random_unit_vector(&mut r);
            let b = random_unit_vector(&mut r);
            // Noisy second direction in the world.
            let b_world = perturb_bearing(&mut r, &(truth * b), 0.01);
            let est = triad([&a, &b], [&(truth * a), &b_world]).unwrap();
            assert!((est * a - truth * a).norm() < 1e-14);
            // The second direction still lands in the plane of (a, b_world).
            let n = (truth * a).cross(&b_world).normalize();
            assert!((est * b).dot(&n).abs() < 1e-12);
        }
    }

    #[test]
    fn degenerate_inputs_give_none() {
        let x = Vector3::x();
        let y = Vector3::y();
        let nan = Vector3::new(f64::NAN, 0.0, 1.0);
        let inf = Vector3::new(f64::INFINITY, 0.0, 1.0);
        assert!(triad([&x, &y], [&x, &y]).is_some());
        assert!(triad([&x, &(3.0 * x)], [&x, &y]).is_none());
        assert!(triad([&x, &(-x)], [&x, &y]).is_none());
        assert!(triad([&x, &y], [&y, &y]).is_none());
        assert!(triad([&Vector3::zeros(), &y], [&x, &y]).is_none());
        assert!(triad([&x, &nan], [&x, &y]).is_none());
        assert!(triad([&x, &y], [&inf, &y]).is_none());
    }
}
