//! Times `vgps::solvers::p3p` with `std::time::Instant`, for the peer comparison script
//! `bench/peers/p3p_peers.py` (the criterion benchmark `p3p` is the reference figure).
//!
//! Usage: `cargo run --release --example p3p_timing -- [N] [SEED] [REPEATS]`
//! (defaults 100000, 1, 5). Problems come from the shared generator
//! `vgps::synthetic::P3pProblem::random_omni` (scene size 50 m), generated before timing.
//! Prints one line `vgps_p3p ns_per_solve=<wall, best of REPEATS> cpu_ns_per_solve=<thread
//! CPU time, best of REPEATS> mean_solutions=<..> nonfinite=<..>`, then the same for 0.5°
//! bearing noise. On a loaded machine the thread CPU time is the meaningful figure.
use std::hint::black_box;
use std::time::Instant;
use vgps::synthetic::{P3pProblem, rng};

/// CPU time this thread has run, in ns (Linux `/proc/thread-self/schedstat`), so that the
/// figure stays meaningful on a loaded machine where wall time includes waiting to run.
fn thread_cpu_ns() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

fn run(label: &str, problems: &[P3pProblem], repeats: usize) {
    let mut best = f64::INFINITY;
    let mut best_cpu = f64::INFINITY;
    let mut n_solutions = 0usize;
    let mut nonfinite = 0usize;
    for _ in 0..repeats {
        n_solutions = 0;
        nonfinite = 0;
        let cpu_start = thread_cpu_ns();
        let start = Instant::now();
        for p in problems {
            let s =
                vgps::solvers::p3p(black_box(&p.bearings_in_rig), black_box(&p.points_in_world));
            n_solutions += s.len();
            for pose in &s {
                let m = pose.to_homogeneous();
                if m.iter().any(|e| !e.is_finite()) {
                    nonfinite += 1;
                }
            }
            black_box(&s);
        }
        let ns = start.elapsed().as_secs_f64() * 1e9 / problems.len() as f64;
        best = best.min(ns);
        // schedstat advances at scheduler events only: ignore runs it did not see.
        if let (Some(a), Some(b)) = (cpu_start, thread_cpu_ns())
            && b > a
        {
            best_cpu = best_cpu.min((b - a) / problems.len() as f64);
        }
    }
    println!(
        "{label} ns_per_solve={best:.1} cpu_ns_per_solve={best_cpu:.1} mean_solutions={:.3} \
         nonfinite={nonfinite}",
        n_solutions as f64 / problems.len() as f64
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let repeats: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5);
    let mut r = rng(seed);
    let problems: Vec<P3pProblem> = (0..n)
        .map(|_| P3pProblem::random_omni(&mut r, 50.0))
        .collect();
    run("vgps_p3p", &problems, repeats);
    let sigma = 0.5f64.to_radians();
    let noisy: Vec<P3pProblem> = problems
        .iter()
        .map(|p| p.with_noise(&mut r, sigma))
        .collect();
    run("vgps_p3p_noisy_0.5deg", &noisy, repeats);
}
