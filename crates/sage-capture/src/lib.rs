//! `sage-capture`: one job — turn a user's own 3DGS capture into a scene in the world frame W
//! (right-handed, Z up, metres, floor at z = 0; SPEC §3).
//!
//! A capture comes in its reconstruction's frame: Y-up, Z-up or tilted, in arbitrary units,
//! with floaters. [`align`] takes its Gaussians and:
//!
//! 1. resolves the metric scale ([`Scale`]: given, or two points and their distance in the
//!    capture's own coordinates, or none: units taken as metres);
//! 2. removes floaters, the nearly transparent, isolated Gaussians training leaves in empty
//!    space ([`floaters`]), counting them;
//! 3. finds gravity and the floor from the surfaces ([`floor`]);
//! 4. applies one similarity ([`transform`]): scale, the rotation that puts up on +Z (and the
//!    walls on x and y), and the translation that puts the floor at z = 0. Each Gaussian's
//!    orientation turns, its scales grow, and its spherical harmonics of degrees 1–3 turn
//!    ([`sh`]), so that it looks the same from the same (turned) viewpoint. A capture whose
//!    Gaussians would reach beyond ±[`sage_core::MAX_COORDINATE`] m (one kept in a
//!    georeferenced or SLAM frame) is also moved in x and y, by whole metres, so that its
//!    median stands at the origin ([`Aligned::recentred`]); one that spans more than that is
//!    refused. Captures within the bound keep their x and y, so their imports do not change.
//!
//! Writing the scene folder and its map is the pipeline's (`sage_pipeline::capture`).

pub mod floaters;
pub mod floor;
pub mod sh;
pub mod transform;

pub use floaters::FloaterSettings;
pub use floor::{
    CEILING_AREA_SHARE, FloorFit, FloorSettings, FloorSide, MAX_CEILING_M, MIN_CEILING_M, Up,
};
pub use transform::Similarity;

use glam::Vec3;
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use serde::Serialize;

/// How the capture's units become metres.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Scale {
    /// No scale given: the capture's units are taken as metres.
    #[default]
    None,
    /// Metres per capture unit.
    Given {
        /// The factor.
        value: f32,
    },
    /// Two points in the capture's coordinates and their true distance in metres.
    Points {
        /// First point.
        a: Vec3,
        /// Second point.
        b: Vec3,
        /// Their distance, metres.
        distance: f32,
    },
}

impl Scale {
    /// Metres per capture unit.
    ///
    /// # Errors
    ///
    /// A factor or distance that is not finite and positive, or two points that coincide (no
    /// distance to scale by), named.
    pub fn factor(&self) -> Result<f32> {
        match *self {
            Scale::None => Ok(1.0),
            Scale::Given { value } => {
                if value.is_finite() && value > 0.0 {
                    Ok(value)
                } else {
                    Err(Error::invalid(format!(
                        "`scale` must be a finite number > 0, got {value}"
                    )))
                }
            }
            Scale::Points { a, b, distance } => {
                if !(distance.is_finite() && distance > 0.0) {
                    return Err(Error::invalid(format!(
                        "`scale_distance` must be a finite number > 0, got {distance}"
                    )));
                }
                if !(a.is_finite() && b.is_finite()) {
                    return Err(Error::invalid("`scale_points` must be finite numbers"));
                }
                let d = a.distance(b);
                let least = 1e-6 * a.abs().max(b.abs()).max_element().max(1.0);
                if d.is_nan() || d <= least {
                    return Err(Error::invalid(format!(
                        "`scale_points` are the same point ({}, {}, {}): two distinct points are needed to scale by their distance",
                        a.x, a.y, a.z
                    )));
                }
                let f = distance / d;
                if f.is_finite() && f > 0.0 {
                    Ok(f)
                } else {
                    Err(Error::invalid(format!(
                        "`scale_points` give a scale of {f}, which is not usable"
                    )))
                }
            }
        }
    }
}

/// Everything [`align`] needs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CaptureSettings {
    /// The metric scale.
    pub scale: Scale,
    /// How the floor is found.
    pub floor: FloorSettings,
    /// What counts as a floater.
    pub floaters: FloaterSettings,
}

/// A capture in W.
#[derive(Debug, Clone, PartialEq)]
pub struct Aligned {
    /// The Gaussians kept, in W, in their input order.
    pub gaussians: Gaussians,
    /// The capture's indices of the Gaussians kept (`gaussians[j]` is `kept[j]`).
    pub kept: Vec<u32>,
    /// The map from capture coordinates to W.
    pub transform: Similarity,
    /// The floor found (in the scaled capture's axes).
    pub floor: FloorFit,
    /// Gaussians in the capture.
    pub input: usize,
    /// Floaters removed.
    pub floaters: usize,
    /// The shift in x and y, metres, that brought a capture reaching beyond
    /// ±[`sage_core::MAX_COORDINATE`] m back to the origin (part of `transform`'s translation);
    /// `None` for a capture within the bound, which keeps its x and y.
    pub recentred: Option<[f32; 2]>,
}

/// Puts the capture `g` in W (see the crate docs).
///
/// # Errors
///
/// A capture with no Gaussians or with values that are not finite, bad settings (scale,
/// scale points), or no floor found; each says what was wrong.
pub fn align(g: &Gaussians, settings: &CaptureSettings) -> Result<Aligned> {
    if g.is_empty() {
        return Err(Error::invalid("the capture holds no Gaussians"));
    }
    g.validate()?;
    let scale = settings.scale.factor()?;
    let floaters = floaters::find(g, scale, &settings.floaters)?;
    let keep: Vec<u32> = (0..g.len() as u32)
        .filter(|&i| !floaters[i as usize])
        .collect();
    let removed = g.len() - keep.len();
    let fit = floor::find_floor(g, &keep, scale, &settings.floor)?;
    let mut transform = Similarity {
        scale,
        rotation: fit.rotation(),
        translation: Vec3::new(0.0, 0.0, -fit.offset),
    };
    let mut gaussians = transform::transform(g, &keep, &transform)?;
    let recentred = recentre(&mut gaussians, &mut transform)?;
    Ok(Aligned {
        gaussians,
        kept: keep,
        transform,
        floor: fit,
        input: g.len(),
        floaters: removed,
        recentred,
    })
}

/// Moves Gaussians `g` (in W, by `transform`) in x and y so that their median stands at the
/// origin, when any reaches beyond ±[`sage_core::MAX_COORDINATE`] m: every reader of the
/// scene's positions (episodes, maps) refuses coordinates beyond it. The shift is rounded to
/// whole metres, so that the translation in `capture.json` reads as the offset it undoes, and
/// added to `transform`. The median, not the bounds' centre, so a few stray Gaussians far
/// out cannot move the room off the origin.
///
/// # Errors
///
/// Gaussians that span more than the bound allows, even moved (or reach beyond it along z,
/// which stays measured from the floor), naming the capture's extent and the bound.
fn recentre(g: &mut Gaussians, transform: &mut Similarity) -> Result<Option<[f32; 2]>> {
    let limit = sage_core::MAX_COORDINATE;
    let within = |g: &Gaussians| {
        g.positions
            .iter()
            .all(|p| p.iter().all(|v| v.abs() <= limit))
    };
    if within(g) {
        return Ok(None);
    }
    let median = |axis: usize| {
        let mut v: Vec<f32> = g.positions.iter().map(|p| p[axis]).collect();
        let mid = v.len() / 2;
        let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
        f64::from(*m).round()
    };
    let shift = [-median(0), -median(1)];
    for p in &mut g.positions {
        // In f64: the sum of two large, nearly opposite numbers keeps what f32 held of each.
        p[0] = (f64::from(p[0]) + shift[0]) as f32;
        p[1] = (f64::from(p[1]) + shift[1]) as f32;
    }
    let shift = shift.map(|v| v as f32);
    transform.translation += Vec3::new(shift[0], shift[1], 0.0);
    if !within(g) {
        let b = g.bounds();
        let (lo, hi) = (
            b.min - Vec3::new(shift[0], shift[1], 0.0),
            b.max - Vec3::new(shift[0], shift[1], 0.0),
        );
        return Err(Error::invalid(format!(
            "the capture spans x {:.0}..{:.0}, y {:.0}..{:.0}, z {:.0}..{:.0} m above the floor (after scaling), more than a scene may (every coordinate within ±{limit} m, even centred on the origin); a capture that large is no room: check the scale (`scale`, or `scale_points` with `scale_distance`) and remove stray Gaussians far from it",
            lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
        )));
    }
    Ok(Some(shift))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_are_checked() {
        assert_eq!(Scale::None.factor().unwrap(), 1.0);
        assert_eq!(Scale::Given { value: 2.5 }.factor().unwrap(), 2.5);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(Scale::Given { value: bad }.factor().is_err(), "{bad}");
        }
        let p = |a: [f32; 3], b: [f32; 3], distance| Scale::Points {
            a: Vec3::from_array(a),
            b: Vec3::from_array(b),
            distance,
        };
        assert!((p([0.0; 3], [0.0, 2.0, 0.0], 5.0).factor().unwrap() - 2.5).abs() < 1e-6);
        let e = p([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], 2.0)
            .factor()
            .unwrap_err()
            .to_string();
        assert!(e.contains("same point"), "{e}");
        assert!(p([0.0; 3], [1.0, 0.0, 0.0], 0.0).factor().is_err());
        assert!(p([0.0; 3], [1.0, 0.0, 0.0], -2.0).factor().is_err());
    }

    #[test]
    fn an_empty_capture_is_refused() {
        let e = align(&Gaussians::new(0).unwrap(), &CaptureSettings::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no Gaussians"), "{e}");
    }
}
