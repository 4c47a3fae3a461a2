//! The bearing measurement model shared by the fix, the matcher and the localizer.
//!
//! A detection's bearing has the angular standard deviation `σ` (radians). A landmark's
//! surveyed position has the isotropic standard deviation `σ_m` (metres); seen from `ρ`
//! metres, its error across the line of sight turns the bearing by about `σ_m / ρ`. The
//! two are independent, so the bearing to the surveyed position has the effective standard
//! deviation `√(σ² + (σ_m / ρ)²)`.
//!
//! Each caller decides how near a landmark may be before the survey term is capped: the
//! fix keeps `σ` alone at `ρ ≤ 0`, the matcher's refinement takes `ρ ≥ 1 mm` and the
//! localizer `ρ ≥ 1 m`; those limits stay with the callers.

/// Default standard deviation of a detected bearing, radians (0.1°): the default of
/// [`crate::fix::FixOptions`] and [`crate::matcher::MatchOptions`], and of the geometry
/// crate's estimators (defined there, once).
pub use vgps_geometry::DEFAULT_BEARING_SIGMA_RAD;

/// The effective variance of a bearing, rad²: `σ² + (σ_m / ρ)²` for the bearing noise
/// `sigma_rad`, the landmark's survey σ `sigma_m` (metres) and its range `range` (metres).
#[inline]
pub fn effective_bearing_variance(sigma_rad: f64, sigma_m: f64, range: f64) -> f64 {
    sigma_rad * sigma_rad + (sigma_m / range).powi(2)
}

/// The effective standard deviation of a bearing, radians: the square root of
/// [`effective_bearing_variance`].
#[inline]
pub fn effective_bearing_sigma(sigma_rad: f64, sigma_m: f64, range: f64) -> f64 {
    effective_bearing_variance(sigma_rad, sigma_m, range).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_a_tenth_of_a_degree_bit_for_bit() {
        assert_eq!(
            DEFAULT_BEARING_SIGMA_RAD.to_bits(),
            0.1_f64.to_radians().to_bits()
        );
    }

    #[test]
    fn the_survey_term_adds_in_quadrature() {
        assert_eq!(effective_bearing_sigma(3e-3, 0.0, 10.0), 3e-3);
        let s = effective_bearing_sigma(3e-3, 0.04, 10.0);
        assert!((s - 5e-3).abs() < 1e-15, "{s}");
        // The forms the callers wrote before, bit for bit.
        let (sigma, sigma_m, range) = (1.7e-3, 0.03, 7.3);
        let r = sigma_m / range;
        assert_eq!(
            effective_bearing_sigma(sigma, sigma_m, range).to_bits(),
            (sigma * sigma + r * r).sqrt().to_bits()
        );
        assert_eq!(
            effective_bearing_variance(sigma, sigma_m, range).to_bits(),
            (sigma.powi(2) + (sigma_m / range).powi(2)).to_bits()
        );
    }
}
