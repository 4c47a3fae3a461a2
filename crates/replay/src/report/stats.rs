//! The statistics of a replay: accuracy against truth and satellite, blackouts, statuses,
//! heading, covariance consistency and drift on surrogate-only stretches.

use super::derived::{Diff, FrameGeom, derive, runs};
use super::{CHI2_2DOF_95, DriveInfo, ELLIPSE_PROBABILITY, FrameOutcome, MIN_SURVEYED_LANDMARKS};
use serde::Serialize;
use std::collections::BTreeMap;
use vgps_geometry::geo::Geodetic;

/// Distance travelled (metres) below which a surrogate-only frame's error is not divided
/// by the distance (the ratio would be dominated by the anchor fix's own error).
pub const MIN_DRIFT_DISTANCE_M: f64 = 1.0;

/// The `p`-quantile of `values` by the nearest-rank order statistic: the `k`-th smallest
/// value with `k = ⌈p·n⌉` (clamped to `1 … n`). `None` for an empty list or `p` outside
/// [0, 1]; non-finite values are ignored.
///
/// With this convention CEP50 of `[1, 2, 3, 4]` is 2 and CEP95 is 4: the reported radius
/// always contains at least a fraction `p` of the samples.
///
/// # Example
/// ```
/// use vgps_replay::report::quantile_nearest_rank;
/// let d = [4.0, 1.0, 3.0, 2.0];
/// assert_eq!(quantile_nearest_rank(&d, 0.5), Some(2.0));
/// assert_eq!(quantile_nearest_rank(&d, 0.95), Some(4.0));
/// assert_eq!(quantile_nearest_rank(&d, 0.0), Some(1.0));
/// assert_eq!(quantile_nearest_rank(&[], 0.5), None);
/// ```
pub fn quantile_nearest_rank(values: &[f64], p: f64) -> Option<f64> {
    if !(0.0..=1.0).contains(&p) {
        return None;
    }
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let k = ((p * n as f64).ceil() as usize).clamp(1, n);
    Some(v[k - 1])
}

fn rms(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    (values.iter().map(|x| x * x).sum::<f64>() / values.len() as f64).sqrt()
}

/// Statistics of horizontal distances (metres).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HorizontalStats {
    /// Circular error probable: the nearest-rank 50 % quantile (metres).
    pub cep50: f64,
    /// The nearest-rank 95 % quantile (metres).
    pub cep95: f64,
    /// Root mean square (metres).
    pub rms: f64,
    /// Largest distance (metres).
    pub max: f64,
}

/// The differences between two position sources over the frames where both exist.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// Horizontal distance statistics (metres).
    pub horizontal_m: HorizontalStats,
    /// Root mean square of the up difference (metres).
    pub vertical_rms_m: f64,
    /// Number of frames compared.
    pub n: u64,
}

impl Comparison {
    /// The statistics of `diffs`; `None` when there are none.
    pub(crate) fn from_diffs(diffs: impl IntoIterator<Item = Diff>) -> Option<Self> {
        let (h, v): (Vec<f64>, Vec<f64>) = diffs.into_iter().map(|d| (d.h, d.v)).unzip();
        Some(Comparison {
            horizontal_m: HorizontalStats {
                cep50: quantile_nearest_rank(&h, 0.5)?,
                cep95: quantile_nearest_rank(&h, 0.95)?,
                rms: rms(&h),
                max: h.iter().copied().fold(0.0, f64::max),
            },
            vertical_rms_m: rms(&v),
            n: h.len() as u64,
        })
    }
}

/// The statistics restricted to satellite blackouts (frames without a satellite position).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlackoutSection {
    /// Number of blackout frames.
    pub frames: u64,
    /// The blackout stretches as `[first_frame, last_frame]` (frame numbers, inclusive).
    pub stretches: Vec<[u64; 2]>,
    /// Number of blackout frames with a visual fix.
    pub visual_fixes: u64,
    /// `visual_fixes / frames`; `null` without blackout frames.
    pub visual_fix_rate: Option<f64>,
    /// Visual against truth during blackouts; `null` when no frame has both.
    pub visual_vs_truth: Option<Comparison>,
    /// Always `null` in a blackout (kept for a uniform schema).
    pub gnss_vs_truth: Option<Comparison>,
    /// Always `null` in a blackout (kept for a uniform schema).
    pub visual_vs_gnss: Option<Comparison>,
}

/// How often the truth lies inside the 95 % horizontal error ellipse of the visual fix.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CovarianceConsistency {
    /// Visual fixes with truth and a positive-definite horizontal covariance.
    pub n: u64,
    /// Of those, how many have `eᵀ Σ⁻¹ e ≤ χ²₂(0.95)`.
    pub inside_95: u64,
    /// `inside_95 / n` (a consistent covariance gives ≈ `expected`).
    pub fraction_inside_95: f64,
    /// The ellipse probability, 0.95.
    pub expected: f64,
}

/// One stretch of consecutive surrogate-only fixes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriftStretch {
    /// First frame of the stretch.
    pub first_frame: u64,
    /// Last frame of the stretch.
    pub last_frame: u64,
    /// The last earlier frame whose fix had ≥ 3 surveyed landmarks; `null` if none.
    pub anchor_frame: Option<u64>,
    /// Distance travelled along the true track from the anchor to the last frame of the
    /// stretch with a measured ratio (metres); `null` if none.
    pub distance_m: Option<f64>,
    /// Horizontal error against truth at that frame (metres).
    pub error_h_m: Option<f64>,
    /// `error_h_m / distance_m` at that frame.
    pub error_per_distance: Option<f64>,
}

/// Drift of the fixes that rest on surrogate landmarks only.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurrogateDrift {
    /// Number of surrogate-only fixes.
    pub frames: u64,
    /// Number of those with a ratio (truth, an anchor, distance ≥ 1 m).
    pub n: u64,
    /// Median of the per-frame `error / distance` (nearest rank); `null` if `n = 0`.
    pub median_error_per_distance: Option<f64>,
    /// Largest per-frame `error / distance`; `null` if `n = 0`.
    pub max_error_per_distance: Option<f64>,
    /// The stretches of consecutive surrogate-only fixes.
    pub stretches: Vec<DriftStretch>,
}

/// The accounting of the frames whose detections came from the images.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageAccounting {
    /// Frames whose detections came from their images.
    pub frames: u64,
    /// Of those, frames with at least one unusable image (missing, corrupt, wrong size,
    /// detector failure), whatever their status.
    pub frames_with_unusable_images: u64,
    /// Of those, frames localized with the images that could be used (some usable).
    pub frames_partially_usable: u64,
    /// Unusable images over all frames.
    pub unusable_images: u64,
}

/// The statistics of a replay, serialized as `report.json` ([`Report::to_json`]).
///
/// Every field is documented key by key in `docs/replay-report.md`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The drive's name.
    pub drive: String,
    /// The origin of the ENU frame of every difference.
    pub origin: Geodetic,
    /// Number of frames.
    pub frames: u64,
    /// Time of the first frame (Unix seconds, UTC); `null` without frames.
    pub first_time_s: Option<f64>,
    /// Time of the last frame (Unix seconds, UTC); `null` without frames.
    pub last_time_s: Option<f64>,
    /// Number of frames with a visual fix.
    pub visual_fixes: u64,
    /// `visual_fixes / frames`; `null` without frames.
    pub visual_fix_rate: Option<f64>,
    /// Number of frames by status (sorted by status).
    pub status_counts: BTreeMap<String, u64>,
    /// Visual fix against truth; `null` when no frame has both.
    pub visual_vs_truth: Option<Comparison>,
    /// Visual fix against truth over the fixes that used at least
    /// [`crate::report::MIN_SURVEYED_LANDMARKS`] surveyed landmarks (the accuracy the
    /// localizer targets where the survey covers the street); `null` when none.
    pub visual_vs_truth_surveyed: Option<Comparison>,
    /// Satellite against truth; `null` when no frame has both.
    pub gnss_vs_truth: Option<Comparison>,
    /// Visual fix against satellite; `null` when no frame has both.
    pub visual_vs_gnss: Option<Comparison>,
    /// The same statistics during satellite blackouts.
    pub blackout: BlackoutSection,
    /// Median of `|visual heading − true heading|` (degrees, wrapped to [0, 180]);
    /// `null` without truth.
    pub heading_error_median_deg: Option<f64>,
    /// Covariance consistency against truth; `null` when not measurable.
    pub covariance_consistency: Option<CovarianceConsistency>,
    /// Drift on surrogate-only stretches; `null` when the drive has no surrogate-only fix.
    pub surrogate_drift: Option<SurrogateDrift>,
    /// Image accounting; `null` when no frame's detections came from its images.
    pub images: Option<ImageAccounting>,
}

fn rate(k: u64, n: u64) -> Option<f64> {
    (n > 0).then(|| k as f64 / n as f64)
}

/// `eᵀ Σ⁻¹ e` for a symmetric positive-definite 2×2 `Σ`; `None` otherwise.
pub(crate) fn mahalanobis2(
    e: &nalgebra::Vector2<f64>,
    cov: &nalgebra::Matrix2<f64>,
) -> Option<f64> {
    if !cov.iter().all(|x| x.is_finite()) {
        return None;
    }
    let chol = nalgebra::Cholesky::new(0.5 * (cov + cov.transpose()))?;
    let d2 = e.dot(&chol.solve(e));
    d2.is_finite().then_some(d2)
}

impl Report {
    /// The statistics of `records` (in drive order) of `drive`.
    ///
    /// Frames count whatever their status; a comparison uses the frames where both of its
    /// positions exist; a blackout frame is one without a satellite position. See
    /// `docs/replay-report.md` for every definition.
    pub fn compute(drive: &DriveInfo, records: &[FrameOutcome]) -> Report {
        let geom = derive(drive, records);
        let frames = records.len() as u64;
        let visual_fixes = records.iter().filter(|r| r.visual.is_some()).count() as u64;
        let mut status_counts = BTreeMap::new();
        for r in records {
            *status_counts.entry(r.status.clone()).or_insert(0) += 1;
        }
        let pick = |f: fn(&FrameGeom) -> Option<Diff>, blackout_only: bool| {
            Comparison::from_diffs(
                geom.iter()
                    .filter(|g| !blackout_only || g.blackout)
                    .filter_map(f),
            )
        };
        let blackout_frames = geom.iter().filter(|g| g.blackout).count() as u64;
        let blackout_fixes = records
            .iter()
            .zip(&geom)
            .filter(|(r, g)| g.blackout && r.visual.is_some())
            .count() as u64;
        let blackout = BlackoutSection {
            frames: blackout_frames,
            stretches: runs(geom.iter().map(|g| g.blackout))
                .into_iter()
                .map(|(a, b)| [records[a].frame, records[b].frame])
                .collect(),
            visual_fixes: blackout_fixes,
            visual_fix_rate: rate(blackout_fixes, blackout_frames),
            visual_vs_truth: pick(|g| g.visual_vs_truth, true),
            gnss_vs_truth: pick(|g| g.gnss_vs_truth, true),
            visual_vs_gnss: pick(|g| g.visual_vs_gnss, true),
        };
        let heading_abs: Vec<f64> = geom
            .iter()
            .filter_map(|g| g.heading_err_deg.map(f64::abs))
            .collect();
        Report {
            drive: drive.name.clone(),
            origin: drive.origin,
            frames,
            first_time_s: records.first().map(|r| r.time_s).filter(|t| t.is_finite()),
            last_time_s: records.last().map(|r| r.time_s).filter(|t| t.is_finite()),
            visual_fixes,
            visual_fix_rate: rate(visual_fixes, frames),
            status_counts,
            visual_vs_truth: pick(|g| g.visual_vs_truth, false),
            visual_vs_truth_surveyed: Comparison::from_diffs(
                records
                    .iter()
                    .zip(&geom)
                    .filter(|(r, _)| {
                        r.visual
                            .as_ref()
                            .is_some_and(|v| v.n_landmarks >= crate::report::MIN_SURVEYED_LANDMARKS)
                    })
                    .filter_map(|(_, g)| g.visual_vs_truth),
            ),
            gnss_vs_truth: pick(|g| g.gnss_vs_truth, false),
            visual_vs_gnss: pick(|g| g.visual_vs_gnss, false),
            blackout,
            heading_error_median_deg: quantile_nearest_rank(&heading_abs, 0.5),
            covariance_consistency: covariance_consistency(records, &geom),
            surrogate_drift: surrogate_drift(records, &geom),
            images: image_accounting(records),
        }
    }

    /// The report as pretty-printed JSON (`report.json`, `--format json`), ending in a
    /// newline. Keys keep the struct order; maps are sorted; no NaN (missing is `null`).
    pub fn to_json(&self) -> String {
        match serde_json::to_string_pretty(self) {
            Ok(mut s) => {
                s.push('\n');
                s
            }
            // Serializing plain structs with string keys cannot fail.
            Err(e) => format!("{{\"error\": \"{e}\"}}\n"),
        }
    }
}

/// A frame whose images were all unusable has this status (and is not "partially usable").
const BAD_IMAGE_STATUS: &str = "bad_image";

fn image_accounting(records: &[FrameOutcome]) -> Option<ImageAccounting> {
    let from_images: Vec<(u32, &str)> = records
        .iter()
        .filter_map(|r| r.unusable_images.map(|n| (n, r.status.as_str())))
        .collect();
    if from_images.is_empty() {
        return None;
    }
    let with = from_images.iter().filter(|(n, _)| *n > 0);
    Some(ImageAccounting {
        frames: from_images.len() as u64,
        frames_with_unusable_images: with.clone().count() as u64,
        frames_partially_usable: with.filter(|(_, s)| *s != BAD_IMAGE_STATUS).count() as u64,
        unusable_images: from_images.iter().map(|(n, _)| u64::from(*n)).sum(),
    })
}

fn covariance_consistency(
    records: &[FrameOutcome],
    geom: &[FrameGeom],
) -> Option<CovarianceConsistency> {
    let mut n = 0u64;
    let mut inside = 0u64;
    for (r, g) in records.iter().zip(geom) {
        let (Some(v), Some(d)) = (&r.visual, g.visual_vs_truth) else {
            continue;
        };
        if let Some(d2) = mahalanobis2(&d.en, &v.horizontal_covariance_m2) {
            n += 1;
            if d2 <= CHI2_2DOF_95 {
                inside += 1;
            }
        }
    }
    Some(CovarianceConsistency {
        n,
        inside_95: inside,
        fraction_inside_95: rate(inside, n)?,
        expected: ELLIPSE_PROBABILITY,
    })
}

fn surrogate_drift(records: &[FrameOutcome], geom: &[FrameGeom]) -> Option<SurrogateDrift> {
    let surrogate: Vec<bool> = records
        .iter()
        .map(|r| r.visual.as_ref().is_some_and(|v| v.is_surrogate_only()))
        .collect();
    let frames = surrogate.iter().filter(|&&s| s).count() as u64;
    if frames == 0 {
        return None;
    }
    // Cumulative horizontal distance along the true track (metres), and the anchor (index
    // of the last fix with enough surveyed landmarks) of every frame.
    let mut cum = Vec::with_capacity(records.len());
    let mut travelled = 0.0;
    let mut last_truth: Option<nalgebra::Vector3<f64>> = None;
    let mut anchors = Vec::with_capacity(records.len());
    let mut anchor: Option<usize> = None;
    for (i, (r, g)) in records.iter().zip(geom).enumerate() {
        if let Some(t) = g.truth {
            if let Some(p) = last_truth {
                travelled += (t - p).xy().norm();
            }
            last_truth = Some(t);
        }
        cum.push(g.truth.map(|_| travelled));
        anchors.push(anchor);
        if r.visual
            .as_ref()
            .is_some_and(|v| v.n_landmarks >= MIN_SURVEYED_LANDMARKS)
            && g.truth.is_some()
        {
            anchor = Some(i);
        }
    }
    let ratio_at = |i: usize| -> Option<(f64, f64, f64)> {
        let a = anchors[i]?;
        let dist = cum[i]? - cum[a]?;
        let err = geom[i].visual_vs_truth?.h;
        (dist >= MIN_DRIFT_DISTANCE_M).then(|| (dist, err, err / dist))
    };
    let ratios: Vec<f64> = (0..records.len())
        .filter(|&i| surrogate[i])
        .filter_map(|i| ratio_at(i).map(|(_, _, q)| q))
        .collect();
    let stretches = runs(surrogate.iter().copied())
        .into_iter()
        .map(|(a, b)| {
            let last = (a..=b).rev().find_map(&ratio_at);
            DriftStretch {
                first_frame: records[a].frame,
                last_frame: records[b].frame,
                anchor_frame: anchors[a].map(|k| records[k].frame),
                distance_m: last.map(|x| x.0),
                error_h_m: last.map(|x| x.1),
                error_per_distance: last.map(|x| x.2),
            }
        })
        .collect();
    Some(SurrogateDrift {
        frames,
        n: ratios.len() as u64,
        median_error_per_distance: quantile_nearest_rank(&ratios, 0.5),
        max_error_per_distance: ratios.iter().copied().reduce(f64::max),
        stretches,
    })
}
