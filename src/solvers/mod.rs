//! Pose solvers: one minimal solver per file, with one uniform signature.

mod cubic;
pub mod p3p;
pub use p3p::p3p;
