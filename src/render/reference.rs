//! Ground truth for the accuracy measures of `render` and `sweep` (`--reference supersampled[:S]`): the
//! frame drawn with the original textures (naive draws, [`Mode::Original`]) at S × S times the pixels, then
//! box-filtered on the GPU in linear light down to the frame size (`shaders/downsample.wgsl`; its CPU twin
//! is [`crate::report::supersample::box_downsample_linear`]). Where the original textures alias or
//! alpha-tested coverage thins through the mips, this reference does not: it shows where the tree's loss
//! is the tree's and where the original falls short too.

use super::frame::Renderer;
use super::pipeline::{COLOR_FORMAT, DEPTH_FORMAT};
use super::wgsl::downsample::{self, Params, binding};
use super::{Mode, RenderError};
use crate::gpu::readback_rgba8;
use crate::plan::FramePlan;

/// What frames are compared against.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Reference {
    /// The original textures drawn at the frame's own resolution with hardware mip-mapping.
    Original,
    /// The original textures at `S × S` times the pixels, box-filtered in linear light.
    Supersampled(u32),
}

impl Reference {
    /// S of `supersampled` without a factor.
    pub const DEFAULT_FACTOR: u32 = 4;
    /// The largest S accepted.
    pub const MAX_FACTOR: u32 = 8;

    /// `original`, `supersampled:S`.
    pub fn name(&self) -> String {
        match self {
            Reference::Original => "original".into(),
            Reference::Supersampled(s) => format!("supersampled:{s}"),
        }
    }
}

impl std::str::FromStr for Reference {
    type Err = String;
    fn from_str(s: &str) -> Result<Reference, String> {
        let bad = || {
            format!(
                "{s:?}: expected original, supersampled or supersampled:S with S from 1 to {}",
                Reference::MAX_FACTOR
            )
        };
        match s.split_once(':') {
            None if s == "original" => Ok(Reference::Original),
            None if s == "supersampled" => Ok(Reference::Supersampled(Reference::DEFAULT_FACTOR)),
            Some(("supersampled", f)) => match f.parse::<u32>() {
                Ok(v) if (1..=Reference::MAX_FACTOR).contains(&v) => Ok(Reference::Supersampled(v)),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }
}

/// The supersampled targets, the downsample pass and its output, for one frame size and factor.
pub(super) struct Supersample {
    size: (u32, u32),
    factor: u32,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    out: wgpu::Texture,
    out_view: wgpu::TextureView,
    pipeline: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
}

impl Supersample {
    fn new(device: &wgpu::Device, size: (u32, u32), factor: u32) -> Supersample {
        let texture = |label, w, h, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        use wgpu::TextureUsages as U;
        let (sw, sh) = (size.0 * factor, size.1 * factor);
        let color = texture(
            "supersampled colour",
            sw,
            sh,
            COLOR_FORMAT,
            U::RENDER_ATTACHMENT | U::TEXTURE_BINDING | U::COPY_SRC,
        );
        let depth = texture(
            "supersampled depth",
            sw,
            sh,
            DEPTH_FORMAT,
            U::RENDER_ATTACHMENT,
        );
        let out = texture(
            "supersampled reference",
            size.0,
            size.1,
            COLOR_FORMAT,
            U::RENDER_ATTACHMENT | U::COPY_SRC,
        );
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (color_view, depth_view, out_view) = (view(&color), view(&depth), view(&out));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("downsample group 0"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: binding::SOURCE,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: binding::PARAMS,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let params = wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("downsample params"),
                contents: bytemuck::bytes_of(&Params {
                    factor,
                    ..Params::default()
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("downsample"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: binding::SOURCE,
                    resource: wgpu::BindingResource::TextureView(&color_view),
                },
                wgpu::BindGroupEntry {
                    binding: binding::PARAMS,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        let pipeline = crate::gpu::fullscreen_pipeline(
            device,
            "downsample",
            downsample::WGSL,
            &layout,
            COLOR_FORMAT,
        );
        Supersample {
            size,
            factor,
            color,
            color_view,
            depth_view,
            out,
            out_view,
            pipeline,
            group,
        }
    }
}

/// [`RenderError::BadSupersample`] where a `width × height` frame at `factor` times its sides exceeds the
/// device's texture size, or `factor` is 0: asked before a run starts (`render` found out at its first
/// reference frame, after removing the earlier run's frames, and `sweep` after its builds: fault hunt,
/// session 35) and by [`Renderer::execute_supersampled`].
pub fn check_supersample(
    ctx: &crate::gpu::GpuContext,
    width: u32,
    height: u32,
    factor: u32,
) -> Result<(), RenderError> {
    let limit = ctx.device.limits().max_texture_dimension_2d;
    let (sw, sh) = (width.saturating_mul(factor), height.saturating_mul(factor));
    if factor == 0 || sw > limit || sh > limit {
        return Err(RenderError::BadSupersample {
            width,
            height,
            factor,
            limit,
        });
    }
    Ok(())
}

impl Renderer<'_> {
    /// The supersampled reference of `plan` ([`Reference::Supersampled`]): the plan drawn with the
    /// original textures ([`Mode::Original`], all blocks resident) at `factor` times the frame's width and
    /// height, box-filtered in linear light to the frame size and read back (`width · height · 4` sRGB
    /// RGBA bytes, rows top to bottom). The colour target keeps the last ordinary frame. Errors: those of
    /// [`Renderer::execute`] in original mode (paged renderers refuse it), and [`RenderError::BadSupersample`]
    /// when the supersampled frame exceeds the device's texture size or `factor` is 0.
    pub fn execute_supersampled(
        &mut self,
        plan: &FramePlan,
        factor: u32,
    ) -> Result<Vec<u8>, RenderError> {
        let (w, h) = (self.opts.width, self.opts.height);
        check_supersample(self.ctx, w, h, factor)?;
        let (sw, sh) = (w * factor, h * factor);
        let mut ss = match self.supersample.take() {
            Some(s) if s.size == (w, h) && s.factor == factor => s,
            _ => Supersample::new(&self.ctx.device, (w, h), factor),
        };
        self.swap_targets(&mut ss, (sw, sh));
        let drawn = self.execute(plan, Mode::Original);
        self.swap_targets(&mut ss, (w, h));
        let result = drawn.and_then(|_| {
            let mut encoder =
                self.ctx
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("downsample"),
                    });
            {
                let mut rp =
                    crate::gpu::begin_fullscreen_pass(&mut encoder, "downsample", &ss.out_view);
                rp.set_pipeline(&ss.pipeline);
                rp.set_bind_group(0, &ss.group, &[]);
                rp.draw(0..3, 0..1);
            }
            self.ctx.queue.submit([encoder.finish()]);
            Ok(readback_rgba8(self.ctx, &ss.out)?)
        });
        self.supersample = Some(ss);
        result
    }

    /// The last supersampled frame before its downsample (`(width, height, sRGB RGBA bytes)`), `None`
    /// before the first [`Renderer::execute_supersampled`]: what the CPU twin of the downsample
    /// ([`crate::report::supersample::box_downsample_linear`]) is checked on.
    pub fn read_supersampled(&self) -> Result<Option<(u32, u32, Vec<u8>)>, RenderError> {
        let Some(ss) = &self.supersample else {
            return Ok(None);
        };
        let (w, h) = (ss.size.0 * ss.factor, ss.size.1 * ss.factor);
        Ok(Some((w, h, readback_rgba8(self.ctx, &ss.color)?)))
    }

    /// Exchanges the renderer's colour and depth targets with `ss`'s supersampled ones and sets the frame
    /// size the renderer believes in.
    fn swap_targets(&mut self, ss: &mut Supersample, size: (u32, u32)) {
        std::mem::swap(&mut self.color, &mut ss.color);
        std::mem::swap(&mut self.color_view, &mut ss.color_view);
        std::mem::swap(&mut self.depth_view, &mut ss.depth_view);
        (self.opts.width, self.opts.height) = size;
    }
}
