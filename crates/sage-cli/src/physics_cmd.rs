//! `sage3d physics …` and `sage3d export usd`: collision bodies and their quality, the CoACD
//! work list, driving an agent, the hybrid USDA scene.

use clap::{Args, Subcommand};
use sage_core::{Error, Pose, Result, Vec3};
use sage_physics::{
    AgentBody, AgentProfile, BodyKind, BuildReport, Command, Decomposer, HullCache, SceneBodies,
    SplatBodies, World, WorldOptions, default_cache_dir,
};
use sage_pipeline::physics::BodyOptions;
use sage_scene::{BodySource, LoadOptions, Scene};
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum PhysicsCommand {
    /// Build the collision bodies of a scene (decomposing meshes not yet in the cache) and
    /// report the decomposition quality: hull counts and hull volume against mesh volume.
    Build(BuildArgs),
    /// List the object meshes whose hulls are not yet cached (missing, or a damaged entry), with
    /// their cache paths, as JSON (the work list of python/tools/coacd_cache.py).
    Pending(PendingArgs),
    /// Drive an agent through a scene with a list of commands; print one JSON report per step.
    Drive(DriveArgs),
}

#[derive(Subcommand)]
pub enum ExportCommand {
    /// Write the hybrid scene as USDA: collision parts with UsdPhysics schemas, rigid bodies and
    /// joints, semantic labels, the Gaussians referenced as a PLY asset.
    Usd(UsdArgs),
}

/// How bodies are made: a published collision file, how meshes are decomposed and where the
/// hulls are cached.
#[derive(Args, Clone)]
pub struct DecompArgs {
    /// Published collision file (SAGE-Bench `{scene}_collision.usd`, USDC or USDA) to use as the
    /// physics layer; by default one in the scene folder by that name (or the folder's numeric
    /// id: 0001_839920 -> 839920_collision.usd) is used when present.
    #[arg(long, value_name = "FILE")]
    collision: Option<PathBuf>,
    /// Hull cache folder (default: SCENE/.sage3d/collision).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Decomposer: vhacd (in process) or coacd (hulls made offline by python/tools/coacd_cache.py).
    #[arg(long, default_value = "vhacd")]
    backend: String,
    /// V-HACD voxel resolution.
    #[arg(long, default_value_t = 64)]
    resolution: u32,
    /// V-HACD maximum concavity.
    #[arg(long, default_value_t = 0.01)]
    concavity: f32,
    /// CoACD concavity threshold.
    #[arg(long, default_value_t = 0.05)]
    threshold: f32,
    /// Most convex parts per object (CoACD: 0 for no cap).
    #[arg(long, default_value_t = 32)]
    max_hulls: u32,
    /// Which objects get bodies recovered from their own Gaussians: auto (those with neither a
    /// published body nor a mesh, instead of their box), always (every object), never.
    #[arg(long, default_value_t = SplatBodies::default())]
    splat_bodies: SplatBodies,
    /// Recover every object's body from its Gaussians (the same as --splat-bodies always).
    #[arg(long, conflicts_with = "splat_bodies")]
    from_splats: bool,
}

impl DecompArgs {
    fn decomposer(&self) -> Result<Decomposer> {
        let d = match self.backend.to_ascii_lowercase().as_str() {
            "vhacd" => Decomposer::Vhacd {
                resolution: self.resolution,
                concavity: self.concavity,
                max_hulls: self.max_hulls,
            },
            "coacd" => Decomposer::Coacd {
                threshold: self.threshold,
                max_hulls: self.max_hulls,
            },
            other => {
                return Err(Error::invalid(format!(
                    "--backend: unknown decomposer '{other}' (expected vhacd or coacd)"
                )));
            }
        };
        d.validate()?;
        Ok(d)
    }

    fn cache(&self, scene_dir: &Path) -> HullCache {
        HullCache::new(
            self.cache
                .clone()
                .unwrap_or_else(|| default_cache_dir(scene_dir)),
        )
    }

    /// How the scene is loaded for its bodies: with the collision file given, if any, and the
    /// objects whose bodies are recovered from their Gaussians.
    fn body_options(&self) -> BodyOptions {
        BodyOptions {
            load: LoadOptions {
                collision: self.collision.clone(),
            },
            splat_bodies: if self.from_splats {
                SplatBodies::Always
            } else {
                self.splat_bodies
            },
        }
    }

    /// Loads the scene and builds its bodies under a progress bar.
    fn bodies(&self, scene_dir: &Path) -> Result<(Scene, SceneBodies, BuildReport)> {
        let (decomposer, cache) = (self.decomposer()?, self.cache(scene_dir));
        let options = self.body_options();
        let built = with_bar(|on_object| {
            sage_pipeline::physics::bodies(scene_dir, &options, &decomposer, &cache, on_object)
        })?;
        note_cache(&built.2);
        Ok(built)
    }
}

/// Tells, on standard error, which damaged hull cache entries the build made anew, and which
/// entries it could not write (the first, and how many).
fn note_cache(report: &BuildReport) {
    for damage in &report.remade {
        eprintln!("note: a damaged hull cache entry was decomposed anew and replaced: {damage}");
    }
    if let Some(first) = report.unstored.first() {
        let more = match report.unstored.len() {
            1 => String::new(),
            n => format!(" (and {} other write errors)", n - 1),
        };
        eprintln!(
            "note: a hull cache entry could not be written, so its object's parts are decomposed again on every load; give a writable folder with --cache to keep them: {first}{more}"
        );
    }
}

/// Runs `work` under a bar of the objects whose bodies are built, which `work` hands to the
/// pipeline as its `on_object`.
fn with_bar<T>(work: impl FnOnce(&(dyn Fn(usize) + Sync)) -> Result<T>) -> Result<T> {
    // Hidden when standard error is not a terminal.
    let bar = crate::progress::bar("collision bodies {bar:40} {pos}/{len} objects {elapsed}");
    let done = work(&|n| {
        bar.set_length(n as u64);
        bar.inc(1);
    });
    bar.finish_and_clear();
    done
}

#[derive(Args)]
pub struct BuildArgs {
    /// Scene folder.
    scene: PathBuf,
    #[command(flatten)]
    decomp: DecompArgs,
    /// Print the full report as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct PendingArgs {
    /// Scene folder.
    scene: PathBuf,
    #[command(flatten)]
    decomp: DecompArgs,
    /// Output JSON file (an existing one is refused without --force, and a file of the scene
    /// always).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
pub struct DriveArgs {
    /// Scene folder.
    scene: PathBuf,
    #[command(flatten)]
    decomp: DecompArgs,
    /// Agent profile: wheeled, go2, g1, h1 or uav.
    #[arg(long, default_value = "wheeled")]
    agent: String,
    /// Start position X,Y,Z (metres, world frame, each within ±10000; ground robots: Z of the
    /// floor).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    position: Vec<f32>,
    /// Start heading, degrees counter-clockwise from +X.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    yaw: f32,
    /// Commands: forward:D, turn:DEG, stop, vel:VX:VY:WZDEG:DT, uav:VX:VY:VZ:WZDEG:DT
    /// (finite; distances and speeds within ±10000, turns within ±3600°, DT 0-60 s).
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    commands: Vec<String>,
    /// Put doors on revolute joints instead of fixing them at their state's angle.
    #[arg(long)]
    articulated_doors: bool,
}

#[derive(Args)]
pub struct UsdArgs {
    /// Scene folder.
    scene: PathBuf,
    /// Output `.usda` file (an existing one is refused without --force, and a file of the
    /// scene always).
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    decomp: DecompArgs,
}

pub fn run(cmd: PhysicsCommand) -> Result<()> {
    match cmd {
        PhysicsCommand::Build(a) => build(a),
        PhysicsCommand::Pending(a) => pending(a),
        PhysicsCommand::Drive(a) => drive(a),
    }
}

pub fn run_export(cmd: ExportCommand) -> Result<()> {
    match cmd {
        ExportCommand::Usd(a) => export_usd(a),
    }
}

fn build(a: BuildArgs) -> Result<()> {
    let (scene, bodies, report) = a.decomp.bodies(&a.scene)?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| Error::invalid(e.to_string()))?
        );
        return Ok(());
    }
    print_build(&scene, &bodies, &report);
    Ok(())
}

/// Prints what building a scene's bodies did: counts, hull volumes, the worst objects.
pub fn print_build(scene: &Scene, bodies: &SceneBodies, report: &BuildReport) {
    println!(
        "scene            {} ({} objects)",
        scene.name,
        scene.objects.len()
    );
    if let Some(c) = &report.collision {
        println!("published        {c}");
    }
    println!("decomposer       {}", report.decomposer);
    println!("cache            {}", report.cache_dir);
    let given = |src: BodySource| report.sources.iter().filter(|o| o.source == src).count();
    println!(
        "objects          {} published, {} from Gaussians, {} decomposed, {} from cache, {} as boxes (no mesh)",
        given(BodySource::Published),
        given(BodySource::Gaussians),
        report.decomposed,
        report.cached,
        report.boxes
    );
    let parts_of = |kind: fn(&BodyKind) -> bool| -> usize {
        bodies
            .bodies
            .iter()
            .filter(|b| kind(&b.kind))
            .map(|b| b.parts.len())
            .sum()
    };
    let meshed = if report.objects.is_empty() {
        String::new()
    } else {
        format!(
            "; {:.1} per object with a mesh ({} of them)",
            report.mean_hulls(),
            report.objects.len()
        )
    };
    println!(
        "hulls            {} convex parts: {} of objects, {} of walls, {} of the structure body, {} of floor and ceiling slabs{meshed}",
        report.parts,
        parts_of(|k| matches!(k, BodyKind::Object(_))),
        parts_of(|k| matches!(k, BodyKind::Wall(_))),
        parts_of(|k| matches!(k, BodyKind::Structure)),
        parts_of(|k| matches!(k, BodyKind::Floor | BodyKind::Ceiling)),
    );
    if !report.objects.is_empty() {
        println!(
            "volume           hulls / meshes = {:.3} (1 = exact, > 1 = fattened)",
            report.volume_ratio()
        );
    }
    let mut worst: Vec<_> = report
        .objects
        .iter()
        .filter(|o| o.mesh_volume > 0.0)
        .collect();
    worst.sort_by(|x, y| {
        (y.hull_volume / y.mesh_volume).total_cmp(&(x.hull_volume / x.mesh_volume))
    });
    for o in worst.iter().take(5) {
        println!(
            "  worst          {}_{}: {} hulls, {:.4} m³ hulls / {:.4} m³ mesh = {:.2}",
            o.category,
            o.instance,
            o.hulls,
            o.hull_volume,
            o.mesh_volume,
            o.hull_volume / o.mesh_volume
        );
    }
    let loose = scene.structure_body.as_ref().map_or(String::new(), |b| {
        format!("{} {} parts, ", report.structure_parts, b.source.as_str())
    });
    println!(
        "structure        {} wall pieces, {} openings cut, {loose}floor and ceiling slabs (ceiling at {:.2} m)",
        report.wall_pieces, report.openings_cut, bodies.ceiling_height
    );
    println!("time             {:.2} s", report.seconds);
}

fn pending(a: PendingArgs) -> Result<()> {
    let list = sage_pipeline::physics::work_list(
        &a.scene,
        &a.decomp.body_options(),
        &a.out,
        &a.decomp.decomposer()?,
        &a.decomp.cache(&a.scene),
        a.force,
    )?;
    println!(
        "{} meshes without cached hulls (missing or damaged) -> {}",
        list.meshes.len(),
        a.out.display()
    );
    Ok(())
}

fn drive(a: DriveArgs) -> Result<()> {
    let profile: AgentProfile = a.agent.parse()?;
    let commands = a
        .commands
        .iter()
        .map(|c| c.parse::<Command>())
        .collect::<Result<Vec<_>>>()?;
    let position = match a.position.as_slice() {
        [x, y, z] => Vec3::new(*x, *y, *z),
        [] => Err(Error::invalid("--position X,Y,Z is required"))?,
        _ => Err(Error::invalid("--position takes three numbers X,Y,Z"))?,
    };
    let start = Pose::new(position, a.yaw.to_radians());
    // Checked before the bodies are built, as the commands are: a bad flag costs nothing.
    sage_physics::check_pose(&start).map_err(|e| e.within("--position/--yaw"))?;
    let (scene, bodies, _) = a.decomp.bodies(&a.scene)?;
    let options = WorldOptions {
        articulated_doors: a.articulated_doors,
        ..WorldOptions::default()
    };
    let mut world = World::new(&scene, bodies, &options);
    let mut agent = AgentBody::new(profile, start);
    for (i, c) in commands.iter().enumerate() {
        let report = agent.step(&mut world, c)?;
        let mut line = serde_json::to_value(&report).map_err(|e| Error::invalid(e.to_string()))?;
        line["step"] = serde_json::json!(i);
        line["command"] = serde_json::json!(c.to_string());
        println!("{line}");
    }
    Ok(())
}

fn export_usd(a: UsdArgs) -> Result<()> {
    let (decomposer, cache) = (a.decomp.decomposer()?, a.decomp.cache(&a.scene));
    let report = with_bar(|on_object| {
        sage_pipeline::physics::export_usd(
            &a.scene,
            &a.decomp.body_options(),
            &a.out,
            &decomposer,
            &cache,
            a.force,
            on_object,
        )
    })?;
    note_cache(&report.build);
    println!(
        "{} -> {} ({} bodies, {} collision parts; {} decomposed, {} from cache)",
        a.scene.display(),
        a.out.display(),
        report.bodies,
        report.build.parts,
        report.build.decomposed,
        report.build.cached
    );
    Ok(())
}
