//! What a calibration covers and whether it is sound: fields of view, the fraction of the
//! sphere each camera and each pair of cameras sees, and the checks of `vgps calib check`
//! (rotation orthonormality, pixel ↔ bearing round trips, monotonic tables).
//!
//! The command line only formats these figures; a robot stack can run the same checks on
//! the calibration it loads.

use super::{Camera, CameraModel, Lut, Pixel, ROTATION_TOLERANCE, Rig};
use nalgebra::{Matrix3, Vector2, Vector3};
use vgps_geometry::geometry::angle_between;

/// Number of directions (a Fibonacci sphere) used for coverage figures.
pub const COVERAGE_SAMPLES: usize = 20_000;

/// Largest accepted pixel → bearing → pixel round-trip error of [`check_camera`] (pixels).
pub const CHECK_ROUND_TRIP_PX: f64 = 1e-6;

/// Largest accepted bearing → pixel → bearing round-trip error of [`check_camera`]
/// (radians).
pub const CHECK_ROUND_TRIP_RAD: f64 = 1e-9;

/// Pixels probed per image side by [`check_camera`]'s round trip.
pub const CHECK_GRID: usize = 97;

/// Samples along an image line when measuring a field of view.
pub const FOV_SAMPLES: usize = 2000;

/// Steps of 0.1° in azimuth probed by [`Coverage::horizon_gap_deg`].
const HORIZON_STEPS: usize = 3600;

/// Rigs with more cameras than this have the extra cameras left out of the coverage masks.
pub const MAX_COVERAGE_CAMERAS: usize = 64;

/// `n` directions evenly spread on the unit sphere (Fibonacci lattice).
///
/// # Example
/// ```
/// let d = vgps_camera::calibration::inspect::fibonacci_sphere(100);
/// assert_eq!(d.len(), 100);
/// assert!(d.iter().all(|v| (v.norm() - 1.0).abs() < 1e-12));
/// ```
pub fn fibonacci_sphere(n: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            Vector3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Elevation of a direction in degrees (rig frame, z up).
pub fn elevation_deg(d: &Vector3<f64>) -> f64 {
    d.z.clamp(-1.0, 1.0).asin().to_degrees()
}

/// Azimuth of a direction in degrees, counter-clockwise from the rig's +x (forward) axis.
pub fn azimuth_deg(d: &Vector3<f64>) -> f64 {
    d.y.atan2(d.x).to_degrees()
}

/// The fields of view of a camera with a bounded image, in degrees (`None` where the line
/// through the image centre has no valid pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldOfView {
    /// Along the row through the centre (u).
    pub across_deg: Option<f64>,
    /// Along the column through the centre (v).
    pub down_deg: Option<f64>,
    /// Along the diagonal from the top-left to the bottom-right corner.
    pub diagonal_deg: Option<f64>,
}

/// The fields of view of `camera`, or `None` for an unbounded image (size 0×0).
pub fn field_of_view(camera: &Camera) -> Option<FieldOfView> {
    let (w, h) = camera.image_size();
    if w == 0 || h == 0 {
        return None;
    }
    let (wf, hf) = (f64::from(w) - 0.5, f64::from(h) - 0.5);
    let centre = Vector2::new((wf - 0.5) / 2.0, (hf - 0.5) / 2.0);
    let along = |a: Pixel, b: Pixel| fov_along(camera, &centre, &a, &b);
    Some(FieldOfView {
        across_deg: along(Vector2::new(-0.5, centre.y), Vector2::new(wf, centre.y)),
        down_deg: along(Vector2::new(centre.x, -0.5), Vector2::new(centre.x, hf)),
        diagonal_deg: along(Vector2::new(-0.5, -0.5), Vector2::new(wf, hf)),
    })
}

/// Field of view (degrees) along the image line from `a` to `b` through `centre`: the
/// largest angle from the centre's bearing towards `a` plus towards `b` over valid pixels.
fn fov_along(model: &Camera, centre: &Pixel, a: &Pixel, b: &Pixel) -> Option<f64> {
    let c = model.try_bearing(centre)?;
    let half = |end: &Pixel| {
        (0..=FOV_SAMPLES)
            .filter_map(|k| {
                let t = k as f64 / FOV_SAMPLES as f64;
                model
                    .try_bearing(&(centre + (end - centre) * t))
                    .map(|x| angle_between(&c, &x))
            })
            .fold(0.0, f64::max)
    };
    Some((half(a) + half(b)).to_degrees())
}

/// Which cameras see each direction of a Fibonacci sphere ([`COVERAGE_SAMPLES`]).
#[derive(Clone, Debug)]
pub struct Coverage {
    /// Per sample: bit mask of the cameras that see it (camera `i` is bit `i`, for the
    /// first [`MAX_COVERAGE_CAMERAS`] cameras).
    seen_by: Vec<u64>,
    directions: Vec<Vector3<f64>>,
    /// Whether each of 3,600 horizontal directions is seen by some camera.
    horizon_seen: Vec<bool>,
}

impl Coverage {
    /// Projects [`COVERAGE_SAMPLES`] directions through `rig`. `None` when a camera's
    /// image is unbounded (coverage would be meaningless).
    pub fn try_new(rig: &Rig) -> Option<Self> {
        if rig.cameras().iter().any(|c| c.model.image_size().0 == 0) {
            return None;
        }
        let directions = fibonacci_sphere(COVERAGE_SAMPLES);
        let seen_by = directions
            .iter()
            .map(|d| {
                rig.project_direction(d)
                    .iter()
                    .filter(|p| p.camera < MAX_COVERAGE_CAMERAS)
                    .fold(0u64, |m, p| m | (1 << p.camera))
            })
            .collect();
        let horizon_seen = (0..HORIZON_STEPS)
            .map(|k| {
                let a = (k as f64 * 360.0 / HORIZON_STEPS as f64).to_radians();
                !rig.project_direction(&Vector3::new(a.cos(), a.sin(), 0.0))
                    .is_empty()
            })
            .collect();
        Some(Self {
            seen_by,
            directions,
            horizon_seen,
        })
    }

    /// The fraction of the samples for which `keep(mask, direction)` holds.
    pub fn fraction(&self, keep: impl Fn(u64, &Vector3<f64>) -> bool) -> f64 {
        let n = self
            .seen_by
            .iter()
            .zip(&self.directions)
            .filter(|(m, d)| keep(**m, d))
            .count();
        n as f64 / self.directions.len() as f64
    }

    /// The fraction of the sphere seen by at least `cameras` cameras.
    pub fn seen_by_at_least(&self, cameras: u32) -> f64 {
        self.fraction(|m, _| m.count_ones() >= cameras)
    }

    /// The fraction of the directions above `elevation_deg` that some camera sees.
    pub fn seen_above(&self, elevation_deg: f64) -> f64 {
        let low = elevation_deg.to_radians().sin();
        let above = self.fraction(|_, d| d.z >= low);
        if above > 0.0 {
            self.fraction(|m, d| m != 0 && d.z >= low) / above
        } else {
            0.0
        }
    }

    /// The fraction of the sphere seen by both cameras `i` and `j`.
    pub fn overlap(&self, i: usize, j: usize) -> f64 {
        if i >= MAX_COVERAGE_CAMERAS || j >= MAX_COVERAGE_CAMERAS {
            return 0.0;
        }
        let both = (1u64 << i) | (1u64 << j);
        self.fraction(|m, _| m & both == both)
    }

    /// The lowest elevation (degrees) above which every sample is covered, or `None` when
    /// the zenith itself is not covered.
    pub fn covered_above(&self) -> Option<f64> {
        let highest_gap = self
            .seen_by
            .iter()
            .zip(&self.directions)
            .filter(|(m, _)| **m == 0)
            .map(|(_, d)| elevation_deg(d))
            .fold(f64::NEG_INFINITY, f64::max);
        if highest_gap == f64::NEG_INFINITY {
            Some(-90.0)
        } else if highest_gap >= 89.0 {
            None
        } else {
            Some(highest_gap)
        }
    }

    /// Degrees of the 360° of azimuth on the horizon that no camera sees (0.1° steps).
    pub fn horizon_gap_deg(&self) -> f64 {
        let unseen = self.horizon_seen.iter().filter(|s| !**s).count();
        unseen as f64 * 360.0 / HORIZON_STEPS as f64
    }
}

/// The figures of [`check_camera`] for one camera. `passed()` says whether it is sound.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraCheck {
    /// max |RᵀR − I| and |det R − 1| of `rig_from_camera`'s rotation.
    pub rotation_deviation: f64,
    /// Probe pixels ([`CHECK_GRID`]² over the image).
    pub probes: usize,
    /// Probe pixels with a bearing.
    pub valid: usize,
    /// Valid probes whose bearing has no pixel.
    pub lost: usize,
    /// Largest pixel → bearing → pixel error (pixels).
    pub worst_round_trip_px: f64,
    /// Largest bearing → pixel → bearing error (radians).
    pub worst_round_trip_rad: f64,
    /// The table checks of a tabulated camera, when it has tables.
    pub tables: Option<TableCheck>,
}

/// Monotonicity (and, for two-way tables, consistency) of a tabulated camera.
#[derive(Clone, Debug, PartialEq)]
pub enum TableCheck {
    /// A LUT: the smallest `((b10 − b00) × (b01 − b00)) · b00` over its cells (> 0 when
    /// every cell keeps the image's orientation).
    Lut {
        /// The smallest cell orientation.
        min_orientation: f64,
    },
    /// Distortion tables (raw → undistorted D2U and back U2D).
    Distortion {
        /// Smallest cell Jacobian determinant of D2U (> 0 when monotonic).
        min_jacobian_d2u: f64,
        /// Smallest cell Jacobian determinant of U2D.
        min_jacobian_u2d: f64,
        /// max |U2D(D2U(p)) − p| at the raw pixel centres (information: only D2U defines
        /// the model).
        worst_inconsistency_px: f64,
    },
}

impl TableCheck {
    /// Whether the tables are monotonic.
    pub fn passed(&self) -> bool {
        match self {
            Self::Lut { min_orientation } => *min_orientation > 0.0,
            Self::Distortion {
                min_jacobian_d2u,
                min_jacobian_u2d,
                ..
            } => *min_jacobian_d2u > 0.0 && *min_jacobian_u2d > 0.0,
        }
    }
}

impl CameraCheck {
    /// Whether the rotation is orthonormal within [`ROTATION_TOLERANCE`].
    pub fn rotation_passed(&self) -> bool {
        self.rotation_deviation <= ROTATION_TOLERANCE
    }

    /// Whether every valid probe came back within [`CHECK_ROUND_TRIP_PX`] and
    /// [`CHECK_ROUND_TRIP_RAD`].
    pub fn round_trip_passed(&self) -> bool {
        self.lost == 0
            && self.worst_round_trip_px <= CHECK_ROUND_TRIP_PX
            && self.worst_round_trip_rad <= CHECK_ROUND_TRIP_RAD
    }

    /// Whether every check of the camera passed.
    pub fn passed(&self) -> bool {
        self.rotation_passed()
            && self.round_trip_passed()
            && self.tables.as_ref().is_none_or(TableCheck::passed)
    }
}

/// Checks one camera of a rig: its rotation, pixel ↔ bearing round trips over a grid of
/// probe pixels, and its tables.
pub fn check_camera(camera: &super::RigCamera) -> CameraCheck {
    let r: &Matrix3<f64> = camera.rig_from_camera.rotation.matrix();
    let rotation_deviation = (r.transpose() * r - Matrix3::identity())
        .abs()
        .max()
        .max((r.determinant() - 1.0).abs());
    let probes = probe_pixels(&camera.model);
    let (mut worst_px, mut worst_rad, mut valid, mut lost) = (0.0f64, 0.0f64, 0usize, 0usize);
    for p in &probes {
        let Some(b) = camera.model.try_bearing(p) else {
            continue;
        };
        valid += 1;
        match camera.model.try_pixel(&b) {
            Some(q) => {
                worst_px = worst_px.max((q - p).norm());
                if let Some(b2) = camera.model.try_bearing(&q) {
                    worst_rad = worst_rad.max(angle_between(&b, &b2));
                }
            }
            None => lost += 1,
        }
    }
    CameraCheck {
        rotation_deviation,
        probes: probes.len(),
        valid,
        lost,
        worst_round_trip_px: worst_px,
        worst_round_trip_rad: worst_rad,
        tables: table_check(&camera.model),
    }
}

fn table_check(model: &Camera) -> Option<TableCheck> {
    match model {
        Camera::Lut(lut) => Some(TableCheck::Lut {
            min_orientation: lut_min_orientation(lut),
        }),
        Camera::TabulatedPinhole(m) => {
            let p = m.params();
            let (d2u, u2d) = (
                p.raw_to_undistorted.as_ref()?,
                p.undistorted_to_raw.as_ref()?,
            );
            let mut worst: f64 = 0.0;
            for r in 0..d2u.height {
                for col in 0..d2u.width {
                    let px = Vector2::new(f64::from(col), f64::from(r));
                    let q = d2u.interpolate(&px).0;
                    worst = worst.max((u2d.interpolate(&q).0 - px).norm());
                }
            }
            Some(TableCheck::Distortion {
                min_jacobian_d2u: d2u.min_jacobian_determinant(),
                min_jacobian_u2d: u2d.min_jacobian_determinant(),
                worst_inconsistency_px: worst,
            })
        }
        _ => None,
    }
}

/// Deterministic probe pixels of a camera: a grid over the image rectangle (inset by a
/// hundredth of a pixel) with irrational offsets; for an unbounded image, over
/// `[0, 2 cx] × [0, 2 cy]`.
fn probe_pixels(model: &Camera) -> Vec<Pixel> {
    let (w, h) = model.image_size();
    let (w, h) = if w == 0 {
        match model {
            Camera::TabulatedPinhole(m) => {
                let p = m.params();
                ((2.0 * p.cx + 1.0).max(2.0), (2.0 * p.cy + 1.0).max(2.0))
            }
            _ => (2.0, 2.0),
        }
    } else {
        (f64::from(w), f64::from(h))
    };
    let n = CHECK_GRID;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let fu = (i as f64 + 0.5 * (i % 2) as f64 * 0.618) / (n - 1) as f64;
            let fv = (j as f64 + 0.5 * (j % 2) as f64 * 0.414) / (n - 1) as f64;
            let u = -0.49 + fu.min(1.0) * (w - 0.98);
            let v = -0.49 + fv.min(1.0) * (h - 0.98);
            out.push(Vector2::new(u, v));
        }
    }
    out
}

/// The smallest `((b10 − b00) × (b01 − b00)) · b00` over the cells of a LUT (> 0 when every
/// cell keeps the image's orientation).
fn lut_min_orientation(lut: &Lut) -> f64 {
    let (cols, rows) = lut.grid_size();
    let b = &lut.params().bearings;
    let v = |i: usize, j: usize| {
        let x = b[j * cols + i];
        Vector3::new(f64::from(x[0]), f64::from(x[1]), f64::from(x[2]))
    };
    let mut min = f64::INFINITY;
    for j in 0..rows.saturating_sub(1) {
        for i in 0..cols.saturating_sub(1) {
            let b00 = v(i, j);
            min = min.min((v(i + 1, j) - b00).cross(&(v(i, j + 1) - b00)).dot(&b00));
        }
    }
    min
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Equirectangular, EquirectangularParams};

    fn panorama() -> Rig {
        let params = EquirectangularParams {
            width: 720,
            height: 360,
        };
        Rig::panorama(Camera::from(Equirectangular::new(params).unwrap()))
    }

    #[test]
    fn a_panorama_sees_the_whole_sphere_and_its_horizon() {
        let rig = panorama();
        let cov = Coverage::try_new(&rig).unwrap();
        assert_eq!(cov.seen_by_at_least(1), 1.0);
        assert_eq!(cov.seen_by_at_least(2), 0.0);
        assert_eq!(cov.covered_above(), Some(-90.0));
        assert_eq!(cov.horizon_gap_deg(), 0.0);
        let fov = field_of_view(&rig.cameras()[0].model).unwrap();
        let across = fov.across_deg.unwrap();
        assert!((across - 360.0).abs() < 1.0, "{across}");
    }

    #[test]
    fn a_sound_camera_passes_and_a_skewed_rotation_fails() {
        let rig = panorama();
        let check = check_camera(&rig.cameras()[0]);
        assert!(check.passed(), "{check:?}");
        assert_eq!(check.probes, CHECK_GRID * CHECK_GRID);
        let mut skewed = check.clone();
        skewed.rotation_deviation = 10.0 * ROTATION_TOLERANCE;
        assert!(!skewed.passed());
    }
}
