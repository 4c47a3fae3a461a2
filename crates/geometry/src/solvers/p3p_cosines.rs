//! P3P by the law of cosines and a one-dimensional root search (Bierre's directional
//! triangulation).

use crate::geometry::{MIN_DIRECTION_NORM, Pose, PoseSolutions, is_finite};
use arrayvec::ArrayVec;
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// Smallest sine of the angle between two bearings: closer to parallel (same direction),
/// the pair is degenerate and the solver returns no solution. Anti-parallel bearings (rig
/// between two landmarks) are valid.
pub const MIN_BEARING_SINE: f64 = 1e-9;

/// Smallest twice-area of the landmark triangle relative to its longest side squared
/// (≈ the sine of its largest angle): below it the landmarks are collinear (or coincident)
/// and the pose is not determined.
pub const MIN_TRIANGLE_SINE: f64 = 1e-9;

/// Number of uniform samples of the residual over the parameter interval (per branch).
/// Sign changes, near-tangent extrema and S-shapes between samples are all searched, so
/// with 24 samples no root of the 4096-sample reference was missed in 10⁵ random
/// omnidirectional problems (see `docs/solvers.md` for the measured miss rates).
pub const RESIDUAL_SAMPLES: usize = 24;

/// Two range solutions closer than this fraction of the scene size are the same solution.
pub const DUPLICATE_RANGE_TOLERANCE: f64 = 1e-9;

/// Deepest subdivision of a sampling interval by the extremum and S-shape searches.
const MAX_SPLIT_DEPTH: u32 = 48;

/// Most subdivisions of one sampling interval (all depths together). Subdivision follows
/// the residual's extrema; a well-posed residual needs a few dozen, so this only bounds the
/// work on pathological input (a fuzzer found a scene whose subdivision tree was
/// exponential in [`MAX_SPLIT_DEPTH`]). When it runs out, the interval is treated as
/// unsplittable: a sign change is still refined to its root.
const MAX_SPLITS_PER_INTERVAL: u32 = 512;

/// Narrowest subdivided interval (radians of the parameter α).
const MIN_SPLIT_WIDTH: f64 = 1e-13;

/// Residual accepted as a double root at a located extremum, relative to the squared scene
/// size (the rounding level of the residual).
const TANGENT_RESIDUAL_TOLERANCE: f64 = 1e-14;

/// Iteration cap of the safeguarded Newton refinement of a bracketed root (bisection
/// alone needs at most ~60 halvings to reach full double precision).
const MAX_REFINE_ITERATIONS: usize = 100;

/// The ranges `[r₀, r₁, r₂]` (metres, rig origin to each landmark) of every P3P solution.
pub type RangeSolutions = ArrayVec<[f64; 3], 4>;

/// Every pose `world_from_rig` consistent with three bearings and three landmarks, by
/// Bierre's directional triangulation: the law of cosines for the ranges, solved by a
/// bracketing search on one parameter, then the pose from the two congruent triangles.
///
/// # Equation
/// With unit bearings `dᵢ` (rig frame), `cos θᵢⱼ = dᵢ·dⱼ` and landmark distances
/// `sᵢⱼ = |Xᵢ − Xⱼ|`, the ranges `rᵢ > 0` satisfy
///
/// ```text
/// sᵢⱼ² = rᵢ² + rⱼ² − 2 rᵢ rⱼ cos θᵢⱼ      (ij = 01, 02, 12)
/// ```
///
/// The two equations through landmark 0 are solved for the other ranges as functions of
/// one parameter (both quadratic branches, parameterised by an angle of the triangle so that
/// the branches join smoothly), and the third equation's residual is searched for every
/// root; see [`p3p_cosines_ranges`] and `docs/solvers.md`. The rig-frame points `rᵢdᵢ` and
/// the world points form congruent triangles; the rotation is the TRIAD (as in
/// [`crate::attitude::triad`]) of two triangle edges and the translation matches the centroids (a closed-form three-point absolute
/// orientation, preferred to sphere trilateration, which loses half the digits when the rig
/// is near the plane of the landmarks).
///
/// # Convention
/// `point_in_world = pose * (rᵢ dᵢ)`; poses are `world_from_rig`. Bearings may have any
/// non-zero finite length (normalised inside). Omnidirectional: bearings may point anywhere
/// on the sphere, but ranges are positive (a landmark is in the direction of its bearing).
///
/// # Returns
/// Up to four poses, in increasing order of `r₀`. Empty on degenerate input: a zero or
/// non-finite bearing or point, parallel bearings ([`MIN_BEARING_SINE`]), coincident or
/// collinear landmarks ([`MIN_TRIANGLE_SINE`]), or no real solution.
///
/// # Units
/// Points in metres (any consistent length unit); bearings dimensionless.
///
/// # Role in vgps
/// The proposal's own method, kept as the **reference and cross-check**: production does not
/// call it. Hypotheses in the matcher and the robust estimator come from
/// [`crate::solvers::p3p()`] (0.3 µs against 1.2 µs per solve, docs/dev/journal.md); the final
/// fix is [`crate::solvers::refine_pose()`] over every landmark. `tests/p3p_cross_check.rs`
/// checks that both solvers find the same poses.
///
/// # Example
/// ```
/// use nalgebra::{Isometry3, Vector3};
/// use vgps_geometry::solvers::p3p_cosines;
/// let truth = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.3, -0.2, 1.1));
/// let truth = vgps_geometry::geometry::Pose::from_parts(truth.translation, truth.rotation.into());
/// let points = [
///     Vector3::new(10.0, 3.0, 2.0),
///     Vector3::new(-4.0, 8.0, 1.0),
///     Vector3::new(2.0, -7.0, 6.0),
/// ];
/// let bearings = points.map(|x| vgps_geometry::geometry::bearing_in_rig(&truth, &x).unwrap());
/// let poses = p3p_cosines(&bearings, &points);
/// assert!(poses.iter().any(|p| {
///     (p.translation.vector - truth.translation.vector).norm() < 1e-9
///         && (p.rotation.matrix() - truth.rotation.matrix()).norm() < 1e-9
/// }));
/// ```
///
/// # References
/// - P. Bierre, "Position and Attitude Sensing by Directional Triangulation", ION National
///   Technical Meeting, Emerging Technologies Panel, Monterey CA, January 2006 (as cited by
///   the Visual GPS proposal).
/// - J. A. Grunert, "Das pothenotische Problem in erweiterter Gestalt nebst über seine
///   Anwendungen in der Geodäsie", Grunerts Archiv für Mathematik und Physik 1, 1841 (the
///   same three law-of-cosines equations).
pub fn p3p_cosines(
    bearings_in_rig: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
) -> PoseSolutions {
    let mut out = PoseSolutions::new();
    let Some(unit) = unit_bearings(bearings_in_rig) else {
        return out;
    };
    let ranges = solve_unit(&unit, points_in_world, RESIDUAL_SAMPLES, true);
    if ranges.is_empty() {
        return out;
    }
    let x = points_in_world;
    let Some(world_frame) = edge_frame(&(x[1] - x[0]), &(x[2] - x[0])) else {
        return out;
    };
    let centroid_world = (x[0] + x[1] + x[2]) * (1.0 / 3.0);
    for r in &ranges {
        if let Some(pose) = pose_from_ranges(&unit, r, &world_frame, &centroid_world) {
            out.push(pose);
        }
    }
    out
}

/// The ranges of every solution of the law-of-cosines system of [`p3p_cosines`].
///
/// # Method
/// Landmark 0 is the pivot; of landmarks 1 and 2, call `a` the one with the smaller
/// `R₀ₐ = s₀ₐ / sin θ₀ₐ` and `b` the other. The equation of the pair (0, a) is an ellipse in
/// the `(r₀, rₐ)` plane, parameterised by the angle `α` at `X₀` of the triangle
/// (rig, X₀, Xₐ); by the law of sines
///
/// ```text
/// r₀(α) = R₀ₐ sin(θ₀ₐ + α),  rₐ(α) = R₀ₐ sin α,   α ∈ [0, π − θ₀ₐ]
/// ```
///
/// which covers both quadratic branches `rₐ = r₀ cos θ₀ₐ ± √(s₀ₐ² − r₀² sin² θ₀ₐ)` with
/// `r₀, rₐ ≥ 0` in one smooth sweep (the branches meet at `r₀ = R₀ₐ`, `α = π/2 − θ₀ₐ`, where
/// `drₐ/dr₀` is infinite but `α` is regular). Then `r_b = r₀ cos θ₀b ± √(s₀b² − r₀² sin² θ₀b)`
/// is real on the whole sweep because `r₀ ≤ R₀ₐ ≤ R₀b`. On each of the two `r_b` branches
/// the residual `g(α) = rₐ² + r_b² − 2 rₐ r_b cos θₐb − sₐb²` is sampled at
/// [`RESIDUAL_SAMPLES`] uniform nodes (plus the branch junction) with its analytic
/// derivative; one evaluation serves both branches (`g± = A ± B √(…)`), and the node sines
/// and cosines come from a rotation recurrence (no libm call in the sampling). Intervals
/// where `r_b` cannot be positive on a branch are skipped (`r₀` is monotonic between
/// nodes). Every sign change is refined by safeguarded Newton iteration, started at the root
/// of the cubic Hermite interpolant of the bracket; an interval
/// whose end slopes show `|g|` falling then rising is searched for a near-double root (the
/// tangent lines at its ends bound a convex `|g|` from below, and the interval is split at
/// their intersection until the bound clears or a sign change appears); an interval whose
/// cubic Hermite interpolant has two interior extrema (possible triple crossing) is split
/// between them. Roots with all ranges positive are kept, duplicates removed.
///
/// # Returns
/// Up to four range triples `[r₀, r₁, r₂]` in increasing order of `r₀`; empty on the
/// degenerate inputs listed in [`p3p_cosines`].
///
/// # Units
/// Metres (the unit of the points).
pub fn p3p_cosines_ranges(
    bearings_in_rig: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
) -> RangeSolutions {
    solve_ranges(bearings_in_rig, points_in_world, RESIDUAL_SAMPLES, true)
}

/// Unit bearings, or `None` if one is zero or not finite.
fn unit_bearings(bearings: &[Vector3<f64>; 3]) -> Option<[Vector3<f64>; 3]> {
    // As `geometry::try_unit`, component by component.
    let unit = |v: &Vector3<f64>| {
        let n = (v.x * v.x + v.y * v.y + v.z * v.z).sqrt();
        if !(n.is_finite() && n > MIN_DIRECTION_NORM) {
            return None;
        }
        let u = Vector3::new(v.x / n, v.y / n, v.z / n);
        (u.x.is_finite() && u.y.is_finite() && u.z.is_finite()).then_some(u)
    };
    Some([
        unit(&bearings[0])?,
        unit(&bearings[1])?,
        unit(&bearings[2])?,
    ])
}

/// Largest angle (radians) for which [`sin_cos_small`] uses its Taylor polynomials (the
/// first omitted terms, `u¹⁷/17!` and `u¹⁸/18!`, are below 10⁻¹⁸ there).
const SMALL_ANGLE: f64 = 0.55;

/// `(sin u, cos u)` without a libm call for `|u| ≤` [`SMALL_ANGLE`] (Taylor polynomials of
/// degree 15 and 16, full double precision), by libm beyond.
#[inline]
fn sin_cos_small(u: f64) -> (f64, f64) {
    if u.abs() > SMALL_ANGLE {
        return u.sin_cos();
    }
    let x = u * u;
    // 1/k! for k = 2..=16.
    const F: [f64; 15] = [
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362880.0,
        1.0 / 3628800.0,
        1.0 / 39916800.0,
        1.0 / 479001600.0,
        1.0 / 6227020800.0,
        1.0 / 87178291200.0,
        1.0 / 1307674368000.0,
        1.0 / 20922789888000.0,
    ];
    let sin = u
        * (1.0
            - x * (F[1]
                - x * (F[3] - x * (F[5] - x * (F[7] - x * (F[9] - x * (F[11] - x * F[13])))))));
    let cos = 1.0
        - x * (F[0]
            - x * (F[2]
                - x * (F[4] - x * (F[6] - x * (F[8] - x * (F[10] - x * (F[12] - x * F[14])))))));
    (sin, cos)
}

/// The residual of the third law-of-cosines equation along the (0, a) ellipse, in units of
/// the longest landmark distance.
///
/// With `rb± = r₀ cos θ₀b ± √(s₀b² − r₀² sin² θ₀b)`, the residual on both branches is
/// `g± = A ± B √(…)` with `A = rₐ² + r₀² cos 2θ₀b + s₀b² − sₐb² − 2 cos θₐb cos θ₀b rₐ r₀`
/// and `B = 2 (r₀ cos θ₀b − cos θₐb rₐ)`: one evaluation serves both branches.
struct Residual {
    /// `R₀ₐ = s₀ₐ / sin θ₀ₐ`.
    radius: f64,
    sin_0a: f64,
    cos_0a: f64,
    cos_0b: f64,
    sin2_0b: f64,
    s2_0b: f64,
    cos_ab: f64,
    /// `cos 2θ₀b`.
    cos2_0b: f64,
    /// `2 cos θₐb cos θ₀b`.
    k_ab: f64,
    /// `s₀b² − sₐb²`.
    k0: f64,
}

/// The ranges and the residual terms at one parameter value, shared by both `r_b` branches.
#[derive(Clone, Copy)]
struct BranchSample {
    r0: f64,
    ra: f64,
    /// `√(s₀b² − r₀² sin² θ₀b)`.
    root: f64,
    /// `g± = a ± b·root`, `g±' = da ± db_root`.
    a: f64,
    b: f64,
    da: f64,
    db_root: f64,
}

impl BranchSample {
    /// The residual and its derivative on branch `sign` (±1).
    #[inline]
    fn value(&self, sign: f64) -> (f64, f64) {
        (
            self.a + sign * (self.b * self.root),
            self.da + sign * self.db_root,
        )
    }
}

/// The residual and its derivative at one parameter value `alpha`, with `(sin α, cos α)`.
#[derive(Clone, Copy, Debug)]
struct Node {
    alpha: f64,
    sin: f64,
    cos: f64,
    g: f64,
    dg: f64,
}

/// Number of sampling nodes evaluated together (the production sampling fits in one).
const CHUNK: usize = 32;

/// Sampling nodes as a structure of arrays: the parameter, its sine and cosine, `r₀`, and
/// the residual with its derivative on both branches (`[+, −]`).
struct Chunk {
    alpha: [f64; CHUNK],
    sin: [f64; CHUNK],
    cos: [f64; CHUNK],
    r0: [f64; CHUNK],
    g: [[f64; CHUNK]; 2],
    dg: [[f64; CHUNK]; 2],
}

impl Chunk {
    fn new() -> Self {
        Self {
            alpha: [0.0; CHUNK],
            sin: [0.0; CHUNK],
            cos: [0.0; CHUNK],
            r0: [0.0; CHUNK],
            g: [[0.0; CHUNK]; 2],
            dg: [[0.0; CHUNK]; 2],
        }
    }

    /// Evaluates the residual at the first `len` nodes.
    #[inline]
    fn evaluate(&mut self, residual: &Residual, len: usize) {
        let len = len.min(CHUNK);
        let [gp, gm] = &mut self.g;
        let [dgp, dgm] = &mut self.dg;
        for i in 0..len {
            let x = residual.sample(self.sin[i], self.cos[i]);
            self.r0[i] = x.r0;
            let br = x.b * x.root;
            gp[i] = x.a + br;
            gm[i] = x.a - br;
            dgp[i] = x.da + x.db_root;
            dgm[i] = x.da - x.db_root;
        }
    }

    fn node(&self, branch: usize, i: usize) -> Node {
        Node {
            alpha: self.alpha[i],
            sin: self.sin[i],
            cos: self.cos[i],
            g: self.g[branch][i],
            dg: self.dg[branch][i],
        }
    }
}

/// A root of the residual: the parameter's sine and cosine and the `r_b` branch.
#[derive(Clone, Copy)]
struct Root {
    sin: f64,
    cos: f64,
    sign: f64,
}

impl Node {
    fn root(&self, sign: f64) -> Root {
        Root {
            sin: self.sin,
            cos: self.cos,
            sign,
        }
    }
}

impl Residual {
    #[inline]
    fn sample(&self, sin_a: f64, cos_a: f64) -> BranchSample {
        let r0 = self.radius * (self.sin_0a * cos_a + self.cos_0a * sin_a);
        let ra = self.radius * sin_a;
        let dr0 = self.radius * (self.cos_0a * cos_a - self.sin_0a * sin_a);
        let dra = self.radius * cos_a;
        let q = (self.s2_0b - r0 * r0 * self.sin2_0b).max(0.0);
        let root = q.sqrt();
        let droot = if root > 0.0 {
            -r0 * dr0 * self.sin2_0b / root
        } else {
            0.0
        };
        let a = ra * ra + self.cos2_0b * (r0 * r0) - self.k_ab * (ra * r0) + self.k0;
        let da = 2.0 * (ra * dra + self.cos2_0b * (r0 * dr0)) - self.k_ab * (dra * r0 + ra * dr0);
        let b = 2.0 * (r0 * self.cos_0b - self.cos_ab * ra);
        let db = 2.0 * (dr0 * self.cos_0b - self.cos_ab * dra);
        BranchSample {
            r0,
            ra,
            root,
            a,
            b,
            da,
            db_root: db * root + b * droot,
        }
    }

    /// `r_b` on branch `sign` (±1).
    #[inline]
    fn rb(&self, x: &BranchSample, sign: f64) -> f64 {
        x.r0 * self.cos_0b + sign * x.root
    }

    /// The node at `base.alpha + u` on branch `sign` (sine and cosine by rotating the
    /// base node's by `u`, no libm call for a small `u`).
    #[inline]
    fn node_from(&self, base: &Node, u: f64, sign: f64) -> Node {
        let (sin, cos) = rotate(base, u);
        let (g, dg) = self.sample(sin, cos).value(sign);
        Node {
            alpha: base.alpha + u,
            sin,
            cos,
            g,
            dg,
        }
    }

    /// The root between nodes `a` and `b` (with `g` of opposite signs or zero) by
    /// safeguarded Newton iteration (Newton steps that leave the bracket or converge slowly
    /// are replaced by bisection), in the offset `u` from `a`, started at the root of the
    /// cubic Hermite interpolant of the two nodes. Stops when the step reaches the rounding
    /// level of α, or when two successive Newton steps predict (quadratic convergence,
    /// next error ≈ step³ / previous step²) that the next would; the last iterate is then
    /// accepted without evaluating the residual there.
    fn refine(&self, sign: f64, a: &Node, b: &Node) -> Root {
        if a.g == 0.0 {
            return a.root(sign);
        }
        if b.g == 0.0 {
            return b.root(sign);
        }
        let h = b.alpha - a.alpha;
        // Bracket with g(lo) < 0 < g(hi).
        let (mut lo, mut hi) = if a.g < 0.0 { (0.0, h) } else { (h, 0.0) };
        let mut x = h * hermite_root(a, b, h);
        let mut m = self.node_from(a, x, sign);
        let mut step_old = h;
        let mut step = h;
        let mut previous_newton: Option<f64> = None;
        for _ in 0..MAX_REFINE_ITERATIONS {
            if m.g == 0.0 {
                break;
            }
            if m.g < 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            let newton_leaves = ((x - hi) * m.dg - m.g) * ((x - lo) * m.dg - m.g) > 0.0;
            let newton = !(newton_leaves || (2.0 * m.g).abs() > (step_old * m.dg).abs());
            step_old = step;
            if newton {
                step = m.g / m.dg;
                x -= step;
            } else {
                step = 0.5 * (hi - lo);
                x = lo + step;
            }
            let tolerance = 2.0 * f64::EPSILON * (a.alpha + x).abs().max(1.0);
            let s = step.abs();
            let converged = s <= tolerance
                || (newton && previous_newton.is_some_and(|p| s * s * s <= tolerance * p * p));
            if converged {
                let (sin, cos) = rotate(a, x);
                return Root { sin, cos, sign };
            }
            previous_newton = newton.then_some(s);
            m = self.node_from(a, x, sign);
        }
        m.root(sign)
    }

    /// Every root of the residual on branch `sign` in `(a, b]`, pushed to `roots`.
    ///
    /// - A sign change is refined as one root, unless the cubic Hermite interpolant of the
    ///   end values and slopes has two critical points inside (an S-shape that may cross
    ///   three times): then the interval is split between them.
    /// - Without a sign change, roots need an extremum approaching zero: `|g|` decreasing
    ///   at `a` and increasing at `b`. The tangent lines at both ends bound a convex `|g|`
    ///   from below; if their intersection stays on the side of the end values there is no
    ///   root (no evaluation needed, the common case). Otherwise the interval is split at
    ///   the intersection (a secant step towards the extremum) until a sign change appears,
    ///   the bound clears, or the extremum is located to [`MIN_SPLIT_WIDTH`], where a
    ///   residual within `tangent_tolerance` is taken as a double root.
    #[allow(clippy::too_many_arguments)] // the recursion's state, passed down unchanged
    fn scan(
        &self,
        sign: f64,
        a: Node,
        b: Node,
        depth: u32,
        tangent_tolerance: f64,
        roots: &mut ArrayVec<Root, 16>,
        splits_left: &mut u32,
    ) {
        if b.g == 0.0 {
            let _ = roots.try_push(b.root(sign));
            return;
        }
        if a.g == 0.0 {
            return; // Recorded as the end of the interval on its left.
        }
        let h = b.alpha - a.alpha;
        let splittable = depth < MAX_SPLIT_DEPTH && h > MIN_SPLIT_WIDTH && *splits_left > 0;
        if splittable {
            *splits_left -= 1;
        }
        if a.g * b.g < 0.0 {
            if splittable && let Some(t) = hermite_two_extrema(&a, &b) {
                let m = self.node_from(&a, t * h, sign);
                self.scan(sign, a, m, depth + 1, tangent_tolerance, roots, splits_left);
                self.scan(sign, m, b, depth + 1, tangent_tolerance, roots, splits_left);
            } else {
                let _ = roots.try_push(self.refine(sign, &a, &b));
            }
            return;
        }
        // Same sign: look at f = |g|.
        let s = a.g.signum();
        let (fa, fb, dfa, dfb) = (s * a.g, s * b.g, s * a.dg, s * b.dg);
        if dfa < 0.0 && dfb > 0.0 {
            if tangents_clear(fa, fb, dfa, dfb, h) {
                return;
            }
            let t = (fb - fa - dfb * h) / (dfa - dfb);
            if !splittable {
                let m = self.node_from(&a, t.clamp(0.0, h), sign);
                if m.g.abs() <= tangent_tolerance {
                    let _ = roots.try_push(m.root(sign));
                }
                return;
            }
            let m = self.node_from(&a, t.clamp(0.01 * h, 0.99 * h), sign);
            self.scan(sign, a, m, depth + 1, tangent_tolerance, roots, splits_left);
            self.scan(sign, m, b, depth + 1, tangent_tolerance, roots, splits_left);
        } else if splittable && let Some(t) = hermite_two_extrema(&a, &b) {
            let m = self.node_from(&a, t * h, sign);
            self.scan(sign, a, m, depth + 1, tangent_tolerance, roots, splits_left);
            self.scan(sign, m, b, depth + 1, tangent_tolerance, roots, splits_left);
        }
    }
}

/// `(sin, cos)` of `base.alpha + u`, by rotating the base node's by `u`.
#[inline]
fn rotate(base: &Node, u: f64) -> (f64, f64) {
    let (su, cu) = sin_cos_small(u);
    (base.sin * cu + base.cos * su, base.cos * cu - base.sin * su)
}

/// Iterations of Newton's method on the cubic Hermite interpolant for the refinement start.
const HERMITE_START_ITERATIONS: usize = 2;

/// The root, as a fraction of the interval, of the cubic Hermite interpolant of two nodes
/// whose residuals have opposite signs: a few Newton steps from the secant point, kept
/// inside `[0, 1]`.
fn hermite_root(a: &Node, b: &Node, h: f64) -> f64 {
    let (ga, gb, m0, m1) = (a.g, b.g, a.dg * h, b.dg * h);
    let mut t = ga / (ga - gb);
    for _ in 0..HERMITE_START_ITERATIONS {
        let t2 = t * t;
        let t3 = t2 * t;
        let value = (2.0 * t3 - 3.0 * t2 + 1.0) * ga
            + (t3 - 2.0 * t2 + t) * m0
            + (3.0 * t2 - 2.0 * t3) * gb
            + (t3 - t2) * m1;
        let slope = (6.0 * t2 - 6.0 * t) * (ga - gb)
            + (3.0 * t2 - 4.0 * t + 1.0) * m0
            + (3.0 * t2 - 2.0 * t) * m1;
        let next = t - value / slope;
        if !(next > 0.0 && next < 1.0) {
            break;
        }
        t = next;
    }
    t
}

/// Whether the tangent lines of `f = |g|` at the ends of an interval of width `h` (`f`
/// falling at the start, `dfa < 0`, rising at the end, `dfb > 0`) meet above zero: then a
/// convex `f` has no root inside. Division-free form of `fa + dfa t > 0` with
/// `t = (fb − fa − dfb h) / (dfa − dfb)` (the denominator is negative). The expression is
/// unchanged when `f`, `df` are replaced by `g`, `dg` (`f = ±g`), so it also takes `g`.
#[inline]
fn tangents_clear(fa: f64, fb: f64, dfa: f64, dfb: f64, h: f64) -> bool {
    dfa * fb - fa * dfb - dfa * dfb * h < 0.0
}

/// Whether an interval without a sign change (`ga ≠ 0`) may hold roots and must be scanned:
/// the same tests as [`Residual::scan`], evaluated without divisions or sign flips. With
/// `s = sign(ga)`, `f = s·g`: the valley `s·dga < 0 < s·dgb` needs end slopes of opposite
/// signs (`dga·dgb < 0`) and is `ga·dga < 0`; the tangent-line bound
/// `dfa·fb − fa·dfb − dfa·dfb·h` equals `dga·gb − ga·dgb − dga·dgb·h` (`s² = 1`); and the
/// Hermite S-shape needs end slopes of the same sign (`dga·dgb > 0`).
#[inline]
fn same_sign_needs_scan(ga: f64, gb: f64, dga: f64, dgb: f64, h: f64) -> bool {
    let p = dga * dgb;
    if p < 0.0 {
        ga * dga < 0.0 && !tangents_clear(ga, gb, dga, dgb, h)
    } else {
        // m0·m1 = p·h² > 0: the rest of `hermite_has_two_extrema`.
        let (m0, _, qa, qb) = hermite_slope(ga, gb, dga, dgb, h);
        p > 0.0
            && qa * qb < 0.0
            && (qb + 2.0 * qa) * qa > 0.0
            && (4.0 * qa * m0 - qb * qb) * m0 * qa < 0.0
    }
}

/// The coefficients `(m0, qa, qb)` of `H'(t) = qa t² + qb t + m0` of the cubic Hermite
/// interpolant of two nodes on `t ∈ [0, 1]`, and `m1 = H'(1)`.
#[inline]
fn hermite_slope(ga: f64, gb: f64, dga: f64, dgb: f64, h: f64) -> (f64, f64, f64, f64) {
    let (m0, m1, delta) = (dga * h, dgb * h, gb - ga);
    let qa = 3.0 * (m0 + m1) - 6.0 * delta;
    let qb = 6.0 * delta - 4.0 * m0 - 2.0 * m1;
    (m0, m1, qa, qb)
}

/// Whether the cubic Hermite interpolant of two nodes has two critical points strictly
/// inside the interval: `m0`, `m1` of the same sign, and the vertex `t = −qb / 2qa` inside
/// with `H'` of the other sign there (`m0 − qb²/4qa`), all without division.
#[inline]
fn hermite_has_two_extrema(ga: f64, gb: f64, dga: f64, dgb: f64, h: f64) -> bool {
    let (m0, m1, qa, qb) = hermite_slope(ga, gb, dga, dgb, h);
    m0 * m1 > 0.0
        && qa * qb < 0.0
        && (qb + 2.0 * qa) * qa > 0.0
        && (4.0 * qa * m0 - qb * qb) * m0 * qa < 0.0
}

/// If the cubic Hermite interpolant of two nodes has two critical points strictly inside
/// the interval, the midpoint between them as a fraction of the interval.
fn hermite_two_extrema(a: &Node, b: &Node) -> Option<f64> {
    let h = b.alpha - a.alpha;
    if !hermite_has_two_extrema(a.g, b.g, a.dg, b.dg, h) {
        return None;
    }
    let (_, _, qa, qb) = hermite_slope(a.g, b.g, a.dg, b.dg, h);
    Some(-qb / (2.0 * qa))
}

/// The law-of-cosines root search with a given sampling (exposed to the crate for the
/// miss-rate measurements).
pub(crate) fn solve_ranges(
    bearings_in_rig: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
    samples: usize,
    search_extrema: bool,
) -> RangeSolutions {
    match unit_bearings(bearings_in_rig) {
        Some(d) => solve_unit(&d, points_in_world, samples, search_extrema),
        None => RangeSolutions::new(),
    }
}

/// [`solve_ranges`] for unit bearings.
fn solve_unit(
    d: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
    samples: usize,
    search_extrema: bool,
) -> RangeSolutions {
    let mut out = RangeSolutions::new();
    if !points_in_world.iter().all(is_finite) {
        return out;
    }
    let x = points_in_world;
    let (e01, e02, e12) = (x[1] - x[0], x[2] - x[0], x[2] - x[1]);
    let (q01, q02, q12) = (e01.norm_squared(), e02.norm_squared(), e12.norm_squared());
    let longest2 = q01.max(q02).max(q12);
    let area2 = e01.cross(&e02).norm_squared();
    if area2.is_nan() || area2 <= MIN_TRIANGLE_SINE * MIN_TRIANGLE_SINE * longest2 * longest2 {
        return out;
    }
    // Work in units of the longest side (residual magnitudes O(1)).
    let longest = longest2.sqrt();
    let unit = 1.0 / longest;
    let (s01, s02, s12) = (q01.sqrt() * unit, q02.sqrt() * unit, q12.sqrt() * unit);
    let cos = [d[0].dot(&d[1]), d[0].dot(&d[2]), d[1].dot(&d[2])];
    let sin = [
        d[0].cross(&d[1]).norm(),
        d[0].cross(&d[2]).norm(),
        d[1].cross(&d[2]).norm(),
    ];
    if (0..3).any(|k| sin[k] <= MIN_BEARING_SINE && cos[k] > 0.0) {
        return out;
    }
    // a = the landmark whose (0, a) ellipse is the smaller: R₀₁ ≤ R₀₂ ⇔ s₀₁ sin θ₀₂ ≤ s₀₂ sin θ₀₁.
    let swap = s01 * sin[1] > s02 * sin[0];
    let (s0a, s0b, sin_0a, cos_0a, sin_0b, cos_0b) = if swap {
        (s02, s01, sin[1], cos[1], sin[0], cos[0])
    } else {
        (s01, s02, sin[0], cos[0], sin[1], cos[1])
    };
    let sin2_0b = sin_0b * sin_0b;
    let residual = Residual {
        radius: s0a / sin_0a,
        sin_0a,
        cos_0a,
        cos_0b,
        sin2_0b,
        s2_0b: s0b * s0b,
        cos_ab: cos[2],
        cos2_0b: cos_0b * cos_0b - sin2_0b,
        k_ab: 2.0 * cos[2] * cos_0b,
        k0: s0b * s0b - s12 * s12,
    };
    if !residual.radius.is_finite() {
        return out;
    }
    let theta = sin_0a.atan2(cos_0a);
    let alpha_end = PI - theta;
    let junction = FRAC_PI_2 - theta;
    let scale = residual.radius.max(1.0);

    // Nodes: uniform in α (sines and cosines by the rotation recurrence), with the branch
    // junction of rₐ inserted as an extra node, so that r₀ is monotonic between nodes. The
    // end nodes have rₐ = 0 or r₀ = 0, so a root exactly there is no solution.
    let mut found: ArrayVec<Root, 16> = ArrayVec::new();
    // r_b is positive on the + branch where cos θ0b ≥ 0 or r0 < s0b, on the − branch where
    // cos θ0b > 0 and r0 > s0b. An interval (r0 monotonic) whose two ends are outside holds
    // no solution on that branch. r0 peaks at R0a (at the junction) or, past a right angle
    // θ0a, at s0a (α = 0): skip the − branch when r0 never exceeds s0b.
    let r0_max = if junction > 0.0 { residual.radius } else { s0a };
    let minus_branch = cos_0b > 0.0 && r0_max > s0b;
    let plus_needs_small_r0 = cos_0b < 0.0;
    let tangent_tolerance = TANGENT_RESIDUAL_TOLERANCE * scale * scale;
    let n = samples.max(2);
    let step = alpha_end / n as f64;
    let (sin_h, cos_h) = sin_cos_small(step);
    let mut junction_pending = junction > 0.0 && junction < alpha_end;

    // Nodes are generated and evaluated in chunks (structure of arrays, so that the
    // evaluation loop vectorises), then the intervals of the chunk are searched; the last
    // node of a chunk is the first of the next. Grid node k is at α = k·step, preceded by
    // the junction when that falls strictly inside the grid interval.
    let (mut k, mut sin_k, mut cos_k) = (0usize, 0.0_f64, 1.0_f64);
    let mut c = Chunk::new();
    (c.alpha[0], c.sin[0], c.cos[0]) = (0.0, 0.0, 1.0);
    loop {
        let mut len = 1;
        while len < CHUNK && k < n {
            let next = k + 1;
            let alpha = if next == n {
                alpha_end
            } else {
                next as f64 * step
            };
            if junction_pending && junction <= alpha {
                junction_pending = false;
                if junction < alpha {
                    // sin(π/2 − θ) = cos θ, cos(π/2 − θ) = sin θ.
                    (c.alpha[len], c.sin[len], c.cos[len]) = (junction, cos_0a, sin_0a);
                    len += 1;
                    continue;
                }
            }
            k = next;
            if k == n {
                // sin(π − θ) = sin θ, cos(π − θ) = −cos θ.
                (sin_k, cos_k) = (sin_0a, -cos_0a);
            } else {
                (sin_k, cos_k) = (sin_k * cos_h + cos_k * sin_h, cos_k * cos_h - sin_k * sin_h);
            }
            (c.alpha[len], c.sin[len], c.cos[len]) = (alpha, sin_k, cos_k);
            len += 1;
        }
        c.evaluate(&residual, len);
        let mut search = |branch: usize, i: usize| {
            let sign = if branch == 0 { 1.0 } else { -1.0 };
            let (a, b) = (c.node(branch, i - 1), c.node(branch, i));
            if b.g == 0.0 {
                let _ = found.try_push(b.root(sign));
            } else if a.g * b.g < 0.0 {
                if search_extrema {
                    residual.scan(sign, a, b, 0, tangent_tolerance, &mut found, &mut {
                        MAX_SPLITS_PER_INTERVAL
                    });
                } else {
                    let _ = found.try_push(residual.refine(sign, &a, &b));
                }
            } else if search_extrema && a.g != 0.0 {
                residual.scan(sign, a, b, 0, tangent_tolerance, &mut found, &mut {
                    MAX_SPLITS_PER_INTERVAL
                });
            }
        };
        let len = len.min(CHUNK);
        for (branch, feasible) in [(0, true), (1, minus_branch)] {
            if !feasible {
                continue;
            }
            let windows = c.g[branch][..len]
                .windows(2)
                .zip(c.dg[branch][..len].windows(2))
                .zip(c.alpha[..len].windows(2))
                .zip(c.r0[..len].windows(2));
            for (i, (((g, dg), alpha), r0)) in windows.enumerate() {
                let feasible = if branch == 0 {
                    !plus_needs_small_r0 || r0[0].min(r0[1]) < s0b
                } else {
                    r0[0].max(r0[1]) > s0b
                };
                let (ga, gb) = (g[0], g[1]);
                if feasible
                    && (gb == 0.0
                        || ga * gb < 0.0
                        || (search_extrema
                            && ga != 0.0
                            && same_sign_needs_scan(ga, gb, dg[0], dg[1], alpha[1] - alpha[0])))
                {
                    search(branch, i + 1);
                }
            }
        }
        if k >= n {
            break;
        }
        (c.alpha[0], c.sin[0], c.cos[0]) = (c.alpha[len - 1], c.sin[len - 1], c.cos[len - 1]);
    }

    // Ranges of the roots: all positive, duplicates removed.
    let mut roots: ArrayVec<[f64; 3], 8> = ArrayVec::new();
    for root in &found {
        let p = residual.sample(root.sin, root.cos);
        let r = [p.r0, p.ra, residual.rb(&p, root.sign)];
        if r.iter().all(|v| *v > 0.0 && v.is_finite())
            && !roots
                .iter()
                .any(|q| (0..3).all(|k| (q[k] - r[k]).abs() <= DUPLICATE_RANGE_TOLERANCE * scale))
        {
            let _ = roots.try_push(r);
        }
    }
    roots.sort_unstable_by(|p, q| p[0].total_cmp(&q[0]));
    for r in roots.into_iter().take(4) {
        let r = r.map(|v| v * longest);
        out.push(if swap { [r[0], r[2], r[1]] } else { r });
    }
    out
}

/// Smallest norm of the cross product of two unit triangle edges (the sine of the triangle
/// angle between them) for which the orientation of the triangle is defined.
const MIN_EDGE_SINE: f64 = 1e-10;

/// The right-handed orthonormal frame `[t₁ | t₂ | t₁ × t₂]` of a triangle's edges `e₁`,
/// `e₂` from its first vertex (`t₁ ∥ e₁`, `t₂ ∥ e₁ × e₂`), or `None` when degenerate.
fn edge_frame(e1: &Vector3<f64>, e2: &Vector3<f64>) -> Option<Matrix3<f64>> {
    let n1 = e1.norm();
    let c = e1.cross(e2);
    let nc = c.norm();
    // |e₁ × e₂| ≤ sine threshold × |e₁| |e₂| (also rejects zero, NaN and infinite norms).
    if !(n1 > 0.0 && nc > MIN_EDGE_SINE * n1 * e2.norm() && nc.is_finite()) {
        return None;
    }
    let t1 = e1 / n1;
    let t2 = c / nc;
    Some(Matrix3::from_columns(&[t1, t2, t1.cross(&t2)]))
}

/// The pose mapping the rig-frame points `rᵢ dᵢ` onto the world points, given the world
/// triangle's [`edge_frame`]: rotation by TRIAD on the two triangle edges from point 0
/// (the rig triangle's edge frame onto the world's), translation by the centroids.
fn pose_from_ranges(
    unit_bearings: &[Vector3<f64>; 3],
    ranges: &[f64; 3],
    world_frame: &Matrix3<f64>,
    centroid_world: &Vector3<f64>,
) -> Option<Pose> {
    let p: [Vector3<f64>; 3] = std::array::from_fn(|i| unit_bearings[i] * ranges[i]);
    let rig_frame = edge_frame(&(p[1] - p[0]), &(p[2] - p[0]))?;
    let rotation = world_frame * rig_frame.transpose();
    let centroid_rig = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
    let t = centroid_world - rotation * centroid_rig;
    let ok = is_finite(&t) && rotation.iter().all(|v| v.is_finite());
    ok.then(|| {
        Pose::from_parts(
            Translation3::from(t),
            Rotation3::from_matrix_unchecked(rotation),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{P3pProblem, rng};

    fn true_ranges(p: &P3pProblem) -> [f64; 3] {
        let t = p.world_from_rig.translation.vector;
        p.points_in_world.map(|x| (x - t).norm())
    }

    fn best_range_error(sol: &RangeSolutions, truth: &[f64; 3]) -> f64 {
        sol.iter()
            .map(|r| (0..3).map(|k| (r[k] - truth[k]).abs()).fold(0.0, f64::max))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn sin_cos_small_matches_libm() {
        for k in -1000..=1000 {
            let u = k as f64 * 1.2 * SMALL_ANGLE / 1000.0;
            let (s, c) = sin_cos_small(u);
            assert!((s - u.sin()).abs() <= 2.0 * f64::EPSILON, "sin {u}");
            assert!((c - u.cos()).abs() <= 2.0 * f64::EPSILON, "cos {u}");
        }
    }

    /// The division-free interval tests agree with their direct forms (away from ties at
    /// the rounding level).
    #[test]
    fn division_free_tests_match_direct_forms() {
        use rand::RngExt;
        let mut r = rng(5);
        let (mut hermite_hits, mut tangent_hits) = (0, 0);
        for _ in 0..200_000 {
            let v: [f64; 5] = std::array::from_fn(|_| r.random_range(-1.0..1.0));
            let (ga, gb, dga, dgb, h) = (v[0], v[1], v[2], v[3], 0.05 + 0.5 * v[4].abs());
            // Hermite: two interior critical points of H'(t) = qa t² + qb t + m0.
            let (m0, m1, qa, qb) = hermite_slope(ga, gb, dga, dgb, h);
            let t = -qb / (2.0 * qa);
            let at_vertex = m0 - qb * qb / (4.0 * qa);
            let direct = m0 * m1 > 0.0 && t > 0.0 && t < 1.0 && at_vertex * m0 < 0.0;
            let margin =
                (t.abs() - 1.0).abs().min(t.abs()) > 1e-9 && at_vertex.abs() > 1e-9 * m0.abs();
            if margin {
                assert_eq!(
                    hermite_has_two_extrema(ga, gb, dga, dgb, h),
                    direct,
                    "{v:?}"
                );
                hermite_hits += usize::from(direct);
            }
            // Tangent lines of f = |g| falling then rising.
            let (fa, fb, dfa, dfb) = (ga.abs(), gb.abs(), -dga.abs(), dgb.abs());
            let t = (fb - fa - dfb * h) / (dfa - dfb);
            let bound = fa + dfa * t;
            if bound.abs() > 1e-9 {
                assert_eq!(tangents_clear(fa, fb, dfa, dfb, h), bound > 0.0, "{v:?}");
                tangent_hits += usize::from(bound <= 0.0);
            }
        }
        // Both outcomes occur.
        assert!(
            hermite_hits > 1000 && tangent_hits > 1000,
            "{hermite_hits} {tangent_hits}"
        );
        // The combined same-sign filter against the direct form of the tests of `scan`.
        let mut needed = 0;
        for _ in 0..200_000 {
            let v: [f64; 5] = std::array::from_fn(|_| r.random_range(-1.0..1.0));
            let (ga, dga, dgb, h) = (v[0], v[2], v[3], 0.05 + 0.5 * v[4].abs());
            let gb = ga.signum() * v[1].abs(); // same sign as ga
            let s = ga.signum();
            let (fa, fb, dfa, dfb) = (s * ga, s * gb, s * dga, s * dgb);
            let (direct, near_tie) = if dfa < 0.0 && dfb > 0.0 {
                let t = (fb - fa - dfb * h) / (dfa - dfb);
                let bound = fa + dfa * t;
                (bound <= 0.0, bound.abs() < 1e-9)
            } else {
                let a = Node {
                    alpha: 0.0,
                    sin: 0.0,
                    cos: 1.0,
                    g: ga,
                    dg: dga,
                };
                let b = Node {
                    alpha: h,
                    sin: h.sin(),
                    cos: h.cos(),
                    g: gb,
                    dg: dgb,
                };
                let (m0, _, qa, qb) = hermite_slope(ga, gb, dga, dgb, h);
                let t = -qb / (2.0 * qa);
                let at_vertex = m0 - qb * qb / (4.0 * qa);
                let tie = t.abs().min((t - 1.0).abs()) < 1e-9 || at_vertex.abs() < 1e-9;
                (hermite_two_extrema(&a, &b).is_some(), tie)
            };
            if !near_tie {
                assert_eq!(same_sign_needs_scan(ga, gb, dga, dgb, h), direct, "{v:?}");
                needed += usize::from(direct);
            }
        }
        assert!(needed > 1000, "{needed}");
    }

    /// The Hermite start of the refinement lies in the bracket and, for a smooth residual
    /// sampled finely, is far closer to the root than the secant point.
    #[test]
    fn hermite_start_beats_the_secant_point() {
        // g(α) = sin α − 0.3 on [0.2, 0.5] (root at asin 0.3 ≈ 0.3047).
        let node = |alpha: f64| Node {
            alpha,
            sin: alpha.sin(),
            cos: alpha.cos(),
            g: alpha.sin() - 0.3,
            dg: alpha.cos(),
        };
        let (a, b) = (node(0.2), node(0.5));
        let h = b.alpha - a.alpha;
        let truth = 0.3_f64.asin();
        let start = a.alpha + h * hermite_root(&a, &b, h);
        let secant = a.alpha + h * a.g / (a.g - b.g);
        assert!((start - truth).abs() < 1e-4, "{start} vs {truth}");
        assert!((start - truth).abs() < 0.05 * (secant - truth).abs());
    }

    /// Miss-rate measurement against a 4096-sample reference on 10⁵ problems, for several
    /// sample counts with and without the extremum search (≈ 10 s in release):
    /// `cargo test --release --lib p3p_cosines::tests::miss_rate -- --nocapture`.
    #[test]
    fn miss_rate() {
        let trials = 100_000;
        let problems: Vec<P3pProblem> = {
            let mut r = rng(1000);
            (0..trials)
                .map(|_| P3pProblem::random_omni(&mut r, 1.0))
                .collect()
        };
        let reference: Vec<RangeSolutions> = problems
            .iter()
            .map(|p| solve_ranges(&p.bearings_in_rig, &p.points_in_world, 4096, true))
            .collect();
        let ref_missed = problems
            .iter()
            .zip(&reference)
            .filter(|(p, s)| best_range_error(s, &true_ranges(p)) > 1e-6)
            .count();
        let total_roots: usize = reference.iter().map(|s| s.len()).sum();
        println!("reference: {total_roots} roots, truth missed {ref_missed}");
        for extrema in [false, true] {
            for n in [6, 8, 12, 16, 24, 32] {
                let mut missed_truth = 0;
                let mut missed_roots = 0;
                let mut extra = 0;
                for (p, s_ref) in problems.iter().zip(&reference) {
                    let s = solve_ranges(&p.bearings_in_rig, &p.points_in_world, n, extrema);
                    if best_range_error(&s, &true_ranges(p)) > 1e-6 {
                        missed_truth += 1;
                    }
                    for r in s_ref {
                        if best_range_error(&s, r) > 1e-6 {
                            missed_roots += 1;
                        }
                    }
                    extra += s.len().saturating_sub(s_ref.len());
                }
                println!(
                    "extrema={extrema} n={n}: truth missed {missed_truth}/{trials}, roots missed {missed_roots}/{total_roots}, extra {extra}"
                );
                if extrema && n == RESIDUAL_SAMPLES {
                    assert_eq!(missed_roots, 0);
                    assert_eq!(extra, 0);
                }
            }
        }
    }
}
