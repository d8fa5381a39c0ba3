//! A leaf's atlas (paper §5.2.3): every material's area drawn from its source into level 0, band by band
//! where it can be ([`super::image_ops::draw_leaf_banded`]), else whole ([`leaf_atlas`]).

use super::BuildError;
use super::finish::AtlasStart;
use super::image_cache::CachedImage;
use super::image_ops::{
    ImageOpsError, LinearImage, MipFilter, RectJob, RectPlan, draw_leaf_banded, draw_rect,
};
use super::raster::{RasterCtx, fill_for, image_err};
use crate::ids::{ImageId, NodeId};
use crate::model::{AtlasTree, Leaf};
use std::collections::HashMap;
use std::sync::Arc;

/// A leaf's atlas as [`super::finish::finish_atlas`] takes it: level 0 drawn band by band, halved and
/// encoded as it goes ([`draw_leaf_banded`]: the same bytes with a quarter of the memory traffic) where
/// nothing changes level 0 or 1 after drawing — the 2×2 box and no coverage regions — and the leaf's
/// sources together take at most the image cache's size / 4 / rasteriser threads (a band draws from all of them, so each
/// thread holds its leaf's sources at once); else drawn whole ([`leaf_atlas`]).
pub(super) fn leaf_start(
    ctx: &RasterCtx<'_>,
    tree: &AtlasTree,
    id: NodeId,
    leaf: &Leaf,
) -> Result<AtlasStart, BuildError> {
    let err = |e| image_err(format!("leaf atlas of node {}", id.0), e);
    let (size, fill) = (ctx.out.atlas_size, fill_for(tree.kind));
    let box_only = ctx.out.mip_filter == MipFilter::Box
        && super::alpha_coverage::node_regions(tree, id, size, &ctx.out.mask_cutoffs).is_empty();
    // What the threads hold beside the cache: together at most a quarter of it (4 threads at a quarter
    // each peaked 30 MiB above a 1200 MiB budget where the whole-level path stayed 60 MiB further below).
    let share = ctx.cache.capacity() / 4 / rayon::current_num_threads().max(1) as u64;
    if box_only && let Some(images) = leaf_images_within(ctx, leaf, share) {
        let plans = leaf
            .rects
            .iter()
            .zip(&images)
            .map(|(r, img)| RectPlan::new(size, size, &rect_job(ctx, r), &img.chain))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err)?;
        if let Some(levels) = draw_leaf_banded(size, fill, &plans) {
            return Ok(AtlasStart::Banded(levels));
        }
    }
    leaf_atlas(ctx, leaf, size, fill)
        .map(AtlasStart::Linear)
        .map_err(err)
}

/// The source of each of `leaf`'s rects, in rect order, while their distinct images take at most
/// `bytes`; `None` beyond.
fn leaf_images_within(
    ctx: &RasterCtx<'_>,
    leaf: &Leaf,
    bytes: u64,
) -> Option<Vec<Arc<CachedImage>>> {
    let mut held: HashMap<ImageId, Arc<CachedImage>> = HashMap::new();
    let mut total = 0u64;
    let mut out = Vec::with_capacity(leaf.rects.len());
    for r in &leaf.rects {
        let id = ctx.scene.materials[r.material.idx()].image;
        let img = match held.get(&id) {
            Some(img) => img.clone(),
            None => {
                let img = ctx.cache.get(id);
                total = total.saturating_add(img.bytes());
                if total > bytes {
                    return None;
                }
                held.insert(id, img.clone());
                img
            }
        };
        out.push(img);
    }
    Some(out)
}

/// The draw job of `r` with its material's wrap modes and colour factor.
fn rect_job(ctx: &RasterCtx<'_>, r: &crate::model::AtlasRect) -> RectJob {
    let mat = &ctx.scene.materials[r.material.idx()];
    RectJob::from_atlas_rect(r, mat.wrap, mat.base_color_factor)
}

/// A leaf atlas: every material's area drawn from its source (§5.2.3; the paper renders textured quads on
/// the GPU, we filter on the CPU in linear light with correct minification).
fn leaf_atlas(
    ctx: &RasterCtx<'_>,
    leaf: &Leaf,
    size: u32,
    fill: [f32; 4],
) -> Result<LinearImage, ImageOpsError> {
    let mut atlas = LinearImage::new_filled(size, size, fill);
    for r in &leaf.rects {
        let img = ctx.cache.get(ctx.scene.materials[r.material.idx()].image);
        draw_rect(&mut atlas, &rect_job(ctx, r), &img.chain)?;
    }
    Ok(atlas)
}
