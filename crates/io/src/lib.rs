//! Readers for the CSV inputs, with errors that name the file, the line and the field.
//!
//! Three files feed the command line (`docs/cli.md` has the full description):
//! - **landmarks** ([`read_landmarks`]): `id,lat,lon,alt` and optional `sigma_m`, `class`;
//! - **observations** ([`read_observations`]): optional `frame`, then either `bx,by,bz` (a
//!   bearing in the rig frame) or `camera,u,v` (pixels), and an optional `landmark` id;
//! - **rays** ([`read_rays`]): `id,lat,lon,alt,de,dn,du` and optional
//!   `sigma_pos_m,sigma_ang_deg`.
//!
//! # Format rules (all three files)
//! - The first line that is not a comment is the header; columns may come in any order.
//! - Column names are exact and lower case. An **unknown column is an error** (strict: a
//!   misspelt optional column such as `sigma` instead of `sigma_m` would otherwise be silently
//!   ignored), so is a duplicated column and a missing required column.
//! - Lines starting with `#` are comments; blank lines are skipped; spaces around values are
//!   trimmed.
//! - Every row has exactly as many fields as the header. Numbers must be finite; an empty
//!   value is allowed only in an optional column and means "not given".
//!
//! Every error is an [`InputError`] naming the file, the 1-based line and the field.
//!
//! # Units
//! Latitude and longitude in degrees (WGS84), heights in metres above the ellipsoid,
//! `sigma_m` and `sigma_pos_m` in metres, `sigma_ang_deg` in degrees, pixels for `u,v`.
//! Bearings and directions may have any non-zero length: the readers normalise them.
//!
//! # Example
//! ```
//! use std::path::Path;
//! let text = "id,lat,lon,alt,sigma_m\nlamp1,37.77,-122.42,12.5,0.05\n";
//! let landmarks = vgps_io::landmarks_from_reader(Path::new("L.csv"), text.as_bytes()).unwrap();
//! assert_eq!(landmarks[0].id, "lamp1");
//! assert_eq!(landmarks[0].sigma_m, Some(0.05));
//!
//! let bad = "id,lat,lon,alt\nlamp1,97.0,-122.42,12.5\n";
//! let err = vgps_io::landmarks_from_reader(Path::new("L.csv"), bad.as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), "L.csv:2: field `lat`: latitude 97 is outside [-90, 90] degrees");
//! ```

mod atomic;
pub mod footprints;
pub mod gis;
mod landmarks;
mod observations;
mod rays;
pub mod table;

pub use atomic::write_atomic;
pub use landmarks::{Landmark, landmarks_from_reader, read_landmarks};
pub use observations::{
    MeasurementRecord, ObservationRecord, observations_from_reader, read_observations,
};
pub use rays::{RayRecord, rays_from_reader, read_rays};

use std::path::PathBuf;

/// An error in an input file: which file, which line, which field, and why.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{}: cannot read the file: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A value, a row or the header is invalid.
    #[error("{}:{line}: field `{field}`: {reason}", path.display())]
    Field {
        /// The file.
        path: PathBuf,
        /// The 1-based line number in the file.
        line: u64,
        /// The column name (or a description of the position for fields outside the header).
        field: String,
        /// What is wrong.
        reason: String,
    },
}

impl InputError {
    /// An error about one field of one line.
    pub fn field(
        path: impl Into<PathBuf>,
        line: u64,
        field: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Self::Field {
            path: path.into(),
            line,
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// The largest accepted |latitude| (degrees).
pub const MAX_ABS_LAT_DEG: f64 = 90.0;
/// The largest accepted |longitude| (degrees).
pub const MAX_ABS_LON_DEG: f64 = 180.0;

/// The input column (`lat`, `lon` or `alt`) a [`vgps_geometry::geo::GeoError`] of
/// [`vgps_geometry::geo::Geodetic::try_new`] is about, for error messages that name the field.
pub fn geodetic_column(e: &vgps_geometry::geo::GeoError) -> &'static str {
    use vgps_geometry::geo::GeoError;
    match e {
        GeoError::AltitudeOutOfRange { .. } | GeoError::NonFinite { what: "altitude" } => "alt",
        GeoError::NonFinite { what: "longitude" } => "lon",
        _ => "lat",
    }
}
