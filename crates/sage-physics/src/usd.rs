//! The hybrid scene as USDA text (SPEC §6): Z up, metres; one invisible collision mesh per
//! convex part with the UsdPhysics collision schemas; rigid-body, mass and material schemas on
//! movable and articulated objects; a revolute joint per articulated door; semantic labels on
//! every body; the Gaussians referenced as an asset path to the scene's PLY.
//!
//! Layout:
//! ```text
//! /World                      Xform (defaultPrim)
//!   /PhysicsScene             PhysicsScene, gravity −Z 9.81
//!   /Gaussians                Xform, asset sage3d:splats = @…/3dgs_compressed.ply@
//!   /Looks/PhysicsMaterial_N  Material + PhysicsMaterialAPI (one per friction/restitution pair)
//!   /Objects/{category}_{id}  Xform + SemanticsLabelsAPI:class (+ rigid body, mass)
//!     /hull_K                 Mesh + PhysicsCollisionAPI + PhysicsMeshCollisionAPI (convexHull)
//!     /hinge                  PhysicsRevoluteJoint (articulated doors)
//!   /Structure/{wall_i,structure,floor,ceiling}   (structure: a published file's parts of no object)
//! ```

use crate::bodies::{Body, SceneBodies};
use crate::world::hinge_of;
use sage_core::{Result, Vec3};
use sage_io::files::write_atomic;
use sage_scene::PhysicsRole;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

/// Where the Gaussians are, as written into the USDA.
#[derive(Debug, Clone, PartialEq)]
pub struct SplatAsset {
    /// Asset path (relative to the USDA file where possible).
    pub path: String,
    /// Number of Gaussians.
    pub count: usize,
    /// SH degree.
    pub sh_degree: u8,
}

/// A prim name from free text: `[A-Za-z0-9_]`, never starting with a digit.
pub fn prim_name(text: &str) -> String {
    let mut s: String = text
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

fn quote(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c if c.is_control() => {}
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

fn vec3(v: Vec3) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}

/// The material prim name of a friction/restitution pair, adding it to `materials` if new.
fn material_of(materials: &mut Vec<(f32, f32)>, friction: f32, restitution: f32) -> usize {
    let key = (friction, restitution);
    match materials.iter().position(|m| *m == key) {
        Some(i) => i,
        None => {
            materials.push(key);
            materials.len() - 1
        }
    }
}

fn write_hulls(out: &mut String, body: &Body, indent: &str) {
    for (k, part) in body.parts.iter().enumerate() {
        let points: Vec<String> = part.vertices.iter().map(|v| vec3(*v)).collect();
        let indices: Vec<String> = part
            .triangles
            .iter()
            .flat_map(|t| t.iter().map(|i| i.to_string()))
            .collect();
        let counts = vec!["3"; part.triangles.len()].join(", ");
        let _ = write!(
            out,
            "{indent}def Mesh \"hull_{k}\" (\n{indent}    prepend apiSchemas = [\"PhysicsCollisionAPI\", \"PhysicsMeshCollisionAPI\"]\n{indent})\n{indent}{{\n\
             {indent}    uniform token purpose = \"guide\"\n\
             {indent}    token visibility = \"invisible\"\n\
             {indent}    bool physics:collisionEnabled = true\n\
             {indent}    uniform token physics:approximation = \"convexHull\"\n\
             {indent}    uniform token subdivisionScheme = \"none\"\n\
             {indent}    point3f[] points = [{}]\n\
             {indent}    int[] faceVertexCounts = [{counts}]\n\
             {indent}    int[] faceVertexIndices = [{}]\n\
             {indent}}}\n",
            points.join(", "),
            indices.join(", "),
        );
    }
}

fn write_body(out: &mut String, body: &Body, materials: &mut Vec<(f32, f32)>) {
    let dynamic = body.role != PhysicsRole::Static;
    let mut schemas = vec!["\"SemanticsLabelsAPI:class\"", "\"MaterialBindingAPI\""];
    if dynamic {
        schemas.extend(["\"PhysicsRigidBodyAPI\"", "\"PhysicsMassAPI\""]);
    }
    let name = prim_name(&body.name);
    let _ = writeln!(
        out,
        "        def Xform \"{name}\" (\n            prepend apiSchemas = [{}]\n        )\n        {{",
        schemas.join(", ")
    );
    let _ = writeln!(
        out,
        "            token[] semantics:labels:class = [{}]",
        quote(&body.category)
    );
    let _ = writeln!(
        out,
        "            custom int sage3d:instanceId = {}",
        body.instance.0
    );
    let _ = writeln!(
        out,
        "            custom token sage3d:physicsRole = \"{}\"",
        match body.role {
            PhysicsRole::Static => "static",
            PhysicsRole::Movable => "movable",
            PhysicsRole::Articulated => "articulated",
        }
    );
    if let Some(src) = body.given {
        // Given parts (a published collision file's, or recovered from Gaussians) are not
        // ours to re-derive: say whose they are.
        let _ = writeln!(
            out,
            "            custom token sage3d:bodySource = \"{}\"",
            src.as_str()
        );
    }
    let m = material_of(
        materials,
        body.rigid_body.friction,
        body.rigid_body.restitution,
    );
    let _ = writeln!(
        out,
        "            rel material:binding:physics = </World/Looks/PhysicsMaterial_{m}> (\n                bindMaterialAs = \"strongerThanDescendants\"\n            )"
    );
    if dynamic {
        let _ = writeln!(out, "            bool physics:rigidBodyEnabled = true");
        let _ = writeln!(
            out,
            "            float physics:mass = {}",
            body.rigid_body.mass
        );
    }
    write_hulls(out, body, "            ");
    if body.role == PhysicsRole::Articulated {
        let hinge = hinge_of(&body.obb);
        let _ = writeln!(
            out,
            "            def PhysicsRevoluteJoint \"hinge\"\n            {{\n\
             \x20               rel physics:body1 = <..>\n\
             \x20               uniform token physics:axis = \"Z\"\n\
             \x20               point3f physics:localPos0 = {h}\n\
             \x20               point3f physics:localPos1 = {h}\n\
             \x20               quatf physics:localRot0 = (1, 0, 0, 0)\n\
             \x20               quatf physics:localRot1 = (1, 0, 0, 0)\n\
             \x20               float physics:lowerLimit = -180\n\
             \x20               float physics:upperLimit = 180\n\
             \x20           }}",
            h = vec3(hinge)
        );
    }
    let _ = writeln!(out, "        }}");
}

/// The USDA text of a scene's bodies with the Gaussians referenced as `splats`.
pub fn to_usda(scene_name: &str, bodies: &SceneBodies, splats: Option<&SplatAsset>) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "#usda 1.0\n(\n    defaultPrim = \"World\"\n    doc = {}\n    metersPerUnit = 1\n    kilogramsPerUnit = 1\n    upAxis = \"Z\"\n)\n",
        quote(&format!(
            "sage3d hybrid scene {scene_name}: Gaussians by reference, collision by convex parts"
        ))
    );
    out.push_str("def Xform \"World\"\n{\n");
    out.push_str(
        "    def PhysicsScene \"PhysicsScene\"\n    {\n        vector3f physics:gravityDirection = (0, 0, -1)\n        float physics:gravityMagnitude = 9.81\n    }\n",
    );
    if let Some(s) = splats {
        let _ = writeln!(
            out,
            "    def Xform \"Gaussians\"\n    {{\n        custom asset sage3d:splats = @{}@\n        custom int sage3d:gaussianCount = {}\n        custom int sage3d:shDegree = {}\n    }}",
            s.path.replace('@', "%40"),
            s.count,
            s.sh_degree
        );
    }
    let mut materials = Vec::new();
    let mut objects = String::new();
    let mut structure = String::new();
    for b in &bodies.bodies {
        let target = if matches!(b.kind, crate::bodies::BodyKind::Object(_)) {
            &mut objects
        } else {
            &mut structure
        };
        write_body(target, b, &mut materials);
    }
    out.push_str("    def Scope \"Looks\"\n    {\n");
    for (i, (f, r)) in materials.iter().enumerate() {
        let _ = writeln!(
            out,
            "        def Material \"PhysicsMaterial_{i}\" (\n            prepend apiSchemas = [\"PhysicsMaterialAPI\"]\n        )\n        {{\n            float physics:staticFriction = {f}\n            float physics:dynamicFriction = {f}\n            float physics:restitution = {r}\n        }}"
        );
    }
    out.push_str("    }\n");
    let _ = write!(
        out,
        "    def Scope \"Objects\"\n    {{\n{objects}    }}\n    def Scope \"Structure\"\n    {{\n{structure}    }}\n}}\n"
    );
    out
}

/// Writes the USDA file atomically.
pub fn write_usda(
    path: &Path,
    scene_name: &str,
    bodies: &SceneBodies,
    splats: Option<&SplatAsset>,
) -> Result<()> {
    let text = to_usda(scene_name, bodies, splats);
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_names_are_identifiers() {
        assert_eq!(prim_name("chair_3"), "chair_3");
        assert_eq!(prim_name("3d printer"), "_3d_printer");
        assert_eq!(prim_name(""), "_");
    }

    #[test]
    fn quotes_escape() {
        assert_eq!(quote("a\"b\\c\n"), "\"a\\\"b\\\\c\\n\"");
    }
}
