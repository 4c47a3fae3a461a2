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
    // Omnidirectional problems whose bearings are spread beyond a hemisphere: every pair
    // more than 90° apart (at least one bearing behind any pinhole camera looking along
    // another).
    let wide: Vec<P3pProblem> = std::iter::repeat_with(|| P3pProblem::random_omni(&mut r, 50.0))
        .filter(|p| {
            let [a, b, c] = &p.bearings_in_rig;
            a.dot(b) < 0.0 && a.dot(c) < 0.0 && b.dot(c) < 0.0
        })
        .take(PROBLEMS)
        .collect();
    let mut k = 0usize;
    c.bench_function("p3p/omni_wide_over_90deg", |b| {
        b.iter(|| {
            let p = &wide[k % PROBLEMS];
            k = k.wrapping_add(1);
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
