//! GPS time-offset calibration: the offset between the GPS track and the camera clock that
//! best explains the rays.

use super::refine::{MapRay, refine_landmark};
use super::survey::{survey_inflated, validate_gps};
use super::{CameraFrame, GpsSample, MappingError, SurveyOptions, gps_pose_at};

/// Default search interval half-width (seconds): GPS receivers report with latencies of
/// tens to a few hundred milliseconds.
pub const MAX_GPS_OFFSET_S: f64 = 0.5;
/// Default number of grid points of the coarse scan before the golden-section search.
pub const OFFSET_GRID_POINTS: usize = 21;
/// Default tolerance of the golden-section search (seconds).
pub const OFFSET_TOLERANCE_S: f64 = 1e-3;
/// Step of the finite-difference curvature that gives the offset's standard deviation
/// (seconds).
const CURVATURE_STEP_S: f64 = 0.01;

/// The interval and resolution of the offset search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetSearch {
    /// Smallest offset tried (seconds).
    pub min_s: f64,
    /// Largest offset tried (seconds).
    pub max_s: f64,
    /// Points of the coarse scan (≥ 3) ([`OFFSET_GRID_POINTS`]).
    pub grid_points: usize,
    /// Golden-section tolerance (seconds, [`OFFSET_TOLERANCE_S`]).
    pub tolerance_s: f64,
}

impl Default for OffsetSearch {
    fn default() -> Self {
        Self {
            min_s: -MAX_GPS_OFFSET_S,
            max_s: MAX_GPS_OFFSET_S,
            grid_points: OFFSET_GRID_POINTS,
            tolerance_s: OFFSET_TOLERANCE_S,
        }
    }
}

/// The result of [`calibrate_gps_offset`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetCalibration {
    /// The offset to put in [`SurveyOptions::gps_time_offset_s`] (seconds).
    pub offset_s: f64,
    /// Its standard deviation from the curvature of the χ² (`√(2 / χ²'')`, seconds), when the
    /// curvature is positive.
    pub sigma_s: Option<f64>,
    /// Total χ² of the rays at offset 0.
    pub chi2_at_zero: f64,
    /// Total χ² of the rays at `offset_s`.
    pub chi2_at_offset: f64,
    /// Degrees of freedom of the χ² (`Σ (2 nᵢ − 3)` over the landmarks used).
    pub dof: usize,
    /// Number of landmarks used.
    pub n_landmarks: usize,
}

/// Estimates the time offset between the GPS track and the camera: the offset `τ` (pose of
/// a frame at `t` read from the track at `t + τ`) minimising the total χ² of the landmark
/// rays, `Σ_landmarks Σ_rays rᵢᵀ Sᵢ⁺ rᵢ` with `rᵢ` the residual of ray `i` at its landmark's
/// refined estimate and `Sᵢ` its covariance ([`super::ray_residual_covariance`]).
///
/// 1. A coarse scan of `grid_points` offsets, each with its own association
///    ([`super::survey`] at that offset), scored by `χ² + 3 ln(N_rays)` per landmark (the
///    Bayesian information criterion of 3 parameters per landmark): at a wrong offset the
///    mapper splits a landmark seen around a turn into two self-consistent tracks, which the
///    χ² alone would reward.
/// 2. With the association of the best grid offset fixed, `χ²(τ)` is smooth: a
///    golden-section search in the two cells around it.
/// 3. `σ_τ = √(2 / χ²''(τ))` (a χ² is −2 log-likelihood).
///
/// # Observability
/// A constant lag moves every pose along the track by `v·τ`. On a straight road at constant
/// speed that is a rigid translation of all rays of a landmark: they still meet, at a
/// landmark shifted by `v·τ` — the paper's "about a metre behind" — and `χ²` does not see
/// it. The offset shows when the velocity changes while a landmark is observed: turns,
/// speed changes, or the same landmark seen again in the opposite direction. A straight
/// constant-speed drive gives a flat `χ²` and no `sigma_s`.
///
/// # Errors
/// [`MappingError::GpsTrack`], [`MappingError::InvalidOption`] (bad interval or options),
/// [`MappingError::InvalidObservation`], [`MappingError::NotObservable`] when no landmark
/// has enough rays.
pub fn calibrate_gps_offset(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
    search: &OffsetSearch,
) -> Result<OffsetCalibration, MappingError> {
    validate_gps(gps)?;
    if !(search.min_s.is_finite() && search.max_s.is_finite() && search.min_s < search.max_s) {
        return Err(MappingError::InvalidOption("offset interval"));
    }
    if search.grid_points < 3 || search.tolerance_s.is_nan() || search.tolerance_s <= 0.0 {
        return Err(MappingError::InvalidOption(
            "offset grid_points or tolerance_s",
        ));
    }
    // Coarse scan, re-associating at every offset: score = χ² + BIC penalty per landmark.
    let n = search.grid_points;
    let step = (search.max_s - search.min_s) / (n - 1) as f64;
    let mut best: Option<(f64, f64, Groups)> = None;
    for i in 0..n {
        let tau = search.min_s + step * i as f64;
        let groups = associate(gps, frames, options, tau)?;
        let (chi2, _, used) = total_chi2(gps, frames, &groups, options, tau);
        let n_rays: usize = groups.iter().map(Vec::len).sum();
        let score = chi2 + 3.0 * (n_rays.max(1) as f64).ln() * used as f64;
        if best.as_ref().is_none_or(|b| score < b.1) {
            best = Some((tau, score, groups));
        }
    }
    let Some((tau0, _, groups)) = best else {
        return Err(MappingError::NotObservable("empty offset grid"));
    };
    if groups.is_empty() {
        return Err(MappingError::NotObservable("no landmark with enough rays"));
    }
    // Fine search with the association of the best grid offset fixed.
    let chi2 = |tau: f64| total_chi2(gps, frames, &groups, options, tau);
    let lo = (tau0 - step).max(search.min_s);
    let hi = (tau0 + step).min(search.max_s);
    let offset_s = golden_section(|t| chi2(t).0, lo, hi, search.tolerance_s);
    let (chi2_at_offset, dof, n_landmarks) = chi2(offset_s);
    let h = CURVATURE_STEP_S;
    let curvature = (chi2(offset_s + h).0 - 2.0 * chi2_at_offset + chi2(offset_s - h).0) / (h * h);
    let sigma_s = (curvature > 0.0 && curvature.is_finite()).then(|| (2.0 / curvature).sqrt());
    let chi2_at_zero = total_chi2(
        gps,
        frames,
        &associate(gps, frames, options, 0.0)?,
        options,
        0.0,
    )
    .0;
    Ok(OffsetCalibration {
        offset_s,
        sigma_s,
        chi2_at_zero,
        chi2_at_offset,
        dof,
        n_landmarks,
    })
}

/// The sources `(frame, observation)` of each landmark's rays.
type Groups = Vec<Vec<(usize, usize)>>;

/// The landmark rays (sources) of a survey at offset `tau` (landmarks with enough rays).
fn associate(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    options: &SurveyOptions,
    tau: f64,
) -> Result<Vec<Vec<(usize, usize)>>, MappingError> {
    let mut o = *options;
    o.gps_time_offset_s = tau;
    let s = survey_inflated(gps, frames, &o, 0.0)?;
    Ok(s.sources
        .into_iter()
        .map(|(_, v)| v)
        .filter(|v| v.len() >= options.mapper.min_landmark_rays)
        .collect())
}

/// Minimum of a unimodal function on `[lo, hi]` by golden-section search.
fn golden_section(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64, tol: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = hi - g * (hi - lo);
    let mut d = lo + g * (hi - lo);
    let (mut fc, mut fd) = (f(c), f(d));
    while hi - lo > tol {
        if fc < fd {
            hi = d;
            d = c;
            fd = fc;
            c = hi - g * (hi - lo);
            fc = f(c);
        } else {
            lo = c;
            c = d;
            fc = fd;
            d = lo + g * (hi - lo);
            fd = f(d);
        }
    }
    0.5 * (lo + hi)
}

/// `(χ², dof, landmarks used)` of the fixed association at offset `tau`.
fn total_chi2(
    gps: &[GpsSample],
    frames: &[CameraFrame],
    groups: &[Vec<(usize, usize)>],
    options: &SurveyOptions,
    tau: f64,
) -> (f64, usize, usize) {
    let mut total = 0.0;
    let mut dof = 0;
    let mut used = 0;
    let mut rays = Vec::new();
    for g in groups {
        rays.clear();
        for &(fi, k) in g {
            let f = &frames[fi];
            if let Some((pose, cov)) = gps_pose_at(gps, f.time_s + tau, options.sigma_level_rad) {
                let o = &f.observations[k];
                rays.push(MapRay::from_rig(&pose, &cov, &o.ray_in_rig, o.sigma_rad));
            }
        }
        if rays.len() < options.mapper.min_landmark_rays {
            continue;
        }
        let Ok(est) = refine_landmark(&rays) else {
            continue;
        };
        let mut chi = 0.0;
        for r in &rays {
            chi += super::refine::ray_chi2(r, &est.point).unwrap_or(0.0);
        }
        if chi.is_finite() {
            total += chi;
            dof += 2 * rays.len() - 3;
            used += 1;
        }
    }
    (total, dof, used)
}
