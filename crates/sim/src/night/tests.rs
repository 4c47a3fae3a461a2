//! Known answers of the realistic night renderer: where reflections, windows and car lights
//! are drawn, what the truth says, determinism and vignetting.

use super::*;
use crate::day::scene::{BoxKind, SceneBox};
use crate::simulate::{Preset, Scenario, simulate};
use nalgebra::{Translation3, UnitQuaternion, Vector3};

/// Options without noise or vignetting, so pixel values are the model's.
fn quiet_options() -> NightOptions {
    let mut o = NightOptions::default();
    o.scene.gain_e_per_dn = 0.0;
    o.scene.read_noise_dn = 0.0;
    o.vignetting = 0.0;
    o
}

fn rig() -> Rig {
    Scenario::preset(Preset::Short, 1).rig
}

/// The rig at `(x, y, 2 m)` with its forward axis (camera 0) along the ENU heading `yaw`.
fn rig_at(x: f64, y: f64, yaw: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, 2.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw).into(),
    )
}

fn empty_scene(boxes: Vec<SceneBox>) -> DayScene {
    DayScene {
        boxes,
        canopies: vec![],
        block_m: 1000.0,
        corners: vec![],
    }
}

/// The pixel of camera `camera` where the world point `p` projects.
fn project(rig: &Rig, world_from_rig: &Pose, camera: usize, p: &Vector3<f64>) -> Vector2<f64> {
    let c = &rig.cameras()[camera];
    let q = (world_from_rig * c.rig_from_camera)
        .inverse_transform_point(&Point3::from(*p))
        .coords;
    c.model.try_pixel(&q.normalize()).unwrap()
}

/// A lamp at the world point `p`, in the frame of camera 0.
fn lamp_at(rig: &Rig, world_from_rig: &Pose, p: &Vector3<f64>) -> LightSource {
    let c = &rig.cameras()[0];
    LightSource {
        point_in_camera: (world_from_rig * c.rig_from_camera)
            .inverse_transform_point(&Point3::from(*p))
            .coords,
        radius_m: 0.2,
        intensity: 1.0,
    }
}

#[test]
fn a_lamps_reflection_is_its_mirror_image_about_the_road_stretched_vertically() {
    let rig = rig();
    let pose = rig_at(0.0, 0.0, 0.0);
    let renderer = NightRenderer::new(quiet_options(), &rig);
    // Over the road (the street along x at y = 0): the line of sight to the mirror image
    // meets the ground at y = 0.75 m.
    let lamp = Vector3::new(30.0, 3.0, 6.0);
    let frame = renderer
        .render(
            &empty_scene(vec![]),
            &pose,
            0,
            &[lamp_at(&rig, &pose, &lamp)],
            1,
        )
        .unwrap();
    let find = |kind| frame.spots.iter().find(|s| s.kind == kind).copied();
    let drawn = find(NightSpotKind::Lamp(0)).unwrap();
    let reflection = find(NightSpotKind::Reflection(0)).unwrap();
    let expected = project(&rig, &pose, 0, &Vector3::new(30.0, 3.0, -6.0));
    assert!((reflection.u - expected.x).hypot(reflection.v - expected.y) < 1e-6);
    let at_lamp = project(&rig, &pose, 0, &lamp);
    assert!((drawn.u - at_lamp.x).hypot(drawn.v - at_lamp.y) < 1e-6);
    // Below the lamp: on the side of the image where the lamp's foot (30, 3, 0) is.
    let foot = project(&rig, &pose, 0, &Vector3::new(30.0, 3.0, 0.0));
    let down = (foot - at_lamp).normalize();
    let centre = Vector2::new(reflection.u, reflection.v);
    assert!((centre - at_lamp).dot(&down) > (foot - at_lamp).norm());
    assert!(reflection.peak_dn < drawn.peak_dn);
    // Stretched along the vertical: 4 px along it is brighter than 4 px across it.
    let across = Vector2::new(-down.y, down.x);
    let value = |p: Vector2<f64>| {
        frame
            .image
            .get_pixel(p.x.round() as u32, p.y.round() as u32)[0]
    };
    let (along, side) = (value(centre + down * 4.0), value(centre + across * 4.0));
    assert!(along > side + 2, "along {along}, across {side}");

    // A lamp whose line of sight to its mirror image meets the sidewalk (at y = 8 m): the
    // ground there is dry, no reflection.
    let dry = Vector3::new(30.0, 18.0, 2.5);
    let frame = renderer
        .render(
            &empty_scene(vec![]),
            &pose,
            0,
            &[lamp_at(&rig, &pose, &dry)],
            1,
        )
        .unwrap();
    assert_eq!(frame.spots.len(), 1);
    assert_eq!(frame.spots[0].kind, NightSpotKind::Lamp(0));
}

fn building() -> SceneBox {
    SceneBox {
        min: Vector3::new(20.0, -30.0, 0.0),
        max: Vector3::new(32.0, 30.0, 25.0),
        albedo: 0.5,
        kind: BoxKind::Building,
        awnings: vec![],
    }
}

#[test]
fn lit_windows_lie_inside_facades_and_are_drawn_lit() {
    let rig = rig();
    let pose = rig_at(0.0, 0.0, 0.0);
    let options = quiet_options();
    let renderer = NightRenderer::new(options.clone(), &rig);
    let scene = empty_scene(vec![building()]);
    let windows = windows_of(&scene, 0);
    let lit = windows
        .iter()
        .filter(|w| window_light(&w.key, &options.scene).is_some())
        .count();
    // A hash decides which: about a quarter of them.
    let share = lit as f64 / windows.len() as f64;
    assert!(
        windows.len() > 100 && (0.15..0.35).contains(&share),
        "{lit} of {}",
        windows.len()
    );
    let b = building();
    for w in &windows {
        // On a face of the box, inside its extent.
        let axis = if w.normal.x.abs() > 0.5 { 0 } else { 1 };
        let plane = if w.normal[axis] > 0.0 {
            b.max[axis]
        } else {
            b.min[axis]
        };
        assert_eq!(w.centre[axis], plane);
        let run = 1 - axis;
        assert!(w.centre[run] > b.min[run] + 1.0 && w.centre[run] < b.max[run] - 1.0);
        assert!(w.centre.z > 4.8 && w.centre.z < b.max.z - 1.0);
    }
    let frame = renderer.render(&scene, &pose, 0, &[], 1).unwrap();
    let truth: Vec<_> = frame
        .spots
        .iter()
        .filter(|s| s.kind == NightSpotKind::Window)
        .collect();
    assert!(truth.len() >= 5, "{} lit windows in view", truth.len());
    for s in truth {
        // The facade x = 20 faces the camera: each listed window is a lit pane there.
        let value = frame
            .image
            .get_pixel(s.u.round() as u32, s.v.round() as u32)[0];
        assert!(
            (f64::from(value) - s.peak_dn).abs() < 3.0,
            "{value} vs {s:?}"
        );
        assert!((s.range_m - 20.0).abs() < 35.0);
    }
}

#[test]
fn car_lights_come_in_pairs_at_the_cars_width_and_face_their_end() {
    let rig = rig();
    let car = SceneBox {
        min: Vector3::new(-2.2, -0.9, 0.0),
        max: Vector3::new(2.2, 0.9, 1.45),
        albedo: 0.4,
        kind: BoxKind::Car,
        awnings: vec![],
    };
    let mut options = quiet_options();
    options.car_light_share = 1.0;
    let renderer = NightRenderer::new(options, &rig);
    let (forward, lateral) = car_axes(&car, 0, 1.0).unwrap();
    let scene = empty_scene(vec![car]);
    for (ahead, height, kind) in [
        (1.0, 0.65, NightSpotKind::Headlight),
        (-1.0, 0.9, NightSpotKind::Taillight),
    ] {
        // The rig 15 m off this end, looking at the car.
        let at = forward * (15.0 * ahead);
        let yaw = (-at.y).atan2(-at.x);
        let pose = rig_at(at.x, at.y, yaw);
        let frame = renderer.render(&scene, &pose, 0, &[], 1).unwrap();
        let spots: Vec<_> = frame.spots.iter().collect();
        assert_eq!(spots.len(), 2, "{spots:?}");
        assert!(spots.iter().all(|s| s.kind == kind));
        let end = Vector3::new(0.0, 0.0, height) + forward * (ahead * (2.2 + 0.03));
        for side in [-1.0, 1.0] {
            let p = end + lateral * (side * CAR_LIGHT_SPACING_M / 2.0);
            let expected = project(&rig, &pose, 0, &p);
            assert!(
                spots
                    .iter()
                    .any(|s| (s.u - expected.x).hypot(s.v - expected.y) < 1e-6),
                "{kind:?} at {p:?}"
            );
        }
    }
}

#[test]
fn a_drive_frame_is_deterministic_and_its_truth_is_drawn() {
    let mut sc = Scenario::preset(Preset::Short, 2);
    sc.length_m = 40.0;
    let drive = simulate(&sc).unwrap();
    let scene = DayScene::from_world(&drive.world, sc.block_m, sc.seed);
    let renderer = NightRenderer::new(NightOptions::default(), &sc.rig);
    let f = &drive.frames[4];
    let lights: Vec<LightSource> = crate::simulate::images::lights_of(
        &drive,
        f,
        0,
        &crate::simulate::images::ImageOptions::default(),
    )
    .into_iter()
    .filter(|(_, s)| matches!(s, crate::simulate::Source::Landmark(_)))
    .map(|(l, _)| l)
    .collect();
    assert!(lights.len() >= 3);
    let a = renderer
        .render(&scene, &f.world_from_rig, 0, &lights, 7)
        .unwrap();
    let b = renderer
        .render(&scene, &f.world_from_rig, 0, &lights, 7)
        .unwrap();
    let c = renderer
        .render(&scene, &f.world_from_rig, 0, &lights, 8)
        .unwrap();
    assert_eq!(a.image, b.image);
    assert_eq!(a.spots, b.spots);
    assert_ne!(a.image, c.image);
    assert_eq!(a.spots, c.spots, "the seed draws the noise only");
    // Every lamp in the image is listed once, and each drawn point light is bright where
    // the truth puts it (vignetting at most 35 %, noise a few DN).
    let lamps: Vec<usize> = a
        .spots
        .iter()
        .filter_map(|s| match s.kind {
            NightSpotKind::Lamp(i) => Some(i),
            _ => None,
        })
        .collect();
    let mut unique = lamps.clone();
    unique.dedup();
    assert_eq!(lamps, unique);
    assert!(!lamps.is_empty());
    let background = {
        let mut all = a.image.as_raw().clone();
        all.sort_unstable();
        f64::from(all[all.len() / 2])
    };
    let mut checked = 0;
    for s in a.spots.iter().filter(|s| s.kind != NightSpotKind::Window) {
        if s.clipped_by_border || s.peak_dn < 20.0 {
            continue;
        }
        let value = f64::from(a.image.get_pixel(s.u.round() as u32, s.v.round() as u32)[0]);
        let expected = (0.5 * s.peak_dn).min(120.0);
        assert!(value > background + expected, "{s:?}: {value}");
        checked += 1;
    }
    assert!(checked >= 3, "{checked}");
}

#[test]
fn vignetting_falls_off_as_configured() {
    let (w, h) = (101, 51);
    let mut r = vec![100.0f32; w * h];
    vignette(&mut r, w, h, 0.4);
    let at = |u: usize, v: usize| r[v * w + u];
    assert!((at(50, 25) - 100.0).abs() < 1e-4);
    for (u, v) in [(0, 0), (100, 0), (0, 50), (100, 50)] {
        assert!((at(u, v) - 60.0).abs() < 1e-3, "{}", at(u, v));
    }
    // Middle of the left edge: r² = 50² of the corner's 50² + 25².
    let expected = 100.0 * (1.0 - 0.4 * 2500.0 / 3125.0);
    assert!((f64::from(at(0, 25)) - expected).abs() < 1e-3);
    // Zero, negative or NaN vignetting leaves the image alone.
    for v in [0.0, -1.0, f64::NAN] {
        let mut r = vec![7.0f32; 20];
        vignette(&mut r, 5, 4, v);
        assert!(r.iter().all(|&x| x == 7.0));
    }
}

#[test]
fn realistic_drive_images_name_every_class_in_their_truth() {
    use crate::simulate::images::{IMAGES_TRUTH_NAME, ImageOptions, NightScene, write_images};
    let mut sc = Scenario::preset(Preset::Short, 3);
    sc.length_m = 12.0;
    let drive = simulate(&sc).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = ImageOptions {
        night_scene: NightScene::Realistic,
        jpeg_quality: Some(90),
        ..ImageOptions::default()
    };
    let summary = write_images(&drive, dir.path(), &options, 2, &|_| {}).unwrap();
    assert_eq!(summary.images, drive.frames.len() * 6);
    assert_eq!((summary.transients, summary.clutter), (0, 0));
    assert!(summary.lamps > 0 && summary.windows > 0 && summary.reflections > 0);
    let truth = std::fs::read_to_string(dir.path().join(IMAGES_TRUTH_NAME)).unwrap();
    let mut kinds = std::collections::BTreeSet::new();
    for line in truth.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), 9, "{line}");
        // Lamps and reflections name their lamp's landmark; the clutter names none.
        let named = matches!(fields[2], "lamp" | "reflection");
        assert_eq!(!fields[3].is_empty(), named, "{line}");
        kinds.insert(fields[2].to_string());
    }
    for k in ["lamp", "reflection", "window"] {
        assert!(kinds.contains(k), "{kinds:?}");
    }
    assert!(kinds.iter().all(|k| {
        ["lamp", "reflection", "window", "headlight", "taillight"].contains(&k.as_str())
    }));
    assert!(
        std::fs::metadata(dir.path().join("images/000000_0.jpg")).is_ok(),
        "JPEG at the chosen quality"
    );
}
