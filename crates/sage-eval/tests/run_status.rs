//! A run folder says whether its writer finished it: an evaluation records itself unfinished
//! when it claims the folder and finished once its summary and report are written; a run
//! stopped half-way is refused by every reader, naming what to rerun, and its rerun ends with
//! the bytes of an uninterrupted run; runs recorded before the status existed read as
//! finished; human play is finished once an episode is recorded; a folder of another run is
//! refused naming the settings that differ; a run records the environment it ran in
//! (`env`), resumes only in it, and its rescoring and merge carry it through, while a run
//! recorded before the environment was still resumes, rescores and reports.

mod common;

use sage_env::agents::run_episode;
use sage_env::{Env, EnvConfig, SceneContext};
use sage_eval::report::{self, ReportJob};
use sage_eval::{EvalSettings, HumanRun, Runner};
use sage_io::run::RUN_RECORD;
use sage_metrics::Mode;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// A small dataset and its scenes, made once, never changed.
struct Fixture {
    _dir: tempfile::TempDir,
    scenes: PathBuf,
    data: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, _, data) = common::small_dataset(dir.path(), 4);
        Fixture {
            _dir: dir,
            scenes,
            data,
        }
    })
}

/// The oracle over the train split of `data`.
fn settings(data: &Path, scenes: &Path) -> EvalSettings {
    EvalSettings {
        dataset: data.to_path_buf(),
        scenes: scenes.to_path_buf(),
        split: "train".into(),
        agent: "oracle".parse().unwrap(),
        mode: Mode::Sage,
        dtw: Default::default(),
        seed: 0,
        preset: "sage".into(),
        device: Default::default(),
        splat_bodies: Default::default(),
    }
}

/// The run record of `run`.
fn record(run: &Path) -> serde_json::Value {
    sage_io::files::read_json(&run.join(RUN_RECORD)).unwrap()
}

/// An evaluation with its report into `out`, as `sage3d eval` writes it.
fn evaluate(settings: &EvalSettings, out: &Path) {
    let _lock = sage_eval::claim(out, false).unwrap();
    sage_eval::with_runner(settings, |runner| {
        sage_eval::run_with_report(
            settings,
            runner,
            out,
            &|_, _| {},
            &ReportJob::new(&settings.scenes),
        )
    })
    .unwrap();
}

/// The files of a run folder an evaluation writes, by name.
fn outputs(run: &Path) -> Vec<(&'static str, Vec<u8>)> {
    ["episodes.jsonl", "summary.json", RUN_RECORD, "report.html"]
        .into_iter()
        .map(|name| (name, std::fs::read(run.join(name)).unwrap()))
        .collect()
}

#[test]
fn a_stopped_evaluation_is_unfinished_until_its_rerun_which_ends_as_an_uninterrupted_one() {
    let f = fixture();
    let settings = settings(&f.data, &f.scenes);
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    evaluate(&settings, &whole);
    assert_eq!(record(&whole)["status"], "finished");

    // Stopped once its first episode is recorded, as a kill would stop it.
    let stopped = dir.path().join("stopped");
    let maker = settings.agent.maker().unwrap();
    let stop = AtomicBool::new(false);
    let runner = Runner {
        config: sage_eval::env_config(&settings, &maker).unwrap(),
        agent_name: settings.agent.to_string(),
        agent: &|| maker.build(settings.seed),
        shard: None,
        serial: true,
        stop: Some(&stop),
    };
    {
        let _lock = sage_eval::claim(&stopped, false).unwrap();
        let job = ReportJob::new(&f.scenes);
        let on_done = |_: &sage_eval::EvalRecord, _| stop.store(true, Ordering::Relaxed);
        assert!(sage_eval::run_with_report(&settings, &runner, &stopped, &on_done, &job).is_err());
    }
    assert_eq!(record(&stopped)["status"], "unfinished");
    let recorded = std::fs::read_to_string(stopped.join("episodes.jsonl")).unwrap();
    assert_eq!(recorded.lines().count(), 1);
    // Its summary of an earlier run, had it one, would count other records: every reader of a
    // run refuses it for its status alone.
    std::fs::copy(whole.join("summary.json"), stopped.join("summary.json")).unwrap();
    let expected = format!(
        "{}: the evaluation in this folder was not finished (its {RUN_RECORD} has status 'unfinished'): rerun the same `sage3d eval` into it to finish it",
        stopped.display()
    );
    let errors = [
        report::read_run(&stopped).unwrap_err(),
        report::write(&stopped, &f.scenes).unwrap_err(),
        sage_eval::rescore(&stopped, Some(Mode::Vlnce), None, &dir.path().join("re")).unwrap_err(),
        sage_eval::folder::finished_run_record(&stopped).unwrap_err(),
    ];
    for e in errors {
        assert_eq!(e.to_string(), expected);
    }
    assert!(!stopped.join("report.html").exists() && !dir.path().join("re").exists());
    // While its writer still writes it, a reader names the writer rather than a rerun.
    {
        let _writer = sage_eval::claim(&stopped, false).unwrap();
        let writer = format!(
            "being written by the `eval` run of process {}",
            std::process::id()
        );
        let errors = [
            report::read_run(&stopped).unwrap_err(),
            sage_eval::folder::finished_run_record(&stopped).unwrap_err(),
        ];
        for e in errors {
            assert!(e.to_string().contains(&writer), "{e}");
        }
    }

    evaluate(&settings, &stopped);
    assert_eq!(outputs(&stopped), outputs(&whole));
    report::read_run(&stopped).unwrap();

    // The library's run without a report finishes its run too.
    let bare = dir.path().join("bare");
    sage_eval::run(&settings, &bare, &|_, _| {}).unwrap();
    assert_eq!(
        std::fs::read(bare.join(RUN_RECORD)).unwrap(),
        std::fs::read(whole.join(RUN_RECORD)).unwrap()
    );
}

#[test]
fn a_run_recorded_before_the_status_existed_reads_as_finished() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    sage_eval::run(&settings(&f.data, &f.scenes), &run, &|_, _| {}).unwrap();
    let mut old = record(&run);
    old.as_object_mut().unwrap().remove("status");
    sage_io::files::write_json(&run.join(RUN_RECORD), &old).unwrap();
    report::write(&run, &f.scenes).unwrap();
    // Such a run killed before its summary says so, as it always did.
    std::fs::remove_file(run.join("summary.json")).unwrap();
    let e = report::read_run(&run).unwrap_err().to_string();
    assert!(e.contains("no summary.json"), "{e}");
}

#[test]
fn a_merge_and_a_rescoring_record_themselves_finished_only_at_their_end() {
    let f = fixture();
    let settings = settings(&f.data, &f.scenes);
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    evaluate(&settings, &run);
    let shards = [std::fs::read_to_string(run.join("episodes.jsonl")).unwrap()];
    let merged = dir.path().join("merged");
    let job = ReportJob::new(&f.scenes);
    sage_eval::merge_shards_with_report(&settings, "oracle", None, &shards, &merged, &job).unwrap();
    assert_eq!(outputs(&merged), outputs(&run));
    let rescored = dir.path().join("rescored");
    let _lock = sage_eval::claim(&rescored, false).unwrap();
    sage_eval::rescore_with_report(&run, Some(Mode::Vlnce), None, &rescored, &job).unwrap();
    assert_eq!(record(&rescored)["status"], "finished");
    assert!(rescored.join("report.html").is_file());
}

#[test]
fn a_human_run_is_finished_once_an_episode_is_played() {
    let f = fixture();
    let settings = EvalSettings {
        agent: sage_agents::AgentKind::Human,
        ..settings(&f.data, &f.scenes)
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("human");
    let mut run = HumanRun::open(settings.clone(), &out, false).unwrap();
    assert_eq!(record(&out)["status"], "unfinished");
    // Open for play here, it names the process playing it.
    let e = report::read_run(&out).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "the human run in this folder is open for play in the `eval` run of process {}",
            std::process::id()
        )) && e.contains("play an episode there to finish it"),
        "{e}"
    );
    // Closed unplayed, it says how to finish it.
    let unplayed = dir.path().join("unplayed");
    drop(HumanRun::open(settings.clone(), &unplayed, false).unwrap());
    let e = report::read_run(&unplayed).unwrap_err().to_string();
    assert!(
        e.contains("the human run in this folder was not finished")
            && e.contains(&format!(
                "play an episode of it (`sage3d view {} --play {}`)",
                f.data.display(),
                unplayed.display()
            )),
        "{e}"
    );
    // The oracle's moves stand in for a person's: the trace is scored the same (without
    // images, which never change the motion).
    let episode = run
        .episodes()
        .iter()
        .find(|e| e.task == sage_dataset::Task::Vln)
        .unwrap()
        .clone();
    let ctx = Arc::new(SceneContext::load(run.scene_dir(&episode.scene).unwrap(), None).unwrap());
    let oracle = "oracle"
        .parse::<sage_agents::AgentKind>()
        .unwrap()
        .maker()
        .unwrap();
    let config = sage_eval::env_config(run.settings(), &oracle).unwrap();
    let mut env = Env::new(ctx.clone(), config).unwrap();
    let mut agent = oracle.build(0).unwrap();
    let trace = run_episode(&mut env, agent.as_mut(), &episode.env_episode()).unwrap();
    run.record(&ctx, &episode.episode_id, &trace, Vec::new())
        .unwrap();
    assert_eq!(record(&out)["status"], "finished");
    drop(run);
    // Opened again, it is a finished run of its episodes played so far.
    let reopened = HumanRun::open(settings, &out, false).unwrap();
    assert_eq!(reopened.played(), 1);
    assert_eq!(record(&out)["status"], "finished");
    assert_eq!(report::read_run(&out).unwrap().records.len(), 1);
}

#[test]
fn a_folder_of_another_run_is_refused_naming_its_record_and_what_differs() {
    // A dataset of this test's own: its split file is changed below.
    let dir = tempfile::tempdir().unwrap();
    let (scenes, _, data) = common::small_dataset(dir.path(), 4);
    let oracle = settings(&data, &scenes);
    let run = dir.path().join("run");
    sage_eval::run(&oracle, &run, &|_, _| {}).unwrap();
    let before = sage_io::files::read_tree(&run).unwrap();
    let refused = |settings: &EvalSettings| {
        sage_eval::run(settings, &run, &|_, _| {})
            .unwrap_err()
            .to_string()
    };
    let file = run.join(RUN_RECORD);
    let message = |why: &str| {
        format!(
            "{}: this run folder holds a run with {why}; use a new run folder (`out`)",
            file.display()
        )
    };
    let random = EvalSettings {
        agent: "random".parse().unwrap(),
        ..oracle.clone()
    };
    assert_eq!(
        refused(&random),
        message("other settings (agent: oracle recorded, random asked)")
    );
    let more = EvalSettings {
        seed: 7,
        mode: Mode::Vlnce,
        ..random.clone()
    };
    assert_eq!(
        refused(&more),
        message(
            "other settings (agent: oracle recorded, random asked; mode: sage recorded, vlnce asked; seed: 0 recorded, 7 asked)"
        )
    );
    // A run recorded without the bodies ran with the default ones.
    let boxes = EvalSettings {
        splat_bodies: sage_physics::SplatBodies::Never,
        ..oracle.clone()
    };
    assert_eq!(
        refused(&boxes),
        message("other settings (splat_bodies: auto recorded, never asked)")
    );
    // The split's episodes file changed since the run (a line added at its end).
    let split = data.join("episodes/train.jsonl");
    let mut text = std::fs::read_to_string(&split).unwrap();
    text.push('\n');
    std::fs::write(&split, text).unwrap();
    let dataset = format!(
        "another dataset (its split file {} changed since the run)",
        split.display()
    );
    assert_eq!(refused(&oracle), message(&dataset));
    assert_eq!(
        refused(&random),
        message(&format!(
            "other settings (agent: oracle recorded, random asked) and {dataset}"
        ))
    );
    assert_eq!(sage_io::files::read_tree(&run).unwrap(), before);
    // A run of another split: its file is another file, whose hash differing is no news.
    let mut of_val = record(&run);
    of_val["settings"]["split"] = "val".into();
    sage_io::files::write_json(&file, &of_val).unwrap();
    assert_eq!(
        refused(&oracle),
        message("other settings (split: val recorded, train asked)")
    );
}

#[test]
fn a_run_loads_its_scenes_with_the_bodies_it_records() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, _, data) = common::small_dataset(dir.path(), 0);
    let bodies_of = |run: &Path| -> Vec<serde_json::Value> {
        std::fs::read_to_string(run.join("episodes.jsonl"))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["bodies"].clone())
            .collect()
    };
    let default = dir.path().join("default");
    sage_eval::run(&settings(&data, &scenes), &default, &|_, _| {}).unwrap();
    assert!(record(&default)["settings"].get("splat_bodies").is_none());
    let always = dir.path().join("always");
    let from_gaussians = EvalSettings {
        splat_bodies: sage_physics::SplatBodies::Always,
        ..settings(&data, &scenes)
    };
    sage_eval::run(&from_gaussians, &always, &|_, _| {}).unwrap();
    assert_eq!(record(&always)["settings"]["splat_bodies"], "always");
    // The synthetic scene's objects have meshes: by default none is recovered from its
    // Gaussians; asked for always, every episode ran among bodies from the Gaussians.
    let (by_default, asked) = (bodies_of(&default), bodies_of(&always));
    assert!(!asked.is_empty());
    assert!(
        by_default
            .iter()
            .all(|b| b.get("gaussians").is_none_or(|n| n == 0))
    );
    assert!(
        asked.iter().all(|b| b["gaussians"].as_u64().unwrap() > 0),
        "{asked:?}"
    );
}

/// An oracle runner in `config` (the stand-in for a front end's own environment: the Python
/// package's `overrides`).
fn run_in(settings: &EvalSettings, config: &EnvConfig, out: &Path) -> sage_core::Result<()> {
    let maker = settings.agent.maker().unwrap();
    let runner = Runner {
        config: config.clone(),
        agent_name: settings.agent.to_string(),
        agent: &|| maker.build(settings.seed),
        shard: None,
        serial: false,
        stop: None,
    };
    sage_eval::run_with(settings, &runner, out, &|_, _| {}).map(|_| ())
}

#[test]
fn a_run_records_its_environment_and_resumes_only_in_it() {
    let f = fixture();
    let oracle = settings(&f.data, &f.scenes);
    let plain = sage_eval::env_config(&oracle, &oracle.agent.maker().unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    sage_eval::run(&oracle, &run, &|_, _| {}).unwrap();
    let recorded: EnvConfig = serde_json::from_value(record(&run)["env"].clone()).unwrap();
    assert_eq!(recorded, plain);

    // A front end's own environment is recorded as it ran, each float as the f32 it is.
    let own = EnvConfig {
        sensors: sage_env::SensorConfig {
            camera_height: Some(1.1),
            ..plain.sensors
        },
        task: sage_env::TaskConfig {
            max_steps: 9,
            ..plain.task
        },
        ..plain.clone()
    };
    let custom = dir.path().join("custom");
    run_in(&oracle, &own, &custom).unwrap();
    let env = &record(&custom)["env"];
    assert_eq!(env["sensors"]["camera_height"], serde_json::json!(1.1));
    assert_eq!(env["task"]["max_steps"], 9);
    assert_eq!(
        serde_json::from_value::<EnvConfig>(env.clone()).unwrap(),
        own
    );
    // The same environment resumes; the record is the same bytes.
    let bytes = std::fs::read(custom.join(RUN_RECORD)).unwrap();
    run_in(&oracle, &own, &custom).unwrap();
    assert_eq!(std::fs::read(custom.join(RUN_RECORD)).unwrap(), bytes);

    // Another one is refused, naming each field that differs, before anything is written.
    let before = sage_io::files::read_tree(&custom).unwrap();
    let file = custom.join(RUN_RECORD);
    let message = |why: &str| {
        format!(
            "{}: this run folder holds a run with {why}; use a new run folder (`out`)",
            file.display()
        )
    };
    assert_eq!(
        run_in(&oracle, &plain, &custom).unwrap_err().to_string(),
        message(
            "another environment (env.sensors.camera_height: 1.1 recorded, none asked; env.task.max_steps: 9 recorded, 500 asked)"
        )
    );
    assert_eq!(
        sage_eval::run(&oracle, &custom, &|_, _| {})
            .unwrap_err()
            .to_string(),
        message(
            "another environment (env.sensors.camera_height: 1.1 recorded, none asked; env.task.max_steps: 9 recorded, 500 asked)"
        )
    );
    let seed = EvalSettings {
        seed: 7,
        ..oracle.clone()
    };
    let longer = EnvConfig {
        task: sage_env::TaskConfig {
            max_steps: 12,
            ..own.task
        },
        ..own.clone()
    };
    assert_eq!(
        run_in(&seed, &longer, &custom).unwrap_err().to_string(),
        message(
            "other settings (seed: 0 recorded, 7 asked) and another environment (env.task.max_steps: 9 recorded, 12 asked)"
        )
    );
    assert_eq!(sage_io::files::read_tree(&custom).unwrap(), before);

    // A rescoring and a merge carry the environment through.
    let rescored = dir.path().join("rescored");
    sage_eval::rescore(&custom, Some(Mode::Vlnce), None, &rescored).unwrap();
    assert_eq!(record(&rescored)["env"], record(&custom)["env"]);
    let shards = [std::fs::read_to_string(custom.join("episodes.jsonl")).unwrap()];
    let merged = dir.path().join("merged");
    sage_eval::merge_shards(&oracle, "oracle", Some(&own), &shards, &merged).unwrap();
    assert_eq!(record(&merged)["env"], record(&custom)["env"]);
    assert_eq!(record(&merged)["status"], "finished");
    // A merge that is not told, of an agent that is not the settings' own (a Python agent's
    // records), claims no environment.
    let python = dir.path().join("python");
    sage_eval::merge_shards(&oracle, "my-agent", None, &shards, &python).unwrap();
    assert!(record(&python).get("env").is_none());
}

#[test]
fn a_run_recorded_before_the_environment_still_resumes_rescores_and_reports() {
    let f = fixture();
    let oracle = settings(&f.data, &f.scenes);
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    sage_eval::run(&oracle, &run, &|_, _| {}).unwrap();
    let mut old = record(&run);
    let env = old.as_object_mut().unwrap().remove("env").unwrap();
    sage_io::files::write_json(&run.join(RUN_RECORD), &old).unwrap();
    // Read as it always was: its report, and a rescoring, which has no environment to claim.
    report::write(&run, &f.scenes).unwrap();
    let rescored = dir.path().join("rescored");
    sage_eval::rescore(&run, Some(Mode::Vlnce), None, &rescored).unwrap();
    assert!(record(&rescored).get("env").is_none());
    // Nothing recorded to compare: it resumes (every episode already run), and its record now
    // holds the environment this run asked for.
    let maker = oracle.agent.maker().unwrap();
    let other = EnvConfig {
        task: sage_env::TaskConfig {
            max_steps: 9,
            ..Default::default()
        },
        ..sage_eval::env_config(&oracle, &maker).unwrap()
    };
    let records = std::fs::read(run.join("episodes.jsonl")).unwrap();
    sage_eval::run(&oracle, &run, &|_, _| {}).unwrap();
    assert_eq!(record(&run)["env"], env);
    assert_eq!(std::fs::read(run.join("episodes.jsonl")).unwrap(), records);
    // From then on it resumes only in that environment.
    let e = run_in(&oracle, &other, &run).unwrap_err().to_string();
    assert!(
        e.contains("another environment (env.task.max_steps: 500 recorded, 9 asked)"),
        "{e}"
    );
}
