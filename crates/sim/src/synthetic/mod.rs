//! Every synthetic-problem generator of the workspace in one place: the test kit of
//! `vgps-geometry` (random helpers, P3P, PnP, RANSAC and ray problems), the synthetic
//! calibrations of `vgps-camera`, the matcher and mapping scenarios of `vgps-core`, and
//! night streets.

pub use vgps_camera::synthetic::{calibration, calibration_files};
pub use vgps_core::synthetic::{mapping, matcher, scatter};
pub use vgps_geometry::synthetic::*;

pub mod night;
