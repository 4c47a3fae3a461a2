//! The command implementations behind the `vgps` binary.

pub mod calib;

use clap::Parser;

/// The `vgps` command line (placeholder holding only `calib` on this branch).
#[derive(Debug, Parser)]
#[command(name = "vgps", version, about = "Visual GPS")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Inspect, check, use and convert calibration files.
    Calib(calib::CalibArgs),
}

/// Runs the command line and returns the process exit code.
pub fn main() -> std::process::ExitCode {
    match Cli::parse().command {
        Command::Calib(args) => calib::run(args),
    }
}
