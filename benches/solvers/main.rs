//! Criterion benchmarks of the solvers. One module per topic; the medians are the figures
//! quoted in the README. Run: `cargo bench --bench solvers [-- FILTER]`.
use criterion::{criterion_group, criterion_main};

mod calibration;
mod fix;
mod geo;
mod imaging;
mod localizer;
mod mapping;
mod matcher;
mod p3p;
mod p3p_cosines;
mod refine_pose;
mod replay;
mod robust;
mod synthetic;
mod triangulation;
mod up2p;

criterion_group!(
    benches,
    calibration::benches,
    fix::benches,
    geo::benches,
    imaging::benches,
    imaging::day_benches,
    localizer::benches,
    mapping::benches,
    matcher::benches,
    p3p::benches,
    p3p_cosines::benches,
    refine_pose::benches,
    replay::benches,
    robust::benches,
    synthetic::benches,
    triangulation::benches,
    up2p::benches,
);
criterion_main!(benches);
