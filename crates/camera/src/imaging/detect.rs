//! The lamp detector: threshold, run-length connected components, sub-pixel centroids.
//!
//! # Method
//! 1. **Background and noise** are estimated robustly from a histogram of every
//!    [`DetectorConfig::background_row_stride`]-th row: the background is the (interpolated)
//!    median, the noise `1.4826 ·` the median absolute deviation (floored at
//!    [`MIN_NOISE_DN`]). Bright pixels are rare, so neither is pulled by the lamps.
//! 2. **Threshold**: a pixel is bright when its value exceeds
//!    `t = background + max(k · noise, min_contrast)` ([`Threshold::Adaptive`]) or a fixed
//!    value ([`Threshold::Fixed`]).
//! 3. **Runs**: each row is scanned in chunks of [`SCAN_CHUNK`] bytes whose maximum is
//!    compared with `t` (a vectorised max); only chunks holding a bright pixel are scanned
//!    pixel by pixel, giving the row's bright runs. Masked pixels ([`Mask`]) are not bright.
//!    Each run carries its moments (pixel count, Σx, Σy, Σx², Σy², Σxy, ΣI, ΣI·x, ΣI·y,
//!    peak, saturated count, bounding box).
//! 4. **Components** (8-connectivity): a run is united (union–find) with every run of the
//!    previous row whose columns overlap `[start − 1, end + 1]`. No label image is ever
//!    written: the work is proportional to the image size for the chunk scan and to the
//!    number of bright pixels for everything else.
//! 5. **Centroid**: `u = Σ w·x / Σ w`, `v = Σ w·y / Σ w` with the background-subtracted
//!    weight `w = I − background` ([`CentroidWeight::BackgroundSubtracted`]) or the
//!    threshold-subtracted weight `w = I − t` ([`CentroidWeight::ThresholdSubtracted`], a
//!    weight that is a continuous, point-symmetric function of the blob's profile, so the
//!    threshold cut biases it less). Both come from the same integer sums.
//! 6. **Limits**: components with an area outside `[min_area, max_area]` or an elongation
//!    (square root of the ratio of the eigenvalues of the binary shape's second moments, each
//!    pixel counted as a unit square) above `max_elongation` are rejected.
//!
//! The configuration is plain data (`Send + Sync`); the detector has no global state.

use super::ImagingError;
use image::GrayImage;

/// Bytes per chunk of the row scan (a chunk whose maximum is below the threshold is skipped).
pub const SCAN_CHUNK: usize = 32;

/// Smallest noise estimate (DN): a noise-free image still needs a positive contrast.
pub const MIN_NOISE_DN: f64 = 0.5;

/// Ratio of the standard deviation to the median absolute deviation of a Gaussian.
const MAD_TO_SIGMA: f64 = 1.4826;

/// Variance of a unit square (a pixel's own extent in the shape moments), px².
const PIXEL_AREA_VARIANCE: f64 = 1.0 / 12.0;

/// Largest threshold (a pixel is bright when strictly above it: 255 means none is).
const MAX_THRESHOLD: u8 = 255;

/// Value of a saturated pixel.
const SATURATED: u8 = 255;

/// How the bright-pixel threshold is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    /// Pixels strictly above this value are bright.
    Fixed(u8),
    /// Pixels above `background + max(k_sigma · noise, min_contrast_dn)` are bright, with the
    /// background and noise estimated from the image.
    Adaptive {
        /// Multiple of the noise standard deviation.
        k_sigma: f64,
        /// Smallest contrast above background (DN).
        min_contrast_dn: f64,
    },
}

/// The weight of a pixel in the centroid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CentroidWeight {
    /// `I − background`: the background-subtracted intensity.
    BackgroundSubtracted,
    /// `I − threshold`: continuous at the component's edge, less biased by the cut.
    ThresholdSubtracted,
}

/// The detector's parameters. [`Default`] suits dark night frames with a few DN of noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectorConfig {
    /// The threshold rule.
    pub threshold: Threshold,
    /// The centroid weight.
    pub centroid_weight: CentroidWeight,
    /// Smallest accepted component (pixels).
    pub min_area: u32,
    /// Largest accepted component (pixels).
    pub max_area: u32,
    /// Largest accepted elongation (major/minor axis ratio of the component's shape).
    pub max_elongation: f64,
    /// Largest number of bright runs per image; more is a flooded frame
    /// ([`ImagingError::TooManyRuns`]), which bounds the work on any input.
    pub max_runs: usize,
    /// Every this many rows feed the background histogram (1 = all rows).
    pub background_row_stride: usize,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            threshold: Threshold::Adaptive {
                k_sigma: 6.0,
                min_contrast_dn: 6.0,
            },
            centroid_weight: CentroidWeight::ThresholdSubtracted,
            min_area: 2,
            max_area: 40_000,
            max_elongation: 5.0,
            max_runs: 200_000,
            background_row_stride: 4,
        }
    }
}

/// One detected bright spot.
///
/// # Units
/// Pixels (`u` = column, `v` = row, integer = pixel centre) and DN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LampDetection {
    /// Sub-pixel column of the centroid.
    pub u: f64,
    /// Sub-pixel row of the centroid.
    pub v: f64,
    /// Number of bright pixels.
    pub area: u32,
    /// Largest pixel value (DN).
    pub peak: u8,
    /// Background-subtracted sum of the component's pixels (DN).
    pub strength: f64,
    /// Number of saturated (255) pixels.
    pub saturated: u32,
    /// Major/minor axis ratio of the component's shape (≥ 1).
    pub elongation: f64,
    /// Bounding box `[u_min, v_min, u_max, v_max]` (inclusive pixel indices).
    pub bbox: [u32; 4],
}

/// The detections of one image and the statistics behind them.
#[derive(Clone, Debug, PartialEq)]
pub struct Detections {
    /// Accepted spots, in raster order of their first pixel.
    pub lamps: Vec<LampDetection>,
    /// Estimated background level (DN).
    pub background_dn: f64,
    /// Estimated noise standard deviation (DN).
    pub noise_dn: f64,
    /// The threshold used: pixels above it are bright (DN).
    pub threshold: u8,
    /// Components rejected by the area or elongation limits.
    pub rejected: usize,
}

/// Pixels excluded from detection (the vehicle's body, the sky, a window reflection):
/// a bit per pixel, built from rectangles, polygons or an image.
///
/// # Example
/// ```
/// use vgps_camera::imaging::Mask;
/// let mut mask = Mask::new(1024, 768);
/// mask.add_rectangle(0, 700, 1023, 767); // the bonnet along the bottom
/// mask.add_polygon(&[(0.0, 0.0), (200.0, 0.0), (0.0, 200.0)]); // a corner
/// assert!(mask.is_masked(500, 720) && mask.is_masked(10, 10));
/// assert!(!mask.is_masked(500, 300));
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    width: u32,
    height: u32,
    words_per_row: usize,
    bits: Vec<u64>,
}

impl Mask {
    /// An empty mask (nothing masked) of `width × height` pixels.
    pub fn new(width: u32, height: u32) -> Self {
        let words_per_row = (width as usize).div_ceil(64);
        Self {
            width,
            height,
            words_per_row,
            bits: vec![0; words_per_row * height as usize],
        }
    }

    /// The detection mask of a calibration's camera mask (the pixels that never see the
    /// world: the vehicle's body, the mount), so that detection skips them.
    ///
    /// # Example
    /// ```
    /// use vgps_camera::calibration::CameraMask;
    /// use vgps_camera::imaging::Mask;
    /// let body = CameraMask::from_fn(64, 32, |_, v| v >= 28).expect("mask");
    /// let mask = Mask::from_camera_mask(&body);
    /// assert!(mask.is_masked(10, 30) && !mask.is_masked(10, 5));
    /// ```
    pub fn from_camera_mask(camera_mask: &crate::calibration::CameraMask) -> Self {
        let (width, height) = camera_mask.dimensions();
        let mut mask = Self::new(width, height);
        for y in 0..height {
            for x in 0..width {
                if camera_mask.is_masked(x, y) {
                    mask.set(x, y);
                }
            }
        }
        mask
    }

    /// A mask from an image of the same size: non-zero pixels are masked.
    pub fn from_image(image: &GrayImage) -> Self {
        let mut mask = Self::new(image.width(), image.height());
        for (x, y, p) in image.enumerate_pixels() {
            if p[0] != 0 {
                mask.set(x, y);
            }
        }
        mask
    }

    /// `(width, height)` in pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Masks the pixels `u0..=u1` × `v0..=v1` (clipped to the image).
    pub fn add_rectangle(&mut self, u0: u32, v0: u32, u1: u32, v1: u32) {
        if self.width == 0 || self.height == 0 {
            return;
        }
        for y in v0..=v1.min(self.height - 1) {
            for x in u0..=u1.min(self.width - 1) {
                self.set(x, y);
            }
        }
    }

    /// Masks the pixels whose centres lie inside the polygon (vertices `(u, v)` in pixels,
    /// even–odd rule). Fewer than three vertices or non-finite ones mask nothing.
    pub fn add_polygon(&mut self, vertices: &[(f64, f64)]) {
        if vertices.len() < 3 || !vertices.iter().all(|(u, v)| u.is_finite() && v.is_finite()) {
            return;
        }
        let mut crossings = Vec::new();
        for y in 0..self.height {
            let yc = y as f64;
            crossings.clear();
            for (i, &(ua, va)) in vertices.iter().enumerate() {
                let (ub, vb) = vertices[(i + 1) % vertices.len()];
                if (va <= yc) != (vb <= yc) {
                    crossings.push(ua + (yc - va) / (vb - va) * (ub - ua));
                }
            }
            crossings.sort_by(f64::total_cmp);
            for pair in crossings.chunks_exact(2) {
                let first = pair[0].ceil().max(0.0);
                let last = pair[1].floor().min(self.width as f64 - 1.0);
                if first <= last {
                    for x in first as u32..=last as u32 {
                        self.set(x, y);
                    }
                }
            }
        }
    }

    /// Whether pixel `(u, v)` is masked (pixels outside the mask are not).
    pub fn is_masked(&self, u: u32, v: u32) -> bool {
        u < self.width
            && v < self.height
            && self.bits[v as usize * self.words_per_row + u as usize / 64] >> (u % 64) & 1 == 1
    }

    fn set(&mut self, u: u32, v: u32) {
        self.bits[v as usize * self.words_per_row + u as usize / 64] |= 1 << (u % 64);
    }

    fn row(&self, v: usize) -> &[u64] {
        &self.bits[v * self.words_per_row..(v + 1) * self.words_per_row]
    }
}

/// The lamp detector (see the [module docs](self) for the method).
///
/// # Example
/// ```
/// use vgps_camera::imaging::LampDetector;
/// // A dark 64×48 image with one 3×3 spot centred on pixel (20, 10), brighter at (21, 10).
/// let mut image = image::GrayImage::from_pixel(64, 48, image::Luma([5]));
/// for (du, dv) in (-1..=1).flat_map(|a| (-1..=1).map(move |b| (a, b))) {
///     image.put_pixel((20 + du) as u32, (10 + dv) as u32, image::Luma([105]));
/// }
/// image.put_pixel(21, 10, image::Luma([205]));
/// let found = LampDetector::default().detect(&image, None)?;
/// assert_eq!(found.lamps.len(), 1);
/// let lamp = found.lamps[0];
/// assert_eq!((lamp.area, lamp.peak), (9, 205));
/// assert!(lamp.u > 20.0 && lamp.u < 21.0 && (lamp.v - 10.0).abs() < 1e-12);
/// # Ok::<(), vgps_camera::imaging::ImagingError>(())
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LampDetector {
    /// The parameters.
    pub config: DetectorConfig,
}

/// The moments of a run or of a merged component.
#[derive(Clone, Copy, Debug)]
struct Moments {
    n: u64,
    sx: u64,
    sy: u64,
    sxx: u64,
    syy: u64,
    sxy: u64,
    si: u64,
    six: u64,
    siy: u64,
    peak: u8,
    saturated: u32,
    bbox: [u32; 4],
}

impl Moments {
    fn run(row: &[u8], y: usize, x0: usize, x1: usize) -> Self {
        let (mut si, mut six, mut peak, mut saturated) = (0u64, 0u64, 0u8, 0u32);
        for (x, &p) in row[x0..=x1].iter().enumerate() {
            let p64 = u64::from(p);
            si += p64;
            six += p64 * (x0 + x) as u64;
            peak = peak.max(p);
            saturated += u32::from(p == SATURATED);
        }
        let (a, b, y) = (x0 as u64, x1 as u64, y as u64);
        let n = b - a + 1;
        let sx = (a + b) * n / 2;
        // Σ x² for x in a..=b.
        let sq = |m: u64| m * (m + 1) * (2 * m + 1) / 6;
        let sxx = sq(b) - if a > 0 { sq(a - 1) } else { 0 };
        Self {
            n,
            sx,
            sy: n * y,
            sxx,
            syy: n * y * y,
            sxy: sx * y,
            si,
            six,
            siy: si * y,
            peak,
            saturated,
            bbox: [x0 as u32, y as u32, x1 as u32, y as u32],
        }
    }

    fn merge(&mut self, o: &Self) {
        self.n += o.n;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sxx += o.sxx;
        self.syy += o.syy;
        self.sxy += o.sxy;
        self.si += o.si;
        self.six += o.six;
        self.siy += o.siy;
        self.peak = self.peak.max(o.peak);
        self.saturated += o.saturated;
        self.bbox = [
            self.bbox[0].min(o.bbox[0]),
            self.bbox[1].min(o.bbox[1]),
            self.bbox[2].max(o.bbox[2]),
            self.bbox[3].max(o.bbox[3]),
        ];
    }

    fn elongation(&self) -> f64 {
        let n = self.n as f64;
        let (mx, my) = (self.sx as f64 / n, self.sy as f64 / n);
        let cxx = self.sxx as f64 / n - mx * mx + PIXEL_AREA_VARIANCE;
        let cyy = self.syy as f64 / n - my * my + PIXEL_AREA_VARIANCE;
        let cxy = self.sxy as f64 / n - mx * my;
        let half = 0.5 * (cxx + cyy);
        let spread = (0.25 * (cxx - cyy).powi(2) + cxy * cxy).sqrt();
        let minor = (half - spread).max(PIXEL_AREA_VARIANCE);
        ((half + spread) / minor).sqrt()
    }
}

/// A bright run of one row: columns `x0..=x1`, union–find node `node`.
#[derive(Clone, Copy, Debug)]
struct Run {
    x0: u32,
    x1: u32,
    node: u32,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let grand = parent[parent[i as usize] as usize];
        parent[i as usize] = grand;
        i = grand;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

impl LampDetector {
    /// A detector with `config`.
    pub fn new(config: DetectorConfig) -> Self {
        Self { config }
    }

    /// Detects the bright spots of `image`, ignoring the pixels of `mask`.
    ///
    /// # Errors
    /// [`ImagingError::MaskDimensions`] when the mask's size differs from the image's;
    /// [`ImagingError::TooManyRuns`] when the frame has more than
    /// [`DetectorConfig::max_runs`] bright runs.
    pub fn detect(
        &self,
        image: &GrayImage,
        mask: Option<&Mask>,
    ) -> Result<Detections, ImagingError> {
        let (width, height) = image.dimensions();
        if let Some(m) = mask
            && m.dimensions() != (width, height)
        {
            return Err(ImagingError::MaskDimensions {
                mask_width: m.width,
                mask_height: m.height,
                width,
                height,
            });
        }
        let (w, h) = (width as usize, height as usize);
        let pixels = image.as_raw();
        let (background_dn, noise_dn) =
            estimate_background(pixels, w, h, self.config.background_row_stride);
        let threshold = match self.config.threshold {
            Threshold::Fixed(t) => t,
            Threshold::Adaptive {
                k_sigma,
                min_contrast_dn,
            } => {
                let level = background_dn + (k_sigma * noise_dn).max(min_contrast_dn);
                if level.is_finite() {
                    level.floor().clamp(0.0, MAX_THRESHOLD as f64) as u8
                } else {
                    MAX_THRESHOLD
                }
            }
        };
        let mut moments: Vec<Moments> = Vec::new();
        let mut parent: Vec<u32> = Vec::new();
        let mut previous: Vec<Run> = Vec::new();
        let mut current: Vec<Run> = Vec::new();
        for y in 0..h {
            let row = &pixels[y * w..(y + 1) * w];
            let mask_row = mask.map(|m| m.row(y));
            current.clear();
            scan_row(row, threshold, mask_row, |x0, x1| {
                current.push(Run {
                    x0: x0 as u32,
                    x1: x1 as u32,
                    node: 0,
                })
            });
            if moments.len() + current.len() > self.config.max_runs {
                return Err(ImagingError::TooManyRuns {
                    max_runs: self.config.max_runs,
                    threshold,
                });
            }
            let mut p = 0;
            for run in current.iter_mut() {
                let node = moments.len() as u32;
                moments.push(Moments::run(row, y, run.x0 as usize, run.x1 as usize));
                parent.push(node);
                run.node = node;
                // Skip previous runs ending left of this run's 8-neighbourhood.
                while p < previous.len() && previous[p].x1 + 1 < run.x0 {
                    p += 1;
                }
                let mut q = p;
                while q < previous.len() && previous[q].x0 <= run.x1 + 1 {
                    union(&mut parent, previous[q].node, node);
                    q += 1;
                }
            }
            std::mem::swap(&mut previous, &mut current);
        }
        for i in 0..moments.len() as u32 {
            let root = find(&mut parent, i);
            if root != i {
                let m = moments[i as usize];
                moments[root as usize].merge(&m);
            }
        }
        let weight_offset = match self.config.centroid_weight {
            CentroidWeight::BackgroundSubtracted => background_dn,
            CentroidWeight::ThresholdSubtracted => threshold as f64,
        };
        let mut lamps = Vec::new();
        let mut rejected = 0;
        for (i, m) in moments.iter().enumerate() {
            if parent[i] != i as u32 {
                continue;
            }
            let elongation = m.elongation();
            let area_ok =
                m.n >= u64::from(self.config.min_area) && m.n <= u64::from(self.config.max_area);
            let total = m.si as f64 - weight_offset * m.n as f64;
            if !area_ok || !(elongation <= self.config.max_elongation) || !(total > 0.0) {
                rejected += 1;
                continue;
            }
            let u = (m.six as f64 - weight_offset * m.sx as f64) / total;
            let v = (m.siy as f64 - weight_offset * m.sy as f64) / total;
            lamps.push(LampDetection {
                u,
                v,
                area: m.n as u32,
                peak: m.peak,
                strength: m.si as f64 - background_dn * m.n as f64,
                saturated: m.saturated,
                elongation,
                bbox: m.bbox,
            });
        }
        Ok(Detections {
            lamps,
            background_dn,
            noise_dn,
            threshold,
            rejected,
        })
    }
}

/// Calls `emit(x0, x1)` for every run of pixels above `threshold` (and not masked) in `row`.
fn scan_row(row: &[u8], threshold: u8, mask: Option<&[u64]>, mut emit: impl FnMut(usize, usize)) {
    let mut open: Option<usize> = None;
    let mut base = 0;
    for chunk in row.chunks(SCAN_CHUNK) {
        let max = chunk.iter().fold(0u8, |a, &b| a.max(b));
        if max <= threshold {
            if let Some(start) = open.take() {
                emit(start, base - 1);
            }
        } else {
            for (i, &p) in chunk.iter().enumerate() {
                let x = base + i;
                let bright = p > threshold && mask.is_none_or(|m| m[x / 64] >> (x % 64) & 1 == 0);
                match (bright, open) {
                    (true, None) => open = Some(x),
                    (false, Some(start)) => {
                        emit(start, x - 1);
                        open = None;
                    }
                    _ => {}
                }
            }
        }
        base += chunk.len();
    }
    if let Some(start) = open {
        emit(start, row.len() - 1);
    }
}

/// Background level (interpolated median) and noise (1.4826 · MAD, at least
/// [`MIN_NOISE_DN`]) from a histogram of every `stride`-th row.
fn estimate_background(pixels: &[u8], w: usize, h: usize, stride: usize) -> (f64, f64) {
    let mut hist = [[0u32; 256]; 4];
    for y in (0..h).step_by(stride.max(1)) {
        let row = &pixels[y * w..(y + 1) * w];
        let mut quads = row.chunks_exact(4);
        for q in &mut quads {
            hist[0][q[0] as usize] += 1;
            hist[1][q[1] as usize] += 1;
            hist[2][q[2] as usize] += 1;
            hist[3][q[3] as usize] += 1;
        }
        for &p in quads.remainder() {
            hist[0][p as usize] += 1;
        }
    }
    let counts: Vec<u64> = (0..256)
        .map(|i| hist.iter().map(|hh| u64::from(hh[i])).sum())
        .collect();
    let total: u64 = counts.iter().sum();
    if total == 0 {
        return (0.0, MIN_NOISE_DN);
    }
    let half = total as f64 / 2.0;
    let mut below = 0u64;
    let mut median_bin = 0usize;
    for (i, &c) in counts.iter().enumerate() {
        if (below + c) as f64 >= half {
            median_bin = i;
            break;
        }
        below += c;
    }
    let c = counts[median_bin].max(1) as f64;
    // Values are spread over [i − ½, i + ½) within their bin.
    let median = median_bin as f64 - 0.5 + (half - below as f64) / c;
    let mut within = counts[median_bin];
    let mut mad = 0usize;
    while (within as f64) < half && mad < 255 {
        mad += 1;
        if median_bin >= mad {
            within += counts[median_bin - mad];
        }
        if median_bin + mad < 256 {
            within += counts[median_bin + mad];
        }
    }
    (median, (MAD_TO_SIGMA * mad as f64).max(MIN_NOISE_DN))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blank(w: u32, h: u32, level: u8) -> GrayImage {
        GrayImage::from_pixel(w, h, image::Luma([level]))
    }

    /// A naive 8-connected labelling over a dense label image, as a reference.
    fn reference_components(image: &GrayImage, t: u8) -> Vec<(u32, f64, f64)> {
        let (w, h) = image.dimensions();
        let mut label = vec![0u32; (w * h) as usize];
        let mut out = Vec::new();
        let mut next = 0;
        for y in 0..h {
            for x in 0..w {
                if image.get_pixel(x, y)[0] <= t || label[(y * w + x) as usize] != 0 {
                    continue;
                }
                next += 1;
                let mut stack = vec![(x, y)];
                label[(y * w + x) as usize] = next;
                let (mut n, mut su, mut sv, mut sw) = (0u32, 0.0, 0.0, 0.0);
                while let Some((cx, cy)) = stack.pop() {
                    let wgt = image.get_pixel(cx, cy)[0] as f64 - t as f64;
                    n += 1;
                    su += wgt * cx as f64;
                    sv += wgt * cy as f64;
                    sw += wgt;
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (nx, ny) = (cx as i64 + dx, cy as i64 + dy);
                            if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                                continue;
                            }
                            let idx = (ny as u32 * w + nx as u32) as usize;
                            if label[idx] == 0 && image.get_pixel(nx as u32, ny as u32)[0] > t {
                                label[idx] = next;
                                stack.push((nx as u32, ny as u32));
                            }
                        }
                    }
                }
                out.push((n, su / sw, sv / sw));
            }
        }
        out
    }

    #[test]
    fn matches_a_dense_reference_labelling_on_random_images() {
        use rand::RngExt;
        let mut rng = vgps_geometry::synthetic::rng(21);
        let config = DetectorConfig {
            threshold: Threshold::Fixed(200),
            min_area: 1,
            max_area: u32::MAX,
            max_elongation: f64::INFINITY,
            ..DetectorConfig::default()
        };
        for case in 0..20 {
            // Random sparse blobs of every shape (U-shapes, diagonals), widths across chunks.
            let (w, h) = (rng.random_range(1..150u32), rng.random_range(1..60u32));
            let density = rng.random_range(0.05..0.6);
            let image = GrayImage::from_fn(w, h, |_, _| {
                image::Luma([if rng.random_range(0.0..1.0) < density {
                    rng.random_range(201..=255u8)
                } else {
                    3
                }])
            });
            let found = LampDetector::new(config).detect(&image, None).unwrap();
            let mut expected = reference_components(&image, 200);
            let mut got: Vec<_> = found.lamps.iter().map(|l| (l.area, l.u, l.v)).collect();
            let key = |a: &(u32, f64, f64)| (a.0, (a.1 * 1e6) as i64, (a.2 * 1e6) as i64);
            expected.sort_by_key(key);
            got.sort_by_key(key);
            assert_eq!(got.len(), expected.len(), "case {case}: {w}×{h}");
            for (g, e) in got.iter().zip(&expected) {
                assert_eq!(g.0, e.0, "case {case}");
                assert!(
                    (g.1 - e.1).abs() < 1e-9 && (g.2 - e.2).abs() < 1e-9,
                    "case {case}: {g:?} {e:?}"
                );
            }
        }
    }

    #[test]
    fn background_and_noise_estimates() {
        // Uniform over 8..=12: median 10, median absolute deviation 1.
        let image = GrayImage::from_fn(255, 64, |x, y| {
            image::Luma([((x * 7 + y * 3) % 5 + 8) as u8])
        });
        let (bg, noise) = estimate_background(image.as_raw(), 255, 64, 1);
        assert!((bg - 10.0).abs() < 0.05, "{bg}");
        assert!((noise - MAD_TO_SIGMA).abs() < 1e-12, "{noise}");
        let flat = blank(100, 10, 7);
        let (bg, noise) = estimate_background(flat.as_raw(), 100, 10, 1);
        assert!((bg - 7.0).abs() <= 0.5 && noise == MIN_NOISE_DN);
    }

    #[test]
    fn area_and_elongation_limits() {
        let mut image = blank(100, 50, 5);
        // A single hot pixel, a 1×20 streak and a 4×4 square.
        image.put_pixel(10, 10, image::Luma([250]));
        for x in 30..50 {
            image.put_pixel(x, 20, image::Luma([250]));
        }
        for (x, y) in (60..64).flat_map(|x| (30..34).map(move |y| (x, y))) {
            image.put_pixel(x, y, image::Luma([250]));
        }
        let found = LampDetector::default().detect(&image, None).unwrap();
        assert_eq!(found.lamps.len(), 1);
        assert_eq!(found.rejected, 2);
        let lamp = found.lamps[0];
        assert_eq!((lamp.area, lamp.bbox), (16, [60, 30, 63, 33]));
        assert!((lamp.u - 61.5).abs() < 1e-12 && (lamp.v - 31.5).abs() < 1e-12);
        assert!((lamp.elongation - 1.0).abs() < 1e-12);
        assert_eq!(lamp.saturated, 0);
    }

    #[test]
    fn masked_pixels_are_ignored() {
        let mut image = blank(80, 40, 5);
        for (x, y) in (10..14).flat_map(|x| (10..14).map(move |y| (x, y))) {
            image.put_pixel(x, y, image::Luma([255]));
            image.put_pixel(x + 50, y + 20, image::Luma([255]));
        }
        let mut mask = Mask::new(80, 40);
        mask.add_rectangle(55, 25, 79, 39);
        let found = LampDetector::default().detect(&image, Some(&mask)).unwrap();
        assert_eq!(found.lamps.len(), 1);
        assert_eq!(found.lamps[0].saturated, 16);
        assert!((found.lamps[0].u - 11.5).abs() < 1e-12);
        let wrong = Mask::new(81, 40);
        assert!(matches!(
            LampDetector::default().detect(&image, Some(&wrong)),
            Err(ImagingError::MaskDimensions { mask_width: 81, .. })
        ));
        let from_image = Mask::from_image(&GrayImage::from_fn(80, 40, |x, _| {
            image::Luma([(x >= 55) as u8])
        }));
        assert!(from_image.is_masked(55, 0) && !from_image.is_masked(54, 39));
    }

    #[test]
    fn polygon_mask_covers_pixel_centres_inside() {
        let mut mask = Mask::new(20, 20);
        mask.add_polygon(&[(2.0, 2.0), (12.0, 2.0), (12.0, 12.0), (2.0, 12.0)]);
        let count = (0..20)
            .flat_map(|x| (0..20).map(move |y| (x, y)))
            .filter(|&(x, y)| mask.is_masked(x, y))
            .count();
        // Rows 2..12 (the bottom edge excluded by the half-open rule) × columns 2..=12.
        assert_eq!(count, 10 * 11);
        let mut empty = Mask::new(20, 20);
        empty.add_polygon(&[(1.0, 1.0), (f64::NAN, 3.0), (5.0, 5.0)]);
        empty.add_polygon(&[(1.0, 1.0), (5.0, 5.0)]);
        assert_eq!(empty, Mask::new(20, 20));
    }

    #[test]
    fn flooded_frame_is_a_typed_error_and_empty_images_work() {
        let image = GrayImage::from_fn(200, 100, |x, y| {
            image::Luma([if (x + y) % 2 == 0 { 255 } else { 0 }])
        });
        let detector = LampDetector::new(DetectorConfig {
            threshold: Threshold::Fixed(100),
            max_runs: 1000,
            ..DetectorConfig::default()
        });
        assert!(matches!(
            detector.detect(&image, None),
            Err(ImagingError::TooManyRuns { max_runs: 1000, .. })
        ));
        let empty = GrayImage::new(0, 0);
        assert!(
            LampDetector::default()
                .detect(&empty, None)
                .unwrap()
                .lamps
                .is_empty()
        );
        let saturated = blank(64, 64, 255);
        let found = LampDetector::default().detect(&saturated, None).unwrap();
        assert!(found.lamps.is_empty(), "{found:?}");
    }
}
