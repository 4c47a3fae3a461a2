//! The azimuth test of a landmark triple before its P3P solve, with a known vertical: whether
//! an upright-enough pose seeing the triple along the detection triple's levelled bearings
//! can stand within a cell's reach.

use nalgebra::{Vector2, Vector3};
use vgps_geometry::geometry::try_unit;

/// The landmark pairs of a triple, in the order of [`LevelledTriple`]'s arrays.
pub(super) const TRIPLE_PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Added to the azimuth bound of [`LevelledTriple`] for the rounding of a P3P pose (its
/// distance equations hold to 1e-9 relative), radians.
pub(super) const AZIMUTH_TEST_SLACK_RAD: f64 = 1e-6;

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
pub(super) struct LevelledTriple {
    /// `cos γ` per pair.
    pub(super) cos: [f64; 3],
    /// `sin γ` per pair.
    pub(super) sin: [f64; 3],
    /// `sin(min(η_p + η_q, B_pq, π/2))` per pair (`B_pq` of
    /// [`shared_tilt_azimuth_bound`]): the bound on `|sin(θ − γ)|` for the angle `θ` under
    /// which an upright-enough pose sees the pair.
    pub(super) tolerance: [f64; 3],
}

impl LevelledTriple {
    /// From three unit bearings, the unit up `u` and the tilt bound (radians); `None` when
    /// the test cannot be used: a tilt of `π/2` or more, or a bearing along `±u` (no
    /// azimuth).
    pub(super) fn new(bearings: &[Vector3<f64>; 3], up: &Vector3<f64>, tilt: f64) -> Option<Self> {
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
pub(super) fn shared_tilt_azimuth_bound(
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
pub(super) fn azimuths_can_meet(
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

#[cfg(test)]
mod tests {
    use super::super::UP_CHECK_MARGIN_RAD;
    use super::*;
    use rand::RngExt;
    use vgps_geometry::geometry::Pose;
    use vgps_geometry::solvers::p3p::p3p;

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
}
