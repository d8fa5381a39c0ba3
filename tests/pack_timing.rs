//! Packing time for 50, 500 and 2,000 rectangles (ignored by default: timing, not correctness).
//! `cargo test --test pack_timing -- --ignored --nocapture`

use atlastree::preprocess::pack::{PackFailure, PackOptions, SortOrder, pack, verify_packing};
use std::time::{Duration, Instant};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn range(&mut self, lo: u32, hi: u32) -> u32 {
        lo + (self.next() % u64::from(hi - lo + 1)) as u32
    }
}

/// `n` outer areas (inner + 16, 4-aligned): 90 % tiny (inner 1–16), 10 % up to `big` inner.
fn mostly_tiny(rng: &mut Rng, n: usize, big: u32) -> Vec<[u32; 2]> {
    (0..n)
        .map(|_| {
            let hi = if rng.range(0, 9) == 0 { big } else { 16 };
            [
                (rng.range(1, hi) + 16).next_multiple_of(4),
                (rng.range(1, hi) + 16).next_multiple_of(4),
            ]
        })
        .collect()
}

/// `n` uniformly random sizes (many distinct sizes: the slow case for global best fit).
fn uniform(rng: &mut Rng, n: usize, max: u32) -> Vec<[u32; 2]> {
    (0..n)
        .map(|_| [rng.range(1, max / 4) * 4, rng.range(1, max / 4) * 4])
        .collect()
}

/// Grow or shrink random rectangles by 4 texels (outer sides kept in `20..=side/2`) until the summed area
/// is within one 4-texel step of `fill · side²`: a fixed count at a chosen occupancy.
fn adjust_to_fill(rng: &mut Rng, sizes: &mut [[u32; 2]], side: u32, fill: f64) {
    let target = fill * f64::from(side) * f64::from(side);
    let area = |s: &[[u32; 2]]| {
        s.iter()
            .map(|r| f64::from(r[0]) * f64::from(r[1]))
            .sum::<f64>()
    };
    let mut a = area(sizes);
    let n = sizes.len() as u32;
    for _ in 0..10_000_000 {
        let i = rng.range(0, n - 1) as usize;
        let axis = rng.range(0, 1) as usize;
        let other = f64::from(sizes[i][1 - axis]);
        if a > target + 4.0 * other && sizes[i][axis] > 20 {
            sizes[i][axis] -= 4;
            a -= 4.0 * other;
        } else if a + 4.0 * other < target && sizes[i][axis] < side / 2 {
            sizes[i][axis] += 4;
            a += 4.0 * other;
        } else if (a - target).abs() <= 4.0 * f64::from(side / 2) {
            return;
        }
    }
}

fn time(sizes: &[[u32; 2]], opts: &PackOptions) -> (Duration, Result<SortOrder, PackFailure>) {
    let mut best = Duration::MAX;
    let mut out = Err(PackFailure::NoFit {
        placed: 0,
        total: 0,
    });
    for _ in 0..3 {
        let t = Instant::now();
        let r = pack(sizes, opts);
        best = best.min(t.elapsed());
        if let Ok(p) = &r {
            verify_packing(sizes, &p.positions, opts.atlas_size).unwrap();
        }
        out = r.map(|p| p.order_used);
    }
    (best, out)
}

#[test]
#[ignore]
fn timing() {
    let mut rng = Rng(7);
    let cases: [(usize, u32, u32, &str); 4] = [
        (50, 1024, 240, "mostly tiny"),
        (500, 1024, 120, "mostly tiny"),
        (2000, 1024, 16, "tiny"),
        (2000, 2048, 120, "mostly tiny"),
    ];
    for (n, side, big, kind) in cases {
        for fill in [0.80, 0.90, 0.95, 0.99] {
            for (label, mut sizes) in [
                (kind, mostly_tiny(&mut rng, n, big)),
                ("uniform", uniform(&mut rng, n, side / 4)),
            ] {
                adjust_to_fill(&mut rng, &mut sizes, side, fill);
                let area: f64 = sizes
                    .iter()
                    .map(|s| f64::from(s[0]) * f64::from(s[1]))
                    .sum();
                let opts = PackOptions {
                    atlas_size: side,
                    ..Default::default()
                };
                let (t, r) = time(&sizes, &opts);
                let global_only = PackOptions {
                    atlas_size: side,
                    orders: vec![SortOrder::GlobalBestFit],
                };
                let (tg, _) = time(&sizes, &global_only);
                println!(
                    "n={n:5} {label:11} atlas {side:5} fill {:.3}: all attempts {:>8.2} ms -> {:?}; global alone {:.2} ms",
                    area / (f64::from(side) * f64::from(side)),
                    t.as_secs_f64() * 1e3,
                    r,
                    tg.as_secs_f64() * 1e3
                );
            }
        }
    }
}
