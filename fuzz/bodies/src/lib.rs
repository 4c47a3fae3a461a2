//! Fuzz-target bodies: one function per target of `fuzz/` (see `docs/fuzzing.md`).
//!
//! Each function takes the fuzzer's raw bytes, feeds them through one parser or solver and
//! **panics** when an invariant is broken: a panic inside the library, a non-finite number
//! or an out-of-range value in an `Ok` output, a rotation that is not orthonormal. Errors
//! and empty solution lists are fine. The solver targets decode their bytes into
//! structured inputs with the [`arbitrary`] crate ([`P3pInput`], [`MatcherInput`], …);
//! their numbers ([`Num`]) are small integers, powers of ten from 10⁻³³⁰ to 10³³⁰, or raw
//! bit patterns (NaN, ±∞, subnormals), so that degenerate and extreme values are common.
//!
//! The bodies live here, not in the fuzz crate, so that a stable `cargo test`
//! (`tests/fuzz_corpus.rs`) runs every committed corpus file and every crash regression
//! through exactly the code the fuzzer runs. `cargo +nightly fuzz run <target>` only adds
//! coverage-guided input generation.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use arbitrary::{Arbitrary, Unstructured};
use nalgebra::{Matrix3, Vector2, Vector3};
use std::path::Path;
use vgps_camera::calibration::formats::{ladybug_conf, ladybug_ini, native, nclt};
use vgps_camera::calibration::{
    Camera, CameraMask, CameraModel, Lut, MAX_IMAGE_SIDE_PX, Pinhole, PinholeParams, Rig,
    TabulatedPinhole, TabulatedPinholeParams,
};
use vgps_camera::imaging::formats::jpeg_frame_header;
use vgps_camera::imaging::{DecodeLimits, StreetLampDetector, decode_image, decode_png};
use vgps_core::matcher::{
    DbLandmark, Detection, LandmarkDb, MatchOptions, MatchStatus, SearchArea, match_detections,
};
use vgps_geometry::attitude::{triad, wahba, wahba_with_covariance};
use vgps_geometry::geometry::{Pose, Ray};
use vgps_geometry::solvers::{p3p, p3p_cosines, trilaterate};
use vgps_geometry::triangulation::{
    RayObservation, intersect_two_rays, triangulate_rays, triangulate_rays_weighted,
};

/// A path that does not exist: quoted in errors, and side files it names cannot be read.
const FUZZ_PATH: &str = "/nonexistent/vgps-fuzz/input";

/// Largest deviation of a returned rotation from orthonormality (`‖RᵀR − I‖∞`).
const ROTATION_TOLERANCE: f64 = 1e-6;

/// Largest deviation of a returned bearing's norm from 1.
const UNIT_TOLERANCE: f64 = 1e-6;

/// Limits of the PNG target: small, so that every execution is fast.
pub const PNG_LIMITS: DecodeLimits = DecodeLimits {
    max_width: 512,
    max_height: 512,
    max_bytes: 4 << 20,
};

/// Most landmarks and detections handed to the matcher by [`matcher`].
pub const MATCHER_MAX_ITEMS: usize = 48;

/// The matcher target skips areas of more cells than this: each cell builds its candidate
/// tables, and a search of [`vgps_core::matcher::MAX_CELLS`] cells around landmarks visible from
/// everywhere takes about 0.3 s in a release build, over the fuzzer's 10 s with its
/// sanitizers (three timeouts of that kind were found and bounded: docs/fuzzing.md).
pub const MATCHER_MAX_FUZZ_CELLS: f64 = 20_000.0;

/// Most rays or vector pairs handed to the triangulation and attitude solvers.
pub const MAX_OBSERVATIONS: usize = 16;

/// A number for structure-aware targets: mostly "interesting" values.
#[derive(Arbitrary, Clone, Copy, Debug)]
pub enum Num {
    /// A small integer (zero, exact coincidences, collinear points).
    Int(i8),
    /// `mantissa · 10^exponent`, the exponent clamped to ±330 (tiny, huge, 0 and ∞).
    Pow(i8, i16),
    /// Any `f64` bit pattern (NaN, ±∞, subnormals).
    Raw(f64),
}

impl Num {
    /// The value.
    pub fn get(self) -> f64 {
        match self {
            Num::Int(i) => f64::from(i),
            Num::Pow(m, e) => f64::from(m) * 10f64.powi(i32::from(e.clamp(-330, 330))),
            Num::Raw(x) => x,
        }
    }
}

/// A vector of three [`Num`]s.
pub type V3 = [Num; 3];

/// The vector of a [`V3`].
pub fn vec3(v: &V3) -> Vector3<f64> {
    Vector3::new(v[0].get(), v[1].get(), v[2].get())
}

/// Input of the `p3p` and `p3p_cosines` targets.
#[derive(Arbitrary, Clone, Debug)]
pub struct P3pInput {
    /// Bearings in the rig frame (any length, zero and non-finite included).
    pub bearings: [V3; 3],
    /// World points.
    pub points: [V3; 3],
}

/// Input of the `trilaterate` target.
#[derive(Arbitrary, Clone, Debug)]
pub struct TrilaterateInput {
    /// Sphere centres.
    pub centres: [V3; 3],
    /// Sphere radii.
    pub ranges: [Num; 3],
}

/// Input of the `attitude` target (triad on the first two pairs, wahba on all).
#[derive(Arbitrary, Clone, Debug)]
pub struct AttitudeInput {
    /// `(in_rig, in_world, weight)` triples.
    pub pairs: Vec<(V3, V3, Num)>,
    /// Direction σ of `wahba_with_covariance`, radians.
    pub sigma_rad: Num,
}

/// Input of the `triangulate` target.
#[derive(Arbitrary, Clone, Debug)]
pub struct TriangulateInput {
    /// `(origin, direction, sigma_pos_m, sigma_ang_rad)`; the direction is used as given
    /// (not normalised), so non-unit directions are exercised too.
    pub rays: Vec<(V3, V3, Num, Num)>,
    /// Normalise the directions first (finite, non-zero ones).
    pub normalise: bool,
}

/// Input of the `matcher` target. Counts of the options are bounded (small) so that one
/// execution stays fast; every real-valued option is arbitrary.
#[derive(Arbitrary, Clone, Debug)]
pub struct MatcherInput {
    /// `(position, class, sigma_m)` of each landmark.
    pub landmarks: Vec<(V3, Option<u8>, Num)>,
    /// `(origin, direction, class)` of each detection; finite non-zero directions are
    /// normalised, the others passed as they are.
    pub detections: Vec<(V3, V3, Option<u8>)>,
    /// Search area corners (`SearchArea::try_new`; if it refuses, a box around the first
    /// corner of radius 50 m).
    pub area: (V3, V3),
    /// `sigma_rad`, `inlier_threshold_sigmas`, `visibility_range_m`, `cell_size_m`.
    pub reals: [Num; 4],
    /// `min_inliers`, `ambiguity_margin`, `max_core_detections`, `max_detection_triples`,
    /// `max_hypotheses`, `min_extensions` and `max_rounds` (`c % 4`, `1 + (c / 4) % 4`).
    pub counts: [u8; 6],
    /// The sampling seed.
    pub seed: u64,
    /// Known vertical (direction, tolerance radians).
    pub up: Option<(V3, Num)>,
}

/// Decodes a structure-aware input; `None` when the bytes run out.
fn decode<'a, T: Arbitrary<'a>>(data: &'a [u8]) -> Option<T> {
    T::arbitrary_take_rest(Unstructured::new(data)).ok()
}

fn text(data: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(data)
}

fn assert_finite(x: f64, what: &str) {
    assert!(x.is_finite(), "{what} is not finite: {x}");
}

fn assert_vec_finite(v: &Vector3<f64>, what: &str) {
    assert!(
        v.iter().all(|x| x.is_finite()),
        "{what} is not finite: {v:?}"
    );
}

fn assert_rotation(r: &Matrix3<f64>, what: &str) {
    assert!(
        r.iter().all(|x| x.is_finite()),
        "{what} is not finite: {r:?}"
    );
    let deviation = (r.transpose() * r - Matrix3::identity()).abs().max();
    assert!(
        deviation <= ROTATION_TOLERANCE && (r.determinant() - 1.0).abs() <= ROTATION_TOLERANCE,
        "{what} is not a rotation (‖RᵀR − I‖ = {deviation}): {r:?}"
    );
}

fn assert_pose(p: &Pose, what: &str) {
    assert_rotation(p.rotation.matrix(), what);
    assert_vec_finite(&p.translation.vector, what);
}

fn assert_unit(v: &Vector3<f64>, what: &str) {
    assert_vec_finite(v, what);
    assert!(
        (v.norm() - 1.0).abs() <= UNIT_TOLERANCE,
        "{what} is not a unit vector: {v:?}"
    );
}

/// Checks a camera model: bearings of sample pixels (when given) are unit, their
/// Jacobians finite, and the pixels of those bearings finite.
fn check_camera(model: &Camera) {
    let (w, h) = model.image_size();
    let (w, h) = (f64::from(w), f64::from(h));
    let samples = [
        (0.0, 0.0),
        (w / 2.0 - 0.5, h / 2.0 - 0.5),
        (w - 1.0, h - 1.0),
        (w / 3.0, h / 5.0),
        (-0.5, -0.5),
    ];
    for (u, v) in samples {
        let pixel = Vector2::new(u, v);
        if let Some(b) = model.try_bearing(&pixel) {
            assert_unit(&b, "camera bearing");
            if let Some(p) = model.try_pixel(&b) {
                assert!(p.iter().all(|x| x.is_finite()), "pixel not finite: {p:?}");
            }
        }
        if let Some((b, j)) = model.try_bearing_with_jacobian(&pixel) {
            assert_unit(&b, "camera bearing (with Jacobian)");
            assert!(
                j.iter().all(|x| x.is_finite()),
                "Jacobian not finite: {j:?}"
            );
        }
    }
}

/// Checks a rig: every camera ([`check_camera`]) and the projection of the six axes.
fn check_rig(rig: &Rig) {
    for c in rig.cameras() {
        check_camera(&c.model);
        assert_rotation(c.rig_from_camera.rotation.matrix(), "rig_from_camera");
        assert_vec_finite(&c.rig_from_camera.translation.vector, "camera centre");
    }
    for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
        for d in [axis, -axis] {
            for p in rig.project_direction(&d) {
                assert!(
                    p.pixel.iter().all(|x| x.is_finite()),
                    "projected pixel not finite"
                );
            }
        }
    }
}

/// Target `native_json`: the native calibration JSON ([`native::parse`]).
pub fn native_json(data: &[u8]) {
    if let Ok(rig) = native::parse(&text(data), Path::new(FUZZ_PATH)) {
        check_rig(&rig);
    }
}

/// Target `ladybug_ini`: the Ladybug INI export ([`ladybug_ini::parse`]), without and with
/// an image size.
pub fn ladybug_ini(data: &[u8]) {
    let text = text(data);
    for size in [None, Some((64, 48))] {
        if let Ok(rig) = ladybug_ini::parse(&text, Path::new(FUZZ_PATH), size) {
            check_rig(&rig);
        }
    }
}

/// Target `ladybug_conf`: the Ladybug SDK `.conf` file ([`ladybug_conf::parse`]), then the
/// raw and rectified rigs and the stored pairs' residuals (finite, or flagged not seen).
pub fn ladybug_conf(data: &[u8]) {
    let text = text(data);
    let Ok(conf) = ladybug_conf::parse(&text, Path::new(FUZZ_PATH)) else {
        return;
    };
    if let Ok(rig) = conf.raw_rig() {
        check_rig(&rig);
    }
    if let Ok(rig) = conf.rectified_rig() {
        check_rig(&rig);
    }
    for c in &conf.cameras {
        for ((_, _, r), seen) in conf.pair_residuals(c) {
            assert!(
                !seen || r.iter().all(|x| x.is_finite()),
                "pair residual {r}"
            );
        }
    }
}

/// Target `nclt_calibration`: `K_cam{i}.csv` ([`nclt::intrinsics_from_str`], then a
/// camera of those intrinsics) and `x_lb3_c{i}.csv` ([`nclt::extrinsics_from_str`], then
/// a rig of that placement).
pub fn nclt_calibration(data: &[u8]) {
    let text = text(data);
    let path = Path::new(FUZZ_PATH);
    if let Ok([fx, fy, skew, cx, cy]) = nclt::intrinsics_from_str(&text, path) {
        let params = TabulatedPinholeParams {
            width: Some(64),
            height: Some(48),
            fx,
            fy,
            skew,
            cx,
            cy,
            raw_to_undistorted: None,
            undistorted_to_raw: None,
        };
        if let Ok(model) = TabulatedPinhole::new(params) {
            check_camera(&Camera::TabulatedPinhole(model));
        }
    }
    if let Ok(rig_from_camera) = nclt::extrinsics_from_str(&text, path) {
        assert_pose(&rig_from_camera, "x_lb3 placement");
    }
}

/// Target `nclt_table`: a distortion table ([`nclt::table_from_str`]), then a camera with
/// that table in both directions.
pub fn nclt_table(data: &[u8]) {
    let Ok(table) = nclt::table_from_str(&text(data), Path::new(FUZZ_PATH), None) else {
        return;
    };
    assert_eq!(
        table.positions.len(),
        table.width as usize * table.height as usize
    );
    assert!(
        table
            .positions
            .iter()
            .all(|p| p[0].is_finite() && p[1].is_finite())
    );
    let (w, h) = (f64::from(table.width), f64::from(table.height));
    let params = TabulatedPinholeParams {
        width: Some(table.width),
        height: Some(table.height),
        fx: w,
        fy: w,
        skew: 0.0,
        cx: (w - 1.0) / 2.0,
        cy: (h - 1.0) / 2.0,
        raw_to_undistorted: Some(table.clone()),
        undistorted_to_raw: Some(table),
    };
    if let Ok(model) = TabulatedPinhole::new(params) {
        check_camera(&Camera::TabulatedPinhole(model));
    }
}

/// Target `camera_mask`: a PNG mask ([`CameraMask::from_png_bytes`]); an `Ok` mask has a
/// size within the limits, no more masked pixels than pixels, answers look-ups anywhere
/// (inside, outside, non-finite), and is accepted by a rig whose camera has its size.
pub fn camera_mask(data: &[u8]) {
    let Ok(mask) = CameraMask::from_png_bytes(data, Path::new(FUZZ_PATH)) else {
        return;
    };
    let (w, h) = mask.dimensions();
    assert!(w >= 1 && h >= 1 && w <= MAX_IMAGE_SIDE_PX && h <= MAX_IMAGE_SIDE_PX);
    assert!(mask.count() <= u64::from(w) * u64::from(h));
    for (u, v) in [(0.0, 0.0), (-0.6, 0.0), (f64::NAN, 1.0), (1e300, 0.0)] {
        let _ = mask.is_masked_at(&Vector2::new(u, v));
    }
    assert!(!mask.is_masked(w, 0) && !mask.is_masked(0, h));
    let (wf, hf) = (f64::from(w), f64::from(h));
    let params = PinholeParams::ideal(w, h, wf, wf, (wf - 1.0) / 2.0, (hf - 1.0) / 2.0);
    if let Ok(camera) = Pinhole::new(params) {
        let rig = Rig::panorama(Camera::Pinhole(camera));
        assert!(
            rig.with_mask(0, mask).is_ok(),
            "mask of the camera's size refused"
        );
    }
}

/// Target `lut`: a LUT file ([`Lut::from_bytes`]).
pub fn lut(data: &[u8]) {
    if let Ok(lut) = Lut::from_bytes(data, FUZZ_PATH) {
        check_camera(&Camera::Lut(lut));
    }
}

/// Target `landmarks_csv`: [`vgps_io::landmarks_from_reader`].
pub fn landmarks_csv(data: &[u8]) {
    let Ok(landmarks) = vgps_io::landmarks_from_reader(Path::new(FUZZ_PATH), data) else {
        return;
    };
    let mut ids = std::collections::HashSet::new();
    for l in &landmarks {
        assert!(
            !l.id.is_empty() && ids.insert(l.id.clone()),
            "bad id {:?}",
            l.id
        );
        assert!(l.lat_deg.abs() <= 90.0 && l.lon_deg.abs() <= 180.0);
        assert_finite(l.alt_m, "alt_m");
        if let Some(s) = l.sigma_m {
            assert!(s.is_finite() && s >= 0.0, "sigma_m {s}");
        }
    }
}

/// Target `observations_csv`: [`vgps_io::observations_from_reader`].
pub fn observations_csv(data: &[u8]) {
    let Ok(obs) = vgps_io::observations_from_reader(Path::new(FUZZ_PATH), data) else {
        return;
    };
    for o in &obs {
        match &o.measurement {
            vgps_io::MeasurementRecord::Bearing(b) => {
                assert_vec_finite(b, "bearing");
                assert!(b.norm() > 0.0, "zero bearing");
            }
            vgps_io::MeasurementRecord::Pixel { u, v, .. } => {
                assert!(u.is_finite() && v.is_finite(), "pixel ({u}, {v})");
            }
        }
    }
}

/// Target `rays_csv`: [`vgps_io::rays_from_reader`].
pub fn rays_csv(data: &[u8]) {
    let Ok(rays) = vgps_io::rays_from_reader(Path::new(FUZZ_PATH), data) else {
        return;
    };
    for r in &rays {
        assert!(r.lat_deg.abs() <= 90.0 && r.lon_deg.abs() <= 180.0);
        assert_finite(r.alt_m, "alt_m");
        assert_vec_finite(&r.direction_in_enu, "direction");
        assert!(r.direction_in_enu.norm() > 0.0, "zero direction");
        for s in [r.sigma_pos_m, r.sigma_ang_deg].into_iter().flatten() {
            assert!(s.is_finite() && s >= 0.0, "sigma {s}");
        }
    }
}

/// Target `drive_tables`: the drive's `frames.csv`, `truth.csv` (against those frames) and
/// `detections.csv` (a rig of six cameras) readers, on the same text.
pub fn drive_tables(data: &[u8]) {
    let text = text(data);
    let path = Path::new(FUZZ_PATH);
    let frames = vgps_replay::drive::frames_from_text(path, &text).unwrap_or_default();
    for f in &frames {
        assert_finite(f.time_s, "time_s");
    }
    if let Ok(truth) = vgps_replay::drive::truth_from_text(path, &text, &frames) {
        for t in &truth {
            assert!(t.position.lat_deg.abs() <= 90.0 && t.position.alt_m.is_finite());
            assert!(t.enu_from_rig.coords.iter().all(|x| x.is_finite()));
        }
    }
    if let Ok(rows) = vgps_replay::drive::detections_from_text(path, &text, 6) {
        for row in rows {
            if let vgps_replay::drive::DetectionRow::Ok(d) = row {
                assert!(d.camera < 6 && d.u.is_finite() && d.v.is_finite());
                assert!(d.strength.is_none_or(f64::is_finite));
            }
        }
    }
}

/// Target `drive_json`: the manifest [`vgps_replay::drive::Manifest::parse`], strict and lenient.
pub fn drive_json(data: &[u8]) {
    let text = text(data);
    for strictness in [
        vgps_replay::drive::Strictness::Strict,
        vgps_replay::drive::Strictness::Lenient,
    ] {
        if let Ok((m, _)) =
            vgps_replay::drive::Manifest::parse(Path::new(FUZZ_PATH), &text, strictness)
        {
            assert_eq!(m.version, vgps_replay::drive::FORMAT_VERSION);
            assert!(!m.calibration.is_empty() && !m.landmarks.is_empty() && !m.frames.is_empty());
        }
    }
}

/// Target `nmea`: [`vgps_replay::drive::nmea::read_nmea`].
pub fn nmea(data: &[u8]) {
    let text = text(data);
    let (records, stats) = vgps_replay::drive::nmea::read_nmea(&text);
    // A line may hold several sentences: each sentence starts with a `$`, and a line is
    // refused (garbage, checksum, truncated) at most once.
    let sentences = text.matches('$').count();
    assert!(stats.used + stats.invalid + stats.unsupported <= sentences);
    assert!(stats.garbage + stats.bad_checksum + stats.truncated <= stats.lines);
    assert_gnss_records(&records);
}

/// The invariants of GNSS records read from any format: finite times, positions in range.
fn assert_gnss_records(records: &[vgps_replay::drive::GnssRecord]) {
    for r in records {
        assert_finite(r.time_s, "time_s");
        if let Some(f) = &r.fix {
            let p = &f.position;
            assert!(p.lat_deg.abs() <= 90.0 && p.lon_deg.abs() <= 180.0 && p.alt_m.is_finite());
            assert!(f.hdop.is_none_or(f64::is_finite));
        }
        if let Some(h) = r.heading_deg {
            assert!((0.0..360.0).contains(&h), "heading {h}");
        }
    }
}

/// Target `ubx`: [`vgps_replay::drive::ubx::read_ubx`] (UBX frames mixed with NMEA).
pub fn ubx(data: &[u8]) {
    let (records, stats) = vgps_replay::drive::ubx::read_ubx(data);
    assert!(stats.nav_pvt <= stats.frames);
    assert_gnss_records(&records);
}

/// Target `sirf`: [`vgps_replay::drive::sirf::read_sirf`] (SiRF binary frames mixed with
/// NMEA).
pub fn sirf(data: &[u8]) {
    let (records, stats) = vgps_replay::drive::sirf::read_sirf(data);
    assert!(stats.navigation + stats.geodetic + stats.geodetic_untimed <= stats.frames);
    assert_gnss_records(&records);
}

/// Target `imu_csv`: [`vgps_replay::drive::imu::imu_from_text`] and the attitude prior of
/// every sample read.
pub fn imu_csv(data: &[u8]) {
    let (samples, errors) =
        vgps_replay::drive::imu::imu_from_text(std::path::Path::new("imu.csv"), &text(data));
    assert!(errors.iter().all(|e| e.context.starts_with("imu.csv:")));
    for s in &samples {
        assert_finite(s.time_s, "time_s");
        if let Some(p) = s.attitude_prior(0.05) {
            assert!(
                (p.up_in_rig.norm() - 1.0).abs() < 1e-9,
                "up {:?}",
                p.up_in_rig
            );
            assert!(p.up_tolerance_rad.is_finite() && p.up_tolerance_rad >= 0.0);
            if let Some((h, tol)) = p.heading {
                assert!(h.is_finite() && tol.is_finite() && tol >= 0.0);
            }
        }
    }
    if let Some(first) = samples.first() {
        let _ = vgps_replay::drive::imu::attitude_at(&samples, first.time_s);
    }
}

/// Target `gis_landmarks`: [`vgps_io::gis::landmarks_from_geojson`] and
/// [`vgps_io::gis::landmarks_from_gis_csv`] (a ground height given).
pub fn gis_landmarks(data: &[u8]) {
    let options = vgps_io::gis::GisOptions {
        ground_height_m: Some(10.0),
        ..Default::default()
    };
    let path = std::path::Path::new("fuzz.geojson");
    let text = text(data);
    for read in [
        vgps_io::gis::landmarks_from_geojson(path, &text, &options),
        vgps_io::gis::landmarks_from_gis_csv(path, &text, &options),
    ]
    .into_iter()
    .flatten()
    {
        for l in &read.landmarks {
            assert!(l.lat_deg.abs() <= 90.0 && l.lon_deg.abs() <= 180.0 && l.alt_m.is_finite());
            assert!(l.sigma_m.is_some_and(|s| s.is_finite() && s >= 0.0));
        }
    }
}

/// Target `building_footprints`: [`vgps_io::footprints::corners_from_footprints`] (a ground
/// height given, ellipsoidal: the geoid is fuzzed by `gis_landmarks`), ground corners on.
pub fn building_footprints(data: &[u8]) {
    let options = vgps_io::footprints::FootprintOptions {
        ground_height_m: Some(10.0),
        reference: vgps_io::gis::GroundReference::Ellipsoid,
        ground_corners: true,
        ..Default::default()
    };
    let path = std::path::Path::new("fuzz.geojson");
    if let Ok(read) = vgps_io::footprints::corners_from_footprints(path, &text(data), &options) {
        assert!(!read.landmarks.is_empty());
        for l in &read.landmarks {
            assert!(l.lat_deg.abs() <= 90.0 && l.lon_deg.abs() <= 180.0 && l.alt_m.is_finite());
            assert!(l.sigma_m.is_some_and(|s| s.is_finite() && s >= 0.0));
        }
    }
}

/// Target `truth_formats`: [`vgps_replay::drive::truth_formats::read_truth`] for three
/// frames (vgps, INS, NCLT and TUM truth).
pub fn truth_formats(data: &[u8]) {
    let frames: Vec<vgps_replay::drive::FrameRecord> = (0..3)
        .map(|k| vgps_replay::drive::FrameRecord {
            frame: k,
            time_s: k as f64 * 0.1,
            images: vec![],
        })
        .collect();
    let path = std::path::Path::new("fuzz.csv");
    if let Ok(read) = vgps_replay::drive::truth_formats::read_truth(path, &text(data), &frames) {
        for t in &read.records {
            let p = &t.position;
            assert!(p.lat_deg.abs() <= 90.0 && p.lon_deg.abs() <= 180.0 && p.alt_m.is_finite());
            assert!((t.enu_from_rig.norm() - 1.0).abs() < 1e-9);
        }
    }
}

/// Target `gpx`: [`vgps_replay::drive::gpx::read_gpx`] (GPX 1.0/1.1 track points).
pub fn gpx(data: &[u8]) {
    if let Ok((records, _)) =
        vgps_replay::drive::gpx::read_gpx(std::path::Path::new("fuzz.gpx"), &text(data))
    {
        assert_gnss_records(&records);
    }
}

/// Target `nclt_gps`: [`vgps_replay::drive::nclt_gps::read_nclt_gps`] (NCLT `gps.csv`).
pub fn nclt_gps(data: &[u8]) {
    if let Ok((records, _)) =
        vgps_replay::drive::nclt_gps::read_nclt_gps(std::path::Path::new("gps.csv"), &text(data))
    {
        assert_gnss_records(&records);
    }
}

/// Target `png_decode`: [`decode_png`] within [`PNG_LIMITS`].
pub fn png_decode(data: &[u8]) {
    if let Ok(image) = decode_png(data, &PNG_LIMITS) {
        assert!(image.width() <= PNG_LIMITS.max_width);
        assert!(image.height() <= PNG_LIMITS.max_height);
    }
}

/// The common body of the image-decoder targets: [`decode_image`] within [`PNG_LIMITS`],
/// the size of an `Ok` image within the limits, and the night-street detector run on it
/// (its detections finite and inside the image).
fn image_decode(data: &[u8]) {
    if let Ok(image) = decode_image(data, &PNG_LIMITS) {
        assert!(image.width() <= PNG_LIMITS.max_width);
        assert!(image.height() <= PNG_LIMITS.max_height);
        if let Ok(found) = StreetLampDetector::default().detect(&image) {
            for d in found.lamps.iter().chain(&found.others) {
                assert!(
                    d.u >= -0.5 && d.u <= f64::from(image.width()) - 0.5,
                    "{d:?}"
                );
                assert!(
                    d.v >= -0.5 && d.v <= f64::from(image.height()) - 0.5,
                    "{d:?}"
                );
                assert!(
                    d.strength.is_finite() && d.elongation >= 1.0 - 1e-9,
                    "{d:?}"
                );
            }
        }
    }
}

/// Target `jpeg_decode`: JPEG bytes through `image_decode`, and the frame-header walk.
pub fn jpeg_decode(data: &[u8]) {
    let _ = jpeg_frame_header(data);
    image_decode(data);
}

/// Target `tiff_decode`: TIFF bytes through `image_decode`.
pub fn tiff_decode(data: &[u8]) {
    image_decode(data);
}

/// Target `bmp_decode`: BMP bytes through `image_decode`.
pub fn bmp_decode(data: &[u8]) {
    image_decode(data);
}

/// Three vectors.
type Triple = [Vector3<f64>; 3];

fn check_p3p_input(data: &[u8]) -> Option<(Triple, Triple)> {
    let input: P3pInput = decode(data)?;
    Some((
        input.bearings.each_ref().map(vec3),
        input.points.each_ref().map(vec3),
    ))
}

/// Target `p3p`: [`p3p()`] (Lambda Twist) on arbitrary bearings and points.
pub fn p3p_lambda_twist(data: &[u8]) {
    if let Some((bearings, points)) = check_p3p_input(data) {
        for pose in &p3p(&bearings, &points) {
            assert_pose(pose, "p3p pose");
        }
    }
}

/// Target `p3p_cosines`: [`p3p_cosines()`] on arbitrary bearings and points.
pub fn p3p_law_of_cosines(data: &[u8]) {
    if let Some((bearings, points)) = check_p3p_input(data) {
        for pose in &p3p_cosines(&bearings, &points) {
            assert_pose(pose, "p3p_cosines pose");
        }
    }
}

/// Target `trilaterate`: [`trilaterate()`] on arbitrary centres and ranges.
pub fn trilateration(data: &[u8]) {
    let Some(input): Option<TrilaterateInput> = decode(data) else {
        return;
    };
    let centres = input.centres.each_ref().map(vec3);
    let ranges = input.ranges.map(Num::get);
    if let Ok(points) = trilaterate(&centres, &ranges) {
        for p in &points {
            assert_vec_finite(p, "trilaterated point");
        }
    }
}

/// Target `attitude`: [`triad()`] on the first two pairs, [`wahba()`] and
/// [`wahba_with_covariance`] on all of them.
pub fn attitude(data: &[u8]) {
    let Some(input): Option<AttitudeInput> = decode(data) else {
        return;
    };
    let pairs: Vec<_> = input.pairs.iter().take(MAX_OBSERVATIONS).collect();
    let in_rig: Vec<_> = pairs.iter().map(|p| vec3(&p.0)).collect();
    let in_world: Vec<_> = pairs.iter().map(|p| vec3(&p.1)).collect();
    let weights: Vec<_> = pairs.iter().map(|p| p.2.get()).collect();
    if in_rig.len() >= 2
        && let Some(r) = triad([&in_rig[0], &in_rig[1]], [&in_world[0], &in_world[1]])
    {
        assert_rotation(r.matrix(), "triad");
    }
    if let Some(r) = wahba(&in_rig, &in_world, &weights) {
        assert_rotation(r.matrix(), "wahba");
    }
    if let Some((r, cov)) =
        wahba_with_covariance(&in_rig, &in_world, &weights, input.sigma_rad.get())
    {
        assert_rotation(r.matrix(), "wahba_with_covariance");
        assert!(cov.iter().all(|x| x.is_finite()), "covariance {cov:?}");
    }
}

/// Target `triangulate`: [`intersect_two_rays()`] on the first two rays,
/// [`triangulate_rays()`] and [`triangulate_rays_weighted`] on all of them.
pub fn triangulate(data: &[u8]) {
    let Some(input): Option<TriangulateInput> = decode(data) else {
        return;
    };
    let obs: Vec<RayObservation> = input
        .rays
        .iter()
        .take(MAX_OBSERVATIONS)
        .map(|(o, d, sp, sa)| {
            let (origin, direction) = (vec3(o), vec3(d));
            let ray = match (input.normalise, Ray::try_new(origin, direction)) {
                (true, Some(r)) => r,
                _ => Ray { origin, direction },
            };
            RayObservation {
                ray,
                sigma_pos_m: sp.get(),
                sigma_ang_rad: sa.get(),
            }
        })
        .collect();
    if obs.len() >= 2
        && let Ok(x) = intersect_two_rays(&obs[0].ray, &obs[1].ray)
    {
        assert_vec_finite(&x.point, "intersection");
        assert!(x.ranges.iter().all(|r| r.is_finite() && *r > 0.0), "{x:?}");
        assert!(x.gap_m.is_finite() && x.gap_m >= 0.0, "{x:?}");
        assert!(x.parallax_rad().is_finite(), "{x:?}");
    }
    for t in [triangulate_rays(&obs), triangulate_rays_weighted(&obs)]
        .into_iter()
        .flatten()
    {
        assert_vec_finite(&t.point, "triangulated point");
        assert!(t.covariance.iter().all(|x| x.is_finite()), "{t:?}");
        assert!(t.max_parallax_rad().is_finite(), "{t:?}");
        assert_eq!(t.n_obs, obs.len());
    }
}

/// Target `matcher`: [`match_detections`] on arbitrary landmarks, detections, area and
/// options (at most [`MATCHER_MAX_ITEMS`] landmarks and detections).
pub fn matcher(data: &[u8]) {
    let Some(input): Option<MatcherInput> = decode(data) else {
        return;
    };
    let landmarks = input
        .landmarks
        .iter()
        .take(MATCHER_MAX_ITEMS)
        .enumerate()
        .map(|(i, (p, class, sigma))| DbLandmark {
            id: i.to_string(),
            position_in_world: vec3(p),
            class: class.map(u32::from),
            sigma_m: sigma.get(),
        })
        .collect();
    let Ok(db) = LandmarkDb::new(landmarks) else {
        return;
    };
    let detections: Vec<Detection> = input
        .detections
        .iter()
        .take(MATCHER_MAX_ITEMS)
        .map(|(o, d, class)| {
            let (origin, direction) = (vec3(o), vec3(d));
            Detection {
                ray: Ray::try_new(origin, direction).unwrap_or(Ray { origin, direction }),
                class: class.map(u32::from),
            }
        })
        .collect();
    let (lo, hi) = (vec3(&input.area.0), vec3(&input.area.1));
    let Some(area) = SearchArea::try_new(lo, hi).or_else(|| SearchArea::around(&lo, 50.0, 5.0))
    else {
        return;
    };
    let [sigma, threshold, range, cell] = input.reals.map(Num::get);
    let extent = area.max_in_world - area.min_in_world;
    let cells: f64 = (0..3).map(|k| (extent[k] / cell).ceil().max(1.0)).product();
    if cell > 0.0 && cell.is_finite() && cells > MATCHER_MAX_FUZZ_CELLS {
        return;
    }
    let c = input.counts.map(usize::from);
    let options = MatchOptions {
        sigma_rad: sigma,
        inlier_threshold_sigmas: threshold,
        visibility_range_m: range,
        cell_size_m: cell,
        min_inliers: c[0],
        ambiguity_margin: c[1],
        max_core_detections: c[2],
        max_detection_triples: c[3],
        max_hypotheses: c[4],
        seed: input.seed,
        up_in_rig: input.up.map(|(u, t)| (vec3(&u), t.get())),
        heading_in_world: None,
        min_extensions: c[5] % 4,
        max_rounds: 1 + (c[5] / 4) % 4,
        // 0, 0.4995 or 0.999.
        min_link_probability: ((c[5] / 16) % 3) as f64 * 0.4995,
        max_false_alarms: MatchOptions::default().max_false_alarms,
        // No cache, a small one (cells turn transient part-way) or the default.
        cache_budget_bytes: [0, 1 << 16, MatchOptions::default().cache_budget_bytes]
            [(input.seed % 3) as usize],
    };
    let Ok(result) = match_detections(&db, &detections, &area, &options) else {
        return;
    };
    assert_eq!(result.assignment.len(), detections.len());
    assert!(result.assignment.iter().flatten().all(|&k| k < db.len()));
    for (a, p) in result.assignment.iter().zip(&result.link_probability) {
        assert_eq!(a.is_some(), p.is_some());
        assert!(p.is_none_or(|p| (options.min_link_probability..=1.0).contains(&p)));
    }
    assert_eq!(result.estimate.is_some(), result.status == MatchStatus::Ok);
    if let Some(e) = &result.estimate {
        assert_pose(&e.world_from_rig, "matcher pose");
        assert!(e.covariance.iter().all(|x| x.is_finite()), "{e:?}");
        assert_finite(e.rms_residual_rad, "rms residual");
    }
    if let Some(p) = &result.runner_up_pose {
        assert_pose(p, "runner-up pose");
    }
}

/// Target `ros_cdr`: the CDR decoders of [`vgps_import::ros_decode`] (CompressedImage,
/// Image, NavSatFix, Imu) on the same bytes: never a panic; a decoded message's data lies
/// within the input and its strings within the limit.
pub fn ros_cdr(data: &[u8]) {
    use vgps_import::ros_decode::{self, MAX_STRING_BYTES};
    if let Ok(m) = ros_decode::compressed_image(data) {
        assert!(m.data.len() <= data.len() && m.format.len() <= MAX_STRING_BYTES);
        let _ = m.header.stamp_ns();
    }
    if let Ok(m) = ros_decode::raw_image(data) {
        assert!(m.data.len() <= data.len() && m.encoding.len() <= MAX_STRING_BYTES);
    }
    if let Ok(m) = ros_decode::nav_sat_fix(data) {
        assert!(m.header.frame_id.len() <= MAX_STRING_BYTES);
    }
    let _ = ros_decode::imu(data);
}

/// Target `mcap_read`: [`vgps_import::mcap_read::read_mcap`] on raw bytes, every message
/// handed to the CDR decoders ([`ros_cdr`]): never a panic; the counts agree with the
/// messages seen.
pub fn mcap_read(data: &[u8]) {
    let mut seen = 0u64;
    let result =
        vgps_import::mcap_read::read_mcap(std::path::Path::new("x.mcap"), data, &mut |m| {
            seen += 1;
            // Within the input, or within one decompressed chunk.
            assert!(m.data.len() as u64 <= vgps_import::mcap_read::MAX_CHUNK_BYTES);
            ros_cdr(m.data);
        });
    if let Ok(summary) = result {
        assert_eq!(summary.messages, seen);
        assert!(summary.bytes <= data.len() as u64);
    }
}

/// Target `import_tables`: the small text files of the imports — the MCAP topic mapping
/// (`topic,camera`), an image folder's `times.csv`, the times in image file names, and
/// NCLT's ground truth (`vgps_import`): never a panic; what is read is within bounds.
pub fn import_tables(data: &[u8]) {
    use vgps_import::{drive_out::ImportReport, folders, mcap_import, nclt};
    let text = text(data);
    let path = Path::new(FUZZ_PATH);
    let lines = text.lines().count();
    if let Ok(map) = mcap_import::topic_map_from_str(&text, path) {
        assert!(map.len() <= lines);
        assert!(
            map.values()
                .all(|&c| c < vgps_replay::drive::MAX_IMAGE_COLUMNS)
        );
    }
    let mut report = ImportReport::default();
    let times = folders::times_from_str(&text, path, &mut report);
    assert!(times.len() as u64 + report.skipped <= lines as u64);
    for line in text.lines() {
        let _ = folders::time_ns_of_name(line);
    }
    let mut report = ImportReport::default();
    let truth = nclt::read_ground_truth(path, &text, &mut report);
    assert!(truth.len() <= lines);
    assert!(truth.windows(2).all(|w| w[0].utime < w[1].utime));
    for row in &truth {
        assert!(row.ned_m.iter().chain(&row.rpy).all(|x| x.is_finite()));
    }
}

/// Target `raw_image`: a `sensor_msgs/Image` CDR decoded and written as PNG as the MCAP
/// import does ([`vgps_import::mcap_import::raw_image_to_png`]): never a panic, and a PNG
/// written decodes back to the image's size.
pub fn raw_image(data: &[u8]) {
    let Ok(img) = vgps_import::ros_decode::raw_image(data) else {
        return;
    };
    let Ok(png) = vgps_import::mcap_import::raw_image_to_png(&img) else {
        return;
    };
    // The input holds every row, so the image has fewer pixels than the input has bytes.
    let limits = DecodeLimits {
        max_width: u32::MAX,
        max_height: u32::MAX,
        max_bytes: 64 << 20,
    };
    let back = decode_png(&png, &limits).expect("the PNG written decodes");
    assert_eq!((back.width(), back.height()), (img.width, img.height));
}

/// A target: its name and its body.
pub type Target = (&'static str, fn(&[u8]));

/// Every target: `(name, body)`, the names of `fuzz/fuzz_targets/*.rs` and of the corpus
/// directories `fuzz/corpus/<name>/`.
pub const TARGETS: &[Target] = &[
    ("native_json", native_json),
    ("ladybug_ini", ladybug_ini),
    ("ladybug_conf", ladybug_conf),
    ("nclt_calibration", nclt_calibration),
    ("nclt_table", nclt_table),
    ("lut", lut),
    ("camera_mask", camera_mask),
    ("landmarks_csv", landmarks_csv),
    ("observations_csv", observations_csv),
    ("rays_csv", rays_csv),
    ("drive_tables", drive_tables),
    ("drive_json", drive_json),
    ("nmea", nmea),
    ("gpx", gpx),
    ("nclt_gps", nclt_gps),
    ("ubx", ubx),
    ("sirf", sirf),
    ("imu_csv", imu_csv),
    ("gis_landmarks", gis_landmarks),
    ("building_footprints", building_footprints),
    ("truth_formats", truth_formats),
    ("ros_cdr", ros_cdr),
    ("mcap_read", mcap_read),
    ("import_tables", import_tables),
    ("raw_image", raw_image),
    ("png_decode", png_decode),
    ("jpeg_decode", jpeg_decode),
    ("tiff_decode", tiff_decode),
    ("bmp_decode", bmp_decode),
    ("p3p", p3p_lambda_twist),
    ("p3p_cosines", p3p_law_of_cosines),
    ("trilaterate", trilateration),
    ("attitude", attitude),
    ("triangulate", triangulate),
    ("matcher", matcher),
];
