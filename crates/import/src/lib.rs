//! # vgps-import — logs of other tools into drive folders
//!
//! - [`ros_decode`]: decoding of the CDR of the few ROS 2 messages a drive needs
//!   (`CompressedImage`, `Image`, `NavSatFix`, `Imu`).
//! - [`mcap_read`]: a tolerant, streaming MCAP reader (rosbag2's storage) over the `mcap`
//!   crate.
//! - [`mcap_import`]: a rosbag2 MCAP recording (images per camera, NavSatFix, Imu) into a
//!   drive folder.
//! - [`nclt`]: an NCLT session (Ladybug3 images, `gps.csv`, ground truth) into a drive.
//! - [`folders`]: per-camera folders of timestamped images into a drive.
//! - [`drive_out`]: what they share: frames assembled by stamp, the drive writer, the report.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod drive_out;
pub mod folders;
pub mod mcap_import;
pub mod mcap_read;
pub mod nclt;
pub mod ros_decode;
