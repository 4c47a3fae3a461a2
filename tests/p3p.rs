//! Tests of the Lambda Twist P3P solver `vgps::solvers::p3p` on omnidirectional problems.
use nalgebra::{Matrix3, Point3, Rotation3, Translation3, Vector3};
use vgps::geometry::{Pose, angle_between};
use vgps::solvers::p3p;
use vgps::synthetic::{P3pProblem, random_pose, random_unit_vector, rng};

const SCENE: f64 = 50.0;

/// (position error, rotation error angle), the angle from the chordal distance so that it
/// keeps full precision near zero: ‖R₁ − R₂‖_F = 2√2 sin(θ/2).
fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    let dp = (a.translation.vector - b.translation.vector).norm();
    let chord = (a.rotation.matrix() - b.rotation.matrix()).norm();
    let dr = 2.0 * (chord / (2.0 * 2f64.sqrt())).min(1.0).asin();
    (dp, dr)
}

/// The solution closest to the truth: (position error, rotation error).
fn closest(solutions: &[Pose], truth: &Pose) -> Option<(f64, f64)> {
    solutions
        .iter()
        .map(|s| pose_error(s, truth))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Largest angle between a given bearing and the bearing the pose predicts.
fn max_bearing_error(pose: &Pose, bearings: &[Vector3<f64>; 3], points: &[Vector3<f64>; 3]) -> f64 {
    bearings
        .iter()
        .zip(points)
        .map(|(b, p)| {
            let in_rig = pose.inverse_transform_point(&Point3::from(*p)).coords;
            angle_between(b, &in_rig)
        })
        .fold(0.0, f64::max)
}

/// Orthonormality error ‖RᵀR − I‖∞ and determinant.
fn rotation_quality(pose: &Pose) -> (f64, f64) {
    let r: &Matrix3<f64> = pose.rotation.matrix();
    let e = (r.transpose() * r - Matrix3::identity()).amax();
    (e, r.determinant())
}

/// The bits of a pose's rotation and translation, to compare two solutions exactly.
fn pose_bits(pose: &Pose) -> Vec<u64> {
    let mut v: Vec<u64> = pose.rotation.matrix().iter().map(|x| x.to_bits()).collect();
    v.extend(pose.translation.vector.iter().map(|x| x.to_bits()));
    v
}

fn all_finite(pose: &Pose) -> bool {
    pose.to_homogeneous().iter().all(|e| e.is_finite())
}

#[test]
fn true_pose_is_recovered_in_random_omni_problems() {
    let mut r = rng(20240601);
    // VGPS_P3P_SAMPLES overrides the sample size for a longer run.
    let n = std::env::var("VGPS_P3P_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000usize);
    let mut found = 0usize;
    let mut worst_found_position = 0.0f64;
    let mut worst_found_rotation = 0.0f64;
    let mut histogram = [0usize; 5];
    let mut misses = Vec::new();
    for _ in 0..n {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        let s = p3p(&p.bearings_in_rig, &p.points_in_world);
        histogram[s.len()] += 1;
        match closest(&s, &p.world_from_rig) {
            Some((dp, dr)) if dp <= 1e-9 * SCENE => {
                found += 1;
                worst_found_position = worst_found_position.max(dp);
                worst_found_rotation = worst_found_rotation.max(dr);
            }
            other => misses.push(other.map(|(dp, _)| dp)),
        }
    }
    let rate = found as f64 / n as f64;
    println!(
        "p3p: true pose within 1e-9 x scene in {found}/{n} = {:.6}% of omni problems; \
         worst position error among those {worst_found_position:.3e} m, rotation \
         {worst_found_rotation:.3e} rad; solution-count histogram {histogram:?}; closest \
         position error (m) of the misses: {misses:?}",
        100.0 * rate
    );
    assert!(rate >= 0.99999, "recovery rate {rate}");
    assert!(worst_found_rotation < 1e-8);
}

#[test]
fn every_solution_reproduces_the_bearings() {
    let mut r = rng(7);
    let mut worst = 0.0f64;
    let mut count = 0usize;
    for _ in 0..20_000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        for s in &p3p(&p.bearings_in_rig, &p.points_in_world) {
            worst = worst.max(max_bearing_error(s, &p.bearings_in_rig, &p.points_in_world));
            count += 1;
        }
    }
    println!("p3p: {count} solutions, worst bearing error {worst:.3e} rad");
    assert!(count > 20_000);
    assert!(worst <= 1e-9, "worst bearing error {worst}");
}

#[test]
fn known_pose_with_points_behind_the_rig() {
    // Two of the three landmarks are behind the rig (negative x in the rig frame).
    let truth = Pose::from_parts(
        Translation3::new(3.0, -7.0, 1.5),
        Rotation3::from_euler_angles(0.1, -0.2, 2.5),
    );
    let points_in_rig = [
        Vector3::new(-10.0, 2.0, 1.0),
        Vector3::new(-3.0, -8.0, -2.0),
        Vector3::new(5.0, 0.5, 4.0),
    ];
    let points = points_in_rig
        .map(|p| truth * Point3::from(p))
        .map(|p| p.coords);
    let bearings = points_in_rig.map(|p| p.normalize());
    let s = p3p(&bearings, &points);
    let (dp, dr) = closest(&s, &truth).expect("no solution");
    assert!(dp < 1e-11 && dr < 1e-12, "{dp} {dr}");
}

#[test]
fn bearing_length_does_not_matter() {
    let mut r = rng(11);
    for _ in 0..1000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        let scaled = [
            p.bearings_in_rig[0] * 1e-3,
            p.bearings_in_rig[1] * 7.0,
            p.bearings_in_rig[2] * 1e5,
        ];
        let a = p3p(&p.bearings_in_rig, &p.points_in_world);
        let b = p3p(&scaled, &p.points_in_world);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            let (dp, dr) = pose_error(x, y);
            assert!(dp < 1e-9 * SCENE && dr < 1e-9);
        }
    }
}

#[test]
fn moving_the_world_moves_the_poses() {
    let mut r = rng(12);
    let mut checked = 0;
    for _ in 0..2000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        // A rigid change of world frame: new_from_old.
        let new_from_old = random_pose(&mut r, 1e3);
        let moved = p
            .points_in_world
            .map(|x| (new_from_old * Point3::from(x)).coords);
        let a = p3p(&p.bearings_in_rig, &p.points_in_world);
        let b = p3p(&p.bearings_in_rig, &moved);
        assert_eq!(a.len(), b.len());
        for sa in &a {
            let expected = new_from_old * sa;
            let (dp, dr) = b
                .iter()
                .map(|sb| pose_error(sb, &expected))
                .min_by(|x, y| x.0.total_cmp(&y.0))
                .unwrap();
            assert!(dp < 1e-7 && dr < 1e-9, "{dp} {dr}");
            checked += 1;
        }
    }
    assert!(checked >= 2000);
}

#[test]
fn scaling_the_world_scales_the_position() {
    let mut r = rng(13);
    for _ in 0..1000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        let k = 1234.5;
        let scaled = p.points_in_world.map(|x| x * k);
        let a = p3p(&p.bearings_in_rig, &p.points_in_world);
        let b = p3p(&p.bearings_in_rig, &scaled);
        assert_eq!(a.len(), b.len());
        for (sa, sb) in a.iter().zip(&b) {
            let dp = (sa.translation.vector * k - sb.translation.vector).norm();
            let (_, dr) = pose_error(sa, sb);
            assert!(dp < 1e-9 * SCENE * k && dr < 1e-9, "{dp} {dr}");
        }
    }
}

#[test]
fn degenerate_inputs_give_no_solution() {
    let mut r = rng(14);
    let p = P3pProblem::random_omni(&mut r, SCENE);
    let (b, x) = (p.bearings_in_rig, p.points_in_world);
    assert!(!p3p(&b, &x).is_empty());
    let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    for v in bad {
        for i in 0..3 {
            let mut bb = b;
            bb[i].y = v;
            assert!(p3p(&bb, &x).is_empty());
            let mut xx = x;
            xx[i].z = v;
            assert!(p3p(&b, &xx).is_empty());
        }
    }
    // Zero bearing.
    let mut bb = b;
    bb[1] = Vector3::zeros();
    assert!(p3p(&bb, &x).is_empty());
    // Parallel and antiparallel bearings.
    let mut bb = b;
    bb[2] = b[0] * 3.0;
    assert!(p3p(&bb, &x).is_empty());
    bb[2] = -b[0];
    assert!(p3p(&bb, &x).is_empty());
    // Coincident points.
    let mut xx = x;
    xx[1] = x[0];
    assert!(p3p(&b, &xx).is_empty());
    // Collinear points.
    let mut xx = x;
    xx[2] = x[0] + (x[1] - x[0]) * 2.5;
    assert!(p3p(&b, &xx).is_empty());
    // All points equal, all bearings equal.
    assert!(p3p(&[b[0]; 3], &[x[0]; 3]).is_empty());
    // Overflowing coordinates.
    let xx = x.map(|p| p * 1e300);
    assert!(p3p(&b, &xx).is_empty());
}

/// Noisy bearings and near-degenerate configurations: the class of inputs on which solvers
/// that take the square root of a possibly negative quotient return NaN poses.
#[test]
fn noisy_and_near_degenerate_samples_never_give_non_finite_or_improper_poses() {
    let mut r = rng(15);
    let sigma = 0.5f64.to_radians();
    let n = 100_000;
    let mut solutions = 0usize;
    let mut worst_orthonormality = 0.0f64;
    let mut worst_det = 0.0f64;
    for i in 0..n {
        let base = P3pProblem::random_omni(&mut r, SCENE);
        let mut points = base.points_in_world;
        let c = base.world_from_rig.translation.vector;
        match i % 5 {
            // Plain noisy omni problem.
            0 => {}
            // Nearly collinear world points.
            1 => {
                let eps = 10f64.powf(-(1.0 + 8.0 * (i as f64 / n as f64)));
                points[2] =
                    points[0] + (points[1] - points[0]) * 1.7 + random_unit_vector(&mut r) * eps;
            }
            // Nearly parallel bearings: two points almost on one ray.
            2 => {
                let d = points[0] - c;
                points[1] = c + d * 0.5 + random_unit_vector(&mut r) * 1e-4;
            }
            // The rig almost in the plane of the points (coplanar bearings).
            3 => {
                let n = (points[1] - points[0])
                    .cross(&(points[2] - points[0]))
                    .normalize();
                let off = n.dot(&(c - points[0]));
                for q in &mut points {
                    *q += n * (off + 1e-6);
                }
            }
            // Nearly antiparallel bearings (the rig between two points).
            _ => {
                let d = points[0] - c;
                points[1] = c - d * 0.8 + random_unit_vector(&mut r) * 1e-4;
            }
        }
        if points.iter().any(|q| (q - c).norm() < 1e-9) {
            continue;
        }
        let p = P3pProblem::from_points(base.world_from_rig, points).with_noise(&mut r, sigma);
        for s in &p3p(&p.bearings_in_rig, &p.points_in_world) {
            assert!(all_finite(s), "non-finite pose from {p:?}");
            let (e, det) = rotation_quality(s);
            worst_orthonormality = worst_orthonormality.max(e);
            worst_det = worst_det.max((det - 1.0).abs());
            // Positive ranges: every point lies ahead along its bearing.
            for (b, q) in p.bearings_in_rig.iter().zip(&p.points_in_world) {
                let in_rig = s.inverse_transform_point(&Point3::from(*q)).coords;
                assert!(b.dot(&in_rig) > 0.0);
            }
            solutions += 1;
        }
    }
    println!(
        "p3p noisy: {solutions} solutions, all finite; worst |RᵀR − I| {worst_orthonormality:.3e}, \
         worst |det − 1| {worst_det:.3e}"
    );
    assert!(solutions > n / 2);
    assert!(worst_orthonormality < 1e-9 && worst_det < 1e-9);
}

/// Bearings prepared once (`P3pBearings`) give `p3p`'s solutions bit for bit, for many
/// landmark triples seen along one detection triple (the matcher's use) and on degenerate
/// input; a degenerate bearing triple cannot be prepared, and `p3p` has no solution for it.
#[test]
fn prepared_bearings_give_the_same_solutions_bit_for_bit() {
    use vgps::geometry::PoseSolutions;
    use vgps::solvers::p3p::{P3pBearings, p3p_prepared_into};
    let mut r = rng(16);
    let sigma = 0.5f64.to_radians();
    let mut out = PoseSolutions::new();
    let mut compared = 0usize;
    for i in 0..2_000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        let p = if i % 2 == 0 {
            p
        } else {
            p.with_noise(&mut r, sigma)
        };
        let bearings = p.bearings_in_rig.map(|b| b * (1.0 + 9.0 * (i % 7) as f64));
        let Some(prepared) = P3pBearings::try_new(&bearings) else {
            panic!("random bearings {bearings:?} not prepared");
        };
        // The detection triple against its own points and against other landmark triples.
        for k in 0..5 {
            let points = if k == 0 {
                p.points_in_world
            } else {
                P3pProblem::random_omni(&mut r, SCENE).points_in_world
            };
            p3p_prepared_into(&prepared, &points, &mut out);
            let direct = p3p(&bearings, &points);
            assert_eq!(out.len(), direct.len());
            for (a, b) in out.iter().zip(&direct) {
                assert_eq!(pose_bits(a), pose_bits(b));
            }
            compared += direct.len();
        }
    }
    assert!(compared > 5_000, "{compared} solutions compared");
    let p = P3pProblem::random_omni(&mut r, SCENE);
    let b = p.bearings_in_rig;
    for bad in [
        [b[0], b[1], b[0] * 2.0],
        [b[0], -b[0], b[2]],
        [b[0], Vector3::zeros(), b[2]],
        [b[0], b[1], Vector3::new(f64::NAN, 0.0, 1.0)],
    ] {
        assert!(P3pBearings::try_new(&bad).is_none(), "{bad:?}");
        assert!(p3p(&bad, &p.points_in_world).is_empty());
    }
}

/// With a known vertical (`P3pBearings::with_max_tilt`), P3P returns exactly `p3p`'s
/// solutions whose up is within the tilt, bit for bit: the early rejection by the
/// triangle's frame axes never drops an upright solution, including solutions right at
/// the limit, tilts up to 80° and noisy bearings.
#[test]
fn a_known_vertical_keeps_exactly_the_upright_solutions() {
    use vgps::geometry::PoseSolutions;
    use vgps::solvers::p3p::{P3pBearings, p3p_prepared_into};
    let mut r = rng(17);
    let mut out = PoseSolutions::new();
    let (mut kept, mut dropped) = (0usize, 0usize);
    for i in 0..20_000 {
        let p = P3pProblem::random_omni(&mut r, SCENE);
        let p = if i % 2 == 0 {
            p
        } else {
            p.with_noise(&mut r, 0.2f64.to_radians())
        };
        let solutions = p3p(&p.bearings_in_rig, &p.points_in_world);
        if solutions.is_empty() {
            continue;
        }
        // The up of one solution (so that the limit is met exactly one time in four), else
        // a random direction; limits from 0 to 80°.
        let pick = &solutions[i % solutions.len()];
        let up = if i % 2 == 0 {
            pick.rotation.inverse() * Vector3::z()
        } else {
            random_unit_vector(&mut r)
        };
        let tilt = angle_between(&(pick.rotation * up), &Vector3::z());
        let max_tilt = match i % 4 {
            0 => tilt,
            1 => tilt * 1.5 + 1e-3,
            _ => 1.4 * (i % 97) as f64 / 97.0,
        };
        let Some(prepared) =
            P3pBearings::try_new(&p.bearings_in_rig).and_then(|b| b.with_max_tilt(&up, max_tilt))
        else {
            panic!("problem {i}: not prepared");
        };
        p3p_prepared_into(&prepared, &p.points_in_world, &mut out);
        let expected: Vec<Vec<u64>> = solutions
            .iter()
            .filter(|s| max_tilt >= std::f64::consts::PI || (s.rotation * up).z >= max_tilt.cos())
            .map(pose_bits)
            .collect();
        let got: Vec<Vec<u64>> = out.iter().map(pose_bits).collect();
        assert_eq!(got, expected, "problem {i}, max tilt {max_tilt}");
        kept += got.len();
        dropped += solutions.len() - got.len();
    }
    assert!(
        kept > 5_000 && dropped > 5_000,
        "kept {kept}, dropped {dropped}"
    );
    // Invalid verticals; no constraint from π on.
    let p = P3pProblem::random_omni(&mut r, SCENE);
    let b = P3pBearings::try_new(&p.bearings_in_rig).expect("random bearings");
    let z = Vector3::z();
    assert!(b.with_max_tilt(&(z * 2.0), 0.1).is_none());
    assert!(b.with_max_tilt(&Vector3::zeros(), 0.1).is_none());
    assert!(b.with_max_tilt(&z, -0.1).is_none());
    assert!(b.with_max_tilt(&z, f64::NAN).is_none());
    let all = b.with_max_tilt(&z, std::f64::consts::PI).expect("valid");
    p3p_prepared_into(&all, &p.points_in_world, &mut out);
    assert_eq!(out.len(), p3p(&p.bearings_in_rig, &p.points_in_world).len());
}
