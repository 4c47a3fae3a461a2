//! ROS 2 messages of a replay, written as an MCAP file that `ros2 bag play` and Foxglove
//! open: per visual fix one `sensor_msgs/NavSatFix` on [`TOPIC_FIX`], one
//! `geometry_msgs/PoseWithCovarianceStamped` on [`TOPIC_POSE`] and one `sensor_msgs/Imu`
//! (orientation only) on [`TOPIC_ATTITUDE`], stamped with the frame time.
//!
//! The file follows rosbag2's MCAP layout: profile `ros2`, schemas in `ros2msg` (with
//! their dependencies), messages in `cdr` (encoded here, [`cdr`]), no chunk compression.
//! Frames and conventions (REP-103 ENU `map` frame at the drive origin, REP-105 names,
//! covariance orders) are in `docs/ros2.md`, with the design of a live node that publishes
//! the same messages.
//!
//! # Example
//! ```
//! use vgps_geometry::geo::Geodetic;
//! use vgps_replay::report::{DriveInfo, FrameOutcome};
//! use vgps_replay::ros_out::mcap_bytes;
//! let drive = DriveInfo { name: "empty".into(), origin: Geodetic::try_new(48.0, 11.0, 500.0)? };
//! let records: Vec<FrameOutcome> = Vec::new();
//! let bytes = mcap_bytes(&drive, &records)?;
//! assert!(bytes.starts_with(b"\x89MCAP0\r\n"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod cdr;
pub mod msgs;

use crate::report::{DriveInfo, FrameOutcome, VisualFix};
use nalgebra::Matrix3;
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;
use vgps_geometry::geo::{LocalFrame, rotate_covariance};

/// Topic of the `NavSatFix` messages.
pub const TOPIC_FIX: &str = "/vgps/fix";
/// Topic of the `PoseWithCovarianceStamped` messages.
pub const TOPIC_POSE: &str = "/vgps/pose";
/// Topic of the `Imu` (orientation) messages.
pub const TOPIC_ATTITUDE: &str = "/vgps/attitude";
/// The local ENU frame of the poses (REP-103/105 `map`), origin at the drive's origin.
pub const MAP_FRAME: &str = "map";
/// The frame of the rig (x forward, y left, z up), the `child` of the pose and the frame of
/// `NavSatFix` and `Imu`.
pub const RIG_FRAME: &str = "vgps_rig";

/// Errors of the ROS 2 outputs.
#[derive(Debug, thiserror::Error)]
pub enum RosOutError {
    /// The MCAP writer failed.
    #[error("cannot encode the MCAP file: {0}")]
    Mcap(String),
    /// The file could not be written.
    #[error("cannot write {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's message.
        reason: String,
    },
}

impl From<mcap::McapError> for RosOutError {
    fn from(e: mcap::McapError) -> Self {
        Self::Mcap(e.to_string())
    }
}

/// The three messages of one visual fix, CDR-encoded: `(NavSatFix, Pose, Imu)`. `None`
/// when the time does not fit a ROS stamp.
///
/// - `NavSatFix`: WGS84 position, ENU position covariance at the fix (m²);
/// - `PoseWithCovarianceStamped` in [`MAP_FRAME`]: ENU position from `map`'s origin (m),
///   orientation `map_from_rig`, covariance of `[δE, δN, δU, δθE, δθN, δθU]`;
/// - `Imu` in [`RIG_FRAME`]: orientation `enu_from_rig` (ENU at the fix, REP-145) and its
///   covariance (rad²).
pub fn fix_messages(
    map: &LocalFrame,
    time_s: f64,
    fix: &VisualFix,
) -> Option<(Vec<u8>, Vec<u8>, Vec<u8>)> {
    let stamp = msgs::stamp(time_s)?;
    // The covariance is in map's ENU axes; NavSatFix and Imu use ENU at the fix.
    let map_from_here = map.enu_here_from_enu_at(&fix.geodetic);
    let here_from_map = map_from_here.inverse();
    let block =
        |r: usize| -> Matrix3<f64> { fix.pose_covariance.fixed_view::<3, 3>(r, r).into_owned() };
    let position_cov = rotate_covariance(&here_from_map, &block(0));
    let attitude_cov = rotate_covariance(&here_from_map, &block(3));
    let g = &fix.geodetic;
    let nav = msgs::nav_sat_fix(
        stamp,
        RIG_FRAME,
        g.lat_deg,
        g.lon_deg,
        g.alt_m,
        &position_cov,
    );
    let map_from_rig =
        nalgebra::UnitQuaternion::from_rotation_matrix(&map_from_here) * fix.enu_from_rig;
    let pose = msgs::pose_with_covariance_stamped(
        stamp,
        MAP_FRAME,
        &map.to_enu(g),
        &map_from_rig,
        &fix.pose_covariance,
    );
    let imu = msgs::imu_orientation(stamp, RIG_FRAME, &fix.enu_from_rig, &attitude_cov);
    Some((nav, pose, imu))
}

/// The MCAP file of a replay's records (see the module docs); frames without a visual fix
/// have no message.
///
/// # Errors
/// [`RosOutError::Mcap`] if the MCAP writer fails (it writes to memory).
pub fn mcap_bytes(drive: &DriveInfo, records: &[FrameOutcome]) -> Result<Vec<u8>, RosOutError> {
    let options = mcap::WriteOptions::new()
        .profile("ros2")
        .library(concat!("vgps ", env!("CARGO_PKG_VERSION")))
        .compression(None);
    let mut writer = options.create(Cursor::new(Vec::new()))?;
    let metadata = BTreeMap::new();
    let mut channel = |name: &str, topic: &str| -> Result<u16, RosOutError> {
        let text = msgs::schema_text(name).unwrap_or_default();
        let schema = writer.add_schema(name, "ros2msg", text.as_bytes())?;
        Ok(writer.add_channel(schema, topic, "cdr", &metadata)?)
    };
    let fix_channel = channel(msgs::NAV_SAT_FIX, TOPIC_FIX)?;
    let pose_channel = channel(msgs::POSE_WITH_COVARIANCE_STAMPED, TOPIC_POSE)?;
    let imu_channel = channel(msgs::IMU, TOPIC_ATTITUDE)?;
    let map = LocalFrame::new(drive.origin);
    let mut sequence = 0u32;
    for r in records {
        let Some(fix) = &r.visual else { continue };
        let Some((nav, pose, imu)) = fix_messages(&map, r.time_s, fix) else {
            continue;
        };
        let Some((sec, nanosec)) = msgs::stamp(r.time_s) else {
            continue;
        };
        let log_time =
            u64::try_from(i64::from(sec) * 1_000_000_000 + i64::from(nanosec)).unwrap_or(0);
        for (channel_id, data) in [(fix_channel, nav), (pose_channel, pose), (imu_channel, imu)] {
            writer.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id,
                    sequence,
                    log_time,
                    publish_time: log_time,
                },
                &data,
            )?;
        }
        sequence = sequence.wrapping_add(1);
    }
    writer.finish()?;
    Ok(writer.into_inner().into_inner())
}

/// Writes [`mcap_bytes`] to `path` atomically.
///
/// # Errors
/// [`RosOutError::Io`] naming the file, or [`RosOutError::Mcap`].
pub fn write_mcap(
    path: &Path,
    drive: &DriveInfo,
    records: &[FrameOutcome],
) -> Result<(), RosOutError> {
    let bytes = mcap_bytes(drive, records)?;
    vgps_io::write_atomic(path, &bytes).map_err(|e| RosOutError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests;
