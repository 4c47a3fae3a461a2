//! Pose solvers: one minimal solver per file, with one uniform signature.

pub mod refine_pose;
pub use refine_pose::{RefineError, RefineOptions, RefinedPose, RobustLoss, refine_pose};
