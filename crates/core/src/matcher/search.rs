//! The search loop behind [`super::match_detections`]: the checks of the input, the cells
//! with their candidates, and detection triples round by round, each solved by P3P for the
//! landmark triples its pair tables allow, the poses scored and kept, until the early stop
//! or the budget; then [`super::conclusion`].

use super::azimuth::{LevelledTriple, azimuths_can_meet};
use super::cells::cells;
use super::conclusion::conclude;
use super::pairs::{PairContext, cell_data};
use super::scoring::ConclusionCache;
use super::scratch::{Cells, SolvedTriples, shuffle};
use super::{
    CORE_GROWTH, DUPLICATE_ANGLE_RAD, Detection, HYPOTHESIS_THRESHOLD_FACTOR, LandmarkDb,
    MAX_CONFIRMATION_TRIPLES, MIN_TRIPLE_ANGLE_RAD, MatchError, MatchOptions, MatchResult,
    MatchStatus, STOP_CONFIRMATIONS, STOP_MIN_INLIER_FRACTION, SearchArea, UP_CHECK_MARGIN_RAD,
    keeps_vertical,
};
use nalgebra::{Matrix6, Vector3};
use rand::SeedableRng;
use vgps_geometry::geometry::{Pose, PoseSolutions, angle_between, try_unit};
use vgps_geometry::solvers::p3p::{P3pBearings, p3p_prepared_into};

/// One scored hypothesis.
#[derive(Clone)]
pub(super) struct KeptHypothesis {
    pub(super) pose: Pose,
    pub(super) inliers: usize,
    pub(super) cost: f64,
    /// The detection triples that confirmed the pose, pairwise disjoint (their number is the
    /// pose's confirmations).
    pub(super) confirming: Vec<[usize; 3]>,
    /// The detections the pose explains (at the hypothesis threshold), in index order: the
    /// pool of its confirmation triples ([`Search::confirmation_triples`]).
    pub(super) explained: Vec<usize>,
}

/// The message of [`MatchStatus::NoLandmarksInRange`].
pub(super) const NO_LANDMARKS_IN_RANGE: &str =
    "fewer than 3 landmarks within the visibility range of the search area";

/// The determinant of three unit bearings has a reliable sign when it exceeds this many
/// times the per-bearing noise bound (each bearing moves by at most the bound).
pub(super) const RELIABLE_DETERMINANT_NOISES: f64 = 3.0;

/// Cells sampled (evenly over the visiting order) to measure the cost of each detection
/// triple when no vertical is known ([`Search::order_by_sampled_cost`]).
pub(super) const COST_SAMPLE_CELLS: usize = 16;

/// Confirmation triples weighed by their sampled cost when no vertical is known (the
/// cheapest is run).
pub(super) const CONFIRMATION_CANDIDATES: usize = 24;

/// Initial capacity of the map of solved landmark triples (one detection triple's worth
/// over a prior; a cold start grows it).
pub(super) const SOLVED_TRIPLES_CAPACITY: usize = 1024;

pub(super) fn validate(detections: &[Detection], options: &MatchOptions) -> Result<(), MatchError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !positive(options.sigma_rad) {
        return Err(MatchError::InvalidOption("sigma_rad"));
    }
    if !positive(options.inlier_threshold_sigmas) {
        return Err(MatchError::InvalidOption("inlier_threshold_sigmas"));
    }
    if !positive(options.visibility_range_m) {
        return Err(MatchError::InvalidOption("visibility_range_m"));
    }
    if !positive(options.cell_size_m) {
        return Err(MatchError::InvalidOption("cell_size_m"));
    }
    if options.min_inliers < 4 {
        return Err(MatchError::InvalidOption("min_inliers"));
    }
    if options.ambiguity_margin < 1 {
        return Err(MatchError::InvalidOption("ambiguity_margin"));
    }
    if !(0.0..=1.0).contains(&options.min_link_probability) {
        return Err(MatchError::InvalidOption("min_link_probability"));
    }
    if options.max_false_alarms.is_nan() || options.max_false_alarms <= 0.0 {
        return Err(MatchError::InvalidOption("max_false_alarms"));
    }
    if options.max_rounds == 0 {
        return Err(MatchError::InvalidOption("max_rounds"));
    }
    if options.max_core_detections < 3 {
        return Err(MatchError::InvalidOption("max_core_detections"));
    }
    for (k, d) in detections.iter().enumerate() {
        if !vgps_geometry::geometry::is_finite(&d.ray.origin)
            || try_unit(&d.ray.direction).is_none()
        {
            return Err(MatchError::InvalidDetection(k));
        }
    }
    Ok(())
}

/// Up to `max` of the usable detections, greedily spread over the sphere (farthest-point
/// order). A detection is unusable when no candidate of any cell may be it (class, or
/// elevation when the vertical is known): e.g. a stray light below the horizon.
pub(super) fn core_detections(angles: &[f64], usable: &[bool], max: usize) -> Vec<usize> {
    let n = usable.len();
    let candidates: Vec<usize> = (0..n).filter(|&k| usable[k]).collect();
    if candidates.len() <= max {
        return candidates;
    }
    let first = candidates[0];
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = (0..n)
        .map(|k| {
            if usable[k] {
                angles[k * n + first]
            } else {
                f64::NEG_INFINITY
            }
        })
        .collect();
    while chosen.len() < max {
        let (next, _) = nearest
            .iter()
            .enumerate()
            .fold((first, 0.0), |b, (k, &a)| if a > b.1 { (k, a) } else { b });
        chosen.push(next);
        for (k, nearest) in nearest.iter_mut().enumerate() {
            *nearest = nearest.min(angles[k * n + next]);
        }
    }
    chosen
}

pub(super) struct Search<'a> {
    pub(super) db: &'a LandmarkDb,
    pub(super) detections: &'a [Detection],
    pub(super) directions: Vec<Vector3<f64>>,
    pub(super) options: &'a MatchOptions,
    /// Per-bearing noise bound k·σ (radians).
    pub(super) noise: f64,
    /// `cos(min(HYPOTHESIS_THRESHOLD_FACTOR · noise, π))`, the verification's test
    /// ([`Search::verify`]), once per frame.
    pub(super) cos_hypothesis_threshold: f64,
    pub(super) kept: Vec<KeptHypothesis>,
    pub(super) hypotheses: usize,
    /// Distinct P3P poses generated inside the area's reach, over every detection triple:
    /// the number of tests of the acceptance test ([`super::nfa`]).
    pub(super) pose_tests: usize,
    /// Scratch of [`Search::score`]: per landmark in range, its offset in the rig frame,
    /// index and range.
    pub(super) scratch_dirs: Vec<(Vector3<f64>, usize, f64)>,
    pub(super) scratch_best: Vec<(usize, f64)>,
    /// Scratch of [`Search::verify`]: per extension detection, its world direction and
    /// whether it has been seen.
    pub(super) scratch_extensions: Vec<(Vector3<f64>, bool)>,
    /// The angle between the bearings of each two detections, radians, `n × n`.
    pub(super) angles: Vec<f64>,
    /// The rig's up direction (unit, rig frame) and its tolerance (radians), when known.
    pub(super) up: Option<(Vector3<f64>, f64)>,
    /// The search area widened by the position margin of a P3P pose (its box, and a
    /// cylinder's radius): a fix must lie in it.
    pub(super) widened_area: SearchArea,
    /// Landmark sets, refinements and scratch kept for the conclusion.
    pub(super) conclusion: ConclusionCache,
    /// The bytes the cells may keep in pair values and tables ([`MatchOptions::cache_budget_bytes`]),
    /// what is left of it, the most held at once, and the cells stored and transient
    /// ([`super::pairs::CellCache`]).
    pub(super) cache_budget: usize,
    pub(super) cache_left: std::cell::Cell<usize>,
    pub(super) cache_peak: std::cell::Cell<usize>,
    pub(super) cache_stored: std::cell::Cell<usize>,
    pub(super) cache_transient: std::cell::Cell<usize>,
}

/// How a search used the cells' cache budget: the most bytes held at once, and the cells
/// that kept their caches and those that did not (at the end of the search).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct CacheUse {
    pub(super) peak_bytes: usize,
    pub(super) stored_cells: usize,
    pub(super) transient_cells: usize,
}

/// Whether `t` lies in the axis-aligned box `[min, max]` (bounds included).
pub(super) fn in_box(t: &Vector3<f64>, min: &Vector3<f64>, max: &Vector3<f64>) -> bool {
    (0..3).all(|a| t[a] >= min[a] && t[a] <= max[a])
}

/// The P3P poses of every landmark triple in `points` seen along `bearings` (`None`:
/// degenerate bearings, no pose) that pass `keep`, in `poses`, and each triple's range of
/// them (start, count) in `ranges`, in the order of `points`.
pub(super) fn solve_triples(
    bearings: Option<&P3pBearings>,
    points: &[[Vector3<f64>; 3]],
    keep: impl Fn(&Pose) -> bool,
    poses: &mut Vec<Pose>,
    ranges: &mut Vec<(usize, usize)>,
) {
    poses.clear();
    ranges.clear();
    let mut solutions = PoseSolutions::new();
    for triple in points {
        let start = poses.len();
        match bearings {
            Some(bearings) => p3p_prepared_into(bearings, triple, &mut solutions),
            None => solutions.clear(),
        }
        poses.extend(solutions.iter().filter(|pose| keep(pose)));
        ranges.push((start, poses.len() - start));
    }
}

/// The search: the cells and their candidates, then rounds of detection triples from a
/// growing core of the detections, until a triple's early-stop check concludes with a fix,
/// the budget of P3P solves is spent or the rounds end; then the conclusion.
pub(super) fn run(
    db: &LandmarkDb,
    detections: &[Detection],
    area: &SearchArea,
    options: &MatchOptions,
) -> Result<MatchResult, MatchError> {
    run_with_cache_budget(db, detections, area, options, options.cache_budget_bytes)
        .map(|(result, _)| result)
}

/// [`run`] with the cells' cache budget in bytes (the results do not depend on it), and how
/// the search used it.
pub(super) fn run_with_cache_budget(
    db: &LandmarkDb,
    detections: &[Detection],
    area: &SearchArea,
    options: &MatchOptions,
    cache_budget: usize,
) -> Result<(MatchResult, CacheUse), MatchError> {
    let unused = |result: MatchResult| Ok((result, CacheUse::default()));
    validate(detections, options)?;
    let n = detections.len();
    let (centres, shape) = cells(area, options.cell_size_m)?;
    if n < 3 {
        return unused(MatchResult::failed(
            MatchStatus::TooFewDetections,
            n,
            format!("{n} detections; a match needs at least 3"),
        ));
    }
    let directions: Vec<Vector3<f64>> = detections
        .iter()
        .filter_map(|d| try_unit(&d.ray.direction))
        .collect();
    let angles = bearing_angles(&directions);
    if let Some(failed) = duplicate_detections(&angles, n) {
        return unused(failed);
    }
    let up = known_up(options)?;
    known_heading(options)?;
    let mut search = Search::new(db, detections, directions, angles, up, area, options)
        .with_cache_budget(cache_budget);

    // Fewer than three landmarks within reach of the whole area: no cell to visit.
    let area_centre = area.center();
    let reach = area_reach(area, shape.radius, options);
    if reach.is_finite() {
        let mut near = Vec::new();
        db.within(&area_centre, reach, &mut near);
        if near.len() < 3 {
            return unused(MatchResult::failed(
                MatchStatus::NoLandmarksInRange,
                n,
                NO_LANDMARKS_IN_RANGE,
            ));
        }
    }
    // The cells with candidates, nearest to the area's centre first.
    let (mut cell_data, pair_context) = cell_data(&search, centres, &area_centre, reach, &shape);
    if cell_data.is_empty() {
        return unused(MatchResult::failed(
            MatchStatus::NoLandmarksInRange,
            n,
            NO_LANDMARKS_IN_RANGE,
        ));
    }
    let frame = SearchPlan::new(&search, &cell_data, area, shape.radius);
    let result = search.rounds(&mut cell_data, &pair_context, &frame);
    let cache_use = CacheUse {
        peak_bytes: search.cache_peak.get(),
        stored_cells: search.cache_stored.get(),
        transient_cells: search.cache_transient.get(),
    };
    Ok((result, cache_use))
}

/// The angles between the detections' bearings, `n × n`, radians: computed once (the pair
/// tables of every cell, the triples' spread and the core's order use them).
fn bearing_angles(directions: &[Vector3<f64>]) -> Vec<f64> {
    let n = directions.len();
    let mut angles = vec![0.0; n * n];
    for a in 0..n {
        for b in a + 1..n {
            let angle = angle_between(&directions[a], &directions[b]);
            angles[a * n + b] = angle;
            angles[b * n + a] = angle;
        }
    }
    angles
}

/// The failed result for two detections with the same bearing, if there are two.
fn duplicate_detections(angles: &[f64], n: usize) -> Option<MatchResult> {
    for a in 0..n {
        for b in a + 1..n {
            if angles[a * n + b] < DUPLICATE_ANGLE_RAD {
                return Some(MatchResult::failed(
                    MatchStatus::DuplicateDetections,
                    n,
                    format!("detections {a} and {b} have the same bearing"),
                ));
            }
        }
    }
    None
}

/// The rig's unit up and its tolerance, when the options give them.
fn known_up(options: &MatchOptions) -> Result<Option<(Vector3<f64>, f64)>, MatchError> {
    match options.up_in_rig {
        Some((u, tol)) => {
            let u = try_unit(&u).ok_or(MatchError::InvalidOption("up_in_rig"))?;
            if !(tol.is_finite() && tol >= 0.0) {
                return Err(MatchError::InvalidOption("up_in_rig"));
            }
            Ok(Some((u, tol)))
        }
        None => Ok(None),
    }
}

/// The known heading and its tolerance, when the options give them.
fn known_heading(options: &MatchOptions) -> Result<Option<(f64, f64)>, MatchError> {
    match options.heading_in_world {
        Some((h, tol)) if h.is_finite() && tol.is_finite() && tol >= 0.0 => Ok(Some((h, tol))),
        Some(_) => Err(MatchError::InvalidOption("heading_in_world")),
        None => Ok(None),
    }
}

/// Whether the heading of `pose` (its x axis' azimuth in the world) is within `limit` of
/// `heading` (radians). A pose whose x axis is vertical has no heading and is kept.
fn heading_within(pose: &Pose, heading: f64, limit: f64) -> bool {
    let x = pose.rotation * Vector3::x();
    if x.x.hypot(x.y) < 1e-9 {
        return true;
    }
    let d = (x.y.atan2(x.x) - heading).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d) <= limit
}

/// How far a P3P pose from noisy bearings may be from the truth (the bearing noise bound
/// at the visibility range, twice), metres.
fn position_margin(options: &MatchOptions) -> f64 {
    options.visibility_range_m * 2.0 * options.inlier_threshold_sigmas * options.sigma_rad
}

/// The distance from the area's centre within which every cell's candidates lie: the
/// farthest a point of the area is from its centre (half the box's diagonal, or less for a
/// cylinder), plus the cells' radius and the visibility range.
fn area_reach(area: &SearchArea, radius: f64, options: &MatchOptions) -> f64 {
    let half_box = 0.5 * (area.max_in_world - area.min_in_world).norm();
    let half_extent = area.horizontal_radius_m.map_or(half_box, |r| {
        half_box.min(r.hypot(0.5 * (area.max_in_world.z - area.min_in_world.z)))
    });
    half_extent + radius + options.visibility_range_m
}

/// Per detection, the (cell, candidate) pairs it may be: the size of its rows and columns
/// in the pair tables (0 for an unusable detection).
fn allowed_counts(cells: &Cells, n: usize) -> Vec<usize> {
    (0..n)
        .map(|d| {
            cells
                .iter()
                .map(|cell| {
                    cell.allowed[d * cell.words..(d + 1) * cell.words]
                        .iter()
                        .map(|w| w.count_ones() as usize)
                        .sum::<usize>()
                })
                .sum()
        })
        .collect()
}

/// What the rounds of a frame share: the detections' order and costs, and where a pose may
/// be.
struct SearchPlan {
    /// Per detection, the (cell, candidate) pairs it may be ([`allowed_counts`]).
    allowed_counts: Vec<usize>,
    /// The usable detections (those with a candidate somewhere).
    n_usable: usize,
    /// Every usable detection in farthest-point order; round `r` draws its triples from the
    /// first `max_core_detections · CORE_GROWTH^r` of them.
    order: Vec<usize>,
    /// The cells' ball radius, metres.
    radius: f64,
    /// How far from its cell's centre a pose of the cell may be, metres.
    cell_reach: f64,
    /// With a known vertical: the rig's up and the largest tilt of a pose worth keeping, the
    /// tolerance plus `UP_CHECK_MARGIN_RAD` (P3P's upright check, and the azimuth test).
    up_limit: Option<(Vector3<f64>, f64)>,
    /// With a known heading: the heading and the largest difference of a pose worth
    /// keeping (the tolerance plus `UP_CHECK_MARGIN_RAD`).
    heading_limit: Option<(f64, f64)>,
    /// The box a kept P3P pose lies in: the area with the cells' reach.
    reach_min: Vector3<f64>,
    reach_max: Vector3<f64>,
}

impl SearchPlan {
    fn new(search: &Search, cells: &Cells, area: &SearchArea, radius: f64) -> Self {
        let n = search.detections.len();
        let allowed_counts = allowed_counts(cells, n);
        let usable: Vec<bool> = allowed_counts.iter().map(|&c| c > 0).collect();
        let n_usable = usable.iter().filter(|&&u| u).count();
        let order = core_detections(&search.angles, &usable, n_usable);
        let position_margin = position_margin(search.options);
        Self {
            allowed_counts,
            n_usable,
            order,
            radius,
            cell_reach: radius + position_margin,
            up_limit: search.up.map(|(u, tol)| (u, tol + UP_CHECK_MARGIN_RAD)),
            heading_limit: search
                .options
                .heading_in_world
                .map(|(h, tol)| (h, tol + UP_CHECK_MARGIN_RAD)),
            reach_min: area.min_in_world.add_scalar(-(radius + position_margin)),
            reach_max: area.max_in_world.add_scalar(radius + position_margin),
        }
    }
}

/// The buffers of the detection triples of a frame, reused from triple to triple.
struct TripleWork {
    /// Landmark triples `(i, j, k)` of a cell that pass its three pair tables.
    survivors: Vec<[usize; 3]>,
    /// The three pair tables of a transient cell ([`Search::cell_survivors`]).
    scratch_tables: Vec<u64>,
    /// Per landmark triple of the current detection triple: its index in `to_solve` (and in
    /// `solved_ranges`). A detection triple solves about 700 distinct landmark triples over
    /// a 30 m prior: sized once, so that it does not grow by rehashing during the first
    /// triple.
    solved: SolvedTriples,
    /// The distinct landmark triples to solve (their points).
    to_solve: Vec<[Vector3<f64>; 3]>,
    /// The landmark triples of the cells in visiting order (cell, candidates, index into
    /// `to_solve`).
    work: Vec<(usize, [usize; 3], usize)>,
    /// The kept poses of every distinct landmark triple, and each one's range of them.
    solved_poses: Vec<Pose>,
    solved_ranges: Vec<(usize, usize)>,
    /// P3P solves so far (every hypothesis scored comes from one): the budget of the frame.
    solves: usize,
}

/// At most this many bytes of a frame's [`TripleWork`] buffers are kept per thread for the
/// next frame (8 MiB): a cold start's buffers can grow far larger and are freed.
pub(super) const MAX_POOLED_WORK_BYTES: usize = 1 << 23;

thread_local! {
    /// The [`TripleWork`] of this thread's last frame, whose buffers the next frame reuses
    /// instead of growing fresh ones (about 35 reallocations and their copies per prior
    /// frame, and the solved-triples map's allocation).
    static TRIPLE_WORK_POOL: std::cell::RefCell<Option<TripleWork>> =
        const { std::cell::RefCell::new(None) };
}

/// A frame's [`TripleWork`], from the thread's pool when it has one; its buffers go back to
/// the pool when the frame is done (if they are not too large).
struct PooledWork(TripleWork);

impl PooledWork {
    fn take() -> Self {
        let pooled = TRIPLE_WORK_POOL
            .try_with(|pool| pool.try_borrow_mut().ok().and_then(|mut p| p.take()))
            .ok()
            .flatten();
        Self(match pooled {
            Some(mut work) => {
                work.reset();
                work
            }
            None => TripleWork::new(),
        })
    }
}

impl Drop for PooledWork {
    fn drop(&mut self) {
        if self.0.held_bytes() > MAX_POOLED_WORK_BYTES {
            return;
        }
        let work = std::mem::replace(&mut self.0, TripleWork::empty());
        let _ = TRIPLE_WORK_POOL.try_with(|pool| {
            if let Ok(mut pool) = pool.try_borrow_mut() {
                *pool = Some(work);
            }
        });
    }
}

impl std::ops::Deref for PooledWork {
    type Target = TripleWork;
    fn deref(&self) -> &TripleWork {
        &self.0
    }
}

impl std::ops::DerefMut for PooledWork {
    fn deref_mut(&mut self) -> &mut TripleWork {
        &mut self.0
    }
}

impl TripleWork {
    /// Buffers without capacity (what a [`PooledWork`] leaves behind when it is dropped).
    fn empty() -> Self {
        Self {
            survivors: Vec::new(),
            scratch_tables: Vec::new(),
            solved: SolvedTriples::with_capacity(0),
            to_solve: Vec::new(),
            work: Vec::new(),
            solved_poses: Vec::new(),
            solved_ranges: Vec::new(),
            solves: 0,
        }
    }

    /// Empties the buffers (their capacity is kept) for a new frame.
    fn reset(&mut self) {
        self.survivors.clear();
        self.scratch_tables.clear();
        self.solved.clear();
        self.to_solve.clear();
        self.work.clear();
        self.solved_poses.clear();
        self.solved_ranges.clear();
        self.solves = 0;
    }

    /// The bytes the buffers hold (their capacities; the map's entries counted once).
    fn held_bytes(&self) -> usize {
        use std::mem::size_of;
        self.survivors.capacity() * size_of::<[usize; 3]>()
            + self.scratch_tables.capacity() * size_of::<u64>()
            + self.solved.held_bytes()
            + self.to_solve.capacity() * size_of::<[Vector3<f64>; 3]>()
            + self.work.capacity() * size_of::<(usize, [usize; 3], usize)>()
            + self.solved_poses.capacity() * size_of::<Pose>()
            + self.solved_ranges.capacity() * size_of::<(usize, usize)>()
    }

    fn new() -> Self {
        Self {
            survivors: Vec::new(),
            scratch_tables: Vec::new(),
            solved: SolvedTriples::with_capacity(SOLVED_TRIPLES_CAPACITY),
            to_solve: Vec::new(),
            work: Vec::new(),
            solved_poses: Vec::new(),
            solved_ranges: Vec::new(),
            solves: 0,
        }
    }
}

/// A detection triple's bearings and what the tests of its landmark triples need.
struct DetectionTriple {
    detections: [usize; 3],
    /// With a known vertical: the levelled azimuths, for the test of a landmark triple
    /// before its P3P solve ([`azimuths_can_meet`]).
    levelled: Option<LevelledTriple>,
    /// `det[b_a, b_b, b_c]` of the three bearings.
    det_b: f64,
    /// Whether the orientation test is used: only when the sign of the detections'
    /// determinant is beyond the noise (each bearing moves by at most `noise`).
    det_b_reliable: bool,
    /// The core detections other than the three, for the preemptive verification.
    extensions: Vec<usize>,
    /// `None` for (anti)parallel detections: no landmark triple has a pose for them. With
    /// a known vertical, P3P keeps only the poses whose up is within the limit of the
    /// world's (no check from π on).
    prepared: Option<P3pBearings>,
}

impl DetectionTriple {
    fn new(search: &Search, frame: &SearchPlan, [a, b, c]: [usize; 3], core: &[usize]) -> Self {
        let bearings = [
            search.directions[a],
            search.directions[b],
            search.directions[c],
        ];
        let levelled = frame
            .up_limit
            .and_then(|(u, limit)| LevelledTriple::new(&bearings, &u, limit));
        let det_b = bearings[0].dot(&bearings[1].cross(&bearings[2]));
        let det_b_reliable = det_b.abs() > RELIABLE_DETERMINANT_NOISES * search.noise;
        let extensions: Vec<usize> = core
            .iter()
            .copied()
            .filter(|&l| l != a && l != b && l != c)
            .collect();
        let prepared = P3pBearings::try_new(&bearings).and_then(|prepared| match frame.up_limit {
            Some((u, limit)) => prepared.with_max_tilt(&u, limit),
            None => Some(prepared),
        });
        Self {
            detections: [a, b, c],
            levelled,
            det_b,
            det_b_reliable,
            extensions,
            prepared,
        }
    }
}

/// The detection triples of a round drawn from `core` (those with a detection beyond its
/// first `previous`, the bearings at least [`MIN_TRIPLE_ANGLE_RAD`] apart), in a fixed
/// pseudo-random order, at most `budget`, then cheapest first: by the largest number of
/// (cell, candidate) pairs one of its detections may be (stable, so the pseudo-random order
/// breaks ties). The cost of a triple grows with its detections' candidates (a lamp near
/// the horizon may be any of 80 % of a cell's candidates, a roof corner high up a tenth),
/// and all of a round's triples are run unless one stops the search: the order decides the
/// time to the first triple of true detections, not which triples are run.
fn round_triples(
    angles: &[f64],
    core: &[usize],
    previous: usize,
    seed: u64,
    budget: usize,
    allowed_counts: &[usize],
) -> Vec<[usize; 3]> {
    let n = allowed_counts.len();
    let mut triples = Vec::new();
    for z in previous.max(2)..core.len() {
        for y in 1..z {
            for x in 0..y {
                let t = [core[x], core[y], core[z]];
                let ok = (0..3).all(|p| angles[t[p] * n + t[(p + 1) % 3]] >= MIN_TRIPLE_ANGLE_RAD);
                if ok {
                    triples.push(t);
                }
            }
        }
    }
    shuffle(
        &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed),
        &mut triples,
    );
    triples.truncate(budget);
    triples.sort_by_key(|t| t.iter().map(|&d| allowed_counts[d]).max());
    triples
}

impl Search<'_> {
    /// The search with a cache budget of `bytes` instead of the options'.
    fn with_cache_budget(self, bytes: usize) -> Self {
        self.cache_left.set(bytes);
        Self {
            cache_budget: bytes,
            ..self
        }
    }

    /// A search over `db` for `detections` (their unit `directions` and pairwise `angles`),
    /// with the rig's `up` when known.
    fn new<'a>(
        db: &'a LandmarkDb,
        detections: &'a [Detection],
        directions: Vec<Vector3<f64>>,
        angles: Vec<f64>,
        up: Option<(Vector3<f64>, f64)>,
        area: &SearchArea,
        options: &'a MatchOptions,
    ) -> Search<'a> {
        let cache_budget = options.cache_budget_bytes;
        let position_margin = position_margin(options);
        let noise = options.inlier_threshold_sigmas * options.sigma_rad;
        Search {
            db,
            detections,
            directions,
            options,
            noise,
            cos_hypothesis_threshold: (HYPOTHESIS_THRESHOLD_FACTOR * noise)
                .min(std::f64::consts::PI)
                .cos(),
            kept: Vec::new(),
            hypotheses: 0,
            pose_tests: 0,
            scratch_dirs: Vec::new(),
            scratch_best: Vec::new(),
            scratch_extensions: Vec::new(),
            angles,
            up,
            widened_area: SearchArea {
                min_in_world: area.min_in_world.add_scalar(-position_margin),
                max_in_world: area.max_in_world.add_scalar(position_margin),
                horizontal_radius_m: area.horizontal_radius_m.map(|r| r + position_margin),
            },
            conclusion: ConclusionCache::default(),
            cache_budget,
            cache_left: std::cell::Cell::new(cache_budget),
            cache_peak: std::cell::Cell::new(0),
            cache_stored: std::cell::Cell::new(0),
            cache_transient: std::cell::Cell::new(0),
        }
    }

    /// The rounds of detection triples: round `r` draws its triples from the first
    /// `max_core_detections · CORE_GROWTH^r` detections of the frame's order. When inliers
    /// are few among many detections the core may hold fewer than three of them, so the next
    /// round draws from a larger core, unless the hypotheses so far already give a decisive
    /// fix. Ends with the conclusion.
    fn rounds(
        &mut self,
        cells: &mut Cells,
        context: &PairContext,
        frame: &SearchPlan,
    ) -> MatchResult {
        let options = self.options;
        let mut work = PooledWork::take();
        // The confirmation triples run so far (sorted detection indices).
        let mut confirmations_tried: Vec<[usize; 3]> = Vec::new();
        let mut previous = 0;
        let mut core_size = options.max_core_detections.min(frame.order.len());
        let mut round = 0u64;
        // The inliers of the top hypothesis when the early stop was last checked and refused.
        let mut stop_checked_inliers = 0;
        loop {
            let core = &frame.order[..core_size];
            let budget = options
                .max_detection_triples
                .saturating_mul(core_size.div_ceil(options.max_core_detections));
            let mut triples = round_triples(
                &self.angles,
                core,
                previous,
                options.seed.wrapping_add(round),
                budget,
                &frame.allowed_counts,
            );
            if self.up.is_none() {
                self.order_by_sampled_cost(cells, context, &mut triples, &mut work);
            }
            // The next triple: a confirmation triple of the best pose when one is due (see
            // `Search::confirmation_triples`), else the next of the round's triples.
            let mut next = 0;
            let mut confirmation: Option<[usize; 3]> = None;
            loop {
                let triple = match confirmation.take() {
                    Some(t) => t,
                    None => {
                        let Some(&t) = triples.get(next) else { break };
                        next += 1;
                        t
                    }
                };
                let triple = DetectionTriple::new(self, frame, triple, core);
                let budget_spent = self.landmark_triples(cells, context, frame, &triple, &mut work);
                self.pose_tests += work.solved_poses.len();
                self.hypotheses_of(cells, frame, &triple, &work);
                if budget_spent {
                    return conclude(self, cells.len());
                }
                // Early stop only for a best that explains at least half the usable
                // detections: a wrong pose on a repetitive layout can be confirmed twice
                // while the true one (with more inliers) has not been generated yet.
                let enough = options
                    .min_inliers
                    .max((STOP_MIN_INLIER_FRACTION * frame.n_usable as f64).ceil() as usize);
                if let Some(fix) = self.early_stop(cells.len(), enough, &mut stop_checked_inliers) {
                    return fix;
                }
                if confirmations_tried.len() < MAX_CONFIRMATION_TRIPLES {
                    // Without a vertical the pool's order says nothing of the cost: the
                    // cheapest of the first few by sampled cost.
                    let limit = if self.up.is_none() {
                        CONFIRMATION_CANDIDATES
                    } else {
                        1
                    };
                    let mut candidates = self.confirmation_triples(
                        enough,
                        &frame.allowed_counts,
                        &confirmations_tried,
                        limit,
                    );
                    if candidates.len() > 1 {
                        self.order_by_sampled_cost(cells, context, &mut candidates, &mut work);
                    }
                    confirmation = candidates.first().copied();
                    confirmations_tried.extend(confirmation);
                }
            }
            if core_size == frame.order.len() || round + 1 >= options.max_rounds as u64 {
                break;
            }
            let so_far = conclude(self, cells.len());
            if so_far.status == MatchStatus::Ok {
                return so_far;
            }
            previous = core_size;
            core_size = core_size.saturating_mul(CORE_GROWTH).min(frame.order.len());
            round += 1;
        }
        conclude(self, cells.len())
    }

    /// Without a known vertical every detection may be every candidate (`allowed_counts`
    /// are all equal), so [`round_triples`]' order is random, while the landmark triples a
    /// detection triple lets through its pair tables, and so its P3P solves, differ several
    /// times between triples (0.2–1.7 million solves over 1 km² of issue #25's random
    /// layout, 12 m cells): a pair of bearings far apart allows a landmark pair under a
    /// tolerance that grows with the angle (`pair_angle_wander`), and landmark pairs at wide
    /// angles are the many. Over a cold start two random triples spent the whole budget of
    /// solves, so that in 10 of 10 frames no triple of true detections ran at all (the
    /// truth was never generated: `no_match`). So the triples are run
    /// cheapest first by their measured cost: the landmark triples that pass their tables
    /// in [`COST_SAMPLE_CELLS`] cells spread over the visiting order (stable sort, ties
    /// keep the pseudo-random order). This changes only the order: the same triples are
    /// run unless the budget or the early stop ends the search, and the acceptance test
    /// counts the poses actually tried.
    fn order_by_sampled_cost(
        &self,
        cells: &mut Cells,
        context: &PairContext,
        triples: &mut [[usize; 3]],
        work: &mut TripleWork,
    ) {
        let stride = cells.len().div_ceil(COST_SAMPLE_CELLS).max(1);
        let mut costs: Vec<(usize, [usize; 3])> = triples.iter().map(|&t| (0, t)).collect();
        for cell in cells.iter_mut().step_by(stride) {
            for (cost, [a, b, c]) in &mut costs {
                self.cell_survivors(
                    cell,
                    context,
                    [*a, *b, *c],
                    &mut work.survivors,
                    &mut work.scratch_tables,
                );
                *cost += work.survivors.len();
            }
        }
        costs.sort_by_key(|&(cost, _)| cost);
        for (slot, (_, t)) in triples.iter_mut().zip(costs) {
            *slot = t;
        }
    }

    /// The landmark triples of every cell in visiting order for a detection triple (in
    /// `work.work`), and the distinct ones among them to solve (`work.to_solve`; each once
    /// per detection triple: the same landmark triple passes in neighbouring cells), then
    /// their P3P poses. Returns whether the budget of P3P solves is spent (after solving).
    fn landmark_triples(
        &self,
        cells: &mut Cells,
        context: &PairContext,
        frame: &SearchPlan,
        triple: &DetectionTriple,
        work: &mut TripleWork,
    ) -> bool {
        let db = self.db;
        let radius = frame.radius;
        work.solved.clear();
        work.work.clear();
        work.to_solve.clear();
        let mut budget_spent = false;
        'cells: for (cell_index, cell) in cells.iter_mut().enumerate() {
            self.cell_survivors(
                cell,
                context,
                triple.detections,
                &mut work.survivors,
                &mut work.scratch_tables,
            );
            let cands = &cell.cands;
            let centre = &cell.centre;
            for &[i, j, k] in &work.survivors {
                let points = [
                    db.landmarks()[cands[i].index].position_in_world,
                    db.landmarks()[cands[j].index].position_in_world,
                    db.landmarks()[cands[k].index].position_in_world,
                ];
                // The orientation test (the sign first: the plane's distance, with its
                // square root and division, only decides whether the sign may be used).
                if triple.det_b_reliable
                    && cands[i]
                        .direction
                        .dot(&cands[j].direction.cross(&cands[k].direction))
                        * triple.det_b
                        < 0.0
                {
                    let normal = (points[1] - points[0]).cross(&(points[2] - points[0]));
                    let nn = normal.norm();
                    if nn > 0.0 && (normal.dot(&(centre - points[0])) / nn).abs() > radius {
                        continue;
                    }
                }
                let key = [cands[i].index, cands[j].index, cands[k].index];
                let slot = match work.solved.find(&key) {
                    Ok(slot) => slot,
                    Err(position) => {
                        // Not solved when no pose of it could be upright enough within
                        // this cell's reach (the only poses this cell uses); nor
                        // remembered, since a neighbouring cell may need it. The
                        // hypotheses are the same as without the test; only `solves`
                        // (the budget) counts fewer.
                        if let Some(levelled) = &triple.levelled
                            && !azimuths_can_meet(
                                levelled,
                                &points.map(|l| (l - centre).xy()),
                                &[
                                    cands[i].horizontal + frame.cell_reach,
                                    cands[j].horizontal + frame.cell_reach,
                                    cands[k].horizontal + frame.cell_reach,
                                ],
                                frame.cell_reach,
                            )
                        {
                            continue;
                        }
                        work.to_solve.push(points);
                        let slot = work.to_solve.len() - 1;
                        work.solved.insert(position, key, slot);
                        slot
                    }
                };
                work.work.push((cell_index, [i, j, k], slot));
                // P3P solves (every hypothesis scored comes from one): the budget.
                if work.solves + work.to_solve.len() >= self.options.max_hypotheses {
                    budget_spent = true;
                    break 'cells;
                }
            }
        }
        work.solves += work.to_solve.len();
        // Each distinct landmark triple's P3P poses (upright enough) inside the area
        // with the cells' reach.
        let keep_pose = |pose: &Pose| {
            in_box(&pose.translation.vector, &frame.reach_min, &frame.reach_max)
                && frame
                    .heading_limit
                    .is_none_or(|(h, limit)| heading_within(pose, h, limit))
        };
        solve_triples(
            triple.prepared.as_ref(),
            &work.to_solve,
            keep_pose,
            &mut work.solved_poses,
            &mut work.solved_ranges,
        );
        budget_spent
    }

    /// Scores the P3P poses of the landmark triples in `work` in the cells' visiting order,
    /// keeping those that could be the best or a close runner-up.
    fn hypotheses_of(
        &mut self,
        cells: &Cells,
        frame: &SearchPlan,
        triple: &DetectionTriple,
        work: &TripleWork,
    ) {
        let options = self.options;
        for &(cell_index, [i, j, k], slot) in &work.work {
            let cell = &cells[cell_index];
            let centre = &cell.centre;
            let (start, count) = work.solved_ranges[slot];
            for &pose in &work.solved_poses[start..start + count] {
                if (pose.translation.vector - centre).norm() > frame.cell_reach {
                    continue;
                }
                // Preemptive verification: enough other core detections must each see,
                // under this exact pose, a candidate landmark of the cell.
                if options.min_extensions > 0
                    && !self.verify(&pose, &triple.extensions, [i, j, k], cell)
                {
                    continue;
                }
                self.hypotheses += 1;
                // Only hypotheses that could be the best or a close runner-up are worth
                // scoring to the end.
                let best = self.kept.first().map_or(0, |h| h.inliers);
                let needed = best.saturating_sub(options.ambiguity_margin + 1).max(4);
                let (inliers, cost, assignment) =
                    self.score(&pose, &cell.indices, HYPOTHESIS_THRESHOLD_FACTOR, needed);
                if inliers >= options.min_inliers.min(4) {
                    self.keep(pose, inliers, cost, triple.detections, &assignment);
                }
            }
        }
    }

    /// The early stop, when the top hypothesis has [`STOP_CONFIRMATIONS`] disjoint
    /// confirmations, explains `enough` detections and more than when the stop was last
    /// checked (`checked_inliers`, updated): the conclusion, if it is a fix that still
    /// explains `enough`. A pose from three nearly collinear lamps can be confirmed twice
    /// and still refine into a worse one; the search then goes on, and the stop is checked
    /// again once a hypothesis explains more.
    fn early_stop(
        &mut self,
        cells: usize,
        enough: usize,
        checked_inliers: &mut usize,
    ) -> Option<MatchResult> {
        let top = self.kept.first()?;
        if top.confirming.len() >= STOP_CONFIRMATIONS as usize
            && top.inliers >= enough
            && top.inliers > *checked_inliers
        {
            *checked_inliers = top.inliers;
            let so_far = conclude(self, cells);
            if so_far.status == MatchStatus::Ok && so_far.best_score >= enough {
                return Some(so_far);
            }
        }
        None
    }
}

impl Search<'_> {
    pub(super) fn compatible(&self, detection: usize, landmark: usize) -> bool {
        match (
            self.detections[detection].class,
            self.db.landmarks()[landmark].class,
        ) {
            (Some(a), Some(b)) => a == b,
            _ => true,
        }
    }

    /// Whether a pose lies in the search area (widened by the position margin). The area is
    /// the prior: a hypothesis outside it, e.g. one that refinement moved away, is not a fix.
    pub(super) fn within_area(&self, pose: &Pose) -> bool {
        self.widened_area.contains(&pose.translation.vector)
    }

    /// Whether a refined pose keeps the known vertical ([`keeps_vertical`]); always true
    /// without one.
    pub(super) fn within_vertical(&self, pose: &Pose, covariance: &Matrix6<f64>) -> bool {
        self.up
            .is_none_or(|(u, tolerance)| keeps_vertical(pose, covariance, &u, tolerance))
    }
}

#[cfg(test)]
mod tests;
