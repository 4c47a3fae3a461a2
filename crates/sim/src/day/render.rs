//! Ray-cast rendering of day frames through a calibrated camera model (with its
//! distortion): every pixel's bearing from the model ([`CameraModel::try_bearing`], tabled
//! once per camera), cast into the [`DayScene`].
//!
//! # Model
//! - **Geometry**: boxes (buildings, cars, tree trunks), spheres (canopies), the ground plane
//!   `z = 0` with the street layout, and the sky. Each image is cut into tiles of
//!   [`TILE_PX`] pixels; a tile tests only the objects whose bounding sphere meets the cone of
//!   its bearings.
//! - **Light**: a Lambertian surface of reflectance `ρ` with normal `n` has the radiance
//!   `ρ · (ambient_dn + sun_dn · max(0, n·s))` DN, `s` the direction to the sun (no direct
//!   light when the sun is below the horizon; no cast shadows). The sky is a gradient from
//!   the horizon to the zenith with a glow around the sun. Facades have a grid of dark
//!   windows from 4.8 m up (clear of the building's edges) and dark awning bands.
//! - **Pixel area**: a pixel whose surface (object, face, material) differs from one of its
//!   four neighbours is the mean of [`DayOptions::supersampling`]² sub-samples, their
//!   bearings interpolated bilinearly in the table; the others are one sample at the centre.
//! - **Optics and sensor**: a Gaussian point-spread function of
//!   [`DayOptions::psf_sigma_px`], shot noise of variance `s / gain` and read noise, drawn
//!   from a counter-based hash of `(seed, pixel)`; rounded and clamped to 8 bits.
//!
//! The truth of a frame is every corner landmark whose projection is inside the image and
//! whose line of sight is not cut by a box or a canopy (the box of the corner itself
//! excepted: its vertex is the corner).

use super::scene::{AWNING_BAND_M, BoxKind, DayScene, Ground, ground_at};
use crate::render::{approx_normal, splitmix64};
use image::GrayImage;
use nalgebra::{Matrix3, Point3, Vector3};
use vgps_camera::calibration::{CameraModel, Pixel, Rig, in_image_rectangle};
use vgps_geometry::geometry::Pose;

/// Side of a culling tile (pixels).
pub const TILE_PX: usize = 16;
/// A corner closer than this to the image border is flagged `near_border` (pixels).
pub const BORDER_PX: f64 = 10.0;
/// A box or canopy hides a corner when it cuts the line of sight this far before it (metres).
const OCCLUSION_MARGIN_M: f64 = 0.05;
/// Height of the first window floor's base, floor pitch, sill and lintel (metres).
const WINDOW_FLOORS_M: (f64, f64, f64, f64) = (4.8, 3.2, 0.9, 2.3);
/// Window pitch along a facade and its window width (metres).
const WINDOW_PITCH_M: (f64, f64) = (2.8, 1.4);
/// Facade margin kept free of windows at each end and under the roof (metres).
const WINDOW_MARGIN_M: f64 = 1.0;
/// Reflectance of glass, awnings and the ground materials.
const GLASS_ALBEDO: f64 = 0.08;
const AWNING_ALBEDO: f64 = 0.1;
/// Sky light reflected by a window (DN).
const GLASS_REFLECTION_DN: f64 = 35.0;

/// Parameters of the day renderer. [`Default`]: a bright afternoon, a sky of 215 DN at the
/// horizon and 165 DN at the zenith, a sunlit white wall ≈ 250 DN, a 0.6 px PSF, gain
/// 8 e⁻/DN and 1.5 DN read noise.
#[derive(Clone, Debug, PartialEq)]
pub struct DayOptions {
    /// Sky brightness at the horizon (DN).
    pub sky_horizon_dn: f64,
    /// Sky brightness at the zenith (DN).
    pub sky_zenith_dn: f64,
    /// Radiance of a white surface in diffuse light only (DN).
    pub ambient_dn: f64,
    /// Extra radiance of a white surface facing the sun (DN).
    pub sun_dn: f64,
    /// Standard deviation of the optics' point-spread function (pixels).
    pub psf_sigma_px: f64,
    /// Sensor gain (electrons per DN; shot-noise variance `s / gain`); ≤ 0 disables it.
    pub gain_e_per_dn: f64,
    /// Standard deviation of the read noise (DN).
    pub read_noise_dn: f64,
    /// Sub-samples per axis of an edge pixel (1 = no anti-aliasing).
    pub supersampling: usize,
    /// Objects and corners farther than this are not drawn (metres).
    pub max_range_m: f64,
    /// Sky light reflected by an unlit window (DN).
    pub glass_reflection_dn: f64,
    /// Share of the windows that are lit from inside (0–1; the night scene): which ones is
    /// a hash of the building, face, floor and column.
    pub lit_window_share: f64,
    /// Radiance range of a lit window (DN), drawn per window from the same hash.
    pub lit_window_dn: (f64, f64),
}

impl Default for DayOptions {
    fn default() -> Self {
        Self {
            sky_horizon_dn: 215.0,
            sky_zenith_dn: 165.0,
            ambient_dn: 110.0,
            sun_dn: 150.0,
            psf_sigma_px: 0.6,
            gain_e_per_dn: 8.0,
            read_noise_dn: 1.5,
            supersampling: 4,
            max_range_m: 150.0,
            glass_reflection_dn: GLASS_REFLECTION_DN,
            lit_window_share: 0.0,
            lit_window_dn: (60.0, 160.0),
        }
    }
}

/// The truth of one visible corner landmark in a day frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerTruth {
    /// Index of the landmark in `World::landmarks`.
    pub landmark: usize,
    /// Column of the projected corner (pixels).
    pub u: f64,
    /// Row of the projected corner (pixels).
    pub v: f64,
    /// Distance from the camera (metres).
    pub range_m: f64,
    /// Whether it is closer than [`BORDER_PX`] to the image border.
    pub near_border: bool,
}

/// A rendered day image with its visible corners.
#[derive(Clone, Debug)]
pub struct DayFrame {
    /// The 8-bit image.
    pub image: GrayImage,
    /// Every visible corner landmark.
    pub corners: Vec<CornerTruth>,
}

struct CameraTable {
    width: usize,
    height: usize,
    /// Bearing of every pixel centre in the camera frame; NaN outside the model's domain.
    bearings: Vec<[f32; 3]>,
    tiles_x: usize,
    /// Per tile: the axis of its bearing cone (camera frame) and its half-angle (radians).
    cones: Vec<(Vector3<f64>, f64)>,
}

/// The day renderer: [`DayOptions`] and each camera's bearing table. `Send + Sync`.
pub struct DayRenderer {
    options: DayOptions,
    rig: Rig,
    tables: Vec<CameraTable>,
}

/// An object of one render, relative to the camera centre (ENU axes).
struct Object {
    centre: Vector3<f64>,
    radius: f64,
    shape: Shape,
    index: usize,
}

enum Shape {
    Box {
        min: Vector3<f64>,
        max: Vector3<f64>,
    },
    Sphere,
}

struct Hit {
    t: f64,
    object: Option<usize>,
    normal: Vector3<f64>,
}

impl DayRenderer {
    /// A renderer for the cameras of `rig` (tables every pixel's bearing: ≈ 0.1 s per camera
    /// of 1024 × 768).
    pub fn new(options: DayOptions, rig: &Rig) -> Self {
        let tables = rig
            .cameras()
            .iter()
            .map(|c| {
                let (w, h) = c.model.image_size();
                let (w, h) = (w as usize, h as usize);
                let bearings: Vec<[f32; 3]> = (0..w * h)
                    .map(|i| {
                        let p = Pixel::new((i % w) as f64, (i / w) as f64);
                        match c.model.try_bearing(&p) {
                            Some(b) => [b.x as f32, b.y as f32, b.z as f32],
                            None => [f32::NAN; 3],
                        }
                    })
                    .collect();
                let tiles_x = w.div_ceil(TILE_PX);
                let tiles_y = h.div_ceil(TILE_PX);
                let mut cones = Vec::with_capacity(tiles_x * tiles_y);
                for ty in 0..tiles_y {
                    for tx in 0..tiles_x {
                        // The tile and a one-pixel border (sub-samples reach ±0.5 px).
                        let (u0, u1) = (
                            (tx * TILE_PX).saturating_sub(1),
                            ((tx + 1) * TILE_PX + 1).min(w),
                        );
                        let (v0, v1) = (
                            (ty * TILE_PX).saturating_sub(1),
                            ((ty + 1) * TILE_PX + 1).min(h),
                        );
                        let mut sum = Vector3::zeros();
                        let mut all = Vec::new();
                        for v in v0..v1 {
                            for u in u0..u1 {
                                let b = bearings[v * w + u];
                                if b[0].is_finite() {
                                    let b = Vector3::new(b[0] as f64, b[1] as f64, b[2] as f64);
                                    sum += b;
                                    all.push(b);
                                }
                            }
                        }
                        let axis = sum.try_normalize(1e-12).unwrap_or_else(Vector3::z);
                        let half = all
                            .iter()
                            .map(|b| axis.dot(b).clamp(-1.0, 1.0).acos())
                            .fold(0.0, f64::max);
                        cones.push((axis, half + 1e-3));
                    }
                }
                CameraTable {
                    width: w,
                    height: h,
                    bearings,
                    tiles_x,
                    cones,
                }
            })
            .collect();
        Self {
            options: options.clone(),
            rig: rig.clone(),
            tables,
        }
    }

    /// The options.
    pub fn options(&self) -> &DayOptions {
        &self.options
    }

    /// The rig.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// Renders camera `camera` of the rig at `world_from_rig` in `scene`, lit by the sun in
    /// the ENU direction `sun` (unit; below the horizon: diffuse light only), deterministic
    /// for `seed`. `None` for a camera index outside the rig.
    pub fn render(
        &self,
        scene: &DayScene,
        world_from_rig: &Pose,
        camera: usize,
        sun: &Vector3<f64>,
        seed: u64,
    ) -> Option<DayFrame> {
        let traced = self.trace(scene, world_from_rig, camera, sun)?;
        let o = &self.options;
        let pixels = expose(
            &traced.radiance,
            &traced.ids,
            seed,
            o.gain_e_per_dn,
            o.read_noise_dn,
        );
        let image = GrayImage::from_raw(traced.width as u32, traced.height as u32, pixels)
            .unwrap_or_else(|| unreachable!("the buffer has width × height bytes"));
        Some(DayFrame {
            image,
            corners: traced.corners,
        })
    }

    /// The noiseless radiance of camera `camera` (after the PSF), with each pixel's surface
    /// id and depth and the visible corners: [`DayRenderer::render`] before the sensor, and
    /// the background of the realistic night renderer ([`crate::night`]).
    ///
    /// Long (about 170 lines) for a reason: the per-tile ray loop shares its candidate
    /// lists, shading and anti-aliasing state in one hot body (the renderer's time is here).
    pub(crate) fn trace(
        &self,
        scene: &DayScene,
        world_from_rig: &Pose,
        camera: usize,
        sun: &Vector3<f64>,
    ) -> Option<Traced> {
        let rig_camera = self.rig.cameras().get(camera)?;
        let table = self.tables.get(camera)?;
        let world_from_camera = world_from_rig * rig_camera.rig_from_camera;
        let origin = world_from_camera.translation.vector;
        let enu_from_camera: Matrix3<f64> = *world_from_camera.rotation.matrix();
        let o = &self.options;
        let objects: Vec<Object> = scene
            .boxes
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let c = (b.min + b.max) / 2.0 - origin;
                Object {
                    centre: c,
                    radius: (b.max - b.min).norm() / 2.0,
                    shape: Shape::Box {
                        min: b.min - origin,
                        max: b.max - origin,
                    },
                    index: i,
                }
            })
            .chain(scene.canopies.iter().enumerate().map(|(i, s)| Object {
                centre: s.centre - origin,
                radius: s.radius_m,
                shape: Shape::Sphere,
                index: scene.boxes.len() + i,
            }))
            .filter(|ob| ob.centre.norm() - ob.radius < o.max_range_m)
            .collect();
        // Candidate objects of each tile, nearest first.
        let tile_objects: Vec<Vec<u32>> = table
            .cones
            .iter()
            .map(|(axis, half)| {
                let axis = enu_from_camera * axis;
                let mut list: Vec<(f64, u32)> = objects
                    .iter()
                    .enumerate()
                    .filter(|(_, ob)| {
                        let d = ob.centre.norm();
                        d <= ob.radius || {
                            let angle = (axis.dot(&ob.centre) / d).clamp(-1.0, 1.0).acos();
                            angle <= half + (ob.radius / d).asin()
                        }
                    })
                    .map(|(k, ob)| (ob.centre.norm() - ob.radius, k as u32))
                    .collect();
                list.sort_by(|a, b| a.0.total_cmp(&b.0));
                list.into_iter().map(|(_, k)| k).collect()
            })
            .collect();
        let sun_up = sun.z > 0.0;
        let shader = Shader {
            scene,
            objects: &objects,
            origin,
            sun: *sun,
            sun_up,
            options: o,
        };
        let (w, h) = (table.width, table.height);
        let mut ids = vec![u32::MAX; w * h];
        let mut radiance = vec![0f32; w * h];
        let mut depth = vec![f32::INFINITY; w * h];
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let b = table.bearings[i];
                if !b[0].is_finite() {
                    continue;
                }
                let d = enu_from_camera * Vector3::new(b[0] as f64, b[1] as f64, b[2] as f64);
                let cands = &tile_objects[(v / TILE_PX) * table.tiles_x + u / TILE_PX];
                let (id, value, t) = shader.sample(&d, cands);
                ids[i] = id;
                radiance[i] = value as f32;
                depth[i] = t as f32;
            }
        }
        // Anti-aliasing of the pixels on a surface boundary.
        let n = o.supersampling.max(1);
        if n > 1 {
            for v in 0..h {
                for u in 0..w {
                    let i = v * w + u;
                    let id = ids[i];
                    if id == u32::MAX {
                        continue;
                    }
                    let differs = (u > 0 && ids[i - 1] != id)
                        || (u + 1 < w && ids[i + 1] != id)
                        || (v > 0 && ids[i - w] != id)
                        || (v + 1 < h && ids[i + w] != id);
                    if !differs {
                        continue;
                    }
                    let cands = &tile_objects[(v / TILE_PX) * table.tiles_x + u / TILE_PX];
                    let (mut sum, mut count) = (0.0, 0usize);
                    for sy in 0..n {
                        for sx in 0..n {
                            let su = u as f64 + (sx as f64 + 0.5) / n as f64 - 0.5;
                            let sv = v as f64 + (sy as f64 + 0.5) / n as f64 - 0.5;
                            if let Some(b) = interpolated_bearing(table, su, sv) {
                                sum += shader.sample(&(enu_from_camera * b), cands).1;
                                count += 1;
                            }
                        }
                    }
                    if count > 0 {
                        radiance[i] = (sum / count as f64) as f32;
                    }
                }
            }
        }
        let radiance = gaussian_blur(&radiance, w, h, o.psf_sigma_px);
        // The visible corners.
        let camera_from_world = world_from_camera.inverse();
        let mut corners = Vec::new();
        for &(landmark, p) in &scene.corners {
            let rel = p - origin;
            let range_m = rel.norm();
            if !(range_m > 0.5 && range_m < o.max_range_m) {
                continue;
            }
            let in_camera = camera_from_world.transform_point(&Point3::from(p)).coords;
            let Some(pixel) = rig_camera.model.try_pixel(&(in_camera / range_m)) else {
                continue;
            };
            if !in_image_rectangle(w as u32, h as u32, &pixel) {
                continue;
            }
            let (tu, tv) = (pixel.x.round() as usize, pixel.y.round() as usize);
            let cands =
                &tile_objects[(tv.min(h - 1) / TILE_PX) * table.tiles_x + tu.min(w - 1) / TILE_PX];
            let d = rel / range_m;
            if shader.occluded(&d, cands, range_m - OCCLUSION_MARGIN_M) {
                continue;
            }
            let near_border = pixel.x < BORDER_PX
                || pixel.y < BORDER_PX
                || pixel.x > w as f64 - 1.0 - BORDER_PX
                || pixel.y > h as f64 - 1.0 - BORDER_PX;
            corners.push(CornerTruth {
                landmark,
                u: pixel.x,
                v: pixel.y,
                range_m,
                near_border,
            });
        }
        Some(Traced {
            radiance,
            ids,
            depth,
            width: w,
            height: h,
            world_from_camera,
            corners,
        })
    }
}

/// The output of [`DayRenderer::trace`].
pub(crate) struct Traced {
    /// Radiance of every pixel after the PSF (DN, noiseless).
    pub(crate) radiance: Vec<f32>,
    /// The surface id of every pixel (`u32::MAX` outside the camera model's domain).
    pub(crate) ids: Vec<u32>,
    /// Distance to the surface seen by every pixel centre (metres; infinite for the sky).
    pub(crate) depth: Vec<f32>,
    /// Image width (pixels).
    pub(crate) width: usize,
    /// Image height (pixels).
    pub(crate) height: usize,
    /// The camera's pose in the world (ENU).
    pub(crate) world_from_camera: Pose,
    /// The visible corner landmarks.
    pub(crate) corners: Vec<CornerTruth>,
}

/// The sensor: shot noise of variance `s / gain` (none for `gain ≤ 0`) and read noise of
/// `read_noise_dn`, drawn from a counter-based hash of `(seed, pixel)`, rounded and clamped
/// to 8 bits; pixels whose id is `u32::MAX` (outside the model's domain) are 0.
pub(crate) fn expose(
    radiance: &[f32],
    ids: &[u32],
    seed: u64,
    gain_e_per_dn: f64,
    read_noise_dn: f64,
) -> Vec<u8> {
    let inv_gain = if gain_e_per_dn > 0.0 {
        1.0 / gain_e_per_dn
    } else {
        0.0
    };
    let read2 = read_noise_dn * read_noise_dn;
    radiance
        .iter()
        .zip(ids)
        .enumerate()
        .map(|(i, (&s, &id))| {
            if id == u32::MAX {
                return 0;
            }
            let s = f64::from(s).max(0.0);
            let hsh = splitmix64(seed ^ splitmix64(i as u64));
            let value = s + (s * inv_gain + read2).sqrt() * approx_normal(hsh);
            if value.is_nan() {
                return 0;
            }
            value.round().clamp(0.0, 255.0) as u8
        })
        .collect()
}

/// The bilinearly interpolated bearing at a fractional pixel (camera frame, unit).
fn interpolated_bearing(table: &CameraTable, u: f64, v: f64) -> Option<Vector3<f64>> {
    let (w, h) = (table.width, table.height);
    let u = u.clamp(0.0, (w - 1) as f64);
    let v = v.clamp(0.0, (h - 1) as f64);
    let (u0, v0) = (u.floor() as usize, v.floor() as usize);
    let (u1, v1) = ((u0 + 1).min(w - 1), (v0 + 1).min(h - 1));
    let (fu, fv) = (u - u0 as f64, v - v0 as f64);
    let get = |uu: usize, vv: usize| {
        let b = table.bearings[vv * w + uu];
        Vector3::new(b[0] as f64, b[1] as f64, b[2] as f64)
    };
    let b = get(u0, v0) * ((1.0 - fu) * (1.0 - fv))
        + get(u1, v0) * (fu * (1.0 - fv))
        + get(u0, v1) * ((1.0 - fu) * fv)
        + get(u1, v1) * (fu * fv);
    b.try_normalize(1e-12)
        .filter(|b| b.iter().all(|x| x.is_finite()))
}

struct Shader<'a> {
    scene: &'a DayScene,
    objects: &'a [Object],
    origin: Vector3<f64>,
    sun: Vector3<f64>,
    sun_up: bool,
    options: &'a DayOptions,
}

impl Shader<'_> {
    /// The nearest object hit along `d` among `cands` (ground excluded), closer than `limit`.
    fn cast(&self, d: &Vector3<f64>, cands: &[u32], limit: f64) -> Hit {
        let mut best = Hit {
            t: limit,
            object: None,
            normal: Vector3::zeros(),
        };
        for &k in cands {
            let ob = &self.objects[k as usize];
            if ob.centre.norm() - ob.radius > best.t {
                break;
            }
            match &ob.shape {
                Shape::Box { min, max } => {
                    let (mut t0, mut t1, mut axis) = (f64::NEG_INFINITY, f64::INFINITY, 0usize);
                    let mut miss = false;
                    for a in 0..3 {
                        if d[a].abs() < 1e-15 {
                            if min[a] > 0.0 || max[a] < 0.0 {
                                miss = true;
                                break;
                            }
                            continue;
                        }
                        let inv = 1.0 / d[a];
                        let (mut lo, mut hi) = (min[a] * inv, max[a] * inv);
                        if lo > hi {
                            std::mem::swap(&mut lo, &mut hi);
                        }
                        if lo > t0 {
                            t0 = lo;
                            axis = a;
                        }
                        t1 = t1.min(hi);
                    }
                    if !miss && t0 <= t1 && t0 > 0.0 && t0 < best.t {
                        let mut normal = Vector3::zeros();
                        normal[axis] = -d[axis].signum();
                        best = Hit {
                            t: t0,
                            object: Some(k as usize),
                            normal,
                        };
                    }
                }
                Shape::Sphere => {
                    let b = ob.centre.dot(d);
                    let disc = b * b - (ob.centre.norm_squared() - ob.radius * ob.radius);
                    if disc > 0.0 {
                        let t = b - disc.sqrt();
                        if t > 0.0 && t < best.t {
                            best = Hit {
                                t,
                                object: Some(k as usize),
                                normal: (d * t - ob.centre) / ob.radius,
                            };
                        }
                    }
                }
            }
        }
        best
    }

    /// Whether a box or canopy cuts the ray `d` before `limit`.
    fn occluded(&self, d: &Vector3<f64>, cands: &[u32], limit: f64) -> bool {
        self.cast(d, cands, limit).object.is_some()
    }

    fn lit(&self, albedo: f64, normal: &Vector3<f64>) -> f64 {
        let direct = if self.sun_up {
            self.options.sun_dn * normal.dot(&self.sun).max(0.0)
        } else {
            0.0
        };
        albedo * (self.options.ambient_dn + direct)
    }

    fn sky(&self, d: &Vector3<f64>) -> f64 {
        let o = self.options;
        let glow = if self.sun_up {
            40.0 * d.dot(&self.sun).max(0.0).powi(16)
        } else {
            0.0
        };
        o.sky_horizon_dn + (o.sky_zenith_dn - o.sky_horizon_dn) * d.z.max(0.0).sqrt() + glow
    }

    /// The surface id and radiance (DN) seen along the unit ENU direction `d`.
    /// The surface id, radiance (DN) and distance (metres; infinite for the sky) seen
    /// along the unit ENU direction `d`.
    fn sample(&self, d: &Vector3<f64>, cands: &[u32]) -> (u32, f64, f64) {
        let ground_t = if d.z < -1e-12 {
            -(self.origin.z) / d.z
        } else {
            f64::INFINITY
        };
        let limit = ground_t.min(self.options.max_range_m * 2.0);
        let hit = self.cast(d, cands, limit);
        if let Some(k) = hit.object {
            let ob = &self.objects[k];
            let p = self.origin + d * hit.t;
            let face = hit.normal.iter().position(|x| x.abs() > 0.5).unwrap_or(0) as u32 * 2
                + u32::from(hit.normal.iter().any(|x| *x > 0.5));
            let base = 16 + (ob.index as u32) * 64 + face * 4;
            if ob.index >= self.scene.boxes.len() {
                let albedo = self.scene.canopies[ob.index - self.scene.boxes.len()].albedo;
                return (base, self.lit(albedo, &hit.normal), hit.t);
            }
            let b = &self.scene.boxes[ob.index];
            let (mut material, albedo, cell) = match b.kind {
                BoxKind::Building => facade_material(b, &p, &hit.normal),
                _ => (0, b.albedo, None),
            };
            let mut value = self.lit(albedo, &hit.normal);
            if let Some((floor, column)) = cell {
                value += self.options.glass_reflection_dn;
                let key = WindowKey {
                    building: ob.index,
                    face,
                    floor,
                    column,
                };
                if let Some(lit) = window_light(&key, self.options) {
                    // A lit window: its own light, not the sky's reflection.
                    value = lit;
                    material = 3;
                }
            }
            return (base + material, value, hit.t);
        }
        if ground_t.is_finite() && ground_t <= limit {
            let p = self.origin + d * ground_t;
            let (id, albedo) = match ground_at(p.x, p.y, self.scene.block_m) {
                Ground::Road => (1, 0.12),
                Ground::LaneMark => (2, 0.75),
                Ground::Kerb => (3, 0.6),
                Ground::Sidewalk => (4, 0.35),
                Ground::Lot => (5, 0.2),
            };
            return (id, self.lit(albedo, &Vector3::z()), ground_t);
        }
        (0, self.sky(d), f64::INFINITY)
    }
}

/// The material (0 wall, 1 window, 2 awning) and reflectance of a building's face at `p`,
/// with the window's `(floor, column)` in its facade's grid for a window.
fn facade_material(
    b: &super::scene::SceneBox,
    p: &Vector3<f64>,
    normal: &Vector3<f64>,
) -> (u32, f64, Option<(i64, i64)>) {
    if normal.z.abs() > 0.5 {
        return (0, b.albedo, None);
    }
    let along_x = normal.y.abs() > 0.5; // a face of constant y runs along x
    for a in &b.awnings {
        let on_face = if along_x {
            (p.y - a.y).abs() < 1e-3
        } else {
            (p.x - a.x).abs() < 1e-3
        };
        if on_face && p.z <= a.z && p.z >= a.z - AWNING_BAND_M {
            return (2, AWNING_ALBEDO, None);
        }
    }
    let (face_min, face_len, along) = if along_x {
        (b.min.x, b.max.x - b.min.x, p.x)
    } else {
        (b.min.y, b.max.y - b.min.y, p.y)
    };
    let (base, pitch, sill, lintel) = WINDOW_FLOORS_M;
    if p.z >= base {
        let floor = ((p.z - base) / pitch).floor();
        let fz = p.z - base - floor * pitch;
        if let Some((n, start)) = window_columns(face_len)
            && fz >= sill
            && fz <= lintel
            && (floor as i64) < window_floors(b.max.z)
        {
            let x = along - face_min - start;
            let k = (x / WINDOW_PITCH_M.0).floor();
            let in_cell = x - k * WINDOW_PITCH_M.0;
            let margin = (WINDOW_PITCH_M.0 - WINDOW_PITCH_M.1) / 2.0;
            if k >= 0.0 && k < n && in_cell >= margin && in_cell <= margin + WINDOW_PITCH_M.1 {
                return (1, GLASS_ALBEDO, Some((floor as i64, k as i64)));
            }
        }
    }
    (0, b.albedo, None)
}

/// The window columns of a facade `face_len` metres long: their number and the offset of
/// the first column's cell from the facade's start; `None` when no window fits.
fn window_columns(face_len: f64) -> Option<(f64, f64)> {
    let n = ((face_len - 2.0 * WINDOW_MARGIN_M) / WINDOW_PITCH_M.0).floor();
    (n >= 1.0).then(|| (n, (face_len - n * WINDOW_PITCH_M.0) / 2.0))
}

/// The number of window floors under a roof at `roof_z` (a floor's lintel stays
/// [`WINDOW_MARGIN_M`] under the roof).
fn window_floors(roof_z: f64) -> i64 {
    let (base, pitch, _, lintel) = WINDOW_FLOORS_M;
    let room = roof_z - WINDOW_MARGIN_M - base - lintel;
    if room >= 0.0 {
        (room / pitch).floor() as i64 + 1
    } else {
        0
    }
}

/// Which window: the building's index among the scene's boxes, the face (`2 × axis +
/// [normal positive]`), floor and column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WindowKey {
    pub(crate) building: usize,
    pub(crate) face: u32,
    pub(crate) floor: i64,
    pub(crate) column: i64,
}

/// Salt of the lit-window hash.
const LIT_WINDOW_SALT: u64 = 0x6c69_745f_7769_6e64;

/// The radiance (DN) of a window lit from inside, `None` for an unlit window: a hash of the
/// window decides, so every camera and frame sees the same windows lit.
pub(crate) fn window_light(key: &WindowKey, options: &DayOptions) -> Option<f64> {
    if options.lit_window_share.is_nan() || options.lit_window_share <= 0.0 {
        return None;
    }
    let h = splitmix64(
        LIT_WINDOW_SALT
            ^ splitmix64(key.building as u64)
            ^ splitmix64(
                (u64::from(key.face) << 40) ^ ((key.floor as u64) << 20) ^ key.column as u64,
            ),
    );
    let unit = |x: u64| (x >> 11) as f64 / (1u64 << 53) as f64;
    if unit(h) >= options.lit_window_share {
        return None;
    }
    let (lo, hi) = options.lit_window_dn;
    Some(lo + unit(splitmix64(h)) * (hi - lo))
}

/// A window of a facade (ENU metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Window {
    pub(crate) key: WindowKey,
    /// Centre of the pane.
    pub(crate) centre: Vector3<f64>,
    /// Outward normal of its face.
    pub(crate) normal: Vector3<f64>,
}

/// Every window of building box `index` of `scene` (the grid [`facade_material`] draws).
pub(crate) fn windows_of(scene: &DayScene, index: usize) -> Vec<Window> {
    let Some(b) = scene
        .boxes
        .get(index)
        .filter(|b| b.kind == BoxKind::Building)
    else {
        return Vec::new();
    };
    let (base, pitch, sill, lintel) = WINDOW_FLOORS_M;
    let floors = window_floors(b.max.z);
    let mut out = Vec::new();
    for axis in 0..2usize {
        // Faces of constant x (axis 0) run along y, and faces of constant y along x.
        let run = 1 - axis;
        let Some((n, start)) = window_columns(b.max[run] - b.min[run]) else {
            continue;
        };
        for positive in [false, true] {
            let mut normal = Vector3::zeros();
            normal[axis] = if positive { 1.0 } else { -1.0 };
            let plane = if positive { b.max[axis] } else { b.min[axis] };
            for floor in 0..floors {
                for column in 0..n as i64 {
                    let mut centre = Vector3::zeros();
                    centre[axis] = plane;
                    centre[run] = b.min[run] + start + (column as f64 + 0.5) * WINDOW_PITCH_M.0;
                    centre.z = base + floor as f64 * pitch + (sill + lintel) / 2.0;
                    out.push(Window {
                        key: WindowKey {
                            building: index,
                            face: axis as u32 * 2 + u32::from(positive),
                            floor,
                            column,
                        },
                        centre,
                        normal,
                    });
                }
            }
        }
    }
    out
}

/// Separable Gaussian blur of standard deviation `sigma` (pixels; ≤ 0: a copy), the borders
/// clamped.
fn gaussian_blur(src: &[f32], w: usize, h: usize, sigma: f64) -> Vec<f32> {
    if sigma.is_nan() || sigma <= 0.0 || w == 0 || h == 0 {
        return src.to_vec();
    }
    let r = (3.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let mut tmp = vec![0f32; w * h];
    for v in 0..h {
        let row = &src[v * w..(v + 1) * w];
        for u in 0..w {
            let mut s = 0.0;
            for (j, k) in kernel.iter().enumerate() {
                let uu = (u as isize + j as isize - r).clamp(0, w as isize - 1) as usize;
                s += k * row[uu];
            }
            tmp[v * w + u] = s;
        }
    }
    let mut out = vec![0f32; w * h];
    for v in 0..h {
        for (j, k) in kernel.iter().enumerate() {
            let vv = (v as isize + j as isize - r).clamp(0, h as isize - 1) as usize;
            let (src_row, dst) = (&tmp[vv * w..(vv + 1) * w], &mut out[v * w..(v + 1) * w]);
            for (o, s) in dst.iter_mut().zip(src_row) {
                *o += k * s;
            }
        }
    }
    out
}
