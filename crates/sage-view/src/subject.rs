//! What the viewer shows: the folder it was given, told apart by what it holds, and the
//! options it was started with.

use sage_core::{Error, Result, ResultExt};
use sage_dataset::Episode;
use sage_dataset::folder::{non_empty_splits, scenes_folder, split_episodes};
use sage_env::EnvConfig;
use sage_eval::report::{read_instructions, read_run, run_env};
use sage_eval::{EvalRecord, EvalSettings, HumanRun};
use sage_io::run::recorded_command;
use sage_metrics::{Dtw, Mode};
use sage_splat::Device;
use std::collections::BTreeMap;
use std::net::{IpAddr, Ipv4Addr};
use std::path::{Path, PathBuf};

/// How `sage3d view` was asked to run.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewOptions {
    /// A scene folder, a folder of scenes, a dataset folder or an evaluation run folder.
    pub path: PathBuf,
    /// The scenes of a dataset or run (default: the folder its run record names).
    pub scenes: Option<PathBuf>,
    /// The split of a dataset (default: the first split with episodes).
    pub split: Option<String>,
    /// Human play: the run folder the person's episodes are recorded into (a dataset only).
    pub play: Option<PathBuf>,
    /// Write the human-play run into a folder holding other files (never replacing one).
    pub force: bool,
    /// The environment preset the agent moves with (`sage`, `vlnce`, `gnbench`).
    pub preset: String,
    /// The metric mode human play is scored in.
    pub mode: Mode,
    /// Where frames are rendered.
    pub device: Device,
    /// The address to bind.
    pub host: IpAddr,
    /// The port to bind (0: any free port).
    pub port: u16,
    /// Allow an address other than the loopback; every request then needs the URL's token.
    pub public: bool,
}

impl ViewOptions {
    /// Options viewing `path` on 127.0.0.1:8765 with the `sage` preset on the CPU.
    pub fn new(path: impl Into<PathBuf>) -> ViewOptions {
        ViewOptions {
            path: path.into(),
            scenes: None,
            split: None,
            play: None,
            force: false,
            preset: "sage".into(),
            mode: Mode::default(),
            device: Device::Cpu,
            host: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 8765,
            public: false,
        }
    }
}

/// The folder being viewed, by kind.
#[derive(Debug)]
pub enum Subject {
    /// One scene or a folder of scenes: explore them.
    Scenes,
    /// A dataset split: its episodes, explored from their starts.
    Dataset {
        /// The split's name.
        split: String,
        /// Its episodes.
        episodes: Vec<Episode>,
    },
    /// A dataset split played by a person into a human run.
    Play {
        /// The human run (its episodes, settings and records).
        run: Box<HumanRun>,
    },
    /// An evaluation run: its episodes and their records.
    Run {
        /// The run's settings.
        settings: Box<EvalSettings>,
        /// The environment its episodes ran in ([`sage_eval::report::run_env`]).
        env: Box<EnvConfig>,
        /// Its records, by episode id order.
        records: Vec<EvalRecord>,
        /// The instruction of each episode (empty when the dataset is gone).
        instructions: BTreeMap<String, String>,
    },
}

impl Subject {
    /// A word for the page: `scenes`, `dataset`, `play` or `run`.
    pub fn kind(&self) -> &'static str {
        match self {
            Subject::Scenes => "scenes",
            Subject::Dataset { .. } => "dataset",
            Subject::Play { .. } => "play",
            Subject::Run { .. } => "run",
        }
    }
}

/// Tells what `opts.path` is and opens it: an evaluation run (its run record says `eval`),
/// a dataset (it has `episodes/`), else scenes; returns it with the scene folders by name.
///
/// # Errors
///
/// A path that is none of these, `play` for anything but a dataset, an unknown or empty
/// split, a run folder that cannot be read, scenes that cannot be found, or the human run's
/// own errors ([`HumanRun::open`]).
pub fn open(opts: &ViewOptions) -> Result<(Subject, BTreeMap<String, PathBuf>)> {
    let path = &opts.path;
    if !path.exists() {
        return Err(Error::invalid("no such file or folder").in_file(path));
    }
    let is_run = recorded_command(path).as_deref() == Some(sage_eval::folder::COMMAND);
    let is_dataset = path.join("episodes").is_dir();
    if opts.play.is_some() && !is_dataset {
        return Err(Error::invalid(
            "human play (`play`) needs a dataset folder (one with episodes/) to play",
        )
        .in_file(path));
    }
    if is_run {
        let files = read_run(path)?;
        let settings: EvalSettings = serde_json::from_value(
            files
                .run
                .get("settings")
                .cloned()
                .unwrap_or(serde_json::Value::Null),
        )
        .map_err(|e| Error::format("settings", e.to_string()).in_file(path))?;
        let scenes = match &opts.scenes {
            Some(scenes) => scenes.clone(),
            None => sage_eval::folder::recorded_scenes(path)?,
        };
        let dirs = scene_dirs(&scenes)?;
        // A run whose dataset moved still plays: its records hold every pose.
        let instructions = read_instructions(&files.run, &settings.split).unwrap_or_default();
        return Ok((
            Subject::Run {
                env: Box::new(run_env(&files.run).in_file(path)?),
                settings: Box::new(settings),
                records: files.records,
                instructions,
            },
            dirs,
        ));
    }
    if is_dataset {
        let split = match &opts.split {
            Some(s) => s.clone(),
            None => non_empty_splits(path)?.into_iter().next().ok_or_else(|| {
                Error::invalid("the dataset has no split with episodes").in_file(path)
            })?,
        };
        let scenes = scenes_folder(path, opts.scenes.as_deref())?;
        if let Some(out) = &opts.play {
            let settings = EvalSettings {
                dataset: path.clone(),
                scenes: scenes.clone(),
                split,
                agent: sage_agents::AgentKind::Human,
                mode: opts.mode,
                dtw: Dtw::default(),
                seed: 0,
                preset: opts.preset.clone(),
                device: opts.device,
                splat_bodies: Default::default(),
            };
            let run = HumanRun::open(settings, out, opts.force).within("human play")?;
            let dirs = scene_dirs(&scenes)?;
            return Ok((Subject::Play { run: Box::new(run) }, dirs));
        }
        let (file, episodes) = split_episodes(path, &split)?;
        if episodes.is_empty() {
            return Err(Error::invalid(format!("split '{split}' has no episodes")).in_file(&file));
        }
        let dirs = scene_dirs(&scenes)?;
        return Ok((Subject::Dataset { split, episodes }, dirs));
    }
    Ok((Subject::Scenes, scene_dirs(path)?))
}

/// The scene folders under `root` by name, at least one.
fn scene_dirs(root: &Path) -> Result<BTreeMap<String, PathBuf>> {
    let dirs = sage_io::scenes::scene_dirs_by_name(root)?;
    if dirs.is_empty() {
        return Err(Error::invalid(
            "no scene folder here (expected a scene, a folder of scenes, a dataset or an evaluation run)",
        )
        .in_file(root));
    }
    Ok(dirs)
}
