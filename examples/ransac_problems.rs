//! Robust-pose problems for the peer comparison (`bench/peers/ransac_peers.py`).
//!
//! ```text
//! cargo run --release --example ransac_problems -- generate N SEED FILE [MIN_RANGE MAX_RANGE]
//! cargo run --release --example ransac_problems -- solve FILE
//! cargo run --release --example ransac_problems -- scale SEED
//! ```
//!
//! `generate` writes N problems of each scene of `vgps::synthetic::robust` (the target
//! problem: 100 bearings, 50 % outliers, 0.1° noise) as JSON: per problem the true
//! `world_from_rig` (row-major rotation, translation), the ray origins and directions (rig
//! frame), the world points, the observing camera and the inlier mask; per scene the
//! cameras (centre, axis). `solve` reads such a file and, for every problem, times one
//! `estimate_absolute_pose` and one `compute_fix` (std::time::Instant, after one untimed
//! pass over all problems) and prints JSON: per scene the times (ms) and position errors (m).
//! `scale` prints a Markdown table of the median time per frame and iterations of
//! `estimate_absolute_pose` against the number of bearings and the outlier ratio.
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};
use serde_json::{Value, json};
use std::time::Instant;
use vgps::fix::{FixOptions, FixStatus, compute_fix};
use vgps::geometry::{Pose, Ray};
use vgps::robust::{AbsolutePoseOptions, estimate_absolute_pose};
use vgps::synthetic::pnp::ladybug_cameras;
use vgps::synthetic::{self, RansacProblemConfig, RansacScene, ransac_problem};

const SCENES: [(&str, RansacScene); 2] = [
    ("all_around", RansacScene::AllAround),
    ("front_hemisphere", RansacScene::FrontHemisphere),
];

fn v3(v: &Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

fn parse_v3(v: &Value) -> Vector3<f64> {
    let a: Vec<f64> = serde_json::from_value(v.clone()).expect("a 3-vector");
    Vector3::new(a[0], a[1], a[2])
}

fn generate(n: usize, seed: u64, file: &str, ranges: Option<(f64, f64)>) {
    let mut out = serde_json::Map::new();
    let base = RansacProblemConfig::default();
    let (min_range_m, max_range_m) = ranges.unwrap_or((base.min_range_m, base.max_range_m));
    out.insert("sigma_rad".into(), json!(base.sigma_rad));
    out.insert("min_range_m".into(), json!(min_range_m));
    out.insert("max_range_m".into(), json!(max_range_m));
    for (name, scene) in SCENES {
        let config = RansacProblemConfig {
            scene,
            min_range_m,
            max_range_m,
            ..base
        };
        let mut rng = synthetic::rng(seed);
        let problems: Vec<Value> = (0..n)
            .map(|_| {
                let p = ransac_problem(&mut rng, &config);
                let r = p.world_from_rig.rotation.matrix();
                json!({
                    "rotation": (0..3).flat_map(|i| (0..3).map(move |j| r[(i, j)])).collect::<Vec<f64>>(),
                    "translation": v3(&p.world_from_rig.translation.vector),
                    "origins": p.rays_in_rig.iter().map(|r| v3(&r.origin)).collect::<Vec<_>>(),
                    "directions": p.rays_in_rig.iter().map(|r| v3(&r.direction)).collect::<Vec<_>>(),
                    "points": p.points_in_world.iter().map(v3).collect::<Vec<_>>(),
                    "camera": p.camera_of_point,
                    "inliers": p.inliers,
                })
            })
            .collect();
        let cameras: Vec<Value> = match scene {
            RansacScene::AllAround => ladybug_cameras()
                .iter()
                .map(|c| json!({"centre": v3(&c.centre_in_rig), "axis": v3(&c.axis_in_rig)}))
                .collect(),
            RansacScene::FrontHemisphere => {
                vec![json!({"centre": [0.0, 0.0, 0.0], "axis": [0.0, 0.0, 1.0]})]
            }
        };
        out.insert(
            name.into(),
            json!({"cameras": cameras, "problems": problems}),
        );
    }
    std::fs::write(
        file,
        serde_json::to_string(&Value::Object(out)).expect("json"),
    )
    .expect("write the problem file");
}

struct Problem {
    truth: Pose,
    rays: Vec<Ray>,
    points: Vec<Vector3<f64>>,
    /// The true inliers.
    inliers: Vec<bool>,
}

/// The maximum-likelihood pose on the true inliers (angular least squares, started at the
/// truth): the reference an estimator that finds the inliers cannot beat on average.
fn ml_on_true_inliers(p: &Problem, sigma_rad: f64) -> Option<Pose> {
    let idx: Vec<usize> = (0..p.rays.len()).filter(|&i| p.inliers[i]).collect();
    let rays: Vec<Ray> = idx.iter().map(|&i| p.rays[i]).collect();
    let points: Vec<Vector3<f64>> = idx.iter().map(|&i| p.points[i]).collect();
    let options = vgps::solvers::RefineOptions {
        sigma_rad,
        ..Default::default()
    };
    vgps::solvers::refine_pose(&p.truth, &rays, &points, &options)
        .ok()
        .map(|r| r.world_from_rig)
}

fn parse_problem(p: &Value) -> Problem {
    let r: Vec<f64> = serde_json::from_value(p["rotation"].clone()).expect("rotation");
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(&r));
    let truth = Pose::from_parts(Translation3::from(parse_v3(&p["translation"])), rotation);
    let origins = p["origins"].as_array().expect("origins");
    let directions = p["directions"].as_array().expect("directions");
    let rays = origins
        .iter()
        .zip(directions)
        .map(|(o, d)| Ray::try_new(parse_v3(o), parse_v3(d)).expect("a valid ray"))
        .collect();
    let points = p["points"]
        .as_array()
        .expect("points")
        .iter()
        .map(parse_v3)
        .collect();
    let inliers: Vec<bool> = serde_json::from_value(p["inliers"].clone()).expect("inliers");
    Problem {
        truth,
        rays,
        points,
        inliers,
    }
}

fn solve(file: &str) {
    let text = std::fs::read_to_string(file).expect("read the problem file");
    let root: Value = serde_json::from_str(&text).expect("json");
    let sigma_rad = root["sigma_rad"].as_f64().expect("sigma_rad");
    let ransac_options = AbsolutePoseOptions {
        sigma_rad,
        ..AbsolutePoseOptions::default()
    };
    let fix_options = FixOptions {
        sigma_rad,
        ..FixOptions::default()
    };
    let mut out = serde_json::Map::new();
    for (name, _) in SCENES {
        let problems: Vec<Problem> = root[name]["problems"]
            .as_array()
            .expect("problems")
            .iter()
            .map(parse_problem)
            .collect();
        // Warm-up pass.
        for p in &problems {
            let _ = estimate_absolute_pose(&p.rays, &p.points, &ransac_options);
        }
        let zeros = vec![0.0; problems.first().map_or(0, |p| p.rays.len())];
        let (mut ransac_ms, mut ransac_err, mut iterations) = (vec![], vec![], vec![]);
        let (mut fix_ms, mut fix_err, mut fix_ok) = (vec![], vec![], vec![]);
        let (mut ml_err, mut fix_wrong_inliers) = (vec![], vec![]);
        for p in &problems {
            ml_err.push(
                ml_on_true_inliers(p, sigma_rad)
                    .map_or(f64::INFINITY, |m| synthetic::pose_error(&m, &p.truth).0),
            );
            let start = Instant::now();
            let result = estimate_absolute_pose(&p.rays, &p.points, &ransac_options);
            ransac_ms.push(start.elapsed().as_secs_f64() * 1e3);
            match result {
                Ok(r) => {
                    ransac_err.push(synthetic::pose_error(&r.model, &p.truth).0);
                    iterations.push(r.iterations);
                }
                Err(_) => {
                    ransac_err.push(f64::INFINITY);
                    iterations.push(0);
                }
            }
            let start = Instant::now();
            let fix = compute_fix(&p.rays, &p.points, &zeros[..p.rays.len()], &fix_options);
            fix_ms.push(start.elapsed().as_secs_f64() * 1e3);
            fix_wrong_inliers.push(fix.as_ref().map_or(0, |f| {
                f.inliers
                    .iter()
                    .zip(&p.inliers)
                    .filter(|(a, b)| a != b)
                    .count()
            }));
            let estimate = fix
                .ok()
                .filter(|f| f.status == FixStatus::Ok)
                .and_then(|f| f.estimate);
            fix_ok.push(estimate.is_some());
            fix_err.push(estimate.map_or(f64::INFINITY, |e| {
                synthetic::pose_error(&e.world_from_rig, &p.truth).0
            }));
        }
        // JSON has no infinity: failures are null.
        let finite = |v: Vec<f64>| -> Vec<Value> {
            v.into_iter()
                .map(|x| if x.is_finite() { json!(x) } else { Value::Null })
                .collect()
        };
        out.insert(
            name.into(),
            json!({
                "ransac_ms": ransac_ms,
                "ransac_err_m": finite(ransac_err),
                "ransac_iterations": iterations,
                "fix_ms": fix_ms,
                "fix_err_m": finite(fix_err),
                "fix_ok": fix_ok,
                "fix_inliers_differing": fix_wrong_inliers,
                "ml_err_m": finite(ml_err),
            }),
        );
    }
    println!("{}", Value::Object(out));
}

/// Median time per frame (ms) and median iterations of `estimate_absolute_pose` over 64
/// all-around problems per number of bearings and outlier ratio, as a Markdown table.
fn scale(seed: u64) {
    let ns = [25usize, 50, 100, 200, 400];
    let ratios = [0.0, 0.3, 0.5, 0.7];
    println!(
        "| bearings | {} |",
        ratios
            .iter()
            .map(|r| format!("{:.0} % outliers", r * 100.0))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---|{}", "---|".repeat(ratios.len()));
    for n in ns {
        let mut cells = Vec::new();
        for outlier_fraction in ratios {
            let config = RansacProblemConfig {
                n_points: n,
                outlier_fraction,
                ..RansacProblemConfig::default()
            };
            let mut rng = synthetic::rng(seed);
            let problems: Vec<_> = (0..64).map(|_| ransac_problem(&mut rng, &config)).collect();
            let options = AbsolutePoseOptions {
                sigma_rad: config.sigma_rad,
                ..AbsolutePoseOptions::default()
            };
            for p in &problems {
                let _ = estimate_absolute_pose(&p.rays_in_rig, &p.points_in_world, &options);
            }
            let mut ms = Vec::new();
            let mut iterations = Vec::new();
            for p in &problems {
                let start = Instant::now();
                let r = estimate_absolute_pose(&p.rays_in_rig, &p.points_in_world, &options);
                ms.push(start.elapsed().as_secs_f64() * 1e3);
                iterations.push(r.map_or(0, |r| r.iterations));
            }
            ms.sort_by(f64::total_cmp);
            iterations.sort_unstable();
            cells.push(format!("{:.3} ms ({} it.)", ms[32], iterations[32]));
        }
        println!("| {n} | {} |", cells.join(" | "));
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: ransac_problems generate N SEED FILE [MIN_RANGE MAX_RANGE] | solve FILE | scale SEED";
    match args.get(1).map(String::as_str) {
        Some("generate") if args.len() == 5 || args.len() == 7 => {
            let n = args[2].parse().expect("N");
            let seed = args[3].parse().expect("SEED");
            let ranges = (args.len() == 7).then(|| {
                (
                    args[5].parse().expect("MIN_RANGE"),
                    args[6].parse().expect("MAX_RANGE"),
                )
            });
            generate(n, seed, &args[4], ranges);
        }
        Some("solve") if args.len() == 3 => solve(&args[2]),
        Some("scale") if args.len() == 3 => scale(args[2].parse().expect("SEED")),
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    }
}
