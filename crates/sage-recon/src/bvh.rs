//! A bounding volume hierarchy over triangles: nearest-surface distance for the safety filter
//! and first hits for the renderer's rays, both in O(log n) per query on indoor scenes.
//!
//! Built by median splits along the widest axis of the centroids (ties broken by triangle
//! index), so the tree, and everything queried from it, is the same on every run.

use glam::Vec3;
use sage_core::Aabb;

/// Triangles per leaf at most.
const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child.
    start: u32,
    /// Leaf: triangle count; inner: 0.
    count: u32,
    /// Inner: index of the right child.
    right: u32,
}

/// The hierarchy and its own copy of the triangles (in leaf order).
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Triangle indices (into the caller's slice) in leaf order.
    order: Vec<u32>,
    tris: Vec<[Vec3; 3]>,
}

/// A ray's first hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: the distance in units of the ray direction's length.
    pub t: f32,
    /// Index of the triangle hit (into the slice the hierarchy was built from).
    pub triangle: usize,
}

impl Bvh {
    /// Builds the hierarchy over `triangles`.
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1),
            order: (0..triangles.len() as u32).collect(),
            tris: Vec::new(),
        };
        if triangles.is_empty() {
            return bvh;
        }
        let centroids: Vec<Vec3> = triangles
            .iter()
            .map(|t| (t[0] + t[1] + t[2]) / 3.0)
            .collect();
        bvh.split(triangles, &centroids, 0, triangles.len());
        bvh.tris = bvh.order.iter().map(|&i| triangles[i as usize]).collect();
        bvh
    }

    fn split(&mut self, tris: &[[Vec3; 3]], cent: &[Vec3], lo: usize, hi: usize) -> u32 {
        let bounds = self.order[lo..hi].iter().fold(Aabb::EMPTY, |b, &i| {
            let t = tris[i as usize];
            b.grow(t[0]).grow(t[1]).grow(t[2])
        });
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            bounds,
            start: lo as u32,
            count: (hi - lo) as u32,
            right: 0,
        });
        if hi - lo <= LEAF_SIZE {
            return id;
        }
        let cb = Aabb::from_points(self.order[lo..hi].iter().map(|&i| cent[i as usize]));
        let axis = cb.size().max_position();
        let mid = (lo + hi) / 2;
        self.order[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| {
            cent[a as usize][axis]
                .total_cmp(&cent[b as usize][axis])
                .then(a.cmp(&b))
        });
        let left = self.split(tris, cent, lo, mid);
        let right = self.split(tris, cent, mid, hi);
        self.nodes[id as usize] = Node {
            bounds,
            start: left,
            count: 0,
            right,
        };
        id
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when built from no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Distance from `p` to the nearest triangle and that triangle's index (`None` when
    /// empty).
    pub fn nearest(&self, p: Vec3) -> Option<(f32, usize)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = (f32::INFINITY, 0usize);
        let mut stack = Stack::new();
        while let Some(n) = stack.pop() {
            let node = self.nodes[n as usize];
            if box_distance_sq(&node.bounds, p) >= best.0 {
                continue;
            }
            if node.count > 0 {
                for k in node.start..node.start + node.count {
                    let d = point_triangle_distance_sq(p, &self.tris[k as usize]);
                    if d < best.0 {
                        best = (d, self.order[k as usize] as usize);
                    }
                }
            } else {
                // Visit the nearer child first so the bound tightens early.
                let (l, r) = (node.start, node.right);
                let dl = box_distance_sq(&self.nodes[l as usize].bounds, p);
                let dr = box_distance_sq(&self.nodes[r as usize].bounds, p);
                if dl < dr {
                    stack.push2(r, l);
                } else {
                    stack.push2(l, r);
                }
            }
        }
        Some((best.0.sqrt(), best.1))
    }

    /// The first triangle hit by the ray `origin + t·dir` with `t_min < t < t_max`; ties go to
    /// the lower triangle index, so the answer does not depend on the tree's shape.
    pub fn raycast(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = dir.recip();
        let mut best: Option<Hit> = None;
        let mut limit = t_max;
        let mut stack = Stack::new();
        while let Some(n) = stack.pop() {
            let node = self.nodes[n as usize];
            if slab(&node.bounds, origin, inv, t_min, limit).is_none() {
                continue;
            }
            if node.count > 0 {
                for k in node.start..node.start + node.count {
                    if let Some(t) = ray_triangle(origin, dir, &self.tris[k as usize])
                        && t > t_min
                        && t <= limit
                    {
                        let tri = self.order[k as usize] as usize;
                        let better = match best {
                            Some(b) => t < b.t || (t == b.t && tri < b.triangle),
                            None => true,
                        };
                        if better {
                            best = Some(Hit { t, triangle: tri });
                            limit = t;
                        }
                    }
                }
            } else {
                let (l, r) = (node.start, node.right);
                let el = slab(&self.nodes[l as usize].bounds, origin, inv, t_min, limit);
                let er = slab(&self.nodes[r as usize].bounds, origin, inv, t_min, limit);
                match (el, er) {
                    (Some(a), Some(b)) if a <= b => stack.push2(r, l),
                    (Some(_), Some(_)) => stack.push2(l, r),
                    (Some(_), None) => stack.push(l),
                    (None, Some(_)) => stack.push(r),
                    (None, None) => {}
                }
            }
        }
        best
    }
}

/// A fixed traversal stack: a query allocates nothing. Median splits make the depth
/// log2(n / LEAF_SIZE) + 1, and a traversal holds at most one pending node per level.
struct Stack {
    items: [u32; 64],
    len: usize,
}

impl Stack {
    fn new() -> Stack {
        Stack {
            items: [0; 64],
            len: 1,
        }
    }

    fn pop(&mut self) -> Option<u32> {
        self.len = self.len.checked_sub(1)?;
        Some(self.items[self.len])
    }

    fn push(&mut self, n: u32) {
        self.items[self.len] = n;
        self.len += 1;
    }

    /// Pushes `later` then `first`, so `first` is visited next.
    fn push2(&mut self, later: u32, first: u32) {
        self.push(later);
        self.push(first);
    }
}

fn box_distance_sq(b: &Aabb, p: Vec3) -> f32 {
    let d = (b.min - p).max(p - b.max).max(Vec3::ZERO);
    d.length_squared()
}

/// Entry parameter of the ray into the box within `[t_min, t_max]`, if it enters.
fn slab(b: &Aabb, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t0 = (b.min - o) * inv;
    let t1 = (b.max - o) * inv;
    // NaN (0 × ∞ for a ray in a box face plane) must not cut the ray short: min/max of glam
    // return the other operand, and the comparisons below treat the box as entered.
    let near = t0.min(t1).max_element().max(t_min);
    let far = t0.max(t1).min_element().min(t_max);
    (near <= far).then_some(near)
}

/// Möller–Trumbore: the ray parameter of the hit with the triangle (either side), if any.
pub fn ray_triangle(o: Vec3, d: Vec3, t: &[Vec3; 3]) -> Option<f32> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - t[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// Squared distance from `p` to the triangle (closest point by Voronoi regions, Ericson §5.1.5).
pub fn point_triangle_distance_sq(p: Vec3, t: &[Vec3; 3]) -> f32 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length_squared();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_soup(n: usize, seed: u64) -> Vec<[Vec3; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut v = || Vec3::new(rng.random(), rng.random(), rng.random()) * 4.0;
        (0..n)
            .map(|_| {
                let a = v();
                [a, a + (v() - 2.0) * 0.2, a + (v() - 2.0) * 0.2]
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn queries_match_brute_force(seed in 0u64..1000, px in -1.0f32..5.0, py in -1.0f32..5.0, pz in -1.0f32..5.0, dx in -1.0f32..1.0, dy in -1.0f32..1.0) {
            let tris = random_soup(300, seed);
            let bvh = Bvh::build(&tris);
            let p = Vec3::new(px, py, pz);
            let brute = tris.iter().map(|t| point_triangle_distance_sq(p, t)).fold(f32::INFINITY, f32::min).sqrt();
            let (d, k) = bvh.nearest(p).unwrap();
            prop_assert!((d - brute).abs() < 1e-5);
            prop_assert!((point_triangle_distance_sq(p, &tris[k]).sqrt() - brute).abs() < 1e-5);
            let dir = Vec3::new(dx, dy, 0.3);
            let brute_hit = tris.iter().enumerate()
                .filter_map(|(i, t)| ray_triangle(p, dir, t).filter(|&t| t > 0.0 && t <= 100.0).map(|t| (t, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let hit = bvh.raycast(p, dir, 0.0, 100.0).map(|h| (h.t, h.triangle));
            prop_assert_eq!(hit, brute_hit);
        }
    }

    #[test]
    fn point_triangle_regions() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!((point_triangle_distance_sq(Vec3::new(0.2, 0.2, 2.0), &t) - 4.0).abs() < 1e-6);
        assert!((point_triangle_distance_sq(Vec3::new(-1.0, -1.0, 0.0), &t) - 2.0).abs() < 1e-6);
        assert!((point_triangle_distance_sq(Vec3::new(0.5, -2.0, 0.0), &t) - 4.0).abs() < 1e-6);
        assert!((point_triangle_distance_sq(Vec3::new(1.0, 1.0, 0.0), &t) - 0.5).abs() < 1e-6);
    }
}
