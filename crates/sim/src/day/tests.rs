use super::scene::{BoxKind, SceneBox};
use super::*;
use crate::simulate::{Preset, Scenario, simulate};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use vgps_geometry::geometry::Pose;

fn one_building_scene() -> DayScene {
    let min = Vector3::new(20.0, 5.0, 0.0);
    let max = Vector3::new(40.0, 25.0, 12.0);
    DayScene {
        boxes: vec![SceneBox {
            min,
            max,
            albedo: 0.5,
            kind: BoxKind::Building,
            awnings: vec![],
        }],
        canopies: vec![],
        block_m: 1000.0,
        corners: vec![
            (7, Vector3::new(20.0, 5.0, 12.0)),
            (8, Vector3::new(40.0, 25.0, 12.0)),
        ],
    }
}

#[test]
fn a_roof_corner_is_drawn_where_it_projects() {
    let rig = Scenario::preset(Preset::Short, 1).rig;
    let renderer = DayRenderer::new(
        DayOptions {
            read_noise_dn: 0.0,
            gain_e_per_dn: 0.0,
            ..DayOptions::default()
        },
        &rig,
    );
    // The rig at 2 m, looking along +x (east): camera 0 faces forward.
    let world_from_rig = Pose::from_parts(
        Translation3::new(0.0, 0.0, 2.0),
        UnitQuaternion::identity().into(),
    );
    let sun = sun_position(1_778_794_200.0, 37.7793, -122.4193).direction_in_enu();
    let frame = renderer
        .render(&one_building_scene(), &world_from_rig, 0, &sun, 1)
        .unwrap();
    // The near corner (20, 5, 12) is visible, the far one (40, 25, 12) is hidden by the box.
    assert_eq!(frame.corners.len(), 1, "{:?}", frame.corners);
    let c = frame.corners[0];
    assert_eq!(c.landmark, 7);
    let at = |du: f64, dv: f64| {
        frame
            .image
            .get_pixel((c.u + du).round() as u32, (c.v + dv).round() as u32)[0]
    };
    // Around the corner: sky (bright, ≈ 200 DN) on some sides, the wall on another.
    let samples = [at(-4.0, -4.0), at(4.0, -4.0), at(-4.0, 4.0), at(4.0, 4.0)];
    let (lo, hi) = (
        *samples.iter().min().unwrap(),
        *samples.iter().max().unwrap(),
    );
    assert!(hi > 150 && hi - lo > 20, "{samples:?}");
}

#[test]
fn a_drive_frame_renders_with_visible_corners() {
    let mut sc = Scenario::preset(Preset::Short, 3);
    sc.length_m = 60.0;
    let drive = simulate(&sc).unwrap();
    let scene = DayScene::from_world(&drive.world, sc.block_m, sc.seed);
    assert!(scene.boxes.iter().any(|b| !b.awnings.is_empty()));
    assert!(scene.boxes.iter().any(|b| b.kind == BoxKind::Car));
    let renderer = DayRenderer::new(DayOptions::default(), &sc.rig);
    let f = &drive.frames[2];
    let sun = sun_position(f.time_s, sc.origin.lat_deg, sc.origin.lon_deg).direction_in_enu();
    assert!(sun.z > 0.0, "the default drive is an afternoon");
    let total: usize = (0..sc.rig.len())
        .map(|k| {
            renderer
                .render(&scene, &f.world_from_rig, k, &sun, 9)
                .unwrap()
                .corners
                .len()
        })
        .sum();
    assert!(total > 3, "{total} corners");
    let a = renderer
        .render(&scene, &f.world_from_rig, 1, &sun, 9)
        .unwrap();
    let b = renderer
        .render(&scene, &f.world_from_rig, 1, &sun, 9)
        .unwrap();
    assert_eq!(a.image, b.image);
}

/// A small rendered day frame (one 400 × 300 fisheye camera, two buildings): the vertex
/// detector finds each visible roof corner within 0.5 px of its projection, through the
/// camera model. Seconds: the frame is an eighth of a Ladybug image.
#[test]
fn the_vertex_detector_finds_the_corners_of_a_small_day_frame() {
    use nalgebra::{IsometryMatrix3, Matrix3, Rotation3};
    use vgps_camera::calibration::{Camera, KannalaBrandt, KannalaBrandtParams, Rig, RigCamera};
    use vgps_camera::imaging::VertexDetector;
    let model = KannalaBrandt::new(KannalaBrandtParams {
        width: 400,
        height: 300,
        fx: 260.0,
        fy: 260.0,
        cx: 199.5,
        cy: 149.5,
        k1: -0.2,
        k2: 0.1,
        k3: 0.0,
        k4: 0.0,
    })
    .unwrap();
    // Camera x right (rig −y), y down (rig −z), z forward (rig x).
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
    ));
    let rig = Rig::new(vec![RigCamera {
        model: Camera::from(model.clone()),
        rig_from_camera: IsometryMatrix3::from_parts(Translation3::identity(), rotation),
    }])
    .unwrap();
    let building = |min: Vector3<f64>, max: Vector3<f64>, albedo: f64| SceneBox {
        min,
        max,
        albedo,
        kind: BoxKind::Building,
        awnings: vec![],
    };
    let scene = DayScene {
        boxes: vec![
            building(
                Vector3::new(25.0, 4.0, 0.0),
                Vector3::new(45.0, 24.0, 11.0),
                0.55,
            ),
            building(
                Vector3::new(28.0, -24.0, 0.0),
                Vector3::new(48.0, -5.0, 9.0),
                0.35,
            ),
        ],
        canopies: vec![],
        block_m: 1000.0,
        corners: vec![
            (0, Vector3::new(25.0, 4.0, 11.0)),
            (1, Vector3::new(28.0, -5.0, 9.0)),
        ],
    };
    let renderer = DayRenderer::new(DayOptions::default(), &rig);
    let world_from_rig = Pose::from_parts(
        Translation3::new(0.0, 0.0, 2.0),
        UnitQuaternion::from_euler_angles(0.0, -0.15, 0.0).into(),
    );
    let sun = sun_position(1_778_794_200.0, 37.7793, -122.4193).direction_in_enu();
    let frame = renderer
        .render(&scene, &world_from_rig, 0, &sun, 3)
        .unwrap();
    assert_eq!(frame.corners.len(), 2, "{:?}", frame.corners);
    let found = VertexDetector::default().detect(&frame.image, Some(&Camera::from(model)), None);
    for c in &frame.corners {
        let error = found
            .iter()
            .map(|d| (d.u - c.u).hypot(d.v - c.v))
            .fold(f64::INFINITY, f64::min);
        assert!(
            error < 0.5,
            "corner {c:?}: nearest detection {error} px; {found:?}"
        );
    }
}
