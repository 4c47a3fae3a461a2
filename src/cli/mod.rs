//! The command implementations behind the `vgps` binary.
//!
//! The command line is parsed once ([`args::Cli`], clap) and validated into [`Settings`]
//! ([`settings`]: one settings value per subcommand);
//! each subcommand then runs on those settings, writing its results to `out` and its
//! diagnostics to `err`. `docs/cli.md` documents the subcommands, the file formats, the
//! outputs and the exit codes:
//! - `0`: success (frames or ids without a result are reported in the output, not failures);
//! - `1`: an output error (e.g. stdout closed);
//! - `2`: a usage error or an invalid input file (the message names file, line and field).

pub mod args;
pub mod calib;
pub mod calib_file_info;
pub mod demo;
pub mod detect;
pub mod gnss_input;
pub mod image_size;
pub mod import;
pub mod landmarks;
pub mod locate;
pub mod map;
pub mod replay;
pub mod robot_out;
pub mod settings;
pub mod simulate;
pub mod triangulate;
pub mod value_enums;

pub use args::{Cli, PriorArg};
pub use settings::{
    CalibSettings, DemoSettings, DetectSettings, LandmarksSettings, LocateSettings, MapSettings,
    ReplaySettings, Settings, SimulateSettings, TriangulateSettings,
};

use clap::Parser;
use std::ffi::OsString;
use std::io::Write;
use std::process::ExitCode;
use vgps_io::InputError;

/// Exit code of a usage error or an invalid input.
pub const EXIT_INPUT: u8 = 2;
/// Exit code of an output error.
pub const EXIT_OUTPUT: u8 = 1;

/// Errors of the commands.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// An input file is invalid (names the file, line and field).
    #[error(transparent)]
    Input(#[from] InputError),
    /// The calibration file could not be loaded.
    #[error("{0}")]
    Calibration(String),
    /// An internal inconsistency (a bug: please report it).
    #[error("internal error: {0}")]
    Internal(String),
    /// Writing the output failed.
    #[error("cannot write the output: {0}")]
    Output(#[from] std::io::Error),
}

impl CliError {
    /// The process exit code of this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::Input(_) | Self::Calibration(_) => EXIT_INPUT,
            Self::Output(_) | Self::Internal(_) => EXIT_OUTPUT,
        }
    }
}

/// Runs the command line and returns the process exit code.
pub fn main() -> ExitCode {
    let stdout = std::io::stdout();
    let stderr = std::io::stderr();
    run(std::env::args_os(), &mut stdout.lock(), &mut stderr.lock())
}

/// Parses `args` (the first is the program name), runs the command and returns the exit
/// code; results go to `out`, diagnostics to `err` (`vgps calib` writes to the process's
/// stdout and stderr itself).
pub fn run<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let code = u8::try_from(e.exit_code()).unwrap_or(EXIT_INPUT);
            let sink: &mut dyn Write = if e.use_stderr() { err } else { out };
            // Nothing more can be reported if even this write fails.
            let _ = write!(sink, "{}", e.render());
            return ExitCode::from(code);
        }
    };
    let settings = Settings::try_from(cli);
    if let Ok(Settings::Calib(s)) = &settings {
        return calib::run(s);
    }
    let result = settings.and_then(|settings| match settings {
        Settings::Locate(s) => locate::run(&s, out, err),
        Settings::Triangulate(s) => triangulate::run(&s, out, err),
        Settings::Demo(s) => demo::run(&s, out, err),
        Settings::Simulate(s) => simulate::run(&s, out),
        Settings::Replay(s) => replay::run(&s, out, err),
        Settings::Detect(s) => detect::run(&s, out, err),
        Settings::Map(s) => map::run(&s, out, err),
        Settings::Landmarks(a) => landmarks::run(&a, out, err),
        Settings::Import(a) => import::run(&a, out, err),
        // Handled above: `vgps calib` reports on its own.
        Settings::Calib(_) => Ok(()),
    });
    match result.and_then(|()| out.flush().map_err(CliError::from)) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader went away (`vgps locate … | head`): stop quietly, as Unix tools do.
        Err(CliError::Output(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            let _ = writeln!(err, "vgps: error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
