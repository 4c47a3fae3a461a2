//! The ROS 2 messages vgps writes, their `ros2msg` schemas (each with its dependencies, as
//! rosbag2 stores them) and their CDR encoding.
//!
//! Field by field, the messages and the frames are described in `docs/ros2.md`.

use super::cdr::CdrWriter;
use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3};

/// The separator between a schema's definitions (rosbag2 / MCAP `ros2msg` convention).
const SEPARATOR: &str =
    "================================================================================\n";

const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const TIME: &str = "int32 sec\nuint32 nanosec\n";
const QUATERNION: &str = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
const VECTOR3: &str = "float64 x\nfloat64 y\nfloat64 z\n";
const POINT: &str = "float64 x\nfloat64 y\nfloat64 z\n";
const POSE: &str = "Point position\nQuaternion orientation\n";
const POSE_WITH_COVARIANCE: &str = "Pose pose\nfloat64[36] covariance\n";
const NAV_SAT_STATUS: &str = "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\n\
int8 STATUS_GBAS_FIX=2\nint8 status\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\n\
uint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\nuint16 service\n";

/// `sensor_msgs/msg/NavSatFix`'s schema name.
pub const NAV_SAT_FIX: &str = "sensor_msgs/msg/NavSatFix";
/// `geometry_msgs/msg/PoseWithCovarianceStamped`'s schema name.
pub const POSE_WITH_COVARIANCE_STAMPED: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";
/// `sensor_msgs/msg/Imu`'s schema name.
pub const IMU: &str = "sensor_msgs/msg/Imu";

/// `NavSatStatus.status` of a fix.
pub const STATUS_FIX: i8 = 0;
/// `NavSatStatus.service` of a visual fix: no satellite system (none of the GPS, GLONASS,
/// COMPASS, GALILEO bits) — what tells a consumer this fix is not from satellites.
pub const SERVICE_NONE: u16 = 0;
/// `NavSatFix.position_covariance_type`: the full covariance is known.
pub const COVARIANCE_TYPE_KNOWN: u8 = 3;

fn schema(main: &str, deps: &[(&str, &str)]) -> String {
    let mut s = main.to_string();
    for (name, text) in deps {
        s.push_str(SEPARATOR);
        s.push_str("MSG: ");
        s.push_str(name);
        s.push('\n');
        s.push_str(text);
    }
    s
}

/// The `ros2msg` schema text of `name` (one of [`NAV_SAT_FIX`],
/// [`POSE_WITH_COVARIANCE_STAMPED`], [`IMU`]).
pub fn schema_text(name: &str) -> Option<String> {
    let header = ("std_msgs/Header", HEADER);
    let time = ("builtin_interfaces/Time", TIME);
    Some(match name {
        NAV_SAT_FIX => schema(
            "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\n\
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\n\
std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\n\
float64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\n\
uint8 position_covariance_type\n",
            &[header, time, ("sensor_msgs/NavSatStatus", NAV_SAT_STATUS)],
        ),
        POSE_WITH_COVARIANCE_STAMPED => schema(
            "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n",
            &[
                header,
                time,
                ("geometry_msgs/PoseWithCovariance", POSE_WITH_COVARIANCE),
                ("geometry_msgs/Pose", POSE),
                ("geometry_msgs/Point", POINT),
                ("geometry_msgs/Quaternion", QUATERNION),
            ],
        ),
        IMU => schema(
            "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n\
float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n\
float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
float64[9] linear_acceleration_covariance\n",
            &[
                header,
                time,
                ("geometry_msgs/Quaternion", QUATERNION),
                ("geometry_msgs/Vector3", VECTOR3),
            ],
        ),
        _ => return None,
    })
}

/// A `builtin_interfaces/Time` from Unix seconds: whole seconds (floor) and nanoseconds
/// in [0, 1e9). `None` when the time does not fit an `int32` of seconds.
pub fn stamp(time_s: f64) -> Option<(i32, u32)> {
    if !time_s.is_finite() {
        return None;
    }
    // Split before scaling: 1e9 × a Unix time exceeds f64's 53-bit integers.
    let mut sec = time_s.floor();
    let mut nanosec = ((time_s - sec) * 1e9).round();
    if nanosec >= 1e9 {
        sec += 1.0;
        nanosec = 0.0;
    }
    if !(f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&sec) {
        return None;
    }
    Some((sec as i32, nanosec as u32))
}

fn header(w: &mut CdrWriter, (sec, nanosec): (i32, u32), frame_id: &str) {
    w.i32(sec);
    w.u32(nanosec);
    w.string(frame_id);
}

fn quaternion(w: &mut CdrWriter, q: &UnitQuaternion<f64>) {
    w.f64(q.i);
    w.f64(q.j);
    w.f64(q.k);
    w.f64(q.w);
}

/// Row-major elements of a 3×3 matrix.
fn row_major3(m: &Matrix3<f64>) -> [f64; 9] {
    std::array::from_fn(|k| m[(k / 3, k % 3)])
}

/// `sensor_msgs/NavSatFix` of a visual fix: status [`STATUS_FIX`] with service
/// [`SERVICE_NONE`], WGS84 latitude and longitude (degrees) and ellipsoidal height (m),
/// the position covariance (m², ENU at the fix, row-major) as
/// [`COVARIANCE_TYPE_KNOWN`].
pub fn nav_sat_fix(
    stamp: (i32, u32),
    frame_id: &str,
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    covariance_enu_m2: &Matrix3<f64>,
) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    w.i8(STATUS_FIX);
    w.u16(SERVICE_NONE);
    w.f64(lat_deg);
    w.f64(lon_deg);
    w.f64(alt_m);
    w.f64_array(&row_major3(covariance_enu_m2));
    w.u8(COVARIANCE_TYPE_KNOWN);
    w.into_bytes()
}

/// `geometry_msgs/PoseWithCovarianceStamped`: the position (m) and orientation of the rig
/// in `frame_id`, with the 6×6 covariance of `[x, y, z, rotation about x, y, z]` (m², rad²,
/// row-major).
pub fn pose_with_covariance_stamped(
    stamp: (i32, u32),
    frame_id: &str,
    position: &Vector3<f64>,
    orientation: &UnitQuaternion<f64>,
    covariance: &Matrix6<f64>,
) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    w.f64(position.x);
    w.f64(position.y);
    w.f64(position.z);
    quaternion(&mut w, orientation);
    let row_major: [f64; 36] = std::array::from_fn(|k| covariance[(k / 6, k % 6)]);
    w.f64_array(&row_major);
    w.into_bytes()
}

/// `sensor_msgs/Imu` carrying an orientation only: the orientation and its covariance
/// (rad², about the axes of the frame the orientation is given in, row-major); angular
/// velocity and linear acceleration zero with covariance element 0 = −1 ("not given",
/// as `sensor_msgs/Imu` specifies).
pub fn imu_orientation(
    stamp: (i32, u32),
    frame_id: &str,
    orientation: &UnitQuaternion<f64>,
    covariance_rad2: &Matrix3<f64>,
) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    quaternion(&mut w, orientation);
    w.f64_array(&row_major3(covariance_rad2));
    let mut not_given = [0.0; 9];
    not_given[0] = -1.0;
    for _ in 0..2 {
        w.f64_array(&[0.0; 3]);
        w.f64_array(&not_given);
    }
    w.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_split_seconds_and_nanoseconds() {
        // Exactly representable: exact nanoseconds.
        assert_eq!(stamp(1_778_794_200.25), Some((1_778_794_200, 250_000_000)));
        // 1_778_794_200.066_667 is stored as the nearest f64 (spacing 2⁻²² s ≈ 238 ns at
        // this magnitude): the stamp is that value to the nanosecond, 1_778_794_200 s and
        // 66_667_080 ns, within half the spacing of the decimal time.
        let (sec, nanosec) = stamp(1_778_794_200.066_667).unwrap();
        assert_eq!((sec, nanosec), (1_778_794_200, 66_667_080));
        assert!(nanosec.abs_diff(66_667_000) <= 120);
        assert_eq!(stamp(-0.25), Some((-1, 750_000_000)));
        assert_eq!(stamp(f64::NAN), None);
        assert_eq!(stamp(1e12), None);
    }

    #[test]
    fn schemas_name_every_dependency_once() {
        for name in [NAV_SAT_FIX, POSE_WITH_COVARIANCE_STAMPED, IMU] {
            let text = schema_text(name).unwrap();
            assert!(text.contains("MSG: std_msgs/Header\n"), "{name}");
            let deps: Vec<&str> = text.lines().filter(|l| l.starts_with("MSG: ")).collect();
            let mut unique = deps.clone();
            unique.sort_unstable();
            unique.dedup();
            assert_eq!(deps.len(), unique.len(), "{name}");
        }
        assert!(schema_text("std_msgs/msg/String").is_none());
    }

    #[test]
    fn nav_sat_fix_layout() {
        let b = nav_sat_fix((1, 2), "vgps", 1.0, 2.0, 3.0, &Matrix3::identity());
        // header: 4 + 4 + 4 + 5 ("vgps\0") = 17 → status at 17, service at 18, floats at 24.
        assert_eq!(b[4 + 17], 0);
        assert_eq!(&b[4 + 18..4 + 20], &0u16.to_le_bytes());
        assert_eq!(&b[4 + 24..4 + 32], &1.0f64.to_le_bytes());
        assert_eq!(b.len(), 4 + 24 + 3 * 8 + 9 * 8 + 1);
        assert_eq!(b[b.len() - 1], COVARIANCE_TYPE_KNOWN);
    }
}
