//! Times `vgps::solvers::p3p_cosines` on pre-generated problems, for deterministic
//! instruction counts under cachegrind (the criterion benchmark `p3p_cosines` is the
//! reference figure for time).
//!
//! Usage: `cargo run --release --example p3p_cosines_timing -- [N] [SEED] [REPEATS]`
//! (defaults 10000, 1, 1). Problems come from the shared generator
//! `vgps::synthetic::P3pProblem::random_omni` (scene size 50 m), generated before the
//! solves. Instructions per solve:
//! `valgrind --tool=cachegrind --cache-sim=no target/release/examples/p3p_cosines_timing
//! 10000 1 1` once with N and once with N = 0; the difference divided by N.
//! Prints `vgps_p3p_cosines ns_per_solve=<wall, best of REPEATS> mean_solutions=<..>
//! nonfinite=<..>`.
use std::hint::black_box;
use std::time::Instant;
use vgps::synthetic::{P3pProblem, rng};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let repeats: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let solve = args.get(4).is_none_or(|s| s != "generate-only");
    let mut r = rng(seed);
    let problems: Vec<P3pProblem> = (0..n)
        .map(|_| P3pProblem::random_omni(&mut r, 50.0))
        .collect();
    if !solve {
        black_box(&problems);
        return;
    }
    let mut best = f64::INFINITY;
    let mut n_solutions = 0usize;
    let mut nonfinite = 0usize;
    for _ in 0..repeats {
        n_solutions = 0;
        nonfinite = 0;
        let start = Instant::now();
        for p in &problems {
            let s = vgps::solvers::p3p_cosines(
                black_box(&p.bearings_in_rig),
                black_box(&p.points_in_world),
            );
            n_solutions += s.len();
            nonfinite += s
                .iter()
                .filter(|pose| pose.to_homogeneous().iter().any(|e| !e.is_finite()))
                .count();
            black_box(&s);
        }
        let ns = start.elapsed().as_secs_f64() * 1e9 / problems.len().max(1) as f64;
        best = best.min(ns);
    }
    println!(
        "vgps_p3p_cosines ns_per_solve={best:.1} mean_solutions={:.4} nonfinite={nonfinite}",
        n_solutions as f64 / problems.len().max(1) as f64
    );
}
