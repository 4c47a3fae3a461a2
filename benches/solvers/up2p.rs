//! The two-point known-vertical solver `up2p` on random problems drawn from P3P problems (the
//! first two bearings and points; the up direction from the true pose).
use criterion::Criterion;
use nalgebra::Vector3;
use std::hint::black_box;
use vgps::synthetic::{P3pProblem, rng};

/// Number of pre-generated problems cycled through by the benchmark.
const PROBLEMS: usize = 1024;

/// One problem: the rig's up, two bearings in the rig frame, two world points.
type Problem = (Vector3<f64>, [Vector3<f64>; 2], [Vector3<f64>; 2]);

/// Benchmarks of `vgps::solvers::up2p` (full, with levelling) and `up2p_levelled` (the inner
/// loop of a matcher: bearings levelled once).
pub fn benches(c: &mut Criterion) {
    let mut r = rng(11);
    let problems: Vec<Problem> = (0..PROBLEMS)
        .map(|_| {
            let p = P3pProblem::random_omni(&mut r, 50.0);
            let up = p.world_from_rig.rotation.inverse() * Vector3::z();
            (
                up,
                [p.bearings_in_rig[0], p.bearings_in_rig[1]],
                [p.points_in_world[0], p.points_in_world[1]],
            )
        })
        .collect();
    let mut i = 0usize;
    c.bench_function("up2p", |b| {
        b.iter(|| {
            let (up, bearings, points) = &problems[i % PROBLEMS];
            i = i.wrapping_add(1);
            vgps::solvers::up2p(black_box(up), black_box(bearings), black_box(points))
        })
    });
    let levelled: Vec<_> = problems
        .iter()
        .map(|(up, b, p)| {
            let level = vgps::solvers::up2p::level_from_rig(up).unwrap();
            (
                level,
                [level * b[0].normalize(), level * b[1].normalize()],
                *p,
            )
        })
        .collect();
    let mut j = 0usize;
    c.bench_function("up2p/levelled", |b| {
        b.iter(|| {
            let (level, f, p) = &levelled[j % PROBLEMS];
            j = j.wrapping_add(1);
            let mut out = vgps::geometry::PoseSolutions::new();
            vgps::solvers::up2p::up2p_levelled(
                black_box(level),
                black_box(f),
                black_box(p),
                &mut out,
            );
            out
        })
    });
}
