//! Helpers shared by the command-line integration tests.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `vgps` binary with `args` (no standard input) and collects its output.
pub fn vgps(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vgps"))
        .args(args)
        .output()
        .expect("the vgps binary runs")
}

/// The path of a committed fixture under `tests/fixtures/`.
pub fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
        .to_string_lossy()
        .into_owned()
}
