//! A leaf atlas's level 0 drawn, halved and encoded band by band (issue 26,
//! docs/DESIGN.md "Build throughput"): the rects of a leaf ([`RectPlan`]) fill a band of rows in a small
//! f32 buffer, which is halved into level 1 and encoded to RGBA8 while it is still in the cache, so the
//! 16 bytes a texel of a whole f32 level 0 are never written to memory, nor read back twice (the encode
//! and the halving of a 1024² level each read 16 MiB). Every texel is the value the whole-level path gives: a rect's row
//! depends on its own `y` alone, the rects are drawn in the same order, the halving sums each 2×2 box
//! in the same order ([`super::mip::halve_row_pair`]) and the encoding is per texel until the colour
//! bleed, which runs afterwards over the whole level as it does there.

use super::linear::{LinearImage, bleed_into_transparent, encode_texels};
use super::mip::halve_row_pair;
use super::raster::RectPlan;
use super::srgb::Encoder;
use rayon::prelude::*;

/// Rows of level 0 a band holds: 32 rows of a 1024² atlas are 512 KiB of f32 RGBA, well inside a core's
/// L2; even, so a band halves into whole rows of level 1.
pub(super) const BAND_ROWS: usize = 32;

/// Level 0 of a leaf atlas as stored, and level 1 in linear light: what the rest of its chain and its
/// parent are made from.
pub struct BandedLevels {
    /// Level 0 as RGBA8 (sRGB, straight alpha, colour bled into transparent texels).
    pub rgba0: Vec<u8>,
    /// Whether level 0 had a transparent texel, so colour was bled into it (`to_rgba8_into`'s answer).
    pub bled: bool,
    /// Level 1, the 2×2 box of level 0.
    pub level1: LinearImage,
}

/// Level 0 of a `size × size` atlas filled with `fill` and then `rects` drawn in order, stored as RGBA8,
/// and its level 1: the bytes and values of `draw_rect` of every rect into a filled level, `halve` and
/// `to_rgba8_into`. `None` where `size` is odd or 0 (the caller draws the whole level).
pub fn draw_leaf_banded(size: u32, fill: [f32; 4], rects: &[RectPlan<'_>]) -> Option<BandedLevels> {
    let n = size as usize;
    if n == 0 || !n.is_multiple_of(2) {
        return None;
    }
    let band = BAND_ROWS.min(n);
    let half = n / 2;
    let mut rgba0 = vec![0u8; n * n * 4];
    let mut level1 = LinearImage::new_filled(size / 2, size / 2, [0.0; 4]);
    let enc = Encoder::get();
    let transparent = rgba0
        .par_chunks_mut(band * n * 4)
        .zip(level1.data.par_chunks_mut(band / 2 * half))
        .enumerate()
        .map_init(Vec::new, |buf: &mut Vec<[f32; 4]>, (b, (px, halves))| {
            let y0 = b * band;
            let rows = (px.len() / (4 * n)).min(band);
            buf.clear();
            buf.resize(rows * n, fill);
            for rect in rects {
                let r = rect.rows();
                for y in r.start.max(y0)..r.end.min(y0 + rows) {
                    rect.fill_row(y, &mut buf[(y - y0) * n..(y - y0 + 1) * n]);
                }
            }
            for (j, dst) in halves.chunks_exact_mut(half).enumerate() {
                let (r0, r1) = (2 * j * n, (2 * j + 1) * n);
                halve_row_pair(&buf[r0..r1], &buf[r1..r1 + n], dst);
            }
            encode_texels(enc, buf, px)
        })
        .reduce(|| false, |a, b| a | b);
    if transparent {
        bleed_into_transparent(&mut rgba0, n, n);
    }
    Some(BandedLevels {
        rgba0,
        bled: transparent,
        level1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::image_ops::{MipChain, RectJob, draw_rect, halve};
    use crate::scene::Wrap;

    /// A source with every texel different, alpha varying (some 0), so encoding, bleed and filtering are
    /// all exercised.
    fn source(w: u32, h: u32, seed: u32) -> MipChain {
        let mut img = LinearImage::new_filled(w, h, [0.0; 4]);
        for (i, t) in img.data.iter_mut().enumerate() {
            let v = (i as u32).wrapping_mul(2654435761).wrapping_add(seed);
            let a = if v.is_multiple_of(7) {
                0.0
            } else {
                (v >> 8 & 255) as f32 / 255.0
            };
            let c = |s: u32| (v >> s & 255) as f32 / 255.0 * a;
            *t = [c(0), c(16), c(24), a];
        }
        MipChain::build(img)
    }

    fn job(outer: [u32; 4], uv: [f64; 4], wrap: Wrap) -> RectJob {
        RectJob {
            outer,
            inner: [outer[0] + 2, outer[1] + 2, outer[2] - 4, outer[3] - 4],
            uv_min: [uv[0], uv[1]],
            uv_max: [uv[2], uv[3]],
            wrap: [wrap, Wrap::ClampToEdge],
            factor: [1.0, 0.8, 0.9, 1.0],
        }
    }

    #[test]
    fn banded_levels_are_the_whole_level_drawn_halved_and_encoded() {
        let (a, b) = (source(37, 20, 1), source(64, 64, 9));
        // Overlapping rects, rows across band edges, magnified and minified, one in the last band.
        let jobs = [
            (job([3, 5, 40, 50], [0.0, 0.0, 1.0, 1.0], Wrap::Repeat), &a),
            (
                job([30, 20, 60, 33], [-2.5, 0.1, 3.0, 0.9], Wrap::Repeat),
                &b,
            ),
            (
                job([0, 90, 128, 38], [0.2, 0.0, 0.7, 1.0], Wrap::MirroredRepeat),
                &b,
            ),
            (
                job([100, 0, 28, 120], [0.0, 0.0, 4.0, 1.0], Wrap::Repeat),
                &a,
            ),
        ];
        // Four whole bands; three and a short one (100 = 3 · 32 + 4); one band and a short one; one short.
        for (fill, size) in [
            ([0.2, 0.2, 0.2, 1.0], 128),
            ([0.0; 4], 128),
            ([0.0; 4], 100),
            ([0.2, 0.2, 0.2, 1.0], 34),
            ([0.0; 4], 6),
        ] {
            // The jobs scaled to the atlas (inner at least one texel).
            let fit = |j: &RectJob| {
                let s = |v: u32| v * size / 128;
                let [x, y, w, h] = j.outer;
                let outer = [s(x), s(y), s(w).max(5), s(h).max(5)];
                let outer = [
                    outer[0].min(size - outer[2]),
                    outer[1].min(size - outer[3]),
                    outer[2],
                    outer[3],
                ];
                RectJob {
                    outer,
                    inner: [outer[0] + 2, outer[1] + 2, outer[2] - 4, outer[3] - 4],
                    ..j.clone()
                }
            };
            let jobs: Vec<(RectJob, &MipChain)> =
                jobs.iter().map(|(j, src)| (fit(j), *src)).collect();
            let mut whole = LinearImage::new_filled(size, size, fill);
            for (j, src) in &jobs {
                draw_rect(&mut whole, j, src).unwrap();
            }
            let mut rgba = vec![0u8; whole.texel_count() * 4];
            let bled = whole.to_rgba8_into(&mut rgba);
            let plans: Vec<RectPlan<'_>> = jobs
                .iter()
                .map(|(j, src)| RectPlan::new(size, size, j, src).unwrap())
                .collect();
            let banded = draw_leaf_banded(size, fill, &plans).unwrap();
            if fill[3] == 0.0 && size >= 100 {
                assert!(bled, "the transparent fill is left between the rects");
            }
            assert_eq!(banded.bled, bled);
            assert_eq!(banded.rgba0, rgba);
            let bits = |l: &LinearImage| {
                l.data
                    .iter()
                    .flatten()
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&banded.level1), bits(&halve(&whole)));
        }
    }

    #[test]
    fn an_opaque_level_is_not_bled_and_odd_sizes_are_left_to_the_caller() {
        let plans: [RectPlan<'_>; 0] = [];
        let fill = [0.5, 0.25, 0.125, 1.0];
        let banded = draw_leaf_banded(8, fill, &plans).unwrap();
        assert!(!banded.bled);
        assert_eq!(banded.rgba0, LinearImage::new_filled(8, 8, fill).to_rgba8());
        assert_eq!((banded.level1.width, banded.level1.height), (4, 4));
        assert!(banded.level1.data.iter().all(|t| *t == fill));
        assert!(draw_leaf_banded(7, [0.0; 4], &plans).is_none());
        assert!(draw_leaf_banded(0, [0.0; 4], &plans).is_none());
    }
}
