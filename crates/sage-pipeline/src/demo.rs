//! The demo: the whole pipeline on synthetic scenes (or a folder of real ones), end to end.
//!
//! [`plan`] decides every step before anything runs; each [`Step`] is one pipeline step of this
//! crate with its typed settings, the same settings the `sage3d` subcommand that does the same
//! takes (the front end prints each step as that command), so the demo doubles as a worked
//! example of pointing the same commands at real data. Each step resumes: scenes already
//! synthesised are kept (one cut short is made again), collision hulls come from their cache,
//! the dataset build and the evaluations skip what their folders already hold.
//!
//! The demo's output folder is claimed ([`claim`]), its run record written marked unfinished,
//! before any step writes into it, so that a demo that stopped half-way is recognised as the
//! demo's when it is rerun to resume, and says it is not complete until [`run`] has written
//! everything; a folder of someone else's files is refused.

use crate::dataset::{BuildSettings, DatasetReport};
use crate::nav::MapReport;
use crate::physics::BodyOptions;
use sage_agents::AgentKind;
use sage_core::{Error, Result, ResultExt};
use sage_dataset::split::{SPLITS, SplitParams, TEST_BALANCED, splits_possible};
use sage_eval::folder::SUMMARY_FILE;
use sage_eval::report::ReportOutcome;
use sage_eval::{EvalSettings, RunOutcome, Summary};
use sage_io::lock::FolderLock;
use sage_io::run::{FINISHED, UNFINISHED};
use sage_metrics::{Dtw, Mode};
use sage_nav::GridParams;
use sage_physics::{BuildReport, Decomposer, HullCache, SceneBodies, default_cache_dir};
use sage_scene::{Scene, SplatLayout};
use sage_synth::{SceneKind, SynthConfig};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Settings of the demo (`sage3d demo`'s flags, `sage3d.demo`'s keyword arguments);
/// [`DemoSettings::default`] gives every default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct DemoSettings {
    /// Output folder: scenes/, dataset/, train_data/, runs/{agent}/ (each with report.html),
    /// overview.png; new, empty, or a demo's (rerunning resumes).
    #[cfg_attr(feature = "clap", arg(long, default_value_os_t = DemoSettings::default().out))]
    pub out: PathBuf,
    /// Number of synthetic scenes (homes, every third an office).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DemoSettings::default().scenes))]
    pub scenes: usize,
    /// Seed of every random choice (scene k uses seed + k).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DemoSettings::default().seed))]
    pub seed: u64,
    /// Trajectories per scene in the dataset.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DemoSettings::default().per_scene))]
    pub per_scene: usize,
    /// Gaussians per five rooms of a synthetic scene (a scene gets its share by its rooms).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DemoSettings::default().gaussians))]
    pub gaussians: usize,
    /// Agents to evaluate, comma-separated (any agent of `sage3d eval`), each into
    /// runs/{agent}/ (an agent string of other characters than lower-case letters, digits, `_`
    /// and `-` as a file name with a hash suffix: `replay:r.jsonl` into
    /// runs/replay_r_jsonl-…/).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_delimiter = ',', default_value = sage_core::named::comma_list(&DemoSettings::default().agents))
    )]
    pub agents: Vec<String>,
    /// Dataset split the agents are evaluated on.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DemoSettings::default().split))]
    pub split: String,
    /// Run the pipeline on these scenes instead of synthetic ones: a folder of scene folders
    /// (InteriorGS or ours). Maps go to SCENE/nav, collision hulls to SCENE/.sage3d.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(rename = "from_dir")]
    pub from: Option<PathBuf>,
}

impl Default for DemoSettings {
    fn default() -> Self {
        DemoSettings {
            out: PathBuf::from("demo"),
            scenes: 3,
            seed: 0,
            per_scene: 12,
            gaussians: 150_000,
            agents: ["oracle", "random", "forward"].map(String::from).to_vec(),
            split: sage_dataset::split::TEST_BALANCED.into(),
            from: None,
        }
    }
}

impl DemoSettings {
    /// Where the scenes are: `from`, or the synthetic ones under `out/scenes`.
    pub fn scenes_folder(&self) -> PathBuf {
        self.from.clone().unwrap_or_else(|| self.out.join("scenes"))
    }

    /// The dataset folder.
    pub fn dataset(&self) -> PathBuf {
        self.out.join("dataset")
    }

    /// The run folder of `agent`: `runs/` and the agent string as a file name
    /// ([`sage_io::names::stem`]: `oracle` stays `oracle`, `replay:../r.jsonl` becomes
    /// `replay____r_jsonl-` and a hash), so that no agent string names a folder elsewhere.
    pub fn run_folder(&self, agent: &str) -> PathBuf {
        self.out.join("runs").join(sage_io::names::stem(agent))
    }
}

/// One step of the demo.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Synthesise a scene folder.
    Synth {
        /// Scene name.
        name: String,
        /// Generator settings.
        config: SynthConfig,
        /// Scene folder.
        out: PathBuf,
    },
    /// A scene's semantic map and occupancy grid (into `scene/nav`).
    NavMap {
        /// Scene name.
        name: String,
        /// Scene folder.
        scene: PathBuf,
    },
    /// A scene's collision bodies (hulls cached under `scene/.sage3d`).
    Physics {
        /// Scene name.
        name: String,
        /// Scene folder.
        scene: PathBuf,
    },
    /// Trajectories, instructions, episodes and splits of every scene.
    Dataset {
        /// Folder of scene folders.
        scenes: PathBuf,
        /// Dataset folder.
        out: PathBuf,
        /// The build's settings.
        settings: Box<BuildSettings>,
    },
    /// A small training set rendered from the dataset's train split, with a preview GIF.
    TrainData {
        /// The render.
        options: Box<sage_traindata::Options>,
        /// Output folder.
        out: PathBuf,
    },
    /// Evaluate one agent, with its report.
    Eval {
        /// The evaluation.
        settings: EvalSettings,
        /// Run folder.
        out: PathBuf,
    },
}

/// What one step made.
#[derive(Debug, Clone)]
pub enum StepReport {
    /// The synthesised scene.
    Synth(Box<Scene>),
    /// The map written.
    NavMap(MapReport),
    /// The scene and the bodies built.
    Physics(Box<(Scene, SceneBodies, BuildReport)>),
    /// The dataset built.
    Dataset(Box<DatasetReport>),
    /// The training-data render (`None`: the train split had no episode to render).
    TrainData(Option<Box<crate::traindata::TrainDataReport>>),
    /// The evaluation and its report.
    Eval(Box<(RunOutcome, ReportOutcome)>),
}

/// Progress inside a step: `done` of `total` units (`what`: scenes, objects, episodes, maps).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick<'a> {
    /// Units done so far.
    pub done: usize,
    /// Units in all.
    pub total: usize,
    /// What the units are.
    pub what: &'a str,
}

impl Step {
    /// What the step does, in words.
    pub fn title(&self) -> String {
        match self {
            Step::Synth { name, .. } => format!("synthesise scene {name}"),
            Step::NavMap { name, .. } => format!("semantic map and occupancy of {name}"),
            Step::Physics { name, .. } => format!("collision bodies of {name}"),
            Step::Dataset { .. } => "trajectories, instructions, episodes and splits".into(),
            Step::TrainData { .. } => "a small training set (NaVILA layout) with a preview".into(),
            Step::Eval { settings, .. } => format!("evaluate the {} agent", settings.agent),
        }
    }

    /// Runs the step; `on_tick` follows its progress.
    ///
    /// # Errors
    ///
    /// The step's own errors; an evaluation of an empty split fails early, saying what to pass.
    pub fn run(&self, on_tick: &(dyn Fn(Tick<'_>) + Sync)) -> Result<StepReport> {
        let counter = std::sync::atomic::AtomicUsize::new(0);
        let tick = |total: usize, what: &str| {
            let done = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            on_tick(Tick { done, total, what });
        };
        Ok(match self {
            Step::Synth { config, out, .. } => StepReport::Synth(Box::new(
                crate::scene::synthesize(config, out, SplatLayout::Compressed, &|_| {})?,
            )),
            Step::NavMap { scene, .. } => {
                StepReport::NavMap(crate::nav::map(scene, None, &GridParams::default())?)
            }
            Step::Physics { scene, .. } => {
                let cache = HullCache::new(default_cache_dir(scene));
                StepReport::Physics(Box::new(crate::physics::bodies(
                    scene,
                    &BodyOptions::default(),
                    &Decomposer::default(),
                    &cache,
                    &|n| tick(n, "objects"),
                )?))
            }
            Step::Dataset {
                scenes,
                out,
                settings,
            } => StepReport::Dataset(Box::new(crate::dataset::build(
                scenes,
                out,
                settings,
                false,
                &|_, n| tick(n, "scenes"),
            )?)),
            Step::TrainData { options, out } => {
                let (_, train) =
                    sage_dataset::folder::split_episodes(&options.dataset, &options.split)?;
                StepReport::TrainData(if train.is_empty() {
                    None
                } else {
                    let report = crate::traindata::render(options, out, false, &|p| {
                        if let sage_traindata::Progress::Route(r) = p {
                            tick(r.of, "walks");
                        }
                    })?;
                    Some(Box::new(report))
                })
            }
            Step::Eval { settings, out } => {
                check_split(&settings.dataset, &settings.split)?;
                StepReport::Eval(Box::new(crate::evaluate::evaluate(
                    settings,
                    out,
                    false,
                    crate::evaluate::Callbacks {
                        on_episode: &|_, n| tick(n, "episodes"),
                        on_map: &|_, _| {},
                    },
                )?))
            }
        })
    }
}

/// The name of demo scene `k` and its layout: kind, rooms and objects. Every three scenes: a
/// small home with few assets (< 184 objects), a larger home with a medium count and a 40-room
/// office with many (> 376), large enough for paths in the `long` bin (> 29 m), so the test
/// split holds every slice value (tested).
fn scene_name(k: usize) -> (String, SynthConfig) {
    let (kind, rooms, objects) = match k % 3 {
        0 => (SceneKind::Home, 5, 60),
        1 => (SceneKind::Home, 9, 260),
        _ => (SceneKind::Office, 40, 400),
    };
    let config = SynthConfig {
        kind,
        rooms,
        objects,
        ..SynthConfig::default()
    };
    (format!("{}_{k}", kind.as_str()), config)
}

/// The dataset settings of the demo: `per_scene` trajectories, with a share of each length bin
/// wanted ([`LENGTH_MIX`]) so the large scene gives long paths.
fn build_settings(s: &DemoSettings) -> BuildSettings {
    BuildSettings {
        per_scene: s.per_scene,
        seed: s.seed,
        length_mix: Some(LENGTH_MIX.to_vec()),
        ..BuildSettings::default()
    }
}

/// Rooms that [`DemoSettings::gaussians`] are for.
const ROOMS_PER_GAUSSIAN_SHARE: usize = 5;

/// The demo's wanted shares of short, medium and long reference paths (SPEC §9 bins): small
/// scenes have no long paths and give fewer trajectories; the large office gives its share.
const LENGTH_MIX: [f32; 3] = [0.4, 0.4, 0.2];

/// The steps of the demo, in order: what runs is decided (and the replay files that agents
/// name read) before anything runs.
///
/// # Errors
///
/// No scenes or no agents asked for, an agent name that does not parse (or names a replay
/// file that cannot be read), two agents whose run folders would be one, or a `from` folder
/// without scenes.
pub fn plan(s: &DemoSettings) -> Result<Vec<Step>> {
    if s.scenes == 0 {
        return Err(Error::invalid("`scenes` must be at least 1"));
    }
    if s.agents.is_empty() {
        return Err(Error::invalid("`agents` names no agent"));
    }
    sage_io::names::distinct_stems("agent", s.agents.iter().map(String::as_str))
        .within("`agents`")?;
    let scenes = s.scenes_folder();
    let mut steps = Vec::new();
    let dirs: Vec<(String, PathBuf)> = match &s.from {
        Some(from) => sage_io::scenes::scene_dirs_by_name(from)?
            .into_iter()
            .collect(),
        None => (0..s.scenes)
            .map(|k| (scene_name(k).0, scenes.join(scene_name(k).0)))
            .collect(),
    };
    check_split_possible(s, dirs.len())?;
    for (k, (name, dir)) in dirs.into_iter().enumerate() {
        // A scene is kept once its run record is there and not marked unfinished: one killed
        // half-way is synthesised again.
        if s.from.is_none() && !sage_io::run::is_finished(&dir) {
            let layout = scene_name(k).1;
            steps.push(Step::Synth {
                name: name.clone(),
                config: SynthConfig {
                    seed: s.seed + k as u64,
                    // As dense in a large scene as in a small one: a first-person view of a
                    // 40-room office from the Gaussians of a 5-room home is a blur.
                    gaussians: (s.gaussians * layout.rooms).div_ceil(ROOMS_PER_GAUSSIAN_SHARE),
                    ..layout
                },
                out: dir.clone(),
            });
        }
        steps.push(Step::NavMap {
            name: name.clone(),
            scene: dir.clone(),
        });
        steps.push(Step::Physics { name, scene: dir });
    }
    steps.push(Step::Dataset {
        scenes: scenes.clone(),
        out: s.dataset(),
        settings: Box::new(build_settings(s)),
    });
    steps.push(Step::TrainData {
        options: Box::new(sage_traindata::Options {
            limit: Some(8),
            preview: 2,
            ..sage_traindata::Options::new(s.dataset(), Some(scenes.clone()))
        }),
        out: s.out.join("train_data"),
    });
    for agent in &s.agents {
        let kind: AgentKind = agent
            .parse()
            .map_err(|e: Error| e.within(format!("`agents` '{agent}'")))?;
        // A replay file is read now: a missing or bad one stops the demo before any work.
        kind.maker().within(format!("`agents` '{agent}'"))?;
        steps.push(Step::Eval {
            settings: EvalSettings {
                dataset: s.dataset(),
                scenes: scenes.clone(),
                split: s.split.clone(),
                agent: kind,
                mode: Mode::default(),
                dtw: Dtw::default(),
                seed: s.seed,
                preset: "sage".into(),
                device: Default::default(),
                splat_bodies: Default::default(),
            },
            out: s.run_folder(agent),
        });
    }
    Ok(steps)
}

/// Refuses, before any work, a split to evaluate that `scenes` scenes cannot fill: the split
/// rule deals out whole scenes, so one scene leaves every episode in train.
fn check_split_possible(s: &DemoSettings, scenes: usize) -> Result<()> {
    let build = build_settings(s);
    let params = SplitParams::holding_out(build.scene_unseen, build.val);
    let possible = splits_possible(scenes, &params);
    if possible.contains(&s.split.as_str()) {
        return Ok(());
    }
    let known = SPLITS.contains(&s.split.as_str()) || s.split == TEST_BALANCED;
    Err(Error::invalid(if known {
        format!(
            "with {scenes} scene(s) the {} split gets no episode (the split rule deals out whole scenes); evaluate `split` {}, or use more `scenes`",
            s.split,
            possible.join(" or ")
        )
    } else {
        format!(
            "`split` '{}' is none of {}, {TEST_BALANCED}",
            s.split,
            SPLITS.join(", ")
        )
    }))
}

/// Fails early, with what to do, when the split to evaluate holds no episode (with few
/// scenes every scene can go to the training split).
fn check_split(dataset: &Path, split: &str) -> Result<()> {
    let (_, episodes) = sage_dataset::folder::split_episodes(dataset, split)?;
    if episodes.is_empty() {
        return Err(Error::invalid(format!(
            "the {split} split is empty (with few scenes, all of them can land in train); evaluate `split` train, or use more `scenes`"
        ))
        .in_file(dataset));
    }
    Ok(())
}

/// The command, as the demo folder's run record names it.
pub const COMMAND: &str = "demo";

/// Everything the demo writes at the top of its folder.
const OUTPUTS: [&str; 6] = [
    "scenes",
    "dataset",
    "train_data",
    "runs",
    "overview.png",
    sage_io::RUN_RECORD,
];

/// Claims `s.out` for the demo and writes its run record, marked unfinished
/// ([`sage_io::run::UNFINISHED`]) until [`run`] has written everything
/// ([`finish`]): the folder must be new, empty or a demo's, finished or not (a rerun, which
/// resumes); with `force`, a folder of other files is written into, provided none of them
/// would be replaced ([`sage_io::run::claim_folder`]). Returns the folder's lock, to hold
/// while [`run`] writes there. Each step claims its own sub-folder in turn. Settings that make
/// no demo ([`plan`]'s errors) are refused first, before the folder is made.
///
/// # Errors
///
/// As [`plan`]; a folder that another command is writing, one holding files the demo did not
/// write, or a write error.
pub fn claim(s: &DemoSettings, force: bool) -> Result<FolderLock> {
    plan(s)?;
    let lock = sage_io::run::claim_folder(&s.out, &[COMMAND], &OUTPUTS, force)?;
    check_same_demo(s)?;
    write_record(s, UNFINISHED)?;
    Ok(lock)
}

/// Refuses a folder whose demo was made with other settings than `s` (agents aside: another
/// agent is one more run over the same scenes and dataset). Its steps would otherwise rebuild
/// some outputs with the new settings and refuse others, leaving the folder of neither demo.
fn check_same_demo(s: &DemoSettings) -> Result<()> {
    let Some(old) = sage_io::run::read_record(&s.out) else {
        return Ok(());
    };
    if old.get("command").and_then(serde_json::Value::as_str) != Some(COMMAND) {
        return Ok(());
    }
    let mut new = details(s, UNFINISHED);
    // The seed stands beside the details in every run record.
    new["seed"] = s.seed.into();
    let compared = |record: &serde_json::Value| {
        ["seed", "scenes", "per_scene", "gaussians", "split", "from"]
            .into_iter()
            .filter_map(|k| Some((k.to_string(), record.get(k)?.clone())))
            .collect()
    };
    let differ = sage_io::run::differences(&compared(&old), &compared(&new));
    if differ.is_empty() {
        return Ok(());
    }
    Err(Error::invalid(format!(
        "this folder holds a demo with other settings ({}); use a new output folder (`out`)",
        differ.join("; ")
    ))
    .in_file(&s.out))
}

/// Marks the demo's run record finished ([`sage_io::run::FINISHED`]), once every step and the
/// overview are written: the record a rerun that resumed ends with is the same, byte for byte,
/// as that of a run never interrupted.
///
/// # Errors
///
/// The record cannot be written.
pub fn finish(s: &DemoSettings) -> Result<()> {
    write_record(s, FINISHED)
}

/// Writes the demo's run record in `s.out`: its settings and `status`.
fn write_record(s: &DemoSettings, status: &str) -> Result<()> {
    sage_io::run::write_run_record(&s.out, COMMAND, Some(s.seed), details(s, status))
}

/// What the demo's run record says of it besides the tool and command: its settings and
/// `status`.
fn details(s: &DemoSettings, status: &str) -> serde_json::Value {
    serde_json::json!({
        "status": status,
        "scenes": s.scenes,
        "per_scene": s.per_scene,
        "gaussians": s.gaussians,
        "agents": s.agents,
        "split": s.split,
        "from": s.from.as_ref().map(|p| p.to_string_lossy()),
    })
}

/// Runs the demo: every step of [`plan`] in order (`on_step(k, n, step)` before step `k` of
/// `n`, `on_tick` inside it, `on_done(step, report)` after it), then the overview picture
/// `out/overview.png` of the first agent's run, and last marks the demo's run record finished
/// ([`finish`]; [`claim`] wrote it unfinished, and the
/// caller holds the folder's lock meanwhile). Returns the summaries of the agents' runs.
///
/// # Errors
///
/// The first failing step's error, naming the step.
pub fn run(
    s: &DemoSettings,
    on_step: &dyn Fn(usize, usize, &Step),
    on_tick: &(dyn Fn(Tick<'_>) + Sync),
    on_done: &dyn Fn(&Step, &StepReport),
) -> Result<Vec<(String, Summary)>> {
    let steps = plan(s)?;
    for (k, step) in steps.iter().enumerate() {
        on_step(k, steps.len(), step);
        let report = step
            .run(on_tick)
            .map_err(|e| e.within(format!("demo step '{}'", step.title())))?;
        on_done(step, &report);
    }
    crate::overview::write(
        &s.scenes_folder(),
        &s.run_folder(&s.agents[0]),
        &s.out.join("overview.png"),
    )?;
    let runs = s
        .agents
        .iter()
        .map(|agent| {
            let path = s.run_folder(agent).join(SUMMARY_FILE);
            Ok((agent.clone(), sage_io::files::read_json(&path)?))
        })
        .collect::<Result<Vec<_>>>()?;
    finish(s)?;
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_scenes_plan_synth_map_physics_each_then_the_dataset_and_one_eval_per_agent() {
        let dir = tempfile::tempdir().unwrap();
        let s = DemoSettings {
            out: dir.path().join("demo"),
            ..DemoSettings::default()
        };
        let steps = plan(&s).unwrap();
        assert_eq!(steps.len(), 3 * 3 + 2 + 3);
        assert!(steps.iter().any(
            |st| matches!(st, Step::Synth { config, .. } if config.kind == SceneKind::Office)
        ));
        // A scene already synthesised is kept.
        let first = s.scenes_folder().join(scene_name(0).0);
        std::fs::create_dir_all(&first).unwrap();
        std::fs::write(first.join(sage_io::RUN_RECORD), "{}").unwrap();
        assert_eq!(plan(&s).unwrap().len(), steps.len() - 1);
        // One whose synthesis was killed half-way is made again.
        sage_io::run::mark_unfinished(&first, crate::scene::SYNTH_COMMAND, Some(0)).unwrap();
        assert_eq!(plan(&s).unwrap().len(), steps.len());
        let none = DemoSettings {
            scenes: 0,
            ..s.clone()
        };
        assert!(plan(&none).unwrap_err().to_string().contains("scenes"));
        let bad = DemoSettings {
            agents: vec!["genius".into()],
            ..s.clone()
        };
        assert!(plan(&bad).unwrap_err().to_string().contains("genius"));
        // A replay file is read before any work; an agent string never names a folder
        // outside `runs/`.
        let missing = DemoSettings {
            agents: vec!["replay:../nofile.jsonl".into()],
            ..s.clone()
        };
        let e = plan(&missing).unwrap_err().to_string();
        assert!(
            e.contains("`agents` 'replay:../nofile.jsonl'") && e.contains("nofile.jsonl"),
            "{e}"
        );
        let file = dir.path().join("one.jsonl");
        std::fs::write(&file, "{\"episode_id\": \"e\", \"actions\": [\"stop\"]}\n").unwrap();
        std::fs::create_dir_all(dir.path().join("sub")).unwrap();
        let agent = format!("replay:{}/sub/../one.jsonl", dir.path().display());
        let replay = DemoSettings {
            agents: vec!["oracle".into(), agent.clone()],
            ..s.clone()
        };
        let runs: Vec<PathBuf> = plan(&replay)
            .unwrap()
            .into_iter()
            .filter_map(|st| match st {
                Step::Eval { out, .. } => Some(out),
                _ => None,
            })
            .collect();
        assert_eq!(runs[0], s.out.join("runs").join("oracle"));
        assert_eq!(runs[1].parent(), Some(s.out.join("runs").as_path()));
        assert!(runs[1].starts_with(&s.out) && !runs[1].to_string_lossy().contains(".."));
        // One scene leaves every episode in train: evaluating a test split is refused before
        // any work, saying what would do; evaluating train is planned.
        let one = DemoSettings {
            scenes: 1,
            ..s.clone()
        };
        let e = plan(&one).unwrap_err().to_string();
        assert!(e.contains("test_balanced split gets no episode") && e.contains("`split` train"));
        let train = DemoSettings {
            split: "train".into(),
            ..one
        };
        assert!(plan(&train).is_ok());
        let unknown = DemoSettings {
            split: "tset".into(),
            ..s
        };
        assert!(
            plan(&unknown)
                .unwrap_err()
                .to_string()
                .contains("'tset' is none of")
        );
    }

    /// The demo's balanced test split holds every value of both slices: few, medium and many
    /// assets; short, medium and long paths (the layouts do not depend on the Gaussian count,
    /// so the scenes are made with few).
    #[test]
    fn the_demo_test_split_covers_every_slice_value() {
        let dir = tempfile::tempdir().unwrap();
        let s = DemoSettings {
            out: dir.path().join("demo"),
            gaussians: 1000,
            ..DemoSettings::default()
        };
        for step in plan(&s).unwrap() {
            if matches!(step, Step::Synth { .. } | Step::Dataset { .. }) {
                step.run(&|_| {}).unwrap();
            }
        }
        let episodes =
            std::fs::read_to_string(s.dataset().join("episodes/test_balanced.jsonl")).unwrap();
        let mut seen = std::collections::BTreeSet::new();
        for line in episodes.lines() {
            let e: serde_json::Value = serde_json::from_str(line).unwrap();
            for slice in ["assets", "path"] {
                seen.insert(format!("{slice}={}", e["slices"][slice].as_str().unwrap()));
            }
        }
        for want in [
            "assets=few",
            "assets=medium",
            "assets=many",
            "path=short",
            "path=medium",
            "path=long",
        ] {
            assert!(seen.contains(want), "{want} missing: {seen:?}");
        }
    }

    #[test]
    fn the_record_is_unfinished_from_the_claim_until_finish_and_a_rerun_claims_it() {
        let dir = tempfile::tempdir().unwrap();
        let s = DemoSettings {
            out: dir.path().join("demo"),
            ..DemoSettings::default()
        };
        let lock = claim(&s, false).unwrap();
        assert_eq!(
            sage_io::run::unfinished_command(&s.out).as_deref(),
            Some(COMMAND)
        );
        // What a demo killed after its first step leaves: its record, unfinished, and a file.
        std::fs::write(s.out.join("overview.png"), "half").unwrap();
        drop(lock);
        let lock = claim(&s, false).unwrap();
        assert!(!sage_io::run::is_finished(&s.out));
        finish(&s).unwrap();
        drop(lock);
        let record = sage_io::run::read_record(&s.out).unwrap();
        assert_eq!(record["status"], FINISHED);
        assert_eq!(record["command"], COMMAND);
        assert_eq!(record["agents"], serde_json::json!(s.agents));
        // The resumed demo ends with the record of one never interrupted.
        let whole = DemoSettings {
            out: dir.path().join("whole"),
            ..s.clone()
        };
        let lock = claim(&whole, false).unwrap();
        finish(&whole).unwrap();
        drop(lock);
        let record = |d: &DemoSettings| std::fs::read(d.out.join(sage_io::RUN_RECORD)).unwrap();
        assert_eq!(record(&s), record(&whole));
        // A finished demo is a demo's folder too: rerunning it resumes, with another agent too.
        drop(claim(&s, false).unwrap());
        let more = DemoSettings {
            agents: vec!["oracle".into()],
            ..s.clone()
        };
        drop(claim(&more, false).unwrap());
        // Other settings are refused before any step, naming what differs, with or without
        // `force`: the steps would remake some outputs and refuse others.
        let other = DemoSettings {
            seed: 3,
            ..s.clone()
        };
        for force in [false, true] {
            let e = claim(&other, force).err().unwrap().to_string();
            assert!(
                e.contains("other settings (seed: 0 recorded, 3 asked)") && e.contains("`out`"),
                "{e}"
            );
        }
        // Another command may not take it over.
        assert!(sage_io::run::claim_folder(&s.out, &["eval"], &[], false).is_err());
    }
}
