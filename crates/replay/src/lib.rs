//! # vgps-replay — logged drives in, replay outputs out
//!
//! - [`drive`]: drive logs (manifest, frames, detections, NMEA/GPX/NCLT satellite GPS,
//!   truth): reader and writers.
//! - [`frame_images`]: a drive frame's images decoded and run through the lamp detector.
//! - [`report`]: the outputs of `vgps replay` (statistics, tables, track files, plots, the
//!   HTML report, NMEA).
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod drive;
pub mod frame_images;
pub mod report;
