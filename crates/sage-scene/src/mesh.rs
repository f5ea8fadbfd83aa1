//! Triangle meshes: the type, and reading them from OBJ (tobj), glTF/GLB (gltf) and PLY files.

use crate::ply::header::{element_rows, parse_header};
use glam::{Mat4, Vec3};
use sage_core::{Aabb, Error, MAX_COORDINATE, Result, ResultExt, within_bounds};
use sage_io::limits::{Limit, MESH_MB};
use std::io::Write;
use std::path::Path;

/// An indexed triangle mesh in world coordinates (metres, W frame).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// The closed surface of an oriented box: its 8 corners (in [`sage_core::Obb::corners`] order) and 12
    /// triangles wound outwards.
    pub fn from_obb(obb: &sage_core::Obb) -> TriMesh {
        TriMesh {
            positions: obb.corners().to_vec(),
            triangles: vec![
                [0, 2, 1],
                [0, 3, 2],
                [4, 5, 6],
                [4, 6, 7],
                [0, 1, 5],
                [0, 5, 4],
                [1, 2, 6],
                [1, 6, 5],
                [2, 3, 7],
                [2, 7, 6],
                [3, 0, 4],
                [3, 4, 7],
            ],
        }
    }

    /// Appends another mesh (its indices shifted).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    /// The mesh with every vertex transformed by `m`.
    pub fn transformed(&self, m: &Mat4) -> TriMesh {
        TriMesh {
            positions: self
                .positions
                .iter()
                .map(|p| m.transform_point3(*p))
                .collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Corner positions of triangle `t`.
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// Total surface area, m².
    pub fn area(&self) -> f32 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Enclosed volume, m³, for a closed mesh (positive when triangles face outwards).
    pub fn signed_volume(&self) -> f32 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Bounds of the vertices.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points(self.positions.iter().copied())
    }

    /// Checks indices and coordinates (finite, within ±[`MAX_COORDINATE`] m); names the first
    /// bad triangle or vertex.
    pub fn validate(&self) -> Result<()> {
        if let Some(i) = self.first_vertex_out_of_bounds() {
            return Err(Error::format(
                format!("vertex[{i}]"),
                vertex_out_of_bounds(self.positions[i]),
            ));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i >= n))
        {
            return Err(Error::format(
                format!("face[{t}]"),
                format!("vertex index out of range (mesh has {n} vertices)"),
            ));
        }
        Ok(())
    }

    /// The index of the first vertex that is not finite or lies beyond ±[`MAX_COORDINATE`] m.
    fn first_vertex_out_of_bounds(&self) -> Option<usize> {
        self.positions.iter().position(|p| !within_bounds(*p))
    }

    /// Writes the mesh as Wavefront OBJ text.
    pub fn write_obj(&self, out: &mut impl Write, name: &str) -> std::io::Result<()> {
        writeln!(out, "o {name}")?;
        for p in &self.positions {
            writeln!(out, "v {} {} {}", p.x, p.y, p.z)?;
        }
        for t in &self.triangles {
            writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    }

    /// Reads a mesh, choosing the format by extension (`.obj`, `.gltf`, `.glb`, `.ply`).
    pub fn load(path: &Path) -> Result<TriMesh> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let mesh = match ext.as_str() {
            "obj" => file_size(path).and_then(|_| load_obj(path)),
            "gltf" | "glb" => load_gltf(path),
            "ply" => read_file(path).and_then(|bytes| read_ply(&bytes)),
            _ => Err(Error::invalid(format!(
                "unknown mesh format '.{ext}' (expected .obj, .gltf, .glb or .ply)"
            ))),
        };
        let mesh = mesh.in_file(path)?;
        mesh.validate().in_file(path)?;
        Ok(mesh)
    }
}

/// The size limit on a mesh file and on each external glTF buffer, checked before either is
/// read: the size and variable of [`MESH_MB`], so that one setting raises both, named for what
/// it limits here. Without it a huge file (or a buffer declaring one) takes memory without end.
const MESH_FILE_MB: Limit = Limit {
    what: "a mesh file",
    ..MESH_MB
};

/// The size of the mesh file `path`, checked: it must be a regular file (not a device or a pipe,
/// which never end) of at most [`MESH_FILE_MB`].
///
/// # Errors
///
/// No such file, not a regular file, or over the limit; the caller names the file.
fn file_size(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::invalid("not a regular file"));
    }
    MESH_FILE_MB.check(meta.len(), "file size")?;
    Ok(meta.len())
}

/// The bytes of the mesh file `path`, its size checked first ([`file_size`]).
fn read_file(path: &Path) -> Result<Vec<u8>> {
    let size = file_size(path)?;
    read_at_most(path, size).map_err(|e| Error::io(path, e))
}

/// The first `len` bytes of the file `path` (fewer when it is shorter), read into a buffer of
/// that size: a file that grows while it is read cannot make it larger.
fn read_at_most(path: &Path, len: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let file = std::fs::File::open(path)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(len).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Why the buffer `uri` of a glTF file may not be read, or `None`: it must be a relative path
/// that stays in the glTF file's folder. Refused: an empty uri, an absolute path, a scheme or a
/// drive (`file:`, `http:`, `C:`; any `:`), a `..` component (`\` counted as a separator, as
/// Windows-made files use it) and control characters. The uri is not percent-decoded (this
/// reader never has), so `%2e%2e` is a literal name, not `..`.
fn buffer_uri_problem(uri: &str) -> Option<&'static str> {
    if uri.is_empty() {
        Some("is empty")
    } else if uri.starts_with(['/', '\\']) {
        Some("is an absolute path")
    } else if uri.contains(':') {
        Some("names a scheme or a drive (only files beside the glTF file are read)")
    } else if uri.split(['/', '\\']).any(|part| part == "..") {
        Some("has a '..' component")
    } else if uri.chars().any(char::is_control) {
        Some("holds a control character")
    } else {
        None
    }
}

/// A buffer `uri` as error messages show it: escaped, and cut short.
fn shown_uri(uri: &str) -> String {
    uri.chars()
        .take(200)
        .collect::<String>()
        .escape_debug()
        .to_string()
}

/// Checks the external buffers of a glTF file before any is read: each uri
/// ([`buffer_uri_problem`]; `data:` ones are left to the reader, which refuses them), and the
/// declared `byteLength`s against [`MESH_FILE_MB`], each alone and all together (two buffers
/// naming the same large file would otherwise each pass).
///
/// # Errors
///
/// Each names `buffers[i].uri` or `buffers[i].byteLength`; the caller names the glTF file.
fn check_buffers(gltf: &gltf::Gltf) -> Result<()> {
    let mut declared = 0u64;
    for (i, buffer) in gltf.buffers().enumerate() {
        let gltf::buffer::Source::Uri(uri) = buffer.source() else {
            continue;
        };
        if uri.starts_with("data:") {
            continue;
        }
        if let Some(problem) = buffer_uri_problem(uri) {
            return Err(Error::format(
                format!("buffers[{i}].uri"),
                format!(
                    "'{}' {problem}: a buffer must be a file in the glTF file's folder or below \
                     it, named by a relative path",
                    shown_uri(uri)
                ),
            ));
        }
        let length = buffer.length() as u64;
        MESH_FILE_MB.check(length, &format!("buffers[{i}].byteLength"))?;
        declared = declared.saturating_add(length);
    }
    MESH_FILE_MB.check(
        declared,
        "buffers[*].byteLength (the external buffers together)",
    )
}

/// The bytes of buffer `i` of the glTF file in `dir`, external at `uri` (checked by
/// [`check_buffers`]) and declared `byte_length` long. The file must be a regular file holding
/// at least that many bytes, which is checked before any byte is read; then exactly
/// `byte_length` bytes are read.
///
/// # Errors
///
/// Each names `buffers[i].uri`; the caller names the glTF file.
fn read_buffer(dir: &Path, i: usize, uri: &str, byte_length: u64) -> Result<Vec<u8>> {
    let at = format!("buffers[{i}].uri");
    let shown = || shown_uri(uri);
    let p = dir.join(uri);
    let unreadable =
        |e: std::io::Error| format!("'{}' cannot be read ({}): {e}", shown(), p.display());
    let short = |found: u64| {
        format!(
            "'{}' holds {found} bytes; its byteLength declares {byte_length}",
            shown()
        )
    };
    let meta = std::fs::metadata(&p).map_err(|e| Error::format(&at, unreadable(e)))?;
    if !meta.is_file() {
        return Err(Error::format(
            at,
            format!(
                "'{}' is not a regular file ({}): a device or a pipe may never end",
                shown(),
                p.display()
            ),
        ));
    }
    if meta.len() < byte_length {
        return Err(Error::format(at, short(meta.len())));
    }
    let data = read_at_most(&p, byte_length).map_err(|e| Error::format(&at, unreadable(e)))?;
    if (data.len() as u64) < byte_length {
        // The file shrank between the check and the read.
        return Err(Error::format(at, short(data.len() as u64)));
    }
    Ok(data)
}

/// Reads a PLY mesh (`vertex` x y z, `face` `vertex_indices`/`vertex_index` lists; polygons
/// are fanned into triangles), ASCII or binary. It lives with the mesh type rather than in
/// [`crate::ply`] so that the PLY module stays about splats and only its header parser is shared.
pub fn read_ply(bytes: &[u8]) -> Result<TriMesh> {
    let header = parse_header(bytes)?;
    let (vi, ve) = header
        .element("vertex")
        .ok_or_else(|| Error::format("vertex", "missing element"))?;
    let rows = element_rows(&header, bytes)?;
    let idx = |n: &str| {
        ve.property_index(n)
            .ok_or_else(|| Error::format(format!("vertex.{n}"), "missing property"))
    };
    let (ix, iy, iz) = (idx("x")?, idx("y")?, idx("z")?);
    let v = &rows[vi];
    let positions: Vec<Vec3> = (0..ve.count)
        .map(|r| {
            let g = |p| v.values(ve, r, p).first().copied().unwrap_or(f64::NAN) as f32;
            Vec3::new(g(ix), g(iy), g(iz))
        })
        .collect();
    let mut triangles = Vec::new();
    if let Some((fi, fe)) = header.element("face") {
        let p = fe
            .property_index("vertex_indices")
            .or_else(|| fe.property_index("vertex_index"))
            .ok_or_else(|| Error::format("face.vertex_indices", "missing property"))?;
        if fe.properties[p].list_count.is_none() {
            return Err(Error::format(
                "face.vertex_indices",
                "must be a list property",
            ));
        }
        for r in 0..fe.count {
            let poly = rows[fi].values(fe, r, p);
            if poly.iter().any(|i| *i < 0.0 || i.fract() != 0.0) {
                return Err(Error::format(
                    format!("face[{r}]"),
                    "vertex index is not a non-negative integer",
                ));
            }
            for k in 1..poly.len().saturating_sub(1) {
                triangles.push([poly[0] as u32, poly[k] as u32, poly[k + 1] as u32]);
            }
        }
    }
    Ok(TriMesh {
        positions,
        triangles,
    })
}

/// How OBJ files are read, by [`TriMesh::load`] and [`obj_material_colors`] alike, so that the
/// triangles of the one match the colours of the other: faces fanned into triangles, one index
/// per vertex.
fn obj_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    }
}

fn load_obj(path: &Path) -> Result<TriMesh> {
    let options = obj_options();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = LineCounter::new(std::io::BufReader::new(file));
    // Materials are not read: a missing or bad `.mtl` is no error of the mesh.
    let loaded = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    });
    let (models, _materials) = loaded.map_err(|e| obj_error(e, reader.line()))?;
    let mut mesh = TriMesh::default();
    for m in &models {
        let positions = m.mesh.positions.chunks_exact(3);
        if let Some(p) = positions
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .find(|p| !within_bounds(*p))
        {
            // tobj renumbers vertices (single index), so the vertex's own line is found again.
            let at = obj_vertex_line(path, p).map_or_else(
                || format!("object '{}'", m.name),
                |line| format!("line {line}"),
            );
            return Err(Error::format(at, vertex_out_of_bounds(p)));
        }
        let part = TriMesh {
            positions: m
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
            triangles: m
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        };
        part.validate().within(format!("object '{}'", m.name))?;
        mesh.append(&part);
    }
    Ok(mesh)
}

/// The diffuse (`Kd`) colour of each triangle of the OBJ mesh `path`, in the order
/// [`TriMesh::load`] reads them, where its models name a material that defines one; `None`
/// when it names no material file, or none that can be read (the mesh keeps its object's
/// colour). A material file is read only from beside the OBJ, as a glTF buffer is: a relative
/// name without `..`, a scheme or a drive, naming a regular file within the mesh file size
/// limit (`SAGE3D_MAX_MESH_MB`); any other is treated as missing, never opened.
///
/// # Errors
///
/// The OBJ file itself: missing, over the size limit, or not OBJ; naming the file.
pub fn obj_material_colors(path: &Path) -> Result<Option<Vec<Option<[f32; 3]>>>> {
    let options = obj_options();
    let bytes = read_file(path).in_file(path)?;
    let folder = path.parent().unwrap_or(Path::new(""));
    let load_mtl = |name: &Path| {
        let refused = || tobj::LoadError::OpenFileFailed;
        let name = name.to_str().ok_or_else(refused)?;
        if buffer_uri_problem(name).is_some() {
            return Err(refused());
        }
        let bytes = read_file(&folder.join(name)).map_err(|_| refused())?;
        tobj::load_mtl_buf(&mut bytes.as_slice())
    };
    let mut reader = LineCounter::new(bytes.as_slice());
    let loaded = tobj::load_obj_buf(&mut reader, &options, load_mtl);
    let (models, materials) = loaded
        .map_err(|e| obj_error(e, reader.line()))
        .in_file(path)?;
    let materials = match materials {
        Ok(m) if !m.is_empty() => m,
        _ => return Ok(None),
    };
    let mut colors = Vec::new();
    for m in &models {
        let kd = m
            .mesh
            .material_id
            .and_then(|id| materials.get(id))
            .and_then(|mat| mat.diffuse);
        colors.extend(std::iter::repeat_n(kd, m.mesh.indices.len() / 3));
    }
    Ok(Some(colors))
}

/// Why vertex `p` is refused.
fn vertex_out_of_bounds(p: Vec3) -> String {
    format!(
        "vertex ({:?}, {:?}, {:?}): expected finite coordinates within ±{MAX_COORDINATE} m (a \
         mesh is in metres, in the scene's frame)",
        p.x, p.y, p.z
    )
}

/// The line (from 1) of the first `v` statement of the OBJ file `path` whose position is `p`,
/// read as tobj reads it (the first three numbers, as f32); `None` when the file cannot be
/// read again or holds no such line. Only called for an error, so reading twice costs nothing
/// on the good path.
fn obj_vertex_line(path: &Path, p: Vec3) -> Option<usize> {
    use std::io::BufRead;
    let file = std::fs::File::open(path).ok()?;
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let mut reader = std::io::BufReader::new(file);
    let mut line = Vec::new();
    let mut n = 0;
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line).ok()? == 0 {
            return None;
        }
        n += 1;
        let text = String::from_utf8_lossy(&line);
        let mut words = text.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        let xyz: Vec<f32> = words.take(3).map_while(|w| w.parse().ok()).collect();
        if let [x, y, z] = xyz[..]
            && same(x, p.x)
            && same(y, p.y)
            && same(z, p.z)
        {
            return Some(n);
        }
    }
}

/// An OBJ reading error, at `line` where tobj found it on the line it was reading (its
/// checks of face indices run when an object ends, so those errors name no line).
fn obj_error(e: tobj::LoadError, line: usize) -> Error {
    use tobj::LoadError as E;
    match e {
        E::ReadError
        | E::UnrecognizedCharacter
        | E::PositionParseError
        | E::ScalingByZeroError
        | E::ColorParseError
        | E::NormalParseError
        | E::TexcoordParseError
        | E::FaceParseError
        | E::MaterialParseError
        | E::InvalidObjectName => Error::format(format!("line {line}"), e.to_string()),
        other => Error::format("obj", other.to_string()),
    }
}

/// A buffered reader that counts the lines read through it, so that an error of tobj, which
/// reads a whole line and then parses it, can name the line.
struct LineCounter<R> {
    inner: R,
    lines: Lines,
}

/// Lines seen in the bytes consumed.
#[derive(Default)]
struct Lines {
    /// Newlines consumed.
    newlines: usize,
    /// Whether bytes of a line not yet ended by a newline have been consumed.
    open_line: bool,
}

impl Lines {
    /// Counts `bytes`, consumed.
    fn count(&mut self, bytes: &[u8]) {
        if let Some(&last) = bytes.last() {
            self.newlines += bytes.iter().filter(|&&b| b == b'\n').count();
            self.open_line = last != b'\n';
        }
    }
}

impl<R: std::io::BufRead> LineCounter<R> {
    fn new(inner: R) -> Self {
        LineCounter {
            inner,
            lines: Lines::default(),
        }
    }

    /// The line (from 1) that the last bytes consumed belong to.
    fn line(&self) -> usize {
        let l = &self.lines;
        l.newlines + usize::from(l.open_line || l.newlines == 0)
    }
}

impl<R: std::io::BufRead> std::io::Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.lines.count(&buf[..n]);
        Ok(n)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for LineCounter<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        // The bytes consumed are those `fill_buf` last returned: asking again reads nothing.
        if let Ok(buf) = self.inner.fill_buf() {
            self.lines.count(&buf[..amt.min(buf.len())]);
        }
        self.inner.consume(amt);
    }
}

/// Checks what the glTF reader's own validation assumes: it looks up a primitive's POSITION
/// accessor before checking that the index exists, and panics on one that does not.
fn check_position_accessors(bytes: &[u8]) -> Result<()> {
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| Error::format("gltf", e.to_string()))?;
    let root = unchecked.document.as_json();
    let position = gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(a) = primitive.attributes.get(&position)
                && a.value() >= root.accessors.len()
            {
                return Err(Error::format(
                    format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                    format!(
                        "accessor {} does not exist (the file has {})",
                        a.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn load_gltf(path: &Path) -> Result<TriMesh> {
    let bytes = read_file(path)?;
    check_position_accessors(&bytes)?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| Error::format("gltf", e.to_string()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    check_buffers(&gltf)?;
    let mut buffers = Vec::new();
    for (i, buffer) in gltf.buffers().enumerate() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| Error::format(format!("buffers[{i}]"), "GLB has no binary chunk"))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                return Err(Error::format(
                    format!("buffers[{i}].uri"),
                    "embedded data: URIs are not supported; use .glb or an external .bin",
                ));
            }
            gltf::buffer::Source::Uri(uri) => read_buffer(dir, i, uri, buffer.length() as u64)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::format(
                format!("buffers[{i}]"),
                format!("expected {} bytes, found {}", buffer.length(), data.len()),
            ));
        }
        buffers.push(data);
    }
    let buffer_bytes = buffers.iter().map(|b| b.len() as u64).sum();
    let Some(scene) = gltf.default_scene().or_else(|| gltf.scenes().next()) else {
        return Ok(TriMesh::default());
    };
    let nodes = placed_nodes(&scene, gltf.nodes().len())?;
    check_sizes(&nodes, buffer_bytes, &MESH_MB)?;
    let mut mesh = TriMesh::default();
    for (node, world) in &nodes {
        if let Some(m) = node.mesh() {
            for (pi, prim) in m.primitives().enumerate() {
                let at = || format!("meshes[{}].primitives[{pi}]", m.index());
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    return Err(Error::format(
                        at(),
                        "only triangle primitives are supported",
                    ));
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
                let positions: Vec<Vec3> = reader
                    .read_positions()
                    .ok_or_else(|| Error::format(at(), "primitive has no POSITION attribute"))?
                    .map(|p| world.transform_point3(Vec3::from_array(p)))
                    .collect();
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(ix) => ix.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                if !indices.len().is_multiple_of(3) {
                    return Err(Error::format(at(), "index count is not a multiple of 3"));
                }
                let part = TriMesh {
                    positions,
                    triangles: indices
                        .chunks_exact(3)
                        .map(|t| [t[0], t[1], t[2]])
                        .collect(),
                };
                part.validate().within(at())?;
                mesh.append(&part);
            }
        }
    }
    Ok(mesh)
}

/// The nodes of `scene` in depth-first order (parents before children, as the file lists
/// them), each with its world transform.
///
/// glTF nodes form trees; a node reached twice (listed under two parents, or its own
/// ancestor) is an error, since following such a file would repeat its meshes without end.
fn placed_nodes<'a>(
    scene: &gltf::Scene<'a>,
    node_count: usize,
) -> Result<Vec<(gltf::Node<'a>, Mat4)>> {
    let mut reached = vec![false; node_count];
    let mut out = Vec::new();
    // A stack popped from the end: each list of siblings is pushed in reverse.
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    stack.reverse();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(Error::format(
                format!("nodes[{}]", node.index()),
                "reached twice from the scene (glTF nodes form trees: one parent each, never \
                 their own ancestor)",
            ));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let siblings = stack.len();
        stack.extend(node.children().map(|c| (c, world)));
        stack[siblings..].reverse();
        out.push((node, world));
    }
    Ok(out)
}

/// Checks, before anything is decoded, that each accessor a mesh is read from declares at least
/// one and no more elements than the file's buffers can hold (a sparse accessor needs no
/// buffer for its zeros, so its count is otherwise unbounded), and that the decoded mesh, every
/// instance counted, stays within `limit`.
fn check_sizes(nodes: &[(gltf::Node, Mat4)], buffer_bytes: u64, limit: &Limit) -> Result<()> {
    // Decoded bytes: a vertex is 12 (3 × f32), a triangle 12 (3 × u32).
    let mut decoded = 0u64;
    for m in nodes.iter().filter_map(|(node, _)| node.mesh()) {
        for (pi, prim) in m.primitives().enumerate() {
            let at = format!("meshes[{}].primitives[{pi}]", m.index());
            let count = |a: Option<gltf::Accessor>, name: &str| -> Result<u64> {
                let Some(a) = a else { return Ok(0) };
                let (count, size) = (a.count() as u64, a.size() as u64);
                if count == 0 || count.saturating_mul(size) > buffer_bytes {
                    return Err(Error::format(
                        format!("{at}.{name}"),
                        format!(
                            "accessor {} declares {count} elements of {size} bytes; the file's \
                             buffers hold {buffer_bytes} bytes",
                            a.index()
                        ),
                    ));
                }
                Ok(count)
            };
            let vertices = count(prim.get(&gltf::Semantic::Positions), "attributes.POSITION")?;
            let indices = match count(prim.indices(), "indices")? {
                0 => vertices,
                n => n,
            };
            decoded = decoded.saturating_add(12 * vertices + 4 * indices);
        }
    }
    limit.check(decoded, "decoded size (every instance counted)")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A glTF document of `instances` root nodes, each instancing one mesh of `vertices`
    /// vertices without indices (the buffer itself is not needed to check sizes).
    fn instanced(instances: usize, vertices: usize) -> gltf::Gltf {
        let json = serde_json::json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": (0..instances).collect::<Vec<_>>()}],
            "nodes": vec![serde_json::json!({"mesh": 0}); instances],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "buffers": [{"byteLength": 12 * vertices, "uri": "mesh.bin"}],
            "bufferViews": [{"buffer": 0, "byteLength": 12 * vertices}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": vertices,
                           "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}]
        });
        gltf::Gltf::from_slice(&serde_json::to_vec(&json).unwrap()).unwrap()
    }

    #[test]
    fn every_instance_counts_towards_the_decoded_size() {
        let limit = Limit {
            variable: "SAGE3D_MAX_TEST_MESH_MB",
            default: 1,
            unit: "MB",
            scale: 1 << 20,
            what: "a decoded mesh",
        };
        // 16 bytes a vertex decoded (its position, and a third of a triangle): 16 instances of
        // 4096 vertices are exactly 1 MB, one more is over.
        let sizes = |instances| {
            let doc = instanced(instances, 4096);
            let scene = doc.scenes().next().unwrap();
            let nodes = placed_nodes(&scene, doc.nodes().len()).unwrap();
            check_sizes(&nodes, 12 * 4096, &limit)
        };
        sizes(16).unwrap();
        let e = sizes(17).unwrap_err();
        assert_eq!(
            e.to_string(),
            "decoded size (every instance counted): 1.1 MB, over the limit of 1 MB on a decoded \
             mesh; set the environment variable SAGE3D_MAX_TEST_MESH_MB to raise it"
        );
    }
}
