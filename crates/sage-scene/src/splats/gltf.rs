//! glTF 2.0 / GLB with the `KHR_gaussian_splatting` extension (Khronos; the text read is the
//! 2026 release candidate, KhronosGroup/glTF `extensions/2.0/Khronos/KHR_gaussian_splatting`).
//!
//! A splat primitive is a `POINTS` primitive (`mode` 0) whose `extensions` hold a
//! `KHR_gaussian_splatting` object (`kernel` — only `"ellipse"` is defined —, `colorSpace`,
//! `projection`, `sortingMethod`: informative here, not interpreted) and whose attributes are one
//! accessor per property, one element per Gaussian:
//!
//! | attribute | type | component types | meaning |
//! |---|---|---|---|
//! | `POSITION` | VEC3 | float (or the `KHR_mesh_quantization` integers) | centre |
//! | `KHR_gaussian_splatting:ROTATION` | VEC4 | float, normalized byte/short | unit quaternion x, y, z, w |
//! | `KHR_gaussian_splatting:SCALE` | VEC3 | float, ubyte/ushort (normalized or not; drafts: signed) | **linear** scale |
//! | `KHR_gaussian_splatting:OPACITY` | SCALAR | float, normalized ubyte/ushort | alpha in \[0, 1\] |
//! | `KHR_gaussian_splatting:SH_DEGREE_0_COEF_0` | VEC3 | float | `f_dc` (r, g, b) |
//! | `KHR_gaussian_splatting:SH_DEGREE_ℓ_COEF_n` | VEC3 | float | degree ℓ = 1…3, n = 0…2ℓ (m = −ℓ…ℓ) |
//! | `COLOR_0` | VEC3/VEC4 | float, normalized ubyte/ushort | fallback colour (and alpha) |
//!
//! The SH are the 3DGS ones (real, Condon–Shortley phase, the reference rasterizer's constants):
//! coefficient `n` of degree ℓ is `sh_rest[ℓ² − 1 + n]`, and every degree up to the highest
//! present must be complete. Without `SH_DEGREE_0_COEF_0` (required by the text, absent from some
//! writers' files), `f_dc = (rgb − 0.5) / SH_C0` from `COLOR_0`, taking it as the display colour
//! `splat-transform` writes; the text asks for linear `COLOR_0`, which would come out darker.
//!
//! Conventions decoded to the standard (Inria) PLY's:
//!
//! - Scale: linear and non-negative in the current text; earlier drafts (and files written from
//!   them, e.g. `splat-transform` before its fix and the Khronos sample assets) stored natural
//!   logs. A primitive whose `SCALE` holds any negative value is read as such a log-space file
//!   ([`GltfDecoder::legacy_log_scale`]); otherwise `log_scale = ln(scale)`, a zero scale
//!   becoming the log of the smallest normal `f32` rather than −∞.
//! - Opacity: the logit of the stored alpha, clamped to ±[`MAX_LOGIT`]; alpha outside \[0, 1\] is
//!   an error (the text calls it invalid).
//! - Axes: glTF is Y-up; PlayCanvas' `splat-transform` (the common PLY → GLB converter) writes
//!   the PLY frame rotated 180° about Z (`(x, y, z) → (−x, −y, z)`, quaternion `r ⊗ q` with
//!   `r = Rz(180°)`, and the SH rotated with it, i.e. the coefficients odd in (x, y) negated).
//!   This reader applies the inverse, so a PLY → GLB → sage3d round trip is the identity. (A GLB
//!   made with another convention, e.g. Niantic's RDF → RUB flip `(x, −y, −z)`, comes out turned
//!   180° about Y relative to its source PLY.)
//! - Node transforms (matrix or TRS, composed down the node tree of the default scene) are
//!   applied as the text defines them: positions by the matrix, covariances as `M Σ Mᵀ`, the SH
//!   rotated by the matrix's rotation part. A uniform scale is added to the log-scales; under a
//!   non-uniform one each covariance is decomposed again (new rotation and scales). A shear is an
//!   error; a mirror (undefined by the text) is read as a rotation with the SH of odd degree
//!   negated.
//!
//! Containers: GLB (12-byte header, JSON chunk, optional BIN chunk) and `.gltf` JSON whose
//! buffers are embedded as base64 `data:` URIs; a buffer in an external file is an error (the
//! reader has bytes, not a folder). `extensionsRequired` naming anything but
//! `KHR_gaussian_splatting` / `KHR_mesh_quantization` (SPZ or meshopt compression…) is an
//! error. Sparse accessors, accessors without a buffer view, indexed splat primitives and the
//! first Cesium drafts' layout (`_ROTATION`, `_SCALE`) are rejected. Primitives of several meshes
//! and nodes are concatenated in scene order.
//!
//! The `gltf` crate (1.4) is not used: its validation rejects attribute names such as
//! `KHR_gaussian_splatting:ROTATION` as invalid semantics, and iterating them without
//! validation panics, so the container and JSON are parsed here with `serde_json`.
//!
//! What is lost: with float accessors nothing but the `f32` rounding of the writer's `exp` and
//! `sigmoid` (the file holds scale and alpha; log and logit are recomputed, the logit losing
//! precision near alpha 0 or 1); `colorSpace`, `kernel`, `projection` and `sortingMethod` are not
//! kept (a `lin_rec709_display` file's SH are taken as stored, unconverted).

use crate::gaussians::{Gaussian, SH_C0, sh_rest_count};
use crate::ply::standard::MAX_LOGIT;
use crate::splats::BlockDecoder;
use glam::{DMat3, DMat4, DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;
use sage_core::{Error, Result};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::collections::BTreeMap;

/// The extension's name, also the prefix of its attribute names.
pub const EXTENSION: &str = "KHR_gaussian_splatting";

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
/// Extensions a file may require and still be read.
const SUPPORTED_REQUIRED: [&str; 2] = [EXTENSION, "KHR_mesh_quantization"];
/// The log-scale of a zero (or subnormal) linear scale: finite, far below any real Gaussian.
const MIN_LOG_SCALE: f64 = -87.336_544_750_553_1; // ln(f32::MIN_POSITIVE)
/// Relative tolerance on a node matrix being a rotation times a uniform scale (glTF JSON holds
/// decimal `f32`s, so an exact test would reject honest files).
const RIGID_TOLERANCE: f64 = 1e-4;

// ---- glTF JSON (only what this reader needs; unknown members are ignored) ----

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase", default)]
struct Root {
    extensions_required: Vec<String>,
    scene: Option<usize>,
    scenes: Vec<SceneJson>,
    nodes: Vec<NodeJson>,
    meshes: Vec<MeshJson>,
    accessors: Vec<AccessorJson>,
    buffer_views: Vec<BufferViewJson>,
    buffers: Vec<BufferJson>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct SceneJson {
    nodes: Vec<usize>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct NodeJson {
    mesh: Option<usize>,
    children: Vec<usize>,
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct MeshJson {
    primitives: Vec<PrimitiveJson>,
}

fn triangles() -> u32 {
    4
}

#[derive(Deserialize)]
struct PrimitiveJson {
    #[serde(default)]
    attributes: BTreeMap<String, usize>,
    #[serde(default = "triangles")]
    mode: u32,
    #[serde(default)]
    indices: Option<usize>,
    #[serde(default)]
    extensions: Map<String, Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct AccessorJson {
    #[serde(default)]
    buffer_view: Option<usize>,
    #[serde(default)]
    byte_offset: u64,
    component_type: u32,
    #[serde(default)]
    normalized: bool,
    count: u64,
    #[serde(rename = "type")]
    kind: String,
    #[serde(default)]
    sparse: Option<Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferViewJson {
    buffer: usize,
    #[serde(default)]
    byte_offset: u64,
    byte_length: u64,
    #[serde(default)]
    byte_stride: Option<u64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferJson {
    byte_length: u64,
    #[serde(default)]
    uri: Option<String>,
}

// ---- accessors resolved against the buffers ----

/// An accessor component type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Component {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl Component {
    fn from_gl(code: u32) -> Option<Component> {
        Some(match code {
            5120 => Component::I8,
            5121 => Component::U8,
            5122 => Component::I16,
            5123 => Component::U16,
            5125 => Component::U32,
            5126 => Component::F32,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Component::I8 | Component::U8 => 1,
            Component::I16 | Component::U16 => 2,
            Component::U32 | Component::F32 => 4,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Component::I8 => "byte",
            Component::U8 => "unsigned byte",
            Component::I16 => "short",
            Component::U16 => "unsigned short",
            Component::U32 => "unsigned int",
            Component::F32 => "float",
        }
    }
}

/// A (component type, normalized) pair an attribute may use.
type Encoding = (Component, bool);

const FLOAT: &[Encoding] = &[(Component::F32, false)];
const POSITION_ENCODINGS: &[Encoding] = &[
    (Component::F32, false),
    (Component::I8, false),
    (Component::I8, true),
    (Component::U8, false),
    (Component::U8, true),
    (Component::I16, false),
    (Component::I16, true),
    (Component::U16, false),
    (Component::U16, true),
];
const ROTATION_ENCODINGS: &[Encoding] = &[
    (Component::F32, false),
    (Component::I8, true),
    (Component::I16, true),
];
/// The release candidate's unsigned types, and the signed ones of the earlier drafts.
const SCALE_ENCODINGS: &[Encoding] = &[
    (Component::F32, false),
    (Component::U8, false),
    (Component::U8, true),
    (Component::U16, false),
    (Component::U16, true),
    (Component::I8, false),
    (Component::I8, true),
    (Component::I16, false),
    (Component::I16, true),
];
const UNIT_ENCODINGS: &[Encoding] = &[
    (Component::F32, false),
    (Component::U8, true),
    (Component::U16, true),
];

fn describe(encodings: &[Encoding]) -> String {
    encodings
        .iter()
        .map(|(c, n)| {
            if *n {
                format!("normalized {}", c.name())
            } else {
                c.name().to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// One attribute's elements: where element `k` component `c` lies, and how to read it.
#[derive(Debug, Clone)]
struct Acc {
    buffer: usize,
    start: usize,
    stride: usize,
    component: Component,
    normalized: bool,
    /// The attribute name, for errors.
    name: String,
}

/// Where the base colour comes from.
#[derive(Debug, Clone)]
enum Color {
    /// `SH_DEGREE_0_COEF_0`: `f_dc` itself.
    Sh(Acc),
    /// `COLOR_0` (RGB of RGBA): `f_dc = (c − 0.5) / SH_C0`.
    Fallback(Acc),
}

/// How a primitive's local frame maps to the decoded (PLY) frame.
#[derive(Debug, Clone)]
enum Frame {
    /// No node transform: only the inverse of the GLB convention, exact sign flips.
    Convention,
    /// A node transform composed with the inverse convention, in `f64`.
    General(Box<General>),
}

#[derive(Debug, Clone)]
struct General {
    /// Point transform (node world matrix, then the inverse convention).
    affine: DMat4,
    /// Quaternion to pre-multiply the Gaussians' rotations with (its rotation part).
    rotation: DQuat,
    /// A uniform scale, added to every log-scale; `None` for a non-uniform one, whose
    /// covariances are transformed and decomposed again, Gaussian by Gaussian.
    log_scale: Option<f64>,
    /// The linear part of `affine` (for covariances under a non-uniform scale).
    linear: DMat3,
    /// SH rotation per degree 1–3 (row-major, `2ℓ + 1` square), mirror sign included.
    sh: [[[f64; 7]; 7]; 3],
}

/// One splat primitive instanced by one node.
#[derive(Debug, Clone)]
struct Part {
    /// Index of its first Gaussian in the decoder.
    start: usize,
    count: usize,
    /// `meshes[m].primitives[p]` (and the node), for errors.
    location: String,
    position: Acc,
    rotation: Acc,
    scale: Acc,
    opacity: Acc,
    color: Color,
    /// Higher-order SH accessors in coefficient order (3, 8 or 15; none at degree 0).
    rest: Vec<Acc>,
    degree: u8,
    scale_is_log: bool,
    frame: Frame,
}

/// A glTF/GLB file holding `KHR_gaussian_splatting` primitives, opened for decoding (see the
/// module docs for what is read and how).
pub struct GltfDecoder {
    buffers: Vec<Vec<u8>>,
    parts: Vec<Part>,
    len: usize,
    sh_degree: u8,
}

impl GltfDecoder {
    /// Opens a GLB, or a `.gltf` JSON document whose buffers are base64 `data:` URIs: unpacks
    /// the container, checks every accessor the splat primitives use against the bytes present
    /// and resolves node transforms. Values are decoded later, by [`BlockDecoder::decode`].
    ///
    /// # Errors
    ///
    /// A damaged container, invalid JSON, a buffer in an external file, a required extension
    /// this reader lacks, no splat primitive, or an accessor that is missing, of the wrong type
    /// or outside its buffer — each naming the JSON member at fault.
    pub fn open(bytes: &[u8]) -> Result<GltfDecoder> {
        let (json, bin) = container(bytes)?;
        let root: Root = serde_json::from_slice(json)
            .map_err(|e| Error::format("glTF JSON", format!("not a valid glTF document: {e}")))?;
        for (i, ext) in root.extensions_required.iter().enumerate() {
            if !SUPPORTED_REQUIRED.contains(&ext.as_str()) {
                return Err(Error::format(
                    format!("extensionsRequired[{i}]"),
                    format!(
                        "the file requires extension '{ext}', which this reader does not \
                         support (only {})",
                        SUPPORTED_REQUIRED.join(" and ")
                    ),
                ));
            }
        }
        let buffers = load_buffers(&root, bin)?;
        let mut decoder = GltfDecoder {
            buffers,
            parts: Vec::new(),
            len: 0,
            sh_degree: 0,
        };
        let instances = instances(&root)?;
        for (node, mesh_index, world) in instances {
            let Some(mesh) = root.meshes.get(mesh_index) else {
                let at = node.map_or_else(|| "meshes".to_string(), |n| format!("nodes[{n}].mesh"));
                return Err(Error::format(
                    at,
                    format!(
                        "mesh {mesh_index} does not exist ({} meshes)",
                        root.meshes.len()
                    ),
                ));
            };
            for (pi, prim) in mesh.primitives.iter().enumerate() {
                if !prim.extensions.contains_key(EXTENSION) {
                    continue;
                }
                let location = match node {
                    Some(n) => format!("meshes[{mesh_index}].primitives[{pi}] (node {n})"),
                    None => format!("meshes[{mesh_index}].primitives[{pi}]"),
                };
                let part = decoder.part(&root, prim, location, world, decoder.len)?;
                decoder.len = decoder.len.saturating_add(part.count);
                // Instancing a primitive from many nodes (or meshes) multiplies its Gaussians
                // without more bytes; bound the total by the file size, checked as it grows so
                // that a small file can neither ask for an enormous table nor make this loop
                // scan the same accessor over and over.
                if decoder.len > bytes.len() {
                    return Err(Error::format(
                        "nodes",
                        format!(
                            "the scene instances more Gaussians than the file's {} bytes: too \
                             many instances of the same primitives",
                            bytes.len()
                        ),
                    ));
                }
                decoder.sh_degree = decoder.sh_degree.max(part.degree);
                decoder.parts.push(part);
            }
        }
        if decoder.parts.is_empty() {
            return Err(Error::format(
                "meshes",
                format!(
                    "no primitive of the scene carries the {EXTENSION} extension (a mesh-only \
                     glTF?)"
                ),
            ));
        }
        Ok(decoder)
    }

    /// True when some primitive's `SCALE` held negative values and was therefore read as
    /// natural logs (the earlier drafts' layout) rather than linear scales.
    pub fn legacy_log_scale(&self) -> bool {
        self.parts.iter().any(|p| p.scale_is_log)
    }

    /// Resolves one splat primitive: its accessors, SH degree, scale encoding and frame.
    fn part(
        &self,
        root: &Root,
        prim: &PrimitiveJson,
        location: String,
        world: Option<DMat4>,
        start: usize,
    ) -> Result<Part> {
        let at = |what: &str| format!("{location}.{what}");
        if prim.mode != 0 {
            return Err(Error::format(
                at("mode"),
                format!(
                    "a {EXTENSION} primitive must have mode 0 (POINTS), found {}",
                    prim.mode
                ),
            ));
        }
        if prim.indices.is_some() {
            return Err(Error::format(
                at("indices"),
                "indexed splat primitives are not supported",
            ));
        }
        let compression = prim
            .extensions
            .get(EXTENSION)
            .and_then(|e| e.get("extensions"))
            .and_then(Value::as_object)
            .map(|m| m.keys().cloned().collect::<Vec<_>>().join(", "))
            .unwrap_or_default();
        let required = |name: &str| -> Result<usize> {
            prim.attributes.get(name).copied().ok_or_else(|| {
                let mut why = format!("the required attribute {name} is missing");
                if prim.attributes.contains_key("_ROTATION") {
                    why += "; the primitive has the first drafts' _ROTATION/_SCALE layout, which \
                            this reader does not support";
                } else if !compression.is_empty() {
                    why += &format!(
                        "; the primitive uses {compression}, an encoding this reader does not \
                         support"
                    );
                }
                Error::format(at("attributes"), why)
            })
        };
        let position_index = required("POSITION")?;
        let count = root
            .accessors
            .get(position_index)
            .map(|a| a.count)
            .unwrap_or(0);
        let accessor = |name: &str, index: usize, kinds: &[&str], encodings: &[Encoding]| {
            self.accessor(root, index, name, kinds, encodings, count)
                .map_err(|e| e.within(format!("{location}.attributes[{name}]")))
        };
        let position = accessor("POSITION", position_index, &["VEC3"], POSITION_ENCODINGS)?;
        let count = usize::try_from(count).map_err(|_| {
            Error::format(
                at("attributes[POSITION]"),
                "the count does not fit in memory",
            )
        })?;
        let name = |s: &str| format!("{EXTENSION}:{s}");
        let rotation_name = name("ROTATION");
        let rotation = accessor(
            &rotation_name,
            required(&rotation_name)?,
            &["VEC4"],
            ROTATION_ENCODINGS,
        )?;
        let scale_name = name("SCALE");
        let scale = accessor(
            &scale_name,
            required(&scale_name)?,
            &["VEC3"],
            SCALE_ENCODINGS,
        )?;
        let opacity_name = name("OPACITY");
        let opacity = accessor(
            &opacity_name,
            required(&opacity_name)?,
            &["SCALAR"],
            UNIT_ENCODINGS,
        )?;
        let dc_name = name("SH_DEGREE_0_COEF_0");
        let color = match prim.attributes.get(&dc_name) {
            Some(&i) => Color::Sh(accessor(&dc_name, i, &["VEC3"], FLOAT)?),
            None => match prim.attributes.get("COLOR_0") {
                Some(&i) => {
                    Color::Fallback(accessor("COLOR_0", i, &["VEC3", "VEC4"], UNIT_ENCODINGS)?)
                }
                None => {
                    return Err(Error::format(
                        at("attributes"),
                        format!("neither {dc_name} nor COLOR_0 is present: no colour"),
                    ));
                }
            },
        };
        let (degree, rest_indices) = sh_attributes(&prim.attributes)
            .map_err(|e| e.within(format!("{location}.attributes")))?;
        let rest = rest_indices
            .into_iter()
            .map(|(n, i)| accessor(&n, i, &["VEC3"], FLOAT))
            .collect::<Result<Vec<_>>>()?;
        let scale_is_log = self.any_negative(&scale, count);
        let frame = match world {
            None => Frame::Convention,
            Some(m) => Frame::General(Box::new(
                general_frame(&m).map_err(|e| e.within(location.clone()))?,
            )),
        };
        Ok(Part {
            start,
            count,
            location,
            position,
            rotation,
            scale,
            opacity,
            color,
            rest,
            degree,
            scale_is_log,
            frame,
        })
    }

    /// Resolves accessor `index` for attribute `name`: type, encoding, count and byte range.
    fn accessor(
        &self,
        root: &Root,
        index: usize,
        name: &str,
        kinds: &[&str],
        encodings: &[Encoding],
        count: u64,
    ) -> Result<Acc> {
        let at = format!("accessors[{index}]");
        let a = root.accessors.get(index).ok_or_else(|| {
            Error::format(
                &at,
                format!("does not exist ({} accessors)", root.accessors.len()),
            )
        })?;
        if !kinds.contains(&a.kind.as_str()) {
            return Err(Error::format(
                format!("{at}.type"),
                format!("is {}, expected {}", a.kind, kinds.join(" or ")),
            ));
        }
        let width = match a.kind.as_str() {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        let component = Component::from_gl(a.component_type).ok_or_else(|| {
            Error::format(
                format!("{at}.componentType"),
                format!("{} is not a glTF component type", a.component_type),
            )
        })?;
        if !encodings.contains(&(component, a.normalized)) {
            let found = if a.normalized {
                format!("normalized {}", component.name())
            } else {
                component.name().to_string()
            };
            return Err(Error::format(
                format!("{at}.componentType"),
                format!("{name} cannot be {found}; allowed: {}", describe(encodings)),
            ));
        }
        if a.count != count {
            return Err(Error::format(
                format!("{at}.count"),
                format!("is {}, but POSITION has {count} elements", a.count),
            ));
        }
        if a.sparse.is_some() {
            return Err(Error::format(
                format!("{at}.sparse"),
                "sparse accessors are not supported",
            ));
        }
        let view_index = a.buffer_view.ok_or_else(|| {
            Error::format(
                format!("{at}.bufferView"),
                "missing (zero-filled accessors are not supported)",
            )
        })?;
        let view = root.buffer_views.get(view_index).ok_or_else(|| {
            Error::format(
                format!("{at}.bufferView"),
                format!(
                    "buffer view {view_index} does not exist ({} views)",
                    root.buffer_views.len()
                ),
            )
        })?;
        let vat = format!("bufferViews[{view_index}]");
        let buffer = self.buffers.get(view.buffer).ok_or_else(|| {
            Error::format(
                format!("{vat}.buffer"),
                format!(
                    "buffer {} does not exist ({} buffers)",
                    view.buffer,
                    self.buffers.len()
                ),
            )
        })?;
        let elem = (component.size() * width) as u64;
        let stride = view.byte_stride.unwrap_or(elem);
        if stride < elem {
            return Err(Error::format(
                format!("{vat}.byteStride"),
                format!("{stride} is less than the {elem}-byte element of {at}"),
            ));
        }
        let view_end = view.byte_offset.checked_add(view.byte_length);
        if view_end.is_none_or(|e| e > buffer.len() as u64) {
            return Err(Error::format(
                &vat,
                format!(
                    "bytes {} + {} lie outside buffer {} ({} bytes)",
                    view.byte_offset,
                    view.byte_length,
                    view.buffer,
                    buffer.len()
                ),
            ));
        }
        // The last element must end inside the view: offset + (count − 1) · stride + elem.
        let needed = match count.checked_sub(1) {
            None => Some(a.byte_offset),
            Some(last) => last
                .checked_mul(stride)
                .and_then(|v| v.checked_add(elem))
                .and_then(|v| v.checked_add(a.byte_offset)),
        };
        if needed.is_none_or(|n| n > view.byte_length) {
            return Err(Error::format(
                &at,
                format!(
                    "{count} elements of {elem} bytes every {stride} from byte {} do not fit \
                     in buffer view {view_index} ({} bytes)",
                    a.byte_offset, view.byte_length
                ),
            ));
        }
        // Everything above is bounded by the buffer's length, which is a usize.
        let start = view.byte_offset as usize + a.byte_offset as usize;
        Ok(Acc {
            buffer: view.buffer,
            start,
            stride: stride as usize,
            component,
            normalized: a.normalized,
            name: name.to_string(),
        })
    }

    /// Whether any component of the first `count` elements of `acc` is negative.
    fn any_negative(&self, acc: &Acc, count: usize) -> bool {
        (0..count)
            .into_par_iter()
            .any(|k| (0..3).any(|c| self.value(acc, k, c).is_ok_and(|v| v < 0.0)))
    }

    /// Component `c` of element `k` of `acc` as a float (normalized integers per glTF 2.0 §3.11).
    fn value(&self, acc: &Acc, k: usize, c: usize) -> Result<f32> {
        let size = acc.component.size();
        let at = acc.start + k * acc.stride + c * size;
        let bytes = self
            .buffers
            .get(acc.buffer)
            .and_then(|b| b.get(at..at + size))
            .ok_or_else(|| Error::format(format!("{}[{k}]", acc.name), "outside its buffer"))?;
        let mut raw = [0u8; 4];
        raw[..size].copy_from_slice(bytes);
        let n = acc.normalized;
        Ok(match acc.component {
            Component::F32 => f32::from_le_bytes(raw),
            Component::I8 if n => (f32::from(raw[0] as i8) / 127.0).max(-1.0),
            Component::I8 => f32::from(raw[0] as i8),
            Component::U8 if n => f32::from(raw[0]) / 255.0,
            Component::U8 => f32::from(raw[0]),
            Component::I16 => {
                let v = f32::from(i16::from_le_bytes([raw[0], raw[1]]));
                if n { (v / 32767.0).max(-1.0) } else { v }
            }
            Component::U16 => {
                let v = f32::from(u16::from_le_bytes([raw[0], raw[1]]));
                if n { v / 65535.0 } else { v }
            }
            Component::U32 => u32::from_le_bytes(raw) as f32,
        })
    }

    fn values<const N: usize>(&self, acc: &Acc, k: usize) -> Result<[f64; N]> {
        let mut out = [0.0; N];
        for (c, o) in out.iter_mut().enumerate() {
            *o = f64::from(self.value(acc, k, c)?);
        }
        Ok(out)
    }

    /// Gaussian `k` of `part`, in the decoded frame.
    fn gaussian(&self, part: &Part, k: usize) -> Result<Gaussian> {
        let bad = |acc: &Acc, why: &str| {
            Err(Error::format(
                format!("{}.{}[{k}]", part.location, acc.name),
                why.to_string(),
            ))
        };
        let p = self.values::<3>(&part.position, k)?;
        if !p.iter().all(|v| v.is_finite()) {
            return bad(&part.position, "position is not finite");
        }
        let [x, y, z, w] = self.values::<4>(&part.rotation, k)?;
        if ![x, y, z, w].iter().all(|v| v.is_finite()) || [x, y, z, w] == [0.0; 4] {
            return bad(&part.rotation, "rotation is not finite or is zero");
        }
        let s = self.values::<3>(&part.scale, k)?;
        if !s.iter().all(|v| v.is_finite()) {
            return bad(&part.scale, "scale is not finite");
        }
        let log_scale = if part.scale_is_log {
            s
        } else {
            s.map(|v| {
                if v > 0.0 {
                    v.ln().max(MIN_LOG_SCALE)
                } else {
                    MIN_LOG_SCALE
                }
            })
        };
        let [alpha] = self.values::<1>(&part.opacity, k)?;
        if !(0.0..=1.0).contains(&alpha) {
            return bad(&part.opacity, "opacity is not within [0, 1]");
        }
        let logit = (alpha.ln() - (-alpha).ln_1p()).clamp(-MAX_LOGIT as f64, MAX_LOGIT as f64);
        let sh_dc = match &part.color {
            Color::Sh(acc) => self.values::<3>(acc, k)?,
            Color::Fallback(acc) => self
                .values::<3>(acc, k)?
                .map(|c| (c - 0.5) / f64::from(SH_C0)),
        };
        if !sh_dc.iter().all(|v| v.is_finite()) {
            let acc = match &part.color {
                Color::Sh(a) | Color::Fallback(a) => a,
            };
            return bad(acc, "colour is not finite");
        }
        let mut sh_rest = [[0.0f64; 3]; 15];
        for (coef, acc) in sh_rest.iter_mut().zip(&part.rest) {
            *coef = self.values::<3>(acc, k)?;
            if !coef.iter().all(|v| v.is_finite()) {
                return bad(acc, "SH coefficient is not finite");
            }
        }
        let out = match &part.frame {
            Frame::Convention => {
                // Rz(180°)⁻¹: exact sign flips, and q ↦ (0, 0, −1, 0) ⊗ q written out.
                for (coef, sign) in sh_rest.iter_mut().zip(RZ180_SH_SIGNS) {
                    *coef = coef.map(|v| v * sign);
                }
                Gaussian {
                    position: Vec3::new(-p[0] as f32, -p[1] as f32, p[2] as f32),
                    rotation: Quat::from_xyzw(y as f32, -x as f32, -w as f32, z as f32),
                    log_scale: Vec3::from_array(log_scale.map(|v| v as f32)),
                    opacity_logit: logit as f32,
                    sh_dc: sh_dc.map(|v| v as f32),
                    sh_rest: sh_rest.map(|c| c.map(|v| v as f32)),
                    instance: 0,
                }
            }
            Frame::General(g) => {
                let position = g.affine.transform_point3(DVec3::from_array(p));
                let q = DQuat::from_xyzw(x, y, z, w);
                let (q, log_scale) = match g.log_scale {
                    Some(ls) => (g.rotation * q, log_scale.map(|v| v + ls)),
                    None => transform_covariance(&g.linear, q, log_scale),
                };
                rotate_sh(&g.sh, &mut sh_rest);
                Gaussian {
                    position: position.as_vec3(),
                    rotation: q.as_quat(),
                    log_scale: Vec3::from_array(log_scale.map(|v| v as f32)),
                    opacity_logit: logit as f32,
                    sh_dc: sh_dc.map(|v| v as f32),
                    sh_rest: sh_rest.map(|c| c.map(|v| v as f32)),
                    instance: 0,
                }
            }
        };
        Ok(out)
    }
}

impl BlockDecoder for GltfDecoder {
    fn len(&self) -> usize {
        self.len
    }

    fn sh_degree(&self) -> u8 {
        self.sh_degree
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        if start
            .checked_add(out.len())
            .is_none_or(|end| end > self.len)
        {
            return Err(Error::invalid(format!(
                "Gaussians {start}..{} requested from a glTF of {}",
                start.saturating_add(out.len()),
                self.len
            )));
        }
        // Parts are in index order; find the one holding `start`, then walk forward.
        let mut pi = self.parts.partition_point(|p| p.start + p.count <= start);
        for (j, g) in out.iter_mut().enumerate() {
            let i = start + j;
            while self.parts.get(pi).is_some_and(|p| p.start + p.count <= i) {
                pi += 1;
            }
            let part = self.parts.get(pi).ok_or_else(|| {
                Error::invalid(format!("Gaussian {i} is past the last primitive"))
            })?;
            *g = self.gaussian(part, i - part.start)?;
        }
        Ok(())
    }
}

/// True for a GLB (magic `glTF`) or glTF JSON text naming `KHR_gaussian_splatting`.
pub fn sniff(bytes: &[u8]) -> bool {
    if bytes.starts_with(GLB_MAGIC) {
        return true;
    }
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let first = text.iter().find(|b| !b.is_ascii_whitespace());
    first == Some(&b'{')
        && text
            .windows(EXTENSION.len())
            .any(|w| w == EXTENSION.as_bytes())
}

// ---- container ----

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// The JSON text and, for a GLB, its BIN chunk.
fn container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    if !bytes.starts_with(GLB_MAGIC) {
        let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        if text.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
            return Err(Error::format(
                "header",
                "neither a GLB (magic 'glTF') nor glTF JSON text",
            ));
        }
        return Ok((text, None));
    }
    let header = |what: &str| Error::format("GLB header", what.to_string());
    let version = u32_at(bytes, 4).ok_or_else(|| header("truncated (under 12 bytes)"))?;
    let length = u32_at(bytes, 8).ok_or_else(|| header("truncated (under 12 bytes)"))?;
    if version != 2 {
        return Err(header(&format!(
            "version {version}; only GLB version 2 is supported"
        )));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(header(&format!(
            "declares {length} bytes but the file has {}: truncated",
            bytes.len()
        )));
    }
    let file = &bytes[..length];
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < file.len() {
        let chunk = format!("GLB chunk {index}");
        let (Some(size), Some(kind)) = (u32_at(file, at), u32_at(file, at + 4)) else {
            return Err(Error::format(chunk, "truncated chunk header"));
        };
        let data = at
            .checked_add(8)
            .and_then(|s| Some(s..s.checked_add(size as usize)?))
            .and_then(|r| file.get(r))
            .ok_or_else(|| {
                Error::format(
                    &chunk,
                    format!(
                        "declares {size} bytes but only {} remain: truncated",
                        file.len().saturating_sub(at + 8)
                    ),
                )
            })?;
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(data),
            (0, _) => {
                return Err(Error::format(chunk, "the first chunk must be JSON"));
            }
            (1, CHUNK_BIN) => bin = Some(data),
            _ => {} // Unknown chunks are skipped, as glTF asks.
        }
        at += 8 + data.len();
        index += 1;
    }
    let json = json.ok_or_else(|| Error::format("GLB chunk 0", "missing JSON chunk"))?;
    // Writers pad the JSON with spaces (as specified) or, sometimes, NULs.
    let end = json.iter().rposition(|&b| b != 0).map_or(0, |p| p + 1);
    Ok((&json[..end], bin))
}

/// Every buffer's bytes, cut to its declared length (which must be present).
fn load_buffers(root: &Root, bin: Option<&[u8]>) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::with_capacity(root.buffers.len().min(1024));
    for (i, buffer) in root.buffers.iter().enumerate() {
        let at = format!("buffers[{i}]");
        let mut data = match (&buffer.uri, bin) {
            (None, Some(bin)) if i == 0 => bin.to_vec(),
            (None, _) => {
                return Err(Error::format(
                    at,
                    "has no uri and is not the GLB binary chunk",
                ));
            }
            (Some(uri), _) if uri.starts_with("data:") => {
                data_uri(uri).map_err(|why| Error::format(format!("{at}.uri"), why))?
            }
            (Some(uri), _) => {
                return Err(Error::format(
                    format!("{at}.uri"),
                    format!(
                        "refers to the external file '{uri}'; only GLB and .gltf with embedded \
                         (base64 data:) buffers can be read — pack the file as GLB"
                    ),
                ));
            }
        };
        if (data.len() as u64) < buffer.byte_length {
            return Err(Error::format(
                at,
                format!(
                    "declares {} bytes but holds {}: truncated",
                    buffer.byte_length,
                    data.len()
                ),
            ));
        }
        data.truncate(buffer.byte_length as usize);
        out.push(data);
    }
    Ok(out)
}

/// The bytes of a `data:[<media type>];base64,<data>` URI.
fn data_uri(uri: &str) -> std::result::Result<Vec<u8>, String> {
    let (head, body) = uri
        .split_once(',')
        .ok_or_else(|| "a data: URI without a comma".to_string())?;
    if !head.ends_with(";base64") {
        return Err("only base64 data: URIs are supported".to_string());
    }
    base64_decode(body.as_bytes())
}

/// Standard base64 (RFC 4648 §4), padding optional.
fn base64_decode(text: &[u8]) -> std::result::Result<Vec<u8>, String> {
    let text = match text.iter().rposition(|&b| b != b'=') {
        Some(p) => &text[..=p],
        None => &text[..0],
    };
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc = 0u32;
    let mut bits = 0u32;
    for (i, &c) in text.iter().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return Err(format!("invalid base64 character at byte {i} of the data")),
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err("base64 data of an impossible length".to_string());
    }
    Ok(out)
}

// ---- scene traversal and frames ----

/// A mesh instance: the node (if any), the mesh and the world matrix (`None` for the identity).
type Instance = (Option<usize>, usize, Option<DMat4>);

/// Every mesh instance of the default scene, in scene order. Without scenes, the root nodes are
/// used; without nodes, every mesh once, untransformed.
fn instances(root: &Root) -> Result<Vec<Instance>> {
    let roots: Vec<usize> = if let Some(s) = root.scene {
        root.scenes
            .get(s)
            .ok_or_else(|| {
                Error::format(
                    "scene",
                    format!("scene {s} does not exist ({} scenes)", root.scenes.len()),
                )
            })?
            .nodes
            .clone()
    } else if let Some(first) = root.scenes.first() {
        first.nodes.clone()
    } else if !root.nodes.is_empty() {
        let mut child = vec![false; root.nodes.len()];
        for n in &root.nodes {
            for &c in &n.children {
                if let Some(f) = child.get_mut(c) {
                    *f = true;
                }
            }
        }
        (0..root.nodes.len()).filter(|&i| !child[i]).collect()
    } else {
        return Ok((0..root.meshes.len()).map(|m| (None, m, None)).collect());
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut out = Vec::new();
    // Depth-first with an explicit stack (no recursion on file-controlled depth); children are
    // pushed in reverse so they are visited in order.
    let mut stack: Vec<(usize, DMat4)> =
        roots.iter().rev().map(|&n| (n, DMat4::IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        let at = format!("nodes[{n}]");
        let node = root.nodes.get(n).ok_or_else(|| {
            Error::format(&at, format!("does not exist ({} nodes)", root.nodes.len()))
        })?;
        if std::mem::replace(&mut visited[n], true) {
            return Err(Error::format(
                at,
                "is reached twice (glTF nodes must form disjoint trees)",
            ));
        }
        let world = parent * local_matrix(node).map_err(|e| e.within(at.clone()))?;
        if let Some(m) = node.mesh {
            let matrix = (world != DMat4::IDENTITY).then_some(world);
            out.push((Some(n), m, matrix));
        }
        for &c in node.children.iter().rev() {
            stack.push((c, world));
        }
    }
    Ok(out)
}

/// A node's local matrix (its `matrix`, or T · R · S).
fn local_matrix(node: &NodeJson) -> Result<DMat4> {
    if node.matrix.is_none()
        && node.translation.is_none()
        && node.rotation.is_none()
        && node.scale.is_none()
    {
        return Ok(DMat4::IDENTITY);
    }
    if let Some(m) = node.matrix {
        if node.translation.is_some() || node.rotation.is_some() || node.scale.is_some() {
            return Err(Error::format(
                "matrix",
                "a node may have a matrix or TRS properties, not both",
            ));
        }
        let m = DMat4::from_cols_array(&m);
        if m.row(3) != glam::DVec4::new(0.0, 0.0, 0.0, 1.0) {
            return Err(Error::format(
                "matrix",
                "is not affine (last row ≠ 0 0 0 1)",
            ));
        }
        return Ok(m);
    }
    let t = DVec3::from_array(node.translation.unwrap_or([0.0; 3]));
    let s = DVec3::from_array(node.scale.unwrap_or([1.0; 3]));
    let [x, y, z, w] = node.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let q = DQuat::from_xyzw(x, y, z, w);
    if !q.is_finite() || q.length() < 1e-6 {
        return Err(Error::format(
            "rotation",
            "is not a finite, non-zero quaternion",
        ));
    }
    Ok(DMat4::from_scale_rotation_translation(s, q.normalize(), t))
}

/// The transform of a primitive under node world matrix `m`, composed with the inverse GLB
/// convention; an error unless `m` is a rotation (possibly mirrored) times a uniform scale.
fn general_frame(m: &DMat4) -> Result<General> {
    if !m.is_finite() {
        return Err(Error::format("node transform", "is not finite"));
    }
    let linear = DMat3::from_mat4(*m);
    let lengths = [linear.x_axis, linear.y_axis, linear.z_axis].map(|c| c.length());
    // Decomposable into T · R · S (the spec's condition): columns of positive length that are
    // orthogonal once normalised.
    let decomposable = lengths.iter().all(|&l| l > 0.0 && l.is_finite()) && {
        let u = linear * DMat3::from_diagonal(DVec3::from_array(lengths.map(|l| 1.0 / l)));
        let d = u.transpose() * u - DMat3::IDENTITY;
        [d.x_axis, d.y_axis, d.z_axis]
            .iter()
            .all(|c| c.abs().max_element() <= RIGID_TOLERANCE)
    };
    if !decomposable {
        return Err(Error::format(
            "node transform",
            format!(
                "is not a translation, rotation and positive scale (axis lengths {:.6}, {:.6},                  {:.6}, or a shear), which the extension leaves undefined",
                lengths[0], lengths[1], lengths[2]
            ),
        ));
    }
    let mut u = linear * DMat3::from_diagonal(DVec3::from_array(lengths.map(|l| 1.0 / l)));
    let mirrored = u.determinant() < 0.0;
    if mirrored {
        // Undefined by the extension; read as −U (a proper rotation) times a negative scale: the
        // sign leaves covariances alone and negates the SH of odd degree.
        u = -u;
    }
    let node_rotation = DQuat::from_mat3(&u).normalize();
    let rotation = CONVENTION_INVERSE * node_rotation;
    let c = DMat3::from_quat(rotation);
    let mut sh = [[[0.0; 7]; 7]; 3];
    for (l, band) in sh.iter_mut().enumerate() {
        *band = sh_band_rotation(l + 1, &c)?;
        if mirrored && l % 2 == 0 {
            for row in band.iter_mut() {
                for v in row.iter_mut() {
                    *v = -*v;
                }
            }
        }
    }
    let mean = (lengths[0] + lengths[1] + lengths[2]) / 3.0;
    let uniform = lengths
        .iter()
        .all(|&l| (l / mean - 1.0).abs() <= RIGID_TOLERANCE);
    let affine = DMat4::from_quat(CONVENTION_INVERSE) * *m;
    Ok(General {
        affine,
        rotation,
        log_scale: uniform.then(|| mean.ln()),
        linear: DMat3::from_mat4(affine),
        sh,
    })
}

/// Rotation and natural-log scales of the Gaussian `(q, log_scale)` after the linear map `a`:
/// the covariance `a R S² Rᵀ aᵀ` decomposed again (Jacobi eigenvalues, in `f64`).
fn transform_covariance(a: &DMat3, q: DQuat, log_scale: [f64; 3]) -> (DQuat, [f64; 3]) {
    let r = DMat3::from_quat(q.normalize());
    let m = a * r * DMat3::from_diagonal(DVec3::from_array(log_scale).exp());
    let cov = m * m.transpose();
    let (values, vectors) = symmetric_eigen(cov);
    let mut v = vectors;
    if v.determinant() < 0.0 {
        v.z_axis = -v.z_axis;
    }
    let log = values.map(|e| {
        if e > 0.0 {
            (0.5 * e.ln()).max(MIN_LOG_SCALE)
        } else {
            MIN_LOG_SCALE
        }
    });
    (DQuat::from_mat3(&v).normalize(), log)
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3×3 matrix by cyclic Jacobi rotations.
fn symmetric_eigen(m: DMat3) -> ([f64; 3], DMat3) {
    let mut a = m.to_cols_array_2d();
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let scale = a.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
    for _sweep in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off <= scale * 1e-18 || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // The rotation zeroing a[p][q] (Golub & Van Loan, symmetric Schur).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← A J (columns p, q), then A ← Jᵀ A (rows p, q), V ← V J.
            for row in a.iter_mut() {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // `v` holds the eigenvectors as columns in row-major form: transpose into glam's columns.
    let vectors = DMat3::from_cols_array_2d(&v).transpose();
    ([a[0][0], a[1][1], a[2][2]], vectors)
}

/// `Rz(180°)⁻¹` as a quaternion (x, y, z, w) = (0, 0, −1, 0): with it, the rotation written by
/// `splat-transform` (`Rz(180°) ⊗ q`) comes back to `q` with its sign.
const CONVENTION_INVERSE: DQuat = DQuat::from_xyzw(0.0, 0.0, -1.0, 0.0);

/// The factor `Rz(180°)` applies to each higher-order SH coefficient: −1 where the basis
/// function is odd in (x, y) together.
const RZ180_SH_SIGNS: [f64; 15] = [
    -1.0, 1.0, -1.0, // degree 1: y, z, x
    1.0, -1.0, 1.0, -1.0, 1.0, // degree 2: xy, yz, 3z²−1, xz, x²−y²
    -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, // degree 3
];

// ---- SH rotation ----

/// The real SH basis of degree `l` (1–3) at unit direction `d`, in the 3DGS order and signs
/// (the constants of the reference rasterizer, also in the extension's Appendix A).
pub(crate) fn sh_basis(l: usize, d: DVec3) -> [f64; 7] {
    let (x, y, z) = (d.x, d.y, d.z);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    const C1: f64 = 0.488_602_511_902_919_9;
    const C2: [f64; 5] = [
        1.092_548_430_592_079_2,
        -1.092_548_430_592_079_2,
        0.315_391_565_252_520_05,
        -1.092_548_430_592_079_2,
        0.546_274_215_296_039_6,
    ];
    const C3: [f64; 7] = [
        -0.590_043_589_926_643_5,
        2.890_611_442_640_554,
        -0.457_045_799_464_465_8,
        0.373_176_332_590_115_4,
        -0.457_045_799_464_465_8,
        1.445_305_721_320_277,
        -0.590_043_589_926_643_5,
    ];
    match l {
        1 => [-C1 * y, C1 * z, -C1 * x, 0.0, 0.0, 0.0, 0.0],
        2 => [
            C2[0] * x * y,
            C2[1] * y * z,
            C2[2] * (2.0 * zz - xx - yy),
            C2[3] * x * z,
            C2[4] * (xx - yy),
            0.0,
            0.0,
        ],
        _ => [
            C3[0] * y * (3.0 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4.0 * zz - xx - yy),
            C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            C3[4] * x * (4.0 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3.0 * yy),
        ],
    }
}

/// Generic unit directions at which the basis is sampled: any `2l + 1` of them in general
/// position make the sample matrix invertible (checked by the tests for each degree).
const SAMPLES: [[f64; 3]; 7] = [
    [0.267, 0.535, 0.802],
    [-0.861, 0.431, 0.269],
    [0.134, -0.446, 0.885],
    [0.802, 0.281, -0.527],
    [-0.542, -0.813, -0.211],
    [0.241, -0.145, -0.960],
    [-0.560, 0.725, -0.401],
];

/// The matrix `D` taking degree-`l` coefficients `c` of `f` to those of `g(d) = f(Cᵀ d)`, the
/// function rotated by `c`: from `Σ c'ₙ Yₙ(dⱼ) = Σ cₙ Yₙ(Cᵀ dⱼ)` at `2l + 1` sample directions,
/// `D = A⁻¹ B` (exact up to rounding, since each degree's span is closed under rotation).
fn sh_band_rotation(l: usize, c: &DMat3) -> Result<[[f64; 7]; 7]> {
    let n = 2 * l + 1;
    let mut a = [[0.0; 7]; 7];
    let mut b = [[0.0; 7]; 7];
    let ct = c.transpose();
    for j in 0..n {
        let d = DVec3::from_array(SAMPLES[j]).normalize();
        a[j] = sh_basis(l, d);
        b[j] = sh_basis(l, ct * d);
    }
    // Gauss–Jordan elimination with partial pivoting on [A | B].
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &k| a[i][col].abs().total_cmp(&a[k][col].abs()))
            .unwrap_or(col);
        if a[pivot][col].abs() < 1e-9 {
            return Err(Error::format(
                "SH rotation",
                "the sample directions are degenerate (a bug)",
            ));
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let inv = 1.0 / a[col][col];
        for k in 0..n {
            a[col][k] *= inv;
            b[col][k] *= inv;
        }
        for row in 0..n {
            if row != col {
                let f = a[row][col];
                if f != 0.0 {
                    for k in 0..n {
                        a[row][k] -= f * a[col][k];
                        b[row][k] -= f * b[col][k];
                    }
                }
            }
        }
    }
    Ok(b)
}

/// Applies the per-degree rotations to coefficient-major SH (`[k][channel]`).
fn rotate_sh(sh: &[[[f64; 7]; 7]; 3], rest: &mut [[f64; 3]; 15]) {
    // Degree l holds coefficients l² − 1 .. (l + 1)² − 1: 0..3, 3..8, 8..15.
    for (l, d) in (1..=3usize).zip(sh) {
        let band = &mut rest[l * l - 1..(l + 1) * (l + 1) - 1];
        let old: [[f64; 3]; 7] = std::array::from_fn(|i| band.get(i).copied().unwrap_or([0.0; 3]));
        for (row, out) in d.iter().zip(band.iter_mut()) {
            *out = std::array::from_fn(|ch| row.iter().zip(&old).map(|(r, v)| r * v[ch]).sum());
        }
    }
}

/// The SH degree of a primitive and its higher-order attributes in coefficient order, checking
/// that every degree up to the highest is complete and no unknown SH attribute is present.
fn sh_attributes(attributes: &BTreeMap<String, usize>) -> Result<(u8, Vec<(String, usize)>)> {
    let prefix = format!("{EXTENSION}:SH_DEGREE_");
    for name in attributes.keys() {
        if let Some(rest) = name.strip_prefix(&prefix) {
            let valid = rest.split_once("_COEF_").is_some_and(|(l, n)| {
                match (l.parse::<usize>(), n.parse::<usize>()) {
                    (Ok(l), Ok(n)) => l <= 3 && n <= 2 * l && format!("{l}_COEF_{n}") == rest,
                    _ => false,
                }
            });
            if !valid {
                return Err(Error::format(
                    name.as_str(),
                    "not an SH attribute of degree 0–3 (SH_DEGREE_ℓ_COEF_n with n ≤ 2ℓ)",
                ));
            }
        }
    }
    let mut degree = 0u8;
    let mut out = Vec::new();
    for l in 1..=3u8 {
        let names: Vec<String> = (0..=2 * l)
            .map(|n| format!("{prefix}{l}_COEF_{n}"))
            .collect();
        let present: Vec<Option<usize>> =
            names.iter().map(|n| attributes.get(n).copied()).collect();
        let found = present.iter().flatten().count();
        if found == 0 {
            continue;
        }
        if found < names.len() || degree + 1 != l {
            let missing = names
                .iter()
                .zip(&present)
                .find(|(_, p)| p.is_none())
                .map(|(n, _)| n.clone())
                .unwrap_or_else(|| format!("{prefix}{}_COEF_0", degree + 1));
            return Err(Error::format(
                missing,
                format!("missing: SH degree {l} is present, so every coefficient up to it must be"),
            ));
        }
        degree = l;
        out.extend(names.into_iter().zip(present.into_iter().flatten()));
    }
    debug_assert_eq!(out.len(), sh_rest_count(degree));
    Ok((degree, out))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec4;
    use proptest::prelude::*;
    use std::path::PathBuf;

    pub(crate) fn testdata(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/splats")
            .join(name)
    }

    /// A standard PLY of the test files at full precision: (Gaussians, SH degree).
    pub(crate) fn read_ply(name: &str) -> (Vec<Gaussian>, u8) {
        let table =
            crate::splats::test_files::standard_table(&std::fs::read(testdata(name)).unwrap());
        (table.gaussians, table.sh_degree)
    }

    fn sigmoid(x: f32) -> f64 {
        1.0 / (1.0 + (-f64::from(x)).exp())
    }

    /// The JSON and BIN chunk of a GLB.
    fn split(glb: &[u8]) -> (Value, Vec<u8>) {
        let (json, bin) = container(glb).unwrap();
        (serde_json::from_slice(json).unwrap(), bin.unwrap().to_vec())
    }

    /// A GLB of `json` and `bin`, padded as the format asks.
    fn pack(json: &Value, bin: &[u8]) -> Vec<u8> {
        let mut text = serde_json::to_vec(json).unwrap();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let mut bin = bin.to_vec();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + text.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        out.extend_from_slice(&text);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
        out
    }

    fn base64_encode(bytes: &[u8]) -> String {
        const ALPHABET: &[u8; 64] =
            b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let b = [
                chunk[0],
                *chunk.get(1).unwrap_or(&0),
                *chunk.get(2).unwrap_or(&0),
            ];
            let v = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
            for i in 0..4 {
                if i <= chunk.len() {
                    out.push(ALPHABET[(v >> (18 - 6 * i) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    }

    fn decode_all(bytes: &[u8]) -> Result<Vec<Gaussian>> {
        GltfDecoder::open(bytes)?.to_table().map(|t| t.gaussians)
    }

    fn message(r: Result<impl Sized>) -> String {
        match r {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    /// Compares a decode of a `splat-transform` GLB with the PLY it was written from.
    fn check_against_ply(stem: &str) {
        let glb = std::fs::read(testdata(&format!("{stem}.glb"))).unwrap();
        let (ply, degree) = read_ply(&format!("{stem}.ply"));
        let decoder = GltfDecoder::open(&glb).unwrap();
        assert_eq!(decoder.len(), ply.len());
        assert_eq!(decoder.sh_degree(), degree);
        assert!(!decoder.legacy_log_scale());
        let table = decoder.to_table().unwrap();
        let (mut pos, mut rot, mut scale, mut alpha, mut logit, mut dc, mut rest) =
            (0f32, 0f32, 0f32, 0f64, 0f32, 0f32, 0f32);
        for (g, r) in table.gaussians.iter().zip(&ply) {
            pos = pos.max((g.position - r.position).abs().max_element());
            // Component-wise, without folding q and −q together: the sign must survive.
            rot = rot.max(
                (Vec4::from(g.rotation) - Vec4::from(r.rotation))
                    .abs()
                    .max_element(),
            );
            scale = scale.max((g.log_scale - r.log_scale).abs().max_element());
            alpha = alpha.max((sigmoid(g.opacity_logit) - sigmoid(r.opacity_logit)).abs());
            logit = logit.max((g.opacity_logit - r.opacity_logit).abs());
            for c in 0..3 {
                dc = dc.max((g.sh_dc[c] - r.sh_dc[c]).abs());
                for k in 0..15 {
                    rest = rest.max((g.sh_rest[k][c] - r.sh_rest[k][c]).abs());
                }
            }
            assert_eq!(g.instance, 0);
        }
        println!(
            "{stem}.glb vs {stem}.ply over {} Gaussians: position {pos:e}, rotation {rot:e}, \
             log-scale {scale:e}, alpha {alpha:e} (logit {logit:e}), f_dc {dc:e}, f_rest {rest:e}",
            ply.len()
        );
        // Positions, rotations and SH are permuted/negated only: bit-exact.
        assert_eq!(pos, 0.0);
        assert_eq!(rot, 0.0);
        assert_eq!(dc, 0.0);
        assert_eq!(rest, 0.0);
        // exp and sigmoid went through f32 in the writer.
        assert!(scale < 2e-6, "{scale}");
        assert!(alpha < 2e-7, "{alpha}");
        assert!(logit < 1e-3, "{logit}");
    }

    #[test]
    fn sh0_glb_matches_its_ply() {
        check_against_ply("random_3k_sh0");
    }

    #[test]
    fn sh3_glb_matches_its_ply() {
        check_against_ply("random_4k_sh3");
    }

    #[test]
    fn blocks_decode_like_the_whole() {
        let glb = std::fs::read(testdata("random_4k_sh3.glb")).unwrap();
        let d = GltfDecoder::open(&glb).unwrap();
        let all = d.to_table().unwrap().gaussians;
        let mut part = vec![Gaussian::default(); 100];
        d.decode(1234, &mut part).unwrap();
        assert_eq!(part[..], all[1234..1334]);
        assert!(d.decode(4000, &mut part).is_err());
        assert!(d.decode(usize::MAX, &mut part).is_err());
        let store = d.to_gaussians().unwrap();
        assert_eq!(store.len(), all.len());
    }

    #[test]
    fn sniffs_glb_and_gltf_json() {
        let glb = std::fs::read(testdata("random_3k_sh0.glb")).unwrap();
        assert!(sniff(&glb));
        assert!(sniff(br#"  {"extensionsUsed":["KHR_gaussian_splatting"]}"#));
        assert!(!sniff(br#"{"asset":{"version":"2.0"}}"#));
        assert!(!sniff(b"ply\nformat binary_little_endian 1.0\n"));
        assert!(!sniff(b""));
    }

    #[test]
    fn gltf_with_data_uri_decodes_like_the_glb() {
        let glb = std::fs::read(testdata("random_4k_sh3.glb")).unwrap();
        let (mut json, bin) = split(&glb);
        json["buffers"][0]["uri"] = format!(
            "data:application/octet-stream;base64,{}",
            base64_encode(&bin)
        )
        .into();
        let text = serde_json::to_vec_pretty(&json).unwrap();
        assert!(sniff(&text));
        assert_eq!(decode_all(&text).unwrap(), decode_all(&glb).unwrap());

        json["buffers"][0]["uri"] = "scene.bin".into();
        let text = serde_json::to_vec(&json).unwrap();
        let e = message(GltfDecoder::open(&text));
        assert!(
            e.contains("buffers[0].uri") && e.contains("external file"),
            "{e}"
        );

        json["buffers"][0]["uri"] = "data:application/octet-stream;base64,AB$C".into();
        let e = message(GltfDecoder::open(&serde_json::to_vec(&json).unwrap()));
        assert!(e.contains("base64"), "{e}");
    }

    #[test]
    fn base64_round_trips() {
        for n in 0..10 {
            let data: Vec<u8> = (0..n).map(|i| (i * 37 + 11) as u8).collect();
            assert_eq!(
                base64_decode(base64_encode(&data).as_bytes()).unwrap(),
                data
            );
        }
        assert!(base64_decode(b"A").is_err());
    }

    /// The GLB of the degree-3 file with its SCALE replaced by the PLY's logs (as the
    /// pre-ratification drafts stored them).
    #[test]
    fn log_space_scales_of_draft_files_are_detected() {
        let glb = std::fs::read(testdata("random_4k_sh3.glb")).unwrap();
        let (ply, _) = read_ply("random_4k_sh3.ply");
        let (json, mut bin) = split(&glb);
        let attr = &json["meshes"][0]["primitives"][0]["attributes"];
        let acc = attr["KHR_gaussian_splatting:SCALE"].as_u64().unwrap() as usize;
        let view = json["accessors"][acc]["bufferView"].as_u64().unwrap() as usize;
        let offset = json["bufferViews"][view]["byteOffset"].as_u64().unwrap() as usize;
        for (i, g) in ply.iter().enumerate() {
            for c in 0..3 {
                let at = offset + (i * 3 + c) * 4;
                bin[at..at + 4].copy_from_slice(&g.log_scale[c].to_le_bytes());
            }
        }
        let d = GltfDecoder::open(&pack(&json, &bin)).unwrap();
        assert!(d.legacy_log_scale());
        let out = d.to_table().unwrap().gaussians;
        for (g, r) in out.iter().zip(&ply) {
            assert_eq!(g.log_scale, r.log_scale);
        }
    }

    fn sh3_json() -> (Value, Vec<u8>) {
        split(&std::fs::read(testdata("random_4k_sh3.glb")).unwrap())
    }

    /// A change to a glTF document.
    type Edit = Box<dyn Fn(&mut Value)>;

    #[test]
    fn clear_errors_for_unsupported_or_broken_files() {
        let (json, bin) = sh3_json();
        const PRIM: &str = "/meshes/0/primitives/0";
        let cases: Vec<(Edit, &str)> = vec![
            (
                Box::new(|j| j["meshes"][0]["primitives"][0]["mode"] = 4.into()),
                "mode 0 (POINTS)",
            ),
            (
                Box::new(|j| {
                    j.pointer_mut(&format!("{PRIM}/attributes"))
                        .unwrap()
                        .as_object_mut()
                        .unwrap()
                        .remove("KHR_gaussian_splatting:ROTATION");
                }),
                "KHR_gaussian_splatting:ROTATION is missing",
            ),
            (
                Box::new(|j| {
                    j.pointer_mut(&format!("{PRIM}/attributes"))
                        .unwrap()
                        .as_object_mut()
                        .unwrap()
                        .remove("KHR_gaussian_splatting:SH_DEGREE_2_COEF_3");
                }),
                "SH_DEGREE_2_COEF_3",
            ),
            (
                Box::new(|j| {
                    j.pointer_mut(&format!("{PRIM}/attributes"))
                        .unwrap()
                        .as_object_mut()
                        .unwrap()
                        .insert("KHR_gaussian_splatting:SH_DEGREE_4_COEF_0".into(), 5.into());
                }),
                "degree 0–3",
            ),
            (
                Box::new(|j| {
                    let attrs = j
                        .pointer_mut(&format!("{PRIM}/attributes"))
                        .unwrap()
                        .as_object_mut()
                        .unwrap();
                    let r = attrs.remove("KHR_gaussian_splatting:ROTATION").unwrap();
                    attrs.insert("_ROTATION".into(), r);
                }),
                "_ROTATION/_SCALE layout",
            ),
            (
                Box::new(|j| j["accessors"][5]["componentType"] = 5121.into()),
                "SH_DEGREE_0_COEF_0 cannot be unsigned byte",
            ),
            (
                Box::new(|j| j["accessors"][2]["componentType"] = 5125.into()),
                "ROTATION cannot be unsigned int",
            ),
            (
                Box::new(|j| j["accessors"][4]["componentType"] = 9999.into()),
                "not a glTF component type",
            ),
            (
                Box::new(|j| j["accessors"][3]["type"] = "VEC4".into()),
                "expected VEC3",
            ),
            (
                Box::new(|j| j["accessors"][3]["count"] = 4095.into()),
                "POSITION has 4096",
            ),
            (
                Box::new(|j| j["accessors"][0]["count"] = u64::MAX.into()),
                "do not fit",
            ),
            (
                Box::new(|j| j["accessors"][2]["byteOffset"] = 4.into()),
                "do not fit",
            ),
            (
                Box::new(|j| j["bufferViews"][2]["byteStride"] = 8.into()),
                "byteStride",
            ),
            (
                Box::new(|j| j["bufferViews"][2]["byteLength"] = 1_000_000_000.into()),
                "outside buffer",
            ),
            (
                Box::new(|j| j["accessors"][2]["bufferView"] = 999.into()),
                "buffer view 999 does not exist",
            ),
            (
                Box::new(|j| j["accessors"][1]["sparse"] = serde_json::json!({"count": 1})),
                "", // COLOR_0 is unused when SH degree 0 is present: no error
            ),
            (
                Box::new(|j| j["accessors"][2]["sparse"] = serde_json::json!({"count": 1})),
                "sparse",
            ),
            (
                Box::new(|j| {
                    j["extensionsRequired"] = serde_json::json!(["EXT_meshopt_compression"])
                }),
                "EXT_meshopt_compression",
            ),
            (
                Box::new(|j| {
                    j.pointer_mut(&format!("{PRIM}/extensions"))
                        .unwrap()
                        .as_object_mut()
                        .unwrap()
                        .clear();
                }),
                "no primitive",
            ),
            (
                // A shear: not decomposable into T · R · S.
                Box::new(|j| {
                    j["nodes"][0]["matrix"] = serde_json::json!([
                        1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
                        1.0
                    ])
                }),
                "is not a translation, rotation and positive scale",
            ),
            (
                Box::new(|j| j["nodes"][0]["children"] = serde_json::json!([0])),
                "reached twice",
            ),
            (
                Box::new(|j| {
                    for a in j["accessors"].as_array_mut().unwrap() {
                        a["count"] = 0.into();
                    }
                }),
                "", // an empty splat primitive is valid
            ),
            (
                Box::new(|j| {
                    for a in j["accessors"].as_array_mut().unwrap() {
                        a["count"] = 0.into();
                    }
                    j["accessors"][0]["byteOffset"] = u64::MAX.into();
                }),
                "do not fit",
            ),
            (
                Box::new(|j| j["scene"] = 3.into()),
                "scene 3 does not exist",
            ),
            (
                Box::new(|j| j["buffers"][0]["byteLength"] = 2_000_000.into()),
                "truncated",
            ),
        ];
        for (edit, expected) in cases {
            let mut j = json.clone();
            edit(&mut j);
            let r = decode_all(&pack(&j, &bin));
            if expected.is_empty() {
                assert!(r.is_ok(), "{:?}", r.err().map(|e| e.to_string()));
            } else {
                let e = message(r);
                assert!(e.contains(expected), "expected '{expected}' in: {e}");
            }
        }
    }

    /// Nodes instancing the same mesh: each instance is decoded (here, shifted copies), and
    /// a flood of instances is refused early.
    #[test]
    fn instances_are_concatenated_and_bounded() {
        let glb = std::fs::read(testdata("random_3k_sh0.glb")).unwrap();
        let (mut json, bin) = split(&glb);
        let one = decode_all(&glb).unwrap();
        json["nodes"] = serde_json::json!([
            {"children": [1, 2]},
            {"mesh": 0},
            {"mesh": 0, "translation": [0.0, 0.0, 5.0]}
        ]);
        let two = decode_all(&pack(&json, &bin)).unwrap();
        assert_eq!(two.len(), 2 * one.len());
        assert_eq!(two[..one.len()], one[..]);
        for (a, b) in two[one.len()..].iter().zip(&one) {
            // glTF z is the PLY's z under the Rz(180°) convention.
            assert!(
                (a.position - b.position - Vec3::new(0.0, 0.0, 5.0))
                    .abs()
                    .max_element()
                    < 1e-5
            );
            assert_eq!(a.log_scale, b.log_scale);
        }
        let many: Vec<Value> = (0..10_000)
            .map(|_| serde_json::json!({"mesh": 0}))
            .collect();
        json["nodes"] = many.into();
        json["scenes"][0]["nodes"] = (0..10_000).collect::<Vec<usize>>().into();
        let start = std::time::Instant::now();
        let e = message(GltfDecoder::open(&pack(&json, &bin)));
        assert!(e.contains("too many instances"), "{e}");
        assert!(start.elapsed().as_secs_f64() < 2.0);
    }

    #[test]
    fn colour_falls_back_to_color_0() {
        let (mut json, bin) = split(&std::fs::read(testdata("random_3k_sh0.glb")).unwrap());
        json["meshes"][0]["primitives"][0]["attributes"]
            .as_object_mut()
            .unwrap()
            .remove("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0");
        let (ply, _) = read_ply("random_3k_sh0.ply");
        let out = decode_all(&pack(&json, &bin)).unwrap();
        for (g, r) in out.iter().zip(&ply) {
            for c in 0..3 {
                let expect = (0.5 + SH_C0 * r.sh_dc[c]).clamp(0.0, 1.0);
                let got = 0.5 + SH_C0 * g.sh_dc[c];
                assert!((got - expect).abs() <= 0.5 / 255.0 + 1e-6, "{got} {expect}");
            }
        }
    }

    /// The rotation matrices of each degree: identity for the identity, orthogonal, a
    /// homomorphism, and `Rz(180°)` the sign flips `splat-transform` applied.
    #[test]
    fn sh_rotation_matrices() {
        let r1 = DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(1.0, 2.0, -0.5).normalize(),
            0.7,
        ));
        let r2 = DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(-0.3, 0.1, 1.0).normalize(),
            -2.1,
        ));
        let rz = DMat3::from_quat(DQuat::from_rotation_z(std::f64::consts::PI));
        for l in 1..=3 {
            let n = 2 * l + 1;
            let id = sh_band_rotation(l, &DMat3::IDENTITY).unwrap();
            let a = sh_band_rotation(l, &r1).unwrap();
            let b = sh_band_rotation(l, &r2).unwrap();
            let ab = sh_band_rotation(l, &(r1 * r2)).unwrap();
            let z = sh_band_rotation(l, &rz).unwrap();
            for i in 0..n {
                for k in 0..n {
                    let delta = if i == k { 1.0 } else { 0.0 };
                    assert!((id[i][k] - delta).abs() < 1e-12);
                    let ata: f64 = (0..n).map(|m| a[m][i] * a[m][k]).sum();
                    assert!((ata - delta).abs() < 1e-12, "degree {l} not orthogonal");
                    let prod: f64 = (0..n).map(|m| a[i][m] * b[m][k]).sum();
                    assert!(
                        (prod - ab[i][k]).abs() < 1e-12,
                        "degree {l} not a homomorphism"
                    );
                    let sign = RZ180_SH_SIGNS[l * l - 1 + i];
                    assert!((z[i][k] - if i == k { sign } else { 0.0 }).abs() < 1e-12);
                }
            }
        }
    }

    /// Node transforms — rotation, translation and a uniform scale; a non-uniform scale; a
    /// mirror — move the Gaussians, transform their covariances (`L Σ Lᵀ`) and rotate their
    /// view-dependent colour by the transform's rotation part.
    #[test]
    fn node_transforms_are_applied() {
        let (ply, _) = read_ply("random_4k_sh3.ply");
        let (json, bin) = sh3_json();
        let q = DQuat::from_axis_angle(DVec3::new(0.2, -1.0, 0.4).normalize(), 1.1);
        let t = DVec3::new(1.5, -2.0, 0.25);
        let trs = DMat4::from_scale_rotation_translation(DVec3::splat(2.5), q, t);
        let stretched = DMat4::from_scale_rotation_translation(DVec3::new(0.5, 3.0, 1.25), q, t);
        let mirror = DMat4::from_scale(DVec3::new(1.0, -1.0, 1.0)) * trs;
        let conv = DMat4::from_quat(CONVENTION_INVERSE);
        let ply_to_glb = DMat4::from_quat(CONVENTION_INVERSE.inverse());
        for (name, matrix) in [
            ("uniform", trs),
            ("non-uniform", stretched),
            ("mirror", mirror),
        ] {
            let mut j = json.clone();
            j["nodes"][0]["matrix"] = matrix.to_cols_array().to_vec().into();
            let out = decode_all(&pack(&j, &bin)).unwrap();
            // The full map of the decoded frame: PLY → GLB frame, node, back to PLY.
            let full = conv * matrix * ply_to_glb;
            let lin = DMat3::from_mat4(full);
            // Its orthogonal part (columns normalised), mirror included.
            let cols = [lin.x_axis, lin.y_axis, lin.z_axis].map(|c| c.normalize());
            let orthogonal = DMat3::from_cols(cols[0], cols[1], cols[2]);
            let (mut pos, mut cov_err, mut sh_err) = (0f64, 0f64, 0f64);
            for (g, r) in out.iter().zip(&ply).step_by(7) {
                let p = full.transform_point3(r.position.as_dvec3());
                pos = pos.max((g.position.as_dvec3() - p).abs().max_element());
                let cov = |q: Quat, ls: Vec3| {
                    let m = DMat3::from_quat(q.as_dquat().normalize())
                        * DMat3::from_diagonal(ls.as_dvec3().exp());
                    m * m.transpose()
                };
                let want = lin * cov(r.rotation, r.log_scale) * lin.transpose();
                let got = cov(g.rotation, g.log_scale);
                let scale = want
                    .to_cols_array()
                    .iter()
                    .fold(0f64, |m, v| m.max(v.abs()));
                let err = (got - want)
                    .to_cols_array()
                    .iter()
                    .fold(0f64, |m, v| m.max(v.abs()));
                cov_err = cov_err.max(err / scale);
                // The colour seen along d is the original's along Oᵀ d.
                for d in SAMPLES.iter().map(|d| DVec3::from_array(*d).normalize()) {
                    let back = orthogonal.transpose() * d;
                    for ch in 0..3 {
                        let eval = |sh: &[[f32; 3]; 15], dir: DVec3| -> f64 {
                            (1..=3)
                                .map(|l| {
                                    let y = sh_basis(l, dir);
                                    (0..2 * l + 1)
                                        .map(|i| y[i] * f64::from(sh[l * l - 1 + i][ch]))
                                        .sum::<f64>()
                                })
                                .sum()
                        };
                        let (a, b) = (eval(&g.sh_rest, d), eval(&r.sh_rest, back));
                        sh_err = sh_err.max((a - b).abs());
                    }
                }
            }
            println!(
                "{name} node: position {pos:e}, covariance {cov_err:e} (relative), SH colour \
                 {sh_err:e}"
            );
            assert!(pos < 1e-5, "{name}: position off by {pos}");
            assert!(cov_err < 1e-5, "{name}: covariance off by {cov_err}");
            assert!(sh_err < 1e-5, "{name}: SH off by {sh_err}");
        }
    }

    #[test]
    fn symmetric_eigen_decomposes() {
        let r = DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(1.0, 0.3, -0.7).normalize(),
            0.9,
        ));
        for diag in [
            [4.0, 1e-6, 0.25],
            [1.0, 1.0, 2.0],
            [3.0, 3.0, 3.0],
            [1e-8, 2e-8, 5.0],
        ] {
            let m = r * DMat3::from_diagonal(DVec3::from_array(diag)) * r.transpose();
            let (values, v) = symmetric_eigen(m);
            let back = v * DMat3::from_diagonal(DVec3::from_array(values)) * v.transpose();
            let err = (back - m)
                .to_cols_array()
                .iter()
                .fold(0f64, |a, x| a.max(x.abs()));
            assert!(err < 1e-12, "{diag:?}: {err}");
            let mut got = values;
            got.sort_by(f64::total_cmp);
            let mut want = diag;
            want.sort_by(f64::total_cmp);
            // Absolute: the input's own rounding (~1e-16 of the largest) bounds the small ones.
            for (a, b) in got.iter().zip(want) {
                assert!((a - b).abs() <= 1e-14 * want[2], "{got:?} vs {want:?}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_glb_never_panics(cut in 0usize..181_664) {
            let glb = std::fs::read(testdata("random_3k_sh0.glb")).unwrap();
            let r = decode_all(&glb[..cut.min(glb.len())]);
            prop_assert!(r.is_err());
        }

        #[test]
        fn mutated_glb_never_panics(edits in proptest::collection::vec((0usize..1_000_000, any::<u8>()), 1..16)) {
            let mut glb = std::fs::read(testdata("random_3k_sh0.glb")).unwrap();
            let json_len = u32_at(&glb, 12).unwrap() as usize + 20;
            for (at, v) in edits {
                // Half the edits land in the header and JSON, where the structure lives.
                let at = if at % 2 == 0 { at % json_len } else { at % glb.len() };
                glb[at] = v;
            }
            let _ = decode_all(&glb);
        }

        #[test]
        fn hostile_accessors_are_errors(
            acc in 0usize..6,
            count in prop_oneof![Just(u64::MAX), Just(u64::MAX / 4), Just(0u64), 0u64..10_000_000_000],
            offset in prop_oneof![Just(u64::MAX), Just(0u64), 0u64..10_000_000_000],
            stride in prop_oneof![Just(None), Just(Some(u64::MAX)), Just(Some(0u64)), (0u64..300).prop_map(Some)],
            component in prop_oneof![Just(5126u32), 5119u32..5127],
            kind in prop_oneof![Just("VEC3"), Just("VEC4"), Just("SCALAR"), Just("MAT4")],
        ) {
            let (mut json, bin) = split(&std::fs::read(testdata("random_3k_sh0.glb")).unwrap());
            json["accessors"][acc]["count"] = count.into();
            json["accessors"][acc]["byteOffset"] = offset.into();
            json["accessors"][acc]["componentType"] = component.into();
            json["accessors"][acc]["type"] = kind.into();
            if let Some(s) = stride {
                json["bufferViews"][acc]["byteStride"] = s.into();
            }
            // Only fast, bounded work: any outcome but a panic is fine, and a success must
            // hold no more Gaussians than the file has bytes.
            if let Ok(d) = GltfDecoder::open(&pack(&json, &bin)) {
                prop_assert!(d.len() <= 181_664);
                let _ = d.to_table();
            }
        }
    }
}
