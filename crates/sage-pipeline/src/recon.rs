//! Reconstruction, step by step: plan cameras over a mesh scene, render their ground-truth
//! views, export them for nerfstudio / gsplat, fit Gaussians to them on the CPU, and project a
//! world point into the planned views (`docs/reconstruction.md`). Each step reads and writes the
//! reconstruction folder, so the steps can run apart and resume.

use rayon::prelude::*;
use sage_core::{Error, Result, Vec3};
use sage_io::files::write_json;
use sage_io::lock::FolderLock;
use sage_io::run::write_run_record;
use sage_recon::export::{
    POINTS_FILE, TRANSFORMS_FILE, is_heldout, transforms_for, write_points_ply, write_transforms,
};
use sage_recon::plan::{PLAN_FILE, PLAN_PNG, Plan, PlanSettings, Policy, draw_plan, make_plan};
use sage_recon::views::{self, Manifest};
use sage_recon::{SceneSurfaces, render_view, surface_samples};
use sage_scene::{Scene, SplatLayout};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The fit's report inside the output scene folder.
pub const FIT_REPORT: &str = "fit_report.json";

/// Loads a scene with the surfaces reconstruction renders (its meshes, or its object boxes).
///
/// # Errors
///
/// The scene cannot be loaded, or it has nothing to render.
pub fn load_mesh_scene(dir: &Path) -> Result<(Scene, SceneSurfaces)> {
    let (scene, _) = Scene::load(dir)?;
    let surfaces = SceneSurfaces::build(&scene, Some(dir))?;
    if surfaces.is_empty() {
        return Err(Error::invalid(format!(
            "{}: the scene has no meshes and no object boxes to render",
            dir.display()
        )));
    }
    Ok((scene, surfaces))
}

/// What [`plan`] made.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanReport {
    /// Scene name.
    pub scene: String,
    /// Placement policy.
    pub policy: Policy,
    /// Cameras asked for.
    pub budget: usize,
    /// Cameras sampled.
    pub sampled: usize,
    /// Cameras kept.
    pub kept: usize,
    /// Cameras dropped by the safety filter.
    pub dropped: usize,
    /// The safety filter's least distance to a surface, metres.
    pub safety_threshold: f32,
    /// Kept and dropped per tier (sweep) or template view (volume).
    pub groups: BTreeMap<String, (usize, usize)>,
}

/// The command that plans a reconstruction folder, as its run record names it.
pub const PLAN_COMMAND: &str = "recon plan";

/// The command that renders a reconstruction folder's views, as its lock file names it.
pub const RENDER_COMMAND: &str = "recon render";

/// The command that exports a reconstruction folder, as its lock file names it.
pub const EXPORT_COMMAND: &str = "recon export";

/// The command that fits a scene folder, as its run record names it.
pub const FIT_COMMAND: &str = sage_scene::scene::writers::FIT;

/// Everything the reconstruction steps write at the top of the folder [`plan`] makes (the
/// later steps write into the plan's folder).
const RECON_OUTPUTS: [&str; 6] = [
    PLAN_FILE,
    PLAN_PNG,
    views::VIEWS_DIR,
    TRANSFORMS_FILE,
    POINTS_FILE,
    sage_io::RUN_RECORD,
];

/// Plans the cameras of the scene in `scene_dir` into `out` (`plan.json`, `plan.png`, the run
/// record, marked unfinished before the plan: [`sage_io::run::mark_unfinished`]). `out` must
/// be new, empty or a reconstruction folder, finished or not (a rerun replaces its plan);
/// with `force`, a folder of other files is written into, provided none of them would be
/// replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// An output folder holding files the command did not write, the scene cannot be loaded or
/// planned, or a file cannot be written.
pub fn plan(
    scene_dir: &Path,
    settings: &PlanSettings,
    out: &Path,
    force: bool,
) -> Result<PlanReport> {
    let _lock = sage_io::run::claim_folder(out, &[PLAN_COMMAND], &RECON_OUTPUTS, force)?;
    let (scene, surfaces) = load_mesh_scene(scene_dir)?;
    let plan = make_plan(&scene, &scene_dir.to_string_lossy(), &surfaces, settings)?;
    sage_io::run::mark_unfinished(out, PLAN_COMMAND, Some(settings.seed))?;
    plan.save(&out.join(PLAN_FILE))?;
    draw_plan(&scene, &plan).save_png(&out.join(PLAN_PNG))?;
    let sampled = plan.views.len() + plan.dropped.len();
    // Per tier (sweep) or template view (volume): the part of the tag after the position.
    let mut groups: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for (v, kept) in plan
        .views
        .iter()
        .map(|v| (v, true))
        .chain(plan.dropped.iter().map(|v| (v, false)))
    {
        let key = v.tag.split_once('/').map_or("", |t| t.1).to_string();
        let e = groups.entry(key).or_default();
        if kept {
            e.0 += 1;
        } else {
            e.1 += 1;
        }
    }
    write_run_record(
        out,
        PLAN_COMMAND,
        Some(settings.seed),
        serde_json::json!({
            "scene": plan.scene,
            "policy": plan.policy,
            "budget": plan.budget,
            "sampled": sampled,
            "kept": plan.views.len(),
            "dropped": plan.dropped.len(),
            "inputs": sage_scene::input_hashes(scene_dir),
        }),
    )?;
    Ok(PlanReport {
        scene: plan.scene,
        policy: plan.policy,
        budget: plan.budget,
        sampled,
        kept: plan.views.len(),
        dropped: plan.dropped.len(),
        safety_threshold: plan.safety_threshold,
        groups,
    })
}

/// Locks the reconstruction folder `dir` that [`plan`] made for `command`, a later step that
/// writes into it ([`FolderLock`]; [`plan`] itself claims the folder), and reads its plan.
/// Under the lock no other command writes there, so once the folder is known to be a plan's,
/// the temporary files that an interrupted step left in it are stale and go.
fn lock_folder(dir: &Path, command: &str) -> Result<(FolderLock, Plan)> {
    let lock = FolderLock::acquire(dir, command)?;
    let plan = Plan::load(&dir.join(PLAN_FILE))?;
    lock.remove_temporary();
    Ok((lock, plan))
}

/// Holds the reconstruction folder `dir` that `command` reads ([`FolderLock::acquire_shared`]):
/// a `recon render`, `recon export` or `recon plan` into it would change the views under the
/// reader, and is refused naming it, while other readers share it. `None` when `dir` is the
/// reader's own output folder `out`, which its claim already holds, or does not exist (reading
/// its plan then says what is missing).
fn read_lock(dir: &Path, out: &Path, command: &str) -> Result<Option<FolderLock>> {
    if !dir.is_dir() {
        return Ok(None);
    }
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same(dir, out) {
        return Ok(None);
    }
    FolderLock::acquire_shared(dir, command).map(Some)
}

/// The files of reconstruction folder `dir` a fit reads: the plan and the rendered views,
/// sorted.
fn recon_inputs(dir: &Path) -> Vec<PathBuf> {
    let views = dir.join(views::VIEWS_DIR);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&views)
        .map(|entries| entries.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.sort();
    files.insert(0, dir.join(PLAN_FILE));
    files
}

/// The scene folder of a step: the one given, else the one the plan was made from.
fn scene_of(plan: &Plan, scene: Option<&Path>) -> PathBuf {
    scene.map_or_else(|| PathBuf::from(&plan.scene_dir), Path::to_path_buf)
}

/// What [`render`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RenderReport {
    /// Views rendered by this call (0 when all were already there).
    pub rendered: usize,
    /// Views in the plan.
    pub total: usize,
    /// Triangles rendered (0 when nothing was to render).
    pub triangles: usize,
    /// The scene the plan was made for, when another one was rendered.
    pub other_scene: Option<(String, String)>,
}

/// Renders the planned views of the reconstruction folder `dir` at `width × height` that are
/// not yet there (RGB + depth into `dir/views`); `on_view` is called after each. Holds the
/// folder's lock meanwhile ([`FolderLock`]): another render would write the same views, a new
/// plan would change them under this one.
///
/// # Errors
///
/// A folder that another command is writing, no plan, a manifest of another size, the scene
/// cannot be loaded, or a write error.
pub fn render(
    dir: &Path,
    scene: Option<&Path>,
    width: u32,
    height: u32,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    let (_lock, plan) = lock_folder(dir, RENDER_COMMAND)?;
    let scene_dir = scene_of(&plan, scene);
    let manifest = Manifest {
        scene: Some(scene_dir.file_name().map_or_else(
            || scene_dir.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )),
        ..Manifest::new(&plan, width, height)?
    };
    views::prepare(dir, &manifest)?;
    let todo = views::pending(dir, &plan);
    if todo.is_empty() {
        return Ok(RenderReport {
            rendered: 0,
            total: plan.views.len(),
            triangles: 0,
            other_scene: None,
        });
    }
    let (scene, surfaces) = load_mesh_scene(&scene_dir)?;
    let other_scene = (scene.name != plan.scene).then(|| (plan.scene.clone(), scene.name));
    let bvh = surfaces.bvh();
    let k = manifest.intrinsics();
    todo.par_iter().try_for_each(|&id| {
        let image = render_view(&surfaces, &bvh, &plan.views[id].camera(k));
        views::write_view(dir, id, &image)?;
        on_view(id, todo.len());
        Ok::<(), Error>(())
    })?;
    Ok(RenderReport {
        rendered: todo.len(),
        total: plan.views.len(),
        triangles: surfaces.len(),
        other_scene,
    })
}

/// What [`export`] wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExportReport {
    /// `transforms.json`.
    pub path: PathBuf,
    /// Frames.
    pub frames: usize,
    /// Training frames.
    pub train: usize,
    /// Held-out frames.
    pub heldout: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// The point cloud's file name, if one was written.
    pub points: Option<String>,
    /// An earlier export's point cloud, removed since this one wrote none (a reader looking
    /// beside `transforms.json` would otherwise start from stale points).
    pub removed_points: Option<PathBuf>,
}

/// Writes `dir/transforms.json` for the rendered views, and `points3d.ply` of `points` surface
/// samples when `points > 0`, holding the folder's lock meanwhile ([`FolderLock`]): the views
/// it lists may not change while it reads them.
///
/// # Errors
///
/// A folder that another command is writing, no plan or views, the scene cannot be loaded, or
/// a write error.
pub fn export(dir: &Path, scene: Option<&Path>, points: usize) -> Result<ExportReport> {
    sage_recon::surfaces::check_points(points)?;
    let (_lock, plan) = lock_folder(dir, EXPORT_COMMAND)?;
    let views = views::export_views(dir, &plan)?;
    let mut transforms = transforms_for(&views)?;
    if points > 0 {
        let (_, surfaces) = load_mesh_scene(&scene_of(&plan, scene))?;
        let samples = surface_samples(&surfaces, points, plan.seed);
        write_points_ply(&dir.join(POINTS_FILE), &samples)?;
        transforms.ply_file_path = Some(POINTS_FILE.to_string());
    }
    let path = dir.join(TRANSFORMS_FILE);
    let removed_points = write_transforms(&path, &transforms)?;
    Ok(ExportReport {
        path,
        frames: transforms.frames.len(),
        train: transforms.train_filenames.len(),
        heldout: (0..views.len()).filter(|&i| is_heldout(i)).count(),
        width: transforms.w,
        height: transforms.h,
        points: transforms.ply_file_path,
        removed_points,
    })
}

/// Settings of [`fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// Optimisation steps (one training view each).
    pub iterations: usize,
    /// Surface samples the Gaussians start from (one Gaussian each).
    pub points: usize,
    /// Seed of the samples and of the fit (default: the plan's).
    pub seed: Option<u64>,
}

/// What [`fit`] made.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitReport {
    /// Gaussians fitted.
    pub gaussians: usize,
    /// Training views.
    pub train_views: usize,
    /// Held-out views.
    pub heldout_views: usize,
    /// Held-out PSNR before fitting, dB.
    pub initial_heldout_psnr: f32,
    /// Held-out PSNR after fitting, dB.
    pub final_heldout_psnr: f32,
    /// Training PSNR after fitting, dB.
    pub final_train_psnr: f32,
}

/// Fits Gaussians to the rendered views of the reconstruction folder `dir` (the pipeline recon
/// → fit): starts from surface samples of the scene's meshes, optimises with `sage-train`
/// (`on_iteration(iteration, loss)`), and writes the scene folder `out` (the fitted Gaussians
/// with the original labels, structure and meshes), `out/fit_report.json` and the run record,
/// marked unfinished before the first file and written in full after the last
/// ([`sage_io::run::mark_unfinished`]: a fit killed half-way leaves a folder that loads as no
/// scene and that its rerun redoes). `out` must be new, empty or a fit's, finished or not (a
/// rerun replaces its files); with `force`, a folder of other files is written into, provided
/// none of them would be replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// An output folder holding files the command did not write, a reconstruction folder another
/// command is writing (the fit holds it while it runs, [`FolderLock::acquire_shared`]), no plan
/// or rendered views, no points asked for, the scene cannot be loaded, the fit fails, or a
/// write error.
pub fn fit(
    dir: &Path,
    scene: Option<&Path>,
    settings: &FitSettings,
    out: &Path,
    force: bool,
    on_iteration: &(dyn Fn(usize, f32) + Sync),
) -> Result<FitReport> {
    let mut names = sage_scene::scene::files::WRITTEN.to_vec();
    names.extend([FIT_REPORT, sage_io::RUN_RECORD]);
    let _lock = sage_io::run::claim_folder(out, &[FIT_COMMAND], &names, force)?;
    let _reading = read_lock(dir, out, FIT_COMMAND)?;
    let plan = Plan::load(&dir.join(PLAN_FILE))?;
    let exported = views::export_views(dir, &plan)?;
    let manifest = views::read_manifest(dir)?
        .ok_or_else(|| Error::invalid("no views/render.json: run `sage3d recon render` first"))?;
    if settings.points == 0 {
        return Err(Error::invalid("`points` must be at least 1"));
    }
    sage_recon::surfaces::check_points(settings.points)?;
    let seed = settings.seed.unwrap_or(plan.seed);
    let scene_dir = scene_of(&plan, scene);
    let (scene, surfaces) = load_mesh_scene(&scene_dir)?;
    let samples = surface_samples(&surfaces, settings.points, seed);
    // The mean distance between samples spread evenly over the area.
    let spacing = (surfaces.area() / settings.points as f64).sqrt() as f32;
    let init = sage_train::init_gaussians(&samples, spacing);
    let loaded: Vec<(bool, sage_train::View)> = exported
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            Ok((
                is_heldout(i),
                sage_train::View {
                    camera: v.camera,
                    rgb: views::read_rgb(dir, i, &manifest)?,
                },
            ))
        })
        .collect::<Result<_>>()?;
    let (heldout, train): (Vec<_>, Vec<_>) = loaded.into_iter().partition(|(h, _)| *h);
    let train: Vec<sage_train::View> = train.into_iter().map(|(_, v)| v).collect();
    let heldout: Vec<sage_train::View> = heldout.into_iter().map(|(_, v)| v).collect();
    let params = sage_train::FitParams {
        iterations: settings.iterations,
        seed,
        ..sage_train::FitParams::default()
    };
    let (gaussians, report) = sage_train::fit(&init, &train, &heldout, &params, on_iteration)?;
    let mut fitted = scene;
    fitted.gaussians = gaussians;
    fitted.finish();
    sage_io::run::mark_unfinished(out, FIT_COMMAND, Some(seed))?;
    fitted.save(out, SplatLayout::Compressed)?;
    let details = serde_json::json!({
        "recon": dir.to_string_lossy(),
        "scene": plan.scene,
        "iterations": settings.iterations,
        "train_views": train.len(),
        "heldout_views": heldout.len(),
        "image_size": [manifest.width, manifest.height],
        "init_points": samples.len(),
        "init_spacing_m": spacing,
        "initial_heldout_psnr": report.initial_heldout_psnr,
        "final_heldout_psnr": report.final_heldout_psnr,
        "final_train_psnr": report.final_train_psnr,
        "gaussians": report.gaussians,
        "heldout_curve": report.heldout_curve,
        "loss": report.loss,
    });
    write_json(&out.join(FIT_REPORT), &details)?;
    write_run_record(
        out,
        FIT_COMMAND,
        Some(seed),
        serde_json::json!({
            "recon": dir.to_string_lossy(),
            "iterations": settings.iterations,
            "points": settings.points,
            // The plan, every file of the rendered views, and the scene.
            "inputs": sage_io::scenes::hash_files(dir, &recon_inputs(dir)),
            "scene_inputs": sage_scene::input_hashes(&scene_dir),
        }),
    )?;
    Ok(FitReport {
        gaussians: report.gaussians,
        train_views: train.len(),
        heldout_views: heldout.len(),
        initial_heldout_psnr: report.initial_heldout_psnr,
        final_heldout_psnr: report.final_heldout_psnr,
        final_train_psnr: report.final_train_psnr,
    })
}

/// Where world point `p` lands in each planned view of `dir` that sees it in front of the camera
/// and inside the image: `{view, file_path, u, v, depth}` per view.
///
/// # Errors
///
/// A point not finite or past ±[`sage_core::MAX_COORDINATE`] m, no plan, or no rendered views
/// (the image size is set by rendering).
pub fn project(dir: &Path, p: Vec3) -> Result<Vec<serde_json::Value>> {
    if !sage_core::within_bounds(p) {
        return Err(Error::invalid(format!(
            "`point` must be finite and within ±{} m, got {}, {}, {}",
            sage_core::MAX_COORDINATE,
            p.x,
            p.y,
            p.z
        )));
    }
    let plan = Plan::load(&dir.join(PLAN_FILE))?;
    let manifest = views::read_manifest(dir)?.ok_or_else(|| {
        Error::invalid("no views/render.json: the image size is set by `sage3d recon render`")
    })?;
    let k = manifest.intrinsics();
    let mut hits = Vec::new();
    for v in &plan.views {
        let cam = v.camera(k);
        let c = cam.world_to_camera(p);
        if c.z <= cam.near {
            continue;
        }
        let (u, vv) = cam.project(c);
        if u >= 0.0 && vv >= 0.0 && u < k.width as f32 && vv < k.height as f32 {
            hits.push(serde_json::json!({
                "view": v.id,
                "file_path": views::rgb_name(v.id),
                "u": u,
                "v": vv,
                "depth": c.z,
            }));
        }
    }
    Ok(hits)
}
