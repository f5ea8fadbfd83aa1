//! `sage3d bench bodies`: bodies recovered from the Gaussians against the bodies decomposed from
//! the meshes, on generated homes where both exist.
//!
//! Per scene: the mesh bodies (the default V-HACD) and the bodies recovered from the Gaussians
//! alone ([`sage_physics::splat_bodies`], every object); the volume IoU of each object's two
//! bodies; then the same walks in a world of each (no rendering), scored in mode `sage`: the
//! oracle on the scene's trajectories, and — since the oracle keeps clear of everything — a
//! seeded random agent on the same episodes, whose bumps show where the bodies differ. The mean
//! CR and ICP of each world and their differences are reported. A picture shows a vertical section through a table and a chair: mesh
//! hulls, recovered parts and their overlap.

use crate::{machine, median};
use glam::{Vec2, Vec3};
use sage_core::{Error, Result};
use sage_env::agents::{Agent, OracleAgent, RandomAgent};
use sage_env::{Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig, scoring};
use sage_io::canvas::Canvas;
use sage_metrics::Mode;
use sage_nav::{GridParams, TrajectoryParams};
use sage_physics::{
    ConvexPart, Decomposer, HullCache, SceneBodies, SplatBodies, SplatBodyParams, splat_bodies,
    volume_iou,
};
use sage_scene::Scene;
use sage_synth::{SceneKind, SynthConfig};
use serde::Serialize;
use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

/// What `bench bodies` compares.
#[derive(Clone, Debug, PartialEq)]
pub struct BodiesSettings {
    /// Seeds of the generated homes (one home each).
    pub seeds: Vec<u64>,
    /// Rooms per home.
    pub rooms: usize,
    /// Objects per home.
    pub objects: usize,
    /// Gaussians per home.
    pub gaussians: usize,
    /// Oracle walks per home.
    pub walks: usize,
    /// IoU sampling cell, metres.
    pub cell: f32,
    /// Hull cache folder (`None`: a folder in the system temp dir, so repeated runs reuse it).
    pub cache: Option<PathBuf>,
    /// Where to write the section picture (`None`: none).
    pub picture: Option<PathBuf>,
}

impl Default for BodiesSettings {
    fn default() -> Self {
        BodiesSettings {
            seeds: vec![5, 6, 7],
            rooms: 3,
            objects: 30,
            gaussians: 400_000,
            walks: 16,
            cell: 0.01,
            cache: None,
            picture: None,
        }
    }
}

/// One object's comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObjectIou {
    /// Seed of its home.
    pub seed: u64,
    /// Category.
    pub category: String,
    /// Volume IoU of its recovered and mesh bodies.
    pub iou: f32,
    /// Convex parts of the recovered body.
    pub parts: usize,
}

/// What `bench bodies` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BodiesReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Every object compared.
    pub objects: Vec<ObjectIou>,
    /// Median IoU over them.
    pub median_iou: f64,
    /// Oracle walks run in each world.
    pub walks: usize,
    /// Mean CR (collision events per episode, mode `sage`) with mesh bodies.
    pub cr_mesh: f64,
    /// Mean CR with recovered bodies.
    pub cr_splats: f64,
    /// Mean ICP with mesh bodies.
    pub icp_mesh: f64,
    /// Mean ICP with recovered bodies.
    pub icp_splats: f64,
    /// The random agent's mean CR with mesh bodies.
    pub random_cr_mesh: f64,
    /// The random agent's mean CR with recovered bodies.
    pub random_cr_splats: f64,
    /// The random agent's mean ICP with mesh bodies.
    pub random_icp_mesh: f64,
    /// The random agent's mean ICP with recovered bodies.
    pub random_icp_splats: f64,
    /// The picture written, if any.
    pub picture: Option<String>,
}

/// Builds both kinds of bodies of each home, compares them and walks them.
///
/// # Errors
///
/// A home, its bodies or its trajectories cannot be made, the environment fails, or the
/// picture cannot be written.
pub fn run(settings: &BodiesSettings) -> Result<BodiesReport> {
    if settings.seeds.is_empty() || settings.cell.is_nan() || settings.cell <= 0.0 {
        return Err(Error::invalid("bench bodies needs a seed and a cell > 0"));
    }
    let cache = HullCache::new(
        settings
            .cache
            .clone()
            .unwrap_or_else(|| std::env::temp_dir().join("sage3d-bench-bodies-hulls")),
    );
    let mut objects = Vec::new();
    let (mut mesh_walks, mut splat_walks) = (Vec::new(), Vec::new());
    let (mut mesh_random, mut splat_random) = (Vec::new(), Vec::new());
    let mut section: Option<Section> = None;
    for &seed in &settings.seeds {
        eprintln!("home {seed}: generating, decomposing and recovering bodies …");
        let scene = sage_synth::generate(&SynthConfig {
            seed,
            kind: SceneKind::Home,
            rooms: settings.rooms,
            objects: settings.objects,
            gaussians: settings.gaussians,
            ..SynthConfig::default()
        })?;
        let (mesh, _) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
        let mut recovered = scene.clone();
        splat_bodies::attach(
            &mut recovered,
            SplatBodies::Always,
            &SplatBodyParams::default(),
        )?;
        let (splats, _) = SceneBodies::build(&recovered, &Decomposer::default(), &cache)?;
        let object_parts = |b: &SceneBodies, i: usize| -> Vec<ConvexPart> {
            b.bodies
                .iter()
                .filter(|x| x.kind == sage_physics::BodyKind::Object(i))
                .flat_map(|x| x.parts.iter().cloned())
                .collect()
        };
        for (i, o) in scene.objects.iter().enumerate() {
            let (m, s) = (object_parts(&mesh, i), object_parts(&splats, i));
            if m.is_empty() && s.is_empty() {
                continue;
            }
            objects.push(ObjectIou {
                seed,
                category: o.category.clone(),
                iou: volume_iou(&m, &s, settings.cell),
                parts: s.len(),
            });
        }
        if settings.picture.is_some() {
            section
                .get_or_insert_with(Section::default)
                .add(&scene, &mesh, &splats);
        }
        eprintln!("home {seed}: oracle and random walks in both worlds …");
        let episodes = walks(&scene, settings.walks, seed)?;
        let (m, r) = walk(scene.clone(), mesh, &episodes, seed)?;
        mesh_walks.extend(m);
        mesh_random.extend(r);
        let (m, r) = walk(recovered, splats, &episodes, seed)?;
        splat_walks.extend(m);
        splat_random.extend(r);
    }
    let picture = match (&settings.picture, &section) {
        (Some(path), Some(s)) => {
            s.save(path)?;
            Some(path.display().to_string())
        }
        _ => None,
    };
    let ious: Vec<f64> = objects.iter().map(|o| f64::from(o.iou)).collect();
    let mean = |v: &[(f64, f64)], k: fn(&(f64, f64)) -> f64| {
        v.iter().map(k).sum::<f64>() / v.len().max(1) as f64
    };
    Ok(BodiesReport {
        machine: machine::describe(),
        median_iou: median(&ious),
        walks: mesh_walks.len(),
        cr_mesh: mean(&mesh_walks, |w| w.0),
        cr_splats: mean(&splat_walks, |w| w.0),
        icp_mesh: mean(&mesh_walks, |w| w.1),
        icp_splats: mean(&splat_walks, |w| w.1),
        random_cr_mesh: mean(&mesh_random, |w| w.0),
        random_cr_splats: mean(&splat_random, |w| w.0),
        random_icp_mesh: mean(&mesh_random, |w| w.1),
        random_icp_splats: mean(&splat_random, |w| w.1),
        objects,
        picture,
    })
}

/// The oracle walks of a home: its generated trajectories as goal episodes.
fn walks(scene: &Scene, count: usize, seed: u64) -> Result<Vec<EnvEpisode>> {
    let params = TrajectoryParams {
        count,
        seed,
        ..TrajectoryParams::default()
    };
    let prep = sage_nav::trajectory::prepare(scene, &params)?;
    let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params)?;
    Ok(set
        .trajectories
        .iter()
        .map(|t| EnvEpisode::from_trajectory(format!("t{}", t.id), t, "go to the goal"))
        .collect())
}

/// (CR, ICP) per episode: of the oracle, and of the random agent.
type Walked = (Vec<(f64, f64)>, Vec<(f64, f64)>);

/// Walks every episode in a world of `bodies` with the oracle, then with a random agent seeded
/// with `seed`.
fn walk(scene: Scene, bodies: SceneBodies, episodes: &[EnvEpisode], seed: u64) -> Result<Walked> {
    let ctx = Arc::new(SceneContext::new(
        scene,
        bodies,
        &GridParams::default(),
        TrajectoryParams::default().cost,
    )?);
    let config = EnvConfig {
        sensors: SensorConfig::default().without_images(),
        ..EnvConfig::default()
    };
    let mut env = Env::new(ctx.clone(), config)?;
    let mut run = |agent: &mut dyn Agent, e: &EnvEpisode| -> Result<(f64, f64)> {
        let mut obs = env.reset(e)?;
        agent.reset(&env, e)?;
        while !env.done() {
            let action = agent.act(&obs)?;
            obs = env.step(action)?.0;
        }
        let trace = env
            .trace()
            .ok_or_else(|| Error::invalid("an episode ended without a trace"))?;
        let m = scoring::score(&ctx, trace, Mode::Sage)?;
        Ok((m.cr.unwrap_or(0.0), m.icp.unwrap_or(0.0)))
    };
    let (mut oracle, mut random) = (Vec::new(), Vec::new());
    for e in episodes {
        oracle.push(run(&mut OracleAgent::default(), e)?);
        random.push(run(&mut RandomAgent::new(seed, 0.01)?, e)?);
    }
    Ok((oracle, random))
}

/// Vertical sections through the first table and the first chair found: each object's mesh
/// hulls and recovered parts sampled over the plane through its centre along its own x axis.
#[derive(Default)]
struct Section {
    panels: Vec<Panel>,
}

/// One object's section: its name, cells along x and z, and per cell (top row first) whether
/// it lies in the mesh hulls and in the recovered parts.
struct Panel {
    name: String,
    nx: usize,
    nz: usize,
    cells: Vec<(bool, bool)>,
}

/// Pixels per section cell.
const CELL_PX: usize = 4;
/// Section sampling cell, metres.
const SECTION_CELL: f32 = 0.01;

impl Section {
    fn add(&mut self, scene: &Scene, mesh: &SceneBodies, splats: &SceneBodies) {
        for (wants, label) in [
            (
                &["dining_table", "coffee_table", "table", "desk"][..],
                "TABLE",
            ),
            (&["dining_chair", "chair"][..], "CHAIR"),
        ] {
            if self.panels.iter().any(|p| p.name.starts_with(label)) {
                continue;
            }
            // The first object of the most wanted category present (a lamp is no table).
            let Some(i) = wants.iter().find_map(|w| {
                scene
                    .objects
                    .iter()
                    .position(|o| o.category.contains(w) && !o.category.contains("lamp"))
            }) else {
                continue;
            };
            let o = &scene.objects[i];
            let parts = |b: &SceneBodies| -> Vec<ConvexPart> {
                b.bodies
                    .iter()
                    .filter(|x| x.kind == sage_physics::BodyKind::Object(i))
                    .flat_map(|x| x.parts.iter().cloned())
                    .collect()
            };
            let (m, s) = (parts(mesh), parts(splats));
            let half = o.obb.half_extents + Vec3::splat(0.05);
            let (nx, nz) = (
                (half.x * 2.0 / SECTION_CELL).ceil() as usize,
                (half.z * 2.0 / SECTION_CELL).ceil() as usize,
            );
            let (c, sn) = (o.obb.yaw.cos(), o.obb.yaw.sin());
            let cells = (0..nz)
                .rev()
                .flat_map(|k| (0..nx).map(move |j| (j, k)))
                .map(|(j, k)| {
                    let lx = -half.x + (j as f32 + 0.5) * SECTION_CELL;
                    let lz = -half.z + (k as f32 + 0.5) * SECTION_CELL;
                    let p = o.obb.center + Vec3::new(c * lx, sn * lx, lz);
                    (
                        m.iter().any(|q| q.contains(p)),
                        s.iter().any(|q| q.contains(p)),
                    )
                })
                .collect();
            self.panels.push(Panel {
                name: format!("{label} {}", o.category.to_uppercase()),
                nx,
                nz,
                cells,
            });
        }
    }

    fn save(&self, path: &std::path::Path) -> Result<()> {
        const MESH: [u8; 3] = [70, 130, 220];
        const SPLATS: [u8; 3] = [230, 120, 40];
        const BOTH: [u8; 3] = [90, 90, 90];
        let gap = 16;
        let width = self
            .panels
            .iter()
            .map(|p| p.nx * CELL_PX + gap)
            .sum::<usize>()
            .max(200)
            + gap
            + sage_io::canvas::legend_width(16);
        let rows = self
            .panels
            .iter()
            .map(|p| p.nz * CELL_PX)
            .max()
            .unwrap_or(0);
        let height = rows.max(sage_io::canvas::legend_height(3)) + 3 * gap;
        let mut canvas = Canvas::new(width, height, [255, 255, 255], Vec2::ZERO, 1.0, height);
        let mut x0 = gap;
        for Panel {
            name,
            nx,
            nz,
            cells,
        } in &self.panels
        {
            canvas.text(x0 as i64, (gap / 2) as i64, name, [0, 0, 0], 1);
            for (n, &(m, s)) in cells.iter().enumerate() {
                let color = match (m, s) {
                    (true, true) => BOTH,
                    (true, false) => MESH,
                    (false, true) => SPLATS,
                    (false, false) => continue,
                };
                let (j, k) = (n % nx, n / nx);
                for dy in 0..CELL_PX {
                    for dx in 0..CELL_PX {
                        canvas.put(
                            (x0 + j * CELL_PX + dx) as i64,
                            (2 * gap + rows - nz * CELL_PX + k * CELL_PX + dy) as i64,
                            color,
                        );
                    }
                }
            }
            x0 += nx * CELL_PX + gap;
        }
        canvas.legend(
            x0 as i64,
            "SECTION",
            &[
                (MESH, "MESH HULLS ONLY".into()),
                (SPLATS, "GAUSSIANS ONLY".into()),
                (BOTH, "BOTH".into()),
            ],
        );
        canvas.save_png(path)
    }
}

impl fmt::Display for BodiesReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "machine: {}", self.machine)?;
        let mut categories: Vec<&str> = self.objects.iter().map(|o| o.category.as_str()).collect();
        categories.sort_unstable();
        categories.dedup();
        for c in categories {
            let ious: Vec<f64> = self
                .objects
                .iter()
                .filter(|o| o.category == c)
                .map(|o| f64::from(o.iou))
                .collect();
            writeln!(
                f,
                "  {c:<16} {:>3} objects  median IoU {:.3}",
                ious.len(),
                median(&ious)
            )?;
        }
        writeln!(
            f,
            "volume IoU, bodies from Gaussians vs mesh hulls: median {:.3} over {} objects",
            self.median_iou,
            self.objects.len()
        )?;
        writeln!(
            f,
            "oracle walks: {}  CR mesh {:.3} / Gaussians {:.3} (diff {:+.3})  ICP mesh {:.4} / Gaussians {:.4} (diff {:+.4})",
            self.walks,
            self.cr_mesh,
            self.cr_splats,
            self.cr_splats - self.cr_mesh,
            self.icp_mesh,
            self.icp_splats,
            self.icp_splats - self.icp_mesh
        )?;
        writeln!(
            f,
            "random walks: {}  CR mesh {:.3} / Gaussians {:.3} (diff {:+.3})  ICP mesh {:.4} / Gaussians {:.4} (diff {:+.4})",
            self.walks,
            self.random_cr_mesh,
            self.random_cr_splats,
            self.random_cr_splats - self.random_cr_mesh,
            self.random_icp_mesh,
            self.random_icp_splats,
            self.random_icp_splats - self.random_icp_mesh
        )?;
        if let Some(p) = &self.picture {
            writeln!(f, "section picture: {p}")?;
        }
        Ok(())
    }
}
