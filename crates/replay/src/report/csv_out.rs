//! `fixes.csv`: one row per frame.

use super::derived::{derive, finite};
use super::{DriveInfo, FrameOutcome};
use vgps_geometry::geo::Geodetic;

/// The columns of `fixes.csv` present for every drive.
pub const FIXES_COLUMNS: [&str; 18] = [
    "frame",
    "time_s",
    "status",
    "lat",
    "lon",
    "alt",
    "heading_deg",
    "pitch_deg",
    "roll_deg",
    "sigma_e_m",
    "sigma_n_m",
    "sigma_u_m",
    "n_landmarks",
    "n_surrogates",
    "gnss_lat",
    "gnss_lon",
    "gnss_alt",
    "diff_h_m",
];

/// The columns appended when any record has a ground truth.
pub const TRUTH_COLUMNS: [&str; 6] = [
    "truth_lat",
    "truth_lon",
    "truth_alt",
    "err_h_m",
    "err_v_m",
    "err_heading_deg",
];

/// The column appended when any record's detections came from the images
/// ([`FrameOutcome::unusable_images`] is `Some`): the number of the frame's images that could
/// not be used.
pub const IMAGE_COLUMNS: [&str; 1] = ["unusable_images"];

/// The last column, always present: [`FrameOutcome::message`], why the frame has its status.
pub const MESSAGE_COLUMN: &str = "message";

/// Decimals of latitudes and longitudes (1e-9° ≈ 0.1 mm).
pub(crate) const LATLON_DECIMALS: usize = 9;
/// Decimals of metres (millimetres).
pub(crate) const METRE_DECIMALS: usize = 3;
/// Decimals of angles in degrees.
pub(crate) const ANGLE_DECIMALS: usize = 4;
/// Decimals of Unix times (microseconds).
pub(crate) const TIME_DECIMALS: usize = 6;

/// `x` with `decimals` decimals, or the empty string for a missing or non-finite value.
pub(crate) fn fmt_opt(x: Option<f64>, decimals: usize) -> String {
    match x.and_then(finite) {
        // Avoid "-0.000".
        Some(v) => {
            let s = format!("{v:.decimals$}");
            if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
                s[1..].to_string()
            } else {
                s
            }
        }
        None => String::new(),
    }
}

fn push_geodetic(row: &mut Vec<String>, g: Option<&Geodetic>) {
    row.push(fmt_opt(g.map(|g| g.lat_deg), LATLON_DECIMALS));
    row.push(fmt_opt(g.map(|g| g.lon_deg), LATLON_DECIMALS));
    row.push(fmt_opt(g.map(|g| g.alt_m), METRE_DECIMALS));
}

/// `fixes.csv`: a header line ([`FIXES_COLUMNS`], then [`TRUTH_COLUMNS`] when any record
/// has a truth, then [`IMAGE_COLUMNS`] when any record came from images, then
/// [`MESSAGE_COLUMN`]) and one row per record. Missing values are empty fields; latitudes and
/// longitudes have 9 decimals, metres 3, degrees 4, times 6. Lines end in `\n`; a text field
/// (status, message) is quoted only if it contains a comma, quote or newline, and a message's
/// line breaks are replaced by spaces so that one frame stays one line.
pub fn fixes_csv(drive: &DriveInfo, records: &[FrameOutcome]) -> String {
    let geom = derive(drive, records);
    let with_truth = records.iter().any(|r| r.truth.is_some());
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let mut header: Vec<&str> = FIXES_COLUMNS.to_vec();
    if with_truth {
        header.extend(TRUTH_COLUMNS);
    }
    let with_images = records.iter().any(|r| r.unusable_images.is_some());
    if with_images {
        header.extend(IMAGE_COLUMNS);
    }
    header.push(MESSAGE_COLUMN);
    let mut rows: Vec<Vec<String>> = vec![header.iter().map(|s| s.to_string()).collect()];
    for (r, g) in records.iter().zip(&geom) {
        let v = r.visual.as_ref();
        let mut row = vec![
            r.frame.to_string(),
            fmt_opt(Some(r.time_s), TIME_DECIMALS),
            r.status.clone(),
        ];
        push_geodetic(&mut row, v.map(|v| &v.geodetic));
        for a in [
            v.map(|v| v.heading_deg),
            v.map(|v| v.pitch_deg),
            v.map(|v| v.roll_deg),
        ] {
            row.push(fmt_opt(a, ANGLE_DECIMALS));
        }
        for s in [
            v.map(|v| v.sigma_e_m),
            v.map(|v| v.sigma_n_m),
            v.map(|v| v.sigma_u_m),
        ] {
            row.push(fmt_opt(s, METRE_DECIMALS));
        }
        row.push(v.map(|v| v.n_landmarks.to_string()).unwrap_or_default());
        row.push(v.map(|v| v.n_surrogates.to_string()).unwrap_or_default());
        push_geodetic(&mut row, r.gnss.as_ref());
        row.push(fmt_opt(g.visual_vs_gnss.map(|d| d.h), METRE_DECIMALS));
        if with_truth {
            push_geodetic(&mut row, r.truth.as_ref().map(|t| &t.geodetic));
            row.push(fmt_opt(g.visual_vs_truth.map(|d| d.h), METRE_DECIMALS));
            row.push(fmt_opt(g.visual_vs_truth.map(|d| d.v), METRE_DECIMALS));
            row.push(fmt_opt(g.heading_err_deg, ANGLE_DECIMALS));
        }
        if with_images {
            row.push(r.unusable_images.map(|n| n.to_string()).unwrap_or_default());
        }
        row.push(r.message.replace(['\r', '\n'], " "));
        rows.push(row);
    }
    for row in &rows {
        // Writing into a Vec cannot fail; a failure would only drop the row.
        let _ = w.write_record(row);
    }
    let bytes = w.into_inner().unwrap_or_default();
    String::from_utf8(bytes).unwrap_or_default()
}
