//! # vgps-core — a fix from bearings to landmarks
//!
//! The localization core, the crate a robot stack depends on:
//! - [`fix`]: a fix from bearings to known landmarks (hypotheses, inliers, refinement,
//!   ambiguity and degeneracy statuses).
//! - [`matcher`]: which detections are which surveyed landmarks, when that is not known.
//! - [`localizer`]: the frame-by-frame localizer (tracking, re-acquisition, surrogates).
//! - [`mapping`]: landmark mapping from a moving rig (association, covariance, surrogates,
//!   survey mode, GPS time offset).
//! - [`stats`]: the χ² quantile, Pearson correlation and median of the consistency tests and
//!   summaries.
//!
//! The crates below it are re-exported ([`geometry`], [`geo`], [`calibration`], …), so one
//! dependency is enough.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub use vgps_camera::{calibration, imaging};
pub use vgps_geometry::{attitude, geo, geometry, robust, solvers, triangulation};
pub use vgps_io as io;

pub mod fix;
pub mod localizer;
pub mod mapping;
pub mod matcher;
pub mod measurement;
pub mod stats;
#[cfg(any(test, feature = "synthetic"))]
pub mod synthetic;
