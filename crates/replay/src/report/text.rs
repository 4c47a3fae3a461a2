//! The text summary table printed on stdout.

use super::stats::{Comparison, Report};
use std::fmt::Write;

fn opt(x: Option<f64>, decimals: usize) -> String {
    match x.filter(|v| v.is_finite()) {
        Some(v) => format!("{v:.decimals$}"),
        None => "-".into(),
    }
}

fn pct(x: Option<f64>) -> String {
    opt(x.map(|v| 100.0 * v), 1) + "%"
}

fn comparison_rows<const N: usize>(
    s: &mut String,
    indent: &str,
    rows: [(&str, &Option<Comparison>); N],
) {
    for (name, c) in rows {
        let Some(c) = c else { continue };
        let h = &c.horizontal_m;
        let _ = writeln!(
            s,
            "{indent}{name:<18} {:>6} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3}",
            c.n, h.cep50, h.cep95, h.rms, h.max, c.vertical_rms_m
        );
    }
}

/// A fixed-width text table of `report` for stdout: frames and fix rate, the accuracy
/// table (n, CEP50, CEP95, RMS, max horizontal, vertical RMS, metres) overall and during
/// blackouts, status counts, heading, covariance consistency and surrogate drift. Missing
/// values print as `-`.
///
/// # Example
/// ```
/// use vgps_geometry::geo::Geodetic;
/// use vgps_replay::report::{summary_table, DriveInfo, Report};
/// let drive = DriveInfo { name: "empty".into(), origin: Geodetic::try_new(0.0, 0.0, 0.0)? };
/// let table = summary_table(&Report::compute(&drive, &[]));
/// assert!(table.contains("frames 0"));
/// # Ok::<(), vgps_geometry::geo::GeoError>(())
/// ```
pub fn summary_table(report: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "drive {}: frames {}, visual fixes {} ({})",
        report.drive,
        report.frames,
        report.visual_fixes,
        pct(report.visual_fix_rate)
    );
    let _ = writeln!(
        s,
        "{:<18} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "horizontal (m)", "n", "CEP50", "CEP95", "RMS", "max", "vert RMS"
    );
    comparison_rows(
        &mut s,
        "",
        [
            ("visual vs truth", &report.visual_vs_truth),
            ("  ≥3 surveyed", &report.visual_vs_truth_surveyed),
            ("satellite vs truth", &report.gnss_vs_truth),
            ("visual vs sat.", &report.visual_vs_gnss),
        ],
    );
    let b = &report.blackout;
    let _ = writeln!(
        s,
        "blackout: frames {}, stretches {}, visual fixes {} ({})",
        b.frames,
        b.stretches.len(),
        b.visual_fixes,
        pct(b.visual_fix_rate)
    );
    comparison_rows(
        &mut s,
        "  ",
        [
            ("visual vs truth", &b.visual_vs_truth),
            ("", &None),
            ("", &None),
        ],
    );
    let statuses: Vec<String> = report
        .status_counts
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    let _ = writeln!(s, "statuses: {}", statuses.join(", "));
    let _ = writeln!(
        s,
        "heading error median: {} deg",
        opt(report.heading_error_median_deg, 3)
    );
    if let Some(i) = &report.images {
        let _ = writeln!(
            s,
            "images: {} frames from images, {} with unusable images ({} localized with the rest), {} unusable images",
            i.frames, i.frames_with_unusable_images, i.frames_partially_usable, i.unusable_images
        );
    }
    if let Some(c) = &report.covariance_consistency {
        let _ = writeln!(
            s,
            "covariance: {} of {} fixes inside their 95% ellipse ({})",
            c.inside_95,
            c.n,
            pct(Some(c.fraction_inside_95))
        );
    }
    if let Some(d) = &report.surrogate_drift {
        let _ = writeln!(
            s,
            "surrogate-only: {} fixes in {} stretches, error/distance median {} max {} (n {})",
            d.frames,
            d.stretches.len(),
            pct(d.median_error_per_distance),
            pct(d.max_error_per_distance),
            d.n
        );
    }
    s
}
