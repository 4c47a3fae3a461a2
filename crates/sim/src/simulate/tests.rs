use super::*;
use std::collections::BTreeSet;

fn short(seed: u64) -> SimulatedDrive {
    simulate(&Scenario::preset(Preset::Short, seed)).unwrap()
}

#[test]
fn bundled_calibration_is_the_repository_file() {
    let rig = default_rig().unwrap();
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../calibration/ladybug2.json"
    );
    assert_eq!(
        rig,
        vgps_camera::calibration::load(path.as_ref(), None, None).unwrap()
    );
    assert_eq!(rig.len(), 6);
}

#[test]
fn same_seed_same_bytes_other_seed_other_drive() {
    let mut sc = Scenario::preset(Preset::Short, 5);
    sc.length_m = 300.0;
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    simulate(&sc).unwrap().write(a.path()).unwrap();
    simulate(&sc).unwrap().write(b.path()).unwrap();
    let mut names: Vec<_> = std::fs::read_dir(a.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names.len(), 10);
    for n in &names {
        let (x, y) = (
            std::fs::read(a.path().join(n)).unwrap(),
            std::fs::read(b.path().join(n)).unwrap(),
        );
        assert!(x == y, "{n:?} differs");
    }
    sc.seed = 6;
    let c = tempfile::tempdir().unwrap();
    simulate(&sc).unwrap().write(c.path()).unwrap();
    let d = |p: &Path| std::fs::read(p.join("detections.csv")).unwrap();
    assert_ne!(d(a.path()), d(c.path()));
}

#[test]
fn vehicle_motion_is_plausible() {
    let drive = short(1);
    let sc = &drive.scenario;
    let n = drive.frames.len();
    assert!((300..700).contains(&n), "{n} frames");
    let dt = 1.0 / sc.frame_rate_hz;
    for w in drive.frames.windows(2) {
        let d = (w[1].world_from_rig.translation.vector - w[0].world_from_rig.translation.vector)
            .xy()
            .norm();
        let v = d / dt;
        assert!((4.9..15.01).contains(&v), "speed {v}");
    }
    let enu = LocalFrame::new(sc.origin);
    for f in &drive.frames {
        let p = f.world_from_rig.translation.vector;
        assert!((p.z - sc.rig_height_m).abs() < 0.02);
        let t = truth_of(&enu, &f.world_from_rig).unwrap();
        let (roll, pitch, _) = t.enu_from_rig.euler_angles();
        assert!(roll.abs().to_degrees() <= 0.76 && pitch.abs().to_degrees() <= 0.76);
    }
    let speeds_high = drive
        .frames
        .windows(2)
        .filter(|w| (w[1].arc_m - w[0].arc_m) / dt > 10.0)
        .count();
    assert!(
        speeds_high > n / 4,
        "the vehicle should cruise above 10 m/s on straights"
    );
}

/// Maximal runs of GNSS epochs without a fix, as (first time, last time).
fn no_fix_runs(gnss: &[GnssRecord]) -> Vec<(f64, f64)> {
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut open = false;
    for r in gnss {
        match (r.fix.is_none(), open) {
            (true, false) => {
                runs.push((r.time_s, r.time_s));
                open = true;
            }
            (true, true) => {
                if let Some(last) = runs.last_mut() {
                    last.1 = r.time_s;
                }
            }
            (false, _) => open = false,
        }
    }
    runs
}

#[test]
fn outages_cover_15_percent_and_one_long_one_has_no_surveyed_landmarks() {
    for seed in [1, 2] {
        let drive = short(seed);
        let arc_at = |t: f64| {
            let k = drive
                .frames
                .partition_point(|f| f.time_s < t)
                .min(drive.frames.len() - 1);
            drive.frames[k].arc_m
        };
        let runs = no_fix_runs(&drive.gnss);
        let lengths: Vec<f64> = runs.iter().map(|&(a, b)| arc_at(b) - arc_at(a)).collect();
        let total: f64 = lengths.iter().sum();
        assert!(total >= 0.15 * drive.route.length_m, "{lengths:?}");
        let mut found = false;
        for (&(a, b), len) in runs.iter().zip(&lengths) {
            if *len < 300.0 {
                continue;
            }
            let inside: Vec<&SimFrame> = drive
                .frames
                .iter()
                .filter(|f| f.time_s >= a && f.time_s <= b)
                .collect();
            let max_surveyed = inside
                .iter()
                .map(|f| {
                    f.visible
                        .iter()
                        .filter_map(|v| match v.source {
                            Source::Landmark(i) if drive.world.landmarks[i].surveyed => Some(i),
                            _ => None,
                        })
                        .collect::<BTreeSet<_>>()
                        .len()
                })
                .max()
                .unwrap_or(0);
            let min_unsurveyed = inside
                .iter()
                .map(|f| {
                    f.visible
                        .iter()
                        .filter_map(|v| match v.source {
                            Source::Landmark(i) if !drive.world.landmarks[i].surveyed => Some(i),
                            _ => None,
                        })
                        .collect::<BTreeSet<_>>()
                        .len()
                })
                .min()
                .unwrap_or(0);
            if max_surveyed < 3 && min_unsurveyed >= 3 {
                found = true;
            }
        }
        assert!(
            found,
            "seed {seed}: no ≥ 300 m outage without surveyed landmarks: {lengths:?}"
        );
    }
}

#[test]
fn detections_have_the_stated_noise_misses_and_false_share() {
    let drive = short(3);
    let sc = &drive.scenario;
    let (true_det, false_det, sightings) = drive.detection_counts();
    let false_share = false_det as f64 / (true_det + false_det) as f64;
    assert!(
        (false_share - sc.false_fraction).abs() < 0.02,
        "{false_share}"
    );
    let detected = true_det as f64 / sightings as f64;
    assert!((detected - (1.0 - sc.miss_rate)).abs() < 0.02, "{detected}");
    let mut sum2 = 0.0;
    let mut count = 0.0;
    for f in &drive.frames {
        for d in &f.detections {
            let r = Vector2::new(d.detection.u, d.detection.v) - d.true_pixel;
            assert!(r.norm() < 6.0 * sc.pixel_sigma_px);
            sum2 += r.norm_squared();
            count += 2.0;
            // The true pixel is the landmark's projection from the true pose.
            if let Source::Landmark(i) = d.source {
                let p = drive.world.landmarks[i].position_in_enu;
                let seen = project(&sc.rig, &f.world_from_rig, &p, d.source);
                assert!(
                    seen.iter().any(|v| v.camera == d.detection.camera
                        && (v.pixel - d.true_pixel).norm() < 1e-9)
                );
            }
        }
    }
    let rms = (sum2 / count).sqrt();
    assert!(
        (rms - sc.pixel_sigma_px).abs() < 0.02 * sc.pixel_sigma_px + 0.005,
        "rms {rms}"
    );
}

#[test]
fn gnss_noise_has_the_stated_cep() {
    let mut rng = vgps_geometry::synthetic::rng(17);
    let mut noise = GnssNoise::new(&mut rng, 2.0, 0.78, 60.0, 1.5);
    // 100 000 epochs at 5 Hz: 20 000 s, about 330 bias correlation times.
    let mut errors: Vec<f64> = (0..100_000)
        .map(|_| noise.step(&mut rng, 0.2).xy().norm())
        .collect();
    errors.sort_by(f64::total_cmp);
    let cep = errors[errors.len() / 2];
    assert!((cep - 2.0).abs() < 0.12, "CEP {cep}");
}

#[test]
fn fixes_lag_the_truth_by_the_latency() {
    let mut sc = Scenario::preset(Preset::Short, 4);
    sc.length_m = 500.0;
    sc.gnss_cep_m = 0.0;
    let drive = simulate(&sc).unwrap();
    let enu = LocalFrame::new(sc.origin);
    let motion_pose = |t: f64| {
        // Frames are at 5 Hz like the GNSS epochs and start together: epoch k is frame k.
        let k = ((t - sc.start_unix_s) * sc.frame_rate_hz).round() as usize;
        drive.frames[k].world_from_rig.translation.vector
    };
    let mut checked = 0;
    for w in drive.gnss.windows(2) {
        let (Some(fix), Some(_)) = (w[1].fix, w[0].fix) else {
            continue;
        };
        let reported = enu.to_enu(&fix.position);
        let now = motion_pose(w[1].time_s);
        let before = motion_pose(w[0].time_s);
        let speed = (now - before).xy().norm() / 0.2;
        let behind = (now - reported).xy().norm();
        // The fix is where the rig was lag_s earlier (NMEA rounding: millimetres).
        assert!(
            (behind - speed * sc.gnss_lag_s).abs() < 0.05 * speed * sc.gnss_lag_s + 0.01,
            "{behind} vs {speed}"
        );
        checked += 1;
    }
    assert!(checked > 100);
}

#[test]
fn no_survey_gap_and_a_full_survey_leave_no_landmark_unsurveyed() {
    let mut sc = Scenario::preset(Preset::Short, 1);
    sc.length_m = 300.0;
    sc.surveyed_fraction = 1.0;
    sc.survey_gap_m = 0.0;
    let drive = simulate(&sc).unwrap();
    assert!(!drive.world.landmarks.is_empty());
    assert!(drive.world.landmarks.iter().all(|l| l.surveyed));
    assert!(drive.outages.iter().all(|o| o.kind != "survey_gap"));
    // With the gap, the landmarks near it are unsurveyed even with a full survey.
    sc.survey_gap_m = 60.0;
    let drive = simulate(&sc).unwrap();
    assert!(drive.world.landmarks.iter().any(|l| !l.surveyed));
    assert!(drive.outages.iter().any(|o| o.kind == "survey_gap"));
}

#[test]
fn a_short_route_starts_with_surveyed_lamps_in_view() {
    // The README's 150 m drive: before the lead-in, the survey gap's unsurveyed zone (the
    // gap plus the detection range around it) covered the whole route, so at night (lamps
    // only) no frame after the first few had a surveyed lamp in view.
    for seed in [1, 2, 3] {
        let mut sc = Scenario::preset(Preset::Short, seed);
        sc.length_m = 150.0;
        let drive = simulate(&sc).unwrap();
        let gap = drive.outages.iter().find(|o| o.kind == "survey_gap");
        assert!(gap.is_none_or(|o| o.start_m >= SURVEYED_LEAD_IN_M - 1e-9));
        let lead_in: Vec<&SimFrame> = drive
            .frames
            .iter()
            .filter(|f| f.arc_m <= SURVEYED_LEAD_IN_M)
            .collect();
        let with_three = lead_in
            .iter()
            .filter(|f| {
                f.visible
                    .iter()
                    .filter_map(|v| match v.source {
                        Source::Landmark(i)
                            if drive.world.landmarks[i].surveyed
                                && drive.world.landmarks[i].class == LandmarkClass::Streetlight =>
                        {
                            Some(i)
                        }
                        _ => None,
                    })
                    .collect::<BTreeSet<_>>()
                    .len()
                    >= 3
            })
            .count();
        assert!(
            with_three * 10 >= lead_in.len() * 9,
            "seed {seed}: {with_three} of {} lead-in frames see 3 surveyed lamps",
            lead_in.len()
        );
    }
}
