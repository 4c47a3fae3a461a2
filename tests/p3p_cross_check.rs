//! Cross-check of the two P3P solvers: Lambda Twist (`p3p`) and the law-of-cosines search
//! (`p3p_cosines`) must return the same solution set on random omni-directional problems.
use vgps::geometry::{Pose, PoseSolutions};
use vgps::solvers::{p3p, p3p_cosines};
use vgps::synthetic::{P3pProblem, pose_error, rng};

/// Number of random problems of the cross-check.
const TRIALS: usize = 100_000;
/// Two poses are "the same solution" within this relative position and rotation error.
const SAME_POSITION_REL: f64 = 1e-6;
const SAME_ROTATION_RAD: f64 = 1e-6;

fn contains(set: &PoseSolutions, pose: &Pose, scale: f64) -> bool {
    set.iter().any(|s| {
        let (dp, dr) = pose_error(s, pose);
        dp <= SAME_POSITION_REL * scale && dr <= SAME_ROTATION_RAD
    })
}

#[test]
fn p3p_and_p3p_cosines_return_the_same_solutions() {
    let scene = 50.0;
    let mut r = rng(2024);
    let mut same_sets = 0usize;
    let mut truth_in_fast = 0usize;
    let mut truth_in_cosines = 0usize;
    let mut count_hist = [[0usize; 5]; 2];
    for _ in 0..TRIALS {
        let problem = P3pProblem::random_omni(&mut r, scene);
        let fast = p3p(&problem.bearings_in_rig, &problem.points_in_world);
        let slow = p3p_cosines(&problem.bearings_in_rig, &problem.points_in_world);
        for s in fast.iter().chain(slow.iter()) {
            assert!(s.translation.vector.iter().all(|x| x.is_finite()));
            assert!(s.rotation.matrix().iter().all(|x| x.is_finite()));
        }
        count_hist[0][fast.len()] += 1;
        count_hist[1][slow.len()] += 1;
        let agree = fast.len() == slow.len()
            && fast.iter().all(|s| contains(&slow, s, scene))
            && slow.iter().all(|s| contains(&fast, s, scene));
        same_sets += usize::from(agree);
        truth_in_fast += usize::from(contains(&fast, &problem.world_from_rig, scene));
        truth_in_cosines += usize::from(contains(&slow, &problem.world_from_rig, scene));
    }
    let rate = |n: usize| n as f64 / TRIALS as f64;
    println!(
        "same solution set: {:.6}; truth found: p3p {:.6}, p3p_cosines {:.6}; \
         solution counts 0..4: p3p {:?}, p3p_cosines {:?}",
        rate(same_sets),
        rate(truth_in_fast),
        rate(truth_in_cosines),
        count_hist[0],
        count_hist[1]
    );
    assert!(rate(truth_in_fast) >= 0.99999);
    assert!(rate(truth_in_cosines) >= 0.99999);
    assert!(
        rate(same_sets) >= 0.9999,
        "solution sets agree in {}",
        rate(same_sets)
    );
}
