//! Pose solvers: one minimal solver per file, with one uniform signature.
