//! `vgps replay`'s outputs for a robot stack: the live NMEA stream for gpsd
//! (`--nmea-tcp HOST:PORT`, paced by `--pace`) and the ROS 2 messages as an MCAP file
//! (`--mcap FILE`). Neither can stop a replay: a stream that cannot listen, a client that
//! leaves, no client at all are messages on stderr, and the replay's files are written.

use super::value_enums::PaceArg;
use std::io::Write;
use std::path::PathBuf;
use vgps_replay::live::{NmeaTcpServer, Pacer};
use vgps_replay::report::{DriveInfo, FrameOutcome};

/// The robot-stack options of `vgps replay`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RobotOutputArgs {
    /// Serve the fixes as NMEA 0183 on a TCP port while replaying (gpsd reads it with
    /// `gpsd -n tcp://HOST:PORT`); see docs/gpsd.md.
    #[arg(long, value_name = "HOST:PORT")]
    pub nmea_tcp: Option<String>,
    /// Pace of the live stream: `real` sends each frame at the drive's own time, `fast` as
    /// soon as it is localized.
    #[arg(long, value_enum, default_value = "real")]
    pub pace: PaceArg,
    /// Before the first frame, wait up to this many seconds for a client of the live
    /// stream (gpsd started after vgps then gets every fix); 0 does not wait.
    #[arg(long, value_name = "S", default_value_t = 0.0, value_parser = super::args::parse_non_negative, requires = "nmea_tcp", allow_hyphen_values = true)]
    pub nmea_wait_client: f64,
    /// Also write the fixes as ROS 2 messages (NavSatFix, PoseWithCovarianceStamped, Imu)
    /// into this MCAP file; see docs/ros2.md.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
}

/// The live stream of a replay, if one was asked for and could listen.
pub struct LiveStream {
    server: Option<NmeaTcpServer>,
    pacer: Pacer,
    address: String,
}

impl LiveStream {
    /// Starts listening (a failure is a warning on `err`: the replay goes on without it).
    pub fn start(args: &RobotOutputArgs, err: &mut dyn Write) -> Self {
        let address = args.nmea_tcp.clone().unwrap_or_default();
        let server = args
            .nmea_tcp
            .as_deref()
            .and_then(|a| match NmeaTcpServer::bind(a) {
                Ok(s) => {
                    let _ = writeln!(
                        err,
                        "vgps: nmea-tcp: serving NMEA on {} (gpsd -n tcp://{})",
                        s.local_addr(),
                        s.local_addr()
                    );
                    if args.nmea_wait_client > 0.0 {
                        wait_for_a_client(&s, args.nmea_wait_client, err);
                    }
                    Some(s)
                }
                Err(e) => {
                    let _ = writeln!(
                        err,
                        "vgps: warning: --nmea-tcp: {e}; the replay goes on without the live stream"
                    );
                    None
                }
            });
        Self {
            server,
            pacer: Pacer::new(args.pace.into()),
            address,
        }
    }

    /// Sends one frame at its time (nothing without a stream).
    pub fn send(&mut self, record: &FrameOutcome, err: &mut dyn Write) {
        let Some(server) = &mut self.server else {
            return;
        };
        self.pacer.wait_until_due(record.time_s);
        server.send(record.time_s, record.visual.as_ref());
        for m in server.take_messages() {
            let _ = writeln!(err, "vgps: nmea-tcp: {m}");
        }
    }

    /// Closes the stream, saying so when no client ever connected.
    pub fn finish(self, err: &mut dyn Write) {
        let Some(mut server) = self.server else {
            return;
        };
        for m in server.take_messages() {
            let _ = writeln!(err, "vgps: nmea-tcp: {m}");
        }
        if server.clients_ever() == 0 {
            let _ = writeln!(
                err,
                "vgps: warning: --nmea-tcp {}: no client connected during the replay (is gpsd running with tcp://{}?)",
                self.address,
                server.local_addr()
            );
        } else {
            let _ = writeln!(
                err,
                "vgps: nmea-tcp: {} frame(s) sent to {} client(s)",
                server.frames_sent(),
                server.clients_ever()
            );
        }
    }
}

/// Waits up to `seconds` for the stream's first client, saying so; the replay goes on
/// either way.
fn wait_for_a_client(server: &NmeaTcpServer, seconds: f64, err: &mut dyn Write) {
    let _ = writeln!(
        err,
        "vgps: nmea-tcp: waiting up to {seconds} s for a client before the first frame"
    );
    // Bounded so that a huge value cannot overflow a Duration: a day is longer than any wait.
    let timeout = std::time::Duration::from_secs_f64(seconds.min(86_400.0));
    if !server.wait_for_clients(1, timeout) {
        let _ = writeln!(
            err,
            "vgps: warning: --nmea-tcp {}: no client after {seconds} s; the replay goes on",
            server.local_addr()
        );
    }
}

/// Writes the MCAP file if one was asked for.
///
/// # Errors
/// [`super::CliError::Output`] naming the file when it cannot be written.
pub fn write_mcap(
    args: &RobotOutputArgs,
    drive: &DriveInfo,
    records: &[FrameOutcome],
) -> Result<(), super::CliError> {
    let Some(path) = &args.mcap else {
        return Ok(());
    };
    vgps_replay::ros_out::write_mcap(path, drive, records)
        .map_err(|e| super::CliError::Output(std::io::Error::other(e.to_string())))
}
