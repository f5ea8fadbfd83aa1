//! `sage3d recon …`: make a Gaussian scene from a mesh scene — plan cameras, render the
//! ground-truth views, export them for nerfstudio / gsplat, fit, project a point into them.
//! The steps are `sage_pipeline::recon`'s; this module translates flags and prints.

use clap::{Args, Subcommand};
use sage_core::named::comma_list;
use sage_core::{Error, Result};
use sage_pipeline::recon::{self, FitSettings};
use sage_recon::plan::{PLAN_FILE, PLAN_PNG, PlanSettings, Policy};
use sage_recon::sweep::SweepParams;
use sage_recon::views;
use std::path::PathBuf;
use std::time::Instant;

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
    #[arg(long, default_value_t = PlanSettings::default().policy)]
    policy: Policy,
    /// Cameras to sample before the safety filter.
    #[arg(long, default_value_t = PlanSettings::default().budget)]
    budget: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = PlanSettings::default().seed)]
    seed: u64,
    /// Output folder: new, empty, or a reconstruction folder (rerunning replaces its plan).
    #[arg(long)]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Horizontal field of view of the views, degrees.
    #[arg(long, default_value_t = PlanSettings::default().hfov_deg, value_parser = sage_env::config::parse_hfov)]
    hfov: f32,
    /// Least distance from a camera to the nearest mesh surface, metres.
    #[arg(long, default_value_t = PlanSettings::default().safety_threshold)]
    safety: f32,
    /// Sweep: inward offsets of the rings, metres, outermost first.
    #[arg(long, value_delimiter = ',', default_value = comma_list(&SweepParams::default().offsets))]
    offsets: Vec<f32>,
    /// Sweep: tangential shift of the left and right baselines, metres.
    #[arg(long, default_value_t = SweepParams::default().baseline)]
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
    #[arg(long, default_value = "640x480", value_parser = crate::flags::parse_size)]
    size: (u32, u32),
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
    /// Output scene folder: new, empty, or one this command wrote (rerunning replaces it).
    #[arg(long)]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
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

fn plan(a: PlanArgs) -> Result<()> {
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
    let r = recon::plan(&a.scene, &settings, &a.out, a.force)?;
    println!(
        "{}: {:?} policy, budget {}, sampled {}, kept {}, dropped {} (closer than {} m to a surface)",
        r.scene, r.policy, r.budget, r.sampled, r.kept, r.dropped, r.safety_threshold
    );
    for (group, (kept, dropped)) in &r.groups {
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
    let (w, h) = a.size;
    let progress = crate::progress::bar("{bar:30} {pos}/{len} views {elapsed} (eta {eta})");
    let start = Instant::now();
    let r = recon::render(&a.dir, a.scene.as_deref(), w, h, &|_, todo| {
        progress.set_length(todo as u64);
        progress.inc(1);
    });
    progress.finish_and_clear();
    let r = r?;
    let views_dir = a.dir.join(views::VIEWS_DIR);
    if r.rendered == 0 {
        println!(
            "all {} views already rendered in {}",
            r.total,
            views_dir.display()
        );
        return Ok(());
    }
    if let Some((planned, rendered)) = &r.other_scene {
        eprintln!("warning: the plan was made for scene {planned}, rendering {rendered}");
    }
    println!(
        "rendered {} of {} views at {w}x{h} ({} triangles) in {:.1} s into {}",
        r.rendered,
        r.total,
        r.triangles,
        start.elapsed().as_secs_f64(),
        views_dir.display()
    );
    Ok(())
}

fn export(a: ExportArgs) -> Result<()> {
    let r = recon::export(&a.dir, a.scene.as_deref(), a.points)?;
    println!(
        "wrote {} ({} frames: {} train, {} held out; OPENCV {}x{}, c2w in OpenGL axes, world Z up; points: {})",
        r.path.display(),
        r.frames,
        r.train,
        r.heldout,
        r.width,
        r.height,
        r.points.as_deref().unwrap_or("none")
    );
    if let Some(stale) = &r.removed_points {
        println!(
            "removed {} (an earlier export's points; this one wrote none)",
            stale.display()
        );
    }
    Ok(())
}

fn fit(a: FitArgs) -> Result<()> {
    let settings = FitSettings {
        iterations: a.iterations,
        points: a.points,
        seed: a.seed,
    };
    let progress =
        crate::progress::bar("{bar:30} {pos}/{len} iterations {msg} {elapsed} (eta {eta})");
    progress.set_length(a.iterations as u64);
    let start = Instant::now();
    let r = recon::fit(
        &a.dir,
        a.scene.as_deref(),
        &settings,
        &a.out,
        a.force,
        &|it, loss| {
            progress.set_position(it as u64);
            progress.set_message(format!("loss {loss:.4}"));
        },
    );
    progress.finish_and_clear();
    let r = r?;
    println!(
        "fitted {} Gaussians to {} views ({} held out) in {:.1} s: held-out PSNR {:.2} -> {:.2} dB, train {:.2} dB; wrote {}",
        r.gaussians,
        r.train_views,
        r.heldout_views,
        start.elapsed().as_secs_f64(),
        r.initial_heldout_psnr,
        r.final_heldout_psnr,
        r.final_train_psnr,
        a.out.display()
    );
    Ok(())
}

fn project(a: ProjectArgs) -> Result<()> {
    let &[x, y, z] = a.point.as_slice() else {
        return Err(Error::invalid(format!(
            "--point needs 3 numbers x,y,z, got {}",
            a.point.len()
        )));
    };
    for hit in recon::project(&a.dir, glam::Vec3::new(x, y, z))? {
        println!("{hit}");
    }
    Ok(())
}
