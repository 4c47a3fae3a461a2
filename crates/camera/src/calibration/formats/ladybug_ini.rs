//! Ladybug SDK calibration parameters dumped as INI (as Ladybug5 owners export them).
//!
//! `key = value` lines (`key=value` too); blank lines, `;`/`#` comments and `[section]`
//! headers are ignored. For every camera `N = 0 … 5` exactly these keys:
//!
//! | key | unit | meaning |
//! |---|---|---|
//! | `cameraN_rotX`, `cameraN_rotY`, `cameraN_rotZ` | radians | `head_from_camera` rotation `Rz(rotZ)·Ry(rotY)·Rx(rotX)` |
//! | `cameraN_transX`, `cameraN_transY`, `cameraN_transZ` | metres | camera centre in the head frame |
//! | `cameraN_FocalLen` | pixels | focal length of the rectified image |
//! | `cameraN_CameraCenterX`, `cameraN_CameraCenterY` | pixels | principal point (column, row) of the rectified image |
//!
//! and optionally `image_width`, `image_height` (both or neither). Any other key, a
//! repeated key, a missing key or a value that is not a finite number is an error naming
//! the key and line.
//!
//! # Frames
//! The Ladybug projection is `col = f·x/z + cx`, `row = f·y/z + cy` in the camera frame, so
//! the Ladybug camera frame **is** vgps's camera frame (x along increasing columns = right,
//! y along increasing rows = down, z forward along the optical axis). The head frame has
//! camera 0 looking along +x and the top camera along +z; being right-handed, its +y is to
//! the left of camera 0: it is vgps's rig frame (x forward, y left, z up) unchanged. So
//! `rig_from_camera = head_from_camera`.
//!
//! Each camera is a [`TabulatedPinhole`] without tables (`fx = fy = FocalLen`), bounded by
//! the image size when one is known, unbounded otherwise.

use super::LoadError;
use crate::calibration::{Camera, Rig, RigCamera, TabulatedPinhole, TabulatedPinholeParams};
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// Number of cameras of a Ladybug head (five side cameras and one top camera).
pub const LADYBUG_CAMERAS: usize = 6;

/// The per-camera key suffixes, in file order.
pub const CAMERA_KEYS: [&str; 9] = [
    "rotX",
    "rotY",
    "rotZ",
    "transX",
    "transY",
    "transZ",
    "FocalLen",
    "CameraCenterX",
    "CameraCenterY",
];

/// `head_from_camera` from the Ladybug angles: `Rz(rot_z)·Ry(rot_y)·Rx(rot_x)` (radians).
pub fn head_from_camera_rotation(rot_x: f64, rot_y: f64, rot_z: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), rot_z)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), rot_y)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), rot_x)
}

/// Parses the text of an INI export; `path` is quoted in errors. `image_size` is used when
/// the file names none, and must agree with it otherwise.
///
/// # Errors
/// [`LoadError::Invalid`] naming the key (and line) and the reason.
pub fn parse(text: &str, path: &Path, image_size: Option<(u32, u32)>) -> Result<Rig, LoadError> {
    let mut values: HashMap<String, (usize, f64)> = HashMap::new();
    for (index, raw) in text.lines().enumerate() {
        let n = index + 1;
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with(';') || line.starts_with('#') {
            continue;
        }
        if line.starts_with('[') && line.ends_with(']') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(LoadError::invalid(
                path,
                format!("line {n}"),
                format!("`{line}` is not `key = value`"),
            ));
        };
        let (key, value) = (key.trim(), value.trim());
        let at = || format!("line {n}, key {key}");
        if !is_known_key(key) {
            return Err(LoadError::invalid(path, at(), "unknown key"));
        }
        let v: f64 = value
            .parse()
            .map_err(|_| LoadError::invalid(path, at(), format!("`{value}` is not a number")))?;
        if !v.is_finite() {
            return Err(LoadError::invalid(path, at(), format!("{v} is not finite")));
        }
        if let Some((first, _)) = values.insert(key.to_string(), (n, v)) {
            return Err(LoadError::invalid(
                path,
                at(),
                format!("repeated key (first on line {first})"),
            ));
        }
    }
    let get = |key: &str| -> Result<f64, LoadError> {
        values
            .get(key)
            .map(|&(_, v)| v)
            .ok_or_else(|| LoadError::invalid(path, format!("key {key}"), "missing key"))
    };
    let size_in_file = match (values.get("image_width"), values.get("image_height")) {
        (None, None) => None,
        (Some(&(n, w)), Some(&(_, h))) => {
            let max = f64::from(crate::calibration::MAX_IMAGE_SIDE_PX);
            let whole = |v: f64| v.fract() == 0.0 && v >= 1.0 && v <= max;
            if !whole(w) || !whole(h) {
                return Err(LoadError::invalid(
                    path,
                    format!("line {n}, key image_width"),
                    format!("image size {w}×{h} is not two positive integers ≤ {max}"),
                ));
            }
            Some((w as u32, h as u32))
        }
        (Some(_), None) => {
            return Err(LoadError::invalid(
                path,
                "key image_height",
                "missing key (image_width is given)",
            ));
        }
        (None, Some(_)) => {
            return Err(LoadError::invalid(
                path,
                "key image_width",
                "missing key (image_height is given)",
            ));
        }
    };
    let size = match (size_in_file, image_size) {
        (Some(a), Some(b)) if a != b => {
            return Err(LoadError::invalid(
                path,
                "key image_width",
                format!(
                    "the file's image size {}×{} contradicts the given {}×{}",
                    a.0, a.1, b.0, b.1
                ),
            ));
        }
        (a, b) => a.or(b),
    };
    let mut cameras = Vec::with_capacity(LADYBUG_CAMERAS);
    for i in 0..LADYBUG_CAMERAS {
        let key = |suffix: &str| format!("camera{i}_{suffix}");
        let v: Vec<f64> = CAMERA_KEYS
            .iter()
            .map(|s| get(&key(s)))
            .collect::<Result<_, _>>()?;
        let focal = v[6];
        let params = TabulatedPinholeParams {
            width: size.map(|s| s.0),
            height: size.map(|s| s.1),
            fx: focal,
            fy: focal,
            skew: 0.0,
            cx: v[7],
            cy: v[8],
            raw_to_undistorted: None,
            undistorted_to_raw: None,
        };
        let model = TabulatedPinhole::new(params).map_err(|e| {
            let line = values.get(&key("FocalLen")).map_or(0, |&(n, _)| n);
            LoadError::invalid(
                path,
                format!("line {line}, key {}", key("FocalLen")),
                e.to_string(),
            )
        })?;
        cameras.push(RigCamera {
            model: Camera::TabulatedPinhole(model),
            rig_from_camera: IsometryMatrix3::from_parts(
                Translation3::new(v[3], v[4], v[5]),
                head_from_camera_rotation(v[0], v[1], v[2]),
            ),
        });
    }
    Rig::new(cameras).map_err(|e| LoadError::invalid(path, "rotation", e.to_string()))
}

fn is_known_key(key: &str) -> bool {
    if key == "image_width" || key == "image_height" {
        return true;
    }
    let Some(rest) = key.strip_prefix("camera") else {
        return false;
    };
    let Some((n, suffix)) = rest.split_once('_') else {
        return false;
    };
    n.parse::<usize>()
        .is_ok_and(|k| k < LADYBUG_CAMERAS && k.to_string() == n)
        && CAMERA_KEYS.contains(&suffix)
}

/// Reads an INI export (see [`parse`]).
///
/// # Errors
/// As [`parse`], and [`LoadError::Io`].
pub fn read(path: &Path, image_size: Option<(u32, u32)>) -> Result<Rig, LoadError> {
    let text = std::fs::read_to_string(path).map_err(|e| LoadError::io(path, &e))?;
    parse(&text, path, image_size)
}

/// The INI text of a Ladybug head: per camera `(rot_x, rot_y, rot_z, trans (m), focal,
/// cx, cy)`, and an optional image size. Used to generate the shipped example.
pub fn to_text(cameras: &[[f64; 9]], image_size: Option<(u32, u32)>) -> String {
    use std::fmt::Write;
    let mut out = String::from("[Ladybug calibration]\n");
    if let Some((w, h)) = image_size {
        let _ = writeln!(out, "image_width = {w}\nimage_height = {h}");
    }
    for (i, c) in cameras.iter().enumerate() {
        for (suffix, value) in CAMERA_KEYS.iter().zip(c) {
            let _ = writeln!(out, "camera{i}_{suffix} = {value}");
        }
    }
    out
}
