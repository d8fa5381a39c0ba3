//! The renderer: executes a [`FramePlan`] (batch → upload → one render pass) and counts what it did. It
//! owns pipelines, residency (texture arrays, geometry) and targets; what to draw is decided by the
//! [`FramePlanner`].

use super::batch::FrameBatch;
use super::density::{DensityFrame, DensityTarget};
use super::dummy::Dummy;
use super::naive::Naive;
use super::pipeline::{
    COLOR_FORMAT, DEPTH_FORMAT, PassPipelines, Specialisation, sampler, tree_bind_group_layout,
    vertex_layout,
};
use super::reference::Supersample;
use super::resident::Resident;
use super::textures::{CLASS_COUNT, MAX_ATLAS_ARRAYS};
use super::wgsl::tree::{self, Globals, MODE_LEVELS, MODE_TEXTURED};
use super::{Mode, RenderError};
use crate::camera::Camera;
use crate::gpu::{GpuContext, readback_rgba8};
use crate::paging::{Event, ResidencyError};
use crate::plan::{FramePlan, FramePlanner, PagingFrame, PlanError, PlanStats, Residency};
use crate::report::columns::{self, Column};
use crate::store::TreeFile;
use glam::{DMat4, DVec4};
use std::time::Instant;

/// Counters and timings of one frame: the plan's counters as the planner made them ([`PlanStats`], held,
/// not copied) and what the renderer did with the plan. The CSV columns of every per-frame table come
/// from [`crate::report::columns`].
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// The executed plan's counters: nodes visited and drawn, select and paging time, paging counters.
    pub plan: PlanStats,
    /// Indirect records submitted (tree modes) — 0 in original mode.
    pub indirect_records: u32,
    /// Records drawn with original textures (tree modes).
    pub original_records: u32,
    /// API draw calls (`multi_draw_indexed_indirect` counts once).
    pub draw_calls: u32,
    /// `set_bind_group` calls.
    pub bind_group_changes: u32,
    /// `set_pipeline` calls.
    pub pipeline_changes: u32,
    pub triangles: u64,
    /// CPU time of batching, uploads and command encoding, µs.
    pub encode_us: f64,
    /// GPU time of the render pass from timestamp queries, ms (`None` without timestamp support).
    pub gpu_ms: Option<f64>,
    /// Wall time from the start of select to the GPU having finished the frame, ms.
    pub frame_ms: f64,
    /// Cut items the batch could not draw: their resolved atlas (or original texture) holds no GPU layer.
    /// Always 0 while the planner's residency and the GPU's agree; counted, never silently dropped.
    pub skipped_draws: u32,
    /// Layers in use in the atlas arrays and the original-texture arrays after the frame.
    pub atlas_layers_used: u32,
    pub original_layers_used: u32,
}

impl FrameStats {
    /// Paging counters of the plan (`None` when all blocks are resident).
    pub fn paging(&self) -> Option<&PagingFrame> {
        self.plan.paging.as_ref()
    }
}

/// The renderer's [`Residency`]: a plan's residency changes become uploads into (and frees of) the
/// texture arrays. A change that cannot be applied is an error the planner counts and takes back.
pub struct GpuResidency<'r> {
    resident: &'r mut Resident,
    queue: &'r wgpu::Queue,
}

impl Residency for GpuResidency<'_> {
    fn apply(&mut self, event: &Event) -> Result<u64, ResidencyError> {
        self.resident
            .apply(self.queue, event)
            .map_err(ResidencyError::from)
    }
}

/// Options of a [`Renderer`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RendererOptions {
    pub width: u32,
    pub height: u32,
    /// Measure GPU time with timestamp queries where supported (adds a readback per frame).
    pub gpu_timing: bool,
    /// Anisotropy clamp of every sampler, 1 (isotropic trilinear) to 16, or [`RendererOptions::AUTO`];
    /// 1 where the device lacks anisotropic filtering. A software rasteriser pays per tap: an
    /// accuracy-for-time knob.
    pub anisotropy: u16,
}

impl RendererOptions {
    /// `width × height` pixels with the defaults: no GPU timing, anisotropy [`RendererOptions::ANISOTROPY`].
    pub fn sized(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            gpu_timing: false,
            anisotropy: Self::ANISOTROPY,
        }
    }

    /// Anisotropy chosen for the device: 16 (the best every desktop GPU offers) on a hardware GPU, 1 on a
    /// software rasteriser. Atlas draws sample with explicit gradients (the UV is wrapped into its rect per
    /// fragment, so implicit derivatives would jump at every seam), and lavapipe's anisotropic path with
    /// explicit gradients costs two orders of magnitude more per pixel than its isotropic one (an overview
    /// of a SuperTuxKart track at 400×300: 57 s against 0.15 s per frame); an explicit `--anisotropy 16`
    /// still gets it.
    pub const AUTO: u16 = 0;
    /// The default: [`RendererOptions::AUTO`].
    pub const ANISOTROPY: u16 = RendererOptions::AUTO;

    /// `anisotropy` as the device applies it: [`RendererOptions::AUTO`] resolved, clamped to 1..=16, and 1
    /// without anisotropic filtering.
    pub fn device_anisotropy(&self, ctx: &GpuContext) -> u16 {
        if !ctx.features.anisotropic_filtering {
            1
        } else if self.anisotropy == RendererOptions::AUTO {
            if ctx.info.is_software() { 1 } else { 16 }
        } else {
            self.anisotropy.clamp(1, 16)
        }
    }
}

/// A GPU-side growable buffer.
pub(super) struct Growable {
    pub(super) buffer: wgpu::Buffer,
    pub(super) capacity: u64,
    pub(super) usage: wgpu::BufferUsages,
    pub(super) label: &'static str,
}

impl Growable {
    fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> Growable {
        let capacity = 4096;
        Growable {
            buffer: make_buffer(device, label, capacity, usage),
            capacity,
            usage,
            label,
        }
    }

    /// Writes `data`, growing (power of two) first if needed; returns true when the buffer was replaced.
    pub(super) fn write(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        data: &[u8],
    ) -> bool {
        let mut grew = false;
        if data.len() as u64 > self.capacity {
            self.capacity = (data.len() as u64).next_power_of_two();
            self.buffer = make_buffer(device, self.label, self.capacity, self.usage);
            grew = true;
        }
        if !data.is_empty() {
            queue.write_buffer(&self.buffer, 0, data);
        }
        grew
    }
}

fn make_buffer(
    device: &wgpu::Device,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

pub(super) struct Timestamps {
    pub(super) set: wgpu::QuerySet,
    pub(super) resolve: wgpu::Buffer,
    pub(super) read: wgpu::Buffer,
    pub(super) period_ns: f64,
}

/// Renders frames of one paging file into an offscreen target.
pub struct Renderer<'f> {
    pub(super) ctx: &'f GpuContext,
    pub(super) file: &'f TreeFile,
    /// The node tables of every tree, copied at the start (`plan::file_trees_copied`): each frame's
    /// draws are made from them, not from the memory map a file rewritten in place would change.
    pub(super) nodes: Vec<Vec<crate::store::format::NodeRecord>>,
    /// The file's atlas side, read once (the shader divides by it every frame).
    pub(super) atlas_texels: f32,
    pub resident: Resident,
    pub(super) opts: RendererOptions,
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) pipelines: PassPipelines,
    pub(super) globals: wgpu::Buffer,
    pub(super) records: Growable,
    pub(super) indirect: Growable,
    pub(super) bind_group: wgpu::BindGroup,
    /// Atlas and original-texture samplers (the shader's bindings in that order).
    pub(super) samplers: [wgpu::Sampler; 2],
    pub(super) naive: Option<Naive>,
    /// The dummy baseline's pipelines and texture, created on the first dummy frame.
    pub(super) dummy: Option<Dummy>,
    /// The supersampled reference's targets and pass, created on first use.
    pub(super) supersample: Option<Supersample>,
    pub color: wgpu::Texture,
    pub(super) color_view: wgpu::TextureView,
    pub(super) depth_view: wgpu::TextureView,
    pub(super) batch: FrameBatch,
    pub(super) timestamps: Option<Timestamps>,
    /// Texel-density pipelines and target, created on the first [`Renderer::render_density`].
    pub(super) density: Option<DensityTarget>,
    /// Created for a paging planner: texture arrays sized for its capacity, blocks arrive as it plans.
    pub(super) paged: bool,
}

impl<'f> Renderer<'f> {
    /// Uploads the whole file (all blocks resident) and creates the opaque pipeline.
    pub fn new(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
    ) -> Result<Renderer<'f>, RenderError> {
        check_size(ctx, opts.width, opts.height)?;
        // Every block at once: the texture arrays are the largest allocations, and a device out of memory
        // (lavapipe's heap, a small GPU) is an error naming the load, not wgpu's uncaptured-error panic.
        let resident = ctx.scoped(
            "uploading every block (all resident; `--capacity K` pages K blocks instead)",
            |_| Resident::load(ctx, file),
        )??;
        Self::with_resident(ctx, file, opts, resident, false)
    }

    /// A renderer for a paging `planner` (paper §6): texture arrays sized for the planner's capacity, the
    /// root atlases the planner bootstrapped uploaded now, everything else as the planner's plans page it
    /// in through [`Renderer::residency`]. Errors: [`RenderError::Plan`] when the planner does not page.
    pub fn new_paged(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
        planner: &mut FramePlanner<'_>,
    ) -> Result<Renderer<'f>, RenderError> {
        check_size(ctx, opts.width, opts.height)?;
        let (Some(table), Some(capacity)) = (planner.table(), planner.max_capacity()) else {
            return Err(RenderError::Plan(PlanError::NotPaged));
        };
        let mut resident = ctx.scoped(
            "allocating the paged texture arrays (a smaller `--capacity` needs less)",
            |_| Resident::load_paged(ctx, file, table, capacity),
        )??;
        for e in &planner.take_bootstrap() {
            resident.apply(&ctx.queue, e)?;
        }
        Self::with_resident(ctx, file, opts, resident, true)
    }

    fn with_resident(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
        resident: Resident,
        paged: bool,
    ) -> Result<Renderer<'f>, RenderError> {
        let device = &ctx.device;
        let layout = tree_bind_group_layout(device);
        let pipelines = PassPipelines::new(
            device,
            "tree",
            tree::WGSL,
            &[&layout],
            vertex_layout(),
            tree_specialisation(&resident),
        );
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let records = Growable::new(device, "node records", wgpu::BufferUsages::STORAGE);
        let indirect = Growable::new(device, "indirect", wgpu::BufferUsages::INDIRECT);
        let aniso = opts.device_anisotropy(ctx);
        let clamp = [wgpu::AddressMode::ClampToEdge; 2];
        let repeat = [wgpu::AddressMode::Repeat; 2];
        let samplers = [
            sampler(device, "atlas sampler", clamp, aniso),
            sampler(device, "original sampler", repeat, aniso),
        ];
        let (color, color_view, depth_view) = targets(device, opts.width, opts.height);
        let bind_group = tree_bind_group(
            device,
            &layout,
            &resident,
            &globals,
            &records.buffer,
            &samplers,
        );
        let timestamps = (opts.gpu_timing && ctx.features.timestamp_query).then(|| Timestamps {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            read: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp read"),
                size: 16,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            period_ns: f64::from(ctx.features.timestamp_period_ns),
        });
        Ok(Renderer {
            ctx,
            file,
            nodes: crate::plan::file_trees_copied(file),
            atlas_texels: file.params().atlas_size as f32,
            resident,
            opts,
            layout,
            pipelines,
            globals,
            records,
            indirect,
            bind_group,
            samplers,
            naive: None,
            dummy: None,
            supersample: None,
            color,
            color_view,
            depth_view,
            batch: FrameBatch::new(),
            timestamps,
            density: None,
            paged,
        })
    }

    /// Where a plan applies its residency changes: this renderer's texture arrays (uploads and frees).
    pub fn residency(&mut self) -> GpuResidency<'_> {
        GpuResidency {
            resident: &mut self.resident,
            queue: &self.ctx.queue,
        }
    }

    /// Replaces the colour and depth targets by ones of `width`×`height` pixels (a resized window); the
    /// resident data and pipelines are kept. Errors: [`RenderError::BadSize`] for an empty size.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        check_size(self.ctx, width, height)?;
        if (width, height) == (self.opts.width, self.opts.height) {
            return Ok(());
        }
        (self.color, self.color_view, self.depth_view) = targets(&self.ctx.device, width, height);
        self.opts.width = width;
        self.opts.height = height;
        self.density = None;
        Ok(())
    }

    /// The batch of the last tree-mode frame.
    pub fn batch(&self) -> &FrameBatch {
        &self.batch
    }

    /// Executes `plan` (made by a [`FramePlanner`] whose residency changes went to
    /// [`Renderer::residency`]) in `mode`, and waits for the GPU. A plan may be executed any number of
    /// times and in several modes: executing steps nothing.
    pub fn execute(&mut self, plan: &FramePlan, mode: Mode) -> Result<FrameStats, RenderError> {
        self.execute_to(plan, mode, false)
    }

    /// Texel-density debug frame of `plan`: the draws of [`Mode::Tree`], each pixel holding the texels (of
    /// mip 0 of the atlas or original texture it samples) per screen pixel instead of a colour; read back
    /// to the CPU. See [`super::density`]. Works on paged renderers too (the plan is not stepped again).
    /// Alpha-tested as the colour pass is: a pixel is drawn here exactly where [`Mode::Tree`] draws it.
    pub fn execute_density(
        &mut self,
        plan: &FramePlan,
    ) -> Result<(FrameStats, DensityFrame), RenderError> {
        if self.density.is_none() {
            self.density = Some(DensityTarget::new(
                &self.ctx.device,
                &self.layout,
                tree_specialisation(&self.resident),
                self.opts.width,
                self.opts.height,
            ));
        }
        let stats = self.execute_to(plan, Mode::Tree, true)?;
        let Some(d) = &self.density else {
            return Err(RenderError::BadSize {
                width: self.opts.width,
                height: self.opts.height,
                limit: self.ctx.device.limits().max_texture_dimension_2d,
            });
        };
        Ok((stats, d.read(self.ctx)?))
    }

    /// One frame of `plan` into the colour target, or (`density`) into the density target.
    fn execute_to(
        &mut self,
        plan: &FramePlan,
        mode: Mode,
        density: bool,
    ) -> Result<FrameStats, RenderError> {
        let t1 = Instant::now();
        if self.paged && mode == Mode::Original {
            return Err(RenderError::NotWhenPaged {
                what: "the naive original-texture mode",
            });
        }
        if plan.cuts.len() != self.resident.infos.len() {
            return Err(RenderError::PlanMismatch {
                cuts: plan.cuts.len(),
                trees: self.resident.infos.len(),
            });
        }
        let camera = &plan.camera;
        let mut stats = FrameStats {
            plan: plan.stats,
            ..FrameStats::default()
        };
        let p = &self.resident.residency;
        stats.atlas_layers_used = p.atlas_layers_used;
        stats.original_layers_used = p.original_layers_used;
        for (info, cut) in self.resident.infos.iter().zip(&plan.cuts) {
            self.resident.leaf_offsets.update(info, cut, camera.eye);
        }
        self.resident.write_offsets(&self.ctx.queue);
        let globals = Globals {
            view_proj: view_proj_reverse_z(camera),
            mode: if mode == Mode::TreeLevels {
                MODE_LEVELS
            } else {
                MODE_TEXTURED
            },
            atlas_texels: self.atlas_texels,
            _p1: 0,
            _p2: 0,
        };
        self.ctx
            .queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));

        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        if mode == Mode::Original {
            self.encode_naive(&mut encoder, &plan.cuts, &mut stats)?;
        } else {
            self.encode_tree(&mut encoder, plan, mode, density, &mut stats);
        }
        if let Some(ts) = &self.timestamps {
            encoder.resolve_query_set(&ts.set, 0..2, &ts.resolve, 0);
            encoder.copy_buffer_to_buffer(&ts.resolve, 0, &ts.read, 0, 16);
        }
        self.ctx.queue.submit([encoder.finish()]);
        stats.encode_us = t1.elapsed().as_secs_f64() * 1e6;
        stats.gpu_ms = self.read_timestamps()?;
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Gpu(e.into()))?;
        stats.frame_ms =
            (plan.stats.select_us + plan.stats.page_us) * 1e-3 + t1.elapsed().as_secs_f64() * 1e3;
        Ok(stats)
    }

    /// Reads the last frame back: `width · height · 4` sRGB RGBA bytes, rows top to bottom.
    pub fn read_frame(&self) -> Result<Vec<u8>, RenderError> {
        Ok(readback_rgba8(self.ctx, &self.color)?)
    }

    pub fn options(&self) -> RendererOptions {
        self.opts
    }
}

/// Specialisation of `tree.wgsl` to what the file has: the number of atlas arrays and the class arrays present (absent ones are compiled out, see [`Group`]).
pub(super) fn tree_specialisation(res: &Resident) -> Specialisation {
    let class_mask = res
        .class_arrays
        .iter()
        .enumerate()
        .filter(|(_, a)| a.is_some())
        .fold(0u32, |m, (k, _)| m | 1 << k);
    Specialisation {
        constants: vec![(tree::overrides::CLASS_MASK, f64::from(class_mask))],
        source: true,
        density: false,
    }
}

/// A target of `width`×`height` pixels fits the device: each side 1 to `max_texture_dimension_2d`
/// (wgpu would otherwise fail texture creation with an uncaptured validation error).
fn check_size(ctx: &GpuContext, width: u32, height: u32) -> Result<(), RenderError> {
    let limit = ctx.device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > limit || height > limit {
        return Err(RenderError::BadSize {
            width,
            height,
            limit,
        });
    }
    Ok(())
}

/// `Camera::view_proj_relative` with depth mapped to reverse Z (`z' = w − z`: near → 1, far → 0), as f32.
fn view_proj_reverse_z(camera: &Camera) -> [[f32; 4]; 4] {
    let flip = DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 1.0, 0.0, 0.0),
        DVec4::new(0.0, 0.0, -1.0, 0.0),
        DVec4::new(0.0, 0.0, 1.0, 1.0),
    );
    (flip * camera.view_proj_relative())
        .as_mat4()
        .to_cols_array_2d()
}

fn targets(
    device: &wgpu::Device,
    width: u32,
    height: u32,
) -> (wgpu::Texture, wgpu::TextureView, wgpu::TextureView) {
    let size = wgpu::Extent3d {
        width,
        height,
        depth_or_array_layers: 1,
    };
    let color = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("frame colour"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: COLOR_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let depth = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("frame depth"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: DEPTH_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let cv = color.create_view(&wgpu::TextureViewDescriptor::default());
    let dv = depth.create_view(&wgpu::TextureViewDescriptor::default());
    (color, cv, dv)
}

/// The frame's one bind group: buffers, samplers, the atlas arrays and the class arrays (missing arrays
/// bound to the 1×1 placeholder).
pub(super) fn tree_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    res: &Resident,
    globals: &wgpu::Buffer,
    records: &wgpu::Buffer,
    samplers: &[wgpu::Sampler; 2],
) -> wgpu::BindGroup {
    let mut entries = vec![
        wgpu::BindGroupEntry {
            binding: tree::binding::GLOBALS,
            resource: globals.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::DRAWS,
            resource: records.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::LEAVES,
            resource: res.leaves_buffer.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::OFFSETS,
            resource: res.offsets_buffer.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::TAM,
            resource: res.tam_buffer.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::RECTS,
            resource: res.rects_buffer.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::ATLAS_SAMPLER,
            resource: wgpu::BindingResource::Sampler(&samplers[0]),
        },
        wgpu::BindGroupEntry {
            binding: tree::binding::ORIGINAL_SAMPLER,
            resource: wgpu::BindingResource::Sampler(&samplers[1]),
        },
    ];
    for i in 0..MAX_ATLAS_ARRAYS {
        let view = match res.atlas_arrays.get(i) {
            Some(a) => &a.view,
            None => &res.dummy.view,
        };
        entries.push(wgpu::BindGroupEntry {
            binding: tree::binding::ATLAS0 + i as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    for k in 0..CLASS_COUNT {
        let view = match res.class_arrays.get(k).and_then(|a| a.as_ref()) {
            Some(a) => &a.view,
            None => &res.dummy.view,
        };
        entries.push(wgpu::BindGroupEntry {
            binding: tree::binding::CLASS0 + k as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("tree frame"),
        layout,
        entries: &entries,
    })
}

/// Columns of an executed frame: the plan's counters ([`columns::plan_columns`]), then the renderer's draw
/// counters and timings (the paging counters are [`columns::paging_columns`]). `gpu_ms` is NaN (`nan`) without
/// timestamp queries.
pub fn frame_columns(s: &FrameStats) -> Vec<Column> {
    let FrameStats {
        plan,
        indirect_records,
        original_records,
        draw_calls,
        bind_group_changes,
        pipeline_changes,
        triangles,
        encode_us,
        gpu_ms,
        frame_ms,
        skipped_draws,
        atlas_layers_used,
        original_layers_used,
    } = *s;
    let mut out = columns::plan_columns(&plan);
    out.extend([
        Column::counter("indirect_records", indirect_records),
        Column::counter("original_records", original_records),
        Column::counter("draw_calls", draw_calls),
        Column::counter("bind_group_changes", bind_group_changes),
        Column::counter("pipeline_changes", pipeline_changes),
        Column::counter("triangles", triangles),
        Column::counter("skipped_draws", skipped_draws),
        Column::counter("atlas_layers_used", atlas_layers_used),
        Column::counter("original_layers_used", original_layers_used),
        Column::timing("encode_us", encode_us),
        Column::timing("gpu_ms", gpu_ms.unwrap_or(f64::NAN)),
        Column::timing("frame_ms", frame_ms),
    ]);
    out
}
