//! Encoding one frame of a plan: the render pass, the tree draws (texture-array batching: one bind group,
//! one `multi_draw_indexed_indirect` per non-empty pipeline) and the naive per-texture baseline, and the
//! GPU timestamps around them.

use super::batch::{DrawIndexedIndirect, Group, Pass};
use super::dummy::Dummy;
use super::frame::{FrameStats, Renderer, tree_bind_group};
use super::naive::Naive;
use super::naive_batch::visible_draws;
use super::wgsl::tree::NodeDraw;
use super::{Mode, RenderError};
use crate::plan::FramePlan;
use crate::select::Cut;

/// Background colour (linear).
const SKY: wgpu::Color = wgpu::Color {
    r: 0.30,
    g: 0.45,
    b: 0.70,
    a: 1.0,
};

/// The background as a read-back frame holds it: [`SKY`] encoded to sRGB8, as the frame's target does.
pub fn sky_srgb8() -> [u8; 3] {
    [SKY.r, SKY.g, SKY.b].map(crate::util::srgb::linear_to_srgb8)
}

impl Renderer<'_> {
    pub(super) fn read_timestamps(&self) -> Result<Option<f64>, RenderError> {
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
    pub(super) fn encode_tree(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        plan: &FramePlan,
        mode: Mode,
        density: bool,
        stats: &mut FrameStats,
    ) {
        let ctx = self.ctx;
        let device = &ctx.device;
        let queue = &ctx.queue;
        self.batch.clear();
        for (t, (info, cut)) in self.resident.infos.iter().zip(&plan.cuts).enumerate() {
            if let Some(nodes) = self.nodes.get(t) {
                stats.skipped_draws += self.batch.add_cut(info, nodes, cut, plan.resolved(t));
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
            self.bind_group = tree_bind_group(
                device,
                &self.layout,
                &self.resident,
                &self.globals,
                &self.records.buffer,
                &self.samplers,
            );
            if let Some(d) = &mut self.dummy {
                d.buffers_replaced();
            }
        }
        let dummy = mode == Mode::Dummy && !density;
        if dummy && self.dummy.is_none() {
            self.dummy = Some(Dummy::new(ctx, self.opts.device_anisotropy(ctx)));
        }
        let passes: Vec<(Group, u32, u32)> = Group::ALL
            .iter()
            .map(|&g| {
                let (start, count) = self.batch.group_ranges[g.index()];
                (g, start, count)
            })
            .filter(|&(_, _, count)| count > 0)
            .collect();
        if let (true, Some(d)) = (dummy, &mut self.dummy) {
            d.prepare(
                device,
                &self.globals,
                &self.records.buffer,
                &self.resident.offsets_buffer,
            );
            for &(p, _, _) in &passes {
                d.pipelines.get(device, p);
            }
        } else {
            let pipelines = match (&mut self.density, density) {
                (Some(d), true) => &mut d.pipelines,
                _ => &mut self.pipelines,
            };
            for &(p, _, _) in &passes {
                pipelines.get(device, p);
            }
        }
        let (pipelines, group) = match (&self.density, density, &self.dummy) {
            (Some(d), true, _) => (&d.pipelines, &self.bind_group),
            (
                _,
                false,
                Some(Dummy {
                    pipelines,
                    group: Some(group),
                    ..
                }),
            ) if dummy => (pipelines, group),
            _ => (&self.pipelines, &self.bind_group),
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
    pub(super) fn encode_naive(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        cuts: &[Cut],
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
        // Visible leaves: every leaf below a cut item (same culling as the tree modes), planned on the CPU.
        let lists = visible_draws(&self.resident.infos, cuts, &naive.leaf_draws, &naive.draws)?;
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
            for draw in list {
                let group =
                    naive
                        .groups
                        .get(draw.texture as usize)
                        .ok_or(RenderError::MissingTexture {
                            texture: draw.texture,
                            textures: naive.groups.len(),
                        })?;
                rp.set_bind_group(1, group, &[]);
                stats.bind_group_changes += 1;
                rp.draw_indexed(
                    draw.first_index..draw.first_index + draw.index_count,
                    draw.base_vertex,
                    0..1,
                );
                stats.draw_calls += 1;
                // Every triangle once, as the tree counts its nodes: a BLEND triangle is drawn in the
                // mask pass (its depth pre-pass) and again in the blend pass.
                if p != Pass::Blend {
                    stats.triangles += u64::from(draw.index_count / 3);
                }
            }
        }
        Ok(())
    }
}
