//! `sage-core`: the vocabulary every sage3d crate shares.
//!
//! Math types (re-exported from `glam`), the three coordinate frames of SPEC §3 (the internal
//! world frame W, Habitat's Y-up frame and the SAGE "S" frame), poses and angles, plain geometry
//! (oriented boxes, polygons), instance ids, the task of an episode, the one error type whose
//! messages name the file and field at fault, and the conversions of settings named by a word
//! ([`named_by_string!`]). Nothing here touches files or threads.

pub mod error;
pub mod frame;
pub mod geometry;
pub mod id;
pub mod named;
pub mod pose;
pub mod task;

pub use error::{Error, ErrorKind, Result, ResultExt};
pub use geometry::{Aabb, MAX_COORDINATE, Obb, Polygon2, within_bounds};
pub use glam;
pub use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
pub use id::InstanceId;
pub use pose::{Pose, wrap_angle};
pub use task::Task;
