//! `vgps demo [--out DIR]`: the main job end to end on the bundled reference drive.
//!
//! Simulates the reference drive (`vgps simulate --preset reference --seed 1`: deterministic,
//! under a second) into `DIR/reference`, replays it (`vgps replay`) into `DIR/replay`, and prints
//! the summary table and where the report is. The drive is written anew each time (the same
//! seed gives the same bytes), so the demo never depends on a stale copy.

use super::CliError;
use super::replay::{OutputFormat, ReplayArgs};
use crate::simulate::{Preset, Scenario, simulate};
use std::io::Write;
use std::path::PathBuf;

/// Default output directory of the demo (relative to the working directory).
pub const DEFAULT_DEMO_DIR: &str = "vgps-demo";
/// Seed of the demo's reference drive.
pub const DEMO_SEED: u64 = 1;

/// Arguments of `vgps demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Output directory: the drive goes to `DIR/reference`, the report to `DIR/replay`.
    #[arg(long, default_value = DEFAULT_DEMO_DIR)]
    pub out: PathBuf,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: OutputFormat,
}

/// Runs `vgps demo`.
///
/// # Errors
/// [`CliError::Output`] when the drive or the report cannot be written; the replay's errors.
pub fn run(args: &DemoArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<(), CliError> {
    let drive_dir = args.out.join("reference");
    let started = std::time::Instant::now();
    let drive = simulate(&Scenario::preset(Preset::Reference, DEMO_SEED))
        .map_err(|e| CliError::Internal(format!("the reference drive: {e}")))?;
    drive
        .write(&drive_dir)
        .map_err(|e| CliError::Output(std::io::Error::other(e.to_string())))?;
    if args.format == OutputFormat::Text {
        writeln!(
            out,
            "vgps demo: simulated the reference drive ({} frames, {:.0} m) into {} in {:.1} s; replaying…",
            drive.frames.len(),
            drive.frames.last().map_or(0.0, |f| f.arc_m),
            drive_dir.display(),
            started.elapsed().as_secs_f64()
        )?;
    }
    let replay = ReplayArgs {
        drive: drive_dir,
        out: Some(args.out.join("replay")),
        threads: None,
        quiet: false,
        format: args.format,
        strict: true,
        pixel_sigma_px: crate::localizer::DEFAULT_PIXEL_SIGMA_PX,
        no_surrogates: false,
        no_gnss_prior: false,
        from_images: false,
        gnss: Default::default(),
    };
    super::replay::run(&replay, out, err)?;
    if args.format == OutputFormat::Text {
        writeln!(
            out,
            "vgps demo: done in {:.1} s",
            started.elapsed().as_secs_f64()
        )?;
    }
    Ok(())
}
