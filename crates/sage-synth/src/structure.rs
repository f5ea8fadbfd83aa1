//! The structure's surfaces and mesh.
//!
//! Surfaces (for the Gaussians): each room's floor, ceiling and the four wall faces around it, the
//! outside faces of the outside walls, all with the openings left out, and the faces inside each
//! opening (jambs, lintel, sill or threshold). The mesh: every wall as solid boxes around its
//! openings, plus a floor and a ceiling per room.

use crate::layout::{Axis, EXTERIOR_WALL, Layout, Opening, RoomCell};
use crate::look::Look;
use crate::shapes::{cuboid, first_use_order};
use crate::surfaces::{Frame, Geometry, Patch};
use glam::Vec3;
use sage_scene::floorplan::HoleKind;
use sage_scene::mesh::TriMesh;

/// A vertical wall face on the plane `across` of `axis`, along `span`, from the floor to the
/// ceiling, facing `facing`, minus the openings of the wall whose centre line is `line`.
struct Face {
    axis: Axis,
    line: f32,
    across: f32,
    span: [f32; 2],
    facing: f32,
    look: Look,
}

/// The openings cut into the wall at `line` on `axis` that overlap `span`, in order along it.
fn openings_on(layout: &Layout, axis: Axis, line: f32, span: [f32; 2]) -> Vec<&Opening> {
    let mut found: Vec<&Opening> = layout
        .openings
        .iter()
        .filter(|o| {
            o.axis == axis
                && (o.line - line).abs() < 1e-3
                && o.span[0] < span[1]
                && o.span[1] > span[0]
        })
        .collect();
    found.sort_by(|a, b| a.span[0].total_cmp(&b.span[0]));
    found
}

/// The pieces (along range, z range) of a wall from `span` and the floor to `height` that are
/// left around `openings`.
fn solid_pieces(span: [f32; 2], height: f32, openings: &[&Opening]) -> Vec<([f32; 2], [f32; 2])> {
    let mut pieces = Vec::new();
    let mut at = span[0];
    for o in openings {
        let (s0, s1) = (o.span[0].max(span[0]), o.span[1].min(span[1]));
        if s0 > at {
            pieces.push(([at, s0], [0.0, height]));
        }
        if o.z[0] > 0.0 {
            pieces.push(([s0, s1], [0.0, o.z[0]]));
        }
        if o.z[1] < height {
            pieces.push(([s0, s1], [o.z[1], height]));
        }
        at = at.max(s1);
    }
    if span[1] > at {
        pieces.push(([at, span[1]], [0.0, height]));
    }
    pieces
}

fn face_patches(layout: &Layout, f: &Face, out: &mut Vec<Patch>) {
    let openings = openings_on(layout, f.axis, f.line, f.span);
    for (s, z) in solid_pieces(f.span, layout.height, &openings) {
        let origin = f.axis.point3(s[0], f.across, z[0]);
        let geometry = Geometry::rect_facing(
            origin,
            f.axis.dir() * (s[1] - s[0]),
            Vec3::Z * (z[1] - z[0]),
            f.axis.normal() * f.facing,
        );
        out.push(Patch {
            geometry,
            look: f.look,
            frame: Frame::WORLD,
        });
    }
}

/// Floor, ceiling and the four inner wall faces of a room.
fn room_patches(layout: &Layout, room: &RoomCell, out: &mut Vec<Patch>) {
    let (r, i, h) = (room.rect, room.inner, layout.height);
    let size = i.size();
    let floor_origin = i.min.extend(0.0);
    out.push(Patch {
        geometry: Geometry::rect_facing(floor_origin, Vec3::X * size.x, Vec3::Y * size.y, Vec3::Z),
        look: room.floor,
        frame: Frame::WORLD,
    });
    out.push(Patch {
        geometry: Geometry::rect_facing(
            i.min.extend(h),
            Vec3::X * size.x,
            Vec3::Y * size.y,
            -Vec3::Z,
        ),
        look: room.ceiling,
        frame: Frame::WORLD,
    });
    let faces = [
        Face {
            axis: Axis::X,
            line: r.min.y,
            across: i.min.y,
            span: [i.min.x, i.max.x],
            facing: 1.0,
            look: room.wall,
        },
        Face {
            axis: Axis::X,
            line: r.max.y,
            across: i.max.y,
            span: [i.min.x, i.max.x],
            facing: -1.0,
            look: room.wall,
        },
        Face {
            axis: Axis::Y,
            line: r.min.x,
            across: i.min.x,
            span: [i.min.y, i.max.y],
            facing: 1.0,
            look: room.wall,
        },
        Face {
            axis: Axis::Y,
            line: r.max.x,
            across: i.max.x,
            span: [i.min.y, i.max.y],
            facing: -1.0,
            look: room.wall,
        },
    ];
    for f in &faces {
        face_patches(layout, f, out);
    }
}

/// The outside faces of the four outside walls.
fn outside_patches(layout: &Layout, out: &mut Vec<Patch>) {
    for w in layout.walls.iter().filter(|w| w.thickness == EXTERIOR_WALL) {
        let [lo, hi] = layout.footprint.extent(w.axis.other());
        let facing = if w.line > 0.5 * (lo + hi) { 1.0 } else { -1.0 };
        let face = Face {
            axis: w.axis,
            line: w.line,
            across: w.line + facing * w.thickness * 0.5,
            span: w.span,
            facing,
            look: layout.outside,
        };
        face_patches(layout, &face, out);
    }
}

/// The faces inside an opening: jambs, lintel, and a sill (windows) or threshold floor (doors).
fn reveal_patches(layout: &Layout, o: &Opening, out: &mut Vec<Patch>) {
    let room = o
        .rooms
        .iter()
        .flatten()
        .next()
        .and_then(|&r| layout.rooms.get(r));
    let (wall, floor) = match room {
        Some(r) => (r.wall, r.floor),
        None => (layout.outside, layout.outside),
    };
    let (t, [s0, s1], [z0, z1]) = (o.thickness, o.span, o.z);
    let (dir, normal) = (o.axis.dir(), o.axis.normal());
    let back = o.line - t * 0.5;
    let mut push = |geometry, look| {
        out.push(Patch {
            geometry,
            look,
            frame: Frame::WORLD,
        })
    };
    for (s, facing) in [(s0, dir), (s1, -dir)] {
        push(
            Geometry::rect_facing(
                o.axis.point3(s, back, z0),
                normal * t,
                Vec3::Z * (z1 - z0),
                facing,
            ),
            wall,
        );
    }
    let across = |z, facing| {
        Geometry::rect_facing(
            o.axis.point3(s0, back, z),
            dir * (s1 - s0),
            normal * t,
            facing,
        )
    };
    push(across(z1, -Vec3::Z), wall);
    push(
        across(z0, Vec3::Z),
        if o.kind == HoleKind::Door {
            floor
        } else {
            wall
        },
    );
}

/// Every structural surface of the layout.
pub(crate) fn patches(layout: &Layout) -> Vec<Patch> {
    let mut out = Vec::new();
    for room in &layout.rooms {
        room_patches(layout, room, &mut out);
    }
    outside_patches(layout, &mut out);
    for o in &layout.openings {
        reveal_patches(layout, o, &mut out);
    }
    out
}

/// A two-triangle quad with normal `u × v`.
fn quad(origin: Vec3, u: Vec3, v: Vec3) -> TriMesh {
    TriMesh {
        positions: vec![origin, origin + u, origin + u + v, origin + v],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The structure mesh: walls as solid boxes around their openings, floors and ceilings per room.
pub(crate) fn mesh(layout: &Layout) -> TriMesh {
    let mut mesh = TriMesh::default();
    for w in &layout.walls {
        let openings = openings_on(layout, w.axis, w.line, w.span);
        for (s, z) in solid_pieces(w.span, layout.height, &openings) {
            let a = w.axis.point3(s[0], w.line - w.thickness * 0.5, z[0]);
            let b = w.axis.point3(s[1], w.line + w.thickness * 0.5, z[1]);
            mesh.append(&cuboid(a.min(b), a.max(b)));
        }
    }
    for room in &layout.rooms {
        let (r, size) = (room.rect, room.rect.size());
        mesh.append(&quad(r.min.extend(0.0), Vec3::X * size.x, Vec3::Y * size.y));
        mesh.append(&quad(
            r.min.extend(layout.height),
            Vec3::Y * size.y,
            Vec3::X * size.x,
        ));
    }
    first_use_order(&mesh)
}
