//! `sage3d nav …`: semantic maps, occupancy grids and trajectories.

use clap::{Args, Subcommand};
use sage_core::named::comma_list;
use sage_core::{Error, Result};
use sage_io::runner::{Status, Tally};
use sage_nav::GridParams;
use sage_nav::trajectory::TrajectoryParams;
use sage_pipeline::nav::MapReport;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum NavCommand {
    /// Write a scene's semantic top-down map (JSON + PNG with legend) and its occupancy grid
    /// (InteriorGS occupancy.png/json) for an agent height.
    Map(MapArgs),
    /// Generate trajectories for a scene, or for every scene folder inside a folder (parallel
    /// over scenes, resumable: complete scenes with the same settings and unchanged scene files
    /// are skipped).
    Trajectories(TrajectoriesArgs),
}

/// Grid settings shared by the commands.
#[derive(Args, Clone)]
pub struct GridArgs {
    /// Cell size, metres.
    #[arg(long, default_value_t = GridParams::default().cell)]
    cell: f32,
    /// Agent height: the top of the obstacle slab, metres.
    #[arg(long, default_value_t = GridParams::default().agent_height)]
    agent_height: f32,
}

impl GridArgs {
    fn grid(&self) -> GridParams {
        GridParams {
            cell: self.cell,
            agent_height: self.agent_height,
            ..GridParams::default()
        }
    }
}

#[derive(Args)]
pub struct MapArgs {
    /// Scene folder.
    scene: PathBuf,
    /// Output folder (default: SCENE/nav): new, empty, or a nav folder this command or
    /// `nav trajectories` wrote (rerunning replaces the maps).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    grid: GridArgs,
}

#[derive(Args)]
pub struct TrajectoriesArgs {
    /// A scene folder, or a folder of scene folders.
    scenes: PathBuf,
    /// Trajectories per scene (at most 100,000).
    #[arg(long, default_value_t = TrajectoryParams::default().count)]
    count: usize,
    /// Seed (each scene mixes in a hash of its name).
    #[arg(long, default_value_t = TrajectoryParams::default().seed)]
    seed: u64,
    /// Output folder: one sub-folder per scene, and sage3d_run.json (default: SCENES/nav for a
    /// scene, SCENES/../nav_trajectories for a folder of scenes); new, empty, or a nav folder
    /// this command or `nav map` wrote (rerunning resumes).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Resampling step, metres (at most 0.5: points further apart are joined around corners
    /// by chords through walls).
    #[arg(long, default_value_t = TrajectoryParams::default().step)]
    step: f32,
    /// Robot radius, metres (navigable cells keep a further 0.05 m safety margin).
    #[arg(long, default_value_t = TrajectoryParams::default().cost.robot_radius)]
    radius: f32,
    /// Narrow-passage penalty weight (0: off).
    #[arg(long, default_value_t = TrajectoryParams::default().cost.narrow_weight)]
    narrow_weight: f32,
    /// Least straight-line start–goal distance, metres.
    #[arg(long, default_value_t = TrajectoryParams::default().sampling.min_distance)]
    min_distance: f32,
    /// Shares of short / medium / long paths (SPEC §9 bins), e.g. 0.4,0.4,0.2 (default: free).
    #[arg(long, value_delimiter = ',')]
    length_mix: Option<Vec<f32>>,
    /// Weights of room, object and area endpoints, e.g. 1,2,1.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = comma_list(&TrajectoryParams::default().sampling.kind_weights)
    )]
    kinds: Vec<f32>,
    #[command(flatten)]
    grid: GridArgs,
}

pub fn run(cmd: NavCommand) -> Result<()> {
    match cmd {
        NavCommand::Map(a) => map(a),
        NavCommand::Trajectories(a) => trajectories(a),
    }
}

fn map(a: MapArgs) -> Result<()> {
    let report = sage_pipeline::nav::map_into(&a.scene, a.out.as_deref(), &a.grid.grid(), a.force)?;
    print_map(&report);
    Ok(())
}

/// Prints what the map step wrote.
pub fn print_map(r: &MapReport) {
    println!(
        "{}: {} items, {} walls, {} doors, {} rooms; grid {} x {} at {} m from {} ({} free, {} occupied, {} unknown) -> {}",
        r.scene,
        r.items,
        r.walls,
        r.doors,
        r.rooms,
        r.width,
        r.height,
        r.cell,
        r.source,
        r.free,
        r.occupied,
        r.unknown,
        r.out.display()
    );
    if let Some(n) = r.published_entries {
        println!(
            "  the published builder's map of the scene's occupancy image: {n} entries -> {}",
            r.out
                .join(sage_nav::published_map::file_name(&r.scene))
                .display()
        );
    }
}

fn trajectory_params(a: &TrajectoriesArgs) -> Result<TrajectoryParams> {
    let mut p = TrajectoryParams {
        count: a.count,
        seed: a.seed,
        step: a.step,
        grid: a.grid.grid(),
        ..TrajectoryParams::default()
    };
    p.cost.robot_radius = a.radius;
    p.cost.narrow_weight = a.narrow_weight;
    p.sampling.min_distance = a.min_distance;
    p.sampling.length_mix = a.length_mix.clone();
    p.sampling.kind_weights = match a.kinds.as_slice() {
        [r, o, ar] if a.kinds.iter().all(|w| *w >= 0.0) && r + o + ar > 0.0 => [*r, *o, *ar],
        other => {
            return Err(Error::invalid(format!(
                "--kinds needs three weights (room,object,area) >= 0, not all 0, got {other:?}"
            )));
        }
    };
    // The planner's setting is `robot_radius`; this command line calls it --radius.
    p.validate()
        .map_err(|e| Error::invalid(e.to_string().replace("`robot_radius`", "--radius")))?;
    Ok(p)
}

fn trajectories(a: TrajectoriesArgs) -> Result<()> {
    let params = trajectory_params(&a)?;
    let bar = crate::progress::bar("{bar:30} {pos}/{len} scenes {elapsed} (eta {eta})");
    let start = Instant::now();
    let report =
        sage_pipeline::nav::trajectories(&a.scenes, a.out.as_deref(), &params, a.force, &|_, n| {
            bar.set_length(n as u64);
            bar.inc(1);
        });
    bar.finish_and_clear();
    let report = report?;
    let outcomes = &report.outcomes;
    let tally = Tally::of(outcomes.iter().map(|o| o.status));
    let total: usize = outcomes.iter().map(|o| o.trajectories).sum();
    for o in outcomes.iter().filter(|o| o.status == Status::Skipped) {
        eprintln!(
            "skipped {}: {}",
            o.scene.display(),
            o.reason.as_deref().unwrap_or("")
        );
    }
    println!(
        "{} scenes: {tally}; {total} trajectories in {} ({:.1} s)",
        outcomes.len(),
        report.out.display(),
        start.elapsed().as_secs_f64()
    );
    // Fewer than asked is a property of the scene (too small for the distances asked), said
    // but not a failure; none at all is.
    for o in outcomes
        .iter()
        .filter(|o| o.status != Status::Skipped && o.trajectories < params.count)
    {
        eprintln!(
            "note: {}: {} of {} trajectories; its trajectories.json counts the candidates rejected, by reason",
            o.scene.display(),
            o.trajectories,
            params.count
        );
    }
    if tally.skipped > 0 {
        return Err(Error::invalid(format!(
            "{} of {} scenes were skipped (listed above); they have no trajectories, and a rerun retries them",
            tally.skipped,
            outcomes.len()
        )));
    }
    if total == 0 && params.count > 0 {
        return Err(Error::invalid(
            "no trajectory was made in any scene (see the notes above)",
        ));
    }
    Ok(())
}
