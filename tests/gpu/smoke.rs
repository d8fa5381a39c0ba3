//! Smoke tests: the device clears, rasterises and reads back exactly, and the texture-array-batching mechanics
//! (multi_draw_indexed_indirect, first_instance ≠ 0, per-draw layer from a storage buffer) work on this machine.

use atlastree::gpu::{GpuContext, readback_rgba8};
use atlastree::render::wgsl::smoke_tab::{self, DrawData, binding};
use wgpu::util::DeviceExt;

use crate::harness::GpuTest;

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "smoke::clear_readback_exact_bytes",
            run: clear_readback_exact_bytes,
        },
        GpuTest {
            name: "smoke::triangle_matches_cpu_rasterisation",
            run: triangle_matches_cpu_rasterisation,
        },
        GpuTest {
            name: "smoke::multi_draw_indirect_first_instance_selects_layer",
            run: multi_draw_indirect_first_instance_selects_layer,
        },
    ]
}

const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// An offscreen RGBA8 render target that can be read back.
fn make_target(ctx: &GpuContext, width: u32, height: u32) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("smoke target"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// A clear colour from exact 8-bit values, so the stored bytes are known exactly.
fn color_of(rgba: [u8; 4]) -> wgpu::Color {
    let c = |v: u8| f64::from(v) / 255.0;
    wgpu::Color {
        r: c(rgba[0]),
        g: c(rgba[1]),
        b: c(rgba[2]),
        a: c(rgba[3]),
    }
}

fn clear_attachment(
    view: &wgpu::TextureView,
    clear: [u8; 4],
) -> wgpu::RenderPassColorAttachment<'_> {
    wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(color_of(clear)),
            store: wgpu::StoreOp::Store,
        },
    }
}

fn pass_descriptor<'a>(
    attachments: &'a [Option<wgpu::RenderPassColorAttachment<'a>>],
) -> wgpu::RenderPassDescriptor<'a> {
    wgpu::RenderPassDescriptor {
        label: Some("smoke pass"),
        color_attachments: attachments,
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    }
}

/// RGBA of pixel (x, y) of a tightly packed readback.
fn pixel(bytes: &[u8], width: u32, x: u32, y: u32) -> Result<[u8; 4], String> {
    let i = ((y as usize) * (width as usize) + x as usize) * 4;
    bytes
        .get(i..i + 4)
        .and_then(|s| <[u8; 4]>::try_from(s).ok())
        .ok_or_else(|| format!("pixel ({x}, {y}) outside readback of {} bytes", bytes.len()))
}

/// Pixel-centre position of pixel (x, y) in clip space (y up), for a `width × height` target.
fn pixel_centre_ndc(x: u32, y: u32, width: u32, height: u32) -> [f64; 2] {
    [
        (f64::from(x) + 0.5) / f64::from(width) * 2.0 - 1.0,
        1.0 - (f64::from(y) + 0.5) / f64::from(height) * 2.0,
    ]
}

fn pipeline(
    ctx: &GpuContext,
    shader: &wgpu::ShaderModule,
    layout: Option<&wgpu::PipelineLayout>,
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
) -> wgpu::RenderPipeline {
    ctx.device
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("smoke pipeline"),
            layout,
            vertex: wgpu::VertexState {
                module: shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers,
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: shader,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
}

fn shader(ctx: &GpuContext, label: &str, source: &'static str) -> wgpu::ShaderModule {
    ctx.device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        })
}

/// Clears a 37×23 target (row pitch 148 B, padded to 256 B) to (51, 102, 153, 255) and expects those bytes in
/// every texel: proves clear, copy, row unpadding and the unorm byte order.
fn clear_readback_exact_bytes(ctx: &GpuContext) -> Result<(), String> {
    const CLEAR: [u8; 4] = [51, 102, 153, 255];
    let (width, height) = (37, 23);
    let target = make_target(ctx, width, height);
    let view = target.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    let attachments = [Some(clear_attachment(&view, CLEAR))];
    drop(encoder.begin_render_pass(&pass_descriptor(&attachments)));
    ctx.queue.submit([encoder.finish()]);
    let bytes = readback_rgba8(ctx, &target).map_err(|e| e.to_string())?;
    let expected_len = (width * height * 4) as usize;
    if bytes.len() != expected_len {
        return Err(format!(
            "readback has {} bytes, expected {expected_len}",
            bytes.len()
        ));
    }
    let wrong = bytes.chunks_exact(4).filter(|px| *px != CLEAR).count();
    match wrong {
        0 => Ok(()),
        n => Err(format!(
            "{n} of {} texels differ from {CLEAR:?}; first: {:?}",
            width * height,
            pixel(&bytes, width, 0, 0)?
        )),
    }
}

/// Clip-space vertices and linear colours of the smoke triangle.
const TRI_POS: [[f64; 2]; 3] = [[-0.8, -0.8], [0.8, -0.6], [-0.2, 0.8]];
const TRI_COLOR: [[f64; 4]; 3] = [
    [1.0, 0.0, 0.0, 1.0],
    [0.0, 1.0, 0.0, 1.0],
    [0.0, 0.0, 1.0, 1.0],
];

/// Barycentric coordinates of `p` in the smoke triangle, computed in pixel space (so edge distances are pixels),
/// and the smallest distance of `p` to an edge in pixels (negative outside).
fn barycentric_px(p: [f64; 2], width: u32, height: u32) -> ([f64; 3], f64) {
    let to_px = |v: [f64; 2]| {
        [
            v[0] * f64::from(width) / 2.0,
            v[1] * f64::from(height) / 2.0,
        ]
    };
    let [a, b, c] = TRI_POS.map(to_px);
    let p = to_px(p);
    let edge = |u: [f64; 2], v: [f64; 2], q: [f64; 2]| {
        (v[0] - u[0]) * (q[1] - u[1]) - (v[1] - u[1]) * (q[0] - u[0])
    };
    let len = |u: [f64; 2], v: [f64; 2]| ((v[0] - u[0]).powi(2) + (v[1] - u[1]).powi(2)).sqrt();
    let area = edge(a, b, c);
    let (wa, wb, wc) = (edge(b, c, p), edge(c, a, p), edge(a, b, p));
    let sign = area.signum();
    let dist = (sign * wa / len(b, c))
        .min(sign * wb / len(c, a))
        .min(sign * wc / len(a, b));
    ([wa / area, wb / area, wc / area], dist)
}

/// Draws one triangle with per-vertex colours on black into a 50×40 target and compares every pixel whose centre
/// is more than 0.01 px from an edge with the CPU expectation: inside, the barycentric blend of the vertex colours
/// within ±2 of 255 per channel (interpolation and rounding); outside, exactly the clear colour.
fn triangle_matches_cpu_rasterisation(ctx: &GpuContext) -> Result<(), String> {
    const CLEAR: [u8; 4] = [0, 0, 0, 255];
    const TOLERANCE: i32 = 2;
    let (width, height) = (50, 40);
    let vertices: Vec<f32> = (0..3)
        .flat_map(|i| {
            let [x, y] = TRI_POS[i];
            let [r, g, b, a] = TRI_COLOR[i];
            [x, y, r, g, b, a].map(|v| v as f32)
        })
        .collect();
    let vertex_buffer = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("smoke triangle"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
    let module = shader(ctx, "smoke.wgsl", include_str!("../../shaders/smoke.wgsl"));
    let layout = wgpu::VertexBufferLayout {
        array_stride: 24,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32x4],
    };
    let pipeline = pipeline(ctx, &module, None, &[Some(layout)]);
    let target = make_target(ctx, width, height);
    let view = target.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let attachments = [Some(clear_attachment(&view, CLEAR))];
        let mut pass = encoder.begin_render_pass(&pass_descriptor(&attachments));
        pass.set_pipeline(&pipeline);
        pass.set_vertex_buffer(0, vertex_buffer.slice(..));
        pass.draw(0..3, 0..1);
    }
    ctx.queue.submit([encoder.finish()]);
    let bytes = readback_rgba8(ctx, &target).map_err(|e| e.to_string())?;

    let (mut inside, mut outside) = (0u32, 0u32);
    for y in 0..height {
        for x in 0..width {
            let (bary, dist) = barycentric_px(pixel_centre_ndc(x, y, width, height), width, height);
            let got = pixel(&bytes, width, x, y)?;
            if dist > 0.01 {
                inside += 1;
                let expected: [i32; 4] = std::array::from_fn(|c| {
                    let v: f64 = (0..3).map(|i| bary[i] * TRI_COLOR[i][c]).sum();
                    (v * 255.0).round() as i32
                });
                if (0..4).any(|c| (i32::from(got[c]) - expected[c]).abs() > TOLERANCE) {
                    return Err(format!(
                        "inside pixel ({x}, {y}): got {got:?}, expected {expected:?} ±{TOLERANCE}"
                    ));
                }
            } else if dist < -0.01 {
                outside += 1;
                if got != CLEAR {
                    return Err(format!(
                        "outside pixel ({x}, {y}): got {got:?}, expected clear {CLEAR:?}"
                    ));
                }
            }
        }
    }
    // Triangle area: 0.5·|cross| in NDC is 1.24 of 4 units → 31 % of 2000 pixels ≈ 620.
    if !(550..=690).contains(&inside) || outside < 1200 {
        return Err(format!(
            "coverage off: {inside} inside, {outside} outside of {}",
            width * height
        ));
    }
    Ok(())
}

/// Texel colours of the two solid layers of the smoke texture array.
const LAYER_COLORS: [[u8; 4]; 2] = [[200, 30, 40, 255], [20, 180, 60, 255]];

/// A 4×4, 2-layer RGBA8 texture array, layer i filled with `LAYER_COLORS[i]`.
fn make_layers(ctx: &GpuContext) -> wgpu::Texture {
    let size = wgpu::Extent3d {
        width: 4,
        height: 4,
        depth_or_array_layers: 2,
    };
    let texels: Vec<u8> = LAYER_COLORS.iter().flat_map(|c| c.repeat(16)).collect();
    ctx.device.create_texture_with_data(
        &ctx.queue,
        &wgpu::TextureDescriptor {
            label: Some("smoke layers"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &texels,
    )
}

fn tab_bind_group_layout(ctx: &GpuContext) -> wgpu::BindGroupLayout {
    let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    };
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("smoke tab"),
            entries: &[
                entry(
                    binding::DRAWS,
                    wgpu::ShaderStages::VERTEX,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    binding::ATLAS,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
                entry(
                    binding::ATLAS_SAMPLER,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                ),
            ],
        })
}

/// Two quads, each a record of one `multi_draw_indexed_indirect` call. Record 0 draws the left quad with
/// first_instance 0, record 1 the right quad with first_index 6, base_vertex 4 and first_instance 1. The per-draw
/// storage buffer maps instance 0 → layer 1 and instance 1 → layer 0, so the left quad must show layer 1's
/// colour and the right quad layer 0's. Without INDIRECT_FIRST_INSTANCE wgpu drops record 1 (right quad clear);
/// if `instance_index` ignored first_instance, the right quad would show layer 1 too.
fn multi_draw_indirect_first_instance_selects_layer(ctx: &GpuContext) -> Result<(), String> {
    const CLEAR: [u8; 4] = [0, 0, 0, 255];
    let (width, height) = (64, 32);
    if !ctx.features.indirect_first_instance || !ctx.features.multi_draw_indirect {
        return Err(format!("context lacks required features: {}", ctx.features));
    }
    // Quads in clip space: left x ∈ [-0.9, -0.1], right x ∈ [0.1, 0.9], both y ∈ [-0.8, 0.8]; (x, y, u, v).
    let quad = |x0: f32, x1: f32| {
        [
            [x0, -0.8, 0.0, 1.0],
            [x1, -0.8, 1.0, 1.0],
            [x1, 0.8, 1.0, 0.0],
            [x0, 0.8, 0.0, 0.0],
        ]
    };
    let vertices: Vec<[f32; 4]> = quad(-0.9, -0.1).into_iter().chain(quad(0.1, 0.9)).collect();
    let indices: [u32; 12] = [0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 3];
    let draw_layers = [1, 0].map(|layer| DrawData {
        layer,
        ..DrawData::default()
    });
    let records = [
        wgpu::util::DrawIndexedIndirectArgs {
            index_count: 6,
            instance_count: 1,
            first_index: 0,
            base_vertex: 0,
            first_instance: 0,
        },
        wgpu::util::DrawIndexedIndirectArgs {
            index_count: 6,
            instance_count: 1,
            first_index: 6,
            base_vertex: 4,
            first_instance: 1,
        },
    ];
    let indirect: Vec<u8> = records.iter().flat_map(|r| r.as_bytes().to_vec()).collect();
    let init = |label, contents: &[u8], usage| {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
    };
    let vertex_buffer = init(
        "tab vertices",
        bytemuck::cast_slice(&vertices),
        wgpu::BufferUsages::VERTEX,
    );
    let index_buffer = init(
        "tab indices",
        bytemuck::cast_slice(&indices),
        wgpu::BufferUsages::INDEX,
    );
    let draw_buffer = init(
        "tab draws",
        bytemuck::cast_slice(&draw_layers),
        wgpu::BufferUsages::STORAGE,
    );
    let indirect_buffer = init("tab indirect", &indirect, wgpu::BufferUsages::INDIRECT);

    let layers = make_layers(ctx);
    let layers_view = layers.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    let sampler = ctx
        .device
        .create_sampler(&wgpu::SamplerDescriptor::default());
    let bgl = tab_bind_group_layout(ctx);
    let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("smoke tab"),
        layout: &bgl,
        entries: &[
            wgpu::BindGroupEntry {
                binding: binding::DRAWS,
                resource: draw_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: binding::ATLAS,
                resource: wgpu::BindingResource::TextureView(&layers_view),
            },
            wgpu::BindGroupEntry {
                binding: binding::ATLAS_SAMPLER,
                resource: wgpu::BindingResource::Sampler(&sampler),
            },
        ],
    });
    let pipeline_layout = ctx
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("smoke tab"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
    let module = shader(ctx, "smoke_tab.wgsl", smoke_tab::WGSL);
    let layout = wgpu::VertexBufferLayout {
        array_stride: 16,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32x2],
    };
    let pipeline = pipeline(ctx, &module, Some(&pipeline_layout), &[Some(layout)]);

    let target = make_target(ctx, width, height);
    let view = target.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let attachments = [Some(clear_attachment(&view, CLEAR))];
        let mut pass = encoder.begin_render_pass(&pass_descriptor(&attachments));
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.set_vertex_buffer(0, vertex_buffer.slice(..));
        pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.multi_draw_indexed_indirect(&indirect_buffer, 0, 2);
    }
    ctx.queue.submit([encoder.finish()]);
    let bytes = readback_rgba8(ctx, &target).map_err(|e| e.to_string())?;

    let [layer0, layer1] = LAYER_COLORS;
    let mut counts = [0u32; 3]; // left, right, outside
    for y in 0..height {
        for x in 0..width {
            let [px, py] = pixel_centre_ndc(x, y, width, height);
            let in_y = py.abs() < 0.8;
            let (expected, slot) = if in_y && px > -0.9 && px < -0.1 {
                (layer1, 0)
            } else if in_y && px > 0.1 && px < 0.9 {
                (layer0, 1)
            } else {
                (CLEAR, 2)
            };
            let got = pixel(&bytes, width, x, y)?;
            if got != expected {
                let which = [
                    "left quad (record 0)",
                    "right quad (record 1, first_instance 1)",
                    "outside",
                ][slot];
                return Err(format!(
                    "pixel ({x}, {y}) in {which}: got {got:?}, expected {expected:?}"
                ));
            }
            counts[slot] += 1;
        }
    }
    // Each quad spans 0.8 of 2 NDC units: 25.6 of 64 columns and 25.6 of 32 rows; its edges fall at .2/.8 of a
    // pixel, so exactly 26 × 26 pixel centres lie inside.
    if counts[0] != 676 || counts[1] != 676 {
        return Err(format!(
            "quad pixel counts: left {}, right {}, expected 676 each",
            counts[0], counts[1]
        ));
    }
    Ok(())
}
