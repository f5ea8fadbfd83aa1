//! No episode is solved by doing nothing: an agent that calls STOP at its start scores SR 0 in
//! mode `sage` on every VLN episode of a generated dataset, whatever its instruction type
//! (Base-Action turns in place and one-step moves included), while the oracle solves them.

use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::formats::jsonl;
use sage_dataset::split::SplitParams;
use sage_env::agents::{OracleAgent, run_episode};
use sage_env::scoring::score;
use sage_env::{Action, Env, EnvConfig, SceneContext, SensorConfig};
use sage_lang::InstructionType;
use sage_metrics::Mode;
use sage_synth::{SynthConfig, generate};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

#[test]
fn stop_at_start_never_succeeds_and_the_oracle_does() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path().join("scenes/home1");
    generate(&SynthConfig {
        seed: 3,
        rooms: 4,
        objects: 40,
        gaussians: 1000,
        ..SynthConfig::default()
    })
    .unwrap()
    .save(&home, sage_scene::SplatLayout::Compressed)
    .unwrap();
    let data = dir.path().join("data");
    // Enough Base-Actions to draw every motion (forward, backward, turns left and right).
    let params = SceneParams {
        base_actions: 24,
        ..SceneParams::new(6, 5)
    };
    let assemble = AssembleParams {
        seed: 5,
        split: SplitParams::default(),
        balanced: 0,
    };
    build::build(
        std::slice::from_ref(&home),
        &data,
        &params,
        &assemble,
        &|_| {},
    )
    .unwrap();
    let mut episodes = BTreeMap::new();
    for file in std::fs::read_dir(data.join("episodes")).unwrap() {
        for e in jsonl::read(&file.unwrap().path()).unwrap() {
            episodes.insert(e.episode_id.clone(), e);
        }
    }
    let ctx = Arc::new(SceneContext::load(&home, None).unwrap());
    let config = EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    };
    let mut env = Env::new(ctx.clone(), config).unwrap();
    let mut types = BTreeSet::new();
    let mut turns_in_place = 0;
    for e in episodes.values().filter(|e| e.task == sage_core::Task::Vln) {
        let episode = e.env_episode();
        env.reset(&episode).unwrap();
        env.step(Action::Stop).unwrap();
        let m = score(&ctx, env.trace().unwrap(), Mode::Sage).unwrap();
        assert_eq!(
            m.sr,
            Some(0.0),
            "{} ({:?}): STOP at start succeeded: '{}'",
            e.episode_id,
            e.instruction_type,
            e.instruction
        );
        types.insert(e.instruction_type);
        if e.instruction_type == InstructionType::BaseAction {
            turns_in_place += usize::from(e.path_length == 0.0);
            let trace = run_episode(&mut env, &mut OracleAgent::new(0.25), &episode).unwrap();
            let m = score(&ctx, &trace, Mode::Sage).unwrap();
            assert_eq!(
                m.sr,
                Some(1.0),
                "{}: the oracle failed '{}'",
                e.episode_id,
                e.instruction
            );
        }
    }
    assert!(turns_in_place > 0, "no Base-Action turn in place drawn");
    for t in [
        InstructionType::AddObject,
        InstructionType::ScenarioDriven,
        InstructionType::RelativeRelationship,
        InstructionType::AttributeBased,
        InstructionType::AreaBased,
        InstructionType::BaseAction,
        InstructionType::SingleGoal,
    ] {
        assert!(types.contains(&t), "no {t:?} episode in the dataset");
    }
}
