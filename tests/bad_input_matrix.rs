//! The bad-input matrix: malformed or hostile inputs to every `vgps` subcommand, one row
//! each. Every row runs the built binary in a fresh temporary directory and asserts
//! - the exit code (0 success with per-item failures reported, 1 output error, 2 unusable
//!   input; never a panic or an abort),
//! - that stderr contains the given substrings (the file, and the line or the field),
//! - that no temporary file (`*.tmp*`) is left anywhere in the directory, and, for a
//!   failing row, that the directory is byte-for-byte as it was before the run (no partial
//!   output).
//!
//! In the arguments and the expected substrings `{t}` is the row's temporary directory and
//! `{fx}` the committed fixtures directory (`tests/fixtures`).
mod common;

use common::fixture;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// One row of the matrix.
struct Row {
    /// What the row feeds in.
    name: &'static str,
    /// Writes the row's input files into the temporary directory.
    setup: fn(&Path),
    /// The command line (without `vgps`).
    args: &'static [&'static str],
    /// The expected exit code.
    code: i32,
    /// Substrings stderr must contain.
    stderr: &'static [&'static str],
}

/// A small drive with images (3 frames, 6 PNGs each), simulated once per test run.
fn base_drive() -> &'static Path {
    static DRIVE: OnceLock<tempfile::TempDir> = OnceLock::new();
    DRIVE
        .get_or_init(|| {
            let dir = tempfile::tempdir().expect("temp dir");
            let out = dir.path().join("drive");
            let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
                .args([
                    "simulate",
                    "--preset",
                    "short",
                    "--length-m",
                    "3",
                    "--images",
                ])
                .args(["--quiet", "--out"])
                .arg(&out)
                .output()
                .expect("vgps runs");
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            dir
        })
        .path()
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read dir") {
        let e = e.expect("entry");
        let target = to.join(e.file_name());
        if e.file_type().expect("type").is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).expect("copy");
        }
    }
}

/// Copies the base drive to `t/d`.
fn drive(t: &Path) -> PathBuf {
    let d = t.join("d");
    copy_dir(&base_drive().join("drive"), &d);
    d
}

fn write(t: &Path, name: &str, bytes: impl AsRef<[u8]>) {
    std::fs::write(t.join(name), bytes).expect("write");
}

fn fixture_text(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).expect("fixture")
}

/// Replaces camera 0's image of frame 0 by `images/000000_0.<ext>` holding the bytes
/// `make` builds from that frame's decoded image, and names it in `frames.csv`.
fn replace_image(t: &Path, ext: &str, make: fn(&image::GrayImage) -> Vec<u8>) {
    let d = drive(t);
    let png = d.join("images/000000_0.png");
    let grey = vgps::imaging::read_image(&png, &vgps::imaging::DecodeLimits::default())
        .expect("drive image");
    std::fs::write(d.join(format!("images/000000_0.{ext}")), make(&grey)).expect("write");
    let frames = std::fs::read_to_string(d.join("frames.csv")).expect("frames");
    let renamed = frames.replace("images/000000_0.png", &format!("images/000000_0.{ext}"));
    assert_ne!(frames, renamed);
    std::fs::write(d.join("frames.csv"), renamed).expect("write");
}

/// A colour JPEG (quality 90) of `grey`.
fn jpeg_of(grey: &image::GrayImage) -> Vec<u8> {
    let rgb = image::DynamicImage::ImageLuma8(grey.clone()).to_rgb8();
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
        .encode_image(&rgb)
        .expect("jpeg");
    bytes
}

/// A JPEG of `grey` whose baseline frame header is patched by `patch(header_bytes)`.
fn patched_jpeg(grey: &image::GrayImage, patch: fn(&mut [u8])) -> Vec<u8> {
    let mut b = jpeg_of(grey);
    let at = (2..b.len() - 1)
        .find(|&i| b[i] == 0xFF && b[i + 1] == 0xC0)
        .expect("SOF0");
    patch(&mut b[at + 4..at + 10]);
    b
}

/// The real Ladybug5+ `.conf` (tests/data/ladybug5p, MIT, BEAMRobotics/libbeam).
fn real_conf() -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ladybug5p/ladybug5p.conf"),
    )
    .expect("the real .conf")
}

/// Deterministic binary garbage (invalid UTF-8 on its first line).
fn garbage() -> Vec<u8> {
    (0..2000u32).map(|i| ((i * 37 + 128) % 256) as u8).collect()
}

/// A regular file `t/file` (an output path under it fails with ENOTDIR, even for root).
fn regular_file(t: &Path) {
    write(t, "file", "not a directory\n");
}

/// The PNG `path` with its IHDR rewritten to claim `width × height` (valid CRC).
fn claim_png_size(path: &Path, width: u32, height: u32) {
    let mut b = std::fs::read(path).expect("png");
    b[16..20].copy_from_slice(&width.to_be_bytes());
    b[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = crc32(&b[12..29]);
    b[29..33].copy_from_slice(&crc.to_be_bytes());
    std::fs::write(path, b).expect("write png");
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

const L: &str = "id,lat,lon,alt\n";
const R: &str = "id,lat,lon,alt,de,dn,du\n";

/// The committed MCAP test files (`tests/data/mcap`, written by `make_mcap.py`).
fn mcap_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mcap")
}

fn copy_mcap(t: &Path) {
    for f in ["run.mcap", "bad.mcap", "small_rig.json"] {
        std::fs::copy(mcap_data().join(f), t.join(f)).expect("copy");
    }
}

fn cut_mcap(t: &Path) {
    copy_mcap(t);
    let bytes = std::fs::read(t.join("run.mcap")).expect("read");
    write(t, "cut.mcap", &bytes[..bytes.len() * 6 / 10]);
}

fn crc_mcap(t: &Path) {
    copy_mcap(t);
    let mut bytes = std::fs::read(t.join("bad.mcap")).expect("read");
    let second_png = bytes
        .windows(4)
        .enumerate()
        .filter(|(_, w)| *w == b"\x89PNG")
        .nth(1)
        .expect("two PNGs")
        .0;
    bytes[second_png + 100] ^= 0x55;
    write(t, "crc.mcap", bytes);
}

fn garbage_mcap(t: &Path) {
    copy_mcap(t);
    write(t, "x.mcap", garbage());
}

fn bad_topic_map(t: &Path) {
    copy_mcap(t);
    write(t, "topics.csv", "topic,camera\n/a,x\n");
}

fn nclt_without_lb3(t: &Path) {
    copy_mcap(t);
    std::fs::create_dir_all(t.join("session/sensor_data")).expect("mkdir");
}

fn nclt_bad_ground_truth(t: &Path) {
    copy_mcap(t);
    let cam = t.join("session/lb3/Cam0");
    std::fs::create_dir_all(&cam).expect("mkdir");
    write(&cam, "1353099827000000.tiff", b"");
    write(
        &t.join("session"),
        "groundtruth_2012-11-16.csv",
        "1353099827000000,1,2\n",
    );
}

fn folders_without_cameras(t: &Path) {
    copy_mcap(t);
    std::fs::create_dir_all(t.join("root/notes")).expect("mkdir");
}

fn folders_image_without_time(t: &Path) {
    copy_mcap(t);
    let cam = t.join("root/cam0");
    std::fs::create_dir_all(&cam).expect("mkdir");
    write(&cam, "1700000000.png", b"");
    write(&cam, "frame.png", b"");
}

fn rows() -> Vec<Row> {
    vec![
        // ---- vgps locate: landmarks ----
        Row {
            name: "landmarks: empty file",
            setup: |t| write(t, "L.csv", ""),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:1: field `header`", "empty"],
        },
        Row {
            name: "landmarks: binary garbage",
            setup: |t| write(t, "L.csv", garbage()),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:1:", "UTF-8"],
        },
        Row {
            name: "landmarks: wrong header",
            setup: |t| write(t, "L.csv", "name,latitude,longitude,height\nx,1,2,3\n"),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:1: field `name`", "unknown column"],
        },
        Row {
            name: "landmarks: truncated in the middle of a row",
            setup: |t| write(t, "L.csv", &fixture_text("landmarks.csv")[..100]),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:3: field `lat`", "missing value"],
        },
        Row {
            name: "landmarks: NaN height",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/bad_landmarks_nan.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["bad_landmarks_nan.csv:3: field `alt`", "NaN"],
        },
        Row {
            name: "landmarks: infinite height",
            setup: |t| write(t, "L.csv", format!("{L}lamp1,37.79,-122.39,inf\n")),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:2: field `alt`", "not a finite number"],
        },
        Row {
            name: "landmarks: absurd height 1e30 m names `alt`",
            setup: |t| {
                let text = fixture_text("landmarks.csv").replace(
                    "lamp2,37.795842364,-122.393529692,12.000",
                    "lamp2,37.795842364,-122.393529692,1e30",
                );
                write(t, "L.csv", text);
            },
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:4: field `alt`", "ellipsoidal height"],
        },
        Row {
            name: "landmarks: duplicate id",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/bad_landmarks_duplicate.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &[
                "bad_landmarks_duplicate.csv:4: field `id`",
                "lamp1",
                "line 2",
            ],
        },
        Row {
            name: "landmarks: latitude 95",
            setup: |t| write(t, "L.csv", format!("{L}lamp1,95,0,0\n")),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:2: field `lat`", "95"],
        },
        Row {
            name: "landmarks: negative sigma_m",
            setup: |t| write(t, "L.csv", "id,lat,lon,alt,sigma_m\nlamp1,37,-122,1,-0.5\n"),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv:2: field `sigma_m`", "negative"],
        },
        Row {
            name: "landmarks: lat/lon in radians (prior in degrees)",
            setup: |t| {
                let mut text = String::from(L);
                for line in fixture_text("landmarks.csv").lines().skip(2) {
                    let f: Vec<&str> = line.split(',').collect();
                    let lat: f64 = f[1].parse().expect("lat");
                    let lon: f64 = f[2].parse().expect("lon");
                    text += &format!(
                        "{},{},{},{}\n",
                        f[0],
                        lat.to_radians(),
                        lon.to_radians(),
                        f[3]
                    );
                }
                write(t, "L.csv", text);
            },
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
                "--prior",
                "37.7955,-122.3937,7,50",
            ],
            code: 2,
            stderr: &["--prior", "{t}/L.csv", "are the coordinates in degrees?"],
        },
        Row {
            name: "landmarks: a directory",
            setup: |t| std::fs::create_dir(t.join("L.csv")).expect("mkdir"),
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/L.csv: cannot read the file"],
        },
        Row {
            name: "landmarks: missing file",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{t}/nothing.csv",
                "--observations",
                "{fx}/observations.csv",
            ],
            code: 2,
            stderr: &["{t}/nothing.csv: cannot read the file"],
        },
        Row {
            name: "landmarks and observations: UTF-8 BOM and CRLF line endings are accepted",
            setup: |t| {
                let mut bytes = vec![0xEF, 0xBB, 0xBF];
                bytes.extend(fixture_text("landmarks.csv").replace('\n', "\r\n").bytes());
                write(t, "L.csv", bytes);
                write(
                    t,
                    "O.csv",
                    fixture_text("observations.csv").replace('\n', "\r\n"),
                );
            },
            args: &[
                "locate",
                "--landmarks",
                "{t}/L.csv",
                "--observations",
                "{t}/O.csv",
            ],
            code: 0,
            stderr: &["frame 2: 4 of 4 observations have no landmark id"],
        },
        // ---- vgps locate: prior and options ----
        Row {
            name: "prior in radians",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/observations.csv",
                "--prior",
                "0.6596,-2.1362,7,100",
            ],
            code: 2,
            stderr: &[
                "--prior LAT,LON 0.6596",
                "landmarks.csv",
                "km away",
                "are the coordinates in degrees?",
            ],
        },
        Row {
            name: "region in radians",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/observations.csv",
                "--region",
                "0.6596,-2.1362,7,1000",
            ],
            code: 2,
            stderr: &["--region LAT,LON 0.6596", "are the coordinates in degrees?"],
        },
        Row {
            name: "prior latitude 91",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/observations.csv",
                "--prior",
                "91,0,0,1",
            ],
            code: 2,
            stderr: &["--prior", "LAT 91"],
        },
        Row {
            name: "prior NaN",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/observations.csv",
                "--prior",
                "37,NaN,0,10",
            ],
            code: 2,
            stderr: &["--prior", "LON `NaN`"],
        },
        Row {
            name: "sigma infinite",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/observations.csv",
                "--sigma-deg",
                "inf",
            ],
            code: 2,
            stderr: &["--sigma-deg", "`inf`"],
        },
        // ---- vgps locate: observations ----
        Row {
            name: "observations: empty file",
            setup: |t| write(t, "O.csv", ""),
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{t}/O.csv",
            ],
            code: 2,
            stderr: &["{t}/O.csv:1: field `header`", "empty"],
        },
        Row {
            name: "observations: unknown landmark id",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/bad_observations_unknown_landmark.csv",
            ],
            code: 2,
            stderr: &[
                "bad_observations_unknown_landmark.csv:5: field `landmark`",
                "lamp33",
            ],
        },
        Row {
            name: "observations: a row with a missing field",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/bad_observations_fields.csv",
            ],
            code: 2,
            stderr: &["bad_observations_fields.csv:3: field"],
        },
        Row {
            name: "observations: zero bearing",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/bad_observations_zero_bearing.csv",
            ],
            code: 2,
            stderr: &[
                "bad_observations_zero_bearing.csv:3: field `bx`",
                "zero bearing",
            ],
        },
        Row {
            name: "observations: pixels without a calibration",
            setup: |_| {},
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{fx}/bad_observations_pixels.csv",
            ],
            code: 2,
            stderr: &[
                "bad_observations_pixels.csv:2: field `camera`",
                "--calibration",
            ],
        },
        Row {
            name: "observations: pixel 1e9 outside the image",
            setup: |t| write(t, "O.csv", "frame,camera,u,v,landmark\n0,0,1e9,3,lamp1\n"),
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{t}/O.csv",
                "--calibration",
                "{fx}/calibration/native_mixed.json",
            ],
            code: 2,
            stderr: &["{t}/O.csv:2: field `camera`", "outside"],
        },
        Row {
            name: "calibration with an absurd image size (locate)",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/native_mixed.json"))
                    .expect("json");
                write(
                    t,
                    "c.json",
                    text.replacen("\"width\": 64", "\"width\": 4000000000", 1),
                );
                write(t, "O.csv", "frame,camera,u,v,landmark\n0,0,1,3,lamp1\n");
            },
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{t}/O.csv",
                "--calibration",
                "{t}/c.json",
            ],
            code: 2,
            stderr: &["{t}/c.json", "cameras[0].camera", "exceeds 65536 pixels"],
        },
        Row {
            name: "calibration declaring the rig level within -3° (locate)",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/native_mixed.json"))
                    .expect("json");
                write(
                    t,
                    "c.json",
                    text.replacen(
                        "\"version\": 1,",
                        "\"version\": 1, \"level_within_deg\": -3,",
                        1,
                    ),
                );
                write(t, "O.csv", "frame,bx,by,bz\n0,1,0,0\n");
            },
            args: &[
                "locate",
                "--landmarks",
                "{fx}/landmarks.csv",
                "--observations",
                "{t}/O.csv",
                "--calibration",
                "{t}/c.json",
            ],
            code: 2,
            stderr: &["{t}/c.json", "level_within_deg", "-3"],
        },
        // ---- vgps triangulate ----
        Row {
            name: "rays: not a number",
            setup: |_| {},
            args: &["triangulate", "--rays", "{fx}/bad_rays_not_a_number.csv"],
            code: 2,
            stderr: &["bad_rays_not_a_number.csv:3: field `dn`", "north"],
        },
        Row {
            name: "rays: direction 1e308 overflows",
            setup: |t| {
                write(
                    t,
                    "R.csv",
                    format!(
                        "{R}s,37.7955,-122.3937,7,1e308,1e308,1e308\ns,37.7956,-122.3937,7,1,0,0\n"
                    ),
                )
            },
            args: &["triangulate", "--rays", "{t}/R.csv"],
            code: 2,
            stderr: &["{t}/R.csv:2: field `de`", "overflowing"],
        },
        Row {
            name: "rays: absurd observer height names `alt`",
            setup: |t| {
                write(
                    t,
                    "R.csv",
                    format!("{R}s,37.7955,-122.3937,1e30,1,0,0\ns,37.7956,-122.3937,7,1,0,0\n"),
                )
            },
            args: &["triangulate", "--rays", "{t}/R.csv"],
            code: 2,
            stderr: &["{t}/R.csv:2: field `alt`", "ellipsoidal height"],
        },
        Row {
            name: "rays: zero sigma_ang_deg",
            setup: |t| {
                write(
                    t,
                    "R.csv",
                    "id,lat,lon,alt,de,dn,du,sigma_ang_deg\ns,37,-122,7,1,0,0,0\n",
                )
            },
            args: &["triangulate", "--rays", "{t}/R.csv"],
            code: 2,
            stderr: &["{t}/R.csv:2: field `sigma_ang_deg`", "not positive"],
        },
        Row {
            name: "rays: a landmarks file instead",
            setup: |_| {},
            args: &["triangulate", "--rays", "{fx}/landmarks.csv"],
            code: 2,
            stderr: &["landmarks.csv:2: field `sigma_m`", "unknown column"],
        },
        Row {
            name: "rays: duplicated rays (no parallax) are reported, not fatal",
            setup: |t| {
                write(
                    t,
                    "R.csv",
                    format!(
                        "{R}s,37.7955,-122.3937,7,0.43,0.89,0.07\ns,37.7955,-122.3937,7,0.43,0.89,0.07\n"
                    ),
                )
            },
            args: &["triangulate", "--rays", "{t}/R.csv"],
            code: 0,
            stderr: &["{t}/R.csv: id `s` (line 2, 3): not triangulated"],
        },
        Row {
            name: "rays: UTF-8 BOM and CRLF are accepted",
            setup: |t| {
                let mut bytes = vec![0xEF, 0xBB, 0xBF];
                bytes.extend(fixture_text("rays.csv").replace('\n', "\r\n").bytes());
                write(t, "R.csv", bytes);
            },
            args: &["triangulate", "--rays", "{t}/R.csv"],
            code: 0,
            stderr: &["{t}/R.csv: id `tree3` (line 9)"],
        },
        // ---- vgps calib ----
        Row {
            name: "calib: JSON width 4e9 (would allocate 64 GB)",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/native_mixed.json"))
                    .expect("json");
                write(
                    t,
                    "c.json",
                    text.replacen("\"width\": 64", "\"width\": 4000000000", 1),
                );
            },
            args: &["calib", "show", "{t}/c.json"],
            code: 2,
            stderr: &[
                "{t}/c.json: cameras[0].camera",
                "4000000000×48 exceeds 65536",
            ],
        },
        Row {
            name: "calib: Ladybug INI claiming 100000000×100000000",
            setup: |t| {
                let text =
                    std::fs::read_to_string(fixture("calibration/ladybug_64x48.ini")).expect("ini");
                write(
                    t,
                    "c.ini",
                    text.replace("image_width = 64", "image_width = 100000000")
                        .replace("image_height = 48", "image_height = 100000000"),
                );
            },
            args: &["calib", "check", "{t}/c.ini"],
            code: 2,
            stderr: &["{t}/c.ini: line 2, key image_width"],
        },
        Row {
            name: "calib: NaN focal length",
            setup: |t| {
                let text =
                    std::fs::read_to_string(fixture("calibration/ladybug_64x48.ini")).expect("ini");
                write(
                    t,
                    "c.ini",
                    text.replace("camera0_FocalLen = 40", "camera0_FocalLen = nan"),
                );
            },
            args: &["calib", "show", "{t}/c.ini"],
            code: 2,
            stderr: &["{t}/c.ini: line 10, key camera0_FocalLen", "not finite"],
        },
        Row {
            name: "calib: Ladybug .conf with a missing warp id",
            setup: |t| {
                write(
                    t,
                    "c.conf",
                    real_conf().replace("RectifiedSpline 8 9", "RectifiedSpline 8 99"),
                )
            },
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &[
                "{t}/c.conf: line 39, field RectifiedSpline",
                "warp id 99 is not defined",
            ],
        },
        Row {
            name: "calib: Ladybug .conf with a duplicated warp id",
            setup: |t| write(t, "c.conf", real_conf().replace("  Id 47\n", "  Id 46\n")),
            args: &["calib", "check", "{t}/c.conf"],
            code: 2,
            stderr: &["{t}/c.conf: line 6219, field Id", "warp id 46 is repeated"],
        },
        Row {
            name: "calib: Ladybug .conf with decreasing knots",
            setup: |t| {
                write(
                    t,
                    "c.conf",
                    real_conf().replacen("0.05 0.1 0.15", "0.05 0.01 0.15", 1),
                )
            },
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &[
                "{t}/c.conf: line 178, field KnotsX",
                "knots must not decrease",
            ],
        },
        Row {
            name: "calib: Ladybug .conf with a coefficient count that is not nx·ny",
            setup: |t| write(t, "c.conf", real_conf().replacen("  0.00362313 ", "  ", 1)),
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &[
                "{t}/c.conf: line 181, field Coefs",
                "528 coefficients, but NumberCoefs 23 23",
            ],
        },
        Row {
            name: "calib: Ladybug .conf with a NaN coefficient",
            setup: |t| write(t, "c.conf", real_conf().replacen("0.00362313", "nan", 1)),
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &["{t}/c.conf: line 182, field Coefs", "not finite"],
        },
        Row {
            name: "calib: Ladybug .conf truncated in a warp block",
            setup: |t| write(t, "c.conf", &real_conf()[..330_000]),
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &["{t}/c.conf: line 6218, field BeginWarp", "block not closed"],
        },
        Row {
            name: "calib: Ladybug .conf of an unknown Version",
            setup: |t| {
                write(
                    t,
                    "c.conf",
                    real_conf().replace("Ladybug 2.0", "Ladybug 3.0"),
                )
            },
            args: &["calib", "show", "{t}/c.conf"],
            code: 2,
            stderr: &["{t}/c.conf: line 1, field Version", "unknown version"],
        },
        Row {
            name: "calib: Ladybug INI dump (dotted spelling) missing a required key",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/ladybug_64x48.ini"))
                    .expect("ini")
                    .replace("camera2_transZ = 0\n", "")
                    .replace(" = ", " ")
                    .replacen(
                        "camera",
                        "#camera_model Ladybug5 LD5-U3-51S5C-44\ncamera",
                        1,
                    );
                write(
                    t,
                    "c.ini",
                    text.replace("_rot", ".rot").replace("_trans", ".trans"),
                );
            },
            args: &["calib", "show", "{t}/c.ini"],
            code: 2,
            stderr: &["{t}/c.ini: key camera2_transZ", "missing key"],
        },
        Row {
            name: "calib: Ladybug INI dump (underscore spelling) with a value that is not a number",
            setup: |t| {
                let text = fixture_text("calibration/ladybug_64x48.ini")
                    .replace("camera1_FocalLen = 40", "camera1_FocalLen = forty");
                write(t, "c.ini", text);
            },
            args: &["calib", "show", "{t}/c.ini"],
            code: 2,
            stderr: &["{t}/c.ini", "camera1_FocalLen"],
        },
        Row {
            name: "calib: NCLT directory with a K_cam file that is not a matrix",
            setup: |t| {
                copy_dir(Path::new(&fixture("calibration/nclt_16x12")), &t.join("n"));
                write(t, "n/K_cam1.csv", "10,0,7.5\n0,ten,5.5\n0,0,1\n");
            },
            args: &["calib", "show", "{t}/n"],
            code: 2,
            stderr: &["{t}/n/K_cam1.csv"],
        },
        Row {
            name: "calib: NCLT mask of the wrong size",
            setup: |t| {
                copy_dir(Path::new(&fixture("calibration/nclt_16x12")), &t.join("n"));
                let small = image::GrayImage::from_fn(8, 6, |_, _| image::Luma([0]));
                let mut png = Vec::new();
                small
                    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                    .expect("png");
                write(t, "n/mask_cam2.png", png);
            },
            args: &["calib", "show", "{t}/n"],
            code: 2,
            stderr: &["{t}/n/mask_cam2.png", "8×6"],
        },
        Row {
            name: "calib: native JSON naming a mask that is not a PNG",
            setup: |t| {
                write(
                    t,
                    "c.json",
                    r#"{"format": "vgps-calibration", "version": 1, "cameras": [
  {"camera": {"model": "equirectangular", "width": 64, "height": 32},
   "rig_from_camera": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "translation": [0, 0, 0]},
   "mask": "m.png"}]}
"#,
                );
                write(t, "m.png", garbage());
            },
            args: &["calib", "show", "{t}/c.json"],
            code: 2,
            stderr: &[
                "{t}/c.json",
                "cameras[0].mask",
                "{t}/m.png",
                "not a readable PNG",
            ],
        },
        Row {
            name: "calib: truncated JSON",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/native_mixed.json"))
                    .expect("json");
                write(t, "c.json", &text[..500]);
            },
            args: &["calib", "show", "{t}/c.json"],
            code: 2,
            stderr: &["{t}/c.json: line 26"],
        },
        Row {
            name: "calib: binary garbage",
            setup: |t| write(t, "c.bin", garbage()),
            args: &["calib", "show", "{t}/c.bin"],
            code: 2,
            stderr: &["{t}/c.bin: cannot tell the calibration format"],
        },
        Row {
            name: "calib convert: output under a regular file",
            setup: regular_file,
            args: &[
                "calib",
                "convert",
                "--to",
                "native",
                "{fx}/calibration/ladybug_64x48.ini",
                "{t}/file/out.json",
            ],
            code: 1,
            stderr: &["{t}/file/out.json", "Not a directory"],
        },
        // ---- vgps simulate ----
        Row {
            name: "simulate: 1e12 m route",
            setup: |_| {},
            args: &[
                "simulate",
                "--preset",
                "short",
                "--length-m",
                "1e12",
                "--out",
                "{t}/s",
            ],
            code: 2,
            stderr: &["invalid scenario", "100 km"],
        },
        Row {
            name: "simulate: origin latitude 100",
            setup: |_| {},
            args: &[
                "simulate", "--preset", "short", "--origin", "100,0", "--out", "{t}/s",
            ],
            code: 2,
            stderr: &["--origin", "100,0"],
        },
        Row {
            name: "simulate: calibration with an absurd image size",
            setup: |t| {
                let text = std::fs::read_to_string(fixture("calibration/native_mixed.json"))
                    .expect("json");
                write(
                    t,
                    "c.json",
                    text.replacen("\"height\": 48", "\"height\": 100000", 1),
                );
            },
            args: &[
                "simulate",
                "--preset",
                "short",
                "--length-m",
                "10",
                "--calibration",
                "{t}/c.json",
                "--out",
                "{t}/s",
            ],
            code: 2,
            stderr: &["{t}/c.json", "exceeds 65536"],
        },
        Row {
            name: "simulate: output under a regular file",
            setup: regular_file,
            args: &[
                "simulate",
                "--preset",
                "short",
                "--length-m",
                "10",
                "--out",
                "{t}/file/s",
            ],
            code: 1,
            stderr: &["{t}/file/s", "Not a directory"],
        },
        // ---- truth and GIS inventories (issue 27) ----
        Row {
            name: "replay: truth.csv with one broken quaternion (refused alone, replay goes on)",
            setup: |t| {
                let d = drive(t);
                let text = std::fs::read_to_string(d.join("truth.csv")).expect("truth");
                let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
                // Row 2: qw doubled (norm ≈ 2); row 3: norm off by 2e-6 (normalised).
                let mut f: Vec<String> = lines[1].split(',').map(str::to_string).collect();
                f[4] = "2".into();
                lines[1] = f.join(",");
                std::fs::write(d.join("truth.csv"), lines.join("\n") + "\n").expect("write");
            },
            args: &["replay", "{t}/d", "--quiet", "--out", "{t}/out"],
            code: 0,
            stderr: &[
                "{t}/d/truth.csv: 1 truth rows refused",
                "truth.csv:2: field `qw`: quaternion norm",
            ],
        },
        Row {
            name: "replay: truth file that is not a truth file (warning, replay goes on)",
            setup: |t| std::fs::write(drive(t).join("truth.csv"), "hello\n").expect("write"),
            args: &["replay", "{t}/d", "--quiet", "--out", "{t}/out"],
            code: 0,
            stderr: &[
                "{t}/d/truth.csv: not a truth file",
                "the drive is read without truth",
            ],
        },
        Row {
            name: "replay: UBX log whose only NAV-PVT frame has a wrong checksum (warning, replay goes on)",
            setup: |t| {
                drive(t);
                // Sync, class 0x01 NAV, id 0x07 PVT, length 92, a zero payload, checksum 0.
                let mut ubx = vec![0xB5, 0x62, 0x01, 0x07, 92, 0];
                ubx.extend([0u8; 92]);
                ubx.extend([0, 0]);
                write(t, "g.ubx", ubx);
            },
            args: &[
                "replay",
                "{t}/d",
                "--gnss",
                "{t}/g.ubx",
                "--gnss-format",
                "ubx",
                "--quiet",
                "--out",
                "{t}/r",
            ],
            code: 0,
            stderr: &["{t}/g.ubx: no GNSS fix"],
        },
        Row {
            name: "landmarks import: GeoJSON in a projected CRS (coordinates in metres)",
            setup: |t| {
                write(
                    t,
                    "l.geojson",
                    r#"{"type":"FeatureCollection","features":[{"type":"Feature","id":"node/7","properties":{"height":8},"geometry":{"type":"Point","coordinates":[452000.5,5411000.0]}}]}"#,
                )
            },
            args: &[
                "landmarks",
                "import",
                "{t}/l.geojson",
                "--ground-height",
                "30",
                "--out",
                "{t}/L.csv",
            ],
            code: 2,
            stderr: &[
                "{t}/l.geojson:1: field `coordinates`: feature 0 (id node/7)",
                "projected CRS",
            ],
        },
        Row {
            name: "landmarks import: GeoJSON with a crs member naming UTM",
            setup: |t| {
                write(
                    t,
                    "l.geojson",
                    r#"{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"urn:ogc:def:crs:EPSG::25832"}},"features":[]}"#,
                )
            },
            args: &[
                "landmarks",
                "import",
                "{t}/l.geojson",
                "--ground-height",
                "30",
                "--out",
                "{t}/L.csv",
            ],
            code: 2,
            stderr: &["{t}/l.geojson:1: field `crs`", "EPSG::25832"],
        },
        Row {
            name: "landmarks import: a lamp without height (default height, larger sigma, said once)",
            setup: |t| {
                write(
                    t,
                    "l.geojson",
                    r#"{"type":"FeatureCollection","features":[{"type":"Feature","id":"node/7","properties":{},"geometry":{"type":"Point","coordinates":[2.35,48.85]}}]}"#,
                )
            },
            args: &[
                "landmarks",
                "import",
                "{t}/l.geojson",
                "--ground-height",
                "30",
                "--out",
                "{t}/L.csv",
            ],
            code: 0,
            stderr: &[
                "{t}/l.geojson: 1 of 1 lamps have no height above ground: 6 m used with σ 1.5 m",
            ],
        },
        Row {
            name: "landmarks import: a lamp without ground height and no --ground-height",
            setup: |t| {
                write(
                    t,
                    "l.geojson",
                    r#"{"type":"FeatureCollection","features":[{"type":"Feature","id":"node/7","properties":{"height":8},"geometry":{"type":"Point","coordinates":[2.35,48.85]}}]}"#,
                )
            },
            args: &["landmarks", "import", "{t}/l.geojson", "--out", "{t}/L.csv"],
            code: 2,
            stderr: &["{t}/l.geojson:1: field `ele`: feature 0 (id node/7): no ground height"],
        },
        Row {
            name: "landmarks footprints: unclosed, self-intersecting, negative-height and projected features skipped by name, the rest converted",
            setup: |t| {
                write(
                    t,
                    "b.geojson",
                    r#"{"type":"FeatureCollection","features":[
{"type":"Feature","id":"way/1","properties":{"height":12},"geometry":{"type":"Polygon","coordinates":[[[2.35,48.85],[2.3502,48.85],[2.3502,48.8501],[2.35,48.8501],[2.35,48.85]]]}},
{"type":"Feature","id":"bow","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[2.36,48.85],[2.3601,48.8501],[2.3601,48.85],[2.36,48.8501],[2.36,48.85]]]}},
{"type":"Feature","id":"open","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[2.37,48.85],[2.3701,48.85],[2.3701,48.8501],[2.37,48.8501]]]}},
{"type":"Feature","id":"neg","properties":{"height":-4},"geometry":{"type":"Polygon","coordinates":[[[2.38,48.85],[2.3801,48.85],[2.3801,48.8501],[2.38,48.85]]]}},
{"type":"Feature","id":"utm","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[452000,5411000],[452020,5411000],[452020,5411010],[452000,5411000]]]}}]}"#,
                )
            },
            args: &[
                "landmarks",
                "footprints",
                "{t}/b.geojson",
                "--ground-height",
                "35",
                "--out",
                "{t}/L.csv",
            ],
            code: 0,
            stderr: &[
                "{t}/b.geojson: feature 1 (id bow) skipped: the outer ring intersects itself",
                "{t}/b.geojson: feature 2 (id open) skipped: the outer ring is not closed",
                "{t}/b.geojson: feature 3 (id neg) skipped: height -4 is not positive",
                "{t}/b.geojson: feature 4 (id utm) skipped: (452000, 5411000) is not WGS84",
            ],
        },
        Row {
            name: "landmarks footprints: an empty collection",
            setup: |t| {
                write(
                    t,
                    "b.geojson",
                    r#"{"type":"FeatureCollection","features":[]}"#,
                )
            },
            args: &[
                "landmarks",
                "footprints",
                "{t}/b.geojson",
                "--ground-height",
                "35",
                "--out",
                "{t}/L.csv",
            ],
            code: 2,
            stderr: &[
                "{t}/b.geojson:1: field `features`: no building corner: the collection has no feature",
            ],
        },
        Row {
            name: "landmarks footprints: a crs member naming a projected CRS",
            setup: |t| {
                write(
                    t,
                    "b.geojson",
                    r#"{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:2263"}},"features":[]}"#,
                )
            },
            args: &[
                "landmarks",
                "footprints",
                "{t}/b.geojson",
                "--ground-height",
                "35",
                "--out",
                "{t}/L.csv",
            ],
            code: 2,
            stderr: &["{t}/b.geojson:1: field `crs`", "EPSG:2263"],
        },
        Row {
            name: "landmarks footprints: a building without any height and no --ground-height",
            setup: |t| {
                write(
                    t,
                    "b.geojson",
                    r#"{"type":"Feature","id":"way/9","properties":{"height":9},"geometry":{"type":"Polygon","coordinates":[[[2.35,48.85],[2.3502,48.85],[2.3502,48.8501],[2.35,48.85]]]}}"#,
                )
            },
            args: &[
                "landmarks",
                "footprints",
                "{t}/b.geojson",
                "--out",
                "{t}/L.csv",
            ],
            code: 2,
            stderr: &[
                "{t}/b.geojson:1: field `features`: no building corner: {t}/b.geojson: feature 0 (id way/9) skipped: no ground height",
            ],
        },
        // ---- vgps replay ----
        Row {
            name: "replay: no drive.json",
            setup: |t| std::fs::create_dir(t.join("d")).expect("mkdir"),
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/drive.json: cannot read the file"],
        },
        Row {
            name: "replay: truncated drive.json",
            setup: |t| {
                let d = drive(t);
                let text = std::fs::read_to_string(d.join("drive.json")).expect("manifest");
                std::fs::write(d.join("drive.json"), &text[..40]).expect("write");
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/drive.json:", "field `json`"],
        },
        Row {
            name: "replay: empty drive.json",
            setup: |t| std::fs::write(drive(t).join("drive.json"), "").expect("write"),
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/drive.json:1: field `json`"],
        },
        Row {
            name: "replay: drive.json is a directory",
            setup: |t| {
                let d = drive(t);
                std::fs::remove_file(d.join("drive.json")).expect("rm");
                std::fs::create_dir(d.join("drive.json")).expect("mkdir");
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/drive.json: cannot read the file"],
        },
        Row {
            name: "replay: drive.json version 99",
            setup: |t| {
                let d = drive(t);
                let text = std::fs::read_to_string(d.join("drive.json")).expect("manifest");
                std::fs::write(
                    d.join("drive.json"),
                    text.replace("\"version\": 1", "\"version\": 99"),
                )
                .expect("write");
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/drive.json:2: field `version`", "99"],
        },
        Row {
            name: "replay: calibration file missing",
            setup: |t| std::fs::remove_file(drive(t).join("calibration.json")).expect("rm"),
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/calibration.json"],
        },
        Row {
            name: "replay: calibration declaring the rig level within 200°",
            setup: |t| {
                let path = drive(t).join("calibration.json");
                let text = std::fs::read_to_string(&path).expect("json");
                assert!(text.contains("\"version\": 1,"), "{text}");
                std::fs::write(
                    &path,
                    text.replacen(
                        "\"version\": 1,",
                        "\"version\": 1, \"level_within_deg\": 200,",
                        1,
                    ),
                )
                .expect("write");
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/calibration.json", "level_within_deg", "200"],
        },
        Row {
            name: "replay: frames.csv NaN time",
            setup: |t| {
                std::fs::write(drive(t).join("frames.csv"), "frame,time_s\n0,1\n1,NaN\n")
                    .expect("write")
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/frames.csv:3: field `time_s`", "NaN"],
        },
        Row {
            name: "replay: frames.csv duplicate frame",
            setup: |t| {
                std::fs::write(drive(t).join("frames.csv"), "frame,time_s\n0,1\n0,2\n")
                    .expect("write")
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/frames.csv:3: field `frame`"],
        },
        Row {
            name: "replay: duplicate landmark id in the drive",
            setup: |t| {
                let d = drive(t);
                let text = std::fs::read_to_string(d.join("landmarks.csv")).expect("landmarks");
                let mut lines: Vec<&str> = text.lines().collect();
                let dup = lines[1].to_string();
                lines.insert(2, &dup);
                std::fs::write(d.join("landmarks.csv"), lines.join("\n") + "\n").expect("write");
            },
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/landmarks.csv:3: field `id`", "duplicate"],
        },
        Row {
            name: "replay: landmarks.csv is binary garbage",
            setup: |t| std::fs::write(drive(t).join("landmarks.csv"), garbage()).expect("write"),
            args: &["replay", "{t}/d", "--quiet"],
            code: 2,
            stderr: &["{t}/d/landmarks.csv:1:", "UTF-8"],
        },
        Row {
            name: "replay: zero pixel sigma",
            setup: |t| {
                drive(t);
            },
            args: &["replay", "{t}/d", "--quiet", "--pixel-sigma-px", "0"],
            code: 2,
            stderr: &["--pixel-sigma-px 0"],
        },
        Row {
            name: "replay: zero visibility range",
            setup: |t| {
                drive(t);
            },
            args: &["replay", "{t}/d", "--quiet", "--visibility-range-m", "0"],
            code: 2,
            stderr: &[
                "--visibility-range-m",
                "`0` is not a positive finite number",
            ],
        },
        Row {
            name: "replay: a matcher memory that is not a number of MiB",
            setup: |t| {
                drive(t);
            },
            args: &["replay", "{t}/d", "--quiet", "--matcher-memory-mib", "1.5"],
            code: 2,
            stderr: &["--matcher-memory-mib"],
        },
        Row {
            name: "replay: a negative turn rate change",
            setup: |t| {
                drive(t);
            },
            args: &[
                "replay",
                "{t}/d",
                "--quiet",
                "--max-turn-rate-change-deg-s=-5",
            ],
            code: 2,
            stderr: &["--max-turn-rate-change-deg-s", "non-negative"],
        },
        Row {
            name: "replay: output directory under a regular file (fails before localizing)",
            setup: |t| {
                drive(t);
                regular_file(t);
            },
            args: &["replay", "{t}/d", "--quiet", "--out", "{t}/file/r"],
            code: 1,
            stderr: &["{t}/file/r", "Not a directory"],
        },
        Row {
            name: "replay --from-images: a frame references a missing image",
            setup: |t| std::fs::remove_file(drive(t).join("images/000001_2.png")).expect("rm"),
            args: &[
                "replay",
                "{t}/d",
                "--quiet",
                "--from-images",
                "--threads",
                "1",
                "--out",
                "{t}/r",
            ],
            code: 0,
            stderr: &["frame 1", "{t}/d/images/000001_2.png"],
        },
        // ---- vgps detect ----
        Row {
            name: "detect: PNG header claiming 100000×100000",
            setup: |t| claim_png_size(&drive(t).join("images/000000_0.png"), 100_000, 100_000),
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &["frame 0: {t}/d/images/000000_0.png", "100000×100000"],
        },
        Row {
            name: "detect: truncated PNG, garbage PNG, missing PNG",
            setup: |t| {
                let d = drive(t);
                let png = std::fs::read(d.join("images/000001_2.png")).expect("png");
                std::fs::write(d.join("images/000001_2.png"), &png[..1000]).expect("write");
                std::fs::write(d.join("images/000000_4.png"), garbage()).expect("write");
                std::fs::remove_file(d.join("images/000002_3.png")).expect("rm");
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &[
                "frame 0: {t}/d/images/000000_4.png: not a PNG, JPEG, TIFF or BMP file (camera 4)",
                "frame 1: {t}/d/images/000001_2.png",
                "frame 2: {t}/d/images/000002_3.png",
            ],
        },
        Row {
            name: "detect: truncated JPEG",
            setup: |t| {
                replace_image(t, "jpg", |g| {
                    let b = jpeg_of(g);
                    b[..b.len() / 2].to_vec()
                })
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &[
                "frame 0: {t}/d/images/000000_0.jpg: cannot decode JPEG",
                "(camera 0)",
            ],
        },
        Row {
            name: "detect: truncated BMP",
            setup: |t| {
                replace_image(t, "bmp", |g| {
                    let mut b = Vec::new();
                    g.write_to(&mut std::io::Cursor::new(&mut b), image::ImageFormat::Bmp)
                        .expect("bmp");
                    b[..b.len() / 3].to_vec()
                })
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &["frame 0: {t}/d/images/000000_0.bmp", "(camera 0)"],
        },
        Row {
            name: "detect: CMYK JPEG (four components)",
            setup: |t| replace_image(t, "jpg", |g| patched_jpeg(g, |h| h[5] = 4)),
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &[
                "frame 0: {t}/d/images/000000_0.jpg: unsupported JPEG",
                "CMYK",
            ],
        },
        Row {
            name: "detect: 12-bit JPEG",
            setup: |t| replace_image(t, "jpg", |g| patched_jpeg(g, |h| h[0] = 12)),
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &[
                "frame 0: {t}/d/images/000000_0.jpg: unsupported JPEG",
                "12-bit",
            ],
        },
        Row {
            name: "detect: JPEG header claiming 65535×65535 (4.3·10⁹ pixels)",
            setup: |t| {
                replace_image(t, "jpg", |g| {
                    patched_jpeg(g, |h| h[1..5].copy_from_slice(&[0xFF; 4]))
                })
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &["frame 0: {t}/d/images/000000_0.jpg", "65535×65535"],
        },
        Row {
            name: "detect: JPEG of the wrong size for its camera",
            setup: |t| {
                replace_image(t, "jpg", |g| {
                    jpeg_of(&image::imageops::crop_imm(g, 0, 0, 512, 384).to_image())
                })
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &[
                "frame 0: {t}/d/images/000000_0.jpg",
                "512×384",
                "(camera 0)",
            ],
        },
        Row {
            name: "detect: TIFF with an unsupported compression",
            setup: |t| {
                replace_image(t, "tif", |g| {
                    let mut c = std::io::Cursor::new(Vec::new());
                    image::ImageEncoder::write_image(
                        image::codecs::tiff::TiffEncoder::new(&mut c),
                        g.as_raw(),
                        g.width(),
                        g.height(),
                        image::ExtendedColorType::L8,
                    )
                    .expect("tiff");
                    let mut b = c.into_inner();
                    let ifd = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize;
                    let n = u16::from_le_bytes([b[ifd], b[ifd + 1]]) as usize;
                    for k in 0..n {
                        let e = ifd + 2 + 12 * k;
                        if b[e..e + 2] == [3, 1] {
                            b[e + 8..e + 10].copy_from_slice(&34712u16.to_le_bytes());
                        }
                    }
                    b
                })
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &["frame 0: {t}/d/images/000000_0.tif: unsupported TIFF"],
        },
        Row {
            name: "detect: an image path that is a directory",
            setup: |t| {
                let d = drive(t);
                std::fs::remove_file(d.join("images/000001_1.png")).expect("rm");
                std::fs::create_dir(d.join("images/000001_1.png")).expect("mkdir");
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 0,
            stderr: &["frame 1: {t}/d/images/000001_1.png"],
        },
        Row {
            name: "detect: no image columns",
            setup: |t| {
                std::fs::write(
                    drive(t).join("frames.csv"),
                    "frame,time_s\n0,1\n1,1.2\n2,1.4\n",
                )
                .expect("write")
            },
            args: &["detect", "{t}/d", "--quiet", "--out", "{t}/det.csv"],
            code: 2,
            stderr: &["{t}/d", "no frame names an image"],
        },
        Row {
            name: "detect: output is a directory",
            setup: |t| {
                drive(t);
                std::fs::create_dir(t.join("det.csv")).expect("mkdir");
            },
            args: &[
                "detect",
                "{t}/d",
                "--quiet",
                "--threads",
                "1",
                "--out",
                "{t}/det.csv",
            ],
            code: 1,
            stderr: &["{t}/det.csv", "Is a directory"],
        },
        // ---- vgps map ----
        Row {
            name: "map: GNSS file of garbage (no fix, no heading)",
            setup: |t| std::fs::write(drive(t).join("gnss.nmea"), garbage()).expect("write"),
            args: &["map", "{t}/d", "--out", "{t}/m.csv"],
            code: 2,
            stderr: &["{t}/d/gnss.nmea", "lines skipped", "no GNSS fix"],
        },
        Row {
            name: "map: output under a regular file",
            setup: |t| {
                drive(t);
                regular_file(t);
            },
            args: &["map", "{t}/d", "--out", "{t}/file/m.csv"],
            code: 1,
            stderr: &["{t}/file/m.csv", "Not a directory"],
        },
        Row {
            name: "map: coverage 2",
            setup: |t| {
                drive(t);
            },
            args: &["map", "{t}/d", "--min-coverage", "2"],
            code: 2,
            stderr: &["--min-coverage", "`2`"],
        },
        // ---- vgps import (docs/import.md) ----
        Row {
            name: "import mcap: not an MCAP file",
            setup: garbage_mcap,
            args: &[
                "import",
                "mcap",
                "{t}/x.mcap",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 2,
            stderr: &["{t}/x.mcap", "not an MCAP file"],
        },
        Row {
            name: "import mcap: an unreadable calibration",
            setup: copy_mcap,
            args: &[
                "import",
                "mcap",
                "{t}/run.mcap",
                "--rig",
                "{t}/missing.json",
                "--out",
                "{t}/d",
            ],
            code: 2,
            stderr: &["{t}/missing.json", "cannot read"],
        },
        Row {
            name: "import mcap: a recording cut by a crash",
            setup: cut_mcap,
            args: &[
                "import",
                "mcap",
                "{t}/cut.mcap",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 0,
            stderr: &["{t}/cut.mcap: record ", "reading stopped"],
        },
        Row {
            name: "import mcap: a chunk with a bad CRC",
            setup: crc_mcap,
            args: &[
                "import",
                "mcap",
                "{t}/crc.mcap",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 0,
            stderr: &["{t}/crc.mcap: record ", "CRC"],
        },
        Row {
            name: "import mcap: json encoding, unmapped topic, status -1, short CDR",
            setup: copy_mcap,
            args: &[
                "import",
                "mcap",
                "{t}/bad.mcap",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 0,
            stderr: &[
                "{t}/bad.mcap: topic /gps/json: message encoding `json` is not supported",
                "{t}/bad.mcap: topic /front/image/compressed: image topic without a camera number",
                "NavSatFix status -1 (no fix)",
                "topic /ladybug/cam1/image/compressed: image: field `header.stamp.nanosec`",
            ],
        },
        Row {
            name: "import mcap: a bad topic mapping row",
            setup: bad_topic_map,
            args: &[
                "import",
                "mcap",
                "{t}/bad.mcap",
                "--rig",
                "{t}/small_rig.json",
                "--topics",
                "{t}/topics.csv",
                "--out",
                "{t}/d",
            ],
            code: 2,
            stderr: &["{t}/topics.csv:2", "field `camera`"],
        },
        Row {
            name: "replay run.mcap without --rig",
            setup: copy_mcap,
            args: &["replay", "{t}/run.mcap"],
            code: 2,
            stderr: &["{t}/run.mcap", "--rig"],
        },
        Row {
            name: "import nclt: no lb3 folder",
            setup: nclt_without_lb3,
            args: &[
                "import",
                "nclt",
                "{t}/session",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 2,
            stderr: &["{t}/session", "no `lb3` folder"],
        },
        Row {
            name: "import nclt: a bad ground-truth row",
            setup: nclt_bad_ground_truth,
            args: &[
                "import",
                "nclt",
                "{t}/session",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 0,
            stderr: &["groundtruth_2012-11-16.csv:1", "3 fields, expected 7"],
        },
        Row {
            name: "import folders: no camera folder",
            setup: folders_without_cameras,
            args: &[
                "import",
                "folders",
                "{t}/root",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 2,
            stderr: &["{t}/root", "no camera folder"],
        },
        Row {
            name: "import folders: an image without a time",
            setup: folders_image_without_time,
            args: &[
                "import",
                "folders",
                "{t}/root",
                "--rig",
                "{t}/small_rig.json",
                "--out",
                "{t}/d",
            ],
            code: 0,
            stderr: &["frame.png: no time in the file name"],
        },
        // ---- vgps demo ----
        Row {
            name: "demo: output under a regular file",
            setup: regular_file,
            args: &["demo", "--out", "{t}/file/demo"],
            code: 1,
            stderr: &["{t}/file/demo/reference", "Not a directory"],
        },
    ]
}

/// Every file under `dir` with a hash of its bytes (directories as `None`).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Option<u64>> {
    use std::hash::{DefaultHasher, Hash, Hasher};
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read dir") {
            let path = e.expect("entry").path();
            if path.is_dir() {
                out.insert(path.clone(), None);
                stack.push(path);
            } else {
                let mut h = DefaultHasher::new();
                std::fs::read(&path).expect("read").hash(&mut h);
                out.insert(path, Some(h.finish()));
            }
        }
    }
    out
}

#[test]
fn bad_input_matrix() {
    let rows = rows();
    assert!(rows.len() >= 40, "only {} rows", rows.len());
    let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let fx = fx.to_string_lossy();
    let mut failures = Vec::new();
    for row in &rows {
        let dir = tempfile::tempdir().expect("temp dir");
        let t = dir.path().to_string_lossy().into_owned();
        let expand = |s: &str| s.replace("{t}", &t).replace("{fx}", &fx);
        (row.setup)(dir.path());
        let before = snapshot(dir.path());
        let args: Vec<String> = row.args.iter().map(|a| expand(a)).collect();
        let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .expect("vgps runs");
        let stderr = String::from_utf8_lossy(&o.stderr);
        let mut problems = Vec::new();
        if o.status.code() != Some(row.code) {
            problems.push(format!("exit {:?}, expected {}", o.status.code(), row.code));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".into());
        }
        for s in row.stderr {
            if !stderr.contains(&expand(s)) {
                problems.push(format!("stderr lacks `{}`", expand(s)));
            }
        }
        let after = snapshot(dir.path());
        for path in after.keys() {
            let inside = path.strip_prefix(dir.path()).unwrap_or(path);
            if inside.to_string_lossy().contains(".tmp") {
                problems.push(format!("temporary file left: {}", path.display()));
            }
        }
        if row.code != 0 && after != before {
            let changed: Vec<_> = after
                .iter()
                .filter(|(p, h)| before.get(*p) != Some(h))
                .map(|(p, _)| p.display().to_string())
                .collect();
            problems.push(format!("a failing run changed the directory: {changed:?}"));
        }
        if row.code == 2 && !o.stdout.is_empty() {
            problems.push("an input error wrote to stdout".into());
        }
        if !problems.is_empty() {
            failures.push(format!(
                "row `{}`: {}\n  stderr: {}",
                row.name,
                problems.join("; "),
                stderr.trim()
            ));
        }
    }
    println!("{} rows", rows.len());
    assert!(
        failures.is_empty(),
        "{} of {} rows failed:\n{}",
        failures.len(),
        rows.len(),
        failures.join("\n")
    );
}
