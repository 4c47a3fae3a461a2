//! `vgps::fix::compute_fix`: a whole fix (P3P hypotheses, scoring, refinement, ambiguity
//! check) from n bearings with known correspondences, 0.05° noise, one wrong pairing.
use criterion::Criterion;
use nalgebra::Vector3;
use rand::RngExt;
use vgps::fix::{FixOptions, compute_fix};
use vgps::geometry::{Ray, bearing_in_rig};
use vgps::synthetic::{perturb_bearing, random_pose, random_unit_vector, rng};

/// Benchmarks of `compute_fix` for 8 (every triple) and 20 (random triples) observations.
pub fn benches(c: &mut Criterion) {
    let sigma = 0.05f64.to_radians();
    for n in [8usize, 20] {
        let mut r = rng(n as u64);
        let truth = random_pose(&mut r, 20.0);
        let points: Vec<Vector3<f64>> = (0..n)
            .map(|_| {
                truth.translation.vector + random_unit_vector(&mut r) * r.random_range(10.0..60.0)
            })
            .collect();
        let mut rays: Vec<Ray> = points
            .iter()
            .map(|p| {
                let b = perturb_bearing(&mut r, &bearing_in_rig(&truth, p).unwrap(), sigma);
                Ray::try_new(Vector3::zeros(), b).unwrap()
            })
            .collect();
        rays.swap(0, 1);
        let sigmas = vec![0.02; n];
        let options = FixOptions {
            sigma_rad: sigma,
            ..FixOptions::default()
        };
        c.bench_function(&format!("fix/compute_fix_n{n}"), |b| {
            b.iter(|| compute_fix(&rays, &points, &sigmas, &options).unwrap())
        });
    }
}
