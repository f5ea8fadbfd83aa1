//! `sage-eval`: the evaluator of sage3d and its report (SPEC §10, `docs/evaluation.md`).
//!
//! [`evaluator`] runs an agent (named by `sage-agents`) over a dataset split (read by
//! `sage-dataset`) in the environment, resumably and in parallel; [`settings`] is what a run
//! folder records and resumes, [`records`] the per-episode records file, [`summary`] the
//! metric means overall and per slice, [`merge`] the merge of sharded runs,
//! [`rescore`](mod@rescore) a finished run scored again in another metric mode from its stored
//! records, and [`folder`] the layout of a run folder and how a folder is told to be one;
//! [`human`] records and scores the episodes a person plays in the viewer like an agent's. [`report`] turns a run folder into a self-contained HTML page with
//! the metric tables, per-slice charts and per-episode trajectory maps.

pub mod evaluator;
pub mod folder;
pub mod human;
pub mod merge;
pub mod records;
pub mod report;
pub mod rescore;
pub mod settings;
pub mod summary;

pub use evaluator::{
    RunOutcome, Runner, claim, claim_rescoring, env_config, evaluation_env, run, run_with,
    run_with_report, score_into, with_runner,
};
pub use human::HumanRun;
pub use merge::{merge_shards, merge_shards_with_report};
pub use records::{EvalRecord, Failure};
pub use rescore::{Rescored, rescore, rescore_with_report};
pub use settings::EvalSettings;
pub use summary::Summary;
