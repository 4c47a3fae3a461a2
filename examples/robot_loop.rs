//! A robot stack's loop around the localizer: a camera thread sends frames (time,
//! detections, satellite GPS while there is any) over a channel; the localizer runs on its
//! own thread and publishes fixes. Half way through, the satellite GPS is cut: the visual
//! fix carries on.
//!
//! Run: `cargo run --release --example robot_loop`
use std::sync::Arc;
use std::sync::mpsc;
use vgps::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus,
};
use vgps::simulate::{Preset, Scenario, simulate};

const FRAMES: usize = 600;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The "world": a simulated drive stands in for the camera and the survey.
    let drive = simulate(&Scenario::preset(Preset::Reference, 1))?;
    let map = Arc::new(LandmarkMap::from_landmarks(
        &drive.surveyed_landmarks()?,
        None,
    )?);
    let rig = Arc::new(drive.scenario.rig.clone());
    // The simulator's poses are in ENU at the scenario's origin.
    let sim_frame = vgps::geo::LocalFrame::new(drive.scenario.origin);

    let (frames_tx, frames_rx) = mpsc::channel::<Frame>();
    let (fixes_tx, fixes_rx) = mpsc::channel();

    // The localizer thread: owns its Localizer (Send); the map is shared read-only.
    let localizer_map = Arc::clone(&map);
    let worker = std::thread::spawn(move || -> Result<(), String> {
        let mut localizer = Localizer::new(rig, localizer_map, LocalizerOptions::default())
            .map_err(|e| e.to_string())?;
        for frame in frames_rx {
            let fix = localizer.process(&frame);
            if fixes_tx.send(fix).is_err() {
                break;
            }
        }
        Ok(())
    });

    // The camera thread's job, here inline: detections plus satellite GPS (the truth blurred
    // by 2 m stands in for a receiver) until half way.
    for (k, f) in drive.frames.iter().take(FRAMES).enumerate() {
        let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
        let gnss = if k < FRAMES / 2 {
            let p = f.world_from_rig.translation.vector + nalgebra::Vector3::new(1.5, -1.2, 0.5);
            Some(GnssPosition {
                position: sim_frame.try_to_geodetic(&p)?,
            })
        } else {
            None
        };
        frames_tx.send(Frame::from_detections(f.time_s, &detections, &map, gnss))?;
    }
    drop(frames_tx);

    // The consumer: count fixes and print a few.
    let mut ok = [0usize; 2];
    for (k, fix) in fixes_rx.iter().enumerate() {
        let half = usize::from(k >= FRAMES / 2);
        if fix.status == LocalizerStatus::Ok {
            ok[half] += 1;
        }
        if k % 100 == 0 {
            match &fix.estimate {
                Some(e) => {
                    let [h, p, r] = e.heading_pitch_roll.to_degrees();
                    let [se, sn, _] = e.sigma_enu_m();
                    println!(
                        "frame {k:4}: {:.7}, {:.7}  heading {h:6.2}° pitch {p:5.2}° roll {r:5.2}°  σ {se:.3}/{sn:.3} m  {} landmarks, {} surrogates",
                        e.geodetic.lat_deg,
                        e.geodetic.lon_deg,
                        e.landmarks.len(),
                        e.surrogates.len()
                    );
                }
                None => println!("frame {k:4}: {} ({})", fix.status, fix.message),
            }
        }
    }
    worker.join().map_err(|_| "localizer thread panicked")??;
    println!(
        "fixes with satellite GPS: {}/{}, without: {}/{}",
        ok[0],
        FRAMES / 2,
        ok[1],
        FRAMES - FRAMES / 2
    );
    Ok(())
}
