//! The drift a pose accumulates while it is carried on surrogate landmarks.
//!
//! Along a stretch without surveyed landmarks, each fix rests on surrogates mapped from the
//! poses before it, and those poses from the surrogates before them. The covariance chain
//! (the fix's covariance → the surrogates' pose-correlation floor → the next fix) grows
//! like a random walk, but a map built this way can drift like a bias: on a day drive of
//! building corners it moved 1.1 m in one direction over 330 m while the chain said
//! 0.2 m (docs/localizer.md, "Honest covariance"). [`SurrogateDrift`] measures the path
//! carried since the fix last rested on surveyed landmarks; the reported covariance adds
//! `(f·r·d)²` per position axis, `f` the share of the fix's information that comes from
//! surrogates, `r` the drift per metre ([`LocalizerOptions::surrogate_drift_per_m`]) and `d`
//! the distance carried.
//!
//! [`LocalizerOptions::surrogate_drift_per_m`]: super::LocalizerOptions::surrogate_drift_per_m

use nalgebra::{Matrix3, Vector3};

/// A fix rests on surveyed landmarks (and resets the distance carried) when it uses at
/// least [`crate::fix::MIN_OBSERVATIONS`] of them and at most this share of its
/// information comes from surrogates: a fix dominated by surrogates still inherits their
/// drift, whatever number of surveyed landmarks it also uses.
pub const SURVEYED_ANCHOR_MAX_SURROGATE_SHARE: f64 = 0.5;

/// A step between consecutive fixes longer than this (metres) is not travel along one
/// stretch (a re-acquisition after an outage, or a time reset): the distance carried is
/// kept, not extended by it.
pub const MAX_CARRIED_STEP_M: f64 = 50.0;

/// The path carried on surrogates since the last fix that rested on surveyed landmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurrogateDrift {
    carried_m: f64,
    last_position: Option<Vector3<f64>>,
}

impl SurrogateDrift {
    /// Records a fix at `position` (world frame, metres) with `n_surveyed` surveyed
    /// landmarks and a surrogate information share `surrogate_share` in `[0, 1]`; returns the
    /// distance carried at this fix (0 for a fix that rests on surveyed landmarks).
    pub fn record(
        &mut self,
        position: &Vector3<f64>,
        n_surveyed: usize,
        surrogate_share: f64,
    ) -> f64 {
        let anchored = n_surveyed >= crate::fix::MIN_OBSERVATIONS
            && surrogate_share <= SURVEYED_ANCHOR_MAX_SURROGATE_SHARE;
        if anchored {
            self.carried_m = 0.0;
        } else if let Some(last) = self.last_position {
            let step = (position - last).norm();
            if step.is_finite() && step <= MAX_CARRIED_STEP_M {
                self.carried_m += step;
            }
        }
        self.last_position = Some(*position);
        self.carried_m
    }

    /// The covariance (m², per position axis) the drift adds to a fix carried `carried_m`
    /// with surrogate share `surrogate_share`, at `drift_per_m` per metre.
    pub fn covariance(carried_m: f64, surrogate_share: f64, drift_per_m: f64) -> Matrix3<f64> {
        let sigma = surrogate_share.clamp(0.0, 1.0) * drift_per_m * carried_m;
        if sigma.is_finite() && sigma > 0.0 {
            Matrix3::identity() * (sigma * sigma)
        } else {
            Matrix3::zeros()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_grows_on_surrogates_and_resets_on_surveyed_landmarks() {
        let mut d = SurrogateDrift::default();
        assert_eq!(d.record(&Vector3::new(0.0, 0.0, 0.0), 5, 0.1), 0.0);
        // Three surrogate-dominated fixes 10 m apart: 10, 20, 30 m carried, even with
        // three surveyed landmarks when surrogates give most of the information.
        assert_eq!(d.record(&Vector3::new(10.0, 0.0, 0.0), 0, 1.0), 10.0);
        assert_eq!(d.record(&Vector3::new(20.0, 0.0, 0.0), 2, 0.9), 20.0);
        assert_eq!(d.record(&Vector3::new(30.0, 0.0, 0.0), 3, 0.8), 30.0);
        // Surveyed landmarks dominate again: back to 0.
        assert_eq!(d.record(&Vector3::new(40.0, 0.0, 0.0), 3, 0.5), 0.0);
        assert_eq!(d.record(&Vector3::new(40.0, 3.0, 4.0), 1, 0.7), 5.0);
    }

    #[test]
    fn a_jump_is_not_travel() {
        let mut d = SurrogateDrift::default();
        d.record(&Vector3::zeros(), 0, 1.0);
        assert_eq!(d.record(&Vector3::new(20.0, 0.0, 0.0), 0, 1.0), 20.0);
        // 200 m in one step: a re-acquisition elsewhere, not distance along the stretch.
        assert_eq!(d.record(&Vector3::new(220.0, 0.0, 0.0), 0, 1.0), 20.0);
        assert_eq!(d.record(&Vector3::new(f64::NAN, 0.0, 0.0), 0, 1.0), 20.0);
    }

    #[test]
    fn the_added_sigma_is_share_times_rate_times_distance() {
        let c = SurrogateDrift::covariance(300.0, 0.5, 0.002);
        // 0.5 · 0.2 % · 300 m = 0.3 m per axis.
        assert!((c[(0, 0)] - 0.09).abs() < 1e-12);
        assert!((c[(2, 2)] - 0.09).abs() < 1e-12);
        assert_eq!(c[(0, 1)], 0.0);
        assert_eq!(
            SurrogateDrift::covariance(300.0, 0.0, 0.002),
            Matrix3::zeros()
        );
        assert_eq!(
            SurrogateDrift::covariance(0.0, 1.0, 0.002),
            Matrix3::zeros()
        );
        assert_eq!(
            SurrogateDrift::covariance(f64::NAN, 1.0, 0.002),
            Matrix3::zeros()
        );
    }
}
