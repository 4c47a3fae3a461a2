//! # vgps-camera — from pixels to bearings
//!
//! - [`calibration`]: camera models (pinhole, fisheye, panorama, LUT, NCLT tables), the
//!   camera rig, and the calibration file formats.
//! - [`imaging`]: decoding images with limits, and the lamp detector (pixels of lit lamps).
//! - `synthetic` (feature `synthetic`): synthetic calibrations for tests and benchmarks.
//!
//! Conventions are those of [`vgps_geometry`]: camera frame x right, y down, z forward;
//! pixels `(u, v)` = (column, row), integers at pixel centres, `(0, 0)` the top-left pixel.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod calibration;
pub mod imaging;
#[cfg(any(test, feature = "synthetic"))]
pub mod synthetic;
