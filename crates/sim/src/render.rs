//! Rendering of night frames: lamps and clutter lights on a dark, noisy background, through a
//! calibrated camera model (with its distortion).
//!
//! # Model
//! - **Background**: a flat level [`RenderOptions::background_dn`] plus Gaussian read noise
//!   of standard deviation [`RenderOptions::read_noise_dn`], quantised to 8 bits. The noise is
//!   precomputed once per [`Renderer`] in a tile of [`NOISE_TILE_LEN`] samples; each image row
//!   copies [`width`](vgps_camera::calibration::CameraModel::image_size) samples from an offset
//!   given by a hash of `(seed, row)`, so an image costs one `memcpy` per row, not one random
//!   draw per pixel.
//! - **Lamp**: a sphere of radius `radius_m` at range `r` subtends the angular radius
//!   `α = asin(radius_m / r)`; it is modelled as a Gaussian in angle with per-axis standard
//!   deviation `α / 2` (the second moment of a uniform disc), mapped to pixels by the
//!   Jacobian `J = d pixel / d bearing` of the camera model at the lamp's bearing. The blob's
//!   pixel covariance is `Σ = (α/2)² J Jᵀ + (σ_psf² + 1/12) I`: the optics' point-spread
//!   function and the integration over the pixel's area (a unit box of variance 1/12 px² per
//!   axis, matched in its first two moments). Its total signal is
//!   `flux = flux_scale · intensity / r²` DN, its centre the projection of the lamp centre
//!   ([`CameraModel::try_pixel_with_jacobian`]), and its profile is point-symmetric about
//!   that centre, so an unbiased centroid recovers it.
//! - **Shot noise**: a signal of `s` DN gets Gaussian noise of variance `s / gain`, drawn from
//!   a counter-based hash of `(seed, pixel)` (only the few signal pixels pay for it), plus a
//!   uniform dither before quantisation. Values saturate at 255.
//! - **Clutter**: [`RenderOptions::clutter_lights`] elongated Gaussian spots at uniformly
//!   random pixels (windows, signs, car lights): real bright spots that are not lamps.
//!
//! Rendering is deterministic for a seed.

// `!(x < limit)` is used on purpose: it rejects NaN along with out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use image::GrayImage;
use nalgebra::{Matrix2, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use vgps_camera::calibration::{Camera, CameraModel};

/// Number of samples of the precomputed read-noise tile (the noise pattern of a row is a
/// window of the tile at a hashed offset).
pub const NOISE_TILE_LEN: usize = 1 << 16;

/// Seed of the read-noise tile (fixed: the tile is part of the renderer, the per-image seed
/// chooses the offsets).
const NOISE_TILE_SEED: u64 = 0x6e69_6768_745f_7678;

/// Lamps closer than this (metres) are not rendered (the camera is inside or touching them).
pub const MIN_LAMP_RANGE_M: f64 = 0.5;

/// A blob is drawn out to where its signal falls below this many DN.
const MIN_DRAWN_SIGNAL_DN: f64 = 0.05;

/// A blob is drawn at least this many standard deviations from its centre.
const MIN_DRAWN_SIGMAS: f64 = 3.0;

/// Largest half-size (pixels) of a drawn blob window (bounds the work of a lamp touching the
/// lens).
const MAX_BLOB_HALF_SIZE_PX: f64 = 200.0;

/// Variance (px²) of a unit box: the pixel-area integration, per axis.
const PIXEL_BOX_VARIANCE: f64 = 1.0 / 12.0;

/// Largest 8-bit value.
const SATURATION_DN: f64 = 255.0;

/// A light in the scene of one camera.
///
/// # Units
/// `point_in_camera` and `radius_m` in metres (camera frame: x right, y down, z forward);
/// `intensity` is relative (1 = a typical street lamp, see [`RenderOptions::flux_scale`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSource {
    /// The lamp's centre in the camera frame (metres).
    pub point_in_camera: Vector3<f64>,
    /// The radius of the lamp's glowing part (metres).
    pub radius_m: f64,
    /// Relative luminous intensity (1 = typical street lamp).
    pub intensity: f64,
}

/// Parameters of the night-scene renderer. [`Default`] is a dark street with a typical
/// low-light camera: background 6 DN, read noise 1 DN, a unit-intensity lamp peaking at
/// ≈ 70 DN above background at 80 m with a Ladybug2-like lens.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Mean background level (DN).
    pub background_dn: f64,
    /// Standard deviation of the read noise (DN).
    pub read_noise_dn: f64,
    /// Sensor gain (electrons per DN): a signal of `s` DN has shot-noise variance `s / gain`
    /// DN². Zero or negative disables shot noise.
    pub gain_e_per_dn: f64,
    /// Total signal (DN) of a unit-intensity lamp at 1 m: a lamp's flux is
    /// `flux_scale · intensity / range²`.
    pub flux_scale: f64,
    /// Standard deviation of the optics' point-spread function (pixels).
    pub psf_sigma_px: f64,
    /// Number of clutter lights per image.
    pub clutter_lights: usize,
    /// Range of a clutter light's total signal (DN), drawn log-uniformly.
    pub clutter_flux_dn: (f64, f64),
    /// Range of a clutter light's major-axis standard deviation (pixels), drawn uniformly.
    pub clutter_sigma_px: (f64, f64),
    /// Largest major/minor axis ratio of a clutter light, drawn uniformly from `[1, max]`.
    pub clutter_max_aspect: f64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            background_dn: 6.0,
            read_noise_dn: 1.0,
            gain_e_per_dn: 4.0,
            flux_scale: 2.5e6,
            psf_sigma_px: 0.7,
            clutter_lights: 0,
            clutter_flux_dn: (200.0, 5000.0),
            clutter_sigma_px: (0.8, 4.0),
            clutter_max_aspect: 3.0,
        }
    }
}

/// What a rendered spot is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpotKind {
    /// The lamp at this index of the `lights` slice.
    Lamp(usize),
    /// A clutter light (not a lamp).
    Clutter,
}

/// The ground truth of one rendered spot.
///
/// # Units
/// Pixels and DN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderedSpot {
    /// What the spot is.
    pub kind: SpotKind,
    /// Column of the true centre (pixel convention of vgps).
    pub u: f64,
    /// Row of the true centre.
    pub v: f64,
    /// Standard deviation along the blob's major axis (pixels).
    pub sigma_major_px: f64,
    /// Standard deviation along the blob's minor axis (pixels).
    pub sigma_minor_px: f64,
    /// Total signal (DN, before saturation).
    pub flux_dn: f64,
    /// Peak signal above background (DN, before saturation).
    pub peak_dn: f64,
    /// Range of the lamp (metres); `None` for clutter.
    pub range_m: Option<f64>,
    /// Whether the drawn window (≥ 3σ) was cut by the image border.
    pub clipped_by_border: bool,
}

/// A rendered image with the ground truth of its spots.
#[derive(Clone, Debug)]
pub struct RenderedFrame {
    /// The 8-bit image.
    pub image: GrayImage,
    /// Every drawn spot (lamps whose centre projects into the image, and clutter).
    pub spots: Vec<RenderedSpot>,
}

/// The night-scene renderer: [`RenderOptions`] and the precomputed read-noise tile.
/// `Send + Sync`; render many images with one renderer.
#[derive(Clone, Debug)]
pub struct Renderer {
    options: RenderOptions,
    noise_tile: Vec<u8>,
}

impl Renderer {
    /// A renderer (computes the noise tile: ≈ 1 ms).
    pub fn new(options: RenderOptions) -> Self {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(NOISE_TILE_SEED);
        let noise_tile = (0..NOISE_TILE_LEN)
            .map(|_| {
                let n: f64 =
                    rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                quantise(options.background_dn + options.read_noise_dn * n)
            })
            .collect();
        Self {
            options,
            noise_tile,
        }
    }

    /// The options.
    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Renders the night image of `camera` seeing `lights`, deterministic for `seed`.
    ///
    /// Lamps behind the camera, outside its image, closer than [`MIN_LAMP_RANGE_M`] or with
    /// non-finite or non-positive parameters are not drawn.
    pub fn render(&self, camera: &Camera, lights: &[LightSource], seed: u64) -> RenderedFrame {
        let (width, height) = camera.image_size();
        let (w, h) = (width as usize, height as usize);
        let mut pixels = vec![0u8; w * h];
        let span = NOISE_TILE_LEN.saturating_sub(w).max(1) as u64;
        for (row, out) in pixels.chunks_exact_mut(w.max(1)).enumerate() {
            let offset = (splitmix64(seed ^ splitmix64(row as u64)) % span) as usize;
            let n = out.len().min(self.noise_tile.len() - offset);
            out[..n].copy_from_slice(&self.noise_tile[offset..offset + n]);
        }
        let mut canvas = Exposure {
            pixels: &mut pixels,
            width: w,
            height: h,
            seed,
            gain: self.options.gain_e_per_dn,
        };
        let mut spots = Vec::new();
        for (index, light) in lights.iter().enumerate() {
            if let Some(blob) = self.lamp_blob(camera, light) {
                spots.push(canvas.draw(&blob, SpotKind::Lamp(index), Some(blob.range)));
            }
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(splitmix64(seed ^ CLUTTER_SALT));
        for _ in 0..self.options.clutter_lights {
            let blob = self.clutter_blob(&mut rng, width, height);
            spots.push(canvas.draw(&blob, SpotKind::Clutter, None));
        }
        let image = GrayImage::from_raw(width, height, pixels)
            .unwrap_or_else(|| unreachable!("the buffer has width × height bytes"));
        RenderedFrame { image, spots }
    }

    /// The pixel blob of `light` (see the module's model); `None` when it is not drawn.
    pub(crate) fn lamp_blob(&self, camera: &Camera, light: &LightSource) -> Option<Blob> {
        let p = light.point_in_camera;
        let range = p.norm();
        let valid_range = range >= MIN_LAMP_RANGE_M && range.is_finite();
        let valid_radius = light.radius_m >= 0.0 && light.radius_m < range;
        let valid_intensity = light.intensity > 0.0 && light.intensity.is_finite();
        if !(valid_range && valid_radius && valid_intensity) {
            return None;
        }
        let bearing = p / range;
        let (centre, jacobian) = camera.try_pixel_with_jacobian(&bearing)?;
        let alpha = (light.radius_m / range).asin();
        let s = alpha / 2.0;
        let isotropic = self.options.psf_sigma_px.powi(2) + PIXEL_BOX_VARIANCE;
        let covariance =
            (jacobian * jacobian.transpose()) * (s * s) + Matrix2::identity() * isotropic;
        let flux = self.options.flux_scale * light.intensity / (range * range);
        Blob::new(centre, covariance, flux, range)
    }

    fn clutter_blob<R: rand::Rng + ?Sized>(&self, rng: &mut R, width: u32, height: u32) -> Blob {
        let o = &self.options;
        let u = rng.random_range(0.0..1.0) * width as f64 - 0.5;
        let v = rng.random_range(0.0..1.0) * height as f64 - 0.5;
        let (f0, f1) = (o.clutter_flux_dn.0.max(1e-3), o.clutter_flux_dn.1.max(1e-3));
        let flux = (f0.ln() + rng.random_range(0.0..1.0) * (f1.ln() - f0.ln())).exp();
        let (s0, s1) = o.clutter_sigma_px;
        let major = (s0 + rng.random_range(0.0..1.0) * (s1 - s0)).max(0.3);
        let aspect = 1.0 + rng.random_range(0.0..1.0) * (o.clutter_max_aspect - 1.0).max(0.0);
        let minor = major / aspect;
        let angle = rng.random_range(0.0..std::f64::consts::PI);
        let (sn, cs) = angle.sin_cos();
        let r = Matrix2::new(cs, -sn, sn, cs);
        let covariance = r * Matrix2::new(major * major, 0.0, 0.0, minor * minor) * r.transpose()
            + Matrix2::identity() * PIXEL_BOX_VARIANCE;
        Blob::new(Vector2::new(u, v), covariance, flux, 0.0)
            .unwrap_or_else(|| unreachable!("clutter covariance is positive definite"))
    }
}

/// Salt of the clutter generator's seed.
const CLUTTER_SALT: u64 = 0xc1u64 << 56;

/// Renders the night image of `camera` seeing `lights` (see [`Renderer::render`]). Builds a
/// [`Renderer`] per call: to render many images, keep one [`Renderer`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use vgps_sim::render::{LightSource, RenderOptions, render_camera};
/// let camera = vgps_camera::calibration::Camera::from(vgps_camera::synthetic::calibration_files::ladybug2_lens());
/// let lamp = LightSource { point_in_camera: Vector3::new(0.0, 0.0, 20.0), radius_m: 0.15, intensity: 1.0 };
/// let image = render_camera(&camera, &[lamp], &RenderOptions::default(), 1);
/// assert_eq!(image.dimensions(), (1024, 768));
/// // The lamp on the optical axis is bright at the principal point (511.5, 383.5).
/// assert!(image.get_pixel(511, 383)[0] > 150);
/// assert!(image.get_pixel(100, 100)[0] < 20);
/// ```
pub fn render_camera(
    camera: &Camera,
    lights: &[LightSource],
    options: &RenderOptions,
    seed: u64,
) -> GrayImage {
    Renderer::new(options.clone())
        .render(camera, lights, seed)
        .image
}

/// A Gaussian blob in pixel space.
#[derive(Clone, Debug)]
pub(crate) struct Blob {
    /// Centre (pixels).
    pub(crate) centre: Vector2<f64>,
    /// Covariance (px²).
    pub(crate) covariance: Matrix2<f64>,
    /// Inverse covariance entries (a, b, c): q = a du² + 2 b du dv + c dv².
    inverse: (f64, f64, f64),
    half_u: f64,
    half_v: f64,
    /// Peak signal (DN).
    pub(crate) peak: f64,
    /// Total signal (DN).
    pub(crate) flux: f64,
    sigma_major: f64,
    sigma_minor: f64,
    /// Range of its light (metres; 0 for a spot without one).
    pub(crate) range: f64,
}

impl Blob {
    /// A blob; `None` for a covariance that is not positive definite, a non-finite centre or
    /// a non-positive flux.
    pub(crate) fn new(
        centre: Vector2<f64>,
        covariance: Matrix2<f64>,
        flux: f64,
        range: f64,
    ) -> Option<Self> {
        let det = covariance.determinant();
        if !(det > 0.0) || !centre.iter().all(|x| x.is_finite()) || !(flux > 0.0) {
            return None;
        }
        let (suu, suv, svv) = (covariance[(0, 0)], covariance[(0, 1)], covariance[(1, 1)]);
        let peak = flux / (std::f64::consts::TAU * det.sqrt());
        let k = (2.0 * (peak / MIN_DRAWN_SIGNAL_DN).max(1.0).ln())
            .sqrt()
            .max(MIN_DRAWN_SIGMAS);
        let half_mean = 0.5 * (suu + svv);
        let spread = (0.25 * (suu - svv).powi(2) + suv * suv).sqrt();
        Some(Self {
            centre,
            covariance,
            inverse: (svv / det, -suv / det, suu / det),
            half_u: (k * suu.sqrt()).min(MAX_BLOB_HALF_SIZE_PX),
            half_v: (k * svv.sqrt()).min(MAX_BLOB_HALF_SIZE_PX),
            peak,
            flux,
            sigma_major: (half_mean + spread).sqrt(),
            sigma_minor: (half_mean - spread).max(0.0).sqrt(),
            range,
        })
    }
}

impl Blob {
    /// The pixel window drawn (columns `u0..=u1`, rows `v0..=v1`; `None` when it misses the
    /// image) and whether the image border cut it.
    fn window(&self, width: usize, height: usize) -> (Option<(usize, usize, usize, usize)>, bool) {
        let (cu, cv) = (self.centre.x, self.centre.y);
        let (w, h) = (width as f64, height as f64);
        let u0 = (cu - self.half_u).ceil();
        let u1 = (cu + self.half_u).floor();
        let v0 = (cv - self.half_v).ceil();
        let v1 = (cv + self.half_v).floor();
        let clipped = u0 < 0.0 || v0 < 0.0 || u1 > w - 1.0 || v1 > h - 1.0;
        let (u0, u1) = (u0.max(0.0), u1.min(w - 1.0));
        let (v0, v1) = (v0.max(0.0), v1.min(h - 1.0));
        let inside = u0 <= u1 && v0 <= v1;
        let window = inside.then_some((u0 as usize, u1 as usize, v0 as usize, v1 as usize));
        (window, clipped)
    }

    /// The noiseless signal (DN) at the pixel centre `(col, row)`.
    fn signal(&self, col: usize, row: usize) -> f64 {
        let (du, dv) = (col as f64 - self.centre.x, row as f64 - self.centre.y);
        let (a, b, c) = self.inverse;
        let q = a * du * du + 2.0 * b * du * dv + c * dv * dv;
        self.peak * (-0.5 * q).exp()
    }

    /// Adds the blob's noiseless signal to a `width × height` radiance buffer (the realistic
    /// night renderer adds the sensor's noise to the sum); returns whether the border cut it.
    pub(crate) fn add_to(&self, radiance: &mut [f32], width: usize, height: usize) -> bool {
        let (window, clipped) = self.window(width, height);
        if let Some((u0, u1, v0, v1)) = window
            && radiance.len() >= width * height
        {
            for row in v0..=v1 {
                let line = &mut radiance[row * width..(row + 1) * width];
                for (col, p) in line.iter_mut().enumerate().take(u1 + 1).skip(u0) {
                    let s = self.signal(col, row);
                    if s >= MIN_DRAWN_SIGNAL_DN {
                        *p += s as f32;
                    }
                }
            }
        }
        clipped
    }

    /// The truth row of the blob.
    pub(crate) fn spot(&self, kind: SpotKind, range: Option<f64>, clipped: bool) -> RenderedSpot {
        RenderedSpot {
            kind,
            u: self.centre.x,
            v: self.centre.y,
            sigma_major_px: self.sigma_major,
            sigma_minor_px: self.sigma_minor,
            flux_dn: self.flux,
            peak_dn: self.peak,
            range_m: range.filter(|_| self.range > 0.0),
            clipped_by_border: clipped,
        }
    }
}

struct Exposure<'a> {
    pixels: &'a mut [u8],
    width: usize,
    height: usize,
    seed: u64,
    gain: f64,
}

impl Exposure<'_> {
    fn draw(&mut self, blob: &Blob, kind: SpotKind, range: Option<f64>) -> RenderedSpot {
        let (cu, cv) = (blob.centre.x, blob.centre.y);
        let (window, clipped_by_border) = blob.window(self.width, self.height);
        let shot = self.gain > 0.0;
        let inv_gain = if shot { 1.0 / self.gain } else { 0.0 };
        if let Some((u0, u1, v0, v1)) = window {
            for row in v0..=v1 {
                let line = &mut self.pixels[row * self.width..(row + 1) * self.width];
                for (col, p) in line.iter_mut().enumerate().take(u1 + 1).skip(u0) {
                    let s = blob.signal(col, row);
                    if s < MIN_DRAWN_SIGNAL_DN {
                        continue;
                    }
                    let key = self.seed ^ ((row as u64) << 32 | col as u64);
                    let h = splitmix64(key ^ splitmix64(blob_salt(cu, cv)));
                    let noise = if shot {
                        (s * inv_gain).sqrt() * approx_normal(h)
                    } else {
                        0.0
                    };
                    let dither = (h >> 40) as f64 / (1u64 << 24) as f64;
                    let value = *p as f64 + s + noise + dither;
                    *p = value.floor().clamp(0.0, SATURATION_DN) as u8;
                }
            }
        }
        blob.spot(kind, range, clipped_by_border)
    }
}

/// A per-blob salt so overlapping blobs draw independent noise.
fn blob_salt(u: f64, v: f64) -> u64 {
    u.to_bits() ^ v.to_bits().rotate_left(17)
}

/// Rounds and clamps to 8 bits.
fn quantise(x: f64) -> u8 {
    x.round().clamp(0.0, SATURATION_DN) as u8
}

/// SplitMix64: a fast, well-mixed 64-bit hash (the counter-based noise source).
pub(crate) fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An approximately standard normal sample from a hash: the sum of four 10-bit uniforms
/// (Irwin–Hall), centred and scaled to unit variance (the low 40 bits; the high 24 bits are
/// left for the dither).
pub(crate) fn approx_normal(h: u64) -> f64 {
    const SCALE: f64 = 1024.0;
    let sum = (h & 0x3ff) + ((h >> 10) & 0x3ff) + ((h >> 20) & 0x3ff) + ((h >> 30) & 0x3ff);
    // Four uniforms on [0, 1): mean 2, variance 4/12.
    ((sum as f64 + 2.0) / SCALE - 2.0) * 3f64.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use vgps_camera::synthetic::calibration_files::ladybug2_lens;

    fn camera() -> Camera {
        Camera::from(ladybug2_lens())
    }

    #[test]
    fn background_has_the_configured_level_and_noise() {
        let r = Renderer::new(RenderOptions::default());
        let image = r.render(&camera(), &[], 3).image;
        let n = image.as_raw().len() as f64;
        let mean = image.as_raw().iter().map(|&p| p as f64).sum::<f64>() / n;
        let var = image
            .as_raw()
            .iter()
            .map(|&p| (p as f64 - mean).powi(2))
            .sum::<f64>()
            / n;
        assert!((mean - 6.0).abs() < 0.05, "mean {mean}");
        // Read noise 1 DN plus the quantisation's 1/12 DN².
        assert!((var - (1.0 + 1.0 / 12.0)).abs() < 0.1, "variance {var}");
    }

    #[test]
    fn deterministic_for_a_seed_and_different_across_seeds() {
        let r = Renderer::new(RenderOptions {
            clutter_lights: 5,
            ..RenderOptions::default()
        });
        let lamp = LightSource {
            point_in_camera: Vector3::new(2.0, 1.0, 15.0),
            radius_m: 0.2,
            intensity: 1.0,
        };
        let a = r.render(&camera(), &[lamp], 11);
        let b = r.render(&camera(), &[lamp], 11);
        let c = r.render(&camera(), &[lamp], 12);
        assert_eq!(a.image, b.image);
        assert_eq!(a.spots, b.spots);
        assert_ne!(a.image, c.image);
        assert_eq!(a.spots.len(), 6);
    }

    #[test]
    fn blob_flux_and_centre_match_the_truth() {
        // No noise, no shot noise: the background-subtracted sum is the flux and the
        // intensity-weighted centroid is the projected lamp centre.
        let options = RenderOptions {
            read_noise_dn: 0.0,
            gain_e_per_dn: 0.0,
            flux_scale: 2.0e5,
            ..RenderOptions::default()
        };
        let lamp = LightSource {
            point_in_camera: Vector3::new(-4.0, 2.5, 30.0),
            radius_m: 0.15,
            intensity: 1.0,
        };
        let frame = Renderer::new(options).render(&camera(), &[lamp], 5);
        let truth = frame.spots[0];
        assert!(truth.peak_dn < 200.0, "unsaturated test blob");
        let (mut sum, mut su, mut sv) = (0.0, 0.0, 0.0);
        for (x, y, p) in frame.image.enumerate_pixels() {
            // Dither adds 0.5 DN on average to drawn pixels: subtract the background only.
            let s = p[0] as f64 - 6.0;
            if s > 0.0 {
                sum += s;
                su += s * x as f64;
                sv += s * y as f64;
            }
        }
        assert!(
            (sum - truth.flux_dn).abs() < 0.03 * truth.flux_dn + 40.0,
            "{sum} vs {}",
            truth.flux_dn
        );
        assert!(
            (su / sum - truth.u).abs() < 0.05,
            "u {} vs {}",
            su / sum,
            truth.u
        );
        assert!(
            (sv / sum - truth.v).abs() < 0.05,
            "v {} vs {}",
            sv / sum,
            truth.v
        );
    }

    #[test]
    fn lamps_behind_or_degenerate_are_not_drawn() {
        let r = Renderer::new(RenderOptions::default());
        let bad = [
            LightSource {
                point_in_camera: Vector3::new(0.0, 0.0, -10.0),
                radius_m: 0.1,
                intensity: 1.0,
            },
            LightSource {
                point_in_camera: Vector3::new(0.0, 0.0, 0.1),
                radius_m: 0.1,
                intensity: 1.0,
            },
            LightSource {
                point_in_camera: Vector3::new(0.0, 0.0, 10.0),
                radius_m: 0.1,
                intensity: f64::NAN,
            },
            LightSource {
                point_in_camera: Vector3::new(f64::INFINITY, 0.0, 10.0),
                radius_m: 0.1,
                intensity: 1.0,
            },
        ];
        let frame = r.render(&camera(), &bad, 1);
        assert!(frame.spots.is_empty());
        assert!(frame.image.as_raw().iter().all(|&p| p < 20));
    }

    #[test]
    fn brightness_falls_with_range_squared() {
        let r = Renderer::new(RenderOptions::default());
        let at = |z: f64| {
            let lamp = LightSource {
                point_in_camera: Vector3::new(0.0, 0.0, z),
                radius_m: 0.15,
                intensity: 1.0,
            };
            r.render(&camera(), &[lamp], 1).spots[0]
        };
        let (near, far) = (at(20.0), at(40.0));
        assert!((near.flux_dn / far.flux_dn - 4.0).abs() < 1e-9);
        assert!(near.sigma_major_px > far.sigma_major_px);
    }

    #[test]
    fn png_round_trip() {
        let frame = Renderer::new(RenderOptions::default()).render(&camera(), &[], 2);
        let bytes = vgps_camera::imaging::encode_png(&frame.image).unwrap();
        let back = vgps_camera::imaging::decode_png(
            &bytes,
            &vgps_camera::imaging::DecodeLimits::default(),
        )
        .unwrap();
        assert_eq!(back, frame.image);
    }
}
