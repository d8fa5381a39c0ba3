//! Texel-density debug pass: how many texels of the texture actually sampled reach each screen pixel.
//!
//! The pass draws the cut of [`super::Mode::Tree`] with the `DENSITY = 1` variant of `shaders/tree.wgsl`
//! into an `Rgba32Float` target, on the pixels the colour pass draws (MASK cutoffs and the blend pass's
//! discards applied; session 38). Per pixel it writes the singular values of the Jacobian
//! d(texel of mip 0)/d(screen pixel), from the quad derivatives of the UV times the texture size (atlas
//! array size, or the stored sides of the original texture): the smaller one is the texel density along the
//! least-sampled screen direction (< 1: the texture is magnified there), the larger one the density the
//! isotropic mip selection sees. The paper's selection criterion (§3.3, `min_distance`) promises that an
//! atlas delivers at least `texel_ratio` texels per pixel; original textures are the source resolution
//! and may magnify.

use super::pipeline::{DENSITY_FORMAT, PassPipelines, Specialisation, vertex_layout};
use crate::gpu::{GpuContext, GpuError};

/// Clear value of the density target: source −1 marks a pixel nothing was drawn on.
pub(super) const CLEAR: wgpu::Color = wgpu::Color {
    r: 0.0,
    g: 0.0,
    b: -1.0,
    a: 0.0,
};

/// Bytes per texel of [`DENSITY_FORMAT`].
const TEXEL_BYTES: u32 = 16;

/// The density of one drawn pixel.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TexelDensity {
    /// Texels (mip 0) per pixel along the least-sampled screen direction.
    pub min: f32,
    /// Texels (mip 0) per pixel along the most-sampled screen direction.
    pub max: f32,
    /// Drawn with an original texture (else an atlas).
    pub original: bool,
    /// Tree level of the atlas ([`LEVEL_ORIGINAL`](super::wgsl::tree::LEVEL_ORIGINAL) for original
    /// textures).
    pub level: u32,
}

/// A read-back density frame, rows top to bottom; `None` where nothing was drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityFrame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Option<TexelDensity>>,
}

impl DensityFrame {
    /// The minimum texel density (texels of mip 0 per pixel along the least-sampled direction) of every
    /// pixel, row-major; NaN where nothing was drawn. Input for `report::metrics::magnified_share` and
    /// `Histogram::log2`.
    pub fn min_density(&self) -> Vec<f32> {
        self.pixels
            .iter()
            .map(|p| p.map_or(f32::NAN, |d| d.min))
            .collect()
    }
}

/// Pixel counts of `values` by ⌊log2 v⌋ (keys ascending); values ≤ 0 or not finite are left out.
pub fn log2_histogram(values: impl IntoIterator<Item = f32>) -> Vec<(i32, usize)> {
    let mut bins = std::collections::BTreeMap::<i32, usize>::new();
    for v in values {
        if v.is_finite() && v > 0.0 {
            *bins.entry(v.log2().floor() as i32).or_default() += 1;
        }
    }
    bins.into_iter().collect()
}

/// The density pipelines (one per [`Group`], created on first use) and the `Rgba32Float` target.
pub(super) struct DensityTarget {
    pub pipelines: PassPipelines,
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
}

impl DensityTarget {
    /// `spec`: the tree shader's specialisation for the file (the density flag is set here).
    pub(super) fn new(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        spec: Specialisation,
        width: u32,
        height: u32,
    ) -> DensityTarget {
        let pipelines = PassPipelines::new(
            device,
            "tree density",
            super::wgsl::tree::WGSL,
            &[layout],
            vertex_layout(),
            Specialisation {
                density: true,
                ..spec
            },
        );
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("density target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DENSITY_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        DensityTarget {
            pipelines,
            texture,
            view,
        }
    }

    /// Reads the target back (blocks until the GPU is done).
    pub(super) fn read(&self, ctx: &GpuContext) -> Result<DensityFrame, GpuError> {
        let (width, height) = (self.texture.width(), self.texture.height());
        let data = crate::gpu::readback_texels(ctx, &self.texture, 0, TEXEL_BYTES)?;
        let pixels = data
            .chunks_exact(TEXEL_BYTES as usize)
            .map(|t| {
                let v: [f32; 4] = bytemuck::pod_read_unaligned(t);
                (v[2] >= 0.0).then_some(TexelDensity {
                    min: v[0],
                    max: v[1],
                    original: v[2] > 0.5,
                    level: v[3] as u32,
                })
            })
            .collect();
        Ok(DensityFrame {
            width,
            height,
            pixels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::log2_histogram;

    #[test]
    fn log2_histogram_bins_by_floor_log2_and_skips_non_positive() {
        let h = log2_histogram([
            0.2,
            0.25,
            0.5,
            0.99,
            1.0,
            1.99,
            2.0,
            0.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
        ]);
        assert_eq!(h, vec![(-3, 1), (-2, 1), (-1, 2), (0, 2), (1, 1)]);
    }
}
