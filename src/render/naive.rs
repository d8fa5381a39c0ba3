//! The naive baseline for the frame-time comparison (`--mode original`): every distinct original texture is
//! its own `texture_2d` with its own bind group, and every (leaf, original texture) pair of every visible
//! leaf is one `draw_indexed` after one `set_bind_group`, sorted only by pass. Built on first use.

use super::RenderError;
use super::batch::Pass;
use super::pipeline::{
    PassPipelines, Specialisation, naive_bind_group_layouts, sampler, vertex_layout,
};
use super::resident::Resident;
use super::textures::{gpu_format, mip_levels, rect_texels_for_upload, upload_mip_chain_rect};
use super::wgsl::naive::{self, ALPHA_MASK, ALPHA_OPAQUE, Material, binding};
use crate::gpu::GpuContext;
use crate::scene::Wrap;
use crate::store::TreeFile;
use wgpu::util::DeviceExt;

/// One draw: a leaf's triangles that use one original texture.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct NaiveDraw {
    pub first_index: u32,
    pub index_count: u32,
    pub base_vertex: i32,
    /// First instance = the tree's leaf base (the shader adds the vertex's tree-local leaf).
    pub leaf_base: u32,
    /// Index into the unique textures (bind groups).
    pub texture: u32,
    pub pass: Pass,
}

pub struct Naive {
    pub pipelines: PassPipelines,
    pub group0: wgpu::BindGroup,
    pub groups: Vec<wgpu::BindGroup>,
    pub index_buffer: wgpu::Buffer,
    pub draws: Vec<NaiveDraw>,
    /// Per global leaf: its draws `[first, first + count)` in `draws`.
    pub leaf_draws: Vec<(u32, u32)>,
    _textures: Vec<wgpu::Texture>,
    _uniforms: Vec<wgpu::Buffer>,
}

fn address(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::MirroredRepeat => wgpu::AddressMode::MirrorRepeat,
        Wrap::ClampToEdge => wgpu::AddressMode::ClampToEdge,
    }
}

impl Naive {
    pub fn new(
        ctx: &GpuContext,
        file: &TreeFile,
        res: &Resident,
        globals: &wgpu::Buffer,
        anisotropy: u16,
    ) -> Result<Naive, RenderError> {
        let device = &ctx.device;
        let [l0, l1] = naive_bind_group_layouts(device);
        let pipelines = PassPipelines::new(
            device,
            "naive",
            naive::WGSL,
            &[&l0, &l1],
            vertex_layout(),
            Specialisation::default(),
        );
        let group0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("naive group 0"),
            layout: &l0,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: binding::GLOBALS,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: binding::OFFSETS,
                    resource: res.offsets_buffer.as_entire_binding(),
                },
            ],
        });

        // One texture, sampler and bind group per distinct original.
        let mut textures = Vec::new();
        let mut uniforms = Vec::new();
        let mut groups = Vec::new();
        let mut samplers: Vec<([Wrap; 2], wgpu::Sampler)> = Vec::new();
        for u in &res.uniques {
            let m = res.materials.get(u.material as usize).copied();
            let target = gpu_format(u.format, ctx.features.texture_compression_bc);
            let wrap = m.and_then(|m| m.wraps()).unwrap_or([Wrap::Repeat; 2]);
            let tex = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("naive original"),
                size: wgpu::Extent3d {
                    width: u.extent[0],
                    height: u.extent[1],
                    depth_or_array_layers: 1,
                },
                mip_level_count: mip_levels(u.extent[0].max(u.extent[1])),
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: target.wgpu_format(),
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let bytes = file.block(u.block)?;
            let chain = usize::try_from(u.offset)
                .ok()
                .and_then(|o| bytes.get(o..))
                .ok_or(RenderError::ShortBlock { block: u.block })?;
            let texels = rect_texels_for_upload(u.format, chain, u.extent, target)
                .ok_or(RenderError::ShortBlock { block: u.block })?;
            upload_mip_chain_rect(&ctx.queue, &tex, u.extent, 0, &texels, target)
                .ok_or(RenderError::ShortBlock { block: u.block })?;
            let view = tex.create_view(&wgpu::TextureViewDescriptor::default());
            if !samplers.iter().any(|(w, _)| *w == wrap) {
                let s = sampler(
                    device,
                    "naive sampler",
                    [address(wrap[0]), address(wrap[1])],
                    anisotropy,
                );
                samplers.push((wrap, s));
            }
            let s = &samplers.iter().find(|(w, _)| *w == wrap).map(|(_, s)| s);
            let params = Material {
                factor: m.map_or([1.0; 4], |m| m.base_color_factor),
                alpha_mode: m.map_or(ALPHA_OPAQUE, |m| m.alpha_mode),
                cutoff: m.map_or(0.5, |m| m.alpha_cutoff),
                _p0: 0,
                _p1: 0,
            };
            let ub = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("naive material"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let Some(s) = s else { continue };
            groups.push(device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("naive group 1"),
                layout: &l1,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: binding::TEX,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::TEX_SAMPLER,
                        resource: wgpu::BindingResource::Sampler(s),
                    },
                    wgpu::BindGroupEntry {
                        binding: binding::MATERIAL,
                        resource: ub.as_entire_binding(),
                    },
                ],
            }));
            textures.push(tex);
            uniforms.push(ub);
        }

        // Indices regrouped per (leaf, original).
        let mut indices: Vec<u32> = Vec::new();
        let mut draws = Vec::new();
        let mut leaf_draws = Vec::new();
        for (t, info) in res.infos.iter().enumerate() {
            let view = file.tree(t).ok_or(RenderError::MissingTree { tree: t })?;
            for (li, leaf) in view.leaves.iter().enumerate() {
                let first = leaf.first_index as usize;
                let tri_indices = view
                    .indices
                    .get(first..first.saturating_add(leaf.index_count as usize))
                    .unwrap_or(&[]);
                let global_leaf = info.leaf_base as usize + li;
                let first_tam = res
                    .tam
                    .len()
                    .min(global_first_tam(res, global_leaf) as usize);
                let start = draws.len() as u32;
                for o in 0..leaf.original_count {
                    let first_index = indices.len() as u32;
                    for tri in tri_indices.chunks_exact(3) {
                        let v = view.vertices.get(tri[0] as usize);
                        if v.is_some_and(|v| v.original == o) {
                            indices.extend_from_slice(tri);
                        }
                    }
                    let count = indices.len() as u32 - first_index;
                    let tam_i = first_tam + o as usize;
                    let (Some(&unique), Some(e)) = (res.tam_unique.get(tam_i), res.tam.get(tam_i))
                    else {
                        continue;
                    };
                    if count == 0 {
                        continue;
                    }
                    let pass = match e.alpha_mode {
                        ALPHA_OPAQUE => Pass::Opaque,
                        ALPHA_MASK => Pass::Mask,
                        _ => Pass::Blend,
                    };
                    draws.push(NaiveDraw {
                        first_index,
                        index_count: count,
                        base_vertex: info.vertex_base,
                        leaf_base: info.leaf_base,
                        texture: unique,
                        pass,
                    });
                }
                leaf_draws.push((start, draws.len() as u32 - start));
            }
        }
        if indices.is_empty() {
            indices.extend_from_slice(&[0, 0, 0, 0]);
        }
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("naive indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        Ok(Naive {
            pipelines,
            group0,
            groups,
            index_buffer,
            draws,
            leaf_draws,
            _textures: textures,
            _uniforms: uniforms,
        })
    }
}

fn global_first_tam(res: &Resident, global_leaf: usize) -> u32 {
    res.leaves
        .get(global_leaf)
        .map_or(u32::MAX, |l| l.first_tam)
}
