//! Mapping: per-observation association + update, per-landmark refinement.
use criterion::{BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use vgps::mapping::{LandmarkMapper, MapRay, MapperOptions, refine_landmark};
use vgps::synthetic::mapping::{DriveConfig, MappingScenario, streetlights_along};

/// Benchmarks of `vgps::mapping`.
pub fn benches(c: &mut Criterion) {
    // A 400 m road with lights every 25 m on both sides (31 lights, ≈ 6 in view per frame).
    let config = DriveConfig::straight(400.0);
    let lights = streetlights_along(&config, 25.0, 6.0, 7.0, true);
    let mut rng = vgps::synthetic::rng(11);
    let sc = MappingScenario::generate(&mut rng, &config, &lights, None);
    let frames = sc.mapping_frames(config.sigma_level_rad);
    let n_obs: usize = frames.iter().map(|f| f.observations.len()).sum();
    let mut group = c.benchmark_group("mapping/drive");
    group.throughput(Throughput::Elements(n_obs as u64));
    group.bench_function("associate_and_update_per_observation", |b| {
        b.iter(|| {
            let mut mapper = LandmarkMapper::new(MapperOptions::default()).unwrap();
            for f in &frames {
                black_box(mapper.add_frame(black_box(f)).unwrap());
            }
            mapper.track_count()
        })
    });
    group.finish();

    let mut group = c.benchmark_group("mapping/refine_landmark");
    for n in [10usize, 40, 160] {
        // Rays of one landmark: the first light, seen from the first frames of the drive.
        let mut one = Vec::new();
        for (f, truth) in frames.iter().zip(&sc.truth) {
            if let Some(k) = truth.iter().position(|&t| t == 0) {
                let o = &f.observations[k];
                one.push(MapRay::from_rig(
                    &f.world_from_rig,
                    &f.pose_covariance,
                    &o.ray_in_rig,
                    o.sigma_rad,
                ));
            }
        }
        let pool: Vec<MapRay> = one.iter().cycle().take(n).copied().collect();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &pool, |b, pool| {
            b.iter(|| refine_landmark(black_box(pool)))
        });
    }
    group.finish();
}
