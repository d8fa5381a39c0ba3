//! The context itself: limits raised to the adapter's, readback of array layers and its error paths,
//! timestamp queries when the device has them.

use atlastree::gpu::{GpuContext, GpuError, readback_rgba8, readback_rgba8_layer};
use wgpu::util::DeviceExt;

use crate::harness::GpuTest;

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "device::limits_match_adapter",
            run: limits_match_adapter,
        },
        GpuTest {
            name: "device::readback_layers_and_errors",
            run: readback_layers_and_errors,
        },
        GpuTest {
            name: "device::timestamps_measure_a_pass",
            run: timestamps_measure_a_pass,
        },
    ]
}

/// The device was opened with the adapter's maxima for the limits the atlas arrays depend on, and those are
/// what `GpuFeatures` reports; the required features are on.
fn limits_match_adapter(ctx: &GpuContext) -> Result<(), String> {
    let adapter = ctx.adapter.limits();
    let device = ctx.device.limits();
    let f = &ctx.features;
    let pairs = [
        (
            "max_texture_array_layers",
            u64::from(adapter.max_texture_array_layers),
            u64::from(device.max_texture_array_layers),
            u64::from(f.max_texture_array_layers),
        ),
        (
            "max_texture_dimension_2d",
            u64::from(adapter.max_texture_dimension_2d),
            u64::from(device.max_texture_dimension_2d),
            u64::from(f.max_texture_dimension_2d),
        ),
        (
            "max_storage_buffer_binding_size",
            adapter.max_storage_buffer_binding_size,
            device.max_storage_buffer_binding_size,
            f.max_storage_buffer_binding_size,
        ),
        (
            "max_buffer_size",
            adapter.max_buffer_size,
            device.max_buffer_size,
            f.max_buffer_size,
        ),
    ];
    for (name, a, d, reported) in pairs {
        if a != d || d != reported {
            return Err(format!(
                "{name}: adapter {a}, device {d}, GpuFeatures {reported}"
            ));
        }
    }
    if !ctx
        .device
        .features()
        .contains(wgpu::Features::INDIRECT_FIRST_INSTANCE)
        || !f.indirect_first_instance
    {
        return Err("INDIRECT_FIRST_INSTANCE not enabled".to_owned());
    }
    if f.max_texture_array_layers < 256 || f.max_texture_dimension_2d < 8192 {
        return Err(format!("limits below WebGPU defaults: {f}"));
    }
    Ok(())
}

/// Uploads a 5×3, 3-layer array whose texel (x, y) of layer l is (x, y, l, 255), reads every layer back with
/// `readback_rgba8_layer` and expects exactly those bytes; then checks the three error paths.
fn readback_layers_and_errors(ctx: &GpuContext) -> Result<(), String> {
    let (width, height, layers) = (5u32, 3u32, 3u32);
    let texel = |x: u32, y: u32, l: u32| [x as u8, y as u8, l as u8, 255];
    let data: Vec<u8> = (0..layers)
        .flat_map(|l| (0..height).flat_map(move |y| (0..width).flat_map(move |x| texel(x, y, l))))
        .collect();
    let desc = |format, usage| wgpu::TextureDescriptor {
        label: Some("readback test"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    };
    let usage = wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST;
    let texture = ctx.device.create_texture_with_data(
        &ctx.queue,
        &desc(wgpu::TextureFormat::Rgba8Unorm, usage),
        wgpu::util::TextureDataOrder::LayerMajor,
        &data,
    );
    let layer_bytes = (width * height * 4) as usize;
    for l in 0..layers {
        let got = readback_rgba8_layer(ctx, &texture, l).map_err(|e| e.to_string())?;
        let start = l as usize * layer_bytes;
        if data.get(start..start + layer_bytes) != Some(got.as_slice()) {
            return Err(format!("layer {l}: read back {got:?}"));
        }
    }
    match readback_rgba8_layer(ctx, &texture, layers) {
        Err(GpuError::LayerOutOfRange {
            layer: 3,
            layers: 3,
        }) => {}
        other => {
            return Err(format!(
                "layer 3 of 3: expected LayerOutOfRange, got {other:?}"
            ));
        }
    }
    let no_copy = ctx.device.create_texture(&desc(
        wgpu::TextureFormat::Rgba8Unorm,
        wgpu::TextureUsages::COPY_DST,
    ));
    match readback_rgba8(ctx, &no_copy) {
        Err(GpuError::NotCopySource {
            width: 5,
            height: 3,
        }) => {}
        other => {
            return Err(format!(
                "no COPY_SRC: expected NotCopySource, got {other:?}"
            ));
        }
    }
    let bgra = ctx
        .device
        .create_texture(&desc(wgpu::TextureFormat::Bgra8Unorm, usage));
    match readback_rgba8(ctx, &bgra) {
        Err(GpuError::UnsupportedReadbackFormat {
            format: wgpu::TextureFormat::Bgra8Unorm,
        }) => Ok(()),
        other => Err(format!(
            "Bgra8Unorm: expected UnsupportedReadbackFormat, got {other:?}"
        )),
    }
}

/// With `TIMESTAMP_QUERY`, timestamps written at the start and end of a render pass that clears a 1024² target
/// resolve to a non-zero, non-decreasing pair; the elapsed time is below 10 s. Without the feature the context
/// must report a zero timestamp period.
fn timestamps_measure_a_pass(ctx: &GpuContext) -> Result<(), String> {
    if !ctx.features.timestamp_query {
        return match ctx.features.timestamp_period_ns {
            0.0 => {
                println!(
                    "  SKIPPED in part: the adapter has no TIMESTAMP_QUERY (only its zero period checked)"
                );
                Ok(())
            }
            p => Err(format!(
                "no TIMESTAMP_QUERY but a timestamp period of {p} ns"
            )),
        };
    }
    let query_set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("pass timestamps"),
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("timestamp resolve"),
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("timestamp read"),
        size: 16,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let target = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("timestamp target"),
        size: wgpu::Extent3d {
            width: 1024,
            height: 1024,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let view = target.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    drop(encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("timed clear"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::BLUE),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: Some(wgpu::RenderPassTimestampWrites {
            query_set: &query_set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }),
        occlusion_query_set: None,
        multiview_mask: None,
    }));
    encoder.resolve_query_set(&query_set, 0..2, &resolve, 0);
    encoder.copy_buffer_to_buffer(&resolve, 0, &read, 0, 16);
    ctx.queue.submit([encoder.finish()]);
    let bytes = map_read(ctx, &read)?;
    let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes);
    let [start, end] = ticks.as_slice() else {
        return Err(format!("expected 2 timestamps, got {ticks:?}"));
    };
    let elapsed_ns =
        (end.wrapping_sub(*start)) as f64 * f64::from(ctx.features.timestamp_period_ns);
    if *start == 0 || end < start || elapsed_ns > 10e9 {
        return Err(format!(
            "timestamps {start} → {end} ({elapsed_ns} ns) are not a plausible pass duration"
        ));
    }
    println!("    timed 1024² clear pass: {:.3} ms", elapsed_ns / 1e6);
    Ok(())
}

/// Maps `buffer` for reading, waits, and copies its bytes out.
pub(crate) fn map_read(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, String> {
    let (sender, receiver) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = sender.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| e.to_string())?;
    receiver
        .recv()
        .map_err(|e| e.to_string())?
        .map_err(|e| e.to_string())?;
    let bytes = buffer
        .get_mapped_range(..)
        .map_err(|e| e.to_string())?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}
