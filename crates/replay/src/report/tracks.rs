//! Track files: GeoJSON (RFC 7946), KML 2.2 and GPX 1.1.

use super::csv_out::{ANGLE_DECIMALS, LATLON_DECIMALS, METRE_DECIMALS, fmt_opt};
use super::derived::{derive, finite, runs};
use super::time::utc_iso8601;
use super::{DriveInfo, FrameOutcome};
use serde_json::{Map, Value, json};
use std::fmt::Write;
use vgps_geometry::geo::Geodetic;

/// The three tracks: name, position getter, KML colour (`aabbggrr`).
type Getter = fn(&FrameOutcome) -> Option<&Geodetic>;
const TRACKS: [(&str, Getter, &str); 3] = [
    (
        "visual",
        |r| r.visual.as_ref().map(|v| &v.geodetic),
        "ff2020e0",
    ),
    ("gnss", |r| r.gnss.as_ref(), "ffe08020"),
    (
        "truth",
        |r| r.truth.as_ref().map(|t| &t.geodetic),
        "ff20b020",
    ),
];

/// `x` rounded to `decimals` decimals as a JSON number (`null` if not finite).
fn jnum(x: f64, decimals: i32) -> Value {
    let s = 10f64.powi(decimals);
    finite(x)
        .map(|v| json!((v * s).round() / s + 0.0))
        .unwrap_or(Value::Null)
}

fn position(g: &Geodetic) -> Value {
    json!([
        jnum(g.lon_deg, LATLON_DECIMALS as i32),
        jnum(g.lat_deg, LATLON_DECIMALS as i32),
        jnum(g.alt_m, METRE_DECIMALS as i32)
    ])
}

/// The runs (index ranges) of consecutive records that have a position on `track`.
fn segments(records: &[FrameOutcome], get: Getter) -> Vec<(usize, usize)> {
    runs(records.iter().map(|r| get(r).is_some()))
}

/// `track.geojson`: an RFC 7946 FeatureCollection (positions `[lon, lat, alt]`, WGS84) with
///
/// - one `LineString` per run of ≥ 2 consecutive frames of each track, properties
///   `{"track": "visual"|"gnss"|"truth", "first_frame", "last_frame"}`;
/// - one `Point` per visual fix, properties `frame`, `time_s`, `time` (ISO 8601 UTC),
///   `status`, `heading_deg`, `pitch_deg`, `roll_deg`, `sigma_e_m`, `sigma_n_m`,
///   `sigma_u_m`, `n_landmarks`, `n_surrogates`, `blackout`, and `err_h_m` / `diff_h_m`
///   when truth / satellite exist.
pub fn track_geojson(drive: &DriveInfo, records: &[FrameOutcome]) -> String {
    let geom = derive(drive, records);
    let mut features = Vec::new();
    for (name, get, _) in TRACKS {
        for (a, b) in segments(records, get) {
            if b == a {
                continue;
            }
            let coords: Vec<Value> = records[a..=b]
                .iter()
                .filter_map(|r| get(r).map(position))
                .collect();
            features.push(json!({
                "type": "Feature",
                "properties": {
                    "track": name,
                    "first_frame": records[a].frame,
                    "last_frame": records[b].frame,
                },
                "geometry": {"type": "LineString", "coordinates": coords},
            }));
        }
    }
    for (r, g) in records.iter().zip(&geom) {
        let Some(v) = &r.visual else { continue };
        let mut p = Map::new();
        p.insert("track".into(), json!("visual_fix"));
        p.insert("frame".into(), json!(r.frame));
        p.insert("time_s".into(), jnum(r.time_s, 6));
        p.insert(
            "time".into(),
            utc_iso8601(r.time_s)
                .map(Value::from)
                .unwrap_or(Value::Null),
        );
        p.insert("status".into(), json!(r.status));
        for (k, x, d) in [
            ("heading_deg", v.heading_deg, ANGLE_DECIMALS),
            ("pitch_deg", v.pitch_deg, ANGLE_DECIMALS),
            ("roll_deg", v.roll_deg, ANGLE_DECIMALS),
            ("sigma_e_m", v.sigma_e_m, METRE_DECIMALS),
            ("sigma_n_m", v.sigma_n_m, METRE_DECIMALS),
            ("sigma_u_m", v.sigma_u_m, METRE_DECIMALS),
        ] {
            p.insert(k.into(), jnum(x, d as i32));
        }
        p.insert("n_landmarks".into(), json!(v.n_landmarks));
        p.insert("n_surrogates".into(), json!(v.n_surrogates));
        p.insert("blackout".into(), json!(g.blackout));
        if let Some(d) = g.visual_vs_truth {
            p.insert("err_h_m".into(), jnum(d.h, METRE_DECIMALS as i32));
        }
        if let Some(d) = g.visual_vs_gnss {
            p.insert("diff_h_m".into(), jnum(d.h, METRE_DECIMALS as i32));
        }
        features.push(json!({
            "type": "Feature",
            "properties": Value::Object(p),
            "geometry": {"type": "Point", "coordinates": position(&v.geodetic)},
        }));
    }
    let fc = json!({
        "type": "FeatureCollection",
        "name": drive.name,
        "features": features,
    });
    let mut s = serde_json::to_string(&fc).unwrap_or_default();
    s.push('\n');
    s
}

/// Escapes `&`, `<`, `>`, `"` and `'` for XML text and attributes.
pub(crate) fn xml_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            // Control characters are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

fn kml_coord(g: &Geodetic) -> String {
    format!(
        "{},{},{}",
        fmt_opt(Some(g.lon_deg), LATLON_DECIMALS),
        fmt_opt(Some(g.lat_deg), LATLON_DECIMALS),
        fmt_opt(Some(g.alt_m), METRE_DECIMALS)
    )
}

/// `track.kml`: a KML 2.2 Document with one Style per track, a Folder per track holding a
/// `LineString` Placemark per run of consecutive frames (`clampToGround`: the heights are
/// ellipsoidal, not above the terrain), and a Folder `fixes` with one `Point` Placemark per
/// visual fix (name = frame, `TimeStamp`, a description with status, heading, σ and
/// landmark counts). Coordinates are `lon,lat,alt`.
pub fn track_kml(drive: &DriveInfo, records: &[FrameOutcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n<name>{}</name>",
        xml_escape(&drive.name)
    );
    for (name, _, colour) in TRACKS {
        let _ = writeln!(
            s,
            "<Style id=\"{name}\"><LineStyle><color>{colour}</color><width>3</width></LineStyle>\
             <IconStyle><color>{colour}</color><scale>0.5</scale></IconStyle></Style>"
        );
    }
    for (name, get, _) in TRACKS {
        let segs: Vec<_> = segments(records, get)
            .into_iter()
            .filter(|(a, b)| b > a)
            .collect();
        if segs.is_empty() {
            continue;
        }
        let _ = writeln!(s, "<Folder>\n<name>{name}</name>");
        for (a, b) in segs {
            let coords: Vec<String> = records[a..=b]
                .iter()
                .filter_map(|r| get(r).map(kml_coord))
                .collect();
            let _ = writeln!(
                s,
                "<Placemark><name>{name} {}-{}</name><styleUrl>#{name}</styleUrl>\
                 <LineString><tessellate>1</tessellate><altitudeMode>clampToGround</altitudeMode>\
                 <coordinates>{}</coordinates></LineString></Placemark>",
                records[a].frame,
                records[b].frame,
                coords.join(" ")
            );
        }
        s.push_str("</Folder>\n");
    }
    if records.iter().any(|r| r.visual.is_some()) {
        s.push_str("<Folder>\n<name>fixes</name>\n");
        for r in records {
            let Some(v) = &r.visual else { continue };
            let when = utc_iso8601(r.time_s)
                .map(|t| format!("<TimeStamp><when>{t}</when></TimeStamp>"))
                .unwrap_or_default();
            let desc = format!(
                "status {}; heading {} deg; sigma e/n/u {}/{}/{} m; landmarks {}; surrogates {}",
                r.status,
                fmt_opt(Some(v.heading_deg), 2),
                fmt_opt(Some(v.sigma_e_m), 3),
                fmt_opt(Some(v.sigma_n_m), 3),
                fmt_opt(Some(v.sigma_u_m), 3),
                v.n_landmarks,
                v.n_surrogates
            );
            let _ = writeln!(
                s,
                "<Placemark><name>{}</name>{when}<description>{}</description>\
                 <styleUrl>#visual</styleUrl><Point><coordinates>{}</coordinates></Point>\
                 </Placemark>",
                r.frame,
                xml_escape(&desc),
                kml_coord(&v.geodetic)
            );
        }
        s.push_str("</Folder>\n");
    }
    s.push_str("</Document>\n</kml>\n");
    s
}

/// `x` rounded to `decimals` decimals (`-0` becomes `0`), so that the `gpx` writer's
/// shortest round-trip form of an `f64` prints at most `decimals` decimals; `None` if not
/// finite.
fn rounded(x: f64, decimals: usize) -> Option<f64> {
    let s = 10f64.powi(decimals as i32);
    finite(x).map(|v| (v * s).round() / s + 0.0)
}

/// Unix seconds as a GPX time, rounded to the millisecond like every time of the report;
/// `None` for a time that is not finite or that ISO 8601's four-digit years cannot write.
fn gpx_time(time_s: f64) -> Option<gpx::Time> {
    const MAX_ABS_TIME_S: f64 = 1e12;
    if !time_s.is_finite() || time_s.abs() > MAX_ABS_TIME_S {
        return None;
    }
    let ms = (time_s * 1e3).round() as i128;
    let t = gpx::Time::from(time::OffsetDateTime::from_unix_timestamp_nanos(ms * 1_000_000).ok()?);
    // The writer formats with ISO 8601's four-digit years: leave out what it cannot write.
    t.format().is_ok().then_some(t)
}

/// A GPX track point at `g` (lat/lon to 9 decimals, `ele` to the millimetre); `None` when
/// the position is not finite.
fn gpx_point(g: &Geodetic, time_s: f64) -> Option<gpx::Waypoint> {
    let lat = rounded(g.lat_deg, LATLON_DECIMALS)?;
    let lon = rounded(g.lon_deg, LATLON_DECIMALS)?;
    let mut p = gpx::Waypoint::new((lon, lat).into());
    p.elevation = rounded(g.alt_m, METRE_DECIMALS);
    p.time = gpx_time(time_s);
    Some(p)
}

/// The GPX document of [`track_gpx`].
fn gpx_document(drive: &DriveInfo, records: &[FrameOutcome]) -> gpx::Gpx {
    // XML 1.0 allows no control characters but tab and line breaks.
    let name: String = drive
        .name
        .chars()
        .map(|c| match c {
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => ' ',
            c => c,
        })
        .collect();
    let mut tracks = Vec::new();
    for (track_name, get, _) in TRACKS {
        let segments: Vec<gpx::TrackSegment> = segments(records, get)
            .into_iter()
            .map(|(a, b)| {
                let mut seg = gpx::TrackSegment::new();
                seg.points = records[a..=b]
                    .iter()
                    .filter_map(|r| {
                        let mut p = gpx_point(get(r)?, r.time_s)?;
                        if track_name == "visual"
                            && let Some(v) = &r.visual
                        {
                            p.sat = u64::try_from(v.n_landmarks + v.n_surrogates).ok();
                        }
                        Some(p)
                    })
                    .collect();
                seg
            })
            .filter(|seg| !seg.points.is_empty())
            .collect();
        if segments.is_empty() {
            continue;
        }
        let mut track = gpx::Track::new();
        track.name = Some(track_name.to_owned());
        track.segments = segments;
        tracks.push(track);
    }
    gpx::Gpx {
        version: gpx::GpxVersion::Gpx11,
        creator: Some("vgps".to_owned()),
        metadata: Some(gpx::Metadata {
            name: Some(name),
            time: records.first().and_then(|r| gpx_time(r.time_s)),
            ..gpx::Metadata::default()
        }),
        tracks,
        ..gpx::Gpx::default()
    }
}

/// `track.gpx`: GPX 1.1 (namespace `http://www.topografix.com/GPX/1/1`), written by the
/// [`gpx`] crate, with metadata (name, time of the first frame) and one `trk` per track
/// (`visual`, `gnss`, `truth`), one `trkseg` per run of consecutive frames, each `trkpt`
/// with `lat`/`lon` (9 decimals), `ele` (ellipsoidal height, millimetres), `time` (UTC, to
/// the millisecond) and, for visual fixes, `sat` (landmarks + surrogates).
pub fn track_gpx(drive: &DriveInfo, records: &[FrameOutcome]) -> String {
    let mut bytes = Vec::new();
    // The writer fails only on an I/O error (none: it writes to memory), a version other
    // than 1.0/1.1 or a time it cannot format (`gpx_time` leaves those out).
    match gpx::write(&gpx_document(drive, records), &mut bytes) {
        Ok(()) => {
            let mut s = String::from_utf8(bytes).unwrap_or_default();
            s.push('\n');
            s
        }
        Err(_) => String::new(),
    }
}
