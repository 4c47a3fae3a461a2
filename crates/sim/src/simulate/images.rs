//! Night images of a simulated drive: every camera of every frame rendered through the
//! calibration ([`crate::render::Renderer`]) and written as PNG (`vgps simulate --images`).
//!
//! What is drawn in the image of camera `k` at frame `f` is what the simulator says camera
//! `k` sees ([`SimFrame::visible`]): the streetlights (lamps of radius
//! [`ImageOptions::lamp_radius_m`]) and the transient lights (car lights, windows: radius
//! [`ImageOptions::transient_radius_m`], intensity drawn per light), with the renderer's
//! range-dependent blob size and brightness, read and shot noise, plus
//! [`RenderOptions::clutter_lights`] clutter spots. Building corners are not lights and are
//! not drawn. Everything is deterministic for the scenario seed: the image of `(f, k)` uses
//! the seed [`image_seed`]`(seed, f, k)`, whatever the number of threads.
//!
//! Files: `images/FFFFFF_K.png` ([`image_name`]), the `image_0 … image_5` columns of
//! `frames.csv`, and the sidecar `images_truth.csv` (`frame,camera,kind,landmark,u,v,
//! range_m,peak_dn,clipped`: every drawn spot, `kind` = `lamp`, `transient` or `clutter`).
//!
//! By day ([`TimeOfDay::Day`]) the frames are rendered by [`crate::day`] instead: buildings
//! lit by the sun of the frame's time at the scenario's origin, optionally written as JPEG
//! (`images/FFFFFF_K.jpg`, [`ImageOptions::jpeg_quality`]); the truth rows are the visible
//! corner landmarks (`kind` = `corner`, `peak_dn` empty, `clipped` = closer than
//! [`crate::day::render::BORDER_PX`] to the border).

use super::{SimFrame, SimulatedDrive, Source};
use crate::day::{DayOptions, DayRenderer, DayScene, sun_position};
use crate::night::{NightOptions, NightRenderer, NightSpotKind};
use crate::render::{LightSource, RenderOptions, RenderedFrame, Renderer, SpotKind};
use rand::{RngExt, SeedableRng};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use vgps_camera::imaging::encode_png;
use vgps_replay::drive::{DriveError, FrameRecord, MAX_IMAGE_COLUMNS, frames_to_csv, write_text};

/// The image directory inside a drive.
pub const IMAGES_DIR: &str = "images";
/// The image truth sidecar's file name.
pub const IMAGES_TRUTH_NAME: &str = "images_truth.csv";
/// Default radius of a streetlight's glowing part (metres).
pub const DEFAULT_LAMP_RADIUS_M: f64 = 0.2;
/// Default radius of a transient light (metres).
pub const DEFAULT_TRANSIENT_RADIUS_M: f64 = 0.1;
/// Default number of clutter spots per image.
pub const DEFAULT_CLUTTER_LIGHTS: usize = 3;
/// Salt of the per-image seed.
const IMAGE_SEED_SALT: u64 = 0x696d_6167_6573_0001;

/// What the images of a simulated drive show. [`Default`]: unit-intensity lamps of radius
/// [`DEFAULT_LAMP_RADIUS_M`], transient lights of radius [`DEFAULT_TRANSIENT_RADIUS_M`] and
/// intensity 0.3–1, the renderer's defaults with [`DEFAULT_CLUTTER_LIGHTS`] clutter spots.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageOptions {
    /// The renderer's parameters.
    pub render: RenderOptions,
    /// Radius of a lamp's glowing part (metres).
    pub lamp_radius_m: f64,
    /// Relative intensity of a lamp (1 = typical).
    pub lamp_intensity: f64,
    /// Radius of a transient light (metres).
    pub transient_radius_m: f64,
    /// Range of a transient light's relative intensity, drawn uniformly per light.
    pub transient_intensity: (f64, f64),
    /// Night (lamps) or day (buildings in sunlight).
    pub time_of_day: TimeOfDay,
    /// The day renderer's parameters.
    pub day: DayOptions,
    /// Write JPEG at this quality (1–100) instead of PNG.
    pub jpeg_quality: Option<u8>,
    /// Which night renderer draws night images.
    pub night_scene: NightScene,
    /// The realistic night renderer's parameters ([`NightScene::Realistic`]).
    pub night: NightOptions,
}

/// The night renderer of [`TimeOfDay::Night`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NightScene {
    /// Lamps, transient lights and clutter spots on a flat dark background
    /// ([`crate::render`]): fast, the tests' and the demo's.
    #[default]
    Flat,
    /// The day scene at night with lamps, lit windows, car lights, wet-road reflections,
    /// bloom and vignetting ([`crate::night`]); transient lights and clutter spots are
    /// replaced by the scene's own windows and cars.
    Realistic,
}

/// What the images show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeOfDay {
    /// Street lamps on a dark background ([`crate::render`]).
    #[default]
    Night,
    /// Buildings, streets and clutter in daylight ([`crate::day`]).
    Day,
}

impl Default for ImageOptions {
    fn default() -> Self {
        Self {
            render: RenderOptions {
                clutter_lights: DEFAULT_CLUTTER_LIGHTS,
                ..RenderOptions::default()
            },
            lamp_radius_m: DEFAULT_LAMP_RADIUS_M,
            lamp_intensity: 1.0,
            transient_radius_m: DEFAULT_TRANSIENT_RADIUS_M,
            transient_intensity: (0.3, 1.0),
            time_of_day: TimeOfDay::Night,
            day: DayOptions::default(),
            jpeg_quality: None,
            night_scene: NightScene::Flat,
            night: NightOptions::default(),
        }
    }
}

/// Counts of [`write_images`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImagesSummary {
    /// PNG files written.
    pub images: usize,
    /// Their total size (bytes).
    pub bytes: u64,
    /// Lamp spots drawn.
    pub lamps: usize,
    /// Transient-light spots drawn.
    pub transients: usize,
    /// Clutter spots drawn.
    pub clutter: usize,
    /// Visible corner landmarks (day images).
    pub corners: usize,
    /// Visible lit windows (realistic night images).
    pub windows: usize,
    /// Head- and taillights drawn (realistic night images).
    pub car_lights: usize,
    /// Wet-road reflections drawn (realistic night images).
    pub reflections: usize,
}

/// The image file of camera `camera` at frame `frame`, relative to the drive directory
/// (`images/000123_2.png`).
pub fn image_name(frame: u64, camera: usize) -> String {
    image_name_with_extension(frame, camera, "png")
}

/// [`image_name`] with another extension (`jpg`).
pub fn image_name_with_extension(frame: u64, camera: usize, extension: &str) -> String {
    format!("{IMAGES_DIR}/{frame:06}_{camera}.{extension}")
}

/// Encodes an image as PNG, or as JPEG at `quality` (clamped to 1–100).
///
/// # Errors
/// The encoder's message.
pub fn encode_image(image: &image::GrayImage, jpeg_quality: Option<u8>) -> Result<Vec<u8>, String> {
    match jpeg_quality {
        None => encode_png(image).map_err(|e| e.to_string()),
        Some(q) => {
            let mut bytes = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, q.clamp(1, 100))
                .encode_image(image)
                .map_err(|e| e.to_string())?;
            Ok(bytes)
        }
    }
}

/// The render seed of camera `camera` at frame `frame` for the scenario seed `seed`.
pub fn image_seed(seed: u64, frame: u64, camera: usize) -> u64 {
    let mut z = seed ^ IMAGE_SEED_SALT;
    for x in [frame, camera as u64] {
        z = crate::render::splitmix64(z ^ x);
    }
    z
}

/// The lights camera `camera` sees at `frame` (lamps and transient lights, in the order of
/// [`SimFrame::visible`]) with what each is (`Source`).
pub fn lights_of(
    drive: &SimulatedDrive,
    frame: &SimFrame,
    camera: usize,
    options: &ImageOptions,
) -> Vec<(LightSource, Source)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(image_seed(
        drive.scenario.seed,
        frame.frame,
        camera,
    ));
    let (i0, i1) = options.transient_intensity;
    frame
        .visible
        .iter()
        .filter(|v| v.camera == camera)
        .filter_map(|v| {
            let (radius_m, intensity) = match v.source {
                Source::Landmark(i) => {
                    let lamp =
                        drive.world.landmarks.get(i)?.class == super::LandmarkClass::Streetlight;
                    if !lamp {
                        return None;
                    }
                    (options.lamp_radius_m, options.lamp_intensity)
                }
                Source::Transient => (
                    options.transient_radius_m,
                    i0 + rng.random_range(0.0..1.0) * (i1 - i0),
                ),
            };
            Some((
                LightSource {
                    point_in_camera: v.point_in_camera,
                    radius_m,
                    intensity,
                },
                v.source,
            ))
        })
        .collect()
}

/// Renders every camera of `frame` (index order of the rig), with the lights of
/// [`lights_of`] and the seed of [`image_seed`]; returns each image with its lights' sources.
pub fn render_frame(
    drive: &SimulatedDrive,
    frame: &SimFrame,
    renderer: &Renderer,
    options: &ImageOptions,
) -> Vec<(RenderedFrame, Vec<Source>)> {
    drive
        .scenario
        .rig
        .cameras()
        .iter()
        .enumerate()
        .map(|(k, camera)| {
            let (lights, sources): (Vec<LightSource>, Vec<Source>) =
                lights_of(drive, frame, k, options).into_iter().unzip();
            let seed = image_seed(drive.scenario.seed, frame.frame, k);
            (renderer.render(&camera.model, &lights, seed), sources)
        })
        .collect()
}

/// Renders and writes the images of every frame under `dir/images/`, rewrites
/// `dir/frames.csv` with the image columns and writes `dir/images_truth.csv`. Frames are
/// rendered and encoded on `threads` threads (scoped threads taking frames in turn); the
/// files do not depend on the number of threads. `progress` is called with the number of
/// frames finished since its last call.
///
/// # Errors
/// [`DriveError::Write`] naming the file that cannot be written (or the rig with more
/// cameras than the drive format's [`MAX_IMAGE_COLUMNS`]).
pub fn write_images(
    drive: &SimulatedDrive,
    dir: &Path,
    options: &ImageOptions,
    threads: usize,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<ImagesSummary, DriveError> {
    let cameras = drive.scenario.rig.len();
    let werr = |path: PathBuf, message: String| DriveError::Write {
        path,
        source: std::io::Error::other(message),
    };
    if cameras > MAX_IMAGE_COLUMNS {
        return Err(werr(
            dir.join("frames.csv"),
            format!(
                "the rig has {cameras} cameras, the drive format names at most {MAX_IMAGE_COLUMNS} images per frame"
            ),
        ));
    }
    let images_dir = dir.join(IMAGES_DIR);
    std::fs::create_dir_all(&images_dir).map_err(|source| DriveError::Write {
        path: images_dir.clone(),
        source,
    })?;
    let renderer = Renderer::new(options.render.clone());
    let extension = extension_of(options);
    let scene = || DayScene::from_world(&drive.world, drive.scenario.block_m, drive.scenario.seed);
    let day = (options.time_of_day == TimeOfDay::Day).then(|| {
        (
            scene(),
            DayRenderer::new(options.day.clone(), &drive.scenario.rig),
        )
    });
    let realistic =
        options.time_of_day == TimeOfDay::Night && options.night_scene == NightScene::Realistic;
    let night = realistic.then(|| {
        (
            scene(),
            NightRenderer::new(options.night.clone(), &drive.scenario.rig),
        )
    });
    let next = AtomicUsize::new(0);
    let threads = threads.clamp(1, drive.frames.len().max(1));
    type FrameOutput = (usize, String, ImagesSummary);
    let worker = || -> Result<Vec<FrameOutput>, DriveError> {
        let mut done = Vec::new();
        loop {
            let index = next.fetch_add(1, Ordering::Relaxed);
            let Some(frame) = drive.frames.get(index) else {
                return Ok(done);
            };
            if let Some((scene, day_renderer)) = &day {
                let (rows, summary) =
                    write_day_frame(drive, frame, scene, day_renderer, dir, options)?;
                progress(1);
                done.push((index, rows, summary));
                continue;
            }
            if let Some((scene, night_renderer)) = &night {
                let (rows, summary) =
                    write_night_frame(drive, frame, scene, night_renderer, dir, options)?;
                progress(1);
                done.push((index, rows, summary));
                continue;
            }
            let mut rows = String::new();
            let mut summary = ImagesSummary::default();
            for (camera, (rendered, sources)) in render_frame(drive, frame, &renderer, options)
                .into_iter()
                .enumerate()
            {
                summary.bytes += write_image(dir, frame.frame, camera, &rendered.image, options)?;
                summary.images += 1;
                for spot in &rendered.spots {
                    let (kind, label) = match spot.kind {
                        SpotKind::Lamp(i) => match sources.get(i) {
                            Some(Source::Landmark(l)) => {
                                summary.lamps += 1;
                                ("lamp", drive.world.landmarks[*l].id.as_str())
                            }
                            _ => {
                                summary.transients += 1;
                                ("transient", "")
                            }
                        },
                        SpotKind::Clutter => {
                            summary.clutter += 1;
                            ("clutter", "")
                        }
                    };
                    let _ = writeln!(
                        rows,
                        "{},{camera},{kind},{label},{:.3},{:.3},{},{:.1},{}",
                        frame.frame,
                        spot.u,
                        spot.v,
                        spot.range_m.map_or(String::new(), |r| format!("{r:.2}")),
                        spot.peak_dn,
                        spot.clipped_by_border
                    );
                }
            }
            progress(1);
            done.push((index, rows, summary));
        }
    };
    let mut outputs: Vec<FrameOutput> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(worker)).collect();
        let mut all = Vec::with_capacity(drive.frames.len());
        for h in handles {
            match h.join() {
                Ok(Ok(part)) => all.extend(part),
                Ok(Err(e)) => return Err(e),
                Err(_) => return Err(werr(images_dir.clone(), "a render thread panicked".into())),
            }
        }
        Ok(all)
    })?;
    outputs.sort_by_key(|o| o.0);
    let mut total = ImagesSummary::default();
    let mut truth = String::from("frame,camera,kind,landmark,u,v,range_m,peak_dn,clipped\n");
    for (_, rows, s) in &outputs {
        truth.push_str(rows);
        total.images += s.images;
        total.bytes += s.bytes;
        total.lamps += s.lamps;
        total.transients += s.transients;
        total.clutter += s.clutter;
        total.corners += s.corners;
        total.windows += s.windows;
        total.car_lights += s.car_lights;
        total.reflections += s.reflections;
    }
    write_text(&dir.join(IMAGES_TRUTH_NAME), &truth)?;
    let frames: Vec<FrameRecord> = drive
        .frames
        .iter()
        .map(|f| FrameRecord {
            frame: f.frame,
            time_s: f.time_s,
            images: (0..cameras)
                .map(|k| Some(image_name_with_extension(f.frame, k, extension)))
                .collect(),
        })
        .collect();
    write_text(&dir.join("frames.csv"), &frames_to_csv(&frames))?;
    Ok(total)
}

/// The image file extension of `options`.
fn extension_of(options: &ImageOptions) -> &'static str {
    if options.jpeg_quality.is_some() {
        "jpg"
    } else {
        "png"
    }
}

/// Renders, encodes and writes the day images of every camera of `frame`; returns its truth
/// rows and counts.
fn write_day_frame(
    drive: &SimulatedDrive,
    frame: &SimFrame,
    scene: &DayScene,
    renderer: &DayRenderer,
    dir: &Path,
    options: &ImageOptions,
) -> Result<(String, ImagesSummary), DriveError> {
    let origin = &drive.scenario.origin;
    let sun = sun_position(frame.time_s, origin.lat_deg, origin.lon_deg).direction_in_enu();
    let mut rows = String::new();
    let mut summary = ImagesSummary::default();
    for camera in 0..drive.scenario.rig.len() {
        let seed = image_seed(drive.scenario.seed, frame.frame, camera);
        let Some(rendered) = renderer.render(scene, &frame.world_from_rig, camera, &sun, seed)
        else {
            continue;
        };
        summary.bytes += write_image(dir, frame.frame, camera, &rendered.image, options)?;
        summary.images += 1;
        for c in &rendered.corners {
            summary.corners += 1;
            let _ = writeln!(
                rows,
                "{},{camera},corner,{},{:.3},{:.3},{:.2},,{}",
                frame.frame,
                drive.world.landmarks[c.landmark].id,
                c.u,
                c.v,
                c.range_m,
                c.near_border
            );
        }
    }
    Ok((rows, summary))
}

/// Renders, encodes and writes the realistic night images of every camera of `frame`;
/// returns its truth rows and counts. Only the streetlights of [`lights_of`] are drawn as
/// lamps: the scene's windows and cars take the place of the transient lights and clutter.
fn write_night_frame(
    drive: &SimulatedDrive,
    frame: &SimFrame,
    scene: &DayScene,
    renderer: &NightRenderer,
    dir: &Path,
    options: &ImageOptions,
) -> Result<(String, ImagesSummary), DriveError> {
    let mut rows = String::new();
    let mut summary = ImagesSummary::default();
    for camera in 0..drive.scenario.rig.len() {
        let (lights, landmarks): (Vec<LightSource>, Vec<usize>) =
            lights_of(drive, frame, camera, options)
                .into_iter()
                .filter_map(|(light, source)| match source {
                    Source::Landmark(l) => Some((light, l)),
                    Source::Transient => None,
                })
                .unzip();
        let seed = image_seed(drive.scenario.seed, frame.frame, camera);
        let Some(rendered) = renderer.render(scene, &frame.world_from_rig, camera, &lights, seed)
        else {
            continue;
        };
        summary.bytes += write_image(dir, frame.frame, camera, &rendered.image, options)?;
        summary.images += 1;
        let id = |i: usize| {
            landmarks
                .get(i)
                .and_then(|&l| drive.world.landmarks.get(l))
                .map_or("", |l| l.id.as_str())
        };
        for spot in &rendered.spots {
            let (kind, label) = match spot.kind {
                NightSpotKind::Lamp(i) => {
                    summary.lamps += 1;
                    ("lamp", id(i))
                }
                NightSpotKind::Reflection(i) => {
                    summary.reflections += 1;
                    ("reflection", id(i))
                }
                NightSpotKind::Window => {
                    summary.windows += 1;
                    ("window", "")
                }
                NightSpotKind::Headlight => {
                    summary.car_lights += 1;
                    ("headlight", "")
                }
                NightSpotKind::Taillight => {
                    summary.car_lights += 1;
                    ("taillight", "")
                }
            };
            let _ = writeln!(
                rows,
                "{},{camera},{kind},{label},{:.3},{:.3},{:.2},{:.1},{}",
                frame.frame, spot.u, spot.v, spot.range_m, spot.peak_dn, spot.clipped_by_border
            );
        }
    }
    Ok((rows, summary))
}

/// Encodes `image` as `options` ask and writes it as the image of `(frame, camera)` under
/// `dir`; returns its size in bytes.
fn write_image(
    dir: &Path,
    frame: u64,
    camera: usize,
    image: &image::GrayImage,
    options: &ImageOptions,
) -> Result<u64, DriveError> {
    let path = dir.join(image_name_with_extension(
        frame,
        camera,
        extension_of(options),
    ));
    let bytes = encode_image(image, options.jpeg_quality).map_err(|e| DriveError::Write {
        path: path.clone(),
        source: std::io::Error::other(e),
    })?;
    write_bytes(&path, &bytes)?;
    Ok(bytes.len() as u64)
}

/// Writes bytes atomically (temporary file in the same directory, then a rename).
fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), DriveError> {
    vgps_io::write_atomic(path, bytes).map_err(|source| DriveError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{Preset, Scenario, simulate};

    fn short_drive() -> SimulatedDrive {
        let mut sc = Scenario::preset(Preset::Short, 5);
        sc.length_m = 60.0;
        simulate(&sc).unwrap()
    }

    #[test]
    fn images_are_deterministic_and_thread_independent() {
        let drive = short_drive();
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let options = ImageOptions::default();
        let sa = write_images(&drive, a.path(), &options, 1, &|_| {}).unwrap();
        let sb = write_images(&drive, b.path(), &options, 3, &|_| {}).unwrap();
        assert_eq!(sa, sb);
        assert_eq!(sa.images, drive.frames.len() * 6);
        assert!(sa.lamps > drive.frames.len(), "{sa:?}");
        for name in [IMAGES_TRUTH_NAME, "frames.csv"] {
            assert_eq!(
                std::fs::read(a.path().join(name)).unwrap(),
                std::fs::read(b.path().join(name)).unwrap()
            );
        }
        let f = &drive.frames[drive.frames.len() / 2];
        for k in 0..6 {
            let name = image_name(f.frame, k);
            assert_eq!(
                std::fs::read(a.path().join(&name)).unwrap(),
                std::fs::read(b.path().join(&name)).unwrap()
            );
        }
    }

    #[test]
    fn lamps_are_drawn_where_the_simulator_projects_them() {
        let drive = short_drive();
        let options = ImageOptions::default();
        let renderer = Renderer::new(options.render.clone());
        let frame = &drive.frames[3];
        let images = render_frame(&drive, frame, &renderer, &options);
        let mut checked = 0;
        for v in &frame.visible {
            let Source::Landmark(i) = v.source else {
                continue;
            };
            if drive.world.landmarks[i].class != super::super::LandmarkClass::Streetlight {
                continue;
            }
            let (rendered, _) = &images[v.camera];
            let spot = rendered
                .spots
                .iter()
                .find(|s| (s.u - v.pixel.x).hypot(s.v - v.pixel.y) < 1e-6);
            assert!(spot.is_some(), "lamp {i} in camera {} not drawn", v.camera);
            checked += 1;
        }
        assert!(checked > 3, "only {checked} lamps in view");
        assert_ne!(image_seed(1, 2, 3), image_seed(1, 3, 2));
        assert_eq!(image_name(123, 2), "images/000123_2.png");
    }
}
