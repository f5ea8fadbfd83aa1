//! `sage-physics`: Φ of G + M + Φ — what makes a 3DGS scene executable.
//!
//! Collision bodies per object by approximate convex decomposition of its mesh (parry's V-HACD
//! in process, CoACD offline), cached on disk by mesh hash and settings ([`decompose`]); walls
//! extruded from the floorplan with their openings cut, floor and ceiling slabs ([`bodies`]);
//! bodies recovered from an object's own Gaussians where it has no mesh ([`splat_bodies`]);
//! a rapier3d world with static, movable and articulated bodies ([`world`]); ground robots and a
//! UAV moved by collide-and-slide with a contact report per step — touched instances,
//! penetration, collision intensity c(t), contact onset, stuck and recovery ([`agent`]); and the
//! hybrid USDA scene ([`usd`]).

pub mod agent;
pub mod bodies;
pub mod decompose;
pub mod hull;
pub mod splat_bodies;
pub mod usd;
pub mod worklist;
pub mod world;

pub use agent::{
    AgentBody, AgentProfile, Command, Locomotion, StepReport, Touch, check_pose,
    collision_intensity,
};
pub use bodies::{Body, BodyKind, BuildReport, PartSource, SceneBodies};
pub use decompose::{CacheEntry, Decomposer, HullCache, cache_key, default_cache_dir};
pub use hull::{ConvexPart, volume_iou};
pub use splat_bodies::{SplatBodies, SplatBodyParams, SplatBodyReport};
pub use worklist::WorkList;
pub use world::{World, WorldOptions};
