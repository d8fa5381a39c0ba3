//! Per-frame draw data, as plain data (no wgpu types): from the cut of each tree ([`crate::select::Cut`]),
//! one indirect record per selected node and one [`NodeRecordGpu`] per record, grouped by pipeline pass
//! (texture-array batching, Trapp & Döllner 2015: one multi-draw-indirect call per pipeline).
//!
//! Layout of the GPU data (all trees of a file share one set of buffers):
//!
//! - vertices: every tree's [`TreeVertex`] back to back; tree `t` starts at vertex `vertex_base[t]`, which
//!   is the record's `base_vertex` (tree indices are tree-local absolute vertex numbers);
//! - indices: every tree's indices back to back; tree `t` starts at `index_base[t]`, added to the node's
//!   `first_index`;
//! - leaves: every tree's leaves back to back; tree `t` starts at `leaf_base[t]`, stored in the node record so
//!   the shader finds leaf `leaf_base + vertex.leaf`;
//! - per-frame leaf offsets `leaf.origin − eye` (f64 on the CPU, then f32; DESIGN.md "Precision"): only the
//!   leaves of drawn nodes are updated ([`LeafOffsets::update`]).
//!
//! Record `i` of the indirect buffer has `first_instance = i`: the vertex shader reads `records[i]` through
//! `instance_index`.

use crate::ids::NONE;
use crate::model::transform::half_gap;
use crate::model::{AtlasRect, RectWrap, TreeVertex};
use crate::paging::Resolved;
use crate::scene::AlphaMode;
use crate::select::{Cut, Source};
use crate::store::format::NodeRecord;
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec2};

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

/// Alpha at and above which a BLEND material's texel counts as opaque in the depth pre-pass of blend
/// nodes (the mask pipeline). WGSL twin: `OPAQUE_ALPHA`.
pub const OPAQUE_ALPHA: f32 = 1.0 - 0.5 / 255.0;

/// Per-draw data, indexed by `instance_index` (= the record's `first_instance`).
/// WGSL twin: `NodeDraw` in `shaders/tree.wgsl`.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct NodeRecordGpu {
    /// Layer of the node's atlas in atlas array `atlas_array`; [`NONE`] for an original-texture draw.
    pub atlas_layer: u32,
    /// Which atlas array (0 unless the layers exceed the device limit, see `render::textures`).
    pub atlas_array: u32,
    /// The node's level j: vertices map their leaf-local atlas UV into this ancestor's atlas.
    pub level: u32,
    /// Index of the tree's leaf 0 in the leaves and leaf-offset buffers.
    pub leaf_base: u32,
    /// The smallest MASK cutoff below the node (diagnostics; fragments are tested with their material's
    /// cutoff, from its rect or TAM entry).
    pub alpha_cutoff: f32,
    /// Tree-local node id (diagnostics).
    pub node: u32,
    /// Tree index.
    pub tree: u32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<NodeRecordGpu>() == 32);

/// Static per-leaf data. WGSL twin: `LeafInfo` in `shaders/tree.wgsl`.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct LeafGpu {
    /// The leaf's cell at its level (paper Fig. 4).
    pub cell_ix: u32,
    pub cell_iy: u32,
    /// The leaf's level K.
    pub level: u32,
    /// First entry of the leaf's texture-array mapping in the TAM buffer (global index).
    pub first_tam: u32,
    /// First entry of the leaf's rects in the rect buffer (global index).
    pub first_rect: u32,
    pub _pad: [u32; 3],
}
const _: () = assert!(size_of::<LeafGpu>() == 32);

/// How a fragment's original UV reaches its texture's rect in its leaf's atlas (DESIGN.md "Repeats"): the
/// rect's per-axis wrap ([`RectWrap`]), then the linear map onto the inner rectangle, kept inside the
/// outer rectangle by the filter footprint. WGSL twin: `RectMap` in `shaders/tree.wgsl`;
/// [`RectMap::texel_f32`] is the shader's arithmetic on the CPU, [`crate::model::transform::rect_texel`]
/// its f64 reference. All lengths in leaf-atlas texels.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct RectMap {
    /// UV shown at the inner rectangle's low edge (after the wrap).
    pub uv_min: [f32; 2],
    /// Leaf-atlas texels per unit of UV.
    pub texels_per_uv: [f32; 2],
    /// Low corner of the inner rectangle.
    pub inner_lo: [f32; 2],
    /// REPEAT axes: half the part of the period the rect does not hold ([`crate::model::transform::half_gap`]).
    pub half_gap: [f32; 2],
    /// The outer rectangle (border included).
    pub outer_lo: [f32; 2],
    pub outer_hi: [f32; 2],
    /// `wrap_s | wrap_t << 2` ([`RectWrap::code`]s) `| alpha_mode << 4` (the material's: 0 opaque, 1 mask,
    /// 2 blend, as [`TamEntry::alpha_mode`]): atlas draws test and blend per material, as originals do.
    pub wrap: u32,
    /// The material's MASK cutoff (0.5 for other modes).
    pub cutoff: f32,
    /// Size of the inner rectangle.
    pub inner_size: [f32; 2],
}
const _: () = assert!(size_of::<RectMap>() == 64);

impl RectMap {
    /// Texels of the inner rectangle at the mip a flattened sample reads ([`RectMap::texel_f32`]): at 2,
    /// a bilinear tap at the inner centre averages the whole period. Block-compressed atlases use the
    /// same level (measured on data/city, BC7 against uncompressed: 47.5–53 dB per view, against 34 dB
    /// with a finer level for BC).
    pub const CELLS: f32 = 2.0;
    /// A footprint larger than this share of the period gets the period's average.
    pub const FLAT_SHARE: f32 = 1.0;
    /// Where the footprint reaches past the border (coarse levels, whose borders are halved per level),
    /// the gradients are sharpened by `k ≤ 1` to what the border protects; below this `k` the sharpened
    /// sample would alias, and the pixel gets the period's average instead.
    pub const SHARPEN_MIN: f32 = 0.25;

    /// The GPU record of a stored rect of a material with alpha mode `alpha`.
    pub fn new(r: &AtlasRect, alpha: AlphaMode) -> RectMap {
        let (mode, cutoff) = match alpha {
            AlphaMode::Opaque => (0, 0.5),
            AlphaMode::Mask { cutoff } => (1, cutoff),
            AlphaMode::Blend => (2, 0.5),
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
            wrap: r.wrap[0].code() | r.wrap[1].code() << 2 | mode << 4,
            cutoff,
            inner_size: [r.inner[2] as f32, r.inner[3] as f32],
        }
    }

    /// `(rect coordinate, sign of its derivative)` of `u` on axis `k`: `rect_axis` in the shader.
    pub fn axis_f32(&self, u: f32, k: usize) -> (f32, f32) {
        let mode = (self.wrap >> (2 * k)) & 3;
        let lo = self.uv_min[k];
        if mode == RectWrap::Repeat.code() {
            let x = u - lo;
            return (x - (x + self.half_gap[k]).floor(), 1.0);
        }
        if mode == RectWrap::Mirror.code() {
            let p = u - 2.0 * (u * 0.5).floor();
            return if p > 1.0 {
                (2.0 - p - lo, -1.0)
            } else {
                (p - lo, 1.0)
            };
        }
        if mode == RectWrap::Clamp.code() {
            return (u.clamp(0.0, 1.0) - lo, 1.0);
        }
        (u - lo, 1.0)
    }

    /// The shader's `rect_texel`: leaf-atlas texel coordinates of UV `uv` with screen derivatives `ddx`,
    /// `ddy` drawn at a level `level_texels` leaf texels per texel of the drawn atlas (`2^(K − j)`), and the
    /// derivatives the sampler is given.
    ///
    /// - Where the filter footprint (half the gradient box plus half a drawn texel) would reach past the
    ///   rect's border, the gradients are scaled by `k = room / half box ≤ 1`, so the filter reads the
    ///   rect's border (the sampler's rule) and never a neighbouring rect.
    /// - A pixel whose footprint exceeds [`RectMap::FLAT_SHARE`] of the inner rectangle's smaller side, or
    ///   whose `k` is below [`RectMap::SHARPEN_MIN`], covers (about) a period: it gets the period's
    ///   average, which the mip level where the inner rectangle is [`RectMap::CELLS`] texels wide holds at
    ///   its centre (the gradients are scaled to that level, the sample moved to the centre) — no neighbour
    ///   bleeds in, no aliasing, and every such pixel of the rect reads the same texels.
    /// - Otherwise the sample is kept half the (sharpened) footprint plus half a drawn texel inside the
    ///   outer rectangle; at the inner centre where the rectangle is narrower than that.
    pub fn texel_f32(
        &self,
        uv: Vec2,
        ddx: Vec2,
        ddy: Vec2,
        level_texels: f32,
    ) -> (Vec2, Vec2, Vec2) {
        let (ts, ss) = self.axis_f32(uv.x, 0);
        let (tt, st) = self.axis_f32(uv.y, 1);
        let tpu = Vec2::from(self.texels_per_uv) * Vec2::new(ss, st);
        let gx = ddx * tpu;
        let gy = ddy * tpu;
        let inner_lo = Vec2::from(self.inner_lo);
        let inner = Vec2::from(self.inner_size);
        let centre = inner_lo + 0.5 * inner;
        let period = inner.x.min(inner.y);
        let footprint = gx.length().max(gy.length());
        let half_box = 0.5 * (gx.abs() + gy.abs());
        let (outer_lo, outer_hi) = (Vec2::from(self.outer_lo), Vec2::from(self.outer_hi));
        let border = (inner_lo - outer_lo).min(outer_hi - (inner_lo + inner));
        let room = (border - Vec2::splat(0.5 * level_texels)).max(Vec2::ZERO);
        let fit = room / half_box.max(Vec2::splat(1e-30));
        let k = fit.min_element().min(1.0);
        if footprint > period * RectMap::FLAT_SHARE || k < RectMap::SHARPEN_MIN {
            let kk = period / RectMap::CELLS / footprint;
            return (centre, gx * kk, gy * kk);
        }
        let (gx, gy) = (gx * k, gy * k);
        let margin = half_box * k + Vec2::splat(0.5 * level_texels);
        let lo = outer_lo + margin;
        let hi = outer_hi - margin;
        let t = inner_lo + Vec2::new(ts, tt) * Vec2::from(self.texels_per_uv);
        let texel = Vec2::new(
            if lo.x > hi.x {
                centre.x
            } else {
                t.x.clamp(lo.x, hi.x)
            },
            if lo.y > hi.y {
                centre.y
            } else {
                t.y.clamp(lo.y, hi.y)
            },
        );
        (texel, gx, gy)
    }
}

/// Wrap codes of [`TamEntry::wrap`] (per axis; `wrap = s | t << 2`), as in the paging file.
pub const WRAP_REPEAT: u32 = 0;
pub const WRAP_MIRROR: u32 = 1;
pub const WRAP_CLAMP: u32 = 2;

/// One entry of TAB's texture-array mapping (TAM): where an original texture lives and how it is sampled.
/// WGSL twin: `TamEntry` in `shaders/tree.wgsl`.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct TamEntry {
    /// Class array binding (`class0..class9` in the shader). Paged: `log2(class_size) − 2` (class 4 → 0 …
    /// class 2048 → 9); all resident, a class past the layer limit continues in unused bindings
    /// (`resident::class_slots`), so the binding's size is `class_size`, not derived from the index.
    pub class: u32,
    /// Layer in the class array.
    pub layer: u32,
    /// `wrap_s | wrap_t << 2` ([`WRAP_REPEAT`], [`WRAP_MIRROR`], [`WRAP_CLAMP`]).
    pub wrap: u32,
    /// 0 opaque, 1 mask, 2 blend (the paging file's codes).
    pub alpha_mode: u32,
    /// Linear RGBA multiplier (the atlas has it baked in; originals are stored without it).
    pub factor: [f32; 4],
    /// MASK cutoff.
    pub cutoff: f32,
    /// Side of the class, texels.
    pub class_size: f32,
    pub _pad: [u32; 2],
}
const _: () = assert!(size_of::<TamEntry>() == 48);

/// The pipeline a record is drawn with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Pass {
    /// Opaque tree: depth write, no blending.
    Opaque = 0,
    /// Alpha tree, subtree without BLEND materials: discard below the cutoff, depth write.
    Mask = 1,
    /// Alpha tree, subtree with a BLEND material: blending, no depth write, after the others.
    Blend = 2,
}

impl Pass {
    pub const ALL: [Pass; 3] = [Pass::Opaque, Pass::Mask, Pass::Blend];
}

/// A pipeline of the tree renderer: pass × texture source. Atlas and original-texture records are drawn
/// by separate pipelines (each one `multi_draw_indexed_indirect`): a software rasteriser such as lavapipe
/// executes every texture fetch of a shader under an execution mask, so a fragment shader that can sample
/// both the atlas arrays and every class array pays for all of them on every pixel.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct Group {
    pub pass: Pass,
    /// Original textures (else atlases).
    pub original: bool,
}

/// Number of [`Group`]s.
pub const GROUPS: usize = 6;

impl Group {
    /// All groups in draw order: opaque atlas, opaque originals, mask atlas, mask originals, blend …
    pub const ALL: [Group; GROUPS] = [
        Group::new(Pass::Opaque, false),
        Group::new(Pass::Opaque, true),
        Group::new(Pass::Mask, false),
        Group::new(Pass::Mask, true),
        Group::new(Pass::Blend, false),
        Group::new(Pass::Blend, true),
    ];

    pub const fn new(pass: Pass, original: bool) -> Group {
        Group { pass, original }
    }

    /// Position in [`Group::ALL`].
    pub fn index(self) -> usize {
        self.pass as usize * 2 + usize::from(self.original)
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
    /// Per node: the alpha cutoff of its atlas draws in the mask pass.
    pub cutoffs: Vec<f32>,
    /// Per node: where its atlas is resident (`None`: not resident; such nodes are drawn with originals if
    /// they are leaves and skipped otherwise — with all blocks resident this does not happen).
    pub atlas_slots: Vec<Option<AtlasSlot>>,
    /// Per node: original-texture blocks of the leaf not yet resident (0 = its originals can be drawn;
    /// always 0 when everything is resident, and for inner nodes).
    pub originals_missing: Vec<u32>,
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
    pub records: Vec<NodeRecordGpu>,
    /// Per [`Group`] (by [`Group::index`]): `(first, count)` of `indirect` drawn by that group's multi-draw
    /// call.
    pub group_ranges: [(u32, u32); GROUPS],
    /// Triangles drawn.
    pub triangles: u64,
    /// Records drawn with original textures.
    pub original_records: u32,
    pending: [Vec<(DrawIndexedIndirect, NodeRecordGpu)>; GROUPS],
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
    /// whose node is out of range, or whose atlas holds no GPU layer, are skipped; returns how many were
    /// (the renderer reports them as `FrameStats::skipped_draws`).
    pub fn add_cut(
        &mut self,
        info: &TreeBatchInfo,
        nodes: &[NodeRecord],
        cut: &Cut,
        resolved: Option<&[Resolved]>,
        opts: BatchOptions,
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
            let atlas = match (draw_with, opts.dummy) {
                (_, true) => Some((AtlasSlot { array: 0, layer: 0 }, node.level)),
                (Some(a), false) => {
                    let slot = info.atlas_slots.get(a.idx()).copied().flatten();
                    match (slot, nodes.get(a.idx())) {
                        (Some(s), Some(an)) => Some((s, an.level)),
                        _ => {
                            skipped += 1;
                            continue;
                        }
                    }
                }
                (None, false) => None,
            };
            let record = NodeRecordGpu {
                atlas_layer: atlas.map_or(NONE, |(s, _)| s.layer),
                atlas_array: atlas.map_or(0, |(s, _)| s.array),
                level: atlas.map_or(node.level, |(_, l)| l),
                leaf_base: info.leaf_base,
                alpha_cutoff: info.cutoffs.get(n).copied().unwrap_or(0.5),
                node: item.node.0,
                tree: info.tree,
                _pad: 0,
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
            if pass == Pass::Blend {
                // Depth pre-pass of the node's opaque texels (MASK materials above their cutoff, BLEND
                // ones at full alpha) in the mask pipeline: a node mixing MASK and BLEND materials (one
                // scaled leaf may hold a whole track's vegetation) keeps MASK occlusion right; the blend
                // pass then adds only what the pre-pass left (equal depth fails the Greater test).
                self.pending[Group::new(Pass::Mask, atlas.is_none()).index()].push((draw, record));
            }
            self.pending[Group::new(pass, atlas.is_none()).index()].push((draw, record));
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
/// (DESIGN.md "Precision"). WGSL: `array<vec4<f32>>` indexed by `leaf_base + vertex.leaf`.
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
