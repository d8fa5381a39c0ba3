//! Getting frames onto the window: the surface configuration, the composite image (the renderer's frame
//! with the overlay drawn on top; what screenshots read) and the blit pass into the surface texture
//! (`shaders/blit.wgsl`).
//!
//! Per frame: `renderer.color` (sRGB RGBA8) is copied into the composite (`Rgba8Unorm`, the same bytes), egui
//! draws into the composite, and the blit copies it texel for texel into the surface texture through a
//! non-sRGB view, so the window shows exactly the bytes a headless `render` would write to a PNG.

use super::ViewError;
use crate::gpu::{GpuContext, readback_rgba8, readback_texels};
use crate::render::wgsl::blit;

/// Format of the composite image and of the overlay's target: raw sRGB-encoded bytes.
pub(super) const COMPOSITE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Where a screenshot's pixels came from.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum ShotSource {
    /// The surface texture about to be presented (the surface allows `COPY_SRC`).
    Surface,
    /// The composite image the surface texture was blitted from.
    Composite,
}

impl ShotSource {
    pub fn name(self) -> &'static str {
        match self {
            ShotSource::Surface => "surface",
            ShotSource::Composite => "composite",
        }
    }
}

/// The configured surface and what the blit needs.
pub(super) struct Presenter<'w> {
    pub surface: wgpu::Surface<'w>,
    pub config: wgpu::SurfaceConfiguration,
    /// Format of the views the blit renders to (the surface format without sRGB).
    target_format: wgpu::TextureFormat,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    composite: Composite,
    /// Whether screenshots can read the surface texture itself.
    pub readable_surface: bool,
}

/// The composite image and the blit's bind group reading it.
struct Composite {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    group: wgpu::BindGroup,
}

/// A 4-byte 8-bit colour format the blit can write raw bytes to, and whether it is BGRA.
fn byte_format(format: wgpu::TextureFormat) -> Option<bool> {
    use wgpu::TextureFormat as F;
    match format.remove_srgb_suffix() {
        F::Rgba8Unorm => Some(false),
        F::Bgra8Unorm => Some(true),
        _ => None,
    }
}

impl<'w> Presenter<'w> {
    /// Configures `surface` at `width`×`height` physical pixels (at least 1×1) with an RGBA8/BGRA8 format,
    /// FIFO (`vsync`) or the lowest-latency mode available, and builds the blit pipeline.
    pub(super) fn new(
        ctx: &GpuContext,
        surface: wgpu::Surface<'w>,
        width: u32,
        height: u32,
        vsync: bool,
    ) -> Result<Presenter<'w>, ViewError> {
        // Past the device's largest texture wgpu panics configuring the surface (`view --width 20000`;
        // fault hunt, session 37); `render` refuses such a frame as well.
        let limit = ctx.device.limits().max_texture_dimension_2d;
        if width > limit || height > limit {
            return Err(ViewError::Surface {
                message: format!(
                    "the window is {width}x{height} pixels; each side must be at most {limit} on this \
                     device (lower --width / --height)"
                ),
            });
        }
        let caps = surface.get_capabilities(&ctx.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| byte_format(*f).is_some())
            .ok_or_else(|| ViewError::Surface {
                message: format!(
                    "the window surface offers no RGBA8/BGRA8 format (it offers {:?})",
                    caps.formats
                ),
            })?;
        let target_format = format.remove_srgb_suffix();
        let readable_surface = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
        if readable_surface {
            usage |= wgpu::TextureUsages::COPY_SRC;
        }
        let present_mode = if vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        let config = wgpu::SurfaceConfiguration {
            usage,
            format,
            width: width.max(1),
            height: height.max(1),
            present_mode,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            color_space: wgpu::SurfaceColorSpace::Auto,
            view_formats: if target_format == format {
                vec![]
            } else {
                vec![target_format]
            },
        };
        surface.configure(&ctx.device, &config);
        let device = &ctx.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blit"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: blit::binding::SOURCE,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let pipeline = blit_pipeline(device, &layout, target_format);
        let composite = Composite::new(device, &layout, config.width, config.height);
        tracing::info!(
            ?format,
            ?present_mode,
            readable_surface,
            "surface configured"
        );
        Ok(Presenter {
            surface,
            config,
            target_format,
            pipeline,
            layout,
            composite,
            readable_surface,
        })
    }

    /// Reconfigures the surface and recreates the composite at `width`×`height` (no-op when unchanged or
    /// empty, e.g. a minimised window).
    pub(super) fn resize(&mut self, ctx: &GpuContext, width: u32, height: u32) {
        // A window stretched past the device's largest texture is drawn at that size (wgpu panicked).
        let limit = ctx.device.limits().max_texture_dimension_2d;
        let (width, height) = (width.min(limit), height.min(limit));
        if width == 0 || height == 0 || (width, height) == (self.config.width, self.config.height) {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&ctx.device, &self.config);
        self.composite = Composite::new(&ctx.device, &self.layout, width, height);
    }

    /// Re-applies the configuration (after a lost or outdated surface).
    pub(super) fn reconfigure(&self, ctx: &GpuContext) {
        self.surface.configure(&ctx.device, &self.config);
    }

    /// Size of the surface and composite, physical pixels.
    pub(super) fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    /// The composite image's view for the overlay pass.
    pub(super) fn composite_view(&self) -> &wgpu::TextureView {
        &self.composite.view
    }

    /// Records the copy of the renderer's frame `color` into the composite (sizes must match).
    pub(super) fn copy_frame(&self, encoder: &mut wgpu::CommandEncoder, color: &wgpu::Texture) {
        let size = wgpu::Extent3d {
            width: color.width().min(self.config.width),
            height: color.height().min(self.config.height),
            depth_or_array_layers: 1,
        };
        encoder.copy_texture_to_texture(
            color.as_image_copy(),
            self.composite.texture.as_image_copy(),
            size,
        );
    }

    /// Records the blit of the composite into `target` (the surface texture).
    pub(super) fn blit(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Texture) {
        let view = target.create_view(&wgpu::TextureViewDescriptor {
            format: Some(self.target_format),
            ..Default::default()
        });
        let mut pass = crate::gpu::begin_fullscreen_pass(encoder, "blit", &view);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.composite.group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Reads the frame back as RGBA bytes, rows top to bottom: from `surface` (the texture about to be
    /// presented) when there is one and the surface allows it, else from the composite. Blocks until the
    /// GPU is done.
    pub(super) fn read(
        &self,
        ctx: &GpuContext,
        surface: Option<&wgpu::Texture>,
    ) -> Result<(Vec<u8>, ShotSource), ViewError> {
        if let Some(surface) = surface.filter(|_| self.readable_surface)
            && let Some(bgra) = byte_format(surface.format())
        {
            let mut rgba = readback_texels(ctx, surface, 0, 4)?;
            if bgra {
                rgba.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
            }
            return Ok((rgba, ShotSource::Surface));
        }
        Ok((
            readback_rgba8(ctx, &self.composite.texture)?,
            ShotSource::Composite,
        ))
    }
}

impl Composite {
    fn new(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        width: u32,
        height: u32,
    ) -> Composite {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("composite"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COMPOSITE_FORMAT,
            usage: wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blit source"),
            layout,
            entries: &[wgpu::BindGroupEntry {
                binding: blit::binding::SOURCE,
                resource: wgpu::BindingResource::TextureView(&view),
            }],
        });
        Composite {
            texture,
            view,
            group,
        }
    }
}

fn blit_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    crate::gpu::fullscreen_pipeline(device, "blit", blit::WGSL, layout, format)
}
