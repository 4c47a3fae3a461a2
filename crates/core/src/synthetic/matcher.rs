//! A city-like world for the landmark matcher: a street grid, streetlights along the kerbs at
//! regular spacing (the repetitive hard case), roof corners of the buildings, a rig on a
//! street about 2 m up, and frames of detections with noise, missed landmarks and false
//! detections.
//!
//! # Example
//! ```
//! use vgps_core::synthetic::matcher::{CityConfig, CityWorld, FrameConfig};
//! let mut rng = vgps_geometry::synthetic::rng(1);
//! let world = CityWorld::generate(&mut rng, &CityConfig::default());
//! let pose = world.random_rig_pose(&mut rng);
//! let frame = world.frame(&mut rng, &pose, &FrameConfig::default());
//! assert_eq!(frame.detections.len(), frame.truth.len());
//! ```

use crate::matcher::scratch::shuffle;
use crate::matcher::{DbLandmark, LandmarkDb, MatchError, SearchArea};
use nalgebra::{Rotation3, Translation3, Vector3};
use rand::{Rng, RngExt};
use vgps_geometry::geometry::{Pose, bearing_in_rig};
use vgps_geometry::synthetic::{normal, perturb_bearing, random_unit_vector};

/// Horizontal radius of the prior of [`CityWorld::prior_trial`], metres: the prior's centre
/// is up to this far from the truth, and the search area this wide around it.
pub const TRIAL_PRIOR_RADIUS_M: f64 = 30.0;

/// Vertical half-range of the search area of [`CityWorld::prior_trial`], metres.
pub const TRIAL_PRIOR_HALF_HEIGHT_M: f64 = 1.0;

/// Class code of streetlights.
pub const CLASS_STREETLIGHT: u32 = 0;
/// Class code of building roof corners.
pub const CLASS_CORNER: u32 = 1;

/// Height of the rig above the street, metres.
pub const RIG_HEIGHT_M: f64 = 2.0;

/// A rig pose at `position` with a random heading and pitch and roll within ±3° (drawn in
/// that order: roll, pitch, heading).
pub fn rig_pose_at<R: Rng + ?Sized>(rng: &mut R, position: Vector3<f64>) -> Pose {
    let tilt = 3.0_f64.to_radians();
    let rotation = Rotation3::from_euler_angles(
        rng.random_range(-tilt..=tilt),
        rng.random_range(-tilt..=tilt),
        rng.random_range(-std::f64::consts::PI..=std::f64::consts::PI),
    );
    Pose::from_parts(Translation3::from(position), rotation)
}

/// Layout of a synthetic city.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CityConfig {
    /// Blocks east and north.
    pub blocks: (usize, usize),
    /// Distance between street centre lines, metres.
    pub block_m: f64,
    /// Kerb-to-kerb width of a street, metres.
    pub street_m: f64,
    /// Spacing of the streetlights along a kerb, metres.
    pub lamp_spacing_m: f64,
    /// Streetlights on both kerbs (true) or one.
    pub lamps_both_sides: bool,
    /// Height of the streetlights, metres.
    pub lamp_height_m: f64,
    /// Range of building heights (roof corners), metres.
    pub building_height_m: (f64, f64),
    /// Survey noise added to every landmark position, metres per axis.
    pub survey_sigma_m: f64,
}

impl Default for CityConfig {
    /// 10 × 10 blocks of 100 m (1 km²), 16 m streets, lamps every 25 m on both kerbs,
    /// 1,940 landmarks.
    fn default() -> Self {
        Self {
            blocks: (10, 10),
            block_m: 100.0,
            street_m: 16.0,
            lamp_spacing_m: 25.0,
            lamps_both_sides: true,
            lamp_height_m: 6.0,
            building_height_m: (8.0, 30.0),
            survey_sigma_m: 0.0,
        }
    }
}

impl CityConfig {
    /// About 1,060 landmarks over 1 km² (lamps every 30 m on one kerb).
    pub fn sparse() -> Self {
        Self {
            lamp_spacing_m: 30.0,
            lamps_both_sides: false,
            ..Self::default()
        }
    }
}

/// Options of a synthetic frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameConfig {
    /// Bearing noise per tangent axis, radians.
    pub sigma_rad: f64,
    /// Landmarks beyond this range are not detected, metres.
    pub visibility_m: f64,
    /// Detections of true landmarks (fewer when fewer are visible; the rest are missed).
    pub true_detections: usize,
    /// False detections (other lights): random directions.
    pub false_detections: usize,
    /// Give detections their landmark's class (false ones a random class).
    pub labelled: bool,
}

impl Default for FrameConfig {
    /// 14 true + 6 false detections (30 % false), 0.05° noise, 80 m, unlabelled.
    fn default() -> Self {
        Self {
            sigma_rad: 0.05_f64.to_radians(),
            visibility_m: 80.0,
            true_detections: 14,
            false_detections: 6,
            labelled: false,
        }
    }
}

/// A matcher database of points: ids `L<k>` (`k` the index in `points`), unlabelled,
/// survey σ 0.
///
/// # Errors
/// Those of [`LandmarkDb::new`] (a non-finite point).
pub fn landmark_db(points: &[Vector3<f64>]) -> Result<LandmarkDb, MatchError> {
    LandmarkDb::new(
        points
            .iter()
            .enumerate()
            .map(|(k, p)| DbLandmark {
                id: format!("L{k}"),
                position_in_world: *p,
                class: None,
                sigma_m: 0.0,
            })
            .collect(),
    )
}

/// A synthetic city.
#[derive(Clone, Debug)]
pub struct CityWorld {
    /// The layout.
    pub config: CityConfig,
    /// Surveyed landmark positions (with the survey noise), ENU metres.
    pub landmarks: Vec<Vector3<f64>>,
    /// True landmark positions (what the camera sees).
    pub true_landmarks: Vec<Vector3<f64>>,
    /// Class code per landmark.
    pub classes: Vec<u32>,
    /// Building footprints `(min_x, min_y, max_x, max_y)`, one per block.
    pub buildings: Vec<[f64; 4]>,
}

/// One trial of the matcher's Monte-Carlo experiments: the true pose, its frame and the
/// search area handed to the matcher.
#[derive(Clone, Debug)]
pub struct Trial {
    /// The true rig pose (`world_from_rig`).
    pub pose: Pose,
    /// The detections and their truth.
    pub frame: SyntheticFrame,
    /// The search area: a prior around a point near the truth, or the whole city.
    pub area: SearchArea,
}

/// One synthetic frame.
#[derive(Clone, Debug)]
pub struct SyntheticFrame {
    /// Unit bearings in the rig frame.
    pub detections: Vec<Vector3<f64>>,
    /// Class label per detection (`None` when unlabelled).
    pub classes: Vec<Option<u32>>,
    /// Per detection: the landmark it sees (`None`: a false detection).
    pub truth: Vec<Option<usize>>,
}

impl CityWorld {
    /// The matcher's database of the surveyed landmarks ([`landmark_db`]).
    ///
    /// # Errors
    /// Those of [`LandmarkDb::new`] (not for a generated city: its positions are finite).
    pub fn landmark_db(&self) -> Result<LandmarkDb, MatchError> {
        landmark_db(&self.landmarks)
    }

    /// Generates the city. Streets run along `x = i·block_m` and `y = j·block_m`; each block's
    /// building fills the block less the half-streets and a 2 m pavement.
    pub fn generate<R: Rng + ?Sized>(rng: &mut R, config: &CityConfig) -> Self {
        let (nx, ny) = config.blocks;
        let b = config.block_m;
        let half = config.street_m / 2.0;
        let mut true_landmarks = Vec::new();
        let mut classes = Vec::new();
        let mut buildings = Vec::new();
        let kerbs: &[f64] = if config.lamps_both_sides {
            &[-1.0, 1.0]
        } else {
            &[1.0]
        };
        // Lamps along the east-west streets (y = j·b) and the north-south ones (x = i·b).
        for along_x in [true, false] {
            let (lines, segments) = if along_x { (ny + 1, nx) } else { (nx + 1, ny) };
            for line in 0..lines {
                for seg in 0..segments {
                    // North-south kerbs start half a spacing later: no lamp is on two
                    // streets' kerbs at a corner.
                    let stagger = if along_x {
                        0.0
                    } else {
                        config.lamp_spacing_m / 2.0
                    };
                    let start = seg as f64 * b + half + stagger;
                    let end = (seg + 1) as f64 * b - half;
                    for &side in kerbs {
                        let mut s = start;
                        while s <= end + 1e-9 {
                            let across = line as f64 * b + side * half;
                            let p = if along_x {
                                Vector3::new(s, across, config.lamp_height_m)
                            } else {
                                Vector3::new(across, s, config.lamp_height_m)
                            };
                            true_landmarks.push(p);
                            classes.push(CLASS_STREETLIGHT);
                            s += config.lamp_spacing_m;
                        }
                    }
                }
            }
        }
        let inset = half + 2.0;
        for i in 0..nx {
            for j in 0..ny {
                let fp = [
                    i as f64 * b + inset,
                    j as f64 * b + inset,
                    (i + 1) as f64 * b - inset,
                    (j + 1) as f64 * b - inset,
                ];
                let h = rng.random_range(config.building_height_m.0..=config.building_height_m.1);
                for (x, y) in [
                    (fp[0], fp[1]),
                    (fp[2], fp[1]),
                    (fp[0], fp[3]),
                    (fp[2], fp[3]),
                ] {
                    true_landmarks.push(Vector3::new(x, y, h));
                    classes.push(CLASS_CORNER);
                }
                buildings.push(fp);
            }
        }
        let landmarks = true_landmarks
            .iter()
            .map(|p| {
                p + Vector3::new(normal(rng), normal(rng), normal(rng)) * config.survey_sigma_m
            })
            .collect();
        Self {
            config: *config,
            landmarks,
            true_landmarks,
            classes,
            buildings,
        }
    }

    /// Where [`Self::random_rig_pose`] puts the rig: the streets (up to 2 m from the kerbs)
    /// at heights within 1 m of [`RIG_HEIGHT_M`]. This is the region of a cold start: the
    /// landmarks' own extent misses the outer half of the streets along the city's edge when
    /// the lamps stand on one kerb only.
    pub fn rig_region(&self) -> Option<SearchArea> {
        let (nx, ny) = self.config.blocks;
        let b = self.config.block_m;
        let lateral = self.config.street_m / 2.0 - 2.0;
        SearchArea::try_new(
            Vector3::new(-lateral, -lateral, RIG_HEIGHT_M - 1.0),
            Vector3::new(
                nx as f64 * b + lateral,
                ny as f64 * b + lateral,
                RIG_HEIGHT_M + 1.0,
            ),
        )
    }

    /// A rig on a random street (see [`Self::rig_region`]), [`RIG_HEIGHT_M`] up, random
    /// heading, pitch and roll within ±3°.
    pub fn random_rig_pose<R: Rng + ?Sized>(&self, rng: &mut R) -> Pose {
        let (nx, ny) = self.config.blocks;
        let b = self.config.block_m;
        let lateral = rng
            .random_range(-(self.config.street_m / 2.0 - 2.0)..=(self.config.street_m / 2.0 - 2.0));
        let p = if rng.random::<bool>() {
            let line = rng.random_range(0..=ny) as f64 * b;
            Vector3::new(
                rng.random_range(0.0..=nx as f64 * b),
                line + lateral,
                RIG_HEIGHT_M,
            )
        } else {
            let line = rng.random_range(0..=nx) as f64 * b;
            Vector3::new(
                line + lateral,
                rng.random_range(0.0..=ny as f64 * b),
                RIG_HEIGHT_M,
            )
        };
        rig_pose_at(rng, p)
    }

    /// True when the straight line from `from` to the landmark is not blocked by a building
    /// (2-D test against the footprints; a roof corner does not block itself).
    pub fn line_of_sight(&self, from: &Vector3<f64>, to: &Vector3<f64>) -> bool {
        const SHRINK: f64 = 0.05;
        self.buildings.iter().all(|fp| {
            !segment_hits_box(
                (from.x, from.y),
                (to.x, to.y),
                [
                    fp[0] + SHRINK,
                    fp[1] + SHRINK,
                    fp[2] - SHRINK,
                    fp[3] - SHRINK,
                ],
            )
        })
    }

    /// The indices of the landmarks visible from a pose (in range, in line of sight).
    pub fn visible(&self, pose: &Pose, range_m: f64) -> Vec<usize> {
        let c = pose.translation.vector;
        (0..self.true_landmarks.len())
            .filter(|&k| {
                let p = &self.true_landmarks[k];
                (p - c).norm() <= range_m && self.line_of_sight(&c, p)
            })
            .collect()
    }

    /// The next trial with a prior: a random rig pose, its frame, and a search area of
    /// ±[`TRIAL_PRIOR_RADIUS_M`] horizontally and ±[`TRIAL_PRIOR_HALF_HEIGHT_M`] vertically
    /// around a point uniformly distributed in the disc of that radius around the truth.
    /// The Monte-Carlo example (`examples/matcher_monte_carlo.rs`) and the tests draw their
    /// frames from this, so a frame number and seed name the same frame in both.
    pub fn prior_trial<R: Rng + ?Sized>(&self, rng: &mut R, config: &FrameConfig) -> Trial {
        let pose = self.random_rig_pose(rng);
        let frame = self.frame(rng, &pose, config);
        let direction = random_unit_vector(rng).xy();
        let direction = direction
            .try_normalize(f64::EPSILON)
            .unwrap_or_else(nalgebra::Vector2::x);
        let offset = direction * (TRIAL_PRIOR_RADIUS_M * rng.random_range(0.0..1.0f64).sqrt());
        let centre = pose.translation.vector + Vector3::new(offset.x, offset.y, 0.0);
        let area = SearchArea::around(&centre, TRIAL_PRIOR_RADIUS_M, TRIAL_PRIOR_HALF_HEIGHT_M)
            .unwrap_or_else(|| unreachable_area(&centre));
        Trial { pose, frame, area }
    }

    /// The next cold-start trial: a random rig pose, its frame, and the whole city (the
    /// landmarks' horizontal extent, rig heights within 1 m of [`RIG_HEIGHT_M`]) as the
    /// search area.
    pub fn cold_trial<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        config: &FrameConfig,
        db: &LandmarkDb,
    ) -> Trial {
        let pose = self.random_rig_pose(rng);
        let frame = self.frame(rng, &pose, config);
        let area = self
            .rig_region()
            .or_else(|| SearchArea::over_landmarks(db, 0.0, RIG_HEIGHT_M - 1.0, RIG_HEIGHT_M + 1.0))
            .unwrap_or_else(|| unreachable_area(&pose.translation.vector));
        Trial { pose, frame, area }
    }

    /// A frame of detections from a pose: up to `true_detections` visible landmarks (chosen
    /// at random: the others are missed), plus `false_detections` random directions, all
    /// with bearing noise, in random order.
    pub fn frame<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        pose: &Pose,
        config: &FrameConfig,
    ) -> SyntheticFrame {
        let mut visible = self.visible(pose, config.visibility_m);
        shuffle(rng, &mut visible);
        visible.truncate(config.true_detections);
        let mut items: Vec<(Vector3<f64>, Option<u32>, Option<usize>)> = Vec::new();
        for &k in &visible {
            if let Some(b) = bearing_in_rig(pose, &self.true_landmarks[k]) {
                let class = config.labelled.then_some(self.classes[k]);
                items.push((perturb_bearing(rng, &b, config.sigma_rad), class, Some(k)));
            }
        }
        for _ in 0..config.false_detections {
            let class = config.labelled.then(|| {
                if rng.random::<bool>() {
                    CLASS_STREETLIGHT
                } else {
                    CLASS_CORNER
                }
            });
            items.push((random_unit_vector(rng), class, None));
        }
        shuffle(rng, &mut items);
        SyntheticFrame {
            detections: items.iter().map(|i| i.0).collect(),
            classes: items.iter().map(|i| i.1).collect(),
            truth: items.iter().map(|i| i.2).collect(),
        }
    }
}

/// A one-point area at `centre` (only for a centre that is not finite, which a generated
/// city never gives).
fn unreachable_area(centre: &Vector3<f64>) -> SearchArea {
    SearchArea {
        min_in_world: *centre,
        max_in_world: *centre,
        horizontal_radius_m: None,
    }
}

/// Whether the 2-D segment p→q meets the open box `[min_x, min_y, max_x, max_y]` (slabs).
fn segment_hits_box(p: (f64, f64), q: (f64, f64), bx: [f64; 4]) -> bool {
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (o, d, lo, hi) in [
        (p.0, q.0 - p.0, bx[0], bx[2]),
        (p.1, q.1 - p.1, bx[1], bx[3]),
    ] {
        if d.abs() < 1e-12 {
            if o <= lo || o >= hi {
                return false;
            }
        } else {
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            let (a, b) = if a < b { (a, b) } else { (b, a) };
            t0 = t0.max(a);
            t1 = t1.min(b);
            if t0 >= t1 {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn city_has_the_documented_sizes_and_frames_see_real_landmarks() {
        let mut r = vgps_geometry::synthetic::rng(5);
        let world = CityWorld::generate(&mut r, &CityConfig::default());
        assert!(
            (1900..2100).contains(&world.landmarks.len()),
            "{}",
            world.landmarks.len()
        );
        let sparse = CityWorld::generate(&mut r, &CityConfig::sparse());
        assert!(
            (950..1150).contains(&sparse.landmarks.len()),
            "{}",
            sparse.landmarks.len()
        );
        for (k, p) in world.true_landmarks.iter().enumerate() {
            for q in &world.true_landmarks[k + 1..] {
                assert!((p - q).norm() > 1.0, "duplicate landmark at {p:?}");
            }
        }
        let mut enough = 0;
        for _ in 0..200 {
            let pose = world.random_rig_pose(&mut r);
            let frame = world.frame(
                &mut r,
                &pose,
                &FrameConfig {
                    sigma_rad: 0.0,
                    ..FrameConfig::default()
                },
            );
            for (b, t) in frame.detections.iter().zip(&frame.truth) {
                if let Some(k) = t {
                    let expected = bearing_in_rig(&pose, &world.true_landmarks[*k]).unwrap();
                    assert!((b - expected).norm() < 1e-12);
                    assert!((world.true_landmarks[*k] - pose.translation.vector).norm() <= 80.0);
                }
            }
            if frame.truth.iter().flatten().count() >= 10 {
                enough += 1;
            }
        }
        // Most street positions see at least 10 landmarks within 80 m.
        assert!(enough >= 150, "{enough}");
    }

    #[test]
    fn buildings_block_the_view() {
        assert!(segment_hits_box(
            (0.0, 5.0),
            (10.0, 5.0),
            [2.0, 2.0, 8.0, 8.0]
        ));
        assert!(!segment_hits_box(
            (0.0, 1.0),
            (10.0, 1.0),
            [2.0, 2.0, 8.0, 8.0]
        ));
        assert!(!segment_hits_box(
            (0.0, 0.0),
            (1.9, 5.0),
            [2.0, 2.0, 8.0, 8.0]
        ));
    }
}
