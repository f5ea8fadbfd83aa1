//! The validator every instruction sage3d writes passes, whatever wrote it (SPEC §8; imported
//! benchmarks keep their published instructions): no internal ids, 5–20
//! words, every object noun grounded in the scene's text map, and the type's defining feature
//! present. Rejects are counted by reason.

use crate::instruction::InstructionType;
use crate::textmap::TextMap;
use crate::words::{self, contains_phrase, tokens};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// Why an instruction was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RejectReason {
    /// No words.
    Empty,
    /// Contains an internal id (`chair_3`, `room_2`) or an id-like word.
    InternalId,
    /// Fewer words than the minimum.
    TooShort,
    /// More words than the maximum.
    TooLong,
    /// Names an object the text map does not have.
    Ungrounded,
    /// Lacks the defining feature of its type.
    MissingFeature,
    /// An LLM answer with a type name that is not one of the five.
    UnknownType,
    /// An LLM answer whose `start` / `end` are not the ones asked for.
    EndpointMismatch,
    /// The same text twice for one trajectory.
    Duplicate,
}

impl RejectReason {
    /// The snake-case name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            RejectReason::Empty => "empty",
            RejectReason::InternalId => "internal_id",
            RejectReason::TooShort => "too_short",
            RejectReason::TooLong => "too_long",
            RejectReason::Ungrounded => "ungrounded",
            RejectReason::MissingFeature => "missing_feature",
            RejectReason::UnknownType => "unknown_type",
            RejectReason::EndpointMismatch => "endpoint_mismatch",
            RejectReason::Duplicate => "duplicate",
        }
    }
}

/// Counts of checked, accepted and rejected instructions.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// Instructions checked.
    pub checked: usize,
    /// Accepted.
    pub accepted: usize,
    /// Rejected, per reason.
    pub rejected: BTreeMap<String, usize>,
}

impl ValidationReport {
    /// Counts one outcome.
    pub fn record(&mut self, outcome: Result<(), RejectReason>) {
        self.checked += 1;
        match outcome {
            Ok(()) => self.accepted += 1,
            Err(r) => *self.rejected.entry(r.as_str().to_string()).or_insert(0) += 1,
        }
    }

    /// Adds another report's counts.
    pub fn merge(&mut self, other: &ValidationReport) {
        self.checked += other.checked;
        self.accepted += other.accepted;
        for (k, v) in &other.rejected {
            *self.rejected.entry(k.clone()).or_insert(0) += v;
        }
    }
}

/// Fewest words an instruction may have (the paper's range).
pub const MIN_WORDS: usize = 5;
/// Most words an instruction may have (the paper's range).
pub const MAX_WORDS: usize = 20;

/// Checks instructions against one scene's text map.
#[derive(Debug, Clone)]
pub struct Validator {
    min_words: usize,
    max_words: usize,
    ids: BTreeSet<String>,
    /// Words of every object noun, room name and area name of the map.
    grounded: BTreeSet<String>,
    /// Attribute words valid for this map (plus the general ones).
    attributes: Vec<String>,
}

impl Validator {
    /// A validator for `tm` with the paper's 5–20 word range.
    pub fn new(tm: &TextMap) -> Validator {
        let mut grounded: BTreeSet<String> = BTreeSet::new();
        let names = tm
            .objects
            .iter()
            .map(|o| o.noun.clone())
            .chain(tm.rooms.iter().map(|r| r.name.clone()))
            .chain(tm.areas.iter().map(|a| a.name.clone()));
        for n in names {
            for w in tokens(&n) {
                if let Some(group) = words::SYNONYMS.iter().find(|g| g.contains(&w.as_str())) {
                    grounded.extend(group.iter().map(|s| s.to_string()));
                }
                grounded.insert(w);
            }
        }
        let mut attributes: Vec<String> = words::ATTRIBUTE_WORDS
            .iter()
            .map(|s| s.to_string())
            .collect();
        attributes.extend(
            sage_scene::vocabulary::COLORS
                .iter()
                .map(|(n, _)| n.to_string()),
        );
        for o in &tm.objects {
            let a = &o.attributes;
            attributes.extend(a.color.iter().cloned());
            attributes.extend(a.size.iter().cloned());
            attributes.extend(a.material.iter().map(|m| words::material_adjective(m)));
            attributes.extend(
                a.state
                    .iter()
                    .map(|s| words::state_adjective(s, &o.category)),
            );
        }
        attributes.sort();
        attributes.dedup();
        Validator {
            min_words: MIN_WORDS,
            max_words: MAX_WORDS,
            ids: tm.ids().map(|s| s.to_lowercase()).collect(),
            grounded,
            attributes,
        }
    }

    /// Checks one instruction of type `kind`.
    pub fn check(&self, text: &str, kind: InstructionType) -> Result<(), RejectReason> {
        let t = tokens(text);
        if t.is_empty() {
            return Err(RejectReason::Empty);
        }
        let id_like = |w: &String| {
            self.ids.contains(w)
                || w.contains('_')
                || (w.chars().any(|c| c.is_ascii_digit()) && w.chars().any(|c| c.is_alphabetic()))
        };
        if t.iter().any(id_like) {
            return Err(RejectReason::InternalId);
        }
        if t.len() < self.min_words {
            return Err(RejectReason::TooShort);
        }
        if t.len() > self.max_words {
            return Err(RejectReason::TooLong);
        }
        let ungrounded = t.iter().any(|w| {
            let forms = [Some(w.as_str()), w.strip_suffix("es"), w.strip_suffix('s')];
            forms
                .into_iter()
                .flatten()
                .find(|f| words::OBJECT_NOUNS.contains(f))
                .is_some_and(|noun| !self.grounded.contains(noun))
        });
        if ungrounded {
            return Err(RejectReason::Ungrounded);
        }
        let any = |list: &[&str]| list.iter().any(|v| contains_phrase(&t, v));
        let ok = match kind {
            InstructionType::AddObject => any(words::CARRY_VERBS),
            InstructionType::ScenarioDriven => any(words::NEED_WORDS),
            InstructionType::RelativeRelationship => any(words::RELATION_PHRASES),
            InstructionType::AttributeBased => {
                self.attributes.iter().any(|a| contains_phrase(&t, a))
            }
            InstructionType::AreaBased => any(words::AREA_WORDS),
            InstructionType::BaseAction => any(words::BASE_ACTION_WORDS),
            InstructionType::SingleGoal => any(words::MOTION_VERBS),
            InstructionType::GoalLess => true,
        };
        if ok {
            Ok(())
        } else {
            Err(RejectReason::MissingFeature)
        }
    }
}
