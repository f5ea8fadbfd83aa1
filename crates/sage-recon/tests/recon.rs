//! The reconstruction pipeline against independent oracles: budget splits recomputed from the
//! floorplan, distances and depths by brute force over every triangle, a box face of known
//! colour, and cameras read back from `transforms.json` the way nerfstudio reads them.

use glam::{Mat4, Vec2, Vec3, Vec4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{InstanceId, Obb, Polygon2};
use sage_recon::bvh::{point_triangle_distance_sq, ray_triangle};
use sage_recon::export::{
    ExportView, POINTS_FILE, TRANSFORMS_FILE, Transforms, read_transforms, transforms_for,
    write_points_ply, write_transforms,
};
use sage_recon::plan::{PLAN_FILE, PlanSettings, Policy, make_plan};
use sage_recon::raster::{pixel_ray, render_view, to_u8};
use sage_recon::surfaces::{SceneSurfaces, SurfaceKind, shade};
use sage_recon::sweep::{Baseline, SweepParams, Tier, perimeter, sweep};
use sage_recon::views::{self, Manifest};
use sage_recon::volume::{TEMPLATE, VolumeParams, volume};
use sage_recon::{PoseTag, apportion};
use sage_scene::{Floorplan, Object, Room, Scene};
use sage_splat::{Camera, Intrinsics};
use sage_synth::{SynthConfig, generate};
use std::sync::OnceLock;

fn scene() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        generate(&SynthConfig {
            seed: 7,
            rooms: 3,
            objects: 25,
            gaussians: 1000,
            ..SynthConfig::default()
        })
        .unwrap()
    })
}

fn surfaces() -> &'static SceneSurfaces {
    static S: OnceLock<SceneSurfaces> = OnceLock::new();
    S.get_or_init(|| SceneSurfaces::build(scene(), None).unwrap())
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn sweep_splits_the_budget_by_perimeter_with_the_paper_tiers() {
    let s = scene();
    let params = SweepParams::default();
    let budget = 905;
    let out = sweep(&s.floorplan, budget, 3, &params).unwrap();
    assert!(
        out.rings.len() >= s.floorplan.rooms.len(),
        "every room has a ring"
    );
    // The split, recomputed from the ring perimeters.
    let per: Vec<f64> = out
        .rings
        .iter()
        .map(|r| perimeter(&r.polygon) as f64)
        .collect();
    let total: f64 = per.iter().sum();
    let placements = budget / 9;
    for (r, p) in out.rings.iter().zip(&per) {
        let quota = p / total * placements as f64;
        assert!(
            (r.placements as f64 - quota).abs() < 1.0,
            "{} vs {quota}",
            r.placements
        );
    }
    assert_eq!(
        out.rings.iter().map(|r| r.placements).sum::<usize>(),
        placements
    );
    assert_eq!(out.poses.len(), 9 * placements);
    let height = s.floorplan.ceiling_height();
    let mut at = 0;
    for r in &out.rings {
        let ring_poses = &out.poses[at..at + 9 * r.placements];
        at += 9 * r.placements;
        let inner_t = r.ring as f32 / params.offsets.len() as f32;
        for p in ring_poses {
            let PoseTag::Sweep {
                ring,
                tier,
                baseline,
            } = p.tag
            else {
                panic!("sweep pose with a volume tag")
            };
            assert_eq!((ring, p.room), (r.ring, r.room));
            let pitch = p.pitch.to_degrees();
            let z = p.position.z;
            match (tier, r.ring) {
                (Tier::Low, 0) => assert!(close(z, 0.15, 1e-5) && close(pitch, 30.0, 1e-3)),
                (Tier::High, 0) => {
                    assert!(close(z, height - 0.5, 1e-5) && close(pitch, -30.0, 1e-3))
                }
                (Tier::Mid, _) => assert!(close(z, height / 2.0, 1e-5) && close(pitch, 0.0, 1e-6)),
                (Tier::Low, _) => {
                    assert!(close(pitch, 15.0, 1e-3));
                    assert!(close(z, 0.15 + (height / 2.0 - 0.15) * inner_t, 1e-4));
                }
                (Tier::High, _) => {
                    assert!(close(pitch, -15.0, 1e-3));
                    let high = height - 0.5;
                    assert!(close(z, high + (height / 2.0 - high) * inner_t, 1e-4));
                }
            }
            // The centre baseline stands on the ring; the others are shifted along the camera's
            // right axis by the baseline; all look inwards.
            let xy = p.position.truncate();
            let right = Vec2::new(p.yaw.sin(), -p.yaw.cos());
            let on_ring = xy - right * baseline.sign() * params.baseline;
            assert!(
                r.polygon.distance_to_boundary(on_ring) < 1e-3,
                "{baseline:?}"
            );
            let forward = Vec2::new(p.yaw.cos(), p.yaw.sin());
            assert!(r.polygon.contains(on_ring + forward * 0.05));
            assert!(!r.polygon.contains(on_ring - forward * 0.05));
        }
        // Each placement has all nine tier × baseline combinations.
        for chunk in ring_poses.chunks(9) {
            let mut seen: Vec<(Tier, Baseline)> = chunk
                .iter()
                .map(|p| match p.tag {
                    PoseTag::Sweep { tier, baseline, .. } => (tier, baseline),
                    PoseTag::Volume { .. } => unreachable!(),
                })
                .collect();
            seen.sort();
            seen.dedup();
            assert_eq!(seen.len(), 9);
        }
    }
}

#[test]
fn volume_splits_positions_by_room_volume_with_one_perturbation_each() {
    let s = scene();
    let params = VolumeParams::default();
    let out = volume(s, 300, 5, &params).unwrap();
    let height = s.floorplan.ceiling_height();
    let vols: Vec<f64> = s
        .floorplan
        .rooms
        .iter()
        .map(|r| (r.profile.area() * height) as f64)
        .collect();
    assert_eq!(out.requested, apportion(50, &vols));
    assert_eq!(
        out.placed, out.requested,
        "synthetic rooms have free volume"
    );
    assert_eq!(out.poses.len(), 300);
    for (k, views) in out.poses.chunks(6).enumerate() {
        let p0 = views[0].position;
        let room = &s.floorplan.rooms[views[0].room].profile;
        assert!(room.contains(p0.truncate()));
        assert!(room.distance_to_boundary(p0.truncate()) >= params.wall_margin - 1e-5);
        assert!(p0.z >= params.floor_margin && p0.z <= height - params.ceiling_margin);
        assert!(s.objects.iter().all(|o| !o.obb.contains(p0, 0.0)));
        let dyaw = sage_core::wrap_angle(views[0].yaw - TEMPLATE[0].0.to_radians());
        let dpitch = views[0].pitch - TEMPLATE[0].1.to_radians();
        assert!(dyaw.abs() <= params.yaw_jitter_deg.to_radians() + 1e-5);
        assert!(dpitch.abs() <= params.pitch_jitter_deg.to_radians() + 1e-5);
        for (v, p) in views.iter().enumerate() {
            assert_eq!(
                p.tag,
                PoseTag::Volume {
                    position: k,
                    view: v
                }
            );
            assert_eq!(p.position, p0);
            let (ty, tp) = TEMPLATE[v];
            assert!(sage_core::wrap_angle(p.yaw - ty.to_radians() - dyaw).abs() < 1e-4);
            assert!((p.pitch - tp.to_radians() - dpitch).abs() < 1e-5);
        }
    }
    assert_eq!(
        out.poses,
        volume(s, 300, 5, &params).unwrap().poses,
        "same seed"
    );
    assert_ne!(out.poses, volume(s, 300, 6, &params).unwrap().poses);
}

#[test]
fn safety_filter_agrees_with_brute_force() {
    let s = scene();
    let surf = surfaces();
    for policy in [Policy::Sweep, Policy::Volume] {
        let settings = PlanSettings {
            policy,
            budget: 180,
            seed: 1,
            // Above the low tier's 150 mm, so the sweep drops some poses.
            safety_threshold: 0.3,
            ..PlanSettings::default()
        };
        let plan = make_plan(s, "scene", surf, &settings).unwrap();
        assert!(
            !plan.views.is_empty() && !plan.dropped.is_empty(),
            "{policy:?}"
        );
        let brute = |p: [f32; 3]| {
            surf.triangles
                .iter()
                .map(|t| point_triangle_distance_sq(Vec3::from_array(p), t))
                .fold(f32::INFINITY, f32::min)
                .sqrt()
        };
        for v in &plan.views {
            let d = brute(v.position);
            assert!(
                d >= 0.3 && close(v.clearance, d, 1e-5),
                "kept {} at {d}",
                v.tag
            );
        }
        for v in &plan.dropped {
            let d = brute(v.position);
            assert!(
                d < 0.3 && close(v.clearance, d, 1e-5),
                "dropped {} at {d}",
                v.tag
            );
        }
    }
}

#[test]
fn every_surface_kind_is_present_and_boxes_stand_in_for_missing_meshes() {
    let surf = surfaces();
    for k in [SurfaceKind::Floor, SurfaceKind::Wall, SurfaceKind::Ceiling] {
        assert!(surf.kinds.contains(&k), "{k:?}");
    }
    let mut s = scene().clone();
    s.objects[0].mesh = None;
    let boxed = SceneSurfaces::build(&s, None).unwrap();
    let n = boxed
        .kinds
        .iter()
        .filter(|k| **k == SurfaceKind::Object(0))
        .count();
    assert_eq!(n, 12);
}

#[test]
fn rendered_depth_matches_brute_force_rays() {
    let s = scene();
    let surf = surfaces();
    let bvh = surf.bvh();
    let plan = make_plan(
        s,
        "scene",
        surf,
        &PlanSettings {
            budget: 60,
            policy: Policy::Volume,
            ..PlanSettings::default()
        },
    )
    .unwrap();
    let k = Intrinsics::from_hfov(48, 36, 90.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for v in plan.views.iter().take(4) {
        let cam = v.camera(k);
        let img = render_view(surf, &bvh, &cam);
        for _ in 0..25 {
            let (i, j) = (rng.random_range(0..48), rng.random_range(0..36));
            let dir = pixel_ray(&cam, i, j);
            let best = surf
                .triangles
                .iter()
                .enumerate()
                .filter_map(|(n, t)| {
                    ray_triangle(cam.position, dir, t)
                        .filter(|t| *t > cam.near && *t <= cam.far)
                        .map(|t| (t, n))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let px = j * 48 + i;
            match best {
                Some((t, n)) => {
                    assert!(close(img.depth[px], t, 1e-5), "{} vs {t}", img.depth[px]);
                    assert_eq!(&img.rgb[px * 3..px * 3 + 3], &surf.colors[n].map(to_u8));
                    // The depth is along the optical axis: the hit point's camera z.
                    let hit = cam.position + dir * t;
                    assert!(close(cam.world_to_camera(hit).z, t, 1e-4));
                }
                None => assert_eq!(img.depth[px], 0.0),
            }
        }
    }
}

fn box_scene(color: &str) -> Scene {
    let obb = Obb {
        center: Vec3::new(3.0, 0.0, 1.0),
        half_extents: Vec3::new(0.5, 1.0, 1.0),
        yaw: 0.0,
    };
    let mut scene = Scene {
        name: "box".into(),
        gaussians: sage_scene::Gaussians::new(0).unwrap(),
        objects: vec![Object {
            id: InstanceId(1),
            ins_id: "1".into(),
            label: "Cabinet".into(),
            category: "cabinet".into(),
            obb,
            room: None,
            attributes: sage_scene::Attributes {
                color: Some(color.into()),
                ..Default::default()
            },
            role: Default::default(),
            rigid_body: Default::default(),
            mesh: None,
            body: None,
        }],
        floorplan: Floorplan {
            rooms: vec![Room {
                profile: Polygon2::new(vec![
                    Vec2::new(-1.0, -3.0),
                    Vec2::new(5.0, -3.0),
                    Vec2::new(5.0, 3.0),
                    Vec2::new(-1.0, 3.0),
                ]),
                room_type: "Storage".into(),
            }],
            ..Default::default()
        },
        occupancy: None,
        structure_mesh: None,
        structure_body: None,
        instances: Default::default(),
    };
    scene.finish();
    scene
}

#[test]
fn a_red_box_face_renders_red_under_the_fixed_light() {
    let scene = box_scene("red");
    let surf = SceneSurfaces::build(&scene, None).unwrap();
    let bvh = surf.bvh();
    // Looking along +X at the face x = 2.5, whose outward normal is −X.
    let cam = Camera::from_yaw_pitch(
        Intrinsics::from_hfov(32, 32, 60.0).unwrap(),
        Vec3::new(0.0, 0.0, 1.0),
        0.0,
        0.0,
    );
    let img = render_view(&surf, &bvh, &cam);
    let expected = shade(sage_scene::vocabulary::color_rgb("red").unwrap(), -Vec3::X).map(to_u8);
    for (i, j) in [(15, 15), (16, 16), (10, 20)] {
        let px = j * 32 + i;
        assert_eq!(&img.rgb[px * 3..px * 3 + 3], &expected);
        assert!(close(img.depth[px], 2.5, 1e-5));
    }
    // Beyond the box's edge there is nothing: black and no depth.
    let far_up = Camera::from_yaw_pitch(cam.intrinsics, Vec3::new(0.0, 0.0, 1.0), 0.0, 1.2);
    let img = render_view(&surf, &bvh, &far_up);
    assert_eq!(&img.rgb[..3], &[0, 0, 0]);
    assert_eq!(img.depth[0], 0.0);
}

fn plan_cameras(n: usize) -> Vec<Camera> {
    let plan = make_plan(
        scene(),
        "scene",
        surfaces(),
        &PlanSettings {
            budget: 90,
            ..PlanSettings::default()
        },
    )
    .unwrap();
    let k = Intrinsics {
        width: 64,
        height: 48,
        fx: 40.5,
        fy: 41.25,
        cx: 31.7,
        cy: 24.2,
    };
    plan.views.iter().take(n).map(|v| v.camera(k)).collect()
}

#[test]
fn transforms_json_round_trips_cameras_exactly() {
    let cams = plan_cameras(20);
    let views: Vec<ExportView> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| ExportView {
            camera: *c,
            rgb: format!("views/rgb_{i:04}.png"),
            depth: Some(format!("views/depth_{i:04}.png")),
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("transforms.json");
    write_transforms(&path, &transforms_for(&views).unwrap()).unwrap();
    let back = read_transforms(&path).unwrap();
    let read = back.cameras().unwrap();
    assert_eq!(read.len(), cams.len());
    for (a, b) in cams.iter().zip(&read) {
        assert_eq!(a.c2w().to_cols_array(), b.c2w().to_cols_array());
        assert_eq!(a.intrinsics, b.intrinsics);
    }
    assert_eq!(
        back.val_filenames,
        [
            "views/rgb_0000.png",
            "views/rgb_0008.png",
            "views/rgb_0016.png"
        ]
    );
    assert_eq!(back.train_filenames.len(), 17);
    // A frame that is not a rigid motion is an error naming it.
    let mut bad = back.clone();
    bad.frames[3].transform_matrix[0][0] = 2.0;
    let e = bad.cameras().unwrap_err().to_string();
    assert!(e.contains("frames[3].transform_matrix"), "{e}");
}

#[test]
fn an_export_without_points_removes_the_points_it_owns_and_no_others() {
    let k = Intrinsics::from_hfov(32, 24, 90.0).unwrap();
    let views: Vec<ExportView> = (0..3)
        .map(|i| ExportView {
            camera: Camera::from_yaw_pitch(k, Vec3::new(i as f32, 0.0, 1.2), 0.0, 0.0),
            rgb: format!("views/rgb_{i:04}.png"),
            depth: None,
        })
        .collect();
    let without = transforms_for(&views).unwrap();
    let with = Transforms {
        ply_file_path: Some(POINTS_FILE.to_string()),
        ..without.clone()
    };
    let samples = [(Vec3::ZERO, [0.5; 3], Vec3::Z)];
    let names_points = |path: &std::path::Path| {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v.get("ply_file_path").is_some()
    };

    // An export with points, then one without (`--points 0`): the old points go, and the new
    // index names none.
    let dir = tempfile::tempdir().unwrap();
    let (path, points) = (
        dir.path().join(TRANSFORMS_FILE),
        dir.path().join(POINTS_FILE),
    );
    write_points_ply(&points, &samples).unwrap();
    assert_eq!(write_transforms(&path, &with).unwrap(), None);
    assert!(points.is_file() && names_points(&path));
    // Rewritten with its points, they stay.
    assert_eq!(write_transforms(&path, &with).unwrap(), None);
    assert!(points.is_file());
    assert_eq!(
        write_transforms(&path, &without).unwrap().as_deref(),
        Some(points.as_path()),
        "the removal is reported"
    );
    assert!(
        !points.exists(),
        "stale points beside an export without them"
    );
    assert!(!names_points(&path));
    assert_eq!(read_transforms(&path).unwrap(), without);

    // A reconstruction folder (it holds the plan, whose claim reserves the points for the
    // export) whose last export was cut short after its points, before its index: they go too.
    let recon = tempfile::tempdir().unwrap();
    std::fs::write(recon.path().join(PLAN_FILE), "{}").unwrap();
    write_points_ply(&recon.path().join(POINTS_FILE), &samples).unwrap();
    assert!(
        write_transforms(&recon.path().join(TRANSFORMS_FILE), &without)
            .unwrap()
            .is_some()
    );
    assert!(!recon.path().join(POINTS_FILE).exists());

    // Elsewhere, points that no index of the export named are the user's and stay.
    let user = tempfile::tempdir().unwrap();
    let (path, points) = (
        user.path().join(TRANSFORMS_FILE),
        user.path().join(POINTS_FILE),
    );
    write_points_ply(&points, &samples).unwrap();
    write_transforms(&path, &without).unwrap();
    let elsewhere = Transforms {
        ply_file_path: Some("../points3d.ply".to_string()),
        ..without.clone()
    };
    write_transforms(&path, &elsewhere).unwrap();
    assert_eq!(write_transforms(&path, &without).unwrap(), None);
    assert!(points.is_file());

    // An earlier index over the JSON limit (a sparse file) is not read whole to find out
    // whether it named the points: the export stops, naming it and the limit, and leaves both.
    std::fs::File::create(&path)
        .unwrap()
        .set_len((1024 << 20) + 1)
        .unwrap();
    let e = write_transforms(&path, &without).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: file size: 1024.1 MB", path.display()))
            && e.contains("SAGE3D_MAX_JSON_MB"),
        "{e}"
    );
    assert!(points.is_file());
}

#[test]
fn nerfstudio_reading_of_transform_matrix_projects_to_our_pixels() {
    let cams = plan_cameras(12);
    let t = transforms_for(
        &cams
            .iter()
            .map(|c| ExportView {
                camera: *c,
                rgb: "x.png".into(),
                depth: None,
            })
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for (cam, frame) in cams.iter().zip(&t.frames) {
        // nerfstudio: c2w in OpenGL axes; a point in front has negative camera z, and image v
        // grows downwards while camera y points up.
        let c2w = Mat4::from_cols_array_2d(&frame.transform_matrix).transpose();
        let w2c = c2w.inverse();
        for _ in 0..10 {
            let ahead = cam.rotation
                * Vec3::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.4..0.4),
                    1.0,
                );
            let x = cam.position + ahead * rng.random_range(0.5..5.0);
            let p = w2c * Vec4::new(x.x, x.y, x.z, 1.0);
            assert!(p.z < 0.0, "in front means -z in OpenGL axes");
            let u = t.fl_x * p.x / -p.z + t.cx;
            let v = t.fl_y * -p.y / -p.z + t.cy;
            let (eu, ev) = cam.project(cam.world_to_camera(x));
            assert!(
                close(u, eu, 1e-3) && close(v, ev, 1e-3),
                "({u}, {v}) vs ({eu}, {ev})"
            );
        }
    }
}

#[test]
fn plans_and_images_are_the_same_for_a_seed_whatever_the_threads() {
    let settings = PlanSettings {
        budget: 120,
        seed: 4,
        policy: Policy::Volume,
        ..PlanSettings::default()
    };
    let a = make_plan(scene(), "scene", surfaces(), &settings).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one.install(|| make_plan(scene(), "scene", surfaces(), &settings).unwrap());
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
    let k = Intrinsics::from_hfov(40, 30, 90.0).unwrap();
    let bvh = surfaces().bvh();
    let cam = a.views[0].camera(k);
    let img = render_view(surfaces(), &bvh, &cam);
    let img1 = one.install(|| render_view(surfaces(), &bvh, &cam));
    assert_eq!(img, img1);
    let other = make_plan(
        scene(),
        "scene",
        surfaces(),
        &PlanSettings {
            seed: 5,
            ..settings
        },
    )
    .unwrap();
    assert_ne!(a.views, other.views);
}

#[test]
fn obj_materials_colour_their_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = box_scene("red");
    scene.objects[0].mesh = Some(sage_recon::surfaces::obb_mesh(&scene.objects[0].obb));
    scene
        .save(dir.path(), sage_scene::SplatLayout::Standard)
        .unwrap();
    // Rewrite the object's OBJ as two parts, the second with a blue material.
    let m = scene.objects[0].mesh.as_ref().unwrap();
    let mut obj = String::from("mtllib box.mtl\no bottom\n");
    for p in &m.positions {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for (k, t) in m.triangles.iter().enumerate() {
        if k == 4 {
            obj += "o rest\nusemtl blue\n";
        }
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let meshes = dir.path().join("meshes");
    std::fs::write(meshes.join("1.obj"), obj).unwrap();
    std::fs::write(meshes.join("box.mtl"), "newmtl blue\nKd 0.1 0.2 0.9\n").unwrap();
    let (loaded, _) = Scene::load(dir.path()).unwrap();
    let with = SceneSurfaces::build(&loaded, Some(dir.path())).unwrap();
    let without = SceneSurfaces::build(&loaded, None).unwrap();
    let red = sage_scene::vocabulary::color_rgb("red").unwrap();
    for t in 0..12 {
        let n = with.normals[t];
        assert_eq!(without.colors[t], shade(red, n));
        let expected = if t < 4 { red } else { [0.1, 0.2, 0.9] };
        assert_eq!(with.colors[t], shade(expected, n), "triangle {t}");
    }
}

#[test]
fn plan_files_round_trip_and_bad_ones_name_the_field() {
    let plan = make_plan(
        scene(),
        "scene",
        surfaces(),
        &PlanSettings {
            budget: 45,
            ..PlanSettings::default()
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    plan.save(&path).unwrap();
    assert_eq!(sage_recon::Plan::load(&path).unwrap(), plan);
    let mut bad = plan.clone();
    bad.views.swap(0, 1);
    bad.save(&path).unwrap();
    let e = sage_recon::Plan::load(&path).unwrap_err().to_string();
    assert!(e.contains("plan.json") && e.contains("views[0].id"), "{e}");
    std::fs::write(&path, "{\"format\": 3}").unwrap();
    let e = sage_recon::Plan::load(&path).unwrap_err().to_string();
    assert!(e.contains("plan.json") && e.contains("line 1"), "{e}");
    // Over the JSON limit (one byte over the default, a sparse file): refused from its size.
    std::fs::File::create(&path)
        .unwrap()
        .set_len((1024 << 20) + 1)
        .unwrap();
    let e = sage_recon::Plan::load(&path).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!(
            "{}: file size: 1024.1 MB, over the limit",
            path.display()
        )) && e.contains("SAGE3D_MAX_JSON_MB"),
        "{e}"
    );
}

#[test]
fn views_of_a_replaced_plan_are_refused_with_the_same_advice_everywhere() {
    let make = |budget| {
        make_plan(
            scene(),
            "scene",
            surfaces(),
            &PlanSettings {
                budget,
                ..PlanSettings::default()
            },
        )
        .unwrap()
    };
    let (old, new) = (make(30), make(45));
    let dir = tempfile::tempdir().unwrap();
    views::prepare(dir.path(), &Manifest::new(&old, 24, 16).unwrap()).unwrap();
    // A rerun plan: rendering refuses the old views, and so does exporting (or fitting), and
    // both say what works: remove the folder, then render again.
    let render = views::prepare(dir.path(), &Manifest::new(&new, 24, 16).unwrap())
        .unwrap_err()
        .to_string();
    let export = views::export_views(dir.path(), &new)
        .unwrap_err()
        .to_string();
    for e in [&render, &export] {
        assert!(
            e.contains("rendered for another plan")
                && e.contains("remove the views folder, then run `sage3d recon render` again"),
            "{e}"
        );
    }
    assert_eq!(render, export);
    // Nothing was deleted: the old manifest still stands.
    assert_eq!(
        views::read_manifest(dir.path()).unwrap(),
        Some(Manifest::new(&old, 24, 16).unwrap())
    );
    // Views rendered from one scene are not taken for another's; a folder rendered before the
    // scene was recorded resumes with any.
    let from = |scene: &str| Manifest {
        scene: Some(scene.into()),
        ..Manifest::new(&old, 24, 16).unwrap()
    };
    views::prepare(dir.path(), &from("home")).unwrap();
    let recorded = tempfile::tempdir().unwrap();
    views::prepare(recorded.path(), &from("home")).unwrap();
    views::prepare(recorded.path(), &from("home")).unwrap();
    let e = views::prepare(recorded.path(), &from("fitted"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("views already rendered from scene 'home'")
            && e.contains("remove the views folder"),
        "{e}"
    );
}

#[test]
fn a_plan_that_keeps_no_camera_is_an_error_naming_what_to_change() {
    let plan = |policy, budget, safety_threshold| {
        make_plan(
            scene(),
            "scene",
            surfaces(),
            &PlanSettings {
                policy,
                budget,
                safety_threshold,
                ..PlanSettings::default()
            },
        )
    };
    for policy in [Policy::Sweep, Policy::Volume] {
        let e = plan(policy, 0, 0.1).unwrap_err().to_string();
        assert!(
            e.contains("`budget` 0 placed no camera") && e.contains("raise it"),
            "{policy:?}: {e}"
        );
        // Every camera of a room is nearer a wall than 100 m.
        let e = plan(policy, 60, 100.0).unwrap_err().to_string();
        assert!(
            e.contains("within the safety threshold (100 m)") && e.contains("`budget`"),
            "{policy:?}: {e}"
        );
        assert!(!plan(policy, 60, 0.1).unwrap().views.is_empty());
    }
}
