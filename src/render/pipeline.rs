//! Bind group layouts, samplers and render pipelines of the tree renderer (`shaders/tree.wgsl`) and of the
//! naive baseline (`shaders/naive.wgsl`). The opaque pipeline always exists; the alpha-mask and alpha-blend
//! pipelines are created on first use (only files with an alpha tree need them).

use super::batch::{GROUPS, Group, Pass, VERTEX_STRIDE};
use super::textures::{CLASS_COUNT, MAX_ATLAS_ARRAYS};
use super::wgsl::{naive, tree};

/// Colour target format: sRGB, so the shaders work in linear light and the PNGs hold sRGB bytes.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Target format of the texel-density debug pipelines (`DENSITY = 1`, see [`super::density`]): not
/// blendable, and those pipelines do not blend.
pub const DENSITY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Depth format; reverse Z (clear 0, compare Greater) for precision at large depth ranges.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// pos, orig_uv, leaf, original, rect (the fields of `TreeVertex` in order).
const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 5] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x2, 2 => Uint32, 3 => Uint32, 4 => Uint32
];

/// Vertex buffer layout of `TreeVertex`.
pub fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    wgpu::VertexBufferLayout {
        array_stride: VERTEX_STRIDE,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &VERTEX_ATTRIBUTES,
    }
}

fn entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    }
}

fn storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn filtering() -> wgpu::BindingType {
    wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)
}

fn uniform() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn texture(dim: wgpu::TextureViewDimension) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: true },
        view_dimension: dim,
        multisampled: false,
    }
}

const VF: wgpu::ShaderStages = wgpu::ShaderStages::VERTEX_FRAGMENT;
const V: wgpu::ShaderStages = wgpu::ShaderStages::VERTEX;
const F: wgpu::ShaderStages = wgpu::ShaderStages::FRAGMENT;

/// Group 0 of `tree.wgsl` ([`tree::binding`]).
pub fn tree_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    use tree::binding as b;
    let mut entries = vec![
        entry(b::GLOBALS, VF, uniform()),
        entry(b::DRAWS, V, storage()),
        entry(b::LEAVES, V, storage()),
        entry(b::OFFSETS, V, storage()),
        entry(b::TAM, VF, storage()),
        entry(b::RECTS, VF, storage()),
        entry(b::ATLAS_SAMPLER, F, filtering()),
        entry(b::ORIGINAL_SAMPLER, F, filtering()),
    ];
    // The class bindings follow the atlas bindings.
    for i in 0..(MAX_ATLAS_ARRAYS + CLASS_COUNT) as u32 {
        entries.push(entry(
            b::ATLAS0 + i,
            F,
            texture(wgpu::TextureViewDimension::D2Array),
        ));
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("tree group 0"),
        entries: &entries,
    })
}

/// Group 0 (globals, leaf offsets) and group 1 (texture, sampler, material) of `naive.wgsl`
/// ([`naive::binding`]).
pub fn naive_bind_group_layouts(device: &wgpu::Device) -> [wgpu::BindGroupLayout; 2] {
    use naive::binding as b;
    let g0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("naive group 0"),
        entries: &[
            entry(b::GLOBALS, VF, uniform()),
            entry(b::OFFSETS, V, storage()),
        ],
    });
    let g1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("naive group 1"),
        entries: &[
            entry(b::TEX, F, texture(wgpu::TextureViewDimension::D2)),
            entry(
                b::TEX_SAMPLER,
                F,
                wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            ),
            entry(b::MATERIAL, F, uniform()),
        ],
    });
    [g0, g1]
}

/// A trilinear sampler with the given address modes and anisotropy clamp (1 = isotropic; see
/// [`super::RendererOptions::anisotropy`]).
pub fn sampler(
    device: &wgpu::Device,
    label: &str,
    address: [wgpu::AddressMode; 2],
    anisotropy: u16,
) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some(label),
        address_mode_u: address[0],
        address_mode_v: address[1],
        address_mode_w: wgpu::AddressMode::ClampToEdge,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        anisotropy_clamp: anisotropy.clamp(1, 16),
        ..Default::default()
    })
}

/// How a shader is specialised per [`Group`] (WGSL `override` constants; `tree.wgsl` and `naive.wgsl`
/// both have `PASS`, [`tree::overrides`], [`naive::overrides`]).
#[derive(Clone, Debug, Default)]
pub struct Specialisation {
    /// Constants every pipeline gets (besides `PASS`).
    pub constants: Vec<(&'static str, f64)>,
    /// The shader has `override SOURCE` ([`tree::SOURCE_ATLAS`], [`tree::SOURCE_ORIGINAL`]) and `override
    /// ATLAS_ARRAY` ([`Group::array`]).
    pub source: bool,
    /// The texel-density variant: `DENSITY` = [`tree::DENSITY_ON`], target [`DENSITY_FORMAT`], no
    /// blending.
    pub density: bool,
}

/// The pipelines of one shader, one per [`Group`], each created on first use (opaque atlas eagerly).
pub struct PassPipelines {
    label: &'static str,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    vertex: wgpu::VertexBufferLayout<'static>,
    spec: Specialisation,
    pipelines: [Option<wgpu::RenderPipeline>; GROUPS],
}

impl PassPipelines {
    /// Compiles `source` and creates the opaque pipeline.
    pub fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &'static str,
        groups: &[&wgpu::BindGroupLayout],
        vertex: wgpu::VertexBufferLayout<'static>,
        spec: Specialisation,
    ) -> PassPipelines {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let groups: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(|g| Some(*g)).collect();
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
        let mut p = PassPipelines {
            label,
            module,
            layout,
            vertex,
            spec,
            pipelines: Default::default(),
        };
        p.get(device, Group::new(Pass::Opaque, false));
        p
    }

    /// The group whose pipeline `group` draws with: itself, or for a shader without the `SOURCE` and
    /// `ATLAS_ARRAY` overrides (the dummy) the same pass and source on atlas array 0 (one pipeline for
    /// every array).
    fn key(&self, group: Group) -> Group {
        if self.spec.source {
            group
        } else {
            Group::new(group.pass, group.original)
        }
    }

    /// The pipeline of `group` if it was created.
    pub fn existing(&self, group: Group) -> Option<&wgpu::RenderPipeline> {
        self.pipelines[self.key(group).index()].as_ref()
    }

    /// The pipeline of `group`, created on first use.
    pub fn get(&mut self, device: &wgpu::Device, group: Group) -> &wgpu::RenderPipeline {
        let group = self.key(group);
        let slot = &mut self.pipelines[group.index()];
        let spec = &self.spec;
        slot.get_or_insert_with(|| {
            create_pipeline(
                device,
                self.label,
                &self.module,
                &self.layout,
                &self.vertex,
                group,
                spec,
            )
        })
    }
}

fn create_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    vertex: &wgpu::VertexBufferLayout<'static>,
    group: Group,
    spec: &Specialisation,
) -> wgpu::RenderPipeline {
    let mut constants = spec.constants.clone();
    constants.push((tree::overrides::PASS, f64::from(group.pass as u32)));
    if spec.source {
        let source = if group.original {
            tree::SOURCE_ORIGINAL
        } else {
            tree::SOURCE_ATLAS
        };
        constants.push((tree::overrides::SOURCE, f64::from(source)));
        constants.push((tree::overrides::ATLAS_ARRAY, f64::from(group.array)));
    }
    if spec.density {
        constants.push((tree::overrides::DENSITY, f64::from(tree::DENSITY_ON)));
    }
    let (pass, density) = (group.pass, spec.density);
    let blend = (pass == Pass::Blend && !density).then_some(wgpu::BlendState::ALPHA_BLENDING);
    let format = if density {
        DENSITY_FORMAT
    } else {
        COLOR_FORMAT
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            },
            buffers: &[Some(vertex.clone())],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(pass != Pass::Blend),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            },
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}
