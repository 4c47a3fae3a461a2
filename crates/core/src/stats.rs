//! Small statistics used by the consistency tests and summaries of mapping: the χ²
//! quantile (Wilson–Hilferty), the Pearson correlation and the median of finite values.

/// The χ²(dof) quantile at the standard-normal quantile `z` (Wilson–Hilferty:
/// `dof·(1 − 2/(9 dof) + z √(2/(9 dof)))³`, within 2 % (above) for dof ≥ 3). `dof` 0 is
/// taken as 1.
pub fn chi2_quantile(dof: usize, z: f64) -> f64 {
    let k = dof.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Pearson correlation of the pairs (`None` for fewer than 3 or a constant coordinate).
pub fn pearson(pairs: &[(f64, f64)]) -> Option<f64> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (mx, my) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
    }
    let r = sxy / (sxx * syy).sqrt();
    r.is_finite().then_some(r)
}

/// The upper median of the finite values (the element at index `n / 2` once sorted;
/// `None` when there is none).
pub fn median(mut values: Vec<f64>) -> Option<f64> {
    values.retain(|x| x.is_finite());
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Standard-normal quantile at 99.9 %.
    const Z_999: f64 = 3.090_232_306_167_813;

    #[test]
    fn chi2_quantile_matches_tables() {
        // χ² 99.9 % quantiles: dof 3 → 16.27, 10 → 29.59, 100 → 149.45.
        for (dof, q) in [(3, 16.266), (10, 29.588), (100, 149.449)] {
            let r = chi2_quantile(dof, Z_999) / q;
            assert!((r - 1.0).abs() < 0.02, "dof {dof}: {r}");
        }
    }

    #[test]
    fn pearson_of_a_line_and_of_noise() {
        let line: Vec<(f64, f64)> = (0..10).map(|k| (k as f64, 3.0 * k as f64 + 1.0)).collect();
        assert!((pearson(&line).unwrap_or(0.0) - 1.0).abs() < 1e-12);
        assert_eq!(pearson(&[(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)]), None);
    }

    #[test]
    fn median_ignores_non_finite_values() {
        assert_eq!(median(vec![3.0, f64::NAN, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(median(vec![f64::INFINITY]), None);
    }
}
