//! `sage3d scene …`: synthesise, import and describe scene folders.

use clap::{Args, Subcommand, ValueEnum};
use sage_core::{Error, Result};
use sage_scene::{LoadOptions, Scene, SplatLayout};
use sage_synth::{SceneKind, SynthConfig};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Generate a synthetic scene folder in the InteriorGS layout (same seed, same bytes).
    Synth(SynthArgs),
    /// Describe a scene folder: counts, categories, rooms, bounds, Gaussians, memory.
    Info(InfoArgs),
    /// Draw a top-down plan view of a scene's Gaussians (ceiling cut away) as a PNG.
    Preview(PreviewArgs),
    /// Import your own capture (any 3DGS file sage3d reads) as a scene folder: floor and
    /// gravity found, put in W (Z up, floor at z = 0), scaled, floaters removed, occupancy
    /// map derived.
    Import(ImportArgs),
}

/// The Gaussian file layout to write.
#[derive(Clone, Copy, ValueEnum)]
pub enum LayoutArg {
    /// `3dgs_compressed.ply` (SuperSplat chunked; what InteriorGS ships).
    Compressed,
    /// `3dgs.ply` (standard Inria float layout).
    Standard,
}

impl From<LayoutArg> for SplatLayout {
    fn from(l: LayoutArg) -> Self {
        match l {
            LayoutArg::Compressed => SplatLayout::Compressed,
            LayoutArg::Standard => SplatLayout::Standard,
        }
    }
}

#[derive(Args)]
pub struct SynthArgs {
    /// Random seed: every byte of the output follows from it and the options.
    #[arg(long, default_value_t = SynthConfig::default().seed)]
    seed: u64,
    /// Output folder: new, empty, or a scene this command wrote (rerunning replaces its files).
    #[arg(long)]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Kind of space.
    #[arg(long, default_value_t = SynthConfig::default().kind)]
    kind: SceneKind,
    /// Target number of rooms.
    #[arg(long, value_parser = crate::flags::count_in(sage_synth::ROOMS))]
    rooms: Option<usize>,
    /// Target number of objects.
    #[arg(long, value_parser = crate::flags::count_in(sage_synth::OBJECTS))]
    objects: Option<usize>,
    /// Gaussian budget.
    #[arg(long, value_parser = crate::flags::count_in(sage_synth::GAUSSIANS))]
    gaussians: Option<usize>,
    /// Gaussian file layout.
    #[arg(long, value_enum, default_value = "compressed")]
    layout: LayoutArg,
}

#[derive(Args)]
pub struct InfoArgs {
    /// Scene folder.
    dir: PathBuf,
    /// Published collision file (SAGE-Bench `{scene}_collision.usd`, USDC or USDA) to read as
    /// the physics layer; by default one in the folder by that name (or the folder's numeric
    /// id: 0001_839920 -> 839920_collision.usd) is read when present.
    #[arg(long, value_name = "FILE")]
    collision: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct PreviewArgs {
    /// Scene folder.
    dir: PathBuf,
    /// Output PNG (default: DIR/preview.png); an existing file is refused without --force,
    /// and a file of the scene always.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
    /// Metres per pixel.
    #[arg(long, default_value_t = 0.02)]
    resolution: f32,
}

#[derive(Args)]
pub struct ImportArgs {
    /// The capture: a 3DGS file (PLY, compressed PLY, SPZ, SOG, glTF/GLB, .splat).
    capture: PathBuf,
    /// Output scene folder: new or empty.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    settings: sage_pipeline::capture::ImportSettings,
}

pub fn run(cmd: SceneCommand) -> Result<()> {
    match cmd {
        SceneCommand::Synth(a) => {
            let mut config = SynthConfig {
                seed: a.seed,
                kind: a.kind,
                ..SynthConfig::default()
            };
            if let Some(r) = a.rooms {
                config.rooms = r;
            }
            if let Some(o) = a.objects {
                config.objects = o;
            }
            if let Some(g) = a.gaussians {
                config.gaussians = g;
            }
            let scene = synthesize(&config, &a.out, a.layout.into(), a.force)?;
            println!("{}", scene.summary());
            Ok(())
        }
        SceneCommand::Info(a) => info(
            &a.dir,
            &LoadOptions {
                collision: a.collision,
            },
            a.json,
        ),
        SceneCommand::Import(a) => import(&a),
        SceneCommand::Preview(a) => {
            let out = a.out.unwrap_or_else(|| a.dir.join("preview.png"));
            // Checked before the scene is loaded: a refused output costs nothing.
            let inputs = sage_scene::scene_files(&a.dir);
            sage_io::run::claim_output_file(&out, &inputs, "a file of the input scene", a.force)?;
            let (scene, _) = Scene::load_for_rendering(&a.dir)?;
            write_preview(&scene, &out, a.resolution, a.force)
        }
    }
}

/// Writes the plan view of `scene` (replacing an existing `out` only with `force`) and says
/// where.
fn write_preview(scene: &Scene, out: &Path, resolution: f32, force: bool) -> Result<()> {
    if resolution.is_nan() || resolution <= 0.0 {
        return Err(Error::invalid(format!(
            "--resolution must be > 0, got {resolution}"
        )));
    }
    sage_io::run::claim_file(out, force)?;
    let cut = scene.floorplan.ceiling_height() - 0.1;
    let image = sage_scene::preview::plan_view(&scene.gaussians, resolution, cut);
    image.save_png(out)?;
    eprintln!(
        "plan view: {} ({} x {} px)",
        out.display(),
        image.width,
        image.height
    );
    Ok(())
}

/// Synthesises a scene folder under a spinner; returns the scene.
fn synthesize(config: &SynthConfig, out: &Path, layout: SplatLayout, force: bool) -> Result<Scene> {
    let start = Instant::now();
    let bar = crate::progress::spinner(&format!(
        "generating a {} scene (seed {})",
        config.kind.as_str(),
        config.seed
    ));
    let scene = sage_pipeline::scene::synthesize_into(config, out, layout, force, &|stage| {
        if stage == sage_pipeline::scene::Stage::Writing {
            bar.set_message(format!("writing {}", out.display()));
        }
    });
    bar.finish_and_clear();
    let scene = scene?;
    eprintln!(
        "wrote {} in {:.1} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(scene)
}

/// Imports a capture under a spinner and prints what was done to it.
fn import(a: &ImportArgs) -> Result<()> {
    use sage_pipeline::capture::Stage;
    let start = Instant::now();
    let bar = crate::progress::spinner(&format!("reading {}", a.capture.display()));
    let report = sage_pipeline::capture::import(&a.capture, &a.out, &a.settings, &|stage| {
        bar.set_message(match stage {
            Stage::Reading => format!("reading {}", a.capture.display()),
            Stage::Aligning => "finding floor, gravity and floaters".to_string(),
            Stage::Mapping => "deriving the occupancy map".to_string(),
            Stage::Writing => format!("writing {}", a.out.display()),
        });
    });
    bar.finish_and_clear();
    let r = report?;
    let scale = match r.scale_source.as_str() {
        "none" => "1 (none given: capture units taken as metres)".to_string(),
        source => format!("{} m per unit ({source})", r.scale),
    };
    println!(
        "capture     {} ({}, {} Gaussians)",
        r.input.display(),
        r.format,
        r.gaussians_in
    );
    println!("scale       {scale}");
    println!(
        "up          ({:.4}, {:.4}, {:.4}) in the capture's axes, tilted {:.2} deg from the nearest axis",
        r.up[0], r.up[1], r.up[2], r.tilt_deg
    );
    println!(
        "floor       {:.1} m2 fitted, rms {:.1} mm; ceiling {}",
        r.floor_area,
        r.floor_rms * 1000.0,
        if r.ceiling > 0.0 {
            format!("{:.2} m above it", r.ceiling)
        } else {
            format!(
                "none (no plane covering {:.0} % of the floor's area lies {} m or more above it); physics caps the scene at the top of its Gaussians",
                100.0 * sage_pipeline::capture::CEILING_AREA_SHARE,
                sage_pipeline::capture::MIN_CEILING_M
            )
        }
    );
    if let Some([x, y]) = r.recentred {
        println!(
            "recentred   moved {x:.0} m in x and {y:.0} m in y: the capture lay beyond the +-{} m a scene may reach (in capture.json's transform)",
            sage_core::MAX_COORDINATE
        );
    }
    println!(
        "walls       turned {:.1} deg about up onto x and y",
        r.yaw_deg
    );
    println!(
        "floaters    {} removed; {} Gaussians written",
        r.floaters, r.gaussians_out
    );
    println!(
        "occupancy   {:.1} m2 free, {:.1} m2 occupied (from the Gaussians)",
        r.free_m2, r.occupied_m2
    );
    if r.losses.is_empty() {
        println!("written     {}: every value as computed", r.splat_file);
    } else {
        println!(
            "written     {}, lossy (--layout standard keeps every value):",
            r.splat_file
        );
        for loss in &r.losses {
            println!("  lost: {loss}");
        }
    }
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!(
        "wrote {} in {:.1} s",
        r.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn info(dir: &Path, options: &LoadOptions, json: bool) -> Result<()> {
    let start = Instant::now();
    let (scene, report) = Scene::load_with(dir, options)?;
    let elapsed = start.elapsed().as_secs_f64();
    let summary = scene.summary();
    if json {
        let value = serde_json::json!({
            "summary": summary,
            "files": report.files,
            "missing": report.missing,
            "format": report.splat_format.map(|f| f.as_str()),
            "morton_reordered": report.morton_reordered,
            "warnings": report.warnings,
            "collision": report.collision,
            "load_seconds": elapsed,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).map_err(|e| Error::invalid(e.to_string()))?
        );
        return Ok(());
    }
    println!("{summary}");
    println!("files       {}", report.files.join(", "));
    if !report.missing.is_empty() {
        println!("missing     {}", report.missing.join(", "));
    }
    if let Some(f) = report.splat_format {
        let note = if report.morton_reordered {
            " (Gaussians sorted into Morton order for rendering)"
        } else {
            ""
        };
        println!("format      {f}{note}");
    }
    if let Some(c) = &report.collision {
        println!("collision   {c}");
    }
    for w in &report.warnings {
        println!("warning     {w}");
    }
    println!("loaded in   {elapsed:.2} s");
    Ok(())
}
