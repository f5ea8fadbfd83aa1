//! The occupancy grid of a scene's Gaussians alone, for scenes that come with no floorplan and
//! no occupancy map (a capture of one's own, or InteriorGS labels without `structure.json`).
//!
//! Each Gaussian that is opaque enough (opacity ≥ [`SplatGridParams::min_opacity`]) is evidence
//! where its footprint falls: its horizontal covariance, widened by half a cell so that a thin
//! wall's Gaussians still reach the cells they cross, is splatted onto the grid as
//! `opacity · exp(−m²/2)` (m the Mahalanobis distance of a cell centre, up to 3). Two masses are
//! summed per cell:
//!
//! - **floor**: Gaussians centred within [`SplatGridParams::floor_band`] of z = 0 and thin
//!   vertically (vertical standard deviation ≤ [`SplatGridParams::floor_thickness`]): the floor
//!   was seen there;
//! - **obstacle**: Gaussians centred in the agent's slab, from the higher of the slab bottom and
//!   the floor band (floor noise is no obstacle) up to the agent height.
//!
//! A cell is occupied where the obstacle mass reaches [`SplatGridParams::obstacle_mass`], free
//! where the floor mass reaches [`SplatGridParams::floor_mass`] and the cell is not occupied, and
//! unknown otherwise (floor never seen: outside the building, under a sofa, behind a wall). The
//! cleanup is a closing (dilation then erosion by one cell) of both masks, which fills the gaps
//! between sparse Gaussians, and the removal of free components smaller than
//! [`SplatGridParams::min_free_area`] (floor seen through a window, a sliver between furniture
//! that no agent reaches). A dense surface gives a mass of about 2π·σ²·density ≈ 3 per cell
//! whatever its sampling, so the thresholds hold across densities.

use crate::grid::{NavGrid, flood4};
use glam::{Mat3, Vec2, Vec3};
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use sage_scene::occupancy::{FREE, OCCUPIED, UNKNOWN};

/// How the Gaussians become evidence (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatGridParams {
    /// Gaussians more transparent than this are no evidence (default 0.3): floaters and the
    /// faint fringes of trained scenes say little about solid matter.
    pub min_opacity: f32,
    /// Half-height of the floor band around z = 0, metres (default
    /// [`sage_scene::FLOOR_BAND`], where a capture's collision body starts too).
    pub floor_band: f32,
    /// Largest vertical standard deviation of a floor Gaussian, metres (default 0.05).
    pub floor_thickness: f32,
    /// Floor mass that makes a cell seen (default 0.5).
    pub floor_mass: f32,
    /// Obstacle mass that makes a cell occupied (default 1.0).
    pub obstacle_mass: f32,
    /// Free components smaller than this are unknown, m² (default 0.5).
    pub min_free_area: f32,
    /// Largest footprint radius splatted, metres (default 0.5): a huge background Gaussian must
    /// not paint the whole map.
    pub max_radius: f32,
}

impl Default for SplatGridParams {
    fn default() -> Self {
        SplatGridParams {
            min_opacity: 0.3,
            floor_band: sage_scene::FLOOR_BAND,
            floor_thickness: 0.05,
            floor_mass: 0.5,
            obstacle_mass: 1.0,
            min_free_area: 0.5,
            max_radius: 0.5,
        }
    }
}

impl SplatGridParams {
    /// Checks the ranges (every field finite and positive, opacity below 1).
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the first field out of range.
    pub fn validate(&self) -> Result<()> {
        let fields = [
            ("min_opacity", self.min_opacity),
            ("floor_band", self.floor_band),
            ("floor_thickness", self.floor_thickness),
            ("floor_mass", self.floor_mass),
            ("obstacle_mass", self.obstacle_mass),
            ("min_free_area", self.min_free_area),
            ("max_radius", self.max_radius),
        ];
        for (name, v) in fields {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(format!(
                    "Gaussian grid {name} must be finite and >= 0, got {v}"
                )));
            }
        }
        if self.min_opacity >= 1.0 {
            return Err(Error::invalid(format!(
                "Gaussian grid min_opacity must be below 1, got {}",
                self.min_opacity
            )));
        }
        Ok(())
    }
}

/// One Gaussian's part in the grid: its centre, horizontal covariance (widened) and weight.
struct Evidence {
    center: Vec2,
    cov: [f32; 3],
    weight: f32,
    floor: bool,
}

/// The evidence Gaussians of `g` (see the module docs) for a slab `slab` (bottom, top).
fn evidence(g: &Gaussians, slab: (f32, f32), cell: f32, p: &SplatGridParams) -> Vec<Evidence> {
    let obstacle_lo = slab.0.max(p.floor_band);
    let widen = (cell * 0.5) * (cell * 0.5);
    let cap = (p.max_radius / 3.0).powi(2);
    (0..g.len())
        .filter_map(|i| {
            let alpha = 1.0 / (1.0 + (-g.opacity_logit(i)).exp());
            let pos = Vec3::from_array(g.positions[i]);
            if alpha < p.min_opacity || !pos.is_finite() {
                return None;
            }
            let r = Mat3::from_quat(g.rotation(i));
            let s = g.log_scale(i).exp();
            // Σ = R S² Rᵀ; only its horizontal block and vertical variance matter.
            let m = r * Mat3::from_diagonal(s * s) * r.transpose();
            let var_z = m.z_axis.z;
            let floor = pos.z.abs() <= p.floor_band && var_z.sqrt() <= p.floor_thickness;
            let obstacle = pos.z >= obstacle_lo && pos.z <= slab.1;
            if !(floor || obstacle) {
                return None;
            }
            Some(Evidence {
                center: pos.truncate(),
                cov: [
                    m.x_axis.x.min(cap) + widen,
                    m.y_axis.x,
                    m.y_axis.y.min(cap) + widen,
                ],
                weight: alpha,
                floor,
            })
        })
        .collect()
}

/// Adds `e`'s footprint to `mass` (a grid-sized array).
fn splat(grid: &NavGrid, e: &Evidence, mass: &mut [f32]) {
    let [a, mut b, c] = e.cov;
    // Keep the matrix positive definite after the caps on the diagonal.
    let lim = (a * c).sqrt() * 0.99;
    b = b.clamp(-lim, lim);
    let det = a * c - b * b;
    if det.is_nan() || det <= 0.0 {
        return;
    }
    let (ia, ib, ic) = (c / det, -b / det, a / det);
    let half = Vec2::new(a.sqrt(), c.sqrt()) * 3.0;
    let Some((i0, j0, i1, j1)) = grid.cell_range(e.center - half, e.center + half) else {
        return;
    };
    for j in j0..=j1 {
        for i in i0..=i1 {
            let d = grid.center(i, j) - e.center;
            let m2 = ia * d.x * d.x + 2.0 * ib * d.x * d.y + ic * d.y * d.y;
            if m2 <= 9.0 {
                mass[grid.index(i, j)] += e.weight * (-0.5 * m2).exp();
            }
        }
    }
}

/// The grid of the Gaussians `g` alone over their evidence bounds (plus `margin`), with cells
/// of `cell` metres, for the slab `slab` = (bottom, top) above the floor at z = 0.
///
/// # Errors
///
/// Bad parameters, or no Gaussian that is evidence of floor or obstacle (the scene is not in
/// the world frame, with its floor at z = 0, or has no Gaussians).
pub fn gaussian_grid(
    g: &Gaussians,
    cell: f32,
    slab: (f32, f32),
    margin: f32,
    params: &SplatGridParams,
) -> Result<NavGrid> {
    gaussian_grid_with(g, cell, slab, margin, params, None)
}

/// [`gaussian_grid`] over the union of the Gaussians' evidence bounds and `extra` (lower and
/// upper corners), for grids that other geometry adds to.
pub(crate) fn gaussian_grid_with(
    g: &Gaussians,
    cell: f32,
    slab: (f32, f32),
    margin: f32,
    params: &SplatGridParams,
    extra: Option<(Vec2, Vec2)>,
) -> Result<NavGrid> {
    params.validate()?;
    let items = evidence(g, slab, cell, params);
    if !items.iter().any(|e| e.floor) {
        return Err(Error::invalid(format!(
            "no floor among the {} Gaussians: none that is opaque (>= {}), flat and within {} m of z = 0; \
             the scene must be in the world frame W (Z up, floor at z = 0; `sage3d scene import` puts a capture there)",
            g.len(),
            params.min_opacity,
            params.floor_band
        )));
    }
    let (mut lo, mut hi) = (Vec2::INFINITY, Vec2::NEG_INFINITY);
    for e in &items {
        lo = lo.min(e.center);
        hi = hi.max(e.center);
    }
    if let Some((a, b)) = extra {
        lo = lo.min(a);
        hi = hi.max(b);
    }
    let m = Vec2::splat(margin.max(cell));
    let mut grid = NavGrid::new(lo - m, hi + m, cell)?;
    let n = grid.cells.len();
    let (mut floor, mut solid) = (vec![0.0f32; n], vec![0.0f32; n]);
    for e in &items {
        splat(&grid, e, if e.floor { &mut floor } else { &mut solid });
    }
    let seen = close(
        &grid,
        &floor
            .iter()
            .map(|&v| v >= params.floor_mass)
            .collect::<Vec<_>>(),
    );
    let blocked = close(
        &grid,
        &solid
            .iter()
            .map(|&v| v >= params.obstacle_mass)
            .collect::<Vec<_>>(),
    );
    for k in 0..n {
        grid.cells[k] = if blocked[k] {
            OCCUPIED
        } else if seen[k] {
            FREE
        } else {
            UNKNOWN
        };
    }
    drop_small_free(&mut grid, params.min_free_area);
    Ok(grid)
}

/// Dilation by one cell (3 × 3) of `mask`.
fn dilate(grid: &NavGrid, mask: &[bool]) -> Vec<bool> {
    let (w, h) = (grid.width, grid.height);
    let mut out = vec![false; mask.len()];
    for j in 0..h {
        for i in 0..w {
            if !mask[j * w + i] {
                continue;
            }
            for y in j.saturating_sub(1)..=(j + 1).min(h - 1) {
                for x in i.saturating_sub(1)..=(i + 1).min(w - 1) {
                    out[y * w + x] = true;
                }
            }
        }
    }
    out
}

/// Closing by one cell: a dilation then an erosion (the dilation of the complement). Fills the
/// one-cell gaps between sparse Gaussians without growing the mask.
fn close(grid: &NavGrid, mask: &[bool]) -> Vec<bool> {
    let grown = dilate(grid, mask);
    let outside: Vec<bool> = grown.iter().map(|v| !v).collect();
    dilate(grid, &outside).iter().map(|v| !v).collect()
}

/// Turns the free components (4-connected) smaller than `min_area` m² into unknown.
pub(crate) fn drop_small_free(grid: &mut NavGrid, min_area: f32) {
    let min_cells = (min_area / (grid.cell * grid.cell)).ceil() as usize;
    if min_cells <= 1 {
        return;
    }
    let (w, h) = (grid.width, grid.height);
    let mut seen = vec![false; grid.cells.len()];
    let (mut stack, mut component) = (Vec::new(), Vec::new());
    for start in 0..grid.cells.len() {
        if seen[start] || grid.cells[start] != FREE {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        component.clear();
        flood4(
            w,
            h,
            &mut stack,
            |n| {
                let take = !seen[n] && grid.cells[n] == FREE;
                seen[n] |= take;
                take
            },
            |k| component.push(k),
        );
        if component.len() < min_cells {
            for &k in &component {
                grid.cells[k] = UNKNOWN;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
    use sage_scene::gaussians::Gaussian;

    /// A flat, opaque Gaussian at `p`, lying in the plane orthogonal to `normal` (Z or X).
    fn surfel(p: Vec3, normal: Vec3) -> Gaussian {
        let rotation = Quat::from_rotation_arc(Vec3::Z, normal);
        Gaussian {
            position: p,
            rotation,
            log_scale: Vec3::new(0.04f32.ln(), 0.04f32.ln(), 0.004f32.ln()),
            opacity_logit: 4.0,
            ..Gaussian::default()
        }
    }

    /// A 4 × 3 m floor sampled every 5 cm, a wall across x = 2 from y = 0 to 2 (1 m gap at the
    /// top), and a floater-like faint Gaussian in the middle of the room.
    fn room() -> Gaussians {
        let mut g = Gaussians::new(0).unwrap();
        for j in 0..60 {
            for i in 0..80 {
                let p = Vec3::new(i as f32 * 0.05, j as f32 * 0.05, 0.0);
                g.push(&surfel(p, Vec3::Z));
            }
        }
        for j in 0..40 {
            for k in 0..50 {
                let p = Vec3::new(2.0, j as f32 * 0.05, k as f32 * 0.05);
                g.push(&surfel(p, Vec3::X));
            }
        }
        g.push(&Gaussian {
            position: Vec3::new(1.0, 1.5, 0.6),
            log_scale: Vec3::splat(-1.0),
            opacity_logit: -4.0,
            ..Gaussian::default()
        });
        g
    }

    #[test]
    fn floor_is_free_wall_is_occupied_outside_is_unknown() {
        let grid =
            gaussian_grid(&room(), 0.05, (0.03, 1.2), 0.5, &SplatGridParams::default()).unwrap();
        let at = |x: f32, y: f32| {
            let (i, j) = grid.cell_at(Vec2::new(x, y)).unwrap();
            grid.cells[grid.index(i, j)]
        };
        assert_eq!(at(1.0, 1.5), FREE, "the faint Gaussian is no obstacle");
        assert_eq!(at(3.0, 1.0), FREE);
        assert_eq!(at(2.0, 1.0), OCCUPIED);
        assert_eq!(at(2.0, 2.5), FREE, "the gap beside the wall");
        assert_eq!(
            at(1.96, 1.0),
            OCCUPIED,
            "the cells on either side of the wall"
        );
        assert_eq!(at(2.04, 1.0), OCCUPIED);
        assert_eq!(at(1.88, 1.0), FREE, "and no more than those");
        assert_eq!(at(2.12, 1.0), FREE);
        assert_eq!(at(-0.3, 1.0), UNKNOWN, "no floor seen");
        assert_eq!(at(4.3, 1.0), UNKNOWN);
    }

    #[test]
    fn a_scene_without_floor_is_refused_with_the_reason() {
        let mut g = Gaussians::new(0).unwrap();
        g.push(&surfel(Vec3::new(0.0, 0.0, 1.5), Vec3::Z));
        let e = gaussian_grid(&g, 0.05, (0.03, 1.2), 0.5, &SplatGridParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no floor"), "{e}");
    }

    #[test]
    fn small_free_islands_are_dropped() {
        let mut g = Gaussians::new(0).unwrap();
        for j in 0..6 {
            for i in 0..6 {
                let p = Vec3::new(i as f32 * 0.05, j as f32 * 0.05, 0.0);
                g.push(&surfel(p, Vec3::Z));
            }
        }
        let grid = gaussian_grid(&g, 0.05, (0.03, 1.2), 0.5, &SplatGridParams::default()).unwrap();
        assert_eq!(
            grid.counts().0,
            0,
            "a 0.3 m patch of floor is no navigable space"
        );
    }
}
