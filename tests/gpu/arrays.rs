//! Texture arrays split at the device's largest allocation (`textures::layers_per_array`): lavapipe
//! allocates at most 2 GiB, and the all-tracks world's 790 RGBA8 atlases in one array could not be
//! rendered. Here the same device is presented with a smaller allocation limit, so the deep city's atlases
//! spread over three arrays, and every frame must be the one the single array draws.

use atlastree::gpu::{GpuContext, GpuFeatures};
use atlastree::render::Mode;
use atlastree::render::textures::array_byte_limit;
use atlastree::store::TreeFile;
use atlastree::texfmt::TexFormat;

use crate::harness::GpuTest;
use crate::render::{city_deep, dive_cameras, e, frame, renderer};

pub fn tests() -> Vec<GpuTest> {
    vec![GpuTest {
        name: "arrays::atlases_split_by_bytes_draw_the_frames_of_one_array",
        run: atlases_split_by_bytes_draw_the_frames_of_one_array,
    }]
}

/// `ctx` as a device whose largest allocation is `max_buffer_size` bytes would present it.
fn with_allocation_limit(ctx: &GpuContext, max_buffer_size: u64) -> GpuContext {
    crate::harness::with_features(
        ctx,
        GpuFeatures {
            max_buffer_size,
            ..ctx.features
        },
    )
}

/// The deep city (RGBA8 atlases of 512²) with every atlas resident: in one array on the real device, in
/// three under an allocation limit of a third of them; six views along the dive, tree mode, identical
/// frames (the records name their array, each array its own pipeline). Measured on lavapipe: 107 atlases,
/// identical; with every atlas record grouped into array 0's pipeline, view 0 already differs (32 px).
fn atlases_split_by_bytes_draw_the_frames_of_one_array(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city_deep()?).map_err(e)?;
    let cams = dive_cameras(&file, 6)?;
    let draw = |ctx: &GpuContext| -> Result<(u32, u32, Vec<Vec<u8>>), String> {
        let mut r = renderer(ctx, &file)?;
        let stats = &r.renderer.resident.stats;
        let (layers, arrays) = (stats.atlas_layers, stats.atlas_arrays);
        let mut frames = Vec::new();
        for cam in &cams {
            frames.push(frame(&mut r, &file, cam, Mode::Tree)?.1);
        }
        Ok((layers, arrays, frames))
    };
    let (layers, one_array, want) = draw(ctx)?;
    if one_array != 1 {
        return Err(format!(
            "{layers} atlases took {one_array} arrays on the device"
        ));
    }
    // A limit whose array_byte_limit holds ⌈layers / 3⌉ chains and half of one more.
    let chain = TexFormat::Rgba8.chain_bytes(file.to_params().atlas_size);
    let per_array = u64::from(layers.div_ceil(3));
    let wanted_limit = per_array * chain + chain / 2;
    let max_buffer_size = wanted_limit * 64 / 63 + 1;
    if array_byte_limit(max_buffer_size) / chain != per_array {
        return Err(format!(
            "limit {max_buffer_size} does not hold {per_array} chains"
        ));
    }
    let small = with_allocation_limit(ctx, max_buffer_size);
    let (_, arrays, got) = draw(&small)?;
    println!(
        "  {layers} atlases: 1 array on the device, {arrays} under a {max_buffer_size}-byte allocation limit; \
         {} views",
        cams.len()
    );
    if arrays != 3 {
        return Err(format!(
            "{layers} atlases under the limit took {arrays} arrays, want 3"
        ));
    }
    for (i, (a, b)) in want.iter().zip(&got).enumerate() {
        if a != b {
            let differ = a
                .chunks_exact(4)
                .zip(b.chunks_exact(4))
                .filter(|(p, q)| p != q)
                .count();
            return Err(format!(
                "view {i}: {differ} pixels differ between one array and three"
            ));
        }
    }
    Ok(())
}
