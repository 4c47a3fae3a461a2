//! Polynomial `acos` and `atan2` with proven error bounds, for the cell set-up (one angle per
//! candidate pair, two elevations per candidate): the bounds are added to every bound built
//! on them, so the pair tables and elevation gates stay sound.

/// Largest error of [`fast_acos`], radians. The approximation is accurate to 2.2·10⁻⁸
/// (checked on 2·10⁶ points, `fast_acos_is_within_its_error_bound`); the rest is room for
/// rounding. It is added to every pair bound built on the angle, so the pair tables stay
/// sound.
pub(super) const FAST_ACOS_MAX_ERROR_RAD: f64 = 1e-7;

/// `acos(x)` (radians, in `[0, π]`) for `x` in `[−1, 1]` (clamped), to within
/// [`FAST_ACOS_MAX_ERROR_RAD`]: `acos(|x|) = √(1 − |x|) · P(|x|)` with the degree-7
/// polynomial of Abramowitz & Stegun, and `acos(x) = π − acos(−x)` for `x < 0`. One square
/// root and seven multiply-adds, against libm's correctly rounded `acos`, which took an
/// eighth of a prior frame's time in the cell set-up (one angle per candidate pair).
///
/// # References
/// M. Abramowitz and I. A. Stegun, *Handbook of Mathematical Functions* (1964), 4.4.46.
pub(super) fn fast_acos(x: f64) -> f64 {
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
pub(super) const FAST_ATAN_MAX_ERROR_RAD: f64 = 1e-7;

/// `atan2(y, x)` (radians, in `[−π/2, π/2]`) for `x ≥ 0`, to within
/// [`FAST_ATAN_MAX_ERROR_RAD`]: `atan(a) = a · P(a²)` for `a = min(|x|, |y|) / max(|x|, |y|)`
/// in `[0, 1]` (`P` of degree 7, a minimax fit made for this crate; tested against libm on a
/// dense grid), `π/2 − atan(1/a)` when `|y| > |x|`, and the sign of `y`. One division and
/// eight multiply-adds, against libm's `atan2`, which took 3 % of a prior frame's time in
/// the cell set-up (two per candidate and cell). `0` for `x = y = 0`; finite inputs.
pub(super) fn fast_atan2(y: f64, x: f64) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
