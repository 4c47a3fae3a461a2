//! What `vgps calib show` and `check` print about the calibration *file* beyond its rig:
//! for a Ladybug `.conf`, the header (serial, part id, resolution, stitching sphere) and
//! per camera the residuals of the 3-D ↔ 2-D pairs the SDK stored in the file and the
//! consistency of its two warps; for a Ladybug INI dump, the informational keys, the global
//! rotation, where the image size comes from and the warnings.

use super::calib::SourceArgs;
use std::path::Path;
use vgps_camera::calibration::Format;
use vgps_camera::calibration::formats::{detect, ladybug_conf, ladybug_ini};

/// Largest stored-pair residual accepted by `calib check` (pixels of the rectified image).
pub const PAIR_RESIDUAL_LIMIT_PX: f64 = 0.05;

/// The lines about the file (empty for the formats that have nothing more to say), and
/// whether every check passed.
///
/// # Errors
/// The message of a file that cannot be read again.
pub fn file_info(path: &Path, source: &SourceArgs) -> Result<(String, bool), String> {
    let format = match source.format {
        Some(f) => f,
        None => detect::detect(path).map_err(|e| e.to_string())?,
    };
    match format {
        Format::LadybugConf => {
            let conf = ladybug_conf::read_conf(path).map_err(|e| e.to_string())?;
            Ok(conf_text(&conf))
        }
        Format::LadybugIni => {
            let text =
                std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
            let (_, info) = ladybug_ini::parse_with_info(&text, path, source.image_size)
                .map_err(|e| e.to_string())?;
            let mut out = String::new();
            let or_none = |v: &Option<String>| v.clone().unwrap_or_else(|| "(not given)".into());
            out += &format!("camera model: {}\n", or_none(&info.camera_model));
            out += &format!(
                "serial: base {}, head {}\n",
                or_none(&info.serial_base),
                or_none(&info.serial_head)
            );
            match info.global_rotation {
                Some([x, y, z]) => {
                    out += &format!(
                        "global rotation dRx {:.6}° dRy {:.6}° dRz {:.6}° (applied: rig_from_camera = G·camera)\n",
                        x.to_degrees(),
                        y.to_degrees(),
                        z.to_degrees()
                    );
                }
                None => out += "global rotation: none\n",
            }
            match &info.image_size {
                Some(((w, h), from)) => out += &format!("image size: {w}×{h} (from {from})\n"),
                None => out += "image size: unknown (give --image-size WxH)\n",
            }
            for w in &info.warnings {
                out += &format!("warning: {w}\n");
            }
            Ok((out, true))
        }
        _ => Ok((String::new(), true)),
    }
}

fn conf_text(conf: &ladybug_conf::LadybugConf) -> (String, bool) {
    let mut ok = true;
    let or_none = |v: &Option<String>| v.clone().unwrap_or_else(|| "(not given)".into());
    let mut out = format!(
        "Ladybug .conf {:?}: product {}, part {}, serial {}, date {}\n",
        conf.version,
        or_none(&conf.product),
        or_none(&conf.part_id),
        or_none(&conf.serial_number),
        or_none(&conf.date)
    );
    out += &format!(
        "resolution {}×{} px per camera (raw and rectified, sensor orientation)",
        conf.resolution.0, conf.resolution.1
    );
    match conf.surface_parameter {
        Some(r) => out += &format!(", stitching sphere radius {r} m\n"),
        None => out += "\n",
    }
    for c in &conf.cameras {
        let [fx, fy, cx, cy] = conf.rectified_intrinsics(c);
        out += &format!(
            "camera {}: rectified pinhole fx {fx:.3} fy {fy:.3} cx {cx:.3} cy {cy:.3} px; warps raw→rectified {:?}, rectified→raw {:?}\n",
            c.id, c.distorted_spline, c.rectified_spline
        );
        let residuals = conf.pair_residuals(c);
        let mut parts = Vec::new();
        let mut worst: f64 = 0.0;
        for ((name, _, r), seen) in &residuals {
            if *seen {
                parts.push(format!("{name} {:.4}", r.norm()));
                worst = worst.max(r.norm());
            } else {
                parts.push(format!("{name} not seen"));
                worst = f64::INFINITY;
            }
        }
        let pass = worst <= PAIR_RESIDUAL_LIMIT_PX;
        ok &= pass;
        out += &format!(
            "  stored pairs (px): {}; max {worst:.4} (limit {PAIR_RESIDUAL_LIMIT_PX}) {}\n",
            parts.join(", "),
            if pass { "ok" } else { "FAIL" }
        );
        if let Some(w) = conf.warp_consistency(c, 41) {
            out += &format!(
                "  RectifiedSpline vs the inverse of DistortedSpline: max {w:.4} px (information; vgps inverts DistortedSpline by Newton)\n"
            );
        }
    }
    for w in &conf.warnings {
        out += &format!("warning: {w}\n");
    }
    (out, ok)
}
