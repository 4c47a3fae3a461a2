//! The MCAP file read back with the `mcap` crate and the CDR decoded field by field.

use super::*;
use crate::report::FrameOutcome;
use nalgebra::{Matrix2, Matrix6, UnitQuaternion, Vector3};
use vgps_geometry::geo::Geodetic;

/// A CDR reader for the test (the inverse of [`cdr::CdrWriter`]).
struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn new(b: &'a [u8]) -> Self {
        assert_eq!(&b[..4], &cdr::CDR_LE_HEADER);
        Self { b, at: 4 }
    }
    fn take(&mut self, n: usize) -> &'a [u8] {
        let pad = (n - (self.at - 4) % n) % n;
        self.at += pad;
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        s
    }
    fn i8(&mut self) -> i8 {
        i8::from_le_bytes([self.take(1)[0]])
    }
    fn u8(&mut self) -> u8 {
        self.take(1)[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take(2).try_into().unwrap())
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    fn f64s<const N: usize>(&mut self) -> [f64; N] {
        std::array::from_fn(|_| self.f64())
    }
    fn string(&mut self) -> String {
        let n = self.u32() as usize;
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        assert_eq!(s[n - 1], 0);
        String::from_utf8(s[..n - 1].to_vec()).unwrap()
    }
    fn header(&mut self) -> (i32, u32, String) {
        (self.i32(), self.u32(), self.string())
    }
    fn done(&self) {
        assert_eq!(self.at, self.b.len());
    }
}

fn origin() -> Geodetic {
    Geodetic::try_new(37.7793, -122.4193, 2.0).unwrap()
}

fn visual(e: f64, n: f64) -> VisualFix {
    let g = LocalFrame::new(origin())
        .try_to_geodetic(&Vector3::new(e, n, 1.0))
        .unwrap();
    // A full covariance: correlated east-north, up, and the attitude.
    let l = Matrix6::from_fn(|i, j| {
        if i >= j {
            0.01 * (1.0 + (i + 2 * j) as f64)
        } else {
            0.0
        }
    });
    let cov = l * l.transpose();
    VisualFix {
        geodetic: g,
        heading_deg: 30.0,
        pitch_deg: 0.0,
        roll_deg: 0.0,
        enu_from_rig: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0),
        sigma_e_m: cov[(0, 0)].sqrt(),
        sigma_n_m: cov[(1, 1)].sqrt(),
        sigma_u_m: cov[(2, 2)].sqrt(),
        horizontal_covariance_m2: Matrix2::new(cov[(0, 0)], cov[(0, 1)], cov[(1, 0)], cov[(1, 1)]),
        pose_covariance: cov,
        n_landmarks: 5,
        n_surrogates: 0,
    }
}

/// How far two covariances given in ENU axes a distance `d` apart may differ: the axes
/// turn by about `d / R` (R = 6,356 km, the Earth's smallest radius of curvature), which
/// changes an entry by at most `2 (d / R) max|C|` to first order; 2.5 × that.
fn rotation_tolerance(d_m: f64, c: &Matrix6<f64>) -> f64 {
    2.5 * d_m / 6_356_752.0 * c.amax() + 1e-15
}

#[test]
fn one_of_each_message_per_fix_with_the_fix_covariances() {
    let drive = DriveInfo {
        name: "t".into(),
        origin: origin(),
    };
    let t0 = 1_778_794_200.0;
    let records: Vec<FrameOutcome> = (0..5)
        .map(|k| FrameOutcome {
            frame: k,
            time_s: t0 + 0.1 * k as f64,
            status: if k == 2 { "no_fix" } else { "ok" }.into(),
            visual: (k != 2).then(|| visual(10.0 * k as f64, 5.0)),
            gnss: None,
            unusable_images: None,
            truth: None,
            message: String::new(),
        })
        .collect();
    let bytes = mcap_bytes(&drive, &records).unwrap();
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let fixes: Vec<&FrameOutcome> = records.iter().filter(|r| r.visual.is_some()).collect();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let m = message.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(
            (
                schema.encoding.as_str(),
                m.channel.message_encoding.as_str()
            ),
            ("ros2msg", "cdr")
        );
        let k = seen.entry(m.channel.topic.clone()).or_default();
        let r = fixes[*k];
        *k += 1;
        let v = r.visual.as_ref().unwrap();
        let mut c = Reader::new(&m.data);
        let (sec, nanosec, frame_id) = c.header();
        assert!((f64::from(sec) + f64::from(nanosec) * 1e-9 - r.time_s).abs() < 1e-6);
        assert_eq!(m.log_time, sec as u64 * 1_000_000_000 + u64::from(nanosec));
        match m.channel.topic.as_str() {
            TOPIC_FIX => {
                assert_eq!(schema.name, msgs::NAV_SAT_FIX);
                assert_eq!(frame_id, RIG_FRAME);
                assert_eq!((c.i8(), c.u16()), (msgs::STATUS_FIX, msgs::SERVICE_NONE));
                let [lat, lon, alt] = c.f64s::<3>();
                assert_eq!(
                    (lat, lon, alt),
                    (v.geodetic.lat_deg, v.geodetic.lon_deg, v.geodetic.alt_m)
                );
                let cov = c.f64s::<9>();
                // ENU at the fix is within 10 µrad of the map's: the same covariance but for
                // that rotation.
                let d = LocalFrame::new(origin()).to_enu(&v.geodetic).xy().norm();
                let tolerance = rotation_tolerance(d, &v.pose_covariance);
                assert!(tolerance < 1e-5, "{tolerance}");
                for (k, x) in cov.iter().enumerate() {
                    let expected = v.pose_covariance[(k / 3, k % 3)];
                    assert!((x - expected).abs() <= tolerance, "{k}: {x} {expected}");
                }
                assert!((cov[0].sqrt() - v.sigma_e_m).abs() < 1e-6);
                assert!((cov[4].sqrt() - v.sigma_n_m).abs() < 1e-6);
                assert!((cov[8].sqrt() - v.sigma_u_m).abs() < 1e-6);
                assert_eq!(c.u8(), msgs::COVARIANCE_TYPE_KNOWN);
            }
            TOPIC_POSE => {
                assert_eq!(schema.name, msgs::POSE_WITH_COVARIANCE_STAMPED);
                assert_eq!(frame_id, MAP_FRAME);
                let p = Vector3::from(c.f64s::<3>());
                let expected = LocalFrame::new(origin()).to_enu(&v.geodetic);
                assert!((p - expected).norm() < 1e-9, "{p} {expected}");
                let [x, y, z, w] = c.f64s::<4>();
                let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
                assert!(q.angle_to(&v.enu_from_rig) < 1e-4);
                let cov = Matrix6::from_row_slice(&c.f64s::<36>());
                assert_eq!(cov, v.pose_covariance);
            }
            TOPIC_ATTITUDE => {
                assert_eq!(schema.name, msgs::IMU);
                assert_eq!(frame_id, RIG_FRAME);
                let [x, y, z, w] = c.f64s::<4>();
                assert_eq!(
                    (x, y, z, w),
                    (
                        v.enu_from_rig.i,
                        v.enu_from_rig.j,
                        v.enu_from_rig.k,
                        v.enu_from_rig.w
                    )
                );
                let cov = c.f64s::<9>();
                let d = LocalFrame::new(origin()).to_enu(&v.geodetic).xy().norm();
                let tolerance = rotation_tolerance(d, &v.pose_covariance);
                for (k, x) in cov.iter().enumerate() {
                    let expected = v.pose_covariance[(3 + k / 3, 3 + k % 3)];
                    assert!((x - expected).abs() <= tolerance, "{k}: {x} {expected}");
                }
                for _ in 0..2 {
                    assert_eq!(c.f64s::<3>(), [0.0; 3]);
                    assert_eq!(c.f64s::<9>()[0], -1.0);
                }
            }
            other => panic!("unexpected topic {other}"),
        }
        c.done();
    }
    for topic in [TOPIC_FIX, TOPIC_POSE, TOPIC_ATTITUDE] {
        assert_eq!(seen.get(topic), Some(&fixes.len()), "{topic}");
    }
    // The same records give the same bytes.
    assert_eq!(mcap_bytes(&drive, &records).unwrap(), bytes);
}
