//! Heading, pitch and roll of an `enu_from_rig` attitude, and its quaternion.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use std::f64::consts::{FRAC_PI_2, TAU};

/// Below this value of `cos(pitch)` the attitude is treated as gimbal-locked (rig +x within
/// about 2·10⁻⁸ rad of the zenith or nadir): heading and roll are then not separable, and
/// roll is reported as zero with all of the rotation about the vertical put in the heading.
pub const GIMBAL_LOCK_COS_PITCH: f64 = 1e-12;

/// Attitude of the rig in a local East-North-Up frame as heading, pitch and roll (radians).
///
/// # Convention
/// Rig frame: x forward, y left, z up. World frame: ENU.
/// - `heading_rad`: angle of the rig +x axis clockwise from true north, seen from above, in
///   `[0, 2π)` (0 → +x points north, π/2 → east).
/// - `pitch_rad`: elevation of the rig +x axis above the horizon, in `[−π/2, π/2]`.
/// - `roll_rad`: rotation about the rig +x axis, positive when the right side (rig −y) goes
///   down, in `(−π, π]`.
///
/// The rotation sequence (intrinsic z-y-x, applied to the rig starting from x north, y west,
/// z up) is
///
/// ```text
/// enu_from_rig = Rz(π/2 − heading) · Ry(−pitch) · Rx(roll)
/// ```
///
/// with `Rz`, `Ry`, `Rx` the right-handed elementary rotations about the frame axes.
/// Hence the rig +x axis in ENU is `(cos p · sin h, cos p · cos h, sin p)`.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_geometry::attitude::HeadingPitchRoll;
/// let hpr = HeadingPitchRoll { heading_rad: 90f64.to_radians(), pitch_rad: 0.0, roll_rad: 0.0 };
/// let enu_from_rig = hpr.to_enu_from_rig();
/// assert!((enu_from_rig * Vector3::x() - Vector3::x()).norm() < 1e-15); // forward = east
/// let back = HeadingPitchRoll::from_enu_from_rig(&enu_from_rig);
/// assert!((back.heading_rad - hpr.heading_rad).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingPitchRoll {
    /// Heading of the rig +x axis, clockwise from true north (radians, `[0, 2π)`).
    pub heading_rad: f64,
    /// Elevation of the rig +x axis above the horizon (radians, `[−π/2, π/2]`).
    pub pitch_rad: f64,
    /// Roll about the rig +x axis, right side down positive (radians, `(−π, π]`).
    pub roll_rad: f64,
}

impl HeadingPitchRoll {
    /// Heading, pitch and roll of an `enu_from_rig` rotation.
    ///
    /// With `M = enu_from_rig`: `pitch = atan2(M₂₀, √(M₂₁² + M₂₂²))`,
    /// `heading = atan2(M₀₀, M₁₀)`, `roll = atan2(M₂₁, M₂₂)`. At gimbal lock
    /// (`cos pitch <` [`GIMBAL_LOCK_COS_PITCH`]) roll is set to 0 and the heading is read from
    /// the rig y axis, `heading = atan2(M₁₁, −M₀₁)`; the returned angles still reproduce the
    /// rotation. Every output is finite for a finite rotation.
    pub fn from_enu_from_rig(enu_from_rig: &Rotation3<f64>) -> Self {
        let m = enu_from_rig.matrix();
        let horizontal = m[(2, 1)].hypot(m[(2, 2)]);
        let pitch_rad = m[(2, 0)].atan2(horizontal);
        let (heading, roll_rad) = if horizontal < GIMBAL_LOCK_COS_PITCH {
            (m[(1, 1)].atan2(-m[(0, 1)]), 0.0)
        } else {
            (m[(0, 0)].atan2(m[(1, 0)]), m[(2, 1)].atan2(m[(2, 2)]))
        };
        Self {
            heading_rad: wrap_to_tau(heading),
            pitch_rad,
            roll_rad,
        }
    }

    /// The rotation `enu_from_rig` of these angles:
    /// `Rz(π/2 − heading) · Ry(−pitch) · Rx(roll)`.
    pub fn to_enu_from_rig(&self) -> Rotation3<f64> {
        let (sh, ch) = (FRAC_PI_2 - self.heading_rad).sin_cos();
        let (sp, cp) = (-self.pitch_rad).sin_cos();
        let (sr, cr) = self.roll_rad.sin_cos();
        let rz = Matrix3::new(ch, -sh, 0.0, sh, ch, 0.0, 0.0, 0.0, 1.0);
        let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
        Rotation3::from_matrix_unchecked(rz * ry * rx)
    }

    /// The angles in degrees, `[heading, pitch, roll]` (for files and the command line).
    pub fn to_degrees(&self) -> [f64; 3] {
        [
            self.heading_rad.to_degrees(),
            self.pitch_rad.to_degrees(),
            self.roll_rad.to_degrees(),
        ]
    }
}

/// `angle` wrapped into `[0, 2π)`.
fn wrap_to_tau(angle: f64) -> f64 {
    let a = angle.rem_euclid(TAU);
    if a >= TAU { 0.0 } else { a }
}

/// The unit quaternion of a rotation as `[w, x, y, z]`, with the sign chosen so that
/// `w ≥ 0` (the two quaternions `±q` are the same rotation).
///
/// # Example
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// let r = Rotation3::from_axis_angle(&Vector3::z_axis(), 3.0 * std::f64::consts::FRAC_PI_2);
/// let [w, x, y, z] = vgps_geometry::attitude::quaternion_wxyz(&r);
/// let h = std::f64::consts::FRAC_1_SQRT_2;
/// assert!((w - h).abs() < 1e-15 && x == 0.0 && y == 0.0 && (z + h).abs() < 1e-15);
/// ```
pub fn quaternion_wxyz(rotation: &Rotation3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(rotation);
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    let v: Vector3<f64> = q.imag() * s;
    [q.w * s, v.x, v.y, v.z]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{random_rotation, rng};
    use rand::RngExt;
    use std::f64::consts::PI;

    fn hpr_deg(h: f64, p: f64, r: f64) -> HeadingPitchRoll {
        HeadingPitchRoll {
            heading_rad: h.to_radians(),
            pitch_rad: p.to_radians(),
            roll_rad: r.to_radians(),
        }
    }

    #[test]
    fn known_answers() {
        let x = Vector3::x();
        let y = Vector3::y();
        let z = Vector3::z();
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() < 1e-15;
        // Heading 0: forward = north, left = west, up = up.
        let r = hpr_deg(0.0, 0.0, 0.0).to_enu_from_rig();
        assert!(close(r * x, y) && close(r * y, -x) && close(r * z, z));
        // Heading 90°: forward = east, left = north.
        let r = hpr_deg(90.0, 0.0, 0.0).to_enu_from_rig();
        assert!(close(r * x, x) && close(r * y, y));
        // Heading 180°: forward = south. Heading 270°: forward = west.
        assert!(close(hpr_deg(180.0, 0.0, 0.0).to_enu_from_rig() * x, -y));
        assert!(close(hpr_deg(270.0, 0.0, 0.0).to_enu_from_rig() * x, -x));
        // Pitch +30° at heading 0: forward points up-north.
        let f = hpr_deg(0.0, 30.0, 0.0).to_enu_from_rig() * x;
        assert!(close(
            f,
            Vector3::new(0.0, 0.5f64.sqrt() * 1.5f64.sqrt(), 0.5)
        ));
        // Roll +90° at heading 0: the right side (−y) points down, left (+y) points up.
        let r = hpr_deg(0.0, 0.0, 90.0).to_enu_from_rig();
        assert!(close(r * (-y), -z) && close(r * x, y));
        // Heading 45°, pitch 0: forward = north-east.
        let h = 0.5f64.sqrt();
        assert!(close(
            hpr_deg(45.0, 0.0, 0.0).to_enu_from_rig() * x,
            Vector3::new(h, h, 0.0)
        ));
    }

    #[test]
    fn angles_round_trip_through_the_rotation() {
        let mut r = rng(31);
        for _ in 0..20_000 {
            let a = HeadingPitchRoll {
                heading_rad: r.random_range(0.0..TAU),
                pitch_rad: r.random_range(-1.5..1.5),
                roll_rad: r.random_range(-3.1..3.1),
            };
            let b = HeadingPitchRoll::from_enu_from_rig(&a.to_enu_from_rig());
            assert!((a.heading_rad - b.heading_rad).abs() < 1e-12, "{a:?} {b:?}");
            assert!((a.pitch_rad - b.pitch_rad).abs() < 1e-12);
            assert!((a.roll_rad - b.roll_rad).abs() < 1e-12);
        }
    }

    #[test]
    fn rotations_round_trip_through_the_angles() {
        let mut r = rng(32);
        for _ in 0..20_000 {
            let rot = random_rotation(&mut r);
            let hpr = HeadingPitchRoll::from_enu_from_rig(&rot);
            assert!((0.0..TAU).contains(&hpr.heading_rad));
            assert!(hpr.pitch_rad.abs() <= FRAC_PI_2);
            assert!(hpr.roll_rad > -PI - 1e-15 && hpr.roll_rad <= PI);
            assert!((hpr.to_enu_from_rig().matrix() - rot.matrix()).norm() < 1e-12);
        }
    }

    #[test]
    fn gimbal_lock_is_finite_and_reproduces_the_rotation() {
        for pitch in [90.0, -90.0, 89.999_999_999, -89.999_999_999] {
            for (h, roll) in [(0.0, 0.0), (30.0, 20.0), (200.0, -120.0), (359.0, 179.0)] {
                let a = hpr_deg(h, pitch, roll);
                let rot = a.to_enu_from_rig();
                let b = HeadingPitchRoll::from_enu_from_rig(&rot);
                assert!(b.heading_rad.is_finite() && b.pitch_rad.is_finite());
                assert!(b.roll_rad.is_finite());
                assert!((b.pitch_rad - a.pitch_rad).abs() < 1e-7);
                assert!(
                    (b.to_enu_from_rig().matrix() - rot.matrix()).norm() < 1e-7,
                    "{a:?} {b:?}"
                );
            }
        }
        // Exactly at the zenith, roll is reported as zero and heading absorbs it.
        let b = HeadingPitchRoll::from_enu_from_rig(&hpr_deg(30.0, 90.0, 20.0).to_enu_from_rig());
        assert_eq!(b.roll_rad, 0.0);
        assert!((b.heading_rad.to_degrees() - 10.0).abs() < 1e-9, "{b:?}");
    }

    #[test]
    fn quaternion_has_non_negative_w_and_matches() {
        let mut r = rng(33);
        for _ in 0..10_000 {
            let rot = random_rotation(&mut r);
            let [w, x, y, z] = quaternion_wxyz(&rot);
            assert!(w >= 0.0);
            assert!(((w * w + x * x + y * y + z * z) - 1.0).abs() < 1e-14);
            let q = UnitQuaternion::new_normalize(nalgebra::Quaternion::new(w, x, y, z));
            assert!((q.to_rotation_matrix().matrix() - rot.matrix()).norm() < 1e-12);
        }
        let id = quaternion_wxyz(&Rotation3::identity());
        assert_eq!(id, [1.0, 0.0, 0.0, 0.0]);
    }
}
