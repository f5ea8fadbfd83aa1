//! The published collision bodies: SAGE-Bench's `{scene}_collision.usd` (USDC or USDA), read
//! as the scene's physics layer.
//!
//! The file holds one `UsdGeom.Mesh` prim per convex part, under nested `Xform`s. [`read`]
//! composes each mesh prim's transform (every `xformOp` of `xformOpOrder`, the stage's
//! `metersPerUnit` and `upAxis`) into metres, Z up. [`attach`] then decides the file's frame
//! from the data — W as the InteriorGS files are, or S, W turned 180° about Z, the frame the
//! published Isaac template puts the file in — by how well the parts agree with the
//! `labels.json` boxes, and gives each part to the object it belongs to: by name where a prim's
//! path names an object's `ins_id`, else by the box it lies in. Parts of no object (walls,
//! floors) become the scene's structure parts. docs/scene-format.md ("The published collision
//! file") says the rules.

mod usdc;

use crate::mesh::TriMesh;
use crate::object::{BodyParts, BodySource, Object};
use glam::{DMat4, DQuat, DVec3, Vec3};
use openusd::{sdf, usd};
use sage_core::{Aabb, Error, MAX_COORDINATE, Obb, Result, within_bounds};
use sage_io::limits::{COLLISION_MB, MESH_MB};
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The end of a published collision file's name: `{scene}_collision.usd`.
pub const SUFFIX: &str = "_collision";

/// Extensions looked for after [`SUFFIX`], in this order (the published files are `.usd`).
pub const EXTENSIONS: [&str; 3] = ["usd", "usdc", "usda"];

/// How far (m) a part may reach out of a label box and still count as inside it: the boxes are
/// annotations, the parts hulls of the artists' meshes.
pub const BOX_TOLERANCE: f32 = 0.05;

/// The share of a part's extent that must lie in a box for the part to be that box's object.
pub const INSIDE_SHARE: f32 = 0.5;

/// One mesh prim of a collision file: its path and its triangles, composed into metres, Z up,
/// in the file's own frame (see [`CollisionFrame`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionPrim {
    /// The prim's path in the stage (`/World/ins_12/part_0`).
    pub path: String,
    /// The triangles (polygons fanned), transforms applied.
    pub mesh: TriMesh,
}

/// A collision file as read: its mesh prims and the stage units applied to them.
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionFile {
    /// The file read.
    pub path: PathBuf,
    /// Mesh prims with at least one triangle, in traversal order.
    pub prims: Vec<CollisionPrim>,
    /// Mesh prims without points or faces (skipped).
    pub empty: usize,
    /// The stage's `metersPerUnit` (1 when unauthored; see [`read`]).
    pub meters_per_unit: f64,
    /// The stage's `upAxis` (`Z` when unauthored).
    pub up_axis: String,
}

/// The frame a collision file's coordinates are in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum CollisionFrame {
    /// The InteriorGS world frame (the frame of `labels.json`): used as read.
    W,
    /// W turned 180° about Z (the published Isaac template's frame): turned back on load.
    S,
}

impl CollisionFrame {
    /// The frame's letter (`W`, `S`).
    pub fn as_str(self) -> &'static str {
        match self {
            CollisionFrame::W => "W",
            CollisionFrame::S => "S",
        }
    }

    /// A point of this frame in W.
    pub fn to_w(self, p: Vec3) -> Vec3 {
        match self {
            CollisionFrame::W => p,
            CollisionFrame::S => Vec3::new(-p.x, -p.y, p.z),
        }
    }
}

/// How well a collision file's parts agree with the label boxes in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameAgreement {
    /// Share of the parts lying inside a box (at least [`INSIDE_SHARE`] of their extent along
    /// every axis, boxes grown by [`BOX_TOLERANCE`]).
    pub inside: f32,
    /// Share of the parts overlapping a box at all.
    pub overlapping: f32,
}

/// How a collision file was used: the frame chosen and why, and where its parts went (the
/// load report's `collision`; `scene info` prints it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CollisionReport {
    /// The file read.
    pub file: String,
    /// The frame its coordinates were taken to be in.
    pub frame: CollisionFrame,
    /// True when the frame was measured against the label boxes; false when it was assumed
    /// (W: the scene has no boxes to compare with).
    pub frame_measured: bool,
    /// Agreement with the boxes read as W (`None` without boxes).
    pub agreement_w: Option<FrameAgreement>,
    /// Agreement with the boxes turned 180° about Z, frame S (`None` without boxes).
    pub agreement_s: Option<FrameAgreement>,
    /// The stage's `metersPerUnit`.
    pub meters_per_unit: f64,
    /// The stage's `upAxis`.
    pub up_axis: String,
    /// Mesh prims used (each one convex part).
    pub parts: usize,
    /// Empty mesh prims skipped.
    pub empty: usize,
    /// Parts given to an object because their path names its `ins_id`.
    pub by_name: usize,
    /// Parts given to an object because they lie in its box.
    pub by_box: usize,
    /// Parts of no object: the structure (walls, floors, ceilings).
    pub structure: usize,
    /// Parts whose path names an object that they lie wholly outside of: the name was not
    /// trusted and the part placed by its box instead.
    pub names_rejected: usize,
    /// Objects given parts.
    pub objects: usize,
    /// Objects of the scene that got no part (they keep their mesh or box).
    pub objects_without: usize,
}

/// The published collision file of the scene folder `dir` named `scene_name`, if present:
/// `{scene_name}_collision.usd`, or with the numeric id after the last `_` of the name
/// (`0001_839920` → `839920_collision.usd`, as SAGE-Bench names it), `.usd`, `.usdc` or
/// `.usda`.
pub fn find_in_folder(dir: &Path, scene_name: &str) -> Option<PathBuf> {
    names(scene_name)
        .into_iter()
        .map(|n| dir.join(n))
        .find(|p| p.is_file())
}

/// The file names [`find_in_folder`] looks for, in order.
pub fn names(scene_name: &str) -> Vec<String> {
    let mut stems = vec![scene_name.to_string()];
    if let Some((_, id)) = scene_name.rsplit_once('_')
        && !id.is_empty()
        && id.chars().all(|c| c.is_ascii_digit())
    {
        stems.push(id.to_string());
    }
    stems
        .iter()
        .flat_map(|s| EXTENSIONS.iter().map(move |e| format!("{s}{SUFFIX}.{e}")))
        .collect()
}

/// Reads the mesh prims of a collision file (USDC, USDA or USDZ, told from the content), each
/// composed with the transforms of its prim and ancestors and the stage's units, Z up.
///
/// `metersPerUnit` is read as authored and taken as 1 when unauthored (SAGE's stages are in
/// metres; USD's own fallback of 0.01 would shrink an unannotated file a hundredfold).
///
/// # Errors
///
/// A file over `SAGE3D_MAX_COLLISION_MB`, a USDC file (or a USDC layer of a USDZ) whose sections
/// declare more than their bytes hold (checked before the USD reader allocates what they
/// declare), one the USD reader refuses (truncated, not USD), a mesh prim with non-finite
/// points, out-of-range indices or face counts that do not add up, an unknown or ill-typed
/// `xformOp`, decoded meshes over `SAGE3D_MAX_MESH_MB`, or a stage with no mesh prim: each names
/// the file and, where one is at fault, the prim.
pub fn read(path: &Path) -> Result<CollisionFile> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    COLLISION_MB
        .check(meta.len(), "file size")
        .map_err(|e| e.in_file(path))?;
    let path_str = path
        .to_str()
        .ok_or_else(|| Error::invalid("the path is not valid UTF-8").in_file(path))?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let declared = if bytes.starts_with(usdc::MAGIC) {
        usdc::check(&bytes)
    } else if bytes.starts_with(usdc::ZIP_MAGIC) {
        usdc::check_package(&bytes, COLLISION_MB.get()?)
    } else {
        Ok(())
    };
    declared.map_err(|e| {
        Error::format("(file)", format!("not a readable USD file: {e}")).in_file(path)
    })?;
    // The reader is a large third-party parser: a panic inside it on a hostile file becomes
    // an error naming the file, never a crash of the caller.
    let stage = match quietly(|| usd::Stage::open(path_str)) {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => {
            return Err(
                Error::format("(file)", format!("not a readable USD file: {e:#}")).in_file(path),
            );
        }
        Err(failure) => return Err(failure.in_file(path)),
    };
    let mut file = match quietly(std::panic::AssertUnwindSafe(|| compose(&stage))) {
        Ok(r) => r.map_err(|e| e.in_file(path))?,
        Err(failure) => return Err(failure.in_file(path)),
    };
    file.path = path.to_path_buf();
    if file.prims.is_empty() {
        return Err(Error::format(
            "(stage)",
            format!(
                "no mesh prim with triangles ({} empty mesh prims): not a collision file",
                file.empty
            ),
        )
        .in_file(path));
    }
    Ok(file)
}

/// Runs `f`, a call into the USD reader, turning a panic into an error that carries its
/// message, without the panic hook printing it (on this thread; the hook is chained, so other
/// threads' panics print as before).
fn quietly<T>(f: impl FnOnce() -> T + std::panic::UnwindSafe) -> std::result::Result<T, Error> {
    use std::cell::Cell;
    thread_local! {
        static QUIET: Cell<bool> = const { Cell::new(false) };
    }
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Cell::get) {
                previous(info);
            }
        }));
    });
    QUIET.with(|q| q.set(true));
    let result = std::panic::catch_unwind(f);
    QUIET.with(|q| q.set(false));
    result.map_err(|payload| {
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("no message");
        Error::format(
            "(file)",
            format!("the USD reader failed on this file ({message})"),
        )
    })
}

/// Walks the stage and composes its mesh prims.
fn compose(stage: &usd::Stage) -> Result<CollisionFile> {
    let meters_per_unit = match stage.stage_metadata("metersPerUnit") {
        Ok(Some(v)) => scalar(&v).ok_or_else(|| {
            Error::format("metersPerUnit", format!("expected a number, found {v:?}"))
        })?,
        Ok(None) => 1.0,
        Err(e) => return Err(Error::format("metersPerUnit", format!("{e:#}"))),
    };
    if !(meters_per_unit.is_finite() && meters_per_unit > 0.0) {
        return Err(Error::format(
            "metersPerUnit",
            format!("must be a positive number, found {meters_per_unit}"),
        ));
    }
    let up_axis = match stage.stage_metadata("upAxis") {
        Ok(Some(sdf::Value::Token(t))) => t.as_str().to_string(),
        Ok(Some(sdf::Value::String(s))) => s,
        Ok(Some(v)) => {
            return Err(Error::format(
                "upAxis",
                format!("expected Y or Z, found {v:?}"),
            ));
        }
        Ok(None) => "Z".to_string(),
        Err(e) => return Err(Error::format("upAxis", format!("{e:#}"))),
    };
    // Y up is turned to Z up by +90° about X, as USD's own conversion does.
    let up = match up_axis.as_str() {
        "Z" => DMat4::IDENTITY,
        "Y" => DMat4::from_rotation_x(std::f64::consts::FRAC_PI_2),
        other => {
            return Err(Error::format(
                "upAxis",
                format!("expected Y or Z, found '{other}'"),
            ));
        }
    };
    let stage_to_world = up * DMat4::from_scale(DVec3::splat(meters_per_unit));
    let mut paths = Vec::new();
    stage
        .traverse(usd::PrimPredicate::DEFAULT_PROXIES, |p| {
            paths.push(p.clone())
        })
        .map_err(|e| Error::format("(stage)", format!("cannot traverse: {e:#}")))?;
    let mut worlds: HashMap<String, DMat4> = HashMap::new();
    let mut file = CollisionFile {
        path: PathBuf::new(),
        prims: Vec::new(),
        empty: 0,
        meters_per_unit,
        up_axis,
    };
    let budget = MESH_MB.get()?;
    let mut decoded = 0u64;
    for p in paths {
        let prim = stage.prim(p.clone());
        let name = p.as_str().to_string();
        let local = local_transform(&prim, &name)?;
        let parent = parent_path(&name)
            .and_then(|q| worlds.get(q).copied())
            .unwrap_or(DMat4::IDENTITY);
        let world = match local {
            Local::Reset(m) => m,
            Local::Relative(m) => parent * m,
        };
        worlds.insert(name.clone(), world);
        let type_name = prim
            .type_name()
            .map_err(|e| Error::format(name.clone(), format!("{e:#}")))?;
        if type_name.as_ref().map(|t| t.as_str()) != Some("Mesh") {
            continue;
        }
        let mesh = read_mesh(&prim, &name)?;
        decoded += (mesh.positions.len() * 12 + mesh.triangles.len() * 12) as u64;
        if decoded > budget {
            MESH_MB.check(decoded, &name)?;
        }
        if mesh.triangles.is_empty() {
            file.empty += 1;
            continue;
        }
        let m = (stage_to_world * world).as_mat4();
        let mesh = mesh.transformed(&m);
        if let Some(i) = mesh.positions.iter().position(|v| !within_bounds(*v)) {
            return Err(Error::format(
                format!("{name}.points[{i}]"),
                format!(
                    "not finite or past ±{MAX_COORDINATE} m once transformed (a huge point, or a degenerate or huge xformOp)"
                ),
            ));
        }
        file.prims.push(CollisionPrim { path: name, mesh });
    }
    Ok(file)
}

/// The parent of an absolute prim path (`/A/B` → `/A`), `None` for a root prim.
fn parent_path(path: &str) -> Option<&str> {
    let i = path.rfind('/')?;
    (i > 0).then(|| &path[..i])
}

/// A prim's own transform: relative to its parent, or replacing it (`!resetXformStack!`).
enum Local {
    Relative(DMat4),
    Reset(DMat4),
}

/// Composes a prim's `xformOpOrder` (column vectors: the first op listed is the outermost).
fn local_transform(prim: &usd::Prim, name: &str) -> Result<Local> {
    let order = match get(prim, name, "xformOpOrder")? {
        None => return Ok(Local::Relative(DMat4::IDENTITY)),
        Some(sdf::Value::TokenVec(v)) => v.iter().map(|t| t.as_str().to_string()).collect(),
        Some(sdf::Value::StringVec(v)) => v,
        Some(sdf::Value::TokenListOp(op)) => op
            .flatten()
            .iter()
            .map(|t| t.as_str().to_string())
            .collect(),
        Some(v) => {
            return Err(Error::format(
                format!("{name}.xformOpOrder"),
                format!("expected token[], found {v:?}"),
            ));
        }
    };
    let mut m = DMat4::IDENTITY;
    let mut reset = false;
    for (i, op) in order.iter().enumerate() {
        if op == "!resetXformStack!" {
            if i != 0 {
                return Err(Error::format(
                    format!("{name}.xformOpOrder[{i}]"),
                    "!resetXformStack! may only come first",
                ));
            }
            reset = true;
            continue;
        }
        m *= op_matrix(prim, name, op)?;
    }
    if !m.is_finite() {
        return Err(Error::format(
            format!("{name}.xformOpOrder"),
            "the ops compose to a matrix that is not finite",
        ));
    }
    Ok(if reset {
        Local::Reset(m)
    } else {
        Local::Relative(m)
    })
}

/// The matrix of one entry of `xformOpOrder` (`xformOp:rotateZ:spin`, `!invert!xformOp:…`).
fn op_matrix(prim: &usd::Prim, name: &str, op: &str) -> Result<DMat4> {
    let (invert, attr) = match op.strip_prefix("!invert!") {
        Some(a) => (true, a),
        None => (false, op),
    };
    let at = || format!("{name}.{attr}");
    let kind = attr
        .strip_prefix("xformOp:")
        .and_then(|s| s.split(':').next())
        .ok_or_else(|| {
            Error::format(
                at(),
                "an xformOpOrder entry must name an xformOp:… attribute",
            )
        })?;
    let Some(value) = get(prim, name, attr)? else {
        return Err(Error::format(
            at(),
            "listed in xformOpOrder but has no value",
        ));
    };
    let ill = |want: &str| Error::format(at(), format!("expected {want}, found {value:?}"));
    let deg = |v: f64| v.to_radians();
    let m = match kind {
        "translate" => DMat4::from_translation(vec3(&value).ok_or_else(|| ill("a 3-vector"))?),
        "translateX" | "translateY" | "translateZ" => {
            let s = scalar(&value).ok_or_else(|| ill("a number"))?;
            DMat4::from_translation(axis_vec(kind, s, 0.0))
        }
        "scale" => DMat4::from_scale(vec3(&value).ok_or_else(|| ill("a 3-vector"))?),
        "scaleX" | "scaleY" | "scaleZ" => {
            let s = scalar(&value).ok_or_else(|| ill("a number"))?;
            DMat4::from_scale(axis_vec(kind, s, 1.0))
        }
        "rotateX" => DMat4::from_rotation_x(deg(scalar(&value).ok_or_else(|| ill("a number"))?)),
        "rotateY" => DMat4::from_rotation_y(deg(scalar(&value).ok_or_else(|| ill("a number"))?)),
        "rotateZ" => DMat4::from_rotation_z(deg(scalar(&value).ok_or_else(|| ill("a number"))?)),
        "rotateXYZ" | "rotateXZY" | "rotateYXZ" | "rotateYZX" | "rotateZXY" | "rotateZYX" => {
            let v = vec3(&value).ok_or_else(|| ill("a 3-vector of degrees"))?;
            // `rotateXYZ` turns about X first, then Y, then Z: with column vectors the first
            // axis is the innermost factor.
            kind[6..].chars().fold(DMat4::IDENTITY, |acc, axis| {
                let r = match axis {
                    'X' => DMat4::from_rotation_x(deg(v.x)),
                    'Y' => DMat4::from_rotation_y(deg(v.y)),
                    _ => DMat4::from_rotation_z(deg(v.z)),
                };
                r * acc
            })
        }
        "orient" => {
            let q = quat(&value).ok_or_else(|| ill("a quaternion"))?;
            if !(q.is_finite() && q.length() > 1e-12) {
                return Err(ill("a non-zero finite quaternion"));
            }
            DMat4::from_quat(q.normalize())
        }
        "transform" => match &value {
            // USD's matrices act on row vectors (translation in the last row): read row-major,
            // they are the column-major matrix of the same transform.
            sdf::Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
            _ => return Err(ill("a matrix4d")),
        },
        other => {
            return Err(Error::format(
                at(),
                format!("unknown xformOp kind '{other}'"),
            ));
        }
    };
    if invert {
        if m.determinant().abs() < 1e-18 {
            return Err(Error::format(at(), "!invert! of a singular op"));
        }
        Ok(m.inverse())
    } else {
        Ok(m)
    }
}

/// `s` on the axis a `…X`/`…Y`/`…Z` op names, `other` on the rest.
fn axis_vec(kind: &str, s: f64, other: f64) -> DVec3 {
    let mut v = DVec3::splat(other);
    match kind.as_bytes().last() {
        Some(b'X') => v.x = s,
        Some(b'Y') => v.y = s,
        _ => v.z = s,
    }
    v
}

/// An attribute's composed default value.
fn get(prim: &usd::Prim, name: &str, attr: &str) -> Result<Option<sdf::Value>> {
    prim.attribute(attr)
        .get::<sdf::Value>()
        .map_err(|e| Error::format(format!("{name}.{attr}"), format!("{e:#}")))
}

fn scalar(v: &sdf::Value) -> Option<f64> {
    match v {
        sdf::Value::Double(d) => Some(*d),
        sdf::Value::Float(f) => Some(f64::from(*f)),
        sdf::Value::Half(h) => Some(f64::from(h.to_f32())),
        sdf::Value::Int(i) => Some(f64::from(*i)),
        sdf::Value::Int64(i) => Some(*i as f64),
        _ => None,
    }
}

fn vec3(v: &sdf::Value) -> Option<DVec3> {
    match v {
        sdf::Value::Vec3d(a) => Some(DVec3::new(a.x, a.y, a.z)),
        sdf::Value::Vec3f(a) => Some(DVec3::new(a.x.into(), a.y.into(), a.z.into())),
        sdf::Value::Vec3h(a) => Some(DVec3::new(
            a.x.to_f32().into(),
            a.y.to_f32().into(),
            a.z.to_f32().into(),
        )),
        sdf::Value::Vec3i(a) => Some(DVec3::new(a.x.into(), a.y.into(), a.z.into())),
        _ => None,
    }
}

fn quat(v: &sdf::Value) -> Option<DQuat> {
    match v {
        sdf::Value::Quatd(q) => Some(DQuat::from_xyzw(q.x, q.y, q.z, q.w)),
        sdf::Value::Quatf(q) => Some(DQuat::from_xyzw(
            q.x.into(),
            q.y.into(),
            q.z.into(),
            q.w.into(),
        )),
        sdf::Value::Quath(q) => Some(DQuat::from_xyzw(
            q.x.to_f32().into(),
            q.y.to_f32().into(),
            q.z.to_f32().into(),
            q.w.to_f32().into(),
        )),
        _ => None,
    }
}

/// A mesh prim's points and faces (polygons fanned into triangles), in the prim's own space.
fn read_mesh(prim: &usd::Prim, name: &str) -> Result<TriMesh> {
    let points: Vec<Vec3> = match get(prim, name, "points")? {
        None => Vec::new(),
        Some(sdf::Value::Vec3fVec(v)) => v.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        Some(sdf::Value::Vec3dVec(v)) => v
            .iter()
            .map(|p| Vec3::new(p.x as f32, p.y as f32, p.z as f32))
            .collect(),
        Some(sdf::Value::Vec3hVec(v)) => v
            .iter()
            .map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()))
            .collect(),
        Some(v) => {
            return Err(Error::format(
                format!("{name}.points"),
                format!("expected point3f[], found {}", kind_of(&v)),
            ));
        }
    };
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(Error::format(
            format!("{name}.points[{i}]"),
            "coordinate is not finite",
        ));
    }
    let counts = ints(
        get(prim, name, "faceVertexCounts")?,
        name,
        "faceVertexCounts",
    )?;
    let indices = ints(
        get(prim, name, "faceVertexIndices")?,
        name,
        "faceVertexIndices",
    )?;
    let n = points.len() as i64;
    if let Some(i) = indices.iter().position(|&k| k < 0 || k >= n) {
        return Err(Error::format(
            format!("{name}.faceVertexIndices[{i}]"),
            format!(
                "vertex index {} out of range (the mesh has {n} points)",
                indices[i]
            ),
        ));
    }
    let mut triangles = Vec::new();
    let mut at = 0usize;
    for (f, &c) in counts.iter().enumerate() {
        if c < 3 {
            return Err(Error::format(
                format!("{name}.faceVertexCounts[{f}]"),
                format!("a face needs at least 3 vertices, found {c}"),
            ));
        }
        let c = c as usize;
        let Some(face) = indices.get(at..at + c) else {
            return Err(Error::format(
                format!("{name}.faceVertexCounts"),
                format!(
                    "the counts add up to more than the {} face vertex indices",
                    indices.len()
                ),
            ));
        };
        for k in 1..c - 1 {
            triangles.push([face[0] as u32, face[k] as u32, face[k + 1] as u32]);
        }
        at += c;
    }
    if at != indices.len() {
        return Err(Error::format(
            format!("{name}.faceVertexCounts"),
            format!(
                "the counts add up to {at}, but there are {} face vertex indices",
                indices.len()
            ),
        ));
    }
    Ok(TriMesh {
        positions: points,
        triangles,
    })
}

/// An integer array attribute (`int[]`), empty when unauthored.
fn ints(v: Option<sdf::Value>, name: &str, attr: &str) -> Result<Vec<i64>> {
    Ok(match v {
        None => Vec::new(),
        Some(sdf::Value::IntVec(v)) => v.into_iter().map(i64::from).collect(),
        Some(sdf::Value::UintVec(v)) => v.into_iter().map(i64::from).collect(),
        Some(sdf::Value::Int64Vec(v)) => v,
        Some(v) => {
            return Err(Error::format(
                format!("{name}.{attr}"),
                format!("expected int[], found {}", kind_of(&v)),
            ));
        }
    })
}

/// A value's variant name, for messages (not its possibly huge content).
fn kind_of(v: &sdf::Value) -> String {
    let s = format!("{v:?}");
    s.split(['(', ' ', '{']).next().unwrap_or("?").to_string()
}

/// How much of a part lies in a box: the product over the box's axes of the share of the
/// part's extent inside the box grown by [`BOX_TOLERANCE`] (an axis where the part is flat
/// counts 1 inside, 0 outside). 0 = apart, 1 = wholly inside.
pub fn share_inside(points: &[Vec3], obb: &Obb) -> f32 {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for p in points {
        let l = obb.to_local(*p);
        lo = lo.min(l);
        hi = hi.max(l);
    }
    if lo.x > hi.x {
        return 0.0;
    }
    let h = obb.half_extents + Vec3::splat(BOX_TOLERANCE);
    (0..3)
        .map(|a| {
            let (a0, a1, b) = (lo[a], hi[a], h[a]);
            let len = a1 - a0;
            if len < 1e-5 {
                return f32::from(u8::from(a0.abs() <= b));
            }
            ((a1.min(b) - a0.max(-b)).max(0.0) / len).min(1.0)
        })
        .product()
}

/// The parts of each prim in W for `frame`, with their bounds.
fn in_frame(file: &CollisionFile, frame: CollisionFrame) -> Vec<(Vec<Vec3>, Aabb)> {
    file.prims
        .iter()
        .map(|p| {
            let pts: Vec<Vec3> = p.mesh.positions.iter().map(|&v| frame.to_w(v)).collect();
            let b = Aabb::from_points(pts.iter().copied());
            (pts, b)
        })
        .collect()
}

/// For each part, the best box: its object index and share inside (0 when no box overlaps).
/// Ties go to the smaller box (a cup on a table is the cup's).
fn best_boxes(parts: &[(Vec<Vec3>, Aabb)], boxes: &[(Obb, Aabb)]) -> Vec<(Option<usize>, f32)> {
    parts
        .iter()
        .map(|(pts, b)| {
            let mut best: (Option<usize>, f32) = (None, 0.0);
            for (i, (obb, ob)) in boxes.iter().enumerate() {
                let t = Vec3::splat(BOX_TOLERANCE);
                if (b.min - t).cmpgt(ob.max).any() || (b.max + t).cmplt(ob.min).any() {
                    continue;
                }
                let s = share_inside(pts, obb);
                let better = match best.0 {
                    None => s > 0.0,
                    Some(j) => {
                        s > best.1 + 1e-6
                            || ((s - best.1).abs() <= 1e-6 && obb.volume() < boxes[j].0.volume())
                    }
                };
                if better {
                    best = (Some(i), s);
                }
            }
            best
        })
        .collect()
}

fn agreement(best: &[(Option<usize>, f32)]) -> FrameAgreement {
    let n = best.len().max(1) as f32;
    FrameAgreement {
        inside: best.iter().filter(|b| b.1 >= INSIDE_SHARE).count() as f32 / n,
        overlapping: best.iter().filter(|b| b.0.is_some()).count() as f32 / n,
    }
}

/// A prim path component written as USD writes an arbitrary id as a prim name: characters
/// outside `[A-Za-z0-9_]` become `_`, and a leading digit gets a `_` before it.
pub fn identifier(id: &str) -> String {
    let mut s: String = id
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

/// The objects a prim path names: a path component that is an `ins_id` (as is, or as a prim
/// name: [`identifier`]), or one with a word and an optional `_` before it (`ins_12`,
/// `obj12`, `Instance_12`). Outermost first, each object once.
fn named_objects(path: &str, ids: &HashMap<String, Option<usize>>) -> Vec<usize> {
    let mut found = Vec::new();
    for comp in path.split('/').filter(|c| !c.is_empty()) {
        let word = comp.trim_start_matches(|c: char| c.is_ascii_alphabetic());
        let rest = word.strip_prefix('_').unwrap_or(word);
        for key in [comp, word, rest] {
            if key.is_empty() {
                continue;
            }
            if let Some(Some(i)) = ids.get(key)
                && !found.contains(i)
            {
                found.push(*i);
                break;
            }
        }
    }
    found
}

/// What [`attach`] did to a scene's objects: the structure parts and the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Attached {
    /// Parts of no object, in W.
    pub structure: Option<BodyParts>,
    /// How the file was used.
    pub report: CollisionReport,
}

/// Decides the frame of `file` against the objects' boxes, turns its parts into W and gives
/// them to `objects` (each object given parts gets `body = Some(BodyParts { source:
/// Published, … })`, replacing any other given body; the published parts are the bodies the
/// paper's agents collided with). Parts of no object are returned as the structure.
pub fn attach(file: &CollisionFile, objects: &mut [Object]) -> Attached {
    let boxes: Vec<(Obb, Aabb)> = objects.iter().map(|o| (o.obb, o.obb.aabb())).collect();
    let (frame, measured, agreement_w, agreement_s, parts, best) = if boxes.is_empty() {
        let parts = in_frame(file, CollisionFrame::W);
        let best = vec![(None, 0.0); parts.len()];
        (CollisionFrame::W, false, None, None, parts, best)
    } else {
        let pw = in_frame(file, CollisionFrame::W);
        let ps = in_frame(file, CollisionFrame::S);
        let bw = best_boxes(&pw, &boxes);
        let bs = best_boxes(&ps, &boxes);
        let (aw, as_) = (agreement(&bw), agreement(&bs));
        // W unless S agrees better: a tie (a scene symmetric about the origin, or one that
        // agrees with neither) keeps the InteriorGS frame the labels are in.
        let s_wins = (as_.inside, as_.overlapping) > (aw.inside, aw.overlapping);
        if s_wins {
            (CollisionFrame::S, true, Some(aw), Some(as_), ps, bs)
        } else {
            (CollisionFrame::W, true, Some(aw), Some(as_), pw, bw)
        }
    };
    let mut ids: HashMap<String, Option<usize>> = HashMap::new();
    for (i, o) in objects.iter().enumerate() {
        for key in [o.ins_id.clone(), identifier(&o.ins_id)] {
            // An id two objects share names neither.
            ids.entry(key)
                .and_modify(|e| {
                    if *e != Some(i) {
                        *e = None
                    }
                })
                .or_insert(Some(i));
        }
    }
    let mut report = CollisionReport {
        file: file.path.display().to_string(),
        frame,
        frame_measured: measured,
        agreement_w,
        agreement_s,
        meters_per_unit: file.meters_per_unit,
        up_axis: file.up_axis.clone(),
        parts: file.prims.len(),
        empty: file.empty,
        by_name: 0,
        by_box: 0,
        structure: 0,
        names_rejected: 0,
        objects: 0,
        objects_without: 0,
    };
    let mut given: Vec<Vec<TriMesh>> = vec![Vec::new(); objects.len()];
    let mut structure = Vec::new();
    for ((prim, (pts, _)), (best, share)) in file.prims.iter().zip(parts).zip(best) {
        let mesh = TriMesh {
            positions: pts,
            triangles: prim.mesh.triangles.clone(),
        };
        let named = named_objects(&prim.path, &ids);
        // A name is trusted unless the part lies wholly outside that object's box; among
        // several named objects (`/room_3/ins_12/part_0`) the one whose box holds the most of
        // the part wins.
        let by_name = named
            .iter()
            .map(|&i| (i, share_inside(&mesh.positions, &objects[i].obb)))
            .filter(|&(_, s)| s > 0.0 || boxes.is_empty())
            .fold(None::<(usize, f32)>, |acc, (i, s)| match acc {
                Some((_, t)) if t >= s => acc,
                _ => Some((i, s)),
            });
        if let Some((i, _)) = by_name {
            report.by_name += 1;
            given[i].push(mesh);
            continue;
        }
        if !named.is_empty() {
            report.names_rejected += 1;
        }
        match best {
            Some(i) if share >= INSIDE_SHARE => {
                report.by_box += 1;
                given[i].push(mesh);
            }
            _ => {
                report.structure += 1;
                structure.push(mesh);
            }
        }
    }
    for (o, parts) in objects.iter_mut().zip(given) {
        if parts.is_empty() {
            report.objects_without += 1;
        } else {
            report.objects += 1;
            o.body = Some(BodyParts {
                source: BodySource::Published,
                parts,
            });
        }
    }
    Attached {
        structure: (!structure.is_empty()).then_some(BodyParts {
            source: BodySource::Published,
            parts: structure,
        }),
        report,
    }
}

impl std::fmt::Display for CollisionReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pct = |a: Option<FrameAgreement>| match a {
            Some(a) => format!(
                "{:.0}% inside, {:.0}% overlapping",
                a.inside * 100.0,
                a.overlapping * 100.0
            ),
            None => "-".to_string(),
        };
        write!(
            f,
            "{}: {} parts ({} by name, {} by box, {} structure{}) on {} objects ({} without); frame {} ({}; W: {}, S: {})",
            self.file,
            self.parts,
            self.by_name,
            self.by_box,
            self.structure,
            if self.names_rejected > 0 {
                format!(", {} names outside their box", self.names_rejected)
            } else {
                String::new()
            },
            self.objects,
            self.objects_without,
            self.frame.as_str(),
            if self.frame_measured {
                "measured against labels.json"
            } else {
                "assumed: no labels to compare with"
            },
            pct(self.agreement_w),
            pct(self.agreement_s),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::object::{Attributes, PhysicsRole, RigidBody};
    use sage_core::InstanceId;

    /// A unit-cube mesh prim named `name` (corners 0..1), with `ops` as its xformOp lines.
    fn cube(name: &str, ops: &str) -> String {
        format!(
            r#"def Mesh "{name}"
{{
    point3f[] points = [(0,0,0),(1,0,0),(1,1,0),(0,1,0),(0,0,1),(1,0,1),(1,1,1),(0,1,1)]
    int[] faceVertexCounts = [4,4,4,4,4,4]
    int[] faceVertexIndices = [0,3,2,1, 4,5,6,7, 0,1,5,4, 1,2,6,5, 2,3,7,6, 3,0,4,7]
    {ops}
}}
"#
        )
    }

    fn stage(header: &str, body: &str) -> String {
        format!("#usda 1.0\n(\n{header}\n)\n\n{body}")
    }

    fn read_text(text: &str) -> Result<CollisionFile> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s_collision.usda");
        std::fs::write(&p, text).unwrap();
        read(&p)
    }

    fn object(ins_id: &str, center: Vec3, half: Vec3, yaw: f32) -> Object {
        Object {
            id: InstanceId(0),
            ins_id: ins_id.into(),
            label: "Thing".into(),
            category: "thing".into(),
            obb: Obb {
                center,
                half_extents: half,
                yaw,
            },
            room: None,
            attributes: Attributes::default(),
            role: PhysicsRole::Static,
            rigid_body: RigidBody::default(),
            mesh: None,
            body: None,
        }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-4
    }

    #[test]
    fn nested_transforms_compose_outermost_first() {
        // /World: translate (10,0,0) then rotateZ 90 (listed in that order: the rotation is
        // applied first). /World/g: scale 2. The mesh: orient 180° about Z.
        let body = format!(
            r#"def Xform "World"
{{
    double3 xformOp:translate = (10, 0, 0)
    float xformOp:rotateZ = 90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateZ"]
    def Xform "g"
    {{
        float3 xformOp:scale = (2, 2, 2)
        uniform token[] xformOpOrder = ["xformOp:scale"]
        {}
    }}
}}
"#,
            cube(
                "m",
                r#"quatf xformOp:orient = (0, 0, 0, 1)
    uniform token[] xformOpOrder = ["xformOp:orient"]"#
            )
        );
        let f = read_text(&stage("    upAxis = \"Z\"\n    metersPerUnit = 1", &body)).unwrap();
        assert_eq!(f.prims.len(), 1);
        let m = &f.prims[0].mesh;
        assert_eq!(f.prims[0].path, "/World/g/m");
        // Quads fanned: 6 faces → 12 triangles.
        assert_eq!(m.triangles.len(), 12);
        // (1,0,0): orient 180° about Z → (-1,0,0); scale 2 → (-2,0,0); rotateZ 90 → (0,-2,0);
        // translate → (10,-2,0).
        assert!(
            close(m.positions[1], Vec3::new(10.0, -2.0, 0.0)),
            "{:?}",
            m.positions[1]
        );
        // (0,1,1) → (0,-1,1) → (0,-2,2) → (2,0,2) → (12,0,2).
        assert!(
            close(m.positions[7], Vec3::new(12.0, 0.0, 2.0)),
            "{:?}",
            m.positions[7]
        );
    }

    #[test]
    fn matrix_ops_inversion_reset_and_stage_units() {
        // A row-vector matrix with translation (1,2,3) in its last row; metersPerUnit 0.01 and
        // Y up: (x,y,z) cm → (x,-z,y) m.
        let body = format!(
            r#"def Xform "World"
{{
    double3 xformOp:translate = (100, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def Xform "a"
    {{
        matrix4d xformOp:transform = ( (1,0,0,0), (0,1,0,0), (0,0,1,0), (1,2,3,1) )
        uniform token[] xformOpOrder = ["xformOp:transform"]
        {}
    }}
    {}
}}
"#,
            cube(
                "m",
                r#"double3 xformOp:translate:offset = (0, 0, 5)
    uniform token[] xformOpOrder = ["!invert!xformOp:translate:offset"]"#
            ),
            cube(
                "r",
                r#"double3 xformOp:translate = (7, 0, 0)
    uniform token[] xformOpOrder = ["!resetXformStack!", "xformOp:translate"]"#
            )
        );
        let f = read_text(&stage(
            "    upAxis = \"Y\"\n    metersPerUnit = 0.01",
            &body,
        ))
        .unwrap();
        assert_eq!(f.up_axis, "Y");
        let m = &f.prims[0].mesh;
        // (0,0,0) → (0,0,-5) → (1,2,-2) → (101,2,-2) cm → (1.01, 0.02, 0.02) m, Z up.
        assert!(
            close(m.positions[0], Vec3::new(1.01, 0.02, 0.02)),
            "{:?}",
            m.positions[0]
        );
        // The reset prim ignores /World's translate: (0,0,0) → (7,0,0) cm → (0.07, 0, 0).
        let r = &f.prims[1].mesh;
        assert!(
            close(r.positions[0], Vec3::new(0.07, 0.0, 0.0)),
            "{:?}",
            r.positions[0]
        );
    }

    #[test]
    fn rotate_xyz_turns_about_x_first() {
        let body = cube(
            "m",
            r#"float3 xformOp:rotateXYZ = (90, 0, 90)
    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]"#,
        );
        let f = read_text(&stage("    upAxis = \"Z\"", &body)).unwrap();
        // (0,1,0): about X by 90 → (0,0,1); about Z by 90 → (0,0,1).
        assert!(close(
            f.prims[0].mesh.positions[3],
            Vec3::new(0.0, 0.0, 1.0)
        ));
        // (1,0,0): X leaves it; Z by 90 → (0,1,0).
        assert!(close(
            f.prims[0].mesh.positions[1],
            Vec3::new(0.0, 1.0, 0.0)
        ));
    }

    #[test]
    fn damaged_files_name_the_prim() {
        let bad_index = stage(
            "",
            r#"def Mesh "wall"
{
    point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0,1,7]
}
"#,
        );
        let e = read_text(&bad_index).unwrap_err().to_string();
        assert!(
            e.contains("/wall.faceVertexIndices[2]") && e.contains("out of range"),
            "{e}"
        );
        assert!(e.contains("s_collision.usda"), "{e}");
        let bad_counts = bad_index.replace("[0,1,7]", "[0,1,2,0]");
        let e = read_text(&bad_counts).unwrap_err().to_string();
        assert!(
            e.contains("/wall.faceVertexCounts") && e.contains("add up to 3"),
            "{e}"
        );
        let nan = bad_index
            .replace("(1,0,0)", "(nan,0,0)")
            .replace("[0,1,7]", "[0,1,2]");
        let e = read_text(&nan).unwrap_err().to_string();
        assert!(
            e.contains("/wall.points[1]") && e.contains("not finite"),
            "{e}"
        );
        let far = nan.replace("(nan,0,0)", "(1e30,0,0)");
        let e = read_text(&far).unwrap_err().to_string();
        assert!(
            e.contains("/wall.points[1]") && e.contains("past ±10000 m"),
            "{e}"
        );
        let none = stage("", "def Xform \"World\"\n{\n}\n");
        let e = read_text(&none).unwrap_err().to_string();
        assert!(e.contains("no mesh prim"), "{e}");
        let bad_op = cube(
            "m",
            r#"double3 xformOp:shear = (1, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:shear"]"#,
        );
        let e = read_text(&stage("", &bad_op)).unwrap_err().to_string();
        assert!(
            e.contains("/m.xformOp:shear") && e.contains("unknown xformOp"),
            "{e}"
        );
        let e = read_text("#usda 1.0\ndef Mesh \"m\" {\n  point3f[] points = [(0,0").unwrap_err();
        assert!(e.to_string().contains("not a readable USD file"), "{e}");
    }

    #[test]
    fn names_and_identifiers() {
        assert_eq!(identifier("123"), "_123");
        assert_eq!(identifier("a-b c"), "a_b_c");
        let mut ids = HashMap::new();
        ids.insert("12".to_string(), Some(0));
        ids.insert("_12".to_string(), Some(0));
        ids.insert("3".to_string(), Some(1));
        assert_eq!(named_objects("/World/ins_12/part_0", &ids), vec![0]);
        assert_eq!(named_objects("/World/_12/hull", &ids), vec![0]);
        assert_eq!(named_objects("/World/obj12", &ids), vec![0]);
        assert_eq!(
            named_objects("/World/room_3/Instance_12/p", &ids),
            vec![1, 0]
        );
        assert!(named_objects("/World/wall_a", &ids).is_empty());
        let n = names("0001_839920");
        assert_eq!(n[0], "0001_839920_collision.usd");
        assert!(n.contains(&"839920_collision.usd".to_string()));
        assert!(n.contains(&"839920_collision.usda".to_string()));
        assert_eq!(names("kitchen").len(), 3);
    }

    /// Two objects, a wall and the parts of a file in frame `s` (turned 180° about Z) or W.
    fn scene_file(turned: bool) -> (CollisionFile, Vec<Object>) {
        let objects = vec![
            // A table at (3, 1), a cup on it at (3, 1, 0.8).
            object("7", Vec3::new(3.0, 1.0, 0.4), Vec3::new(0.6, 0.4, 0.4), 0.3),
            object(
                "8",
                Vec3::new(3.0, 1.0, 0.85),
                Vec3::new(0.05, 0.05, 0.05),
                0.0,
            ),
        ];
        let boxmesh = |c: Vec3, h: Vec3| TriMesh {
            positions: [-1.0f32, 1.0]
                .iter()
                .flat_map(|&x| {
                    [-1.0f32, 1.0]
                        .iter()
                        .flat_map(move |&y| [-1.0f32, 1.0].map(|z| c + h * Vec3::new(x, y, z)))
                })
                .collect(),
            triangles: vec![[0, 1, 2], [1, 3, 2]],
        };
        let prims = vec![
            (
                "/World/ins_7/top",
                boxmesh(Vec3::new(3.0, 1.0, 0.75), Vec3::new(0.5, 0.3, 0.03)),
            ),
            (
                "/World/ins_7/leg",
                boxmesh(Vec3::new(2.7, 0.8, 0.35), Vec3::new(0.03, 0.03, 0.35)),
            ),
            // Unnamed: the cup, by its box (the table's box holds it too; the smaller wins).
            (
                "/World/mesh_0",
                boxmesh(Vec3::new(3.0, 1.0, 0.83), Vec3::new(0.04, 0.04, 0.04)),
            ),
            // Walls: named like nothing, far from every box.
            (
                "/World/wall_0",
                boxmesh(Vec3::new(0.0, -2.0, 1.4), Vec3::new(5.0, 0.05, 1.4)),
            ),
            (
                "/World/floor",
                boxmesh(Vec3::new(0.0, 0.0, -0.05), Vec3::new(5.0, 5.0, 0.05)),
            ),
            // Named after the table but nowhere near it: the name is not trusted.
            (
                "/World/stray/ins_7",
                boxmesh(Vec3::new(-3.0, 3.0, 1.0), Vec3::new(0.1, 0.1, 0.1)),
            ),
        ];
        let frame = if turned {
            CollisionFrame::S
        } else {
            CollisionFrame::W
        };
        let file = CollisionFile {
            path: PathBuf::from("x_collision.usd"),
            prims: prims
                .into_iter()
                .map(|(p, m)| CollisionPrim {
                    path: p.into(),
                    // S → W and W → S are the same turn.
                    mesh: TriMesh {
                        positions: m.positions.iter().map(|&v| frame.to_w(v)).collect(),
                        triangles: m.triangles,
                    },
                })
                .collect(),
            empty: 0,
            meters_per_unit: 1.0,
            up_axis: "Z".into(),
        };
        (file, objects)
    }

    #[test]
    fn parts_go_to_their_objects_in_either_frame() {
        for turned in [false, true] {
            let (file, mut objects) = scene_file(turned);
            let a = attach(&file, &mut objects);
            let r = &a.report;
            let want = if turned {
                CollisionFrame::S
            } else {
                CollisionFrame::W
            };
            assert_eq!(r.frame, want, "{r}");
            assert!(r.frame_measured);
            let (good, bad) = if turned {
                (r.agreement_s.unwrap(), r.agreement_w.unwrap())
            } else {
                (r.agreement_w.unwrap(), r.agreement_s.unwrap())
            };
            assert!(good.inside > bad.inside, "{r}");
            assert_eq!((r.by_name, r.by_box, r.structure), (2, 1, 3), "{r}");
            assert_eq!(r.names_rejected, 1, "{r}");
            assert_eq!((r.objects, r.objects_without), (2, 0));
            let table = objects[0].body.as_ref().unwrap();
            assert_eq!(table.source, BodySource::Published);
            assert_eq!(table.parts.len(), 2);
            // In W whatever the file's frame: the leg stands at (2.7, 0.8).
            let leg = table.parts[1].aabb();
            assert!(
                close((leg.min + leg.max) * 0.5, Vec3::new(2.7, 0.8, 0.35)),
                "{leg:?}"
            );
            assert_eq!(objects[1].body.as_ref().unwrap().parts.len(), 1);
            assert_eq!(a.structure.as_ref().unwrap().parts.len(), 3);
        }
    }

    #[test]
    fn without_labels_the_frame_is_assumed_and_everything_is_structure() {
        let (file, _) = scene_file(false);
        let a = attach(&file, &mut []);
        assert_eq!(a.report.frame, CollisionFrame::W);
        assert!(!a.report.frame_measured && a.report.agreement_w.is_none());
        assert_eq!(a.report.structure, file.prims.len());
        assert!(a.report.to_string().contains("assumed"));
    }

    #[test]
    fn share_inside_measures_extent() {
        let b = Obb {
            center: Vec3::ZERO,
            half_extents: Vec3::splat(1.0),
            yaw: 0.0,
        };
        assert_eq!(
            share_inside(&[Vec3::splat(-0.5), Vec3::splat(0.5)], &b),
            1.0
        );
        assert_eq!(share_inside(&[Vec3::splat(3.0), Vec3::splat(4.0)], &b), 0.0);
        // Half of x outside (tolerance aside).
        let s = share_inside(&[Vec3::new(0.05, 0.0, 0.0), Vec3::new(2.05, 0.1, 0.1)], &b);
        assert!((s - 0.5).abs() < 1e-4, "{s}");
    }
}
