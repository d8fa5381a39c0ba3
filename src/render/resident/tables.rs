//! The CPU half of a GPU load: every tree's geometry, leaf table, rect maps and original-texture mapping
//! (TAM) gathered into the shared arrays the shader indexes ([`gather_tables`]), with what the shader does
//! not check checked here (vertex → TAM and rect ranges, class sizes, slot offsets).

use super::{MaterialOriginal, UniqueOriginal};
use crate::ids::{BlockId, NONE};
use crate::model::TreeVertex;
use crate::render::RenderError;
use crate::render::batch::{Pass, TreeBatchInfo, blend_list, leaf_ranges};
use crate::render::textures::class_index;
use crate::render::wgsl::tree::{ALPHA_OPAQUE, LeafInfo, RectMap, TamEntry, WRAP_T_SHIFT};
use crate::scene::{AlphaMode, Wrap};
use crate::store::format::{MaterialRecord, OriginalRecord, encode_wrap};
use crate::store::{TreeFile, TreeView};
use crate::texfmt::TexFormat;
use glam::DVec3;
use std::collections::HashMap;

/// Geometry, leaves and the original-texture mapping of all trees, gathered on the CPU ([`gather_tables`]): what
/// [`super::Resident`] uploads. Atlas slots are still `None` and TAM layers 0 (assigned at upload).
#[derive(Default)]
pub struct GpuTables {
    pub infos: Vec<TreeBatchInfo>,
    pub vertices: Vec<TreeVertex>,
    pub indices: Vec<u32>,
    pub leaves: Vec<LeafInfo>,
    /// Every leaf's rects, global numbering.
    pub rects: Vec<RectMap>,
    /// Leaf origins, f64, global leaf numbering.
    pub origins: Vec<DVec3>,
    pub tam: Vec<TamEntry>,
    pub tam_unique: Vec<u32>,
    pub uniques: Vec<UniqueOriginal>,
    /// Per TAM entry, its index in `material_originals` (the naive baseline's bind group).
    pub tam_material_original: Vec<u32>,
    pub material_originals: Vec<MaterialOriginal>,
    /// `(tree, node, block)` of every atlas, in upload order.
    pub atlas_blocks: Vec<(u32, u32, BlockId)>,
    /// `(block, unique, offset in the block)` of every original texture reference (one per TAM entry: per
    /// leaf and material that draws it).
    pub block_uniques: Vec<(BlockId, u32, u64)>,
    /// Storage format of each tree's blocks.
    pub formats: Vec<TexFormat>,
    pub has_alpha: bool,
}

/// Reads all trees' tables into the shared CPU arrays; checks what the shader will index.
pub fn gather_tables(file: &TreeFile) -> Result<GpuTables, RenderError> {
    let materials = file.materials();
    let mut g = GpuTables::default();
    // A stored original (its block and slot) is one texture layer, however many materials draw it
    // (`assemble::StoredOriginal`; keyed by material, 64 materials on one image held 64 layers: fault
    // hunt, session 34); the naive baseline binds each (material, texture) pair on its own.
    let mut unique_of: HashMap<(u32, u32), u32> = HashMap::new();
    let mut material_original_of: HashMap<(u32, u32), u32> = HashMap::new();
    // Per alpha tree: (its position in `g.infos`, its blend list, per node its range of the list).
    type BlendList = (usize, Vec<u32>, Vec<(u32, u32)>);
    let mut blend_lists: Vec<BlendList> = Vec::new();
    for t in 0..file.trees() {
        let view = file.tree(t).ok_or(RenderError::MissingTree { tree: t })?;
        if view.kind == crate::model::TreeKind::Alpha {
            g.has_alpha = true;
        }
        let offsets = slot_offsets(view.originals, view.format());
        let count_u32 = |what: &'static str, n: usize| {
            u32::try_from(n).map_err(|_| RenderError::TooLarge { what })
        };
        let leaf_base = count_u32("leaves", g.leaves.len())?;
        let index_base = count_u32("indices", g.indices.len())?;
        let vertex_base = i32::try_from(g.vertices.len())
            .map_err(|_| RenderError::TooLarge { what: "vertices" })?;
        for (li, leaf) in view.leaves.iter().enumerate() {
            let node = view
                .nodes
                .get(leaf.node as usize)
                .ok_or(RenderError::LeafNode {
                    tree: t,
                    leaf: li,
                    node: leaf.node,
                    nodes: view.nodes.len(),
                })?;
            let originals = view.leaf_originals(leaf);
            let first_tam = count_u32("tam", g.tam.len())?;
            let first_rect = count_u32("rects", g.rects.len())?;
            let cell = [node.cell.ix, node.cell.iy];
            let level = node.level;
            g.leaves.push(LeafInfo {
                cell,
                level,
                first_tam,
                first_rect,
                cell_level: LeafInfo::pack_cell_level(level, cell),
                _p1: 0,
                _p2: 0,
            });
            g.rects.extend(view.leaf_rects(leaf).iter().map(|r| {
                let alpha = materials
                    .get(r.material as usize)
                    .and_then(|m| m.alpha())
                    .unwrap_or(AlphaMode::Opaque);
                RectMap::new(&r.decode(), alpha)
            }));
            g.origins.push(DVec3::from_array(leaf.origin));
            for o in originals {
                // Built from the same table: a missing slot is a broken invariant, not a zero offset.
                let offset = *offsets
                    .get(&(o.block, o.slot))
                    .ok_or(RenderError::MissingSlot {
                        block: o.block,
                        slot: o.slot,
                    })?;
                let m = materials.get(o.material as usize).copied();
                let class = class_index(o.class_size()).ok_or(RenderError::BadClass {
                    tree: t,
                    leaf: li as u32,
                    class_size: o.class_size(),
                })?;
                let next = g.uniques.len() as u32;
                let ui = *unique_of.entry((o.block, o.slot)).or_insert(next);
                if ui == next {
                    g.uniques.push(UniqueOriginal {
                        class_size: o.class_size(),
                        extent: o.extent(),
                        class,
                        slot: 0,
                        layer: 0,
                        block: BlockId(o.block),
                        offset,
                        format: view.format(),
                    });
                }
                g.tam_unique.push(ui);
                let next = g.material_originals.len() as u32;
                let mi = *material_original_of.entry((o.material, ui)).or_insert(next);
                if mi == next {
                    g.material_originals.push(MaterialOriginal {
                        material: o.material,
                        unique: ui,
                    });
                }
                g.tam_material_original.push(mi);
                g.block_uniques.push((BlockId(o.block), ui, offset));
                let wrap = m.and_then(|m| m.wraps()).unwrap_or([Wrap::Repeat; 2]);
                g.tam.push(TamEntry {
                    class_index: class,
                    layer: 0,
                    wrap: encode_wrap(wrap[0]) | encode_wrap(wrap[1]) << WRAP_T_SHIFT,
                    alpha_mode: m.map_or(ALPHA_OPAQUE, |m| m.alpha_mode),
                    factor: m.map_or([1.0; 4], |m| m.base_color_factor),
                    cutoff: m.map_or(0.5, |m| m.alpha_cutoff),
                    class_size: o.class_size() as f32,
                    extent: o.extent().map(|v| v as f32),
                });
            }
            // Every vertex's `original` and `rect` must index the leaf's TAM and rect ranges (the shader does
            // not check).
            let first = leaf.first_vertex as usize;
            let verts = view
                .vertices
                .get(first..first.saturating_add(leaf.vertex_count as usize))
                .unwrap_or(&[]);
            if let Some(v) = verts.iter().find(|v| {
                v.original >= leaf.original_count
                    || v.rect >= leaf.rect_count
                    || v.leaf != li as u32
            }) {
                return Err(RenderError::BadVertex {
                    tree: t,
                    leaf: li as u32,
                    original: v.original,
                    originals: leaf.original_count,
                    rect: v.rect,
                    rects: leaf.rect_count,
                });
            }
        }
        let ranges = leaf_ranges(view.nodes);
        let (passes, cutoffs) = passes_and_cutoffs(&view, materials, &ranges);
        for (ni, n) in view.nodes.iter().enumerate() {
            if n.atlas_block != NONE {
                g.atlas_blocks
                    .push((t as u32, ni as u32, BlockId(n.atlas_block)));
            }
        }
        g.formats.push(view.format());
        if passes.contains(&Pass::Blend) {
            let ranges = view.nodes.iter().map(|n| (n.first_index, n.index_count));
            let (list, ranges) = blend_list(view.indices, ranges, |t| {
                masked_triangle(&view, materials, t)
            });
            blend_lists.push((g.infos.len(), list, ranges));
        }
        g.infos.push(TreeBatchInfo {
            tree: t as u32,
            leaf_base,
            index_base,
            vertex_base,
            leaf_ranges: ranges,
            passes,
            cutoffs,
            blend_ranges: Vec::new(),
            atlas_slots: vec![None; view.nodes.len()],
        });
        // The GPU copy carries global numbers (checked above: every vertex's leaf is its own, its rect
        // and original inside the leaf's ranges): leaf, rect and TAM entry, so the vertex stage indexes
        // the buffers without loading a base (docs/DESIGN.md "Storage loads in the vertex stage").
        // A vertex outside every leaf's range was not checked there: its leaf must still exist.
        let leaves = &g.leaves[leaf_base as usize..];
        g.vertices.reserve(view.vertices.len());
        for (vi, v) in view.vertices.iter().enumerate() {
            let leaf = leaves.get(v.leaf as usize).ok_or(RenderError::VertexLeaf {
                tree: t,
                vertex: vi,
                leaf: v.leaf,
                leaves: leaves.len(),
            })?;
            g.vertices.push(TreeVertex {
                leaf: v.leaf.saturating_add(leaf_base),
                original: v.original.saturating_add(leaf.first_tam),
                rect: v.rect.saturating_add(leaf.first_rect),
                ..*v
            });
        }
        g.indices.extend_from_slice(view.indices);
    }
    // The blend lists after every tree's indices (their values are tree-local vertex numbers, as the
    // tree's own indices, drawn with the tree's base vertex).
    for (info, list, ranges) in blend_lists {
        let base = u32::try_from(g.indices.len())
            .ok()
            .filter(|b| b.checked_add(list.len() as u32).is_some())
            .ok_or(RenderError::TooLarge { what: "indices" })?;
        g.indices.extend_from_slice(&list);
        g.infos[info].blend_ranges = ranges.into_iter().map(|(f, c)| (base + f, c)).collect();
    }
    Ok(g)
}

/// Triangle `t` of an alpha tree is MASK for the blend pass of tree.wgsl (which drops it, by the alpha
/// mode of its rect in atlas draws and of its TAM entry in original draws): every vertex's rect and
/// original are of a MASK material. Anything else, an index or record out of range included, is kept.
fn masked_triangle(view: &TreeView<'_>, materials: &[MaterialRecord], t: usize) -> bool {
    let is_mask = |material: u32| {
        matches!(
            materials.get(material as usize).and_then(|m| m.alpha()),
            Some(AlphaMode::Mask { .. })
        )
    };
    let tri = view.indices.get(3 * t..3 * t + 3).unwrap_or(&[]);
    tri.len() == 3
        && tri.iter().all(|&i| {
            let Some(v) = view.vertices.get(i as usize) else {
                return false;
            };
            let Some(leaf) = view.leaves.get(v.leaf as usize) else {
                return false;
            };
            let rect = view.leaf_rects(leaf).get(v.rect as usize);
            let original = view.leaf_originals(leaf).get(v.original as usize);
            rect.is_some_and(|r| is_mask(r.material))
                && original.is_some_and(|o| is_mask(o.material))
        })
}

/// Per node of an alpha tree: Blend if any leaf below uses a BLEND material, else Mask; cutoff = smallest
/// MASK cutoff below (0.5 without one). Opaque trees: all Opaque.
fn passes_and_cutoffs(
    view: &TreeView<'_>,
    materials: &[MaterialRecord],
    ranges: &[(u32, u32)],
) -> (Vec<Pass>, Vec<f32>) {
    let n = view.nodes.len();
    if view.kind == crate::model::TreeKind::Opaque {
        return (vec![Pass::Opaque; n], vec![0.5; n]);
    }
    let per_leaf: Vec<(bool, f32)> = view
        .leaves
        .iter()
        .map(|l| {
            let mut blend = false;
            let mut cutoff = f32::INFINITY;
            for r in view.leaf_rects(l) {
                match materials.get(r.material as usize).and_then(|m| m.alpha()) {
                    Some(AlphaMode::Blend) => blend = true,
                    Some(AlphaMode::Mask { cutoff: c }) => cutoff = cutoff.min(c),
                    _ => {}
                }
            }
            (blend, cutoff)
        })
        .collect();
    let mut passes = Vec::with_capacity(n);
    let mut cutoffs = Vec::with_capacity(n);
    for &(first, count) in ranges {
        let below = per_leaf
            .get(first as usize..(first as usize).saturating_add(count as usize))
            .unwrap_or(&[]);
        let blend = below.iter().any(|l| l.0);
        let cutoff = below.iter().map(|l| l.1).fold(f32::INFINITY, f32::min);
        passes.push(if blend { Pass::Blend } else { Pass::Mask });
        cutoffs.push(if cutoff.is_finite() { cutoff } else { 0.5 });
    }
    (passes, cutoffs)
}

/// Byte offset of each original inside its block ([`crate::model::original_slots`]).
fn slot_offsets(originals: &[OriginalRecord], format: TexFormat) -> HashMap<(u32, u32), u64> {
    let slots = originals.iter().map(|o| (o.block, o.slot, o.extent()));
    crate::model::original_slots(slots, format)
        .into_iter()
        .map(|(b, slot, _, off)| ((b, slot), off))
        .collect()
}
