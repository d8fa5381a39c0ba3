//! Per-frame draw data, as plain data (no wgpu types): from the cut of each tree ([`crate::select::Cut`]),
//! one indirect record per selected node and one [`NodeDraw`] per record, grouped by pipeline pass
//! (texture-array batching, Trapp & Döllner 2015: one multi-draw-indirect call per pipeline).
//!
//! Layout of the GPU data (all trees of a file share one set of buffers):
//!
//! - vertices: every tree's [`TreeVertex`] back to back; tree `t` starts at vertex `vertex_base[t]`, which
//!   is the record's `base_vertex` (tree indices are tree-local absolute vertex numbers);
//! - indices: every tree's indices back to back; tree `t` starts at `index_base[t]`, added to the node's
//!   `first_index`;
//! - leaves: every tree's leaves back to back; tree `t` starts at `leaf_base[t]`, which the GPU copy of the
//!   vertices adds to their tree-local `leaf`, so the shader finds leaf `vertex.leaf`;
//! - per-frame leaf offsets `leaf.origin − eye` (f64 on the CPU, then f32; docs/DESIGN.md "Precision"): only the
//!   leaves of drawn nodes are updated ([`LeafOffsets::update`]).
//!
//! Record `i` of the indirect buffer has `first_instance = i`: the vertex shader reads `records[i]` through
//! `instance_index`.
//!
//! The records themselves ([`NodeDraw`], [`RectMap`], and the leaf and TAM records) are the shader's
//! twins in [`crate::render::wgsl::tree`].

use super::textures::MAX_ATLAS_ARRAYS;
use super::wgsl::tree::{
    ALPHA_BLEND, ALPHA_MASK, ALPHA_OPAQUE, ALPHA_SHIFT, NodeDraw, PASS_BLEND, PASS_MASK,
    PASS_OPAQUE, RectMap, WRAP_T_SHIFT,
};
use crate::ids::NONE;
use crate::model::transform::half_gap;
use crate::model::{AtlasRect, TreeVertex};
use crate::paging::Resolved;
use crate::scene::AlphaMode;
use crate::select::{Cut, Source};
use crate::store::format::NodeRecord;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

/// `DrawIndexedIndirectArgs` as stored in the indirect buffer (20 bytes, wgpu's layout).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct DrawIndexedIndirect {
    pub index_count: u32,
    pub instance_count: u32,
    pub first_index: u32,
    pub base_vertex: i32,
    pub first_instance: u32,
}
const _: () = assert!(size_of::<DrawIndexedIndirect>() == 20);

/// Built from the stored tree (the struct and its shader twins are in [`crate::render::wgsl::tree`]).
impl RectMap {
    /// The GPU record of a stored rect of a material with alpha mode `alpha`.
    pub fn new(r: &AtlasRect, alpha: AlphaMode) -> RectMap {
        let (mode, cutoff) = match alpha {
            AlphaMode::Opaque => (ALPHA_OPAQUE, 0.5),
            AlphaMode::Mask { cutoff } => (ALPHA_MASK, cutoff),
            AlphaMode::Blend => (ALPHA_BLEND, 0.5),
        };
        let tpu = r.texels_per_uv();
        let gap = |k: usize| half_gap(r.uv_min[k], r.uv_max[k]) as f32;
        RectMap {
            uv_min: [r.uv_min[0] as f32, r.uv_min[1] as f32],
            texels_per_uv: [tpu[0] as f32, tpu[1] as f32],
            inner_lo: [r.inner[0] as f32, r.inner[1] as f32],
            half_gap: [gap(0), gap(1)],
            outer_lo: [r.outer[0] as f32, r.outer[1] as f32],
            outer_hi: [
                (r.outer[0] + r.outer[2]) as f32,
                (r.outer[1] + r.outer[3]) as f32,
            ],
            wrap: r.wrap[0].code() | r.wrap[1].code() << WRAP_T_SHIFT | mode << ALPHA_SHIFT,
            cutoff,
            inner_size: [r.inner[2] as f32, r.inner[3] as f32],
            mean: u32::from_le_bytes(r.mean),
            point: u32::from(r.uv_min == r.uv_max && r.inner[2] <= 1 && r.inner[3] <= 1),
        }
    }
}

/// The pipeline a record is drawn with; the discriminant is the shader's `PASS`.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Pass {
    /// Opaque tree: depth write, no blending.
    Opaque = PASS_OPAQUE,
    /// Alpha tree, subtree without BLEND materials: discard below the cutoff, depth write.
    Mask = PASS_MASK,
    /// Alpha tree, subtree with a BLEND material: blending, no depth write, after the others.
    Blend = PASS_BLEND,
}

impl Pass {
    pub const ALL: [Pass; 3] = [Pass::Opaque, Pass::Mask, Pass::Blend];
}

/// A pipeline of the tree renderer: pass × texture source, atlas records also by atlas array. Each is one
/// `multi_draw_indexed_indirect`: a software rasteriser such as lavapipe executes every texture fetch of
/// a shader under an execution mask, so a fragment shader able to sample both the atlas arrays and every
/// class array would pay for all of them on every pixel; with one pipeline per atlas array an atlas
/// fragment runs exactly one fetch (`ATLAS_ARRAY` in tree.wgsl).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct Group {
    pub pass: Pass,
    /// Original textures (else atlases).
    pub original: bool,
    /// The atlas array the records sample (below [`MAX_ATLAS_ARRAYS`]; 0 for originals).
    pub array: u8,
}

/// Groups a pass has: one per atlas array, then the originals.
const GROUPS_PER_PASS: usize = MAX_ATLAS_ARRAYS + 1;

/// Number of [`Group`]s.
pub const GROUPS: usize = 3 * GROUPS_PER_PASS;

impl Group {
    /// All groups in draw order: opaque atlas arrays 0 … 3, opaque originals, mask atlas arrays …, mask
    /// originals, blend ….
    pub const ALL: [Group; GROUPS] = {
        let mut all = [Group::new(Pass::Opaque, false); GROUPS];
        let passes = [Pass::Opaque, Pass::Mask, Pass::Blend];
        let mut i = 0;
        while i < GROUPS {
            let pass = passes[i / GROUPS_PER_PASS];
            let k = i % GROUPS_PER_PASS;
            all[i] = if k == MAX_ATLAS_ARRAYS {
                Group::new(pass, true)
            } else {
                Group::atlas(pass, k as u8)
            };
            i += 1;
        }
        all
    };

    /// Atlas array 0 (`original == false`) or the original textures of `pass`.
    pub const fn new(pass: Pass, original: bool) -> Group {
        Group {
            pass,
            original,
            array: 0,
        }
    }

    /// Atlas array `array` of `pass`.
    pub const fn atlas(pass: Pass, array: u8) -> Group {
        Group {
            pass,
            original: false,
            array,
        }
    }

    /// Position in [`Group::ALL`]. Contract: `array < MAX_ATLAS_ARRAYS` ([`FrameBatch::add_cut`] skips
    /// and counts a slot past it), so every group has its own position.
    pub fn index(self) -> usize {
        debug_assert!(usize::from(self.array) < MAX_ATLAS_ARRAYS, "{self:?}");
        let k = if self.original {
            MAX_ATLAS_ARRAYS
        } else {
            usize::from(self.array)
        };
        self.pass as usize * GROUPS_PER_PASS + k
    }
}

/// Where a node's atlas is resident.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AtlasSlot {
    pub array: u32,
    pub layer: u32,
}

/// Everything batching needs to know about one tree (static for the life of a renderer).
#[derive(Clone, Debug, Default)]
pub struct TreeBatchInfo {
    /// Tree index in the file.
    pub tree: u32,
    pub leaf_base: u32,
    pub index_base: u32,
    pub vertex_base: i32,
    /// Per node: its subtree's leaves `[first, first + count)` (tree-local; leaves are in tree order).
    pub leaf_ranges: Vec<(u32, u32)>,
    /// Per node: the pass its records go to.
    pub passes: Vec<Pass>,
    /// Per node of an alpha tree: `(first index, index count)` in the shared index buffer of the triangles
    /// of its subtree that its blend-pass record draws: the tree's blend list ([`blend_list`]). Empty
    /// (opaque trees, or not built): the blend pass draws the node's whole range.
    pub blend_ranges: Vec<(u32, u32)>,
    /// Per node: the alpha cutoff of its atlas draws in the mask pass.
    pub cutoffs: Vec<f32>,
    /// Per node: where its atlas is resident (`None`: not resident; such nodes are drawn with originals if
    /// they are leaves and skipped otherwise — with all blocks resident this does not happen).
    pub atlas_slots: Vec<Option<AtlasSlot>>,
}

/// Per node, the range of leaves of its subtree: `(first leaf, count)`. Leaves are numbered in tree order and
/// parents precede children, so a reverse sweep unions the children's ranges. Out-of-range child links are
/// ignored (validated files have none).
pub fn leaf_ranges(nodes: &[NodeRecord]) -> Vec<(u32, u32)> {
    let mut lo = vec![u32::MAX; nodes.len()];
    let mut hi = vec![0u32; nodes.len()];
    for (i, n) in nodes.iter().enumerate().rev() {
        if n.leaf != NONE {
            lo[i] = lo[i].min(n.leaf);
            hi[i] = hi[i].max(n.leaf.saturating_add(1));
        }
        for &c in &n.children {
            let c = c as usize;
            if c > i && c < nodes.len() {
                lo[i] = lo[i].min(lo[c]);
                hi[i] = hi[i].max(hi[c]);
            }
        }
    }
    lo.iter()
        .zip(&hi)
        .map(|(&l, &h)| if h > l { (l, h - l) } else { (0, 0) })
        .collect()
}

/// The blend list of one alpha tree ([`TreeBatchInfo::blend_ranges`]): the tree's indices without the
/// triangles the blend pass would drop (`drops(t)` for triangle `t` of the index buffer: a MASK triangle,
/// drawn by its node's depth pre-pass), in index-buffer order, and per node the range of it inside the
/// node's range `(first_index, index_count)` of the tree's index buffer, relative to the list's start.
/// Node ranges of a pre-order tree are unions of their leaves' ranges, so each is one run of the list.
pub fn blend_list(
    indices: &[u32],
    node_ranges: impl Iterator<Item = (u32, u32)>,
    mut drops: impl FnMut(usize) -> bool,
) -> (Vec<u32>, Vec<(u32, u32)>) {
    let triangles = indices.len() / 3;
    let mut list = Vec::new();
    // kept[t]: triangles of the list before triangle t.
    let mut kept = Vec::with_capacity(triangles + 1);
    kept.push(0u32);
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        if !drops(t) {
            list.extend_from_slice(tri);
        }
        kept.push((list.len() / 3) as u32);
    }
    let ranges = node_ranges
        .map(|(first, count)| {
            let lo = (first / 3) as usize;
            let hi = (first.saturating_add(count) / 3) as usize;
            let (lo, hi) = (lo.min(triangles), hi.min(triangles));
            let (a, b) = (kept[lo], kept[hi.max(lo)]);
            (a * 3, (b - a) * 3)
        })
        .collect();
    (list, ranges)
}

/// How records are made.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct BatchOptions {
    /// Dummy mode: every record is an atlas draw of layer 0 (one 1×1 texture bound for everything).
    pub dummy: bool,
}

/// One frame's draw data for all trees.
#[derive(Clone, Debug, Default)]
pub struct FrameBatch {
    /// Indirect records, grouped by [`Group`] (`group_ranges`); `indirect[i].first_instance == i`.
    pub indirect: Vec<DrawIndexedIndirect>,
    /// `records[i]` belongs to `indirect[i]`.
    pub records: Vec<NodeDraw>,
    /// Per [`Group`] (by [`Group::index`]): `(first, count)` of `indirect` drawn by that group's multi-draw
    /// call.
    pub group_ranges: [(u32, u32); GROUPS],
    /// Triangles drawn.
    pub triangles: u64,
    /// Records drawn with original textures.
    pub original_records: u32,
    pending: [Vec<(DrawIndexedIndirect, NodeDraw)>; GROUPS],
}

impl FrameBatch {
    pub fn new() -> FrameBatch {
        FrameBatch::default()
    }

    /// Starts a frame (keeps allocations).
    pub fn clear(&mut self) {
        self.indirect.clear();
        self.records.clear();
        self.group_ranges = [(0, 0); GROUPS];
        self.triangles = 0;
        self.original_records = 0;
        for p in &mut self.pending {
            p.clear();
        }
    }

    /// Adds the records of one tree's cut. `resolved[i]` says how item `i` is drawn this frame (its own
    /// atlas, an ancestor's atlas because blocks are missing, or the leaf's originals; see
    /// [`crate::paging::resolve`](mod@crate::paging::resolve)); pass `None` when everything is resident (every item as selected). Items
    /// whose node is out of range, or whose atlas holds no GPU layer (or one in an array past
    /// [`MAX_ATLAS_ARRAYS`]), are skipped; returns how many were
    /// (the renderer reports them as `FrameStats::skipped_draws`).
    pub fn add_cut(
        &mut self,
        info: &TreeBatchInfo,
        nodes: &[NodeRecord],
        cut: &Cut,
        resolved: Option<&[Resolved]>,
    ) -> u32 {
        let mut skipped = 0;
        for (i, item) in cut.items.iter().enumerate() {
            let n = item.node.idx();
            let (Some(node), Some(&pass)) = (nodes.get(n), info.passes.get(n)) else {
                skipped += 1;
                continue;
            };
            let draw_with = match resolved.and_then(|r| r.get(i)) {
                Some(r) => r.atlas_node,
                None => (item.source == Source::Atlas).then_some(item.node),
            };
            let atlas = match draw_with {
                Some(a) => {
                    let slot = info.atlas_slots.get(a.idx()).copied().flatten();
                    match (slot, nodes.get(a.idx())) {
                        // An array past the pipelines' (a broken slot table) is skipped and counted,
                        // never drawn from another array.
                        (Some(s), Some(an)) if (s.array as usize) < MAX_ATLAS_ARRAYS => {
                            Some((s, an.level))
                        }
                        _ => {
                            skipped += 1;
                            continue;
                        }
                    }
                }
                None => None,
            };
            let record = NodeDraw {
                atlas_layer: atlas.map_or(NONE, |(s, _)| s.layer),
                atlas_array: atlas.map_or(0, |(s, _)| s.array),
                level: atlas.map_or(node.level, |(_, l)| l),
                leaf_base: info.leaf_base,
                alpha_cutoff: info.cutoffs.get(n).copied().unwrap_or(0.5),
                node: item.node.0,
                tree: info.tree,
                draw_bits: atlas.map_or(0, |(s, l)| NodeDraw::pack(s.layer, s.array, l)),
            };
            let draw = DrawIndexedIndirect {
                index_count: item.index_count,
                instance_count: 1,
                first_index: info.index_base.saturating_add(item.first_index),
                base_vertex: info.vertex_base,
                first_instance: 0,
            };
            if atlas.is_none() {
                self.original_records += 1;
            }
            self.triangles += u64::from(item.index_count / 3);
            let group = match atlas {
                Some((s, _)) => Group::atlas(pass, s.array as u8),
                None => Group::new(pass, true),
            };
            if pass != Pass::Blend {
                self.pending[group.index()].push((draw, record));
                continue;
            }
            // Depth pre-pass of the node's opaque texels (MASK materials above their cutoff, BLEND ones at
            // full alpha) in the mask pipeline: a node mixing MASK and BLEND materials (one scaled leaf may
            // hold a whole track's vegetation) keeps MASK occlusion right; the blend pass then adds only
            // what the pre-pass left (equal depth fails the Greater test), drawing only the node's range
            // of the blend list: its MASK triangles could not change a pixel there.
            let pre_pass = Group {
                pass: Pass::Mask,
                ..group
            };
            self.pending[pre_pass.index()].push((draw, record));
            let draw = match info.blend_ranges.get(n) {
                Some(&(first_index, index_count)) => DrawIndexedIndirect {
                    index_count,
                    first_index,
                    ..draw
                },
                None => draw,
            };
            if draw.index_count > 0 {
                self.pending[group.index()].push((draw, record));
            }
        }
        skipped
    }

    /// Concatenates the passes into `indirect`/`records` and numbers `first_instance`. Call once after all
    /// [`FrameBatch::add_cut`]s of the frame.
    pub fn finish(&mut self) {
        self.indirect.clear();
        self.records.clear();
        for g in Group::ALL {
            let start = self.indirect.len() as u32;
            for (mut draw, record) in self.pending[g.index()].drain(..) {
                draw.first_instance = self.indirect.len() as u32;
                self.indirect.push(draw);
                self.records.push(record);
            }
            self.group_ranges[g.index()] = (start, self.indirect.len() as u32 - start);
        }
    }

    /// Number of indirect records.
    pub fn len(&self) -> usize {
        self.indirect.len()
    }

    pub fn is_empty(&self) -> bool {
        self.indirect.is_empty()
    }
}

/// The per-frame, camera-relative leaf origins `leaf.origin − eye`, computed in f64 and stored as f32
/// (docs/DESIGN.md "Precision"). WGSL: `array<vec4<f32>>` indexed by the vertex's global `leaf`.
#[derive(Clone, Debug, Default)]
pub struct LeafOffsets {
    /// All trees' leaf origins back to back (same numbering as the leaves buffer).
    pub origins: Vec<DVec3>,
    /// `xyz` = origin − eye, `w` = 0.
    pub offsets: Vec<[f32; 4]>,
}

impl LeafOffsets {
    pub fn new(origins: Vec<DVec3>) -> LeafOffsets {
        let offsets = vec![[0.0; 4]; origins.len()];
        LeafOffsets { origins, offsets }
    }

    /// Updates the offsets of the leaves under every item of `cut` (tree with leaves from `leaf_base`);
    /// returns the number of leaves updated.
    pub fn update(&mut self, info: &TreeBatchInfo, cut: &Cut, eye: DVec3) -> u32 {
        let mut updated = 0;
        for item in &cut.items {
            let Some(&(first, count)) = info.leaf_ranges.get(item.node.idx()) else {
                continue;
            };
            let start = info.leaf_base.saturating_add(first) as usize;
            let end = start.saturating_add(count as usize).min(self.origins.len());
            for i in start.min(end)..end {
                let d = self.origins[i] - eye;
                self.offsets[i] = [d.x as f32, d.y as f32, d.z as f32, 0.0];
                updated += 1;
            }
        }
        updated
    }
}

/// The vertex stride of [`TreeVertex`] (locations 0–4: pos, orig_uv, leaf, original, rect).
pub const VERTEX_STRIDE: u64 = size_of::<TreeVertex>() as u64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blend_list_keeps_order_and_cuts_node_ranges() {
        // Six triangles (vertex numbers = 10 × triangle + corner); 1 and 4 are dropped.
        let indices: Vec<u32> = (0..6u32)
            .flat_map(|t| [10 * t, 10 * t + 1, 10 * t + 2])
            .collect();
        // Root (all), two children (triangles 0–2 and 3–5), a leaf holding only the dropped triangle 4,
        // an empty node, and a range past the end (clamped).
        let nodes = [(0, 18), (0, 9), (9, 9), (12, 3), (6, 0), (15, 9)];
        let (list, ranges) = blend_list(&indices, nodes.into_iter(), |t| t == 1 || t == 4);
        let kept: Vec<u32> = [0u32, 2, 3, 5]
            .iter()
            .flat_map(|&t| [10 * t, 10 * t + 1, 10 * t + 2])
            .collect();
        assert_eq!(list, kept);
        assert_eq!(
            ranges,
            vec![(0, 12), (0, 6), (6, 6), (9, 0), (3, 0), (9, 3)]
        );
        // Every node's run of the list is exactly its kept triangles, in index-buffer order.
        for (&(first, count), &(lf, lc)) in nodes.iter().zip(&ranges) {
            let end = (first + count).min(18) as usize;
            let want: Vec<u32> = indices[first as usize..end.max(first as usize)]
                .chunks_exact(3)
                .filter(|t| t[0] / 10 != 1 && t[0] / 10 != 4)
                .flatten()
                .copied()
                .collect();
            assert_eq!(list[lf as usize..(lf + lc) as usize], want[..]);
        }
    }
}
