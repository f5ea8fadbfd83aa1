//! Referring expressions that single out one object, room or area of a text map.
//!
//! A description is a small formula — category, optionally an attribute word, a place (a room
//! type, or one room said uniquely) and a relation to a landmark that is itself described
//! uniquely — and its text is rendered from exactly those parts. [`Description::matches`]
//! evaluates the formula over the text map; a description is used only when it matches its
//! target and nothing else. So "the chair" is said only when the scene has one chair, else "the
//! chair in the kitchen", "the red chair" or "the chair next to the dining table", whichever is
//! unique first (for [`Style::Any`]). Where rooms of a type repeat (large homes and offices),
//! a room is said by what sets it apart from the others of its type ([`room_phrase`]): "the
//! bedroom with the desk", "the bedroom with the red bed", "the bedroom next to the kitchen",
//! "the largest bedroom".

use crate::textmap::{RelKind, TextMap, TmRoom};
use crate::words;
use rand::Rng;
use rand::seq::IndexedRandom;

/// Which parts a description must use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// The simplest unique description.
    Any,
    /// One with a spatial relation.
    Relation,
    /// One with an attribute (colour, state, material, size).
    Attribute,
}

/// An attribute word and the field it comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AttrWord {
    /// `color`, `state`, `material` or `size`.
    pub field: &'static str,
    /// The raw value (`red`, `on`, `wood`).
    pub value: String,
    /// How it is said before the noun (`red`, `lit`, `wooden`).
    pub word: String,
}

/// Where a description places its object.
#[derive(Debug, Clone, PartialEq)]
pub enum Place {
    /// Any room of this type (`in the kitchen`).
    RoomType(String),
    /// One room (its index), said by its unique phrase (`in the largest bedroom`).
    Room(usize, String),
}

/// A description of an object (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Description {
    /// The category it names.
    pub category: String,
    /// An attribute, if any.
    pub attribute: Option<AttrWord>,
    /// Where it is (`in the kitchen`, `in the largest bedroom`), if said.
    pub place: Option<Place>,
    /// A relation to a uniquely described landmark object.
    pub relation: Option<(RelKind, usize, Box<Description>)>,
}

fn attr_words(tm: &TextMap, k: usize) -> Vec<AttrWord> {
    let o = &tm.objects[k];
    let a = &o.attributes;
    let mut out = Vec::new();
    let mut add = |field: &'static str, v: &Option<String>, word: fn(&str, &str) -> String| {
        if let Some(v) = v {
            out.push(AttrWord {
                field,
                value: v.clone(),
                word: word(v, &o.category),
            });
        }
    };
    add("color", &a.color, |v, _| v.to_string());
    add("state", &a.state, words::state_adjective);
    add("material", &a.material, |v, _| words::material_adjective(v));
    add("size", &a.size, |v, _| v.to_string());
    out
}

impl Description {
    /// True when object `k` of `tm` fits this description.
    pub fn matches(&self, tm: &TextMap, k: usize) -> bool {
        let o = &tm.objects[k];
        if o.category != self.category {
            return false;
        }
        if let Some(a) = &self.attribute
            && !attr_words(tm, k)
                .iter()
                .any(|w| w.field == a.field && w.value == a.value)
        {
            return false;
        }
        match &self.place {
            Some(Place::RoomType(rt))
                if o.room
                    .and_then(|r| tm.room(r))
                    .is_none_or(|r| &r.room_type != rt) =>
            {
                return false;
            }
            Some(Place::Room(index, _)) if o.room != Some(*index) => return false,
            _ => {}
        }
        if let Some((kind, landmark, _)) = &self.relation
            && !tm.holds(k, *kind, *landmark)
        {
            return false;
        }
        true
    }

    /// The objects of `tm` that fit.
    pub fn extension(&self, tm: &TextMap) -> Vec<usize> {
        (0..tm.objects.len())
            .filter(|&k| self.matches(tm, k))
            .collect()
    }

    /// The text, with its article (`the red chair in the kitchen`).
    pub fn render(&self) -> String {
        let mut s = String::from("the ");
        if let Some(a) = &self.attribute {
            s.push_str(&a.word);
            s.push(' ');
        }
        s.push_str(&words::noun(&self.category));
        if let Some((kind, _, landmark)) = &self.relation {
            s.push(' ');
            s.push_str(kind.phrase());
            s.push(' ');
            s.push_str(&landmark.render());
        }
        match &self.place {
            Some(Place::RoomType(rt)) => {
                s.push_str(" in the ");
                s.push_str(&words::room_name(rt));
            }
            Some(Place::Room(_, phrase)) => {
                s.push_str(" in ");
                s.push_str(phrase);
            }
            None => {}
        }
        s
    }

    /// True when the description uses a relation.
    pub fn has_relation(&self) -> bool {
        self.relation.is_some()
    }
}

/// Candidate descriptions of object `k`, simplest first, for `style`.
fn candidates(tm: &TextMap, k: usize, style: Style, depth: usize) -> Vec<Description> {
    let o = &tm.objects[k];
    let base = Description {
        category: o.category.clone(),
        attribute: None,
        place: None,
        relation: None,
    };
    // The room's type, then — when other rooms share it — the room itself by its phrase.
    let mut places = Vec::new();
    if let Some(room) = o.room.and_then(|r| tm.room(r)) {
        places.push(Place::RoomType(room.room_type.clone()));
        let repeated = tm
            .rooms
            .iter()
            .any(|r| r.room_type == room.room_type && r.index != room.index);
        if repeated && let Some(phrase) = room_phrase_except(tm, room.index, Some(k)) {
            places.push(Place::Room(room.index, phrase));
        }
    }
    let mut out = Vec::new();
    let push_pair = |out: &mut Vec<Description>, d: Description| {
        let placed: Vec<Description> = places
            .iter()
            .map(|p| Description {
                place: Some(p.clone()),
                ..d.clone()
            })
            .collect();
        out.push(d);
        out.extend(placed);
    };
    if style == Style::Any {
        push_pair(&mut out, base.clone());
    }
    if style != Style::Relation {
        for a in attr_words(tm, k) {
            push_pair(
                &mut out,
                Description {
                    attribute: Some(a),
                    ..base.clone()
                },
            );
        }
    }
    if style != Style::Attribute && depth == 0 {
        for r in tm.relations.iter().filter(|r| r.subject == k) {
            if let Some(landmark) = describe_at(tm, r.object, Style::Any, 1) {
                // A landmark already placed in a room places the pair: no second "in the …".
                let placed = landmark.place.is_some();
                let d = Description {
                    relation: Some((r.kind, r.object, Box::new(landmark))),
                    ..base.clone()
                };
                if placed {
                    out.push(d);
                } else {
                    push_pair(&mut out, d);
                }
            }
        }
    }
    out
}

fn describe_at(tm: &TextMap, k: usize, style: Style, depth: usize) -> Option<Description> {
    let mut all = candidates(tm, k, style, depth);
    // Simplest first: the fewest words (stable, so ties keep the candidates' order).
    all.sort_by_key(|d| d.render().split_whitespace().count());
    all.into_iter().find(|d| d.extension(tm) == [k])
}

/// The simplest unique description of object `k` in `style` (deterministic), if there is one.
pub fn describe(tm: &TextMap, k: usize, style: Style) -> Option<Description> {
    describe_at(tm, k, style, 0)
}

/// A random unique description of object `k` in `style`, if there is one: every unique
/// candidate is equally likely (for phrasing variety).
pub fn describe_random(
    tm: &TextMap,
    k: usize,
    style: Style,
    rng: &mut impl Rng,
) -> Option<Description> {
    let unique: Vec<Description> = candidates(tm, k, style, 0)
        .into_iter()
        .filter(|d| d.extension(tm) == [k])
        .collect();
    unique.choose(rng).cloned()
}

/// A room is "the largest" or "the smallest" of its type only when it is this much larger or
/// smaller than every other (so that a person walking through would see it).
const SIZE_MARGIN: f32 = 1.15;

/// How to say room `index` uniquely: `the kitchen` when its type is unique, else by what sets
/// it apart from the other rooms of its type, first that works of: a category only it holds
/// (`the bedroom with the desk`), an attribute of a category only it holds (`the bedroom with
/// the red bed`), a neighbour of a unique type next to it alone (`the bedroom next to the
/// kitchen`), its size (`the largest bedroom`); `None` when nothing does.
pub fn room_phrase(tm: &TextMap, index: usize) -> Option<String> {
    room_phrase_except(tm, index, None)
}

/// [`room_phrase`] without leaning on object `except` (so an object is never placed by itself:
/// not "the white cup in the meeting room with the white cup").
fn room_phrase_except(tm: &TextMap, index: usize, except: Option<usize>) -> Option<String> {
    let room = tm.room(index)?;
    let same: Vec<&TmRoom> = tm
        .rooms
        .iter()
        .filter(|r| r.room_type == room.room_type && r.index != index)
        .collect();
    if same.is_empty() {
        return Some(format!("the {}", room.name));
    }
    let in_room = |k: usize, r: usize| tm.objects[k].room == Some(r) && tm.objects[k].relatable;
    let held: Vec<usize> = (0..tm.objects.len())
        .filter(|&k| in_room(k, index) && Some(k) != except)
        .collect();
    let elsewhere = |pred: &dyn Fn(usize) -> bool| {
        (0..tm.objects.len()).any(|k| same.iter().any(|r| in_room(k, r.index)) && pred(k))
    };
    let mut by_category: Vec<&str> = held
        .iter()
        .map(|&k| tm.objects[k].category.as_str())
        .collect();
    by_category.sort_unstable();
    by_category.dedup();
    if let Some(c) = by_category
        .into_iter()
        .find(|c| !elsewhere(&|k| tm.objects[k].category == *c))
    {
        return Some(format!("the {} with the {}", room.name, words::noun(c)));
    }
    for &k in &held {
        let category = &tm.objects[k].category;
        for a in attr_words(tm, k) {
            let shared = |j: usize| {
                &tm.objects[j].category == category
                    && attr_words(tm, j)
                        .iter()
                        .any(|b| b.field == a.field && b.value == a.value)
            };
            let twice = held.iter().filter(|&&j| shared(j)).count() > 1;
            if !twice && !elsewhere(&shared) {
                return Some(format!(
                    "the {} with the {} {}",
                    room.name,
                    a.word,
                    words::noun(category)
                ));
            }
        }
    }
    let unique_type = |r: &TmRoom| {
        !tm.rooms
            .iter()
            .any(|o| o.room_type == r.room_type && o.index != r.index)
    };
    for &n in &room.neighbours {
        let Some(neighbour) = tm.room(n) else {
            continue;
        };
        if unique_type(neighbour) && !same.iter().any(|r| r.neighbours.contains(&n)) {
            return Some(format!("the {} next to the {}", room.name, neighbour.name));
        }
    }
    if same.iter().all(|r| room.area_m2 >= r.area_m2 * SIZE_MARGIN) {
        return Some(format!("the largest {}", room.name));
    }
    if same.iter().all(|r| room.area_m2 * SIZE_MARGIN <= r.area_m2) {
        return Some(format!("the smallest {}", room.name));
    }
    None
}

/// How to say area `id`: `the dining area` when its name is unique, else `the dining area in
/// the kitchen` (or in its room's unique phrase) when no area of that name shares its room;
/// `None` otherwise.
pub fn area_phrase(tm: &TextMap, id: &str) -> Option<String> {
    let area = tm.area(id)?;
    let same: Vec<_> = tm
        .areas
        .iter()
        .filter(|a| a.name == area.name && a.id != area.id)
        .collect();
    if same.is_empty() {
        return Some(format!("the {}", area.name));
    }
    let room = area.room?;
    if same.iter().any(|a| a.room == Some(room)) {
        return None;
    }
    let rt = &tm.room(room)?.room_type;
    let type_clash = same.iter().any(|a| {
        a.room
            .and_then(|r| tm.room(r))
            .is_some_and(|r| &r.room_type == rt)
    });
    let where_ = if type_clash {
        room_phrase(tm, room)?
    } else {
        format!("the {}", tm.room(room)?.name)
    };
    Some(format!("the {} in {where_}", area.name))
}
