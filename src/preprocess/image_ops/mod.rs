//! CPU image operations for atlas rasterisation, all in linear light (paper §5.1, §5.2.3).
//!
//! The paper renders textured quads into a P-buffer and notes that "more sophisticated filtering algorithms
//! could be used" (§5.2.3); this module is that alternative, on the CPU:
//!
//! - [`srgb`]: exact sRGB8 ↔ linear conversion (the round trip u8 → linear → u8 is the identity).
//! - [`LinearImage`]: linear RGB premultiplied by linear alpha, `f32` per channel. Every filter below works
//!   on premultiplied values, so transparent texels never darken their neighbours (no dark fringes on
//!   alpha-tested edges after halving).
//! - [`halve`], [`downsample`], [`MipChain`], [`mip_chain_rgba8`]: mip generation with a box (default) or a
//!   Kaiser-windowed sinc kernel ([`MipFilter`]); odd and non-square sizes use exact footprint weights.
//! - [`preserve_coverage`]: optional α-test coverage kept through the mips of MASK areas ([`AlphaMips`]).
//! - [`sample_footprint`]: minification-correct sampling of a mip chain with per-axis wrap modes, in f64 UV
//!   maths (UVs of ±1e5 are reduced by their period first).
//! - [`draw_rect`]: fill one packed texture area of a leaf atlas, border included (§5.2.2, §5.2.3);
//!   [`draw_leaf_banded`]: a leaf's rects drawn, halved and encoded band by band (the same bytes).
//! - [`combine_quadrants`]: the inner-node atlas from four children's level-1 mips (§5.1).
//! - [`resample_rect`] / [`resample_square`]: original textures at their stored power-of-two sides (a
//!   Catmull-Rom cubic where they grow: [`magnify_cubic`]),
//!   seamless under wrap.
//!
//! Conventions: texel `(x, y)` has `y` = row from the top; UV `(0, 0)` is the top-left corner of the image,
//! `u` runs along `x` and `v` along `y` (glTF); texel centres are at `(x + 0.5) / width`.

mod band;
mod coverage;
mod linear;
mod magnify;
mod mip;
mod raster;
mod sample;
pub mod srgb;
mod srgb_simd;

pub use band::{BandedLevels, draw_leaf_banded};
pub use coverage::{AlphaMips, CoverageRegion, preserve_coverage};
pub use linear::LinearImage;
pub use magnify::magnify_cubic;
pub use mip::{
    MipChain, MipFilter, MipOptions, downsample, halve, mip_chain_rgba8, mip_chain_rgba8_with,
};
pub use raster::{
    RectJob, RectPlan, combine_quadrants, draw_rect, neutral_fill, resample_rect, resample_square,
};
pub(crate) use sample::period_shift;
pub use sample::{FootprintPlan, MAX_ANISOTROPY, sample_footprint, sample_planned, wrap_index};
pub use srgb::{linear_to_srgb8, srgb8_to_linear};

thread_local! {
    /// Set by [`on_this_thread`]: this thread's per-texel passes stay on it.
    static ON_THIS_THREAD: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` with the per-texel passes of [`LinearImage::from_decoded`] and the mip halving
/// ([`MipChain::build`]) on the calling thread alone, without splitting them into rayon tasks (the
/// same texels: each is computed on its own). For work done while other threads wait on it: a
/// thread that waits inside a rayon task must not hold a piece of that work, or both wait forever
/// (`image_cache::ImageCache` builds an image's chain once while the threads that need it wait).
pub fn on_this_thread<T>(f: impl FnOnce() -> T) -> T {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            ON_THIS_THREAD.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(ON_THIS_THREAD.with(|c| c.replace(true)));
    f()
}

/// Whether a per-texel pass over `texels` texels splits into rayon tasks: at `threshold` texels or
/// more, outside [`on_this_thread`].
fn split(texels: usize, threshold: usize) -> bool {
    texels >= threshold && !ON_THIS_THREAD.with(|c| c.get())
}

/// Errors of the image operations; every variant names the sizes and coordinates involved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageOpsError {
    #[error("decoded image is {width}×{height} but has {pixels} pixels (expected width·height)")]
    PixelCount {
        width: u32,
        height: u32,
        pixels: usize,
    },
    #[error(
        "level 0 was encoded band by band, but coverage regions ({regions}) would rescale it (banded \
         levels are made only without them)"
    )]
    BandedWithCoverage { regions: usize },
    #[error("linear image is {width}×{height} but has {texels} texels (expected width·height)")]
    TexelCount {
        width: u32,
        height: u32,
        texels: usize,
    },
    #[error("texel ({x}, {y}) is outside the {width}×{height} image")]
    OutOfBounds {
        x: u32,
        y: u32,
        width: u32,
        height: u32,
    },
    #[error("rect {what} [{x}, {y}, {w}, {h}] does not fit the {width}×{height} destination")]
    RectOutside {
        what: &'static str,
        x: u32,
        y: u32,
        w: u32,
        h: u32,
        width: u32,
        height: u32,
    },
    #[error("rect inner [{x}, {y}, {w}, {h}] is empty: the UV mapping is undefined")]
    EmptyInner { x: u32, y: u32, w: u32, h: u32 },
    #[error("rect UV range [{u0}, {v0}]–[{u1}, {v1}] is not finite")]
    NonFiniteUv { u0: f64, v0: f64, u1: f64, v1: f64 },
    #[error("source mip chain is empty or has a zero-size base level")]
    EmptySource,
    #[error("atlas size {size} must be even and at least 2 to hold four quadrants")]
    QuadrantSize { size: u32 },
    #[error("quadrant {quadrant}: child image is {width}×{height}, expected {half}×{half}")]
    ChildSize {
        quadrant: usize,
        width: u32,
        height: u32,
        half: u32,
    },
    #[error("resample size {size} must be at least 1")]
    ZeroSize { size: u32 },
}
