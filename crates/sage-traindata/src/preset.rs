//! Action presets: the step and turn of the discrete actions a trajectory is cut into, and the
//! text NaVILA is trained to answer with.

use sage_core::{Error, Result};
use sage_env::Action;
use serde::{Deserialize, Serialize};

/// Motions per trajectory at most, the published default: the published action generator
/// stops adding actions once a trajectory has `min(50, 2 × max_actions_per_trajectory)`, which
/// is 50 for every one of its presets.
pub const DEFAULT_MAX_ACTIONS: usize = 50;

/// How a trajectory becomes discrete actions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionPreset {
    /// The preset's name (`vlnce`, `navila_small`, `navila_large`, `custom_small`, `custom`).
    pub name: String,
    /// MOVE_FORWARD distance, metres.
    pub step_m: f32,
    /// TURN_LEFT / TURN_RIGHT angle, degrees.
    pub turn_deg: f32,
    /// Motions (every action but STOP) at most; past it the replay calls STOP where it
    /// stands.
    pub max_actions: usize,
}

/// The published presets: name, step (m), turn (°).
const PUBLISHED: [(&str, f32, f32); 4] = [
    ("vlnce", 0.25, 15.0),
    ("navila_small", 0.35, 30.0),
    ("navila_large", 0.75, 15.0),
    ("custom_small", 0.50, 30.0),
];

impl ActionPreset {
    /// The names [`ActionPreset::named`] knows.
    pub fn names() -> Vec<&'static str> {
        PUBLISHED.iter().map(|p| p.0).collect()
    }

    /// A published preset by name, with the published cap of 50 motions.
    ///
    /// # Errors
    ///
    /// An unknown name, listing the known ones.
    pub fn named(name: &str) -> Result<ActionPreset> {
        let (name, step_m, turn_deg) =
            PUBLISHED
                .iter()
                .find(|p| p.0 == name)
                .copied()
                .ok_or_else(|| {
                    Error::invalid(format!(
                        "unknown action preset '{name}' (known: {})",
                        Self::names().join(", ")
                    ))
                })?;
        Ok(ActionPreset {
            name: name.to_string(),
            step_m,
            turn_deg,
            max_actions: DEFAULT_MAX_ACTIONS,
        })
    }

    /// `base` with its step, turn or cap replaced; a preset with a changed step or turn is
    /// named `custom`.
    ///
    /// # Errors
    ///
    /// A step outside (0, 5] m, a turn outside (0, 180] degrees or a cap of 0.
    pub fn with(
        base: ActionPreset,
        step_m: Option<f32>,
        turn_deg: Option<f32>,
        max_actions: Option<usize>,
    ) -> Result<ActionPreset> {
        let mut p = base;
        if step_m.is_some_and(|s| s != p.step_m) || turn_deg.is_some_and(|t| t != p.turn_deg) {
            p.name = "custom".into();
        }
        p.step_m = step_m.unwrap_or(p.step_m);
        p.turn_deg = turn_deg.unwrap_or(p.turn_deg);
        p.max_actions = max_actions.unwrap_or(p.max_actions);
        if !(p.step_m > 0.0 && p.step_m <= 5.0) {
            return Err(Error::invalid(format!(
                "step: {} m is outside (0, 5]",
                p.step_m
            )));
        }
        if !(p.turn_deg > 0.0 && p.turn_deg <= 180.0) {
            return Err(Error::invalid(format!(
                "turn: {} degrees is outside (0, 180]",
                p.turn_deg
            )));
        }
        if p.max_actions == 0 {
            return Err(Error::invalid("max actions: must be at least 1"));
        }
        Ok(p)
    }

    /// The action in NaVILA's words: `move forward 0.35 meter`, `turn left 30 degree`,
    /// `turn right 30 degree`, `stop` (numbers as the published pipeline prints them).
    pub fn words(&self, action: Action) -> String {
        match action {
            Action::MoveForward => format!("move forward {} meter", self.step_m),
            Action::TurnLeft => format!("turn left {} degree", self.turn_deg),
            Action::TurnRight => format!("turn right {} degree", self.turn_deg),
            _ => "stop".to_string(),
        }
    }

    /// The answer of a NaVILA sample: `The next action is move forward 0.35 meter.`
    pub fn answer(&self, action: Action) -> String {
        format!("The next action is {}.", self.words(action))
    }
}

/// The published name of a discrete action (`MOVE_FORWARD`, `TURN_LEFT`, `TURN_RIGHT`,
/// `STOP`).
pub fn action_name(action: Action) -> &'static str {
    match action {
        Action::MoveForward => "MOVE_FORWARD",
        Action::TurnLeft => "TURN_LEFT",
        Action::TurnRight => "TURN_RIGHT",
        _ => "STOP",
    }
}

/// The discrete action of a published name (anything else is STOP).
pub fn action_from_name(name: &str) -> Action {
    match name {
        "MOVE_FORWARD" => Action::MoveForward,
        "TURN_LEFT" => Action::TurnLeft,
        "TURN_RIGHT" => Action::TurnRight,
        _ => Action::Stop,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn published_presets_and_their_words() {
        let p = ActionPreset::named("navila_small").unwrap();
        assert_eq!((p.step_m, p.turn_deg, p.max_actions), (0.35, 30.0, 50));
        assert_eq!(
            p.answer(Action::MoveForward),
            "The next action is move forward 0.35 meter."
        );
        assert_eq!(p.words(Action::TurnLeft), "turn left 30 degree");
        assert_eq!(p.words(Action::TurnRight), "turn right 30 degree");
        assert_eq!(p.answer(Action::Stop), "The next action is stop.");
        let c = ActionPreset::named("custom_small").unwrap();
        assert_eq!(c.words(Action::MoveForward), "move forward 0.5 meter");
        assert_eq!(
            ActionPreset::named("vlnce")
                .unwrap()
                .words(Action::TurnLeft),
            "turn left 15 degree"
        );
        let e = ActionPreset::named("habitat").unwrap_err().to_string();
        assert!(e.contains("navila_large"), "{e}");
    }

    #[test]
    fn overrides_rename_and_are_checked() {
        let base = ActionPreset::named("vlnce").unwrap();
        let p = ActionPreset::with(base.clone(), Some(0.4), None, Some(20)).unwrap();
        assert_eq!(
            (p.name.as_str(), p.step_m, p.max_actions),
            ("custom", 0.4, 20)
        );
        let same = ActionPreset::with(base.clone(), Some(0.25), None, None).unwrap();
        assert_eq!(same.name, "vlnce");
        assert!(ActionPreset::with(base.clone(), Some(0.0), None, None).is_err());
        assert!(ActionPreset::with(base.clone(), None, Some(200.0), None).is_err());
        assert!(ActionPreset::with(base, None, None, Some(0)).is_err());
    }
}
