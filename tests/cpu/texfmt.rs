//! Block compression (issue 9): encode/decode round trips on real textures with PSNR floors per format, and
//! the no-bleeding property of compressed atlases (which mip levels a 4×4 block can mix two textures at).

use atlastree::preprocess::image_ops::{
    LinearImage, MipChain, RectJob, combine_quadrants, draw_rect, mip_chain_rgba8, neutral_fill,
    resample_square,
};
use atlastree::scene::{DecodedImage, Wrap};
use atlastree::texfmt::{
    TexFormat, decode_chain, decode_level, encode_chain, encode_level, mip_sizes, psnr, sse_rgba8,
};
use std::path::PathBuf;

fn load(name: &str) -> DecodedImage {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data/city/textures")
        .join(name);
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8();
    DecodedImage {
        width: img.width(),
        height: img.height(),
        pixels: img.pixels().map(|p| p.0).collect(),
    }
}

/// Opaque city textures with real detail (photos, facades, paving, roof, concrete, asphalt).
const OPAQUE: [&str; 8] = [
    "c00000_photo.jpg",
    "c00001_photo.jpg",
    "c00005_concrete.png",
    "c00006_paving.png",
    "c00007_roof.png",
    "c00008_facade.png",
    "c00011_facade.png",
    "asphalt.png",
];
/// City textures with alpha (fences, trees).
const ALPHA: [&str; 4] = [
    "c00002_fence.png",
    "c00003_tree.png",
    "c00009_fence.png",
    "c00010_tree.png",
];

/// PSNR floors (dB, 8-bit sRGB, full mip chain of a 256² resample) per format, opaque (RGB) and alpha
/// (RGBA). Measured minimums over the textures above (printed by the test): BC1 34.9, BC7 51.7 (RGB);
/// BC3 39.1, BC7 45.6 (RGBA). The floors sit about 3 dB below.
const FLOOR_BC1_RGB: f64 = 32.0;
const FLOOR_BC7_RGB: f64 = 48.0;
const FLOOR_BC3_RGBA: f64 = 36.0;
const FLOOR_BC7_RGBA: f64 = 42.0;

fn chain_of(name: &str, size: u32) -> Vec<u8> {
    let lin = resample_square(&load(name), size, [Wrap::Repeat; 2]).unwrap();
    mip_chain_rgba8(&lin)
}

/// Encodes, checks the recorded error against an independent decode, returns the PSNR.
fn round_trip(format: TexFormat, chain: &[u8], size: u32, channels: usize) -> f64 {
    let enc = encode_chain(format, chain, size, channels).unwrap();
    assert_eq!(enc.bytes.len() as u64, format.chain_bytes(size));
    let dec = decode_chain(format, &enc.bytes, size).unwrap();
    assert_eq!(dec.len(), chain.len());
    assert_eq!(sse_rgba8(chain, &dec, channels), enc.sse, "{format:?}");
    if channels == 3 {
        // BC7 mode 6 stores alpha with 7 bits + a p-bit shared with RGB, so an opaque block may decode to
        // alpha 254; the opaque pass ignores alpha (tree.wgsl writes 1.0).
        assert!(
            dec.chunks_exact(4).all(|p| p[3] >= 254),
            "{format:?}: opaque stays opaque"
        );
    }
    psnr(enc.sse, enc.samples)
}

#[test]
fn round_trip_psnr_floors_on_city_textures() {
    let size = 256;
    let mut worst = [f64::INFINITY; 4];
    for name in OPAQUE {
        let chain = chain_of(name, size);
        let bc1 = round_trip(TexFormat::Bc1, &chain, size, 3);
        let bc7 = round_trip(TexFormat::Bc7, &chain, size, 3);
        let rgba = round_trip(TexFormat::Rgba8, &chain, size, 3);
        eprintln!("{name}: BC1 {bc1:.2} dB, BC7 {bc7:.2} dB");
        assert_eq!(
            rgba,
            atlastree::texfmt::PSNR_CAP_DB,
            "RGBA8 is lossless (the PSNR cap)"
        );
        assert!(bc7 > bc1, "{name}: BC7 ({bc7:.2}) beats BC1 ({bc1:.2})");
        worst[0] = worst[0].min(bc1);
        worst[1] = worst[1].min(bc7);
    }
    for name in ALPHA {
        let chain = chain_of(name, size);
        assert!(
            chain.chunks_exact(4).any(|p| p[3] < 128) && chain.chunks_exact(4).any(|p| p[3] > 128),
            "{name} has real alpha"
        );
        let bc3 = round_trip(TexFormat::Bc3, &chain, size, 4);
        let bc7 = round_trip(TexFormat::Bc7, &chain, size, 4);
        eprintln!("{name}: BC3 {bc3:.2} dB, BC7 {bc7:.2} dB (RGBA)");
        worst[2] = worst[2].min(bc3);
        worst[3] = worst[3].min(bc7);
    }
    eprintln!(
        "minimum PSNR: BC1 {:.2}, BC7 {:.2} (RGB); BC3 {:.2}, BC7 {:.2} (RGBA)",
        worst[0], worst[1], worst[2], worst[3]
    );
    assert!(worst[0] >= FLOOR_BC1_RGB, "BC1 {:.2}", worst[0]);
    assert!(worst[1] >= FLOOR_BC7_RGB, "BC7 {:.2}", worst[1]);
    assert!(worst[2] >= FLOOR_BC3_RGBA, "BC3 {:.2}", worst[2]);
    assert!(worst[3] >= FLOOR_BC7_RGBA, "BC7 alpha {:.2}", worst[3]);
}

#[test]
fn noise_is_harder_than_photos_but_bounded() {
    // Uniform white noise is the worst case of block compression (no correlation within a block). The
    // floor is what any encoder gets by storing each 4×4 block as its mean colour (~11 dB on uniform
    // noise, computed below): BC1's four colours along a line and BC7's partitions must beat it by a
    // margin, so an encoder that drops every block's detail fails (random endpoints would give ~8 dB).
    let size = 64u32;
    let mut rng = atlastree::util::XorShift64::new(0x9E37_79B9_7F4A_7C15);
    let level: Vec<u8> = (0..size * size * 4)
        .map(|i| {
            let h = rng.next_u64();
            if i % 4 == 3 { 255 } else { (h >> 24) as u8 }
        })
        .collect();
    let flat = block_means(&level, size);
    let flat_db = psnr(sse_rgba8(&level, &flat, 3), u64::from(size * size) * 3);
    eprintln!("noise, each block its mean colour: {flat_db:.2} dB");
    assert!(
        (10.5..11.5).contains(&flat_db),
        "uniform noise's block-mean PSNR {flat_db:.2} dB"
    );
    // Measured: block means 11.06 dB, BC1 13.63 dB, BC7 16.71 dB.
    for (f, margin) in [(TexFormat::Bc1, 2.0), (TexFormat::Bc7, 4.5)] {
        let enc = encode_level(f, &level, size, false);
        let dec = decode_level(f, &enc, size);
        let p = psnr(sse_rgba8(&level, &dec, 3), u64::from(size * size) * 3);
        eprintln!("noise {f:?}: {p:.2} dB");
        assert!(
            p >= flat_db + margin,
            "{f:?}: {p:.2} dB, not {margin} dB above the block means' {flat_db:.2} dB"
        );
    }
}

/// `level` (RGBA8, `size`², a multiple of 4) with every texel of each 4×4 block set to the block's mean
/// colour (rounded): the best a codec that stores one colour per block can do.
fn block_means(level: &[u8], size: u32) -> Vec<u8> {
    let s = size as usize;
    let mut out = level.to_vec();
    for by in (0..s).step_by(4) {
        for bx in (0..s).step_by(4) {
            let texels = || (by..by + 4).flat_map(|y| (bx..bx + 4).map(move |x| (y * s + x) * 4));
            for c in 0..4 {
                let sum: u32 = texels().map(|i| u32::from(level[i + c])).sum();
                let mean = ((sum + 8) / 16) as u8;
                texels().for_each(|i| out[i + c] = mean);
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------------------
// Bleeding (the analysis in src/texfmt.rs). Packing aligns outer rectangles, and so the inner edges, to 4
// texels; the border is `b` texels (16 by default, the paper's 8 as the thin case). Measured in level-0
// texels past the inner edge:
//   - a level-L texel overlapping the inner rect starts at most (2^L − 4)⁺ outside it (box filter), so
//     uncompressed, level L is independent of the neighbours while (2^L − 4)⁺ ≤ b: levels 0–3 at b = 8,
//     0–4 at b = 16;
//   - a 4×4 block of level L holding such a texel starts at most 4·(2^L − 1) outside it (0, 4, 12, 28 …),
//     so compressed, the blocks that touch the inner rect hold only its own texels while
//     4·(2^L − 1) ≤ b: levels 0–1 at b = 8, 0–2 at b = 16. Past those levels, texels within 3 texels of
//     the inner edge can change with the neighbour.
// An inner atlas at height h above the leaves shows leaf level h + L at its level L, so at b = 8 "levels
// 0–1" means: leaf atlases' levels 0 and 1, and their parents' level 0.

/// The last level whose texels touching the inner rect are independent of the neighbours at border `b`:
/// uncompressed and block-compressed (see above).
fn independent_levels(border: u32, compressed: bool) -> u32 {
    let reach = |l: u32| {
        if compressed {
            4 * ((1 << l) - 1)
        } else {
            (1u32 << l).saturating_sub(4)
        }
    };
    (0..16).take_while(|&l| reach(l) <= border).last().unwrap()
}

/// Adjacent 4-aligned outer rects (worst case: no gap) with an 8-texel border, inside a 256² atlas.
fn layout() -> Vec<([u32; 4], [u32; 4])> {
    layout_with_border(8)
}

/// [`layout`] with a `border`-texel border.
fn layout_with_border(border: u32) -> Vec<([u32; 4], [u32; 4])> {
    let widths = [44u32, 60, 36, 100];
    let heights = [52u32, 76, 40, 84];
    let mut rects = Vec::new();
    let mut y = 0;
    for (j, &h) in heights.iter().enumerate() {
        let mut x = 0;
        for i in 0..widths.len() {
            let w = widths[(i + j) % widths.len()];
            let outer = [x, y, w, h];
            let inner = [x + border, y + border, w - 2 * border, h - 2 * border];
            rects.push((outer, inner));
            x += w;
        }
        y += h;
    }
    rects
}

/// A detailed, strongly tinted texture: texture `k` is photo `k % 8` with its colour channels rotated, so
/// neighbours contrast in hue as well as in structure.
fn tinted(k: usize, invert: bool) -> MipChain {
    let img = load(OPAQUE[k % OPAQUE.len()]);
    let lin = resample_square(&img, 64, [Wrap::Repeat; 2]).unwrap();
    let mut out = LinearImage::new_filled(64, 64, [0.0; 4]);
    for y in 0..64 {
        for x in 0..64 {
            let p = lin.get(x, y).unwrap();
            let mut c = [p[k % 3], p[(k + 1) % 3] * 0.2, p[(k + 2) % 3] * 0.05, 1.0];
            if invert {
                c = [1.0 - c[0], 1.0 - c[1], 1.0 - c[2], 1.0];
            }
            out.set(x, y, c).unwrap();
        }
    }
    MipChain::build(out)
}

/// The leaf atlas with every rect drawn; rect `keep` always from its own texture, the others inverted when
/// `invert_others`.
fn atlas(rects: &[([u32; 4], [u32; 4])], keep: usize, invert_others: bool) -> LinearImage {
    let mut atlas = LinearImage::new_filled(256, 256, [0.2140, 0.2140, 0.2140, 1.0]);
    for (k, &(outer, inner)) in rects.iter().enumerate() {
        let src = tinted(k, invert_others && k != keep);
        let job = RectJob {
            outer,
            inner,
            uv_min: [0.0; 2],
            uv_max: [1.0; 2],
            wrap: [Wrap::Repeat; 2],
            factor: [1.0; 4],
        };
        draw_rect(&mut atlas, &job, &src).unwrap();
    }
    atlas
}

/// Per level: decoded RGBA8 of a stored chain.
fn levels(format: TexFormat, chain_rgba: &[u8], size: u32) -> Vec<Vec<u8>> {
    let enc = encode_chain(format, chain_rgba, size, 3).unwrap();
    let dec = decode_chain(format, &enc.bytes, size).unwrap();
    let mut out = Vec::new();
    let mut off = 0;
    for s in mip_sizes(size) {
        let n = (s * s * 4) as usize;
        out.push(dec[off..off + n].to_vec());
        off += n;
    }
    out
}

/// Texels of level `l` that overlap the inner rect (in level-0 texels).
fn inner_texels(inner: [u32; 4], l: u32) -> impl Iterator<Item = (u32, u32)> {
    let x0 = inner[0] >> l;
    let y0 = inner[1] >> l;
    let x1 = (inner[0] + inner[2]).div_ceil(1 << l);
    let y1 = (inner[1] + inner[3]).div_ceil(1 << l);
    (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
}

/// Distance (texels at level `l`) from texel `(x, y)` to the nearest edge of the inner rect's texels.
fn edge_distance(inner: [u32; 4], l: u32, x: u32, y: u32) -> u32 {
    let x0 = inner[0] >> l;
    let y0 = inner[1] >> l;
    let x1 = (inner[0] + inner[2]).div_ceil(1 << l) - 1;
    let y1 = (inner[1] + inner[3]).div_ceil(1 << l) - 1;
    (x - x0).min(x1 - x).min(y - y0).min(y1 - y)
}

#[test]
fn atlas_levels_the_border_protects_never_mix_textures() {
    assert_eq!(
        [8, 16].map(|b| (independent_levels(b, false), independent_levels(b, true))),
        [(3, 1), (4, 2)]
    );
    for border in [8, 16] {
        atlas_levels_never_mix_textures(border);
    }
}

/// At border `border`: the levels [`independent_levels`] names are unchanged by the neighbours, deeper
/// levels change only within 3 texels of the inner edge (levels 0–3 checked).
fn atlas_levels_never_mix_textures(border: u32) {
    let rects = layout_with_border(border);
    let size = 256u32;
    for format in [TexFormat::Rgba8, TexFormat::Bc1, TexFormat::Bc7] {
        let mut report = Vec::new();
        for keep in [0usize, 5, 10, 15] {
            let (_, inner) = rects[keep];
            let a = levels(
                format,
                &MipChain::build(atlas(&rects, keep, false)).to_rgba8(),
                size,
            );
            let b = levels(
                format,
                &MipChain::build(atlas(&rects, keep, true)).to_rgba8(),
                size,
            );
            for l in 0..4u32 {
                let s = size >> l;
                let (mut changed, mut max_diff, mut max_dist) = (0u32, 0u8, 0u32);
                for (x, y) in inner_texels(inner, l) {
                    let i = ((y * s + x) * 4) as usize;
                    let d = (0..3)
                        .map(|c| a[l as usize][i + c].abs_diff(b[l as usize][i + c]))
                        .max()
                        .unwrap();
                    if d > 0 {
                        changed += 1;
                        max_diff = max_diff.max(d);
                        max_dist = max_dist.max(edge_distance(inner, l, x, y));
                    }
                }
                let safe = independent_levels(border, format != TexFormat::Rgba8);
                if l <= safe {
                    assert_eq!(
                        changed, 0,
                        "border {border}, {format:?} level {l}: rect {keep}'s texels depend on its neighbours"
                    );
                } else {
                    // A 4×4 block reaches at most 3 texels inward from where the foreign texels are.
                    assert!(
                        max_dist < 3,
                        "border {border}, {format:?} level {l}: a texel {max_dist} texels inside rect \
                         {keep} changed"
                    );
                }
                report.push(format!(
                    "L{l} rect {keep}: {changed} texels changed, max |Δ| {max_diff}"
                ));
            }
        }
        eprintln!("border {border}, {format:?}: {}", report.join("; "));
    }
}

#[test]
fn parent_level_0_does_not_mix_textures() {
    // An inner atlas's level 0 is its children's level 1 combined: the same guarantee.
    let rects = layout();
    let size = 256u32;
    let parent = |invert: bool| {
        let child = MipChain::build(atlas(&rects, 5, invert));
        let half = child.levels[1].clone();
        combine_quadrants([Some(&half), None, None, Some(&half)], size, neutral_fill()).unwrap()
    };
    for format in [TexFormat::Bc1, TexFormat::Bc7] {
        let a = levels(format, &MipChain::build(parent(false)).to_rgba8(), size);
        let b = levels(format, &MipChain::build(parent(true)).to_rgba8(), size);
        let (_, inner) = rects[5];
        // Quadrant 0 holds the child at half size: its inner rect at the parent's level 0 is the child's
        // inner rect at level 1.
        for (x, y) in inner_texels(inner, 1) {
            let i = ((y * size + x) * 4) as usize;
            assert_eq!(
                a[0][i..i + 3],
                b[0][i..i + 3],
                "{format:?}: parent texel ({x}, {y}) depends on the neighbours"
            );
        }
    }
}
