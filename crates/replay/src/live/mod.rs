//! Live outputs while frames are localized: an NMEA 0183 TCP server that gpsd (or any NMEA
//! reader) connects to, and the pacing of a replay at the drive's own time.
//!
//! gpsd reads a `tcp://HOST:PORT` source as a client (`gpsd -n tcp://127.0.0.1:10110`), so
//! [`NmeaTcpServer`] listens and writes every frame's sentences ([`NmeaEpochWriter`]) to
//! every connected client. A client that goes away is dropped with a message, a slow one
//! too (after [`CLIENT_WRITE_TIMEOUT`]); with no client the sentences go nowhere. The server
//! never stops the caller: it returns messages ([`NmeaTcpServer::take_messages`]) instead of
//! errors once it listens.
//!
//! # Example
//! ```
//! use std::io::{BufRead, BufReader};
//! use vgps_replay::live::NmeaTcpServer;
//! let mut server = NmeaTcpServer::bind("127.0.0.1:0")?;
//! let client = std::net::TcpStream::connect(server.local_addr())?;
//! server.wait_for_clients(1, std::time::Duration::from_secs(5));
//! server.send(1_700_000_000.0, None); // a frame without a fix
//! let mut line = String::new();
//! BufReader::new(client).read_line(&mut line)?;
//! assert!(line.starts_with("$GPGGA,221320.00,,,,,0,"), "{line}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::report::{NmeaEpochWriter, VisualFix};
use std::io::Write as _;
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// A client that cannot take a frame's sentences within this time is dropped.
pub const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// How often the accepting thread looks for new clients and for the server's end.
const ACCEPT_POLL: Duration = Duration::from_millis(10);

/// Errors of the live outputs.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The address could not be listened on (in use, not local, no permission, not an
    /// address).
    #[error("cannot listen on {address}: {reason}")]
    Listen {
        /// The address as given.
        address: String,
        /// The operating system's (or the resolver's) message.
        reason: String,
    },
}

/// What the accepting thread shares with the server.
#[derive(Default)]
struct Shared {
    clients: Vec<(SocketAddr, TcpStream)>,
    messages: Vec<String>,
    connected: usize,
}

fn lock(shared: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    // A panic while holding the lock cannot leave `Shared` inconsistent: use it anyway.
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// An NMEA 0183 TCP server: every frame's sentences to every connected client (see the
/// module docs). Dropping it closes the listening socket and the clients.
pub struct NmeaTcpServer {
    address: SocketAddr,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    accept: Option<std::thread::JoinHandle<()>>,
    writer: NmeaEpochWriter,
    sent: usize,
}

impl std::fmt::Debug for NmeaTcpServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NmeaTcpServer")
            .field("address", &self.address)
            .field("sent", &self.sent)
            .finish_non_exhaustive()
    }
}

impl NmeaTcpServer {
    /// Listens on `address` (`HOST:PORT`; port 0 picks a free port, see
    /// [`local_addr`](Self::local_addr)) and accepts clients on a background thread.
    ///
    /// # Errors
    /// [`LiveError::Listen`] when the address cannot be resolved or listened on (e.g.
    /// "Address already in use").
    pub fn bind(address: &str) -> Result<Self, LiveError> {
        let listen_error = |reason: String| LiveError::Listen {
            address: address.to_string(),
            reason,
        };
        let addrs: Vec<SocketAddr> = address
            .to_socket_addrs()
            .map_err(|e| listen_error(e.to_string()))?
            .collect();
        let listener = TcpListener::bind(&addrs[..]).map_err(|e| listen_error(e.to_string()))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| listen_error(e.to_string()))?;
        let local = listener
            .local_addr()
            .map_err(|e| listen_error(e.to_string()))?;
        let shared = Arc::new(Mutex::new(Shared::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let accept = {
            let shared = Arc::clone(&shared);
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || accept_loop(&listener, &shared, &stop))
        };
        Ok(Self {
            address: local,
            shared,
            stop,
            accept: Some(accept),
            writer: NmeaEpochWriter::new(),
            sent: 0,
        })
    }

    /// The address listened on (with the port chosen when 0 was given).
    pub fn local_addr(&self) -> SocketAddr {
        self.address
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        lock(&self.shared).clients.len()
    }

    /// Clients that have connected since the server started.
    pub fn clients_ever(&self) -> usize {
        lock(&self.shared).connected
    }

    /// Frames sent to at least one client.
    pub fn frames_sent(&self) -> usize {
        self.sent
    }

    /// Waits until at least `n` clients are connected or `timeout` has passed; returns
    /// whether they are.
    pub fn wait_for_clients(&self, n: usize, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while self.clients() < n {
            if Instant::now() >= end {
                return false;
            }
            std::thread::sleep(ACCEPT_POLL);
        }
        true
    }

    /// Writes one frame's sentences ([`NmeaEpochWriter::epoch`]) to every client; returns
    /// how many took them. A client whose write fails or times out is dropped (a message
    /// says so).
    pub fn send(&mut self, time_s: f64, visual: Option<&VisualFix>) -> usize {
        let text = self.writer.epoch(time_s, visual);
        self.send_text(&text)
    }

    /// Writes a localizer fix as [`send`](Self::send) does.
    pub fn send_fix(&mut self, fix: &vgps_core::localizer::LocalizerFix) -> usize {
        let visual = VisualFix::from_localizer(fix);
        self.send(fix.time_s, visual.as_ref())
    }

    /// Writes text as it is to every client (see [`send`](Self::send)).
    pub fn send_text(&mut self, text: &str) -> usize {
        if text.is_empty() {
            return 0;
        }
        let mut shared = lock(&self.shared);
        let mut dropped = Vec::new();
        shared
            .clients
            .retain_mut(|(peer, stream)| match stream.write_all(text.as_bytes()) {
                Ok(()) => true,
                Err(e) => {
                    dropped.push(format!("client {peer} dropped: {e}"));
                    false
                }
            });
        let n = shared.clients.len();
        shared.messages.extend(dropped);
        drop(shared);
        if n > 0 {
            self.sent += 1;
        }
        n
    }

    /// The messages since the last call (clients connected and dropped), oldest first.
    pub fn take_messages(&mut self) -> Vec<String> {
        std::mem::take(&mut lock(&self.shared).messages)
    }
}

impl Drop for NmeaTcpServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.accept.take() {
            // The accepting thread only polls and locks; it ends within ACCEPT_POLL.
            let _ = handle.join();
        }
    }
}

fn accept_loop(listener: &TcpListener, shared: &Mutex<Shared>, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, peer)) => {
                let ready = stream
                    .set_nonblocking(false)
                    .and_then(|()| stream.set_write_timeout(Some(CLIENT_WRITE_TIMEOUT)))
                    .and_then(|()| stream.set_nodelay(true));
                let mut s = lock(shared);
                match ready {
                    Ok(()) => {
                        s.messages.push(format!("client {peer} connected"));
                        s.clients.push((peer, stream));
                        s.connected += 1;
                    }
                    Err(e) => s.messages.push(format!("client {peer} refused: {e}")),
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(ACCEPT_POLL);
            }
            Err(e) => {
                lock(shared).messages.push(format!("accept failed: {e}"));
                std::thread::sleep(ACCEPT_POLL);
            }
        }
    }
}

/// How fast a replay feeds its live outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pace {
    /// At the drive's own time: a frame is sent no earlier than its time after the first
    /// frame's (as a receiver would send it); never waits when localizing is slower.
    #[default]
    Real,
    /// As fast as frames are localized.
    Fast,
}

impl Pace {
    /// Every pace.
    pub const ALL: [Self; 2] = [Self::Real, Self::Fast];

    /// The pace's name (`real`, `fast`): what [`std::str::FromStr`] reads and
    /// [`std::fmt::Display`] writes.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Real => "real",
            Self::Fast => "fast",
        }
    }
}

impl std::fmt::Display for Pace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Pace {
    type Err = String;

    /// `real` or `fast` (any case; surrounding spaces ignored).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|p| p.as_str().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| format!("`{s}` is not a pace (real or fast)"))
    }
}

/// Holds a replay to the drive's time ([`Pace::Real`]) or lets it run ([`Pace::Fast`]).
#[derive(Clone, Copy, Debug)]
pub struct Pacer {
    pace: Pace,
    start: Option<(Instant, f64)>,
}

impl Pacer {
    /// A pacer whose clock starts at the first frame it is given.
    pub fn new(pace: Pace) -> Self {
        Self { pace, start: None }
    }

    /// Sleeps until the frame of time `time_s` (seconds) is due. A non-finite time or a
    /// time before the first frame's is due at once.
    pub fn wait_until_due(&mut self, time_s: f64) {
        if self.pace == Pace::Fast || !time_s.is_finite() {
            return;
        }
        let (wall0, t0) = *self.start.get_or_insert((Instant::now(), time_s));
        let ahead = time_s - t0;
        if ahead > 0.0 {
            let due = wall0 + Duration::from_secs_f64(ahead.min(1e9));
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read as _;

    #[test]
    fn pace_names_round_trip() {
        for p in Pace::ALL {
            assert_eq!(p.to_string().parse::<Pace>(), Ok(p));
        }
        assert_eq!(" FAST ".parse::<Pace>(), Ok(Pace::Fast));
        assert_eq!(
            "slow".parse::<Pace>(),
            Err("`slow` is not a pace (real or fast)".to_owned())
        );
    }

    #[test]
    fn an_address_in_use_is_a_clear_error() {
        let first = NmeaTcpServer::bind("127.0.0.1:0").unwrap();
        let address = first.local_addr().to_string();
        let err = NmeaTcpServer::bind(&address).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!("cannot listen on {address}: ")),
            "{err}"
        );
        assert!(err.to_lowercase().contains("in use"), "{err}");
        let err = NmeaTcpServer::bind("no port").unwrap_err().to_string();
        assert!(err.starts_with("cannot listen on no port: "), "{err}");
    }

    #[test]
    fn a_client_that_leaves_is_dropped_and_the_others_go_on() {
        let mut server = NmeaTcpServer::bind("127.0.0.1:0").unwrap();
        assert_eq!(server.send(1_700_000_000.0, None), 0); // nobody listens: fine
        let leaving = TcpStream::connect(server.local_addr()).unwrap();
        let mut staying = TcpStream::connect(server.local_addr()).unwrap();
        assert!(server.wait_for_clients(2, Duration::from_secs(5)));
        drop(leaving);
        // The first write after a peer closed may still succeed (the kernel learns of the
        // close from the reply); a few more must fail.
        let mut n = 2;
        for k in 0..50 {
            n = server.send(1_700_000_001.0 + f64::from(k), None);
            if n == 1 {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(n, 1);
        let messages = server.take_messages();
        assert!(
            messages.iter().any(|m| m.contains("dropped")),
            "{messages:?}"
        );
        assert_eq!(server.clients_ever(), 2);
        drop(server);
        let mut text = String::new();
        staying.read_to_string(&mut text).unwrap();
        assert!(text.starts_with("$GPGGA,221321.00,"), "{text}");
    }

    #[test]
    fn real_pace_waits_for_the_drive_time_and_fast_does_not() {
        let mut pacer = Pacer::new(Pace::Real);
        let start = Instant::now();
        for k in 0..4 {
            pacer.wait_until_due(100.0 + 0.05 * f64::from(k));
        }
        pacer.wait_until_due(f64::NAN);
        pacer.wait_until_due(50.0);
        let elapsed = start.elapsed().as_secs_f64();
        assert!((0.15..0.5).contains(&elapsed), "{elapsed}");
        let mut fast = Pacer::new(Pace::Fast);
        let start = Instant::now();
        fast.wait_until_due(0.0);
        fast.wait_until_due(1000.0);
        assert!(start.elapsed() < Duration::from_millis(50));
    }
}
