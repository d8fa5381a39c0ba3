//! Integration tests of `preprocess::image_ops` (issue 8, case 8): linear-light filtering, sRGB exactness,
//! premultiplied alpha, minification, wrap modes, huge UVs, border continuation, quadrant combine.

use atlastree::preprocess::image_ops::{
    ImageOpsError, LinearImage, MipChain, RectJob, combine_quadrants, draw_rect, halve,
    linear_to_srgb8, mip_chain_rgba8, neutral_fill, resample_square, sample_footprint,
    srgb8_to_linear,
};
use atlastree::scene::{DecodedImage, Wrap};
use atlastree::texfmt::TexFormat as MipFormat;
use glam::DVec2;

/// Deterministic xorshift64 bytes.
fn noise_bytes(n: usize, seed: u64) -> Vec<u8> {
    let mut rng = atlastree::util::XorShift64::new(seed);
    (0..n).map(|_| (rng.next_u64() >> 56) as u8).collect()
}

fn opaque_noise(w: u32, h: u32, seed: u64) -> DecodedImage {
    let b = noise_bytes((w * h * 3) as usize, seed);
    let pixels = b.chunks_exact(3).map(|c| [c[0], c[1], c[2], 255]).collect();
    DecodedImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Checker of `cell`-texel squares, black and white, opaque.
fn checker(w: u32, h: u32, cell: u32) -> DecodedImage {
    let pixels = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                if ((x / cell) + (y / cell)).is_multiple_of(2) {
                    [0, 0, 0, 255]
                } else {
                    [255; 4]
                }
            })
        })
        .collect();
    DecodedImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Rec. 709 luminance of linear RGB.
fn luminance(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Mean linear luminance of opaque sRGB8 pixels.
fn mean_lum_rgba8(px: &[u8]) -> f64 {
    let n = px.len() / 4;
    px.chunks_exact(4)
        .map(|p| luminance([0, 1, 2].map(|c| srgb8_to_linear(p[c]) as f64)))
        .sum::<f64>()
        / n as f64
}

fn mean_lum_linear(img: &LinearImage) -> f64 {
    let m = img.mean();
    luminance([m[0], m[1], m[2]])
}

/// The naive halving everyone writes first: average the sRGB bytes (and straight alpha) directly.
fn naive_halve_rgba8(img: &DecodedImage) -> Vec<[u8; 4]> {
    let (w, h) = (img.width as usize, img.height as usize);
    let mut out = Vec::new();
    for y in 0..h / 2 {
        for x in 0..w / 2 {
            let px = [(0, 0), (1, 0), (0, 1), (1, 1)]
                .map(|(dx, dy)| img.pixels[(2 * y + dy) * w + 2 * x + dx]);
            out.push(
                [0, 1, 2, 3]
                    .map(|c| (px.iter().map(|p| p[c] as f32).sum::<f32>() / 4.0).round() as u8),
            );
        }
    }
    out
}

fn stddev(v: &[f64]) -> (f64, f64) {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / v.len() as f64;
    (mean, var.sqrt())
}

#[test]
fn srgb_round_trip_is_exact_for_all_256_values() {
    for c in 0..=255u8 {
        assert_eq!(linear_to_srgb8(srgb8_to_linear(c)), c, "code {c}");
    }
    assert_eq!(srgb8_to_linear(0), 0.0);
    assert_eq!(srgb8_to_linear(255), 1.0);
    // Monotonic table.
    assert!((1..=255u8).all(|c| srgb8_to_linear(c) > srgb8_to_linear(c - 1)));
}

#[test]
fn linear_halving_preserves_mean_luminance() {
    for (name, img) in [
        ("checker", checker(64, 64, 1)),
        ("noise", opaque_noise(64, 64, 0x5eed)),
    ] {
        let src_lum = mean_lum_rgba8(&img.pixels.concat());
        let lin = LinearImage::from_decoded(&img).unwrap();
        let half = halve(&lin);
        // In linear light (before 8-bit encoding) the box keeps the mean to f32 rounding.
        let rel_linear = (mean_lum_linear(&half) - src_lum).abs() / src_lum;
        assert!(rel_linear < 0.005, "{name}: linear {rel_linear}");
        assert!(rel_linear < 1e-5, "{name}: linear {rel_linear}");
        // Through the stored sRGB8 bytes: the checker's mid-grey lands on code 188 = linear 0.50289
        // (0.58 % high: the 8-bit quantisation floor at mid-grey, codes 187/188 are 0.61 %/0.58 % off);
        // noise averages the quantisation out.
        let rel_8bit = (mean_lum_rgba8(&half.to_rgba8()) - src_lum).abs() / src_lum;
        let limit = if name == "checker" { 0.006 } else { 0.005 };
        assert!(rel_8bit < limit, "{name}: 8-bit {rel_8bit}");
        // Naive sRGB-space byte averaging, measured: checker −56.8 % (code 128 = linear 0.216 instead of
        // 0.5), noise −22.8 %.
        let naive = naive_halve_rgba8(&img).concat();
        let rel_naive = (mean_lum_rgba8(&naive) - src_lum) / src_lum;
        eprintln!(
            "{name}: linear {rel_linear:.2e}, 8-bit {rel_8bit:.4}, naive sRGB {rel_naive:.4}"
        );
        assert!(rel_naive < -0.05, "{name}: naive {rel_naive}");
    }
}

#[test]
fn premultiplied_halving_has_no_dark_fringe() {
    // Opaque red disc ("leaf") on fully transparent BLACK: texels outside the disc are [0, 0, 0, 0].
    let (w, h) = (64u32, 64u32);
    let pixels: Vec<[u8; 4]> = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let (dx, dy) = (x as f64 - 31.3, y as f64 - 30.7);
                if dx * dx + dy * dy < 20.0 * 20.0 {
                    [255, 0, 0, 255]
                } else {
                    [0, 0, 0, 0]
                }
            })
        })
        .collect();
    let img = DecodedImage {
        width: w,
        height: h,
        pixels,
    };
    let lin = LinearImage::from_decoded(&img).unwrap();
    let mut cur = lin;
    let mut partial = 0;
    // Several levels: every texel with alpha > 0 is still pure red after un-premultiply.
    for _ in 0..4 {
        cur = halve(&cur);
        let rgba = cur.to_rgba8();
        for p in rgba.chunks_exact(4).filter(|p| p[3] > 0) {
            assert!(p[0] >= 254 && p[1] <= 1 && p[2] <= 1, "fringe texel {p:?}");
            partial += usize::from(p[3] < 255);
        }
    }
    assert!(partial > 20, "edges must produce partial alpha: {partial}");
    // The naive straight-alpha average darkens the edge: red 255 with three transparent black texels
    // averages to [64, 0, 0, 64].
    let naive = naive_halve_rgba8(&img);
    let darkest = naive
        .iter()
        .filter(|p| p[3] > 0)
        .map(|p| p[0])
        .min()
        .unwrap();
    assert!(darkest <= 128, "naive darkest red {darkest}");
    eprintln!(
        "naive straight-alpha halving: darkest edge red {darkest}/255 (premultiplied: ≥ 254)"
    );
}

/// Rasterise `src` over its full UV square into a `n × n` destination; returns RGBA8.
fn rasterise_full(src: &DecodedImage, n: u32) -> Vec<u8> {
    let chain = MipChain::build(LinearImage::from_decoded(src).unwrap());
    let mut dst = LinearImage::new_filled(n, n, [0.0; 4]);
    let job = RectJob {
        outer: [0, 0, n, n],
        inner: [0, 0, n, n],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap: [Wrap::Repeat; 2],
        factor: [1.0; 4],
    };
    draw_rect(&mut dst, &job, &chain).unwrap();
    dst.to_rgba8()
}

/// Point sampling: the source texel under each destination texel centre.
fn point_sample(src: &DecodedImage, n: u32) -> Vec<u8> {
    let mut out = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let sx = ((x as f64 + 0.5) / n as f64 * src.width as f64) as usize;
            let sy = ((y as f64 + 0.5) / n as f64 * src.height as f64) as usize;
            out.extend_from_slice(&src.pixels[sy * src.width as usize + sx]);
        }
    }
    out
}

fn red_stats(rgba: &[u8]) -> (f64, f64) {
    stddev(
        &rgba
            .chunks_exact(4)
            .map(|p| p[0] as f64)
            .collect::<Vec<_>>(),
    )
}

#[test]
fn minified_checkerboard_is_uniform_grey() {
    let src = checker(512, 512, 1);
    // Linear 0.5 encodes to sRGB code 188.
    for n in [64u32, 61, 45] {
        let (mean, sd) = red_stats(&rasterise_full(&src, n));
        let (pmean, psd) = red_stats(&point_sample(&src, n));
        eprintln!(
            "512² checker → {n}²: filtered mean {mean:.2} sd {sd:.3}; point mean {pmean:.1} sd {psd:.1}"
        );
        assert!((mean - 188.0).abs() <= 1.0, "{n}: mean {mean}");
        assert!(sd < 2.0, "{n}: sd {sd}");
        // Point sampling aliases: at exactly 8× every centre hits the same colour (mean 0 or 255, all
        // wrong); at 8.39× and 11.4× it is a high-contrast moiré (sd ≈ 127).
        assert!(
            (pmean - 188.0).abs() > 50.0 || psd > 100.0,
            "{n}: point {pmean} {psd}"
        );
    }
}

#[test]
fn minified_coarse_checker_is_antialiased() {
    // 4-texel cells (period 8) minified 5.3×: the destination period is 1.5 texels, beyond Nyquist.
    let src = checker(512, 512, 4);
    let n = 97;
    let (mean, sd) = red_stats(&rasterise_full(&src, n));
    let (_, psd) = red_stats(&point_sample(&src, n));
    eprintln!("512² 4-texel checker → {n}²: filtered sd {sd:.2}, point sd {psd:.1}");
    assert!((mean - 188.0).abs() <= 2.0, "mean {mean}");
    // Measured: 7.7 (point sampling: 127.5). The fundamental is at 0.66 cycles/pixel; even an ideal
    // one-pixel box would only attenuate it to sinc(0.66) = 44 %. Taps at half-texel spacing improve this
    // only to 5.9 at 4× the cost, so 2×2 taps stay.
    assert!(sd < 10.0, "sd {sd}");
    assert!(psd > 100.0, "point sd {psd}");
}

#[test]
fn anisotropic_footprint_keeps_the_sharp_axis() {
    // Source: 1-texel vertical stripes (x) plus 2-texel horizontal bands (y). Squashed 8× in x, 1:1 in
    // y: x must average to 0.25 (no aliasing), y must keep its bands exactly.
    let (w, h) = (256u32, 32u32);
    let data = (0..h)
        .flat_map(|y| (0..w).map(move |x| 0.5 * (x & 1) as f32 + 0.5 * ((y >> 1) & 1) as f32))
        .map(|v| [v, v, v, 1.0])
        .collect();
    let chain = MipChain::build(LinearImage {
        width: w,
        height: h,
        data,
    });
    let mut dst = LinearImage::new_filled(32, 32, [0.0; 4]);
    let job = RectJob {
        outer: [0, 0, 32, 32],
        inner: [0, 0, 32, 32],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap: [Wrap::Repeat; 2],
        factor: [1.0; 4],
    };
    draw_rect(&mut dst, &job, &chain).unwrap();
    for y in 0..32 {
        let want = 0.25 + 0.5 * ((y >> 1) & 1) as f32;
        for x in 0..32 {
            let v = dst.get(x, y).unwrap()[0];
            assert!((v - want).abs() < 1e-5, "({x}, {y}): {v} vs {want}");
        }
    }
}

fn ramp(values: &[f32], vertical: bool) -> MipChain {
    let n = values.len() as u32;
    let data = values.iter().map(|&v| [v, v, v, 1.0]).collect();
    let (width, height) = if vertical { (1, n) } else { (n, 1) };
    MipChain::build(LinearImage {
        width,
        height,
        data,
    })
}

#[test]
fn wrap_modes_at_uv_1_25() {
    let vals = [0.1f32, 0.3, 0.6, 0.9];
    let fp = DVec2::splat(1.0 / 4.0);
    for vertical in [false, true] {
        let chain = ramp(&vals, vertical);
        let at = |t: f64, wrap: Wrap| {
            let (uv, w) = if vertical {
                (DVec2::new(0.5, t), [Wrap::ClampToEdge, wrap])
            } else {
                (DVec2::new(t, 0.5), [wrap, Wrap::ClampToEdge])
            };
            sample_footprint(&chain, w, uv, fp)[0]
        };
        // 1.25 lies on the boundary of texels 0|1 (repeat) or 3|2 (mirror): bilinear gives their mean.
        assert!((at(1.25, Wrap::Repeat) - at(0.25, Wrap::Repeat)).abs() < 1e-6);
        assert!((at(1.25, Wrap::Repeat) - 0.2).abs() < 1e-6);
        assert!((at(1.25, Wrap::MirroredRepeat) - at(0.75, Wrap::MirroredRepeat)).abs() < 1e-6);
        assert!((at(1.25, Wrap::MirroredRepeat) - 0.75).abs() < 1e-6);
        assert!((at(1.25, Wrap::ClampToEdge) - 0.9).abs() < 1e-6);
        assert!((at(-0.25, Wrap::ClampToEdge) - 0.1).abs() < 1e-6);
        // Negative side: -0.75 ≡ 0.25 (repeat); -0.25 mirrors to 0.25.
        assert!((at(-0.75, Wrap::Repeat) - 0.2).abs() < 1e-6);
        assert!((at(-0.25, Wrap::MirroredRepeat) - 0.2).abs() < 1e-6);
    }
}

#[test]
fn huge_uv_offsets_match_small_ones() {
    let chain = MipChain::build(LinearImage::from_decoded(&opaque_noise(64, 64, 9)).unwrap());
    for (wrap, base) in [
        (Wrap::Repeat, 1e5),
        (Wrap::Repeat, -1e5),
        (Wrap::MirroredRepeat, 1e5),
        (Wrap::MirroredRepeat, -2e5),
    ] {
        let draw = |off: f64| {
            let mut dst = LinearImage::new_filled(40, 40, [0.0; 4]);
            let job = RectJob {
                outer: [0, 0, 40, 40],
                inner: [4, 4, 32, 32],
                uv_min: [off + 0.25, off + 0.25],
                uv_max: [off + 1.6, off + 0.75],
                wrap: [wrap; 2],
                factor: [1.0; 4],
            };
            draw_rect(&mut dst, &job, &chain).unwrap();
            dst
        };
        let (far, near) = (draw(base), draw(0.0));
        for (a, b) in far.data.iter().zip(&near.data) {
            for c in 0..4 {
                assert!(
                    (a[c] - b[c]).abs() < 1e-6,
                    "{wrap:?} {base}: {a:?} vs {b:?}"
                );
            }
        }
        let s_far = sample_footprint(
            &chain,
            [wrap; 2],
            DVec2::splat(base + 0.25),
            DVec2::splat(0.01),
        );
        let s_near = sample_footprint(&chain, [wrap; 2], DVec2::splat(0.25), DVec2::splat(0.01));
        for c in 0..4 {
            assert!((s_far[c] - s_near[c]).abs() < 1e-6);
        }
    }
}

#[test]
fn draw_rect_border_continues_the_texture() {
    // 16-texel source, A_tex = [0.25, 0.75] on an 8-texel inner rect: 1 destination texel = 1 source
    // texel and destination centres hit source centres, so every texel is an exact copy of the source
    // texel its continued UV lands on: x_src = x_dst − inner_x + 4 (wrapped), same for y.
    let img = opaque_noise(16, 16, 77);
    let lin = LinearImage::from_decoded(&img).unwrap();
    let chain = MipChain::build(lin.clone());
    for wrap in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge] {
        let mut dst = LinearImage::new_filled(32, 32, [9.0; 4]);
        let job = RectJob {
            outer: [3, 5, 24, 24],
            inner: [11, 13, 8, 8],
            uv_min: [0.25; 2],
            uv_max: [0.75; 2],
            wrap: [wrap; 2],
            factor: [1.0; 4],
        };
        draw_rect(&mut dst, &job, &chain).unwrap();
        for y in 0..32u32 {
            for x in 0..32u32 {
                let got = dst.get(x, y).unwrap();
                let inside = (3..27).contains(&x) && (5..29).contains(&y);
                if !inside {
                    assert_eq!(got, [9.0; 4], "texel ({x}, {y}) outside outer was written");
                    continue;
                }
                let sx = atlastree::preprocess::image_ops::wrap_index(x as i64 - 11 + 4, 16, wrap);
                let sy = atlastree::preprocess::image_ops::wrap_index(y as i64 - 13 + 4, 16, wrap);
                let want = lin.get(sx, sy).unwrap();
                for c in 0..4 {
                    assert!(
                        (got[c] - want[c]).abs() < 1e-6,
                        "{wrap:?} ({x}, {y}): {got:?} vs {want:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn draw_rect_applies_factor_and_rejects_bad_rects() {
    let chain = MipChain::build(LinearImage::new_filled(4, 4, [0.5, 0.25, 1.0, 1.0]));
    let mut dst = LinearImage::new_filled(8, 8, [0.0; 4]);
    let mut job = RectJob {
        outer: [0, 0, 8, 8],
        inner: [0, 0, 8, 8],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap: [Wrap::Repeat; 2],
        factor: [0.5, 1.0, 1.0, 0.5],
    };
    draw_rect(&mut dst, &job, &chain).unwrap();
    // Straight colour × factor, premultiplied by alpha × factor_a = 0.5.
    let want = [0.125, 0.125, 0.5, 0.5];
    for t in &dst.data {
        for c in 0..4 {
            assert!((t[c] - want[c]).abs() < 1e-6);
        }
    }
    job.outer = [4, 0, 5, 8];
    assert!(matches!(
        draw_rect(&mut dst, &job, &chain),
        Err(ImageOpsError::RectOutside { what: "outer", .. })
    ));
    job.outer = [u32::MAX, 0, 2, 2];
    assert!(matches!(
        draw_rect(&mut dst, &job, &chain),
        Err(ImageOpsError::RectOutside { .. })
    ));
    job.outer = [0, 0, 8, 8];
    job.inner = [0, 0, 0, 8];
    assert!(matches!(
        draw_rect(&mut dst, &job, &chain),
        Err(ImageOpsError::EmptyInner { .. })
    ));
    job.inner = [0, 0, 8, 8];
    job.uv_max = [f64::NAN, 1.0];
    assert!(matches!(
        draw_rect(&mut dst, &job, &chain),
        Err(ImageOpsError::NonFiniteUv { .. })
    ));
}

#[test]
fn combine_quadrants_places_children() {
    let colours = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
        [0.5, 0.5, 0.0, 1.0],
    ];
    let kids: Vec<LinearImage> = colours
        .iter()
        .map(|&c| LinearImage::new_filled(4, 4, c))
        .collect();
    let out = combine_quadrants(
        [Some(&kids[0]), Some(&kids[1]), Some(&kids[2]), None],
        8,
        neutral_fill(),
    )
    .unwrap();
    assert_eq!((out.width, out.height, out.data.len()), (8, 8, 64));
    for y in 0..8u32 {
        for x in 0..8u32 {
            let q = (x >= 4) as usize | (((y >= 4) as usize) << 1);
            let want = if q == 3 { neutral_fill() } else { colours[q] };
            assert_eq!(out.get(x, y).unwrap(), want, "({x}, {y}) quadrant {q}");
        }
    }
    // Sub-texel placement: a distinct texel at (1, 2) of child 3 lands at (4 + 1, 4 + 2).
    let mut k3 = LinearImage::new_filled(4, 4, [0.0; 4]);
    k3.set(1, 2, [0.2, 0.3, 0.4, 1.0]).unwrap();
    let out = combine_quadrants([None, None, None, Some(&k3)], 8, neutral_fill()).unwrap();
    assert_eq!(out.get(5, 6).unwrap(), [0.2, 0.3, 0.4, 1.0]);
    assert_eq!(out.get(5, 5).unwrap(), [0.0; 4]);
    let grey = neutral_fill();
    assert_eq!(linear_to_srgb8(grey[0]), 128);
    // Errors.
    assert!(matches!(
        combine_quadrants([Some(&kids[0]), None, None, None], 6, neutral_fill()),
        Err(ImageOpsError::ChildSize { quadrant: 0, .. })
    ));
    assert!(matches!(
        combine_quadrants([None; 4], 7, neutral_fill()),
        Err(ImageOpsError::QuadrantSize { size: 7 })
    ));
}

#[test]
fn combine_of_halved_children_equals_halved_combination() {
    // Box halving is local: combining the children's level-1 mips equals halving the full-size mosaic.
    let kids: Vec<LinearImage> = (0..4)
        .map(|s| LinearImage::from_decoded(&opaque_noise(16, 16, 100 + s)).unwrap())
        .collect();
    let halves: Vec<LinearImage> = kids.iter().map(halve).collect();
    let combined = combine_quadrants(
        [
            Some(&halves[0]),
            Some(&halves[1]),
            Some(&halves[2]),
            Some(&halves[3]),
        ],
        16,
        neutral_fill(),
    )
    .unwrap();
    let mut mosaic = LinearImage::new_filled(32, 32, [0.0; 4]);
    for (q, k) in kids.iter().enumerate() {
        for y in 0..16 {
            for x in 0..16 {
                let t = k.get(x, y).unwrap();
                mosaic
                    .set(x + 16 * (q as u32 & 1), y + 16 * (q as u32 >> 1), t)
                    .unwrap();
            }
        }
    }
    let direct = halve(&mosaic);
    for (a, b) in combined.data.iter().zip(&direct.data) {
        for c in 0..4 {
            assert!((a[c] - b[c]).abs() < 1e-6);
        }
    }
}

#[test]
fn mip_chain_rgba8_length_matches_block_size() {
    for size in [1u32, 2, 4, 64, 256] {
        let base = LinearImage::new_filled(size, size, [0.2, 0.2, 0.2, 1.0]);
        let bytes = mip_chain_rgba8(&base);
        assert_eq!(
            bytes.len() as u64,
            MipFormat::Rgba8.chain_bytes(size),
            "size {size}"
        );
        // The 1×1 tail is the image's mean.
        let last = &bytes[bytes.len() - 4..];
        assert_eq!(
            last,
            &[
                linear_to_srgb8(0.2),
                linear_to_srgb8(0.2),
                linear_to_srgb8(0.2),
                255
            ]
        );
    }
    // Level layout: level 0 first, then level 1 right after it.
    let base = LinearImage::from_decoded(&checker(8, 8, 1)).unwrap();
    let bytes = mip_chain_rgba8(&base);
    assert_eq!(&bytes[0..4], &[0, 0, 0, 255]);
    assert_eq!(&bytes[256..260], &[188, 188, 188, 255]);
}

#[test]
fn resample_square_tiles_seamlessly_under_wrap() {
    // 5×5 source, column 0 white, the rest black. Upsampled to 8×8: under Repeat the right edge blends
    // towards column 0 (its neighbour across the seam); under Clamp it stays black.
    let pixels = (0..25)
        .map(|i| {
            if i % 5 == 0 {
                [255u8; 4]
            } else {
                [0, 0, 0, 255]
            }
        })
        .collect();
    let img = DecodedImage {
        width: 5,
        height: 5,
        pixels,
    };
    let rep = resample_square(&img, 8, [Wrap::Repeat; 2]).unwrap();
    let clamp = resample_square(&img, 8, [Wrap::ClampToEdge; 2]).unwrap();
    let mirror = resample_square(&img, 8, [Wrap::MirroredRepeat; 2]).unwrap();
    let (r_left, r_right) = (rep.get(0, 3).unwrap()[0], rep.get(7, 3).unwrap()[0]);
    assert!(r_right > 0.1, "repeat right edge {r_right}");
    assert_eq!(clamp.get(7, 3).unwrap()[0], 0.0);
    assert_eq!(mirror.get(7, 3).unwrap()[0], 0.0);
    // Magnification 5/8: a Catmull-Rom cubic. Texel 7's centre is at source x = 4.1875 (t = 0.1875 past
    // texel 4; weight ½(−3t³ + 4t² + t) = 0.15417 on texel 5 ≡ 0, white); texel 0's at −0.1875 (t =
    // 0.8125 past texel −1; the same weight, 0.92200, on texel 0): continuous across the seam.
    assert!((r_right - 0.154_174_8).abs() < 1e-6, "{r_right}");
    assert!((r_left - 0.921_997).abs() < 1e-6, "{r_left}");
    // Downsampling keeps the mean under Repeat (the wrap keeps every texel's total weight equal).
    let big = opaque_noise(48, 48, 5);
    let m_src = LinearImage::from_decoded(&big).unwrap().mean();
    let m_dst = resample_square(&big, 32, [Wrap::Repeat; 2]).unwrap().mean();
    for c in 0..3 {
        assert!(
            (m_src[c] - m_dst[c]).abs() < 0.01 * m_src[c],
            "{m_src:?} vs {m_dst:?}"
        );
    }
    assert!(matches!(
        resample_square(&img, 0, [Wrap::Repeat; 2]),
        Err(ImageOpsError::ZeroSize { .. })
    ));
}

#[test]
fn draw_rect_equals_per_texel_sampling_on_the_parallel_path() {
    // 160×150 = 24000 texels ≥ the rayon threshold; every texel equals sample_footprint at its centre's
    // UV under the inner → A_tex map, with one destination texel as the footprint.
    let chain = MipChain::build(LinearImage::from_decoded(&opaque_noise(64, 32, 31)).unwrap());
    let mut dst = LinearImage::new_filled(170, 160, [0.0; 4]);
    let job = RectJob {
        outer: [5, 3, 160, 150],
        inner: [13, 11, 144, 134],
        uv_min: [-0.3, 2.1],
        uv_max: [3.7, 0.4],
        wrap: [Wrap::MirroredRepeat, Wrap::Repeat],
        factor: [1.0; 4],
    };
    draw_rect(&mut dst, &job, &chain).unwrap();
    let fp = DVec2::new(4.0 / 144.0, 1.7 / 134.0);
    for y in 3..153u32 {
        for x in 5..165u32 {
            let t = DVec2::new(
                (x as f64 + 0.5 - 13.0) / 144.0,
                (y as f64 + 0.5 - 11.0) / 134.0,
            );
            let uv = DVec2::new(-0.3 + t.x * 4.0, 2.1 - t.y * 1.7);
            let want = sample_footprint(&chain, job.wrap, uv, fp);
            let got = dst.get(x, y).unwrap();
            for c in 0..4 {
                assert!(
                    (got[c] - want[c]).abs() < 1e-5,
                    "({x}, {y}): {got:?} vs {want:?}"
                );
            }
        }
    }
    assert_eq!(dst.get(4, 3).unwrap(), [0.0; 4]);
    assert_eq!(dst.get(165, 3).unwrap(), [0.0; 4]);
}
