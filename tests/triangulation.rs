//! Triangulation: known answers, the two-ray / projector-sum identity, origin invariance of
//! the covariance, Monte-Carlo consistency (NEES) and unbiasedness, the paper's linear
//! growth of the information with the number of observations, and degenerate input.
//!
//! Figures quoted in docs/triangulation.md are printed with
//! `cargo test --release --test triangulation -- --nocapture`.

use nalgebra::{Matrix3, Vector3};
use vgps::geometry::{Ray, angle_between};
use vgps::synthetic::rays::{DriveBy, RayProblem};
use vgps::synthetic::{random_unit_vector, rng};
use vgps::triangulation::{
    MIN_PARALLAX_RAD, RayObservation, RaySum, TriangulatedPoint, TriangulationError,
    intersect_two_rays, reciprocal_condition, triangulate_rays, triangulate_rays_weighted,
};

type Estimator = fn(&[RayObservation]) -> Result<TriangulatedPoint, TriangulationError>;

fn ray(origin: [f64; 3], direction: [f64; 3]) -> Ray {
    Ray::try_new(Vector3::from(origin), Vector3::from(direction)).unwrap()
}

fn obs(r: Ray, sigma_pos_m: f64, sigma_ang_rad: f64) -> RayObservation {
    RayObservation {
        ray: r,
        sigma_pos_m,
        sigma_ang_rad,
    }
}

fn nees(e: &Vector3<f64>, cov: &Matrix3<f64>) -> f64 {
    let chol = cov.cholesky().expect("covariance positive definite");
    e.dot(&chol.solve(e))
}

fn rel_diff(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (a - b).norm() / a.norm().max(b.norm())
}

/// The covariance of Ku, Ho & Sarma's eq. (9) as printed (isotropic Σ(δ), Σ(γ)):
/// `P(U) (Σ Pᵢ σ_pos² Pᵢ + xᵢᵀ σ_ang² xᵢ I) P(U)`, with `xᵢ` measured from the frame origin.
fn paper_covariance(obs: &[RayObservation]) -> Matrix3<f64> {
    let mut a = Matrix3::zeros();
    let mut m = Matrix3::zeros();
    for o in obs {
        let u = o.ray.direction;
        let p = Matrix3::identity() - u * u.transpose();
        a += p;
        m += p * o.sigma_pos_m.powi(2)
            + Matrix3::identity() * (o.sigma_ang_rad.powi(2) * o.ray.origin.norm_squared());
    }
    let a_inv = a.try_inverse().unwrap();
    a_inv * m * a_inv
}

// ---------------------------------------------------------------- two rays

#[test]
fn two_skew_rays_known_answer() {
    // a along +x from the origin; b along +y from (5, −3, 2): closest points (5,0,0), (5,0,2).
    let a = ray([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
    let b = ray([5.0, -3.0, 2.0], [0.0, 1.0, 0.0]);
    let hit = intersect_two_rays(&a, &b).unwrap();
    assert!((hit.point - Vector3::new(5.0, 0.0, 1.0)).norm() < 1e-14);
    assert!((hit.ranges[0] - 5.0).abs() < 1e-14 && (hit.ranges[1] - 3.0).abs() < 1e-14);
    assert!((hit.gap_m - 2.0).abs() < 1e-14);
    assert!((hit.parallax_rad() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    // Symmetric in its arguments.
    let rev = intersect_two_rays(&b, &a).unwrap();
    assert!((rev.point - hit.point).norm() < 1e-14);
    assert_eq!(rev.ranges, [hit.ranges[1], hit.ranges[0]]);
}

#[test]
fn two_rays_noise_free_recover_the_landmark() {
    let mut r = rng(11);
    let mut checked = 0;
    for _ in 0..2000 {
        let problem = RayProblem::around(&mut r, 2, 1.0, 500.0, 0.0, 0.0);
        let o = problem.exact_observations();
        let (u, v) = (o[0].ray.direction, o[1].ray.direction);
        let line_angle = u.cross(&v).norm().asin();
        if line_angle < 0.05 {
            continue;
        }
        checked += 1;
        let hit = intersect_two_rays(&o[0].ray, &o[1].ray).unwrap();
        let ranges = problem.ranges();
        let scale = ranges[0].max(ranges[1]);
        assert!((hit.point - problem.landmark).norm() < 1e-11 * scale);
        assert!(hit.gap_m < 1e-11 * scale);
        assert!((hit.ranges[0] - ranges[0]).abs() < 1e-11 * scale);
        assert!((hit.ranges[1] - ranges[1]).abs() < 1e-11 * scale);
        assert!((hit.parallax_rad() - angle_between(&u, &v)).abs() < 1e-14);
    }
    assert!(checked > 1800, "{checked}");
}

#[test]
fn two_ray_midpoint_equals_projector_sum() {
    let mut r = rng(12);
    let mut checked = 0;
    for _ in 0..2000 {
        let problem = RayProblem::around(&mut r, 2, 5.0, 80.0, 0.3, 5e-3);
        let o = problem.noisy_observations(&mut r);
        let (Ok(hit), Ok(est)) = (
            intersect_two_rays(&o[0].ray, &o[1].ray),
            triangulate_rays(&o),
        ) else {
            continue;
        };
        checked += 1;
        assert!((hit.point - est.point).norm() < 1e-9, "{hit:?} {est:?}");
        assert!((hit.parallax_rad() - est.max_parallax_rad()).abs() < 1e-12);
    }
    assert!(checked > 1900, "{checked}");
}

#[test]
fn two_ray_degenerate_inputs_are_typed_errors() {
    let a = ray([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
    // Parallel, anti-parallel (collinear, facing each other) and just below the minimum.
    for b in [
        ray([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
        ray([10.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ray([0.0, 1.0, 0.0], [1.0, 0.99 * MIN_PARALLAX_RAD, 0.0]),
    ] {
        assert!(
            matches!(
                intersect_two_rays(&a, &b),
                Err(TriangulationError::NoParallax { line_angle_rad }) if line_angle_rad < MIN_PARALLAX_RAD
            ),
            "{b:?}"
        );
    }
    // Just above the minimum: a valid, far intersection.
    let b = ray([0.0, 1.0, 0.0], [1.0, -1.01 * MIN_PARALLAX_RAD, 0.0]);
    let hit = intersect_two_rays(&a, &b).unwrap();
    assert!(hit.ranges[0] > 900.0 && hit.ranges[0] < 1000.0, "{hit:?}");
    // Behind a: the rays' lines cross at x = −5.
    let b = ray([-5.0, 5.0, 0.0], [0.0, -1.0, 0.0]);
    assert!(matches!(
        intersect_two_rays(&a, &b),
        Err(TriangulationError::BehindRay { index: 0, range_m }) if (range_m + 5.0).abs() < 1e-12
    ));
    // Behind b.
    let b = ray([5.0, 5.0, 0.0], [0.0, 1.0, 0.0]);
    assert!(matches!(
        intersect_two_rays(&a, &b),
        Err(TriangulationError::BehindRay { index: 1, .. })
    ));
    // Non-unit and non-finite.
    let mut bad = a;
    bad.direction *= 2.0;
    assert_eq!(
        intersect_two_rays(&b, &bad),
        Err(TriangulationError::InvalidRay { index: 1 })
    );
    for k in 0..3 {
        let mut bad = a;
        bad.origin[k] = f64::NAN;
        assert_eq!(
            intersect_two_rays(&bad, &b),
            Err(TriangulationError::InvalidRay { index: 0 })
        );
        let mut bad = a;
        bad.direction[k] = f64::INFINITY;
        assert_eq!(
            intersect_two_rays(&b, &bad),
            Err(TriangulationError::InvalidRay { index: 1 })
        );
    }
    // Finite origins whose difference overflows.
    let far = ray([1.7e308, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let far2 = ray([-1.7e308, 0.0, 0.0], [1.0, 0.0, 0.0]);
    assert_eq!(
        intersect_two_rays(&far, &far2),
        Err(TriangulationError::NonFinite)
    );
}

#[test]
fn two_ray_never_returns_non_finite_output() {
    let mut r = rng(13);
    let scales = [1e-300, 1e-8, 1.0, 1e8, 1e200, 1e307];
    for i in 0..20_000 {
        let s = scales[i % scales.len()];
        let a = Ray {
            origin: random_unit_vector(&mut r) * s,
            direction: random_unit_vector(&mut r),
        };
        let b = Ray {
            origin: random_unit_vector(&mut r) * s,
            direction: random_unit_vector(&mut r),
        };
        if let Ok(hit) = intersect_two_rays(&a, &b) {
            assert!(vgps::geometry::is_finite(&hit.point) && hit.gap_m.is_finite());
            assert!(hit.ranges.iter().all(|t| *t > 0.0 && t.is_finite()));
        }
    }
}

// ---------------------------------------------------------------- n rays: exactness

#[test]
fn noise_free_rays_recover_the_landmark_exactly() {
    let mut r = rng(21);
    for i in 0..500 {
        let n = 2 + i % 40;
        let problem = if i % 2 == 0 {
            RayProblem::around(&mut r, n, 5.0, 80.0, 0.1, 1e-3)
        } else {
            RayProblem::drive_by(&mut r, n.max(3), &DriveBy::streetlight(), 0.1, 1e-3)
        };
        let o = problem.exact_observations();
        for estimator in [triangulate_rays as Estimator, triangulate_rays_weighted] {
            let Ok(est) = estimator(&o) else {
                // Only a pathological random draw (two observers a hair apart) may fail.
                assert!(n == 2 || i % 2 == 1, "n = {n}");
                continue;
            };
            assert!((est.point - problem.landmark).norm() < 1e-9, "{i}: {est:?}");
            assert_eq!(est.n_obs, o.len());
        }
        // The same in ECEF-sized coordinates: computed about the first ray, no precision lost.
        let ecef = problem.translated(&Vector3::new(4.2e6, 1.3e6, 4.6e6));
        if let Ok(est) = triangulate_rays(&ecef.exact_observations()) {
            assert!((est.point - ecef.landmark).norm() < 1e-7, "{i}");
        }
    }
}

#[test]
fn covariance_is_origin_invariant_and_the_papers_is_not() {
    let mut r = rng(22);
    for _ in 0..200 {
        let problem = RayProblem::around(&mut r, 8, 5.0, 80.0, 0.2, 2e-3);
        let o = problem.noisy_observations(&mut r);
        let offset = 1000.0 * random_unit_vector(&mut r);
        let moved: Vec<RayObservation> = o
            .iter()
            .map(|x| RayObservation {
                ray: Ray {
                    origin: x.ray.origin + offset,
                    ..x.ray
                },
                ..*x
            })
            .collect();
        for estimator in [triangulate_rays as Estimator, triangulate_rays_weighted] {
            let (e0, e1) = (estimator(&o).unwrap(), estimator(&moved).unwrap());
            assert!((e1.point - e0.point - offset).norm() < 1e-9);
            assert!(rel_diff(&e0.covariance, &e1.covariance) < 1e-9);
        }
        let mut sum = RaySum::new();
        moved.iter().for_each(|x| sum.add(x).unwrap());
        let e_sum = sum.solve().unwrap();
        assert!(rel_diff(&e_sum.covariance, &triangulate_rays(&o).unwrap().covariance) < 1e-9);
        // The paper's form changes with the origin, by orders of magnitude here.
        let (c0, c1) = (paper_covariance(&o), paper_covariance(&moved));
        assert!(rel_diff(&c0, &c1) > 0.5, "{}", rel_diff(&c0, &c1));
    }
}

// ---------------------------------------------------------------- Monte Carlo

struct Case {
    name: &'static str,
    drive_by: bool,
    n: usize,
    sigma_pos_m: f64,
    sigma_ang_rad: f64,
}

const CASES: [Case; 5] = [
    Case {
        name: "around n=5, pos 0.05 m + ang 2 mrad",
        drive_by: false,
        n: 5,
        sigma_pos_m: 0.05,
        sigma_ang_rad: 2e-3,
    },
    Case {
        name: "around n=20, pos 0.5 m only",
        drive_by: false,
        n: 20,
        sigma_pos_m: 0.5,
        sigma_ang_rad: 0.0,
    },
    Case {
        name: "around n=3, ang 3 mrad only",
        drive_by: false,
        n: 3,
        sigma_pos_m: 0.0,
        sigma_ang_rad: 3e-3,
    },
    Case {
        name: "drive-by n=10, pos 0.1 m + ang 1 mrad",
        drive_by: true,
        n: 10,
        sigma_pos_m: 0.1,
        sigma_ang_rad: 1e-3,
    },
    Case {
        name: "around n=40, pos 0.3 m + ang 5 mrad",
        drive_by: false,
        n: 40,
        sigma_pos_m: 0.3,
        sigma_ang_rad: 5e-3,
    },
];

const TRIALS: usize = 10_000;

/// NEES statistics of an estimator over fresh random geometries (ranges 5–80 m).
fn monte_carlo(case: &Case, seed: u64, estimator: Estimator) -> (f64, f64, usize) {
    let mut r = rng(seed);
    let (mut sum_nees, mut sum_sq_err, mut ok) = (0.0, 0.0, 0);
    for _ in 0..TRIALS {
        let problem = if case.drive_by {
            let setting = DriveBy {
                lateral_offset_m: 5.0 + 25.0 * rand::RngExt::random::<f64>(&mut r),
                ..DriveBy::streetlight()
            };
            RayProblem::drive_by(
                &mut r,
                case.n,
                &setting,
                case.sigma_pos_m,
                case.sigma_ang_rad,
            )
        } else {
            RayProblem::around(
                &mut r,
                case.n,
                5.0,
                80.0,
                case.sigma_pos_m,
                case.sigma_ang_rad,
            )
        };
        let o = problem.noisy_observations(&mut r);
        let Ok(est) = estimator(&o) else { continue };
        let e = est.point - problem.landmark;
        sum_nees += nees(&e, &est.covariance);
        sum_sq_err += e.norm_squared();
        ok += 1;
    }
    (sum_nees / ok as f64, (sum_sq_err / ok as f64).sqrt(), ok)
}

#[test]
fn covariance_matches_the_empirical_error_nees() {
    for (k, case) in CASES.iter().enumerate() {
        for (name, estimator) in [
            ("plain", triangulate_rays as Estimator),
            ("weighted", triangulate_rays_weighted),
        ] {
            let (mean_nees, rms, ok) = monte_carlo(case, 100 + k as u64, estimator);
            eprintln!(
                "NEES {name:8} {:40} mean {mean_nees:.3} (expect 3)  rms error {rms:.4} m  solved {ok}/{TRIALS}",
                case.name
            );
            assert!(ok as f64 >= 0.999 * TRIALS as f64, "{}: {ok}", case.name);
            assert!(
                (mean_nees - 3.0).abs() <= 0.3,
                "{} {name}: NEES mean {mean_nees}",
                case.name
            );
        }
    }
}

#[test]
fn papers_covariance_is_not_consistent_away_from_the_origin() {
    // Case 0 with the landmark 5 km from the frame origin: the paper's |xᵢ|² term inflates
    // the angular part ~ (5000/40)² times, so its NEES collapses; ours stays at 3.
    let case = &CASES[0];
    let mut r = rng(150);
    let offset = Vector3::new(3000.0, -4000.0, 0.0);
    let (mut ours, mut papers) = (0.0, 0.0);
    let trials = 2000;
    for _ in 0..trials {
        let problem = RayProblem::around(
            &mut r,
            case.n,
            5.0,
            80.0,
            case.sigma_pos_m,
            case.sigma_ang_rad,
        )
        .translated(&offset);
        let o = problem.noisy_observations(&mut r);
        let est = triangulate_rays(&o).unwrap();
        let e = est.point - problem.landmark;
        ours += nees(&e, &est.covariance) / trials as f64;
        papers += nees(&e, &paper_covariance(&o)) / trials as f64;
    }
    eprintln!("NEES 5 km from the origin: ours {ours:.3}, paper's eq. (9) {papers:.5}");
    assert!((ours - 3.0).abs() < 0.3, "{ours}");
    assert!(papers < 0.1, "{papers}");
}

#[test]
fn estimates_are_unbiased() {
    // A fixed geometry: the mean error over the trials is within 4 standard errors.
    for (seed, case) in [(31, &CASES[0]), (32, &CASES[3]), (33, &CASES[4])] {
        let mut r = rng(seed);
        let problem = if case.drive_by {
            RayProblem::drive_by(
                &mut r,
                case.n,
                &DriveBy::streetlight(),
                case.sigma_pos_m,
                case.sigma_ang_rad,
            )
        } else {
            RayProblem::around(
                &mut r,
                case.n,
                5.0,
                80.0,
                case.sigma_pos_m,
                case.sigma_ang_rad,
            )
        };
        let cov = triangulate_rays(&problem.exact_observations())
            .unwrap()
            .covariance;
        let mut mean = Vector3::zeros();
        for _ in 0..TRIALS {
            let est = triangulate_rays(&problem.noisy_observations(&mut r)).unwrap();
            mean += (est.point - problem.landmark) / TRIALS as f64;
        }
        for k in 0..3 {
            let standard_error = (cov[(k, k)] / TRIALS as f64).sqrt();
            eprintln!(
                "bias {:40} axis {k}: mean error {:+.2e} m = {:+.2} standard errors",
                case.name,
                mean[k],
                mean[k] / standard_error
            );
            assert!(
                mean[k].abs() < 4.0 * standard_error,
                "{} axis {k}",
                case.name
            );
        }
    }
}

#[test]
fn weighting_helps_when_ranges_differ() {
    // Angular noise dominant, ranges 5–80 m: the weighted estimate has a smaller actual error
    // (and its covariance stays consistent).
    let case = Case {
        name: "around n=6, pos 0.01 m + ang 3 mrad",
        drive_by: false,
        n: 6,
        sigma_pos_m: 0.01,
        sigma_ang_rad: 3e-3,
    };
    let (nees_p, rms_p, _) = monte_carlo(&case, 40, triangulate_rays);
    let (nees_w, rms_w, _) = monte_carlo(&case, 40, triangulate_rays_weighted);
    eprintln!(
        "{}: rms error plain {rms_p:.4} m, weighted {rms_w:.4} m (NEES {nees_p:.3}, {nees_w:.3})",
        case.name
    );
    assert!(rms_w < 0.9 * rms_p, "{rms_w} vs {rms_p}");
    assert!((nees_w - 3.0).abs() < 0.3 && (nees_p - 3.0).abs() < 0.3);
}

/// Pearson correlation coefficient.
fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let syy: f64 = y.iter().map(|b| (b - my).powi(2)).sum();
    sxy / (sxx * syy).sqrt()
}

/// `(n, 1/‖Σ‖₂)` for 300 lamps of the paper's field setting, lamps `offsets` metres from the
/// road's centre line.
fn information_by_count(seed: u64, offsets: (f64, f64)) -> (Vec<f64>, Vec<f64>) {
    let sigma_pos = 2.0 / 1.1774;
    let sigma_ang = 0.5f64.to_radians();
    let mut r = rng(seed);
    let (mut ns, mut info) = (Vec::new(), Vec::new());
    for _ in 0..300 {
        let n: usize = rand::RngExt::random_range(&mut r, 2..=60);
        let setting = DriveBy {
            lateral_offset_m: rand::RngExt::random_range(&mut r, offsets.0..=offsets.1),
            ..DriveBy::streetlight()
        };
        let problem = RayProblem::drive_by(&mut r, n, &setting, sigma_pos, sigma_ang);
        let Ok(est) = triangulate_rays(&problem.noisy_observations(&mut r)) else {
            continue;
        };
        ns.push(n as f64);
        info.push(1.0 / est.covariance.symmetric_eigenvalues().max());
    }
    (ns, info)
}

#[test]
fn information_grows_linearly_with_the_number_of_observations() {
    // The paper's field setting: GPS with CEP 2.0 m (σ = CEP / 1.1774 per axis), heading
    // good to 0.5°, a right-looking camera with an 80° field of view, a row of streetlights
    // 5.5–6.5 m right of the road's centre line, 7 m high; the vehicle samples at a fixed
    // rate, its speed setting how many times (2–60) each lamp is seen. ‖Σ‖ is the spectral
    // norm of the covariance computed from the noisy observations.
    let (ns, info) = information_by_count(50, (5.5, 6.5));
    let rho = correlation(&ns, &info);
    eprintln!(
        "correlation of 1/‖Σ‖ with n, {} lamps 5.5–6.5 m off: {rho:.4} (paper: 0.9942)",
        ns.len()
    );
    assert!(ns.len() >= 295);
    assert!(rho >= 0.99, "{rho}");
    // The slope: information per observation, the same at every n (the fit is linear).
    let slope = info.iter().zip(&ns).map(|(i, n)| i / n).sum::<f64>() / ns.len() as f64;
    eprintln!("mean information per observation {slope:.4} m⁻²");
    // A more varied street (lamps 3–12 m off) scatters the slope, as the geometry changes.
    let (ns, info) = information_by_count(51, (3.0, 12.0));
    eprintln!(
        "correlation, lamps 3–12 m off: {:.4}",
        correlation(&ns, &info)
    );
}

// ---------------------------------------------------------------- online form

#[test]
fn ray_sum_matches_the_batch_estimator_at_every_step() {
    let mut r = rng(60);
    for _ in 0..100 {
        let problem = RayProblem::around(&mut r, 30, 5.0, 80.0, 0.2, 3e-3)
            .translated(&Vector3::new(4.2e6, 1.3e6, 4.6e6));
        let o = problem.noisy_observations(&mut r);
        let mut sum = RaySum::new();
        assert!(sum.is_empty());
        assert_eq!(sum.solve(), Err(TriangulationError::TooFewRays(0)));
        for (i, x) in o.iter().enumerate() {
            sum.add(x).unwrap();
            assert_eq!(sum.len(), i + 1);
            if i == 0 {
                assert_eq!(sum.solve(), Err(TriangulationError::TooFewRays(1)));
                continue;
            }
            let (online, batch) = (sum.solve().unwrap(), triangulate_rays(&o[..=i]).unwrap());
            assert!((online.point - batch.point).norm() < 1e-8);
            assert!(rel_diff(&online.covariance, &batch.covariance) < 1e-8);
            assert_eq!(online.n_obs, batch.n_obs);
            assert!((online.max_parallax_rad() - batch.max_parallax_rad()).abs() < 1e-12);
        }
    }
}

#[test]
fn ray_sum_rejects_invalid_observations_unchanged() {
    let mut sum = RaySum::new();
    sum.add(&obs(ray([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]), 0.1, 1e-3))
        .unwrap();
    let before = sum;
    let mut bad = ray([5.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    bad.origin.y = f64::NAN;
    assert_eq!(
        sum.add(&obs(bad, 0.1, 1e-3)),
        Err(TriangulationError::InvalidRay { index: 1 })
    );
    let good = ray([10.0, 0.0, 0.0], [-1.0, 1.0, 0.0]);
    assert_eq!(
        sum.add(&obs(good, -0.1, 1e-3)),
        Err(TriangulationError::InvalidNoise { index: 1 })
    );
    assert_eq!(sum, before);
    sum.add(&obs(good, 0.1, 1e-3)).unwrap();
    let est = sum.solve().unwrap();
    assert!((est.point - Vector3::new(5.0, 5.0, 0.0)).norm() < 1e-12);
    assert!((est.max_parallax_rad() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
}

// ---------------------------------------------------------------- degenerate input

#[test]
fn degenerate_bundles_are_typed_errors() {
    let x = |a: f64| obs(ray([a, 0.0, 0.0], [0.0, 1.0, 0.0]), 0.1, 1e-3);
    for estimator in [triangulate_rays as Estimator, triangulate_rays_weighted] {
        assert_eq!(estimator(&[]), Err(TriangulationError::TooFewRays(0)));
        assert_eq!(estimator(&[x(0.0)]), Err(TriangulationError::TooFewRays(1)));
        // All parallel.
        assert!(matches!(
            estimator(&[x(0.0), x(1.0), x(2.0)]),
            Err(TriangulationError::IllConditioned { .. })
        ));
        // Nearly parallel: 10 µrad apart.
        let mut tilted = x(1.0);
        tilted.ray.direction = Vector3::new(1e-5, 1.0, 0.0).normalize();
        assert!(matches!(
            estimator(&[x(0.0), tilted]),
            Err(TriangulationError::IllConditioned { .. })
        ));
        // The lines meet behind the second observer.
        let behind = obs(ray([5.0, 10.0, 0.0], [-1.0, 1.0, 0.0]), 0.1, 1e-3);
        let front = obs(ray([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]), 0.1, 1e-3);
        assert!(matches!(
            estimator(&[front, behind]),
            Err(TriangulationError::BehindRay { index: 1, range_m }) if range_m < 0.0
        ));
        // Invalid rays and noise, named by index.
        let good = [
            front,
            obs(ray([10.0, 0.0, 0.0], [-1.0, 1.0, 0.0]), 0.1, 1e-3),
        ];
        assert!(estimator(&good).is_ok());
        for (k, value) in [f64::NAN, f64::INFINITY, -f64::INFINITY]
            .into_iter()
            .enumerate()
        {
            let mut bad = good;
            bad[1].ray.origin[k] = value;
            assert_eq!(
                estimator(&bad),
                Err(TriangulationError::InvalidRay { index: 1 })
            );
            let mut bad = good;
            bad[0].ray.direction[k] = value;
            assert_eq!(
                estimator(&bad),
                Err(TriangulationError::InvalidRay { index: 0 })
            );
            let mut bad = good;
            bad[1].sigma_ang_rad = value;
            assert_eq!(
                estimator(&bad),
                Err(TriangulationError::InvalidNoise { index: 1 })
            );
        }
        let mut bad = good;
        bad[0].ray.direction *= 1.01;
        assert_eq!(
            estimator(&bad),
            Err(TriangulationError::InvalidRay { index: 0 })
        );
        let mut bad = good;
        bad[0].sigma_pos_m = -1.0;
        assert_eq!(
            estimator(&bad),
            Err(TriangulationError::InvalidNoise { index: 0 })
        );
    }
    // Zero noise is fine for the plain estimator (a zero covariance), not for the weighted.
    let exact = [
        obs(ray([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]), 0.0, 0.0),
        obs(ray([10.0, 0.0, 0.0], [-1.0, 1.0, 0.0]), 0.0, 0.0),
    ];
    assert_eq!(
        triangulate_rays(&exact).unwrap().covariance,
        Matrix3::zeros()
    );
    assert_eq!(
        triangulate_rays_weighted(&exact),
        Err(TriangulationError::InvalidNoise { index: 0 })
    );
}

#[test]
fn n_rays_never_return_non_finite_output() {
    let mut r = rng(70);
    let scales = [1e-300, 1e-8, 1.0, 1e8, 1e200, 1e307];
    for i in 0..20_000 {
        let s = scales[i % scales.len()];
        let n = 2 + i % 5;
        let o: Vec<RayObservation> = (0..n)
            .map(|_| {
                let r0 = Ray {
                    origin: random_unit_vector(&mut r) * s,
                    direction: random_unit_vector(&mut r),
                };
                obs(r0, s.min(1e3), 1e-3)
            })
            .collect();
        for estimator in [triangulate_rays as Estimator, triangulate_rays_weighted] {
            if let Ok(est) = estimator(&o) {
                assert!(vgps::geometry::is_finite(&est.point));
                assert!(est.covariance.iter().all(|c| c.is_finite()));
            }
        }
    }
}

#[test]
fn reciprocal_condition_brackets_the_eigenvalue_ratio() {
    let mut r = rng(80);
    for _ in 0..1000 {
        let problem = RayProblem::around(&mut r, 3, 5.0, 80.0, 0.0, 0.0);
        let a: Matrix3<f64> = problem
            .exact_observations()
            .iter()
            .map(|o| Matrix3::identity() - o.ray.direction * o.ray.direction.transpose())
            .sum();
        let ev = a.symmetric_eigenvalues();
        let ratio = ev.min() / ev.max();
        let rc = reciprocal_condition(&a);
        assert!(rc <= ratio * (1.0 + 1e-12) && rc >= ratio / 9.0 * (1.0 - 1e-12));
    }
}
