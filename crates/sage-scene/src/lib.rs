//! `sage-scene`: the scene model of sage3d and its files.
//!
//! A scene is a folder in the InteriorGS layout (SPEC §4) plus optional files of ours. This crate
//! holds the in-memory model — [`Gaussians`] in a compact structure of arrays, [`Object`]s with
//! boxes, meshes and attributes, the [`Floorplan`], the [`OccupancyMap`] — the readers and
//! writers of every file ([`ply`] for 3DGS in the standard and SuperSplat compressed layouts,
//! [`formats`] for the JSON files, [`mesh`] for OBJ/glTF/PLY meshes), and the attribute
//! [`vocabulary`] the layers above share. The seeded generator of whole scenes in that layout is
//! the `sage-synth` crate.
//!
//! Load a folder with [`Scene::load`]; write one with [`Scene::save`].

pub mod collision;
pub mod floorplan;
pub mod formats;
pub mod gaussians;
pub mod instances;
mod mapped;
pub mod mesh;
pub mod object;
pub mod occupancy;
pub mod ply;
pub mod preview;
pub mod scene;
pub mod splats;
pub mod summary;
pub mod vocabulary;

pub use floorplan::{Floorplan, Hole, HoleKind, Room, StructureItem, Wall};
pub use gaussians::{FLOOR_BAND, Gaussian, Gaussians};
pub use instances::{InstanceKind, InstanceTable};
pub use mesh::TriMesh;
pub use object::{Attributes, BodyParts, BodySource, DoorState, Object, PhysicsRole, RigidBody};
pub use occupancy::OccupancyMap;
pub use ply::SplatLayout;
pub use scene::{
    LoadOptions, LoadReport, Scene, gaussians_file, input_hashes, scene_files, scenes_input_hashes,
};
pub use summary::SceneSummary;
