//! The mean colour of each texture rectangle of a stored leaf atlas (docs/DESIGN.md "Repeats: one period
//! per rect, wrapped in the shader"): what a pixel that covers a whole period of a repeated texture shows.
//!
//! The shader used to read it from the atlas's mips, at the rect's centre on the mip where the rect is
//! two texels wide; those texels are blocks aligned to the atlas, not to the rect, so it read the
//! middle half of the period where the rect sat off the block grid (a 64-texel period of black with
//! white edge lines drew black where its mean is grey; a 32 %-coverage alpha-tested sprite drew solid,
//! since its middle is opaque). The mean is a per-rect constant, so it is measured once, here, from the
//! bytes the file stores: a build and the merge of a sharded build, which both write through
//! [`crate::store::FileWriter`], measure the same bytes and store the same means.
//!
//! A rect is measured on level [`MEAN_LEVEL`] where it covers whole texels of it (16 times fewer than
//! level 0, decoded where compressed; each the box mean of 4 × 4 texels of level 0) and on level 0 in the
//! strips along its edges that cover level-2 texels in part (decoding only the blocks under them), so
//! the mean is the level-0 mean but for 8-bit rounding and compression error of level 2 (a measurement
//! of level-2 texels weighted by their overlap read up to 16 sRGB levels of border into 65–129-texel
//! rects; fault hunt). Every rect of the alpha tree, whose mips may keep α-test coverage instead of the
//! mean, is measured on level 0. Averaged in linear light with premultiplied alpha, as the mips are;
//! stored as sRGB8 with straight alpha.

use super::{TexFormat, decode_level_rect, mip_sizes};
use crate::util::srgb::{linear_to_srgb8, srgb8_to_linear};

/// The level the means are measured on where a rect covers whole texels of it (level 0 alone where the
/// chain has no such level, or its side is not a quarter of level 0's).
pub const MEAN_LEVEL: usize = 2;

/// [`srgb8_to_linear`] of every 8-bit code.
static TO_LINEAR: std::sync::LazyLock<[f64; 256]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|c| srgb8_to_linear(c as u8)));

/// Weighted sums over texels: `[Σ w·a·c (r, g, b), Σ w·a, Σ w, Σ w·c (r, g, b)]`, colour in linear light.
type Sums = [f64; 8];

/// The sums of the `[x0, x1) × [y0, y1)` texels (fractional, in texels of the level) of a `w × h` RGBA8
/// sRGB straight-alpha level, each weighted by its overlap times `weight`.
fn area_sums(rgba: &[u8], w: u32, h: u32, area: [f64; 4], weight: f64) -> Sums {
    let lut = &*TO_LINEAR;
    let [x0, y0, x1, y1] = area;
    let (w, h) = (w as usize, h as usize);
    let span = |lo: f64, hi: f64, n: usize| {
        let a = lo.floor().max(0.0) as usize;
        let b = (hi.ceil().max(0.0) as usize).min(n);
        (a, b)
    };
    let overlap = |i: usize, lo: f64, hi: f64| (hi.min(i as f64 + 1.0) - lo.max(i as f64)).max(0.0);
    let ((xa, xb), (ya, yb)) = (span(x0, x1, w), span(y0, y1, h));
    let mut sum = [0.0f64; 8];
    for y in ya..yb {
        let wy = weight * overlap(y, y0, y1);
        for x in xa..xb {
            let wt = wy * overlap(x, x0, x1);
            let Some(t) = rgba.get((y * w + x) * 4..(y * w + x) * 4 + 4) else {
                continue;
            };
            let a = f64::from(t[3]) / 255.0;
            for k in 0..3 {
                let c = lut[usize::from(t[k])];
                sum[k] += wt * a * c;
                sum[5 + k] += wt * c;
            }
            sum[3] += wt * a;
            sum[4] += wt;
        }
    }
    sum
}

/// The mean the sums give: linear premultiplied colour over coverage, straight alpha; without coverage
/// the straight colour mean with alpha 0; without any texel, transparent black.
fn mean_of(sum: &Sums) -> [u8; 4] {
    if sum[4] <= 0.0 {
        return [0; 4];
    }
    let colour = |k: usize| {
        if sum[3] > 0.0 {
            linear_to_srgb8(sum[k] / sum[3])
        } else {
            linear_to_srgb8(sum[5 + k] / sum[4])
        }
    };
    let alpha = (sum[3] / sum[4] * 255.0).round().clamp(0.0, 255.0) as u8;
    [colour(0), colour(1), colour(2), alpha]
}

/// The mean of the `[x0, x1) × [y0, y1)` texels (fractional, in texels of the level) of a `w × h` RGBA8
/// sRGB straight-alpha level: linear premultiplied colour over coverage, straight alpha; texels weighted by
/// their overlap. An area without coverage gives its straight colour mean with alpha 0; an empty area or
/// one outside the level, transparent black.
pub fn area_mean(rgba: &[u8], w: u32, h: u32, area: [f64; 4]) -> [u8; 4] {
    mean_of(&area_sums(rgba, w, h, area, 1.0))
}

/// The mean ([`area_mean`]) of each inner rectangle `[x, y, w, h]` (level-0 texels) of the leaf atlas
/// `chain`: a `side²` image and its mip chain stored in `format`, level 0 first. `exact`: every rect on
/// level 0 — the alpha tree's, whose level 2 may hold alpha rescaled to keep α-test coverage
/// (`--alpha-mips coverage`), not the mean that decides whether a distant sprite is drawn. `None` where
/// `chain` is not the chain of `side` (a block of another length).
pub fn rect_means(
    format: TexFormat,
    chain: &[u8],
    side: u32,
    inners: &[[u32; 4]],
    exact: bool,
) -> Option<Vec<[u8; 4]>> {
    if chain.len() as u64 != format.chain_bytes(side) {
        return None;
    }
    let sizes: Vec<u32> = mip_sizes(side).collect();
    let level_bytes = |l: usize| -> Option<&[u8]> {
        let offset: u64 = sizes[..l].iter().map(|&s| format.level_bytes(s)).sum();
        let bytes = chain.get(usize::try_from(offset).ok()?..)?;
        bytes.get(..usize::try_from(format.level_bytes(sizes[l])).ok()?)
    };
    let fine = level_bytes(0)?;
    // Level 2, where its texels are exactly 4 × 4 texels of level 0 (the box mip filter of a side that
    // is a multiple of 4), decoded once. With `--filter kaiser` they are not (the kernel reaches ~12
    // level-0 texels further, within the default border of 16, and keeps the mean but for its clamped
    // ringing): the means are then close, not exact.
    let coarse = match sizes.get(MEAN_LEVEL) {
        Some(&s) if !exact && side.is_multiple_of(4) && s * 4 == side => {
            Some(decode_level_rect(format, level_bytes(MEAN_LEVEL)?, s, s))
        }
        _ => None,
    };
    let level0 = |[x, y, w, h]: [u32; 4]| -> Sums {
        if w == 0 || h == 0 {
            return [0.0; 8];
        }
        let (rgba, [bx, by, bw, bh]) = decode_blocks(format, fine, side, [x, y, w, h]);
        let [x, y, w, h, bx, by] = [x, y, w, h, bx, by].map(f64::from);
        let area = [x - bx, y - by, x + w - bx, y + h - by];
        area_sums(&rgba, bw, bh, area, 1.0)
    };
    let means = inners.iter().map(|&[x, y, w, h]| {
        // The part of the rect on whole level-2 texels, and the strips around it on level 0.
        let (ax0, ay0) = (x.div_ceil(4) * 4, y.div_ceil(4) * 4);
        let (ax1, ay1) = ((x + w) / 4 * 4, (y + h) / 4 * 4);
        let Some(rgba) = coarse.as_ref().filter(|_| ax1 > ax0 && ay1 > ay0) else {
            return mean_of(&level0([x, y, w, h]));
        };
        let s = side / 4;
        let inner = [ax0, ay0, ax1, ay1].map(|v| f64::from(v / 4));
        let mut sum = area_sums(rgba, s, s, inner, 16.0);
        let strips = [
            [x, y, w, ay0 - y],
            [x, ay1, w, y + h - ay1],
            [x, ay0, ax0 - x, ay1 - ay0],
            [ax1, ay0, x + w - ax1, ay1 - ay0],
        ];
        for strip in strips {
            for (a, b) in sum.iter_mut().zip(level0(strip)) {
                *a += b;
            }
        }
        mean_of(&sum)
    });
    Some(means.collect())
}

/// The texels of the 4×4 blocks (texels for RGBA8) of a `side²` level under `[x, y, w, h]`, clipped to
/// the level: RGBA8 rows and their rectangle `[x, y, w, h]` in the level.
fn decode_blocks(
    format: TexFormat,
    level: &[u8],
    side: u32,
    [x, y, w, h]: [u32; 4],
) -> (Vec<u8>, [u32; 4]) {
    let step = if format == TexFormat::Rgba8 { 1 } else { 4 };
    let x0 = (x / step * step).min(side);
    let y0 = (y / step * step).min(side);
    let x1 = x.saturating_add(w).min(side).div_ceil(step) * step;
    let y1 = y.saturating_add(h).min(side).div_ceil(step) * step;
    let (bw, bh) = ((x1 - x0) as usize, (y1 - y0) as usize);
    let mut out = vec![0u8; bw * bh * 4];
    if format == TexFormat::Rgba8 {
        for row in 0..bh {
            let at = ((y0 as usize + row) * side as usize + x0 as usize) * 4;
            if let Some(src) = level.get(at..at + bw * 4) {
                out[row * bw * 4..(row + 1) * bw * 4].copy_from_slice(src);
            }
        }
    } else {
        let bb = format.bytes_per_block() as usize;
        let blocks_per_row = side.div_ceil(4) as usize;
        let pitch = bw * 4;
        for by in (y0 / 4) as usize..(y1 / 4) as usize {
            for bx in (x0 / 4) as usize..(x1 / 4) as usize {
                let at = (by * blocks_per_row + bx) * bb;
                let Some(block) = level.get(at..at + bb) else {
                    continue;
                };
                let dst = &mut out[((by * 4 - y0 as usize) * bw + (bx * 4 - x0 as usize)) * 4..];
                match format {
                    TexFormat::Bc1 => bcdec_rs::bc1(block, dst, pitch),
                    TexFormat::Bc3 => bcdec_rs::bc3(block, dst, pitch),
                    TexFormat::Bc7 => bcdec_rs::bc7(block, dst, pitch),
                    TexFormat::Rgba8 => {}
                }
            }
        }
    }
    // Texels past the level (a level whose side is not a multiple of 4) are cut off by `area_mean`'s
    // rectangle, which lies inside the level.
    (out, [x0, y0, bw as u32, bh as u32])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Level 2 with level-0 strips, and level 0 alone (`exact`), give the mean of the decoded level 0
    /// on RGBA8, BC1 and BC7 chains, for rects aligned and not to level 2's texels: exactly on level 0,
    /// within the rounding and compression error of level 2 otherwise.
    #[test]
    fn rect_means_agree_with_the_decoded_level_0() {
        use crate::preprocess::image_ops::{LinearImage, MipChain};
        let side = 256u32;
        let mut rng = crate::util::XorShift64::new(7);
        let pixels = (0..side * side)
            .map(|i| {
                let (x, y) = (i % side, i / side);
                let n = (rng.next_u64() % 24) as u8;
                [
                    (x / 2) as u8 + n,
                    (y / 2) as u8,
                    ((x ^ y) & 0xff) as u8 / 2 + n,
                    255,
                ]
            })
            .collect();
        let img = crate::scene::DecodedImage {
            width: side,
            height: side,
            pixels,
        };
        let rgba_chain = MipChain::build(LinearImage::from_decoded(&img).unwrap()).to_rgba8();
        let inners = [
            [3, 5, 70, 90],
            [17, 130, 9, 13],
            [200, 200, 56, 56],
            [1, 1, 1, 1],
        ];
        for format in [TexFormat::Rgba8, TexFormat::Bc1, TexFormat::Bc7] {
            let chain = crate::texfmt::encode_chain(format, &rgba_chain, side, 4)
                .unwrap()
                .bytes;
            let level0 = &chain[..format.level_bytes(side) as usize];
            let fine = crate::texfmt::decode_level(format, level0, side);
            for exact in [false, true] {
                let means = rect_means(format, &chain, side, &inners, exact).unwrap();
                for (inner, got) in inners.iter().zip(means) {
                    let [x, y, w, h] = inner.map(f64::from);
                    let want = area_mean(&fine, side, side, [x, y, x + w, y + h]);
                    let tol = if exact { 0 } else { 2 };
                    let diff = got.iter().zip(want).map(|(a, b)| a.abs_diff(b)).max();
                    assert!(
                        diff <= Some(tol),
                        "{format:?} exact {exact} {inner:?}: {got:?} vs {want:?}"
                    );
                }
            }
        }
        assert!(rect_means(TexFormat::Bc1, &[0; 9], side, &inners, false).is_none());
    }

    #[test]
    fn area_means_weigh_by_overlap_coverage_and_light() {
        // 4×1: black opaque, white opaque, red transparent, grey half.
        let rgba = [
            0, 0, 0, 255, 255, 255, 255, 255, 255, 0, 0, 0, 128, 128, 128, 128,
        ];
        // Black and white in linear light: 0.5 linear is sRGB 188, not 128.
        let grey = linear_to_srgb8(0.5);
        assert_eq!(
            area_mean(&rgba, 4, 1, [0.0, 0.0, 2.0, 1.0]),
            [grey, grey, grey, 255]
        );
        // A quarter of white and three quarters of black: linear 0.25.
        assert_eq!(
            area_mean(&rgba, 4, 1, [0.25, 0.0, 1.25, 1.0])[0],
            linear_to_srgb8(0.25)
        );
        // The transparent texel adds no colour, only weight to alpha.
        assert_eq!(
            area_mean(&rgba, 4, 1, [1.0, 0.0, 3.0, 1.0]),
            [255, 255, 255, 128]
        );
        // No coverage at all: the straight colour, alpha 0.
        assert_eq!(area_mean(&rgba, 4, 1, [2.0, 0.0, 3.0, 1.0]), [255, 0, 0, 0]);
        // Outside or empty: transparent black.
        assert_eq!(area_mean(&rgba, 4, 1, [5.0, 0.0, 6.0, 1.0]), [0; 4]);
        assert_eq!(area_mean(&rgba, 4, 1, [1.0, 0.0, 1.0, 1.0]), [0; 4]);
    }
}
