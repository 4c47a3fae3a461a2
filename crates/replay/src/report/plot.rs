//! PNG plots drawn with `plotters` (bitmap backend) and encoded with `png`.
//!
//! Text needs a font: plotters' `ab_glyph` backend renders a font embedded in the binary
//! (`assets/fonts/DejaVuSansMono-subset.ttf`, DejaVu Sans Mono cut down to printable ASCII
//! and a few symbols, 8.6 kB, DejaVu licence in `assets/fonts/LICENSE-DejaVu.txt`), so the
//! plots do not depend on the fonts installed on the machine and are byte-identical
//! everywhere.

use super::derived::{FrameGeom, derive, runs};
use super::{DriveInfo, FrameRecord, ReportError};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::Once;

/// Width of every PNG plot (pixels).
pub const PLOT_WIDTH_PX: u32 = 1000;
/// Height of every PNG plot (pixels).
pub const PLOT_HEIGHT_PX: u32 = 750;

/// The embedded font (a subset of DejaVu Sans Mono).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono-subset.ttf");
/// The family name under which the embedded font is registered with plotters.
const FONT_FAMILY: &str = "vgps-mono";

static FONT: Once = Once::new();

/// Registers the embedded font with plotters, as [`FONT_FAMILY`] (PNG plots) and as
/// `sans-serif` (the layout font of the SVG plots of `report.html`).
pub(crate) fn register_font() {
    FONT.call_once(|| {
        // A failure leaves text undrawn (plotters then reports an error per label).
        let _ = plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES);
        let _ = plotters::style::register_font(
            super::svg_plots::SVG_FONT,
            FontStyle::Normal,
            FONT_BYTES,
        );
    });
}

/// Colours of the visual, satellite and truth tracks (also used by the HTML page).
pub(crate) const VISUAL_RGB: (u8, u8, u8) = (220, 40, 40);
pub(crate) const GNSS_RGB: (u8, u8, u8) = (40, 110, 220);
pub(crate) const TRUTH_RGB: (u8, u8, u8) = (30, 160, 60);
/// Colour of the blackout shading.
pub(crate) const BLACKOUT_RGB: (u8, u8, u8) = (235, 225, 200);

fn rgb(c: (u8, u8, u8)) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

fn plot_error(what: &'static str) -> impl Fn(String) -> ReportError {
    move |reason| ReportError::Plot { what, reason }
}

fn encode_png(buf: &[u8], what: &'static str) -> Result<Vec<u8>, ReportError> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(
            buf,
            PLOT_WIDTH_PX,
            PLOT_HEIGHT_PX,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| plot_error(what)(e.to_string()))?;
    Ok(out)
}

/// A square-ish range `[lo, hi]` around `values` with 5 % margin (never empty).
fn padded(lo: f64, hi: f64) -> (f64, f64) {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() && lo <= hi {
        (lo, hi)
    } else {
        (0.0, 1.0)
    };
    let span = (hi - lo).max(1.0);
    (lo - 0.05 * span, lo + 1.05 * span)
}

/// The track map as PNG: visual (red), satellite (blue) and truth (green) tracks in the
/// drive's ENU frame (metres east and north of the origin, equal scales, axes labelled in
/// metres), visual fixes during satellite blackouts marked with orange circles.
///
/// # Errors
/// [`ReportError::Plot`] if drawing or encoding fails.
pub fn plot_track_png(drive: &DriveInfo, records: &[FrameRecord]) -> Result<Vec<u8>, ReportError> {
    const WHAT: &str = "track.png";
    register_font();
    let geom = derive(drive, records);
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
    let mut buf = vec![255u8; (PLOT_WIDTH_PX * PLOT_HEIGHT_PX * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (PLOT_WIDTH_PX, PLOT_HEIGHT_PX))
            .into_drawing_area();
        let e = plot_error(WHAT);
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{}: track (ENU metres)", drive.name),
                (FONT_FAMILY, 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|x| e(x.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("east (m)")
            .y_desc("north (m)")
            .label_style((FONT_FAMILY, 14))
            .axis_desc_style((FONT_FAMILY, 16))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(|x| e(x.to_string()))?;
        type Get = fn(&FrameGeom) -> Option<nalgebra::Vector3<f64>>;
        type Track<'a> = (&'a str, Get, (u8, u8, u8), u32);
        // Width 1 for the noisy tracks: plotters' wide bitmap polylines draw miter spikes
        // at sharp turns.
        let tracks: [Track; 3] = [
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
                    .map_err(|x| e(x.to_string()))?;
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
                .map_err(|x| e(x.to_string()))?
                .label("visual in blackout")
                .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(240, 150, 0)));
        }
        chart
            .configure_series_labels()
            .label_font((FONT_FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|x| e(x.to_string()))?;
        root.present().map_err(|x| e(x.to_string()))?;
    }
    encode_png(&buf, WHAT)
}

/// The horizontal error against time as PNG: visual against truth (or against the
/// satellite when the drive has no truth) in red, satellite against truth in blue, blackout
/// stretches shaded; time in seconds since the first frame.
///
/// # Errors
/// [`ReportError::Plot`] if drawing or encoding fails.
pub fn plot_error_png(drive: &DriveInfo, records: &[FrameRecord]) -> Result<Vec<u8>, ReportError> {
    const WHAT: &str = "error.png";
    register_font();
    let geom = derive(drive, records);
    let t0 = records
        .iter()
        .map(|r| r.time_s)
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let has_truth = geom.iter().any(|g| g.truth.is_some());
    let visual: Vec<(f64, f64)> = records
        .iter()
        .zip(&geom)
        .filter_map(|(r, g)| {
            let d = if has_truth {
                g.visual_vs_truth
            } else {
                g.visual_vs_gnss
            }?;
            Some((r.time_s - t0, d.h)).filter(|p| p.0.is_finite())
        })
        .collect();
    let gnss: Vec<(f64, f64)> = records
        .iter()
        .zip(&geom)
        .filter_map(|(r, g)| Some((r.time_s - t0, g.gnss_vs_truth?.h)).filter(|p| p.0.is_finite()))
        .collect();
    let t_end = records
        .iter()
        .map(|r| r.time_s - t0)
        .filter(|t| t.is_finite())
        .fold(1.0_f64, f64::max);
    let e_max = visual
        .iter()
        .chain(&gnss)
        .map(|p| p.1)
        .fold(1.0_f64, f64::max)
        * 1.1;
    let mut buf = vec![255u8; (PLOT_WIDTH_PX * PLOT_HEIGHT_PX * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (PLOT_WIDTH_PX, PLOT_HEIGHT_PX))
            .into_drawing_area();
        let e = plot_error(WHAT);
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{}: horizontal error", drive.name),
                (FONT_FAMILY, 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_end, 0.0..e_max)
            .map_err(|x| e(x.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("time since first frame (s)")
            .y_desc("horizontal error (m)")
            .label_style((FONT_FAMILY, 14))
            .axis_desc_style((FONT_FAMILY, 16))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(|x| e(x.to_string()))?;
        let shade = rgb(BLACKOUT_RGB).filled();
        let bands: Vec<_> = runs(geom.iter().map(|g| g.blackout))
            .into_iter()
            .map(|(a, b)| (records[a].time_s - t0, records[b].time_s - t0))
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
        let visual_name = if has_truth {
            "visual vs truth"
        } else {
            "visual vs satellite"
        };
        for (name, pts, colour) in [
            ("satellite vs truth", gnss, GNSS_RGB),
            (visual_name, visual, VISUAL_RGB),
        ] {
            if pts.is_empty() {
                continue;
            }
            let style = rgb(colour);
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, style.filled())))
                .map_err(|x| e(x.to_string()))?
                .label(name)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, style.filled()));
        }
        chart
            .configure_series_labels()
            .label_font((FONT_FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|x| e(x.to_string()))?;
        root.present().map_err(|x| e(x.to_string()))?;
    }
    encode_png(&buf, WHAT)
}
