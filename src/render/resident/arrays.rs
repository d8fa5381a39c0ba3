//! Texture arrays of a load: atlas arrays per GPU format ([`atlas_arrays_for`]) and class arrays for the
//! original textures ([`class_slots`]), both sized for a capacity of k resident blocks (all blocks for an
//! all-resident load: the same policy either way).

use super::tables::GpuTables;
use crate::gpu::GpuContext;
use crate::render::RenderError;
use crate::render::textures::{
    CLASS_COUNT, MAX_ATLAS_ARRAYS, TextureArray, array_byte_limit, gpu_format, layer_limit,
    layers_per_array,
};
use crate::texfmt::TexFormat;

/// The atlas arrays of a plan: per GPU format of the trees' atlases (BC formats only where the device samples
/// them), room for `min(cap, atlases of that format)` layers, split at the device's layer limit and at its
/// largest allocation ([`layers_per_array`]); at most [`MAX_ATLAS_ARRAYS`] arrays.
pub(super) fn atlas_arrays_for(
    ctx: &GpuContext,
    g: &GpuTables,
    atlas_size: u32,
    cap: u32,
) -> Result<Vec<TextureArray>, RenderError> {
    let per_array = |f: TexFormat| device_layers_per_array(ctx, f, atlas_size);
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
        .map(|&(f, n)| n.min(cap).div_ceil(per_array(f)).max(1) as usize)
        .sum();
    if arrays_needed > MAX_ATLAS_ARRAYS {
        // The most layers MAX_ATLAS_ARRAYS arrays hold (of the format whose arrays hold fewest).
        let fewest = per_format.iter().map(|&(f, _)| per_array(f)).min();
        return Err(RenderError::TooManyLayers {
            what: "atlases".into(),
            layers: u64::from(layers),
            limit: u64::from(fewest.unwrap_or(1)) * MAX_ATLAS_ARRAYS as u64,
        });
    }
    let mut arrays = Vec::with_capacity(arrays_needed);
    for &(format, count) in &per_format {
        let mut remaining = count.min(cap).max(1);
        while remaining > 0 {
            let n = remaining.min(per_array(format));
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

/// Layers one array of `size²` textures of `format` holds on this device: [`layers_per_array`] under
/// its layer limit and its largest allocation.
pub(super) fn device_layers_per_array(ctx: &GpuContext, format: TexFormat, size: u32) -> u32 {
    layers_per_array(
        layer_limit(ctx.features.max_texture_array_layers),
        array_byte_limit(ctx.features.max_buffer_size),
        format,
        size,
    )
}

/// Texture-array slots (bindings `class0..`): slot `k` holds class `k` (`4 << k` texels), up to
/// `max_layers[k]` layers (the device's layer limit and largest allocation: [`layers_per_array`]); a class
/// with more originals than that continues in the lowest slots no class uses. `per_class[k]`: originals of
/// class k. Each entry: `(class, layers)`. Errors when the free slots run out.
pub fn class_slots(
    per_class: &[u32; CLASS_COUNT],
    max_layers: &[u32; CLASS_COUNT],
) -> Result<[Option<(u32, u32)>; CLASS_COUNT], RenderError> {
    let mut slots: [Option<(u32, u32)>; CLASS_COUNT] = [None; CLASS_COUNT];
    for (k, &n) in per_class.iter().enumerate() {
        if n > 0 {
            slots[k] = Some((k as u32, n.min(max_layers[k].max(1))));
        }
    }
    for (k, &n) in per_class.iter().enumerate() {
        let max_layers = max_layers[k].max(1);
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
    use crate::texfmt::TexFormat;

    #[test]
    fn class_slots_split_a_full_class_into_unused_bindings() {
        let mut per_class = [0u32; CLASS_COUNT];
        per_class[6] = 4304; // class 256 (4 << 6)
        per_class[2] = 10;
        let s = class_slots(&per_class, &[2048; CLASS_COUNT]).expect("fits");
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
        assert!(class_slots(&all, &[2048; CLASS_COUNT]).is_ok());
        all[7] += 1;
        let e = class_slots(&all, &[2048; CLASS_COUNT]).expect_err("one layer too many");
        assert!(e.to_string().contains("class 512"), "{e}");
    }

    #[test]
    fn class_slots_split_at_each_class_own_limit() {
        // Class 2048 holds 94 RGBA8 layers under lavapipe's allocation limit, class 4 the device's 2048.
        let byte_limit = array_byte_limit(i32::MAX as u64);
        let limits: [u32; CLASS_COUNT] =
            std::array::from_fn(|k| layers_per_array(2048, byte_limit, TexFormat::Rgba8, 4 << k));
        assert_eq!((limits[9], limits[0]), (94, 2048));
        let mut per_class = [0u32; CLASS_COUNT];
        per_class[9] = 200;
        per_class[0] = 3000;
        let s = class_slots(&per_class, &limits).expect("fits");
        assert_eq!(s[9], Some((9, 94)));
        assert_eq!(s[0], Some((0, 2048)));
        // The rest in class order: 952 of class 4 in slot 1; 106 of class 2048: 94 in slot 2, 12 in slot 3.
        assert_eq!(s[1], Some((0, 952)));
        assert_eq!(s[2], Some((9, 94)));
        assert_eq!(s[3], Some((9, 12)));
    }

    #[test]
    fn arrays_stay_under_the_largest_allocation() {
        let byte_limit = array_byte_limit(i32::MAX as u64);
        // 1024² RGBA8 with mips: 5,592,404 bytes a layer; lavapipe refuses 384 of them in one array.
        let n = layers_per_array(2048, byte_limit, TexFormat::Rgba8, 1024);
        assert_eq!(n, 378);
        assert!(u64::from(n) * TexFormat::Rgba8.chain_bytes(1024) <= byte_limit);
        // BC1 is an eighth of that: the device's layer limit binds first below 4096² texels.
        assert_eq!(
            layers_per_array(2048, byte_limit, TexFormat::Bc1, 1024),
            2048
        );
        // One layer past the limit still gets its array (its allocation then fails, reported).
        assert_eq!(layers_per_array(2048, 1000, TexFormat::Rgba8, 1024), 1);
        // No byte limit: the layer limit.
        assert_eq!(
            layers_per_array(2048, u64::MAX, TexFormat::Rgba8, 1024),
            2048
        );
    }
}
