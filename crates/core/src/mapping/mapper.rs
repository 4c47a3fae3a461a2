//! The online landmark mapper: association, track initialisation, refinement, pruning.

use super::refine::{MapRay, ray_residual_tangent, ray_residual_variance, refine_landmark};
use super::{
    GATE_CHI2_1DOF, GATE_CHI2_2DOF, MAX_INIT_RELATIVE_SIGMA, MAX_RANGE_M, MIN_INIT_PARALLAX_RAD,
    MIN_LANDMARK_RAYS, MIN_RANGE_M, MappedLandmark, MappingError, MappingFrame, SurrogateCriteria,
    TENTATIVE_TIMEOUT_S,
};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use std::ops::Range;
use vgps_geometry::geometry::tangent_basis;
use vgps_geometry::triangulation::{
    RayObservation, RaySum, TriangulatedPoint, TriangulationError, intersect_two_rays,
};

/// Options of the [`LandmarkMapper`]; `Default` gives the documented constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapperOptions {
    /// Gate on the squared Mahalanobis distance of a landmark estimate from a new ray
    /// ([`GATE_CHI2_2DOF`]).
    pub gate_chi2_2dof: f64,
    /// Gate on the squared, normalised gap between a new ray and a one-ray track
    /// ([`GATE_CHI2_1DOF`]).
    pub gate_chi2_1dof: f64,
    /// Farthest landmark associated (metres, [`MAX_RANGE_M`]).
    pub max_range_m: f64,
    /// Smallest two-ray parallax that initialises a track (radians,
    /// [`MIN_INIT_PARALLAX_RAD`]).
    pub min_init_parallax_rad: f64,
    /// Time after which an unseen track with fewer than `min_landmark_rays` rays is dropped
    /// (seconds, [`TENTATIVE_TIMEOUT_S`]).
    pub tentative_timeout_s: f64,
    /// Fewest rays of a reported landmark ([`MIN_LANDMARK_RAYS`]).
    pub min_landmark_rays: usize,
    /// When a landmark becomes a surrogate.
    pub surrogate: SurrogateCriteria,
}

impl Default for MapperOptions {
    fn default() -> Self {
        Self {
            gate_chi2_2dof: GATE_CHI2_2DOF,
            gate_chi2_1dof: GATE_CHI2_1DOF,
            max_range_m: MAX_RANGE_M,
            min_init_parallax_rad: MIN_INIT_PARALLAX_RAD,
            tentative_timeout_s: TENTATIVE_TIMEOUT_S,
            min_landmark_rays: MIN_LANDMARK_RAYS,
            surrogate: SurrogateCriteria::default(),
        }
    }
}

impl MapperOptions {
    fn validate(&self) -> Result<(), MappingError> {
        let pos = |v: f64| v > 0.0 && v.is_finite();
        if !pos(self.gate_chi2_2dof) {
            return Err(MappingError::InvalidOption("gate_chi2_2dof"));
        }
        if !pos(self.gate_chi2_1dof) {
            return Err(MappingError::InvalidOption("gate_chi2_1dof"));
        }
        if !pos(self.max_range_m) {
            return Err(MappingError::InvalidOption("max_range_m"));
        }
        if !(self.min_init_parallax_rad >= 0.0 && self.min_init_parallax_rad < 1.5) {
            return Err(MappingError::InvalidOption("min_init_parallax_rad"));
        }
        if self.tentative_timeout_s.is_nan() || self.tentative_timeout_s < 0.0 {
            return Err(MappingError::InvalidOption("tentative_timeout_s"));
        }
        if self.min_landmark_rays < 2 {
            return Err(MappingError::InvalidOption("min_landmark_rays"));
        }
        Ok(())
    }
}

/// The tentative-track gate compares a new ray with at most this many of the track's latest
/// rays.
pub const MAX_PAIRWISE_RAYS: usize = 16;

/// Where an observation came from: (frame number in the order added, index in the frame).
pub(crate) type ObservationSource = (usize, usize);

/// One track: a tentative or confirmed landmark.
#[derive(Clone, Debug)]
struct Track {
    id: u64,
    class: Option<u32>,
    rays: Vec<MapRay>,
    /// The isotropic noise approximation of each ray (for gating).
    effective: Vec<RayObservation>,
    /// The [`PoseSpread`] of each ray (for the cheap gate bounds).
    spreads: Vec<PoseSpread>,
    sources: Vec<ObservationSource>,
    sum: RaySum,
    estimate: Option<TriangulatedPoint>,
    last_seen_s: f64,
    /// Running sum of the rays' pose position covariances (the pose-correlation floor of
    /// [`NearbySurrogate`] is its mean).
    floor_sum: Matrix3<f64>,
    /// The last [`refine_landmark`] of the track and the number of rays it used (rays are
    /// only ever appended, so it stays valid until the track gains a ray).
    refined: Option<(usize, Option<TriangulatedPoint>)>,
    /// The direction making the largest angle with the first ray's, and its cosine (as
    /// [`refine_landmark`] finds it, so the parallax criterion is checked before refining).
    far: (f64, Vector3<f64>),
}

impl Track {
    /// The track's landmark and refined point when its running estimate lies within
    /// `radius_m` of `position_in_world`, its parallax reaches `min_parallax_rad` and its
    /// rays meet at one point; `None` otherwise. The refinement is kept until the track
    /// gains a ray.
    fn refined_within(
        &mut self,
        position_in_world: &Vector3<f64>,
        radius_m: f64,
        min_parallax_rad: f64,
    ) -> Option<(MappedLandmark, TriangulatedPoint)> {
        let running = self.estimate.as_ref()?;
        if (running.point - position_in_world).norm() > radius_m {
            return None;
        }
        // The parallax criterion does not need the refinement (same rays, same formula as
        // `TriangulatedPoint::max_parallax_rad`).
        let u0 = self.rays.first()?.ray.direction;
        let parallax = u0.cross(&self.far.1).norm().atan2(u0.dot(&self.far.1));
        if parallax.is_nan() || parallax < min_parallax_rad {
            return None;
        }
        let n_rays = self.rays.len();
        let e = match &self.refined {
            Some((n, e)) if *n == n_rays => (*e)?,
            _ => {
                // A track whose rays do not meet at one point (rays of different landmarks
                // or false detections joined while the gates were wide) is no surrogate:
                // its refinement is not kept.
                let e = refine_landmark(&self.rays)
                    .ok()
                    .filter(|e| rays_consistent(&self.rays, &e.point));
                self.refined = Some((n_rays, e));
                e?
            }
        };
        Some((self.mapped(&e), e))
    }

    /// The mapped landmark of this track, refined to `e`.
    fn mapped(&self, e: &TriangulatedPoint) -> MappedLandmark {
        MappedLandmark {
            id: self.id,
            position_enu: e.point,
            covariance: e.covariance,
            n_obs: e.n_obs,
            max_parallax_rad: e.max_parallax_rad(),
            class: self.class,
        }
    }

    fn new(
        id: u64,
        class: Option<u32>,
        ray: MapRay,
        eff: RayObservation,
        source: ObservationSource,
        t: f64,
        floor: &Matrix3<f64>,
    ) -> Result<Self, TriangulationError> {
        let mut sum = RaySum::new();
        sum.add(&eff)?;
        Ok(Self {
            id,
            class,
            rays: vec![ray],
            effective: vec![eff],
            spreads: vec![PoseSpread::of(&ray)],
            sources: vec![source],
            sum,
            estimate: None,
            last_seen_s: t,
            floor_sum: *floor,
            refined: None,
            far: (1.0, ray.ray.direction),
        })
    }

    /// Adds a ray (its frame's pose-correlation floor contribution `floor`), then updates
    /// (or tries to initialise) the estimate.
    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        ray: MapRay,
        eff: RayObservation,
        source: ObservationSource,
        t: f64,
        min_parallax: f64,
        max_range_m: f64,
        floor: &Matrix3<f64>,
    ) -> Result<(), TriangulationError> {
        self.sum.add(&eff)?;
        self.floor_sum += floor;
        if let Some(first) = self.rays.first() {
            let cos = ray.ray.direction.dot(&first.ray.direction);
            if cos < self.far.0 {
                self.far = (cos, ray.ray.direction);
            }
        }
        self.rays.push(ray);
        self.effective.push(eff);
        self.spreads.push(PoseSpread::of(&ray));
        self.sources.push(source);
        self.last_seen_s = t;
        if self.estimate.is_some() {
            if let Ok(e) = self.sum.solve() {
                self.estimate = Some(e);
            }
            return Ok(());
        }
        let Some(first) = self.rays.first() else {
            return Ok(());
        };
        let initialised = match intersect_two_rays(&first.ray, &ray.ray) {
            Ok(hit) => {
                hit.parallax_rad()
                    .min(std::f64::consts::PI - hit.parallax_rad())
                    >= min_parallax
            }
            Err(_) => false,
        };
        if initialised
            && let Ok(e) = self.sum.solve()
            && self.rays.iter().all(|r| {
                let range = (e.point - r.ray.origin).dot(&r.ray.direction);
                range > 0.0 && range <= max_range_m
            })
            && e.covariance.symmetric_eigenvalues().max().max(0.0).sqrt()
                <= MAX_INIT_RELATIVE_SIGMA * (e.point - ray.ray.origin).norm()
        {
            self.estimate = Some(e);
        }
        Ok(())
    }
}

/// Ku, Ho & Sarma's online landmark mapper (O(n·k) association per frame).
///
/// Feed frames in time order with [`add_frame`](Self::add_frame); read the refined
/// landmarks with [`landmarks`](Self::landmarks) and the surrogates with
/// [`surrogates`](Self::surrogates).
///
/// # Association
/// For each new ray (origin `x`, unit direction `u`, isotropic noise `σ_pos`, `σ_ang` from
/// [`MapRay::effective_observation`]) and each track of the same class within
/// `max_range_m` of the rig:
/// - a track with an estimate `p̂`, `Σ̂` (its rays' projector sum, [`RaySum`]): with `E` two
///   unit vectors perpendicular to `u` and `r = p̂ − x` (in front, `u·r ∈ (0, max_range]`),
///   `m = (Eᵀr)ᵀ [Eᵀ(Σ̂ + (σ_pos² + σ_ang²|r|²) I)E]⁻¹ (Eᵀr) ≤ gate_chi2_2dof`;
/// - a track without one (one ray, or rays without enough parallax): the gap `g` between
///   the new ray and each of the track's last [`MAX_PAIRWISE_RAYS`] rays (the largest `m`
///   counts), both taken as segments from the camera to `max_range_m`,
///   over its variance along the gap (full residual covariances at the closest points):
///   `m = g² / var ≤ gate_chi2_1dof`.
///
/// The pairs that pass are assigned greedily, tracks with an estimate first (a ray that fits
/// an established landmark is not given to a tentative track that happens to lie on the
/// same line of sight), then by increasing `m`, one to one (a frame cannot
/// see one landmark twice); an unassigned ray starts a tentative track. A track is
/// initialised when its first ray and a new ray intersect in front of both with parallax
/// ≥ `min_init_parallax_rad` and the projector sum of its rays is determined to
/// [`MAX_INIT_RELATIVE_SIGMA`] of its range (worst-axis σ), in front of every ray within
/// `max_range_m`; from then on it follows the projector sum of all its rays.
/// Tracks unseen for `tentative_timeout_s` with fewer than `min_landmark_rays` rays are
/// dropped.
///
/// # Example
/// ```
/// use nalgebra::{Matrix6, Point3, Translation3, UnitQuaternion, Vector3};
/// use vgps_geometry::geometry::{Pose, Ray};
/// use vgps_core::mapping::{LandmarkMapper, MapperOptions, MappingFrame, RigObservation};
/// let lamp = Vector3::new(15.0, -6.0, 7.0);
/// let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
/// let cov = Matrix6::from_diagonal_element(1e-4);
/// for k in 0..20 {
///     let pose = Pose::from_parts(Translation3::new(k as f64, 0.0, 2.0), UnitQuaternion::identity().into());
///     let in_rig = pose.inverse() * Point3::from(lamp);
///     let observations = vec![RigObservation {
///         ray_in_rig: Ray::try_new(Vector3::zeros(), in_rig.coords).unwrap(),
///         sigma_rad: 1e-3,
///         class: None,
///     }];
///     let frame = MappingFrame { time_s: 0.1 * k as f64, world_from_rig: pose, pose_covariance: cov, observations };
///     mapper.add_frame(&frame).unwrap();
/// }
/// let landmarks = mapper.landmarks();
/// assert_eq!(landmarks.len(), 1);
/// assert_eq!(landmarks[0].n_obs, 20);
/// assert!((landmarks[0].position_enu - lamp).norm() < 1e-6);
/// assert_eq!(mapper.surrogates().len(), 1);
/// ```
///
/// # References
/// - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", §II-E.
#[derive(Clone, Debug)]
pub struct LandmarkMapper {
    options: MapperOptions,
    tracks: Vec<Track>,
    next_id: u64,
    frames_added: usize,
}

impl LandmarkMapper {
    /// An empty mapper.
    ///
    /// # Errors
    /// [`MappingError::InvalidOption`] for a non-positive gate or range, a negative time-out,
    /// a parallax outside `[0, 1.5)` rad, or `min_landmark_rays < 2`.
    pub fn new(options: MapperOptions) -> Result<Self, MappingError> {
        options.validate()?;
        Ok(Self {
            options,
            tracks: Vec::new(),
            next_id: 0,
            frames_added: 0,
        })
    }

    /// The options in use.
    pub fn options(&self) -> &MapperOptions {
        &self.options
    }

    /// Number of tracks (tentative and confirmed).
    pub fn track_count(&self) -> usize {
        self.tracks.len()
    }

    /// Number of frames added.
    pub fn frames_added(&self) -> usize {
        self.frames_added
    }

    /// Associates the observations of one frame and updates the tracks. Returns, per
    /// observation, the id of the track it joined or started.
    ///
    /// # Errors
    /// [`MappingError::InvalidPose`] / [`MappingError::InvalidObservation`] (with `frame` =
    /// the number of frames added before); the mapper is then unchanged.
    pub fn add_frame(&mut self, frame: &MappingFrame) -> Result<Vec<u64>, MappingError> {
        let shared = frame.pose_covariance.fixed_view::<3, 3>(0, 0).into_owned();
        self.add_frame_with_shared(frame, &shared)
    }

    /// [`add_frame`](Self::add_frame) for a frame whose pose error is partly shared with
    /// other frames: `frame.pose_covariance` is the part independent from frame to frame
    /// (used by the gates, the refinement and the consistency test of a surrogate), and
    /// `shared_position_covariance` (m², world) the position error the frame shares with the
    /// others (what a common drift moves every pose by; it goes into the surrogates'
    /// pose-correlation floor, [`NearbySurrogate::pose_floor_covariance`]). A localizer
    /// fixing from surrogates has such poses: treating their common drift as independent
    /// noise widens every gate by it, and rays of different landmarks then join one track.
    ///
    /// Long (about 200 lines) for a reason: gating, the assignment by priority and the
    /// validation all run before the first change to the mapper, so that an error leaves it
    /// unchanged; one body keeps that order plain.
    ///
    /// # Errors
    /// As [`add_frame`](Self::add_frame); also [`MappingError::InvalidPose`] for a
    /// non-finite shared covariance.
    pub fn add_frame_with_shared(
        &mut self,
        frame: &MappingFrame,
        shared_position_covariance: &Matrix3<f64>,
    ) -> Result<Vec<u64>, MappingError> {
        let frame_index = self.frames_added;
        frame.validate(frame_index)?;
        if !shared_position_covariance.iter().all(|v| v.is_finite()) {
            return Err(MappingError::InvalidPose { frame: frame_index });
        }
        let floor = *shared_position_covariance;
        let rig_origin = frame.world_from_rig.translation.vector;
        let rays: Vec<MapRay> = frame
            .observations
            .iter()
            .map(|o| {
                MapRay::from_rig(
                    &frame.world_from_rig,
                    &frame.pose_covariance,
                    &o.ray_in_rig,
                    o.sigma_rad,
                )
            })
            .collect();
        let effective: Vec<RayObservation> =
            rays.iter().map(MapRay::effective_observation).collect();
        let spreads: Vec<PoseSpread> = rays.iter().map(PoseSpread::of).collect();
        let opts = self.options;
        // The directions, contiguous, for the cone pre-filters below, and the frame's largest
        // noise terms (every bound of the gates holds with them).
        let directions: Vec<Vector3<f64>> = rays.iter().map(|r| r.ray.direction).collect();
        let frame_spread = FrameSpread::of(&rays, &spreads);
        let near = MIN_RANGE_M.min(0.5 * opts.max_range_m);
        let by_azimuth = AzimuthIndex::new(&directions);
        // (priority: 0 = track with an estimate, 1 = tentative; m; observation; track)
        let mut candidates: Vec<(u8, f64, usize, usize)> = Vec::new();
        for (ti, track) in self.tracks.iter().enumerate() {
            match &track.estimate {
                Some(est) => {
                    let lever = (est.point - rig_origin).norm();
                    if lever > opts.max_range_m * 1.5 {
                        continue;
                    }
                    let est_trace = est.covariance.trace().max(0.0);
                    let cone = DirectionCone::around_estimate(
                        &est.point,
                        est_trace,
                        &rig_origin,
                        lever,
                        &frame_spread,
                        &opts,
                    );
                    for range in by_azimuth.window(&cone) {
                        for &k in &by_azimuth.order[range] {
                            let (o, ray) = (&frame.observations[k], &rays[k]);
                            if !cone.admits(&directions[k]) || !classes_match(track.class, o.class)
                            {
                                continue;
                            }
                            if let Some(m) = gate_estimate(
                                est,
                                est_trace,
                                ray,
                                &spreads[k],
                                opts.max_range_m,
                                opts.gate_chi2_2dof,
                            ) && m <= opts.gate_chi2_2dof
                            {
                                candidates.push((0, m, k, ti));
                            }
                        }
                    }
                }
                None => {
                    let Some(last) = track.rays.last() else {
                        continue;
                    };
                    if (last.ray.origin - rig_origin).norm() > 2.0 * opts.max_range_m {
                        continue;
                    }
                    // The gate below starts with the last ray, and a ray that fails it is not
                    // a candidate: only the directions that can pass it are gated.
                    let last_spread = track.spreads.last().copied().unwrap_or(PoseSpread {
                        pos: f64::INFINITY,
                        rot: f64::INFINITY,
                        offset: f64::INFINITY,
                    });
                    let cone = DirectionCone::around_segment(
                        last,
                        &last_spread,
                        &rig_origin,
                        near,
                        &frame_spread,
                        &opts,
                    );
                    // The new ray must pass near every recent ray of the track.
                    let start = track.rays.len().saturating_sub(MAX_PAIRWISE_RAYS);
                    for range in by_azimuth.window(&cone) {
                        for &k in &by_azimuth.order[range] {
                            let (o, ray) = (&frame.observations[k], &rays[k]);
                            if !cone.admits(&directions[k]) || !classes_match(track.class, o.class)
                            {
                                continue;
                            }
                            // Most recent first; stop at the first ray that fails the gate.
                            let mut worst = Some(0.0f64);
                            for (r, rs) in track.rays[start..]
                                .iter()
                                .zip(&track.spreads[start..])
                                .rev()
                            {
                                match gate_two_rays(r, rs, ray, &spreads[k], &opts) {
                                    Some(m) if m <= opts.gate_chi2_1dof => {
                                        worst = worst.map(|w| w.max(m));
                                    }
                                    _ => {
                                        worst = None;
                                        break;
                                    }
                                }
                            }
                            if let Some(m) = worst
                                && m <= opts.gate_chi2_1dof
                            {
                                candidates.push((1, m, k, ti));
                            }
                        }
                    }
                }
            }
        }
        // By priority and m; ties in (track, observation) order, so that the assignment does
        // not depend on the order the windows gave the pairs in.
        candidates.sort_unstable_by(|a, b| {
            a.0.cmp(&b.0)
                .then(a.1.total_cmp(&b.1))
                .then(a.3.cmp(&b.3))
                .then(a.2.cmp(&b.2))
        });
        let mut obs_track: Vec<Option<usize>> = vec![None; rays.len()];
        let mut track_used = vec![false; self.tracks.len()];
        for &(_, _, k, ti) in &candidates {
            if obs_track[k].is_none() && !track_used[ti] {
                obs_track[k] = Some(ti);
                track_used[ti] = true;
            }
        }
        // Validate before mutating: every effective observation must be accepted by RaySum.
        for (k, eff) in effective.iter().enumerate() {
            RaySum::new()
                .add(eff)
                .map_err(|_| MappingError::InvalidObservation {
                    frame: frame_index,
                    observation: k,
                    reason: "ray rejected by the accumulator",
                })?;
        }
        let mut ids = Vec::with_capacity(rays.len());
        for (k, ((ray, eff), assigned)) in rays.iter().zip(&effective).zip(&obs_track).enumerate() {
            let source = (frame_index, k);
            match assigned {
                Some(ti) => {
                    let track = &mut self.tracks[*ti];
                    // Validated above: cannot fail.
                    let _ = track.add(
                        *ray,
                        *eff,
                        source,
                        frame.time_s,
                        opts.min_init_parallax_rad,
                        opts.max_range_m,
                        &floor,
                    );
                    ids.push(track.id);
                }
                None => {
                    let id = self.next_id;
                    self.next_id += 1;
                    if let Ok(t) = Track::new(
                        id,
                        frame.observations[k].class,
                        *ray,
                        *eff,
                        source,
                        frame.time_s,
                        &floor,
                    ) {
                        self.tracks.push(t);
                    }
                    ids.push(id);
                }
            }
        }
        let now = frame.time_s;
        self.tracks.retain(|t| {
            t.rays.len() >= opts.min_landmark_rays
                || (now - t.last_seen_s).abs() <= opts.tentative_timeout_s
        });
        self.frames_added += 1;
        Ok(ids)
    }

    /// The refined landmarks: every track with an estimate and at least `min_landmark_rays`
    /// rays, refined by [`refine_landmark`] (tracks whose refinement fails are left out).
    pub fn landmarks(&self) -> Vec<MappedLandmark> {
        self.refined_tracks().map(|(t, e)| t.mapped(&e)).collect()
    }

    /// Every track with an estimate and at least `min_landmark_rays` rays, with its
    /// refinement (tracks whose refinement fails are left out).
    fn refined_tracks(&self) -> impl Iterator<Item = (&Track, TriangulatedPoint)> {
        self.tracks
            .iter()
            .filter(|t| t.estimate.is_some() && t.rays.len() >= self.options.min_landmark_rays)
            .filter_map(|t| Some((t, refine_landmark(&t.rays).ok()?)))
    }

    /// The landmarks that meet the surrogate criteria of the options (refined, with
    /// position, covariance and number of rays): the secondary landmarks the localizer may
    /// use, weighted by their covariance, when primary landmarks are occluded.
    ///
    /// A track whose rays do not meet at one point within their independent noise (mean
    /// squared normalised residual above [`MAX_SURROGATE_MEAN_CHI2`]: rays of different
    /// landmarks or false detections joined into one track) is no surrogate.
    pub fn surrogates(&self) -> Vec<MappedLandmark> {
        let c = self.options.surrogate;
        self.refined_tracks()
            .filter(|(t, e)| rays_consistent(&t.rays, &e.point))
            .map(|(t, e)| t.mapped(&e))
            .filter(|l| c.accepts(l))
            .collect()
    }

    /// The surrogates within `radius_m` of `position_in_world` (selected by each track's
    /// running estimate, then refined by [`refine_landmark`]), with the pose-correlation
    /// floor of each (see [`NearbySurrogate`]). A track's refinement is kept until it gains a
    /// ray, so calling this every few frames only refines the tracks that changed.
    pub fn surrogates_near(
        &mut self,
        position_in_world: &Vector3<f64>,
        radius_m: f64,
    ) -> Vec<NearbySurrogate> {
        let c = self.options.surrogate;
        let min_rays = c.min_rays.max(self.options.min_landmark_rays);
        self.tracks
            .iter_mut()
            .filter(|t| t.rays.len() >= min_rays)
            .filter_map(|t| {
                let (landmark, _) =
                    t.refined_within(position_in_world, radius_m, c.min_parallax_rad)?;
                if !c.accepts(&landmark) {
                    return None;
                }
                let pose_floor_covariance = t.floor_sum / landmark.n_obs as f64;
                Some(NearbySurrogate {
                    landmark,
                    pose_floor_covariance,
                })
            })
            .collect()
    }

    /// Lamps seen ahead: tracks within `radius_m` of `position_in_world` that the surrogate
    /// criteria refuse but that are placed well enough *as seen from there* — with the
    /// criteria's rays, [`MapperOptions::min_init_parallax_rad`], consistent rays, and an
    /// error across the line of sight plus along it times `min(1, travel_m / range)`
    /// ([`seen_covariance`]) whose worst σ is within the criteria's σ cap. From a rig that
    /// moves `travel_m` before it looks again, an error along the line of sight turns the
    /// direction to the lamp by at most that share of it.
    pub fn surrogates_seen_from(
        &mut self,
        position_in_world: &Vector3<f64>,
        radius_m: f64,
        travel_m: f64,
    ) -> Vec<SeenAhead> {
        let c = self.options.surrogate;
        let min_rays = c.min_rays.max(self.options.min_landmark_rays);
        let min_parallax = self.options.min_init_parallax_rad;
        self.tracks
            .iter_mut()
            .filter(|t| t.rays.len() >= min_rays)
            .filter_map(|t| {
                let (landmark, e) = t.refined_within(position_in_world, radius_m, min_parallax)?;
                if c.accepts(&landmark) {
                    // A surrogate already ([`Self::surrogates_near`]).
                    return None;
                }
                let seen_covariance =
                    seen_covariance(&e.covariance, &(e.point - position_in_world), travel_m);
                let seen_sigma_m = seen_covariance
                    .symmetric_eigenvalues()
                    .max()
                    .max(0.0)
                    .sqrt();
                if seen_sigma_m.is_nan() || seen_sigma_m > c.max_sigma_m {
                    return None;
                }
                let pose_floor_covariance = t.floor_sum / landmark.n_obs as f64;
                Some(SeenAhead {
                    surrogate: NearbySurrogate {
                        landmark,
                        pose_floor_covariance,
                    },
                    seen_sigma_m,
                    seen_covariance,
                })
            })
            .collect()
    }

    /// The sources `(frame number, observation index)` of every reported landmark's rays,
    /// keyed by landmark id.
    pub fn associations(&self) -> Vec<(u64, Vec<(usize, usize)>)> {
        self.tracks
            .iter()
            .filter(|t| t.estimate.is_some() && t.rays.len() >= self.options.min_landmark_rays)
            .map(|t| (t.id, t.sources.clone()))
            .collect()
    }
}

/// Mean squared normalised residual (per ray, 2 degrees of freedom: expected 2) above which
/// a track's rays are taken not to meet at one point, and the track is no surrogate. The
/// rays' residual covariances hold only the part of the pose errors that is independent from
/// frame to frame (a drift shared by every pose moves the landmark, not the residuals).
pub const MAX_SURROGATE_MEAN_CHI2: f64 = 4.0;

/// True when the rays' mean squared normalised residual at `point` is at most
/// [`MAX_SURROGATE_MEAN_CHI2`] (see [`super::ray_chi2`]); a ray whose residual covariance
/// cannot be inverted makes the track inconsistent.
pub(crate) fn rays_consistent(rays: &[MapRay], point: &Vector3<f64>) -> bool {
    if rays.is_empty() {
        return false;
    }
    let mut sum = 0.0;
    for r in rays {
        match super::ray_chi2(r, point) {
            Some(c) if c.is_finite() => sum += c,
            _ => return false,
        }
    }
    sum / rays.len() as f64 <= MAX_SURROGATE_MEAN_CHI2
}

/// A surrogate near a position, for the localizer.
#[derive(Clone, Debug, PartialEq)]
pub struct NearbySurrogate {
    /// The landmark (running estimate of its track).
    pub landmark: MappedLandmark,
    /// Mean position covariance of the poses its rays were seen from (m²): the part of its
    /// error that does not average out over its rays when those poses' errors are
    /// correlated — as they are along a stretch fixed from surrogates alone, where every
    /// pose inherits the same drift. Add it to `landmark.covariance` for an honest bound.
    pub pose_floor_covariance: Matrix3<f64>,
}

/// A lamp seen ahead ([`LandmarkMapper::surrogates_seen_from`]): a track the surrogate
/// criteria refuse, with its covariance as seen from the rig.
#[derive(Clone, Debug, PartialEq)]
pub struct SeenAhead {
    /// The track's landmark and pose floor, as for a surrogate.
    pub surrogate: NearbySurrogate,
    /// Worst σ of [`Self::seen_covariance`] (metres).
    pub seen_sigma_m: f64,
    /// The landmark's covariance as seen from the rig ([`seen_covariance`], m²).
    pub seen_covariance: Matrix3<f64>,
}

/// The square roots of the traces of a ray's pose position and attitude covariances, for
/// the gates' cheap bound on the ray's residual variance in any direction.
#[derive(Clone, Copy, Debug)]
struct PoseSpread {
    /// `√tr Σ_pp` (metres).
    pos: f64,
    /// `√tr Σ_θθ` (radians).
    rot: f64,
    /// Distance of the camera from the rig origin (metres).
    offset: f64,
}

impl PoseSpread {
    fn of(ray: &MapRay) -> Self {
        let c = &ray.pose_covariance;
        Self {
            pos: (c[(0, 0)] + c[(1, 1)] + c[(2, 2)]).max(0.0).sqrt(),
            rot: (c[(3, 3)] + c[(4, 4)] + c[(5, 5)]).max(0.0).sqrt(),
            offset: (ray.ray.origin - ray.rig_origin).norm(),
        }
    }

    /// `(√tr Σ_pp + lever·√tr Σ_θθ)² + (range·σ_cam)²`: an upper bound on the residual
    /// variance of the ray in any direction at a point `lever` from the rig origin and
    /// `range` from the camera.
    #[inline]
    fn variance_bound(&self, lever: f64, range: f64, sigma_rad: f64) -> f64 {
        (self.pos + lever * self.rot).powi(2) + (range * sigma_rad).powi(2)
    }
}

/// The largest noise terms of one frame's rays: with them, [`PoseSpread::variance_bound`]
/// bounds the residual variance of every ray of the frame.
#[derive(Clone, Copy, Debug)]
struct FrameSpread {
    /// Largest `√tr Σ_pp` (metres).
    pos: f64,
    /// Largest `√tr Σ_θθ` (radians).
    rot: f64,
    /// Largest camera offset from the rig origin (metres).
    offset: f64,
    /// Largest camera bearing σ (radians).
    sigma_rad: f64,
}

impl FrameSpread {
    fn of(rays: &[MapRay], spreads: &[PoseSpread]) -> Self {
        let mut w = Self {
            pos: 0.0,
            rot: 0.0,
            offset: 0.0,
            sigma_rad: 0.0,
        };
        for (r, s) in rays.iter().zip(spreads) {
            w.pos = max_or_nan(w.pos, s.pos);
            w.rot = max_or_nan(w.rot, s.rot);
            w.offset = max_or_nan(w.offset, s.offset);
            w.sigma_rad = max_or_nan(w.sigma_rad, r.sigma_rad);
        }
        w
    }

    fn variance_bound(&self, lever: f64, range: f64) -> f64 {
        (self.pos + lever * self.rot).powi(2) + (range * self.sigma_rad).powi(2)
    }
}

/// Relative widening of the pre-filter cones (here and in the localizer's tracker), far
/// above rounding errors: the cones only skip pairs whose gate value is well beyond the gate.
pub(crate) const CONE_RELATIVE_MARGIN: f64 = 1e-3;
/// Absolute widening of the pre-filter cones (metres of radius, and cosine).
pub(crate) const CONE_ABSOLUTE_MARGIN: f64 = 1e-9;
/// Below this cosine of its half-angle a cone is not convex enough to help: no filter.
pub(crate) const CONE_MIN_COS: f64 = 0.05;

/// The larger of `a` and `b`, NaN when `b` is NaN: the largest noise term of a frame, so
/// that a NaN term makes the cone's bound NaN, which disables the cone.
#[inline]
pub(crate) fn max_or_nan(a: f64, b: f64) -> f64 {
    if b > a || b.is_nan() { b } else { a }
}

/// A cone of directions from the rig origin outside which a gate cannot pass: a conservative
/// pre-filter that skips (track, observation) pairs without changing the gates' results.
///
/// Both gates pass only when a point `q_x` of the new ray, in front of its camera `x`, lies
/// within `δ = √(gate · variance bound)` of the track (its estimate, or a segment of its
/// last ray). The point `q = t + (q_x − x)` on the parallel ray from the rig origin `t` is
/// then within `ρ = δ + |x − t|` of it, so the ray's direction lies in the cone from `t`
/// that contains the ball (or capsule) of radius `ρ` around the track.
#[derive(Clone, Copy, Debug)]
struct DirectionCone {
    /// Unit axis, or zero for the cone of every direction.
    axis: Vector3<f64>,
    /// Cosine of the half-angle (−∞ for every direction).
    min_cos: f64,
    /// Sine of the half-angle (widened like `min_cos`; ∞ for every direction).
    sin_half: f64,
}

impl DirectionCone {
    const ALL: Self = Self {
        axis: Vector3::new(0.0, 0.0, 0.0),
        min_cos: f64::NEG_INFINITY,
        sin_half: f64::INFINITY,
    };

    /// True when the unit direction `u` may pass the gate.
    #[inline]
    fn admits(&self, u: &Vector3<f64>) -> bool {
        u.dot(&self.axis) >= self.min_cos
    }

    /// The cone of [`gate_estimate`] for an estimate at `point`, `lever` from the rig origin.
    /// The ray's range to the point is at most `lever` + camera offset (and `max_range_m`).
    fn around_estimate(
        point: &Vector3<f64>,
        est_trace: f64,
        rig_origin: &Vector3<f64>,
        lever: f64,
        w: &FrameSpread,
        opts: &MapperOptions,
    ) -> Self {
        let range = (lever + w.offset).min(opts.max_range_m);
        let var = est_trace + w.variance_bound(lever, range);
        let rho = (opts.gate_chi2_2dof * var).sqrt() + w.offset;
        let rho = rho * (1.0 + CONE_RELATIVE_MARGIN) + CONE_ABSOLUTE_MARGIN;
        let k = rho / lever;
        if k.is_nan() || k >= 1.0 {
            return Self::ALL;
        }
        let min_cos = (1.0 - k * k).sqrt() - CONE_ABSOLUTE_MARGIN;
        if min_cos.is_nan() || min_cos <= CONE_MIN_COS {
            return Self::ALL;
        }
        Self {
            axis: (point - rig_origin) / lever,
            min_cos,
            sin_half: k + CONE_ABSOLUTE_MARGIN,
        }
    }

    /// The cone of [`gate_two_rays`] against the track ray `a` (its segment from `near` to
    /// `max_range_m` in front of its camera), for the rays of a frame with rig origin
    /// `rig_origin`. Both closest points are at most `max_range_m` from their cameras.
    fn around_segment(
        a: &MapRay,
        a_spread: &PoseSpread,
        rig_origin: &Vector3<f64>,
        near: f64,
        w: &FrameSpread,
        opts: &MapperOptions,
    ) -> Self {
        let l = opts.max_range_m;
        let var = a_spread.variance_bound(l + a_spread.offset, l, a.sigma_rad)
            + w.variance_bound(l + w.offset, l);
        let rho = (opts.gate_chi2_1dof * var).sqrt() + w.offset;
        let rho = rho * (1.0 + CONE_RELATIVE_MARGIN) + CONE_ABSOLUTE_MARGIN;
        let c1 = a.ray.at(near) - rig_origin;
        let c2 = a.ray.at(l) - rig_origin;
        let (d1, d2) = (c1.norm(), c2.norm());
        let (k1, k2) = (rho / d1, rho / d2);
        if !(k1 < 1.0 && k2 < 1.0) {
            return Self::ALL;
        }
        let (c1, c2) = (c1 / d1, c2 / d2);
        let sum = c1 + c2;
        let n = sum.norm();
        if n.is_nan() || n <= 0.5 {
            return Self::ALL;
        }
        let axis = sum / n;
        // Half the angle between the end directions, from the axis (sine from the cross
        // product: accurate for small angles).
        let cos_a = c1.dot(&axis);
        let sin_a = c1.cross(&axis).norm();
        // cos(α + asin k) for the larger k (the larger half-angle).
        let k = k1.max(k2);
        let cos_k = (1.0 - k * k).sqrt();
        let min_cos = cos_a * cos_k - sin_a * k - CONE_ABSOLUTE_MARGIN;
        if min_cos.is_nan() || min_cos <= CONE_MIN_COS {
            return Self::ALL;
        }
        Self {
            axis,
            min_cos,
            sin_half: sin_a * cos_k + cos_a * k + CONE_ABSOLUTE_MARGIN,
        }
    }
}

/// A monotonic stand-in for the azimuth `atan2(y, x)` of a horizontal direction, in
/// `[0, 4)` (0 along +x, 1 along +y, 2 along −x, 3 along −y); NaN for `(0, 0)`.
#[inline]
fn pseudo_azimuth(x: f64, y: f64) -> f64 {
    let p = x / (x.abs() + y.abs());
    if y < 0.0 { 3.0 + p } else { 1.0 - p }
}

/// Largest `sin Δ` of an azimuth window (`Δ` its half-width); wider cones scan everything.
const WINDOW_MAX_SIN: f64 = 0.95;

/// Number of azimuth buckets of an [`AzimuthIndex`] (over the 4 units of [`pseudo_azimuth`]).
const AZIMUTH_BUCKETS: usize = 64;

/// A frame's observations sorted by azimuth, so that a track only visits the observations
/// in the azimuth window of its [`DirectionCone`].
#[derive(Debug)]
struct AzimuthIndex {
    /// The observations by increasing [`pseudo_azimuth`], then those without an azimuth
    /// (straight up or down), which every window includes.
    order: Vec<usize>,
    /// Number of observations with an azimuth (the sorted part of `order`).
    n_sorted: usize,
    /// `bucket_start[b]`: the first position of `order` whose key is at least
    /// `4 b / AZIMUTH_BUCKETS`.
    bucket_start: [usize; AZIMUTH_BUCKETS + 1],
}

impl AzimuthIndex {
    fn new(directions: &[Vector3<f64>]) -> Self {
        let mut keyed = Vec::with_capacity(directions.len());
        let mut polar = Vec::new();
        for (k, u) in directions.iter().enumerate() {
            let key = pseudo_azimuth(u.x, u.y);
            if key.is_finite() {
                keyed.push((key, k));
            } else {
                polar.push(k);
            }
        }
        keyed.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut bucket_start = [keyed.len(); AZIMUTH_BUCKETS + 1];
        let mut b = 0;
        for (i, (key, _)) in keyed.iter().enumerate() {
            let kb = Self::bucket(*key);
            while b <= kb {
                bucket_start[b] = i;
                b += 1;
            }
        }
        let n_sorted = keyed.len();
        let mut order: Vec<usize> = keyed.into_iter().map(|e| e.1).collect();
        order.extend(polar);
        Self {
            order,
            n_sorted,
            bucket_start,
        }
    }

    /// The bucket of a key in `[0, 4)` (clamped).
    #[inline]
    fn bucket(key: f64) -> usize {
        // `as` saturates: negative keys go to bucket 0.
        ((key * (AZIMUTH_BUCKETS as f64 / 4.0)) as usize).min(AZIMUTH_BUCKETS - 1)
    }

    /// Ranges of `order` holding a superset of the observations whose direction is in
    /// `cone`: a cone of half-angle `β` around an axis at elevation `θ` spans the azimuths
    /// within `Δ = asin(sin β / cos θ)` of the axis's (when `β < 90° − |θ|`); whole buckets
    /// of that window are visited. Everything when the cone is too wide.
    #[inline]
    fn window(&self, cone: &DirectionCone) -> [Range<usize>; 3] {
        let all = [0..self.order.len(), 0..0, 0..0];
        let a = cone.axis;
        let h = (a.x * a.x + a.y * a.y).sqrt();
        let sin_d = cone.sin_half / h + CONE_ABSOLUTE_MARGIN;
        if sin_d.is_nan() || sin_d >= WINDOW_MAX_SIN {
            return all;
        }
        let cos_d = (1.0 - sin_d * sin_d).sqrt();
        let (hx, hy) = (a.x / h, a.y / h);
        let mut lo =
            pseudo_azimuth(hx * cos_d + hy * sin_d, hy * cos_d - hx * sin_d) - CONE_ABSOLUTE_MARGIN;
        let mut hi =
            pseudo_azimuth(hx * cos_d - hy * sin_d, hy * cos_d + hx * sin_d) + CONE_ABSOLUTE_MARGIN;
        if !(lo.is_finite() && hi.is_finite()) {
            return all;
        }
        if lo < 0.0 {
            lo += 4.0;
        }
        if hi >= 4.0 {
            hi -= 4.0;
        }
        let first = self.bucket_start[Self::bucket(lo)];
        let past = self.bucket_start[Self::bucket(hi) + 1];
        let polar = self.n_sorted..self.order.len();
        if lo <= hi {
            [first..past, polar, 0..0]
        } else {
            // The window wraps through azimuth 0.
            [first..self.n_sorted, 0..past, polar]
        }
    }
}

/// True when two optional class labels may belong to one landmark.
#[inline]
fn classes_match(a: Option<u32>, b: Option<u32>) -> bool {
    match (a, b) {
        (Some(x), Some(y)) => x == y,
        _ => true,
    }
}

/// Squared Mahalanobis distance of a landmark estimate from a ray (2 dof), or `None` when the
/// estimate is behind the ray or beyond `max_range_m`. The ray's own residual covariance is
/// the full propagation of [`super::ray_residual_covariance`].
#[inline]
fn gate_estimate(
    est: &TriangulatedPoint,
    est_trace: f64,
    ray: &MapRay,
    spread: &PoseSpread,
    max_range_m: f64,
    gate: f64,
) -> Option<f64> {
    let u = ray.ray.direction;
    let r = est.point - ray.ray.origin;
    let range = r.dot(&u);
    if !(range > 0.0 && range <= max_range_m) {
        return None;
    }
    // Cheap early rejection (as in `gate_two_rays`): with `tr Σ̂` plus the ray's variance
    // bound above every variance, `|r⊥|² / bound ≤ m`; beyond the gate, skip the exact form.
    let perp2 = (r - u * range).norm_squared();
    let lever = (est.point - ray.rig_origin).norm();
    let var_bound = est_trace + spread.variance_bound(lever, range, ray.sigma_rad);
    if perp2 > gate * var_bound {
        let m = perp2 / var_bound;
        return m.is_finite().then_some(m);
    }
    let (e1, e2) = tangent_basis(&u);
    let rv = Vector2::new(e1.dot(&r), e2.dot(&r));
    // Eᵀ (Σ̂ + S) E, with Eᵀ S E from the ray's residual covariance without forming it.
    let ce1: Vector3<f64> = est.covariance * e1;
    let ce2: Vector3<f64> = est.covariance * e2;
    let (s11, s12, s22) = ray_residual_tangent(ray, &est.point, &e1, &e2);
    let m12 = 0.5 * (e1.dot(&ce2) + e2.dot(&ce1)) + s12;
    let m = Matrix2::new(e1.dot(&ce1) + s11, m12, m12, e2.dot(&ce2) + s22);
    let inv = m.try_inverse()?;
    let d2 = rv.dot(&(inv * rv));
    d2.is_finite().then_some(d2)
}

/// Closest points `(s, t)` of the segments `a0 + s·u`, `b0 + t·v`, `s, t ∈ [0, len]`
/// (`u`, `v` unit), after Ericson, *Real-Time Collision Detection* §5.1.9.
fn closest_on_segments(
    a0: &Vector3<f64>,
    u: &Vector3<f64>,
    b0: &Vector3<f64>,
    v: &Vector3<f64>,
    len: f64,
) -> (f64, f64) {
    let r = a0 - b0;
    let b = u.dot(v);
    let c = u.dot(&r);
    let f = v.dot(&r);
    let denom = 1.0 - b * b;
    let mut s = if denom > 1e-12 {
        ((b * f - c) / denom).clamp(0.0, len)
    } else {
        0.0
    };
    let mut t = b * s + f;
    if t < 0.0 {
        t = 0.0;
        s = (-c).clamp(0.0, len);
    } else if t > len {
        t = len;
        s = (b * len - c).clamp(0.0, len);
    }
    (s, t)
}

/// The two-ray gate: squared gap between a track's last ray and a new ray, each taken as the
/// segment from [`MIN_RANGE_M`] to `max_range_m` in front of its camera, over its variance `ĝᵀ(S_a + S_b)ĝ`
/// along the gap `ĝ` (both residual covariances of [`super::ray_residual_covariance`] at the
/// closest points). Unlike a line intersection, this stays meaningful for nearly parallel
/// rays, whose noisy intersection can be anywhere along the line of sight.
#[inline]
fn gate_two_rays(
    a: &MapRay,
    a_spread: &PoseSpread,
    b: &MapRay,
    b_spread: &PoseSpread,
    opts: &MapperOptions,
) -> Option<f64> {
    let (u, v) = (a.ray.direction, b.ray.direction);
    let near = MIN_RANGE_M.min(0.5 * opts.max_range_m);
    let (a0, b0) = (a.ray.at(near), b.ray.at(near));
    let (s, t) = closest_on_segments(&a0, &u, &b0, &v, opts.max_range_m - near);
    let pa = a0 + u * s;
    let pb = b0 + v * t;
    let g = pa - pb;
    let gap2 = g.norm_squared();
    if gap2 == 0.0 {
        return Some(0.0);
    }
    // Cheap early rejection: an upper bound on each ray's residual variance along any
    // direction, `(√tr Σ_pp + r·√tr Σ_θθ)² + d²σ²` (r: lever arm from the rig, d: range),
    // gives a lower bound on `m`; when even that exceeds the gate, the exact variance is not
    // needed.
    // The closest points are `near + s` and `near + t` from the cameras (unit directions),
    // and the lever from the rig origin is at most that plus the camera offset: no square
    // root is needed for the bound.
    let bound = |ray: &MapRay, spread: &PoseSpread, d: f64| {
        spread.variance_bound(d + spread.offset, d, ray.sigma_rad)
    };
    let var_bound = bound(a, a_spread, near + s) + bound(b, b_spread, near + t);
    if gap2 > opts.gate_chi2_1dof * var_bound {
        let m = gap2 / var_bound;
        return m.is_finite().then_some(m);
    }
    let gap = gap2.sqrt();
    let gh = g / gap;
    let var = ray_residual_variance(a, &pa, &gh) + ray_residual_variance(b, &pb, &gh);
    let m = gap2 / var;
    m.is_finite().then_some(m)
}

#[cfg(test)]
mod cone_tests {
    use super::*;
    use nalgebra::{Matrix6, SMatrix};
    use rand::{Rng, RngExt};
    use vgps_geometry::geometry::Ray;
    use vgps_geometry::synthetic::{random_unit_vector, rng};

    /// A random pose covariance: position σ 1 cm – `max_m`, attitude σ 0.1 mrad – `max_rad`,
    /// correlated.
    fn pose_covariance<R: Rng + ?Sized>(r: &mut R, max_m: f64, max_rad: f64) -> Matrix6<f64> {
        let a = SMatrix::<f64, 6, 6>::from_fn(|_, _| r.random_range(-1.0..1.0));
        let (sp, sr) = (r.random_range(0.01..max_m), r.random_range(1e-4..max_rad));
        let d = Matrix6::from_diagonal(&nalgebra::Vector6::new(sp, sp, sp, sr, sr, sr));
        d * (a * a.transpose() / 6.0 + Matrix6::identity() * 0.1) * d
    }

    /// One frame: rays from cameras around `rig`, each aimed at `target` off by 0 to 4
    /// times `width(range)` (metres), or anywhere.
    fn frame_rays<R: Rng + ?Sized>(
        r: &mut R,
        rig: &Vector3<f64>,
        target: &Vector3<f64>,
        pose_covariance: Matrix6<f64>,
        width: impl Fn(f64) -> f64,
    ) -> Vec<MapRay> {
        (0..24)
            .map(|k| {
                let origin = rig + random_unit_vector(r) * r.random_range(0.0..0.3);
                let to = target - origin;
                let direction = if k % 6 == 5 {
                    random_unit_vector(r)
                } else {
                    let off = random_unit_vector(r) * (r.random_range(0.0..4.0) * width(to.norm()));
                    (to + off).normalize()
                };
                MapRay {
                    ray: Ray { origin, direction },
                    rig_origin: *rig,
                    pose_covariance,
                    sigma_rad: r.random_range(1e-4..3e-3),
                }
            })
            .collect()
    }

    /// The observations an [`AzimuthIndex`] window visits.
    fn visited(index: &AzimuthIndex, cone: &DirectionCone) -> Vec<usize> {
        index
            .window(cone)
            .into_iter()
            .flat_map(|range| index.order[range].iter().copied())
            .collect()
    }

    /// The estimate cone and its azimuth window never drop a pair that `gate_estimate`
    /// passes, and they drop most of the pairs it fails.
    #[test]
    fn estimate_cone_never_rejects_a_passing_pair() {
        let mut r = rng(0xc0e5);
        let opts = MapperOptions::default();
        let (mut passed, mut outside, mut dropped_outside) = (0, 0, 0);
        for _ in 0..1500 {
            let rig = Vector3::new(
                r.random_range(-50.0..50.0),
                r.random_range(-50.0..50.0),
                r.random_range(0.0..3.0),
            );
            let point = rig + random_unit_vector(&mut r) * r.random_range(1.0..140.0);
            let s = r.random_range(0.005..2.0);
            let c = pose_covariance(&mut r, 1.0, 0.02)
                .fixed_view::<3, 3>(0, 0)
                .into_owned()
                * (s * s);
            let est = TriangulatedPoint {
                point,
                covariance: c,
                n_obs: 5,
                max_parallax_sin_cos: (0.1, 1.0),
            };
            let est_trace = c.trace().max(0.0);
            let cov = pose_covariance(&mut r, 1.0, 0.02);
            let rays = frame_rays(&mut r, &rig, &point, cov, |range| {
                s * 4.0 + range * 0.01 + 0.5
            });
            let spreads: Vec<PoseSpread> = rays.iter().map(PoseSpread::of).collect();
            let w = FrameSpread::of(&rays, &spreads);
            let lever = (point - rig).norm();
            let cone = DirectionCone::around_estimate(&point, est_trace, &rig, lever, &w, &opts);
            let directions: Vec<_> = rays.iter().map(|x| x.ray.direction).collect();
            let index = AzimuthIndex::new(&directions);
            let seen = visited(&index, &cone);
            for (k, ray) in rays.iter().enumerate() {
                let kept = cone.admits(&ray.ray.direction) && seen.contains(&k);
                let m = gate_estimate(
                    &est,
                    est_trace,
                    ray,
                    &spreads[k],
                    opts.max_range_m,
                    opts.gate_chi2_2dof,
                );
                if m.is_some_and(|m| m <= opts.gate_chi2_2dof) {
                    passed += 1;
                    assert!(kept, "passing pair dropped: {ray:?} {est:?}");
                } else {
                    outside += 1;
                    dropped_outside += usize::from(!kept);
                }
            }
        }
        assert!(passed > 3000 && outside > 3000, "{passed} {outside}");
        assert!(
            dropped_outside * 2 > outside,
            "{dropped_outside} of {outside}"
        );
    }

    /// The segment cone and its azimuth window never drop a pair whose first gate
    /// (`gate_two_rays` against the track's last ray) passes, and drop a good part of
    /// the rays in random directions.
    #[test]
    fn segment_cone_never_rejects_a_passing_pair() {
        let mut r = rng(0x5e9);
        let opts = MapperOptions::default();
        let near = MIN_RANGE_M.min(0.5 * opts.max_range_m);
        let (mut passed, mut outside, mut dropped_outside) = (0, 0, 0);
        for _ in 0..1500 {
            let rig = Vector3::new(
                r.random_range(-50.0..50.0),
                r.random_range(-50.0..50.0),
                r.random_range(0.0..3.0),
            );
            // The track's last ray, seen from up to 5 m away (or, for narrow cones, 20 – 60 m
            // away), at a landmark 1.5 – 120 m off.
            let gap = if r.random_range(0.0..1.0) < 0.5 {
                r.random_range(0.0..5.0)
            } else {
                r.random_range(20.0..60.0)
            };
            let before = rig + random_unit_vector(&mut r) * gap;
            let landmark = rig + random_unit_vector(&mut r) * r.random_range(1.5..120.0);
            // Pose σ up to 20 cm and 2 mrad (a tracked drive).
            let cov = pose_covariance(&mut r, 0.2, 2e-3);
            let last = frame_rays(&mut r, &before, &landmark, cov, |_| 0.0)[0];
            let last_spread = PoseSpread::of(&last);
            let cov = pose_covariance(&mut r, 0.2, 2e-3);
            let mut rays = frame_rays(&mut r, &rig, &landmark, cov, |range| 0.2 + range * 0.01);
            // Half of the aimed rays at other points of the track's segment instead.
            for (k, ray) in rays.iter_mut().enumerate() {
                if k % 6 < 3 {
                    // Along the segment, or up to 3 m past either end.
                    let along = match k % 6 {
                        0 => r.random_range(near..opts.max_range_m),
                        1 => opts.max_range_m + r.random_range(0.0..3.0),
                        _ => near - r.random_range(0.0..3.0),
                    };
                    let target = last.ray.at(along);
                    let to = target - ray.ray.origin;
                    let off = random_unit_vector(&mut r)
                        * (r.random_range(0.0..4.0) * (0.2 + to.norm() * 0.01));
                    ray.ray.direction = (to + off).normalize();
                }
            }
            let spreads: Vec<PoseSpread> = rays.iter().map(PoseSpread::of).collect();
            let w = FrameSpread::of(&rays, &spreads);
            let cone = DirectionCone::around_segment(&last, &last_spread, &rig, near, &w, &opts);
            let directions: Vec<_> = rays.iter().map(|x| x.ray.direction).collect();
            let index = AzimuthIndex::new(&directions);
            let seen = visited(&index, &cone);
            for (k, ray) in rays.iter().enumerate() {
                let kept = cone.admits(&ray.ray.direction) && seen.contains(&k);
                let m = gate_two_rays(&last, &last_spread, ray, &spreads[k], &opts);
                if m.is_some_and(|m| m <= opts.gate_chi2_1dof) {
                    passed += 1;
                    assert!(kept, "passing pair dropped: {ray:?} {last:?}");
                } else if k % 6 == 5 {
                    // A ray in a random direction that fails the gate.
                    outside += 1;
                    dropped_outside += usize::from(!kept);
                }
            }
        }
        assert!(passed > 3000 && outside > 1000, "{passed} {outside}");
        // A segment from 1 m to 100 m in front of a camera a few metres away spans a wide
        // angle: about a third of the random directions fall outside its cone.
        assert!(
            dropped_outside * 4 > outside,
            "{dropped_outside} of {outside}"
        );
    }

    /// An azimuth window holds every direction of its cone, across the wrap at azimuth 0
    /// and near the poles.
    #[test]
    fn azimuth_window_holds_its_cone() {
        let mut r = rng(0xa21);
        for _ in 0..2000 {
            let directions: Vec<Vector3<f64>> =
                (0..40).map(|_| random_unit_vector(&mut r)).collect();
            let axis = random_unit_vector(&mut r);
            let half = r.random_range(0.0..1.2f64);
            let cone = DirectionCone {
                axis,
                min_cos: half.cos(),
                sin_half: half.sin(),
            };
            let index = AzimuthIndex::new(&directions);
            let seen = visited(&index, &cone);
            for (k, u) in directions.iter().enumerate() {
                if cone.admits(u) {
                    assert!(seen.contains(&k), "{u:?} {cone:?}");
                }
            }
        }
    }
}

/// The covariance `c` of a point as seen from `v` before it (`v` = point − rig) by a rig
/// that moves `travel_m` before it looks again: across the line of sight whole, along it
/// times `sin² δ`, `sin δ = min(1, travel / |v|)`: `P C P + sin²δ (uᵀCu) uuᵀ`, `u = v/|v|`,
/// `P = I − uuᵀ`. `c` itself for `v = 0`.
pub fn seen_covariance(c: &Matrix3<f64>, v: &Vector3<f64>, travel_m: f64) -> Matrix3<f64> {
    let range = v.norm();
    if range.is_nan() || range <= 0.0 {
        return *c;
    }
    let u = v / range;
    let p = Matrix3::identity() - u * u.transpose();
    let along = u.dot(&(c * u)).max(0.0);
    let sin = (travel_m / range).min(1.0);
    p * c * p + u * u.transpose() * (along * sin * sin)
}

#[cfg(test)]
mod seen_tests {
    use super::*;

    /// A point 40 m ahead (x), σ 2 m along the line of sight and 0.1 m across it.
    fn elongated() -> (Matrix3<f64>, Vector3<f64>) {
        (
            Matrix3::from_diagonal(&Vector3::new(4.0, 0.01, 0.01)),
            Vector3::new(40.0, 0.0, 0.0),
        )
    }

    #[test]
    fn the_seen_covariance_keeps_the_error_across_and_scales_the_error_along() {
        let (c, v) = elongated();
        // Not moving: only the error across the line of sight turns the direction.
        let still = seen_covariance(&c, &v, 0.0);
        assert!((still - Matrix3::from_diagonal(&Vector3::new(0.0, 0.01, 0.01))).norm() < 1e-12);
        // Moving 4 m (sin δ = 0.1): the error along counts for 0.1 of its σ.
        let moved = seen_covariance(&c, &v, 4.0);
        assert!((moved[(0, 0)] - 4.0 * 0.01).abs() < 1e-12);
        assert!((moved[(1, 1)] - 0.01).abs() < 1e-12);
        // Moving as far as the range or more: the whole covariance.
        assert!((seen_covariance(&c, &v, 40.0) - c).norm() < 1e-12);
        assert!((seen_covariance(&c, &v, 400.0) - c).norm() < 1e-12);
        // From the point itself: the whole covariance.
        assert_eq!(seen_covariance(&c, &Vector3::zeros(), 1.0), c);
        // Seen from the side (y), the 2 m error is across the line of sight: whole.
        let side = seen_covariance(&c, &Vector3::new(0.0, 40.0, 0.0), 0.0);
        assert!((side[(0, 0)] - 4.0).abs() < 1e-12);
        assert!(side[(1, 1)].abs() < 1e-12);
        // Symmetric positive semi-definite whatever the direction.
        let oblique = seen_covariance(&c, &Vector3::new(30.0, 20.0, 5.0), 3.0);
        assert!((oblique - oblique.transpose()).norm() < 1e-12);
        assert!(oblique.symmetric_eigenvalues().min() > -1e-12);
    }
}
