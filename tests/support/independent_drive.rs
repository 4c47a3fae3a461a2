//! An independent drive generator (issue #25): a loop with street lamps on both kerbs and
//! building corners, driven at a given speed and frame rate with a Ladybug-like rig read
//! from an INI export (or an equirectangular panorama), satellite GPS with a blackout, and a
//! stretch whose landmarks are not surveyed. It shares no code with `vgps::simulate` (its
//! own path, landmark layout, rig, noise and GNSS models), so that the localizer is measured
//! on drives it was not tuned on.
//!
//! Used by `tests/surrogates_independent_drive.rs` and `examples/independent_drives.rs`.
#![allow(dead_code)]

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};
use std::path::Path;
use std::sync::Arc;
use vgps::calibration::{Camera, CameraModel, Equirectangular, EquirectangularParams, Pixel, Rig};
use vgps::geo::{Geodetic, LocalFrame};
use vgps::geometry::Pose;
use vgps::io::Landmark;
use vgps::localizer::{
    Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions, LocalizerStatus, Measurement,
    Observation,
};

/// The camera rig of a drive.
#[derive(Clone, Copy, Debug)]
pub enum RigKind {
    /// A Ladybug-like head (five portrait side cameras and a top camera, pinhole, written as
    /// an INI export and read back by `vgps::calibration`'s Ladybug INI reader), yawed by
    /// this angle (degrees) from the vehicle's forward axis.
    LadybugIni {
        /// Yaw of camera 0 from forward (degrees).
        yaw_deg: f64,
        /// Focal length (pixels; image 2048 × 2448 portrait).
        focal_px: f64,
    },
    /// One equirectangular panorama of this width (height = width / 2).
    Panorama {
        /// Image width (pixels).
        width: u32,
    },
}

/// What the drive is.
#[derive(Clone, Copy, Debug)]
pub struct DriveSpec {
    /// Seed of every random draw.
    pub seed: u64,
    /// Mean speed (m/s); the speed varies by ±15 % over 40 s.
    pub speed_m_s: f64,
    /// Frame rate (Hz).
    pub frame_rate_hz: f64,
    /// Lamp spacing along each kerb (m); the two kerbs are staggered by half of it.
    pub lamp_spacing_m: f64,
    /// Lateral offset of the lamps from the lane centre (m).
    pub lamp_offset_m: f64,
    /// Building-corner spacing along each side (m).
    pub corner_spacing_m: f64,
    /// Lateral offset of the building corners (m).
    pub corner_offset_m: f64,
    /// Straight sides of the rounded-rectangle loop (m) and its corner radius (m).
    pub loop_sides_m: (f64, f64),
    /// Corner radius of the loop (m).
    pub corner_radius_m: f64,
    /// Start of the stretch without surveyed landmarks in view (m along the loop).
    pub unsurveyed_start_m: f64,
    /// Length of the stretch along which no surveyed landmark is within detection range (m).
    pub unsurveyed_length_m: f64,
    /// Landmarks are detected up to this range (m).
    pub detection_range_m: f64,
    /// Probability that a landmark in range is detected.
    pub detection_probability: f64,
    /// False detections per true detection (Poisson mean).
    pub false_rate: f64,
    /// Pixel noise σ per axis (pixels).
    pub pixel_sigma_px: f64,
    /// Satellite GPS blackout (m along the loop, start and end).
    pub gnss_blackout_m: (f64, f64),
    /// The camera rig.
    pub rig: RigKind,
}

impl DriveSpec {
    /// The issue's drive made fast and sparse: lamps every 30 m, corners every 60 m,
    /// 15 m/s at 15 Hz, a 40 m detection range and 20 % false detections.
    pub fn fast(seed: u64) -> Self {
        Self {
            lamp_spacing_m: 30.0,
            corner_spacing_m: 60.0,
            speed_m_s: 15.0,
            frame_rate_hz: 15.0,
            detection_range_m: 40.0,
            false_rate: 0.2,
            ..Self::issue(seed)
        }
    }

    /// The issue's drive, as described (1 km loop, lamps every 25 m on both kerbs, a corner
    /// every 50 m, 8 m/s at 10 Hz, a Ladybug-like rig, a GPS blackout, 120 m unsurveyed).
    pub fn issue(seed: u64) -> Self {
        Self {
            seed,
            speed_m_s: 8.0,
            frame_rate_hz: 10.0,
            lamp_spacing_m: 25.0,
            lamp_offset_m: 7.0,
            corner_spacing_m: 50.0,
            corner_offset_m: 14.0,
            loop_sides_m: (300.0, 170.0),
            corner_radius_m: 12.0,
            unsurveyed_start_m: 420.0,
            unsurveyed_length_m: 120.0,
            detection_range_m: 50.0,
            detection_probability: 0.9,
            false_rate: 0.1,
            pixel_sigma_px: 0.5,
            gnss_blackout_m: (300.0, 700.0),
            rig: RigKind::LadybugIni {
                yaw_deg: 0.0,
                focal_px: 1100.0,
            },
        }
    }

    /// Loop length (m).
    pub fn loop_length_m(&self) -> f64 {
        2.0 * (self.loop_sides_m.0 + self.loop_sides_m.1)
            + 2.0 * std::f64::consts::PI * self.corner_radius_m
    }
}

/// A generated drive.
pub struct Drive {
    /// The spec.
    pub spec: DriveSpec,
    /// The rig.
    pub rig: Rig,
    /// The INI text of the rig (Ladybug rigs only).
    pub ini: Option<String>,
    /// ENU frame of the generator (and of the map).
    pub frame: LocalFrame,
    /// The surveyed landmarks (2 cm survey noise).
    pub surveyed: Vec<Landmark>,
    /// Per frame: time, truth pose (ENU), distance along the loop, detections (camera, u, v,
    /// class name), the satellite GPS position, and the number of surveyed landmarks within
    /// detection range.
    pub frames: Vec<DriveFrame>,
}

/// One frame of a [`Drive`].
pub struct DriveFrame {
    /// Time (s).
    pub time_s: f64,
    /// Truth `world_from_rig`.
    pub truth: Pose,
    /// Distance along the loop (m).
    pub s_m: f64,
    /// Detections: camera, column, row, class.
    pub detections: Vec<(usize, f64, f64, &'static str)>,
    /// Satellite GPS (none in the blackout).
    pub gnss: Option<Geodetic>,
    /// Surveyed landmarks within detection range.
    pub surveyed_in_range: usize,
}

/// Position (z = 0 plane) and heading of the loop at distance `s` (counter-clockwise
/// rounded rectangle starting at the origin heading east).
fn path_at(spec: &DriveSpec, s: f64) -> (Vector3<f64>, f64) {
    let (a, b) = spec.loop_sides_m;
    let r = spec.corner_radius_m;
    let quarter = 0.5 * std::f64::consts::PI * r;
    let mut s = s.rem_euclid(spec.loop_length_m());
    let mut p = Vector3::zeros();
    let mut heading: f64 = 0.0;
    for side in [a, b, a, b] {
        let dir = Vector3::new(heading.cos(), heading.sin(), 0.0);
        if s <= side {
            return (p + dir * s, heading);
        }
        p += dir * side;
        s -= side;
        let left = Vector3::new(-heading.sin(), heading.cos(), 0.0);
        let centre = p + left * r;
        if s <= quarter {
            let h = heading + s / r;
            return (centre - Vector3::new(-h.sin(), h.cos(), 0.0) * r, h);
        }
        heading += 0.5 * std::f64::consts::PI;
        p = centre - Vector3::new(-heading.sin(), heading.cos(), 0.0) * r;
        s -= quarter;
    }
    (p, heading)
}

/// Ground height at distance `s` (m): a gentle hill of ±3 m.
fn ground_at(spec: &DriveSpec, s: f64) -> f64 {
    3.0 * (2.0 * std::f64::consts::PI * s / spec.loop_length_m()).sin()
}

/// The rig of a drive (and its INI text).
fn make_rig(kind: RigKind) -> (Rig, Option<String>) {
    match kind {
        RigKind::Panorama { width } => {
            let pano = Equirectangular::new(EquirectangularParams {
                width,
                height: width / 2,
            })
            .expect("valid panorama");
            (Rig::panorama(Camera::from(pano)), None)
        }
        RigKind::LadybugIni { yaw_deg, focal_px } => {
            let (w, h) = (2048u32, 2448u32);
            let mut cams = Vec::new();
            for i in 0..6 {
                // Camera axes in the rig: z forward, x right (image columns), y down.
                let (x, y, z, centre) = if i < 5 {
                    let az = (yaw_deg + 72.0 * i as f64).to_radians();
                    let d = Vector3::new(az.cos(), az.sin(), 0.0);
                    // Portrait sensor: columns run down the world vertical.
                    let x = Vector3::new(0.0, 0.0, -1.0);
                    (x, d.cross(&x), d, d * 0.062)
                } else {
                    let z = Vector3::z();
                    let az = yaw_deg.to_radians();
                    let x = Vector3::new(az.cos(), az.sin(), 0.0);
                    (x, z.cross(&x), z, Vector3::new(0.0, 0.0, 0.071))
                };
                let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
                let (rx, ry, rz) = r.euler_angles();
                // Principal points off centre by a few pixels, as calibrated heads are.
                let cx = (f64::from(w) - 1.0) / 2.0 + 3.0 * (i as f64 - 2.5);
                let cy = (f64::from(h) - 1.0) / 2.0 - 2.0 * (i as f64 - 2.5);
                cams.push([
                    rx,
                    ry,
                    rz,
                    centre.x,
                    centre.y,
                    centre.z,
                    focal_px + 4.0 * i as f64,
                    cx,
                    cy,
                ]);
            }
            let text = vgps::calibration::formats::ladybug_ini::to_text(&cams, Some((w, h)));
            let rig = vgps::calibration::formats::ladybug_ini::parse(
                &text,
                Path::new("independent.ini"),
                None,
            )
            .expect("the generated INI parses");
            (rig, Some(text))
        }
    }
}

/// Builds a drive.
pub fn generate(spec: &DriveSpec) -> Drive {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let n = |r: &mut ChaCha8Rng| unit.sample(r);
    let origin = Geodetic::try_new(46.2044, 6.1432, 380.0).expect("valid origin");
    let frame = LocalFrame::new(origin);
    let length = spec.loop_length_m();
    let (rig, ini) = make_rig(spec.rig);

    // Landmarks: (position, class, distance along the loop).
    let mut world: Vec<(Vector3<f64>, &'static str, f64)> = Vec::new();
    let place = |s: f64, offset: f64, height: f64| {
        let (p, h) = path_at(spec, s);
        let left = Vector3::new(-h.sin(), h.cos(), 0.0);
        let mut q = p + left * offset;
        q.z = ground_at(spec, s) + height;
        q
    };
    for (side, stagger) in [(1.0, 0.0), (-1.0, 0.5)] {
        let count = (length / spec.lamp_spacing_m).floor() as usize;
        for k in 0..count {
            let s = (k as f64 + stagger) * spec.lamp_spacing_m + rng.random_range(-1.0..1.0);
            let off = side * (spec.lamp_offset_m + rng.random_range(-0.3..0.3));
            let height = rng.random_range(6.0..9.0);
            world.push((place(s, off, height), "streetlight", s));
        }
        let count = (length / spec.corner_spacing_m).floor() as usize;
        for k in 0..count {
            let s = (k as f64 + 0.25 + 0.5 * stagger) * spec.corner_spacing_m
                + rng.random_range(-3.0..3.0);
            let off = side * (spec.corner_offset_m + rng.random_range(-2.0..2.0));
            let height = rng.random_range(3.0..15.0);
            world.push((place(s, off, height), "corner", s));
        }
    }
    // Not surveyed: every landmark seen from the stretch (within detection range of a point
    // of it), so that no surveyed landmark is in view along its whole length.
    let (u0, u1) = (
        spec.unsurveyed_start_m,
        spec.unsurveyed_start_m + spec.unsurveyed_length_m,
    );
    let stretch: Vec<Vector3<f64>> = (0..=((u1 - u0) as usize))
        .map(|k| {
            let s = u0 + k as f64;
            let (p, _) = path_at(spec, s);
            Vector3::new(p.x, p.y, ground_at(spec, s) + RIG_HEIGHT_M)
        })
        .collect();
    let unsurveyed: Vec<bool> = world
        .iter()
        .map(|(p, _, _)| {
            stretch
                .iter()
                .any(|q| (p - q).norm() <= spec.detection_range_m)
        })
        .collect();
    let mut surveyed = Vec::new();
    let mut surveyed_positions = Vec::new();
    for (k, ((p, class, _), hidden)) in world.iter().zip(&unsurveyed).enumerate() {
        if *hidden {
            continue;
        }
        let noisy = p + Vector3::new(n(&mut rng), n(&mut rng), n(&mut rng)) * 0.02;
        let g = frame.try_to_geodetic(&noisy).expect("landmark in range");
        surveyed_positions.push(*p);
        surveyed.push(Landmark {
            id: format!("L{k:04}"),
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_m: g.alt_m,
            sigma_m: Some(0.02),
            class: Some((*class).to_string()),
            line: 0,
        });
    }

    // The drive: one loop plus 50 m, so that it ends among surveyed landmarks.
    let dt = 1.0 / spec.frame_rate_hz;
    let false_count = Poisson::new(spec.false_rate.max(1e-9)).expect("valid rate");
    let (mut t, mut s) = (0.0f64, 0.0f64);
    let mut bias = Vector3::new(n(&mut rng), n(&mut rng), 0.5 * n(&mut rng)) * 1.5;
    let mut frames = Vec::new();
    let mut yaw_wobble = 0.0f64;
    while s <= length + 50.0 {
        let (p, heading) = path_at(spec, s);
        let grade = ground_at(spec, s + 0.5) - ground_at(spec, s - 0.5);
        let speed = spec.speed_m_s * (1.0 + 0.15 * (2.0 * std::f64::consts::PI * t / 40.0).sin());
        // Body motion: pitch with the grade, roll in the turns and a little sway.
        let (_, h_next) = path_at(spec, s + 1.0);
        let curvature = (h_next - heading + std::f64::consts::PI)
            .rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
        yaw_wobble = 0.95 * yaw_wobble + 0.002 * n(&mut rng);
        let roll = -0.03 * curvature * speed * speed / 9.81 + 0.004 * n(&mut rng);
        let pitch = -grade.atan() + 0.003 * n(&mut rng);
        let rotation = Rotation3::from_euler_angles(roll, pitch, heading + yaw_wobble);
        let position = Vector3::new(p.x, p.y, ground_at(spec, s) + RIG_HEIGHT_M);
        let truth = Pose::from_parts(position.into(), rotation);
        // Detections.
        let mut detections = Vec::new();
        let mut surveyed_in_range = 0;
        for (q, class, _) in &world {
            if (q - position).norm() > spec.detection_range_m {
                continue;
            }
            if rng.random_range(0.0..1.0) > spec.detection_probability {
                continue;
            }
            let in_rig = truth.inverse_transform_point(&(*q).into()).coords;
            if let Some((camera, pixel)) = best_pixel(&rig, &rig.project_point(&in_rig)) {
                let u = pixel.x + spec.pixel_sigma_px * n(&mut rng);
                let v = pixel.y + spec.pixel_sigma_px * n(&mut rng);
                detections.push((camera, u, v, *class));
            }
        }
        for q in &surveyed_positions {
            if (q - position).norm() <= spec.detection_range_m {
                surveyed_in_range += 1;
            }
        }
        let n_false = (0..detections.len())
            .map(|_| false_count.sample(&mut rng) as usize)
            .sum::<usize>()
            .min(60);
        for _ in 0..n_false {
            let az = rng.random_range(0.0..2.0 * std::f64::consts::PI);
            let el = rng.random_range(-0.1f64..0.8);
            let d = Vector3::new(az.cos() * el.cos(), az.sin() * el.cos(), el.sin());
            if let Some((camera, pixel)) = best_pixel(&rig, &rig.project_direction(&d)) {
                let class = if rng.random_range(0.0..1.0) < 0.5 {
                    "streetlight"
                } else {
                    "corner"
                };
                detections.push((camera, pixel.x, pixel.y, class));
            }
        }
        // Shuffle so that the order says nothing about truth.
        for k in (1..detections.len()).rev() {
            let j = rng.random_range(0..=k);
            detections.swap(k, j);
        }
        // Satellite GPS: a bias that wanders (60 s correlation) plus 0.4 m white noise.
        let a = (-dt / 60.0f64).exp();
        let step = (1.0 - a * a).sqrt() * 1.5;
        bias = bias * a + Vector3::new(n(&mut rng), n(&mut rng), 0.5 * n(&mut rng)) * step;
        let in_blackout = {
            let sl = s.rem_euclid(length);
            sl >= spec.gnss_blackout_m.0 && sl <= spec.gnss_blackout_m.1
        };
        let gnss = (!in_blackout).then(|| {
            let g = position + bias + Vector3::new(n(&mut rng), n(&mut rng), n(&mut rng)) * 0.4;
            frame.try_to_geodetic(&g).expect("gnss in range")
        });
        frames.push(DriveFrame {
            time_s: 1_700_000_000.0 + t,
            truth,
            s_m: s,
            detections,
            gnss,
            surveyed_in_range,
        });
        t += dt;
        s += speed * dt;
    }
    Drive {
        spec: *spec,
        rig,
        ini,
        frame,
        surveyed,
        frames,
    }
}

/// Height of the rig above the road (m).
pub const RIG_HEIGHT_M: f64 = 2.3;

/// The pixel nearest its image centre among the cameras that see a point.
fn best_pixel(rig: &Rig, seen: &[vgps::calibration::RigPixel]) -> Option<(usize, Pixel)> {
    seen.iter()
        .filter_map(|p| {
            let cam = rig.camera(p.camera).ok()?;
            let (w, h) = cam.model.image_size();
            let off =
                (p.pixel.x / f64::from(w) - 0.5).powi(2) + (p.pixel.y / f64::from(h) - 0.5).powi(2);
            Some((off, p.camera, p.pixel))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c, p)| (c, p))
}

/// What a replay of a drive measured.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Frames.
    pub frames: usize,
    /// Frames with an `ok` fix.
    pub fixes: usize,
    /// Horizontal errors of the `ok` fixes (m), sorted.
    pub errors_m: Vec<f64>,
    /// Frames of the stretch without surveyed landmarks in range, and how many were fixed.
    pub stretch_frames: (usize, usize),
    /// Longest distance (m) driven with `ok` fixes using fewer than three surveyed landmarks.
    pub carried_m: f64,
    /// Distance (m) of the longest run with no surveyed landmark in range.
    pub unsurveyed_run_m: f64,
    /// Frames fixed per second of wall time.
    pub frames_per_s: f64,
}

impl Outcome {
    /// Fraction of frames with a fix.
    pub fn availability(&self) -> f64 {
        self.fixes as f64 / self.frames.max(1) as f64
    }

    /// A percentile of the horizontal error (m).
    pub fn cep(&self, q: f64) -> f64 {
        if self.errors_m.is_empty() {
            return f64::NAN;
        }
        let k = ((self.errors_m.len() as f64 - 1.0) * q).round() as usize;
        self.errors_m[k]
    }
}

/// Replays a drive through the localizer (default options).
pub fn replay(drive: &Drive) -> Outcome {
    let mut options = LocalizerOptions::default();
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    if let Some(v) = env("VGPS_PAR") {
        options.mapper.surrogate.min_parallax_rad = v;
    }
    if let Some(v) = env("VGPS_SIG") {
        options.mapper.surrogate.max_sigma_m = v;
    }
    if let Some(v) = env("VGPS_RAYS") {
        options.mapper.surrogate.min_rays = v as usize;
    }
    replay_with(drive, options, |_, _| {})
}

/// Replays a drive through the localizer with `options`, calling `each(frame index, fix)`.
pub fn replay_with(
    drive: &Drive,
    options: LocalizerOptions,
    mut each: impl FnMut(usize, &vgps::localizer::LocalizerFix),
) -> Outcome {
    let map = Arc::new(
        LandmarkMap::from_landmarks(&drive.surveyed, Some(drive.frame.origin()))
            .expect("valid map"),
    );
    let mut localizer =
        Localizer::new(Arc::new(drive.rig.clone()), Arc::clone(&map), options).expect("options");
    let mut errors = Vec::new();
    let mut fixes = 0;
    let (mut stretch, mut stretch_fixed) = (0, 0);
    let (mut carried, mut run_start): (f64, Option<f64>) = (0.0, None);
    let (mut unsurveyed, mut un_start): (f64, Option<f64>) = (0.0, None);
    let start = std::time::Instant::now();
    let trace = std::env::var_os("VGPS_TRACE").is_some();
    for (k, f) in drive.frames.iter().enumerate() {
        let observations = f
            .detections
            .iter()
            .map(|&(camera, u, v, class)| Observation {
                measurement: Measurement::Pixel { camera, u, v },
                class: map.class_index(class),
            })
            .collect();
        let frame = Frame {
            time_s: f.time_s,
            observations,
            gnss: f.gnss.map(|position| GnssPosition { position }),
            attitude: None,
        };
        let fix = localizer.process(&frame);
        each(k, &fix);
        if trace {
            let all = localizer.mapped_landmarks();
            let near: Vec<_> = all
                .iter()
                .filter(|l| (l.position_enu - f.truth.translation.vector).norm() < 50.0)
                .collect();
            let good = near
                .iter()
                .filter(|l| l.n_obs >= 5 && l.sigma_m() <= 0.5)
                .count();
            let par = near
                .iter()
                .filter(|l| l.n_obs >= 5 && l.max_parallax_rad >= 0.1)
                .count();
            let err = fix.estimate.as_ref().map_or(f64::NAN, |e| {
                (e.world_from_rig.translation.vector - f.truth.translation.vector)
                    .xy()
                    .norm()
            });
            let sig = fix.estimate.as_ref().map_or(f64::NAN, |e| {
                (e.covariance[(0, 0)] + e.covariance[(1, 1)])
                    .max(0.0)
                    .sqrt()
            });
            println!(
                "{k} s={:.0} err={err:.2} sig={sig:.2} sv={} {} [{}] surr={} mapped_near={} (n>=5&sig<=0.5: {good}, n>=5&par: {par}) det={}",
                f.s_m,
                f.surveyed_in_range,
                fix.status,
                fix.message,
                localizer.surrogates().len(),
                near.len(),
                f.detections.len()
            );
        }
        let ok = fix.status == LocalizerStatus::Ok;
        if f.surveyed_in_range == 0 {
            stretch += 1;
            stretch_fixed += usize::from(ok);
            let s0 = *un_start.get_or_insert(f.s_m);
            unsurveyed = unsurveyed.max(f.s_m - s0);
        } else {
            un_start = None;
        }
        match &fix.estimate {
            Some(e) if ok => {
                fixes += 1;
                let d = e.world_from_rig.translation.vector - f.truth.translation.vector;
                errors.push(d.xy().norm());
                if e.landmarks.len() < 3 {
                    let s0 = *run_start.get_or_insert(f.s_m);
                    carried = carried.max(f.s_m - s0);
                } else {
                    run_start = None;
                }
            }
            _ => run_start = None,
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    errors.sort_by(f64::total_cmp);
    Outcome {
        frames: drive.frames.len(),
        fixes,
        errors_m: errors,
        stretch_frames: (stretch, stretch_fixed),
        carried_m: carried,
        unsurveyed_run_m: unsurveyed,
        frames_per_s: drive.frames.len() as f64 / elapsed.max(1e-9),
    }
}
