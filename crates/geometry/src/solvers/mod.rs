//! Pose solvers: one minimal solver per file, with one uniform signature.
//!
//! Every minimal solver has the signature of [`MinimalSolver`]: three bearings in the rig
//! frame (any non-zero finite length) and the three world points they see, returning every
//! pose `world_from_rig` consistent with them. An empty list means a degenerate sample
//! (collinear or coincident points, parallel bearings, non-finite input), never a NaN.
//!
//! - [`p3p`](p3p::p3p): Lambda Twist (Persson & Nordberg 2018), the fast closed-form P3P,
//!   adapted to bearings all around the sphere.
//! - [`p3p_cosines`](p3p_cosines::p3p_cosines): the law-of-cosines P3P of the Visual GPS
//!   proposal, solved by a one-parameter root scan (Bierre 2006).
//! - [`trilaterate`](trilaterate::trilaterate): intersection of three spheres.
//! - [`refine_pose`](refine_pose::refine_pose): Levenberg–Marquardt on angular residuals over
//!   all correspondences, for central and non-central rigs, with a 6×6 covariance.

use crate::geometry::PoseSolutions;
use nalgebra::Vector3;

/// The uniform signature of the minimal (three-point) pose solvers.
pub type MinimalSolver =
    fn(bearings_in_rig: &[Vector3<f64>; 3], points_in_world: &[Vector3<f64>; 3]) -> PoseSolutions;

mod cubic;
pub mod p3p;
pub mod p3p_cosines;
pub mod refine_pose;
pub mod trilaterate;
pub mod up2p;

pub use p3p::p3p;
pub use p3p_cosines::p3p_cosines;
pub use refine_pose::{RefineError, RefineOptions, RefinedPose, RobustLoss, refine_pose};
pub use trilaterate::{TrilaterationError, select_by_handedness, trilaterate};
pub use up2p::up2p;
