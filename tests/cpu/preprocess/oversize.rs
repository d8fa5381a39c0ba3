//! Oversize input (hard case 5 of issue 8): one triangle that alone needs more than the atlas; thousands of triangles with the
//! same midpoint; a scene that is a single point in the distribution plane.
//!
//! Guards against the paper's non-termination (§5.3 splits "until each node fits", which never happens
//! for a triangle larger than the atlas, and a spatial split of triangles with one midpoint never separates
//! them). Ours: an oversize triangle is tessellated up to `max_pieces` (the pieces tile it exactly and keep
//! `min_distance = d_min`), beyond that its leaf is clamped (reported; `min_distance = d_min / clamp`); the
//! area-balanced cut always leaves every child smaller than its parent, so equal midpoints and a point
//! footprint still terminate, with depth ≈ log4(n / leaf capacity); a scene that is one point in 3-D
//! cannot have a d_min derived from its size and is refused naming the parameter.

use crate::built::*;
use atlastree::preprocess::BuildError;
use atlastree::preprocess::BuildOptions;
use atlastree::preprocess::prepare::{PrepareOptions, prepare};
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// One 100 m triangle with 10 repetitions of a 256² texture.
fn one_big_triangle() -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("big", 256, 3);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    b.triangle(
        [
            DVec3::ZERO,
            DVec3::new(100.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 100.0),
        ],
        [DVec2::ZERO, DVec2::new(10.0, 0.0), DVec2::new(0.0, 10.0)],
        m,
    );
    b.build()
}

/// 128² atlases, no source cap, d_min such that the triangle needs 100 m · f ≈ 1000 texels per axis.
fn big_opts(max_pieces: u32) -> BuildOptions {
    BuildOptions {
        cap_to_source: false,
        max_pieces,
        // Tessellation and clamping are what baked repeats need (wrapped: one period, 100 texels).
        repeat: atlastree::preprocess::RepeatMode::Bake,
        ..tiny_opts(128, 69.3)
    }
}

fn tri_area(p: [DVec3; 3]) -> f64 {
    0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
}

#[test]
fn oversize_triangle_is_clamped_with_one_piece_and_split_by_default() {
    let scene = one_big_triangle();
    // max_pieces = 1: one leaf, clamped, min_distance = d_min / clamp_scale.
    let clamped = build_ok(&scene, &big_opts(1));
    assert_sound(&clamped.file);
    let r = &clamped.report.trees[0];
    assert_eq!((r.pieces, r.leaves, r.clamped_leaves), (1, 1, 1), "{r:?}");
    assert!(
        clamped
            .report
            .warnings
            .iter()
            .any(|w| w.contains("scaled down"))
    );
    let p = clamped.file.to_params();
    let t = clamped.file.tree(0).unwrap();
    let leaf = t.leaves[0];
    let need = 100.0 * p.f_proj(); // texels per axis at scale 1
    assert!(need > 900.0, "{need}");
    assert!(leaf.clamp_scale < 1.0 && leaf.clamp_scale > 0.0);
    assert_eq!(t.nodes[0].min_distance, p.d_min / leaf.clamp_scale);
    let rect = t.leaf_rects(&leaf)[0];
    let inner_max = f64::from(p.atlas_size - 2 * p.border);
    // The clamp is the largest that fits, to the bisection's precision (2^(40/4096) ≈ 0.7 %).
    assert!(need * leaf.clamp_scale <= inner_max, "{rect:?}");
    assert!(
        f64::from(rect.inner[2]) >= 0.95 * (inner_max - 4.0),
        "{rect:?}"
    );

    // Default: split into pieces that tile the triangle, nothing clamped, every leaf at d_min.
    let split = build_ok(&scene, &big_opts(BuildOptions::default().max_pieces));
    assert_sound(&split.file);
    let r = &split.report.trees[0];
    assert_eq!(r.clamped_leaves, 0, "{r:?}");
    assert!(r.pieces > 100 && r.leaves > 1, "{r:?}");
    let t = split.file.tree(0).unwrap();
    let mut covered = 0.0;
    let mut worst: f64 = 0.0;
    for leaf in t.leaves {
        assert_eq!(leaf.clamp_scale, 1.0);
        assert_eq!(t.nodes[leaf.node as usize].min_distance, p.d_min);
        let first = leaf.first_index as usize / 3;
        for k in 0..leaf.index_count as usize / 3 {
            let (pos, v) = leaf_triangle(&t, leaf.origin, first + k);
            covered += tri_area(pos);
            // The d_min guarantee holds for every piece at its own leaf.
            let uv = v.map(|v| vertex_atlas_texels(&t, leaf, &v));
            if let Some(ppt) = pixels_per_texel(pos, uv, f_proj_params(&p, p.d_min)) {
                worst = worst.max(ppt);
            }
        }
    }
    let want = tri_area(scene.tri_positions(&scene.triangles[0]));
    assert!(
        (covered - want).abs() <= 1e-6 * want,
        "pieces cover {covered} of {want}"
    );
    assert!(worst <= 1.01, "{worst} pixels per texel at d_min");
    let root_split = t.nodes[0].min_distance;
    let root_clamp = clamped.file.tree(0).unwrap().nodes[0].min_distance;
    eprintln!(
        "oversize triangle ({need:.0} texels/axis, 128 atlas): clamp scale {:.4}, clamped root min_distance \
         {root_clamp:.0} m (leaf at d_min/clamp); split into {} pieces in {} leaves, worst {worst:.3} pixels \
         per texel at d_min, root min_distance {root_split:.0} m",
        leaf.clamp_scale, r.pieces, r.leaves
    );
}

/// `n` triangles of equal area with exactly the same centroid (integer corners summing to 3·centre), each
/// with its own texture, so at most 9 share a 64² atlas.
fn same_midpoint(n: u32) -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let c = DVec3::new(500.0, 0.0, 500.0);
    for i in 0..n {
        let img = b.image(&format!("m{i}"), 4, 4, move |_, _| {
            [(i % 251) as u8, (i / 251) as u8, 99, 255]
        });
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        // Sheared copies of one triangle: equal areas (1.5 · 20 · 20), different shapes, one centroid.
        let d = DVec3::new(20.0, 0.0, 0.0);
        let e = DVec3::new(f64::from(i) - f64::from(n / 2), 0.0, 20.0);
        b.triangle(
            [c + d, c + e, c - d - e],
            [DVec2::ZERO, DVec2::X, DVec2::Y],
            m,
        );
    }
    b.build()
}

#[test]
fn thousands_of_triangles_with_one_midpoint_terminate() {
    let n = 2000;
    let scene = same_midpoint(n);
    let popts = PrepareOptions {
        f_proj: 1e-3,
        up: UpAxis::Y,
        cap_to_source: true,
        split_limit: 16.0,
        max_pieces: 4096,
        wrap: true,
        palette_cells: 0,
    };
    let infos = prepare(&scene, &(0..n).collect::<Vec<_>>(), &popts).infos;
    let mid = infos[0].mid;
    assert!(
        infos.iter().all(|t| t.mid == mid),
        "midpoints must coincide exactly"
    );
    // Naive: a spatial split at the mean midpoint puts every triangle on one side — no progress, forever.
    let below = infos.iter().filter(|t| t.mid.x < mid.x).count();
    assert_eq!(below, 0);

    let built = build_ok(&scene, &tiny_opts(64, 1e6));
    assert_sound(&built.file);
    let r = &built.report.trees[0];
    // 2000 textures, ≤ 9 per leaf: ≥ 223 leaves; the balanced cut gives depth ⌈log4(2000 / 9)⌉ + 1 at most.
    assert!(r.leaves >= 223, "{r:?}");
    assert!(r.depth <= 5, "depth {}", r.depth);
    eprintln!(
        "{n} triangles with one midpoint: spatial split moves {below} of {n}; ours: depth {}, {} leaves",
        r.depth, r.leaves
    );
}

/// `n` vertical triangles at one spot: needles (ε = 0, zero area) or walls ε wide.
fn vertical_at_one_spot(n: u32, eps: f64) -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    for i in 0..n {
        let img = b.image(&format!("v{i}"), 4, 4, move |_, _| {
            [(i % 256) as u8, 50, 50, 255]
        });
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let h = 10.0 + f64::from(i % 7);
        let a = f64::from(i) * 0.1;
        let off = DVec3::new(a.cos(), 0.0, a.sin()) * eps;
        b.triangle(
            [
                DVec3::new(7.0, 0.0, 7.0),
                DVec3::new(7.0, h, 7.0) + off,
                DVec3::new(7.0, h * 0.5, 7.0) - off,
            ],
            [DVec2::ZERO, DVec2::X, DVec2::Y],
            m,
        );
    }
    b.build()
}

#[test]
fn a_point_footprint_terminates_and_a_point_scene_is_refused() {
    for eps in [0.0, 1e-9] {
        let scene = vertical_at_one_spot(300, eps);
        let o = BuildOptions {
            d_min: atlastree::preprocess::DMin::Ratio(20.0),
            ..tiny_opts(64, 1.0)
        };
        let built = build_ok(&scene, &o);
        assert_sound(&built.file);
        let r = &built.report.trees[0];
        assert!(r.leaves >= 34 && r.depth <= 4, "ε {eps}: {r:?}");
        if eps == 0.0 {
            assert_eq!(r.sizing.world_degenerate, 300);
        } else {
            assert_eq!(r.sizing.exact, 300);
        }
        eprintln!(
            "300 vertical triangles at one spot, ε = {eps}: depth {}, {} leaves",
            r.depth, r.leaves
        );
    }
    // Every vertex at one point: d_min = diagonal / R = 0 is refused, naming the parameter.
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("p", 4, 0);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    for _ in 0..50 {
        b.triangle([DVec3::splat(3.0); 3], [DVec2::ZERO, DVec2::X, DVec2::Y], m);
    }
    let point = b.build();
    let o = BuildOptions {
        d_min: atlastree::preprocess::DMin::Ratio(20.0),
        ..tiny_opts(64, 1.0)
    };
    let Err((_, e)) = try_build(&point, &o) else {
        panic!("a point scene built with a d_min derived from its size")
    };
    assert!(
        matches!(e, BuildError::DegenerateExtent { diagonal, ratio, .. } if diagonal == 0.0 && ratio == 20.0),
        "{e}"
    );
    assert!(e.to_string().contains("all one point"), "{e}");
    assert!(e.to_string().contains("give --d-min"), "{e}");
    // With d_min given in metres it builds: one leaf, the paper's 1×1 area.
    let built = build_ok(&point, &tiny_opts(64, 10.0));
    assert_sound(&built.file);
    assert_eq!(built.report.trees[0].leaves, 1);
}

/// A scene wider than the f32 its vertices are stored in (relative to their leaf) holds is refused
/// whatever d_min says: with `--d-min` given it built and stored every vertex at 0, one point.
#[test]
fn a_scene_wider_than_an_f32_is_refused() {
    for (span, ok) in [(1e300, false), (1e39, false), (1e38, true)] {
        let mut b = SceneBuilder::new(UpAxis::Y);
        let img = b.pattern_image("p", 4, 0);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let (p, q, r) = (DVec3::ZERO, DVec3::X * span, DVec3::Z * span);
        b.triangle([p, q, r], [DVec2::ZERO, DVec2::X, DVec2::Y], m);
        let scene = b.build();
        let got = try_build(&scene, &tiny_opts(64, 1e37));
        match (ok, got) {
            (true, Ok(built)) => assert_sound(&built.file),
            (false, Err((_, BuildError::ExtentOverflow { extent, .. }))) => {
                assert_eq!(extent, span)
            }
            (_, Err((_, e))) => panic!("span {span}: {e}"),
            (false, Ok(_)) => panic!("span {span}: built"),
        }
    }
}

/// A d_min so small that the texel density at it, `screen width × texel ratio / (2 d_min tan(fov/2))`,
/// overflows would size every triangle at 0 texels (the coarsest tree, labelled the finest): it is
/// refused naming --d-min, in short numbers. Just above the overflow it builds the finest tree.
#[test]
fn a_d_min_whose_texel_density_overflows_is_refused() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("p", 16, 0);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    let (p, q, r) = (DVec3::ZERO, DVec3::X, DVec3::Z);
    b.triangle([p, q, r], [DVec2::ZERO, DVec2::X, DVec2::Y], m);
    let scene = b.build();
    let Err((_, e)) = try_build(&scene, &tiny_opts(64, 1e-307)) else {
        panic!("d_min 1e-307 built")
    };
    let msg = e.to_string();
    assert!(
        matches!(&e, BuildError::InvalidParam { name: "d-min", value, .. } if value == "1e-307"),
        "{msg}"
    );
    assert!(msg.contains("no finite texel density"), "{msg}");
    // 1e-300: f_proj ≈ 1.4e302, finite; every rect is capped to its 16² source.
    let fine = build_ok(&scene, &tiny_opts(64, 1e-300));
    assert_sound(&fine.file);
    assert_eq!(fine.report.trees[0].leaves, 1);
    // A ratio that makes d_min overflow: the message prints its numbers short (the subnormal 1e-320 is
    // stored as 9.99988867183e-321).
    let o = BuildOptions {
        d_min: atlastree::preprocess::DMin::Ratio(1e-320),
        ..tiny_opts(64, 1.0)
    };
    let Err((_, e)) = try_build(&scene, &o) else {
        panic!("d_min = diagonal / 1e-320 built")
    };
    let msg = e.to_string();
    assert!(
        msg.contains("diagonal / 9.99988867183e-321 is no distance"),
        "{msg}"
    );
    assert!(msg.len() < 400, "{} characters: {msg}", msg.len());
}

/// A texture whose single period needs far more than an atlas (no source cap) shrinks every texture of its
/// leaf with it; below scale 1/8 the build says so (`--no-source-cap` took hacienda's alpha tree to one
/// leaf at scale 0.001, 5.6× the scene's diagonal, without a word). Capped to its 64² source the period
/// fits, and nothing is said.
#[test]
fn a_leaf_shrunk_far_for_an_oversized_rect_is_warned_about() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("fine", 64, 4);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    ground_quad(&mut b, [0.0, 0.0], 10.0, 1.0, m);
    let scene = b.build();
    let build = |cap_to_source| {
        build_ok(
            &scene,
            &BuildOptions {
                cap_to_source,
                ..tiny_opts(256, 0.05)
            },
        )
    };
    let uncapped = build(false);
    let lr = &uncapped.report.trees[0].leaf_reasons;
    assert!(lr.oversized > 0 && lr.scale_min < 0.125, "{lr:?}");
    let warned =
        (uncapped.report.warnings.iter()).any(|w| w.contains("scaled for an oversized rect"));
    assert!(warned, "{:?}", uncapped.report.warnings);
    let capped = build(true);
    assert_eq!(capped.report.trees[0].leaf_reasons.oversized, 0);
    assert!(
        capped.report.warnings.is_empty(),
        "{:?}",
        capped.report.warnings
    );
}

/// A 4096 × 4 texture with the defaults: its source side alone is wider than the 256² atlas, so its leaf
/// is scaled far and the warning names that cause (it named only `--no-source-cap` and the texel ratio,
/// flags this build does not use); and its original is stored at 2048 × 4, the largest original class,
/// which the build says, naming the image and both sizes (it said nothing: close views and `--mode
/// original` drew a quarter of the source's texels without a word). A 64² texture gets neither warning
/// (the test above).
#[test]
fn a_source_wider_than_the_atlas_and_the_largest_original_class_is_warned_about() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.image("long strip", 4096, 4, |x, _| {
        [(x % 251) as u8, 90, 160, 255]
    });
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    ground_quad(&mut b, [0.0, 0.0], 10.0, 1.0, m);
    let built = build_ok(&b.build(), &tiny_opts(256, 0.05));
    let w = &built.report.warnings;
    let oversized = w
        .iter()
        .find(|w| w.contains("scaled for an oversized rect"));
    assert!(
        oversized.is_some_and(|w| w.contains("a source side above --atlas-size")),
        "{w:?}"
    );
    let downsampled = w.iter().find(|w| w.contains("stored at that size"));
    assert!(
        downsampled
            .is_some_and(|w| w.starts_with("1 original texture has")
                && w.contains("long strip 4096×4 → 2048×4")),
        "{w:?}"
    );
}

/// A 64² texture repeated 8 × 8 times over a 400 m ground, beside 16 small quads of their own textures
/// that make the tree split: `d_min` asks for far more texels per period than the source has, so the
/// ground's rects are capped at 64 (docs/DESIGN.md "Where the guarantee does not hold: capped rects above
/// their leaf"). The report says by how much they fall short above their leaves — each level up halves
/// them, so `one_up` is 2 where the need is at least twice the source, and the root's factor is
/// `min(2^depth, need / source)` — and with the cap off (rects as fine as asked) nothing is capped and
/// nothing falls short.
#[test]
fn capped_rects_report_how_far_short_they_fall_above_their_leaf() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let ground = b.pattern_image("ground", 64, 0);
    let m = b.material(ground, [Wrap::Repeat; 2], AlphaMode::Opaque);
    ground_quad(&mut b, [0.0, 0.0], 400.0, 8.0, m);
    for i in 0..16u32 {
        let img = b.pattern_image(&format!("q{i}"), 64, i + 1);
        let mq = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let (x, z) = (
            f64::from(i % 4) * 100.0 + 40.0,
            f64::from(i / 4) * 100.0 + 40.0,
        );
        ground_quad(&mut b, [x, z], 4.0, 1.0, mq);
    }
    let scene = b.build();
    let capped = build_ok(&scene, &tiny_opts(256, 50.0));
    let t = &capped.report.trees[0];
    let s = t.capped_shortfall;
    assert!(
        t.depth >= 1 && t.capped_rects > 0,
        "depth {}, capped {}",
        t.depth,
        t.capped_rects
    );
    assert_eq!(s.at_leaf, 1.0, "no leaf is scaled: {s:?}");
    assert_eq!(s.one_up, 2.0, "{s:?}");
    assert!(
        s.at_root >= s.one_up && s.at_root <= 2f64.powi(i32::from(t.depth)),
        "{s:?}"
    );
    let uncapped = build_ok(
        &scene,
        &BuildOptions {
            cap_to_source: false,
            max_file_bytes: 1 << 30,
            ..tiny_opts(256, 50.0)
        },
    );
    let u = &uncapped.report.trees[0];
    assert_eq!(
        (u.capped_rects, u.capped_shortfall),
        (0, Default::default())
    );
}

/// `--max-depth 0` is a tree of one leaf (it was refused as "must be from 1 to 30"): a scene that fits one
/// atlas builds one node per tree, one that does not is an error naming depth 0.
#[test]
fn max_depth_zero_builds_one_leaf_or_says_the_region_needs_more() {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let mats: Vec<_> = (0..8)
        .map(|i| {
            let img = b.pattern_image(&format!("t{i}"), 64, i);
            b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque)
        })
        .collect();
    for (i, &m) in mats.iter().enumerate() {
        ground_quad(&mut b, [30.0 * i as f64, 0.0], 10.0, 1.0, m);
    }
    let scene = b.build();
    let opts = |atlas| BuildOptions {
        max_depth: 0,
        ..tiny_opts(atlas, 0.05)
    };
    let one = build_ok(&scene, &opts(1024));
    assert_eq!(
        (one.report.trees[0].nodes, one.report.trees[0].depth),
        (1, 0)
    );
    let Err((_, e)) = try_build(&scene, &opts(128)) else {
        panic!("eight 64² textures fit one 128² atlas at depth 0")
    };
    assert!(e.to_string().contains("depth 0"), "{e}");
}

/// Under `--max-memory`, the pieces baked repeats cut a triangle into are counted before any is made:
/// the same triangle fits a budget whole and is refused cut, with the pieces named, and the budget the
/// refusal states fits (2,048 baked triangles accepted at 300 MiB once peaked at 1.08 GiB; fault hunt,
/// session 32).
#[test]
fn baked_pieces_count_against_the_memory_budget_before_they_exist() {
    let scene = one_big_triangle();
    let cut = build_ok(&scene, &big_opts(4096));
    let pieces = cut.report.trees[0].pieces;
    assert!(pieces > 100, "{pieces}");
    let per_piece = atlastree::preprocess::memory::BAKED_PIECE_BYTES;
    let probe = |max_memory: u64, max_pieces: u32| {
        let opts = BuildOptions {
            max_memory_bytes: Some(max_memory),
            ..big_opts(max_pieces)
        };
        try_build(&scene, &opts)
    };
    let Err((_, e)) = probe(1 << 20, 4096) else {
        panic!("1 MiB held the plan")
    };
    let BuildError::Memory(m) = e else {
        panic!("{e}")
    };
    assert_eq!(m.extra_pieces, pieces - 1, "{m}");
    let needed = m.needed_mib << 20;
    // One piece's worth less than the need of the cut plan still holds the whole triangle.
    assert!(probe(needed - (pieces - 1) * per_piece + (1 << 20), 1).is_ok());
    assert!(probe(needed, 4096).is_ok(), "the stated need must fit");
}
