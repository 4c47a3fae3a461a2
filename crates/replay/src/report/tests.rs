//! Tests of the report module: known answers, round trips, determinism, atomicity, NaN.

use super::*;
use nalgebra::{Matrix2, Vector3};
use vgps_geometry::geo::LocalFrame;

const T0: f64 = 1_700_000_000.0; // 2023-11-14T22:13:20Z

fn origin() -> Geodetic {
    Geodetic::try_new(48.137_154, 11.576_124, 520.0).unwrap()
}

fn at(e: f64, n: f64, u: f64) -> Geodetic {
    LocalFrame::new(origin())
        .try_to_geodetic(&Vector3::new(e, n, u))
        .unwrap()
}

fn drive() -> DriveInfo {
    DriveInfo {
        name: "test <drive> & co".into(),
        origin: origin(),
    }
}

fn fix(g: Geodetic, heading_deg: f64, n_landmarks: usize, n_surrogates: usize) -> VisualFix {
    VisualFix {
        geodetic: g,
        heading_deg,
        pitch_deg: 1.5,
        roll_deg: -0.5,
        enu_from_rig: nalgebra::UnitQuaternion::identity(),
        sigma_e_m: 1.0,
        sigma_n_m: 1.0,
        sigma_u_m: 2.0,
        horizontal_covariance_m2: Matrix2::identity(),
        pose_covariance: nalgebra::Matrix6::from_diagonal(&nalgebra::Vector6::new(
            1.0, 1.0, 4.0, 1e-6, 1e-6, 1e-6,
        )),
        n_landmarks,
        n_surrogates,
    }
}

/// Ten frames along the east axis (10 m apart); the visual fix of frame i is (i + 1) m
/// east and 2 m above the truth; the satellite is exact except in frames 3–5 and 8
/// (blackout); every frame has a fix; the true heading turns from 359° to 350°.
fn known_records() -> Vec<FrameOutcome> {
    (0..10u64)
        .map(|i| {
            let x = 10.0 * i as f64;
            let gnss_missing = matches!(i, 3..=5 | 8);
            FrameOutcome {
                frame: 100 + i,
                time_s: T0 + 0.5 * i as f64,
                status: "ok".into(),
                visual: Some(fix(at(x + (i + 1) as f64, 0.0, 2.0), 1.0, 5, 0)),
                gnss: (!gnss_missing).then(|| at(x, 0.0, 0.0)),
                unusable_images: None,
                truth: Some(Truth {
                    geodetic: at(x, 0.0, 0.0),
                    heading_deg: 359.0 - i as f64,
                }),
                message: String::new(),
            }
        })
        .collect()
}

#[test]
fn statistics_known_answers() {
    let r = Report::compute(&drive(), &known_records());
    assert_eq!(r.frames, 10);
    assert_eq!(r.visual_fix_rate, Some(1.0));
    let v = r.visual_vs_truth.as_ref().unwrap();
    assert_eq!(v.n, 10);
    // Errors 1, 2, …, 10 m: nearest rank ⌈0.5·10⌉ = 5th, ⌈0.95·10⌉ = 10th.
    let h = &v.horizontal_m;
    assert!((h.cep50 - 5.0).abs() < 1e-6, "{h:?}");
    assert!((h.cep95 - 10.0).abs() < 1e-6);
    assert!((h.max - 10.0).abs() < 1e-6);
    assert!((h.rms - 38.5f64.sqrt()).abs() < 1e-6);
    assert!((v.vertical_rms_m - 2.0).abs() < 1e-6);
    let g = r.gnss_vs_truth.as_ref().unwrap();
    assert_eq!(g.n, 6);
    assert!(g.horizontal_m.max < 1e-6);
    let vg = r.visual_vs_gnss.as_ref().unwrap();
    assert_eq!(vg.n, 6);
    // Frames 0, 1, 2, 6, 7, 9: errors 1, 2, 3, 7, 8, 10 → 3rd = 3, 6th = 10.
    assert!((vg.horizontal_m.cep50 - 3.0).abs() < 1e-6);
    assert!((vg.horizontal_m.cep95 - 10.0).abs() < 1e-6);
    // Heading: 1° against 359°, 358°, …, 350°: |errors| 2, 3, …, 11 → 5th = 6.
    assert!((r.heading_error_median_deg.unwrap() - 6.0).abs() < 1e-9);
    // Identity covariance: inside when e² ≤ 5.99, i.e. errors 1 and 2 m.
    let c = r.covariance_consistency.as_ref().unwrap();
    assert_eq!((c.n, c.inside_95), (10, 2));
    assert!((c.fraction_inside_95 - 0.2).abs() < 1e-12);
    assert_eq!(r.status_counts.get("ok"), Some(&10));
    assert!(r.surrogate_drift.is_none());
}

#[test]
fn blackout_split() {
    let r = Report::compute(&drive(), &known_records());
    let b = &r.blackout;
    assert_eq!(b.frames, 4);
    assert_eq!(b.stretches, vec![[103, 105], [108, 108]]);
    assert_eq!(b.visual_fix_rate, Some(1.0));
    let v = b.visual_vs_truth.as_ref().unwrap();
    // Blackout errors 4, 5, 6, 9 m.
    assert_eq!(v.n, 4);
    assert!((v.horizontal_m.cep50 - 5.0).abs() < 1e-6);
    assert!((v.horizontal_m.cep95 - 9.0).abs() < 1e-6);
    assert!((v.horizontal_m.rms - ((16.0 + 25.0 + 36.0 + 81.0) / 4.0f64).sqrt()).abs() < 1e-6);
    assert!(b.gnss_vs_truth.is_none() && b.visual_vs_gnss.is_none());
}

#[test]
fn quantile_convention() {
    let d: Vec<f64> = (1..=20).map(f64::from).collect();
    assert_eq!(quantile_nearest_rank(&d, 0.5), Some(10.0));
    assert_eq!(quantile_nearest_rank(&d, 0.95), Some(19.0));
    assert_eq!(quantile_nearest_rank(&d, 1.0), Some(20.0));
    assert_eq!(quantile_nearest_rank(&[3.0], 0.95), Some(3.0));
    assert_eq!(quantile_nearest_rank(&[f64::NAN, 1.0], 0.5), Some(1.0));
    assert_eq!(quantile_nearest_rank(&d, 1.5), None);
}

/// Frames 0 (anchored, 5 landmarks), 1–4 surrogate-only with an error of 10 % of the
/// distance travelled since frame 0, 5 without fix, 6–7 surrogate-only again.
fn drift_records() -> Vec<FrameOutcome> {
    (0..8u64)
        .map(|i| {
            let x = 20.0 * i as f64;
            let visual = match i {
                0 => Some(fix(at(0.0, 0.0, 0.0), 90.0, 5, 0)),
                5 => None,
                _ => Some(fix(at(x, 0.1 * x, 0.0), 90.0, 1, 4)),
            };
            FrameOutcome {
                frame: i,
                time_s: T0 + i as f64,
                status: if visual.is_some() { "ok" } else { "no_fix" }.into(),
                visual,
                gnss: None,
                unusable_images: None,
                truth: Some(Truth {
                    geodetic: at(x, 0.0, 0.0),
                    heading_deg: 90.0,
                }),
                message: String::new(),
            }
        })
        .collect()
}

#[test]
fn surrogate_drift_ratio() {
    let r = Report::compute(&drive(), &drift_records());
    let d = r.surrogate_drift.as_ref().unwrap();
    assert_eq!(d.frames, 6);
    assert_eq!(d.n, 6);
    assert!((d.median_error_per_distance.unwrap() - 0.1).abs() < 1e-6);
    assert!((d.max_error_per_distance.unwrap() - 0.1).abs() < 1e-6);
    assert_eq!(d.stretches.len(), 2);
    let s = &d.stretches[1];
    assert_eq!(
        (s.first_frame, s.last_frame, s.anchor_frame),
        (6, 7, Some(0))
    );
    assert!((s.distance_m.unwrap() - 140.0).abs() < 1e-6);
    assert!((s.error_h_m.unwrap() - 14.0).abs() < 1e-6);
    assert_eq!(r.status_counts.get("no_fix"), Some(&1));
    assert!((r.visual_fix_rate.unwrap() - 7.0 / 8.0).abs() < 1e-12);
}

/// Records with gaps and non-finite values: a NaN sigma and heading, a no-fix frame,
/// a frame without satellite and without truth.
fn awkward_records() -> Vec<FrameOutcome> {
    let mut rs = known_records();
    if let Some(v) = rs[2].visual.as_mut() {
        v.sigma_e_m = f64::NAN;
        v.heading_deg = f64::INFINITY;
        v.horizontal_covariance_m2 = Matrix2::new(f64::NAN, 0.0, 0.0, 1.0);
    }
    rs[4].visual = None;
    rs[4].status = "bad_image".into();
    // A message with the characters CSV quotes, and a line break that must not split the row.
    rs[4].message = "camera 2: \"000004_2.png\", not a PNG,\nJPEG or TIFF file".into();
    rs[6].truth = None;
    rs[6].gnss = None;
    rs
}

#[test]
fn csv_round_trip() {
    let recs = awkward_records();
    let text = fixes_csv(&drive(), &recs);
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
    let expected: Vec<&str> = FIXES_COLUMNS
        .iter()
        .chain(&TRUTH_COLUMNS)
        .copied()
        .chain([MESSAGE_COLUMN])
        .collect();
    assert_eq!(header, expected);
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), recs.len());
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    for (row, r) in rows.iter().zip(&recs) {
        assert_eq!(row[col("frame")].parse::<u64>().unwrap(), r.frame);
        assert!((row[col("time_s")].parse::<f64>().unwrap() - r.time_s).abs() < 1e-6);
        match &r.visual {
            Some(v) => {
                let lat: f64 = row[col("lat")].parse().unwrap();
                let lon: f64 = row[col("lon")].parse().unwrap();
                assert!((lat - v.geodetic.lat_deg).abs() <= 5e-10);
                assert!((lon - v.geodetic.lon_deg).abs() <= 5e-10);
                assert_eq!(row[col("lat")].split('.').nth(1).unwrap().len(), 9);
            }
            None => assert!(row[col("lat")].is_empty() && row[col("n_landmarks")].is_empty()),
        }
        assert_eq!(row[col("gnss_lat")].is_empty(), r.gnss.is_none());
        assert_eq!(row[col("truth_lat")].is_empty(), r.truth.is_none());
    }
    // Non-finite values are empty, and the error column matches the statistics.
    assert!(rows[2][col("sigma_e_m")].is_empty());
    assert!(rows[2][col("heading_deg")].is_empty());
    assert!(rows[2][col("err_heading_deg")].is_empty());
    assert_eq!(&rows[0][col("err_h_m")], "1.000");
    assert_eq!(&rows[0][col("err_v_m")], "2.000");
    assert_eq!(&rows[4][col("status")], "bad_image");
    assert_eq!(
        &rows[4][col("message")],
        "camera 2: \"000004_2.png\", not a PNG, JPEG or TIFF file"
    );
    assert_eq!(text.lines().count(), recs.len() + 1, "one line per frame");
    assert!(rows[0][col("message")].is_empty());
    // Without any truth the truth columns are absent.
    let no_truth: Vec<FrameOutcome> = recs
        .into_iter()
        .map(|mut r| {
            r.truth = None;
            r
        })
        .collect();
    let first = fixes_csv(&drive(), &no_truth)
        .lines()
        .next()
        .unwrap()
        .to_string();
    assert_eq!(
        first,
        format!("{},{MESSAGE_COLUMN}", FIXES_COLUMNS.join(","))
    );
}

#[test]
fn geojson_round_trip() {
    let recs = awkward_records();
    let text = track_geojson(&drive(), &recs);
    let gj: geojson::GeoJson = text.parse().unwrap();
    let fc = geojson::FeatureCollection::try_from(gj).unwrap();
    let lines: Vec<_> = fc
        .features
        .iter()
        .filter(|f| {
            matches!(
                f.geometry.as_ref().unwrap().value,
                geojson::GeometryValue::LineString { .. }
            )
        })
        .collect();
    let points: Vec<_> = fc
        .features
        .iter()
        .filter_map(|f| match &f.geometry.as_ref().unwrap().value {
            geojson::GeometryValue::Point { coordinates: p } => Some((f, p.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(
        points.len(),
        recs.iter().filter(|r| r.visual.is_some()).count()
    );
    // visual: runs 0–3 and 5–9; gnss: 0–2, 7; truth: 0–5, 7–9 (runs of one point dropped).
    assert_eq!(lines.len(), 2 + 1 + 2);
    let with_fix: Vec<&FrameOutcome> = recs.iter().filter(|r| r.visual.is_some()).collect();
    for ((f, p), r) in points.iter().zip(&with_fix) {
        let g = r.visual.as_ref().unwrap().geodetic;
        assert!((p[0] - g.lon_deg).abs() < 1e-9 && (p[1] - g.lat_deg).abs() < 1e-9);
        assert!((p[2] - g.alt_m).abs() < 1e-3);
        let props = f.properties.as_ref().unwrap();
        assert_eq!(props["frame"], serde_json::json!(r.frame));
    }
    // Heading of frame 2 is infinite: null, never NaN.
    assert!(!text.contains("NaN") && !text.contains("inf"));
}

/// The GPX tracks read back with `gpx::read`: per track, per segment, the frames' positions
/// (to the written 9 decimals of a degree and 1 mm), times (to the ms) and `sat`.
#[test]
fn gpx_round_trip() {
    let mut recs = known_records();
    // Sub-millisecond times round to the millisecond; a time past year 9999 is left out.
    recs[1].time_s = T0 + 0.500_4;
    recs[2].time_s = T0 + 0.999_6;
    recs[9].time_s = 3e11;
    recs[4].visual.as_mut().unwrap().n_surrogates = 2;
    let text = track_gpx(&drive(), &recs);
    let gpx = gpx::read(text.as_bytes()).unwrap();
    assert_eq!(gpx.version, gpx::GpxVersion::Gpx11);
    assert_eq!(gpx.creator.as_deref(), Some("vgps"));
    let meta = gpx.metadata.as_ref().unwrap();
    assert_eq!(meta.name.as_deref(), Some("test <drive> & co"));
    let t0: ::time::OffsetDateTime = meta.time.unwrap().into();
    assert_eq!(t0.unix_timestamp_nanos(), T0 as i128 * 1_000_000_000);
    let names: Vec<_> = gpx.tracks.iter().map(|t| t.name.clone().unwrap()).collect();
    assert_eq!(names, ["visual", "gnss", "truth"]);
    // The satellite track is split by the blackouts into 0–2, 6–7, 9.
    let runs = |t: usize| -> Vec<usize> {
        gpx.tracks[t]
            .segments
            .iter()
            .map(|s| s.points.len())
            .collect()
    };
    assert_eq!(
        (runs(0), runs(1), runs(2)),
        (vec![10], vec![3, 2, 1], vec![10])
    );
    type Get = fn(&FrameOutcome) -> Option<Geodetic>;
    let getters: [Get; 3] = [
        |r| r.visual.as_ref().map(|v| v.geodetic),
        |r| r.gnss,
        |r| r.truth.as_ref().map(|t| t.geodetic),
    ];
    for (track, get) in gpx.tracks.iter().zip(getters) {
        let points = track.segments.iter().flat_map(|s| &s.points);
        let written: Vec<&FrameOutcome> = recs.iter().filter(|r| get(r).is_some()).collect();
        assert_eq!(points.clone().count(), written.len());
        for (p, r) in points.zip(written) {
            let g = get(r).unwrap();
            assert!((p.point().y() - g.lat_deg).abs() <= 5e-10, "{p:?}");
            assert!((p.point().x() - g.lon_deg).abs() <= 5e-10, "{p:?}");
            assert!((p.elevation.unwrap() - g.alt_m).abs() <= 5e-4, "{p:?}");
            match p.time {
                Some(t) => {
                    let ns = ::time::OffsetDateTime::from(t).unix_timestamp_nanos();
                    assert_eq!(ns, (r.time_s * 1e3).round() as i128 * 1_000_000, "{p:?}");
                }
                None => assert_eq!(r.time_s, 3e11, "{p:?}"),
            }
            let sat = r
                .visual
                .as_ref()
                .map(|v| (v.n_landmarks + v.n_surrogates) as u64);
            assert_eq!(
                p.sat,
                if track.name.as_deref() == Some("visual") {
                    sat
                } else {
                    None
                }
            );
        }
    }
    let pts = &gpx.tracks[0].segments[0].points;
    assert_eq!(pts[4].sat, Some(7));
    let t = pts[1].time.unwrap().format().unwrap();
    assert_eq!(t, "2023-11-14T22:13:20.500000000Z");
    assert_eq!(
        pts[2].time.unwrap().format().unwrap(),
        "2023-11-14T22:13:21.000000000Z"
    );
    // Written with at most 9 decimals of a degree and 3 of a metre.
    for line in text.lines().filter(|l| l.contains("<trkpt")) {
        for attr in ["lat=\"", "lon=\""] {
            let v = line.split(attr).nth(1).unwrap().split('"').next().unwrap();
            assert!(v.split('.').nth(1).is_none_or(|d| d.len() <= 9), "{line}");
        }
    }
    for ele in text.split("<ele>").skip(1) {
        let v = ele.split('<').next().unwrap();
        assert!(v.split('.').nth(1).is_none_or(|d| d.len() <= 3), "{v}");
    }
}

#[test]
fn nmea_checksums_and_round_trip() {
    let mut recs = drift_records();
    recs[3].time_s = T0 + 86_399.0; // crosses into the next day
    let text = fixes_nmea(&recs);
    let mut counts = std::collections::BTreeMap::new();
    for line in text.split_terminator("\r\n") {
        assert!(line.len() <= 82, "{line}");
        let (body, cs) = line[1..].split_once('*').unwrap();
        assert_eq!(nmea_checksum(body), cs);
        if let Some(fields) = line.strip_prefix("$GPGBS,") {
            // The `nmea` crate wants every GBS field; receivers leave the fault-detection
            // fields empty, as vgps does: read the σ here.
            let f: Vec<&str> = fields.split(['*', ',']).collect();
            assert_eq!(
                &f[1..8],
                ["1.000", "1.000", "2.000", "", "", "", ""],
                "{line}"
            );
            *counts.entry("GBS").or_insert(0) += 1;
            continue;
        }
        let parsed = ::nmea::parse_str(line).unwrap_or_else(|e| panic!("{line}: {e:?}"));
        let kind = match parsed {
            ::nmea::ParseResult::GGA(g) => {
                if let Some(lat) = g.latitude {
                    assert!(g.fix_satellites.unwrap() >= 5);
                    assert!(lat > 48.0 && lat < 48.2);
                    // A visual fix: quality 1, and no HDOP (not a satellite geometry).
                    assert_eq!(g.fix_type, Some(::nmea::sentences::FixType::Gps));
                    assert_eq!(g.hdop, None);
                }
                "GGA"
            }
            ::nmea::ParseResult::RMC(_) => "RMC",
            ::nmea::ParseResult::GST(g) => {
                // σ 1 m east and north, 2 m up: a circle of 1 m.
                assert_eq!(
                    (g.lat_sd, g.long_sd, g.alt_sd),
                    (Some(1.0), Some(1.0), Some(2.0))
                );
                assert_eq!(g.ellipse_semi_major_sd, Some(1.0));
                assert_eq!(g.ellipse_semi_minor_sd, Some(1.0));
                assert_eq!(g.rms_sd, None);
                "GST"
            }
            ::nmea::ParseResult::HDT(h) => {
                assert_eq!(h.heading, Some(90.0));
                "HDT"
            }
            other => panic!("unexpected {other:?}"),
        };
        *counts.entry(kind).or_insert(0) += 1;
    }
    // 8 frames: GGA and RMC for each, GST, GBS and HDT for the 7 fixes.
    assert_eq!(counts.get("GGA"), Some(&8));
    assert_eq!(counts.get("RMC"), Some(&8));
    assert_eq!(counts.get("GST"), Some(&7));
    assert_eq!(counts.get("GBS"), Some(&7));
    assert_eq!(counts.get("HDT"), Some(&7));
    // Exact position of frame 0 (the origin) and the date of frame 3.
    let first = ::nmea::parse_str(text.lines().next().unwrap()).unwrap();
    let ::nmea::ParseResult::GGA(g) = first else {
        panic!()
    };
    assert!((g.latitude.unwrap() - origin().lat_deg).abs() < 1e-7);
    assert!((g.longitude.unwrap() - origin().lon_deg).abs() < 1e-7);
    assert_eq!(g.fix_type, Some(::nmea::sentences::FixType::Gps));
    assert!(
        text.contains(",151123,"),
        "date of the day after 2023-11-14"
    );
    // Speed over ground between frames 1 and 2: 20 m east + 2 m north in 1 s.
    let rmc = text
        .lines()
        .filter(|l| l.starts_with("$GPRMC"))
        .nth(2)
        .unwrap();
    let ::nmea::ParseResult::RMC(m) = ::nmea::parse_str(rmc.trim()).unwrap() else {
        panic!()
    };
    let expected_knots = (20.0f64.powi(2) + 2.0f64.powi(2)).sqrt() / (1852.0 / 3600.0);
    assert!((f64::from(m.speed_over_ground.unwrap()) - expected_knots).abs() < 0.01);
    // Mode A ("autonomous"), as for every visual fix (docs/replay-report.md, `fixes.nmea`).
    assert_eq!(m.faa_mode, Some(::nmea::sentences::FaaMode::Autonomous));
}

/// `report.html` without the vendored Leaflet and the map script (code with words like
/// "Infinity"): the page's text, styles, plots and data.
fn own_part(html: &str) -> String {
    let a = html.find(VENDOR_BEGIN).unwrap();
    let b = html.find(VENDOR_END).unwrap();
    let map_js = include_str!("../../assets/report/map.js");
    let leaflet_css = include_str!("../../assets/leaflet/leaflet.css");
    assert!(html.contains(map_js) && html.contains(leaflet_css));
    format!("{}{}", &html[..a], &html[b..])
        .replace(map_js, "")
        .replace(leaflet_css, "")
}

/// Parses `text` as XML to the end; returns the element names seen.
fn xml_elements(text: &str) -> Vec<String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(text);
    let mut names = Vec::new();
    loop {
        match reader.read_event() {
            Ok(Event::Start(e)) | Ok(Event::Empty(e)) => {
                let name = e.name();
                let name: &str = name.as_ref();
                names.push(name.to_owned())
            }
            Ok(Event::Eof) => break,
            Ok(_) => {}
            Err(e) => panic!("not well-formed at {}: {e}", reader.buffer_position()),
        }
    }
    names
}

#[test]
fn html_and_kml_are_well_formed_and_self_contained() {
    let recs = awkward_records();
    let report = Report::compute(&drive(), &recs);
    let html = report_html(&drive(), &recs, &report);
    let names = xml_elements(&html);
    // The two plotters plots; the map is drawn by the script.
    assert_eq!(names.iter().filter(|n| *n == "svg").count(), 2);
    assert!(names.iter().any(|n| n == "table"));
    assert!(names.iter().filter(|n| *n == "polyline").count() >= 3);
    assert_eq!(names.iter().filter(|n| *n == "script").count(), 4);
    assert!(names.iter().any(|n| n == "div"));
    // Nothing to load: no script or style file, no image, no address outside the vendored
    // library but the opt-in background map's tile template.
    let own = own_part(&html);
    for banned in ["<link", "src=", "href=", "@import", "url("] {
        assert!(!own.contains(banned), "{banned}");
    }
    assert!(!own.contains("https://"));
    // The map script's one address: the opt-in background map's tile template.
    let map_js = include_str!("../../assets/report/map.js");
    assert_eq!(map_js.matches("https://").count(), 1);
    assert!(map_js.contains("'https://tile.openstreetmap.org/"));
    assert!(html.contains("test &lt;drive&gt; &amp; co"));
    // The drive name is in the data too, safe inside the script.
    assert!(html.contains("\\u003cdrive\\u003e"));
    let kml = track_kml(&drive(), &recs);
    let names = xml_elements(&kml);
    assert_eq!(names[0], "kml");
    assert!(names.iter().filter(|n| *n == "Style").count() == 3);
    assert_eq!(
        names.iter().filter(|n| *n == "Point").count(),
        recs.iter().filter(|r| r.visual.is_some()).count()
    );
    assert!(names.iter().any(|n| n == "LineString"));
    xml_elements(&track_gpx(&drive(), &recs));
}

#[test]
fn no_nan_anywhere() {
    let recs = awkward_records();
    let d = drive();
    let report = Report::compute(&d, &recs);
    let json = report.to_json();
    let texts = [
        fixes_csv(&d, &recs),
        json.clone(),
        own_part(&report_html(&d, &recs, &report)),
        track_geojson(&d, &recs),
        track_kml(&d, &recs),
        track_gpx(&d, &recs),
        fixes_nmea(&recs),
        summary_table(&report),
    ];
    for t in &texts {
        let lower = t.to_lowercase();
        assert!(!lower.contains("nan") && !lower.contains("inf"), "{t}");
    }
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    for key in [
        "frames",
        "visual_fix_rate",
        "visual_vs_truth",
        "gnss_vs_truth",
        "visual_vs_gnss",
        "blackout",
        "status_counts",
        "heading_error_median_deg",
        "covariance_consistency",
        "surrogate_drift",
    ] {
        assert!(v.get(key).is_some(), "{key}");
    }
    assert_eq!(v["status_counts"]["bad_image"], 1);
    // 10 frames − no fix (4) − no truth (6) − NaN covariance (2) = 7 fixes counted.
    assert_eq!(v["covariance_consistency"]["n"], 7);
    // Empty drive: rates are null, nothing panics.
    let empty = Report::compute(&d, &[]);
    assert_eq!(empty.visual_fix_rate, None);
    assert!(!empty.to_json().contains("NaN"));
    report_html(&d, &[], &empty);
    plot_track_png(&d, &[]).unwrap();
}

fn dir_snapshot(dir: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn outputs_deterministic_and_atomic() {
    let recs = awkward_records();
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a");
    let b = tmp.path().join("b");
    // An existing, longer file is replaced whole.
    std::fs::create_dir_all(&a).unwrap();
    std::fs::write(a.join("report.json"), vec![b'x'; 1_000_000]).unwrap();
    let (report, written) = write_outputs(&a, &drive(), &recs).unwrap();
    write_outputs(&b, &drive(), &recs).unwrap();
    assert_eq!(written.len(), OUTPUT_FILES.len());
    let sa = dir_snapshot(&a);
    let sb = dir_snapshot(&b);
    assert_eq!(sa, sb, "two runs give byte-identical files");
    let names: Vec<&str> = sa.iter().map(|(n, _)| n.as_str()).collect();
    let mut expected = OUTPUT_FILES.to_vec();
    expected.sort();
    assert_eq!(names, expected, "no temporary file left");
    let json = std::fs::read_to_string(a.join("report.json")).unwrap();
    assert_eq!(json, report.to_json());
    // Writing again over the same directory gives the same bytes.
    write_outputs(&a, &drive(), &recs).unwrap();
    assert_eq!(dir_snapshot(&a), sb);
    // PNGs decode to the documented size.
    for name in ["track.png", "error.png"] {
        let bytes = std::fs::read(a.join(name)).unwrap();
        let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).unwrap();
        assert_eq!(
            (image.width(), image.height()),
            (PLOT_WIDTH_PX, PLOT_HEIGHT_PX)
        );
    }
    // A failing write names the file and leaves no temporary file.
    let missing = tmp.path().join("no/such/dir/x.json");
    let err = write_atomic(&missing, b"{}").unwrap_err();
    assert!(err.to_string().contains("x.json"));
}

#[test]
fn summary_table_lists_the_figures() {
    let r = Report::compute(&drive(), &known_records());
    let t = summary_table(&r);
    assert!(t.contains("frames 10, visual fixes 10 (100.0%)"), "{t}");
    let row = t
        .lines()
        .find(|l| l.starts_with("visual vs truth"))
        .unwrap();
    let cols: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(
        &cols[3..],
        ["10", "5.000", "10.000", "6.205", "10.000", "2.000"]
    );
    assert!(t.contains("blackout: frames 4, stretches 2"));
}

#[test]
fn html_without_truth_has_no_truth_rows_legend_or_heading_and_keeps_the_headline_row() {
    let mut recs = known_records();
    let with_truth = report_html(&drive(), &recs, &Report::compute(&drive(), &recs));
    // With truth: the headline row first, and the truth layer's checkbox.
    let table =
        &with_truth[with_truth.find("<table>").unwrap()..with_truth.find("</table>").unwrap()];
    let rows: Vec<&str> = table.split("<tr").skip(2).collect();
    assert!(
        rows[0].starts_with(" class=\"headline\"><td>visual vs truth, \u{2265} 3 surveyed</td>"),
        "{table}"
    );
    assert!(with_truth.contains("id=\"vgps-show-truth\""));
    assert!(with_truth.contains("Median heading error"));
    for r in &mut recs {
        r.truth = None;
    }
    let html = report_html(&drive(), &recs, &Report::compute(&drive(), &recs));
    // Everything the page shows before the text summary, but the map's data and scripts.
    let own = own_part(&html);
    let shown = &own[..own.find("<h2>Text summary").unwrap()];
    assert!(!shown.contains("truth"), "{shown}");
    assert!(!shown.contains("heading error"));
    assert!(shown.contains("<td>visual vs satellite</td>"));
    assert!(html.contains("\"has_truth\":false"));
}

/// A latitude, longitude (degrees) and height (metres).
type LatLonAlt = (f64, f64, f64);

/// `fixes.csv`'s rows as (frame, lat, lon, alt), `None` for a row without a visual fix.
fn csv_positions(text: &str) -> Vec<(u64, Option<LatLonAlt>)> {
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let header = rd.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (f, lat, lon, alt) = (col("frame"), col("lat"), col("lon"), col("alt"));
    rd.records()
        .map(|r| {
            let r = r.unwrap();
            let p = (!r[lat].is_empty()).then(|| {
                let v = |k: usize| r[k].parse::<f64>().unwrap();
                (v(lat), v(lon), v(alt))
            });
            (r[f].parse().unwrap(), p)
        })
        .collect()
}

/// `fixes.nmea` and `track.geojson` read back by third-party readers (the `nmea` and
/// `geojson` crates) give the positions of `fixes.csv`, within the files' rounding
/// (NMEA: 10⁻⁷ minute; CSV and GeoJSON: 10⁻⁹ degree; heights: 1 mm).
#[test]
fn nmea_and_geojson_read_back_equal_fixes_csv() {
    let recs = drift_records();
    let csv = csv_positions(&fixes_csv(&drive(), &recs));
    assert_eq!(csv.len(), recs.len());
    assert!(csv.iter().filter(|r| r.1.is_some()).count() >= 5);
    let close = |a: (f64, f64, f64), b: (f64, f64, f64), deg: f64| {
        (a.0 - b.0).abs() <= deg && (a.1 - b.1).abs() <= deg && (a.2 - b.2).abs() <= 1e-3
    };
    // NMEA: every GGA, RMC and GST sentence parses; one GGA and one RMC per CSV row, in
    // order, with the row's position (an empty one for a row without a fix).
    let nmea_text = fixes_nmea(&recs);
    let (mut gga, mut rmc, mut gst) = (Vec::new(), Vec::new(), 0);
    for line in nmea_text.split_terminator("\r\n") {
        if line.starts_with("$GPGBS") || line.starts_with("$GPHDT") {
            continue; // GBS: see nmea_checksums_and_round_trip; HDT carries no position.
        }
        match ::nmea::parse_str(line).unwrap_or_else(|e| panic!("{line}: {e:?}")) {
            ::nmea::ParseResult::GGA(g) => gga.push(
                g.latitude
                    .map(|lat| (lat, g.longitude.unwrap(), f64::from(g.altitude.unwrap()))),
            ),
            ::nmea::ParseResult::RMC(m) => rmc.push(m.lat.map(|lat| (lat, m.lon.unwrap()))),
            ::nmea::ParseResult::GST(_) => gst += 1,
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(gga.len(), csv.len());
    assert_eq!(rmc.len(), csv.len());
    assert_eq!(gst, csv.iter().filter(|r| r.1.is_some()).count());
    let nmea_deg = 0.5e-7 / 60.0 + 0.5e-9 + 1e-12;
    for ((frame, row), (g, m)) in csv.iter().zip(gga.iter().zip(&rmc)) {
        match row {
            Some(p) => {
                let g = g.unwrap_or_else(|| panic!("frame {frame}: GGA without a position"));
                assert!(close(*p, g, nmea_deg), "frame {frame}: {p:?} vs GGA {g:?}");
                let m = m.unwrap();
                assert!(
                    close(*p, (m.0, m.1, p.2), nmea_deg),
                    "frame {frame}: RMC {m:?}"
                );
            }
            None => assert!(g.is_none() && m.is_none(), "frame {frame}"),
        }
    }
    // GeoJSON: a FeatureCollection whose points are the CSV's fixes, by frame.
    let gj: geojson::GeoJson = track_geojson(&drive(), &recs).parse().unwrap();
    let fc = geojson::FeatureCollection::try_from(gj).unwrap();
    let mut points = 0;
    for f in &fc.features {
        let Some(geometry) = &f.geometry else {
            continue;
        };
        let geojson::GeometryValue::Point { coordinates: p } = &geometry.value else {
            continue;
        };
        let frame = f.properties.as_ref().unwrap()["frame"].as_u64().unwrap();
        let row = csv.iter().find(|r| r.0 == frame).unwrap().1.unwrap();
        let q = (p[1], p[0], p[2]);
        assert!(
            close(row, q, 1e-9 + 1e-12),
            "frame {frame}: {row:?} vs {q:?}"
        );
        points += 1;
    }
    assert_eq!(points, csv.iter().filter(|r| r.1.is_some()).count());
}
