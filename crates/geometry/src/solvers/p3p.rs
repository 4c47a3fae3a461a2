//! Lambda Twist P3P for bearings all around the sphere.
//!
//! # Equation
//! With unit bearings `yᵢ` (rig frame), world points `xᵢ` and unknown ranges `λᵢ > 0`, the
//! rig-frame points `λᵢ yᵢ` must keep the world distances:
//!
//! ```text
//! λᵢ² + λⱼ² − 2 bᵢⱼ λᵢ λⱼ = aᵢⱼ,   bᵢⱼ = yᵢ·yⱼ,  aᵢⱼ = |xᵢ − xⱼ|²,  (ij) ∈ {12, 13, 23}.
//! ```
//!
//! Writing `Λ = (λ₁, λ₂, λ₃)` and `Mᵢⱼ` for the quadratic form of the left-hand side, the
//! scale-free conics `D₁ = a₂₃M₁₂ − a₁₂M₂₃` and `D₂ = a₂₃M₁₃ − a₁₃M₂₃` satisfy
//! `ΛᵀD₁Λ = ΛᵀD₂Λ = 0`. A real root `γ` of the cubic `det(D₁ + γD₂) = 0` (its coefficients
//! in closed form in `aᵢⱼ`, `bᵢⱼ` and `sᵢⱼ = 1 − bᵢⱼ²`, as in the paper; the root by
//! Halley's method, see `cubic.rs`) gives a degenerate conic `D₀ = D₁ + γD₂`, a pair of
//! lines `l`, `m` through every solution: `D₀ = ½(l mᵀ + m lᵀ)`. It is split without an
//! eigen-decomposition: `adj D₀ = −p pᵀ` with `p = ½ l × m`, so `p` is a column of the
//! adjugate over the square root of its diagonal entry, and `D₀ + [p]ₓ = l mᵀ` has rank one:
//! its row and column through its largest entry are the two lines (`σ₁σ₂ = tr adj D₀ ≤ 0`
//! for a real pair). On each line the other conic leaves a homogeneous quadratic in two
//! ranges, and the sum of the three distance equations fixes the scale. No quartic is
//! solved. The ranges are then polished by Gauss-Newton (Newton) steps on the three
//! distance equations when their residual is not already negligible, and the pose follows
//! from the two congruent triangles: the rotation maps the orthonormal frame (edge 12,
//! in-plane normal, plane normal) of the rig-frame triangle `λᵢyᵢ` onto that of the world
//! triangle `xᵢ`, and the rig origin is `x₁ − R λ₁y₁`.
//!
//! # Omnidirectional bearings
//! Nothing in the method assumes a bearing in front of a pinhole: only the dot products
//! `bᵢⱼ` are used, so bearings anywhere on the sphere work (including angles above 90°).
//! The only sign condition is the physical one, `λᵢ > 0` (the point lies ahead along its
//! bearing), applied to every candidate.
//!
//! # Guards
//! Every square root and division is guarded; degenerate input (zero, non-finite,
//! parallel or antiparallel bearings, coincident or collinear points, a vanishing pencil)
//! gives an empty list, a complex line pair or a negative discriminant gives no candidate
//! from that branch, and a candidate that does not satisfy the distance equations after
//! refinement (so would give a non-orthonormal rotation) or has a non-finite entry is
//! dropped. The output therefore never contains NaN or infinity.
//!
//! # References
//! - M. Persson and K. Nordberg, "Lambda Twist: An Accurate Fast Robust Perspective Three
//!   Point (P3P) Solver", ECCV 2018.

use super::cubic::outer_real_root;
use crate::geometry::{Pose, PoseSolutions};
use crate::sym3::Sym3;
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

/// Smallest sine of the angle between two bearings: closer (or antiparallel) bearings are
/// a degenerate sample.
pub const MIN_BEARING_SINE: f64 = 1e-9;

/// Smallest ratio of twice the triangle area to the squared longest side of the three world
/// points (about the height over the longest side): flatter triangles are collinear.
pub const MIN_TRIANGLE_SHAPE: f64 = 1e-9;

/// A pencil whose leading coefficient is this small relative to the others has its root at
/// infinity: `D₂` itself is the degenerate conic.
const CUBIC_LEADING_TOL: f64 = 1e-14;

/// Relative tolerance below which a (slightly) negative quadratic discriminant is treated
/// as a double root, and a (slightly) positive eigenvalue product as a double line.
const DISCRIMINANT_TOL: f64 = 1e-12;

/// Largest accepted magnitude of the root γ of the pencil's cubic. With the normalised
/// coefficients (|aᵢⱼ|, |bᵢⱼ|, sᵢⱼ ≤ 1) and the leading coefficient at least
/// [`CUBIC_LEADING_TOL`] times the others, every root satisfies |γ| < 1 + 1e14 (Cauchy's
/// bound); anything beyond this is a failed iteration. It also bounds D0 and what follows,
/// so no later overflow is possible.
const MAX_PENCIL_ROOT: f64 = 1e20;

/// Most Newton steps on the distance equations (the paper uses a few Gauss-Newton steps;
/// the closed-form ranges are usually accurate to 1e-12 or better, so one step suffices).
const REFINE_STEPS: usize = 3;

/// Largest residual of the normalised distance equations (longest side 1) at which the
/// ranges count as converged.
const REFINE_CONVERGED: f64 = 1e-14;

/// Largest residual of the normalised distance equations accepted in a solution; larger
/// ones would make the recovered rotation measurably non-orthonormal.
const MAX_RESIDUAL: f64 = 1e-9;

/// `x > 0`, false for NaN: the guard form used before every square root and division.
#[inline(always)]
fn positive(x: f64) -> bool {
    x > 0.0
}

/// Index of the entry of largest magnitude.
#[inline(always)]
fn argmax_abs(v: &Vector3<f64>) -> usize {
    argmax3(v.x.abs(), v.y.abs(), v.z.abs())
}

/// Index (0, 1 or 2) of the largest of three numbers, the first on ties.
#[inline(always)]
fn argmax3(a: f64, b: f64, c: f64) -> usize {
    if a >= b {
        if a >= c { 0 } else { 2 }
    } else if b >= c {
        1
    } else {
        2
    }
}

/// Squared norms accepted by the fast normalisation (no under- or overflow).
const FAST_NORM2_RANGE: (f64, f64) = (1e-280, 1e280);

/// The smaller of two numbers (plain comparison: no NaN handling, the callers check).
#[inline(always)]
fn min2(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

/// The larger of two numbers (plain comparison: no NaN handling, the callers check).
#[inline(always)]
fn max2(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// Squared sine above which 1 − b² (b the cosine of unit bearings) is accurate enough to
/// show that a pair of bearings passes the [`MIN_BEARING_SINE`] guard.
const SMALL_SINE2: f64 = 1e-6;

/// The parallel-bearing guard from cross products: every pair of unit bearings at a sine
/// above [`MIN_BEARING_SINE`]. The slow path for nearly (anti)parallel pairs.
#[cold]
#[inline(never)]
fn bearings_apart(y1: &Vector3<f64>, y2: &Vector3<f64>, y3: &Vector3<f64>) -> bool {
    let min_sin2 = MIN_BEARING_SINE * MIN_BEARING_SINE;
    y1.cross(y2).norm_squared() > min_sin2
        && y1.cross(y3).norm_squared() > min_sin2
        && y2.cross(y3).norm_squared() > min_sin2
}

/// The three unit bearings, rescaling vectors whose squared norm would under- or overflow;
/// `None` if one is zero or not finite. The slow path of the normalisation.
#[cold]
#[inline(never)]
fn units_rescaled(v: &[Vector3<f64>; 3]) -> Option<[Vector3<f64>; 3]> {
    let unit = |v: &Vector3<f64>| {
        let m = v.amax();
        if !(m > 0.0 && m.is_finite()) {
            return None;
        }
        let w = v / m;
        let n = w.norm();
        Some(w / n)
    };
    Some([unit(&v[0])?, unit(&v[1])?, unit(&v[2])?])
}

/// Every pose of a rig that sees three world points along three bearings (P3P), by the
/// Lambda Twist method, for bearings anywhere on the sphere.
///
/// Returns every real solution with positive ranges along all three bearings (at most
/// four), each as a `world_from_rig` pose (rotation + rig origin in the world frame). An
/// empty list means a degenerate sample (see the module documentation); no output ever
/// contains NaN or infinity.
///
/// # Units
/// Bearings: directions in the rig frame, any non-zero finite length (normalised inside).
/// Points: metres in a Cartesian world frame. Poses: metres and rotation matrices.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::{bearing_in_rig, Pose};
/// // The rig sits at (10, -5, 2), rotated 0.3 rad about z; one landmark is behind it.
/// let truth = Pose::new(Vector3::new(10.0, -5.0, 2.0), Vector3::new(0.0, 0.0, 0.3));
/// let points = [
///     Vector3::new(30.0, 0.0, 5.0),
///     Vector3::new(-20.0, 4.0, 1.0),
///     Vector3::new(12.0, 25.0, -3.0),
/// ];
/// let bearings = points.map(|p| bearing_in_rig(&truth, &p).unwrap());
/// let solutions = vgps_geometry::solvers::p3p(&bearings, &points);
/// let best = solutions
///     .iter()
///     .map(|s| (s.translation.vector - truth.translation.vector).norm())
///     .fold(f64::INFINITY, f64::min);
/// assert!(best < 1e-9);
/// ```
///
/// # References
/// M. Persson and K. Nordberg, "Lambda Twist: An Accurate Fast Robust Perspective Three
/// Point (P3P) Solver", ECCV 2018.
#[inline]
pub fn p3p(
    bearings_in_rig: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
) -> PoseSolutions {
    let mut solutions = PoseSolutions::new();
    solve_into(bearings_in_rig, points_in_world, &mut solutions);
    solutions
}

/// Three bearings prepared for P3P: made unit, with their pairwise cosines and squared
/// sines. What [`p3p`] computes from the bearings alone, done once when one detection
/// triple is solved against many landmark triples (the matcher solves hundreds per triple).
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::geometry::{bearing_in_rig, Pose, PoseSolutions};
/// use vgps_geometry::solvers::p3p::{p3p_prepared_into, P3pBearings};
/// let truth = Pose::new(Vector3::new(10.0, -5.0, 2.0), Vector3::new(0.0, 0.0, 0.3));
/// let points = [
///     Vector3::new(30.0, 0.0, 5.0),
///     Vector3::new(-20.0, 4.0, 1.0),
///     Vector3::new(12.0, 25.0, -3.0),
/// ];
/// let bearings = P3pBearings::try_new(&points.map(|p| bearing_in_rig(&truth, &p).unwrap()))
///     .unwrap();
/// let mut solutions = PoseSolutions::new();
/// p3p_prepared_into(&bearings, &points, &mut solutions);
/// assert!(solutions
///     .iter()
///     .any(|s| (s.translation.vector - truth.translation.vector).norm() < 1e-9));
/// ```
#[derive(Clone, Copy, Debug)]
pub struct P3pBearings {
    /// Unit bearings.
    ys: [Vector3<f64>; 3],
    /// Cosines `b12, b13, b23`.
    b: [f64; 3],
    /// Squared sines `s12, s13, s23`.
    s: [f64; 3],
    /// The known vertical, when solutions must be upright ([`P3pBearings::with_max_tilt`]).
    up: Option<UpLimit>,
}

/// Added to the frame-axis test of [`UpLimit`] for rounding: the rotation maps each rig
/// frame axis onto its world axis to about 1e-15, and the computed `cos` test of the
/// final pose may pass at an angle above the limit by about `√(1e-16)`.
const UP_AXIS_SLACK: f64 = 1e-7;

/// Largest `||u|² − 1|` of the up direction given to [`P3pBearings::with_max_tilt`].
pub const UNIT_UP_TOLERANCE: f64 = 1e-12;

/// A known vertical for [`P3pBearings::with_max_tilt`].
#[derive(Clone, Copy, Debug)]
struct UpLimit {
    /// The rig's up direction, unit, in the rig frame.
    up_in_rig: Vector3<f64>,
    /// `cos` of the largest tilt: a pose is upright enough when `(R u)_z ≥ min_z`.
    min_z: f64,
    /// `2 sin(max_tilt / 2) + UP_AXIS_SLACK`: for every rig vector `w` of unit length,
    /// `|u·w − (R w)_z| ≤ |u − Rᵀz| = 2 sin(θ/2)`, `θ` the pose's tilt.
    axis_tol: f64,
}

impl P3pBearings {
    /// Prepares three bearings (any non-zero finite length); `None` when a bearing is zero
    /// or not finite, or two are (anti)parallel to within [`MIN_BEARING_SINE`]: a
    /// degenerate sample for every landmark triple.
    #[inline(always)]
    pub fn try_new(bearings_in_rig: &[Vector3<f64>; 3]) -> Option<Self> {
        let [r1, r2, r3] = bearings_in_rig;
        let (n1, n2, n3) = (r1.norm_squared(), r2.norm_squared(), r3.norm_squared());
        // All three within FAST_NORM2_RANGE; a NaN or infinity makes the sum fail the test.
        let fast = min2(min2(n1, n2), n3) > FAST_NORM2_RANGE.0 && n1 + n2 + n3 < FAST_NORM2_RANGE.1;
        let [y1, y2, y3] = if fast {
            [
                r1 * (1.0 / n1.sqrt()),
                r2 * (1.0 / n2.sqrt()),
                r3 * (1.0 / n3.sqrt()),
            ]
        } else {
            units_rescaled(bearings_in_rig)?
        };
        let (b12, b13, b23) = (y1.dot(&y2), y1.dot(&y3), y2.dot(&y3));
        // Squared sines of the angles between the bearings, the sᵢⱼ of the cubic.
        let (s12, s13, s23) = (1.0 - b12 * b12, 1.0 - b13 * b13, 1.0 - b23 * b23);
        // 1 − b² cannot resolve the tiny angles of the parallel-bearing guard: below
        // SMALL_SINE2 the guard uses the cross products (exact for small angles).
        let clearly_apart = s12 > SMALL_SINE2 && s13 > SMALL_SINE2 && s23 > SMALL_SINE2;
        if !clearly_apart && !bearings_apart(&y1, &y2, &y3) {
            return None;
        }
        Some(Self {
            ys: [y1, y2, y3],
            b: [b12, b13, b23],
            s: [s12, s13, s23],
            up: None,
        })
    }

    /// Keeps only the solutions whose up is within `max_tilt_rad` of the world's `+z`:
    /// `(R·up_in_rig)_z ≥ cos(max_tilt_rad)` for `R = world_from_rig` (a level vehicle, an
    /// IMU). `up_in_rig` must be a unit vector (to [`UNIT_UP_TOLERANCE`] in its squared
    /// norm) and `max_tilt_rad` in `[0, ∞)` (no constraint from `π` on); `None` otherwise. The kept
    /// solutions are `p3p`'s bit for bit, and the others are dropped before the pose is
    /// assembled whenever an axis of the triangle's frame already shows the tilt (the
    /// frames map onto each other, so `|u·wₖ − uₖ_z| ≤ 2 sin(θ/2)` for each rig axis `wₖ`
    /// and its world axis `uₖ`), which saves most of the work of a tilted candidate.
    ///
    /// # Units
    /// Radians.
    pub fn with_max_tilt(mut self, up_in_rig: &Vector3<f64>, max_tilt_rad: f64) -> Option<Self> {
        if !((up_in_rig.norm_squared() - 1.0).abs() <= UNIT_UP_TOLERANCE && max_tilt_rad >= 0.0) {
            return None;
        }
        self.up = (max_tilt_rad < std::f64::consts::PI).then(|| UpLimit {
            up_in_rig: *up_in_rig,
            min_z: max_tilt_rad.cos(),
            axis_tol: 2.0 * (0.5 * max_tilt_rad).sin() + UP_AXIS_SLACK,
        });
        Some(self)
    }
}

/// [`p3p`] with the bearings prepared once ([`P3pBearings`]), writing every solution into
/// `solutions` (cleared first) instead of returning a new list: the same solutions, bit for
/// bit, for many landmark triples seen along the same three bearings.
#[inline]
pub fn p3p_prepared_into(
    bearings: &P3pBearings,
    points_in_world: &[Vector3<f64>; 3],
    solutions: &mut PoseSolutions,
) {
    solutions.clear();
    solve_prepared(bearings, points_in_world, solutions);
}

/// The body of [`p3p`], pushing every solution into `solutions`.
#[inline(always)]
fn solve_into(
    bearings_in_rig: &[Vector3<f64>; 3],
    points_in_world: &[Vector3<f64>; 3],
    solutions: &mut PoseSolutions,
) {
    if let Some(bearings) = P3pBearings::try_new(bearings_in_rig) {
        solve_prepared(&bearings, points_in_world, solutions);
    }
}

/// The world-side part of [`p3p`], from prepared bearings.
#[inline(always)]
fn solve_prepared(
    bearings: &P3pBearings,
    points_in_world: &[Vector3<f64>; 3],
    solutions: &mut PoseSolutions,
) {
    let [y1, y2, y3] = bearings.ys;
    let [b12, b13, b23] = bearings.b;
    let [s12, s13, s23] = bearings.s;
    let [x1, x2, x3] = points_in_world;
    let d12 = x1 - x2;
    let d13 = x1 - x3;
    let d23 = x2 - x3;
    let (a12r, a13r, a23r) = (d12.norm_squared(), d13.norm_squared(), d23.norm_squared());
    let normal = d12.cross(&d13);
    let nn = normal.norm_squared();
    let a_max = max2(max2(a12r, a13r), a23r);
    // Also rejects NaN and infinite points: a non-finite coordinate makes the normal (a
    // cross product of the differences) non-finite, and the comparisons false.
    if !(nn.is_finite()
        && a_max.is_finite()
        && nn > MIN_TRIANGLE_SHAPE * MIN_TRIANGLE_SHAPE * a_max * a_max)
    {
        return;
    }
    let inv_a = 1.0 / a_max;
    let (a12, a13, a23) = (a12r * inv_a, a13r * inv_a, a23r * inv_a);

    // --- The pencil of conics and one degenerate member -----------------------------------
    // D1 = a23 M12 − a12 M23 and D2 = a23 M13 − a13 M23 (see the module documentation).
    let d1 = Sym3 {
        xx: a23,
        xy: -a23 * b12,
        xz: 0.0,
        yy: a23 - a12,
        yz: a12 * b23,
        zz: -a12,
    };
    let d2 = Sym3 {
        xx: a23,
        xy: 0.0,
        xz: -a23 * b13,
        yy: -a13,
        yz: a13 * b23,
        zz: a23 - a13,
    };
    // det(D1 + γ D2) = −a23 (p3 γ³ − p2 γ² + p1 γ − p0), expanded in closed form with
    // sᵢⱼ = 1 − bᵢⱼ² (Persson & Nordberg's coefficients).
    let blob = b12 * b13 * b23 - 1.0;
    let p3 = a13 * (a23 * s13 - a13 * s23);
    let p2 = 2.0 * blob * a23 * a13 + a13 * (2.0 * a12 + a13) * s23 + a23 * (a23 - a12) * s13;
    let p1 = a23 * (a13 - a23) * s12 - a12 * a12 * s23 - 2.0 * a12 * (blob * a23 + a13 * s23);
    let p0 = a12 * (a12 * s23 - a23 * s12);
    let (d0, restrict) =
        if p3.abs() <= CUBIC_LEADING_TOL * (p0.abs() + p1.abs() + p2.abs()) || p3 == 0.0 {
            // Root at infinity: D2 is (numerically) degenerate itself.
            (d2, d1)
        } else {
            let inv = 1.0 / p3;
            let gamma = outer_real_root(-p2 * inv, p1 * inv, -p0 * inv);
            // Also rejects NaN: a root beyond the bound is a failed iteration.
            let bounded = gamma.abs() <= MAX_PENCIL_ROOT;
            if !bounded {
                return;
            }
            // D0 = D1 + γ D2; on a line of D0, D1 = −γ D2: restrict the better-scaled one.
            let d0 = Sym3 {
                xx: a23 + gamma * a23,
                xy: d1.xy,
                xz: gamma * d2.xz,
                yy: d1.yy - gamma * a13,
                yz: d1.yz + gamma * d2.yz,
                zz: gamma * d2.zz - a12,
            };
            (d0, if gamma.abs() >= 1.0 { d1 } else { d2 })
        };

    // --- Split the degenerate conic D0 into its two lines ----------------------------------
    // For D0 = ½(l mᵀ + m lᵀ) (l, m the lines), adj D0 = −p pᵀ with p = ½ l × m their
    // intersection, and D0 + [p]ₓ = l mᵀ (for one sign of p): any non-zero row of it is m,
    // any non-zero column l. adj D0 = σ₁σ₂ e₃e₃ᵀ, so its trace σ₁σ₂ must be ≤ 0.
    let adj0 = d0.adj();
    let m = adj0.xx + adj0.yy + adj0.zz;
    if m > DISCRIMINANT_TOL * d0.inner(&d0) {
        // A complex-conjugate line pair: no real line through a solution.
        return;
    }
    let (nxx, nyy, nzz) = (-adj0.xx, -adj0.yy, -adj0.zz);
    let (pkk, pcol) = if nxx >= nyy && nxx >= nzz {
        (nxx, Vector3::new(adj0.xx, adj0.xy, adj0.xz))
    } else if nyy >= nzz {
        (nyy, Vector3::new(adj0.xy, adj0.yy, adj0.yz))
    } else {
        (nzz, Vector3::new(adj0.xz, adj0.yz, adj0.zz))
    };
    // pkk ≤ 0 (adj D0 vanishes, or m is positive within the tolerance): a double line,
    // D0 = ±l lᵀ, and p = 0.
    let double_line = !positive(pkk);
    let p = if double_line {
        Vector3::zeros()
    } else {
        pcol * (1.0 / pkk.sqrt())
    };
    let rows = [
        Vector3::new(d0.xx, d0.xy - p.z, d0.xz + p.y),
        Vector3::new(d0.xy + p.z, d0.yy, d0.yz - p.x),
        Vector3::new(d0.xz - p.y, d0.yz + p.x, d0.zz),
    ];
    // The entry of largest magnitude, (bi, bj): its row and its column are the best
    // conditioned representatives of the two lines.
    let row_max = rows.map(|r| max2(max2(r.x.abs(), r.y.abs()), r.z.abs()));
    let bi = argmax3(row_max[0], row_max[1], row_max[2]);
    let row = rows[bi];
    let bj = argmax3(row.x.abs(), row.y.abs(), row.z.abs());
    // D0 = 0 would mean a vanishing pencil. Everything here is finite: the normalised aᵢⱼ,
    // bᵢⱼ, sᵢⱼ are at most 1 in magnitude and |γ| ≤ MAX_PENCIL_ROOT, so D0, its adjugate, p
    // and the rows are bounded far below overflow.
    if !positive(row_max[bi]) {
        return;
    }
    let lines = [row, Vector3::new(rows[0][bj], rows[1][bj], rows[2][bj])];

    // --- World-side orthonormal frame of the triangle: (edge 12, in-plane, normal) ----------
    let u1 = d12 * (1.0 / a12r.sqrt());
    let u3 = normal * (1.0 / nn.sqrt());
    let u2 = u3.cross(&u1);
    let frame = ProblemSetup {
        ys: [y1, y2, y3],
        x1: *x1,
        u: [u1, u2, u3],
        eq: Equations {
            a: [a12, a13, a23],
            b: [b12, b13, b23],
        },
        a_sum: a12 + a13 + a23,
        scale: a_max.sqrt(),
        up: bearings.up,
    };

    let n_lines = if double_line { 1 } else { 2 };
    for u in &lines[..n_lines] {
        // The plane u·Λ = 0 meets the open positive octant only if u has entries of both
        // signs: skip lines that cannot carry positive ranges.
        let any_neg = u.x < 0.0 || u.y < 0.0 || u.z < 0.0;
        let any_pos = u.x > 0.0 || u.y > 0.0 || u.z > 0.0;
        if !(any_neg && any_pos) {
            continue;
        }
        // Λ = α va + β vb spans the plane u·Λ = 0, with va = uₖeᵢ − uᵢeₖ and
        // vb = uₖeⱼ − uⱼeₖ for k the largest entry of u and (i, j) the other two axes.
        // On the other conic R: A α² + 2B αβ + C β² = 0, with (rᵢⱼ the entries of R)
        // A = uₖ²rᵢᵢ − 2uₖuᵢrᵢₖ + uᵢ²rₖₖ, B = uₖ²rᵢⱼ − uₖuⱼrᵢₖ − uₖuᵢrⱼₖ + uᵢuⱼrₖₖ,
        // C = uₖ²rⱼⱼ − 2uₖuⱼrⱼₖ + uⱼ²rₖₖ.
        let r = &restrict;
        let (ui, uj, uk, [rii, rjj, rkk, rij, rik, rjk], va, vb) = match argmax_abs(u) {
            0 => (
                u.y,
                u.z,
                u.x,
                [r.yy, r.zz, r.xx, r.yz, r.xy, r.xz],
                Vector3::new(-u.y, u.x, 0.0),
                Vector3::new(-u.z, 0.0, u.x),
            ),
            1 => (
                u.x,
                u.z,
                u.y,
                [r.xx, r.zz, r.yy, r.xz, r.xy, r.yz],
                Vector3::new(u.y, -u.x, 0.0),
                Vector3::new(0.0, -u.z, u.y),
            ),
            _ => (
                u.x,
                u.y,
                u.z,
                [r.xx, r.yy, r.zz, r.xy, r.xz, r.yz],
                Vector3::new(u.z, 0.0, -u.x),
                Vector3::new(0.0, u.z, -u.y),
            ),
        };
        let (kk, ki, kj) = (uk * uk, uk * ui, uk * uj);
        let qa = kk * rii - 2.0 * ki * rik + ui * ui * rkk;
        let qb = kk * rij - kj * rik - ki * rjk + ui * uj * rkk;
        let qc = kk * rjj - 2.0 * kj * rjk + uj * uj * rkk;
        let disc = qb * qb - qa * qc;
        if disc < -DISCRIMINANT_TOL * (qb * qb + (qa * qc).abs()) {
            continue;
        }
        let sq = disc.max(0.0).sqrt();
        let w = -(qb + sq.copysign(qb));
        // The two roots (α, β) = (w, A) and (C, w), division-free; a double root keeps
        // whichever representation is not (nearly) zero.
        if sq > 0.0 {
            frame.try_candidate(va * w + vb * qa, solutions);
            frame.try_candidate(va * qc + vb * w, solutions);
        } else if qa.abs() >= qc.abs() {
            frame.try_candidate(va * w + vb * qa, solutions);
        } else {
            frame.try_candidate(va * qc + vb * w, solutions);
        }
    }
}

/// What the candidates of one problem share: the rig-frame bearings, the world triangle's
/// first point and orthonormal frame, and the normalised distance equations.
struct ProblemSetup {
    /// Unit bearings.
    ys: [Vector3<f64>; 3],
    /// First world point.
    x1: Vector3<f64>,
    /// World frame of the triangle: edge 12, in-plane normal, plane normal.
    u: [Vector3<f64>; 3],
    /// Normalised distance equations.
    eq: Equations,
    /// a12 + a13 + a23 (normalised).
    a_sum: f64,
    /// Length of the longest side (metres): the normalisation.
    scale: f64,
    /// The known vertical, when solutions must be upright.
    up: Option<UpLimit>,
}

impl ProblemSetup {
    /// Completes a candidate direction of the ranges (any scale and sign) into a pose and
    /// pushes it, if its ranges are positive and satisfy the distance equations.
    #[inline(always)]
    fn try_candidate(&self, mut lam: Vector3<f64>, solutions: &mut PoseSolutions) {
        // Same sign for all three ranges, else no physical solution.
        if lam.x < 0.0 {
            lam = -lam;
        }
        if !(lam.x > 0.0 && lam.y > 0.0 && lam.z > 0.0) {
            return;
        }
        // Fix the scale s by the sum of the three distance equations (well conditioned:
        // every term is non-negative); the residuals at the scaled ranges follow from the
        // same quadratic forms.
        let q = self.eq.forms(&lam);
        let q_sum = q[0] + q[1] + q[2];
        if !positive(q_sum) {
            return;
        }
        let s2 = self.a_sum / q_sum;
        let [a12, a13, a23] = self.eq.a;
        let residual = [s2 * q[0] - a12, s2 * q[1] - a13, s2 * q[2] - a23];
        let Some(lam) = self.eq.refine(lam * s2.sqrt(), residual) else {
            return;
        };
        if !(lam.x > 0.0 && lam.y > 0.0 && lam.z > 0.0) {
            return;
        }
        // The same frame built from the rig-frame triangle (in normalised units, so that
        // nothing can overflow); world_from_rig maps one onto the other. Built from
        // orthonormal frames, the rotation is orthonormal with det +1 even when the
        // triangle is thin.
        let [y1, y2, y3] = &self.ys;
        let p1 = y1 * lam.x;
        let v1 = p1 - y2 * lam.y;
        let v2 = p1 - y3 * lam.z;
        let v3 = v1.cross(&v2);
        let (n1, n3) = (v1.norm_squared(), v3.norm_squared());
        if !(n1 > 0.0 && n3 > 0.0) {
            return;
        }
        let [u1, u2, u3] = &self.u;
        // With a known vertical: each frame axis is tested as soon as it exists.
        let tilted = |w: &Vector3<f64>, world_axis: &Vector3<f64>| {
            self.up
                .is_some_and(|up| (up.up_in_rig.dot(w) - world_axis.z).abs() > up.axis_tol)
        };
        let w1 = v1 * (1.0 / n1.sqrt());
        if tilted(&w1, u1) {
            return;
        }
        let w3 = v3 * (1.0 / n3.sqrt());
        if tilted(&w3, u3) {
            return;
        }
        let w2 = w3.cross(&w1);
        // world_from_rig = [u1 u2 u3] [w1 w2 w3]ᵀ.
        let rot = Matrix3::new(
            u1.x * w1.x + u2.x * w2.x + u3.x * w3.x,
            u1.x * w1.y + u2.x * w2.y + u3.x * w3.y,
            u1.x * w1.z + u2.x * w2.z + u3.x * w3.z,
            u1.y * w1.x + u2.y * w2.x + u3.y * w3.x,
            u1.y * w1.y + u2.y * w2.y + u3.y * w3.y,
            u1.y * w1.z + u2.y * w2.z + u3.y * w3.z,
            u1.z * w1.x + u2.z * w2.x + u3.z * w3.x,
            u1.z * w1.y + u2.z * w2.y + u3.z * w3.y,
            u1.z * w1.z + u2.z * w2.z + u3.z * w3.z,
        );
        let origin = self.x1 - rot * (p1 * self.scale);
        // One test for all twelve entries: a NaN or infinity makes the sum non-finite
        // (the entries are bounded, so the sum cannot overflow on its own).
        let total = rot.sum() + origin.sum();
        if !total.is_finite() {
            return;
        }
        let pose = Pose::from_parts(
            Translation3::from(origin),
            Rotation3::from_matrix_unchecked(rot),
        );
        let upright = self
            .up
            .is_none_or(|up| (pose.rotation * up.up_in_rig).z >= up.min_z);
        if !upright {
            return;
        }
        let _ = solutions.try_push(pose);
    }
}

/// The three normalised distance equations `λᵢ² + λⱼ² − 2bᵢⱼλᵢλⱼ = aᵢⱼ`, ordered 12, 13, 23.
struct Equations {
    a: [f64; 3],
    b: [f64; 3],
}

impl Equations {
    /// The left-hand sides of the three equations (quadratic forms in the ranges).
    #[inline(always)]
    fn forms(&self, l: &Vector3<f64>) -> [f64; 3] {
        let [b12, b13, b23] = self.b;
        let (xx, yy, zz) = (l.x * l.x, l.y * l.y, l.z * l.z);
        [
            xx + yy - 2.0 * b12 * l.x * l.y,
            xx + zz - 2.0 * b13 * l.x * l.z,
            yy + zz - 2.0 * b23 * l.y * l.z,
        ]
    }

    /// Residuals of the three equations.
    #[inline(always)]
    fn residual(&self, l: &Vector3<f64>) -> [f64; 3] {
        let [a12, a13, a23] = self.a;
        let [q12, q13, q23] = self.forms(l);
        [q12 - a12, q13 - a13, q23 - a23]
    }

    /// At most [`REFINE_STEPS`] Newton steps on the three equations (closed-form inverse of
    /// the sparse Jacobian) from ranges `l` with residuals `residual`, stopping once
    /// converged. Returns `None` if the ranges do not satisfy the equations to
    /// [`MAX_RESIDUAL`].
    #[inline(always)]
    fn refine(&self, mut l: Vector3<f64>, mut residual: [f64; 3]) -> Option<Vector3<f64>> {
        let [b12, b13, b23] = self.b;
        let mut step_count = 0;
        loop {
            let [r1, r2, r3] = residual;
            // Each test is false for NaN.
            let within = |tol: f64| r1.abs() <= tol && r2.abs() <= tol && r3.abs() <= tol;
            if within(REFINE_CONVERGED) {
                return Some(l);
            }
            if step_count == REFINE_STEPS {
                return within(MAX_RESIDUAL).then_some(l);
            }
            step_count += 1;
            // Half the Jacobian: rows ∂/∂λ of equations 12, 13, 23.
            let x11 = l.x - b12 * l.y;
            let x12 = l.y - b12 * l.x;
            let x21 = l.x - b13 * l.z;
            let x23 = l.z - b13 * l.x;
            let x32 = l.y - b23 * l.z;
            let x33 = l.z - b23 * l.y;
            let det = -(x11 * x23 * x32 + x12 * x21 * x33);
            let k = -0.5 / det;
            let step = Vector3::new(
                (-x23 * x32 * r1 - x12 * x33 * r2 + x12 * x23 * r3) * k,
                (-x21 * x33 * r1 + x11 * x33 * r2 - x11 * x23 * r3) * k,
                (x21 * x32 * r1 - x11 * x32 * r2 - x12 * x21 * r3) * k,
            );
            if !crate::geometry::is_finite(&step) {
                return within(MAX_RESIDUAL).then_some(l);
            }
            l += step;
            residual = self.residual(&l);
        }
    }
}
