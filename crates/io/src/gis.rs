//! Landmark inventories from GIS: GeoJSON points (e.g. an OpenStreetMap
//! `highway=street_lamp` export) and CSV with latitude and longitude only, turned into
//! [`Landmark`]s with ellipsoidal heights.
//!
//! # Heights
//! GIS gives a lamp's 2-D position, often the height of the lamp head above the ground
//! (OSM `height`) and sometimes the ground's elevation above the geoid (OSM `ele`, "above
//! mean sea level"). The ellipsoidal height of the lamp head is
//! `h = H_ground + N(lat, lon) + lamp height`, where `H_ground` is the feature's `ele` (else
//! [`GisOptions::ground_height_m`]) and `N` the EGM96 geoid height (the `egm96` crate,
//! EGM96 spherical harmonics to degree and order 360 with NGA's correction term: the geoid
//! model itself, not a grid; it agrees with NGA's reference values to a centimetre, and
//! EGM96 represents the true geoid to about ±0.5–1 m, see `docs/geodesy.md`). With
//! [`GroundReference::Ellipsoid`] the ground heights are already ellipsoidal and `N` is not
//! added.
//!
//! A lamp without a height above ground gets [`GisOptions::default_lamp_height_m`] and the
//! larger σ [`GisOptions::default_height_sigma_m`]; the count is reported once
//! ([`GisRead::default_height`]), not per lamp.
//!
//! # Coordinates
//! GeoJSON (RFC 7946) positions are WGS84 longitude, latitude. A `crs` member naming
//! anything but WGS84 (`EPSG:4326`, `OGC:CRS84`) or a position outside ±180°/±90° (a
//! projected CRS such as UTM or Web Mercator) refuses the file, naming the feature. Features
//! that are not points (a lamp row drawn as a line) are skipped and counted.

use crate::{InputError, Landmark, MAX_ABS_LAT_DEG, MAX_ABS_LON_DEG};
use std::path::Path;

/// How the ground heights (feature `ele`, [`GisOptions::ground_height_m`]) are referenced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroundReference {
    /// Orthometric (above the geoid, "above mean sea level"): EGM96 `N` is added.
    Geoid,
    /// Already ellipsoidal (WGS84).
    Ellipsoid,
}

/// How GIS features become landmarks.
#[derive(Clone, Debug, PartialEq)]
pub struct GisOptions {
    /// The ground height where a feature has no `ele`, metres (in [`GisOptions::reference`]).
    /// `None`: a feature without `ele` is refused.
    pub ground_height_m: Option<f64>,
    /// The reference of the ground heights.
    pub reference: GroundReference,
    /// The lamp-head height above the ground for features without `height`, metres.
    pub default_lamp_height_m: f64,
    /// σ per axis of a landmark whose height is known, metres (features with `sigma_m`
    /// keep theirs).
    pub sigma_m: f64,
    /// σ per axis of a landmark whose height is the default, metres.
    pub default_height_sigma_m: f64,
    /// The class of features without `class` (or OSM `highway`).
    pub default_class: String,
}

impl Default for GisOptions {
    /// Ground heights above the geoid, not given; lamp heads 6 m above the ground when not
    /// given, σ 0.5 m (1.5 m with the default height); class `streetlight`.
    fn default() -> Self {
        Self {
            ground_height_m: None,
            reference: GroundReference::Geoid,
            default_lamp_height_m: 6.0,
            sigma_m: 0.5,
            default_height_sigma_m: 1.5,
            default_class: "streetlight".into(),
        }
    }
}

/// An inventory read: its landmarks and what was amended or skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct GisRead {
    /// The landmarks, in file order.
    pub landmarks: Vec<Landmark>,
    /// Landmarks given the default lamp height (and its larger σ).
    pub default_height: usize,
    /// Features skipped because they are not points.
    pub not_points: usize,
}

impl GisRead {
    /// The one warning about defaulted heights and skipped features, if any.
    pub fn warning(&self, path: &Path, options: &GisOptions) -> Option<String> {
        let mut parts = Vec::new();
        if self.default_height > 0 {
            parts.push(format!(
                "{} of {} lamps have no height above ground: {} m used with σ {} m",
                self.default_height,
                self.landmarks.len(),
                options.default_lamp_height_m,
                options.default_height_sigma_m
            ));
        }
        if self.not_points > 0 {
            parts.push(format!(
                "{} features that are not points skipped",
                self.not_points
            ));
        }
        (!parts.is_empty()).then(|| format!("{}: {}", path.display(), parts.join("; ")))
    }
}

/// The EGM96 geoid height `N` (metres above the WGS84 ellipsoid) at a WGS84 position.
///
/// # Example
/// ```
/// // NGA's EGM96 test point (F477 `outintpt.dat`): 38.6281550° N, 269.7791550° E → −31.628 m.
/// let n = vgps_io::gis::geoid_height_m(38.628155, 269.779155 - 360.0);
/// assert!((n + 31.628).abs() < 0.01, "{n}");
/// ```
pub fn geoid_height_m(lat_deg: f64, lon_deg: f64) -> f64 {
    egm96::egm96_compute_altitude_offset(lat_deg, lon_deg)
}

/// A feature's fields, from GeoJSON properties or CSV columns.
struct Fields {
    id: Option<String>,
    lat: f64,
    lon: f64,
    height: Option<f64>,
    ele: Option<f64>,
    class: Option<String>,
    sigma: Option<f64>,
}

fn landmark(
    path: &Path,
    line: u64,
    what: &str,
    f: Fields,
    options: &GisOptions,
    read: &mut GisRead,
) -> Result<Landmark, InputError> {
    let err = |field: &str, reason: String| InputError::field(path, line, field, reason);
    if f.lat.abs() > MAX_ABS_LAT_DEG || f.lon.abs() > MAX_ABS_LON_DEG {
        return Err(err(
            "coordinates",
            format!(
                "{what}: ({}, {}) is not WGS84 longitude, latitude: a projected CRS? \
                 (reproject to EPSG:4326 first, e.g. `ogr2ogr -t_srs EPSG:4326`)",
                f.lon, f.lat
            ),
        ));
    }
    let ground = f.ele.or(options.ground_height_m).ok_or_else(|| {
        err(
            "ele",
            format!("{what}: no ground height (`ele`) and no default ground height given"),
        )
    })?;
    let (lamp, default_sigma) = match f.height {
        Some(h) if h >= 0.0 => (h, options.sigma_m),
        Some(h) => return Err(err("height", format!("{what}: height {h} is negative"))),
        None => {
            read.default_height += 1;
            (
                options.default_lamp_height_m,
                options.default_height_sigma_m,
            )
        }
    };
    let n = match options.reference {
        GroundReference::Geoid => geoid_height_m(f.lat, f.lon),
        GroundReference::Ellipsoid => 0.0,
    };
    let alt_m = ground + n + lamp;
    if !alt_m.is_finite() {
        return Err(err("height", format!("{what}: height is not finite")));
    }
    let sigma = match f.sigma {
        Some(s) if s >= 0.0 => s.max(if f.height.is_none() { default_sigma } else { s }),
        Some(s) => return Err(err("sigma_m", format!("{what}: {s} is negative"))),
        None => default_sigma,
    };
    Ok(Landmark {
        id: f.id.unwrap_or_else(|| format!("lamp{line}")),
        lat_deg: f.lat,
        lon_deg: f.lon,
        alt_m,
        sigma_m: Some(sigma),
        class: Some(f.class.unwrap_or_else(|| options.default_class.clone())),
        line,
    })
}

/// A number from a GeoJSON property: a JSON number or a string such as OSM's `"8"` or
/// `"8 m"`.
pub(crate) fn number(value: Option<&serde_json::Value>) -> Result<Option<f64>, String> {
    let parsed = match value {
        None | Some(serde_json::Value::Null) => return Ok(None),
        Some(serde_json::Value::Number(n)) => n.as_f64(),
        Some(serde_json::Value::String(s)) => {
            s.trim().trim_end_matches('m').trim().parse::<f64>().ok()
        }
        Some(_) => None,
    };
    match parsed {
        Some(x) if x.is_finite() => Ok(Some(x)),
        _ => Err(format!(
            "`{}` is not a number",
            value.map_or(String::new(), |v| v.to_string())
        )),
    }
}

/// CRS names that are WGS84 longitude, latitude.
pub(crate) fn is_wgs84(name: &str) -> bool {
    let n = name.to_ascii_uppercase();
    n.ends_with("CRS84") || n.ends_with("4326") || n.ends_with("CRS:84")
}

/// The features of a GeoJSON text (a `FeatureCollection`, or one `Feature`) in WGS84: the
/// parsed root, whose `features` the caller reads with [`geojson_features`]. Errors name the
/// file and the field: not JSON, a `crs` that is not WGS84.
pub(crate) fn parse_wgs84_geojson(
    path: &Path,
    text: &str,
) -> Result<serde_json::Value, InputError> {
    let err = |field: &str, reason: String| InputError::field(path, 1, field, reason);
    let root: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| InputError::field(path, e.line() as u64, "json", e.to_string()))?;
    if let Some(crs) = root.get("crs") {
        let name = crs
            .pointer("/properties/name")
            .and_then(|v| v.as_str())
            .unwrap_or("");
        if !is_wgs84(name) {
            return Err(err(
                "crs",
                format!(
                    "the coordinates are in `{}`, not WGS84 longitude, latitude: reproject to \
                     EPSG:4326 first (e.g. `ogr2ogr -t_srs EPSG:4326`)",
                    if name.is_empty() {
                        crs.to_string()
                    } else {
                        name.to_string()
                    }
                ),
            ));
        }
    }
    Ok(root)
}

/// The features of a GeoJSON root parsed by [`parse_wgs84_geojson`]; errors name `path`.
pub(crate) fn geojson_features<'a>(
    path: &Path,
    root: &'a serde_json::Value,
) -> Result<Vec<&'a serde_json::Value>, InputError> {
    let err = |field: &str, reason: String| InputError::field(path, 1, field, reason);
    Ok(match root.get("type").and_then(|t| t.as_str()) {
        Some("FeatureCollection") => root
            .get("features")
            .and_then(|f| f.as_array())
            .ok_or_else(|| err("features", "missing or not an array".into()))?
            .iter()
            .collect(),
        Some("Feature") => vec![root],
        other => {
            return Err(err(
                "type",
                format!("{other:?} is not a FeatureCollection or a Feature"),
            ));
        }
    })
}

/// Reads a GeoJSON `FeatureCollection` (or a single `Feature`) of points.
///
/// # Errors
/// [`InputError`] naming the file and the feature (`feature k`, 0-based, and its id): not
/// JSON, a `crs` that is not WGS84, a position outside ±180°/±90°, a feature without a
/// ground height when no default is given, a non-number `height`/`ele`/`sigma_m`.
/// (The line given is 1, GeoJSON has no rows; the feature is named in the message.)
pub fn landmarks_from_geojson(
    path: &Path,
    text: &str,
    options: &GisOptions,
) -> Result<GisRead, InputError> {
    let err = |field: &str, reason: String| InputError::field(path, 1, field, reason);
    let root = parse_wgs84_geojson(path, text)?;
    let features = geojson_features(path, &root)?;
    let mut read = GisRead {
        landmarks: Vec::new(),
        default_height: 0,
        not_points: 0,
    };
    let mut seen = std::collections::HashMap::new();
    for (k, feature) in features.iter().enumerate() {
        let props = feature.get("properties").and_then(|p| p.as_object());
        let prop = |name: &str| props.and_then(|p| p.get(name));
        let id = feature
            .get("id")
            .or_else(|| prop("@id"))
            .or_else(|| prop("id"))
            .map(|v| v.as_str().map_or_else(|| v.to_string(), str::to_string));
        let what = match &id {
            Some(id) => format!("feature {k} (id {id})"),
            None => format!("feature {k}"),
        };
        let geometry = feature.get("geometry");
        if geometry
            .and_then(|g| g.get("type"))
            .and_then(|t| t.as_str())
            != Some("Point")
        {
            read.not_points += 1;
            continue;
        }
        let coords = geometry
            .and_then(|g| g.get("coordinates"))
            .and_then(|c| c.as_array())
            .filter(|c| c.len() >= 2)
            .ok_or_else(|| err("coordinates", format!("{what}: not [lon, lat]")))?;
        let lon = coords[0].as_f64();
        let lat = coords[1].as_f64();
        let (Some(lon), Some(lat)) = (lon, lat) else {
            return Err(err("coordinates", format!("{what}: not numbers")));
        };
        let field = |name: &str| number(prop(name)).map_err(|e| err(name, format!("{what}: {e}")));
        let class = prop("class")
            .or_else(|| prop("highway"))
            .and_then(|v| v.as_str())
            .map(str::to_string);
        let fields = Fields {
            id: id.clone(),
            lat,
            lon,
            height: field("height")?,
            ele: field("ele")?,
            class,
            sigma: field("sigma_m")?,
        };
        let l = landmark(path, 1, &what, fields, options, &mut read)?;
        let l = Landmark {
            id: id.unwrap_or_else(|| format!("lamp{k}")),
            line: k as u64,
            ..l
        };
        if let Some(first) = seen.insert(l.id.clone(), k) {
            return Err(err(
                "id",
                format!("{what}: duplicate id (first feature {first})"),
            ));
        }
        read.landmarks.push(l);
    }
    Ok(read)
}

/// Reads a CSV inventory: `lat`/`latitude`, `lon`/`longitude` and optional `id`, `height`
/// (lamp above ground), `ele` (ground), `class`, `sigma_m`; other columns are ignored.
///
/// # Errors
/// [`InputError`] naming the file, line and field: a missing column, a non-number, a
/// position out of range, a row without ground height when no default is given.
pub fn landmarks_from_gis_csv(
    path: &Path,
    text: &str,
    options: &GisOptions,
) -> Result<GisRead, InputError> {
    let mut read = GisRead {
        landmarks: Vec::new(),
        default_height: 0,
        not_points: 0,
    };
    let mut rows = text
        .trim_start_matches('\u{feff}')
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hk, header)) = rows.next() else {
        return Err(InputError::field(path, 1, "header", "the file is empty"));
    };
    let names: Vec<String> = header
        .split(',')
        .map(|n| n.trim().to_ascii_lowercase())
        .collect();
    let col = |options: &[&str]| names.iter().position(|n| options.contains(&n.as_str()));
    let need = |options: &[&str]| {
        col(options).ok_or_else(|| {
            InputError::field(
                path,
                hk as u64 + 1,
                options[0],
                "required column is missing",
            )
        })
    };
    let (lat_c, lon_c) = (
        need(&["lat", "latitude"])?,
        need(&["lon", "longitude", "lng"])?,
    );
    let (id_c, h_c, e_c) = (col(&["id"]), col(&["height"]), col(&["ele", "elevation"]));
    let (class_c, sigma_c) = (col(&["class"]), col(&["sigma_m"]));
    let mut seen = std::collections::HashMap::new();
    for (k, row) in rows {
        let line = k as u64 + 1;
        let parts: Vec<&str> = row.split(',').map(str::trim).collect();
        let get = |c: Option<usize>| {
            c.and_then(|c| parts.get(c).copied())
                .filter(|s| !s.is_empty())
        };
        let num = |c: Option<usize>, name: &str| -> Result<Option<f64>, InputError> {
            match get(c) {
                None => Ok(None),
                Some(s) => match s.parse::<f64>() {
                    Ok(x) if x.is_finite() => Ok(Some(x)),
                    _ => Err(InputError::field(
                        path,
                        line,
                        name,
                        format!("`{s}` is not a finite number"),
                    )),
                },
            }
        };
        let lat = num(Some(lat_c), "lat")?
            .ok_or_else(|| InputError::field(path, line, "lat", "missing value"))?;
        let lon = num(Some(lon_c), "lon")?
            .ok_or_else(|| InputError::field(path, line, "lon", "missing value"))?;
        let fields = Fields {
            id: get(id_c).map(str::to_string),
            lat,
            lon,
            height: num(h_c, "height")?,
            ele: num(e_c, "ele")?,
            class: get(class_c).map(str::to_string),
            sigma: num(sigma_c, "sigma_m")?,
        };
        let l = landmark(
            path,
            line,
            &format!("row {line}"),
            fields,
            options,
            &mut read,
        )?;
        if let Some(first) = seen.insert(l.id.clone(), line) {
            return Err(InputError::field(
                path,
                line,
                "id",
                format!("duplicate landmark id `{}` (first on line {first})", l.id),
            ));
        }
        read.landmarks.push(l);
    }
    Ok(read)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(ground: Option<f64>) -> GisOptions {
        GisOptions {
            ground_height_m: ground,
            ..GisOptions::default()
        }
    }

    const OSM: &str = r#"{"type":"FeatureCollection","features":[
      {"type":"Feature","id":"node/1","properties":{"highway":"street_lamp","height":"8"},
       "geometry":{"type":"Point","coordinates":[2.3522,48.8566]}},
      {"type":"Feature","id":"node/2","properties":{"highway":"street_lamp","ele":40.0},
       "geometry":{"type":"Point","coordinates":[2.3523,48.8567]}},
      {"type":"Feature","id":"way/3","properties":{},
       "geometry":{"type":"LineString","coordinates":[[2.35,48.85],[2.36,48.86]]}}]}"#;

    #[test]
    fn osm_lamps_get_ellipsoidal_heights_and_the_default_once() {
        let r = landmarks_from_geojson(Path::new("l.geojson"), OSM, &opts(Some(35.0))).unwrap();
        assert_eq!(
            (r.landmarks.len(), r.default_height, r.not_points),
            (2, 1, 1)
        );
        let n = geoid_height_m(48.8566, 2.3522);
        // EGM96 in Paris is about +44.6 m.
        assert!((n - 44.6).abs() < 1.0, "{n}");
        let a = &r.landmarks[0];
        assert_eq!(
            (a.id.as_str(), a.class.as_deref(), a.sigma_m),
            ("node/1", Some("street_lamp"), Some(0.5))
        );
        assert!((a.alt_m - (35.0 + n + 8.0)).abs() < 1e-9);
        let b = &r.landmarks[1];
        assert!((b.alt_m - (40.0 + geoid_height_m(48.8567, 2.3523) + 6.0)).abs() < 1e-9);
        assert_eq!(b.sigma_m, Some(1.5));
        let w = r.warning(Path::new("l.geojson"), &opts(None)).unwrap();
        assert_eq!(
            w,
            "l.geojson: 1 of 2 lamps have no height above ground: 6 m used with σ 1.5 m; 1 features that are not points skipped"
        );
        // Without a ground height, the first lamp (no `ele`) is refused by name.
        let e = landmarks_from_geojson(Path::new("l.geojson"), OSM, &opts(None)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "l.geojson:1: field `ele`: feature 0 (id node/1): no ground height (`ele`) and no default ground height given"
        );
        // Ellipsoidal ground heights: no geoid added.
        let o = GisOptions {
            reference: GroundReference::Ellipsoid,
            ..opts(Some(35.0))
        };
        let r = landmarks_from_geojson(Path::new("l.geojson"), OSM, &o).unwrap();
        assert_eq!(r.landmarks[0].alt_m, 43.0);
    }

    #[test]
    fn projected_coordinates_are_refused_naming_file_and_feature() {
        let utm = OSM.replace("[2.3523,48.8567]", "[452000.5,5411000.0]");
        let e = landmarks_from_geojson(Path::new("l.geojson"), &utm, &opts(Some(0.0))).unwrap_err();
        assert!(e.to_string().starts_with("l.geojson:1: field `coordinates`: feature 1 (id node/2): (452000.5, 5411000) is not WGS84"), "{e}");
        let crs = OSM.replacen(
            "\"type\":\"FeatureCollection\",",
            "\"type\":\"FeatureCollection\",\"crs\":{\"type\":\"name\",\"properties\":{\"name\":\"urn:ogc:def:crs:EPSG::25832\"}},",
            1,
        );
        let e = landmarks_from_geojson(Path::new("l.geojson"), &crs, &opts(Some(0.0))).unwrap_err();
        assert!(
            e.to_string()
                .contains("`urn:ogc:def:crs:EPSG::25832`, not WGS84"),
            "{e}"
        );
        let wgs = crs.replace("EPSG::25832", "OGC:1.3:CRS84");
        assert!(landmarks_from_geojson(Path::new("l.geojson"), &wgs, &opts(Some(0.0))).is_ok());
        let e =
            landmarks_from_geojson(Path::new("l.geojson"), "{\"type\":", &opts(None)).unwrap_err();
        assert!(
            e.to_string().starts_with("l.geojson:1: field `json`"),
            "{e}"
        );
    }

    #[test]
    fn csv_with_latitude_and_longitude_only() {
        let text = "latitude,longitude,height,class\n48.8566,2.3522,,\n48.8567,2.3523,7.5,lamp\n";
        let r = landmarks_from_gis_csv(Path::new("l.csv"), text, &opts(Some(30.0))).unwrap();
        assert_eq!((r.landmarks.len(), r.default_height), (2, 1));
        assert_eq!(r.landmarks[0].id, "lamp2");
        assert_eq!(r.landmarks[1].class.as_deref(), Some("lamp"));
        assert!((r.landmarks[1].alt_m - (37.5 + geoid_height_m(48.8567, 2.3523))).abs() < 1e-9);
        let e = landmarks_from_gis_csv(Path::new("l.csv"), "lat,lon\n1,x\n", &opts(Some(0.0)))
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "l.csv:2: field `lon`: `x` is not a finite number"
        );
        let e = landmarks_from_gis_csv(Path::new("l.csv"), "lat,lon\n1,500\n", &opts(Some(0.0)))
            .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("l.csv:2: field `coordinates`: row 2: (500, 1)"),
            "{e}"
        );
    }

    #[test]
    fn geoid_agrees_with_ngas_reference_values() {
        // NGA F477 `outintpt.dat` (EGM96 with the correction term): lat, lon (E), N.
        for (lat, lon, n) in [
            (38.6281550, 269.7791550, -31.628),
            (-14.6212170, 305.0211140, -2.969),
            (46.8743190, 102.4487290, -43.575),
            (-23.6174460, 133.8747120, 15.871),
            (38.6254730, 359.9995000, 50.066),
            (-0.4667440, 0.0023000, 17.329),
        ] {
            let got = geoid_height_m(lat, lon);
            assert!((got - n).abs() < 0.01, "{lat} {lon}: {got} vs {n}");
        }
    }
}
