//! An NCLT session (University of Michigan North Campus Long-Term dataset) into a drive.
//!
//! Looked for under the session directory (at any depth up to 3, so that both the
//! downloaded layout `…/2012-11-16/lb3/Cam0`, `sensor_data/2012-11-16/gps.csv`,
//! `ground_truth/groundtruth_2012-11-16.csv` and a flat one work):
//! - `lb3/Cam0…Cam5/<utime>.tiff`: the Ladybug3 images ([`crate::folders`], `utime` in µs);
//! - `gps.csv`: the consumer GPS, copied as the drive's satellite GPS (read by the drive's
//!   NCLT `gps.csv` reader);
//! - `gps_rtk.csv`: the RTK GPS, copied beside it (`gps_rtk.csv`, not in the manifest);
//! - `groundtruth_<date>.csv`: the ground truth, interpolated at each frame's time into
//!   `truth.csv`.
//!
//! # Ground truth
//! Rows `utime, x, y, z, roll, pitch, yaw` (µs; metres; radians), no header; rows with a
//! NaN (the first rows of a session) are skipped. `x, y, z` are north, east, down in
//! NCLT's local frame, whose origin is latitude [`NCLT_LAT0_RAD`], longitude
//! [`NCLT_LON0_RAD`] (as in NCLT's tools, linearized on an ellipsoid of radii
//! [`NCLT_RE_M`], [`NCLT_RP_M`]: `x = sin(lat − lat0)·r_ns`, `y = sin(lon − lon0)·r_ew·cos lat0`);
//! its height is not published: `alt = origin_alt − z` with `origin_alt` an option (0 by
//! default, so truth heights are relative). The attitude is `ned_from_body =
//! Rz(yaw)·Ry(pitch)·Rx(roll)` of NCLT's body frame (x forward, y right, z down), turned into
//! the drive's `enu_from_rig` (rig x forward, y left, z up); the ≈ 0.01° of meridian
//! convergence between the origin and the campus is neglected. A frame more than
//! [`MAX_TRUTH_GAP_S`] from a ground-truth sample on either side gets no truth.

use crate::drive_out::{DriveContent, ImportError, ImportReport, assemble_frames, write_drive};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use std::path::{Path, PathBuf};
use vgps_geometry::geo::Geodetic;
use vgps_replay::drive::{FrameRecord, Manifest, TruthRecord};

/// Latitude of the origin of NCLT's local frame, radians.
pub const NCLT_LAT0_RAD: f64 = 0.738_167_915_410_646;
/// Longitude of the origin of NCLT's local frame, radians.
pub const NCLT_LON0_RAD: f64 = -1.460_986_506_709_22;
/// Equatorial radius used by NCLT's linearization, metres.
pub const NCLT_RE_M: f64 = 6_378_135.0;
/// Polar radius used by NCLT's linearization, metres.
pub const NCLT_RP_M: f64 = 6_356_750.0;
/// Largest gap between a frame and the ground-truth samples around it, seconds.
pub const MAX_TRUTH_GAP_S: f64 = 0.5;
/// How deep below the session directory the files are looked for.
const SEARCH_DEPTH: usize = 3;

/// One ground-truth sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundTruthRow {
    /// Unix time, microseconds.
    pub utime: i64,
    /// North, east, down in the local frame, metres.
    pub ned_m: [f64; 3],
    /// Roll, pitch, yaw, radians.
    pub rpy: [f64; 3],
}

/// Reads NCLT ground truth; bad rows are warnings (naming file and line), NaN rows are
/// skipped silently (counted in `report.skipped`).
pub fn read_ground_truth(
    path: &Path,
    text: &str,
    report: &mut ImportReport,
) -> Vec<GroundTruthRow> {
    let mut out: Vec<GroundTruthRow> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed = (|| -> Result<Option<GroundTruthRow>, String> {
            if fields.len() < 7 {
                return Err(format!(
                    "{} fields, expected 7 (utime,x,y,z,roll,pitch,yaw)",
                    fields.len()
                ));
            }
            let utime: i64 = fields[0]
                .parse::<f64>()
                .ok()
                .filter(|t| t.is_finite() && t.abs() < 1e17)
                .map(|t| t as i64)
                .ok_or_else(|| format!("field `utime`: `{}` is not a time in µs", fields[0]))?;
            let mut v = [0.0; 6];
            for (k, name) in ["x", "y", "z", "roll", "pitch", "yaw"].iter().enumerate() {
                v[k] = fields[k + 1]
                    .parse::<f64>()
                    .map_err(|_| format!("field `{name}`: `{}` is not a number", fields[k + 1]))?;
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Ok(None);
            }
            Ok(Some(GroundTruthRow {
                utime,
                ned_m: [v[0], v[1], v[2]],
                rpy: [v[3], v[4], v[5]],
            }))
        })();
        match parsed {
            Ok(Some(row)) if out.last().is_none_or(|p| p.utime < row.utime) => out.push(row),
            Ok(Some(_)) => {
                report.skipped += 1;
                report.warn(format!(
                    "{}:{}: time does not increase; skipped",
                    path.display(),
                    n + 1
                ));
            }
            Ok(None) => report.skipped += 1,
            Err(e) => {
                report.skipped += 1;
                report.warn(format!("{}:{}: {e}; skipped", path.display(), n + 1));
            }
        }
    }
    out
}

/// The geodetic position of a point of NCLT's local frame (north, east, down; metres).
pub fn geodetic_of_local(ned_m: [f64; 3], origin_alt_m: f64) -> Option<Geodetic> {
    let (s, c) = NCLT_LAT0_RAD.sin_cos();
    let d = ((NCLT_RE_M * c).powi(2) + (NCLT_RP_M * s).powi(2)).sqrt();
    let r_ns = (NCLT_RE_M * NCLT_RP_M).powi(2) / d.powi(3);
    let r_ew = NCLT_RE_M.powi(2) / d;
    let sn = ned_m[0] / r_ns;
    let se = ned_m[1] / (r_ew * c);
    if sn.abs() > 1.0 || se.abs() > 1.0 {
        return None;
    }
    Geodetic::try_new(
        (NCLT_LAT0_RAD + sn.asin()).to_degrees(),
        (NCLT_LON0_RAD + se.asin()).to_degrees(),
        origin_alt_m - ned_m[2],
    )
    .ok()
}

/// The drive's `enu_from_rig` of an NCLT attitude (roll, pitch, yaw of the body in NED).
pub fn enu_from_rig_of_rpy(rpy: [f64; 3]) -> UnitQuaternion<f64> {
    let ned_from_body = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    let enu_from_ned = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0),
    ));
    let body_from_rig = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    enu_from_ned * ned_from_body * body_from_rig
}

/// The truth of each frame, interpolated in the ground truth (linear in position, slerp in
/// attitude).
pub fn truth_at_frames(
    frames: &[FrameRecord],
    gt: &[GroundTruthRow],
    origin_alt_m: f64,
) -> Vec<TruthRecord> {
    let mut out = Vec::new();
    for f in frames {
        let t_us = f.time_s * 1e6;
        let k = gt.partition_point(|r| (r.utime as f64) <= t_us);
        let (Some(a), Some(b)) = (
            k.checked_sub(1).and_then(|i| gt.get(i)),
            gt.get(k).or(gt.get(k.wrapping_sub(1))),
        ) else {
            continue;
        };
        let (ta, tb) = (a.utime as f64, b.utime as f64);
        if (t_us - ta) * 1e-6 > MAX_TRUTH_GAP_S || (tb - t_us) * 1e-6 > MAX_TRUTH_GAP_S {
            continue;
        }
        let w = if tb > ta {
            ((t_us - ta) / (tb - ta)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let ned = [0, 1, 2].map(|i| a.ned_m[i] + w * (b.ned_m[i] - a.ned_m[i]));
        let qa = enu_from_rig_of_rpy(a.rpy);
        let qb = enu_from_rig_of_rpy(b.rpy);
        let q = qa.try_slerp(&qb, w, 1e-9).unwrap_or(qa);
        if let Some(position) = geodetic_of_local(ned, origin_alt_m) {
            out.push(TruthRecord {
                frame: f.frame,
                position,
                enu_from_rig: q,
            });
        }
    }
    out
}

/// Options of an NCLT import.
#[derive(Clone, Debug)]
pub struct NcltImportOptions {
    /// The rig calibration (an NCLT calibration directory, or any format `vgps calib` reads).
    pub rig: PathBuf,
    /// The surveyed landmarks, if any (an empty table otherwise).
    pub landmarks: Option<PathBuf>,
    /// Largest spread of the stamps of one frame, seconds.
    pub stamp_tolerance_s: f64,
    /// Ellipsoidal height of the origin of NCLT's local frame, metres (truth heights).
    pub origin_alt_m: f64,
}

fn find(dir: &Path, depth: usize, want: &dyn Fn(&str, bool) -> bool, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        let is_dir = p.is_dir();
        if p.file_name()
            .is_some_and(|n| want(&n.to_string_lossy(), is_dir))
        {
            found.push(p.clone());
        }
        if is_dir && depth > 0 {
            find(&p, depth - 1, want, found);
        }
    }
}

fn find_one(
    session: &Path,
    want: &dyn Fn(&str, bool) -> bool,
    report: &mut ImportReport,
    what: &str,
) -> Option<PathBuf> {
    let mut found = Vec::new();
    find(session, SEARCH_DEPTH, want, &mut found);
    if found.len() > 1 {
        report.warn(format!(
            "{}: {} {what} found; using {}",
            session.display(),
            found.len(),
            found[0].display()
        ));
    }
    found.into_iter().next()
}

/// Imports the NCLT session under `session` into the drive folder `out`.
///
/// # Errors
/// [`ImportError`] when there is no `lb3` folder, a file cannot be read, or a drive file
/// cannot be written.
pub fn import_nclt(
    session: &Path,
    out: &Path,
    options: &NcltImportOptions,
) -> Result<(Manifest, ImportReport), ImportError> {
    let mut report = ImportReport::default();
    let lb3 = find_one(
        session,
        &|n, dir| dir && n == "lb3",
        &mut report,
        "lb3 folders",
    )
    .ok_or_else(|| {
        ImportError::Input(format!(
            "{}: no `lb3` folder (with Cam0…Cam5) found",
            session.display()
        ))
    })?;
    let images = crate::folders::scan_folders(&lb3, &mut report)?;
    let frames = assemble_frames(images, (options.stamp_tolerance_s * 1e9).round() as i64);
    let gps = find_one(
        session,
        &|n, dir| !dir && n == "gps.csv",
        &mut report,
        "gps.csv files",
    );
    if gps.is_none() {
        report.warn(format!(
            "{}: no gps.csv: the drive has no satellite GPS",
            session.display()
        ));
    }
    let truth = match find_one(
        session,
        &|n, dir| !dir && n.starts_with("groundtruth_") && n.ends_with(".csv"),
        &mut report,
        "ground-truth files",
    ) {
        Some(path) => {
            let text = std::fs::read_to_string(&path).map_err(|source| ImportError::Read {
                path: path.clone(),
                source,
            })?;
            let gt = read_ground_truth(&path, &text, &mut report);
            truth_at_frames(&frames, &gt, options.origin_alt_m)
        }
        None => Vec::new(),
    };
    let content = DriveContent {
        frames,
        gnss_file: gps,
        truth,
        ..DriveContent::default()
    };
    let manifest = write_drive(
        out,
        &options.rig,
        options.landmarks.as_deref(),
        &content,
        &mut report,
    )?;
    if let Some(rtk) = find_one(
        session,
        &|n, dir| !dir && n == "gps_rtk.csv",
        &mut report,
        "gps_rtk.csv files",
    ) {
        let bytes = std::fs::read(&rtk).map_err(|source| ImportError::Read {
            path: rtk.clone(),
            source,
        })?;
        let dest = out.join("gps_rtk.csv");
        vgps_io::write_atomic(&dest, &bytes)
            .map_err(|source| ImportError::Write { path: dest, source })?;
    }
    Ok((manifest, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_origin_is_the_published_origin() {
        let g = geodetic_of_local([0.0, 0.0, -3.0], 250.0).unwrap();
        assert!((g.lat_deg - NCLT_LAT0_RAD.to_degrees()).abs() < 1e-12);
        assert!((g.lon_deg - NCLT_LON0_RAD.to_degrees()).abs() < 1e-12);
        assert_eq!(g.alt_m, 253.0);
        // 100 m north is 100 m of latitude (to the linearization's 1e-4).
        let n = geodetic_of_local([100.0, 0.0, 0.0], 0.0).unwrap();
        let frame = vgps_geometry::geo::LocalFrame::new(g);
        let enu = frame.to_enu(&n);
        assert!(
            (enu.y - 100.0).abs() < 0.05 && enu.x.abs() < 1e-6,
            "{enu:?}"
        );
    }

    #[test]
    fn attitude_conversion_maps_the_axes() {
        // Yaw 90° (body x to the east), level: rig x (forward) is east, rig y (left) north,
        // rig z up.
        let q = enu_from_rig_of_rpy([0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let x = q * Vector3::x();
        let y = q * Vector3::y();
        let z = q * Vector3::z();
        assert!((x - Vector3::x()).norm() < 1e-12, "{x:?}");
        assert!((y - Vector3::y()).norm() < 1e-12, "{y:?}");
        assert!((z - Vector3::z()).norm() < 1e-12, "{z:?}");
        // Yaw 0: forward is north, left is west.
        let q = enu_from_rig_of_rpy([0.0, 0.0, 0.0]);
        assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert!((q * Vector3::y() + Vector3::x()).norm() < 1e-12);
    }
}
