//! The winit application: window and device set-up on `resumed`, input to the controller and egui, one
//! `Renderer::render` per redraw, composite + overlay + blit + present, screenshots and recordings.

use super::controls::{ControlMode, Controller, Key, Recorder, follow_time};
use super::overlay::{self, FrameTimes, NodeBox, PagingStats, Readout, Requests, Settings};
use super::present::{COMPOSITE_FORMAT, Presenter, ShotSource};
use super::{ViewError, ViewOptions, ViewReport, scene_bounds};
use crate::camera::{Camera, CameraPath};
use crate::gpu::{GpuContext, GpuOptions};
use crate::render::{FrameLoop, FrameStats, Mode, RendererOptions};
use crate::select::{SelectOptions, min_distance_scale};
use crate::store::TreeFile;
use glam::DVec3;
use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// Pixels of a touchpad's pixel-precise scroll that count as one wheel notch.
const PIXELS_PER_NOTCH: f64 = 50.0;

/// Whether a session's event loop is running ([`run`]), and whether a panic raised in winit while it
/// ran was caught ([`window_panic_caught`]).
static IN_SESSION: AtomicBool = AtomicBool::new(false);
static WINDOW_PANIC: AtomicBool = AtomicBool::new(false);

/// For a panic hook: true where `location` (a panic's file) lies in winit and a session's event loop is
/// running, so [`run`] ends the session with [`ViewError::WindowSystem`] (the hook need not print it);
/// false for every other panic, which [`run`] lets go on.
pub fn window_panic_caught(location: &str) -> bool {
    let caught = IN_SESSION.load(Ordering::SeqCst) && location.contains("/winit-");
    if caught {
        WINDOW_PANIC.store(true, Ordering::SeqCst);
    }
    caught
}

/// Opens the window on `file` and runs until it is closed (or `--exit` after the screenshot).
///
/// Errors: no window system ([`ViewError::EventLoop`]), no adapter that can present, renderer and I/O
/// errors of a frame, the window system failing under the session ([`ViewError::WindowSystem`]: winit
/// panics where its connection fails, and the panic hook tells it by [`window_panic_caught`]); the first
/// error ends the session.
pub fn run(file: &TreeFile, opts: ViewOptions) -> Result<ViewReport, ViewError> {
    let (lo, hi) = scene_bounds(file).ok_or(ViewError::EmptyFile)?;
    let event_loop = EventLoop::new()?;
    event_loop.set_control_flow(ControlFlow::Poll);
    // The window and the device outlive the application state that borrows them (dropped first).
    let window = OnceCell::new();
    let ctx = OnceCell::new();
    let mut app = App {
        file,
        bounds: (lo, hi),
        opts,
        window: &window,
        ctx: &ctx,
        running: None,
        error: None,
        report: ViewReport::default(),
    };
    // winit unwraps its connection's errors (an X server gone mid-session panicked in
    // `Window::inner_size`): such a panic ends the session with an error, any other goes on as a panic.
    // Nothing of the window system is dropped after it (dropping a window or surface on a dead
    // connection may panic again).
    IN_SESSION.store(true, Ordering::SeqCst);
    let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        event_loop.run_app(&mut app)
    }));
    IN_SESSION.store(false, Ordering::SeqCst);
    let ran = match ran {
        Ok(ran) => ran,
        Err(payload) if WINDOW_PANIC.load(Ordering::SeqCst) => {
            let reason = crate::util::panic_message(payload.as_ref());
            std::mem::forget(app);
            std::mem::forget(window);
            std::mem::forget(ctx);
            return Err(ViewError::WindowSystem { reason });
        }
        Err(payload) => std::panic::resume_unwind(payload),
    };
    ran?;
    if let Some(running) = app.running.as_mut() {
        running.finish(&mut app.report)?;
    }
    match app.error {
        Some(e) => Err(e),
        None => Ok(app.report),
    }
}

struct App<'a> {
    file: &'a TreeFile,
    bounds: (DVec3, DVec3),
    opts: ViewOptions,
    window: &'a OnceCell<Window>,
    ctx: &'a OnceCell<GpuContext>,
    running: Option<Running<'a>>,
    error: Option<ViewError>,
    report: ViewReport,
}

impl<'a> App<'a> {
    /// Creates the window, the device that presents to it, the renderer and the overlay.
    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<(), ViewError> {
        let attrs = Window::default_attributes()
            .with_title(format!("atlastree view — {}", self.file.path().display()))
            .with_inner_size(PhysicalSize::new(
                self.opts.width.max(1),
                self.opts.height.max(1),
            ));
        let created = event_loop.create_window(attrs)?;
        let window_cell: &'a OnceCell<Window> = self.window;
        let window: &'a Window = window_cell.get_or_init(|| created);
        let opts = GpuOptions {
            label: "atlastree view",
            ..GpuOptions::default()
        };
        let (ctx, surface) =
            GpuContext::new_for_surface(&opts, event_loop.owned_display_handle(), window)?;
        let ctx_cell: &'a OnceCell<GpuContext> = self.ctx;
        let ctx: &'a GpuContext = ctx_cell.get_or_init(|| ctx);
        self.running = Some(Running::new(
            ctx,
            window,
            surface,
            self.file,
            self.bounds,
            &self.opts,
        )?);
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: ViewError) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        event_loop.exit();
    }
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() || self.error.is_some() {
            return;
        }
        if let Err(e) = self.start(event_loop) {
            self.fail(event_loop, e);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(running) = self.running.as_mut() else {
            return;
        };
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::RedrawRequested => running.frame(event_loop, &mut self.report),
            other => {
                running.input(event_loop, &other);
                Ok(())
            }
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(r) = &self.running {
            r.window.request_redraw();
        }
    }
}

/// Everything that exists while the window is open.
struct Running<'a> {
    window: &'a Window,
    ctx: &'a GpuContext,
    /// `ctx.adapter_summary()`, shown in the inspector.
    adapter: String,
    /// The file's parameters, read once (not through the memory map every frame).
    params: crate::model::BuildParams,
    bounds: (DVec3, DVec3),
    presenter: Presenter<'a>,
    /// The frame planner and the renderer that executes its plans.
    frame_loop: FrameLoop<'a>,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    settings: Settings,
    controller: Controller,
    path: Option<CameraPath>,
    path_fps: Option<f64>,
    /// Wall time at which follow mode (re)started, for real-time following.
    follow_start: Instant,
    /// Camera whose cut is kept while `freeze` is on.
    frozen: Option<Camera>,
    recorder: Option<Recorder>,
    times: FrameTimes,
    stats: FrameStats,
    /// Pager counters of the last frame: `None` until a pager is plugged in (shown as n/a).
    paging: Option<PagingStats>,
    started: Instant,
    last_frame: Option<Instant>,
    frames: u64,
    /// Mouse: dragging (look/orbit) and the last cursor position, physical pixels.
    dragging: bool,
    cursor: Option<(f64, f64)>,
    screenshot_requested: bool,
    screenshot_after: Option<u64>,
    exit_after_screenshot: bool,
    screenshot_file: PathBuf,
    out_dir: PathBuf,
    /// Camera paths written by `R` so far.
    recordings: Vec<PathBuf>,
    message: String,
}

impl<'a> Running<'a> {
    fn new(
        ctx: &'a GpuContext,
        window: &'a Window,
        surface: wgpu::Surface<'a>,
        file: &'a TreeFile,
        bounds: (DVec3, DVec3),
        opts: &ViewOptions,
    ) -> Result<Running<'a>, ViewError> {
        let size = window.inner_size();
        let (w, h) = (size.width.max(1), size.height.max(1));
        let presenter = Presenter::new(ctx, surface, w, h, opts.vsync)?;
        let ropts = RendererOptions {
            gpu_timing: opts.gpu_timing,
            ..RendererOptions::sized(w, h)
        };
        let frame_loop = match opts.capacity {
            None => FrameLoop::new(ctx, file, ropts)?,
            Some(k) => {
                // Blocks from the same file through the pager's loader threads (paper §6).
                let reopened = file.reopen().map_err(crate::render::RenderError::from)?;
                let source = std::sync::Arc::new(crate::paging::FileSource::new(
                    std::sync::Arc::new(reopened),
                ));
                FrameLoop::new_paged(
                    ctx,
                    file,
                    ropts,
                    crate::plan::PagingSetup {
                        pager: crate::paging::PagerOptions {
                            capacity: k,
                            ..Default::default()
                        },
                        source,
                        loader_threads: 2,
                    },
                )?
            }
        };
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(ctx.features.max_texture_dimension_2d as usize),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&ctx.device, COMPOSITE_FORMAT, Default::default());
        let up = file.to_params().up.vector();
        let aspect = f64::from(w) / f64::from(h);
        let controller = initial_controller(opts, up, bounds, aspect);
        let settings = Settings {
            mode: if opts.mode == Mode::TreeLevels {
                Mode::Tree
            } else {
                opts.mode
            },
            levels: opts.mode == Mode::TreeLevels,
            bounds: opts.bounds,
            freeze: false,
            texel_ratio: opts.texel_ratio,
            capacity: opts.capacity.unwrap_or(1024),
            show_overlay: !opts.hide_overlay,
            control: ControlMode::Fly,
            follow: opts.path.is_some(),
        };
        tracing::info!(adapter = %ctx.adapter_summary(), width = w, height = h, "viewer ready");
        Ok(Running {
            window,
            ctx,
            adapter: ctx.adapter_summary(),
            params: file.to_params(),
            bounds,
            presenter,
            frame_loop,
            egui_ctx,
            egui_state,
            egui_renderer,
            settings,
            controller,
            path: opts.path.clone(),
            path_fps: opts.path_fps,
            follow_start: Instant::now(),
            frozen: None,
            recorder: None,
            times: FrameTimes::default(),
            stats: FrameStats::default(),
            paging: None,
            started: Instant::now(),
            last_frame: None,
            frames: 0,
            dragging: false,
            cursor: None,
            screenshot_requested: false,
            screenshot_after: opts.screenshot_after,
            exit_after_screenshot: opts.exit_after_screenshot,
            screenshot_file: opts.screenshot.clone(),
            out_dir: opts.out_dir.clone(),
            recordings: Vec::new(),
            message: String::new(),
        })
    }

    /// Routes a window event to egui and, when egui does not want it, to the controls.
    fn input(&mut self, event_loop: &ActiveEventLoop, event: &WindowEvent) {
        let consumed = self.egui_state.on_window_event(self.window, event).consumed;
        match event {
            WindowEvent::Resized(size) => {
                self.presenter.resize(self.ctx, size.width, size.height);
            }
            WindowEvent::Focused(false) => {
                self.controller.release_all();
                self.dragging = false;
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let keyboard_taken = consumed && self.egui_ctx.egui_wants_keyboard_input();
                if !keyboard_taken || event.state == ElementState::Released {
                    self.key(event_loop, event);
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                if matches!(button, MouseButton::Left | MouseButton::Right) {
                    self.dragging = *state == ElementState::Pressed && !consumed;
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let now = (position.x, position.y);
                if let (true, Some((x, y))) = (self.dragging, self.cursor) {
                    self.follow_off();
                    self.controller.drag(now.0 - x, now.1 - y);
                }
                self.cursor = Some(now);
            }
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(*y),
                    MouseScrollDelta::PixelDelta(p) => p.y / PIXELS_PER_NOTCH,
                };
                self.controller.scroll(notches);
            }
            _ => {}
        }
    }

    /// Movement keys (held state) and one-shot keys (on press).
    fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyEvent) {
        let PhysicalKey::Code(code) = event.physical_key else {
            return;
        };
        let pressed = event.state == ElementState::Pressed;
        if let Some(k) = movement_key(code) {
            if pressed && k != Key::Fast {
                self.follow_off();
            }
            self.controller.set_key(k, pressed);
            return;
        }
        if !pressed || event.repeat {
            return;
        }
        let s = &mut self.settings;
        match code {
            KeyCode::Escape => event_loop.exit(),
            KeyCode::KeyF => self.frame_scene(),
            KeyCode::KeyP => self.screenshot_requested = true,
            KeyCode::KeyR => self.toggle_recording(),
            KeyCode::KeyL => s.levels = !s.levels,
            KeyCode::KeyB => s.bounds = !s.bounds,
            KeyCode::KeyG => s.freeze = !s.freeze,
            KeyCode::KeyH => s.show_overlay = !s.show_overlay,
            KeyCode::KeyO => {
                s.control = match s.control {
                    ControlMode::Fly => ControlMode::Orbit,
                    ControlMode::Orbit => ControlMode::Fly,
                }
            }
            KeyCode::Digit1 => s.mode = Mode::Tree,
            KeyCode::Digit2 => s.mode = Mode::Original,
            KeyCode::Digit3 => s.mode = Mode::Dummy,
            _ => {}
        }
    }

    fn follow_off(&mut self) {
        self.settings.follow = false;
    }

    fn frame_scene(&mut self) {
        self.follow_off();
        let (lo, hi) = self.bounds;
        self.controller.frame(lo, hi, self.aspect());
    }

    fn aspect(&self) -> f64 {
        let (w, h) = self.presenter.size();
        f64::from(w) / f64::from(h.max(1))
    }

    fn toggle_recording(&mut self) {
        match self.recorder.take() {
            None => {
                self.recorder = Some(Recorder::new());
                self.message = "recording the camera path (R stops)".to_owned();
            }
            Some(rec) => match self.save_recording(&rec) {
                Ok(Some(p)) => {
                    self.message = format!("path written: {}", p.display());
                    self.recordings.push(p);
                }
                Ok(None) => self.message = "recording was empty".to_owned(),
                Err(e) => self.message = e.to_string(),
            },
        }
    }

    /// Writes a recording to `out_dir/path_NNN.json` (atomically); `None` when it is empty.
    fn save_recording(&self, rec: &Recorder) -> Result<Option<PathBuf>, ViewError> {
        let Some(path) = rec.path() else {
            return Ok(None);
        };
        let file = numbered(&self.out_dir, "path", "json");
        write_atomic(&file, (path.to_json() + "\n").as_bytes())?;
        Ok(Some(file))
    }

    /// The camera of this frame: the path in follow mode (the controller follows along, so flying
    /// continues from there), else the controller after `dt` seconds of held keys.
    fn camera(&mut self, dt: f64) -> Camera {
        let aspect = self.aspect();
        if self.settings.follow
            && let Some(path) = &self.path
        {
            let t = match self.path_fps {
                Some(fps) => path.start() + self.frames as f64 / fps,
                None => follow_time(path, self.follow_start.elapsed().as_secs_f64()),
            };
            let mut cam = path.sample(t);
            cam.aspect = aspect;
            self.controller.eye = cam.eye;
            self.controller.look_along(cam.target - cam.eye);
            self.controller.fov_x_deg = cam.fov_x_deg;
            self.controller.near = cam.near;
            self.controller.far = cam.far;
            return cam;
        }
        self.follow_start = Instant::now();
        if self.controller.mode != self.settings.control {
            self.controller.set_mode(self.settings.control);
        }
        self.controller.update(dt);
        self.controller.camera(aspect)
    }

    /// One frame: camera, render, overlay, present, screenshot.
    fn frame(
        &mut self,
        event_loop: &ActiveEventLoop,
        report: &mut ViewReport,
    ) -> Result<(), ViewError> {
        let now = Instant::now();
        let dt = self.last_frame.map_or(0.0, |t| (now - t).as_secs_f64());
        if self.last_frame.is_some() {
            self.times.push(dt);
        }
        self.last_frame = Some(now);
        let (w, h) = self.presenter.size();
        self.frame_loop.renderer.resize(w, h)?;
        let camera = self.camera(dt);
        match (self.settings.freeze, self.frozen) {
            (true, None) => self.frozen = Some(camera),
            (false, Some(_)) => self.frozen = None,
            _ => {}
        }
        self.frame_loop.planner.freeze_selection(self.frozen);
        let selector = self.frozen.as_ref().unwrap_or(&camera);
        let scale = min_distance_scale(
            &self.params,
            &SelectOptions {
                screen_width: w,
                texel_ratio: self.settings.texel_ratio,
                fov_x_deg: selector.fov_x_deg,
            },
        )?;
        // The planner pages on the wall clock; the capacity slider applies live, up to the capacity the
        // texture arrays were sized for.
        let clock = self.started.elapsed().as_secs_f64();
        if let Some(pager) = self.frame_loop.pager()
            && pager.options().capacity != self.settings.capacity
        {
            self.frame_loop.planner.set_capacity(self.settings.capacity);
        }
        self.frame_loop.set_clock(clock);
        self.stats = self
            .frame_loop
            .render(&camera, scale, self.settings.render_mode())?;
        self.paging = self.stats.plan.paging.map(|p| PagingStats {
            needed: p.pager().usage.needed,
            resident: p.pager().resident,
            in_flight: p.session.in_flight + p.session.queued,
            bytes_per_second: if dt > 0.0 {
                p.pager().bytes_loaded as f64 / dt
            } else {
                0.0
            },
            coarser_share: p.coarse.share(),
        });
        if let Some(rec) = &mut self.recorder {
            rec.push(clock, &camera);
        }
        let (primitives, textures) = self.overlay(&camera);
        self.present(event_loop, primitives, textures, report)?;
        self.frames += 1;
        report.frames = self.frames;
        Ok(())
    }

    /// Runs the egui pass: bounds lines and the inspector; applies the inspector's requests.
    fn overlay(&mut self, camera: &Camera) -> (Vec<egui::ClippedPrimitive>, egui::TexturesDelta) {
        let raw = self.egui_state.take_egui_input(self.window);
        let boxes = if self.settings.bounds {
            self.node_boxes()
        } else {
            Vec::new()
        };
        let size = self.presenter.size();
        let mut settings = self.settings.clone();
        let mut requests = Requests::default();
        let readout = Readout {
            stats: &self.stats,
            times: &self.times,
            paging: self.paging,
            size,
            camera,
            speed: self.controller.speed,
            adapter: &self.adapter,
            recording: self.recorder.as_ref().map(Recorder::len),
            has_path: self.path.is_some(),
            message: &self.message,
        };
        let full = self.egui_ctx.run_pass(raw, |ctx| {
            overlay::paint_bounds(ctx, camera, &boxes, size);
            requests = overlay::inspector(ctx, &mut settings, &readout);
        });
        if settings.follow && !self.settings.follow {
            self.follow_start = Instant::now();
        }
        self.settings = settings;
        self.egui_state
            .handle_platform_output(self.window, full.platform_output);
        if requests.frame_scene {
            self.frame_scene();
        }
        if requests.screenshot {
            self.screenshot_requested = true;
        }
        if requests.toggle_recording {
            self.toggle_recording();
        }
        let primitives = self.egui_ctx.tessellate(full.shapes, full.pixels_per_point);
        (primitives, full.textures_delta)
    }

    /// World bounds and levels of the last frame's cut items.
    fn node_boxes(&self) -> Vec<NodeBox> {
        let mut boxes = Vec::new();
        for (t, cut) in self.frame_loop.cuts().iter().enumerate() {
            let Some(nodes) = self.frame_loop.planner.tree(t) else {
                continue;
            };
            boxes.extend(cut.items.iter().filter_map(|item| {
                let n = nodes.get(item.node.idx())?;
                Some(NodeBox {
                    lo: DVec3::from_array(n.bounds_min),
                    hi: DVec3::from_array(n.bounds_max),
                    level: item.level,
                })
            }));
        }
        boxes
    }

    /// Copies the frame into the composite, draws the overlay on it, blits it into the surface texture,
    /// takes a due screenshot, presents.
    fn present(
        &mut self,
        event_loop: &ActiveEventLoop,
        primitives: Vec<egui::ClippedPrimitive>,
        mut textures: egui::TexturesDelta,
        report: &mut ViewReport,
    ) -> Result<(), ViewError> {
        // Taken out so that no early return drops undelivered deltas.
        let set = std::mem::take(&mut textures.set);
        let free = std::mem::take(&mut textures.free);
        let device = &self.ctx.device;
        let queue = &self.ctx.queue;
        for (id, deltas) in &set {
            for delta in deltas {
                self.egui_renderer.update_texture(device, queue, *id, delta);
            }
        }
        let (w, h) = self.presenter.size();
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [w, h],
            pixels_per_point: self.egui_ctx.pixels_per_point(),
        };
        let surface_texture = self.acquire();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("view frame"),
        });
        self.presenter
            .copy_frame(&mut encoder, &self.frame_loop.renderer.color);
        let extra =
            self.egui_renderer
                .update_buffers(device, queue, &mut encoder, &primitives, &screen);
        {
            let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("overlay"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: self.presenter.composite_view(),
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let mut pass = pass.forget_lifetime();
            self.egui_renderer.render(&mut pass, &primitives, &screen);
        }
        if let Some(st) = &surface_texture {
            self.presenter.blit(&mut encoder, &st.texture);
        }
        queue.submit(extra.into_iter().chain([encoder.finish()]));
        for id in &free {
            self.egui_renderer.free_texture(id);
        }
        let frame_number = self.frames + 1;
        let scripted = self.screenshot_after == Some(frame_number);
        if scripted || self.screenshot_requested {
            self.screenshot_requested = false;
            let file = if scripted {
                self.screenshot_file.clone()
            } else {
                numbered(&self.out_dir, "screenshot", "png")
            };
            let source = self.screenshot(surface_texture.as_ref().map(|s| &s.texture), &file)?;
            self.message = format!("screenshot {} ({})", file.display(), source.name());
            tracing::info!(file = %file.display(), w, h, frame_number, source = source.name(), "screenshot");
            report.screenshots.push((file, source));
        }
        if let Some(st) = surface_texture {
            self.window.pre_present_notify();
            self.ctx.queue.present(st);
        }
        if scripted && self.exit_after_screenshot {
            event_loop.exit();
        }
        Ok(())
    }

    /// The surface texture to draw into, or `None` this frame (timeout, occluded; a lost or outdated
    /// surface is reconfigured for the next frame).
    fn acquire(&self) -> Option<wgpu::SurfaceTexture> {
        match self.presenter.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                self.presenter.reconfigure(self.ctx);
                Some(t)
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.presenter.reconfigure(self.ctx);
                None
            }
            other => {
                tracing::warn!(status = ?other, "no surface texture this frame");
                None
            }
        }
    }

    /// Reads the presented image (or the composite) and writes it as PNG, atomically.
    fn screenshot(
        &self,
        surface: Option<&wgpu::Texture>,
        file: &Path,
    ) -> Result<ShotSource, ViewError> {
        let (w, h) = self.presenter.size();
        let (rgba, source) = self.presenter.read(self.ctx, surface)?;
        let mut png = Vec::new();
        let img = image::RgbaImage::from_raw(w, h, rgba).ok_or_else(|| ViewError::Write {
            path: file.to_owned(),
            message: "the readback does not match the window size".to_owned(),
        })?;
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .map_err(|e| ViewError::Write {
                path: file.to_owned(),
                message: e.to_string(),
            })?;
        write_atomic(file, &png)?;
        Ok(source)
    }

    /// Saves an unfinished recording and fills the final report fields.
    fn finish(&mut self, report: &mut ViewReport) -> Result<(), ViewError> {
        if let Some(rec) = self.recorder.take()
            && let Some(p) = self.save_recording(&rec)?
        {
            self.recordings.push(p);
        }
        report.recordings = std::mem::take(&mut self.recordings);
        report.adapter = self.ctx.adapter_summary();
        report.size = self.presenter.size();
        report.warnings = (self.frame_loop.planner.failure_warnings().into_iter())
            .map(|w| format!("during the session, {w}"))
            .collect();
        let secs = self.started.elapsed().as_secs_f64();
        report.fps = if secs > 0.0 {
            self.frames as f64 / secs
        } else {
            0.0
        };
        Ok(())
    }
}

/// The controller at start: the given camera, else the path's first camera, else framing the scene.
fn initial_controller(
    opts: &ViewOptions,
    up: DVec3,
    (lo, hi): (DVec3, DVec3),
    aspect: f64,
) -> Controller {
    if let Some(c) = opts.camera {
        // `--camera` names no clip planes: the far plane reaches the scene's farthest corner (a 20 km
        // terrain seen from 110 km was clipped away by the fixed 100 km; fault hunt, session 37).
        let mut ctl = Controller::from_camera(&c, up);
        ctl.far = ctl.far.max(far_to_see(c.eye, lo, hi));
        return ctl;
    }
    if let Some(p) = &opts.path {
        return Controller::from_camera(&p.sample(p.start()), up);
    }
    let centre = (lo + hi) * 0.5;
    let look = Camera {
        eye: centre + up,
        target: centre,
        up,
        fov_x_deg: 60.0,
        aspect,
        near: 0.25,
        far: 1.0e5,
    };
    let mut c = Controller::from_camera(&look, up);
    c.frame(lo, hi, aspect);
    c
}

/// A far plane, world units, beyond every corner of the box `[lo, hi]` seen from `eye` (twice the
/// farthest corner's distance, as [`Controller::frame`] leaves room); 0 for a box that is not finite.
fn far_to_see(eye: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    if !(lo.is_finite() && hi.is_finite()) {
        return 0.0;
    }
    let corners = (0..8).map(|k| {
        let pick = |bit: u32, a: f64, b: f64| if k & bit == 0 { a } else { b };
        DVec3::new(
            pick(1, lo.x, hi.x),
            pick(2, lo.y, hi.y),
            pick(4, lo.z, hi.z),
        )
    });
    2.0 * corners.map(|c| c.distance(eye)).fold(0.0, f64::max)
}

fn movement_key(code: KeyCode) -> Option<Key> {
    Some(match code {
        KeyCode::KeyW | KeyCode::ArrowUp => Key::Forward,
        KeyCode::KeyS | KeyCode::ArrowDown => Key::Back,
        KeyCode::KeyA | KeyCode::ArrowLeft => Key::Left,
        KeyCode::KeyD | KeyCode::ArrowRight => Key::Right,
        KeyCode::KeyQ | KeyCode::PageDown => Key::Down,
        KeyCode::KeyE | KeyCode::PageUp => Key::Up,
        KeyCode::ShiftLeft | KeyCode::ShiftRight => Key::Fast,
        _ => return None,
    })
}

/// `dir/stem_NNNN.ext` with the first number not yet taken.
fn numbered(dir: &Path, stem: &str, ext: &str) -> PathBuf {
    (0u32..)
        .map(|i| dir.join(format!("{stem}_{i:04}.{ext}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| dir.join(format!("{stem}.{ext}")))
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so no reader
/// sees a half-written file. Creates the directory.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ViewError> {
    let err = |e: std::io::Error| ViewError::Write {
        path: path.to_owned(),
        message: e.to_string(),
    };
    std::fs::create_dir_all(crate::util::parent_dir(path)).map_err(err)?;
    crate::util::write_atomic(path, bytes).map_err(err)
}

#[cfg(test)]
mod far_tests {
    use super::far_to_see;
    use glam::DVec3;

    /// The far plane reaches the box's farthest corner: a 20 km terrain seen from 110 km away needs more
    /// than the default 100 km; a box that is not finite asks for nothing.
    #[test]
    fn the_far_plane_reaches_the_farthest_corner() {
        let (lo, hi) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(20e3, 50.0, 20e3));
        let eye = DVec3::new(10e3, 110e3, 10e3);
        let farthest = DVec3::new(0.0, 0.0, 0.0).distance(eye);
        assert_eq!(far_to_see(eye, lo, hi), 2.0 * farthest);
        assert!(far_to_see(eye, lo, hi) > 1e5);
        assert_eq!(far_to_see(eye, DVec3::splat(f64::NAN), hi), 0.0);
    }
}
