//! The scene as coloured triangles: the structure mesh and every object's mesh (its oriented box
//! where it has none), each triangle with the base colour and the shading the renderer gives it.
//! The same triangles feed the safety filter, the renderer and the Gaussians' first positions.

use crate::bvh::Bvh;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Obb, Result};
use sage_scene::{Scene, TriMesh};
use std::path::Path;

/// What a structure triangle is (decides its colour); objects are their own kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurfaceKind {
    /// Facing up at floor level.
    Floor,
    /// Facing down at ceiling level.
    Ceiling,
    /// Every other structure face: walls, jambs, lintels, sills.
    Wall,
    /// A face of the object with this index in `Scene::objects`.
    Object(usize),
}

/// Base colour of floors (sRGB 0–1): a mid wood.
pub const FLOOR_RGB: [f32; 3] = [0.58, 0.45, 0.32];
/// Base colour of walls: an off-white.
pub const WALL_RGB: [f32; 3] = [0.86, 0.84, 0.79];
/// Base colour of ceilings: white.
pub const CEILING_RGB: [f32; 3] = [0.95, 0.95, 0.94];
/// Direction towards the fixed light (unit length); high and oblique so floors, walls and
/// ceilings all get different shades.
pub const LIGHT_DIR: Vec3 = Vec3::new(0.267_261_24, 0.534_522_5, 0.801_783_7);
/// Ambient share of the shading: a face turned away from the light keeps this fraction.
pub const AMBIENT: f32 = 0.45;
/// How close (metres) a horizontal face must be to the floor or the ceiling to count as one.
const LEVEL_TOLERANCE: f32 = 0.05;

/// Every triangle of a scene with its kind, unit normal and shaded colour.
#[derive(Debug, Clone, Default)]
pub struct SceneSurfaces {
    /// Corners of each triangle.
    pub triangles: Vec<[Vec3; 3]>,
    /// Unit normal of each triangle (from its winding; zero for a degenerate triangle).
    pub normals: Vec<Vec3>,
    /// Kind of each triangle.
    pub kinds: Vec<SurfaceKind>,
    /// The colour each triangle is rendered with: base colour × [`shade`] (sRGB 0–1).
    pub colors: Vec<[f32; 3]>,
}

/// Lambert plus ambient under [`LIGHT_DIR`], two-sided (windings in scene files are not
/// reliable, and a face is seen from the side the camera is on).
pub fn shade(base: [f32; 3], normal: Vec3) -> [f32; 3] {
    let k = AMBIENT + (1.0 - AMBIENT) * normal.dot(LIGHT_DIR).abs();
    base.map(|c| (c * k).clamp(0.0, 1.0))
}

/// The base colour of an object: its `color` attribute when it is a colour word of
/// [`sage_scene::vocabulary::COLORS`], else a stable colour for its category.
pub fn object_base_color(category: &str, color: Option<&str>) -> [f32; 3] {
    if let Some(rgb) = color.and_then(sage_scene::vocabulary::color_rgb) {
        return rgb;
    }
    let h = sage_io::hash::fnv1a32(category.as_bytes());
    sage_io::palette::distinct_color(h % 4096).map(|c| c as f32 / 255.0)
}

/// What structure triangle `tri` is in a scene whose ceiling is at `height`: a floor when it is
/// horizontal and within [`LEVEL_TOLERANCE`] of z = 0, a ceiling when horizontal and within it
/// of `height`, a wall otherwise (a step, a sunken floor or a roof above the ceiling included:
/// they are neither level).
fn structure_kind(tri: &[Vec3; 3], height: f32) -> SurfaceKind {
    let horizontal = normal(tri).z.abs() > 0.9;
    let z = (tri[0].z + tri[1].z + tri[2].z) / 3.0;
    if horizontal && z.abs() < LEVEL_TOLERANCE {
        SurfaceKind::Floor
    } else if horizontal && (z - height).abs() < LEVEL_TOLERANCE {
        SurfaceKind::Ceiling
    } else {
        SurfaceKind::Wall
    }
}

/// The 12 triangles of an oriented box, wound outwards.
pub fn obb_mesh(b: &Obb) -> TriMesh {
    // Not shared with the generator's axis-aligned boxes (`sage-synth`, `shapes::cuboid`): their
    // corner, face and diagonal orders differ, and each order is part of the bytes it produces
    // (here the surface samples and depth maps of objects without meshes).
    let c = b.corners();
    // Corners 0–3 bottom counter-clockwise seen from above, 4–7 above them.
    let quads = [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh {
        positions: c.to_vec(),
        triangles,
    }
}

impl SceneSurfaces {
    /// The triangles of `scene`; with `scene_dir`, object OBJ files that name materials give
    /// their triangles the material's diffuse colour (`Kd`) instead.
    pub fn build(scene: &Scene, scene_dir: Option<&Path>) -> Result<SceneSurfaces> {
        let mut s = SceneSurfaces::default();
        let height = scene.floorplan.ceiling_height();
        if let Some(m) = &scene.structure_mesh {
            for t in 0..m.triangles.len() {
                let tri = m.triangle(t);
                let kind = structure_kind(&tri, height);
                let base = match kind {
                    SurfaceKind::Floor => FLOOR_RGB,
                    SurfaceKind::Ceiling => CEILING_RGB,
                    _ => WALL_RGB,
                };
                s.push(tri, kind, base);
            }
        }
        for (i, o) in scene.objects.iter().enumerate() {
            let base = object_base_color(&o.category, o.attributes.color.as_deref());
            let boxed;
            let mesh = match &o.mesh {
                Some(m) => m,
                None => {
                    boxed = obb_mesh(&o.obb);
                    &boxed
                }
            };
            let kd = match (scene_dir, &o.mesh) {
                (Some(dir), Some(m)) => material_colors(dir, &o.ins_id, m.triangles.len())?,
                _ => None,
            };
            for t in 0..mesh.triangles.len() {
                let rgb = kd.as_ref().and_then(|k| k[t]).unwrap_or(base);
                s.push(mesh.triangle(t), SurfaceKind::Object(i), rgb);
            }
        }
        Ok(s)
    }

    fn push(&mut self, tri: [Vec3; 3], kind: SurfaceKind, base: [f32; 3]) {
        let n = normal(&tri);
        self.triangles.push(tri);
        self.normals.push(n);
        self.kinds.push(kind);
        self.colors.push(shade(base, n));
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when the scene has no triangle at all.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Total surface area, m².
    pub fn area(&self) -> f64 {
        self.triangles.iter().map(triangle_area).sum()
    }

    /// The bounding volume hierarchy over these triangles (indices match).
    pub fn bvh(&self) -> Bvh {
        Bvh::build(&self.triangles)
    }
}

fn triangle_area(t: &[Vec3; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length() as f64
}

fn normal(t: &[Vec3; 3]) -> Vec3 {
    (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero()
}

/// Per-triangle `Kd` colours of `meshes/{ins_id}.obj` when its models name materials that
/// define one, `None` when the file has no materials (or is not an OBJ). Triangles come in the
/// order `TriMesh::load` reads them, so indices match `expected`.
fn material_colors(
    dir: &Path,
    ins_id: &str,
    expected: usize,
) -> Result<Option<Vec<Option<[f32; 3]>>>> {
    let path =
        sage_scene::scene::object_file(&dir.join(sage_scene::scene::files::MESHES), ins_id, "obj")?;
    if !path.is_file() {
        return Ok(None);
    }
    let Some(colors) = sage_scene::mesh::obj_material_colors(&path)? else {
        return Ok(None);
    };
    if colors.len() != expected {
        return Err(Error::format(
            "obj",
            format!(
                "materials cover {} triangles but the mesh has {expected}",
                colors.len()
            ),
        )
        .in_file(&path));
    }
    Ok(Some(colors))
}

/// The most surface points a reconstruction may start from (or export): ten times the
/// Gaussians of a large InteriorGS scene.
pub const MAX_POINTS: usize = 10_000_000;

/// Checks a count of surface points asked for, named `points`.
///
/// # Errors
///
/// More than [`MAX_POINTS`].
pub fn check_points(points: usize) -> Result<()> {
    if points > MAX_POINTS {
        return Err(Error::invalid(format!(
            "`points` must be at most {MAX_POINTS}, got {points}"
        )));
    }
    Ok(())
}

/// `n` points on the scene's surfaces, area-weighted, each with the colour the renderer gives
/// its triangle and the triangle's unit normal: where the fitted Gaussians start.
///
/// One ChaCha8 stream seeded by `seed` draws them in order, so the result does not depend on
/// the thread count. An empty scene gives no points.
pub fn surface_samples(
    surfaces: &SceneSurfaces,
    n: usize,
    seed: u64,
) -> Vec<(Vec3, [f32; 3], Vec3)> {
    let mut cumulative = Vec::with_capacity(surfaces.len());
    let mut total = 0.0f64;
    for t in &surfaces.triangles {
        total += triangle_area(t);
        cumulative.push(total);
    }
    if total <= 0.0 {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let u = rng.random::<f64>() * total;
            let k = cumulative
                .partition_point(|&c| c <= u)
                .min(cumulative.len() - 1);
            let [a, b, c] = surfaces.triangles[k];
            let (mut r1, mut r2) = (rng.random::<f32>(), rng.random::<f32>());
            if r1 + r2 > 1.0 {
                (r1, r2) = (1.0 - r1, 1.0 - r2);
            }
            (
                a + (b - a) * r1 + (c - a) * r2,
                surfaces.colors[k],
                surfaces.normals[k],
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obb_mesh_is_closed_and_outward() {
        let b = Obb {
            center: Vec3::new(1.0, 2.0, 0.5),
            half_extents: Vec3::new(0.5, 0.25, 0.5),
            yaw: 0.7,
        };
        let m = obb_mesh(&b);
        assert!((m.signed_volume() - b.volume()).abs() < 1e-4);
        assert!((m.area() - 2.0 * (1.0 * 0.5 + 1.0 * 1.0 + 0.5 * 1.0)).abs() < 1e-4);
    }

    #[test]
    fn samples_follow_area_and_carry_their_triangle() {
        // Two triangles, the second three times the area of the first.
        let s = SceneSurfaces {
            triangles: vec![
                [Vec3::ZERO, Vec3::X, Vec3::Y],
                [
                    Vec3::new(0.0, 0.0, 1.0),
                    Vec3::new(3.0, 0.0, 1.0),
                    Vec3::new(0.0, 1.0, 1.0),
                ],
            ],
            normals: vec![Vec3::Z, Vec3::Z],
            kinds: vec![SurfaceKind::Floor, SurfaceKind::Ceiling],
            colors: vec![[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        };
        assert!((s.area() - 2.0).abs() < 1e-9);
        let pts = surface_samples(&s, 4000, 3);
        let upper = pts.iter().filter(|p| p.0.z > 0.5).count() as f32 / 4000.0;
        assert!((upper - 0.75).abs() < 0.03, "{upper}");
        for (p, rgb, _) in &pts {
            let on_upper = p.z > 0.5;
            assert_eq!(
                *rgb,
                if on_upper {
                    [0.0, 0.0, 1.0]
                } else {
                    [1.0, 0.0, 0.0]
                }
            );
            let scale = if on_upper { 3.0 } else { 1.0 };
            assert!(p.x >= 0.0 && p.y >= 0.0 && p.x / scale + p.y <= 1.0 + 1e-5);
        }
        assert_eq!(pts, surface_samples(&s, 4000, 3));
    }

    #[test]
    fn only_horizontal_faces_level_with_the_floor_or_the_ceiling_are_floors_or_ceilings() {
        // A flat triangle at height z, and one standing up from it.
        let flat = |z: f32| {
            [
                Vec3::new(0.0, 0.0, z),
                Vec3::new(1.0, 0.0, z),
                Vec3::new(0.0, 1.0, z),
            ]
        };
        let upright = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 0.0, 1.0)];
        let height = 2.8;
        for (z, kind) in [
            (0.0, SurfaceKind::Floor),
            (0.04, SurfaceKind::Floor),
            (-0.04, SurfaceKind::Floor),
            (2.78, SurfaceKind::Ceiling),
            (2.84, SurfaceKind::Ceiling),
            // Neither level: a sunken slab's underside, a sill, a roof above the ceiling.
            (-0.5, SurfaceKind::Wall),
            (0.9, SurfaceKind::Wall),
            (3.5, SurfaceKind::Wall),
        ] {
            assert_eq!(structure_kind(&flat(z), height), kind, "z = {z}");
        }
        assert_eq!(structure_kind(&upright, height), SurfaceKind::Wall);
    }

    #[test]
    fn palette_words_win_over_category_colours() {
        assert_eq!(object_base_color("sofa", Some("red")), [0.72, 0.14, 0.12]);
        assert_eq!(
            object_base_color("sofa", Some("plaid")),
            object_base_color("sofa", None)
        );
        assert_ne!(
            object_base_color("sofa", None),
            object_base_color("chair", None)
        );
        assert!((LIGHT_DIR.length() - 1.0).abs() < 1e-6);
    }
}
