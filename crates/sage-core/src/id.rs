//! Instance ids: the dense integer that names an object or structure element inside one scene.

use serde::{Deserialize, Serialize};

/// A dense per-scene instance id. `0` means "no instance" (a Gaussian that belongs to nothing).
///
/// Ids are assigned when a scene loads: objects first (in `labels.json` order, from 1), then the
/// structure elements (walls, then floors, then ceilings). The scene's instance table maps each id
/// back to its source (`ins_id` string, category, kind).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct InstanceId(pub u32);

impl InstanceId {
    /// The id of nothing.
    pub const NONE: InstanceId = InstanceId(0);

    /// True for [`InstanceId::NONE`].
    pub fn is_none(self) -> bool {
        self.0 == 0
    }
}
