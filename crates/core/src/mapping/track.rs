//! The GNSS track of a survey: smoothing, coverage of a frame's time by the track, speed,
//! and the per-landmark checks survey mode applies before writing a landmark (frame
//! coverage, χ² of its rays).
//!
//! # Gaps
//! [`gps_pose_at`] interpolates linearly between any two samples; across an outage that
//! would invent poses. [`track_covers`] accepts a time only when the track covers
//! `[t − m, t + m]` with epochs at most [`MAX_GNSS_GAP_S`] apart.

use super::{
    CameraFrame, GpsSample, MapRay, SurveyOptions, gps_pose_at, ray_chi2, refine_landmark,
};
use nalgebra::{Matrix3, Vector3};

/// Largest gap between two GNSS epochs with a fix and a heading over which the pose is
/// interpolated (seconds); a longer gap is an outage.
pub const MAX_GNSS_GAP_S: f64 = 1.0;

/// Fewest fixes in a smoothing window for the quadratic fit (else the fix is kept raw).
pub const MIN_SMOOTH_FIXES: usize = 5;

/// The track with every position replaced by a local quadratic fit (least squares in
/// time, per axis) over the fixes within `half_window_s` in the same outage-free segment,
/// and its σ by `σ √h` (`h` = the fit's leverage at the centre). The white part of the
/// GNSS noise shrinks; the errors of nearby smoothed fixes become correlated, which the
/// mapper (independent pose errors) does not model. `half_window_s ≤ 0` returns the raw
/// track.
pub fn smooth_track(gps: &[GpsSample], half_window_s: f64) -> Vec<GpsSample> {
    if half_window_s <= 0.0 {
        return gps.to_vec();
    }
    let mut out = gps.to_vec();
    for (i, o) in out.iter_mut().enumerate() {
        let t0 = gps[i].time_s;
        let mut lo = i;
        while lo > 0
            && t0 - gps[lo - 1].time_s <= half_window_s
            && gps[lo].time_s - gps[lo - 1].time_s <= MAX_GNSS_GAP_S
        {
            lo -= 1;
        }
        let mut hi = i;
        while hi + 1 < gps.len()
            && gps[hi + 1].time_s - t0 <= half_window_s
            && gps[hi + 1].time_s - gps[hi].time_s <= MAX_GNSS_GAP_S
        {
            hi += 1;
        }
        if hi - lo + 1 < MIN_SMOOTH_FIXES {
            continue;
        }
        let mut ata = Matrix3::<f64>::zeros();
        let mut atb = Matrix3::<f64>::zeros();
        for g in &gps[lo..=hi] {
            let dt = g.time_s - t0;
            let row = Vector3::new(1.0, dt, dt * dt);
            ata += row * row.transpose();
            atb += row * g.position_enu.transpose();
        }
        let Some(inv) = ata.try_inverse() else {
            continue;
        };
        let coef = inv * atb;
        let position = coef.row(0).transpose();
        let leverage = inv[(0, 0)];
        if !(vgps_geometry::geometry::is_finite(&position) && leverage > 0.0 && leverage <= 1.0) {
            continue;
        }
        o.position_enu = position;
        o.sigma_horizontal_m *= leverage.sqrt();
        o.sigma_vertical_m *= leverage.sqrt();
    }
    out
}

/// True when the track covers `[t − margin, t + margin]` with epochs at most
/// [`MAX_GNSS_GAP_S`] apart.
pub fn track_covers(gps: &[GpsSample], t: f64, margin: f64) -> bool {
    let (lo, hi) = (t - margin, t + margin);
    // The last epoch at or before `lo`, then every epoch up to the first at or after `hi`.
    let first = gps.partition_point(|g| g.time_s <= lo);
    let Some(start) = first.checked_sub(1) else {
        return false;
    };
    let mut i = start;
    while gps[i].time_s < hi {
        let Some(next) = gps.get(i + 1) else {
            return false;
        };
        if next.time_s - gps[i].time_s > MAX_GNSS_GAP_S {
            return false;
        }
        i += 1;
    }
    true
}

/// Median horizontal speed between consecutive epochs at most [`MAX_GNSS_GAP_S`] apart
/// (m/s; 0 when there are none).
pub fn median_speed(gps: &[GpsSample]) -> f64 {
    let speeds = gps
        .windows(2)
        .filter(|w| w[1].time_s - w[0].time_s <= MAX_GNSS_GAP_S)
        .map(|w| (w[1].position_enu - w[0].position_enu).xy().norm() / (w[1].time_s - w[0].time_s))
        .collect();
    crate::stats::median(speeds).unwrap_or(0.0)
}

/// Fraction of the frames between a landmark's first and last observation in which it is
/// observed (`sources` = `(frame, observation)` pairs, as in [`super::Survey::sources`]; 0
/// when empty).
pub fn frame_coverage(sources: &[(usize, usize)]) -> f64 {
    let mut frames: Vec<usize> = sources.iter().map(|s| s.0).collect();
    frames.sort_unstable();
    frames.dedup();
    match (frames.first(), frames.last()) {
        (Some(a), Some(b)) => frames.len() as f64 / (b - a + 1) as f64,
        _ => 0.0,
    }
}

/// `(χ², dof)` of one landmark's rays at its refined estimate (residual perpendicular to
/// each ray over its covariance, [`super::ray_residual_covariance`]); `None` when a source
/// is missing, a pose cannot be interpolated, the refinement fails or the χ² is not finite.
pub fn landmark_chi2(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    sources: &[(usize, usize)],
    options: &SurveyOptions,
) -> Option<(f64, usize)> {
    let mut rays = Vec::with_capacity(sources.len());
    for &(fi, k) in sources {
        let f = frames.get(fi)?;
        let o = f.observations.get(k)?;
        let (pose, cov) = gps_pose_at(
            gps,
            f.time_s + options.gps_time_offset_s,
            options.sigma_level_rad,
        )?;
        rays.push(MapRay::from_rig(&pose, &cov, &o.ray_in_rig, o.sigma_rad));
    }
    let est = refine_landmark(&rays).ok()?;
    let mut chi2 = 0.0;
    for r in &rays {
        chi2 += ray_chi2(r, &est.point)?;
    }
    let dof = (2 * rays.len()).checked_sub(3)?;
    chi2.is_finite().then_some((chi2, dof))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64) -> GpsSample {
        GpsSample {
            time_s: t,
            position_enu: Vector3::new(10.0 * t, 0.0, 0.0),
            heading_rad: 0.0,
            sigma_horizontal_m: 1.0,
            sigma_vertical_m: 1.0,
            sigma_heading_rad: 0.01,
        }
    }

    #[test]
    fn coverage_excludes_outages_and_track_ends() {
        let mut gps: Vec<GpsSample> = (0..10).map(|k| sample(0.2 * k as f64)).collect();
        gps.extend((0..10).map(|k| sample(5.0 + 0.2 * k as f64)));
        assert!(track_covers(&gps, 1.0, 0.5));
        assert!(
            !track_covers(&gps, 0.3, 0.5),
            "before the start with the margin"
        );
        assert!(track_covers(&gps, 0.3, 0.0));
        assert!(
            !track_covers(&gps, 1.6, 0.5),
            "margin reaches into the outage"
        );
        assert!(!track_covers(&gps, 3.0, 0.0), "inside the outage");
        assert!(track_covers(&gps, 5.9, 0.5));
        assert!(!track_covers(&gps, 6.7, 0.5), "after the end");
        assert!((median_speed(&gps) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn frame_coverage_counts_distinct_frames_of_the_span() {
        assert_eq!(frame_coverage(&[]), 0.0);
        assert_eq!(frame_coverage(&[(2, 0), (2, 1), (5, 0)]), 0.5);
    }
}
