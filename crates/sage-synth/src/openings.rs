//! The objects that fill wall openings: a door leaf swung about its hinge by the door's state, and
//! a window frame with glass.

use crate::furniture::frame;
use crate::item::Item;
use crate::layout::{Layout, Opening};
use crate::look::{Look, Material};
use crate::shapes::{Part, cuboid};
use crate::{pick, uniform};
use glam::Vec3;
use rand::RngCore;
use sage_scene::floorplan::HoleKind;
use sage_scene::object::{Attributes, DoorState, PhysicsRole, RigidBody};

/// Thickness of a door leaf (m).
const LEAF: f32 = 0.04;
/// Gap between a door leaf and each jamb and the lintel (m): more than the margin within which a Gaussian counts
/// as an object's, so the opening's faces stay the wall's.
const JAMB_GAP: f32 = 0.02;
/// Depth of a window frame (m).
const WINDOW_FRAME: f32 = 0.07;

/// One object per opening, in opening order: door leaves and windows.
pub(crate) fn build(layout: &Layout, rng: &mut impl RngCore) -> Vec<Item> {
    layout
        .openings
        .iter()
        .map(|o| match o.kind {
            HoleKind::Door => door_leaf(o, rng),
            HoleKind::Window => window(o, rng),
        })
        .collect()
}

/// A door leaf hinged at one jamb, on the face of the wall it swings towards, turned by the
/// state's swing angle.
fn door_leaf(o: &Opening, rng: &mut impl RngCore) -> Item {
    let state = o.state.unwrap_or(DoorState::Closed);
    let width = o.width() - 2.0 * JAMB_GAP;
    let top = o.z[1] - JAMB_GAP;
    let (hinge_along, sign) = if o.hinge_at_start {
        (o.span[0] + JAMB_GAP, 1.0)
    } else {
        (o.span[1] - JAMB_GAP, -1.0)
    };
    let along = o.axis.dir() * sign;
    let into = o.axis.normal() * o.swing;
    let hinge = o
        .axis
        .point3(hinge_along, o.line + o.swing * o.thickness * 0.5, 0.0);
    // The leaf frame has x along the closed leaf and y = x turned +90°; `side` says whether that y
    // points into the room the leaf swings towards.
    let side = if Vec3::new(-along.y, along.x, 0.0).dot(into) > 0.0 {
        1.0
    } else {
        -1.0
    };
    let yaw = along.y.atan2(along.x) + side * state.swing_angle();
    let color = pick(rng, &["white", "brown", "tan", "gray", "dark brown"]);
    let wood = Look::named(color, Material::Wood, rng.next_u32());
    let metal = Look::named(
        pick(rng, &["silver", "gold", "black"]),
        Material::Metal,
        rng.next_u32(),
    );
    let (y_back, y_front) = (-side * LEAF, 0.0);
    let slab = cuboid(
        Vec3::new(0.0, y_back.min(y_front), 0.0),
        Vec3::new(width, y_back.max(y_front), top),
    );
    let lever = |y0: f32, y1: f32| {
        cuboid(
            Vec3::new(width - 0.16, y0.min(y1), 0.98),
            Vec3::new(width - 0.05, y0.max(y1), 1.02),
        )
    };
    let parts = vec![
        Part::new(slab, wood),
        Part::new(lever(y_front, y_front + side * 0.06), metal),
        Part::new(lever(y_back, y_back - side * 0.06), metal),
    ];
    let attributes = Attributes {
        color: Some(color.to_string()),
        material: Some(Material::Wood.name().to_string()),
        state: Some(state.as_str().to_string()),
        size: Some(if o.width() > 0.95 { "large" } else { "medium" }.to_string()),
    };
    let rigid_body = RigidBody {
        mass: 22.0 * o.width() + uniform(rng, 0.0, 4.0),
        friction: Material::Wood.friction(),
        restitution: Material::Wood.restitution(),
    };
    Item::place(
        "Door",
        parts,
        hinge,
        yaw,
        attributes,
        PhysicsRole::Articulated,
        rigid_body,
    )
}

/// A window frame with a mullion on wide windows and a glass pane, centred in the wall.
fn window(o: &Opening, rng: &mut impl RngCore) -> Item {
    let (width, height) = (o.width(), o.z[1] - o.z[0]);
    let (material, colors): (Material, &[&'static str]) = match rng.next_u32() % 3 {
        0 => (Material::Wood, &["brown", "white", "dark brown"]),
        1 => (Material::Metal, &["black", "gray", "silver"]),
        _ => (Material::Plastic, &["white", "gray"]),
    };
    let color = pick(rng, colors);
    let look = Look::named(color, material, rng.next_u32());
    let glass = Look::named("light blue", Material::Glass, rng.next_u32());
    let (hx, b, hd) = (width * 0.5, 0.05, WINDOW_FRAME * 0.5);
    let mut parts = frame(Vec3::new(width, 0.0, height), b, -hd, hd, look);
    if width > 1.0 {
        parts.push(Part::new(
            cuboid(Vec3::new(-0.025, -hd, b), Vec3::new(0.025, hd, height - b)),
            look,
        ));
    }
    parts.push(Part::new(
        cuboid(
            Vec3::new(-hx + b, -0.005, b),
            Vec3::new(hx - b, 0.005, height - b),
        ),
        glass,
    ));
    let origin = o.center().extend(o.z[0]);
    let attributes = Attributes {
        color: Some(color.to_string()),
        material: Some(material.name().to_string()),
        state: Some("closed".to_string()),
        size: Some(
            if width < 1.0 {
                "small"
            } else if width < 1.4 {
                "medium"
            } else {
                "large"
            }
            .to_string(),
        ),
    };
    let rigid_body = RigidBody {
        mass: 12.0 * width * height,
        friction: material.friction(),
        restitution: material.restitution(),
    };
    Item::place(
        "Window",
        parts,
        origin,
        o.axis.yaw(),
        attributes,
        PhysicsRole::Static,
        rigid_body,
    )
}
