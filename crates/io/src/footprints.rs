//! Building-corner landmarks from building footprints with heights: GeoJSON polygons as
//! cities and OpenStreetMap publish them (`height` in metres above the ground, or
//! `building:levels`).
//!
//! # What becomes a landmark
//! Every vertex of a footprint's outer ring where the outline turns by at least
//! [`FootprintOptions::min_turn_deg`] becomes a **roof corner** at the roof height (the
//! corner a camera in the street sees against the sky); with
//! [`FootprintOptions::ground_corners`] also a **ground corner** at the ground height. A vertex
//! where the outline runs on almost straight is no visible corner and is skipped; inner rings
//! (courtyards) are left out. A corner shared by two footprints of the same height (row houses)
//! is written once. Class `corner` (the class the vertex detector gives its detections).
//!
//! # Heights and σ
//! The roof's ellipsoidal height is `H_ground + N(lat, lon) + height`, as for lamps
//! ([`crate::gis`]): the feature's `ele`, else [`FootprintOptions::ground_height_m`] (a
//! flat-ground assumption for the area, with its σ [`FootprintOptions::ground_sigma_m`]),
//! plus the EGM96 geoid height when the ground heights are orthometric. Without `height`,
//! `building:levels` × [`FootprintOptions::level_height_m`] is used with the larger σ
//! [`FootprintOptions::levels_sigma_m`]. A landmark's σ per axis is the largest of the
//! footprint's horizontal σ, the ground's σ and the height's σ (the landmark file has one σ
//! per landmark).
//!
//! # Bad features
//! A feature that cannot be converted — not a polygon, an unclosed or self-intersecting ring,
//! fewer than three corners, coordinates outside ±180°/±90° (a projected CRS), no usable height
//! or ground height, a negative height — is skipped with a message naming the file and the
//! feature ([`FootprintRead::skipped`]); the other features are converted. Not JSON, a `crs`
//! that is not WGS84, or no landmark at all is an error.

use crate::gis::{GroundReference, geoid_height_m, geojson_features, number, parse_wgs84_geojson};
use crate::{InputError, Landmark, MAX_ABS_LAT_DEG, MAX_ABS_LON_DEG};
use std::path::Path;

/// Metres per degree of latitude (a local plane for the geometric checks of one footprint).
const METRES_PER_DEG: f64 = 111_320.0;

/// Two corners closer than this (metres, horizontally and in height) are one landmark.
const SAME_CORNER_M: f64 = 0.1;

/// Most vertices of one ring (the self-intersection check is quadratic in them).
pub const MAX_RING_VERTICES: usize = 10_000;

/// How footprints become corner landmarks.
#[derive(Clone, Debug, PartialEq)]
pub struct FootprintOptions {
    /// The ground height for features without `ele`, metres (in [`Self::reference`]);
    /// `None`: such features are skipped.
    pub ground_height_m: Option<f64>,
    /// The reference of the ground heights.
    pub reference: GroundReference,
    /// σ of the ground height (the flat-ground assumption), metres.
    pub ground_sigma_m: f64,
    /// σ of a footprint's vertices horizontally (its stated accuracy), metres.
    pub horizontal_sigma_m: f64,
    /// σ of a `height` tag, metres.
    pub height_sigma_m: f64,
    /// Storey height for `building:levels`, metres.
    pub level_height_m: f64,
    /// σ of a height from `building:levels`, metres.
    pub levels_sigma_m: f64,
    /// Least turn of the outline at a vertex for it to be a corner, degrees.
    pub min_turn_deg: f64,
    /// Also write the ground corners.
    pub ground_corners: bool,
}

impl Default for FootprintOptions {
    /// Ground height not given (orthometric), σ 0.5 m for the ground, the footprint and a
    /// `height` tag; 3 m per level with σ 1.5 m; corners where the outline turns by 20° or
    /// more; roof corners only.
    fn default() -> Self {
        Self {
            ground_height_m: None,
            reference: GroundReference::Geoid,
            ground_sigma_m: 0.5,
            horizontal_sigma_m: 0.5,
            height_sigma_m: 0.5,
            level_height_m: 3.0,
            levels_sigma_m: 1.5,
            min_turn_deg: 20.0,
            ground_corners: false,
        }
    }
}

/// Footprints read: the corner landmarks and what was skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct FootprintRead {
    /// The corner landmarks, in file order.
    pub landmarks: Vec<Landmark>,
    /// Footprints converted.
    pub footprints: usize,
    /// Footprints whose height came from `building:levels`.
    pub from_levels: usize,
    /// One message per skipped feature, naming the file and the feature.
    pub skipped: Vec<String>,
}

/// A footprint's outer ring as `(lon, lat)` positions, without the closing repeat.
fn outer_ring(geometry: Option<&serde_json::Value>) -> Result<Vec<Vec<[f64; 2]>>, String> {
    let kind = geometry
        .and_then(|g| g.get("type"))
        .and_then(|t| t.as_str());
    let coords = geometry.and_then(|g| g.get("coordinates"));
    let polygons: Vec<&serde_json::Value> = match (kind, coords) {
        (Some("Polygon"), Some(c)) => vec![c],
        (Some("MultiPolygon"), Some(serde_json::Value::Array(ps))) => ps.iter().collect(),
        (other, _) => {
            return Err(format!(
                "not a Polygon or MultiPolygon ({})",
                other.unwrap_or("no geometry")
            ));
        }
    };
    polygons
        .into_iter()
        .map(|p| {
            let ring = p
                .get(0)
                .and_then(|r| r.as_array())
                .ok_or("a polygon without an outer ring")?;
            if ring.len() > MAX_RING_VERTICES {
                return Err(format!(
                    "a ring of {} vertices (at most {MAX_RING_VERTICES})",
                    ring.len()
                ));
            }
            let points = ring
                .iter()
                .map(|q| match q.as_array().map(|a| a.as_slice()) {
                    Some([lon, lat, ..]) => match (lon.as_f64(), lat.as_f64()) {
                        (Some(lon), Some(lat)) if lon.is_finite() && lat.is_finite() => {
                            Ok([lon, lat])
                        }
                        _ => Err("a position that is not numbers".to_string()),
                    },
                    _ => Err("a position that is not [lon, lat]".to_string()),
                })
                .collect::<Result<Vec<_>, _>>()?;
            if let Some(p) = points
                .iter()
                .find(|p| p[0].abs() > MAX_ABS_LON_DEG || p[1].abs() > MAX_ABS_LAT_DEG)
            {
                return Err(format!(
                    "({}, {}) is not WGS84 longitude, latitude: a projected CRS? (reproject to \
                     EPSG:4326 first, e.g. `ogr2ogr -t_srs EPSG:4326`)",
                    p[0], p[1]
                ));
            }
            match (points.first(), points.last()) {
                (Some(a), Some(b)) if points.len() >= 4 && a == b => {
                    Ok(points[..points.len() - 1].to_vec())
                }
                _ => Err(
                    "the outer ring is not closed (its last position must repeat the \
                          first, with at least three others)"
                        .to_string(),
                ),
            }
        })
        .collect()
}

/// `true` when segments `ab` and `cd` cross or touch (a plane, metres).
fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let orient = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    };
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    let on = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    ((d1 > 0.0) != (d2 > 0.0) && (d3 > 0.0) != (d4 > 0.0) && d1 != 0.0 && d2 != 0.0)
        || (d1 == 0.0 && on(c, d, a))
        || (d2 == 0.0 && on(c, d, b))
        || (d3 == 0.0 && on(a, b, c))
        || (d4 == 0.0 && on(a, b, d))
}

/// The ring in a local plane (metres east, north of its first vertex).
fn local_plane(ring: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let [lon0, lat0] = ring[0];
    let k = lat0.to_radians().cos() * METRES_PER_DEG;
    ring.iter()
        .map(|p| [(p[0] - lon0) * k, (p[1] - lat0) * METRES_PER_DEG])
        .collect()
}

/// `true` when two non-adjacent edges of the closed ring meet.
fn self_intersects(xy: &[[f64; 2]]) -> bool {
    let n = xy.len();
    (0..n).any(|i| {
        (i + 1..n).any(|j| {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            !adjacent && segments_meet(xy[i], xy[(i + 1) % n], xy[j], xy[(j + 1) % n])
        })
    })
}

/// Indices of the vertices where the outline turns by at least `min_turn_rad`.
fn corner_indices(xy: &[[f64; 2]], min_turn_rad: f64) -> Vec<usize> {
    let n = xy.len();
    (0..n)
        .filter(|&i| {
            let (p, q, r) = (xy[(i + n - 1) % n], xy[i], xy[(i + 1) % n]);
            let (u, v) = ([q[0] - p[0], q[1] - p[1]], [r[0] - q[0], r[1] - q[1]]);
            let turn = (u[0] * v[1] - u[1] * v[0])
                .atan2(u[0] * v[0] + u[1] * v[1])
                .abs();
            turn >= min_turn_rad
        })
        .collect()
}

/// Reads a GeoJSON `FeatureCollection` (or one `Feature`) of building footprints and returns
/// their corners as landmarks (see the module docs).
///
/// # Errors
/// [`InputError`] naming the file: not JSON, not a `FeatureCollection` or `Feature`, a `crs`
/// that is not WGS84, or no corner at all (an empty collection, or every feature skipped:
/// the first reason is given).
pub fn corners_from_footprints(
    path: &Path,
    text: &str,
    options: &FootprintOptions,
) -> Result<FootprintRead, InputError> {
    let err = |field: &str, reason: String| InputError::field(path, 1, field, reason);
    let root = parse_wgs84_geojson(path, text)?;
    let features = geojson_features(path, &root)?;
    let mut read = FootprintRead {
        landmarks: Vec::new(),
        footprints: 0,
        from_levels: 0,
        skipped: Vec::new(),
    };
    for (k, feature) in features.iter().enumerate() {
        let props = feature.get("properties").and_then(|p| p.as_object());
        let prop = |name: &str| props.and_then(|p| p.get(name));
        let id = feature
            .get("id")
            .or_else(|| prop("@id"))
            .map(|v| v.as_str().map_or_else(|| v.to_string(), str::to_string))
            .unwrap_or_else(|| format!("building{k}"));
        match footprint_corners(feature, &id, options, &mut read) {
            Ok(corners) => {
                read.footprints += 1;
                for c in corners {
                    let duplicate = read.landmarks.iter().any(|l| {
                        (l.alt_m - c.alt_m).abs() < SAME_CORNER_M
                            && ((l.lat_deg - c.lat_deg) * METRES_PER_DEG).abs() < SAME_CORNER_M
                            && ((l.lon_deg - c.lon_deg)
                                * METRES_PER_DEG
                                * c.lat_deg.to_radians().cos())
                            .abs()
                                < SAME_CORNER_M
                    });
                    if !duplicate {
                        read.landmarks.push(Landmark {
                            line: k as u64,
                            ..c
                        });
                    }
                }
            }
            Err(reason) => read.skipped.push(format!(
                "{}: feature {k} (id {id}) skipped: {reason}",
                path.display()
            )),
        }
    }
    if read.landmarks.is_empty() {
        let why = read
            .skipped
            .first()
            .cloned()
            .unwrap_or_else(|| "the collection has no feature".into());
        return Err(err("features", format!("no building corner: {why}")));
    }
    Ok(read)
}

/// The corners of one footprint, or why it is skipped.
fn footprint_corners(
    feature: &serde_json::Value,
    id: &str,
    options: &FootprintOptions,
    read: &mut FootprintRead,
) -> Result<Vec<Landmark>, String> {
    let props = feature.get("properties").and_then(|p| p.as_object());
    let prop = |name: &str| props.and_then(|p| p.get(name));
    let rings = outer_ring(feature.get("geometry"))?;
    let (height, height_sigma) = match number(prop("height"))? {
        Some(h) if h > 0.0 => (h, options.height_sigma_m),
        Some(h) => return Err(format!("height {h} is not positive")),
        None => match number(prop("building:levels"))? {
            Some(l) if l > 0.0 => {
                read.from_levels += 1;
                (l * options.level_height_m, options.levels_sigma_m)
            }
            Some(l) => return Err(format!("building:levels {l} is not positive")),
            None => return Err("no `height` and no `building:levels`".into()),
        },
    };
    let ground = number(prop("ele"))?
        .or(options.ground_height_m)
        .ok_or("no ground height (`ele`) and no default ground height given")?;
    let sigma = options
        .horizontal_sigma_m
        .max(options.ground_sigma_m)
        .max(height_sigma);
    let ground_sigma = options.horizontal_sigma_m.max(options.ground_sigma_m);
    let mut corners = Vec::new();
    for (r, ring) in rings.iter().enumerate() {
        let xy = local_plane(ring);
        if self_intersects(&xy) {
            return Err("the outer ring intersects itself".into());
        }
        let indices = corner_indices(&xy, options.min_turn_deg.to_radians());
        if indices.len() < 3 {
            return Err(format!(
                "{} corner(s) turning by {}° or more: not a footprint",
                indices.len(),
                options.min_turn_deg
            ));
        }
        for i in indices {
            let [lon, lat] = ring[i];
            let n = match options.reference {
                GroundReference::Geoid => geoid_height_m(lat, lon),
                GroundReference::Ellipsoid => 0.0,
            };
            let base = ground + n;
            let part = if rings.len() > 1 {
                format!("{id}/{r}")
            } else {
                id.to_string()
            };
            let corner = |suffix: &str, alt_m: f64, sigma_m: f64| Landmark {
                id: format!("{part}/{suffix}{i}"),
                lat_deg: lat,
                lon_deg: lon,
                alt_m,
                sigma_m: Some(sigma_m),
                class: Some("corner".into()),
                line: 0,
            };
            corners.push(corner("roof", base + height, sigma));
            if options.ground_corners {
                corners.push(corner("ground", base, ground_sigma));
            }
        }
    }
    if corners.iter().any(|c| !c.alt_m.is_finite()) {
        return Err("a height that is not finite".into());
    }
    Ok(corners)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(extra: &str, props: &str) -> String {
        // A 20 m × 10 m block at 60.17° N, a vertex in the middle of its long side.
        let (lat, lon): (f64, f64) = (60.17, 24.94);
        let dlat = 10.0 / METRES_PER_DEG;
        let dlon = 20.0 / (METRES_PER_DEG * lat.to_radians().cos());
        format!(
            r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","id":"way/1",
            "properties":{{{props}}},"geometry":{{"type":"Polygon","coordinates":[[
            [{lon},{lat}],[{},{lat}],[{},{lat}],[{},{}],[{lon},{}],[{lon},{lat}]]]}}}}{extra}]}}"#,
            lon + dlon / 2.0,
            lon + dlon,
            lon + dlon,
            lat + dlat,
            lat + dlat
        )
    }

    fn options() -> FootprintOptions {
        FootprintOptions {
            ground_height_m: Some(10.0),
            reference: GroundReference::Ellipsoid,
            ..FootprintOptions::default()
        }
    }

    #[test]
    fn a_block_gives_its_four_roof_corners_and_not_the_straight_vertex() {
        let read = corners_from_footprints(
            Path::new("b.geojson"),
            &square("", r#""height":"12.5""#),
            &options(),
        )
        .unwrap();
        assert_eq!(read.footprints, 1);
        assert_eq!(read.landmarks.len(), 4, "{:?}", read.landmarks);
        assert!(
            read.landmarks
                .iter()
                .all(|l| (l.alt_m - 22.5).abs() < 1e-12)
        );
        assert!(read.landmarks.iter().all(|l| l.sigma_m == Some(0.5)));
        assert!(
            read.landmarks
                .iter()
                .all(|l| l.class.as_deref() == Some("corner"))
        );
        // Vertex 1 (the middle of the long side) is not a corner.
        let ids: Vec<_> = read.landmarks.iter().map(|l| l.id.as_str()).collect();
        assert_eq!(
            ids,
            ["way/1/roof0", "way/1/roof2", "way/1/roof3", "way/1/roof4"]
        );
    }

    #[test]
    fn levels_give_the_height_with_the_larger_sigma_and_ground_corners_are_optional() {
        let o = FootprintOptions {
            ground_corners: true,
            ..options()
        };
        let read = corners_from_footprints(
            Path::new("b.geojson"),
            &square("", r#""building:levels":"4""#),
            &o,
        )
        .unwrap();
        assert_eq!(read.from_levels, 1);
        assert_eq!(read.landmarks.len(), 8);
        let roof = &read.landmarks[0];
        assert_eq!((roof.alt_m, roof.sigma_m), (22.0, Some(1.5)));
        let ground = &read.landmarks[1];
        assert_eq!((ground.alt_m, ground.sigma_m), (10.0, Some(0.5)));
    }

    #[test]
    fn orthometric_ground_heights_get_the_geoid_added() {
        let o = FootprintOptions {
            reference: GroundReference::Geoid,
            ..options()
        };
        let read =
            corners_from_footprints(Path::new("b.geojson"), &square("", r#""height":10"#), &o)
                .unwrap();
        let l = &read.landmarks[0];
        let n = geoid_height_m(l.lat_deg, l.lon_deg);
        assert!((l.alt_m - (20.0 + n)).abs() < 1e-9);
        // EGM96 in Helsinki: about 17.6 m.
        assert!((n - 17.6).abs() < 1.0, "{n}");
    }

    #[test]
    fn bad_features_are_skipped_by_name_and_the_rest_converted() {
        let bad = [
            // unclosed
            r#"{"type":"Feature","id":"open","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.9001,60.1],[24.9001,60.1001],[24.9,60.1001]]]}}"#,
            // a bow tie
            r#"{"type":"Feature","id":"bowtie","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.9001,60.1001],[24.9001,60.1],[24.9,60.1001],[24.9,60.1]]]}}"#,
            // negative height
            r#"{"type":"Feature","id":"neg","properties":{"height":-3},"geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.9001,60.1],[24.9001,60.1001],[24.9,60.1]]]}}"#,
            // no height
            r#"{"type":"Feature","id":"flat","properties":{},"geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.9001,60.1],[24.9001,60.1001],[24.9,60.1]]]}}"#,
            // metres of a projected CRS
            r#"{"type":"Feature","id":"utm","properties":{"height":5},"geometry":{"type":"Polygon","coordinates":[[[385000,6672000],[385020,6672000],[385020,6672010],[385000,6672000]]]}}"#,
            // a point
            r#"{"type":"Feature","id":"lamp","properties":{"height":5},"geometry":{"type":"Point","coordinates":[24.9,60.1]}}"#,
        ];
        let extra: String = bad.iter().map(|f| format!(",{f}")).collect();
        let read = corners_from_footprints(
            Path::new("city.geojson"),
            &square(&extra, r#""height":9"#),
            &options(),
        )
        .unwrap();
        assert_eq!((read.footprints, read.landmarks.len()), (1, 4));
        let expect = [
            ("open", "not closed"),
            ("bowtie", "intersects itself"),
            ("neg", "not positive"),
            ("flat", "no `height`"),
            ("utm", "projected CRS"),
            ("lamp", "not a Polygon"),
        ];
        assert_eq!(read.skipped.len(), expect.len(), "{:?}", read.skipped);
        for (message, (id, why)) in read.skipped.iter().zip(expect) {
            assert!(
                message.starts_with("city.geojson: feature")
                    && message.contains(&format!("(id {id})"))
                    && message.contains(why),
                "{message}"
            );
        }
    }

    #[test]
    fn an_empty_collection_or_a_projected_crs_is_an_error() {
        for (text, why) in [
            (
                r#"{"type":"FeatureCollection","features":[]}"#,
                "no feature",
            ),
            (
                r#"{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:3067"}},"features":[]}"#,
                "EPSG:3067",
            ),
            ("not json", "json"),
        ] {
            let e = corners_from_footprints(Path::new("x.geojson"), text, &options())
                .unwrap_err()
                .to_string();
            assert!(e.contains("x.geojson") && e.contains(why), "{e}");
        }
    }

    #[test]
    fn a_corner_shared_by_two_footprints_of_one_height_is_written_once() {
        // Two 10 m squares side by side share an edge (two vertices).
        let (lat, lon): (f64, f64) = (60.17, 24.94);
        let d = 10.0 / METRES_PER_DEG;
        let e = 10.0 / (METRES_PER_DEG * lat.to_radians().cos());
        let sq = |x0: f64, id: &str| {
            format!(
                r#"{{"type":"Feature","id":"{id}","properties":{{"height":6}},"geometry":{{"type":"Polygon","coordinates":[[[{x0},{lat}],[{},{lat}],[{},{}],[{x0},{}],[{x0},{lat}]]]}}}}"#,
                x0 + e,
                x0 + e,
                lat + d,
                lat + d
            )
        };
        let text = format!(
            r#"{{"type":"FeatureCollection","features":[{},{}]}}"#,
            sq(lon, "a"),
            sq(lon + e, "b")
        );
        let read = corners_from_footprints(Path::new("r.geojson"), &text, &options()).unwrap();
        assert_eq!(read.landmarks.len(), 6);
    }
}
