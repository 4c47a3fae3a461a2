//! A stable-toolchain stand-in for `cargo fuzz` on the image decoders: runs a fuzz body of
//! `vgps::fuzzing` over mutations of its committed seed corpus (`fuzz/corpus/<target>/`),
//! without coverage guidance.
//!
//! Usage: `cargo run --release --example fuzz_mutate -- TARGET [EXECUTIONS] [SEED]`
//! (default 10⁶ executions, seed 1); TARGET is a name of `vgps_fuzz_bodies::TARGETS`
//! (`jpeg_decode`, `tiff_decode`, `bmp_decode`, `png_decode`, …). Each execution takes a
//! seed file (or an earlier mutant that decoded) and applies 1–8 mutations: byte set, bit
//! flip, interesting value (0, 0xFF, 0x7F, 0x80) at a random place, truncation, a copied or
//! deleted run of bytes, insertion of 0xFF marker bytes. A panic is reported with its input
//! written to `fuzz/artifacts/<target>/mutate-<n>`. Prints executions, seconds and panics.
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::Instant;

/// Leading bytes (the format's signature) left alone by 15 of 16 mutations.
const KEEP: usize = 4;

/// The mutation source: ChaCha8, seeded for reproducible runs.
struct Rng(rand_chacha::ChaCha8Rng);

impl Rng {
    fn next(&mut self) -> u64 {
        rand::Rng::next_u64(&mut self.0)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn mutate(rng: &mut Rng, data: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(8) {
        if data.is_empty() {
            data.push(rng.next() as u8);
            continue;
        }
        // Keep the 4-byte signature most of the time, so mutants reach the decoder.
        let keep = if data.len() > KEEP && rng.below(16) != 0 {
            KEEP
        } else {
            0
        };
        let i = keep + rng.below(data.len() - keep);
        match rng.below(7) {
            0 => data[i] = rng.next() as u8,
            1 => data[i] ^= 1 << rng.below(8),
            2 => data[i] = [0, 0xFF, 0x7F, 0x80][rng.below(4)],
            3 => data.truncate(i.max(keep + 1)),
            4 => {
                let len = rng.below(64).min(data.len() - i);
                let run: Vec<u8> = data[i..i + len].to_vec();
                let at = rng.below(data.len());
                data.splice(at..at, run);
            }
            5 => {
                let len = rng.below(32).min(data.len() - i);
                data.drain(i..i + len);
            }
            _ => data.insert(i, 0xFF),
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args
        .first()
        .ok_or("usage: fuzz_mutate TARGET [EXECUTIONS] [SEED]")?;
    let executions: u64 = args.get(1).map_or(Ok(1_000_000), |s| s.parse())?;
    let mut rng = Rng(rand::SeedableRng::seed_from_u64(
        args.get(2).map_or(Ok(1), |s| s.parse())?,
    ));
    let body = vgps_fuzz_bodies::TARGETS
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, b)| *b)
        .ok_or_else(|| format!("no target {name}"))?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut pool: Vec<Vec<u8>> = Vec::new();
    for entry in std::fs::read_dir(root.join("corpus").join(name))? {
        pool.push(std::fs::read(entry?.path())?);
    }
    if pool.is_empty() {
        return Err(format!("empty corpus for {name}").into());
    }
    let seeds = pool.len();
    std::panic::set_hook(Box::new(|_| {}));
    let start = Instant::now();
    let mut panics = 0u64;
    for n in 0..executions {
        let mut input = pool[rng.below(pool.len())].clone();
        mutate(&mut rng, &mut input);
        if catch_unwind(AssertUnwindSafe(|| body(&input))).is_err() {
            panics += 1;
            let dir = root.join("artifacts").join(name);
            std::fs::create_dir_all(&dir)?;
            std::fs::write(dir.join(format!("mutate-{n}")), &input)?;
        } else if pool.len() < seeds + 256 && rng.below(64) == 0 {
            // Keep a few mutants as further starting points.
            pool.push(input);
        }
    }
    println!(
        "{name} executions={executions} seconds={:.1} panics={panics}",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
