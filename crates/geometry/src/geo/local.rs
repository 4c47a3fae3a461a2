//! [`LocalFrame`]: an East-North-Up frame anchored at a geodetic origin.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::{GeoError, Geodetic};

/// The rotation `enu_from_ecef` at geodetic latitude `lat_rad` and longitude `lon_rad`.
///
/// Its rows are the east, north and up unit vectors expressed in ECEF:
/// `e = (−sin λ, cos λ, 0)`, `n = (−sin φ cos λ, −sin φ sin λ, cos φ)`,
/// `u = (cos φ cos λ, cos φ sin λ, sin φ)`.
fn enu_from_ecef_at(lat_rad: f64, lon_rad: f64) -> Rotation3<f64> {
    let (sin_lat, cos_lat) = lat_rad.sin_cos();
    let (sin_lon, cos_lon) = lon_rad.sin_cos();
    #[rustfmt::skip]
    let m = Matrix3::new(
        -sin_lon,           cos_lon,           0.0,
        -sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat,
        cos_lat * cos_lon,  cos_lat * sin_lon,  sin_lat,
    );
    // Orthonormal by construction (sin² + cos² = 1 up to rounding).
    Rotation3::from_matrix_unchecked(m)
}

/// A local East-North-Up (ENU) frame anchored at a geodetic origin.
///
/// The frame's origin is the anchor point (at its ellipsoidal height); +x points east, +y
/// north, +z up along the ellipsoid normal. `point_in_enu = enu_from_ecef · (point_in_ecef −
/// origin_in_ecef)`. The frame is exact (no flat-Earth approximation): points far from the
/// origin simply have large coordinates and "up" is only the local vertical at the origin.
///
/// # Units
/// Metres for ENU and ECEF coordinates; degrees only in [`Geodetic`].
///
/// # Example
/// ```
/// use vgps_geometry::geo::{Geodetic, LocalFrame};
/// let frame = LocalFrame::new(Geodetic::try_new(37.7749, -122.4194, 10.0)?);
/// // Coit Tower, about 1.2 km east and 3.1 km north.
/// let coit = Geodetic::try_new(37.8024, -122.4058, 64.0)?;
/// let enu = frame.to_enu(&coit);
/// // Reference values from PROJ 9.5 (`+proj=topocentric`).
/// assert!((enu.x - 1_197.731_522).abs() < 1e-6);
/// assert!((enu.y - 3_052.410_905).abs() < 1e-6);
/// assert!((enu.z - 53.155_136).abs() < 1e-6);
/// let back = frame.try_to_geodetic(&enu)?;
/// assert!((back.lat_deg - coit.lat_deg).abs() < 1e-12);
/// assert!((back.alt_m - coit.alt_m).abs() < 1e-8);
/// # Ok::<(), vgps_geometry::geo::GeoError>(())
/// ```
///
/// # References
/// J. Farrell, M. Barth, *The Global Positioning System and Inertial Navigation* (1999), §2.3;
/// PROJ's `topocentric` conversion implements the same frame.
#[derive(Clone, Debug)]
pub struct LocalFrame {
    origin: Geodetic,
    origin_in_ecef: Vector3<f64>,
    enu_from_ecef: Rotation3<f64>,
}

impl LocalFrame {
    /// The ENU frame anchored at `origin`.
    pub fn new(origin: Geodetic) -> Self {
        Self {
            origin,
            origin_in_ecef: origin.to_ecef(),
            enu_from_ecef: enu_from_ecef_at(origin.lat_rad(), origin.lon_rad()),
        }
    }

    /// The geodetic origin of the frame.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// The origin of the frame in ECEF (metres).
    pub fn origin_in_ecef(&self) -> Vector3<f64> {
        self.origin_in_ecef
    }

    /// The rotation part of the ECEF → ENU transform: `vector_in_enu = R · vector_in_ecef`.
    ///
    /// Use it for directions and (with [`rotate_covariance`]) covariances; use
    /// [`LocalFrame::ecef_to_enu`] for points.
    pub fn enu_from_ecef(&self) -> Rotation3<f64> {
        self.enu_from_ecef
    }

    /// The ENU coordinates (metres) of an ECEF point (metres).
    ///
    /// Finite input gives finite output; a NaN or infinite coordinate propagates.
    pub fn ecef_to_enu(&self, ecef: &Vector3<f64>) -> Vector3<f64> {
        self.enu_from_ecef * (ecef - self.origin_in_ecef)
    }

    /// The ECEF coordinates (metres) of a point given in this ENU frame (metres).
    ///
    /// Finite input gives finite output; a NaN or infinite coordinate propagates.
    pub fn enu_to_ecef(&self, enu: &Vector3<f64>) -> Vector3<f64> {
        self.origin_in_ecef + self.enu_from_ecef.inverse() * enu
    }

    /// The ENU coordinates (metres) of a geodetic point.
    pub fn to_enu(&self, g: &Geodetic) -> Vector3<f64> {
        self.ecef_to_enu(&g.to_ecef())
    }

    /// The geodetic position of a point given in this ENU frame (metres).
    ///
    /// # Errors
    /// [`GeoError::NonFinite`] for a non-finite input, otherwise the errors of
    /// [`Geodetic::try_from_ecef`] (a point deep inside the Earth or beyond the supported
    /// heights).
    pub fn try_to_geodetic(&self, enu: &Vector3<f64>) -> Result<Geodetic, GeoError> {
        if !(enu.x.is_finite() && enu.y.is_finite() && enu.z.is_finite()) {
            return Err(GeoError::NonFinite { what: "ENU point" });
        }
        Geodetic::try_from_ecef(&self.enu_to_ecef(enu))
    }

    /// The rotation `enu_here_from_enu_at_other`: it takes a vector expressed in the ENU frame
    /// at `other` into the ENU frame of this origin (`R_here · R_otherᵀ`, both `enu_from_ecef`).
    ///
    /// Use it for directions or covariances given "in the local ENU frame at the observer":
    /// `frame.enu_here_from_enu_at(&observer) * dir_at_observer` is that direction in this
    /// frame, and [`rotate_covariance`] moves a covariance. Its inverse
    /// (`.inverse()`, the transpose) goes the other way. Only `other`'s latitude and
    /// longitude matter (the ENU axes do not depend on height).
    ///
    /// # Example
    /// ```
    /// use nalgebra::Vector3;
    /// use vgps_geometry::geo::{Geodetic, LocalFrame};
    /// let here = LocalFrame::new(Geodetic::try_new(0.0, 0.0, 0.0)?);
    /// let other = Geodetic::try_new(0.0, 90.0, 0.0)?;
    /// // "Up" at (0°, 90° E) is "east" at (0°, 0°).
    /// let up_there_seen_here = here.enu_here_from_enu_at(&other) * Vector3::z();
    /// assert!((up_there_seen_here - Vector3::x()).norm() < 1e-15);
    /// # Ok::<(), vgps_geometry::geo::GeoError>(())
    /// ```
    pub fn enu_here_from_enu_at(&self, other: &Geodetic) -> Rotation3<f64> {
        let enu_other_from_ecef = enu_from_ecef_at(other.lat_rad(), other.lon_rad());
        self.enu_from_ecef * enu_other_from_ecef.inverse()
    }
}

/// The covariance `R Σ Rᵀ` of `R x` when `x` has covariance `Σ` (symmetrised, so a symmetric
/// input gives an exactly symmetric output).
///
/// # Units
/// Those of `cov` (e.g. m² for a position covariance); `r` is dimensionless.
///
/// # Example
/// ```
/// use nalgebra::{Matrix3, Rotation3, Vector3};
/// use vgps_geometry::geo::rotate_covariance;
/// // 1 m² east, 4 m² north; rotate the axes by 90° about up: east ↔ north.
/// let cov = Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 9.0));
/// let r = Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
/// let rotated = rotate_covariance(&r, &cov);
/// assert!((rotated - Matrix3::from_diagonal(&Vector3::new(4.0, 1.0, 9.0))).norm() < 1e-12);
/// ```
pub fn rotate_covariance(r: &Rotation3<f64>, cov: &Matrix3<f64>) -> Matrix3<f64> {
    let rotated = r.matrix() * cov * r.matrix().transpose();
    (rotated + rotated.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enu_axes_at_the_origin_of_longitude() {
        let r = enu_from_ecef_at(0.0, 0.0);
        // At (0°, 0°): east = +y_ecef, north = +z_ecef, up = +x_ecef.
        assert!((r * Vector3::y() - Vector3::x()).norm() < 1e-15);
        assert!((r * Vector3::z() - Vector3::y()).norm() < 1e-15);
        assert!((r * Vector3::x() - Vector3::z()).norm() < 1e-15);
    }

    #[test]
    fn rotation_is_orthonormal_everywhere() {
        for lat in [-90.0_f64, -45.0, 0.0, 12.3, 89.9, 90.0] {
            for lon in [-180.0_f64, -90.0, 0.0, 33.0, 179.9] {
                let r = enu_from_ecef_at(lat.to_radians(), lon.to_radians());
                let m = r.matrix();
                assert!((m * m.transpose() - Matrix3::identity()).norm() < 1e-15);
                assert!((m.determinant() - 1.0).abs() < 1e-15);
            }
        }
    }
}
