//! The robust estimator on the target problem of `docs/robust.md` (100 bearings, 50 %
//! outliers, 0.1° noise, all around a Ladybug-like rig; and the front-hemisphere central
//! scene), and its scaling with the number of bearings and the outlier ratio. Each
//! benchmark cycles through [`PROBLEMS`] different problems, so its figure is the time per
//! frame averaged over them.
use criterion::{BenchmarkId, Criterion};
use std::hint::black_box;
use vgps::fix::{FixOptions, compute_fix};
use vgps::geometry::Pose;
use vgps::robust::{AbsolutePoseOptions, estimate_absolute_pose};
use vgps::synthetic::{RansacProblemConfig, RansacScene, ransac_problem, rng};

/// Problems per benchmark.
const PROBLEMS: usize = 64;

fn problems(config: &RansacProblemConfig, seed: u64) -> Vec<vgps::synthetic::PnpProblem> {
    let mut r = rng(seed);
    (0..PROBLEMS)
        .map(|_| ransac_problem(&mut r, config))
        .collect()
}

/// Benchmarks of `estimate_absolute_pose` and `compute_fix` on many bearings.
pub fn benches(c: &mut Criterion) {
    let mut group = c.benchmark_group("robust");
    for (name, scene) in [
        ("all_around", RansacScene::AllAround),
        ("front_hemisphere", RansacScene::FrontHemisphere),
    ] {
        let config = RansacProblemConfig {
            scene,
            ..RansacProblemConfig::default()
        };
        let set = problems(&config, 1);
        let options = AbsolutePoseOptions {
            sigma_rad: config.sigma_rad,
            ..AbsolutePoseOptions::default()
        };
        let mut k = 0;
        group.bench_function(BenchmarkId::new("estimate_absolute_pose", name), |b| {
            b.iter(|| {
                k = (k + 1) % PROBLEMS;
                let p = &set[k];
                estimate_absolute_pose(
                    black_box(&p.rays_in_rig),
                    black_box(&p.points_in_world),
                    &options,
                )
                .map(|r| r.model)
                .unwrap_or_else(|_| Pose::identity())
            })
        });
        let fix_options = FixOptions {
            sigma_rad: config.sigma_rad,
            ..FixOptions::default()
        };
        let zeros = vec![0.0; config.n_points];
        group.bench_function(BenchmarkId::new("compute_fix", name), |b| {
            b.iter(|| {
                k = (k + 1) % PROBLEMS;
                let p = &set[k];
                compute_fix(
                    black_box(&p.rays_in_rig),
                    black_box(&p.points_in_world),
                    &zeros,
                    &fix_options,
                )
            })
        });
    }
    group.finish();
    // Scaling with the number of bearings and the outlier ratio (all around).
    let mut group = c.benchmark_group("robust_scaling");
    group.sample_size(20);
    for n in [25usize, 50, 100, 200, 400] {
        for outliers in [0.0, 0.3, 0.5, 0.7] {
            let config = RansacProblemConfig {
                n_points: n,
                outlier_fraction: outliers,
                ..RansacProblemConfig::default()
            };
            let set = problems(&config, 2);
            let options = AbsolutePoseOptions {
                sigma_rad: config.sigma_rad,
                ..AbsolutePoseOptions::default()
            };
            let mut k = 0;
            let id = format!("n{n}_outliers{:02}", (outliers * 100.0) as usize);
            group.bench_function(BenchmarkId::new("estimate_absolute_pose", id), |b| {
                b.iter(|| {
                    k = (k + 1) % PROBLEMS;
                    let p = &set[k];
                    estimate_absolute_pose(&p.rays_in_rig, &p.points_in_world, &options)
                        .map(|r| r.model)
                        .unwrap_or_else(|_| Pose::identity())
                })
            });
        }
    }
    group.finish();
}
