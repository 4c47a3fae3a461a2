//! The search behind [`super::match_detections`]: cells, pair tables, hypotheses, scoring,
//! refinement and the runner-up.

use super::{
    CORE_GROWTH, DECISIVE_LOG_ODDS, DISTINCT_POSITION_M, DISTINCT_ROTATION_RAD,
    DUPLICATE_ANGLE_RAD, Detection, HYPOTHESIS_THRESHOLD_FACTOR, LIKELY_WRONG_LINK_PROBABILITY,
    LandmarkDb, MAX_CELLS, MAX_CONFIRMATION_TRIPLES, MAX_KEPT_HYPOTHESES, MAX_REFINED_HYPOTHESES,
    MIN_DETECTION_PROBABILITY, MIN_LINK_LEVERAGE_GAP, MIN_TRIPLE_ANGLE_RAD, MatchError,
    MatchEstimate, MatchOptions, MatchResult, MatchStatus, REFINE_PASSES, STOP_CONFIRMATIONS,
    STOP_MIN_INLIER_FRACTION, SearchArea, UP_CHECK_MARGIN_RAD,
};
use nalgebra::{Matrix2, Matrix6, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use std::cell::RefCell;
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::hash::{BuildHasherDefault, Hasher};
use vgps_geometry::geometry::{Pose, PoseSolutions, Ray, angle_between, rotation_angle, try_unit};
use vgps_geometry::solvers::p3p::{P3pBearings, p3p_prepared_into};
use vgps_geometry::solvers::refine_pose::{
    RefineOptions, RefinedPose, angular_residual, refine_pose_with_sigmas,
};

/// A landmark index triple, the key of the per-detection-triple P3P cache.
#[derive(Clone, Copy, PartialEq, Eq)]
struct TripleKey([usize; 3]);

impl std::hash::Hash for TripleKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        // One word per key: collisions cost a comparison, never a wrong answer.
        let [i, j, k] = self.0.map(|x| x as u64);
        state.write_u64(i ^ j.rotate_left(21) ^ k.rotate_left(42));
    }
}

/// A multiply hasher for [`TripleKey`] (one `write_u64` per key): the standard SipHash
/// cost as much as a third of a P3P solve.
#[derive(Default)]
struct TripleHasher(u64);

impl Hasher for TripleHasher {
    fn finish(&self) -> u64 {
        // A product's low bits depend only on the factor's low bits, and the table takes
        // its bucket from the low bits: bring the well-mixed high half down.
        self.0.rotate_left(26)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, i: u64) {
        // The constant of FxHash (rustc's hasher).
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// A landmark as seen from a cell centre.
struct Candidate {
    index: usize,
    direction: Vector3<f64>,
    /// Half-width of the direction's wander over the cell, radians (π when the landmark is
    /// within the cell's ball).
    wander: f64,
    /// The survey term [`survey_angle`] of the landmark's survey bound `k σ_m`, radians.
    survey: f64,
    /// `1 / (range − radius)`, the reciprocal of the least range over the cell's ball
    /// (`+∞` when the landmark is within the ball), 1/metres.
    inv_near: f64,
    /// The horizontal distance of the landmark from the cell centre, metres: for the azimuth
    /// test ([`azimuths_can_meet`]).
    horizontal: f64,
}

impl Candidate {
    /// A landmark at `v` from a cell centre (`range = |v|` metres, in the unit `direction`),
    /// for a cell ball of `radius`, with the survey term `survey` (radians).
    fn new(
        index: usize,
        v: &Vector3<f64>,
        direction: Vector3<f64>,
        range: f64,
        radius: f64,
        survey: f64,
    ) -> Self {
        let inside = range <= radius;
        Self {
            index,
            direction,
            horizontal: v.xy().norm(),
            wander: if inside {
                std::f64::consts::PI
            } else {
                (radius / range).asin()
            },
            survey,
            inv_near: if inside {
                f64::INFINITY
            } else {
                1.0 / (range - radius)
            },
        }
    }
}

/// How far the direction to a landmark may turn, seen from any point of a cell's ball
/// (`radius` around a centre `range` metres from the landmark), when the landmark is anywhere
/// within `survey_m` of its surveyed position: `asin(survey_m / (range − radius))` (the
/// half-angle of the cone tangent to the survey ball from the nearest viewpoint), `π` when
/// the survey ball may reach the viewpoint, `0` without a survey error. Radians.
///
/// The pair tables and the elevation gates add it per landmark to their bounds, which hold
/// the surveyed positions seen from the ball.
fn survey_angle(survey_m: f64, range: f64, radius: f64) -> f64 {
    if survey_m <= 0.0 {
        return 0.0;
    }
    let nearest = range - radius;
    if nearest > survey_m {
        (survey_m / nearest).asin()
    } else {
        std::f64::consts::PI
    }
}

/// The largest change of the angle between the directions to two landmarks `i, j` when the
/// viewpoint moves from the cell centre to any point of the cell's ball (radius `radius`),
/// radians.
///
/// Two bounds, the smaller is used:
/// - each direction turns by at most its `wander` (`asin(radius / range)`), so the angle
///   changes by at most `wander_i + wander_j`;
/// - the angle's gradient has the norm `|∇φᵢⱼ(x)| = |Lᵢ − Lⱼ| / (ρᵢ(x) ρⱼ(x))` (from
///   `∇φ = [(uⱼ − cos φ uᵢ)/ρᵢ + (uᵢ − cos φ uⱼ)/ρⱼ] / sin φ` and the law of cosines), and
///   every point of the segment from the centre to a point of the ball is in the ball, where
///   `ρ ≥ range − radius`; so the change is at most
///   `radius · |Lᵢ − Lⱼ| / ((ρᵢ − radius)(ρⱼ − radius))`.
///
/// The second is much tighter for two landmarks in similar directions (a row of lamps
/// along a street, seen end-on): their separation is far less than `ρᵢ + ρⱼ`.
///
/// Evaluated with the candidates' reciprocal least ranges (no division per pair): when a
/// landmark is within the ball its `inv_near` is `+∞`, the product is `+∞` or NaN, and
/// `f64::min` keeps the first bound.
fn pair_angle_wander(ci: &Candidate, cj: &Candidate, separation: f64, radius: f64) -> f64 {
    let sum = ci.wander + cj.wander;
    sum.min(radius * separation * ci.inv_near * cj.inv_near)
}

/// One scored hypothesis.
#[derive(Clone)]
struct Hypothesis {
    pose: Pose,
    inliers: usize,
    cost: f64,
    /// The detection triples that confirmed the pose, pairwise disjoint (their number is the
    /// pose's confirmations).
    confirming: Vec<[usize; 3]>,
    /// The detections the pose explains (at the hypothesis threshold), in index order: the
    /// pool of its confirmation triples ([`Search::confirmation_triple`]).
    explained: Vec<usize>,
}

/// The message of [`MatchStatus::NoLandmarksInRange`].
const NO_LANDMARKS_IN_RANGE: &str =
    "fewer than 3 landmarks within the visibility range of the search area";

/// A refined hypothesis.
#[derive(Clone)]
struct Refined {
    pose: Pose,
    covariance: Matrix6<f64>,
    rms: f64,
    inliers: usize,
    /// Truncated (MSAC) cost over every detection, in units of the squared inlier
    /// threshold: `Σ min(rᵢ² / tᵢ², 1)`. An outlier costs 1, a perfect inlier 0.
    cost: f64,
    assignment: Vec<Option<usize>>,
}

/// What a fix says about the frame's detections (see [`Search::detection_model`]).
struct DetectionModel {
    /// False detections per steradian.
    clutter_per_sr: f64,
    /// Probability that a landmark in range is detected.
    detection_probability: f64,
    /// The landmarks in range of the fix.
    near: Vec<usize>,
    /// The factor on σ² the fix's own residuals call for, at least 1: `χ² / (2k − 6)` over
    /// its `k` inliers. Evidence from residuals is weighed with the larger σ, so that a σ
    /// set too small does not make the comparison of two poses overconfident.
    noise_scale: f64,
}

/// A search cell: its candidates seen from the centre and its lazily built pair tables.
struct CellData {
    centre: Vector3<f64>,
    cands: Vec<Candidate>,
    /// What the pair tables test of each candidate pair `(i, j)`, row-major `m × m` (the
    /// diagonal unused): one record per pair, so a table row reads one contiguous run.
    /// Computed when a pair table first needs the pair ([`CellData::ensure_pairs`]).
    pairs: Vec<PairValues>,
    /// Which entries of `pairs` are computed: `m × words` bits, row `i` the `j`.
    pairs_done: Vec<u64>,
    /// Per candidate: its position in the frame's shared landmarks ([`PairContext`]) and the
    /// terms of [`det_range`] it brings to a pair.
    slots_shared: Vec<usize>,
    sides: Vec<DetSide>,
    /// Database indices of the candidates.
    indices: Vec<usize>,
    /// 64-bit words per candidate bitset.
    words: usize,
    /// Per detection, the candidates it may be (class, and elevation when up is known):
    /// `n × words` bits.
    allowed: Vec<u64>,
    /// Pair tables by ordered detection pair `a · n + b`: `slots[a · n + b]` is the table's
    /// position in `store` (`NO_TABLE`: not built yet); row `i` of a table (`words` words)
    /// holds the candidates `j` that detection `b` may be when detection `a` is candidate `i`.
    slots: Vec<u32>,
    /// The tables, each `m × words` words.
    store: Vec<u64>,
}

/// The determinant of three unit bearings has a reliable sign when it exceeds this many
/// times the per-bearing noise bound (each bearing moves by at most the bound).
const RELIABLE_DETERMINANT_NOISES: f64 = 3.0;

/// Initial capacity of the map of solved landmark triples (one detection triple's worth
/// over a prior; a cold start grows it).
const SOLVED_TRIPLES_CAPACITY: usize = 1024;

/// A pair table not built yet.
const NO_TABLE: u32 = u32::MAX;

/// How far (in visibility ranges) a pose may be from the centre of a gathered landmark set
/// for the landmarks in its range to be taken from that set ([`Search::in_range`]).
const RANGE_SET_SLACK: f64 = 0.25;
/// Relative widening of a gathered landmark set's radius: far above the rounding of the
/// distances compared, so that the set provably holds every landmark in range of a pose
/// within [`RANGE_SET_SLACK`] of its centre.
const RANGE_SET_ROUNDING: f64 = 1e-9;
/// At most this many gathered landmark sets per frame (the oldest is dropped).
const MAX_RANGE_SETS: usize = 4;
/// Relative widening of the widest gate angle below which a landmark is skipped in
/// [`Search::link_probabilities`] without computing its residual: the residual's norm is
/// the angle to within 1e-12 relative, far inside this margin.
const LINK_GATE_ANGLE_MARGIN: f64 = 1e-3;
/// Absolute margin on the cosine of that angle, far above the rounding of the dot product.
const LINK_GATE_COS_MARGIN: f64 = 1e-12;

/// What the conclusion keeps between its calls in a frame (early-stop checks conclude
/// more than once) and scratch space of the scoring.
#[derive(Default)]
struct ConclusionCache {
    /// Landmark sets gathered with one R*-tree query each: (centre, indices of the
    /// landmarks within `(1 + RANGE_SET_SLACK) ·` the visibility range of it, widened by
    /// [`RANGE_SET_ROUNDING`], in increasing order).
    ranges: Vec<(Vector3<f64>, Vec<usize>)>,
    /// Each hypothesis pose refined so far (bit for bit) and what [`Search::refine`] gave.
    refined: Vec<(Pose, Option<Refined>)>,
    /// Scratch of [`Search::score`]: the (landmark, detection) links taken so far.
    taken: Vec<(usize, usize)>,
    /// Scratch of [`Search::score_in_range`]: the landmarks in range.
    near: Vec<usize>,
    /// Scratch of [`Search::score`]: the unit directions of the landmarks in range.
    units: Vec<Vector3<f64>>,
}

/// Whether two poses are equal bit for bit (the key of the refinement cache).
fn same_bits(a: &Pose, b: &Pose) -> bool {
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

/// Pair tables a cell has room for before its store grows: a median prior frame runs five
/// detection triples, about a dozen distinct detection pairs.
const INITIAL_PAIR_TABLES: usize = 16;

/// At most this many cells' buffers are kept per thread for the next frame (a prior frame
/// has about 25 cells; a cold start's thousands are not kept).
const MAX_POOLED_CELLS: usize = 64;

thread_local! {
    /// Cells of earlier frames of this thread, whose buffers the next frame reuses: filling
    /// a fresh `m × m` buffer of pair values cost about 0.15 ms of a 1.3 ms prior frame (25
    /// cells of 65 kB, with page faults). An entry of `pairs` is only read once computed
    /// ([`CellData::ensure_pairs`] keeps `pairs_done`), so a reused one needs no filling;
    /// every other buffer is cleared.
    static CELL_POOL: RefCell<Vec<CellData>> = const { RefCell::new(Vec::new()) };
}

/// A cell with empty buffers, from the pool when it has one (see [`CELL_POOL`]).
fn take_cell() -> CellData {
    CELL_POOL
        .with_borrow_mut(|pool| pool.pop())
        .unwrap_or_else(|| CellData {
            centre: Vector3::zeros(),
            cands: Vec::new(),
            pairs: Vec::new(),
            pairs_done: Vec::new(),
            slots_shared: Vec::new(),
            sides: Vec::new(),
            indices: Vec::new(),
            words: 0,
            allowed: Vec::new(),
            slots: Vec::new(),
            store: Vec::new(),
        })
}

/// Gives cells back to the pool (at most [`MAX_POOLED_CELLS`]); `try_with`, since a thread
/// that ends drops its pool.
fn recycle_cells(cells: &mut Vec<CellData>) {
    let _ = CELL_POOL.try_with(|pool| {
        if let Ok(mut pool) = pool.try_borrow_mut() {
            let room = MAX_POOLED_CELLS.saturating_sub(pool.len());
            pool.extend(cells.drain(..).take(room));
        }
    });
}

/// The cells of a frame; their buffers go back to the pool when the frame is done.
struct Cells(Vec<CellData>);

impl Drop for Cells {
    fn drop(&mut self) {
        recycle_cells(&mut self.0);
    }
}

impl std::ops::Deref for Cells {
    type Target = Vec<CellData>;
    fn deref(&self) -> &Vec<CellData> {
        &self.0
    }
}

impl std::ops::DerefMut for Cells {
    fn deref_mut(&mut self) -> &mut Vec<CellData> {
        &mut self.0
    }
}

impl CellData {
    /// Computes the pair values the table of detections `(a, b)` reads, those of the
    /// candidates `i` detection `a` may be and `j` detection `b` may be, that are not computed
    /// yet. Each pair is computed with its candidates in database order and written at
    /// `(i, j)` and, mirrored, at `(j, i)`: the angle and its bound are symmetric, the side
    /// of the pair changes sign. A frame's first triples (the cheapest, see `run`) read few
    /// rows and columns: a roof corner high up may be a tenth of a cell's candidates.
    fn ensure_pairs(&mut self, db: &LandmarkDb, context: &PairContext, a: usize, b: usize) {
        let Self {
            cands,
            sides,
            slots_shared,
            words,
            allowed,
            pairs,
            pairs_done,
            ..
        } = self;
        let (m, words) = (cands.len(), *words);
        let allowed_b = &allowed[b * words..(b + 1) * words];
        for_each_bit(&allowed[a * words..(a + 1) * words], |i| {
            for (w, &word_b) in allowed_b.iter().enumerate() {
                let mut missing = word_b & !pairs_done[i * words + w];
                // The diagonal is never tested (`i ≠ j`).
                if w == i / 64 {
                    missing &= !(1u64 << (i % 64));
                }
                while missing != 0 {
                    let j = w * 64 + missing.trailing_zeros() as usize;
                    missing &= missing - 1;
                    let (lo, hi) = (i.min(j), i.max(j));
                    let values = context.values(db, cands, sides, slots_shared, lo, hi);
                    pairs[lo * m + hi] = values;
                    pairs[hi * m + lo] = values.mirrored();
                    bit_set(&mut pairs_done[i * words..(i + 1) * words], j);
                    bit_set(&mut pairs_done[j * words..(j + 1) * words], i);
                }
            }
        });
    }

    /// The whole (built) table of the ordered detection pair `key`.
    fn table(&self, key: usize) -> &[u64] {
        let size = self.cands.len() * self.words;
        let start = self.slots[key] as usize * size;
        &self.store[start..start + size]
    }
}

fn bit_set(bits: &mut [u64], k: usize) {
    bits[k / 64] |= 1 << (k % 64);
}

/// Calls `f` with the index of every set bit, in increasing order.
fn for_each_bit(bits: &[u64], mut f: impl FnMut(usize)) {
    for (w, &word) in bits.iter().enumerate() {
        let mut rest = word;
        while rest != 0 {
            f(w * 64 + rest.trailing_zeros() as usize);
            rest &= rest - 1;
        }
    }
}

fn validate(detections: &[Detection], options: &MatchOptions) -> Result<(), MatchError> {
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

/// The shape of the search cells. Every cell lies within the vertical cylinder of radius
/// `half_horizontal` and half-height `half_vertical` around its centre, and within the ball
/// of `radius` around it.
#[derive(Clone, Copy, Debug)]
struct CellShape {
    /// Radius of the ball around a centre that holds the cell, metres.
    radius: f64,
    /// Horizontal radius of the cylinder that holds the cell, metres.
    half_horizontal: f64,
    /// Half-height of the cell, metres.
    half_vertical: f64,
}

/// Relative widening of the disc a ring covering must cover (and narrowing of the cells'
/// radius it may use), for the rounding of the centres' positions.
const RING_COVER_SLACK: f64 = 1e-9;

/// How many ring sizes past the fewest that can close a ring are compared (each ring takes
/// the size that covers the most area per cell).
const RING_SIZES_TRIED: usize = 24;

/// Centres (relative to the disc's centre) of discs of radius `r` that together cover the
/// disc of radius `big`; `Err(count)` once more than `limit` would be needed.
///
/// Rings from the outside in, then one disc at the centre. `n` discs whose centres are
/// evenly spaced on the circle of radius `ρ` cover every point at a distance `t` from the
/// centre with `t² + ρ² − 2tρ cos α ≤ r²`, `α = π/n` (the point midway between two
/// centres is the farthest from both), i.e. the annulus
/// `ρ cos α ∓ √(r² − ρ² sin² α)`. A ring whose outer edge is the radius still to cover,
/// `R`, has `ρ = R cos α − √(r² − R² sin² α)` (the smaller root of
/// `ρ² − 2Rρ cos α + R² − r² = 0`, real when `R sin α ≤ r`; positive while `R > r`), and
/// covers down to its inner edge, the next ring's `R`. Of the ring sizes that close, the one
/// that covers the most area per disc is taken. A disc of radius 30 m with `r` = 8.5 m
/// takes rings of 13 and 7 cells and the centre: 21 cells, against the 25 squares of 12 m
/// (the same half-diagonal) over its bounding box.
fn ring_centres(big: f64, r: f64, limit: usize) -> Result<Vec<Vector2<f64>>, usize> {
    let r = r * (1.0 - RING_COVER_SLACK);
    let mut outer = big * (1.0 + RING_COVER_SLACK) + RING_COVER_SLACK;
    let mut centres = Vec::new();
    while outer > r {
        // The fewest cells that can close a ring: `outer · sin(π/n) ≤ r`.
        let fewest = (std::f64::consts::PI / (r / outer).asin()).ceil().max(3.0) as usize;
        let mut best: Option<(f64, f64, usize, f64)> = None;
        for n in fewest..fewest + RING_SIZES_TRIED {
            let (sin_a, cos_a) = (std::f64::consts::PI / n as f64).sin_cos();
            let d = r * r - (outer * sin_a).powi(2);
            if d < 0.0 {
                continue;
            }
            let rho = outer * cos_a - d.sqrt();
            let inner = rho * cos_a - (r * r - (rho * sin_a).powi(2)).max(0.0).sqrt();
            let per_cell = (outer * outer - inner.max(0.0).powi(2)) / n as f64;
            if best.is_none_or(|(b, ..)| per_cell > b) {
                best = Some((per_cell, inner, n, rho));
            }
        }
        let Some((_, inner, n, rho)) = best else {
            break;
        };
        if centres.len() + n > limit {
            return Err(centres.len() + n);
        }
        centres.extend((0..n).map(|k| {
            let (sin, cos) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
            Vector2::new(rho * cos, rho * sin)
        }));
        if inner <= 0.0 {
            return Ok(centres);
        }
        outer = inner;
    }
    if centres.len() >= limit {
        return Err(centres.len() + 1);
    }
    centres.push(Vector2::zeros());
    Ok(centres)
}

/// The cells that cover the search area: their centres and shape.
///
/// A box: a grid of `size`-edged cells (as many along each axis as it takes, stretched to
/// fit). A cylinder: layers of height `size` (stretched to fit), each covered by rings of
/// round cells with the half-diagonal of a square `size` cell ([`ring_centres`]); a cell
/// whose disc misses the box is dropped.
fn cells(area: &SearchArea, size: f64) -> Result<(Vec<Vector3<f64>>, CellShape), MatchError> {
    let extent = area.max_in_world - area.min_in_world;
    let count = |e: f64| ((e / size).ceil() as usize).max(1);
    if let Some(big) = area.horizontal_radius_m {
        if !(big.is_finite() && big >= 0.0) {
            return Err(MatchError::InvalidArea);
        }
        let layers = count(extent.z);
        let height = extent.z / layers as f64;
        let half_horizontal = size * std::f64::consts::FRAC_1_SQRT_2;
        let half_vertical = 0.5 * height;
        let centre = area.center();
        let limit = MAX_CELLS / layers;
        let ring = ring_centres(big, half_horizontal, limit)
            .map_err(|n| MatchError::AreaTooLarge(n.saturating_mul(layers)))?;
        // The cells whose disc meets the box (all of them for `SearchArea::around`).
        let ring: Vec<Vector2<f64>> = ring
            .into_iter()
            .map(|p| centre.xy() + p)
            .filter(|p| {
                let nearest = Vector2::new(
                    p.x.clamp(area.min_in_world.x, area.max_in_world.x),
                    p.y.clamp(area.min_in_world.y, area.max_in_world.y),
                );
                (nearest - p).norm() <= half_horizontal
            })
            .collect();
        let centres = (0..layers)
            .flat_map(|iz| {
                let z = area.min_in_world.z + height * (iz as f64 + 0.5);
                ring.iter().map(move |p| Vector3::new(p.x, p.y, z))
            })
            .collect();
        let shape = CellShape {
            radius: half_horizontal.hypot(half_vertical),
            half_horizontal,
            half_vertical,
        };
        return Ok((centres, shape));
    }
    let counts: Vec<usize> = (0..3).map(|k| count(extent[k])).collect();
    let total = counts[0]
        .saturating_mul(counts[1])
        .saturating_mul(counts[2]);
    if total > MAX_CELLS {
        return Err(MatchError::AreaTooLarge(total));
    }
    let step = Vector3::from_fn(|k, _| extent[k] / counts[k] as f64);
    let mut centres = Vec::with_capacity(total);
    for iz in 0..counts[2] {
        for iy in 0..counts[1] {
            for ix in 0..counts[0] {
                let f = Vector3::new(ix as f64 + 0.5, iy as f64 + 0.5, iz as f64 + 0.5);
                centres.push(area.min_in_world + step.component_mul(&f));
            }
        }
    }
    let shape = CellShape {
        radius: 0.5 * step.norm(),
        half_horizontal: 0.5 * step.xy().norm(),
        half_vertical: 0.5 * step.z,
    };
    Ok((centres, shape))
}

/// Up to `max` of the usable detections, greedily spread over the sphere (farthest-point
/// order). A detection is unusable when no candidate of any cell may be it (class, or
/// elevation when the vertical is known): e.g. a stray light below the horizon.
fn core_detections(angles: &[f64], usable: &[bool], max: usize) -> Vec<usize> {
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

struct Search<'a> {
    db: &'a LandmarkDb,
    detections: &'a [Detection],
    directions: Vec<Vector3<f64>>,
    options: &'a MatchOptions,
    /// Per-bearing noise bound k·σ (radians).
    noise: f64,
    kept: Vec<Hypothesis>,
    hypotheses: usize,
    /// Scratch of [`Search::score`]: per landmark in range, its offset in the rig frame,
    /// index and range.
    scratch_dirs: Vec<(Vector3<f64>, usize, f64)>,
    scratch_best: Vec<(usize, f64)>,
    /// Scratch of [`Search::verify`]: per extension detection, its world direction and
    /// whether it has been seen.
    scratch_extensions: Vec<(Vector3<f64>, bool)>,
    /// The angle between the bearings of each two detections, radians, `n × n`.
    angles: Vec<f64>,
    /// The rig's up direction (unit, rig frame) and its tolerance (radians), when known.
    up: Option<(Vector3<f64>, f64)>,
    /// The search area widened by the position margin of a P3P pose (its box, and a
    /// cylinder's radius): a fix must lie in it.
    widened_area: SearchArea,
    /// Landmark sets, refinements and scratch kept for the conclusion.
    conclusion: ConclusionCache,
}

impl Search<'_> {
    fn compatible(&self, detection: usize, landmark: usize) -> bool {
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
    fn within_area(&self, pose: &Pose) -> bool {
        self.widened_area.contains(&pose.translation.vector)
    }

    /// With a known vertical: `det[up, b_a, b_b]` and how far the true value may be from it
    /// ([`det_of_bearings`]).
    fn pair_det(&self, a: usize, b: usize) -> Option<(f64, f64)> {
        let (up, tol) = self.up?;
        Some(det_of_bearings(
            &up,
            tol,
            self.noise,
            &self.directions[a],
            &self.directions[b],
        ))
    }

    /// Builds the pair table of the ordered detection pair `(a, b)` in a cell (once).
    fn ensure_table(&self, cell: &mut CellData, context: &PairContext, a: usize, b: usize) {
        let n = self.detections.len();
        let key = a * n + b;
        if cell.slots[key] != NO_TABLE {
            return;
        }
        cell.ensure_pairs(self.db, context, a, b);
        let m = cell.cands.len();
        let words = cell.words;
        // Every pair the table reads is computed (the pair buffers hold stale values).
        #[cfg(debug_assertions)]
        for_each_bit(&cell.allowed[a * words..(a + 1) * words], |i| {
            for_each_bit(&cell.allowed[b * words..(b + 1) * words], |j| {
                let done = cell.pairs_done[i * words + j / 64] >> (j % 64) & 1 == 1;
                debug_assert!(i == j || done, "pair ({i}, {j}) read before it is computed");
            });
        });
        let theta = self.angles[key];
        let tol = 2.0 * self.noise;
        let pair_det = self.pair_det(a, b);
        let start = cell.store.len();
        cell.slots[key] = (start / (m * words)) as u32;
        cell.store.resize(start + m * words, 0);

        let table = &mut cell.store[start..];
        let allowed_a = &cell.allowed[a * words..(a + 1) * words];
        let allowed_b = &cell.allowed[b * words..(b + 1) * words];
        // Each test is evaluated whole and its outcome OR-ed in as a bit: about one pair in
        // eight passes, at random, so a branch per test would be mispredicted often.
        for_each_bit(allowed_a, |i| {
            let row = &mut table[i * words..(i + 1) * words];
            let pairs = &cell.pairs[i * m..(i + 1) * m];
            match pair_det {
                Some((d, margin)) => for_each_bit(allowed_b, |j| {
                    let p = &pairs[j];
                    let (lo, hi) = p.det;
                    let pass = (i != j)
                        & ((theta - p.angle).abs() <= tol + p.bound)
                        & (d + margin >= lo)
                        & (d - margin <= hi);
                    row[j / 64] |= u64::from(pass) << (j % 64);
                }),
                None => for_each_bit(allowed_b, |j| {
                    let p = &pairs[j];
                    let pass = (i != j) & ((theta - p.angle).abs() <= tol + p.bound);
                    row[j / 64] |= u64::from(pass) << (j % 64);
                }),
            }
        });
    }

    /// Whether at least `min_extensions` of the detections `extensions` each lie, under
    /// `pose`, within the hypothesis threshold of a candidate of the cell other than the
    /// hypothesis's own three (`exclude`, cell-local indices).
    fn verify(
        &mut self,
        pose: &Pose,
        extensions: &[usize],
        exclude: [usize; 3],
        cell: &CellData,
    ) -> bool {
        let threshold = HYPOTHESIS_THRESHOLD_FACTOR * self.noise;
        let cos_threshold = threshold.min(std::f64::consts::PI).cos();
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
    fn score(
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
            let sigma = (self.options.sigma_rad.powi(2) + (sigma_m / r).powi(2)).sqrt();
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
    fn keep(
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
            self.kept.push(Hypothesis {
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
    fn confirmation_triple(
        &self,
        enough: usize,
        allowed_counts: &[usize],
        tried: &[[usize; 3]],
    ) -> Option<[usize; 3]> {
        let top = self.kept.first()?;
        if top.inliers < enough || top.confirming.len() >= STOP_CONFIRMATIONS as usize {
            return None;
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
                        return Some(t);
                    }
                }
            }
        }
        None
    }

    /// The effective bearing σ of landmark `l` at `range` metres: the bearing noise and the
    /// survey σ seen from that range, radians.
    fn sigma_of(&self, l: &super::DbLandmark, range: f64) -> f64 {
        (self.options.sigma_rad.powi(2) + (l.sigma_m / range.max(1e-3)).powi(2)).sqrt()
    }

    /// Refines `pose` on the links of `assignment` (σ inflated by the survey σ); `None` with
    /// fewer than four links or when the refinement fails.
    fn fit(&self, pose: &Pose, assignment: &[Option<usize>]) -> Option<RefinedPose> {
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

    /// The detection model of a fix: false detections per steradian (those the fix does not
    /// explain, at least one, spread over the sphere) and the probability that a landmark in
    /// range is detected (inliers over landmarks in range, at least
    /// [`MIN_DETECTION_PROBABILITY`]).
    fn detection_model(&mut self, best: &Refined) -> DetectionModel {
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
    /// `cost` (see [`Refined::cost`]) against "every detection is false": each inlier adds
    /// `ln(P_d / (c · 2πs²)) − r²/(2s²)` (the Gaussian bearing of a detected landmark against
    /// false detections of density `c` per steradian), with `Σ r²/σ²` recovered from the
    /// cost (in units of the squared gate) and `s² = σ² ·` [`DetectionModel::noise_scale`].
    fn log_evidence(&self, model: &DetectionModel, inliers: usize, cost: f64) -> f64 {
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
    fn link_probabilities(&self, best: &Refined, model: &DetectionModel) -> Vec<Option<f64>> {
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

    /// One refinement pass: the detections within `factor` × the inlier threshold of a
    /// landmark in range under `pose` are fitted, and the fitted pose is re-scored against
    /// every landmark in range at the inlier threshold.
    fn refine_pass(&mut self, pose: &Pose, factor: f64, near: &mut Vec<usize>) -> Option<Refined> {
        let (_, _, assignment) = self.score_in_range(pose, factor, near);
        self.fit_and_rescore(pose, &assignment, near)
    }

    /// The detections within `factor` × the inlier threshold of a landmark in range of
    /// `pose`, scored as by [`Search::score`] (`near` receives the landmarks in range).
    fn score_in_range(
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
    fn in_range(&mut self, position: &Vector3<f64>, out: &mut Vec<usize>) {
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
    fn fit_and_rescore(
        &mut self,
        pose: &Pose,
        assignment: &[Option<usize>],
        near: &mut Vec<usize>,
    ) -> Option<Refined> {
        let fitted = self.fit(pose, assignment)?;
        let pose = fitted.world_from_rig;
        let (inliers, cost, assignment) = self.score_in_range(&pose, 1.0, near);
        Some(Refined {
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
    fn refine_once(&mut self, start: &Pose) -> Option<Refined> {
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
    fn refine(&mut self, start: &Pose, near: &mut Vec<usize>) -> Option<Refined> {
        let mut result: Option<Refined> = None;
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

fn same_pose(a: &Pose, b: &Pose) -> bool {
    (a.translation.vector - b.translation.vector).norm() < DISTINCT_POSITION_M
        && rotation_angle(&(a.rotation.inverse() * b.rotation)) < DISTINCT_ROTATION_RAD
}

/// `det[up, a, b]` for two bearings and a bound on how far the true value (the true up,
/// within `tol` of `up`, and the true bearings, each within `noise`, radians) may be from
/// it. With a known vertical this is a rotation invariant: it equals `det[z, uᵢ, uⱼ]` for
/// the world directions of the two landmarks, i.e. `cos eₐ cos e_b sin(α_b − αₐ)` in
/// elevations and azimuths. Tilting `up` by at most `tol` changes it by at most
/// `2 sin(tol/2) |a × b|`, and moving each bearing by at most `noise` (a chord of at most
/// `noise`) changes it, and the norm of the cross product, by at most `2 noise + noise²`.
fn det_of_bearings(
    up: &Vector3<f64>,
    tol: f64,
    noise: f64,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
) -> (f64, f64) {
    let cross = a.cross(b);
    let wobble = 2.0 * noise + noise * noise;
    let tilt = 2.0 * (0.5 * tol.min(std::f64::consts::PI)).sin();
    (up.dot(&cross), tilt * (cross.norm() + wobble) + wobble)
}

/// Whether `t` lies in the axis-aligned box `[min, max]` (bounds included).
fn in_box(t: &Vector3<f64>, min: &Vector3<f64>, max: &Vector3<f64>) -> bool {
    (0..3).all(|a| t[a] >= min[a] && t[a] <= max[a])
}

/// The range of `det[z, uᵢ(x), uⱼ(x)]` (`u`: unit directions from `x` to the landmarks) over
/// every point `x` of a cell inside the ball of radius `radius` around `centre` and inside
/// the vertical cylinder of radius `half_horizontal` around it, with the landmarks anywhere
/// within their survey bounds `eᵢ, eⱼ` (metres) of `Lᵢ, Lⱼ`.
///
/// `det[z, uᵢ, uⱼ] = N(x) / (ρᵢ(x) ρⱼ(x))` with `N(x) = ((Lᵢ − x) × (Lⱼ − Lᵢ))_z`. `N` is
/// linear in `x` (zero on the vertical plane through both landmarks), so over the cylinder
/// it stays within `|Lⱼ − Lᵢ|_xy · half_horizontal` of `N(centre)`, and the survey bounds
/// change it by at most `eᵢ |Lⱼ − x|_xy + eⱼ |Lᵢ − x|_xy + eᵢ eⱼ`; each range `ρ` is within
/// `radius + e` of its value from the centre. The quotient's range follows by interval
/// arithmetic, clamped to `[−1, 1]`; `[−1, 1]` when a range may reach 0.
///
/// The matcher evaluates it from its pieces ([`DetSide`] per landmark and cell,
/// [`PairTerms`] per landmark pair) with [`det_range`]; this form is the reference the tests
/// check.
#[cfg(test)]
fn det_range_from_above(
    (li, ei): (&Vector3<f64>, f64),
    (lj, ej): (&Vector3<f64>, f64),
    centre: &Vector3<f64>,
    radius: f64,
    half_horizontal: f64,
) -> (f64, f64) {
    let side = |l: &Vector3<f64>, e: f64| {
        let v = l - centre;
        DetSide::new(&v, v.norm(), e, radius, half_horizontal)
    };
    let pair = PairTerms::new((li, ei), (lj, ej), half_horizontal);
    det_range(&side(li, ei), &side(lj, ej), &pair)
}

/// The pieces of [`det_range`] that depend on one landmark and the cell (computed once per
/// candidate of a cell instead of once per pair).
#[derive(Clone, Copy)]
struct DetSide {
    /// `(L − centre)_xy`, metres.
    from_xy: Vector2<f64>,
    /// `|(L − centre)_xy| + half_horizontal`: the factor of the other landmark's survey bound
    /// in the reach of `N`, metres.
    widened: f64,
    /// The survey bound `e = k σ`, metres.
    survey_m: f64,
    /// The least range over the cell, `ρ − radius − e` (no bound when `≤ 0`), metres.
    range_lo: f64,
    /// `1 / range_lo` (meaningful when `range_lo > 0`), 1/metres.
    inv_lo: f64,
    /// `1 / (ρ + radius + e)`, the reciprocal of the largest range over the cell, 1/metres.
    inv_hi: f64,
}

impl DetSide {
    /// `v = L − centre`, `range = |v|`, survey bound `e`.
    fn new(v: &Vector3<f64>, range: f64, e: f64, radius: f64, half_horizontal: f64) -> Self {
        let from_xy = v.xy();
        Self {
            from_xy,
            widened: from_xy.norm() + half_horizontal,
            survey_m: e,
            range_lo: range - radius - e,
            inv_lo: 1.0 / (range - radius - e),
            inv_hi: 1.0 / (range + radius + e),
        }
    }
}

/// The terms of a landmark pair `(i, j)` (`i` first in database order) that do not depend on
/// the cell: computed once per frame for the landmarks within reach of a small search area,
/// shared by every cell (per pair of each cell otherwise).
#[derive(Clone, Copy)]
struct PairTerms {
    /// `|Lᵢ − Lⱼ|`, metres (for [`pair_angle_wander`]).
    separation_m: f64,
    /// `(Lⱼ − Lᵢ)_xy`, metres.
    baseline: Vector2<f64>,
    /// `|(Lⱼ − Lᵢ)_xy| · half_horizontal`, square metres.
    spread: f64,
    /// `eᵢ eⱼ`, square metres.
    survey_product: f64,
}

impl PairTerms {
    fn new(
        (li, ei): (&Vector3<f64>, f64),
        (lj, ej): (&Vector3<f64>, f64),
        half_horizontal: f64,
    ) -> Self {
        let baseline = (lj - li).xy();
        Self {
            separation_m: (li - lj).norm(),
            baseline,
            spread: baseline.norm() * half_horizontal,
            survey_product: ei * ej,
        }
    }
}

/// `det_range_from_above` from its per-landmark and per-pair pieces: the same expressions
/// in the same order, so the same bits.
fn det_range(i: &DetSide, j: &DetSide, pair: &PairTerms) -> (f64, f64) {
    if i.range_lo <= 0.0 || j.range_lo <= 0.0 {
        return (-1.0, 1.0);
    }
    let n = i.from_xy.perp(&pair.baseline);
    let reach = pair.spread + i.survey_m * j.widened + j.survey_m * i.widened + pair.survey_product;
    let (n_lo, n_hi) = (n - reach, n + reach);
    // Reciprocals of the least and the largest products of the two ranges: each end of the
    // quotient's range divides by the one that makes it extreme for its sign.
    let inv_den_lo = i.inv_lo * j.inv_lo;
    let inv_den_hi = i.inv_hi * j.inv_hi;
    let lo = n_lo * if n_lo >= 0.0 { inv_den_hi } else { inv_den_lo };
    let hi = n_hi * if n_hi <= 0.0 { inv_den_hi } else { inv_den_lo };
    (lo.max(-1.0), hi.min(1.0))
}

/// Largest error of [`fast_acos`], radians. The approximation is accurate to 2.2·10⁻⁸
/// (checked on 2·10⁶ points, `fast_acos_is_within_its_error_bound`); the rest is room for
/// rounding. It is added to every pair bound built on the angle, so the pair tables stay
/// sound.
const FAST_ACOS_MAX_ERROR_RAD: f64 = 1e-7;

/// `acos(x)` (radians, in `[0, π]`) for `x` in `[−1, 1]` (clamped), to within
/// [`FAST_ACOS_MAX_ERROR_RAD`]: `acos(|x|) = √(1 − |x|) · P(|x|)` with the degree-7
/// polynomial of Abramowitz & Stegun, and `acos(x) = π − acos(−x)` for `x < 0`. One square
/// root and seven multiply-adds, against libm's correctly rounded `acos`, which took an
/// eighth of a prior frame's time in the cell set-up (one angle per candidate pair).
///
/// # References
/// M. Abramowitz and I. A. Stegun, *Handbook of Mathematical Functions* (1964), 4.4.46.
fn fast_acos(x: f64) -> f64 {
    const A: [f64; 8] = [
        1.570_796_305_0,
        -0.214_598_801_6,
        0.088_978_987_4,
        -0.050_174_304_6,
        0.030_891_881_0,
        -0.017_088_125_6,
        0.006_670_090_1,
        -0.001_262_491_1,
    ];
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let p = A.iter().rev().fold(0.0, |p, &c| p * a + c);
    let r = (1.0 - a).sqrt() * p;
    if x >= 0.0 {
        r
    } else {
        std::f64::consts::PI - r
    }
}

/// Largest error of [`fast_atan2`] (radians): the fit's 3.8e-8 with a margin for rounding.
const FAST_ATAN_MAX_ERROR_RAD: f64 = 1e-7;

/// `atan2(y, x)` (radians, in `[−π/2, π/2]`) for `x ≥ 0`, to within
/// [`FAST_ATAN_MAX_ERROR_RAD`]: `atan(a) = a · P(a²)` for `a = min(|x|, |y|) / max(|x|, |y|)`
/// in `[0, 1]` (`P` of degree 7, a minimax fit made for this crate; tested against libm on a
/// dense grid), `π/2 − atan(1/a)` when `|y| > |x|`, and the sign of `y`. One division and
/// eight multiply-adds, against libm's `atan2`, which took 3 % of a prior frame's time in
/// the cell set-up (two per candidate and cell). `0` for `x = y = 0`; finite inputs.
fn fast_atan2(y: f64, x: f64) -> f64 {
    const P: [f64; 8] = [
        0.999_999_335_580_321_8,
        -0.333_298_607_867_919_5,
        0.199_465_656_490_803_72,
        -0.139_086_294_463_775_77,
        0.096_421_969_012_260_7,
        -0.055_912_319_319_527_62,
        0.021_862_951_841_463_554,
        -0.004_054_565_351_761_397,
    ];
    let (ay, ax) = (y.abs(), x.abs());
    let steep = ay > ax;
    let (num, den) = if steep { (ax, ay) } else { (ay, ax) };
    if den == 0.0 {
        return 0.0;
    }
    let a = num / den;
    let t = a * a;
    let r = a * P.iter().rev().fold(0.0, |p, &c| p * t + c);
    let r = if steep {
        std::f64::consts::FRAC_PI_2 - r
    } else {
        r
    };
    r.copysign(y)
}

/// The range of elevations (radians) of the offset `v = L − c` seen from every point of the
/// cylinder of horizontal radius `half_horizontal` and half-height `half_vertical` around the
/// cell centre `c` (which contains the cell). Elevation `atan2(dz, d)` is monotone in the
/// height difference `dz` and in the horizontal distance `d ≥ 0` separately, so its extremes
/// are at the corners of `[dz ± half_vertical] × [max(0, d − half_horizontal), d +
/// half_horizontal]`. Evaluated by [`fast_atan2`] and widened by its error bound, so the
/// range still holds every elevation.
fn elevation_range(v: &Vector3<f64>, half_horizontal: f64, half_vertical: f64) -> (f64, f64) {
    let d = v.xy().norm();
    let (d_lo, d_hi) = ((d - half_horizontal).max(0.0), d + half_horizontal);
    let (dz_lo, dz_hi) = (v.z - half_vertical, v.z + half_vertical);
    // Increasing in `dz`; in `d`, decreasing above the viewpoint and increasing below it:
    // the two extreme corners, without evaluating the other two.
    let lo = fast_atan2(dz_lo, if dz_lo >= 0.0 { d_hi } else { d_lo });
    let hi = fast_atan2(dz_hi, if dz_hi >= 0.0 { d_lo } else { d_hi });
    (lo - FAST_ATAN_MAX_ERROR_RAD, hi + FAST_ATAN_MAX_ERROR_RAD)
}

/// Fisher–Yates shuffle with the crate's reproducible generator.
fn shuffle<T>(items: &mut [T], seed: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for i in (1..items.len()).rev() {
        let j = rng.random_range(0..=i);
        items.swap(i, j);
    }
}

/// What the pair tables test of a candidate pair `(i, j)` of a cell (see [`CellData`]).
#[derive(Clone, Copy)]
struct PairValues {
    /// The angle between the directions to the two candidates from the cell centre, radians.
    angle: f64,
    /// How far the angle may be from `angle` over the cell, plus the survey terms and the
    /// error of [`fast_acos`], radians: [`pair_angle_wander`] `+ surveyᵢ + surveyⱼ`.
    bound: f64,
    /// With a known vertical, the range of `det[z, uᵢ(x), uⱼ(x)]` (unit directions to the
    /// landmarks) over the cell ([`det_range_from_above`]); `(−1, 1)` without.
    det: (f64, f64),
}

impl PairValues {
    /// The value on the diagonal, which the tables never test (`i ≠ j`).
    const DIAGONAL: Self = Self {
        angle: 0.0,
        bound: 0.0,
        det: (-1.0, 1.0),
    };

    /// The values of the pair `(j, i)`: the side of the pair changes sign.
    fn mirrored(self) -> Self {
        let (lo, hi) = self.det;
        Self {
            det: (-hi, -lo),
            ..self
        }
    }
}

/// What computing a cell's [`PairValues`] needs besides the cell: the frame's shared pair
/// terms, when the area is small enough to have them, and the cells' size.
struct PairContext {
    /// The [`PairTerms`] of every pair of the landmarks within reach of the whole area, row
    /// by row of the triangle `(a, b)`, `b > a` (empty: computed per pair).
    shared_pairs: Vec<PairTerms>,
    /// Start of row `a` of `shared_pairs`: pair `(a, b)` is at `row_start[a] + b − a − 1`.
    row_start: Vec<usize>,
    /// The cells' ball radius, metres.
    radius: f64,
    /// The cells' horizontal half-diagonal, metres.
    half_horizontal: f64,
    /// Whether the vertical is known (the side of a pair is tested).
    with_up: bool,
}

impl PairContext {
    /// The values of the candidate pair `(i, j)`, `i < j` (database order) of a cell.
    fn values(
        &self,
        db: &LandmarkDb,
        cands: &[Candidate],
        sides: &[DetSide],
        slots: &[usize],
        i: usize,
        j: usize,
    ) -> PairValues {
        let (ci, cj) = (&cands[i], &cands[j]);
        let (si, sj) = (&sides[i], &sides[j]);
        let pair = if self.shared_pairs.is_empty() {
            let (li, lj) = (&db.landmarks()[ci.index], &db.landmarks()[cj.index]);
            PairTerms::new(
                (&li.position_in_world, si.survey_m),
                (&lj.position_in_world, sj.survey_m),
                self.half_horizontal,
            )
        } else {
            self.shared_pairs[self.row_start[slots[i]] + slots[j] - slots[i] - 1]
        };
        PairValues {
            // The `acos` of the dot product of unit vectors (its error near 0 and π, about
            // 1e-8 rad, is far below the bearing noise), by a polynomial: libm's `acos` took
            // an eighth of a prior frame's time.
            angle: fast_acos(ci.direction.dot(&cj.direction)),
            bound: pair_angle_wander(ci, cj, pair.separation_m, self.radius)
                + ci.survey
                + cj.survey
                + FAST_ACOS_MAX_ERROR_RAD,
            // Which side of each other landmark a landmark is, seen from above.
            det: if self.with_up {
                det_range(si, sj, &pair)
            } else {
                (-1.0, 1.0)
            },
        }
    }
}

/// Above this many landmark pairs within reach of the whole search area, the [`PairTerms`]
/// are computed per cell instead of once per frame: a cold start over a city would fill a
/// table of every pair of its landmarks, mostly never in one cell together.
const MAX_SHARED_PAIRS: usize = 1 << 15;

/// Relative widening of the query for the landmarks within reach of the whole area, so that
/// it holds every landmark a cell's own query would find despite rounding.
const REACH_SLACK: f64 = 1e-9;

/// The cells with at least three candidates, nearest to the area's centre first, each with
/// its candidates seen from the centre and per detection the candidates it may be, and what
/// computing their pair values needs ([`PairContext`]): the pairwise angles, bounds and
/// (with a known vertical) determinant ranges are computed when a pair table first reads
/// them ([`CellData::ensure_pairs`]).
///
/// Work that does not depend on the cell is done once: the detections' elevations, and for a
/// small area (a prior) the landmarks within reach of the whole area, gathered contiguously,
/// with the [`PairTerms`] of each of their pairs; a cell's candidates are then those of
/// them within its reach, by the same squared-distance test as [`LandmarkDb::within`].
/// Per candidate, the pieces of the pair quantities that depend on one landmark
/// ([`DetSide`]) are computed once, so that per pair only the angle ([`fast_acos`]), the
/// angle bound and the determinant range remain. The bound and the determinant range come
/// from the same expressions as the direct per-pair formulas ([`pair_angle_wander`],
/// `det_range_from_above`); the angle is within [`FAST_ACOS_MAX_ERROR_RAD`] of libm's, which
/// the bound includes.
#[inline(never)]
fn cell_data(
    search: &Search,
    centres: Vec<Vector3<f64>>,
    area_centre: &Vector3<f64>,
    area_reach: f64,
    shape: &CellShape,
) -> (Cells, PairContext) {
    let db = search.db;
    let options = search.options;
    let up = search.up;
    let n = search.detections.len();
    let k = options.inlier_threshold_sigmas;
    let mut keyed: Vec<(f64, Vector3<f64>)> = centres
        .into_iter()
        .map(|c| ((c - area_centre).norm(), c))
        .collect();
    keyed.sort_by(|x, y| x.0.total_cmp(&y.0));
    let CellShape {
        radius,
        half_horizontal,
        half_vertical,
    } = *shape;
    // A cell's candidates: the landmarks within this distance of its centre.
    let cell_reach = options.visibility_range_m + radius;

    // The landmarks within reach of the whole area (a superset of every cell's candidates),
    // with the terms of each of their pairs, when they are few enough.
    let mut shared: Vec<usize> = Vec::new();
    let mut shared_points: Vec<Vector3<f64>> = Vec::new();
    let mut shared_pairs: Vec<PairTerms> = Vec::new();
    if area_reach.is_finite() {
        db.within(
            area_centre,
            area_reach * (1.0 + REACH_SLACK) + REACH_SLACK,
            &mut shared,
        );
        let g = shared.len();
        if g * g.saturating_sub(1) / 2 <= MAX_SHARED_PAIRS {
            shared_points = shared
                .iter()
                .map(|&index| db.landmarks()[index].position_in_world)
                .collect();
            shared_pairs.reserve(g * g.saturating_sub(1) / 2);
            for (a, &index_a) in shared.iter().enumerate() {
                let la = &db.landmarks()[index_a];
                for &index_b in &shared[a + 1..] {
                    let lb = &db.landmarks()[index_b];
                    shared_pairs.push(PairTerms::new(
                        (&la.position_in_world, k * la.sigma_m),
                        (&lb.position_in_world, k * lb.sigma_m),
                        half_horizontal,
                    ));
                }
            }
        } else {
            shared.clear();
        }
    }
    let use_shared = !shared_points.is_empty();
    // Start of row `a` of the triangular `shared_pairs` (the pairs `(a, b)`, `b > a`, row by
    // row): pair `(a, b)` is at `row_start[a] + b − a − 1`.
    let g = shared_points.len();
    let row_start: Vec<usize> = (0..g).map(|a| a * (2 * g - a - 1) / 2).collect();

    // Per detection: its elevation, with a known vertical.
    let elevations: Vec<Option<f64>> = search
        .directions
        .iter()
        .map(|d| up.map(|(u, _)| d.dot(&u).clamp(-1.0, 1.0).asin()))
        .collect();
    // Whether a detection has a class (only then are classes compared).
    let classed = search.detections.iter().any(|d| d.class.is_some());
    // With a known vertical, the detections in increasing elevation: the detections within a
    // candidate's elevation gate are a run of them.
    let mut by_elevation: Vec<(f64, usize)> = elevations
        .iter()
        .enumerate()
        .filter_map(|(d, e)| e.map(|e| (e, d)))
        .collect();
    by_elevation.sort_by(|x, y| x.0.total_cmp(&y.0));

    let mut near = Vec::new();
    let mut cell_data = Cells(Vec::new());
    for (_, centre) in &keyed {
        // The candidates, seen from the centre, in increasing database index; per candidate
        // its position in `shared` and its [`DetSide`].
        let mut cell = take_cell();
        let (cands, slots, sides) = (&mut cell.cands, &mut cell.slots_shared, &mut cell.sides);
        cands.clear();
        slots.clear();
        sides.clear();
        let mut add = |index: usize, slot: usize, position: &Vector3<f64>| {
            let v = position - centre;
            let range = v.norm();
            let Some(direction) = try_unit(&v) else {
                return;
            };
            let e = k * db.landmarks()[index].sigma_m;
            cands.push(Candidate::new(
                index,
                &v,
                direction,
                range,
                radius,
                survey_angle(e, range, radius),
            ));
            slots.push(slot);
            sides.push(DetSide::new(&v, range, e, radius, half_horizontal));
        };
        if use_shared {
            // `LandmarkDb::within`'s test: the squared distance (summed x, y, z) against
            // the squared radius.
            let limit = cell_reach * cell_reach;
            for (slot, (&index, p)) in shared.iter().zip(&shared_points).enumerate() {
                let d = p - centre;
                if d.x * d.x + d.y * d.y + d.z * d.z <= limit {
                    add(index, slot, p);
                }
            }
        } else {
            db.within(centre, cell_reach, &mut near);
            for &index in &near {
                add(index, 0, &db.landmarks()[index].position_in_world);
            }
        }
        #[cfg(debug_assertions)]
        if use_shared {
            db.within(centre, cell_reach, &mut near);
            near.retain(|&index| {
                try_unit(&(db.landmarks()[index].position_in_world - centre)).is_some()
            });
            let found: Vec<usize> = cands.iter().map(|c| c.index).collect();
            debug_assert_eq!(
                found, near,
                "the candidates of a cell from the shared landmarks"
            );
        }
        if cands.len() < 3 {
            recycle_cells(&mut vec![cell]);
            continue;
        }
        let cands = &cell.cands;
        let m = cands.len();
        let words = m.div_ceil(64);
        let mut allowed = std::mem::take(&mut cell.allowed);
        allowed.clear();
        allowed.resize(n * words, 0);
        // Per candidate: its elevation range over the cell, widened by the tilt tolerance,
        // the bearing noise and the survey error.
        // Candidate by candidate, its bit in the row of each detection it may be: with a
        // known vertical those within its elevation gate (a run of `by_elevation`), else all.
        for (i, cand) in cands.iter().enumerate() {
            let (word, bit) = (i / 64, 1u64 << (i % 64));
            let mut set = |d: usize| {
                if !classed || search.compatible(d, cand.index) {
                    allowed[d * words + word] |= bit;
                }
            };
            match up {
                Some((_, tol)) => {
                    let v = db.landmarks()[cand.index].position_in_world - centre;
                    let (lo, hi) = elevation_range(&v, half_horizontal, half_vertical);
                    let margin = tol + search.noise + cand.survey;
                    let (lo, hi) = (lo - margin, hi + margin);
                    let first = by_elevation.partition_point(|&(e, _)| e < lo);
                    for &(e, d) in &by_elevation[first..] {
                        if e > hi {
                            break;
                        }
                        set(d);
                    }
                }
                None => (0..n).for_each(&mut set),
            }
        }
        cell.indices.clear();
        cell.indices.extend(cands.iter().map(|c| c.index));
        cell.centre = *centre;
        cell.words = words;
        cell.allowed = allowed;
        // Stale pair values are never read (`pairs_done`).
        if cell.pairs.len() < m * m {
            cell.pairs.resize(m * m, PairValues::DIAGONAL);
        }
        cell.pairs_done.clear();
        cell.pairs_done.resize(m * words, 0);
        cell.slots.clear();
        cell.slots.resize(n * n, NO_TABLE);
        cell.store.clear();
        cell.store.reserve(m * words * INITIAL_PAIR_TABLES);
        cell_data.push(cell);
    }
    let context = PairContext {
        shared_pairs,
        row_start,
        radius,
        half_horizontal,
        with_up: up.is_some(),
    };
    (cell_data, context)
}

/// The landmark pairs of a triple, in the order of [`LevelledTriple`]'s arrays.
const TRIPLE_PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Added to the azimuth bound of [`LevelledTriple`] for the rounding of a P3P pose (its
/// distance equations hold to 1e-9 relative), radians.
const AZIMUTH_TEST_SLACK_RAD: f64 = 1e-6;

/// A detection triple's bearings levelled with the known vertical `u`, for
/// [`azimuths_can_meet`]: per pair `(p, q)` of [`TRIPLE_PAIRS`], the cosine and sine of the
/// difference `γ = α_q − α_p` of the bearings' azimuths about `u`, and how far a pose tilted
/// by at most `tilt` may move it.
///
/// **The azimuth bound.** A pose `world_from_rig = R` whose up `R u` is within `tilt` of the
/// world's `z` is `R = H · Rz(ψ) · Q`, with `Q` the fixed rotation taking `u` to `z` (the
/// levelled bearings `q = Q b` have elevation `e = asin(u·b)` and azimuth `α`), `Rz(ψ)` a
/// heading and `H` the least rotation taking `z` to `R u`: its angle is at most `tilt` and
/// its axis is horizontal. About a horizontal axis (say `x`) by `θ`, a direction at elevation
/// `e` and azimuth `a` keeps its horizontal x-component and its y-component changes by
/// `cos e sin a (cos θ − 1) − sin e sin θ`, so its horizontal projection (length `cos e`)
/// moves by at most `cos e (1 − cos θ) + |sin e| sin θ` and its azimuth by at most
/// `η = asin((1 − cos θ) + |tan e| sin θ)` (increasing in `θ ≤ π/2`; `π/2` when the
/// argument reaches 1). So the world azimuths of a P3P pose's landmark directions are
/// `α + ψ + ε` with `|ε| ≤ η` per bearing, and the horizontal angle under which the pose
/// sees two landmarks differs from `γ` by at most `η_p + η_q`. The two bearings share one
/// tilt, so the difference `ε_q − ε_p` is bounded more tightly by
/// [`shared_tilt_azimuth_bound`]; the smaller bound is used.
#[derive(Clone, Copy)]
struct LevelledTriple {
    /// `cos γ` per pair.
    cos: [f64; 3],
    /// `sin γ` per pair.
    sin: [f64; 3],
    /// `sin(min(η_p + η_q, B_pq, π/2))` per pair (`B_pq` of
    /// [`shared_tilt_azimuth_bound`]): the bound on `|sin(θ − γ)|` for the angle `θ` under
    /// which an upright-enough pose sees the pair.
    tolerance: [f64; 3],
}

impl LevelledTriple {
    /// From three unit bearings, the unit up `u` and the tilt bound (radians); `None` when
    /// the test cannot be used: a tilt of `π/2` or more, or a bearing along `±u` (no
    /// azimuth).
    fn new(bearings: &[Vector3<f64>; 3], up: &Vector3<f64>, tilt: f64) -> Option<Self> {
        if tilt.is_nan() || tilt >= std::f64::consts::FRAC_PI_2 {
            return None;
        }
        // A basis of the plane normal to `u`, with `(e1, e2, u)` right-handed like the
        // world's `(x, y, z)`.
        let seed = if up.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = try_unit(&(seed - up * up.dot(&seed)))?;
        let e2 = up.cross(&e1);
        let (sin_t, cos_t) = tilt.sin_cos();
        let mut flat = [Vector2::zeros(); 3];
        let mut tan_e = [0.0; 3];
        let mut eta = [0.0; 3];
        for (p, b) in bearings.iter().enumerate() {
            let h = Vector2::new(b.dot(&e1), b.dot(&e2));
            let n = h.norm();
            if n.is_nan() || n <= 0.0 {
                return None;
            }
            flat[p] = h / n;
            tan_e[p] = b.dot(up) / n;
            let reach = (1.0 - cos_t) + tan_e[p].abs() * sin_t;
            eta[p] = if reach < 1.0 {
                reach.asin()
            } else {
                std::f64::consts::FRAC_PI_2
            };
        }
        let pair = |f: &dyn Fn(usize, usize) -> f64| TRIPLE_PAIRS.map(|(p, q)| f(p, q));
        let sin = pair(&|p, q| flat[p].perp(&flat[q]));
        Some(Self {
            cos: pair(&|p, q| flat[p].dot(&flat[q])),
            sin,
            tolerance: std::array::from_fn(|k| {
                let (p, q) = TRIPLE_PAIRS[k];
                let shared = shared_tilt_azimuth_bound(
                    (tan_e[p], &flat[p]),
                    (tan_e[q], &flat[q]),
                    sin[k],
                    (sin_t, cos_t),
                );
                (shared.min(eta[p] + eta[q]) + 2.0 * AZIMUTH_TEST_SLACK_RAD)
                    .min(std::f64::consts::FRAC_PI_2)
                    .sin()
            }),
        })
    }
}

/// A bound on how far one tilt of at most `τ` (`(sin τ, cos τ)`, `0 ≤ τ < π/2`) moves the
/// difference of the azimuths of two directions, radians; `+∞` when it does not apply.
/// Each direction is given by the tangent `t = tan e` of its elevation (signed) and its unit
/// horizontal direction `f = e^{iα}` about the vertical; `sin_gamma = sin(α_q − α_p)`.
///
/// **Derivation.** Tilt about a horizontal axis at azimuth `β` by `θ` (`0 ≤ θ ≤ τ`; the other
/// sense is the axis at `β + π`), and write `a = α − β` (after any heading: it cancels below). The
/// horizontal projection of the direction, divided by `cos e`, goes from `e^{ia}` to
/// `cos a + i (sin a cos θ − t sin θ) = e^{ia} − i k`, `k = sin a (1 − cos θ) + t sin θ`,
/// so its azimuth moves by `ε = arg(1 + z)`, `z = −i k e^{−ia}`, `|z| = |k| ≤ K =
/// (1 − cos τ) + |t| sin τ`. For `K < 1`, `|arg(1 + z) − Im z| ≤ |log(1 + z) − z| ≤
/// Σ_{n≥2} |z|ⁿ/n ≤ K² / (2 (1 − K)) =: r` (the principal `arg` is the continuous one: `1 + z`
/// stays in the right half-plane), and `Im z = −k cos a = −t sin θ cos a − ½ (1 − cos θ)
/// sin 2a`. For two directions under the same `(β, θ)`:
/// `ε_p − ε_q = −sin θ Re[(t_p e^{iα_p} − t_q e^{iα_q}) e^{−iβ}] − ½ (1 − cos θ)
/// Im[(e^{2iα_p} − e^{2iα_q}) e^{−2iβ}] + (R_p − R_q)`, `|R| ≤ r`, hence
/// `|ε_p − ε_q| ≤ sin τ |t_p f_p − t_q f_q| + (1 − cos τ) |sin(α_q − α_p)| + r_p + r_q`
/// (`|e^{2iα_p} − e^{2iα_q}| = 2 |sin(α_q − α_p)|`). To first order this is
/// `τ |tan e_p e^{iα_p} − tan e_q e^{iα_q}|`: small for two landmarks at similar elevations in
/// similar directions, where the per-bearing bound `η_p + η_q` is `≈ τ (|t_p| + |t_q|)`.
/// Tested in `shared_tilt_azimuth_bound_holds_for_every_tilt_within_the_tolerance`.
fn shared_tilt_azimuth_bound(
    (t_p, f_p): (f64, &Vector2<f64>),
    (t_q, f_q): (f64, &Vector2<f64>),
    sin_gamma: f64,
    (sin_tau, cos_tau): (f64, f64),
) -> f64 {
    let remainder = |t: f64| {
        let big_k = (1.0 - cos_tau) + t.abs() * sin_tau;
        if big_k < 1.0 {
            big_k * big_k / (2.0 * (1.0 - big_k))
        } else {
            f64::INFINITY
        }
    };
    sin_tau * (f_p * t_p - f_q * t_q).norm()
        + (1.0 - cos_tau) * sin_gamma.abs()
        + remainder(t_p)
        + remainder(t_q)
}

/// Whether a pose that sees three landmarks along the levelled bearings of `triple`, tilted
/// within its bound, can stand within horizontal distance `reach` of a cell centre; the
/// landmarks' horizontal offsets from the centre are `offsets` and their horizontal
/// distances from any such point at most `range_max` (in the matcher: the offset's length,
/// kept per candidate, plus `reach`). A necessary condition: `false` only if no such
/// pose exists.
///
/// For a point `t` (horizontal, relative to the centre) and a pair `(p, q)` with offsets
/// `A, B`, `f(t) = (A − t) × (B − t) cos γ − (A − t)·(B − t) sin γ = ρ_p ρ_q sin(θ − γ)`
/// (`θ` the angle under which `t` sees the pair, `ρ` the horizontal distances), so a pose at
/// `t` needs `|f(t)| ≤ tolerance · ρ_p ρ_q` ([`LevelledTriple`]). `f` is a quadratic in `t`
/// whose quadratic part is `−sin γ |t|²`; for the two pairs `k₁, k₂` through one landmark,
/// `sin γ_{k₂} f_{k₁} − sin γ_{k₁} f_{k₂}` is linear in `t` (it vanishes on the line through
/// that landmark and the 2D resection point) and at most
/// `|sin γ_{k₂}| tol_{k₁} ρρ + |sin γ_{k₁}| tol_{k₂} ρρ =: B` in magnitude. Any combination
/// `μ₁ L₁ + μ₂ L₂` of two such lines is then at most `|μ₁| B₁ + |μ₂| B₂`, and over the disk of
/// radius `reach` a linear `L₀ + g·t` comes no closer to 0 than `|L₀| − |g| reach`: the
/// triple is rejected when that exceeds the bound for the combination of some two lines
/// whose gradient points from the centre at their crossing (the resection point). (Testing
/// each line alone as well rejected 1 % more triples and cost as much as it saved.)
#[inline]
fn azimuths_can_meet(
    triple: &LevelledTriple,
    offsets: &[Vector2<f64>; 3],
    range_max: &[f64; 3],
    reach: f64,
) -> bool {
    // Per pair: f's constant term, its linear part, and the bound on |f|.
    let pair = |k: usize, p: usize, q: usize| {
        let (a, b) = (&offsets[p], &offsets[q]);
        let (c, s) = (triple.cos[k], triple.sin[k]);
        (
            c * (a.x * b.y - a.y * b.x) - s * (a.x * b.x + a.y * b.y),
            Vector2::new(
                c * (a.y - b.y) + s * (a.x + b.x),
                s * (a.y + b.y) - c * (a.x - b.x),
            ),
            triple.tolerance[k] * range_max[p] * range_max[q],
        )
    };
    let (f01, f02, f12) = (pair(0, 0, 1), pair(1, 0, 2), pair(2, 1, 2));
    // Per landmark, its two pairs: the line `l₀ + g·t`, zero on the line through the
    // landmark and the resection point, and the bound on its magnitude.
    let line = |(f1, g1, b1): (f64, Vector2<f64>, f64),
                s1: f64,
                (f2, g2, b2): (f64, Vector2<f64>, f64),
                s2: f64| {
        (
            s2 * f1 - s1 * f2,
            g1 * s2 - g2 * s1,
            s2.abs() * b1 + s1.abs() * b2,
        )
    };
    let [s01, s02, s12] = triple.sin;
    let lines = [
        line(f01, s01, f02, s02),
        line(f01, s01, f12, s12),
        line(f02, s02, f12, s12),
    ];
    let reach2 = reach * reach;
    // Whether `|l₀ + g·t| ≤ b` somewhere in the disk.
    let clear = |l0: f64, g: Vector2<f64>, b: f64| {
        let excess = l0.abs() - b;
        excess <= 0.0 || excess * excess <= g.norm_squared() * reach2
    };
    // Any combination `μ₁ L₁ + μ₂ L₂` is bounded by `|μ₁| B₁ + |μ₂| B₂`; for each two lines,
    // the combination whose gradient points at their crossing (the resection point) from
    // the centre, `μ = adj(G) l₀` with `G` the Gram matrix of the gradients (no division:
    // the test is homogeneous in `μ`).
    let combined = |(l1, g1, b1): (f64, Vector2<f64>, f64),
                    (l2, g2, b2): (f64, Vector2<f64>, f64)| {
        let (g11, g12, g22) = (g1.norm_squared(), g1.dot(&g2), g2.norm_squared());
        let (m1, m2) = (g22 * l1 - g12 * l2, g11 * l2 - g12 * l1);
        clear(
            m1 * l1 + m2 * l2,
            g1 * m1 + g2 * m2,
            m1.abs() * b1 + m2.abs() * b2,
        )
    };
    combined(lines[0], lines[1]) && combined(lines[0], lines[2]) && combined(lines[1], lines[2])
}
/// The P3P poses of every landmark triple in `points` seen along `bearings` (`None`:
/// degenerate bearings, no pose) that pass `keep`, in `poses`, and each triple's range of
/// them (start, count) in `ranges`, in the order of `points`.
fn solve_triples(
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

pub(super) fn run(
    db: &LandmarkDb,
    detections: &[Detection],
    area: &SearchArea,
    options: &MatchOptions,
) -> Result<MatchResult, MatchError> {
    validate(detections, options)?;
    let n = detections.len();
    let (centres, shape) = cells(area, options.cell_size_m)?;
    let radius = shape.radius;
    if n < 3 {
        return Ok(MatchResult::failed(
            MatchStatus::TooFewDetections,
            n,
            format!("{n} detections; a match needs at least 3"),
        ));
    }
    let directions: Vec<Vector3<f64>> = detections
        .iter()
        .filter_map(|d| try_unit(&d.ray.direction))
        .collect();
    // The angles between the detections' bearings, once (the pair tables of every cell,
    // the triples' spread and the core's order use them).
    let mut angles = vec![0.0; n * n];
    for a in 0..n {
        for b in a + 1..n {
            let angle = angle_between(&directions[a], &directions[b]);
            angles[a * n + b] = angle;
            angles[b * n + a] = angle;
        }
    }
    for a in 0..n {
        for b in a + 1..n {
            if angles[a * n + b] < DUPLICATE_ANGLE_RAD {
                return Ok(MatchResult::failed(
                    MatchStatus::DuplicateDetections,
                    n,
                    format!("detections {a} and {b} have the same bearing"),
                ));
            }
        }
    }
    let up = match options.up_in_rig {
        Some((u, tol)) => {
            let u = try_unit(&u).ok_or(MatchError::InvalidOption("up_in_rig"))?;
            if !(tol.is_finite() && tol >= 0.0) {
                return Err(MatchError::InvalidOption("up_in_rig"));
            }
            Some((u, tol))
        }
        None => None,
    };
    // How far a P3P pose from noisy bearings may be from the truth (the bearing noise bound
    // at the visibility range, twice).
    let position_margin =
        options.visibility_range_m * 2.0 * options.inlier_threshold_sigmas * options.sigma_rad;
    let mut search = Search {
        db,
        detections,
        directions,
        options,
        noise: options.inlier_threshold_sigmas * options.sigma_rad,
        kept: Vec::new(),
        hypotheses: 0,
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
    };

    // The cells with candidates, each with its pairwise landmark angles, nearest to the
    // area's centre first.
    let mut near = Vec::new();
    let area_centre = area.center();
    // Fewer than three landmarks within reach of the whole area: no cell to visit.
    // The farthest a point of the area is from its centre: half the box's diagonal, or less
    // for a cylinder.
    let half_box = 0.5 * (area.max_in_world - area.min_in_world).norm();
    let half_extent = area.horizontal_radius_m.map_or(half_box, |r| {
        half_box.min(r.hypot(0.5 * (area.max_in_world.z - area.min_in_world.z)))
    });
    let reach = half_extent + radius + options.visibility_range_m;
    if reach.is_finite() {
        db.within(&area_centre, reach, &mut near);
        if near.len() < 3 {
            return Ok(MatchResult::failed(
                MatchStatus::NoLandmarksInRange,
                n,
                NO_LANDMARKS_IN_RANGE,
            ));
        }
    }
    let (mut cell_data, pair_context) = cell_data(&search, centres, &area_centre, reach, &shape);
    if cell_data.is_empty() {
        return Ok(MatchResult::failed(
            MatchStatus::NoLandmarksInRange,
            n,
            NO_LANDMARKS_IN_RANGE,
        ));
    }

    // Detection triples from the core detections, in a fixed pseudo-random order.
    //
    // Per detection, the (cell, candidate) pairs it may be: the size of its rows and columns
    // in the pair tables (0 for an unusable detection).
    let allowed_counts: Vec<usize> = (0..n)
        .map(|d| {
            cell_data
                .iter()
                .map(|cell| {
                    cell.allowed[d * cell.words..(d + 1) * cell.words]
                        .iter()
                        .map(|w| w.count_ones() as usize)
                        .sum::<usize>()
                })
                .sum()
        })
        .collect();
    let usable: Vec<bool> = allowed_counts.iter().map(|&c| c > 0).collect();
    let n_usable = usable.iter().filter(|&&u| u).count();
    // The confirmation triples run so far (sorted detection indices).
    let mut confirmations_tried: Vec<[usize; 3]> = Vec::new();
    // Every usable detection in farthest-point order; round `r` draws its triples from the
    // first `max_core_detections · CORE_GROWTH^r` of them.
    let order = core_detections(&search.angles, &usable, n_usable);
    let mut survivors: Vec<[usize; 3]> = Vec::new();
    // Per landmark triple of the current detection triple: its index in `to_solve` (and in
    // `solved_ranges`, the range of `solved_poses` that holds its P3P poses inside the area,
    // with the cells' reach, and upright enough).
    // A detection triple solves about 700 distinct landmark triples over a 30 m prior:
    // sized once, so that it does not grow by rehashing during the first triple.
    let mut solved: HashMap<TripleKey, usize, BuildHasherDefault<TripleHasher>> =
        HashMap::with_capacity_and_hasher(SOLVED_TRIPLES_CAPACITY, Default::default());
    // Per detection triple: the distinct landmark triples to solve (their points), and the
    // landmark triples of the cells in visiting order (cell, candidates, index into the
    // former).
    let mut to_solve: Vec<[Vector3<f64>; 3]> = Vec::new();
    let mut work: Vec<(usize, [usize; 3], usize)> = Vec::new();
    // The kept poses of every distinct landmark triple, and each one's range of them.
    let mut solved_poses: Vec<Pose> = Vec::new();
    let mut solved_ranges: Vec<(usize, usize)> = Vec::new();
    // How far from its cell's centre a pose of the cell may be.
    let cell_reach = radius + position_margin;
    // With a known vertical: the rig's up and the largest tilt of a pose worth keeping, the
    // tolerance plus `UP_CHECK_MARGIN_RAD` (P3P's upright check, and the azimuth test).
    let up_limit = up.map(|(u, tol)| (u, tol + UP_CHECK_MARGIN_RAD));
    let reach_min = area.min_in_world.add_scalar(-(radius + position_margin));
    let reach_max = area.max_in_world.add_scalar(radius + position_margin);
    // P3P solves (every hypothesis scored comes from one): the budget of the frame.
    let mut solves = 0usize;
    let mut previous = 0;
    let mut core_size = options.max_core_detections.min(order.len());
    let mut round = 0u64;
    // The inliers of the top hypothesis when the early stop was last checked and refused.
    let mut stop_checked_inliers = 0;
    'rounds: loop {
        let core = &order[..core_size];
        let mut triples = Vec::new();
        for z in previous.max(2)..core.len() {
            for y in 1..z {
                for x in 0..y {
                    let t = [core[x], core[y], core[z]];
                    let ok = (0..3)
                        .all(|p| search.angles[t[p] * n + t[(p + 1) % 3]] >= MIN_TRIPLE_ANGLE_RAD);
                    if ok {
                        triples.push(t);
                    }
                }
            }
        }
        shuffle(&mut triples, options.seed.wrapping_add(round));
        let budget = options
            .max_detection_triples
            .saturating_mul(core_size.div_ceil(options.max_core_detections));
        triples.truncate(budget);
        // The round's triples, cheapest first: by the largest number of (cell, candidate)
        // pairs one of its detections may be (stable, so the pseudo-random order breaks
        // ties). The cost of a triple grows with its detections' candidates (a lamp near the
        // horizon may be any of 80 % of a cell's candidates, a roof corner high up a tenth),
        // and all of a round's triples are run unless one stops the search: the order decides
        // the time to the first triple of true detections, not which triples are run.
        triples.sort_by_key(|t| t.iter().map(|&d| allowed_counts[d]).max());
        // The next triple: a confirmation triple of the best pose when one is due (see
        // `Search::confirmation_triple`), else the next of the round's triples.
        let mut next = 0;
        let mut confirmation: Option<[usize; 3]> = None;
        loop {
            let [a, b, c] = match confirmation.take() {
                Some(t) => t,
                None => {
                    let Some(&t) = triples.get(next) else { break };
                    next += 1;
                    t
                }
            };
            solved.clear();
            let bearings = [
                search.directions[a],
                search.directions[b],
                search.directions[c],
            ];
            // With a known vertical: the levelled azimuths, for the test of a landmark triple
            // before its P3P solve (`azimuths_can_meet`).
            let levelled =
                up_limit.and_then(|(u, limit)| LevelledTriple::new(&bearings, &u, limit));
            let det_b = bearings[0].dot(&bearings[1].cross(&bearings[2]));
            // The orientation test is used only when the sign of the detections' determinant is
            // beyond the noise (each bearing moves by at most `noise`).
            let det_b_reliable = det_b.abs() > RELIABLE_DETERMINANT_NOISES * search.noise;
            let extensions: Vec<usize> = core
                .iter()
                .copied()
                .filter(|&l| l != a && l != b && l != c)
                .collect();
            // `None` for (anti)parallel detections: no landmark triple has a pose for them.
            // With a known vertical, P3P keeps only the poses whose up is within the limit
            // of the world's (no check from π on).
            let prepared = P3pBearings::try_new(&bearings).and_then(|prepared| match up_limit {
                Some((u, limit)) => prepared.with_max_tilt(&u, limit),
                None => Some(prepared),
            });
            // The landmark triples of every cell in visiting order, and the distinct ones
            // among them to solve (each once per detection triple: the same landmark triple
            // passes in neighbouring cells).
            work.clear();
            to_solve.clear();
            let mut budget_spent = false;
            'cells: for (cell_index, cell) in cell_data.iter_mut().enumerate() {
                let words = cell.words;
                for (p, q) in [(a, b), (a, c), (b, c)] {
                    search.ensure_table(cell, &pair_context, p, q);
                }
                // Landmark triples (i, j, k) that pass the three pair tables.
                survivors.clear();
                {
                    let ab = cell.table(a * n + b);
                    let ac = cell.table(a * n + c);
                    let bc = cell.table(b * n + c);
                    for i in 0..cell.cands.len() {
                        let ab_i = &ab[i * words..(i + 1) * words];
                        let ac_i = &ac[i * words..(i + 1) * words];
                        if ab_i.iter().all(|&w| w == 0) || ac_i.iter().all(|&w| w == 0) {
                            continue;
                        }
                        for_each_bit(ab_i, |j| {
                            let bc_j = &bc[j * words..(j + 1) * words];
                            for (wk, (&x, &y)) in ac_i.iter().zip(bc_j).enumerate() {
                                let mut bits_k = x & y;
                                while bits_k != 0 {
                                    let k = wk * 64 + bits_k.trailing_zeros() as usize;
                                    bits_k &= bits_k - 1;
                                    if k != i && k != j {
                                        survivors.push([i, j, k]);
                                    }
                                }
                            }
                        });
                    }
                }
                let cands = &cell.cands;
                let centre = &cell.centre;
                for &[i, j, k] in &survivors {
                    let points = [
                        db.landmarks()[cands[i].index].position_in_world,
                        db.landmarks()[cands[j].index].position_in_world,
                        db.landmarks()[cands[k].index].position_in_world,
                    ];
                    // The orientation test (the sign first: the plane's distance, with its
                    // square root and division, only decides whether the sign may be used).
                    if det_b_reliable
                        && cands[i]
                            .direction
                            .dot(&cands[j].direction.cross(&cands[k].direction))
                            * det_b
                            < 0.0
                    {
                        let normal = (points[1] - points[0]).cross(&(points[2] - points[0]));
                        let nn = normal.norm();
                        if nn > 0.0 && (normal.dot(&(centre - points[0])) / nn).abs() > radius {
                            continue;
                        }
                    }
                    let key = [cands[i].index, cands[j].index, cands[k].index];
                    let slot = match solved.entry(TripleKey(key)) {
                        Entry::Occupied(entry) => *entry.get(),
                        Entry::Vacant(entry) => {
                            // Not solved when no pose of it could be upright enough within
                            // this cell's reach (the only poses this cell uses); nor
                            // remembered, since a neighbouring cell may need it. The
                            // hypotheses are the same as without the test; only `solves`
                            // (the budget) counts fewer.
                            if let Some(levelled) = &levelled
                                && !azimuths_can_meet(
                                    levelled,
                                    &points.map(|l| (l - centre).xy()),
                                    &[
                                        cands[i].horizontal + cell_reach,
                                        cands[j].horizontal + cell_reach,
                                        cands[k].horizontal + cell_reach,
                                    ],
                                    cell_reach,
                                )
                            {
                                continue;
                            }
                            to_solve.push(points);
                            *entry.insert(to_solve.len() - 1)
                        }
                    };
                    work.push((cell_index, [i, j, k], slot));
                    // P3P solves (every hypothesis scored comes from one): the budget.
                    if solves + to_solve.len() >= options.max_hypotheses {
                        budget_spent = true;
                        break 'cells;
                    }
                }
            }
            solves += to_solve.len();
            // Each distinct landmark triple's P3P poses (upright enough) inside the area
            // with the cells' reach.
            let keep_pose = |pose: &Pose| in_box(&pose.translation.vector, &reach_min, &reach_max);
            solve_triples(
                prepared.as_ref(),
                &to_solve,
                keep_pose,
                &mut solved_poses,
                &mut solved_ranges,
            );
            // The hypotheses, in the cells' visiting order.
            for &(cell_index, [i, j, k], slot) in &work {
                let cell = &cell_data[cell_index];
                let centre = &cell.centre;
                let (start, count) = solved_ranges[slot];
                for &pose in &solved_poses[start..start + count] {
                    if (pose.translation.vector - centre).norm() > radius + position_margin {
                        continue;
                    }
                    // Preemptive verification: enough other core detections must each see,
                    // under this exact pose, a candidate landmark of the cell.
                    if options.min_extensions > 0
                        && !search.verify(&pose, &extensions, [i, j, k], cell)
                    {
                        continue;
                    }
                    search.hypotheses += 1;
                    // Only hypotheses that could be the best or a close runner-up are worth
                    // scoring to the end.
                    let best = search.kept.first().map_or(0, |h| h.inliers);
                    let needed = best.saturating_sub(options.ambiguity_margin + 1).max(4);
                    let (inliers, cost, assignment) =
                        search.score(&pose, &cell.indices, HYPOTHESIS_THRESHOLD_FACTOR, needed);
                    if inliers >= options.min_inliers.min(4) {
                        search.keep(pose, inliers, cost, [a, b, c], &assignment);
                    }
                }
            }
            if budget_spent {
                break 'rounds;
            }
            // Early stop only for a best that explains at least half the usable detections: a
            // wrong pose on a repetitive layout can be confirmed twice while the true one (with
            // more inliers) has not been generated yet.
            let enough = options
                .min_inliers
                .max((STOP_MIN_INLIER_FRACTION * n_usable as f64).ceil() as usize);
            if let Some(top) = search.kept.first()
                && top.confirming.len() >= STOP_CONFIRMATIONS as usize
                && top.inliers >= enough
                && top.inliers > stop_checked_inliers
            {
                // Stop only when the refined conclusion is a fix that still explains enough
                // detections: a pose from three nearly collinear lamps can be confirmed twice
                // and still refine into a worse one. The search then goes on, and the stop is
                // checked again once a hypothesis explains more.
                stop_checked_inliers = top.inliers;
                let so_far = conclude(&mut search, cell_data.len());
                if so_far.status == MatchStatus::Ok && so_far.best_score >= enough {
                    return Ok(so_far);
                }
            }
            if confirmations_tried.len() < MAX_CONFIRMATION_TRIPLES {
                confirmation =
                    search.confirmation_triple(enough, &allowed_counts, &confirmations_tried);
                confirmations_tried.extend(confirmation);
            }
        }
        // No early stop: when inliers are few among many detections the core may hold fewer
        // than three of them, so the next round draws from a larger core, unless the
        // hypotheses so far already give a decisive fix.
        if core_size == order.len() || round + 1 >= options.max_rounds as u64 {
            break;
        }
        let so_far = conclude(&mut search, cell_data.len());
        if so_far.status == MatchStatus::Ok {
            return Ok(so_far);
        }
        previous = core_size;
        core_size = core_size.saturating_mul(CORE_GROWTH).min(order.len());
        round += 1;
    }
    Ok(conclude(&mut search, cell_data.len()))
}

/// The result from the hypotheses kept so far. The strongest are refined: a P3P pose from
/// three noisy bearings (nearly collinear lamps along a street) may explain fewer
/// detections than a wrong pose before refinement and all of them after. The refined pose
/// with the most inliers (ties: least truncated cost) is the fix; the runner-up is the
/// distinct pose with the most inliers (a hypothesis that does not refine is scored as it
/// is, at the tight threshold).
fn conclude(search: &mut Search, cells: usize) -> MatchResult {
    let n = search.detections.len();
    let options = search.options;
    let hypotheses = search.hypotheses;
    let failed = |status, message: String| {
        let mut r = MatchResult::failed(status, n, message);
        r.cells = cells;
        r.hypotheses = hypotheses;
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
    let mut refined: Vec<Refined> = Vec::new();
    // Hypotheses that are runner-ups only: those that do not refine (scored as they are) and
    // those outside the area.
    let mut unrefined: Vec<(usize, f64, Pose)> = Vec::new();
    let mut near = Vec::new();
    for start in &starts {
        if refined.iter().any(|r| same_pose(&r.pose, start)) {
            continue;
        }
        let (pose, scored) = match search.refine_once(start) {
            Some(r) if search.within_area(&r.pose) => {
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
        // A pose outside the area (the prior), e.g. one that refinement moved away, cannot
        // be the fix, but it still counts as a runner-up: if the prior is off, it may be the
        // truth, and a look-alike inside the area must not then pass for a fix.
        unrefined.push((scored.0, scored.1, pose));
    }
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
    let runner_up: Option<(usize, f64, Pose)> = refined
        .iter()
        .map(|r| (r.inliers, r.cost, r.pose))
        .chain(unrefined.iter().copied())
        .filter(|(_, _, p)| !same_pose(p, &pose))
        .min_by(|x, y| y.0.cmp(&x.0).then(x.1.total_cmp(&y.1)));
    let mut result = MatchResult {
        status: MatchStatus::Ok,
        message: String::new(),
        estimate: None,
        assignment: vec![None; n],
        link_probability: vec![None; n],
        best_score,
        runner_up_score: runner_up.map(|r| r.0),
        runner_up_pose: runner_up.map(|r| r.2),
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
        && score + options.ambiguity_margin > best_score
    {
        // Up to two inliers short of the margin is enough when the evidence is decisive: the
        // likelihood ratio of the best against all its close rivals together (each inlier
        // weighed by its residual against the density of false detections; a sum over the
        // rivals, since each is a chance for a coincidence) is at least e^DECISIVE_LOG_ODDS.
        let rivals: Vec<f64> = refined
            .iter()
            .map(|r| (r.inliers, r.cost, r.pose))
            .chain(unrefined.iter().copied())
            .filter(|(s, _, p)| s + options.ambiguity_margin > best_score && !same_pose(p, &pose))
            .map(|(s, c, _)| search.log_evidence(&model, s, c))
            .collect();
        let top = rivals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let rivals_evidence = top + rivals.iter().map(|e| (e - top).exp()).sum::<f64>().ln();
        let odds = search.log_evidence(&model, best_score, best.cost) - rivals_evidence;
        let decisive =
            best_score + 2 >= score + options.ambiguity_margin && odds >= DECISIVE_LOG_ODDS;
        if !decisive {
            return result.refused(
                MatchStatus::Ambiguous,
                format!(
                    "two distinct poses with {best_score} and {score} inliers (margin {} needed; log odds {odds:.1})",
                    options.ambiguity_margin
                ),
            );
        }
    }
    // Links. First, while the least probable link is more likely wrong than right, it is
    // dropped and the pose refined on the rest (a false link biases the pose and makes
    // every other link look doubtful); a fix that would then keep fewer than `min_inliers`
    // links is refused. Then only the links whose probability reaches
    // `min_link_probability` are reported (a frame of few detections has links that the
    // others check poorly: they stay in the pose but are not reported).
    let drop_below = options
        .min_link_probability
        .min(LIKELY_WRONG_LINK_PROBABILITY);
    let mut current = best;
    let mut probabilities = search.link_probabilities(&current, &model);
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
        probabilities = search.link_probabilities(&current, &model);
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use vgps_geometry::solvers::p3p::p3p;

    #[test]
    fn fast_acos_is_within_its_error_bound() {
        // A dense grid over [−1, 1], both ends, and points ever closer to ±1, where acos is
        // steepest (the callers pass dot products of unit vectors, never NaN).
        let n = 2_000_000;
        let mut worst = 0.0f64;
        let near_ends = (0..60).flat_map(|k| {
            let t = 0.5f64.powi(k);
            [1.0 - t, -1.0 + t]
        });
        for x in (0..=n)
            .map(|k| -1.0 + 2.0 * k as f64 / n as f64)
            .chain(near_ends)
            .chain([1.0, -1.0, 0.0])
        {
            let e = (fast_acos(x) - x.acos()).abs();
            worst = worst.max(e);
        }
        assert!(worst <= FAST_ACOS_MAX_ERROR_RAD, "{worst}");
        assert!(
            worst > 1e-9,
            "the bound should be close to the error: {worst}"
        );
        // Beyond the range it clamps.
        assert_eq!(fast_acos(1.0 + 1e-12), fast_acos(1.0));
        assert_eq!(fast_acos(-1.0 - 1e-12), fast_acos(-1.0));
    }

    #[test]
    fn fast_atan2_is_within_its_error_bound() {
        // Directions all around the right half-plane (x ≥ 0), dense near the axes and the
        // diagonal, over many scales; the ends and zero.
        let n = 1_000_000;
        let mut worst = 0.0f64;
        for k in 0..=n {
            let angle = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / n as f64;
            let scale = 10f64.powi((k % 13) - 6);
            let (y, x) = (scale * angle.sin(), (scale * angle.cos()).max(0.0));
            worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
        }
        for k in 0..60 {
            let t = 0.5f64.powi(k);
            for (y, x) in [(t, 1.0), (1.0, t), (-t, 1.0), (-1.0, t), (1.0, 1.0 - t)] {
                worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst <= FAST_ATAN_MAX_ERROR_RAD, "{worst}");
        assert!(
            worst > 1e-9,
            "the bound should be close to the error: {worst}"
        );
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert_eq!(fast_atan2(2.0, 0.0), std::f64::consts::FRAC_PI_2);
        assert_eq!(fast_atan2(-2.0, 0.0), -std::f64::consts::FRAC_PI_2);
    }

    #[test]
    fn elevation_range_bounds_every_point_of_the_cylinder() {
        let mut r = vgps_geometry::synthetic::rng(4);
        for _ in 0..200 {
            let v = Vector3::new(
                r.random_range(-60.0..60.0),
                r.random_range(-60.0..60.0),
                r.random_range(-5.0..20.0),
            );
            let (hh, hz) = (r.random_range(0.5..10.0), r.random_range(0.0..2.0));
            let (lo, hi) = elevation_range(&v, hh, hz);
            assert!(lo <= hi);
            for _ in 0..50 {
                let a = r.random_range(0.0..std::f64::consts::TAU);
                let rho = hh * r.random_range(0.0..1.0f64).sqrt();
                let x = Vector3::new(rho * a.cos(), rho * a.sin(), r.random_range(-hz..=hz));
                let w = v - x;
                let e = w.z.atan2(w.xy().norm());
                assert!(
                    e >= lo - 1e-12 && e <= hi + 1e-12,
                    "{e} not in [{lo}, {hi}]"
                );
            }
            // Tight: the centre's own elevation is inside, and the corners are reached.
            let e0 = v.z.atan2(v.xy().norm());
            assert!(lo <= e0 && e0 <= hi);
        }
    }

    /// A pose `world_from_rig` whose up (`u` in the rig) is tilted by exactly `theta` from
    /// the world's `z`, about a random horizontal axis, with a random heading.
    fn tilted_pose<R: rand::Rng + ?Sized>(
        r: &mut R,
        up: &Vector3<f64>,
        theta: f64,
        position: Vector3<f64>,
    ) -> Pose {
        let level = nalgebra::Rotation3::rotation_between(up, &Vector3::z()).unwrap_or_else(|| {
            nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        let heading = nalgebra::Rotation3::from_axis_angle(
            &Vector3::z_axis(),
            r.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        );
        let a = r.random_range(0.0..std::f64::consts::TAU);
        let axis = nalgebra::Unit::new_normalize(Vector3::new(a.cos(), a.sin(), 0.0));
        let tilt = nalgebra::Rotation3::from_axis_angle(&axis, theta);
        Pose::from_parts(position.into(), tilt * heading * level)
    }

    #[test]
    fn shared_tilt_azimuth_bound_holds_for_every_tilt_within_the_tolerance() {
        let mut r = vgps_geometry::synthetic::rng(78);
        let (mut tested, mut tighter, mut near_horizon) = (0, 0, 0);
        let mut worst_ratio = 0f64;
        let trials = 40_000;
        for trial in 0..trials {
            let up = vgps_geometry::synthetic::random_unit_vector(&mut r);
            // Tolerances up to 80°, half of them at the matcher's 6°.
            let tol = if trial % 2 == 0 {
                4f64.to_radians() + UP_CHECK_MARGIN_RAD
            } else {
                r.random_range(0.0..1.4)
            };
            let (sin_t, cos_t) = tol.sin_cos();
            // Tilted by the whole tolerance one time in two.
            let theta = if trial % 4 < 2 {
                tol
            } else {
                tol * r.random_range(0.0..1.0)
            };
            let pose = tilted_pose(&mut r, &up, theta, Vector3::zeros());
            // Three bearings: near the horizon (elevations within ±20°) two times in three, as
            // street lamps are, else anywhere.
            let level =
                nalgebra::Rotation3::rotation_between(&Vector3::z(), &up).unwrap_or_else(|| {
                    nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
                });
            let low = trial % 3 != 2;
            let bearing = |r: &mut vgps_geometry::synthetic::TestRng| {
                if low {
                    let e: f64 = r.random_range(-20f64.to_radians()..20f64.to_radians());
                    let a: f64 = r.random_range(0.0..std::f64::consts::TAU);
                    level * Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
                } else {
                    vgps_geometry::synthetic::random_unit_vector(r)
                }
            };
            let bearings = [bearing(&mut r), bearing(&mut r), bearing(&mut r)];
            let Some(levelled) = LevelledTriple::new(&bearings, &up, tol) else {
                continue;
            };
            // The same levelling as `LevelledTriple::new`.
            let seed = if up.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let e1 = try_unit(&(seed - up * up.dot(&seed))).unwrap();
            let e2 = up.cross(&e1);
            let flat = |b: &Vector3<f64>| {
                let h = Vector2::new(b.dot(&e1), b.dot(&e2));
                (b.dot(&up) / h.norm(), h / h.norm())
            };
            for (k, (p, q)) in TRIPLE_PAIRS.into_iter().enumerate() {
                let ((t_p, f_p), (t_q, f_q)) = (flat(&bearings[p]), flat(&bearings[q]));
                let gamma = f_p.perp(&f_q).atan2(f_p.dot(&f_q));
                let bound = shared_tilt_azimuth_bound(
                    (t_p, &f_p),
                    (t_q, &f_q),
                    levelled.sin[k],
                    (sin_t, cos_t),
                );
                // The azimuth difference in the world under the tilted pose.
                let (d_p, d_q) = (
                    (pose.rotation * bearings[p]).xy(),
                    (pose.rotation * bearings[q]).xy(),
                );
                let seen = d_p.perp(&d_q).atan2(d_p.dot(&d_q));
                let mut moved = seen - gamma;
                if moved > std::f64::consts::PI {
                    moved -= std::f64::consts::TAU;
                } else if moved < -std::f64::consts::PI {
                    moved += std::f64::consts::TAU;
                }
                assert!(
                    moved.abs() <= bound + 1e-9,
                    "trial {trial}: moved {moved} beyond {bound} (tilt {theta} of {tol})"
                );
                tested += 1;
                // The per-bearing bound, as in `LevelledTriple::new`.
                let eta = |t: f64| ((1.0 - cos_t) + t.abs() * sin_t).min(1.0).asin();
                if low && trial % 2 == 0 {
                    near_horizon += 1;
                    if bound < 0.75 * (eta(t_p) + eta(t_q)) {
                        tighter += 1;
                    }
                    if theta == tol {
                        worst_ratio = worst_ratio.max(moved.abs() / bound);
                    }
                }
            }
        }
        assert!(tested > trials * 2, "{tested}");
        // Tighter by a quarter than the per-bearing bound for most pairs near the horizon
        // at the matcher's tolerance, and nearly reached.
        assert!(
            tighter > near_horizon / 2,
            "{tighter} of {near_horizon} tighter by a quarter"
        );
        assert!(worst_ratio > 0.9, "{worst_ratio}");
    }

    #[test]
    fn azimuths_can_meet_holds_for_every_upright_pose_within_reach() {
        let mut r = vgps_geometry::synthetic::rng(77);
        let (mut tested, mut solutions, mut rejected_far) = (0, 0, 0);
        let trials = 20_000;
        for trial in 0..trials {
            let up = vgps_geometry::synthetic::random_unit_vector(&mut r);
            // Tolerances up to 80°, a third of them at the matcher's 6°.
            let tol = if trial % 3 == 0 {
                4f64.to_radians() + UP_CHECK_MARGIN_RAD
            } else {
                r.random_range(0.0..1.4)
            };
            let centre = Vector3::new(
                r.random_range(-50.0..50.0),
                r.random_range(-50.0..50.0),
                r.random_range(0.0..4.0),
            );
            let reach = r.random_range(0.5..12.0);
            // A point of the ball, on its boundary one time in four.
            let dir = vgps_geometry::synthetic::random_unit_vector(&mut r);
            let dist = if trial % 4 == 0 {
                reach
            } else {
                reach * r.random_range(0.0..1.0f64).cbrt()
            };
            let position = centre + dir * dist;
            // Tilted by the whole tolerance one time in four.
            let theta = if trial % 4 == 1 {
                tol
            } else {
                tol * r.random_range(0.0..1.0)
            };
            let pose = tilted_pose(&mut r, &up, theta, position);
            let points: [Vector3<f64>; 3] = std::array::from_fn(|_| {
                position
                    + Vector3::new(
                        r.random_range(-80.0..80.0),
                        r.random_range(-80.0..80.0),
                        r.random_range(-5.0..30.0),
                    )
            });
            let bearings = points.map(|l| pose.rotation.inverse() * (l - position).normalize());
            let offsets = points.map(|l| (l - centre).xy());
            let range_max = points.map(|l| (l - centre).xy().norm() + reach);
            if let Some(levelled) = LevelledTriple::new(&bearings, &up, tol) {
                tested += 1;
                assert!(
                    azimuths_can_meet(&levelled, &offsets, &range_max, reach),
                    "trial {trial}: an upright pose within reach was rejected"
                );
                // The matcher's use: every P3P pose of these bearings on other landmarks
                // that is upright enough passes for any cell within whose reach it lies.
                let others: [Vector3<f64>; 3] = std::array::from_fn(|p| {
                    points[p]
                        + Vector3::new(
                            r.random_range(-20.0..20.0),
                            r.random_range(-20.0..20.0),
                            r.random_range(-3.0..3.0),
                        )
                });
                for solution in p3p(&bearings, &others) {
                    if (solution.rotation * up).z >= tol.cos() {
                        solutions += 1;
                        let t = solution.translation.vector;
                        let cell = t + vgps_geometry::synthetic::random_unit_vector(&mut r)
                            * (reach * r.random_range(0.0..1.0));
                        assert!(
                            azimuths_can_meet(
                                &levelled,
                                &others.map(|l| (l - cell).xy()),
                                &others.map(|l| (l - cell).xy().norm() + reach),
                                reach,
                            ),
                            "trial {trial}: an upright P3P pose within reach was rejected"
                        );
                    }
                }
                // Not vacuous: seen from a cell three reaches away, most such triples fail.
                let far = centre + Vector3::new(3.0 * reach + 10.0, 0.0, 0.0);
                let far_offsets = points.map(|l| (l - far).xy());
                let far_range = points.map(|l| (l - far).xy().norm() + reach);
                if !azimuths_can_meet(&levelled, &far_offsets, &far_range, reach) {
                    rejected_far += 1;
                }
            }
        }
        assert!(tested > trials * 9 / 10, "{tested}");
        assert!(solutions > trials / 10, "{solutions}");
        assert!(
            rejected_far > tested / 4,
            "{rejected_far} of {tested} rejected from a far cell"
        );
    }

    #[test]
    fn pair_angle_wander_bounds_every_point_of_the_ball() {
        let mut r = vgps_geometry::synthetic::rng(21);
        let mut tighter = 0;
        for _ in 0..2_000 {
            let radius = r.random_range(0.5..10.0);
            let li = Vector3::new(
                r.random_range(-80.0..80.0),
                r.random_range(-80.0..80.0),
                r.random_range(-5.0..30.0),
            );
            // Half the second landmarks near the first (a row of lamps), half anywhere.
            let lj = if r.random::<bool>() {
                li + Vector3::new(
                    r.random_range(-30.0..30.0),
                    r.random_range(-3.0..3.0),
                    r.random_range(-1.0..1.0),
                )
            } else {
                Vector3::new(
                    r.random_range(-80.0..80.0),
                    r.random_range(-80.0..80.0),
                    r.random_range(-5.0..30.0),
                )
            };
            let candidate = |l: &Vector3<f64>| {
                let range = l.norm();
                Candidate::new(0, l, l / range, range, radius, 0.0)
            };
            let (ci, cj) = (candidate(&li), candidate(&lj));
            let bound = pair_angle_wander(&ci, &cj, (li - lj).norm(), radius);
            if bound < ci.wander + cj.wander {
                tighter += 1;
            }
            let phi = angle_between(&li, &lj);
            for _ in 0..50 {
                let x = vgps_geometry::synthetic::random_unit_vector(&mut r)
                    * radius
                    * r.random_range(0.0..1.0f64).cbrt();
                let moved = angle_between(&(li - x), &(lj - x));
                assert!(
                    (moved - phi).abs() <= bound + 1e-12,
                    "{moved} vs {phi}: bound {bound}"
                );
            }
        }
        // The gradient bound is the tighter one for most pairs.
        assert!(tighter > 1_000, "{tighter}");
    }

    #[test]
    fn survey_angle_bounds_every_survey_error_seen_from_the_ball() {
        let mut r = vgps_geometry::synthetic::rng(22);
        let mut useful = 0;
        for _ in 0..2_000 {
            let radius = r.random_range(0.5..10.0);
            let survey = r.random_range(0.01..2.0);
            let l =
                vgps_geometry::synthetic::random_unit_vector(&mut r) * r.random_range(0.0..60.0);
            let bound = survey_angle(survey, l.norm(), radius);
            useful += usize::from(bound < 0.1);
            for _ in 0..50 {
                let x = vgps_geometry::synthetic::random_unit_vector(&mut r)
                    * radius
                    * r.random_range(0.0..1.0f64).cbrt();
                let moved = l + vgps_geometry::synthetic::random_unit_vector(&mut r)
                    * survey
                    * r.random_range(0.0..1.0f64).cbrt();
                let turn = angle_between(&(moved - x), &(l - x));
                assert!(turn <= bound + 1e-12, "{turn} > {bound}");
            }
        }
        assert!(useful > 1_000, "{useful}");
        assert_eq!(survey_angle(0.0, 5.0, 8.0), 0.0);
    }

    #[test]
    fn det_range_from_above_holds_over_the_cell_and_the_survey_bounds() {
        let mut r = vgps_geometry::synthetic::rng(22);
        let (mut narrow, mut tested) = (0, 0);
        let point = |r: &mut rand_chacha::ChaCha8Rng| {
            Vector3::new(
                r.random_range(-60.0..60.0),
                r.random_range(-60.0..60.0),
                r.random_range(0.0..30.0),
            )
        };
        for _ in 0..2_000 {
            let (li, lj) = (point(&mut r), point(&mut r));
            let (ei, ej) = (r.random_range(0.0..0.5), r.random_range(0.0..0.5));
            let (half, half_z): (f64, f64) = (r.random_range(0.5..10.0), r.random_range(0.0..2.0));
            let radius = (half * half + half_z * half_z).sqrt();
            let (lo, hi) =
                det_range_from_above((&li, ei), (&lj, ej), &Vector3::zeros(), radius, half);
            assert!(lo <= hi);
            if hi - lo < 0.5 {
                narrow += 1;
            }
            for _ in 0..50 {
                let a = r.random_range(0.0..std::f64::consts::TAU);
                let rho = half * r.random_range(0.0..1.0f64).sqrt();
                let x = Vector3::new(
                    rho * a.cos(),
                    rho * a.sin(),
                    r.random_range(-half_z..=half_z),
                );
                let shift = |r: &mut rand_chacha::ChaCha8Rng, e: f64| {
                    vgps_geometry::synthetic::random_unit_vector(r) * e * r.random_range(0.0..=1.0)
                };
                let (pi, pj) = (li + shift(&mut r, ei), lj + shift(&mut r, ej));
                let (ui, uj) = ((pi - x).normalize(), (pj - x).normalize());
                let det = Vector3::z().dot(&ui.cross(&uj));
                assert!(
                    det >= lo - 1e-12 && det <= hi + 1e-12,
                    "{det} not in [{lo}, {hi}]"
                );
                tested += 1;
            }
        }
        assert!(narrow > 1_000, "{narrow}");
        assert!(tested == 100_000);
    }

    #[test]
    fn det_of_bearings_bounds_every_tilt_and_noise_within_the_tolerances() {
        let mut r = vgps_geometry::synthetic::rng(23);
        for _ in 0..2_000 {
            let up = vgps_geometry::synthetic::random_unit_vector(&mut r);
            let tol = r.random_range(0.0..0.2);
            let noise = r.random_range(0.0..0.01);
            let a = vgps_geometry::synthetic::random_unit_vector(&mut r);
            let b = vgps_geometry::synthetic::random_unit_vector(&mut r);
            let (value, margin) = det_of_bearings(&up, tol, noise, &a, &b);
            // A direction within `angle` of `v`.
            let turn = |r: &mut rand_chacha::ChaCha8Rng, v: &Vector3<f64>, angle: f64| {
                let axis = vgps_geometry::synthetic::random_unit_vector(r);
                match vgps_geometry::geometry::try_unit(&v.cross(&axis)) {
                    Some(w) => {
                        let t = angle * r.random_range(0.0..=1.0);
                        v * t.cos() + w * t.sin()
                    }
                    None => *v,
                }
            };
            for _ in 0..50 {
                let true_up = turn(&mut r, &up, tol);
                let (ta, tb) = (turn(&mut r, &a, noise), turn(&mut r, &b, noise));
                let det = true_up.dot(&ta.cross(&tb));
                assert!(
                    (det - value).abs() <= margin + 1e-12,
                    "{det} vs {value} ± {margin}"
                );
            }
        }
    }

    #[test]
    fn ring_centres_cover_every_point_of_the_disc() {
        let mut g = vgps_geometry::synthetic::rng(21);
        for (big, r) in [
            (30.0, 12.0 * std::f64::consts::FRAC_1_SQRT_2),
            (30.0, 5.0),
            (15.0, 8.0),
            (7.9, 8.0),
            (0.0, 8.0),
            (250.0, 8.5),
            (1.0, 0.05),
        ] {
            let centres = ring_centres(big, r, MAX_CELLS).unwrap();
            let nearest = |p: Vector2<f64>| {
                centres
                    .iter()
                    .map(|c| (p - c).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            // Random points, and the circle's edge densely (where a ring's gaps are).
            for k in 0..20_000 {
                let p = if k % 2 == 0 {
                    let (t, u): (f64, f64) = (g.random_range(0.0..1.0), g.random_range(0.0..1.0));
                    let (sin, cos) = (std::f64::consts::TAU * t).sin_cos();
                    Vector2::new(cos, sin) * (big * u.sqrt())
                } else {
                    let (sin, cos) = (std::f64::consts::TAU * k as f64 / 20_000.0).sin_cos();
                    Vector2::new(cos, sin) * big
                };
                assert!(nearest(p) <= r, "{big} {r}: {p:?} is {} away", nearest(p));
            }
            // Fewer cells than the grid over the bounding box, for a disc of a few cells.
            let side = r * std::f64::consts::SQRT_2;
            let grid = ((2.0 * big / side).ceil().max(1.0) as usize).pow(2);
            assert!(
                centres.len() <= grid,
                "{big} {r}: {} > {grid}",
                centres.len()
            );
        }
        // The prior of the Monte Carlo (30 m, 12 m cells): 21 cells instead of 25.
        let prior = ring_centres(30.0, 12.0 * std::f64::consts::FRAC_1_SQRT_2, MAX_CELLS);
        assert_eq!(prior.map(|c| c.len()), Ok(21));
        // Too many cells: refused with the count so far.
        assert!(ring_centres(1e4, 1.0, 1000).is_err_and(|n| n > 1000));
    }

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
