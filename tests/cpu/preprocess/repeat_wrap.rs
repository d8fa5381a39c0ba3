//! Repeats wrapped in the shader (docs/DESIGN.md "Repeats"): the CPU twin of the fragment
//! shader's rect mapping samples what the original texture shows, per wrap mode, per level and at the rect
//! edges; the split balances texel demand, not world area; a translated scene (UTM coordinates, with
//! rounding) gives the identical tree; a UV range of ±2.9e9 on one triangle builds without NaN.

use crate::built::*;
use atlastree::ids::MaterialId;
use atlastree::model::{AtlasRect, RectWrap};
use atlastree::preprocess::image_ops::{
    LinearImage, MipChain, RectJob, draw_rect, neutral_fill, sample_footprint, srgb8_to_linear,
};
use atlastree::preprocess::{BuildOptions, DMin};
use atlastree::render::wgsl::tree::RectMap;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, DecodedImage, Scene, UpAxis, Wrap};
use atlastree::texfmt::TexFormat;
use glam::{DVec2, DVec3, Vec2};

/// A 64² source, continuous under the sampler's rule (else the original itself has a hard edge at the
/// seam, where two correct filters of different shape disagree), but not symmetric: for REPEAT a periodic
/// wave with a phase (u and v), otherwise ramps (dark → bright red in u, green in v). A wrong seam —
/// clamping where the sampler repeats, the far edge of the rect, no reflection — shows as a jump of up to
/// the whole range.
fn source(periodic: bool) -> DecodedImage {
    let n = 64u32;
    let pixels = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            let (u, v) = ((f64::from(x) + 0.5) / 64.0, (f64::from(y) + 0.5) / 64.0);
            let c = |t: f64| {
                if periodic {
                    0.5 + 0.5 * (std::f64::consts::TAU * t + 0.9).sin()
                } else {
                    t
                }
            };
            [(c(u) * 255.0) as u8, (c(v) * 255.0) as u8, 40, 255]
        })
        .collect();
    DecodedImage {
        width: n,
        height: n,
        pixels,
    }
}

/// Bilinear sample of `img` at texel coordinates `p` (texel units, centres at +0.5), clamped to the image.
fn bilinear(img: &LinearImage, p: DVec2) -> [f32; 4] {
    let x = p.x - 0.5;
    let y = p.y - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let at = |xi: f64, yi: f64| {
        let cx = (xi as i64).clamp(0, i64::from(img.width) - 1) as u32;
        let cy = (yi as i64).clamp(0, i64::from(img.height) - 1) as u32;
        img.get(cx, cy).unwrap_or([0.0; 4])
    };
    let (a, b, c, d) = (
        at(x0, y0),
        at(x0 + 1.0, y0),
        at(x0, y0 + 1.0),
        at(x0 + 1.0, y0 + 1.0),
    );
    let mut out = [0.0f32; 4];
    for k in 0..4 {
        let top = a[k] * (1.0 - fx) + b[k] * fx;
        let bottom = c[k] * (1.0 - fx) + d[k] * fx;
        out[k] = top * (1.0 - fy) + bottom * fy;
    }
    out
}

fn max_diff(a: [f32; 4], b: [f32; 4]) -> f32 {
    (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f32::max)
}

/// One case of the twin test: a rect of the source under `wrap`, holding `[lo, hi]` on both axes at
/// 48 texels per UV, in a 128² leaf atlas with a 16-texel border.
struct Case {
    wrap: Wrap,
    mode: RectWrap,
    lo: f64,
    hi: f64,
    /// UVs to sample: inside, at the seams / edges, far outside.
    us: Vec<f64>,
}

fn cases() -> Vec<Case> {
    let seam = |c: f64| [c - 0.004, c - 0.0005, c, c + 0.0005, c + 0.004];
    let mut repeat_full: Vec<f64> = [0.13, 0.5, 0.87, -3.6, 7.25].to_vec();
    repeat_full.extend(seam(0.0).iter().chain(&seam(1.0)).chain(&seam(5.0)));
    let mut repeat_part: Vec<f64> = [0.25, 0.45, 0.65, 3.3, -1.55].to_vec();
    repeat_part.extend(seam(0.2).iter().chain(&seam(1.7)));
    let mut mirror: Vec<f64> = [0.3, 1.3, -0.7, 2.6].to_vec();
    mirror.extend(seam(0.0).iter().chain(&seam(1.0)).chain(&seam(2.0)));
    let mut clamp: Vec<f64> = [0.4, -0.5, 1.5, 9.0].to_vec();
    clamp.extend(seam(0.0).iter().chain(&seam(1.0)));
    vec![
        Case {
            wrap: Wrap::Repeat,
            mode: RectWrap::Repeat,
            lo: 0.0,
            hi: 1.0,
            us: repeat_full,
        },
        Case {
            wrap: Wrap::Repeat,
            mode: RectWrap::Repeat,
            lo: 0.2,
            hi: 0.7,
            us: repeat_part,
        },
        Case {
            wrap: Wrap::MirroredRepeat,
            mode: RectWrap::Mirror,
            lo: 0.0,
            hi: 1.0,
            us: mirror,
        },
        Case {
            wrap: Wrap::ClampToEdge,
            mode: RectWrap::Clamp,
            lo: 0.0,
            hi: 1.0,
            us: clamp,
        },
    ]
}

/// The rect sampled through the shader's mapping (`RectMap::texel_f32`) at level `K − n` (the leaf
/// atlas's mip n, which is exactly that leaf's part of its level-(K − n) ancestor), against the original
/// texture filtered over the same footprint, per wrap mode, for UVs inside, at the seams and far outside.
/// The naive mapping (no wrap: the UV clamped to the rect) is measured too and must fail at the seams, so
/// the tolerance is tight enough to see a wrong border.
#[test]
fn rect_sampling_matches_the_original_per_mode_level_and_edge() {
    let (tpu, border, size) = (48.0f64, 16u32, 128u32);
    let mut report = Vec::new();
    for case in cases() {
        let src = source(case.wrap == Wrap::Repeat);
        let src_chain = MipChain::build(LinearImage::from_decoded(&src).unwrap());
        let span = case.hi - case.lo;
        let inner = (tpu * span).round() as u32;
        let outer = inner + 2 * border;
        let rect = AtlasRect {
            material: MaterialId(0),
            outer: [8, 8, outer, outer],
            inner: [8 + border, 8 + border, inner, inner],
            uv_min: [case.lo; 2],
            uv_max: [case.hi; 2],
            wrap: [case.mode; 2],
            capped: [false; 2],
            mean: [0; 4],
        };
        let mut atlas = LinearImage::new_filled(size, size, neutral_fill());
        let job = RectJob::from_atlas_rect(&rect, [case.wrap; 2], [1.0; 4]);
        draw_rect(&mut atlas, &job, &src_chain).unwrap();
        let atlas = MipChain::build(atlas);
        let map = RectMap::new(&rect, atlastree::scene::AlphaMode::Opaque);
        let (mut worst, mut worst_naive) = (0.0f32, 0.0f32);
        for n in 0..3u32 {
            let scale = f64::from(1u32 << n);
            let level = &atlas.levels[n as usize];
            // One pixel covers one texel of the drawn level.
            let fp = scale / f64::from(inner) * span;
            for &u in &case.us {
                for &v in &[0.37 * span + case.lo, u] {
                    let uv = DVec2::new(u, v);
                    let want = sample_footprint(&src_chain, [case.wrap; 2], uv, DVec2::splat(fp));
                    let d = Vec2::new(fp as f32, 0.0);
                    let (texel, _, _) =
                        map.texel_f32(uv.as_vec2(), d, Vec2::new(0.0, fp as f32), scale as f32);
                    let got = bilinear(level, texel.as_dvec2() / scale);
                    if std::env::var_os("TWIN_DEBUG").is_some() && max_diff(got, want) > 0.02 {
                        eprintln!("{:?} n={n} uv={uv} got {got:?} want {want:?}", case.mode);
                    }
                    worst = worst.max(max_diff(got, want));
                    // Naive: the UV clamped to the rect's range, no wrap.
                    let naive_t = |x: f64| x.clamp(case.lo, case.hi) - case.lo;
                    let p = DVec2::new(
                        f64::from(rect.inner[0]) + naive_t(u) * tpu,
                        f64::from(rect.inner[1]) + naive_t(v) * tpu,
                    );
                    let naive = bilinear(level, p / scale);
                    worst_naive = worst_naive.max(max_diff(naive, want));
                }
            }
        }
        report.push(format!(
            "{:?} [{}, {}]: worst {worst:.4}, naive {worst_naive:.3}",
            case.mode, case.lo, case.hi
        ));
        assert!(
            worst <= 0.03,
            "{:?} [{}, {}]: the rect through the shader's mapping differs from the original by {worst} \
             (linear, max over R, G, B)",
            case.mode,
            case.lo,
            case.hi
        );
        if case.mode != RectWrap::Clamp {
            assert!(
                worst_naive > 0.1,
                "{:?}: the naive mapping should fail at the seams ({worst_naive})",
                case.mode
            );
        }
    }
    eprintln!(
        "rect sampling vs the original, levels K..K−2:\n  {}",
        report.join("\n  ")
    );
}

/// A hand-made scene whose world areas and texel demands disagree: west, 16 big ground tiles (100 × 100 m
/// each) share one repeated texture (one period in any atlas); east, 16 small 2 × 2 m plates with a
/// texture each. Equal world areas put almost everything east of the cut into one half; equal demand cuts
/// among the plates. The first split (x) of the demand tree keeps the shared-texture tiles and part of
/// the plates together, the area tree separates the tiles from every plate.
/// A 1:2 sprite far away (the footprint covers its rect: the period's mean). Its alpha is 1 in the
/// middle half of each axis, a quarter of its area; on the mip where its rect is 2 × 4 texels a tap at
/// the centre reads the middle 2 × 2 (alpha 0.5, above a 0.5 cutoff: black_forest's firs drew as solid
/// sheets), so the fragment is flat and shows the rect's mean measured on the stored atlas (alpha 0.25,
/// `texfmt::rect_means`), whatever the mips hold at the centre.
#[test]
fn a_flat_sprite_shows_the_mean_of_its_whole_rect() {
    let (w, h) = (64u32, 128u32);
    let pixels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let inside = (16..48).contains(&x) && (32..96).contains(&y);
            [90, 140, 60, if inside { 255 } else { 0 }]
        })
        .collect();
    let sprite = DecodedImage {
        width: w,
        height: h,
        pixels,
    };
    let chain = MipChain::build(LinearImage::from_decoded(&sprite).unwrap());
    let rect = AtlasRect {
        material: MaterialId(0),
        outer: [16, 16, w + 32, h + 32],
        inner: [32, 32, w, h],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap: [RectWrap::Clamp; 2],
        capped: [false; 2],
        mean: [0; 4],
    };
    let mut atlas = LinearImage::new_filled(256, 256, neutral_fill());
    let job = RectJob::from_atlas_rect(&rect, [Wrap::ClampToEdge; 2], [1.0; 4]);
    draw_rect(&mut atlas, &job, &chain).unwrap();
    let atlas = MipChain::build(atlas);
    let map = RectMap::new(&rect, AlphaMode::Mask { cutoff: 0.5 });
    let (ddx, ddy) = (Vec2::new(3.0, 0.0), Vec2::new(0.0, 3.0));
    let s = map.sample_f32(Vec2::new(0.3, 0.6), ddx, ddy, 1.0);
    let (centre, gx, gy) = (s.texel, s.gx, s.gy);
    assert!(s.flat && s.mix_mean == 1.0);
    assert_eq!(centre, Vec2::new(64.0, 96.0));
    // What the flat branch read before format 6: the centre of the mip where the rect's smaller side is
    // 2 texels (mip 5), alpha 0.5.
    let lod = (gx.length().max(gy.length())).log2();
    assert!((lod - 5.0).abs() < 1e-5, "{lod}");
    let at_centre = bilinear(&atlas.levels[5], centre.as_dvec2() / 32.0)[3];
    assert!((at_centre - 0.5).abs() < 0.02, "{at_centre}");
    // The stored mean: the sprite's colour at a quarter coverage, below the cutoff.
    let stored = atlas.to_rgba8();
    let means = atlastree::texfmt::rect_means(TexFormat::Rgba8, &stored, 256, &[rect.inner], false)
        .unwrap();
    let want = [90, 140, 60, 64];
    assert!(
        (means[0].iter().zip(want)).all(|(&g, w)| g.abs_diff(w) <= 1),
        "{:?}",
        means[0]
    );
    let shown = RectMap::new(
        &AtlasRect {
            mean: means[0],
            ..rect
        },
        AlphaMode::Opaque,
    )
    .mean_linear();
    assert!(
        (shown[3] - 0.25).abs() < 0.01 && shown[3] < 0.5,
        "{shown:?}"
    );
}

/// An isotropic trilinear sampler (anisotropy 1, as lavapipe's `auto`) at `texel` with gradients `gx`,
/// `gy` (texels of mip 0 of `atlas`): the longer gradient picks the lod on both axes, and the two mips
/// around it are blended.
fn trilinear(atlas: &MipChain, texel: Vec2, gx: Vec2, gy: Vec2) -> [f32; 4] {
    let lod = gx.length().max(gy.length()).max(1e-30).log2().max(0.0);
    let top = atlas.levels.len() - 1;
    let m = (lod.floor() as usize).min(top);
    let f = if m == top { 0.0 } else { lod - m as f32 };
    let at = |l: usize| bilinear(&atlas.levels[l], texel.as_dvec2() / f64::from(1u32 << l));
    let (a, b) = (at(m), at((m + 1).min(top)));
    std::array::from_fn(|c| a[c] * (1.0 - f) + b[c] * f)
}

/// The lighthouse sea (stk_lighthouse, default build): a REPEAT rect of 120 × 60 inner texels with a
/// 16-texel border between two bright neighbours, seen at a grazing angle, so the footprint along v is
/// many times the one along u (up to several periods). Whatever the footprint, the rect's texels sampled
/// through the shader's mapping by an isotropic trilinear sampler (whose lod the longer gradient sets on
/// both axes, and whose coarser mip's texels straddle the rect's edges) read nothing of a neighbour: the
/// neighbours are pure blue, the rect's source has a constant blue of 40/255, so any bleed raises blue.
/// Before the fix the sharpening modelled the filter per axis as half the gradient box: at the u seams
/// lod ≈ 6 reached ~96 texels past a 16-texel border (bright streaks across the sea).
#[test]
fn an_isotropic_trilinear_filter_never_reads_a_neighbouring_rect() {
    let src = source(true);
    let chain = MipChain::build(LinearImage::from_decoded(&src).unwrap());
    let own_blue = srgb8_to_linear(40);
    let rect = AtlasRect {
        material: MaterialId(0),
        outer: [64, 36, 152, 92],
        inner: [80, 52, 120, 60],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap: [RectWrap::Repeat; 2],
        capped: [false; 2],
        mean: [0; 4],
    };
    let mut atlas = LinearImage::new_filled(256, 128, [0.0, 0.0, 1.0, 1.0]);
    draw_rect(
        &mut atlas,
        &RectJob::from_atlas_rect(&rect, [Wrap::Repeat; 2], [1.0; 4]),
        &chain,
    )
    .unwrap();
    let atlas = MipChain::build(atlas);
    let map = RectMap::new(&rect, AlphaMode::Blend);
    let (mut worst, mut at) = (0.0f32, String::new());
    let mut sharpened = 0;
    // Footprints in leaf texels along u (across) and v (along the view), and the transposed case.
    for &(fu, fv) in &[
        (1.0f32, 1.0f32),
        (3.0, 8.0),
        (3.0, 20.0),
        (3.0, 40.0),
        (3.0, 55.0),
        (3.0, 64.0),
        (6.0, 130.0),
        (20.0, 20.0),
        (40.0, 3.0),
        (100.0, 4.0),
    ] {
        for transpose in [false, true] {
            let (a, b) = if transpose { (fv, fu) } else { (fu, fv) };
            let ddx = Vec2::new(a / 120.0, 0.0);
            let ddy = Vec2::new(0.0, b / 60.0);
            for i in 0..=240 {
                for j in 0..=24 {
                    let uv = Vec2::new(-0.5 + i as f32 / 80.0, 3.0 + j as f32 / 8.0);
                    let (texel, gx, gy) = map.texel_f32(uv, ddx, ddy, 1.0);
                    if gx.length().max(gy.length()) < a.max(b) * 0.999 {
                        sharpened += 1;
                    }
                    let blue = trilinear(&atlas, texel, gx, gy)[2];
                    if blue - own_blue > worst {
                        worst = blue - own_blue;
                        at = format!(
                            "uv {uv} footprint ({a}, {b}) → texel {texel}, gradients {gx} {gy}"
                        );
                    }
                }
            }
        }
    }
    assert!(sharpened > 0, "the grid never needed sharpening");
    assert!(
        worst <= 1e-4,
        "a neighbouring rect bled in: blue {worst} above the rect's own at {at}"
    );
}

#[test]
fn the_split_balances_texel_demand_not_world_area() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let ground_img = b.pattern_image("ground", 64, 0);
    let ground = b.material(ground_img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    for i in 0..16 {
        let x = f64::from(i % 4) * 100.0;
        let z = f64::from(i / 4) * 100.0;
        b.quad(
            [
                DVec3::new(x, 0.0, z),
                DVec3::new(x + 100.0, 0.0, z),
                DVec3::new(x + 100.0, 0.0, z + 100.0),
                DVec3::new(x, 0.0, z + 100.0),
            ],
            DVec2::ZERO,
            DVec2::splat(20.0),
            ground,
        );
    }
    for i in 0..16 {
        let img = b.pattern_image(&format!("plate {i}"), 64, 1 + i);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let x = 420.0 + f64::from(i % 4) * 5.0;
        let z = f64::from(i / 4) * 100.0 + 40.0;
        b.quad(
            [
                DVec3::new(x, 0.0, z),
                DVec3::new(x + 2.0, 0.0, z),
                DVec3::new(x + 2.0, 0.0, z + 2.0),
                DVec3::new(x, 0.0, z + 2.0),
            ],
            DVec2::ZERO,
            DVec2::ONE,
            m,
        );
    }
    let scene = b.build();
    let opts = |split| BuildOptions {
        split,
        ..tiny_opts(128, 30.0)
    };
    let plates_beside_tiles = |built: &Built| -> usize {
        // Which top-level quadrant (by its x half) each triangle ended in: count plates sharing the west
        // half with the tiles.
        let t = built.file.tree(0).unwrap();
        let root = &t.nodes[0];
        let west: Vec<u32> = [0usize, 2]
            .iter()
            .filter_map(|&q| {
                let c = root.children[q];
                (c != atlastree::ids::NONE).then_some(c)
            })
            .collect();
        let mut plates = 0;
        for c in west {
            let n = &t.nodes[c as usize];
            let tris = &t.source_triangles
                [n.first_index as usize / 3..(n.first_index + n.index_count) as usize / 3];
            plates += tris.iter().filter(|&&s| s >= 32).count() / 2;
        }
        plates
    };
    let demand = build_ok(
        &scene,
        &opts(atlastree::preprocess::layout::SplitRule::Demand),
    );
    let area = build_ok(
        &scene,
        &opts(atlastree::preprocess::layout::SplitRule::Area),
    );
    assert_sound(&demand.file);
    assert_sound(&area.file);
    let (d, a) = (plates_beside_tiles(&demand), plates_beside_tiles(&area));
    eprintln!(
        "plates in the tiles' half: demand split {d} of 16, area split {a} of 16 (nodes {} vs {})",
        demand.report.trees[0].nodes, area.report.trees[0].nodes
    );
    assert_eq!(a, 0, "the area split puts the tiles alone in the west half");
    assert!(
        (4..=12).contains(&d),
        "the demand split balances the plates' textures against the one shared tile texture: {d}"
    );
}

/// Adds `by` to every position, rounding as f64 does (the scene's coordinates are not representable
/// after the translation, as in real data).
fn translated(scene: &Scene, by: DVec3) -> Scene {
    let mut s = scene.clone();
    for v in &mut s.vertices {
        v.pos += by;
    }
    s
}

/// A scene with coordinates that lose bits when moved to UTM size: vertices at irrational-looking
/// offsets.
fn jittered_city() -> Scene {
    let mut s = atlastree::scene::synthetic::small_city(3, 64);
    for (i, v) in s.vertices.iter_mut().enumerate() {
        let j = (i as f64 * 0.618_033_988_749_895).fract();
        v.pos += DVec3::new(j * 0.731, 0.0, (1.0 - j) * 0.377);
    }
    s
}

/// The same scene under an extra translation of (4.5e6, 120, 5.5e6) — positions rounded to f64 at that
/// size, so every midpoint and area differs in its last bits — gives the identical tree: every node's level,
/// cell, children and triangle set, every leaf's rects.
#[test]
fn a_translated_scene_gives_the_identical_tree() {
    let scene = jittered_city();
    let moved = translated(&scene, DVec3::new(4.5e6, 120.0, 5.5e6));
    // The translation really rounds: some positions differ from exact after moving back.
    let rounded = scene
        .vertices
        .iter()
        .zip(&moved.vertices)
        .filter(|(a, b)| (b.pos - DVec3::new(4.5e6, 120.0, 5.5e6)) != a.pos)
        .count();
    assert!(rounded > 100, "{rounded} positions rounded");
    for opts in [
        BuildOptions {
            d_min: DMin::Ratio(60.0),
            ..tiny_opts(128, 1.0)
        },
        BuildOptions {
            d_min: DMin::Ratio(60.0),
            atlas_size: 128,
            max_file_bytes: 256 << 20,
            ..BuildOptions::default()
        },
    ] {
        let a = build_ok(&scene, &opts);
        let b = build_ok(&moved, &opts);
        let (ta, tb) = (a.file.tree(0).unwrap(), b.file.tree(0).unwrap());
        assert!(ta.nodes.len() > 1, "want a multi-node tree");
        assert_eq!(ta.nodes.len(), tb.nodes.len());
        for (i, (x, y)) in ta.nodes.iter().zip(tb.nodes).enumerate() {
            assert_eq!(
                (x.level, x.cell, x.children, x.first_index, x.index_count),
                (y.level, y.cell, y.children, y.first_index, y.index_count),
                "node {i}"
            );
        }
        assert_eq!(ta.source_triangles, tb.source_triangles, "triangle sets");
        for (x, y) in ta.leaves.iter().zip(tb.leaves) {
            let (rx, ry) = (ta.leaf_rects(x), tb.leaf_rects(y));
            assert_eq!(rx.len(), ry.len());
            for (p, q) in rx.iter().zip(ry) {
                assert_eq!(
                    (p.material, p.outer, p.inner, p.flags),
                    (q.material, q.outer, q.inner, q.flags)
                );
            }
        }
        eprintln!(
            "translated by (4.5e6, 120, 5.5e6), {rounded} positions rounded: {} nodes, identical",
            ta.nodes.len()
        );
    }
}

/// One triangle whose UVs span ±2.9e9 repetitions: it builds (one period), verifies, and the shader's
/// mapping gives finite texels inside the rect at its vertices and across it.
#[test]
fn a_uv_range_of_2_9e9_builds_and_maps_without_nan() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("t", 32, 7);
    for (i, wrap) in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge]
        .into_iter()
        .enumerate()
    {
        let m = b.material(img, [wrap; 2], AlphaMode::Opaque);
        let x = i as f64 * 200.0;
        b.triangle(
            [
                DVec3::new(x, 0.0, 0.0),
                DVec3::new(x + 100.0, 0.0, 0.0),
                DVec3::new(x, 0.0, 100.0),
            ],
            [
                DVec2::new(-2.9e9, -2.9e9),
                DVec2::new(2.9e9, -2.9e9),
                DVec2::new(-2.9e9, 2.9e9),
            ],
            m,
        );
    }
    let built = build_ok(&b.build(), &tiny_opts(128, 50.0));
    assert_sound(&built.file);
    let t = built.file.tree(0).unwrap();
    let size = built.file.to_params().atlas_size as f32;
    let mut checked = 0;
    for leaf in t.leaves {
        let rects = t.leaf_rects(leaf);
        for k in 0..leaf.index_count as usize / 3 {
            let (_, v) = leaf_triangle(&t, leaf.origin, leaf.first_index as usize / 3 + k);
            let r = rects[v[0].rect as usize].decode();
            assert!(
                r.uv_max[0] - r.uv_min[0] <= 1.0 && r.uv_max[1] - r.uv_min[1] <= 1.0,
                "{r:?}"
            );
            let map = RectMap::new(&r, atlastree::scene::AlphaMode::Opaque);
            // The vertices and points across the triangle, with the enormous gradients such a triangle
            // has on screen.
            for a in [0.0f32, 0.25, 0.5, 1.0] {
                for c in [0.0f32, 0.3, 1.0 - a] {
                    let uv = Vec2::from(v[0].orig_uv) * (1.0 - a - c)
                        + Vec2::from(v[1].orig_uv) * a
                        + Vec2::from(v[2].orig_uv) * c;
                    let (texel, gx, gy) =
                        map.texel_f32(uv, Vec2::new(1e8, 0.0), Vec2::new(0.0, 1e8), 1.0);
                    assert!(
                        texel.is_finite() && gx.is_finite() && gy.is_finite(),
                        "{uv} → {texel} {gx} {gy}"
                    );
                    let lo = Vec2::new(r.outer[0] as f32, r.outer[1] as f32);
                    let hi = lo + Vec2::new(r.outer[2] as f32, r.outer[3] as f32);
                    assert!(
                        texel.cmpge(lo).all()
                            && texel.cmple(hi).all()
                            && texel.cmple(Vec2::splat(size)).all(),
                        "{texel} outside {lo}..{hi}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked >= 3 * 12, "{checked}");
}

/// Repeated textures of 1–7 texels of noise, built with BC1 and BC7 (border 0 too): `verify` passes. Their
/// periods are shorter than two 4×4 blocks, so a border and its partner share blocks with the texture's
/// own detail and block compression moves them apart by as much as it flattens that detail (21 levels in
/// BC1 on a 5 × 7 noise texture); the check refused every such fresh build (fault hunt, session 27).
#[test]
fn tiny_repeated_noise_textures_verify_under_block_compression() {
    use atlastree::texfmt::Compression;
    let mut b = SceneBuilder::new(UpAxis::Y);
    let sizes = [
        (1, 1),
        (2, 2),
        (1, 4),
        (4, 1),
        (3, 3),
        (2, 5),
        (4, 4),
        (5, 7),
    ];
    for (i, &(w, h)) in sizes.iter().enumerate() {
        // Every other one alpha-tested, its first texel transparent (the alpha tree's BC3 or BC7).
        let masked = i % 2 == 1;
        let noise = move |x: u32, y: u32| {
            let v = (x * 7919 + y * 104_729 + i as u32 * 31) ^ 0x5bd1_e995;
            let v = v.wrapping_mul(0x2c1b_3c6d);
            let a = if masked && x == 0 && y == 0 { 0 } else { 255 };
            [(v >> 24) as u8, (v >> 16) as u8, (v >> 8) as u8, a]
        };
        let img = b.image(&format!("t{i}"), w, h, noise);
        let alpha = if masked {
            AlphaMode::Mask { cutoff: 0.5 }
        } else {
            AlphaMode::Opaque
        };
        let m = b.material(img, [Wrap::Repeat; 2], alpha);
        let (x, z) = (12.0 * (i % 4) as f64, 12.0 * (i / 4) as f64);
        let c = [(x, z), (x + 10.0, z), (x + 10.0, z + 10.0), (x, z + 10.0)];
        b.quad(
            c.map(|(x, z)| DVec3::new(x, 0.0, z)),
            DVec2::ZERO,
            DVec2::splat(20.0),
            m,
        );
    }
    let scene = b.build();
    for (compress, border) in [(Compression::Bc1, 16), (Compression::Bc7, 0)] {
        let opts = BuildOptions {
            compress,
            border,
            ..BuildOptions::default()
        };
        let built = build_ok(&scene, &opts);
        assert_sound(&built.file);
    }
}

/// Two more fresh builds `verify` refused: repeated 64² textures at `--border 1` in BC1 (a border narrower
/// than a block is encoded with the texture's own detail: 17.9 levels against a tolerance of 16), and a
/// clamp-to-edge axis whose UVs lie wholly outside `[0, 1]` without the source cap (stored as the one
/// edge line every sample reads, which the period check counted as 1 texel per period).
#[test]
fn narrow_borders_in_bc1_and_collapsed_clamp_axes_verify() {
    use atlastree::texfmt::Compression;
    let mut b = SceneBuilder::new(UpAxis::Y);
    for i in 0..8 {
        let img = b.pattern_image(&format!("p{i}"), 64, i);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let (x, z) = (3.0 * (i % 4) as f64, 3.0 * (i / 4) as f64);
        let c = [(x, z), (x + 2.0, z), (x + 2.0, z + 2.0), (x, z + 2.0)];
        b.quad(
            c.map(|(x, z)| DVec3::new(x, 0.0, z)),
            DVec2::ZERO,
            DVec2::splat(3.0),
            m,
        );
    }
    let built = build_ok(
        &b.build(),
        &BuildOptions {
            compress: Compression::Bc1,
            border: 1,
            atlas_size: 128,
            d_min: DMin::Metres(0.02),
            ..BuildOptions::default()
        },
    );
    assert_sound(&built.file);
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("edge", 64, 3);
    let m = b.material(img, [Wrap::ClampToEdge; 2], AlphaMode::Opaque);
    let c = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
    b.quad(
        c.map(|(x, z)| DVec3::new(x, 0.0, z)),
        DVec2::new(0.0, 1.0),
        DVec2::new(1.0, 2.0),
        m,
    );
    let built = build_ok(
        &b.build(),
        &BuildOptions {
            cap_to_source: false,
            ..BuildOptions::default()
        },
    );
    assert_sound(&built.file);
}
