//! The build's report and its warnings: the finished build's [`BuildReport`], what planning the trees
//! warns about ([`tree_warnings`], said alike by a one-process build, a self-planning shard and the plan
//! step) and the image cache's resized originals.

use super::{AtlasForest, BuildParams, BuildReport, StageLog, TreeReport};
use std::sync::atomic::Ordering;

/// Below this scale, leaves scaled for an oversized rect are warned about: the whole leaf shrinks with
/// its one oversized texture (`--no-source-cap` took hacienda's opaque root to one leaf at 770 m, its
/// alpha tree to scale 0.001, 5.6× the scene's diagonal, without a word).
const OVERSIZED_WARN_SCALE: f64 = 0.125;

/// The warnings for original textures stored smaller than their source, and for those stored larger on a
/// side: how many, and the first few by name with both sizes.
pub(super) fn resized_warnings(cache: &super::image_cache::ImageCache<'_>) -> Vec<String> {
    let mut out = Vec::new();
    if let Ok(d) = cache.downsampled.lock()
        && !d.is_empty()
    {
        let (list, what, them) = resized_list(cache, &d);
        out.push(format!(
            "{} {what} a side above {} texels, stored at that size ({list}): views nearer than the \
             leaf's min_distance and --mode original draw {them} at that resolution",
            d.len(),
            crate::model::MAX_ORIGINAL_CLASS,
        ));
    }
    // Said as the downsampled ones are: a 48 × 80 original stored at 64 × 128 drew 31.9 dB from an exact
    // bilinear of its source where the tree drew 57.8, and nothing said why (fault hunt, session 31).
    if let Ok(u) = cache.upsampled.lock()
        && !u.is_empty()
    {
        let (list, what, _) = resized_list(cache, &u);
        out.push(format!(
            "{} {what} a side that is not a power of two (or under {} texels), stored resampled up to \
             one ({list}): views nearer than the leaf's min_distance and --mode original (the reference \
             of render and sweep) draw the resampled copy, not the source",
            u.len(),
            crate::model::MIN_ORIGINAL_CLASS,
        ));
    }
    out
}

/// The first three of `map` as `name W×H → W×H` (", …" past them), and the words for one or several.
fn resized_list(
    cache: &super::image_cache::ImageCache<'_>,
    map: &std::collections::BTreeMap<crate::ids::ImageId, super::image_cache::Downsampled>,
) -> (String, &'static str, &'static str) {
    let names: Vec<String> = (map.iter().take(3))
        .map(|(id, (src, stored))| {
            let name = cache.image_name(*id);
            format!("{name} {}×{} → {}×{}", src[0], src[1], stored[0], stored[1])
        })
        .collect();
    let more = if map.len() > names.len() { ", …" } else { "" };
    let (what, them) = if map.len() == 1 {
        ("original texture has", "it")
    } else {
        ("original textures have", "them")
    };
    (format!("{}{more}", names.join(", ")), what, them)
}

/// What the plan of each tree warns about (oversized rects, clamped triangles, palettes past their limit):
/// the same lines from a one-process build, a self-planning shard and the plan step (`--shard plan`).
pub(super) fn tree_warnings(trees: &[TreeReport]) -> Vec<String> {
    let mut warnings = Vec::new();
    for r in trees {
        let lr = &r.leaf_reasons;
        if lr.oversized > 0 && lr.scale_min < OVERSIZED_WARN_SCALE {
            warnings.push(format!(
                "{:?} tree: {} leaves scaled for an oversized rect, down to scale {} (root min_distance {:.1} \
                 m): one texture's period alone needs more than an atlas (a source side above --atlas-size, \
                 --no-source-cap, a large --texel-ratio) \
                 and every texture of such a leaf is shrunk with it, so the tree serves from far away only; \
                 keep textures capped to their source or raise --atlas-size",
                r.kind,
                lr.oversized,
                crate::util::fraction_text(lr.scale_min),
                r.root_min_distance
            ));
        }
        for m in &r.sizing.palette.over_limit {
            warnings.push(format!(
                "{:?} tree: material {} ('{}') paints constant-UV triangles at {} distinct points of its \
                 image (texels, to a 64th), more than the {} kept as rects of their own: they share one rect, \
                 so scaled leaves and ancestor levels draw them mixed with neighbouring texels",
                r.kind, m.material, m.name, m.cells, r.sizing.palette.limit
            ));
        }
        if lr.clamped > 0 {
            warnings.push(format!(
                "{:?} tree: {} leaves hold a triangle that alone needs more than one atlas; their resolution was \
                 scaled down and their min_distance raised accordingly",
                r.kind, lr.clamped
            ));
        }
    }
    warnings
}

/// The report of a finished build, with the warnings of the image cache and of clamped leaves.
pub(super) fn build_report(
    params: BuildParams,
    scene_diagonal: f64,
    forest: &AtlasForest,
    trees: Vec<TreeReport>,
    file_bytes: u64,
    timings: StageLog,
    cache: &super::image_cache::ImageCache<'_>,
) -> BuildReport {
    let atlas_blocks = forest
        .blocks
        .iter()
        .filter(|b| matches!(b.kind, crate::model::BlockKind::Atlas { .. }))
        .count() as u64;
    let mut warnings = cache.warnings.lock().map(|w| w.clone()).unwrap_or_default();
    warnings.extend(tree_warnings(&trees));
    for w in resized_warnings(cache) {
        warnings.push(w);
    }
    warnings.extend(cache.redecode_warning());
    let atlas_texels = crate::texfmt::TexFormat::Rgba8.chain_bytes(forest.params.atlas_size) / 4;
    let texels_stored = trees
        .iter()
        .map(|r| r.originals.texels)
        .sum::<u64>()
        .saturating_add(atlas_blocks.saturating_mul(atlas_texels));
    BuildReport {
        params,
        scene_diagonal,
        trees,
        blocks: forest.blocks.len() as u64,
        atlas_blocks,
        original_blocks: forest.blocks.len() as u64 - atlas_blocks,
        file_bytes,
        stages: timings,
        images_decoded: cache.decodes.load(Ordering::Relaxed),
        texels_decoded: cache.decoded_texels.load(Ordering::Relaxed),
        texels_stored,
        image_fallbacks: cache.fallbacks(),
        images_alpha_ignored: cache.alpha_ignored(),
        memory: None,
        warnings,
        import: crate::scene::ImportReport::default(),
    }
}
