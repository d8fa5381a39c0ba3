//! A paging file on the GPU: geometry of all trees in shared buffers, the static leaf table, rect maps and
//! texture-array mapping (TAM), and texture arrays sized for k resident blocks, into which blocks are
//! uploaded as they become resident and from which they are freed when evicted ([`Resident::apply`]).
//! The all-resident load is the same load with k = every block ([`Resident::load`]).
//!
//! Original textures are deduplicated by their stored slot `(block, slot)`: one layer serves every leaf
//! and material that shows the texture (materials of one image and sampler share a stored original),
//! held while the block that carries it is resident. A non-square texture
//! fills its square class layer tiled ([`crate::texfmt::tile_chain_to_square`]).
//!
//! - `tables`: the CPU gathering of what the shader indexes ([`gather_tables`]);
//! - `arrays`: the texture arrays a capacity needs (atlas arrays per format, [`class_slots`]);
//! - `apply`: uploads and frees of one block ([`Resident::apply`]).

mod apply;
mod arrays;
mod tables;

pub use arrays::class_slots;
pub use tables::{GpuTables, gather_tables};

use super::RenderError;
use super::batch::{LeafOffsets, TreeBatchInfo};
use super::textures::{CLASS_COUNT, TextureArray, common_format, gpu_format};
use super::wgsl::tree::{LeafInfo, TamEntry};
use crate::gpu::GpuContext;
use crate::ids::BlockId;
use crate::paging::BlockTable;
use crate::store::TreeFile;
use crate::store::format::MaterialRecord;
use crate::texfmt::TexFormat;
use arrays::{atlas_arrays_for, device_layers_per_array};

/// One distinct original texture: where its pixels are in the file and where they live on the GPU.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct UniqueOriginal {
    pub class_size: u32,
    /// Stored `[width, height]`, texels (`class_size` is the larger; the layer tiles the texture).
    pub extent: [u32; 2],
    /// Size class: `class_size == 4 << class`.
    pub class: u32,
    /// The class binding (`class0..`) and layer it occupies while resident (0, 0 before its first upload).
    pub slot: u32,
    pub layer: u32,
    /// Block and byte offset of its mip chain inside the block.
    pub block: BlockId,
    pub offset: u64,
    /// Storage format of the block (its tree's format).
    pub format: TexFormat,
}

/// A material drawing a distinct original texture: what the naive baseline binds per draw (its texture,
/// and the material's factor, cutoff and sampler).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialOriginal {
    pub material: u32,
    /// Index in [`Resident::uniques`].
    pub unique: u32,
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
    /// Every leaf's rects (`RectMap`), global numbering (`LeafInfo::first_rect`).
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
    /// Per TAM entry, its index in `material_originals`.
    pub tam_material_original: Vec<u32>,
    pub material_originals: Vec<MaterialOriginal>,
    pub materials: Vec<MaterialRecord>,
    pub has_alpha: bool,
    pub stats: LoadStats,
    /// Bookkeeping of residency: which block holds what, reference counts, layers in use.
    pub residency: Bookkeeping,
}

/// What [`Resident::apply`] needs to page blocks in and out of the texture arrays.
#[derive(Debug)]
pub struct Bookkeeping {
    /// The blocks (kinds, leaves that use each originals block).
    pub table: BlockTable,
    /// Stored format of each tree's blocks, the atlas side, and whether the GPU samples BC formats
    /// (else compressed blocks are decoded on upload).
    pub tree_formats: Vec<TexFormat>,
    pub atlas_size: u32,
    pub bc: bool,
    /// Per class binding: the size class it holds (`None`: unused binding).
    pub slot_class: [Option<u32>; CLASS_COUNT],
    /// Compressed chains decoded to RGBA8, and BC1 chains widened to BC3, on upload so far.
    pub decoded_on_load: u64,
    pub widened_on_load: u64,
    /// Per unique original texture: resident blocks holding a copy (a layer is held while > 0).
    pub unique_refs: Vec<u32>,
    /// Per block: `(unique, offset)` of the original textures it holds (empty for atlases).
    pub block_uniques: Vec<Vec<(u32, u64)>>,
    /// Per unique: the TAM entries that name it.
    pub tam_users: Vec<Vec<u32>>,
    /// Atlas layers in use, original-texture layers in use (residency statistics).
    pub atlas_layers_used: u32,
    pub original_layers_used: u32,
}

/// A buffer holding `contents`, made inside an error scope: a device out of memory is
/// [`GpuError::OutOfMemory`] naming the buffer (a buffer mapped at creation panicked in wgpu when it
/// could not be allocated: fault hunt, session 29), then filled through the queue.
pub(crate) fn buffer(
    ctx: &GpuContext,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> Result<wgpu::Buffer, RenderError> {
    // wgpu rejects zero-sized bindings and ones smaller than one array element: keep at least 256 bytes.
    let mut owned;
    let contents = if contents.len() < 256 {
        owned = contents.to_vec();
        owned.resize(256, 0);
        &owned[..]
    } else {
        contents
    };
    // `write_buffer` takes whole multiples of 4 bytes.
    let mut padded;
    let contents = if contents.len() % 4 == 0 {
        contents
    } else {
        padded = contents.to_vec();
        padded.resize(contents.len().next_multiple_of(4), 0);
        &padded[..]
    };
    // The write stages a copy as large as the buffer: in the same scope, so its failure is an error too.
    ctx.scoped(&format!("allocating the {label} buffer"), |device| {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: contents.len() as u64,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue.write_buffer(&buffer, 0, contents);
        buffer
    })
    .map_err(RenderError::Gpu)
}

impl Resident {
    /// Loads every tree of `file` and uploads all its blocks: the paged load with a capacity of every
    /// block ([`Resident::load_paged`]), each block uploaded through the same path a paged block takes
    /// ([`Resident::upload_block`]), so there is one upload path and one class-split policy.
    pub fn load(ctx: &GpuContext, file: &TreeFile) -> Result<Resident, RenderError> {
        let table = BlockTable::from_file(file)?;
        let all =
            u32::try_from(table.len()).map_err(|_| RenderError::TooLarge { what: "blocks" })?;
        let mut r = Resident::load_paged(ctx, file, &table, all)?;
        // Parents before children is not needed here (nothing is drawn until all are in), block order is.
        // Each `write_texture` stages its bytes until the next submit: flushed every FLUSH_BYTES, the
        // staging memory is that much, not the whole file again (the all-tracks world on lavapipe: peak RSS
        // 19.8 → 13.3 GB for 6.2 GiB of textures).
        const FLUSH_BYTES: u64 = 256 << 20;
        let mut staged = 0;
        for b in 0..all {
            let block = BlockId(b);
            let bytes = file.block(block)?;
            let uploaded = r.upload_block(&ctx.queue, block, &bytes)?;
            r.stats.texture_bytes += uploaded;
            staged += uploaded;
            if staged >= FLUSH_BYTES {
                ctx.queue.submit(std::iter::empty());
                ctx.device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .map_err(|e| RenderError::Gpu(e.into()))?;
                staged = 0;
            }
        }
        let p = &r.residency;
        r.stats.decoded_on_load = p.decoded_on_load;
        r.stats.widened_on_load = p.widened_on_load;
        if p.decoded_on_load > 0 {
            tracing::warn!(
                "{} compressed mip chains decoded to RGBA8 on load (adapter BC support: {})",
                p.decoded_on_load,
                p.bc
            );
        }
        Ok(r)
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(
        ctx: &GpuContext,
        g: GpuTables,
        infos: Vec<TreeBatchInfo>,
        atlas_arrays: Vec<TextureArray>,
        class_arrays: Vec<Option<TextureArray>>,
        uniques: Vec<UniqueOriginal>,
        tam: Vec<TamEntry>,
        materials: Vec<MaterialRecord>,
        stats: LoadStats,
        leaf_offsets: LeafOffsets,
        residency: Bookkeeping,
    ) -> Result<Resident, RenderError> {
        let storage = wgpu::BufferUsages::STORAGE;
        let dummy = TextureArray::new(&ctx.device, "dummy 1x1", 1, 1, TexFormat::Rgba8);
        dummy.upload_chain(&ctx.queue, 0, &[200, 200, 200, 255]);
        Ok(Resident {
            vertex_buffer: buffer(
                ctx,
                "tree vertices",
                bytemuck::cast_slice(&g.vertices),
                wgpu::BufferUsages::VERTEX,
            )?,
            index_buffer: buffer(
                ctx,
                "tree indices",
                bytemuck::cast_slice(&g.indices),
                wgpu::BufferUsages::INDEX,
            )?,
            leaves_buffer: buffer(ctx, "leaves", bytemuck::cast_slice(&g.leaves), storage)?,
            offsets_buffer: buffer(
                ctx,
                "leaf offsets",
                bytemuck::cast_slice(&leaf_offsets.offsets),
                storage | wgpu::BufferUsages::COPY_DST,
            )?,
            tam_buffer: buffer(
                ctx,
                "tam",
                bytemuck::cast_slice(&tam),
                storage | wgpu::BufferUsages::COPY_DST,
            )?,
            rects_buffer: buffer(ctx, "rects", bytemuck::cast_slice(&g.rects), storage)?,
            leaf_offsets,
            infos,
            atlas_arrays,
            class_arrays,
            dummy,
            tam,
            leaves: g.leaves,
            uniques,
            tam_unique: g.tam_unique,
            tam_material_original: g.tam_material_original,
            material_originals: g.material_originals,
            materials,
            has_alpha: g.has_alpha,
            stats,
            residency,
        })
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

impl Resident {
    /// Tables and geometry of `file` on the GPU, texture arrays sized for at most `capacity` resident
    /// blocks, and **no** texture uploaded: blocks arrive through [`Resident::apply`] as the planner makes
    /// them resident (paper §6). Atlas layers: `min(capacity, atlases)`; original-texture layers per class:
    /// the most that `capacity` blocks can hold (the sum of the `capacity` largest per-block counts), so the
    /// GPU memory is bounded by the capacity, not by the file. A class with more layers than the device
    /// allows continues in the class bindings no class uses ([`class_slots`]).
    pub fn load_paged(
        ctx: &GpuContext,
        file: &TreeFile,
        table: &BlockTable,
        capacity: u32,
    ) -> Result<Resident, RenderError> {
        let materials = file.materials().to_vec();
        let params = file.to_params();
        let mut g = gather_tables(file)?;
        let infos = std::mem::take(&mut g.infos);
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
        let mut per_class = [0u32; CLASS_COUNT];
        for (k, layers) in per_class.iter_mut().enumerate() {
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
            *layers = total.min(bound);
        }
        let class_formats: [TexFormat; CLASS_COUNT] = std::array::from_fn(|k| {
            common_format(
                g.uniques
                    .iter()
                    .filter(|u| u.class as usize == k)
                    .map(|u| gpu_format(u.format, bc)),
            )
        });
        let class_layers: [u32; CLASS_COUNT] =
            std::array::from_fn(|k| device_layers_per_array(ctx, class_formats[k], 4 << k));
        let slots = class_slots(&per_class, &class_layers)?;
        let class_arrays: Vec<Option<TextureArray>> = slots
            .iter()
            .map(|s| {
                s.map(|(k, layers)| {
                    let format = class_formats[k as usize];
                    let label = format!("class {} ({})", 4u32 << k, format.name());
                    TextureArray::new(&ctx.device, &label, 4 << k, layers, format)
                })
            })
            .collect();
        let mut tam_users: Vec<Vec<u32>> = vec![Vec::new(); g.uniques.len()];
        for (e, &ui) in g.tam_unique.iter().enumerate() {
            if let Some(v) = tam_users.get_mut(ui as usize) {
                v.push(e as u32);
            }
        }
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
        let residency = Bookkeeping {
            table: table.clone(),
            tree_formats: g.formats.clone(),
            atlas_size: params.atlas_size,
            bc,
            slot_class: slots.map(|s| s.map(|(k, _)| k)),
            decoded_on_load: 0,
            widened_on_load: 0,
            unique_refs: vec![0; uniques.len()],
            block_uniques,
            tam_users,
            atlas_layers_used: 0,
            original_layers_used: 0,
        };
        let leaf_offsets = LeafOffsets::new(std::mem::take(&mut g.origins));
        Self::assemble(
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
            residency,
        )
    }
}
