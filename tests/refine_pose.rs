//! Behaviour of `refine_pose`: convergence, non-central bias, Jacobians, covariance
//! consistency, robust losses and degenerate input. All seeds are fixed.

use nalgebra::{Rotation3, Translation3, Vector3, Vector6};
use vgps::geometry::{Pose, Ray};
use vgps::solvers::refine_pose::{
    DEFAULT_SIGMA_RAD, RefineError, RefineOptions, RefinedPose, RobustLoss, angular_residual,
    refine_pose, refine_pose_with_sigmas,
};
use vgps::synthetic::pnp::{
    PnpConfig, PnpProblem, RigModel, nees, perturb_pose, pose_error_vector, position_nees,
};
use vgps::synthetic::rng;

/// (position error in metres, rotation error in radians), accurate to rounding.
fn pose_error(estimate: &Pose, truth: &Pose) -> (f64, f64) {
    let e = pose_error_vector(estimate, truth);
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}

/// RMS distance of the points from the true rig position (metres).
fn rms_range(p: &PnpProblem) -> f64 {
    let c = p.world_from_rig.translation.vector;
    let s: f64 = p
        .points_in_world
        .iter()
        .map(|x| (x - c).norm_squared())
        .sum();
    (s / p.points_in_world.len() as f64).sqrt()
}

fn all_finite(r: &RefinedPose) -> bool {
    r.world_from_rig
        .translation
        .vector
        .iter()
        .all(|x| x.is_finite())
        && r.world_from_rig
            .rotation
            .matrix()
            .iter()
            .all(|x| x.is_finite())
        && r.covariance.iter().all(|x| x.is_finite())
        && r.rms_residual_rad.is_finite()
}

fn noise_free_convergence(rig: RigModel, seed: u64) {
    let mut rng = rng(seed);
    let config = PnpConfig {
        n_points: 20,
        min_range_m: 5.0,
        max_range_m: 50.0,
        rig,
        ..PnpConfig::default()
    };
    let trials = 200;
    let mut worst_relative: f64 = 0.0;
    let mut worst_rotation: f64 = 0.0;
    let mut max_iterations = 0;
    for _ in 0..trials {
        let p = PnpProblem::generate(&mut rng, &config);
        let start = perturb_pose(&mut rng, &p.world_from_rig, 1.0, 5f64.to_radians());
        let r = refine_pose(
            &start,
            &p.rays_in_rig,
            &p.points_in_world,
            &RefineOptions::default(),
        )
        .expect("noise-free refinement converges");
        assert!(r.converged && all_finite(&r));
        let (dp, dr) = pose_error(&r.world_from_rig, &p.world_from_rig);
        worst_relative = worst_relative.max(dp / rms_range(&p));
        worst_rotation = worst_rotation.max(dr);
        max_iterations = max_iterations.max(r.iterations);
        assert!(r.rms_residual_rad < 1e-12, "rms {}", r.rms_residual_rad);
    }
    println!(
        "worst relative position error {worst_relative:.2e}, rotation {worst_rotation:.2e} rad, \
         most iterations {max_iterations}"
    );
    assert!(worst_relative <= 1e-9, "{worst_relative}");
    assert!(worst_rotation <= 1e-9, "{worst_rotation}");
}

#[test]
fn noise_free_central_converges_from_one_metre_and_five_degrees() {
    noise_free_convergence(RigModel::Central, 100);
}

#[test]
fn noise_free_non_central_converges_from_one_metre_and_five_degrees() {
    noise_free_convergence(RigModel::Ladybug, 101);
}

/// The analytic 2×6 Jacobian matches central differences of the residual under the
/// retraction `(exp(δθ)·R, p + δp)`, for central and non-central rays and large residuals.
#[test]
fn jacobian_matches_finite_differences() {
    let mut rng = rng(102);
    let config = PnpConfig {
        n_points: 30,
        min_range_m: 2.0,
        max_range_m: 60.0,
        rig: RigModel::Ladybug,
        outlier_fraction: 0.3,
        ..PnpConfig::default()
    };
    let mut checked = 0;
    for _ in 0..20 {
        let p = PnpProblem::generate(&mut rng, &config);
        // Evaluate away from the truth so residuals are not zero.
        let pose = perturb_pose(&mut rng, &p.world_from_rig, 0.5, 0.05);
        for (ray, x) in p.rays_in_rig.iter().zip(&p.points_in_world) {
            let Some((r0, j)) = angular_residual(&pose, ray, x) else {
                panic!("valid observation rejected");
            };
            if r0.norm() > 1e3 {
                continue; // Frozen near the antipode: zero Jacobian by design.
            }
            for k in 0..6 {
                let h = if k < 3 { 1e-6 } else { 1e-7 };
                let mut e = Vector6::zeros();
                e[k] = h;
                let eval = |sign: f64| {
                    let d = e * sign;
                    let moved = Pose::from_parts(
                        Translation3::from(pose.translation.vector + d.fixed_rows::<3>(0)),
                        Rotation3::from_scaled_axis(d.fixed_rows::<3>(3).into_owned())
                            * pose.rotation,
                    );
                    angular_residual(&moved, ray, x).unwrap().0
                };
                let numeric = (eval(1.0) - eval(-1.0)) / (2.0 * h);
                let analytic = j.column(k).into_owned();
                let scale = 1.0 + analytic.norm() + r0.norm();
                assert!(
                    (numeric - analytic).norm() < 1e-6 * scale,
                    "column {k}: numeric {numeric:?} analytic {analytic:?}"
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 500, "{checked}");
}

/// A Ladybug-like rig modelled as central is biased by its 4 cm camera offsets at 10–30 m;
/// the non-central model removes the bias.
#[test]
fn non_central_model_removes_the_central_bias() {
    let mut rng = rng(103);
    let config = PnpConfig {
        n_points: 30,
        min_range_m: 10.0,
        max_range_m: 30.0,
        rig: RigModel::Ladybug,
        ..PnpConfig::default()
    };
    let options = RefineOptions::default();
    // Noise-free: the central model misses the truth by centimetres, the non-central model
    // recovers it exactly.
    let mut central_errors = Vec::new();
    for _ in 0..50 {
        let p = PnpProblem::generate(&mut rng, &config);
        let central = refine_pose(
            &p.world_from_rig,
            &p.central_rays(),
            &p.points_in_world,
            &options,
        )
        .unwrap();
        let exact = refine_pose(
            &p.world_from_rig,
            &p.rays_in_rig,
            &p.points_in_world,
            &options,
        )
        .unwrap();
        let (dp_c, _) = pose_error(&central.world_from_rig, &p.world_from_rig);
        let (dp_n, dr_n) = pose_error(&exact.world_from_rig, &p.world_from_rig);
        assert!(dp_n < 1e-9 && dr_n < 1e-10, "{dp_n} {dr_n}");
        central_errors.push(dp_c);
    }
    central_errors.sort_by(f64::total_cmp);
    let median = central_errors[central_errors.len() / 2];
    println!("central-model position error, noise-free: median {median:.4} m");
    assert!(median > 0.005, "{median}");

    // With one-pixel noise on one geometry: the mean error over noise draws is far from zero
    // (many standard errors) for the central model and within noise for the non-central one.
    let p0 = PnpProblem::generate(&mut rng, &config);
    let draws = 400;
    let mut sum_c = Vector6::zeros();
    let mut sum_n = Vector6::zeros();
    let mut nees_c = 0.0;
    let mut nees_n = 0.0;
    let mut cov_n = nalgebra::Matrix6::zeros();
    for _ in 0..draws {
        let rays: Vec<Ray> = p0
            .true_rays_in_rig
            .iter()
            .map(|r| Ray {
                origin: r.origin,
                direction: vgps::synthetic::perturb_bearing(
                    &mut rng,
                    &r.direction,
                    DEFAULT_SIGMA_RAD,
                ),
            })
            .collect();
        let central_rays: Vec<Ray> = rays
            .iter()
            .map(|r| Ray {
                origin: Vector3::zeros(),
                direction: r.direction,
            })
            .collect();
        let c = refine_pose(
            &p0.world_from_rig,
            &central_rays,
            &p0.points_in_world,
            &options,
        )
        .unwrap();
        let n = refine_pose(&p0.world_from_rig, &rays, &p0.points_in_world, &options).unwrap();
        let ec = pose_error_vector(&c.world_from_rig, &p0.world_from_rig);
        let en = pose_error_vector(&n.world_from_rig, &p0.world_from_rig);
        sum_c += ec;
        sum_n += en;
        nees_c += nees(&ec, &c.covariance).unwrap();
        nees_n += nees(&en, &n.covariance).unwrap();
        cov_n = n.covariance;
    }
    let mean_c = sum_c / draws as f64;
    let mean_n = sum_n / draws as f64;
    // NEES of the mean error against the covariance of the mean (Σ / draws): ~6 if unbiased.
    let bias_nees_c = nees(&mean_c, &(cov_n / draws as f64)).unwrap();
    let bias_nees_n = nees(&mean_n, &(cov_n / draws as f64)).unwrap();
    nees_c /= draws as f64;
    nees_n /= draws as f64;
    println!(
        "mean position error: central {:.4} m, non-central {:.4} m; bias NEES {bias_nees_c:.1} vs \
         {bias_nees_n:.1}; NEES {nees_c:.1} vs {nees_n:.1}",
        mean_c.fixed_rows::<3>(0).norm(),
        mean_n.fixed_rows::<3>(0).norm()
    );
    assert!(bias_nees_n < 25.0, "{bias_nees_n}");
    assert!(bias_nees_c > 100.0, "{bias_nees_c}");
    assert!(nees_c > 1.5 * nees_n, "{nees_c} {nees_n}");
}
