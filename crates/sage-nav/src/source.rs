//! Which source a scene's occupancy grid is built from ([`NavGrid::from_scene`]): the scene's
//! own occupancy map, its geometry ([`crate::grid`]), its geometry and its Gaussians, or its
//! Gaussians alone ([`crate::splat_grid`]). This module sits above both builders, so neither
//! needs the other.

use crate::grid::{
    ExtentPart, GridParams, NavGrid, block_geometry, farthest, geometry_bounds, geometry_parts,
    rasterize,
};
use crate::splat_grid::{self, SplatGridParams};
use sage_core::{Error, Result};
use sage_scene::Scene;

/// Where a grid's cells came from, in the order [`NavGrid::from_scene`] prefers them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridSource {
    /// The scene's own `occupancy.png` (it has no meshes, or no rooms to tell free space by).
    SceneOccupancy,
    /// Rasterised from meshes, boxes and walls; free space is the rooms of `structure.json`.
    Geometry,
    /// Obstacles from meshes, boxes and walls and from the Gaussians; free space where the
    /// Gaussians show floor (the scene has objects but no rooms).
    GeometryGaussians,
    /// The Gaussians alone ([`crate::splat_grid`]): the scene has no rooms, no objects and no
    /// occupancy map.
    Gaussians,
}

impl GridSource {
    /// `scene-occupancy`, `geometry`, `geometry+gaussians` or `gaussians`.
    pub fn as_str(self) -> &'static str {
        match self {
            GridSource::SceneOccupancy => "scene-occupancy",
            GridSource::Geometry => "geometry",
            GridSource::GeometryGaussians => "geometry+gaussians",
            GridSource::Gaussians => "gaussians",
        }
    }
}

impl NavGrid {
    /// Builds the grid of a scene from the best source it has, in this order:
    ///
    /// 1. its own occupancy map, when it has no meshes (its map was made with the geometry it
    ///    does not ship) or no rooms (nothing else tells free space as well);
    /// 2. its geometry, free space being the rooms of `structure.json`;
    /// 3. with objects but no rooms: obstacles from the geometry and the Gaussians, free space
    ///    where the Gaussians show floor ([`crate::splat_grid`]);
    /// 4. with neither: the Gaussians alone.
    ///
    /// # Errors
    ///
    /// Bad parameters, or a scene with no rooms, no occupancy map and no Gaussians showing a
    /// floor at z = 0.
    pub fn from_scene(scene: &Scene, params: &GridParams) -> Result<(NavGrid, GridSource)> {
        NavGrid::from_scene_with(scene, params, &SplatGridParams::default())
    }

    /// [`NavGrid::from_scene`] with the Gaussian evidence rules `splat` (used by sources 3 and
    /// 4 only).
    ///
    /// # Errors
    ///
    /// As [`NavGrid::from_scene`].
    pub fn from_scene_with(
        scene: &Scene,
        params: &GridParams,
        splat: &SplatGridParams,
    ) -> Result<(NavGrid, GridSource)> {
        params.validate()?;
        let has_meshes =
            scene.structure_mesh.is_some() || scene.objects.iter().any(|o| o.mesh.is_some());
        let has_rooms = !scene.floorplan.rooms.is_empty();
        if (!has_meshes || !has_rooms)
            && let Some(occ) = &scene.occupancy
        {
            let mut grid = NavGrid::from_occupancy(occ)?;
            grid.mark_rooms(scene);
            return Ok((grid, GridSource::SceneOccupancy));
        }
        if has_rooms {
            return Ok((rasterize(scene, params)?, GridSource::Geometry));
        }
        if scene.gaussians.is_empty() {
            return Err(Error::invalid(format!(
                "scene {}: no rooms in structure.json, no occupancy map and no Gaussians, so free space is undefined",
                scene.name
            )));
        }
        let slab = (params.slab_bottom, params.agent_height);
        let has_geometry = !scene.objects.is_empty()
            || !scene.floorplan.walls.is_empty()
            || scene.structure_mesh.is_some();
        let extra = has_geometry.then(|| geometry_bounds(scene));
        let mut grid = splat_grid::gaussian_grid_with(
            &scene.gaussians,
            params.cell,
            slab,
            params.margin,
            splat,
            extra,
        )
        .map_err(|e| {
            // The extent is the Gaussians' and the geometry's: say where each reaches.
            let g = scene.gaussians.bounds();
            let mut parts = vec![ExtentPart {
                name: "the Gaussians".to_string(),
                lo: g.min.truncate(),
                hi: g.max.truncate(),
            }];
            parts.extend(geometry_parts(scene));
            Error::invalid(format!("scene {}: {e}{}", scene.name, farthest(&parts)))
        })?;
        if !has_geometry {
            return Ok((grid, GridSource::Gaussians));
        }
        block_geometry(&mut grid, scene, slab);
        splat_grid::drop_small_free(&mut grid, splat.min_free_area);
        Ok((grid, GridSource::GeometryGaussians))
    }
}
