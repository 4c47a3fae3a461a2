//! Why night frames lose the fix (issues #24 item 6, #25): the `short` preset replayed in
//! memory from the simulator's detections with the building corners removed (lamps only, an
//! upper bound of what pixels can give), one line per frame with the localizer's status and
//! message, the surveyed and unsurveyed lamps in view (truth), the surrogates in use, the
//! mapped tracks near the rig and why those that are not surrogates fail the criteria, and
//! the error against the truth. Ends with the counts per status and message.
//!
//! Run: `cargo run --release --example night_lamps [-- --preset short|reference --seed 1
//! --all --quiet]` (`--all` keeps the corners).
use std::collections::BTreeMap;
use std::sync::Arc;
use vgps::localizer::{Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions};
use vgps::mapping::SurrogateCriteria;
use vgps::simulate::{Preset, Scenario, Source, simulate};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|k| args.get(k + 1))
            .cloned()
    };
    let preset = match value("--preset").as_deref() {
        Some("reference") => Preset::Reference,
        _ => Preset::Short,
    };
    let seed = value("--seed").and_then(|s| s.parse().ok()).unwrap_or(1);
    let all = args.iter().any(|a| a == "--all");
    let quiet = args.iter().any(|a| a == "--quiet");
    let drive = match simulate(&Scenario::preset(preset, seed)) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("simulate: {e}");
            return;
        }
    };
    let Ok(landmarks) = drive.surveyed_landmarks() else {
        eprintln!("no surveyed landmarks");
        return;
    };
    let Ok(map) = LandmarkMap::from_landmarks(&landmarks, None).map(Arc::new) else {
        eprintln!("bad map");
        return;
    };
    let scenario = vgps::geo::LocalFrame::new(drive.scenario.origin);
    let rig = Arc::new(drive.scenario.rig.clone());
    let Ok(mut localizer) = Localizer::new(rig, Arc::clone(&map), LocalizerOptions::default())
    else {
        eprintln!("bad localizer");
        return;
    };
    let criteria = SurrogateCriteria::default();
    let range = drive.scenario.range_m;
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let (mut ok, mut errors, mut far, mut inside) = (0usize, Vec::new(), 0usize, 0usize);
    for f in &drive.frames {
        let detections: Vec<_> = f
            .detections
            .iter()
            .filter(|d| all || d.detection.class.as_deref() != Some("corner"))
            .map(|d| d.detection.clone())
            .collect();
        let gnss = vgps::drive::gnss::gnss_at(&drive.gnss, f.time_s)
            .map(|position| GnssPosition { position });
        let fix = localizer.process(&Frame::from_detections(f.time_s, &detections, &map, gnss));
        // Truth: lamps detected in this frame, surveyed or not.
        let (mut surveyed, mut unsurveyed) = (
            std::collections::BTreeSet::new(),
            std::collections::BTreeSet::new(),
        );
        for d in &f.detections {
            if let Source::Landmark(k) = d.source {
                let l = &drive.world.landmarks[k];
                if !all && d.detection.class.as_deref() == Some("corner") {
                    continue;
                }
                if l.surveyed {
                    surveyed.insert(k);
                } else {
                    unsurveyed.insert(k);
                }
            }
        }
        // The rig in the localizer's world frame (ENU at the map's origin, not the
        // scenario's).
        let Ok(truth) = scenario.try_to_geodetic(&f.world_from_rig.translation.vector) else {
            continue;
        };
        let here = map.frame().to_enu(&truth);
        let mapped = localizer.mapped_landmarks();
        let near: Vec<_> = mapped
            .iter()
            .filter(|m| (m.position_enu - here).norm() <= range)
            .collect();
        let (mut few_rays, mut low_parallax, mut wide) = (0, 0, 0);
        for m in &near {
            if criteria.accepts(m) {
                continue;
            }
            if m.n_obs < criteria.min_rays {
                few_rays += 1;
            } else if m.max_parallax_rad < criteria.min_parallax_rad {
                low_parallax += 1;
            } else {
                wide += 1;
            }
        }
        let n_surrogates = localizer
            .surrogates()
            .iter()
            .filter(|s| (s.landmark.position_enu - here).norm() <= range)
            .count();
        let mut err = f64::NAN;
        let mut in_ellipse = false;
        if let Some(e) = &fix.estimate {
            let d = (e.world_from_rig.translation.vector - here).xy();
            err = d.norm();
            let c = e.covariance.fixed_view::<2, 2>(0, 0).into_owned();
            in_ellipse = c.try_inverse().is_some_and(|ci| d.dot(&(ci * d)) <= 5.991);
        }
        let used = fix
            .estimate
            .as_ref()
            .map_or((0, 0), |e| (e.landmarks.len(), e.surrogates.len()));
        if !quiet {
            println!(
                "{:4} {:10} {:11} lamps s{:2} u{:2} | surrogates {:2} mapped {:2} (rays<{} {:2}, parallax {:2}, σ {:2}) | used s{:2} r{:2} | err {:7.3} {} | {}",
                f.frame,
                fix.status.as_str(),
                fix.source.map_or("-", |s| s.as_str()),
                surveyed.len(),
                unsurveyed.len(),
                n_surrogates,
                near.len(),
                criteria.min_rays,
                few_rays,
                low_parallax,
                wide,
                used.0,
                used.1,
                err,
                if in_ellipse { "in " } else { "out" },
                fix.message
            );
        }
        let key = if fix.status.as_str() == "ok" {
            "ok".to_string()
        } else {
            // The message without its numbers, so that frames group by reason.
            let m: String = fix
                .message
                .chars()
                .map(|c| if c.is_ascii_digit() { '#' } else { c })
                .collect();
            format!("{}: {}", fix.status.as_str(), m)
        };
        *counts.entry(key).or_default() += 1;
        if fix.status.as_str() == "ok" {
            ok += 1;
            errors.push(err);
            if err > 5.0 {
                far += 1;
            }
            if in_ellipse {
                inside += 1;
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let q = |p: f64| {
        errors
            .get(((errors.len() as f64 * p).ceil() as usize).saturating_sub(1))
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "fixed {ok}/{} CEP50 {:.3} m CEP95 {:.3} m max {:.3} m, ok > 5 m: {far}, inside 95 % ellipse {inside}/{ok}",
        drive.frames.len(),
        q(0.5),
        q(0.95),
        errors.last().copied().unwrap_or(f64::NAN)
    );
    for (k, n) in counts {
        println!("{n:5} {k}");
    }
}
