//! The clearance-aware cost of moving through a cell (SPEC §7): clearance from the exact distance
//! transform, the robot radius plus a safety margin as a hard inflation, a narrow-passage
//! penalty and an area preference.
//!
//! A cell's clearance `c` is the distance from its centre to the nearest non-free cell's centre
//! minus half a cell (the distance to that cell's near edge). A cell is navigable when it is free
//! and `c ≥ robot_radius + safety_margin`: the grid knows where an obstacle is only to a cell,
//! and an agent following a path with discrete steps and turns strays a few centimetres from
//! its line, so a path at bare radius clearance is contact. Its cost multiplier is
//!
//! `(1 + narrow_weight · max(0, 1 − m / narrow_distance) + tight_weight · [m < shortcut_margin])
//!     · area_weight(room)`, where `m = c − robot_radius − safety_margin`,
//!
//! so a step costs its length times the mean multiplier of its two cells. The tight term keeps
//! planned paths at the wider shortcut margin from obstacles wherever the space allows it.
//! Cells inside that margin are still navigable (a goal beside furniture, a narrow door), only
//! dear. Geodesic distances ignore the multipliers.

use crate::edt;
use crate::grid::{NO_ROOM, NavGrid};
use sage_core::{Error, Result};
use sage_scene::Floorplan;
use sage_scene::occupancy::FREE;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of the cost function.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CostParams {
    /// Robot radius, metres (default 0.2).
    pub robot_radius: f32,
    /// Clearance beyond the radius that every navigable cell has, metres (default 0.05, one
    /// cell of the default grid): the grid's own precision and the few centimetres an agent
    /// with discrete steps strays from a path, so that a reference path can be driven without
    /// touching anything.
    #[serde(default = "default_safety_margin")]
    pub safety_margin: f32,
    /// Extra cost factor at the least navigable clearance; 0 turns the penalty off (default 2).
    pub narrow_weight: f32,
    /// Clearance beyond the least navigable over which the penalty fades to 0, metres (default
    /// 0.3).
    pub narrow_distance: f32,
    /// Cost factor per room type (lower case, as in `structure.json`); unlisted types get
    /// `default_area_weight`.
    pub area_weights: BTreeMap<String, f32>,
    /// Cost factor of rooms not listed and of cells outside every room (default 1).
    pub default_area_weight: f32,
    /// Clearance beyond the least navigable that shortcut segments keep, metres (default
    /// 0.1): a segment is taken only where every cell it crosses has that much more clearance,
    /// so an agent a few centimetres off the line (discrete steps and turns) does not touch;
    /// where the grid path itself is narrower, it is followed cell by cell.
    #[serde(default = "default_shortcut_margin")]
    pub shortcut_margin: f32,
    /// Extra cost factor of a navigable cell with less than `shortcut_margin` clearance to spare
    /// (default 10); 0 turns it off.
    #[serde(default = "default_tight_weight")]
    pub tight_weight: f32,
}

fn default_safety_margin() -> f32 {
    0.05
}

fn default_shortcut_margin() -> f32 {
    0.1
}

fn default_tight_weight() -> f32 {
    10.0
}

impl Default for CostParams {
    fn default() -> Self {
        CostParams {
            robot_radius: 0.2,
            safety_margin: default_safety_margin(),
            narrow_weight: 2.0,
            narrow_distance: 0.3,
            area_weights: BTreeMap::new(),
            default_area_weight: 1.0,
            shortcut_margin: default_shortcut_margin(),
            tight_weight: default_tight_weight(),
        }
    }
}

impl CostParams {
    /// The parameters with the penalties off and every area weight 1: cost = path length.
    pub fn length_only(robot_radius: f32) -> CostParams {
        CostParams {
            robot_radius,
            narrow_weight: 0.0,
            tight_weight: 0.0,
            ..CostParams::default()
        }
    }

    /// The least clearance of a navigable cell: radius plus safety margin, metres.
    pub fn navigable_clearance(&self) -> f32 {
        self.robot_radius + self.safety_margin
    }

    /// The least clearance of a roomy cell, one a shortcut may cross and an agent may stop on:
    /// the navigable clearance plus the shortcut margin, metres.
    pub fn roomy_clearance(&self) -> f32 {
        self.navigable_clearance() + self.shortcut_margin
    }

    /// Checks the ranges: radius ≥ 0, weights ≥ 0, area weights > 0, distance > 0, margins
    /// 0–10 m.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f32| Error::invalid(format!("cost: {what} out of range: {v}"));
        if !(self.robot_radius >= 0.0 && self.robot_radius < 10.0) {
            return Err(bad("`robot_radius` (0-10 m)", self.robot_radius));
        }
        if !(self.narrow_weight >= 0.0 && self.narrow_weight.is_finite()) {
            return Err(bad("`narrow_weight` (>= 0)", self.narrow_weight));
        }
        if !(self.tight_weight >= 0.0 && self.tight_weight.is_finite()) {
            return Err(bad("`tight_weight` (>= 0)", self.tight_weight));
        }
        if !(self.narrow_distance > 0.0 && self.narrow_distance.is_finite()) {
            return Err(bad("`narrow_distance` (> 0)", self.narrow_distance));
        }
        for (k, &w) in &self.area_weights {
            if !(w > 0.0 && w.is_finite()) {
                return Err(bad(&format!("`area_weights`[{k}] (> 0)"), w));
            }
        }
        if !(self.default_area_weight > 0.0 && self.default_area_weight.is_finite()) {
            return Err(bad("`default_area_weight` (> 0)", self.default_area_weight));
        }
        if !(self.shortcut_margin >= 0.0 && self.shortcut_margin < 10.0) {
            return Err(bad("`shortcut_margin` (0-10 m)", self.shortcut_margin));
        }
        if !(self.safety_margin >= 0.0 && self.safety_margin < 10.0) {
            return Err(bad("`safety_margin` (0-10 m)", self.safety_margin));
        }
        Ok(())
    }
}

/// Clearance (metres) of every cell: 0 on non-free cells, infinite when nothing blocks.
pub fn clearance(grid: &NavGrid) -> Vec<f32> {
    let blocked: Vec<bool> = grid.cells.iter().map(|&v| v != FREE).collect();
    edt::squared_distance(grid.width, grid.height, &blocked)
        .into_iter()
        .map(|d2| (d2.sqrt() * grid.cell - 0.5 * grid.cell).max(0.0))
        .collect()
}

/// The cells that are free, have at least `least` clearance and lie off the grid border (so
/// that searches never step outside).
pub fn navigable(grid: &NavGrid, clearance: &[f32], least: f32) -> Vec<bool> {
    let (w, h) = (grid.width, grid.height);
    (0..w * h)
        .map(|k| {
            let (i, j) = (k % w, k / w);
            let inner = i > 0 && j > 0 && i + 1 < w && j + 1 < h;
            inner && grid.cells[k] == FREE && clearance[k] >= least
        })
        .collect()
}

/// The cost multiplier of every cell (see the module docs); non-navigable cells get 1.
pub fn multipliers(
    grid: &NavGrid,
    clearance: &[f32],
    floorplan: &Floorplan,
    params: &CostParams,
) -> Vec<f32> {
    let room_weight: Vec<f32> = floorplan
        .rooms
        .iter()
        .map(|r| {
            *params
                .area_weights
                .get(&r.room_type.to_lowercase())
                .unwrap_or(&params.default_area_weight)
        })
        .collect();
    (0..grid.cells.len())
        .map(|k| {
            let margin = clearance[k] - params.navigable_clearance();
            let narrow = (1.0 - margin / params.narrow_distance).clamp(0.0, 1.0);
            let tight = if margin < params.shortcut_margin {
                params.tight_weight
            } else {
                0.0
            };
            let area = match grid.rooms[k] {
                NO_ROOM => params.default_area_weight,
                r => room_weight
                    .get(r as usize)
                    .copied()
                    .unwrap_or(params.default_area_weight),
            };
            (1.0 + params.narrow_weight * narrow + tight) * area
        })
        .collect()
}
