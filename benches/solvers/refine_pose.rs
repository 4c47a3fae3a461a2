//! `refine_pose` on 10, 50 and 100 correspondences, central and non-central (Ladybug-like)
//! rigs, one-pixel noise, started 0.3 m and 1° from the truth.
use criterion::{BenchmarkId, Criterion};
use std::hint::black_box;
use vgps::solvers::refine_pose::{DEFAULT_SIGMA_RAD, RefineOptions, RobustLoss, refine_pose};
use vgps::synthetic::pnp::{PnpConfig, PnpProblem, RigModel, perturb_pose};

/// Benchmarks of the pose refinement.
pub fn benches(c: &mut Criterion) {
    let mut group = c.benchmark_group("refine_pose");
    for (rig_name, rig) in [
        ("central", RigModel::Central),
        ("ladybug", RigModel::Ladybug),
    ] {
        for n in [10, 50, 100] {
            let mut rng = vgps::synthetic::rng(n as u64);
            let config = PnpConfig {
                n_points: n,
                rig: rig.clone(),
                sigma_rad: DEFAULT_SIGMA_RAD,
                ..PnpConfig::default()
            };
            let problem = PnpProblem::generate(&mut rng, &config);
            let start = perturb_pose(&mut rng, &problem.world_from_rig, 0.3, 1f64.to_radians());
            let options = RefineOptions::default();
            group.bench_with_input(BenchmarkId::new(rig_name, n), &n, |b, _| {
                b.iter(|| {
                    refine_pose(
                        black_box(&start),
                        black_box(&problem.rays_in_rig),
                        black_box(&problem.points_in_world),
                        &options,
                    )
                })
            });
        }
    }
    // Robust loss with 20 % outliers, 50 correspondences.
    let mut rng = vgps::synthetic::rng(7);
    let config = PnpConfig {
        n_points: 50,
        rig: RigModel::Ladybug,
        sigma_rad: DEFAULT_SIGMA_RAD,
        outlier_fraction: 0.2,
        ..PnpConfig::default()
    };
    let problem = PnpProblem::generate(&mut rng, &config);
    let start = perturb_pose(&mut rng, &problem.world_from_rig, 0.3, 1f64.to_radians());
    let options = RefineOptions {
        loss: RobustLoss::Cauchy {
            scale_rad: 2.0 * DEFAULT_SIGMA_RAD,
        },
        ..RefineOptions::default()
    };
    group.bench_function("ladybug_cauchy_20pct_outliers/50", |b| {
        b.iter(|| {
            refine_pose(
                black_box(&start),
                black_box(&problem.rays_in_rig),
                black_box(&problem.points_in_world),
                &options,
            )
        })
    });
    group.finish();
}
