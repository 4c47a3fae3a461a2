//! Triangulation: two-ray intersection per vertex, and the projector-sum estimator per ray.
use criterion::{BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use vgps::synthetic::rays::{DriveBy, RayProblem};
use vgps::triangulation::{
    RaySum, intersect_two_rays, triangulate_rays, triangulate_rays_weighted,
};

/// Number of pre-generated problems cycled through (defeats branch-history memorisation).
const POOL: usize = 256;

/// Benchmarks of `vgps::triangulation`.
pub fn benches(c: &mut Criterion) {
    let mut rng = vgps::synthetic::rng(3);
    let pairs: Vec<_> = (0..POOL)
        .map(|_| {
            let p = RayProblem::drive_by(&mut rng, 2, &DriveBy::streetlight(), 0.1, 1e-3);
            let o = p.noisy_observations(&mut rng);
            (o[0].ray, o[1].ray)
        })
        .collect();
    let mut i = 0;
    c.bench_function("triangulation/intersect_two_rays", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (a, r) = &pairs[i];
            intersect_two_rays(black_box(a), black_box(r))
        })
    });

    let mut group = c.benchmark_group("triangulation/rays");
    for n in [2usize, 10, 100] {
        let pool: Vec<_> = (0..POOL)
            .map(|_| {
                RayProblem::around(&mut rng, n, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut rng)
            })
            .collect();
        group.throughput(Throughput::Elements(n as u64));
        let mut i = 0;
        group.bench_with_input(BenchmarkId::new("triangulate_rays", n), &pool, |b, pool| {
            b.iter(|| {
                i = (i + 1) % POOL;
                triangulate_rays(black_box(&pool[i]))
            })
        });
        group.bench_with_input(
            BenchmarkId::new("triangulate_rays_weighted", n),
            &pool,
            |b, pool| {
                b.iter(|| {
                    i = (i + 1) % POOL;
                    triangulate_rays_weighted(black_box(&pool[i]))
                })
            },
        );
        group.bench_with_input(
            BenchmarkId::new("ray_sum_add_solve", n),
            &pool,
            |b, pool| {
                b.iter(|| {
                    i = (i + 1) % POOL;
                    let mut sum = RaySum::new();
                    for o in black_box(&pool[i]) {
                        let _ = sum.add(o);
                    }
                    sum.solve()
                })
            },
        );
    }
    group.finish();
}
