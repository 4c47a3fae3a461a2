//! # vgps-replay — logged drives in, replay outputs out
//!
//! - [`drive`]: drive logs (manifest, frames, detections, NMEA/GPX/NCLT satellite GPS,
//!   truth): reader and writers.
//! - [`frame_images`]: a drive frame's images decoded and run through the lamp detector.
//! - [`report`]: the outputs of `vgps replay` (statistics, tables, track files, plots, the
//!   HTML report, NMEA).
//! - [`live`]: the live NMEA stream for gpsd (a TCP server) and the pacing of a replay.
//! - [`ros_out`]: ROS 2 messages (`NavSatFix`, `PoseWithCovarianceStamped`, `Imu`) in CDR,
//!   written as an MCAP file.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod drive;
pub mod frame_images;
pub mod live;
pub mod report;
pub mod ros_out;
