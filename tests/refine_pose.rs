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

/// Monte Carlo covariance consistency: with one-pixel noise the normalised estimation error
/// squared averages 6 (full pose) and 3 (position block) within ±10 %, over 10⁴ trials.
#[test]
fn covariance_is_consistent_nees_monte_carlo() {
    let mut rng = rng(104);
    let trials = 10_000;
    let mut sum_nees = 0.0;
    let mut sum_position_nees = 0.0;
    for t in 0..trials {
        let config = PnpConfig {
            n_points: 20,
            min_range_m: 5.0,
            max_range_m: 50.0,
            // Alternate central and non-central rigs.
            rig: if t % 2 == 0 {
                RigModel::Central
            } else {
                RigModel::Ladybug
            },
            sigma_rad: DEFAULT_SIGMA_RAD,
            ..PnpConfig::default()
        };
        let p = PnpProblem::generate(&mut rng, &config);
        let start = perturb_pose(&mut rng, &p.world_from_rig, 0.2, 1f64.to_radians());
        let r = refine_pose(
            &start,
            &p.rays_in_rig,
            &p.points_in_world,
            &RefineOptions::default(),
        )
        .unwrap();
        let e = pose_error_vector(&r.world_from_rig, &p.world_from_rig);
        sum_nees += nees(&e, &r.covariance).unwrap();
        sum_position_nees += position_nees(&e, &r.covariance).unwrap();
    }
    let mean = sum_nees / trials as f64;
    let mean_position = sum_position_nees / trials as f64;
    println!("NEES mean {mean:.3} (6), position NEES mean {mean_position:.3} (3)");
    assert!((mean - 6.0).abs() < 0.6, "{mean}");
    assert!((mean_position - 3.0).abs() < 0.3, "{mean_position}");
}

/// Per-observation σ: scaling every σ by k leaves the solution and scales the covariance by
/// k²; giving the noisy half of the rays their true (larger) σ keeps the NEES at 6.
#[test]
fn per_observation_sigmas_weight_the_rays() {
    let mut rng = rng(105);
    let config = PnpConfig {
        n_points: 24,
        rig: RigModel::Ladybug,
        sigma_rad: 1e-3,
        ..PnpConfig::default()
    };
    let p = PnpProblem::generate(&mut rng, &config);
    let options = RefineOptions {
        sigma_rad: 1e-3,
        ..RefineOptions::default()
    };
    let a = refine_pose(
        &p.world_from_rig,
        &p.rays_in_rig,
        &p.points_in_world,
        &options,
    )
    .unwrap();
    let b = refine_pose_with_sigmas(
        &p.world_from_rig,
        &p.rays_in_rig,
        &p.points_in_world,
        &[3e-3; 24],
        &options,
    )
    .unwrap();
    let (dp, dr) = pose_error(&a.world_from_rig, &b.world_from_rig);
    assert!(dp < 1e-9 && dr < 1e-11);
    assert!((b.covariance - a.covariance * 9.0).norm() < 1e-9 * b.covariance.norm());

    // Mixed quality: even rays have σ = 0.5 mrad, odd rays 5 mrad.
    let sigmas: Vec<f64> = (0..24)
        .map(|i| if i % 2 == 0 { 5e-4 } else { 5e-3 })
        .collect();
    let trials = 2000;
    let (mut weighted, mut unweighted) = (0.0, 0.0);
    let (mut weighted_err, mut unweighted_err) = (0.0, 0.0);
    for _ in 0..trials {
        let q = PnpProblem::generate(
            &mut rng,
            &PnpConfig {
                sigma_rad: 0.0,
                ..config.clone()
            },
        );
        let rays: Vec<Ray> = q
            .true_rays_in_rig
            .iter()
            .zip(&sigmas)
            .map(|(r, &s)| Ray {
                origin: r.origin,
                direction: vgps::synthetic::perturb_bearing(&mut rng, &r.direction, s),
            })
            .collect();
        let w = refine_pose_with_sigmas(
            &q.world_from_rig,
            &rays,
            &q.points_in_world,
            &sigmas,
            &options,
        )
        .unwrap();
        let u = refine_pose(&q.world_from_rig, &rays, &q.points_in_world, &options).unwrap();
        let ew = pose_error_vector(&w.world_from_rig, &q.world_from_rig);
        let eu = pose_error_vector(&u.world_from_rig, &q.world_from_rig);
        weighted += nees(&ew, &w.covariance).unwrap();
        unweighted += nees(&eu, &u.covariance).unwrap();
        weighted_err += ew.fixed_rows::<3>(0).norm_squared();
        unweighted_err += eu.fixed_rows::<3>(0).norm_squared();
    }
    let (weighted, unweighted) = (weighted / trials as f64, unweighted / trials as f64);
    println!(
        "mixed σ: NEES weighted {weighted:.2}, unweighted {unweighted:.2}; position MSE ratio {:.2}",
        unweighted_err / weighted_err
    );
    assert!((weighted - 6.0).abs() < 0.6, "{weighted}");
    // A single σ of 1 mrad is wrong for both halves: its covariance is inconsistent.
    assert!(unweighted > 9.0, "{unweighted}");
    // The weighted solution is the more accurate one.
    assert!(unweighted_err > 1.5 * weighted_err);
}

fn robust_trial(loss: RobustLoss, seed: u64) -> (usize, usize, f64) {
    let mut rng = rng(seed);
    let config = PnpConfig {
        n_points: 50,
        min_range_m: 5.0,
        max_range_m: 50.0,
        rig: RigModel::Ladybug,
        sigma_rad: DEFAULT_SIGMA_RAD,
        outlier_fraction: 0.2,
        ..PnpConfig::default()
    };
    let options = RefineOptions {
        loss,
        ..RefineOptions::default()
    };
    let trials = 200;
    let mut good = 0;
    let mut plain_good = 0;
    let mut worst: f64 = 0.0;
    for _ in 0..trials {
        let p = PnpProblem::generate(&mut rng, &config);
        // A good start, as from a minimal solver on an inlier sample.
        let start = perturb_pose(&mut rng, &p.world_from_rig, 0.3, 1f64.to_radians());
        // The reference: least squares on the inliers alone.
        let (rays, points): (Vec<Ray>, Vec<Vector3<f64>>) = p
            .rays_in_rig
            .iter()
            .zip(&p.points_in_world)
            .zip(&p.inliers)
            .filter(|(_, inlier)| **inlier)
            .map(|((r, x), _)| (*r, *x))
            .unzip();
        let oracle = refine_pose(&start, &rays, &points, &RefineOptions::default()).unwrap();
        let sigma_position = oracle.covariance.fixed_view::<3, 3>(0, 0).trace().sqrt();
        let r = refine_pose(&start, &p.rays_in_rig, &p.points_in_world, &options).unwrap();
        // Least squares on the same data, for contrast (it may not even converge).
        let plain = refine_pose(
            &start,
            &p.rays_in_rig,
            &p.points_in_world,
            &RefineOptions {
                accept_unconverged: true,
                ..RefineOptions::default()
            },
        );
        let (dp, _) = pose_error(&r.world_from_rig, &p.world_from_rig);
        let dp_plain = plain.map_or(f64::INFINITY, |q| {
            pose_error(&q.world_from_rig, &p.world_from_rig).0
        });
        worst = worst.max(dp / sigma_position);
        // "Small": within 3 σ (total position σ of the inlier-only solution) of the truth.
        good += usize::from(dp < 3.0 * sigma_position);
        plain_good += usize::from(dp_plain < 3.0 * sigma_position);
    }
    (good, plain_good, worst)
}

/// With 20 % gross outliers (random bearings) and a good start, Huber and Cauchy keep the
/// position error within 3 σ of the inlier-only covariance; plain least squares does not.
#[test]
fn robust_losses_reject_gross_outliers() {
    let huber = robust_trial(
        RobustLoss::Huber {
            scale_rad: 2.0 * DEFAULT_SIGMA_RAD,
        },
        106,
    );
    let cauchy = robust_trial(
        RobustLoss::Cauchy {
            scale_rad: 2.0 * DEFAULT_SIGMA_RAD,
        },
        106,
    );
    println!(
        "of 200: huber good {} (plain {}), worst {:.2} σ",
        huber.0, huber.1, huber.2
    );
    println!(
        "of 200: cauchy good {} (plain {}), worst {:.2} σ",
        cauchy.0, cauchy.1, cauchy.2
    );
    assert!(huber.0 >= 190, "{huber:?}");
    assert!(cauchy.0 >= 195, "{cauchy:?}");
    assert!(huber.1 <= 20, "{huber:?}");
}

fn valid_problem() -> PnpProblem {
    PnpProblem::generate(
        &mut rng(107),
        &PnpConfig {
            n_points: 10,
            rig: RigModel::Ladybug,
            ..PnpConfig::default()
        },
    )
}

#[test]
fn invalid_inputs_are_typed_errors() {
    let p = valid_problem();
    let pose = p.world_from_rig;
    let o = RefineOptions::default();
    let rays = &p.rays_in_rig;
    let pts = &p.points_in_world;
    assert_eq!(
        refine_pose(&pose, &rays[..2], &pts[..2], &o),
        Err(RefineError::TooFewCorrespondences(2))
    );
    assert!(matches!(
        refine_pose(&pose, &rays[..5], &pts[..6], &o),
        Err(RefineError::LengthMismatch {
            rays: 5,
            points: 6,
            ..
        })
    ));
    assert!(matches!(
        refine_pose_with_sigmas(&pose, rays, pts, &[1e-3; 3], &o),
        Err(RefineError::LengthMismatch { sigmas: 3, .. })
    ));
    let mut bad = rays.clone();
    bad[4].direction.y = f64::NAN;
    assert_eq!(
        refine_pose(&pose, &bad, pts, &o),
        Err(RefineError::NonFiniteRay(4))
    );
    let mut bad = rays.clone();
    bad[3].origin.x = f64::INFINITY;
    assert_eq!(
        refine_pose(&pose, &bad, pts, &o),
        Err(RefineError::NonFiniteRay(3))
    );
    let mut bad = rays.clone();
    bad[2].direction = Vector3::zeros();
    assert_eq!(
        refine_pose(&pose, &bad, pts, &o),
        Err(RefineError::ZeroDirection(2))
    );
    let mut bad = pts.clone();
    bad[7].z = f64::NEG_INFINITY;
    assert_eq!(
        refine_pose(&pose, rays, &bad, &o),
        Err(RefineError::NonFinitePoint(7))
    );
    let mut nan_pose = pose;
    nan_pose.translation.vector.x = f64::NAN;
    assert_eq!(
        refine_pose(&nan_pose, rays, pts, &o),
        Err(RefineError::NonFiniteInitialPose)
    );
    // Point 5 placed exactly on the centre of the camera that sees it.
    let mut bad = pts.clone();
    bad[5] = (pose * nalgebra::Point3::from(rays[5].origin)).coords;
    assert_eq!(
        refine_pose(&pose, rays, &bad, &o),
        Err(RefineError::PointAtRayOrigin(5))
    );
    let mut sigmas = vec![1e-3; 10];
    sigmas[1] = 0.0;
    assert!(matches!(
        refine_pose_with_sigmas(&pose, rays, pts, &sigmas, &o),
        Err(RefineError::InvalidSigma { index: 1, .. })
    ));
    for bad_options in [
        RefineOptions {
            sigma_rad: -1.0,
            ..o
        },
        RefineOptions {
            sigma_rad: f64::NAN,
            ..o
        },
        RefineOptions {
            loss: RobustLoss::Huber { scale_rad: 0.0 },
            ..o
        },
        RefineOptions {
            loss: RobustLoss::Cauchy {
                scale_rad: f64::INFINITY,
            },
            ..o
        },
        RefineOptions {
            step_tolerance_rad: f64::NAN,
            ..o
        },
    ] {
        assert!(matches!(
            refine_pose(&pose, rays, pts, &bad_options),
            Err(RefineError::InvalidOptions(_))
        ));
    }
}

/// Points on one line (through the rig or not) leave a rotation about that line
/// unobservable for a central camera: a typed error, not a NaN covariance.
#[test]
fn collinear_points_are_rank_deficient() {
    let mut r = rng(108);
    for through_rig in [true, false] {
        for _ in 0..20 {
            let truth = vgps::synthetic::random_pose(&mut r, 20.0);
            let dir = vgps::synthetic::random_unit_vector(&mut r);
            let base = if through_rig {
                truth.translation.vector
            } else {
                truth.translation.vector + vgps::synthetic::random_unit_vector(&mut r) * 7.0
            };
            let points: Vec<Vector3<f64>> = [3.0, 8.0, -5.0, 12.0, 20.0, -9.0]
                .iter()
                .map(|t| base + dir * *t)
                .collect();
            let rays: Vec<Ray> = points
                .iter()
                .map(|x| Ray {
                    origin: Vector3::zeros(),
                    direction: vgps::geometry::bearing_in_rig(&truth, x).unwrap(),
                })
                .collect();
            let start = perturb_pose(&mut r, &truth, 0.1, 0.01);
            let result = refine_pose(&start, &rays, &points, &RefineOptions::default());
            assert_eq!(
                result,
                Err(RefineError::RankDeficient),
                "through rig: {through_rig}"
            );
        }
    }
}

#[test]
fn iteration_budget_is_reported() {
    let p = valid_problem();
    let start = perturb_pose(&mut rng(109), &p.world_from_rig, 1.0, 0.1);
    let strict = RefineOptions {
        max_iterations: 2,
        ..RefineOptions::default()
    };
    assert!(matches!(
        refine_pose(&start, &p.rays_in_rig, &p.points_in_world, &strict),
        Err(RefineError::NoConvergence { iterations: 2, .. })
    ));
    let lenient = RefineOptions {
        accept_unconverged: true,
        ..strict
    };
    let r = refine_pose(&start, &p.rays_in_rig, &p.points_in_world, &lenient).unwrap();
    assert!(!r.converged && r.iterations == 2 && all_finite(&r));
    // Two steps still improve on the start.
    let (dp0, _) = pose_error(&start, &p.world_from_rig);
    let (dp2, _) = pose_error(&r.world_from_rig, &p.world_from_rig);
    assert!(dp2 < 0.1 * dp0, "{dp2} vs {dp0}");
    // Zero iterations: the covariance at the given pose.
    let zero = RefineOptions {
        max_iterations: 0,
        accept_unconverged: true,
        ..RefineOptions::default()
    };
    let at_truth =
        refine_pose(&p.world_from_rig, &p.rays_in_rig, &p.points_in_world, &zero).unwrap();
    assert_eq!(at_truth.world_from_rig, p.world_from_rig);
    assert!(at_truth.covariance.iter().all(|x| x.is_finite()) && at_truth.covariance[(0, 0)] > 0.0);
}

/// Whatever the input, the result is a typed error or finite numbers: random poses far
/// from the truth, huge coordinates, rays pointing anywhere, tiny and huge σ.
#[test]
fn never_nan_on_arbitrary_input() {
    let mut r = rng(110);
    let mut ok = 0;
    for k in 0..2000 {
        let n = 3 + k % 8;
        let scale = [1e-3, 1.0, 1e3, 1e7][k % 4];
        let points: Vec<Vector3<f64>> = (0..n)
            .map(|_| vgps::synthetic::random_unit_vector(&mut r) * scale * (1.0 + (k % 3) as f64))
            .collect();
        let rays: Vec<Ray> = (0..n)
            .map(|_| Ray {
                origin: vgps::synthetic::random_unit_vector(&mut r) * 0.04 * ((k % 2) as f64),
                direction: vgps::synthetic::random_unit_vector(&mut r),
            })
            .collect();
        let pose = vgps::synthetic::random_pose(&mut r, scale);
        let options = RefineOptions {
            sigma_rad: [1e-9, 1e-3, 1.0][k % 3],
            loss: [
                RobustLoss::None,
                RobustLoss::Huber { scale_rad: 0.01 },
                RobustLoss::Cauchy { scale_rad: 0.01 },
            ][k % 3],
            accept_unconverged: k % 2 == 0,
            ..RefineOptions::default()
        };
        if let Ok(result) = refine_pose(&pose, &rays, &points, &options) {
            assert!(all_finite(&result), "{result:?}");
            ok += 1;
        }
    }
    println!("{ok} of 2000 arbitrary problems returned a pose");
    assert!(ok > 0);
}
