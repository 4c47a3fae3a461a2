//! The realistic night renderer: the day scene's geometry ([`DayScene`]) at night, with the
//! street lamps and the clutter of a real night street (issue #24).
//!
//! # Model
//! - **Background**: the day renderer's ray cast ([`DayRenderer`]) with the sun below the
//!   horizon and night levels ([`NightOptions::default`]): a sky glow brighter at the
//!   horizon than at the zenith, facades and the street faintly lit by the sky (ambient
//!   light only), and a random share of the facades' window grid lit from inside
//!   ([`DayOptions::lit_window_share`]: warm, rectangular, the same windows in every frame).
//! - **Lamps**: the night renderer's Gaussian blobs ([`crate::render`]: size from the lamp's
//!   angular radius and the PSF, flux falling with the range squared), added to the
//!   radiance. A lamp whose peak saturates also gets a **bloom**: a wide, dim Gaussian of
//!   [`NightOptions::bloom_fraction`] of its flux, centred on it.
//! - **Wet-road reflections**: each lamp mirrored about the road plane `z = 0`, drawn where
//!   the line of sight to the mirror image meets the road (the roadway or a lane
//!   mark) and the pixel sees that road point; [`NightOptions::reflection_gain`] of the
//!   lamp's intensity, stretched along the image's vertical direction at that point by
//!   [`NightOptions::reflection_stretch`].
//! - **Cars**: a share [`NightOptions::car_light_share`] of the scene's cars shows a pair of
//!   headlights at one end and a pair of (red, so dim in luminance) taillights at the other,
//!   [`CAR_LIGHT_SPACING_M`] apart; a light is drawn when its face turns towards the camera
//!   and no surface hides it; headlights are brighter seen from ahead.
//! - **Optics and sensor**: vignetting (a radial falloff to `1 − vignetting` at the image
//!   corners), then the day renderer's sensor: shot noise, read noise, 8 bits.
//!
//! The truth ([`NightSpot`]) names every drawn lamp (with its index in the `lights` slice),
//! reflection (of which lamp), head- and taillight and every visible lit window (its pane's
//! centre, up to [`NightOptions::window_truth_range_m`]). Rendering is deterministic for a
//! seed.

// `!(x < limit)` is used on purpose: it rejects NaN along with out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::day::render::{DayOptions, DayRenderer, Traced, expose, window_light, windows_of};
use crate::day::scene::{BoxKind, DayScene, Ground, SceneBox, ground_at};
use crate::render::{Blob, LightSource, RenderOptions, Renderer, splitmix64};
use image::GrayImage;
use nalgebra::{Matrix2, Point3, Vector2, Vector3};
use vgps_camera::calibration::{CameraModel, Rig, in_image_rectangle};
use vgps_geometry::geometry::Pose;

/// Distance between the two lights of a pair (metres, centre to centre).
pub const CAR_LIGHT_SPACING_M: f64 = 1.3;
/// Height of a car's headlights and taillights above the road (metres).
const CAR_LIGHT_HEIGHT_M: (f64, f64) = (0.65, 0.9);
/// A light sits this far outside its car's face, so the face does not hide it (metres).
const CAR_LIGHT_OUTSET_M: f64 = 0.03;
/// A point is visible when the surface its pixel sees is no nearer than its range less
/// this (metres), or less [`DEPTH_MARGIN_SHARE`] of its range when that is more: a pixel
/// spans more depth far away and on grazing surfaces.
const DEPTH_MARGIN_M: f64 = 0.3;
/// See [`DEPTH_MARGIN_M`].
const DEPTH_MARGIN_SHARE: f64 = 0.05;

/// The depth tolerance at `range` (metres).
fn depth_margin(range: f64) -> f64 {
    DEPTH_MARGIN_M.max(DEPTH_MARGIN_SHARE * range)
}
/// Height drop used to find the image's vertical direction at a reflection (metres).
const VERTICAL_PROBE_M: f64 = 0.3;
/// Salt of the per-car light hash.
const CAR_SALT: u64 = 0x6361_725f_6c69_6768;

/// Parameters of the realistic night renderer. [`Default`]: a city night (sky 14 DN at the
/// horizon, 4 DN at the zenith; walls 3–10 DN; a quarter of the windows lit at 40–140 DN),
/// lamps four times as bright as the flat renderer's, bloom of 4 % of a saturated lamp's
/// flux, reflections at 60 % stretched 4×, lights on 40 % of the cars, 35 % vignetting at
/// the corners, gain 4 e⁻/DN and 1 DN read noise.
#[derive(Clone, Debug, PartialEq)]
pub struct NightOptions {
    /// The background: sky, facades, windows, sensor noise ([`DayRenderer`]'s options; the
    /// sun is below the horizon).
    pub scene: DayOptions,
    /// The lamps' blobs: `flux_scale` and `psf_sigma_px` are used (the noise is the
    /// scene's sensor).
    pub lamps: RenderOptions,
    /// Share of a saturated lamp's flux in its bloom.
    pub bloom_fraction: f64,
    /// Standard deviation added to the lamp's blob for its bloom (pixels).
    pub bloom_sigma_px: f64,
    /// Intensity of a reflection relative to its lamp.
    pub reflection_gain: f64,
    /// A reflection's standard deviation along the image's vertical is its lamp's times this.
    pub reflection_stretch: f64,
    /// Share of the cars with their lights on (0–1).
    pub car_light_share: f64,
    /// Relative intensity of a headlight seen from straight ahead (1 = a street lamp).
    pub headlight_intensity: f64,
    /// Relative intensity of a taillight (its luminance: red light).
    pub taillight_intensity: f64,
    /// Radius of a car light (metres).
    pub car_light_radius_m: f64,
    /// Share of the light lost at the image corners (0 = none).
    pub vignetting: f64,
    /// Lit windows farther than this are not listed in the truth (metres).
    pub window_truth_range_m: f64,
}

impl Default for NightOptions {
    fn default() -> Self {
        Self {
            scene: DayOptions {
                sky_horizon_dn: 14.0,
                sky_zenith_dn: 4.0,
                ambient_dn: 14.0,
                sun_dn: 0.0,
                psf_sigma_px: 0.7,
                gain_e_per_dn: 4.0,
                read_noise_dn: 1.0,
                supersampling: 2,
                max_range_m: 150.0,
                glass_reflection_dn: 2.0,
                lit_window_share: 0.25,
                lit_window_dn: (40.0, 140.0),
            },
            lamps: RenderOptions {
                // Four times the flat renderer's lamps: real lamp heads saturate a camera
                // exposed for the street (the lamps within ≈ 40 m do here, with bloom).
                flux_scale: 1.0e7,
                ..RenderOptions::default()
            },
            bloom_fraction: 0.04,
            bloom_sigma_px: 6.0,
            reflection_gain: 0.6,
            reflection_stretch: 4.0,
            car_light_share: 0.4,
            headlight_intensity: 0.4,
            taillight_intensity: 0.05,
            car_light_radius_m: 0.09,
            vignetting: 0.35,
            window_truth_range_m: 100.0,
        }
    }
}

/// What a spot of a realistic night frame is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NightSpotKind {
    /// The lamp at this index of the `lights` slice.
    Lamp(usize),
    /// The wet-road reflection of the lamp at this index.
    Reflection(usize),
    /// A lit window (its pane's centre).
    Window,
    /// A car's headlight.
    Headlight,
    /// A car's taillight.
    Taillight,
}

/// The truth of one spot of a realistic night frame.
///
/// # Units
/// Pixels, metres and DN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NightSpot {
    /// What it is.
    pub kind: NightSpotKind,
    /// Column of its centre.
    pub u: f64,
    /// Row of its centre.
    pub v: f64,
    /// Distance from the camera to the light (for a reflection: to the mirror image).
    pub range_m: f64,
    /// Peak signal above the background (DN, before vignetting and saturation); a window's
    /// radiance.
    pub peak_dn: f64,
    /// Whether the image border cuts its drawn window.
    pub clipped_by_border: bool,
}

/// A rendered realistic night image with the truth of its spots.
#[derive(Clone, Debug)]
pub struct NightFrame {
    /// The 8-bit image.
    pub image: GrayImage,
    /// Every drawn spot and visible lit window.
    pub spots: Vec<NightSpot>,
}

/// The realistic night renderer of a rig. `Send + Sync`.
pub struct NightRenderer {
    options: NightOptions,
    scene_renderer: DayRenderer,
    lamp_renderer: Renderer,
}

/// One camera's render in progress.
struct Canvas<'a> {
    traced: Traced,
    model: &'a vgps_camera::calibration::Camera,
    spots: Vec<NightSpot>,
}

impl Canvas<'_> {
    /// Whether the pixel of `pixel` sees a surface no nearer than `range` (less the margin).
    fn sees(&self, pixel: &Vector2<f64>, range: f64) -> bool {
        let (w, h) = (self.traced.width, self.traced.height);
        if !in_image_rectangle(w as u32, h as u32, pixel) {
            return false;
        }
        let (u, v) = (pixel.x.round() as usize, pixel.y.round() as usize);
        let depth = self.traced.depth[v.min(h - 1) * w + u.min(w - 1)];
        f64::from(depth) >= range - depth_margin(range)
    }

    /// The world point `p` in the camera frame.
    fn in_camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.traced
            .world_from_camera
            .inverse_transform_point(&Point3::from(*p))
            .coords
    }

    fn add(&mut self, blob: &Blob, kind: NightSpotKind) {
        let (w, h) = (self.traced.width, self.traced.height);
        let clipped = blob.add_to(&mut self.traced.radiance, w, h);
        self.spots.push(NightSpot {
            kind,
            u: blob.centre.x,
            v: blob.centre.y,
            range_m: blob.range,
            peak_dn: blob.peak,
            clipped_by_border: clipped,
        });
    }
}

impl NightRenderer {
    /// A renderer for the cameras of `rig` (tables every pixel's bearing, as
    /// [`DayRenderer::new`]).
    pub fn new(options: NightOptions, rig: &Rig) -> Self {
        Self {
            scene_renderer: DayRenderer::new(options.scene.clone(), rig),
            lamp_renderer: Renderer::new(options.lamps.clone()),
            options,
        }
    }

    /// The options.
    pub fn options(&self) -> &NightOptions {
        &self.options
    }

    /// Renders camera `camera` of the rig at `world_from_rig` in `scene` at night, seeing
    /// the lamps `lights` (in the camera frame, as [`Renderer::render`]), deterministic for
    /// `seed`. `None` for a camera index outside the rig.
    pub fn render(
        &self,
        scene: &DayScene,
        world_from_rig: &Pose,
        camera: usize,
        lights: &[LightSource],
        seed: u64,
    ) -> Option<NightFrame> {
        let below_horizon = -Vector3::z();
        let traced = self
            .scene_renderer
            .trace(scene, world_from_rig, camera, &below_horizon)?;
        let model = &self.scene_renderer.rig().cameras().get(camera)?.model;
        let mut canvas = Canvas {
            traced,
            model,
            spots: Vec::new(),
        };
        for (index, light) in lights.iter().enumerate() {
            self.draw_lamp(&mut canvas, scene, light, index);
        }
        self.draw_car_lights(&mut canvas, scene);
        self.list_windows(&mut canvas, scene);
        let Canvas {
            mut traced, spots, ..
        } = canvas;
        vignette(
            &mut traced.radiance,
            traced.width,
            traced.height,
            self.options.vignetting,
        );
        let o = &self.options.scene;
        let pixels = expose(
            &traced.radiance,
            &traced.ids,
            seed,
            o.gain_e_per_dn,
            o.read_noise_dn,
        );
        let image = GrayImage::from_raw(traced.width as u32, traced.height as u32, pixels)
            .unwrap_or_else(|| unreachable!("the buffer has width × height bytes"));
        Some(NightFrame { image, spots })
    }

    /// A lamp, its bloom when it saturates, and its reflection on the wet road.
    fn draw_lamp(&self, canvas: &mut Canvas, scene: &DayScene, light: &LightSource, index: usize) {
        let Some(blob) = self.lamp_renderer.lamp_blob(canvas.model, light) else {
            return;
        };
        canvas.add(&blob, NightSpotKind::Lamp(index));
        let o = &self.options;
        let background = canvas.traced.radiance[pixel_index(&canvas.traced, &blob.centre)];
        if blob.peak + f64::from(background) > 255.0 && o.bloom_fraction > 0.0 {
            let spread = Matrix2::identity() * o.bloom_sigma_px.powi(2);
            if let Some(bloom) = Blob::new(
                blob.centre,
                blob.covariance + spread,
                blob.flux * o.bloom_fraction,
                blob.range,
            ) {
                // Part of the lamp's image, not a spot of its own: no truth row.
                let (w, h) = (canvas.traced.width, canvas.traced.height);
                bloom.add_to(&mut canvas.traced.radiance, w, h);
            }
        }
        if let Some(reflection) = self.reflection(canvas, scene, light) {
            canvas.add(&reflection, NightSpotKind::Reflection(index));
        }
    }

    /// The blob of a lamp's mirror image about the road plane, when the wet road shows it.
    fn reflection(&self, canvas: &Canvas, scene: &DayScene, light: &LightSource) -> Option<Blob> {
        let o = &self.options;
        if !(o.reflection_gain > 0.0) {
            return None;
        }
        let pose = &canvas.traced.world_from_camera;
        let origin = pose.translation.vector;
        let lamp = pose
            .transform_point(&Point3::from(light.point_in_camera))
            .coords;
        if !(lamp.z > 0.0 && origin.z > 0.0) {
            return None;
        }
        let mirror = Vector3::new(lamp.x, lamp.y, -lamp.z);
        // Where the line of sight to the mirror image meets the road.
        let ground = origin + (mirror - origin) * (origin.z / (origin.z + lamp.z));
        let wet = matches!(
            ground_at(ground.x, ground.y, scene.block_m),
            Ground::Road | Ground::LaneMark
        );
        if !wet {
            return None;
        }
        let mirrored = LightSource {
            point_in_camera: canvas.in_camera(&mirror),
            radius_m: light.radius_m,
            intensity: light.intensity * o.reflection_gain,
        };
        let blob = self.lamp_renderer.lamp_blob(canvas.model, &mirrored)?;
        if !canvas.sees(&blob.centre, (ground - origin).norm()) {
            return None;
        }
        let below = canvas.in_camera(&(mirror - Vector3::z() * VERTICAL_PROBE_M));
        let down = canvas.model.try_pixel(&below.normalize())? - blob.centre;
        let down = down.try_normalize(1e-9)?;
        let sigma = blob.covariance.trace().max(0.0).sqrt();
        let stretch = (o.reflection_stretch.max(1.0).powi(2) - 1.0) * sigma * sigma;
        Blob::new(
            blob.centre,
            blob.covariance + down * down.transpose() * stretch,
            blob.flux,
            blob.range,
        )
    }

    /// The head- and taillight pairs of the cars whose lights are on.
    fn draw_car_lights(&self, canvas: &mut Canvas, scene: &DayScene) {
        let o = &self.options;
        let origin = canvas.traced.world_from_camera.translation.vector;
        for (index, car) in scene.boxes.iter().enumerate() {
            let Some((forward, lateral)) = car_axes(car, index, o.car_light_share) else {
                continue;
            };
            let centre = (car.min + car.max) / 2.0;
            if (centre - origin).norm() > o.scene.max_range_m {
                continue;
            }
            let half_length = (car.max - car.min).dot(&forward.abs()) / 2.0 + CAR_LIGHT_OUTSET_M;
            for (ahead, height, kind) in [
                (1.0, CAR_LIGHT_HEIGHT_M.0, NightSpotKind::Headlight),
                (-1.0, CAR_LIGHT_HEIGHT_M.1, NightSpotKind::Taillight),
            ] {
                let normal = forward * ahead;
                let end = Vector3::new(centre.x, centre.y, height) + normal * half_length;
                for side in [-0.5, 0.5] {
                    let p = end + lateral * (side * CAR_LIGHT_SPACING_M);
                    let to_camera = origin - p;
                    let range = to_camera.norm();
                    let facing = to_camera.dot(&normal) / range;
                    if !(facing > 0.0) {
                        continue;
                    }
                    let intensity = if kind == NightSpotKind::Headlight {
                        // Headlights are aimed ahead: brighter seen from in front.
                        o.headlight_intensity * (0.2 + 0.8 * facing)
                    } else {
                        o.taillight_intensity
                    };
                    let light = LightSource {
                        point_in_camera: canvas.in_camera(&p),
                        radius_m: o.car_light_radius_m,
                        intensity,
                    };
                    if let Some(blob) = self.lamp_renderer.lamp_blob(canvas.model, &light)
                        && canvas.sees(&blob.centre, range)
                    {
                        canvas.add(&blob, kind);
                    }
                }
            }
        }
    }

    /// The truth rows of the visible lit windows (drawn by the background already).
    fn list_windows(&self, canvas: &mut Canvas, scene: &DayScene) {
        let o = &self.options;
        let origin = canvas.traced.world_from_camera.translation.vector;
        for (index, b) in scene.boxes.iter().enumerate() {
            let reach = (b.max - b.min).norm() / 2.0 + o.window_truth_range_m;
            if b.kind != BoxKind::Building || ((b.min + b.max) / 2.0 - origin).norm() > reach {
                continue;
            }
            for window in windows_of(scene, index) {
                let Some(radiance) = window_light(&window.key, &o.scene) else {
                    continue;
                };
                let to_camera = origin - window.centre;
                let range = to_camera.norm();
                if !(to_camera.dot(&window.normal) > 0.0 && range < o.window_truth_range_m) {
                    continue;
                }
                let p = canvas.in_camera(&window.centre);
                let Some(pixel) = canvas.model.try_pixel(&(p / range)) else {
                    continue;
                };
                // The pane's own surface: it lies at the window's range, not nearer.
                let (w, h) = (canvas.traced.width, canvas.traced.height);
                if canvas.sees(&pixel, range)
                    && f64::from(canvas.traced.depth[pixel_index(&canvas.traced, &pixel)])
                        < range + depth_margin(range)
                {
                    canvas.spots.push(NightSpot {
                        kind: NightSpotKind::Window,
                        u: pixel.x,
                        v: pixel.y,
                        range_m: range,
                        peak_dn: radiance,
                        clipped_by_border: !in_image_rectangle(w as u32, h as u32, &pixel),
                    });
                }
            }
        }
    }
}

/// The index of the pixel nearest `pixel` (clamped into the image).
fn pixel_index(traced: &Traced, pixel: &Vector2<f64>) -> usize {
    let (w, h) = (traced.width, traced.height);
    let u = pixel.x.round().clamp(0.0, (w.max(1) - 1) as f64) as usize;
    let v = pixel.y.round().clamp(0.0, (h.max(1) - 1) as f64) as usize;
    v * w + u
}

/// A lit car's forward and lateral unit axes (ENU, horizontal), `None` for a box that is not
/// a car or a car whose lights are off: a hash of its index decides both.
fn car_axes(car: &SceneBox, index: usize, share: f64) -> Option<(Vector3<f64>, Vector3<f64>)> {
    if car.kind != BoxKind::Car {
        return None;
    }
    let h = splitmix64(CAR_SALT ^ splitmix64(index as u64));
    if !(((h >> 11) as f64 / (1u64 << 53) as f64) < share) {
        return None;
    }
    let size = car.max - car.min;
    let (long, across) = if size.x >= size.y {
        (Vector3::x(), Vector3::y())
    } else {
        (Vector3::y(), Vector3::x())
    };
    let sign = if h & 1 == 0 { 1.0 } else { -1.0 };
    Some((long * sign, across))
}

/// Multiplies the radiance by the vignetting falloff `1 − vignetting · (r / r_corner)²`, `r`
/// the distance from the image centre.
pub(crate) fn vignette(radiance: &mut [f32], width: usize, height: usize, vignetting: f64) {
    if !(vignetting > 0.0) || width == 0 || height == 0 {
        return;
    }
    let (cu, cv) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
    let corner2 = (cu * cu + cv * cv).max(1.0);
    let k = vignetting.min(1.0) / corner2;
    for (v, row) in radiance.chunks_exact_mut(width).enumerate() {
        let dv2 = (v as f64 - cv).powi(2);
        for (u, p) in row.iter_mut().enumerate() {
            let r2 = (u as f64 - cu).powi(2) + dv2;
            *p *= (1.0 - k * r2) as f32;
        }
    }
}

#[cfg(test)]
mod tests;
