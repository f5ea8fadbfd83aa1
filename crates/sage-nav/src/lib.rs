//! `sage-nav`: where an agent can go in a scene, and the reference paths of the benchmark.
//!
//! From a [`sage_scene::Scene`] this crate builds the 2-D semantic top-down map
//! ([`semantic_map`]), the occupancy grid of an agent's height slab ([`grid`]; from the
//! Gaussians where a scene has no floorplan, [`splat_grid`]; which of them, [`source`]), its exact
//! Euclidean distance transform ([`edt`]), a clearance-aware cost ([`cost`]) and an array-based
//! A* / Dijkstra ([`astar`]); [`pathfinder`] wraps them in a Habitat-like API, [`path`] turns grid
//! paths into smooth, resampled trajectories, [`sampling`] draws start–goal pairs over rooms,
//! functional areas and objects, and [`trajectory`] generates, writes and resumes whole datasets.
//! SPEC §5 and §7; the conventions are documented in `docs/navigation.md`.

pub mod astar;
pub mod cost;
pub mod edt;
pub mod gnbench;
pub mod grid;
pub mod path;
pub mod pathfinder;
pub mod published_map;
pub mod sampling;
pub mod semantic_map;
pub mod source;
pub mod splat_grid;
pub mod trajectory;

pub use cost::CostParams;
pub use grid::{GridParams, NavGrid};
pub use pathfinder::{NavPath, PathFinder};
pub use published_map::PublishedMap;
pub use sampling::{EndpointKind, SamplingParams};
pub use semantic_map::{MapItem, SemanticMap};
pub use source::GridSource;
pub use splat_grid::SplatGridParams;
pub use trajectory::{Trajectory, TrajectoryParams, TrajectorySet};
