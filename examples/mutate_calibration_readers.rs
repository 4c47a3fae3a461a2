//! Runs the fuzz bodies of the Ladybug `.conf` and INI readers (`vgps_fuzz_bodies::ladybug_conf`,
//! `vgps_fuzz_bodies::ladybug_ini`) over many mutated copies of their seeds, on stable: the
//! stand-in for `cargo +nightly fuzz run` when the sanitized build is out of reach. A body
//! panics when an invariant breaks; this counts the executions and stops at the first
//! panic (printing the input's file name after saving it).
//!
//! ```text
//! cargo run --release --example mutate_calibration_readers -- [EXECUTIONS] [SEED]
//! ```

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

const TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "0",
    "-0",
    "1e-320",
    "4294967295",
    "99999999999",
    "BeginWarp",
    "EndWarp",
    "BeginCamera",
    "EndCamera",
    "Id 0",
    "Coefs",
    "NumberCoefs 0 0",
    "KnotsX 1 0",
    "Version \"Ladybug 2.0\"",
    "Resolution 0 0",
    "NumCameras 64",
    "=",
    ".",
    "#",
    "\u{0}",
    "\u{feff}",
    "é",
    "rotation_dRx = 1e300",
    "camera0.rotX nan",
    "camera_model LD5P",
];

fn mutate(rng: &mut ChaCha8Rng, seed: &[u8]) -> Vec<u8> {
    let mut data = seed.to_vec();
    let edits = 1 + rng.random_range(0..8);
    for _ in 0..edits {
        if data.is_empty() {
            data.extend_from_slice(TOKENS[rng.random_range(0..TOKENS.len())].as_bytes());
            continue;
        }
        let at = rng.random_range(0..data.len());
        match rng.random_range(0..7) {
            0 => data[at] = rng.random(),
            1 => {
                data.remove(at);
            }
            2 => {
                let t = TOKENS[rng.random_range(0..TOKENS.len())].as_bytes();
                data.splice(at..at, t.iter().copied());
            }
            3 => {
                // Replace the number (or word) at `at` by a token.
                let start = data[..at]
                    .iter()
                    .rposition(|b| b.is_ascii_whitespace())
                    .map_or(0, |p| p + 1);
                let end = data[at..]
                    .iter()
                    .position(|b| b.is_ascii_whitespace())
                    .map_or(data.len(), |p| at + p);
                let t = TOKENS[rng.random_range(0..TOKENS.len())].as_bytes();
                data.splice(start..end, t.iter().copied());
            }
            4 => {
                // Delete or duplicate a whole line.
                let start = data[..at]
                    .iter()
                    .rposition(|&b| b == b'\n')
                    .map_or(0, |p| p + 1);
                let end = data[at..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(data.len(), |p| at + p + 1);
                if rng.random() {
                    data.drain(start..end);
                } else {
                    let line: Vec<u8> = data[start..end].to_vec();
                    data.splice(end..end, line);
                }
            }
            5 => data.truncate(at),
            _ => {
                // A digit changed (keeps the text parseable, moves the numbers).
                if data[at].is_ascii_digit() {
                    data[at] = b'0' + rng.random_range(0..10u8);
                }
            }
        }
    }
    data
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let executions: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let seed: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(23);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let read = |p: &str| std::fs::read(root.join(p)).unwrap_or_else(|e| panic!("{p}: {e}"));
    let conf_seeds = [
        read("fuzz/corpus/ladybug_conf/one_camera_64x48.conf"),
        read("tests/data/ladybug5p/ladybug5p.conf"),
    ];
    let ini_seeds = [
        read("fuzz/corpus/ladybug_ini/ladybug_dotted_rotation.ini"),
        read("fuzz/corpus/ladybug_ini/ladybug_64x48.ini"),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let started = std::time::Instant::now();
    let (mut conf_runs, mut ini_runs, mut real_runs) = (0u64, 0u64, 0u64);
    for k in 0..executions {
        let (body, input): (fn(&[u8]), Vec<u8>) = if k % 2 == 0 {
            // One in 200 `.conf` inputs is a mutation of the real 340 kB file.
            let real = rng.random_range(0..200) == 0;
            if real {
                real_runs += 1;
            }
            conf_runs += 1;
            (
                vgps_fuzz_bodies::ladybug_conf,
                mutate(&mut rng, &conf_seeds[usize::from(real)]),
            )
        } else {
            ini_runs += 1;
            let s = &ini_seeds[rng.random_range(0..2)];
            (vgps_fuzz_bodies::ladybug_ini, mutate(&mut rng, s))
        };
        if std::panic::catch_unwind(|| body(&input)).is_err() {
            let name = format!("mutate-crash-{seed}-{k}.bin");
            let _ = std::fs::write(&name, &input);
            eprintln!("panic on execution {k}; input saved to {name}");
            std::process::exit(1);
        }
    }
    println!(
        "{executions} executions ({conf_runs} .conf of which {real_runs} from the real file, \
         {ini_runs} INI), 0 panics, {:.1} s",
        started.elapsed().as_secs_f64()
    );
}
