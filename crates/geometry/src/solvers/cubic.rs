//! One real root of a real monic cubic, found without trigonometry.
//!
//! Used by [`super::p3p`] (Lambda Twist) to find a degenerate member of a pencil of conics.
//! The start is placed beyond the root from the nearest critical point (or from the
//! inflection point of a monotone cubic) using the exact expansion of the cubic about that
//! point, and Halley's method (cubic convergence) polishes it, typically in three steps.
//! No `acos`/`cos`/`cbrt` call is needed: the cube root that enters the start is a
//! bit-level estimate (3 % error), enough for a starting point.

/// Most Halley steps taken on the cubic. Convergence is cubic for simple roots (typically
/// three steps); the cap only bounds the linear convergence at a multiple root.
const MAX_HALLEY_STEPS: usize = 40;

/// Relative step size below which the Halley iteration has converged: convergence is
/// cubic, so after a step of relative size 1e-6 the error is at rounding level.
const HALLEY_REL_STEP: f64 = 1e-6;

/// `t³ + b t² + c t + d`.
#[inline(always)]
fn eval(b: f64, c: f64, d: f64, t: f64) -> f64 {
    ((t + b) * t + c) * t + d
}

/// A rough cube root (relative error below 3.2 %) of a finite `x ≥ 0`, from the bits of
/// the float: dividing the biased exponent (and mantissa) by three. Only a starting point.
#[inline(always)]
fn rough_cbrt(x: f64) -> f64 {
    f64::from_bits(x.to_bits() / 3 + 0x2A9F_7893_782D_A1CE)
}

/// The largest real root of `t³ + b t² + c t + d` when the cubic has three real roots, else
/// its only real root. All inputs finite gives a finite output, unless the cubic
/// overflows (then the result is not finite, and the caller must check it).
///
/// The start uses the exact expansion about the nearest critical point `t₀`
/// (`f(t₀ + δ) = f(t₀) ± g δ² + δ³`): `δ² (g + |δ|) = |f(t₀)|`, estimated by
/// `δ = √(|f(t₀)| / (g + ∛|f(t₀)|))` (exact when either term dominates, within 6 %
/// otherwise); for a monotone cubic, about the inflection point
/// (`f(tᵢ + s) = k + m s + s³`), `s = k / (m + ∛k²)`.
#[inline(always)]
pub(crate) fn outer_real_root(b: f64, c: f64, d: f64) -> f64 {
    let disc = b * b - 3.0 * c;
    let t0 = if disc > 0.0 {
        // Two critical points (-b ∓ g) / 3; f''/2 there is ∓g.
        let g = disc.sqrt();
        let t_min = (-b + g) * (1.0 / 3.0);
        let f_min = eval(b, c, d, t_min);
        if f_min <= 0.0 {
            // The largest root lies to the right of the local minimum.
            let k = -f_min;
            t_min + (k / (g + rough_cbrt(k))).sqrt()
        } else {
            // The local maximum is positive too: one real root, left of the local maximum.
            let t_max = (-b - g) * (1.0 / 3.0);
            let k = eval(b, c, d, t_max).max(0.0);
            t_max - (k / (g + rough_cbrt(k))).sqrt()
        }
    } else {
        // Monotone cubic: expand about the inflection point, f(tᵢ + s) = k + m s + s³.
        let t_inf = -b * (1.0 / 3.0);
        let k = eval(b, c, d, t_inf);
        let m = -disc * (1.0 / 3.0);
        let ka = k.abs();
        let r = rough_cbrt(ka);
        t_inf - (ka / (m + r * r)).copysign(k)
    };
    halley(b, c, d, t0)
}

/// Halley's method on the cubic from `t`, stopping at convergence or at a non-finite step
/// (zero denominator).
#[inline(always)]
fn halley(b: f64, c: f64, d: f64, mut t: f64) -> f64 {
    // The Halley step at t, or None where it is not finite (zero denominator).
    let step_at = |t: f64| {
        let f = eval(b, c, d, t);
        let df = (3.0 * t + 2.0 * b) * t + c;
        // Half the second derivative.
        let h = 3.0 * t + b;
        let step = f * df / (df * df - f * h);
        step.is_finite().then_some(step)
    };
    // The start is never within HALLEY_REL_STEP of the root in practice: the first step
    // is taken without the convergence test.
    match step_at(t) {
        Some(step) => t -= step,
        None => return t,
    }
    for _ in 1..MAX_HALLEY_STEPS {
        let Some(step) = step_at(t) else {
            break;
        };
        t -= step;
        if step.abs() <= HALLEY_REL_STEP * t.abs() {
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
