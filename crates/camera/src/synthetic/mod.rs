//! Synthetic calibrations for tests and benchmarks (feature `synthetic`).

pub mod calibration;
pub mod calibration_files;
