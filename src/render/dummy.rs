//! The paper's dummy baseline (`--mode dummy`, BD05 §7): the tree's frame with its texturing taken out.
//! The same cut, indirect records, passes (the depth pre-pass of blend nodes included) and one
//! `multi_draw_indexed_indirect` per pipeline as mode tree, drawn by `shaders/dummy.wgsl`: one ordinary
//! texture sampled at the vertex UV, nothing else per fragment. Built on first use.

use super::pipeline::{PassPipelines, Specialisation, sampler, vertex_layout};
use super::wgsl::dummy::{self, binding};
use wgpu::util::DeviceExt;

/// Side of the dummy's one texture (a full mip chain, like an atlas of the smallest size).
pub const DUMMY_TEXTURE_SIZE: u32 = 256;

/// The dummy's pipelines, texture and bind group.
pub(super) struct Dummy {
    pub pipelines: PassPipelines,
    layout: wgpu::BindGroupLayout,
    view: wgpu::TextureView,
    sampler: wgpu::Sampler,
    _texture: wgpu::Texture,
    /// Over the renderer's buffers; dropped ([`Dummy::buffers_replaced`]) when it replaces one.
    pub group: Option<wgpu::BindGroup>,
}

/// The dummy texture's mip chain: a grey 8 × 8 checker at mip 0, each further level the 2 × 2 mean of the
/// one above (sRGB bytes; what it shows does not matter, only that sampling it is one trilinear fetch).
pub fn dummy_texture_chain(size: u32) -> Vec<u8> {
    let mut level: Vec<u8> = Vec::with_capacity((size * size * 4) as usize);
    let cell = (size / 8).max(1);
    for y in 0..size {
        for x in 0..size {
            let v = if (x / cell + y / cell).is_multiple_of(2) {
                200
            } else {
                120
            };
            level.extend_from_slice(&[v, v, v, 255]);
        }
    }
    let mut chain = level.clone();
    let mut s = size;
    while s > 1 {
        let h = s / 2;
        let mut next = vec![0u8; (h * h * 4) as usize];
        for y in 0..h {
            for x in 0..h {
                for c in 0..4 {
                    let at = |dx: u32, dy: u32| {
                        u32::from(level[(((2 * y + dy) * s + 2 * x + dx) * 4 + c) as usize])
                    };
                    let sum = at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1);
                    next[((y * h + x) * 4 + c) as usize] = ((sum + 2) / 4) as u8;
                }
            }
        }
        chain.extend_from_slice(&next);
        level = next;
        s = h;
    }
    chain
}

impl Dummy {
    pub(super) fn new(ctx: &crate::gpu::GpuContext, anisotropy: u16) -> Dummy {
        let device = &ctx.device;
        let layout = dummy_bind_group_layout(device);
        let pipelines = PassPipelines::new(
            device,
            "dummy",
            dummy::WGSL,
            &[&layout],
            vertex_layout(),
            Specialisation::default(),
        );
        let size = DUMMY_TEXTURE_SIZE;
        let texture = device.create_texture_with_data(
            &ctx.queue,
            &wgpu::TextureDescriptor {
                label: Some("dummy texture"),
                size: wgpu::Extent3d {
                    width: size,
                    height: size,
                    depth_or_array_layers: 1,
                },
                mip_level_count: crate::texfmt::mip_level_count(size),
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8UnormSrgb,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            &dummy_texture_chain(size),
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let repeat = [wgpu::AddressMode::Repeat; 2];
        Dummy {
            pipelines,
            layout,
            view,
            sampler: sampler(device, "dummy sampler", repeat, anisotropy),
            _texture: texture,
            group: None,
        }
    }

    /// The renderer replaced a buffer the bind group names (its records buffer grew).
    pub(super) fn buffers_replaced(&mut self) {
        self.group = None;
    }

    /// Makes the bind group over the renderer's `globals`, `records` and `offsets` buffers if there is none.
    pub(super) fn prepare(
        &mut self,
        device: &wgpu::Device,
        globals: &wgpu::Buffer,
        records: &wgpu::Buffer,
        offsets: &wgpu::Buffer,
    ) {
        let (layout, view, sampler) = (&self.layout, &self.view, &self.sampler);
        self.group.get_or_insert_with(|| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("dummy frame"),
                layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: binding::GLOBALS,
                        resource: globals.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::DRAWS,
                        resource: records.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::OFFSETS,
                        resource: offsets.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::TEX,
                        resource: wgpu::BindingResource::TextureView(view),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::TEX_SAMPLER,
                        resource: wgpu::BindingResource::Sampler(sampler),
                    },
                ],
            })
        });
    }
}

/// Group 0 of `dummy.wgsl` ([`binding`]).
fn dummy_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    };
    let buffer = |ty| wgpu::BindingType::Buffer {
        ty,
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let storage = buffer(wgpu::BufferBindingType::Storage { read_only: true });
    use wgpu::ShaderStages as S;
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("dummy group 0"),
        entries: &[
            entry(
                binding::GLOBALS,
                S::VERTEX_FRAGMENT,
                buffer(wgpu::BufferBindingType::Uniform),
            ),
            entry(binding::DRAWS, S::VERTEX, storage),
            entry(binding::OFFSETS, S::VERTEX, storage),
            entry(
                binding::TEX,
                S::FRAGMENT,
                wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
            ),
            entry(
                binding::TEX_SAMPLER,
                S::FRAGMENT,
                wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            ),
        ],
    })
}
