//! `--gnss FILE [--gnss-format nmea|gpx|nclt|ubx] [--gnss-time-offset S]`: the satellite GPS of
//! a drive taken from another file (shared by `vgps replay` and `vgps map`).

use super::CliError;
use super::value_enums::GnssFormatArg;
use std::io::Write;
use std::path::PathBuf;
use vgps_replay::drive::Drive;
use vgps_replay::drive::gnss::read_gnss_file;

fn parse_finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("`{text}` is not a finite number of seconds")),
    }
}

/// The options that replace a drive's satellite GPS.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct GnssInputArgs {
    /// Satellite GPS file to use instead of the drive's `gnss` (NMEA 0183, GPX 1.0/1.1
    /// track, or NCLT `gps.csv`; see docs/drive-format.md).
    #[arg(long, value_name = "FILE")]
    pub gnss: Option<PathBuf>,
    /// Format of `--gnss` (default: detected from the content, then the extension).
    #[arg(long, value_enum, value_name = "FORMAT", requires = "gnss")]
    pub gnss_format: Option<GnssFormatArg>,
    /// Seconds added to every time of `--gnss` to put it on the drive clock (Unix UTC).
    #[arg(long, value_name = "S", default_value_t = 0.0, value_parser = parse_finite, allow_hyphen_values = true, requires = "gnss")]
    pub gnss_time_offset: f64,
}

impl GnssInputArgs {
    /// Reads `--gnss` (when given) into `drive` ([`Drive::replace_gnss`]: the reader's
    /// warning joins [`Drive::warnings`]); warns on `err` when the file has no fix.
    ///
    /// # Errors
    /// [`CliError::Calibration`] (exit 2) naming the file, line and field of an unreadable
    /// or malformed file.
    pub fn apply(&self, drive: &mut Drive, err: &mut dyn Write) -> Result<(), CliError> {
        let Some(path) = &self.gnss else {
            return Ok(());
        };
        let log = read_gnss_file(
            path,
            self.gnss_format.map(Into::into),
            self.gnss_time_offset,
        )
        .map_err(|e| CliError::Calibration(e.to_string()))?;
        let s = &log.stats;
        if s.fixes == 0 {
            let _ = writeln!(
                err,
                "vgps: warning: {}: no GNSS fix in {} {} entries",
                path.display(),
                s.entries,
                s.format
            );
        }
        drive.replace_gnss(log);
        Ok(())
    }
}
