//! Tests of the mapping module: known answers, invariants, Monte-Carlo with fixed seeds.

use super::*;
use crate::synthetic::mapping::{DriveConfig, MappingScenario, streetlights_along};
use nalgebra::{Matrix3, Matrix6, Rotation3, Translation3, Vector3, Vector6};
use vgps_geometry::geometry::{Pose, Ray};
use vgps_geometry::synthetic::{normal, rng};
use vgps_geometry::triangulation::{RayObservation, triangulate_rays_weighted};

fn diag6(s: [f64; 6]) -> Matrix6<f64> {
    Matrix6::from_diagonal(&Vector6::from_iterator(s.iter().map(|v| v * v)))
}

/// Rays to `lamp` from rig origins along x, pose covariance `cov`, camera at the rig origin.
fn rays_to(
    lamp: &Vector3<f64>,
    xs: impl Iterator<Item = f64>,
    cov: Matrix6<f64>,
    sigma: f64,
) -> Vec<MapRay> {
    xs.map(|x| {
        let o = Vector3::new(x, 0.0, 2.0);
        MapRay {
            ray: Ray::try_new(o, lamp - o).unwrap(),
            rig_origin: o,
            pose_covariance: cov,
            sigma_rad: sigma,
        }
    })
    .collect()
}

#[test]
fn refine_equals_the_weighted_projector_sum_for_isotropic_position_noise() {
    // No attitude noise, isotropic position noise: S = σ²P + d²σ_cam²P exactly the model of
    // triangulate_rays_weighted, so both must agree on point and covariance.
    let lamp = Vector3::new(12.0, -7.0, 6.0);
    let mut r = rng(1);
    let cov = diag6([0.3, 0.3, 0.3, 0.0, 0.0, 0.0]);
    let mut rays = rays_to(&lamp, (0..25).map(|k| 2.0 * k as f64), cov, 2e-3);
    for ray in &mut rays {
        ray.ray.direction =
            vgps_geometry::synthetic::perturb_bearing(&mut r, &ray.ray.direction, 2e-3);
        ray.ray.origin += Vector3::new(normal(&mut r), normal(&mut r), normal(&mut r)) * 0.3;
    }
    let ours = refine_landmark(&rays).unwrap();
    let obs: Vec<RayObservation> = rays
        .iter()
        .map(|m| RayObservation {
            ray: m.ray,
            sigma_pos_m: 0.3,
            sigma_ang_rad: 2e-3,
        })
        .collect();
    let theirs = triangulate_rays_weighted(&obs).unwrap();
    assert!(
        (ours.point - theirs.point).norm() < 1e-9,
        "{} vs {}",
        ours.point,
        theirs.point
    );
    assert!((ours.covariance - theirs.covariance).norm() < 1e-9 * theirs.covariance.norm());
    assert_eq!(ours.n_obs, 25);
}

#[test]
fn residual_covariance_matches_monte_carlo_pose_perturbations() {
    // Perturb the pose by (δp, δθ) drawn from a correlated 6×6 covariance; the residual of the
    // re-expressed ray at the fixed landmark must have the predicted covariance.
    let lamp = Vector3::new(8.0, 15.0, 6.0);
    let lever = Vector3::new(0.3, 0.1, 0.5);
    let pose = Pose::from_parts(
        Translation3::new(1.0, 2.0, 2.0),
        Rotation3::from_euler_angles(0.02, -0.01, 0.7),
    );
    let mut l = Matrix6::zeros();
    let mut r = rng(2);
    for i in 0..6 {
        for j in 0..=i {
            l[(i, j)] = if i < 3 { 0.3 } else { 0.01 } * normal(&mut r) * 0.5
                + if i == j { 0.05 } else { 0.0 };
        }
    }
    let cov = l * l.transpose();
    let cam = pose * nalgebra::Point3::from(lever);
    let dir_in_rig = pose.rotation.inverse() * (lamp - cam.coords).normalize();
    let ray_in_rig = Ray::try_new(lever, dir_in_rig).unwrap();
    let nominal = MapRay::from_rig(&pose, &cov, &ray_in_rig, 0.0);
    let predicted = ray_residual_covariance(&nominal, &lamp);
    let chol = cov.cholesky().unwrap();
    let n = 20_000;
    let mut acc = Matrix3::zeros();
    let p = Matrix3::identity() - nominal.ray.direction * nominal.ray.direction.transpose();
    for _ in 0..n {
        let z = Vector6::from_iterator((0..6).map(|_| normal(&mut r)));
        let d = chol.l() * z;
        let dp = Vector3::new(d[0], d[1], d[2]);
        let dt = Vector3::new(d[3], d[4], d[5]);
        let perturbed = Pose::from_parts(
            Translation3::from(pose.translation.vector + dp),
            Rotation3::new(dt) * pose.rotation,
        );
        let m = MapRay::from_rig(&perturbed, &cov, &ray_in_rig, 0.0);
        // Residual of the perturbed ray at the true landmark, in the nominal ray's plane.
        let q = Matrix3::identity() - m.ray.direction * m.ray.direction.transpose();
        let res = p * (q * (lamp - m.ray.origin));
        acc += res * res.transpose();
    }
    let empirical = acc / n as f64;
    let rel = (empirical - predicted).norm() / predicted.norm();
    assert!(
        rel < 0.05,
        "relative difference {rel}\n{empirical}\n{predicted}"
    );
}

#[test]
fn refine_rejects_degenerate_input_without_nan() {
    let lamp = Vector3::new(10.0, 10.0, 5.0);
    let cov = diag6([0.1, 0.1, 0.1, 0.01, 0.01, 0.01]);
    // All rays from one point: parallel.
    let rays = rays_to(&lamp, std::iter::repeat_n(0.0, 5), cov, 1e-3);
    assert!(matches!(
        refine_landmark(&rays),
        Err(vgps_geometry::triangulation::TriangulationError::IllConditioned { .. })
    ));
    assert!(matches!(
        refine_landmark(&rays[..1]),
        Err(vgps_geometry::triangulation::TriangulationError::TooFewRays(1))
    ));
    let mut bad = rays_to(&lamp, [0.0, 5.0].into_iter(), cov, 1e-3);
    bad[1].ray.origin.x = f64::NAN;
    assert!(matches!(
        refine_landmark(&bad),
        Err(vgps_geometry::triangulation::TriangulationError::InvalidRay { index: 1 })
    ));
}

/// Purity and completeness of the association on a both-sides streetlight road.
#[test]
fn associates_a_streetlight_road_without_mixing_landmarks() {
    let config = DriveConfig::straight(400.0);
    let lights = streetlights_along(&config, 25.0, 6.0, 7.0, true);
    let mut passes = 0;
    let trials = 5;
    for seed in 0..trials {
        let mut r = rng(100 + seed);
        let sc = MappingScenario::generate(&mut r, &config, &lights, None);
        let opts = SurveyOptions {
            sigma_level_rad: config.sigma_level_rad,
            ..Default::default()
        };
        let s = survey(&sc.gps, &sc.frames, &opts).unwrap();
        // Purity: every landmark's rays come from one true landmark.
        let mut pure = 0;
        let mut matched = vec![0usize; lights.len()];
        for (_, src) in &s.sources {
            let truths: Vec<usize> = src.iter().map(|&(f, k)| sc.truth[f][k]).collect();
            if truths.iter().all(|&t| t == truths[0]) {
                pure += 1;
                matched[truths[0]] += 1;
            }
        }
        let complete = matched.iter().filter(|&&m| m == 1).count();
        // Errors of the pure landmarks within 4σ along the worst axis.
        let close = s
            .landmarks
            .iter()
            .zip(&s.sources)
            .filter(|(l, (_, src))| {
                let t = sc.truth[src[0].0][src[0].1];
                src.iter().all(|&(f, k)| sc.truth[f][k] == t)
                    && (l.position_enu - lights[t]).norm() < 4.0 * l.sigma_m()
            })
            .count();
        // At most one light split or mixed, ≥ 90 % of the tracks pure, all but one estimate
        // within 4σ.
        if complete + 1 >= lights.len() && 10 * pure >= 9 * s.sources.len() && close + 1 >= pure {
            passes += 1;
        } else {
            eprintln!(
                "seed {seed}: {pure}/{} pure, {complete}/{} complete, {close} close",
                s.sources.len(),
                lights.len()
            );
        }
    }
    assert_eq!(passes, trials);
}

/// One landmark 6 m right of a straight road, full survey pipeline; returns (error, Σ).
fn one_landmark_trial(
    seed: u64,
    detection: f64,
    rate_hz: f64,
) -> Option<(Vector3<f64>, Matrix3<f64>, usize)> {
    let mut config = DriveConfig::straight(80.0);
    config.frame_rate_hz = rate_hz;
    let lamp = Vector3::new(40.0, -6.0, 7.0);
    let mut r = rng(seed);
    let sc = MappingScenario::generate(&mut r, &config, &[lamp], Some(&[detection]));
    let opts = SurveyOptions {
        sigma_level_rad: config.sigma_level_rad,
        ..Default::default()
    };
    let s = survey(&sc.gps, &sc.frames, &opts).ok()?;
    if s.landmarks.len() != 1 {
        return None;
    }
    let l = &s.landmarks[0];
    Some((l.position_enu - lamp, l.covariance, l.n_obs))
}

#[test]
fn mapped_landmarks_are_unbiased_and_consistent() {
    let trials = 1000;
    let chi2_3dof_95 = 7.814_727_903_251_178;
    let mut errors = Vec::new();
    let mut nees = Vec::new();
    for seed in 0..trials {
        if let Some((e, c, _)) = one_landmark_trial(1000 + seed, 1.0, 10.0) {
            let inv = c.try_inverse().unwrap();
            nees.push(e.dot(&(inv * e)));
            errors.push(e);
        }
    }
    assert!(
        errors.len() >= trials as usize * 99 / 100,
        "only {} landmarks",
        errors.len()
    );
    let n = errors.len() as f64;
    let mean_nees = nees.iter().sum::<f64>() / n;
    let inside = nees.iter().filter(|&&v| v <= chi2_3dof_95).count() as f64 / n;
    eprintln!("mean NEES {mean_nees:.3}, inside 95% ellipsoid {inside:.3}");
    assert!((2.7..=3.3).contains(&mean_nees), "mean NEES {mean_nees}");
    assert!((0.93..=0.97).contains(&inside), "containment {inside}");
    let mean: Vector3<f64> = errors.iter().sum::<Vector3<f64>>() / n;
    for k in 0..3 {
        let var = errors.iter().map(|e| (e[k] - mean[k]).powi(2)).sum::<f64>() / (n - 1.0);
        let se = (var / n).sqrt();
        eprintln!(
            "axis {k}: mean error {:.4} m, standard error {:.4} m",
            mean[k], se
        );
        assert!(
            mean[k].abs() < 3.0 * se,
            "axis {k}: bias {} vs standard error {se}",
            mean[k]
        );
    }
}

/// Pearson correlation.
fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let syy: f64 = y.iter().map(|b| (b - my).powi(2)).sum();
    sxy / (sxx * syy).sqrt()
}

/// Ku et al. Fig. 7: the inverse norm of the covariance grows linearly with the number of
/// observations. (a) One landmark, the same drive sampled at 2–20 Hz: the same geometry,
/// `n` from ≈ 16 to ≈ 160. (b) Landmarks detected with probabilities 0.15–1 at 10 Hz: `n`
/// varies by thinning, and which rays survive adds scatter.
#[test]
fn inverse_covariance_norm_is_linear_in_the_number_of_observations() {
    let run = |detection: &dyn Fn(f64) -> f64, rate: &dyn Fn(f64) -> f64| {
        let mut n_obs = Vec::new();
        let mut inv_norm = Vec::new();
        for k in 0..40u64 {
            let x = k as f64 / 39.0;
            if let Some((_, c, n)) = one_landmark_trial(5000 + k, detection(x), rate(x)) {
                n_obs.push(n as f64);
                inv_norm.push(1.0 / c.symmetric_eigenvalues().max());
            }
        }
        assert!(n_obs.len() >= 39);
        correlation(&n_obs, &inv_norm)
    };
    let by_rate = run(&|_| 1.0, &|x| 2.0 + 18.0 * x);
    let by_detection = run(&|x| 0.15 + 0.85 * x, &|_| 10.0);
    eprintln!(
        "correlation of n_obs and 1/‖Σ‖: {by_rate:.4} (rate 2–20 Hz), {by_detection:.4} (detection 0.15–1)"
    );
    assert!(by_rate >= 0.99, "correlation {by_rate}");
    assert!(by_detection >= 0.95, "correlation {by_detection}");
}

#[test]
fn surrogates_need_rays_parallax_and_a_small_covariance() {
    let c = SurrogateCriteria::default();
    let good = MappedLandmark {
        id: 0,
        position_enu: Vector3::zeros(),
        covariance: Matrix3::from_diagonal_element(0.2 * 0.2),
        n_obs: 10,
        max_parallax_rad: 0.5,
        class: None,
    };
    assert!(c.accepts(&good));
    assert!(!c.accepts(&MappedLandmark {
        n_obs: MIN_SURROGATE_RAYS - 1,
        ..good.clone()
    }));
    assert!(!c.accepts(&MappedLandmark {
        max_parallax_rad: 0.05,
        ..good.clone()
    }));
    let mut cov = good.covariance;
    cov[(2, 2)] = 0.6 * 0.6;
    assert!(!c.accepts(&MappedLandmark {
        covariance: cov,
        ..good.clone()
    }));
    assert!(
        (MappedLandmark {
            covariance: cov,
            ..good
        }
        .sigma_m()
            - 0.6)
            .abs()
            < 1e-12
    );
}

#[test]
fn mapper_promotes_surrogates_as_rays_accumulate_and_drops_stray_rays() {
    let mut config = DriveConfig::straight(100.0);
    config.sigma_gps_horizontal_m = 0.05;
    config.sigma_gps_vertical_m = 0.05;
    config.sigma_heading_rad = 1e-3;
    config.sigma_level_rad = 1e-3;
    let lamp = Vector3::new(50.0, -6.0, 7.0);
    let mut r = rng(7);
    let sc = MappingScenario::generate(&mut r, &config, &[lamp], None);
    let frames = sc.mapping_frames(1e-3);
    let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
    let mut first_surrogate = None;
    for (i, f) in frames.iter().enumerate() {
        let mut f = f.clone();
        if i == 3 {
            // A stray detection pointing straight up: never seen again, must be pruned.
            f.observations.push(RigObservation {
                ray_in_rig: Ray::try_new(Vector3::zeros(), Vector3::z()).unwrap(),
                sigma_rad: 1e-3,
                class: None,
            });
        }
        mapper.add_frame(&f).unwrap();
        if first_surrogate.is_none() && !mapper.surrogates().is_empty() {
            first_surrogate = Some(mapper.surrogates()[0].clone());
        }
    }
    let s = first_surrogate.expect("a surrogate");
    assert!(s.n_obs >= MIN_SURROGATE_RAYS && s.max_parallax_rad >= MIN_SURROGATE_PARALLAX_RAD);
    assert!(s.sigma_m() <= MAX_SURROGATE_SIGMA_M);
    assert_eq!(mapper.landmarks().len(), 1);
    assert_eq!(mapper.track_count(), 1, "the stray ray's track is pruned");
    assert!((mapper.landmarks()[0].position_enu - lamp).norm() < 0.2);
}

#[test]
fn classes_are_never_mixed() {
    // Two landmarks at the same place but different classes stay two tracks.
    let config = DriveConfig::straight(60.0);
    let lamp = Vector3::new(30.0, -6.0, 7.0);
    let mut r = rng(9);
    let sc = MappingScenario::generate(&mut r, &config, &[lamp], None);
    let mut frames = sc.mapping_frames(config.sigma_level_rad);
    for f in &mut frames {
        let mut o = f.observations[0];
        o.class = Some(1);
        f.observations[0].class = Some(0);
        f.observations.push(o);
    }
    let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
    for f in &frames {
        let ids = mapper.add_frame(f).unwrap();
        assert_ne!(ids[0], ids[1]);
    }
    let l = mapper.landmarks();
    assert_eq!(l.len(), 2);
    assert_ne!(l[0].class, l[1].class);
}

#[test]
fn invalid_frames_and_options_are_errors_and_leave_the_mapper_unchanged() {
    let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
    let mut frame = MappingFrame {
        time_s: 0.0,
        world_from_rig: Pose::identity(),
        pose_covariance: Matrix6::identity() * 0.01,
        observations: vec![RigObservation {
            ray_in_rig: Ray::try_new(Vector3::zeros(), Vector3::x()).unwrap(),
            sigma_rad: -1.0,
            class: None,
        }],
    };
    assert!(matches!(
        mapper.add_frame(&frame),
        Err(MappingError::InvalidObservation {
            frame: 0,
            observation: 0,
            ..
        })
    ));
    frame.observations[0].sigma_rad = 1e-3;
    frame.pose_covariance[(3, 3)] = f64::NAN;
    assert!(matches!(
        mapper.add_frame(&frame),
        Err(MappingError::InvalidPose { frame: 0 })
    ));
    assert_eq!((mapper.track_count(), mapper.frames_added()), (0, 0));
    let bad = MapperOptions {
        max_range_m: 0.0,
        ..Default::default()
    };
    assert!(matches!(
        LandmarkMapper::new(bad),
        Err(MappingError::InvalidOption("max_range_m"))
    ));
}

#[test]
fn a_stationary_rig_maps_nothing_and_reports_no_nan() {
    let lamp = Vector3::new(10.0, 5.0, 6.0);
    let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
    for k in 0..30 {
        let pose = Pose::from_parts(Translation3::new(0.0, 0.0, 2.0), Rotation3::identity());
        let frame = MappingFrame {
            time_s: k as f64 * 0.1,
            world_from_rig: pose,
            pose_covariance: Matrix6::identity() * 1e-4,
            observations: vec![RigObservation {
                ray_in_rig: Ray::try_new(Vector3::zeros(), lamp - Vector3::new(0.0, 0.0, 2.0))
                    .unwrap(),
                sigma_rad: 1e-3,
                class: None,
            }],
        };
        let ids = mapper.add_frame(&frame).unwrap();
        assert_eq!(ids, vec![0], "every ray joins the one track");
    }
    assert!(mapper.landmarks().is_empty());
}

#[test]
fn gps_interpolation_wraps_the_heading_and_stays_inside_the_track() {
    let fix = |t: f64, h_deg: f64| GpsSample {
        time_s: t,
        position_enu: Vector3::new(t, 0.0, 0.0),
        heading_rad: h_deg.to_radians(),
        sigma_horizontal_m: 1.0,
        sigma_vertical_m: 1.0,
        sigma_heading_rad: 0.01,
    };
    let track = [fix(0.0, 359.0), fix(1.0, 1.0), fix(2.0, 3.0)];
    let (pose, _) = gps_pose_at(&track, 0.5, 0.0).unwrap();
    // Heading 0°: rig x points north.
    assert!((pose.rotation * Vector3::x() - Vector3::y()).norm() < 1e-12);
    assert!(gps_pose_at(&track, 2.0, 0.0).is_some());
    assert!(gps_pose_at(&track, 2.0001, 0.0).is_none());
    assert!(gps_pose_at(&track, -0.1, 0.0).is_none());
    let unordered = [fix(0.0, 0.0), fix(0.0, 0.0)];
    assert!(matches!(
        survey(&unordered, &[], &SurveyOptions::default()),
        Err(MappingError::GpsTrack { index: 1, .. })
    ));
}

#[test]
fn landmarks_csv_round_trips_through_the_landmarks_reader() {
    let frame = vgps_geometry::geo::LocalFrame::new(
        vgps_geometry::geo::Geodetic::try_new(37.77, -122.42, 10.0).unwrap(),
    );
    let l = vec![
        MappedLandmark {
            id: 4,
            position_enu: Vector3::new(120.5, -33.25, 6.5),
            covariance: Matrix3::from_diagonal(&Vector3::new(0.01, 0.04, 0.09)),
            n_obs: 12,
            max_parallax_rad: 0.8,
            class: Some(1),
        },
        MappedLandmark {
            id: 9,
            position_enu: Vector3::new(-5.0, 8.0, 2.0),
            covariance: Matrix3::identity() * 0.25,
            n_obs: 3,
            max_parallax_rad: 0.2,
            class: None,
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("landmarks.csv");
    write_landmarks_csv(&path, &l, &frame, &["pole".into(), "street, light".into()]).unwrap();
    let back = vgps_io::read_landmarks(&path).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[0].id, "m4");
    assert_eq!(back[0].class.as_deref(), Some("street, light"));
    assert_eq!(back[1].class, None);
    assert!((back[0].sigma_m.unwrap() - 0.3).abs() < 1e-4);
    for (orig, read) in l.iter().zip(&back) {
        let g =
            vgps_geometry::geo::Geodetic::try_new(read.lat_deg, read.lon_deg, read.alt_m).unwrap();
        assert!((frame.to_enu(&g) - orig.position_enu).norm() < 1e-3);
    }
}

/// A rectangular loop with lights on both sides, GPS lagging by `lag` seconds.
fn loop_scenario(seed: u64, lag: f64) -> (MappingScenario, DriveConfig) {
    let mut config = DriveConfig::straight(1.0);
    config.waypoints = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(150.0, 0.0, 0.0),
        Vector3::new(150.0, 100.0, 0.0),
        Vector3::new(0.0, 100.0, 0.0),
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(20.0, 0.0, 0.0),
    ];
    config.gps_lag_s = lag;
    // The paper's setting: lights on one side of the road only.
    let lights = streetlights_along(&config, 30.0, 6.0, 7.0, false);
    let mut r = rng(seed);
    (
        MappingScenario::generate(&mut r, &config, &lights, None),
        config,
    )
}

#[test]
fn gps_time_offset_is_recovered_on_a_loop_and_applying_it_removes_the_lag_error() {
    let lag = 0.15; // 1.5 m at 10 m/s: the paper's "about a metre behind".
    let mut ok = 0;
    let trials = 3;
    for seed in 0..trials {
        let (sc, config) = loop_scenario(300 + seed, lag);
        let base = SurveyOptions {
            sigma_level_rad: config.sigma_level_rad,
            ..Default::default()
        };
        let search = OffsetSearch {
            min_s: -0.3,
            max_s: 0.3,
            ..Default::default()
        };
        let cal = calibrate_gps_offset(&sc.gps, &sc.frames, &base, &search).unwrap();
        let sigma = cal.sigma_s.unwrap_or(f64::INFINITY);
        eprintln!(
            "seed {seed}: offset {:.4} s ± {sigma:.4}, χ² {:.0} → {:.0} ({} dof, {} landmarks)",
            cal.offset_s, cal.chi2_at_zero, cal.chi2_at_offset, cal.dof, cal.n_landmarks
        );
        // Mean landmark error with and without the offset.
        let err = |offset: f64| {
            let o = SurveyOptions {
                gps_time_offset_s: offset,
                ..base
            };
            let s = survey(&sc.gps, &sc.frames, &o).unwrap();
            let e: Vec<f64> = s
                .landmarks
                .iter()
                .zip(&s.sources)
                .map(|(l, (_, src))| {
                    (l.position_enu - sc.landmarks[sc.truth[src[0].0][src[0].1]]).norm()
                })
                .collect();
            let mut e = e;
            e.sort_by(f64::total_cmp);
            e[e.len() / 2]
        };
        let (before, after) = (err(0.0), err(cal.offset_s));
        eprintln!("  median landmark error {before:.3} m → {after:.3} m");
        if (cal.offset_s - lag).abs() < 0.03
            && (cal.offset_s - lag).abs() < 3.0 * sigma
            && after < 0.6 * before
        {
            ok += 1;
        }
    }
    assert_eq!(ok, trials);
}

/// The gates' quadratic forms (`vᵀSv`, `EᵀSE`) equal those of the full residual covariance,
/// and the full covariance equals the textbook `P J Σ Jᵀ P + d²σ² P` it is built to match.
#[test]
fn residual_quadratic_forms_match_the_full_covariance() {
    use super::refine::{ray_residual_tangent, ray_residual_variance};
    use vgps_geometry::synthetic::{random_unit_vector, tangent_basis};
    let mut r = rng(11);
    for _ in 0..200 {
        let mut l = Matrix6::zeros();
        for i in 0..6 {
            for j in 0..=i {
                l[(i, j)] = normal(&mut r) * if i < 3 { 0.3 } else { 0.01 };
            }
        }
        let cov = l * l.transpose();
        let origin = Vector3::from_iterator((0..3).map(|_| normal(&mut r) * 10.0));
        let rig_origin = origin + Vector3::from_iterator((0..3).map(|_| normal(&mut r) * 0.2));
        let u = random_unit_vector(&mut r);
        let ray = MapRay {
            ray: Ray::try_new(origin, u).unwrap(),
            rig_origin,
            pose_covariance: cov,
            sigma_rad: 1e-3,
        };
        let point = origin + u * 30.0 + Vector3::from_iterator((0..3).map(|_| normal(&mut r)));
        let s = ray_residual_covariance(&ray, &point);
        // Reference: the general products.
        let lever = point - rig_origin;
        let mut j = nalgebra::Matrix3x6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::identity());
        j.fixed_view_mut::<3, 3>(0, 3).copy_from(&-Matrix3::new(
            0.0, -lever.z, lever.y, lever.z, 0.0, -lever.x, -lever.y, lever.x, 0.0,
        ));
        let p = Matrix3::identity() - u * u.transpose();
        let d2 = (point - origin).norm_squared();
        let reference = p * (j * cov * j.transpose()) * p + p * (d2 * 1e-6);
        let scale = reference.norm();
        assert!(
            (s - reference).norm() <= 1e-12 * scale.max(1e-12),
            "{s} vs {reference}"
        );
        let v = random_unit_vector(&mut r);
        let q = ray_residual_variance(&ray, &point, &v);
        assert!((q - v.dot(&(s * v))).abs() <= 1e-12 * scale.max(1e-12));
        let (e1, e2) = tangent_basis(&u);
        let (s11, s12, s22) = ray_residual_tangent(&ray, &point, &e1, &e2);
        assert!((s11 - e1.dot(&(s * e1))).abs() <= 1e-12 * scale.max(1e-12));
        assert!((s12 - e1.dot(&(s * e2))).abs() <= 1e-12 * scale.max(1e-12));
        assert!((s22 - e2.dot(&(s * e2))).abs() <= 1e-12 * scale.max(1e-12));
    }
}

/// A track whose rays alternate between two lamps 2 m apart (what wide gates let through)
/// does not meet at one point within the rays' independent noise: no surrogate; the rays of
/// one lamp do.
#[test]
fn rays_of_two_landmarks_fail_the_surrogate_consistency_test() {
    let a = Vector3::new(40.0, -8.0, 7.0);
    let b = a + Vector3::new(2.0, 0.0, 0.0);
    let cov = diag6([0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3]);
    let mut r = rng(11);
    let noisy = |rays: Vec<MapRay>, r: &mut _| -> Vec<MapRay> {
        rays.into_iter()
            .map(|mut m| {
                m.ray.direction =
                    vgps_geometry::synthetic::perturb_bearing(r, &m.ray.direction, 1e-3);
                m
            })
            .collect()
    };
    let one = noisy(
        rays_to(&a, (0..20).map(|k| 1.5 * k as f64), cov, 1e-3),
        &mut r,
    );
    let e = refine_landmark(&one).unwrap();
    assert!(super::mapper::rays_consistent(&one, &e.point));
    let mixed: Vec<MapRay> = (0..20)
        .map(|k| {
            let lamp = if k % 2 == 0 { a } else { b };
            rays_to(&lamp, std::iter::once(1.5 * k as f64), cov, 1e-3)[0]
        })
        .collect();
    let mixed = noisy(mixed, &mut r);
    let e = refine_landmark(&mixed).unwrap();
    // The refinement alone would call it a good landmark (σ well under the surrogate bound).
    assert!(e.covariance.symmetric_eigenvalues().max().sqrt() < MAX_SURROGATE_SIGMA_M);
    assert!(!super::mapper::rays_consistent(&mixed, &e.point));
    assert!(!super::mapper::rays_consistent(&[], &a));
}

/// `add_frame_with_shared`: the gates and the landmark covariance use the frame's
/// (independent) pose covariance, the surrogate's pose-correlation floor the shared one.
#[test]
fn shared_pose_error_goes_into_the_floor_not_the_gates() {
    let lamp = Vector3::new(30.0, -6.0, 7.0);
    let independent = diag6([0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3]);
    let shared = Matrix3::from_diagonal_element(1.0);
    let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
    let mut r = rng(12);
    for k in 0..30 {
        let o = Vector3::new(1.5 * k as f64, 0.0, 2.0);
        let pose = Pose::from_parts(Translation3::from(o), Rotation3::identity());
        let d = vgps_geometry::synthetic::perturb_bearing(&mut r, &(lamp - o).normalize(), 1e-3);
        let frame = MappingFrame {
            time_s: 0.1 * k as f64,
            world_from_rig: pose,
            pose_covariance: independent,
            observations: vec![RigObservation {
                ray_in_rig: Ray::try_new(Vector3::zeros(), d).unwrap(),
                sigma_rad: 1e-3,
                class: None,
            }],
        };
        mapper.add_frame_with_shared(&frame, &shared).unwrap();
    }
    let near = mapper.surrogates_near(&Vector3::zeros(), 200.0);
    assert_eq!(near.len(), 1);
    assert!((near[0].pose_floor_covariance - shared).norm() < 1e-12);
    assert!(
        near[0].landmark.sigma_m() < 0.1,
        "{}",
        near[0].landmark.sigma_m()
    );
    assert!((near[0].landmark.position_enu - lamp).norm() < 0.1);
    assert_eq!(mapper.surrogates().len(), 1);
    // A non-finite shared covariance is refused and leaves the mapper unchanged.
    let bad = Matrix3::from_diagonal_element(f64::NAN);
    let frame = MappingFrame {
        time_s: 10.0,
        world_from_rig: Pose::identity(),
        pose_covariance: independent,
        observations: Vec::new(),
    };
    assert!(mapper.add_frame_with_shared(&frame, &bad).is_err());
    assert_eq!(mapper.frames_added(), 30);
}
