//! Absolute pose from two bearings with a known vertical direction (the "up2p" problem).

use crate::geometry::{Pose, PoseSolutions, is_finite, try_unit};
use nalgebra::{Rotation3, Translation3, Vector3};

/// Below this |vertical component| of both (levelled, unit) bearings, the depths are not
/// determined by the height difference: the bearings are horizontal and the rig may be
/// anywhere on a circle (an empty result).
pub const MIN_VERTICAL_COMPONENT: f64 = 1e-12;

/// Below this squared norm of the quadratic's leading coefficient (relative to the unit
/// bearings) the depth equation is degenerate (the two bearings are the same horizontal
/// direction scaled): an empty result.
pub const MIN_LEADING_COEFFICIENT: f64 = 1e-18;

/// Below this horizontal separation of the two points relative to the scene size, the heading
/// is not determined (the points are on one vertical line): an empty result.
pub const MIN_HORIZONTAL_SEPARATION: f64 = 1e-12;

/// The rotation `level_from_rig` that takes the rig's unit `up_in_rig` to `+z` (the
/// smallest such rotation; a half turn about x when up is `−z`). `None` for a zero or
/// non-finite vector.
pub fn level_from_rig(up_in_rig: &Vector3<f64>) -> Option<Rotation3<f64>> {
    let u = try_unit(up_in_rig)?;
    Rotation3::rotation_between(&u, &Vector3::z()).or_else(|| {
        (u.z < 0.0).then(|| Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI))
    })
}

/// Every pose `world_from_rig` under which two bearings see two world points, when the
/// rig's up direction is known (world up is `+z`): two of the four unknowns (heading and
/// position) per bearing.
///
/// # Equation
/// With `f₁, f₂` the unit bearings levelled by `R₀ = level_from_rig(up)` (`R₀ up = z`), the
/// pose is `R = R_z(ψ) R₀`, `t`, with depths `λ₁, λ₂ > 0`: `t + λₖ R_z(ψ) fₖ = Pₖ`. The
/// difference `D = P₁ − P₂ = R_z(ψ)(λ₁ f₁ − λ₂ f₂)`; its z row does not depend on `ψ`:
///
/// ```text
/// λ₁ f₁z − λ₂ f₂z = D_z                      (linear: λ₂ = p λ₁ + q)
/// |λ₁ f₁,xy − λ₂ f₂,xy|² = |D_xy|²            (a quadratic in λ₁)
/// ψ = atan2(D_xy) − atan2(λ₁ f₁,xy − λ₂ f₂,xy),   t = P₁ − λ₁ R_z(ψ) f₁
/// ```
///
/// (the linear equation is solved for the depth whose bearing has the larger vertical
/// component). At most two solutions, both with positive depths.
///
/// # Convention
/// Bearings in the rig frame (any non-zero finite length), points in the world frame, world
/// up `+z`; the result is `world_from_rig` (see [`crate::geometry::Pose`]) and maps
/// `up_in_rig` exactly to `+z`. An empty list for degenerate input: non-finite or zero
/// vectors, both bearings horizontal, coincident bearings, points on one vertical line.
///
/// # References
/// Z. Kukelova, M. Bujnak, T. Pajdla, "Closed-form solutions to minimal absolute pose
/// problems with known vertical direction", ACCV 2010; C. Sweeney, J. Flynn, M. Turk,
/// "Solving for relative pose with a partially known rotation is a quadratic eigenvalue
/// problem", 3DV 2014 (the same reduction of the rotation to one angle).
///
/// # Units
/// Metres (any consistent length unit); the heading is in radians inside the pose.
///
/// # Role in vgps
/// A **cross-check** and a building block for a known vertical: the matcher does not call it
/// (with a known vertical it keeps [`crate::solvers::p3p()`] and gates hypotheses by their tilt);
/// `examples/up2p_conditioning.rs` and the `solvers` benchmark measure it.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::{Pose, bearing_in_rig};
/// use vgps_geometry::solvers::up2p;
/// let truth = Pose::new(Vector3::new(3.0, -2.0, 1.5), Vector3::new(0.0, 0.0, 0.8));
/// let points = [Vector3::new(20.0, 5.0, 6.0), Vector3::new(-4.0, 30.0, 9.0)];
/// let bearings = [bearing_in_rig(&truth, &points[0]).unwrap(), bearing_in_rig(&truth, &points[1]).unwrap()];
/// let poses = up2p(&Vector3::z(), &bearings, &points);
/// assert!(poses.iter().any(|p| (p.translation.vector - truth.translation.vector).norm() < 1e-9));
/// ```
pub fn up2p(
    up_in_rig: &Vector3<f64>,
    bearings_in_rig: &[Vector3<f64>; 2],
    points_in_world: &[Vector3<f64>; 2],
) -> PoseSolutions {
    let mut solutions = PoseSolutions::new();
    let Some(level) = level_from_rig(up_in_rig) else {
        return solutions;
    };
    if !points_in_world.iter().all(is_finite) {
        return solutions;
    }
    let (Some(b1), Some(b2)) = (try_unit(&bearings_in_rig[0]), try_unit(&bearings_in_rig[1]))
    else {
        return solutions;
    };
    up2p_levelled(
        &level,
        &[level * b1, level * b2],
        points_in_world,
        &mut solutions,
    );
    solutions
}

/// The body of [`up2p`] on bearings already levelled (`f = level · b`, unit), pushing every
/// solution into `solutions` (which must have room for two). For callers that solve many
/// point pairs for the same bearings.
pub fn up2p_levelled(
    level_from_rig: &Rotation3<f64>,
    levelled: &[Vector3<f64>; 2],
    points_in_world: &[Vector3<f64>; 2],
    solutions: &mut PoseSolutions,
) {
    // Solve the z row for the depth of the bearing with the larger vertical component.
    let swap = levelled[0].z.abs() > levelled[1].z.abs();
    let (f1, f2, p1, p2) = if swap {
        (
            levelled[1],
            levelled[0],
            points_in_world[1],
            points_in_world[0],
        )
    } else {
        (
            levelled[0],
            levelled[1],
            points_in_world[0],
            points_in_world[1],
        )
    };
    if f2.z.abs() < MIN_VERTICAL_COMPONENT {
        return;
    }
    let d = p1 - p2;
    let dxy2 = d.x * d.x + d.y * d.y;
    let scale2 = d.norm_squared();
    if dxy2.is_nan() || dxy2 <= MIN_HORIZONTAL_SEPARATION * MIN_HORIZONTAL_SEPARATION * scale2 {
        return;
    }
    // λ₂ = p λ₁ + q.
    let p = f1.z / f2.z;
    let q = -d.z / f2.z;
    // w = f₁,xy − p f₂,xy; |λ₁ w − q f₂,xy|² = |D_xy|².
    let (wx, wy) = (f1.x - p * f2.x, f1.y - p * f2.y);
    let a = wx * wx + wy * wy;
    if a < MIN_LEADING_COEFFICIENT {
        return;
    }
    let b = -2.0 * q * (wx * f2.x + wy * f2.y);
    let c = q * q * (f2.x * f2.x + f2.y * f2.y) - dxy2;
    let disc = b * b - 4.0 * a * c;
    if disc.is_nan() || disc < 0.0 {
        return;
    }
    let sq = disc.sqrt();
    // Numerically stable roots.
    let k = -0.5 * (b + b.signum() * sq);
    let roots = if k == 0.0 {
        [-b / (2.0 * a), -b / (2.0 * a)]
    } else {
        [k / a, c / k]
    };
    let heading_d = d.y.atan2(d.x);
    for (n, &l1) in roots.iter().enumerate() {
        if n == 1 && sq == 0.0 {
            break;
        }
        let l2 = p * l1 + q;
        if !(l1 > 0.0 && l2 > 0.0 && l1.is_finite() && l2.is_finite()) {
            continue;
        }
        let v = f1 * l1 - f2 * l2;
        let psi = heading_d - v.y.atan2(v.x);
        let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), psi);
        let t = p1 - yaw * (f1 * l1);
        let rotation = yaw * level_from_rig;
        if !is_finite(&t) {
            continue;
        }
        if solutions.is_full() {
            return;
        }
        solutions.push(Pose::from_parts(Translation3::from(t), rotation));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::bearing_in_rig;
    use crate::synthetic::{pose_error, random_unit_vector, rng};
    use rand::RngExt;

    /// A random pose whose up is `up_in_rig` (random heading and tilt), and two points in
    /// front of it at 5–100 m.
    fn problem(seed: u64) -> (Pose, Vector3<f64>, [Vector3<f64>; 2]) {
        let mut r = rng(seed);
        let up = random_unit_vector(&mut r);
        let level = level_from_rig(&up).unwrap();
        let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), r.random_range(-3.0..3.0));
        let rotation = yaw * level;
        let t = Vector3::new(
            r.random_range(-50.0..50.0),
            r.random_range(-50.0..50.0),
            r.random_range(-5.0..5.0),
        );
        let pose = Pose::from_parts(Translation3::from(t), rotation);
        let points = [0, 1].map(|_| t + random_unit_vector(&mut r) * r.random_range(5.0..100.0));
        (pose, up, points)
    }

    #[test]
    fn recovers_the_true_pose_among_its_solutions() {
        let mut worst: f64 = 0.0;
        for seed in 0..2000 {
            let (truth, up, points) = problem(seed);
            let bearings = points.map(|p| bearing_in_rig(&truth, &p).unwrap() * 3.0);
            let poses = up2p(&up, &bearings, &points);
            assert!(poses.len() <= 2);
            let best = poses
                .iter()
                .map(|p| {
                    let (dt, dr) = pose_error(p, &truth);
                    dt / 100.0 + dr
                })
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(best);
            // Every solution sees both points exactly and keeps the vertical.
            for p in &poses {
                assert!(((p.rotation * up).z - 1.0).abs() < 1e-12);
                for (b, x) in bearings.iter().zip(&points) {
                    let predicted = bearing_in_rig(p, x).unwrap();
                    assert!(crate::geometry::angle_between(&predicted, b) < 1e-8);
                }
            }
        }
        // The true pose is found in every non-degenerate random problem.
        assert!(worst < 1e-7, "worst error {worst}");
    }

    #[test]
    fn degenerate_inputs_give_no_solution() {
        let truth = Pose::new(Vector3::new(1.0, 2.0, 0.0), Vector3::new(0.0, 0.0, 0.3));
        // Both points at the rig's height: horizontal bearings.
        let flat = [Vector3::new(10.0, 3.0, 0.0), Vector3::new(-4.0, 12.0, 0.0)];
        let b = flat.map(|p| bearing_in_rig(&truth, &p).unwrap());
        assert!(up2p(&Vector3::z(), &b, &flat).is_empty());
        // Points on one vertical line.
        let vertical = [Vector3::new(10.0, 3.0, 2.0), Vector3::new(10.0, 3.0, 9.0)];
        let b = vertical.map(|p| bearing_in_rig(&truth, &p).unwrap());
        assert!(up2p(&Vector3::z(), &b, &vertical).is_empty());
        // Zero, non-finite, coincident.
        let points = [Vector3::new(10.0, 3.0, 2.0), Vector3::new(-3.0, 8.0, 5.0)];
        let b = points.map(|p| bearing_in_rig(&truth, &p).unwrap());
        assert!(up2p(&Vector3::zeros(), &b, &points).is_empty());
        assert!(up2p(&Vector3::z(), &[Vector3::zeros(), b[1]], &points).is_empty());
        assert!(up2p(&Vector3::z(), &[b[0], b[0]], &points).is_empty());
        let nan = [Vector3::new(f64::NAN, 0.0, 1.0), points[1]];
        assert!(up2p(&Vector3::z(), &b, &nan).is_empty());
        // Up pointing down is a valid (upside-down) rig.
        let down = level_from_rig(&-Vector3::z()).unwrap();
        assert!(((down * -Vector3::z()) - Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn noisy_bearings_give_a_near_pose() {
        // 0.05° noise, points at 20–80 m in random directions: the position error stays within a
        // metre in 90 % (the rest: near-degenerate geometry, e.g. points at equal elevation).
        let mut r = rng(77);
        let mut good = 0;
        let trials = 500;
        for seed in 0..trials {
            let (truth, up, _) = problem(seed);
            let t = truth.translation.vector;
            let points = [0, 1].map(|_| {
                let d = random_unit_vector(&mut r);
                t + d * r.random_range(20.0..80.0)
            });
            let bearings = points.map(|p| {
                crate::synthetic::perturb_bearing(
                    &mut r,
                    &bearing_in_rig(&truth, &p).unwrap(),
                    0.05f64.to_radians(),
                )
            });
            let poses = up2p(&up, &bearings, &points);
            if poses
                .iter()
                .any(|p| (p.translation.vector - t).norm() < 1.0)
            {
                good += 1;
            }
        }
        assert!(good >= trials * 90 / 100, "{good} of {trials}");
    }
}
