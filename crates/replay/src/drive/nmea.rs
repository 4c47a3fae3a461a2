//! Satellite GPS as NMEA 0183 text: `GGA` or `GNS` (position, quality, HDOP, satellites),
//! `RMC` (the date) and `HDT` (true heading), as a receiver logs them, from any talker (`GP`,
//! `GN`, `GL`, `GA`, `GB`, …).
//!
//! The reader is small and strict about each sentence but never fails on a bad line: a line
//! without `$`, a sentence whose checksum is wrong, a truncated last line and a sentence of an
//! unsupported type are skipped and counted in [`NmeaStats`]. A sentence is found anywhere in
//! a line: bytes before its `$` or after its checksum (binary messages of the same port, a
//! logger's prefix and suffix such as Android's `NMEA,$GPGGA,…*63,1699400577561`) are skipped
//! and the line counted in [`NmeaStats::noisy`]; a line may hold several sentences. (The `nmea` crate was
//! considered: it stores the altitude, the geoid separation and the HDOP as `f32` and brings
//! `chrono` and `nom`; the three sentences needed here are simpler to read directly.)
//!
//! # Time
//! A `GGA` carries the UTC time of day only; the date comes from the latest `RMC`. A `GGA`
//! whose time of day is more than 12 h before (after) that `RMC`'s is taken to be on the next
//! (previous) day, which handles the midnight rollover whichever sentence comes first in an
//! epoch. `GGA` sentences before the first `RMC` are dated by it; without any `RMC` they are
//! dropped and counted ([`NmeaStats::undated`]). An `HDT` applies to the record of the
//! preceding `GGA` (an `HDT` before any `GGA` is counted in [`NmeaStats::unattached`]).
//!
//! # GNS
//! A `GNS` gives what a `GGA` gives; its mode letters (one per constellation) become the GGA
//! quality of the best of them (`R` 4, `F` 5, `P`/`D` 2, `A` 1, `E` 6, all `N`: no fix). When
//! a receiver sends both for one epoch, the `GGA` is kept and the `GNS` counted as used.
//!
//! # Heights
//! `GGA` gives the height above mean sea level and the geoid separation `N`; the ellipsoidal
//! height is their sum (an empty separation is taken as 0).

use crate::report::time::{date_from_days, days_from_date};
use std::fmt::Write as _;
use vgps_geometry::geo::Geodetic;

/// Seconds in a day.
const DAY_S: f64 = 86_400.0;
/// Half a day: the largest plausible gap between a `GGA` and the `RMC` that dates it.
const HALF_DAY_S: f64 = 43_200.0;
/// Decimals of the written minutes of arc: 1e-7 minute (≈ 0.19 mm of latitude).
const MINUTE_DECIMALS: usize = 7;
/// How many messages about invalid sentences [`NmeaStats::messages`] keeps.
const MAX_MESSAGES: usize = 20;

/// A position fix reported by the receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// The reported position (ellipsoidal height = GGA altitude + geoid separation).
    pub position: Geodetic,
    /// The GGA fix quality (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, …; never 0 here).
    pub quality: u8,
    /// Horizontal dilution of precision, when given.
    pub hdop: Option<f64>,
    /// Number of satellites used, when given.
    pub num_sats: Option<u32>,
}

/// One receiver epoch: its time, its fix (none during an outage: GGA quality 0) and its
/// heading (from an `HDT` following the `GGA`).
///
/// # Units
/// `time_s`: Unix time in seconds (UTC); `heading_deg`: degrees clockwise from true north.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssRecord {
    /// Unix time of the epoch, seconds (UTC).
    pub time_s: f64,
    /// The fix, `None` when the receiver has none (GGA quality 0).
    pub fix: Option<GnssFix>,
    /// True heading, degrees clockwise from north in [0, 360), when an `HDT` gave one.
    pub heading_deg: Option<f64>,
}

/// Counts of what the reader used and skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NmeaStats {
    /// Non-empty lines read.
    pub lines: usize,
    /// Sentences used (GGA, RMC, HDT).
    pub used: usize,
    /// Sentences whose checksum is wrong or missing.
    pub bad_checksum: usize,
    /// Lines that hold no sentence (no `$`).
    pub garbage: usize,
    /// Lines with bytes before a sentence's `$` or after its checksum (binary noise, a
    /// logger's prefix or suffix); their sentences are read.
    pub noisy: usize,
    /// The last line, unterminated and not a valid sentence.
    pub truncated: usize,
    /// Valid sentences of other types (GSA, GSV, VTG, …).
    pub unsupported: usize,
    /// Sentences with a valid checksum but an invalid field.
    pub invalid: usize,
    /// GGA sentences dropped because no RMC gave a date.
    pub undated: usize,
    /// HDT sentences before any GGA.
    pub unattached: usize,
    /// The first few messages about skipped lines (`line N: reason`).
    pub messages: Vec<String>,
}

impl NmeaStats {
    /// Lines skipped for any reason.
    pub fn skipped(&self) -> usize {
        self.bad_checksum
            + self.garbage
            + self.truncated
            + self.unsupported
            + self.invalid
            + self.undated
            + self.unattached
    }

    fn note(&mut self, line: usize, reason: impl Into<String>) {
        if self.messages.len() < MAX_MESSAGES {
            self.messages
                .push(format!("line {line}: {}", reason.into()));
        }
    }
}

/// The NMEA checksum: XOR of the bytes between `$` and `*`.
pub fn checksum(body: &str) -> u8 {
    body.bytes().fold(0, |a, b| a ^ b)
}

/// A GGA waiting for its date.
struct Epoch {
    tod_s: f64,
    /// (day number, RMC time of day) of the latest RMC before this GGA.
    date: Option<(i64, f64)>,
    fix: Option<GnssFix>,
    heading_deg: Option<f64>,
    /// Read from a `GNS` (a `GGA` of the same epoch replaces it).
    from_gns: bool,
}

/// Reads NMEA text into receiver epochs (sorted by time) and the counts of skipped lines.
/// Never fails: what cannot be used is counted.
///
/// # Example
/// ```
/// use vgps_replay::drive::nmea::{read_nmea, write_nmea, GnssFix, GnssRecord};
/// use vgps_geometry::geo::Geodetic;
/// let fix = GnssFix {
///     position: Geodetic::try_new(37.7793, -122.4193, 10.0)?,
///     quality: 1, hdop: Some(0.9), num_sats: Some(9),
/// };
/// let records = [GnssRecord { time_s: 1_778_794_200.2, fix: Some(fix), heading_deg: Some(91.5) }];
/// let text = write_nmea(&records, -32.0);
/// let (back, stats) = read_nmea(&format!("junk\n{text}$GPGGA,1"));
/// assert_eq!((back.len(), stats.garbage, stats.truncated), (1, 1, 1));
/// assert!((back[0].time_s - 1_778_794_200.2).abs() < 1e-6);
/// assert!((back[0].fix.unwrap().position.alt_m - 10.0).abs() < 1e-3);
/// # Ok::<(), vgps_geometry::geo::GeoError>(())
/// ```
pub fn read_nmea(text: &str) -> (Vec<GnssRecord>, NmeaStats) {
    let mut stats = NmeaStats::default();
    let mut epochs: Vec<Epoch> = Vec::new();
    let mut date: Option<(i64, f64)> = None;
    let mut first_date: Option<(i64, f64)> = None;
    let terminated = text.ends_with('\n');
    let lines: Vec<&str> = text.split('\n').collect();
    let count = lines.len();
    for (k, raw) in lines.iter().enumerate() {
        let number = k + 1;
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        stats.lines += 1;
        let last_unterminated = k + 1 == count && !terminated;
        let found = find_sentences(line);
        if found.noisy && !found.bodies.is_empty() {
            stats.noisy += 1;
        }
        if found.bodies.is_empty() {
            if last_unterminated && found.error != Some(LineError::Garbage) {
                stats.truncated += 1;
                stats.note(number, "truncated last line");
            } else if found.error == Some(LineError::Garbage) || found.error.is_none() {
                stats.garbage += 1;
                stats.note(number, "not a sentence");
            } else {
                stats.bad_checksum += 1;
                stats.note(number, "bad or missing checksum");
            }
            continue;
        }
        for body in found.bodies {
            let fields: Vec<&str> = body.split(',').collect();
            let kind = fields[0].get(2..).unwrap_or("");
            let result = match kind {
                "RMC" => parse_rmc(&fields).map(|(day, tod)| {
                    date = Some((day, tod));
                    first_date.get_or_insert((day, tod));
                }),
                "GGA" | "GNS" => {
                    let gns = kind == "GNS";
                    let parsed = if gns {
                        parse_gns(&fields)
                    } else {
                        parse_gga(&fields)
                    };
                    parsed.map(|(tod_s, fix)| {
                        push_epoch(&mut epochs, tod_s, date, fix, gns);
                    })
                }
                "HDT" => parse_hdt(&fields).map(|heading| match epochs.last_mut() {
                    Some(e) => e.heading_deg = Some(heading),
                    None => {
                        stats.unattached += 1;
                        stats.note(number, "HDT before any GGA");
                    }
                }),
                _ => {
                    stats.unsupported += 1;
                    continue;
                }
            };
            match result {
                Ok(()) => stats.used += 1,
                Err(reason) => {
                    stats.invalid += 1;
                    stats.note(number, format!("{}: {reason}", fields[0]));
                }
            }
        }
    }
    let mut records = Vec::with_capacity(epochs.len());
    for e in epochs {
        let Some((day, rmc_tod)) = e.date.or(first_date) else {
            stats.undated += 1;
            continue;
        };
        let mut day = day;
        if e.tod_s < rmc_tod - HALF_DAY_S {
            day += 1;
        } else if e.tod_s > rmc_tod + HALF_DAY_S {
            day -= 1;
        }
        records.push(GnssRecord {
            time_s: day as f64 * DAY_S + e.tod_s,
            fix: e.fix,
            heading_deg: e.heading_deg,
        });
    }
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    (records, stats)
}

#[derive(Debug, PartialEq, Eq)]
enum LineError {
    Garbage,
    Checksum,
}

/// The sentences found in one line.
struct Found<'a> {
    /// The text between `$` and `*` of each sentence whose checksum is right.
    bodies: Vec<&'a str>,
    /// Bytes outside the sentences (before a `$`, after a checksum).
    noisy: bool,
    /// Why the last candidate failed, when none was read.
    error: Option<LineError>,
}

/// Every `$…*hh` sentence of a line whose checksum is right, wherever it starts.
fn find_sentences(line: &str) -> Found<'_> {
    let mut found = Found {
        bodies: Vec::new(),
        noisy: false,
        error: Some(LineError::Garbage),
    };
    let mut rest = line;
    while let Some(at) = rest.find('$') {
        if at > 0 {
            found.noisy = true;
        }
        let candidate = &rest[at + 1..];
        match sentence_body(candidate) {
            Ok((body, used)) => {
                found.bodies.push(body);
                found.error = None;
                rest = &candidate[used..];
            }
            Err(kind) => {
                if found.bodies.is_empty() {
                    found.error = Some(kind);
                }
                rest = candidate;
            }
        }
    }
    if !rest.trim().is_empty() && !found.bodies.is_empty() {
        found.noisy = true;
    }
    found
}

/// The body (between `$` and `*`) of the sentence at the start of `text` (after its `$`)
/// when its checksum is right, and the bytes it takes with the checksum.
fn sentence_body(text: &str) -> Result<(&str, usize), LineError> {
    let star = text.find(['*', '$']).ok_or(LineError::Checksum)?;
    if !text[star..].starts_with('*') {
        return Err(LineError::Checksum);
    }
    let body = &text[..star];
    let sum = text.get(star + 1..star + 3).ok_or(LineError::Checksum)?;
    if body.len() < 5 || !body.is_ascii() {
        return Err(LineError::Checksum);
    }
    let expected = u8::from_str_radix(sum, 16).map_err(|_| LineError::Checksum)?;
    if checksum(body) != expected {
        return Err(LineError::Checksum);
    }
    Ok((body, star + 3))
}

/// Adds a GGA or GNS epoch; a GNS of the same time of day as the previous epoch from a GGA
/// (or the reverse) is one epoch, the GGA's.
fn push_epoch(
    epochs: &mut Vec<Epoch>,
    tod_s: f64,
    date: Option<(i64, f64)>,
    fix: Option<GnssFix>,
    from_gns: bool,
) {
    if let Some(last) = epochs.last_mut()
        && last.tod_s == tod_s
        && last.from_gns != from_gns
    {
        if last.from_gns {
            last.fix = fix;
            last.from_gns = false;
        }
        return;
    }
    epochs.push(Epoch {
        tod_s,
        date,
        fix,
        heading_deg: None,
        from_gns,
    });
}

fn field<'a>(fields: &[&'a str], k: usize) -> &'a str {
    fields.get(k).copied().unwrap_or("")
}

fn number(fields: &[&str], k: usize, name: &str) -> Result<Option<f64>, String> {
    let text = field(fields, k);
    if text.is_empty() {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(Some(x)),
        _ => Err(format!("{name} `{text}` is not a number")),
    }
}

/// `hhmmss.sss` → seconds of the day.
fn time_of_day(text: &str) -> Result<f64, String> {
    let bad = || format!("time `{text}` is not hhmmss.ss");
    // ASCII digits first: the slices below must fall on character boundaries.
    if text.len() < 6 || !text.as_bytes()[..6].is_ascii() {
        return Err(bad());
    }
    let h: u32 = text[0..2].parse().map_err(|_| bad())?;
    let m: u32 = text[2..4].parse().map_err(|_| bad())?;
    let s: f64 = text[4..].parse().map_err(|_| bad())?;
    if h > 23 || m > 59 || !(0.0..61.0).contains(&s) {
        return Err(bad());
    }
    Ok(f64::from(h * 3600 + m * 60) + s)
}

/// `ddmm.mmmm` (or `dddmm.mmmm`) and a hemisphere → signed degrees.
fn angle(text: &str, hemi: &str, degree_digits: usize, limit: f64) -> Result<f64, String> {
    let bad = || format!("angle `{text},{hemi}` is invalid");
    if text.len() < degree_digits + 2 || !text.is_char_boundary(degree_digits) {
        return Err(bad());
    }
    let deg: f64 = text[..degree_digits].parse().map_err(|_| bad())?;
    let min: f64 = text[degree_digits..].parse().map_err(|_| bad())?;
    if !(0.0..60.0).contains(&min) {
        return Err(bad());
    }
    let value = deg + min / 60.0;
    if value > limit {
        return Err(bad());
    }
    match hemi {
        "N" | "E" => Ok(value),
        "S" | "W" => Ok(-value),
        _ => Err(bad()),
    }
}

/// RMC → (day number since 1970-01-01, time of day).
fn parse_rmc(f: &[&str]) -> Result<(i64, f64), String> {
    let tod = time_of_day(field(f, 1))?;
    let d = field(f, 9);
    let bad = || format!("date `{d}` is not ddmmyy");
    if d.len() != 6 || !d.is_ascii() {
        return Err(bad());
    }
    let day: u32 = d[0..2].parse().map_err(|_| bad())?;
    let month: u32 = d[2..4].parse().map_err(|_| bad())?;
    let yy: i64 = d[4..6].parse().map_err(|_| bad())?;
    let year = if yy < 80 { 2000 + yy } else { 1900 + yy };
    // A date that does not exist (31 February, month 13) is an error, not the next month.
    let days = days_from_date(year, month, day).ok_or_else(bad)?;
    Ok((days, tod))
}

/// The fix fields GGA and GNS share (latitude 2–3, longitude 4–5, satellites 7, HDOP 8,
/// altitude above mean sea level 9) and the geoid separation at `separation_field` (GGA 11,
/// GNS 10).
fn fix_fields(f: &[&str], quality: u8, separation_field: usize) -> Result<GnssFix, String> {
    let lat = angle(field(f, 2), field(f, 3), 2, 90.0)?;
    let lon = angle(field(f, 4), field(f, 5), 3, 180.0)?;
    let num_sats = match field(f, 7) {
        "" => None,
        s => Some(
            s.parse::<u32>()
                .map_err(|_| format!("satellites `{s}` is not a count"))?,
        ),
    };
    let hdop = number(f, 8, "hdop")?;
    let msl = number(f, 9, "altitude")?.ok_or("altitude is missing")?;
    let separation = number(f, separation_field, "geoid separation")?.unwrap_or(0.0);
    let position = Geodetic::try_new(lat, lon, msl + separation).map_err(|e| e.to_string())?;
    Ok(GnssFix {
        position,
        quality,
        hdop,
        num_sats,
    })
}

/// GGA → (time of day, fix or none).
fn parse_gga(f: &[&str]) -> Result<(f64, Option<GnssFix>), String> {
    let tod = time_of_day(field(f, 1))?;
    let quality: u8 = field(f, 6)
        .parse()
        .map_err(|_| format!("quality `{}` is not 0-8", field(f, 6)))?;
    if quality == 0 {
        return Ok((tod, None));
    }
    Ok((tod, Some(fix_fields(f, quality, 11)?)))
}

/// GNS → (time of day, fix or none): `GNS,time,lat,N,lon,E,mode,sats,hdop,alt,sep,…`.
fn parse_gns(f: &[&str]) -> Result<(f64, Option<GnssFix>), String> {
    let tod = time_of_day(field(f, 1))?;
    let mode = field(f, 6);
    let bad_mode = || format!("mode `{mode}` is not GNS mode letters");
    if mode.is_empty() {
        return Err(bad_mode());
    }
    let mut quality: Option<u8> = None;
    for c in mode.chars() {
        let q = match c {
            'N' => None,
            'A' => Some(1),
            'D' | 'P' => Some(2),
            'R' => Some(4),
            'F' => Some(5),
            'E' => Some(6),
            'M' => Some(7),
            'S' => Some(8),
            _ => return Err(bad_mode()),
        };
        // The best solution of the constellations: RTK fixed, float, differential, autonomous.
        let rank = |q: u8| match q {
            4 => 0,
            5 => 1,
            2 => 2,
            1 => 3,
            _ => 4,
        };
        quality = match (quality, q) {
            (Some(a), Some(b)) => Some(if rank(b) < rank(a) { b } else { a }),
            (a, b) => a.or(b),
        };
    }
    let Some(quality) = quality else {
        return Ok((tod, None));
    };
    Ok((tod, Some(fix_fields(f, quality, 10)?)))
}

fn parse_hdt(f: &[&str]) -> Result<f64, String> {
    let h = number(f, 1, "heading")?.ok_or("heading is missing")?;
    if !(0.0..=360.0).contains(&h) {
        return Err(format!("heading {h} is outside [0, 360]"));
    }
    Ok(h.rem_euclid(360.0))
}

/// Appends `$BODY*CS\r\n` (the checksum as two upper-case hex digits): the one sentence
/// writer of vgps, shared by the drive's satellite GPS and the replay's `fixes.nmea`.
pub(crate) fn push_sentence(out: &mut String, body: &str) {
    let _ = write!(out, "${body}*{:02X}\r\n", checksum(body));
}

/// An angle as NMEA writes it, `ddmm.mmm…,H` (latitude, `degree_digits` 2) or `dddmm.mmm…,H`
/// (longitude, 3), with `minute_decimals` decimals of a minute and its hemisphere letter.
/// Rounded in units of the last decimal first, so that 59.99…' carries into the degrees.
pub(crate) fn format_angle(
    value: f64,
    degree_digits: usize,
    minute_decimals: usize,
    positive: char,
    negative: char,
) -> String {
    let minute_units = 10_u64.pow(minute_decimals as u32);
    let units = (value.abs() * 60.0 * minute_units as f64).round() as u64;
    let per_degree = 60 * minute_units;
    let deg = units / per_degree;
    let rem = units % per_degree;
    let min = rem / minute_units;
    let frac = rem % minute_units;
    let hemi = if value < 0.0 { negative } else { positive };
    format!("{deg:0degree_digits$}{min:02}.{frac:0minute_decimals$},{hemi}")
}

/// Writes receiver epochs as NMEA text: per epoch `$GPRMC`, `$GPGGA` and, with a heading,
/// `$GPHDT`, with correct checksums and CR LF line ends. An epoch without a fix is written
/// as RMC status `V` and GGA quality 0 with empty position fields. `geoid_separation_m` is
/// the geoid height `N` written in the GGA (the altitude field is then `h − N`).
///
/// # Units
/// Times rounded to 0.01 s (GGA/RMC resolution), angles to 1e-7 minute, altitudes to 1 mm.
pub fn write_nmea(records: &[GnssRecord], geoid_separation_m: f64) -> String {
    let mut out = String::new();
    for r in records {
        let centis = (r.time_s * 100.0).round() as i64;
        let days = centis.div_euclid(8_640_000);
        let tod_c = centis.rem_euclid(8_640_000);
        let Some((year, month, day)) = date_from_days(days) else {
            continue;
        };
        let time = format!(
            "{:02}{:02}{:02}.{:02}",
            tod_c / 360_000,
            tod_c / 6000 % 60,
            tod_c / 100 % 60,
            tod_c % 100
        );
        let date = format!("{day:02}{month:02}{:02}", year.rem_euclid(100));
        match &r.fix {
            Some(fix) => {
                let lat = format_angle(fix.position.lat_deg, 2, MINUTE_DECIMALS, 'N', 'S');
                let lon = format_angle(fix.position.lon_deg, 3, MINUTE_DECIMALS, 'E', 'W');
                let course = r.heading_deg.map_or(String::new(), |h| format!("{h:.1}"));
                push_sentence(
                    &mut out,
                    &format!("GPRMC,{time},A,{lat},{lon},,{course},{date},,,A"),
                );
                let sats = fix.num_sats.map_or(String::new(), |n| format!("{n:02}"));
                let hdop = fix.hdop.map_or(String::new(), |h| format!("{h:.1}"));
                let msl = fix.position.alt_m - geoid_separation_m;
                push_sentence(
                    &mut out,
                    &format!(
                        "GPGGA,{time},{lat},{lon},{},{sats},{hdop},{msl:.3},M,{geoid_separation_m:.1},M,,",
                        fix.quality
                    ),
                );
            }
            None => {
                push_sentence(&mut out, &format!("GPRMC,{time},V,,,,,,,{date},,,N"));
                push_sentence(&mut out, &format!("GPGGA,{time},,,,,0,00,99.9,,M,,M,,"));
            }
        }
        if let Some(h) = r.heading_deg {
            push_sentence(&mut out, &format!("GPHDT,{:.2},T", h.rem_euclid(360.0)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(lat: f64, lon: f64, alt: f64) -> Option<GnssFix> {
        Some(GnssFix {
            position: Geodetic::try_new(lat, lon, alt).unwrap(),
            quality: 1,
            hdop: Some(1.1),
            num_sats: Some(8),
        })
    }

    #[test]
    fn checksum_of_the_standard_example() {
        // The classic example sentence with its published checksum 47.
        let body = "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,";
        assert_eq!(checksum(body), 0x47);
        let (r, s) = read_nmea(&format!("${body}*47\n"));
        assert_eq!(s.undated, 1);
        assert!(r.is_empty());
        let rmc = "GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W";
        let text = format!("${rmc}*{:02X}\n${body}*47\n", checksum(rmc));
        let (r, s) = read_nmea(&text);
        assert_eq!((r.len(), s.used, s.skipped()), (1, 2, 0));
        let expected = days_from_date(1994, 3, 23).unwrap() as f64 * DAY_S
            + 12.0 * 3600.0
            + 35.0 * 60.0
            + 19.0;
        assert_eq!(r[0].time_s, expected);
        let p = r[0].fix.unwrap().position;
        assert!((p.lat_deg - (48.0 + 7.038 / 60.0)).abs() < 1e-12);
        assert!((p.lon_deg - (11.0 + 31.0 / 60.0)).abs() < 1e-12);
        assert!((p.alt_m - (545.4 + 46.9)).abs() < 1e-9);
    }

    #[test]
    fn round_trip_with_signs_outage_and_heading() {
        let t0 = 1_778_794_200.0;
        let records = vec![
            GnssRecord {
                time_s: t0,
                fix: fix(37.7793, -122.4193, -12.25),
                heading_deg: Some(359.99),
            },
            GnssRecord {
                time_s: t0 + 0.2,
                fix: None,
                heading_deg: None,
            },
            GnssRecord {
                time_s: t0 + 0.4,
                fix: fix(-33.8568, 151.2153, 5.0),
                heading_deg: None,
            },
            GnssRecord {
                time_s: t0 + 0.6,
                fix: fix(0.5, -0.25, 100.0),
                heading_deg: Some(0.0),
            },
        ];
        let text = write_nmea(&records, -32.0);
        let (back, stats) = read_nmea(&text);
        assert_eq!(stats.skipped(), 0, "{stats:?}");
        assert_eq!(back.len(), records.len());
        for (a, b) in records.iter().zip(&back) {
            assert!((a.time_s - b.time_s).abs() < 1e-6);
            match (a.heading_deg, b.heading_deg) {
                (Some(x), Some(y)) => assert!((x - y).abs() < 0.006),
                (None, None) => {}
                other => panic!("heading {other:?}"),
            }
            match (&a.fix, &b.fix) {
                (Some(x), Some(y)) => {
                    assert!((x.position.lat_deg - y.position.lat_deg).abs() < 2e-9);
                    assert!((x.position.lon_deg - y.position.lon_deg).abs() < 2e-9);
                    assert!((x.position.alt_m - y.position.alt_m).abs() < 1e-3);
                    assert_eq!((y.quality, y.num_sats), (1, Some(8)));
                    assert!((y.hdop.unwrap() - 1.1).abs() < 1e-12);
                }
                (None, None) => {}
                other => panic!("fix {other:?}"),
            }
        }
        // No-fix epochs are GGA quality 0.
        assert!(text.contains("$GPGGA,213000.20,,,,,0,"));
    }

    #[test]
    fn bad_checksum_garbage_and_truncation_are_counted_not_fatal() {
        let t0 = 1_778_794_200.0;
        let records: Vec<GnssRecord> = (0..4)
            .map(|k| GnssRecord {
                time_s: t0 + f64::from(k),
                fix: fix(37.0, -122.0, 1.0),
                heading_deg: Some(10.0),
            })
            .collect();
        let text = write_nmea(&records, 0.0);
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        // Epoch 1's GGA gets a corrupted digit (checksum no longer matches).
        let gga1 = lines
            .iter()
            .position(|l| l.starts_with("$GPGGA,213001"))
            .unwrap();
        lines[gga1] = lines[gga1].replacen("37", "38", 1);
        lines.insert(3, "\u{0}\u{7f}binary noise".to_string());
        let gsv = "GPGSV,3,1,11,03,03,111,00";
        lines.push(format!("${gsv}*{:02X}", checksum(gsv)));
        lines.push("$GPHDT,12.0,T".to_string()); // no checksum
        let mut joined = lines.join("\n");
        joined.push_str("\n$GPGGA,213004.00,3700.00");
        let (back, stats) = read_nmea(&joined);
        assert_eq!(back.len(), 3);
        assert_eq!(stats.bad_checksum, 2, "{stats:?}");
        assert_eq!(stats.garbage, 1);
        assert_eq!(stats.truncated, 1);
        assert_eq!(stats.unsupported, 1);
        assert!(stats.messages.iter().any(|m| m.contains("truncated")));
        // Epoch 1's HDT attaches to epoch 0 (its GGA was lost): the reader keeps what it can.
        assert!(back.iter().all(|r| r.fix.is_some()));
    }

    #[test]
    fn midnight_rollover_in_either_order() {
        // 23:59:59.80 on 31 Dec 2025 then 00:00:00.00 on 1 Jan 2026.
        let midnight = days_from_date(2026, 1, 1).unwrap() as f64 * DAY_S;
        let records = vec![
            GnssRecord {
                time_s: midnight - 0.2,
                fix: fix(37.0, -122.0, 1.0),
                heading_deg: None,
            },
            GnssRecord {
                time_s: midnight,
                fix: fix(37.0, -122.0, 1.0),
                heading_deg: None,
            },
            GnssRecord {
                time_s: midnight + 0.2,
                fix: None,
                heading_deg: None,
            },
        ];
        let text = write_nmea(&records, 0.0);
        assert!(text.contains(",311225,") && text.contains(",010126,"));
        let (back, _) = read_nmea(&text);
        let times: Vec<f64> = back.iter().map(|r| r.time_s).collect();
        for (a, b) in times.iter().zip(&records) {
            assert!((a - b.time_s).abs() < 1e-6);
        }
        // A receiver that sends the GGA before the RMC: the new day's GGA is dated by the
        // previous day's RMC and must still land after midnight.
        let lines: Vec<&str> = text.lines().collect();
        let swapped = [lines[1], lines[0], lines[3], lines[2]].join("\n");
        let (back, stats) = read_nmea(&swapped);
        assert_eq!(stats.skipped(), 0);
        assert!((back[0].time_s - (midnight - 0.2)).abs() < 1e-6);
        assert!((back[1].time_s - midnight).abs() < 1e-6);
        // And one that leaves the RMC date behind: 00:00 GGA after the 23:59 RMC only.
        let only_first_rmc = [lines[0], lines[1], lines[3]].join("\n");
        let (back, _) = read_nmea(&only_first_rmc);
        assert!((back[1].time_s - midnight).abs() < 1e-6);
    }

    #[test]
    fn an_rmc_date_that_does_not_exist_is_invalid_not_the_next_month() {
        // 31 February 2022 once became 3 March 2022.
        let text = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,310222,003.1,W*6A\r\n";
        let body = &text[1..text.find('*').unwrap()];
        let text = format!("${body}*{:02X}\r\n", checksum(body));
        let (records, stats) = read_nmea(&text);
        assert!(records.is_empty(), "{records:?}");
        assert_eq!(stats.skipped(), 1);
        assert!(
            stats
                .messages
                .iter()
                .any(|m| m.contains("date `310222` is not ddmmyy")),
            "{:?}",
            stats.messages
        );
        // The same sentence on 28 February is read.
        let good = text.replace("310222", "280222");
        let body = &good[1..good.find('*').unwrap()];
        let good = format!("${body}*{:02X}\r\n", checksum(body));
        assert_eq!(read_nmea(&good).1.skipped(), 0);
    }

    #[test]
    fn invalid_fields_are_counted() {
        let bad = "GPGGA,253000.00,3700.0,N,12200.0,W,1,08,0.9,1.0,M,0.0,M,,";
        let rmc = "GPRMC,000000.00,A,,,,,,,010126,,,A";
        let text = format!(
            "${rmc}*{:02X}\n${bad}*{:02X}\n",
            checksum(rmc),
            checksum(bad)
        );
        let (back, stats) = read_nmea(&text);
        assert!(back.is_empty());
        assert_eq!((stats.invalid, stats.used), (1, 1));
        assert!(stats.messages[0].starts_with("line 2: GPGGA: time"));
    }
}
