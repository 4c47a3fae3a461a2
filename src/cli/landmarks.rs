//! `vgps landmarks import FILE --out landmarks.csv`: a landmark inventory from GIS (GeoJSON
//! points, CSV with latitude and longitude) with ellipsoidal heights
//! ([`vgps_io::gis`]), written as vgps's `landmarks.csv`.
//!
//! GIS inventories need a statement of their heights (ground height, its reference, the
//! lamp height when missing) that a drive's `landmarks.csv` does not, so they are imported
//! once, explicitly, and the written file is what `vgps replay`, `locate` and drives read.

use super::CliError;
use std::io::Write;
use std::path::PathBuf;
use vgps_io::gis::{self, GisOptions, GroundReference};

/// Arguments of `vgps landmarks`.
#[derive(Debug, clap::Args)]
pub struct LandmarksArgs {
    /// The landmarks subcommand.
    #[command(subcommand)]
    pub command: LandmarksCommand,
}

/// The `vgps landmarks` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum LandmarksCommand {
    /// Import a GIS inventory (GeoJSON points or CSV lat/lon) into `landmarks.csv`.
    Import(LandmarkImportArgs),
}

/// How the ground heights are referenced on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HeightReferenceArg {
    /// Above the geoid (orthometric, "above mean sea level"): EGM96 is added.
    Geoid,
    /// Above the WGS84 ellipsoid.
    Ellipsoid,
}

/// Arguments of `vgps landmarks import`.
#[derive(Debug, clap::Args)]
pub struct LandmarkImportArgs {
    /// The inventory: `.geojson`/`.json` (GeoJSON points, WGS84) or `.csv`
    /// (`lat,lon[,id][,height][,ele][,class][,sigma_m]`).
    pub input: PathBuf,
    /// The output `landmarks.csv` (written atomically).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Ground height (m) for features without `ele`.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub ground_height: Option<f64>,
    /// The reference of the ground heights (`ele`, `--ground-height`).
    #[arg(long, value_enum, default_value = "geoid")]
    pub heights: HeightReferenceArg,
    /// Lamp-head height above ground (m) for features without `height`.
    #[arg(long, value_name = "M", default_value_t = 6.0)]
    pub default_lamp_height: f64,
    /// σ per axis (m) of landmarks with a known height.
    #[arg(long, value_name = "M", default_value_t = 0.5)]
    pub sigma: f64,
    /// σ per axis (m) of landmarks given the default lamp height.
    #[arg(long, value_name = "M", default_value_t = 1.5)]
    pub default_height_sigma: f64,
}

/// Validated settings of `vgps landmarks import` ([`super::Settings::Landmarks`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LandmarksSettings {
    /// The inventory (GeoJSON or CSV).
    pub input: PathBuf,
    /// The output `landmarks.csv`.
    pub out: PathBuf,
    /// How features become landmarks (heights, σ).
    pub options: GisOptions,
}

impl TryFrom<LandmarksArgs> for LandmarksSettings {
    type Error = CliError;

    /// # Errors
    /// [`CliError::Input`] (exit 2) naming the option when `--default-lamp-height`,
    /// `--sigma` or `--default-height-sigma` is not a non-negative number, or
    /// `--ground-height` is not finite.
    fn try_from(args: LandmarksArgs) -> Result<Self, CliError> {
        let LandmarksCommand::Import(a) = args.command;
        let bad = |field: &str, reason: String| {
            CliError::Input(vgps_io::InputError::field("command line", 1, field, reason))
        };
        for (name, v) in [
            ("--default-lamp-height", a.default_lamp_height),
            ("--sigma", a.sigma),
            ("--default-height-sigma", a.default_height_sigma),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(name, format!("{v} is not a non-negative number")));
            }
        }
        if let Some(g) = a.ground_height
            && !g.is_finite()
        {
            return Err(bad(
                "--ground-height",
                format!("{g} is not a finite number"),
            ));
        }
        Ok(Self {
            options: GisOptions {
                ground_height_m: a.ground_height,
                reference: match a.heights {
                    HeightReferenceArg::Geoid => GroundReference::Geoid,
                    HeightReferenceArg::Ellipsoid => GroundReference::Ellipsoid,
                },
                default_lamp_height_m: a.default_lamp_height,
                sigma_m: a.sigma,
                default_height_sigma_m: a.default_height_sigma,
                ..GisOptions::default()
            },
            input: a.input,
            out: a.out,
        })
    }
}

/// Runs `vgps landmarks import` on validated settings.
///
/// # Errors
/// [`CliError::Input`] naming the file and the feature or line.
pub fn run(
    s: &LandmarksSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let (a, options) = (s, &s.options);
    let bytes = std::fs::read(&a.input).map_err(|source| vgps_io::InputError::Read {
        path: a.input.clone(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let is_json = text.trim_start().starts_with('{');
    let read = if is_json {
        gis::landmarks_from_geojson(&a.input, &text, options)?
    } else {
        gis::landmarks_from_gis_csv(&a.input, &text, options)?
    };
    if let Some(w) = read.warning(&a.input, options) {
        writeln!(err, "vgps: warning: {w}")?;
    }
    let csv = vgps_replay::drive::landmarks_to_csv(&read.landmarks);
    vgps_io::write_atomic(&a.out, csv.as_bytes())?;
    writeln!(
        out,
        "{} landmarks written to {} ({} with the default lamp height)",
        read.landmarks.len(),
        a.out.display(),
        read.default_height
    )?;
    Ok(())
}
