//! Criterion benchmarks of the solvers (medians are the figures quoted in the README).
use criterion::{Criterion, criterion_group, criterion_main};

fn bench_generator(c: &mut Criterion) {
    let mut rng = vgps::synthetic::rng(1);
    c.bench_function("synthetic/p3p_problem", |b| {
        b.iter(|| vgps::synthetic::P3pProblem::random_omni(&mut rng, 50.0))
    });
}

criterion_group!(benches, bench_generator);
criterion_main!(benches);
