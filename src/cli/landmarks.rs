//! `vgps landmarks import FILE --out landmarks.csv`: a landmark inventory from GIS (GeoJSON
//! points, CSV with latitude and longitude) with ellipsoidal heights
//! ([`vgps_io::gis`]), written as vgps's `landmarks.csv`.
//! `vgps landmarks footprints FILE --out landmarks.csv`: building-corner landmarks from
//! building footprints with heights ([`vgps_io::footprints`]).
//!
//! GIS inventories need a statement of their heights (ground height, its reference, the
//! lamp height when missing) that a drive's `landmarks.csv` does not, so they are imported
//! once, explicitly, and the written file is what `vgps replay`, `locate` and drives read.

use super::CliError;
use std::io::Write;
use std::path::PathBuf;
use vgps_io::footprints::{self, FootprintOptions};
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
    /// Building-corner landmarks from footprints with heights (GeoJSON polygons, `height`
    /// or `building:levels`) into `landmarks.csv`.
    Footprints(FootprintArgs),
}

/// Arguments of `vgps landmarks footprints`.
#[derive(Debug, clap::Args)]
pub struct FootprintArgs {
    /// The footprints: GeoJSON (WGS84) polygons or multipolygons with `height` (m above the
    /// ground) or `building:levels`, and optionally `ele` (the ground).
    pub input: PathBuf,
    /// The output `landmarks.csv` (written atomically).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Ground height (m) for features without `ele`: a flat ground for the area.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub ground_height: Option<f64>,
    /// σ (m) of the ground height.
    #[arg(long, value_name = "M", default_value_t = 0.5)]
    pub ground_sigma: f64,
    /// The reference of the ground heights (`ele`, `--ground-height`).
    #[arg(long, value_enum, default_value = "geoid")]
    pub heights: HeightReferenceArg,
    /// σ (m) of the footprints' vertices horizontally (their stated accuracy).
    #[arg(long, value_name = "M", default_value_t = 0.5)]
    pub footprint_sigma: f64,
    /// σ (m) of a `height` tag.
    #[arg(long, value_name = "M", default_value_t = 0.5)]
    pub height_sigma: f64,
    /// Storey height (m) for features with `building:levels` only.
    #[arg(long, value_name = "M", default_value_t = 3.0)]
    pub level_height: f64,
    /// σ (m) of a height from `building:levels`.
    #[arg(long, value_name = "M", default_value_t = 1.5)]
    pub levels_sigma: f64,
    /// Least turn of the outline (degrees) at a vertex for it to be a corner.
    #[arg(long, value_name = "DEG", default_value_t = 20.0)]
    pub min_turn_deg: f64,
    /// Also write each corner at ground level.
    #[arg(long)]
    pub ground_corners: bool,
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

/// Validated settings of `vgps landmarks` ([`super::Settings::Landmarks`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LandmarksSettings {
    /// The inventory (GeoJSON or CSV) or the footprints (GeoJSON).
    pub input: PathBuf,
    /// The output `landmarks.csv`.
    pub out: PathBuf,
    /// What to read and how features become landmarks.
    pub job: LandmarksJob,
}

/// The conversion of `vgps landmarks`.
#[derive(Clone, Debug, PartialEq)]
pub enum LandmarksJob {
    /// Points of a GIS inventory (`import`).
    Inventory(GisOptions),
    /// Corners of building footprints (`footprints`).
    Footprints(FootprintOptions),
}

impl TryFrom<LandmarksArgs> for LandmarksSettings {
    type Error = CliError;

    /// # Errors
    /// [`CliError::Input`] (exit 2) naming the option when `--default-lamp-height`,
    /// `--sigma` or `--default-height-sigma` is not a non-negative number, or
    /// `--ground-height` is not finite.
    fn try_from(args: LandmarksArgs) -> Result<Self, CliError> {
        let bad = |field: &str, reason: String| {
            CliError::Input(vgps_io::InputError::field("command line", 1, field, reason))
        };
        let non_negative = |values: &[(&str, f64)]| {
            values.iter().try_for_each(|&(name, v)| {
                if v.is_finite() && v >= 0.0 {
                    Ok(())
                } else {
                    Err(bad(name, format!("{v} is not a non-negative number")))
                }
            })
        };
        let ground = |g: Option<f64>| match g {
            Some(g) if !g.is_finite() => Err(bad(
                "--ground-height",
                format!("{g} is not a finite number"),
            )),
            _ => Ok(g),
        };
        let reference = |h: HeightReferenceArg| match h {
            HeightReferenceArg::Geoid => GroundReference::Geoid,
            HeightReferenceArg::Ellipsoid => GroundReference::Ellipsoid,
        };
        match args.command {
            LandmarksCommand::Import(a) => {
                non_negative(&[
                    ("--default-lamp-height", a.default_lamp_height),
                    ("--sigma", a.sigma),
                    ("--default-height-sigma", a.default_height_sigma),
                ])?;
                Ok(Self {
                    job: LandmarksJob::Inventory(GisOptions {
                        ground_height_m: ground(a.ground_height)?,
                        reference: reference(a.heights),
                        default_lamp_height_m: a.default_lamp_height,
                        sigma_m: a.sigma,
                        default_height_sigma_m: a.default_height_sigma,
                        ..GisOptions::default()
                    }),
                    input: a.input,
                    out: a.out,
                })
            }
            LandmarksCommand::Footprints(a) => {
                non_negative(&[
                    ("--ground-sigma", a.ground_sigma),
                    ("--footprint-sigma", a.footprint_sigma),
                    ("--height-sigma", a.height_sigma),
                    ("--level-height", a.level_height),
                    ("--levels-sigma", a.levels_sigma),
                    ("--min-turn-deg", a.min_turn_deg),
                ])?;
                Ok(Self {
                    job: LandmarksJob::Footprints(FootprintOptions {
                        ground_height_m: ground(a.ground_height)?,
                        reference: reference(a.heights),
                        ground_sigma_m: a.ground_sigma,
                        horizontal_sigma_m: a.footprint_sigma,
                        height_sigma_m: a.height_sigma,
                        level_height_m: a.level_height,
                        levels_sigma_m: a.levels_sigma,
                        min_turn_deg: a.min_turn_deg,
                        ground_corners: a.ground_corners,
                    }),
                    input: a.input,
                    out: a.out,
                })
            }
        }
    }
}

/// Runs `vgps landmarks import` or `vgps landmarks footprints` on validated settings.
///
/// # Errors
/// [`CliError::Input`] naming the file and the feature or line.
pub fn run(
    s: &LandmarksSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let bytes = std::fs::read(&s.input).map_err(|source| vgps_io::InputError::Read {
        path: s.input.clone(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let (landmarks, summary) = match &s.job {
        LandmarksJob::Inventory(options) => {
            let read = if text.trim_start().starts_with('{') {
                gis::landmarks_from_geojson(&s.input, &text, options)?
            } else {
                gis::landmarks_from_gis_csv(&s.input, &text, options)?
            };
            if let Some(w) = read.warning(&s.input, options) {
                writeln!(err, "vgps: warning: {w}")?;
            }
            let summary = format!("({} with the default lamp height)", read.default_height);
            (read.landmarks, summary)
        }
        LandmarksJob::Footprints(options) => {
            let read = footprints::corners_from_footprints(&s.input, &text, options)?;
            for message in &read.skipped {
                writeln!(err, "vgps: warning: {message}")?;
            }
            let summary = format!(
                "(corners of {} footprints, {} with heights from building:levels; {} features skipped)",
                read.footprints,
                read.from_levels,
                read.skipped.len()
            );
            (read.landmarks, summary)
        }
    };
    let csv = vgps_replay::drive::landmarks_to_csv(&landmarks);
    vgps_io::write_atomic(&s.out, csv.as_bytes())?;
    writeln!(
        out,
        "{} landmarks written to {} {summary}",
        landmarks.len(),
        s.out.display()
    )?;
    Ok(())
}
