//! Attitude from known directions.
//!
//! - [`triad`]: the rotation from two directions known in both frames (the "rotational
//!   inference" of the Visual GPS proposal; the classical TRIAD algorithm).
//! - [`wahba`] / [`wahba_with_covariance`]: the optimal rotation from any number of weighted
//!   direction pairs, and its error covariance.
//! - [`HeadingPitchRoll`] and [`quaternion_wxyz`]: the reporting forms of an `enu_from_rig`
//!   attitude.
//!
//! # Conventions
//! Every rotation returned here is `world_from_rig`: `direction_in_world = R * direction_in_rig`.
//! Rotation errors are small rotation vectors δθ in the world frame, with
//! `world_from_rig = exp(δθ) · R̂`.

mod euler;
mod triad;
mod wahba;

pub use euler::{GIMBAL_LOCK_COS_PITCH, HeadingPitchRoll, quaternion_wxyz};
pub use triad::{MIN_TRIAD_SINE, triad};
pub use wahba::{MIN_WAHBA_SINE, wahba, wahba_with_covariance};
