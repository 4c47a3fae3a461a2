//! A rosbag2 recording in MCAP into a drive folder.
//!
//! Read are `sensor_msgs/msg/CompressedImage` and `sensor_msgs/msg/Image` (one topic per
//! camera), `sensor_msgs/msg/NavSatFix` (the satellite GPS) and `sensor_msgs/msg/Imu`;
//! every other type (`CameraInfo`, `/tf`, …) is counted and ignored. Each image is named
//! `images/cam<k>/<stamp_ns>.<ext>` and the images are grouped into frames by stamp
//! ([`assemble_frames`]). With [`ImageOutput::Files`] each is written there (a compressed
//! image as it is, a raw image as PNG); with [`ImageOutput::InRecording`] none is written and
//! [`RecordingImages::stream`] reads the bytes back from the recording frame by frame.
//!
//! # Cameras
//! A topic's camera index comes from a mapping file (`topic,camera` CSV) when one is
//! given; otherwise it is the last number in the topic name (`/ladybug/cam3/image/compressed`
//! → 3, `/camera_0/image_raw` → 0). An image topic with no index is skipped with a warning.
//!
//! # Satellite GPS
//! Each `NavSatFix` becomes an epoch of `gnss.nmea` at its header stamp: `status` −1 (no fix)
//! an epoch without fix (a warning names the record where each outage starts), 0 GGA quality 1, 1 (SBAS) quality
//! 2, 2 (GBAS, as ROS drivers report RTK) quality 4. Every field, status and covariance
//! included, is also kept in `navsatfix.csv`; IMU samples go to `imu.csv`.

use crate::drive_out::{
    DriveContent, ImportError, ImportReport, ImuRow, NavSatRow, StampedImage, assemble_frames,
    create_dir, seconds_of_ns, write_drive,
};
use crate::mcap_read::{McapMessage, McapReadSummary, read_mcap_file, read_mcap_file_until};
use crate::ros_decode;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use vgps_geometry::geo::Geodetic;
use vgps_replay::drive::{FrameRecord, GnssFix, GnssRecord, MAX_IMAGE_COLUMNS, Manifest};

/// Largest raw image accepted, pixels (100 megapixels).
pub const MAX_RAW_PIXELS: u64 = 100_000_000;

/// Options of an MCAP import.
#[derive(Clone, Debug)]
pub struct McapImportOptions {
    /// The rig calibration.
    pub rig: PathBuf,
    /// The surveyed landmarks, if any (an empty table otherwise).
    pub landmarks: Option<PathBuf>,
    /// Topic → camera index, if given (else the naming rule).
    pub topics: Option<BTreeMap<String, usize>>,
    /// Largest spread of the stamps of one frame, seconds.
    pub stamp_tolerance_s: f64,
    /// Where the images go: files of the drive, or left in the recording.
    pub images: ImageOutput,
}

/// Where an MCAP import puts the images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ImageOutput {
    /// Each image is a file of the drive, written durably ([`vgps_io::write_atomic`]), as
    /// `vgps import mcap` keeps it.
    #[default]
    Files,
    /// No image file is written: the frames name each image as [`ImageOutput::Files`]
    /// would (`images/cam<k>/<stamp>.<ext>`), but only [`McapImport::recording_images`]
    /// says where it is in the recording, and [`RecordingImages::stream`] reads the bytes
    /// back frame by frame (`vgps replay run.mcap`).
    InRecording,
}

/// Reads a topic mapping file: CSV `topic,camera` with a header; blank lines and lines
/// starting with `#` are ignored.
///
/// # Errors
/// [`ImportError`] naming the file and line of a bad row or a duplicated topic.
pub fn read_topic_map(path: &Path) -> Result<BTreeMap<String, usize>, ImportError> {
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    topic_map_from_str(&text, path)
}

/// [`read_topic_map`] on the text of the file `path` (named in errors).
///
/// # Errors
/// As [`read_topic_map`], except reading.
///
/// # Example
/// ```
/// use std::path::Path;
/// use vgps_import::mcap_import::topic_map_from_str;
/// let map = topic_map_from_str("topic,camera\n/front/image,2\n", Path::new("t.csv"))?;
/// assert_eq!(map["/front/image"], 2);
/// let e = topic_map_from_str("/a,1\n/a,2\n", Path::new("t.csv")).unwrap_err();
/// assert!(e.to_string().contains("t.csv:2: topic `/a` is mapped twice"));
/// # Ok::<(), vgps_import::drive_out::ImportError>(())
/// ```
pub fn topic_map_from_str(text: &str, path: &Path) -> Result<BTreeMap<String, usize>, ImportError> {
    let mut map = BTreeMap::new();
    let mut header_seen = false;
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if !header_seen {
            header_seen = true;
            if line.replace(' ', "") == "topic,camera" {
                continue;
            }
        }
        let bad = |why: String| ImportError::Input(format!("{}:{}: {why}", path.display(), n + 1));
        let (topic, camera) = line
            .split_once(',')
            .ok_or_else(|| bad("expected `topic,camera`".into()))?;
        let camera: usize = camera
            .trim()
            .parse()
            .ok()
            .filter(|&c| c < MAX_IMAGE_COLUMNS)
            .ok_or_else(|| {
                bad(format!(
                    "field `camera`: `{}` is not a camera index 0–{}",
                    camera.trim(),
                    MAX_IMAGE_COLUMNS - 1
                ))
            })?;
        if map.insert(topic.trim().to_string(), camera).is_some() {
            return Err(bad(format!("topic `{}` is mapped twice", topic.trim())));
        }
    }
    Ok(map)
}

/// The camera index of a topic by the naming rule: its last run of decimal digits.
///
/// # Example
/// ```
/// use vgps_import::mcap_import::camera_of_topic;
/// assert_eq!(camera_of_topic("/ladybug/cam3/image/compressed"), Some(3));
/// assert_eq!(camera_of_topic("/front/image_raw"), None);
/// assert_eq!(camera_of_topic("/caméra2"), Some(2));
/// ```
pub fn camera_of_topic(topic: &str) -> Option<usize> {
    let end = topic.rfind(|c: char| c.is_ascii_digit())? + 1;
    let start = topic[..end]
        .trim_end_matches(|c: char| c.is_ascii_digit())
        .len();
    topic[start..end].parse().ok()
}

/// Message types the import reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Compressed,
    Raw,
    NavSat,
    Imu,
}

fn kind_of(schema: &str) -> Option<Kind> {
    match schema.replace("/msg/", "/").as_str() {
        "sensor_msgs/CompressedImage" => Some(Kind::Compressed),
        "sensor_msgs/Image" => Some(Kind::Raw),
        "sensor_msgs/NavSatFix" => Some(Kind::NavSat),
        "sensor_msgs/Imu" => Some(Kind::Imu),
        _ => None,
    }
}

/// Where one image is in the recording: the ordinal of its message among the messages the
/// reader hands over (the same on every read of the same file), its record and topic.
#[derive(Clone, Debug)]
struct ImageRef {
    ordinal: u64,
    record: u64,
    topic: String,
    dimensions: Option<(u32, u32)>,
}

struct State<'o> {
    out: PathBuf,
    /// Messages seen so far (the ordinal of the next one).
    ordinal: u64,
    /// [`ImageOutput::InRecording`]: each image name's place in the recording.
    refs: HashMap<String, ImageRef>,
    file: PathBuf,
    options: &'o McapImportOptions,
    images: Vec<StampedImage>,
    names: HashSet<String>,
    content: DriveContent,
    report: ImportReport,
    /// Topics skipped as a whole, with the reason, and their message count.
    skipped_topics: BTreeMap<String, (String, u64)>,
    ignored_types: BTreeMap<String, u64>,
    cameras: HashMap<String, Option<usize>>,
    error: Option<ImportError>,
    /// Whether the last NavSatFix had no fix (one warning per outage, not per epoch).
    in_outage: bool,
}

impl State<'_> {
    fn warn_record(&mut self, m: &McapMessage<'_>, what: String) {
        self.report.skipped += 1;
        self.report.warn(format!(
            "{}: record {}: topic {}: {what}",
            self.file.display(),
            m.record,
            m.topic
        ));
    }

    fn skip_topic(&mut self, topic: &str, reason: String) {
        self.report.skipped += 1;
        self.skipped_topics
            .entry(topic.to_string())
            .or_insert((reason, 0))
            .1 += 1;
    }

    fn camera(&mut self, topic: &str) -> Option<usize> {
        if let Some(c) = self.cameras.get(topic) {
            return *c;
        }
        let c = match &self.options.topics {
            Some(map) => map.get(topic).copied(),
            None => camera_of_topic(topic).filter(|&c| c < MAX_IMAGE_COLUMNS),
        };
        self.cameras.insert(topic.to_string(), c);
        c
    }

    fn message(&mut self, m: &McapMessage<'_>) {
        let ordinal = self.ordinal;
        self.ordinal += 1;
        if self.error.is_some() {
            return;
        }
        let Some(kind) = kind_of(m.schema) else {
            *self
                .ignored_types
                .entry(
                    if m.schema.is_empty() {
                        "(no schema)"
                    } else {
                        m.schema
                    }
                    .to_string(),
                )
                .or_insert(0) += 1;
            return;
        };
        if m.encoding != "cdr" {
            self.skip_topic(
                m.topic,
                format!(
                    "message encoding `{}` is not supported (only `cdr`, as rosbag2 writes)",
                    m.encoding
                ),
            );
            return;
        }
        match kind {
            Kind::Compressed | Kind::Raw => self.image(m, kind, ordinal),
            Kind::NavSat => self.navsat(m),
            Kind::Imu => match ros_decode::imu(m.data) {
                Ok(imu) => {
                    let c = imu.orientation_covariance;
                    // A sample the replay could not use (NaN, zero quaternion, …) is refused
                    // here, naming the record and the field.
                    let [x, y, z, w] = imu.orientation;
                    if let Err(e) = vgps_replay::drive::imu::ImuSample::try_new(
                        0.0,
                        [x, y, z, w],
                        [c[0], c[4], c[8]],
                        imu.angular_velocity,
                        imu.linear_acceleration,
                    ) {
                        return self.warn_record(
                            m,
                            format!("Imu: field `{}`: {}; skipped", e.field, e.reason),
                        );
                    }
                    self.content.imu.push(ImuRow {
                        time_s: seconds_of_ns(stamp_or_log_time(&imu.header, m)),
                        orientation: imu.orientation,
                        orientation_variance: [c[0], c[4], c[8]],
                        angular_velocity: imu.angular_velocity,
                        linear_acceleration: imu.linear_acceleration,
                    });
                }
                Err(e) => self.warn_record(m, format!("Imu: {e}; skipped")),
            },
        }
    }

    fn image(&mut self, m: &McapMessage<'_>, kind: Kind, ordinal: u64) {
        let Some(camera) = self.camera(m.topic) else {
            let why = match &self.options.topics {
                Some(_) => "image topic not in the topic mapping file".to_string(),
                None => {
                    "image topic without a camera number in its name (give a topic mapping file)"
                        .to_string()
                }
            };
            self.skip_topic(m.topic, why);
            return;
        };
        let in_recording = self.options.images == ImageOutput::InRecording;
        let decoded = match kind {
            Kind::Compressed => ros_decode::compressed_image(m.data)
                .map_err(|e| e.to_string())
                .and_then(|img| {
                    let ext = compressed_extension(img.format, img.data)?;
                    let stamp = stamp_or_log_time(&img.header, m);
                    Ok(if in_recording {
                        (stamp, ext, Vec::new(), bytes_dimensions(img.data))
                    } else {
                        (stamp, ext, img.data.to_vec(), None)
                    })
                }),
            _ => ros_decode::raw_image(m.data)
                .map_err(|e| e.to_string())
                .and_then(|img| {
                    let stamp = stamp_or_log_time(&img.header, m);
                    if in_recording {
                        // Checked now (the same checks as the conversion), converted when
                        // the replay reads it.
                        raw_layout(&img)?;
                        Ok((stamp, "png", Vec::new(), Some((img.width, img.height))))
                    } else {
                        Ok((stamp, "png", raw_image_to_png(&img)?, None))
                    }
                }),
        };
        let (stamp, ext, bytes, dimensions) = match decoded {
            Ok(x) => x,
            Err(e) => return self.warn_record(m, format!("image: {e}; skipped")),
        };
        let mut name = format!("images/cam{camera}/{stamp}.{ext}");
        let mut k = 1;
        while self.names.contains(&name) {
            name = format!("images/cam{camera}/{stamp}_{k}.{ext}");
            k += 1;
        }
        if in_recording {
            self.refs.insert(
                name.clone(),
                ImageRef {
                    ordinal,
                    record: m.record,
                    topic: m.topic.to_string(),
                    dimensions,
                },
            );
        } else {
            let path = self.out.join(&name);
            if let Some(dir) = path.parent()
                && let Err(e) = create_dir(dir)
            {
                self.error = Some(e);
                return;
            }
            if let Err(source) = vgps_io::write_atomic(&path, &bytes) {
                self.error = Some(ImportError::Write { path, source });
                return;
            }
        }
        self.names.insert(name.clone());
        self.images.push(StampedImage {
            time_ns: stamp,
            camera,
            path: name,
        });
    }

    fn navsat(&mut self, m: &McapMessage<'_>) {
        let fix = match ros_decode::nav_sat_fix(m.data) {
            Ok(f) => f,
            Err(e) => return self.warn_record(m, format!("NavSatFix: {e}; skipped")),
        };
        let time_s = seconds_of_ns(stamp_or_log_time(&fix.header, m));
        let position = Geodetic::try_new(fix.latitude, fix.longitude, fix.altitude)
            .ok()
            .filter(|_| fix.latitude.abs() <= 90.0 && fix.longitude.abs() <= 180.0);
        let quality = match fix.status {
            0 => Some(1),
            1 => Some(2),
            2 => Some(4),
            _ => None,
        };
        let gnss_fix = match (quality, position) {
            (Some(quality), Some(position)) => {
                self.in_outage = false;
                Some(GnssFix {
                    position,
                    quality,
                    hdop: None,
                    num_sats: None,
                })
            }
            (None, _) => {
                if !self.in_outage {
                    self.report.warn(format!(
                        "{}: record {}: topic {}: NavSatFix status {} (no fix): epochs without fix from here to the next fix",
                        self.file.display(),
                        m.record,
                        m.topic,
                        fix.status
                    ));
                }
                self.in_outage = true;
                None
            }
            (Some(_), None) => {
                return self.warn_record(
                    m,
                    format!(
                        "NavSatFix position {}, {}, {} is not a valid position; skipped",
                        fix.latitude, fix.longitude, fix.altitude
                    ),
                );
            }
        };
        self.content.gnss.push(GnssRecord {
            time_s,
            fix: gnss_fix,
            heading_deg: None,
        });
        self.content.navsat.push(NavSatRow {
            time_s,
            status: fix.status,
            service: fix.service,
            lat_lon_alt: [fix.latitude, fix.longitude, fix.altitude],
            covariance_type: fix.position_covariance_type,
            covariance: fix.position_covariance,
        });
    }
}

/// The header stamp, or the log time when the stamp is zero (a driver that sets none).
fn stamp_or_log_time(header: &ros_decode::Header, m: &McapMessage<'_>) -> i64 {
    match header.stamp_ns() {
        0 => i64::try_from(m.log_time).unwrap_or(i64::MAX),
        s => s,
    }
}

/// The file extension of a compressed image from its `format`, else its magic bytes.
fn compressed_extension(format: &str, data: &[u8]) -> Result<&'static str, String> {
    let f = format.to_ascii_lowercase();
    if f.contains("jpeg") || f.contains("jpg") || data.starts_with(&[0xff, 0xd8]) {
        Ok("jpg")
    } else if f.contains("png") || data.starts_with(b"\x89PNG") {
        Ok("png")
    } else if f.contains("tiff") || data.starts_with(b"II*\0") || data.starts_with(b"MM\0*") {
        Ok("tiff")
    } else {
        Err(format!(
            "compressed image format `{format}` is not JPEG, PNG or TIFF"
        ))
    }
}

/// A `sensor_msgs/Image` as PNG (`mono8`, `8UC1`, `mono16`, `16UC1`, `rgb8`, `bgr8`, `rgba8`,
/// `bgra8`): what the import writes for a raw image.
///
/// # Errors
/// The reason, for an unsupported encoding, an empty or too large image
/// (more than [`MAX_RAW_PIXELS`]), a `step` shorter than a row or too few data bytes.
pub fn raw_image_to_png(img: &ros_decode::RawImage<'_>) -> Result<Vec<u8>, String> {
    let (color, channels, bytes, swap_rb) = raw_layout(img)?;
    let (w, h) = (u64::from(img.width), u64::from(img.height));
    let row = w * channels * bytes;
    let step = u64::from(img.step);
    let mut pixels = Vec::with_capacity((row * h) as usize);
    for y in 0..h as usize {
        let start = y * step as usize;
        pixels.extend_from_slice(&img.data[start..start + row as usize]);
    }
    let px = (channels * bytes) as usize;
    if swap_rb {
        for p in pixels.chunks_exact_mut(px) {
            p.swap(0, 2);
        }
    }
    if bytes == 2 && img.is_bigendian != cfg!(target_endian = "big") {
        // The encoder takes 16-bit samples in native byte order.
        for p in pixels.chunks_exact_mut(2) {
            p.swap(0, 1);
        }
    }
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
        .write_image(&pixels, img.width, img.height, color)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// The colour type, channels, bytes per sample and whether red and blue are swapped of a
/// raw image, after checking its encoding, size and data length.
fn raw_layout(
    img: &ros_decode::RawImage<'_>,
) -> Result<(ExtendedColorType, u64, u64, bool), String> {
    let (color, channels, bytes, swap_rb) = match img.encoding {
        "mono8" | "8UC1" => (ExtendedColorType::L8, 1, 1, false),
        "mono16" | "16UC1" => (ExtendedColorType::L16, 1, 2, false),
        "rgb8" => (ExtendedColorType::Rgb8, 3, 1, false),
        "bgr8" => (ExtendedColorType::Rgb8, 3, 1, true),
        "rgba8" => (ExtendedColorType::Rgba8, 4, 1, false),
        "bgra8" => (ExtendedColorType::Rgba8, 4, 1, true),
        other => return Err(format!("raw image encoding `{other}` is not supported")),
    };
    let (w, h) = (u64::from(img.width), u64::from(img.height));
    if w == 0 || h == 0 || w * h > MAX_RAW_PIXELS {
        return Err(format!("raw image of {w}x{h} pixels is empty or too large"));
    }
    let row = w * channels * bytes;
    let step = u64::from(img.step);
    if step < row || (img.data.len() as u64) < step * (h - 1) + row {
        return Err(format!(
            "raw image {w}x{h} `{}` step {step}: {} data bytes are too few",
            img.encoding,
            img.data.len()
        ));
    }
    Ok((color, channels, bytes, swap_rb))
}

/// `(width, height)` from a PNG's IHDR or a JPEG's start-of-frame segment, `None` for
/// anything else (the replay then reports the image when it decodes it).
fn bytes_dimensions(data: &[u8]) -> Option<(u32, u32)> {
    if data.len() >= 24 && data[..8] == *b"\x89PNG\r\n\x1a\n" && data[12..16] == *b"IHDR" {
        let be = |i: usize| u32::from_be_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
        return Some((be(16), be(20)));
    }
    if !data.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let h = vgps_camera::imaging::formats::jpeg_frame_header(&data[..data.len().min(256 * 1024)])?;
    Some((u32::from(h.width), u32::from(h.height)))
}

/// The outcome of an MCAP import.
#[derive(Debug)]
pub struct McapImport {
    /// The manifest written.
    pub manifest: Manifest,
    /// Counts and warnings.
    pub report: ImportReport,
    /// What the MCAP reader read and skipped.
    pub mcap: McapReadSummary,
    /// Message types ignored, with their counts.
    pub ignored_types: BTreeMap<String, u64>,
    /// [`ImageOutput::InRecording`]: where the frames' images are in the recording.
    pub recording_images: Option<RecordingImages>,
}

/// Imports `file` (a rosbag2 MCAP) into the drive folder `out`.
///
/// # Errors
/// [`ImportError`] when the file cannot be read at all or a drive file cannot be written;
/// damaged records and unusable messages are warnings in the report.
pub fn import_mcap(
    file: &Path,
    out: &Path,
    options: &McapImportOptions,
) -> Result<McapImport, ImportError> {
    // The inputs named by the options are checked before anything is written.
    for p in std::iter::once(&options.rig).chain(&options.landmarks) {
        std::fs::metadata(p).map_err(|source| ImportError::Read {
            path: p.clone(),
            source,
        })?;
    }
    let mut state = State {
        out: out.to_path_buf(),
        ordinal: 0,
        refs: HashMap::new(),
        file: file.to_path_buf(),
        options,
        images: Vec::new(),
        names: HashSet::new(),
        content: DriveContent::default(),
        report: ImportReport::default(),
        skipped_topics: BTreeMap::new(),
        ignored_types: BTreeMap::new(),
        cameras: HashMap::new(),
        error: None,
        in_outage: false,
    };
    let mcap = read_mcap_file(file, &mut |m| state.message(m))?;
    if let Some(e) = state.error.take() {
        return Err(e);
    }
    let mut report = std::mem::take(&mut state.report);
    for w in mcap.messages() {
        report.warn(w);
    }
    for (topic, (reason, n)) in &state.skipped_topics {
        report.warn(format!(
            "{}: topic {topic}: {reason}; its {n} message(s) skipped",
            file.display()
        ));
    }
    let mut content = std::mem::take(&mut state.content);
    content.gnss.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    content.navsat.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    content.imu.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let tolerance_ns = (options.stamp_tolerance_s * 1e9).round() as i64;
    content.frames = assemble_frames(std::mem::take(&mut state.images), tolerance_ns);
    let recording_images = (options.images == ImageOutput::InRecording)
        .then(|| RecordingImages::new(file, &content.frames, std::mem::take(&mut state.refs)));
    let manifest = write_drive(
        out,
        &options.rig,
        options.landmarks.as_deref(),
        &content,
        &mut report,
    )?;
    Ok(McapImport {
        manifest,
        report,
        mcap,
        ignored_types: state.ignored_types,
        recording_images,
    })
}

/// Where the images of an imported recording's frames are ([`ImageOutput::InRecording`]):
/// each image's message, found again by its ordinal on a second read of the file.
#[derive(Clone, Debug)]
pub struct RecordingImages {
    file: PathBuf,
    /// Image name (as in the frames) → its place in the recording.
    refs: HashMap<String, ImageRef>,
    /// Message ordinal → (frame position, camera).
    wanted: Arc<HashMap<u64, (usize, usize)>>,
    /// Per frame position: the frame number and the cameras that name an image.
    frames: Arc<Vec<(u64, Vec<bool>)>>,
}

/// The images of one frame read back from the recording ([`RecordingImages::stream`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameImages {
    /// The frame number.
    pub frame: u64,
    /// Per camera: `None` where the frame names no image; else the image's bytes as a
    /// drive file would hold them (a compressed image as recorded, a raw image as PNG), or
    /// why they could not be read again.
    pub images: Vec<Option<Result<Vec<u8>, String>>>,
}

/// Frames' images read from the recording in frame order by a reader thread, at most a few
/// frames ahead of their use ([`RecordingImages::stream`]).
#[derive(Debug)]
pub struct FrameStream {
    frames: Option<std::sync::mpsc::Receiver<FrameImages>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Iterator for FrameStream {
    type Item = FrameImages;

    fn next(&mut self) -> Option<FrameImages> {
        self.frames.as_ref()?.recv().ok()
    }
}

impl Drop for FrameStream {
    fn drop(&mut self) {
        // The reader stops at its next frame once nobody receives.
        self.frames = None;
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
    }
}

impl RecordingImages {
    fn new(file: &Path, frames: &[FrameRecord], refs: HashMap<String, ImageRef>) -> Self {
        let mut wanted = HashMap::new();
        let mut named = Vec::with_capacity(frames.len());
        for (position, f) in frames.iter().enumerate() {
            for (camera, name) in f.images.iter().enumerate() {
                if let Some(r) = name.as_ref().and_then(|n| refs.get(n)) {
                    wanted.insert(r.ordinal, (position, camera));
                }
            }
            named.push((f.frame, f.images.iter().map(Option::is_some).collect()));
        }
        Self {
            file: file.to_path_buf(),
            refs,
            wanted: Arc::new(wanted),
            frames: Arc::new(named),
        }
    }

    /// The recording.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Whether `name` (an image name of the frames) is an image of the recording.
    pub fn contains(&self, name: &str) -> bool {
        self.refs.contains_key(name)
    }

    /// `(width, height)` of image `name` from its PNG or JPEG header (a raw image: its
    /// fields); `None` when the header gives none or `name` is not an image of the
    /// recording.
    pub fn dimensions(&self, name: &str) -> Option<(u32, u32)> {
        self.refs.get(name)?.dimensions
    }

    /// How messages name image `name`: `FILE: record N (TOPIC)`.
    pub fn describe(&self, name: &str) -> PathBuf {
        match self.refs.get(name) {
            Some(r) => PathBuf::from(format!(
                "{}: record {} ({})",
                self.file.display(),
                r.record,
                r.topic
            )),
            None => self.file.join(name),
        }
    }

    /// Reads the recording again on a thread and yields every frame's images, in the order
    /// of the frames, as soon as the last of them is read. At most `ahead` finished frames
    /// wait to be taken, besides the frames whose images are still being read (those the
    /// recording interleaves with later frames: one or two for a recording in time order),
    /// so memory stays bounded however long the recording. A frame whose image is no longer
    /// found (the file changed between the reads, a chunk unreadable) comes with the reason
    /// in place of that image's bytes.
    pub fn stream(&self, ahead: usize) -> FrameStream {
        let (tx, rx) = std::sync::mpsc::sync_channel(ahead.max(1));
        let file = self.file.clone();
        let wanted = Arc::clone(&self.wanted);
        let frames = Arc::clone(&self.frames);
        let reader = std::thread::spawn(move || {
            let mut pending: BTreeMap<usize, (usize, FrameImages)> = BTreeMap::new();
            let mut next = 0usize;
            let mut ordinal = 0u64;
            let expected = |p: usize| frames[p].1.iter().filter(|&&b| b).count();
            let new_frame = |p: usize| {
                (
                    0,
                    FrameImages {
                        frame: frames[p].0,
                        images: vec![None; frames[p].1.len()],
                    },
                )
            };
            let read = read_mcap_file_until(&file, &mut |m| {
                let o = ordinal;
                ordinal += 1;
                let Some(&(position, camera)) = wanted.get(&o) else {
                    return ControlFlow::Continue(());
                };
                if position < next {
                    return ControlFlow::Continue(());
                }
                let entry = pending
                    .entry(position)
                    .or_insert_with(|| new_frame(position));
                if let Some(slot) = entry.1.images.get_mut(camera)
                    && slot.is_none()
                {
                    *slot = Some(image_bytes(m));
                    entry.0 += 1;
                }
                while next < frames.len()
                    && pending
                        .get(&next)
                        .map_or(expected(next) == 0, |(got, _)| *got >= expected(next))
                {
                    let (_, f) = pending.remove(&next).unwrap_or_else(|| new_frame(next));
                    if tx.send(f).is_err() {
                        return ControlFlow::Break(());
                    }
                    next += 1;
                }
                ControlFlow::Continue(())
            });
            // The rest of the frames, with what was found; a missing image says why.
            let why = match &read {
                Ok(s) if s.truncated || s.bad_chunks > 0 => format!(
                    "not found on reading {} again (the recording is damaged)",
                    file.display()
                ),
                Ok(_) => format!(
                    "not found on reading {} again (the recording changed)",
                    file.display()
                ),
                Err(e) => e.to_string(),
            };
            for position in next..frames.len() {
                let (_, mut f) = pending
                    .remove(&position)
                    .unwrap_or_else(|| new_frame(position));
                for (slot, named) in f.images.iter_mut().zip(&frames[position].1) {
                    if *named && slot.is_none() {
                        *slot = Some(Err(why.clone()));
                    }
                }
                if tx.send(f).is_err() {
                    return;
                }
            }
        });
        FrameStream {
            frames: Some(rx),
            reader: Some(reader),
        }
    }
}

/// The bytes of an image message as a drive file would hold them.
fn image_bytes(m: &McapMessage<'_>) -> Result<Vec<u8>, String> {
    match kind_of(m.schema) {
        Some(Kind::Compressed) => ros_decode::compressed_image(m.data)
            .map(|img| img.data.to_vec())
            .map_err(|e| e.to_string()),
        Some(Kind::Raw) => ros_decode::raw_image(m.data)
            .map_err(|e| e.to_string())
            .and_then(|img| raw_image_to_png(&img)),
        _ => Err(format!("record {}: not an image message", m.record)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn naming_rule_takes_the_last_number() {
        assert_eq!(camera_of_topic("/lb3/cam12x/image"), Some(12));
        assert_eq!(camera_of_topic("/camera_0/image_raw"), Some(0));
        assert_eq!(camera_of_topic("/a5/b7"), Some(7));
        assert_eq!(camera_of_topic("/image"), None);
    }

    #[test]
    fn raw_bgr_becomes_rgb_png() {
        let data = [1u8, 2, 3, 4, 5, 6, 0, 0]; // 2x1 bgr8, step 8 (padding)
        let img = ros_decode::RawImage {
            header: ros_decode::Header {
                sec: 0,
                nanosec: 0,
                frame_id: String::new(),
            },
            height: 1,
            width: 2,
            encoding: "bgr8",
            is_bigendian: false,
            step: 8,
            data: &data,
        };
        let png = raw_image_to_png(&img).unwrap();
        let decoded = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
        assert_eq!(&decoded.to_rgb8().as_raw()[..6], &[3, 2, 1, 6, 5, 4]);
        let short = ros_decode::RawImage {
            data: &data[..5],
            ..img
        };
        assert!(raw_image_to_png(&short).unwrap_err().contains("too few"));
    }
}
