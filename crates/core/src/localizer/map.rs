//! The surveyed landmark map a [`super::Localizer`] works in: landmarks in a local ENU frame
//! with a spatial index, shareable between threads.

use super::LocalizerError;
use crate::matcher::{DbLandmark, LandmarkDb};
use std::collections::HashMap;
use vgps_geometry::geo::{Geodetic, LocalFrame};
use vgps_io::Landmark;

/// Surveyed landmarks in a local ENU frame (the "world" of the localizer) with their ids,
/// class names and a spatial index. Immutable after construction, `Send + Sync`: share one
/// map between localizers (threads, robots) in an `Arc`.
///
/// # Example
/// ```
/// use vgps_io::Landmark;
/// use vgps_core::localizer::LandmarkMap;
/// let lamp = |id: &str, lat: f64, lon: f64| Landmark {
///     id: id.into(), lat_deg: lat, lon_deg: lon, alt_m: 20.0,
///     sigma_m: Some(0.02), class: Some("streetlight".into()), line: 2,
/// };
/// let map = LandmarkMap::from_landmarks(&[lamp("a", 37.7793, -122.4193), lamp("b", 37.7794, -122.4190)], None)?;
/// assert_eq!(map.len(), 2);
/// // The origin is the centroid of the landmarks, so both are within ~15 m of it.
/// assert!(map.db().landmarks().iter().all(|l| l.position_in_world.norm() < 20.0));
/// assert_eq!(map.class_index("streetlight"), Some(0));
/// # Ok::<(), vgps_core::localizer::LocalizerError>(())
/// ```
#[derive(Debug)]
pub struct LandmarkMap {
    frame: LocalFrame,
    db: LandmarkDb,
    classes: Vec<String>,
}

impl LandmarkMap {
    /// Builds the map from surveyed landmarks. The local frame is ENU at `origin`, or at the
    /// landmarks' centroid (height: their mean) when `None`. Landmarks without `sigma_m` are
    /// taken as exact; class names are numbered in order of first appearance.
    ///
    /// # Errors
    /// [`LocalizerError::NoLandmarks`] for an empty list; [`LocalizerError::Landmark`] for a
    /// landmark whose coordinates the geodetic conversion rejects (names its id and line).
    pub fn from_landmarks(
        landmarks: &[Landmark],
        origin: Option<Geodetic>,
    ) -> Result<Self, LocalizerError> {
        if landmarks.is_empty() {
            return Err(LocalizerError::NoLandmarks);
        }
        let mut geodetic = Vec::with_capacity(landmarks.len());
        for l in landmarks {
            let g = Geodetic::try_new(l.lat_deg, l.lon_deg, l.alt_m).map_err(|e| {
                LocalizerError::Landmark {
                    id: l.id.clone(),
                    line: l.line,
                    message: e.to_string(),
                }
            })?;
            geodetic.push(g);
        }
        let origin = match origin {
            Some(o) => o,
            None => centroid(&geodetic).ok_or(LocalizerError::NoLandmarks)?,
        };
        let frame = LocalFrame::new(origin);
        let mut classes: Vec<String> = Vec::new();
        let mut class_of: HashMap<String, u32> = HashMap::new();
        let mut db_landmarks = Vec::with_capacity(landmarks.len());
        for (l, g) in landmarks.iter().zip(&geodetic) {
            let class = l.class.as_ref().map(|name| {
                *class_of.entry(name.clone()).or_insert_with(|| {
                    classes.push(name.clone());
                    u32::try_from(classes.len() - 1).unwrap_or(u32::MAX)
                })
            });
            db_landmarks.push(DbLandmark {
                id: l.id.clone(),
                position_in_world: frame.to_enu(g),
                class,
                sigma_m: l.sigma_m.unwrap_or(0.0),
            });
        }
        let db = LandmarkDb::new(db_landmarks).map_err(|e| LocalizerError::Landmark {
            id: String::new(),
            line: 0,
            message: e.to_string(),
        })?;
        Ok(Self { frame, db, classes })
    }

    /// The local ENU frame of the map (the localizer's world frame).
    pub fn frame(&self) -> &LocalFrame {
        &self.frame
    }

    /// The landmark database (positions in the map's ENU frame, spatial index).
    pub fn db(&self) -> &LandmarkDb {
        &self.db
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.db.len()
    }

    /// True when the map has no landmarks (never, for a map built by
    /// [`Self::from_landmarks`]).
    pub fn is_empty(&self) -> bool {
        self.db.is_empty()
    }

    /// The class names, indexed by class code.
    pub fn classes(&self) -> &[String] {
        &self.classes
    }

    /// The class code of a class name, if any landmark has it.
    pub fn class_index(&self, name: &str) -> Option<u32> {
        self.classes
            .iter()
            .position(|c| c == name)
            .and_then(|k| u32::try_from(k).ok())
    }
}

/// The centroid of geodetic points (mean ECEF position projected to the surface height of
/// the mean altitude); `None` for an empty list.
fn centroid(points: &[Geodetic]) -> Option<Geodetic> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as f64;
    let ecef = points
        .iter()
        .fold(nalgebra::Vector3::zeros(), |acc, g| acc + g.to_ecef())
        / n;
    let mean_alt = points.iter().map(|g| g.alt_m).sum::<f64>() / n;
    let g = Geodetic::try_from_ecef(&ecef).ok()?;
    Geodetic::try_new(g.lat_deg, g.lon_deg, mean_alt).ok()
}
