//! Deterministic cost figure for `vgps::solvers::p3p`: runs the solver through one
//! non-inlined wrapper so that an instruction counter can attribute every instruction of
//! the solve to it.
//!
//! Usage (instructions per solve = inclusive Ir of `solve` / N):
//! ```text
//! cargo build --release --example p3p_instructions
//! valgrind --tool=callgrind --toggle-collect='*p3p_instructions::solve*' \
//!     target/release/examples/p3p_instructions 20000 1 clean
//! ```
//! Arguments: `[N] [SEED] [clean|noisy]` (defaults 20000, 1, clean). Problems come from the
//! shared generator `P3pProblem::random_omni` (scene 50 m; `noisy` adds 0.5° bearing noise).
use std::hint::black_box;
use vgps::geometry::PoseSolutions;
use vgps::synthetic::{P3pProblem, rng};

/// One solve, never inlined: the unit the instruction counter measures.
#[inline(never)]
fn solve(p: &P3pProblem) -> PoseSolutions {
    vgps::solvers::p3p(black_box(&p.bearings_in_rig), black_box(&p.points_in_world))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let noisy = args.get(3).is_some_and(|s| s == "noisy");
    let mut r = rng(seed);
    let mut problems: Vec<P3pProblem> = (0..n)
        .map(|_| P3pProblem::random_omni(&mut r, 50.0))
        .collect();
    if noisy {
        let sigma = 0.5f64.to_radians();
        problems = problems
            .iter()
            .map(|p| p.with_noise(&mut r, sigma))
            .collect();
    }
    let mut n_solutions = 0usize;
    for p in &problems {
        let s = solve(p);
        n_solutions += s.len();
        black_box(&s);
    }
    println!(
        "solves={n} mean_solutions={:.4}",
        n_solutions as f64 / n as f64
    );
}
