//! From a grid path to a trajectory: line-of-sight shortcutting on the inflated grid, resampling
//! at a fixed step, and headings along the path.

use glam::Vec2;

/// True when every cell the segment between the centres of cells `a` and `b` passes through
/// (a supercover: where it crosses a cell corner exactly, both cells beside the corner count)
/// is navigable.
pub fn line_clear(width: usize, passable: &[bool], a: usize, b: usize) -> bool {
    let (mut x, mut y) = ((a % width) as i64, (a / width) as i64);
    let (x1, y1) = ((b % width) as i64, (b / width) as i64);
    let (nx, ny) = ((x1 - x).abs(), (y1 - y).abs());
    let (sx, sy) = ((x1 - x).signum(), (y1 - y).signum());
    let ok = |x: i64, y: i64| passable[(y as usize) * width + x as usize];
    if !ok(x, y) {
        return false;
    }
    let (mut ix, mut iy) = (0i64, 0i64);
    while ix < nx || iy < ny {
        let decision = (1 + 2 * ix) * ny - (1 + 2 * iy) * nx;
        if decision == 0 {
            if !(ok(x + sx, y) && ok(x, y + sy)) {
                return false;
            }
            x += sx;
            y += sy;
            ix += 1;
            iy += 1;
        } else if decision < 0 {
            x += sx;
            ix += 1;
        } else {
            y += sy;
            iy += 1;
        }
        if !ok(x, y) {
            return false;
        }
    }
    true
}

/// The waypoints of `cells` (a connected grid path) kept by greedy line-of-sight shortcutting:
/// from each kept cell, the farthest later cell still in sight is kept next.
pub fn shortcut(width: usize, passable: &[bool], cells: &[usize]) -> Vec<usize> {
    let Some(&first) = cells.first() else {
        return Vec::new();
    };
    let mut out = vec![first];
    let mut anchor = 0;
    while anchor + 1 < cells.len() {
        let mut j = anchor + 1;
        while j + 1 < cells.len() && line_clear(width, passable, cells[anchor], cells[j + 1]) {
            j += 1;
        }
        out.push(cells[j]);
        anchor = j;
    }
    out
}

/// Length of a polyline.
pub fn polyline_length(points: &[Vec2]) -> f32 {
    points.windows(2).map(|w| w[0].distance(w[1])).sum()
}

/// Heading (radians, from +x counter-clockwise) at each point: towards the next point; the last
/// point takes `final_heading` when given, else the previous heading.
pub fn headings(points: &[Vec2], final_heading: Option<f32>) -> Vec<f32> {
    let mut out: Vec<f32> = points
        .windows(2)
        .map(|w| {
            let d = w[1] - w[0];
            d.y.atan2(d.x)
        })
        .collect();
    if !points.is_empty() {
        out.push(final_heading.or(out.last().copied()).unwrap_or(0.0));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resample_spaces_points_evenly_and_keeps_ends() {
        let pts = [Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(1.0, 0.6)];
        let r = sage_core::geometry::resample_polyline(&pts, 0.25);
        assert_eq!(r.first(), Some(&Vec2::ZERO));
        assert_eq!(r.last(), Some(&Vec2::new(1.0, 0.6)));
        for w in r.windows(2).take(r.len() - 2) {
            let along = polyline_length(&[w[0], w[1]]);
            assert!(along <= 0.25 + 1e-5, "{along}");
        }
        assert_eq!(r.len(), 8);
    }

    #[test]
    fn line_of_sight_is_conservative_at_corners() {
        // 4x4 with one blocked cell at (1, 2); a diagonal from (0,1)... passes its corner.
        let w = 4;
        let mut p = vec![true; 16];
        p[2 * w + 1] = false;
        assert!(!line_clear(w, &p, w, 2 * w + 2 + w));
        assert!(line_clear(w, &p, 0, 3));
        // Exact corner crossing (0,0)→(2,2) touches (1,0)/(0,1) and (2,1)/(1,2).
        assert!(!line_clear(w, &p, 0, 2 * w + 2));
    }

    #[test]
    fn headings_follow_the_path() {
        let h = headings(&[Vec2::ZERO, Vec2::Y, Vec2::new(-1.0, 1.0)], Some(0.5));
        assert!((h[0] - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((h[1] - std::f32::consts::PI).abs() < 1e-6);
        assert_eq!(h[2], 0.5);
    }
}
