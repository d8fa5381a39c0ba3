//! Palette textures (`preprocess::palette`): quads whose UVs all sit on one texel of a small palette,
//! the way game levels paint whole models. Each cell a material's constant-UV triangles show gets a rect
//! of its own: 1 × 1 inner, the cell's exact colour, in a leaf scaled far below its sources' resolution
//! as at scale 1 (before: one rect of the used palette shrunk with the leaf, each texel a mix of 4 × 4
//! cells at scale 1/4). Past the limit the build keeps one rect and warns, naming the material.

use crate::built::*;
use atlastree::ids::{BlockId, MaterialId};
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// The palette's colour of cell `(x, y)`: every cell differs from its neighbours by ≥ 40 levels.
fn cell_colour(x: u32, y: u32) -> [u8; 4] {
    [
        (x * 97 + y * 13) as u8 % 200 + 40,
        (y * 71 + x * 29) as u8 % 200 + 40,
        ((x + 2 * y) % 3 * 100) as u8 + 20,
        255,
    ]
}

/// `cells` palette quads (0.2 m, each on one texel of a 16² REPEAT palette, the texel centre as its one
/// UV; with `jitter`, a second quad on each at a UV `jitter` away) beside 36 ground quads (0.9 m) of
/// distinct 64² textures, more than one 256² atlas holds at their source resolution. With `max_depth` 0 the root is the only leaf and is scaled to fit.
fn scene(cells: u32, jitter: f64) -> (Scene, MaterialId) {
    scene_with(cells, jitter, Variant::Constant)
}

/// How [`scene_with`] paints its palette quads beyond [`scene`]'s constant UVs.
#[derive(Clone, Copy, PartialEq)]
enum Variant {
    Constant,
    /// Each quad's UVs spread by this much about the texel's centre: float noise of an exporter within
    /// one quad when tiny, a well-formed mapping of that much of the palette (a texel magnified) when
    /// not.
    Spread(f64),
    /// One corner of each triangle this far from the others (UVs of no mapping: the sizing's edge fallback).
    OneCorner(f64),
    /// A MIRRORED_REPEAT palette, each cell painted at `uv` and again at `2 − uv` (the same texel).
    Mirrored,
}

fn scene_with(cells: u32, jitter: f64, variant: Variant) -> (Scene, MaterialId) {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let palette = b.image("palette", 16, 16, cell_colour);
    let wrap = if variant == Variant::Mirrored {
        Wrap::MirroredRepeat
    } else {
        Wrap::Repeat
    };
    let pm = b.material(palette, [wrap; 2], AlphaMode::Opaque);
    for i in 0..36 {
        let img = b.pattern_image(&format!("ground{i}"), 64, i);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let (x, z) = (f64::from(i % 6), f64::from(i / 6));
        ground_quad(&mut b, [x, z], 0.9, 1.0, m);
    }
    for k in 0..cells {
        let (cx, cy) = (k % 16, (k / 16 + 3 * k) % 16);
        let uv = DVec2::new((f64::from(cx) + 0.5) / 16.0, (f64::from(cy) + 0.5) / 16.0);
        let (x, z) = (0.25 * f64::from(k % 8), 6.0 + 0.25 * f64::from(k / 8));
        let c = [(x, z), (x + 0.2, z), (x + 0.2, z + 0.2), (x, z + 0.2)];
        match variant {
            Variant::Constant => b.quad(c.map(|(x, z)| DVec3::new(x, 0.0, z)), uv, uv, pm),
            Variant::Spread(d) => {
                let (lo, hi) = (uv - d / 2.0, uv + d / 2.0);
                b.quad(c.map(|(x, z)| DVec3::new(x, 0.0, z)), lo, hi, pm);
            }
            Variant::OneCorner(d) => {
                // About the texel's centre: two corners d/2 below it, one d/2 above.
                let p = c.map(|(x, z)| DVec3::new(x, 0.0, z));
                let (at, moved) = (uv - DVec2::splat(d / 2.0), uv + DVec2::splat(d / 2.0));
                b.triangle([p[0], p[1], p[2]], [at, at, moved], pm);
                b.triangle([p[0], p[2], p[3]], [at, moved, at], pm);
            }
            Variant::Mirrored => {
                b.quad(c.map(|(x, z)| DVec3::new(x, 0.0, z)), uv, uv, pm);
                let twin = DVec2::splat(2.0) - uv;
                b.quad(c.map(|(x, z)| DVec3::new(x, 0.2, z)), twin, twin, pm);
            }
        }
        if jitter != 0.0 {
            // A second quad on the same texel, its UV `jitter` away (float noise in real files).
            let uv = uv + DVec2::splat(jitter);
            b.quad(c.map(|(x, z)| DVec3::new(x, 0.1, z)), uv, uv, pm);
        }
    }
    (b.build(), pm)
}

/// Every stored palette triangle: its rect's inner is 1 × 1, holds the cell's colour in the leaf atlas
/// (level 0), in its parent's atlas (the four children halved: the texel under the inner one's centre,
/// §5.1) and as the rect's mean. Returns the palette triangles checked.
fn check_cells(built: &Built, pm: MaterialId) -> usize {
    let t = built.file.tree(0).expect("tree");
    let size = built.file.to_params().atlas_size as usize;
    let (mut checked, mut ancestors) = (0, 0);
    for leaf in t.leaves {
        let rects = t.leaf_rects(leaf);
        let atlas = built
            .file
            .block(BlockId(t.nodes[leaf.node as usize].atlas_block))
            .expect("leaf atlas");
        for k in 0..leaf.index_count as usize / 3 {
            let (_, v) = leaf_triangle(&t, leaf.origin, leaf.first_index as usize / 3 + k);
            let r = rects[v[0].rect as usize];
            if r.material != pm.0 {
                continue;
            }
            assert!(v.iter().all(|w| w.rect == v[0].rect), "one rect a triangle");
            assert_eq!(&r.inner[2..], &[1, 1], "a cell's rect: {r:?}");
            let uv = v[0].orig_uv;
            let want = cell_colour((uv[0] * 16.0) as u32, (uv[1] * 16.0) as u32);
            let i = (r.inner[1] as usize * size + r.inner[0] as usize) * 4;
            let got = &atlas[i..i + 4];
            let close = |a: &[u8], b: &[u8; 4]| a.iter().zip(b).all(|(&x, &y)| x.abs_diff(y) <= 1);
            assert!(
                close(got, &want),
                "cell at {uv:?}: stored {got:?}, palette {want:?}"
            );
            assert!(
                close(&r.mean, &want),
                "cell at {uv:?}: mean {:?}, palette {want:?}",
                r.mean
            );
            let node = &t.nodes[leaf.node as usize];
            if node.parent != atlastree::ids::NONE {
                let parent = built
                    .file
                    .block(BlockId(t.nodes[node.parent as usize].atlas_block))
                    .expect("parent atlas");
                // The child's quadrant in its parent: the low bit of its cell per axis.
                let half = size / 2;
                let px = (node.cell.ix & 1) as usize * half + r.inner[0] as usize / 2;
                let py = (node.cell.iy & 1) as usize * half + r.inner[1] as usize / 2;
                let i = (py * size + px) * 4;
                let got = &parent[i..i + 4];
                let near =
                    |a: &[u8], b: &[u8; 4]| a.iter().zip(b).all(|(&x, &y)| x.abs_diff(y) <= 2);
                assert!(
                    near(got, &want),
                    "cell at {uv:?}, one level up: {got:?}, palette {want:?}"
                );
                ancestors += 1;
            }
            checked += 1;
        }
    }
    if t.nodes.len() > 1 {
        assert_eq!(ancestors, checked, "every leaf has a parent");
    }
    checked
}

/// The defaults but 256² atlases with the paper's border: 36 distinct 64² textures within 6 m make leaves at their sources'
/// resolution that do not fit, scaled ([`atlastree::preprocess::layout`]'s `scaled_leaf`).
fn opts() -> atlastree::preprocess::BuildOptions {
    atlastree::preprocess::BuildOptions {
        atlas_size: 256,
        // The paper's border: 1 × 1 rects of 20², at most 20 of a material in a 256² atlas.
        border: 8,
        max_file_bytes: 256 << 20,
        ..Default::default()
    }
}

#[test]
fn palette_cells_keep_their_colours_in_a_scaled_leaf() {
    let (scene, pm) = scene(12, 0.0);
    let opts = opts();
    let built = build_ok(&scene, &opts);
    assert_sound(&built.file);
    let tree = &built.report.trees[0];
    assert_eq!(tree.leaves, 1);
    assert!(
        tree.leaf_reasons.scale_min < 0.5,
        "the root is scaled: {:?}",
        tree.leaf_reasons
    );
    let p = &tree.sizing.palette;
    assert_eq!((p.materials, p.cells, p.limit), (1, 12, 20));
    assert!(p.over_limit.is_empty());
    assert_eq!(check_cells(&built, pm), 24, "12 quads, 2 triangles each");
}

/// Quads whose own UVs spread by float noise (one f32 step at 0.5, 6·10⁻⁸), or whose triangles have one
/// corner a hundredth of a texel off the others (UVs of no mapping), are cells too, stored with their centre's one UV: they were sized as ordinary triangles, kept in one
/// rect at the source's resolution and drawn mixed with the neighbouring cells in the scaled leaf (15 dB
/// against 99 for their constant twins; session 30's hunt). A MIRRORED_REPEAT cell painted at `uv` and at
/// `2 − uv` is one cell (it counted two, past the limit with its twins).
#[test]
fn near_constant_and_mirrored_palette_uvs_are_cells() {
    for variant in [
        Variant::Spread(2f64.powi(-24)),
        Variant::OneCorner(1.0 / 16.0 / 100.0),
        Variant::Mirrored,
    ] {
        let (scene, pm) = scene_with(12, 0.0, variant);
        let built = build_ok(&scene, &opts());
        assert_sound(&built.file);
        let p = &built.report.trees[0].sizing.palette;
        assert_eq!((p.materials, p.cells), (1, 12), "{p:?}");
        let triangles = if variant == Variant::Mirrored { 48 } else { 24 };
        assert_eq!(check_cells(&built, pm), triangles);
        // Every palette triangle is stored with one UV, in the first period.
        let t = built.file.tree(0).unwrap();
        for leaf in t.leaves {
            for k in 0..leaf.index_count as usize / 3 {
                let (_, v) = leaf_triangle(&t, leaf.origin, leaf.first_index as usize / 3 + k);
                if t.leaf_rects(leaf)[v[0].rect as usize].material == pm.0 {
                    assert!(v.iter().all(|w| w.orig_uv == v[0].orig_uv), "{v:?}");
                    assert!(v[0].orig_uv.iter().all(|&u| (0.0..=1.0).contains(&u)));
                }
            }
        }
    }
}

/// A well-formed mapping of a hundredth of a texel (a texel magnified over a quad) is drawn as sized, not
/// as a cell: snapping such triangles faceted magnified terrain and pushed real palettes past their limit
/// (session 30's second palette hunt).
#[test]
fn a_magnified_texel_is_not_a_cell() {
    let (scene, _) = scene_with(12, 0.0, Variant::Spread(1.0 / 16.0 / 100.0));
    let built = build_ok(&scene, &opts());
    assert_sound(&built.file);
    let p = &built.report.trees[0].sizing.palette;
    assert_eq!((p.materials, p.cells), (0, 0), "{p:?}");
    assert!(p.over_limit.is_empty(), "{p:?}");
}

/// Two quads on each texel, their UVs 10⁻⁶ apart: each pair took one rect spanning the whole texel at the
/// source's resolution, which the scaled leaf averaged with the neighbouring texels (the palette hunt of
/// session 29: 16.98 dB against the truth where the original drew 31.67).
#[test]
fn palette_uvs_a_hair_apart_keep_their_colours_in_a_scaled_leaf() {
    let (scene, pm) = scene(12, 1e-6);
    let built = build_ok(&scene, &opts());
    assert_sound(&built.file);
    assert!(built.report.trees[0].leaf_reasons.scale_min < 0.5);
    assert_eq!(check_cells(&built, pm), 48, "24 quads, 2 triangles each");
}

#[test]
fn palette_cells_keep_their_colours_in_a_tree() {
    let (scene, pm) = scene(12, 0.0);
    let built = build_ok(&scene, &tiny_opts(256, 5.0));
    assert_sound(&built.file);
    assert!(
        built.report.trees[0].depth >= 2,
        "{:?}",
        built.report.trees[0]
    );
    assert_eq!(check_cells(&built, pm), 24);
}

#[test]
fn a_palette_past_the_limit_is_one_rect_and_a_warning() {
    let (scene, pm) = scene(24, 0.0);
    let opts = opts();
    let built = build_ok(&scene, &opts);
    assert_sound(&built.file);
    let p = &built.report.trees[0].sizing.palette;
    assert_eq!((p.materials, p.cells), (0, 0));
    assert_eq!(p.over_limit.len(), 1);
    assert_eq!(
        (p.over_limit[0].material, p.over_limit[0].cells),
        (pm.0, 24)
    );
    let warned = built
        .report
        .warnings
        .iter()
        .filter(|w| w.contains("24 distinct points") && w.contains(&format!("material {}", pm.0)))
        .count();
    assert_eq!(warned, 1, "{:#?}", built.report.warnings);
    // A shard that plans for itself says it too (only the one-process build did).
    let shard = atlastree::preprocess::build_shard(
        &scene,
        &opts,
        &built.dir.path().join("sharded.atlastree"),
        &atlastree::preprocess::ShardedOptions {
            spec: atlastree::preprocess::shard::ShardSpec { index: 0, count: 2 },
            argv: Vec::new(),
            import: None,
        },
        &atlastree::preprocess::NoProgress,
    )
    .expect("shard 0 of 2");
    let in_shard = (shard.warnings.iter())
        .filter(|w| w.contains("24 distinct points"))
        .count();
    assert_eq!(in_shard, 1, "{:#?}", shard.warnings);
    // One rect holds the palette's used cells, shrunk with the scaled leaf.
    let t = built.file.tree(0).unwrap();
    let rects = t.leaf_rects(&t.leaves[0]);
    assert_eq!(rects.iter().filter(|r| r.material == pm.0).count(), 1);
}
