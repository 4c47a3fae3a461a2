//! `vgps replay run.mcap` reads the frames' images from the recording (no image file is
//! written) and gives the same `fixes.csv` as the replay of the drive folder that
//! `vgps import mcap` writes from the same recording (`tests/data/mcap/run.mcap`, written by
//! the official Python writers; see `tests/data/mcap/make_mcap.py`).

mod common;

use common::vgps;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mcap")
}

/// Every file under `dir`, relative, sorted.
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

fn is_image(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    [".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"]
        .iter()
        .any(|e| n.ends_with(e))
}

#[test]
fn the_recording_replays_to_the_fixes_of_its_imported_folder_without_writing_an_image() {
    let t = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (mcap, rig, landmarks) = (
        s(&data().join("run.mcap")),
        s(&data().join("source/calibration.json")),
        s(&data().join("source/landmarks.csv")),
    );
    let imported = s(&t.path().join("imported"));
    let o = vgps(&[
        "import",
        "mcap",
        &mcap,
        "--rig",
        &rig,
        "--landmarks",
        &landmarks,
        "--out",
        &imported,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        files_under(Path::new(&imported))
            .iter()
            .filter(|f| is_image(f))
            .count(),
        29
    );
    let folder_out = t.path().join("o_folder");
    let o = vgps(&[
        "replay",
        &imported,
        "--from-images",
        "--quiet",
        "--out",
        &s(&folder_out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The MCAP replay, with its temporary directory inside the test's.
    let tmp = t.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mcap_out = t.path().join("o_mcap");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vgps"))
        .args([
            "replay",
            &mcap,
            "--rig",
            &rig,
            "--landmarks",
            &landmarks,
            "--quiet",
            "--out",
            &s(&mcap_out),
        ])
        .env("TMPDIR", &tmp)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fixes = std::fs::read_to_string(mcap_out.join("fixes.csv")).unwrap();
    assert_eq!(
        fixes,
        std::fs::read_to_string(folder_out.join("fixes.csv")).unwrap()
    );
    // Every image named by the frames was found in the recording and decoded at the
    // calibration's size (a wrong or missing image would be counted in `unusable_images`
    // and make its frame `bad_image`).
    let header: Vec<&str> = fixes.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|c| *c == "unusable_images").unwrap();
    for line in fixes.lines().skip(1) {
        assert_eq!(line.split(',').nth(col), Some("0"), "{line}");
        assert!(!line.contains("bad_image"), "{line}");
    }
    assert_eq!(fixes.lines().count(), 6);
    // Nothing is left behind in the temporary directory, and the outputs are the folder
    // replay's (its two plots the only images), with no image of the recording among them.
    assert!(files_under(&tmp).is_empty(), "{:?}", files_under(&tmp));
    let outputs = files_under(&mcap_out);
    assert_eq!(outputs, files_under(&folder_out));
    let images: Vec<&String> = outputs.iter().filter(|f| is_image(f)).collect();
    assert_eq!(images, ["error.png", "track.png"], "{outputs:?}");
}
