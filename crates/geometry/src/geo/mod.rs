//! WGS84 geodetic ↔ ECEF ↔ local East-North-Up frames.
//!
//! - [`Geodetic`]: a validated WGS84 position (latitude, longitude in degrees, ellipsoidal
//!   height in metres) with [`Geodetic::to_ecef`] and [`Geodetic::try_from_ecef`].
//! - [`LocalFrame`]: an East-North-Up (ENU) frame anchored at an origin, the world frame in
//!   which vgps does its geometry.
//! - [`rotate_covariance`]: `R Σ Rᵀ`, to move a covariance between frames.
//!
//! # Frames
//! - **ECEF** (WGS84 Earth-centred, Earth-fixed): origin at the Earth's centre of mass, +x
//!   through (0° N, 0° E), +z through the north pole, +y completing a right-handed frame
//!   (through 0° N, 90° E). Metres.
//! - **ENU at an origin**: origin at the anchor point, +x east, +y north, +z up along the
//!   ellipsoid normal (geodetic vertical). Metres.
//!
//! # Accuracy
//! The geodetic ↔ ECEF conversions come from the `sguaba` crate (Shu & Li 2010 iteration
//! within −10 km…50 km of the ellipsoid, the closed form of Quan & Zhang 2024 elsewhere).
//! Against PROJ 9.5 (`+proj=cart`, `+proj=topocentric`) the errors are below 1e-8 m for
//! heights −100 m … 9 km; round trips stay below 4e-7 m over all of
//! [[`ALT_MIN_M`], [`ALT_MAX_M`]]. See `docs/geodesy.md` and `tests/geo_reference.rs`.
//!
//! # References
//! - NGA.STND.0036, *Department of Defense World Geodetic System 1984*, v1.0.0 (2014):
//!   WGS84 constants and the geodetic → ECEF formula.
//! - C. Shu, F. Li, "An iterative algorithm to compute geodetic coordinates", Computers &
//!   Geosciences 36 (2010) 1145–1149.
//! - Quan, Zhang, "A complete closed-form method for transformation from Cartesian to
//!   geodetic coordinates", Journal of Geodesy 98 (2024).
//! - J. Farrell, M. Barth, *The Global Positioning System and Inertial Navigation* (1999),
//!   §2.3: the ECEF → ENU rotation.

mod geodetic;
mod local;

pub use geodetic::Geodetic;
pub use local::{LocalFrame, rotate_covariance};

/// WGS84 semi-major axis `a` (metres).
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 inverse flattening `1/f`.
pub const WGS84_INV_F: f64 = 298.257_223_563;
/// WGS84 semi-minor axis `b = a (1 − f)` (metres).
pub const WGS84_B_M: f64 = WGS84_A_M * (1.0 - 1.0 / WGS84_INV_F);

/// Lowest accepted ellipsoidal height (metres): below the deepest ocean floor
/// (Challenger Deep, ≈ −10.9 km) with margin for the geoid undulation.
pub const ALT_MIN_M: f64 = -12_000.0;
/// Highest accepted ellipsoidal height (metres): the Kármán line, above any aircraft or
/// balloon that could carry the camera.
pub const ALT_MAX_M: f64 = 100_000.0;

/// Errors of the geodesy module. Every failing conversion returns one of these; no function
/// here returns NaN or infinity for validated inputs.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GeoError {
    /// An input value was NaN or infinite.
    #[error("non-finite {what}")]
    NonFinite {
        /// Which input was not finite (e.g. `"latitude"`, `"ECEF point"`).
        what: &'static str,
    },
    /// The latitude was outside [−90°, 90°].
    #[error("latitude {lat_deg}° is outside [-90°, 90°]")]
    LatitudeOutOfRange {
        /// The rejected latitude (degrees).
        lat_deg: f64,
    },
    /// The ellipsoidal height was outside [`ALT_MIN_M`, `ALT_MAX_M`].
    #[error("ellipsoidal height {alt_m} m is outside [{ALT_MIN_M} m, {ALT_MAX_M} m]")]
    AltitudeOutOfRange {
        /// The rejected height (metres).
        alt_m: f64,
    },
    /// An ECEF point too close to the Earth's centre (or too far from it) to lie within the
    /// supported heights.
    #[error(
        "ECEF point at {distance_m} m from the Earth's centre is outside the supported heights \
         [{ALT_MIN_M} m, {ALT_MAX_M} m]"
    )]
    EcefOutOfRange {
        /// Distance of the rejected point from the Earth's centre (metres).
        distance_m: f64,
    },
}
