//! `vgps replay --direction combined`: a backward pass fills the frames the forward pass
//! left without a fix, and leaves the forward fixes as they were.
//!
//! The drive: a simulated 120 m drive whose first five frames keep only three detections
//! each, replayed without the satellite prior. The forward pass's first cold start (frame
//! 0, three detections) cannot succeed, so the frames until the next one is due
//! (`no_prior`) have no fix; the backward pass tracks back to frame 5.

mod common;

use common::vgps;
use std::collections::HashMap;
use std::path::Path;

/// Rows of `fixes.csv` as maps of column → value.
fn fixes(out: &Path) -> Vec<HashMap<String, String>> {
    let mut reader = csv::Reader::from_path(out.join("fixes.csv")).unwrap();
    let header = reader.headers().unwrap().clone();
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            header
                .iter()
                .zip(r.iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// Keeps at most `keep` detections of each of the first `frames` frames.
fn thin_first_frames(drive: &Path, frames: u64, keep: usize) {
    let path = drive.join("detections.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut kept: HashMap<u64, usize> = HashMap::new();
    let mut out = String::new();
    for (k, line) in text.lines().enumerate() {
        let frame: Option<u64> = line.split(',').next().and_then(|f| f.parse().ok());
        let keep_line = match frame {
            Some(f) if k > 0 && f < frames => {
                let n = kept.entry(f).or_default();
                *n += 1;
                *n <= keep
            }
            _ => true,
        };
        if keep_line {
            out.push_str(line);
            out.push('\n');
        }
    }
    std::fs::write(&path, out).unwrap();
}

fn replay(drive: &Path, out: &Path, direction: &str) -> std::process::Output {
    replay_on(drive, out, direction, "2")
}

fn replay_on(drive: &Path, out: &Path, direction: &str, threads: &str) -> std::process::Output {
    let o = vgps(&[
        "replay",
        drive.to_str().unwrap(),
        "--no-gnss-prior",
        "--direction",
        direction,
        "--threads",
        threads,
        "--format",
        "json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

#[test]
fn the_backward_pass_fills_frames_without_a_forward_fix_and_keeps_the_forward_ones() {
    let dir = tempfile::tempdir().unwrap();
    let drive = dir.path().join("drive");
    let o = vgps(&[
        "simulate",
        "--preset",
        "short",
        "--length-m",
        "120",
        "--quiet",
        "--out",
        drive.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    thin_first_frames(&drive, 5, 3);

    replay(&drive, &dir.path().join("forward"), "forward");
    let combined_run = replay(&drive, &dir.path().join("combined"), "combined");
    let forward = fixes(&dir.path().join("forward"));
    let combined = fixes(&dir.path().join("combined"));
    assert_eq!(forward.len(), combined.len());
    let ok = |rows: &[HashMap<String, String>]| rows.iter().filter(|r| r["status"] == "ok").count();
    let waiting = forward.iter().filter(|r| r["status"] == "no_prior").count();
    eprintln!(
        "forward {} ok, {waiting} no_prior; combined {} ok of {}",
        ok(&forward),
        ok(&combined),
        forward.len()
    );
    assert!(
        waiting >= 10,
        "the forward pass waits for its cold start: {waiting}"
    );

    let mut filled = 0;
    for (f, c) in forward.iter().zip(&combined) {
        if f["status"] == "ok" {
            // A forward fix is kept as it was, every column.
            assert_eq!(f, c, "frame {}", f["frame"]);
        } else if c["status"] == "ok" {
            filled += 1;
            assert!(
                c["message"].starts_with("backward pass: "),
                "frame {}: {}",
                c["frame"],
                c["message"]
            );
            let error: f64 = c["err_h_m"].parse().unwrap();
            assert!(
                error < 0.5,
                "frame {}: {error} m from the truth",
                c["frame"]
            );
        } else {
            assert_eq!(f, c, "frame {}", f["frame"]);
        }
    }
    // The frames that waited for the cold start are tracked back from it; the first five
    // (three detections) are not.
    assert!(filled >= waiting - 5, "{filled} filled, {waiting} waiting");
    assert_eq!(ok(&combined), ok(&forward) + filled);
    for r in &combined[..5] {
        assert_ne!(r["status"], "ok", "frame {}", r["frame"]);
    }
    // Both passes give the same fixes on one thread (frame after frame) as on two (the run
    // above) and three (the searches of a lost localizer run ahead on worker threads).
    let two = std::fs::read(dir.path().join("combined").join("fixes.csv")).unwrap();
    for threads in ["1", "3"] {
        let out = dir.path().join(format!("combined{threads}"));
        replay_on(&drive, &out, "combined", threads);
        assert!(
            std::fs::read(out.join("fixes.csv")).unwrap() == two,
            "fixes differ between 2 and {threads} threads"
        );
    }
    // The summary counts what the combination did.
    let report: serde_json::Value = serde_json::from_slice(&combined_run.stdout).unwrap();
    assert_eq!(report["visual_fixes"], ok(&combined));
    let err = String::from_utf8_lossy(&combined_run.stderr);
    assert!(
        err.contains(&format!("{filled} frames filled by the backward pass")),
        "{err}"
    );
}
