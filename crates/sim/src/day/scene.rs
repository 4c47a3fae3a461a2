//! The daytime scene of a simulated city: the buildings as boxes whose vertices are the
//! corner landmarks, awning bands at the awning corners, parked cars and trees as clutter,
//! and the street layout (road, kerb, lane markings) on the ground plane `z = 0`.

use crate::simulate::{CORNER_CLEARANCE_M, KERB_M, LandmarkClass, SETBACK_M, World};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};

/// Height of an awning band below its corner (metres).
pub const AWNING_BAND_M: f64 = 0.35;
/// Lateral offset of a parked car's centre from the street's centre line (metres).
const CAR_LATERAL_M: f64 = KERB_M - 1.1;
/// Car size (length, width, height; metres).
const CAR_SIZE_M: (f64, f64, f64) = (4.4, 1.8, 1.45);
/// Gap range between parked cars along a kerb (metres).
const CAR_GAP_M: (f64, f64) = (4.0, 30.0);
/// Lateral offset of a tree from the street's centre line (metres).
const TREE_LATERAL_M: f64 = KERB_M + 1.0;
/// Spacing range of trees along a sidewalk (metres).
const TREE_GAP_M: (f64, f64) = (15.0, 45.0);
/// Free distance kept from an intersection's centre (metres).
const INTERSECTION_CLEAR_M: f64 = SETBACK_M + 3.0;
/// Salt of the clutter generator's seed.
const CLUTTER_SALT: u64 = 0x6461_795f_636c_7574;

/// What a box is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxKind {
    /// A building (facade with windows; its vertices are corner landmarks).
    Building,
    /// A parked car.
    Car,
    /// A tree trunk.
    Trunk,
}

/// An axis-aligned box of the day scene (ENU metres).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneBox {
    /// Minimum corner.
    pub min: Vector3<f64>,
    /// Maximum corner.
    pub max: Vector3<f64>,
    /// Diffuse reflectance of its sides (0–1).
    pub albedo: f64,
    /// What it is.
    pub kind: BoxKind,
    /// Awning corners `(x, y, z)` on its vertical edges: a dark band
    /// [`AWNING_BAND_M`] high under `z` on the two faces meeting at `(x, y)`.
    pub awnings: Vec<Vector3<f64>>,
}

/// A tree's canopy: a sphere (its trunk is a [`BoxKind::Trunk`] box).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Canopy {
    /// Centre (ENU metres).
    pub centre: Vector3<f64>,
    /// Radius (metres).
    pub radius_m: f64,
    /// Diffuse reflectance (0–1).
    pub albedo: f64,
}

/// The day scene: boxes, canopies and the street grid spacing.
#[derive(Clone, Debug, PartialEq)]
pub struct DayScene {
    /// Buildings, cars and trunks.
    pub boxes: Vec<SceneBox>,
    /// Tree canopies.
    pub canopies: Vec<Canopy>,
    /// Street spacing (metres): street centre lines at multiples of it along x and y.
    pub block_m: f64,
    /// The corner landmarks `(index into World::landmarks, position)`.
    pub corners: Vec<(usize, Vector3<f64>)>,
}

impl DayScene {
    /// The day scene of `world` (street spacing `block_m`), its clutter drawn from `seed`.
    ///
    /// Each building box is grown by [`CORNER_CLEARANCE_M`] so that its vertices are the
    /// corner landmarks; awning corners (corner landmarks below the roof) get an awning band.
    pub fn from_world(world: &World, block_m: f64, seed: u64) -> DayScene {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ CLUTTER_SALT);
        let grow = Vector3::new(CORNER_CLEARANCE_M, CORNER_CLEARANCE_M, CORNER_CLEARANCE_M);
        let mut boxes: Vec<SceneBox> = world
            .buildings
            .iter()
            .map(|b| SceneBox {
                min: Vector3::new(b.min.x - grow.x, b.min.y - grow.y, 0.0),
                max: b.max + grow,
                albedo: rng.random_range(0.25..0.75),
                kind: BoxKind::Building,
                awnings: Vec::new(),
            })
            .collect();
        let corners: Vec<(usize, Vector3<f64>)> = world
            .landmarks
            .iter()
            .enumerate()
            .filter(|(_, l)| l.class == LandmarkClass::Corner)
            .map(|(i, l)| (i, l.position_in_enu))
            .collect();
        for (_, p) in &corners {
            let on_edge = |b: &SceneBox| {
                let ex = (p.x - b.min.x).abs() < 1e-6 || (p.x - b.max.x).abs() < 1e-6;
                let ey = (p.y - b.min.y).abs() < 1e-6 || (p.y - b.max.y).abs() < 1e-6;
                ex && ey && p.z < b.max.z - 1e-6
            };
            if let Some(b) = boxes.iter_mut().find(|b| on_edge(b)) {
                b.awnings.push(*p);
            }
        }
        let (lo, hi) = world.buildings.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), b| (lo.inf(&b.min), hi.sup(&b.max)),
        );
        let mut canopies = Vec::new();
        if lo.x.is_finite() && block_m > 2.0 * INTERSECTION_CLEAR_M {
            let (i0, i1) = (
                (lo.x / block_m).floor() as i64,
                (hi.x / block_m).ceil() as i64,
            );
            let (j0, j1) = (
                (lo.y / block_m).floor() as i64,
                (hi.y / block_m).ceil() as i64,
            );
            // Streets along x at y = j·block (between nodes i and i+1), and along y.
            let mut streets = Vec::new();
            for j in j0..=j1 {
                for i in i0..i1 {
                    streets.push((true, i as f64 * block_m, j as f64 * block_m));
                }
            }
            for i in i0..=i1 {
                for j in j0..j1 {
                    streets.push((false, j as f64 * block_m, i as f64 * block_m));
                }
            }
            for (along_x, start, line) in streets {
                for side in [-1.0, 1.0] {
                    let place = |along: f64, lateral: f64| {
                        if along_x {
                            (start + along, line + side * lateral)
                        } else {
                            (line + side * lateral, start + along)
                        }
                    };
                    let mut a = INTERSECTION_CLEAR_M + rng.random_range(0.0..CAR_GAP_M.1);
                    while a + CAR_SIZE_M.0 < block_m - INTERSECTION_CLEAR_M {
                        let (cx, cy) = place(a + CAR_SIZE_M.0 / 2.0, CAR_LATERAL_M);
                        let (hx, hy) = if along_x {
                            (CAR_SIZE_M.0 / 2.0, CAR_SIZE_M.1 / 2.0)
                        } else {
                            (CAR_SIZE_M.1 / 2.0, CAR_SIZE_M.0 / 2.0)
                        };
                        boxes.push(SceneBox {
                            min: Vector3::new(cx - hx, cy - hy, 0.0),
                            max: Vector3::new(cx + hx, cy + hy, CAR_SIZE_M.2),
                            albedo: rng.random_range(0.05..0.8),
                            kind: BoxKind::Car,
                            awnings: Vec::new(),
                        });
                        a += CAR_SIZE_M.0 + rng.random_range(CAR_GAP_M.0..CAR_GAP_M.1);
                    }
                    let mut a = INTERSECTION_CLEAR_M + rng.random_range(0.0..TREE_GAP_M.1);
                    while a < block_m - INTERSECTION_CLEAR_M {
                        let (tx, ty) = place(a, TREE_LATERAL_M);
                        let radius_m = rng.random_range(1.2..2.2);
                        let top = rng.random_range(4.5..7.0);
                        boxes.push(SceneBox {
                            min: Vector3::new(tx - 0.15, ty - 0.15, 0.0),
                            max: Vector3::new(tx + 0.15, ty + 0.15, top - radius_m),
                            albedo: 0.15,
                            kind: BoxKind::Trunk,
                            awnings: Vec::new(),
                        });
                        canopies.push(Canopy {
                            centre: Vector3::new(tx, ty, top - radius_m * 0.6),
                            radius_m,
                            albedo: rng.random_range(0.08..0.2),
                        });
                        a += rng.random_range(TREE_GAP_M.0..TREE_GAP_M.1);
                    }
                }
            }
        }
        DayScene {
            boxes,
            canopies,
            block_m,
            corners,
        }
    }
}

/// Ground materials of the street layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ground {
    Road,
    LaneMark,
    Kerb,
    Sidewalk,
    Lot,
}

/// Width of the kerb stone band (metres, inside [`KERB_M`]).
const KERB_BAND_M: f64 = 0.2;
/// Half-width of a lane marking (metres).
const LANE_MARK_HALF_M: f64 = 0.06;
/// Dash period and dash length of the centre line (metres).
const DASH_M: (f64, f64) = (9.0, 3.0);

/// The ground material at `(x, y)` for streets at multiples of `block_m`.
pub(crate) fn ground_at(x: f64, y: f64, block_m: f64) -> Ground {
    let off = |c: f64| c - (c / block_m).round() * block_m;
    let (dx, dy) = (off(x), off(y));
    let d = dx.abs().min(dy.abs());
    if d < KERB_M - KERB_BAND_M {
        // The centre line of the street we are on (not inside an intersection).
        let (lateral, along) = if dy.abs() < dx.abs() {
            (dy, x)
        } else {
            (dx, y)
        };
        let in_intersection = dx.abs() < KERB_M && dy.abs() < KERB_M;
        if !in_intersection
            && lateral.abs() < LANE_MARK_HALF_M
            && along.rem_euclid(DASH_M.0) < DASH_M.1
        {
            return Ground::LaneMark;
        }
        Ground::Road
    } else if d < KERB_M {
        Ground::Kerb
    } else if d < SETBACK_M {
        Ground::Sidewalk
    } else {
        Ground::Lot
    }
}
