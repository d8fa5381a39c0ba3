//! Image-side precision end to end (hard case 8 of issue 8). `preprocess/image_ops.rs` covers the filters
//! in isolation; this cross-reference builds an alpha tree (BLEND textures: opaque red discs on fully
//! transparent *black*) and reads the stored atlas blocks of the leaves and of the inner nodes (the 2×2
//! combinations halved, paper §5.1) with every mip level.
//!
//! Guards against the dark fringe of straight-alpha averaging: red 255 averaged with transparent black
//! gives dark red at the disc's edge, in every inner atlas and mip level, compounding per level (measured
//! below on the source textures). Ours filters premultiplied in linear light and bleeds colour into
//! transparent texels: every stored texel, transparent or not, is pure red.

use crate::built::*;
use atlastree::ids::{BlockId, NONE};
use atlastree::model::TreeKind;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// Six 20 m quads, each with its own 32² red disc on transparent black.
fn discs() -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    for i in 0..6u32 {
        let r = 9.0 + f64::from(i);
        let img = b.image(&format!("disc {i}"), 32, 32, move |x, y| {
            let (dx, dy) = (f64::from(x) - 15.5, f64::from(y) - 15.5);
            if dx * dx + dy * dy < r * r {
                [255, 0, 0, 255]
            } else {
                [0, 0, 0, 0]
            }
        });
        let m = b.material(img, [Wrap::ClampToEdge; 2], AlphaMode::Blend);
        grid_quad(&mut b, i, m);
    }
    b.build()
}

/// Splits a stored atlas block into its mip levels (RGBA8, level 0 first).
fn levels(block: &[u8], size: usize) -> Vec<(usize, &[u8])> {
    let mut out = Vec::new();
    let (mut off, mut s) = (0, size);
    loop {
        out.push((s, &block[off..off + s * s * 4]));
        off += s * s * 4;
        if s == 1 {
            break;
        }
        s /= 2;
    }
    assert_eq!(off, block.len());
    out
}

/// Straight-alpha 2×2 box halving of RGBA8 (the naive filter).
fn naive_halve(px: &[u8], s: usize) -> Vec<u8> {
    let h = s / 2;
    let mut out = vec![0u8; h * h * 4];
    for y in 0..h {
        for x in 0..h {
            for c in 0..4 {
                let at =
                    |dx: usize, dy: usize| u32::from(px[((2 * y + dy) * s + 2 * x + dx) * 4 + c]);
                out[(y * h + x) * 4 + c] =
                    ((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8;
            }
        }
    }
    out
}

#[test]
fn stored_alpha_atlases_have_no_dark_fringe_at_any_level() {
    let scene = discs();
    let b = build_ok(&scene, &tiny_opts(64, 120.0));
    assert_sound(&b.file);
    let t = b.file.tree(0).unwrap();
    assert_eq!(t.kind, TreeKind::Alpha);
    assert!(
        b.report.trees[0].depth >= 2,
        "want inner nodes: {:?}",
        b.report.trees[0]
    );
    let size = b.file.to_params().atlas_size as usize;
    let (mut partial_inner, mut transparent, mut checked) = (0, 0, 0);
    for n in t.nodes {
        let block = b.file.block(BlockId(n.atlas_block)).unwrap();
        for (_, px) in levels(&block, size) {
            for p in px.chunks_exact(4) {
                // Texels with alpha > 0: premultiplied filtering keeps them pure red. Texels with alpha 0
                // carry the bled colour of their nearest visible texel (red), so GPU bilinear filtering of
                // the straight-alpha texture does not pull black into the edge either.
                assert!(
                    p[0] >= 254 && p[1] <= 1 && p[2] <= 1,
                    "node level {}: fringe texel {p:?}",
                    n.level
                );
                checked += 1;
                transparent += usize::from(p[3] == 0);
                if n.leaf == NONE && p[3] > 0 && p[3] < 255 {
                    partial_inner += 1;
                }
            }
        }
    }
    assert!(
        partial_inner > 10,
        "inner atlases must have partial-alpha edges: {partial_inner}"
    );
    assert!(transparent > 1000, "{transparent}");
    // Naive: straight-alpha box halving of the same source textures, three levels.
    let mut naive_darkest = 255u8;
    for img in &scene.images {
        let d = img.decode().unwrap();
        let mut px: Vec<u8> = d.pixels.iter().flatten().copied().collect();
        let mut s = d.width as usize;
        for _ in 0..3 {
            px = naive_halve(&px, s);
            s /= 2;
            for p in px.chunks_exact(4).filter(|p| p[3] > 0) {
                naive_darkest = naive_darkest.min(p[0]);
            }
        }
    }
    assert!(naive_darkest <= 128, "{naive_darkest}");
    eprintln!(
        "alpha tree: {checked} stored texels checked in all atlases and mip levels, all pure red \
         ({partial_inner} partial-alpha texels in inner atlases, {transparent} transparent with bled colour); \
         naive straight-alpha halving of the source textures: darkest edge red {naive_darkest}/255"
    );
}

/// An OPAQUE material ignores its texture's alpha (glTF 2.0 §3.9.4): a texture whose alpha is 0 over
/// half its texels (game textures often carry alpha for other uses) must keep its colours there, in
/// the atlas and in the stored original, not the colour bled in from the visible half. Before the
/// decode forced alpha 1 for opaque-only images, those texels held the bled neighbour colour.
#[test]
fn opaque_materials_keep_the_colour_under_zero_alpha() {
    let texel = |x: u32, y: u32| -> [u8; 4] {
        let a = if x < 16 { 255 } else { 0 };
        [(x * 8) as u8, (y * 8) as u8, 200, a]
    };
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.image("logo", 32, 32, texel);
    let m = b.material(img, [Wrap::ClampToEdge; 2], AlphaMode::Opaque);
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(20.0, 0.0, 0.0),
            DVec3::new(20.0, 0.0, 20.0),
            DVec3::new(0.0, 0.0, 20.0),
        ],
        DVec2::ZERO,
        DVec2::ONE,
        m,
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("logo.atlastree");
    let opts = atlastree::preprocess::BuildOptions {
        // d_min small enough that the 32² source is capped: the rect holds it texel for texel.
        d_min: atlastree::preprocess::DMin::Ratio(200.0),
        atlas_size: 128,
        max_file_bytes: 1 << 30,
        ..Default::default()
    };
    let report =
        atlastree::preprocess::build(&b.build(), &opts, &out, &atlastree::preprocess::NoProgress)
            .unwrap();
    assert_eq!(report.images_alpha_ignored, 1);
    let f = atlastree::store::TreeFile::open(&out).unwrap();
    let t = f.tree(0).unwrap();
    assert_eq!(t.kind, TreeKind::Opaque);
    let leaf = &t.leaves[0];
    let rect = t.leaf_rects(leaf)[0];
    assert_eq!(
        &rect.inner[2..],
        &[32, 32],
        "the rect holds the source texel for texel"
    );
    let atlas = f
        .block(BlockId(t.nodes[leaf.node as usize].atlas_block))
        .unwrap();
    let size = 128usize;
    let mut worst = 0i32;
    for y in 0..32u32 {
        for x in 0..32u32 {
            let (ax, ay) = (rect.inner[0] + x, rect.inner[1] + y);
            let i = (ay as usize * size + ax as usize) * 4;
            let want = texel(x, y);
            for c in 0..3 {
                worst = worst.max((i32::from(atlas[i + c]) - i32::from(want[c])).abs());
            }
        }
    }
    assert!(
        worst <= 2,
        "atlas colours under alpha 0 differ by up to {worst} levels"
    );
    // The stored original (slot 0 of its block, level 0 first) holds the same colours.
    let o = t.leaf_originals(leaf)[0];
    assert_eq!(o.extent(), [32, 32]);
    let block = f.block(BlockId(o.block)).unwrap();
    let mut worst = 0i32;
    for y in 0..32u32 {
        for x in 0..32u32 {
            let i = (y as usize * 32 + x as usize) * 4;
            let want = texel(x, y);
            for c in 0..3 {
                worst = worst.max((i32::from(block[i + c]) - i32::from(want[c])).abs());
            }
        }
    }
    assert!(
        worst <= 2,
        "original colours under alpha 0 differ by up to {worst} levels"
    );
}
