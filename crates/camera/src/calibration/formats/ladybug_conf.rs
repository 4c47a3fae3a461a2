//! The Ladybug SDK's own calibration file (`.conf`, `Version "Ladybug 2.0"`).
//!
//! # Layout
//! Whitespace-separated `Key value…` lines; lines whose first non-blank character is `#` are
//! comments; trailing NUL bytes (the SDK writes one) are ignored.
//! - Header: `Version "Ladybug 2.0"` (required, the only version read), `Product`,
//!   `SerialNumber`, `PartID`, `Resolution W H` (required: pixels of each camera's image),
//!   `NumCameras n` (required), `SurfaceSplineFunction`, `SurfaceParameter r` (the radius of
//!   the stitching sphere, metres), `MaxBlendingWidth`, `Date`.
//! - Per camera, `BeginCamera … EndCamera`: `Id`, `focalLength fx fy` (normalised: pixels
//!   divided by `W` and `H`), `RectifiedSpline u v` and `DistortedSpline u v` (warp ids),
//!   `CamToLadybugEulerZYX Rx Ry Rz Tx Ty Tz` (radians, metres), the pairs `Center`,
//!   `TopLeft`, `BottomLeft`, `TopRight`, `BottomRight` (`X Y Z u v`: a head-frame point on
//!   the stitching sphere, metres, and its normalised rectified position), `3DSurfaceSpline
//!   x y z` (warp ids), and the photometric keys `falloffCorrection`, `falloffRed`,
//!   `falloffGreen`, `falloffBlue`, `crosstalk` (kept out of the geometry).
//! - Per warp, `BeginWarp … EndWarp`: `Id`, `NumberKnots n`, `KnotsX …`, `KnotsY …`,
//!   `NumberCoefs nx ny`, `Coefs` followed by `nx · ny` numbers over any number of lines:
//!   a clamped cubic tensor-product B-spline ([`BSplineSurface`]).
//!
//! # Conventions (worked out from the file; see `docs/calibration-formats.md`)
//! - Normalised image coordinates: `(x, y) = ((u + ½) / W, (v + ½) / H)` with `(u, v)` the
//!   pixel (integer = centre) of a `W × H` image, `W, H` from `Resolution` (the corner pairs
//!   sit at `½ / W` and `1 − ½ / W`: the centres of the corner pixels). The focal lengths in
//!   pixels are `fx · W` and `fy · H` (equal for the real file: 453.23 px).
//! - The rectified image is a pinhole: `x = cx + fx X/Z`, `y = cy + fy Y/Z` with
//!   `(X, Y, Z)` the point in the camera frame (x right, y down, z forward);
//!   `head_from_camera = (Rz(Rz)·Ry(Ry)·Rx(Rx), (Tx, Ty, Tz))` (ZYX Euler, as named); the
//!   principal point `(cx, cy)` is the `Center` pair's 2-D position (the stored
//!   `Center` point lies on the optical axis). The four corner pairs are then independent
//!   checks: the real file reproduces them within 0.005 px.
//! - `DistortedSpline` maps raw (distorted) normalised → rectified normalised;
//!   `RectifiedSpline` maps rectified → raw. `3DSurfaceSpline` maps raw normalised → the
//!   head-frame point on the stitching sphere. Coefficient `(i, j)` (i along x) is at index
//!   `i · ny + j`. Evidence: projecting `3DSurfaceSpline(p)` by the pinhole lands on
//!   `DistortedSpline(p)` within 0.008 px over every camera; with the other direction or
//!   the other coefficient order the discrepancy is hundreds of pixels.
//! - The head frame (camera 0 along +x, the top camera along +z, right-handed) is vgps's rig
//!   frame (x forward, y left, z up), and the file's camera frame is vgps's camera frame.
//!   The image axes are the sensor's: `u` runs along `Resolution`'s first number (2464 for
//!   a Ladybug5+, which points *down* in the world for a side camera) and `v` along the
//!   second (pointing *left*). The SDK's upright (portrait) images are these rotated by
//!   90°: upright `(col, row) = (H − 1 − v, u)`.

use super::LoadError;
use crate::calibration::bspline::{BSplineSurface, BSplineSurfaceParams};
use crate::calibration::formats::ladybug_ini::head_from_camera_rotation;
use crate::calibration::{
    Camera, CameraModel, Rig, RigCamera, SplinePinhole, SplinePinholeParams, SplineWarp,
    TabulatedPinhole, TabulatedPinholeParams,
};
use nalgebra::{IsometryMatrix3, Point3, Translation3, Vector2, Vector3};
use std::collections::BTreeMap;
use std::path::Path;

/// The only `Version` read.
pub const CONF_VERSION: &str = "Ladybug 2.0";

/// Most cameras accepted in a file (`NumCameras`).
pub const MAX_CONF_CAMERAS: usize = 64;

/// The names of the stored 3-D ↔ 2-D pairs of a camera, in file order.
pub const PAIR_NAMES: [&str; 5] = ["Center", "TopLeft", "BottomLeft", "TopRight", "BottomRight"];

/// One stored 3-D ↔ 2-D pair of a camera.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredPair {
    /// `Center`, `TopLeft`, …
    pub name: &'static str,
    /// Line of the pair in the file (1-based).
    pub line: usize,
    /// The head-frame point (metres).
    pub point: Vector3<f64>,
    /// Its normalised rectified position `(x, y)`.
    pub normalised: Vector2<f64>,
}

/// One `BeginCamera … EndCamera` block.
#[derive(Clone, Debug, PartialEq)]
pub struct ConfCamera {
    /// `Id`.
    pub id: usize,
    /// Line of `BeginCamera`.
    pub line: usize,
    /// `focalLength fx fy` (normalised).
    pub focal_length: [f64; 2],
    /// `RectifiedSpline` warp ids (rectified → raw, u and v).
    pub rectified_spline: [u32; 2],
    /// `DistortedSpline` warp ids (raw → rectified, u and v).
    pub distorted_spline: [u32; 2],
    /// `CamToLadybugEulerZYX Rx Ry Rz Tx Ty Tz` (radians, metres).
    pub cam_to_ladybug: [f64; 6],
    /// The stored pairs (in file order).
    pub pairs: Vec<StoredPair>,
    /// `3DSurfaceSpline` warp ids (raw → sphere point x, y, z), when given.
    pub surface_spline: Option<[u32; 3]>,
}

/// A parsed `.conf` file.
#[derive(Clone, Debug, PartialEq)]
pub struct LadybugConf {
    /// `Version` (always [`CONF_VERSION`]).
    pub version: String,
    /// `Product`.
    pub product: Option<String>,
    /// `SerialNumber`.
    pub serial_number: Option<String>,
    /// `PartID` (the camera model, e.g. `LD5P-U3-51S5C-B`).
    pub part_id: Option<String>,
    /// `Date`.
    pub date: Option<String>,
    /// `Resolution W H` (pixels).
    pub resolution: (u32, u32),
    /// `SurfaceParameter`: the stitching sphere's radius (metres).
    pub surface_parameter: Option<f64>,
    /// The cameras, by `Id` (0 … `NumCameras − 1`).
    pub cameras: Vec<ConfCamera>,
    /// The warps by `Id`.
    pub warps: BTreeMap<u32, BSplineSurface>,
    /// Lines accepted with a warning (unknown keys).
    pub warnings: Vec<String>,
}

/// The lines of a block being read: `(line number, key, the rest's tokens)`.
struct Cursor<'a> {
    lines: Vec<(usize, &'a str)>,
    next: usize,
}

impl<'a> Cursor<'a> {
    fn new(text: &'a str) -> Self {
        let lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                (
                    i + 1,
                    l.trim_matches(|c: char| c.is_whitespace() || c == '\0'),
                )
            })
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
            .collect();
        Self { lines, next: 0 }
    }

    fn next_line(&mut self) -> Option<(usize, &'a str)> {
        let l = self.lines.get(self.next).copied();
        self.next += 1;
        l
    }

    fn peek(&self) -> Option<(usize, &'a str)> {
        self.lines.get(self.next).copied()
    }
}

/// Splits a line into its key and the rest.
fn key_rest(line: &str) -> (&str, &str) {
    match line.split_once(char::is_whitespace) {
        Some((k, r)) => (k, r.trim()),
        None => (line, ""),
    }
}

struct Ctx<'p> {
    path: &'p Path,
}

impl Ctx<'_> {
    fn err(&self, line: usize, field: &str, reason: impl Into<String>) -> LoadError {
        LoadError::invalid(self.path, format!("line {line}, field {field}"), reason)
    }

    fn floats(&self, line: usize, field: &str, rest: &str) -> Result<Vec<f64>, LoadError> {
        rest.split_whitespace()
            .enumerate()
            .map(|(k, t)| {
                let v: f64 = t.parse().map_err(|_| {
                    self.err(
                        line,
                        field,
                        format!("value {} `{t}` is not a number", k + 1),
                    )
                })?;
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(self.err(line, field, format!("value {} `{t}` is not finite", k + 1)))
                }
            })
            .collect()
    }

    fn floats_n<const N: usize>(
        &self,
        line: usize,
        field: &str,
        rest: &str,
    ) -> Result<[f64; N], LoadError> {
        let v = self.floats(line, field, rest)?;
        v.as_slice()
            .try_into()
            .map_err(|_| self.err(line, field, format!("{} values, expected {N}", v.len())))
    }

    fn ints_n<const N: usize>(
        &self,
        line: usize,
        field: &str,
        rest: &str,
    ) -> Result<[u32; N], LoadError> {
        let v: Vec<u32> = rest
            .split_whitespace()
            .map(|t| {
                t.parse().map_err(|_| {
                    self.err(line, field, format!("`{t}` is not a non-negative integer"))
                })
            })
            .collect::<Result<_, _>>()?;
        v.as_slice()
            .try_into()
            .map_err(|_| self.err(line, field, format!("{} values, expected {N}", v.len())))
    }
}

/// Parses the text of a `.conf` file; `path` is quoted in errors.
///
/// Long (about 175 lines) for a reason: one loop over the file's blocks (header keys,
/// camera blocks, warp blocks), then the cross-checks between blocks; the blocks' own
/// readers (`parse_warp`, the camera block) are separate functions.
///
/// # Errors
/// [`LoadError::Invalid`] naming the line and the field: an unknown `Version`, a missing
/// required field, a value that is not a (finite) number, a block without its `End…`
/// line, decreasing knots, a coefficient count that is not `nx · ny`, a duplicated warp id
/// or a camera naming a warp id that the file does not define.
pub fn parse(text: &str, path: &Path) -> Result<LadybugConf, LoadError> {
    let ctx = Ctx { path };
    let mut cur = Cursor::new(text);
    let mut version: Option<(usize, String)> = None;
    let mut product = None;
    let mut serial_number = None;
    let mut part_id = None;
    let mut date = None;
    let mut resolution: Option<(usize, (u32, u32))> = None;
    let mut num_cameras: Option<(usize, usize)> = None;
    let mut surface_parameter = None;
    let mut warnings = Vec::new();
    let mut cameras: Vec<ConfCamera> = Vec::new();
    let mut warps: BTreeMap<u32, (usize, BSplineSurface)> = BTreeMap::new();
    let mut first = true;
    while let Some((n, line)) = cur.next_line() {
        let (key, rest) = key_rest(line);
        if first {
            first = false;
            if key != "Version" {
                return Err(ctx.err(
                    n,
                    "Version",
                    "the file must begin with `Version \"Ladybug 2.0\"`",
                ));
            }
        }
        match key {
            "Version" => {
                let v = rest.trim_matches('"');
                if v != CONF_VERSION {
                    return Err(ctx.err(
                        n,
                        "Version",
                        format!("unknown version `{rest}` (only \"{CONF_VERSION}\" is read)"),
                    ));
                }
                if version.is_some() {
                    return Err(ctx.err(n, "Version", "repeated"));
                }
                version = Some((n, v.to_string()));
            }
            "Product" => product = Some(rest.to_string()),
            "SerialNumber" => serial_number = Some(rest.to_string()),
            "PartID" => part_id = Some(rest.to_string()),
            "Date" => date = Some(rest.to_string()),
            "SurfaceSplineFunction" | "MaxBlendingWidth" => {}
            "Resolution" => {
                let [w, h] = ctx.ints_n::<2>(n, "Resolution", rest)?;
                let max = crate::calibration::MAX_IMAGE_SIDE_PX;
                if w == 0 || h == 0 || w > max || h > max {
                    return Err(ctx.err(
                        n,
                        "Resolution",
                        format!("{w}×{h} is not two positive integers ≤ {max}"),
                    ));
                }
                resolution = Some((n, (w, h)));
            }
            "NumCameras" => {
                let [c] = ctx.ints_n::<1>(n, "NumCameras", rest)?;
                let c = c as usize;
                if c == 0 || c > MAX_CONF_CAMERAS {
                    return Err(ctx.err(
                        n,
                        "NumCameras",
                        format!("{c} cameras (expected 1 … {MAX_CONF_CAMERAS})"),
                    ));
                }
                num_cameras = Some((n, c));
            }
            "SurfaceParameter" => {
                let [r] = ctx.floats_n::<1>(n, "SurfaceParameter", rest)?;
                if !(r > 0.0) {
                    return Err(ctx.err(n, "SurfaceParameter", format!("{r} must be > 0")));
                }
                surface_parameter = Some(r);
            }
            "BeginCamera" => {
                if cameras.len() >= MAX_CONF_CAMERAS {
                    return Err(ctx.err(
                        n,
                        "BeginCamera",
                        format!("more than {MAX_CONF_CAMERAS} cameras"),
                    ));
                }
                cameras.push(parse_camera(&ctx, &mut cur, n, &mut warnings)?);
            }
            "BeginWarp" => {
                let (id, id_line, warp) = parse_warp(&ctx, &mut cur, n)?;
                if let Some((first_line, _)) = warps.get(&id) {
                    return Err(ctx.err(
                        id_line,
                        "Id",
                        format!("warp id {id} is repeated (first defined at line {first_line})"),
                    ));
                }
                warps.insert(id, (id_line, warp));
            }
            "EndCamera" | "EndWarp" => {
                return Err(ctx.err(n, key, "without its Begin line"));
            }
            _ => warnings.push(format!("line {n}: unknown key `{key}` ignored")),
        }
    }
    let Some((_, version)) = version else {
        return Err(ctx.err(1, "Version", "missing (empty file)"));
    };
    let end = cur.lines.last().map_or(1, |l| l.0);
    let (_, resolution) =
        resolution.ok_or_else(|| ctx.err(end, "Resolution", "missing header field"))?;
    let (nc_line, num_cameras) =
        num_cameras.ok_or_else(|| ctx.err(end, "NumCameras", "missing header field"))?;
    if cameras.len() != num_cameras {
        return Err(ctx.err(
            nc_line,
            "NumCameras",
            format!(
                "{num_cameras} cameras announced, {} blocks found",
                cameras.len()
            ),
        ));
    }
    let mut by_id: Vec<Option<ConfCamera>> = vec![None; num_cameras];
    for c in cameras {
        let Some(slot) = by_id.get_mut(c.id) else {
            return Err(ctx.err(
                c.line,
                "Id",
                format!("camera id {} is not below NumCameras = {num_cameras}", c.id),
            ));
        };
        if slot.is_some() {
            return Err(ctx.err(c.line, "Id", format!("camera id {} is repeated", c.id)));
        }
        for (field, ids) in [
            ("RectifiedSpline", c.rectified_spline.to_vec()),
            ("DistortedSpline", c.distorted_spline.to_vec()),
            (
                "3DSurfaceSpline",
                c.surface_spline.map(|s| s.to_vec()).unwrap_or_default(),
            ),
        ] {
            for id in ids {
                if !warps.contains_key(&id) {
                    return Err(ctx.err(
                        c.line,
                        field,
                        format!("camera {}: warp id {id} is not defined in the file", c.id),
                    ));
                }
            }
        }
        *slot = Some(c);
    }
    let cameras: Vec<ConfCamera> = by_id.into_iter().flatten().collect();
    let conf = LadybugConf {
        version,
        product,
        serial_number,
        part_id,
        date,
        resolution,
        surface_parameter,
        cameras,
        warps: warps.into_iter().map(|(k, (_, w))| (k, w)).collect(),
        warnings,
    };
    // Build every model now so that an invalid camera is an error naming its block.
    for c in &conf.cameras {
        conf.raw_model(c)
            .map_err(|e| ctx.err(c.line, "BeginCamera", format!("camera {}: {e}", c.id)))?;
    }
    Ok(conf)
}

fn parse_camera(
    ctx: &Ctx<'_>,
    cur: &mut Cursor<'_>,
    begin: usize,
    warnings: &mut Vec<String>,
) -> Result<ConfCamera, LoadError> {
    let mut id = None;
    let mut focal = None;
    let mut rect = None;
    let mut dist = None;
    let mut euler = None;
    let mut surface = None;
    let mut pairs: Vec<StoredPair> = Vec::new();
    loop {
        let Some((n, line)) = cur.next_line() else {
            return Err(ctx.err(
                begin,
                "BeginCamera",
                "block not closed: the file ends before EndCamera",
            ));
        };
        let (key, rest) = key_rest(line);
        match key {
            "EndCamera" => break,
            "BeginCamera" | "BeginWarp" | "EndWarp" => {
                return Err(ctx.err(
                    n,
                    key,
                    format!("inside the camera block of line {begin} (EndCamera missing)"),
                ));
            }
            "Id" => {
                let [v] = ctx.ints_n::<1>(n, "Id", rest)?;
                id = Some(v as usize);
            }
            "focalLength" => {
                let v = ctx.floats_n::<2>(n, key, rest)?;
                if !(v[0] > 0.0 && v[1] > 0.0) {
                    return Err(ctx.err(n, key, format!("{v:?} must be > 0")));
                }
                focal = Some(v);
            }
            "RectifiedSpline" => rect = Some(ctx.ints_n::<2>(n, key, rest)?),
            "DistortedSpline" => dist = Some(ctx.ints_n::<2>(n, key, rest)?),
            "3DSurfaceSpline" => surface = Some(ctx.ints_n::<3>(n, key, rest)?),
            "CamToLadybugEulerZYX" => euler = Some(ctx.floats_n::<6>(n, key, rest)?),
            "falloffCorrection" | "falloffRed" | "falloffGreen" | "falloffBlue" | "crosstalk" => {}
            _ => {
                if let Some(name) = PAIR_NAMES.iter().find(|p| **p == key) {
                    let v = ctx.floats_n::<5>(n, key, rest)?;
                    if pairs.iter().any(|p| p.name == *name) {
                        return Err(ctx.err(n, key, "repeated"));
                    }
                    pairs.push(StoredPair {
                        name,
                        line: n,
                        point: Vector3::new(v[0], v[1], v[2]),
                        normalised: Vector2::new(v[3], v[4]),
                    });
                } else {
                    warnings.push(format!("line {n}: unknown camera key `{key}` ignored"));
                }
            }
        }
    }
    let missing = |field: &str| ctx.err(begin, field, "missing in the camera block");
    let pairs_ok = pairs.iter().any(|p| p.name == "Center");
    if !pairs_ok {
        return Err(missing("Center"));
    }
    Ok(ConfCamera {
        id: id.ok_or_else(|| missing("Id"))?,
        line: begin,
        focal_length: focal.ok_or_else(|| missing("focalLength"))?,
        rectified_spline: rect.ok_or_else(|| missing("RectifiedSpline"))?,
        distorted_spline: dist.ok_or_else(|| missing("DistortedSpline"))?,
        cam_to_ladybug: euler.ok_or_else(|| missing("CamToLadybugEulerZYX"))?,
        pairs,
        surface_spline: surface,
    })
}

/// Returns `(id, line of Id, spline)`.
fn parse_warp(
    ctx: &Ctx<'_>,
    cur: &mut Cursor<'_>,
    begin: usize,
) -> Result<(u32, usize, BSplineSurface), LoadError> {
    let mut id = None;
    let mut number_knots = None;
    let mut knots_x: Option<(usize, Vec<f64>)> = None;
    let mut knots_y: Option<(usize, Vec<f64>)> = None;
    let mut number_coefs: Option<(usize, [u32; 2])> = None;
    let mut coefs: Option<(usize, Vec<f64>)> = None;
    loop {
        let Some((n, line)) = cur.next_line() else {
            return Err(ctx.err(
                begin,
                "BeginWarp",
                "block not closed: the file ends before EndWarp",
            ));
        };
        let (key, rest) = key_rest(line);
        match key {
            "EndWarp" => break,
            "BeginCamera" | "BeginWarp" | "EndCamera" => {
                return Err(ctx.err(
                    n,
                    key,
                    format!("inside the warp block of line {begin} (EndWarp missing)"),
                ));
            }
            "Id" => id = Some((n, ctx.ints_n::<1>(n, "Id", rest)?[0])),
            "NumberKnots" => number_knots = Some((n, ctx.ints_n::<1>(n, key, rest)?[0])),
            "KnotsX" => knots_x = Some((n, ctx.floats(n, key, rest)?)),
            "KnotsY" => knots_y = Some((n, ctx.floats(n, key, rest)?)),
            "NumberCoefs" => number_coefs = Some((n, ctx.ints_n::<2>(n, key, rest)?)),
            "Coefs" => {
                let mut values = ctx.floats(n, "Coefs", rest)?;
                // The numbers follow on the next lines, up to the next key.
                while let Some((m, l)) = cur.peek() {
                    // Every line up to the next key of the block holds coefficients (a
                    // word such as `nan` there is a bad coefficient, not a key).
                    let (first_token, _) = key_rest(l);
                    let is_key = matches!(
                        first_token,
                        "Id" | "NumberKnots" | "KnotsX" | "KnotsY" | "NumberCoefs" | "Coefs"
                    ) || first_token.starts_with("Begin")
                        || first_token.starts_with("End");
                    if is_key {
                        break;
                    }
                    values.extend(ctx.floats(m, "Coefs", l)?);
                    cur.next += 1;
                }
                coefs = Some((n, values));
            }
            _ => {
                return Err(ctx.err(
                    n,
                    key,
                    format!("unknown key in the warp block of line {begin}"),
                ));
            }
        }
    }
    let missing = |field: &str| ctx.err(begin, field, "missing in the warp block");
    let (id_line, id) = id.ok_or_else(|| missing("Id"))?;
    let (kx_line, knots_x) = knots_x.ok_or_else(|| missing("KnotsX"))?;
    let (ky_line, knots_y) = knots_y.ok_or_else(|| missing("KnotsY"))?;
    let (nc_line, [nx, ny]) = number_coefs.ok_or_else(|| missing("NumberCoefs"))?;
    let (c_line, coefs) = coefs.ok_or_else(|| missing("Coefs"))?;
    if let Some((nk_line, nk)) = number_knots {
        for (name, line, knots) in [("KnotsX", kx_line, &knots_x), ("KnotsY", ky_line, &knots_y)] {
            if knots.len() != nk as usize {
                return Err(ctx.err(
                    line,
                    name,
                    format!(
                        "{} knots, but NumberKnots (line {nk_line}) is {nk}",
                        knots.len()
                    ),
                ));
            }
        }
    }
    for (name, line, knots, count) in [
        ("KnotsX", kx_line, &knots_x, nx),
        ("KnotsY", ky_line, &knots_y, ny),
    ] {
        if knots.len() != count as usize + 4 {
            return Err(ctx.err(
                line,
                name,
                format!(
                    "{} knots, but a cubic spline of NumberCoefs {count} (line {nc_line}) needs {}",
                    knots.len(),
                    u64::from(count) + 4
                ),
            ));
        }
        if let Some(k) = (1..knots.len()).find(|&k| knots[k] < knots[k - 1]) {
            return Err(ctx.err(
                line,
                name,
                format!(
                    "knot {} = {} is smaller than knot {} = {} (knots must not decrease)",
                    k,
                    knots[k],
                    k - 1,
                    knots[k - 1]
                ),
            ));
        }
    }
    let expected = nx as usize * ny as usize;
    if coefs.len() != expected {
        return Err(ctx.err(
            c_line,
            "Coefs",
            format!(
                "{} coefficients, but NumberCoefs {nx} {ny} (line {nc_line}) needs {expected}",
                coefs.len()
            ),
        ));
    }
    let spline = BSplineSurface::new(BSplineSurfaceParams {
        knots_x,
        knots_y,
        coefs,
    })
    .map_err(|e| ctx.err(begin, "BeginWarp", format!("warp {id}: {e}")))?;
    Ok((id, id_line, spline))
}

/// Reads a `.conf` file (see [`parse`]).
///
/// # Errors
/// As [`parse`], [`LoadError::Io`], and [`LoadError::Invalid`] for a file that is not text.
pub fn read_conf(path: &Path) -> Result<LadybugConf, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, &e))?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        LoadError::invalid(path, format!("line {line}"), "not UTF-8 text")
    })?;
    parse(text, path)
}

/// Reads a `.conf` file into a rig of its raw cameras ([`LadybugConf::raw_rig`]).
///
/// # Errors
/// As [`read_conf`].
pub fn read(path: &Path) -> Result<Rig, LoadError> {
    let conf = read_conf(path)?;
    conf.raw_rig()
        .map_err(|e| LoadError::invalid(path, "rig", e.to_string()))
}

/// The residual of one stored pair: `(name, line, rectified pixel by vgps − stored pixel)`.
pub type PairResidual = (&'static str, usize, Vector2<f64>);

impl LadybugConf {
    /// `head_from_camera` = `rig_from_camera` of a camera (see the module documentation).
    pub fn rig_from_camera(&self, c: &ConfCamera) -> IsometryMatrix3<f64> {
        let e = c.cam_to_ladybug;
        IsometryMatrix3::from_parts(
            Translation3::new(e[3], e[4], e[5]),
            head_from_camera_rotation(e[0], e[1], e[2]),
        )
    }

    /// The rectified pinhole of a camera in pixels: `(fx, fy, cx, cy)`.
    pub fn rectified_intrinsics(&self, c: &ConfCamera) -> [f64; 4] {
        let (w, h) = (f64::from(self.resolution.0), f64::from(self.resolution.1));
        let centre = c
            .pairs
            .iter()
            .find(|p| p.name == "Center")
            .map_or(Vector2::new(0.5, 0.5), |p| p.normalised);
        [
            c.focal_length[0] * w,
            c.focal_length[1] * h,
            centre.x * w - 0.5,
            centre.y * h - 0.5,
        ]
    }

    /// The rectified image of a camera as a pinhole bounded to `Resolution`.
    ///
    /// # Errors
    /// When the parameters are invalid.
    pub fn rectified_model(
        &self,
        c: &ConfCamera,
    ) -> Result<TabulatedPinhole, crate::calibration::CalibrationError> {
        let [fx, fy, cx, cy] = self.rectified_intrinsics(c);
        TabulatedPinhole::new(TabulatedPinholeParams {
            width: Some(self.resolution.0),
            height: Some(self.resolution.1),
            fx,
            fy,
            skew: 0.0,
            cx,
            cy,
            raw_to_undistorted: None,
            undistorted_to_raw: None,
        })
    }

    fn warp(&self, ids: [u32; 2]) -> Result<SplineWarp, crate::calibration::CalibrationError> {
        let get = |id: u32| {
            self.warps.get(&id).cloned().ok_or_else(|| {
                crate::calibration::CalibrationError::InvalidParameters {
                    model: "spline_pinhole",
                    reason: format!("warp id {id} is not defined"),
                }
            })
        };
        Ok(SplineWarp {
            u: get(ids[0])?,
            v: get(ids[1])?,
        })
    }

    /// The raw (distorted) image of a camera: a [`SplinePinhole`].
    ///
    /// # Errors
    /// When the parameters are invalid.
    pub fn raw_model(
        &self,
        c: &ConfCamera,
    ) -> Result<SplinePinhole, crate::calibration::CalibrationError> {
        let [fx, fy, cx, cy] = self.rectified_intrinsics(c);
        SplinePinhole::new(SplinePinholeParams {
            width: self.resolution.0,
            height: self.resolution.1,
            fx,
            fy,
            cx,
            cy,
            raw_to_rectified: self.warp(c.distorted_spline)?,
            rectified_to_raw: self.warp(c.rectified_spline)?,
        })
    }

    /// The rig of the raw cameras (what the sensors record).
    ///
    /// # Errors
    /// When a camera's parameters are invalid.
    pub fn raw_rig(&self) -> Result<Rig, crate::calibration::CalibrationError> {
        let cameras = self
            .cameras
            .iter()
            .map(|c| {
                Ok(RigCamera {
                    model: Camera::SplinePinhole(self.raw_model(c)?),
                    rig_from_camera: self.rig_from_camera(c),
                })
            })
            .collect::<Result<Vec<_>, crate::calibration::CalibrationError>>()?;
        Rig::new(cameras)
    }

    /// The rig of the rectified cameras (the SDK's rectified images, in the sensor's
    /// orientation).
    ///
    /// # Errors
    /// When a camera's parameters are invalid.
    pub fn rectified_rig(&self) -> Result<Rig, crate::calibration::CalibrationError> {
        let cameras = self
            .cameras
            .iter()
            .map(|c| {
                Ok(RigCamera {
                    model: Camera::TabulatedPinhole(self.rectified_model(c)?),
                    rig_from_camera: self.rig_from_camera(c),
                })
            })
            .collect::<Result<Vec<_>, crate::calibration::CalibrationError>>()?;
        Rig::new(cameras)
    }

    /// Per stored pair of a camera: vgps's rectified pixel of the stored 3-D point minus the
    /// stored 2-D position in pixels (`None` entries are pairs behind the camera).
    pub fn pair_residuals(&self, c: &ConfCamera) -> Vec<(PairResidual, bool)> {
        let (w, h) = (f64::from(self.resolution.0), f64::from(self.resolution.1));
        let iso = self.rig_from_camera(c);
        let Ok(model) = self.rectified_model(c) else {
            return Vec::new();
        };
        c.pairs
            .iter()
            .map(|p| {
                let local = iso.inverse_transform_point(&Point3::from(p.point)).coords;
                let stored = Vector2::new(p.normalised.x * w - 0.5, p.normalised.y * h - 0.5);
                // The stored corners are the corner pixels' centres, inside the image.
                match model.try_pixel(&local) {
                    Some(px) => ((p.name, p.line, px - stored), true),
                    None => ((p.name, p.line, Vector2::new(f64::NAN, f64::NAN)), false),
                }
            })
            .collect()
    }

    /// The largest distance (pixels) between the raw point that the rectified → raw warp
    /// gives and the one that inverts the raw → rectified warp, over an `n × n` grid of the
    /// rectified image restricted to points whose raw pixel is inside the image: how
    /// consistent the two fitted warps of a camera are.
    pub fn warp_consistency(&self, c: &ConfCamera, n: usize) -> Option<f64> {
        let model = self.raw_model(c).ok()?;
        let (w, h) = (f64::from(self.resolution.0), f64::from(self.resolution.1));
        let n = n.max(2);
        let mut worst: f64 = 0.0;
        for a in 0..n {
            for b in 0..n {
                let q = Vector2::new(
                    -0.5 + w * a as f64 / (n - 1) as f64,
                    -0.5 + h * b as f64 / (n - 1) as f64,
                );
                if let Some(p) = model.unrectify(&q)
                    && model.is_inside(&p)
                {
                    worst = worst.max((model.unrectify_by_warp(&q) - p).norm());
                }
            }
        }
        Some(worst)
    }
}
