//! Low-level instructions (paper appendix C): Base-Action motions with their exact ground-truth
//! actions, and Single-Goal point-to-point instructions from templates over a trajectory's start
//! and goal.

use crate::actions::{DiscreteAction, StepSizes};
use crate::grammar::expand;
use crate::instruction::{Instruction, InstructionType, SingleGoalKind, Source};
use crate::refexp::{self, Style};
use crate::textmap::TextMap;
use crate::validate;
use crate::words::{number_word, tokens};
use glam::Vec2;
use rand::Rng;
use rand::seq::IndexedRandom;
use sage_core::Pose;
use sage_nav::EndpointKind;
use sage_nav::PathFinder;
use sage_nav::trajectory::EndRef;
use std::collections::BTreeMap;

/// A Base-Action instruction, where it starts and its exact actions (ending with STOP).
#[derive(Debug, Clone, PartialEq)]
pub struct BaseActionPlan {
    /// The instruction.
    pub instruction: Instruction,
    /// Start pose (W frame, navigable).
    pub start: Pose,
    /// Ground truth: what the words say, step for step.
    pub actions: Vec<DiscreteAction>,
}

/// Turn counts a Base-Action may ask for (×15°: 30°–180°).
const TURN_COUNTS: [usize; 6] = [2, 3, 4, 6, 8, 12];

/// Draws a Base-Action instruction at a random navigable start: move forward 1–8 steps, move
/// backward 1–4 steps, or turn 30–180° left or right in place. Moving backward is, in the
/// four-action space, a half turn left, the steps forward, and a half turn left again (the agent
/// ends facing the way it started). The start is redrawn (up to 20 times) until every point the
/// motion passes is navigable; `None` when none is found.
pub fn base_action(
    pf: &PathFinder,
    space: &StepSizes,
    rng: &mut impl Rng,
) -> Option<BaseActionPlan> {
    let kind = rng.random_range(0..4u8);
    let half_turn = (180.0 / space.turn_deg).round() as usize;
    let (text_template, actions, travel): (&str, Vec<DiscreteAction>, f32) = match kind {
        0 => {
            let n = rng.random_range(1..=8usize);
            let t = "[Move|Walk|Go] forward {n} {steps}[ and stop|, then stop| in a straight line and stop| and wait there].";
            (
                t,
                vec![DiscreteAction::Forward; n],
                n as f32 * space.forward,
            )
        }
        1 => {
            let n = rng.random_range(1..=4usize);
            let t = "[Move|Step|Go] backward {n} {steps}[ and stop|, then stop| and wait there].";
            let mut a = vec![DiscreteAction::Left; half_turn];
            a.extend(vec![DiscreteAction::Forward; n]);
            a.extend(vec![DiscreteAction::Left; half_turn]);
            (t, a, -(n as f32) * space.forward)
        }
        _ => {
            let k = *TURN_COUNTS.choose(rng)?;
            let t = "[Turn {deg} degrees to the {dir} in place|Rotate {deg} degrees to the {dir} without moving|Stay where you are and turn {deg} degrees {dir}].";
            let a = if kind == 2 {
                DiscreteAction::Left
            } else {
                DiscreteAction::Right
            };
            (t, vec![a; k], 0.0)
        }
    };
    let n = actions
        .iter()
        .filter(|a| **a == DiscreteAction::Forward)
        .count();
    let k = actions
        .iter()
        .filter(|a| **a != DiscreteAction::Forward)
        .count();
    let slots: BTreeMap<&str, String> = [
        ("n", number_word(n)),
        (
            "steps",
            if n == 1 {
                "step".into()
            } else {
                "steps".into()
            },
        ),
        ("deg", format!("{}", (k as f32 * space.turn_deg).round())),
        (
            "dir",
            if kind == 2 {
                "left".into()
            } else {
                "right".into()
            },
        ),
    ]
    .into();
    let text = expand(text_template, &slots, rng)?;
    for _ in 0..20 {
        let p = pf.sample_navigable_point(rng, None)?;
        let yaw = (rng.random_range(0..24) as f32 * 15.0).to_radians();
        let dir = Vec2::new(yaw.cos(), yaw.sin());
        let samples = (travel.abs() / 0.05).ceil() as usize;
        let clear = (0..=samples).all(|i| {
            let t = if samples == 0 {
                0.0
            } else {
                travel * i as f32 / samples as f32
            };
            pf.is_navigable(p + dir * t)
        });
        if clear {
            let mut all = actions.clone();
            all.push(DiscreteAction::Stop);
            return Some(BaseActionPlan {
                instruction: Instruction {
                    text,
                    kind: InstructionType::BaseAction,
                    subtype: None,
                    source: Source::Template,
                },
                start: Pose::new(p.extend(0.0), yaw),
                actions: all,
            });
        }
    }
    None
}

/// The room index of a `room_{i}` reference. A region (`region_{i}`, the room endpoints of a
/// scene with neither rooms nor objects) has none, so no instruction names it: nothing there
/// is visible to name it by.
pub fn room_index(reference: &str) -> Option<usize> {
    reference.strip_prefix("room_")?.parse().ok()
}

/// How to say a trajectory end (room, object or area), uniquely; `None` when it cannot be.
pub fn end_phrase(tm: &TextMap, end: &EndRef) -> Option<String> {
    match end.kind {
        EndpointKind::Room => refexp::room_phrase(tm, room_index(&end.reference)?),
        EndpointKind::Object => {
            let k = tm.object_index(&end.reference)?;
            Some(refexp::describe(tm, k, Style::Any)?.render())
        }
        EndpointKind::Area => refexp::area_phrase(tm, &end.reference),
    }
}

/// How to say a trajectory end as a zone: `the center of the kitchen`, `the area by the sofa`,
/// `the dining area`.
fn zone_phrase(tm: &TextMap, end: &EndRef) -> Option<String> {
    let p = end_phrase(tm, end)?;
    Some(match end.kind {
        EndpointKind::Room => format!("the center of {p}"),
        EndpointKind::Object => format!("the area by {p}"),
        EndpointKind::Area => p,
    })
}

/// The Single-Goal subtype of a trip: by the kinds of its ends; any trip with an area end is
/// zone→zone.
pub fn single_goal_kind(start: EndpointKind, goal: EndpointKind) -> SingleGoalKind {
    use EndpointKind::*;
    match (start, goal) {
        (Room, Room) => SingleGoalKind::RoomToRoom,
        (Room, Object) => SingleGoalKind::RoomToObject,
        (Object, Object) => SingleGoalKind::ObjectToObject,
        (Object, Room) => SingleGoalKind::ObjectToRoom,
        _ => SingleGoalKind::ZoneToZone,
    }
}

/// Single-Goal templates with the start named.
const FROM_TO: &str = "[Go from {start} to {goal}|Walk from {start} to {goal}|Head from {start} over to {goal}|Leave {start} and walk to {goal}|Starting at {start}, go to {goal}|Make your way from {start} to {goal}]";
/// Single-Goal templates with the start implicit.
const TO_ONLY: &str = "[Walk over to {goal} and stop|Go straight to {goal} and stop there|Make your way to {goal}, please|Navigate to {goal} from where you are]";

/// A Single-Goal instruction for a trip (see [`single_goal_kind`]); `None` when the goal cannot
/// be named uniquely. The start is where the agent stands, so it is left out where it cannot
/// be named uniquely or where naming it makes the sentence longer than
/// [`validate::MAX_WORDS`] (in a large building both ends need a room to tell them apart).
pub fn single_goal(
    tm: &TextMap,
    start: &EndRef,
    goal: &EndRef,
    rng: &mut impl Rng,
) -> Option<Instruction> {
    let kind = single_goal_kind(start.kind, goal.kind);
    let (s, g) = if kind == SingleGoalKind::ZoneToZone {
        (zone_phrase(tm, start), zone_phrase(tm, goal)?)
    } else {
        (end_phrase(tm, start), end_phrase(tm, goal)?)
    };
    let named = rng.random_bool(0.75) && s.is_some();
    let slots: BTreeMap<&str, String> = [("start", s.unwrap_or_default()), ("goal", g)].into();
    let mut text = expand(if named { FROM_TO } else { TO_ONLY }, &slots, rng)?;
    if named && tokens(&text).len() > validate::MAX_WORDS {
        text = expand(TO_ONLY, &slots, rng)?;
    }
    Some(Instruction {
        text,
        kind: InstructionType::SingleGoal,
        subtype: Some(kind),
        source: Source::Template,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rooms_have_an_index_and_regions_none() {
        assert_eq!(room_index("room_2"), Some(2));
        assert_eq!(room_index("region_0"), None);
        assert_eq!(room_index("room_x"), None);
    }
}
