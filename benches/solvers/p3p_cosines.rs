//! The law-of-cosines P3P (Bierre) and the attitude-from-directions solvers.
use criterion::{BatchSize, Criterion};
use nalgebra::Vector3;
use std::hint::black_box;
use vgps::synthetic::{P3pProblem, perturb_bearing, random_rotation, random_unit_vector, rng};

/// Benchmarks of `solvers::p3p_cosines`, `attitude::triad` and `attitude::wahba`.
pub fn benches(c: &mut Criterion) {
    // A fixed pool of random omnidirectional problems, cycled through.
    let mut r = rng(2);
    let problems: Vec<P3pProblem> = (0..1024)
        .map(|_| P3pProblem::random_omni(&mut r, 50.0))
        .collect();
    let mut i = 0;
    c.bench_function("p3p_cosines/random_omni", |b| {
        b.iter(|| {
            let p = &problems[i % problems.len()];
            i += 1;
            vgps::solvers::p3p_cosines(black_box(&p.bearings_in_rig), black_box(&p.points_in_world))
        })
    });

    let truth = random_rotation(&mut r);
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = (0..10)
        .map(|_| {
            let a = random_unit_vector(&mut r);
            (a, perturb_bearing(&mut r, &(truth * a), 1e-3))
        })
        .collect();
    c.bench_function("attitude/triad", |b| {
        b.iter(|| {
            vgps::attitude::triad(
                black_box([&pairs[0].0, &pairs[1].0]),
                black_box([&pairs[0].1, &pairs[1].1]),
            )
        })
    });
    for n in [3usize, 10] {
        let rig: Vec<_> = pairs[..n].iter().map(|p| p.0).collect();
        let world: Vec<_> = pairs[..n].iter().map(|p| p.1).collect();
        let w = vec![1.0; n];
        c.bench_function(&format!("attitude/wahba_n{n}"), |b| {
            b.iter_batched_ref(
                || (),
                |_| vgps::attitude::wahba(black_box(&rig), black_box(&world), black_box(&w)),
                BatchSize::SmallInput,
            )
        });
    }
}
