//! The sun's direction for a time and place: the low-precision solar coordinates of the
//! Astronomical Almanac (accurate to ≈ 0.01° in 1950–2050), enough to shade facades.
//!
//! # References
//! - The Astronomical Almanac, section C ("Low precision formulas for the Sun"); the same
//!   formulas are in Michalsky, *The Astronomical Almanac's algorithm for approximate solar
//!   position (1950–2050)*, Solar Energy 40 (1988) 227–235.
//! - Checked against Reda & Andreas, *Solar position algorithm for solar radiation
//!   applications*, NREL/TP-560-34302 (2008), the worked example of its appendix A.5.

use nalgebra::Vector3;

/// Unix time (s) of the J2000.0 epoch (2000-01-01 12:00 TT, taken as UTC here: the 64 s
/// between them move the sun by < 0.001°).
const J2000_UNIX_S: f64 = 946_728_000.0;
/// Seconds per day.
const DAY_S: f64 = 86_400.0;

/// The sun seen from a place at a time.
///
/// # Units
/// Degrees; azimuth clockwise from north (east = 90°); elevation above the horizon without
/// atmospheric refraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPosition {
    /// Azimuth (degrees, 0 = north, 90 = east).
    pub azimuth_deg: f64,
    /// Elevation above the geometric horizon (degrees, negative at night).
    pub elevation_deg: f64,
}

impl SunPosition {
    /// The unit direction towards the sun in the local ENU frame (x east, y north, z up).
    pub fn direction_in_enu(&self) -> Vector3<f64> {
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        Vector3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
    }
}

/// The sun's azimuth and elevation at `unix_s` (UTC seconds) seen from latitude `lat_deg`,
/// longitude `lon_deg` (degrees, east positive).
///
/// # Example
/// ```
/// use vgps_sim::day::sun::sun_position;
/// // Golden, Colorado, 2003-10-17 19:30:30 UTC (Reda & Andreas 2008, appendix A.5):
/// // zenith 50.11°, azimuth 194.34°.
/// let sun = sun_position(1_066_419_030.0, 39.742476, -105.1786);
/// assert!((90.0 - sun.elevation_deg - 50.11).abs() < 0.05);
/// assert!((sun.azimuth_deg - 194.34).abs() < 0.05);
/// ```
pub fn sun_position(unix_s: f64, lat_deg: f64, lon_deg: f64) -> SunPosition {
    let n = (unix_s - J2000_UNIX_S) / DAY_S;
    let mean_longitude = (280.460 + 0.985_647_4 * n).rem_euclid(360.0);
    let g = (357.528 + 0.985_600_3 * n).rem_euclid(360.0).to_radians();
    let ecliptic_longitude =
        (mean_longitude + 1.915 * g.sin() + 0.020 * (2.0 * g).sin()).to_radians();
    let obliquity = (23.439 - 0.000_000_4 * n).to_radians();
    let right_ascension =
        (obliquity.cos() * ecliptic_longitude.sin()).atan2(ecliptic_longitude.cos());
    let declination = (obliquity.sin() * ecliptic_longitude.sin()).asin();
    let gmst_h = (18.697_374_558 + 24.065_709_824_419_08 * n).rem_euclid(24.0);
    let hour_angle = (gmst_h * 15.0 + lon_deg).to_radians() - right_ascension;
    let lat = lat_deg.to_radians();
    let elevation = (lat.sin() * declination.sin()
        + lat.cos() * declination.cos() * hour_angle.cos())
    .clamp(-1.0, 1.0)
    .asin();
    let azimuth =
        (-hour_angle.sin()).atan2(declination.tan() * lat.cos() - lat.sin() * hour_angle.cos());
    SunPosition {
        azimuth_deg: azimuth.to_degrees().rem_euclid(360.0),
        elevation_deg: elevation.to_degrees(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_nrel_spa_example() {
        // Reda & Andreas (2008), A.5: 2003-10-17 12:30:30 local (UTC−7), 39.742476 N,
        // 105.1786 W: topocentric zenith 50.11162° (with ≈ 0.02° of refraction), azimuth
        // 194.34024°.
        let sun = sun_position(1_066_419_030.0, 39.742476, -105.1786);
        let zenith = 90.0 - sun.elevation_deg;
        assert!((zenith - 50.11162).abs() < 0.05, "zenith {zenith}");
        assert!(
            (sun.azimuth_deg - 194.34024).abs() < 0.05,
            "azimuth {}",
            sun.azimuth_deg
        );
        let d = sun.direction_in_enu();
        assert!((d.norm() - 1.0).abs() < 1e-12);
        assert!(
            d.x < 0.0 && d.y < 0.0 && d.z > 0.0,
            "south-south-west and up: {d:?}"
        );
    }

    #[test]
    fn noon_and_midnight_at_the_equinox() {
        // 2024-03-20 12:00 UTC on the Greenwich meridian at the equator: the sun is near the
        // zenith (equation of time ≈ −7.5 min, declination ≈ 0); twelve hours later it is
        // near the nadir.
        let noon = sun_position(1_710_936_000.0, 0.0, 0.0);
        assert!(noon.elevation_deg > 87.0, "{noon:?}");
        let midnight = sun_position(1_710_936_000.0 + 43_200.0, 0.0, 0.0);
        assert!(midnight.elevation_deg < -85.0, "{midnight:?}");
    }
}
