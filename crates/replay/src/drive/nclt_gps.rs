//! NCLT `gps.csv` (and `gps_rtk.csv`): the satellite GPS of the University of Michigan
//! North Campus Long-Term dataset, read into [`GnssRecord`]s.
//!
//! The file has no header; each row is
//!
//! | column | unit | meaning |
//! |---|---|---|
//! | `utime` | µs | Unix time (UTC) in microseconds |
//! | `mode` | — | 0 or 1: no fix; 2: 2-D fix; 3: 3-D fix |
//! | `num_sats` | — | satellites used |
//! | `lat` | rad | latitude (WGS84) |
//! | `lng` | rad | longitude (WGS84) |
//! | `alt` | m | height as the receiver reports it (taken as the ellipsoidal height; no geoid model) |
//! | `track` | rad | course over ground (not read: a course is not the rig's heading) |
//! | `speed` | m/s | speed over ground (not read) |
//!
//! The first six columns are required, further ones are ignored.
//!
//! - A row with `mode` < 2 is an epoch without a fix: a record with `fix: None`, counted in
//!   [`GnssFileStats::no_fix`] (a no-fix epoch stops the replay's interpolation across it).
//! - A row with a fix whose latitude, longitude or height is not finite (NCLT files contain
//!   `NaN` rows) or out of range is skipped and counted in
//!   [`GnssFileStats::invalid_position`].
//! - A field that is not a number is a [`GnssFileError::Csv`] naming file, line and column,
//!   except in an unterminated last line (an interrupted log), which is skipped and counted
//!   in [`GnssFileStats::other_skipped`].
//!
//! The fix quality of a record is 1 (GPS); the HDOP is unknown (`None`).

use super::gnss::{GnssFileError, GnssFileStats, GnssFormat, sort_by_time};
use super::nmea::{GnssFix, GnssRecord};
use std::path::Path;
use vgps_geometry::geo::Geodetic;

/// The columns of an NCLT `gps.csv` row, in order.
pub const COLUMNS: [&str; 8] = [
    "utime", "mode", "num_sats", "lat", "lng", "alt", "track", "speed",
];
/// Columns a row must have (`utime` … `alt`).
pub const MIN_COLUMNS: usize = 6;
/// The smallest `mode` of a fix (2 = 2-D).
pub const MIN_FIX_MODE: i64 = 2;
/// The largest magnitude of a longitude (degrees); beyond it a row is invalid.
const MAX_LON_DEG: f64 = 180.0;
/// Microseconds per second.
const MICROS: i64 = 1_000_000;
/// The GGA-style quality given to an NCLT fix (1 = GPS).
pub const NCLT_FIX_QUALITY: u8 = 1;

/// Reads the text of an NCLT `gps.csv` (`path` names it in errors and messages); returns the
/// records sorted by time and the counts.
///
/// # Errors
/// [`GnssFileError::Csv`] naming the file, the line and the column of a row with too few
/// fields or a field that is not a number (see the module documentation).
///
/// # Example
/// ```
/// use std::path::Path;
/// use vgps_replay::drive::nclt_gps::read_nclt_gps;
/// let text = "1326030000250000,3,8,0.7381,-1.4610,270.0,0.2,1.0\n\
///             1326030001250000,0,0,NaN,NaN,NaN,NaN,NaN\n";
/// let (records, stats) = read_nclt_gps(Path::new("gps.csv"), text)?;
/// assert_eq!((records.len(), stats.fixes, stats.no_fix), (2, 1, 1));
/// assert_eq!(records[0].time_s, 1_326_030_000.25);
/// assert_eq!(records[0].fix.unwrap().num_sats, Some(8));
/// let err = read_nclt_gps(Path::new("gps.csv"), "1,3,8,x,0,0,0,0\n").unwrap_err();
/// assert_eq!(err.to_string(), "gps.csv:1: field `lat`: `x` is not a number");
/// # Ok::<(), vgps_replay::drive::gnss::GnssFileError>(())
/// ```
pub fn read_nclt_gps(
    path: &Path,
    text: &str,
) -> Result<(Vec<GnssRecord>, GnssFileStats), GnssFileError> {
    let mut stats = GnssFileStats::new(GnssFormat::Nclt);
    let mut records = Vec::new();
    let terminated = text.ends_with('\n');
    let last_line = text.lines().count() as u64;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut record = csv::StringRecord::new();
    let mut line = 0_u64;
    loop {
        let more = reader
            .read_record(&mut record)
            .map_err(|e| GnssFileError::Csv {
                path: path.to_path_buf(),
                line: e.position().map_or(line + 1, |p| p.line()),
                field: "row".into(),
                reason: e.to_string(),
            })?;
        if !more {
            break;
        }
        line = record.position().map_or(line + 1, |p| p.line());
        if record.iter().all(str::is_empty) {
            continue;
        }
        stats.entries += 1;
        match parse_row(&record) {
            Ok(GpsRow::Fix(r)) => {
                stats.fixes += 1;
                records.push(r);
            }
            Ok(GpsRow::NoFix(r)) => {
                stats.no_fix += 1;
                records.push(r);
            }
            Ok(GpsRow::Invalid(reason)) => {
                stats.invalid_position += 1;
                stats.note(format!("line {line}: {reason}; skipped"));
            }
            Err((field, reason)) if !terminated && line == last_line => {
                stats.other_skipped += 1;
                stats.note(format!(
                    "line {line}: unterminated last row, field `{field}`: {reason}; skipped"
                ));
            }
            Err((field, reason)) => {
                return Err(GnssFileError::Csv {
                    path: path.to_path_buf(),
                    line,
                    field: field.into(),
                    reason,
                });
            }
        }
    }
    sort_by_time(&mut records);
    Ok((records, stats))
}

enum GpsRow {
    Fix(GnssRecord),
    NoFix(GnssRecord),
    Invalid(String),
}

fn number(record: &csv::StringRecord, k: usize) -> Result<f64, (&'static str, String)> {
    let field = COLUMNS[k];
    let text = record.get(k).ok_or_else(|| {
        (
            field,
            format!("missing (a row has at least {MIN_COLUMNS} fields)"),
        )
    })?;
    text.parse::<f64>()
        .map_err(|_| (field, format!("`{text}` is not a number")))
}

fn integer(record: &csv::StringRecord, k: usize) -> Result<i64, (&'static str, String)> {
    let field = COLUMNS[k];
    let text = record.get(k).unwrap_or_default();
    if let Ok(v) = text.parse::<i64>() {
        return Ok(v);
    }
    let v = number(record, k)?;
    if v.fract() == 0.0 && v.abs() < 9.0e15 {
        Ok(v as i64)
    } else {
        Err((field, format!("`{text}` is not an integer")))
    }
}

fn parse_row(record: &csv::StringRecord) -> Result<GpsRow, (&'static str, String)> {
    let utime = integer(record, 0)?;
    let mode = integer(record, 1)?;
    let sats = integer(record, 2)?;
    let lat_rad = number(record, 3)?;
    let lng_rad = number(record, 4)?;
    let alt_m = number(record, 5)?;
    let time_s = utime.div_euclid(MICROS) as f64 + utime.rem_euclid(MICROS) as f64 * 1e-6;
    if mode < MIN_FIX_MODE {
        return Ok(GpsRow::NoFix(GnssRecord {
            time_s,
            fix: None,
            heading_deg: None,
        }));
    }
    let (lat, lon) = (lat_rad.to_degrees(), lng_rad.to_degrees());
    if lon.abs() > MAX_LON_DEG {
        return Ok(GpsRow::Invalid(format!(
            "mode {mode} with longitude {lng_rad} rad outside [-π, π]"
        )));
    }
    match Geodetic::try_new(lat, lon, alt_m) {
        Ok(position) => Ok(GpsRow::Fix(GnssRecord {
            time_s,
            fix: Some(GnssFix {
                position,
                quality: NCLT_FIX_QUALITY,
                hdop: None,
                num_sats: u32::try_from(sats).ok(),
            }),
            heading_deg: None,
        })),
        Err(e) => Ok(GpsRow::Invalid(format!(
            "mode {mode} with an invalid position (lat {lat_rad} rad, lng {lng_rad} rad, alt {alt_m} m): {e}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use vgps_geometry::synthetic::rng;

    /// Writes records as NCLT rows (radians with Rust's shortest round-trip formatting).
    fn to_nclt(records: &[GnssRecord]) -> String {
        let mut s = String::new();
        for r in records {
            let utime = (r.time_s * 1e6).round() as i64;
            match r.fix {
                Some(f) => s.push_str(&format!(
                    "{utime},3,{},{},{},{},0.5,1.5\n",
                    f.num_sats.unwrap_or(0),
                    f.position.lat_deg.to_radians(),
                    f.position.lon_deg.to_radians(),
                    f.position.alt_m
                )),
                None => s.push_str(&format!("{utime},1,0,NaN,NaN,NaN,NaN,NaN\n")),
            }
        }
        s
    }

    fn random_records(n: usize, seed: u64) -> Vec<GnssRecord> {
        let mut g = rng(seed);
        (0..n)
            .map(|k| {
                let fix = (k % 7 != 3).then(|| GnssFix {
                    position: Geodetic::try_new(
                        g.random_range(-89.9..89.9),
                        g.random_range(-179.9..179.9),
                        g.random_range(-100.0..3000.0),
                    )
                    .unwrap(),
                    quality: NCLT_FIX_QUALITY,
                    hdop: None,
                    num_sats: Some(g.random_range(4..20)),
                });
                GnssRecord {
                    time_s: 1_326_030_000.0 + 0.2 * k as f64,
                    fix,
                    heading_deg: None,
                }
            })
            .collect()
    }

    #[test]
    fn round_trip_within_1e9_deg() {
        let records = random_records(200, 11);
        let (back, stats) = read_nclt_gps(Path::new("gps.csv"), &to_nclt(&records)).unwrap();
        assert_eq!(back.len(), records.len());
        assert_eq!(
            stats.no_fix,
            records.iter().filter(|r| r.fix.is_none()).count()
        );
        assert_eq!(stats.fixes + stats.no_fix, stats.entries);
        for (a, b) in records.iter().zip(&back) {
            assert!(
                (a.time_s - b.time_s).abs() < 1e-6,
                "{} {}",
                a.time_s,
                b.time_s
            );
            match (a.fix, b.fix) {
                (Some(x), Some(y)) => {
                    assert!((x.position.lat_deg - y.position.lat_deg).abs() < 1e-9);
                    assert!((x.position.lon_deg - y.position.lon_deg).abs() < 1e-9);
                    assert!((x.position.alt_m - y.position.alt_m).abs() < 1e-9);
                    assert_eq!(x.num_sats, y.num_sats);
                }
                (None, None) => {}
                other => panic!("fix mismatch {other:?}"),
            }
        }
    }

    #[test]
    fn nan_and_out_of_range_rows_are_skipped_and_counted() {
        let text = "1000000,3,8,0.5,0.5,10,0,0\n\
                    2000000,3,8,NaN,NaN,NaN,NaN,NaN\n\
                    3000000,2,8,2.0,0.5,10,0,0\n\
                    4000000,3,8,0.5,inf,10,0,0\n\
                    5000000,0,0,NaN,NaN,NaN,NaN,NaN\n\
                    6000000,3,8,0.5,0.5,10\n";
        let (records, stats) = read_nclt_gps(Path::new("g.csv"), text).unwrap();
        assert_eq!(stats.entries, 6);
        assert_eq!(stats.invalid_position, 3);
        assert_eq!((stats.fixes, stats.no_fix), (2, 1));
        let times: Vec<f64> = records.iter().map(|r| r.time_s).collect();
        assert_eq!(times, [1.0, 5.0, 6.0]);
        assert!(stats.messages[0].starts_with("line 2: mode 3"));
        assert!(stats.messages[1].starts_with("line 3:"));
    }

    #[test]
    fn garbage_is_an_error_naming_line_and_field() {
        let text = "1000000,3,8,0.5,0.5,10,0,0\n2000000,three,8,0.5,0.5,10,0,0\n";
        let e = read_nclt_gps(Path::new("d/gps.csv"), text).unwrap_err();
        assert_eq!(
            e.to_string(),
            "d/gps.csv:2: field `mode`: `three` is not a number"
        );
        let e = read_nclt_gps(Path::new("gps.csv"), "1000000,3,8,0.5\n").unwrap_err();
        assert!(matches!(e, GnssFileError::Csv { line: 1, ref field, .. } if field == "lng"));
        let e = read_nclt_gps(Path::new("gps.csv"), "1.5e6x,3,8,0.5,0.5,1\n").unwrap_err();
        assert!(matches!(e, GnssFileError::Csv { ref field, .. } if field == "utime"));
    }

    #[test]
    fn unterminated_last_row_is_counted_not_fatal() {
        let text = "1000000,3,8,0.5,0.5,10,0,0\n2000000,3,8,0.5,0.";
        let (records, stats) = read_nclt_gps(Path::new("gps.csv"), text).unwrap();
        assert_eq!((records.len(), stats.other_skipped), (1, 1));
        // Terminated, the same row is an error.
        assert!(read_nclt_gps(Path::new("gps.csv"), &format!("{text}\n")).is_err());
    }

    #[test]
    fn rows_are_sorted_and_negative_times_exact() {
        let text = "2000001,3,8,0.5,0.5,10\n-1500000,3,8,0.5,0.5,10\n";
        let (records, _) = read_nclt_gps(Path::new("gps.csv"), text).unwrap();
        assert_eq!(records[0].time_s, -1.5);
        assert!((records[1].time_s - 2.000001).abs() < 1e-12);
    }
}
