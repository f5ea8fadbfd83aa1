//! Collision bodies recovered from an object's own Gaussians, for objects with neither a mesh
//! nor a published body (InteriorGS ships none of either).
//!
//! Each Gaussian already carries its instance. The object's Gaussians are drawn into a voxel
//! grid in the object's own frame: a voxel is skin where some Gaussian's ellipsoid, `reach`
//! standard deviations along each of its axes plus half a voxel, holds the voxel's centre (so a
//! disc thinner than a voxel still marks the voxels it passes through). A morphological closing
//! (grow one voxel, flood the outside, shrink one voxel) seals gaps up to two voxels wide and
//! fills what the skin encloses — a cabinet becomes solid — while what it does not enclose stays
//! free: the space under a table top, between a chair's legs. The solid is clipped to the
//! object's annotated box (the object lies inside it; Gaussians' tails reach past it), and its
//! voxels are merged greedily into boxes along the object's axes; each box is one convex part.
//!
//! Flat Gaussians lying on the structure — the floor at z = 0, the ceiling, a wall's faces — are
//! left out: the box test that gives Gaussians their instance hands the floor under a table to
//! the table and the wall behind a painting to the painting, and they would close the space
//! beneath the one and thicken the other.
//!
//! In a scene with no structure at all (a capture), the Gaussians that belong to no object make
//! the scene's structure body the same way, closed but not filled (a room's walls and ceiling
//! enclose its air); those of the floor band ([`sage_scene::FLOOR_BAND`]) are left to the floor
//! slab every scene has.
//!
//! Same Gaussians, same parts: nothing here depends on the thread count.

use crate::bodies::wall_pieces;
use crate::hull::ConvexPart;
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use sage_core::{Aabb, Obb, Result};
use sage_scene::{BodyParts, BodySource, FLOOR_BAND, Gaussians, Object, Scene, TriMesh};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Which objects get bodies recovered from their Gaussians.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum SplatBodies {
    /// Only objects that would otherwise be their box (no published body, no mesh).
    #[default]
    Auto,
    /// Every object, whatever else it has (to compare with the mesh's bodies).
    Always,
    /// None: objects without a mesh or a published body stay their box. A scene with no
    /// structure at all (a capture) still gets its structure body from its loose Gaussians:
    /// that is its walls, not an object's body, and without it nothing would stop an agent.
    Never,
}

impl SplatBodies {
    /// Every choice, in the order `--help` lists them.
    pub const ALL: [SplatBodies; 3] = [SplatBodies::Auto, SplatBodies::Always, SplatBodies::Never];

    /// `auto`, `always` or `never`.
    pub fn as_str(self) -> &'static str {
        match self {
            SplatBodies::Auto => "auto",
            SplatBodies::Always => "always",
            SplatBodies::Never => "never",
        }
    }

    /// True when `object` gets its body from its Gaussians under this choice.
    pub fn applies_to(self, object: &Object) -> bool {
        match self {
            SplatBodies::Auto => object.body_source() == BodySource::Box,
            SplatBodies::Always => true,
            SplatBodies::Never => false,
        }
    }
}

impl fmt::Display for SplatBodies {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SplatBodies {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        SplatBodies::ALL
            .into_iter()
            .find(|c| c.as_str() == s)
            .ok_or_else(|| {
                format!("unknown choice '{s}' for bodies from splats (auto, always, never)")
            })
    }
}

sage_core::named_by_string!(SplatBodies);

/// How bodies are recovered from Gaussians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatBodyParams {
    /// Voxel edge, metres (grown for large objects so that no axis exceeds [`MAX_VOXELS`]).
    pub voxel: f32,
    /// How far a Gaussian reaches, in standard deviations along each of its axes.
    pub reach: f32,
    /// Gaussians more transparent than this are left out.
    pub min_opacity: f32,
    /// Objects with fewer usable Gaussians keep their box.
    pub min_gaussians: usize,
    /// Convex parts per object wanted at most: while there are more, a coarser voxel (×1.5) is
    /// tried, up to three times; the third coarser one is kept whatever its count.
    pub max_parts: usize,
}

impl Default for SplatBodyParams {
    fn default() -> Self {
        SplatBodyParams {
            voxel: 0.02,
            reach: 1.0,
            min_opacity: 0.1,
            min_gaussians: 16,
            max_parts: 96,
        }
    }
}

/// Most voxels along one axis of an object's grid.
pub const MAX_VOXELS: usize = 200;
/// Voxels of free margin around an object's box (Gaussians reach a little outside it).
const MARGIN: usize = 3;
/// How many times a coarser voxel (× 1.5) is tried when an object has too many parts.
const COARSEN_TRIES: usize = 3;

/// What [`attach`] did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SplatBodyReport {
    /// Objects given bodies recovered from their Gaussians.
    pub recovered: usize,
    /// Objects the choice applied to that had too few Gaussians (they keep what they had).
    pub too_few_gaussians: usize,
    /// Parts of the body recovered from the Gaussians of no object, in a scene with no
    /// structure (a capture): 0 when there was none.
    pub structure_parts: usize,
}

/// Gives the objects `choice` selects a body recovered from their Gaussians
/// ([`BodySource::Gaussians`]), in parallel over objects.
///
/// # Errors
///
/// Bad parameters.
pub fn attach(
    scene: &mut Scene,
    choice: SplatBodies,
    params: &SplatBodyParams,
) -> Result<SplatBodyReport> {
    validate(params)?;
    let mut report = SplatBodyReport::default();
    let members = members_by_instance(&scene.gaussians);
    let structure = Structure::of(scene);
    let gaussians = &scene.gaussians;
    let recovered: Vec<Option<Option<Vec<TriMesh>>>> = scene
        .objects
        .par_iter()
        .map(|o| {
            choice.applies_to(o).then(|| {
                let own = members.get(o.id.0 as usize).map_or(&[][..], Vec::as_slice);
                recover(gaussians, own, &o.obb, &structure, params)
            })
        })
        .collect();
    for (o, parts) in scene.objects.iter_mut().zip(recovered) {
        match parts {
            Some(Some(parts)) => {
                report.recovered += 1;
                o.body = Some(BodyParts {
                    source: BodySource::Gaussians,
                    parts,
                });
            }
            Some(None) => report.too_few_gaussians += 1,
            None => {}
        }
    }
    let bare = scene.floorplan.rooms.is_empty()
        && scene.floorplan.walls.is_empty()
        && scene.structure_mesh.is_none()
        && scene.structure_body.is_none();
    if bare && let Some(parts) = loose_body(scene, &structure, params) {
        report.structure_parts = parts.len();
        scene.structure_body = Some(BodyParts {
            source: BodySource::Gaussians,
            parts,
        });
    }
    Ok(report)
}

/// Most convex parts of the body of a scene's loose Gaussians.
const MAX_LOOSE_PARTS: usize = 4096;

/// The body of the Gaussians that belong to no object, for a scene with no structure at all (a
/// capture): their skin, closed but not filled — a room's walls and ceiling enclose its air,
/// which must stay free. Gaussians centred in the floor band are left to the floor slab: the
/// skin of a floor a few centimetres thick would stand above a ground robot's clearance, and
/// every agent on the floor would touch it; the occupancy grid counts no obstacle there either.
fn loose_body(
    scene: &Scene,
    structure: &Structure,
    params: &SplatBodyParams,
) -> Option<Vec<TriMesh>> {
    let g = &scene.gaussians;
    let loose: Vec<u32> = (0..g.len() as u32)
        .filter(|&i| g.instances[i as usize] == 0 && g.positions[i as usize][2] >= FLOOR_BAND)
        .collect();
    let bounds = Aabb::from_points(
        loose
            .iter()
            .map(|&i| Vec3::from_array(g.positions[i as usize])),
    );
    if bounds.is_empty() {
        return None;
    }
    let obb = Obb {
        center: (bounds.min + bounds.max) * 0.5,
        half_extents: ((bounds.max - bounds.min) * 0.5).max(Vec3::splat(params.voxel)),
        yaw: 0.0,
    };
    let params = SplatBodyParams {
        max_parts: MAX_LOOSE_PARTS,
        ..*params
    };
    recover_solid(g, &loose, &obb, structure, &params, false)
}

fn validate(p: &SplatBodyParams) -> Result<()> {
    let ok = p.voxel > 0.001
        && p.voxel.is_finite()
        && p.reach > 0.0
        && p.reach.is_finite()
        && (0.0..1.0).contains(&p.min_opacity)
        && p.max_parts > 0;
    if ok {
        Ok(())
    } else {
        Err(sage_core::Error::invalid(format!(
            "bodies from splats need voxel > 1 mm, reach > 0, min opacity in [0, 1) and max parts > 0, got {p:?}"
        )))
    }
}

/// The indices of the Gaussians of each instance id.
fn members_by_instance(g: &Gaussians) -> Vec<Vec<u32>> {
    let n = g
        .instances
        .iter()
        .copied()
        .max()
        .map_or(0, |m| m as usize + 1);
    let mut members = vec![Vec::new(); n];
    for (i, &k) in g.instances.iter().enumerate() {
        if k != 0 {
            members[k as usize].push(i as u32);
        }
    }
    members
}

/// The solid structure of a scene that objects stand on, hang from or lean against: below the
/// floor at z = 0, above the ceiling, the walls with their openings cut.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Structure {
    /// Ceiling height, metres (`None` without a floorplan).
    pub ceiling: Option<f32>,
    /// The walls' solid pieces.
    pub walls: Vec<ConvexPart>,
}

impl Structure {
    /// The structure of `scene`'s floorplan (the floor alone when it has none).
    pub fn of(scene: &Scene) -> Structure {
        let fp = &scene.floorplan;
        Structure {
            ceiling: (!fp.rooms.is_empty() || !fp.walls.is_empty()).then(|| fp.ceiling_height()),
            walls: fp
                .walls
                .iter()
                .flat_map(|w| wall_pieces(w, scene).0)
                .collect(),
        }
    }

    /// The part of the structure near `obb` (its walls whose bounds come within `margin`).
    fn near(&self, obb: &Obb, margin: f32) -> Structure {
        let b = obb.aabb();
        let (lo, hi) = (b.min - Vec3::splat(margin), b.max + Vec3::splat(margin));
        Structure {
            ceiling: self.ceiling,
            walls: self
                .walls
                .iter()
                .filter(|w| {
                    let wb = Aabb::from_points(w.vertices.iter().copied());
                    wb.min.cmple(hi).all() && wb.max.cmpge(lo).all()
                })
                .cloned()
                .collect(),
        }
    }

    /// True when `p` lies in the structure's solid. The outside flood does not pass there, so
    /// an object standing on the floor or hung on a wall is closed by it where its own
    /// Gaussians on that side were left out.
    fn solid_at(&self, p: Vec3) -> bool {
        p.z < 0.0
            || self.ceiling.is_some_and(|c| p.z > c)
            || self.walls.iter().any(|w| w.contains(p))
    }

    /// True when a flat Gaussian at `p` with unit normal `n` lies on the structure's surface:
    /// the solid is just behind it or just in front of it.
    fn holds(&self, p: Vec3, n: Vec3) -> bool {
        let step = n * SURFACE_BAND;
        !self.solid_at(p) && (self.solid_at(p + step) || self.solid_at(p - step))
    }
}

/// How far from a structure surface a flat Gaussian counts as lying on it (m).
const SURFACE_BAND: f32 = 0.02;

/// The convex parts (closed box meshes, W) of the solid the Gaussians `members` of `g` make
/// inside the box `obb`, leaving out those on `structure`; `None` when fewer than
/// `params.min_gaussians` of them are usable or they make no solid.
pub fn recover(
    g: &Gaussians,
    members: &[u32],
    obb: &Obb,
    structure: &Structure,
    params: &SplatBodyParams,
) -> Option<Vec<TriMesh>> {
    recover_solid(g, members, obb, structure, params, true)
}

/// [`recover`], filling what the skin encloses only with `fill`.
fn recover_solid(
    g: &Gaussians,
    members: &[u32],
    obb: &Obb,
    structure: &Structure,
    params: &SplatBodyParams,
    fill: bool,
) -> Option<Vec<TriMesh>> {
    let structure = &structure.near(obb, 2.0 * SURFACE_BAND);
    let kept: Vec<Kernel> = members
        .iter()
        .filter_map(|&i| Kernel::of(g, i as usize, obb, structure, params))
        .collect();
    if kept.iter().filter(|k| !k.barrier).count() < params.min_gaussians {
        return None;
    }
    let extent = obb.half_extents * 2.0;
    let mut voxel = params
        .voxel
        .max(extent.max_element() / (MAX_VOXELS - 2 * MARGIN) as f32);
    for attempt in 0..=COARSEN_TRIES {
        let grid = solid_of(&kept, obb, structure, voxel, fill);
        let boxes = grid.boxes();
        if boxes.is_empty() {
            return None;
        }
        if boxes.len() <= params.max_parts || attempt == COARSEN_TRIES {
            return Some(
                boxes
                    .iter()
                    .map(|b| TriMesh::from_obb(&grid.world_box(b, obb)))
                    .collect(),
            );
        }
        voxel *= 1.5;
    }
    None
}

/// One Gaussian in the object's frame: centre, the rotation from the object's frame to the
/// Gaussian's axes, and its reach along each axis (`reach`·σ).
struct Kernel {
    center: Vec3,
    to_axes: Mat3,
    radii: Vec3,
    /// A flat Gaussian on the structure: it stops the outside flood (an object a finger's
    /// width from a wall is still closed at its back) but is no skin of the object.
    barrier: bool,
}

impl Kernel {
    /// Gaussian `i` of `g` in the frame of `obb`, or `None` when too transparent or a flat piece
    /// of the structure.
    fn of(
        g: &Gaussians,
        i: usize,
        obb: &Obb,
        structure: &Structure,
        params: &SplatBodyParams,
    ) -> Option<Kernel> {
        let opacity = 1.0 / (1.0 + (-g.opacity_logit(i)).exp());
        if opacity < params.min_opacity {
            return None;
        }
        let p = Vec3::from_array(g.positions[i]);
        let scale = g.log_scale(i).exp();
        let rot = Mat3::from_quat(g.rotation(i));
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| scale[a].total_cmp(&scale[b]));
        let flat = scale[order[0]] < 0.3 * scale[order[1]];
        let barrier = flat && structure.holds(p, rot.col(order[0]));
        let to_local = Mat3::from_rotation_z(-obb.yaw);
        Some(Kernel {
            center: obb.to_local(p),
            to_axes: (to_local * rot).transpose(),
            radii: scale * params.reach,
            barrier,
        })
    }
}

/// A voxel grid in an object's frame: `solid[(z·ny + y)·nx + x]`.
struct VoxelGrid {
    dims: [usize; 3],
    /// Object-frame position of voxel (0, 0, 0)'s lower corner.
    origin: Vec3,
    voxel: f32,
    solid: Vec<bool>,
}

/// An inclusive box of voxel indices: `[x0, y0, z0]`..=`[x1, y1, z1]`.
type VoxelBox = ([usize; 3], [usize; 3]);

impl VoxelGrid {
    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    /// The solid voxels merged greedily into boxes: the first free voxel in x, y, z order
    /// grows along x, then y by whole rows, then z by whole layers.
    fn boxes(&self) -> Vec<VoxelBox> {
        let [nx, ny, nz] = self.dims;
        let mut used = vec![false; self.solid.len()];
        let open = |used: &[bool], x: usize, y: usize, z: usize| {
            let k = self.index(x, y, z);
            self.solid[k] && !used[k]
        };
        let mut boxes = Vec::new();
        for z0 in 0..nz {
            for y0 in 0..ny {
                for x0 in 0..nx {
                    if !open(&used, x0, y0, z0) {
                        continue;
                    }
                    let mut x1 = x0;
                    while x1 + 1 < nx && open(&used, x1 + 1, y0, z0) {
                        x1 += 1;
                    }
                    let mut y1 = y0;
                    while y1 + 1 < ny && (x0..=x1).all(|x| open(&used, x, y1 + 1, z0)) {
                        y1 += 1;
                    }
                    let mut z1 = z0;
                    while z1 + 1 < nz
                        && (y0..=y1).all(|y| (x0..=x1).all(|x| open(&used, x, y, z1 + 1)))
                    {
                        z1 += 1;
                    }
                    for z in z0..=z1 {
                        for y in y0..=y1 {
                            for x in x0..=x1 {
                                used[self.index(x, y, z)] = true;
                            }
                        }
                    }
                    boxes.push(([x0, y0, z0], [x1, y1, z1]));
                }
            }
        }
        boxes
    }

    /// True when no voxel of the layer just past face `side` (0 low, 1 high) of box `b` along
    /// `axis` is solid.
    fn exposed(&self, b: &VoxelBox, axis: usize, side: usize) -> bool {
        let (lo, hi) = (b.0, b.1);
        let layer = if side == 0 {
            match lo[axis].checked_sub(1) {
                Some(l) => l,
                None => return true,
            }
        } else if hi[axis] + 1 < self.dims[axis] {
            hi[axis] + 1
        } else {
            return true;
        };
        let (mut from, mut to) = (lo, hi);
        from[axis] = layer;
        to[axis] = layer;
        (from[2]..=to[2]).all(|z| {
            (from[1]..=to[1]).all(|y| (from[0]..=to[0]).all(|x| !self.solid[self.index(x, y, z)]))
        })
    }

    /// A box of voxels as an oriented box in W. Faces where the object's box cut the solid are
    /// that box's faces; other faces on the solid's outside are pulled in by half a voxel (at
    /// most a quarter of the box's width): a skin voxel is marked when its centre is near the
    /// surface, so on average the voxels reach half a voxel past it.
    fn world_box(&self, b: &VoxelBox, obb: &Obb) -> Obb {
        let mut lo = self.origin + Vec3::from_array(b.0.map(|v| v as f32)) * self.voxel;
        let mut hi = self.origin + Vec3::from_array(b.1.map(|v| v as f32 + 1.0)) * self.voxel;
        let he = obb.half_extents;
        for axis in 0..3 {
            let pull = (self.voxel * 0.5).min((hi[axis] - lo[axis]) * 0.25);
            // A face where the solid was cut by the box is the box's face, exactly.
            if lo[axis] + self.voxel * 0.5 - self.voxel < -he[axis] {
                lo[axis] = lo[axis].max(-he[axis]);
            } else if self.exposed(b, axis, 0) {
                lo[axis] += pull;
            }
            if hi[axis] - self.voxel * 0.5 + self.voxel > he[axis] {
                hi[axis] = hi[axis].min(he[axis]);
            } else if self.exposed(b, axis, 1) {
                hi[axis] -= pull;
            }
        }
        Obb {
            center: to_world(obb, (lo + hi) * 0.5),
            half_extents: (hi - lo) * 0.5,
            yaw: obb.yaw,
        }
    }
}

/// The world point of `local`, a point in the frame of `obb` (the inverse of [`Obb::to_local`]).
fn to_world(obb: &Obb, local: Vec3) -> Vec3 {
    let (c, s) = (obb.yaw.cos(), obb.yaw.sin());
    obb.center
        + Vec3::new(
            c * local.x - s * local.y,
            s * local.x + c * local.y,
            local.z,
        )
}

/// The closed solid of `kernels` inside `obb` at `voxel`, closed by `structure` where it meets
/// it; what the skin encloses is filled only with `fill`.
fn solid_of(
    kernels: &[Kernel],
    obb: &Obb,
    structure: &Structure,
    voxel: f32,
    fill: bool,
) -> VoxelGrid {
    let half = obb.half_extents + Vec3::splat(MARGIN as f32 * voxel);
    let dims = (half * 2.0 / voxel)
        .ceil()
        .to_array()
        .map(|n| (n as usize).clamp(1, MAX_VOXELS + 2 * MARGIN));
    let origin = -Vec3::from_array(dims.map(|n| n as f32)) * voxel * 0.5;
    let centre = |x: usize, y: usize, z: usize| {
        origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * voxel
    };
    let last = Vec3::from_array(dims.map(|n| n as f32 - 1.0));
    let mut skin = vec![false; dims[0] * dims[1] * dims[2]];
    let mut barrier = skin.clone();
    for k in kernels {
        // Half a voxel more on every axis: a disc thinner than a voxel still holds the centre
        // of each voxel it passes through.
        let radii = k.radii + Vec3::splat(voxel * 0.5);
        let reach = Vec3::splat(radii.max_element());
        let lo = ((k.center - reach - origin) / voxel).floor();
        let hi = ((k.center + reach - origin) / voxel).floor();
        if lo.cmpgt(last).any() || hi.cmplt(Vec3::ZERO).any() {
            continue;
        }
        let range = |a: usize| lo[a].max(0.0) as usize..=hi[a].min(last[a]) as usize;
        for z in range(2) {
            for y in range(1) {
                for x in range(0) {
                    let q = k.to_axes * (centre(x, y, z) - k.center) / radii;
                    if q.length_squared() <= 1.0 {
                        let mask = if k.barrier { &mut barrier } else { &mut skin };
                        mask[(z * dims[1] + y) * dims[0] + x] = true;
                    }
                }
            }
        }
    }
    let mut grown = dilate(&skin, dims);
    let mut structural = vec![false; skin.len()];
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let k = (z * dims[1] + y) * dims[0] + x;
                structural[k] = structure.solid_at(to_world(obb, centre(x, y, z)));
                grown[k] |= structural[k] || barrier[k];
            }
        }
    }
    let filled: Vec<bool> = if fill {
        flood_outside(&grown, dims).iter().map(|&o| !o).collect()
    } else {
        grown
            .iter()
            .zip(&structural)
            .map(|(&g, &s)| g && !s)
            .collect()
    };
    let closed = erode(&filled, dims);
    let mut solid = vec![false; skin.len()];
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let k = (z * dims[1] + y) * dims[0] + x;
                let inside = centre(x, y, z).abs().cmple(obb.half_extents).all();
                solid[k] = inside && !structural[k] && (closed[k] || skin[k]);
            }
        }
    }
    VoxelGrid {
        dims,
        origin,
        voxel,
        solid,
    }
}

/// The 26-neighbourhood (and the voxel itself) of every voxel, clipped to the grid.
fn neighbourhood(
    dims: [usize; 3],
    x: usize,
    y: usize,
    z: usize,
) -> impl Iterator<Item = Option<usize>> {
    (0..27).map(move |n| {
        let d = [n % 3, (n / 3) % 3, n / 9];
        let p = [x + d[0], y + d[1], z + d[2]];
        (p[0] >= 1
            && p[1] >= 1
            && p[2] >= 1
            && p[0] <= dims[0]
            && p[1] <= dims[1]
            && p[2] <= dims[2])
            .then(|| ((p[2] - 1) * dims[1] + p[1] - 1) * dims[0] + p[0] - 1)
    })
}

/// Voxels set or next to a set voxel (26-neighbourhood).
fn dilate(set: &[bool], dims: [usize; 3]) -> Vec<bool> {
    morph(set, dims, false)
}

/// Voxels whose whole 26-neighbourhood is set (outside the grid counts as not set).
fn erode(set: &[bool], dims: [usize; 3]) -> Vec<bool> {
    morph(set, dims, true)
}

/// Dilation (any neighbour set) or, with `every`, erosion (every neighbour set).
fn morph(set: &[bool], dims: [usize; 3], every: bool) -> Vec<bool> {
    let mut out = vec![false; set.len()];
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let mut n = neighbourhood(dims, x, y, z).map(|k| k.is_some_and(|k| set[k]));
                out[(z * dims[1] + y) * dims[0] + x] =
                    if every { n.all(|v| v) } else { n.any(|v| v) };
            }
        }
    }
    out
}

/// The voxels not in `wall` that the grid's border reaches through face neighbours.
fn flood_outside(wall: &[bool], dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let mut outside = vec![false; wall.len()];
    let mut stack = Vec::new();
    let visit = |k: usize, outside: &mut Vec<bool>, stack: &mut Vec<usize>| {
        if !wall[k] && !outside[k] {
            outside[k] = true;
            stack.push(k);
        }
    };
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                if x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz {
                    visit((z * ny + y) * nx + x, &mut outside, &mut stack);
                }
            }
        }
    }
    while let Some(k) = stack.pop() {
        let (x, y, z) = (k % nx, (k / nx) % ny, k / (nx * ny));
        if x > 0 {
            visit(k - 1, &mut outside, &mut stack);
        }
        if x + 1 < nx {
            visit(k + 1, &mut outside, &mut stack);
        }
        if y > 0 {
            visit(k - nx, &mut outside, &mut stack);
        }
        if y + 1 < ny {
            visit(k + nx, &mut outside, &mut stack);
        }
        if z > 0 {
            visit(k - nx * ny, &mut outside, &mut stack);
        }
        if z + 1 < nz {
            visit(k + nx * ny, &mut outside, &mut stack);
        }
    }
    outside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_boxes_cover_the_solid_voxels_once() {
        let dims = [7, 5, 4];
        let n = dims[0] * dims[1] * dims[2];
        // A seeded scatter of solid voxels.
        let solid: Vec<bool> = (0..n as u64)
            .map(|i| (i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 61) < 5)
            .collect();
        let grid = VoxelGrid {
            dims,
            origin: Vec3::ZERO,
            voxel: 1.0,
            solid: solid.clone(),
        };
        let mut covered = vec![0u8; n];
        for (lo, hi) in grid.boxes() {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        covered[grid.index(x, y, z)] += 1;
                    }
                }
            }
        }
        for k in 0..n {
            assert_eq!(covered[k], u8::from(solid[k]), "voxel {k}");
        }
    }

    #[test]
    fn a_closed_skin_is_filled_and_an_open_one_is_not() {
        let dims = [9, 9, 9];
        let at = |x: usize, y: usize, z: usize| (z * 9 + y) * 9 + x;
        let mut shell = vec![false; 729];
        for z in 2..=6 {
            for y in 2..=6 {
                for x in 2..=6 {
                    let edge = [x, y, z].iter().any(|&c| c == 2 || c == 6);
                    shell[at(x, y, z)] = edge;
                }
            }
        }
        let outside = flood_outside(&shell, dims);
        assert!(
            !outside[at(4, 4, 4)],
            "the inside of a closed shell is not reached"
        );
        // Open one face: the flood gets in.
        for y in 3..=5 {
            for x in 3..=5 {
                shell[at(x, y, 6)] = false;
            }
        }
        assert!(flood_outside(&shell, dims)[at(4, 4, 4)]);
        // Growing then shrinking a voxel keeps a lone voxel's 3×3×3 block only where it was.
        let mut one = vec![false; 729];
        one[at(4, 4, 4)] = true;
        assert_eq!(erode(&dilate(&one, dims), dims), one);
    }
}
