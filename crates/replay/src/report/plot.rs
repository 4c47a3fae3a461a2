//! The plots as files: PNG (`plotters`' bitmap backend, encoded by `image`) and SVG
//! (`plotters`' SVG backend, inlined in `report.html`). Each plot is drawn once, by a
//! function of [`super::charts`] generic over the backend; this module only picks the
//! backend, the size and the [`Look`].
//!
//! Text needs a font: plotters' `ab_glyph` backend renders a font embedded in the binary
//! (`assets/fonts/DejaVuSansMono-subset.ttf`, DejaVu Sans Mono cut down to printable ASCII
//! and a few symbols, 8.6 kB, DejaVu licence in `assets/fonts/LICENSE-DejaVu.txt`), so the
//! plots do not depend on the fonts installed on the machine and are byte-identical
//! everywhere.

use super::charts::{Canvas, Look, draw_error_cdf, draw_error_vs_time, draw_track};
use super::derived::{FrameGeom, derive};
use super::{DriveInfo, FrameOutcome, ReportError};
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
/// Width of both SVG plots (CSS pixels).
pub(crate) const SVG_W: u32 = 900;
/// Height of both SVG plots (CSS pixels).
pub(crate) const SVG_H: u32 = 520;
/// The font family of the SVG text: the embedded font is registered under it for layout,
/// and the browser draws the text with its own sans-serif font.
const SVG_FONT: &str = "sans-serif";

/// The look of the PNG files.
const PNG_LOOK: Look = Look {
    font: FONT_FAMILY,
    caption: Some(22),
    label: 14,
    desc: 16,
    margin: 15,
    label_areas: (45, 70),
    legend_border: BLACK,
};

/// The look of the SVG plots of `report.html` (no caption: the page has headings).
const SVG_LOOK: Look = Look {
    font: SVG_FONT,
    caption: None,
    label: 13,
    desc: 14,
    margin: 12,
    label_areas: (40, 60),
    legend_border: RGBColor(170, 170, 170),
};

static FONT: Once = Once::new();

/// Registers the embedded font with plotters, as [`FONT_FAMILY`] (PNG plots) and as
/// `sans-serif` (the layout font of the SVG plots of `report.html`).
pub(crate) fn register_font() {
    FONT.call_once(|| {
        // A failure leaves text undrawn (plotters then reports an error per label).
        let _ = plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES);
        let _ = plotters::style::register_font(SVG_FONT, FontStyle::Normal, FONT_BYTES);
    });
}

fn plot_error(what: &'static str) -> impl Fn(String) -> ReportError {
    move |reason| ReportError::Plot { what, reason }
}

/// Draws one plot with the bitmap backend and encodes it as PNG.
fn png(
    what: &'static str,
    caption: &str,
    draw: impl FnOnce(&Canvas<'_, BitMapBackend<'_>>) -> Result<(), ReportError>,
) -> Result<Vec<u8>, ReportError> {
    use image::ImageEncoder;
    register_font();
    let mut buf = vec![255u8; (PLOT_WIDTH_PX * PLOT_HEIGHT_PX * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (PLOT_WIDTH_PX, PLOT_HEIGHT_PX))
            .into_drawing_area();
        draw(&Canvas {
            root: &root,
            look: &PNG_LOOK,
            caption,
            what,
        })?;
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(
            &buf,
            PLOT_WIDTH_PX,
            PLOT_HEIGHT_PX,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| plot_error(what)(e.to_string()))?;
    Ok(out)
}

/// Draws one plot with the SVG backend.
fn svg(
    what: &'static str,
    draw: impl FnOnce(&Canvas<'_, SVGBackend<'_>>) -> Result<(), ReportError>,
) -> Result<String, ReportError> {
    register_font();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (SVG_W, SVG_H)).into_drawing_area();
        draw(&Canvas {
            root: &root,
            look: &SVG_LOOK,
            caption: "",
            what,
        })?;
    }
    Ok(out)
}

/// The track map as PNG: visual (red), satellite (blue) and truth (green) tracks in the
/// drive's ENU frame (metres east and north of the origin, equal scales, axes labelled in
/// metres), visual fixes during satellite blackouts marked with orange circles.
///
/// # Errors
/// [`ReportError::Plot`] if drawing or encoding fails.
pub fn plot_track_png(drive: &DriveInfo, records: &[FrameOutcome]) -> Result<Vec<u8>, ReportError> {
    const WHAT: &str = "track.png";
    let caption = format!("{}: track (ENU metres)", drive.name);
    let geom = derive(drive, records);
    png(WHAT, &caption, |c| draw_track(c, &geom))
}

/// The horizontal error against time as PNG: visual against truth (or against the
/// satellite when the drive has no truth) in red, satellite against truth in blue, as lines
/// broken at gaps, blackout stretches shaded; time in seconds since the first frame. The
/// same drawing as `report.html`'s error plot.
///
/// # Errors
/// [`ReportError::Plot`] if drawing or encoding fails.
pub fn plot_error_png(drive: &DriveInfo, records: &[FrameOutcome]) -> Result<Vec<u8>, ReportError> {
    const WHAT: &str = "error.png";
    let caption = format!("{}: horizontal error", drive.name);
    let geom = derive(drive, records);
    png(WHAT, &caption, |c| draw_error_vs_time(c, records, &geom))
}

/// `report.html`'s error plot as SVG (see [`plot_error_png`]).
pub(crate) fn error_vs_time_svg(
    records: &[FrameOutcome],
    geom: &[FrameGeom],
) -> Result<String, ReportError> {
    svg("report.html error plot", |c| {
        draw_error_vs_time(c, records, geom)
    })
}

/// `report.html`'s error CDF plot as SVG.
pub(crate) fn error_cdf_svg(geom: &[FrameGeom]) -> Result<String, ReportError> {
    svg("report.html CDF plot", |c| draw_error_cdf(c, geom))
}
