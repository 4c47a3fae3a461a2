//! Writes every `vgps replay` output for a synthetic drive (a 200 m loop at 2 Hz with a
//! satellite blackout and a surrogate-only stretch), to look at them.
//!
//! `cargo run --release --example replay_report -- OUT_DIR`

use nalgebra::{Matrix2, UnitQuaternion, Vector3};
use rand_distr::{Distribution, Normal};
use vgps::geo::{Geodetic, LocalFrame};
use vgps::report::{DriveInfo, FrameOutcome, Truth, VisualFix, summary_table, write_outputs};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "replay_report".into());
    let origin = Geodetic::try_new(37.4275, -122.1697, 30.0)?;
    let frame = LocalFrame::new(origin);
    let drive = DriveInfo {
        name: "synthetic loop".into(),
        origin,
    };
    let mut rng = vgps::synthetic::rng(7);
    let unit = Normal::new(0.0, 1.0)?;
    let n = 600;
    let radius = 200.0;
    let mut records = Vec::with_capacity(n);
    for i in 0..n {
        let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
        let p = Vector3::new(radius * a.cos(), radius * a.sin(), 0.5 * (3.0 * a).sin());
        let heading = (90.0 - (a.to_degrees() + 90.0)).rem_euclid(360.0);
        let truth = frame.try_to_geodetic(&p)?;
        let blackout = (200..300).contains(&i);
        let surrogate = (220..280).contains(&i);
        let no_fix = i % 37 == 5;
        let sigma = if surrogate {
            0.5 + 0.03 * (i - 220) as f64
        } else {
            0.4
        };
        let drift = if surrogate {
            0.02 * 1.05 * (i - 219) as f64 * 2.0
        } else {
            0.0
        };
        let err = Vector3::new(
            sigma * unit.sample(&mut rng) + drift,
            sigma * unit.sample(&mut rng),
            0.8 * unit.sample(&mut rng),
        );
        let gnss_err = Vector3::new(
            2.5 * unit.sample(&mut rng),
            2.5 * unit.sample(&mut rng),
            4.0 * unit.sample(&mut rng),
        );
        let visual = (!no_fix).then(|| -> Result<VisualFix, vgps::geo::GeoError> {
            Ok(VisualFix {
                geodetic: frame.try_to_geodetic(&(p + err))?,
                heading_deg: heading + 0.3 * unit.sample(&mut rng),
                pitch_deg: 0.2,
                roll_deg: -0.1,
                enu_from_rig: UnitQuaternion::identity(),
                sigma_e_m: sigma,
                sigma_n_m: sigma,
                sigma_u_m: 0.8,
                horizontal_covariance_m2: Matrix2::identity() * sigma * sigma,
                pose_covariance: nalgebra::Matrix6::from_diagonal(&nalgebra::Vector6::new(
                    sigma * sigma,
                    sigma * sigma,
                    0.64,
                    1e-6,
                    1e-6,
                    1e-6,
                )),
                n_landmarks: if surrogate { 1 } else { 6 },
                n_surrogates: if surrogate { 5 } else { 0 },
            })
        });
        let visual = visual.transpose()?;
        records.push(FrameOutcome {
            frame: i as u64,
            time_s: 1_700_000_000.0 + 0.5 * i as f64,
            status: if no_fix { "no_fix" } else { "ok" }.into(),
            visual,
            gnss: if blackout {
                None
            } else {
                Some(frame.try_to_geodetic(&(p + gnss_err))?)
            },
            unusable_images: None,
            truth: Some(Truth {
                geodetic: truth,
                heading_deg: heading,
            }),
            message: if no_fix {
                "simulated: no fix on this frame".into()
            } else {
                String::new()
            },
        });
    }
    let (report, files) = write_outputs(std::path::Path::new(&out), &drive, &records)?;
    print!("{}", summary_table(&report));
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
