//! `sage3d recon …`: make a Gaussian scene from a mesh scene — plan cameras, render the
//! ground-truth views, export them for nerfstudio / gsplat, project a point into them.

use clap::{Args, Subcommand};
use indicatif::{ParallelProgressIterator, ProgressBar, ProgressStyle};
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_recon::export::{
    POINTS_FILE, TRANSFORMS_FILE, is_heldout, transforms_for, write_points_ply, write_transforms,
};
use sage_recon::plan::{PLAN_FILE, PLAN_PNG, Plan, PlanSettings, Policy, draw_plan, make_plan};
use sage_recon::sweep::SweepParams;
use sage_recon::views::{self, Manifest};
use sage_recon::{SceneSurfaces, render_view, surface_samples};
use sage_scene::fsutil::{write_json, write_run_record};
use sage_scene::{Scene, SplatLayout};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The fit's report inside the output scene folder.
const FIT_REPORT: &str = "fit_report.json";

#[derive(Subcommand)]
pub enum ReconCommand {
    /// Sample cameras over a scene (perimeter sweeps or volume-uniform), drop those too close
    /// to a surface; writes OUT/plan.json and OUT/plan.png (kept green, dropped red).
    Plan(PlanArgs),
    /// Render the planned views of the scene's meshes (RGB + depth) into DIR/views; resumes,
    /// skipping views already written.
    Render(RenderArgs),
    /// Write DIR/transforms.json (nerfstudio / gsplat layout) for the rendered views.
    Export(ExportArgs),
    /// Fit Gaussians to the rendered views on the CPU (sage-train), starting from points on the
    /// meshes; writes a scene folder (the fitted Gaussians with the original labels, structure
    /// and meshes) and OUT/fit_report.json (held-out PSNR before and after, the loss curve).
    Fit(FitArgs),
    /// Print where a world point lands in each planned view (pixel and depth, one JSON line per
    /// view that sees it in front of the camera and inside the image).
    Project(ProjectArgs),
}

#[derive(Args)]
pub struct PlanArgs {
    /// Scene folder (its meshes: meshes/structure.obj and per-object meshes or boxes).
    scene: PathBuf,
    /// Camera placement policy: sweep or volume.
    #[arg(long, default_value = "sweep")]
    policy: Policy,
    /// Cameras to sample before the safety filter.
    #[arg(long, default_value_t = 3000)]
    budget: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Horizontal field of view of the views, degrees.
    #[arg(long, default_value_t = 90.0)]
    hfov: f32,
    /// Least distance from a camera to the nearest mesh surface, metres.
    #[arg(long, default_value_t = sage_recon::safety::DEFAULT_THRESHOLD)]
    safety: f32,
    /// Sweep: inward offsets of the rings, metres, outermost first.
    #[arg(long, value_delimiter = ',', default_value = "0.4,0.9,1.4")]
    offsets: Vec<f32>,
    /// Sweep: tangential shift of the left and right baselines, metres.
    #[arg(long, default_value_t = 0.2)]
    baseline: f32,
}

#[derive(Args)]
pub struct RenderArgs {
    /// Reconstruction folder (holds plan.json).
    dir: PathBuf,
    /// Scene folder (default: the one the plan was made from).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Image size as WxH.
    #[arg(long, default_value = "640x480")]
    size: String,
}

#[derive(Args)]
pub struct ExportArgs {
    /// Reconstruction folder (holds plan.json and the rendered views).
    dir: PathBuf,
    /// Scene folder for the point cloud (default: the one the plan was made from).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Surface samples written to points3d.ply (0: no point cloud).
    #[arg(long, default_value_t = 100_000)]
    points: usize,
}

#[derive(Args)]
pub struct FitArgs {
    /// Reconstruction folder (plan.json and every view rendered).
    dir: PathBuf,
    /// Optimisation steps (one training view each).
    #[arg(long, default_value_t = 2000)]
    iterations: usize,
    /// Output scene folder.
    #[arg(long)]
    out: PathBuf,
    /// Scene folder (default: the one the plan was made from).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Surface samples the Gaussians start from (one Gaussian each).
    #[arg(long, default_value_t = 50_000)]
    points: usize,
    /// Seed of the samples and of the fit (default: the plan's).
    #[arg(long)]
    seed: Option<u64>,
}

#[derive(Args)]
pub struct ProjectArgs {
    /// Reconstruction folder (holds plan.json and views/render.json).
    dir: PathBuf,
    /// World point (W frame, metres) as X,Y,Z.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        required = true
    )]
    point: Vec<f32>,
}

pub fn run(cmd: ReconCommand) -> Result<()> {
    match cmd {
        ReconCommand::Plan(a) => plan(a),
        ReconCommand::Render(a) => render(a),
        ReconCommand::Export(a) => export(a),
        ReconCommand::Fit(a) => fit(a),
        ReconCommand::Project(a) => project(a),
    }
}

fn load_scene(dir: &Path) -> Result<(Scene, SceneSurfaces)> {
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

fn plan(a: PlanArgs) -> Result<()> {
    let (scene, surfaces) = load_scene(&a.scene)?;
    let settings = PlanSettings {
        policy: a.policy,
        budget: a.budget,
        seed: a.seed,
        hfov_deg: a.hfov,
        safety_threshold: a.safety,
        sweep: SweepParams {
            offsets: a.offsets,
            baseline: a.baseline,
            ..SweepParams::default()
        },
        ..PlanSettings::default()
    };
    let plan = make_plan(&scene, &a.scene.to_string_lossy(), &surfaces, &settings)?;
    std::fs::create_dir_all(&a.out).map_err(|e| Error::io(&a.out, e))?;
    plan.save(&a.out.join(PLAN_FILE))?;
    draw_plan(&scene, &plan).save_png(&a.out.join(PLAN_PNG))?;
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
        &a.out,
        "recon plan",
        Some(a.seed),
        serde_json::json!({
            "scene": plan.scene,
            "policy": plan.policy,
            "budget": plan.budget,
            "sampled": sampled,
            "kept": plan.views.len(),
            "dropped": plan.dropped.len(),
        }),
    )?;
    println!(
        "{}: {:?} policy, budget {}, sampled {sampled}, kept {}, dropped {} (closer than {} m to a surface)",
        plan.scene,
        plan.policy,
        plan.budget,
        plan.views.len(),
        plan.dropped.len(),
        plan.safety_threshold
    );
    for (group, (kept, dropped)) in &groups {
        println!("  {group:<24} kept {kept:>5}  dropped {dropped:>5}");
    }
    println!(
        "wrote {} and {}",
        a.out.join(PLAN_FILE).display(),
        a.out.join(PLAN_PNG).display()
    );
    Ok(())
}

fn render(a: RenderArgs) -> Result<()> {
    let plan = Plan::load(&a.dir.join(PLAN_FILE))?;
    let scene_dir = a.scene.unwrap_or_else(|| PathBuf::from(&plan.scene_dir));
    let (w, h) = crate::flags::parse_size(&a.size)?;
    let manifest = Manifest::new(&plan, w, h)?;
    views::prepare(&a.dir, &manifest)?;
    let todo = views::pending(&a.dir, &plan);
    if todo.is_empty() {
        println!(
            "all {} views already rendered in {}",
            plan.views.len(),
            a.dir.join(views::VIEWS_DIR).display()
        );
        return Ok(());
    }
    let (scene, surfaces) = load_scene(&scene_dir)?;
    if scene.name != plan.scene {
        eprintln!(
            "warning: the plan was made for scene {}, rendering {}",
            plan.scene, scene.name
        );
    }
    let bvh = surfaces.bvh();
    let k = manifest.intrinsics();
    let bar = ProgressBar::new(todo.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} views {elapsed} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    todo.par_iter()
        .progress_with(bar.clone())
        .try_for_each(|&id| {
            let image = render_view(&surfaces, &bvh, &plan.views[id].camera(k));
            views::write_view(&a.dir, id, &image)
        })?;
    bar.finish_and_clear();
    println!(
        "rendered {} of {} views at {w}x{h} ({} triangles) in {:.1} s into {}",
        todo.len(),
        plan.views.len(),
        surfaces.len(),
        start.elapsed().as_secs_f64(),
        a.dir.join(views::VIEWS_DIR).display()
    );
    Ok(())
}

fn export(a: ExportArgs) -> Result<()> {
    let plan = Plan::load(&a.dir.join(PLAN_FILE))?;
    let views = views::export_views(&a.dir, &plan)?;
    let mut transforms = transforms_for(&views)?;
    if a.points > 0 {
        let scene_dir = a.scene.unwrap_or_else(|| PathBuf::from(&plan.scene_dir));
        let (_, surfaces) = load_scene(&scene_dir)?;
        let points = surface_samples(&surfaces, a.points, plan.seed);
        write_points_ply(&a.dir.join(POINTS_FILE), &points)?;
        transforms.ply_file_path = Some(POINTS_FILE.to_string());
    }
    let path = a.dir.join(TRANSFORMS_FILE);
    write_transforms(&path, &transforms)?;
    println!(
        "wrote {} ({} frames: {} train, {} held out; OPENCV {}x{}, c2w in OpenGL axes, world Z up; points: {})",
        path.display(),
        transforms.frames.len(),
        transforms.train_filenames.len(),
        (0..views.len()).filter(|&i| is_heldout(i)).count(),
        transforms.w,
        transforms.h,
        transforms.ply_file_path.as_deref().unwrap_or("none")
    );
    Ok(())
}

fn fit(a: FitArgs) -> Result<()> {
    let plan = Plan::load(&a.dir.join(PLAN_FILE))?;
    let exported = views::export_views(&a.dir, &plan)?;
    let manifest = views::read_manifest(&a.dir)?
        .ok_or_else(|| Error::invalid("no views/render.json: run `sage3d recon render` first"))?;
    if a.points == 0 {
        return Err(Error::invalid("--points must be at least 1"));
    }
    let seed = a.seed.unwrap_or(plan.seed);
    let scene_dir = a.scene.unwrap_or_else(|| PathBuf::from(&plan.scene_dir));
    let (scene, surfaces) = load_scene(&scene_dir)?;
    let samples = surface_samples(&surfaces, a.points, seed);
    // The mean distance between samples spread evenly over the area.
    let spacing = (surfaces.area() / a.points as f64).sqrt() as f32;
    let init = sage_train::init_gaussians(&samples, spacing);
    let loaded: Vec<(bool, sage_train::View)> = exported
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            Ok((
                is_heldout(i),
                sage_train::View {
                    camera: v.camera,
                    rgb: views::read_rgb(&a.dir, i, &manifest)?,
                },
            ))
        })
        .collect::<Result<_>>()?;
    let (heldout, train): (Vec<_>, Vec<_>) = loaded.into_iter().partition(|(h, _)| *h);
    let train: Vec<sage_train::View> = train.into_iter().map(|(_, v)| v).collect();
    let heldout: Vec<sage_train::View> = heldout.into_iter().map(|(_, v)| v).collect();
    let params = sage_train::FitParams {
        iterations: a.iterations,
        seed,
        ..sage_train::FitParams::default()
    };
    let bar = ProgressBar::new(a.iterations as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} iterations {msg} {elapsed} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let (gaussians, report) = sage_train::fit(&init, &train, &heldout, &params, &|it, loss| {
        bar.set_position(it as u64);
        bar.set_message(format!("loss {loss:.4}"));
    })?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let mut fitted = scene;
    fitted.gaussians = gaussians;
    fitted.finish();
    fitted.save(&a.out, SplatLayout::Compressed)?;
    let details = serde_json::json!({
        "recon": a.dir.to_string_lossy(),
        "scene": plan.scene,
        "iterations": a.iterations,
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
    write_json(&a.out.join(FIT_REPORT), &details)?;
    write_run_record(
        &a.out,
        "recon fit",
        Some(seed),
        serde_json::json!({ "recon": a.dir.to_string_lossy(), "iterations": a.iterations, "points": a.points }),
    )?;
    println!(
        "fitted {} Gaussians to {} views ({} held out) in {:.1} s: held-out PSNR {:.2} -> {:.2} dB, train {:.2} dB; wrote {}",
        report.gaussians,
        train.len(),
        heldout.len(),
        seconds,
        report.initial_heldout_psnr,
        report.final_heldout_psnr,
        report.final_train_psnr,
        a.out.display()
    );
    Ok(())
}

fn project(a: ProjectArgs) -> Result<()> {
    let plan = Plan::load(&a.dir.join(PLAN_FILE))?;
    let manifest = views::read_manifest(&a.dir)?.ok_or_else(|| {
        Error::invalid("no views/render.json: the image size is set by `sage3d recon render`")
    })?;
    let &[x, y, z] = a.point.as_slice() else {
        return Err(Error::invalid(format!(
            "--point needs 3 numbers x,y,z, got {}",
            a.point.len()
        )));
    };
    let p = glam::Vec3::new(x, y, z);
    let k = manifest.intrinsics();
    for v in &plan.views {
        let cam = v.camera(k);
        let c = cam.world_to_camera(p);
        if c.z <= cam.near {
            continue;
        }
        let (u, vv) = cam.project(c);
        if u >= 0.0 && vv >= 0.0 && u < k.width as f32 && vv < k.height as f32 {
            println!(
                "{}",
                serde_json::json!({
                    "view": v.id,
                    "file_path": views::rgb_name(v.id),
                    "u": u,
                    "v": vv,
                    "depth": c.z,
                })
            );
        }
    }
    Ok(())
}
