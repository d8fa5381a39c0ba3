//! The per-frame loop of a [`FramePlanner`] and a [`Renderer`]: plan the frame (select, page, resolve; the
//! residency changes go to the renderer's texture arrays), then execute the plan. [`FrameLoop::new`] and
//! [`FrameLoop::new_paged`] are the one way to set the pair up (`render`, `sweep`, the viewer, tests);
//! [`FrameLoop::render`] serves callers that draw each frame once, and callers that execute one plan
//! several times (`render` with several modes, the sweep's density pass) use the public `planner` and
//! `renderer` directly.

use super::density::DensityFrame;
use super::frame::{FrameStats, Renderer, RendererOptions};
use super::{Mode, RenderError};
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::paging::Pager;
use crate::plan::{FramePlanner, PagingSetup};
use crate::select::Cut;
use crate::store::TreeFile;

/// A planner and the renderer that executes its plans.
pub struct FrameLoop<'f> {
    pub planner: FramePlanner<'f>,
    pub renderer: Renderer<'f>,
    /// Clock of the next paged plan, seconds, and whether it was set for it ([`FrameLoop::set_clock`]).
    clock: f64,
    clock_set: bool,
}

impl<'f> FrameLoop<'f> {
    /// Every block of `file` resident.
    pub fn new(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
    ) -> Result<FrameLoop<'f>, RenderError> {
        Ok(FrameLoop {
            planner: FramePlanner::from_file(file),
            renderer: Renderer::new(ctx, file, opts)?,
            clock: 0.0,
            clock_set: false,
        })
    }

    /// Blocks paged from `setup.source` under `setup.pager` (paper §6).
    pub fn new_paged(
        ctx: &'f GpuContext,
        file: &'f TreeFile,
        opts: RendererOptions,
        setup: PagingSetup,
    ) -> Result<FrameLoop<'f>, RenderError> {
        let mut planner = FramePlanner::paged_from_file(file, setup)?;
        let renderer = Renderer::new_paged(ctx, file, opts, &mut planner)?;
        Ok(FrameLoop {
            planner,
            renderer,
            clock: 0.0,
            clock_set: false,
        })
    }

    /// Sets the clock (seconds) of the next frame; without it the clock advances 1/60 s per frame.
    pub fn set_clock(&mut self, seconds: f64) {
        self.clock = seconds;
        self.clock_set = true;
    }

    /// The clock of the next paged plan: as set, or 1/60 s after the last one.
    fn tick(&mut self) -> f64 {
        if !self.clock_set {
            self.clock += 1.0 / 60.0;
        }
        self.clock_set = false;
        self.clock
    }

    /// Plans and draws one frame of `camera` (its aspect should be width/height) with node
    /// `min_distance`s scaled by `scale` ([`crate::select::min_distance_scale`]), and waits for the GPU.
    pub fn render(
        &mut self,
        camera: &Camera,
        scale: f64,
        mode: Mode,
    ) -> Result<FrameStats, RenderError> {
        let now = self.tick();
        let plan = self
            .planner
            .plan(camera, now, scale, &mut self.renderer.residency())?;
        self.renderer.execute(plan, mode)
    }

    /// Plans one frame and draws its texel-density pass ([`Renderer::execute_density`]).
    pub fn render_density(
        &mut self,
        camera: &Camera,
        scale: f64,
    ) -> Result<(FrameStats, DensityFrame), RenderError> {
        let now = self.tick();
        let plan = self
            .planner
            .plan(camera, now, scale, &mut self.renderer.residency())?;
        self.renderer.execute_density(plan)
    }

    /// The cuts of the last plan, one per tree (empty before the first frame).
    pub fn cuts(&self) -> &[Cut] {
        self.planner.last().map_or(&[], |p| p.cuts.as_slice())
    }

    /// The pager (`None` when all blocks are resident).
    pub fn pager(&self) -> Option<&Pager> {
        self.planner.pager()
    }

    /// Reads the last frame back ([`Renderer::read_frame`]).
    pub fn read_frame(&self) -> Result<Vec<u8>, RenderError> {
        self.renderer.read_frame()
    }
}
