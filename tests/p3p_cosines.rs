//! Behaviour of the law-of-cosines P3P solver (`solvers::p3p_cosines`).
use nalgebra::{Rotation3, Translation3, Vector3};
use vgps::geometry::{Pose, bearing_in_rig};
use vgps::solvers::p3p_cosines;
use vgps::solvers::p3p_cosines::{RangeSolutions, p3p_cosines_ranges};
use vgps::synthetic::{P3pProblem, random_rotation, random_unit_vector, rng};

/// Position error (m) and rotation error (Frobenius norm of the matrix difference, ≈ √2 ×
/// angle, precise near zero unlike an acos-based angle).
fn errors(estimate: &Pose, truth: &Pose) -> (f64, f64) {
    (
        (estimate.translation.vector - truth.translation.vector).norm(),
        (estimate.rotation.matrix() - truth.rotation.matrix()).norm(),
    )
}

fn pose_is_finite(p: &Pose) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.matrix().iter().all(|v| v.is_finite())
}

/// The acceptance test of the solver: over 10⁵ random omnidirectional problems the true
/// pose is among the solutions (position within 10⁻⁹ × scene size) in ≥ 99.999 % of them,
/// and no output is ever non-finite.
#[test]
fn finds_the_true_pose_in_random_omni_problems() {
    let scene = 50.0;
    let trials = 100_000;
    let mut r = rng(2024);
    let mut missed = 0;
    let mut worst_position = 0.0_f64;
    let mut worst_rotation = 0.0_f64;
    let mut solutions = 0;
    for _ in 0..trials {
        let problem = P3pProblem::random_omni(&mut r, scene);
        let poses = p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world);
        assert!(poses.iter().all(pose_is_finite));
        solutions += poses.len();
        let best = poses
            .iter()
            .map(|p| errors(p, &problem.world_from_rig))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        match best {
            Some((dp, dr)) if dp <= 1e-9 * scene => {
                worst_position = worst_position.max(dp);
                worst_rotation = worst_rotation.max(dr);
            }
            _ => missed += 1,
        }
    }
    println!(
        "missed {missed}/{trials}, worst position {worst_position:.2e} m, worst rotation \
         {worst_rotation:.2e}, mean solutions {:.3}",
        solutions as f64 / trials as f64
    );
    assert!(missed <= trials / 100_000, "missed {missed}");
    assert!(worst_rotation < 1e-8);
}

/// Every returned pose (not only the true one) explains the data: it reprojects the three
/// landmarks onto the given bearings.
#[test]
fn every_solution_reprojects_its_bearings() {
    let mut r = rng(7);
    let mut checked = 0;
    for _ in 0..20_000 {
        let problem = P3pProblem::random_omni(&mut r, 10.0);
        for pose in p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world) {
            for (x, d) in problem.points_in_world.iter().zip(&problem.bearings_in_rig) {
                let b = bearing_in_rig(&pose, x).unwrap();
                assert!((b - d).norm() < 1e-7, "{}", (b - d).norm());
            }
            checked += 1;
        }
    }
    assert!(checked > 20_000);
}

/// An equilateral triangle seen from its axis with pairwise bearing angles below 60° has
/// exactly four solutions: the truth (r, r, r) and the three (r(2c − 1), r, r) and
/// permutations, with c the cosine of the pairwise angle. All four are found and verified.
#[test]
fn symmetric_configuration_has_four_solutions() {
    let mut r = rng(8);
    for height in [1.5, 3.0, 10.0] {
        for _ in 0..20 {
            // Circumradius 1 triangle at z = 0, rig on the axis at `height`, then a random
            // rigid motion of everything.
            let motion = Pose::from_parts(
                Translation3::from(random_unit_vector(&mut r) * 5.0),
                random_rotation(&mut r),
            );
            let tri: [Vector3<f64>; 3] = std::array::from_fn(|k| {
                let a = k as f64 * 2.0 * std::f64::consts::PI / 3.0;
                motion * nalgebra::Point3::new(a.cos(), a.sin(), 0.0)
            })
            .map(|p| p.coords);
            let rig = Pose::from_parts(
                Translation3::from(motion * nalgebra::Point3::new(0.0, 0.0, height)),
                random_rotation(&mut r),
            );
            let problem = P3pProblem::from_points(rig, tri);
            let ranges = p3p_cosines_ranges(&problem.bearings_in_rig, &problem.points_in_world);
            let rr = (1.0 + height * height).sqrt();
            let c = problem.bearings_in_rig[0].dot(&problem.bearings_in_rig[1]);
            let other = rr * (2.0 * c - 1.0);
            let mut expected: RangeSolutions = RangeSolutions::new();
            expected.push([other, rr, rr]);
            expected.push([rr, other, rr]);
            expected.push([rr, rr, other]);
            expected.push([rr, rr, rr]);
            assert_eq!(ranges.len(), 4, "h={height}: {ranges:?}");
            for e in &expected {
                assert!(
                    ranges
                        .iter()
                        .any(|g| (0..3).all(|k| (g[k] - e[k]).abs() < 1e-9 * rr)),
                    "h={height}: expected {e:?} in {ranges:?}"
                );
            }
            let poses = p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world);
            assert_eq!(poses.len(), 4);
            for pose in &poses {
                for (x, d) in tri.iter().zip(&problem.bearings_in_rig) {
                    assert!((bearing_in_rig(pose, x).unwrap() - d).norm() < 1e-9);
                }
            }
            assert!(poses.iter().any(|p| errors(p, &rig).0 < 1e-9));
        }
    }
}

/// Above 60° between the bearings (the rig close to the triangle) only the truth remains.
#[test]
fn symmetric_configuration_close_up_has_one_solution() {
    let tri = [0.0, 1.0, 2.0].map(|k: f64| {
        let a = k * 2.0 * std::f64::consts::PI / 3.0;
        Vector3::new(a.cos(), a.sin(), 0.0)
    });
    let rig = Pose::from_parts(Translation3::new(0.0, 0.0, 0.8), Rotation3::identity());
    let problem = P3pProblem::from_points(rig, tri);
    let poses = p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world);
    assert_eq!(poses.len(), 1);
    assert!(errors(&poses[0], &rig).0 < 1e-12);
}

#[test]
fn bearings_of_any_length_are_normalised() {
    let mut r = rng(9);
    for _ in 0..1000 {
        let problem = P3pProblem::random_omni(&mut r, 20.0);
        let scaled = [
            problem.bearings_in_rig[0] * 1e-3,
            problem.bearings_in_rig[1] * 7.0,
            problem.bearings_in_rig[2] * 1e5,
        ];
        let a = p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world);
        let b = p3p_cosines(&scaled, &problem.points_in_world);
        assert_eq!(a.len(), b.len());
        for (pa, pb) in a.iter().zip(&b) {
            assert!(errors(pa, pb).0 < 1e-9 && errors(pa, pb).1 < 1e-9);
        }
    }
}

/// The rig exactly between two landmarks (anti-parallel bearings) is a valid problem.
#[test]
fn anti_parallel_bearings_are_solved() {
    let points = [
        Vector3::new(-3.0, 0.0, 0.0),
        Vector3::new(5.0, 0.0, 0.0),
        Vector3::new(1.0, 4.0, 2.0),
    ];
    let mut r = rng(10);
    for _ in 0..100 {
        let rig = Pose::from_parts(Translation3::new(0.5, 0.0, 0.0), random_rotation(&mut r));
        let problem = P3pProblem::from_points(rig, points);
        let poses = p3p_cosines(&problem.bearings_in_rig, &points);
        assert!(poses.iter().any(|p| errors(p, &rig).0 < 1e-9), "{poses:?}");
    }
}

#[test]
fn degenerate_inputs_give_no_solution() {
    let mut r = rng(11);
    let problem = P3pProblem::random_omni(&mut r, 10.0);
    let (d, x) = (problem.bearings_in_rig, problem.points_in_world);
    assert!(!p3p_cosines(&d, &x).is_empty());
    // Collinear landmarks, seen from off the line.
    let line = [x[0], x[0] + (x[1] - x[0]) * 0.5, x[1]];
    let collinear = P3pProblem::from_points(problem.world_from_rig, line);
    assert!(p3p_cosines(&collinear.bearings_in_rig, &line).is_empty());
    // Duplicate points.
    assert!(p3p_cosines(&d, &[x[0], x[0], x[2]]).is_empty());
    assert!(p3p_cosines(&d, &[x[0], x[1], x[1]]).is_empty());
    // Zero, NaN and infinite bearings or points.
    for bad in [Vector3::zeros(), Vector3::new(f64::NAN, 1.0, 0.0)] {
        assert!(p3p_cosines(&[d[0], bad, d[2]], &x).is_empty());
        if bad.iter().any(|v| !v.is_finite()) {
            assert!(p3p_cosines(&d, &[x[0], x[1], bad]).is_empty());
        }
    }
    let inf = Vector3::new(0.0, f64::INFINITY, 0.0);
    assert!(p3p_cosines(&[inf, d[1], d[2]], &x).is_empty());
    assert!(p3p_cosines(&d, &[inf, x[1], x[2]]).is_empty());
    // Parallel bearings.
    assert!(p3p_cosines(&[d[0], d[0] * 2.0, d[2]], &x).is_empty());
    assert!(p3p_cosines(&[d[0], d[1], d[1]], &x).is_empty());
}

/// Near-degenerate but valid inputs never produce non-finite output.
#[test]
fn near_degenerate_inputs_stay_finite() {
    let mut r = rng(12);
    for _ in 0..20_000 {
        let problem = P3pProblem::random_omni(&mut r, 10.0);
        let mut d = problem.bearings_in_rig;
        let mut x = problem.points_in_world;
        // Push one configuration towards a degeneracy at random.
        let eps = 10f64.powi(-(r.random_range(3..15)));
        match r.random_range(0..3) {
            0 => d[1] = d[0] + random_unit_vector(&mut r) * eps,
            1 => x[2] = x[0] + (x[1] - x[0]) * 0.3 + random_unit_vector(&mut r) * eps,
            _ => x[1] = x[0] + random_unit_vector(&mut r) * eps,
        }
        for pose in p3p_cosines(&d, &x) {
            assert!(pose_is_finite(&pose));
        }
    }
}

use rand::RngExt;
