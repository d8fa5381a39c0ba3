//! Each rect's mean colour ([`RectRecord::mean`], format 6), measured as its leaf's atlas block is
//! written ([`crate::texfmt::rect_means`]) and stored in the rect table when the file is finished. The
//! tables are written before any block, so the rect table is written again at the end, as the block
//! table is with its checksums; a sharded build's merge, which copies the shards' blocks through the same
//! writer, measures the same bytes and finishes the same file.

use super::format::{LeafRecord, NodeRecord, RectRecord};
use crate::ids::{BlockId, LeafId};
use crate::texfmt::TexFormat;
use std::sync::atomic::{AtomicU32, Ordering};

/// One tree's tables as the means need them.
pub(super) struct TreeRects<'a> {
    pub(super) format: TexFormat,
    /// Every rect measured on level 0 ([`crate::texfmt::rect_means`]'s `exact`): the alpha tree.
    pub(super) exact: bool,
    pub(super) nodes: &'a [NodeRecord],
    pub(super) leaves: &'a [LeafRecord],
    pub(super) rects: &'a [RectRecord],
}

/// A leaf atlas block's rects: tree and range in its rect table.
#[derive(Copy, Clone)]
struct LeafRects {
    tree: usize,
    format: TexFormat,
    exact: bool,
    first: usize,
    count: usize,
}

/// The rect tables of a file being written, and their means as the leaf atlas blocks arrive.
pub(super) struct RectMeans {
    atlas_size: u32,
    /// Per block: the leaf whose atlas it is, if any.
    by_block: Vec<Option<LeafRects>>,
    /// Per tree: the rect records as the tables hold them (means zero).
    rects: Vec<Vec<RectRecord>>,
    /// Per tree, per rect: its mean's bytes as a little-endian `u32`.
    means: Vec<Vec<AtomicU32>>,
}

impl RectMeans {
    /// The means of `trees` (every leaf's atlas block among `blocks` blocks) to be measured; `None`
    /// where a leaf or block index is out of range (the tables were validated before: not reached).
    pub(super) fn new(
        atlas_size: u32,
        blocks: usize,
        trees: &[TreeRects<'_>],
    ) -> Option<RectMeans> {
        let mut by_block = vec![None; blocks];
        for (t, tree) in trees.iter().enumerate() {
            for node in tree.nodes {
                let Some(leaf) = LeafId::from_raw(node.leaf) else {
                    continue;
                };
                let leaf = tree.leaves.get(leaf.idx())?;
                let (first, count) = (leaf.first_rect as usize, leaf.rect_count as usize);
                tree.rects.get(first..first.checked_add(count)?)?;
                *by_block.get_mut(node.atlas_block as usize)? = Some(LeafRects {
                    tree: t,
                    format: tree.format,
                    exact: tree.exact,
                    first,
                    count,
                });
            }
        }
        Some(RectMeans {
            atlas_size,
            by_block,
            rects: trees.iter().map(|t| t.rects.to_vec()).collect(),
            means: (trees.iter())
                .map(|t| t.rects.iter().map(|_| AtomicU32::new(0)).collect())
                .collect(),
        })
    }

    /// Measures the rects of the leaf whose atlas is block `id` on its bytes. A no-op for other blocks,
    /// and for an atlas block that is not one atlas chain of the file's format and size: the store does
    /// not require that of a block (a build always writes one; the store's own tests write blocks of any
    /// length), so its rects keep mean 0, and `inspect --verify` reports the block as no atlas chain.
    pub(super) fn record(&self, id: BlockId, bytes: &[u8]) {
        let Some(Some(leaf)) = self.by_block.get(id.idx()) else {
            return;
        };
        let rects = &self.rects[leaf.tree][leaf.first..leaf.first + leaf.count];
        let inners: Vec<[u32; 4]> = rects.iter().map(|r| r.inner).collect();
        let means =
            crate::texfmt::rect_means(leaf.format, bytes, self.atlas_size, &inners, leaf.exact);
        let Some(means) = means else {
            return;
        };
        let slots = &self.means[leaf.tree][leaf.first..leaf.first + leaf.count];
        for (slot, mean) in slots.iter().zip(means) {
            slot.store(u32::from_le_bytes(mean), Ordering::Relaxed);
        }
    }

    /// Every tree's rect records with their means.
    pub(super) fn finished(&self) -> Vec<Vec<RectRecord>> {
        (self.rects.iter().zip(&self.means))
            .map(|(rects, means)| {
                (rects.iter().zip(means))
                    .map(|(r, m)| RectRecord {
                        mean: m.load(Ordering::Relaxed).to_le_bytes(),
                        ..*r
                    })
                    .collect()
            })
            .collect()
    }
}
