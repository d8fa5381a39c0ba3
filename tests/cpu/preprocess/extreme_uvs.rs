//! Extreme UVs (hard case 3 of issue 8): repeats of 1e3 and 1e4 on one triangle, UV offsets of ±1e5, UVs at
//! −2.9e9 (seen in real data), a clamped triangle spanning 2.9e9 repetitions, and non-finite UVs.
//!
//! Guards against: (a) the paper's A_tex, the UV bounding box of a texture's triangles in a node: two
//! triangles of one texture at +1e5 and −1e5 give an A_tex 2e5 repetitions wide, an area no atlas holds
//! (the split can only separate them, never shrink them); we shift each triangle's UVs by whole periods
//! (`prepare::period_shift`). (b) f32 UVs at −2.9e9: the f32 ulp there is 256 repetitions, so the
//! texture phase is lost entirely; the stored `orig_uv` is the shifted one. (c) NaN reaching a stored
//! vertex or the sizing; sizing must stay finite and every atlas area within the atlas, or the build must
//! fail naming the triangle.

use crate::built::*;
use atlastree::ids::MaterialId;
use atlastree::model::sizing::{SizeMethod, texels_per_uv};
use atlastree::preprocess::sizing::analyze_sizing;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

struct Case {
    scene: Scene,
    /// Material shared by the +1e5 and −1e5 quads.
    offsets: MaterialId,
    mirror: MaterialId,
    far: MaterialId,
}

fn quad_at(b: &mut SceneBuilder, x: f64, side: f64, uv0: DVec2, uv1: DVec2, m: MaterialId) {
    b.quad(
        [
            DVec3::new(x, 0.0, 0.0),
            DVec3::new(x + side, 0.0, 0.0),
            DVec3::new(x + side, 0.0, side),
            DVec3::new(x, 0.0, side),
        ],
        uv0,
        uv1,
        m,
    );
}

fn scene(non_finite: bool) -> Case {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let mat = |b: &mut SceneBuilder, i: u32, wrap: Wrap| {
        let img = b.pattern_image(&format!("tex {i}"), 16, i);
        b.material(img, [wrap; 2], AlphaMode::Opaque)
    };
    let rep3 = mat(&mut b, 0, Wrap::Repeat);
    let rep4 = mat(&mut b, 1, Wrap::Repeat);
    let offsets = mat(&mut b, 2, Wrap::Repeat);
    let far = mat(&mut b, 3, Wrap::Repeat);
    let mirror = mat(&mut b, 4, Wrap::MirroredRepeat);
    let clamp = mat(&mut b, 5, Wrap::ClampToEdge);
    // 1e3 repetitions on a 100 m quad, 1e4 on one 100 m triangle.
    quad_at(&mut b, 0.0, 100.0, DVec2::ZERO, DVec2::splat(1e3), rep3);
    b.triangle(
        [
            DVec3::new(110.0, 0.0, 0.0),
            DVec3::new(210.0, 0.0, 0.0),
            DVec3::new(110.0, 0.0, 100.0),
        ],
        [DVec2::ZERO, DVec2::new(1e4, 0.0), DVec2::new(0.0, 1e4)],
        rep4,
    );
    // One texture at +1e5 and at −1e5, side by side.
    quad_at(
        &mut b,
        220.0,
        20.0,
        DVec2::splat(1e5),
        DVec2::splat(1e5 + 2.0),
        offsets,
    );
    quad_at(
        &mut b,
        245.0,
        20.0,
        DVec2::splat(-1e5 - 2.0),
        DVec2::splat(-1e5),
        offsets,
    );
    // −2.9e9 with repeat and with mirrored repeat (phase 0.25).
    quad_at(
        &mut b,
        270.0,
        20.0,
        DVec2::splat(-2.9e9),
        DVec2::splat(-2.9e9 + 1.0),
        far,
    );
    quad_at(
        &mut b,
        295.0,
        20.0,
        DVec2::splat(-2.9e9 + 0.25),
        DVec2::splat(-2.9e9 + 1.75),
        mirror,
    );
    // Clamp-to-edge spanning 2.9e9 repetitions (ill-conditioned UV matrix: the edge fallback).
    b.triangle(
        [
            DVec3::new(320.0, 0.0, 0.0),
            DVec3::new(340.0, 0.0, 0.0),
            DVec3::new(340.0, 0.0, 20.0),
        ],
        [
            DVec2::new(-2.9e9, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
        ],
        clamp,
    );
    if non_finite {
        for (k, bad) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY]
            .into_iter()
            .enumerate()
        {
            let x = 350.0 + 10.0 * k as f64;
            b.triangle(
                [
                    DVec3::new(x, 0.0, 0.0),
                    DVec3::new(x + 5.0, 0.0, 0.0),
                    DVec3::new(x, 0.0, 5.0),
                ],
                [DVec2::ZERO, DVec2::new(bad, 0.0), DVec2::new(0.0, 1.0)],
                rep3,
            );
        }
    }
    Case {
        scene: b.build(),
        offsets,
        mirror,
        far,
    }
}

const D_MIN: f64 = 200.0;

#[test]
fn sizing_stays_finite_and_uses_the_expected_method() {
    let c = scene(true);
    let p = atlastree::preprocess::resolve_params(&c.scene, &tiny_opts(128, D_MIN))
        .unwrap()
        .0;
    let f = p.f_proj();
    let s = &c.scene;
    let tris = s
        .triangles
        .iter()
        .map(|t| (s.tri_positions(t), s.tri_uvs(t)));
    let r = analyze_sizing(tris, f);
    assert!(r.max_w.is_finite() && r.max_h.is_finite(), "{r:?}");
    // The largest need: the quad at −2.9e9, 20 m per repetition (exact although its UVs are at −2.9e9).
    assert!(
        (r.max_w - 20.0 * f).abs() < 1e-6 * f,
        "{} vs {}",
        r.max_w,
        20.0 * f
    );
    assert_eq!(
        r.world_degenerate, 3,
        "NaN/±inf UVs are ignored for sizing: {r:?}"
    );
    assert_eq!(r.edge_fallback, 1, "the clamped 2.9e9-wide triangle: {r:?}");
    assert_eq!(r.exact, r.triangles - 4, "{r:?}");
    let e = texels_per_uv(
        s.tri_positions(&s.triangles[9]),
        s.tri_uvs(&s.triangles[9]),
        f,
    );
    // The mirrored quad at −2.9e9 + 0.25: 20 m over 1.5 repetitions.
    assert_eq!(e.method, SizeMethod::Exact);
    assert!((e.w - 20.0 / 1.5 * f).abs() < 1e-6 * e.w, "{e:?}");
}

#[test]
fn extreme_uvs_build_bounded_finite_and_verified() {
    let c = scene(true);
    let built = build_ok(&c.scene, &tiny_opts(128, D_MIN));
    assert_sound(&built.file);
    let size = built.file.to_params().atlas_size;
    let t = built.file.tree(0).unwrap();
    let (mut offsets_extent, mut widest) = (0f64, 0f64);
    for leaf in t.leaves {
        for r in t.leaf_rects(leaf) {
            assert!(r.inner[2] <= size && r.inner[3] <= size, "{r:?}");
            assert!(
                r.uv_min.iter().chain(&r.uv_max).all(|x| x.is_finite()),
                "{r:?}"
            );
            let extent = (r.uv_max[0] - r.uv_min[0]).max(r.uv_max[1] - r.uv_min[1]);
            let wrap = c.scene.materials[r.material as usize].wrap[0];
            if wrap != Wrap::ClampToEdge {
                // Period-shifted: the area starts in [0, 2) and spans at most one triangle (≤ 1e4) + 1.
                assert!(r.uv_min.iter().all(|&u| (0.0..2.0).contains(&u)), "{r:?}");
                widest = widest.max(extent);
            }
            if r.material == c.offsets.0 {
                offsets_extent = offsets_extent.max(extent);
            }
        }
    }
    assert!(widest <= 1e4 + 1.0, "{widest}");
    // The ±1e5 quads share their texture: each leaf's area spans at most 2 repetitions.
    assert!(
        offsets_extent > 0.0 && offsets_extent <= 2.0,
        "{offsets_extent}"
    );
    let f = built.file.to_params().f_proj();
    let w = 20.0 / 2.0 * f; // texels per repetition of the offsets texture
    eprintln!(
        "±1e5 offsets, one texture: paper's A_tex spans {} repetitions = {:.0} texels wide; ours ≤ {} \
         repetitions = {:.0} texels",
        2e5 + 2.0,
        (2e5 + 2.0) * w,
        offsets_extent,
        offsets_extent * w
    );

    // Stored original UVs of the −2.9e9 textures are the shifted ones: small, with the phase intact.
    let mut mirror_u = Vec::new();
    let mut far_max = 0f32;
    for leaf in t.leaves {
        let originals = t.leaf_originals(leaf);
        for v in &t.vertices
            [leaf.first_vertex as usize..(leaf.first_vertex + leaf.vertex_count) as usize]
        {
            let m = originals[v.original as usize].material;
            if m == c.mirror.0 {
                mirror_u.push(v.orig_uv[0]);
            }
            if m == c.far.0 {
                far_max = far_max.max(v.orig_uv[0].abs()).max(v.orig_uv[1].abs());
            }
        }
    }
    assert!(far_max <= 1.0, "{far_max}");
    assert!(
        mirror_u.contains(&0.25) && mirror_u.contains(&1.75),
        "{mirror_u:?}"
    );
    assert!(mirror_u.iter().all(|u| (0.25..=1.75).contains(u)));
    // Naive: the source UVs rounded to f32.
    let naive_phase = |u: f64| {
        let d = (u as f32) as f64 - u;
        (d - d.round()).abs()
    };
    let lost = naive_phase(-2.9e9 + 0.25).max(naive_phase(-2.9e9 + 1.75));
    let ulp = (-2.9e9f32).next_up() - -2.9e9f32;
    eprintln!(
        "UV −2.9e9 + 0.25 / + 1.75 in f32: ulp {ulp} repetitions, phase off by {lost}; stored shifted UVs \
         exact (0.25, 1.75)"
    );
    assert_eq!(ulp, 256.0);
    assert!(lost >= 0.25);
}

#[test]
fn repeats_cost_texels_by_world_size_only() {
    // The 1e4-repeat triangle alone: its leaf area is its world size × f_proj, not 1e4 × texture width.
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("t", 64, 1);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    b.triangle(
        [
            DVec3::ZERO,
            DVec3::new(100.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 100.0),
        ],
        [
            DVec2::splat(5e4),
            DVec2::new(5e4 + 1e4, 5e4),
            DVec2::new(5e4, 5e4 + 1e4),
        ],
        m,
    );
    let scene = b.build();
    let baked = atlastree::preprocess::BuildOptions {
        repeat: atlastree::preprocess::RepeatMode::Bake,
        ..tiny_opts(256, 2000.0)
    };
    let built = build_ok(&scene, &baked);
    assert_sound(&built.file);
    let f = built.file.to_params().f_proj();
    let t = built.file.tree(0).unwrap();
    assert_eq!(t.leaves.len(), 1);
    let r = t.leaf_rects(&t.leaves[0])[0];
    let want = (100.0 * f).ceil() as u32;
    assert_eq!([r.inner[2], r.inner[3]], [want, want], "{r:?}");
    assert_eq!((r.uv_min, r.uv_max), ([0.0; 2], [1e4; 2]));
    // Wrapped in the shader: one period at the texels one period needs (100 m / 1e4 · f), ≥ 1.
    let wrapped = build_ok(&scene, &tiny_opts(256, 2000.0));
    assert_sound(&wrapped.file);
    let tw = wrapped.file.tree(0).unwrap();
    let rw = tw.leaf_rects(&tw.leaves[0])[0];
    let per_period = ((100.0 / 1e4 * f).ceil() as u32).max(1);
    assert_eq!([rw.inner[2], rw.inner[3]], [per_period; 2], "{rw:?}");
    assert_eq!((rw.uv_min, rw.uv_max), ([0.0; 2], [1.0; 2]));
    eprintln!(
        "1e4 repetitions of a 64² texture on a 100 m triangle: baked {want}² texels, wrapped {per_period}² \
         (source-resolution copy: {}²)",
        64e4
    );
}

/// A rect that holds its source's own resolution (the source cap) shows the source's texels, copied: its
/// UV range, `[0.1, 0.6]` of a 64-texel source here (texels 6.4 … 38.4), is widened to whole texels
/// (6 … 39), and one f32 step past a texel edge adds no texel. Fault hunt, session 27: both drew at
/// 28.3 and 25.7 dB against original mode, the texels resampled onto a grid off the source's. A repeated
/// texture's half-texel inset, `[0.5, 63.5] / 64`, is its whole period (session 28: kept off the grid, it
/// drew at 30.5 dB).
#[test]
fn a_rect_at_source_resolution_copies_the_source_texels() {
    let texel = |x: u32, y: u32| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 4) as u8, 255];
    let past_half = f64::from(f32::from_bits(0.5f32.to_bits() + 1));
    let (clamp, repeat) = (Wrap::ClampToEdge, Wrap::Repeat);
    for (lo, hi, wrap, first, last) in [
        (0.1, 0.6, clamp, 6u32, 39u32),
        (0.0, past_half, clamp, 0, 32),
        (0.5 / 64.0, 63.5 / 64.0, repeat, 0, 64),
    ] {
        let mut b = SceneBuilder::new(UpAxis::Y);
        let img = b.image("grid", 64, 64, texel);
        let m = b.material(img, [wrap; 2], AlphaMode::Opaque);
        // At least 64 texels per UV at d_min 0.5 (the source cap).
        let side = 40.0 * (hi - lo);
        let corners = [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side)];
        b.quad(
            corners.map(|(x, z)| DVec3::new(x, 0.0, z)),
            DVec2::splat(lo),
            DVec2::splat(hi),
            m,
        );
        let built = build_ok(&b.build(), &tiny_opts(256, 0.5));
        let t = built.file.tree(0).unwrap();
        let leaf = &t.leaves[0];
        let rect = t.leaf_rects(leaf)[0].decode();
        let n = last - first;
        assert_eq!(
            [rect.inner[2], rect.inner[3]],
            [n, n],
            "[{lo}, {hi}]: {rect:?}"
        );
        assert_eq!(rect.uv_min, [f64::from(first) / 64.0; 2]);
        assert_eq!(rect.uv_max, [f64::from(last) / 64.0; 2]);
        let node = &t.nodes[leaf.node as usize];
        let block = built
            .file
            .block(atlastree::ids::BlockId(node.atlas_block))
            .unwrap();
        let [ix, iy, ..] = rect.inner;
        for j in 0..n {
            for i in 0..n {
                let at = (((iy + j) * 256 + ix + i) * 4) as usize;
                let want = texel(first + i, first + j);
                assert_eq!(
                    block[at..at + 4],
                    want,
                    "[{lo}, {hi}]: rect texel ({i}, {j})"
                );
            }
        }
    }
}
