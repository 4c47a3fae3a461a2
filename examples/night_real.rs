//! Lamp-head recall and precision of [`StreetLampDetector`] on hand-labelled real night
//! photos (the issue #24 metric).
//!
//! Usage: `cargo run --release --example night_real -- DIR` where DIR holds `labels.csv`
//! (`image,u,v,radius_px,certain`) and the images it names (`bench/night_real.sh` passes
//! the project's shared real-data folder). For each image: a certain lamp is found when a lamp
//! detection lies within `max(1.5 · radius, 3 px)` of it; a lamp detection is true when it is
//! the first within that distance of a certain lamp, excused (not counted) when it lies on a
//! lamp labelled `certain = 0`, and false otherwise (a second detection on the same lamp is
//! false). Detections of the other classes (window, reflection, vehicle, ghost) are not lamp
//! detections and are only counted. Prints one line per image and a total.
//!
//! With `VGPS_DUMP=DIR` set, writes `DIR/<image>.png`: the luminance with lamp detections
//! marked by white crosses, other classes by grey squares and missed certain lamps by
//! black circles.
use std::collections::BTreeMap;
use std::path::PathBuf;
use vgps::imaging::{DecodeLimits, StreetLampDetector, encode_png, read_image};

/// The match distance for a labelled radius (px).
fn reach(radius: f64) -> f64 {
    (1.5 * radius).max(3.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: night_real DIR")?);
    let dump = std::env::var_os("VGPS_DUMP").map(PathBuf::from);
    let text = std::fs::read_to_string(dir.join("labels.csv"))?;
    let mut labels: BTreeMap<String, Vec<(f64, f64, f64, bool)>> = BTreeMap::new();
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 5 {
            return Err(format!("labels.csv: bad line {line:?}").into());
        }
        labels.entry(f[0].to_string()).or_default().push((
            f[1].parse()?,
            f[2].parse()?,
            f[3].parse()?,
            f[4] == "1",
        ));
    }
    let detector = StreetLampDetector::default();
    let (mut all_found, mut all_certain, mut all_true, mut all_false) = (0, 0, 0, 0);
    for (name, lamps) in &labels {
        let image = read_image(&dir.join(name), &DecodeLimits::default())?;
        let t = std::time::Instant::now();
        let det = detector.detect(&image)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let certain = lamps.iter().filter(|l| l.3).count();
        let mut hit = vec![false; lamps.len()];
        let (mut tp, mut fp, mut excused) = (0, 0, 0);
        let mut false_at = Vec::new();
        for d in &det.lamps {
            let on = lamps
                .iter()
                .enumerate()
                .filter(|(_, l)| (d.u - l.0).hypot(d.v - l.1) <= reach(l.2))
                .min_by(|a, b| {
                    let da = (d.u - a.1.0).hypot(d.v - a.1.1);
                    let db = (d.u - b.1.0).hypot(d.v - b.1.1);
                    da.total_cmp(&db)
                });
            match on {
                Some((k, l)) if l.3 && !hit[k] => {
                    hit[k] = true;
                    tp += 1;
                }
                Some((_, l)) if !l.3 => excused += 1,
                _ => {
                    fp += 1;
                    false_at.push(format!("({:.0},{:.0} r{:.1})", d.u, d.v, d.radius_px));
                }
            }
        }
        let found = lamps.iter().zip(&hit).filter(|(l, h)| l.3 && **h).count();
        let missed: Vec<String> = lamps
            .iter()
            .zip(&hit)
            .filter(|(l, h)| l.3 && !**h)
            .map(|(l, _)| format!("({:.0},{:.0} r{})", l.0, l.1, l.2))
            .collect();
        println!(
            "{name}: recall {found}/{certain} = {:.1} %, precision {tp}/{} = {:.1} % \
             (excused {excused}; other classes {}; rejected {}; detect {ms:.2} ms) missed {missed:?} false {false_at:?}",
            100.0 * found as f64 / certain.max(1) as f64,
            tp + fp,
            100.0 * tp as f64 / (tp + fp).max(1) as f64,
            det.others.len(),
            det.rejected,
        );
        all_found += found;
        all_certain += certain;
        all_true += tp;
        all_false += fp;
        if let Some(out) = &dump {
            std::fs::create_dir_all(out)?;
            let mut img = image.clone();
            let mut put = |x: f64, y: f64, value: u8| {
                if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
                    img.put_pixel(x as u32, y as u32, image::Luma([value]));
                }
            };
            for d in &det.lamps {
                for k in -8..=8 {
                    put(d.u + f64::from(k), d.v, 255);
                    put(d.u, d.v + f64::from(k), 255);
                }
            }
            for d in &det.others {
                for k in -6..=6 {
                    let k = f64::from(k);
                    put(d.u + k, d.v - 6.0, 128);
                    put(d.u + k, d.v + 6.0, 128);
                    put(d.u - 6.0, d.v + k, 128);
                    put(d.u + 6.0, d.v + k, 128);
                }
            }
            for (l, _) in lamps.iter().zip(&hit).filter(|(l, h)| l.3 && !**h) {
                for a in 0..64 {
                    let t = f64::from(a) / 64.0 * std::f64::consts::TAU;
                    put(l.0 + reach(l.2) * t.cos(), l.1 + reach(l.2) * t.sin(), 0);
                }
            }
            std::fs::write(out.join(format!("{name}.png")), encode_png(&img)?)?;
        }
    }
    println!(
        "total: recall {all_found}/{all_certain} = {:.1} %, precision {all_true}/{} = {:.1} %",
        100.0 * all_found as f64 / all_certain.max(1) as f64,
        all_true + all_false,
        100.0 * all_true as f64 / (all_true + all_false).max(1) as f64
    );
    Ok(())
}
