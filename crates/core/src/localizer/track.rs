//! Tracking: associate each observation with the landmark (surveyed or surrogate) predicted
//! nearest to it from a pose guess, then refine the pose on the associations.

use crate::mapping::{CONE_ABSOLUTE_MARGIN, CONE_MIN_COS, CONE_RELATIVE_MARGIN, max_or_nan};
use crate::measurement::effective_bearing_sigma;
use nalgebra::{Matrix6, Vector3};
use vgps_geometry::geometry::{Pose, Ray};
use vgps_geometry::solvers::refine_pose::refine_pose_with_sigmas;
use vgps_geometry::solvers::{RefineOptions, RobustLoss};

/// Where a candidate landmark comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CandidateSource {
    /// A surveyed landmark: its index in the map's database.
    Surveyed(usize),
    /// A surrogate (mapped) landmark: its track id.
    Surrogate(u64),
}

/// A landmark the observations may be associated with.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub position: Vector3<f64>,
    /// Standard deviation of the position per axis (metres; isotropic bound).
    pub sigma_m: f64,
    pub class: Option<u32>,
    pub source: CandidateSource,
    /// For a surrogate: its full covariance plus its pose-correlation floor (m²), the
    /// error it shares with the poses it was mapped from.
    pub common_covariance: Option<nalgebra::Matrix3<f64>>,
}

/// One observation ready for tracking: its ray in the rig frame and angular σ.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ObsRay {
    pub ray: Ray,
    pub sigma_rad: f64,
    pub class: Option<u32>,
}

/// The uncertainty of a pose guess, for the association gates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GuessUncertainty {
    /// Position σ per axis, metres.
    pub position_m: f64,
    /// Attitude σ per axis, radians.
    pub rotation_rad: f64,
}

/// The result of tracking.
#[derive(Clone, Debug)]
pub(crate) struct TrackResult {
    pub world_from_rig: Pose,
    pub covariance: Matrix6<f64>,
    /// Per observation: the candidate index it is associated with (inliers only).
    pub assignment: Vec<Option<usize>>,
    pub rms_residual_rad: f64,
    /// Mean squared normalised residual of the inliers.
    pub mean_chi2: f64,
}

/// Gate on the normalised angular residual of an association (σ units).
pub const ASSOCIATION_GATE_SIGMAS: f64 = 5.0;
/// After refinement, an association whose normalised residual exceeds this is dropped.
pub const OUTLIER_SIGMAS: f64 = 4.0;
/// Association / refinement passes.
pub const TRACKING_PASSES: usize = 3;

/// The angular σ of candidate `c` seen from `origin_in_world`, given the guess uncertainty.
fn predicted_sigma(obs: &ObsRay, c: &Candidate, range: f64, guess: &GuessUncertainty) -> f64 {
    let lateral = (guess.position_m * guess.position_m + c.sigma_m * c.sigma_m) / (range * range);
    (obs.sigma_rad * obs.sigma_rad + lateral + guess.rotation_rad * guess.rotation_rad).sqrt()
}

/// The largest noise terms of a frame's observations, for [`gate_cone`].
#[derive(Clone, Copy, Debug)]
struct ObsSpread {
    /// Largest `σ_obs²` (rad²).
    sigma2: f64,
    /// Largest camera offset from the rig origin (metres).
    offset: f64,
}

impl ObsSpread {
    fn of(observations: &[ObsRay]) -> Self {
        // NaN terms propagate (and then disable the cone).
        observations.iter().fold(
            Self {
                sigma2: 0.0,
                offset: 0.0,
            },
            |w, o| Self {
                sigma2: max_or_nan(w.sigma2, o.sigma_rad * o.sigma_rad),
                offset: max_or_nan(w.offset, o.ray.origin.norm()),
            },
        )
    }
}

/// Observation directions may be this far from unit length (see `observation_rays`).
const DIRECTION_NORM_TOLERANCE: f64 = 1e-5;

/// A cone `(axis, min_cos)` of rig-frame directions outside which no observation can pass
/// the gate of [`associate`] for a candidate at `in_rig`: a conservative pre-filter
/// (`u · axis < min_cos` ⇒ the pair fails the gate), derived from the gate itself.
///
/// The gate passes only when the candidate is within `δ = g √(|v|²(σ_obs² + σ_rot²) + σ_lat²)`
/// of the observation's ray in front of its camera `x` (`v` the candidate from `x`, `|v| ≤
/// |c| + |x|`); the parallel ray from the rig origin then passes within `ρ = δ + |x|`, so its
/// direction is within `asin(ρ / |c|)` of the candidate's.
fn gate_cone(in_rig: &Vector3<f64>, gate: &GateTerms, w: &ObsSpread) -> (Vector3<f64>, f64) {
    let every = (Vector3::zeros(), f64::NEG_INFINITY);
    let d = in_rig.norm();
    let range = d + w.offset;
    let var = range * range * (w.sigma2 + gate.rot2) + gate.lateral2;
    // |u × v| ≤ δ with |u| ≥ 1 − tolerance.
    let delta = (gate.gate2 * var).sqrt() / (1.0 - DIRECTION_NORM_TOLERANCE);
    let rho = (delta + w.offset) * (1.0 + CONE_RELATIVE_MARGIN) + CONE_ABSOLUTE_MARGIN;
    let k = rho / d;
    if k.is_nan() || k >= 1.0 {
        return every;
    }
    // u · axis = |u| cos θ ≥ (1 − tolerance) cos θ.
    let min_cos = (1.0 - k * k).sqrt() * (1.0 - DIRECTION_NORM_TOLERANCE) - CONE_ABSOLUTE_MARGIN;
    if min_cos.is_nan() || min_cos <= CONE_MIN_COS {
        return every;
    }
    (in_rig / d, min_cos)
}

/// The squared terms of the association gate `z ≤ gate_sigmas` for one candidate under a
/// pose guess, shared by [`gate_cone`] and [`pair_z`].
#[derive(Clone, Copy, Debug)]
struct GateTerms {
    /// The gate, in σ.
    gate_sigmas: f64,
    /// Its square.
    gate2: f64,
    /// The guess's rotation variance (rad²).
    rot2: f64,
    /// The guess's position variance plus the candidate's (m²).
    lateral2: f64,
}

impl GateTerms {
    fn new(guess: &GuessUncertainty, c: &Candidate, gate_sigmas: f64) -> Self {
        Self {
            gate_sigmas,
            gate2: gate_sigmas * gate_sigmas,
            rot2: guess.rotation_rad * guess.rotation_rad,
            lateral2: guess.position_m * guess.position_m + c.sigma_m * c.sigma_m,
        }
    }
}

/// The normalised residual `z` of observation `o` against candidate `c` (at `in_rig` in the
/// rig frame of the pose guess), or `None` when the pair fails the gate `z ≤ gate_sigmas`
/// (or the classes differ, or the candidate is not in front of the camera).
#[inline]
fn pair_z(
    o: &ObsRay,
    c: &Candidate,
    in_rig: &Vector3<f64>,
    guess: &GuessUncertainty,
    gate: &GateTerms,
) -> Option<f64> {
    if let (Some(a), Some(b)) = (o.class, c.class)
        && a != b
    {
        return None;
    }
    // z² = sin²/σ² with sin² = |u × v|²/|v|² and σ² from `predicted_sigma`, rearranged so
    // that the gate needs neither a square root nor a division:
    // |u × v|² ≤ g² (|v|² (σ_obs² + σ_rot²) + σ_pos² + σ_c²).
    let GateTerms {
        gate_sigmas,
        gate2,
        rot2,
        lateral2,
    } = *gate;
    let v = in_rig - o.ray.origin;
    let range2 = v.norm_squared();
    if !range2.is_finite() || range2 <= f64::EPSILON * f64::EPSILON {
        return None;
    }
    if o.ray.direction.dot(&v) <= 0.0 {
        return None;
    }
    let cross2 = o.ray.direction.cross(&v).norm_squared();
    let var = range2 * (o.sigma_rad * o.sigma_rad + rot2) + lateral2;
    if cross2 > gate2 * var {
        return None;
    }
    let range = range2.sqrt();
    let sin = cross2.sqrt() / range;
    let sigma = predicted_sigma(o, c, range, guess);
    let z = sin / sigma;
    (z <= gate_sigmas).then_some(z)
}

/// Associates observations with candidates one-to-one (smallest normalised residual first)
/// from the pose guess; returns per observation the candidate index.
fn associate(
    pose: &Pose,
    guess: &GuessUncertainty,
    observations: &[ObsRay],
    candidates: &[Candidate],
    gate_sigmas: f64,
    pairs: &mut Vec<(f64, usize, usize)>,
) -> Vec<Option<usize>> {
    pairs.clear();
    let rig_from_world = pose.inverse();
    let worst = ObsSpread::of(observations);
    for (ci, c) in candidates.iter().enumerate() {
        let in_rig = rig_from_world * nalgebra::Point3::from(c.position);
        let gate = GateTerms::new(guess, c, gate_sigmas);
        let (axis, min_cos) = gate_cone(&in_rig.coords, &gate, &worst);
        for (oi, o) in observations.iter().enumerate() {
            if o.ray.direction.dot(&axis) < min_cos {
                continue;
            }
            if let Some(z) = pair_z(o, c, &in_rig.coords, guess, &gate) {
                pairs.push((z, oi, ci));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut assignment = vec![None; observations.len()];
    let mut taken = vec![false; candidates.len()];
    for &(_, oi, ci) in pairs.iter() {
        if assignment[oi].is_none() && !taken[ci] {
            assignment[oi] = Some(ci);
            taken[ci] = true;
        }
    }
    assignment
}

/// The variance (m², largest axis) of a candidate's position: its full covariance for a
/// surrogate (with the pose-correlation floor it shares with the poses it was mapped from),
/// its σ² for a surveyed landmark.
fn position_variance(c: &Candidate) -> f64 {
    c.common_covariance.map_or(c.sigma_m * c.sigma_m, |cov| {
        cov.symmetric_eigenvalues().max().max(c.sigma_m * c.sigma_m)
    })
}

/// True when candidates `a` and `b` may be one physical landmark: closer than
/// [`ASSOCIATION_GATE_SIGMAS`] σ of their combined position uncertainty. A surrogate mapped
/// from sightings of a surveyed landmark (when the observation was not associated with the
/// surveyed one) sits on it; two observations associated with the pair give one bearing
/// twice, not two landmarks.
pub(crate) fn same_point(a: &Candidate, b: &Candidate) -> bool {
    let d2 = (a.position - b.position).norm_squared();
    let gate2 = ASSOCIATION_GATE_SIGMAS * ASSOCIATION_GATE_SIGMAS;
    d2 <= gate2 * (position_variance(a) + position_variance(b))
}

/// True when, at the pose guess `pose` (uncertainty `guess`), some observation associated
/// in `assignment` had within its association gate a candidate at another point than the one
/// it was given (see [`same_point`]): the guess did not decide that association, tracking
/// chose it. With a wide guess (a prediction over a gap, its attitude σ grown to tenths of a
/// radian) every observation has several candidates in its gate and a handful of chosen
/// associations can fit a wrong pose exactly.
pub(crate) fn chosen_among_several(
    pose: &Pose,
    guess: &GuessUncertainty,
    observations: &[ObsRay],
    candidates: &[Candidate],
    assignment: &[Option<usize>],
) -> bool {
    let rig_from_world = pose.inverse();
    let in_rig: Vec<Vector3<f64>> = candidates
        .iter()
        .map(|c| (rig_from_world * nalgebra::Point3::from(c.position)).coords)
        .collect();
    for (o, a) in observations.iter().zip(assignment) {
        let Some(mine) = a.and_then(|ci| candidates.get(ci)) else {
            continue;
        };
        for (c, p) in candidates.iter().zip(&in_rig) {
            if same_point(c, mine) {
                continue;
            }
            let gate = GateTerms::new(guess, c, ASSOCIATION_GATE_SIGMAS);
            if pair_z(o, c, p, guess, &gate).is_some() {
                return true;
            }
        }
    }
    false
}

/// The number of distinct points (see [`same_point`]) among the associated candidates of
/// `assignment`, surveyed landmarks counted first: `(surveyed, all)`.
pub(crate) fn distinct_associated_points(
    candidates: &[Candidate],
    assignment: &[Option<usize>],
) -> (usize, usize) {
    let associated = || {
        assignment
            .iter()
            .flatten()
            .filter_map(|&ci| candidates.get(ci))
    };
    let mut kept: Vec<&Candidate> = Vec::new();
    let mut surveyed = 0;
    for c in associated().filter(|c| matches!(c.source, CandidateSource::Surveyed(_))) {
        if !kept.iter().any(|k| same_point(k, c)) {
            kept.push(c);
            surveyed += 1;
        }
    }
    for c in associated().filter(|c| matches!(c.source, CandidateSource::Surrogate(_))) {
        if !kept.iter().any(|k| same_point(k, c)) {
            kept.push(c);
        }
    }
    (surveyed, kept.len())
}

/// True when the association set `assignment` fits one pose: refined from `pose` (as
/// [`track`] refines), every association's normalised residual is within
/// [`OUTLIER_SIGMAS`] and their mean square within `max_mean_chi2`. Used to test a rival
/// association set (one observation given another landmark): a rival the geometry refutes
/// is no alternative to the fix.
pub(crate) fn assignment_fits(
    pose: &Pose,
    observations: &[ObsRay],
    candidates: &[Candidate],
    assignment: &[Option<usize>],
    max_mean_chi2: f64,
) -> bool {
    let (rays, points, sigmas) = linked_rays(pose, observations, candidates, assignment);
    if rays.len() < 4 {
        // Three associations fit some pose exactly: nothing refutes them.
        return true;
    }
    let Ok(r) = refine_linked(pose, &rays, &points, &sigmas) else {
        return false;
    };
    let rig_from_world = r.world_from_rig.inverse();
    let mut chi2 = 0.0;
    for k in 0..rays.len() {
        let v = (rig_from_world * nalgebra::Point3::from(points[k])).coords - rays[k].origin;
        let n = v.norm().max(f64::EPSILON);
        if rays[k].direction.dot(&v) <= 0.0 {
            return false;
        }
        let z = rays[k].direction.cross(&v).norm() / n / sigmas[k];
        // NaN (a degenerate ray) fails too.
        if z.is_nan() || z > OUTLIER_SIGMAS {
            return false;
        }
        chi2 += z * z;
    }
    chi2 / rays.len() as f64 <= max_mean_chi2
}

/// Tracks from a pose guess: associate, refine, drop outliers, re-associate with the
/// refined pose. `None` when fewer than `min_correspondences` associations survive or the
/// refinement fails.
pub(crate) fn track(
    guess_pose: &Pose,
    guess: GuessUncertainty,
    observations: &[ObsRay],
    candidates: &[Candidate],
    min_correspondences: usize,
) -> Option<TrackResult> {
    let mut pose = *guess_pose;
    let mut uncertainty = guess;
    let mut pairs = Vec::new();
    let mut result: Option<TrackResult> = None;
    let mut rays = Vec::with_capacity(observations.len());
    let mut points = Vec::with_capacity(observations.len());
    let mut sigmas = Vec::with_capacity(observations.len());
    let mut index = Vec::with_capacity(observations.len());
    let options = RefineOptions {
        loss: RobustLoss::None,
        accept_unconverged: true,
        ..RefineOptions::default()
    };
    for _ in 0..TRACKING_PASSES {
        let mut assignment = associate(
            &pose,
            &uncertainty,
            observations,
            candidates,
            ASSOCIATION_GATE_SIGMAS,
            &mut pairs,
        );
        let mut refined = None;
        // Refine, drop the worst outlier-beyond-threshold, refine again.
        for _ in 0..observations.len() {
            rays.clear();
            points.clear();
            sigmas.clear();
            index.clear();
            for (oi, a) in assignment.iter().enumerate() {
                if let Some(ci) = *a {
                    let o = &observations[oi];
                    let c = &candidates[ci];
                    let range = (c.position - pose.translation.vector).norm().max(1.0);
                    let s = effective_bearing_sigma(o.sigma_rad, c.sigma_m, range);
                    rays.push(o.ray);
                    points.push(c.position);
                    sigmas.push(s);
                    index.push(oi);
                }
            }
            if rays.len() < min_correspondences {
                return result;
            }
            let r = refine_pose_with_sigmas(&pose, &rays, &points, &sigmas, &options).ok()?;
            // Normalised residuals at the refined pose.
            let rig_from_world = r.world_from_rig.inverse();
            let mut worst = (0.0, usize::MAX);
            let mut chi2 = 0.0;
            for k in 0..rays.len() {
                let v =
                    (rig_from_world * nalgebra::Point3::from(points[k])).coords - rays[k].origin;
                let n = v.norm().max(f64::EPSILON);
                let sin = rays[k].direction.cross(&v).norm() / n;
                let z = sin / sigmas[k];
                chi2 += z * z;
                if z > worst.0 {
                    worst = (z, k);
                }
            }
            if worst.0 > OUTLIER_SIGMAS && worst.1 < index.len() {
                assignment[index[worst.1]] = None;
                continue;
            }
            refined = Some((r, chi2 / rays.len() as f64));
            break;
        }
        let (r, mean_chi2) = refined?;
        pose = r.world_from_rig;
        uncertainty = GuessUncertainty {
            position_m: (r.covariance[(0, 0)] + r.covariance[(1, 1)] + r.covariance[(2, 2)])
                .max(0.0)
                .sqrt()
                .max(1e-3),
            rotation_rad: (r.covariance[(3, 3)] + r.covariance[(4, 4)] + r.covariance[(5, 5)])
                .max(0.0)
                .sqrt()
                .max(1e-5),
        };
        let unchanged = result
            .as_ref()
            .is_some_and(|prev| prev.assignment == assignment);
        result = Some(TrackResult {
            world_from_rig: r.world_from_rig,
            covariance: r.covariance,
            assignment,
            rms_residual_rad: r.rms_residual_rad,
            mean_chi2,
        });
        if unchanged {
            break;
        }
    }
    result
}

/// A pose guess too uncertain for nearest-neighbour association (after frames without a
/// fix the gates grow as `a·dt²/2`, until each observation has several landmarks in its
/// gate and the nearest one is often wrong) is replaced by the pose most observations agree
/// on, before tracking from it.
///
/// Every triple of gated (observation, candidate) pairs, with distinct observations and
/// candidates whose angles agree pairwise within what the noise and the guess's position
/// error allow, is solved by P3P; a pose within the guess's gates scores the observations
/// that then have a candidate within [`CONSENSUS_SIGMAS`] of the observation's and the
/// landmark's σ plus [`CONSENSUS_POSITION_SLACK_M`]. The best pose is returned with that
/// slack as its σ, unless another pose that links some observation to another landmark
/// explains as many observations less [`CONSENSUS_MARGIN`] − 1 (then the frame reads two
/// ways and no pose is decided: `None`), or it explains fewer than `min_correspondences`. At most
/// [`CONSENSUS_MAX_SOLVES`] P3P problems are solved.
pub(crate) fn pose_consensus(
    pose: &Pose,
    guess: &GuessUncertainty,
    observations: &[ObsRay],
    candidates: &[Candidate],
    min_correspondences: usize,
) -> Option<(Pose, GuessUncertainty)> {
    let rig_from_world = pose.inverse();
    let in_rig: Vec<Vector3<f64>> = candidates
        .iter()
        .map(|c| (rig_from_world * nalgebra::Point3::from(c.position)).coords)
        .collect();
    let mut pairs: Vec<GatedPair> = Vec::new();
    for (ci, c) in candidates.iter().enumerate() {
        let gate = GateTerms::new(guess, c, ASSOCIATION_GATE_SIGMAS);
        let range = in_rig[ci].norm();
        if range.is_nan() || range < 1.0 {
            continue;
        }
        for (oi, o) in observations.iter().enumerate() {
            if pair_z(o, c, &in_rig[ci], guess, &gate).is_some() {
                let own = (o.sigma_rad * o.sigma_rad + (c.sigma_m / range).powi(2)).sqrt();
                pairs.push(GatedPair {
                    obs: oi,
                    cand: ci,
                    range,
                    own,
                });
            }
        }
    }
    // Two pairs may be one pose's only if the angle between the observations is the angle
    // between the landmarks seen from within the guess's position gate: that angle moves by
    // at most |Δx| (1/ρ₁ + 1/ρ₂).
    let reach = ASSOCIATION_GATE_SIGMAS * guess.position_m;
    let compatible = |a: &GatedPair, b: &GatedPair| -> bool {
        if a.obs == b.obs || a.cand == b.cand {
            return false;
        }
        let seen = vgps_geometry::geometry::angle_between(
            &observations[a.obs].ray.direction,
            &observations[b.obs].ray.direction,
        );
        let expected = vgps_geometry::geometry::angle_between(&in_rig[a.cand], &in_rig[b.cand]);
        let slack = ASSOCIATION_GATE_SIGMAS * (a.own + b.own)
            + (reach + CONSENSUS_POSITION_SLACK_M)
                * (1.0 / (a.range - reach).max(1.0) + 1.0 / (b.range - reach).max(1.0));
        (seen - expected).abs() <= slack
    };
    let max_turn = ASSOCIATION_GATE_SIGMAS * guess.rotation_rad;
    let mut scored: Vec<(usize, f64, Pose, Vec<Option<usize>>)> = Vec::new();
    let mut solves = 0usize;
    'outer: for i in 0..pairs.len() {
        for j in i + 1..pairs.len() {
            if !compatible(&pairs[i], &pairs[j]) {
                continue;
            }
            for k in j + 1..pairs.len() {
                if !compatible(&pairs[i], &pairs[k]) || !compatible(&pairs[j], &pairs[k]) {
                    continue;
                }
                if solves >= CONSENSUS_MAX_SOLVES {
                    break 'outer;
                }
                solves += 1;
                let three = [pairs[i], pairs[j], pairs[k]];
                let bearings = three.map(|p| observations[p.obs].ray.direction);
                let points = three.map(|p| candidates[p.cand].position);
                for solution in vgps_geometry::solvers::p3p(&bearings, &points).iter() {
                    let moved = (solution.translation.vector - pose.translation.vector).norm();
                    let turned = nalgebra::UnitQuaternion::from_rotation_matrix(
                        &(solution.rotation * pose.rotation.inverse()),
                    )
                    .angle();
                    if !(moved <= reach && turned <= max_turn) {
                        continue;
                    }
                    let (count, z2, links) = consensus_count(
                        solution,
                        observations,
                        candidates,
                        &pairs,
                        CONSENSUS_POSITION_SLACK_M,
                    );
                    if count >= min_correspondences {
                        scored.push((count, z2, *solution, links));
                    }
                }
            }
        }
    }
    scored.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.total_cmp(&b.1)));
    // The best reading, refined on its links and scored again without the slack of a P3P
    // pose: the runner-ups are compared with it.
    let refined = |links: &[Option<usize>], from: &Pose| {
        let pose = refine_on_links(from, links, observations, candidates)?;
        let (count, _, links) = consensus_count(
            &pose,
            observations,
            candidates,
            &pairs,
            CONSENSUS_REFINED_SLACK_M,
        );
        Some((count, pose, links))
    };
    let (_, _, first, first_links) = scored.first()?;
    let (count, best, links) = refined(first_links, first)?;
    if count < min_correspondences {
        return None;
    }
    // Another pose that explains nearly as many observations but links one of them to
    // another landmark is another reading of the frame.
    let conflict = |theirs: &[Option<usize>]| links_conflict(&links, theirs);
    let mut compared = 0;
    for (other, _, pose, theirs) in &scored[1..] {
        if other + CONSENSUS_MARGIN <= count || compared >= CONSENSUS_MAX_RIVALS {
            break;
        }
        if !conflict(theirs) {
            continue;
        }
        compared += 1;
        if let Some((n, _, theirs)) = refined(theirs, pose)
            && n + CONSENSUS_MARGIN > count
            && conflict(&theirs)
        {
            return None;
        }
    }
    Some((
        best,
        GuessUncertainty {
            position_m: CONSENSUS_POSITION_SLACK_M,
            rotation_rad: CONSENSUS_ROTATION_SLACK_RAD,
        },
    ))
}

/// True when two readings of a frame (per observation, the candidate it is linked to) link
/// some observation to different landmarks.
pub(crate) fn links_conflict(a: &[Option<usize>], b: &[Option<usize>]) -> bool {
    a.iter()
        .zip(b)
        .any(|(x, y)| x.is_some() && y.is_some() && x != y)
}

/// The pose refined on the observations' links (`None` when fewer than four, or the
/// refinement fails).
fn refine_on_links(
    from: &Pose,
    links: &[Option<usize>],
    observations: &[ObsRay],
    candidates: &[Candidate],
) -> Option<Pose> {
    let (rays, points, sigmas) = linked_rays(from, observations, candidates, links);
    if rays.len() < 4 {
        return None;
    }
    refine_linked(from, &rays, &points, &sigmas)
        .ok()
        .map(|r| r.world_from_rig)
}

/// The rays of the linked observations, their landmarks' positions and each pair's bearing
/// σ (observation and landmark σ, the range taken from `pose`).
fn linked_rays(
    pose: &Pose,
    observations: &[ObsRay],
    candidates: &[Candidate],
    links: &[Option<usize>],
) -> (Vec<Ray>, Vec<Vector3<f64>>, Vec<f64>) {
    let (mut rays, mut points, mut sigmas) = (Vec::new(), Vec::new(), Vec::new());
    for (o, ci) in observations.iter().zip(links) {
        let Some(c) = ci.and_then(|ci| candidates.get(ci)) else {
            continue;
        };
        let range = (c.position - pose.translation.vector).norm().max(1.0);
        rays.push(o.ray);
        points.push(c.position);
        sigmas.push(effective_bearing_sigma(o.sigma_rad, c.sigma_m, range));
    }
    (rays, points, sigmas)
}

/// The pose refined from `pose` on linked rays (least squares, unconverged results kept).
fn refine_linked(
    pose: &Pose,
    rays: &[Ray],
    points: &[Vector3<f64>],
    sigmas: &[f64],
) -> Result<vgps_geometry::solvers::RefinedPose, vgps_geometry::solvers::RefineError> {
    let options = RefineOptions {
        loss: RobustLoss::None,
        accept_unconverged: true,
        ..RefineOptions::default()
    };
    refine_pose_with_sigmas(pose, rays, points, sigmas, &options)
}

/// An (observation, candidate) pair within the prediction's association gate.
#[derive(Clone, Copy, Debug)]
struct GatedPair {
    /// Index of the observation.
    obs: usize,
    /// Index of the candidate.
    cand: usize,
    /// The candidate's range from the predicted rig origin, metres.
    range: f64,
    /// The pair's angular σ without the guess's terms (observation and landmark), radians.
    own: f64,
}

/// Gate of the consensus score, in σ.
pub const CONSENSUS_SIGMAS: f64 = 5.0;
/// The position error a P3P pose of three noisy bearings may have, metres: added to the
/// landmark's σ in the consensus score, and the position σ of the guess tracked from.
pub const CONSENSUS_POSITION_SLACK_M: f64 = 0.25;
/// The rotation σ of the guess tracked from a consensus pose, radians.
pub const CONSENSUS_ROTATION_SLACK_RAD: f64 = 0.005;
/// The position error of a pose refined on a consensus's links, metres: the slack of its
/// score.
pub const CONSENSUS_REFINED_SLACK_M: f64 = 0.05;
/// At most this many rival readings are refined and compared with the best.
pub const CONSENSUS_MAX_RIVALS: usize = 20;
/// A consensus pose must explain this many observations more than any distinct one.
pub const CONSENSUS_MARGIN: usize = 2;
/// The most P3P problems one consensus solves.
pub const CONSENSUS_MAX_SOLVES: usize = 20_000;

/// The observations `pose` brings within [`CONSENSUS_SIGMAS`] of one of their gated
/// candidates, one to one (smallest normalised residual first; the landmark's σ plus
/// `slack_m` over the range), the sum of those residuals squared, and per observation its
/// candidate.
fn consensus_count(
    pose: &Pose,
    observations: &[ObsRay],
    candidates: &[Candidate],
    pairs: &[GatedPair],
    slack_m: f64,
) -> (usize, f64, Vec<Option<usize>>) {
    let rig_from_world = pose.inverse();
    let mut within: Vec<(f64, usize, usize)> = Vec::new();
    for &GatedPair {
        obs: oi,
        cand: ci,
        own,
        ..
    } in pairs
    {
        let o = &observations[oi];
        let v = (rig_from_world * nalgebra::Point3::from(candidates[ci].position)).coords
            - o.ray.origin;
        let range = v.norm();
        let sigma = (own * own + (slack_m / range).powi(2)).sqrt();
        let z = vgps_geometry::geometry::angle_between(&o.ray.direction, &v) / sigma;
        if z <= CONSENSUS_SIGMAS {
            within.push((z, oi, ci));
        }
    }
    within.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut links = vec![None; observations.len()];
    let mut taken = vec![false; candidates.len()];
    let (mut count, mut z2) = (0, 0.0);
    for (z, oi, ci) in within {
        if links[oi].is_none() && !taken[ci] {
            links[oi] = Some(ci);
            taken[ci] = true;
            count += 1;
            z2 += z * z;
        }
    }
    (count, z2, links)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use vgps_geometry::synthetic::{random_unit_vector, rng};

    /// The cone of [`gate_cone`] never rejects a pair that [`pair_z`] accepts (directions of
    /// every length the localizer accepts, cameras off the rig origin), and it does reject
    /// most pairs well outside the gate.
    #[test]
    fn gate_cone_never_rejects_a_passing_pair() {
        let mut r = rng(0x5eed_c0de);
        let (mut passed, mut outside, mut rejected_outside) = (0, 0, 0);
        for _ in 0..3000 {
            let guess = GuessUncertainty {
                position_m: r.random_range(0.001..2.0),
                rotation_rad: r.random_range(1e-5..0.02),
            };
            let c = Candidate {
                position: random_unit_vector(&mut r) * r.random_range(0.5..150.0),
                sigma_m: r.random_range(0.0..1.0),
                class: None,
                source: CandidateSource::Surveyed(0),
                common_covariance: None,
            };
            let observations: Vec<ObsRay> = (0..20)
                .map(|_| {
                    let origin = random_unit_vector(&mut r) * r.random_range(0.0..0.3);
                    let sigma_rad: f64 = r.random_range(1e-4..5e-3);
                    let to = c.position - origin;
                    // Aim at the candidate, off by 0 to 4 angular gate widths.
                    let width = ASSOCIATION_GATE_SIGMAS
                        * (sigma_rad.powi(2)
                            + guess.rotation_rad.powi(2)
                            + (guess.position_m.powi(2) + c.sigma_m.powi(2)) / to.norm_squared())
                        .sqrt();
                    let off = random_unit_vector(&mut r) * (r.random_range(0.0..4.0) * width);
                    let direction =
                        (to.normalize() + off).normalize() * (1.0 + r.random_range(-1e-6..1e-6));
                    ObsRay {
                        ray: Ray { origin, direction },
                        sigma_rad,
                        class: None,
                    }
                })
                .collect();
            let worst = ObsSpread::of(&observations);
            let gate = GateTerms::new(&guess, &c, ASSOCIATION_GATE_SIGMAS);
            let (axis, min_cos) = gate_cone(&c.position, &gate, &worst);
            for o in &observations {
                let admitted = o.ray.direction.dot(&axis) >= min_cos;
                if pair_z(o, &c, &c.position, &guess, &gate).is_some() {
                    passed += 1;
                    assert!(admitted, "passing pair rejected: {o:?} {c:?} {guess:?}");
                } else {
                    outside += 1;
                    rejected_outside += usize::from(!admitted);
                }
            }
        }
        assert!(passed > 10_000 && outside > 10_000, "{passed} {outside}");
        assert!(
            rejected_outside * 2 > outside,
            "the cone rejects only {rejected_outside} of {outside} failing pairs"
        );
    }

    /// Observations of `landmarks` from `truth` (bearings from the rig origin with noise
    /// σ = 0.5 mrad), then `false_rays` random directions.
    fn observed(
        truth: &Pose,
        landmarks: &[Vector3<f64>],
        false_rays: usize,
        r: &mut impl rand::Rng,
    ) -> Vec<ObsRay> {
        let sigma_rad = 5e-4;
        let mut out: Vec<ObsRay> = landmarks
            .iter()
            .map(|p| {
                let b = vgps_geometry::geometry::bearing_in_rig(truth, p).unwrap();
                let noisy =
                    (b + random_unit_vector(r) * r.random_range(0.0..sigma_rad)).normalize();
                ObsRay {
                    ray: Ray {
                        origin: Vector3::zeros(),
                        direction: noisy,
                    },
                    sigma_rad,
                    class: None,
                }
            })
            .collect();
        for _ in 0..false_rays {
            out.push(ObsRay {
                ray: Ray {
                    origin: Vector3::zeros(),
                    direction: random_unit_vector(r),
                },
                sigma_rad,
                class: None,
            });
        }
        out
    }

    fn surveyed_at(points: &[Vector3<f64>]) -> Vec<Candidate> {
        points
            .iter()
            .enumerate()
            .map(|(k, p)| Candidate {
                position: *p,
                sigma_m: 0.02,
                class: None,
                source: CandidateSource::Surveyed(k),
                common_covariance: None,
            })
            .collect()
    }

    /// A prediction 1 m and 8.6° off with the σ of the third frame without a fix (0.6 s at
    /// 5 frames/s): the pose most observations agree on is the truth's to decimetres, and
    /// tracking from it links every observation of a mapped landmark to its own landmark and
    /// no other observation, on 50 random streets (lamps 5–9 m high on both kerbs, every
    /// 12–20 m, 8 of the 12 mapped, four false lights).
    #[test]
    fn the_consensus_finds_the_pose_a_stale_prediction_misses() {
        const MAPPED: usize = 8;
        let mut r = rng(0xc0_5e45);
        let mut missed = 0;
        for _ in 0..50 {
            let spacing = r.random_range(12.0..20.0);
            let landmarks: Vec<Vector3<f64>> = (0..12)
                .map(|k| {
                    let side = if k % 2 == 0 { 6.0 } else { -6.0 };
                    Vector3::new(
                        (k as f64 - 5.5) * spacing / 2.0 + r.random_range(-1.0..1.0),
                        side + r.random_range(-0.5..0.5),
                        r.random_range(5.0..9.0),
                    )
                })
                .collect();
            let truth = Pose::new(
                Vector3::new(r.random_range(-3.0..3.0), -3.0, 2.0),
                Vector3::new(0.005, -0.004, r.random_range(-3.0..3.0)),
            );
            let observations = observed(&truth, &landmarks, 4, &mut r);
            let off = Vector3::new(0.0, 0.0, 0.15 * if r.random::<bool>() { 1.0 } else { -1.0 });
            let predicted = Pose::from_parts(
                (truth.translation.vector + Vector3::new(0.8, -0.5, 0.1)).into(),
                nalgebra::Rotation3::new(off) * truth.rotation,
            );
            let guess = GuessUncertainty {
                position_m: 1.0,
                rotation_rad: 0.19,
            };
            // Four of the lamps seen are not mapped yet.
            let candidates = surveyed_at(&landmarks[..MAPPED]);
            let right = |t: &TrackResult| {
                t.assignment
                    .iter()
                    .enumerate()
                    .all(|(k, a)| *a == (k < MAPPED).then_some(k))
            };
            if !track(&predicted, guess, &observations, &candidates, 4).is_some_and(|t| right(&t)) {
                missed += 1;
            }
            let (pose, narrow) =
                pose_consensus(&predicted, &guess, &observations, &candidates, 4).unwrap();
            assert!((pose.translation.vector - truth.translation.vector).norm() < 0.3);
            assert!(
                nalgebra::UnitQuaternion::from_rotation_matrix(
                    &(pose.rotation * truth.rotation.inverse())
                )
                .angle()
                    < 0.01
            );
            let t = track(&pose, narrow, &observations, &candidates, 4).unwrap();
            assert!(right(&t), "{:?}", t.assignment);
        }
        // Nearest-neighbour association from the prediction itself gets many of them wrong
        // (20 of 50 with this seed).
        assert!(
            missed >= 15,
            "tracking from the prediction missed only {missed} of 50"
        );
    }

    /// Lamps placed point-symmetrically about the rig are seen the same after a half turn:
    /// a prediction that allows both turns decides nothing.
    #[test]
    fn a_layout_seen_alike_after_a_turn_decides_no_pose() {
        let mut r = rng(7);
        let half: Vec<Vector3<f64>> = (0..5)
            .map(|k| {
                Vector3::new(
                    10.0 + 9.0 * k as f64,
                    6.0 - 12.0 * (k % 2) as f64,
                    6.0 + k as f64,
                )
            })
            .collect();
        let landmarks: Vec<Vector3<f64>> = half
            .iter()
            .flat_map(|p| [*p, Vector3::new(-p.x, -p.y, p.z)])
            .collect();
        let truth = Pose::new(Vector3::new(0.0, 0.0, 2.0), Vector3::new(0.0, 0.0, 0.3));
        let observations = observed(&truth, &landmarks, 0, &mut r);
        let predicted = Pose::new(
            Vector3::new(0.0, 0.0, 2.0),
            Vector3::new(0.0, 0.0, 0.3 + 1.57),
        );
        let guess = GuessUncertainty {
            position_m: 0.5,
            rotation_rad: 0.7,
        };
        let candidates = surveyed_at(&landmarks);
        assert!(pose_consensus(&predicted, &guess, &observations, &candidates, 4).is_none());
        // Told the heading to a few degrees, the same observations decide the pose.
        let near = Pose::new(Vector3::new(0.0, 0.0, 2.0), Vector3::new(0.0, 0.0, 0.35));
        let narrow = GuessUncertainty {
            position_m: 0.5,
            rotation_rad: 0.02,
        };
        let (pose, _) = pose_consensus(&near, &narrow, &observations, &candidates, 4).unwrap();
        assert!(
            nalgebra::UnitQuaternion::from_rotation_matrix(
                &(pose.rotation * truth.rotation.inverse())
            )
            .angle()
                < 0.01
        );
    }

    /// Three landmarks cannot make a consensus of four.
    #[test]
    fn fewer_landmarks_than_needed_give_no_pose() {
        let mut r = rng(9);
        let landmarks = [
            Vector3::new(20.0, 6.0, 7.0),
            Vector3::new(-15.0, -6.0, 8.0),
            Vector3::new(5.0, 30.0, 6.0),
        ];
        let truth = Pose::new(Vector3::new(0.0, 0.0, 2.0), Vector3::new(0.0, 0.0, 1.0));
        let observations = observed(&truth, &landmarks, 3, &mut r);
        let guess = GuessUncertainty {
            position_m: 1.0,
            rotation_rad: 0.1,
        };
        let candidates = surveyed_at(&landmarks);
        assert!(pose_consensus(&truth, &guess, &observations, &candidates, 4).is_none());
    }
}
