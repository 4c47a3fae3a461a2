//! Per-frame geometry shared by every output: ENU positions at the drive origin and the
//! differences between the visual, satellite and true positions.

use super::{DriveInfo, FrameOutcome};
use nalgebra::{Vector2, Vector3};
use vgps_geometry::geo::{Geodetic, LocalFrame};

/// A horizontal and vertical difference `a − b` in the drive's ENU frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Diff {
    /// East and north components (metres).
    pub en: Vector2<f64>,
    /// Horizontal distance `|en|` (metres).
    pub h: f64,
    /// Up component (metres).
    pub v: f64,
}

/// The ENU geometry of one frame.
#[derive(Clone, Debug, Default)]
pub(crate) struct FrameGeom {
    pub visual: Option<Vector3<f64>>,
    pub gnss: Option<Vector3<f64>>,
    pub truth: Option<Vector3<f64>>,
    /// Visual − truth.
    pub visual_vs_truth: Option<Diff>,
    /// Satellite − truth.
    pub gnss_vs_truth: Option<Diff>,
    /// Visual − satellite.
    pub visual_vs_gnss: Option<Diff>,
    /// Visual heading − true heading, wrapped into (−180°, 180°].
    pub heading_err_deg: Option<f64>,
    /// True when the satellite position is missing (blackout or gap).
    pub blackout: bool,
}

/// `Some(x)` for finite `x`.
pub(crate) fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// An angle difference in degrees wrapped into (−180, 180].
pub(crate) fn wrap_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 { w - 360.0 } else { w }
}

fn enu(frame: &LocalFrame, g: &Geodetic) -> Option<Vector3<f64>> {
    let p = frame.to_enu(g);
    (p.x.is_finite() && p.y.is_finite() && p.z.is_finite()).then_some(p)
}

fn diff(a: Option<Vector3<f64>>, b: Option<Vector3<f64>>) -> Option<Diff> {
    let d = a? - b?;
    let en = Vector2::new(d.x, d.y);
    Some(Diff {
        en,
        h: en.norm(),
        v: d.z,
    })
}

/// The geometry of every record, in the records' order.
pub(crate) fn derive(drive: &DriveInfo, records: &[FrameOutcome]) -> Vec<FrameGeom> {
    let frame = LocalFrame::new(drive.origin);
    records
        .iter()
        .map(|r| {
            let visual = r.visual.as_ref().and_then(|v| enu(&frame, &v.geodetic));
            let gnss = r.gnss.as_ref().and_then(|g| enu(&frame, g));
            let truth = r.truth.as_ref().and_then(|t| enu(&frame, &t.geodetic));
            let heading_err_deg = match (&r.visual, &r.truth) {
                (Some(v), Some(t)) => finite(wrap_deg(v.heading_deg - t.heading_deg)),
                _ => None,
            };
            FrameGeom {
                visual,
                gnss,
                truth,
                visual_vs_truth: diff(visual, truth),
                gnss_vs_truth: diff(gnss, truth),
                visual_vs_gnss: diff(visual, gnss),
                heading_err_deg,
                blackout: r.gnss.is_none(),
            }
        })
        .collect()
}

/// Maximal runs `[first, last]` (indices into `flags`) of consecutive `true` values.
pub(crate) fn runs(flags: impl IntoIterator<Item = bool>) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    let mut last = 0;
    for (i, f) in flags.into_iter().enumerate() {
        match (f, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((s, i - 1));
                start = None;
            }
            _ => {}
        }
        last = i;
    }
    if let Some(s) = start {
        out.push((s, last));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_and_wrap() {
        assert_eq!(
            runs([true, true, false, true, false, false, true]),
            vec![(0, 1), (3, 3), (6, 6)]
        );
        assert!(runs([false, false]).is_empty());
        assert_eq!(runs([true]), vec![(0, 0)]);
        assert_eq!(wrap_deg(350.0 - 10.0), -20.0);
        assert_eq!(wrap_deg(10.0 - 350.0), 20.0);
        assert_eq!(wrap_deg(-180.0), 180.0);
    }
}
