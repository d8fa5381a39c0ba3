//! Deep trees, depth 20–24 (hard case 1 of issue 8).
//!
//! Guards against: the paper's texture transform `fract(uv_root · 2^k)` in f32, which keeps only
//! `24 − k − log2(atlas)` bits below a texel: at depth 20 in a 1024 atlas it is off by tens of texels, at
//! depth 24 by the whole atlas. We store leaf-local atlas UVs plus the integer cell and do one exact
//! power-of-two scale and one rounding (`model::transform`). Also guards against seams: the children of
//! every node must tile its atlas square exactly (no gap, no overlap) at every level down to 24, and
//! against a depth cap that is not enforced.
//!
//! The scene forcing the depth is small (`tests/fixtures/peel_strip.rs`, shared with the GPU suite): a
//! strip of right triangles whose areas halve from one to the next, each with its own 4×4 texture. §5.3
//! cuts where the summed area is closest to half, so every split peels off the two largest triangles
//! (quadrants 0 and 1) and keeps all the others in quadrant 3; a node fits one 64² atlas only when it
//! has at most 9 textures (9 areas of 20×20 incl. the 8-texel border).
//! With `2D + 9` triangles the tree has depth exactly D and `3D + 1` nodes (≈ 1.5 MB at D = 22).

use crate::built::*;
use crate::fixtures::peel_strip::{peel_strip, strip_options};
use atlastree::ids::{Cell, Level, NONE};
use atlastree::model::transform::{atlas_uv_at, atlas_uv_at_f32, atlas_uv_naive_f32};
use atlastree::preprocess::BuildError;
use atlastree::preprocess::layout::LayoutError;
use glam::{DVec2, Vec2};

#[test]
fn depth_22_builds_verifies_and_the_depth_cap_is_enforced() {
    let built = build_ok(&peel_strip(22), &strip_options());
    let r = &built.report.trees[0];
    assert_eq!(r.depth, 22, "{r:?}");
    assert_eq!(r.nodes, 3 * 22 + 1);
    assert_eq!(r.leaves, 2 * 22 + 1);
    assert_sound(&built.file);
    let t = built.file.tree(0).unwrap();
    // The deepest leaf holds the 9 smallest triangles in cell (2^22 − 1, 2^22 − 1).
    let deep = t
        .nodes
        .iter()
        .find(|n| n.level == 22 && n.index_count == 27)
        .unwrap();
    assert_eq!(
        deep.cell,
        Cell {
            ix: (1 << 22) - 1,
            iy: (1 << 22) - 1
        }
    );
    assert_eq!(deep.index_count, 27);
    assert!(
        built.report.file_bytes < 4 << 20,
        "{}",
        built.report.file_bytes
    );

    // --max-depth is respected: the same scene with a cap of 21 is refused, naming the region and cap.
    let o = atlastree::preprocess::BuildOptions {
        max_depth: 21,
        ..strip_options()
    };
    let Err((dir, e)) = try_build(&peel_strip(22), &o) else {
        panic!("depth 22 built under --max-depth 21")
    };
    match &e {
        BuildError::Layout {
            source:
                LayoutError::DepthExceeded {
                    depth,
                    triangles,
                    lo,
                    hi,
                    ..
                },
            ..
        } => {
            assert_eq!(*depth, 21);
            assert_eq!(
                *triangles, 11,
                "the region that does not fit: 2 + 9 triangles"
            );
            assert!(lo.x > 0.0 && hi.x > lo.x, "{lo} {hi}");
        }
        other => panic!("expected DepthExceeded, got {other}"),
    }
    let msg = e.to_string();
    assert!(
        msg.contains("--max-depth 21") && msg.contains("region x∈["),
        "{msg}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "nothing written"
    );

    // The default cap is 24: a scene that needs depth 25 is refused by default, 24 builds.
    let Err((_, e)) = try_build(&peel_strip(25), &strip_options()) else {
        panic!("depth 25 built under the default --max-depth 24")
    };
    assert!(e.to_string().contains("--max-depth 24"), "{e}");
}

/// Texel coordinates (in texels of a `size` atlas) of the exact f64 transform, the shader's f32 form and
/// the paper's naive f32 form, at `level`.
fn texel_coords(uv: Vec2, cell: Cell, leaf: Level, level: Level, size: f64) -> [DVec2; 3] {
    [
        atlas_uv_at(uv.as_dvec2(), cell, leaf, level) * size,
        atlas_uv_at_f32(uv, cell, leaf, level).as_dvec2() * size,
        atlas_uv_naive_f32(uv, cell, leaf, level).as_dvec2() * size,
    ]
}

/// True if `got` lies in the same texel as `want`, allowing the neighbour only when `want` is within
/// `tol` texels of the texel boundary between them.
fn same_texel(want: DVec2, got: DVec2, tol: f64) -> bool {
    let axis = |w: f64, g: f64| {
        let (tw, tg) = (w.floor(), g.floor());
        tw == tg || ((w - w.round()).abs() <= tol && (tw - tg).abs() == 1.0)
    };
    axis(want.x, got.x) && axis(want.y, got.y)
}

#[test]
fn deep_leaves_sample_the_same_texel_as_f64_at_every_level() {
    let built = build_ok(&peel_strip(24), &strip_options());
    assert_eq!(built.report.trees[0].depth, 24);
    let t = built.file.tree(0).unwrap();
    let size = f64::from(built.file.to_params().atlas_size);
    // One f32 rounding of a value in [0, 1]: ≤ 2^-24, in texels of this atlas.
    let tol = 2f64.powi(-24) * size;
    let (mut checked, mut naive_wrong, mut worst_exact, mut worst_naive) = (0u64, 0u64, 0f64, 0f64);
    for leaf in t.leaves {
        let node = &t.nodes[leaf.node as usize];
        if node.level < 20 {
            continue;
        }
        let k = Level(node.level as u8);
        for tri in 0..(leaf.index_count / 3) as usize {
            let first = leaf.first_index as usize / 3 + tri;
            let (_, v) = leaf_triangle(&t, leaf.origin, first);
            let uvs = v.map(|v| vertex_leaf_uv(&t, leaf, &v, size as f32));
            for &uv in &uvs {
                assert!(uv.min_element() >= 0.0 && uv.max_element() <= 1.0, "{uv}");
            }
            for j in 0..=k.0 {
                let level = Level(j);
                // The vertices, and the centroid as the rasteriser interpolates the per-vertex results.
                let per_vertex = uvs.map(|uv| texel_coords(uv, node.cell, k, level, size));
                let centroid =
                    |i: usize| (per_vertex[0][i] + per_vertex[1][i] + per_vertex[2][i]) / 3.0;
                for c in per_vertex
                    .iter()
                    .copied()
                    .chain([[centroid(0), centroid(1), centroid(2)]])
                {
                    let [exact, f32form, naive] = c;
                    let err = (f32form - exact).abs().max_element();
                    worst_exact = worst_exact.max(err);
                    assert!(
                        err <= tol * 1.5,
                        "level {j} of a level-{} leaf: {err} texels",
                        k.0
                    );
                    assert!(
                        same_texel(exact, f32form, tol * 1.5),
                        "level {j}: {exact} vs {f32form}"
                    );
                    if j == k.0 {
                        worst_naive = worst_naive.max((naive - exact).abs().max_element());
                        naive_wrong += u64::from(!same_texel(exact, naive, tol * 1.5));
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 1500, "{checked}");
    eprintln!(
        "depth-24 tree, leaves at levels 20–24, all ancestor levels: {checked} samples; exact form worst \
         {worst_exact:.2e} texels; naive fract form at the leaf's own level: worst {worst_naive:.1} texels, \
         {naive_wrong} samples in the wrong texel"
    );
    // The naive form is off by many texels this deep (64² atlas, depth ≥ 20: ≥ 2^(20−24)·64 = 4 texels).
    assert!(worst_naive >= 4.0 && naive_wrong > 0, "{worst_naive}");
}

#[test]
fn children_tile_their_parent_exactly_at_every_level() {
    let built = build_ok(&peel_strip(24), &strip_options());
    let t = built.file.tree(0).unwrap();
    let mut squares = 0;
    for (ni, n) in t.nodes.iter().enumerate() {
        let level = Level(n.level as u8);
        // The node's atlas square, seen at every ancestor level, is exact in f32 (so the squares of
        // siblings share their edges bit for bit).
        for j in 0..=level.0 {
            for corner in [Vec2::ZERO, Vec2::ONE, Vec2::X, Vec2::Y] {
                let want = atlas_uv_at(corner.as_dvec2(), n.cell, level, Level(j));
                let got = atlas_uv_at_f32(corner, n.cell, level, Level(j));
                assert_eq!(
                    got.as_dvec2(),
                    want,
                    "node {ni} corner {corner} at level {j}"
                );
            }
            squares += 1;
        }
        // Children: exactly the quadrant squares of the parent's atlas.
        for (q, &c) in n.children.iter().enumerate() {
            if c == NONE {
                continue;
            }
            let ch = &t.nodes[c as usize];
            assert_eq!(ch.cell, n.cell.child(q as u32));
            let lo = atlas_uv_at_f32(Vec2::ZERO, ch.cell, Level(ch.level as u8), level);
            let hi = atlas_uv_at_f32(Vec2::ONE, ch.cell, Level(ch.level as u8), level);
            let q_lo = Vec2::new((q & 1) as f32, (q >> 1) as f32) * 0.5;
            assert_eq!(
                (lo, hi),
                (q_lo, q_lo + Vec2::splat(0.5)),
                "node {ni} child {q}"
            );
        }
    }
    assert!(squares > 900, "{squares}");
}

/// The naive `fract(uv_root · 2^k)` f32 error at a leaf's own level, against the exact form, in texels of
/// a 1024 atlas: measured over cells near the far corner of the root (largest root UVs) and a grid of UVs.
/// Returns (worst error modulo the atlas width, samples that wrapped to the opposite edge, exact form's
/// worst error).
fn measure(k: u8) -> (f64, u32, f64) {
    let n = (1u64 << k) as u32;
    let (mut naive, mut wraps, mut exact) = (0f64, 0u32, 0f64);
    for c in 0..64u32 {
        let cell = Cell {
            ix: n - 1 - c * 7 % n.max(1),
            iy: n - 1 - (c * 13) % n.max(1),
        };
        for s in 0..64 {
            let uv = Vec2::new(
                (s as f32 + 0.37) / 64.0,
                ((s * 29 % 64) as f32 + 0.61) / 64.0,
            );
            let want = atlas_uv_at(uv.as_dvec2(), cell, Level(k), Level(k));
            let e = |got: Vec2| (got.as_dvec2() - want).abs().max_element() * 1024.0;
            // fract() of a root UV rounded up to the next cell gives 0 instead of ~1: a wrap.
            let err = e(atlas_uv_naive_f32(uv, cell, Level(k), Level(k)));
            wraps += u32::from(err > 512.0);
            naive = naive.max(err.min(1024.0 - err));
            exact = exact.max(e(atlas_uv_at_f32(uv, cell, Level(k), Level(k))));
        }
    }
    (naive, wraps, exact)
}

#[test]
fn naive_fract_error_at_depth_16_20_24_in_texels_of_a_1024_atlas() {
    let mut rows = Vec::new();
    for k in [16u8, 20, 24] {
        let (naive, wraps, exact) = measure(k);
        rows.push((k, naive, wraps, exact));
        // Expected: half an ulp of the root UV times 2^k: 2^(k−24) atlas widths = 2^(k−14) texels.
        let predicted = 2f64.powi(i32::from(k) - 14);
        assert!(
            naive >= 0.25 * predicted && naive <= predicted,
            "depth {k}: naive {naive}"
        );
        assert_eq!(
            exact, 0.0,
            "depth {k}: the leaf's own level is the identity"
        );
    }
    for (k, naive, wraps, exact) in rows {
        eprintln!(
            "depth {k}: naive fract f32 error {naive:.1} texels (1024 atlas, modulo wrap), {wraps}/4096 samples \
             wrapped to the opposite edge; exact form {exact}"
        );
    }
}

mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]

        /// The shader's f32 form is within one f32 rounding (2^-24) of the f64 reference at every
        /// (leaf level ≤ 30, ancestor level, cell, uv); the identity at the leaf's own level.
        #[test]
        fn f32_exact_form_within_2_pow_minus_24(k in 0u8..=30, j_frac in 0.0f64..=1.0,
                                                 cx in any::<u32>(), cy in any::<u32>(),
                                                 u in 0.0f32..=1.0, v in 0.0f32..=1.0) {
            let j = ((f64::from(k) * j_frac).floor() as u8).min(k);
            let mask = if k >= 32 { u32::MAX } else { ((1u64 << k) - 1) as u32 };
            let cell = Cell { ix: cx & mask, iy: cy & mask };
            let uv = Vec2::new(u, v);
            let want = atlas_uv_at(uv.as_dvec2(), cell, Level(k), Level(j));
            let got = atlas_uv_at_f32(uv, cell, Level(k), Level(j)).as_dvec2();
            prop_assert!((want - got).abs().max_element() <= 2f64.powi(-24),
                         "k {} j {} cell {:?} uv {}: {} vs {}", k, j, cell, uv, want, got);
            prop_assert!(want.min_element() >= 0.0 && want.max_element() <= 1.0);
            if j == k {
                prop_assert_eq!(got, uv.as_dvec2());
            }
        }

        /// Going up one level at a time equals going up directly (the transform composes), in f64.
        #[test]
        fn transform_composes(k in 1u8..=30, cx in any::<u32>(), cy in any::<u32>(),
                              u in 0.0f64..=1.0, v in 0.0f64..=1.0) {
            let mask = ((1u64 << k) - 1) as u32;
            let cell = Cell { ix: cx & mask, iy: cy & mask };
            let uv = DVec2::new(u, v);
            let one_up = atlas_uv_at(uv, cell, Level(k), Level(k - 1));
            let parent = Cell { ix: cell.ix >> 1, iy: cell.iy >> 1 };
            for j in 0..k {
                let direct = atlas_uv_at(uv, cell, Level(k), Level(j));
                let via = atlas_uv_at(one_up, parent, Level(k - 1), Level(j));
                prop_assert!((direct - via).abs().max_element() <= 2.0 * f64::EPSILON, "{} {}", direct, via);
            }
        }
    }
}
