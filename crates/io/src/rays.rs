//! The rays file: rays from known observer positions towards landmarks to be mapped.

use super::InputError;
use super::landmarks::{latitude, longitude};
use super::table::{Table, open};
use nalgebra::Vector3;
use std::io::Read;
use std::path::Path;
use vgps_geometry::geometry::try_unit;

const COLUMNS: &[&str] = &[
    "id",
    "lat",
    "lon",
    "alt",
    "de",
    "dn",
    "du",
    "sigma_pos_m",
    "sigma_ang_deg",
];
const REQUIRED: &[&str] = &["id", "lat", "lon", "alt", "de", "dn", "du"];
const EXPECTED: &str = "id,lat,lon,alt,de,dn,du[,sigma_pos_m][,sigma_ang_deg]";

/// One row of the rays file: a ray from an observer towards the landmark `id`.
///
/// # Units
/// Degrees (WGS84) and metres for the observer; the direction is a unit vector in the local
/// East-North-Up frame **at the observer**; `sigma_pos_m` in metres, `sigma_ang_deg` in
/// degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct RayRecord {
    /// The landmark the ray points at; rows with the same id are rays to one landmark.
    pub id: String,
    /// Observer latitude, degrees.
    pub lat_deg: f64,
    /// Observer longitude, degrees.
    pub lon_deg: f64,
    /// Observer ellipsoidal height, metres.
    pub alt_m: f64,
    /// Unit direction (east, north, up) in the ENU frame at the observer.
    pub direction_in_enu: Vector3<f64>,
    /// Standard deviation of the observer position per axis, metres (`None`: not given).
    pub sigma_pos_m: Option<f64>,
    /// Standard deviation of the direction per tangent axis, degrees (`None`: not given).
    pub sigma_ang_deg: Option<f64>,
    /// The 1-based line of the row in its file.
    pub line: u64,
}

/// Reads a rays file (`id,lat,lon,alt,de,dn,du` and optional `sigma_pos_m,sigma_ang_deg`).
///
/// # Errors
/// [`InputError`] naming the file, line and field: unreadable file, bad header, wrong field
/// count, non-number or non-finite value, latitude or longitude out of range, a zero
/// direction, a negative `sigma_pos_m`, a `sigma_ang_deg` that is not positive.
pub fn read_rays(path: &Path) -> Result<Vec<RayRecord>, InputError> {
    rays_from_reader(path, open(path)?)
}

/// Reads rays from any reader; `path` is used only in error messages.
///
/// # Errors
/// As [`read_rays`].
pub fn rays_from_reader<R: Read>(path: &Path, reader: R) -> Result<Vec<RayRecord>, InputError> {
    let table = Table::read(path, reader, COLUMNS, EXPECTED)?;
    table.require(REQUIRED, EXPECTED)?;
    let mut out = Vec::new();
    for row in table.rows() {
        let row = row?;
        let id = row.required_str("id")?.to_string();
        let lat_deg = latitude(&row, "lat")?;
        let lon_deg = longitude(&row, "lon")?;
        let alt_m = row.required_f64("alt")?;
        let d = Vector3::new(
            row.required_f64("de")?,
            row.required_f64("dn")?,
            row.required_f64("du")?,
        );
        // The format asks for a finite length (|d|² must not overflow), not only a direction.
        let finite_length = d.norm().is_finite();
        let direction_in_enu = try_unit(&d).filter(|_| finite_length).ok_or_else(|| {
            row.error(
                "de",
                "zero or overflowing direction: (de, dn, du) must have a finite non-zero length",
            )
        })?;
        let sigma_pos_m = row.optional_f64("sigma_pos_m")?;
        if let Some(s) = sigma_pos_m
            && s < 0.0
        {
            return Err(row.error("sigma_pos_m", format!("{s} is negative")));
        }
        let sigma_ang_deg = row.optional_f64("sigma_ang_deg")?;
        if let Some(s) = sigma_ang_deg
            && s <= 0.0
        {
            return Err(row.error("sigma_ang_deg", format!("{s} is not positive")));
        }
        out.push(RayRecord {
            id,
            lat_deg,
            lon_deg,
            alt_m,
            direction_in_enu,
            sigma_pos_m,
            sigma_ang_deg,
            line: row.line,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<RayRecord>, InputError> {
        rays_from_reader(Path::new("R.csv"), text.as_bytes())
    }

    #[test]
    fn reads_rays_with_optional_sigmas() {
        let r = read(
            "id,lat,lon,alt,de,dn,du,sigma_pos_m,sigma_ang_deg\n\
             p,37,-122,5,0,3,0,0.5,\np,37.001,-122,5,1,0,0,,0.2\n",
        )
        .unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].direction_in_enu, Vector3::y());
        assert_eq!((r[0].sigma_pos_m, r[0].sigma_ang_deg), (Some(0.5), None));
        assert_eq!(
            (r[1].sigma_pos_m, r[1].sigma_ang_deg, r[1].line),
            (None, Some(0.2), 3)
        );
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let h = "id,lat,lon,alt,de,dn,du\n";
        let msg = |t: &str| read(&format!("{h}{t}")).unwrap_err().to_string();
        assert_eq!(
            msg("p,37,-122,5,0,0,0\n"),
            "R.csv:2: field `de`: zero or overflowing direction: (de, dn, du) must have a finite non-zero length"
        );
        assert_eq!(
            msg("p,-91,-122,5,0,0,1\n"),
            "R.csv:2: field `lat`: latitude -91 is outside [-90, 90] degrees"
        );
        assert_eq!(
            msg("p,37,-122,5,0,0,1e999\n"),
            "R.csv:2: field `du`: `1e999` is not a finite number"
        );
        let e = read("id,lat,lon,alt,de,dn,du,sigma_ang_deg\np,37,-122,5,0,0,1,0\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "R.csv:2: field `sigma_ang_deg`: 0 is not positive");
    }
}
