//! Lambda Twist P3P on random omnidirectional problems (all solutions, full poses).
use criterion::Criterion;
use std::hint::black_box;
use vgps::synthetic::{P3pProblem, rng};

/// Number of pre-generated problems cycled through by the benchmark.
const PROBLEMS: usize = 1024;

/// Benchmarks of `vgps::solvers::p3p`.
pub fn benches(c: &mut Criterion) {
    let mut r = rng(3);
    let problems: Vec<P3pProblem> = (0..PROBLEMS)
        .map(|_| P3pProblem::random_omni(&mut r, 50.0))
        .collect();
    let mut i = 0usize;
    c.bench_function("p3p", |b| {
        b.iter(|| {
            let p = &problems[i % PROBLEMS];
            i = i.wrapping_add(1);
            vgps::solvers::p3p(black_box(&p.bearings_in_rig), black_box(&p.points_in_world))
        })
    });
    let sigma = 0.5f64.to_radians();
    let noisy: Vec<P3pProblem> = problems
        .iter()
        .map(|p| p.with_noise(&mut r, sigma))
        .collect();
    let mut j = 0usize;
    c.bench_function("p3p/noisy_0.5deg", |b| {
        b.iter(|| {
            let p = &noisy[j % PROBLEMS];
            j = j.wrapping_add(1);
            vgps::solvers::p3p(black_box(&p.bearings_in_rig), black_box(&p.points_in_world))
        })
    });
}
