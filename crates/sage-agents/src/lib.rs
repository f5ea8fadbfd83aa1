//! Agents of the evaluator: [`kind`] names them (`--agent`) and makes one per episode; beyond
//! the environment's local baselines, [`replay`] replays the
//! actions or poses recorded per episode elsewhere, so their metrics can be computed here, and
//! [`remote`] queries model servers (the SAGE socket protocol, HTTP `/vln_step`) and
//! OpenAI-compatible chat models with the episode's recent frames (`docs/evaluation.md`).

pub mod kind;
pub mod remote;
pub mod replay;

pub use kind::{AgentKind, AgentMaker};
