//! `vgps landmarks footprints` on real OpenStreetMap footprints (tests/data/buildings, ODbL).
mod common;
use common::vgps;
use std::path::Path;

fn data(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/buildings")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn manhattan_footprints_give_roof_corners_at_ground_geoid_and_height() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("L.csv");
    let o = vgps(&[
        "landmarks",
        "footprints",
        &data("manhattan_broadway_union_sq_osm.geojson"),
        "--ground-height",
        "10",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // All 67 buildings have a `height`: every footprint is converted, none skipped.
    assert!(
        stdout.contains(
            "(corners of 67 footprints, 0 with heights from building:levels; 0 features skipped)"
        ),
        "{stdout}"
    );
    let landmarks = vgps::io::read_landmarks(&out).unwrap();
    assert!(landmarks.len() >= 4 * 67, "{} corners", landmarks.len());
    assert!(
        landmarks
            .iter()
            .all(|l| l.class.as_deref() == Some("corner"))
    );
    // The Goelet Building (way/248773492, height 44.6 m): its 10-vertex outline has 9
    // distinct vertices, of which the ones where it runs on straight are not corners.
    let goelet: Vec<_> = landmarks
        .iter()
        .filter(|l| l.id.starts_with("way/248773492/roof"))
        .collect();
    assert!((4..=9).contains(&goelet.len()), "{goelet:?}");
    for l in goelet {
        let n = vgps::io::gis::geoid_height_m(l.lat_deg, l.lon_deg);
        // EGM96 at Union Square is about −32.6 m.
        assert!((n + 32.6).abs() < 1.0, "{n}");
        assert!((l.alt_m - (10.0 + n + 44.6)).abs() < 1e-6, "{l:?}");
        assert_eq!(l.sigma_m, Some(0.5));
    }
}

#[test]
fn helsinki_footprints_use_levels_and_skip_buildings_without_a_height_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("L.csv");
    let o = vgps(&[
        "landmarks",
        "footprints",
        &data("helsinki_center_buildings_osm.geojson"),
        "--ground-height",
        "15",
        "--ground-corners",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stdout}{stderr}");
    // Counted independently of vgps (a script over the GeoJSON): 171 of the 494 footprints
    // have `height` or `building:levels`; 11 of those have a broken outline (unclosed,
    // self-intersecting, or round with no corner), so 160 convert and 334 are skipped.
    let skipped = stderr.matches(" skipped: ").count();
    assert_eq!(skipped, 334, "{stderr}");
    assert_eq!(
        stderr
            .matches("no `height` and no `building:levels`")
            .count(),
        316
    );
    assert_eq!(stderr.matches("the outer ring is not closed").count(), 12);
    assert_eq!(
        stderr.matches("the outer ring intersects itself").count(),
        4
    );
    assert!(
        stdout.contains("corners of 160 footprints, 149 with heights from building:levels"),
        "{stdout}"
    );
    assert!(stderr.contains("helsinki_center_buildings_osm.geojson: feature "));
    let landmarks = vgps::io::read_landmarks(&out).unwrap();
    let roofs = landmarks.iter().filter(|l| l.id.contains("/roof")).count();
    let grounds = landmarks
        .iter()
        .filter(|l| l.id.contains("/ground"))
        .count();
    assert!(roofs > 0 && grounds > 0, "{roofs} {grounds}");
    // Levels-only heights carry the larger σ.
    assert!(landmarks.iter().any(|l| l.sigma_m == Some(1.5)));
    assert!(stdout.contains("features skipped)"), "{stdout}");
}
