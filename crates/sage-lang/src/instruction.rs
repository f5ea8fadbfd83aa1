//! What an instruction is: its text, level, type and where it came from.

use serde::{Deserialize, Serialize};

/// Instruction level (SPEC §8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// Task semantics and human intent.
    High,
    /// Motion primitives and point-to-point goals.
    Low,
}

impl Level {
    /// `high` or `low`.
    pub fn as_str(self) -> &'static str {
        match self {
            Level::High => "high",
            Level::Low => "low",
        }
    }
}

/// Instruction type, spelled as in SAGE-Bench files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum InstructionType {
    /// A causal object to carry (the released data calls it `Add_Causality`; read as this).
    #[serde(rename = "Add_Object", alias = "Add_Causality")]
    AddObject,
    /// A human need that makes the goal reasonable.
    #[serde(rename = "Scenario_Driven")]
    ScenarioDriven,
    /// The goal singled out by a spatial relation.
    #[serde(rename = "Relative_Relationship")]
    RelativeRelationship,
    /// The goal singled out by a perceivable attribute.
    #[serde(rename = "Attribute-based")]
    AttributeBased,
    /// A functional area rather than an object.
    #[serde(rename = "Area-based")]
    AreaBased,
    /// Low level: move forward / backward N steps, turn X degrees in place.
    #[serde(rename = "Base-Action")]
    BaseAction,
    /// Low level: go from a room, object or zone to another.
    #[serde(rename = "Single-Goal")]
    SingleGoal,
    /// No-goal exploration.
    #[serde(rename = "Goal-less")]
    GoalLess,
}

impl InstructionType {
    /// The five high-level types, in the order of the paper.
    pub const HIGH: [InstructionType; 5] = [
        InstructionType::AddObject,
        InstructionType::ScenarioDriven,
        InstructionType::RelativeRelationship,
        InstructionType::AttributeBased,
        InstructionType::AreaBased,
    ];

    /// The name used in files (`Add_Object`, `Base-Action`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            InstructionType::AddObject => "Add_Object",
            InstructionType::ScenarioDriven => "Scenario_Driven",
            InstructionType::RelativeRelationship => "Relative_Relationship",
            InstructionType::AttributeBased => "Attribute-based",
            InstructionType::AreaBased => "Area-based",
            InstructionType::BaseAction => "Base-Action",
            InstructionType::SingleGoal => "Single-Goal",
            InstructionType::GoalLess => "Goal-less",
        }
    }

    /// Parses a file name of a type (also `Add_Causality`, case-insensitive).
    pub fn parse(s: &str) -> Option<InstructionType> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("Add_Causality") {
            return Some(InstructionType::AddObject);
        }
        [
            InstructionType::AddObject,
            InstructionType::ScenarioDriven,
            InstructionType::RelativeRelationship,
            InstructionType::AttributeBased,
            InstructionType::AreaBased,
            InstructionType::BaseAction,
            InstructionType::SingleGoal,
            InstructionType::GoalLess,
        ]
        .into_iter()
        .find(|t| t.as_str().eq_ignore_ascii_case(s))
    }

    /// The level of the type (`None` for no-goal).
    pub fn level(self) -> Option<Level> {
        match self {
            InstructionType::BaseAction | InstructionType::SingleGoal => Some(Level::Low),
            InstructionType::GoalLess => None,
            _ => Some(Level::High),
        }
    }
}

/// The five Single-Goal subtypes (paper appendix C).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SingleGoalKind {
    /// Between two rooms.
    RoomToRoom,
    /// From a room to an object.
    RoomToObject,
    /// Between two objects.
    ObjectToObject,
    /// From an object to a room.
    ObjectToRoom,
    /// Between functional zones (any trip with an area at either end).
    ZoneToZone,
}

impl SingleGoalKind {
    /// The file name (`room_to_object`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            SingleGoalKind::RoomToRoom => "room_to_room",
            SingleGoalKind::RoomToObject => "room_to_object",
            SingleGoalKind::ObjectToObject => "object_to_object",
            SingleGoalKind::ObjectToRoom => "object_to_room",
            SingleGoalKind::ZoneToZone => "zone_to_zone",
        }
    }
}

/// Who wrote an instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// Low-level templates.
    Template,
    /// The offline grammar.
    Grammar,
    /// An LLM endpoint.
    Llm,
    /// Read from an external file.
    Imported,
}

/// One instruction for a trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instruction {
    /// The text.
    pub text: String,
    /// Its type.
    pub kind: InstructionType,
    /// For Single-Goal: the subtype.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subtype: Option<SingleGoalKind>,
    /// Who wrote it.
    pub source: Source,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_released_alias_reads() {
        for t in InstructionType::HIGH {
            assert_eq!(InstructionType::parse(t.as_str()), Some(t));
            let json = serde_json::to_string(&t).unwrap();
            assert_eq!(json, format!("\"{}\"", t.as_str()));
        }
        let t: InstructionType = serde_json::from_str("\"Add_Causality\"").unwrap();
        assert_eq!(t, InstructionType::AddObject);
        assert_eq!(
            InstructionType::parse("Add_Causality"),
            Some(InstructionType::AddObject)
        );
        assert_eq!(InstructionType::parse("nonsense"), None);
    }
}
