//! Furnishing: each room gets its share of the object target, filled from its plan by rejection
//! sampling. A candidate is kept only when its box lies inside the room's walls and overlaps no
//! other object, no door leaf and no clearance zone in front of a door or window.

use crate::catalog::{self, Entry, Mount, Shape, Spec};
use crate::furniture;
use crate::item::Item;
use crate::layout::{Layout, Opening, Rect};
use crate::look::{Look, Material};
use crate::{pick, uniform};
use glam::{Vec2, Vec3};
use rand::seq::IndexedRandom;
use rand::{Rng, RngCore};
use sage_core::Obb;
use sage_scene::floorplan::HoleKind;
use sage_scene::object::{Attributes, RigidBody};
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// Candidates tried per object before giving up on it.
const ATTEMPTS: usize = 80;
/// Failed fillers in a row after which a room counts as full.
const FILLER_FAILURES: usize = 30;
/// Depth of the clear zone kept on both sides of a door, from the wall face (m; at least the
/// door's width, so that its leaf can always swing open).
const DOOR_CLEARANCE: f32 = 0.9;
/// Depth of the clear zone kept in front of a window (m) …
const WINDOW_CLEARANCE: f32 = 0.35;
/// … from this far above its sill (a bed's headboard may sit under it) to its top (m).
const WINDOW_CLEAR_FROM: f32 = 0.3;
/// Gap between a wall and what stands or hangs against it (m): more than the margin within which
/// a Gaussian counts as an object's, so the wall behind stays the wall's.
const WALL_GAP: f32 = 0.02;
/// Smallest gap between two pieces of furniture (m).
const GAP: f32 = 0.02;
/// The look of a category without looks (the catalogue has none such; see its tests).
const FALLBACK_LOOK: (Material, &[&str]) = (Material::Plastic, &["gray"]);

/// The box of a room (or any rectangle) from the floor to `height`.
fn rect_box(r: Rect, height: f32) -> Obb {
    let c = r.center();
    Obb {
        center: Vec3::new(c.x, c.y, height * 0.5),
        half_extents: (r.size() * 0.5).extend(height * 0.5),
        yaw: 0.0,
    }
}

/// The zone kept clear in front of an opening, on both sides of its wall.
fn clearance(o: &Opening, height: f32) -> Obb {
    let (depth, z0, z1) = match o.kind {
        HoleKind::Door => (DOOR_CLEARANCE.max(o.width()), 0.0, height),
        HoleKind::Window => (WINDOW_CLEARANCE, o.z[0] + WINDOW_CLEAR_FROM, o.z[1] + 0.05),
    };
    let c = o.center();
    Obb {
        center: Vec3::new(c.x, c.y, 0.5 * (z0 + z1)),
        half_extents: Vec3::new(
            o.width() * 0.5 + 0.1,
            o.thickness * 0.5 + depth,
            0.5 * (z1 - z0),
        ),
        yaw: o.axis.yaw(),
    }
}

/// Furnishes every room, about `target` objects in all, shared out by floor area (what a full room
/// cannot take passes on to the next). `fixed` holds what is already there (door leaves, windows).
pub(crate) fn furnish(
    layout: &Layout,
    fixed: &[Item],
    target: usize,
    rng: &mut impl RngCore,
) -> Vec<Item> {
    let total: f32 = layout.rooms.iter().map(|r| r.rect.area()).sum();
    let mut acc = 0.0f64;
    let mut given = 0usize;
    let mut items = Vec::new();
    for room in &layout.rooms {
        acc += f64::from(room.rect.area() / total.max(1e-6)) * target as f64;
        let quota = (acc.round() as usize).saturating_sub(given);
        let room_box = rect_box(room.rect, layout.height);
        let blockers = layout
            .openings
            .iter()
            .map(|o| clearance(o, layout.height))
            .chain(fixed.iter().map(|i| i.obb))
            .filter(|b| b.overlaps(&room_box, 0.0))
            .collect();
        let mut state = RoomState {
            inner: room.inner,
            height: layout.height,
            blockers,
            placed: Vec::new(),
        };
        state.fill(catalog::plan(room.kind), quota, rng);
        given += state.placed.len();
        items.extend(state.placed);
    }
    items
}

/// A room being furnished.
struct RoomState {
    /// Floor between the wall faces.
    inner: Rect,
    /// Ceiling height.
    height: f32,
    /// Boxes nothing may overlap besides the placed objects.
    blockers: Vec<Obb>,
    /// Objects placed so far.
    placed: Vec<Item>,
}

impl RoomState {
    /// Places the plan's main entries in order, then fillers, up to `quota` objects.
    fn fill(&mut self, plan: &catalog::Plan, quota: usize, rng: &mut impl RngCore) {
        for entry in plan.main {
            let count = rng.random_range(entry.count.0..=entry.count.1);
            for _ in 0..count {
                if self.placed.len() >= quota {
                    return;
                }
                self.try_place(entry, rng);
            }
        }
        let mut failures = 0;
        while self.placed.len() < quota && failures < FILLER_FAILURES {
            let Some(entry) = plan.fillers.choose(rng) else {
                return;
            };
            let held = self
                .placed
                .iter()
                .filter(|i| i.label == entry.spec.label)
                .count();
            if held < usize::from(entry.count.1) && self.try_place(entry, rng) {
                failures = 0;
            } else {
                failures += 1;
            }
        }
    }

    /// Tries to place one object of `entry`; true on success.
    fn try_place(&mut self, entry: &Entry, rng: &mut impl RngCore) -> bool {
        let spec = entry.spec;
        for _ in 0..ATTEMPTS {
            let t = rng.random::<f32>();
            let size = Vec3::from_array(std::array::from_fn(|k| {
                let f = (t + uniform(rng, -0.15, 0.15)).clamp(0.0, 1.0);
                spec.min[k] + f * (spec.max[k] - spec.min[k])
            }));
            let Some((origin, yaw, support)) = self.pose(entry.mount, spec, size, rng) else {
                continue;
            };
            let nominal = Obb {
                center: origin + Vec3::Z * size.z * 0.5,
                half_extents: size * 0.5,
                yaw,
            };
            if self.fits(&nominal, spec, support) {
                let item = self.make(spec, size, t, origin, yaw, rng);
                self.placed.push(item);
                return true;
            }
        }
        false
    }

    /// True when `b` is inside the room, clear of everything, spaced from its kind, and (for an
    /// object standing on `support`) within the support's top.
    fn fits(&self, b: &Obb, spec: &Spec, support: Option<usize>) -> bool {
        let room = self.inner.shrink(WALL_GAP - 0.005);
        if !b.footprint().iter().all(|&p| room.contains(p)) || b.max_z() > self.height + 1e-4 {
            return false;
        }
        if let Some(s) = support {
            let top = &self.placed[s].obb;
            let inside = b.footprint().iter().all(|&p| {
                let l = top.to_local(p.extend(top.center.z)).truncate().abs();
                l.cmple(top.half_extents.truncate() - Vec2::splat(0.005))
                    .all()
            });
            if !inside {
                return false;
            }
        }
        let gap = if support.is_some() { 0.0 } else { GAP };
        let clear = self
            .blockers
            .iter()
            .chain(self.placed.iter().map(|i| &i.obb))
            .all(|o| !b.overlaps(o, gap));
        let spaced = spec.spacing <= 0.0
            || self
                .placed
                .iter()
                .filter(|i| i.label == spec.label)
                .all(|i| i.obb.center.truncate().distance(b.center.truncate()) >= spec.spacing);
        clear && spaced
    }

    /// A candidate bottom-centre and heading for `mount`, and the support it stands on.
    fn pose(
        &self,
        mount: Mount,
        spec: &Spec,
        s: Vec3,
        rng: &mut impl RngCore,
    ) -> Option<(Vec3, f32, Option<usize>)> {
        let r = self.inner;
        let on_floor = |(p, yaw): (Vec2, f32)| (p.extend(0.0), yaw, None);
        match mount {
            Mount::Wall => wall_pose(r, s, rng).map(on_floor),
            Mount::Hung(lo, hi) => {
                let z = uniform(rng, lo, hi).min(self.height - 0.05 - s.z);
                wall_pose(r, s, rng).map(|(p, yaw)| (p.extend(z), yaw, None))
            }
            Mount::Free => Some(on_floor(free_pose(r, s, rng))),
            Mount::Center => {
                let along = if r.size().x >= r.size().y {
                    0.0
                } else {
                    FRAC_PI_2
                };
                let yaw = along + PI * rng.random_range(0..2) as f32;
                Some(on_floor((near_center(r, 0.15, rng), yaw)))
            }
            Mount::Ceiling => {
                let yaw = FRAC_PI_2 * rng.random_range(0..4) as f32;
                Some((
                    near_center(r, 0.35, rng).extend(self.height - s.z),
                    yaw,
                    None,
                ))
            }
            Mount::Around(label) => {
                let t = &self.placed[self.target(&[label], rng)?].obb;
                around_pose(t, s, rng).map(on_floor)
            }
            Mount::Front(label, g0, g1) => {
                let t = &self.placed[self.target(&[label], rng)?].obb;
                let (ax, ay) = t.axes();
                let slide = (t.half_extents.x - s.x * 0.5).clamp(0.0, 0.1);
                let p = t.center.truncate()
                    + ay * (t.half_extents.y + s.y * 0.5 + uniform(rng, g0, g1))
                    + ax * uniform(rng, -slide, slide);
                Some(on_floor((p, t.yaw + PI)))
            }
            Mount::Beside(label) => {
                let t = &self.placed[self.target(&[label], rng)?].obb;
                let (ax, ay) = t.axes();
                let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let p = t.center.truncate()
                    + ax * side * (t.half_extents.x + s.x * 0.5 + uniform(rng, 0.02, 0.08))
                    - ay * (t.half_extents.y - s.y * 0.5);
                Some(on_floor((p, t.yaw)))
            }
            Mount::On(labels) => {
                let index = self.target(labels, rng)?;
                let t = &self.placed[index].obb;
                let (p, yaw) = on_pose(t, spec.shape, s, rng)?;
                Some((p.extend(t.max_z()), yaw, Some(index)))
            }
        }
    }

    /// A random placed object with one of `labels`.
    fn target(&self, labels: &[&str], rng: &mut impl RngCore) -> Option<usize> {
        let found: Vec<usize> = (0..self.placed.len())
            .filter(|&i| labels.contains(&self.placed[i].label))
            .collect();
        found.choose(rng).copied()
    }

    /// Builds the object: look, state, mesh, attributes and physics from the size parameter `t`.
    fn make(
        &self,
        spec: &Spec,
        size: Vec3,
        t: f32,
        origin: Vec3,
        yaw: f32,
        rng: &mut impl RngCore,
    ) -> Item {
        let (material, colors) = spec.looks.choose(rng).copied().unwrap_or(FALLBACK_LOOK);
        let color = pick(rng, colors);
        let main = Look::named(color, material, rng.next_u32());
        let state = spec.states.choose(rng).copied();
        let parts = furniture::build(spec.shape, size, main, state, rng);
        let attributes = Attributes {
            color: Some(color.to_string()),
            material: Some(material.name().to_string()),
            state: state.map(str::to_string),
            size: Some(
                if t < 1.0 / 3.0 {
                    "small"
                } else if t < 2.0 / 3.0 {
                    "medium"
                } else {
                    "large"
                }
                .to_string(),
            ),
        };
        let rigid_body = RigidBody {
            mass: spec.mass[0] + t * (spec.mass[1] - spec.mass[0]),
            friction: material.friction(),
            restitution: material.restitution(),
        };
        Item::place(
            spec.label, parts, origin, yaw, attributes, spec.role, rigid_body,
        )
    }
}

/// A spot with the back against one of the room's walls (chosen by length), facing into the room;
/// a third of the time pushed into a corner.
fn wall_pose(r: Rect, s: Vec3, rng: &mut impl RngCore) -> Option<(Vec2, f32)> {
    let size = r.size();
    let side = if rng.random::<f32>() * (size.x + size.y) < size.x {
        0
    } else {
        2
    } + rng.random_range(0..2);
    let (lo, hi) = if side < 2 {
        (r.min.x, r.max.x)
    } else {
        (r.min.y, r.max.y)
    };
    let (a, b) = (lo + s.x * 0.5 + WALL_GAP, hi - s.x * 0.5 - WALL_GAP);
    if a > b {
        return None;
    }
    let along = match rng.random_range(0..6) {
        0 => a,
        1 => b,
        _ => uniform(rng, a, b),
    };
    let off = s.y * 0.5 + WALL_GAP;
    Some(match side {
        0 => (Vec2::new(along, r.min.y + off), 0.0),
        1 => (Vec2::new(along, r.max.y - off), PI),
        2 => (Vec2::new(r.min.x + off, along), -FRAC_PI_2),
        _ => (Vec2::new(r.max.x - off, along), FRAC_PI_2),
    })
}

/// A spot away from the walls with a mostly square heading.
fn free_pose(r: Rect, s: Vec3, rng: &mut impl RngCore) -> (Vec2, f32) {
    let margin = s.x.max(s.y) * 0.5 + 0.4;
    let area = if r.size().min_element() > 2.0 * margin {
        r.shrink(margin)
    } else {
        r.shrink(s.x.max(s.y) * 0.5)
    };
    let p = Vec2::new(
        uniform(rng, area.min.x, area.max.x),
        uniform(rng, area.min.y, area.max.y),
    );
    let yaw = if rng.random_bool(0.75) {
        FRAC_PI_2 * rng.random_range(0..4) as f32 + uniform(rng, -0.25, 0.25)
    } else {
        uniform(rng, 0.0, TAU)
    };
    (p, yaw)
}

/// A point within `spread` of the room's size from its centre.
fn near_center(r: Rect, spread: f32, rng: &mut impl RngCore) -> Vec2 {
    let size = r.size();
    r.center()
        + Vec2::new(
            uniform(rng, -spread, spread) * size.x,
            uniform(rng, -spread, spread) * size.y,
        )
}

/// A spot on the top of support `t`: screens and appliances face the support's front, small
/// items lie at any angle.
fn on_pose(t: &Obb, shape: Shape, s: Vec3, rng: &mut impl RngCore) -> Option<(Vec2, f32)> {
    let (ax, ay) = t.axes();
    let aligned = matches!(
        shape,
        Shape::Screen | Shape::Laptop | Shape::Microwave | Shape::Register
    );
    let (yaw, reach) = if aligned {
        let reach = Vec2::new(t.half_extents.x - s.x * 0.5, t.half_extents.y - s.y * 0.5);
        (t.yaw, reach)
    } else {
        let yaw = t.yaw + FRAC_PI_2 * rng.random_range(0..4) as f32 + uniform(rng, -0.4, 0.4);
        (
            yaw,
            t.half_extents.truncate() - Vec2::splat(s.x.min(s.y) * 0.5),
        )
    };
    if reach.min_element() < 0.0 {
        return None;
    }
    let p = t.center.truncate()
        + ax * uniform(rng, -reach.x, reach.x)
        + ay * uniform(rng, -reach.y, reach.y);
    Some((p, yaw))
}

/// A spot at one of the four sides of table `t`, facing it.
fn around_pose(t: &Obb, s: Vec3, rng: &mut impl RngCore) -> Option<(Vec2, f32)> {
    let (ax, ay) = t.axes();
    let he = t.half_extents;
    let c = t.center.truncate();
    let gap = uniform(rng, 0.02, 0.12);
    let side = rng.random_range(0..4);
    let (along, across, reach, depth, yaw) = match side {
        0 => (ax, ay, he.x, he.y, t.yaw + PI),
        1 => (ax, -ay, he.x, he.y, t.yaw),
        2 => (ay, ax, he.y, he.x, t.yaw + FRAC_PI_2),
        _ => (ay, -ax, he.y, he.x, t.yaw - FRAC_PI_2),
    };
    let slide = reach - s.x * 0.5;
    if slide < 0.0 {
        return None;
    }
    Some((
        c + along * uniform(rng, -slide, slide) + across * (depth + s.y * 0.5 + gap),
        yaw,
    ))
}
