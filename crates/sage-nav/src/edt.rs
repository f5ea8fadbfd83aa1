//! The exact Euclidean distance transform of Felzenszwalb and Huttenlocher ("Distance Transforms
//! of Sampled Functions", 2012): two passes of the 1-D lower envelope of parabolas give, for every
//! cell, the squared distance (in cells, centre to centre) to the nearest obstacle cell, in
//! O(cells) time.

/// The value standing for "no obstacle in reach": large, yet finite so the envelope arithmetic
/// stays exact for every real distance.
const FAR: f32 = 1e20;

/// Squared distance, in cell units, from each cell to the nearest cell where `obstacle` is true
/// (0 on obstacles; `f32::INFINITY` everywhere when there is no obstacle at all).
pub fn squared_distance(width: usize, height: usize, obstacle: &[bool]) -> Vec<f32> {
    assert_eq!(obstacle.len(), width * height, "mask size");
    if !obstacle.iter().any(|&o| o) {
        return vec![f32::INFINITY; width * height];
    }
    let mut d: Vec<f32> = obstacle
        .iter()
        .map(|&o| if o { 0.0 } else { FAR })
        .collect();
    let n = width.max(height);
    let mut scratch = Scratch {
        f: vec![0.0; n],
        out: vec![0.0; n],
        v: vec![0; n],
        z: vec![0.0; n + 1],
    };
    for x in 0..width {
        for y in 0..height {
            scratch.f[y] = d[y * width + x];
        }
        scratch.envelope(height);
        for y in 0..height {
            d[y * width + x] = scratch.out[y];
        }
    }
    for row in d.chunks_exact_mut(width) {
        scratch.f[..width].copy_from_slice(row);
        scratch.envelope(width);
        row.copy_from_slice(&scratch.out[..width]);
    }
    d
}

/// Buffers of the 1-D transform, reused across rows and columns.
struct Scratch {
    f: Vec<f32>,
    out: Vec<f32>,
    v: Vec<usize>,
    z: Vec<f32>,
}

impl Scratch {
    /// `out[q] = min_p (q − p)² + f[p]` over the first `n` samples.
    fn envelope(&mut self, n: usize) {
        let (f, v, z) = (&self.f, &mut self.v, &mut self.z);
        let mut k = 0usize;
        v[0] = 0;
        z[0] = f32::NEG_INFINITY;
        z[1] = f32::INFINITY;
        let meet = |q: usize, p: usize| {
            let (qf, pf) = (q as f32, p as f32);
            ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * qf - 2.0 * pf)
        };
        for q in 1..n {
            let mut s = meet(q, v[k]);
            while s <= z[k] {
                k -= 1;
                s = meet(q, v[k]);
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f32::INFINITY;
        }
        k = 0;
        for q in 0..n {
            while z[k + 1] < q as f32 {
                k += 1;
            }
            let dq = q as f32 - v[k] as f32;
            self.out[q] = dq * dq + f[v[k]];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute(width: usize, height: usize, obstacle: &[bool]) -> Vec<f32> {
        (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as i64, (i / width) as i64);
                obstacle
                    .iter()
                    .enumerate()
                    .filter(|(_, o)| **o)
                    .map(|(j, _)| {
                        let (u, v) = ((j % width) as i64, (j / width) as i64);
                        ((x - u).pow(2) + (y - v).pow(2)) as f32
                    })
                    .fold(f32::INFINITY, f32::min)
            })
            .collect()
    }

    proptest! {
        #[test]
        fn matches_brute_force(
            width in 1usize..24,
            height in 1usize..24,
            seed in any::<u64>(),
            density in 0.0f64..0.5,
        ) {
            let mut state = seed | 1;
            let mask: Vec<bool> = (0..width * height)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state % 1000) as f64 / 1000.0 < density
                })
                .collect();
            prop_assert_eq!(squared_distance(width, height, &mask), brute(width, height, &mask));
        }
    }

    #[test]
    fn single_obstacle_gives_squared_radii() {
        let mut mask = vec![false; 25];
        mask[12] = true;
        let d = squared_distance(5, 5, &mask);
        assert_eq!(d[12], 0.0);
        assert_eq!(d[0], 8.0);
        assert_eq!(d[13], 1.0);
        assert_eq!(d[2], 4.0);
    }
}
