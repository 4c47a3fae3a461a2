//! `report.html`: one self-contained, interactive page that is also well-formed XML
//! (XHTML syntax: every element closed, scripts inside CDATA sections).
//!
//! - the summary table (rows without data, truth rows without truth, are left out);
//! - an interactive map drawn by the inlined [Leaflet](https://leafletjs.com/) 1.9.4
//!   (BSD 2-Clause, `assets/leaflet/`): pans and zooms from the whole drive down to
//!   millimetres, every frame's fix coloured by its horizontal σ or by its status, the 95 %
//!   covariance ellipses, the drive's landmarks, and a click on a fix shows its frame;
//! - the horizontal error against time and the error CDFs, drawn with `plotters`' SVG
//!   backend (drawn by [`super::charts`], the same functions as the PNGs);
//! - the text summary.
//!
//! The page asks for nothing over the network unless its reader ticks "online background
//! map"; the scripts, styles, data and plots are all inline.

use super::derived::derive;
use super::plot::{error_cdf_svg, error_vs_time_svg};
use super::stats::{Comparison, Report};
use super::text::summary_table;
use super::time::utc_iso8601;
use super::tracks::xml_escape;
use super::{DriveInfo, FrameOutcome, MIN_SURVEYED_LANDMARKS};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write;

/// The vendored Leaflet script (1.9.4, BSD 2-Clause; see `assets/leaflet/README.md`).
const LEAFLET_JS: &str = include_str!("../../assets/leaflet/leaflet.js");
/// The vendored Leaflet style sheet.
const LEAFLET_CSS: &str = include_str!("../../assets/leaflet/leaflet.css");
/// vgps's map script (reads the global `VGPS`).
const MAP_JS: &str = include_str!("../../assets/report/map.js");

/// Marks the start of the vendored library in the page (tests skip what follows up to
/// [`VENDOR_END`] when they look for "NaN" or network addresses in vgps's own output).
pub const VENDOR_BEGIN: &str = "/* vendored: Leaflet 1.9.4, BSD 2-Clause licence, (c) 2010-2023 Volodymyr Agafonkin, (c) 2010-2011 CloudMade */";
/// Marks the end of the vendored library in the page.
pub const VENDOR_END: &str = "/* end of vendored Leaflet */";

const CSS: &str = "body{font-family:sans-serif;margin:2em auto;max-width:1000px;color:#222;padding:0 1em}\
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:2em}\
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
th:first-child,td:first-child{text-align:left}tr.headline td{font-weight:bold;background:#f4f8ff}\
svg{background:#fff;border:1px solid #ddd;max-width:100%;height:auto}\
pre{background:#f6f6f6;padding:1em;overflow-x:auto}\
#vgps-map{height:600px;border:1px solid #bbb}\
#vgps-controls{margin:.5em 0;font-size:.9em}#vgps-controls label{margin-right:1em}\
#vgps-frame{min-height:8em;border:1px solid #ddd;background:#fafafa;padding:.5em;font-size:.9em;margin-top:.5em}\
#vgps-frame .t{color:#666}.key span{display:inline-block;width:1em;height:1em;vertical-align:middle;margin:0 .3em 0 .8em;border:1px solid #555}";

/// What the report's map shows besides the frames: the drive's surveyed landmarks and, per
/// frame, the ids of the surveyed landmarks its fix used.
#[derive(Clone, Debug, Default)]
pub struct MapExtras {
    /// The drive's surveyed landmarks.
    pub landmarks: Vec<vgps_io::Landmark>,
    /// Frame number → ids of the surveyed landmarks its fix used.
    pub used: BTreeMap<u64, Vec<String>>,
}

fn num(x: Option<f64>, decimals: usize) -> String {
    x.filter(|v| v.is_finite())
        .map(|v| format!("{v:.decimals$}"))
        .unwrap_or_else(|| "&#8211;".into())
}

fn comparison_row(s: &mut String, name: &str, c: &Option<Comparison>, class: &str) {
    let Some(c) = c else { return };
    let h = &c.horizontal_m;
    let _ = writeln!(
        s,
        "<tr{class}><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>",
        xml_escape(name),
        c.n,
        h.cep50,
        h.cep95,
        h.rms,
        h.max,
        c.vertical_rms_m
    );
}

/// A JSON number with `decimals` decimals, `null` when not finite.
fn jnum(s: &mut String, x: f64, decimals: usize) {
    if x.is_finite() {
        let _ = write!(s, "{x:.decimals$}");
    } else {
        s.push_str("null");
    }
}

/// A JSON string safe inside a script element and a CDATA section.
fn jstr(s: &mut String, text: &str) {
    let quoted = serde_json::Value::from(text).to_string();
    s.push_str(
        &quoted
            .replace('<', "\\u003c")
            .replace('>', "\\u003e")
            .replace('&', "\\u0026"),
    );
}

/// `[lat, lon]` with 9 decimals (0.1 mm).
fn jlatlon(s: &mut String, g: &vgps_geometry::geo::Geodetic) {
    s.push('[');
    jnum(s, g.lat_deg, 9);
    s.push(',');
    jnum(s, g.lon_deg, 9);
    s.push(']');
}

/// The map's data: `window.VGPS = {…}` (see `assets/report/map.js` for the row layout).
fn map_data(drive: &DriveInfo, records: &[FrameOutcome], extras: &MapExtras) -> String {
    let mut s = String::from("window.VGPS={\"name\":");
    jstr(&mut s, &drive.name);
    s.push_str(",\"origin\":");
    jlatlon(&mut s, &drive.origin);
    let has_truth = records.iter().any(|r| r.truth.is_some());
    let _ = write!(s, ",\"has_truth\":{has_truth},\"statuses\":[");
    let mut statuses: Vec<&str> = records.iter().map(|r| r.status.as_str()).collect();
    statuses.sort_unstable();
    statuses.dedup();
    for (k, st) in statuses.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        jstr(&mut s, st);
    }
    let status_index: HashMap<&str, usize> = statuses
        .iter()
        .enumerate()
        .map(|(k, st)| (*st, k))
        .collect();
    let landmark_index: HashMap<&str, usize> = extras
        .landmarks
        .iter()
        .enumerate()
        .map(|(k, l)| (l.id.as_str(), k))
        .collect();
    let mut use_count = vec![0usize; extras.landmarks.len()];
    s.push_str("],\"frames\":[");
    for (k, r) in records.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        s.push('[');
        let _ = write!(s, "{},", r.frame);
        jnum(&mut s, r.time_s, 3);
        let _ = write!(
            s,
            ",{},",
            status_index.get(r.status.as_str()).copied().unwrap_or(0)
        );
        match &r.visual {
            Some(v) => {
                s.push('[');
                jnum(&mut s, v.geodetic.lat_deg, 9);
                s.push(',');
                jnum(&mut s, v.geodetic.lon_deg, 9);
                let c = &v.horizontal_covariance_m2;
                for (x, d) in [
                    (v.sigma_e_m, 4),
                    (v.sigma_n_m, 4),
                    (v.sigma_u_m, 4),
                    (c[(0, 0)], 7),
                    (c[(0, 1)], 7),
                    (c[(1, 1)], 7),
                ] {
                    s.push(',');
                    jnum(&mut s, x, d);
                }
                let _ = write!(s, ",{},{},", v.n_landmarks, v.n_surrogates);
                jnum(&mut s, v.heading_deg, 2);
                s.push(']');
            }
            None => s.push_str("null"),
        }
        s.push(',');
        match &r.gnss {
            Some(g) => jlatlon(&mut s, g),
            None => s.push_str("null"),
        }
        s.push(',');
        match &r.truth {
            Some(t) => jlatlon(&mut s, &t.geodetic),
            None => s.push_str("null"),
        }
        s.push_str(",[");
        if r.visual.is_some() {
            let ids = extras.used.get(&r.frame).map(Vec::as_slice).unwrap_or(&[]);
            let mut first = true;
            for i in ids.iter().filter_map(|id| landmark_index.get(id.as_str())) {
                use_count[*i] += 1;
                if !first {
                    s.push(',');
                }
                first = false;
                let _ = write!(s, "{i}");
            }
        }
        s.push_str("]]");
    }
    s.push_str("],\"landmarks\":[");
    for (k, l) in extras.landmarks.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        s.push('[');
        jstr(&mut s, &l.id);
        s.push(',');
        jnum(&mut s, l.lat_deg, 9);
        s.push(',');
        jnum(&mut s, l.lon_deg, 9);
        let _ = write!(s, ",{}]", use_count[k]);
    }
    s.push_str("]};\n");
    s
}

fn script(s: &mut String, body: &str) {
    s.push_str("<script>//<![CDATA[\n");
    s.push_str(body);
    s.push_str("\n//]]></script>\n");
}

/// `report.html` without landmarks: [`report_html_with`] and an empty [`MapExtras`].
pub fn report_html(drive: &DriveInfo, records: &[FrameOutcome], report: &Report) -> String {
    report_html_with(drive, records, report, &MapExtras::default())
}

/// `report.html`: the title and time span, the accuracy table (the visual fixes with
/// ≥ [`MIN_SURVEYED_LANDMARKS`] surveyed landmarks as the headline row, truth rows only
/// with truth, the blackout row), the interactive map (fixes coloured by σ or status, 95 %
/// ellipses when zoomed in, `extras`' landmarks, a click on a fix shows its frame), the
/// horizontal error against time (blackouts shaded), the error CDFs and the text summary.
///
/// The page loads nothing: scripts (vendored Leaflet and vgps's map script), styles, data
/// and SVG plots are inline, unless the reader ticks the online background map. It is
/// written in XHTML syntax, so it parses as XML as well as HTML. A plot that cannot be
/// drawn is replaced by its error message.
pub fn report_html_with(
    drive: &DriveInfo,
    records: &[FrameOutcome],
    report: &Report,
    extras: &MapExtras,
) -> String {
    let geom = derive(drive, records);
    let has_truth = records.iter().any(|r| r.truth.is_some());
    let has_gnss = records.iter().any(|r| r.gnss.is_some());
    let name = xml_escape(&drive.name);
    let mut s = String::with_capacity(300_000 + 200 * records.len());
    let _ = writeln!(
        s,
        "<!DOCTYPE html>\n<html xmlns=\"http://www.w3.org/1999/xhtml\" lang=\"en\">\n<head>\n\
         <meta charset=\"utf-8\"/>\n<title>vgps replay: {name}</title>\n<style>{CSS}</style>"
    );
    s.push_str("<style>/*<![CDATA[*/\n");
    s.push_str(LEAFLET_CSS);
    s.push_str("\n/*]]>*/</style>\n");
    // Collect script errors from the first moment (read by the headless-browser test).
    script(
        &mut s,
        "window.VGPS_ERRORS=[];window.addEventListener('error',function(e){window.VGPS_ERRORS.push(String(e.message));});",
    );
    let _ = writeln!(s, "</head>\n<body>\n<h1>vgps replay: {name}</h1>");
    let span = match (
        report.first_time_s.and_then(utc_iso8601),
        report.last_time_s.and_then(utc_iso8601),
    ) {
        (Some(a), Some(b)) => format!(", {a} to {b}"),
        _ => String::new(),
    };
    let o = &report.origin;
    let _ = writeln!(
        s,
        "<p>{} frames{span}; visual fixes {} ({} %); ENU origin {:.9}&#176;, {:.9}&#176;, {:.3} m.</p>",
        report.frames,
        report.visual_fixes,
        num(report.visual_fix_rate.map(|r| 100.0 * r), 1),
        o.lat_deg,
        o.lon_deg,
        o.alt_m
    );
    s.push_str(
        "<h2>Summary</h2>\n<table>\n<tr><th>horizontal (m)</th><th>n</th><th>CEP50</th>\
         <th>CEP95</th><th>RMS</th><th>max</th><th>vertical RMS</th></tr>\n",
    );
    let headline = format!("visual vs truth, \u{2265} {MIN_SURVEYED_LANDMARKS} surveyed");
    comparison_row(
        &mut s,
        &headline,
        &report.visual_vs_truth_surveyed,
        " class=\"headline\"",
    );
    comparison_row(&mut s, "visual vs truth", &report.visual_vs_truth, "");
    comparison_row(&mut s, "satellite vs truth", &report.gnss_vs_truth, "");
    comparison_row(&mut s, "visual vs satellite", &report.visual_vs_gnss, "");
    comparison_row(
        &mut s,
        "visual vs truth, blackout",
        &report.blackout.visual_vs_truth,
        "",
    );
    s.push_str("</table>\n");
    let b = &report.blackout;
    let _ = write!(
        s,
        "<p>Satellite blackouts: {} frames in {} stretches, visual fix rate {} %.",
        b.frames,
        b.stretches.len(),
        num(b.visual_fix_rate.map(|r| 100.0 * r), 1),
    );
    if report.heading_error_median_deg.is_some() {
        let _ = write!(
            s,
            " Median heading error {} &#176;.",
            num(report.heading_error_median_deg, 3)
        );
    }
    if let Some(c) = &report.covariance_consistency {
        let _ = write!(
            s,
            " Truth inside the 95 % error ellipse: {} of {} fixes ({} %).",
            c.inside_95,
            c.n,
            num(Some(100.0 * c.fraction_inside_95), 1)
        );
    }
    s.push_str("</p>\n<h2>Map</h2>\n");
    map_section(&mut s, has_truth, has_gnss);
    s.push_str("<h2>Horizontal error against time</h2>\n");
    push_plot(&mut s, error_vs_time_svg(records, &geom));
    s.push_str("<h2>Cumulative distribution of the horizontal error</h2>\n");
    push_plot(&mut s, error_cdf_svg(&geom));
    let _ = writeln!(
        s,
        "<h2>Text summary</h2>\n<pre>{}</pre>",
        xml_escape(&summary_table(report))
    );
    script(&mut s, &map_data(drive, records, extras));
    s.push_str("<script>//<![CDATA[\n");
    s.push_str(VENDOR_BEGIN);
    s.push('\n');
    s.push_str(LEAFLET_JS);
    s.push('\n');
    s.push_str(VENDOR_END);
    s.push_str("\n//]]></script>\n");
    script(&mut s, MAP_JS);
    s.push_str("</body>\n</html>\n");
    s
}

fn push_plot(s: &mut String, svg: Result<String, super::ReportError>) {
    match svg {
        // plotters starts with an XML declaration: not allowed inside the page.
        Ok(svg) => {
            let body = match svg.find("<svg") {
                Some(k) => &svg[k..],
                None => svg.as_str(),
            };
            s.push_str(body);
            s.push('\n');
        }
        Err(e) => {
            let _ = writeln!(s, "<p>{}</p>", xml_escape(&e.to_string()));
        }
    }
}

fn map_section(s: &mut String, has_truth: bool, has_gnss: bool) {
    s.push_str("<div id=\"vgps-controls\">");
    if has_truth {
        s.push_str("<label><input type=\"checkbox\" id=\"vgps-show-truth\" checked=\"checked\"/> <span style=\"color:#1ea03c\">truth</span></label>");
    }
    if has_gnss {
        s.push_str("<label><input type=\"checkbox\" id=\"vgps-show-gnss\" checked=\"checked\"/> <span style=\"color:#286edc\">satellite</span></label>");
    }
    s.push_str(
        "<label><input type=\"checkbox\" id=\"vgps-show-visual\" checked=\"checked\"/> <span style=\"color:#dc2828\">visual track</span></label>\
         <label><input type=\"checkbox\" id=\"vgps-show-landmarks\" checked=\"checked\"/> landmarks</label>\
         <label><input type=\"checkbox\" id=\"vgps-show-ellipses\" checked=\"checked\"/> 95 % ellipses (when zoomed in)</label>\
         <label><input type=\"checkbox\" id=\"vgps-show-background\"/> online background map</label>\
         <label>colour fixes by <select id=\"vgps-colour\"><option value=\"sigma\" selected=\"selected\">horizontal &#963;</option><option value=\"status\">status</option></select></label>\
         <div class=\"key\" id=\"vgps-key-sigma\">&#963;:<span style=\"background:#1a9850\"></span>&lt; 2 cm<span style=\"background:#91cf60\"></span>2&#8211;5 cm<span style=\"background:#fee08b\"></span>5&#8211;10 cm<span style=\"background:#fc8d59\"></span>10&#8211;25 cm<span style=\"background:#d73027\"></span>&#8805; 25 cm<span style=\"background:#888\"></span>no fix</div>\
         <div class=\"key\" id=\"vgps-key-status\"><span style=\"background:#2060c0\"></span>fix, &#8805; 3 surveyed<span style=\"background:#f08c00\"></span>fix, fewer surveyed<span style=\"background:#888\"></span>no fix (drawn at the satellite or true position)</div>\
         </div>\n<div id=\"vgps-map\"></div>\n\
         <div id=\"vgps-frame\">Click a fix on the map to see its frame. Scroll or pinch to zoom, drag to pan.</div>\n\
         <pre id=\"vgps-selftest\" style=\"display:none\"></pre>\n",
    );
}
