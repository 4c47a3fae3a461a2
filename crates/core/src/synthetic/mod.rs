//! Synthetic matcher and mapping scenarios for tests and benchmarks (feature `synthetic`).

pub mod mapping;
pub mod matcher;
pub mod scatter;
