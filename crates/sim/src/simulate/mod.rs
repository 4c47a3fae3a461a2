//! Simulated drives: a city of blocks, buildings, streetlights and building corners; a
//! vehicle with a spherical camera rig driving a route through it; detections of what the
//! rig sees; satellite GPS with bias, latency and outages. `docs/simulate.md` describes the
//! model, the presets and the files.
//!
//! - [`Scenario::preset`] gives a scenario ([`Preset::Reference`] for the demo and the
//!   benchmarks, [`Preset::Short`] for tests); every parameter is a public field.
//! - [`simulate`] runs it in memory ([`SimulatedDrive`]: world, poses, per-frame visible
//!   points and detections with their truth labels, GNSS epochs, outages).
//! - [`SimulatedDrive::write`] writes a drive directory ([`vgps_replay::drive`]) plus the sidecar
//!   files `world_landmarks.csv`, `detections_truth.csv` and `simulation.json`.
//!
//! The same scenario (and seed) gives byte-identical files.
//!
//! # Frames
//! The world frame is ENU at the scenario origin (metres); the ground is the plane `z = 0`
//! (ellipsoidal height of the origin). Poses are `world_from_rig` in that frame; the truth
//! file gives them as WGS84 positions and `enu_from_rig` in the local-level ENU frame at
//! the rig's own position.
//!
//! # Example
//! ```
//! use vgps_sim::simulate::{simulate, Preset, Scenario};
//! let mut scenario = Scenario::preset(Preset::Short, 3);
//! scenario.length_m = 200.0;
//! let drive = simulate(&scenario)?;
//! assert!(drive.frames.len() > 80);
//! assert!(drive.frames.iter().all(|f| !f.detections.is_empty()));
//! # Ok::<(), vgps_sim::simulate::SimulateError>(())
//! ```

pub mod images;
mod route;
mod world;

pub use route::{Route, TURN_RADIUS_M};
pub use world::{
    Building, CORNER_CLEARANCE_M, CityParams, KERB_M, LAMP_ARM_M, LandmarkClass, SETBACK_M, Source,
    VisiblePoint, World, WorldLandmark, observe, project,
};

use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{Rng, RngExt};
use std::fmt::Write as _;
use std::path::Path;
use vgps_camera::calibration::{CameraModel, LoadError};
use vgps_camera::calibration::{Pixel, Rig, in_image_rectangle};
use vgps_geometry::geo::{GeoError, Geodetic, LocalFrame};
use vgps_geometry::geometry::Pose;
use vgps_io::Landmark;
use vgps_replay::drive::nmea::{GnssFix, GnssRecord, write_nmea};
use vgps_replay::drive::{
    DriveError, FrameRecord, Manifest, PixelDetection, TruthRecord, detections_to_csv,
    frames_to_csv, landmarks_to_csv, truth_to_csv, write_manifest, write_text,
};

/// The bundled default calibration (the Ladybug2 rig of `calibration/ladybug2.json`).
pub const DEFAULT_CALIBRATION_JSON: &str = include_str!("../../../../calibration/ladybug2.json");
/// The default origin: San Francisco, near Civic Center (latitude, longitude, degrees).
pub const DEFAULT_ORIGIN_DEG: (f64, f64) = (37.7793, -122.4193);
/// Start of every simulated drive: 2026-05-14 21:30:00 UTC (Unix seconds).
pub const DEFAULT_START_UNIX_S: f64 = 1_778_794_200.0;
/// CEP (50 % horizontal radius) of a circular Gaussian per unit per-axis σ: √(2 ln 2).
pub const CEP_PER_SIGMA: f64 = 1.177_410_022_515_474_6;
/// Time step of the vehicle's speed integration, seconds.
const INTEGRATION_STEP_S: f64 = 0.01;
/// Extra margin beyond the detection range within which landmarks of the survey gap are
/// left out of the survey, metres.
const SURVEY_GAP_MARGIN_M: f64 = 10.0;
/// Spacing of the route samples used to find the landmarks near the survey gap, metres.
const GAP_SAMPLE_M: f64 = 5.0;
/// The first this many metres of a route are surveyed: the survey gap starts no earlier,
/// and the landmarks within the detection range of this stretch stay out of the gap's
/// unsurveyed zone. A drive starts where the survey covers the street, as a user switching
/// vgps on in a surveyed city; without it the zone of a short route's gap (the gap plus the
/// detection range around it) covered the whole route, so no frame had a surveyed
/// landmark in view at night (the README's 150 m drive: 0 surveyed lamps after frame 10).
pub const SURVEYED_LEAD_IN_M: f64 = 100.0;
/// Attempts to place one transient light in some camera's view.
const TRANSIENT_ATTEMPTS: usize = 10;
/// Smallest share of the route without a GPS fix (the canyon outage is lengthened to reach
/// it on long routes).
pub const MIN_OUTAGE_SHARE: f64 = 0.16;
/// Pixel coordinates are written rounded to this step (pixels).
const PIXEL_QUANTUM: f64 = 1e-3;

/// Errors of the simulation.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// A scenario parameter is invalid.
    #[error("invalid scenario: {0}")]
    Scenario(String),
    /// A position fell outside the valid geodetic range (an absurd origin or length).
    #[error("geodesy: {0}")]
    Geo(#[from] GeoError),
    /// The bundled calibration cannot be parsed (a build problem).
    #[error(transparent)]
    Calibration(#[from] LoadError),
}

/// A named scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// The fixed scenario of `vgps demo` and the benchmarks: 2.4 km at 15 frames/s.
    Reference,
    /// A short drive for tests: 900 m at 5 frames/s.
    Short,
}

impl Preset {
    /// The preset's name (`reference`, `short`).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Reference => "reference",
            Preset::Short => "short",
        }
    }
}

/// Every parameter of a simulation.
///
/// # Units
/// Metres, seconds, metres per second, degrees where the name says `_deg`, pixels `_px`.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The preset it started from.
    pub preset: Preset,
    /// Random seed.
    pub seed: u64,
    /// The world origin (ENU frame anchor; ground height).
    pub origin: Geodetic,
    /// The camera rig.
    pub rig: Rig,
    /// A label of the calibration for `simulation.json`.
    pub calibration_name: String,
    /// Route length.
    pub length_m: f64,
    /// Frame rate (frames per second).
    pub frame_rate_hz: f64,
    /// Unix time of the first frame.
    pub start_unix_s: f64,
    /// Street spacing (centre line to centre line).
    pub block_m: f64,
    /// Distance of the driven lane right of the centre line.
    pub lane_offset_m: f64,
    /// Lowest speed (turns, start, end).
    pub speed_min_mps: f64,
    /// Range of the cruising speed drawn per straight.
    pub speed_cruise_mps: (f64, f64),
    /// Longitudinal acceleration limit.
    pub accel_mps2: f64,
    /// Height of the rig origin above the road.
    pub rig_height_m: f64,
    /// Amplitudes of the two sinusoids of pitch and of roll (sum ≤ 1°).
    pub tilt_amplitudes_deg: (f64, f64),
    /// Lamp spacing along a kerb.
    pub lamp_spacing_m: f64,
    /// Lamp heights.
    pub lamp_height_m: (f64, f64),
    /// Building heights.
    pub building_height_m: (f64, f64),
    /// Fraction of landmarks (outside the survey gap) in the surveyed file.
    pub surveyed_fraction: f64,
    /// Survey error σ per axis (written as `sigma_m`).
    pub survey_sigma_m: f64,
    /// Detection range.
    pub range_m: f64,
    /// Pixel noise σ per axis.
    pub pixel_sigma_px: f64,
    /// Probability of missing a visible landmark in one camera.
    pub miss_rate: f64,
    /// Expected fraction of false detections among all detections.
    pub false_fraction: f64,
    /// Length of the stretch whose landmarks are all unsurveyed (GPS is out there too).
    pub survey_gap_m: f64,
    /// Where the survey gap starts, as a fraction of the route length (never before
    /// [`SURVEYED_LEAD_IN_M`]; the gap is cut at the route's end).
    pub survey_gap_at: f64,
    /// Length of the second GPS outage (urban canyon).
    pub canyon_outage_m: f64,
    /// Where the second outage starts, as a fraction of the route length.
    pub canyon_outage_at: f64,
    /// GNSS epoch rate.
    pub gnss_rate_hz: f64,
    /// GNSS circular error probable (horizontal).
    pub gnss_cep_m: f64,
    /// Share of the per-axis variance in the slowly varying bias (rest is white noise).
    pub gnss_bias_share: f64,
    /// Correlation time of the bias (first-order Gauss–Markov).
    pub gnss_bias_tau_s: f64,
    /// Vertical σ over horizontal σ.
    pub gnss_vertical_factor: f64,
    /// Latency: a fix stamped `t` is the position at `t − lag`.
    pub gnss_lag_s: f64,
    /// Heading (HDT) noise σ.
    pub heading_sigma_deg: f64,
    /// Geoid separation written in the GGA sentences.
    pub geoid_separation_m: f64,
}

impl Scenario {
    /// A preset scenario with the bundled Ladybug2 calibration and the default origin.
    ///
    /// # Panics
    /// Never: the bundled calibration is a compile-time constant checked by the tests.
    pub fn preset(preset: Preset, seed: u64) -> Scenario {
        let rig = default_rig().expect("the bundled calibration is valid (tested)");
        let origin = Geodetic {
            lat_deg: DEFAULT_ORIGIN_DEG.0,
            lon_deg: DEFAULT_ORIGIN_DEG.1,
            alt_m: 0.0,
        };
        let (length_m, frame_rate_hz) = match preset {
            Preset::Reference => (2400.0, 15.0),
            Preset::Short => (900.0, 5.0),
        };
        Scenario {
            preset,
            seed,
            origin,
            rig,
            calibration_name: "bundled calibration/ladybug2.json".into(),
            length_m,
            frame_rate_hz,
            start_unix_s: DEFAULT_START_UNIX_S,
            block_m: 110.0,
            lane_offset_m: 3.0,
            speed_min_mps: 5.0,
            speed_cruise_mps: (11.0, 14.0),
            accel_mps2: 1.5,
            rig_height_m: 2.0,
            tilt_amplitudes_deg: (0.5, 0.25),
            lamp_spacing_m: 28.0,
            lamp_height_m: (5.0, 9.0),
            building_height_m: (6.0, 30.0),
            surveyed_fraction: 0.75,
            survey_sigma_m: 0.02,
            range_m: 80.0,
            pixel_sigma_px: 0.5,
            miss_rate: 0.1,
            false_fraction: 0.2,
            survey_gap_m: 330.0,
            survey_gap_at: 0.35,
            canyon_outage_m: 120.0,
            canyon_outage_at: 0.82,
            gnss_rate_hz: 5.0,
            gnss_cep_m: 2.0,
            gnss_bias_share: 0.78,
            gnss_bias_tau_s: 60.0,
            gnss_vertical_factor: 1.5,
            gnss_lag_s: 0.1,
            heading_sigma_deg: 0.3,
            geoid_separation_m: -32.0,
        }
    }

    fn validate(&self) -> Result<(), SimulateError> {
        let bad = |what: &str| Err(SimulateError::Scenario(what.to_string()));
        let positive = [
            self.length_m,
            self.frame_rate_hz,
            self.block_m,
            self.speed_min_mps,
            self.accel_mps2,
            self.lamp_spacing_m,
            self.range_m,
            self.gnss_rate_hz,
            self.gnss_bias_tau_s,
        ];
        if positive.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return bad("lengths, rates, speeds and times must be finite and positive");
        }
        if self.length_m > 100_000.0 {
            return bad("the route is limited to 100 km");
        }
        if self.block_m < 2.0 * (SETBACK_M + TURN_RADIUS_M) {
            return bad("blocks are too small for the streets and turns");
        }
        if !(0.0..1.0).contains(&self.false_fraction) || !(0.0..=1.0).contains(&self.miss_rate) {
            return bad("false_fraction must be in [0, 1) and miss_rate in [0, 1]");
        }
        if self.rig.is_empty() {
            return bad("the rig has no camera");
        }
        Ok(())
    }
}

/// The bundled Ladybug2 rig.
///
/// # Errors
/// [`LoadError`] only if the bundled file were broken (tested).
pub fn default_rig() -> Result<Rig, LoadError> {
    vgps_camera::calibration::formats::native::parse(
        DEFAULT_CALIBRATION_JSON,
        Path::new("calibration/ladybug2.json"),
    )
}

/// A detection with its truth label.
#[derive(Clone, Debug, PartialEq)]
pub struct SimDetection {
    /// The detection as written to `detections.csv`.
    pub detection: PixelDetection,
    /// Where it comes from.
    pub source: Source,
    /// The noise-free pixel.
    pub true_pixel: Pixel,
}

/// One simulated frame.
#[derive(Clone, Debug)]
pub struct SimFrame {
    /// Frame number.
    pub frame: u64,
    /// Unix time, seconds.
    pub time_s: f64,
    /// Distance driven, metres.
    pub arc_m: f64,
    /// The rig pose in the world frame (ENU at the origin).
    pub world_from_rig: Pose,
    /// Every landmark and transient light each camera sees (noise-free).
    pub visible: Vec<VisiblePoint>,
    /// The detections (noisy, with misses and false ones), with their truth.
    pub detections: Vec<SimDetection>,
}

/// A GPS outage.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Outage {
    /// `survey_gap` (no surveyed landmark in view either) or `canyon`.
    pub kind: String,
    /// Start along the route, metres.
    pub start_m: f64,
    /// End along the route, metres.
    pub end_m: f64,
    /// Unix time the vehicle reaches the start.
    pub start_time_s: f64,
    /// Unix time the vehicle reaches the end.
    pub end_time_s: f64,
}

/// A simulated drive in memory.
#[derive(Clone, Debug)]
pub struct SimulatedDrive {
    /// The scenario.
    pub scenario: Scenario,
    /// The world.
    pub world: World,
    /// The route.
    pub route: Route,
    /// The frames.
    pub frames: Vec<SimFrame>,
    /// The GNSS epochs (as written to NMEA, before its rounding).
    pub gnss: Vec<GnssRecord>,
    /// The GPS outages.
    pub outages: Vec<Outage>,
}

/// The vehicle's motion: distance driven against time.
struct Motion {
    arc: Vec<f64>,
    phases: [f64; 4],
}

impl Motion {
    fn arc_at(&self, t: f64) -> f64 {
        let x = t / INTEGRATION_STEP_S;
        if x <= 0.0 {
            return self.arc[0] + x * INTEGRATION_STEP_S * 5.0;
        }
        let k = x.floor() as usize;
        if k + 1 >= self.arc.len() {
            return self.arc[self.arc.len() - 1];
        }
        let f = x - k as f64;
        self.arc[k] * (1.0 - f) + self.arc[k + 1] * f
    }

    fn time_at(&self, s: f64) -> f64 {
        let k = self.arc.partition_point(|&a| a < s);
        k as f64 * INTEGRATION_STEP_S
    }
}

/// World pose at relative time `t` (seconds since the first frame).
fn pose_at(sc: &Scenario, route: &Route, motion: &Motion, t: f64) -> Pose {
    let s = motion.arc_at(t);
    let (xy, tangent): (Vector2<f64>, Vector2<f64>) = route.at(s);
    let tau = std::f64::consts::TAU;
    let p = &motion.phases;
    let (a1, a2) = (
        sc.tilt_amplitudes_deg.0.to_radians(),
        sc.tilt_amplitudes_deg.1.to_radians(),
    );
    let pitch = a1 * (tau * t / 17.0 + p[0]).sin() + a2 * (tau * t / 5.3 + p[1]).sin();
    let roll = a1 * (tau * t / 13.0 + p[2]).sin() + a2 * (tau * t / 4.1 + p[3]).sin();
    let yaw = tangent.y.atan2(tangent.x);
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), -pitch)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), roll);
    let z = sc.rig_height_m + 0.01 * (tau * t / 0.7).sin();
    Pose::from_parts(Translation3::new(xy.x, xy.y, z), r)
}

/// The GNSS error model: a first-order Gauss–Markov bias per axis plus white noise.
#[derive(Clone, Debug)]
pub struct GnssNoise {
    bias: Vector3<f64>,
    sigma_bias: f64,
    sigma_white: f64,
    tau_s: f64,
    vertical: f64,
}

impl GnssNoise {
    /// A model with horizontal CEP `cep_m`, a share `bias_share` of the per-axis variance
    /// in the bias of correlation time `tau_s`, and vertical σ `vertical` × horizontal.
    pub fn new<R: Rng + ?Sized>(
        rng: &mut R,
        cep_m: f64,
        bias_share: f64,
        tau_s: f64,
        vertical: f64,
    ) -> Self {
        let sigma = cep_m / CEP_PER_SIGMA;
        let share = bias_share.clamp(0.0, 1.0);
        let sigma_bias = sigma * share.sqrt();
        let sigma_white = sigma * (1.0 - share).sqrt();
        let n = |r: &mut R| vgps_geometry::synthetic::normal(r);
        let bias = Vector3::new(n(rng), n(rng), n(rng) * vertical) * sigma_bias;
        Self {
            bias,
            sigma_bias,
            sigma_white,
            tau_s,
            vertical,
        }
    }

    /// The error (ENU metres) of the next epoch, `dt_s` after the previous one.
    pub fn step<R: Rng + ?Sized>(&mut self, rng: &mut R, dt_s: f64) -> Vector3<f64> {
        let a = (-dt_s / self.tau_s).exp();
        let q = self.sigma_bias * (1.0 - a * a).sqrt();
        let mut n = || vgps_geometry::synthetic::normal(rng);
        let drive = Vector3::new(n(), n(), n() * self.vertical) * q;
        self.bias = self.bias * a + drive;
        let white = Vector3::new(n(), n(), n() * self.vertical) * self.sigma_white;
        self.bias + white
    }
}

/// A Poisson sample (Knuth's method; fine for the small means used here).
fn poisson<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> usize {
    let limit = (-mean).exp();
    let mut product: f64 = rng.random();
    let mut k = 0;
    while product > limit && k < 1000 {
        product *= rng.random::<f64>();
        k += 1;
    }
    k
}

fn stream(seed: u64, k: u64) -> vgps_geometry::synthetic::TestRng {
    vgps_geometry::synthetic::rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k)
}

fn quantize(x: f64, q: f64) -> f64 {
    (x / q).round() * q
}

/// Runs a scenario.
///
/// Long (about 260 lines) for a reason: the stages (motion, world, outages, survey, frames,
/// GNSS) draw from four seeded random streams in a fixed order, and every published drive
/// depends on that order bit for bit; one body keeps the order visible. Split only with a
/// byte-identical `vgps demo` check.
///
/// # Errors
/// [`SimulateError::Scenario`] for an invalid parameter, [`SimulateError::Geo`] when a
/// position leaves the valid geodetic range.
pub fn simulate(sc: &Scenario) -> Result<SimulatedDrive, SimulateError> {
    sc.validate()?;
    let mut rng_route = stream(sc.seed, 1);
    let mut rng_world = stream(sc.seed, 2);
    let mut rng_detect = stream(sc.seed, 3);
    let mut rng_gnss = stream(sc.seed, 4);
    let route = Route::random(&mut rng_route, sc.length_m, sc.block_m, sc.lane_offset_m);
    let length = route.length_m;

    // Speed profile and motion.
    let mut cruise = Vec::with_capacity(route.turns.len() + 1);
    for _ in 0..=route.turns.len() {
        cruise.push(rng_route.random_range(sc.speed_cruise_mps.0..sc.speed_cruise_mps.1));
    }
    let speed = |s: f64| -> f64 {
        let k = route.turns.partition_point(|&t| t < s);
        let v2 = sc.speed_min_mps * sc.speed_min_mps;
        let mut v = cruise[k]
            .min((v2 + 2.0 * sc.accel_mps2 * s.max(0.0)).sqrt())
            .min((v2 + 2.0 * sc.accel_mps2 * (length - s).max(0.0)).sqrt());
        for &t in &route.turns {
            v = v.min((v2 + 2.0 * sc.accel_mps2 * (s - t).abs()).sqrt());
        }
        v.max(sc.speed_min_mps)
    };
    let mut arc = vec![0.0];
    let mut s = 0.0;
    while s < length {
        let mid = s + speed(s) * INTEGRATION_STEP_S / 2.0;
        s += speed(mid) * INTEGRATION_STEP_S;
        arc.push(s);
    }
    let phases = [0; 4].map(|_| rng_route.random_range(0.0..std::f64::consts::TAU));
    let motion = Motion { arc, phases };
    let duration = (motion.arc.len() - 1) as f64 * INTEGRATION_STEP_S;

    // World over the cells around the route.
    let idx = |x: f64| (x / sc.block_m).round() as i64;
    let (mut i0, mut i1, mut j0, mut j1) = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    for n in &route.nodes {
        i0 = i0.min(idx(n.x));
        i1 = i1.max(idx(n.x));
        j0 = j0.min(idx(n.y));
        j1 = j1.max(idx(n.y));
    }
    let city = CityParams {
        block_m: sc.block_m,
        lamp_spacing_m: sc.lamp_spacing_m,
        lamp_height_m: sc.lamp_height_m,
        building_height_m: sc.building_height_m,
    };
    let mut world = World::generate(&mut rng_world, &city, (i0 - 1, i1 + 1, j0 - 1, j1 + 1));

    // Outages: the survey gap, then the canyon.
    let gap_start = (sc.survey_gap_at * length).max(SURVEYED_LEAD_IN_M.min(length));
    let gap_len = sc.survey_gap_m.min(0.4 * length).min(length - gap_start);
    // Long routes: the canyon outage grows so that the outages cover MIN_OUTAGE_SHARE.
    let canyon_len = sc
        .canyon_outage_m
        .min(0.1 * length)
        .max(MIN_OUTAGE_SHARE * length - gap_len);
    let canyon_start = (sc.canyon_outage_at * length).min(length - canyon_len);
    let start = sc.start_unix_s;
    let outage = |kind: &str, a: f64, b: f64| Outage {
        kind: kind.into(),
        start_m: a,
        end_m: b,
        start_time_s: start + motion.time_at(a),
        end_time_s: start + motion.time_at(b),
    };
    // A scenario without a survey gap (length 0) has no survey-gap outage either.
    let mut outages = Vec::new();
    if gap_len > 0.0 {
        outages.push(outage("survey_gap", gap_start, gap_start + gap_len));
    }
    outages.push(outage("canyon", canyon_start, canyon_start + canyon_len));

    // Survey: everything near the survey gap is unsurveyed, and a random share elsewhere.
    let gap_points: Vec<Vector2<f64>> = if gap_len > 0.0 {
        (0..=((gap_len / GAP_SAMPLE_M).ceil() as usize))
            .map(|k| {
                route
                    .at(gap_start + (k as f64 * GAP_SAMPLE_M).min(gap_len))
                    .0
            })
            .collect()
    } else {
        Vec::new()
    };
    let gap_radius = sc.range_m + SURVEY_GAP_MARGIN_M;
    let lead_in_points: Vec<Vector2<f64>> = if gap_len > 0.0 {
        let lead_in = SURVEYED_LEAD_IN_M.min(length);
        (0..=((lead_in / GAP_SAMPLE_M).ceil() as usize))
            .map(|k| route.at((k as f64 * GAP_SAMPLE_M).min(lead_in)).0)
            .collect()
    } else {
        Vec::new()
    };
    for l in &mut world.landmarks {
        let xy = l.position_in_enu.xy();
        let in_lead_in = lead_in_points.iter().any(|g| (g - xy).norm() < sc.range_m);
        let near_gap = !in_lead_in && gap_points.iter().any(|g| (g - xy).norm() < gap_radius);
        let drawn: f64 = rng_world.random();
        l.surveyed = !near_gap && drawn < sc.surveyed_fraction;
        let n = |r: &mut vgps_geometry::synthetic::TestRng| vgps_geometry::synthetic::normal(r);
        let e = Vector3::new(n(&mut rng_world), n(&mut rng_world), n(&mut rng_world));
        l.surveyed_in_enu = l.position_in_enu + e * sc.survey_sigma_m;
    }

    // Frames.
    let n_frames = (duration * sc.frame_rate_hz).floor() as usize + 1;
    let mut frames = Vec::with_capacity(n_frames);
    for k in 0..n_frames {
        let t = k as f64 / sc.frame_rate_hz;
        let pose = pose_at(sc, &route, &motion, t);
        let mut visible = observe(&world, &sc.rig, &pose, sc.range_m);
        let mut detections = Vec::new();
        let frame = k as u64;
        let mut push = |v: &VisiblePoint,
                        rng: &mut vgps_geometry::synthetic::TestRng,
                        class: &str,
                        strength: f64| {
            let noise = Vector2::new(
                vgps_geometry::synthetic::normal(rng),
                vgps_geometry::synthetic::normal(rng),
            );
            let pixel = v.pixel + noise * sc.pixel_sigma_px;
            let (w, h) = sc.rig.cameras()[v.camera].model.image_size();
            if !in_image_rectangle(w, h, &pixel) {
                return;
            }
            detections.push(SimDetection {
                detection: PixelDetection {
                    frame,
                    camera: v.camera,
                    u: quantize(pixel.x, PIXEL_QUANTUM),
                    v: quantize(pixel.y, PIXEL_QUANTUM),
                    strength: Some(quantize(strength, PIXEL_QUANTUM)),
                    class: Some(class.to_string()),
                },
                source: v.source,
                true_pixel: v.pixel,
            });
        };
        let mut n_true = 0;
        for v in &visible {
            if rng_detect.random::<f64>() < sc.miss_rate {
                continue;
            }
            let Source::Landmark(i) = v.source else {
                continue;
            };
            let class = world.landmarks[i].class;
            let brightness = match class {
                LandmarkClass::Streetlight => 1.0,
                LandmarkClass::Corner => 0.5,
            };
            push(
                v,
                &mut rng_detect,
                class.label(),
                brightness * (20.0 / v.range_m).min(1.0),
            );
            n_true += 1;
        }
        // Transient lights: Poisson, so that they make `false_fraction` of the detections.
        let mean = n_true as f64 * sc.false_fraction / (1.0 - sc.false_fraction);
        let n_false = poisson(&mut rng_detect, mean);
        let origin = pose.translation.vector;
        let mut transients = Vec::new();
        for _ in 0..n_false {
            for _ in 0..TRANSIENT_ATTEMPTS {
                let az = rng_detect.random_range(0.0..std::f64::consts::TAU);
                let el = rng_detect.random_range(-3.0_f64..25.0).to_radians();
                let range = rng_detect.random_range(8.0..sc.range_m);
                let dir = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                let seen = project(&sc.rig, &pose, &(origin + dir * range), Source::Transient);
                if let Some(first) = seen.first() {
                    let strength = rng_detect.random_range(0.2..1.0);
                    push(
                        first,
                        &mut rng_detect,
                        LandmarkClass::Streetlight.label(),
                        strength,
                    );
                    transients.push(*first);
                    break;
                }
            }
        }
        visible.extend(transients);
        detections.sort_by(|a, b| {
            (a.detection.camera, a.detection.u, a.detection.v)
                .partial_cmp(&(b.detection.camera, b.detection.u, b.detection.v))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        frames.push(SimFrame {
            frame,
            time_s: start + t,
            arc_m: motion.arc_at(t),
            world_from_rig: pose,
            visible,
            detections,
        });
    }

    // GNSS epochs.
    let enu = LocalFrame::new(sc.origin);
    let mut noise = GnssNoise::new(
        &mut rng_gnss,
        sc.gnss_cep_m,
        sc.gnss_bias_share,
        sc.gnss_bias_tau_s,
        sc.gnss_vertical_factor,
    );
    let dt = 1.0 / sc.gnss_rate_hz;
    let n_epochs = (duration * sc.gnss_rate_hz).floor() as usize + 1;
    let mut gnss = Vec::with_capacity(n_epochs);
    for k in 0..n_epochs {
        let t = k as f64 * dt;
        let error = noise.step(&mut rng_gnss, dt);
        let hdop = quantize(0.9 + 0.3 * rng_gnss.random::<f64>(), 0.1);
        let sats = rng_gnss.random_range(8..=11_u32);
        let heading_noise = vgps_geometry::synthetic::normal(&mut rng_gnss) * sc.heading_sigma_deg;
        let time_s = start + t;
        if outages
            .iter()
            .any(|o| time_s >= o.start_time_s && time_s <= o.end_time_s)
        {
            gnss.push(GnssRecord {
                time_s,
                fix: None,
                heading_deg: None,
            });
            continue;
        }
        let pose = pose_at(sc, &route, &motion, t - sc.gnss_lag_s);
        let truth = truth_of(&enu, &pose)?;
        let reported = enu.try_to_geodetic(&(pose.translation.vector + error))?;
        let heading = (heading_deg(&truth.enu_from_rig) + heading_noise).rem_euclid(360.0);
        gnss.push(GnssRecord {
            time_s,
            fix: Some(GnssFix {
                position: reported,
                quality: 1,
                hdop: Some(hdop),
                num_sats: Some(sats),
            }),
            heading_deg: Some(heading),
        });
    }
    Ok(SimulatedDrive {
        scenario: sc.clone(),
        world,
        route,
        frames,
        gnss,
        outages,
    })
}

/// The truth record of a world pose: WGS84 position and `enu_from_rig` in the local-level
/// frame at that position.
///
/// # Errors
/// [`GeoError`] when the position is outside the valid geodetic range.
pub fn truth_of(enu: &LocalFrame, world_from_rig: &Pose) -> Result<TruthRecord, GeoError> {
    let position = enu.try_to_geodetic(&world_from_rig.translation.vector)?;
    let local = enu.enu_here_from_enu_at(&position).inverse() * world_from_rig.rotation;
    Ok(TruthRecord {
        frame: 0,
        position,
        enu_from_rig: UnitQuaternion::from_rotation_matrix(&local),
    })
}

/// Heading of the rig +x axis, degrees clockwise from north in [0, 360), from `enu_from_rig`.
pub fn heading_deg(enu_from_rig: &UnitQuaternion<f64>) -> f64 {
    let x = enu_from_rig * Vector3::x();
    x.x.atan2(x.y).to_degrees().rem_euclid(360.0)
}

impl SimulatedDrive {
    /// The surveyed landmarks (the content of `landmarks.csv`), surveyed positions.
    ///
    /// # Errors
    /// [`GeoError`] for a position outside the valid range.
    pub fn surveyed_landmarks(&self) -> Result<Vec<Landmark>, GeoError> {
        let enu = LocalFrame::new(self.scenario.origin);
        let mut out = Vec::new();
        for l in self.world.landmarks.iter().filter(|l| l.surveyed) {
            let g = enu.try_to_geodetic(&l.surveyed_in_enu)?;
            out.push(Landmark {
                id: l.id.clone(),
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: g.alt_m,
                sigma_m: Some(self.scenario.survey_sigma_m),
                class: Some(l.class.label().to_string()),
                line: 0,
            });
        }
        Ok(out)
    }

    /// The truth records of every frame.
    ///
    /// # Errors
    /// [`GeoError`] for a position outside the valid range.
    pub fn truth(&self) -> Result<Vec<TruthRecord>, GeoError> {
        let enu = LocalFrame::new(self.scenario.origin);
        self.frames
            .iter()
            .map(|f| {
                truth_of(&enu, &f.world_from_rig).map(|mut t| {
                    t.frame = f.frame;
                    t
                })
            })
            .collect()
    }

    /// Counts: (true detections, false detections, visible landmark sightings).
    pub fn detection_counts(&self) -> (usize, usize, usize) {
        let mut counts = (0, 0, 0);
        for f in &self.frames {
            for d in &f.detections {
                match d.source {
                    Source::Landmark(_) => counts.0 += 1,
                    Source::Transient => counts.1 += 1,
                }
            }
            counts.2 += f
                .visible
                .iter()
                .filter(|v| matches!(v.source, Source::Landmark(_)))
                .count();
        }
        counts
    }

    /// Fraction of the route length without a GPS fix.
    pub fn outage_fraction(&self) -> f64 {
        self.outages
            .iter()
            .map(|o| o.end_m - o.start_m)
            .sum::<f64>()
            / self.route.length_m
    }

    /// Writes the drive directory (created if needed): `drive.json`, `calibration.json`,
    /// `landmarks.csv`, `frames.csv`, `detections.csv`, `gnss.nmea`, `truth.csv`, and the
    /// sidecars `world_landmarks.csv`, `detections_truth.csv`, `simulation.json`.
    ///
    /// # Errors
    /// [`DriveError::Write`] naming the file that cannot be written.
    pub fn write(&self, dir: &Path) -> Result<(), DriveError> {
        let werr = |path: &Path, e: &dyn std::fmt::Display| DriveError::Write {
            path: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        };
        std::fs::create_dir_all(dir).map_err(|source| DriveError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        let manifest = Manifest::standard();
        vgps_camera::calibration::save_native(
            &self.scenario.rig,
            &dir.join(&manifest.calibration),
        )?;
        let landmarks_path = dir.join(&manifest.landmarks);
        let landmarks = self
            .surveyed_landmarks()
            .map_err(|e| werr(&landmarks_path, &e))?;
        write_text(&landmarks_path, &landmarks_to_csv(&landmarks))?;
        let frames: Vec<FrameRecord> = self
            .frames
            .iter()
            .map(|f| FrameRecord {
                frame: f.frame,
                time_s: f.time_s,
                images: Vec::new(),
            })
            .collect();
        write_text(&dir.join(&manifest.frames), &frames_to_csv(&frames))?;
        let detections: Vec<PixelDetection> = self
            .frames
            .iter()
            .flat_map(|f| f.detections.iter().map(|d| d.detection.clone()))
            .collect();
        write_text(&dir.join("detections.csv"), &detections_to_csv(&detections))?;
        write_text(
            &dir.join("gnss.nmea"),
            &write_nmea(&self.gnss, self.scenario.geoid_separation_m),
        )?;
        let truth_path = dir.join("truth.csv");
        let truth = self.truth().map_err(|e| werr(&truth_path, &e))?;
        write_text(&truth_path, &truth_to_csv(&truth))?;
        // Sidecars.
        let enu = LocalFrame::new(self.scenario.origin);
        let world_path = dir.join("world_landmarks.csv");
        let mut text = String::from("id,lat,lon,alt,class,surveyed\n");
        for l in &self.world.landmarks {
            let g = enu
                .try_to_geodetic(&l.position_in_enu)
                .map_err(|e| werr(&world_path, &e))?;
            let _ = writeln!(
                text,
                "{},{},{},{},{},{}",
                l.id,
                g.lat_deg,
                g.lon_deg,
                g.alt_m,
                l.class.label(),
                l.surveyed
            );
        }
        write_text(&world_path, &text)?;
        let mut text = String::from("frame,camera,u,v,landmark,u_true,v_true\n");
        for f in &self.frames {
            for d in &f.detections {
                let label = match d.source {
                    Source::Landmark(i) => self.world.landmarks[i].id.as_str(),
                    Source::Transient => "false",
                };
                let _ = writeln!(
                    text,
                    "{},{},{},{},{},{},{}",
                    f.frame,
                    d.detection.camera,
                    d.detection.u,
                    d.detection.v,
                    label,
                    d.true_pixel.x,
                    d.true_pixel.y
                );
            }
        }
        write_text(&dir.join("detections_truth.csv"), &text)?;
        let json_path = dir.join("simulation.json");
        let json = self.summary_json();
        let text = serde_json::to_string_pretty(&json).map_err(|e| werr(&json_path, &e))?;
        write_text(&json_path, &(text + "\n"))?;
        write_manifest(dir, &manifest)
    }

    /// The content of `simulation.json`.
    pub fn summary_json(&self) -> serde_json::Value {
        let sc = &self.scenario;
        let count = |c: LandmarkClass, surveyed: Option<bool>| {
            self.world
                .landmarks
                .iter()
                .filter(|l| l.class == c && surveyed.is_none_or(|s| l.surveyed == s))
                .count()
        };
        let (true_det, false_det, sightings) = self.detection_counts();
        serde_json::json!({
            "format": "vgps-simulation",
            "version": 1,
            "seed": sc.seed,
            "preset": sc.preset.name(),
            "calibration": sc.calibration_name,
            "origin": {"lat": sc.origin.lat_deg, "lon": sc.origin.lon_deg, "alt": sc.origin.alt_m},
            "route_length_m": self.route.length_m,
            "frames": self.frames.len(),
            "duration_s": self.frames.last().map_or(0.0, |f| f.time_s - sc.start_unix_s),
            "frame_rate_hz": sc.frame_rate_hz,
            "start_unix_s": sc.start_unix_s,
            "world": {
                "buildings": self.world.buildings.len(),
                "streetlights": count(LandmarkClass::Streetlight, None),
                "corners": count(LandmarkClass::Corner, None),
                "surveyed_streetlights": count(LandmarkClass::Streetlight, Some(true)),
                "surveyed_corners": count(LandmarkClass::Corner, Some(true)),
                "block_m": sc.block_m,
                "lane_offset_m": sc.lane_offset_m,
                "lamp_spacing_m": sc.lamp_spacing_m,
                "lamp_height_m": [sc.lamp_height_m.0, sc.lamp_height_m.1],
                "building_height_m": [sc.building_height_m.0, sc.building_height_m.1],
                "surveyed_fraction": sc.surveyed_fraction,
                "survey_sigma_m": sc.survey_sigma_m,
            },
            "vehicle": {
                "speed_min_mps": sc.speed_min_mps,
                "speed_cruise_mps": [sc.speed_cruise_mps.0, sc.speed_cruise_mps.1],
                "accel_mps2": sc.accel_mps2,
                "rig_height_m": sc.rig_height_m,
                "tilt_amplitudes_deg": [sc.tilt_amplitudes_deg.0, sc.tilt_amplitudes_deg.1],
                "turn_radius_m": TURN_RADIUS_M,
            },
            "detections": {
                "range_m": sc.range_m,
                "pixel_sigma_px": sc.pixel_sigma_px,
                "miss_rate": sc.miss_rate,
                "false_fraction": sc.false_fraction,
                "true": true_det,
                "false": false_det,
                "landmark_sightings": sightings,
            },
            "gnss": {
                "rate_hz": sc.gnss_rate_hz,
                "cep_m": sc.gnss_cep_m,
                "bias_share": sc.gnss_bias_share,
                "bias_tau_s": sc.gnss_bias_tau_s,
                "vertical_factor": sc.gnss_vertical_factor,
                "lag_s": sc.gnss_lag_s,
                "heading_sigma_deg": sc.heading_sigma_deg,
                "geoid_separation_m": sc.geoid_separation_m,
                "epochs": self.gnss.len(),
                "fixes": self.gnss.iter().filter(|r| r.fix.is_some()).count(),
            },
            "outages": self.outages,
            "outage_fraction": self.outage_fraction(),
        })
    }
}

#[cfg(test)]
mod tests;
