//! One real root of a real monic cubic, found without trigonometry.
//!
//! Used by [`super::p3p`] (Lambda Twist) to find a degenerate member of a pencil of conics.
//! The root is bracketed from the critical points of the cubic so that Newton's method
//! converges monotonically from the first step; no `acos`/`cos` is needed and `cbrt` only
//! in the rare case where the cubic term dominates the starting estimate.

/// Most Newton steps taken on the cubic. Convergence is monotone and quadratic for simple
/// roots (typically 3–6 steps); the cap only bounds the linear convergence at a multiple root.
const MAX_NEWTON_STEPS: usize = 40;

/// Relative step size below which the Newton iteration has converged: convergence is
/// quadratic, so after a step of relative size 1e-9 the error is at rounding level.
const NEWTON_REL_STEP: f64 = 1e-9;

/// `t³ + b t² + c t + d`.
#[inline(always)]
fn eval(b: f64, c: f64, d: f64, t: f64) -> f64 {
    ((t + b) * t + c) * t + d
}

/// The largest real root of `t³ + b t² + c t + d` when the cubic has three real roots, else
/// its only real root. All inputs finite gives a finite output.
///
/// The start is placed on the far side of the root from the nearest critical point, where
/// the cubic does not change convexity, using the exact expansion about that point
/// (`f(t₀ + δ) = f(t₀) ± g δ² + δ³`): the smaller of the quadratic and the cubic estimates
/// of `δ` over-shoots the root by at most a factor of two, and Newton's method then
/// converges monotonically.
#[inline]
pub(crate) fn outer_real_root(b: f64, c: f64, d: f64) -> f64 {
    let disc = b * b - 3.0 * c;
    let t0 = if disc > 0.0 {
        // Two critical points (-b ∓ g) / 3; f''/2 there is ∓g.
        let g = disc.sqrt();
        let t_min = (-b + g) / 3.0;
        let f_min = eval(b, c, d, t_min);
        if f_min <= 0.0 {
            // The largest root lies to the right of the local minimum.
            let k = -f_min;
            let delta = if k <= g * g * g {
                (k / g).sqrt()
            } else {
                k.cbrt()
            };
            t_min + delta
        } else {
            // The local maximum is positive too: one real root, left of the local maximum.
            let t_max = (-b - g) / 3.0;
            let k = eval(b, c, d, t_max);
            let delta = if k <= g * g * g {
                (k / g).sqrt()
            } else {
                k.cbrt()
            };
            t_max - delta
        }
    } else {
        // Monotone cubic: expand about the inflection point, f(tᵢ + s) = k + m s + s³.
        let t_inf = -b / 3.0;
        let k = eval(b, c, d, t_inf);
        if k == 0.0 {
            return t_inf;
        }
        let m = -disc / 3.0;
        let ka = k.abs();
        let delta = if ka * ka <= m * m * m {
            ka / m
        } else {
            ka.cbrt()
        };
        t_inf - delta.copysign(k)
    };
    newton(b, c, d, t0)
}

/// Newton's method on the cubic from `t`, stopping at convergence or at a zero slope.
#[inline]
fn newton(b: f64, c: f64, d: f64, mut t: f64) -> f64 {
    for _ in 0..MAX_NEWTON_STEPS {
        let f = eval(b, c, d, t);
        let df = (3.0 * t + 2.0 * b) * t + c;
        if f == 0.0 || df == 0.0 {
            break;
        }
        let step = f / df;
        if !step.is_finite() {
            break;
        }
        t -= step;
        if step.abs() <= NEWTON_REL_STEP * t.abs() {
            // One more (cheap) step gives full precision at a simple root.
            let f = eval(b, c, d, t);
            let df = (3.0 * t + 2.0 * b) * t + c;
            let step = f / df;
            if step.is_finite() {
                t -= step;
            }
            break;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(roots: [f64; 3]) {
        let [r1, r2, r3] = roots;
        let b = -(r1 + r2 + r3);
        let c = r1 * r2 + r1 * r3 + r2 * r3;
        let d = -r1 * r2 * r3;
        let t = outer_real_root(b, c, d);
        let largest = r1.max(r2).max(r3);
        let scale = 1.0 + r1.abs().max(r2.abs()).max(r3.abs());
        assert!(
            (t - largest).abs() <= 1e-9 * scale,
            "roots {roots:?}: got {t}"
        );
    }

    #[test]
    fn three_real_roots_gives_the_largest() {
        check([1.0, 2.0, 3.0]);
        check([-5.0, 0.1, 0.2]);
        check([-1e3, -2.0, 7.5]);
        check([0.0, 0.0, 1.0]);
        check([2.0, 2.0, 2.0 + 1e-3]);
    }

    #[test]
    fn one_real_root_is_found() {
        // (t - r)(t² + p t + q) with p² < 4q.
        for &(r, p, q) in &[
            (1.5, 0.0, 1.0),
            (-3.0, 2.0, 5.0),
            (1e3, -1.0, 1.0),
            (0.0, 0.1, 1e-2),
        ] {
            let b = p - r;
            let c = q - r * p;
            let d = -r * q;
            let t = outer_real_root(b, c, d);
            assert!((t - r).abs() <= 1e-9 * (1.0 + r.abs()), "{t} vs {r}");
        }
    }

    #[test]
    fn triple_root_is_found() {
        let t = outer_real_root(-3.0, 3.0, -1.0);
        assert!((t - 1.0).abs() < 1e-4, "{t}");
    }
}
