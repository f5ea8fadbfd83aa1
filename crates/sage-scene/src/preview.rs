//! A top-down plan view of a scene's Gaussians: the quickest look at a scene folder, with no
//! renderer. Each pixel shows the base colour of the highest Gaussian below the ceiling cut,
//! so furniture, floors and walls read as on an architect's plan.

use crate::gaussians::Gaussians;
use glam::Vec3;

/// An 8-bit RGB image, row-major, row 0 at the top (max y).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `height × width × 3` bytes.
    pub pixels: Vec<u8>,
}

/// Renders the plan view at `metres_per_pixel`, ignoring Gaussians above `cut_z` (the ceiling)
/// and those with opacity below 0.1. Empty pixels are white.
pub fn plan_view(gaussians: &Gaussians, metres_per_pixel: f32, cut_z: f32) -> RgbImage {
    let bounds = gaussians.bounds();
    let size = if bounds.is_empty() {
        Vec3::ZERO
    } else {
        bounds.size()
    };
    let scale = metres_per_pixel.max(1e-3);
    let width = ((size.x / scale).ceil() as usize).clamp(1, 8192);
    let height = ((size.y / scale).ceil() as usize).clamp(1, 8192);
    let mut top = vec![f32::NEG_INFINITY; width * height];
    let mut pixels = vec![255u8; width * height * 3];
    let min_logit = -(1.0f32 / 0.1 - 1.0).ln();
    for i in 0..gaussians.len() {
        let p = Vec3::from_array(gaussians.positions[i]);
        if p.z > cut_z || gaussians.opacity_logit(i) < min_logit {
            continue;
        }
        // Each Gaussian covers a square of about its largest standard deviation.
        let sigma = gaussians.max_log_scale(i).exp();
        let reach = ((sigma / scale).round() as isize).clamp(0, 4);
        let c = (((p.x - bounds.min.x) / scale) as isize).min(width as isize - 1);
        let r = (((bounds.max.y - p.y) / scale) as isize).min(height as isize - 1);
        let rgb = gaussians
            .get(i)
            .base_color()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
        for rr in (r - reach).max(0)..=(r + reach).min(height as isize - 1) {
            for cc in (c - reach).max(0)..=(c + reach).min(width as isize - 1) {
                let k = rr as usize * width + cc as usize;
                if p.z > top[k] {
                    top[k] = p.z;
                    pixels[k * 3..k * 3 + 3].copy_from_slice(&rgb);
                }
            }
        }
    }
    RgbImage {
        width,
        height,
        pixels,
    }
}

impl RgbImage {
    /// Writes the image as PNG (atomically).
    pub fn save_png(&self, path: &std::path::Path) -> sage_core::Result<()> {
        sage_io::files::write_rgb_png(path, self.width, self.height, &self.pixels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gaussians::{Gaussian, SH_C0};

    #[test]
    fn the_highest_gaussian_below_the_cut_wins() {
        let mut g = Gaussians::new(0).unwrap();
        let red = [(1.0 - 0.5) / SH_C0, -0.5 / SH_C0, -0.5 / SH_C0];
        let blue = [-0.5 / SH_C0, -0.5 / SH_C0, (1.0 - 0.5) / SH_C0];
        let at = |x: f32, z: f32, dc| Gaussian {
            position: Vec3::new(x, 0.0, z),
            sh_dc: dc,
            opacity_logit: 4.0,
            ..Gaussian::default()
        };
        g.push(&at(0.0, 0.0, blue));
        g.push(&at(0.0, 1.0, red));
        g.push(&at(0.0, 3.0, blue));
        g.push(&at(1.0, 0.0, blue));
        let img = plan_view(&g, 0.5, 2.5);
        assert_eq!((img.width, img.height), (2, 1));
        assert_eq!(&img.pixels[..3], &[255, 0, 0]);
        assert_eq!(&img.pixels[3..6], &[0, 0, 255]);
    }
}
