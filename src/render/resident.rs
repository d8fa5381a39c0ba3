//! Everything of a paging file on the GPU, all blocks resident (paging is a later stage): geometry of all
//! trees in shared buffers, all atlases as layers of the atlas array(s), every distinct original texture as a
//! layer of its class array, the static leaf table and the texture-array mapping (TAM).
//!
//! Original textures are deduplicated by `(material, class size)`: the paging file stores a copy per leaf
//! (for paging locality), but the copies are byte-identical (same image, wrap and class size), so one layer
//! serves every leaf.

use super::RenderError;
use super::batch::{AtlasSlot, LeafOffsets, Pass, TreeBatchInfo, leaf_ranges};
use super::textures::{
    CLASS_COUNT, MAX_ATLAS_ARRAYS, TextureArray, class_index, common_format, gpu_format,
    texels_for_upload,
};
use super::wgsl::tree::{
    ALPHA_OPAQUE, LeafInfo, RectMap, TamEntry, WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT, WRAP_T_SHIFT,
};
use crate::gpu::GpuContext;
use crate::ids::{BlockId, NONE, NodeId};
use crate::model::TreeVertex;
use crate::paging::{BlockTable, Event};
use crate::scene::{AlphaMode, Wrap};
use crate::store::format::{MaterialRecord, OriginalRecord};
use crate::store::{TreeFile, TreeView};
use crate::texfmt::TexFormat;
use glam::DVec3;
use std::collections::HashMap;
use wgpu::util::DeviceExt;

/// One distinct original texture: where its pixels are in the file and where they live on the GPU.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct UniqueOriginal {
    pub material: u32,
    pub class_size: u32,
    pub class: u32,
    pub layer: u32,
    /// Block and byte offset of its mip chain inside the block.
    pub block: BlockId,
    pub offset: u64,
    /// Storage format of the block (its tree's format).
    pub format: TexFormat,
}

/// Numbers of a load.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadStats {
    pub trees: u32,
    pub nodes: u64,
    pub leaves: u64,
    pub vertices: u64,
    pub indices: u64,
    pub atlas_layers: u32,
    pub atlas_arrays: u32,
    pub original_layers: u32,
    pub class_arrays: u32,
    pub texture_bytes: u64,
    /// Compressed mip chains decoded to RGBA8 on the CPU at upload (adapter without
    /// `TEXTURE_COMPRESSION_BC`, or a class array shared by trees of formats that do not mix).
    pub decoded_on_load: u64,
    /// BC1 chains widened to BC3 at upload (a class array shared with a BC3 tree).
    pub widened_on_load: u64,
}

/// The GPU-resident file.
pub struct Resident {
    pub infos: Vec<TreeBatchInfo>,
    pub vertex_buffer: wgpu::Buffer,
    pub index_buffer: wgpu::Buffer,
    pub leaves_buffer: wgpu::Buffer,
    pub offsets_buffer: wgpu::Buffer,
    pub tam_buffer: wgpu::Buffer,
    /// Every leaf's rects ([`RectMap`]), global numbering (`LeafInfo::first_rect`).
    pub rects_buffer: wgpu::Buffer,
    pub leaf_offsets: LeafOffsets,
    pub atlas_arrays: Vec<TextureArray>,
    /// One per class (`None`: no original of that class).
    pub class_arrays: Vec<Option<TextureArray>>,
    /// A 1×1, 1-layer array: bound where no array exists, and the only texture in dummy mode.
    pub dummy: TextureArray,
    pub tam: Vec<TamEntry>,
    /// All trees' leaves (global numbering).
    pub leaves: Vec<LeafInfo>,
    pub uniques: Vec<UniqueOriginal>,
    /// Per TAM entry, its index in `uniques`.
    pub tam_unique: Vec<u32>,
    pub materials: Vec<MaterialRecord>,
    pub has_alpha: bool,
    pub stats: LoadStats,
    /// Bookkeeping of on-demand residency (`None`: everything was uploaded at load).
    pub paged: Option<PagedResidency>,
}

/// What [`Resident::apply`] needs to page blocks in and out of the texture arrays.
#[derive(Debug, Default)]
pub struct PagedResidency {
    /// Stored format of each tree's blocks, the atlas side, and whether the GPU samples BC formats
    /// (else compressed blocks are decoded on upload).
    pub tree_formats: Vec<TexFormat>,
    pub atlas_size: u32,
    pub bc: bool,
    /// Compressed chains decoded (or widened) on upload so far.
    pub converted_on_load: u64,
    /// Per unique original texture: resident blocks holding a copy (a layer is held while > 0).
    pub unique_refs: Vec<u32>,
    /// Per block: `(unique, offset)` of the original textures it holds (empty for atlases).
    pub block_uniques: Vec<Vec<(u32, u64)>>,
    /// Per unique: the TAM entries that name it.
    pub tam_users: Vec<Vec<u32>>,
    /// Per block: `(tree, node)` of an atlas block, or of the leaf node of an originals block.
    pub block_node: Vec<(u32, u32)>,
    /// Atlas layers in use, original-texture layers in use (residency statistics).
    pub atlas_layers_used: u32,
    pub original_layers_used: u32,
}

fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => WRAP_REPEAT,
        Wrap::MirroredRepeat => WRAP_MIRROR,
        Wrap::ClampToEdge => WRAP_CLAMP,
    }
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

/// The atlas arrays of a plan: per GPU format of the trees' atlases (BC formats only where the device samples
/// them), room for `min(cap, atlases of that format)` layers, split at the device's layer limit; at most
/// [`MAX_ATLAS_ARRAYS`] arrays.
fn atlas_arrays_for(
    ctx: &GpuContext,
    g: &Plan,
    atlas_size: u32,
    cap: u32,
) -> Result<Vec<TextureArray>, RenderError> {
    let max_layers = ctx.features.max_texture_array_layers.max(1);
    let bc = ctx.features.texture_compression_bc;
    let tree_gpu: Vec<TexFormat> = g.formats.iter().map(|&f| gpu_format(f, bc)).collect();
    let mut per_format: Vec<(TexFormat, u32)> = Vec::new();
    for &(tree, _, _) in &g.atlas_blocks {
        let f = tree_gpu.get(tree as usize).copied().unwrap_or_default();
        match per_format.iter_mut().find(|(pf, _)| *pf == f) {
            Some((_, n)) => *n += 1,
            None => per_format.push((f, 1)),
        }
    }
    if per_format.is_empty() {
        per_format.push((TexFormat::Rgba8, 0));
    }
    let layers: u32 = per_format.iter().map(|&(_, n)| n.min(cap)).sum();
    let arrays_needed: usize = per_format
        .iter()
        .map(|&(_, n)| n.min(cap).div_ceil(max_layers).max(1) as usize)
        .sum();
    if arrays_needed > MAX_ATLAS_ARRAYS {
        return Err(RenderError::TooManyLayers {
            what: "atlases".into(),
            layers: u64::from(layers),
            limit: u64::from(max_layers) * MAX_ATLAS_ARRAYS as u64,
        });
    }
    let mut arrays = Vec::with_capacity(arrays_needed);
    for &(format, count) in &per_format {
        let mut remaining = count.min(cap).max(1);
        while remaining > 0 {
            let n = remaining.min(max_layers);
            remaining -= n;
            let label = format!("atlas array {} ({})", arrays.len(), format.name());
            arrays.push(TextureArray::new(
                &ctx.device,
                &label,
                atlas_size,
                n,
                format,
            ));
        }
    }
    Ok(arrays)
}

/// Byte offset of each original of a leaf inside its block: images of one block are back to back in slot
/// order, each a full mip chain of its class size in the tree's `format`.
fn slot_offsets(originals: &[OriginalRecord], format: TexFormat) -> HashMap<(u32, u32), u64> {
    // Every (block, slot) once (a shared original is listed by every leaf that references it), in slot
    // order per block: the chains lie back to back.
    let mut slots: Vec<(u32, u32, u32)> = originals
        .iter()
        .map(|o| (o.block, o.slot, o.class_size))
        .collect();
    slots.sort_unstable();
    slots.dedup_by_key(|x| (x.0, x.1));
    let mut out = HashMap::with_capacity(slots.len());
    let (mut block, mut off) = (u32::MAX, 0u64);
    for (b, slot, class_size) in slots {
        if b != block {
            (block, off) = (b, 0);
        }
        out.insert((b, slot), off);
        off += format.chain_bytes(class_size);
    }
    out
}

fn buffer(
    ctx: &GpuContext,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    // wgpu rejects zero-sized bindings and ones smaller than one array element: keep at least 256 bytes.
    let mut owned;
    let contents = if contents.len() < 256 {
        owned = contents.to_vec();
        owned.resize(256, 0);
        &owned[..]
    } else {
        contents
    };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
}

/// Geometry, leaves and the original-texture mapping of all trees, gathered on the CPU ([`plan`]): what
/// [`Resident::load`] uploads. Atlas slots are still `None` and TAM layers 0 (assigned at upload).
#[derive(Default)]
pub struct Plan {
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
    /// `(tree, node, block)` of every atlas, in upload order.
    pub atlas_blocks: Vec<(u32, u32, BlockId)>,
    /// `(block, unique, offset in the block)` of every original texture copy (one per leaf that uses it).
    pub block_uniques: Vec<(BlockId, u32, u64)>,
    /// Storage format of each tree's blocks.
    pub formats: Vec<TexFormat>,
    pub has_alpha: bool,
}

impl Resident {
    /// Loads every tree of `file` and uploads all its blocks. `max_layers` is the device's array-layer limit.
    pub fn load(ctx: &GpuContext, file: &TreeFile) -> Result<Resident, RenderError> {
        let params = file.to_params();
        let materials = file.materials().to_vec();
        let max_layers = ctx.features.max_texture_array_layers.max(1);
        let mut g = plan(file)?;

        // Atlas arrays: one format each (trees of different formats get different arrays), layers assigned
        // in node order, split at the device limit.
        let bc = ctx.features.texture_compression_bc;
        let atlas_count = g.atlas_blocks.len() as u32;
        let mut infos = std::mem::take(&mut g.infos);
        let mut atlas_arrays = atlas_arrays_for(ctx, &g, params.atlas_size, u32::MAX)?;
        let mut texture_bytes = 0u64;
        let mut decoded_on_load = 0u64;
        let mut widened_on_load = 0u64;
        for &(tree, node, block) in &g.atlas_blocks {
            let stored = g.formats.get(tree as usize).copied().unwrap_or_default();
            let target = gpu_format(stored, bc);
            let array = atlas_arrays
                .iter_mut()
                .enumerate()
                .find(|(_, a)| a.format == target && a.layers.in_use() < a.layers.capacity());
            let Some((ai, arr)) = array else {
                return Err(RenderError::TooManyLayers {
                    what: "atlases".into(),
                    layers: u64::from(atlas_count),
                    limit: u64::from(max_layers) * MAX_ATLAS_ARRAYS as u64,
                });
            };
            // `array` has a free layer (checked above).
            let layer = arr.layers.alloc().ok_or(RenderError::TooManyLayers {
                what: "atlases".into(),
                layers: u64::from(atlas_count),
                limit: u64::from(arr.layers.capacity()),
            })?;
            let bytes = file.block(block)?;
            let texels = texels_for_upload(stored, bytes, params.atlas_size, target)
                .ok_or(RenderError::ShortBlock { block })?;
            decoded_on_load += u64::from(stored != target);
            texture_bytes += arr
                .upload_chain(&ctx.queue, layer, &texels)
                .ok_or(RenderError::ShortBlock { block })?;
            if let Some(slot) = infos
                .get_mut(tree as usize)
                .and_then(|i| i.atlas_slots.get_mut(node as usize))
            {
                *slot = Some(AtlasSlot {
                    array: ai as u32,
                    layer,
                });
            }
        }

        // Class arrays: the common format of their originals ([`common_format`]), split into slots of at
        // most `max_layers` layers ([`class_slots`]); each unique's `class` becomes its slot (binding).
        let mut per_class = [0u32; CLASS_COUNT];
        let mut class_formats: [Vec<TexFormat>; CLASS_COUNT] = Default::default();
        for u in &g.uniques {
            per_class[u.class as usize] += 1;
            class_formats[u.class as usize].push(gpu_format(u.format, bc));
        }
        let slots = class_slots(&per_class, max_layers)?;
        let mut class_arrays: Vec<Option<TextureArray>> = slots
            .iter()
            .map(|s| {
                s.map(|(k, layers)| {
                    let format = common_format(class_formats[k as usize].iter().copied());
                    let label = format!("class {} ({})", 4u32 << k, format.name());
                    TextureArray::new(&ctx.device, &label, 4 << k, layers, format)
                })
            })
            .collect();
        let mut uniques = std::mem::take(&mut g.uniques);
        let mut block_cache: Option<(BlockId, &[u8])> = None;
        for u in &mut uniques {
            // The first slot of this class with a free layer.
            let Some((slot, arr)) = class_arrays
                .iter_mut()
                .enumerate()
                .filter(|(i, _)| slots[*i].is_some_and(|(k, _)| k == u.class))
                .find_map(|(i, a)| {
                    a.as_mut()
                        .filter(|a| a.layers.in_use() < a.layers.capacity())
                        .map(|a| (i, a))
                })
            else {
                // `class_slots` sized the slots for every unique: running out is a bug.
                return Err(RenderError::Residency {
                    what: "no class slot with a free layer for an original",
                    unique: 0,
                    class: u.class,
                    layer: 0,
                });
            };
            u.class = slot as u32;
            u.layer = arr.layers.alloc().ok_or(RenderError::Residency {
                what: "class slot reported a free layer but allocation failed",
                unique: 0,
                class: u.class,
                layer: 0,
            })?;
            let bytes = match block_cache {
                Some((b, bytes)) if b == u.block => bytes,
                _ => {
                    let bytes = file.block(u.block)?;
                    block_cache = Some((u.block, bytes));
                    bytes
                }
            };
            let chain = usize::try_from(u.offset)
                .ok()
                .and_then(|o| bytes.get(o..))
                .ok_or(RenderError::ShortBlock { block: u.block })?;
            let texels = texels_for_upload(u.format, chain, u.class_size, arr.format)
                .ok_or(RenderError::ShortBlock { block: u.block })?;
            decoded_on_load += u64::from(u.format != arr.format && arr.format == TexFormat::Rgba8);
            widened_on_load += u64::from(u.format != arr.format && arr.format == TexFormat::Bc3);
            texture_bytes += arr
                .upload_chain(&ctx.queue, u.layer, &texels)
                .ok_or(RenderError::ShortBlock { block: u.block })?;
        }
        let mut tam = std::mem::take(&mut g.tam);
        for (e, &ui) in tam.iter_mut().zip(&g.tam_unique) {
            if let Some(u) = uniques.get(ui as usize) {
                e.layer = u.layer;
                e.class_index = u.class;
            }
        }

        if decoded_on_load > 0 {
            tracing::warn!(
                "{decoded_on_load} compressed mip chains decoded to RGBA8 on load (adapter BC support: {bc})"
            );
        }
        let stats = LoadStats {
            trees: infos.len() as u32,
            nodes: infos.iter().map(|i| i.passes.len() as u64).sum(),
            leaves: g.leaves.len() as u64,
            vertices: g.vertices.len() as u64,
            indices: g.indices.len() as u64,
            atlas_layers: atlas_count,
            atlas_arrays: atlas_arrays.len() as u32,
            original_layers: uniques.len() as u32,
            class_arrays: class_arrays.iter().filter(|a| a.is_some()).count() as u32,
            texture_bytes,
            decoded_on_load,
            widened_on_load,
        };
        let leaf_offsets = LeafOffsets::new(std::mem::take(&mut g.origins));
        Ok(Self::assemble(
            ctx,
            g,
            infos,
            atlas_arrays,
            class_arrays,
            uniques,
            tam,
            materials,
            stats,
            leaf_offsets,
            None,
        ))
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(
        ctx: &GpuContext,
        g: Plan,
        infos: Vec<TreeBatchInfo>,
        atlas_arrays: Vec<TextureArray>,
        class_arrays: Vec<Option<TextureArray>>,
        uniques: Vec<UniqueOriginal>,
        tam: Vec<TamEntry>,
        materials: Vec<MaterialRecord>,
        stats: LoadStats,
        leaf_offsets: LeafOffsets,
        paged: Option<PagedResidency>,
    ) -> Resident {
        let storage = wgpu::BufferUsages::STORAGE;
        let dummy = TextureArray::new(&ctx.device, "dummy 1x1", 1, 1, TexFormat::Rgba8);
        dummy.upload_chain(&ctx.queue, 0, &[200, 200, 200, 255]);
        Resident {
            vertex_buffer: buffer(
                ctx,
                "tree vertices",
                bytemuck::cast_slice(&g.vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            index_buffer: buffer(
                ctx,
                "tree indices",
                bytemuck::cast_slice(&g.indices),
                wgpu::BufferUsages::INDEX,
            ),
            leaves_buffer: buffer(ctx, "leaves", bytemuck::cast_slice(&g.leaves), storage),
            offsets_buffer: buffer(
                ctx,
                "leaf offsets",
                bytemuck::cast_slice(&leaf_offsets.offsets),
                storage | wgpu::BufferUsages::COPY_DST,
            ),
            tam_buffer: buffer(
                ctx,
                "tam",
                bytemuck::cast_slice(&tam),
                storage | wgpu::BufferUsages::COPY_DST,
            ),
            rects_buffer: buffer(ctx, "rects", bytemuck::cast_slice(&g.rects), storage),
            leaf_offsets,
            infos,
            atlas_arrays,
            class_arrays,
            dummy,
            tam,
            leaves: g.leaves,
            uniques,
            tam_unique: g.tam_unique,
            materials,
            has_alpha: g.has_alpha,
            stats,
            paged,
        }
    }

    /// Uploads the leaf offsets (after [`LeafOffsets::update`]).
    pub fn write_offsets(&self, queue: &wgpu::Queue) {
        if !self.leaf_offsets.offsets.is_empty() {
            queue.write_buffer(
                &self.offsets_buffer,
                0,
                bytemuck::cast_slice(&self.leaf_offsets.offsets),
            );
        }
    }
}

/// Reads all trees' tables into the shared CPU arrays; checks what the shader will index.
pub fn plan(file: &TreeFile) -> Result<Plan, RenderError> {
    let materials = file.materials();
    let mut g = Plan::default();
    let mut unique_of: HashMap<(u32, u32), u32> = HashMap::new();
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
            let node = view.nodes.get(leaf.node as usize);
            let originals = view.leaf_originals(leaf);
            let first_tam = count_u32("tam", g.tam.len())?;
            let first_rect = count_u32("rects", g.rects.len())?;
            g.leaves.push(LeafInfo {
                cell: node.map_or([0, 0], |n| [n.cell.ix, n.cell.iy]),
                level: node.map_or(0, |n| n.level),
                first_tam,
                first_rect,
                _p0: 0,
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
                let class = class_index(o.class_size).ok_or(RenderError::BadClass {
                    tree: t,
                    leaf: li as u32,
                    class_size: o.class_size,
                })?;
                let next = g.uniques.len() as u32;
                let ui = *unique_of.entry((o.material, o.class_size)).or_insert(next);
                if ui == next {
                    g.uniques.push(UniqueOriginal {
                        material: o.material,
                        class_size: o.class_size,
                        class,
                        layer: 0,
                        block: BlockId(o.block),
                        offset,
                        format: view.format(),
                    });
                }
                g.tam_unique.push(ui);
                g.block_uniques.push((BlockId(o.block), ui, offset));
                let wrap = m.and_then(|m| m.wraps()).unwrap_or([Wrap::Repeat; 2]);
                g.tam.push(TamEntry {
                    class_index: class,
                    layer: 0,
                    wrap: wrap_code(wrap[0]) | wrap_code(wrap[1]) << WRAP_T_SHIFT,
                    alpha_mode: m.map_or(ALPHA_OPAQUE, |m| m.alpha_mode),
                    factor: m.map_or([1.0; 4], |m| m.base_color_factor),
                    cutoff: m.map_or(0.5, |m| m.alpha_cutoff),
                    class_size: o.class_size as f32,
                    _p0: 0,
                    _p1: 0,
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
        g.infos.push(TreeBatchInfo {
            tree: t as u32,
            leaf_base,
            index_base,
            vertex_base,
            leaf_ranges: ranges,
            passes,
            cutoffs,
            atlas_slots: vec![None; view.nodes.len()],
            originals_missing: vec![0; view.nodes.len()],
        });
        g.vertices.extend_from_slice(view.vertices);
        g.indices.extend_from_slice(view.indices);
    }
    Ok(g)
}

impl Resident {
    /// Tables and geometry of `file` on the GPU, texture arrays sized for at most `capacity` resident
    /// blocks, and **no** texture uploaded: blocks arrive through [`Resident::apply`] as the pager makes
    /// them resident (paper §6). Atlas layers: `min(capacity, atlases)`; original-texture layers per class:
    /// the most that `capacity` blocks can hold (the sum of the `capacity` largest per-block counts), so the
    /// GPU memory is bounded by the capacity, not by the file.
    pub fn load_paged(
        ctx: &GpuContext,
        file: &TreeFile,
        table: &BlockTable,
        capacity: u32,
    ) -> Result<Resident, RenderError> {
        let materials = file.materials().to_vec();
        let params = file.to_params();
        let max_layers = ctx.features.max_texture_array_layers.max(1);
        let mut g = plan(file)?;
        let mut infos = std::mem::take(&mut g.infos);
        for (t, info) in infos.iter_mut().enumerate() {
            for (n, missing) in info.originals_missing.iter_mut().enumerate() {
                *missing = table.originals(t, NodeId(n as u32)).len() as u32;
            }
        }
        // Atlas arrays: per GPU format, each with room for min(capacity, atlases of that format) layers.
        let bc = ctx.features.texture_compression_bc;
        let atlas_arrays = atlas_arrays_for(ctx, &g, params.atlas_size, capacity)?;
        let atlas_layers: u32 = atlas_arrays.iter().map(|a| a.layers.capacity()).sum();
        // Original-texture classes: per block the uniques it holds.
        let mut block_uniques: Vec<Vec<(u32, u64)>> = vec![Vec::new(); table.len()];
        for &(b, ui, offset) in &g.block_uniques {
            if let Some(v) = block_uniques.get_mut(b.idx())
                && !v.iter().any(|&(u, _)| u == ui)
            {
                v.push((ui, offset));
            }
        }
        let mut class_arrays: Vec<Option<TextureArray>> = Vec::with_capacity(CLASS_COUNT);
        for k in 0..CLASS_COUNT {
            let total = g.uniques.iter().filter(|u| u.class as usize == k).count() as u32;
            let mut per_block: Vec<u32> = block_uniques
                .iter()
                .map(|v| {
                    v.iter()
                        .filter(|&&(u, _)| g.uniques[u as usize].class as usize == k)
                        .count() as u32
                })
                .filter(|&c| c > 0)
                .collect();
            per_block.sort_unstable_by(|a, b| b.cmp(a));
            let bound: u32 = per_block.iter().take(capacity as usize).sum();
            let layers = total.min(bound);
            if layers > max_layers {
                return Err(RenderError::TooManyLayers {
                    what: format!("original textures of class {}", 4u32 << k),
                    layers: u64::from(layers),
                    limit: u64::from(max_layers),
                });
            }
            let format = common_format(
                g.uniques
                    .iter()
                    .filter(|u| u.class as usize == k)
                    .map(|u| gpu_format(u.format, bc)),
            );
            class_arrays.push((layers > 0).then(|| {
                let label = format!("class {} ({})", 4u32 << k, format.name());
                TextureArray::new(&ctx.device, &label, 4 << k, layers, format)
            }));
        }
        let mut tam_users: Vec<Vec<u32>> = vec![Vec::new(); g.uniques.len()];
        for (e, &ui) in g.tam_unique.iter().enumerate() {
            if let Some(v) = tam_users.get_mut(ui as usize) {
                v.push(e as u32);
            }
        }
        let block_node = table
            .blocks
            .iter()
            .map(|m| (m.tree, m.item.node().0))
            .collect();
        let uniques = std::mem::take(&mut g.uniques);
        let tam = std::mem::take(&mut g.tam);
        let stats = LoadStats {
            trees: infos.len() as u32,
            nodes: infos.iter().map(|i| i.passes.len() as u64).sum(),
            leaves: g.leaves.len() as u64,
            vertices: g.vertices.len() as u64,
            indices: g.indices.len() as u64,
            atlas_layers,
            atlas_arrays: atlas_arrays.len() as u32,
            original_layers: class_arrays
                .iter()
                .flatten()
                .map(|a| a.layers.capacity())
                .sum(),
            class_arrays: class_arrays.iter().filter(|a| a.is_some()).count() as u32,
            texture_bytes: 0,
            decoded_on_load: 0,
            widened_on_load: 0,
        };
        let paged = PagedResidency {
            tree_formats: g.formats.clone(),
            atlas_size: params.atlas_size,
            bc,
            converted_on_load: 0,
            unique_refs: vec![0; uniques.len()],
            block_uniques,
            tam_users,
            block_node,
            atlas_layers_used: 0,
            original_layers_used: 0,
        };
        let leaf_offsets = LeafOffsets::new(std::mem::take(&mut g.origins));
        Ok(Self::assemble(
            ctx,
            g,
            infos,
            atlas_arrays,
            class_arrays,
            uniques,
            tam,
            materials,
            stats,
            leaf_offsets,
            Some(paged),
        ))
    }

    /// Applies one residency change of the pager: uploads a loaded block's texture(s) into free layers, or
    /// frees an evicted block's layers. Returns the bytes uploaded. Without paging this does nothing.
    pub fn apply(
        &mut self,
        queue: &wgpu::Queue,
        table: &BlockTable,
        event: &Event,
    ) -> Result<u64, RenderError> {
        let Some(p) = self.paged.as_mut() else {
            return Ok(0);
        };
        let (block, data) = match event {
            Event::Loaded { block, data } => (*block, Some(data.as_deref())),
            Event::Evicted { block } => (*block, None),
        };
        let (tree, node) = p
            .block_node
            .get(block.idx())
            .copied()
            .ok_or(RenderError::ShortBlock { block })?;
        let info = self
            .infos
            .get_mut(tree as usize)
            .ok_or(RenderError::MissingTree {
                tree: tree as usize,
            })?;
        let is_atlas = table.meta(block).item.is_atlas();
        match (is_atlas, data) {
            (true, Some(bytes)) => {
                let bytes = bytes.ok_or(RenderError::ShortBlock { block })?;
                let stored = p
                    .tree_formats
                    .get(tree as usize)
                    .copied()
                    .unwrap_or_default();
                let target = gpu_format(stored, p.bc);
                let texels = texels_for_upload(stored, bytes, p.atlas_size, target)
                    .ok_or(RenderError::ShortBlock { block })?;
                p.converted_on_load += u64::from(stored != target);
                let (ai, arr) = self
                    .atlas_arrays
                    .iter_mut()
                    .enumerate()
                    .find(|(_, a)| a.format == target && a.layers.in_use() < a.layers.capacity())
                    .ok_or(RenderError::TooManyLayers {
                        what: "resident atlases".into(),
                        layers: u64::from(p.atlas_layers_used) + 1,
                        limit: u64::from(p.atlas_layers_used),
                    })?;
                let layer = arr
                    .layers
                    .alloc()
                    .ok_or(RenderError::ShortBlock { block })?;
                let Some(n) = arr.upload_chain(queue, layer, &texels) else {
                    arr.layers.free(layer);
                    return Err(RenderError::ShortBlock { block });
                };
                if let Some(slot) = info.atlas_slots.get_mut(node as usize) {
                    *slot = Some(AtlasSlot {
                        array: ai as u32,
                        layer,
                    });
                }
                p.atlas_layers_used += 1;
                Ok(n)
            }
            (true, None) => {
                if let Some(s) = info
                    .atlas_slots
                    .get_mut(node as usize)
                    .and_then(Option::take)
                {
                    let freed = self
                        .atlas_arrays
                        .get_mut(s.array as usize)
                        .is_some_and(|a| a.layers.free(s.layer));
                    if !freed {
                        return Err(RenderError::Residency {
                            what: "evicting an atlas whose layer is not allocated",
                            unique: node,
                            class: s.array,
                            layer: s.layer,
                        });
                    }
                    p.atlas_layers_used -= 1;
                }
                Ok(0)
            }
            (false, Some(bytes)) => {
                let bytes = bytes.ok_or(RenderError::ShortBlock { block })?;
                let mut uploaded = 0;
                let held = p
                    .block_uniques
                    .get(block.idx())
                    .cloned()
                    .unwrap_or_default();
                // Check every chain first, so a short block changes no reference count.
                for &(ui, offset) in &held {
                    let u = &self.uniques[ui as usize];
                    let need = u.format.chain_bytes(u.class_size);
                    if offset.saturating_add(need) > bytes.len() as u64 {
                        return Err(RenderError::ShortBlock { block });
                    }
                }
                for (ui, offset) in held {
                    let u = ui as usize;
                    if p.unique_refs[u] > 0 {
                        p.unique_refs[u] += 1;
                        continue;
                    }
                    let class = self.uniques[u].class as usize;
                    let Some(arr) = self.class_arrays.get_mut(class).and_then(|a| a.as_mut())
                    else {
                        return Err(RenderError::Residency {
                            what: "an original's class array does not exist",
                            unique: ui,
                            class: class as u32,
                            layer: 0,
                        });
                    };
                    let layer = arr.layers.alloc().ok_or(RenderError::TooManyLayers {
                        what: format!("resident original textures of class {}", 4u32 << class),
                        layers: u64::from(arr.layers.capacity()) + 1,
                        limit: u64::from(arr.layers.capacity()),
                    })?;
                    // From here a failure hands the layer back: the reference count only counts
                    // uniques that hold a layer.
                    let (stored, size) = (self.uniques[u].format, self.uniques[u].class_size);
                    let target = arr.format;
                    let texels = usize::try_from(offset)
                        .ok()
                        .and_then(|o| bytes.get(o..))
                        .and_then(|chain| texels_for_upload(stored, chain, size, target));
                    let Some(n) = texels.and_then(|t| arr.upload_chain(queue, layer, &t)) else {
                        arr.layers.free(layer);
                        return Err(RenderError::ShortBlock { block });
                    };
                    p.unique_refs[u] = 1;
                    p.converted_on_load += u64::from(stored != target);
                    uploaded += n;
                    self.uniques[u].layer = layer;
                    p.original_layers_used += 1;
                    for &e in &p.tam_users[u] {
                        if let Some(entry) = self.tam.get_mut(e as usize) {
                            entry.layer = layer;
                            queue.write_buffer(
                                &self.tam_buffer,
                                u64::from(e) * size_of::<TamEntry>() as u64,
                                bytemuck::bytes_of(entry),
                            );
                        }
                    }
                }
                // Every leaf that references the block (shared originals) has one block less missing.
                for n in table.users(block) {
                    if let Some(m) = info.originals_missing.get_mut(n.idx()) {
                        *m = m.saturating_sub(1);
                    }
                }
                Ok(uploaded)
            }
            (false, None) => {
                let held = p
                    .block_uniques
                    .get(block.idx())
                    .cloned()
                    .unwrap_or_default();
                for (ui, _) in held {
                    let u = ui as usize;
                    if p.unique_refs[u] == 0 {
                        continue;
                    }
                    p.unique_refs[u] -= 1;
                    if p.unique_refs[u] == 0 {
                        let class = self.uniques[u].class as usize;
                        let layer = self.uniques[u].layer;
                        let freed = self
                            .class_arrays
                            .get_mut(class)
                            .and_then(|a| a.as_mut())
                            .is_some_and(|arr| arr.layers.free(layer));
                        if !freed {
                            return Err(RenderError::Residency {
                                what: "evicting an original whose layer is not allocated",
                                unique: ui,
                                class: class as u32,
                                layer,
                            });
                        }
                        p.original_layers_used -= 1;
                    }
                }
                for n in table.users(block) {
                    if let Some(m) = info.originals_missing.get_mut(n.idx()) {
                        *m += 1;
                    }
                }
                Ok(0)
            }
        }
    }
}

/// Texture-array slots (bindings `class0..`) for the all-resident load: slot `k` holds class `k`
/// (`4 << k` texels), up to `max_layers` layers; a class with more originals than that continues in the
/// lowest slots no class uses. `per_class[k]`: originals of class k. Each entry: `(class, layers)`.
/// Errors when the free slots run out (more than `CLASS_COUNT × max_layers` originals in all).
pub fn class_slots(
    per_class: &[u32; CLASS_COUNT],
    max_layers: u32,
) -> Result<[Option<(u32, u32)>; CLASS_COUNT], RenderError> {
    let max_layers = max_layers.max(1);
    let mut slots: [Option<(u32, u32)>; CLASS_COUNT] = [None; CLASS_COUNT];
    for (k, &n) in per_class.iter().enumerate() {
        if n > 0 {
            slots[k] = Some((k as u32, n.min(max_layers)));
        }
    }
    for (k, &n) in per_class.iter().enumerate() {
        let mut rest = n.saturating_sub(max_layers);
        while rest > 0 {
            let Some(free) = slots.iter().position(Option::is_none) else {
                return Err(RenderError::TooManyLayers {
                    what: format!(
                        "original textures of class {} (every class binding is in use)",
                        4u32 << k
                    ),
                    layers: u64::from(n),
                    limit: u64::from(max_layers),
                });
            };
            slots[free] = Some((k as u32, rest.min(max_layers)));
            rest = rest.saturating_sub(max_layers);
        }
    }
    Ok(slots)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn class_slots_split_a_full_class_into_unused_bindings() {
        let mut per_class = [0u32; CLASS_COUNT];
        per_class[6] = 4304; // class 256 (4 << 6)
        per_class[2] = 10;
        let s = class_slots(&per_class, 2048).expect("fits");
        assert_eq!(s[6], Some((6, 2048)));
        assert_eq!(s[2], Some((2, 10)));
        // The rest, 2256, in the lowest unused slots: 0 (2048), 1 (208).
        assert_eq!(s[0], Some((6, 2048)));
        assert_eq!(s[1], Some((6, 208)));
        assert_eq!(s.iter().flatten().map(|&(_, n)| n).sum::<u32>(), 4314);
        assert!(s[3..6].iter().all(Option::is_none));
        // Ten full slots at most.
        let mut all = [0u32; CLASS_COUNT];
        all[7] = 10 * 2048;
        assert!(class_slots(&all, 2048).is_ok());
        all[7] += 1;
        let e = class_slots(&all, 2048).expect_err("one layer too many");
        assert!(e.to_string().contains("class 512"), "{e}");
    }
}
