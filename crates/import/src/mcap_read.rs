//! A tolerant, streaming reader of MCAP files (rosbag2's default storage), built on the
//! `mcap` crate's sans-I/O linear reader: it reads a file front to back with bounded
//! memory (one record, or one chunk, at a time) and hands every message to a callback
//! together with its channel's topic, schema name and message encoding.
//!
//! # Damage
//! A recording cut by a crash (no summary, no footer, a last record cut in the middle), a
//! chunk whose CRC or compression is bad, a message of an unknown channel: each is a
//! [`McapProblem`] naming the file, the record number and what is wrong; what is intact is
//! read (a bad chunk is skipped whole: its messages are not trusted). Only a file that cannot
//! be opened or does not start with the MCAP magic is an error.

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::HashMap;
use std::io::Read;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// Largest accepted record (a chunk, an attachment), bytes: 1 GiB.
pub const MAX_RECORD_BYTES: usize = 1 << 30;
/// Largest accepted decompressed chunk, bytes: 1 GiB.
pub const MAX_CHUNK_BYTES: u64 = 1 << 30;
/// Largest accepted ratio of a chunk's decompressed to compressed size (above
/// [`MIN_CHUNK_LIMIT_BYTES`]): a corrupt header cannot make the reader reserve a gigabyte for
/// a few bytes of data.
pub const MAX_CHUNK_RATIO: u64 = 1024;
/// A chunk may always decompress to this many bytes, whatever its compressed size: 16 MiB.
pub const MIN_CHUNK_LIMIT_BYTES: u64 = 16 << 20;
/// Most bytes handed to the reader at once: 4 MiB.
const READ_BYTES: usize = 4 << 20;
/// How many problems [`McapReadSummary::problems`] keeps (the rest are counted).
pub const MAX_PROBLEMS: usize = 50;
/// The 8-byte magic that starts an MCAP file.
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// One message of the file, as stored.
#[derive(Clone, Copy, Debug)]
pub struct McapMessage<'a> {
    /// The channel's topic.
    pub topic: &'a str,
    /// The schema's name (`sensor_msgs/msg/NavSatFix`), empty without a schema.
    pub schema: &'a str,
    /// The channel's message encoding (`cdr` for ROS 2).
    pub encoding: &'a str,
    /// Log time, nanoseconds since the Unix epoch.
    pub log_time: u64,
    /// The number of the record (top level, 0-based) that holds the message.
    pub record: u64,
    /// The serialized message.
    pub data: &'a [u8],
}

/// Something skipped while reading, with its place in the file.
#[derive(Clone, Debug, PartialEq)]
pub struct McapProblem {
    /// The top-level record number (0-based) where it happened.
    pub record: u64,
    /// What is wrong.
    pub reason: String,
}

/// What was read and skipped.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct McapReadSummary {
    /// Bytes read from the file.
    pub bytes: u64,
    /// Top-level records read.
    pub records: u64,
    /// Chunks read whole.
    pub chunks: u64,
    /// Chunks skipped (bad CRC, bad compression, too large).
    pub bad_chunks: u64,
    /// Messages handed to the callback.
    pub messages: u64,
    /// Messages of a channel never defined.
    pub orphan_messages: u64,
    /// Whether the file ended inside a record (a cut recording) or reading stopped at damage.
    pub truncated: bool,
    /// Problems, the first [`MAX_PROBLEMS`] (with the file name in [`Self::path`]).
    pub problems: Vec<McapProblem>,
    /// Problems not kept in [`Self::problems`].
    pub more_problems: u64,
    /// The file.
    pub path: PathBuf,
}

impl McapReadSummary {
    fn problem(&mut self, record: u64, reason: String) {
        if self.problems.len() < MAX_PROBLEMS {
            self.problems.push(McapProblem { record, reason });
        } else {
            self.more_problems += 1;
        }
    }

    /// Every kept problem as `FILE: record N: reason`.
    pub fn messages(&self) -> Vec<String> {
        let mut out: Vec<String> = self
            .problems
            .iter()
            .map(|p| format!("{}: record {}: {}", self.path.display(), p.record, p.reason))
            .collect();
        if self.more_problems > 0 {
            out.push(format!(
                "{}: {} more problem(s) not listed",
                self.path.display(),
                self.more_problems
            ));
        }
        out
    }
}

/// Why a file could not be read at all.
#[derive(Debug, thiserror::Error)]
pub enum McapFileError {
    /// The file cannot be opened or read.
    #[error("{}: cannot read the file: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with the MCAP magic.
    #[error("{}: not an MCAP file (no MCAP magic at the start)", path.display())]
    NotMcap {
        /// The file.
        path: PathBuf,
    },
}

#[derive(Default)]
struct Channels {
    /// Schema id → (name, encoding).
    schemas: HashMap<u16, String>,
    /// Channel id → (topic, message encoding, schema id).
    channels: HashMap<u16, (String, String, u16)>,
}

impl Channels {
    fn take(&mut self, record: &Record<'_>) {
        match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name.clone());
            }
            Record::Channel(c) => {
                self.channels.insert(
                    c.id,
                    (c.topic.clone(), c.message_encoding.clone(), c.schema_id),
                );
            }
            _ => {}
        }
    }
}

/// Reads an MCAP file and calls `on_message` for every message of its intact records.
///
/// # Errors
/// [`McapFileError`] when the file cannot be opened or is not an MCAP file; every other
/// problem is in the returned [`McapReadSummary`].
pub fn read_mcap_file(
    path: &Path,
    on_message: &mut dyn FnMut(&McapMessage<'_>),
) -> Result<McapReadSummary, McapFileError> {
    let file = std::fs::File::open(path).map_err(|source| McapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_mcap(
        path,
        std::io::BufReader::with_capacity(1 << 20, file),
        on_message,
    )
}

/// [`read_mcap_file`] that stops as soon as `on_message` returns [`ControlFlow::Break`]
/// (the summary then counts what was read up to there).
///
/// # Errors
/// As [`read_mcap_file`].
pub fn read_mcap_file_until(
    path: &Path,
    on_message: &mut dyn FnMut(&McapMessage<'_>) -> ControlFlow<()>,
) -> Result<McapReadSummary, McapFileError> {
    let file = std::fs::File::open(path).map_err(|source| McapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_mcap_until(
        path,
        std::io::BufReader::with_capacity(1 << 20, file),
        on_message,
    )
}

/// Reads MCAP data from `input` (named `path` in messages); see [`read_mcap_file`].
///
/// # Errors
/// [`McapFileError`] when `input` cannot be read or does not start with the MCAP magic.
pub fn read_mcap(
    path: &Path,
    input: impl Read,
    on_message: &mut dyn FnMut(&McapMessage<'_>),
) -> Result<McapReadSummary, McapFileError> {
    read_mcap_until(path, input, &mut |m| {
        on_message(m);
        ControlFlow::Continue(())
    })
}

/// [`read_mcap`] that stops as soon as `on_message` returns [`ControlFlow::Break`].
///
/// # Errors
/// As [`read_mcap`].
pub fn read_mcap_until(
    path: &Path,
    mut input: impl Read,
    on_message: &mut dyn FnMut(&McapMessage<'_>) -> ControlFlow<()>,
) -> Result<McapReadSummary, McapFileError> {
    let io_err = |source| McapFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut magic = [0u8; 8];
    let got = fill(&mut input, &mut magic).map_err(io_err)?;
    if got < magic.len() || &magic != MAGIC {
        return Err(McapFileError::NotMcap {
            path: path.to_path_buf(),
        });
    }
    let mut summary = McapReadSummary {
        bytes: magic.len() as u64,
        path: path.to_path_buf(),
        ..McapReadSummary::default()
    };
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_emit_chunks(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    let mut channels = Channels::default();
    let mut flow = ControlFlow::Continue(());
    while flow.is_continue() {
        let event = match reader.next_event() {
            None => break,
            Some(Ok(event)) => event,
            Some(Err(e)) => {
                summary.truncated = true;
                let record = summary.records;
                summary.problem(
                    record,
                    format!("{e}; reading stopped here (the rest of the file is not read)"),
                );
                break;
            }
        };
        match event {
            LinearReadEvent::ReadRequest(n) => {
                let buf = reader.insert(n.clamp(1, READ_BYTES));
                let got = match fill(&mut input, buf) {
                    Ok(got) => got,
                    Err(e) => {
                        summary.truncated = true;
                        let record = summary.records;
                        summary.problem(record, format!("read error: {e}; reading stopped here"));
                        break;
                    }
                };
                summary.bytes += got as u64;
                reader.notify_read(got);
            }
            LinearReadEvent::Record { data, opcode } => {
                let record = summary.records;
                summary.records += 1;
                match mcap::parse_record(opcode, data) {
                    Ok(Record::Chunk { header, data }) => {
                        flow = read_chunk(
                            record,
                            header,
                            &data,
                            &mut channels,
                            &mut summary,
                            on_message,
                        );
                    }
                    Ok(rec) => {
                        flow = handle(record, &rec, &mut channels, &mut summary, on_message);
                    }
                    Err(e) => summary.problem(
                        record,
                        format!("record (opcode 0x{opcode:02x}): {e}; skipped"),
                    ),
                }
            }
        }
    }
    Ok(summary)
}

/// Reads as many bytes as `buf` holds, fewer only at the end of the input.
fn fill(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

fn read_chunk(
    record: u64,
    header: mcap::records::ChunkHeader,
    data: &[u8],
    channels: &mut Channels,
    summary: &mut McapReadSummary,
    on_message: &mut dyn FnMut(&McapMessage<'_>) -> ControlFlow<()>,
) -> ControlFlow<()> {
    let limit = header
        .compressed_size
        .saturating_mul(MAX_CHUNK_RATIO)
        .clamp(MIN_CHUNK_LIMIT_BYTES, MAX_CHUNK_BYTES);
    if header.uncompressed_size > limit {
        summary.bad_chunks += 1;
        summary.problem(
            record,
            format!(
                "chunk of {} bytes ({} compressed) exceeds the limit {limit}; skipped",
                header.uncompressed_size, header.compressed_size
            ),
        );
        return ControlFlow::Continue(());
    }
    let compression = header.compression.clone();
    let reader = match mcap::read::ChunkReader::new(header, data) {
        Ok(r) => r,
        Err(e) => {
            summary.bad_chunks += 1;
            summary.problem(record, format!("chunk ({compression}): {e}; skipped"));
            return ControlFlow::Continue(());
        }
    };
    // The chunk's CRC is checked at its end: nothing of it is used before that.
    let mut records = Vec::new();
    for r in reader {
        match r {
            Ok(r) => records.push(r),
            Err(e) => {
                summary.bad_chunks += 1;
                summary.problem(
                    record,
                    format!("chunk ({compression}): {e}; its messages are skipped"),
                );
                return ControlFlow::Continue(());
            }
        }
    }
    summary.chunks += 1;
    for r in &records {
        handle(record, r, channels, summary, on_message)?;
    }
    ControlFlow::Continue(())
}

fn handle(
    record: u64,
    rec: &Record<'_>,
    channels: &mut Channels,
    summary: &mut McapReadSummary,
    on_message: &mut dyn FnMut(&McapMessage<'_>) -> ControlFlow<()>,
) -> ControlFlow<()> {
    let Record::Message { header, data } = rec else {
        channels.take(rec);
        return ControlFlow::Continue(());
    };
    let Some((topic, encoding, schema_id)) = channels.channels.get(&header.channel_id) else {
        summary.orphan_messages += 1;
        summary.problem(
            record,
            format!(
                "message of channel {} which is not defined; skipped",
                header.channel_id
            ),
        );
        return ControlFlow::Continue(());
    };
    let schema = channels.schemas.get(schema_id).map_or("", String::as_str);
    summary.messages += 1;
    on_message(&McapMessage {
        topic,
        schema,
        encoding,
        log_time: header.log_time,
        record,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::borrow::Cow;
    use std::sync::Arc;

    /// An MCAP of `n` messages on one channel, chunked (`chunk_size` bytes) and compressed.
    fn sample(n: u64, compression: Option<mcap::Compression>) -> Vec<u8> {
        let mut buf = Vec::new();
        {
            let mut w = mcap::WriteOptions::new()
                .compression(compression)
                .chunk_size(Some(256))
                .create(std::io::Cursor::new(&mut buf))
                .unwrap();
            let schema = Arc::new(mcap::Schema {
                id: 1,
                name: "std_msgs/msg/String".into(),
                encoding: "ros2msg".into(),
                data: Cow::Borrowed(b"string data"),
            });
            let channel = Arc::new(mcap::Channel {
                id: 0,
                topic: "/t".into(),
                message_encoding: "cdr".into(),
                metadata: Default::default(),
                schema: Some(schema),
            });
            for i in 0..n {
                w.write(&mcap::Message {
                    channel: channel.clone(),
                    sequence: i as u32,
                    log_time: i,
                    publish_time: i,
                    data: Cow::Owned(vec![i as u8; 40]),
                })
                .unwrap();
            }
            w.finish().unwrap();
        }
        buf
    }

    fn read(bytes: &[u8]) -> (Vec<u64>, McapReadSummary) {
        let mut times = Vec::new();
        let s = read_mcap(Path::new("x.mcap"), bytes, &mut |m| {
            assert_eq!(
                (m.topic, m.schema, m.encoding),
                ("/t", "std_msgs/msg/String", "cdr")
            );
            times.push(m.log_time);
        })
        .unwrap();
        (times, s)
    }

    #[test]
    fn reads_every_message_of_a_whole_file() {
        for c in [
            None,
            Some(mcap::Compression::Zstd),
            Some(mcap::Compression::Lz4),
        ] {
            let (times, s) = read(&sample(50, c));
            assert_eq!(times, (0..50).collect::<Vec<_>>());
            assert!(
                s.problems.is_empty() && !s.truncated && s.chunks > 5,
                "{s:?}"
            );
        }
    }

    #[test]
    fn a_cut_file_gives_what_is_intact_and_says_so() {
        let whole = sample(50, Some(mcap::Compression::Zstd));
        let cut = &whole[..whole.len() / 2];
        let (times, s) = read(cut);
        assert!(!times.is_empty() && times.len() < 50);
        assert_eq!(times, (0..times.len() as u64).collect::<Vec<_>>());
        assert!(s.truncated);
        assert!(
            s.messages()[0].starts_with("x.mcap: record "),
            "{:?}",
            s.messages()
        );
    }

    #[test]
    fn a_chunk_with_a_bad_crc_is_skipped_and_the_rest_read() {
        let mut bytes = sample(50, None);
        // Flip a byte of the payload of message 30 (uncompressed chunks of a few messages).
        let at = bytes
            .windows(40)
            .position(|w| w.iter().all(|&b| b == 30))
            .unwrap();
        bytes[at + 5] ^= 0xff;
        let (times, s) = read(&bytes);
        assert!(!times.contains(&30) && times.contains(&49) && times.contains(&0));
        assert!(times.len() >= 45, "only the bad chunk is lost: {times:?}");
        assert_eq!(s.bad_chunks, 1);
        assert!(s.messages()[0].contains("CRC"), "{:?}", s.messages());
    }

    #[test]
    fn reading_stops_when_the_callback_says_so() {
        let bytes = sample(50, Some(mcap::Compression::Zstd));
        let mut times = Vec::new();
        let s = read_mcap_until(Path::new("x.mcap"), &bytes[..], &mut |m| {
            times.push(m.log_time);
            if m.log_time == 7 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        assert_eq!(times, (0..8).collect::<Vec<_>>());
        assert_eq!(s.messages, 8);
        assert!(s.problems.is_empty() && !s.truncated);
    }

    #[test]
    fn not_an_mcap_is_an_error() {
        let e = read_mcap(Path::new("a.bag"), &b"#ROSBAG V2.0\n"[..], &mut |_| {}).unwrap_err();
        assert!(e.to_string().starts_with("a.bag: not an MCAP file"));
    }
}
