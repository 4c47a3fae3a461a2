//! Deterministic cost figure for `vgps::triangulation::triangulate_rays`: runs the solver
//! through one non-inlined wrapper so that an instruction counter can attribute every
//! instruction of the solve to it.
//!
//! Usage (instructions per solve = inclusive Ir of `solve` / N):
//! ```text
//! cargo build --release --example triangulate_rays_instructions
//! valgrind --tool=callgrind --toggle-collect='*triangulate_rays_instructions::solve*' \
//!     target/release/examples/triangulate_rays_instructions 1000 10
//! ```
//! Arguments: `[N] [RAYS] [SEED]` (defaults 1000, 10, 3). Problems come from the shared
//! generator `RayProblem::around` (ranges 5–80 m, σ_pos 0.1 m, σ_ang 2 mrad, noisy rays),
//! as in the `triangulation/rays` criterion benchmark.
use std::hint::black_box;
use vgps::synthetic::rays::RayProblem;
use vgps::triangulation::{
    RayObservation, TriangulatedPoint, TriangulationError, triangulate_rays,
};

/// One solve, never inlined: the unit the instruction counter measures.
#[inline(never)]
fn solve(obs: &[RayObservation]) -> Result<TriangulatedPoint, TriangulationError> {
    triangulate_rays(black_box(obs))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1_000);
    let rays: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10);
    let seed: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let mut r = vgps::synthetic::rng(seed);
    let problems: Vec<Vec<RayObservation>> = (0..n)
        .map(|_| RayProblem::around(&mut r, rays, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut r))
        .collect();
    let mut ok = 0usize;
    for p in &problems {
        let s = solve(p);
        ok += usize::from(s.is_ok());
        black_box(&s);
    }
    println!("solves={n} rays={rays} ok={ok}");
}
