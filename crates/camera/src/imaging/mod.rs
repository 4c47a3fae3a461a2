//! Night images of street lamps: PNG decoding and encoding with limits, and the lamp detector.
//!
//! Two parts of the image pipeline behind `vgps detect` and `vgps replay --from-images` (the
//! night renderer of simulated drives is `vgps_sim::render`):
//! - [`decode`]: PNG decoding with size limits and a dimension check against the
//!   calibration ([`decode_png`], [`read_png`], [`check_dimensions`]), and the fast PNG
//!   encoding of rendered frames ([`encode_png`]).
//! - [`formats`]: PNG, JPEG, TIFF and BMP decoding to Rec. 601 luminance within the same
//!   limits ([`decode_image`], [`read_image`]).
//! - [`detect`]: the lamp detector — adaptive threshold, run-length connected components
//!   (8-connectivity), background-subtracted intensity-weighted sub-pixel centroids, area and
//!   shape limits, per-camera masks ([`LampDetector`], [`Mask`]).
//! - [`street`]: the lamp detector for real night streets — bright cores against their
//!   local background, one detection per bloomed lamp, windows, reflections, vehicle lights
//!   and lens ghosts labelled ([`StreetLampDetector`]).
//! - [`vertex`]: building corners by day, as the intersection of sub-pixel edges
//!   ([`VertexDetector`]).
//!
//! # Conventions
//! Pixels `(u, v)` = (column, row), integer coordinates are pixel centres, `(0, 0)` is the
//! centre of the top-left pixel (as everywhere in vgps). Intensities are 8-bit digital numbers
//! (DN). Lights are given in the camera frame (x right, y down, z forward), metres.
//!
//! # Example
//! ```
//! use nalgebra::Vector3;
//! use vgps_camera::imaging::LampDetector;
//! use vgps_sim::render::{LightSource, RenderOptions, Renderer};
//! use vgps_camera::synthetic::calibration_files::ladybug2_lens;
//! let camera = vgps_camera::calibration::Camera::from(ladybug2_lens());
//! // A lamp 30 m ahead of the camera, slightly right and up.
//! let lamp = LightSource { point_in_camera: Vector3::new(3.0, -2.0, 30.0), radius_m: 0.15, intensity: 1.0 };
//! let renderer = Renderer::new(RenderOptions::default());
//! let frame = renderer.render(&camera, &[lamp], 7);
//! let truth = frame.spots[0];
//! let found = LampDetector::default().detect(&frame.image, None)?;
//! assert_eq!(found.lamps.len(), 1);
//! let error = ((found.lamps[0].u - truth.u).powi(2) + (found.lamps[0].v - truth.v).powi(2)).sqrt();
//! assert!(error < 0.2, "centroid error {error} px");
//! # Ok::<(), vgps_camera::imaging::ImagingError>(())
//! ```

// `!(x < limit)` is used on purpose: it rejects NaN along with out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod corner_response;
pub mod decode;
pub mod detect;
mod detection;
pub mod formats;
pub mod street;
pub mod vertex;

pub use decode::{DecodeLimits, check_dimensions, decode_png, encode_png, read_png};
pub use detect::{
    CentroidWeight, Detections, DetectorConfig, LampDetection, LampDetector, Mask, Threshold,
};
pub use detection::PixelDetection;
pub use formats::{ImageFormat, decode_image, decode_image_named, read_image};
pub use street::{LampClass, StreetDetection, StreetDetections, StreetLampDetector};
pub use vertex::{Rejection, VertexCandidate, VertexConfig, VertexDetection, VertexDetector};

use std::path::PathBuf;
use thiserror::Error;

/// Errors of the imaging module. Every file error names the file.
#[derive(Debug, Error)]
pub enum ImagingError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The bytes are not a PNG (bad signature or missing header).
    #[error("{path}: not a PNG file")]
    NotPng {
        /// The file (or `<memory>`).
        path: PathBuf,
    },
    /// The bytes are none of the formats [`decode_image`] reads (PNG, JPEG, TIFF, BMP).
    #[error("{path}: not a PNG, JPEG, TIFF or BMP file")]
    NotAnImage {
        /// The file (or `<memory>`).
        path: PathBuf,
    },
    /// A JPEG, TIFF or BMP file that is truncated or corrupt.
    #[error("{path}: cannot decode {format}: {message}")]
    Corrupt {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// The format (`JPEG`, `TIFF`, `BMP`).
        format: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A valid file of a kind the decoder does not read (a CMYK or 12-bit JPEG, a TIFF
    /// compression the codec lacks).
    #[error("{path}: unsupported {format}: {message}")]
    Unsupported {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// The format (`JPEG`, `TIFF`, `BMP`).
        format: &'static str,
        /// What is not supported.
        message: String,
    },
    /// The PNG header declares an image larger than the limits allow.
    #[error(
        "{path}: image of {width}×{height} pixels exceeds the limits \
         ({max_width}×{max_height}, {max_bytes} bytes)"
    )]
    TooLarge {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// Largest accepted width.
        max_width: u32,
        /// Largest accepted height.
        max_height: u32,
        /// Largest accepted decoded size in bytes.
        max_bytes: u64,
    },
    /// The PNG data is corrupt or truncated, or uses an unsupported format.
    #[error("{path}: cannot decode PNG: {message}")]
    Decode {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// The image does not have the dimensions of the camera's calibration.
    #[error(
        "{path}: image is {width}×{height} pixels, the calibration expects \
         {expected_width}×{expected_height}"
    )]
    WrongDimensions {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Width of the calibration.
        expected_width: u32,
        /// Height of the calibration.
        expected_height: u32,
    },
    /// PNG encoding failed.
    #[error("cannot encode PNG: {message}")]
    Encode {
        /// The encoder's message.
        message: String,
    },
    /// A detection mask whose size differs from the image's.
    #[error("mask is {mask_width}×{mask_height} pixels, the image {width}×{height}")]
    MaskDimensions {
        /// Mask width.
        mask_width: u32,
        /// Mask height.
        mask_height: u32,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
    },
    /// The image has more bright runs than the detector's bound (a flooded or overexposed
    /// frame): detection is abandoned rather than doing unbounded work.
    #[error("more than {max_runs} bright runs above threshold {threshold} DN: frame flooded")]
    TooManyRuns {
        /// The configured bound ([`DetectorConfig::max_runs`]).
        max_runs: usize,
        /// The threshold used (DN).
        threshold: u8,
    },
}
