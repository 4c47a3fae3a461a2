//! Calibration files: the native JSON format `vgps` writes, Ladybug SDK INI exports and
//! NCLT-style Ladybug3 directories, all loaded into a [`Rig`].
//!
//! - [`native`]: `vgps`'s own JSON (a format name and version, then the cameras with their
//!   serde-tagged model parameters and `rig_from_camera`); LUT cameras and distortion tables
//!   live in side files referenced by a path relative to the JSON.
//! - [`ladybug_ini`]: Ladybug SDK parameters dumped as `key = value` lines
//!   (`camera0_rotX`, …, `camera5_CameraCenterY`), the rectified images of a Ladybug5.
//! - [`nclt`]: a directory in the University of Michigan North Campus (NCLT) Ladybug3
//!   layout: `K_cam{i}.csv`, `x_lb3_c{i}.csv`, `U2D_Cam{i}_{W}X{H}.txt`,
//!   `D2U_Cam{i}_{W}X{H}.txt`.
//! - [`detect`]: tells which of the three a path holds.
//!
//! Every error names the file, the line or key, and the reason ([`LoadError`]). The formats,
//! with examples and the frame conventions, are documented in `docs/calibration-formats.md`.
//!
//! # Example
//! ```
//! use nalgebra::{Vector2, Vector3};
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../calibration/ladybug2.json");
//! let rig = vgps_camera::calibration::load(path.as_ref(), None, None)?;
//! assert_eq!(rig.len(), 6);
//! // The centre of camera 0 looks forward, along rig +x.
//! let ray = rig.ray(0, &Vector2::new(511.5, 383.5))?;
//! assert!((ray.direction - Vector3::x()).norm() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod detect;
pub mod ladybug_conf;
pub mod ladybug_ini;
pub mod native;
pub mod nclt;

use super::{Camera, CameraModel, Lut, Rig, RigCamera};
use std::fmt;
use std::path::Path;
use std::str::FromStr;
use thiserror::Error;

/// A calibration file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// `vgps`'s native JSON ([`native`]); name `native`.
    Native,
    /// A Ladybug SDK INI export ([`ladybug_ini`]); name `ladybug-ini`.
    LadybugIni,
    /// An NCLT-style Ladybug3 directory ([`nclt`]); name `nclt`.
    Nclt,
    /// The Ladybug SDK's own `.conf` file ([`ladybug_conf`]), raw cameras; name
    /// `ladybug-conf`.
    LadybugConf,
}

impl Format {
    /// Every format, in the order of their names in messages.
    pub const ALL: [Format; 4] = [
        Format::Native,
        Format::LadybugIni,
        Format::Nclt,
        Format::LadybugConf,
    ];

    /// The format's name on the command line (`native`, `ladybug-ini`, `nclt`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Native => "native",
            Format::LadybugIni => "ladybug-ini",
            Format::Nclt => "nclt",
            Format::LadybugConf => "ladybug-conf",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Format::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                format!("unknown format `{s}` (expected native, ladybug-ini, nclt or ladybug-conf)")
            })
    }
}

/// Errors of reading and writing calibration files; each names the file.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LoadError {
    /// The file cannot be read or written.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        reason: String,
    },
    /// The content is invalid.
    #[error("{path}: {location}: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// Where in the file: `line 12`, `key camera3_rotX`, `cameras[2].rig_from_camera`, …
        location: String,
        /// What is wrong.
        reason: String,
    },
    /// The format cannot be detected.
    #[error("{path}: cannot tell the calibration format ({reason}); give it with --format")]
    UnknownFormat {
        /// The file or directory.
        path: String,
        /// What was looked at.
        reason: String,
    },
}

impl LoadError {
    /// An [`LoadError::Invalid`] error.
    pub fn invalid(path: &Path, location: impl Into<String>, reason: impl Into<String>) -> Self {
        LoadError::Invalid {
            path: path.display().to_string(),
            location: location.into(),
            reason: reason.into(),
        }
    }

    /// An [`LoadError::Io`] error.
    pub fn io(path: &Path, error: &std::io::Error) -> Self {
        LoadError::Io {
            path: path.display().to_string(),
            reason: error.to_string(),
        }
    }
}

/// Loads a calibration into a [`Rig`] (rig frame: x forward, y left, z up).
///
/// `format` is detected from the file when `None` ([`detect::detect`]). `image_size`
/// `(width, height)` in pixels gives the image size of a Ladybug INI export that names none;
/// for the other formats (and an INI that names one) it must agree with the file's sizes.
///
/// # Errors
/// [`LoadError`] naming the file, the line or key and the reason.
///
/// # Example
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../calibration/equirectangular_2048x1024.json");
/// let rig = vgps_camera::calibration::load(path.as_ref(), None, None)?;
/// assert_eq!(rig.len(), 1);
/// # Ok::<(), vgps_camera::calibration::LoadError>(())
/// ```
pub fn load(
    path: &Path,
    format: Option<Format>,
    image_size: Option<(u32, u32)>,
) -> Result<Rig, LoadError> {
    let format = match format {
        Some(f) => f,
        None => detect::detect(path)?,
    };
    let rig = match format {
        Format::Native => native::read(path)?,
        Format::LadybugIni => return ladybug_ini::read(path, image_size),
        Format::Nclt => nclt::read(path)?,
        Format::LadybugConf => ladybug_conf::read(path)?,
    };
    if let Some((w, h)) = image_size {
        for (i, c) in rig.cameras().iter().enumerate() {
            let size = c.model.image_size();
            if size != (w, h) {
                return Err(LoadError::invalid(
                    path,
                    format!("camera {i}"),
                    format!(
                        "image size {}×{} contradicts the given image size {w}×{h}",
                        size.0, size.1
                    ),
                ));
            }
        }
    }
    Ok(rig)
}

/// Writes a rig in the native format: the JSON at `path` and, next to it, one side file per
/// LUT camera (`<stem>.cam<i>.lut`) and two per tabulated camera
/// (`<stem>.cam<i>.d2u.txt`, `<stem>.cam<i>.u2d.txt`). Every file is written atomically
/// (a temporary file in the same directory, then a rename).
///
/// # Errors
/// [`LoadError::Io`] naming the file that cannot be written.
pub fn save_native(rig: &Rig, path: &Path) -> Result<(), LoadError> {
    native::write(rig, path)
}

/// The rig with every camera replaced by a [`Lut`] of grid step `step` pixels sampled from
/// it (same placements and masks).
///
/// # Errors
/// [`LoadError::Invalid`] naming `path` (the calibration it comes from) and the camera when
/// a camera has no image size or no bearing at some grid node.
pub fn to_lut_rig(rig: &Rig, step: u32, path: &Path) -> Result<Rig, LoadError> {
    let mut cameras = Vec::with_capacity(rig.len());
    for (i, c) in rig.cameras().iter().enumerate() {
        let lut = Lut::from_model(&c.model, step)
            .map_err(|e| LoadError::invalid(path, format!("camera {i}"), e.to_string()))?;
        cameras.push(RigCamera {
            model: Camera::Lut(lut),
            rig_from_camera: c.rig_from_camera,
        });
    }
    let mut lut_rig =
        Rig::new(cameras).map_err(|e| LoadError::invalid(path, "rig", e.to_string()))?;
    // A LUT has its source's image size: the masks carry over.
    for i in 0..rig.len() {
        if let Some(mask) = rig.mask(i) {
            lut_rig = lut_rig
                .with_mask(i, mask.clone())
                .map_err(|e| LoadError::invalid(path, format!("camera {i}"), e.to_string()))?;
        }
    }
    Ok(lut_rig)
}

/// Writes `bytes` to `path` atomically: a temporary file in the same directory, then a
/// rename over `path`.
///
/// # Errors
/// [`LoadError::Io`] naming `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), LoadError> {
    vgps_io::write_atomic(path, bytes).map_err(|e| LoadError::io(path, &e))
}
