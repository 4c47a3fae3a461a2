//! NCLT-style Ladybug3 calibration directories (the University of Michigan North Campus
//! Long-Term dataset layout).
//!
//! For each camera `i = 0, 1, …` (consecutive from 0):
//! - `K_cam{i}.csv`: the 3×3 intrinsic matrix of the **undistorted** image, three lines of
//!   three comma-separated numbers, `[fx s cx; 0 fy cy; 0 0 1]` (pixels; integer = pixel
//!   centre; `u = fx x/z + s y/z + cx`, `v = fy y/z + cy` in the camera frame x right,
//!   y down, z forward).
//! - `x_lb3_c{i}.csv`: one line `x,y,z,roll,pitch,yaw` (metres, degrees):
//!   `head_from_camera = (Rz(yaw)·Ry(pitch)·Rx(roll), (x, y, z))`. The head frame is used as
//!   the rig frame (camera 0 along +x, the top camera along +z, y left).
//! - `U2D_Cam{i}_{W}X{H}.txt` and `D2U_Cam{i}_{W}X{H}.txt`: a header line naming the width
//!   and height (its two integers, e.g. `64 48`), then `W·H` lines `r c r' c'` (whitespace-
//!   or comma-separated): pixel `(r, c)` (row, column, integers) of one image and its
//!   sub-pixel position `(r', c')` in the other. `U2D` maps undistorted → raw, `D2U` raw →
//!   undistorted. Lines may come in any order; each pixel exactly once.
//!
//! The camera is a [`TabulatedPinhole`]: raw pixel → `D2U` (bilinear) → `K⁻¹` → bearing;
//! its inverse seeds with `U2D` and refines on `D2U` by Newton's method.

use super::{LoadError, write_atomic};
use crate::calibration::{
    Camera, DistortionTable, Rig, RigCamera, TabulatedPinhole, TabulatedPinholeParams,
};
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, Vector3};
use std::path::{Path, PathBuf};

/// Largest accepted deviation of `K`'s fixed entries (`K[1][0]`, `K[2][0]`, `K[2][1]` = 0,
/// `K[2][2]` = 1).
pub const K_FIXED_ENTRY_TOLERANCE: f64 = 1e-9;

/// Splits a line into fields at commas and whitespace.
fn fields(line: &str) -> Vec<&str> {
    line.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect()
}

/// Parses finite numbers; the reason on error.
fn numbers(line: &str, expected: usize, what: &str) -> Result<Vec<f64>, String> {
    let f = fields(line);
    if f.len() != expected {
        return Err(format!(
            "expected {expected} numbers ({what}), found {}",
            f.len()
        ));
    }
    f.iter()
        .map(|s| match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(v) => Err(format!("{v} is not finite")),
            Err(_) => Err(format!("`{s}` is not a number")),
        })
        .collect()
}

fn read_text(path: &Path) -> Result<String, LoadError> {
    std::fs::read_to_string(path).map_err(|e| LoadError::io(path, &e))
}

/// Non-empty lines with their 1-based numbers.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
}

/// Reads `K_cam{i}.csv`: `(fx, fy, skew, cx, cy)`.
pub fn read_intrinsics(path: &Path) -> Result<[f64; 5], LoadError> {
    intrinsics_from_str(&read_text(path)?, path)
}

/// Parses the text of a `K_cam{i}.csv` (see [`read_intrinsics`]); `path` is quoted in errors.
pub fn intrinsics_from_str(text: &str, path: &Path) -> Result<[f64; 5], LoadError> {
    let mut rows = Vec::new();
    for (n, line) in content_lines(text) {
        if rows.len() == 3 {
            return Err(LoadError::invalid(
                path,
                format!("line {n}"),
                "extra line after the 3×3 matrix",
            ));
        }
        let row = numbers(line, 3, "a row of K")
            .map_err(|r| LoadError::invalid(path, format!("line {n}"), r))?;
        rows.push((n, row));
    }
    if rows.len() != 3 {
        return Err(LoadError::invalid(
            path,
            "end of file",
            format!("{} rows, K needs 3", rows.len()),
        ));
    }
    for (r, c, expected) in [(1, 0, 0.0), (2, 0, 0.0), (2, 1, 0.0), (2, 2, 1.0)] {
        let (n, row) = &rows[r];
        if !((row[c] - expected).abs() <= K_FIXED_ENTRY_TOLERANCE) {
            return Err(LoadError::invalid(
                path,
                format!("line {n}"),
                format!("K[{r}][{c}] = {} must be {expected}", row[c]),
            ));
        }
    }
    let (k0, k1) = (&rows[0].1, &rows[1].1);
    Ok([k0[0], k1[1], k0[1], k0[2], k1[2]])
}

/// Reads `x_lb3_c{i}.csv`: `head_from_camera`.
pub fn read_extrinsics(path: &Path) -> Result<IsometryMatrix3<f64>, LoadError> {
    extrinsics_from_str(&read_text(path)?, path)
}

/// Parses the text of an `x_lb3_c{i}.csv` (see [`read_extrinsics`]); `path` is quoted in errors.
pub fn extrinsics_from_str(text: &str, path: &Path) -> Result<IsometryMatrix3<f64>, LoadError> {
    let mut lines = content_lines(text);
    let Some((n, line)) = lines.next() else {
        return Err(LoadError::invalid(
            path,
            "line 1",
            "empty file (expected x,y,z,roll,pitch,yaw)",
        ));
    };
    if let Some((extra, _)) = lines.next() {
        return Err(LoadError::invalid(
            path,
            format!("line {extra}"),
            "extra line (expected one line x,y,z,roll,pitch,yaw)",
        ));
    }
    let v = numbers(line, 6, "x,y,z,roll,pitch,yaw")
        .map_err(|r| LoadError::invalid(path, format!("line {n}"), r))?;
    let rotation =
        Rotation3::from_euler_angles(v[3].to_radians(), v[4].to_radians(), v[5].to_radians());
    Ok(IsometryMatrix3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        rotation,
    ))
}

/// The `(W, H)` named by a table file name `…_{W}X{H}.txt`, if any.
pub fn size_from_name(path: &Path) -> Option<(u32, u32)> {
    let name = path.file_stem()?.to_str()?;
    let last = name.rsplit('_').next()?;
    let (w, h) = last.split_once(['X', 'x'])?;
    Some((w.parse().ok()?, h.parse().ok()?))
}

/// Reads a distortion table (see the module docs). `expected`: the size the table must
/// have (from its file name), if known.
///
/// # Errors
/// [`LoadError::Invalid`] naming the file and the line: a header without two integers or
/// contradicting `expected`, a line without four numbers, a non-finite value, a pixel
/// outside the table or given twice, or missing entries.
pub fn read_table(path: &Path, expected: Option<(u32, u32)>) -> Result<DistortionTable, LoadError> {
    table_from_str(&read_text(path)?, path, expected)
}

/// Parses the text of a distortion table (see [`read_table`]); `path` is quoted in errors.
///
/// # Errors
/// As [`read_table`].
pub fn table_from_str(
    text: &str,
    path: &Path,
    expected: Option<(u32, u32)>,
) -> Result<DistortionTable, LoadError> {
    let mut lines = content_lines(text);
    let Some((hn, header)) = lines.next() else {
        return Err(LoadError::invalid(
            path,
            "line 1",
            "empty file (expected a header line `W H`)",
        ));
    };
    let ints: Vec<u32> = header
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .filter_map(|s| s.parse().ok())
        .collect();
    let &[width, height] = ints.as_slice() else {
        return Err(LoadError::invalid(
            path,
            format!("line {hn}"),
            format!("header `{header}` does not name a width and a height"),
        ));
    };
    if let Some((w, h)) = expected
        && (w, h) != (width, height)
    {
        return Err(LoadError::invalid(
            path,
            format!("line {hn}"),
            format!("the header's size {width}×{height} contradicts the expected size {w}×{h}"),
        ));
    }
    if width < 2 || height < 2 {
        return Err(LoadError::invalid(
            path,
            format!("line {hn}"),
            format!("size {width}×{height} is smaller than 2×2"),
        ));
    }
    if width > crate::calibration::MAX_IMAGE_SIDE_PX
        || height > crate::calibration::MAX_IMAGE_SIDE_PX
    {
        return Err(LoadError::invalid(
            path,
            format!("line {hn}"),
            format!(
                "size {width}×{height} exceeds the largest image side {} px",
                crate::calibration::MAX_IMAGE_SIDE_PX
            ),
        ));
    }
    let count = width as usize * height as usize;
    // Every pixel needs its own line: refuse a header the text cannot fill before
    // allocating the table (a 3-line file must not claim 4·10⁹ pixels).
    let available = content_lines(text).count().saturating_sub(1);
    if available < count {
        return Err(LoadError::invalid(
            path,
            "end of file",
            format!(
                "at most {available} entries after the header (line {hn}), but a {width}×{height} table needs {count}"
            ),
        ));
    }
    let mut positions = vec![[f64::NAN; 2]; count];
    let mut seen = vec![false; count];
    let mut entries = 0usize;
    for (n, line) in lines {
        let at = || format!("line {n}");
        let v = numbers(line, 4, "r c r' c'").map_err(|r| LoadError::invalid(path, at(), r))?;
        let (r, c) = (v[0], v[1]);
        let integral = |x: f64, n: u32| x.fract() == 0.0 && x >= 0.0 && x < f64::from(n);
        if !integral(r, height) || !integral(c, width) {
            return Err(LoadError::invalid(
                path,
                at(),
                format!("pixel (r {r}, c {c}) is not a pixel of the {width}×{height} table"),
            ));
        }
        let k = r as usize * width as usize + c as usize;
        if seen[k] {
            return Err(LoadError::invalid(
                path,
                at(),
                format!("pixel (r {r}, c {c}) given twice"),
            ));
        }
        seen[k] = true;
        entries += 1;
        positions[k] = [v[3], v[2]];
    }
    if entries != count {
        let k = seen.iter().position(|s| !s).unwrap_or(0);
        return Err(LoadError::invalid(
            path,
            "end of file",
            format!(
                "{entries} entries, but a {width}×{height} table needs {count} (first missing: \
                 r {}, c {})",
                k / width as usize,
                k % width as usize
            ),
        ));
    }
    Ok(DistortionTable {
        width,
        height,
        positions,
    })
}

/// The text of a table file (header `W H`, then `r c r' c'` in row-major order; numbers in
/// the shortest form that reads back exactly).
pub fn table_text(table: &DistortionTable) -> String {
    use std::fmt::Write;
    let mut out = format!("{} {}\n", table.width, table.height);
    for (k, p) in table.positions.iter().enumerate() {
        let (r, c) = (k / table.width as usize, k % table.width as usize);
        let _ = writeln!(out, "{r} {c} {} {}", p[1], p[0]);
    }
    out
}

/// The unique file `{prefix}{W}X{H}.txt` in `dir`.
fn find_table(dir: &Path, prefix: &str) -> Result<PathBuf, LoadError> {
    let entries = std::fs::read_dir(dir).map_err(|e| LoadError::io(dir, &e))?;
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix) && n.ends_with(".txt"))
        })
        .collect();
    found.sort();
    match found.len() {
        1 => Ok(found.remove(0)),
        0 => Err(LoadError::invalid(
            dir,
            format!("{prefix}{{W}}X{{H}}.txt"),
            "missing table file",
        )),
        _ => Err(LoadError::invalid(
            dir,
            format!("{prefix}{{W}}X{{H}}.txt"),
            format!("{} table files match", found.len()),
        )),
    }
}

/// Reads an NCLT-style directory into a rig (rig frame = Ladybug head frame).
///
/// # Errors
/// [`LoadError`] naming the file (or the directory for a missing file), line and reason.
pub fn read(dir: &Path) -> Result<Rig, LoadError> {
    if !dir.is_dir() {
        return Err(LoadError::invalid(dir, "path", "not a directory"));
    }
    let mut cameras = Vec::new();
    for i in 0.. {
        let k_path = dir.join(format!("K_cam{i}.csv"));
        if !k_path.exists() {
            if i == 0 {
                return Err(LoadError::invalid(dir, "K_cam0.csv", "missing file"));
            }
            break;
        }
        let [fx, fy, skew, cx, cy] = read_intrinsics(&k_path)?;
        let x_path = dir.join(format!("x_lb3_c{i}.csv"));
        if !x_path.exists() {
            return Err(LoadError::invalid(
                dir,
                format!("x_lb3_c{i}.csv"),
                "missing file",
            ));
        }
        let rig_from_camera = read_extrinsics(&x_path)?;
        let read_one = |prefix: String| -> Result<(DistortionTable, PathBuf), LoadError> {
            let path = find_table(dir, &prefix)?;
            let size = size_from_name(&path).ok_or_else(|| {
                LoadError::invalid(&path, "file name", "does not end in _{W}X{H}.txt")
            })?;
            Ok((read_table(&path, Some(size))?, path))
        };
        let (d2u, _) = read_one(format!("D2U_Cam{i}_"))?;
        let (u2d, u2d_path) = read_one(format!("U2D_Cam{i}_"))?;
        if (u2d.width, u2d.height) != (d2u.width, d2u.height) {
            return Err(LoadError::invalid(
                &u2d_path,
                "line 1",
                format!(
                    "size {}×{} contradicts the D2U table's {}×{}",
                    u2d.width, u2d.height, d2u.width, d2u.height
                ),
            ));
        }
        let params = TabulatedPinholeParams {
            width: Some(d2u.width),
            height: Some(d2u.height),
            fx,
            fy,
            skew,
            cx,
            cy,
            raw_to_undistorted: Some(d2u),
            undistorted_to_raw: Some(u2d),
        };
        let model = TabulatedPinhole::new(params)
            .map_err(|e| LoadError::invalid(dir, format!("camera {i}"), e.to_string()))?;
        cameras.push(RigCamera {
            model: Camera::TabulatedPinhole(model),
            rig_from_camera,
        });
    }
    let rig =
        Rig::new(cameras).map_err(|e| LoadError::invalid(dir, "x_lb3_c*.csv", e.to_string()))?;
    read_masks(rig, dir)
}

/// Adds the optional per-camera masks `mask_cam{i}.png` of a calibration directory (black
/// = the pixel never sees the world; in the raw image's orientation and size).
///
/// # Errors
/// [`LoadError::Invalid`] naming the mask file when it cannot be read or its size is not
/// the camera's.
pub fn read_masks(mut rig: Rig, dir: &Path) -> Result<Rig, LoadError> {
    for i in 0..rig.len() {
        let path = dir.join(format!("mask_cam{i}.png"));
        if !path.is_file() {
            continue;
        }
        let mask = crate::calibration::CameraMask::read_png(&path)
            .map_err(|e| LoadError::invalid(&path, "mask", e.to_string()))?;
        rig = rig
            .with_mask(i, mask)
            .map_err(|e| LoadError::invalid(&path, "mask", e.to_string()))?;
    }
    Ok(rig)
}

/// Writes a rig of tabulated cameras as an NCLT-style directory (created if needed; files
/// written atomically). Used to generate the shipped example and test fixtures.
///
/// # Errors
/// [`LoadError::Invalid`] when a camera is not a [`TabulatedPinhole`] with tables;
/// [`LoadError::Io`] when a file cannot be written.
pub fn write(rig: &Rig, dir: &Path) -> Result<(), LoadError> {
    std::fs::create_dir_all(dir).map_err(|e| LoadError::io(dir, &e))?;
    for (i, c) in rig.cameras().iter().enumerate() {
        let Camera::TabulatedPinhole(m) = &c.model else {
            return Err(LoadError::invalid(
                dir,
                format!("camera {i}"),
                format!("a {} camera has no NCLT form", c.model.model_name()),
            ));
        };
        let p = m.params();
        let (Some(d2u), Some(u2d)) = (&p.raw_to_undistorted, &p.undistorted_to_raw) else {
            return Err(LoadError::invalid(
                dir,
                format!("camera {i}"),
                "the NCLT form needs distortion tables",
            ));
        };
        let k = format!("{},{},{}\n0,{},{}\n0,0,1\n", p.fx, p.skew, p.cx, p.fy, p.cy);
        write_atomic(&dir.join(format!("K_cam{i}.csv")), k.as_bytes())?;
        let (roll, pitch, yaw) = c.rig_from_camera.rotation.euler_angles();
        let t: Vector3<f64> = c.rig_from_camera.translation.vector;
        let x = format!(
            "{},{},{},{},{},{}\n",
            t.x,
            t.y,
            t.z,
            roll.to_degrees(),
            pitch.to_degrees(),
            yaw.to_degrees()
        );
        write_atomic(&dir.join(format!("x_lb3_c{i}.csv")), x.as_bytes())?;
        let (w, h) = (d2u.width, d2u.height);
        write_atomic(
            &dir.join(format!("D2U_Cam{i}_{w}X{h}.txt")),
            table_text(d2u).as_bytes(),
        )?;
        write_atomic(
            &dir.join(format!("U2D_Cam{i}_{w}X{h}.txt")),
            table_text(u2d).as_bytes(),
        )?;
    }
    Ok(())
}
