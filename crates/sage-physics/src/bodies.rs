//! The collision bodies of a scene: convex parts per object (decomposed from its mesh, or its
//! oriented box), wall pieces extruded from the floorplan with door and window openings cut out,
//! and floor and ceiling slabs.

use crate::decompose::{CacheEntry, Decomposer, HullCache, cache_key};
use crate::hull::ConvexPart;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use sage_core::{Error, InstanceId, Obb, Result};
use sage_scene::{
    BodyParts, BodySource, DoorState, HoleKind, InstanceKind, Object, PhysicsRole, RigidBody,
    Scene, TriMesh, Wall,
};
use serde::Serialize;
use std::time::Instant;

/// Thickness of the floor and ceiling slabs (m).
pub const SLAB: f32 = 0.2;
/// How far a hole's centre may lie off a wall's centre line, beyond half their thicknesses,
/// and still be cut from that wall (m).
const HOLE_SNAP: f32 = 0.05;

/// What a body stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BodyKind {
    /// `scene.objects[i]`.
    Object(usize),
    /// The solid pieces of `floorplan.walls[i]`.
    Wall(usize),
    /// The floor slab under the whole plan (top at z = 0).
    Floor,
    /// The ceiling slab over the whole plan (bottom at the ceiling height).
    Ceiling,
    /// The structure parts that belong to no object ([`Scene::structure_body`]: the walls,
    /// floors and ceilings of a published collision file, or a capture's loose Gaussians), one
    /// static body.
    Structure,
}

/// Where a body's parts came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PartSource {
    /// Decomposed now and written to the cache (unless [`BuildReport::unstored`] names its
    /// entry).
    Decomposed,
    /// Read from the cache.
    Cached,
    /// The object's oriented box (no mesh).
    Box,
    /// Boxes extruded from the floorplan.
    Structure,
    /// The object's given parts ([`sage_scene::BodyParts`]): read from a published collision
    /// file or recovered from its Gaussians (the object's [`BodySource`] says which).
    Given,
}

/// Where one object's body came from (the provenance `physics build`, `scene info` and run
/// records report, so that numbers made with different physics are not compared unknowingly).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ObjectSource {
    /// Dense instance id.
    pub instance: u32,
    /// The source id (`ins_id`).
    pub ins_id: String,
    /// Category.
    pub category: String,
    /// Where its body came from.
    pub source: BodySource,
    /// Number of convex parts.
    pub parts: usize,
}

/// One collision body: convex parts in world coordinates and what they belong to.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// What it stands for.
    pub kind: BodyKind,
    /// The instance id reported in contacts (0 for floor and ceiling, resolved per room).
    pub instance: InstanceId,
    /// A readable name: category and id (`chair_12`, `wall_3`, `floor`).
    pub name: String,
    /// The semantic category.
    pub category: String,
    /// Physics role (structure is static).
    pub role: PhysicsRole,
    /// Rigid-body parameters.
    pub rigid_body: RigidBody,
    /// The oriented box (objects) or bounds (structure).
    pub obb: Obb,
    /// Convex parts, world frame.
    pub parts: Vec<ConvexPart>,
    /// Where the parts came from.
    pub source: PartSource,
    /// For given parts ([`PartSource::Given`]): whose they are (`published`, `gaussians`), as
    /// the USDA export records them.
    pub given: Option<BodySource>,
}

/// Decomposition quality of one object with a mesh.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ObjectQuality {
    /// Dense instance id.
    pub instance: u32,
    /// Category.
    pub category: String,
    /// Number of convex parts.
    pub hulls: usize,
    /// Volume enclosed by the mesh (|signed volume|, m³).
    pub mesh_volume: f32,
    /// Sum of the parts' volumes (overlaps counted twice), m³.
    pub hull_volume: f32,
    /// Where the parts came from.
    pub source: PartSource,
}

/// What [`SceneBodies::build`] did.
#[derive(Debug, Clone, Serialize, PartialEq, Default)]
pub struct BuildReport {
    /// The decomposer settings.
    pub decomposer: String,
    /// The cache folder.
    pub cache_dir: String,
    /// Objects decomposed now.
    pub decomposed: usize,
    /// Objects read from the cache.
    pub cached: usize,
    /// Objects given their oriented box.
    pub boxes: usize,
    /// Wall pieces after cutting openings.
    pub wall_pieces: usize,
    /// Convex parts of the structure body ([`BodyKind::Structure`]: the parts of a published
    /// collision file that belong to no object, or those recovered from a capture's loose
    /// Gaussians; 0 without one).
    pub structure_parts: usize,
    /// Openings cut.
    pub openings_cut: usize,
    /// Total convex parts of all bodies.
    pub parts: usize,
    /// Per-object quality of mesh decompositions, in object order.
    pub objects: Vec<ObjectQuality>,
    /// Where every object's body came from, in object order.
    pub sources: Vec<ObjectSource>,
    /// How the scene's published collision file was used (frame, agreement with the label
    /// boxes, parts by name, by box and of the structure), when it has one: the loader's
    /// report ([`sage_scene::LoadReport::collision`]), which whoever loaded the scene copies
    /// here.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collision: Option<sage_scene::collision::CollisionReport>,
    /// The damaged hull cache entries ([`CacheEntry::Damaged`]) decomposed anew and replaced,
    /// in object order, each as the error that found it (naming the file).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub remade: Vec<String>,
    /// The hull cache entries that could not be written (a read-only scene folder, a full
    /// disk), in object order, each as its write error (naming the file, or the folder that
    /// could not be made; an error alike for many entries is listed once): their objects took
    /// the parts just decomposed, and every later build decomposes them again until a writable
    /// cache folder is given.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub unstored: Vec<String>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl BuildReport {
    /// Σ hull volume / Σ mesh volume over objects with meshes (1 = exact; > 1 = fattened).
    pub fn volume_ratio(&self) -> f32 {
        let (h, m) = self.objects.iter().fold((0.0, 0.0), |(h, m), o| {
            (h + o.hull_volume, m + o.mesh_volume)
        });
        if m > 0.0 { h / m } else { 1.0 }
    }

    /// Mean convex parts per object with a mesh.
    pub fn mean_hulls(&self) -> f32 {
        // With no meshed object (every body published or boxed) the mean is 0, not the -0.0
        // an empty float sum gives.
        if self.objects.is_empty() {
            return 0.0;
        }
        let n = self.objects.len() as f32;
        self.objects.iter().map(|o| o.hulls as f32).sum::<f32>() / n
    }
}

/// All collision bodies of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneBodies {
    /// Bodies: objects in order, then walls, the structure body, floor, ceiling.
    pub bodies: Vec<Body>,
    /// The floor instance id of each room (for contacts with the floor slab).
    pub floor_ids: Vec<InstanceId>,
    /// The ceiling instance id of each room.
    pub ceiling_ids: Vec<InstanceId>,
    /// The ceiling height, metres.
    pub ceiling_height: f32,
}

impl SceneBodies {
    /// Builds every body of `scene`, decomposing meshes missing from `cache` (in parallel) and
    /// storing them. An entry that cannot be stored does not stop the build: its parts are used
    /// as decomposed and the write error is reported ([`BuildReport::unstored`]), so a scene in
    /// a read-only folder still loads.
    ///
    /// # Errors
    ///
    /// Bad settings, an unreadable cache entry (named), or a CoACD entry that has not been made
    /// yet or is damaged. A damaged entry of the in-process decomposer is made anew and
    /// replaced ([`BuildReport::remade`]).
    pub fn build(
        scene: &Scene,
        decomposer: &Decomposer,
        cache: &HullCache,
    ) -> Result<(SceneBodies, BuildReport)> {
        Self::build_with_progress(scene, decomposer, cache, &|| {})
    }

    /// [`SceneBodies::build`], calling `object_done` after each object's parts are ready (from
    /// worker threads), for progress bars: a cold decomposition takes seconds per object.
    pub fn build_with_progress(
        scene: &Scene,
        decomposer: &Decomposer,
        cache: &HullCache,
        object_done: &(dyn Fn() + Sync),
    ) -> Result<(SceneBodies, BuildReport)> {
        decomposer.validate()?;
        let start = Instant::now();
        let mut report = BuildReport {
            decomposer: decomposer.describe(),
            cache_dir: cache.dir().display().to_string(),
            ..BuildReport::default()
        };
        let object_parts = scene
            .objects
            .par_iter()
            .map(|o| {
                let parts = object_parts(o, decomposer, cache);
                object_done();
                parts
            })
            .collect::<Vec<_>>();
        let mut bodies = Vec::new();
        for (oi, (o, parts)) in scene.objects.iter().zip(object_parts).enumerate() {
            let (parts, source, entry) = parts.map_err(|e| {
                e.within(format!(
                    "object {} (ins_id {}, {})",
                    o.id.0, o.ins_id, o.category
                ))
            })?;
            // Objects of one mesh share its entry: it is named once.
            for (note, list) in [
                (entry.damage, &mut report.remade),
                (entry.unstored, &mut report.unstored),
            ] {
                if let Some(note) = note.map(|e| e.to_string())
                    && !list.contains(&note)
                {
                    list.push(note);
                }
            }
            match source {
                PartSource::Decomposed => report.decomposed += 1,
                PartSource::Cached => report.cached += 1,
                PartSource::Given => {}
                PartSource::Box | PartSource::Structure => report.boxes += 1,
            }
            report.sources.push(ObjectSource {
                instance: o.id.0,
                ins_id: o.ins_id.clone(),
                category: o.category.clone(),
                source: if source == PartSource::Box {
                    BodySource::Box
                } else {
                    o.body_source()
                },
                parts: parts.len(),
            });
            if let Some(mesh) = &o.mesh
                && matches!(source, PartSource::Decomposed | PartSource::Cached)
            {
                report.objects.push(ObjectQuality {
                    instance: o.id.0,
                    category: o.category.clone(),
                    hulls: parts.len(),
                    mesh_volume: mesh.signed_volume().abs(),
                    hull_volume: parts.iter().map(ConvexPart::volume).sum(),
                    source,
                });
            }
            // An open door leaf known only by its box is no body (SPEC §6), as the navigation
            // grid leaves it free: a body there would stop agents on paths planned through it.
            if source == PartSource::Box
                && o.category.contains("door")
                && o.door_state() == Some(DoorState::Open)
            {
                continue;
            }
            bodies.push(Body {
                kind: BodyKind::Object(oi),
                instance: o.id,
                name: format!("{}_{}", o.category, o.id.0),
                category: o.category.clone(),
                role: o.role,
                rigid_body: o.rigid_body,
                obb: o.obb,
                parts,
                source,
                given: (source == PartSource::Given).then(|| o.body_source()),
            });
        }
        let ids = &scene.instances.kinds;
        let id_of = |k: InstanceKind| {
            ids.iter()
                .position(|x| *x == k)
                .map_or(InstanceId::NONE, |i| InstanceId(i as u32))
        };
        for (wi, wall) in scene.floorplan.walls.iter().enumerate() {
            let (parts, cut) = wall_pieces(wall, scene);
            report.wall_pieces += parts.len();
            report.openings_cut += cut;
            bodies.push(Body {
                kind: BodyKind::Wall(wi),
                instance: id_of(InstanceKind::Wall(wi)),
                name: format!("wall_{wi}"),
                category: "wall".into(),
                role: PhysicsRole::Static,
                rigid_body: RigidBody::default(),
                obb: wall.obb(),
                parts,
                source: PartSource::Structure,
                given: None,
            });
        }
        if let Some(given) = &scene.structure_body {
            let parts = given_hulls(given);
            if !parts.is_empty() {
                let aabb = given
                    .parts
                    .iter()
                    .fold(sage_core::Aabb::EMPTY, |b, m| b.union(m.aabb()));
                report.structure_parts = parts.len();
                bodies.push(Body {
                    kind: BodyKind::Structure,
                    instance: InstanceId::NONE,
                    name: "structure".into(),
                    category: "structure".into(),
                    role: PhysicsRole::Static,
                    rigid_body: RigidBody::default(),
                    obb: Obb {
                        center: (aabb.min + aabb.max) * 0.5,
                        half_extents: (aabb.max - aabb.min) * 0.5,
                        yaw: 0.0,
                    },
                    parts,
                    source: PartSource::Given,
                    given: Some(given.source),
                });
            }
        }
        let bounds = scene.bounds();
        // A scene without walls takes the ceiling its capture's import measured; without one
        // (labels without `structure.json`, a capture with no ceiling found) its slab caps
        // everything the scene holds rather than cutting through it at a guessed height.
        let ceiling_height = match scene.floorplan.ceiling {
            _ if !scene.floorplan.walls.is_empty() || bounds.is_empty() => {
                scene.floorplan.ceiling_height()
            }
            Some(measured) => measured,
            None => bounds.max.z,
        };
        if !bounds.is_empty() {
            let (lo, hi) = (bounds.min.truncate(), bounds.max.truncate());
            let slab = |z0: f32, kind: BodyKind, name: &str| {
                let obb = Obb {
                    center: ((lo + hi) * 0.5).extend(z0 + SLAB * 0.5),
                    half_extents: ((hi - lo) * 0.5 + Vec2::splat(0.5)).extend(SLAB * 0.5),
                    yaw: 0.0,
                };
                Body {
                    kind,
                    instance: InstanceId::NONE,
                    name: name.into(),
                    category: name.into(),
                    role: PhysicsRole::Static,
                    rigid_body: RigidBody::default(),
                    obb,
                    parts: ConvexPart::from_obb(&obb).into_iter().collect(),
                    source: PartSource::Structure,
                    given: None,
                }
            };
            bodies.push(slab(-SLAB, BodyKind::Floor, "floor"));
            bodies.push(slab(ceiling_height, BodyKind::Ceiling, "ceiling"));
        }
        report.parts = bodies.iter().map(|b| b.parts.len()).sum();
        report.seconds = start.elapsed().as_secs_f64();
        let rooms = scene.floorplan.rooms.len();
        Ok((
            SceneBodies {
                bodies,
                floor_ids: (0..rooms).map(|r| id_of(InstanceKind::Floor(r))).collect(),
                ceiling_ids: (0..rooms)
                    .map(|r| id_of(InstanceKind::Ceiling(r)))
                    .collect(),
                ceiling_height,
            },
            report,
        ))
    }
}

impl SceneBodies {
    /// How many of `scene`'s objects (the one these bodies were built from) have a body from
    /// each source; an object without a body (an open door known only by its box) counts as a
    /// box.
    pub fn object_sources(&self, scene: &Scene) -> std::collections::BTreeMap<BodySource, usize> {
        let mut counts = std::collections::BTreeMap::new();
        let mut seen = vec![false; scene.objects.len()];
        for b in &self.bodies {
            if let BodyKind::Object(i) = b.kind
                && let Some(o) = scene.objects.get(i)
            {
                seen[i] = true;
                let source = if b.source == PartSource::Box {
                    BodySource::Box
                } else {
                    o.body_source()
                };
                *counts.entry(source).or_insert(0) += 1;
            }
        }
        let unseen = seen.iter().filter(|s| !**s).count();
        if unseen > 0 {
            *counts.entry(BodySource::Box).or_insert(0) += unseen;
        }
        counts
    }
}

/// The convex hulls of given parts: a published part is convex already (its hull is itself); a
/// part too flat to span a volume is dropped.
fn given_hulls(given: &BodyParts) -> Vec<ConvexPart> {
    given
        .parts
        .iter()
        .filter_map(|m| ConvexPart::hull_of(&m.positions))
        .collect()
}

/// The hulls of an object's given parts, when any spans a volume: a body left with none is made
/// as if none were given.
fn given_parts(object: &Object) -> Option<Vec<ConvexPart>> {
    let hulls = given_hulls(object.body.as_ref()?);
    (!hulls.is_empty()).then_some(hulls)
}

/// The mesh whose hulls make `object`'s body: none when its given parts make it, or when it has
/// no mesh with a triangle (its box does). The builder and the CoACD work list both ask here.
pub(crate) fn hull_mesh(object: &Object) -> Option<&TriMesh> {
    if given_parts(object).is_some() {
        return None;
    }
    object.mesh.as_ref().filter(|m| !m.triangles.is_empty())
}

/// What became of an object's hull cache entry besides being read.
#[derive(Debug, Default)]
struct EntryNotes {
    /// The damage of the entry that decomposing replaced ([`BuildReport::remade`]).
    damage: Option<Error>,
    /// Why the entry just decomposed could not be written ([`BuildReport::unstored`]).
    unstored: Option<Error>,
}

/// The parts of one object: its given parts, else cached or decomposed hulls of its mesh, else
/// its box; and what became of its cache entry.
fn object_parts(
    object: &Object,
    decomposer: &Decomposer,
    cache: &HullCache,
) -> Result<(Vec<ConvexPart>, PartSource, EntryNotes)> {
    if let Some(parts) = given_parts(object) {
        return Ok((parts, PartSource::Given, EntryNotes::default()));
    }
    let boxed = || {
        ConvexPart::from_obb(&object.obb)
            .map(|p| vec![p])
            .ok_or_else(|| Error::invalid("the oriented box has no volume and no mesh is given"))
    };
    let Some(mesh) = hull_mesh(object) else {
        return Ok((boxed()?, PartSource::Box, EntryNotes::default()));
    };
    let key = cache_key(mesh, decomposer);
    let damage = match cache.load(key)? {
        CacheEntry::Parts(parts) => {
            return Ok((parts, PartSource::Cached, EntryNotes::default()));
        }
        CacheEntry::Missing => None,
        CacheEntry::Damaged(e) => Some(e),
    };
    let parts = decomposer.run(mesh).map_err(|e| match &damage {
        // CoACD's entries are made offline: the damage, in its file, and how to make it again.
        Some(d) => {
            let why = format!(
                "{}; the entry cannot be read and is to be made again: {}",
                d.message(),
                e.message()
            );
            let e = Error::format(d.location(), why);
            match d.file() {
                Some(file) => e.in_file(file),
                None => e,
            }
        }
        None => e,
    })?;
    // A mesh too thin to voxelise (a flat rug): its box is the honest body.
    let parts = if parts.is_empty() { boxed()? } else { parts };
    // The parts are good whether or not they could be kept: a scene in a read-only folder
    // still loads, decomposing again each time (the report says so).
    let unstored = cache.store(key, &parts).err();
    Ok((
        parts,
        PartSource::Decomposed,
        EntryNotes { damage, unstored },
    ))
}

/// The solid boxes of a wall after cutting the door and window holes that lie in it, and the
/// number of holes cut.
///
/// Along the wall, the holes' extents split the wall into intervals; in each interval the solid
/// height is [0, height] minus the union of the covering holes' height ranges.
pub fn wall_pieces(wall: &Wall, scene: &Scene) -> (Vec<ConvexPart>, usize) {
    let len = wall.length();
    let dir = wall.direction();
    if len <= 1e-6 {
        return (Vec::new(), 0);
    }
    let normal = dir.perp();
    let mut holes: Vec<(f32, f32, f32, f32)> = Vec::new();
    for h in &scene.floorplan.holes {
        let (lo, hi) = h.bounds();
        let centre = ((lo + hi) * 0.5).truncate();
        let off = (centre - wall.start).dot(normal).abs();
        if off > (wall.thickness + h.thickness) * 0.5 + HOLE_SNAP {
            continue;
        }
        let along = h
            .profile
            .iter()
            .map(|p| (p.truncate() - wall.start).dot(dir));
        let (a0, a1) = along.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        });
        let (a0, a1) = (a0.max(0.0), a1.min(len));
        if a1 - a0 > 1e-4 && hi.z > lo.z {
            let top = if h.kind == HoleKind::Door && hi.z >= wall.height {
                wall.height
            } else {
                hi.z
            };
            holes.push((a0, a1, lo.z.max(0.0), top.min(wall.height)));
        }
    }
    let mut cuts: Vec<f32> = vec![0.0, len];
    for &(a0, a1, _, _) in &holes {
        cuts.extend([a0, a1]);
    }
    cuts.sort_by(f32::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-5);
    let mut parts = Vec::new();
    for w in cuts.windows(2) {
        let (s0, s1) = (w[0], w[1]);
        let mid = (s0 + s1) * 0.5;
        let mut gaps: Vec<(f32, f32)> = holes
            .iter()
            .filter(|h| h.0 <= mid && mid <= h.1)
            .map(|h| (h.2, h.3))
            .collect();
        gaps.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut z = 0.0f32;
        let mut solid = Vec::new();
        for (g0, g1) in gaps {
            if g0 > z {
                solid.push((z, g0));
            }
            z = z.max(g1);
        }
        if wall.height > z {
            solid.push((z, wall.height));
        }
        for (z0, z1) in solid {
            if z1 - z0 < 1e-4 {
                continue;
            }
            let c = wall.start + dir * mid;
            let obb = Obb {
                center: Vec3::new(c.x, c.y, (z0 + z1) * 0.5),
                half_extents: Vec3::new((s1 - s0) * 0.5, wall.thickness * 0.5, (z1 - z0) * 0.5),
                yaw: dir.y.atan2(dir.x),
            };
            parts.extend(ConvexPart::from_obb(&obb));
        }
    }
    (parts, holes.len())
}
