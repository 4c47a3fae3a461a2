//! The landmark database: surveyed landmarks in a local world frame with an R*-tree index.

use super::MatchError;
use nalgebra::Vector3;
use rstar::RTree;
use rstar::primitives::GeomWithData;

/// One surveyed landmark of a [`LandmarkDb`].
///
/// # Units
/// Metres in the local world frame (usually ENU at an origin).
#[derive(Clone, Debug, PartialEq)]
pub struct DbLandmark {
    /// Identifier (as in the landmarks file).
    pub id: String,
    /// Position in the world frame, metres.
    pub position_in_world: Vector3<f64>,
    /// Optional class code (e.g. 0 = streetlight, 1 = building corner); a detection with a
    /// class only matches landmarks of the same class or without one.
    pub class: Option<u32>,
    /// Survey standard deviation per axis, metres (0 = exact).
    pub sigma_m: f64,
}

type Entry = GeomWithData<[f64; 3], u32>;

/// Landmarks with a spatial index (an R*-tree, `rstar`): `Send + Sync`, immutable after
/// construction, so one database can be shared between threads in an `Arc`.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_core::matcher::{DbLandmark, LandmarkDb};
/// let db = LandmarkDb::new(vec![
///     DbLandmark { id: "a".into(), position_in_world: Vector3::new(10.0, 0.0, 6.0), class: None, sigma_m: 0.0 },
///     DbLandmark { id: "b".into(), position_in_world: Vector3::new(200.0, 0.0, 6.0), class: None, sigma_m: 0.0 },
/// ]).unwrap();
/// let mut near = Vec::new();
/// db.within(&Vector3::zeros(), 80.0, &mut near);
/// assert_eq!(near, vec![0]);
/// ```
#[derive(Debug)]
pub struct LandmarkDb {
    landmarks: Vec<DbLandmark>,
    tree: RTree<Entry>,
    bounds: Option<(Vector3<f64>, Vector3<f64>)>,
}

impl LandmarkDb {
    /// Builds the database (bulk-loaded R*-tree).
    ///
    /// # Errors
    /// [`MatchError::InvalidLandmark`] for a non-finite position or a negative or non-finite
    /// survey σ; [`MatchError::TooManyLandmarks`] above `u32::MAX` landmarks.
    pub fn new(landmarks: Vec<DbLandmark>) -> Result<Self, MatchError> {
        if u32::try_from(landmarks.len()).is_err() {
            return Err(MatchError::TooManyLandmarks(landmarks.len()));
        }
        let mut bounds: Option<(Vector3<f64>, Vector3<f64>)> = None;
        let mut entries = Vec::with_capacity(landmarks.len());
        for (k, l) in landmarks.iter().enumerate() {
            let p = l.position_in_world;
            if !(vgps_geometry::geometry::is_finite(&p)
                && l.sigma_m.is_finite()
                && l.sigma_m >= 0.0)
            {
                return Err(MatchError::InvalidLandmark(k));
            }
            bounds = Some(match bounds {
                None => (p, p),
                Some((lo, hi)) => (lo.inf(&p), hi.sup(&p)),
            });
            entries.push(Entry::new([p.x, p.y, p.z], k as u32));
        }
        Ok(Self {
            landmarks,
            tree: RTree::bulk_load(entries),
            bounds,
        })
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// True when there are no landmarks.
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// All landmarks, in construction order (indices of [`Self::within`] and of match
    /// assignments refer to this order).
    pub fn landmarks(&self) -> &[DbLandmark] {
        &self.landmarks
    }

    /// The landmark at `index`, if any.
    pub fn get(&self, index: usize) -> Option<&DbLandmark> {
        self.landmarks.get(index)
    }

    /// The axis-aligned bounding box `(min, max)` of the landmarks, `None` when empty.
    pub fn bounds(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        self.bounds
    }

    /// Replaces the contents of `out` by the indices of the landmarks within `radius_m`
    /// (3-D distance) of `center`, in increasing index order.
    pub fn within(&self, center: &Vector3<f64>, radius_m: f64, out: &mut Vec<usize>) {
        out.clear();
        if !(radius_m.is_finite() && radius_m >= 0.0 && vgps_geometry::geometry::is_finite(center))
        {
            return;
        }
        out.extend(
            self.tree
                .locate_within_distance([center.x, center.y, center.z], radius_m * radius_m)
                .map(|e| e.data as usize),
        );
        out.sort_unstable();
    }

    /// Replaces the contents of `out` by the indices of `candidates` whose landmarks lie
    /// within `radius_m` of `center`, in the order of `candidates`, by the same test as
    /// [`Self::within`], bit for bit (the R*-tree's squared distance, summed in its order,
    /// against `radius_m²`). With `candidates` in increasing order and holding every index
    /// that [`Self::within`] returns for `center` and `radius_m` (e.g. the result of a
    /// query with a larger radius around a nearby centre), `out` is exactly that result,
    /// without an R*-tree query. Indices beyond the database are skipped.
    pub fn within_among(
        &self,
        candidates: &[usize],
        center: &Vector3<f64>,
        radius_m: f64,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        if !(radius_m.is_finite() && radius_m >= 0.0 && vgps_geometry::geometry::is_finite(center))
        {
            return;
        }
        let max_distance_2 = radius_m * radius_m;
        out.extend(candidates.iter().copied().filter(|&k| {
            self.landmarks.get(k).is_some_and(|l| {
                let p = &l.position_in_world;
                let (dx, dy, dz) = (p.x - center.x, p.y - center.y, p.z - center.z);
                // rstar's `length_2`: a fold from zero of `cur * cur + acc`.
                dz * dz + (dy * dy + (dx * dx + 0.0)) <= max_distance_2
            })
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    /// `within_among` over a superset gives exactly `within`, also for landmarks on the
    /// sphere's boundary (radius equal to a landmark's distance, to the last bit).
    #[test]
    fn within_among_a_superset_is_within() {
        let mut rng = vgps_geometry::synthetic::rng(11);
        let landmarks: Vec<DbLandmark> = (0..2000)
            .map(|k| DbLandmark {
                id: k.to_string(),
                position_in_world: Vector3::new(
                    rng.random_range(-300.0..300.0),
                    rng.random_range(-300.0..300.0),
                    rng.random_range(0.0..20.0),
                ),
                class: None,
                sigma_m: 0.0,
            })
            .collect();
        let db = LandmarkDb::new(landmarks).unwrap();
        let (mut all, mut near, mut among) = (Vec::new(), Vec::new(), Vec::new());
        let mut boundary_cases = 0;
        for trial in 0..200 {
            let centre = Vector3::new(
                rng.random_range(-100.0..100.0),
                rng.random_range(-100.0..100.0),
                rng.random_range(0.0..10.0),
            );
            // Every tenth trial puts a landmark exactly on the boundary.
            let radius = if trial % 10 == 0 {
                boundary_cases += 1;
                (db.landmarks()[trial].position_in_world - centre).norm()
            } else {
                rng.random_range(0.0..120.0)
            };
            db.within(&centre, radius + 50.0, &mut all);
            db.within(&centre, radius, &mut near);
            let shifted = centre + Vector3::new(20.0, -20.0, 5.0);
            db.within_among(&all, &centre, radius, &mut among);
            assert_eq!(among, near, "trial {trial}");
            // A superset from another centre that still covers the sphere.
            db.within(&shifted, radius + 40.0, &mut all);
            db.within_among(&all, &centre, radius, &mut among);
            assert_eq!(among, near, "trial {trial} (shifted)");
        }
        assert_eq!(boundary_cases, 20);
        db.within_among(&[0, 1], &Vector3::new(f64::NAN, 0.0, 0.0), 10.0, &mut among);
        assert!(among.is_empty());
    }
}
