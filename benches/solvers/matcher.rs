//! `vgps::matcher::match_detections` on the synthetic city: one frame of 20 detections (30 %
//! false) with a 30 m prior, generic and with a known vertical, and a cold start over 1 km².
use criterion::Criterion;
use nalgebra::Vector3;
use vgps::geometry::Ray;
use vgps::matcher::{Detection, MatchOptions, SearchArea, match_detections};
use vgps::synthetic::matcher::{CityConfig, CityWorld, FrameConfig, RIG_HEIGHT_M};
use vgps::synthetic::rng;

/// Benchmarks of the matcher with a prior (generic, known vertical) and a cold start.
pub fn benches(c: &mut Criterion) {
    let mut r = rng(7);
    let config = FrameConfig::default();
    for (name, city) in [
        ("prior30", CityConfig::default()),
        ("cold_1km2", CityConfig::sparse()),
    ] {
        let world = CityWorld::generate(&mut r, &city);
        let db = world.landmark_db().unwrap();
        let pose = world.random_rig_pose(&mut r);
        let frame = world.frame(&mut r, &pose, &config);
        let detections: Vec<Detection> = frame
            .detections
            .iter()
            .map(|b| Detection::new(Ray::try_new(Vector3::zeros(), *b).unwrap()))
            .collect();
        let area = if name == "prior30" {
            SearchArea::around(
                &(pose.translation.vector + Vector3::new(12.0, -9.0, 0.0)),
                30.0,
                1.0,
            )
        } else {
            SearchArea::over_landmarks(&db, 0.0, RIG_HEIGHT_M - 1.0, RIG_HEIGHT_M + 1.0)
        }
        .unwrap();
        let generic = MatchOptions {
            sigma_rad: config.sigma_rad,
            ..MatchOptions::default()
        };
        let up = MatchOptions {
            up_in_rig: Some((Vector3::z(), 4.0f64.to_radians())),
            ..generic
        };
        let mut group = c.benchmark_group("matcher");
        group.sample_size(10);
        if name == "prior30" {
            group.bench_function(format!("{name}_generic"), |b| {
                b.iter(|| match_detections(&db, &detections, &area, &generic).unwrap())
            });
        }
        group.bench_function(format!("{name}_up4deg"), |b| {
            b.iter(|| match_detections(&db, &detections, &area, &up).unwrap())
        });
        group.finish();
    }
}
