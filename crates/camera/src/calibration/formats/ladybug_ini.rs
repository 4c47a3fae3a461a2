//! Ladybug SDK calibration parameters dumped as INI (as Ladybug5 owners export them).
//!
//! `key = value` lines (`key=value` too), or the second spelling found in circulation:
//! dotted keys with the value after whitespace (`camera0.rotX -2.151942`; a dot in a key
//! reads as `_`). Blank lines, `;` comments and `[section]` headers are ignored; `#` lines
//! are comments too, except that an informational key in one (`#camera_model  Ladybug5
//! LD5-U3-51S5C-44`) is kept when no key line gives it. For every camera `N = 0 … 5`
//! exactly these keys:
//!
//! | key | unit | meaning |
//! |---|---|---|
//! | `cameraN_rotX`, `cameraN_rotY`, `cameraN_rotZ` | radians | `head_from_camera` rotation `Rz(rotZ)·Ry(rotY)·Rx(rotX)` |
//! | `cameraN_transX`, `cameraN_transY`, `cameraN_transZ` | metres | camera centre in the head frame |
//! | `cameraN_FocalLen` | pixels | focal length of the rectified image |
//! | `cameraN_CameraCenterX`, `cameraN_CameraCenterY` | pixels | principal point (column, row) of the rectified image |
//!
//! and optionally:
//! - `image_width`, `image_height` (both or neither);
//! - the informational keys `camera_model`, `camera_serialBase`, `camera_serialHead`
//!   (text, kept in [`IniInfo`] and shown by `vgps calib show`);
//! - the global rotation `rotation_dRx`, `rotation_dRy`, `rotation_dRz` (radians, all three
//!   or none): the SDK projects a head-frame point `P` by first rotating it by the
//!   **inverse** of `G = Rz(dRz)·Ry(dRy)·Rx(dRx)`, then applying the per-camera extrinsics
//!   and the rectified pinhole. So `rig_from_camera = G · head_from_camera` (rotation
//!   `G·R`, translation `G·t`). The direction is the one issue 23 reports checked against
//!   1,020 projections by the real SDK's `ladybugXYZtoRC()` (median 0.93 px, up to 4.8 px
//!   off without the rotation, 0.005 px with it); those SDK numbers are not in this
//!   repository, so vgps's tests check the documented relation, not the SDK.
//!
//! A repeated key, a missing required key or a value that is not a finite number is an
//! error naming the key and line; a key that is none of these is a warning
//! ([`IniInfo::warnings`]), never fatal.
//!
//! # Image size
//! Real dumps name no image size. It is, in order: the file's `image_width`/`image_height`;
//! the size given by the caller (`--image-size`); the sensor size of a known
//! `camera_model` ([`KNOWN_SENSORS`]: Ladybug5+ `LD5P…` 2464 × 2048, Ladybug5 `LD5-…`
//! 2448 × 2048, Ladybug3 `LD3…` 1616 × 1232) in the orientation that puts every principal
//! point near the image centre ([`size_from_camera_model`]; not taken when both or
//! neither orientation fit). This assumes the SDK's rectified image has the sensor's full
//! resolution (its default); a rig rectified at another size must be given `--image-size`.
//! Otherwise the cameras are unbounded (every pixel valid).
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

/// The informational content of an INI export beyond the geometry.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IniInfo {
    /// `camera_model` (e.g. `Ladybug5 LD5-U3-51S5C-44`), from a key or a `#` comment line.
    pub camera_model: Option<String>,
    /// `camera_serialBase`.
    pub serial_base: Option<String>,
    /// `camera_serialHead`.
    pub serial_head: Option<String>,
    /// `rotation_dRx`, `rotation_dRy`, `rotation_dRz` (radians), when given.
    pub global_rotation: Option<[f64; 3]>,
    /// The image size used and where it comes from (`file`, `given`, `camera model …`).
    pub image_size: Option<((u32, u32), String)>,
    /// Lines accepted with a warning (unknown keys).
    pub warnings: Vec<String>,
}

/// The informational keys: kept, never required.
pub const INFO_KEYS: [&str; 3] = ["camera_model", "camera_serialBase", "camera_serialHead"];

/// The global rotation keys (radians).
pub const GLOBAL_ROTATION_KEYS: [&str; 3] = ["rotation_dRx", "rotation_dRy", "rotation_dRz"];

/// Sensor sizes `(long side, short side)` in pixels of the Ladybug models whose name
/// identifies them: `(name fragment, long, short)`, matched in order.
pub const KNOWN_SENSORS: [(&str, u32, u32); 6] = [
    ("LD5P", 2464, 2048),
    ("Ladybug5+", 2464, 2048),
    ("LD5-", 2448, 2048),
    ("Ladybug5", 2448, 2048),
    ("LD3", 1616, 1232),
    ("Ladybug3", 1616, 1232),
];

/// The rectified image size of a named camera model when it is unambiguous: the sensor's
/// full resolution, in the orientation (`long × short` or `short × long`) in which every
/// camera's principal point lies within 5 % of the image size from the image centre
/// (`None` when the name is not known, or neither or both orientations fit).
pub fn size_from_camera_model(model: &str, principal_points: &[(f64, f64)]) -> Option<(u32, u32)> {
    let &(_, long, short) = KNOWN_SENSORS.iter().find(|(k, _, _)| model.contains(k))?;
    let fits = |w: u32, h: u32| {
        let (w, h) = (f64::from(w), f64::from(h));
        !principal_points.is_empty()
            && principal_points.iter().all(|&(cx, cy)| {
                (cx - (w - 1.0) / 2.0).abs() <= 0.05 * w && (cy - (h - 1.0) / 2.0).abs() <= 0.05 * h
            })
    };
    match (fits(long, short), fits(short, long)) {
        (true, false) => Some((long, short)),
        (false, true) => Some((short, long)),
        _ => None,
    }
}

/// Parses the text of an INI export; `path` is quoted in errors. `image_size` is used when
/// the file names none, and must agree with it otherwise.
///
/// # Errors
/// [`LoadError::Invalid`] naming the key (and line) and the reason.
pub fn parse(text: &str, path: &Path, image_size: Option<(u32, u32)>) -> Result<Rig, LoadError> {
    parse_with_info(text, path, image_size).map(|(rig, _)| rig)
}

/// Splits a line into `(key, value)`: `key = value`, or the dotted spelling `key value`
/// (`camera0.rotX -2.151942`); dots in the key become underscores.
fn split_line(line: &str) -> Option<(String, &str)> {
    let (key, value) = match line.split_once('=') {
        Some((k, v)) => (k.trim(), v.trim()),
        None => {
            let (k, v) = line.split_once(char::is_whitespace)?;
            (k.trim(), v.trim())
        }
    };
    Some((key.replace('.', "_"), value))
}

/// As [`parse`], with the informational keys, the global rotation, the image size's
/// source and the warnings.
///
/// Long (about 200 lines) for a reason: one pass reads the keys, then the file-level
/// checks (size, global rotation) and the six cameras follow in the order of the format's
/// description, each error naming its key and line.
///
/// # Errors
/// As [`parse`].
pub fn parse_with_info(
    text: &str,
    path: &Path,
    image_size: Option<(u32, u32)>,
) -> Result<(Rig, IniInfo), LoadError> {
    let mut info = IniInfo::default();
    let mut values: HashMap<String, (usize, f64)> = HashMap::new();
    let mut strings: HashMap<String, (usize, String)> = HashMap::new();
    let mut from_comments: HashMap<String, String> = HashMap::new();
    for (index, raw) in text.lines().enumerate() {
        let n = index + 1;
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with(';') {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            // `#camera_model  Ladybug5 LD5-U3-51S5C-44`: an informational key in a comment.
            if let Some((key, value)) = split_line(comment.trim())
                && INFO_KEYS.contains(&key.as_str())
                && !value.is_empty()
            {
                from_comments
                    .entry(key)
                    .or_insert_with(|| value.to_string());
            }
            continue;
        }
        if line.starts_with('[') && line.ends_with(']') {
            continue;
        }
        let Some((key, value)) = split_line(line) else {
            return Err(LoadError::invalid(
                path,
                format!("line {n}"),
                format!("`{line}` is not `key = value` nor `key value`"),
            ));
        };
        let key = key.as_str();
        let at = || format!("line {n}, key {key}");
        if INFO_KEYS.contains(&key) {
            if let Some((first, _)) = strings.insert(key.to_string(), (n, value.to_string())) {
                return Err(LoadError::invalid(
                    path,
                    at(),
                    format!("repeated key (first on line {first})"),
                ));
            }
            continue;
        }
        if !is_known_key(key) && !GLOBAL_ROTATION_KEYS.contains(&key) {
            info.warnings
                .push(format!("line {n}: unknown key `{key}` ignored"));
            continue;
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
    let info_value = |key: &str| {
        strings
            .get(key)
            .map(|(_, v)| v.clone())
            .or_else(|| from_comments.get(key).cloned())
    };
    info.camera_model = info_value("camera_model");
    info.serial_base = info_value("camera_serialBase");
    info.serial_head = info_value("camera_serialHead");
    let get = |key: &str| -> Result<f64, LoadError> {
        values
            .get(key)
            .map(|&(_, v)| v)
            .ok_or_else(|| LoadError::invalid(path, format!("key {key}"), "missing key"))
    };
    info.global_rotation = match GLOBAL_ROTATION_KEYS.map(|k| values.get(k).map(|&(_, v)| v)) {
        [None, None, None] => None,
        [Some(x), Some(y), Some(z)] => Some([x, y, z]),
        given => {
            let (k, _) = GLOBAL_ROTATION_KEYS
                .iter()
                .zip(given)
                .find(|(_, v)| v.is_none())
                .unwrap_or((&GLOBAL_ROTATION_KEYS[0], None));
            return Err(LoadError::invalid(
                path,
                format!("key {k}"),
                "missing key (the other rotation_dR… keys are given)",
            ));
        }
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
        (Some(a), _) => Some((a, "file".to_string())),
        (None, Some(b)) => Some((b, "given".to_string())),
        (None, None) => {
            let centres: Vec<(f64, f64)> = (0..LADYBUG_CAMERAS)
                .filter_map(|i| {
                    let cx = values.get(&format!("camera{i}_CameraCenterX"))?.1;
                    let cy = values.get(&format!("camera{i}_CameraCenterY"))?.1;
                    Some((cx, cy))
                })
                .collect();
            info.camera_model.as_deref().and_then(|m| {
                size_from_camera_model(m, &centres).map(|s| (s, format!("camera model {m}")))
            })
        }
    };
    info.image_size = size.clone();
    let size = size.map(|(s, _)| s);
    let global = info
        .global_rotation
        .map(|[x, y, z]| head_from_camera_rotation(x, y, z));
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
            rig_from_camera: {
                let local = IsometryMatrix3::from_parts(
                    Translation3::new(v[3], v[4], v[5]),
                    head_from_camera_rotation(v[0], v[1], v[2]),
                );
                // head point → G⁻¹ → per-camera extrinsics: rig_from_camera = G · local.
                match global {
                    Some(g) => IsometryMatrix3::from_parts(Translation3::identity(), g) * local,
                    None => local,
                }
            },
        });
    }
    let rig = Rig::new(cameras).map_err(|e| LoadError::invalid(path, "rotation", e.to_string()))?;
    Ok((rig, info))
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
