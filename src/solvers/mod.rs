//! Pose solvers: one minimal solver per file, with one uniform signature.

pub mod p3p_cosines;
pub mod trilaterate;

pub use p3p_cosines::p3p_cosines;
pub use trilaterate::{TrilaterationError, select_by_handedness, trilaterate};
