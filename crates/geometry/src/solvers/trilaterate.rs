//! Trilateration: the intersection of three spheres.

use crate::geometry::is_finite;
use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

/// Smallest distance between two centres, relative to the largest, below which they are
/// treated as coincident.
pub const MIN_CENTRE_SEPARATION: f64 = 1e-12;

/// Smallest sine of the angle at a centre between the other two below which the three
/// centres are treated as collinear (the intersection is then a whole circle).
pub const MIN_CENTRES_SINE: f64 = 1e-9;

/// Largest miss accepted as tangency: when the spheres fail to meet by a height of at most
/// this fraction of the scene size (largest centre separation or range), the intersection
/// is returned as the touching point (twice) instead of an error. Absorbs rounding of ranges
/// that were computed from an exact geometry.
pub const TANGENT_TOLERANCE: f64 = 1e-6;

/// Smallest |det| of three unit bearings, below which [`select_by_handedness`] treats them
/// as coplanar (rig in the plane of the landmarks, where the two mirror points coincide).
pub const MIN_BEARING_TRIPLE_PRODUCT: f64 = 1e-12;

/// Why three spheres have no isolated intersection points.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum TrilaterationError {
    /// A centre or a range is NaN or infinite.
    #[error("a sphere centre or range is not finite")]
    NonFinite,
    /// A range is negative.
    #[error("a range is negative")]
    NegativeRange,
    /// Two centres coincide (within [`MIN_CENTRE_SEPARATION`]).
    #[error("two sphere centres coincide")]
    CoincidentCentres,
    /// The three centres are collinear (within [`MIN_CENTRES_SINE`]).
    #[error("the three sphere centres are collinear")]
    CollinearCentres,
    /// The spheres miss each other by more than [`TANGENT_TOLERANCE`].
    #[error("the spheres do not intersect: they miss by a height of {miss_m} m")]
    NoIntersection {
        /// How far (metres, height above the plane of the centres) the spheres miss.
        miss_m: f64,
    },
}

/// The two points at distances `ranges` from three `centres`.
///
/// With `ex = (c₁ − c₀)/d`, `ey` the unit component of `c₂ − c₀` perpendicular to `ex`,
/// `ez = ex × ey`, `i = ex·(c₂ − c₀)`, `j = ey·(c₂ − c₀)`:
///
/// ```text
/// x = (r₀² − r₁² + d²) / 2d
/// y = (r₀² − r₂² + i² + j²) / 2j − (i/j) x
/// z = ±√(r₀² − x² − y²)
/// p = c₀ + x ex + y ey + z ez
/// ```
///
/// # Order of the solutions
/// `[0]` is on the side of the normal `(c₁ − c₀) × (c₂ − c₀)` (z ≥ 0), `[1]` is its mirror
/// image through the plane of the centres. When the spheres are tangent (z = 0, including a
/// miss within [`TANGENT_TOLERANCE`]) both entries are the same point. To pick the mirror
/// solution seen by a camera use [`select_by_handedness`].
///
/// # Units
/// Metres (any consistent length unit).
///
/// # Errors
/// [`TrilaterationError`] for non-finite input, negative ranges, coincident or collinear
/// centres, and spheres that do not meet.
///
/// # Role in vgps
/// A step of the proposal's method ([`crate::solvers::p3p_cosines()`] gives the ranges,
/// trilateration the position), kept as the **reference**: production positions come from
/// [`crate::solvers::p3p()`] and [`crate::solvers::refine_pose()`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// let c = [Vector3::zeros(), Vector3::new(4.0, 0.0, 0.0), Vector3::new(0.0, 4.0, 0.0)];
/// let p = Vector3::new(1.0, 2.0, 3.0);
/// let r = [p.norm(), (p - c[1]).norm(), (p - c[2]).norm()];
/// let [above, below] = vgps_geometry::solvers::trilaterate(&c, &r).unwrap();
/// assert!((above - p).norm() < 1e-14);
/// assert!((below - Vector3::new(1.0, 2.0, -3.0)).norm() < 1e-14);
/// ```
///
/// # References
/// P. Bierre, "Position and Attitude Sensing by Directional Triangulation", ION National
/// Technical Meeting, Monterey CA, January 2006 ("distance trilateration" step).
pub fn trilaterate(
    centres: &[Vector3<f64>; 3],
    ranges: &[f64; 3],
) -> Result<[Vector3<f64>; 2], TrilaterationError> {
    if !centres.iter().all(is_finite) || !ranges.iter().all(|r| r.is_finite()) {
        return Err(TrilaterationError::NonFinite);
    }
    if ranges.iter().any(|&r| r < 0.0) {
        return Err(TrilaterationError::NegativeRange);
    }
    let e1 = centres[1] - centres[0];
    let e2 = centres[2] - centres[0];
    let (d, l2, l12) = (e1.norm(), e2.norm(), (centres[2] - centres[1]).norm());
    let separation = d.max(l2).max(l12);
    if d.min(l2).min(l12) <= MIN_CENTRE_SEPARATION * separation {
        return Err(TrilaterationError::CoincidentCentres);
    }
    let normal = e1.cross(&e2);
    if normal.norm() <= MIN_CENTRES_SINE * d * l2 {
        return Err(TrilaterationError::CollinearCentres);
    }
    let ex = e1 / d;
    let i = ex.dot(&e2);
    let perpendicular = e2 - ex * i;
    let j = perpendicular.norm();
    let ey = perpendicular / j;
    let ez = ex.cross(&ey);
    let [r0, r1, r2] = *ranges;
    let x = (r0 * r0 - r1 * r1 + d * d) / (2.0 * d);
    let y = (r0 * r0 - r2 * r2 + i * i + j * j) / (2.0 * j) - i / j * x;
    let z2 = r0 * r0 - x * x - y * y;
    let scale = separation.max(r0).max(r1).max(r2);
    let z = if z2 >= 0.0 {
        z2.sqrt()
    } else if (-z2).sqrt() <= TANGENT_TOLERANCE * scale {
        0.0
    } else {
        return Err(TrilaterationError::NoIntersection {
            miss_m: (-z2).sqrt(),
        });
    };
    let foot = centres[0] + ex * x + ey * y;
    let out = [foot + ez * z, foot - ez * z];
    if out.iter().all(is_finite) {
        Ok(out)
    } else {
        Err(TrilaterationError::NonFinite)
    }
}

/// The mirror solution of [`trilaterate`] seen with the handedness of the observed bearings.
///
/// A rotation preserves orientation, so at the true rig position `p` the triple products
/// `det[d₀ d₁ d₂]` (unit bearings in the rig frame) and `det[X₀ − p, X₁ − p, X₂ − p]`
/// (landmarks in the world) have the same sign. Returns the solution whose sign agrees.
///
/// When the bearings are coplanar (|det| ≤ [`MIN_BEARING_TRIPLE_PRODUCT`]: the rig lies in
/// the plane of the landmarks and the two mirror points coincide without noise) the midpoint
/// of the two solutions is returned.
///
/// # Returns
/// `None` when a bearing is zero or not finite, a solution or centre is not finite, or
/// neither solution has the bearings' handedness (both on the plane while the bearings are
/// not coplanar).
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// use vgps_geometry::solvers::{select_by_handedness, trilaterate};
/// let x = [Vector3::zeros(), Vector3::new(4.0, 0.0, 0.0), Vector3::new(0.0, 4.0, 0.0)];
/// let p = Vector3::new(1.0, 1.0, -2.0);
/// let rig_from_world = Rotation3::from_euler_angles(0.2, 0.3, 0.4);
/// let bearings = x.map(|xi| rig_from_world * (xi - p));
/// let solutions = trilaterate(&x, &x.map(|xi| (xi - p).norm())).unwrap();
/// let chosen = select_by_handedness(&solutions, &x, &bearings).unwrap();
/// assert!((chosen - p).norm() < 1e-13);
/// ```
pub fn select_by_handedness(
    solutions: &[Vector3<f64>; 2],
    centres: &[Vector3<f64>; 3],
    bearings_in_rig: &[Vector3<f64>; 3],
) -> Option<Vector3<f64>> {
    let mut unit = [Vector3::zeros(); 3];
    for (u, b) in unit.iter_mut().zip(bearings_in_rig) {
        *u = crate::geometry::try_unit(b)?;
    }
    if !solutions.iter().all(is_finite) || !centres.iter().all(is_finite) {
        return None;
    }
    let det_rig = Matrix3::from_columns(&unit).determinant();
    if det_rig.abs() <= MIN_BEARING_TRIPLE_PRODUCT {
        return Some(0.5 * (solutions[0] + solutions[1]));
    }
    solutions.iter().copied().find(|p| {
        let det_world =
            Matrix3::from_columns(&[centres[0] - p, centres[1] - p, centres[2] - p]).determinant();
        det_world * det_rig > 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{P3pProblem, random_unit_vector, rng};

    #[test]
    fn recovers_both_mirror_points() {
        let mut r = rng(41);
        for _ in 0..10_000 {
            let c = [0; 3].map(|_| random_unit_vector(&mut r) * 30.0);
            let p = random_unit_vector(&mut r) * 20.0;
            let ranges = c.map(|ci| (ci - p).norm());
            let s = trilaterate(&c, &ranges).unwrap();
            let normal = (c[1] - c[0]).cross(&(c[2] - c[0]));
            // Mirror of p through the plane of the centres.
            let n = normal.normalize();
            let mirror = p - 2.0 * n * n.dot(&(p - c[0]));
            let (above, below) = if n.dot(&(p - c[0])) >= 0.0 {
                (p, mirror)
            } else {
                (mirror, p)
            };
            // Precision degrades like √ε near the plane (the intersection is near-tangent).
            let h = n.dot(&(p - c[0])).abs();
            let tol = 1e-12 * 60.0 + 1e-13 * 3600.0 / h.max(1e-3);
            assert!((s[0] - above).norm() < tol, "{} {h}", (s[0] - above).norm());
            assert!((s[1] - below).norm() < tol);
            for si in &s {
                for (ci, ri) in c.iter().zip(&ranges) {
                    assert!(((si - ci).norm() - ri).abs() < tol);
                }
            }
        }
    }

    #[test]
    fn handedness_picks_the_true_position() {
        let mut r = rng(42);
        let mut checked = 0;
        for _ in 0..10_000 {
            let problem = P3pProblem::random_omni(&mut r, 50.0);
            let p = problem.world_from_rig.translation.vector;
            let x = problem.points_in_world;
            let s = trilaterate(&x, &x.map(|xi| (xi - p).norm())).unwrap();
            let chosen = select_by_handedness(&s, &x, &problem.bearings_in_rig).unwrap();
            let h = (x[1] - x[0])
                .cross(&(x[2] - x[0]))
                .normalize()
                .dot(&(p - x[0]))
                .abs();
            if h > 1e-3 {
                assert!((chosen - p).norm() < 1e-8, "{}", (chosen - p).norm());
                checked += 1;
            }
        }
        assert!(checked > 9_900);
    }

    #[test]
    fn tangent_spheres_give_two_equal_points() {
        let c = [
            Vector3::zeros(),
            Vector3::new(2.0, 0.0, 0.0),
            Vector3::new(0.0, 2.0, 0.0),
        ];
        let p = Vector3::new(0.5, 0.7, 0.0);
        let s = trilaterate(&c, &c.map(|ci| (ci - p).norm())).unwrap();
        // z² is zero up to rounding, so z is at most ~√ε × scale.
        assert!((s[0] - p).norm() < 1e-7 && (s[1] - p).norm() < 1e-7);
        // A tiny miss within the tolerance is still tangent.
        let mut ranges = c.map(|ci| (ci - p).norm());
        ranges[0] -= 1e-12;
        let s = trilaterate(&c, &ranges).unwrap();
        assert_eq!(s[0], s[1]);
    }

    #[test]
    fn errors_are_typed() {
        let c = [
            Vector3::zeros(),
            Vector3::new(2.0, 0.0, 0.0),
            Vector3::new(0.0, 2.0, 0.0),
        ];
        assert!(trilaterate(&c, &[1.0, 1.5, 1.5]).is_ok());
        assert_eq!(
            trilaterate(&c, &[1.0, f64::NAN, 1.0]),
            Err(TrilaterationError::NonFinite)
        );
        let mut bad = c;
        bad[2].z = f64::INFINITY;
        assert_eq!(
            trilaterate(&bad, &[1.0; 3]),
            Err(TrilaterationError::NonFinite)
        );
        assert_eq!(
            trilaterate(&c, &[1.0, -1.0, 1.0]),
            Err(TrilaterationError::NegativeRange)
        );
        let coincident = [c[0], c[1], c[1]];
        assert_eq!(
            trilaterate(&coincident, &[1.0; 3]),
            Err(TrilaterationError::CoincidentCentres)
        );
        let collinear = [c[0], c[1], Vector3::new(5.0, 0.0, 0.0)];
        assert_eq!(
            trilaterate(&collinear, &[1.0; 3]),
            Err(TrilaterationError::CollinearCentres)
        );
        match trilaterate(&c, &[0.1, 0.1, 0.1]) {
            Err(TrilaterationError::NoIntersection { miss_m }) => assert!(miss_m > 0.5),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn handedness_degenerate_inputs() {
        let c = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        let s = [Vector3::z(), -Vector3::z()];
        let b = [Vector3::x(), Vector3::y(), Vector3::z()];
        assert!(select_by_handedness(&s, &c, &b).is_some());
        let zero = [Vector3::zeros(), Vector3::y(), Vector3::z()];
        assert!(select_by_handedness(&s, &c, &zero).is_none());
        let nan = [Vector3::new(f64::NAN, 0.0, 0.0), Vector3::y(), Vector3::z()];
        assert!(select_by_handedness(&s, &c, &nan).is_none());
        // Coplanar bearings: the midpoint.
        let flat = [Vector3::x(), Vector3::y(), Vector3::new(1.0, 1.0, 0.0)];
        assert_eq!(select_by_handedness(&s, &c, &flat), Some(Vector3::zeros()));
    }
}
