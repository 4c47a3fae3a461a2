//! The a-contrario acceptance test of a matcher fix: how many of the poses the search tried
//! would, by chance, gather as many inliers as the fix (the number of false alarms, NFA).
//!
//! Under the null hypothesis ("the fix is a wrong pose") the detections that the pose did
//! not fit exactly are unrelated to the landmarks seen from it. Three inliers come free with
//! every P3P pose ([`FREE_INLIERS`]); each other detection lands in the gate of some landmark
//! in range with probability `p` ([`chance_alignment_probability`]). A fix with `k` inliers of
//! `n` detections, found among `N` poses tried, has
//!
//! `NFA = N · P(Bin(n − 3, p) ≥ k − 3)`
//!
//! and is accepted when `NFA ≤ ε` ([`super::MatchOptions::max_false_alarms`], default
//! [`DEFAULT_MAX_FALSE_ALARMS`]): the expected number of wrong poses per frame that would
//! pass is then at most `ε`. Derivation and measured rates: docs/matcher-acceptance.md.
//!
//! # Example
//! ```
//! use vgps_core::matcher::nfa::{chance_alignment_probability, log10_false_alarms};
//! // 40 landmarks spread evenly in elevation over 0–40°, gates of 0.75°.
//! let gate = 0.75_f64.to_radians();
//! let landmarks: Vec<(f64, f64)> =
//!     (0..40).map(|k| ((k as f64).to_radians(), gate)).collect();
//! let p = chance_alignment_probability(&landmarks);
//! assert!(p > 1e-3 && p < 2e-2, "{p}");
//! // 14 inliers of 20 detections among 10⁴ poses: far below one false alarm.
//! assert!(log10_false_alarms(10_000, 20, 14, p) < -15.0);
//! // 6 inliers of 20 among 10⁶ poses: chance explains it.
//! assert!(log10_false_alarms(1_000_000, 20, 6, p) > 0.0);
//! ```

/// Inliers that come free with a pose fitted exactly to them: three bearings fix the six
/// degrees of freedom of a P3P pose.
pub const FREE_INLIERS: usize = 3;

/// Default most expected wrong poses per frame that may pass the test (`ε`, a count per
/// frame): a wrong fix needs the truth not to be generated *and* a chance alignment this
/// unlikely.
pub const DEFAULT_MAX_FALSE_ALARMS: f64 = 1e-3;

/// Width of the window over which the elevation density of the landmarks in range is
/// averaged (radians, 2°; widened to the gate's diameter when that is larger).
pub const ELEVATION_WINDOW_RAD: f64 = 0.034_906_585_039_886_59;

/// The probability `p` that one detection unrelated to the landmarks falls within the gate
/// of at least one of them (union bound: the sum over the landmarks, at most 1).
///
/// `landmarks`: per landmark in range of the pose, its elevation seen from the pose
/// (radians, above the world's horizontal) and its gate (angular radius, radians). The
/// detections of a wrong pose are modelled as having the elevation density `f` of the
/// landmarks in range (a detection of a lamp near the horizon meets the gates of the lamps
/// near the horizon) and a uniform azimuth, so landmark `i` catches one with probability
/// `f(eᵢ) · min(Ω(γᵢ) / (2π cos eᵢ), 2γᵢ)`: `Ω(γ) = 2π(1 − cos γ)` the gate's solid angle
/// over the solid angle per radian of elevation, at most the whole band of elevations the
/// gate spans. `f(eᵢ)` is the fraction of the landmarks within half a window
/// ([`ELEVATION_WINDOW_RAD`], at least `2γᵢ`) of `eᵢ`, divided by the window. For landmarks
/// uniform on the sphere this is the fraction of the sphere the gates cover; for landmarks
/// crowded near the horizon it is several times more, as it should be.
///
/// # Units
/// Radians in, a probability out (0 for no landmark).
pub fn chance_alignment_probability(landmarks: &[(f64, f64)]) -> f64 {
    let m = landmarks.len();
    if m == 0 {
        return 0.0;
    }
    let mut elevations: Vec<f64> = landmarks.iter().map(|l| l.0).collect();
    elevations.sort_by(f64::total_cmp);
    let count_within = |lo: f64, hi: f64| {
        elevations.partition_point(|&e| e <= hi) - elevations.partition_point(|&e| e < lo)
    };
    let mut p = 0.0;
    for &(e, gate) in landmarks {
        if !(e.is_finite() && gate.is_finite() && gate >= 0.0) {
            return 1.0;
        }
        let window = ELEVATION_WINDOW_RAD.max(2.0 * gate);
        let density = count_within(e - 0.5 * window, e + 0.5 * window) as f64 / (m as f64 * window);
        let cap = 2.0 * std::f64::consts::PI * (1.0 - gate.cos());
        let per_elevation = 2.0 * std::f64::consts::PI * e.cos().max(0.0);
        let band = 2.0 * gate;
        let width = if per_elevation > 0.0 {
            (cap / per_elevation).min(band)
        } else {
            band
        };
        p += density * width;
    }
    p.clamp(0.0, 1.0)
}

/// `log10 P(X ≥ k)` for `X ~ Bin(n, p)` (0 for `k = 0`, `−∞` for `k > n` or `p = 0` with
/// `k > 0`). Summed term by term in the log domain from the `k`-th, so tails far below
/// `f64::MIN_POSITIVE` stay exact.
pub fn log10_binomial_tail(n: usize, k: usize, p: f64) -> f64 {
    if k == 0 {
        return 0.0;
    }
    if k > n || p <= 0.0 || p.is_nan() {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return 0.0;
    }
    // ln C(n, k) + k ln p + (n − k) ln(1 − p), then each next term by its ratio.
    let ln_choose: f64 = (0..k)
        .map(|j| ((n - j) as f64).ln() - ((j + 1) as f64).ln())
        .sum();
    let odds = (p / (1.0 - p)).ln();
    let mut term = ln_choose + k as f64 * p.ln() + (n - k) as f64 * (-p).ln_1p();
    let (mut top, mut sum) = (term, 1.0);
    for j in k..n {
        term += ((n - j) as f64).ln() - ((j + 1) as f64).ln() + odds;
        if term > top {
            sum = sum * (top - term).exp() + 1.0;
            top = term;
        } else {
            sum += (term - top).exp();
        }
    }
    ((top + sum.ln()) / std::f64::consts::LN_10).min(0.0)
}

/// `log10 NFA = log10 N + log10 P(Bin(n − 3, p) ≥ k − 3)` for a pose with `inliers` of
/// `detections`, found among `tests` poses (at least 1), with the per-detection chance
/// alignment `p` ([`chance_alignment_probability`]).
pub fn log10_false_alarms(tests: usize, detections: usize, inliers: usize, p: f64) -> f64 {
    let free = FREE_INLIERS.min(inliers);
    (tests.max(1) as f64).log10()
        + log10_binomial_tail(
            detections.saturating_sub(free),
            inliers.saturating_sub(free),
            p,
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact tail by direct summation of the binomial terms (small n).
    fn direct_tail(n: usize, k: usize, p: f64) -> f64 {
        let mut choose = 1.0;
        let mut sum = 0.0;
        for j in 0..=n {
            if j > 0 {
                choose *= (n - j + 1) as f64 / j as f64;
            }
            if j >= k {
                sum += choose * p.powi(j as i32) * (1.0 - p).powi((n - j) as i32);
            }
        }
        sum
    }

    #[test]
    fn the_binomial_tail_matches_direct_summation_and_its_edges() {
        for n in [1usize, 5, 17, 40] {
            for k in 0..=n {
                for p in [1e-4, 0.003, 0.1, 0.5, 0.97] {
                    let exact = direct_tail(n, k, p);
                    let got = 10f64.powf(log10_binomial_tail(n, k, p));
                    assert!(
                        (got - exact).abs() <= 1e-12 + 1e-9 * exact,
                        "n {n} k {k} p {p}: {got} vs {exact}"
                    );
                }
            }
        }
        // P(Bin(20, 0.5) ≥ 10) = 0.5 + C(20,10)/2²¹ = 0.588 098 5.
        assert!((10f64.powf(log10_binomial_tail(20, 10, 0.5)) - 0.588_098_5).abs() < 1e-6);
        // Far tails stay finite in the log: C(100, 100) 1e-300 → −30 000.
        assert!((log10_binomial_tail(100, 100, 1e-300) + 30_000.0).abs() < 1e-6);
        assert_eq!(log10_binomial_tail(5, 6, 0.5), f64::NEG_INFINITY);
        assert_eq!(log10_binomial_tail(5, 1, 0.0), f64::NEG_INFINITY);
        assert_eq!(log10_binomial_tail(5, 0, 0.0), 0.0);
        assert_eq!(log10_binomial_tail(5, 3, 1.0), 0.0);
        assert_eq!(log10_binomial_tail(5, 3, f64::NAN), f64::NEG_INFINITY);
    }

    #[test]
    fn uniform_landmarks_give_the_fraction_of_the_sphere_their_gates_cover() {
        // Elevations with density cos(e)/2 (uniform on the sphere), m = 2000: p ≈ m Ω / 4π.
        let m = 2000;
        let gate = 0.25_f64.to_radians();
        let landmarks: Vec<(f64, f64)> = (0..m)
            .map(|k| (((k as f64 + 0.5) / m as f64 * 2.0 - 1.0).asin(), gate))
            .collect();
        let p = chance_alignment_probability(&landmarks);
        let expected = m as f64 * 2.0 * std::f64::consts::PI * (1.0 - gate.cos())
            / (4.0 * std::f64::consts::PI);
        assert!((p / expected - 1.0).abs() < 0.05, "{p} vs {expected}");
    }

    #[test]
    fn landmarks_crowded_near_the_horizon_raise_the_chance_of_an_alignment() {
        let gate = 0.75_f64.to_radians();
        let spread: Vec<(f64, f64)> = (0..40)
            .map(|k| ((k as f64 * 1.5).to_radians(), gate))
            .collect();
        let crowded: Vec<(f64, f64)> = (0..40)
            .map(|k| ((3.0 + k as f64 * 0.05).to_radians(), gate))
            .collect();
        let (a, b) = (
            chance_alignment_probability(&spread),
            chance_alignment_probability(&crowded),
        );
        assert!(b > 10.0 * a, "{a} {b}");
        // A gate at the zenith covers at most its band of elevations.
        let zenith = [(std::f64::consts::FRAC_PI_2, gate)];
        assert!(chance_alignment_probability(&zenith) <= 1.0);
        assert_eq!(chance_alignment_probability(&[]), 0.0);
        assert_eq!(chance_alignment_probability(&[(f64::NAN, gate)]), 1.0);
    }

    #[test]
    fn more_tests_or_fewer_inliers_mean_more_false_alarms() {
        let p = 0.01;
        let base = log10_false_alarms(1000, 20, 9, p);
        assert!((log10_false_alarms(100_000, 20, 9, p) - base - 2.0).abs() < 1e-12);
        assert!(log10_false_alarms(1000, 20, 8, p) > base);
        assert!(log10_false_alarms(1000, 20, 10, p) < base);
        // Three inliers come free with any pose: P = 1.
        assert!((log10_false_alarms(1000, 20, 3, p) - 3.0).abs() < 1e-12);
    }
}
