//! `vgps triangulate`: landmark positions from rays, written as CSV.

use super::{CliError, TriangulateSettings};
use nalgebra::Matrix3;
use std::collections::HashMap;
use std::io::Write;
use std::path::Path;
use vgps_geometry::geo::{Geodetic, LocalFrame};
use vgps_geometry::geometry::Ray;
use vgps_geometry::triangulation::{RayObservation, TriangulationError, triangulate_rays};
use vgps_io::{InputError, RayRecord};

/// The output columns of `vgps triangulate`.
pub const COLUMNS: [&str; 12] = [
    "id", "lat", "lon", "alt", "n_obs", "cov_ee", "cov_en", "cov_eu", "cov_nn", "cov_nu", "cov_uu",
    "status",
];

/// Status of a triangulated id.
pub const STATUS_OK: &str = "ok";

/// The result for one landmark id.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangulatedLandmark {
    /// The landmark id.
    pub id: String,
    /// Number of rays with this id.
    pub n_obs: usize,
    /// The position and its covariance in the ENU frame at the position (m²), or the reason
    /// there is none (a short status token and a message).
    pub result: Result<(Geodetic, Matrix3<f64>), (String, String)>,
    /// The lines of the rays of this id.
    pub lines: Vec<u64>,
}

/// Runs `vgps triangulate`: reads the rays, writes one CSV row per id (first-seen order).
///
/// An id that cannot be triangulated gets a row with its `n_obs`, empty numeric fields and
/// the reason in `status`, and a line on `err`; the other ids go on.
///
/// # Errors
/// [`CliError::Input`] for an invalid rays file; [`CliError::Output`] when writing fails.
pub fn run(
    settings: &TriangulateSettings,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(), CliError> {
    let rays = vgps_io::read_rays(&settings.rays)?;
    let results = triangulate(&rays, &settings.rays, settings)?;
    let mut writer = csv::Writer::from_writer(out);
    let csv_err = |e: csv::Error| CliError::Output(std::io::Error::other(e.to_string()));
    writer.write_record(COLUMNS).map_err(csv_err)?;
    for t in &results {
        let mut record: Vec<String> = vec![t.id.clone()];
        match &t.result {
            Ok((g, c)) => {
                record.extend([g.lat_deg, g.lon_deg, g.alt_m].map(|v| v.to_string()));
                record.push(t.n_obs.to_string());
                record.extend(
                    [
                        c[(0, 0)],
                        c[(0, 1)],
                        c[(0, 2)],
                        c[(1, 1)],
                        c[(1, 2)],
                        c[(2, 2)],
                    ]
                    .map(|v| v.to_string()),
                );
                record.push(STATUS_OK.to_string());
            }
            Err((status, message)) => {
                record.extend(["", "", ""].map(String::from));
                record.push(t.n_obs.to_string());
                record.extend(std::iter::repeat_n(String::new(), 6));
                record.push(status.clone());
                let lines: Vec<String> = t.lines.iter().map(u64::to_string).collect();
                writeln!(
                    err,
                    "vgps: {}: id `{}` (line {}): not triangulated: {message}",
                    settings.rays.display(),
                    t.id,
                    lines.join(", ")
                )?;
            }
        }
        writer.write_record(&record).map_err(csv_err)?;
    }
    writer.flush()?;
    Ok(())
}

/// Triangulates every id of `rays` (in first-seen order). The work is done in one local ENU
/// frame at the first observer: each ray direction is rotated from the ENU frame at its
/// observer into it, and each covariance rotated back into the ENU frame at the estimate.
/// Rows without `sigma_pos_m` / `sigma_ang_deg` take the defaults of `settings`.
///
/// # Errors
/// [`CliError::Input`] naming the file, line and field when the geodetic conversion rejects
/// an observer position.
pub fn triangulate(
    rays: &[RayRecord],
    path: &Path,
    settings: &TriangulateSettings,
) -> Result<Vec<TriangulatedLandmark>, CliError> {
    let Some(first) = rays.first() else {
        return Ok(Vec::new());
    };
    let geodetic = |r: &RayRecord| {
        Geodetic::try_new(r.lat_deg, r.lon_deg, r.alt_m).map_err(|e| {
            InputError::field(path, r.line, vgps_io::geodetic_column(&e), e.to_string())
        })
    };
    let local = LocalFrame::new(geodetic(first)?);
    let mut order: Vec<String> = Vec::new();
    let mut groups: HashMap<&str, Vec<&RayRecord>> = HashMap::new();
    for r in rays {
        let group = groups.entry(r.id.as_str()).or_default();
        if group.is_empty() {
            order.push(r.id.clone());
        }
        group.push(r);
    }
    let mut out = Vec::with_capacity(order.len());
    for id in order {
        let group = groups.get(id.as_str()).map_or(&[][..], Vec::as_slice);
        let mut observations = Vec::with_capacity(group.len());
        for r in group {
            let observer = geodetic(r)?;
            let direction = local.enu_here_from_enu_at(&observer) * r.direction_in_enu;
            let ray = Ray::try_new(local.to_enu(&observer), direction).ok_or_else(|| {
                InputError::field(path, r.line, "de", "the direction is not a valid ray")
            })?;
            observations.push(RayObservation {
                ray,
                sigma_pos_m: r.sigma_pos_m.unwrap_or(settings.sigma_pos_m),
                sigma_ang_rad: r
                    .sigma_ang_deg
                    .map_or(settings.sigma_ang_rad, f64::to_radians),
            });
        }
        let result = match triangulate_rays(&observations) {
            Err(e) => Err((status_of(&e).to_string(), e.to_string())),
            Ok(t) => match local.try_to_geodetic(&t.point) {
                Err(e) => Err(("no_geodetic_position".to_string(), e.to_string())),
                Ok(g) => {
                    let r = local.enu_here_from_enu_at(&g).inverse();
                    let m: Matrix3<f64> = *r.matrix();
                    let c = m * t.covariance * m.transpose();
                    Ok((g, (c + c.transpose()) * 0.5))
                }
            },
        };
        out.push(TriangulatedLandmark {
            n_obs: group.len(),
            lines: group.iter().map(|r| r.line).collect(),
            id,
            result,
        });
    }
    Ok(out)
}

/// The stable status token of a triangulation failure (the `status` column).
pub fn status_of(error: &TriangulationError) -> &'static str {
    match error {
        TriangulationError::TooFewRays(_) => "too_few_rays",
        TriangulationError::NoParallax { .. } | TriangulationError::IllConditioned { .. } => {
            "no_parallax"
        }
        TriangulationError::WeakParallax { .. } => "weak_parallax",
        TriangulationError::BehindRay { .. } => "behind_ray",
        TriangulationError::InvalidRay { .. } | TriangulationError::InvalidNoise { .. } => {
            "invalid_ray"
        }
        TriangulationError::NonFinite => "non_finite",
    }
}
