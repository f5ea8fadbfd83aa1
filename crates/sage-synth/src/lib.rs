//! `sage-synth`: the seeded generator of whole synthetic scenes — multi-room homes, offices and
//! shops in the InteriorGS layout (SPEC §4) of the `sage-scene` model; the embedded default
//! scene and the test data of the project.
//!
//! [`generate`] builds, from a [`SynthConfig`]:
//!
//! 1. a floorplan: a rectangular footprint cut into typed rooms by binary space partitioning, walls
//!    with thickness, doors (a spanning tree over the rooms plus a few extra, an entrance; open,
//!    closed or half-open) and windows on the outside walls (`layout.rs`);
//! 2. a door leaf or window frame object in every opening (`openings.rs`) and furniture from a
//!    catalogue of about fifty categories placed by room type without overlaps (`catalog.rs`,
//!    `placement.rs`), each with a closed, concave-where-real mesh built from boxes and surfaces of
//!    revolution (`furniture.rs`, `shapes.rs`) and attributes that match how it looks (`look.rs`,
//!    with the colour words of `sage_scene::vocabulary`);
//! 3. Gaussians (SH degree 1) sampled evenly over every surface with procedural textures
//!    (`structure.rs`, `surfaces.rs`), a structure mesh, and an occupancy map (`occupancy.rs`).
//!
//! Everything is drawn from one ChaCha8 stream seeded by [`SynthConfig::seed`]; the parallel
//! Gaussian sampling uses one sub-stream per surface and keeps surface order, so the scene is the
//! same byte for byte whatever the thread count.

mod catalog;
mod furniture;
mod item;
mod layout;
mod look;
mod occupancy;
mod openings;
mod placement;
mod shapes;
mod structure;
mod surfaces;

use rand::seq::IndexedRandom;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Result};
use sage_scene::instances::InstanceTable;
use sage_scene::scene::Scene;
use std::fmt;
use std::str::FromStr;

/// What kind of building to generate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum SceneKind {
    /// A home: living room, kitchen, bedrooms, bathrooms, dining room, study, corridor.
    #[default]
    Home,
    /// An office: open office, meeting rooms, manager offices, pantry, reception.
    Office,
    /// A shop: sales floor, storage room, checkout, fitting rooms.
    Shop,
}

impl SceneKind {
    /// All kinds, in a fixed order.
    pub const ALL: [SceneKind; 3] = [SceneKind::Home, SceneKind::Office, SceneKind::Shop];

    /// The word used on the command line and in scene names (`home`, `office`, `shop`).
    pub fn as_str(self) -> &'static str {
        match self {
            SceneKind::Home => "home",
            SceneKind::Office => "office",
            SceneKind::Shop => "shop",
        }
    }
}

impl fmt::Display for SceneKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SceneKind {
    type Err = Error;

    /// Parses `home`, `office` or `shop` (any case).
    fn from_str(s: &str) -> Result<SceneKind> {
        SceneKind::ALL
            .into_iter()
            .find(|k| k.as_str().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| {
                Error::invalid(format!(
                    "unknown scene kind '{s}' (expected home, office or shop)"
                ))
            })
    }
}

/// What to generate. The same configuration always gives the same scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthConfig {
    /// Seed of every random choice.
    pub seed: u64,
    /// Home, office or shop.
    pub kind: SceneKind,
    /// Number of rooms (1–64); the footprint grows with it.
    pub rooms: usize,
    /// Target number of objects, doors and windows included (0–5000); furniture stops when it is
    /// reached or the rooms are full.
    pub objects: usize,
    /// Number of Gaussians (exact; 1000–20 000 000).
    pub gaussians: usize,
    /// Wall and ceiling height, metres (2.4–5).
    pub wall_height: f32,
    /// Occupancy cell size, metres (0.02–0.5).
    pub cell: f32,
}

impl Default for SynthConfig {
    fn default() -> Self {
        SynthConfig {
            seed: 0,
            kind: SceneKind::Home,
            rooms: 5,
            objects: 60,
            gaussians: 150_000,
            wall_height: 2.8,
            cell: 0.05,
        }
    }
}

/// Rooms a synthetic scene may have.
pub const ROOMS: std::ops::RangeInclusive<usize> = 1..=64;
/// Objects a synthetic scene may have.
pub const OBJECTS: std::ops::RangeInclusive<usize> = 0..=5000;
/// Gaussian budgets a synthetic scene may have.
pub const GAUSSIANS: std::ops::RangeInclusive<usize> = 1000..=20_000_000;

impl SynthConfig {
    /// Checks every field against its documented range.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the first field out of range.
    pub fn validate(&self) -> Result<()> {
        let check = |ok: bool, msg: String| if ok { Ok(()) } else { Err(Error::invalid(msg)) };
        let range = |r: &std::ops::RangeInclusive<usize>| format!("{}-{}", r.start(), r.end());
        check(
            ROOMS.contains(&self.rooms),
            format!("synth: rooms must be {}, got {}", range(&ROOMS), self.rooms),
        )?;
        check(
            OBJECTS.contains(&self.objects),
            format!(
                "synth: objects must be {}, got {}",
                range(&OBJECTS),
                self.objects
            ),
        )?;
        check(
            GAUSSIANS.contains(&self.gaussians),
            format!(
                "synth: gaussians must be {}, got {}",
                range(&GAUSSIANS),
                self.gaussians
            ),
        )?;
        check(
            (2.4..=5.0).contains(&self.wall_height),
            format!(
                "synth: wall_height must be 2.4-5 m, got {}",
                self.wall_height
            ),
        )?;
        check(
            (0.02..=0.5).contains(&self.cell),
            format!("synth: cell must be 0.02-0.5 m, got {}", self.cell),
        )
    }

    /// The name of the generated scene, `synth_{kind}_s{seed}`.
    pub fn scene_name(&self) -> String {
        format!("synth_{}_s{}", self.kind, self.seed)
    }
}

/// A uniform draw between `lo` and `hi` (never panics, unlike `random_range` on an empty range).
pub(crate) fn uniform(rng: &mut (impl RngCore + ?Sized), lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.random::<f32>()
}

/// A random word of `words` (`"gray"` from an empty list).
pub(crate) fn pick<'a>(rng: &mut (impl RngCore + ?Sized), words: &[&'a str]) -> &'a str {
    words.choose(rng).copied().unwrap_or("gray")
}

/// Generates the scene `config` describes (see the module docs).
///
/// # Errors
///
/// An `invalid` error when the configuration is out of range (see [`SynthConfig::validate`]).
pub fn generate(config: &SynthConfig) -> Result<Scene> {
    config.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let layout = layout::plan(config, &mut rng);
    let mut items = openings::build(&layout, &mut rng);
    let quota = config.objects.saturating_sub(items.len());
    let furniture = placement::furnish(&layout, &items, quota, &mut rng);
    items.extend(furniture);
    let mut patches = structure::patches(&layout);
    for item in &items {
        item.patches(&mut patches);
    }
    // Stored along a Morton curve, as splat-transform stores InteriorGS files: compressed chunks
    // stay tight and renderers read the store sequentially.
    let mut gaussians = surfaces::sample(&patches, config.gaussians, rng.next_u64())?;
    gaussians.sort_morton();
    let occupancy = occupancy::build(&layout, &items, config.cell)?;
    let mut scene = Scene {
        name: config.scene_name(),
        gaussians,
        objects: items
            .iter()
            .enumerate()
            .map(|(i, item)| item.to_object(i))
            .collect(),
        floorplan: layout.floorplan(),
        occupancy: Some(occupancy),
        structure_mesh: Some(structure::mesh(&layout)),
        structure_body: None,
        instances: InstanceTable::default(),
    };
    scene.finish();
    Ok(scene)
}
