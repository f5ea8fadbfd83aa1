//! `sage3d render`'s default camera: over free floor and outside every object even when
//! furniture fills the middle of the largest room, recorded in `render.json`; and the old
//! point, with a warning, on a scene that has no navigation grid.

use glam::{Vec2, Vec3};
use sage_core::Obb;
use sage_nav::{GridParams, NavGrid};
use sage_pipeline::render::{
    CameraPose, CameraSource, RenderSettings, free_default_eye, render_to_folder,
};
use sage_scene::occupancy::FREE;
use sage_scene::{Floorplan, Gaussians, Scene, SplatLayout};
use sage_splat::camera::default_eye;
use sage_synth::{SynthConfig, generate};

/// A small home whose last object, made a box-only cabinet 1.4 m tall, stands over the middle
/// of the largest room, where the old default eye is.
fn home_with_a_cabinet_at_the_centre() -> Scene {
    let mut scene = generate(&SynthConfig {
        seed: 4,
        rooms: 2,
        objects: 6,
        gaussians: 2000,
        ..SynthConfig::default()
    })
    .unwrap();
    let old = default_eye(&scene);
    let cabinet = scene.objects.last_mut().unwrap();
    cabinet.obb = Obb {
        center: old.truncate().extend(0.7),
        half_extents: Vec3::new(0.8, 0.5, 0.7),
        yaw: 0.3,
    };
    // Its box, not its old mesh, is its body.
    cabinet.mesh = None;
    cabinet.body = None;
    scene
}

fn small() -> CameraPose {
    CameraPose {
        width: 24,
        height: 16,
        ..CameraPose::DEFAULT
    }
}

#[test]
fn the_default_camera_stands_over_free_floor_outside_every_object() {
    let scene = home_with_a_cabinet_at_the_centre();
    let old = default_eye(&scene);
    let cabinet = scene.objects.last().unwrap().obb;
    assert!(
        cabinet.contains(old, 0.0),
        "the old eye {old} is in the cabinet"
    );

    let camera = CameraSource::Pose(small()).camera(&scene).unwrap();
    let eye = camera.position;
    for o in &scene.objects {
        assert!(!o.obb.contains(eye, 0.0), "{eye} is inside {}", o.ins_id);
    }
    let (grid, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    let (i, j) = grid.cell_at(eye.truncate()).unwrap();
    assert_eq!(grid.cells[grid.index(i, j)], FREE, "{eye}");
    assert_eq!(eye.z, 1.2);
    // Beside the cabinet, not rooms away: its half diagonal plus the clearance sought.
    let reach = Vec2::new(0.8, 0.5).length() + 0.5 + grid.cell;
    assert!(eye.truncate().distance(old.truncate()) <= reach, "{eye}");

    // The render records the eye, and how it was chosen.
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("scene");
    scene.save(&folder, SplatLayout::Standard).unwrap();
    let settings = RenderSettings {
        camera: CameraSource::Pose(small()),
        ..RenderSettings::new(&folder)
    };
    let out = dir.path().join("render");
    let report = render_to_folder(&settings, &out, false, &mut |_| {}).unwrap();
    // The scene as the render loaded it (its meshes went through OBJ text).
    let (loaded, _) = Scene::load(&folder).unwrap();
    let expected = free_default_eye(&loaded);
    assert_eq!(report.default_eye.as_ref(), Some(&expected));
    assert_eq!(expected.target, default_eye(&loaded).to_array());
    assert_eq!(
        (expected.grid, &expected.warning),
        (Some("geometry"), &None)
    );
    assert!(
        Vec3::from(expected.position).distance(eye) <= grid.cell,
        "{eye}"
    );
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("render.json")).unwrap()).unwrap();
    assert_eq!(record["default_eye"]["grid"], "geometry");
    let c2w = &record["camera"]["c2w_row_major"];
    let translation: Vec<f32> = (0..3).map(|r| c2w[r][3].as_f64().unwrap() as f32).collect();
    assert_eq!(translation, expected.position);

    // A position given is taken as it is, and nothing is recorded as chosen.
    let given = CameraPose {
        position: Some(old),
        ..small()
    };
    let (camera, chosen) = given.resolve(&scene).unwrap();
    assert_eq!((camera.position, chosen), (old, None));
}

#[test]
fn a_scene_without_a_navigation_grid_keeps_the_old_point_and_says_so() {
    let mut scene = home_with_a_cabinet_at_the_centre();
    // Nothing tells free space: no rooms, no map, no geometry, no Gaussians.
    scene.floorplan = Floorplan::default();
    scene.objects.clear();
    scene.occupancy = None;
    scene.structure_mesh = None;
    scene.gaussians = Gaussians::default();
    let chosen = free_default_eye(&scene);
    assert_eq!(chosen.position, default_eye(&scene).to_array());
    assert_eq!(chosen.position, chosen.target);
    assert_eq!(chosen.grid, None);
    let warning = chosen.warning.unwrap();
    assert!(warning.starts_with("no navigation grid"), "{warning}");
}
