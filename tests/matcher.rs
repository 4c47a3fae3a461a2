//! The landmark matcher: bad input statuses, the repetitive-street integrity case and a
//! small fixed-seed Monte Carlo on the synthetic city (the large one is
//! `examples/matcher_monte_carlo.rs`).
use nalgebra::Vector3;
use rand::RngExt;
use vgps::geometry::{Pose, Ray, bearing_in_rig};
use vgps::matcher::{
    DbLandmark, Detection, LandmarkDb, MatchError, MatchOptions, MatchStatus, SearchArea,
    match_detections,
};
use vgps::synthetic::matcher::{CityConfig, CityWorld, FrameConfig, Trial};
use vgps::synthetic::{random_unit_vector, rng};

/// Detections of a central rig (every ray from the rig origin) with the given bearings.
fn central_detections(bearings: &[Vector3<f64>]) -> Vec<Detection> {
    bearings
        .iter()
        .map(|b| Detection::new(Ray::try_new(Vector3::zeros(), *b).unwrap()))
        .collect()
}

fn db_of(points: &[Vector3<f64>]) -> LandmarkDb {
    vgps::synthetic::matcher::landmark_db(points).unwrap()
}

fn detections_of(pose: &Pose, points: &[Vector3<f64>]) -> Vec<Detection> {
    points
        .iter()
        .map(|p| {
            Detection::new(
                Ray::try_new(Vector3::zeros(), bearing_in_rig(pose, p).unwrap()).unwrap(),
            )
        })
        .collect()
}

/// A straight street with streetlights every 25 m on both kerbs and nothing else.
fn straight_street() -> Vec<Vector3<f64>> {
    (0..=20)
        .flat_map(|k| {
            let x = 25.0 * k as f64;
            [Vector3::new(x, 8.0, 6.0), Vector3::new(x, -8.0, 6.0)]
        })
        .collect()
}

#[test]
fn bad_input_gives_a_status_and_no_fix() {
    let points = straight_street();
    let db = db_of(&points);
    let pose = Pose::new(Vector3::new(250.0, 1.0, 2.0), Vector3::new(0.0, 0.0, 0.4));
    let visible: Vec<Vector3<f64>> = points
        .iter()
        .filter(|p| (*p - pose.translation.vector).norm() < 80.0)
        .copied()
        .collect();
    let all = detections_of(&pose, &visible);
    let area = SearchArea::around(&pose.translation.vector, 10.0, 1.0).unwrap();
    let options = MatchOptions::default();

    let r = match_detections(&db, &all[..2], &area, &options).unwrap();
    assert_eq!(r.status, MatchStatus::TooFewDetections);
    assert!(r.estimate.is_none() && r.assignment == vec![None; 2]);

    let mut duplicated = all.clone();
    duplicated.push(all[3]);
    let r = match_detections(&db, &duplicated, &area, &options).unwrap();
    assert_eq!(r.status, MatchStatus::DuplicateDetections);
    assert!(r.estimate.is_none());

    // A prior 5 km away from every landmark.
    let far = SearchArea::around(&Vector3::new(5000.0, 5000.0, 2.0), 30.0, 1.0).unwrap();
    let r = match_detections(&db, &all, &far, &options).unwrap();
    assert_eq!(r.status, MatchStatus::NoLandmarksInRange);
    assert!(r.estimate.is_none());

    // Random directions only: nothing matches.
    let mut g = rng(3);
    let noise: Vec<Detection> = (0..12)
        .map(|_| {
            Detection::new(Ray::try_new(Vector3::zeros(), random_unit_vector(&mut g)).unwrap())
        })
        .collect();
    let r = match_detections(&db, &noise, &area, &options).unwrap();
    assert_ne!(r.status, MatchStatus::Ok);
    assert!(r.estimate.is_none());

    let bad = MatchOptions {
        sigma_rad: -1.0,
        ..MatchOptions::default()
    };
    assert_eq!(
        match_detections(&db, &all, &area, &bad),
        Err(MatchError::InvalidOption("sigma_rad"))
    );
    let no_radius = SearchArea {
        horizontal_radius_m: Some(f64::NAN),
        ..area
    };
    assert_eq!(
        match_detections(&db, &all, &no_radius, &options),
        Err(MatchError::InvalidArea)
    );
    let no_rounds = MatchOptions {
        max_rounds: 0,
        ..MatchOptions::default()
    };
    assert_eq!(
        match_detections(&db, &all, &area, &no_rounds),
        Err(MatchError::InvalidOption("max_rounds"))
    );
    assert!(
        LandmarkDb::new(vec![DbLandmark {
            id: "x".into(),
            position_in_world: Vector3::new(f64::NAN, 0.0, 0.0),
            class: None,
            sigma_m: 0.0,
        }])
        .is_err()
    );
}

#[test]
fn a_regular_straight_street_is_ambiguous_not_a_guess() {
    let points = straight_street();
    let db = db_of(&points);
    let pose = Pose::new(Vector3::new(250.0, 1.0, 2.0), Vector3::new(0.0, 0.0, 0.4));
    let visible: Vec<Vector3<f64>> = points
        .iter()
        .filter(|p| (*p - pose.translation.vector).norm() < 60.0)
        .copied()
        .collect();
    let detections = detections_of(&pose, &visible);
    // The prior (±30 m) holds the truth and the poses one lamp spacing along the street.
    let area = SearchArea::around(&Vector3::new(245.0, 0.0, 2.0), 30.0, 1.0).unwrap();
    let r = match_detections(&db, &detections, &area, &MatchOptions::default()).unwrap();
    assert_eq!(r.status, MatchStatus::Ambiguous, "{r:?}");
    assert!(r.estimate.is_none());
    let runner_up = r.runner_up_score.expect("a runner-up score");
    assert!(runner_up + MatchOptions::default().ambiguity_margin > r.best_score);
    // The runner-up is another explanation of the regular street: a whole lamp spacing
    // along it, or across it facing another way (the two kerbs are alike).
    let other = r.runner_up_pose.unwrap();
    let shift = (other.translation.vector - pose.translation.vector).norm();
    // (Angle between the rig +x axes: robust for a half-turn, unlike the trace formula.)
    let turn = vgps::geometry::angle_between(
        &(other.rotation * Vector3::x()),
        &(pose.rotation * Vector3::x()),
    );
    assert!(shift > 10.0 || turn > 1.0, "{other:?}");
}

#[test]
fn city_frames_with_a_prior_give_right_fixes_and_no_wrong_ones() {
    let mut g = rng(11);
    let world = CityWorld::generate(&mut g, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let config = FrameConfig::default();
    let options = MatchOptions {
        sigma_rad: config.sigma_rad,
        ..MatchOptions::default()
    };
    let frames = 6;
    let mut right = 0;
    for _ in 0..frames {
        let pose = world.random_rig_pose(&mut g);
        let frame = world.frame(&mut g, &pose, &config);
        let detections: Vec<Detection> = central_detections(&frame.detections);
        let offset = Vector3::new(17.0, -12.0, 0.0); // 20.8 m from the truth
        let area = SearchArea::around(&(pose.translation.vector + offset), 30.0, 1.0).unwrap();
        let r = match_detections(&db, &detections, &area, &options).unwrap();
        if r.status == MatchStatus::Ok {
            let e = r.estimate.unwrap();
            let error = (e.world_from_rig.translation.vector - pose.translation.vector).norm();
            assert!(error < 0.5, "wrong fix: {error} m");
            for (a, t) in r.assignment.iter().zip(&frame.truth) {
                assert!(a.is_none() || a == t, "wrong link {a:?} for {t:?}");
            }
            assert!(r.best_score >= options.min_inliers);
            right += 1;
        } else {
            assert!(r.estimate.is_none());
        }
    }
    // 11 of 12 in the example run with seed 1; at least 5 of 6 here.
    assert!(right >= 5, "{right} of {frames}");
}

#[test]
fn a_prior_is_a_disc_not_its_bounding_square() {
    // The rig in a corner of the prior's bounding square, 36 m from its centre: a box of
    // ±30 m holds it, the 30 m prior does not, so the true pose is never the fix (a fix, if
    // any, lies inside the prior: a look-alike, which a wrong prior can give); 24 m away the
    // truth is found.
    let mut g = rng(12);
    let world = CityWorld::generate(&mut g, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let config = FrameConfig::default();
    let options = up4_options();
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..6 {
        let pose = world.random_rig_pose(&mut g);
        let frame = world.frame(&mut g, &pose, &config);
        let detections = central_detections(&frame.detections);
        let truth = pose.translation.vector;
        let corner =
            SearchArea::around(&(truth - Vector3::new(25.5, 25.5, 0.0)), 30.0, 1.0).unwrap();
        assert!(!corner.contains(&truth));
        let square = SearchArea {
            horizontal_radius_m: None,
            ..corner
        };
        assert!(square.contains(&truth));
        let r = match_detections(&db, &detections, &corner, &options).unwrap();
        assert!(
            r.estimate
                .as_ref()
                .is_none_or(|e| corner.contains(&e.world_from_rig.translation.vector))
        );
        assert!(
            r.estimate
                .as_ref()
                .is_none_or(|e| (e.world_from_rig.translation.vector - truth).norm() > 5.0)
        );
        outside += usize::from(r.status == MatchStatus::Ok);
        let near = SearchArea::around(&(truth - Vector3::new(17.0, 17.0, 0.0)), 30.0, 1.0).unwrap();
        let r = match_detections(&db, &detections, &near, &options).unwrap();
        if r.status == MatchStatus::Ok {
            let e = r.estimate.unwrap();
            assert!((e.world_from_rig.translation.vector - truth).norm() < 0.5);
            inside += 1;
        }
        let r = match_detections(&db, &detections, &square, &options).unwrap();
        if r.status == MatchStatus::Ok {
            let e = r.estimate.unwrap();
            assert!((e.world_from_rig.translation.vector - truth).norm() < 0.5);
        }
    }
    assert!(inside >= 5, "{inside} of 6");
    // Seed 12: one of the six corner priors holds a look-alike of 7 inliers 25 m from the
    // truth (runner-up 5); the others give no fix.
    assert!(outside <= 1, "{outside} look-alikes");
}

#[test]
fn a_known_vertical_gives_the_same_right_fixes() {
    let mut g = rng(12);
    let world = CityWorld::generate(&mut g, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let config = FrameConfig::default();
    // The synthetic rig tilts by up to 3°: a 4° tolerance always holds the truth.
    let options = up4_options();
    let frames = 20;
    let mut right = 0;
    for _ in 0..frames {
        let pose = world.random_rig_pose(&mut g);
        let frame = world.frame(&mut g, &pose, &config);
        let detections: Vec<Detection> = central_detections(&frame.detections);
        let area = SearchArea::around(
            &(pose.translation.vector + Vector3::new(-20.0, 9.0, 0.0)),
            30.0,
            1.0,
        )
        .unwrap();
        let r = match_detections(&db, &detections, &area, &options).unwrap();
        if r.status == MatchStatus::Ok {
            let e = r.estimate.unwrap();
            let error = (e.world_from_rig.translation.vector - pose.translation.vector).norm();
            assert!(error < 0.5, "wrong fix: {error} m");
            for (a, t) in r.assignment.iter().zip(&frame.truth) {
                assert!(a.is_none() || a == t, "wrong link {a:?} for {t:?}");
            }
            right += 1;
        }
    }
    // 98.4 % right in the 1,000-frame example run; at least 18 of 20 here.
    assert!(right >= 18, "{right} of {frames}");
    // An invalid vertical is an error, not a silent generic search.
    let bad = MatchOptions {
        up_in_rig: Some((Vector3::zeros(), 0.1)),
        ..options
    };
    let pose = world.random_rig_pose(&mut g);
    let frame = world.frame(&mut g, &pose, &config);
    let detections: Vec<Detection> = central_detections(&frame.detections);
    let area = SearchArea::around(&pose.translation.vector, 30.0, 1.0).unwrap();
    assert_eq!(
        match_detections(&db, &detections, &area, &bad),
        Err(MatchError::InvalidOption("up_in_rig"))
    );
}

/// Night frames: lamps among many other lights (75 % false detections), some lamps seen by
/// two cameras of a non-central rig. The first core of detections then rarely holds three
/// lamps; the search widens its core until it does, and a landmark in the overlap of two
/// cameras counts for both.
#[test]
fn lamps_among_many_other_lights_are_found_and_seen_twice() {
    let mut g = rng(23);
    let world = CityWorld::generate(&mut g, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let config = FrameConfig {
        true_detections: 12,
        false_detections: 0,
        ..FrameConfig::default()
    };
    let options = MatchOptions {
        sigma_rad: config.sigma_rad,
        up_in_rig: Some((Vector3::z(), 4f64.to_radians())),
        ..MatchOptions::default()
    };
    // The second camera of an overlap sits 6 cm from the first.
    let second_camera = Vector3::new(0.04, 0.045, 0.0);
    let one_round = MatchOptions {
        max_rounds: 1,
        ..options
    };
    let frames = 8;
    let (mut right, mut doubly_seen, mut right_in_one_round) = (0, 0, 0);
    for _ in 0..frames {
        let pose = world.random_rig_pose(&mut g);
        let frame = world.frame(&mut g, &pose, &config);
        let mut detections: Vec<Detection> = central_detections(&frame.detections);
        let mut truth = frame.truth.clone();
        // 36 other lights (windows, cars) at the heights of the landmarks, so that the
        // known vertical does not tell them apart: 75 % false detections.
        for _ in 0..36 {
            let azimuth = g.random_range(0.0..std::f64::consts::TAU);
            let range = g.random_range(10.0..80.0);
            let height = g.random_range(1.0..25.0);
            let light = Vector3::new(
                pose.translation.vector.x + range * azimuth.cos(),
                pose.translation.vector.y + range * azimuth.sin(),
                height,
            );
            let bearing = bearing_in_rig(&pose, &light).unwrap();
            detections.push(Detection::new(
                Ray::try_new(Vector3::zeros(), bearing).unwrap(),
            ));
            truth.push(None);
        }
        // The first three true detections are also seen from the second camera.
        let twice: Vec<usize> = frame.truth.iter().flatten().take(3).copied().collect();
        for &k in &twice {
            let direction = pose
                .inverse_transform_point(&world.true_landmarks[k].into())
                .coords
                - second_camera;
            detections.push(Detection::new(
                Ray::try_new(second_camera, direction).unwrap(),
            ));
            truth.push(Some(k));
        }
        // In random order (the first detection starts the farthest-point core).
        for i in (1..detections.len()).rev() {
            let j = g.random_range(0..=i);
            detections.swap(i, j);
            truth.swap(i, j);
        }
        let area = SearchArea::around(
            &(pose.translation.vector + Vector3::new(6.0, -4.0, 0.0)),
            15.0,
            1.0,
        )
        .unwrap();
        let first = match_detections(&db, &detections, &area, &one_round).unwrap();
        right_in_one_round += usize::from(first.status == MatchStatus::Ok);
        let r = match_detections(&db, &detections, &area, &options).unwrap();
        if r.status != MatchStatus::Ok {
            assert!(r.estimate.is_none());
            continue;
        }
        let e = r.estimate.unwrap();
        let error = (e.world_from_rig.translation.vector - pose.translation.vector).norm();
        assert!(error < 0.5, "wrong fix: {error} m");
        for (a, t) in r.assignment.iter().zip(&truth) {
            assert!(a.is_none() || a == t, "wrong link {a:?} for {t:?}");
        }
        right += 1;
        doubly_seen += twice
            .iter()
            .filter(|&&k| r.assignment.iter().filter(|a| **a == Some(k)).count() == 2)
            .count();
    }
    eprintln!("{right} of {frames} fixed; {right_in_one_round} with one round");
    assert!(right >= 7, "{right} of {frames} frames fixed");
    // The widening is what finds them: the first core alone fixes far fewer.
    assert!(
        right_in_one_round + 3 <= right,
        "{right_in_one_round} with one round, {right} with widening"
    );
    // Most of the landmarks seen by both cameras are linked to both detections.
    assert!(
        doubly_seen >= 2 * right,
        "{doubly_seen} double links in {right} fixes"
    );
}

/// The landmarks and frame `index` of `matcher_monte_carlo -- prior FRAMES seed` (the
/// default city).
fn monte_carlo_prior_frame(seed: u64, index: usize) -> (LandmarkDb, Trial) {
    let config = FrameConfig::default();
    let mut r = rng(seed);
    let world = CityWorld::generate(&mut r, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let mut trial = world.prior_trial(&mut r, &config);
    for _ in 0..index {
        trial = world.prior_trial(&mut r, &config);
    }
    (db, trial)
}

/// The landmarks and frame `index` of `matcher_monte_carlo -- cold FRAMES seed` (the
/// sparse city).
fn monte_carlo_cold_frame(seed: u64, index: usize) -> (LandmarkDb, Trial) {
    let config = FrameConfig::default();
    let mut r = rng(seed);
    let world = CityWorld::generate(&mut r, &CityConfig::sparse());
    let db = world.landmark_db().unwrap();
    let mut trial = world.cold_trial(&mut r, &config, &db);
    for _ in 0..index {
        trial = world.cold_trial(&mut r, &config, &db);
    }
    (db, trial)
}

/// The options of the Monte-Carlo experiment with a known vertical (`UP_TOL_DEG=4`).
/// A rig tilted 5.3° (beyond a stated 4° vertical, within P3P's 2° margin of it) is not
/// fixed under that vertical: the refined pose contradicts it, so it may only be a
/// runner-up. Stated 6.5°, the same frames are fixed right.
#[test]
fn a_pose_tilted_beyond_the_stated_vertical_is_not_a_fix() {
    let mut g = rng(31);
    let world = CityWorld::generate(&mut g, &CityConfig::default());
    let db = world.landmark_db().unwrap();
    let config = FrameConfig::default();
    let (mut refused, mut right) = (0, 0);
    let frames = 10;
    for k in 0..frames {
        let level = world.random_rig_pose(&mut g);
        let heading = (level.rotation * Vector3::x())
            .y
            .atan2((level.rotation * Vector3::x()).x);
        // Rolled about its own forward axis after its heading: a tilt of exactly 5.3°.
        let rotation = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading)
            * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 5.3f64.to_radians());
        let pose = Pose::from_parts(level.translation, rotation.into());
        let frame = world.frame(&mut g, &pose, &config);
        let detections: Vec<Detection> = central_detections(&frame.detections);
        let area = SearchArea::around(&pose.translation.vector, 30.0, 1.0).unwrap();
        let stated = |deg: f64| MatchOptions {
            up_in_rig: Some((Vector3::z(), deg.to_radians())),
            ..up4_options()
        };
        let r4 = match_detections(&db, &detections, &area, &stated(4.0)).unwrap();
        assert_ne!(
            r4.status,
            MatchStatus::Ok,
            "frame {k}: a fix under a 4° vertical"
        );
        refused += 1;
        let r6 = match_detections(&db, &detections, &area, &stated(6.5)).unwrap();
        if r6.status == MatchStatus::Ok {
            let e = r6.estimate.unwrap();
            let error = (e.world_from_rig.translation.vector - pose.translation.vector).norm();
            assert!(error < 0.5, "frame {k}: wrong fix under 6.5°: {error} m");
            right += 1;
        }
    }
    assert_eq!(refused, frames);
    assert!(
        right >= 8,
        "{right} of {frames} fixed under a 6.5° vertical"
    );
}

fn up4_options() -> MatchOptions {
    MatchOptions {
        sigma_rad: FrameConfig::default().sigma_rad,
        up_in_rig: Some((Vector3::z(), 4.0_f64.to_radians())),
        ..MatchOptions::default()
    }
}

#[test]
fn hard_frames_of_the_monte_carlo_are_fixed_right() {
    // Frames of `UP_TOL_DEG=4 cargo run --release --example matcher_monte_carlo -- prior
    // 10000 SEED` that went wrong (each fails without its fix):
    // - seed 42, frame 351: a pose from three nearly collinear lamps, 0.5 m low, was confirmed
    //   twice with 8 of 16 inliers and refined into a worse one (6): the early stop now
    //   needs a decisive refined conclusion;
    // - seed 42, frame 1476: two refined copies of the true pose compared as distinct
    //   (`Rotation3::angle` was NaN) and made the frame `ambiguous`;
    // - seed 7, frame 6382: a wrong fix, 25 m off: a repetitive look-alike with 9 inliers
    //   was "confirmed" by two triples sharing the same false detection before any
    //   triple gave the true pose; confirmations now need disjoint triples;
    // - seed 42, frames 1168 and 1327 and 6537: a false detection linked to a landmark
    //   (3.8σ from it under the fix; 1.4σ and 4.0σ, but 24σ and 32σ under the true pose:
    //   the false link had pulled the pose 10 and 18 cm towards a nearby landmark). Links
    //   are now kept only when their probability given the other links is ≥ 0.999;
    // - seed 42, frame 1036: 14 inliers against a look-alike one lamp spacing along the
    //   street with 13 (log odds 10): was `ambiguous`; the evidence is now weighed when the
    //   best is one inlier short of the margin.
    for (seed, index) in [
        (42u64, 351usize),
        (42, 1036),
        (42, 1168),
        (42, 1327),
        (42, 1476),
        (42, 6537),
        (7, 6382),
    ] {
        let (db, trial) = monte_carlo_prior_frame(seed, index);
        let detections: Vec<Detection> = central_detections(&trial.frame.detections);
        let result = match_detections(&db, &detections, &trial.area, &up4_options()).unwrap();
        assert_eq!(
            result.status,
            MatchStatus::Ok,
            "seed {seed} frame {index}: {result:?}"
        );
        let estimate = result.estimate.as_ref().unwrap();
        let error =
            (estimate.world_from_rig.translation.vector - trial.pose.translation.vector).norm();
        assert!(error < 0.1, "seed {seed} frame {index}: {error} m");
        for (d, (a, t)) in result.assignment.iter().zip(&trial.frame.truth).enumerate() {
            assert!(
                a.is_none() || a == t,
                "seed {seed} frame {index} detection {d}"
            );
        }
        // The fix explains nearly every true detection (frame 6537 stops at 12 of 14: its
        // false link is dropped and the refined pose is 2.5 cm from the truth).
        let true_detections = trial.frame.truth.iter().flatten().count();
        assert!(result.best_score + 2 >= true_detections, "{result:?}");
        for (a, p) in result.assignment.iter().zip(&result.link_probability) {
            assert_eq!(a.is_some(), p.is_some());
            assert!(p.is_none_or(|p| (0.999..=1.0).contains(&p)), "{p:?}");
        }
    }
}

#[test]
fn a_fix_takes_in_the_near_landmarks_a_tight_gate_left_out() {
    // Seed 42, frame 248: the search stops after its confirmation triple with one
    // hypothesis, whose tight refinement passes converged on 12 of the 14 true detections,
    // 5.4 cm off: the detections of two near landmarks were beyond the inlier gate. The
    // wider last pass of the refinement takes them in.
    let (db, trial) = monte_carlo_prior_frame(42, 248);
    let detections = central_detections(&trial.frame.detections);
    let result = match_detections(&db, &detections, &trial.area, &up4_options()).unwrap();
    assert_eq!(result.status, MatchStatus::Ok, "{result:?}");
    let true_detections = trial.frame.truth.iter().flatten().count();
    assert_eq!(result.best_score, true_detections, "{result:?}");
    let estimate = result.estimate.as_ref().unwrap();
    let error = (estimate.world_from_rig.translation.vector - trial.pose.translation.vector).norm();
    assert!(error < 0.03, "{error} m");
}

#[test]
fn every_gate_inlier_is_linked_when_no_link_probability_is_asked() {
    // Frame 1168 of seed 42 (see above): with `min_link_probability` 0 the matcher links
    // every detection within the inlier gate, including the false detection 3.8σ from a
    // landmark the sure links leave out.
    let (db, trial) = monte_carlo_prior_frame(42, 1168);
    let detections = central_detections(&trial.frame.detections);
    let wrong_links = |options: &MatchOptions| {
        let result = match_detections(&db, &detections, &trial.area, options).unwrap();
        assert_eq!(result.status, MatchStatus::Ok, "{result:?}");
        let links = result.assignment.iter().flatten().count();
        let wrong = result
            .assignment
            .iter()
            .zip(&trial.frame.truth)
            .filter(|(a, t)| a.is_some() && a != t)
            .count();
        (links, wrong)
    };
    let (all_links, all_wrong) = wrong_links(&MatchOptions {
        min_link_probability: 0.0,
        ..up4_options()
    });
    let (sure_links, sure_wrong) = wrong_links(&up4_options());
    assert_eq!((all_wrong, sure_wrong), (1, 0));
    assert!(
        sure_links < all_links && sure_links >= 13,
        "{sure_links} {all_links}"
    );
    // Out of range.
    let bad = MatchOptions {
        min_link_probability: 1.5,
        ..up4_options()
    };
    assert!(match_detections(&db, &detections, &trial.area, &bad).is_err());
}

#[test]
fn a_cold_start_on_the_edge_street_of_a_regular_grid_is_ambiguous_not_wrong() {
    // Frame 42 of `UP_TOL_DEG=4 cargo run --release --example matcher_monte_carlo -- cold
    // 100 3` (the sparse city: 1,060 lamps on one kerb of a regular street grid): the rig is
    // on the city's western street, 5 m outside the landmarks' horizontal extent. The cold
    // trials used that extent as the search area, so the truth could not be generated and a
    // look-alike 608 m away (the grid repeats every 100 m), explaining all 10 true
    // detections, was reported as a fix. The trials now search `rig_region` (the streets),
    // which holds the truth; the frame is then `ambiguous` between two poses that explain
    // every true detection, which is the right answer.
    let (db, trial) = monte_carlo_cold_frame(3, 42);
    let truth = trial.pose.translation.vector;
    let landmarks_only = SearchArea::over_landmarks(&db, 0.0, 1.0, 3.0).unwrap();
    assert!(truth.x < landmarks_only.min_in_world.x, "{truth:?}");
    let region = &trial.area;
    assert!(
        (0..3).all(|k| region.min_in_world[k] <= truth[k] && truth[k] <= region.max_in_world[k])
    );
    let detections: Vec<Detection> = central_detections(&trial.frame.detections);
    let result = match_detections(&db, &detections, region, &up4_options()).unwrap();
    assert_eq!(result.status, MatchStatus::Ambiguous, "{result:?}");
    assert!(result.estimate.is_none());
    let true_detections = trial.frame.truth.iter().flatten().count();
    assert_eq!(result.best_score, true_detections);
    assert_eq!(result.runner_up_score, Some(true_detections));
}

#[test]
fn a_cold_start_with_six_inliers_among_many_poses_is_refused_as_chance() {
    // Frame 8 of `UP_TOL_DEG=4 cargo run --release --example matcher_monte_carlo -- cold
    // 200 5`: 6 true detections of 12, and a look-alike 316 m away explains as many. Its
    // residuals fit far worse (likelihood ratio about 10¹⁰), and until issue #25 the frame
    // was a right fix. But 6 inliers among ~3·10⁵ poses tried is what a wrong pose gathers
    // by chance (the look-alike is one): the acceptance test (docs/matcher-acceptance.md)
    // now refuses it as `no_match`, with its number of false alarms. With the test disabled
    // the residuals still decide it right.
    let (db, trial) = monte_carlo_cold_frame(5, 8);
    let detections: Vec<Detection> = central_detections(&trial.frame.detections);
    let result = match_detections(&db, &detections, &trial.area, &up4_options()).unwrap();
    assert_eq!(result.status, MatchStatus::NoMatch, "{result:?}");
    assert!(result.message.contains("by chance"), "{}", result.message);
    assert!(result.estimate.is_none());
    assert!(
        result.log10_false_alarms.is_some_and(|x| x > -3.0),
        "{result:?}"
    );
    assert!(result.pose_tests > 10_000, "{result:?}");
    let without_test = MatchOptions {
        max_false_alarms: f64::INFINITY,
        ..up4_options()
    };
    let result = match_detections(&db, &detections, &trial.area, &without_test).unwrap();
    assert_eq!(result.status, MatchStatus::Ok, "{result:?}");
    let true_detections = trial.frame.truth.iter().flatten().count();
    assert_eq!(result.runner_up_score, Some(true_detections), "{result:?}");
    let estimate = result.estimate.as_ref().unwrap();
    let error = (estimate.world_from_rig.translation.vector - trial.pose.translation.vector).norm();
    assert!(error < 0.1, "{error} m");
    for (a, t) in result.assignment.iter().zip(&trial.frame.truth) {
        assert!(a.is_none() || a == t);
    }
}

#[test]
fn a_detection_in_the_direction_of_two_landmarks_is_not_linked() {
    // Ten landmarks around the rig and a detection of each but the last two; then one more
    // detection pointing at landmark 8, with landmark 9 placed 10 m farther along the same
    // ray (0.5σ off it): the detection is equally well explained by either, so the link's
    // probability is about one half and no link is reported. Without landmark 9 the same
    // detection is linked, with a probability near 1.
    let pose = Pose::new(Vector3::new(3.0, -2.0, 2.0), Vector3::new(0.0, 0.0, 0.7));
    let options = MatchOptions {
        sigma_rad: 0.05_f64.to_radians(),
        up_in_rig: Some((Vector3::z(), 2.0_f64.to_radians())),
        ..MatchOptions::default()
    };
    let mut points: Vec<Vector3<f64>> = (0..9)
        .map(|k| {
            let a = 0.7 * k as f64;
            let range = 15.0 + 4.0 * k as f64;
            Vector3::new(range * a.cos(), range * a.sin(), 4.0 + (k % 3) as f64 * 3.0)
        })
        .collect();
    let origin = pose.translation.vector;
    let along = (points[8] - origin).normalize();
    let side = along.cross(&Vector3::z()).normalize();
    let range9 = (points[8] - origin).norm() + 10.0;
    let behind = origin + along * range9 + side * (0.5 * options.sigma_rad * range9);
    let area = SearchArea::around(&origin, 3.0, 1.0).unwrap();
    let mut detections = detections_of(&pose, &points[..8]);
    detections.extend(detections_of(&pose, &points[8..9]));
    let alone = match_detections(&db_of(&points), &detections, &area, &options).unwrap();
    points.push(behind);
    let twins = match_detections(&db_of(&points), &detections, &area, &options).unwrap();
    for result in [&alone, &twins] {
        assert_eq!(result.status, MatchStatus::Ok, "{result:?}");
        for k in 0..8 {
            assert_eq!(result.assignment[k], Some(k), "{result:?}");
            assert!(result.link_probability[k].is_some_and(|p| p > 0.999));
        }
    }
    assert_eq!(alone.assignment[8], Some(8));
    assert!(alone.link_probability[8].is_some_and(|p| p > 0.999));
    assert_eq!(twins.assignment[8], None, "{twins:?}");
    assert_eq!(twins.link_probability[8], None);
    assert_eq!(twins.best_score, 9);
    // Asked for every gate inlier, the matcher links it and says how doubtful it is.
    let every = MatchOptions {
        min_link_probability: 0.0,
        ..options
    };
    let doubtful = match_detections(&db_of(&points), &detections, &area, &every).unwrap();
    assert_eq!(doubtful.assignment[8], Some(8));
    let p = doubtful.link_probability[8].unwrap();
    assert!((0.3..0.7).contains(&p), "{p}");
}
