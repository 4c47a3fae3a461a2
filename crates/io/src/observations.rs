//! The observations file: per frame, bearings (or pixels) to landmarks.

use super::InputError;
use super::table::{Row, Table, open};
use nalgebra::Vector3;
use std::io::Read;
use std::path::Path;
use vgps_geometry::geometry::try_unit;

const COLUMNS: &[&str] = &["frame", "bx", "by", "bz", "camera", "u", "v", "landmark"];
const BEARING: &[&str] = &["bx", "by", "bz"];
const PIXEL: &[&str] = &["camera", "u", "v"];
const EXPECTED: &str = "[frame,](bx,by,bz | camera,u,v)[,landmark]";

/// What was measured for one observation.
#[derive(Clone, Debug, PartialEq)]
pub enum MeasurementRecord {
    /// A unit bearing in the rig frame (x forward, y left, z up).
    Bearing(Vector3<f64>),
    /// A pixel of one camera of the rig; a rig calibration turns it into a ray.
    Pixel {
        /// The camera identifier, as written in the file.
        camera: String,
        /// Column, pixels (integer = pixel centre).
        u: f64,
        /// Row, pixels (integer = pixel centre).
        v: f64,
    },
}

/// One row of the observations file.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservationRecord {
    /// The frame (image/epoch) the observation belongs to; 0 when the file has no `frame`
    /// column.
    pub frame: u64,
    /// The measured direction.
    pub measurement: MeasurementRecord,
    /// The id of the landmark seen, when known (`None`: empty or no `landmark` column).
    pub landmark: Option<String>,
    /// The 1-based line of the row in its file.
    pub line: u64,
}

/// Reads an observations file: optional `frame`, then `bx,by,bz` or `camera,u,v` (not
/// both), and an optional `landmark` column.
///
/// # Errors
/// [`InputError`] naming the file, line and field: unreadable file, bad header (unknown,
/// duplicated or missing column, both or neither of the bearing and pixel column groups),
/// wrong field count, non-number or non-finite value, a zero bearing, a `frame` that is not a
/// non-negative integer.
pub fn read_observations(path: &Path) -> Result<Vec<ObservationRecord>, InputError> {
    observations_from_reader(path, open(path)?)
}

/// Reads observations from any reader; `path` is used only in error messages.
///
/// # Errors
/// As [`read_observations`].
pub fn observations_from_reader<R: Read>(
    path: &Path,
    reader: R,
) -> Result<Vec<ObservationRecord>, InputError> {
    let table = Table::read(path, reader, COLUMNS, EXPECTED)?;
    let has_bearing = BEARING.iter().any(|c| table.has(c));
    let has_pixel = PIXEL.iter().any(|c| table.has(c));
    let pixels = match (has_bearing, has_pixel) {
        (true, true) => {
            return Err(table.header_error(
                "camera",
                "a file has either bearing columns `bx,by,bz` or pixel columns `camera,u,v`, \
                 not both",
            ));
        }
        (false, false) => {
            return Err(table.header_error(
                "bx",
                format!("no measurement columns: expected `{EXPECTED}`"),
            ));
        }
        (true, false) => {
            table.require(BEARING, EXPECTED)?;
            false
        }
        (false, true) => {
            table.require(PIXEL, EXPECTED)?;
            true
        }
    };
    let mut out = Vec::new();
    for row in table.rows() {
        let row = row?;
        let frame = frame(&row)?;
        let measurement = if pixels {
            MeasurementRecord::Pixel {
                camera: row.required_str("camera")?.to_string(),
                u: row.required_f64("u")?,
                v: row.required_f64("v")?,
            }
        } else {
            let b = Vector3::new(
                row.required_f64("bx")?,
                row.required_f64("by")?,
                row.required_f64("bz")?,
            );
            let unit = try_unit(&b).ok_or_else(|| {
                row.error(
                    "bx",
                    "zero bearing: (bx, by, bz) must have a non-zero length",
                )
            })?;
            MeasurementRecord::Bearing(unit)
        };
        out.push(ObservationRecord {
            frame,
            measurement,
            landmark: row.optional_str("landmark").map(str::to_string),
            line: row.line,
        });
    }
    Ok(out)
}

fn frame(row: &Row<'_>) -> Result<u64, InputError> {
    match row.raw("frame") {
        None => Ok(0),
        Some("") => Err(row.error("frame", "missing value")),
        Some(text) => text.parse().map_err(|_| {
            row.error(
                "frame",
                format!("`{text}` is not a frame number (a non-negative integer)"),
            )
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<ObservationRecord>, InputError> {
        observations_from_reader(Path::new("O.csv"), text.as_bytes())
    }

    fn message(text: &str) -> String {
        read(text).unwrap_err().to_string()
    }

    #[test]
    fn reads_bearings_normalised_with_frames_and_ids() {
        let o = read("frame,bx,by,bz,landmark\n3,2,0,0,a\n3,0,0,-0.5,\n1,1,1,0,c\n").unwrap();
        assert_eq!(o.len(), 3);
        assert_eq!(o[0].frame, 3);
        assert_eq!(o[0].measurement, MeasurementRecord::Bearing(Vector3::x()));
        assert_eq!(o[0].landmark.as_deref(), Some("a"));
        assert_eq!(o[1].measurement, MeasurementRecord::Bearing(-Vector3::z()));
        assert_eq!((o[1].landmark.as_deref(), o[1].line), (None, 3));
        let MeasurementRecord::Bearing(b) = &o[2].measurement else {
            panic!("not a bearing")
        };
        assert!((b.norm() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn default_frame_is_zero_and_pixels_are_read() {
        let o = read("camera,u,v\n2,100.5,30\n").unwrap();
        assert_eq!(o[0].frame, 0);
        assert_eq!(
            o[0].measurement,
            MeasurementRecord::Pixel {
                camera: "2".into(),
                u: 100.5,
                v: 30.0
            }
        );
        assert_eq!(o[0].landmark, None);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        assert_eq!(
            message("bx,by,bz\n1,0,0\n0,0,0\n"),
            "O.csv:3: field `bx`: zero bearing: (bx, by, bz) must have a non-zero length"
        );
        assert_eq!(
            message("bx,by,bz\n1,inf,0\n"),
            "O.csv:2: field `by`: `inf` is not a finite number"
        );
        assert_eq!(
            message("frame,bx,by,bz\n-1,1,0,0\n"),
            "O.csv:2: field `frame`: `-1` is not a frame number (a non-negative integer)"
        );
        assert_eq!(
            message("frame,bx,by,bz\n1.5,1,0,0\n"),
            "O.csv:2: field `frame`: `1.5` is not a frame number (a non-negative integer)"
        );
        assert!(message("bx,by\n").starts_with("O.csv:1: field `bz`: required column is missing"));
        assert!(message("bx,by,bz,u\n").starts_with("O.csv:1: field `camera`: a file has either"));
        assert!(message("frame,landmark\n").starts_with("O.csv:1: field `bx`: no measurement"));
        assert!(message("bx,by,bz,lm\n").starts_with("O.csv:1: field `lm`: unknown column"));
    }
}
