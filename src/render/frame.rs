//! The renderer: per frame, select (paper §4) → batch → upload → one render pass, and its counters.

use super::batch::{BatchOptions, DrawIndexedIndirect, FrameBatch, Group, Pass};
use super::density::{DensityFrame, DensityTarget};
use super::naive::Naive;
use super::pipeline::{
    COLOR_FORMAT, DEPTH_FORMAT, PassPipelines, Specialisation, sampler, tree_bind_group_layout,
    vertex_layout,
};
use super::resident::Resident;
use super::textures::{CLASS_COUNT, MAX_ATLAS_ARRAYS};
use super::wgsl::tree::{self, Globals, MODE_LEVELS, MODE_TEXTURED, NodeDraw};
use super::{Mode, RenderError};
use crate::camera::Camera;
use crate::gpu::{GpuContext, readback_rgba8};
use crate::paging::{
    BlockSource, BlockTable, Coarseness, ImmediateLoader, Loader, Pager, PagerOptions,
    PagingSession, Resolved, SessionFrame, ThreadedLoader, resolve_frame,
};
use crate::select::{Cut, select};
use crate::store::TreeFile;
use crate::store::format::NodeRecord;
use glam::{DMat4, DVec4};
use std::sync::Arc;
use std::time::Instant;

/// Counters and timings of one frame (the columns of `stats.csv`).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Nodes evaluated by the traversals (all trees), culled ones included.
    pub nodes_visited: u32,
    /// Cut items (selected nodes) of all trees.
    pub nodes_drawn: u32,
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
    /// CPU time of the traversal (select), µs.
    pub select_us: f64,
    /// CPU time of batching, uploads and command encoding, µs.
    pub encode_us: f64,
    /// GPU time of the render pass from timestamp queries, ms (`None` without timestamp support).
    pub gpu_ms: Option<f64>,
    /// Wall time from the start of select to the GPU having finished the frame, ms.
    pub frame_ms: f64,
    /// Paging counters (`None` when all blocks are resident).
    pub paging: Option<PagingFrame>,
}

/// Paging counters of one frame (the paging columns of `stats.csv`).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct PagingFrame {
    pub session: SessionFrame,
    /// Screen accounting of the draws: share rendered coarser than the selection asked for.
    pub coarse: Coarseness,
    /// Time spent in residency changes (uploads), ms, and bytes uploaded to the GPU.
    pub upload_ms: f64,
    pub uploaded_bytes: u64,
    /// Of the bytes the pager loaded this frame, those of original-texture blocks (the rest are atlases).
    pub loaded_original_bytes: u64,
    /// Bytes of the resident blocks after the frame, atlases and original textures apart.
    pub resident_atlas_bytes: u64,
    pub resident_original_bytes: u64,
    /// `xxh3_64` of the sorted resident block ids (compared with the simulator's log).
    pub resident_hash: u64,
    /// Residency changes the GPU side could not apply (drawn coarser instead), this frame.
    pub apply_errors: u32,
    /// Layers in use in the atlas arrays and the original-texture arrays.
    pub atlas_layers_used: u32,
    pub original_layers_used: u32,
}

/// How a paged renderer gets its blocks.
pub struct PagingSetup {
    pub pager: PagerOptions,
    pub source: Arc<dyn BlockSource>,
    /// Loader threads; 0 loads synchronously inside the frame (deterministic, for tests and comparisons).
    pub loader_threads: usize,
}

struct PagingRuntime {
    session: PagingSession,
    loader: Box<dyn Loader>,
    table: BlockTable,
    resolved: Vec<Vec<Resolved>>,
    clock: f64,
    clock_set: bool,
    last_error: Option<String>,
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
struct Growable {
    buffer: wgpu::Buffer,
    capacity: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
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
    fn write(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, data: &[u8]) -> bool {
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

struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
    period_ns: f64,
}

/// Renders frames of one paging file into an offscreen target.
pub struct Renderer<'f> {
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    pub resident: Resident,
    opts: RendererOptions,
    layout: wgpu::BindGroupLayout,
    pipelines: PassPipelines,
    globals: wgpu::Buffer,
    records: Growable,
    indirect: Growable,
    bind_group: wgpu::BindGroup,
    dummy_bind_group: wgpu::BindGroup,
    /// Atlas and original-texture samplers (the shader's bindings in that order).
    samplers: [wgpu::Sampler; 2],
    naive: Option<Naive>,
    pub color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    cuts: Vec<Cut>,
    batch: FrameBatch,
    timestamps: Option<Timestamps>,
    /// Texel-density pipelines and target, created on the first [`Renderer::render_density`].
    density: Option<DensityTarget>,
    /// Block paging (`None`: everything resident).
    paging: Option<PagingRuntime>,
    /// Camera the cut is selected for instead of the frame's camera ([`Renderer::freeze_selection`]).
    frozen: Option<Camera>,
}

impl<'f> Renderer<'f> {
    /// Uploads the whole file (all blocks resident) and creates the opaque pipeline.
    pub fn new(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
    ) -> Result<Renderer<'f>, RenderError> {
        if opts.width == 0 || opts.height == 0 {
            return Err(RenderError::BadSize {
                width: opts.width,
                height: opts.height,
            });
        }
        // Every block at once: the texture arrays are the largest allocations, and a device out of memory
        // (lavapipe's heap, a small GPU) is an error naming the load, not wgpu's uncaptured-error panic.
        let resident = ctx.scoped("uploading every block (all resident)", |_| {
            Resident::load(ctx, file)
        })??;
        Self::with_resident(ctx, file, opts, resident, None)
    }

    /// A renderer that pages blocks (paper §6): texture arrays sized for `setup.pager.capacity` blocks,
    /// the root atlases loaded now, everything else on demand through `setup.source`.
    pub fn new_paged(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
        setup: PagingSetup,
    ) -> Result<Renderer<'f>, RenderError> {
        if opts.width == 0 || opts.height == 0 {
            return Err(RenderError::BadSize {
                width: opts.width,
                height: opts.height,
            });
        }
        let table = BlockTable::from_file(file)?;
        let mut resident = ctx.scoped("allocating the paged texture arrays", |_| {
            Resident::load_paged(ctx, file, &table, setup.pager.capacity)
        })??;
        let mut pager = Pager::new(table.clone(), setup.pager)?;
        let records = file.blocks().to_vec();
        let source = setup.source;
        let events = pager.bootstrap(|b| {
            let r = records
                .get(b.idx())
                .ok_or_else(|| format!("{b} not in the table"))?;
            source.fetch(b, r).map(Some).map_err(|e| e.to_string())
        })?;
        for e in &events {
            resident.apply(&ctx.queue, &table, e)?;
        }
        let loader: Box<dyn Loader> = if setup.loader_threads == 0 {
            Box::new(ImmediateLoader::new(source, records))
        } else {
            Box::new(
                ThreadedLoader::new(source, records, setup.loader_threads)
                    .map_err(RenderError::Loader)?,
            )
        };
        let runtime = PagingRuntime {
            session: PagingSession::new(pager),
            loader,
            table,
            resolved: Vec::new(),
            clock: 0.0,
            clock_set: false,
            last_error: None,
        };
        Self::with_resident(ctx, file, opts, resident, Some(runtime))
    }

    fn with_resident(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
        resident: Resident,
        paging: Option<PagingRuntime>,
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
        let make = |dummy: bool| {
            tree_bind_group(
                device,
                &layout,
                &resident,
                &globals,
                &records.buffer,
                &samplers,
                dummy,
            )
        };
        let bind_group = make(false);
        let dummy_bind_group = make(true);
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
        let trees = resident.infos.len();
        Ok(Renderer {
            ctx,
            file,
            resident,
            opts,
            layout,
            pipelines,
            globals,
            records,
            indirect,
            bind_group,
            dummy_bind_group,
            samplers,
            naive: None,
            color,
            color_view,
            depth_view,
            cuts: vec![Cut::new(); trees],
            batch: FrameBatch::new(),
            timestamps,
            density: None,
            paging,
            frozen: None,
        })
    }

    /// Sets the paging clock (seconds) for the next frame; without it the clock advances 1/60 s per frame.
    pub fn set_clock(&mut self, seconds: f64) {
        if let Some(p) = &mut self.paging {
            p.clock = seconds;
            p.clock_set = true;
        }
    }

    /// The pager (`None` when all blocks are resident).
    pub fn pager(&self) -> Option<&Pager> {
        self.paging.as_ref().map(|p| &p.session.pager)
    }

    /// Changes the paging capacity live (clamped to the GPU layers allocated at creation).
    pub fn set_capacity(&mut self, capacity: u32) {
        if let Some(p) = &mut self.paging {
            p.session
                .pager
                .set_capacity(capacity.min(self.resident.stats.atlas_layers.max(1)));
        }
    }

    /// The last residency error the GPU side reported, if any.
    pub fn last_paging_error(&self) -> Option<&str> {
        self.paging.as_ref().and_then(|p| p.last_error.as_deref())
    }

    /// One paging step after select: plan, load, apply residency changes, resolve the cuts.
    fn page(
        &mut self,
        camera: &Camera,
        frustum: &crate::camera::Frustum,
        scale: f64,
    ) -> Option<PagingFrame> {
        let rt = self.paging.as_mut()?;
        let file = self.file;
        let trees: Vec<&[NodeRecord]> = (0..file.trees())
            .filter_map(|t| file.tree(t).map(|v| v.nodes))
            .collect();
        if !rt.clock_set {
            rt.clock += 1.0 / 60.0;
        }
        rt.clock_set = false;
        let resident = &mut self.resident;
        let queue = &self.ctx.queue;
        let table = &rt.table;
        let (mut bytes, mut errors, mut last_error) = (0u64, 0u32, None);
        let mut loaded_original_bytes = 0u64;
        let t = Instant::now();
        let session = rt.session.frame(
            &trees,
            camera,
            frustum,
            scale,
            rt.clock,
            &mut *rt.loader,
            |ev| match resident.apply(queue, table, &ev) {
                Ok(b) => {
                    bytes += b;
                    if let crate::paging::Event::Loaded { block, .. } = &ev {
                        loaded_original_bytes += table.bytes_by_kind([*block]).1;
                    }
                }
                Err(e) => {
                    errors += 1;
                    last_error = Some(e.to_string());
                }
            },
        );
        let upload_ms = t.elapsed().as_secs_f64() * 1e3;
        if last_error.is_some() {
            rt.last_error = last_error;
        }
        let infos = &self.resident.infos;
        let coarse = resolve_frame(
            &trees,
            &self.cuts,
            camera,
            |t, n| {
                infos
                    .get(t)
                    .and_then(|i| i.atlas_slots.get(n.idx()).copied().flatten())
                    .is_some()
            },
            |t, n| {
                infos
                    .get(t)
                    .and_then(|i| i.originals_missing.get(n.idx()))
                    .is_some_and(|&m| m == 0)
            },
            &mut rt.resolved,
        );
        let p = self.resident.paged.as_ref();
        let (resident_atlas_bytes, resident_original_bytes) = rt
            .table
            .bytes_by_kind(rt.session.pager.resident().iter().copied());
        Some(PagingFrame {
            session,
            coarse,
            upload_ms,
            uploaded_bytes: bytes,
            loaded_original_bytes,
            resident_atlas_bytes,
            resident_original_bytes,
            resident_hash: crate::paging::resident_fingerprint(rt.session.pager.resident()),
            apply_errors: errors,
            atlas_layers_used: p.map_or(0, |p| p.atlas_layers_used),
            original_layers_used: p.map_or(0, |p| p.original_layers_used),
        })
    }

    /// Number of render pipelines created so far (the alpha ones only once needed).
    pub fn pipelines_created(&self) -> usize {
        self.pipelines.created()
    }

    /// Selects every following frame's cut for `camera` instead of the frame's own camera (`None`: the
    /// frame's camera again), so the cut of one view can be looked at from elsewhere (the viewer's "freeze
    /// selection"). Draws still use the frame's camera.
    pub fn freeze_selection(&mut self, camera: Option<Camera>) {
        self.frozen = camera;
    }

    /// Replaces the colour and depth targets by ones of `width`×`height` pixels (a resized window); the
    /// resident data and pipelines are kept. Errors: [`RenderError::BadSize`] for an empty size.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        if width == 0 || height == 0 {
            return Err(RenderError::BadSize { width, height });
        }
        if (width, height) == (self.opts.width, self.opts.height) {
            return Ok(());
        }
        (self.color, self.color_view, self.depth_view) = targets(&self.ctx.device, width, height);
        self.opts.width = width;
        self.opts.height = height;
        self.density = None;
        Ok(())
    }

    /// The cuts of the last frame, one per tree.
    pub fn cuts(&self) -> &[Cut] {
        &self.cuts
    }

    /// The batch of the last tree-mode frame.
    pub fn batch(&self) -> &FrameBatch {
        &self.batch
    }

    /// Renders one frame of `camera` (its aspect should be width/height) with node `min_distance`s scaled by
    /// `scale` ([`crate::select::min_distance_scale`]), and waits for the GPU.
    pub fn render(
        &mut self,
        camera: &Camera,
        scale: f64,
        mode: Mode,
    ) -> Result<FrameStats, RenderError> {
        self.render_to(camera, scale, mode, false)
    }

    /// Texel-density debug frame: the cut and draws of [`Mode::Tree`] for `camera` at `scale`, each pixel
    /// holding the texels (of mip 0 of the atlas or original texture it samples) per screen pixel
    /// instead of a colour; read back to the CPU. See [`super::density`].
    pub fn render_density(
        &mut self,
        camera: &Camera,
        scale: f64,
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
        let stats = self.render_to(camera, scale, Mode::Tree, true)?;
        let Some(d) = &self.density else {
            return Err(RenderError::BadSize {
                width: self.opts.width,
                height: self.opts.height,
            });
        };
        Ok((stats, d.read(self.ctx)?))
    }

    /// One frame into the colour target, or (`density`) into the density target.
    fn render_to(
        &mut self,
        camera: &Camera,
        scale: f64,
        mode: Mode,
        density: bool,
    ) -> Result<FrameStats, RenderError> {
        let t0 = Instant::now();
        let mut stats = FrameStats::default();
        let selector = *self.frozen.as_ref().unwrap_or(camera);
        let frustum = selector.frustum();
        for (t, cut) in self.cuts.iter_mut().enumerate() {
            let view = self
                .file
                .tree(t)
                .ok_or(RenderError::MissingTree { tree: t })?;
            select(view.nodes, &selector, &frustum, scale, cut);
            stats.nodes_visited += cut.visited;
            stats.nodes_drawn += cut.items.len() as u32;
        }
        let t1 = Instant::now();
        stats.select_us = (t1 - t0).as_secs_f64() * 1e6;
        if self.paging.is_some() && mode == Mode::Original {
            return Err(RenderError::NotWhenPaged {
                what: "the naive original-texture mode",
            });
        }
        stats.paging = self.page(&selector, &frustum, scale);
        let t1 = Instant::now();

        for (info, cut) in self.resident.infos.iter().zip(&self.cuts) {
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
            atlas_texels: self.file.params().atlas_size as f32,
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
            self.encode_naive(&mut encoder, &mut stats)?;
        } else {
            self.encode_tree(&mut encoder, mode, density, &mut stats);
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
        stats.frame_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(stats)
    }

    fn read_timestamps(&self) -> Result<Option<f64>, RenderError> {
        let Some(ts) = &self.timestamps else {
            return Ok(None);
        };
        let (tx, rx) = std::sync::mpsc::channel();
        ts.read.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Gpu(e.into()))?;
        let ok = matches!(rx.recv(), Ok(Ok(())));
        if !ok {
            return Ok(None);
        }
        let ticks: [u64; 2] = {
            let view = ts
                .read
                .get_mapped_range(..)
                .map_err(|e| RenderError::Gpu(e.into()))?;
            bytemuck::pod_read_unaligned(&view[..16])
        };
        ts.read.unmap();
        Ok(Some(
            ticks[1].saturating_sub(ticks[0]) as f64 * ts.period_ns * 1e-6,
        ))
    }

    /// The frame's render pass into the colour target, or (`density`) the density target.
    fn pass<'e>(
        &'e self,
        encoder: &'e mut wgpu::CommandEncoder,
        density: bool,
    ) -> wgpu::RenderPass<'e> {
        let (view, clear) = match (&self.density, density) {
            (Some(d), true) => (&d.view, super::density::CLEAR),
            _ => (&self.color_view, SKY),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("frame"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: self
                .timestamps
                .as_ref()
                .map(|ts| wgpu::RenderPassTimestampWrites {
                    query_set: &ts.set,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// TAB: one bind group, one `multi_draw_indexed_indirect` per non-empty pass.
    fn encode_tree(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mode: Mode,
        density: bool,
        stats: &mut FrameStats,
    ) {
        let ctx = self.ctx;
        let device = &ctx.device;
        let queue = &ctx.queue;
        self.batch.clear();
        let opts = BatchOptions {
            dummy: mode == Mode::Dummy,
        };
        for (t, (info, cut)) in self.resident.infos.iter().zip(&self.cuts).enumerate() {
            if let Some(view) = self.file.tree(t) {
                let resolved = self
                    .paging
                    .as_ref()
                    .and_then(|p| p.resolved.get(t))
                    .map(Vec::as_slice);
                self.batch.add_cut(info, view.nodes, cut, resolved, opts);
            }
        }
        self.batch.finish();
        stats.indirect_records = self.batch.len() as u32;
        stats.original_records = self.batch.original_records;
        stats.triangles = self.batch.triangles;
        let grew = self.records.write(
            device,
            queue,
            bytemuck::cast_slice::<NodeDraw, u8>(&self.batch.records),
        );
        self.indirect.write(
            device,
            queue,
            bytemuck::cast_slice::<DrawIndexedIndirect, u8>(&self.batch.indirect),
        );
        if grew {
            let make = |dummy| {
                tree_bind_group(
                    device,
                    &self.layout,
                    &self.resident,
                    &self.globals,
                    &self.records.buffer,
                    &self.samplers,
                    dummy,
                )
            };
            self.bind_group = make(false);
            self.dummy_bind_group = make(true);
        }
        let passes: Vec<(Group, u32, u32)> = Group::ALL
            .iter()
            .map(|&g| {
                let (start, count) = self.batch.group_ranges[g.index()];
                (g, start, count)
            })
            .filter(|&(_, _, count)| count > 0)
            .collect();
        let pipelines = match (&mut self.density, density) {
            (Some(d), true) => &mut d.pipelines,
            _ => &mut self.pipelines,
        };
        for &(p, _, _) in &passes {
            pipelines.get(device, p);
        }
        let group = if mode == Mode::Dummy {
            &self.dummy_bind_group
        } else {
            &self.bind_group
        };
        let pipelines = match (&self.density, density) {
            (Some(d), true) => &d.pipelines,
            _ => &self.pipelines,
        };
        let mut rp = self.pass(encoder, density);
        rp.set_bind_group(0, group, &[]);
        stats.bind_group_changes += 1;
        rp.set_vertex_buffer(0, self.resident.vertex_buffer.slice(..));
        rp.set_index_buffer(
            self.resident.index_buffer.slice(..),
            wgpu::IndexFormat::Uint32,
        );
        for (p, start, count) in passes {
            let Some(pipeline) = pipelines.existing(p) else {
                continue;
            };
            rp.set_pipeline(pipeline);
            stats.pipeline_changes += 1;
            let offset = u64::from(start) * size_of::<DrawIndexedIndirect>() as u64;
            rp.multi_draw_indexed_indirect(&self.indirect.buffer, offset, count);
            stats.draw_calls += 1;
        }
    }

    /// The naive baseline: per visible leaf and original texture, one bind group and one draw.
    fn encode_naive(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        stats: &mut FrameStats,
    ) -> Result<(), RenderError> {
        if self.naive.is_none() {
            self.naive = Some(Naive::new(
                self.ctx,
                self.file,
                &self.resident,
                &self.globals,
                self.opts.device_anisotropy(self.ctx),
            )?);
        }
        let Some(naive) = self.naive.as_mut() else {
            return Ok(());
        };
        // Visible leaves: every leaf below a cut item (same culling as the tree modes).
        let mut lists: [Vec<u32>; 3] = Default::default();
        for (info, cut) in self.resident.infos.iter().zip(&self.cuts) {
            for item in &cut.items {
                let Some(&(first, count)) = info.leaf_ranges.get(item.node.idx()) else {
                    continue;
                };
                for l in first..first.saturating_add(count) {
                    let gl = info.leaf_base.saturating_add(l) as usize;
                    let Some(&(d0, dn)) = naive.leaf_draws.get(gl) else {
                        continue;
                    };
                    for d in d0..d0 + dn {
                        if let Some(draw) = naive.draws.get(d as usize) {
                            lists[draw.pass as usize].push(d);
                        }
                    }
                }
            }
        }
        for p in Pass::ALL {
            if !lists[p as usize].is_empty() {
                naive.pipelines.get(&self.ctx.device, Group::new(p, false));
            }
        }
        let Some(naive) = self.naive.as_ref() else {
            return Ok(());
        };
        let mut rp = self.pass(encoder, false);
        rp.set_bind_group(0, &naive.group0, &[]);
        stats.bind_group_changes += 1;
        rp.set_vertex_buffer(0, self.resident.vertex_buffer.slice(..));
        rp.set_index_buffer(naive.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        for p in Pass::ALL {
            let list = &lists[p as usize];
            let Some(pipeline) = naive
                .pipelines
                .existing(Group::new(p, false))
                .filter(|_| !list.is_empty())
            else {
                continue;
            };
            rp.set_pipeline(pipeline);
            stats.pipeline_changes += 1;
            for &d in list {
                let Some(draw) = naive.draws.get(d as usize) else {
                    continue;
                };
                let Some(group) = naive.groups.get(draw.texture as usize) else {
                    continue;
                };
                rp.set_bind_group(1, group, &[]);
                stats.bind_group_changes += 1;
                rp.draw_indexed(
                    draw.first_index..draw.first_index + draw.index_count,
                    draw.base_vertex,
                    draw.leaf_base..draw.leaf_base + 1,
                );
                stats.draw_calls += 1;
                stats.triangles += u64::from(draw.index_count / 3);
            }
        }
        Ok(())
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
        constants: vec![
            (
                tree::overrides::ATLAS_ARRAYS,
                f64::from(res.atlas_arrays.len().max(1) as u32),
            ),
            (tree::overrides::CLASS_MASK, f64::from(class_mask)),
        ],
        source: true,
        density: false,
    }
}

/// Background colour (linear).
const SKY: wgpu::Color = wgpu::Color {
    r: 0.30,
    g: 0.45,
    b: 0.70,
    a: 1.0,
};

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
/// bound to the 1×1 dummy). `dummy`: every texture binding is the dummy (dummy mode).
fn tree_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    res: &Resident,
    globals: &wgpu::Buffer,
    records: &wgpu::Buffer,
    samplers: &[wgpu::Sampler; 2],
    dummy: bool,
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
            Some(a) if !dummy => &a.view,
            _ => &res.dummy.view,
        };
        entries.push(wgpu::BindGroupEntry {
            binding: tree::binding::ATLAS0 + i as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    for k in 0..CLASS_COUNT {
        let view = match res.class_arrays.get(k).and_then(|a| a.as_ref()) {
            Some(a) if !dummy => &a.view,
            _ => &res.dummy.view,
        };
        entries.push(wgpu::BindGroupEntry {
            binding: tree::binding::CLASS0 + k as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(if dummy {
            "tree frame (dummy)"
        } else {
            "tree frame"
        }),
        layout,
        entries: &entries,
    })
}
