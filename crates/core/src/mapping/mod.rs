//! Landmark mapping from a moving rig: online association, landmark estimates with
//! covariance, surrogate promotion, survey mode and GPS time-offset calibration.
//!
//! - [`LandmarkMapper`]: Ku, Ho & Sarma's online mapper. Each frame brings a pose
//!   `world_from_rig` with its 6×6 covariance and rays in the rig frame; each ray is gated
//!   against the current landmark estimates (Mahalanobis distance of the estimate from the
//!   ray) and against tentative one-ray tracks (gap between the two lines), assigned one to
//!   one per frame, or starts a new tentative track. A track is initialised once two of its
//!   rays intersect with enough parallax ([`vgps_geometry::triangulation::intersect_two_rays`]) and
//!   then follows the projector-sum estimate of all its rays
//!   ([`vgps_geometry::triangulation::RaySum`], O(1) per ray).
//! - [`refine_landmark`]: the per-landmark refinement: the projector-sum estimate weighted by
//!   each ray's residual variance, with a covariance that propagates the full pose covariance
//!   (position, attitude and their correlation) of every frame into its ray.
//! - [`MappedLandmark`], [`SurrogateCriteria`]: the output, and the rule that promotes a
//!   secondary landmark to a surrogate the localizer may use in place of a surveyed one.
//! - [`survey`]: Ku et al.'s inventory: satellite GPS position + heading (level attitude)
//!   → poses with covariance → all observations associated → the landmark inventory, which
//!   [`write_landmarks_csv`] writes in the format [`vgps_io::read_landmarks`] reads.
//! - [`calibrate_gps_offset`]: the time offset between the GPS track and the camera that best
//!   explains the rays (the paper's "about a metre behind" lag).
//! - [`smooth_track`], [`track_covers`], [`frame_coverage`], [`landmark_chi2`]: the GNSS
//!   track of a survey (smoothing, outages) and the checks a surveyed landmark passes before
//!   it is written.
//!
//! The derivations, thresholds and measured figures are in `docs/mapping.md`.
//!
//! # Conventions
//! World frame: local ENU (metres). Rig frame: x forward, y left, z up. A pose is
//! `world_from_rig`; its covariance is ordered `[δp (m, world), δθ (rad, world)]` with
//! `world_from_rig = (exp(δθ)·R̂, p̂ + δp)`. Angles in radians, times in seconds.
//!
//! # References
//! - J. S. Ku, S. Ho, S. Sarma, "Landmark Mapping from Unbiased Observations", MIT
//!   (projector sum eq. (2), covariance eq. (9), online O(nk) association §II-E, Fig. 7).
//! - Visual GPS proposal (Bierre): secondary landmarks mapped by ray intersection from two
//!   poses stand in as surrogates during occlusion of primary landmarks.

mod calibrate;
mod frame;
mod mapper;
mod refine;
mod survey;
mod track;

#[cfg(test)]
mod tests;

pub use calibrate::{
    MAX_GPS_OFFSET_S, OFFSET_GRID_POINTS, OFFSET_TOLERANCE_S, OffsetCalibration, OffsetSearch,
    calibrate_gps_offset,
};
pub use frame::{MappingFrame, RigObservation};
pub(crate) use mapper::{CONE_ABSOLUTE_MARGIN, CONE_MIN_COS, CONE_RELATIVE_MARGIN, max_or_nan};
pub use mapper::{
    LandmarkMapper, MAX_PAIRWISE_RAYS, MAX_SURROGATE_MEAN_CHI2, MapperOptions, NearbySurrogate,
    SeenAhead, seen_covariance,
};
pub use refine::{MapRay, ray_chi2, ray_residual_covariance, refine_landmark};
pub use survey::{
    CameraFrame, GpsSample, SIGMA_LEVEL_RAD, Survey, SurveyOptions, gps_pose_at, landmarks_csv,
    survey, write_landmarks_csv,
};
pub use track::{
    MAX_GNSS_GAP_S, MIN_SMOOTH_FIXES, frame_coverage, landmark_chi2, median_speed, smooth_track,
    track_covers,
};

use nalgebra::{Matrix3, Vector3};
use vgps_geometry::geo::{GeoError, Geodetic, LocalFrame};

/// χ² quantile with 2 degrees of freedom at 99.9 %: the gate on the Mahalanobis distance of
/// a landmark estimate from a new ray (two components perpendicular to the ray).
pub const GATE_CHI2_2DOF: f64 = 13.815_510_557_964_274;

/// χ² quantile with 1 degree of freedom at 99.9 %: the gate on the gap between a new ray and
/// the ray of a one-ray tentative track, in units of its standard deviation squared.
pub const GATE_CHI2_1DOF: f64 = 10.827_566_170_662_733;

/// Farthest landmark considered for association (metres from the camera centre). Also the
/// spatial shortcut: tracks farther than this from the rig are not tested.
pub const MAX_RANGE_M: f64 = 100.0;

/// Nearest landmark considered by the two-ray gate (metres from the camera centre).
pub const MIN_RANGE_M: f64 = 1.0;

/// Smallest parallax at which two rays initialise a track (radians, ≈ 0.57°). Below it the
/// range of a two-ray intersection is uncertain by more than `σ_ang / parallax ≈ 10 %` for a
/// 1 mrad camera; the track waits for a better-separated ray.
pub const MIN_INIT_PARALLAX_RAD: f64 = 0.01;

/// Largest worst-axis standard deviation of a track's first estimate, as a fraction of its
/// range (dimensionless). Two nearly parallel noisy rays can meet anywhere along the line of
/// sight; such an estimate would make the gate reject the landmark's next rays, so the track
/// keeps gating ray-to-ray until its rays pin the range down to 25 %.
pub const MAX_INIT_RELATIVE_SIGMA: f64 = 0.25;

/// A track not seen for this long (seconds) is dropped if it has fewer than
/// [`MIN_LANDMARK_RAYS`] rays.
pub const TENTATIVE_TIMEOUT_S: f64 = 3.0;

/// Fewest rays a track needs to be kept as a landmark (reported, written, kept after
/// [`TENTATIVE_TIMEOUT_S`]). Three rays leave one degree of freedom to check their
/// consistency (2n − 3 = 3).
pub const MIN_LANDMARK_RAYS: usize = 3;

/// Fewest rays of a surrogate landmark.
pub const MIN_SURROGATE_RAYS: usize = 5;

/// Smallest parallax of a surrogate landmark (radians, ≈ 5.7°): the angle the rig's path
/// subtends at the landmark must be wide enough that the range is determined by geometry,
/// not only by the noise model.
pub const MIN_SURROGATE_PARALLAX_RAD: f64 = 0.1;

/// Largest standard deviation of a surrogate landmark along its worst axis (metres,
/// `√λ_max(Σ)`).
pub const MAX_SURROGATE_SIGMA_M: f64 = 0.5;

/// When a secondary (mapped) landmark is good enough to stand in for a surveyed one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurrogateCriteria {
    /// Fewest rays ([`MIN_SURROGATE_RAYS`]).
    pub min_rays: usize,
    /// Smallest largest-angle between its rays (radians, [`MIN_SURROGATE_PARALLAX_RAD`]).
    pub min_parallax_rad: f64,
    /// Largest `√λ_max` of its covariance (metres, [`MAX_SURROGATE_SIGMA_M`]).
    pub max_sigma_m: f64,
}

impl Default for SurrogateCriteria {
    fn default() -> Self {
        Self {
            min_rays: MIN_SURROGATE_RAYS,
            min_parallax_rad: MIN_SURROGATE_PARALLAX_RAD,
            max_sigma_m: MAX_SURROGATE_SIGMA_M,
        }
    }
}

impl SurrogateCriteria {
    /// True when `landmark` meets all three criteria.
    pub fn accepts(&self, landmark: &MappedLandmark) -> bool {
        landmark.n_obs >= self.min_rays
            && landmark.max_parallax_rad >= self.min_parallax_rad
            && landmark.sigma_m() <= self.max_sigma_m
    }
}

/// A mapped landmark: the refined estimate of one track.
///
/// # Units
/// Metres (world ENU) for `position_enu`, m² for `covariance`, radians for the parallax.
#[derive(Clone, Debug, PartialEq)]
pub struct MappedLandmark {
    /// Identifier of the track (unique within one mapper; never reused).
    pub id: u64,
    /// Estimated position in the world (ENU) frame.
    pub position_enu: Vector3<f64>,
    /// Covariance of `position_enu`, including the pose uncertainty of every frame.
    pub covariance: Matrix3<f64>,
    /// Number of rays (observations) used.
    pub n_obs: usize,
    /// Largest angle between the first ray and any other ray (a lower bound on the largest
    /// angle between any two rays, which is at most twice it).
    pub max_parallax_rad: f64,
    /// Class label of the observations (index into the caller's class names), if any.
    pub class: Option<u32>,
}

impl MappedLandmark {
    /// Standard deviation along the worst axis, `√λ_max(Σ)` (metres): the `sigma_m` written
    /// to landmarks.csv (conservative: the file has one σ per landmark).
    pub fn sigma_m(&self) -> f64 {
        let ev = self.covariance.symmetric_eigenvalues();
        ev.max().max(0.0).sqrt()
    }

    /// The WGS84 position, given the ENU frame the mapping was done in.
    ///
    /// # Errors
    /// [`GeoError`] when the point is outside the supported heights.
    pub fn to_geodetic(&self, frame: &LocalFrame) -> Result<Geodetic, GeoError> {
        frame.try_to_geodetic(&self.position_enu)
    }
}

/// Errors of the mapping module.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MappingError {
    /// A frame's pose is not finite, or its covariance is not finite with a non-negative
    /// diagonal.
    #[error("frame {frame}: invalid pose or pose covariance")]
    InvalidPose {
        /// Index of the frame (in the order given).
        frame: usize,
    },
    /// An observation is not a finite unit ray with a finite non-negative σ.
    #[error("frame {frame}, observation {observation}: {reason}")]
    InvalidObservation {
        /// Index of the frame.
        frame: usize,
        /// Index of the observation in its frame.
        observation: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// The GPS track is unusable (fewer than two samples, times not strictly increasing, a
    /// non-finite value or a negative σ).
    #[error("GPS sample {index}: {reason}")]
    GpsTrack {
        /// Index of the offending sample.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// Invalid options (named field).
    #[error("invalid option {0}")]
    InvalidOption(&'static str),
    /// Too few landmarks with rays from the GPS track to calibrate the time offset.
    #[error("time-offset calibration needs landmarks: {0}")]
    NotObservable(&'static str),
    /// A landmark could not be converted to WGS84.
    #[error("landmark {id}: {source}")]
    Geo {
        /// Landmark id.
        id: u64,
        /// The conversion error.
        source: GeoError,
    },
    /// Writing the landmarks file failed.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        reason: String,
    },
}
