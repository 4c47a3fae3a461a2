//! The CSV files of a drive: frames, detections, truth, and the landmarks writer.

use nalgebra::{Quaternion, UnitQuaternion};
use std::fmt::Write as _;
use std::path::Path;
use vgps_io::table::{Row, Table};
use vgps_io::{InputError, Landmark};

/// Largest accepted deviation of a truth quaternion's norm from 1: a quaternion within it
/// is normalised (rounding and format conversions leave norms off by ~1e-6); one further off
/// is a broken row.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;
/// Number of cameras a frame may name images for (`image_0` … `image_5`).
pub const MAX_IMAGE_COLUMNS: usize = 6;
/// The image column names per camera.
const IMAGE_COLUMNS: [&str; MAX_IMAGE_COLUMNS] = [
    "image_0", "image_1", "image_2", "image_3", "image_4", "image_5",
];

/// One frame of the drive.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRecord {
    /// Frame number (unique, increasing in the file).
    pub frame: u64,
    /// Unix time of the exposure, seconds (UTC).
    pub time_s: f64,
    /// Image file per camera (`image_k` → index k; a single `image` panorama → index 0),
    /// relative to the drive directory; `None` where the column is empty or absent.
    pub images: Vec<Option<String>>,
}

pub use vgps_camera::imaging::PixelDetection;

/// The true pose of the rig at one frame (simulations).
///
/// `enu_from_rig` is the attitude in the local-level ENU frame at the rig's own position
/// (`position`): rotating a rig-frame vector by it gives its east, north, up components
/// there.
#[derive(Clone, Debug, PartialEq)]
pub struct TruthRecord {
    /// The frame.
    pub frame: u64,
    /// The rig origin (WGS84).
    pub position: vgps_geometry::geo::Geodetic,
    /// Attitude `enu_from_rig` in the local-level frame at `position`.
    pub enu_from_rig: UnitQuaternion<f64>,
}

fn unsigned(row: &Row<'_>, column: &str) -> Result<u64, InputError> {
    let text = row.required_str(column)?;
    text.parse::<u64>()
        .map_err(|_| row.error(column, format!("`{text}` is not a non-negative integer")))
}

/// Reads `frames.csv`: `frame,time_s` and optional `image_0` … `image_5` or `image`.
///
/// # Errors
/// [`InputError`] naming file, line and field: bad header, non-integer frame, non-finite
/// time, duplicate or decreasing frame numbers, both `image` and `image_k` columns.
pub fn frames_from_text(path: &Path, text: &str) -> Result<Vec<FrameRecord>, InputError> {
    let mut allowed = vec!["frame", "time_s", "image"];
    allowed.extend_from_slice(&IMAGE_COLUMNS);
    let expected = "frame,time_s[,image_0,…,image_5 | ,image]";
    let table = Table::read(path, text.as_bytes(), &allowed, expected)?;
    table.require(&["frame", "time_s"], expected)?;
    let image_columns: Vec<&str> = if table.has("image") {
        if let Some(c) = IMAGE_COLUMNS.iter().find(|c| table.has(c)) {
            return Err(table.header_error(c, "give either `image` or `image_k` columns, not both"));
        }
        vec!["image"]
    } else {
        let last = IMAGE_COLUMNS.iter().rposition(|c| table.has(c));
        last.map_or(Vec::new(), |k| IMAGE_COLUMNS[..=k].to_vec())
    };
    let mut frames: Vec<FrameRecord> = Vec::new();
    for row in table.rows() {
        let row = row?;
        let frame = unsigned(&row, "frame")?;
        if let Some(prev) = frames.last()
            && frame <= prev.frame
        {
            return Err(row.error(
                "frame",
                format!(
                    "frame {frame} does not follow frame {} (frames must increase)",
                    prev.frame
                ),
            ));
        }
        let time_s = row.required_f64("time_s")?;
        let images = image_columns
            .iter()
            .map(|c| row.optional_str(c).map(str::to_string))
            .collect();
        frames.push(FrameRecord {
            frame,
            time_s,
            images,
        });
    }
    Ok(frames)
}

/// One parsed detections row, or the reason it is unusable.
pub enum DetectionRow {
    /// A valid row.
    Ok(PixelDetection),
    /// A bad row whose frame number could be read.
    Bad {
        /// The row's frame number.
        frame: u64,
        /// What is wrong, naming the file, the line and the field.
        message: String,
    },
    /// A bad row without a readable frame number.
    Orphan(String),
}

/// Reads `detections.csv` (`frame,camera,u,v` and optional `strength`, `class`) row by row:
/// a bad row does not stop the reading. Invalid UTF-8 is replaced so that only the rows
/// holding it fail.
///
/// # Errors
/// Only a bad header (unknown, duplicated or missing column, empty file).
pub fn detections_from_text(
    path: &Path,
    text: &str,
    cameras: usize,
) -> Result<Vec<DetectionRow>, InputError> {
    let expected = "frame,camera,u,v[,strength][,class]";
    let table = Table::read(
        path,
        text.as_bytes(),
        &["frame", "camera", "u", "v", "strength", "class"],
        expected,
    )?;
    table.require(&["frame", "camera", "u", "v"], expected)?;
    let mut out = Vec::with_capacity(table.len());
    for row in table.rows() {
        let row = match row {
            Ok(r) => r,
            Err(e) => {
                out.push(DetectionRow::Orphan(e.to_string()));
                continue;
            }
        };
        let frame = match unsigned(&row, "frame") {
            Ok(f) => f,
            Err(e) => {
                out.push(DetectionRow::Orphan(e.to_string()));
                continue;
            }
        };
        let parsed = (|| -> Result<PixelDetection, InputError> {
            let camera = unsigned(&row, "camera")?;
            let camera = usize::try_from(camera)
                .ok()
                .filter(|&c| c < cameras)
                .ok_or_else(|| {
                    row.error(
                        "camera",
                        format!("camera {camera} is not in the rig (it has {cameras})"),
                    )
                })?;
            let strength = row.optional_f64("strength")?;
            Ok(PixelDetection {
                frame,
                camera,
                u: row.required_f64("u")?,
                v: row.required_f64("v")?,
                strength,
                class: row.optional_str("class").map(str::to_string),
            })
        })();
        out.push(match parsed {
            Ok(d) => DetectionRow::Ok(d),
            Err(e) => DetectionRow::Bad {
                frame,
                message: e.to_string(),
            },
        });
    }
    Ok(out)
}

/// Reads `truth.csv`: `frame,lat,lon,alt,qw,qx,qy,qz`. A quaternion whose norm is within
/// [`QUATERNION_NORM_TOLERANCE`] of 1 is normalised.
///
/// # Errors
/// [`InputError`] naming file, line and field: bad header or value, latitude out of range,
/// quaternion norm not 1 within [`QUATERNION_NORM_TOLERANCE`], a frame that does not
/// increase or is not in `frames`. (A drive reads its truth with
/// [`super::truth_formats::read_truth`], which refuses such rows one by one instead.)
pub fn truth_from_text(
    path: &Path,
    text: &str,
    frames: &[FrameRecord],
) -> Result<Vec<TruthRecord>, InputError> {
    let (records, rows) = truth_rows_inner(path, text, frames)?;
    for row in rows {
        row?;
    }
    Ok(records)
}

/// The good records of a `truth.csv` and, per data row, whether its quaternion was
/// normalised or why the row was refused (`file:line: field …`).
pub(super) type TruthRows = (Vec<TruthRecord>, Vec<Result<bool, String>>);

/// As [`truth_from_text`], refusing bad rows one by one; `Err` only for the header.
pub(super) fn truth_rows(
    path: &Path,
    text: &str,
    frames: &[FrameRecord],
) -> Result<TruthRows, InputError> {
    let (records, rows) = truth_rows_inner(path, text, frames)?;
    Ok((
        records,
        rows.into_iter()
            .map(|r| r.map_err(|e| e.to_string()))
            .collect(),
    ))
}

#[allow(clippy::type_complexity)]
fn truth_rows_inner(
    path: &Path,
    text: &str,
    frames: &[FrameRecord],
) -> Result<(Vec<TruthRecord>, Vec<Result<bool, InputError>>), InputError> {
    let cols = ["frame", "lat", "lon", "alt", "qw", "qx", "qy", "qz"];
    let expected = "frame,lat,lon,alt,qw,qx,qy,qz";
    let table = Table::read(path, text.as_bytes(), &cols, expected)?;
    table.require(&cols, expected)?;
    let mut out: Vec<TruthRecord> = Vec::new();
    let mut rows = Vec::new();
    for row in table.rows() {
        let result = row.and_then(|row| truth_row(&row, frames, out.last()));
        rows.push(result.map(|(record, normalised)| {
            out.push(record);
            normalised
        }));
    }
    Ok((out, rows))
}

fn truth_row(
    row: &Row<'_>,
    frames: &[FrameRecord],
    previous: Option<&TruthRecord>,
) -> Result<(TruthRecord, bool), InputError> {
    let frame = unsigned(row, "frame")?;
    if previous.is_some_and(|t| t.frame >= frame) {
        return Err(row.error("frame", format!("frame {frame} does not increase")));
    }
    if frames.binary_search_by_key(&frame, |f| f.frame).is_err() {
        return Err(row.error("frame", format!("frame {frame} is not in the frames file")));
    }
    let lat = row.required_f64("lat")?;
    if lat.abs() > vgps_io::MAX_ABS_LAT_DEG {
        return Err(row.error(
            "lat",
            format!("latitude {lat} is outside [-90, 90] degrees"),
        ));
    }
    let lon = row.required_f64("lon")?;
    if lon.abs() > vgps_io::MAX_ABS_LON_DEG {
        return Err(row.error(
            "lon",
            format!("longitude {lon} is outside [-180, 180] degrees"),
        ));
    }
    let alt = row.required_f64("alt")?;
    let position = vgps_geometry::geo::Geodetic::try_new(lat, lon, alt)
        .map_err(|e| row.error("alt", e.to_string()))?;
    let q = Quaternion::new(
        row.required_f64("qw")?,
        row.required_f64("qx")?,
        row.required_f64("qy")?,
        row.required_f64("qz")?,
    );
    let (enu_from_rig, normalised) =
        super::truth_formats::normalise(q).map_err(|e| row.error("qw", e))?;
    Ok((
        TruthRecord {
            frame,
            position,
            enu_from_rig,
        },
        normalised,
    ))
}

fn opt_f64(x: Option<f64>) -> String {
    x.map_or(String::new(), |v| format!("{v}"))
}

/// CSV text of frames (`frame,time_s` and the image columns the frames use).
pub fn frames_to_csv(frames: &[FrameRecord]) -> String {
    let n = frames.iter().map(|f| f.images.len()).max().unwrap_or(0);
    let mut out = String::from("frame,time_s");
    if n == 1 {
        out.push_str(",image");
    } else {
        for c in IMAGE_COLUMNS.iter().take(n) {
            let _ = write!(out, ",{c}");
        }
    }
    out.push('\n');
    for f in frames {
        let _ = write!(out, "{},{}", f.frame, f.time_s);
        for k in 0..n {
            out.push(',');
            if let Some(Some(p)) = f.images.get(k) {
                out.push_str(p);
            }
        }
        out.push('\n');
    }
    out
}

/// CSV text of detections (`frame,camera,u,v,strength,class`).
pub fn detections_to_csv(detections: &[PixelDetection]) -> String {
    let mut out = String::from("frame,camera,u,v,strength,class\n");
    for d in detections {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{}",
            d.frame,
            d.camera,
            d.u,
            d.v,
            opt_f64(d.strength),
            d.class.as_deref().unwrap_or("")
        );
    }
    out
}

/// CSV text of truth records (`frame,lat,lon,alt,qw,qx,qy,qz`).
pub fn truth_to_csv(truth: &[TruthRecord]) -> String {
    let mut out = String::from("frame,lat,lon,alt,qw,qx,qy,qz\n");
    for t in truth {
        let q = t.enu_from_rig.quaternion();
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{}",
            t.frame, t.position.lat_deg, t.position.lon_deg, t.position.alt_m, q.w, q.i, q.j, q.k
        );
    }
    out
}

/// CSV text of landmarks (`id,lat,lon,alt,sigma_m,class`), readable by
/// [`read_landmarks`](vgps_io::read_landmarks).
pub fn landmarks_to_csv(landmarks: &[Landmark]) -> String {
    let mut out = String::from("id,lat,lon,alt,sigma_m,class\n");
    for l in landmarks {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{}",
            l.id,
            l.lat_deg,
            l.lon_deg,
            l.alt_m,
            opt_f64(l.sigma_m),
            l.class.as_deref().unwrap_or("")
        );
    }
    out
}
