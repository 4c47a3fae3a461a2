//! The conclusion of a search: the hypotheses refined, the fix and its runner-up compared,
//! and the links weighed one by one.

use super::scoring::{RefinedHypothesis, same_pose};
use super::search::Search;
use super::{
    DECISIVE_LOG_ODDS, HYPOTHESIS_THRESHOLD_FACTOR, LIKELY_WRONG_LINK_PROBABILITY,
    MAX_REFINED_HYPOTHESES, MIN_DETECTION_PROBABILITY, MIN_LINK_LEVERAGE_GAP, MatchEstimate,
    MatchResult, MatchStatus,
};
use nalgebra::{Matrix2, Vector3};
use vgps_geometry::geometry::Pose;
use vgps_geometry::solvers::refine_pose::angular_residual;

/// What a fix says about the frame's detections (see [`Search::detection_model`]).
pub(super) struct DetectionModel {
    /// False detections per steradian.
    pub(super) clutter_per_sr: f64,
    /// Probability that a landmark in range is detected.
    pub(super) detection_probability: f64,
    /// The landmarks in range of the fix.
    pub(super) near: Vec<usize>,
    /// The factor on σ² the fix's own residuals call for, at least 1: `χ² / (2k − 6)` over
    /// its `k` inliers. Evidence from residuals is weighed with the larger σ, so that a σ
    /// set too small does not make the comparison of two poses overconfident.
    pub(super) noise_scale: f64,
}

/// Relative widening of the widest gate angle below which a landmark is skipped in
/// [`Search::link_probabilities`] without computing its residual: the residual's norm is
/// the angle to within 1e-12 relative, far inside this margin.
pub(super) const LINK_GATE_ANGLE_MARGIN: f64 = 1e-3;
/// Absolute margin on the cosine of that angle, far above the rounding of the dot product.
pub(super) const LINK_GATE_COS_MARGIN: f64 = 1e-12;

/// A refined pose or a runner-up only: (inliers, truncated cost, pose).
type Scored = (usize, f64, Pose);

/// The result from the hypotheses kept so far. The strongest are refined: a P3P pose from
/// three noisy bearings (nearly collinear lamps along a street) may explain fewer
/// detections than a wrong pose before refinement and all of them after. The refined pose
/// with the most inliers (ties: least truncated cost) is the fix; the runner-up is the
/// distinct pose with the most inliers (a hypothesis that does not refine is scored as it
/// is, at the tight threshold).
pub(super) fn conclude(search: &mut Search, cells: usize) -> MatchResult {
    let n = search.detections.len();
    let options = search.options;
    let hypotheses = search.hypotheses;
    let pose_tests = search.pose_tests;
    let failed = |status, message: String| {
        let mut r = MatchResult::failed(status, n, message);
        r.cells = cells;
        r.hypotheses = hypotheses;
        r.pose_tests = pose_tests;
        r
    };
    let starts: Vec<Pose> = search
        .kept
        .iter()
        .take(MAX_REFINED_HYPOTHESES)
        .map(|h| h.pose)
        .collect();
    if starts.is_empty() {
        return failed(
            MatchStatus::NoMatch,
            "no hypothesis consistent with the detections".to_string(),
        );
    }
    let (mut refined, unrefined) = refine_starts(search, &starts);
    let Some(best_index) = (0..refined.len()).min_by(|&x, &y| {
        refined[y]
            .inliers
            .cmp(&refined[x].inliers)
            .then(refined[x].cost.total_cmp(&refined[y].cost))
    }) else {
        return failed(
            MatchStatus::NoMatch,
            "the best hypothesis did not refine".to_string(),
        );
    };
    let best = refined.swap_remove(best_index);
    let (pose, best_score) = (best.pose, best.inliers);
    // The runner-up: the distinct pose of least cost (a hypothesis that does not refine is
    // scored as it is).
    let runner_up: Option<Scored> = refined
        .iter()
        .map(|r| (r.inliers, r.cost, r.pose))
        .chain(unrefined.iter().copied())
        .filter(|(_, _, p)| !same_pose(p, &pose))
        .min_by(|x, y| y.0.cmp(&x.0).then(x.1.total_cmp(&y.1)));
    let result = MatchResult {
        status: MatchStatus::Ok,
        message: String::new(),
        estimate: None,
        assignment: vec![None; n],
        link_probability: vec![None; n],
        best_score,
        runner_up_score: runner_up.map(|r| r.0),
        runner_up_pose: runner_up.map(|r| r.2),
        log10_false_alarms: None,
        pose_tests: search.pose_tests,
        cells,
        hypotheses,
    };
    if best_score < options.min_inliers {
        return result.refused(
            MatchStatus::NoMatch,
            format!(
                "the best hypothesis has {best_score} inliers (at least {} needed)",
                options.min_inliers
            ),
        );
    }
    let model = search.detection_model(&best);
    if let Some((score, _, _)) = runner_up
        && let Some(message) = ambiguity(search, &model, &best, score, &refined, &unrefined)
    {
        return result.refused(MatchStatus::Ambiguous, message);
    }
    settle_links(search, best, &model, result)
}

/// Refines each start pose once (skipping one already refined to the same pose): the
/// refined poses inside the area that keep the known vertical, and the runner-ups only,
/// those that do not refine (scored as they are), those outside the area and those tilted
/// beyond the vertical ([`Search::within_vertical`]).
fn refine_starts(search: &mut Search, starts: &[Pose]) -> (Vec<RefinedHypothesis>, Vec<Scored>) {
    let n = search.detections.len();
    let mut refined: Vec<RefinedHypothesis> = Vec::new();
    let mut unrefined: Vec<Scored> = Vec::new();
    let mut near = Vec::new();
    for start in starts {
        if refined.iter().any(|r| same_pose(&r.pose, start)) {
            continue;
        }
        let (pose, scored) = match search.refine_once(start) {
            Some(r)
                if search.within_area(&r.pose)
                    && search.within_vertical(&r.pose, &r.covariance) =>
            {
                refined.push(r);
                continue;
            }
            Some(r) => (r.pose, (r.inliers, r.cost)),
            None => {
                search.in_range(&start.translation.vector, &mut near);
                let (inliers, cost, _) = search.score(start, &near, 1.0, 0);
                (*start, (inliers, cost + (n - inliers) as f64))
            }
        };
        // A pose outside the area (the prior), e.g. one that refinement moved away, or
        // tilted beyond the known vertical, cannot be the fix, but it still counts as a
        // runner-up: if the prior or the vertical is off, it may be the truth, and a
        // look-alike inside the area must not then pass for a fix.
        unrefined.push((scored.0, scored.1, pose));
    }
    (refined, unrefined)
}

/// Why the best is ambiguous against a runner-up with `score` inliers within the margin,
/// or `None` when the evidence is decisive: up to two inliers short of the margin is enough
/// when the likelihood ratio of the best against all its close rivals together (each
/// inlier weighed by its residual against the density of false detections; a sum over the
/// rivals, since each is a chance for a coincidence) is at least `e^DECISIVE_LOG_ODDS`.
fn ambiguity(
    search: &Search,
    model: &DetectionModel,
    best: &RefinedHypothesis,
    score: usize,
    refined: &[RefinedHypothesis],
    unrefined: &[Scored],
) -> Option<String> {
    let options = search.options;
    let (pose, best_score) = (best.pose, best.inliers);
    if score + options.ambiguity_margin <= best_score {
        return None;
    }
    let rivals: Vec<f64> = refined
        .iter()
        .map(|r| (r.inliers, r.cost, r.pose))
        .chain(unrefined.iter().copied())
        .filter(|(s, _, p)| s + options.ambiguity_margin > best_score && !same_pose(p, &pose))
        .map(|(s, c, _)| search.log_evidence(model, s, c))
        .collect();
    let top = rivals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let rivals_evidence = top + rivals.iter().map(|e| (e - top).exp()).sum::<f64>().ln();
    let odds = search.log_evidence(model, best_score, best.cost) - rivals_evidence;
    let decisive = best_score + 2 >= score + options.ambiguity_margin && odds >= DECISIVE_LOG_ODDS;
    (!decisive).then(|| {
        format!(
            "two distinct poses with {best_score} and {score} inliers (margin {} needed; log odds {odds:.1})",
            options.ambiguity_margin
        )
    })
}

/// The links of the fix `best`, into `result`. First, while the least probable link is
/// more likely wrong than right, it is dropped and the pose refined on the rest (a false
/// link biases the pose and makes every other link look doubtful); a fix that would then
/// keep fewer than `min_inliers` links is refused. Then only the links whose probability
/// reaches `min_link_probability` are reported (a frame of few detections has links that
/// the others check poorly: they stay in the pose but are not reported).
fn settle_links(
    search: &Search,
    best: RefinedHypothesis,
    model: &DetectionModel,
    mut result: MatchResult,
) -> MatchResult {
    let options = search.options;
    let drop_below = options
        .min_link_probability
        .min(LIKELY_WRONG_LINK_PROBABILITY);
    let mut current = best;
    let mut probabilities = search.link_probabilities(&current, model);
    loop {
        let worst = current
            .assignment
            .iter()
            .zip(&probabilities)
            .enumerate()
            .filter_map(|(d, (a, p))| a.and(*p).map(|p| (d, p)))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        let Some((d, p)) = worst.filter(|&(_, p)| p < drop_below) else {
            break;
        };
        let links = current.assignment.iter().flatten().count();
        if links <= options.min_inliers {
            return result.refused(
                MatchStatus::NoMatch,
                format!(
                    "a link of the best hypothesis is more likely wrong than right (probability {p:.2}) and only {} would remain (at least {} needed)",
                    links - 1,
                    options.min_inliers
                ),
            );
        }
        current.assignment[d] = None;
        let Some(fit) = search.fit(&current.pose, &current.assignment) else {
            return result.refused(
                MatchStatus::NoMatch,
                "the best hypothesis does not refine without its doubtful links".to_string(),
            );
        };
        current.pose = fit.world_from_rig;
        current.covariance = fit.covariance;
        current.rms = fit.rms_residual_rad;
        probabilities = search.link_probabilities(&current, model);
    }
    // The acceptance test: could a wrong pose among those tried gather this many links by
    // chance?
    let links = current.assignment.iter().flatten().count();
    let false_alarms = search.log10_false_alarms(&current.pose, links, &model.near);
    result.log10_false_alarms = Some(false_alarms);
    if false_alarms > options.max_false_alarms.log10() {
        return result.refused(
            MatchStatus::NoMatch,
            format!(
                "the best pose explains {links} of {} detections, which a wrong pose among the {} tried would do by chance (false alarms 10^{false_alarms:.1}, at most {:e})",
                search.detections.len(),
                search.pose_tests,
                options.max_false_alarms
            ),
        );
    }
    let sure: Vec<Option<usize>> = current
        .assignment
        .iter()
        .zip(&probabilities)
        .map(|(a, p)| a.filter(|_| p.is_some_and(|p| p >= options.min_link_probability)))
        .collect();
    result.link_probability = sure
        .iter()
        .zip(&probabilities)
        .map(|(a, p)| a.and(*p))
        .collect();
    result.assignment = sure;
    result.estimate = Some(MatchEstimate {
        world_from_rig: current.pose,
        covariance: current.covariance,
        rms_residual_rad: current.rms,
    });
    result
}

impl Search<'_> {
    /// `log10` of the number of false alarms of a pose with `links` inliers
    /// ([`super::nfa::log10_false_alarms`]): the poses tried so far, and the chance that a
    /// detection unrelated to the landmarks `near` (those in range of `pose`) falls within
    /// the hypothesis gate of one of them (the gate at which a P3P pose gathers the
    /// detections it is refined on; per landmark its σ with the survey term at its range).
    pub(super) fn log10_false_alarms(&self, pose: &Pose, links: usize, near: &[usize]) -> f64 {
        let position = pose.translation.vector;
        let gate = HYPOTHESIS_THRESHOLD_FACTOR * self.options.inlier_threshold_sigmas;
        let landmarks: Vec<(f64, f64)> = near
            .iter()
            .filter_map(|&k| {
                let offset = self.db.landmarks()[k].position_in_world - position;
                let range = offset.norm();
                (range > 0.0).then(|| {
                    (
                        (offset.z / range).clamp(-1.0, 1.0).asin(),
                        (gate * self.sigma_of(&self.db.landmarks()[k], range))
                            .min(std::f64::consts::PI),
                    )
                })
            })
            .collect();
        let p = super::nfa::chance_alignment_probability(&landmarks);
        super::nfa::log10_false_alarms(self.pose_tests, self.detections.len(), links, p)
    }

    /// The detection model of a fix: false detections per steradian (those the fix does not
    /// explain, at least one, spread over the sphere) and the probability that a landmark in
    /// range is detected (inliers over landmarks in range, at least
    /// [`MIN_DETECTION_PROBABILITY`]).
    pub(super) fn detection_model(&mut self, best: &RefinedHypothesis) -> DetectionModel {
        let n = self.detections.len();
        let mut near = Vec::new();
        self.in_range(&best.pose.translation.vector, &mut near);
        let gate2 = self.options.inlier_threshold_sigmas.powi(2);
        let chi2 = gate2 * (best.cost - n.saturating_sub(best.inliers) as f64).max(0.0);
        let dof = (2 * best.inliers).saturating_sub(6).max(1) as f64;
        DetectionModel {
            noise_scale: (chi2 / dof).max(1.0),
            clutter_per_sr: n.saturating_sub(best.inliers).max(1) as f64
                / (4.0 * std::f64::consts::PI),
            detection_probability: (best.inliers as f64 / near.len().max(1) as f64)
                .clamp(MIN_DETECTION_PROBABILITY, 1.0),
            near,
        }
    }

    /// The log-likelihood ratio of a hypothesis with `inliers` inliers and truncated cost
    /// `cost` (see [`RefinedHypothesis::cost`]) against "every detection is false": each inlier adds
    /// `ln(P_d / (c · 2πs²)) − r²/(2s²)` (the Gaussian bearing of a detected landmark against
    /// false detections of density `c` per steradian), with `Σ r²/σ²` recovered from the
    /// cost (in units of the squared gate) and `s² = σ² ·` [`DetectionModel::noise_scale`].
    pub(super) fn log_evidence(&self, model: &DetectionModel, inliers: usize, cost: f64) -> f64 {
        let variance = self.options.sigma_rad.powi(2) * model.noise_scale;
        let per_inlier = (model.detection_probability
            / (model.clutter_per_sr * 2.0 * std::f64::consts::PI * variance))
            .ln();
        let gate = self.options.inlier_threshold_sigmas;
        let outliers = self.detections.len().saturating_sub(inliers) as f64;
        let chi2 = gate * gate * (cost - outliers).max(0.0) / model.noise_scale;
        inliers as f64 * per_inlier - 0.5 * chi2
    }

    /// The probability of each link of a fix given every other link (`None` where there is
    /// no link).
    ///
    /// Link `i` (residual `rᵢ`, a 2-vector; effective σᵢ) is weighed by its predictive
    /// density under the pose fitted to the *other* links: with the leverage
    /// `Hᵢ = Jᵢ Σ Jᵢᵀ / σᵢ²` (Σ the fix's covariance, which includes link `i`), the deleted
    /// residual is `(I − Hᵢ)⁻¹ rᵢ` with covariance `σᵢ² (I − Hᵢ)⁻¹`, so its density is
    /// `fᵢ = √det(I − Hᵢ) / (2πσᵢ²) · exp(−rᵢᵀ (I − Hᵢ)⁻¹ rᵢ / (2σᵢ²))`. A false detection
    /// that pulled the pose towards a nearby landmark has a small residual but a large
    /// leverage, and so a small density. The alternatives are a false detection (density
    /// `c` per steradian) and every other landmark within the gate of the detection (their
    /// own densities `fₖ`): `P = P_d·fᵢ / (c + P_d·(fᵢ + Σₖ fₖ))`.
    ///
    /// The landmarks in range are gathered once per call with their σ². A landmark whose
    /// direction is farther from the detection's than the widest gate angle (the gate times
    /// the largest σ, widened by [`LINK_GATE_ANGLE_MARGIN`]) is outside the gate, since the
    /// residual's norm is that angle: it is skipped without computing its residual.
    pub(super) fn link_probabilities(
        &self,
        best: &RefinedHypothesis,
        model: &DetectionModel,
    ) -> Vec<Option<f64>> {
        let pose = &best.pose;
        let two_pi = 2.0 * std::f64::consts::PI;
        let gate2 = self.options.inlier_threshold_sigmas.powi(2);
        let p = model.detection_probability;
        let position = pose.translation.vector;
        // Per landmark in range: index, position and σ² (as `sigma_of` gives it).
        let others: Vec<(usize, Vector3<f64>, f64)> = model
            .near
            .iter()
            .map(|&k| {
                let other = &self.db.landmarks()[k];
                let range_k = (other.position_in_world - position).norm();
                (
                    k,
                    other.position_in_world,
                    self.sigma_of(other, range_k).powi(2),
                )
            })
            .collect();
        let widest = self.options.inlier_threshold_sigmas
            * others.iter().fold(0.0, |m: f64, o| m.max(o.2)).sqrt()
            * (1.0 + LINK_GATE_ANGLE_MARGIN);
        // A landmark is skipped when `b · v < cos_widest · |v|` (`v` its offset from the ray
        // origin in the rig frame, `b` the unit bearing); never beyond a right angle.
        let cos_widest = if widest < std::f64::consts::FRAC_PI_2 {
            widest.cos() - LINK_GATE_COS_MARGIN
        } else {
            f64::NEG_INFINITY
        };
        let rig_from_world = pose.rotation.matrix().transpose();
        best.assignment
            .iter()
            .enumerate()
            .map(|(d, a)| {
                let index = (*a)?;
                let ray = &self.detections[d].ray;
                let l = &self.db.landmarks()[index];
                let range = (l.position_in_world - pose.translation.vector).norm();
                let sigma2 = self.sigma_of(l, range).powi(2);
                let Some((r, j)) = angular_residual(pose, ray, &l.position_in_world) else {
                    return Some(0.0);
                };
                let rest = Matrix2::identity() - j * best.covariance * j.transpose() / sigma2;
                let det = rest.determinant();
                let own = match rest.try_inverse() {
                    Some(inverse) if det > MIN_LINK_LEVERAGE_GAP => {
                        det.sqrt() / (two_pi * sigma2)
                            * (-0.5 * r.dot(&(inverse * r)) / sigma2).exp()
                    }
                    // The pose is (nearly) determined by this link alone: it cannot be checked.
                    _ => 0.0,
                };
                let bearing = &self.directions[d];
                let mut rivals = 0.0;
                for &(k, point, sigma_k2) in &others {
                    if k == index {
                        continue;
                    }
                    let v = rig_from_world * (point - position) - ray.origin;
                    if bearing.dot(&v) < cos_widest * v.norm() {
                        continue;
                    }
                    if let Some((rk, _)) = angular_residual(pose, ray, &point) {
                        let chi2 = rk.norm_squared() / sigma_k2;
                        if chi2 <= gate2 {
                            rivals += (-0.5 * chi2).exp() / (two_pi * sigma_k2);
                        }
                    }
                }
                let probability = p * own / (model.clutter_per_sr + p * (own + rivals));
                Some(if probability.is_finite() {
                    probability
                } else {
                    0.0
                })
            })
            .collect()
    }
}
