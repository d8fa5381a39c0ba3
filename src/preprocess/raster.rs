//! The pixel pass: leaf atlases rasterised on the CPU in linear light, inner atlases as the 2×2 combination
//! of their children halved (paper §5.1), original textures resampled to their stored sides, every block
//! encoded with its full mip chain and streamed into the paging file at its pre-assigned offset.
//!
//! Post-order and parallel over subtrees (rayon); each call returns its atlas halved, which is all the
//! parent's level 0 needs, and where they can be reused its stored levels from 1 on, which the parent
//! copies instead of encoding ([`super::finish`]); memory stays at a few atlases per tree level and thread.

use super::BuildError;
use super::finish::{AtlasStart, NodeOut, finish_atlas};
use super::image_cache::ImageCache;
use super::image_ops::ImageOpsError;
use super::image_ops::{AlphaMips, LinearImage, MipFilter, combine_quadrants, neutral_fill};
use crate::ids::NodeId;
use crate::model::{AtlasTree, TreeKind};
use crate::scene::Scene;
use crate::store::BlockSink;
use std::collections::HashMap;
use std::sync::atomic::AtomicU64;

/// The pixel options the paging file's tables do not hold: the atlas mip kernel and how alpha is carried
/// through the mips. Shard headers carry them as one code ([`PixelOptions::code`]).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct PixelOptions {
    pub mip_filter: MipFilter,
    pub alpha_mips: AlphaMips,
}

impl PixelOptions {
    /// `filter index + 256 · alpha-mips index` (indices into [`MipFilter::ALL`], [`AlphaMips::ALL`]), so
    /// the plain options keep the codes shard files had before the alpha knob.
    pub fn code(self) -> u32 {
        let index = |found: Option<usize>| found.unwrap_or(0) as u32;
        index(MipFilter::ALL.iter().position(|&f| f == self.mip_filter))
            + 256 * index(AlphaMips::ALL.iter().position(|&m| m == self.alpha_mips))
    }

    /// The options of a shard header's code, if known.
    pub fn from_code(code: u32) -> Option<PixelOptions> {
        Some(PixelOptions {
            mip_filter: *MipFilter::ALL.get((code % 256) as usize)?,
            alpha_mips: *AlphaMips::ALL.get((code / 256) as usize)?,
        })
    }
}

/// Where finished atlases go and what is counted of them: all that the atlases above a shard cut need
/// (the merge has no scene).
pub struct AtlasOut<'a> {
    /// Side of every atlas, texels.
    pub atlas_size: u32,
    /// The paging file, or a shard file.
    pub sink: &'a dyn BlockSink,
    /// Called with the number of nodes finished so far.
    pub progress: &'a (dyn Fn(u64) + Sync),
    pub done: AtomicU64,
    /// Kernel of the atlas mip chains (the level 1 handed to the parent included).
    pub mip_filter: MipFilter,
    /// Per material, the MASK cutoff whose coverage atlas and original mips keep (empty: plain mips;
    /// [`super::alpha_coverage::mask_cutoffs`]).
    pub mask_cutoffs: Vec<Option<f32>>,
    /// Compression error of the atlases finished so far, per tree kind ([`TreeKind::index`]: a forest
    /// has at most one tree of each, `super::partition_triangles`): sums of squared errors and of
    /// compared values ([`crate::texfmt::Encoded`]), kept apart so the trees can be rasterised side by side.
    pub atlas_error: [[AtomicU64; 2]; 2],
}

impl<'a> AtlasOut<'a> {
    /// The atlases of `forest` (its atlas side and materials) with `pixels` into `sink`.
    pub fn new(
        forest: &crate::model::AtlasForest,
        pixels: PixelOptions,
        sink: &'a dyn BlockSink,
        progress: &'a (dyn Fn(u64) + Sync),
    ) -> Self {
        AtlasOut {
            atlas_size: forest.params.atlas_size,
            sink,
            progress,
            done: AtomicU64::new(0),
            mip_filter: pixels.mip_filter,
            mask_cutoffs: super::alpha_coverage::mask_cutoffs(pixels.alpha_mips, &forest.materials),
            atlas_error: Default::default(),
        }
    }
}

/// What the pixel pass below the cut needs.
pub struct RasterCtx<'a> {
    pub scene: &'a Scene,
    pub cache: &'a ImageCache<'a>,
    pub out: AtlasOut<'a>,
}

/// The level 1 of a subtree's root atlas (premultiplied linear RGBA): all its parent needs (§5.1).
pub type Handoff = LinearImage;

/// Rasterises the subtrees rooted at `roots` of `tree` (every atlas, and every original-texture block
/// their leaves own) into the sink, in parallel; returns each root's level 1, in `roots` order.
pub fn raster_subtrees(
    ctx: &RasterCtx<'_>,
    tree: &AtlasTree,
    roots: &[NodeId],
) -> Result<Vec<Handoff>, BuildError> {
    use rayon::prelude::*;
    let owned = owned_blocks(tree);
    roots
        .par_iter()
        .map(|&r| raster_node(ctx, tree, &owned, r).map(|n| n.level1))
        .collect()
}

/// Every block a subtree rooted at `root` writes: its nodes' atlases and the original-texture blocks its
/// leaves own (`owned`: [`leaf_owned_blocks`] of `tree`, computed once per tree by the caller). Unsorted.
pub fn subtree_blocks(
    tree: &AtlasTree,
    owned: &[Vec<crate::ids::BlockId>],
    root: NodeId,
) -> Vec<crate::ids::BlockId> {
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(id) = stack.pop() {
        let Some(node) = tree.nodes.get(id.idx()) else {
            continue;
        };
        out.push(node.atlas_block);
        if let Some(blocks) = node.leaf.and_then(|l| owned.get(l.idx())) {
            out.extend_from_slice(blocks);
        }
        stack.extend(node.children.iter().flatten());
    }
    out
}

/// Per leaf (index) of `tree`, the original-texture blocks it writes ([`owned_blocks`]), ascending.
pub fn leaf_owned_blocks(tree: &AtlasTree) -> Vec<Vec<crate::ids::BlockId>> {
    let mut out = vec![Vec::new(); tree.leaves.len()];
    for (leaf, blocks) in owned_blocks(tree) {
        if let Some(o) = out.get_mut(leaf) {
            *o = blocks.iter().map(|b| b.0).collect();
        }
    }
    out
}

/// Where [`raster_above`] finds the handoff of a node of the cut (`None`: the node is above the cut), read
/// when its parent is combined, so only the handoffs being combined are in memory at once.
pub type HandoffSource<'a> = dyn Fn(NodeId) -> Option<Result<Handoff, BuildError>> + Sync + 'a;

/// The atlases of `tree` above the cut: every node that `handoffs` does not give and that is not below
/// one it gives, combined from its children (four halved, §5.1) and finished into the sink. A leaf reached
/// means the cut did not cover the tree (an internal error, reported, not a panic).
pub fn raster_above(
    out: &AtlasOut<'_>,
    tree: &AtlasTree,
    handoffs: &HandoffSource<'_>,
    id: NodeId,
) -> Result<Handoff, BuildError> {
    if let Some(h) = handoffs(id) {
        return h;
    }
    let node = &tree.nodes[id.idx()];
    if node.leaf.is_some() {
        return Err(BuildError::CutUncovered {
            tree: tree.kind,
            node: id.0,
        });
    }
    // Children known by their level 1 only: every level of this atlas is encoded here.
    let kids = children_of(tree, id, &|c| {
        raster_above(out, tree, handoffs, c).map(NodeOut::level1_only)
    })?;
    let atlas = combine_children(out, tree, id, &kids)?;
    finish_atlas(
        out,
        tree,
        id,
        AtlasStart::Linear(atlas),
        Some(quadrants(&kids)),
    )
    .map(|n| n.level1)
}

/// Rasterises every atlas and original-texture block of `tree` into the sink.
pub fn raster_tree(ctx: &RasterCtx<'_>, tree: &AtlasTree) -> Result<(), BuildError> {
    raster_subtrees(ctx, tree, &[NodeId(0)]).map(|_| ())
}

/// One original-texture block and its images in slot order (each listed once, however many leaves
/// reference it).
type BlockSlots<'t> = (crate::ids::BlockId, Vec<&'t crate::model::OriginalRef>);

/// Per leaf (index), the original-texture blocks it writes: each block is written by the first leaf (in
/// leaf order) that references it, with every slot any leaf references (a block groups textures by
/// their users, so its writer need not show them all).
fn owned_blocks(tree: &AtlasTree) -> HashMap<usize, Vec<BlockSlots<'_>>> {
    let mut owner: HashMap<crate::ids::BlockId, usize> = HashMap::new();
    let mut slots: HashMap<
        crate::ids::BlockId,
        std::collections::BTreeMap<u32, &crate::model::OriginalRef>,
    > = HashMap::new();
    for (li, leaf) in tree.leaves.iter().enumerate() {
        for o in &leaf.originals {
            owner.entry(o.block).or_insert(li);
            slots.entry(o.block).or_default().entry(o.slot).or_insert(o);
        }
    }
    let mut out: HashMap<usize, Vec<BlockSlots<'_>>> = HashMap::new();
    for (block, by_slot) in slots {
        out.entry(owner[&block])
            .or_default()
            .push((block, by_slot.into_values().collect()));
    }
    for blocks in out.values_mut() {
        blocks.sort_by_key(|b| b.0);
    }
    out
}

/// The colour of atlas space no texture occupies (unused leaf space, missing quadrants of inner atlases).
pub(super) fn fill_for(kind: TreeKind) -> [f32; 4] {
    match kind {
        // Mid grey, opaque: unused atlas space is never sampled at the levels borders protect.
        TreeKind::Opaque => neutral_fill(),
        // Transparent: the RGBA8 conversion bleeds the nearest visible colour into it.
        TreeKind::Alpha => [0.0; 4],
    }
}

fn raster_node(
    ctx: &RasterCtx<'_>,
    tree: &AtlasTree,
    owned: &HashMap<usize, Vec<BlockSlots<'_>>>,
    id: NodeId,
) -> Result<NodeOut, BuildError> {
    let node = &tree.nodes[id.idx()];
    if let Some(leaf_id) = node.leaf {
        let leaf = &tree.leaves[leaf_id.idx()];
        if let Some(blocks) = owned.get(&leaf_id.idx()) {
            write_originals(ctx, tree, blocks)?;
        }
        let atlas = super::leaf::leaf_start(ctx, tree, id, leaf)?;
        return finish_atlas(&ctx.out, tree, id, atlas, None);
    }
    let kids = children_of(tree, id, &|c| raster_node(ctx, tree, owned, c))?;
    let atlas = combine_children(&ctx.out, tree, id, &kids)?;
    finish_atlas(
        &ctx.out,
        tree,
        id,
        AtlasStart::Linear(atlas),
        Some(quadrants(&kids)),
    )
}

/// Inner node `id`'s children's outputs from `child` (in parallel), with their quadrants.
fn children_of(
    tree: &AtlasTree,
    id: NodeId,
    child: &(dyn Fn(NodeId) -> Result<NodeOut, BuildError> + Sync),
) -> Result<Vec<(usize, NodeOut)>, BuildError> {
    use rayon::prelude::*;
    let kids: Vec<(usize, NodeId)> = tree.nodes[id.idx()]
        .children
        .iter()
        .enumerate()
        .filter_map(|(q, c)| c.map(|c| (q, c)))
        .collect();
    kids.par_iter()
        .map(|&(q, c)| child(c).map(|out| (q, out)))
        .collect()
}

/// The children's outputs by quadrant.
fn quadrants(kids: &[(usize, NodeOut)]) -> [Option<&NodeOut>; 4] {
    let mut quads = [None; 4];
    for (q, out) in kids {
        if let Some(slot) = quads.get_mut(*q) {
            *slot = Some(out);
        }
    }
    quads
}

/// Inner node `id`'s atlas: its children's levels 1 combined by quadrant (§5.1).
fn combine_children(
    out: &AtlasOut<'_>,
    tree: &AtlasTree,
    id: NodeId,
    kids: &[(usize, NodeOut)],
) -> Result<LinearImage, BuildError> {
    let quads = quadrants(kids).map(|k| k.map(|k| &k.level1));
    combine_quadrants(quads, out.atlas_size, fill_for(tree.kind))
        .map_err(|e| image_err(format!("inner atlas of node {}", id.0), e))
}

pub(super) fn image_err(what: String, source: ImageOpsError) -> BuildError {
    BuildError::Image { what, source }
}

/// The original-texture blocks a leaf writes ([`owned_blocks`]): each block's images resampled to their
/// stored sides with a full mip chain, back to back in slot order (layout of `OriginalRef::slot`).
fn write_originals(
    ctx: &RasterCtx<'_>,
    tree: &AtlasTree,
    blocks: &[BlockSlots<'_>],
) -> Result<(), BuildError> {
    let channels = tree.kind.channels();
    for (block, slots) in blocks {
        let (mut buf, mut sse) = (Vec::new(), 0u64);
        for o in slots {
            let mat = &ctx.scene.materials[o.material.idx()];
            let cutoff = match tree.kind {
                TreeKind::Alpha => ctx
                    .out
                    .mask_cutoffs
                    .get(o.material.idx())
                    .copied()
                    .flatten(),
                TreeKind::Opaque => None,
            };
            let enc = ctx.cache.original((
                o.image,
                o.extent,
                mat.wrap,
                tree.format,
                channels,
                cutoff.map(f32::to_bits),
            ))?;
            buf.extend_from_slice(&enc.bytes);
            sse += enc.sse;
        }
        ctx.out.sink.put_block(*block, &buf, sse)?;
    }
    Ok(())
}
