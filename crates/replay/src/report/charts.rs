//! The report's plots, each drawn by one function generic over the `plotters` backend:
//! [`super::plot`] calls them with the bitmap backend (the PNG files) and with the SVG
//! backend (the plots inlined in `report.html`). Only the [`Look`] (sizes, fonts, caption)
//! differs between the two.

use super::FrameOutcome;
use super::ReportError;
use super::derived::{FrameGeom, runs};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;

/// Colours of the visual, satellite and truth tracks (also used by the HTML page).
pub(crate) const VISUAL_RGB: (u8, u8, u8) = (220, 40, 40);
pub(crate) const GNSS_RGB: (u8, u8, u8) = (40, 110, 220);
pub(crate) const TRUTH_RGB: (u8, u8, u8) = (30, 160, 60);
/// Colour of the blackout shading.
pub(crate) const BLACKOUT_RGB: (u8, u8, u8) = (235, 225, 200);
/// At most this many points per CDF curve (evenly spaced in probability): the curve is
/// exact at those probabilities and the page stays small for long drives.
const CDF_POINTS: usize = 400;

/// How a plot looks on one medium: font, text sizes, margins, legend border.
pub(crate) struct Look {
    /// The font family (registered with plotters, see [`super::plot::register_font`]).
    pub font: &'static str,
    /// Size of the caption; `None` draws no caption (the HTML page has headings).
    pub caption: Option<u32>,
    /// Size of the tick labels and of the legend.
    pub label: u32,
    /// Size of the axis descriptions.
    pub desc: u32,
    /// Margin around the chart.
    pub margin: u32,
    /// Height of the x label area and width of the y label area.
    pub label_areas: (u32, u32),
    /// Colour of the legend's border.
    pub legend_border: RGBColor,
}

/// Where a plot is drawn: the backend's drawing area, the look, the caption (drawn when
/// the look has a caption size) and the plot's name for errors.
pub(crate) struct Canvas<'a, DB: DrawingBackend> {
    /// The whole drawing area of the backend.
    pub root: &'a DrawingArea<DB, Shift>,
    /// How the plot looks on this medium.
    pub look: &'a Look,
    /// The caption.
    pub caption: &'a str,
    /// The plot's name in errors ([`ReportError::Plot`]).
    pub what: &'static str,
}

fn rgb(c: (u8, u8, u8)) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

/// Turns any drawing error into [`ReportError::Plot`] naming the plot.
trait OrPlot<T> {
    fn or_plot(self, what: &'static str) -> Result<T, ReportError>;
}

impl<T, E: std::fmt::Display> OrPlot<T> for Result<T, E> {
    fn or_plot(self, what: &'static str) -> Result<T, ReportError> {
        self.map_err(|x| ReportError::Plot {
            what,
            reason: x.to_string(),
        })
    }
}

/// The chart context [`chart_on`] returns: Cartesian axes over the ranges `X` and `Y`.
type Chart<'a, DB, X, Y> = ChartContext<
    'a,
    DB,
    Cartesian2d<<X as AsRangedCoord>::CoordDescType, <Y as AsRangedCoord>::CoordDescType>,
>;

/// A chart on `root` (filled white first) with the look's caption, margins and ranges.
fn chart_on<'a, DB: DrawingBackend, X: AsRangedCoord, Y: AsRangedCoord>(
    c: &Canvas<'a, DB>,
    (x, y): (X, Y),
) -> Result<Chart<'a, DB, X, Y>, ReportError> {
    c.root.fill(&WHITE).or_plot(c.what)?;
    let mut builder = ChartBuilder::on(c.root);
    if let Some(size) = c.look.caption {
        builder.caption(c.caption, (c.look.font, size));
    }
    builder
        .margin(c.look.margin)
        .x_label_area_size(c.look.label_areas.0)
        .y_label_area_size(c.look.label_areas.1)
        .build_cartesian_2d(x, y)
        .or_plot(c.what)
}

/// Draws the grid with the look's fonts and the axis descriptions.
fn draw_mesh<X, Y, DB: DrawingBackend>(
    mesh: &mut plotters::chart::MeshStyle<'_, '_, X, Y, DB>,
    c: &Canvas<'_, DB>,
    (x_desc, y_desc): (&str, &str),
) -> Result<(), ReportError>
where
    X: Ranged + ValueFormatter<X::ValueType>,
    Y: Ranged + ValueFormatter<Y::ValueType>,
{
    mesh.x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((c.look.font, c.look.label))
        .axis_desc_style((c.look.font, c.look.desc))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()
        .or_plot(c.what)
}

/// Draws the legend box at `position` and presents the drawing.
fn finish<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    c: &Canvas<'a, DB>,
    mut chart: ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), ReportError> {
    chart
        .configure_series_labels()
        .label_font((c.look.font, c.look.label))
        .background_style(WHITE.mix(0.85))
        .border_style(c.look.legend_border)
        .position(position)
        .draw()
        .or_plot(c.what)?;
    c.root.present().or_plot(c.what)
}

/// A range `[lo, hi]` around the values with 5 % margin, at least 1 m wide.
fn padded(lo: f64, hi: f64) -> (f64, f64) {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() && lo <= hi {
        (lo, hi)
    } else {
        (0.0, 1.0)
    };
    let span = (hi - lo).max(1.0);
    (lo - 0.05 * span, lo + 1.05 * span)
}

/// The track map: visual (red), satellite (blue) and truth (green) tracks in the drive's
/// ENU frame (metres east and north of the origin, equal scales), each broken at gaps,
/// visual fixes during satellite blackouts marked with orange circles.
pub(crate) fn draw_track<DB: DrawingBackend>(
    c: &Canvas<'_, DB>,
    geom: &[FrameGeom],
) -> Result<(), ReportError> {
    let pts = geom
        .iter()
        .flat_map(|g| [g.visual, g.gnss, g.truth])
        .flatten();
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for p in pts {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    let (x0, x1) = padded(x0, x1);
    let (y0, y1) = padded(y0, y1);
    // Equal scales: widen the narrower axis to the plot's aspect ratio (plot area ≈ 4:3).
    let aspect = 1.3;
    let (w, h) = (x1 - x0, y1 - y0);
    let (x0, x1, y0, y1) = if w / h < aspect {
        let c = 0.5 * (x0 + x1);
        (c - 0.5 * h * aspect, c + 0.5 * h * aspect, y0, y1)
    } else {
        let c = 0.5 * (y0 + y1);
        (x0, x1, c - 0.5 * w / aspect, c + 0.5 * w / aspect)
    };
    let mut chart = chart_on(c, (x0..x1, y0..y1))?;
    draw_mesh(&mut chart.configure_mesh(), c, ("east (m)", "north (m)"))?;
    type PointOf = fn(&FrameGeom) -> Option<nalgebra::Vector3<f64>>;
    type TrackStyle<'a> = (&'a str, PointOf, (u8, u8, u8), u32);
    // Width 1 for the noisy tracks: plotters' wide bitmap polylines draw miter spikes at
    // sharp turns.
    let tracks: [TrackStyle; 3] = [
        ("truth", |g| g.truth, TRUTH_RGB, 2),
        ("satellite", |g| g.gnss, GNSS_RGB, 1),
        ("visual", |g| g.visual, VISUAL_RGB, 1),
    ];
    for (name, get, colour, width) in tracks {
        let mut first = true;
        for (a, b) in runs(geom.iter().map(|g| get(g).is_some())) {
            let line: Vec<(f64, f64)> = geom[a..=b]
                .iter()
                .filter_map(|g| get(g).map(|p| (p.x, p.y)))
                .collect();
            let style = rgb(colour).stroke_width(width);
            let series = chart
                .draw_series(LineSeries::new(line, style))
                .or_plot(c.what)?;
            if first {
                series
                    .label(name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                first = false;
            }
        }
    }
    let dark = geom
        .iter()
        .filter(|g| g.blackout)
        .filter_map(|g| g.visual.map(|p| (p.x, p.y)))
        .collect::<Vec<_>>();
    if !dark.is_empty() {
        chart
            .draw_series(
                dark.into_iter()
                    .map(|p| Circle::new(p, 3, RGBColor(240, 150, 0).stroke_width(1))),
            )
            .or_plot(c.what)?
            .label("visual in blackout")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(240, 150, 0)));
    }
    finish(c, chart, SeriesLabelPosition::UpperRight)
}

/// One curve of the error plot: its legend, how to pick its value (given whether the
/// drive has truth), its colour and its stroke width.
type Series<'a> = (
    &'a str,
    fn(&FrameGeom, bool) -> Option<f64>,
    (u8, u8, u8),
    u32,
);

/// The horizontal error against time (seconds since the first frame): visual against
/// truth (against the satellite without truth) and satellite against truth as lines broken
/// at gaps (a lone point as a dot), blackout stretches shaded. A curve without points has
/// no legend entry, so a drive without truth shows no truth entry.
///
/// Every curve stays visible where two coincide: the satellite curve is drawn first and
/// wider, the visual curve on top of it.
pub(crate) fn draw_error_vs_time<DB: DrawingBackend>(
    c: &Canvas<'_, DB>,
    records: &[FrameOutcome],
    geom: &[FrameGeom],
) -> Result<(), ReportError> {
    let t0 = records
        .iter()
        .map(|r| r.time_s)
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let has_truth = geom.iter().any(|g| g.truth.is_some());
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
    let mut chart = chart_on(c, (0.0..t_end, 0.0..e_max))?;
    draw_mesh(
        &mut chart.configure_mesh(),
        c,
        ("time since first frame (s)", "horizontal error (m)"),
    )?;
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
            .or_plot(c.what)?
            .label("satellite blackout")
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], shade));
    }
    for (name, pick, colour, width) in series {
        let style = rgb(colour).stroke_width(width);
        let mut first = true;
        let value =
            |k: usize| pick(&geom[k], has_truth).filter(|x| x.is_finite() && times[k].is_finite());
        for (a, b) in runs((0..geom.len()).map(|k| value(k).is_some())) {
            let pts: Vec<(f64, f64)> = (a..=b)
                .filter_map(|k| value(k).map(|v| (times[k], v)))
                .collect();
            let drawn = if pts.len() == 1 {
                chart
                    .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, style.filled())))
                    .or_plot(c.what)?
            } else {
                chart
                    .draw_series(LineSeries::new(pts, style))
                    .or_plot(c.what)?
            };
            if first {
                drawn
                    .label(name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                first = false;
            }
        }
    }
    finish(c, chart, SeriesLabelPosition::UpperRight)
}

/// One CDF curve: name, colour, width, dashed, sorted errors.
type Curve = (&'static str, (u8, u8, u8), u32, bool, Vec<f64>);

/// The cumulative distributions of the horizontal error on a logarithmic error axis (so
/// centimetre and metre errors are both readable), dashed lines at 50 % and 95 %. A curve
/// without points is not drawn and has no legend entry.
///
/// Every curve stays visible where two coincide: the satellite curve is drawn first, wide
/// and light, and "visual vs satellite" (which follows it when the visual error is small)
/// dashed on top of it.
pub(crate) fn draw_error_cdf<DB: DrawingBackend>(
    c: &Canvas<'_, DB>,
    geom: &[FrameGeom],
) -> Result<(), ReportError> {
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
    let mut chart = chart_on(c, ((x0..x1).log_scale(), 0.0..1.0))?;
    let metres = |v: &f64| {
        if *v >= 1.0 {
            format!("{v:.0}")
        } else {
            let d = (-v.log10()).ceil().max(0.0) as usize;
            format!("{v:.d$}")
        }
    };
    draw_mesh(
        chart.configure_mesh().x_label_formatter(&metres),
        c,
        ("horizontal error (m, logarithmic)", "fraction of frames"),
    )?;
    let grey = RGBColor(150, 150, 150);
    for q in [0.5, 0.95] {
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x0, q), (x1, q)],
                4,
                3,
                grey.into(),
            ))
            .or_plot(c.what)?;
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
                .or_plot(c.what)?
        } else {
            chart
                .draw_series(LineSeries::new(pts, style))
                .or_plot(c.what)?
        };
        drawn
            .label(format!("{name} ({n})"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    finish(c, chart, SeriesLabelPosition::LowerRight)
}
