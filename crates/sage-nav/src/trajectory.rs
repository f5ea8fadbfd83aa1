//! Trajectory generation at scale: sample pairs, plan, shortcut, resample, write; over many
//! scenes with resume.
//!
//! Determinism: candidate pairs are drawn one after another from a ChaCha8 stream seeded by the
//! scene seed; each batch of candidates is planned in parallel, and acceptance runs in candidate
//! order, so the output is the same byte for byte with any thread count.

use crate::GridSource;
use crate::astar::Search;
use crate::cost::CostParams;
use crate::grid::GridParams;
use crate::path;
use crate::pathfinder::PathFinder;
use crate::sampling::{Endpoints, Pair, SamplingParams};
use crate::semantic_map::SemanticMap;
use glam::Vec2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_io::runner::{Status, resume_or_run};
use sage_scene::Scene;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// File name of a scene's trajectories; its presence marks the scene as done.
pub const TRAJECTORIES_FILE: &str = "trajectories.json";
/// File name of the map with the paths drawn.
pub const TRAJECTORIES_PNG: &str = "trajectories.png";
/// Candidates planned per parallel batch.
const BATCH: usize = 256;

/// The most trajectories a scene may be asked for.
pub const MAX_TRAJECTORIES: usize = 100_000;

/// The farthest apart a trajectory's points may be, metres. The points are taken at equal
/// distances along the planned path, so two points on either side of a corner are joined by a
/// chord that leaves the path by up to half the step: at 0.5 m that stays within the 0.25 m
/// the planner keeps between the default robot and the walls, where a longer step would draw
/// reference paths through walls.
pub const MAX_STEP: f32 = 0.5;

/// Everything that decides a scene's trajectories.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryParams {
    /// Trajectories wanted per scene.
    pub count: usize,
    /// Seed (each scene mixes in a hash of its name).
    pub seed: u64,
    /// Resampling step, metres (default 0.25).
    pub step: f32,
    /// Grid parameters.
    #[serde(with = "grid_params_serde")]
    pub grid: GridParams,
    /// Cost parameters.
    pub cost: CostParams,
    /// Endpoint sampling parameters.
    pub sampling: SamplingParams,
}

impl Default for TrajectoryParams {
    fn default() -> Self {
        TrajectoryParams {
            count: 100,
            seed: 0,
            step: 0.25,
            grid: GridParams::default(),
            cost: CostParams::default(),
            sampling: SamplingParams::default(),
        }
    }
}

mod grid_params_serde {
    use super::GridParams;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    struct Repr {
        cell: f32,
        agent_height: f32,
        slab_bottom: f32,
        margin: f32,
    }

    pub fn serialize<S: Serializer>(g: &GridParams, s: S) -> Result<S::Ok, S::Error> {
        Repr {
            cell: g.cell,
            agent_height: g.agent_height,
            slab_bottom: g.slab_bottom,
            margin: g.margin,
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<GridParams, D::Error> {
        let r = Repr::deserialize(d)?;
        Ok(GridParams {
            cell: r.cell,
            agent_height: r.agent_height,
            slab_bottom: r.slab_bottom,
            margin: r.margin,
        })
    }
}

impl TrajectoryParams {
    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        if !(self.step > 0.0 && self.step <= MAX_STEP) {
            return Err(Error::invalid(format!(
                "`step` must be > 0 and at most {MAX_STEP} m (points further apart cut corners through walls), got {}",
                self.step
            )));
        }
        if self.count > MAX_TRAJECTORIES {
            return Err(Error::invalid(format!(
                "`count` must be at most {MAX_TRAJECTORIES} trajectories per scene, got {}",
                self.count
            )));
        }
        self.grid.validate()?;
        self.cost.validate()?;
        self.sampling.validate()
    }

    /// The seed of one scene: the run seed mixed with a hash of the scene name, so a scene's
    /// trajectories do not depend on which other scenes are in the run.
    pub fn scene_seed(&self, scene: &str) -> u64 {
        self.seed ^ sage_io::hash::fnv1a64(scene.as_bytes())
    }
}

/// One end of a trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EndRef {
    /// `room`, `object` or `area`.
    pub kind: crate::EndpointKind,
    /// `room_{index}`, the item id, or the area id.
    #[serde(rename = "ref")]
    pub reference: String,
    /// Room type, category or area name.
    pub label: String,
    /// Stand point `[x, y, z]`, W frame, z = floor.
    pub point: [f32; 3],
}

/// One trajectory (W frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Index within the scene.
    pub id: usize,
    /// Where it starts.
    pub start: EndRef,
    /// Where it ends.
    pub goal: EndRef,
    /// Points every `step` metres `[x, y, z]`, z = floor.
    pub points: Vec<[f32; 3]>,
    /// Heading at each point, radians (the last faces the goal object or area).
    pub headings: Vec<f32>,
    /// Length of the path, metres.
    pub length: f32,
    /// Geodesic (shortest) distance between the two stand points, metres.
    pub geodesic_distance: f32,
    /// Planning cost (length × cost multipliers).
    pub cost: f32,
}

/// What sampling did in one scene.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SamplingReport {
    /// Trajectories wanted.
    pub requested: usize,
    /// Trajectories written.
    pub generated: usize,
    /// Candidate pairs drawn.
    pub candidates: usize,
    /// Rejected: stand points closer than `min_distance`.
    pub rejected_too_close: usize,
    /// Rejected: no path (different islands).
    pub rejected_unreachable: usize,
    /// Rejected: path shorter than `min_length`.
    pub rejected_too_short: usize,
    /// Rejected: its length bin already had its share.
    pub rejected_bin_full: usize,
    /// Rejected: the same path as a trajectory already taken (the same endpoints drawn again
    /// with the same stand points), which would weigh one route twice in a benchmark.
    #[serde(default)]
    pub rejected_duplicate: usize,
    /// Endpoints available per kind.
    pub endpoints: BTreeMap<String, usize>,
    /// Trajectories per `start_kind->goal_kind`.
    pub by_kinds: BTreeMap<String, usize>,
    /// Trajectories per length bin (`short`, `medium`, `long` for the default edges).
    pub by_length: BTreeMap<String, usize>,
    /// Mean path length, metres.
    pub mean_length: f32,
}

/// The trajectories of one scene: the file `trajectories.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectorySet {
    /// Scene name.
    pub scene: String,
    /// The scene's seed (see [`TrajectoryParams::scene_seed`]).
    pub seed: u64,
    /// Frame of every coordinate (`W`).
    pub frame: String,
    /// sage3d version that wrote it.
    pub version: String,
    /// Where the grid came from.
    pub grid_source: String,
    /// The resolved settings.
    pub settings: TrajectoryParams,
    /// FNV-1a 64 hashes of the scene's input files when the trajectories were made
    /// ([`sage_io::scenes::input_hashes`]): a rerun keeps the file only while they still hold
    /// ([`run_scene`]). Empty where no scene folder was read ([`generate`] alone), and in files
    /// written before the field, which a rerun therefore makes again.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, String>,
    /// What sampling did.
    pub report: SamplingReport,
    /// The trajectories.
    pub trajectories: Vec<Trajectory>,
}

/// Time spent per stage, summed over the candidates planned (all threads).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Drawing pairs.
    pub sampling: Duration,
    /// A* with the cost function.
    pub astar: Duration,
    /// Line-of-sight shortcutting.
    pub shortcut: Duration,
    /// Resampling and headings.
    pub resample: Duration,
    /// The geodesic distance (a second, length-only A*).
    pub geodesic: Duration,
    /// Candidates planned (A* run).
    pub planned: usize,
}

impl std::ops::AddAssign for StageTimes {
    fn add_assign(&mut self, o: StageTimes) {
        self.sampling += o.sampling;
        self.astar += o.astar;
        self.shortcut += o.shortcut;
        self.resample += o.resample;
        self.geodesic += o.geodesic;
        self.planned += o.planned;
    }
}

/// The outcome of planning one candidate.
enum Planned {
    TooClose,
    Unreachable,
    Done(Box<Trajectory>),
}

/// Plans one candidate into a trajectory (id 0; set on acceptance).
fn plan_pair(
    pf: &PathFinder,
    endpoints: &Endpoints,
    pair: &Pair,
    params: &TrajectoryParams,
    search: &mut Search,
    times: &mut StageTimes,
) -> Planned {
    let (s, g) = (pair.start_stand, pair.goal_stand);
    if s.point.distance(g.point) < params.sampling.min_distance {
        return Planned::TooClose;
    }
    if pf.island_of_cell(s.cell) != pf.island_of_cell(g.cell) {
        return Planned::Unreachable;
    }
    times.planned += 1;
    let t = Instant::now();
    let Some(cost) = search.astar(&pf.graph(), s.cell, g.cell) else {
        return Planned::Unreachable;
    };
    let mut cells = Vec::new();
    search.path_to(g.cell, &mut cells);
    times.astar += t.elapsed();
    let t = Instant::now();
    let waypoints = pf.waypoints(&cells);
    times.shortcut += t.elapsed();
    let t = Instant::now();
    let pts = sage_core::geometry::resample_polyline(&waypoints, params.step);
    let goal_end = &endpoints.list[pair.goal];
    let headings = path::headings(&pts, g.facing);
    let length = path::polyline_length(&waypoints);
    times.resample += t.elapsed();
    let t = Instant::now();
    let geodesic = pf
        .geodesic_cells(search, s.cell, g.cell)
        .unwrap_or(length)
        .min(length);
    times.geodesic += t.elapsed();
    let end = |e: &crate::sampling::Endpoint, p: Vec2| EndRef {
        kind: e.kind,
        reference: e.reference.clone(),
        label: e.label.clone(),
        point: [p.x, p.y, 0.0],
    };
    Planned::Done(Box::new(Trajectory {
        id: 0,
        start: end(&endpoints.list[pair.start], s.point),
        goal: end(goal_end, g.point),
        points: pts.iter().map(|p| [p.x, p.y, 0.0]).collect(),
        headings,
        length,
        geodesic_distance: geodesic,
        cost: cost * pf.grid.cell,
    }))
}

/// Names of the length bins for `edges`.
fn bin_names(edges: &[f32]) -> Vec<String> {
    if edges.len() == 2 {
        return vec!["short".into(), "medium".into(), "long".into()];
    }
    (0..=edges.len())
        .map(|b| {
            let lo = if b == 0 { 0.0 } else { edges[b - 1] };
            match edges.get(b) {
                Some(hi) => format!("{lo}-{hi}m"),
                None => format!(">{lo}m"),
            }
        })
        .collect()
}

/// Everything built for a scene before sampling: reused by the CLI for its images.
pub struct Prepared {
    /// The path finder.
    pub finder: PathFinder,
    /// Where its grid came from.
    pub source: GridSource,
    /// The semantic map.
    pub map: SemanticMap,
    /// The endpoints.
    pub endpoints: Endpoints,
}

/// Builds the grid, clearance, costs, map and endpoints of a scene.
pub fn prepare(scene: &Scene, params: &TrajectoryParams) -> Result<Prepared> {
    params.validate()?;
    let (finder, source) = PathFinder::from_scene(scene, &params.grid, params.cost.clone())?;
    let map = SemanticMap::build(scene);
    let endpoints = Endpoints::collect(&map, &finder, &params.sampling);
    Ok(Prepared {
        finder,
        source,
        map,
        endpoints,
    })
}

/// Generates the trajectories of a prepared scene (see the module docs); also returns the
/// stage times.
///
/// # Errors
///
/// An `invalid` error when the scene has fewer than two endpoints.
pub fn generate(
    scene_name: &str,
    prep: &Prepared,
    params: &TrajectoryParams,
) -> Result<(TrajectorySet, StageTimes)> {
    let sp = &params.sampling;
    if prep.endpoints.list.len() < 2 {
        return Err(Error::invalid(format!(
            "scene {scene_name}: fewer than two endpoints with a navigable stand point"
        )));
    }
    let seed = params.scene_seed(scene_name);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let names = bin_names(&sp.length_edges);
    let quota: Option<Vec<usize>> = sp.length_mix.as_ref().map(|mix| {
        let total: f32 = mix.iter().sum();
        mix.iter()
            .map(|m| (m / total * params.count as f32).ceil() as usize)
            .collect()
    });
    let mut in_bin = vec![0usize; names.len()];
    let mut report = SamplingReport {
        requested: params.count,
        ..SamplingReport::default()
    };
    let mut times = StageTimes::default();
    let mut out: Vec<Trajectory> = Vec::with_capacity(params.count);
    let mut taken: HashSet<PathKey> = HashSet::new();
    let max_candidates = params.count.saturating_mul(sp.attempts_per_trajectory);
    while out.len() < params.count && report.candidates < max_candidates {
        let t = Instant::now();
        let n = BATCH.min(max_candidates - report.candidates);
        let pairs: Vec<Pair> = (0..n)
            .filter_map(|_| prep.endpoints.draw_pair(&mut rng, sp))
            .collect();
        times.sampling += t.elapsed();
        let planned: Vec<(Planned, StageTimes)> = pairs
            .par_iter()
            .map_init(Search::new, |search, pair| {
                let mut st = StageTimes::default();
                let p = plan_pair(&prep.finder, &prep.endpoints, pair, params, search, &mut st);
                (p, st)
            })
            .collect();
        for (p, st) in planned {
            times += st;
            if out.len() == params.count {
                break;
            }
            report.candidates += 1;
            let mut t = match p {
                Planned::TooClose => {
                    report.rejected_too_close += 1;
                    continue;
                }
                Planned::Unreachable => {
                    report.rejected_unreachable += 1;
                    continue;
                }
                Planned::Done(t) => t,
            };
            if t.length < sp.min_length {
                report.rejected_too_short += 1;
                continue;
            }
            if !taken.insert(path_key(&t)) {
                report.rejected_duplicate += 1;
                continue;
            }
            let bin = sp.bin_of(t.length);
            if quota.as_ref().is_some_and(|q| in_bin[bin] >= q[bin]) {
                report.rejected_bin_full += 1;
                continue;
            }
            in_bin[bin] += 1;
            t.id = out.len();
            *report
                .by_kinds
                .entry(format!(
                    "{}->{}",
                    t.start.kind.as_str(),
                    t.goal.kind.as_str()
                ))
                .or_insert(0) += 1;
            out.push(*t);
        }
        if pairs.is_empty() {
            break;
        }
    }
    report.generated = out.len();
    report.by_length = names.iter().cloned().zip(in_bin).collect();
    report.endpoints = crate::EndpointKind::ALL
        .iter()
        .zip(prep.endpoints.counts())
        .map(|(k, n)| (k.as_str().to_string(), n))
        .collect();
    report.mean_length = if out.is_empty() {
        0.0
    } else {
        out.iter().map(|t| t.length).sum::<f32>() / out.len() as f32
    };
    Ok((
        TrajectorySet {
            scene: scene_name.to_string(),
            seed,
            frame: "W".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            grid_source: prep.source.as_str().into(),
            settings: params.clone(),
            inputs: BTreeMap::new(),
            report,
            trajectories: out,
        },
        times,
    ))
}

/// What makes two trajectories the same route: their endpoints and their points, bit for bit.
type PathKey = (String, String, Vec<[u32; 3]>);

fn path_key(t: &Trajectory) -> PathKey {
    (
        t.start.reference.clone(),
        t.goal.reference.clone(),
        t.points.iter().map(|p| p.map(f32::to_bits)).collect(),
    )
}

/// Draws the semantic map with every trajectory (start green, goal red).
pub fn draw_trajectories(prep: &Prepared, set: &TrajectorySet) -> sage_io::Canvas {
    let legend = [
        ([20, 90, 220], "path".to_string()),
        ([0, 160, 0], "start".to_string()),
        ([220, 0, 0], "goal".to_string()),
    ];
    let (mut canvas, _) = prep.map.draw(&prep.finder.grid, &legend);
    for t in &set.trajectories {
        for w in t.points.windows(2) {
            canvas.line(
                Vec2::new(w[0][0], w[0][1]),
                Vec2::new(w[1][0], w[1][1]),
                legend[0].0,
                1,
            );
        }
    }
    for t in &set.trajectories {
        canvas.disc(
            Vec2::new(t.start.point[0], t.start.point[1]),
            3,
            legend[1].0,
        );
        canvas.disc(Vec2::new(t.goal.point[0], t.goal.point[1]), 3, legend[2].0);
    }
    canvas
}

/// What happened to one scene of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneOutcome {
    /// Scene folder.
    pub scene: PathBuf,
    /// Made, resumed (already complete) or skipped.
    pub status: Status,
    /// Trajectories in its file.
    pub trajectories: usize,
    /// Why it was skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// FNV-1a 64 hashes of the input files the navigation reads.
    pub inputs: BTreeMap<String, String>,
}

/// Generates and writes one scene's outputs into `out`: `trajectories.png`, then
/// `trajectories.json` (written last, atomically: its presence means the scene is complete).
/// A scene whose file exists with the same settings and the same hashes of the scene's input
/// files is left as it is (`resumed`); an edited scene is made again.
pub fn run_scene(scene_dir: &Path, out: &Path, params: &TrajectoryParams) -> SceneOutcome {
    let done = out.join(TRAJECTORIES_FILE);
    // Hashed before the scene is read: a file edited while this scene runs then differs from
    // what is recorded, and the next run makes the scene again.
    let inputs = sage_io::scenes::input_hashes(scene_dir);
    let outcome = resume_or_run(
        || complete_with(&done, params, &inputs),
        || {
            let (scene, _) = Scene::load(scene_dir)?;
            let prep = prepare(&scene, params)?;
            let (mut set, _) = generate(&scene.name, &prep, params)?;
            set.inputs = inputs.clone();
            std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
            draw_trajectories(&prep, &set).save_png(&out.join(TRAJECTORIES_PNG))?;
            sage_io::files::write_json(&done, &set)?;
            Ok(set.trajectories.len())
        },
    );
    SceneOutcome {
        scene: scene_dir.to_path_buf(),
        status: outcome.status,
        trajectories: outcome.count,
        reason: outcome.reason,
        inputs,
    }
}

/// The trajectory count of a complete output file written with `params` from input files
/// whose hashes are `inputs`, if there is one.
fn complete_with(
    path: &Path,
    params: &TrajectoryParams,
    inputs: &BTreeMap<String, String>,
) -> Option<usize> {
    let text = std::fs::read_to_string(path).ok()?;
    let set: TrajectorySet = serde_json::from_str(&text).ok()?;
    (set.settings == *params && set.inputs == *inputs).then_some(set.trajectories.len())
}

/// Refuses scene folders whose names are not plain names ([`sage_io::names::check_plain`]):
/// a scene is named by its folder, episodes and trajectory files carry that name, and every
/// reader of episodes refuses any other, so a run over such a folder would write what nothing
/// reads back. Checked over all `dirs` before any work.
///
/// # Errors
///
/// An `invalid` error naming the first such folder and the rule.
pub fn check_scene_names(dirs: &[PathBuf]) -> Result<()> {
    for dir in dirs {
        let name = sage_io::scenes::scene_name(dir);
        sage_io::names::check_plain("scene", &name).map_err(|e| {
            Error::invalid(format!(
                "{} (a scene is named by its folder: rename the folder)",
                e.message()
            ))
            .in_file(dir)
        })?;
    }
    Ok(())
}
