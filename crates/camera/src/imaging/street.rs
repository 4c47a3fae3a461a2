//! A lamp detector for real night streets ([`StreetLampDetector`]).
//!
//! The renderer's detector ([`super::LampDetector`]) finds every spot above a noise-based
//! threshold: right for point lights on a near-black background, wrong for a real street,
//! where pavement texture, lit windows, wet-road reflections, headlights and the bloom
//! around each lamp all rise far above the noise. This detector looks for what a lamp head
//! is in a real night exposure — a **bright core**, at or near the sensor's white level,
//! standing out from its **local** background — and labels the cores that are something
//! else.
//!
//! # Method
//! 1. **Core level**: `max(CORE_FRACTION · white, background + MIN_CORE_CONTRAST_DN)`, with
//!    `white` the image's largest value and `background` its median (a night exposure that
//!    shows the street saturates the lamp heads; the rule follows the exposure, not a fixed
//!    DN). Cores are the 8-connected components above it (the run-length labelling of
//!    [`super::LampDetector`]); each gives its core centroid, area, peak and shape.
//! 2. **One detection per lamp**: a core lying within the bloom of a larger one
//!    (`HALO_RADII` core radii from its bounding box) is a fragment of that lamp's halo or
//!    star-burst spikes, and is merged into it, when the light between them stays above
//!    `BRIDGE_FRACTION` of the core level or the core is under `1/FRAGMENT_AREA_RATIO` of
//!    the larger one's area.
//! 3. **Plausibility**: a core must stand out from its local background, the median of an
//!    annulus from `ANNULUS_INNER_RADII` to `ANNULUS_OUTER_RADII` core radii: its peak at
//!    least `MIN_LOCAL_CONTRAST` of itself above it. A core longer than `MAX_ELONGATION`
//!    (a light trail, a lit edge) is not a lamp head.
//! 4. **Classes** ([`LampClass`]): lit **windows** (cores filling their bounding box like a
//!    rectangle, aligned with at least `WINDOW_GRID_MIN` others of similar size in a row or
//!    a column), specular **reflections** (a vertically stretched core, however long, below
//!    a compact core in the same column), **vehicle** lights (two similar cores side by side below the
//!    horizon, when the horizon row is known) and lens **ghosts** (a faint core
//!    point-symmetric to a much brighter one about the principal point).
//!
//! Every threshold is a named constant with its unit and reason; the geometric ones are in
//! units of the core's own radius, so the rules hold at any resolution.

use super::{DetectorConfig, ImagingError, LampDetection, LampDetector, Mask, Threshold};
use image::GrayImage;

/// Fraction of the image's white level (largest value) above which a pixel belongs to a
/// core. Labelled lamp heads on three real night photos peak at 249–255 DN of 255; lit
/// windows, pavement and bloom mostly stay below (unitless).
pub const CORE_FRACTION: f64 = 0.92;

/// Smallest core level above the image's median (DN): a frame whose brightest pixel is
/// barely above its background has no lamp.
pub const MIN_CORE_CONTRAST_DN: f64 = 40.0;

/// A core within this many radii (of the larger core) of a larger core's bounding box is part
/// of its bloom or star-burst and is merged into it (unitless; bloom around a saturated head
/// reaches 2–3 core radii on the labelled photos).
pub const HALO_RADII: f64 = 3.0;

/// Smallest merge distance (px): JPEG ringing splits tiny cores into neighbouring pieces.
pub const MIN_HALO_PX: f64 = 3.0;

/// A core near a larger one is merged only when the light between them never falls below
/// this fraction of the core level (unitless): a bloom fragment or a star-burst spike is
/// joined to its lamp by bright halo, two distinct lamps have darker sky between them.
pub const BRIDGE_FRACTION: f64 = 0.7;

/// A core with at most 1/this of the area of a larger core whose bloom holds it is a
/// fragment of that lamp (a broken star-burst spike, a JPEG-split piece of halo) whatever
/// lies between them (unitless): a distinct lamp that small beside a large one cannot be
/// told from a fragment at this resolution.
pub const FRAGMENT_AREA_RATIO: f64 = 8.0;

/// Inner radius of the local-background annulus (core radii), beyond most of the bloom.
pub const ANNULUS_INNER_RADII: f64 = 3.0;

/// Outer radius of the local-background annulus (core radii).
pub const ANNULUS_OUTER_RADII: f64 = 5.0;

/// Smallest annulus radii (px), so a one-pixel core still has a ring of background.
pub const MIN_ANNULUS_PX: (f64, f64) = (4.0, 8.0);

/// Smallest contrast of a core's peak over its local background, as a fraction of the
/// peak (unitless): a bright patch of a bright facade is not a lamp.
pub const MIN_LOCAL_CONTRAST: f64 = 0.7;

/// Largest major/minor axis ratio of a lamp head's core (unitless): heads are round or
/// short ellipses; light trails and lit edges are longer.
pub const MAX_ELONGATION: f64 = 2.0;

/// Fill ratio (area / bounding-box area) above which a core is rectangular (a disc fills
/// π/4 ≈ 0.785 of its box, a rectangle 1).
pub const WINDOW_FILL: f64 = 0.88;

/// Smallest core area (px) whose shape is judged (a core of a few pixels is a square
/// whatever it images).
pub const WINDOW_MIN_AREA: u32 = 6;

/// Fewest other rectangular cores of similar size aligned with a core for a grid of windows.
pub const WINDOW_GRID_MIN: usize = 2;

/// Largest size ratio of two cores of "similar size" (unitless).
pub const SIMILAR_SIZE: f64 = 2.0;

/// Elongation above which a vertically oriented core below a brighter one is a reflection.
pub const REFLECTION_ELONGATION: f64 = 1.6;

/// Largest column offset (core radii of the lamp) of a reflection below it.
pub const REFLECTION_COLUMN_RADII: f64 = 1.5;

/// A ghost's strength is at most this fraction of its lamp's (unitless).
pub const GHOST_STRENGTH_RATIO: f64 = 0.1;

/// Largest distance (px, plus one core radius of the lamp) between a ghost and the point
/// reflection of its lamp about the principal point.
pub const GHOST_TOLERANCE_PX: f64 = 4.0;

/// Largest horizontal gap between the two lights of a vehicle pair (core radii of the
/// larger): a car's lights are a few lamp widths apart, not a street apart.
pub const VEHICLE_PAIR_RADII: f64 = 12.0;

/// Largest row offset of the two lights of a vehicle pair (core radii of the larger).
pub const VEHICLE_ROW_RADII: f64 = 1.0;

/// Stride of the annulus sampling (px): enough samples for a median, bounded work.
const ANNULUS_STRIDE_TARGET: f64 = 24.0;

/// What a detected bright core is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LampClass {
    /// A lamp head.
    Lamp,
    /// A lit window (rectangular, in a grid).
    Window,
    /// A specular reflection of a lamp (on a wet road).
    Reflection,
    /// A vehicle's head- or taillight.
    Vehicle,
    /// A lens ghost of a bright lamp.
    Ghost,
}

impl LampClass {
    /// A short label (`lamp`, `window`, `reflection`, `vehicle`, `ghost`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Lamp => "lamp",
            Self::Window => "window",
            Self::Reflection => "reflection",
            Self::Vehicle => "vehicle",
            Self::Ghost => "ghost",
        }
    }
}

/// One bright core of a night street.
///
/// # Units
/// Pixels (`u` = column, `v` = row, integer = pixel centre) and DN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreetDetection {
    /// Sub-pixel column of the core's centroid.
    pub u: f64,
    /// Sub-pixel row of the core's centroid.
    pub v: f64,
    /// Core area (px), merged fragments included.
    pub area: u32,
    /// Equivalent core radius `√(area / π)` (px).
    pub radius_px: f64,
    /// Largest value (DN).
    pub peak: u8,
    /// Local background: the median of the annulus around the core (DN).
    pub background_dn: f64,
    /// Strength: the core's sum above its local background (DN).
    pub strength: f64,
    /// Major/minor axis ratio of the core (≥ 1).
    pub elongation: f64,
    /// What the core is.
    pub class: LampClass,
}

/// The outcome of [`StreetLampDetector::detect`].
#[derive(Clone, Debug, PartialEq, Default)]
pub struct StreetDetections {
    /// Lamp heads (class [`LampClass::Lamp`]).
    pub lamps: Vec<StreetDetection>,
    /// Cores of the other classes (windows, reflections, vehicle lights, ghosts).
    pub others: Vec<StreetDetection>,
    /// Cores rejected as implausible (low local contrast, too long).
    pub rejected: usize,
    /// The core level used: pixels above it are core pixels (DN).
    pub core_level: u8,
}

/// The night-street lamp detector (see the [module docs](self)).
///
/// # Example
/// ```
/// use vgps_camera::imaging::{LampClass, StreetLampDetector};
/// // A lamp (saturated disc, radius 3 px) with a dim halo on a textured street.
/// let image = image::GrayImage::from_fn(120, 90, |x, y| {
///     let d2 = (x as f64 - 60.0).powi(2) + (y as f64 - 30.0).powi(2);
///     let texture = ((x * 7 + y * 13) % 23) as f64 * 2.0;
///     let halo = 150.0 * (-d2 / 50.0).exp();
///     image::Luma([if d2 <= 9.0 { 255 } else { (texture + halo).min(200.0) as u8 }])
/// });
/// let found = StreetLampDetector::default().detect(&image)?;
/// assert_eq!(found.lamps.len(), 1);
/// let lamp = found.lamps[0];
/// assert!((lamp.u - 60.0).abs() < 0.1 && (lamp.v - 30.0).abs() < 0.1);
/// assert_eq!(lamp.class, LampClass::Lamp);
/// # Ok::<(), vgps_camera::imaging::ImagingError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct StreetLampDetector {
    /// Row of the horizon of a level rig (px), when known: vehicle lights are told from
    /// lamps only below it.
    pub horizon_v: Option<f64>,
    /// Principal point `(u, v)` (px) for the ghost test; the image centre when `None`.
    pub principal_point: Option<(f64, f64)>,
}

/// A core during classification.
#[derive(Clone, Copy, Debug)]
struct Core {
    d: LampDetection,
    radius: f64,
    fill: f64,
    vertical: bool,
    merged: bool,
}

impl StreetLampDetector {
    /// Detects and classifies the bright cores of `image`.
    ///
    /// # Errors
    /// [`ImagingError::TooManyRuns`] when the frame is flooded (more core runs than the
    /// component labelling's bound).
    pub fn detect(&self, image: &GrayImage) -> Result<StreetDetections, ImagingError> {
        self.detect_masked(image, None)
    }

    /// Detects and classifies the bright cores of `image`, ignoring the pixels of `mask`
    /// (the vehicle's body, the mount): masked pixels are no core, and count neither in the
    /// white level, the median nor a core's local background.
    ///
    /// # Errors
    /// [`ImagingError::MaskDimensions`] when the mask's size differs from the image's;
    /// [`ImagingError::TooManyRuns`] when the frame is flooded.
    pub fn detect_masked(
        &self,
        image: &GrayImage,
        mask: Option<&Mask>,
    ) -> Result<StreetDetections, ImagingError> {
        let (w, h) = image.dimensions();
        if let Some(m) = mask
            && m.dimensions() != (w, h)
        {
            let (mask_width, mask_height) = m.dimensions();
            return Err(ImagingError::MaskDimensions {
                mask_width,
                mask_height,
                width: w,
                height: h,
            });
        }
        let pixels = image.as_raw();
        if pixels.is_empty() {
            return Ok(StreetDetections::default());
        }
        let white = match mask {
            None => pixels
                .chunks(64)
                .map(|c| c.iter().fold(0u8, |a, &b| a.max(b)))
                .fold(0u8, u8::max),
            Some(m) => image
                .enumerate_pixels()
                .filter(|(x, y, _)| !m.is_masked(*x, *y))
                .fold(0u8, |a, (_, _, p)| a.max(p[0])),
        };
        let median = median_of_rows(image, mask);
        let level = (CORE_FRACTION * f64::from(white)).max(median + MIN_CORE_CONTRAST_DN);
        if !(level < 255.0) {
            // Nothing can be above the level.
            return Ok(StreetDetections {
                core_level: 255,
                ..StreetDetections::default()
            });
        }
        // Pixels strictly above `threshold` are core pixels: value ≥ ceil(level).
        let threshold = (level.ceil() as u8).saturating_sub(1);
        let labelling = LampDetector::new(DetectorConfig {
            threshold: Threshold::Fixed(threshold),
            min_area: 1,
            max_area: u32::MAX,
            max_elongation: f64::INFINITY,
            ..DetectorConfig::default()
        });
        let found = labelling.detect(image, mask)?;
        let mut cores: Vec<Core> = found
            .lamps
            .iter()
            .map(|&d| {
                let [u0, v0, u1, v1] = d.bbox;
                let (bw, bh) = (f64::from(u1 - u0 + 1), f64::from(v1 - v0 + 1));
                Core {
                    d,
                    radius: (f64::from(d.area) / std::f64::consts::PI).sqrt(),
                    fill: f64::from(d.area) / (bw * bh),
                    vertical: bh > bw,
                    merged: false,
                }
            })
            .collect();
        // Largest first: fragments merge into the largest core whose bloom holds them.
        cores.sort_by_key(|c| std::cmp::Reverse(c.d.area));
        for i in 0..cores.len() {
            if cores[i].merged {
                continue;
            }
            // The bloom scales with the core's width: its minor radius √(area / (π · e)).
            let minor = cores[i].radius / cores[i].d.elongation.max(1.0).sqrt();
            let reach = (HALO_RADII * minor).max(MIN_HALO_PX);
            for j in i + 1..cores.len() {
                if cores[j].merged {
                    continue;
                }
                let fragment =
                    f64::from(cores[i].d.area) >= FRAGMENT_AREA_RATIO * f64::from(cores[j].d.area);
                if box_distance(&cores[i].d.bbox, cores[j].d.u, cores[j].d.v) <= reach
                    && (fragment
                        || bridge_min(
                            image,
                            (cores[i].d.u, cores[i].d.v),
                            (cores[j].d.u, cores[j].d.v),
                        ) >= BRIDGE_FRACTION * level)
                {
                    cores[j].merged = true;
                    cores[i].d.area += cores[j].d.area;
                    cores[i].d.peak = cores[i].d.peak.max(cores[j].d.peak);
                }
            }
        }
        let mut kept: Vec<StreetDetection> = Vec::new();
        let mut shapes: Vec<Core> = Vec::new();
        let mut rejected = 0;
        for c in cores.iter().filter(|c| !c.merged) {
            let background = annulus_median(image, mask, c.d.u, c.d.v, c.radius);
            let peak = f64::from(c.d.peak);
            if !(peak - background >= MIN_LOCAL_CONTRAST * peak) {
                rejected += 1;
                continue;
            }
            let strength = c.d.strength + (found.background_dn - background) * f64::from(c.d.area);
            kept.push(StreetDetection {
                u: c.d.u,
                v: c.d.v,
                area: c.d.area,
                radius_px: (f64::from(c.d.area) / std::f64::consts::PI).sqrt(),
                peak: c.d.peak,
                background_dn: background,
                strength,
                elongation: c.d.elongation,
                class: LampClass::Lamp,
            });
            shapes.push(*c);
        }
        let principal = self.principal_point.unwrap_or((
            f64::from(w.saturating_sub(1)) / 2.0,
            f64::from(h.saturating_sub(1)) / 2.0,
        ));
        let classes: Vec<Option<LampClass>> = (0..kept.len())
            .map(|i| self.classify(i, &kept, &shapes, principal))
            .collect();
        rejected += classes.iter().filter(|c| c.is_none()).count();
        let mut out = StreetDetections {
            rejected,
            core_level: threshold.saturating_add(1),
            ..StreetDetections::default()
        };
        for (mut d, class) in kept.into_iter().zip(classes) {
            let Some(class) = class else { continue };
            d.class = class;
            if class == LampClass::Lamp {
                out.lamps.push(d);
            } else {
                out.others.push(d);
            }
        }
        // Raster order of the centroids, as the renderer's detector.
        out.lamps
            .sort_by(|a, b| a.v.total_cmp(&b.v).then(a.u.total_cmp(&b.u)));
        out.others
            .sort_by(|a, b| a.v.total_cmp(&b.v).then(a.u.total_cmp(&b.u)));
        Ok(out)
    }

    /// The class of core `i`, or `None` for a core too long to be a lamp head that is no
    /// reflection either.
    fn classify(
        &self,
        i: usize,
        kept: &[StreetDetection],
        shapes: &[Core],
        principal: (f64, f64),
    ) -> Option<LampClass> {
        let me = &kept[i];
        let compact = |k: usize| kept[k].elongation <= MAX_ELONGATION;
        let similar = |a: &StreetDetection, b: &StreetDetection| {
            let ratio = a.radius_px.max(b.radius_px) / a.radius_px.min(b.radius_px).max(0.5);
            ratio <= SIMILAR_SIZE
        };
        // Reflection: stretched vertically, below a lamp-like core in the same column (a
        // wet road's reflection may be larger than the lamp head itself).
        if shapes[i].vertical
            && me.elongation >= REFLECTION_ELONGATION
            && (0..kept.len()).any(|k| {
                let o = &kept[k];
                k != i
                    && compact(k)
                    && o.v < me.v
                    && (o.u - me.u).abs() <= REFLECTION_COLUMN_RADII * o.radius_px.max(1.0)
            })
        {
            return Some(LampClass::Reflection);
        }
        if !compact(i) {
            return None;
        }
        // Ghost: a faint core at the point reflection of a much stronger one.
        let mirror = (2.0 * principal.0 - me.u, 2.0 * principal.1 - me.v);
        if (0..kept.len()).any(|k| {
            let o = &kept[k];
            k != i
                && compact(k)
                && o.strength > 0.0
                && me.strength < GHOST_STRENGTH_RATIO * o.strength
                && (o.u - mirror.0).hypot(o.v - mirror.1) <= GHOST_TOLERANCE_PX + o.radius_px
        }) {
            return Some(LampClass::Ghost);
        }
        // Window: rectangular and aligned with similar rectangular cores.
        let rectangular =
            |k: usize| shapes[k].fill >= WINDOW_FILL && shapes[k].d.area >= WINDOW_MIN_AREA;
        if rectangular(i) {
            let aligned = (0..kept.len())
                .filter(|&k| k != i && rectangular(k) && similar(me, &kept[k]))
                .filter(|&k| {
                    let o = &kept[k];
                    let tol = me.radius_px.max(o.radius_px);
                    (o.v - me.v).abs() <= tol || (o.u - me.u).abs() <= tol
                })
                .count();
            if aligned >= WINDOW_GRID_MIN {
                return Some(LampClass::Window);
            }
        }
        // Vehicle: a pair of similar cores side by side, below the horizon.
        if let Some(horizon) = self.horizon_v
            && me.v > horizon
            && (0..kept.len()).any(|k| {
                let o = &kept[k];
                let r = me.radius_px.max(o.radius_px).max(1.0);
                k != i
                    && compact(k)
                    && o.v > horizon
                    && similar(me, o)
                    && (o.v - me.v).abs() <= VEHICLE_ROW_RADII * r
                    && (o.u - me.u).abs() <= VEHICLE_PAIR_RADII * r
            })
        {
            return Some(LampClass::Vehicle);
        }
        Some(LampClass::Lamp)
    }
}

/// Distance (px) from `(u, v)` to the pixel box `[u0, v0, u1, v1]` (0 inside).
fn box_distance(bbox: &[u32; 4], u: f64, v: f64) -> f64 {
    let gap = |x: f64, lo: u32, hi: u32| (f64::from(lo) - x).max(x - f64::from(hi)).max(0.0);
    gap(u, bbox[0], bbox[2]).hypot(gap(v, bbox[1], bbox[3]))
}

/// The smallest value on the segment from `a` to `b` (sampled every pixel).
fn bridge_min(image: &GrayImage, a: (f64, f64), b: (f64, f64)) -> f64 {
    let steps = (b.0 - a.0).hypot(b.1 - a.1).ceil().max(1.0) as usize;
    let mut low = f64::INFINITY;
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        let (x, y) = (x.round(), y.round());
        if x >= 0.0 && y >= 0.0 && x < f64::from(image.width()) && y < f64::from(image.height()) {
            low = low.min(f64::from(image.get_pixel(x as u32, y as u32)[0]));
        }
    }
    low
}

/// The median of the image's unmasked pixels (DN), from a histogram of every 8th row.
fn median_of_rows(image: &GrayImage, mask: Option<&Mask>) -> f64 {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let pixels = image.as_raw();
    let mut hist = [0u32; 256];
    let mut n = 0u64;
    for y in (0..h).step_by(8) {
        for (x, &p) in pixels[y * w..(y + 1) * w].iter().enumerate() {
            if mask.is_some_and(|m| m.is_masked(x as u32, y as u32)) {
                continue;
            }
            hist[p as usize] += 1;
            n += 1;
        }
    }
    let mut seen = 0u64;
    for (value, &count) in hist.iter().enumerate() {
        seen += u64::from(count);
        if 2 * seen >= n {
            return value as f64;
        }
    }
    0.0
}

/// The median of the pixels in the annulus around `(u, v)` for a core of `radius` px,
/// sampled on a grid of about [`ANNULUS_STRIDE_TARGET`]² points over its bounding square.
fn annulus_median(image: &GrayImage, mask: Option<&Mask>, u: f64, v: f64, radius: f64) -> f64 {
    let inner = (ANNULUS_INNER_RADII * radius).max(MIN_ANNULUS_PX.0);
    let outer = (ANNULUS_OUTER_RADII * radius).max(MIN_ANNULUS_PX.1);
    let step = ((2.0 * outer / ANNULUS_STRIDE_TARGET).floor() as i64).max(1);
    let (w, h) = (i64::from(image.width()), i64::from(image.height()));
    let (cu, cv) = (u.round() as i64, v.round() as i64);
    let reach = outer.ceil() as i64;
    let mut hist = [0u32; 256];
    let mut n = 0u32;
    let mut dy = -reach;
    while dy <= reach {
        let y = cv + dy;
        if (0..h).contains(&y) {
            let mut dx = -reach;
            while dx <= reach {
                let x = cu + dx;
                let d = ((dx * dx + dy * dy) as f64).sqrt();
                if (0..w).contains(&x)
                    && d >= inner
                    && d <= outer
                    && !mask.is_some_and(|m| m.is_masked(x as u32, y as u32))
                {
                    hist[image.get_pixel(x as u32, y as u32)[0] as usize] += 1;
                    n += 1;
                }
                dx += step;
            }
        }
        dy += step;
    }
    if n == 0 {
        return 0.0;
    }
    let mut seen = 0u32;
    for (value, &count) in hist.iter().enumerate() {
        seen += count;
        if 2 * seen >= n {
            return value as f64;
        }
    }
    0.0
}
