//! Coverage-preserving alpha mips (issue 26 part 2; I. Castaño, "Computing Alpha Mipmaps", 2010).
//!
//! An alpha-tested texture loses coverage through its mips: halving averages an opaque leaf with the
//! transparent space around it, so at a distance fewer texels pass the cutoff and foliage, fences and
//! railings thin out, in the tree's atlases and in the original textures alike. With
//! [`AlphaMips::Coverage`] every stored level `L ≥ 1` of a MASK region is rescaled in alpha so that the
//! share of its texels at or above the material's cutoff is as near as it can be to the share level 0 has
//! (the α-test coverage Castaño preserves): one factor per region and level, the one that lifts (or
//! lowers) the right alpha byte just past the cutoff. Colours are premultiplied, so a texel's straight
//! colour stays; alphas clamp at 1. The chain is still filtered from the *unscaled* levels (the scale is
//! applied after the chain is built), so each level is the plain filter's result with one factor per
//! region.
//!
//! Regions are texel rectangles at level 0 (a leaf rect's outer area, mapped into every ancestor atlas;
//! a whole original texture); a texel belongs to the region its centre lies in, so disjoint regions never
//! share a texel. BLEND materials and opaque trees are never touched. Off by default (`--alpha-mips
//! plain`): the files stay byte-identical to builds without the knob.

use super::linear::LinearImage;

/// How alpha is carried through the mip levels of an alpha tree's atlases and original textures.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub enum AlphaMips {
    /// Alpha filtered like colour (coverage of alpha-tested texels thins or thickens with distance).
    #[default]
    Plain,
    /// Each MASK region's alpha rescaled per level to keep its level-0 α-test coverage.
    Coverage,
}

impl AlphaMips {
    pub const ALL: [AlphaMips; 2] = [AlphaMips::Plain, AlphaMips::Coverage];

    /// The lower-case name used on the command line and in sweep grids.
    pub fn name(self) -> &'static str {
        match self {
            AlphaMips::Plain => "plain",
            AlphaMips::Coverage => "coverage",
        }
    }
}

impl std::str::FromStr for AlphaMips {
    type Err = String;
    fn from_str(s: &str) -> Result<AlphaMips, String> {
        AlphaMips::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown alpha mips {s:?} (plain, coverage)"))
    }
}

/// One alpha-tested area of an image: `[x0, y0, x1, y1)` in level-0 texels (fractions allowed), and the
/// cutoff its texels are tested against.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CoverageRegion {
    pub rect: [f64; 4],
    pub cutoff: f32,
}

/// Half an 8-bit step: the scale aims this far past the cutoff so the stored byte passes (or fails) the
/// test as intended after rounding.
const HALF_STEP: f32 = 0.5 / 255.0;

/// Texel index range `[lo, hi)` along one axis whose centres `i + 0.5` lie in `[a, b)`, within `0..n`.
fn centres_in(a: f64, b: f64, n: u32) -> (u32, u32) {
    let clamp = |v: f64| v.clamp(0.0, f64::from(n)) as u32;
    (clamp((a - 0.5).ceil()), clamp((b - 0.5).ceil()))
}

/// The texel columns `[x0, x1)` and rows `[y0, y1)` of a `width × height` image whose centres lie in
/// `rect` (level-0 texels scaled by `scale` per axis).
fn region_span(
    (width, height): (u32, u32),
    rect: [f64; 4],
    scale: [f64; 2],
) -> ((u32, u32), (u32, u32)) {
    let xs = centres_in(rect[0] * scale[0], rect[2] * scale[0], width);
    let ys = centres_in(rect[1] * scale[1], rect[3] * scale[1], height);
    (xs, ys)
}

/// [`region_span`] as row ranges of indices into the image's data.
fn region_rows(
    (width, height): (u32, u32),
    rect: [f64; 4],
    scale: [f64; 2],
) -> impl Iterator<Item = std::ops::Range<usize>> {
    let ((x0, x1), (y0, y1)) = region_span((width, height), rect, scale);
    let w = width as usize;
    (y0..y1).map(move |y| y as usize * w + x0 as usize..y as usize * w + x1 as usize)
}

/// Regions with fewer texel centres than this at a level are measured and rescaled together with the
/// other small regions of the same cutoff (one factor for the pool): a handful of texels cannot show a
/// share (an area of 3 texels passes 0, 1/3, 2/3 or all).
const MIN_REGION_TEXELS: usize = 64;

/// The texels of every region of `group` in `img` at `scale`, row by row (the iterator holds the
/// image's size, not the image, so the image can be written while it runs).
fn group_rows<'r>(
    img: &LinearImage,
    group: &'r [&'r CoverageRegion],
    scale: [f64; 2],
) -> impl Iterator<Item = std::ops::Range<usize>> + 'r {
    let (size, len) = ((img.width, img.height), img.data.len());
    group
        .iter()
        .flat_map(move |r| region_rows(size, r.rect, scale))
        .filter(move |r| r.end <= len)
}

/// Texels of `group` in `img` at `scale` whose alpha is at or above `cutoff`, and all its texels.
fn passing(
    img: &LinearImage,
    group: &[&CoverageRegion],
    cutoff: f32,
    scale: [f64; 2],
) -> (usize, usize) {
    group_rows(img, group, scale).fold((0, 0), |(p, n), r| {
        let row = &img.data[r];
        (
            p + row.iter().filter(|t| t[3] >= cutoff).count(),
            n + row.len(),
        )
    })
}

/// The alpha factor that gives the texels of `group` (regions sharing `cutoff`) in `img` the share at or
/// above the cutoff nearest to `target` (`k = round(target · n)` of their `n` texels). Alphas are binned
/// by their stored byte (what the GPU tests), so only whole bins can pass: of the reachable counts the one
/// nearest `k` wins, the level's own count (factor 1) on a tie, else the larger. `None`: the level keeps
/// its alpha.
fn coverage_scale(
    img: &LinearImage,
    group: &[&CoverageRegion],
    cutoff: f32,
    scale: [f64; 2],
    target: f64,
) -> Option<f32> {
    // Per stored alpha byte: count, smallest and largest alpha.
    let mut bins = [(0usize, f32::INFINITY, 0.0f32); 256];
    let (mut n, mut passing) = (0usize, 0usize);
    for r in group_rows(img, group, scale) {
        for t in &img.data[r] {
            let a = t[3].clamp(0.0, 1.0);
            let bin = &mut bins[(a * 255.0 + 0.5) as usize];
            bin.0 += 1;
            bin.1 = bin.1.min(a);
            bin.2 = bin.2.max(a);
            n += 1;
            passing += usize::from(t[3] >= cutoff);
        }
    }
    if n == 0 {
        return None;
    }
    let k = (target * n as f64).round() as usize;
    // Candidates: everything from bin b up passes (b ≥ 1: zero alpha never does), or nothing does.
    let key = |count: usize| (count.abs_diff(k), count != passing, usize::MAX - count);
    let (mut best, mut best_bin, mut chosen) = (key(0), None::<usize>, 0);
    let mut above = 0usize;
    for b in (1..256).rev() {
        if bins[b].0 == 0 {
            continue;
        }
        above += bins[b].0;
        if key(above) < best {
            (best, best_bin, chosen) = (key(above), Some(b), above);
        }
    }
    if chosen == passing {
        return None;
    }
    let s = match best_bin {
        // Bin b's least alpha just past the cutoff.
        Some(b) => (cutoff + HALF_STEP) / bins[b].1,
        // Nothing passes: the most opaque texel just below the cutoff.
        None => {
            let max = bins.iter().rev().find(|x| x.0 > 0).map_or(0.0, |x| x.2);
            (cutoff - HALF_STEP).max(0.0) / max
        }
    };
    (s.is_finite() && s > 0.0).then_some(s)
}

/// Multiplies the alpha of `group`'s texels by `s` (clamped to 1), keeping each texel's straight colour.
fn scale_alpha(img: &mut LinearImage, group: &[&CoverageRegion], scale: [f64; 2], s: f32) {
    for r in group_rows(img, group, scale) {
        for t in &mut img.data[r] {
            let a = t[3];
            if a > 0.0 {
                let na = (a * s).min(1.0);
                let f = na / a;
                *t = [t[0] * f, t[1] * f, t[2] * f, na];
            }
        }
    }
}

/// Number of texel centres of `region` in a `w × h` level at `scale`.
fn texels_at(region: &CoverageRegion, w: u32, h: u32, scale: [f64; 2]) -> usize {
    let ((x0, x1), (y0, y1)) = region_span((w, h), region.rect, scale);
    x1.saturating_sub(x0) as usize * y1.saturating_sub(y0) as usize
}

/// Rescales the alpha of every level `≥ 1` of `levels` (a mip chain, level 0 first) so that each region's
/// α-test coverage is as near as it can be to its level 0's. A region with at least
/// [`MIN_REGION_TEXELS`] texels at a level gets a factor of its own; the smaller ones are pooled per
/// cutoff, with the pool's level-0 share as target. Level 0 is left as it is. Returns the number of
/// (region or pool, level) pairs rescaled.
pub fn preserve_coverage(levels: &mut [LinearImage], regions: &[CoverageRegion]) -> u64 {
    let Some((first, rest)) = levels.split_first_mut() else {
        return 0;
    };
    let (w0, h0) = (
        f64::from(first.width.max(1)),
        f64::from(first.height.max(1)),
    );
    // Level-0 (passing, texels) of every region.
    let base: Vec<(usize, usize)> = regions
        .iter()
        .map(|r| passing(first, &[r], r.cutoff, [1.0, 1.0]))
        .collect();
    let mut rescaled = 0;
    for level in rest.iter_mut() {
        let scale = [f64::from(level.width) / w0, f64::from(level.height) / h0];
        // Groups: each big region alone, the small ones pooled by cutoff.
        let mut groups: Vec<(f32, Vec<usize>)> = Vec::new();
        let mut pools: Vec<(u32, Vec<usize>)> = Vec::new();
        for (i, r) in regions.iter().enumerate() {
            if base[i].1 == 0 {
                continue;
            }
            match texels_at(r, level.width, level.height, scale) {
                0 => {}
                n if n >= MIN_REGION_TEXELS => groups.push((r.cutoff, vec![i])),
                _ => match pools.iter_mut().find(|p| p.0 == r.cutoff.to_bits()) {
                    Some(p) => p.1.push(i),
                    None => pools.push((r.cutoff.to_bits(), vec![i])),
                },
            }
        }
        groups.extend(pools.into_iter().map(|(c, m)| (f32::from_bits(c), m)));
        for (cutoff, members) in groups {
            let (passed, n) = members
                .iter()
                .fold((0, 0), |(p, n), &i| (p + base[i].0, n + base[i].1));
            let group: Vec<&CoverageRegion> = members.iter().map(|&i| &regions[i]).collect();
            let target = passed as f64 / n as f64;
            if let Some(s) = coverage_scale(level, &group, cutoff, scale, target) {
                scale_alpha(level, &group, scale, s);
                rescaled += 1;
            }
        }
    }
    rescaled
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::image_ops::MipChain;

    /// Share of `region`'s texels in `img` at or above its cutoff, with their number; `None` when it holds
    /// no texel centre.
    fn coverage(
        img: &LinearImage,
        region: &CoverageRegion,
        scale: [f64; 2],
    ) -> Option<(f64, usize)> {
        let (p, n) = passing(img, &[region], region.cutoff, scale);
        (n > 0).then(|| (p as f64 / n as f64, n))
    }

    /// A `side²` alpha-tested pattern like foliage: scattered opaque texels (one in `one_in`, by a hash
    /// of the position), transparent between, so plain box mips thin it out to nothing within a few
    /// levels.
    fn dots(side: u32, one_in: u32) -> LinearImage {
        let mut img = LinearImage::new_filled(side, side, [0.0; 4]);
        for y in 0..side {
            for x in 0..side {
                let h = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663))
                    .wrapping_mul(2_654_435_761);
                if (h >> 16) % one_in == 0 {
                    img.data[(y * side + x) as usize] = [0.8, 0.5, 0.2, 1.0];
                }
            }
        }
        img
    }

    fn whole(img: &LinearImage, cutoff: f32) -> CoverageRegion {
        CoverageRegion {
            rect: [0.0, 0.0, f64::from(img.width), f64::from(img.height)],
            cutoff,
        }
    }

    fn level_scale(level: &LinearImage, base: &LinearImage) -> [f64; 2] {
        [
            f64::from(level.width) / f64::from(base.width),
            f64::from(level.height) / f64::from(base.height),
        ]
    }

    #[test]
    fn plain_box_mips_lose_coverage_and_the_rescaled_ones_keep_it() {
        let base = dots(64, 5);
        let region = whole(&base, 0.5);
        let plain = MipChain::build(base.clone()).levels;
        let c0 = coverage(&plain[0], &region, [1.0; 2]).unwrap().0;
        assert!((0.15..0.25).contains(&c0), "{c0}");
        // Level 3 averages 8 × 8 texels, a fifth of them opaque: hardly any passes 0.5.
        let c3 = coverage(&plain[3], &region, level_scale(&plain[3], &base))
            .unwrap()
            .0;
        assert!(c3 < c0 / 4.0, "plain level 3 keeps {c3}");
        let mut kept = plain.clone();
        let n = preserve_coverage(&mut kept, std::slice::from_ref(&region));
        assert!(n >= 3, "rescaled {n} levels");
        for (l, level) in kept.iter().enumerate().skip(1) {
            let (c, count) = coverage(level, &region, level_scale(level, &base)).unwrap();
            if count >= 16 {
                // Whole alpha bytes pass or fail together: within 5 points of level 0's share.
                assert!((c - c0).abs() <= 0.05, "level {l}: {c} against {c0}");
            }
            // Straight colour unchanged wherever alpha is non-zero; alpha at most 1.
            for (a, b) in level.data.iter().zip(&plain[l].data) {
                if b[3] > 0.0 {
                    for k in 0..3 {
                        assert!((a[k] / a[3] - b[k] / b[3]).abs() < 1e-5);
                    }
                    assert!(a[3] <= 1.0);
                }
            }
        }
        assert_eq!(kept[0], plain[0], "level 0 untouched");
    }

    #[test]
    fn regions_are_rescaled_apart_and_texels_outside_stay() {
        // Left half: dots; right half: soft alpha 0.3 everywhere (never passes).
        let mut base = dots(64, 5);
        for y in 0..64 {
            for x in 32..64 {
                base.data[y * 64 + x] = [0.1, 0.1, 0.1, 0.3];
            }
        }
        let left = CoverageRegion {
            rect: [0.0, 0.0, 32.0, 64.0],
            cutoff: 0.5,
        };
        let c0 = coverage(&base, &left, [1.0; 2]).unwrap().0;
        let mut levels = MipChain::build(base.clone()).levels;
        let before = levels.clone();
        assert!(preserve_coverage(&mut levels, std::slice::from_ref(&left)) > 0);
        for (l, (a, b)) in levels.iter().zip(&before).enumerate() {
            for y in 0..a.height {
                for x in 0..a.width {
                    let i = (y * a.width + x) as usize;
                    // Texels whose centre is right of the middle are outside the region.
                    if (f64::from(x) + 0.5) * 64.0 / f64::from(a.width) >= 32.0 {
                        assert_eq!(a.data[i], b.data[i], "level {l} texel {x},{y}");
                    }
                }
            }
        }
        let c2 = coverage(&levels[2], &left, [0.25; 2]).unwrap().0;
        assert!((c2 - c0).abs() <= 0.05, "{c2} against {c0}");
    }

    #[test]
    fn coverage_zero_stays_zero_and_full_stays_full() {
        let soft = LinearImage::new_filled(16, 16, [0.2, 0.2, 0.2, 0.4]);
        let mut levels = MipChain::build(soft).levels;
        let before = levels.clone();
        assert_eq!(preserve_coverage(&mut levels, &[whole(&before[0], 0.5)]), 0);
        assert_eq!(levels, before);
        let solid = LinearImage::new_filled(16, 16, [0.2, 0.2, 0.2, 1.0]);
        let mut levels = MipChain::build(solid).levels;
        let before = levels.clone();
        assert_eq!(preserve_coverage(&mut levels, &[whole(&before[0], 0.5)]), 0);
        assert_eq!(levels, before);
    }

    #[test]
    fn names_round_trip() {
        for m in AlphaMips::ALL {
            assert_eq!(m.name().parse::<AlphaMips>(), Ok(m));
        }
        assert!("fancy".parse::<AlphaMips>().is_err());
    }
}
