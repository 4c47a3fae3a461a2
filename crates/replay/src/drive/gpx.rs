//! GPX 1.0 / 1.1 tracks as satellite GPS: every track point (`trkpt`) with its time becomes
//! a [`GnssRecord`]. The document is parsed by the `gpx` crate.
//!
//! # Fields
//! - `lat`, `lon` (degrees, WGS84) → the position; `ele` (m) plus `geoidheight` when given
//!   → the ellipsoidal height (GPX `ele` is the receiver's height, by the specification
//!   above mean sea level, with `geoidheight` the geoid's height above the ellipsoid as in
//!   NMEA GGA; without `geoidheight` `ele` is taken as it is, the rule of the NMEA reader).
//! - `time` (UTC) → `time_s`, Unix seconds: the drive clock (see [`super::gnss`]).
//! - `fix`: `none` → an epoch without a fix (`fix: None`); `dgps` → quality 2, `pps` → 3,
//!   anything else or absent → 1. `sat` → satellites, `hdop` → HDOP.
//! - Waypoints (`wpt`) and routes (`rte`) are not epochs of a receiver and are not read.
//!
//! # Faults
//! - A point whose `lat` or `lon` is a number but not finite or out of range (latitude
//!   outside [−90, 90], longitude outside [−180, 180]) is removed before parsing (the `gpx`
//!   crate rejects the whole document for it) and counted in
//!   [`GnssFileStats::invalid_position`]; a point with a non-finite `ele` likewise.
//! - A point without `time` is skipped and counted ([`GnssFileStats::untimed`]); a point
//!   without `ele` is kept with height 0 and counted ([`GnssFileStats::no_elevation`]).
//! - A `trkpt` without `lat`/`lon`, or whose value is not a number, and any document the
//!   `gpx` crate cannot parse, are a [`GnssFileError::Gpx`] naming the file, and the line
//!   and point index when they are known.

use super::gnss::{GnssFileError, GnssFileStats, GnssFormat, sort_by_time};
use super::nmea::{GnssFix, GnssRecord};
use std::path::Path;
use vgps_geometry::geo::Geodetic;

/// The GGA-style quality of a GPX point whose `fix` is absent, `2d`, `3d` or unknown.
pub const GPX_QUALITY_GPS: u8 = 1;
/// The GGA-style quality of a GPX point with `<fix>dgps</fix>`.
pub const GPX_QUALITY_DGPS: u8 = 2;
/// The GGA-style quality of a GPX point with `<fix>pps</fix>`.
pub const GPX_QUALITY_PPS: u8 = 3;
/// The largest magnitude of a latitude (degrees).
const MAX_LAT_DEG: f64 = 90.0;
/// The largest magnitude of a longitude (degrees).
const MAX_LON_DEG: f64 = 180.0;

/// One `trkpt` start tag found by [`scan`].
struct Scanned {
    /// The 1-based line of the tag.
    line: u64,
}

/// The document with the points of invalid position removed (line breaks kept, so lines
/// stay those of the file), the kept points and the counts.
struct Scan {
    text: String,
    kept: Vec<Scanned>,
}

/// The value and byte span of attribute `name` in the inside of a start tag.
fn attribute<'a>(tag: &'a str, name: &str) -> Option<(&'a str, usize, usize)> {
    let bytes = tag.as_bytes();
    let mut from = 0;
    while let Some(at) = tag[from..].find(name).map(|k| k + from) {
        from = at + name.len();
        let before_ok = at == 0 || bytes[at - 1].is_ascii_whitespace();
        let rest = tag[from..].trim_start();
        if !before_ok || !rest.starts_with('=') {
            continue;
        }
        let rest = rest[1..].trim_start();
        let Some(quote) = rest.chars().next().filter(|c| *c == '"' || *c == '\'') else {
            continue;
        };
        let start = tag.len() - rest.len() + 1;
        let end = start + tag[start..].find(quote)?;
        return Some((&tag[start..end], start, end));
    }
    None
}

/// Finds every `trkpt`, checks its `lat` and `lon`, removes the points whose position is
/// not finite or out of range, and writes `lon="180"` as `-180` (the `gpx` crate wants
/// longitudes in [−180, 180)).
fn scan(path: &Path, text: &str, stats: &mut GnssFileStats) -> Result<Scan, GnssFileError> {
    const TAG: &str = "<trkpt";
    const END: &str = "</trkpt>";
    let mut out = String::with_capacity(text.len());
    let mut kept = Vec::new();
    let (mut copied, mut pos, mut line, mut counted, mut index) = (0, 0, 1_u64, 0, 0_usize);
    while let Some(start) = text[pos..].find(TAG).map(|k| k + pos) {
        let after = start + TAG.len();
        pos = after;
        if !text[after..]
            .chars()
            .next()
            .is_some_and(|c| c.is_whitespace() || c == '>' || c == '/')
        {
            continue;
        }
        line += text[counted..start].matches('\n').count() as u64;
        counted = start;
        let Some(tag_end) = text[after..].find('>').map(|k| k + after) else {
            break; // an unclosed tag: the parser reports it
        };
        pos = tag_end + 1;
        let point = index;
        index += 1;
        let tag = &text[after..tag_end];
        let err = |reason: String| GnssFileError::Gpx {
            path: path.to_path_buf(),
            line: Some(line),
            point: Some(point),
            reason,
        };
        let value = |name: &str| -> Result<(f64, usize, usize), GnssFileError> {
            let (v, a, b) =
                attribute(tag, name).ok_or_else(|| err(format!("`trkpt` without `{name}`")))?;
            let x = v
                .trim()
                .parse::<f64>()
                .map_err(|_| err(format!("`{name}` = `{v}` is not a number")))?;
            Ok((x, after + a, after + b))
        };
        let (lat, _, _) = value("lat")?;
        let (lon, lon_a, lon_b) = value("lon")?;
        let ele_invalid = element_text(text, tag_end, "ele")
            .and_then(|e| e.trim().parse::<f64>().ok())
            .is_some_and(|e| !e.is_finite());
        let bad = if !(lat.is_finite() && lat.abs() <= MAX_LAT_DEG) {
            Some(format!("latitude {lat}"))
        } else if !(lon.is_finite() && lon.abs() <= MAX_LON_DEG) {
            Some(format!("longitude {lon}"))
        } else if ele_invalid {
            Some("a non-finite `ele`".to_string())
        } else {
            None
        };
        if let Some(what) = bad {
            let self_closing = text[..tag_end].ends_with('/');
            let end = if self_closing {
                tag_end + 1
            } else {
                match text[tag_end..].find(END) {
                    Some(k) => tag_end + k + END.len(),
                    None => break, // unclosed: the parser reports it
                }
            };
            stats.entries += 1;
            stats.invalid_position += 1;
            stats.note(format!(
                "line {line}: point {point}: {what} is invalid; skipped"
            ));
            out.push_str(&text[copied..start]);
            out.extend(text[start..end].matches('\n').map(|_| '\n'));
            copied = end;
            pos = end;
            continue;
        }
        if lon == MAX_LON_DEG {
            out.push_str(&text[copied..lon_a]);
            out.push_str("-180");
            copied = lon_b;
        }
        kept.push(Scanned { line });
    }
    out.push_str(&text[copied..]);
    Ok(Scan { text: out, kept })
}

/// The text of the first `<name>` element after `from` and before the next `</trkpt>`.
fn element_text<'a>(text: &'a str, from: usize, name: &str) -> Option<&'a str> {
    let rest = &text[from..];
    let limit = rest.find("</trkpt>").unwrap_or(rest.len());
    let rest = &rest[..limit];
    let open = format!("<{name}>");
    let a = rest.find(&open)? + open.len();
    let b = a + rest[a..].find('<')?;
    Some(&rest[a..b])
}

/// The full message of an error and its sources.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(inner) = source {
        s.push_str(": ");
        s.push_str(&inner.to_string());
        source = inner.source();
    }
    s
}

/// Reads the text of a GPX document (`path` names it in errors and messages): every track
/// point with a time, sorted by time, and the counts.
///
/// # Errors
/// [`GnssFileError::Gpx`] (see the module documentation).
///
/// # Example
/// ```
/// use std::path::Path;
/// use vgps_replay::drive::gpx::read_gpx;
/// let text = r#"<?xml version="1.0"?>
/// <gpx version="1.1" creator="x" xmlns="http://www.topografix.com/GPX/1/1"><trk><trkseg>
/// <trkpt lat="42.2936" lon="-83.7108"><ele>270.5</ele><time>2012-01-08T15:00:00.5Z</time><sat>9</sat></trkpt>
/// <trkpt lat="NaN" lon="-83.7108"><time>2012-01-08T15:00:01Z</time></trkpt>
/// <trkpt lat="42.2937" lon="-83.7108"><ele>270.6</ele></trkpt>
/// </trkseg></trk></gpx>"#;
/// let (records, stats) = read_gpx(Path::new("t.gpx"), text)?;
/// assert_eq!(records.len(), 1);
/// assert_eq!((stats.entries, stats.invalid_position, stats.untimed), (3, 1, 1));
/// assert_eq!(records[0].time_s, 1_326_034_800.5);
/// assert_eq!(records[0].fix.unwrap().num_sats, Some(9));
/// # Ok::<(), vgps_replay::drive::gnss::GnssFileError>(())
/// ```
pub fn read_gpx(
    path: &Path,
    text: &str,
) -> Result<(Vec<GnssRecord>, GnssFileStats), GnssFileError> {
    let mut stats = GnssFileStats::new(GnssFormat::Gpx);
    let scan = scan(path, text, &mut stats)?;
    let document = gpx::read(scan.text.as_bytes()).map_err(|e| GnssFileError::Gpx {
        path: path.to_path_buf(),
        line: None,
        point: None,
        reason: error_chain(&e),
    })?;
    let mut records = Vec::new();
    let points = document
        .tracks
        .iter()
        .flat_map(|t| &t.segments)
        .flat_map(|s| &s.points);
    for (k, p) in points.enumerate() {
        stats.entries += 1;
        let at = scan
            .kept
            .get(k)
            .map(|s| format!("line {}: ", s.line))
            .unwrap_or_default();
        let Some(time) = p.time else {
            stats.untimed += 1;
            stats.note(format!("{at}point without `time`; skipped"));
            continue;
        };
        let time: time::OffsetDateTime = time.into();
        let time_s = time.unix_timestamp() as f64 + f64::from(time.nanosecond()) * 1e-9;
        if matches!(p.fix, Some(gpx::Fix::None)) {
            stats.no_fix += 1;
            records.push(GnssRecord {
                time_s,
                fix: None,
                heading_deg: None,
            });
            continue;
        }
        let alt_m = match p.elevation {
            Some(e) => e + p.geoidheight.filter(|n| n.is_finite()).unwrap_or(0.0),
            None => {
                stats.no_elevation += 1;
                stats.note(format!("{at}point without `ele`; height taken as 0 m"));
                0.0
            }
        };
        let point = p.point();
        let position = match Geodetic::try_new(point.y(), point.x(), alt_m) {
            Ok(g) => g,
            Err(e) => {
                stats.invalid_position += 1;
                stats.note(format!("{at}invalid position: {e}; skipped"));
                continue;
            }
        };
        let quality = match p.fix {
            Some(gpx::Fix::DGPS) => GPX_QUALITY_DGPS,
            Some(gpx::Fix::PPS) => GPX_QUALITY_PPS,
            _ => GPX_QUALITY_GPS,
        };
        stats.fixes += 1;
        records.push(GnssRecord {
            time_s,
            fix: Some(GnssFix {
                position,
                quality,
                hdop: p.hdop.filter(|h| h.is_finite() && *h >= 0.0),
                num_sats: p.sat.and_then(|n| u32::try_from(n).ok()),
            }),
            heading_deg: None,
        });
    }
    sort_by_time(&mut records);
    Ok((records, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use vgps_geometry::synthetic::rng;

    fn random_records(n: usize, seed: u64) -> Vec<GnssRecord> {
        let mut g = rng(seed);
        (0..n)
            .map(|k| GnssRecord {
                time_s: 1_700_000_000.0 + 0.25 * k as f64,
                fix: Some(GnssFix {
                    position: Geodetic::try_new(
                        g.random_range(-89.9..89.9),
                        g.random_range(-179.9..179.9),
                        g.random_range(-100.0..3000.0),
                    )
                    .unwrap(),
                    quality: GPX_QUALITY_GPS,
                    hdop: Some(g.random_range(0.5..3.0)),
                    num_sats: Some(g.random_range(4..20)),
                }),
                heading_deg: None,
            })
            .collect()
    }

    /// Writes records as a GPX 1.1 track with the `gpx` crate.
    fn to_gpx(records: &[GnssRecord]) -> String {
        let mut segment = gpx::TrackSegment::new();
        for r in records {
            let f = r.fix.unwrap();
            let mut p = gpx::Waypoint::new((f.position.lon_deg, f.position.lat_deg).into());
            p.elevation = Some(f.position.alt_m);
            let secs = r.time_s.floor();
            let nanos = ((r.time_s - secs) * 1e9).round() as i128;
            let t = time::OffsetDateTime::from_unix_timestamp_nanos(
                secs as i128 * 1_000_000_000 + nanos,
            )
            .unwrap();
            p.time = Some(t.into());
            p.hdop = f.hdop;
            p.sat = f.num_sats.map(u64::from);
            segment.points.push(p);
        }
        let mut track = gpx::Track::new();
        track.segments.push(segment);
        let doc = gpx::Gpx {
            version: gpx::GpxVersion::Gpx11,
            creator: Some("test".into()),
            tracks: vec![track],
            ..gpx::Gpx::default()
        };
        let mut bytes = Vec::new();
        gpx::write(&doc, &mut bytes).unwrap();
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn round_trip_through_the_gpx_crate() {
        let records = random_records(150, 5);
        let text = to_gpx(&records);
        let (back, stats) = read_gpx(Path::new("t.gpx"), &text).unwrap();
        assert_eq!((back.len(), stats.fixes, stats.skipped()), (150, 150, 0));
        for (a, b) in records.iter().zip(&back) {
            let (x, y) = (a.fix.unwrap(), b.fix.unwrap());
            assert!((a.time_s - b.time_s).abs() < 1e-6);
            assert!((x.position.lat_deg - y.position.lat_deg).abs() < 1e-9);
            assert!((x.position.lon_deg - y.position.lon_deg).abs() < 1e-9);
            assert!((x.position.alt_m - y.position.alt_m).abs() < 1e-9);
            assert_eq!(x.num_sats, y.num_sats);
            assert!((x.hdop.unwrap() - y.hdop.unwrap()).abs() < 1e-9);
        }
    }

    const HEAD: &str = "<?xml version=\"1.0\"?>\n<gpx version=\"1.0\" creator=\"t\" xmlns=\"http://www.topografix.com/GPX/1/0\">\n<trk><trkseg>\n";
    const TAIL: &str = "</trkseg></trk>\n</gpx>\n";

    fn doc(points: &str) -> String {
        format!("{HEAD}{points}{TAIL}")
    }

    #[test]
    fn gpx_1_0_with_invalid_points_counted() {
        let text = doc(concat!(
            "<trkpt lat=\"10\" lon=\"20\"><ele>5</ele><time>2024-01-01T00:00:01Z</time><fix>dgps</fix></trkpt>\n",
            "<trkpt lat=\"95\" lon=\"20\"><ele>5</ele><time>2024-01-01T00:00:02Z</time></trkpt>\n",
            "<trkpt lat=\"10\" lon=\"inf\"><time>2024-01-01T00:00:03Z</time></trkpt>\n",
            "<trkpt lat='10' lon='180'><ele>NaN</ele><time>2024-01-01T00:00:04Z</time></trkpt>\n",
            "<trkpt lat=\"10\" lon=\"180\"><ele>7</ele><geoidheight>-30</geoidheight><time>2024-01-01T00:00:05+01:00</time></trkpt>\n",
            "<trkpt lat=\"10\" lon=\"21\"><time>2024-01-01T00:00:06Z</time><fix>none</fix></trkpt>\n",
            "<trkpt lat=\"10\" lon=\"22\"/>\n",
            "<trkpt lat=\"11\" lon=\"23\"><time>2024-01-01T00:00:07Z</time></trkpt>\n",
        ));
        let (records, stats) = read_gpx(Path::new("t.gpx"), &text).unwrap();
        assert_eq!(stats.entries, 8);
        assert_eq!(stats.invalid_position, 3);
        assert_eq!((stats.untimed, stats.no_fix, stats.fixes), (1, 1, 3));
        assert_eq!(stats.no_elevation, 1);
        assert!(stats.messages[0].starts_with("line 5: point 1: latitude 95"));
        assert!(stats.messages[1].starts_with("line 6: point 2: longitude inf"));
        // Sorted by time: the +01:00 point is an hour earlier.
        let t0 = 1_704_067_200.0;
        let times: Vec<f64> = records.iter().map(|r| r.time_s).collect();
        assert_eq!(times, [t0 + 5.0 - 3600.0, t0 + 1.0, t0 + 6.0, t0 + 7.0]);
        assert_eq!(records[3].fix.unwrap().position.alt_m, 0.0);
        let first = records[0].fix.unwrap();
        assert_eq!(first.position.lon_deg.abs(), 180.0);
        assert_eq!(first.position.alt_m, 7.0 - 30.0);
        assert_eq!(records[1].fix.unwrap().quality, GPX_QUALITY_DGPS);
        assert!(records[2].fix.is_none());
    }

    #[test]
    fn malformed_documents_are_errors_naming_file_and_point() {
        let e = read_gpx(
            Path::new("a.gpx"),
            &doc("<trkpt lat=\"1\" lon=\"2\"></trkpt>\n<trkpt lat=\"x\" lon=\"2\"></trkpt>\n"),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.gpx:5: point 1: `lat` = `x` is not a number"
        );
        let e = read_gpx(Path::new("a.gpx"), &doc("<trkpt lon=\"2\"></trkpt>\n")).unwrap_err();
        assert!(matches!(
            e,
            GnssFileError::Gpx {
                line: Some(4),
                point: Some(0),
                ..
            }
        ));
        let e = read_gpx(Path::new("b.gpx"), "<gpx><trk><trkseg><trkpt").unwrap_err();
        assert!(e.to_string().starts_with("b.gpx: "), "{e}");
        let e = read_gpx(Path::new("c.gpx"), "not xml at all").unwrap_err();
        assert!(e.to_string().starts_with("c.gpx: "), "{e}");
        let e = read_gpx(
            Path::new("d.gpx"),
            &doc("<trkpt lat=\"1\" lon=\"2\"><time>yesterday</time></trkpt>\n"),
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("d.gpx: "), "{e}");
    }

    #[test]
    fn attribute_parser() {
        assert_eq!(attribute(" lat=\"1\" lon='2'", "lon"), Some(("2", 14, 15)));
        assert_eq!(
            attribute(" xlat=\"1\" lat = \"3\"", "lat").map(|a| a.0),
            Some("3")
        );
        assert_eq!(attribute(" lat", "lat"), None);
    }
}
