//! Gravity and floor: which way is up in a capture, and where its floor lies.
//!
//! Captures come Y-up (most reconstruction tools), Z-up, Y-down (COLMAP's camera convention) or
//! tilted by however the first camera was held. Indoors, gravity shows in the surfaces: floor
//! and ceiling are the largest planes facing one way, walls face the two ways across it. So:
//!
//! 1. **Surface normals.** Every opaque Gaussian flat enough to be a disc (smallest scale at
//!    most [`FloorSettings::flatness`] of the middle one) gives a normal, its smallest axis.
//! 2. **Dominant directions.** The normals are binned on a cube map (unsigned: a normal and its
//!    opposite share a bin); the heaviest bins seed a mean shift within a 15° cone, and the
//!    converged directions are scored by the weight within 10°. The best is one axis; the best
//!    nearly orthogonal to it, the second; their cross product the third.
//! 3. **Which axis is up.** Along each axis, the planes of the Gaussians facing it are the
//!    peaks of a 1.5 cm histogram of their heights; the axis whose two outermost planes (the
//!    lowest and the highest with at least a tenth of the largest peak's weight) hold the most
//!    weight is vertical: floor and ceiling (or, without one, the furniture tops) span much of
//!    the capture, the outermost walls only its sides. [`Up`] names the axis instead, when the
//!    heuristic is not wanted.
//! 4. **Which end is the floor** ([`FloorSide`]). Nothing was seen below a floor: where only
//!    one of the two outermost planes bounds the opaque Gaussians (the other has walls and
//!    furniture rising past it, as the highest table top of a capture whose ceiling was cut
//!    away has), that one is the floor. Where both bound them (floor and ceiling), furniture
//!    stands on the floor, so the opaque Gaussians between the two planes lie nearer the floor:
//!    the plane on the side of their median height is the floor. A given up axis is taken as
//!    given, and the same evidence only says whether it looks upside down.
//! 5. **Fit.** The floor plane is refined by principal components of its Gaussians' centres
//!    within [`FloorSettings::tolerance`], three times; its normal is gravity's up. A plane
//!    covering less than [`FloorSettings::min_area`] is no floor.
//! 6. **Ceiling.** The highest plane facing up at least [`MIN_CEILING_M`] above the floor that
//!    covers at least [`CEILING_AREA_SHARE`] of the floor's area; a capture without one (its
//!    ceiling cut away or never seen) has none (0), rather than a table top taken for it.
//! 7. **Heading.** Walls are turned onto the x and y axes (the mean of 4θ of the wall normals'
//!    headings) when they agree on a right-angled layout, so that grids follow them.

use glam::{DMat3, DVec3, Quat, Vec3};
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::fmt;
use std::str::FromStr;

/// Which way is up in the capture.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Up {
    /// Found from the surfaces (see the module docs).
    #[default]
    #[serde(rename = "auto")]
    Auto,
    /// +X.
    #[serde(rename = "x")]
    X,
    /// −X.
    #[serde(rename = "-x")]
    NegX,
    /// +Y (most reconstruction tools).
    #[serde(rename = "y")]
    Y,
    /// −Y (COLMAP's camera axes).
    #[serde(rename = "-y")]
    NegY,
    /// +Z.
    #[serde(rename = "z")]
    Z,
    /// −Z.
    #[serde(rename = "-z")]
    NegZ,
}

impl Up {
    /// Every value, in a fixed order.
    pub const ALL: [Up; 7] = [Up::Auto, Up::X, Up::NegX, Up::Y, Up::NegY, Up::Z, Up::NegZ];

    /// `auto`, `x`, `-x`, `y`, `-y`, `z` or `-z`.
    pub fn as_str(self) -> &'static str {
        match self {
            Up::Auto => "auto",
            Up::X => "x",
            Up::NegX => "-x",
            Up::Y => "y",
            Up::NegY => "-y",
            Up::Z => "z",
            Up::NegZ => "-z",
        }
    }

    /// The axis, or `None` for [`Up::Auto`].
    pub fn axis(self) -> Option<Vec3> {
        match self {
            Up::Auto => None,
            Up::X => Some(Vec3::X),
            Up::NegX => Some(Vec3::NEG_X),
            Up::Y => Some(Vec3::Y),
            Up::NegY => Some(Vec3::NEG_Y),
            Up::Z => Some(Vec3::Z),
            Up::NegZ => Some(Vec3::NEG_Z),
        }
    }
}

impl fmt::Display for Up {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Up {
    type Err = Error;

    /// Parses `auto`, `x`, `-x`, `+x`, `y`, … (any case).
    fn from_str(s: &str) -> Result<Up> {
        let t = s.trim().to_ascii_lowercase();
        let t = t.strip_prefix('+').unwrap_or(&t);
        Up::ALL
            .into_iter()
            .find(|u| u.as_str() == t)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "unknown up axis '{s}' (expected auto, x, -x, y, -y, z or -z)"
                ))
            })
    }
}

/// How the floor is found (lengths in metres, after the capture's scale).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloorSettings {
    /// Which way is up ([`Up::Auto`]: found from the surfaces).
    pub up: Up,
    /// Gaussians more transparent than this are no evidence of a surface (default 0.5).
    pub min_opacity: f32,
    /// A Gaussian is a surface patch when its smallest scale is at most this fraction of its
    /// middle one (default 0.5).
    pub flatness: f32,
    /// Half-thickness of the floor band fitted, metres (default 0.03).
    pub tolerance: f32,
    /// Least floor area, m² (default 1).
    pub min_area: f32,
}

impl Default for FloorSettings {
    fn default() -> Self {
        FloorSettings {
            up: Up::Auto,
            min_opacity: 0.5,
            flatness: 0.5,
            tolerance: 0.03,
            min_area: 1.0,
        }
    }
}

impl FloorSettings {
    /// Checks the ranges.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the setting out of range.
    pub fn validate(&self) -> Result<()> {
        let check = |ok: bool, what: &str, v: f32| {
            if ok {
                Ok(())
            } else {
                Err(Error::invalid(format!("{what}, got {v}")))
            }
        };
        check(
            (0.0..1.0).contains(&self.min_opacity),
            "floor min_opacity must be within 0-1",
            self.min_opacity,
        )?;
        check(
            self.flatness > 0.0 && self.flatness <= 1.0,
            "floor flatness must be within 0-1",
            self.flatness,
        )?;
        check(
            self.tolerance.is_finite() && self.tolerance > 0.0,
            "floor tolerance must be > 0",
            self.tolerance,
        )?;
        check(
            self.min_area.is_finite() && self.min_area >= 0.0,
            "floor min_area must be >= 0",
            self.min_area,
        )
    }
}

/// The least floor-to-ceiling height of a ceiling, metres: a large plane facing up lower than
/// this is a furniture top (a bed, a table), since no room people walk in is lower.
pub const MIN_CEILING_M: f32 = 1.8;

/// The highest floor-to-ceiling height that is plausible indoors, metres (halls and atria
/// reach it rarely); the import warns above it, as a sign of a wrong scale.
pub const MAX_CEILING_M: f32 = 8.0;

/// The least share of the floor's area a ceiling covers: a ceiling spans the room as the floor
/// does (and is less hidden by furniture), while the tops of tall furniture cover a few
/// percent of it.
pub const CEILING_AREA_SHARE: f32 = 0.25;

/// How the floor's end of the up axis was told (see the module docs, step 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FloorSide {
    /// Only one of the two outermost planes bounds the opaque Gaussians: it is the floor.
    Extreme,
    /// Both bound them (floor and ceiling): the floor is the end their median lies nearer.
    Median,
}

impl FloorSide {
    /// `extreme` or `median`.
    pub fn as_str(self) -> &'static str {
        match self {
            FloorSide::Extreme => "extreme",
            FloorSide::Median => "median",
        }
    }
}

/// What was found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FloorFit {
    /// Gravity's up in the capture's axes (unit).
    pub up: Vec3,
    /// The floor's height along `up`, metres, in the scaled capture (`up · (scale · p)` on the
    /// floor).
    pub offset: f32,
    /// The floor's Gaussians.
    pub inliers: usize,
    /// The floor's area (its Gaussians' 10 cm cells), m².
    pub area: f32,
    /// Root mean square distance of the floor's Gaussians to the plane, metres.
    pub rms: f32,
    /// Angle between `up` and the nearest axis of the capture, degrees (the capture's tilt).
    pub tilt_deg: f32,
    /// The share of the opaque Gaussians between the two outermost planes along up that lie
    /// in the half nearer the floor (more than 0.5 is what picks the floor's end when both
    /// planes bound the Gaussians; measured for a given up axis too).
    pub lower_share: f32,
    /// How the floor's end of the up axis was told (for a given up axis: how the evidence that
    /// [`FloorFit::side_doubtful`] weighs was read).
    pub side: FloorSide,
    /// A given up axis that the Gaussians clearly contradict: they put the floor at the other
    /// end, so the capture is likely imported upside down (always false for [`Up::Auto`]).
    pub side_doubtful: bool,
    /// Floor-to-ceiling height, metres: the highest plane facing up at least
    /// [`MIN_CEILING_M`] above the floor and covering at least [`CEILING_AREA_SHARE`] of the
    /// floor's area; 0 when there is none.
    pub ceiling: f32,
    /// Height above the floor of the highest plane facing up (the ceiling where there is one,
    /// else a furniture top or a ceiling too low to be one), metres; 0 when there is none.
    pub top_plane: f32,
    /// The area of that plane (its Gaussians' 10 cm cells), m².
    pub top_plane_area: f32,
    /// The turn about the up axis that puts the walls on x and y, radians (0 when the walls do
    /// not agree on a right-angled layout).
    pub yaw: f32,
    /// How well the walls agree on a right-angled layout (0–1; the yaw is applied from 0.3).
    pub wall_agreement: f32,
    /// The axes considered (unit, capture axes) with the weight of their two outermost
    /// planes.
    pub axes: Vec<(Vec3, f32)>,
    /// The flat, opaque Gaussians sampled as surface evidence.
    pub samples: usize,
}

impl FloorFit {
    /// The rotation that turns the capture's axes into W's: `up` onto +Z, then the walls onto
    /// x and y.
    pub fn rotation(&self) -> Quat {
        // The arc in f64: glam's f32 arc snaps a turn under about 1e-4 rad to none, which the
        // floor's height, measured along the true normal, then misses by that angle times the
        // capture's distance from its origin (a metre at 10 km).
        let level = glam::DQuat::from_rotation_arc(self.up.as_dvec3().normalize(), DVec3::Z);
        let yaw = glam::DQuat::from_rotation_z(f64::from(self.yaw));
        (yaw * level).normalize().as_quat()
    }
}

/// The most surface samples used (every k-th beyond it): the fit needs thousands, not millions.
const MAX_SAMPLES: usize = 300_000;

/// A flat Gaussian: centre (metres), unit normal, weight (opacity).
#[derive(Clone, Copy)]
struct Sample {
    p: Vec3,
    n: Vec3,
    w: f32,
}

/// Finds up and the floor of the Gaussians `keep` of `g`, a capture of `scale` metres per unit.
///
/// # Errors
///
/// Bad settings, or no floor: too few flat opaque Gaussians, no plane facing the up axis, or
/// a plane smaller than [`FloorSettings::min_area`]; the message says which.
pub fn find_floor(
    g: &Gaussians,
    keep: &[u32],
    scale: f32,
    settings: &FloorSettings,
) -> Result<FloorFit> {
    settings.validate()?;
    let (samples, centres) = collect(g, keep, scale, settings);
    if samples.len() < 50 {
        return Err(Error::invalid(format!(
            "no floor found: only {} of the {} Gaussians are opaque (>= {}) and flat enough to be a surface, too few to tell a floor",
            samples.len(),
            keep.len(),
            settings.min_opacity
        )));
    }
    let directions = dominant_directions(&samples);
    let (axis, axes) = match settings.up.axis() {
        Some(h) => {
            let a = mean_shift(&samples, h);
            (
                a,
                vec![(a, outer_planes_weight(&samples, a, settings.tolerance))],
            )
        }
        None => {
            let mut axes = vec![directions[0].0];
            if let Some(second) = directions
                .iter()
                .map(|d| d.0)
                .find(|d| d.dot(axes[0]).abs() < 15f32.to_radians().sin())
            {
                let a2 = (second - axes[0] * second.dot(axes[0])).normalize();
                axes.push(a2);
                axes.push(axes[0].cross(a2).normalize());
            }
            let scored: Vec<(Vec3, f32)> = axes
                .iter()
                .map(|&a| (a, outer_planes_weight(&samples, a, settings.tolerance)))
                .collect();
            let best = scored
                .iter()
                .copied()
                .reduce(|x, y| if y.1 > x.1 { y } else { x })
                .map_or(axes[0], |b| b.0);
            (best, scored)
        }
    };
    let Some((lo, hi)) = outer_planes(&samples, axis, settings.tolerance) else {
        return Err(Error::invalid(format!(
            "no floor found: no plane of flat Gaussians faces the up axis ({:.3}, {:.3}, {:.3})",
            axis.x, axis.y, axis.z
        )));
    };
    // Which end is the floor. The evidence is read the same way for a given axis, which it
    // may only doubt, never overrule.
    let side = floor_side(&centres, axis, lo, hi);
    let (up, lower_share, side_doubtful) = match settings.up.axis() {
        Some(h) => {
            let up = if axis.dot(h) >= 0.0 { axis } else { -axis };
            let share = if up == axis {
                side.lower_share
            } else {
                1.0 - side.lower_share
            };
            (up, share, side.clear && side.lo_is_floor != (up == axis))
        }
        None if side.lo_is_floor => (axis, side.lower_share, false),
        None => (-axis, 1.0 - side.lower_share, false),
    };
    let start = if up == axis { lo } else { -hi };
    let (up, offset, inliers, rms) = fit_plane(&samples, up, start, settings.tolerance)?;
    let area = floor_area(&samples, up, offset, settings.tolerance);
    if area < settings.min_area || inliers < 20 {
        return Err(Error::invalid(format!(
            "no floor found: the lowest plane facing up covers {area:.2} m² ({inliers} Gaussians), less than the {} m² a floor needs",
            settings.min_area
        )));
    }
    let (top_plane, top_plane_area) = outer_planes(&samples, up, settings.tolerance)
        .filter(|&(_, h)| h > offset + settings.tolerance)
        .map_or((0.0, 0.0), |(_, h)| {
            (h - offset, floor_area(&samples, up, h, settings.tolerance))
        });
    let ceiling = find_ceiling(&samples, up, offset, area, settings.tolerance);
    let tilt_deg = [Vec3::X, Vec3::Y, Vec3::Z]
        .iter()
        .map(|a| up.dot(*a).abs())
        .fold(0.0f32, f32::max)
        .min(1.0)
        .acos()
        .to_degrees();
    let level = Quat::from_rotation_arc(up, Vec3::Z);
    let (yaw, wall_agreement) = manhattan_yaw(&samples, up, level);
    Ok(FloorFit {
        up,
        offset,
        inliers,
        area,
        rms,
        tilt_deg,
        lower_share,
        side: side.how,
        side_doubtful,
        ceiling,
        top_plane,
        top_plane_area,
        yaw: if wall_agreement >= 0.3 { yaw } else { 0.0 },
        wall_agreement,
        axes,
        samples: samples.len(),
    })
}

/// The flat opaque Gaussians (surface samples) and the centres of all opaque ones, in metres,
/// every k-th of each so that neither exceeds [`MAX_SAMPLES`].
fn collect(
    g: &Gaussians,
    keep: &[u32],
    scale: f32,
    settings: &FloorSettings,
) -> (Vec<Sample>, Vec<Vec3>) {
    let min_logit = {
        let a = settings.min_opacity.clamp(1e-6, 1.0 - 1e-6);
        (a / (1.0 - a)).ln()
    };
    let opaque: Vec<u32> = keep
        .iter()
        .copied()
        .filter(|&i| g.opacity_logit(i as usize) >= min_logit)
        .collect();
    let stride = opaque.len().div_ceil(MAX_SAMPLES).max(1);
    let mut samples = Vec::new();
    let mut centres = Vec::new();
    for &i in opaque.iter().step_by(stride) {
        let i = i as usize;
        let p = Vec3::from_array(g.positions[i]) * scale;
        if !p.is_finite() {
            continue;
        }
        centres.push(p);
        let s = g.log_scale(i);
        let mut axes = [(s.x, Vec3::X), (s.y, Vec3::Y), (s.z, Vec3::Z)];
        axes.sort_by(|a, b| a.0.total_cmp(&b.0));
        if (axes[0].0 - axes[1].0).exp() <= settings.flatness {
            let n = (g.rotation(i) * axes[0].1).normalize();
            if n.is_finite() {
                let w = 1.0 / (1.0 + (-g.opacity_logit(i)).exp());
                samples.push(Sample { p, n, w });
            }
        }
    }
    (samples, centres)
}

/// The dominant unsigned normal directions, best first, with their weight within 10°.
fn dominant_directions(samples: &[Sample]) -> Vec<(Vec3, f32)> {
    const N: usize = 16;
    // Cube-map bins of the canonical normal (largest component positive).
    let mut bins: Vec<(f32, Vec3)> = vec![(0.0, Vec3::ZERO); 3 * N * N];
    for s in samples {
        let n = s.n;
        let a = n.abs();
        let face = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let n = if n[face] < 0.0 { -n } else { n };
        let (u, v) = (n[(face + 1) % 3] / n[face], n[(face + 2) % 3] / n[face]);
        let bu = (((u + 1.0) * 0.5 * N as f32) as usize).min(N - 1);
        let bv = (((v + 1.0) * 0.5 * N as f32) as usize).min(N - 1);
        let b = &mut bins[(face * N + bu) * N + bv];
        b.0 += s.w;
        b.1 += n * s.w;
    }
    let mut order: Vec<usize> = (0..bins.len()).filter(|&b| bins[b].0 > 0.0).collect();
    order.sort_by(|&a, &b| bins[b].0.total_cmp(&bins[a].0).then(a.cmp(&b)));
    let cos10 = 10f32.to_radians().cos();
    let mut found: Vec<(Vec3, f32)> = Vec::new();
    for &b in order.iter().take(12) {
        let d = mean_shift(samples, bins[b].1.normalize());
        if found
            .iter()
            .any(|f| f.0.dot(d).abs() > 5f32.to_radians().cos())
        {
            continue;
        }
        let w: f32 = samples
            .iter()
            .filter(|s| s.n.dot(d).abs() >= cos10)
            .map(|s| s.w)
            .sum();
        found.push((d, w));
    }
    found.sort_by(|a, b| b.1.total_cmp(&a.1));
    found
}

/// Mean shift of an unsigned direction: the weighted mean of the normals within 15° (each
/// turned to the seed's side), five times.
fn mean_shift(samples: &[Sample], seed: Vec3) -> Vec3 {
    let cos15 = 15f32.to_radians().cos();
    let mut d = seed.normalize();
    for _ in 0..5 {
        let mut acc = DVec3::ZERO;
        for s in samples {
            let c = s.n.dot(d);
            if c.abs() >= cos15 {
                acc += (s.n * c.signum() * s.w).as_dvec3();
            }
        }
        if acc.length() == 0.0 {
            break;
        }
        d = acc.normalize().as_vec3();
    }
    d
}

/// The heights along `axis` of the lowest and highest planes facing it (see the module docs).
fn outer_planes(samples: &[Sample], axis: Vec3, tol: f32) -> Option<(f32, f32)> {
    let cos10 = 10f32.to_radians().cos();
    let facing: Vec<(f32, f32)> = samples
        .iter()
        .filter(|s| s.n.dot(axis).abs() >= cos10)
        .map(|s| (s.p.dot(axis), s.w))
        .collect();
    if facing.len() < 20 {
        return None;
    }
    let lo = facing.iter().map(|f| f.0).fold(f32::INFINITY, f32::min);
    let hi = facing.iter().map(|f| f.0).fold(f32::NEG_INFINITY, f32::max);
    let bin = (tol * 0.5).max((hi - lo) / 200_000.0);
    let n = ((hi - lo) / bin) as usize + 1;
    let mut hist = vec![0.0f32; n];
    for &(t, w) in &facing {
        hist[(((t - lo) / bin) as usize).min(n - 1)] += w;
    }
    let smooth: Vec<f32> = (0..n)
        .map(|k| hist[k.saturating_sub(1)..(k + 2).min(n)].iter().sum())
        .collect();
    let top = smooth.iter().copied().fold(0.0f32, f32::max);
    let significant = |k: &usize| smooth[*k] >= top * 0.1;
    let climb = |mut k: usize, step: isize| {
        loop {
            let next = k as isize + step;
            if next < 0 || next as usize >= n || smooth[next as usize] <= smooth[k] {
                return k;
            }
            k = next as usize;
        }
    };
    let first = (0..n).find(significant)?;
    let last = (0..n).rev().find(significant)?;
    let refine = |k: usize| {
        let c = lo + (k as f32 + 0.5) * bin;
        let (mut sw, mut st) = (0.0f64, 0.0f64);
        for &(t, w) in &facing {
            if (t - c).abs() <= tol {
                sw += f64::from(w);
                st += f64::from(w) * f64::from(t);
            }
        }
        if sw > 0.0 { (st / sw) as f32 } else { c }
    };
    Some((refine(climb(first, 1)), refine(climb(last, -1))))
}

/// The weight of the Gaussians facing `axis` in its two outermost planes.
fn outer_planes_weight(samples: &[Sample], axis: Vec3, tol: f32) -> f32 {
    let Some((lo, hi)) = outer_planes(samples, axis, tol) else {
        return 0.0;
    };
    let cos10 = 10f32.to_radians().cos();
    samples
        .iter()
        .filter(|s| s.n.dot(axis).abs() >= cos10)
        .filter(|s| {
            let t = s.p.dot(axis);
            (t - lo).abs() <= tol || (t - hi).abs() <= tol
        })
        .map(|s| s.w)
        .sum()
}

/// The evidence for which end of an axis the floor is at ([`floor_side`]).
struct SideEvidence {
    /// The lower plane (`lo`, along the axis) is the floor.
    lo_is_floor: bool,
    /// How that was told.
    how: FloorSide,
    /// Whether the evidence is clear enough to doubt a given up axis with.
    clear: bool,
    /// [`lower_share`] along the axis.
    lower_share: f32,
}

/// The least share of the opaque Gaussians beyond an outermost plane for it to be open (walls
/// and furniture rising past it), and the most for it to bound them (noise, stray Gaussians).
const OPEN_SHARE: f32 = 0.1;
const BOUNDING_SHARE: f32 = 0.02;

/// Which end of `axis`, with its outermost planes facing it at `lo` and `hi`, is the floor.
///
/// A capture's floor bounds what was seen: nothing lies under it. Its ceiling bounds it too,
/// but a ceiling is often missing (cut away, or never looked at by a handheld capture), and
/// then the highest plane is a furniture top that the walls rise past. So where exactly one
/// plane bounds the opaque Gaussians (at most [`BOUNDING_SHARE`] of them more than 10 cm
/// beyond it) and the other is open (at least [`OPEN_SHARE`] beyond), the bounding one is the
/// floor. This needs no ceiling and only the centres already collected; the median test it
/// falls back on (furniture stands on the floor, so the Gaussians between the planes gather
/// at the floor's end) needs both planes to be floor and ceiling, as they are when both bound.
fn floor_side(centres: &[Vec3], axis: Vec3, lo: f32, hi: f32) -> SideEvidence {
    let (mut below, mut above) = (0usize, 0usize);
    for p in centres {
        let t = p.dot(axis);
        below += usize::from(t < lo - 0.1);
        above += usize::from(t > hi + 0.1);
    }
    let n = centres.len().max(1) as f32;
    let (below, above) = (below as f32 / n, above as f32 / n);
    let share = lower_share(centres, axis, lo, hi);
    if below <= BOUNDING_SHARE && above >= OPEN_SHARE {
        SideEvidence {
            lo_is_floor: true,
            how: FloorSide::Extreme,
            clear: true,
            lower_share: share,
        }
    } else if above <= BOUNDING_SHARE && below >= OPEN_SHARE {
        SideEvidence {
            lo_is_floor: false,
            how: FloorSide::Extreme,
            clear: true,
            lower_share: share,
        }
    } else {
        SideEvidence {
            lo_is_floor: share >= 0.5,
            how: FloorSide::Median,
            // An even split says little; the synthetic homes measure 0.6-0.65.
            clear: (share - 0.5).abs() >= 0.08,
            lower_share: share,
        }
    }
}

/// The ceiling's height above the floor at `offset` along `up`, whose area is `floor` m² (see
/// the module docs, step 6); 0 when there is none.
fn find_ceiling(samples: &[Sample], up: Vec3, offset: f32, floor: f32, tol: f32) -> f32 {
    // Only planes high enough to be a ceiling compete, so that the tops of furniture, which
    // hold more weight than a sparsely seen ceiling, do not set what counts as a peak there.
    let high: Vec<Sample> = samples
        .iter()
        .filter(|s| s.p.dot(up) - offset >= MIN_CEILING_M - tol)
        .copied()
        .collect();
    let Some((lo, hi)) = outer_planes(&high, up, tol) else {
        return 0.0;
    };
    [hi, lo]
        .into_iter()
        .find(|&h| {
            h - offset >= MIN_CEILING_M
                && floor_area(samples, up, h, tol) >= CEILING_AREA_SHARE * floor
        })
        .map_or(0.0, |h| h - offset)
}

/// The share of `centres` strictly between the planes at `lo` and `hi` along `axis` (10 cm
/// clear of each) that lie in the lower half.
fn lower_share(centres: &[Vec3], axis: Vec3, lo: f32, hi: f32) -> f32 {
    let mid = (lo + hi) * 0.5;
    let (mut below, mut all) = (0usize, 0usize);
    for p in centres {
        let t = p.dot(axis);
        if t > lo + 0.1 && t < hi - 0.1 {
            all += 1;
            below += usize::from(t < mid);
        }
    }
    if all == 0 {
        0.5
    } else {
        below as f32 / all as f32
    }
}

/// Refines the plane near height `start` along `up` by principal components of the centres of
/// its Gaussians, three times; returns (normal, height, inliers, rms).
fn fit_plane(
    samples: &[Sample],
    up: Vec3,
    start: f32,
    tol: f32,
) -> Result<(Vec3, f32, usize, f32)> {
    let cos15 = 15f32.to_radians().cos();
    let (mut n, mut d) = (up, start);
    let mut result = None;
    for band in [tol, tol, tol * 0.67] {
        let inliers: Vec<&Sample> = samples
            .iter()
            .filter(|s| s.n.dot(n).abs() >= cos15 && (s.p.dot(n) - d).abs() <= band)
            .collect();
        let wsum: f64 = inliers.iter().map(|s| f64::from(s.w)).sum();
        if inliers.len() < 3 || wsum <= 0.0 {
            break;
        }
        let c = inliers
            .iter()
            .fold(DVec3::ZERO, |a, s| a + s.p.as_dvec3() * f64::from(s.w))
            / wsum;
        let mut cov = DMat3::ZERO;
        for s in &inliers {
            let v = s.p.as_dvec3() - c;
            let w = f64::from(s.w);
            cov += DMat3::from_cols(v * v.x, v * v.y, v * v.z) * w;
        }
        let (values, vectors) = symmetric_eigen(cov / wsum);
        // The smallest spread is the normal; the other two must span a floor, not a strip.
        if values[1].sqrt() < 0.2 {
            return Err(Error::invalid(format!(
                "no floor found: the plane facing up is a strip {:.2} m wide, not a floor",
                2.0 * values[1].sqrt()
            )));
        }
        let mut normal = vectors[0].as_vec3().normalize();
        if normal.dot(up) < 0.0 {
            normal = -normal;
        }
        n = normal;
        d = c.as_vec3().dot(n);
        let rms = (inliers
            .iter()
            .map(|s| f64::from(s.w) * f64::from(s.p.dot(n) - d).powi(2))
            .sum::<f64>()
            / wsum)
            .sqrt() as f32;
        result = Some((n, d, inliers.len(), rms));
    }
    result.ok_or_else(|| {
        Error::invalid("no floor found: no flat Gaussians lie on the plane facing up")
    })
}

/// The area of the 10 cm cells holding the floor's Gaussians, m².
fn floor_area(samples: &[Sample], up: Vec3, offset: f32, tol: f32) -> f32 {
    let cos15 = 15f32.to_radians().cos();
    let level = Quat::from_rotation_arc(up, Vec3::Z);
    let cells: HashSet<(i64, i64)> = samples
        .iter()
        .filter(|s| s.n.dot(up).abs() >= cos15 && (s.p.dot(up) - offset).abs() <= tol)
        .map(|s| {
            let q = level * s.p / 0.1;
            (q.x.floor() as i64, q.y.floor() as i64)
        })
        .collect();
    cells.len() as f32 * 0.01
}

/// The turn about +Z, after `level`, that puts the wall normals on x and y, and how well the
/// walls agree (the resultant length of 4θ, 0–1).
fn manhattan_yaw(samples: &[Sample], up: Vec3, level: Quat) -> (f32, f32) {
    let sin15 = 15f32.to_radians().sin();
    let (mut c, mut s, mut w) = (0.0f64, 0.0f64, 0.0f64);
    for smp in samples.iter().filter(|x| x.n.dot(up).abs() <= sin15) {
        let n = level * smp.n;
        let theta = f64::from(n.y).atan2(f64::from(n.x));
        c += f64::from(smp.w) * (4.0 * theta).cos();
        s += f64::from(smp.w) * (4.0 * theta).sin();
        w += f64::from(smp.w);
    }
    if w == 0.0 {
        return (0.0, 0.0);
    }
    let agreement = (c * c + s * s).sqrt() / w;
    let theta0 = s.atan2(c) / 4.0;
    (-theta0 as f32, agreement as f32)
}

/// Eigenvalues (ascending) and unit eigenvectors of a symmetric 3 × 3 matrix (Jacobi).
// Matrix code reads best with the indices of its formulas.
#[allow(clippy::needless_range_loop)]
fn symmetric_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m.to_cols_array_2d();
    let mut v = DMat3::IDENTITY.to_cols_array_2d();
    for _ in 0..50 {
        let (mut p, mut q, mut big) = (0, 1, 0.0f64);
        for i in 0..3 {
            for j in i + 1..3 {
                if a[i][j].abs() > big {
                    (p, q, big) = (i, j, a[i][j].abs());
                }
            }
        }
        if big < 1e-18 {
            break;
        }
        let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
        // Numerical Recipes' rotation: t = tan φ of the smaller angle zeroing a[p][q].
        let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
        let c = 1.0 / (t * t + 1.0).sqrt();
        let s = t * c;
        for k in 0..3 {
            let (akp, akq) = (a[k][p], a[k][q]);
            a[k][p] = c * akp - s * akq;
            a[k][q] = s * akp + c * akq;
        }
        for k in 0..3 {
            let (apk, aqk) = (a[p][k], a[q][k]);
            a[p][k] = c * apk - s * aqk;
            a[q][k] = s * apk + c * aqk;
        }
        for row in &mut v {
            let (vp, vq) = (row[p], row[q]);
            row[p] = c * vp - s * vq;
            row[q] = s * vp + c * vq;
        }
    }
    // `v` holds the eigenvectors as its columns in the 2-D array's second index.
    let mut pairs: Vec<(f64, DVec3)> = (0..3)
        .map(|k| (a[k][k], DVec3::new(v[0][k], v[1][k], v[2][k])))
        .collect();
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    (
        [pairs[0].0, pairs[1].0, pairs[2].0],
        [pairs[0].1, pairs[1].1, pairs[2].1],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_rotated_diagonal() {
        let r = DMat3::from_quat(glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1));
        let m = r * DMat3::from_diagonal(DVec3::new(4.0, 0.01, 1.0)) * r.transpose();
        let (values, vectors) = symmetric_eigen(m);
        assert!((values[0] - 0.01).abs() < 1e-9 && (values[2] - 4.0).abs() < 1e-9);
        assert!(vectors[0].dot(r.y_axis).abs() > 1.0 - 1e-9);
        assert!(vectors[2].dot(r.x_axis).abs() > 1.0 - 1e-9);
    }

    #[test]
    fn up_axis_names_parse() {
        assert_eq!("Y".parse::<Up>().unwrap(), Up::Y);
        assert_eq!("+z".parse::<Up>().unwrap(), Up::Z);
        assert_eq!("-y".parse::<Up>().unwrap(), Up::NegY);
        assert!("w".parse::<Up>().is_err());
        for u in Up::ALL {
            assert_eq!(u.as_str().parse::<Up>().unwrap(), u);
        }
    }
}
