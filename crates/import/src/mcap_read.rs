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

/// The top-level records read: schema, channel, message and chunk.
const USED_OPCODES: [u8; 4] = [
    mcap::records::op::SCHEMA,
    mcap::records::op::CHANNEL,
    mcap::records::op::MESSAGE,
    mcap::records::op::CHUNK,
];

/// The records a chunk may hold (MCAP specification, "Chunk").
const IN_CHUNK_OPCODES: [u8; 3] = [
    mcap::records::op::SCHEMA,
    mcap::records::op::CHANNEL,
    mcap::records::op::MESSAGE,
];

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
                // Only the records vgps uses are parsed: the `mcap` crate (0.26) panics on an
                // attachment shorter than its header says (`body.len() - 4` underflows), and
                // the index and summary records are not needed for a linear read.
                if !USED_OPCODES.contains(&opcode) {
                    continue;
                }
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
    // The `mcap` crate (0.26) panics on a chunk whose inner record claims a length within 9
    // bytes of `u64::MAX` (its `9 + len` wraps), compressed or not. So a chunk is decompressed
    // here (zstd, lz4; bounded by its header's size), its record framing checked, and the
    // crate reads it as an uncompressed chunk (which still checks the CRC).
    let plain = match decompress_chunk(&compression, data, header.uncompressed_size) {
        Ok(plain) => plain,
        Err(reason) => {
            summary.bad_chunks += 1;
            let what = if compression.is_empty() {
                "uncompressed"
            } else {
                &compression
            };
            summary.problem(record, format!("chunk ({what}): {reason}; skipped"));
            return ControlFlow::Continue(());
        }
    };
    let (header, data) = match &plain {
        Some(plain) => {
            if let Err(reason) = check_chunk_framing(plain) {
                summary.bad_chunks += 1;
                let what = if compression.is_empty() {
                    "uncompressed"
                } else {
                    &compression
                };
                summary.problem(record, format!("chunk ({what}): {reason}; skipped"));
                return ControlFlow::Continue(());
            }
            let header = mcap::records::ChunkHeader {
                compression: String::new(),
                compressed_size: plain.len() as u64,
                uncompressed_size: plain.len() as u64,
                ..header
            };
            (header, &plain[..])
        }
        None => (header, data),
    };
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

/// The records of a chunk, decompressed: borrowed when not compressed, `None` for a
/// compression other than zstd and lz4 (left to the `mcap` crate, which refuses it). The
/// output is bounded: more bytes than `expected` (the header's size) is an error.
fn decompress_chunk<'d>(
    compression: &str,
    data: &'d [u8],
    expected: u64,
) -> Result<Option<std::borrow::Cow<'d, [u8]>>, String> {
    let mut out = Vec::new();
    let bound = expected.saturating_add(1);
    let read = match compression {
        "" => {
            return if data.len() as u64 == expected {
                Ok(Some(std::borrow::Cow::Borrowed(data)))
            } else {
                Err(format!(
                    "{} byte(s) of records, its header says {expected}",
                    data.len()
                ))
            };
        }
        "zstd" => {
            zstd::stream::read::Decoder::new(data).and_then(|d| d.take(bound).read_to_end(&mut out))
        }
        "lz4" => lz4_flex::frame::FrameDecoder::new(data)
            .take(bound)
            .read_to_end(&mut out),
        _ => return Ok(None),
    };
    read.map_err(|e| format!("cannot decompress: {e}"))?;
    if out.len() as u64 != expected {
        let more = if out.len() as u64 > expected {
            "more than "
        } else {
            ""
        };
        let got = if more.is_empty() {
            out.len() as u64
        } else {
            expected
        };
        return Err(format!(
            "decompresses to {more}{got} byte(s), its header says {expected}"
        ));
    }
    Ok(Some(std::borrow::Cow::Owned(out)))
}

/// Checks that the records of an uncompressed chunk (`opcode: u8`, `length: u64` little
/// endian, then `length` bytes) tile `data` exactly; the error names the first bad record
/// (its index in the chunk and byte offset).
fn check_chunk_framing(data: &[u8]) -> Result<(), String> {
    const HEADER: usize = 9;
    let mut at = 0usize;
    let mut index = 0u64;
    while at < data.len() {
        let rest = data.len() - at;
        let Some(head) = data.get(at..at + HEADER) else {
            return Err(format!(
                "record {index} at byte {at}: {rest} byte(s) left, fewer than a record header"
            ));
        };
        if !IN_CHUNK_OPCODES.contains(&head[0]) {
            return Err(format!(
                "record {index} (opcode 0x{:02x}) at byte {at}: a chunk holds only schema, channel and message records",
                head[0]
            ));
        }
        let mut len_bytes = [0u8; 8];
        len_bytes.copy_from_slice(&head[1..]);
        let len = u64::from_le_bytes(len_bytes);
        let available = (rest - HEADER) as u64;
        if len > available {
            return Err(format!(
                "record {index} (opcode 0x{:02x}) at byte {at}: length {len} exceeds the {available} byte(s) left in the chunk",
                head[0]
            ));
        }
        // `len <= available < usize::MAX`: no overflow.
        at += HEADER + len as usize;
        index += 1;
    }
    Ok(())
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

    /// An MCAP of one uncompressed chunk whose records are `records` (CRC 0: not checked).
    fn one_uncompressed_chunk(records: &[u8]) -> Vec<u8> {
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message_start_time
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message_end_time
        chunk.extend_from_slice(&(records.len() as u64).to_le_bytes()); // uncompressed_size
        chunk.extend_from_slice(&0u32.to_le_bytes()); // uncompressed_crc
        chunk.extend_from_slice(&0u32.to_le_bytes()); // compression: ""
        chunk.extend_from_slice(&(records.len() as u64).to_le_bytes());
        chunk.extend_from_slice(records);
        let mut bytes = MAGIC.to_vec();
        bytes.push(0x06);
        bytes.extend_from_slice(&(chunk.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&chunk);
        bytes
    }

    /// An MCAP of one chunk compressed with `name`, holding `packed` for `size` bytes of
    /// records.
    fn one_packed_chunk(name: &str, packed: &[u8], size: u64) -> Vec<u8> {
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes());
        chunk.extend_from_slice(&0u64.to_le_bytes());
        chunk.extend_from_slice(&size.to_le_bytes());
        chunk.extend_from_slice(&0u32.to_le_bytes());
        chunk.extend_from_slice(&(name.len() as u32).to_le_bytes());
        chunk.extend_from_slice(name.as_bytes());
        chunk.extend_from_slice(&(packed.len() as u64).to_le_bytes());
        chunk.extend_from_slice(packed);
        let mut bytes = MAGIC.to_vec();
        bytes.push(0x06);
        bytes.extend_from_slice(&(chunk.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&chunk);
        bytes
    }

    fn zstd_pack(b: &[u8]) -> Vec<u8> {
        zstd::stream::encode_all(b, 3).unwrap()
    }

    fn lz4_pack(b: &[u8]) -> Vec<u8> {
        use std::io::Write;
        let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
        e.write_all(b).unwrap();
        e.finish().unwrap()
    }

    /// The same framing fault inside a zstd or lz4 chunk: before the fix the `mcap` crate
    /// panicked in its decompressing reader (`linear_reader.rs:83`).
    #[test]
    fn a_compressed_chunk_record_claiming_u64_max_bytes_is_not_a_panic() {
        type Pack = fn(&[u8]) -> Vec<u8>;
        let packers: [(&str, Pack); 2] = [("zstd", zstd_pack), ("lz4", lz4_pack)];
        for (name, pack) in packers {
            for len in [u64::MAX, u64::MAX - 8, 1 << 40] {
                let mut records = vec![0x05];
                records.extend_from_slice(&len.to_le_bytes());
                let bytes = one_packed_chunk(name, &pack(&records), records.len() as u64);
                let (times, s) = read(&bytes);
                assert!(times.is_empty());
                assert_eq!((s.bad_chunks, s.chunks), (1, 0), "{s:?}");
                let m = s.messages();
                assert!(
                    m[0].starts_with(&format!(
                        "x.mcap: record 0: chunk ({name}): record 0 (opcode 0x05) at byte 0: length"
                    )),
                    "{m:?}"
                );
            }
            // A header that understates the decompressed size: refused, bounded.
            let bytes = one_packed_chunk(name, &pack(&[0u8; 4096]), 100);
            let (_, s) = read(&bytes);
            assert_eq!(s.bad_chunks, 1, "{s:?}");
            assert!(
                s.messages()[0]
                    .contains("decompresses to more than 100 byte(s), its header says 100"),
                "{:?}",
                s.messages()
            );
            // Garbage instead of compressed data.
            let (_, s) = read(&one_packed_chunk(name, b"not compressed at all", 9));
            assert!(
                s.messages()[0].contains("cannot decompress"),
                "{:?}",
                s.messages()
            );
        }
    }

    /// Found by the `mcap_read` fuzz target (docs/fuzzing.md): a chunk record of length
    /// `u64::MAX` made the `mcap` crate's chunk reader panic (`9 + len` wrapped to 8).
    #[test]
    fn a_chunk_record_claiming_u64_max_bytes_is_a_bad_chunk_not_a_panic() {
        for len in [u64::MAX, u64::MAX - 8, u64::MAX - 7, 1 << 40, 1] {
            let mut records = vec![0x05];
            records.extend_from_slice(&len.to_le_bytes());
            let (times, s) = read(&one_uncompressed_chunk(&records));
            assert!(times.is_empty());
            assert_eq!((s.bad_chunks, s.chunks), (1, 0), "{s:?}");
            let m = s.messages();
            assert!(
                m[0].starts_with("x.mcap: record 0: chunk (uncompressed): record 0 (opcode 0x05) at byte 0: length")
                    && m[0].ends_with("exceeds the 0 byte(s) left in the chunk; skipped"),
                "{m:?}"
            );
        }
        // A cut header and a well-framed empty chunk.
        let (_, s) = read(&one_uncompressed_chunk(&[0x05, 0, 0]));
        assert!(
            s.messages()[0].contains("fewer than a record header"),
            "{s:?}"
        );
        let (_, s) = read(&one_uncompressed_chunk(&[]));
        assert_eq!((s.bad_chunks, s.chunks), (0, 1), "{s:?}");
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

    /// An attachment record of 32 bytes: its header (two times, two empty strings) and a
    /// data length, with no room for the CRC the `mcap` crate slices off its end.
    fn short_attachment() -> Vec<u8> {
        let mut record = vec![0x09];
        record.extend_from_slice(&32u64.to_le_bytes());
        record.extend_from_slice(&[0u8; 32]);
        record
    }

    #[test]
    fn an_attachment_shorter_than_its_crc_is_skipped_not_a_panic() {
        // Found by the `mcap_read` fuzz target (2026-11-27).
        let mut bytes = sample(3, None);
        let end = bytes.len() - 8; // before the end magic
        bytes.splice(end..end, short_attachment());
        let (times, s) = read(&bytes);
        assert_eq!(times, vec![0, 1, 2]);
        assert!(s.problems.is_empty(), "{s:?}");
    }

    #[test]
    fn a_chunk_holding_an_attachment_is_refused_by_name() {
        let (times, s) = read(&one_uncompressed_chunk(&short_attachment()));
        assert!(times.is_empty());
        assert_eq!((s.bad_chunks, s.chunks), (1, 0), "{s:?}");
        assert!(
            s.problems[0].reason.contains("(opcode 0x09)")
                && s.problems[0]
                    .reason
                    .contains("only schema, channel and message"),
            "{s:?}"
        );
    }

    #[test]
    fn not_an_mcap_is_an_error() {
        let e = read_mcap(Path::new("a.bag"), &b"#ROSBAG V2.0\n"[..], &mut |_| {}).unwrap_err();
        assert!(e.to_string().starts_with("a.bag: not an MCAP file"));
    }
}
