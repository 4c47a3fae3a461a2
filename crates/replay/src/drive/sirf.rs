//! Satellite GPS as SiRF receivers log it: the SiRF binary protocol (SiRF-II, SiRF-III,
//! SiRFstar IV; USB "GPS mice" such as the GlobalSat BU-303 and BU-353), possibly mixed with
//! NMEA sentences. Two messages give the epochs; every other message is counted and skipped:
//!
//! - **MID 41, Geodetic Navigation Data** (91 bytes): UTC date and time, latitude and
//!   longitude (1e-7°), height above the ellipsoid (cm), navigation type, satellites used and
//!   HDOP. Used when its UTC date and time are valid.
//! - **MID 2, Measure Navigation Data Out** (41 bytes): ECEF position (whole metres),
//!   position mode, HDOP, GPS week and time of week (10 ms), satellites used. Used when the
//!   file has no MID 41 with a valid UTC time: SiRF-II firmware (2.x) sends MID 41 with its
//!   UTC fields all zero, as in gpsd's `bu303-moving` regression log.
//!
//! Reference: SiRF Technology, *SiRF Binary Protocol Reference Manual* (revision 2.4, 2008),
//! "Input/Output Messages": the frame, the checksum, MID 2 and MID 41 as decoded here. The
//! decoder is hand-written: no Rust crate reads SiRF binary; the frame and two fixed layouts
//! take less code than an adapter would.
//!
//! # Frame
//! `A0 A2 len(u16 BE, 15 bits) payload checksum(u16 BE) B0 B3`, the checksum being the sum of
//! the payload bytes modulo 2¹⁵; the payload's first byte is the message id (MID); all
//! fields are big-endian. A frame with a wrong checksum or end sequence is counted in
//! [`SirfStats::bad_checksum`], one cut by the end of the file in [`SirfStats::truncated`];
//! the scan goes on one byte later. A length above [`MAX_PAYLOAD`] is noise, not a frame.
//! Bytes outside frames go to the NMEA reader ([`super::nmea::read_nmea`]), whose epochs are
//! used only when the file has no SiRF epoch.
//!
//! # Time of MID 2
//! GPS time (week, time of week) becomes UTC by subtracting the GPS−UTC leap seconds in
//! force at that time ([`gps_minus_utc_s`], the IERS table up to the last leap second,
//! 2017-01-01; none has been announced since). SiRF-II sends the 10-bit week (0–1023); it
//! is taken in the era 1999-08-22 … 2019-04-06 ([`TEN_BIT_WEEK_ERA_START`]), the years these
//! receivers were sold. A log of such a receiver recorded after 2019-04-06 is 1024 weeks
//! early: correct it with a time offset of 619 315 200 s (`--gnss-time-offset`). gpsd, which
//! does not know the leap seconds of a SiRF-II log either, applies today's 18 s: its times
//! of `bu303-moving` (2005, 13 s) are 5 s earlier than these.
//!
//! # Solution type → GGA quality
//! The navigation type (MID 2 `Mode 1`, MID 41 `NAV Type`) bits 0–2: 3 (3 satellites, 2-D),
//! 4 (4 or more, 3-D), 5 (2-D least squares), 6 (3-D least squares) are a fix, quality 2
//! when bit 7 (DGPS corrections used) is set, else 1; 7 (dead reckoning) is quality 6; 0
//! (no solution), 1 and 2 (a one- or two-satellite Kalman propagation) are epochs without a
//! fix. A MID 41 whose `NAV Valid` is not 0 is an epoch without a fix.

use super::nmea::{self, GnssFix, GnssRecord, NmeaStats};
use crate::report::time::days_from_date;
use nalgebra::Vector3;
use vgps_geometry::geo::Geodetic;

/// The start sequence of a SiRF binary frame.
pub const START: [u8; 2] = [0xA0, 0xA2];
/// The end sequence of a SiRF binary frame.
pub const END: [u8; 2] = [0xB0, 0xB3];
/// The largest payload accepted, bytes (the protocol limits messages to fewer than 2¹¹
/// bytes; a larger length is taken as noise).
pub const MAX_PAYLOAD: usize = 2047;
/// MID of Measure Navigation Data Out (ECEF position, GPS time).
pub const MID_NAVIGATION: u8 = 2;
/// Payload length of MID 2, MID byte included.
pub const MID_NAVIGATION_LEN: usize = 41;
/// MID of Geodetic Navigation Data (UTC, latitude, longitude, ellipsoidal height).
pub const MID_GEODETIC: u8 = 41;
/// Payload length of MID 41, MID byte included.
pub const MID_GEODETIC_LEN: usize = 91;
/// Unix time of the GPS epoch, 1980-01-06 00:00:00 UTC (seconds).
pub const GPS_EPOCH_UNIX_S: i64 = 315_964_800;
/// A 10-bit GPS week (0–1023) is taken as this week plus itself: the era from 1999-08-22
/// to 2019-04-06.
pub const TEN_BIT_WEEK_ERA_START: u32 = 1024;

/// GPS−UTC leap seconds and the UTC date (Unix seconds) from which each holds.
const LEAP_SECONDS: [(i64, i64); 18] = [
    (362_793_600, 1),    // 1981-07-01
    (394_329_600, 2),    // 1982-07-01
    (425_865_600, 3),    // 1983-07-01
    (489_024_000, 4),    // 1985-07-01
    (567_993_600, 5),    // 1988-01-01
    (631_152_000, 6),    // 1990-01-01
    (662_688_000, 7),    // 1991-01-01
    (709_948_800, 8),    // 1992-07-01
    (741_484_800, 9),    // 1993-07-01
    (773_020_800, 10),   // 1994-07-01
    (820_454_400, 11),   // 1996-01-01
    (867_715_200, 12),   // 1997-07-01
    (915_148_800, 13),   // 1999-01-01
    (1_136_073_600, 14), // 2006-01-01
    (1_230_768_000, 15), // 2009-01-01
    (1_341_100_800, 16), // 2012-07-01
    (1_435_708_800, 17), // 2015-07-01
    (1_483_228_800, 18), // 2017-01-01
];

/// GPS−UTC (seconds) at the GPS time `gps_unix_s` (GPS seconds counted from the Unix epoch
/// as if GPS time were UTC): 0 before 1981-07-01, 18 since 2017-01-01.
///
/// # Example
/// ```
/// use vgps_replay::drive::sirf::gps_minus_utc_s;
/// assert_eq!(gps_minus_utc_s(1_118_327_702), 13); // June 2005
/// assert_eq!(gps_minus_utc_s(1_700_000_000), 18);
/// ```
pub fn gps_minus_utc_s(gps_unix_s: i64) -> i64 {
    LEAP_SECONDS
        .iter()
        .rev()
        .find(|(utc_start, n)| gps_unix_s >= utc_start + n)
        .map_or(0, |&(_, n)| n)
}

/// Counts of what the reader used and skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SirfStats {
    /// SiRF frames with a right checksum.
    pub frames: usize,
    /// MID 2 messages decoded.
    pub navigation: usize,
    /// MID 41 messages with a valid UTC time.
    pub geodetic: usize,
    /// MID 41 messages without a valid UTC time (SiRF-II; MID 2 is used instead).
    pub geodetic_untimed: usize,
    /// MID 2 or 41 messages with an invalid field (length, position out of range; skipped).
    pub invalid: usize,
    /// Frames of other messages (skipped).
    pub other: usize,
    /// Start bytes followed by a wrong checksum or end sequence.
    pub bad_checksum: usize,
    /// A frame cut by the end of the file.
    pub truncated: usize,
    /// Whether the epochs come from MID 41 (else MID 2, else NMEA).
    pub from_geodetic: bool,
    /// Whether the epochs come from the NMEA sentences (no SiRF epoch in the file).
    pub from_nmea: bool,
    /// The NMEA reader's counts over the bytes outside the SiRF frames.
    pub nmea: NmeaStats,
}

impl SirfStats {
    /// SiRF frames skipped for any reason (not counting NMEA lines nor the MID 41s set aside
    /// for MID 2).
    pub fn skipped(&self) -> usize {
        self.invalid + self.other + self.bad_checksum + self.truncated
    }
}

/// The SiRF checksum of a payload: the sum of its bytes modulo 2¹⁵.
///
/// # Example
/// ```
/// // MID 132, Poll Software Version (SiRF manual): A0 A2 00 02 84 00 00 84 B0 B3.
/// assert_eq!(vgps_replay::drive::sirf::checksum(&[0x84, 0x00]), 0x0084);
/// ```
pub fn checksum(payload: &[u8]) -> u16 {
    let sum = payload
        .iter()
        .fold(0u32, |s, &b| (s + u32::from(b)) & 0x7FFF);
    sum as u16
}

enum SirfFrame<'a> {
    Ok(&'a [u8], usize),
    BadChecksum,
    Truncated,
    NoStart,
}

fn frame_at(bytes: &[u8]) -> SirfFrame<'_> {
    if !bytes.starts_with(&START) {
        return SirfFrame::NoStart;
    }
    let Some(len) = bytes.get(2..4) else {
        return SirfFrame::Truncated;
    };
    let len = usize::from(u16::from_be_bytes([len[0], len[1]]));
    if len == 0 || len > MAX_PAYLOAD {
        return SirfFrame::NoStart;
    }
    let Some(tail) = bytes.get(4 + len..8 + len) else {
        return SirfFrame::Truncated;
    };
    let payload = &bytes[4..4 + len];
    if u16::from_be_bytes([tail[0], tail[1]]) != checksum(payload) || tail[2..] != END {
        return SirfFrame::BadChecksum;
    }
    SirfFrame::Ok(payload, 8 + len)
}

fn find_start(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == START)
}

/// Whether `bytes` hold at least one SiRF frame with a right checksum and end sequence
/// (format detection).
pub fn contains_sirf(bytes: &[u8]) -> bool {
    let mut at = 0;
    while let Some(k) = find_start(&bytes[at..]) {
        if let SirfFrame::Ok(..) = frame_at(&bytes[at + k..]) {
            return true;
        }
        at += k + 1;
    }
    false
}

fn u16_at(p: &[u8], k: usize) -> u16 {
    u16::from_be_bytes([p[k], p[k + 1]])
}

fn u32_at(p: &[u8], k: usize) -> u32 {
    u32::from_be_bytes([p[k], p[k + 1], p[k + 2], p[k + 3]])
}

fn i32_at(p: &[u8], k: usize) -> i32 {
    i32::from_be_bytes([p[k], p[k + 1], p[k + 2], p[k + 3]])
}

/// GGA quality of a SiRF navigation type (see the module documentation).
fn quality_of(nav_type: u8) -> Option<u8> {
    match nav_type & 0b111 {
        3..=6 if nav_type & 0x80 != 0 => Some(2),
        3..=6 => Some(1),
        7 => Some(6),
        _ => None,
    }
}

/// Why a MID 2 or 41 is not an epoch.
enum Skip {
    Untimed,
    Invalid,
}

/// The 0.2-unit HDOP byte of MID 2 and 41 (0: not given).
fn hdop(byte: u8) -> Option<f64> {
    (byte > 0).then_some(f64::from(byte) * 0.2)
}

/// Decodes MID 2 (Measure Navigation Data Out) into an epoch.
fn navigation(p: &[u8]) -> Result<GnssRecord, Skip> {
    if p.len() < MID_NAVIGATION_LEN {
        return Err(Skip::Invalid);
    }
    let mode1 = p[19];
    let week = u32::from(u16_at(p, 22));
    let tow_cs = u32_at(p, 24);
    if tow_cs >= 60_480_000 {
        return Err(Skip::Invalid);
    }
    let week = if week < 1024 {
        week + TEN_BIT_WEEK_ERA_START
    } else {
        week
    };
    let gps_s = GPS_EPOCH_UNIX_S + i64::from(week) * 604_800;
    let gps_time = gps_s as f64 + f64::from(tow_cs) * 0.01;
    let time_s = gps_time - gps_minus_utc_s(gps_s + i64::from(tow_cs / 100)) as f64;
    let fix = match quality_of(mode1) {
        None => None,
        Some(quality) => {
            let ecef = Vector3::new(
                f64::from(i32_at(p, 1)),
                f64::from(i32_at(p, 5)),
                f64::from(i32_at(p, 9)),
            );
            let position = Geodetic::try_from_ecef(&ecef).map_err(|_| Skip::Invalid)?;
            Some(GnssFix {
                position,
                quality,
                hdop: hdop(p[20]),
                num_sats: Some(u32::from(p[28])),
            })
        }
    };
    Ok(GnssRecord {
        time_s,
        fix,
        heading_deg: None,
    })
}

/// Decodes MID 41 (Geodetic Navigation Data) into an epoch.
fn geodetic(p: &[u8]) -> Result<GnssRecord, Skip> {
    if p.len() < MID_GEODETIC_LEN {
        return Err(Skip::Invalid);
    }
    let (nav_valid, nav_type) = (u16_at(p, 1), u16_at(p, 3));
    let year = i64::from(u16_at(p, 11));
    let (month, day, hour, minute) = (p[13], p[14], p[15], p[16]);
    let millis = u16_at(p, 17);
    if !(1980..=2200).contains(&year) || hour > 23 || minute > 59 || millis >= 61_000 {
        return Err(Skip::Untimed);
    }
    let days = days_from_date(year, u32::from(month), u32::from(day)).ok_or(Skip::Untimed)?;
    let time_s = days as f64 * 86_400.0
        + f64::from(u32::from(hour) * 3600 + u32::from(minute) * 60)
        + f64::from(millis) * 1e-3;
    let quality = if nav_valid == 0 {
        quality_of((nav_type & 0xFF) as u8)
    } else {
        None
    };
    let fix = match quality {
        None => None,
        Some(quality) => {
            let lat = f64::from(i32_at(p, 23)) * 1e-7;
            let lon = f64::from(i32_at(p, 27)) * 1e-7;
            let height = f64::from(i32_at(p, 31)) * 0.01;
            if lat.abs() > 90.0 || lon.abs() > 180.0 {
                return Err(Skip::Invalid);
            }
            let position = Geodetic::try_new(lat, lon, height).map_err(|_| Skip::Invalid)?;
            Some(GnssFix {
                position,
                quality,
                hdop: hdop(p[89]),
                num_sats: Some(u32::from(p[88])),
            })
        }
    };
    Ok(GnssRecord {
        time_s,
        fix,
        heading_deg: None,
    })
}

/// Reads a SiRF binary log (SiRF frames, NMEA sentences, noise) into epochs sorted by time
/// and the counts. Never fails: what cannot be used is counted.
///
/// # Example
/// ```
/// use vgps_replay::drive::sirf::{checksum, read_sirf};
/// // A MID 2 of GPS week 302 (10-bit), time of week 398102.28 s: 2005-06-09 14:34:49.28
/// // UTC (13 leap seconds), a 3-D fix (mode 4) at ECEF (4360953, 579351, 4604558) m.
/// let mut p = vec![0u8; 41];
/// p[0] = 2;
/// p[1..5].copy_from_slice(&4_360_953i32.to_be_bytes());
/// p[5..9].copy_from_slice(&579_351i32.to_be_bytes());
/// p[9..13].copy_from_slice(&4_604_558i32.to_be_bytes());
/// (p[19], p[20], p[28]) = (4, 12, 5);
/// p[22..24].copy_from_slice(&302u16.to_be_bytes());
/// p[24..28].copy_from_slice(&39_810_228u32.to_be_bytes());
/// let mut frame = vec![0xA0, 0xA2, 0, 41];
/// frame.extend_from_slice(&p);
/// frame.extend_from_slice(&checksum(&p).to_be_bytes());
/// frame.extend_from_slice(&[0xB0, 0xB3]);
/// let (records, stats) = read_sirf(&[b"\xff\x00".as_slice(), &frame].concat());
/// assert_eq!((records.len(), stats.navigation), (1, 1));
/// assert!((records[0].time_s - 1_118_327_689.28).abs() < 1e-6);
/// let fix = records[0].fix.unwrap();
/// assert_eq!((fix.quality, fix.num_sats), (1, Some(5)));
/// assert!((fix.hdop.unwrap() - 2.4).abs() < 1e-12);
/// assert!((fix.position.lat_deg - 46.498287177).abs() < 1e-9);
/// ```
pub fn read_sirf(bytes: &[u8]) -> (Vec<GnssRecord>, SirfStats) {
    let mut stats = SirfStats::default();
    let (mut from_mid2, mut from_mid41) = (Vec::new(), Vec::new());
    let mut rest: Vec<u8> = Vec::with_capacity(bytes.len());
    let mut at = 0;
    while at < bytes.len() {
        let Some(k) = find_start(&bytes[at..]) else {
            rest.extend_from_slice(&bytes[at..]);
            break;
        };
        rest.extend_from_slice(&bytes[at..at + k]);
        at += k;
        match frame_at(&bytes[at..]) {
            SirfFrame::Ok(payload, taken) => {
                stats.frames += 1;
                match payload[0] {
                    MID_NAVIGATION => match navigation(payload) {
                        Ok(r) => {
                            stats.navigation += 1;
                            from_mid2.push(r);
                        }
                        Err(_) => stats.invalid += 1,
                    },
                    MID_GEODETIC => match geodetic(payload) {
                        Ok(r) => {
                            stats.geodetic += 1;
                            from_mid41.push(r);
                        }
                        Err(Skip::Untimed) => stats.geodetic_untimed += 1,
                        Err(Skip::Invalid) => stats.invalid += 1,
                    },
                    _ => stats.other += 1,
                }
                // A frame becomes a line break, so it never joins the text around it.
                rest.push(b'\n');
                at += taken;
            }
            other => {
                match other {
                    SirfFrame::Truncated => stats.truncated += 1,
                    SirfFrame::BadChecksum => stats.bad_checksum += 1,
                    _ => {}
                }
                rest.push(bytes[at]);
                at += 1;
            }
        }
    }
    let (nmea_records, nmea_stats) = nmea::read_nmea(&String::from_utf8_lossy(&rest));
    stats.nmea = nmea_stats;
    let mut records = if !from_mid41.is_empty() {
        stats.from_geodetic = true;
        from_mid41
    } else if !from_mid2.is_empty() {
        from_mid2
    } else {
        stats.from_nmea = true;
        nmea_records
    };
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    (records, stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(payload: &[u8]) -> Vec<u8> {
        let mut f = vec![0xA0, 0xA2];
        f.extend_from_slice(&(payload.len() as u16).to_be_bytes());
        f.extend_from_slice(payload);
        f.extend_from_slice(&checksum(payload).to_be_bytes());
        f.extend_from_slice(&END);
        f
    }

    fn mid41(nav_valid: u16, nav_type: u16, year: u16) -> Vec<u8> {
        let mut p = vec![0u8; MID_GEODETIC_LEN];
        p[0] = MID_GEODETIC;
        p[1..3].copy_from_slice(&nav_valid.to_be_bytes());
        p[3..5].copy_from_slice(&nav_type.to_be_bytes());
        p[11..13].copy_from_slice(&year.to_be_bytes());
        (p[13], p[14], p[15], p[16]) = (12, 31, 23, 59);
        p[17..19].copy_from_slice(&60_500u16.to_be_bytes()); // a leap second: 60.5 s
        p[23..27].copy_from_slice(&377_793_000i32.to_be_bytes());
        p[27..31].copy_from_slice(&(-1_224_193_000i32).to_be_bytes());
        p[31..35].copy_from_slice(&(-1_234i32).to_be_bytes());
        (p[88], p[89]) = (7, 6);
        p
    }

    #[test]
    fn known_answer_checksums() {
        // The SiRF manual's Poll Software Version (A0 A2 00 02 84 00 00 84 B0 B3), then sums
        // past 255 (kept: 15 bits) and past 2^15 (wrapped).
        assert_eq!(checksum(&[0x84, 0x00]), 0x0084);
        assert_eq!(checksum(&[0xFF; 200]), (200 * 255) as u16 & 0x7FFF);
        assert_eq!(checksum(&[0xFF; 130]), (130 * 255 - 32_768) as u16);
        // A payload summing to exactly 2^15 has checksum 0.
        let mut p = vec![0xFF; 128];
        p.push(128);
        assert_eq!(checksum(&p), 0);
    }

    #[test]
    fn geodetic_messages_give_utc_epochs_and_qualities() {
        let cases = [
            (0, 4, Some(1)),
            (0, 0x84, Some(2)),
            (0, 6, Some(1)),
            (0, 7, Some(6)),
            (0, 2, None),
            (0, 0, None),
            (1, 4, None), // NAV Valid not 0
        ];
        for (valid, nav_type, quality) in cases {
            let (r, s) = read_sirf(&frame(&mid41(valid, nav_type, 2016)));
            assert_eq!((r.len(), s.geodetic, s.from_geodetic), (1, 1, true));
            assert_eq!(
                r[0].fix.map(|f| f.quality),
                quality,
                "{valid} {nav_type:#x}"
            );
        }
        let (r, _) = read_sirf(&frame(&mid41(0, 4, 2016)));
        let expected = days_from_date(2016, 12, 31).unwrap() as f64 * 86_400.0 + 86_400.5;
        assert!((r[0].time_s - expected).abs() < 1e-6);
        let f = r[0].fix.unwrap();
        assert!((f.position.lat_deg - 37.7793).abs() < 1e-12);
        assert!((f.position.lon_deg + 122.4193).abs() < 1e-12);
        assert!((f.position.alt_m + 12.34).abs() < 1e-9);
        assert_eq!((f.num_sats, f.hdop), (Some(7), Some(6.0 * 0.2)));
        // A MID 41 without UTC (SiRF-II) is set aside, not an epoch.
        let (r, s) = read_sirf(&frame(&mid41(0, 4, 0)));
        assert_eq!((r.len(), s.geodetic_untimed, s.from_nmea), (0, 1, true));
    }

    #[test]
    fn leap_seconds_and_ten_bit_weeks() {
        assert_eq!(gps_minus_utc_s(0), 0);
        assert_eq!(gps_minus_utc_s(1_483_228_800 + 17), 17);
        assert_eq!(gps_minus_utc_s(1_483_228_800 + 18), 18);
        // GPS week 1024 + 302 starts on 2005-06-05.
        let mut p = vec![0u8; MID_NAVIGATION_LEN];
        p[0] = MID_NAVIGATION;
        p[19] = 6;
        p[22..24].copy_from_slice(&302u16.to_be_bytes());
        p[1..5].copy_from_slice(&6_378_137i32.to_be_bytes());
        let (r, _) = read_sirf(&frame(&p));
        let sunday = days_from_date(2005, 6, 5).unwrap() as f64 * 86_400.0;
        assert!((r[0].time_s - (sunday - 13.0)).abs() < 1e-9);
        // The extended week (≥ 1024) is taken as it is.
        p[22..24].copy_from_slice(&1326u16.to_be_bytes());
        assert_eq!(read_sirf(&frame(&p)).0[0].time_s, r[0].time_s);
    }

    #[test]
    fn bad_frames_are_counted_and_the_scan_goes_on() {
        let good = frame(&mid41(0, 4, 2016));
        let mut corrupt = good.clone();
        corrupt[40] ^= 0xFF;
        let mut bad_end = good.clone();
        let n = bad_end.len();
        bad_end[n - 1] = 0;
        let short = frame(&[MID_GEODETIC, 0, 0]);
        let mut far = mid41(0, 4, 2016);
        far[23..27].copy_from_slice(&950_000_000i32.to_be_bytes());
        let mut ecef_zero = vec![0u8; MID_NAVIGATION_LEN];
        (ecef_zero[0], ecef_zero[19]) = (MID_NAVIGATION, 4);
        let other = frame(&[9, 1, 2, 3]);
        let log = [
            b"\x00\xa0\xa0\xa2\xff\xff".as_slice(), // a length beyond the limit: noise
            &corrupt,
            &bad_end,
            &short,
            &frame(&far),
            &frame(&ecef_zero),
            &other,
            &good,
            b"$GPTXT,hello\r\n".as_slice(),
            &good[..30],
        ]
        .concat();
        let (r, s) = read_sirf(&log);
        assert_eq!(r.len(), 1);
        assert_eq!(
            (
                s.frames,
                s.geodetic,
                s.invalid,
                s.other,
                s.bad_checksum,
                s.truncated
            ),
            (5, 1, 3, 1, 2, 1),
            "{s:?}"
        );
        assert!(contains_sirf(&log) && !contains_sirf(&corrupt) && !contains_sirf(b"$GPGGA"));
        // Every prefix of the log is read without a panic.
        for k in 0..log.len() {
            let (r, _) = read_sirf(&log[..k]);
            assert!(r.iter().all(|r| r.time_s.is_finite()));
        }
    }
}
