//! The cost of reading an MCAP recording into a drive, for the "reading ≤ 10 % of a replay"
//! target: `mcap_import_time FILE.mcap RIG LANDMARKS OUT durable|temporary`, timed from
//! outside (`/usr/bin/time -v`). `durable` is `vgps import mcap` (every image written with
//! fsync); `temporary` is what `vgps replay run.mcap` does (no fsync per image).
use std::path::PathBuf;
use vgps_import::mcap_import::{McapImportOptions, import_mcap};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 6 {
        return Err("usage: mcap_import_time FILE RIG LANDMARKS OUT durable|temporary".into());
    }
    let options = McapImportOptions {
        rig: PathBuf::from(&a[2]),
        landmarks: Some(PathBuf::from(&a[3])),
        topics: None,
        stamp_tolerance_s: 0.01,
        durable_images: a[5] == "durable",
    };
    let t = std::time::Instant::now();
    let imported = import_mcap(&PathBuf::from(&a[1]), &PathBuf::from(&a[4]), &options)?;
    println!(
        "{} frames, {} bytes, {:.2} s wall ({})",
        imported.report.frames,
        imported.mcap.bytes,
        t.elapsed().as_secs_f64(),
        a[5]
    );
    Ok(())
}
