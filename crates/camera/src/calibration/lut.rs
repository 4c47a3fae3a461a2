//! A dense pixel → bearing lookup table with bilinear interpolation, and its binary file.
//!
//! # File format (version 1, little endian)
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `VGPSLUT\0` ([`LUT_MAGIC`]) |
//! | 8 | 4 | `u32` version = 1 ([`LUT_FILE_VERSION`]) |
//! | 12 | 4 | `u32` image width `W` (pixels) |
//! | 16 | 4 | `u32` image height `H` (pixels) |
//! | 20 | 4 | `u32` grid step `s` (pixels) |
//! | 24 | 4 | `u32` node columns `nu = ⌈W / s⌉ + 1` |
//! | 28 | 4 | `u32` node rows `nv = ⌈H / s⌉ + 1` |
//! | 32 | `12 · nu · nv` | bearings: `nv` rows of `nu` nodes of three `f32` `(x, y, z)` |
//!
//! Node `(i, j)` (column `i`, row `j`, row-major: index `j · nu + i`) sits at pixel
//! `(−½ + min(i s, W), −½ + min(j s, H))`: the nodes cover the whole image rectangle
//! `[−½, W − ½] × [−½, H − ½]`, its edges and corners included; the last column/row of cells
//! is narrower when `s` does not divide the size. Each bearing is a unit vector in the camera
//! frame (x right, y down, z forward) with `|‖b‖ − 1| ≤` [`LUT_UNIT_TOLERANCE`]. The file
//! has exactly `32 + 12 · nu · nv` bytes. `f32` (≈ 6·10⁻⁸ relative) is ~10⁻⁴ px at
//! f = 600 px: far below the 0.01 px accuracy target, at half the size of `f64`.
//!
//! # Memory: a second copy of the nodes for pixel → bearing
//! Row-major, a cell's nodes `(i, j), (i + 1, j)` and `(i, j + 1), (i + 1, j + 1)` lie a row
//! apart (4 kB for 1024 px at step 3): two cache lines per call. A [`Lut`] therefore also keeps
//! the nodes in row pairs (`NodePair`: entry `j · nu + i` holds nodes `(i, j)` and
//! `(i, j + 1)`, each padded to four `f32`), so a cell is 64 contiguous bytes, and the padded
//! nodes convert to `f64` two components at a time. It costs `32 · nu · (nv − 1)` bytes, 2.6
//! times the node table (1024×768 at step 3: 2.8 MB besides 1.06 MB; 17 MB for a 6-camera
//! rig). Measured on the 1,024 random pixels of `calibration/bearing/lut` (best of 30 rounds,
//! fast-phase runs on the shared EPYC, docs/dev/journal.md 2026-11-28): through `Camera`
//! 21.1–22.3 → 20.2–21.2 ns, 147 → 134 instructions per call. A cell-major copy (each
//! cell's four nodes in one aligned 64-byte line, 5.6 MB) timed the same at twice the memory:
//! in this benchmark the gain is the contiguous, padded read, not the single line. The
//! row-major nodes stay the file's layout, the serde form and what the inverse and the
//! Jacobians read; both copies hold the same `f32` values, so the results are bit-identical
//! to reading the rows.

use super::{
    CalibrationError, CameraModel, Pixel, clamp_to_image, in_image_rectangle,
    normalisation_jacobian,
};
use nalgebra::{Matrix2x3, Matrix3x2, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The 8 bytes that open a LUT file.
pub const LUT_MAGIC: [u8; 8] = *b"VGPSLUT\0";

/// The LUT file format version this library reads and writes.
pub const LUT_FILE_VERSION: u32 = 1;

/// Size of the LUT file header in bytes.
pub const LUT_HEADER_BYTES: usize = 32;

/// Largest accepted `|‖b‖ − 1|` of a stored bearing.
pub const LUT_UNIT_TOLERANCE: f64 = 1e-6;

/// The bearing → pixel Newton iteration stops when its step is below this (pixels).
pub const LUT_INVERSE_TOLERANCE: f64 = 1e-10;

/// Most Newton iterations of the bearing → pixel inversion.
pub const MAX_LUT_INVERSE_ITERATIONS: usize = 60;

/// The converged pixel's interpolated bearing must be within this angle (radians) of the
/// asked direction.
pub const LUT_INVERSE_RESIDUAL: f64 = 1e-9;

/// The coarse inverse grid (the first guess of bearing → pixel) has at most this many
/// nodes per side.
pub const LUT_COARSE_SIDE: usize = 24;

/// Smallest squared norm of an interpolated bearing accepted before renormalisation (a
/// cell whose nodes nearly cancel has no meaningful direction).
pub const MIN_INTERPOLATED_NORM_SQUARED: f64 = 1e-12;

/// Grids with at least this many nodes are built on several threads by
/// [`Lut::from_model`].
pub const LUT_PARALLEL_MIN_NODES: usize = 16_384;

/// Largest number of grid nodes a LUT may have (2²⁸, a 3 GiB table).
pub const MAX_LUT_NODES: u64 = 1 << 28;

/// The raw content of a [`Lut`] (serde form): image size, grid step and node bearings
/// (row-major, see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LutParams {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Grid step in pixels (≥ 1).
    pub step: u32,
    /// Unit bearings at the nodes, `rows × cols`, row-major.
    pub bearings: Vec<[f32; 3]>,
}

/// A validated pixel → bearing lookup table.
///
/// # Model
/// Pixel → bearing: bilinear interpolation of the four nodes of the pixel's cell, then
/// renormalisation. Bearing → pixel (source-model free): the best node of a coarse grid of at
/// most [`LUT_COARSE_SIDE`]² nodes (largest dot product with the direction), a hill climb on
/// neighbouring cells (cell centres, so that the identical nodes of a panorama's pole row
/// cannot stall it), then Newton's method on the piecewise-bilinear map: with `t₁, t₂` a
/// basis of the plane normal to the direction `b`, solve `(t₁·B(p), t₂·B(p)) = 0` with the
/// analytic 2×2 Jacobian, to a step below [`LUT_INVERSE_TOLERANCE`] px; accepted when the
/// pixel is inside the image and `∠(B(p), b) ≤` [`LUT_INVERSE_RESIDUAL`].
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use vgps_camera::calibration::{CameraModel, Lut, Pinhole, PinholeParams};
/// let pinhole = Pinhole::new(PinholeParams::ideal(640, 480, 500.0, 500.0, 319.5, 239.5))?;
/// let lut = Lut::from_model(&pinhole, 3)?;
/// let pixel = Vector2::new(100.25, 50.75);
/// let (exact, approx) = (pinhole.try_bearing(&pixel).unwrap(), lut.try_bearing(&pixel).unwrap());
/// assert!((exact - approx).norm() * 500.0 < 0.01); // below 0.01 px
/// assert!((lut.try_pixel(&approx).unwrap() - pixel).norm() < 1e-6);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "LutParams", into = "LutParams")]
pub struct Lut {
    params: LutParams,
    cols: usize,
    rows: usize,
    coarse_stride: usize,
    /// The coarse inverse grid: cell `(i, j)` and its mean node direction.
    coarse: Vec<(usize, usize, Vector3<f64>)>,
    /// The nodes again, rows `j` and `j + 1` side by side: the forward look-up's copy (see
    /// [`NodePair`] and the module docs).
    pairs: Vec<NodePair>,
    u_axis: Axis,
    v_axis: Axis,
}

/// Two vertically adjacent nodes, `(i, j)` and `(i, j + 1)`, each `(x, y, z, 0)` (32 bytes):
/// one entry of the forward look-up's row-pair table (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
struct NodePair([[f32; 4]; 2]);

/// The row-pair copy of row-major `bearings` (`cols × rows` nodes): entry `j · cols + i` holds
/// nodes `(i, j)` and `(i, j + 1)`, for `j < rows − 1`.
fn node_pairs(bearings: &[[f32; 3]], cols: usize, rows: usize) -> Vec<NodePair> {
    let pad = |b: &[f32; 3]| [b[0], b[1], b[2], 0.0];
    bearings[..(rows - 1) * cols]
        .iter()
        .zip(&bearings[cols..])
        .map(|(upper, lower)| NodePair([pad(upper), pad(lower)]))
        .collect()
}

/// `(cols, rows)` of the node grid, or `None` when too large.
fn grid_size(width: u32, height: u32, step: u32) -> Option<(usize, usize)> {
    if width == 0 || height == 0 || step == 0 {
        return None;
    }
    let cols = u64::from(width).div_ceil(u64::from(step)) + 1;
    let rows = u64::from(height).div_ceil(u64::from(step)) + 1;
    if cols * rows > MAX_LUT_NODES {
        return None;
    }
    Some((usize::try_from(cols).ok()?, usize::try_from(rows).ok()?))
}

/// Checks the content; the reason when invalid.
fn validate(params: &LutParams) -> Result<(usize, usize), String> {
    let (cols, rows) = grid_size(params.width, params.height, params.step).ok_or_else(|| {
        format!(
            "size {}×{} with step {} is empty or too large",
            params.width, params.height, params.step
        )
    })?;
    if params.bearings.len() != cols * rows {
        return Err(format!(
            "{} bearings, but {}×{} pixels at step {} need {cols}×{rows} = {}",
            params.bearings.len(),
            params.width,
            params.height,
            params.step,
            cols * rows
        ));
    }
    for (k, b) in params.bearings.iter().enumerate() {
        let (i, j) = (k % cols, k / cols);
        if b.iter().any(|c| !c.is_finite()) {
            return Err(format!("node ({i}, {j}) has a non-finite bearing {b:?}"));
        }
        let norm = b
            .iter()
            .map(|&c| f64::from(c) * f64::from(c))
            .sum::<f64>()
            .sqrt();
        if !((norm - 1.0).abs() <= LUT_UNIT_TOLERANCE) {
            return Err(format!(
                "node ({i}, {j}) bearing {b:?} has norm {norm}, not 1 within {LUT_UNIT_TOLERANCE:e}"
            ));
        }
    }
    Ok((cols, rows))
}

/// The first three components of a stored node (`[f32; 3]`, or `[f32; 4]` padded) in `f64`.
#[inline]
fn to_f64<const N: usize>(b: &[f32; N]) -> Vector3<f64> {
    const { assert!(N >= 3) };
    Vector3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]))
}

/// Cell look-up along one axis: uniform cells of `step` pixels, the last one possibly
/// narrower.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axis {
    /// Number of cells (nodes − 1, ≥ 1).
    cells: usize,
    /// 1 / step.
    inv_step: f64,
    /// Offset (from the image edge at −½) of the last cell's first node.
    last_start: f64,
    /// 1 / width of the last cell.
    inv_last_width: f64,
    /// Largest pixel coordinate inside the image, `extent − ½`.
    upper: f64,
}

impl Axis {
    fn new(extent: u32, step: u32, nodes: usize) -> Self {
        let cells = nodes - 1;
        let last_start = (cells - 1) as f64 * f64::from(step);
        Self {
            cells,
            inv_step: 1.0 / f64::from(step),
            last_start,
            inv_last_width: 1.0 / (f64::from(extent) - last_start),
            upper: f64::from(extent) - 0.5,
        }
    }

    /// Cell index, fraction within the cell and 1 / cell width. The fraction is unclamped:
    /// outside the image it extrapolates the border cell.
    #[inline]
    fn locate(&self, coordinate: f64) -> (usize, f64, f64) {
        let a = coordinate + 0.5;
        let f = a * self.inv_step;
        // `as u32` saturates: negative and NaN go to 0, too large to `u32::MAX` (then the
        // last cell, as `cells < 2³²`). Cheaper than `as usize` (no unsigned 64-bit
        // conversion on x86-64).
        let i = f as u32;
        if (i as usize) + 1 < self.cells {
            (i as usize, f - f64::from(i), self.inv_step)
        } else {
            (
                self.cells - 1,
                (a - self.last_start) * self.inv_last_width,
                self.inv_last_width,
            )
        }
    }
}

impl Lut {
    /// Validates a table: non-zero size and step, `cols × rows` bearings, each finite and
    /// of unit norm within [`LUT_UNIT_TOLERANCE`].
    pub fn new(params: LutParams) -> Result<Self, CalibrationError> {
        let (cols, rows) =
            validate(&params).map_err(|reason| CalibrationError::InvalidParameters {
                model: "lut",
                reason,
            })?;
        Ok(Self::from_validated(params, cols, rows))
    }

    fn from_validated(params: LutParams, cols: usize, rows: usize) -> Self {
        let coarse_stride = cols.max(rows).div_ceil(LUT_COARSE_SIDE).max(1);
        let mut lut = Self {
            pairs: node_pairs(&params.bearings, cols, rows),
            u_axis: Axis::new(params.width, params.step, cols),
            v_axis: Axis::new(params.height, params.step, rows),
            params,
            cols,
            rows,
            coarse_stride,
            coarse: Vec::new(),
        };
        let (ncols, nrows) = (cols - 1, rows - 1);
        let coarse_cols: Vec<usize> = (0..ncols)
            .step_by(coarse_stride)
            .chain([ncols - 1])
            .collect();
        let coarse_rows: Vec<usize> = (0..nrows)
            .step_by(coarse_stride)
            .chain([nrows - 1])
            .collect();
        lut.coarse = coarse_rows
            .iter()
            .flat_map(|&j| coarse_cols.iter().map(move |&i| (i, j)))
            .map(|(i, j)| (i, j, lut.cell_direction(i, j)))
            .collect();
        lut
    }

    /// Samples `model` at every node of a grid of step `step` pixels.
    ///
    /// Grids of at least [`LUT_PARALLEL_MIN_NODES`] nodes are filled by up to
    /// `std::thread::available_parallelism()` scoped threads, one band of rows each.
    ///
    /// # Errors
    /// [`CalibrationError::LutBuild`] when the step is zero, the grid too large or the model
    /// has no bearing at some node (e.g. outside a fisheye's image circle).
    pub fn from_model<M: CameraModel + Sync + ?Sized>(
        model: &M,
        step: u32,
    ) -> Result<Self, CalibrationError> {
        let (width, height) = model.image_size();
        let (cols, rows) =
            grid_size(width, height, step).ok_or_else(|| CalibrationError::LutBuild {
                reason: format!("size {width}×{height} with step {step} is empty or too large"),
            })?;
        let mut bearings = vec![[0.0f32; 3]; cols * rows];
        let threads = if cols * rows >= LUT_PARALLEL_MIN_NODES {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            1
        };
        let rows_per_band = rows.div_ceil(threads.clamp(1, rows));
        // Fills the rows of one band, starting at row `first_row`.
        let fill = |band: &mut [[f32; 3]], first_row: usize| -> Result<(), CalibrationError> {
            for (k, out) in band.iter_mut().enumerate() {
                let (i, j) = (k % cols, first_row + k / cols);
                let u = -0.5 + f64::from(width).min((i as f64) * f64::from(step));
                let v = -0.5 + f64::from(height).min((j as f64) * f64::from(step));
                let b = model.try_bearing(&Vector2::new(u, v)).ok_or_else(|| {
                    CalibrationError::LutBuild {
                        reason: format!("the source model has no bearing at node pixel ({u}, {v})"),
                    }
                })?;
                *out = [b.x as f32, b.y as f32, b.z as f32];
            }
            Ok(())
        };
        if rows_per_band >= rows {
            fill(&mut bearings, 0)?;
        } else {
            std::thread::scope(|scope| {
                let handles: Vec<_> = bearings
                    .chunks_mut(rows_per_band * cols)
                    .enumerate()
                    .map(|(b, band)| {
                        let fill = &fill;
                        scope.spawn(move || fill(band, b * rows_per_band))
                    })
                    .collect();
                handles.into_iter().try_for_each(|h| {
                    h.join().unwrap_or_else(|_| {
                        Err(CalibrationError::LutBuild {
                            reason: "a LUT worker thread panicked".into(),
                        })
                    })
                })
            })?;
        }
        let params = LutParams {
            width,
            height,
            step,
            bearings,
        };
        // Re-validate: rounding to f32 keeps unit norm within 1e-7, but be strict anyway.
        Self::new(params).map_err(|e| CalibrationError::LutBuild {
            reason: e.to_string(),
        })
    }

    /// The content (size, step, node bearings).
    pub fn params(&self) -> &LutParams {
        &self.params
    }

    /// Grid step in pixels.
    pub fn step(&self) -> u32 {
        self.params.step
    }

    /// `(columns, rows)` of the node grid.
    pub fn grid_size(&self) -> (usize, usize) {
        (self.cols, self.rows)
    }

    /// Pixel position of node `(i, j)`.
    #[inline]
    pub fn node_pixel(&self, i: usize, j: usize) -> Pixel {
        let s = f64::from(self.params.step);
        Vector2::new(
            -0.5 + f64::from(self.params.width).min(i as f64 * s),
            -0.5 + f64::from(self.params.height).min(j as f64 * s),
        )
    }

    #[inline]
    fn node(&self, i: usize, j: usize) -> Vector3<f64> {
        to_f64(&self.params.bearings[j * self.cols + i])
    }

    /// `true` when `pixel` lies in the image rectangle `[−½, W − ½] × [−½, H − ½]` (the
    /// same test as [`in_image_rectangle`], with the bounds precomputed).
    #[inline]
    fn contains(&self, pixel: &Pixel) -> bool {
        pixel.x >= -0.5
            && pixel.x <= self.u_axis.upper
            && pixel.y >= -0.5
            && pixel.y <= self.v_axis.upper
    }

    /// Interpolated (unnormalised) bearing only (the hot path of pixel → bearing).
    #[inline]
    fn interpolate_bearing(&self, pixel: &Pixel) -> Vector3<f64> {
        let (i, t, _) = self.u_axis.locate(pixel.x);
        let (j, r, _) = self.v_axis.locate(pixel.y);
        // The cell's four nodes are 64 contiguous bytes (one cache line or two adjacent ones):
        // one bounds check for both entries.
        let pair = &self.pairs[j * self.cols + i..][..2];
        let ([n00, n01], [n10, n11]) = (&pair[0].0, &pair[1].0);
        let (b00, b10) = (to_f64(n00), to_f64(n10));
        let (b01, b11) = (to_f64(n01), to_f64(n11));
        let top = b00 + (b10 - b00) * t;
        let bottom = b01 + (b11 - b01) * t;
        top + (bottom - top) * r
    }

    /// Interpolated (unnormalised) bearing and its derivatives along u and v.
    #[inline]
    fn interpolate(&self, pixel: &Pixel) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let p = &self.params;
        let (i, t, inv_wu) = self.u_axis.locate(pixel.x);
        let (j, r, inv_wv) = self.v_axis.locate(pixel.y);
        let base = j * self.cols + i;
        let b00 = to_f64(&p.bearings[base]);
        let b10 = to_f64(&p.bearings[base + 1]);
        let b01 = to_f64(&p.bearings[base + self.cols]);
        let b11 = to_f64(&p.bearings[base + self.cols + 1]);
        let top = b00 + (b10 - b00) * t;
        let bottom = b01 + (b11 - b01) * t;
        let b = top + (bottom - top) * r;
        let du = ((b10 - b00) * (1.0 - r) + (b11 - b01) * r) * inv_wu;
        let dv = (bottom - top) * inv_wv;
        (b, du, dv)
    }

    /// Unit mean of the four nodes of cell `(i, j)` (its centre's direction, up to the
    /// interpolation error).
    #[inline]
    fn cell_direction(&self, i: usize, j: usize) -> Vector3<f64> {
        let sum =
            self.node(i, j) + self.node(i + 1, j) + self.node(i, j + 1) + self.node(i + 1, j + 1);
        let n = sum.norm();
        if n > 0.0 { sum / n } else { sum }
    }

    /// The cell whose centre direction has the largest dot product with `b`: a coarse grid
    /// of cells, then a hill climb over neighbouring cells. Cells rather than nodes, so that
    /// a row of identical nodes (a panorama's pole) cannot stall the climb.
    fn nearest_cell(&self, b: &Vector3<f64>) -> (usize, usize) {
        let (ncols, nrows) = (self.cols - 1, self.rows - 1);
        let mut best = (0, 0);
        let mut best_dot = f64::NEG_INFINITY;
        for &(i, j, direction) in &self.coarse {
            let d = direction.dot(b);
            if d > best_dot {
                best_dot = d;
                best = (i, j);
            }
        }
        // Hill climb over the 8 neighbours; each move strictly increases the dot product.
        for _ in 0..(ncols + nrows) {
            let (i0, j0) = best;
            let mut moved = false;
            for j in j0.saturating_sub(1)..=(j0 + 1).min(nrows - 1) {
                for i in i0.saturating_sub(1)..=(i0 + 1).min(ncols - 1) {
                    let d = self.cell_direction(i, j).dot(b);
                    if d > best_dot {
                        best_dot = d;
                        best = (i, j);
                        moved = true;
                    }
                }
            }
            if !moved {
                break;
            }
        }
        best
    }

    /// Bearing → pixel by Newton's method on the piecewise-bilinear map.
    fn invert(&self, direction: &Vector3<f64>) -> Option<Pixel> {
        let b = vgps_geometry::geometry::try_unit(direction)?;
        let (i, j) = self.nearest_cell(&b);
        // A basis of the plane normal to b.
        let helper = if b.x.abs() < 0.6 {
            Vector3::x()
        } else if b.y.abs() < 0.6 {
            Vector3::y()
        } else {
            Vector3::z()
        };
        let t1 = b.cross(&helper).normalize();
        let t2 = b.cross(&t1);
        let max_step = f64::from(self.params.step);
        let mut p = 0.5 * (self.node_pixel(i, j) + self.node_pixel(i + 1, j + 1));
        let mut converged = false;
        for _ in 0..MAX_LUT_INVERSE_ITERATIONS {
            let (bp, du, dv) = self.interpolate(&p);
            let r = Vector2::new(t1.dot(&bp), t2.dot(&bp));
            let (a, c, d, e) = (t1.dot(&du), t1.dot(&dv), t2.dot(&du), t2.dot(&dv));
            let det = a * e - c * d;
            if !(det.abs() > super::MIN_JACOBIAN_DETERMINANT) || !det.is_finite() {
                return None;
            }
            let mut step = Vector2::new((e * r.x - c * r.y) / det, (a * r.y - d * r.x) / det);
            let n = step.norm();
            if n > max_step {
                step *= max_step / n;
            }
            p -= step;
            if n <= LUT_INVERSE_TOLERANCE {
                converged = true;
                break;
            }
        }
        if !converged {
            return None;
        }
        let p = clamp_to_image(self.params.width, self.params.height, &p)?;
        let (bp, _, _) = self.interpolate(&p);
        (vgps_geometry::geometry::angle_between(&bp, &b) <= LUT_INVERSE_RESIDUAL).then_some(p)
    }

    /// The file's bytes (see the module docs for the layout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let p = &self.params;
        let mut out = Vec::with_capacity(LUT_HEADER_BYTES + 12 * p.bearings.len());
        out.extend_from_slice(&LUT_MAGIC);
        for value in [
            LUT_FILE_VERSION,
            p.width,
            p.height,
            p.step,
            self.cols as u32,
            self.rows as u32,
        ] {
            out.extend_from_slice(&value.to_le_bytes());
        }
        for b in &p.bearings {
            for c in b {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        out
    }

    /// Parses and validates a LUT file's bytes; `name` (the file name) is quoted in errors.
    ///
    /// # Errors
    /// [`CalibrationError::LutFile`] naming `name` and the reason: short header, wrong magic
    /// or version, node counts or file size contradicting the header, non-finite or
    /// non-unit bearings.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Self, CalibrationError> {
        let fail = |reason: String| CalibrationError::LutFile {
            path: name.to_string(),
            reason,
        };
        if bytes.len() < LUT_HEADER_BYTES {
            return Err(fail(format!(
                "{} bytes, shorter than the {LUT_HEADER_BYTES}-byte header",
                bytes.len()
            )));
        }
        if bytes[..8] != LUT_MAGIC {
            return Err(fail(format!(
                "wrong magic {:?} (expected {:?})",
                String::from_utf8_lossy(&bytes[..8]),
                String::from_utf8_lossy(&LUT_MAGIC)
            )));
        }
        let word = |k: usize| {
            let o = 8 + 4 * k;
            u32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]])
        };
        let (version, width, height, step, cols, rows) =
            (word(0), word(1), word(2), word(3), word(4), word(5));
        if version != LUT_FILE_VERSION {
            return Err(fail(format!(
                "unsupported version {version} (this library reads version {LUT_FILE_VERSION})"
            )));
        }
        let (ecols, erows) = grid_size(width, height, step).ok_or_else(|| {
            fail(format!(
                "size {width}×{height} with step {step} is empty or too large"
            ))
        })?;
        if (cols as usize, rows as usize) != (ecols, erows) {
            return Err(fail(format!(
                "header says {cols}×{rows} nodes but {width}×{height} at step {step} needs {ecols}×{erows}"
            )));
        }
        let expected = LUT_HEADER_BYTES as u64 + 12 * (ecols as u64) * (erows as u64);
        if bytes.len() as u64 != expected {
            return Err(fail(format!(
                "{} bytes, but the header ({ecols}×{erows} nodes of 3 f32) needs {expected}",
                bytes.len()
            )));
        }
        let bearings = bytes[LUT_HEADER_BYTES..]
            .chunks_exact(12)
            .map(|c| {
                let f = |o: usize| f32::from_le_bytes([c[o], c[o + 1], c[o + 2], c[o + 3]]);
                [f(0), f(4), f(8)]
            })
            .collect();
        let params = LutParams {
            width,
            height,
            step,
            bearings,
        };
        let (cols, rows) = validate(&params).map_err(fail)?;
        Ok(Self::from_validated(params, cols, rows))
    }

    /// Reads and validates a LUT file.
    ///
    /// # Errors
    /// [`CalibrationError::LutFile`] naming the file: I/O errors and every
    /// [`from_bytes`](Self::from_bytes) error.
    pub fn read(path: &Path) -> Result<Self, CalibrationError> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| CalibrationError::LutFile {
            path: name.clone(),
            reason: e.to_string(),
        })?;
        Self::from_bytes(&bytes, &name)
    }

    /// Writes the LUT file atomically (a reader sees the old file or the new one whole).
    ///
    /// # Errors
    /// [`CalibrationError::LutFile`] naming the file on an I/O error.
    pub fn write(&self, path: &Path) -> Result<(), CalibrationError> {
        vgps_io::write_atomic(path, &self.to_bytes()).map_err(|e| CalibrationError::LutFile {
            path: path.display().to_string(),
            reason: e.to_string(),
        })
    }
}

impl TryFrom<LutParams> for Lut {
    type Error = CalibrationError;
    fn try_from(params: LutParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<Lut> for LutParams {
    fn from(lut: Lut) -> Self {
        lut.params
    }
}

impl CameraModel for Lut {
    fn image_size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    fn is_inside(&self, pixel: &Pixel) -> bool {
        self.contains(pixel)
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        if !self.contains(pixel) {
            return None;
        }
        let b = self.interpolate_bearing(pixel);
        // Nodes are finite unit vectors and the weights convex: the norm is finite, and it
        // is only zero if opposite nodes cancel (then no bearing).
        let n2 = b.norm_squared();
        if !(n2 > MIN_INTERPOLATED_NORM_SQUARED) {
            return None;
        }
        Some(b * (1.0 / n2.sqrt()))
    }

    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        self.invert(bearing)
    }

    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        if !in_image_rectangle(self.params.width, self.params.height, pixel) {
            return None;
        }
        let (b, du, dv) = self.interpolate(pixel);
        let norm = b.norm();
        let unit = vgps_geometry::geometry::try_unit(&b)?;
        let jac = normalisation_jacobian(&unit, norm) * Matrix3x2::from_columns(&[du, dv]);
        Some((unit, jac))
    }

    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        super::pixel_with_inverted_jacobian(self, self.invert(bearing)?, bearing)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Pinhole, PinholeParams, RadialTangential};

    /// A distorted pinhole whose size is not a multiple of the step (narrower last cells).
    fn distorted_lut() -> Lut {
        let params = PinholeParams::ideal(641, 479, 420.0, 421.0, 320.2, 239.7).with_distortion(
            RadialTangential {
                k1: -0.2,
                k2: 0.05,
                p1: 3e-4,
                p2: -2e-4,
                k3: -0.002,
            },
        );
        let pinhole = Pinhole::new(params).unwrap_or_else(|e| unreachable!("{e}"));
        Lut::from_model(&pinhole, 4).unwrap_or_else(|e| unreachable!("{e}"))
    }

    #[test]
    fn row_pairs_hold_the_rows_nodes() {
        let lut = distorted_lut();
        let (cols, rows) = lut.grid_size();
        assert_eq!(lut.pairs.len(), cols * (rows - 1));
        for (k, pair) in lut.pairs.iter().enumerate() {
            let (i, j) = (k % cols, k / cols);
            for (node, row) in pair.0.iter().zip([j, j + 1]) {
                let b = lut.params.bearings[row * cols + i];
                assert_eq!(*node, [b[0], b[1], b[2], 0.0], "node ({i}, {row})");
            }
        }
    }

    #[test]
    fn pixel_to_bearing_is_the_row_major_interpolation_bit_for_bit() {
        let lut = distorted_lut();
        let (w, h) = lut.image_size();
        let (wf, hf) = (f64::from(w), f64::from(h));
        let mut rng = vgps_geometry::synthetic::rng(23);
        // Random pixels, the corners and the edges (first and narrower last cells), nodes.
        let mut pixels: Vec<Pixel> = (0..5000)
            .map(|_| {
                use rand::RngExt;
                Vector2::new(
                    rng.random_range(-0.5..wf - 0.5),
                    rng.random_range(-0.5..hf - 0.5),
                )
            })
            .collect();
        for (u, v) in [
            (-0.5, -0.5),
            (wf - 0.5, hf - 0.5),
            (-0.5, hf - 0.5),
            (wf - 0.5, -0.5),
        ] {
            pixels.push(Vector2::new(u, v));
        }
        pixels.extend((0..w).map(|u| Vector2::new(f64::from(u), hf - 0.5)));
        pixels.extend((0..h).map(|v| Vector2::new(wf - 0.75, f64::from(v))));
        pixels.push(lut.node_pixel(7, 9));
        for p in &pixels {
            let (rows, _, _) = lut.interpolate(p);
            let pairs = lut.interpolate_bearing(p);
            let bits = |b: &Vector3<f64>| b.map(f64::to_bits);
            assert_eq!(bits(&pairs), bits(&rows), "pixel {p:?}");
            let unit = lut
                .try_bearing(p)
                .unwrap_or_else(|| panic!("no bearing at {p:?}"));
            assert_eq!(
                bits(&unit),
                bits(&(rows * (1.0 / rows.norm_squared().sqrt())))
            );
        }
    }
}
