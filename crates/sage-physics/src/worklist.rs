//! The CoACD work list: the object meshes of a scene whose hulls are not yet in the cache, with
//! what an offline decomposer needs to fill it (`python/tools/coacd_cache.py` reads this file,
//! runs CoACD on each mesh and writes each `cache_file`; `docs/physics.md`).

use crate::bodies::hull_mesh;
use crate::decompose::{CacheEntry, Decomposer, HullCache, cache_key};
use sage_core::{Error, Result};
use sage_scene::Scene;
use serde::Serialize;
use std::path::PathBuf;

/// One mesh to decompose. Fields are in alphabetical order, the file's layout since its first
/// version.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PendingMesh {
    /// Where the decomposer must write the hulls, absolute.
    pub cache_file: PathBuf,
    /// The object's `ins_id` in labels.json.
    pub ins_id: String,
    /// The object's instance id.
    pub instance: u32,
    /// The cache key (32 hex digits).
    pub key: String,
    /// Mesh triangles (vertex indices).
    pub triangles: Vec<[u32; 3]>,
    /// Mesh vertices, W frame.
    pub vertices: Vec<[f32; 3]>,
}

/// The work list file's content (fields in alphabetical order, as [`PendingMesh`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorkList {
    /// The cache folder, absolute.
    pub cache_dir: PathBuf,
    /// The decomposer as the cache key describes it.
    pub decomposer: String,
    /// The meshes without cached hulls (missing or damaged), in object order.
    pub meshes: Vec<PendingMesh>,
    /// Its parameters by name.
    pub settings: serde_json::Value,
}

impl WorkList {
    /// The meshes of `scene` that `decomposer` has not yet decomposed into `cache`, or whose
    /// entry there is damaged (objects with given parts, e.g. from a published collision file,
    /// need none).
    ///
    /// # Errors
    ///
    /// The cache is a file, or an entry exists but cannot be read (permissions), naming it.
    pub fn of(scene: &Scene, decomposer: &Decomposer, cache: &HullCache) -> Result<WorkList> {
        // The decomposer runs in a working folder of its own: a path relative to ours would
        // put the hulls where sage3d never looks.
        let cache_dir = std::path::absolute(cache.dir()).map_err(|e| Error::io(cache.dir(), e))?;
        let absolute = HullCache::new(&cache_dir);
        let mut meshes = Vec::new();
        for o in &scene.objects {
            let Some(mesh) = hull_mesh(o) else {
                continue;
            };
            let key = cache_key(mesh, decomposer);
            // A damaged entry is to be made again, as `physics build` asks.
            if let CacheEntry::Parts(_) = cache.load(key)? {
                continue;
            }
            meshes.push(PendingMesh {
                cache_file: absolute.path(key),
                ins_id: o.ins_id.clone(),
                instance: o.id.0,
                key: format!("{key:032x}"),
                triangles: mesh.triangles.clone(),
                vertices: mesh.positions.iter().map(|p| p.to_array()).collect(),
            });
        }
        let settings = match *decomposer {
            Decomposer::Coacd {
                threshold,
                max_hulls,
            } => serde_json::json!({"threshold": threshold, "max_hulls": max_hulls}),
            Decomposer::Vhacd {
                resolution,
                concavity,
                max_hulls,
            } => {
                serde_json::json!({"resolution": resolution, "concavity": concavity, "max_hulls": max_hulls})
            }
        };
        Ok(WorkList {
            cache_dir,
            decomposer: decomposer.describe(),
            meshes,
            settings,
        })
    }
}
