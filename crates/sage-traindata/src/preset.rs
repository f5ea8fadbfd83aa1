//! Action presets: the step and turn of the discrete actions a trajectory is cut into, and the
//! text NaVILA is trained to answer with ([`Answers`]: SAGE-3D's metres or stock NaVILA's
//! centimetres).

use sage_core::{Error, Result};
use sage_env::Action;
use sage_env::config::TRAINING_STEPS;
use serde::{Deserialize, Serialize};

/// Motions per trajectory at most, the published default: the published action generator
/// stops adding actions once a trajectory has `min(50, 2 × max_actions_per_trajectory)`, which
/// is 50 for every one of its presets.
pub const DEFAULT_MAX_ACTIONS: usize = 50;

/// The motion caps a render takes, on every path in (flags, Python, settings files, settings
/// JSON): at least one motion, and a bound far above any walk that keeps the environment's
/// step limit (`max_actions + 1`) from overflowing.
pub const MAX_ACTIONS_RANGE: std::ops::RangeInclusive<usize> = 1..=1_000_000;

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
    /// How the answers word the step and the turn. Recorded only when not `sage` (so the
    /// record of the default is as it always was); a render resumes only with the wording it
    /// started with.
    #[serde(default, skip_serializing_if = "Answers::is_sage")]
    pub answers: Answers,
}

/// How a sample's answer words the step and the turn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Answers {
    /// SAGE-3D's `create_navila_dataset.py`: metres and degrees as the preset holds them
    /// (`move forward 0.35 meter`, `turn left 30 degree`).
    #[default]
    Sage,
    /// Stock NaVILA's (its R2R data, and the replies its evaluator parses with
    /// `move forward (\d+) cm` and `turn left (\d+) degree`): whole centimetres and whole
    /// degrees (`move forward 35 cm`, `turn left 30 degree`). A step or turn that is not
    /// whole in those units is refused ([`ActionPreset::check_answers`]), never rounded.
    Navila,
}

impl Answers {
    /// Every wording's name.
    pub const NAMES: [&'static str; 2] = ["sage", "navila"];

    /// The wording's name.
    pub fn as_str(self) -> &'static str {
        match self {
            Answers::Sage => "sage",
            Answers::Navila => "navila",
        }
    }

    /// True for the default wording (serde leaves it out of the settings).
    pub fn is_sage(&self) -> bool {
        *self == Answers::Sage
    }
}

impl std::fmt::Display for Answers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Answers {
    type Err = Error;

    /// A wording by its name.
    fn from_str(name: &str) -> Result<Answers> {
        match name {
            "sage" => Ok(Answers::Sage),
            "navila" => Ok(Answers::Navila),
            other => Err(Error::invalid(format!(
                "unknown `answers` wording '{other}' (known: {})",
                Answers::NAMES.join(", ")
            ))),
        }
    }
}

/// A published action preset, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum PresetName {
    /// VLN-CE's: 0.25 m, 15°.
    Vlnce,
    /// NaVILA's small steps: 0.35 m, 30° (the default of every front end).
    #[default]
    NavilaSmall,
    /// NaVILA's large steps: 0.75 m, 15°.
    NavilaLarge,
    /// The published custom preset: 0.50 m, 30°.
    CustomSmall,
}

impl PresetName {
    /// Every published preset.
    pub const ALL: [PresetName; 4] = [
        PresetName::Vlnce,
        PresetName::NavilaSmall,
        PresetName::NavilaLarge,
        PresetName::CustomSmall,
    ];

    /// The preset's name.
    pub fn as_str(self) -> &'static str {
        match self {
            PresetName::Vlnce => "vlnce",
            PresetName::NavilaSmall => "navila_small",
            PresetName::NavilaLarge => "navila_large",
            PresetName::CustomSmall => "custom_small",
        }
    }

    /// The preset, with the published cap of 50 motions: the steps of the environment preset
    /// of the same name ([`TRAINING_STEPS`], in the order of [`PresetName::ALL`]), so that a
    /// model trained on the data is evaluated moving as it was taught (`sage3d eval --preset`).
    pub fn preset(self) -> ActionPreset {
        let (_, step_m, turn_deg) = TRAINING_STEPS[self as usize];
        ActionPreset {
            name: self.as_str().to_string(),
            step_m,
            turn_deg,
            max_actions: DEFAULT_MAX_ACTIONS,
            answers: Answers::default(),
        }
    }
}

impl std::fmt::Display for PresetName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for PresetName {
    type Err = Error;

    /// A preset by its name.
    fn from_str(name: &str) -> Result<PresetName> {
        PresetName::ALL
            .into_iter()
            .find(|p| p.as_str() == name)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "unknown action preset '{name}' (known: {})",
                    ActionPreset::names().join(", ")
                ))
            })
    }
}

impl ActionPreset {
    /// The names [`ActionPreset::named`] knows.
    pub fn names() -> Vec<&'static str> {
        PresetName::ALL.iter().map(|p| p.as_str()).collect()
    }

    /// A published preset by name, with the published cap of 50 motions.
    ///
    /// # Errors
    ///
    /// An unknown name, listing the known ones.
    pub fn named(name: &str) -> Result<ActionPreset> {
        Ok(name.parse::<PresetName>()?.preset())
    }

    /// `base` with its step, turn or cap replaced; a preset with a changed step or turn is
    /// named `custom`.
    ///
    /// # Errors
    ///
    /// A step outside (0, 5] m, a turn outside (0, 180] degrees or a cap outside
    /// [`MAX_ACTIONS_RANGE`].
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
                "`step`: {} m is outside (0, 5]",
                p.step_m
            )));
        }
        if !(p.turn_deg > 0.0 && p.turn_deg <= 180.0) {
            return Err(Error::invalid(format!(
                "`turn`: {} degrees is outside (0, 180]",
                p.turn_deg
            )));
        }
        p.check_max_actions()?;
        Ok(p)
    }

    /// Checks the cap on motions: within [`MAX_ACTIONS_RANGE`].
    ///
    /// # Errors
    ///
    /// A cap outside the range, naming `max_actions`.
    pub fn check_max_actions(&self) -> Result<()> {
        if !MAX_ACTIONS_RANGE.contains(&self.max_actions) {
            return Err(Error::invalid(format!(
                "`max_actions`: {} is outside {}..={} (motions per trajectory)",
                self.max_actions,
                MAX_ACTIONS_RANGE.start(),
                MAX_ACTIONS_RANGE.end()
            )));
        }
        Ok(())
    }

    /// `self` answering in `answers`' words.
    ///
    /// # Errors
    ///
    /// As [`ActionPreset::check_answers`].
    pub fn worded(self, answers: Answers) -> Result<ActionPreset> {
        let p = ActionPreset { answers, ..self };
        p.check_answers()?;
        Ok(p)
    }

    /// Checks that the wording can say the step and the turn exactly: NaVILA's words have
    /// whole centimetres and whole degrees, and a rounded number would teach a model a step
    /// the walk did not take.
    ///
    /// # Errors
    ///
    /// A step or turn that is not whole in the wording's units, naming `answers`.
    pub fn check_answers(&self) -> Result<()> {
        if self.answers != Answers::Navila {
            return Ok(());
        }
        // f32 holds 0.35 as 0.3499999940…: whole within a thousandth is whole.
        // Whole and at least one: a step of 0.004 cm would read "move forward 0 cm".
        let whole = |v: f64| (v - v.round()).abs() < 1e-3 && v.round() >= 1.0;
        let cm = f64::from(self.step_m) * 100.0;
        if !whole(cm) {
            return Err(Error::invalid(format!(
                "`answers` navila words the step in whole centimetres (at least 1), but {} m is {} \
                 cm: give a step of whole centimetres (`step`) or keep `answers` sage",
                self.step_m,
                (cm * 1000.0).round() / 1000.0
            )));
        }
        if !whole(f64::from(self.turn_deg)) {
            return Err(Error::invalid(format!(
                "`answers` navila words the turn in whole degrees (at least 1), but it is {} \
                 degrees: give a turn of whole degrees (`turn`) or keep `answers` sage",
                self.turn_deg
            )));
        }
        Ok(())
    }

    /// The step in the answers' words: `0.35 meter` (SAGE-3D's), `35 cm` (NaVILA's).
    pub fn distance_words(&self) -> String {
        match self.answers {
            Answers::Sage => format!("{} meter", self.step_m),
            Answers::Navila => format!("{} cm", (f64::from(self.step_m) * 100.0).round()),
        }
    }

    /// The turn in the answers' words: `30 degree` (`22.5 degree` in SAGE-3D's words only).
    pub fn angle_words(&self) -> String {
        match self.answers {
            Answers::Sage => format!("{} degree", self.turn_deg),
            Answers::Navila => format!("{} degree", f64::from(self.turn_deg).round()),
        }
    }

    /// The action in the answers' words: `move forward 0.35 meter` (or `move forward 35 cm`),
    /// `turn left 30 degree`, `turn right 30 degree`, `stop` (SAGE-3D's numbers as the
    /// published pipeline prints them).
    pub fn words(&self, action: Action) -> String {
        match action {
            Action::MoveForward => format!("move forward {}", self.distance_words()),
            Action::TurnLeft => format!("turn left {}", self.angle_words()),
            Action::TurnRight => format!("turn right {}", self.angle_words()),
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

sage_core::named_by_string!(PresetName);
sage_core::named_by_string!(Answers);

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

    #[test]
    fn the_presets_are_the_environment_table_in_order() {
        for (p, (name, step, turn)) in PresetName::ALL.iter().zip(TRAINING_STEPS) {
            assert_eq!(p.as_str(), name);
            let preset = p.preset();
            assert_eq!((preset.step_m, preset.turn_deg), (step, turn));
        }
        assert_eq!(PresetName::ALL.len(), TRAINING_STEPS.len());
    }

    #[test]
    fn navila_answers_speak_whole_centimetres_and_refuse_fractions() {
        for (name, forward, left) in [
            ("navila_small", "move forward 35 cm", "turn left 30 degree"),
            ("navila_large", "move forward 75 cm", "turn left 15 degree"),
            ("vlnce", "move forward 25 cm", "turn left 15 degree"),
            ("custom_small", "move forward 50 cm", "turn left 30 degree"),
        ] {
            let p = ActionPreset::named(name)
                .unwrap()
                .worded(Answers::Navila)
                .unwrap();
            assert_eq!(p.words(Action::MoveForward), forward);
            assert_eq!(p.words(Action::TurnLeft), left);
            assert_eq!(p.answer(Action::Stop), "The next action is stop.");
        }
        let p = ActionPreset::named("navila_large")
            .unwrap()
            .worded(Answers::Navila)
            .unwrap();
        assert_eq!(
            p.answer(Action::MoveForward),
            "The next action is move forward 75 cm."
        );
        assert_eq!(p.words(Action::TurnRight), "turn right 15 degree");
        // What NaVILA's `(\d+) cm` and `(\d+) degree` cannot read is refused, not rounded.
        let base = ActionPreset::named("vlnce").unwrap();
        let odd = ActionPreset::with(base.clone(), Some(0.355), None, None).unwrap();
        let e = odd.clone().worded(Answers::Navila).unwrap_err().to_string();
        assert!(e.contains("`answers`") && e.contains("35.5 cm"), "{e}");
        assert_eq!(
            odd.worded(Answers::Sage)
                .unwrap()
                .words(Action::MoveForward),
            "move forward 0.355 meter"
        );
        let half = ActionPreset::with(base.clone(), None, Some(22.5), None).unwrap();
        let e = half
            .clone()
            .worded(Answers::Navila)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`answers`") && e.contains("22.5 degrees"), "{e}");
        assert_eq!(half.words(Action::TurnLeft), "turn left 22.5 degree");
        // Nor a step or turn that would read as 0.
        for (step, turn) in [(Some(0.000_004), None), (None, Some(0.0004))] {
            let tiny = ActionPreset::with(base.clone(), step, turn, None).unwrap();
            let e = tiny.worded(Answers::Navila).unwrap_err().to_string();
            assert!(e.contains("(at least 1)"), "{e}");
        }
        // Names parse the same way from a flag and from JSON; a bad one is named.
        assert_eq!("navila".parse::<Answers>().unwrap(), Answers::Navila);
        let read: Answers = serde_json::from_str("\"sage\"").unwrap();
        assert_eq!(read, Answers::Sage);
        let e = "cm".parse::<Answers>().unwrap_err().to_string();
        assert!(e.contains("`answers`") && e.contains("'cm'"), "{e}");
    }
}
