//! The shared generator itself, as a baseline for the solver timings.
use criterion::Criterion;

/// Benchmarks of the synthetic-problem generator.
pub fn benches(c: &mut Criterion) {
    let mut rng = vgps::synthetic::rng(1);
    c.bench_function("synthetic/p3p_problem", |b| {
        b.iter(|| vgps::synthetic::P3pProblem::random_omni(&mut rng, 50.0))
    });
}
