//! `fixes.nmea`: NMEA 0183 sentences (GGA, RMC, GST, HDT) for every frame.

use super::FrameRecord;
use super::derived::{finite, wrap_deg};
use super::time::utc_fields;
use crate::drive::nmea::{checksum, format_angle, push_sentence};
use vgps_geometry::geo::{Geodetic, LocalFrame};

/// The talker identifier of every sentence (`GP`: understood by every consumer).
pub const NMEA_TALKER: &str = "GP";

/// Metres per second in one knot.
const MPS_PER_KNOT: f64 = 1852.0 / 3600.0;

/// Longest time between two fixes (seconds) over which RMC's speed and course are computed.
pub const MAX_VELOCITY_GAP_S: f64 = 2.0;

/// Decimals of the minutes of latitude and longitude (1e-6 min ≈ 2 mm).
const MINUTE_DECIMALS: usize = 6;

/// GGA fix quality of a fix with at least 3 surveyed landmarks ("GPS fix").
pub const GGA_QUALITY_FIX: u8 = 1;
/// GGA fix quality of a surrogate-only fix ("estimated").
pub const GGA_QUALITY_ESTIMATED: u8 = 6;

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

/// `fixes.nmea`: for every frame with a finite time, in order,
///
/// - `GGA` (time, position, quality 1 for a fix with ≥ 3 surveyed landmarks, 6 "estimated"
///   for a surrogate-only fix, 0 with empty position for a frame without fix; satellites =
///   landmarks + surrogates (at most 99); HDOP = horizontal σ in metres; altitude = the
///   ellipsoidal height with geoid separation 0, as vgps has no geoid model);
/// - `RMC` (status `A` with position, or `V` without; speed in knots and course over ground
///   from the previous fix when it is at most [`MAX_VELOCITY_GAP_S`] earlier, else empty;
///   date `ddmmyy`; mode `A`, `E` for surrogate-only, `N` without fix);
/// - `GST` for a fix (σ of latitude, longitude and altitude in metres; the error ellipse
///   fields empty);
/// - `HDT` for a fix (true heading, degrees).
///
/// Talker `GP`, lines end in `\r\n`, every sentence carries its checksum.
pub fn fixes_nmea(records: &[FrameRecord]) -> String {
    let mut out = String::new();
    let mut previous: Option<(f64, &Geodetic)> = None;
    for r in records {
        let Some(t) = utc_fields(r.time_s, 2) else {
            continue;
        };
        let hms = format!(
            "{:02}{:02}{:02}.{:02}",
            t.hour, t.minute, t.second, t.fraction
        );
        let date = format!("{:02}{:02}{:02}", t.day, t.month, t.year.rem_euclid(100));
        match &r.visual {
            Some(v) => {
                let g = &v.geodetic;
                let quality = if v.is_surrogate_only() {
                    GGA_QUALITY_ESTIMATED
                } else {
                    GGA_QUALITY_FIX
                };
                let sats = (v.n_landmarks + v.n_surrogates).min(99);
                let sigma_h = finite(v.sigma_e_m.hypot(v.sigma_n_m));
                push_sentence(
                    &mut out,
                    &format!(
                        "{NMEA_TALKER}GGA,{hms},{},{quality},{sats:02},{},{},M,0.0,M,,",
                        position(g),
                        num(sigma_h, 2),
                        num(Some(g.alt_m), 3),
                    ),
                );
                let (speed, course) = match previous {
                    Some((t0, g0)) if r.time_s > t0 && r.time_s - t0 <= MAX_VELOCITY_GAP_S => {
                        let d = LocalFrame::new(*g0).to_enu(g);
                        let speed = d.xy().norm() / (r.time_s - t0) / MPS_PER_KNOT;
                        let course = wrap_deg(d.x.atan2(d.y).to_degrees()).rem_euclid(360.0);
                        (Some(speed), (d.xy().norm() > 0.0).then_some(course))
                    }
                    _ => (None, None),
                };
                let mode = if v.is_surrogate_only() { 'E' } else { 'A' };
                push_sentence(
                    &mut out,
                    &format!(
                        "{NMEA_TALKER}RMC,{hms},A,{},{},{},{date},,,{mode}",
                        position(g),
                        num(speed, 3),
                        num(course, 2),
                    ),
                );
                push_sentence(
                    &mut out,
                    &format!(
                        "{NMEA_TALKER}GST,{hms},,,,,{},{},{}",
                        num(Some(v.sigma_n_m), 3),
                        num(Some(v.sigma_e_m), 3),
                        num(Some(v.sigma_u_m), 3),
                    ),
                );
                if let Some(h) = finite(v.heading_deg) {
                    push_sentence(
                        &mut out,
                        &format!("{NMEA_TALKER}HDT,{:.2},T", h.rem_euclid(360.0)),
                    );
                }
                previous = Some((r.time_s, g));
            }
            None => {
                push_sentence(
                    &mut out,
                    &format!("{NMEA_TALKER}GGA,{hms},,,,,0,00,,,M,,M,,"),
                );
                push_sentence(
                    &mut out,
                    &format!("{NMEA_TALKER}RMC,{hms},V,,,,,,,{date},,,N"),
                );
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_carry_and_hemispheres() {
        assert_eq!(
            format_angle(48.5, 2, MINUTE_DECIMALS, 'N', 'S'),
            "4830.000000,N"
        );
        assert_eq!(
            format_angle(-11.25, 3, MINUTE_DECIMALS, 'E', 'W'),
            "01115.000000,W"
        );
        // 59.9999999' rounds into the next degree.
        assert_eq!(
            format_angle(1.0 - 1e-10, 2, MINUTE_DECIMALS, 'N', 'S'),
            "0100.000000,N"
        );
    }
}
