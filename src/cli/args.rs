//! The command-line grammar (clap derive); [`super::settings`] validates it once into
//! settings.

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use vgps_geometry::geo::Geodetic;

/// Default standard deviation of a bearing per tangent axis, degrees: about one pixel of a
/// Ladybug-class camera (1.7 mrad, the figure of the Visual GPS proposal).
pub const DEFAULT_SIGMA_DEG: f64 = 0.1;

/// Default standard deviation of a ray's observer position per axis, metres, for
/// `triangulate` when the rays file has no `sigma_pos_m`.
pub const DEFAULT_SIGMA_POS_M: f64 = 0.0;

/// The `vgps` command line.
#[derive(Debug, Parser)]
#[command(
    name = "vgps",
    version,
    about = "Visual GPS: position and attitude of a spherical camera from surveyed landmarks",
    long_about = None
)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Position and attitude, per frame, from bearings to surveyed landmarks (JSON lines).
    Locate(LocateArgs),
    /// Landmark positions from rays seen at known positions (CSV).
    Triangulate(TriangulateArgs),
    /// The main job end to end: simulate the reference drive, replay it, print the summary.
    Demo(super::demo::DemoArgs),
    /// Inspect, check, use and convert calibration files.
    Calib(super::calib::CalibArgs),
    /// Write a simulated drive (city, route, detections, GPS with outages, truth).
    Simulate(super::simulate::SimulateArgs),
    /// Visual GPS for every frame of a logged drive, against satellite GPS and truth.
    Replay(super::replay::ReplayArgs),
    /// Detect the lamps in every image of a drive (writes a detections file).
    Detect(super::detect::DetectArgs),
    /// Survey mode: a landmark inventory from a drive's GPS + heading and detections.
    Map(super::map::MapArgs),
    /// Landmark inventories: import GIS points (GeoJSON, CSV lat/lon) into landmarks.csv.
    Landmarks(super::landmarks::LandmarksArgs),
    /// Logs of other tools into a drive folder: rosbag2 MCAP, NCLT sessions, image folders.
    Import(super::import::ImportArgs),
}

/// Arguments of `vgps locate`.
#[derive(Debug, Args)]
pub struct LocateArgs {
    /// Landmarks CSV: `id,lat,lon,alt[,sigma_m][,class]`.
    #[arg(long, value_name = "L.csv")]
    pub landmarks: PathBuf,
    /// Observations CSV: `[frame,](bx,by,bz | camera,u,v)[,landmark]`.
    #[arg(long, value_name = "O.csv")]
    pub observations: PathBuf,
    /// Camera calibration of the rig (native JSON, Ladybug INI, NCLT; see `vgps calib`),
    /// needed for pixel observations `camera,u,v`.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Position prior: latitude and longitude (degrees), height (m), radius (m).
    #[arg(long, value_name = "LAT,LON,ALT,RADIUS_M", value_parser = parse_prior, allow_hyphen_values = true)]
    pub prior: Option<PriorArg>,
    /// Cold-start search region for frames without landmark ids (when there is no
    /// `--prior`): the rig is within RADIUS_M (horizontally) of LAT,LON and near height ALT.
    #[arg(long, value_name = "LAT,LON,ALT,RADIUS_M", value_parser = parse_prior, allow_hyphen_values = true)]
    pub region: Option<PriorArg>,
    /// Known vertical for the matcher: the rig's +z axis is within this many degrees of
    /// up (a level vehicle, or an IMU-levelled rig). Much faster matching. Overrides the
    /// calibration's `level_within_deg`.
    #[arg(long, value_name = "DEG", value_parser = parse_non_negative)]
    pub up_tolerance_deg: Option<f64>,
    /// Bearing standard deviation per tangent axis, degrees.
    #[arg(long, value_name = "S", default_value_t = DEFAULT_SIGMA_DEG, value_parser = parse_positive)]
    pub sigma_deg: f64,
}

/// Arguments of `vgps triangulate`.
#[derive(Debug, Args)]
pub struct TriangulateArgs {
    /// Rays CSV: `id,lat,lon,alt,de,dn,du[,sigma_pos_m][,sigma_ang_deg]`.
    #[arg(long, value_name = "R.csv")]
    pub rays: PathBuf,
    /// Direction standard deviation per tangent axis, degrees, for rows without
    /// sigma_ang_deg.
    #[arg(long, value_name = "S", default_value_t = DEFAULT_SIGMA_DEG, value_parser = parse_positive)]
    pub sigma_deg: f64,
    /// Observer position standard deviation per axis, metres, for rows without sigma_pos_m.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_SIGMA_POS_M, value_parser = parse_non_negative)]
    pub sigma_pos_m: f64,
}

/// A position prior as given on the command line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorArg {
    /// The prior position.
    pub position: Geodetic,
    /// Radius around it, metres (positive).
    pub radius_m: f64,
}

fn parse_prior(text: &str) -> Result<PriorArg, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err(format!(
            "expected LAT,LON,ALT,RADIUS_M (4 comma-separated numbers), got {} value(s)",
            parts.len()
        ));
    }
    let names = ["LAT", "LON", "ALT", "RADIUS_M"];
    let mut values = [0.0; 4];
    for ((value, part), name) in values.iter_mut().zip(&parts).zip(names) {
        *value = part
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{name} `{part}` is not a finite number"))?;
    }
    let [lat, lon, alt, radius_m] = values;
    if lat.abs() > vgps_io::MAX_ABS_LAT_DEG {
        return Err(format!("LAT {lat} is outside [-90, 90] degrees"));
    }
    if lon.abs() > vgps_io::MAX_ABS_LON_DEG {
        return Err(format!("LON {lon} is outside [-180, 180] degrees"));
    }
    if radius_m <= 0.0 {
        return Err(format!("RADIUS_M {radius_m} is not positive"));
    }
    let position = Geodetic::try_new(lat, lon, alt).map_err(|e| e.to_string())?;
    Ok(PriorArg { position, radius_m })
}

/// A positive finite number (`--sigma-deg`, `--pixel-sigma-px`, …).
pub(super) fn parse_positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{text}` is not a positive finite number")),
    }
}

/// A non-negative finite number (`--up-tolerance-deg`, `--smooth-s`, …).
pub(super) fn parse_non_negative(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("`{text}` is not a non-negative finite number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prior_parses_and_validates() {
        let p = parse_prior("37.5, -122.25,10,50").unwrap();
        assert_eq!(
            (
                p.position.lat_deg,
                p.position.lon_deg,
                p.position.alt_m,
                p.radius_m
            ),
            (37.5, -122.25, 10.0, 50.0)
        );
        assert!(
            parse_prior("37.5,-122.25,10")
                .unwrap_err()
                .contains("got 3")
        );
        assert!(parse_prior("91,0,0,1").unwrap_err().contains("LAT 91"));
        assert!(parse_prior("1,0,0,0").unwrap_err().contains("RADIUS_M 0"));
        assert!(parse_prior("1,NaN,0,3").unwrap_err().contains("LON `NaN`"));
    }
}
