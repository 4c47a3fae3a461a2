//! Reference poses as other tools write them, read as the drive's truth: vgps's own
//! `truth.csv` (per frame), TUM trajectories, NCLT ground truth and INS exports (per time,
//! interpolated to the frames' times).
//!
//! # Formats (detected from the content)
//! - **vgps** `truth.csv`: a header with `frame`; `frame,lat,lon,alt,qw,qx,qy,qz`,
//!   `enu_from_rig` (see [`super::TruthRecord`]).
//! - **INS export** CSV: a header naming `time` (or `time_s`), `lat`, `lon`, `height` (or
//!   `alt`), `roll`, `pitch`, `yaw` (other columns ignored). Unix seconds (UTC); WGS84
//!   degrees and ellipsoidal metres; **angles in degrees**, the aerospace convention: body
//!   x forward, y right, z down; `ned_from_body = Rz(yaw)·Ry(pitch)·Rx(roll)` (yaw is the
//!   heading, clockwise from true north).
//! - **NCLT ground truth** `groundtruth_<date>.csv`: no header,
//!   `utime,x,y,z,roll,pitch,yaw`: Unix microseconds; metres in NCLT's local NED frame
//!   (x north, y east, z down) at NCLT's origin ([`NCLT_ORIGIN_LAT_RAD`],
//!   [`NCLT_ORIGIN_LON_RAD`], NCLT's `gps_to_local` mapping inverted, the height of the
//!   origin [`NCLT_ORIGIN_ALT_M`]); **angles in radians**, the same body axes and rotation
//!   order as the INS export.
//! - **TUM** trajectory: `timestamp tx ty tz qx qy qz qw` separated by spaces, `#`
//!   comments. Unix seconds; metres in a local east-north-up frame, the quaternion
//!   `enu_from_rig` (rig axes x forward, y left, z up). The local frame's origin comes from a
//!   comment `# origin: lat,lon,alt` (WGS84 degrees, ellipsoidal metres) in the file; a
//!   TUM file without it cannot be placed on the Earth and is refused.
//!
//! # Quaternions
//! A quaternion whose norm is within [`super::QUATERNION_NORM_TOLERANCE`] of 1 (what
//! rounding and conversions leave) is normalised; a row whose norm is further off is
//! refused, and only that row.
//!
//! # Interpolation
//! A frame gets the truth interpolated between the two reference samples around its time
//! when they are at most [`MAX_TRUTH_GAP_S`] apart (position linear in latitude, longitude
//! and height, attitude by slerp); a frame outside or in a larger gap has no truth.

use super::{FrameRecord, TruthRecord};
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};
use std::path::Path;
use vgps_geometry::geo::Geodetic;

/// NCLT's local frame origin latitude, radians (NCLT's `read_gps.py`).
pub const NCLT_ORIGIN_LAT_RAD: f64 = 0.738_167_915_410_646;
/// NCLT's local frame origin longitude, radians.
pub const NCLT_ORIGIN_LON_RAD: f64 = -1.460_986_506_709_22;
/// The height taken for NCLT's origin, metres (NCLT does not publish one; its ground truth
/// heights are relative). Heights of NCLT truth are therefore relative, not ellipsoidal.
pub const NCLT_ORIGIN_ALT_M: f64 = 0.0;
/// Largest gap between two reference samples interpolated across, seconds.
pub const MAX_TRUTH_GAP_S: f64 = 0.5;
/// How many messages about refused rows are kept.
pub const MAX_TRUTH_MESSAGES: usize = 20;

/// The formats of a truth file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TruthFormat {
    /// vgps `truth.csv` (per frame).
    Vgps,
    /// INS export CSV (time, lat, lon, height, roll, pitch, yaw in degrees).
    Ins,
    /// NCLT ground truth (utime, x, y, z, roll, pitch, yaw in radians).
    Nclt,
    /// TUM trajectory (timestamp tx ty tz qx qy qz qw) with a `# origin:` comment.
    Tum,
}

impl TruthFormat {
    /// The format the content shows: a header naming `frame` is vgps, one naming `roll` is
    /// an INS export; a first data line of 7 comma-separated numbers is NCLT, of 8
    /// space-separated numbers TUM. `None` otherwise.
    pub fn sniff(text: &str) -> Option<Self> {
        let mut lines = text
            .trim_start_matches('\u{feff}')
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'));
        let first = lines.next()?;
        let lower = first.to_ascii_lowercase();
        let names: Vec<&str> = lower.split(',').map(str::trim).collect();
        if names.contains(&"frame") {
            return Some(Self::Vgps);
        }
        if names.contains(&"roll") {
            return Some(Self::Ins);
        }
        let numbers = |parts: &[&str]| parts.iter().all(|p| p.parse::<f64>().is_ok());
        let commas: Vec<&str> = first.split(',').map(str::trim).collect();
        if commas.len() == 7 && numbers(&commas) {
            return Some(Self::Nclt);
        }
        let spaces: Vec<&str> = first.split_whitespace().collect();
        if spaces.len() == 8 && numbers(&spaces) {
            return Some(Self::Tum);
        }
        None
    }
}

/// A truth file read: the records of the frames, what was refused, the format.
#[derive(Clone, Debug, PartialEq)]
pub struct TruthRead {
    /// The format read.
    pub format: TruthFormat,
    /// One record per frame that has truth, in frame order.
    pub records: Vec<TruthRecord>,
    /// Rows refused (clearly broken): their count.
    pub refused: usize,
    /// Quaternions normalised (norm off by less than the tolerance but not exactly 1).
    pub normalised: usize,
    /// The first [`MAX_TRUTH_MESSAGES`] messages about refused rows (`file:line: field …`).
    pub messages: Vec<String>,
}

impl TruthRead {
    fn refuse(&mut self, message: String) {
        self.refused += 1;
        if self.messages.len() < MAX_TRUTH_MESSAGES {
            self.messages.push(message);
        }
    }

    /// One warning line when rows were refused, else `None`.
    pub fn warning(&self, path: &Path) -> Option<String> {
        (self.refused > 0).then(|| {
            format!(
                "{}: {} truth rows refused, the others used (first: {})",
                path.display(),
                self.refused,
                self.messages.first().map_or("", String::as_str)
            )
        })
    }
}

/// A reference sample at a time.
#[derive(Clone, Copy, Debug)]
struct TruthSample {
    time_s: f64,
    position: Geodetic,
    enu_from_rig: UnitQuaternion<f64>,
}

/// A quaternion within the norm tolerance, normalised; `Err` names the norm.
pub(super) fn normalise(q: Quaternion<f64>) -> Result<(UnitQuaternion<f64>, bool), String> {
    let norm = q.norm();
    if !norm.is_finite() || (norm - 1.0).abs() > super::QUATERNION_NORM_TOLERANCE {
        return Err(format!(
            "quaternion norm {norm} is not 1 within {}",
            super::QUATERNION_NORM_TOLERANCE
        ));
    }
    Ok((UnitQuaternion::new_normalize(q), norm != 1.0))
}

/// `ned_from_body = Rz(yaw)·Ry(pitch)·Rx(roll)` turned into `enu_from_rig` (rig x forward,
/// y left, z up): `enu_from_ned · ned_from_body · body_from_rig`.
pub fn enu_from_rig_of_ned_euler(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    let ned_from_body = Rotation3::from_euler_angles(roll, pitch, yaw);
    // E = N_y, N = N_x, U = −N_z; body (forward, right, down) → rig (forward, left, up).
    let enu_from_ned = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    let body_from_rig = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let m = enu_from_ned * ned_from_body.matrix() * body_from_rig;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// NCLT's `gps_to_local` radii at its origin (their `re = 6378135`, `rp = 6356750`).
fn nclt_radii() -> (f64, f64) {
    let (re, rp) = (6_378_135.0_f64, 6_356_750.0_f64);
    let (s, c) = NCLT_ORIGIN_LAT_RAD.sin_cos();
    let d = (re * c).powi(2) + (rp * s).powi(2);
    let r_ns = (re * rp).powi(2) / d.powf(1.5);
    let r_ew = re * re / d.sqrt();
    (r_ns, r_ew)
}

/// NCLT local (x north, y east, z down, metres) → WGS84, inverting NCLT's `gps_to_local`
/// (`x = sin(lat − lat0)·r_ns`, `y = sin(lon − lon0)·r_ew·cos(lat0)`).
pub fn nclt_local_to_geodetic(x: f64, y: f64, z: f64) -> Option<Geodetic> {
    let (r_ns, r_ew) = nclt_radii();
    let sl = x / r_ns;
    let so = y / (r_ew * NCLT_ORIGIN_LAT_RAD.cos());
    if sl.abs() > 1.0 || so.abs() > 1.0 {
        return None;
    }
    let lat = (NCLT_ORIGIN_LAT_RAD + sl.asin()).to_degrees();
    let lon = (NCLT_ORIGIN_LON_RAD + so.asin()).to_degrees();
    Geodetic::try_new(lat, lon, NCLT_ORIGIN_ALT_M - z).ok()
}

fn numbers(parts: &[&str], names: &[&str]) -> Result<Vec<f64>, String> {
    parts
        .iter()
        .zip(names)
        .map(|(p, name)| match p.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(format!(
                "field `{name}`: `{}` is not a finite number",
                p.trim()
            )),
        })
        .collect()
}

/// The rows of a headerless table of numbers (`sep`: the field separator, `None` for white
/// space), blank and `#` lines skipped: `(0-based line index, one value per name)`. A row
/// with another number of fields than `names`, or a field that is not a finite number, is
/// refused (`read`, naming file, line and field) and left out.
fn numeric_rows(
    path: &Path,
    text: &str,
    sep: Option<char>,
    names: &[&str],
    format: &str,
    read: &mut TruthRead,
) -> Vec<(usize, Vec<f64>)> {
    let file = path.display();
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let parts: Vec<&str> = match sep {
            Some(c) => line.split(c).collect(),
            None => line.split_whitespace().collect(),
        };
        if parts.len() != names.len() {
            read.refuse(format!(
                "{file}:{}: {} fields, {format} has {}",
                k + 1,
                parts.len(),
                names.len()
            ));
            continue;
        }
        match numbers(&parts, names) {
            Ok(v) => rows.push((k, v)),
            Err(e) => read.refuse(format!("{file}:{}: {e}", k + 1)),
        }
    }
    rows
}

/// Reads a truth file of any format for `frames`. Rows that are clearly broken are refused
/// one by one ([`TruthRead::messages`]); the others are used.
///
/// # Errors
/// A message naming the file (and line) when the file as a whole cannot be used: unknown
/// format, a bad header, a TUM file without its origin.
///
/// # Example
/// ```
/// use vgps_replay::drive::{FrameRecord, truth_formats::{read_truth, TruthFormat}};
/// use std::path::Path;
/// let frames = [FrameRecord { frame: 3, time_s: 100.25, images: vec![] }];
/// // An INS export: level, heading east (yaw 90°), at 100.0 s and 100.5 s.
/// let ins = "time,lat,lon,height,roll,pitch,yaw\n100.0,45,7,300,0,0,90\n100.5,45.00001,7,302,0,0,90\n";
/// let t = read_truth(Path::new("ins.csv"), ins, &frames)?;
/// assert_eq!((t.format, t.records.len()), (TruthFormat::Ins, 1));
/// assert!((t.records[0].position.alt_m - 301.0).abs() < 1e-9);
/// // The rig's forward axis (x) points east.
/// let fwd = t.records[0].enu_from_rig * nalgebra::Vector3::x();
/// assert!((fwd - nalgebra::Vector3::x()).norm() < 1e-12);
/// # Ok::<(), String>(())
/// ```
pub fn read_truth(path: &Path, text: &str, frames: &[FrameRecord]) -> Result<TruthRead, String> {
    let file = path.display();
    let format = TruthFormat::sniff(text).ok_or_else(|| {
        format!(
            "{file}: not a truth file (expected a vgps truth.csv, an INS export CSV with \
             time,lat,lon,height,roll,pitch,yaw, NCLT ground truth or a TUM trajectory)"
        )
    })?;
    let mut read = TruthRead {
        format,
        records: Vec::new(),
        refused: 0,
        normalised: 0,
        messages: Vec::new(),
    };
    if format == TruthFormat::Vgps {
        let (records, rows) =
            super::tables::truth_rows(path, text, frames).map_err(|e| e.to_string())?;
        read.records = records;
        for r in rows {
            match r {
                Ok(normalised) => read.normalised += usize::from(normalised),
                Err(message) => read.refuse(message),
            }
        }
        return Ok(read);
    }
    let samples = match format {
        TruthFormat::Ins => ins_samples(path, text, &mut read)?,
        TruthFormat::Nclt => nclt_samples(path, text, &mut read),
        _ => tum_samples(path, text, &mut read)?,
    };
    read.records = at_frames(&samples, frames);
    Ok(read)
}

fn ins_samples(path: &Path, text: &str, read: &mut TruthRead) -> Result<Vec<TruthSample>, String> {
    let file = path.display();
    let mut lines = text
        .trim_start_matches('\u{feff}')
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (header_k, header) = lines.next().ok_or(format!("{file}: empty"))?;
    let names: Vec<String> = header
        .split(',')
        .map(|n| n.trim().to_ascii_lowercase())
        .collect();
    let column = |options: &[&str]| -> Result<usize, String> {
        names
            .iter()
            .position(|n| options.contains(&n.as_str()))
            .ok_or_else(|| {
                format!(
                    "{file}:{}: field `{}`: required column is missing",
                    header_k + 1,
                    options[0]
                )
            })
    };
    let cols = [
        column(&["time", "time_s"])?,
        column(&["lat"])?,
        column(&["lon"])?,
        column(&["height", "alt"])?,
        column(&["roll"])?,
        column(&["pitch"])?,
        column(&["yaw", "heading"])?,
    ];
    let col_names = ["time", "lat", "lon", "height", "roll", "pitch", "yaw"];
    let mut out = Vec::new();
    for (k, line) in lines {
        let parts: Vec<&str> = line.split(',').collect();
        let picked: Vec<&str> = cols
            .iter()
            .map(|&c| parts.get(c).copied().unwrap_or(""))
            .collect();
        let v = match numbers(&picked, &col_names) {
            Ok(v) => v,
            Err(e) => {
                read.refuse(format!("{file}:{}: {e}", k + 1));
                continue;
            }
        };
        let Ok(position) = Geodetic::try_new(v[1], v[2], v[3]) else {
            read.refuse(format!(
                "{file}:{}: field `lat`: position out of range",
                k + 1
            ));
            continue;
        };
        out.push(TruthSample {
            time_s: v[0],
            position,
            enu_from_rig: enu_from_rig_of_ned_euler(
                v[4].to_radians(),
                v[5].to_radians(),
                v[6].to_radians(),
            ),
        });
    }
    Ok(sorted(out))
}

fn nclt_samples(path: &Path, text: &str, read: &mut TruthRead) -> Vec<TruthSample> {
    let file = path.display();
    let names = ["utime", "x", "y", "z", "roll", "pitch", "yaw"];
    let mut out = Vec::new();
    for (k, v) in numeric_rows(path, text, Some(','), &names, "NCLT ground truth", read) {
        let Some(position) = nclt_local_to_geodetic(v[1], v[2], v[3]) else {
            read.refuse(format!(
                "{file}:{}: field `x`: too far from NCLT's origin",
                k + 1
            ));
            continue;
        };
        out.push(TruthSample {
            time_s: v[0] * 1e-6,
            position,
            enu_from_rig: enu_from_rig_of_ned_euler(v[4], v[5], v[6]),
        });
    }
    sorted(out)
}

fn tum_samples(path: &Path, text: &str, read: &mut TruthRead) -> Result<Vec<TruthSample>, String> {
    let file = path.display();
    let origin = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix('#'))
        .find_map(|c| c.trim().strip_prefix("origin:"))
        .ok_or_else(|| {
            format!(
                "{file}: a TUM trajectory needs its local frame's origin: add a comment \
                 `# origin: lat,lon,alt` (WGS84 degrees, ellipsoidal metres)"
            )
        })?;
    let o: Vec<&str> = origin.split(',').collect();
    let o = numbers(&o, &["origin lat", "origin lon", "origin alt"])
        .ok()
        .filter(|o| o.len() == 3)
        .and_then(|o| Geodetic::try_new(o[0], o[1], o[2]).ok())
        .ok_or_else(|| format!("{file}: `# origin:{origin}` is not lat,lon,alt"))?;
    let local = vgps_geometry::geo::LocalFrame::new(o);
    let names = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"];
    let mut out = Vec::new();
    for (k, v) in numeric_rows(path, text, None, &names, "TUM", read) {
        let (q, normalised) = match normalise(Quaternion::new(v[7], v[4], v[5], v[6])) {
            Ok(q) => q,
            Err(e) => {
                read.refuse(format!("{file}:{}: field `qw`: {e}", k + 1));
                continue;
            }
        };
        read.normalised += usize::from(normalised);
        let Ok(position) = local.try_to_geodetic(&Vector3::new(v[1], v[2], v[3])) else {
            read.refuse(format!("{file}:{}: field `tx`: not a position", k + 1));
            continue;
        };
        // The attitude in the ENU frame at the sample's own position (a few metres to
        // kilometres from the origin): enu_here_from_rig = enu_here_from_enu0 · enu0_from_rig.
        let enu_here_from_enu0 = UnitQuaternion::from_rotation_matrix(
            &vgps_geometry::geo::LocalFrame::new(position).enu_here_from_enu_at(&o),
        );
        out.push(TruthSample {
            time_s: v[0],
            position,
            enu_from_rig: enu_here_from_enu0 * q,
        });
    }
    Ok(sorted(out))
}

fn sorted(mut samples: Vec<TruthSample>) -> Vec<TruthSample> {
    samples.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    samples
}

/// The truth of each frame, interpolated between the samples around its time.
fn at_frames(samples: &[TruthSample], frames: &[FrameRecord]) -> Vec<TruthRecord> {
    let mut out = Vec::new();
    for f in frames {
        let k = samples.partition_point(|s| s.time_s <= f.time_s);
        let Some(a) = k.checked_sub(1).and_then(|i| samples.get(i)) else {
            continue;
        };
        let (position, enu_from_rig) = if a.time_s == f.time_s {
            (a.position, a.enu_from_rig)
        } else {
            let Some(b) = samples.get(k) else { continue };
            let gap = b.time_s - a.time_s;
            if !(gap > 0.0 && gap <= MAX_TRUTH_GAP_S) {
                continue;
            }
            let w = (f.time_s - a.time_s) / gap;
            let lerp = |x: f64, y: f64| x + w * (y - x);
            let Ok(p) = Geodetic::try_new(
                lerp(a.position.lat_deg, b.position.lat_deg),
                lerp(a.position.lon_deg, b.position.lon_deg),
                lerp(a.position.alt_m, b.position.alt_m),
            ) else {
                continue;
            };
            let q = a
                .enu_from_rig
                .try_slerp(&b.enu_from_rig, w, 1e-9)
                .unwrap_or(a.enu_from_rig);
            (p, q)
        };
        out.push(TruthRecord {
            frame: f.frame,
            position,
            enu_from_rig,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(times: &[f64]) -> Vec<FrameRecord> {
        times
            .iter()
            .enumerate()
            .map(|(k, &t)| FrameRecord {
                frame: k as u64,
                time_s: t,
                images: vec![],
            })
            .collect()
    }

    #[test]
    fn sniffing() {
        assert_eq!(TruthFormat::sniff("frame,lat\n"), Some(TruthFormat::Vgps));
        assert_eq!(
            TruthFormat::sniff("# x\nTime,Lat,Lon,Height,Roll,Pitch,Yaw\n"),
            Some(TruthFormat::Ins)
        );
        assert_eq!(
            TruthFormat::sniff("1326030000000000,1,2,3,0.1,0.2,0.3\n"),
            Some(TruthFormat::Nclt)
        );
        assert_eq!(
            TruthFormat::sniff("# origin: 1,2,3\n1.0 1 2 3 0 0 0 1\n"),
            Some(TruthFormat::Tum)
        );
        assert_eq!(TruthFormat::sniff("hello\n"), None);
    }

    #[test]
    fn euler_convention_known_answers() {
        // Yaw 0: forward is north, left is west, up is up.
        let q = enu_from_rig_of_ned_euler(0.0, 0.0, 0.0);
        assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert!((q * Vector3::y() + Vector3::x()).norm() < 1e-12);
        assert!((q * Vector3::z() - Vector3::z()).norm() < 1e-12);
        // Pitch up 10°: forward rises.
        let q = enu_from_rig_of_ned_euler(0.0, 10f64.to_radians(), 0.0);
        let fwd = q * Vector3::x();
        assert!((fwd.z - 10f64.to_radians().sin()).abs() < 1e-12);
        // Roll right 5°: the left axis rises.
        let q = enu_from_rig_of_ned_euler(5f64.to_radians(), 0.0, 0.0);
        assert!(((q * Vector3::y()).z - 5f64.to_radians().sin()).abs() < 1e-12);
    }

    #[test]
    fn nclt_mapping_inverts_nclts_own() {
        // NCLT's gps_to_local of a point 100 m north, 50 m east of the origin.
        let (r_ns, r_ew) = nclt_radii();
        let lat = NCLT_ORIGIN_LAT_RAD + 1e-5;
        let lon = NCLT_ORIGIN_LON_RAD + 2e-5;
        let x = (lat - NCLT_ORIGIN_LAT_RAD).sin() * r_ns;
        let y = (lon - NCLT_ORIGIN_LON_RAD).sin() * r_ew * NCLT_ORIGIN_LAT_RAD.cos();
        let p = nclt_local_to_geodetic(x, y, -2.0).unwrap();
        assert!((p.lat_deg - lat.to_degrees()).abs() < 1e-12);
        assert!((p.lon_deg - lon.to_degrees()).abs() < 1e-12);
        assert_eq!(p.alt_m, 2.0);
        assert!(nclt_local_to_geodetic(1e9, 0.0, 0.0).is_none());
    }

    #[test]
    fn nclt_rows_are_interpolated_and_bad_rows_refused_alone() {
        let text =
            "1000000000,0,0,0,0,0,0\n1000000,nan,0,0,0,0,0\n1000100000,10,0,0,0,0,0.1\n1,2,3\n";
        let t = read_truth(Path::new("gt.csv"), text, &frames(&[1000.05, 2000.0])).unwrap();
        assert_eq!(
            (t.format, t.records.len(), t.refused),
            (TruthFormat::Nclt, 1, 2)
        );
        assert_eq!(
            t.messages[0],
            "gt.csv:2: field `x`: `nan` is not a finite number"
        );
        let (r_ns, _) = nclt_radii();
        let north = (t.records[0].position.lat_deg.to_radians() - NCLT_ORIGIN_LAT_RAD) * r_ns;
        assert!((north - 5.0).abs() < 1e-6, "{north}");
    }

    #[test]
    fn tum_needs_its_origin_and_places_the_rig() {
        let body = "100.0 0 0 0 0 0 0 1\n100.2 10 0 0 0 0 0 1.0000001\n100.4 1 1 1 0 0 0 2\n";
        let e = read_truth(Path::new("t.txt"), body, &frames(&[100.1])).unwrap_err();
        assert!(e.starts_with("t.txt: a TUM trajectory needs"), "{e}");
        let text = format!("# origin: 45,7,300\n{body}");
        let t = read_truth(Path::new("t.txt"), &text, &frames(&[100.1])).unwrap();
        assert_eq!((t.records.len(), t.refused, t.normalised), (1, 1, 1));
        assert!(t.messages[0].starts_with("t.txt:4: field `qw`: quaternion norm 2"));
        let p = t.records[0].position;
        let east_m = (p.lon_deg - 7.0).to_radians() * 6_378_137.0 * 45f64.to_radians().cos();
        assert!((east_m - 5.0).abs() < 0.02, "{east_m}");
    }

    #[test]
    fn vgps_truth_from_another_tool_is_normalised_and_broken_rows_refused_alone() {
        // The issue's file: a norm of 1.000002267965134 was refused whole (exit 2).
        let qw = 1.000_002_267_965_134_f64;
        let text = format!(
            "frame,lat,lon,alt,qw,qx,qy,qz\n0,45,7,300,{qw},0,0,0\n1,45,7,300,2,0,0,0\n2,45,7,x,1,0,0,0\n"
        );
        let t = read_truth(Path::new("truth.csv"), &text, &frames(&[0.0, 0.1, 0.2])).unwrap();
        assert_eq!(
            (t.format, t.records.len(), t.normalised, t.refused),
            (TruthFormat::Vgps, 1, 1, 2)
        );
        assert!((t.records[0].enu_from_rig.quaternion().norm() - 1.0).abs() < 1e-15);
        assert_eq!(
            t.messages,
            [
                "truth.csv:3: field `qw`: quaternion norm 2 is not 1 within 0.001",
                "truth.csv:4: field `alt`: `x` is not a number",
            ]
        );
        assert_eq!(
            t.warning(Path::new("truth.csv")).unwrap(),
            "truth.csv: 2 truth rows refused, the others used (first: truth.csv:3: field `qw`: quaternion norm 2 is not 1 within 0.001)"
        );
        // The strict reader (library API) still reports the first broken row.
        let e =
            super::super::truth_from_text(Path::new("truth.csv"), &text, &frames(&[0.0, 0.1, 0.2]));
        assert!(
            e.unwrap_err()
                .to_string()
                .starts_with("truth.csv:3: field `qw`")
        );
    }

    #[test]
    fn ins_without_a_column_is_refused_whole() {
        let e = read_truth(Path::new("i.csv"), "time,lat,lon,roll,pitch,yaw\n", &[]).unwrap_err();
        assert_eq!(e, "i.csv:1: field `height`: required column is missing");
    }
}
