//! The landmarks file: surveyed WGS84 coordinates of the landmarks.

use super::table::{Row, Table, open};
use super::{InputError, MAX_ABS_LAT_DEG, MAX_ABS_LON_DEG};
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

const COLUMNS: &[&str] = &["id", "lat", "lon", "alt", "sigma_m", "class", "n_obs"];
const REQUIRED: &[&str] = &["id", "lat", "lon", "alt"];
const EXPECTED: &str = "id,lat,lon,alt[,sigma_m][,class][,n_obs]";

/// One surveyed landmark.
///
/// # Units
/// Degrees (WGS84) for `lat_deg`, `lon_deg`; metres above the ellipsoid for `alt_m`; metres
/// for `sigma_m`.
#[derive(Clone, Debug, PartialEq)]
pub struct Landmark {
    /// Unique identifier (non-empty text).
    pub id: String,
    /// Latitude, degrees, in [-90, 90].
    pub lat_deg: f64,
    /// Longitude, degrees, in [-180, 180].
    pub lon_deg: f64,
    /// Ellipsoidal height, metres.
    pub alt_m: f64,
    /// Survey standard deviation of the position per axis, metres (`None`: not given,
    /// treated as exact).
    pub sigma_m: Option<f64>,
    /// Free-text class (e.g. `streetlight`), informational.
    pub class: Option<String>,
    /// The 1-based line of the row in its file.
    pub line: u64,
}

/// Reads a landmarks file (`id,lat,lon,alt` and optional `sigma_m`, `class`, `n_obs`).
///
/// `n_obs` (the number of observations of a mapped landmark, written by `vgps map`) is
/// informational: it is checked (a non-negative integer) and not kept.
///
/// # Errors
/// [`InputError`] naming the file, line and field: unreadable file, bad header (unknown,
/// duplicated or missing column), wrong field count, non-number or non-finite value,
/// latitude or longitude out of range, negative `sigma_m`, empty or duplicate `id`.
pub fn read_landmarks(path: &Path) -> Result<Vec<Landmark>, InputError> {
    landmarks_from_reader(path, open(path)?)
}

/// Reads landmarks from any reader; `path` is used only in error messages.
///
/// # Errors
/// As [`read_landmarks`].
pub fn landmarks_from_reader<R: Read>(path: &Path, reader: R) -> Result<Vec<Landmark>, InputError> {
    let table = Table::read(path, reader, COLUMNS, EXPECTED)?;
    table.require(REQUIRED, EXPECTED)?;
    let mut landmarks: Vec<Landmark> = Vec::new();
    let mut first_line: HashMap<String, u64> = HashMap::new();
    for row in table.rows() {
        let row = row?;
        let landmark = parse_row(&row)?;
        if let Some(first) = first_line.get(&landmark.id) {
            return Err(row.error(
                "id",
                format!(
                    "duplicate landmark id `{}` (first on line {first})",
                    landmark.id
                ),
            ));
        }
        first_line.insert(landmark.id.clone(), landmark.line);
        landmarks.push(landmark);
    }
    Ok(landmarks)
}

fn parse_row(row: &Row<'_>) -> Result<Landmark, InputError> {
    let id = row.required_str("id")?.to_string();
    let lat_deg = latitude(row, "lat")?;
    let lon_deg = longitude(row, "lon")?;
    let alt_m = row.required_f64("alt")?;
    let sigma_m = row.optional_f64("sigma_m")?;
    if let Some(s) = sigma_m
        && s < 0.0
    {
        return Err(row.error("sigma_m", format!("{s} is negative")));
    }
    if let Some(n) = row.optional_f64("n_obs")?
        && !(n >= 0.0 && n.fract() == 0.0)
    {
        return Err(row.error("n_obs", format!("{n} is not a non-negative integer")));
    }
    Ok(Landmark {
        id,
        lat_deg,
        lon_deg,
        alt_m,
        sigma_m,
        class: row.optional_str("class").map(str::to_string),
        line: row.line,
    })
}

/// A latitude in degrees, checked for range.
pub(crate) fn latitude(row: &Row<'_>, column: &str) -> Result<f64, InputError> {
    let lat = row.required_f64(column)?;
    if lat.abs() > MAX_ABS_LAT_DEG {
        return Err(row.error(
            column,
            format!("latitude {lat} is outside [-90, 90] degrees"),
        ));
    }
    Ok(lat)
}

/// A longitude in degrees, checked for range.
pub(crate) fn longitude(row: &Row<'_>, column: &str) -> Result<f64, InputError> {
    let lon = row.required_f64(column)?;
    if lon.abs() > MAX_ABS_LON_DEG {
        return Err(row.error(
            column,
            format!("longitude {lon} is outside [-180, 180] degrees"),
        ));
    }
    Ok(lon)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<Landmark>, InputError> {
        landmarks_from_reader(Path::new("L.csv"), text.as_bytes())
    }

    fn message(text: &str) -> String {
        read(text).unwrap_err().to_string()
    }

    #[test]
    fn reads_columns_in_any_order_with_comments_and_optional_fields() {
        let l = read(
            "# survey of 2024\nalt, id ,lon,lat,sigma_m,class\n\n10.5,a,-122.5,37.5,,lamp\n\
             -3,b,2.25,-45,0.1,\n",
        )
        .unwrap();
        assert_eq!(l.len(), 2);
        assert_eq!(
            l[0],
            Landmark {
                id: "a".into(),
                lat_deg: 37.5,
                lon_deg: -122.5,
                alt_m: 10.5,
                sigma_m: None,
                class: Some("lamp".into()),
                line: 4,
            }
        );
        assert_eq!(
            (l[1].sigma_m, l[1].class.as_deref(), l[1].line),
            (Some(0.1), None, 5)
        );
    }

    #[test]
    fn n_obs_column_is_checked_and_accepted() {
        let h = "id,lat,lon,alt,sigma_m,class,n_obs\n";
        let l = read(&format!("{h}m1,1,2,3,0.1,lamp,12\nm2,1,2,3,0.1,,\n")).unwrap();
        assert_eq!((l.len(), l[0].class.as_deref()), (2, Some("lamp")));
        assert_eq!(
            message(&format!("{h}m1,1,2,3,0.1,lamp,2.5\n")),
            "L.csv:2: field `n_obs`: 2.5 is not a non-negative integer"
        );
        assert_eq!(
            message(&format!("{h}m1,1,2,3,0.1,lamp,-1\n")),
            "L.csv:2: field `n_obs`: -1 is not a non-negative integer"
        );
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let h = "id,lat,lon,alt\n";
        assert_eq!(
            message(&format!("{h}a,1,2,3\na,4,5,6\n")),
            "L.csv:3: field `id`: duplicate landmark id `a` (first on line 2)"
        );
        assert_eq!(
            message(&format!("{h}a,1,x,3\n")),
            "L.csv:2: field `lon`: `x` is not a number"
        );
        assert_eq!(
            message(&format!("{h}a,1,2,NaN\n")),
            "L.csv:2: field `alt`: `NaN` is not a finite number"
        );
        assert_eq!(
            message(&format!("{h}a,1,inf,3\n")),
            "L.csv:2: field `lon`: `inf` is not a finite number"
        );
        assert_eq!(
            message(&format!("{h}a,1,180.5,3\n")),
            "L.csv:2: field `lon`: longitude 180.5 is outside [-180, 180] degrees"
        );
        assert_eq!(
            message(&format!("{h}a,1,2\n")),
            "L.csv:2: field `alt`: missing value: the row has 3 fields, the header has 4"
        );
        assert_eq!(
            message(&format!("{h}a,1,2,3,4\n")),
            "L.csv:2: field `column 5`: unexpected extra value `4`: the row has 5 fields, \
             the header has 4"
        );
        assert_eq!(
            message(&format!("{h},1,2,3\n")),
            "L.csv:2: field `id`: missing value"
        );
        assert_eq!(
            message("id,lat,lon,alt,sigma_m\na,1,2,3,-1\n"),
            "L.csv:2: field `sigma_m`: -1 is negative"
        );
        assert!(
            message("id,lat,lon,alt,sigma\n").starts_with("L.csv:1: field `sigma`: unknown column")
        );
        assert!(
            message("id,lat,alt\n").starts_with("L.csv:1: field `lon`: required column is missing")
        );
        assert!(
            message("id,lat,lat,lon,alt\n")
                .starts_with("L.csv:1: field `lat`: column appears twice")
        );
        assert!(
            message("# only a comment\n").starts_with("L.csv:1: field `header`: the file is empty")
        );
    }

    #[test]
    fn invalid_utf8_names_line_and_column() {
        let bytes = b"id,lat,lon,alt\n# comment\na,1,2,3\nb,1,\xff,3\n";
        let err = landmarks_from_reader(Path::new("L.csv"), &bytes[..]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "L.csv:4: field `column 3`: the value is not valid UTF-8"
        );
    }

    #[test]
    fn missing_file_is_a_read_error() {
        let err = read_landmarks(Path::new("/nonexistent/L.csv")).unwrap_err();
        assert!(matches!(err, InputError::Read { .. }));
        assert!(
            err.to_string()
                .starts_with("/nonexistent/L.csv: cannot read the file")
        );
    }
}
