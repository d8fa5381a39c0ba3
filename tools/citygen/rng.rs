//! Deterministic randomness: a SplitMix64 generator and tileable value noise.
//!
//! Every texture and every building draws from its own stream derived from `(seed, stream, index)`, so the
//! output does not depend on the order in which rayon schedules work.

/// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Stream identifiers, so that e.g. texture 7 and building 7 never share a sequence.
#[derive(Copy, Clone, Debug)]
pub enum Stream {
    Layout = 1,
    Building = 2,
    Texture = 3,
    Pool = 4,
}

/// A small, fast, deterministic generator (SplitMix64).
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// The generator for item `index` of `stream` under the global `seed`.
    pub fn derive(seed: u64, stream: Stream, index: u64) -> Self {
        Rng(mix64(seed ^ mix64((stream as u64) << 56 ^ mix64(index))))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.0)
    }

    /// Uniform in `[0, 1)` with 53 bits.
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }

    /// Uniform integer in `[0, n)`; 0 when `n == 0`.
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * u64::from(n)) >> 32) as u32
    }

    /// Uniform integer in `[lo, hi]`.
    pub fn int(&mut self, lo: u32, hi: u32) -> u32 {
        lo + self.below(hi.saturating_sub(lo).saturating_add(1))
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.f64() < p
    }

    /// Index drawn with probability proportional to `weights` (all non-negative, sum > 0).
    pub fn weighted(&mut self, weights: &[f64]) -> usize {
        let total: f64 = weights.iter().sum();
        let mut t = self.f64() * total;
        for (i, w) in weights.iter().enumerate() {
            if t < *w {
                return i;
            }
            t -= w;
        }
        weights.len().saturating_sub(1)
    }

    /// Fisher–Yates shuffle.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i as u32 + 1) as usize;
            v.swap(i, j);
        }
    }
}

/// Hash of a lattice point to `[0, 1)`.
#[inline]
pub fn hash01(seed: u64, x: i64, y: i64) -> f32 {
    let h = mix64(seed ^ mix64((x as u64).wrapping_mul(0x9e37_79b9) ^ (y as u64).rotate_left(32)));
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Tileable value noise in `[0, 1)`: lattice of `cells_x × cells_y` cells over the unit square, wrapping
/// at its edges, smoothstep-interpolated. `u, v` are in texture units (`[0,1)` is one period).
pub fn value_noise(seed: u64, u: f32, v: f32, cells_x: u32, cells_y: u32) -> f32 {
    let cx = cells_x.max(1) as i64;
    let cy = cells_y.max(1) as i64;
    let x = u * cx as f32;
    let y = v * cy as f32;
    let x0 = x.floor();
    let y0 = y.floor();
    let fx = x - x0;
    let fy = y - y0;
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let h = |i: i64, j: i64| hash01(seed, i.rem_euclid(cx), j.rem_euclid(cy));
    let a = h(ix, iy) + (h(ix + 1, iy) - h(ix, iy)) * sx;
    let b = h(ix, iy + 1) + (h(ix + 1, iy + 1) - h(ix, iy + 1)) * sx;
    a + (b - a) * sy
}

/// Fractal sum of `octaves` tileable value-noise layers, base lattice `cells`, normalised to `[0, 1)`.
pub fn fbm(seed: u64, u: f32, v: f32, cells: u32, octaves: u32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 1.0;
    let mut norm = 0.0;
    let mut c = cells.max(1);
    for o in 0..octaves {
        sum += amp * value_noise(seed.wrapping_add(u64::from(o)), u, v, c, c);
        norm += amp;
        amp *= 0.5;
        c = c.saturating_mul(2);
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Rng::derive(1, Stream::Texture, 7), |r, _: u64| {
                Some(r.next_u64())
            })
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Rng::derive(1, Stream::Texture, 7), |r, _: u64| {
                Some(r.next_u64())
            })
            .collect();
        let c: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Rng::derive(1, Stream::Building, 7), |r, _: u64| {
                Some(r.next_u64())
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn below_stays_in_range() {
        let mut r = Rng::derive(3, Stream::Layout, 0);
        for n in 1..50 {
            for _ in 0..100 {
                assert!(r.below(n) < n);
            }
        }
        assert_eq!(r.below(0), 0);
    }

    #[test]
    fn noise_tiles_across_the_period() {
        // The value at u and at u + 1 (one full period) must agree to float precision.
        for i in 0..20 {
            let u = i as f32 * 0.05;
            let a = value_noise(9, u, 0.3, 8, 8);
            let b = value_noise(9, u + 1.0, 0.3, 8, 8);
            assert!((a - b).abs() < 1e-5, "u={u} {a} vs {b}");
            assert!((0.0..1.0).contains(&a));
        }
    }
}
