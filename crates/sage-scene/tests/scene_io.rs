//! A scene folder written by `Scene::save` loads back as the same scene (within the documented
//! precision of the compressed layout), and loading reports what it found.

use sage_scene::{Scene, SplatLayout};
use sage_synth::{SynthConfig, generate};

fn small() -> SynthConfig {
    SynthConfig {
        seed: 9,
        rooms: 4,
        objects: 40,
        gaussians: 40_000,
        ..SynthConfig::default()
    }
}

#[test]
fn save_then_load_round_trips() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let (back, report) = Scene::load(dir.path()).unwrap();
    assert_eq!(
        report.splat_format,
        Some(sage_scene::splats::Format::Ply(SplatLayout::Compressed))
    );
    assert!(report.missing.is_empty(), "{report:?}");
    assert_eq!(report.meshes, scene.objects.len());
    assert_eq!(back.floorplan, scene.floorplan);
    assert_eq!(back.occupancy, scene.occupancy);
    assert_eq!(back.structure_mesh, scene.structure_mesh);
    assert_eq!(back.instances, scene.instances);
    assert_eq!(back.objects.len(), scene.objects.len());
    for (a, b) in scene.objects.iter().zip(&back.objects) {
        assert_eq!(
            (&a.ins_id, &a.label, &a.category, a.id, a.room),
            (&b.ins_id, &b.label, &b.category, b.id, b.room)
        );
        assert_eq!(
            (&a.attributes, a.role, a.rigid_body),
            (&b.attributes, b.role, b.rigid_body)
        );
        assert!(
            (a.obb.center - b.obb.center).length() < 1e-4,
            "{}",
            a.ins_id
        );
        assert!(
            (a.obb.half_extents - b.obb.half_extents)
                .abs()
                .max_element()
                < 1e-4
        );
        assert_eq!(a.mesh, b.mesh);
    }
    assert_eq!(back.gaussians.len(), scene.gaussians.len());
    let same = scene
        .gaussians
        .instances
        .iter()
        .zip(&back.gaussians.instances)
        .filter(|(a, b)| a == b)
        .count();
    assert!(
        same as f64 >= 0.99 * scene.gaussians.len() as f64,
        "instance ids agree for {same} of {}",
        scene.gaussians.len()
    );
}

#[test]
fn standard_layout_keeps_gaussians_exactly() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Standard).unwrap();
    let (back, report) = Scene::load(dir.path()).unwrap();
    assert_eq!(
        report.splat_format,
        Some(sage_scene::splats::Format::Ply(SplatLayout::Standard))
    );
    assert_eq!(back.gaussians.positions, scene.gaussians.positions);
    assert_eq!(back.gaussians.log_scales, scene.gaussians.log_scales);
    assert_eq!(back.gaussians.sh_dc, scene.gaussians.sh_dc);
    assert_eq!(back.gaussians.instances, scene.gaussians.instances);
}

#[test]
fn a_folder_with_only_labels_loads_and_reports_the_rest_missing() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    for f in [
        "3dgs_compressed.ply",
        "structure.json",
        "objects.json",
        "occupancy.png",
        "occupancy.json",
    ] {
        std::fs::remove_file(dir.path().join(f)).unwrap();
    }
    std::fs::remove_dir_all(dir.path().join("meshes")).unwrap();
    let (back, report) = Scene::load(dir.path()).unwrap();
    assert_eq!(back.objects.len(), scene.objects.len());
    assert!(back.gaussians.is_empty());
    for f in ["3dgs_compressed.ply", "structure.json", "occupancy.png"] {
        assert!(
            report.missing.iter().any(|m| m == f),
            "{f} not reported missing: {report:?}"
        );
    }
}

#[test]
fn a_folder_a_scene_writer_left_unfinished_is_refused_until_it_finishes() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    // What a `recon fit` killed while writing leaves: its record marked unfinished, the
    // Gaussians and the labels, and nothing else.
    sage_io::run::mark_unfinished(out, sage_scene::scene::writers::FIT, Some(0)).unwrap();
    scene.save(out, SplatLayout::Compressed).unwrap();
    for f in [
        "structure.json",
        "objects.json",
        "occupancy.png",
        "occupancy.json",
    ] {
        std::fs::remove_file(out.join(f)).unwrap();
    }
    std::fs::remove_dir_all(out.join("meshes")).unwrap();
    for load in [Scene::load, Scene::load_for_rendering] {
        let e = load(out).unwrap_err().to_string();
        assert!(
            e.contains(&out.display().to_string())
                && e.contains("`sage3d recon fit` did not finish")
                && e.contains("rerun"),
            "{e}"
        );
    }
    // A command that writes no scene, left unfinished beside one, does not unmake it.
    sage_io::run::mark_unfinished(out, "render", None).unwrap();
    Scene::load(out).unwrap();
    // Nor does a scene writer's finished record.
    let finished = serde_json::json!({});
    sage_io::run::write_run_record(out, sage_scene::scene::writers::FIT, Some(0), finished)
        .unwrap();
    Scene::load(out).unwrap();
}

#[test]
fn rendering_needs_a_gaussian_file_that_holds_gaussians() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let (loaded, _) = Scene::load_for_rendering(dir.path()).unwrap();
    assert_eq!(loaded.gaussians.len(), scene.gaussians.len());
    let ply = dir.path().join("3dgs_compressed.ply");
    std::fs::remove_file(&ply).unwrap();
    // Loading for anything else still works, and reports the file missing.
    let (_, report) = Scene::load(dir.path()).unwrap();
    assert!(report.missing.iter().any(|m| m == "3dgs_compressed.ply"));
    let e = Scene::load_for_rendering(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&format!("{}: missing", ply.display()))
            && e.contains("needs the scene's Gaussians"),
        "{e}"
    );
    // A file holding none is no better than no file.
    let empty = sage_scene::Gaussians::new(0).unwrap();
    sage_scene::ply::write_splats_file(&ply, &empty, SplatLayout::Standard).unwrap();
    let e = Scene::load_for_rendering(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&format!("{}: holds no Gaussians", ply.display())),
        "{e}"
    );
}

#[test]
fn a_directory_by_the_name_of_a_scene_file_is_an_error_naming_it() {
    let scene = generate(&small()).unwrap();
    for name in [
        "3dgs_compressed.ply",
        "labels.json",
        "structure.json",
        "objects.json",
        "occupancy.png",
        "meshes/structure.obj",
    ] {
        let dir = tempfile::tempdir().unwrap();
        scene.save(dir.path(), SplatLayout::Compressed).unwrap();
        let p = dir.path().join(name);
        if p.exists() {
            std::fs::remove_file(&p).unwrap();
        }
        std::fs::create_dir(&p).unwrap();
        let e = Scene::load(dir.path()).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "{}: a directory, not a file: the scene needs a file by this name, or none",
                p.display()
            )
        );
    }
    // A mesh of an object found by its id, and the mesh folder itself.
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let with_mesh = scene.objects.iter().find(|o| o.mesh.is_some()).unwrap();
    let mesh = dir.path().join(format!("meshes/{}.obj", with_mesh.ins_id));
    std::fs::remove_file(&mesh).unwrap();
    std::fs::create_dir(&mesh).unwrap();
    let e = Scene::load(dir.path()).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: a directory", mesh.display())),
        "{e}"
    );
    std::fs::remove_dir_all(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes"), "").unwrap();
    let e = Scene::load(dir.path()).unwrap_err().to_string();
    assert!(e.contains("meshes: a file, not a folder"), "{e}");
}

#[test]
fn scene_json_files_may_begin_with_a_byte_order_mark_and_are_refused_over_their_limit() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let (plain, _) = Scene::load(dir.path()).unwrap();
    for f in [
        "labels.json",
        "structure.json",
        "objects.json",
        "occupancy.json",
    ] {
        let p = dir.path().join(f);
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, format!("\u{feff}{text}")).unwrap();
    }
    let (with_marks, report) = Scene::load(dir.path()).unwrap();
    assert!(
        with_marks == plain,
        "the byte-order marks changed the scene"
    );
    assert!(report.missing.is_empty(), "{report:?}");
    // 64 MB and a byte of structure.json (a sparse file: nothing is written), refused from its
    // size alone.
    let p = dir.path().join("structure.json");
    std::fs::File::create(&p)
        .unwrap()
        .set_len((64 << 20) + 1)
        .unwrap();
    let e = Scene::load(dir.path()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}: file size: 64.1 MB, over the limit of 64 MB on a scene JSON file; set the \
             environment variable SAGE3D_MAX_SCENE_JSON_MB to raise it",
            p.display()
        )
    );
}

#[test]
fn an_oversized_run_record_is_refused_naming_the_file_and_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = generate(&SynthConfig {
        rooms: 2,
        objects: 4,
        gaussians: 4_000,
        ..small()
    })
    .unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    // Every load reads the run record (to refuse a half-written folder): one byte over the
    // default limit (a sparse file: nothing is written) is refused from its size, not read.
    let record = dir.path().join(sage_io::RUN_RECORD);
    std::fs::File::create(&record)
        .unwrap()
        .set_len((1024 << 20) + 1)
        .unwrap();
    let e = Scene::load(dir.path()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}: file size: 1024.1 MB, over the limit of 1024 MB on a JSON file; set the \
             environment variable SAGE3D_MAX_JSON_MB to raise it",
            record.display()
        )
    );
    // A record of the right size loads as before.
    sage_io::write_run_record(dir.path(), "scene synth", Some(7), serde_json::json!({})).unwrap();
    assert!(Scene::load(dir.path()).is_ok());
}

#[test]
fn not_a_folder_is_an_error() {
    let e = Scene::load(std::path::Path::new("no/such/scene"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no/such/scene does not exist"), "{e}");
    // An empty folder, or one of other files, is not an empty scene.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "hello").unwrap();
    let e = Scene::load(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("is not a scene folder: missing 3dgs_compressed.ply (or 3dgs.ply")
            && e.contains("labels.json and structure.json"),
        "{e}"
    );
    let e = Scene::load(&dir.path().join("notes.txt"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("is not a scene folder: it is a file"), "{e}");
}

#[test]
fn objects_json_mesh_paths_are_honoured_and_checked() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let first = &scene.objects[0].ins_id;
    std::fs::create_dir(dir.path().join("collision")).unwrap();
    std::fs::rename(
        dir.path().join(format!("meshes/{first}.obj")),
        dir.path().join("collision/first.obj"),
    )
    .unwrap();
    let objects_path = dir.path().join("objects.json");
    let text = std::fs::read_to_string(&objects_path).unwrap();
    let moved = text.replacen(
        &format!("\"meshes/{first}.obj\""),
        "\"collision/first.obj\"",
        1,
    );
    assert_ne!(moved, text);
    std::fs::write(&objects_path, &moved).unwrap();
    let (back, _) = Scene::load(dir.path()).unwrap();
    assert_eq!(back.objects[0].mesh, scene.objects[0].mesh);

    std::fs::write(
        &objects_path,
        moved.replace("collision/first.obj", "collision/gone.obj"),
    )
    .unwrap();
    let e = Scene::load(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("objects.json")
            && e.contains(&format!("objects[ins_id {first}].mesh"))
            && e.contains("collision/gone.obj"),
        "{e}"
    );
}

#[test]
fn a_shuffled_standard_ply_is_loaded_in_morton_order() {
    let scene = generate(&small()).unwrap();
    let n = scene.gaussians.len() as u32;
    // Reverse the order: same Gaussians, far from Morton order.
    let reversed: Vec<u32> = (0..n).rev().collect();
    let mut shuffled = scene.clone();
    shuffled.gaussians = scene.gaussians.permuted(&reversed);
    let dir = tempfile::tempdir().unwrap();
    shuffled.save(dir.path(), SplatLayout::Standard).unwrap();
    let (back, report) = Scene::load(dir.path()).unwrap();
    assert!(report.morton_reordered);
    assert_eq!(back.gaussians.positions, scene.gaussians.positions);
    assert_eq!(back.gaussians.instances, scene.gaussians.instances);
    // Already sorted files load as they are.
    scene.save(dir.path(), SplatLayout::Standard).unwrap();
    assert!(!Scene::load(dir.path()).unwrap().1.morton_reordered);
}

#[test]
fn a_compressed_ply_with_loose_chunks_is_loaded_in_morton_order() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Compressed).unwrap();
    let (compact, report) = Scene::load(dir.path()).unwrap();
    assert!(!report.morton_reordered, "sage3d's own file is compact");
    // Every chunk's position bounds widened to the whole scene's: each chunk's Gaussians now
    // decode to places all over it, as a writer that kept a trained PLY's order leaves them.
    let path = dir.path().join("3dgs_compressed.ply");
    let mut bytes = std::fs::read(&path).unwrap();
    let body = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let chunks = compact.gaussians.len().div_ceil(256);
    let float = |b: &[u8], at: usize| f32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for c in 0..chunks {
        for k in 0..3 {
            lo[k] = lo[k].min(float(&bytes, body + 72 * c + 4 * k));
            hi[k] = hi[k].max(float(&bytes, body + 72 * c + 12 + 4 * k));
        }
    }
    for c in 0..chunks {
        for (k, v) in lo.iter().chain(&hi).enumerate() {
            let at = body + 72 * c + 4 * k;
            bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&path, &bytes).unwrap();
    let (loose, report) = Scene::load(dir.path()).unwrap();
    assert!(report.morton_reordered);
    assert_eq!(loose.gaussians.len(), compact.gaussians.len());
    assert_eq!(
        loose.gaussians.morton_order(),
        (0..loose.gaussians.len() as u32).collect::<Vec<_>>()
    );
}

/// A USDA collision file with one tetrahedron per object (named `ins_{id}`, at its box centre)
/// and one wall far from every box.
fn collision_usda(scene: &Scene) -> String {
    let mut text = String::from("#usda 1.0\n(\n    upAxis = \"Z\"\n    metersPerUnit = 1\n)\n\n");
    let tet = |name: &str, c: glam::Vec3, r: f32| {
        format!(
            "def Mesh \"{name}\"\n{{\n    point3f[] points = [({}, {}, {}), ({}, {}, {}), ({}, {}, {}), ({}, {}, {})]\n    int[] faceVertexCounts = [3, 3, 3, 3]\n    int[] faceVertexIndices = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]\n}}\n",
            c.x - r,
            c.y - r,
            c.z - r,
            c.x + r,
            c.y - r,
            c.z - r,
            c.x - r,
            c.y + r,
            c.z - r,
            c.x - r,
            c.y - r,
            c.z + r
        )
    };
    for o in &scene.objects {
        let r = o.obb.half_extents.min_element() * 0.5;
        text.push_str(&tet(&format!("ins_{}", o.ins_id), o.obb.center, r));
    }
    let far = scene.bounds().max + glam::Vec3::new(5.0, 5.0, 0.0);
    text.push_str(&tet("wall", far.truncate().extend(1.0), 0.5));
    text
}

#[test]
fn a_published_collision_file_in_the_folder_gives_the_objects_their_parts() {
    let scene = generate(&SynthConfig {
        objects: 8,
        gaussians: 1000,
        ..small()
    })
    .unwrap();
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("0001_42");
    scene.save(&dir, SplatLayout::Compressed).unwrap();
    // The published name drops the 4-digit prefix.
    std::fs::write(dir.join("42_collision.usda"), collision_usda(&scene)).unwrap();
    let (back, report) = Scene::load(&dir).unwrap();
    let c = report
        .collision
        .expect("the file is found by the folder's id");
    assert!(report.files.contains(&"42_collision.usda".to_string()));
    assert_eq!(c.frame, sage_scene::collision::CollisionFrame::W);
    assert!(c.frame_measured);
    assert_eq!(
        (c.by_name, c.by_box, c.structure, c.objects),
        (scene.objects.len(), 0, 1, scene.objects.len())
    );
    for o in &back.objects {
        let b = o.body.as_ref().unwrap();
        assert_eq!(b.source, sage_scene::BodySource::Published);
        assert!(o.obb.contains(b.parts[0].aabb().min, 1e-4));
    }
    assert_eq!(back.structure_body.as_ref().unwrap().parts.len(), 1);
    // Given by path from elsewhere, the same; a missing one is an error naming it.
    let elsewhere = root.path().join("c.usda");
    std::fs::rename(dir.join("42_collision.usda"), &elsewhere).unwrap();
    assert!(Scene::load(&dir).unwrap().1.collision.is_none());
    let options = sage_scene::LoadOptions {
        collision: Some(elsewhere.clone()),
    };
    let (_, report) = Scene::load_with(&dir, &options).unwrap();
    assert_eq!(report.collision.unwrap().by_name, scene.objects.len());
    let options = sage_scene::LoadOptions {
        collision: Some(root.path().join("nope.usd")),
    };
    let e = Scene::load_with(&dir, &options).unwrap_err().to_string();
    assert!(
        e.contains("nope.usd") && e.contains("does not exist"),
        "{e}"
    );
}
