//! The native calibration format: JSON written and read by `vgps` (serde).
//!
//! ```json
//! {
//!   "format": "vgps-calibration",
//!   "version": 1,
//!   "cameras": [
//!     {
//!       "camera": {"model": "kannala_brandt", "width": 1024, "height": 768,
//!                  "fx": 596.8, "fy": 596.8, "cx": 511.5, "cy": 383.5,
//!                  "k1": -0.2, "k2": 0.1, "k3": 0.0, "k4": 0.0},
//!       "rig_from_camera": {"rotation": [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
//!                           "translation": [0.04, 0, 0]}
//!     }
//!   ]
//! }
//! ```
//! - `rotation` is the 3×3 matrix of `rig_from_camera`, **row-major** (`rotation[i][j]` =
//!   `R_ij`; its columns are the camera's x, y, z axes in the rig frame); it must be
//!   orthonormal with determinant +1 within [`ROTATION_TOLERANCE`].
//!   `translation` is the camera centre in the rig frame, metres.
//! - `camera` is tagged by `model`: `pinhole`, `kannala_brandt`, `equirectangular` (the
//!   fields of their parameter structs), `lut` (`{"model": "lut", "file": "x.lut"}`: a LUT
//!   file in the binary format of [`Lut`]) or `tabulated_pinhole` (the fields of
//!   [`TabulatedPinholeParams`] with the two tables given as file names
//!   `raw_to_undistorted` / `undistorted_to_raw` in the NCLT text layout of
//!   [`nclt`]). Side-file paths are relative to the JSON file's directory.
//! - `mask` (optional, per camera): a PNG side file of the camera's image size whose black
//!   pixels never see the world (a [`CameraMask`](crate::calibration::CameraMask)).
//! - `level_within_deg` (optional, top level): the rig is level within this many degrees
//!   (its z axis within that angle of the local vertical: a vehicle rig). `vgps locate` and
//!   `vgps replay` then search with this vertical when no `--up-tolerance-deg` is given
//!   ([`Rig::level_within_rad`]). A number in (0, 90].
//! - Unknown fields are errors. Numbers are written in the shortest form that reads back
//!   to the same `f64`, so write → read is exact.

use super::{LoadError, nclt, write_atomic};
use crate::calibration::{
    Camera, DistortionTable, Equirectangular, EquirectangularParams, KannalaBrandt,
    KannalaBrandtParams, Lut, Pinhole, PinholeParams, ROTATION_TOLERANCE, Rig, RigCamera,
    TabulatedPinhole, TabulatedPinholeParams,
};
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The value of the `format` field.
pub const NATIVE_FORMAT_NAME: &str = "vgps-calibration";

/// The format version this library reads and writes.
pub const NATIVE_FORMAT_VERSION: u32 = 1;

/// A native calibration file (serde form).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NativeFile {
    /// Always [`NATIVE_FORMAT_NAME`].
    pub format: String,
    /// Always [`NATIVE_FORMAT_VERSION`].
    pub version: u32,
    /// The cameras, in rig order (camera index = position).
    pub cameras: Vec<NativeCamera>,
    /// The rig is level within this many degrees (its z axis within that angle of the local
    /// vertical), when declared.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level_within_deg: Option<f64>,
}

/// One camera of a native file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NativeCamera {
    /// The model and its parameters.
    pub camera: NativeModel,
    /// The camera's placement in the rig frame.
    pub rig_from_camera: NativePlacement,
    /// The camera's mask (pixels that never see the world): a PNG side file of the image's
    /// size, black = masked, relative to the JSON's directory; absent = no mask.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
}

/// `rig_from_camera`: `point_in_rig = rotation · point_in_camera + translation`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NativePlacement {
    /// Rotation matrix, row-major (`rotation[i][j]` = `R_ij`).
    pub rotation: [[f64; 3]; 3],
    /// Camera centre in the rig frame, metres.
    pub translation: [f64; 3],
}

/// A camera model as stored in the native file (tag `model`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum NativeModel {
    /// [`Pinhole`] parameters.
    Pinhole(PinholeParams),
    /// [`KannalaBrandt`] parameters.
    KannalaBrandt(KannalaBrandtParams),
    /// [`Equirectangular`] parameters.
    Equirectangular(EquirectangularParams),
    /// A [`Lut`] in a side file.
    Lut(LutReference),
    /// A [`TabulatedPinhole`] with its tables in side files.
    TabulatedPinhole(TabulatedReference),
    /// A [`SplinePinhole`](crate::calibration::SplinePinhole) (a Ladybug `.conf` camera),
    /// its warps inline.
    SplinePinhole(Box<crate::calibration::SplinePinholeParams>),
}

/// A LUT camera: the LUT file, relative to the JSON's directory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LutReference {
    /// Path of the binary LUT file.
    pub file: String,
}

/// A [`TabulatedPinhole`] whose tables are side files (NCLT text layout), relative to the
/// JSON's directory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TabulatedReference {
    /// Raw image width (pixels); absent for an unbounded image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Raw image height (pixels); absent for an unbounded image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// Focal length along u (pixels).
    pub fx: f64,
    /// Focal length along v (pixels).
    pub fy: f64,
    /// Skew (pixels).
    #[serde(default)]
    pub skew: f64,
    /// Principal point column.
    pub cx: f64,
    /// Principal point row.
    pub cy: f64,
    /// The raw → undistorted (`D2U`) table file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw_to_undistorted: Option<String>,
    /// The undistorted → raw (`U2D`) table file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub undistorted_to_raw: Option<String>,
}

fn base_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Parses a native file's text; `path` is quoted in errors and locates the side files.
///
/// # Errors
/// [`LoadError::Invalid`] with the line and column of a JSON/serde error (unknown model,
/// unknown or missing field, wrong type), or the camera and field of an invalid value.
pub fn parse(text: &str, path: &Path) -> Result<Rig, LoadError> {
    let file: NativeFile = serde_json::from_str(text)
        .map_err(|e| LoadError::invalid(path, error_location(text, &e), e.to_string()))?;
    if file.format != NATIVE_FORMAT_NAME {
        return Err(LoadError::invalid(
            path,
            "key format",
            format!(
                "`{}` is not `{NATIVE_FORMAT_NAME}`",
                file.format.escape_debug()
            ),
        ));
    }
    if file.version != NATIVE_FORMAT_VERSION {
        return Err(LoadError::invalid(
            path,
            "key version",
            format!(
                "unsupported version {} (this library reads version {NATIVE_FORMAT_VERSION})",
                file.version
            ),
        ));
    }
    if file.cameras.is_empty() {
        return Err(LoadError::invalid(path, "key cameras", "no camera"));
    }
    if let Some(deg) = file.level_within_deg
        && !(deg.is_finite() && deg > 0.0 && deg <= 90.0)
    {
        return Err(LoadError::invalid(
            path,
            "key level_within_deg",
            format!("{deg} is not an angle in (0, 90] degrees"),
        ));
    }
    let dir = base_dir(path);
    let mut cameras = Vec::with_capacity(file.cameras.len());
    for (i, c) in file.cameras.iter().enumerate() {
        let at = |field: &str| format!("cameras[{i}].{field}");
        let model = to_camera(&c.camera, &dir)
            .map_err(|(field, reason)| LoadError::invalid(path, at(&field), reason))?;
        let rig_from_camera = to_isometry(&c.rig_from_camera)
            .map_err(|(field, reason)| LoadError::invalid(path, at(&field), reason))?;
        cameras.push(RigCamera {
            model,
            rig_from_camera,
        });
    }
    let mut rig =
        Rig::new(cameras).map_err(|e| LoadError::invalid(path, "cameras", e.to_string()))?;
    rig = rig
        .with_level_within_rad(file.level_within_deg.map(f64::to_radians))
        .map_err(|e| LoadError::invalid(path, "key level_within_deg", e.to_string()))?;
    for (i, c) in file.cameras.iter().enumerate() {
        if let Some(name) = &c.mask {
            let field = format!("cameras[{i}].mask");
            let mask = crate::calibration::CameraMask::read_png(&dir.join(name))
                .map_err(|e| LoadError::invalid(path, &field, e.to_string()))?;
            rig = rig
                .with_mask(i, mask)
                .map_err(|e| LoadError::invalid(path, &field, e.to_string()))?;
        }
    }
    Ok(rig)
}

/// The line of a serde error. serde reports an unknown model or field of a tagged camera at
/// the end of its object: the line that names the offending value is reported instead.
fn error_location(text: &str, e: &serde_json::Error) -> String {
    let message = e.to_string();
    for prefix in ["unknown variant `", "unknown field `"] {
        if let Some(rest) = message.split(prefix).nth(1)
            && let Some(name) = rest.split('`').next()
        {
            let quoted = format!("\"{name}\"");
            // The last occurrence before the reported line (the object the error is in).
            let found = text
                .lines()
                .take(e.line())
                .enumerate()
                .filter(|(_, l)| l.contains(&quoted))
                .last();
            if let Some((n, _)) = found {
                return format!("line {}", n + 1);
            }
        }
    }
    format!("line {} column {}", e.line(), e.column())
}

/// Reads a native file (and its side files).
///
/// # Errors
/// As [`parse`], and [`LoadError::Io`] when a file cannot be read.
pub fn read(path: &Path) -> Result<Rig, LoadError> {
    let text = std::fs::read_to_string(path).map_err(|e| LoadError::io(path, &e))?;
    parse(&text, path)
}

/// Checks a placement and converts it; `(field, reason)` on error.
fn to_isometry(p: &NativePlacement) -> Result<IsometryMatrix3<f64>, (String, String)> {
    let r = &p.rotation;
    if r.iter().flatten().any(|v| !v.is_finite()) {
        return Err((
            "rig_from_camera.rotation".into(),
            format!("not finite: {r:?}"),
        ));
    }
    let m = Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    );
    let deviation = (m.transpose() * m - Matrix3::identity())
        .abs()
        .max()
        .max((m.determinant() - 1.0).abs());
    if !(deviation <= ROTATION_TOLERANCE) {
        return Err((
            "rig_from_camera.rotation".into(),
            format!(
                "not a rotation: max |RᵀR − I| or |det R − 1| = {deviation:e} > {ROTATION_TOLERANCE:e}"
            ),
        ));
    }
    let t = Vector3::from(p.translation);
    if !vgps_geometry::geometry::is_finite(&t) {
        return Err((
            "rig_from_camera.translation".into(),
            format!("not finite: {:?}", p.translation),
        ));
    }
    Ok(IsometryMatrix3::from_parts(
        Translation3::from(t),
        Rotation3::from_matrix_unchecked(m),
    ))
}

/// Builds a camera model; `(field, reason)` on error.
fn to_camera(model: &NativeModel, dir: &Path) -> Result<Camera, (String, String)> {
    let field = |e: crate::calibration::CalibrationError| ("camera".to_string(), e.to_string());
    Ok(match model {
        NativeModel::Pinhole(p) => Camera::Pinhole(Pinhole::new(*p).map_err(field)?),
        NativeModel::KannalaBrandt(p) => {
            Camera::KannalaBrandt(KannalaBrandt::new(*p).map_err(field)?)
        }
        NativeModel::Equirectangular(p) => {
            Camera::Equirectangular(Equirectangular::new(*p).map_err(field)?)
        }
        NativeModel::Lut(r) => {
            let lut = Lut::read(&dir.join(&r.file))
                .map_err(|e| ("camera.file".to_string(), e.to_string()))?;
            Camera::Lut(lut)
        }
        NativeModel::TabulatedPinhole(r) => {
            let table = |name: &str, file: &Option<String>| -> Result<_, (String, String)> {
                file.as_ref()
                    .map(|f| {
                        nclt::read_table(&dir.join(f), None)
                            .map_err(|e| (format!("camera.{name}"), e.to_string()))
                    })
                    .transpose()
            };
            let params = TabulatedPinholeParams {
                width: r.width,
                height: r.height,
                fx: r.fx,
                fy: r.fy,
                skew: r.skew,
                cx: r.cx,
                cy: r.cy,
                raw_to_undistorted: table("raw_to_undistorted", &r.raw_to_undistorted)?,
                undistorted_to_raw: table("undistorted_to_raw", &r.undistorted_to_raw)?,
            };
            Camera::TabulatedPinhole(TabulatedPinhole::new(params).map_err(field)?)
        }
        NativeModel::SplinePinhole(p) => Camera::SplinePinhole(
            crate::calibration::SplinePinhole::new((**p).clone()).map_err(field)?,
        ),
    })
}

/// The native file content of a rig and the side files to write with it
/// (`(file name, bytes)`), the side files named `<stem>.cam<i>.<kind>`.
pub fn to_native(rig: &Rig, stem: &str) -> (NativeFile, Vec<(String, Vec<u8>)>) {
    let mut side = Vec::new();
    let cameras = rig
        .cameras()
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let camera = match &c.model {
                Camera::Pinhole(m) => NativeModel::Pinhole(*m.params()),
                Camera::KannalaBrandt(m) => NativeModel::KannalaBrandt(*m.params()),
                Camera::Equirectangular(m) => NativeModel::Equirectangular(*m.params()),
                Camera::Lut(m) => {
                    let file = format!("{stem}.cam{i}.lut");
                    side.push((file.clone(), m.to_bytes()));
                    NativeModel::Lut(LutReference { file })
                }
                Camera::TabulatedPinhole(m) => {
                    let p = m.params();
                    let mut table = |kind: &str, t: &Option<DistortionTable>| {
                        t.as_ref().map(|t| {
                            let file = format!("{stem}.cam{i}.{kind}.txt");
                            side.push((file.clone(), nclt::table_text(t).into_bytes()));
                            file
                        })
                    };
                    NativeModel::TabulatedPinhole(TabulatedReference {
                        width: p.width,
                        height: p.height,
                        fx: p.fx,
                        fy: p.fy,
                        skew: p.skew,
                        cx: p.cx,
                        cy: p.cy,
                        raw_to_undistorted: table("d2u", &p.raw_to_undistorted),
                        undistorted_to_raw: table("u2d", &p.undistorted_to_raw),
                    })
                }
                Camera::SplinePinhole(m) => {
                    NativeModel::SplinePinhole(Box::new(m.params().clone()))
                }
            };
            let mask = rig.mask(i).map(|mask| {
                let file = format!("{stem}.cam{i}.mask.png");
                side.push((file.clone(), mask.to_png_bytes()));
                file
            });
            let m = c.rig_from_camera.rotation.matrix();
            let t = c.rig_from_camera.translation.vector;
            NativeCamera {
                camera,
                rig_from_camera: NativePlacement {
                    // `+ 0.0` writes −0 as 0 (the same value).
                    rotation: [
                        [m[(0, 0)] + 0.0, m[(0, 1)] + 0.0, m[(0, 2)] + 0.0],
                        [m[(1, 0)] + 0.0, m[(1, 1)] + 0.0, m[(1, 2)] + 0.0],
                        [m[(2, 0)] + 0.0, m[(2, 1)] + 0.0, m[(2, 2)] + 0.0],
                    ],
                    translation: [t.x + 0.0, t.y + 0.0, t.z + 0.0],
                },
                mask,
            }
        })
        .collect();
    (
        NativeFile {
            format: NATIVE_FORMAT_NAME.into(),
            version: NATIVE_FORMAT_VERSION,
            cameras,
            level_within_deg: rig.level_within_rad().map(f64::to_degrees),
        },
        side,
    )
}

/// Writes a rig as a native file at `path` plus its side files next to it, each atomically
/// (side files first, so the JSON never references a missing file).
///
/// # Errors
/// [`LoadError::Io`] naming the file that cannot be written.
pub fn write(rig: &Rig, path: &Path) -> Result<(), LoadError> {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "calibration".into());
    let (file, side) = to_native(rig, &stem);
    let dir = base_dir(path);
    for (name, bytes) in &side {
        write_atomic(&dir.join(name), bytes)?;
    }
    let pretty = serde_json::to_string_pretty(&file).map_err(|e| LoadError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut text = compact_number_arrays(&pretty);
    text.push('\n');
    write_atomic(path, text.as_bytes())
}

/// Puts every JSON array that holds only numbers on one line (`[0.0, 1.0, 0.0]`).
fn compact_number_arrays(pretty: &str) -> String {
    let mut out = String::with_capacity(pretty.len());
    let mut rest = pretty;
    while let Some(open) = rest.find('[') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let close = after.find(']');
        let inner = close.map(|c| &after[..c]);
        match inner {
            Some(inner)
                if !inner.trim().is_empty()
                    && inner.chars().all(|ch| {
                        ch.is_ascii_digit() || ",.-+eE".contains(ch) || ch.is_whitespace()
                    }) =>
            {
                let items: Vec<&str> = inner.split(',').map(str::trim).collect();
                out.push('[');
                out.push_str(&items.join(", "));
                out.push(']');
                rest = &after[inner.len() + 1..];
            }
            _ => {
                out.push('[');
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-panorama native file, with `extra` inserted after the version.
    fn text(extra: &str) -> String {
        format!(
            r#"{{
  "format": "vgps-calibration",
  "version": 1,{extra}
  "cameras": [
    {{
      "camera": {{"model": "equirectangular", "width": 64, "height": 32}},
      "rig_from_camera": {{"rotation": [[0, 0, 1], [-1, 0, 0], [0, -1, 0]],
                          "translation": [0, 0, 0]}}
    }}
  ]
}}"#
        )
    }

    #[test]
    fn a_declared_level_is_read_written_and_checked() {
        let path = Path::new("rig.json");
        let plain = parse(&text(""), path).unwrap();
        assert_eq!(plain.level_within_rad(), None);
        let level = parse(&text("\n  \"level_within_deg\": 4,"), path).unwrap();
        let t = level.level_within_rad().unwrap();
        assert!((t - 4.0_f64.to_radians()).abs() < 1e-15, "{t}");
        assert_eq!(level.cameras(), plain.cameras());
        // Written and read back: the same rig (and nothing written without a declaration).
        let dir = tempfile::tempdir().unwrap();
        for (rig, declared) in [(&level, true), (&plain, false)] {
            let out = dir.path().join("out.json");
            write(rig, &out).unwrap();
            let written = std::fs::read_to_string(&out).unwrap();
            assert_eq!(written.contains("level_within_deg"), declared, "{written}");
            let back = read(&out).unwrap();
            assert_eq!(back.cameras(), rig.cameras());
            let (a, b) = (back.level_within_rad(), rig.level_within_rad());
            assert_eq!(a.is_some(), b.is_some());
            assert!((a.unwrap_or(0.0) - b.unwrap_or(0.0)).abs() < 1e-15);
        }
        // Bad values: errors naming the file and the field.
        for bad in ["-3", "0", "90.5", "1e308"] {
            let e = parse(&text(&format!("\n  \"level_within_deg\": {bad},")), path)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("rig.json") && e.contains("level_within_deg"),
                "{e}"
            );
        }
        let e = parse(&text("\n  \"level_within_deg\": \"four\","), path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rig.json") && e.contains("line 4"), "{e}");
        // The library's own check.
        assert!(plain.clone().with_level_within_rad(Some(f64::NAN)).is_err());
        assert!(plain.with_level_within_rad(Some(0.07)).is_ok());
    }
}
