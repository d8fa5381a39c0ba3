//! The block table the pager works on (paper §6: "memory blocks of approximately equal size. Each block
//! represents either an atlas texture or a set of original textures of a leaf node").
//!
//! Besides what the file's block records say, the table knows each block's **closure parent**: the block
//! that must be resident before it may be. For an atlas that is the atlas of the parent node (the paper:
//! "if the atlas of a node N is in memory, the atlases for all nodes on the path to N should also be in
//! memory"); for a part of a leaf's original textures it is the leaf's own atlas ("if the original textures
//! of a leaf node are in memory, the atlas of N should be in memory as well"). The resident set is kept
//! closed under this relation, so a resident set is always a union of root paths.

use crate::ids::{BlockId, LeafId, NONE, NodeId};
use crate::store::TreeFile;
use crate::store::format::{BLOCK_ATLAS, BLOCK_ORIGINALS, BlockRecord, NodeRecord};

/// What a block holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum BlockItem {
    /// The atlas (full mip chain) of `node`.
    Atlas { node: NodeId },
    /// Part `part` of the original-texture blocks owned by leaf `leaf` (whose node is `node`): the first
    /// leaf that draws one of its textures; other leaves may reference it too ([`BlockTable::users`]).
    Originals {
        leaf: LeafId,
        node: NodeId,
        part: u32,
    },
}

impl BlockItem {
    /// The node the block belongs to (its atlas node, or the leaf's node).
    pub fn node(self) -> NodeId {
        match self {
            BlockItem::Atlas { node } | BlockItem::Originals { node, .. } => node,
        }
    }

    pub fn is_atlas(self) -> bool {
        matches!(self, BlockItem::Atlas { .. })
    }
}

/// One block as the pager sees it.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct BlockMeta {
    /// Index of the tree (0 opaque, 1 alpha).
    pub tree: u32,
    pub item: BlockItem,
    /// Size in bytes (what a load transfers).
    pub bytes: u64,
    /// Bytes the executor writes to the GPU for it, in the stored format: `bytes` for an atlas; for
    /// original textures their square class layers (a `w × h` texture is uploaded tiled into `class²`,
    /// [`crate::texfmt::tile_chain_to_square`]). What [`crate::paging::UploadBudget::Bytes`] counts.
    pub upload_bytes: u64,
    /// Hierarchy level used for priorities: the node's level for an atlas, the leaf's level + 1 for its
    /// original textures (they refine the leaf atlas).
    pub level: u32,
    /// The block that must be resident first (see the module docs); `None` for a root atlas.
    pub parent: Option<BlockId>,
}

/// Per tree, the blocks of each node.
#[derive(Clone, Debug, Default)]
pub struct TreeBlocks {
    /// Atlas block per node (`None` for a node without an atlas, which validated files do not have).
    pub atlas: Vec<Option<BlockId>>,
    /// Range in [`BlockTable::original_blocks`] per node (empty for inner nodes).
    pub originals: Vec<(u32, u32)>,
}

/// The pager's view of all blocks of a file.
#[derive(Clone, Debug, Default)]
pub struct BlockTable {
    pub blocks: Vec<BlockMeta>,
    pub trees: Vec<TreeBlocks>,
    /// Original-texture blocks grouped by leaf node (see [`TreeBlocks::originals`]); a shared block
    /// appears under every leaf that references it.
    pub original_blocks: Vec<BlockId>,
    /// Per block, the leaf nodes referencing it (original-texture blocks; see [`BlockTable::users`]).
    users: Vec<Vec<NodeId>>,
}

/// Why a block table could not be made (only from unvalidated, hand-made inputs).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum BlockTableError {
    #[error("block {block}: tree {tree} does not exist ({trees} trees)")]
    NoTree { block: u32, tree: u32, trees: usize },
    #[error("block {block}: tree {tree} has no {what} {item}")]
    NoItem {
        block: u32,
        tree: u32,
        what: &'static str,
        item: u32,
    },
    #[error("block {block}: unknown kind {kind}")]
    BadKind { block: u32, kind: u32 },
    #[error("tree {tree}: node {node} has no atlas block")]
    NoAtlas { tree: u32, node: u32 },
    #[error(
        "tree {tree} leaf node {node}: original references block {block}, which is not an original-texture block of the tree"
    )]
    BadOriginalBlock { tree: u32, node: u32, block: u32 },
}

impl BlockTable {
    /// The table of an open file.
    pub fn from_file(file: &TreeFile) -> Result<BlockTable, BlockTableError> {
        let views: Vec<_> = (0..file.trees()).filter_map(|t| file.tree(t)).collect();
        let trees: Vec<&[NodeRecord]> = views.iter().map(|v| v.nodes).collect();
        let mut table = BlockTable::new(&trees, file.blocks())?;
        // Per leaf node, the distinct blocks its originals reference (its own and those stored by an
        // earlier leaf of the tree, docs/DESIGN.md "Originals").
        let refs: Vec<Vec<Vec<BlockId>>> = views
            .iter()
            .map(|v| {
                let mut per_node = vec![Vec::new(); v.nodes.len()];
                for leaf in v.leaves {
                    let Some(list) = per_node.get_mut(leaf.node as usize) else {
                        continue;
                    };
                    for o in v.leaf_originals(leaf) {
                        let b = BlockId(o.block);
                        if !list.contains(&b) {
                            list.push(b);
                        }
                    }
                }
                per_node
            })
            .collect();
        table.share_originals(&trees, &refs)?;
        // Originals upload as whole class layers: each (block, slot) once.
        for v in &views {
            let mut slots = std::collections::BTreeMap::new();
            for o in v.originals {
                slots.insert((o.block, o.slot), o.class_size());
            }
            let mut layers = std::collections::BTreeMap::<u32, u64>::new();
            for ((b, _), class) in slots {
                *layers.entry(b).or_default() += v.format().chain_bytes(class);
            }
            for (b, bytes) in layers {
                if let Some(m) = table.blocks.get_mut(b as usize) {
                    m.upload_bytes = bytes;
                }
            }
        }
        Ok(table)
    }

    /// Replaces each leaf's original blocks by `refs[tree][node]` (blocks may be shared by several
    /// leaves) and makes a shared block's closure parent the atlas of the lowest common ancestor of the
    /// leaves that reference it: that atlas is on the root path of each of them, so the closure costs no
    /// block their own paths do not.
    pub fn share_originals(
        &mut self,
        trees: &[&[NodeRecord]],
        refs: &[Vec<Vec<BlockId>>],
    ) -> Result<(), BlockTableError> {
        let mut users: Vec<Vec<NodeId>> = vec![Vec::new(); self.blocks.len()];
        self.original_blocks.clear();
        for (t, per_node) in refs.iter().enumerate() {
            let Some(tb) = self.trees.get_mut(t) else {
                continue;
            };
            for (n, list) in per_node.iter().enumerate() {
                let first = self.original_blocks.len() as u32;
                for &b in list {
                    let ok = self.blocks.get(b.idx()).is_some_and(|m| {
                        m.tree as usize == t && matches!(m.item, BlockItem::Originals { .. })
                    });
                    if !ok {
                        return Err(BlockTableError::BadOriginalBlock {
                            tree: t as u32,
                            node: n as u32,
                            block: b.0,
                        });
                    }
                    users[b.idx()].push(NodeId(n as u32));
                    self.original_blocks.push(b);
                }
                if let Some(r) = tb.originals.get_mut(n) {
                    *r = (first, list.len() as u32);
                }
            }
        }
        for (b, nodes) in users.iter().enumerate() {
            let (tree, item) = (self.blocks[b].tree as usize, self.blocks[b].item);
            let (Some(nodes_of), BlockItem::Originals { .. }) = (trees.get(tree), item) else {
                continue;
            };
            let Some(lca) = lowest_common_ancestor(nodes_of, nodes) else {
                continue;
            };
            let parent = self.trees[tree]
                .atlas
                .get(lca.idx())
                .copied()
                .flatten()
                .ok_or(BlockTableError::NoAtlas {
                    tree: tree as u32,
                    node: lca.0,
                })?;
            self.blocks[b].parent = Some(parent);
        }
        self.users = users;
        Ok(())
    }

    /// The leaf nodes whose originals reference original-texture block `b`: its own leaf, or after
    /// [`BlockTable::share_originals`] every leaf that references it (empty for atlases).
    pub fn users(&self, b: BlockId) -> &[NodeId] {
        self.users.get(b.idx()).map_or(&[], Vec::as_slice)
    }

    /// The table of `trees` (node tables, tree-local ids) and the global `blocks` records. Every node must
    /// have an atlas block (the closure parents are atlases).
    pub fn new(
        trees: &[&[NodeRecord]],
        blocks: &[BlockRecord],
    ) -> Result<BlockTable, BlockTableError> {
        let mut table = BlockTable {
            blocks: Vec::with_capacity(blocks.len()),
            trees: trees
                .iter()
                .map(|n| TreeBlocks {
                    atlas: vec![None; n.len()],
                    originals: vec![(0, 0); n.len()],
                })
                .collect(),
            original_blocks: Vec::new(),
            users: Vec::new(),
        };
        // Leaf id → node id per tree.
        let leaf_nodes: Vec<Vec<u32>> = trees
            .iter()
            .map(|nodes| {
                let leaves = nodes.iter().filter(|n| n.leaf != NONE).count();
                let mut map = vec![NONE; leaves];
                for (i, n) in nodes.iter().enumerate() {
                    if let Some(slot) = map.get_mut(n.leaf as usize) {
                        *slot = i as u32;
                    }
                }
                map
            })
            .collect();
        // First pass: items and atlas ids.
        let mut items = Vec::with_capacity(blocks.len());
        for (b, r) in blocks.iter().enumerate() {
            let b = b as u32;
            let nodes = trees.get(r.tree as usize).ok_or(BlockTableError::NoTree {
                block: b,
                tree: r.tree,
                trees: trees.len(),
            })?;
            let item = match r.kind {
                BLOCK_ATLAS => {
                    if r.item as usize >= nodes.len() {
                        return Err(BlockTableError::NoItem {
                            block: b,
                            tree: r.tree,
                            what: "node",
                            item: r.item,
                        });
                    }
                    table.trees[r.tree as usize].atlas[r.item as usize] = Some(BlockId(b));
                    BlockItem::Atlas {
                        node: NodeId(r.item),
                    }
                }
                BLOCK_ORIGINALS => {
                    let node = leaf_nodes[r.tree as usize]
                        .get(r.item as usize)
                        .copied()
                        .filter(|&n| n != NONE)
                        .ok_or(BlockTableError::NoItem {
                            block: b,
                            tree: r.tree,
                            what: "leaf",
                            item: r.item,
                        })?;
                    BlockItem::Originals {
                        leaf: LeafId(r.item),
                        node: NodeId(node),
                        part: r.part,
                    }
                }
                kind => return Err(BlockTableError::BadKind { block: b, kind }),
            };
            items.push((r.tree, item, r.length));
        }
        // Second pass: levels and closure parents.
        for (tree, item, bytes) in items {
            let nodes = trees[tree as usize];
            let tb = &table.trees[tree as usize];
            let node = &nodes[item.node().idx()];
            let (level, parent_node) = match item {
                BlockItem::Atlas { .. } => {
                    (node.level, (node.parent != NONE).then_some(node.parent))
                }
                BlockItem::Originals { node: n, .. } => (node.level + 1, Some(n.0)),
            };
            let parent = match parent_node {
                None => None,
                Some(p) => Some(
                    tb.atlas
                        .get(p as usize)
                        .copied()
                        .flatten()
                        .ok_or(BlockTableError::NoAtlas { tree, node: p })?,
                ),
            };
            table.blocks.push(BlockMeta {
                tree,
                item,
                bytes,
                upload_bytes: bytes,
                level,
                parent,
            });
        }
        // Originals grouped by leaf node, parts in order.
        let mut by_node: Vec<(u32, u32, u32, BlockId)> = table
            .blocks
            .iter()
            .enumerate()
            .filter_map(|(b, m)| match m.item {
                BlockItem::Originals { node, part, .. } => {
                    Some((m.tree, node.0, part, BlockId(b as u32)))
                }
                BlockItem::Atlas { .. } => None,
            })
            .collect();
        by_node.sort_unstable();
        table.users = vec![Vec::new(); table.blocks.len()];
        for (tree, node, _, b) in by_node {
            // Each block serves its own leaf until [`BlockTable::share_originals`] says otherwise.
            table.users[b.idx()].push(NodeId(node));
            let range = &mut table.trees[tree as usize].originals[node as usize];
            if range.1 == 0 {
                range.0 = table.original_blocks.len() as u32;
            }
            range.1 += 1;
            table.original_blocks.push(b);
        }
        Ok(table)
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// The atlas block of `node` in `tree`.
    pub fn atlas(&self, tree: usize, node: NodeId) -> Option<BlockId> {
        self.trees
            .get(tree)?
            .atlas
            .get(node.idx())
            .copied()
            .flatten()
    }

    /// The original-texture blocks of leaf node `node` in `tree` (empty for inner nodes).
    pub fn originals(&self, tree: usize, node: NodeId) -> &[BlockId] {
        let Some(&(first, count)) = self
            .trees
            .get(tree)
            .and_then(|t| t.originals.get(node.idx()))
        else {
            return &[];
        };
        self.original_blocks
            .get(first as usize..(first + count) as usize)
            .unwrap_or(&[])
    }

    /// The root atlas of every tree.
    pub fn roots(&self) -> impl Iterator<Item = BlockId> + '_ {
        self.trees
            .iter()
            .filter_map(|t| t.atlas.first().copied().flatten())
    }

    pub fn meta(&self, b: BlockId) -> &BlockMeta {
        &self.blocks[b.idx()]
    }

    /// Bytes of `blocks` as `(atlases, original textures)`: what the renderer and the simulator report
    /// apart for loads and residency.
    pub fn bytes_by_kind(&self, blocks: impl IntoIterator<Item = BlockId>) -> (u64, u64) {
        blocks.into_iter().fold((0, 0), |(a, o), b| {
            let m = self.meta(b);
            if m.item.is_atlas() {
                (a + m.bytes, o)
            } else {
                (a, o + m.bytes)
            }
        })
    }

    /// Total bytes of all blocks.
    pub fn total_bytes(&self) -> u64 {
        self.blocks.iter().map(|b| b.bytes).sum()
    }
}

/// The deepest node that is an ancestor of (or equal to) every node of `nodes` (parent links of `tree`);
/// `None` for an empty list or broken links.
fn lowest_common_ancestor(tree: &[NodeRecord], nodes: &[NodeId]) -> Option<NodeId> {
    let path = |n: NodeId| {
        let mut p = vec![n];
        let mut cur = n;
        while let Some(node) = tree.get(cur.idx()) {
            if node.parent == NONE || p.len() > tree.len() {
                break;
            }
            cur = NodeId(node.parent);
            p.push(cur);
        }
        p.reverse();
        p
    };
    let mut common = path(*nodes.first()?);
    for &n in &nodes[1..] {
        let p = path(n);
        let k = common.iter().zip(&p).take_while(|(a, b)| a == b).count();
        common.truncate(k);
    }
    common.last().copied()
}
