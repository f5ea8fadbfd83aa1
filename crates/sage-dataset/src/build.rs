//! The dataset pipeline (`sage3d data build`): over a folder of scenes, in parallel and
//! resumable, from trajectories to instructions, episodes, splits and files.
//!
//! Per scene (the unit of work and of resume): trajectories by `sage_nav` (its own seeded,
//! thread-count-independent sampler), the text map, then for trajectory `t` a ChaCha8 stream
//! seeded by (run seed, scene) on stream `t` draws its instructions — one Single-Goal and up to
//! one per high-level type (grammar, or the LLM with its answers validated) — and the
//! ground-truth actions; Base-Action and no-goal episodes use streams of their own. The scene's
//! episodes and report go to `scenes/{scene}.json`, written last and atomically: a rerun skips
//! scenes whose file holds the same settings. Then the whole dataset is assembled (splits,
//! balanced test selection, files, summary), which depends only on the scene files, so the same
//! seed gives the same bytes with any thread count.

use crate::episode::{Episode, Goal, StartPose, Task};
use crate::folder;
use crate::formats::gvln::{self, GvlnFrame};
use crate::formats::{jsonl, r2r};
use crate::selector;
use crate::slices::{Slices, assets_slice, path_slice};
use crate::split::{self, SPLITS, SplitParams};
use glam::Vec2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_io::files::write_json;
use sage_io::runner::{Status, resume_or_run};
use sage_lang::actions::{self, StepSizes};
use sage_lang::instruction::Instruction;
use sage_lang::llm::{self, LlmClient, LlmConfig};
use sage_lang::validate::ValidationReport;
use sage_lang::{InstructionType, TextMap, Validator, highlevel, lowlevel};
use sage_nav::trajectory::{self, Trajectory, TrajectoryParams};
use sage_scene::Scene;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The no-goal instruction (the published default, completed).
pub const NOGOAL_TEXT: &str =
    "Explore this environment as much as possible, but avoid colliding with anything.";
pub use crate::folder::COMMAND;

/// What a dataset build writes at the top of its folder (the LLM cache is there by default).
pub const OUTPUTS: [&str; 9] = [
    "episodes",
    "gvln",
    "r2r",
    "scenes",
    "llm_cache",
    folder::SPLITS_FILE,
    "summary.json",
    "summary.txt",
    sage_io::RUN_RECORD,
];

/// Draws per instruction before the grammar gives up on a type for a trajectory.
const ATTEMPTS: usize = 3;
/// Stream offsets of the per-scene random streams (trajectories use stream `t`).
const BASE_STREAM: u64 = 1 << 32;
const NOGOAL_STREAM: u64 = 2 << 32;

/// Everything that decides a scene's episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneParams {
    /// Trajectories per scene (each gives one Single-Goal and up to five high-level episodes).
    pub per_scene: usize,
    /// Run seed.
    pub seed: u64,
    /// Base-Action episodes per scene.
    pub base_actions: usize,
    /// No-goal episodes per scene.
    pub nogoal: usize,
    /// High-level instructions kept per type and trajectory (LLM answers hold 2–4).
    pub high_per_type: usize,
    /// The discrete action space of the ground truth.
    pub space: StepSizes,
    /// Trajectory settings (count and seed are set from the above).
    pub trajectories: TrajectoryParams,
    /// The LLM endpoint for high-level instructions (`None`: the offline grammar).
    pub llm: Option<LlmConfig>,
}

impl SceneParams {
    /// Defaults for `per_scene` trajectories and `seed`: a quarter as many Base-Actions, one
    /// no-goal episode, one high-level instruction per type, the `vlnce` action space.
    pub fn new(per_scene: usize, seed: u64) -> SceneParams {
        SceneParams {
            per_scene,
            seed,
            base_actions: per_scene.div_ceil(4),
            nogoal: 1,
            high_per_type: 1,
            space: StepSizes::default(),
            trajectories: TrajectoryParams {
                count: per_scene,
                seed,
                ..TrajectoryParams::default()
            },
            llm: None,
        }
    }

    /// The settings with trajectories planned for the ground agent profile `agent` (`wheeled`,
    /// `go2`, `g1`, `h1`): its radius is the planner's inflation, so every reference path leaves
    /// that robot room to pass (docs/dataset.md). The default plans for `wheeled` (0.2 m).
    ///
    /// # Errors
    ///
    /// An unknown profile, or one that does not walk (the UAV).
    pub fn for_agent(mut self, agent: &str) -> Result<SceneParams> {
        let profile: sage_physics::AgentProfile = agent.parse()?;
        if profile.kind != sage_physics::Locomotion::Ground {
            return Err(Error::invalid(format!(
                "agent '{agent}': datasets are planned for ground agents (wheeled, go2, g1, h1)"
            )));
        }
        self.trajectories.cost.robot_radius = profile.radius;
        Ok(self)
    }

    /// Checks the settings: counts per scene of at most [`trajectory::MAX_TRAJECTORIES`], a usable action
    /// space, and the trajectory settings.
    pub fn validate(&self) -> Result<()> {
        for (name, count) in [
            ("per_scene", self.per_scene),
            ("base_actions", self.base_actions),
            ("nogoal", self.nogoal),
            ("high_per_type", self.high_per_type),
        ] {
            if count > trajectory::MAX_TRAJECTORIES {
                return Err(Error::invalid(format!(
                    "`{name}` must be at most {} per scene, got {count}",
                    trajectory::MAX_TRAJECTORIES
                )));
            }
        }
        if !(self.space.forward > 0.0 && self.space.turn_deg > 0.0 && self.space.turn_deg <= 180.0)
        {
            return Err(Error::invalid(format!(
                "action space: need forward > 0 and 0 < turn <= 180, got {:?}",
                self.space
            )));
        }
        if self.trajectories.count != self.per_scene || self.trajectories.seed != self.seed {
            return Err(Error::invalid(
                "trajectory count and seed must equal per_scene and seed",
            ));
        }
        self.trajectories.validate()
    }
}

/// What one scene produced besides its episodes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneReport {
    /// Objects in the scene (the asset count of the slices).
    pub assets: usize,
    /// Trajectories generated.
    pub trajectories: usize,
    /// Trajectories dropped because discrete actions cannot follow them.
    pub unfollowable: usize,
    /// Per type: trips the type did not fit (no unique reference, no relation, …).
    pub not_applicable: BTreeMap<String, usize>,
    /// Validator counts over every candidate instruction.
    pub validation: ValidationReport,
    /// LLM requests that failed after all retries.
    pub llm_failures: usize,
}

/// A scene's file `scenes/{scene}.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneEpisodes {
    /// Scene name.
    pub scene: String,
    /// The settings it was made with.
    pub settings: SceneParams,
    /// FNV-1a 64 hashes of the scene's input files.
    pub inputs: BTreeMap<String, String>,
    /// What happened.
    pub report: SceneReport,
    /// The episodes.
    pub episodes: Vec<Episode>,
}

/// Where an episode goes: start, goal, reference path, ground truth and distances.
struct Motion {
    start: StartPose,
    goal: Option<Goal>,
    path: Vec<[f32; 3]>,
    actions: Vec<actions::DiscreteAction>,
    length: f32,
    geodesic: f32,
}

/// An episode of `scene` (with `assets` objects) for an instruction and a motion.
fn make_episode(scene: &str, assets: usize, id: String, ins: &Instruction, m: Motion) -> Episode {
    let nogoal = ins.kind == InstructionType::GoalLess;
    Episode {
        episode_id: id,
        scene: scene.to_string(),
        task: if nogoal { Task::Nogoal } else { Task::Vln },
        trajectory_id: None,
        instruction: ins.text.clone(),
        instruction_texts: Default::default(),
        level: ins.kind.level(),
        instruction_type: ins.kind,
        subtype: ins.subtype,
        source: ins.source,
        start_ref: None,
        start: m.start,
        goal: m.goal,
        reference_path: m.path,
        actions: m.actions,
        path_length: m.length,
        geodesic_distance: m.geodesic,
        slices: Slices {
            assets: assets_slice(assets).into(),
            path: if nogoal {
                "none".into()
            } else {
                path_slice(m.length).into()
            },
        },
    }
}

/// The instructions of one trajectory: a Single-Goal and the high-level ones.
fn trajectory_instructions(
    tm: &TextMap,
    validator: &Validator,
    t: &Trajectory,
    params: &SceneParams,
    client: Option<&LlmClient>,
    rng: &mut ChaCha8Rng,
    report: &mut SceneReport,
) -> Vec<Instruction> {
    let mut out = Vec::new();
    let mut not_applicable = |k: InstructionType| {
        *report
            .not_applicable
            .entry(k.as_str().to_string())
            .or_insert(0) += 1
    };
    let draw = |kind: InstructionType,
                rng: &mut ChaCha8Rng,
                report_v: &mut ValidationReport|
     -> Option<Instruction> {
        for _ in 0..ATTEMPTS {
            let ins = if kind == InstructionType::SingleGoal {
                lowlevel::single_goal(tm, &t.start, &t.goal, rng)
            } else {
                highlevel::generate(tm, &t.start, &t.goal, kind, rng)
            }?;
            let outcome = validator.check(&ins.text, kind);
            report_v.record(outcome);
            if outcome.is_ok() {
                return Some(ins);
            }
        }
        None
    };
    let mut v = std::mem::take(&mut report.validation);
    match draw(InstructionType::SingleGoal, rng, &mut v) {
        Some(i) => out.push(i),
        None => not_applicable(InstructionType::SingleGoal),
    }
    match client {
        Some(c) => match c.ask(tm, &t.start.reference, &t.goal.reference, &t.id.to_string()) {
            Ok(items) => {
                let accepted = llm::accept(
                    &items,
                    &t.start.reference,
                    &t.goal.reference,
                    validator,
                    &mut v,
                );
                for kind in InstructionType::HIGH {
                    out.extend(
                        accepted
                            .iter()
                            .filter(|i| i.kind == kind)
                            .take(params.high_per_type)
                            .cloned(),
                    );
                }
            }
            Err(_) => report.llm_failures += 1,
        },
        None => {
            for kind in InstructionType::HIGH {
                for _ in 0..params.high_per_type {
                    match draw(kind, rng, &mut v) {
                        Some(i) if !out.iter().any(|o| o.text == i.text) => out.push(i),
                        Some(_) => {}
                        None => not_applicable(kind),
                    }
                }
            }
        }
    }
    report.validation = v;
    out
}

/// The Base-Action plan to write, if any: one whose instruction passes the validator, as every
/// instruction written does. The check is counted in `report`'s validation; a scene without a
/// start for the motion, or an instruction the validator rejects, counts as a Base-Action trip
/// not applicable (no episode).
fn validated_base_action(
    validator: &Validator,
    plan: Option<lowlevel::BaseActionPlan>,
    report: &mut SceneReport,
) -> Option<lowlevel::BaseActionPlan> {
    let checked = plan.filter(|p| {
        let outcome = validator.check(&p.instruction.text, InstructionType::BaseAction);
        report.validation.record(outcome);
        outcome.is_ok()
    });
    if checked.is_none() {
        *report
            .not_applicable
            .entry(InstructionType::BaseAction.as_str().into())
            .or_insert(0) += 1;
    }
    checked
}

/// Builds the episodes of one loaded scene.
pub fn scene_episodes(
    scene: &Scene,
    params: &SceneParams,
    client: Option<&LlmClient>,
) -> Result<(SceneReport, Vec<Episode>)> {
    params.validate()?;
    let prep = trajectory::prepare(scene, &params.trajectories)?;
    let (set, _) = trajectory::generate(&scene.name, &prep, &params.trajectories)?;
    let tm = TextMap::build(scene, &prep.map, &prep.endpoints);
    let validator = Validator::new(&tm);
    let assets = scene.objects.len();
    let make =
        |id: String, ins: &Instruction, m: Motion| make_episode(&scene.name, assets, id, ins, m);
    let seed = params.trajectories.scene_seed(&scene.name);
    let rng_on = |stream: u64| {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        r.set_stream(stream);
        r
    };
    let mut report = SceneReport {
        assets,
        trajectories: set.trajectories.len(),
        ..SceneReport::default()
    };
    let mut episodes = Vec::new();
    for t in &set.trajectories {
        let flat: Vec<Vec2> = t.points.iter().map(|p| Vec2::new(p[0], p[1])).collect();
        let start_yaw = t.headings.first().copied().unwrap_or(0.0);
        let Some(acts) =
            actions::follow(&flat, start_yaw, t.headings.last().copied(), &params.space)
        else {
            report.unfollowable += 1;
            continue;
        };
        let mut rng = rng_on(t.id as u64);
        let instructions =
            trajectory_instructions(&tm, &validator, t, params, client, &mut rng, &mut report);
        for (k, ins) in instructions.iter().enumerate() {
            let goal = Goal {
                reference: t.goal.reference.clone(),
                kind: t.goal.kind.as_str().into(),
                position: t.goal.point,
                yaw: None,
            };
            let mut e = make(
                format!("{}-t{}-{k}", scene.name, t.id),
                ins,
                Motion {
                    start: StartPose {
                        position: t.start.point,
                        yaw: start_yaw,
                    },
                    goal: Some(goal),
                    path: t.points.clone(),
                    actions: acts.clone(),
                    length: t.length,
                    geodesic: t.geodesic_distance,
                },
            );
            e.trajectory_id = Some(t.id);
            e.start_ref = Some(t.start.reference.clone());
            episodes.push(e);
        }
    }
    for i in 0..params.base_actions {
        let mut rng = rng_on(BASE_STREAM + i as u64);
        let plan = lowlevel::base_action(&prep.finder, &params.space, &mut rng);
        let Some(plan) = validated_base_action(&validator, plan, &mut report) else {
            continue;
        };
        let poses = actions::replay(plan.start, &plan.actions, &params.space);
        let mut path: Vec<[f32; 3]> = poses.iter().map(|p| p.position.into()).collect();
        path.dedup();
        let length: f32 = path
            .windows(2)
            .map(|w| Vec2::new(w[1][0] - w[0][0], w[1][1] - w[0][1]).length())
            // Folded from +0.0: an empty float sum is −0.0 (a turn in place has no segment).
            .fold(0.0, |a, b| a + b);
        let end = *path.last().unwrap_or(&plan.start.position.into());
        let goal = Goal {
            reference: String::new(),
            kind: "pose".into(),
            position: end,
            yaw: poses.last().map(|p| sage_core::wrap_angle(p.yaw)),
        };
        let start = StartPose {
            position: plan.start.position.into(),
            yaw: plan.start.yaw,
        };
        let straight = Vec2::new(end[0] - start.position[0], end[1] - start.position[1]).length();
        episodes.push(make(
            format!("{}-b{i}", scene.name),
            &plan.instruction,
            Motion {
                start,
                goal: Some(goal),
                path,
                actions: plan.actions,
                length,
                geodesic: straight,
            },
        ));
    }
    let nogoal = Instruction {
        text: NOGOAL_TEXT.into(),
        kind: InstructionType::GoalLess,
        subtype: None,
        source: sage_lang::Source::Template,
    };
    for i in 0..params.nogoal {
        let mut rng = rng_on(NOGOAL_STREAM + i as u64);
        let Some(p) = prep.finder.sample_navigable_point(&mut rng, None) else {
            continue;
        };
        let yaw = (rand::Rng::random_range(&mut rng, 0..24) as f32 * 15.0).to_radians();
        let start = StartPose {
            position: [p.x, p.y, 0.0],
            yaw,
        };
        episodes.push(make(
            format!("{}-n{i}", scene.name),
            &nogoal,
            Motion {
                start,
                goal: None,
                path: vec![start.position],
                actions: Vec::new(),
                length: 0.0,
                geodesic: 0.0,
            },
        ));
    }
    Ok((report, episodes))
}

/// The file of a scene's episodes under the dataset folder.
pub fn scene_file(out: &Path, scene: &str) -> PathBuf {
    out.join("scenes").join(format!("{scene}.json"))
}

/// What happened to one scene of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneOutcome {
    /// Scene name.
    pub scene: String,
    /// Made, resumed (already complete) or skipped.
    pub status: Status,
    /// Episodes in its file.
    pub episodes: usize,
    /// Why it was skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// Builds (or resumes) one scene's file: an earlier file is kept only when it was made with
/// `params` from the scene's input files as they are now and no LLM request of it failed. A
/// scene folder whose name is not a plain name is skipped, with the reason
/// ([`trajectory::check_scene_names`]; [`build()`] refuses the whole build over one).
pub fn run_scene(
    dir: &Path,
    out: &Path,
    params: &SceneParams,
    client: Option<&LlmClient>,
) -> SceneOutcome {
    let name = sage_io::scenes::scene_name(dir);
    if let Err(e) = trajectory::check_scene_names(&[dir.to_path_buf()]) {
        // Never a file: its name would leave `scenes/`, or name episodes no reader takes.
        return SceneOutcome {
            scene: name,
            status: Status::Skipped,
            episodes: 0,
            reason: Some(e.to_string()),
        };
    }
    let file = scene_file(out, &name);
    // Complete: made with these settings from the scene's files as they are now, and every
    // LLM request answered (a failed one is retried by the next run, not kept for good).
    let complete = || {
        let text = std::fs::read_to_string(&file).ok()?;
        let done = serde_json::from_str::<SceneEpisodes>(&text).ok()?;
        (done.settings == *params
            && done.report.llm_failures == 0
            && done.inputs == sage_io::scenes::input_hashes(dir))
        .then_some(done.episodes.len())
    };
    let outcome = resume_or_run(complete, || {
        // An earlier build's file of other settings goes first: were this scene to fail now,
        // the assembly would otherwise take that file's episodes for this build's.
        if file.is_file() {
            std::fs::remove_file(&file).map_err(|e| Error::io(&file, e))?;
        }
        // Hashed before the scene is read: a file edited while this scene builds then differs
        // from what is recorded, and the next run builds the scene again.
        let inputs = sage_io::scenes::input_hashes(dir);
        let (mut scene, _) = Scene::load(dir)?;
        scene.name = name.clone();
        let (report, episodes) = scene_episodes(&scene, params, client)?;
        let n = episodes.len();
        let parent = out.join("scenes");
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        write_json(
            &file,
            &SceneEpisodes {
                scene: name.clone(),
                settings: params.clone(),
                inputs,
                report,
                episodes,
            },
        )?;
        Ok(n)
    });
    SceneOutcome {
        scene: name,
        status: outcome.status,
        episodes: outcome.count,
        reason: outcome.reason,
    }
}

/// Writes the dataset's run record into `out`: the scenes folder `scenes` the dataset was
/// built from ([`folder::scenes_record`]: absolute and relative to `out`, so `eval` and `data
/// render` find it), the settings of both steps, the fingerprints of every scene's input
/// files (`dirs`, the scene folders) and the `status`: [`sage_io::run::FINISHED`] when
/// `finished` (the dataset is assembled), else [`sage_io::run::UNFINISHED`], which every
/// reader of the folder refuses ([`folder::check`]) until a rerun finishes it. `sage3d data
/// build` and the distributed build write it unfinished before their work and finished after.
/// The splits that `data import` added to the dataset stay listed (`imports`), so a rebuild
/// keeps them ([`assemble`]).
///
/// # Errors
///
/// The record cannot be written.
pub fn write_run_record(
    out: &Path,
    scenes: &Path,
    dirs: &[std::path::PathBuf],
    params: &SceneParams,
    assemble: &AssembleParams,
    finished: bool,
) -> Result<()> {
    let inputs: BTreeMap<String, _> = dirs
        .iter()
        .map(|d| {
            (
                sage_io::scenes::scene_name(d),
                sage_io::scenes::input_hashes(d),
            )
        })
        .collect();
    let mut details = serde_json::json!({
        "status": if finished { sage_io::run::FINISHED } else { sage_io::run::UNFINISHED },
        "scenes": folder::scenes_record(out, scenes),
        "config": {"scene": params, "assemble": assemble},
        "inputs": inputs,
    });
    if let Some(imports) = folder::imports(out) {
        details["imports"] = imports;
    }
    sage_io::run::write_run_record(out, COMMAND, Some(assemble.seed), details)
}

/// Settings of the assembly step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AssembleParams {
    /// Seed of the split and the selector.
    pub seed: u64,
    /// Split shares.
    pub split: SplitParams,
    /// Size of the balanced test selection (0: none).
    pub balanced: usize,
}

impl AssembleParams {
    /// Assembly with `seed`, a balanced test selection of `balanced` episodes (0: none), and
    /// the shares of scenes held out as scene-unseen test and validation (the rest of the split
    /// settings at their defaults).
    pub fn new(seed: u64, balanced: usize, scene_unseen: f32, val: f32) -> AssembleParams {
        AssembleParams {
            seed,
            split: SplitParams::holding_out(scene_unseen, val),
            balanced,
        }
    }
}

/// Counts of the whole dataset: the dataset's `summary.json`. Named apart from
/// the evaluator's `sage_eval::Summary`, the `summary.json` of an evaluation run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DatasetSummary {
    /// Scenes with episodes.
    pub scenes: usize,
    /// Episodes.
    pub episodes: usize,
    /// Per task.
    pub by_task: BTreeMap<String, usize>,
    /// Per level (`high`, `low`, `none`).
    pub by_level: BTreeMap<String, usize>,
    /// Per instruction type.
    pub by_type: BTreeMap<String, usize>,
    /// Per Single-Goal subtype.
    pub by_subtype: BTreeMap<String, usize>,
    /// Per asset slice.
    pub by_assets: BTreeMap<String, usize>,
    /// Per path slice.
    pub by_path: BTreeMap<String, usize>,
    /// Per split.
    pub by_split: BTreeMap<String, usize>,
    /// Per instruction source.
    pub by_source: BTreeMap<String, usize>,
    /// Episodes in the balanced test selection.
    pub balanced_test: usize,
    /// Validator counts over every candidate.
    pub validation: ValidationReport,
    /// Trips a type did not fit, per type.
    pub not_applicable: BTreeMap<String, usize>,
    /// Trajectories dropped as not followable with discrete actions.
    pub unfollowable: usize,
    /// Failed LLM requests.
    pub llm_failures: usize,
    /// Episodes written to R2R (no-goal excluded).
    pub r2r_episodes: usize,
}

impl DatasetSummary {
    /// A short text table.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} episodes in {} scenes ({} in the balanced test selection)",
            self.episodes, self.scenes, self.balanced_test
        );
        let rows: [(&str, &BTreeMap<String, usize>); 8] = [
            ("split", &self.by_split),
            ("task", &self.by_task),
            ("level", &self.by_level),
            ("type", &self.by_type),
            ("subtype", &self.by_subtype),
            ("assets", &self.by_assets),
            ("path", &self.by_path),
            ("source", &self.by_source),
        ];
        for (name, m) in rows {
            let cells: Vec<String> = m.iter().map(|(k, v)| format!("{k} {v}")).collect();
            let _ = writeln!(s, "{name:<9}| {}", cells.join(" | "));
        }
        let rejected: Vec<String> = self
            .validation
            .rejected
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let _ = writeln!(
            s,
            "validator| {} checked, {} accepted, rejected: {}",
            self.validation.checked,
            self.validation.accepted,
            if rejected.is_empty() {
                "none".into()
            } else {
                rejected.join(", ")
            }
        );
        let na: Vec<String> = self
            .not_applicable
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let _ = writeln!(
            s,
            "n/a      | {} (trips a type did not fit); {} trajectories not followable; {} LLM failures",
            if na.is_empty() {
                "none".into()
            } else {
                na.join(", ")
            },
            self.unfollowable,
            self.llm_failures
        );
        s
    }
}

/// Reads every scene file of `scenes` (names) under `out`, in name order.
fn load_scene_files(out: &Path, scenes: &[String]) -> Result<Vec<SceneEpisodes>> {
    let mut files = Vec::new();
    for name in scenes {
        let path = scene_file(out, name);
        if !path.is_file() {
            continue;
        }
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        files.push(
            serde_json::from_str(&text)
                .map_err(|e| Error::format("", e.to_string()).in_file(&path))?,
        );
    }
    Ok(files)
}

/// Removes what an earlier build into `out` wrote that this one does not: the scene files of
/// scenes no longer among `scenes`, and without a balanced selection (`balanced` false) the
/// `test_balanced` files of every format, unless `data import` made that split. Outside
/// loaders (SAGE-Bench's, VLN-CE's) would take them for part of the dataset.
fn remove_stale(out: &Path, scenes: &[String], balanced: bool) -> Result<()> {
    let remove = |path: &Path| match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
        _ => Ok(()),
    };
    let scene_dir = out.join("scenes");
    if let Ok(entries) = std::fs::read_dir(&scene_dir) {
        for entry in entries.flatten() {
            let path = entry.path();
            let stale = path.extension().is_some_and(|x| x == "json")
                && path
                    .file_stem()
                    .is_some_and(|n| !scenes.iter().any(|s| n == s.as_str()));
            if stale && entry.file_type().is_ok_and(|t| t.is_file()) {
                remove(&path)?;
            }
        }
    }
    let imported = folder::imported_splits(out)?
        .iter()
        .any(|(name, _)| name == split::TEST_BALANCED);
    if !balanced && !imported {
        let name = split::TEST_BALANCED;
        remove(&out.join("episodes").join(format!("{name}.jsonl")))?;
        remove(&out.join("gvln").join(format!("{name}.json")))?;
        let (episodes, ground_truth) = r2r::paths(&out.join("r2r"), name);
        remove(&episodes)?;
        remove(&ground_truth)?;
        // The split's folder, only when nothing else is in it.
        let _ = std::fs::remove_dir(out.join("r2r").join(name));
    }
    Ok(())
}

/// Assembles the dataset from the scene files: splits, balanced test selection, the JSONL,
/// GVLN and R2R files per split, `splits.json` and `summary.json` / `summary.txt`.
pub fn assemble(
    out: &Path,
    scenes: &[String],
    params: &AssembleParams,
    space: &StepSizes,
) -> Result<DatasetSummary> {
    let files = load_scene_files(out, scenes)?;
    let episodes: Vec<Episode> = files
        .iter()
        .flat_map(|f| f.episodes.iter().cloned())
        .collect();
    let splits = split::assign(&episodes, &params.split, params.seed);
    let mut by_split: BTreeMap<&str, Vec<Episode>> =
        SPLITS.iter().map(|s| (*s, Vec::new())).collect();
    for e in &episodes {
        if let Some(v) = splits.get(&e.episode_id).and_then(|s| by_split.get_mut(s)) {
            v.push(e.clone());
        }
    }
    let test: Vec<&Episode> = by_split
        .iter()
        .filter(|(k, _)| k.starts_with("test"))
        .flat_map(|(_, v)| v.iter())
        .filter(|e| e.task == Task::Vln)
        .collect();
    let balanced = selector::select_balanced(&test, params.balanced, params.seed);
    let balanced_set: std::collections::BTreeSet<&str> =
        balanced.iter().map(String::as_str).collect();
    let balanced_eps: Vec<Episode> = episodes
        .iter()
        .filter(|e| balanced_set.contains(e.episode_id.as_str()))
        .cloned()
        .collect();
    let mut summary = DatasetSummary {
        scenes: files.len(),
        episodes: episodes.len(),
        balanced_test: balanced.len(),
        ..DatasetSummary::default()
    };
    for d in ["episodes", "gvln", "r2r"] {
        let p = out.join(d);
        std::fs::create_dir_all(&p).map_err(|e| Error::io(&p, e))?;
    }
    let mut outputs: Vec<(&str, &Vec<Episode>)> = by_split.iter().map(|(k, v)| (*k, v)).collect();
    if params.balanced > 0 {
        outputs.push((split::TEST_BALANCED, &balanced_eps));
    }
    for (name, eps) in outputs {
        jsonl::write(&out.join("episodes").join(format!("{name}.jsonl")), eps)?;
        gvln::write(
            &out.join("gvln").join(format!("{name}.json")),
            eps,
            GvlnFrame::World,
            space,
        )?;
        let n = r2r::write(&out.join("r2r"), name, eps, space)?;
        if name != split::TEST_BALANCED {
            summary.r2r_episodes += n;
        }
    }
    let count =
        |m: &mut BTreeMap<String, usize>, k: &str| *m.entry(k.to_string()).or_insert(0) += 1;
    for e in &episodes {
        count(
            &mut summary.by_task,
            if e.task == Task::Vln { "vln" } else { "nogoal" },
        );
        count(
            &mut summary.by_level,
            e.level.map_or("none", |l| l.as_str()),
        );
        count(&mut summary.by_type, e.instruction_type.as_str());
        if let Some(s) = e.subtype {
            count(&mut summary.by_subtype, s.as_str());
        }
        count(&mut summary.by_assets, &e.slices.assets);
        count(&mut summary.by_path, &e.slices.path);
        count(
            &mut summary.by_source,
            &serde_json::to_value(e.source)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default(),
        );
        count(
            &mut summary.by_split,
            splits.get(&e.episode_id).copied().unwrap_or("none"),
        );
    }
    for f in &files {
        summary.validation.merge(&f.report.validation);
        for (k, v) in &f.report.not_applicable {
            *summary.not_applicable.entry(k.clone()).or_insert(0) += v;
        }
        summary.unfollowable += f.report.unfollowable;
        summary.llm_failures += f.report.llm_failures;
    }
    remove_stale(out, scenes, params.balanced > 0)?;
    // The list of splits: the files just written, `test_balanced` only when it was.
    let split_ids: BTreeMap<&str, Vec<&str>> = by_split
        .iter()
        .map(|(k, v)| (*k, v.iter().map(|e| e.episode_id.as_str()).collect()))
        .chain((params.balanced > 0).then(|| {
            (
                split::TEST_BALANCED,
                balanced.iter().map(String::as_str).collect(),
            )
        }))
        .collect();
    let mut listed = serde_json::json!(split_ids);
    // The splits `data import` added keep their place beside the built ones (a build's own
    // split of the same name replaces the import's file, so it replaces its entry too).
    for (name, ids) in folder::imported_splits(out)? {
        if !split_ids.contains_key(name.as_str()) {
            listed[name] = ids;
        }
    }
    write_json(
        &out.join(folder::SPLITS_FILE),
        &serde_json::json!({"seed": params.seed, "params": params, "splits": listed}),
    )?;
    write_json(&out.join("summary.json"), &summary)?;
    sage_io::files::write_atomic(&out.join("summary.txt"), |w| {
        std::io::Write::write_all(w, summary.table().as_bytes())
    })?;
    Ok(summary)
}

/// Runs the whole pipeline: every scene (parallel, resumable; `on_scene` is called as each
/// finishes), then the assembly. Returns the outcomes and the summary.
///
/// # Errors
///
/// Bad settings, a scene folder whose name is not a plain name (before any work:
/// [`trajectory::check_scene_names`]), an LLM endpoint that cannot be set up, or a write error.
pub fn build(
    dirs: &[PathBuf],
    out: &Path,
    params: &SceneParams,
    assemble_params: &AssembleParams,
    on_scene: &(dyn Fn(&SceneOutcome) + Sync),
) -> Result<(Vec<SceneOutcome>, DatasetSummary)> {
    params.validate()?;
    trajectory::check_scene_names(dirs)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let client = params.llm.clone().map(LlmClient::new).transpose()?;
    let outcomes: Vec<SceneOutcome> = dirs
        .par_iter()
        .map(|d| {
            let o = run_scene(d, out, params, client.as_ref());
            on_scene(&o);
            o
        })
        .collect();
    let names: Vec<String> = dirs
        .iter()
        .map(|d| sage_io::scenes::scene_name(d))
        .collect();
    let summary = assemble(out, &names, assemble_params, &params.space)?;
    Ok((outcomes, summary))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_base_action_the_validator_rejects_is_not_written() {
        let scene = sage_synth::generate(&sage_synth::SynthConfig {
            seed: 1,
            rooms: 2,
            objects: 6,
            gaussians: 1000,
            ..sage_synth::SynthConfig::default()
        })
        .unwrap();
        let params = SceneParams::new(1, 0);
        let prep = trajectory::prepare(&scene, &params.trajectories).unwrap();
        let tm = TextMap::build(&scene, &prep.map, &prep.endpoints);
        let validator = Validator::new(&tm);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let plan = lowlevel::base_action(&prep.finder, &params.space, &mut rng).unwrap();
        let mut report = SceneReport::default();
        let kept = validated_base_action(&validator, Some(plan.clone()), &mut report);
        assert_eq!(kept.as_ref(), Some(&plan));
        assert_eq!(
            (report.validation.checked, report.validation.accepted),
            (1, 1)
        );
        assert!(report.not_applicable.is_empty());
        // Too short for the validator: counted as checked and rejected, and not applicable.
        let mut bad = plan.clone();
        bad.instruction.text = "Go.".into();
        assert_eq!(
            validated_base_action(&validator, Some(bad), &mut report),
            None
        );
        assert_eq!(
            (report.validation.checked, report.validation.accepted),
            (2, 1)
        );
        assert_eq!(report.validation.rejected.values().sum::<usize>(), 1);
        assert_eq!(report.not_applicable["Base-Action"], 1);
        // No start for the motion: not applicable, nothing checked.
        assert_eq!(validated_base_action(&validator, None, &mut report), None);
        assert_eq!(report.validation.checked, 2);
        assert_eq!(report.not_applicable["Base-Action"], 2);
    }

    #[test]
    fn datasets_are_planned_for_the_ground_profile_asked_for() {
        let radius = |agent: &str| {
            SceneParams::new(3, 0)
                .for_agent(agent)
                .map(|p| p.trajectories.cost.robot_radius)
        };
        assert_eq!(radius("wheeled").unwrap(), 0.2);
        assert_eq!(radius("go2").unwrap(), 0.28);
        assert_eq!(radius("H1").unwrap(), 0.30);
        assert!(
            radius("uav")
                .unwrap_err()
                .to_string()
                .contains("ground agents")
        );
        assert!(radius("robot").is_err());
    }
}
