//! Looks: the materials of the generator, and the procedural textures that turn a point on a
//! surface into a colour.
//!
//! Every colour word an object's `color` attribute can carry is in [`COLORS`], and the texture of a
//! surface only modulates that colour's brightness by a few tens of percent, so the word and the
//! rendered colour agree.

use glam::{Vec2, Vec3};
use sage_scene::vocabulary::{COLORS, color_rgb};

/// What a surface is made of: decides the texture, the gloss and the physics constants.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Material {
    /// Wood with grain stripes.
    Wood,
    /// Brushed metal.
    Metal,
    /// Woven fabric.
    Fabric,
    /// Leather.
    Leather,
    /// Glass (partly transparent).
    Glass,
    /// Glazed ceramic.
    Ceramic,
    /// Plastic or lacquer.
    Plastic,
    /// Veined marble.
    Marble,
    /// Paper (book pages and covers).
    Paper,
    /// Cardboard.
    Cardboard,
    /// Leaves.
    Foliage,
    /// Painted plaster (walls, ceilings).
    Paint,
    /// Wooden floor planks.
    Planks,
    /// Floor tiles in a checker of two tones.
    Tiles,
    /// Wall-to-wall carpet.
    Carpet,
    /// Polished concrete.
    Concrete,
    /// An abstract painting on canvas.
    Canvas,
    /// A lit display.
    Screen,
}

impl Material {
    /// The material word of the `material` attribute.
    pub fn name(self) -> &'static str {
        match self {
            Material::Wood | Material::Planks => "wood",
            Material::Metal => "metal",
            Material::Fabric | Material::Carpet => "fabric",
            Material::Leather => "leather",
            Material::Glass | Material::Screen => "glass",
            Material::Ceramic | Material::Tiles => "ceramic",
            Material::Plastic => "plastic",
            Material::Marble => "marble",
            Material::Paper => "paper",
            Material::Cardboard => "cardboard",
            Material::Foliage => "natural",
            Material::Paint => "plaster",
            Material::Concrete => "concrete",
            Material::Canvas => "canvas",
        }
    }

    /// Strength of the view-dependent highlight (added colour when seen head-on).
    pub fn gloss(self) -> f32 {
        match self {
            Material::Glass | Material::Screen => 0.12,
            Material::Metal => 0.10,
            Material::Ceramic => 0.08,
            Material::Marble => 0.07,
            Material::Tiles => 0.06,
            Material::Plastic => 0.05,
            Material::Leather => 0.04,
            Material::Wood | Material::Planks => 0.03,
            Material::Foliage => 0.02,
            Material::Paint => 0.015,
            Material::Fabric | Material::Carpet | Material::Paper | Material::Cardboard => 0.01,
            Material::Concrete | Material::Canvas => 0.01,
        }
    }

    /// Opacity of a Gaussian on this material (glass lets some light through).
    pub fn opacity(self) -> f32 {
        match self {
            Material::Glass => 0.6,
            _ => 0.96,
        }
    }

    /// Coulomb friction against a typical floor.
    pub fn friction(self) -> f32 {
        match self {
            Material::Metal | Material::Marble | Material::Glass => 0.35,
            Material::Ceramic | Material::Tiles | Material::Screen => 0.4,
            Material::Plastic => 0.45,
            Material::Leather | Material::Cardboard => 0.6,
            Material::Fabric | Material::Carpet | Material::Foliage => 0.7,
            _ => 0.5,
        }
    }

    /// Restitution (bounciness) of a rigid body made of this material.
    pub fn restitution(self) -> f32 {
        match self {
            Material::Plastic => 0.3,
            Material::Ceramic | Material::Glass | Material::Marble => 0.2,
            Material::Metal => 0.15,
            Material::Wood => 0.1,
            _ => 0.05,
        }
    }
}

/// A surface finish: a base colour, a material and a seed that varies the texture between objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Look {
    /// Base colour, sRGB 0–1.
    pub rgb: Vec3,
    /// Material (texture and gloss).
    pub material: Material,
    /// Texture variation seed.
    pub seed: u32,
}

impl Look {
    /// A look with the colour of a palette word (mid gray for a word not in the palette).
    pub fn named(color: &str, material: Material, seed: u32) -> Look {
        let rgb = color_rgb(color).unwrap_or([0.5, 0.5, 0.5]);
        Look {
            rgb: Vec3::from_array(rgb),
            material,
            seed,
        }
    }

    /// The same look in another colour.
    pub fn with_rgb(self, rgb: Vec3) -> Look {
        Look { rgb, ..self }
    }

    /// The colour at texture-space point `p` on a surface with texture-space normal `n`, averaged
    /// over a neighbourhood about `blur` metres wide (the size of the Gaussian that shows it), so
    /// thin lines such as plank seams fade instead of breaking into dots.
    pub fn shade(&self, p: Vec3, n: Vec3, blur: f32) -> Vec3 {
        let uv = plane_coords(p, n);
        let s = self.seed;
        let rgb = match self.material {
            Material::Wood => self.rgb * wood(uv, s),
            Material::Planks => planks(uv, self.rgb, s, blur),
            Material::Tiles => tiles(uv, self.rgb, s, blur),
            Material::Fabric | Material::Carpet => {
                self.rgb
                    * (0.9 + 0.14 * noise2(uv * 70.0, s) + 0.08 * (noise2(uv * 4.0, s ^ 7) - 0.5))
            }
            Material::Leather => self.rgb * (0.93 + 0.1 * noise2(uv * 35.0, s)),
            Material::Metal => {
                self.rgb * (0.95 + 0.08 * noise2(Vec2::new(uv.x * 3.0, uv.y * 250.0), s))
            }
            Material::Marble => marble(uv, self.rgb, s),
            Material::Paint => self.rgb * (0.97 + 0.05 * fbm2(uv * 1.5, s)),
            Material::Concrete => {
                self.rgb
                    * (0.88 + 0.16 * fbm2(uv * 3.0, s) + 0.08 * (noise2(uv * 160.0, s ^ 3) - 0.5))
            }
            Material::Foliage => {
                let t = noise3(p * 16.0, s);
                (self.rgb * (0.55 + 0.75 * t)).lerp(self.rgb * Vec3::new(1.2, 1.25, 0.7), 0.3 * t)
            }
            Material::Canvas => canvas(uv, s),
            Material::Screen => self.rgb * (0.75 + 0.35 * fbm2(uv * 3.0, s)),
            Material::Glass
            | Material::Ceramic
            | Material::Plastic
            | Material::Paper
            | Material::Cardboard => self.rgb * (0.97 + 0.05 * noise2(uv * 20.0, s)),
        };
        rgb.clamp(Vec3::ZERO, Vec3::ONE)
    }
}

/// The two surface coordinates of `p` on the plane facing `n` (the axis most aligned with `n` is
/// dropped; the first coordinate is horizontal on walls).
fn plane_coords(p: Vec3, n: Vec3) -> Vec2 {
    let a = n.abs();
    if a.z >= a.x && a.z >= a.y {
        Vec2::new(p.x, p.y)
    } else if a.x >= a.y {
        Vec2::new(p.y, p.z)
    } else {
        Vec2::new(p.x, p.z)
    }
}

/// A well-mixed hash of a lattice point, in [0, 1).
fn lattice(x: i32, y: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8DA6_B343)
        ^ (y as u32).wrapping_mul(0xD816_3841)
        ^ (z as u32).wrapping_mul(0xCB1A_B31F)
        ^ seed.wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297A_2D39);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Smooth value noise on the plane, in [0, 1).
fn noise2(p: Vec2, seed: u32) -> f32 {
    let i = p.floor();
    let f = p - i;
    let (x, y) = (i.x as i32, i.y as i32);
    let (u, v) = (smooth(f.x), smooth(f.y));
    let a = lattice(x, y, 0, seed) + (lattice(x + 1, y, 0, seed) - lattice(x, y, 0, seed)) * u;
    let b = lattice(x, y + 1, 0, seed)
        + (lattice(x + 1, y + 1, 0, seed) - lattice(x, y + 1, 0, seed)) * u;
    a + (b - a) * v
}

/// Smooth value noise in space, in [0, 1).
fn noise3(p: Vec3, seed: u32) -> f32 {
    let i = p.floor();
    let f = p - i;
    let (x, y, z) = (i.x as i32, i.y as i32, i.z as i32);
    let w = Vec3::new(smooth(f.x), smooth(f.y), smooth(f.z));
    let layer = |dz: i32| {
        let a = lattice(x, y, z + dz, seed)
            + (lattice(x + 1, y, z + dz, seed) - lattice(x, y, z + dz, seed)) * w.x;
        let b = lattice(x, y + 1, z + dz, seed)
            + (lattice(x + 1, y + 1, z + dz, seed) - lattice(x, y + 1, z + dz, seed)) * w.x;
        a + (b - a) * w.y
    };
    let (lo, hi) = (layer(0), layer(1));
    lo + (hi - lo) * w.z
}

/// Three octaves of [`noise2`], in [0, 1).
fn fbm2(p: Vec2, seed: u32) -> f32 {
    (noise2(p, seed) + 0.5 * noise2(p * 2.03, seed ^ 1) + 0.25 * noise2(p * 4.01, seed ^ 2)) / 1.75
}

/// How strongly a line `width` wide shows at distance `d` from its middle, seen through a
/// footprint `blur` wide: fully on a sharp line, wider but fainter under a coarse footprint.
fn line_cover(d: f32, width: f32, blur: f32) -> f32 {
    let spread = width.max(blur);
    (width / spread) * (1.0 - (d / spread).clamp(0.0, 1.0))
}

/// Brightness factor of wood grain running along the first coordinate.
fn wood(uv: Vec2, seed: u32) -> f32 {
    let warp = 3.0 * fbm2(Vec2::new(uv.x * 0.8, uv.y * 4.0), seed);
    let stripes = (std::f32::consts::TAU * (uv.y * 35.0 + warp)).sin();
    0.9 + 0.06 * stripes + 0.1 * (noise2(Vec2::new(uv.x * 1.5, uv.y * 45.0), seed ^ 5) - 0.5)
}

/// Floor planks 0.14 m wide and 1.2 m long in staggered rows, each slightly tinted, with dark seams.
fn planks(uv: Vec2, rgb: Vec3, seed: u32, blur: f32) -> Vec3 {
    let (width, length) = (0.14, 1.2);
    let row = (uv.y / width).floor();
    let shift = lattice(row as i32, 0, 1, seed) * length;
    let col = ((uv.x + shift) / length).floor();
    let tint = 0.88 + 0.22 * lattice(row as i32, col as i32, 2, seed);
    let fu = (uv.x + shift) / length - col;
    let fv = uv.y / width - row;
    let edge = (fu * length)
        .min((1.0 - fu) * length)
        .min(fv * width)
        .min((1.0 - fv) * width);
    let grain = wood(uv + Vec2::new(col * 3.7, 0.0), seed);
    rgb * tint * grain * (1.0 - 0.45 * line_cover(edge, 0.006, blur))
}

/// Square 0.3 m tiles in a two-tone checker with light grout lines.
fn tiles(uv: Vec2, rgb: Vec3, seed: u32, blur: f32) -> Vec3 {
    let size = 0.3;
    let cell = (uv / size).floor();
    let f = uv / size - cell;
    let edge = f.x.min(1.0 - f.x).min(f.y).min(1.0 - f.y) * size;
    let tone = if (cell.x as i64 + cell.y as i64).rem_euclid(2) == 0 {
        1.0
    } else {
        0.8
    };
    let tile = rgb * tone * (0.97 + 0.06 * noise2(uv * 12.0, seed));
    tile.lerp(Vec3::splat(0.78), line_cover(edge, 0.004, blur))
}

/// Marble: the base colour with dark, warped veins.
fn marble(uv: Vec2, rgb: Vec3, seed: u32) -> Vec3 {
    let v = (uv.x * 4.0 + uv.y * 3.0 + 6.0 * fbm2(uv * 1.8, seed))
        .sin()
        .abs();
    let vein = (1.0 - v).powi(8);
    rgb * (1.0 - 0.35 * vein) * (0.97 + 0.05 * noise2(uv * 8.0, seed ^ 9))
}

/// An abstract painting: three colours from the seed blended by low-frequency noise.
fn canvas(uv: Vec2, seed: u32) -> Vec3 {
    let pick = |k: i32| {
        let i = (lattice(k, 0, 3, seed) * COLORS.len() as f32) as usize % COLORS.len();
        Vec3::from_array(COLORS[i].1)
    };
    let w = fbm2(uv * 3.0, seed);
    let a = pick(0).lerp(pick(1), smooth((w * 2.0).clamp(0.0, 1.0)));
    a.lerp(pick(2), smooth((w * 2.0 - 1.0).clamp(0.0, 1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_stay_close_to_the_base_colour() {
        for m in [
            Material::Wood,
            Material::Fabric,
            Material::Metal,
            Material::Paint,
            Material::Leather,
        ] {
            let look = Look::named("blue", m, 11);
            for i in 0..200 {
                let p = Vec3::new(i as f32 * 0.037, i as f32 * 0.011, 0.3);
                let c = look.shade(p, Vec3::Z, 0.01);
                assert!(
                    (c - look.rgb).abs().max_element() < 0.25 * look.rgb.max_element() + 0.02,
                    "{m:?} {c}"
                );
            }
        }
    }

    #[test]
    fn noise_is_in_range_and_deterministic() {
        for i in 0..500 {
            let p = Vec3::new(
                i as f32 * 0.173 - 40.0,
                i as f32 * 0.071,
                -(i as f32) * 0.03,
            );
            let a = noise3(p, 3);
            assert!((0.0..1.0).contains(&a));
            assert_eq!(a, noise3(p, 3));
            assert!((0.0..1.0).contains(&noise2(p.truncate(), 4)));
        }
    }
}
