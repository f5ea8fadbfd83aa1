//! The dataset build over a folder of scenes: per-scene trajectories, instructions and episodes
//! (parallel, resumable), then splits, files and summary, and the run record. Its settings are
//! [`BuildSettings`], the one typed form of `sage3d data build`'s flags, Python's keyword
//! arguments and a `[data.build]` table.

use sage_core::{Error, Result};
use sage_dataset::build::{self, AssembleParams, DatasetSummary, SceneOutcome, SceneParams};
use sage_dataset::import::Source;
use sage_io::lock::FolderLock;
use sage_lang::llm::{LlmClient, LlmConfig};
use sage_physics::AgentProfile;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The settings of a dataset build; [`BuildSettings::default`] gives every default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct BuildSettings {
    /// Trajectories per scene (each gives a Single-Goal and up to five high-level episodes).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().per_scene))]
    pub per_scene: usize,
    /// Seed of every random choice.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().seed))]
    pub seed: u64,
    /// Ground agent profile the reference paths are planned for (wheeled, go2, g1, h1): its
    /// radius is the planner's inflation, so the paths leave that robot room to pass.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().agent))]
    #[serde(with = "sage_physics::agent::profile_name")]
    pub agent: AgentProfile,
    /// Shares of short / medium / long reference paths (SPEC §9 bins), e.g. 0.4,0.4,0.2
    /// (default: free). A scene without room for a bin's share yields fewer trajectories.
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    pub length_mix: Option<Vec<f32>>,
    /// Base-Action episodes per scene (default: a quarter of the trajectories per scene).
    #[cfg_attr(feature = "clap", arg(long))]
    pub base_actions: Option<usize>,
    /// No-goal episodes per scene.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().nogoal))]
    pub nogoal: usize,
    /// High-level instructions kept per type and trajectory.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = BuildSettings::default().high_per_type)
    )]
    pub high_per_type: usize,
    /// Size of the balanced test selection (0: none).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().balanced))]
    pub balanced: usize,
    /// Share of scenes held out for the scene-unseen test set.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = BuildSettings::default().scene_unseen)
    )]
    pub scene_unseen: f32,
    /// Share of scenes for validation.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().val))]
    pub val: f32,
    /// OpenAI-compatible base URL for high-level instructions (default: the offline grammar).
    #[cfg_attr(feature = "clap", arg(long))]
    pub llm_url: Option<String>,
    /// LLM model name.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = BuildSettings::default().llm_model))]
    pub llm_model: String,
    /// Environment variable holding the LLM API key.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = BuildSettings::default().llm_key_env)
    )]
    pub llm_key_env: String,
    /// LLM requests in flight at most.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = BuildSettings::default().llm_concurrency)
    )]
    pub llm_concurrency: usize,
    /// LLM answer cache (default: the output folder's llm_cache).
    #[cfg_attr(feature = "clap", arg(long))]
    pub llm_cache: Option<PathBuf>,
}

impl Default for BuildSettings {
    /// 20 trajectories per scene for the wheeled robot, seed 0, paths of any length, one
    /// no-goal episode and one high-level instruction per type, a balanced test selection of
    /// 1000, 15 % of the scenes held out and 10 % for validation, the offline grammar.
    fn default() -> Self {
        let llm = LlmConfig::default();
        BuildSettings {
            per_scene: 20,
            seed: 0,
            agent: AgentProfile::default(),
            length_mix: None,
            base_actions: None,
            nogoal: 1,
            high_per_type: 1,
            balanced: 1000,
            scene_unseen: 0.15,
            val: 0.1,
            llm_url: None,
            llm_model: llm.model,
            llm_key_env: llm.api_key_env,
            llm_concurrency: llm.concurrency,
            llm_cache: None,
        }
    }
}

impl BuildSettings {
    /// The per-scene settings (an LLM answer cache under `out` unless one is named) and the
    /// assembly settings these settings name.
    ///
    /// # Errors
    ///
    /// An agent profile that is not a ground robot, shares outside 0..1, or per-scene
    /// settings out of range ([`SceneParams::validate`]).
    pub fn params(&self, out: &Path) -> Result<(SceneParams, AssembleParams)> {
        let shares = [("`scene_unseen`", self.scene_unseen), ("`val`", self.val)];
        if let Some((name, share)) = shares.iter().find(|(_, s)| !(0.0..=1.0).contains(s)) {
            return Err(Error::invalid(format!(
                "{name}: {share} is not a share between 0 and 1"
            )));
        }
        let mut params = SceneParams::new(self.per_scene, self.seed)
            .for_agent(self.agent.name)
            .map_err(|e| e.within("`agent`"))?;
        if let Some(b) = self.base_actions {
            params.base_actions = b;
        }
        params.trajectories.sampling.length_mix = self.length_mix.clone();
        params.nogoal = self.nogoal;
        params.high_per_type = self.high_per_type;
        params.llm = self.llm_url.as_ref().map(|url| LlmConfig {
            base_url: url.clone(),
            model: self.llm_model.clone(),
            api_key_env: self.llm_key_env.clone(),
            concurrency: self.llm_concurrency,
            cache_dir: Some(
                self.llm_cache
                    .clone()
                    .unwrap_or_else(|| out.join("llm_cache")),
            ),
            ..LlmConfig::default()
        });
        params.validate()?;
        // An endpoint that cannot be asked (no URL, no model, no concurrency) is refused with
        // the other settings, before any scene: on a distributed build's driver too.
        if let Some(llm) = &params.llm {
            LlmClient::new(llm.clone())?;
        }
        let assemble = AssembleParams::new(self.seed, self.balanced, self.scene_unseen, self.val);
        Ok((params, assemble))
    }
}

/// What [`build()`] did.
#[derive(Debug, Clone)]
pub struct DatasetReport {
    /// The scene folders.
    pub dirs: Vec<PathBuf>,
    /// Per scene: made, resumed or skipped.
    pub outcomes: Vec<SceneOutcome>,
    /// The dataset's summary.
    pub summary: DatasetSummary,
}

impl DatasetReport {
    /// How many scenes were skipped (their reasons are in the outcomes): the dataset lacks
    /// their episodes until a rerun makes them.
    pub fn skipped(&self) -> usize {
        self.outcomes
            .iter()
            .filter(|o| o.status == sage_io::runner::Status::Skipped)
            .count()
    }
}

/// Builds (or resumes) the dataset of the scenes under `scenes` into `out`; `on_scene(outcome,
/// scenes)` is called as each of the `scenes` folders is done. `out` must be new, empty or a
/// dataset build's folder; with `force`, a folder of other files is written into, provided
/// none of them would be replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// Bad settings (naming the field), no scenes, a scene folder whose name is not a plain name
/// ([`sage_nav::trajectory::check_scene_names`]: episodes carry it, and readers take no
/// other), an output folder holding files the build did not write, or a write error. A scene
/// that fails is skipped with its reason (in the outcomes) and the build goes on.
pub fn build(
    scenes: &Path,
    out: &Path,
    settings: &BuildSettings,
    force: bool,
    on_scene: &(dyn Fn(&SceneOutcome, usize) + Sync),
) -> Result<DatasetReport> {
    let (params, assemble) = settings.params(out)?;
    build_with(scenes, out, &params, &assemble, force, on_scene)
}

/// [`build()`] with per-scene and assembly settings made by the caller (the demo's).
///
/// # Errors
///
/// As [`build()`].
pub fn build_with(
    scenes: &Path,
    out: &Path,
    params: &SceneParams,
    assemble: &AssembleParams,
    force: bool,
    on_scene: &(dyn Fn(&SceneOutcome, usize) + Sync),
) -> Result<DatasetReport> {
    params.validate()?;
    let dirs = sage_io::scenes::scene_dirs(scenes)?;
    // Before the folder is claimed: a build refused for a scene's name leaves nothing behind.
    sage_nav::trajectory::check_scene_names(&dirs)?;
    let _lock = sage_io::run::claim_folder(out, &[build::COMMAND], &build::OUTPUTS, force)?;
    // Recorded before the work too, as unfinished: a build that crashes halfway is this
    // command's folder, so its rerun resumes instead of being refused, and no reader takes
    // its half-written files for a dataset.
    build::write_run_record(out, scenes, &dirs, params, assemble, false)?;
    let (outcomes, summary) =
        build::build(&dirs, out, params, assemble, &|o| on_scene(o, dirs.len()))?;
    build::write_run_record(out, scenes, &dirs, params, assemble, true)?;
    Ok(DatasetReport {
        dirs,
        outcomes,
        summary,
    })
}

/// Claims `out` for a dataset build made in steps, as [`build()`] claims it (without `force`):
/// a new or empty folder, or a dataset build's own. The distributed build (Python's
/// `sage3d.distributed.generate`) calls it on its driver before any scene is built, then
/// [`build_scene`] once per scene wherever its tasks run, then [`assemble`] on the driver. The
/// folder is left marked as this build's and unfinished (the other fields of a build's record
/// there are kept, so a rebuild keeps the splits `data import` added): every reader refuses it
/// while the scene files come in, and the assembly's claim takes it as the build's own.
/// Returns the folder's lock: the driver holds it until the assembly (handing it to
/// [`assemble`]), so no other command writes the folder while the steps, which run in other
/// processes and take no lock, write their scene files there.
///
/// # Errors
///
/// An output folder holding files the build did not write, one another command is writing,
/// or a write error.
pub fn claim_steps(out: &Path, seed: u64) -> Result<FolderLock> {
    let lock = sage_io::run::claim_folder(out, &[build::COMMAND], &build::OUTPUTS, false)?;
    let mut details = match sage_io::run::read_record(out) {
        Some(serde_json::Value::Object(record))
            if record.get("command").and_then(|c| c.as_str()) == Some(build::COMMAND) =>
        {
            record
        }
        _ => serde_json::Map::new(),
    };
    // Those four are written afresh; the rest of an earlier build's record stays as it was.
    for own in ["tool", "version", "command", "seed"] {
        details.remove(own);
    }
    details.insert("status".into(), sage_io::run::UNFINISHED.into());
    sage_io::run::write_run_record(
        out,
        build::COMMAND,
        Some(seed),
        serde_json::Value::Object(details),
    )?;
    Ok(lock)
}

/// Builds (or resumes) one scene of a build made in steps ([`claim_steps`]) into
/// `out/scenes/{scene}.json`: [`build::run_scene`] with the LLM client `params.llm` names,
/// made as [`build()`] makes it (without one, the offline grammar), so a scene's file holds
/// what `sage3d data build` with the same settings writes. Each call makes its own client:
/// `params.llm.concurrency` bounds the requests of one call, and the answers are cached in
/// `params.llm.cache_dir` as seen where the call runs.
///
/// # Errors
///
/// A scene folder whose name is not a plain name, or an LLM endpoint that cannot be set up; a
/// scene that fails otherwise is skipped with its reason (in the outcome).
pub fn build_scene(dir: &Path, out: &Path, params: &SceneParams) -> Result<SceneOutcome> {
    sage_nav::trajectory::check_scene_names(&[dir.to_path_buf()])?;
    let client = params.llm.clone().map(LlmClient::new).transpose()?;
    Ok(build::run_scene(dir, out, params, client.as_ref()))
}

/// Assembles a dataset built in steps ([`claim_steps`], [`build_scene`]) from its scene files
/// (one per folder in `dirs`, found in `scenes`) under the lock `held` (the one
/// [`claim_steps`] returned, still held) or, without one, claiming `out` as [`build()`] does:
/// writes the run record unfinished, the splits, files and summary ([`build::assemble`]), then
/// the run record finished. Returns the summary.
///
/// # Errors
///
/// A scene folder whose name is not a plain name, a lock `held` of another folder, an output
/// folder that is no dataset build's (not claimed by [`claim_steps`]) or that another command
/// is writing, or a write error.
pub fn assemble(
    out: &Path,
    scenes: &Path,
    dirs: &[PathBuf],
    params: &SceneParams,
    assemble: &AssembleParams,
    held: Option<&FolderLock>,
) -> Result<DatasetSummary> {
    sage_nav::trajectory::check_scene_names(dirs)?;
    let _own = match held {
        // Taken by `claim_steps` for this build and held since: no other command has written.
        Some(lock) if lock.holds(out) => None,
        Some(_) => {
            return Err(Error::invalid(
                "the lock handed to the assembly is another folder's: claim this one",
            )
            .in_file(out));
        }
        None => Some(sage_io::run::claim_folder(
            out,
            &[build::COMMAND],
            &build::OUTPUTS,
            false,
        )?),
    };
    let names: Vec<String> = dirs
        .iter()
        .map(|d| sage_io::scenes::scene_name(d))
        .collect();
    build::write_run_record(out, scenes, dirs, params, assemble, false)?;
    let summary = build::assemble(out, &names, assemble, &params.space)?;
    build::write_run_record(out, scenes, dirs, params, assemble, true)?;
    Ok(summary)
}

/// What [`import`] did.
#[derive(Debug, Clone)]
pub struct ImportReport {
    /// Episodes written.
    pub episodes: usize,
    /// Scenes they are in.
    pub scenes: usize,
    /// The split's episodes file.
    pub file: PathBuf,
    /// Rows of a GN-Bench file that were not imported, with their reasons.
    pub rejected: Vec<sage_dataset::formats::gnbench::Rejected>,
    /// The report listing them (GN-Bench imports).
    pub report: Option<PathBuf>,
    /// Episodes left at the `medium` asset slice for want of a scenes folder
    /// ([`sage_dataset::import::Imported::assets_unknown`]).
    pub assets_unknown: usize,
}

/// Imports the episodes of `source` (a SAGE-Bench GVLN file, an R2R-VLNCE split or a GN-Bench
/// split) as split `split` of the dataset folder `out`, their scenes in `scenes`
/// ([`sage_dataset::import::import`]).
///
/// # Errors
///
/// As [`sage_dataset::import::import`].
pub fn import(
    source: &Source,
    out: &Path,
    split: &str,
    scenes: Option<&Path>,
    force: bool,
) -> Result<ImportReport> {
    let imported = sage_dataset::import::import(source, out, split, scenes, force)?;
    let scenes: BTreeSet<&str> = imported.episodes.iter().map(|e| e.scene.as_str()).collect();
    Ok(ImportReport {
        episodes: imported.episodes.len(),
        scenes: scenes.len(),
        file: out.join("episodes").join(format!("{split}.jsonl")),
        rejected: imported.rejected,
        report: imported.report,
        assets_unknown: imported.assets_unknown,
    })
}

/// Writes split `split` of `dataset` to the file `out` in `format`
/// ([`sage_dataset::export::export`]), after checking that `out` is none of the files the
/// export reads, force or not: the dataset's own files ([`build::OUTPUTS`], the import's
/// reports) and the files of the scenes in its scenes folder ([`sage_scene::scene_files`]).
///
/// # Errors
///
/// `out` being a file of the dataset or of one of its scenes, or those of
/// [`sage_dataset::export::export`].
pub fn export(
    dataset: &Path,
    split: &str,
    scenes: Option<&Path>,
    format: sage_dataset::export::Format,
    out: &Path,
    force: bool,
) -> Result<sage_dataset::export::Exported> {
    let mut inputs: Vec<PathBuf> = build::OUTPUTS
        .iter()
        .chain(&[sage_dataset::import::REPORTS_DIR])
        .map(|name| dataset.join(name))
        .collect();
    // A scenes folder that cannot be found is the export's error to report, with its advice.
    if let Ok(folder) = sage_dataset::folder::scenes_folder(dataset, scenes) {
        let dirs = sage_io::scenes::scene_dirs(&folder).unwrap_or_default();
        inputs.extend(dirs.iter().flat_map(|d| sage_scene::scene_files(d)));
    }
    sage_io::run::claim_output_file(
        out,
        &inputs,
        "a file of the input dataset or of its scenes",
        force,
    )?;
    sage_dataset::export::export(dataset, split, scenes, format, out, force)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_io::runner::Status;

    /// A scenes folder with one small synthetic scene, `home1`.
    fn scenes(root: &Path) -> PathBuf {
        let scenes = root.join("scenes");
        sage_synth::generate(&sage_synth::SynthConfig {
            seed: 3,
            rooms: 3,
            objects: 20,
            gaussians: 1000,
            ..sage_synth::SynthConfig::default()
        })
        .unwrap()
        .save(&scenes.join("home1"), sage_scene::SplatLayout::Compressed)
        .unwrap();
        scenes
    }

    #[test]
    fn a_build_in_steps_writes_what_the_build_writes_and_claims_its_folder() {
        let root = tempfile::tempdir().unwrap();
        let scenes = scenes(root.path());
        let dirs = sage_io::scenes::scene_dirs(&scenes).unwrap();
        let settings = BuildSettings {
            per_scene: 2,
            seed: 4,
            balanced: 4,
            ..BuildSettings::default()
        };
        let whole = root.path().join("whole");
        build(&scenes, &whole, &settings, false, &|_, _| {}).unwrap();

        let steps = root.path().join("steps");
        let (params, assemble_params) = settings.params(&steps).unwrap();
        let lock = claim_steps(&steps, settings.seed).unwrap();
        // Marked as the build's, unfinished: no reader takes it while the scenes come in, and
        // no other build writes it while the claim's lock is held.
        assert!(sage_dataset::folder::check(&steps).is_err());
        let e = build(&scenes, &steps, &settings, false, &|_, _| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("being written"), "{e}");
        for d in &dirs {
            assert_eq!(
                build_scene(d, &steps, &params).unwrap().status,
                Status::Done
            );
        }
        // The assembly takes only the lock of its own folder.
        let other = FolderLock::acquire(&root.path().join("other"), build::COMMAND).unwrap();
        let e = assemble(
            &steps,
            &scenes,
            &dirs,
            &params,
            &assemble_params,
            Some(&other),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("another folder's"), "{e}");
        drop(other);
        assemble(
            &steps,
            &scenes,
            &dirs,
            &params,
            &assemble_params,
            Some(&lock),
        )
        .unwrap();
        drop(lock);
        let (a, b) = (
            sage_io::files::read_tree(&whole).unwrap(),
            sage_io::files::read_tree(&steps).unwrap(),
        );
        assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
        assert!(a == b, "the build in steps differs from the build");
        sage_dataset::folder::check(&steps).unwrap();

        // A rerun's claim keeps the record's other fields, marked unfinished again.
        drop(claim_steps(&steps, settings.seed).unwrap());
        let record = sage_io::run::read_record(&steps).unwrap();
        assert_eq!(record["status"], sage_io::run::UNFINISHED);
        assert_eq!(
            record["inputs"],
            sage_io::run::read_record(&whole).unwrap()["inputs"]
        );
        assemble(&steps, &scenes, &dirs, &params, &assemble_params, None).unwrap();
        assert!(sage_io::files::read_tree(&steps).unwrap() == a);

        // A folder of other files is refused before anything is written into it, and so is an
        // assembly into a folder no claim made the build's.
        let foreign = root.path().join("foreign");
        std::fs::create_dir_all(&foreign).unwrap();
        std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
        let e = claim_steps(&foreign, 4).unwrap_err().to_string();
        assert!(e.contains("notes.txt"), "{e}");
        assert_eq!(sage_io::run::entries(&foreign).unwrap(), ["notes.txt"]);
        let unclaimed = root.path().join("unclaimed");
        std::fs::create_dir_all(unclaimed.join("scenes")).unwrap();
        let e = assemble(&unclaimed, &scenes, &dirs, &params, &assemble_params, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("'scenes'"), "{e}");
        assert!(!unclaimed.join("episodes").exists());
    }

    #[test]
    fn a_scene_built_in_steps_asks_the_llm_endpoint_its_settings_name() {
        let root = tempfile::tempdir().unwrap();
        let scenes = scenes(root.path());
        let out = root.path().join("out");
        // No server listens at this address: every request fails, which the scene's report
        // counts; the offline grammar would make none.
        let closed = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap();
        let mut params = build::SceneParams::new(2, 1);
        params.llm = Some(LlmConfig {
            base_url: format!("http://{closed}/v1"),
            max_retries: 0,
            timeout_s: 5,
            cache_dir: Some(out.join("llm_cache")),
            ..LlmConfig::default()
        });
        let outcome = build_scene(&scenes.join("home1"), &out, &params).unwrap();
        assert_eq!(outcome.status, Status::Done, "{:?}", outcome.reason);
        let file: build::SceneEpisodes = serde_json::from_str(
            &std::fs::read_to_string(build::scene_file(&out, "home1")).unwrap(),
        )
        .unwrap();
        assert!(file.report.llm_failures > 0, "{:?}", file.report);
        assert_eq!(file.settings.llm, params.llm);
        // An endpoint that cannot be asked is refused with the settings, naming what is wrong.
        let bad = BuildSettings {
            llm_url: Some(" ".into()),
            ..BuildSettings::default()
        };
        assert!(
            bad.params(&out)
                .unwrap_err()
                .to_string()
                .contains("base_url")
        );
    }

    #[test]
    fn a_scene_folder_without_a_plain_name_stops_the_build_before_its_folder() {
        let root = tempfile::tempdir().unwrap();
        let scenes = scenes(root.path());
        let spaced = scenes.join("My Home");
        std::fs::rename(scenes.join("home1"), &spaced).unwrap();
        let out = root.path().join("out");
        let settings = BuildSettings {
            per_scene: 1,
            ..BuildSettings::default()
        };
        let e = build(&scenes, &out, &settings, false, &|_, _| {})
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("'My Home'") && e.contains("rename the folder"),
            "{e}"
        );
        assert!(!out.exists());
        let (params, _) = settings.params(&out).unwrap();
        assert!(build_scene(&spaced, &out, &params).is_err());
    }
}
