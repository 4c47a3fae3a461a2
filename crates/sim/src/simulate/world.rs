//! The simulated city: a street grid, buildings as boxes, streetlights and building corners,
//! and what a rig sees of them.

use nalgebra::{Point3, Vector2, Vector3};
use rand::{Rng, RngExt};
use vgps_camera::calibration::{CameraModel, Pixel, Rig, in_image_rectangle};
use vgps_geometry::geometry::Pose;

/// Distance from a street's centre line to the building line, metres.
pub const SETBACK_M: f64 = 10.0;
/// Distance from a street's centre line to the kerb where the lamp posts stand, metres.
pub const KERB_M: f64 = 7.5;
/// How far a lamp head reaches over the road from its post, metres.
pub const LAMP_ARM_M: f64 = 1.2;
/// Gap kept between a corner landmark and its building's box, metres (so that the box does
/// not hide its own corner).
pub const CORNER_CLEARANCE_M: f64 = 0.05;
/// Probability that a lot holds no building (a parking lot).
const EMPTY_LOT_PROBABILITY: f64 = 0.1;
/// Probability that a street-facing building corner also has an awning corner (3–4.5 m).
const AWNING_PROBABILITY: f64 = 0.3;
/// Segment parameter margin of the occlusion test.
const OCCLUSION_EPS: f64 = 1e-9;

/// A landmark's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LandmarkClass {
    /// A streetlight lamp (5–9 m above the road).
    Streetlight,
    /// A building corner (3–30 m).
    Corner,
}

impl LandmarkClass {
    /// The class label in files (`streetlight`, `corner`).
    pub fn label(self) -> &'static str {
        match self {
            LandmarkClass::Streetlight => "streetlight",
            LandmarkClass::Corner => "corner",
        }
    }
}

/// A static landmark of the world.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldLandmark {
    /// Identifier (`L…` lamps, `C…` corners).
    pub id: String,
    /// True position, ENU at the scenario origin, metres.
    pub position_in_enu: Vector3<f64>,
    /// Kind.
    pub class: LandmarkClass,
    /// Whether it is in the surveyed landmarks file.
    pub surveyed: bool,
    /// The surveyed position (true position plus survey noise), ENU metres.
    pub surveyed_in_enu: Vector3<f64>,
}

/// An axis-aligned box (a building), ENU metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Building {
    /// Minimum corner.
    pub min: Vector3<f64>,
    /// Maximum corner.
    pub max: Vector3<f64>,
}

impl Building {
    /// Whether the open segment `a → b` passes through the box (slab test).
    pub fn blocks(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        let d = b - a;
        let (mut t0, mut t1) = (OCCLUSION_EPS, 1.0 - OCCLUSION_EPS);
        for k in 0..3 {
            if d[k].abs() < 1e-15 {
                if a[k] < self.min[k] || a[k] > self.max[k] {
                    return false;
                }
                continue;
            }
            let (mut lo, mut hi) = ((self.min[k] - a[k]) / d[k], (self.max[k] - a[k]) / d[k]);
            if lo > hi {
                std::mem::swap(&mut lo, &mut hi);
            }
            t0 = t0.max(lo);
            t1 = t1.min(hi);
            if t0 >= t1 {
                return false;
            }
        }
        true
    }

    /// Horizontal distance from a point to the box, metres.
    fn distance_2d(&self, p: &Vector3<f64>) -> f64 {
        let dx = (self.min.x - p.x).max(p.x - self.max.x).max(0.0);
        let dy = (self.min.y - p.y).max(p.y - self.max.y).max(0.0);
        dx.hypot(dy)
    }
}

/// The world: buildings and landmarks.
#[derive(Clone, Debug, Default)]
pub struct World {
    /// Buildings (occluders).
    pub buildings: Vec<Building>,
    /// Every static landmark, surveyed or not.
    pub landmarks: Vec<WorldLandmark>,
}

/// The grid and landmark parameters of [`World::generate`].
#[derive(Clone, Copy, Debug)]
pub struct CityParams {
    /// Street spacing, metres.
    pub block_m: f64,
    /// Lamp spacing along each kerb, metres.
    pub lamp_spacing_m: f64,
    /// Lamp heights, metres.
    pub lamp_height_m: (f64, f64),
    /// Building heights, metres.
    pub building_height_m: (f64, f64),
}

impl World {
    /// A city covering the grid cells `[i0, i1) × [j0, j1)` (cell (i, j) spans
    /// `[i·block, (i+1)·block] × [j·block, (j+1)·block]`).
    pub fn generate<R: Rng + ?Sized>(
        rng: &mut R,
        params: &CityParams,
        cells: (i64, i64, i64, i64),
    ) -> World {
        let (i0, i1, j0, j1) = cells;
        let s = params.block_m;
        let mut world = World::default();
        let mut lamps = 0_usize;
        let mut corners = 0_usize;
        let mut lamp = |world: &mut World, p: Vector3<f64>| {
            lamps += 1;
            world.landmarks.push(WorldLandmark {
                id: format!("L{lamps:04}"),
                position_in_enu: p,
                class: LandmarkClass::Streetlight,
                surveyed: true,
                surveyed_in_enu: p,
            });
        };
        // Streetlights along both kerbs of every street segment of the covered area.
        let usable = s - 2.0 * (SETBACK_M + 2.0);
        let n_lamps = (usable / params.lamp_spacing_m).floor().max(1.0) as usize;
        for i in i0..=i1 {
            for j in j0..=j1 {
                // Street along x from node (i, j) to (i+1, j), and along y to (i, j+1).
                for (dx, dy) in [(1.0, 0.0), (0.0, 1.0)] {
                    if (dx > 0.0 && i == i1) || (dy > 0.0 && j == j1) {
                        continue;
                    }
                    let node = Vector2::new(i as f64 * s, j as f64 * s);
                    let dir = Vector2::new(dx, dy);
                    let left = Vector2::new(-dy, dx);
                    for side in [-1.0, 1.0] {
                        let stagger = if side > 0.0 { 0.5 } else { 0.0 };
                        for k in 0..n_lamps {
                            let jitter = (rng.random::<f64>() - 0.5) * 4.0;
                            let along = SETBACK_M
                                + 2.0
                                + (k as f64 + 0.25 + stagger * 0.5) * usable / n_lamps as f64
                                + jitter;
                            let h =
                                rng.random_range(params.lamp_height_m.0..params.lamp_height_m.1);
                            let xy = node + dir * along + left * (side * (KERB_M - LAMP_ARM_M));
                            lamp(&mut world, Vector3::new(xy.x, xy.y, h));
                        }
                    }
                }
            }
        }
        // Buildings in every block, 2–3 lots by 2, with their corners.
        for i in i0..i1 {
            for j in j0..j1 {
                let (x0, y0) = (i as f64 * s + SETBACK_M, j as f64 * s + SETBACK_M);
                let width = s - 2.0 * SETBACK_M;
                let nx = rng.random_range(2..=3_usize);
                for a in 0..nx {
                    for b in 0..2 {
                        if rng.random::<f64>() < EMPTY_LOT_PROBABILITY {
                            continue;
                        }
                        let lx = width / nx as f64;
                        let ly = width / 2.0;
                        let gap = |r: &mut R| r.random_range(0.0..1.5);
                        let min = Vector3::new(
                            x0 + a as f64 * lx + gap(rng),
                            y0 + b as f64 * ly + gap(rng),
                            0.0,
                        );
                        let h = rng
                            .random_range(params.building_height_m.0..params.building_height_m.1);
                        let max = Vector3::new(
                            x0 + (a + 1) as f64 * lx - gap(rng),
                            y0 + (b + 1) as f64 * ly - gap(rng),
                            h,
                        );
                        world.buildings.push(Building { min, max });
                        for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let sx = if cx == 0 { -1.0 } else { 1.0 };
                            let sy = if cy == 0 { -1.0 } else { 1.0 };
                            let x = if cx == 0 { min.x } else { max.x } + sx * CORNER_CLEARANCE_M;
                            let y = if cy == 0 { min.y } else { max.y } + sy * CORNER_CLEARANCE_M;
                            let mut heights = vec![h + CORNER_CLEARANCE_M];
                            // A street-facing corner (on the block's outer edge) may also have an awning.
                            let outer = (cx == 0 && a == 0)
                                || (cx == 1 && a == nx - 1)
                                || (cy == 0 && b == 0)
                                || (cy == 1 && b == 1);
                            if outer && rng.random::<f64>() < AWNING_PROBABILITY {
                                heights.push(rng.random_range(3.0..4.5));
                            }
                            for z in heights {
                                corners += 1;
                                let p = Vector3::new(x, y, z);
                                world.landmarks.push(WorldLandmark {
                                    id: format!("C{corners:04}"),
                                    position_in_enu: p,
                                    class: LandmarkClass::Corner,
                                    surveyed: true,
                                    surveyed_in_enu: p,
                                });
                            }
                        }
                    }
                }
            }
        }
        world
    }

    /// The buildings that may hide something within `range_m` of `position`.
    pub fn nearby_buildings(&self, position: &Vector3<f64>, range_m: f64) -> Vec<Building> {
        self.buildings
            .iter()
            .filter(|b| b.distance_2d(position) < range_m)
            .copied()
            .collect()
    }
}

/// Where a visible point comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// A static landmark (index into [`World::landmarks`]).
    Landmark(usize),
    /// A transient light (headlight, window): not a landmark.
    Transient,
}

/// A point seen by one camera: everything a renderer needs to draw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisiblePoint {
    /// Where it comes from.
    pub source: Source,
    /// The camera index in the rig.
    pub camera: usize,
    /// The point in the camera frame (x right, y down, z forward), metres.
    pub point_in_camera: Vector3<f64>,
    /// Distance from the camera centre, metres.
    pub range_m: f64,
    /// The noise-free pixel.
    pub pixel: Pixel,
}

/// Every camera and pixel that sees `point_in_world` from the rig at `world_from_rig`
/// (inside the image rectangle), with no occlusion test.
pub fn project(
    rig: &Rig,
    world_from_rig: &Pose,
    point_in_world: &Vector3<f64>,
    source: Source,
) -> Vec<VisiblePoint> {
    let point_in_rig = world_from_rig.inverse_transform_point(&Point3::from(*point_in_world));
    rig.project_point(&point_in_rig.coords)
        .into_iter()
        .filter_map(|rp| {
            let c = &rig.cameras()[rp.camera];
            let (w, h) = c.model.image_size();
            if !in_image_rectangle(w, h, &rp.pixel) {
                return None;
            }
            let point_in_camera = c
                .rig_from_camera
                .inverse_transform_point(&point_in_rig)
                .coords;
            Some(VisiblePoint {
                source,
                camera: rp.camera,
                point_in_camera,
                range_m: point_in_camera.norm(),
                pixel: rp.pixel,
            })
        })
        .collect()
}

/// Every landmark within `range_m` of the rig, not hidden by a building, in every camera
/// that sees it.
pub fn observe(world: &World, rig: &Rig, world_from_rig: &Pose, range_m: f64) -> Vec<VisiblePoint> {
    let origin = world_from_rig.translation.vector;
    let buildings = world.nearby_buildings(&origin, range_m);
    let mut out = Vec::new();
    for (index, l) in world.landmarks.iter().enumerate() {
        let p = l.position_in_enu;
        if (p - origin).norm() > range_m {
            continue;
        }
        if buildings.iter().any(|b| b.blocks(&origin, &p)) {
            continue;
        }
        out.extend(project(rig, world_from_rig, &p, Source::Landmark(index)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_blocks_only_segments_through_it() {
        let b = Building {
            min: Vector3::new(0.0, 0.0, 0.0),
            max: Vector3::new(10.0, 10.0, 10.0),
        };
        let a = Vector3::new(-5.0, 5.0, 2.0);
        assert!(b.blocks(&a, &Vector3::new(15.0, 5.0, 2.0)));
        assert!(!b.blocks(&a, &Vector3::new(-1.0, 5.0, 2.0)));
        assert!(!b.blocks(&a, &Vector3::new(-5.0, 20.0, 2.0)));
        // Over the roof.
        assert!(!b.blocks(&a, &Vector3::new(15.0, 5.0, 60.0)));
        assert!(b.blocks(&a, &Vector3::new(15.0, 5.0, 30.0)));
        // Its own near corner (just outside) is visible; the far one is not.
        assert!(!b.blocks(&a, &Vector3::new(-0.05, -0.05, 10.05)));
        assert!(b.blocks(&a, &Vector3::new(10.05, 10.05, 9.0)));
        // Axis-parallel segment outside the slab.
        assert!(!b.blocks(
            &Vector3::new(-1.0, -1.0, 2.0),
            &Vector3::new(-1.0, 20.0, 2.0)
        ));
    }
}
