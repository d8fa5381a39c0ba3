//! Residency changes of one block on the GPU: a loaded block's atlas or original textures uploaded into
//! free layers, an evicted block's layers freed. Broken invariants (a layer that is not allocated, a class
//! without a binding) are errors, never a wrong texture.

use super::Resident;
use crate::ids::BlockId;
use crate::paging::{Event, ResidencyError};
use crate::render::RenderError;
use crate::render::batch::AtlasSlot;
use crate::render::textures::{gpu_format, layer_texels_for_upload, texels_for_upload};
use crate::render::wgsl::tree::TamEntry;
use crate::texfmt::TexFormat;

impl Resident {
    /// Applies one residency change of the planner: uploads a loaded block's texture(s) into free layers,
    /// or frees an evicted block's layers. Returns the bytes uploaded. A loaded event without data (a
    /// simulated source) is an error: the GPU needs the bytes.
    pub fn apply(&mut self, queue: &wgpu::Queue, event: &Event) -> Result<u64, RenderError> {
        match event {
            Event::Loaded { block, data } => {
                let bytes = data
                    .as_deref()
                    .ok_or(RenderError::ShortBlock { block: *block })?;
                self.upload_block(queue, *block, bytes)
            }
            Event::Evicted { block } => self.free_block(*block).map(|()| 0),
        }
    }

    /// `(tree, node)` of `block`'s atlas or leaf, checked against the loaded trees.
    fn owner(&self, block: BlockId) -> Result<(u32, u32), RenderError> {
        let table = &self.residency.table;
        if block.idx() >= table.len() {
            return Err(RenderError::ShortBlock { block });
        }
        let meta = table.meta(block);
        let (tree, node) = (meta.tree, meta.item.node().0);
        if tree as usize >= self.infos.len() {
            return Err(RenderError::MissingTree {
                tree: tree as usize,
            });
        }
        Ok((tree, node))
    }

    /// Uploads `block` (its bytes as stored): an atlas into a free layer of an atlas array of its GPU
    /// format, an originals block's textures into free layers of their class bindings (a texture another
    /// resident block already brought is only referenced once more). Returns the bytes uploaded. On an
    /// error nothing changes: no layer stays allocated, no reference is counted.
    pub fn upload_block(
        &mut self,
        queue: &wgpu::Queue,
        block: BlockId,
        bytes: &[u8],
    ) -> Result<u64, RenderError> {
        let (tree, node) = self.owner(block)?;
        let p = &mut self.residency;
        let info = &mut self.infos[tree as usize];
        if p.table.meta(block).item.is_atlas() {
            let stored =
                p.tree_formats
                    .get(tree as usize)
                    .copied()
                    .ok_or(RenderError::MissingTree {
                        tree: tree as usize,
                    })?;
            let target = gpu_format(stored, p.bc);
            let texels = texels_for_upload(stored, bytes, p.atlas_size, target)
                .ok_or(RenderError::ShortBlock { block })?;
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
            let layer = arr.layers.alloc().ok_or(RenderError::Residency {
                what: "an atlas array reported a free layer but allocation failed",
                unique: node,
                class: ai as u32,
                layer: 0,
            })?;
            let Some(n) = arr.upload_chain(queue, layer, &texels) else {
                arr.layers.free(layer);
                return Err(RenderError::ShortBlock { block });
            };
            match info.atlas_slots.get_mut(node as usize) {
                Some(slot @ None) => {
                    *slot = Some(AtlasSlot {
                        array: ai as u32,
                        layer,
                    })
                }
                _ => {
                    arr.layers.free(layer);
                    return Err(RenderError::Residency {
                        what: "uploading an atlas whose node already holds a layer (or does not exist)",
                        unique: node,
                        class: ai as u32,
                        layer,
                    });
                }
            }
            p.decoded_on_load += u64::from(stored != target);
            p.atlas_layers_used += 1;
            return Ok(n);
        }
        let held = p
            .block_uniques
            .get(block.idx())
            .cloned()
            .unwrap_or_default();
        // Check every chain first, so a short block changes no reference count.
        for &(ui, offset) in &held {
            let u = &self.uniques[ui as usize];
            let need = u.format.chain_bytes_rect(u.extent[0], u.extent[1]);
            if offset.saturating_add(need) > bytes.len() as u64 {
                return Err(RenderError::ShortBlock { block });
            }
        }
        let mut uploaded = 0;
        for (i, &(ui, offset)) in held.iter().enumerate() {
            match self.reference_unique(queue, block, ui, offset, bytes) {
                Ok(n) => uploaded += n,
                Err(e) => {
                    // Hand back what this block referenced so far: no reference without a resident block.
                    for &(done, _) in &held[..i] {
                        // A rollback that fails is a broken invariant too; the first error is reported.
                        let _ = self.release_unique(done);
                    }
                    return Err(e);
                }
            }
        }
        Ok(uploaded)
    }

    /// Frees an evicted block's layers: its atlas layer, or the layers of the original textures no other
    /// resident block still references.
    pub fn free_block(&mut self, block: BlockId) -> Result<(), RenderError> {
        let (tree, node) = self.owner(block)?;
        let p = &mut self.residency;
        let info = &mut self.infos[tree as usize];
        if p.table.meta(block).item.is_atlas() {
            let Some(s) = info
                .atlas_slots
                .get_mut(node as usize)
                .and_then(Option::take)
            else {
                return Err(RenderError::Residency {
                    what: "evicting an atlas that holds no layer",
                    unique: node,
                    class: 0,
                    layer: 0,
                });
            };
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
            return Ok(());
        }
        let held = p
            .block_uniques
            .get(block.idx())
            .cloned()
            .unwrap_or_default();
        // Check every reference first, so a broken count changes nothing; then release them all (a layer
        // that fails to free is reported after the rest are released).
        if let Some(&(ui, _)) = held
            .iter()
            .find(|&&(u, _)| self.residency.unique_refs[u as usize] == 0)
        {
            return Err(RenderError::Residency {
                what: "evicting an original that holds no reference",
                unique: ui,
                class: self.uniques[ui as usize].class,
                layer: 0,
            });
        }
        let mut first_error = None;
        for (ui, _) in held {
            if let Err(e) = self.release_unique(ui) {
                first_error.get_or_insert(e);
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// One reference more to unique `ui` carried by `block` at `offset`: its first reference allocates a
    /// layer in a binding of its class and uploads it. Returns the bytes uploaded.
    fn reference_unique(
        &mut self,
        queue: &wgpu::Queue,
        block: BlockId,
        ui: u32,
        offset: u64,
        bytes: &[u8],
    ) -> Result<u64, RenderError> {
        let p = &mut self.residency;
        let u = ui as usize;
        if p.unique_refs[u] > 0 {
            p.unique_refs[u] += 1;
            return Ok(0);
        }
        let class = self.uniques[u].class;
        // The first binding of this class with a free layer.
        let found = self.class_arrays.iter_mut().enumerate().find_map(|(i, a)| {
            a.as_mut()
                .filter(|a| {
                    p.slot_class[i] == Some(class) && a.layers.in_use() < a.layers.capacity()
                })
                .map(|a| (i, a))
        });
        let Some((slot, arr)) = found else {
            return Err(RenderError::TooManyLayers {
                what: format!("resident original textures of class {}", 4u32 << class),
                layers: u64::from(p.original_layers_used) + 1,
                limit: u64::from(p.original_layers_used),
            });
        };
        let layer = arr.layers.alloc().ok_or(RenderError::Residency {
            what: "a class array reported a free layer but allocation failed",
            unique: ui,
            class: slot as u32,
            layer: 0,
        })?;
        // From here a failure hands the layer back: the reference count only counts uniques that hold a
        // layer.
        let (stored, extent) = (self.uniques[u].format, self.uniques[u].extent);
        let target = arr.format;
        let texels = usize::try_from(offset)
            .ok()
            .and_then(|o| bytes.get(o..))
            .and_then(|chain| layer_texels_for_upload(stored, chain, extent, target));
        let Some(n) = texels.and_then(|t| arr.upload_chain(queue, layer, &t)) else {
            arr.layers.free(layer);
            return Err(RenderError::ShortBlock { block });
        };
        p.unique_refs[u] = 1;
        p.decoded_on_load += u64::from(stored != target && target == TexFormat::Rgba8);
        p.widened_on_load += u64::from(stored != target && target == TexFormat::Bc3);
        self.uniques[u].slot = slot as u32;
        self.uniques[u].layer = layer;
        p.original_layers_used += 1;
        for &e in &p.tam_users[u] {
            if let Some(entry) = self.tam.get_mut(e as usize) {
                entry.class_index = slot as u32;
                entry.layer = layer;
                queue.write_buffer(
                    &self.tam_buffer,
                    u64::from(e) * size_of::<TamEntry>() as u64,
                    bytemuck::bytes_of(entry),
                );
            }
        }
        Ok(n)
    }

    /// One reference less to unique `ui`; the last frees its layer.
    fn release_unique(&mut self, ui: u32) -> Result<(), RenderError> {
        let p = &mut self.residency;
        let u = ui as usize;
        if p.unique_refs[u] == 0 {
            return Err(RenderError::Residency {
                what: "evicting an original that holds no reference",
                unique: ui,
                class: self.uniques[u].class,
                layer: 0,
            });
        }
        p.unique_refs[u] -= 1;
        if p.unique_refs[u] == 0 {
            let slot = self.uniques[u].slot as usize;
            let layer = self.uniques[u].layer;
            let freed = self
                .class_arrays
                .get_mut(slot)
                .and_then(|a| a.as_mut())
                .is_some_and(|arr| arr.layers.free(layer));
            if !freed {
                return Err(RenderError::Residency {
                    what: "evicting an original whose layer is not allocated",
                    unique: ui,
                    class: slot as u32,
                    layer,
                });
            }
            p.original_layers_used -= 1;
        }
        Ok(())
    }
}

/// The pager's view of a renderer error (the planner decides retry or give-up from it): no free layer,
/// a block whose bytes cannot be uploaded, broken bookkeeping, or anything else as a failed upload.
impl From<RenderError> for ResidencyError {
    fn from(e: RenderError) -> ResidencyError {
        match e {
            RenderError::TooManyLayers {
                what,
                layers,
                limit,
            } => ResidencyError::NoFreeLayer {
                what,
                needed: layers,
                limit,
            },
            RenderError::ShortBlock { block } => ResidencyError::BadBlock { block },
            e @ (RenderError::Residency { .. }
            | RenderError::MissingTree { .. }
            | RenderError::MissingSlot { .. }) => ResidencyError::Bookkeeping {
                message: e.to_string(),
            },
            e => ResidencyError::Upload {
                message: e.to_string(),
            },
        }
    }
}
