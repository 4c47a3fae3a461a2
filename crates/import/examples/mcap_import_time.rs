//! The cost of reading an MCAP recording, for the "reading ≤ 10 % of a replay" target:
//! `mcap_import_time FILE.mcap RIG LANDMARKS OUT files|recording`, timed from outside
//! (`/usr/bin/time -v`). `files` is `vgps import mcap` (every image written as a file,
//! durably); `recording` is what `vgps replay run.mcap` does: the small drive files only, then
//! every frame's image bytes read back from the recording in frame order (no image written;
//! what is left of the replay is decoding them, as from a folder).
use std::path::PathBuf;
use vgps_import::mcap_import::{ImageOutput, McapImportOptions, import_mcap};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 6 || !["files", "recording"].contains(&a[5].as_str()) {
        return Err("usage: mcap_import_time FILE RIG LANDMARKS OUT files|recording".into());
    }
    let options = McapImportOptions {
        rig: PathBuf::from(&a[2]),
        landmarks: Some(PathBuf::from(&a[3])),
        topics: None,
        stamp_tolerance_s: 0.01,
        images: if a[5] == "files" {
            ImageOutput::Files
        } else {
            ImageOutput::InRecording
        },
    };
    let t = std::time::Instant::now();
    let imported = import_mcap(&PathBuf::from(&a[1]), &PathBuf::from(&a[4]), &options)?;
    let first = t.elapsed().as_secs_f64();
    let (mut frames, mut images, mut bytes) = (0, 0, 0);
    if let Some(recording) = &imported.recording_images {
        for f in recording.stream(64) {
            frames += 1;
            for image in f.images.iter().flatten() {
                images += 1;
                bytes += image.as_ref().map_or(0, Vec::len);
            }
        }
    }
    println!(
        "{} frames, {} MCAP bytes, first read {first:.2} s; read back {frames} frames, \
         {images} images, {bytes} image bytes; {:.2} s wall ({})",
        imported.report.frames,
        imported.mcap.bytes,
        t.elapsed().as_secs_f64(),
        a[5]
    );
    Ok(())
}
