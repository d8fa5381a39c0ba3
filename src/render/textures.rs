//! Texture arrays (TAB): every atlas of a file is a layer of one `texture_2d_array` (full mip chain);
//! original textures are layers of one array per class size (4² … 2048²).
//!
//! **Formats.** An array has one [`TexFormat`]: the blocks' stored format (RGBA8 or BC1/BC3/BC7, all sRGB)
//! when the device has `TEXTURE_COMPRESSION_BC` ([`gpu_format`]), else RGBA8, and then compressed blocks are
//! decoded on the CPU as they are uploaded ([`texels_for_upload`]); loaders count and report those.
//!
//! **Layer limit.** A device allows `max_texture_array_layers` layers per array (2048 on lavapipe, 2048 on
//! most desktop GPUs; the shader addresses at most 65,536, [`layer_limit`]). When a file has more atlases than that, they are split over up to
//! [`MAX_ATLAS_ARRAYS`] arrays and each record names its array. A class with more originals than the limit
//! continues in the class bindings no class uses (`resident::class_slots`: the 4,304 facades of a
//! Berlin-like city take three 512² bindings). Beyond that loading fails with
//! [`super::RenderError::TooManyLayers`] — with all blocks resident that is ≥ 8,192 atlases, past what the
//! all-resident renderer is for; paging keeps residency under a capacity instead.
//!
//! **Byte limit.** An array is one allocation, and a device bounds those (`maxMemoryAllocationSize`, which
//! wgpu reports as `max_buffer_size`: 2 GiB − 1 on lavapipe, which refuses an array of 384 RGBA8 atlases of
//! 1024², 2,147,483,136 bytes before its alignment padding). An array holds at most [`array_byte_limit`]
//! bytes ([`layers_per_array`]), so the 790 RGBA8 atlases of the all-tracks world take three arrays
//! instead of one that no allocation holds.
//!
//! [`LayerAllocator`] hands out layers (paging slots) from a free list; the paging issue reuses it.

use crate::texfmt::{TexFormat, mip_level_count};
use std::borrow::Cow;

/// Atlas arrays bound at once (the shader switches over this many bindings).
pub const MAX_ATLAS_ARRAYS: usize = 4;
/// Class arrays: sizes `4 << k` for k in 0..CLASS_COUNT (4 … 2048).
pub const CLASS_COUNT: usize = 10;
/// Smallest class size.
pub const MIN_CLASS_SIZE: u32 = 4;

/// Layers per texture array the renderer uses: the device's `max_texture_array_layers`, at most what the
/// tree shader addresses ([`super::wgsl::tree::MAX_LAYERS`]), at least 1.
pub fn layer_limit(device_max_layers: u32) -> u32 {
    device_max_layers.clamp(1, super::wgsl::tree::MAX_LAYERS)
}

/// Bytes one texture array may take: the device's largest allocation (`max_buffer_size`) less 1/64 of
/// it for the driver's alignment padding of layers and mip levels.
pub fn array_byte_limit(device_max_buffer_size: u64) -> u64 {
    device_max_buffer_size - device_max_buffer_size / 64
}

/// Layers an array of `size²` textures of `format` (full mip chains) may hold: at most `max_layers`
/// ([`layer_limit`]) and `byte_limit` bytes ([`array_byte_limit`]), at least 1.
pub fn layers_per_array(max_layers: u32, byte_limit: u64, format: TexFormat, size: u32) -> u32 {
    let per_layer = format.chain_bytes(size).max(1);
    (byte_limit / per_layer).clamp(1, u64::from(max_layers.max(1))) as u32
}

/// Class index of a power-of-two class size, `None` outside 4..=2048 or not a power of two.
pub fn class_index(size: u32) -> Option<u32> {
    if !size.is_power_of_two() || size < MIN_CLASS_SIZE {
        return None;
    }
    let k = size.trailing_zeros() - MIN_CLASS_SIZE.trailing_zeros();
    ((k as usize) < CLASS_COUNT).then_some(k)
}

/// A free list of layers `0..capacity`. [`LayerAllocator::alloc`] hands out the most recently freed layer
/// first (last in, first out), and only when none is free the lowest layer never handed out (a fresh
/// allocator counts up from 0). [`LayerAllocator::free`] is linear in the number of free layers (it refuses
/// a double free).
#[derive(Clone, Debug)]
pub struct LayerAllocator {
    capacity: u32,
    /// Freed layers (popped last-in first-out).
    free: Vec<u32>,
    /// Layers never handed out are `next..capacity`.
    next: u32,
    in_use: u32,
}

impl LayerAllocator {
    pub fn new(capacity: u32) -> LayerAllocator {
        LayerAllocator {
            capacity,
            free: Vec::new(),
            next: 0,
            in_use: 0,
        }
    }

    /// A free layer (the last one freed, else the next never used), `None` when all `capacity` layers are
    /// in use.
    pub fn alloc(&mut self) -> Option<u32> {
        let layer = match self.free.pop() {
            Some(l) => l,
            None if self.next < self.capacity => {
                self.next += 1;
                self.next - 1
            }
            None => return None,
        };
        self.in_use += 1;
        Some(layer)
    }

    /// Returns `layer` to the free list; `false` (and no change) if it was not allocated.
    pub fn free(&mut self, layer: u32) -> bool {
        if layer >= self.next || self.free.contains(&layer) {
            return false;
        }
        self.free.push(layer);
        self.in_use -= 1;
        true
    }

    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    pub fn in_use(&self) -> u32 {
        self.in_use
    }
}

/// The format of an array holding chains stored in each of `formats` (already mapped by [`gpu_format`]):
/// their common format; BC3 for a mix of BC1 and BC3 (BC1 widens losslessly); else RGBA8 (decoded).
pub fn common_format(formats: impl IntoIterator<Item = TexFormat>) -> TexFormat {
    let mut common: Option<TexFormat> = None;
    for f in formats {
        common = Some(match (common, f) {
            (None, f) => f,
            (Some(c), f) if c == f => c,
            (Some(TexFormat::Bc1), TexFormat::Bc3) | (Some(TexFormat::Bc3), TexFormat::Bc1) => {
                TexFormat::Bc3
            }
            _ => TexFormat::Rgba8,
        });
    }
    common.unwrap_or_default()
}

/// The format a texture holding blocks stored as `stored` gets on the GPU: `stored` itself if it is RGBA8
/// or the device samples BC textures (`bc_supported`: `GpuFeatures::texture_compression_bc`), else RGBA8.
pub fn gpu_format(stored: TexFormat, bc_supported: bool) -> TexFormat {
    if stored.is_compressed() && !bc_supported {
        TexFormat::Rgba8
    } else {
        stored
    }
}

/// The texels of a `size²` mip chain stored as `stored` (the start of `bytes`), as a texture of format
/// `target` takes them: borrowed when the formats agree, decoded on the CPU to RGBA8 when `target` is
/// RGBA8 (the fallback for adapters without BC), BC1 widened to BC3 (a class array shared by a BC1 and a
/// BC3 tree; see [`crate::texfmt::bc1_to_bc3`]). `None` if `bytes` is shorter than the chain or for any
/// other pair (no transcoding).
pub fn texels_for_upload(
    stored: TexFormat,
    bytes: &[u8],
    size: u32,
    target: TexFormat,
) -> Option<Cow<'_, [u8]>> {
    rect_texels_for_upload(stored, bytes, [size, size], target)
}

/// The texels of a `w × h` chain (`crate::texfmt::mip_extents`) stored as `stored`, as a `w × h`
/// texture of format `target` takes them, not tiled (see [`texels_for_upload`]).
pub fn rect_texels_for_upload(
    stored: TexFormat,
    bytes: &[u8],
    [w, h]: [u32; 2],
    target: TexFormat,
) -> Option<Cow<'_, [u8]>> {
    let len = usize::try_from(stored.chain_bytes_rect(w, h)).ok()?;
    let chain = bytes.get(..len)?;
    match (stored, target) {
        (a, b) if a == b => Some(Cow::Borrowed(chain)),
        (TexFormat::Bc1, TexFormat::Bc3) => Some(Cow::Owned(crate::texfmt::bc1_to_bc3(chain))),
        (_, TexFormat::Rgba8) => crate::texfmt::decode_chain_rect(stored, chain, w, h)
            .ok()
            .map(Cow::Owned),
        _ => None,
    }
}

/// The texels of the `s × s` class layer (`s = max(w, h)`) that shows a `w × h` original chain stored as
/// `stored` (the start of `bytes`), in format `target` (as [`texels_for_upload`]), tiled across the layer
/// ([`crate::texfmt::tile_chain_to_square`]; the shader scales its UV by `extent / s`). Square chains are
/// [`texels_for_upload`]. `None` if `bytes` is shorter than the chain or for a pair without a conversion.
pub fn layer_texels_for_upload(
    stored: TexFormat,
    bytes: &[u8],
    [w, h]: [u32; 2],
    target: TexFormat,
) -> Option<Cow<'_, [u8]>> {
    let converted = rect_texels_for_upload(stored, bytes, [w, h], target)?;
    if w == h {
        return Some(converted);
    }
    crate::texfmt::tile_chain_to_square(target, &converted, w, h)
        .ok()
        .map(Cow::Owned)
}

/// One texture array with its allocator.
pub struct TextureArray {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    pub size: u32,
    /// The texture's format (what [`TextureArray::upload_chain`] expects).
    pub format: TexFormat,
    pub layers: LayerAllocator,
}

impl TextureArray {
    /// A `size² × layers` array of `format` with a full mip chain (at least one layer). BC formats need
    /// `TEXTURE_COMPRESSION_BC` on the device (see [`gpu_format`]) and `size` a multiple of 4.
    pub fn new(
        device: &wgpu::Device,
        label: &str,
        size: u32,
        layers: u32,
        format: TexFormat,
    ) -> TextureArray {
        let layers = layers.max(1);
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: size,
                height: size,
                depth_or_array_layers: layers,
            },
            mip_level_count: mip_level_count(size),
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: format.wgpu_format(),
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some(label),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        TextureArray {
            texture,
            view,
            size,
            format,
            layers: LayerAllocator::new(layers),
        }
    }

    /// Uploads a full mip chain (`size²` in the array's format, level 0 first, as in the paging file's
    /// blocks) into `layer`. Returns the bytes consumed; fails (returning `None`) if `chain` is shorter than
    /// a full chain.
    pub fn upload_chain(&self, queue: &wgpu::Queue, layer: u32, chain: &[u8]) -> Option<u64> {
        upload_mip_chain(queue, &self.texture, self.size, layer, chain, self.format)
    }
}

/// Writes a full mip chain of a `size²` image stored as `format` into `layer` of `texture`: the square
/// case of [`upload_mip_chain_rect`].
pub fn upload_mip_chain(
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    size: u32,
    layer: u32,
    chain: &[u8],
    format: TexFormat,
) -> Option<u64> {
    upload_mip_chain_rect(queue, texture, [size, size], layer, chain, format)
}

/// Writes a full mip chain of a `w × h` image stored as `format` ([`crate::texfmt::mip_extents`]) into
/// `layer` of `texture` (which must have that format and size) with one `queue.write_texture` per level.
/// `None` if `chain` is shorter than `format.chain_bytes_rect(w, h)`. BC levels with a side under 4 are
/// copied as whole blocks (their physical size).
pub fn upload_mip_chain_rect(
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    [w, h]: [u32; 2],
    layer: u32,
    chain: &[u8],
    format: TexFormat,
) -> Option<u64> {
    let total = format.chain_bytes_rect(w, h);
    if (chain.len() as u64) < total {
        return None;
    }
    let mut offset = 0usize;
    for (level, (a, b)) in crate::texfmt::mip_extents(w, h).enumerate() {
        let bytes = format.level_bytes_rect(a, b) as usize;
        let data = chain.get(offset..offset + bytes)?;
        let (bytes_per_row, _) = format.upload_layout(a);
        let (width, height, rows) = if format.is_compressed() {
            (a.div_ceil(4) * 4, b.div_ceil(4) * 4, b.div_ceil(4))
        } else {
            (a, b, b)
        };
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: level as u32,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                aspect: wgpu::TextureAspect::All,
            },
            data,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(bytes_per_row),
                rows_per_image: Some(rows),
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        offset += bytes;
    }
    Some(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texfmt::decode_chain;

    #[test]
    fn non_square_layers_convert_then_tile() {
        // A 16×4 gradient chain stored as BC1, uploaded to BC1, BC3 and RGBA8 arrays: each layer is the
        // same picture (the BC1 decode) tiled 4× down at every level.
        let mut chain = Vec::new();
        for (a, b) in crate::texfmt::mip_extents(16, 4) {
            chain.extend(
                (0..a * b).flat_map(|i| [(i % a * 255 / a) as u8, (i / a * 60) as u8, 90, 255]),
            );
        }
        let bc1 = crate::texfmt::encode_chain_rect(TexFormat::Bc1, &chain, 16, 4, 3).unwrap();
        let want = crate::texfmt::decode_chain(
            TexFormat::Bc1,
            &crate::texfmt::tile_chain_to_square(TexFormat::Bc1, &bc1.bytes, 16, 4).unwrap(),
            16,
        )
        .unwrap();
        for target in [TexFormat::Bc1, TexFormat::Bc3, TexFormat::Rgba8] {
            let layer =
                layer_texels_for_upload(TexFormat::Bc1, &bc1.bytes, [16, 4], target).unwrap();
            assert_eq!(layer.len() as u64, target.chain_bytes(16), "{target:?}");
            let got = decode_chain(target, &layer, 16).unwrap();
            assert_eq!(got, want, "{target:?}");
        }
        assert!(
            layer_texels_for_upload(TexFormat::Bc1, &bc1.bytes[..8], [16, 4], TexFormat::Bc1)
                .is_none()
        );
        assert!(
            layer_texels_for_upload(TexFormat::Bc7, &bc1.bytes, [16, 4], TexFormat::Bc1).is_none()
        );
    }

    #[test]
    fn class_indices_cover_4_to_2048() {
        assert_eq!(class_index(4), Some(0));
        assert_eq!(class_index(2048), Some(9));
        assert_eq!(class_index(2), None);
        assert_eq!(class_index(4096), None);
        assert_eq!(class_index(12), None);
        assert_eq!(mip_level_count(512), 10);
        assert_eq!(mip_level_count(1), 1);
    }

    #[test]
    fn upload_texels_borrow_decode_or_refuse() {
        let rgba: Vec<u8> = (0..TexFormat::Rgba8.chain_bytes(8))
            .map(|i| (i * 7) as u8)
            .collect();
        let enc = crate::texfmt::encode_chain(TexFormat::Bc1, &rgba, 8, 3).unwrap();
        let same = texels_for_upload(TexFormat::Bc1, &enc.bytes, 8, TexFormat::Bc1).unwrap();
        assert!(matches!(same, Cow::Borrowed(_)));
        assert_eq!(same.len() as u64, TexFormat::Bc1.chain_bytes(8));
        let dec = texels_for_upload(TexFormat::Bc1, &enc.bytes, 8, TexFormat::Rgba8).unwrap();
        assert!(matches!(dec, Cow::Owned(_)));
        assert_eq!(dec.len() as u64, TexFormat::Rgba8.chain_bytes(8));
        assert_eq!(
            crate::texfmt::sse_rgba8(&rgba, &dec, 3),
            enc.sse,
            "decode on load gives what the build measured"
        );
        assert!(texels_for_upload(TexFormat::Bc1, &enc.bytes, 8, TexFormat::Bc7).is_none());
        let wide = texels_for_upload(TexFormat::Bc1, &enc.bytes, 8, TexFormat::Bc3).unwrap();
        assert_eq!(wide.len() as u64, TexFormat::Bc3.chain_bytes(8));
        let wide_dec = crate::texfmt::decode_chain(TexFormat::Bc3, &wide, 8).unwrap();
        assert_eq!(
            wide_dec, *dec,
            "BC1 widened to BC3 decodes to the same texels"
        );
        assert!(texels_for_upload(TexFormat::Bc1, &enc.bytes[..10], 8, TexFormat::Rgba8).is_none());
        assert_eq!(gpu_format(TexFormat::Bc7, false), TexFormat::Rgba8);
        assert_eq!(gpu_format(TexFormat::Bc7, true), TexFormat::Bc7);
        assert_eq!(gpu_format(TexFormat::Rgba8, true), TexFormat::Rgba8);
        use TexFormat::*;
        assert_eq!(common_format([Bc1, Bc1]), Bc1);
        assert_eq!(common_format([Bc1, Bc3, Bc1]), Bc3);
        assert_eq!(common_format([Bc1, Bc7]), Rgba8);
        assert_eq!(common_format([]), Rgba8);
    }

    #[test]
    fn allocator_reuses_freed_layers_and_stops_at_capacity() {
        let mut a = LayerAllocator::new(3);
        assert_eq!(
            (a.alloc(), a.alloc(), a.alloc()),
            (Some(0), Some(1), Some(2))
        );
        assert_eq!(a.alloc(), None);
        assert!(a.free(1));
        assert!(!a.free(1), "double free");
        assert!(!a.free(7), "never allocated");
        assert_eq!(a.in_use(), 2);
        assert_eq!(a.alloc(), Some(1));
        assert_eq!(a.alloc(), None);
    }

    #[test]
    fn allocator_reuses_the_last_freed_layer_before_fresh_ones() {
        let mut a = LayerAllocator::new(8);
        let first: Vec<_> = (0..4).map(|_| a.alloc()).collect();
        assert_eq!(first, [Some(0), Some(1), Some(2), Some(3)]);
        assert!(a.free(0));
        assert!(a.free(2));
        // Last in, first out; not the lowest free layer (0) first.
        assert_eq!((a.alloc(), a.alloc()), (Some(2), Some(0)));
        // Then the layers never handed out, in order.
        assert_eq!((a.alloc(), a.alloc()), (Some(4), Some(5)));
        assert_eq!(a.in_use(), 6);
    }
}
