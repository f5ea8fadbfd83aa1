//! `sage-lang`: the instructions of the benchmark (SPEC §8).
//!
//! From a scene and its navigation layer this crate builds the [`textmap`] (rooms, functional
//! areas, objects with attributes and spatial relations, as data and as text), writes low-level
//! instructions from templates ([`lowlevel`]: Base-Action with exact ground-truth actions and the
//! five Single-Goal subtypes) and high-level ones from an offline grammar grounded in the text map
//! ([`highlevel`], with unique referring expressions from [`refexp`]) or from any OpenAI-compatible
//! chat endpoint ([`llm`], the paper's prompt), checks every instruction with the [`validate`]
//! rules, and turns reference paths into discrete VLN-CE actions ([`actions`]).
//! Conventions are documented in `docs/instructions.md`.

pub mod actions;
pub mod grammar;
pub mod highlevel;
pub mod instruction;
pub mod llm;
pub mod lowlevel;
pub mod refexp;
pub mod textmap;
pub mod validate;
pub mod words;

pub use actions::{DiscreteAction, StepSizes};
pub use instruction::{Instruction, InstructionType, Level, SingleGoalKind, Source};
pub use textmap::TextMap;
pub use validate::{RejectReason, Validator};
