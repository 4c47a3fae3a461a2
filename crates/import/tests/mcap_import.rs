//! The MCAP import on files written by the official Python writers (`mcap` +
//! `mcap-ros2-support`; `tests/data/mcap/make_mcap.py`) from the small simulated drive
//! `tests/data/mcap/source`: what the recording holds comes back as the drive had it.

use std::path::{Path, PathBuf};
use vgps_import::mcap_import::{ImageOutput, McapImportOptions, import_mcap};
use vgps_replay::drive::{Drive, Strictness};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/mcap")
}

fn options() -> McapImportOptions {
    McapImportOptions {
        rig: data().join("source/calibration.json"),
        landmarks: Some(data().join("source/landmarks.csv")),
        topics: None,
        stamp_tolerance_s: 0.01,
        images: ImageOutput::Files,
    }
}

fn pixels(bytes: &[u8]) -> Vec<u8> {
    image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .unwrap()
        .into_bytes()
}

#[test]
fn the_recording_comes_back_as_the_drive_it_was_made_from() {
    let out = tempfile::tempdir().unwrap();
    let imported = import_mcap(&data().join("run.mcap"), out.path(), &options()).unwrap();
    // The only warnings: the GPS outages (status -1), one per outage, naming the record.
    let w = &imported.report.warnings;
    assert!(!w.is_empty() && w.len() < 3, "{w:?}");
    assert!(
        w.iter()
            .all(|w| w.contains("run.mcap: record ") && w.contains("status -1"))
    );
    assert_eq!(
        imported.ignored_types.get("sensor_msgs/msg/CameraInfo"),
        Some(&1)
    );
    assert!(!imported.mcap.truncated && imported.mcap.bad_chunks == 0);
    let source = Drive::open(&data().join("source"), Strictness::Strict).unwrap();
    let drive = Drive::open(out.path(), Strictness::Strict).unwrap();
    assert_eq!(drive.rig().len(), 6);
    assert_eq!(drive.landmarks().len(), source.landmarks().len());
    // Frames: the same times (stamps spread over 5 ms, tolerance 10 ms); frame 2 lacks
    // camera 4 and is still a frame.
    assert_eq!(drive.frames().len(), source.frames().len());
    for (f, s) in drive.frames().iter().zip(source.frames()) {
        assert_eq!((f.frame, f.time_s), (s.frame, s.time_s));
        for k in 0..6 {
            let Some(name) = &f.images[k] else {
                assert_eq!((f.frame, k), (2, 4));
                continue;
            };
            let got = std::fs::read(out.path().join(name)).unwrap();
            let want =
                std::fs::read(data().join("source").join(s.images[k].as_ref().unwrap())).unwrap();
            if k < 5 {
                assert_eq!(got, want, "frame {} camera {k}: the PNG as it was", f.frame);
            } else {
                assert_eq!(
                    pixels(&got),
                    pixels(&want),
                    "frame {} raw camera 5",
                    f.frame
                );
            }
        }
    }
    assert_eq!(imported.report.frames_missing_cameras, 1);
    // Satellite GPS: the same epochs, fixes and positions (status -1 = the outages).
    assert_eq!(drive.gnss().len(), source.gnss().len());
    for (g, s) in drive.gnss().iter().zip(source.gnss()) {
        assert!((g.time_s - s.time_s).abs() < 1e-6);
        assert_eq!(g.fix.is_some(), s.fix.is_some());
        if let (Some(a), Some(b)) = (g.fix, s.fix) {
            assert!((a.position.lat_deg - b.position.lat_deg).abs() < 1e-9);
            assert!((a.position.lon_deg - b.position.lon_deg).abs() < 1e-9);
            assert!((a.position.alt_m - b.position.alt_m).abs() < 1e-3);
            assert_eq!(a.quality, 1);
        }
    }
    // Status and covariance kept beside it; the IMU stored.
    let navsat = std::fs::read_to_string(out.path().join("navsatfix.csv")).unwrap();
    let lines: Vec<&str> = navsat.lines().collect();
    assert_eq!(lines.len(), source.gnss().len() + 1);
    assert!(lines[1].ends_with(",2,4,0,0,0,4,0,0,0,9"), "{}", lines[1]);
    assert!(navsat.lines().any(|l| l.split(',').nth(1) == Some("-1")));
    let imu = std::fs::read_to_string(out.path().join("imu.csv")).unwrap();
    assert_eq!(imu.lines().count(), source.frames().len() + 1);
}

#[test]
fn bad_messages_are_reported_and_the_rest_imported() {
    let out = tempfile::tempdir().unwrap();
    let imported = import_mcap(&data().join("bad.mcap"), out.path(), &options()).unwrap();
    let w = imported.report.warnings.join("\n");
    let has = |s: &str| assert!(w.contains(s), "no `{s}` in:\n{w}");
    has("bad.mcap: topic /front/image/compressed: image topic without a camera number");
    has("bad.mcap: topic /gps/json: message encoding `json` is not supported");
    has("NavSatFix status -1 (no fix): epochs without fix from here");
    has(
        "topic /ladybug/cam1/image/compressed: image: field `header.stamp.nanosec`: message ends at byte 8",
    );
    assert!(w.contains("bad.mcap: record "), "{w}");
    // A bad IMU is an error of its record, naming the field; the good sample is kept.
    has("topic /imu/data: Imu: field `orientation`: [NaN, 0.0, 0.0, 1.0] is not finite; skipped");
    has("topic /imu/data: Imu: field `orientation`: is the zero quaternion");
    let drive = Drive::open(out.path(), Strictness::Strict).unwrap();
    assert_eq!(drive.imu().len(), 1);
    let prior = drive.attitude_at(drive.frames()[0].time_s).unwrap();
    assert!((prior.up_in_rig - nalgebra::Vector3::z()).norm() < 1e-12);
    assert_eq!(drive.frames().len(), 1);
    assert_eq!(drive.gnss().len(), 2);
    assert_eq!(drive.gnss().iter().filter(|g| g.fix.is_some()).count(), 1);
}

#[test]
fn a_topic_mapping_file_decides_the_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("topics.csv");
    std::fs::write(&map, "topic,camera\n/front/image/compressed,3\n").unwrap();
    let mut o = options();
    o.topics = Some(vgps_import::mcap_import::read_topic_map(&map).unwrap());
    let out = dir.path().join("drive");
    let imported = import_mcap(&data().join("bad.mcap"), &out, &o).unwrap();
    let drive = Drive::open(&out, Strictness::Strict).unwrap();
    let f = &drive.frames()[0];
    assert!(f.images[3].is_some() && f.images[0].is_none());
    assert!(imported.report.warnings.iter().any(|w| w.contains(
        "topic /ladybug/cam0/image/compressed: image topic not in the topic mapping file"
    )));
    std::fs::write(&map, "topic,camera\n/a,9\n").unwrap();
    let e = vgps_import::mcap_import::read_topic_map(&map).unwrap_err();
    assert!(
        e.to_string()
            .ends_with("topics.csv:2: field `camera`: `9` is not a camera index 0–5"),
        "{e}"
    );
}

#[test]
fn a_cut_recording_gives_what_is_intact() {
    let dir = tempfile::tempdir().unwrap();
    let whole = std::fs::read(data().join("run.mcap")).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &whole[..whole.len() * 6 / 10]).unwrap();
    let out = dir.path().join("drive");
    let imported = import_mcap(&cut, &out, &options()).unwrap();
    assert!(imported.mcap.truncated);
    let w = imported.report.warnings.join("\n");
    assert!(
        w.contains("cut.mcap: record ") && w.contains("reading stopped"),
        "{w}"
    );
    let drive = Drive::open(&out, Strictness::Strict).unwrap();
    assert!(
        (1..5).contains(&drive.frames().len()),
        "{}",
        drive.frames().len()
    );
}

#[test]
fn a_chunk_with_a_bad_crc_is_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(data().join("bad.mcap")).unwrap();
    // The second PNG of the file is camera 0's image (uncompressed chunks).
    let pngs: Vec<usize> = bytes
        .windows(4)
        .enumerate()
        .filter(|(_, w)| w == b"\x89PNG")
        .map(|(i, _)| i)
        .collect();
    bytes[pngs[1] + 100] ^= 0x55;
    let file = dir.path().join("crc.mcap");
    std::fs::write(&file, &bytes).unwrap();
    let out = dir.path().join("drive");
    let imported = import_mcap(&file, &out, &options()).unwrap();
    assert_eq!(imported.mcap.bad_chunks, 1);
    let w = imported.report.warnings.join("\n");
    assert!(w.contains("crc.mcap: record ") && w.contains("CRC"), "{w}");
    let drive = Drive::open(&out, Strictness::Strict).unwrap();
    assert!(drive.frames().is_empty());
    assert!(!drive.gnss().is_empty(), "the other chunks are read");
}

/// Every file under `dir`, relative.
fn files_under(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().display().to_string());
            }
        }
    }
    out.sort();
    out
}

#[test]
fn images_left_in_the_recording_come_back_frame_by_frame_as_the_files_would_hold_them() {
    let files = tempfile::tempdir().unwrap();
    let as_files = import_mcap(&data().join("run.mcap"), files.path(), &options()).unwrap();
    assert!(as_files.recording_images.is_none());
    let small = tempfile::tempdir().unwrap();
    let in_recording = import_mcap(
        &data().join("run.mcap"),
        small.path(),
        &McapImportOptions {
            images: ImageOutput::InRecording,
            ..options()
        },
    )
    .unwrap();
    // No image is written: only the drive's small files.
    let written = files_under(small.path());
    assert_eq!(
        written,
        [
            "calibration_calibration.json",
            "drive.json",
            "frames.csv",
            "gnss.nmea",
            "imu.csv",
            "landmarks.csv",
            "navsatfix.csv"
        ],
        "{written:?}"
    );
    assert_eq!(in_recording.report, as_files.report);
    // The same frames (names included) as the import that writes the images.
    let a = Drive::open(files.path(), Strictness::Strict).unwrap();
    let b = Drive::open(small.path(), Strictness::Strict).unwrap();
    assert_eq!(a.frames(), b.frames());
    // Read back in frame order, each image's bytes are the file's: the PNGs as recorded,
    // camera 5's raw mono8 converted to the same PNG; frame 2 has no camera 4.
    let recording = in_recording.recording_images.unwrap();
    let streamed: Vec<_> = recording.stream(1).collect();
    assert_eq!(streamed.len(), a.frames().len());
    let mut images = 0;
    for (f, s) in a.frames().iter().zip(&streamed) {
        assert_eq!(s.frame, f.frame);
        assert_eq!(s.images.len(), f.images.len());
        for (name, got) in f.images.iter().zip(&s.images) {
            match (name, got) {
                (None, None) => {}
                (Some(name), Some(Ok(bytes))) => {
                    assert_eq!(bytes, &std::fs::read(files.path().join(name)).unwrap());
                    assert!(recording.contains(name));
                    assert_eq!(recording.dimensions(name), Some((160, 120)));
                    images += 1;
                }
                other => panic!("frame {}: {other:?}", f.frame),
            }
        }
    }
    assert_eq!(images, 29);
    let shown = recording.describe(a.frames()[0].images[0].as_ref().unwrap());
    assert!(
        shown.display().to_string().contains("run.mcap: record ")
            && shown
                .display()
                .to_string()
                .ends_with("(/ladybug/cam0/image/compressed)"),
        "{shown:?}"
    );
    // A stream dropped half-way stops its reader (no hang, no panic).
    let mut partial = recording.stream(1);
    assert_eq!(partial.next().map(|f| f.frame), Some(0));
    drop(partial);
}

#[test]
fn a_recording_cut_after_the_first_read_gives_the_missing_images_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    std::fs::copy(data().join("run.mcap"), &file).unwrap();
    let small = tempfile::tempdir().unwrap();
    let imported = import_mcap(
        &file,
        small.path(),
        &McapImportOptions {
            images: ImageOutput::InRecording,
            ..options()
        },
    )
    .unwrap();
    let whole = std::fs::read(&file).unwrap();
    std::fs::write(&file, &whole[..whole.len() / 2]).unwrap();
    let streamed: Vec<_> = imported.recording_images.unwrap().stream(2).collect();
    assert_eq!(streamed.len(), 5, "every frame comes, in order");
    assert_eq!(
        streamed.iter().map(|f| f.frame).collect::<Vec<_>>(),
        [0, 1, 2, 3, 4]
    );
    let last = streamed[4].images.iter().flatten().collect::<Vec<_>>();
    assert!(!last.is_empty());
    for image in last {
        let why = image.as_ref().unwrap_err();
        assert!(why.contains("run.mcap") && why.contains("damaged"), "{why}");
    }
    assert!(streamed[0].images.iter().flatten().all(Result::is_ok));
}
