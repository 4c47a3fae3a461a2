//! Satellite GPS files of any supported format: NMEA 0183 ([`super::nmea`]), u-blox UBX
//! mixed with NMEA ([`super::ubx`]), SiRF binary ([`super::sirf`]), GPX 1.0/1.1 tracks ([`super::gpx`]) and NCLT `gps.csv`
//! ([`super::nclt_gps`]), read into the drive's [`GnssRecord`]s.
//!
//! # Time
//! Drive times are Unix seconds (UTC), and so are the times of the three formats: NMEA's
//! UTC date and time of day, GPX's `<time>` (`xsd:dateTime`, UTC or with an offset) and
//! NCLT's `utime` (Unix microseconds). A file's times are therefore used as they are; a
//! receiver whose clock is off (GPS time instead of UTC, a logger's clock) is corrected by
//! `time_offset_s`, added to every time of the file (`drive time = file time + offset`).
//!
//! # Format detection
//! [`GnssFormat::detect_bytes`]: a file holding a UBX frame with a right checksum is UBX
//! (`B5 62` sync, Fletcher checksum; its NMEA is read too); one holding a SiRF frame with a
//! right checksum and end sequence is SiRF (`A0 A2` … `B0 B3`); otherwise
//! [`GnssFormat::detect`]: the content decides when it is unambiguous (`<` first: GPX; `$`
//! or `!` first: NMEA; a first line of numbers separated by commas: NCLT), else the file
//! extension (`.gpx`, `.nmea`/`.nma`, `.csv`), else NMEA (whose reader counts what it
//! cannot use).

use super::nmea::{self, GnssRecord, NmeaStats};
use std::path::{Path, PathBuf};
use vgps_geometry::geo::Geodetic;

/// How many messages about skipped entries [`GnssFileStats::messages`] keeps.
pub const MAX_GNSS_MESSAGES: usize = 20;

/// The formats of a satellite GPS file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GnssFormat {
    /// NMEA 0183 sentences (`GGA`, `RMC`, `HDT`).
    Nmea,
    /// GPX 1.0 or 1.1 track points (`trkpt`).
    Gpx,
    /// NCLT `gps.csv`: `utime,mode,num_sats,lat,lng,alt,track,speed`, no header.
    Nclt,
    /// u-blox UBX binary (`NAV-PVT`) mixed with NMEA, as u-blox receivers log.
    Ubx,
    /// SiRF binary (MID 41 Geodetic Navigation Data, else MID 2 Measure Navigation Data),
    /// as SiRF receivers (SiRF-II … SiRFstar IV) log.
    Sirf,
}

impl GnssFormat {
    /// Every format, in the order of the documentation.
    pub const ALL: [Self; 4] = [Self::Nmea, Self::Gpx, Self::Nclt, Self::Ubx];

    /// The format's name (`nmea`, `gpx`, `nclt`, `ubx`): what [`std::str::FromStr`] reads
    /// and [`std::fmt::Display`] writes.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Nmea => "nmea",
            Self::Gpx => "gpx",
            Self::Nclt => "nclt",
            Self::Ubx => "ubx",
            Self::Sirf => "sirf",
        }
    }

    /// The format named by a file extension (`gpx`, `nmea`/`nma`, `csv`; any case).
    pub fn from_extension(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "gpx" => Some(Self::Gpx),
            "nmea" | "nma" => Some(Self::Nmea),
            "csv" => Some(Self::Nclt),
            "ubx" => Some(Self::Ubx),
            "sirf" | "srf" => Some(Self::Sirf),
            _ => None,
        }
    }

    /// The format the content shows unambiguously: the first non-blank character `<` is
    /// GPX (XML), `$` or `!` NMEA; a first line of at least six comma-separated numbers is
    /// NCLT. `None` otherwise.
    pub fn sniff(text: &str) -> Option<Self> {
        let text = text.trim_start_matches('\u{feff}').trim_start();
        match text.chars().next()? {
            '<' => Some(Self::Gpx),
            '$' | '!' => Some(Self::Nmea),
            _ => {
                let line = text.lines().next()?;
                let fields: Vec<&str> = line.split(',').map(str::trim).collect();
                (fields.len() >= super::nclt_gps::MIN_COLUMNS
                    && fields.iter().all(|f| f.parse::<f64>().is_ok()))
                .then_some(Self::Nclt)
            }
        }
    }

    /// The format of a file: [`GnssFormat::sniff`] of its content, else
    /// [`GnssFormat::from_extension`], else NMEA.
    ///
    /// # Example
    /// ```
    /// use std::path::Path;
    /// use vgps_replay::drive::gnss::GnssFormat;
    /// let csv = "1326030000000000,3,9,0.7381,-1.4610,270.0,0.1,1.2\n";
    /// assert_eq!(GnssFormat::detect(Path::new("gps.txt"), csv), GnssFormat::Nclt);
    /// assert_eq!(GnssFormat::detect(Path::new("a.log"), "<?xml version=\"1.0\"?>"), GnssFormat::Gpx);
    /// assert_eq!(GnssFormat::detect(Path::new("track.gpx"), ""), GnssFormat::Gpx);
    /// assert_eq!(GnssFormat::detect(Path::new("gnss.log"), "junk"), GnssFormat::Nmea);
    /// ```
    pub fn detect(path: &Path, text: &str) -> Self {
        Self::sniff(text)
            .or_else(|| Self::from_extension(path))
            .unwrap_or(Self::Nmea)
    }

    /// The format of a file's bytes: UBX when they hold a UBX frame with a right checksum
    /// ([`super::ubx::contains_ubx`]), else [`GnssFormat::detect`] of their text.
    pub fn detect_bytes(path: &Path, bytes: &[u8]) -> Self {
        if super::ubx::contains_ubx(bytes) {
            return Self::Ubx;
        }
        if super::sirf::contains_sirf(bytes) {
            return Self::Sirf;
        }
        Self::detect(path, &String::from_utf8_lossy(bytes))
    }
}

impl std::fmt::Display for GnssFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is not one of [`GnssFormat::ALL`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is not a satellite GPS format (nmea, gpx, nclt or ubx)")]
pub struct UnknownGnssFormat(pub String);

impl std::str::FromStr for GnssFormat {
    type Err = UnknownGnssFormat;

    /// The format named `nmea`, `gpx`, `nclt` or `ubx` (any case; surrounding spaces
    /// ignored).
    ///
    /// ```
    /// use vgps_replay::drive::gnss::GnssFormat;
    /// assert_eq!("GPX".parse::<GnssFormat>(), Ok(GnssFormat::Gpx));
    /// assert!("kml".parse::<GnssFormat>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let name = s.trim();
        Self::ALL
            .into_iter()
            .find(|f| f.as_str().eq_ignore_ascii_case(name))
            .ok_or_else(|| UnknownGnssFormat(s.to_owned()))
    }
}

/// Errors of reading a GPX or NCLT file (the NMEA reader never fails on content).
#[derive(Debug, thiserror::Error)]
pub enum GnssFileError {
    /// The file cannot be read.
    #[error("{}: cannot read the file: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The GPX document is invalid (`line`/`point` when they are known; `point` is the
    /// 0-based index of the `trkpt` in the file).
    #[error("{}{}{}: {reason}", path.display(),
        line.map(|l| format!(":{l}")).unwrap_or_default(),
        point.map(|k| format!(": point {k}")).unwrap_or_default())]
    Gpx {
        /// The file.
        path: PathBuf,
        /// The 1-based line, when known.
        line: Option<u64>,
        /// The 0-based index of the track point, when known.
        point: Option<usize>,
        /// What is wrong.
        reason: String,
    },
    /// A row of a CSV file is invalid.
    #[error("{}:{line}: field `{field}`: {reason}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// The 1-based line.
        line: u64,
        /// The column name.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The time offset is not a finite number.
    #[error("{}: time offset {offset_s} s is not a finite number", path.display())]
    Offset {
        /// The file.
        path: PathBuf,
        /// The offset given.
        offset_s: f64,
    },
}

/// Counts of what a GNSS reader used and skipped (any format).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GnssFileStats {
    /// The format read.
    pub format: GnssFormat,
    /// Entries read: NMEA lines, GPX track points, NCLT rows.
    pub entries: usize,
    /// Epochs with a fix (records with `fix: Some`).
    pub fixes: usize,
    /// Epochs without a fix, kept as records with `fix: None` (NMEA GGA quality 0, GPX
    /// `<fix>none</fix>`, NCLT `mode` 0 or 1).
    pub no_fix: usize,
    /// Entries skipped because their position is not finite or out of range (latitude
    /// outside [−90, 90], longitude outside [−180, 180], a non-finite height).
    pub invalid_position: usize,
    /// GPX track points without `<time>` (skipped: they cannot be placed on the drive clock).
    pub untimed: usize,
    /// GPX track points without `<ele>` (kept with height 0).
    pub no_elevation: usize,
    /// NCLT: an unterminated last row that cannot be read (an interrupted log). NMEA: every
    /// skipped line ([`NmeaStats::skipped`]).
    pub other_skipped: usize,
    /// The first [`MAX_GNSS_MESSAGES`] messages about skipped or amended entries
    /// (`line N: …`).
    pub messages: Vec<String>,
}

impl GnssFileStats {
    /// Empty counts of `format`.
    pub fn new(format: GnssFormat) -> Self {
        Self {
            format,
            entries: 0,
            fixes: 0,
            no_fix: 0,
            invalid_position: 0,
            untimed: 0,
            no_elevation: 0,
            other_skipped: 0,
            messages: Vec::new(),
        }
    }

    /// The counts of the UBX reader in this form (NMEA lines and UBX frames together).
    pub fn from_ubx(stats: &super::ubx::UbxStats, records: &[GnssRecord]) -> Self {
        let summary = (stats.skipped() > stats.other).then(|| {
            format!(
                "UBX: {} frames, {} NAV-PVT used; skipped {} bad checksum, {} truncated, {} without a valid UTC time, {} invalid",
                stats.frames,
                stats.nav_pvt,
                stats.bad_checksum,
                stats.truncated,
                stats.untimed,
                stats.invalid,
            )
        });
        Self::from_binary(
            GnssFormat::Ubx,
            records,
            summary,
            [stats.frames, stats.bad_checksum, stats.truncated],
            stats.untimed + stats.invalid,
            &stats.nmea,
        )
    }

    /// The counts of the SiRF reader in this form (NMEA lines and SiRF frames together).
    pub fn from_sirf(stats: &super::sirf::SirfStats, records: &[GnssRecord]) -> Self {
        let summary = (stats.skipped() > stats.other).then(|| {
            format!(
                "SiRF: {} frames, {} MID 2 and {} MID 41 read; skipped {} bad checksum, {} truncated, {} invalid",
                stats.frames,
                stats.navigation,
                stats.geodetic,
                stats.bad_checksum,
                stats.truncated,
                stats.invalid,
            )
        });
        Self::from_binary(
            GnssFormat::Sirf,
            records,
            summary,
            [stats.frames, stats.bad_checksum, stats.truncated],
            stats.invalid,
            &stats.nmea,
        )
    }

    /// The counts of a binary reader (UBX, SiRF) with the NMEA lines found amid its frames:
    /// `[frames, bad_checksum, truncated]` of the binary frames, `skipped` the frames read
    /// but unused (untimed, invalid), and the reader's summary message, if any, first.
    fn from_binary(
        format: GnssFormat,
        records: &[GnssRecord],
        summary: Option<String>,
        [frames, bad_checksum, truncated]: [usize; 3],
        skipped: usize,
        nmea: &NmeaStats,
    ) -> Self {
        let fixes = records.iter().filter(|r| r.fix.is_some()).count();
        let mut messages: Vec<String> = summary.into_iter().collect();
        messages.extend(nmea.messages.iter().cloned());
        messages.truncate(MAX_GNSS_MESSAGES);
        Self {
            entries: frames + bad_checksum + truncated + nmea.lines,
            fixes,
            no_fix: records.len() - fixes,
            other_skipped: skipped
                + bad_checksum
                + truncated
                + nmea.bad_checksum
                + nmea.truncated
                + nmea.invalid,
            messages,
            ..Self::new(format)
        }
    }

    /// The counts of the NMEA reader in this form.
    pub fn from_nmea(stats: &NmeaStats, records: &[GnssRecord]) -> Self {
        let fixes = records.iter().filter(|r| r.fix.is_some()).count();
        Self {
            entries: stats.lines,
            fixes,
            no_fix: records.len() - fixes,
            other_skipped: stats.skipped(),
            messages: stats.messages.clone(),
            ..Self::new(GnssFormat::Nmea)
        }
    }

    /// Entries skipped for any reason.
    pub fn skipped(&self) -> usize {
        self.invalid_position + self.untimed + self.other_skipped
    }

    pub(crate) fn note(&mut self, message: String) {
        if self.messages.len() < MAX_GNSS_MESSAGES {
            self.messages.push(message);
        }
    }

    /// One warning line about `path` when anything was skipped or amended, else `None`.
    pub fn warning(&self, path: &Path) -> Option<String> {
        if self.skipped() + self.no_elevation == 0 {
            return None;
        }
        let first = self
            .messages
            .first()
            .map(|m| format!(" (first: {m})"))
            .unwrap_or_default();
        Some(format!(
            "{}: {} GNSS: {} of {} entries skipped ({} invalid position, {} without time, {} other), {} without height (taken as 0 m){first}",
            path.display(),
            self.format,
            self.skipped(),
            self.entries,
            self.invalid_position,
            self.untimed,
            self.other_skipped,
            self.no_elevation,
        ))
    }
}

/// A GNSS file read: its records (sorted by time) and the counts.
#[derive(Clone, Debug, PartialEq)]
pub struct GnssLog {
    /// The file.
    pub path: PathBuf,
    /// The records, sorted by time (drive clock: file time + offset).
    pub records: Vec<GnssRecord>,
    /// The counts.
    pub stats: GnssFileStats,
    /// The NMEA reader's own counts, for an NMEA file.
    pub nmea: Option<NmeaStats>,
}

/// Reads a GNSS file of `format` (detected by [`GnssFormat::detect`] when `None`) and
/// shifts its times by `time_offset_s` (seconds, added).
///
/// # Errors
/// [`GnssFileError`] naming the file (and the line, point or field): the file cannot be
/// read, a GPX document or an NCLT row is malformed, the offset is not finite. Entries with
/// an invalid position, GPX points without time and NMEA lines that cannot be used are
/// counted in [`GnssFileStats`], not errors.
///
/// # Example
/// ```
/// use vgps_replay::drive::gnss::{read_gnss_file, GnssFormat};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("gps.csv");
/// // 1 s apart; the second row has no fix (mode 1), the third a NaN latitude.
/// std::fs::write(&path, "1326030000000000,3,9,0.73817,-1.46102,270.5,0.1,1.2\n\
///     1326030001000000,1,3,0.73817,-1.46102,270.5,0.1,1.2\n\
///     1326030002000000,3,9,NaN,NaN,NaN,NaN,NaN\n")?;
/// let log = read_gnss_file(&path, None, 0.5)?;
/// assert_eq!(log.stats.format, GnssFormat::Nclt);
/// assert_eq!((log.records.len(), log.stats.fixes, log.stats.no_fix), (2, 1, 1));
/// assert_eq!(log.stats.invalid_position, 1);
/// assert_eq!(log.records[0].time_s, 1_326_030_000.5);
/// let fix = log.records[0].fix.unwrap();
/// assert!((fix.position.lat_deg - 0.73817_f64.to_degrees()).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn read_gnss_file(
    path: &Path,
    format: Option<GnssFormat>,
    time_offset_s: f64,
) -> Result<GnssLog, GnssFileError> {
    if !time_offset_s.is_finite() {
        return Err(GnssFileError::Offset {
            path: path.to_path_buf(),
            offset_s: time_offset_s,
        });
    }
    let bytes = std::fs::read(path).map_err(|source| GnssFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let format = format.unwrap_or_else(|| GnssFormat::detect_bytes(path, &bytes));
    let text = || String::from_utf8_lossy(&bytes).into_owned();
    let (mut records, stats, nmea_stats) = match format {
        GnssFormat::Nmea => {
            let (records, stats) = nmea::read_nmea(&text());
            let summary = GnssFileStats::from_nmea(&stats, &records);
            (records, summary, Some(stats))
        }
        GnssFormat::Ubx => {
            let (records, stats) = super::ubx::read_ubx(&bytes);
            let summary = GnssFileStats::from_ubx(&stats, &records);
            (records, summary, Some(stats.nmea))
        }
        GnssFormat::Sirf => {
            let (records, stats) = super::sirf::read_sirf(&bytes);
            let summary = GnssFileStats::from_sirf(&stats, &records);
            (records, summary, Some(stats.nmea))
        }
        GnssFormat::Gpx => {
            let (records, stats) = super::gpx::read_gpx(path, &text())?;
            (records, stats, None)
        }
        GnssFormat::Nclt => {
            let (records, stats) = super::nclt_gps::read_nclt_gps(path, &text())?;
            (records, stats, None)
        }
    };
    shift(&mut records, time_offset_s);
    Ok(GnssLog {
        path: path.to_path_buf(),
        records,
        stats,
        nmea: nmea_stats,
    })
}

fn shift(records: &mut [GnssRecord], time_offset_s: f64) {
    if time_offset_s != 0.0 {
        for r in records {
            r.time_s += time_offset_s;
        }
    }
}

/// Sorts records by time (stable: equal times keep the file order).
pub(crate) fn sort_by_time(records: &mut [GnssRecord]) {
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
}

/// Satellite GPS is interpolated between two epochs with a fix at most this far apart
/// (seconds); a longer gap is a gap.
pub const MAX_GNSS_INTERPOLATION_GAP_S: f64 = 1.0;

/// The satellite position at `time_s`, interpolated between the two epochs with a fix
/// around it when they are at most [`MAX_GNSS_INTERPOLATION_GAP_S`] apart.
pub fn gnss_at(records: &[GnssRecord], time_s: f64) -> Option<Geodetic> {
    let k = records.partition_point(|r| r.time_s <= time_s);
    let before = records.get(k.checked_sub(1)?)?;
    let a = before.fix?;
    if (time_s - before.time_s).abs() < 1e-9 {
        return Some(a.position);
    }
    let after = records.get(k)?;
    let b = after.fix?;
    let gap = after.time_s - before.time_s;
    if !(gap > 0.0 && gap <= MAX_GNSS_INTERPOLATION_GAP_S) {
        return None;
    }
    let w = (time_s - before.time_s) / gap;
    // Interpolating in degrees over < 1 s of travel (tens of metres) is exact to well below
    // a millimetre; longitude wrap-around is handled by interpolating the difference.
    let dlon = (b.position.lon_deg - a.position.lon_deg + 540.0).rem_euclid(360.0) - 180.0;
    let lon = a.position.lon_deg + w * dlon;
    let lon = (lon + 540.0).rem_euclid(360.0) - 180.0;
    Geodetic::try_new(
        a.position.lat_deg + w * (b.position.lat_deg - a.position.lat_deg),
        lon,
        a.position.alt_m + w * (b.position.alt_m - a.position.alt_m),
    )
    .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for f in GnssFormat::ALL {
            assert_eq!(f.to_string().parse::<GnssFormat>(), Ok(f));
            assert_eq!(f.as_str().to_uppercase().parse::<GnssFormat>(), Ok(f));
        }
        let e = "nmea0183".parse::<GnssFormat>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "`nmea0183` is not a satellite GPS format (nmea, gpx, nclt or ubx)"
        );
        assert!("".parse::<GnssFormat>().is_err());
    }

    #[test]
    fn sniffing_beats_the_extension() {
        let p = Path::new("gnss.nmea");
        assert_eq!(GnssFormat::detect(p, "\u{feff}  <gpx>"), GnssFormat::Gpx);
        assert_eq!(GnssFormat::detect(p, "1,2,3,4,5,6\n"), GnssFormat::Nclt);
        assert_eq!(GnssFormat::detect(p, "1,2,3\n"), GnssFormat::Nmea);
        assert_eq!(
            GnssFormat::detect(Path::new("x.CSV"), "utime,mode\n"),
            GnssFormat::Nclt
        );
        assert_eq!(GnssFormat::detect(Path::new("x"), ""), GnssFormat::Nmea);
    }
}
