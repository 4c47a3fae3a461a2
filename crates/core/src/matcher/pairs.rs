//! A cell's data and its pair tables: the candidates seen from the cell's centre, the
//! quantities tested per candidate pair (the angle with its bound over the cell, and with a
//! known vertical the side of the pair), and the bit tables of the pairs each detection pair
//! allows.

use super::LandmarkDb;
use super::cells::{CellShape, elevation_range};
use super::fast_math::{FAST_ACOS_MAX_ERROR_RAD, fast_acos};
use super::scratch::{Cells, bit_set, for_each_bit, recycle_cells, take_cell};
use super::search::Search;
use nalgebra::{Vector2, Vector3};
use vgps_geometry::geometry::try_unit;

/// A landmark as seen from a cell centre.
pub(super) struct CellCandidate {
    pub(super) index: usize,
    pub(super) direction: Vector3<f64>,
    /// Half-width of the direction's wander over the cell, radians (π when the landmark is
    /// within the cell's ball).
    pub(super) wander: f64,
    /// The survey term [`survey_angle`] of the landmark's survey bound `k σ_m`, radians.
    pub(super) survey: f64,
    /// `1 / (range − radius)`, the reciprocal of the least range over the cell's ball
    /// (`+∞` when the landmark is within the ball), 1/metres.
    pub(super) inv_near: f64,
    /// The horizontal distance of the landmark from the cell centre, metres: for the azimuth
    /// test ([`azimuths_can_meet`]).
    pub(super) horizontal: f64,
}

impl CellCandidate {
    /// A landmark at `v` from a cell centre (`range = |v|` metres, in the unit `direction`),
    /// for a cell ball of `radius`, with the survey term `survey` (radians).
    pub(super) fn new(
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
pub(super) fn survey_angle(survey_m: f64, range: f64, radius: f64) -> f64 {
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
pub(super) fn pair_angle_wander(
    ci: &CellCandidate,
    cj: &CellCandidate,
    separation: f64,
    radius: f64,
) -> f64 {
    let sum = ci.wander + cj.wander;
    sum.min(radius * separation * ci.inv_near * cj.inv_near)
}

/// Whether a cell keeps its pair values and pair tables for later detection triples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CellCache {
    /// Not visited by a detection triple yet (no cache buffer is set up).
    Undecided,
    /// The cell keeps its dense `m × m` pair values and its pair tables (charged to the
    /// search's [`super::MatchOptions::cache_budget_bytes`]).
    Stored,
    /// The budget was spent: the cell holds no cache and builds a triple's three tables
    /// afresh, into a scratch shared by every cell, each time a triple visits it.
    Transient,
}

/// The bytes a cell's cache buffers hold (their capacities).
pub(super) fn cached_bytes(cell: &CellData) -> usize {
    cell.pairs.capacity() * std::mem::size_of::<PairValues>()
        + (cell.pairs_done.capacity() + cell.store.capacity()) * std::mem::size_of::<u64>()
        + cell.slots.capacity() * std::mem::size_of::<u32>()
}

/// A search cell: its candidates seen from the centre and its lazily built pair tables.
pub(super) struct CellData {
    pub(super) centre: Vector3<f64>,
    pub(super) cands: Vec<CellCandidate>,
    /// Whether the buffers below are set up and kept ([`CellCache`]).
    pub(super) cache: CellCache,
    /// What the pair tables test of each candidate pair `(i, j)` of the candidates some
    /// detection may be, row-major `u × u` (`u` = `used`, the diagonal unused; candidate `i`
    /// is row and column `rows[i]`): one record per pair, so a table row reads one
    /// contiguous run. Computed when a pair table first needs the pair
    /// ([`CellData::ensure_pairs`]). The other candidates are in no table: with a known
    /// vertical, 44 % of a cold start's candidates at 80 m (issue #25), whose rows and
    /// columns are about two-thirds of an `m × m` buffer.
    pub(super) pairs: Vec<PairValues>,
    /// Per candidate, its row and column in `pairs` ([`NO_ROW`]: no detection may be it).
    pub(super) rows: Vec<u32>,
    /// The candidates some detection may be: the side of `pairs`.
    pub(super) used: usize,
    /// Which entries of `pairs` are computed: `m × words` bits, row `i` the `j`.
    pub(super) pairs_done: Vec<u64>,
    /// Per candidate: its position in the frame's shared landmarks ([`PairContext`]) and the
    /// terms of [`det_range`] it brings to a pair.
    pub(super) slots_shared: Vec<usize>,
    pub(super) sides: Vec<DetSide>,
    /// Database indices of the candidates.
    pub(super) indices: Vec<usize>,
    /// 64-bit words per candidate bitset.
    pub(super) words: usize,
    /// Per detection, the candidates it may be (class, and elevation when up is known):
    /// `n × words` bits.
    pub(super) allowed: Vec<u64>,
    /// Pair tables by ordered detection pair `a · n + b`: `slots[a · n + b]` is the table's
    /// position in `store` (`NO_TABLE`: not built yet); row `i` of a table (`words` words)
    /// holds the candidates `j` that detection `b` may be when detection `a` is candidate `i`.
    pub(super) slots: Vec<u32>,
    /// The tables, each `m × words` words.
    pub(super) store: Vec<u64>,
}

/// A pair table not built yet.
pub(super) const NO_TABLE: u32 = u32::MAX;

/// The row in a cell's pair values of a candidate no detection may be.
pub(super) const NO_ROW: u32 = u32::MAX;

/// Pair tables a cell has room for before its store grows: a median prior frame runs five
/// detection triples, about a dozen distinct detection pairs.
pub(super) const INITIAL_PAIR_TABLES: usize = 16;

impl CellData {
    /// Computes the pair values the table of detections `(a, b)` reads, those of the
    /// candidates `i` detection `a` may be and `j` detection `b` may be, that are not computed
    /// yet. Each pair is computed with its candidates in database order and written at
    /// `(i, j)` and, mirrored, at `(j, i)`: the angle and its bound are symmetric, the side
    /// of the pair changes sign. A frame's first triples (the cheapest, see `run`) read few
    /// rows and columns: a roof corner high up may be a tenth of a cell's candidates.
    pub(super) fn ensure_pairs(
        &mut self,
        db: &LandmarkDb,
        context: &PairContext,
        a: usize,
        b: usize,
    ) {
        let Self {
            cands,
            sides,
            slots_shared,
            words,
            allowed,
            pairs,
            pairs_done,
            rows,
            used,
            ..
        } = self;
        let (u, words) = (*used, *words);
        let allowed_b = &allowed[b * words..(b + 1) * words];
        for_each_bit(&allowed[a * words..(a + 1) * words], |i| {
            let row_i = rows[i] as usize * u;
            for (w, &word_b) in allowed_b.iter().enumerate() {
                let mut missing = word_b & !pairs_done[i * words + w];
                // The diagonal is never tested (`i ≠ j`).
                if w == i / 64 {
                    missing &= !(1u64 << (i % 64));
                }
                // Row `i`'s bits at once; row `j`'s (the mirror) one by one below.
                pairs_done[i * words + w] |= missing;
                while missing != 0 {
                    let j = w * 64 + missing.trailing_zeros() as usize;
                    missing &= missing - 1;
                    let row_j = rows[j] as usize * u;
                    let (i_r, j_r) = (rows[i] as usize, rows[j] as usize);
                    // The pair in database order, mirrored for the other entry.
                    if i < j {
                        let values = context.values(db, cands, sides, slots_shared, i, j);
                        pairs[row_i + j_r] = values;
                        pairs[row_j + i_r] = values.mirrored();
                    } else {
                        let values = context.values(db, cands, sides, slots_shared, j, i);
                        pairs[row_j + i_r] = values;
                        pairs[row_i + j_r] = values.mirrored();
                    }
                    bit_set(&mut pairs_done[j * words..(j + 1) * words], i);
                }
            }
        });
    }

    /// The values of the candidate pair `(i, j)`, `i ≠ j`, computed as
    /// [`CellData::ensure_pairs`] stores them: for the pair in database order, mirrored when
    /// `i > j`.
    pub(super) fn pair_values(
        &self,
        db: &LandmarkDb,
        context: &PairContext,
        i: usize,
        j: usize,
    ) -> PairValues {
        let (lo, hi) = (i.min(j), i.max(j));
        let values = context.values(db, &self.cands, &self.sides, &self.slots_shared, lo, hi);
        if i < j { values } else { values.mirrored() }
    }

    /// Frees the cache buffers (a transient cell, or one whose cache the budget no longer
    /// covers).
    fn release_caches(&mut self) {
        self.pairs = Vec::new();
        self.pairs_done = Vec::new();
        self.slots = Vec::new();
        self.store = Vec::new();
    }

    /// The whole (built) table of the ordered detection pair `key`.
    pub(super) fn table(&self, key: usize) -> &[u64] {
        let size = self.cands.len() * self.words;
        let start = self.slots[key] as usize * size;
        &self.store[start..start + size]
    }
}

/// `det[up, a, b]` for two bearings and a bound on how far the true value (the true up,
/// within `tol` of `up`, and the true bearings, each within `noise`, radians) may be from
/// it. With a known vertical this is a rotation invariant: it equals `det[z, uᵢ, uⱼ]` for
/// the world directions of the two landmarks, i.e. `cos eₐ cos e_b sin(α_b − αₐ)` in
/// elevations and azimuths. Tilting `up` by at most `tol` changes it by at most
/// `2 sin(tol/2) |a × b|`, and moving each bearing by at most `noise` (a chord of at most
/// `noise`) changes it, and the norm of the cross product, by at most `2 noise + noise²`.
pub(super) fn det_of_bearings(
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
pub(super) fn det_range_from_above(
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
pub(super) struct DetSide {
    /// `(L − centre)_xy`, metres.
    pub(super) from_xy: Vector2<f64>,
    /// `|(L − centre)_xy| + half_horizontal`: the factor of the other landmark's survey bound
    /// in the reach of `N`, metres.
    pub(super) widened: f64,
    /// The survey bound `e = k σ`, metres.
    pub(super) survey_m: f64,
    /// The least range over the cell, `ρ − radius − e` (no bound when `≤ 0`), metres.
    pub(super) range_lo: f64,
    /// `1 / range_lo` (meaningful when `range_lo > 0`), 1/metres.
    pub(super) inv_lo: f64,
    /// `1 / (ρ + radius + e)`, the reciprocal of the largest range over the cell, 1/metres.
    pub(super) inv_hi: f64,
}

impl DetSide {
    /// `v = L − centre`, `range = |v|`, survey bound `e`.
    pub(super) fn new(
        v: &Vector3<f64>,
        range: f64,
        e: f64,
        radius: f64,
        half_horizontal: f64,
    ) -> Self {
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
pub(super) struct PairTerms {
    /// `|Lᵢ − Lⱼ|`, metres (for [`pair_angle_wander`]).
    pub(super) separation_m: f64,
    /// `(Lⱼ − Lᵢ)_xy`, metres.
    pub(super) baseline: Vector2<f64>,
    /// `|(Lⱼ − Lᵢ)_xy| · half_horizontal`, square metres.
    pub(super) spread: f64,
    /// `eᵢ eⱼ`, square metres.
    pub(super) survey_product: f64,
}

impl PairTerms {
    pub(super) fn new(
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
pub(super) fn det_range(i: &DetSide, j: &DetSide, pair: &PairTerms) -> (f64, f64) {
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

/// What the pair tables test of a candidate pair `(i, j)` of a cell (see [`CellData`]).
#[derive(Clone, Copy)]
pub(super) struct PairValues {
    /// The angle between the directions to the two candidates from the cell centre, radians.
    pub(super) angle: f64,
    /// How far the angle may be from `angle` over the cell, plus the survey terms and the
    /// error of [`fast_acos`], radians: [`pair_angle_wander`] `+ surveyᵢ + surveyⱼ`.
    pub(super) bound: f64,
    /// With a known vertical, the range of `det[z, uᵢ(x), uⱼ(x)]` (unit directions to the
    /// landmarks) over the cell ([`det_range_from_above`]); `(−1, 1)` without.
    pub(super) det: (f64, f64),
}

impl PairValues {
    /// The value on the diagonal, which the tables never test (`i ≠ j`).
    pub(super) const DIAGONAL: Self = Self {
        angle: 0.0,
        bound: 0.0,
        det: (-1.0, 1.0),
    };

    /// The values of the pair `(j, i)`: the side of the pair changes sign.
    pub(super) fn mirrored(self) -> Self {
        let (lo, hi) = self.det;
        Self {
            det: (-hi, -lo),
            ..self
        }
    }
}

/// What computing a cell's [`PairValues`] needs besides the cell: the frame's shared pair
/// terms, when the area is small enough to have them, and the cells' size.
pub(super) struct PairContext {
    /// The [`PairTerms`] of every pair of the landmarks within reach of the whole area, row
    /// by row of the triangle `(a, b)`, `b > a` (empty: computed per pair).
    pub(super) shared_pairs: Vec<PairTerms>,
    /// Start of row `a` of `shared_pairs`: pair `(a, b)` is at `row_start[a] + b − a − 1`.
    pub(super) row_start: Vec<usize>,
    /// The cells' ball radius, metres.
    pub(super) radius: f64,
    /// The cells' horizontal half-diagonal, metres.
    pub(super) half_horizontal: f64,
    /// Whether the vertical is known (the side of a pair is tested).
    pub(super) with_up: bool,
}

impl PairContext {
    /// The values of the candidate pair `(i, j)`, `i < j` (database order) of a cell.
    /// Inlined into the loop of [`CellData::ensure_pairs`] (about a million calls per 200
    /// prior frames).
    #[inline(always)]
    pub(super) fn values(
        &self,
        db: &LandmarkDb,
        cands: &[CellCandidate],
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
pub(super) const MAX_SHARED_PAIRS: usize = 1 << 15;

/// Relative widening of the query for the landmarks within reach of the whole area, so that
/// it holds every landmark a cell's own query would find despite rounding.
pub(super) const REACH_SLACK: f64 = 1e-9;

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
pub(super) fn cell_data(
    search: &Search,
    centres: Vec<Vector3<f64>>,
    area_centre: &Vector3<f64>,
    area_reach: f64,
    shape: &CellShape,
) -> (Cells, PairContext) {
    let db = search.db;
    let options = search.options;
    let up = search.up;
    let k = options.inlier_threshold_sigmas;
    let mut keyed: Vec<(f64, Vector3<f64>)> = centres
        .into_iter()
        .map(|c| ((c - area_centre).norm(), c))
        .collect();
    keyed.sort_by(|x, y| x.0.total_cmp(&y.0));
    let CellShape {
        radius,
        half_horizontal,
        ..
    } = *shape;
    // A cell's candidates: the landmarks within this distance of its centre.
    let cell_reach = options.visibility_range_m + radius;

    // The landmarks within reach of the whole area (a superset of every cell's candidates),
    // with the terms of each of their pairs, when they are few enough.
    let (shared, shared_points, shared_pairs) =
        shared_landmarks(db, area_centre, area_reach, k, half_horizontal);
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
            cands.push(CellCandidate::new(
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
        prepare_cell(search, &mut cell, centre, shape, classed, &by_elevation);
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

/// The landmarks within reach of the whole area (a superset of every cell's candidates),
/// their positions and the [`PairTerms`] of each of their pairs (survey bounds `k σ_m`),
/// when they are at most [`MAX_SHARED_PAIRS`] pairs; all empty otherwise.
fn shared_landmarks(
    db: &LandmarkDb,
    area_centre: &Vector3<f64>,
    area_reach: f64,
    k: f64,
    half_horizontal: f64,
) -> (Vec<usize>, Vec<Vector3<f64>>, Vec<PairTerms>) {
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
    (shared, shared_points, shared_pairs)
}

/// Sets up a cell whose candidates are gathered: per detection the candidates it may be
/// (class, and with a known vertical the elevation gate, a run of `by_elevation`), its
/// landmark indices and centre; its cache is decided later ([`CellCache`]).
fn prepare_cell(
    search: &Search,
    cell: &mut CellData,
    centre: &Vector3<f64>,
    shape: &CellShape,
    classed: bool,
    by_elevation: &[(f64, usize)],
) {
    let db = search.db;
    let up = search.up;
    let n = search.detections.len();
    let CellShape {
        half_horizontal,
        half_vertical,
        ..
    } = *shape;
    let cands = &cell.cands;
    let m = cands.len();
    let words = m.div_ceil(64);
    let mut allowed = std::mem::take(&mut cell.allowed);
    allowed.clear();
    allowed.resize(n * words, 0);
    // Per candidate: its elevation range over the cell, widened by the tilt tolerance,
    // the bearing noise and the survey error.
    // CellCandidate by candidate, its bit in the row of each detection it may be: with a
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
    // Per candidate its row in the pair values: the candidates some detection may be.
    let mut any = vec![0u64; words];
    for d in 0..n {
        for (w, bits) in any.iter_mut().zip(&allowed[d * words..(d + 1) * words]) {
            *w |= bits;
        }
    }
    cell.rows.clear();
    cell.rows.resize(m, NO_ROW);
    let mut used = 0u32;
    for_each_bit(&any, |i| {
        cell.rows[i] = used;
        used += 1;
    });
    cell.used = used as usize;
    cell.allowed = allowed;
    // The cache buffers are set up when a detection triple first visits the cell, if the
    // frame's budget covers them (`Search::decide_cache`).
    cell.cache = CellCache::Undecided;
}

impl Search<'_> {
    /// Sets up the cache buffers of a cell a detection triple visits first, when the frame's
    /// budget covers them (the pair values `m × m`, which of them are computed, the table
    /// slots and room for [`INITIAL_PAIR_TABLES`] tables); else the cell is transient.
    pub(super) fn decide_cache(&self, cell: &mut CellData) {
        let n = self.detections.len();
        let (m, words) = (cell.cands.len(), cell.words);
        let u = cell.used;
        let need = u * u * std::mem::size_of::<PairValues>()
            + m * words * (1 + INITIAL_PAIR_TABLES) * std::mem::size_of::<u64>()
            + n * n * std::mem::size_of::<u32>();
        // A pooled cell brings its buffers' capacity (at most `before`), kept if stored.
        let before = cached_bytes(cell);
        let left = self.cache_left.get();
        if before.saturating_add(need) > left {
            cell.release_caches();
            cell.cache = CellCache::Transient;
            self.cache_transient.set(self.cache_transient.get() + 1);
            return;
        }
        // Stale pair values are never read (`pairs_done`).
        if cell.pairs.len() < u * u {
            cell.pairs.resize(u * u, PairValues::DIAGONAL);
        }
        cell.pairs_done.clear();
        cell.pairs_done.resize(m * words, 0);
        cell.slots.clear();
        cell.slots.resize(n * n, NO_TABLE);
        cell.store.clear();
        cell.store.reserve_exact(m * words * INITIAL_PAIR_TABLES);
        cell.cache = CellCache::Stored;
        self.charge_cache(cached_bytes(cell));
        self.cache_stored.set(self.cache_stored.get() + 1);
    }

    /// Takes `bytes` from the frame's cache budget, and records the peak held.
    fn charge_cache(&self, bytes: usize) {
        let left = self.cache_left.get().saturating_sub(bytes);
        self.cache_left.set(left);
        let held = self.cache_budget - left;
        self.cache_peak.set(self.cache_peak.get().max(held));
    }

    /// Makes room in a stored cell's table store for `tables` more tables, charged to the
    /// budget; when the budget does not cover it, the cell's cache is freed (its bytes
    /// returned to the budget) and the cell becomes transient.
    pub(super) fn room_for_tables(&self, cell: &mut CellData, tables: usize) {
        let size = cell.cands.len() * cell.words;
        let (len, capacity) = (cell.store.len(), cell.store.capacity());
        if len + tables * size <= capacity {
            return;
        }
        // Doubling, as `Vec` would, but charged before it is allocated.
        let extra = len.max(tables * size);
        let bytes = extra * std::mem::size_of::<u64>();
        if bytes > self.cache_left.get() {
            let freed = cached_bytes(cell);
            self.cache_left.set(
                self.cache_left
                    .get()
                    .saturating_add(freed)
                    .min(self.cache_budget),
            );
            cell.release_caches();
            cell.cache = CellCache::Transient;
            self.cache_stored.set(self.cache_stored.get() - 1);
            self.cache_transient.set(self.cache_transient.get() + 1);
            return;
        }
        cell.store.reserve_exact(extra);
        let grown = (cell.store.capacity() - capacity) * std::mem::size_of::<u64>();
        self.charge_cache(grown);
    }

    /// The landmark triples `(i, j, k)` of a cell that pass the three pair tables of the
    /// detection triple `(a, b, c)`, into `survivors`: from the cell's kept tables (built
    /// once), or for a transient cell from tables built into `scratch` now.
    pub(super) fn cell_survivors(
        &self,
        cell: &mut CellData,
        context: &PairContext,
        [a, b, c]: [usize; 3],
        survivors: &mut Vec<[usize; 3]>,
        scratch: &mut Vec<u64>,
    ) {
        let n = self.detections.len();
        let keys = [(a, b), (a, c), (b, c)];
        if cell.cache == CellCache::Undecided {
            self.decide_cache(cell);
        }
        if cell.cache == CellCache::Stored {
            let missing = keys
                .iter()
                .filter(|&&(p, q)| cell.slots[p * n + q] == NO_TABLE)
                .count();
            self.room_for_tables(cell, missing);
        }
        let (m, words) = (cell.cands.len(), cell.words);
        if cell.cache == CellCache::Stored {
            // An empty table leaves no landmark triple: the tables already built are looked
            // at first, and the others are built one by one until one is empty (a later
            // detection triple builds the rest when it needs them).
            let mut order = keys;
            order.sort_by_key(|&(p, q)| cell.slots[p * n + q] == NO_TABLE);
            for (p, q) in order {
                self.ensure_table(cell, context, p, q);
                if cell.table(p * n + q).iter().all(|&w| w == 0) {
                    survivors.clear();
                    return;
                }
            }
            let tables = keys.map(|(p, q)| cell.table(p * n + q));
            table_survivors(m, words, tables, survivors);
        } else {
            let size = m * words;
            scratch.clear();
            scratch.resize(3 * size, 0);
            for (table, (p, q)) in scratch.chunks_exact_mut(size.max(1)).zip(keys) {
                self.transient_table(cell, context, p, q, table);
            }
            let (ab, rest) = scratch.split_at(size);
            let (ac, bc) = rest.split_at(size);
            table_survivors(m, words, [ab, ac, bc], survivors);
        }
    }

    /// The pair table of the ordered detection pair `(a, b)` of a transient cell, into
    /// `table` (`m × words`, zeroed): the same tests as [`Search::ensure_table`], on pair
    /// values computed now ([`CellData::pair_values`]) instead of kept ones.
    pub(super) fn transient_table(
        &self,
        cell: &CellData,
        context: &PairContext,
        a: usize,
        b: usize,
        table: &mut [u64],
    ) {
        let n = self.detections.len();
        let words = cell.words;
        let theta = self.angles[a * n + b];
        let tol = 2.0 * self.noise;
        let pair_det = self.pair_det(a, b);
        let allowed_a = &cell.allowed[a * words..(a + 1) * words];
        let allowed_b = &cell.allowed[b * words..(b + 1) * words];
        for_each_bit(allowed_a, |i| {
            let row = &mut table[i * words..(i + 1) * words];
            for_each_bit(allowed_b, |j| {
                // The diagonal never passes (`i ≠ j` in the kept tables).
                if i == j {
                    return;
                }
                let p = cell.pair_values(self.db, context, i, j);
                let (lo, hi) = p.det;
                let pass = ((theta - p.angle).abs() <= tol + p.bound)
                    & pair_det.is_none_or(|(d, margin)| (d + margin >= lo) & (d - margin <= hi));
                row[j / 64] |= u64::from(pass) << (j % 64);
            });
        });
    }

    /// With a known vertical: `det[up, b_a, b_b]` and how far the true value may be from it
    /// ([`det_of_bearings`]).
    pub(super) fn pair_det(&self, a: usize, b: usize) -> Option<(f64, f64)> {
        let (up, tol) = self.up?;
        Some(det_of_bearings(
            &up,
            tol,
            self.noise,
            &self.directions[a],
            &self.directions[b],
        ))
    }

    /// Builds the pair table of the ordered detection pair `(a, b)` in a stored cell (once).
    pub(super) fn ensure_table(
        &self,
        cell: &mut CellData,
        context: &PairContext,
        a: usize,
        b: usize,
    ) {
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
        let (u, rows) = (cell.used, &cell.rows);
        // Without a vertical the side of a pair is not tested: the bounds always pass (the
        // pairs' side ranges are finite, `(−1, 1)` then).
        let (det_hi, det_lo) = match pair_det {
            Some((d, margin)) => (d + margin, d - margin),
            None => (f64::INFINITY, f64::NEG_INFINITY),
        };
        // A row's word is gathered in a register and stored once; the diagonal (`i = j`,
        // never passing) is left out of the bits visited.
        for_each_bit(allowed_a, |i| {
            let row = &mut table[i * words..(i + 1) * words];
            let r = rows[i] as usize;
            let pairs = &cell.pairs[r * u..(r + 1) * u];
            for ((w, &bits), out) in allowed_b.iter().enumerate().zip(row.iter_mut()) {
                let mut word = 0u64;
                let mut rest = if w == i / 64 {
                    bits & !(1u64 << (i % 64))
                } else {
                    bits
                };
                while rest != 0 {
                    let bit = rest.trailing_zeros();
                    rest &= rest - 1;
                    let j = w * 64 + bit as usize;
                    let p = &pairs[rows[j] as usize];
                    let (lo, hi) = p.det;
                    let pass = ((theta - p.angle).abs() <= tol + p.bound)
                        & (det_hi >= lo)
                        & (det_lo <= hi);
                    word |= u64::from(pass) << bit;
                }
                *out = word;
            }
        });
    }
}

/// Landmark triples `(i, j, k)` of a cell (`m` candidates, `words` words per bitset) that
/// pass the three pair tables `[ab, ac, bc]` of a detection triple `(a, b, c)`, into
/// `survivors`.
pub(super) fn table_survivors(
    m: usize,
    words: usize,
    [ab, ac, bc]: [&[u64]; 3],
    survivors: &mut Vec<[usize; 3]>,
) {
    survivors.clear();
    for i in 0..m {
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

#[cfg(test)]
mod tests;
