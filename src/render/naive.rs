//! The naive baseline for the frame-time comparison (`--mode original`): every distinct original texture is
//! its own `texture_2d`, every material drawing it its own bind group, and every (leaf, original texture)
//! pair of every visible leaf is one `draw_indexed` after one `set_bind_group`, sorted only by pass. Built
//! on first use.
//!
//! The draws are planned on the CPU as plain data ([`super::naive_batch`]); this module only creates the
//! GPU objects: the pipelines, one texture per distinct original, a sampler per wrap pair, a bind group
//! per (material, original) pair, the index buffer.

use super::RenderError;
use super::naive_batch::{NaiveDraw, NaiveTables, plan_naive};
use super::pipeline::{
    PassPipelines, Specialisation, naive_bind_group_layouts, sampler, vertex_layout,
};
use super::resident::{Resident, UniqueOriginal};
use super::textures::{gpu_format, rect_texels_for_upload, upload_mip_chain_rect};
use super::wgsl::naive::{self, ALPHA_OPAQUE, Material, binding};
use crate::gpu::GpuContext;
use crate::scene::Wrap;
use crate::store::TreeFile;
use crate::store::format::MaterialRecord;
use wgpu::util::DeviceExt;

pub(super) struct Naive {
    pub pipelines: PassPipelines,
    pub group0: wgpu::BindGroup,
    /// One per (material, distinct original texture) pair ([`NaiveDraw::texture`]).
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
    /// Plans the draws (CPU), then creates the pipelines, the per-original textures and bind groups and
    /// the index buffer.
    pub(super) fn new(
        ctx: &GpuContext,
        file: &TreeFile,
        res: &Resident,
        globals: &wgpu::Buffer,
        anisotropy: u16,
    ) -> Result<Naive, RenderError> {
        let plan = plan_naive(
            file,
            NaiveTables {
                infos: &res.infos,
                leaves: &res.leaves,
                tam: &res.tam,
                tam_material_original: &res.tam_material_original,
            },
        )?;
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
        let originals = Originals::upload(ctx, file, res, &l1, anisotropy)?;
        // An empty index buffer cannot be created: one degenerate quad's worth of zeros stands in.
        let indices: &[u32] = if plan.indices.is_empty() {
            &[0; 4]
        } else {
            &plan.indices
        };
        let index_buffer = super::resident::buffer(
            ctx,
            "naive indices",
            bytemuck::cast_slice(indices),
            wgpu::BufferUsages::INDEX,
        )?;
        Ok(Naive {
            pipelines,
            group0,
            groups: originals.groups,
            index_buffer,
            draws: plan.draws,
            leaf_draws: plan.leaf_draws,
            _textures: originals.textures,
            _uniforms: originals.uniforms,
        })
    }
}

/// The GPU objects of the distinct originals: a texture per `Resident::uniques` entry, a uniform and bind
/// group per `Resident::material_originals` entry, in those orders.
struct Originals {
    textures: Vec<wgpu::Texture>,
    uniforms: Vec<wgpu::Buffer>,
    groups: Vec<wgpu::BindGroup>,
}

impl Originals {
    fn upload(
        ctx: &GpuContext,
        file: &TreeFile,
        res: &Resident,
        layout: &wgpu::BindGroupLayout,
        anisotropy: u16,
    ) -> Result<Originals, RenderError> {
        let device = &ctx.device;
        let pairs = &res.material_originals;
        let mut out = Originals {
            textures: Vec::with_capacity(res.uniques.len()),
            uniforms: Vec::with_capacity(pairs.len()),
            groups: Vec::with_capacity(pairs.len()),
        };
        let mut views = Vec::with_capacity(res.uniques.len());
        for u in &res.uniques {
            let tex = upload_original(ctx, file, u)?;
            views.push(tex.create_view(&wgpu::TextureViewDescriptor::default()));
            out.textures.push(tex);
        }
        // One sampler per distinct pair of wrap modes.
        let mut samplers: Vec<([Wrap; 2], wgpu::Sampler)> = Vec::new();
        for pair in pairs {
            let m = res.materials.get(pair.material as usize).copied();
            let wrap = m.and_then(|m| m.wraps()).unwrap_or([Wrap::Repeat; 2]);
            // `gather_tables` made each pair after the unique it names.
            let view = &views[pair.unique as usize];
            let s = match samplers.iter().position(|(w, _)| *w == wrap) {
                Some(i) => i,
                None => {
                    let addr = [address(wrap[0]), address(wrap[1])];
                    samplers.push((wrap, sampler(device, "naive sampler", addr, anisotropy)));
                    samplers.len() - 1
                }
            };
            let ub = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("naive material"),
                contents: bytemuck::bytes_of(&material(m)),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            out.groups
                .push(device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("naive group 1"),
                    layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: binding::TEX,
                            resource: wgpu::BindingResource::TextureView(view),
                        },
                        wgpu::BindGroupEntry {
                            binding: binding::TEX_SAMPLER,
                            resource: wgpu::BindingResource::Sampler(&samplers[s].1),
                        },
                        wgpu::BindGroupEntry {
                            binding: binding::MATERIAL,
                            resource: ub.as_entire_binding(),
                        },
                    ],
                }));
            out.uniforms.push(ub);
        }
        Ok(out)
    }
}

/// The shader's material block of `m` (opaque white without a record).
fn material(m: Option<MaterialRecord>) -> Material {
    Material {
        factor: m.map_or([1.0; 4], |m| m.base_color_factor),
        alpha_mode: m.map_or(ALPHA_OPAQUE, |m| m.alpha_mode),
        cutoff: m.map_or(0.5, |m| m.alpha_cutoff),
        _p0: 0,
        _p1: 0,
    }
}

/// One distinct original as its own mip-mapped `texture_2d`, its chain read from its block.
fn upload_original(
    ctx: &GpuContext,
    file: &TreeFile,
    u: &UniqueOriginal,
) -> Result<wgpu::Texture, RenderError> {
    let target = gpu_format(u.format, ctx.features.texture_compression_bc);
    let tex = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("naive original"),
        size: wgpu::Extent3d {
            width: u.extent[0],
            height: u.extent[1],
            depth_or_array_layers: 1,
        },
        mip_level_count: crate::texfmt::mip_level_count(u.extent[0].max(u.extent[1])),
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: target.wgpu_format(),
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let short = || RenderError::ShortBlock { block: u.block };
    let bytes = file.block(u.block)?;
    let chain = usize::try_from(u.offset)
        .ok()
        .and_then(|o| bytes.get(o..))
        .ok_or_else(short)?;
    let texels = rect_texels_for_upload(u.format, chain, u.extent, target).ok_or_else(short)?;
    upload_mip_chain_rect(&ctx.queue, &tex, u.extent, 0, &texels, target).ok_or_else(short)?;
    Ok(tex)
}
