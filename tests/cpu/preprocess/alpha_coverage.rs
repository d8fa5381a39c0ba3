//! Coverage-preserving alpha mips (`--alpha-mips coverage`, issue 26 part 2) on whole builds: a field of
//! alpha-tested textures like foliage (MASK, cutoff 0.5: scattered opaque texels, one in four by a hash of
//! the position, transparent between). Plain box mips lose that coverage within a few levels (a texel of
//! level 3 averages 64 of them, about a quarter opaque); with coverage kept every stored level of every
//! atlas and original texture passes about the share its level 0 does. BLEND textures are
//! never changed: a BLEND-only scene gives the same file with either setting.

use crate::built::*;
use atlastree::ids::BlockId;
use atlastree::preprocess::BuildOptions;
use atlastree::preprocess::image_ops::AlphaMips;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use atlastree::texfmt::mip_extents;

/// Nine 20 m quads in a 3 × 3 grid, each with its own 64² texture of scattered opaque texels.
fn fences(alpha: AlphaMode) -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    for i in 0..9u32 {
        let shade = 60 + 20 * i as u8;
        let img = b.image(&format!("leaves {i}"), 64, 64, move |x, y| {
            let h = (x.wrapping_mul(73_856_093)
                ^ y.wrapping_mul(19_349_663)
                ^ i.wrapping_mul(83_492_791))
            .wrapping_mul(2_654_435_761);
            if (h >> 16) % 4 == 0 {
                [shade, 200, 90, 255]
            } else {
                [0, 0, 0, 0]
            }
        });
        let m = b.material(img, [Wrap::ClampToEdge; 2], alpha);
        grid_quad(&mut b, i, m);
    }
    b.build()
}

fn opts(alpha_mips: AlphaMips) -> BuildOptions {
    // Every texture at its full 64² (capped to the source): nine do not fit one 128² atlas, so the tree
    // splits and has inner atlases; every leaf stores its originals too.
    BuildOptions {
        alpha_mips,
        ..tiny_opts(128, 5.0)
    }
}

/// Share of `px` (RGBA8) whose alpha passes a 0.5 cutoff as the GPU compares the stored byte.
fn passing(px: &[u8]) -> f64 {
    let n = px.len() / 4;
    px.chunks_exact(4).filter(|p| p[3] >= 128).count() as f64 / n as f64
}

/// The levels of a `w × h` RGBA8 chain starting at `bytes`.
fn chain_levels(bytes: &[u8], w: u32, h: u32) -> Vec<&[u8]> {
    let mut off = 0;
    mip_extents(w, h)
        .map(|(lw, lh)| {
            let n = 4 * (lw * lh) as usize;
            off += n;
            &bytes[off - n..off]
        })
        .collect()
}

/// Per level of a `w × h` RGBA8 chain starting at `bytes`: (texels, passing share).
fn chain_coverage(bytes: &[u8], w: u32, h: u32) -> Vec<(usize, f64)> {
    chain_levels(bytes, w, h)
        .into_iter()
        .map(|level| (level.len() / 4, passing(level)))
        .collect()
}

/// How near to `target` one alpha factor can bring the passing share of `level` (RGBA8): texels with
/// equal alpha bytes pass or fail together, so the reachable shares are those of "every byte ≥ b passes".
fn nearest_reachable(level: &[u8], target: f64) -> f64 {
    let n = (level.len() / 4) as f64;
    (1..=256u32)
        .map(|b| {
            let c = level
                .chunks_exact(4)
                .filter(|p| u32::from(p[3]) >= b)
                .count() as f64
                / n;
            (c - target).abs()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn coverage_mips_keep_the_alpha_tested_share_in_atlases_and_originals() {
    let scene = fences(AlphaMode::Mask { cutoff: 0.5 });
    let plain = build_ok(&scene, &opts(AlphaMips::Plain));
    let kept = build_ok(&scene, &opts(AlphaMips::Coverage));
    assert_sound(&kept.file);
    let size = kept.file.to_params().atlas_size;
    let (tp, tk) = (plain.file.tree(0).unwrap(), kept.file.tree(0).unwrap());
    assert_eq!(tk.nodes.len(), tp.nodes.len(), "same tree");
    assert!(tk.nodes.len() > 1, "want inner nodes: {}", tk.nodes.len());
    let (mut levels_checked, mut worst_plain, mut worst_kept) = (0, 1.0f64, 0.0f64);
    for (np, nk) in tp.nodes.iter().zip(tk.nodes) {
        let cp = chain_coverage(
            &plain.file.block(BlockId(np.atlas_block)).unwrap(),
            size,
            size,
        );
        let ck = chain_coverage(
            &kept.file.block(BlockId(nk.atlas_block)).unwrap(),
            size,
            size,
        );
        // Level 0 of a leaf is drawn from the sources alike; an inner node's level 0 is its children's
        // level 1, which coverage kept.
        if nk.leaf != atlastree::ids::NONE {
            assert_eq!(cp[0], ck[0], "node level {}: leaf level 0", nk.level);
        }
        let share0 = ck[0].1;
        assert!(share0 > 0.05, "node level {}: {share0}", nk.level);
        for (l, (&(n, p), &(_, k))) in cp.iter().zip(&ck).enumerate().skip(1) {
            if n < 16 * 16 {
                continue;
            }
            levels_checked += 1;
            // Whole alpha bytes pass or fail together, and areas' borders and the packing gaps between
            // them move the share a little per level: within 5 points of the atlas's own level 0.
            assert!(
                (k - share0).abs() <= 0.05,
                "node level {} mip {l}: kept {k:.3} against level 0 {share0:.3}",
                nk.level
            );
            worst_kept = worst_kept.max((k - share0).abs());
            if l >= 3 {
                // Where plain mips have thinned out, the kept share is the nearer one.
                assert!(
                    (k - share0).abs() < (p - share0).abs(),
                    "node level {} mip {l}: kept {k:.3}, plain {p:.3}, level 0 {share0:.3}",
                    nk.level
                );
                worst_plain = worst_plain.min(share0 - p);
            }
        }
    }
    assert!(levels_checked >= 3, "{levels_checked}");
    // Plain mips lose part of it from the third level on (measured: at least 5 points of ~25).
    assert!(
        worst_plain > 0.03,
        "plain mips kept coverage: {worst_plain}"
    );
    // Original textures: the whole texture is one MASK area (64² stored at its own side).
    let mut originals = 0;
    for (op, ok) in tp.originals.iter().zip(tk.originals) {
        let (w, h) = (u32::from(ok.width), u32::from(ok.height));
        assert_eq!((op.width, op.height), (ok.width, ok.height));
        let bytes_of = |file: &atlastree::store::TreeFile,
                        o: &atlastree::store::format::OriginalRecord| {
            let block = file.block(BlockId(o.block)).unwrap();
            let chain = 4 * mip_extents(w, h)
                .map(|(a, b)| (a * b) as usize)
                .sum::<usize>();
            block[o.slot as usize * chain..(o.slot as usize + 1) * chain].to_vec()
        };
        let plain_bytes = bytes_of(&plain.file, op);
        let (cp, ck) = (
            chain_coverage(&plain_bytes, w, h),
            chain_coverage(&bytes_of(&kept.file, ok), w, h),
        );
        assert_eq!(cp[0], ck[0]);
        let share0 = ck[0].1;
        let plain_levels = chain_levels(&plain_bytes, w, h);
        for (l, (&(n, p), &(_, k))) in cp.iter().zip(&ck).enumerate().skip(1) {
            // One texture is one area: its share is the reachable one nearest level 0's (to a texel).
            let best = nearest_reachable(plain_levels[l], share0);
            assert!(
                (k - share0).abs() <= best + 1.0 / n as f64 + 1e-9,
                "original mip {l}: {k:.3} against {share0:.3} (nearest reachable {best:.3})"
            );
            if l == 3 {
                assert!(
                    p < share0 / 2.0,
                    "plain original mip 3 passes {p:.3} of {share0:.3}"
                );
            }
        }
        originals += 1;
    }
    assert!(originals > 0, "the fixture stores original textures");
    eprintln!(
        "coverage mips: {levels_checked} atlas levels within {worst_kept:.3} of level 0's share \
         (plain lost at least {worst_plain:.3} from mip 3 on), {originals} originals kept too"
    );
}

#[test]
fn blend_textures_are_never_rescaled() {
    let scene = fences(AlphaMode::Blend);
    let plain = build_ok(&scene, &opts(AlphaMips::Plain));
    let kept = build_ok(&scene, &opts(AlphaMips::Coverage));
    let (a, b) = (
        std::fs::read(&plain.path).unwrap(),
        std::fs::read(&kept.path).unwrap(),
    );
    assert!(a == b, "a BLEND-only scene must give the same file");
}
