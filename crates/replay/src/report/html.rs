//! `report.html`: one self-contained page (inline CSS and inline SVG, no script, no
//! network) that is also well-formed XML (XHTML syntax: every element closed).

use super::derived::{FrameGeom, derive, runs};
use super::plot::{BLACKOUT_RGB, GNSS_RGB, TRUTH_RGB, VISUAL_RGB};
use super::stats::{Comparison, Report};
use super::text::summary_table;
use super::time::utc_iso8601;
use super::tracks::xml_escape;
use super::{DriveInfo, FrameRecord};
use nalgebra::Vector3;
use std::fmt::Write;

/// Width and height of every SVG figure (CSS pixels).
const SVG_W: f64 = 900.0;
const SVG_H: f64 = 560.0;
/// Margins of the plot box inside a figure: left, right, top, bottom.
const MARGIN: (f64, f64, f64, f64) = (70.0, 20.0, 20.0, 50.0);

const CSS: &str = "body{font-family:sans-serif;margin:2em auto;max-width:960px;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:2em}\
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
th:first-child,td:first-child{text-align:left}\
svg{background:#fff;border:1px solid #ddd}svg text{font-size:12px;font-family:sans-serif}\
pre{background:#f6f6f6;padding:1em;overflow-x:auto}";

fn css_rgb(c: (u8, u8, u8)) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// A "nice" step (1, 2 or 5 × 10^k) giving about `target` intervals over `span`.
fn nice_step(span: f64, target: f64) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / target;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let m = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    m * mag
}

/// Formats a tick value with as many decimals as the step needs.
fn tick_label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Data → pixel mapping of one plot box.
struct Axes {
    x: (f64, f64),
    y: (f64, f64),
}

impl Axes {
    fn px(&self, x: f64) -> f64 {
        MARGIN.0 + (x - self.x.0) / (self.x.1 - self.x.0) * (SVG_W - MARGIN.0 - MARGIN.1)
    }
    fn py(&self, y: f64) -> f64 {
        SVG_H - MARGIN.3 - (y - self.y.0) / (self.y.1 - self.y.0) * (SVG_H - MARGIN.2 - MARGIN.3)
    }
    fn point(&self, x: f64, y: f64) -> String {
        format!("{:.1},{:.1}", self.px(x), self.py(y))
    }
    /// Frame, grid, ticks and axis titles.
    fn frame(&self, s: &mut String, x_title: &str, y_title: &str) {
        let (l, r, t, b) = (MARGIN.0, SVG_W - MARGIN.1, MARGIN.2, SVG_H - MARGIN.3);
        let xs = nice_step(self.x.1 - self.x.0, 8.0);
        let ys = nice_step(self.y.1 - self.y.0, 6.0);
        let mut v = (self.x.0 / xs).ceil() * xs;
        while v <= self.x.1 + 1e-9 * xs {
            let p = self.px(v);
            let _ = writeln!(
                s,
                "<line x1=\"{p:.1}\" y1=\"{t:.1}\" x2=\"{p:.1}\" y2=\"{b:.1}\" stroke=\"#eee\"/>\
                 <text x=\"{p:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
                b + 16.0,
                tick_label(v, xs)
            );
            v += xs;
        }
        let mut v = (self.y.0 / ys).ceil() * ys;
        while v <= self.y.1 + 1e-9 * ys {
            let p = self.py(v);
            let _ = writeln!(
                s,
                "<line x1=\"{l:.1}\" y1=\"{p:.1}\" x2=\"{r:.1}\" y2=\"{p:.1}\" stroke=\"#eee\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                l - 6.0,
                p + 4.0,
                tick_label(v, ys)
            );
            v += ys;
        }
        let _ = writeln!(
            s,
            "<rect x=\"{l:.1}\" y=\"{t:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"#888\"/>\n\
             <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n\
             <text transform=\"translate(16,{:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
            r - l,
            b - t,
            0.5 * (l + r),
            SVG_H - 10.0,
            xml_escape(x_title),
            0.5 * (t + b),
            xml_escape(y_title)
        );
    }
}

fn svg_open(s: &mut String, label: &str) {
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{SVG_W}\" height=\"{SVG_H}\" \
         viewBox=\"0 0 {SVG_W} {SVG_H}\" role=\"img\" aria-label=\"{}\">",
        xml_escape(label)
    );
}

fn polyline(s: &mut String, pts: &[String], colour: &str, width: f64, extra: &str) {
    if pts.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"{width}\" \
         stroke-linejoin=\"round\"{extra}/>",
        pts.join(" ")
    );
}

fn legend(s: &mut String, items: &[(&str, String)]) {
    let x = SVG_W - MARGIN.1 - 190.0;
    let mut y = MARGIN.2 + 8.0;
    let _ = writeln!(
        s,
        "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"180\" height=\"{:.1}\" fill=\"#fff\" fill-opacity=\"0.85\" stroke=\"#aaa\"/>",
        x - 5.0,
        y - 4.0,
        18.0 * items.len() as f64 + 6.0
    );
    for (name, colour) in items {
        let _ = writeln!(
            s,
            "<rect x=\"{x:.1}\" y=\"{:.1}\" width=\"16\" height=\"8\" fill=\"{colour}\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\">{}</text>",
            y + 2.0,
            x + 22.0,
            y + 10.0,
            xml_escape(name)
        );
        y += 18.0;
    }
}

type Get = fn(&FrameGeom) -> Option<Vector3<f64>>;

fn track_map(s: &mut String, geom: &[FrameGeom]) {
    svg_open(s, "track map");
    let pts: Vec<Vector3<f64>> = geom
        .iter()
        .flat_map(|g| [g.visual, g.gnss, g.truth])
        .flatten()
        .collect();
    if pts.is_empty() {
        s.push_str("<text x=\"20\" y=\"40\">no positions</text>\n</svg>\n");
        return;
    }
    let (mut x0, mut x1, mut y0, mut y1) = (pts[0].x, pts[0].x, pts[0].y, pts[0].y);
    for p in &pts {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    // Equal scales in both directions, 5 % margin, at least 10 m shown.
    let (pw, ph) = (SVG_W - MARGIN.0 - MARGIN.1, SVG_H - MARGIN.2 - MARGIN.3);
    let span = ((x1 - x0) / pw).max((y1 - y0) / ph).max(10.0 / pw) * 1.1;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let ax = Axes {
        x: (cx - 0.5 * span * pw, cx + 0.5 * span * pw),
        y: (cy - 0.5 * span * ph, cy + 0.5 * span * ph),
    };
    ax.frame(s, "east of origin (m)", "north of origin (m)");
    // Blackout stretches: a wide band under the truth (or visual) track.
    let under: Get = if geom.iter().any(|g| g.truth.is_some()) {
        |g| g.truth
    } else {
        |g| g.visual
    };
    let band = css_rgb((240, 160, 40));
    for (a, b) in runs(geom.iter().map(|g| g.blackout)) {
        let line: Vec<String> = geom[a..=b]
            .iter()
            .filter_map(|g| under(g).map(|p| ax.point(p.x, p.y)))
            .collect();
        polyline(
            s,
            &line,
            &band,
            10.0,
            " stroke-opacity=\"0.35\" stroke-linecap=\"round\"",
        );
    }
    let tracks: [(Get, (u8, u8, u8), f64); 3] = [
        (|g| g.truth, TRUTH_RGB, 2.5),
        (|g| g.gnss, GNSS_RGB, 1.5),
        (|g| g.visual, VISUAL_RGB, 1.5),
    ];
    for (get, colour, width) in tracks {
        for (a, b) in runs(geom.iter().map(|g| get(g).is_some())) {
            let line: Vec<String> = geom[a..=b]
                .iter()
                .filter_map(|g| get(g).map(|p| ax.point(p.x, p.y)))
                .collect();
            if let (1, Some(p)) = (line.len(), get(&geom[a])) {
                let _ = writeln!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2\" fill=\"{}\"/>",
                    ax.px(p.x),
                    ax.py(p.y),
                    css_rgb(colour)
                );
            } else {
                polyline(s, &line, &css_rgb(colour), width, "");
            }
        }
    }
    // Scale bar: a nice length close to a fifth of the plot width, bottom left.
    let len = nice_step(0.2 * span * pw, 1.0);
    let (bx, by) = (MARGIN.0 + 20.0, SVG_H - MARGIN.3 - 20.0);
    let bw = len / span;
    let _ = writeln!(
        s,
        "<g stroke=\"#000\" stroke-width=\"2\"><line x1=\"{bx:.1}\" y1=\"{by:.1}\" x2=\"{:.1}\" y2=\"{by:.1}\"/>\
         <line x1=\"{bx:.1}\" y1=\"{:.1}\" x2=\"{bx:.1}\" y2=\"{:.1}\"/>\
         <line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\"/></g>\
         <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{} m</text>\n\
         <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">N &#8593;</text>",
        bx + bw,
        by - 5.0,
        by + 5.0,
        bx + bw,
        by - 5.0,
        bx + bw,
        by + 5.0,
        bx + 0.5 * bw,
        by - 8.0,
        tick_label(len, len),
        SVG_W - MARGIN.1 - 20.0,
        SVG_H - MARGIN.3 - 12.0
    );
    legend(
        s,
        &[
            ("truth", css_rgb(TRUTH_RGB)),
            ("satellite", css_rgb(GNSS_RGB)),
            ("visual", css_rgb(VISUAL_RGB)),
            ("satellite blackout", band),
        ],
    );
    s.push_str("</svg>\n");
}

fn error_vs_time(s: &mut String, records: &[FrameRecord], geom: &[FrameGeom]) {
    svg_open(s, "horizontal error against time");
    let t0 = records
        .iter()
        .map(|r| r.time_s)
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let has_truth = geom.iter().any(|g| g.truth.is_some());
    type Err = fn(&FrameGeom, bool) -> Option<f64>;
    let series: [(&str, Err, (u8, u8, u8)); 2] = [
        (
            "satellite vs truth",
            |g, _| g.gnss_vs_truth.map(|d| d.h),
            GNSS_RGB,
        ),
        (
            if has_truth {
                "visual vs truth"
            } else {
                "visual vs satellite"
            },
            |g, t| {
                if t {
                    g.visual_vs_truth
                } else {
                    g.visual_vs_gnss
                }
                .map(|d| d.h)
            },
            VISUAL_RGB,
        ),
    ];
    let times: Vec<f64> = records.iter().map(|r| r.time_s - t0).collect();
    let t_end = times
        .iter()
        .copied()
        .filter(|t| t.is_finite())
        .fold(1.0, f64::max);
    let e_max = geom
        .iter()
        .flat_map(|g| series.iter().map(move |(_, f, _)| f(g, has_truth)))
        .flatten()
        .fold(1.0, f64::max)
        * 1.1;
    let ax = Axes {
        x: (0.0, t_end),
        y: (0.0, e_max),
    };
    let (t, b) = (MARGIN.2, SVG_H - MARGIN.3);
    for (a, z) in runs(geom.iter().map(|g| g.blackout)) {
        let (xa, xz) = (times[a], times[z]);
        if !(xa.is_finite() && xz.is_finite()) {
            continue;
        }
        let _ = writeln!(
            s,
            "<rect x=\"{:.1}\" y=\"{t:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{}\"/>",
            ax.px(xa),
            (ax.px(xz) - ax.px(xa)).max(1.0),
            b - t,
            css_rgb(BLACKOUT_RGB)
        );
    }
    ax.frame(s, "time since first frame (s)", "horizontal error (m)");
    let mut items = vec![("satellite blackout", css_rgb(BLACKOUT_RGB))];
    for (name, f, colour) in series {
        let pts: Vec<(f64, f64)> = geom
            .iter()
            .zip(&times)
            .filter_map(|(g, &x)| Some((x, f(g, has_truth)?)).filter(|p| p.0.is_finite()))
            .collect();
        if pts.is_empty() {
            continue;
        }
        let c = css_rgb(colour);
        let _ = write!(s, "<g fill=\"{c}\">");
        for (x, y) in pts {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"1.8\"/>",
                ax.px(x),
                ax.py(y)
            );
        }
        s.push_str("</g>\n");
        items.push((name, c));
    }
    legend(s, &items);
    s.push_str("</svg>\n");
}

fn error_cdf(s: &mut String, geom: &[FrameGeom]) {
    svg_open(s, "cumulative distribution of horizontal errors");
    type Pick = fn(&FrameGeom) -> Option<f64>;
    let series: [(&str, Pick, String); 4] = [
        (
            "visual vs truth",
            |g| g.visual_vs_truth.map(|d| d.h),
            css_rgb(VISUAL_RGB),
        ),
        (
            "visual vs truth, blackout",
            |g| g.visual_vs_truth.filter(|_| g.blackout).map(|d| d.h),
            "#f0a020".into(),
        ),
        (
            "satellite vs truth",
            |g| g.gnss_vs_truth.map(|d| d.h),
            css_rgb(GNSS_RGB),
        ),
        (
            "visual vs satellite",
            |g| g.visual_vs_gnss.map(|d| d.h),
            "#8040c0".into(),
        ),
    ];
    let sorted: Vec<Vec<f64>> = series
        .iter()
        .map(|(_, f, _)| {
            let mut v: Vec<f64> = geom.iter().filter_map(f).collect();
            v.sort_by(f64::total_cmp);
            v
        })
        .collect();
    let x_max = sorted.iter().flatten().copied().fold(1.0, f64::max) * 1.05;
    let ax = Axes {
        x: (0.0, x_max),
        y: (0.0, 1.0),
    };
    ax.frame(s, "horizontal error (m)", "fraction of frames");
    for q in [0.5, 0.95] {
        let _ = writeln!(
            s,
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#999\" stroke-dasharray=\"4 3\"/>",
            ax.px(0.0),
            ax.py(q),
            ax.px(x_max),
            ax.py(q)
        );
    }
    let mut items = Vec::new();
    for ((name, _, colour), v) in series.iter().zip(&sorted) {
        if v.is_empty() {
            continue;
        }
        let n = v.len() as f64;
        let mut pts = vec![ax.point(0.0, 0.0)];
        for (i, &x) in v.iter().enumerate() {
            pts.push(ax.point(x, i as f64 / n));
            pts.push(ax.point(x, (i + 1) as f64 / n));
        }
        pts.push(ax.point(x_max, 1.0));
        polyline(s, &pts, colour, 1.8, "");
        items.push((*name, colour.clone()));
    }
    legend(s, &items);
    s.push_str("</svg>\n");
}

fn num(x: Option<f64>, decimals: usize) -> String {
    x.filter(|v| v.is_finite())
        .map(|v| format!("{v:.decimals$}"))
        .unwrap_or_else(|| "&#8211;".into())
}

fn comparison_row(s: &mut String, name: &str, c: &Option<Comparison>) {
    let Some(c) = c else { return };
    let h = &c.horizontal_m;
    let _ = writeln!(
        s,
        "<tr><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>",
        xml_escape(name),
        c.n,
        h.cep50,
        h.cep95,
        h.rms,
        h.max,
        c.vertical_rms_m
    );
}

/// `report.html`: the title and time span, the accuracy table (overall and during
/// blackouts), the track map (ENU metres at the drive origin, equal scales, scale bar,
/// blackout stretches as an orange band), the horizontal error against time (blackouts
/// shaded), the error CDFs (dashed lines at 50 % and 95 %) and the text summary.
///
/// The page loads nothing: CSS and SVG are inline and there is no script. It is written
/// in XHTML syntax, so it parses as XML as well as HTML.
pub fn report_html(drive: &DriveInfo, records: &[FrameRecord], report: &Report) -> String {
    let geom = derive(drive, records);
    let name = xml_escape(&drive.name);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<!DOCTYPE html>\n<html xmlns=\"http://www.w3.org/1999/xhtml\" lang=\"en\">\n<head>\n\
         <meta charset=\"utf-8\"/>\n<title>vgps replay: {name}</title>\n<style>{CSS}</style>\n\
         </head>\n<body>\n<h1>vgps replay: {name}</h1>"
    );
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
    comparison_row(&mut s, "visual vs truth", &report.visual_vs_truth);
    comparison_row(&mut s, "satellite vs truth", &report.gnss_vs_truth);
    comparison_row(&mut s, "visual vs satellite", &report.visual_vs_gnss);
    comparison_row(
        &mut s,
        "visual vs truth, blackout",
        &report.blackout.visual_vs_truth,
    );
    s.push_str("</table>\n");
    let b = &report.blackout;
    let _ = write!(
        s,
        "<p>Satellite blackouts: {} frames in {} stretches, visual fix rate {} %. \
         Median heading error {} &#176;.",
        b.frames,
        b.stretches.len(),
        num(b.visual_fix_rate.map(|r| 100.0 * r), 1),
        num(report.heading_error_median_deg, 3)
    );
    if let Some(c) = &report.covariance_consistency {
        let _ = write!(
            s,
            " Truth inside the 95 % error ellipse: {} of {} fixes ({} %).",
            c.inside_95,
            c.n,
            num(Some(100.0 * c.fraction_inside_95), 1)
        );
    }
    s.push_str("</p>\n<h2>Track map</h2>\n");
    track_map(&mut s, &geom);
    s.push_str("<h2>Horizontal error against time</h2>\n");
    error_vs_time(&mut s, records, &geom);
    s.push_str("<h2>Cumulative distribution of the horizontal error</h2>\n");
    error_cdf(&mut s, &geom);
    let _ = writeln!(
        s,
        "<h2>Text summary</h2>\n<pre>{}</pre>\n</body>\n</html>",
        xml_escape(&summary_table(report))
    );
    s
}
