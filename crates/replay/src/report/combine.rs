//! The forward and backward passes of an offline replay, combined (`vgps replay
//! --direction combined`).
//!
//! A replay localizes the frames in time order (the forward pass). Offline, the frames can
//! also be localized in reverse (the backward pass, [`Localizer::process_backward`]): where
//! the forward pass lost its fix (a survey gap, a stretch waiting for a cold start), the
//! backward pass arrives tracking from the other side. Each frame keeps its forward fix;
//! a frame without one takes the backward fix, if any. Post-processing GNSS software does
//! the same ("combined" solutions).
//!
//! Where both passes fix a frame, the two fixes are compared: positions further apart
//! than their covariances allow are counted as disagreeing (see [`Combination`]); the
//! forward fix is kept.
//!
//! [`Localizer::process_backward`]: vgps_core::localizer::Localizer::process_backward

use super::{FrameOutcome, VisualFix};
use vgps_geometry::geo::LocalFrame;

/// The χ² quantile with 2 degrees of freedom at a false-alarm probability of 10⁻⁴
/// (`−2 ln 10⁻⁴`): two fixes of one frame disagree when the Mahalanobis distance of their
/// horizontal difference under the sum of their covariances exceeds it.
pub const DISAGREEMENT_CHI2: f64 = 18.420_680_743_952_367;

/// Horizontal differences below this (metres) never count as disagreeing, whatever the
/// covariances: the fixes' σ are centimetres, and a few centimetres of difference between
/// the passes' surrogates are not an integrity event.
pub const DISAGREEMENT_FLOOR_M: f64 = 0.5;

/// What combining the passes did (counts of frames).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Combination {
    /// Frames the forward pass fixed.
    pub forward: usize,
    /// Frames the backward pass fixed.
    pub backward: usize,
    /// Frames without a forward fix that now have the backward one.
    pub filled: usize,
    /// Frames both passes fixed at horizontal positions that differ by more than
    /// [`DISAGREEMENT_FLOOR_M`] and by more than their covariances allow
    /// ([`DISAGREEMENT_CHI2`]).
    pub disagreeing: usize,
}

/// The backward pass's result for one frame: its fix (`None` without one) and the
/// localizer's message.
#[derive(Clone, Debug, PartialEq)]
pub struct BackwardFix {
    /// The fix, if the backward pass found one.
    pub visual: Option<VisualFix>,
    /// Why the frame has this status, in the localizer's words.
    pub message: String,
}

/// Combines the passes in place: each record of `forward` without a visual fix takes the
/// fix of `backward` at the same index (its status becomes `ok`, its message is prefixed
/// `backward pass:`). `backward` is in the records' order (not the pass's); a `None` is a
/// frame the backward pass did not localize (no usable detections). Extra entries of
/// either side are ignored.
pub fn combine_passes(
    forward: &mut [FrameOutcome],
    backward: &[Option<BackwardFix>],
    ok_status: &str,
) -> Combination {
    let mut c = Combination::default();
    for (record, b) in forward.iter_mut().zip(backward) {
        let b = b
            .as_ref()
            .and_then(|b| b.visual.as_ref().map(|v| (v, &b.message)));
        c.backward += usize::from(b.is_some());
        match (&record.visual, b) {
            (Some(f), Some((v, _))) => {
                c.forward += 1;
                c.disagreeing += usize::from(disagree(f, v));
            }
            (Some(_), None) => c.forward += 1,
            (None, Some((v, message))) => {
                c.filled += 1;
                record.visual = Some(v.clone());
                record.status = ok_status.to_string();
                record.message = format!("backward pass: {message}");
            }
            (None, None) => {}
        }
    }
    c
}

/// True when two fixes of one frame differ horizontally by more than
/// [`DISAGREEMENT_FLOOR_M`] and by more than their summed covariances allow.
fn disagree(a: &VisualFix, b: &VisualFix) -> bool {
    let frame = LocalFrame::new(a.geodetic);
    let d = frame.to_enu(&b.geodetic);
    let en = nalgebra::Vector2::new(d.x, d.y);
    if !(en.x.is_finite() && en.y.is_finite()) {
        return true;
    }
    if en.norm() <= DISAGREEMENT_FLOOR_M {
        return false;
    }
    let cov = a.horizontal_covariance_m2 + b.horizontal_covariance_m2;
    // A covariance that cannot be inverted says nothing: a difference beyond the floor is
    // then a disagreement.
    super::stats::mahalanobis2(&en, &cov).is_none_or(|d2| d2 > DISAGREEMENT_CHI2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix6, UnitQuaternion};
    use vgps_geometry::geo::Geodetic;

    fn fix_at(lat_deg: f64, sigma_m: f64) -> VisualFix {
        let var = sigma_m * sigma_m;
        VisualFix {
            geodetic: Geodetic::try_new(lat_deg, 11.0, 500.0).expect("a valid position"),
            heading_deg: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
            enu_from_rig: UnitQuaternion::identity(),
            sigma_e_m: sigma_m,
            sigma_n_m: sigma_m,
            sigma_u_m: sigma_m,
            horizontal_covariance_m2: Matrix2::identity() * var,
            pose_covariance: Matrix6::identity() * var,
            n_landmarks: 4,
            n_surrogates: 0,
        }
    }

    fn record(frame: u64, visual: Option<VisualFix>, status: &str) -> FrameOutcome {
        FrameOutcome {
            frame,
            time_s: frame as f64,
            status: status.into(),
            visual,
            gnss: None,
            unusable_images: None,
            truth: None,
            message: "forward".into(),
        }
    }

    fn backward(visual: Option<VisualFix>) -> Option<BackwardFix> {
        Some(BackwardFix {
            visual,
            message: "2 surveyed landmark(s), 3 surrogate(s)".into(),
        })
    }

    /// One metre of latitude, near enough (the tests compare metres to 0.5 m floors and
    /// centimetre σ).
    const DEG_PER_M: f64 = 1.0 / 111_000.0;

    #[test]
    fn a_frame_without_a_forward_fix_takes_the_backward_one_and_forward_fixes_stay() {
        let mut records = vec![
            record(0, Some(fix_at(48.0, 0.02)), "ok"),
            record(1, None, "no_prior"),
            record(2, None, "no_fix"),
            record(3, None, "bad_image"),
        ];
        let b = vec![
            backward(Some(fix_at(48.0 + 0.01 * DEG_PER_M, 0.02))),
            backward(Some(fix_at(48.0 + 5.0 * DEG_PER_M, 0.02))),
            backward(None),
            None,
        ];
        let c = combine_passes(&mut records, &b, "ok");
        assert_eq!(
            c,
            Combination {
                forward: 1,
                backward: 2,
                filled: 1,
                disagreeing: 0
            }
        );
        // The forward fix stays (not the backward one 1 cm away).
        assert_eq!(records[0].visual, Some(fix_at(48.0, 0.02)));
        assert_eq!(records[0].message, "forward");
        assert_eq!(records[1].status, "ok");
        assert_eq!(
            records[1].visual,
            Some(fix_at(48.0 + 5.0 * DEG_PER_M, 0.02))
        );
        assert_eq!(
            records[1].message,
            "backward pass: 2 surveyed landmark(s), 3 surrogate(s)"
        );
        assert_eq!(
            (records[2].status.as_str(), records[2].visual.is_none()),
            ("no_fix", true)
        );
        assert_eq!(records[3].status, "bad_image");
    }

    #[test]
    fn fixes_metres_apart_disagree_unless_their_covariances_allow_it() {
        let a = fix_at(48.0, 0.02);
        // 2 m apart with 2 cm σ: 70 σ.
        assert!(disagree(&a, &fix_at(48.0 + 2.0 * DEG_PER_M, 0.02)));
        // 2 m apart with 1 m σ each: 1.4 σ.
        assert!(!disagree(
            &fix_at(48.0, 1.0),
            &fix_at(48.0 + 2.0 * DEG_PER_M, 1.0)
        ));
        // 0.4 m apart with 1 cm σ: under the floor.
        assert!(!disagree(
            &fix_at(48.0, 0.01),
            &fix_at(48.0 + 0.4 * DEG_PER_M, 0.01)
        ));
        let mut records = vec![record(0, Some(a), "ok")];
        let b = vec![backward(Some(fix_at(48.0 + 2.0 * DEG_PER_M, 0.02)))];
        let c = combine_passes(&mut records, &b, "ok");
        assert_eq!(
            (c.forward, c.backward, c.filled, c.disagreeing),
            (1, 1, 0, 1)
        );
    }
}
