//! `fixes.nmea` and the live NMEA stream: NMEA 0183 sentences (GGA, RMC, GST, GBS, HDT) for
//! every frame, written by one [`NmeaEpochWriter`].
//!
//! # What the sentences claim (and what gpsd makes of them)
//! NMEA 0183 was made for satellite receivers; a visual fix is written so that no field
//! claims what a satellite receiver would mean by it (`docs/replay-report.md` has the table
//! of gpsd 3.22's reading of every GGA quality code, measured with gpsfake):
//!
//! - GGA quality [`GGA_QUALITY_VISUAL`] = 1, "fix valid". NMEA has no code for an absolute
//!   fix from another sensor. gpsd reports every non-zero code as a 3-D fix (`mode` 3, from
//!   the altitude and ≥ 4 "satellites") but reads the code as the kind of solution: 2
//!   differential, 4/5 RTK (centimetre claims of a carrier-phase solution), 6 dead
//!   reckoning (a visual fix is absolute: it does not drift from the last fix), 7 manual
//!   input (gpsd: a surveyed time-only position), 8 simulator. 1 claims only "a valid
//!   stand-alone fix"; its accuracy is in GST and GBS, not in the code.
//! - GGA HDOP empty: HDOP is a dilution factor of satellite geometry, which a visual fix
//!   has not; gpsd turns any HDOP into `eph` = HDOP × 19 m (its satellite error model).
//! - GGA satellites = landmarks + surrogates used (≤ 99): the count of independent
//!   references in the fix (gpsd needs ≥ 4 for a 3-D fix; every localizer fix has ≥ 4).
//! - GST: σ of latitude, longitude and altitude and the 1-σ horizontal error ellipse
//!   (semi-major, semi-minor, orientation of the major axis from true north), from the
//!   fix's covariance; the RMS of range residuals (satellite-only) empty.
//! - GBS: the same σ of latitude, longitude and altitude, which gpsd reads into the fix's
//!   `epy`, `epx` and `epv` (GST only reaches gpsd's `GST` report).
//! - HDT: the true heading of the rig's +x axis.
//!
//! RMC carries the date, speed and course (mode `A`); a frame without a fix is GGA quality 0
//! and RMC status `V`, as a receiver keeps talking when it loses its fix.

use super::FrameOutcome;
use super::VisualFix;
use super::derived::{finite, wrap_deg};
use super::time::utc_fields;
use crate::drive::nmea::{checksum, format_angle, push_sentence};
use nalgebra::{Matrix2, SymmetricEigen};
use vgps_geometry::geo::{Geodetic, LocalFrame};

/// The talker identifier of every sentence (`GP`: understood by every consumer).
pub const NMEA_TALKER: &str = "GP";

/// Metres per second in one knot.
const MPS_PER_KNOT: f64 = 1852.0 / 3600.0;

/// Longest time between two fixes (seconds) over which RMC's speed and course are computed.
pub const MAX_VELOCITY_GAP_S: f64 = 2.0;

/// Decimals of the minutes of latitude and longitude (1e-7 min ≈ 0.19 mm).
const MINUTE_DECIMALS: usize = 7;

/// Decimals of every σ (metres): millimetres, as in `fixes.csv`, so that a reader of either
/// file gets the same numbers.
const SIGMA_DECIMALS: usize = 3;

/// GGA fix quality of every visual fix: 1, "fix valid" (see the module docs for why not
/// 6 or another code).
pub const GGA_QUALITY_VISUAL: u8 = 1;

/// The NMEA checksum: the XOR of every byte between `$` and `*` (exclusive), as two
/// upper-case hex digits. `body` is that text without `$` and `*`.
///
/// # Example
/// ```
/// use vgps_replay::report::nmea_checksum;
/// assert_eq!(nmea_checksum("GPHDT,274.07,T"), "03");
/// ```
pub fn nmea_checksum(body: &str) -> String {
    format!("{:02X}", checksum(body))
}

fn position(g: &Geodetic) -> String {
    format!(
        "{},{}",
        format_angle(g.lat_deg, 2, MINUTE_DECIMALS, 'N', 'S'),
        format_angle(g.lon_deg, 3, MINUTE_DECIMALS, 'E', 'W')
    )
}

fn num(x: Option<f64>, decimals: usize) -> String {
    x.and_then(finite)
        .map(|v| format!("{v:.decimals$}"))
        .unwrap_or_default()
}

/// The 1-σ horizontal error ellipse of an east-north covariance (m²): semi-major and
/// semi-minor σ (metres) and the orientation of the semi-major axis, degrees clockwise from
/// true north in [0, 180). `None` when the covariance is not finite.
///
/// # Example
/// ```
/// use nalgebra::Matrix2;
/// use vgps_replay::report::error_ellipse;
/// // 4 m² along north-east, 1 m² across: major axis at 45°.
/// let c = 0.5 * Matrix2::new(5.0, 3.0, 3.0, 5.0);
/// let (major, minor, orientation) = error_ellipse(&c).unwrap();
/// assert!((major - 2.0).abs() < 1e-12 && (minor - 1.0).abs() < 1e-12);
/// assert!((orientation - 45.0).abs() < 1e-9);
/// ```
pub fn error_ellipse(covariance_en_m2: &Matrix2<f64>) -> Option<(f64, f64, f64)> {
    if !covariance_en_m2.iter().all(|x| x.is_finite()) {
        return None;
    }
    let symmetric = 0.5 * (covariance_en_m2 + covariance_en_m2.transpose());
    let eigen = SymmetricEigen::new(symmetric);
    let (major, minor) = if eigen.eigenvalues[0] >= eigen.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let axis = eigen.eigenvectors.column(major);
    // Clockwise from north: atan2(east, north).
    let orientation = axis[0].atan2(axis[1]).to_degrees().rem_euclid(180.0);
    Some((
        eigen.eigenvalues[major].max(0.0).sqrt(),
        eigen.eigenvalues[minor].max(0.0).sqrt(),
        orientation,
    ))
}

/// Writes the NMEA sentences of one frame after another, remembering the previous fix for
/// RMC's speed and course: [`fixes_nmea`] for a whole replay, or one frame at a time for a
/// live stream ([`crate::live::NmeaTcpServer`]).
#[derive(Clone, Debug, Default)]
pub struct NmeaEpochWriter {
    previous: Option<(f64, Geodetic)>,
}

impl NmeaEpochWriter {
    /// A writer that has seen no frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// The sentences of one frame (empty when its time is not finite):
    ///
    /// - with a visual fix: `GGA` (quality [`GGA_QUALITY_VISUAL`], satellites = landmarks +
    ///   surrogates, HDOP empty, altitude = the ellipsoidal height with geoid separation 0.0,
    ///   as vgps has no geoid model), `RMC` (status `A`, speed in knots and course over ground
    ///   from the previous fix when it is at most [`MAX_VELOCITY_GAP_S`] earlier, mode `A`),
    ///   `GST` (error ellipse and σ of latitude, longitude, altitude), `GBS` (σ of latitude,
    ///   longitude, altitude) and `HDT` (when the heading is finite);
    /// - without: `GGA` quality 0 with empty position and `RMC` status `V`, mode `N`.
    ///
    /// Talker `GP`, lines end in `\r\n`, every sentence carries its checksum.
    pub fn epoch(&mut self, time_s: f64, visual: Option<&VisualFix>) -> String {
        let mut out = String::new();
        let Some(t) = utc_fields(time_s, 2) else {
            return out;
        };
        let hms = format!(
            "{:02}{:02}{:02}.{:02}",
            t.hour, t.minute, t.second, t.fraction
        );
        let date = format!("{:02}{:02}{:02}", t.day, t.month, t.year.rem_euclid(100));
        let Some(v) = visual else {
            push_sentence(
                &mut out,
                &format!("{NMEA_TALKER}GGA,{hms},,,,,0,00,,,M,,M,,"),
            );
            push_sentence(
                &mut out,
                &format!("{NMEA_TALKER}RMC,{hms},V,,,,,,,{date},,,N"),
            );
            return out;
        };
        let g = &v.geodetic;
        let sats = (v.n_landmarks + v.n_surrogates).min(99);
        push_sentence(
            &mut out,
            &format!(
                "{NMEA_TALKER}GGA,{hms},{},{GGA_QUALITY_VISUAL},{sats:02},,{},M,0.0,M,,",
                position(g),
                num(Some(g.alt_m), 3),
            ),
        );
        let (speed, course) = match self.previous {
            Some((t0, g0)) if time_s > t0 && time_s - t0 <= MAX_VELOCITY_GAP_S => {
                let d = LocalFrame::new(g0).to_enu(g);
                let speed = d.xy().norm() / (time_s - t0) / MPS_PER_KNOT;
                let course = wrap_deg(d.x.atan2(d.y).to_degrees()).rem_euclid(360.0);
                (Some(speed), (d.xy().norm() > 0.0).then_some(course))
            }
            _ => (None, None),
        };
        push_sentence(
            &mut out,
            &format!(
                "{NMEA_TALKER}RMC,{hms},A,{},{},{},{date},,,A",
                position(g),
                num(speed, 3),
                num(course, 2),
            ),
        );
        let sigma = |x: f64| num(Some(x), SIGMA_DECIMALS);
        let (major, minor, orientation) = error_ellipse(&v.horizontal_covariance_m2)
            .map_or((None, None, None), |(a, b, o)| (Some(a), Some(b), Some(o)));
        push_sentence(
            &mut out,
            &format!(
                "{NMEA_TALKER}GST,{hms},,{},{},{},{},{},{}",
                num(major, SIGMA_DECIMALS),
                num(minor, SIGMA_DECIMALS),
                num(orientation, 1),
                sigma(v.sigma_n_m),
                sigma(v.sigma_e_m),
                sigma(v.sigma_u_m),
            ),
        );
        push_sentence(
            &mut out,
            &format!(
                "{NMEA_TALKER}GBS,{hms},{},{},{},,,,",
                sigma(v.sigma_n_m),
                sigma(v.sigma_e_m),
                sigma(v.sigma_u_m),
            ),
        );
        if let Some(h) = finite(v.heading_deg) {
            push_sentence(
                &mut out,
                &format!("{NMEA_TALKER}HDT,{:.2},T", h.rem_euclid(360.0)),
            );
        }
        self.previous = Some((time_s, *g));
        out
    }
}

/// `fixes.nmea`: the sentences of [`NmeaEpochWriter::epoch`] for every frame, in order
/// (frames with a non-finite time are skipped).
pub fn fixes_nmea(records: &[FrameOutcome]) -> String {
    let mut writer = NmeaEpochWriter::new();
    records
        .iter()
        .map(|r| writer.epoch(r.time_s, r.visual.as_ref()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_carry_and_hemispheres() {
        assert_eq!(
            format_angle(48.5, 2, MINUTE_DECIMALS, 'N', 'S'),
            "4830.0000000,N"
        );
        assert_eq!(
            format_angle(-11.25, 3, MINUTE_DECIMALS, 'E', 'W'),
            "01115.0000000,W"
        );
        // 59.99999999' rounds into the next degree.
        assert_eq!(
            format_angle(1.0 - 1e-11, 2, MINUTE_DECIMALS, 'N', 'S'),
            "0100.0000000,N"
        );
    }

    #[test]
    fn error_ellipse_of_axis_aligned_and_degenerate_covariances() {
        // Long axis east: orientation 90°.
        let (a, b, o) = error_ellipse(&Matrix2::new(9.0, 0.0, 0.0, 1.0)).unwrap();
        assert_eq!((a, b), (3.0, 1.0));
        assert!((o - 90.0).abs() < 1e-9, "{o}");
        // Long axis north: orientation 0°.
        let (_, _, o) = error_ellipse(&Matrix2::new(1.0, 0.0, 0.0, 9.0)).unwrap();
        assert!(o.abs() < 1e-9 || (o - 180.0).abs() < 1e-9, "{o}");
        // North-west: 135°.
        let (_, _, o) = error_ellipse(&Matrix2::new(5.0, -3.0, -3.0, 5.0)).unwrap();
        assert!((o - 135.0).abs() < 1e-9, "{o}");
        assert!(error_ellipse(&Matrix2::new(f64::NAN, 0.0, 0.0, 1.0)).is_none());
    }
}
