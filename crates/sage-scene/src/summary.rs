//! A plain-data summary of a scene: what `sage3d scene info` prints.

use crate::instances::InstanceKind;
use crate::object::DoorState;
use crate::scene::Scene;
use serde::Serialize;
use std::collections::BTreeMap;

/// Counts, categories, rooms, bounds and memory of a scene.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SceneSummary {
    /// Scene name.
    pub name: String,
    /// Number of Gaussians.
    pub gaussians: usize,
    /// SH degree of the Gaussians.
    pub sh_degree: u8,
    /// Heap bytes of the Gaussian store.
    pub gaussian_bytes: usize,
    /// Heap bytes per Gaussian.
    pub bytes_per_gaussian: f64,
    /// Share of Gaussians that belong to an object or structure element.
    pub gaussians_with_instance: f64,
    /// Lower corner of the scene bounds (metres, W).
    pub bounds_min: [f32; 3],
    /// Upper corner of the scene bounds.
    pub bounds_max: [f32; 3],
    /// Number of objects.
    pub objects: usize,
    /// Objects that have a mesh.
    pub objects_with_mesh: usize,
    /// Object count per category.
    pub categories: BTreeMap<String, usize>,
    /// Rooms as (type, area m²).
    pub rooms: Vec<(String, f32)>,
    /// Number of walls.
    pub walls: usize,
    /// Door count per state (`unknown` when the file gives none).
    pub doors: BTreeMap<String, usize>,
    /// Number of windows.
    pub windows: usize,
    /// Occupancy map as (width, height, metres per cell), if any.
    pub occupancy: Option<(usize, usize, f32)>,
    /// Number of instance ids (objects and structure elements, without 0).
    pub instances: usize,
}

impl Scene {
    /// Summarises the scene.
    pub fn summary(&self) -> SceneSummary {
        let g = &self.gaussians;
        let bounds = self.bounds();
        let mut categories = BTreeMap::new();
        for o in &self.objects {
            *categories.entry(o.category.clone()).or_insert(0) += 1;
        }
        let mut doors = BTreeMap::new();
        for d in self.floorplan.doors() {
            *doors
                .entry(d.state.map_or("unknown", DoorState::as_str).to_string())
                .or_insert(0) += 1;
        }
        let with_instance = g.instances.iter().filter(|&&i| i != 0).count();
        SceneSummary {
            name: self.name.clone(),
            gaussians: g.len(),
            sh_degree: g.sh_degree(),
            gaussian_bytes: g.heap_bytes(),
            bytes_per_gaussian: g.heap_bytes() as f64 / g.len().max(1) as f64,
            gaussians_with_instance: with_instance as f64 / g.len().max(1) as f64,
            bounds_min: bounds.min.to_array(),
            bounds_max: bounds.max.to_array(),
            objects: self.objects.len(),
            objects_with_mesh: self.objects.iter().filter(|o| o.mesh.is_some()).count(),
            categories,
            rooms: self
                .floorplan
                .rooms
                .iter()
                .map(|r| (r.room_type.clone(), r.profile.area()))
                .collect(),
            walls: self.floorplan.walls.len(),
            doors,
            windows: self.floorplan.windows().count(),
            occupancy: self
                .occupancy
                .as_ref()
                .map(|o| (o.width, o.height, o.scale)),
            instances: self
                .instances
                .kinds
                .iter()
                .filter(|k| **k != InstanceKind::None)
                .count(),
        }
    }
}

impl std::fmt::Display for SceneSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [x0, y0, z0] = self.bounds_min;
        let [x1, y1, z1] = self.bounds_max;
        writeln!(f, "scene       {}", self.name)?;
        writeln!(
            f,
            "bounds      x {x0:.2}..{x1:.2}  y {y0:.2}..{y1:.2}  z {z0:.2}..{z1:.2} m"
        )?;
        writeln!(
            f,
            "gaussians   {} (SH degree {}), {:.1} MB in memory = {:.1} bytes/Gaussian, {:.1}% with an instance",
            self.gaussians,
            self.sh_degree,
            self.gaussian_bytes as f64 / 1e6,
            self.bytes_per_gaussian,
            self.gaussians_with_instance * 100.0
        )?;
        writeln!(
            f,
            "objects     {} in {} categories, {} with a mesh",
            self.objects,
            self.categories.len(),
            self.objects_with_mesh
        )?;
        let cats: Vec<String> = self
            .categories
            .iter()
            .map(|(c, n)| format!("{c} {n}"))
            .collect();
        if !cats.is_empty() {
            writeln!(f, "categories  {}", cats.join(", "))?;
        }
        writeln!(f, "rooms       {}", self.rooms.len())?;
        for (t, a) in &self.rooms {
            writeln!(f, "            {t} ({a:.1} m²)")?;
        }
        let states: Vec<String> = self.doors.iter().map(|(s, n)| format!("{n} {s}")).collect();
        let states = if states.is_empty() {
            String::new()
        } else {
            format!(" ({})", states.join(", "))
        };
        writeln!(
            f,
            "structure   {} walls, {} doors{states}, {} windows",
            self.walls,
            self.doors.values().sum::<usize>(),
            self.windows
        )?;
        match self.occupancy {
            Some((w, h, s)) => writeln!(f, "occupancy   {w} x {h} cells of {s} m")?,
            None => writeln!(f, "occupancy   none")?,
        }
        write!(f, "instances   {}", self.instances)
    }
}
