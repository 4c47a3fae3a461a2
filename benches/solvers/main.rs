//! Criterion benchmarks of the solvers. One module per topic; the medians are the figures
//! quoted in the README. Run: `cargo bench --bench solvers [-- FILTER]`.
use criterion::{criterion_group, criterion_main};

mod calibration;
mod fix;
mod geo;
mod matcher;
mod p3p;
mod p3p_cosines;
mod refine_pose;
mod synthetic;
mod triangulation;

criterion_group!(
    benches,
    calibration::benches,
    fix::benches,
    geo::benches,
    matcher::benches,
    p3p::benches,
    p3p_cosines::benches,
    refine_pose::benches,
    synthetic::benches,
    triangulation::benches,
);
criterion_main!(benches);
