//! High-level instructions from an offline grammar grounded in the text map (SPEC §8): the five
//! types of the paper, each from a handful of templates with varied verbs and frames, filled
//! with unique referring expressions of the trip's start and goal.
//!
//! - **Add_Object**: the thing to carry is a small object standing *on* the start object when
//!   the text map has one ("the cup on the coffee table"), else an everyday item fitting the goal
//!   (groceries for a fridge, dishes for a sink) that is not an object noun of the map.
//! - **Scenario_Driven**: a first-person need fitting the goal's category, area or room ("I'm
//!   thirsty" → fridge), else a generic "I left my phone by …".
//! - **Relative_Relationship**: the goal object described by a relation to a landmark.
//! - **Attribute-based**: the goal object described by an attribute.
//! - **Area-based**: the goal area, the area its goal object belongs to, or "the kitchen area".
//!
//! A type that does not fit a trip (no relation singles out the goal, …) yields `None`.

use crate::grammar::{expand, fill};
use crate::instruction::{Instruction, InstructionType, Source};
use crate::lowlevel::{end_phrase, room_index};
use crate::refexp::{self, Style};
use crate::textmap::{RelKind, TextMap};
use crate::words;
use rand::Rng;
use rand::seq::IndexedRandom;
use sage_nav::EndpointKind;
use sage_nav::trajectory::EndRef;
use std::collections::BTreeMap;

/// Things to carry to a goal, by a word of the goal's category, area or room name (singular,
/// so "it" can refer back to them).
const CARRY: &[(&str, &[&str])] = &[
    (
        "refrigerator",
        &["the grocery bag", "the milk", "this bowl of leftovers"],
    ),
    ("fridge", &["the grocery bag", "the milk"]),
    ("sink", &["the dirty pot", "this mug"]),
    ("stove", &["the pot", "the frying pan"]),
    ("kitchen", &["the grocery bag", "the dirty pot"]),
    ("cooking", &["the frying pan", "the pot"]),
    ("bed", &["the clean sheet", "this blanket", "the pillow"]),
    ("sleeping", &["the clean sheet", "this blanket"]),
    ("bookshelf", &["this novel", "the magazine"]),
    ("desk", &["the folder", "this notebook", "the charger"]),
    ("work", &["the folder", "this notebook"]),
    ("table", &["the fruit bowl", "this plate", "the mail"]),
    ("dining", &["the salad bowl", "this plate"]),
    (
        "sofa",
        &["this cushion", "the remote control", "the blanket"],
    ),
    ("lounge", &["this cushion", "the remote control"]),
    ("bathtub", &["the towel", "the soap"]),
    ("bath", &["the towel", "the shampoo"]),
    ("toilet", &["a roll of paper", "the towel"]),
    ("wardrobe", &["the ironed shirt", "this coat"]),
    ("dresser", &["the folded sweater", "this scarf"]),
    ("counter", &["the receipt", "this parcel"]),
    ("reception", &["the visitor badge", "this parcel"]),
    ("meeting", &["the projector remote", "the marker"]),
    ("checkout", &["the receipt", "this basket"]),
];
/// Things to carry anywhere.
const CARRY_ANY: &[&str] = &["this bag", "the package", "the umbrella", "this basket"];

/// Needs that make a goal reasonable, by a word of its category, area or room name.
const NEEDS: &[(&str, &[&str])] = &[
    (
        "refrigerator",
        &[
            "I'm thirsty, [get me a drink from|grab something cold from]",
            "I'm hungry, [find a snack in|check]",
        ],
    ),
    (
        "fridge",
        &["I'm thirsty, [get me a drink from|grab something cold from]"],
    ),
    (
        "sink",
        &[
            "My hands are dirty, [take me to|go to]",
            "I need to wash these dishes, [head to|go to]",
        ],
    ),
    (
        "stove",
        &[
            "I want to cook dinner, [head to|go to]",
            "My soup needs heating, [go to|head over to]",
        ],
    ),
    (
        "kitchen",
        &[
            "I'm hungry, [go to|head to]",
            "I want to make some tea, [go to|head to]",
        ],
    ),
    ("cooking", &["I want to cook dinner, [head to|go to]"]),
    (
        "sofa",
        &[
            "I want to rest for a while, [take me to|go to]",
            "I'd like to sit and relax, [head to|go to]",
        ],
    ),
    (
        "lounge",
        &["I want to relax for a bit, [take me to|head to]"],
    ),
    (
        "bed",
        &[
            "I'm exhausted and need sleep, [take me to|go to]",
            "I want a quick nap, [head to|go to]",
        ],
    ),
    (
        "sleeping",
        &["I'm exhausted and need sleep, [take me to|go to]"],
    ),
    (
        "desk",
        &[
            "I need to finish some work, [go to|head to]",
            "I have to answer emails, [go to|head to]",
        ],
    ),
    ("work", &["I need to finish some work, [go to|head to]"]),
    ("bookshelf", &["I want something to read, [go to|check]"]),
    ("tv", &["I want to watch the news, [go to|head to]"]),
    (
        "dining",
        &[
            "Our dinner is almost ready, [go to|head to]",
            "We're about to eat, [go to|head to]",
        ],
    ),
    ("toilet", &["I need the restroom, [take me to|go to]"]),
    ("bathtub", &["I'd like a warm bath, [go to|head to]"]),
    ("bath", &["I'd like a warm bath, [go to|head to]"]),
    ("wardrobe", &["I need a clean shirt, [go to|check]"]),
    ("mirror", &["I want to check my hair, [go to|head to]"]),
    (
        "chair",
        &["My feet hurt and I need to sit, [go to|head to]"],
    ),
    ("reception", &["I'm expecting a visitor, [go to|head to]"]),
    ("meeting", &["Our meeting starts soon, [go to|head to]"]),
    ("checkout", &["I'm ready to pay, [go to|head to]"]),
    ("counter", &["I'm ready to pay, [go to|head to]"]),
];
/// Needs that fit any goal (`{at}`: `in` for rooms, else `by` / `near`).
const NEEDS_ANY: &[&str] = &[
    "I think I left my phone {at}",
    "I may have dropped my keys {at}",
];

/// The words a goal is known by: its category words, area name words or room name words.
fn goal_words(tm: &TextMap, goal: &EndRef) -> Vec<String> {
    let name = match goal.kind {
        EndpointKind::Object => goal.label.clone(),
        EndpointKind::Area => goal.label.clone(),
        EndpointKind::Room => room_index(&goal.reference)
            .and_then(|i| tm.room(i))
            .map_or_else(String::new, |r| r.name.clone()),
    };
    words::tokens(&name.replace('_', " "))
}

fn lookup<'a>(table: &'a [(&str, &'a [&'a str])], keys: &[String]) -> Vec<&'a str> {
    table
        .iter()
        .filter(|(k, _)| keys.iter().any(|w| w == k))
        .flat_map(|(_, v)| v.iter().copied())
        .collect()
}

/// The goal phrase in the style a type needs.
fn goal_phrase(tm: &TextMap, goal: &EndRef, style: Style, rng: &mut impl Rng) -> Option<String> {
    if goal.kind == EndpointKind::Object && style != Style::Any {
        let k = tm.object_index(&goal.reference)?;
        return Some(refexp::describe_random(tm, k, style, rng)?.render());
    }
    if style != Style::Any {
        return None;
    }
    end_phrase(tm, goal)
}

/// The area phrase of a trip's goal (see the module docs).
fn area_goal(tm: &TextMap, goal: &EndRef) -> Option<String> {
    match goal.kind {
        EndpointKind::Area => refexp::area_phrase(tm, &goal.reference),
        EndpointKind::Room => {
            let p = refexp::room_phrase(tm, room_index(&goal.reference)?)?;
            // "the bedroom with the desk area" would not parse as one place.
            (!p.contains(" with ") && !p.contains(" next to ")).then(|| format!("{p} area"))
        }
        EndpointKind::Object => {
            let area = tm
                .areas
                .iter()
                .find(|a| a.members.contains(&goal.reference))?;
            refexp::area_phrase(tm, &area.id)
        }
    }
}

/// A high-level instruction of type `kind` for a trip; `None` when the type does not fit it.
pub fn generate(
    tm: &TextMap,
    start: &EndRef,
    goal: &EndRef,
    kind: InstructionType,
    rng: &mut impl Rng,
) -> Option<Instruction> {
    let mut slots: BTreeMap<&str, String> = BTreeMap::new();
    slots.insert("start", end_phrase(tm, start)?);
    let keys = goal_words(tm, goal);
    let template: &str = match kind {
        InstructionType::AddObject => {
            let on_start = tm
                .object_index(&start.reference)
                .filter(|_| start.kind == EndpointKind::Object)
                .and_then(|s| {
                    tm.relations
                        .iter()
                        .find(|r| r.kind == RelKind::On && r.object == s)
                        .map(|r| format!("the {}", tm.objects[r.subject].noun))
                });
            let thing = match on_start {
                Some(t) => t,
                None => {
                    let mut options = lookup(CARRY, &keys);
                    if options.is_empty() {
                        options = CARRY_ANY.to_vec();
                    }
                    options.choose(rng)?.to_string()
                }
            };
            slots.insert("thing", thing);
            slots.insert("goal", goal_phrase(tm, goal, Style::Any, rng)?);
            "[[Please |Could you ][take|bring|carry|move] {thing} from {start} to {goal}|Pick up {thing} [at|from] {start} and [put|leave] it [by|at] {goal}|Grab {thing} [at|from] {start} and [bring|deliver] it to {goal}]"
        }
        InstructionType::ScenarioDriven => {
            let mut needs = lookup(NEEDS, &keys);
            if needs.is_empty() || rng.random_bool(0.15) {
                needs = NEEDS_ANY.to_vec();
            }
            let at = if goal.kind == EndpointKind::Room {
                "in"
            } else {
                "[by|near]"
            };
            let at_slot: BTreeMap<&str, String> = [("at", fill(at, &BTreeMap::new(), rng)?)].into();
            let need = fill(needs.choose(rng)?, &at_slot, rng)?;
            slots.insert("need", need);
            slots.insert("goal", goal_phrase(tm, goal, Style::Any, rng)?);
            if needs == NEEDS_ANY {
                "{need} {goal}[, please go and check|; could you look there|, please go there]"
            } else {
                "[{need} {goal}|{need} {goal}, please]"
            }
        }
        InstructionType::RelativeRelationship => {
            slots.insert("goal", goal_phrase(tm, goal, Style::Relation, rng)?);
            "[[Move|Walk|Go] to {goal}|Find {goal} and stop there|Head over to {goal}|Go from {start} to {goal}]"
        }
        InstructionType::AttributeBased => {
            slots.insert("goal", goal_phrase(tm, goal, Style::Attribute, rng)?);
            "[Find {goal} and stop beside it|Go over to {goal}|Walk from {start} to {goal}|Look for {goal} and go there]"
        }
        InstructionType::AreaBased => {
            slots.insert("goal", area_goal(tm, goal)?);
            "[Walk from here to {goal}|Head over to {goal}, please|Make your way to {goal}|Go from {start} to {goal}|Take me to {goal}, please]"
        }
        _ => return None,
    };
    Some(Instruction {
        text: expand(template, &slots, rng)?,
        kind,
        subtype: None,
        source: Source::Grammar,
    })
}
