//! Near-degenerate triangles (hard case 4 of issue 8): a UV triangle of area 1e-12 relative to its edges,
//! world slivers of aspect 1e6, zero-area world triangles, coincident vertices, coincident UVs.
//!
//! Guards against: the §5.2.1 estimate done naively, `|P_T(Tex_T⁻¹(e_k))|` with an unguarded 2×2 inverse.
//! For a UV triangle of relative area 1e-12 the inverse is ~1e12, so a 10 m triangle "needs" ~1e13 texels
//! per repetition (measured below): an absurd texture that no atlas holds, and (paper) a split that never
//! ends. Ours (`model::sizing::texels_per_uv`) falls back to the paper's edge estimate for ill-conditioned
//! UVs, flags point UVs, ignores zero-area world triangles, and always returns finite sizes; the tree
//! builds and verifies, and no atlas area exceeds what the triangles' world size asks for.

use crate::built::*;
use atlastree::model::sizing::{SizeMethod, texels_per_uv};
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

fn p(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}
fn t(u: f64, v: f64) -> DVec2 {
    DVec2::new(u, v)
}

/// (name, positions, UVs, expected sizing method)
fn cases() -> Vec<(&'static str, [DVec3; 3], [DVec2; 3], SizeMethod)> {
    let unit_uv = [t(0., 0.), t(1., 0.), t(0., 1.)];
    let tri = [p(0., 0., 0.), p(10., 0., 0.), p(0., 0., 10.)];
    vec![
        ("normal", tri, unit_uv, SizeMethod::Exact),
        (
            "uv area 1e-12 of its edges",
            tri,
            [t(0., 0.), t(1., 0.), t(0.5, 1e-12)],
            SizeMethod::EdgeFallback,
        ),
        (
            "world sliver aspect 1e6, uv sliver along",
            [p(0., 0., 0.), p(100., 0., 0.), p(50., 0., 1e-4)],
            [t(0., 0.), t(1., 0.), t(0.5, 1e-6)],
            SizeMethod::EdgeFallback,
        ),
        (
            "world sliver aspect 1e6, unit uv",
            [p(0., 0., 0.), p(100., 0., 0.), p(50., 0., 1e-4)],
            unit_uv,
            SizeMethod::Exact,
        ),
        (
            "zero-area world (collinear)",
            [p(0., 0., 0.), p(5., 0., 0.), p(10., 0., 0.)],
            unit_uv,
            SizeMethod::WorldDegenerate,
        ),
        (
            "two coincident world vertices",
            [p(0., 0., 0.), p(0., 0., 0.), p(0., 0., 10.)],
            unit_uv,
            SizeMethod::WorldDegenerate,
        ),
        (
            "all world vertices coincident",
            [p(3., 0., 3.); 3],
            unit_uv,
            SizeMethod::WorldDegenerate,
        ),
        (
            "all uvs equal",
            tri,
            [t(0.3, 0.7); 3],
            SizeMethod::AllUvEqual,
        ),
        (
            "two coincident uvs",
            tri,
            [t(0., 0.), t(0., 0.), t(0., 1.)],
            SizeMethod::EdgeFallback,
        ),
    ]
}

/// The unguarded §5.2.1 estimate: `max(|s_world|, |t_world|) · f` with the plain 2×2 inverse.
fn naive_size(pos: [DVec3; 3], uv: [DVec2; 3], f: f64) -> f64 {
    let (e1, e2) = (pos[1] - pos[0], pos[2] - pos[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.x * d2.y - d1.y * d2.x;
    let s = (e1 * d2.y - e2 * d1.y) / det;
    let tt = (e2 * d1.x - e1 * d2.x) / det;
    s.length().max(tt.length()) * f
}

fn scene() -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    for (i, (_, pos, uv, _)) in cases().into_iter().enumerate() {
        let img = b.pattern_image(&format!("t{i}"), 16, i as u32);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        // Spread the cases 150 m apart so they do not all share one leaf.
        let off = p(150.0 * i as f64, 0.0, 0.0);
        b.triangle(pos.map(|q| q + off), uv, m);
    }
    b.build()
}

#[test]
fn sizing_takes_the_guarded_path_and_stays_bounded() {
    let f = 10.0;
    let mut rows = Vec::new();
    for (name, pos, uv, method) in cases() {
        let e = texels_per_uv(pos, uv, f);
        assert_eq!(e.method, method, "{name}: {e:?}");
        assert!(e.w.is_finite() && e.h.is_finite(), "{name}: {e:?}");
        // Never more texels per repetition than the longest world edge over the shortest non-zero
        // step of U or V along an edge, times f (the edge estimate's bound), and none where every UV is
        // equal (no repetition to size).
        let longest = (0..3)
            .map(|i| (pos[(i + 1) % 3] - pos[i]).length())
            .fold(0.0, f64::max);
        let steps = (0..3).flat_map(|i| {
            let d = uv[(i + 1) % 3] - uv[i];
            [d.x.abs(), d.y.abs()]
        });
        let shortest = steps.filter(|&d| d > 0.0).fold(f64::INFINITY, f64::min);
        let bound = longest * f / shortest;
        assert!(
            e.w.max(e.h) <= bound * (1.0 + 1e-9),
            "{name}: {e:?} above {bound}"
        );
        rows.push((name, e, naive_size(pos, uv, f)));
    }
    let (_, ours, naive) = rows[1];
    assert_eq!(ours.w, 10.0 * f, "edge estimate: 10 m over 1 UV");
    assert!(naive > 1e12, "naive inverse: {naive}");
    for (name, e, naive) in rows {
        eprintln!(
            "{name:42} ours {:>12.4e} ({:?}), naive inverse {naive:.3e}",
            e.w.max(e.h),
            e.method
        );
    }
}

#[test]
fn degenerate_scene_builds_and_verifies() {
    let s = scene();
    // Large d_min: nothing is split. Small d_min without the source cap: the large ones are tessellated.
    for (d_min, cap) in [(500.0, true), (200.0, false)] {
        let o = atlastree::preprocess::BuildOptions {
            cap_to_source: cap,
            // The baked tree: big triangles are tessellated, never scaled.
            repeat: atlastree::preprocess::RepeatMode::Bake,
            ..tiny_opts(128, d_min)
        };
        let built = build_ok(&s, &o);
        assert_sound(&built.file);
        let rep = &built.report.trees[0];
        let sz = &rep.sizing;
        assert_eq!(rep.triangles, 9);
        assert_eq!(rep.clamped_leaves, 0, "{:?}", rep.leaf_reasons);
        let f = built.file.to_params().f_proj();
        // Counted per prepared piece: every piece carries its scene triangle's method.
        assert!(sz.world_degenerate >= 3 && sz.edge_fallback >= 3, "{sz:?}");
        assert!(sz.all_uv_equal >= 1 && sz.exact >= 2, "{sz:?}");
        assert_eq!(rep.pieces > 9, !cap, "{sz:?}");
        assert_eq!(sz.triangles, rep.pieces);
        let t = built.file.tree(0).unwrap();
        for leaf in t.leaves {
            for r in t.leaf_rects(leaf) {
                // The largest honest need: a 100 m edge at f texels per metre (+ ceil).
                let limit = (100.0 * f).ceil() as u32 + 1;
                assert!(
                    r.inner[2] <= limit && r.inner[3] <= limit,
                    "d_min {d_min}: {r:?} > {limit}"
                );
            }
        }
        eprintln!(
            "d_min {d_min}: {} pieces, {} leaves, sizing {sz:?}",
            rep.pieces, rep.leaves
        );
    }
}
