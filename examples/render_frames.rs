//! Renders night street frames of the Ladybug2-like rig to PNG files, for the detector's peer
//! comparison (`bench/peers/detect_peers.py`) and for looking at.
//!
//! Usage: `cargo run --release --example render_frames -- DIR [FRAMES] [SEED] [CLUTTER]`
//! (defaults 10 frames, seed 1, 6 clutter lights per image). Writes
//! `DIR/frameNNNN_camC.png` (C = 0…5) and `DIR/truth.csv` (one row per drawn spot:
//! `file,kind,u,v,sigma_major_px,flux_dn,peak_dn,range_m`), and prints the median render
//! and encode times per image and the mean PNG size.
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use vgps::imaging::{RenderOptions, Renderer, SpotKind, encode_png};
use vgps::synthetic::calibration_files::ladybug2_rig;
use vgps::synthetic::night::{StreetConfig, lights_in_camera, street_lamps};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(
        args.first()
            .ok_or("usage: render_frames DIR [FRAMES] [SEED] [CLUTTER]")?,
    );
    let frames: usize = args.get(1).map_or(Ok(10), |s| s.parse())?;
    let seed: u64 = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let clutter: usize = args.get(3).map_or(Ok(6), |s| s.parse())?;
    std::fs::create_dir_all(&dir)?;
    let rig = ladybug2_rig();
    let renderer = Renderer::new(RenderOptions {
        clutter_lights: clutter,
        ..RenderOptions::default()
    });
    let mut rng = vgps::synthetic::rng(seed);
    let mut truth = std::io::BufWriter::new(std::fs::File::create(dir.join("truth.csv"))?);
    writeln!(
        truth,
        "file,kind,u,v,sigma_major_px,flux_dn,peak_dn,range_m"
    )?;
    let (mut render_ms, mut encode_ms, mut bytes) = (Vec::new(), Vec::new(), 0usize);
    for frame in 0..frames {
        let lamps = street_lamps(&mut rng, &StreetConfig::default());
        for (c, camera) in rig.cameras().iter().enumerate() {
            let lights = lights_in_camera(camera, &lamps);
            let t = Instant::now();
            let rendered = renderer.render(
                &camera.model,
                &lights,
                seed.wrapping_mul(1 << 20) + (frame * 8 + c) as u64,
            );
            render_ms.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let png = encode_png(&rendered.image)?;
            encode_ms.push(t.elapsed().as_secs_f64() * 1e3);
            bytes += png.len();
            let name = format!("frame{frame:04}_cam{c}.png");
            std::fs::write(dir.join(&name), &png)?;
            for s in &rendered.spots {
                let kind = match s.kind {
                    SpotKind::Lamp(i) => format!("lamp{i}"),
                    SpotKind::Clutter => "clutter".into(),
                };
                let range = s.range_m.map_or(String::new(), |r| format!("{r:.3}"));
                writeln!(
                    truth,
                    "{name},{kind},{:.4},{:.4},{:.3},{:.1},{:.1},{range}",
                    s.u, s.v, s.sigma_major_px, s.flux_dn, s.peak_dn
                )?;
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let n = render_ms.len();
    println!(
        "images={n} render_ms_median={:.3} encode_ms_median={:.3} bytes_per_image_mean={}",
        median(&mut render_ms),
        median(&mut encode_ms),
        bytes / n.max(1)
    );
    Ok(())
}
