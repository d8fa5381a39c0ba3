//! Flattening a layout into the stored tree (paper §3, §5.1): nodes in pre-order, leaves in tree order,
//! per-leaf geometry in the exact single-UV-set form of DESIGN.md "Precision", original-texture classes,
//! and the block table (one block per atlas; a leaf's original textures in blocks of about an atlas' size).

use super::layout::{LayoutKind, LayoutNode, LeafLayout};
use super::prepare::TriInfo;
use crate::ids::{BlockId, LeafId, MaterialId, NodeId};
use crate::model::{
    AtlasRect, AtlasTree, BlockDesc, BlockKind, BuildParams, Leaf, Node, OriginalRef, TreeKind,
    TreeVertex,
};
use crate::scene::Scene;
use crate::texfmt::TexFormat;
use glam::{DVec2, DVec3};
use std::collections::HashMap;

pub use crate::model::{MAX_ORIGINAL_CLASS, MIN_ORIGINAL_CLASS};

/// The square power-of-two class an original image of `w × h` is drawn from (its array's side).
pub fn original_class(w: u32, h: u32) -> u32 {
    w.max(h)
        .max(1)
        .next_power_of_two()
        .clamp(MIN_ORIGINAL_CLASS, MAX_ORIGINAL_CLASS)
}

/// The stored `[width, height]` of an original image of `w × h`: each side to the next power of two in
/// `MIN_ORIGINAL_CLASS..=MAX_ORIGINAL_CLASS` (so the larger is [`original_class`]). Non-square, so a
/// `1024 × 256` texture stores a quarter of the `1024²` its class layer holds (issue 17).
pub fn original_extent(w: u32, h: u32) -> [u32; 2] {
    let side = |v: u32| {
        v.max(1)
            .next_power_of_two()
            .clamp(MIN_ORIGINAL_CLASS, MAX_ORIGINAL_CLASS)
    };
    [side(w), side(h)]
}

/// What a tree's original textures cost in the file against their sources (issue 17's measure).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct OriginalsCost {
    /// Distinct stored chains (`(block, slot)`), and the leaf references to them.
    pub stored: u64,
    pub references: u64,
    /// Bytes of the stored chains (every original-texture block of the tree).
    pub bytes: u64,
    /// What the same chains took as square classes (`max(w, h)²`, format 4 and before).
    pub square_bytes: u64,
    /// Distinct source images behind them, and the bytes of each once at its own size in the tree's
    /// format with a full mip chain (sides halved rounding up down to 1×1).
    pub images: u64,
    pub source_bytes: u64,
}

/// [`OriginalsCost`] of `tree` built from `scene`.
pub fn originals_cost(tree: &AtlasTree, scene: &Scene) -> OriginalsCost {
    let mut chains: HashMap<(BlockId, u32), [u32; 2]> = HashMap::new();
    let mut images = std::collections::HashSet::new();
    let mut c = OriginalsCost::default();
    for o in tree.leaves.iter().flat_map(|l| &l.originals) {
        c.references += 1;
        chains.insert((o.block, o.slot), o.extent);
        images.insert(o.image);
    }
    c.stored = chains.len() as u64;
    c.bytes = chains
        .values()
        .map(|&[w, h]| tree.format.chain_bytes_rect(w, h))
        .sum();
    c.square_bytes = chains
        .values()
        .map(|&[w, h]| tree.format.chain_bytes(w.max(h)))
        .sum();
    c.images = images.len() as u64;
    c.source_bytes = images
        .iter()
        .filter_map(|i| scene.images.get(i.idx()))
        .map(|img| source_chain_bytes(tree.format, img.width, img.height))
        .sum();
    c
}

/// Bytes of a `w × h` image (any sides) with its full mip chain in `format`: levels halved rounding up
/// down to 1×1.
pub fn source_chain_bytes(format: TexFormat, w: u32, h: u32) -> u64 {
    let (mut w, mut h, mut total) = (w.max(1), h.max(1), 0u64);
    loop {
        total += format.level_bytes_rect(w, h);
        if w == 1 && h == 1 {
            return total;
        }
        (w, h) = (w.div_ceil(2), h.div_ceil(2));
    }
}

/// Where a tree goes in its forest.
#[derive(Copy, Clone, Debug)]
pub struct TreeSlot {
    pub kind: TreeKind,
    /// Index of the tree in the forest.
    pub tree_index: u32,
    /// Number of blocks of the forest's earlier trees (this tree's first block id).
    pub first_block: u32,
    /// Storage format of the tree's blocks (fixes every block's byte size).
    pub format: TexFormat,
}

/// Output of [`assemble`].
pub struct Assembled {
    pub tree: AtlasTree,
    pub blocks: Vec<BlockDesc>,
    /// Occupancy per leaf atlas (0..1), in leaf order.
    pub occupancy: Vec<f64>,
    /// Whether each leaf's rect was capped to its source on an axis (parallel to `tree.leaves[i].rects`).
    pub capped: Vec<Vec<bool>>,
    /// Σ over rects of the UV area (periods) their inner rectangles show, and of the UV hull area of
    /// their triangles (what baking would store).
    pub periods_stored: f64,
    pub periods_spanned: f64,
}

struct Asm<'a> {
    scene: &'a Scene,
    infos: &'a [TriInfo],
    order: &'a [u32],
    params: &'a BuildParams,
    tree_index: u32,
    format: TexFormat,
    out: Assembled,
    next_block: u32,
    /// Originals stored so far in this tree, per material: `(block, slot)`. Each is stored once (by the
    /// first leaf that needs it) and referenced by every later leaf (DESIGN.md "Originals").
    stored: HashMap<MaterialId, (BlockId, u32)>,
}

/// Flattens `root` (a layout over `infos`, permutation `order`) into tree `tree_index` of a forest whose
/// blocks so far number `first_block`.
pub fn assemble(
    scene: &Scene,
    infos: &[TriInfo],
    order: &[u32],
    root: &LayoutNode,
    params: &BuildParams,
    slot: TreeSlot,
) -> Assembled {
    let TreeSlot {
        kind,
        tree_index,
        first_block,
        format,
    } = slot;
    let mut a = Asm {
        scene,
        infos,
        order,
        params,
        tree_index,
        format,
        out: Assembled {
            tree: AtlasTree {
                kind,
                format,
                nodes: Vec::new(),
                leaves: Vec::new(),
                vertices: Vec::new(),
                indices: Vec::new(),
                source_triangles: Vec::new(),
            },
            blocks: Vec::new(),
            occupancy: Vec::new(),
            capped: Vec::new(),
            periods_stored: 0.0,
            periods_spanned: 0.0,
        },
        next_block: first_block,
        stored: HashMap::new(),
    };
    a.node(root, None);
    a.out
}

impl Asm<'_> {
    fn block(&mut self, kind: BlockKind, bytes: u64) -> BlockId {
        let id = BlockId(self.next_block);
        self.next_block += 1;
        self.out.blocks.push(BlockDesc {
            tree: self.tree_index,
            kind,
            bytes,
        });
        id
    }

    fn node(&mut self, n: &LayoutNode, parent: Option<NodeId>) -> NodeId {
        let id = NodeId(self.out.tree.nodes.len() as u32);
        let atlas_block = self.block(
            BlockKind::Atlas { node: id },
            self.format.chain_bytes(self.params.atlas_size),
        );
        let first_index = self.out.tree.indices.len() as u32;
        self.out.tree.nodes.push(Node {
            bounds_min: n.lo,
            bounds_max: n.hi,
            level: n.level,
            cell: n.cell,
            parent,
            children: [None; 4],
            min_distance: 0.0,
            first_index,
            index_count: 0,
            atlas_block,
            leaf: None,
        });
        let min_distance = match &n.kind {
            LayoutKind::Leaf(l) => {
                let leaf = self.leaf(n, l, id);
                self.out.tree.nodes[id.idx()].leaf = Some(leaf);
                self.params.d_min / l.clamp_scale
            }
            LayoutKind::Inner { children, order } => {
                let mut md: f64 = 0.0;
                for &q in order {
                    if let Some(c) = &children[q as usize] {
                        let cid = self.node(c, Some(id));
                        self.out.tree.nodes[id.idx()].children[q as usize] = Some(cid);
                        md = md.max(self.out.tree.nodes[cid.idx()].min_distance);
                    }
                }
                2.0 * md
            }
        };
        let end = self.out.tree.indices.len() as u32;
        let node = &mut self.out.tree.nodes[id.idx()];
        node.min_distance = min_distance;
        node.index_count = end - first_index;
        id
    }

    fn leaf(&mut self, n: &LayoutNode, l: &LeafLayout, node: NodeId) -> LeafId {
        let leaf_id = LeafId(self.out.tree.leaves.len() as u32);
        let origin = (n.lo + n.hi) * 0.5;
        let origin = if origin.is_finite() {
            origin
        } else {
            DVec3::ZERO
        };

        // Original textures: one entry per material. Those no earlier leaf of the tree stored are grouped
        // greedily into blocks of about an atlas' size (an image larger than that is a block of its own),
        // owned by this leaf; the others reference the block that holds them (stored once, §8.3).
        let budget = self.format.chain_bytes(self.params.atlas_size);
        let mut seen_materials = std::collections::HashSet::new();
        let classes: Vec<(MaterialId, crate::ids::ImageId, [u32; 2])> = l
            .rects
            .iter()
            .filter(|r| seen_materials.insert(r.material))
            .map(|r| {
                let mat = &self.scene.materials[r.material.idx()];
                let img = &self.scene.images[mat.image.idx()];
                (
                    r.material,
                    mat.image,
                    original_extent(img.width, img.height),
                )
            })
            .collect();
        let new: Vec<usize> = (0..classes.len())
            .filter(|&i| !self.stored.contains_key(&classes[i].0))
            .collect();
        let parts = group_into_blocks(
            new.iter().map(|&i| {
                let [w, h] = classes[i].2;
                self.format.chain_bytes_rect(w, h)
            }),
            budget,
        );
        let mut block_ids: Vec<BlockId> = Vec::new();
        for (part, bytes) in parts.sizes.iter().enumerate() {
            block_ids.push(self.block(
                BlockKind::Originals {
                    leaf: leaf_id,
                    part: part as u32,
                },
                *bytes,
            ));
        }
        for (k, &i) in new.iter().enumerate() {
            let (part, slot) = parts.place[k];
            self.stored.insert(classes[i].0, (block_ids[part], slot));
        }
        let mut originals: Vec<OriginalRef> = Vec::with_capacity(classes.len());
        let mut slot_of: HashMap<MaterialId, u32> = HashMap::new();
        for &(material, image, extent) in &classes {
            let (block, slot) = self.stored[&material];
            slot_of.insert(material, originals.len() as u32);
            originals.push(OriginalRef {
                material,
                image,
                class_size: extent[0].max(extent[1]),
                extent,
                block,
                slot,
            });
        }

        // Geometry: deduplicated vertices, positions relative to the origin, each naming its rect.
        let rect_of: HashMap<(MaterialId, i32), usize> = l
            .rects
            .iter()
            .enumerate()
            .map(|(i, r)| ((r.material, r.class), i))
            .collect();
        let first_vertex = self.out.tree.vertices.len() as u32;
        let first_index = self.out.tree.indices.len() as u32;
        let mut dedup: HashMap<[u32; 8], u32> = HashMap::new();
        let mut hulls =
            vec![(DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)); l.rects.len()];
        for &ti in &self.order[n.range.clone()] {
            let t = &self.infos[ti as usize];
            let pos = t.pos;
            let ri = rect_of[&(t.material, t.class)];
            for uv in t.uv.iter().filter(|uv| uv.is_finite()) {
                hulls[ri].0 = hulls[ri].0.min(*uv);
                hulls[ri].1 = hulls[ri].1.max(*uv);
            }
            for (k, p) in pos.iter().enumerate() {
                let v = TreeVertex {
                    pos: finite3((*p - origin).as_vec3().to_array()),
                    orig_uv: finite2(t.uv[k].as_vec2().to_array()),
                    leaf: leaf_id.0,
                    original: slot_of[&t.material],
                    rect: ri as u32,
                };
                let key: [u32; 8] = bytemuck::cast(v);
                let vi = *dedup.entry(key).or_insert_with(|| {
                    self.out.tree.vertices.push(v);
                    self.out.tree.vertices.len() as u32 - 1
                });
                self.out.tree.indices.push(vi);
            }
            self.out.tree.source_triangles.push(t.scene_tri);
        }
        let vertex_count = self.out.tree.vertices.len() as u32 - first_vertex;
        let index_count = self.out.tree.indices.len() as u32 - first_index;
        self.out.occupancy.push(l.occupancy);
        self.out
            .capped
            .push(l.rects.iter().map(|r| r.capped[0] || r.capped[1]).collect());
        for (r, (lo, hi)) in l.rects.iter().zip(&hulls) {
            let stored = r.uv_max - r.uv_min;
            self.out.periods_stored += stored.x * stored.y;
            let spanned = (*hi - *lo).max(DVec2::ZERO);
            if spanned.is_finite() {
                self.out.periods_spanned += spanned.x * spanned.y;
            }
        }
        self.out.tree.leaves.push(Leaf {
            node,
            origin,
            first_vertex,
            vertex_count,
            first_index,
            index_count,
            rects: l
                .rects
                .iter()
                .map(|r| AtlasRect {
                    material: r.material,
                    outer: r.outer,
                    inner: r.inner,
                    uv_min: r.uv_min.to_array(),
                    uv_max: r.uv_max.to_array(),
                    wrap: r.wrap,
                    capped: r.capped,
                })
                .collect(),
            originals,
            clamp_scale: l.clamp_scale,
        });
        leaf_id
    }
}

fn finite2(a: [f32; 2]) -> [f32; 2] {
    a.map(|x| if x.is_finite() { x } else { 0.0 })
}
fn finite3(a: [f32; 3]) -> [f32; 3] {
    a.map(|x| if x.is_finite() { x } else { 0.0 })
}

/// Greedy grouping of byte sizes into blocks of at most `budget` bytes (items larger than the budget get a
/// block of their own), in order.
pub struct BlockGrouping {
    /// Bytes of each block.
    pub sizes: Vec<u64>,
    /// For each item: (block index, slot within the block).
    pub place: Vec<(usize, u32)>,
}

pub fn group_into_blocks(items: impl IntoIterator<Item = u64>, budget: u64) -> BlockGrouping {
    let mut g = BlockGrouping {
        sizes: Vec::new(),
        place: Vec::new(),
    };
    let mut slot = 0u32;
    for bytes in items {
        match g.sizes.last_mut() {
            Some(last) if *last + bytes <= budget => {
                *last += bytes;
                slot += 1;
            }
            _ => {
                g.sizes.push(bytes);
                slot = 0;
            }
        }
        g.place.push((g.sizes.len() - 1, slot));
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grouping_respects_budget_and_order() {
        let g = group_into_blocks([40, 50, 20, 200, 10, 90], 100);
        assert_eq!(g.sizes, vec![90, 20, 200, 100]);
        assert_eq!(
            g.place,
            vec![(0, 0), (0, 1), (1, 0), (2, 0), (3, 0), (3, 1)]
        );
    }

    #[test]
    fn classes_are_powers_of_two_within_limits() {
        assert_eq!(original_class(1, 1), 4);
        assert_eq!(original_class(300, 200), 512);
        assert_eq!(original_class(512, 512), 512);
        assert_eq!(original_class(8192, 16), 2048);
        assert_eq!(original_extent(8192, 16), [2048, 16]);
        assert_eq!(original_extent(300, 200), [512, 256]);
        assert_eq!(original_extent(1, 1024), [4, 1024]);
    }
}
