//! Triangle meshes from PLY files (`vertex` x y z, `face` `vertex_indices`/`vertex_index` lists;
//! polygons are fanned into triangles). ASCII and binary are both accepted.

use super::header::{element_rows, parse_header};
use crate::mesh::TriMesh;
use glam::Vec3;
use sage_core::{Error, Result};

/// Reads a PLY mesh.
pub fn read_mesh(bytes: &[u8]) -> Result<TriMesh> {
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
