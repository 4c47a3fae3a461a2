//! # vgps-python — the `vgps` Python package's native module
//!
//! PyO3 bindings (module `vgps._vgps`, re-exported by the pure-Python package `vgps` in
//! `python/vgps`) over the workspace's library crates: P3P and triangulation
//! (`vgps-geometry`), calibrations and pixel↔bearing (`vgps-camera`), the frame-by-frame
//! localizer (`vgps-core`), and `locate`, `replay` and `simulate` through the command
//! line's own library functions (`vgps::cli`), so Python and the CLI give the same numbers
//! and the same error messages. Built by maturin as one abi3 wheel (CPython ≥ 3.9); see
//! `crates/python/README.md`.
//!
//! Arrays are NumPy `float64` (any array-like that converts to it is accepted); shapes are
//! checked and a wrong one raises `ValueError` naming the argument. Errors of the library
//! raise `vgps.VgpsError` (a `ValueError`) with the library's message.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array2, ArrayView2, ArrayView3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1, PyArrayLike2, PyArrayLikeDyn,
    PyArrayMethods, PyUntypedArrayMethods, ToPyArray,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::Arc;
use vgps_camera::calibration::{CameraModel, Pixel, Rig};
use vgps_core::localizer::{self, Frame, GnssPosition, LandmarkMap, LocalizerOptions, Observation};
use vgps_geometry::geo::Geodetic;
use vgps_geometry::geometry::Ray;
use vgps_geometry::triangulation::{RayObservation, triangulate_rays};
use vgps_io::{Landmark, ObservationRecord};

// Module `vgps` (where the package exports it), so that pickle finds `vgps.VgpsError`:
// the error crosses process boundaries (multiprocessing, Ray) intact.
pyo3::create_exception!(
    vgps,
    VgpsError,
    PyValueError,
    "An error of the vgps library (bad input file, invalid problem, failed command); the \
     message is the library's, as the command line prints it."
);

/// A `ValueError` naming the argument whose shape is wrong.
fn shape_error(name: &str, expected: &str, got: &[usize]) -> PyErr {
    PyValueError::new_err(format!(
        "{name}: expected an array of shape {expected}, got shape {got:?}"
    ))
}

/// The rows of an `(N, k)` array, checked.
fn rows<const K: usize>(name: &str, array: &ArrayView2<'_, f64>) -> PyResult<Vec<[f64; K]>> {
    let shape = array.shape();
    if shape[1] != K {
        return Err(shape_error(name, &format!("(N, {K})"), shape));
    }
    Ok(array
        .rows()
        .into_iter()
        .map(|r| std::array::from_fn(|k| r[k]))
        .collect())
}

/// The most solutions a P3P problem has.
const P3P_MAX_SOLUTIONS: usize = 4;

/// Every solution of one P3P problem (bearings and points as row-major 3×3) as `k` blocks
/// `[R | t]` (3×4, row-major) at the front of a stack buffer: no heap allocation.
fn p3p_one(b: &[f64], p: &[f64]) -> ([f64; 12 * P3P_MAX_SOLUTIONS], usize) {
    let bearings: [Vector3<f64>; 3] =
        std::array::from_fn(|i| Vector3::new(b[3 * i], b[3 * i + 1], b[3 * i + 2]));
    let points: [Vector3<f64>; 3] =
        std::array::from_fn(|i| Vector3::new(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
    let mut out = [0.0; 12 * P3P_MAX_SOLUTIONS];
    let solutions = vgps_geometry::solvers::p3p(&bearings, &points);
    let k = solutions.len().min(P3P_MAX_SOLUTIONS);
    for (s, block) in solutions.iter().zip(out.chunks_exact_mut(12)) {
        let r = s.rotation.matrix();
        let t = s.translation.vector;
        for i in 0..3 {
            block[4 * i..4 * i + 4].copy_from_slice(&[r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]]);
        }
    }
    (out, k)
}

/// `k` solutions as a new `(k, 3, 4)` array: one NumPy allocation, one copy.
fn poses_array<'py>(
    py: Python<'py>,
    (out, k): ([f64; 12 * P3P_MAX_SOLUTIONS], usize),
) -> PyResult<Bound<'py, PyAny>> {
    let view = ArrayView3::from_shape((k, 3, 4), &out[..12 * k])
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(view.to_pyarray(py).into_any())
}

/// The nine numbers of a C-contiguous `float64` array of shape `(3, 3)` (a row of an
/// `(N, 3, 3)` array is one), read without NumPy's general conversion; `None` for anything
/// else, which then goes through [`array_arg`] and its checks.
fn exact_3x3(a: &Bound<'_, PyAny>) -> Option<Vec<f64>> {
    let a = a.cast::<PyArray2<f64>>().ok()?;
    if a.shape() != [3, 3] || !a.is_c_contiguous() {
        return None;
    }
    a.to_vec().ok()
}

/// Any array-like as a `float64` array (NumPy's `asarray`); a conversion error gets the
/// note "while processing 'NAME'", as PyO3 adds to an argument it converts itself.
fn array_arg<'py>(
    name: &str,
    a: &Bound<'py, PyAny>,
) -> PyResult<PyArrayLikeDyn<'py, f64, AllowTypeChange>> {
    a.extract().inspect_err(|e: &PyErr| {
        // Best effort: a note is an addition to the message, never a second error.
        let _ = e
            .value(a.py())
            .call_method1("add_note", (format!("while processing '{name}'"),));
    })
}

/// Every pose of a rig that sees three world points along three bearings (P3P, Lambda
/// Twist).
///
/// `bearings` are directions in the rig frame (any non-zero length) and `points` metres
/// in a Cartesian world frame, row k of one seeing row k of the other: shape `(3, 3)`, or
/// `(N, 3, 3)` for N problems in one call. Returns, for one problem, an array of shape
/// `(k, 3, 4)` with k ≤ 4 solutions `world_from_rig = [R | t]` (rotation, rig origin in the
/// world); for N problems, a list of N such arrays. A degenerate problem gives k = 0.
///
/// Example:
/// >>> import numpy as np, vgps
/// >>> points = np.array([[30.0, 0, 5], [-20, 4, 1], [12, 25, -3]])
/// >>> bearings = points - np.array([10.0, -5.0, 2.0])   # a rig at (10, -5, 2), not rotated
/// >>> poses = vgps.p3p(bearings, points)
/// >>> bool(min(np.abs(p[:, 3] - [10, -5, 2]).max() for p in poses) < 1e-9)
/// True
#[pyfunction]
fn p3p<'py>(
    py: Python<'py>,
    bearings: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    // One problem per call with float64 (3, 3) arrays, the per-frame case: no conversion,
    // no borrow bookkeeping, one output allocation (issue #29's per-call overhead).
    if let (Some(b), Some(p)) = (exact_3x3(bearings), exact_3x3(points)) {
        return poses_array(py, p3p_one(&b, &p));
    }
    let b = array_arg("bearings", bearings)?;
    let p = array_arg("points", points)?;
    let (b, p) = (b.as_array(), p.as_array());
    if b.shape() != p.shape() {
        return Err(PyValueError::new_err(format!(
            "bearings and points must have the same shape, got {:?} and {:?}",
            b.shape(),
            p.shape()
        )));
    }
    // Row-major copies, whatever the arrays' memory order.
    let bs: Vec<f64> = b.iter().copied().collect();
    let ps: Vec<f64> = p.iter().copied().collect();
    match b.shape() {
        [3, 3] => poses_array(py, p3p_one(&bs, &ps)),
        [_, 3, 3] => {
            let arrays = bs
                .chunks_exact(9)
                .zip(ps.chunks_exact(9))
                .map(|(b, p)| poses_array(py, p3p_one(b, p)))
                .collect::<PyResult<Vec<_>>>()?;
            Ok(PyList::new(py, arrays)?.into_any())
        }
        other => Err(shape_error("bearings", "(3, 3) or (N, 3, 3)", other)),
    }
}

/// The point nearest to several rays in the least-squares sense, with its covariance.
///
/// `origins` (metres) and `directions` (any non-zero length) have shape `(N, 3)`, N ≥ 2,
/// in one Cartesian frame. `sigma_pos_m` is the observer position σ per axis, `sigma_rad`
/// the direction σ per tangent axis (scalars, or arrays of shape `(N,)`). Returns a dict
/// with `point` (3,), `covariance` (3, 3) m², `n_obs` and `max_parallax_rad`.
///
/// Raises `VgpsError` for a degenerate problem (parallel rays, too little parallax), with
/// the library's message.
///
/// Example:
/// >>> import numpy as np, vgps
/// >>> origins = np.array([[0.0, 0, 0], [10, 0, 0]])
/// >>> directions = np.array([[1.0, 1, 0], [-1, 1, 0]])
/// >>> r = vgps.triangulate(origins, directions, sigma_rad=1e-3)
/// >>> np.allclose(r["point"], [5, 5, 0])
/// True
#[pyfunction]
#[pyo3(signature = (origins, directions, sigma_pos_m = None, sigma_rad = None))]
fn triangulate<'py>(
    py: Python<'py>,
    origins: PyArrayLike2<'py, f64, AllowTypeChange>,
    directions: PyArrayLike2<'py, f64, AllowTypeChange>,
    sigma_pos_m: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
    sigma_rad: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
) -> PyResult<Bound<'py, PyDict>> {
    let o = rows::<3>("origins", &origins.as_array())?;
    let d = rows::<3>("directions", &directions.as_array())?;
    if o.len() != d.len() {
        return Err(PyValueError::new_err(format!(
            "origins has {} rows and directions {}: they must match",
            o.len(),
            d.len()
        )));
    }
    let per_ray =
        |name: &str, a: &Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>, default: f64| match a {
            None => Ok(vec![default; o.len()]),
            Some(a) => {
                let v: Vec<f64> = a.as_array().iter().copied().collect();
                match v.len() {
                    1 => Ok(vec![v[0]; o.len()]),
                    n if n == o.len() => Ok(v),
                    n => Err(shape_error(name, &format!("() or ({},)", o.len()), &[n])),
                }
            }
        };
    let sp = per_ray("sigma_pos_m", &sigma_pos_m, 0.0)?;
    let sa = per_ray("sigma_rad", &sigma_rad, 0.1_f64.to_radians())?;
    let mut obs = Vec::with_capacity(o.len());
    for (k, (origin, direction)) in o.iter().zip(&d).enumerate() {
        let ray =
            Ray::try_new(Vector3::from(*origin), Vector3::from(*direction)).ok_or_else(|| {
                VgpsError::new_err(format!("ray {k}: zero or non-finite direction or origin"))
            })?;
        obs.push(RayObservation {
            ray,
            sigma_pos_m: sp[k],
            sigma_ang_rad: sa[k],
        });
    }
    let t = triangulate_rays(&obs).map_err(|e| VgpsError::new_err(e.to_string()))?;
    let dict = PyDict::new(py);
    dict.set_item("point", PyArray1::from_slice(py, t.point.as_slice()))?;
    let cov = Array2::from_shape_fn((3, 3), |(i, j)| t.covariance[(i, j)]);
    dict.set_item("covariance", cov.into_pyarray(py))?;
    dict.set_item("n_obs", t.n_obs)?;
    dict.set_item("max_parallax_rad", t.max_parallax_rad())?;
    Ok(dict)
}

/// A rig calibration: N cameras in the rig frame (x forward, y left, z up), loaded from any
/// format `vgps calib` reads (native JSON, Ladybug INI or `.conf`, NCLT).
///
/// Example:
/// >>> import numpy as np, vgps
/// >>> cal = vgps.Calibration.load("calibration/equirectangular_2048x1024.json")
/// >>> b = cal.pixel_to_bearing(np.array([[1023.5, 511.5]]))   # camera 0
/// >>> px, visible, camera = cal.bearing_to_pixel(b)
/// >>> bool(visible.all() and np.allclose(px, [[1023.5, 511.5]]))
/// True
#[pyclass(frozen, module = "vgps")]
struct Calibration {
    rig: Arc<Rig>,
}

#[pymethods]
impl Calibration {
    /// Loads a calibration file. `image_size=(width, height)` gives the image size of a
    /// Ladybug INI export that names none. Raises `VgpsError` naming the file and the
    /// field for a bad file.
    #[staticmethod]
    #[pyo3(signature = (path, image_size = None))]
    fn load(py: Python<'_>, path: PathBuf, image_size: Option<(u32, u32)>) -> PyResult<Self> {
        let rig = py
            .detach(|| vgps_camera::calibration::formats::load(&path, None, image_size))
            .map_err(|e| VgpsError::new_err(format!("{}: {e}", path.display())))?;
        Ok(Self { rig: Arc::new(rig) })
    }

    /// Number of cameras.
    fn __len__(&self) -> usize {
        self.rig.len()
    }

    /// Image sizes `(width, height)` of every camera.
    #[getter]
    fn image_sizes(&self) -> Vec<(u32, u32)> {
        self.rig
            .cameras()
            .iter()
            .map(|c| c.model.image_size())
            .collect()
    }

    /// Unit bearings in the rig frame, shape `(N, 3)`, of pixels `(N, 2)` (columns u, v;
    /// integer = pixel centre) of one camera (`camera`: an int) or of each row's camera
    /// (`camera`: an int array of shape `(N,)`). Raises `VgpsError` naming the first row
    /// whose pixel is outside its camera's image.
    #[pyo3(signature = (pixels, camera = None))]
    fn pixel_to_bearing<'py>(
        &self,
        py: Python<'py>,
        pixels: PyArrayLike2<'py, f64, AllowTypeChange>,
        camera: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let px = rows::<2>("pixels", &pixels.as_array())?;
        let cams = cameras_arg(camera, px.len())?;
        let rig = Arc::clone(&self.rig);
        let out = py.detach(move || -> Result<Vec<f64>, String> {
            let mut out = Vec::with_capacity(3 * px.len());
            for (k, (p, c)) in px.iter().zip(&cams).enumerate() {
                let ray = rig
                    .ray(*c, &Pixel::new(p[0], p[1]))
                    .map_err(|e| format!("pixels row {k}: {e}"))?;
                out.extend_from_slice(ray.direction.as_slice());
            }
            Ok(out)
        });
        let out = out.map_err(VgpsError::new_err)?;
        let n = out.len() / 3;
        Ok(Array2::from_shape_vec((n, 3), out)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            .into_pyarray(py))
    }

    /// Pixels `(N, 2)` of bearings `(N, 3)` in the rig frame (directions; the camera
    /// centres' offsets are ignored) in one camera (`camera`: an int or `(N,)` ints), and a
    /// boolean mask `(N,)` of the rows that camera sees. With `camera=None`, each bearing
    /// goes to the first camera that sees it, and a third array gives that camera (−1:
    /// none). Rows not seen hold 0.
    #[pyo3(signature = (bearings, camera = None))]
    fn bearing_to_pixel<'py>(
        &self,
        py: Python<'py>,
        bearings: PyArrayLike2<'py, f64, AllowTypeChange>,
        camera: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = rows::<3>("bearings", &bearings.as_array())?;
        let n = b.len();
        let fixed = match camera {
            None => None,
            Some(c) => Some(cameras_arg(Some(c), n)?),
        };
        let rig = Arc::clone(&self.rig);
        let any_camera = fixed.is_none();
        let (pixels, visible, which) = py.detach(move || {
            let mut pixels = vec![0.0; 2 * n];
            let mut visible = vec![false; n];
            let mut which = vec![-1_i64; n];
            for (k, d) in b.iter().enumerate() {
                let d = Vector3::from(*d);
                let hit = match &fixed {
                    Some(cams) => rig.camera(cams[k]).ok().and_then(|c| {
                        c.model
                            .try_pixel(&c.rig_from_camera.rotation.inverse_transform_vector(&d))
                            .map(|p| (cams[k], p))
                    }),
                    None => rig
                        .project_direction(&d)
                        .first()
                        .map(|h| (h.camera, h.pixel)),
                };
                if let Some((c, p)) = hit {
                    pixels[2 * k] = p.x;
                    pixels[2 * k + 1] = p.y;
                    visible[k] = true;
                    which[k] = c as i64;
                }
            }
            (pixels, visible, which)
        });
        let pixels = Array2::from_shape_vec((n, 2), pixels)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            .into_pyarray(py);
        let visible = Array1::from_vec(visible).into_pyarray(py);
        if any_camera {
            let which = Array1::from_vec(which).into_pyarray(py);
            Ok((pixels, visible, which).into_pyobject(py)?.into_any())
        } else {
            Ok((pixels, visible).into_pyobject(py)?.into_any())
        }
    }

    fn __repr__(&self) -> String {
        format!("Calibration({} cameras)", self.rig.len())
    }
}

/// The camera of each of `n` rows: one int for all, or an int sequence of length `n`
/// (default 0).
fn cameras_arg(camera: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Vec<usize>> {
    let Some(camera) = camera else {
        return Ok(vec![0; n]);
    };
    if let Ok(c) = camera.extract::<usize>() {
        return Ok(vec![c; n]);
    }
    let cams: Vec<usize> = camera.extract().map_err(|_| {
        PyValueError::new_err("camera: expected a non-negative int or a sequence of them")
    })?;
    if cams.len() != n {
        return Err(shape_error("camera", &format!("({n},)"), &[cams.len()]));
    }
    Ok(cams)
}

/// Landmark columns from Python: ids, `lat_lon_alt` (N, 3) and `sigma_m` (N,) or None.
type LandmarkColumns<'py> = (
    Vec<String>,
    PyArrayLike2<'py, f64, AllowTypeChange>,
    Option<PyArrayLike1<'py, f64, AllowTypeChange>>,
);

/// Landmarks from a CSV path, or from columns `(ids, lat_lon_alt (N, 3), sigma_m (N,) or
/// None)`.
fn landmarks_arg(landmarks: &Bound<'_, PyAny>) -> PyResult<(Vec<Landmark>, PathBuf)> {
    if let Ok(path) = landmarks.extract::<PathBuf>() {
        let l = vgps_io::read_landmarks(&path).map_err(|e| VgpsError::new_err(e.to_string()))?;
        return Ok((l, path));
    }
    let (ids, lla, sigma): LandmarkColumns<'_> = landmarks.extract().map_err(|_| {
        PyValueError::new_err(
            "landmarks: expected a CSV path or a tuple (ids, lat_lon_alt (N, 3), sigma_m (N,) \
             or None)",
        )
    })?;
    let lla = rows::<3>("landmarks lat_lon_alt", &lla.as_array())?;
    if ids.len() != lla.len() {
        return Err(shape_error(
            "landmarks lat_lon_alt",
            &format!("({}, 3)", ids.len()),
            &[lla.len(), 3],
        ));
    }
    let sigma = match sigma {
        None => vec![None; ids.len()],
        Some(s) => {
            let s = s.as_array();
            if s.len() != ids.len() {
                return Err(shape_error(
                    "landmarks sigma_m",
                    &format!("({},)", ids.len()),
                    &[s.len()],
                ));
            }
            s.iter().map(|&v| Some(v)).collect()
        }
    };
    let list = ids
        .into_iter()
        .zip(lla)
        .zip(sigma)
        .enumerate()
        .map(|(k, ((id, [lat, lon, alt]), sigma_m))| Landmark {
            id,
            lat_deg: lat,
            lon_deg: lon,
            alt_m: alt,
            sigma_m,
            class: None,
            line: k as u64 + 1,
        })
        .collect();
    Ok((list, PathBuf::from("<landmarks array>")))
}

/// A `(lat, lon, alt, radius_m)` tuple as the CLI's `--prior`.
fn area_arg(
    name: &str,
    area: Option<(f64, f64, f64, f64)>,
) -> PyResult<Option<vgps::cli::PriorArg>> {
    let Some((lat, lon, alt, radius_m)) = area else {
        return Ok(None);
    };
    let position = Geodetic::try_new(lat, lon, alt)
        .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
    if !(radius_m.is_finite() && radius_m > 0.0) {
        return Err(PyValueError::new_err(format!(
            "{name}: radius_m {radius_m} must be positive and finite"
        )));
    }
    Ok(Some(vgps::cli::PriorArg { position, radius_m }))
}

/// Turns a serde value into Python objects through `json.loads`.
fn to_python<'py, T: serde::Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| VgpsError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// One fix per frame from bearings (or pixels) to landmarks: the library function behind
/// `vgps locate`, with the same statuses, numbers and messages.
#[pyfunction]
#[pyo3(signature = (landmarks, bearings = None, *, ids = None, pixels = None, camera = None,
    frames = None, calibration = None, prior = None, region = None, sigma_deg = 0.1,
    up_tolerance_deg = None))]
#[allow(clippy::too_many_arguments)]
fn _locate<'py>(
    py: Python<'py>,
    landmarks: &Bound<'py, PyAny>,
    bearings: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
    ids: Option<Vec<Option<String>>>,
    pixels: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
    camera: Option<&Bound<'py, PyAny>>,
    frames: Option<Vec<u64>>,
    calibration: Option<&Calibration>,
    prior: Option<(f64, f64, f64, f64)>,
    region: Option<(f64, f64, f64, f64)>,
    sigma_deg: f64,
    up_tolerance_deg: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let (landmarks, landmarks_path) = landmarks_arg(landmarks)?;
    let measurements: Vec<vgps_io::MeasurementRecord> = match (&bearings, &pixels) {
        (Some(b), None) => rows::<3>("bearings", &b.as_array())?
            .into_iter()
            .map(|b| vgps_io::MeasurementRecord::Bearing(Vector3::from(b)))
            .collect(),
        (None, Some(p)) => {
            let p = rows::<2>("pixels", &p.as_array())?;
            let cams = cameras_arg(camera, p.len())?;
            p.into_iter()
                .zip(cams)
                .map(|([u, v], c)| vgps_io::MeasurementRecord::Pixel {
                    camera: c.to_string(),
                    u,
                    v,
                })
                .collect()
        }
        _ => {
            return Err(PyValueError::new_err(
                "give exactly one of bearings (N, 3) and pixels (N, 2)",
            ));
        }
    };
    let n = measurements.len();
    let ids = ids.unwrap_or_else(|| vec![None; n]);
    let frames = frames.unwrap_or_else(|| vec![0; n]);
    if ids.len() != n {
        return Err(shape_error("ids", &format!("({n},)"), &[ids.len()]));
    }
    if frames.len() != n {
        return Err(shape_error("frames", &format!("({n},)"), &[frames.len()]));
    }
    let observations: Vec<ObservationRecord> = measurements
        .into_iter()
        .zip(ids)
        .zip(frames)
        .enumerate()
        .map(|(k, ((measurement, landmark), frame))| ObservationRecord {
            frame,
            measurement,
            landmark: landmark.filter(|s| !s.is_empty()),
            line: k as u64 + 1,
        })
        .collect();
    if !(sigma_deg.is_finite() && sigma_deg > 0.0) {
        return Err(PyValueError::new_err(format!(
            "sigma_deg {sigma_deg} must be positive"
        )));
    }
    let prior = area_arg("prior", prior)?;
    let region = area_arg("region", region)?;
    let rig = calibration.map(|c| Arc::clone(&c.rig));
    let observations_path = PathBuf::from("<observations array>");
    let result = py.detach(|| {
        let input = vgps::cli::locate::LocateInput {
            landmarks: &landmarks,
            landmarks_path: &landmarks_path,
            observations: &observations,
            observations_path: &observations_path,
            rig: rig.as_deref(),
            prior: prior.as_ref(),
            region: region.as_ref(),
            up_tolerance_rad: up_tolerance_deg.map(f64::to_radians),
            sigma_rad: sigma_deg.to_radians(),
        };
        let mut notes = Vec::new();
        vgps::cli::locate::locate(&input, &mut notes)
    });
    let reports = result.map_err(|e| VgpsError::new_err(e.to_string()))?;
    to_python(py, &reports)
}

/// Runs a `vgps` command line (argv without the program name) with the GIL released;
/// returns its standard output, raises `VgpsError` with its error message on failure.
#[pyfunction]
fn _run_cli(py: Python<'_>, args: Vec<String>) -> PyResult<String> {
    let (code, out, err) = py.detach(move || {
        let mut out = Vec::new();
        let mut err = Vec::new();
        let argv = std::iter::once("vgps".to_string()).chain(args);
        let code = vgps::cli::run(argv, &mut out, &mut err);
        (code, out, err)
    });
    if code == std::process::ExitCode::SUCCESS {
        Ok(String::from_utf8_lossy(&out).into_owned())
    } else {
        let err = String::from_utf8_lossy(&err);
        let message = err
            .lines()
            .filter_map(|l| l.strip_prefix("vgps: error: "))
            .collect::<Vec<_>>()
            .join("\n");
        let message = if message.is_empty() {
            err.trim().to_string()
        } else {
            message
        };
        Err(VgpsError::new_err(message))
    }
}

/// The frame-by-frame localizer for a robot loop: tracking, re-acquisition by the landmark
/// matcher around a prior (the previous fix, or a satellite GPS position given with the
/// frame), surrogate landmarks mapped on the way — `vgps replay`'s engine.
///
/// `Localizer(calibration, landmarks, *, pixel_sigma_px=None, cold_start=True,
/// surrogates=True, level_tolerance_deg=5.0, gnss_prior_radius_m=None)`; `landmarks` is a
/// CSV path or `(ids, lat_lon_alt (N, 3), sigma_m (N,) or None)`.
///
/// `process(time_s, *, pixels=(N, 2), camera=int or (N,), bearings=(M, 3), sigma_rad=None,
/// gnss=(lat, lon, alt))` takes one frame (pixels of the rig's cameras and/or bearings in
/// the rig frame), releases the GIL while it works, and returns a dict: `status` (`ok`,
/// `no_fix`, `no_prior`, `ambiguous`, `too_few_observations`, `invalid_frame`), `message`,
/// `source` (`tracking`, `matcher`, `cold_start`), `lat_lon_alt` (3,), `position_enu` (3,,
/// in the map's ENU frame at `origin`), `enu_from_rig_wxyz` (4,), `heading_pitch_roll_deg`
/// (3,), `covariance` (6, 6: `[δp m, δθ rad]` in the map's ENU), `rms_residual_rad`,
/// `landmarks` (ids used), `surrogates`, `n_observations`, `n_rejected`,
/// `gnss_difference_m`. Without a fix the arrays are `None`. `backward=True` localizes a
/// drive in reverse (frames given in decreasing time, as `vgps replay --direction combined`
/// does in its second pass); use one localizer per direction.
///
/// Example:
/// >>> import vgps
/// >>> cal = vgps.Calibration.load("drive/calibration.json")          # doctest: +SKIP
/// >>> loc = vgps.Localizer(cal, "drive/landmarks.csv")               # doctest: +SKIP
/// >>> for t, pixels, cameras in frames:                               # doctest: +SKIP
/// ...     fix = loc.process(t, pixels=pixels, camera=cameras, gnss=gps_or_none)
/// ...     if fix["status"] == "ok":
/// ...         publish(fix["lat_lon_alt"], fix["enu_from_rig_wxyz"], fix["covariance"])
#[pyclass(module = "vgps", name = "Localizer")]
struct PyLocalizer {
    inner: localizer::Localizer,
    map: Arc<LandmarkMap>,
}

#[pymethods]
impl PyLocalizer {
    /// A localizer for a calibration and a landmark map (CSV path or columns tuple).
    #[new]
    #[pyo3(signature = (calibration, landmarks, *, pixel_sigma_px = None, cold_start = true,
        surrogates = true, level_tolerance_deg = Some(5.0), gnss_prior_radius_m = None,
        max_turn_rate_change_deg_s = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        calibration: &Calibration,
        landmarks: &Bound<'_, PyAny>,
        pixel_sigma_px: Option<f64>,
        cold_start: bool,
        surrogates: bool,
        level_tolerance_deg: Option<f64>,
        gnss_prior_radius_m: Option<f64>,
        max_turn_rate_change_deg_s: Option<f64>,
    ) -> PyResult<Self> {
        let (landmarks, _) = landmarks_arg(landmarks)?;
        let map = Arc::new(
            LandmarkMap::from_landmarks(&landmarks, None)
                .map_err(|e| VgpsError::new_err(e.to_string()))?,
        );
        let defaults = LocalizerOptions::default();
        let options = LocalizerOptions {
            pixel_sigma_px: pixel_sigma_px.unwrap_or(defaults.pixel_sigma_px),
            cold_start,
            surrogates,
            level_tolerance_rad: level_tolerance_deg.map(f64::to_radians),
            gnss_prior_radius_m: gnss_prior_radius_m.unwrap_or(defaults.gnss_prior_radius_m),
            max_turn_rate_change_rad_s: max_turn_rate_change_deg_s
                .map_or(defaults.max_turn_rate_change_rad_s, f64::to_radians),
            ..defaults
        };
        let inner =
            localizer::Localizer::new(Arc::clone(&calibration.rig), Arc::clone(&map), options)
                .map_err(|e| VgpsError::new_err(e.to_string()))?;
        Ok(Self { inner, map })
    }

    /// Processes one frame (releases the GIL); see the Python docstring.
    #[pyo3(signature = (time_s, *, pixels = None, camera = None, bearings = None,
        sigma_rad = None, gnss = None, classes = None, backward = false))]
    #[allow(clippy::too_many_arguments)]
    fn process<'py>(
        &mut self,
        py: Python<'py>,
        time_s: f64,
        pixels: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
        camera: Option<&Bound<'py, PyAny>>,
        bearings: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
        sigma_rad: Option<f64>,
        gnss: Option<(f64, f64, f64)>,
        classes: Option<Vec<Option<String>>>,
        backward: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut observations = Vec::new();
        if let Some(p) = &pixels {
            let p = rows::<2>("pixels", &p.as_array())?;
            let cams = cameras_arg(camera, p.len())?;
            let classes = classes.unwrap_or_else(|| vec![None; p.len()]);
            if classes.len() != p.len() {
                return Err(shape_error(
                    "classes",
                    &format!("({},)", p.len()),
                    &[classes.len()],
                ));
            }
            let map = &self.map;
            observations.extend(
                p.iter()
                    .zip(cams)
                    .zip(classes)
                    .map(|((&[u, v], camera), c)| Observation {
                        measurement: localizer::Measurement::Pixel { camera, u, v },
                        class: c.as_deref().and_then(|c| map.class_index(c)),
                    }),
            );
        }
        if let Some(b) = &bearings {
            let sigma_rad = sigma_rad.unwrap_or(vgps_core::measurement::DEFAULT_BEARING_SIGMA_RAD);
            for (k, d) in rows::<3>("bearings", &b.as_array())?
                .into_iter()
                .enumerate()
            {
                let ray = Ray::try_new(Vector3::zeros(), Vector3::from(d)).ok_or_else(|| {
                    PyValueError::new_err(format!("bearings row {k}: zero or non-finite"))
                })?;
                observations.push(Observation {
                    measurement: localizer::Measurement::Ray { ray, sigma_rad },
                    class: None,
                });
            }
        }
        let gnss = match gnss {
            None => None,
            Some((lat, lon, alt)) => Some(GnssPosition {
                position: Geodetic::try_new(lat, lon, alt)
                    .map_err(|e| PyValueError::new_err(format!("gnss: {e}")))?,
            }),
        };
        let frame = Frame {
            time_s,
            observations,
            gnss,
            attitude: None,
        };
        let inner = &mut self.inner;
        let fix = py.detach(|| {
            if backward {
                inner.process_backward(&frame)
            } else {
                inner.process(&frame)
            }
        });
        let d = PyDict::new(py);
        d.set_item("time_s", fix.time_s)?;
        d.set_item("status", fix.status.as_str())?;
        d.set_item("message", &fix.message)?;
        d.set_item("source", fix.source.map(|s| s.as_str()))?;
        d.set_item("n_observations", fix.n_observations)?;
        d.set_item("n_rejected", fix.n_rejected)?;
        d.set_item("gnss_difference_m", fix.gnss_difference_m)?;
        match &fix.estimate {
            None => {
                for key in [
                    "lat_lon_alt",
                    "position_enu",
                    "enu_from_rig_wxyz",
                    "heading_pitch_roll_deg",
                    "covariance",
                    "rms_residual_rad",
                ] {
                    d.set_item(key, py.None())?;
                }
                d.set_item("landmarks", PyList::empty(py))?;
                d.set_item("surrogates", PyList::empty(py))?;
            }
            Some(e) => {
                let g = e.geodetic;
                d.set_item(
                    "lat_lon_alt",
                    PyArray1::from_slice(py, &[g.lat_deg, g.lon_deg, g.alt_m]),
                )?;
                d.set_item(
                    "position_enu",
                    PyArray1::from_slice(py, e.world_from_rig.translation.vector.as_slice()),
                )?;
                let q = e.enu_from_rig;
                let s = if q.w < 0.0 { -1.0 } else { 1.0 };
                d.set_item(
                    "enu_from_rig_wxyz",
                    PyArray1::from_slice(py, &[s * q.w, s * q.i, s * q.j, s * q.k]),
                )?;
                let hpr = e.heading_pitch_roll;
                d.set_item(
                    "heading_pitch_roll_deg",
                    PyArray1::from_slice(
                        py,
                        &[
                            hpr.heading_rad.to_degrees().rem_euclid(360.0),
                            hpr.pitch_rad.to_degrees(),
                            hpr.roll_rad.to_degrees(),
                        ],
                    ),
                )?;
                let cov = Array2::from_shape_fn((6, 6), |(i, j)| e.covariance[(i, j)]);
                d.set_item("covariance", cov.into_pyarray(py))?;
                d.set_item("rms_residual_rad", e.rms_residual_rad)?;
                d.set_item("landmarks", &e.landmarks)?;
                d.set_item("surrogates", &e.surrogates)?;
            }
        }
        Ok(d)
    }

    /// Forgets the motion state: the next frame is re-acquired (mapped landmarks kept).
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// The map's ENU origin `(lat, lon, alt)` (the frame of `position_enu` and the
    /// covariance).
    #[getter]
    fn origin(&self) -> (f64, f64, f64) {
        let g = self.map.frame().origin();
        (g.lat_deg, g.lon_deg, g.alt_m)
    }
}

/// The native module `vgps._vgps`.
#[pymodule]
#[pyo3(name = "_vgps")]
fn vgps_python(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VgpsError", m.py().get_type::<VgpsError>())?;
    m.add_function(wrap_pyfunction!(p3p, m)?)?;
    m.add_function(wrap_pyfunction!(triangulate, m)?)?;
    m.add_function(wrap_pyfunction!(_locate, m)?)?;
    m.add_function(wrap_pyfunction!(_run_cli, m)?)?;
    m.add_class::<Calibration>()?;
    m.add_class::<PyLocalizer>()?;
    Ok(())
}
