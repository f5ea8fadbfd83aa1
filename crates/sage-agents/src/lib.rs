//! `sage-agents`: the agents an evaluation runs, by name (`docs/evaluation.md`).
//!
//! [`kind`] names them ([`AgentKind`], as `sage3d eval` and `sage3d.evaluate` take them) and
//! makes one per episode; beyond the environment's local baselines, [`replay`] replays the
//! actions or poses recorded per episode elsewhere, so their metrics can be computed here, and
//! [`remote`] queries model servers (the SAGE socket protocol, HTTP `/vln_step`) and
//! OpenAI-compatible chat models with the episode's recent frames.

pub mod kind;
pub mod remote;
pub mod replay;

pub use kind::{AgentKind, AgentMaker};
