//! Scoring a pose against the landmarks in range, keeping hypotheses and their confirmations,
//! and refining a pose on its inliers.

use super::pairs::CellData;
use super::search::Search;
use super::search::{KeptHypothesis, RELIABLE_DETERMINANT_NOISES};
use super::{
    DISTINCT_POSITION_M, DISTINCT_ROTATION_RAD, HYPOTHESIS_THRESHOLD_FACTOR, MAX_KEPT_HYPOTHESES,
    MIN_TRIPLE_ANGLE_RAD, REFINE_PASSES, STOP_CONFIRMATIONS,
};
use crate::measurement::effective_bearing_sigma;
use nalgebra::{Matrix6, Vector3};
use vgps_geometry::geometry::{Pose, Ray, angle_between, rotation_angle};
use vgps_geometry::solvers::refine_pose::{RefineOptions, RefinedPose, refine_pose_with_sigmas};

/// A refined hypothesis.
#[derive(Clone)]
pub(super) struct RefinedHypothesis {
    pub(super) pose: Pose,
    pub(super) covariance: Matrix6<f64>,
    pub(super) rms: f64,
    pub(super) inliers: usize,
    /// Truncated (MSAC) cost over every detection, in units of the squared inlier
    /// threshold: `Σ min(rᵢ² / tᵢ², 1)`. An outlier costs 1, a perfect inlier 0.
    pub(super) cost: f64,
    pub(super) assignment: Vec<Option<usize>>,
}

/// How far (in visibility ranges) a pose may be from the centre of a gathered landmark set
/// for the landmarks in its range to be taken from that set ([`Search::in_range`]).
pub(super) const RANGE_SET_SLACK: f64 = 0.25;
/// Relative widening of a gathered landmark set's radius: far above the rounding of the
/// distances compared, so that the set provably holds every landmark in range of a pose
/// within [`RANGE_SET_SLACK`] of its centre.
pub(super) const RANGE_SET_ROUNDING: f64 = 1e-9;
/// At most this many gathered landmark sets per frame (the oldest is dropped).
pub(super) const MAX_RANGE_SETS: usize = 4;

/// What the conclusion keeps between its calls in a frame (early-stop checks conclude
/// more than once) and scratch space of the scoring.
#[derive(Default)]
pub(super) struct ConclusionCache {
    /// Landmark sets gathered with one R*-tree query each: (centre, indices of the
    /// landmarks within `(1 + RANGE_SET_SLACK) ·` the visibility range of it, widened by
    /// [`RANGE_SET_ROUNDING`], in increasing order).
    pub(super) ranges: Vec<(Vector3<f64>, Vec<usize>)>,
    /// Each hypothesis pose refined so far (bit for bit) and what [`Search::refine`] gave.
    pub(super) refined: Vec<(Pose, Option<RefinedHypothesis>)>,
    /// Scratch of [`Search::score`]: the (landmark, detection) links taken so far.
    pub(super) taken: Vec<(usize, usize)>,
    /// Scratch of [`Search::score_in_range`]: the landmarks in range.
    pub(super) near: Vec<usize>,
    /// Scratch of [`Search::score`]: the unit directions of the landmarks in range.
    pub(super) units: Vec<Vector3<f64>>,
}

/// Whether two poses are equal bit for bit (the key of the refinement cache).
pub(super) fn same_bits(a: &Pose, b: &Pose) -> bool {
    a.rotation
        .matrix()
        .iter()
        .chain(a.translation.vector.iter())
        .zip(
            b.rotation
                .matrix()
                .iter()
                .chain(b.translation.vector.iter()),
        )
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

pub(super) fn same_pose(a: &Pose, b: &Pose) -> bool {
    (a.translation.vector - b.translation.vector).norm() < DISTINCT_POSITION_M
        && rotation_angle(&(a.rotation.inverse() * b.rotation)) < DISTINCT_ROTATION_RAD
}

impl Search<'_> {
    /// Whether at least `min_extensions` of the detections `extensions` each lie, under
    /// `pose`, within the hypothesis threshold of a candidate of the cell other than the
    /// hypothesis's own three (`exclude`, cell-local indices).
    pub(super) fn verify(
        &mut self,
        pose: &Pose,
        extensions: &[usize],
        exclude: [usize; 3],
        cell: &CellData,
    ) -> bool {
        let threshold = HYPOTHESIS_THRESHOLD_FACTOR * self.noise;
        // `cos(min(threshold, π))`, once per frame.
        let cos_threshold = self.cos_hypothesis_threshold;
        let survey_factor = HYPOTHESIS_THRESHOLD_FACTOR * self.options.inlier_threshold_sigmas;
        let t = pose.translation.vector;
        // The extensions' directions in the world frame, and whether each has been seen.
        // Candidates are visited once each (a square root per candidate), so the search
        // stops at the first candidate that completes the count: a detection `d` sees a
        // candidate when `offset · (R b_d) ≥ cos(threshold) · range`.
        self.scratch_extensions.clear();
        self.scratch_extensions.extend(
            extensions
                .iter()
                .map(|&d| (pose.rotation * self.directions[d], false)),
        );
        let mut verified = 0;
        for (m, cand) in cell.cands.iter().enumerate() {
            if exclude.contains(&m) {
                continue;
            }
            let l = &self.db.landmarks()[cand.index];
            let v = l.position_in_world - t;
            let r = v.norm();
            if r > 0.0 {
                // Survey error widens the threshold for near landmarks.
                let cos_t = if l.sigma_m > 0.0 {
                    (threshold + survey_factor * l.sigma_m / r)
                        .min(std::f64::consts::PI)
                        .cos()
                } else {
                    cos_threshold
                };
                let limit = cos_t * r;
                for (w, seen) in &mut self.scratch_extensions {
                    if !*seen && v.dot(w) >= limit {
                        *seen = true;
                        verified += 1;
                        if verified >= self.options.min_extensions {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }

    /// Scores a pose against a set of landmarks: (inliers, cost, assignment).
    /// Gives up (0 inliers) as soon as fewer than `min_needed` inliers remain possible.
    pub(super) fn score(
        &mut self,
        pose: &Pose,
        landmarks: &[usize],
        threshold_factor: f64,
        min_needed: usize,
    ) -> (usize, f64, Vec<Option<usize>>) {
        let allowed_misses = self.detections.len().saturating_sub(min_needed);
        let mut misses = 0;
        let range = self.options.visibility_range_m;
        // Per landmark in range: its offset in the rig frame, index and range, and its
        // direction (in a compact array of its own for the nearest-direction scan).
        self.scratch_dirs.clear();
        let units = &mut self.conclusion.units;
        units.clear();
        for &index in landmarks {
            let l = &self.db.landmarks()[index];
            let v = pose.inverse_transform_vector(&(l.position_in_world - pose.translation.vector));
            let r = v.norm();
            if r <= range && r > 0.0 {
                self.scratch_dirs.push((v, index, r));
                units.push(v / r);
            }
        }
        // Per detection: the nearest landmark direction (for rays with an origin offset the
        // direction from the camera centre is used), the first of equals.
        self.scratch_best.clear();
        let mut assignment = vec![None; self.detections.len()];
        for (d, det) in self.detections.iter().enumerate() {
            let b = &self.directions[d];
            let Some(first) = self.conclusion.units.first() else {
                misses += 1;
                if misses > allowed_misses {
                    return (0, f64::INFINITY, assignment);
                }
                continue;
            };
            let mut best_dot = first.dot(b);
            let mut best = 0;
            for (k, dir) in self.conclusion.units.iter().enumerate().skip(1) {
                let dot = dir.dot(b);
                if dot > best_dot {
                    best_dot = dot;
                    best = k;
                }
            }
            let (v, index, r) = self.scratch_dirs[best];
            let sigma_m = self.db.landmarks()[index].sigma_m;
            let sigma = effective_bearing_sigma(self.options.sigma_rad, sigma_m, r);
            let threshold = (threshold_factor * self.options.inlier_threshold_sigmas * sigma)
                .min(std::f64::consts::PI);
            let predicted = v - det.ray.origin;
            let residual = angle_between(&predicted, b);
            if residual <= threshold {
                assignment[d] = Some(index);
                self.scratch_best.push((d, residual / threshold));
            } else {
                misses += 1;
                if misses > allowed_misses {
                    return (0, f64::INFINITY, assignment);
                }
            }
        }
        // One-to-one per camera: the smaller normalised residual keeps a landmark. Rays with
        // different origins come from different cameras of the rig, and a landmark in the
        // overlap of two cameras is rightly seen by both.
        // A stable sort: links of equal normalised residual keep their detection order.
        self.scratch_best.sort_by(|x, y| x.1.total_cmp(&y.1));
        let mut taken = std::mem::take(&mut self.conclusion.taken);
        taken.clear();
        let mut inliers = 0;
        let mut cost = 0.0;
        for &(d, r) in &self.scratch_best {
            let Some(index) = assignment[d] else { continue };
            let origin = &self.detections[d].ray.origin;
            if taken
                .iter()
                .any(|&(i, e)| i == index && self.detections[e].ray.origin == *origin)
            {
                assignment[d] = None;
            } else {
                taken.push((index, d));
                inliers += 1;
                cost += r * r;
            }
        }
        self.conclusion.taken = taken;
        (inliers, cost, assignment)
    }

    /// Keeps a scored pose generated by the detection triple `triple`. A pose found again
    /// counts as confirmed only by a triple that shares no detection with the triples that
    /// confirmed it before: triples sharing a false detection that happens to line up with a
    /// landmark under a repetitive look-alike pose confirm it without independent evidence.
    pub(super) fn keep(
        &mut self,
        pose: Pose,
        inliers: usize,
        cost: f64,
        triple: [usize; 3],
        assignment: &[Option<usize>],
    ) {
        let explained = || {
            (0..assignment.len())
                .filter(|&d| assignment[d].is_some())
                .collect()
        };
        if let Some(h) = self.kept.iter_mut().find(|h| same_pose(&h.pose, &pose)) {
            if h.confirming
                .iter()
                .all(|t| t.iter().all(|d| !triple.contains(d)))
            {
                h.confirming.push(triple);
            }
            if inliers > h.inliers || (inliers == h.inliers && cost < h.cost) {
                h.pose = pose;
                h.inliers = inliers;
                h.cost = cost;
                h.explained = explained();
            }
        } else {
            if self.kept.len() >= MAX_KEPT_HYPOTHESES {
                let worst = self.kept.last().map_or(0, |h| h.inliers);
                if inliers <= worst {
                    return;
                }
                self.kept.pop();
            }
            self.kept.push(KeptHypothesis {
                pose,
                inliers,
                cost,
                confirming: vec![triple],
                explained: explained(),
            });
        }
        self.kept
            .sort_by(|x, y| y.inliers.cmp(&x.inliers).then(x.cost.total_cmp(&y.cost)));
    }

    /// The detection triple that should run next to confirm the best pose, if one is due:
    /// the best explains at least `enough` detections and has fewer than
    /// [`STOP_CONFIRMATIONS`] disjoint confirming triples. The triple is drawn from the
    /// detections the best explains and that no confirming triple holds, the cheapest first
    /// (fewest candidates in the pair tables, `allowed_counts`), with the three bearings at
    /// least [`MIN_TRIPLE_ANGLE_RAD`] apart and a determinant beyond the noise; `tried`
    /// triples are not drawn again.
    ///
    /// Why this is safe: the triple consists of detections the best explains, which are
    /// detections of landmarks unless they line up with one by chance. If the best is the
    /// true pose the triple generates it again (the stop). If it is a look-alike (the same
    /// detections explained by other landmarks), the triple, made of true detections, also
    /// generates the true pose, which then outranks it or ties with it: the conclusion sees
    /// both, as it would after any other triple of true detections.
    ///
    /// Up to `limit` such triples, in that order (the caller may weigh them further).
    pub(super) fn confirmation_triples(
        &self,
        enough: usize,
        allowed_counts: &[usize],
        tried: &[[usize; 3]],
        limit: usize,
    ) -> Vec<[usize; 3]> {
        let mut found = Vec::new();
        let Some(top) = self.kept.first() else {
            return found;
        };
        if top.inliers < enough || top.confirming.len() >= STOP_CONFIRMATIONS as usize {
            return found;
        }
        let mut pool: Vec<usize> = top
            .explained
            .iter()
            .copied()
            .filter(|&d| allowed_counts[d] > 0 && !top.confirming.iter().flatten().any(|&c| c == d))
            .collect();
        pool.sort_by_key(|&d| (allowed_counts[d], d));
        let dirs = &self.directions;
        let n = dirs.len();
        for z in 2..pool.len() {
            for y in 1..z {
                for x in 0..y {
                    let mut t = [pool[x], pool[y], pool[z]];
                    t.sort_unstable();
                    let spread = (0..3)
                        .all(|p| self.angles[t[p] * n + t[(p + 1) % 3]] >= MIN_TRIPLE_ANGLE_RAD);
                    let determinant = dirs[t[0]].dot(&dirs[t[1]].cross(&dirs[t[2]]));
                    if spread
                        && determinant.abs() > RELIABLE_DETERMINANT_NOISES * self.noise
                        && !tried.contains(&t)
                    {
                        found.push(t);
                        if found.len() >= limit {
                            return found;
                        }
                    }
                }
            }
        }
        found
    }

    /// The effective bearing σ of landmark `l` at `range` metres: the bearing noise and the
    /// survey σ seen from that range, radians.
    pub(super) fn sigma_of(&self, l: &super::DbLandmark, range: f64) -> f64 {
        effective_bearing_sigma(self.options.sigma_rad, l.sigma_m, range.max(1e-3))
    }

    /// Refines `pose` on the links of `assignment` (σ inflated by the survey σ); `None` with
    /// fewer than four links or when the refinement fails.
    pub(super) fn fit(&self, pose: &Pose, assignment: &[Option<usize>]) -> Option<RefinedPose> {
        let links = assignment.iter().flatten().count();
        if links < 4 {
            return None;
        }
        let mut rays: Vec<Ray> = Vec::with_capacity(links);
        let mut points = Vec::with_capacity(links);
        let mut sigmas = Vec::with_capacity(links);
        for (d, a) in assignment.iter().enumerate() {
            if let Some(index) = *a {
                let l = &self.db.landmarks()[index];
                let range = (l.position_in_world - pose.translation.vector).norm();
                rays.push(self.detections[d].ray);
                points.push(l.position_in_world);
                sigmas.push(self.sigma_of(l, range));
            }
        }
        let options = RefineOptions {
            sigma_rad: self.options.sigma_rad,
            accept_unconverged: true,
            ..RefineOptions::default()
        };
        refine_pose_with_sigmas(pose, &rays, &points, &sigmas, &options).ok()
    }

    /// One refinement pass: the detections within `factor` × the inlier threshold of a
    /// landmark in range under `pose` are fitted, and the fitted pose is re-scored against
    /// every landmark in range at the inlier threshold.
    pub(super) fn refine_pass(
        &mut self,
        pose: &Pose,
        factor: f64,
        near: &mut Vec<usize>,
    ) -> Option<RefinedHypothesis> {
        let (_, _, assignment) = self.score_in_range(pose, factor, near);
        self.fit_and_rescore(pose, &assignment, near)
    }

    /// The detections within `factor` × the inlier threshold of a landmark in range of
    /// `pose`, scored as by [`Search::score`] (`near` receives the landmarks in range).
    pub(super) fn score_in_range(
        &mut self,
        pose: &Pose,
        factor: f64,
        near: &mut Vec<usize>,
    ) -> (usize, f64, Vec<Option<usize>>) {
        self.in_range(&pose.translation.vector, near);
        self.score(pose, near, factor, 0)
    }

    /// Replaces `out` by the landmarks within the visibility range of `position`, exactly
    /// as [`LandmarkDb::within`] gives them (same set, same order), but taken from a set
    /// gathered by one R*-tree query for every position within [`RANGE_SET_SLACK`]
    /// visibility ranges of its centre: the conclusion scores some twenty poses per frame,
    /// most a few metres apart.
    ///
    /// The set holds every landmark in range of `position`: one within `range` of it is
    /// within `range + slack` of the set's centre (triangle inequality), and the set's
    /// radius exceeds that by [`RANGE_SET_ROUNDING`] relative, far beyond the rounding of
    /// the distances; [`LandmarkDb::within_among`] then applies the R*-tree's own test.
    pub(super) fn in_range(&mut self, position: &Vector3<f64>, out: &mut Vec<usize>) {
        let range = self.options.visibility_range_m;
        let slack = RANGE_SET_SLACK * range;
        let radius = (range + slack) * (1.0 + RANGE_SET_ROUNDING);
        if !(vgps_geometry::geometry::is_finite(position) && range >= 0.0 && radius.is_finite()) {
            self.db.within(position, range, out);
            return;
        }
        let sets = &mut self.conclusion.ranges;
        let k = match sets
            .iter()
            .position(|(c, _)| (position - c).norm() <= slack)
        {
            Some(k) => k,
            None => {
                if sets.len() >= MAX_RANGE_SETS {
                    sets.remove(0);
                }
                let mut set = Vec::new();
                self.db.within(position, radius, &mut set);
                sets.push((*position, set));
                sets.len() - 1
            }
        };
        self.db.within_among(&sets[k].1, position, range, out);
    }

    /// Fits `pose` to the links of `assignment` and re-scores the fitted pose against every
    /// landmark in range at the inlier threshold.
    pub(super) fn fit_and_rescore(
        &mut self,
        pose: &Pose,
        assignment: &[Option<usize>],
        near: &mut Vec<usize>,
    ) -> Option<RefinedHypothesis> {
        let fitted = self.fit(pose, assignment)?;
        let pose = fitted.world_from_rig;
        let (inliers, cost, assignment) = self.score_in_range(&pose, 1.0, near);
        Some(RefinedHypothesis {
            pose,
            covariance: fitted.covariance,
            rms: fitted.rms_residual_rad,
            inliers,
            cost: cost + (self.detections.len() - inliers) as f64,
            assignment,
        })
    }

    /// [`Search::refine`], once per pose and frame: the early-stop checks conclude more than
    /// once, mostly on the same hypotheses, and a refinement depends on its pose alone.
    pub(super) fn refine_once(&mut self, start: &Pose) -> Option<RefinedHypothesis> {
        if let Some((_, r)) = self
            .conclusion
            .refined
            .iter()
            .find(|(p, _)| same_bits(p, start))
        {
            return r.clone();
        }
        let mut near = std::mem::take(&mut self.conclusion.near);
        let r = self.refine(start, &mut near);
        self.conclusion.near = near;
        self.conclusion.refined.push((*start, r.clone()));
        r
    }

    /// Refines a pose with its inliers and re-scores it against every landmark in range
    /// (`near` is scratch): a first pass at the hypothesis threshold, then passes at the
    /// inlier threshold until the inliers stop changing (at most [`REFINE_PASSES`]). A pass
    /// from a pose that the pass before scored at the inlier threshold fits the links of
    /// that score (scoring the same pose at the same threshold again would give them once
    /// more).
    pub(super) fn refine(
        &mut self,
        start: &Pose,
        near: &mut Vec<usize>,
    ) -> Option<RefinedHypothesis> {
        let mut result: Option<RefinedHypothesis> = None;
        for _ in 0..REFINE_PASSES {
            let pass = match &result {
                None => self.refine_pass(start, HYPOTHESIS_THRESHOLD_FACTOR, near)?,
                Some(r) => self.fit_and_rescore(&r.pose, &r.assignment, near)?,
            };
            match &result {
                // A pass that explains fewer detections than the one before drifts away
                // (three nearly collinear lamps fix the height badly): the better pass is
                // kept.
                Some(r) if pass.inliers < r.inliers => break,
                Some(r) if pass.assignment == r.assignment => {
                    result = Some(pass);
                    break;
                }
                _ => result = Some(pass),
            }
        }
        // The inlier threshold can leave out the detections of near landmarks when the pose
        // is a few centimetres off (5 cm is 0.6° at 5 m); the passes above then converge on
        // the distant ones. One more pass from the refined pose at the hypothesis threshold
        // takes them in; it is kept, refitted once on its inliers, only if it explains more.
        let best = result?;
        // Most refined poses explain as many detections at the hypothesis threshold as at
        // the inlier threshold: then there is nothing to take in, and no fit to run.
        let (loose, _, assignment) =
            self.score_in_range(&best.pose, HYPOTHESIS_THRESHOLD_FACTOR, near);
        if loose <= best.inliers {
            return Some(best);
        }
        match self.fit_and_rescore(&best.pose, &assignment, near) {
            Some(wider) if wider.inliers > best.inliers => {
                // `wider` was scored at the inlier threshold: refit on those links.
                let refit = self.fit_and_rescore(&wider.pose, &wider.assignment, near);
                Some(match refit {
                    Some(r) if r.inliers >= wider.inliers => r,
                    _ => wider,
                })
            }
            _ => Some(best),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_is_the_same_as_itself_and_its_refined_copies() {
        // `Rotation3::angle` is NaN when rounding puts the trace of `R⁻¹R` above 3, which
        // made two identical refined poses "distinct" and their frame ambiguous.
        let mut r = vgps_geometry::synthetic::rng(11);
        for _ in 0..10_000 {
            let pose = vgps_geometry::synthetic::random_pose(&mut r, 100.0);
            assert!(same_pose(&pose, &pose));
            let mut rotation = pose.rotation;
            rotation.renormalize();
            let copy = Pose::from_parts(pose.translation, rotation);
            assert!(same_pose(&pose, &copy));
            let far = Pose::from_parts(
                (pose.translation.vector + Vector3::new(DISTINCT_POSITION_M * 1.01, 0.0, 0.0))
                    .into(),
                pose.rotation,
            );
            assert!(!same_pose(&pose, &far));
        }
    }
}
