//! A whole scene: Gaussians, objects, floorplan, occupancy; loading and saving a scene folder.

use crate::collision::{self, CollisionReport};
use crate::floorplan::Floorplan;
use crate::formats::{labels, objects_json, structure};
use crate::gaussians::Gaussians;
use crate::instances::{InstanceTable, assign_instances};
use crate::mesh::TriMesh;
use crate::object::{BodyParts, Object};
use crate::occupancy::OccupancyMap;
use crate::ply::{self, SplatLayout};
use crate::splats::{self, Format};
use rayon::prelude::*;
use sage_core::{Aabb, Error, Result, ResultExt};
use sage_io::limits::SCENE_JSON_MB;
use std::path::{Path, PathBuf};

/// Everything sage3d knows about one indoor scene, in the world frame W.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Folder name (InteriorGS `NNNN_WWWWWW`) or a generated name.
    pub name: String,
    /// The 3DGS appearance.
    pub gaussians: Gaussians,
    /// Annotated objects, in `labels.json` order; `objects[i].id == i + 1`.
    pub objects: Vec<Object>,
    /// Rooms, walls, holes.
    pub floorplan: Floorplan,
    /// The scene's own occupancy map, when it has one.
    pub occupancy: Option<OccupancyMap>,
    /// The mesh of the structure (walls, floors, ceilings), when the scene has one.
    pub structure_mesh: Option<TriMesh>,
    /// Convex parts of the structure that belong to no object (walls, floors, ceilings), in W:
    /// the parts of a published collision file that no object took
    /// ([`collision::attach`]). Physics makes them static bodies.
    pub structure_body: Option<BodyParts>,
    /// Instance ids and categories.
    pub instances: InstanceTable,
}

/// How far outside every room polygon an object's centre may lie and still be given the nearest
/// room (metres): windows and doors sit on the walls that bound the rooms.
pub const ROOM_SNAP: f32 = 0.5;

/// Mesh file extensions looked for in `meshes/`, in this order.
pub const MESH_EXTENSIONS: [&str; 4] = ["obj", "glb", "gltf", "ply"];

/// What [`Scene::load`] found in a folder.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadReport {
    /// Files read, relative to the folder.
    pub files: Vec<String>,
    /// Expected files that were absent.
    pub missing: Vec<String>,
    /// The format of the Gaussian file (told from its content).
    pub splat_format: Option<Format>,
    /// True when the Gaussians were reordered on load (a standard PLY not in Morton order; see
    /// [`Scene::load`]).
    pub morton_reordered: bool,
    /// Objects that came with a mesh.
    pub meshes: usize,
    /// Non-fatal oddities (entries skipped and why).
    pub warnings: Vec<String>,
    /// How a published collision file was used (frame, agreement, assignment), when one was
    /// read.
    pub collision: Option<CollisionReport>,
}

/// Choices of [`Scene::load_with`] beyond the folder.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadOptions {
    /// A published collision file to use as the scene's physics layer instead of the one found
    /// in the folder by name ([`collision::find_in_folder`]).
    pub collision: Option<PathBuf>,
}

/// File names of the scene layout.
pub mod files {
    /// Gaussians in the SuperSplat compressed layout (InteriorGS).
    pub const COMPRESSED_PLY: &str = "3dgs_compressed.ply";
    /// Gaussians in the standard Inria layout.
    pub const STANDARD_PLY: &str = "3dgs.ply";
    /// Gaussian files looked for, in this order; the first present is read, in whatever
    /// format its content is (so a `3dgs.ply` may be compressed and a `3dgs.spz` is SPZ).
    pub const GAUSSIANS: [&str; 7] = [
        COMPRESSED_PLY,
        STANDARD_PLY,
        "3dgs.spz",
        "3dgs.sog",
        "3dgs.glb",
        "3dgs.gltf",
        "3dgs.splat",
    ];
    /// Object boxes.
    pub const LABELS: &str = "labels.json";
    /// Floorplan.
    pub const STRUCTURE: &str = "structure.json";
    /// Our per-object extras.
    pub const OBJECTS: &str = "objects.json";
    /// Mesh folder.
    pub const MESHES: &str = "meshes";
    /// Structure mesh inside the mesh folder (its stem is
    /// [`crate::formats::labels::STRUCTURE_STEM`], which no object's `ins_id` may be).
    pub const STRUCTURE_MESH: &str = "structure.obj";
    /// What `sage3d scene import` did to a capture (its transform, scale and floor fit); the
    /// loader reads the ceiling height it measured.
    pub const CAPTURE: &str = "capture.json";
    /// Everything [`Scene::save`](super::Scene::save) may write at the top of a scene folder
    /// (the occupancy map's two files included), so that a command writing a scene can refuse
    /// a folder where it would replace someone else's file.
    pub const WRITTEN: [&str; 8] = [
        COMPRESSED_PLY,
        STANDARD_PLY,
        LABELS,
        STRUCTURE,
        OBJECTS,
        "occupancy.png",
        "occupancy.json",
        MESHES,
    ];
}

/// The commands that write scene folders, as their run records name them. A folder whose run
/// record marks one of them unfinished ([`sage_io::run::mark_unfinished`]) holds part of a scene,
/// which [`Scene::load_with`] refuses.
pub mod writers {
    /// `sage3d scene synth`.
    pub const SYNTH: &str = "scene synth";
    /// `sage3d scene import`.
    pub const IMPORT: &str = "scene import";
    /// `sage3d recon fit`.
    pub const FIT: &str = "recon fit";
    /// All of them.
    pub const ALL: [&str; 3] = [SYNTH, IMPORT, FIT];
}

/// Refuses scene folder `dir` when its run record says that the command writing it has not
/// finished ([`writers`]): a killed run's Gaussians and labels are not a scene. A folder
/// without a run record (a downloaded InteriorGS scene) or with a finished one passes; a record
/// over `SAGE3D_MAX_JSON_MB` or one that cannot be read is an error naming it.
fn refuse_unfinished(dir: &Path) -> Result<()> {
    let record = sage_io::run::load_record(dir)?;
    let unfinished = record
        .as_ref()
        .filter(|r| sage_io::run::unfinished_status(r).is_some())
        .and_then(|r| r.get("command")?.as_str());
    match unfinished {
        Some(command) if writers::ALL.contains(&command) => Err(Error::invalid(format!(
            "not a whole scene: `sage3d {command}` did not finish writing this folder (its {} says so); rerun that command into it",
            sage_io::RUN_RECORD
        ))
        .in_file(dir)),
        _ => Ok(()),
    }
}

/// FNV-1a 64 hashes (hex) of every file loading the scene folder `dir` reads, keyed by their
/// path relative to `dir`: the annotations, occupancy, meshes and an imported capture's
/// `capture.json` (its ceiling height) that navigation reads
/// ([`sage_io::scenes::input_hashes`]), the Gaussian file and the published collision file
/// found by name. What run records store, so that a result names the exact scene it came from.
pub fn input_hashes(dir: &Path) -> std::collections::BTreeMap<String, String> {
    let mut hashes = sage_io::scenes::input_hashes(dir);
    let gaussians = files::GAUSSIANS
        .iter()
        .map(|name| dir.join(name))
        .find(|p| p.is_file());
    let name = sage_io::scenes::scene_name(dir);
    let collision = collision::find_in_folder(dir, &name);
    let more: Vec<PathBuf> = gaussians.into_iter().chain(collision).collect();
    hashes.extend(sage_io::scenes::hash_files(dir, &more));
    hashes
}

/// [`input_hashes`] of each scene `names` names (once each, in parallel), by name; a name
/// `dirs` does not hold is left out. What the run records of commands over many scenes store.
pub fn scenes_input_hashes<'a>(
    names: impl IntoIterator<Item = &'a str>,
    dirs: &std::collections::BTreeMap<String, PathBuf>,
) -> std::collections::BTreeMap<String, std::collections::BTreeMap<String, String>> {
    let names: std::collections::BTreeSet<&str> = names.into_iter().collect();
    names
        .into_par_iter()
        .filter_map(|name| Some((name.to_string(), input_hashes(dirs.get(name)?))))
        .collect()
}

impl Scene {
    /// Builds the instance table, numbers the objects, assigns rooms (where unset) and
    /// per-Gaussian instances.
    pub fn finish(&mut self) {
        for o in self.objects.iter_mut().filter(|o| o.room.is_none()) {
            o.room = self.floorplan.room_near(o.obb.center.truncate(), ROOM_SNAP);
        }
        self.instances = InstanceTable::build(&mut self.objects, &self.floorplan);
        assign_instances(
            &mut self.gaussians,
            &self.objects,
            &self.floorplan,
            &self.instances,
        );
    }

    /// Bounds of everything: Gaussians, boxes, walls.
    pub fn bounds(&self) -> Aabb {
        let objects = self
            .objects
            .iter()
            .fold(Aabb::EMPTY, |b, o| b.union(o.obb.aabb()));
        let walls = self
            .floorplan
            .walls
            .iter()
            .fold(Aabb::EMPTY, |b, w| b.union(w.obb().aabb()));
        self.gaussians.bounds().union(objects).union(walls)
    }

    /// Loads a scene folder: the Gaussians (either layout, detected from the header), labels,
    /// structure, occupancy, `objects.json` and meshes, whichever exist.
    ///
    /// Gaussians keep the file's order, except that a standard-layout PLY not in Morton order
    /// is sorted into it ([`Gaussians::sort_morton`], reported in
    /// [`LoadReport::morton_reordered`]) so that the renderer's chunks are compact.
    pub fn load(dir: &Path) -> Result<(Scene, LoadReport)> {
        Self::load_with(dir, &LoadOptions::default())
    }

    /// [`Scene::load`], then the published collision file (`options.collision`, else the one
    /// in the folder named `{scene}_collision.usd`: [`collision::find_in_folder`]) as the
    /// physics layer: its parts go to the objects they belong to and the rest to
    /// [`Scene::structure_body`]; [`LoadReport::collision`] says how.
    ///
    /// # Errors
    ///
    /// Those of [`Scene::load`], a named collision file that does not exist, a folder a scene
    /// writer has not finished ([`writers`]), and those of [`collision::read`].
    pub fn load_with(dir: &Path, options: &LoadOptions) -> Result<(Scene, LoadReport)> {
        if let Some(c) = &options.collision
            && !c.is_file()
        {
            return Err(Error::invalid(format!(
                "the collision file {} does not exist",
                c.display()
            )));
        }
        if !dir.exists() {
            return Err(Error::invalid(format!("{} does not exist", dir.display())));
        }
        if !dir.is_dir() {
            return Err(Error::invalid(format!(
                "{} is not a scene folder: it is a file",
                dir.display()
            )));
        }
        refuse_unfinished(dir)?;
        // Each file is looked at once: a folder by its name is an error, not a missing file.
        let splat_path = gaussians_file(dir)?;
        let labels_path = dir.join(files::LABELS);
        let has_labels = is_present(&labels_path)?;
        let structure_path = dir.join(files::STRUCTURE);
        let has_structure = is_present(&structure_path)?;
        // A folder with none of the files that make a scene is a mistaken path, not an empty
        // scene.
        if splat_path.is_none() && !has_labels && !has_structure {
            return Err(Error::invalid(format!(
                "{} is not a scene folder: missing {} (or {}), {} and {}",
                dir.display(),
                files::COMPRESSED_PLY,
                files::GAUSSIANS[1..].join(", "),
                files::LABELS,
                files::STRUCTURE
            )));
        }
        let mut report = LoadReport::default();
        let mut note = |name: &str, found: bool| {
            if found {
                report.files.push(name.to_string())
            } else {
                report.missing.push(name.to_string())
            }
        };
        let gaussians = match &splat_path {
            Some(p) => {
                note(&p.file_name().unwrap_or_default().to_string_lossy(), true);
                let (mut g, format) = splats::read_gaussians_file(p)?;
                report.splat_format = Some(format);
                // Other files may be in any order (training output is), which would make render
                // chunks loose. Compressed PLY files are chunked spatially by their writers, but
                // a writer that kept a trained PLY's order leaves them loose: those are sorted
                // too, by the compressed writer's own test.
                if format != Format::Ply(SplatLayout::Compressed) {
                    report.morton_reordered = g.sort_morton();
                } else if let Some(order) = ply::compressed::loose_order(&g) {
                    g = g.permuted(&order);
                    report.morton_reordered = true;
                }
                g
            }
            None => {
                note(files::COMPRESSED_PLY, false);
                Gaussians::new(0)?
            }
        };
        let mut objects = if has_labels {
            note(files::LABELS, true);
            let text = read_text(&labels_path)?;
            let (objects, skipped) = labels::parse(&text).in_file(&labels_path)?;
            if skipped > 0 {
                report.warnings.push(format!(
                    "{}: {skipped} entries without bounding_box skipped",
                    files::LABELS
                ));
            }
            objects
        } else {
            note(files::LABELS, false);
            Vec::new()
        };
        let mut floorplan = if has_structure {
            note(files::STRUCTURE, true);
            structure::parse(&read_text(&structure_path)?).in_file(&structure_path)?
        } else {
            note(files::STRUCTURE, false);
            Floorplan::default()
        };
        // A capture has no walls to give its ceiling height: its import measured one.
        let capture_path = dir.join(files::CAPTURE);
        if !has_structure && is_present(&capture_path)? {
            note(files::CAPTURE, true);
            floorplan.ceiling =
                capture_ceiling(&read_text(&capture_path)?).in_file(&capture_path)?;
        }
        let occupancy_json = is_present(&dir.join("occupancy.json"))?;
        let occupancy = if is_present(&dir.join("occupancy.png"))? && occupancy_json {
            note("occupancy.png", true);
            note("occupancy.json", true);
            Some(OccupancyMap::load(dir)?)
        } else {
            note("occupancy.png", false);
            None
        };
        let objects_path = dir.join(files::OBJECTS);
        let mut mesh_files = vec![None; objects.len()];
        if is_present(&objects_path)? {
            note(files::OBJECTS, true);
            let applied = objects_json::apply(&read_text(&objects_path)?, &mut objects)
                .in_file(&objects_path)?;
            mesh_files = applied.mesh_files;
            let unmatched = applied.unmatched;
            if unmatched > 0 {
                report.warnings.push(format!(
                    "{}: {unmatched} entries name no object of labels.json",
                    files::OBJECTS
                ));
            }
        }
        let mesh_dir = dir.join(files::MESHES);
        if mesh_dir.is_dir() {
            note(files::MESHES, true);
        } else if mesh_dir.exists() {
            return Err(
                Error::invalid("a file, not a folder: the scene's meshes go in a folder")
                    .in_file(&mesh_dir),
            );
        }
        let meshes = objects
            .par_iter()
            .zip(&mesh_files)
            .map(|(o, named)| match named {
                Some(rel) => {
                    let p = dir.join(rel);
                    if !is_present(&p)? {
                        return Err(Error::format(
                            format!("objects[ins_id {}].mesh", o.ins_id),
                            format!("names {rel}, which does not exist"),
                        )
                        .in_file(&objects_path));
                    }
                    TriMesh::load(&p).map(Some)
                }
                None => {
                    let named = MESH_EXTENSIONS
                        .iter()
                        .map(|e| object_file(&mesh_dir, &o.ins_id, e))
                        .collect::<Result<Vec<_>>>()
                        .in_file(&labels_path)?;
                    first_present(named)?.map(|p| TriMesh::load(&p)).transpose()
                }
            })
            .collect::<Result<Vec<_>>>()?;
        for (o, m) in objects.iter_mut().zip(meshes) {
            report.meshes += usize::from(m.is_some());
            o.mesh = m;
        }
        let structure_mesh_path = mesh_dir.join(files::STRUCTURE_MESH);
        let structure_mesh = if is_present(&structure_mesh_path)? {
            Some(TriMesh::load(&structure_mesh_path)?)
        } else {
            None
        };
        let name = dir
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "scene".to_string());
        let collision_path = options
            .collision
            .clone()
            .or_else(|| collision::find_in_folder(dir, &name));
        let structure_body = match collision_path {
            Some(p) => {
                // Files are named relative to the folder; one given from elsewhere by its path.
                match p.strip_prefix(dir) {
                    Ok(rel) => note(&rel.to_string_lossy(), true),
                    Err(_) => note(&p.display().to_string(), true),
                }
                let file = collision::read(&p)?;
                let attached = collision::attach(&file, &mut objects);
                report.collision = Some(attached.report);
                attached.structure
            }
            None => None,
        };
        let mut scene = Scene {
            name,
            gaussians,
            objects,
            floorplan,
            occupancy,
            structure_mesh,
            structure_body,
            instances: InstanceTable::default(),
        };
        scene.finish();
        Ok((scene, report))
    }

    /// [`Scene::load`] for work that needs the Gaussians (rendering, plan views): a folder
    /// without a Gaussian file, or whose file holds none, is an error naming the file rather
    /// than a scene that renders black.
    ///
    /// # Errors
    ///
    /// Those of [`Scene::load`], no Gaussian file, or an empty one.
    pub fn load_for_rendering(dir: &Path) -> Result<(Scene, LoadReport)> {
        // Checked first: loading the rest of a scene that cannot be rendered is wasted.
        if dir.is_dir() && gaussians_file(dir)?.is_none() {
            return Err(Error::invalid(format!(
                "missing (and so are {}): this needs the scene's Gaussians",
                files::GAUSSIANS[1..].join(", ")
            ))
            .in_file(dir.join(files::COMPRESSED_PLY)));
        }
        let (scene, report) = Self::load(dir)?;
        if scene.gaussians.is_empty() {
            let file = gaussians_file(dir)?.unwrap_or_else(|| dir.join(files::COMPRESSED_PLY));
            return Err(
                Error::invalid("holds no Gaussians: this needs the scene's Gaussians")
                    .in_file(file),
            );
        }
        Ok((scene, report))
    }

    /// Writes the scene folder (creating it): Gaussians in `layout`, `labels.json`,
    /// `structure.json`, `objects.json`, the occupancy map if any, and meshes as OBJ.
    ///
    /// # Errors
    ///
    /// An object whose `ins_id` cannot name its mesh file
    /// ([`labels::ins_id_problem`]), refused before anything is written: a scene built in
    /// memory (the synthesizer, reconstruction, the Python API) has not been through the
    /// loader's check, and `meshes/{ins_id}.obj` must not land outside `dir`. Then those of
    /// writing the files.
    pub fn save(&self, dir: &Path, layout: SplatLayout) -> Result<()> {
        // Every object, not only those with meshes: labels.json with such an id is a folder
        // the loader refuses.
        for (k, o) in self.objects.iter().enumerate() {
            if let Some(problem) = labels::ins_id_problem(&o.ins_id) {
                return Err(Error::invalid(format!(
                    "cannot save the scene: objects[{k}] (label '{}'): ins_id {}; nothing \
                     was written",
                    o.label.escape_debug(),
                    labels::ins_id_message(&o.ins_id, &problem)
                ))
                .in_file(dir));
            }
        }
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let splat_name = match layout {
            SplatLayout::Compressed => files::COMPRESSED_PLY,
            SplatLayout::Standard => files::STANDARD_PLY,
        };
        ply::write_splats_file(&dir.join(splat_name), &self.gaussians, layout)?;
        sage_io::files::write_json(&dir.join(files::LABELS), &labels::to_json(&self.objects))?;
        sage_io::files::write_json(
            &dir.join(files::STRUCTURE),
            &structure::to_json(&self.floorplan),
        )?;
        sage_io::files::write_json(
            &dir.join(files::OBJECTS),
            &objects_json::to_json(&self.objects, &self.floorplan),
        )?;
        if let Some(occ) = &self.occupancy {
            occ.save(dir)?;
        }
        let mesh_dir = dir.join(files::MESHES);
        let has_meshes =
            self.structure_mesh.is_some() || self.objects.iter().any(|o| o.mesh.is_some());
        if has_meshes {
            std::fs::create_dir_all(&mesh_dir).map_err(|e| Error::io(&mesh_dir, e))?;
        }
        for o in &self.objects {
            if let Some(m) = &o.mesh {
                let p = object_file(&mesh_dir, &o.ins_id, "obj")?;
                sage_io::files::write_atomic(&p, |w| m.write_obj(w, &o.category))?;
            }
        }
        if let Some(m) = &self.structure_mesh {
            sage_io::files::write_atomic(&mesh_dir.join(files::STRUCTURE_MESH), |w| {
                m.write_obj(w, labels::STRUCTURE_STEM)
            })?;
        }
        Ok(())
    }
}

/// Whether the scene file `path` is there: `Ok(true)` for a file, `Ok(false)` when nothing is
/// (a dangling link included).
///
/// # Errors
///
/// Something other than a file at `path`, naming it: a folder by a file's name is a mistake to
/// report, not a file to treat as missing.
pub fn is_present(path: &Path) -> Result<bool> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(true),
        Ok(m) if m.is_dir() => Err(Error::invalid(
            "a directory, not a file: the scene needs a file by this name, or none",
        )
        .in_file(path)),
        Ok(_) => Err(Error::invalid("not a regular file").in_file(path)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(Error::io(path, e)),
    }
}

/// The file `{ins_id}.{ext}` in `folder` (an object's mesh), refusing an `ins_id` that is not
/// one plain file name ([`labels::ins_id_problem`]) so that no id read from a file or set in
/// memory joins `folder` to a path outside it.
///
/// # Errors
///
/// A format error at `ins_id` saying why the id cannot name a file.
pub fn object_file(folder: &Path, ins_id: &str, ext: &str) -> Result<PathBuf> {
    match labels::ins_id_problem(ins_id) {
        Some(problem) => Err(Error::format(
            "ins_id",
            labels::ins_id_message(ins_id, &problem),
        )),
        None => Ok(folder.join(format!("{ins_id}.{ext}"))),
    }
}

/// The first of `paths` that [`is_present`].
fn first_present(paths: impl IntoIterator<Item = PathBuf>) -> Result<Option<PathBuf>> {
    for p in paths {
        if is_present(&p)? {
            return Ok(Some(p));
        }
    }
    Ok(None)
}

/// The ceiling height in a capture's `capture.json` (`floor.ceiling_m`, metres above the
/// floor): `None` where the import found no ceiling (0) or the file has no such field.
///
/// # Errors
///
/// Not JSON, or a ceiling that is not a number from 0 to [`sage_core::MAX_COORDINATE`].
fn capture_ceiling(text: &str) -> Result<Option<f32>> {
    let root: serde_json::Value =
        serde_json::from_str(text).map_err(|e| Error::invalid(format!("not JSON: {e}")))?;
    let Some(value) = root.get("floor").and_then(|f| f.get("ceiling_m")) else {
        return Ok(None);
    };
    match value.as_f64() {
        Some(0.0) => Ok(None),
        Some(c) if c > 0.0 && c <= f64::from(sage_core::MAX_COORDINATE) => Ok(Some(c as f32)),
        _ => Err(Error::format(
            "floor.ceiling_m",
            format!(
                "{value}: expected the ceiling's height in metres, from 0 (none found) to {}",
                sage_core::MAX_COORDINATE
            ),
        )),
    }
}

/// The Gaussian file of scene folder `dir`: the first of [`files::GAUSSIANS`] there, `None` when
/// there is none.
///
/// # Errors
///
/// A folder by one of those names (before the file found), as [`is_present`].
pub fn gaussians_file(dir: &Path) -> Result<Option<PathBuf>> {
    first_present(files::GAUSSIANS.iter().map(|f| dir.join(f)))
}

/// The files of scene folder `dir` that loading it reads ([`input_hashes`]), with every
/// Gaussian file by a name the loader looks for, the provenance of an imported capture and the
/// scene's run record: what a command reading the scene must never write over, whatever
/// `force` says.
pub fn scene_files(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = sage_io::scenes::input_files(dir);
    found.extend(
        files::GAUSSIANS
            .iter()
            .chain(&[files::CAPTURE, sage_io::RUN_RECORD])
            .map(|name| dir.join(name)),
    );
    // The collision file is found by the folder's own name, as loading names the scene.
    let named = [dir.canonicalize().ok(), Some(dir.to_path_buf())];
    for folder in named.iter().flatten() {
        let name = sage_io::scenes::scene_name(folder);
        found.extend(collision::names(&name).into_iter().map(|n| dir.join(n)));
    }
    found.retain(|p| p.is_file());
    found.sort();
    found.dedup();
    found
}

/// A scene JSON file's text, refused before reading when it is over [`SCENE_JSON_MB`].
fn read_text(path: &Path) -> Result<String> {
    sage_io::files::read_text(path, &SCENE_JSON_MB)
}
