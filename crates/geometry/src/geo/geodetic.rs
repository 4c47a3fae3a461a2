//! [`Geodetic`]: a validated WGS84 position and its conversions to and from ECEF.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use sguaba::{Coordinate, systems::Ecef};
use uom::si::{angle::radian, f64::Length, length::meter};

use super::{ALT_MAX_M, ALT_MIN_M, GeoError, WGS84_A_M, WGS84_B_M, WGS84_INV_F};

/// WGS84 first eccentricity squared, `e² = f (2 − f)`.
const WGS84_E2: f64 = (2.0 - 1.0 / WGS84_INV_F) / WGS84_INV_F;

/// Margin (metres) added on both sides of the ECEF shell below, so that rounding of a point
/// built exactly at a height limit never pushes it out of the shell; the height check after
/// the conversion is the exact one.
const SHELL_MARGIN_M: f64 = 1.0;
/// Smallest distance from the Earth's centre (metres) of a point whose ellipsoidal height can
/// be [`ALT_MIN_M`] (the ellipsoid is never closer to the centre than `b`), less a margin.
const MIN_ECEF_RADIUS_M: f64 = WGS84_B_M + ALT_MIN_M - SHELL_MARGIN_M;
/// Largest distance from the Earth's centre (metres) of a point whose ellipsoidal height can
/// be [`ALT_MAX_M`] (the ellipsoid is never farther from the centre than `a`), plus a margin.
const MAX_ECEF_RADIUS_M: f64 = WGS84_A_M + ALT_MAX_M + SHELL_MARGIN_M;

/// How far (metres) beyond [`ALT_MIN_M`] or [`ALT_MAX_M`] a height computed from ECEF may
/// fall and still be clamped onto the limit: above the conversion error (≤ 4e-7 m), far
/// below anything physical.
const HEIGHT_LIMIT_SLACK_M: f64 = 1e-5;

/// A WGS84 position: geodetic latitude and longitude in degrees, ellipsoidal height in metres.
///
/// Construct it with [`Geodetic::try_new`] (or deserialize it, which runs the same checks),
/// so that every value is finite, `|lat_deg| ≤ 90`, `lon_deg ∈ (−180, 180]` and
/// `alt_m ∈ [ALT_MIN_M, ALT_MAX_M]`. The fields are public for reading; a value built by hand
/// with a struct literal bypasses the checks and is the caller's responsibility.
///
/// # Units
/// Degrees for latitude and longitude (the only place where the library uses degrees),
/// metres above the WGS84 ellipsoid (not above the geoid / mean sea level) for `alt_m`.
///
/// # Example
/// ```
/// use vgps_geometry::geo::Geodetic;
/// // San Francisco City Hall area, 10 m above the ellipsoid.
/// let sf = Geodetic::try_new(37.7749, -122.4194, 10.0)?;
/// let ecef = sf.to_ecef();
/// // Reference values from PROJ 9.5 (`+proj=cart +ellps=WGS84`).
/// assert!((ecef.x - -2_706_179.084_171).abs() < 1e-6);
/// assert!((ecef.y - -4_261_066.161_628).abs() < 1e-6);
/// assert!((ecef.z - 3_885_731.615_632).abs() < 1e-6);
/// let back = Geodetic::try_from_ecef(&ecef)?;
/// assert!((back.lat_deg - 37.7749).abs() < 1e-12);
/// assert!((back.alt_m - 10.0).abs() < 1e-8);
/// # Ok::<(), vgps_geometry::geo::GeoError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawGeodetic")]
pub struct Geodetic {
    /// Geodetic latitude (degrees, −90 … 90, positive north).
    pub lat_deg: f64,
    /// Longitude (degrees, (−180, 180], positive east of Greenwich).
    pub lon_deg: f64,
    /// Height above the WGS84 ellipsoid (metres).
    pub alt_m: f64,
}

/// The unchecked serde form of [`Geodetic`]; deserialization goes through
/// [`Geodetic::try_new`].
#[derive(Deserialize)]
struct RawGeodetic {
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
}

impl TryFrom<RawGeodetic> for Geodetic {
    type Error = GeoError;

    fn try_from(raw: RawGeodetic) -> Result<Self, GeoError> {
        Geodetic::try_new(raw.lat_deg, raw.lon_deg, raw.alt_m)
    }
}

/// `lon_deg` wrapped into (−180°, 180°].
fn normalize_lon_deg(lon_deg: f64) -> f64 {
    let wrapped = lon_deg.rem_euclid(360.0); // [0, 360], 360 only by rounding
    if wrapped > 180.0 {
        wrapped - 360.0
    } else {
        wrapped
    }
}

impl Geodetic {
    /// A validated geodetic position.
    ///
    /// The longitude is wrapped into (−180°, 180°] (any finite value is accepted).
    ///
    /// # Errors
    /// - [`GeoError::NonFinite`] if any value is NaN or infinite;
    /// - [`GeoError::LatitudeOutOfRange`] if `|lat_deg| > 90`;
    /// - [`GeoError::AltitudeOutOfRange`] if `alt_m` is outside
    ///   [[`ALT_MIN_M`], [`ALT_MAX_M`]].
    ///
    /// # Units
    /// Degrees, degrees, metres above the WGS84 ellipsoid.
    ///
    /// # Example
    /// ```
    /// use vgps_geometry::geo::{GeoError, Geodetic};
    /// let g = Geodetic::try_new(-33.8568, 540.0 - 208.7847, 5.0)?; // 331.2153° E
    /// assert!((g.lon_deg - -28.7847).abs() < 1e-12);
    /// assert!(matches!(
    ///     Geodetic::try_new(91.0, 0.0, 0.0),
    ///     Err(GeoError::LatitudeOutOfRange { .. })
    /// ));
    /// assert!(Geodetic::try_new(f64::NAN, 0.0, 0.0).is_err());
    /// # Ok::<(), GeoError>(())
    /// ```
    pub fn try_new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Result<Self, GeoError> {
        if !lat_deg.is_finite() {
            return Err(GeoError::NonFinite { what: "latitude" });
        }
        if !lon_deg.is_finite() {
            return Err(GeoError::NonFinite { what: "longitude" });
        }
        if !alt_m.is_finite() {
            return Err(GeoError::NonFinite { what: "altitude" });
        }
        if lat_deg.abs() > 90.0 {
            return Err(GeoError::LatitudeOutOfRange { lat_deg });
        }
        if !(ALT_MIN_M..=ALT_MAX_M).contains(&alt_m) {
            return Err(GeoError::AltitudeOutOfRange { alt_m });
        }
        Ok(Self {
            lat_deg,
            lon_deg: normalize_lon_deg(lon_deg),
            alt_m,
        })
    }

    /// Latitude in radians.
    #[inline]
    pub fn lat_rad(&self) -> f64 {
        self.lat_deg.to_radians()
    }

    /// Longitude in radians.
    #[inline]
    pub fn lon_rad(&self) -> f64 {
        self.lon_deg.to_radians()
    }

    /// The WGS84 ECEF position of this point (metres).
    ///
    /// The closed-form definition of geodetic coordinates:
    /// `N = a / √(1 − e² sin²φ)`, `x = (N + h) cos φ cos λ`, `y = (N + h) cos φ sin λ`,
    /// `z = (N (1 − e²) + h) sin φ`. It is exact up to floating-point rounding (≈ 1 nm).
    ///
    /// # Units
    /// Metres, ECEF frame.
    ///
    /// # Example
    /// ```
    /// use vgps_geometry::geo::Geodetic;
    /// let p = Geodetic::try_new(0.0, 90.0, 0.0)?;
    /// let ecef = p.to_ecef();
    /// assert!(ecef.x.abs() < 1e-6 && (ecef.y - 6_378_137.0).abs() < 1e-6 && ecef.z == 0.0);
    /// # Ok::<(), vgps_geometry::geo::GeoError>(())
    /// ```
    ///
    /// # References
    /// NGA.STND.0036 (WGS84, 2014), eq. 4-14.
    pub fn to_ecef(&self) -> Vector3<f64> {
        let (sin_lat, cos_lat) = self.lat_rad().sin_cos();
        let (sin_lon, cos_lon) = self.lon_rad().sin_cos();
        let prime_vertical = WGS84_A_M / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
        let horizontal = (prime_vertical + self.alt_m) * cos_lat;
        Vector3::new(
            horizontal * cos_lon,
            horizontal * sin_lon,
            (prime_vertical * (1.0 - WGS84_E2) + self.alt_m) * sin_lat,
        )
    }

    /// The geodetic position of an ECEF point.
    ///
    /// Latitude and height come from the `sguaba` crate (`Coordinate<Ecef>::to_wgs84`: the
    /// iteration of Shu & Li (2010) for heights within −10 km … 50 km, the closed form of
    /// Quan & Zhang (2024) elsewhere); the longitude is `atan2(y, x)` (0 on the polar axis).
    /// Measured accuracy (position error of the result): ≤ 1e-8 m for heights −10 km … 50 km,
    /// ≤ 4e-7 m over the rest of [[`ALT_MIN_M`], [`ALT_MAX_M`]] (see `docs/geodesy.md`).
    ///
    /// # Errors
    /// - [`GeoError::NonFinite`] if a coordinate is NaN or infinite;
    /// - [`GeoError::EcefOutOfRange`] if the point is so close to the Earth's centre (or so
    ///   far from it) that no height in [[`ALT_MIN_M`], [`ALT_MAX_M`]] can reach it — this
    ///   includes the Earth's centre itself, where latitude is undefined;
    /// - [`GeoError::AltitudeOutOfRange`] if the computed height is outside that range by
    ///   more than 10 µm (a height within 10 µm outside is clamped onto the limit, so that
    ///   points built at a limit convert back).
    ///
    /// # Units
    /// Input metres (ECEF); output degrees, degrees, metres.
    ///
    /// # Example
    /// ```
    /// use nalgebra::Vector3;
    /// use vgps_geometry::geo::Geodetic;
    /// // The north pole, 100 m above the ellipsoid (b = 6 356 752.314 245 m).
    /// let g = Geodetic::try_from_ecef(&Vector3::new(0.0, 0.0, 6_356_852.314_245))?;
    /// assert_eq!(g.lat_deg, 90.0);
    /// assert!((g.alt_m - 100.0).abs() < 1e-5);
    /// assert!(Geodetic::try_from_ecef(&Vector3::zeros()).is_err());
    /// # Ok::<(), vgps_geometry::geo::GeoError>(())
    /// ```
    ///
    /// # References
    /// - C. Shu, F. Li, "An iterative algorithm to compute geodetic coordinates", Computers &
    ///   Geosciences 36 (2010) 1145–1149.
    /// - Quan, Zhang, "A complete closed-form method for transformation from Cartesian to
    ///   geodetic coordinates", Journal of Geodesy 98 (2024).
    pub fn try_from_ecef(ecef: &Vector3<f64>) -> Result<Self, GeoError> {
        if !(ecef.x.is_finite() && ecef.y.is_finite() && ecef.z.is_finite()) {
            return Err(GeoError::NonFinite { what: "ECEF point" });
        }
        let distance_m = ecef.norm();
        // Outside this shell no supported height is possible; inside it sguaba's conversion
        // is defined (it supports −6.3e6 m … 1e10 m) and never divides by zero.
        if !(MIN_ECEF_RADIUS_M..=MAX_ECEF_RADIUS_M).contains(&distance_m) {
            return Err(GeoError::EcefOutOfRange { distance_m });
        }
        #[allow(deprecated)] // `builder()` is the typestate form of the same constructor
        let coordinate = Coordinate::<Ecef>::from_cartesian(
            Length::new::<meter>(ecef.x),
            Length::new::<meter>(ecef.y),
            Length::new::<meter>(ecef.z),
        );
        let wgs84 = coordinate.to_wgs84();
        let lat_rad = wgs84.latitude().get::<radian>();
        let alt_m = wgs84.altitude().get::<meter>();
        if !(lat_rad.is_finite() && alt_m.is_finite()) {
            return Err(GeoError::NonFinite {
                what: "geodetic result",
            });
        }
        // A point built from a height exactly at a limit must convert back: heights outside
        // the range by no more than the conversion error are clamped onto it.
        let alt_m = if (ALT_MIN_M - HEIGHT_LIMIT_SLACK_M..ALT_MIN_M).contains(&alt_m) {
            ALT_MIN_M
        } else if (ALT_MAX_M..=ALT_MAX_M + HEIGHT_LIMIT_SLACK_M).contains(&alt_m) {
            ALT_MAX_M
        } else {
            alt_m
        };
        let lat_deg = lat_rad.to_degrees().clamp(-90.0, 90.0);
        let lon_deg = ecef.y.atan2(ecef.x).to_degrees();
        Self::try_new(lat_deg, lon_deg, alt_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn longitude_wraps_into_half_open_interval() {
        assert_eq!(normalize_lon_deg(180.0), 180.0);
        assert_eq!(normalize_lon_deg(-180.0), 180.0);
        assert_eq!(normalize_lon_deg(-179.9), -179.9);
        assert_eq!(normalize_lon_deg(540.0), 180.0);
        assert_eq!(normalize_lon_deg(-1e-20), 0.0);
        assert!((normalize_lon_deg(359.0) - -1.0).abs() < 1e-12);
    }

    #[test]
    fn shell_bounds_are_consistent_with_the_ellipsoid() {
        // The extreme corners of the supported heights lie inside the shell and convert back.
        let corners = [-90.0, 0.0, 90.0].into_iter().flat_map(|lat| {
            [-179.9, 0.0, 33.3, 180.0]
                .into_iter()
                .flat_map(move |lon| [ALT_MIN_M, ALT_MAX_M].map(|alt| (lat, lon, alt)))
        });
        for (lat, lon, alt) in corners {
            let g = Geodetic::try_new(lat, lon, alt).unwrap();
            let r = g.to_ecef().norm();
            assert!(
                (MIN_ECEF_RADIUS_M..=MAX_ECEF_RADIUS_M).contains(&r),
                "{g:?}"
            );
            let back = Geodetic::try_from_ecef(&g.to_ecef()).unwrap();
            assert!((back.alt_m - alt).abs() < 1e-6 && (back.lat_deg - lat).abs() < 1e-12);
        }
        assert!((WGS84_E2 - 6.694_379_990_141_3e-3).abs() < 1e-15);
    }
}
