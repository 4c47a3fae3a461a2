//! Criterion benchmarks of the solvers. One module per topic; the medians are the figures
//! quoted in the README. Run: `cargo bench --bench solvers [-- FILTER]`.
use criterion::{criterion_group, criterion_main};

mod p3p;
mod synthetic;

criterion_group!(benches, synthetic::benches, p3p::benches);
criterion_main!(benches);
