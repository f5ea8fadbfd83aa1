//! Floaters: the faint Gaussians that training leaves hanging in empty space (where too few
//! views constrained it). One is nearly transparent and isolated: few other Gaussians of any
//! opacity within a small radius. Both tests are needed: faint Gaussians on surfaces are part
//! of their look, and isolated opaque ones may be a lamp cord or a far window.

use glam::Vec3;
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// What counts as a floater (lengths in metres, after the capture's scale).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloaterSettings {
    /// Opacity below which a Gaussian may be a floater (default 0.15).
    pub max_opacity: f32,
    /// Radius of the neighbourhood searched, metres (default 0.1).
    pub radius: f32,
    /// A candidate with fewer other Gaussians than this within the radius is a floater
    /// (default 3); 0 removes nothing.
    pub min_neighbours: usize,
}

impl Default for FloaterSettings {
    fn default() -> Self {
        FloaterSettings {
            max_opacity: 0.15,
            radius: 0.1,
            min_neighbours: 3,
        }
    }
}

impl FloaterSettings {
    /// Checks the ranges.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the setting out of range.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_opacity.is_finite() && (0.0..=1.0).contains(&self.max_opacity)) {
            return Err(Error::invalid(format!(
                "`floater_opacity` must be within 0-1, got {}",
                self.max_opacity
            )));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(Error::invalid(format!(
                "`floater_radius` must be > 0, got {}",
                self.radius
            )));
        }
        Ok(())
    }
}

/// Which Gaussians of `g` are floaters, for a capture whose units are `scale` metres each (the
/// radius is measured in metres).
///
/// # Errors
///
/// Bad settings, or a scale that is not finite and positive.
pub fn find(g: &Gaussians, scale: f32, settings: &FloaterSettings) -> Result<Vec<bool>> {
    settings.validate()?;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(format!("scale must be > 0, got {scale}")));
    }
    let mut out = vec![false; g.len()];
    if settings.min_neighbours == 0 {
        return Ok(out);
    }
    let logit = |a: f32| (a / (1.0 - a)).ln();
    let max_logit = logit(settings.max_opacity.clamp(1e-6, 1.0 - 1e-6));
    let candidates: Vec<usize> = (0..g.len())
        .filter(|&i| g.opacity_logit(i) < max_logit)
        .collect();
    if candidates.is_empty() {
        return Ok(out);
    }
    // A hash grid with cells of the radius: the neighbours of a point lie in its 27 cells.
    let r = settings.radius / scale;
    let key = |p: Vec3| {
        let q = (p / r).floor();
        [q.x as i64, q.y as i64, q.z as i64]
    };
    let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (i, p) in g.positions.iter().enumerate() {
        let p = Vec3::from_array(*p);
        if p.is_finite() {
            cells.entry(key(p)).or_default().push(i as u32);
        }
    }
    let r2 = r * r;
    for i in candidates {
        let p = Vec3::from_array(g.positions[i]);
        if !p.is_finite() {
            continue;
        }
        let k = key(p);
        let mut found = 0usize;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    for &j in list {
                        if j as usize != i
                            && Vec3::from_array(g.positions[j as usize]).distance_squared(p) <= r2
                        {
                            found += 1;
                            if found >= settings.min_neighbours {
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        out[i] = found < settings.min_neighbours;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_scene::gaussians::Gaussian;

    #[test]
    fn faint_and_alone_is_a_floater_faint_on_a_surface_or_opaque_alone_is_not() {
        let mut g = Gaussians::new(0).unwrap();
        let at = |x: f32, y: f32, z: f32, opacity_logit: f32| Gaussian {
            position: Vec3::new(x, y, z),
            opacity_logit,
            ..Gaussian::default()
        };
        for i in 0..20 {
            for j in 0..20 {
                g.push(&at(i as f32 * 0.05, j as f32 * 0.05, 0.0, 3.0));
            }
        }
        g.push(&at(0.5, 0.5, 0.01, -4.0)); // faint, on the surface
        g.push(&at(0.5, 0.5, 1.0, -4.0)); // faint, alone
        g.push(&at(0.5, 0.5, 2.0, 3.0)); // opaque, alone
        let f = find(&g, 1.0, &FloaterSettings::default()).unwrap();
        assert_eq!(f.iter().filter(|&&v| v).count(), 1);
        assert!(f[401]);
        // In a capture whose unit is half a metre the radius spans 0.2 units.
        let f = find(&g, 0.5, &FloaterSettings::default()).unwrap();
        assert!(f[401] && !f[400]);
        let none = FloaterSettings {
            min_neighbours: 0,
            ..FloaterSettings::default()
        };
        assert!(!find(&g, 1.0, &none).unwrap().contains(&true));
        let bad = FloaterSettings {
            radius: 0.0,
            ..FloaterSettings::default()
        };
        assert!(find(&g, 1.0, &bad).is_err());
    }
}
