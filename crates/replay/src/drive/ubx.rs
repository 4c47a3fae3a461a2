//! Satellite GPS as u-blox receivers log it: the UBX binary protocol, usually mixed with
//! NMEA sentences on the same port. `UBX-NAV-PVT` (class 0x01, id 0x07) gives each epoch's
//! UTC time, position, ellipsoidal height and solution type; every other UBX message is
//! counted and skipped. The NMEA between the UBX frames is read by [`super::nmea::read_nmea`]
//! and used only when the file has no `NAV-PVT` (a receiver that sends both gives the same
//! epochs twice, NAV-PVT to 1 mm and 1e-7°, GGA rounded to its decimals).
//!
//! The decoder is small and hand-written: the `ublox` crate (0.10) was considered; it is a
//! device-communication library (its parser needs a protocol version chosen at build time and
//! brings its own buffer types), while reading `NAV-PVT` from a log takes the frame layout
//! and the Fletcher checksum below (u-blox, *u-blox 8 / M8 Receiver Description*,
//! UBX-13003221, §32 "UBX Protocol"; *ZED-F9P Interface Description*, UBX-18010854).
//!
//! # Frame
//! `B5 62 class id len(u16 LE) payload ck_a ck_b`, the 8-bit Fletcher checksum over class,
//! id, length and payload. A frame whose checksum is wrong is counted in
//! [`UbxStats::bad_checksum`] and the scan goes on one byte later; a frame cut by the end of
//! the file (or sync bytes in noise whose length runs past it) in [`UbxStats::truncated`],
//! the scan going on one byte later. Bytes that are neither UBX nor NMEA (another binary
//! protocol, noise) are skipped by the NMEA reader and counted there.
//!
//! # Solution type → GGA quality
//! `fixType` 2 (2-D) or 3 (3-D) with `gnssFixOK`: RTK fixed (`carrSoln` 2) → 4, RTK float
//! (`carrSoln` 1) → 5, differential (`diffSoln`) → 2, else 1; `fixType` 1 (dead reckoning
//! only) or 4 (GNSS + dead reckoning) → 6; anything else (no fix, time only, or
//! `gnssFixOK` clear) is an epoch without a fix. An epoch whose UTC date and time are not
//! both valid (`valid` bits 0 and 1) cannot be placed on the drive clock and is counted in
//! [`UbxStats::untimed`].

use super::nmea::{self, GnssFix, GnssRecord, NmeaStats};
use crate::report::time::days_from_date;
use vgps_geometry::geo::Geodetic;

/// The two sync bytes of a UBX frame.
pub const SYNC: [u8; 2] = [0xB5, 0x62];
/// Class and id of `UBX-NAV-PVT`.
pub const NAV_PVT: (u8, u8) = (0x01, 0x07);
/// The payload length of `UBX-NAV-PVT` (protocol 15 and later).
pub const NAV_PVT_LEN: usize = 92;
/// The largest payload accepted (u-blox messages are at most a few kB; a larger length is
/// taken as noise, not a frame).
pub const MAX_PAYLOAD: usize = 8192;

/// Counts of what the reader used and skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct UbxStats {
    /// UBX frames with a right checksum.
    pub frames: usize,
    /// `NAV-PVT` frames read into epochs.
    pub nav_pvt: usize,
    /// `NAV-PVT` frames whose UTC date or time is not valid (skipped).
    pub untimed: usize,
    /// `NAV-PVT` frames with an invalid field (length, position out of range; skipped).
    pub invalid: usize,
    /// Frames of other messages (skipped).
    pub other: usize,
    /// Sync bytes followed by a wrong checksum.
    pub bad_checksum: usize,
    /// A frame cut by the end of the file.
    pub truncated: usize,
    /// Whether the epochs come from the NMEA sentences (no `NAV-PVT` in the file).
    pub from_nmea: bool,
    /// The NMEA reader's counts over the bytes outside the UBX frames.
    pub nmea: NmeaStats,
}

impl UbxStats {
    /// UBX frames skipped for any reason (not counting NMEA lines).
    pub fn skipped(&self) -> usize {
        self.untimed + self.invalid + self.other + self.bad_checksum + self.truncated
    }
}

/// The 8-bit Fletcher checksum of UBX over `bytes` (class, id, length, payload).
///
/// # Example
/// ```
/// // UBX-MON-VER poll: B5 62 0A 04 00 00 0E 34.
/// assert_eq!(vgps_replay::drive::ubx::fletcher(&[0x0A, 0x04, 0x00, 0x00]), (0x0E, 0x34));
/// ```
pub fn fletcher(bytes: &[u8]) -> (u8, u8) {
    bytes.iter().fold((0u8, 0u8), |(a, b), &x| {
        let a = a.wrapping_add(x);
        (a, b.wrapping_add(a))
    })
}

/// One UBX frame found at the start of `bytes`: (class, id, payload, bytes taken).
enum UbxFrame<'a> {
    Ok(u8, u8, &'a [u8], usize),
    BadChecksum,
    Truncated,
    /// No sync bytes at the start.
    NoSync,
}

fn frame_at(bytes: &[u8]) -> UbxFrame<'_> {
    if bytes.len() < 6 || bytes[..2] != SYNC {
        return if bytes.len() < 6 && bytes.starts_with(&SYNC) {
            UbxFrame::Truncated
        } else {
            UbxFrame::NoSync
        };
    }
    let len = usize::from(u16::from_le_bytes([bytes[4], bytes[5]]));
    if len > MAX_PAYLOAD {
        return UbxFrame::NoSync;
    }
    let Some(sum) = bytes.get(6 + len..8 + len) else {
        return UbxFrame::Truncated;
    };
    if fletcher(&bytes[2..6 + len]) != (sum[0], sum[1]) {
        return UbxFrame::BadChecksum;
    }
    UbxFrame::Ok(bytes[2], bytes[3], &bytes[6..6 + len], 8 + len)
}

/// Whether `bytes` hold at least one UBX frame with a right checksum (format detection).
pub fn contains_ubx(bytes: &[u8]) -> bool {
    let mut at = 0;
    while let Some(k) = find_sync(&bytes[at..]) {
        if let UbxFrame::Ok(..) = frame_at(&bytes[at + k..]) {
            return true;
        }
        at += k + 1;
    }
    false
}

fn find_sync(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == SYNC)
}

fn u16_at(p: &[u8], k: usize) -> u16 {
    u16::from_le_bytes([p[k], p[k + 1]])
}

fn i32_at(p: &[u8], k: usize) -> i32 {
    i32::from_le_bytes([p[k], p[k + 1], p[k + 2], p[k + 3]])
}

/// Why a `NAV-PVT` is not an epoch.
enum PvtSkip {
    Untimed,
    Invalid,
}

/// Decodes a `NAV-PVT` payload into an epoch.
fn nav_pvt(p: &[u8]) -> Result<GnssRecord, PvtSkip> {
    if p.len() < NAV_PVT_LEN {
        return Err(PvtSkip::Invalid);
    }
    let valid = p[11];
    if valid & 0b11 != 0b11 {
        return Err(PvtSkip::Untimed);
    }
    let (year, month, day) = (i64::from(u16_at(p, 4)), u32::from(p[6]), u32::from(p[7]));
    let (hour, minute, second) = (u32::from(p[8]), u32::from(p[9]), u32::from(p[10]));
    if hour > 23 || minute > 59 || second > 60 {
        return Err(PvtSkip::Invalid);
    }
    let days = days_from_date(year, month, day).ok_or(PvtSkip::Invalid)?;
    let nano = f64::from(i32_at(p, 16));
    let time_s =
        days as f64 * 86_400.0 + f64::from(hour * 3600 + minute * 60 + second) + nano * 1e-9;
    let (fix_type, flags) = (p[20], p[21]);
    let fix_ok = flags & 1 == 1;
    let quality = match fix_type {
        2 | 3 if fix_ok => match (flags >> 6) & 0b11 {
            2 => Some(4),
            1 => Some(5),
            _ if flags & 0b10 != 0 => Some(2),
            _ => Some(1),
        },
        1 | 4 if fix_ok => Some(6),
        _ => None,
    };
    let fix = match quality {
        None => None,
        Some(quality) => {
            let lon = f64::from(i32_at(p, 24)) * 1e-7;
            let lat = f64::from(i32_at(p, 28)) * 1e-7;
            let height = f64::from(i32_at(p, 32)) * 1e-3;
            let position = Geodetic::try_new(lat, lon, height).map_err(|_| PvtSkip::Invalid)?;
            let pdop = f64::from(u16_at(p, 76)) * 0.01;
            Some(GnssFix {
                position,
                quality,
                // NAV-PVT gives the PDOP, not the HDOP; it is kept here as the receiver's
                // dilution of precision (an upper bound of the HDOP).
                hdop: (pdop > 0.0).then_some(pdop),
                num_sats: Some(u32::from(p[23])),
            })
        }
    };
    Ok(GnssRecord {
        time_s,
        fix,
        heading_deg: None,
    })
}

/// Reads a u-blox log (UBX frames, NMEA sentences, noise) into epochs sorted by time and
/// the counts. Never fails: what cannot be used is counted.
///
/// # Example
/// ```
/// use vgps_replay::drive::ubx::{fletcher, read_ubx};
/// // A NAV-PVT of 2022-10-11 11:04:25 UTC, 3-D RTK float fix at 47.1290927° N 15.2120432° E,
/// // 869.218 m, between two lines of noise.
/// let mut p = vec![0u8; 92];
/// p[4..6].copy_from_slice(&2022u16.to_le_bytes());
/// (p[6], p[7], p[8], p[9], p[10], p[11]) = (10, 11, 11, 4, 25, 0b111);
/// (p[20], p[21], p[23]) = (3, 0b0100_0011, 24);
/// p[24..28].copy_from_slice(&152_120_432i32.to_le_bytes());
/// p[28..32].copy_from_slice(&471_290_927i32.to_le_bytes());
/// p[32..36].copy_from_slice(&869_218i32.to_le_bytes());
/// let mut frame = vec![0xB5, 0x62, 0x01, 0x07, 92, 0];
/// frame.extend_from_slice(&p);
/// let (a, b) = fletcher(&frame[2..]);
/// frame.extend_from_slice(&[a, b]);
/// let log = [b"noise\n".as_slice(), &frame[..], b"\n\xff\xfe".as_slice()].concat();
/// let (records, stats) = read_ubx(&log);
/// assert_eq!((records.len(), stats.nav_pvt, stats.nmea.garbage), (1, 1, 2));
/// let fix = records[0].fix.unwrap();
/// assert_eq!(fix.quality, 5); // RTK float
/// assert_eq!(records[0].time_s, 1_665_486_265.0);
/// assert!((fix.position.lat_deg - 47.1290927).abs() < 1e-12);
/// assert!((fix.position.alt_m - 869.218).abs() < 1e-9);
/// ```
pub fn read_ubx(bytes: &[u8]) -> (Vec<GnssRecord>, UbxStats) {
    let mut stats = UbxStats::default();
    let mut records = Vec::new();
    // Bytes outside the UBX frames, for the NMEA reader; a frame is replaced by a line
    // break so that it never joins the text around it into one line.
    let mut rest: Vec<u8> = Vec::with_capacity(bytes.len());
    let mut at = 0;
    while at < bytes.len() {
        let Some(k) = find_sync(&bytes[at..]) else {
            rest.extend_from_slice(&bytes[at..]);
            break;
        };
        rest.extend_from_slice(&bytes[at..at + k]);
        at += k;
        match frame_at(&bytes[at..]) {
            UbxFrame::Ok(class, id, payload, taken) => {
                stats.frames += 1;
                if (class, id) == NAV_PVT {
                    match nav_pvt(payload) {
                        Ok(r) => {
                            stats.nav_pvt += 1;
                            records.push(r);
                        }
                        Err(PvtSkip::Untimed) => stats.untimed += 1,
                        Err(PvtSkip::Invalid) => stats.invalid += 1,
                    }
                } else {
                    stats.other += 1;
                }
                rest.push(b'\n');
                at += taken;
            }
            UbxFrame::Truncated => {
                // A frame cut by the end of the file, or sync bytes in noise whose length
                // runs past it: counted, and the scan goes on one byte later.
                stats.truncated += 1;
                rest.extend_from_slice(&bytes[at..at + 1]);
                at += 1;
            }
            UbxFrame::BadChecksum => {
                stats.bad_checksum += 1;
                rest.extend_from_slice(&bytes[at..at + 1]);
                at += 1;
            }
            UbxFrame::NoSync => {
                rest.extend_from_slice(&bytes[at..at + 1]);
                at += 1;
            }
        }
    }
    let text = String::from_utf8_lossy(&rest);
    let (nmea_records, nmea_stats) = nmea::read_nmea(&text);
    stats.nmea = nmea_stats;
    if records.is_empty() {
        stats.from_nmea = true;
        records = nmea_records;
    }
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    (records, stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
        let mut f = vec![0xB5, 0x62, class, id];
        f.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        f.extend_from_slice(payload);
        let (a, b) = fletcher(&f[2..]);
        f.extend_from_slice(&[a, b]);
        f
    }

    fn pvt(fix_type: u8, flags: u8, valid: u8) -> Vec<u8> {
        let mut p = vec![0u8; NAV_PVT_LEN];
        p[4..6].copy_from_slice(&2024u16.to_le_bytes());
        (p[6], p[7], p[8], p[9], p[10], p[11]) = (2, 29, 23, 59, 59, valid);
        p[16..20].copy_from_slice(&(-5_000_000i32).to_le_bytes());
        (p[20], p[21]) = (fix_type, flags);
        p[24..28].copy_from_slice(&(-1_224_193_000i32).to_le_bytes());
        p[28..32].copy_from_slice(&377_793_000i32.to_le_bytes());
        p[32..36].copy_from_slice(&(-12_345i32).to_le_bytes());
        p
    }

    #[test]
    fn solution_types_map_to_gga_qualities() {
        let cases = [
            (3, 0b0000_0001, Some(1)),
            (3, 0b0000_0011, Some(2)),
            (3, 0b0100_0011, Some(5)),
            (3, 0b1000_0011, Some(4)),
            (2, 0b0000_0001, Some(1)),
            (1, 0b0000_0001, Some(6)),
            (3, 0b0000_0000, None), // gnssFixOK clear
            (0, 0b0000_0001, None),
            (5, 0b0000_0001, None), // time only
        ];
        for (fix_type, flags, quality) in cases {
            let (r, s) = read_ubx(&frame(1, 7, &pvt(fix_type, flags, 0b111)));
            assert_eq!(s.nav_pvt, 1);
            assert_eq!(
                r[0].fix.map(|f| f.quality),
                quality,
                "{fix_type} {flags:#b}"
            );
        }
        // Leap day, negative nanoseconds: 2024-02-29 23:59:58.995 UTC.
        let (r, _) = read_ubx(&frame(1, 7, &pvt(3, 1, 0b111)));
        let expected = days_from_date(2024, 2, 29).unwrap() as f64 * 86_400.0 + 86_398.995;
        assert!((r[0].time_s - expected).abs() < 1e-6);
        let p = r[0].fix.unwrap().position;
        assert!((p.lat_deg - 37.7793).abs() < 1e-12 && (p.lon_deg + 122.4193).abs() < 1e-12);
        assert!((p.alt_m + 12.345).abs() < 1e-12);
    }

    #[test]
    fn bad_frames_are_counted_and_the_scan_goes_on() {
        let good = frame(1, 7, &pvt(3, 1, 0b111));
        let mut corrupt = good.clone();
        corrupt[40] ^= 0xFF;
        let untimed = frame(1, 7, &pvt(3, 1, 0b001));
        let short = frame(1, 7, &[0u8; 20]);
        let other = frame(1, 0x35, &[0u8; 8]);
        let cut = &good[..50];
        let log = [
            b"\x00\xb5\xb5".as_slice(),
            &corrupt[..],
            &other[..],
            &untimed[..],
            &short[..],
            &good[..],
            b"$GPTXT,hello".as_slice(),
            cut,
        ]
        .concat();
        let (r, s) = read_ubx(&log);
        assert_eq!(r.len(), 1);
        assert_eq!(
            (
                s.frames,
                s.nav_pvt,
                s.bad_checksum,
                s.other,
                s.untimed,
                s.invalid,
                s.truncated
            ),
            (4, 1, 1, 1, 1, 1, 1),
            "{s:?}"
        );
        assert!(!s.from_nmea);
        assert!(contains_ubx(&log) && !contains_ubx(&corrupt) && !contains_ubx(b"$GPGGA"));
        // A NAV-PVT whose position is out of range is invalid, not a NaN.
        let mut p = pvt(3, 1, 0b111);
        p[28..32].copy_from_slice(&950_000_000i32.to_le_bytes());
        let (r, s) = read_ubx(&frame(1, 7, &p));
        assert_eq!((r.len(), s.invalid), (0, 1));
    }
}
