//! The static plots of `report.html`, drawn with `plotters`' SVG backend: the horizontal
//! error against time and the cumulative distributions of the horizontal error.
//!
//! Text is laid out with the embedded font (see [`super::plot`]) registered under the
//! family `sans-serif`, which is also the family the SVG asks the browser for.

use super::derived::{FrameGeom, runs};
use super::plot::{BLACKOUT_RGB, GNSS_RGB, VISUAL_RGB, register_font};
use super::{FrameRecord, ReportError};
use plotters::prelude::*;

/// Width and height of both SVG plots (CSS pixels).
pub(crate) const SVG_W: u32 = 900;
/// Height of both SVG plots (CSS pixels).
pub(crate) const SVG_H: u32 = 520;
/// The font family of the SVG text (the embedded font is registered under it for layout).
pub(crate) const SVG_FONT: &str = "sans-serif";
/// At most this many points per CDF curve (evenly spaced in probability): the curve is
/// exact at those probabilities and the page stays small for long drives.
const CDF_POINTS: usize = 400;

fn rgb(c: (u8, u8, u8)) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

fn err(what: &'static str) -> impl Fn(String) -> ReportError {
    move |reason| ReportError::Plot { what, reason }
}

/// The horizontal error against time: visual against truth (against the satellite
/// without truth) and satellite against truth as lines broken at gaps, blackout stretches
/// shaded.
pub(crate) fn error_vs_time_svg(
    records: &[FrameRecord],
    geom: &[FrameGeom],
) -> Result<String, ReportError> {
    const WHAT: &str = "report.html error plot";
    register_font();
    let e = err(WHAT);
    let t0 = records
        .iter()
        .map(|r| r.time_s)
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let has_truth = geom.iter().any(|g| g.truth.is_some());
    type Pick = fn(&FrameGeom, bool) -> Option<f64>;
    /// A curve: its legend, how to pick its value, its colour and its stroke width.
    type Series<'a> = (&'a str, Pick, (u8, u8, u8), u32);
    let visual_name = if has_truth {
        "visual vs truth"
    } else {
        "visual vs satellite"
    };
    let series: [Series; 2] = [
        (
            "satellite vs truth",
            |g, _| g.gnss_vs_truth.map(|d| d.h),
            GNSS_RGB,
            2,
        ),
        (
            visual_name,
            |g, t| {
                if t {
                    g.visual_vs_truth
                } else {
                    g.visual_vs_gnss
                }
                .map(|d| d.h)
            },
            VISUAL_RGB,
            1,
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
        .flat_map(|g| series.iter().map(move |s| (s.1)(g, has_truth)))
        .flatten()
        .filter(|x| x.is_finite())
        .fold(0.1, f64::max)
        * 1.1;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (SVG_W, SVG_H)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, 0.0..e_max)
            .map_err(|x| e(x.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("time since first frame (s)")
            .y_desc("horizontal error (m)")
            .label_style((SVG_FONT, 13))
            .axis_desc_style((SVG_FONT, 14))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(|x| e(x.to_string()))?;
        let shade = rgb(BLACKOUT_RGB).filled();
        let bands: Vec<(f64, f64)> = runs(geom.iter().map(|g| g.blackout))
            .into_iter()
            .map(|(a, b)| (times[a], times[b]))
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        if !bands.is_empty() {
            chart
                .draw_series(
                    bands
                        .into_iter()
                        .map(|(a, b)| Rectangle::new([(a, 0.0), (b.max(a), e_max)], shade)),
                )
                .map_err(|x| e(x.to_string()))?
                .label("satellite blackout")
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], shade));
        }
        for (name, pick, colour, width) in series {
            let style = rgb(colour).stroke_width(width);
            let mut first = true;
            let value = |k: usize| {
                pick(&geom[k], has_truth).filter(|x| x.is_finite() && times[k].is_finite())
            };
            for (a, b) in runs((0..geom.len()).map(|k| value(k).is_some())) {
                let pts: Vec<(f64, f64)> = (a..=b)
                    .filter_map(|k| value(k).map(|v| (times[k], v)))
                    .collect();
                let drawn = if pts.len() == 1 {
                    chart
                        .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, style.filled())))
                        .map_err(|x| e(x.to_string()))?
                } else {
                    chart
                        .draw_series(LineSeries::new(pts, style))
                        .map_err(|x| e(x.to_string()))?
                };
                if first {
                    drawn
                        .label(name)
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                    first = false;
                }
            }
        }
        chart
            .configure_series_labels()
            .label_font((SVG_FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(170, 170, 170))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|x| e(x.to_string()))?;
        root.present().map_err(|x| e(x.to_string()))?;
    }
    Ok(out)
}

/// The error CDF curves, each as (name, colour, width, dashed, sorted errors).
type Curve = (&'static str, (u8, u8, u8), u32, bool, Vec<f64>);

/// The cumulative distributions of the horizontal error on a logarithmic error axis (so
/// centimetre and metre errors are both readable), dashed lines at 50 % and 95 %.
///
/// Every curve stays visible where two coincide: the satellite curve is drawn first, wide
/// and light, and "visual vs satellite" (which follows it when the visual error is small)
/// dashed on top of it.
pub(crate) fn error_cdf_svg(geom: &[FrameGeom]) -> Result<String, ReportError> {
    const WHAT: &str = "report.html CDF plot";
    register_font();
    let e = err(WHAT);
    let collect = |f: &dyn Fn(&FrameGeom) -> Option<f64>| {
        let mut v: Vec<f64> = geom
            .iter()
            .filter_map(f)
            .filter(|x| x.is_finite())
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let curves: Vec<Curve> = vec![
        (
            "satellite vs truth",
            GNSS_RGB,
            5,
            false,
            collect(&|g| g.gnss_vs_truth.map(|d| d.h)),
        ),
        (
            "visual vs truth",
            VISUAL_RGB,
            2,
            false,
            collect(&|g| g.visual_vs_truth.map(|d| d.h)),
        ),
        (
            "visual vs truth, blackout",
            (240, 160, 32),
            2,
            true,
            collect(&|g| g.visual_vs_truth.filter(|_| g.blackout).map(|d| d.h)),
        ),
        (
            "visual vs satellite",
            (128, 64, 192),
            2,
            true,
            collect(&|g| g.visual_vs_gnss.map(|d| d.h)),
        ),
    ];
    let all = curves.iter().flat_map(|c| c.4.iter().copied());
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
        (if x > 0.0 { lo.min(x) } else { lo }, hi.max(x))
    });
    // A logarithmic axis from a decade below the smallest positive error (at least 0.1 mm)
    // to the largest; a floor of 1 mm to 1 m without data.
    let x0 = if lo.is_finite() {
        10f64.powf(lo.max(1e-4).log10().floor())
    } else {
        1e-3
    };
    let x1 = if hi > x0 {
        10f64.powf(hi.log10().ceil()).max(x0 * 10.0)
    } else {
        x0 * 1e3
    };
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (SVG_W, SVG_H)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), 0.0..1.0)
            .map_err(|x| e(x.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("horizontal error (m, logarithmic)")
            .y_desc("fraction of frames")
            .x_label_formatter(&|v| {
                if *v >= 1.0 {
                    format!("{v:.0}")
                } else {
                    let d = (-v.log10()).ceil().max(0.0) as usize;
                    format!("{v:.d$}")
                }
            })
            .label_style((SVG_FONT, 13))
            .axis_desc_style((SVG_FONT, 14))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(|x| e(x.to_string()))?;
        let grey = RGBColor(150, 150, 150);
        for q in [0.5, 0.95] {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(x0, q), (x1, q)],
                    4,
                    3,
                    grey.into(),
                ))
                .map_err(|x| e(x.to_string()))?;
        }
        for (name, colour, width, dashed, v) in curves {
            if v.is_empty() {
                continue;
            }
            let n = v.len();
            let step = n.div_ceil(CDF_POINTS).max(1);
            // The staircase at every `step`-th sample and the last one.
            let mut pts = Vec::with_capacity(2 * (n / step + 2));
            let mut k = 0;
            while k < n {
                let x = v[k].max(x0);
                pts.push((x, k as f64 / n as f64));
                let next = (k + step).min(n);
                pts.push((x, next as f64 / n as f64));
                k = next;
            }
            pts.push((x1, 1.0));
            let light = if width > 2 { 0.45 } else { 1.0 };
            let style = rgb(colour).mix(light).stroke_width(width);
            let drawn = if dashed {
                chart
                    .draw_series(DashedLineSeries::new(pts, 7, 4, style))
                    .map_err(|x| e(x.to_string()))?
            } else {
                chart
                    .draw_series(LineSeries::new(pts, style))
                    .map_err(|x| e(x.to_string()))?
            };
            drawn
                .label(format!("{name} ({n})"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        chart
            .configure_series_labels()
            .label_font((SVG_FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(170, 170, 170))
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(|x| e(x.to_string()))?;
        root.present().map_err(|x| e(x.to_string()))?;
    }
    Ok(out)
}
