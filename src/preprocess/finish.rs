//! Finishing one atlas (paper §5.1): its mip chain, its stored (encoded) levels, the block in the sink,
//! and what its parent needs — its level 1 and, where they can be reused, its stored levels from 1 on.
//!
//! An inner atlas is its four children halved, so with the 2×2 box filter its level `k` is its children's
//! levels `k + 1` side by side, and where the stored cells (RGBA8 texels, 4×4 blocks) are encoded on
//! their own texels alone, its stored level `k` is their stored cells rearranged
//! ([`crate::texfmt::combine_stored_quadrants`]): a quarter to a third of a tree's encoding (its inner
//! atlases) is copied instead of run again. That holds where no colour bleeds (a transparent texel takes
//! its neighbours' colour, across quadrants), so only for the opaque tree, whose levels report no
//! transparent texel, with the box filter and no per-texture alpha rescaling; levels of fewer texels than
//! two cells, and every level elsewhere, are encoded as before. The same bytes either way: the merge of a
//! sharded build, which reads only its children's level 1, encodes every level and writes the same file
//! (the sharded identity tests), and `texfmt`'s tests compare combined levels with encoded ones.

use super::BuildError;
use super::image_ops::{
    BandedLevels, LinearImage, MipChain, MipFilter, MipOptions, preserve_coverage,
};
use super::raster::{AtlasOut, fill_for};
use crate::ids::NodeId;
use crate::model::{AtlasTree, TreeKind};
use crate::texfmt::{StoredLevel, cell_side, combine_stored_quadrants, encode_level_measured};
use std::sync::atomic::Ordering;

/// What a finished atlas hands its parent.
pub(super) struct NodeOut {
    /// Its level 1 (premultiplied linear RGBA): all the parent's own level 0 needs.
    pub(super) level1: LinearImage,
    /// Its stored levels from level 1 on, where the parent may take them as its own levels from 0 on:
    /// encoded per cell, with no colour bled ([`reusable_levels`]); `None` otherwise.
    pub(super) stored: Option<Vec<StoredLevel>>,
}

impl NodeOut {
    /// A child known only by its level 1 (a shard's handoff): the parent encodes every level itself.
    pub(super) fn level1_only(level1: LinearImage) -> NodeOut {
        NodeOut {
            level1,
            stored: None,
        }
    }
}

/// An atlas as it arrives to be finished.
pub(super) enum AtlasStart {
    /// Level 0 in linear light (an inner atlas, or a leaf drawn whole): its chain is built from it.
    Linear(LinearImage),
    /// A leaf drawn band by band: level 0 already stored as RGBA8, the chain built from level 1.
    Banded(BandedLevels),
}

/// Whether atlases of `tree` built with `out`'s options may take stored levels from their children: the
/// opaque tree (the alpha tree bleeds colour into transparent texels across quadrants), the 2×2 box (a
/// Kaiser kernel reaches across quadrants), and no per-texture alpha rescaling (`regions` empty).
fn reusable_levels(out: &AtlasOut<'_>, tree: &AtlasTree, regions_empty: bool) -> bool {
    tree.kind == TreeKind::Opaque && out.mip_filter == MipFilter::Box && regions_empty
}

/// Mip chain, encoding and storing of node `id`'s atlas; returns its level 1 (and stored levels) for the
/// parent. `children[q]` is child `q`'s output for an inner node (`None` for a missing quadrant), `None`
/// for a leaf.
pub(super) fn finish_atlas(
    out: &AtlasOut<'_>,
    tree: &AtlasTree,
    id: NodeId,
    atlas: AtlasStart,
    children: Option<[Option<&NodeOut>; 4]>,
) -> Result<NodeOut, BuildError> {
    let node = &tree.nodes[id.idx()];
    let opts = MipOptions {
        filter: out.mip_filter,
        ..MipOptions::default()
    };
    // A banded leaf's level 0, stored already: (bytes, bled).
    let (level0, base) = match atlas {
        AtlasStart::Linear(level0) => (None, level0),
        AtlasStart::Banded(b) => (Some((b.rgba0, b.bled)), b.level1),
    };
    let regions = super::alpha_coverage::node_regions(tree, id, out.atlas_size, &out.mask_cutoffs);
    if level0.is_some() && !regions.is_empty() {
        return Err(BuildError::Image {
            what: format!("leaf atlas of node {}", id.0),
            source: super::image_ops::ImageOpsError::BandedWithCoverage {
                regions: regions.len(),
            },
        });
    }
    // One mip chain serves both the stored block and the parent, which needs exactly level 1 (with
    // coverage kept, the rescaled level 1: the parent's level 0 then has the leaves' coverage).
    let mut chain = MipChain::build_with(base, &opts);
    preserve_coverage(&mut chain.levels, &regions);
    let reusable = reusable_levels(out, tree, regions.is_empty());
    // Children's stored levels, by quadrant, where every present child has them.
    let from_children: Option<[Option<&[StoredLevel]>; 4]> =
        children.filter(|_| reusable).and_then(|kids| {
            let all = kids.iter().flatten().all(|k| k.stored.is_some());
            all.then(|| kids.map(|k| k.and_then(|k| k.stored.as_deref())))
        });
    let format = tree.format;
    let channels = tree.kind.channels();
    // The fill's stored cell, for missing quadrants: encoded once per inner atlas that combines.
    let fill = from_children.map(|_| stored_fill(tree, channels));
    // The block is built in place, each level's bytes moved or appended once; `levels` are their ranges
    // and errors.
    let mut block: Vec<u8> = Vec::with_capacity(format.chain_bytes(out.atlas_size) as usize);
    let mut levels: Vec<(std::ops::Range<usize>, u64)> = Vec::with_capacity(chain.levels.len());
    let mut bled = false;
    let mut samples = 0u64;
    // The chain's level k is the atlas's level k + skip.
    let skip = usize::from(level0.is_some());
    if let Some((rgba, was_bled)) = level0 {
        let side = out.atlas_size;
        samples += u64::from(side) * u64::from(side) * channels as u64;
        bled |= was_bled;
        let (bytes, sse) = encode_level_measured(format, rgba.into(), side, side, channels);
        block.extend_from_slice(&bytes);
        levels.push((0..block.len(), sse));
    }
    for (k, level) in chain.levels.iter().enumerate() {
        let k = k + skip;
        let side = level.width;
        samples += u64::from(side) * u64::from(level.height) * channels as u64;
        let combined = from_children.zip(fill.as_ref()).and_then(|(kids, fill)| {
            let quads = kids.map(|q| q.and_then(|levels| levels.get(k)));
            // A present child without level k + 1 (or of another side) makes the combine refuse.
            let complete = kids
                .iter()
                .zip(&quads)
                .all(|(k, q)| k.is_none() || q.is_some());
            complete
                .then(|| combine_stored_quadrants(format, quads, side / 2, fill))
                .flatten()
        });
        let stored = match combined {
            Some(l) => l,
            None => {
                let mut rgba = vec![0u8; level.texel_count() * 4];
                bled |= level.to_rgba8_into(&mut rgba);
                let (bytes, sse) =
                    encode_level_measured(format, rgba.into(), side, level.height, channels);
                StoredLevel { bytes, sse }
            }
        };
        let start = block.len();
        block.extend_from_slice(&stored.bytes);
        levels.push((start..block.len(), stored.sse));
    }
    let sse: u64 = levels.iter().map(|l| l.1).sum();
    out.sink.put_block(node.atlas_block, &block, sse)?;
    let [sse_sum, samples_sum] = &out.atlas_error[tree.kind.index()];
    sse_sum.fetch_add(sse, Ordering::Relaxed);
    samples_sum.fetch_add(samples, Ordering::Relaxed);
    let n = out.done.fetch_add(1, Ordering::Relaxed) + 1;
    (out.progress)(n);
    let stored = (reusable && !bled).then(|| {
        let level = |(range, sse): &(std::ops::Range<usize>, u64)| StoredLevel {
            bytes: block[range.clone()].to_vec(),
            sse: *sse,
        };
        levels.iter().skip(1).map(level).collect()
    });
    // The chain starts at level 1 where level 0 came banded; a chain of one level hands that level.
    let mut chain_levels = chain.levels.into_iter();
    let first = chain_levels.next();
    let level1 = if skip == 1 {
        first
    } else {
        chain_levels.next().or(first)
    };
    let level1 = level1.unwrap_or_else(|| LinearImage::new_filled(1, 1, [0.0; 4]));
    Ok(NodeOut { level1, stored })
}

/// The stored cell of the tree's fill colour (missing quadrants of inner atlases), with its error.
fn stored_fill(tree: &AtlasTree, channels: usize) -> StoredLevel {
    let side = cell_side(tree.format);
    let rgba = LinearImage::new_filled(side, side, fill_for(tree.kind)).to_rgba8();
    let (bytes, sse) = encode_level_measured(tree.format, rgba.into(), side, side, channels);
    StoredLevel { bytes, sse }
}
