//! Referring expressions that single out one object, room or area of a text map.
//!
//! A description is a small formula — category, optionally an attribute word, a room type and a
//! relation to a landmark that is itself described uniquely — and its text is rendered from
//! exactly those parts. [`Description::matches`] evaluates the formula over the text map; a
//! description is used only when it matches its target and nothing else. So "the chair" is said
//! only when the scene has one chair, else "the chair in the kitchen", "the red chair" or "the
//! chair next to the dining table", whichever is unique first (for [`Style::Any`]).

use crate::textmap::{RelKind, TextMap};
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

/// A description of an object (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Description {
    /// The category it names.
    pub category: String,
    /// An attribute, if any.
    pub attribute: Option<AttrWord>,
    /// A room type (`in the kitchen`), if any.
    pub room_type: Option<String>,
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
        if let Some(rt) = &self.room_type
            && o.room
                .and_then(|r| tm.room(r))
                .is_none_or(|r| &r.room_type != rt)
        {
            return false;
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
        if let Some(rt) = &self.room_type {
            s.push_str(" in the ");
            s.push_str(&words::room_name(rt));
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
        room_type: None,
        relation: None,
    };
    let room_type = o.room.and_then(|r| tm.room(r)).map(|r| r.room_type.clone());
    let with_room = |d: &Description| -> Option<Description> {
        room_type.as_ref().map(|rt| Description {
            room_type: Some(rt.clone()),
            ..d.clone()
        })
    };
    let mut out = Vec::new();
    let push_pair = |out: &mut Vec<Description>, d: Description| {
        let r = with_room(&d);
        out.push(d);
        out.extend(r);
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
                let placed = landmark.room_type.is_some();
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
    candidates(tm, k, style, depth)
        .into_iter()
        .find(|d| d.extension(tm) == [k])
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

/// How to say room `index`: `the kitchen` when its type is unique, else `the bedroom with the
/// desk` (a category found in it and in no other room of its type); `None` when neither works.
pub fn room_phrase(tm: &TextMap, index: usize) -> Option<String> {
    let room = tm.room(index)?;
    let same: Vec<usize> = tm
        .rooms
        .iter()
        .filter(|r| r.room_type == room.room_type && r.index != index)
        .map(|r| r.index)
        .collect();
    if same.is_empty() {
        return Some(format!("the {}", room.name));
    }
    let mut cats: Vec<&str> = tm
        .objects
        .iter()
        .filter(|o| o.room == Some(index) && o.relatable)
        .map(|o| o.category.as_str())
        .collect();
    cats.sort_unstable();
    cats.dedup();
    cats.into_iter()
        .find(|c| {
            !tm.objects
                .iter()
                .any(|o| o.category == *c && o.room.is_some_and(|r| same.contains(&r)))
        })
        .map(|c| format!("the {} with the {}", room.name, words::noun(c)))
}

/// How to say area `id`: `the dining area` when its name is unique, else `the dining area in the
/// kitchen` when that is; `None` otherwise.
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
    let rt = area.room.and_then(|r| tm.room(r))?;
    let clash = same.iter().any(|a| {
        a.room
            .and_then(|r| tm.room(r))
            .is_some_and(|r| r.room_type == rt.room_type)
    });
    (!clash).then(|| format!("the {} in the {}", area.name, rt.name))
}
