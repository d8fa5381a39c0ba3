//! Twins of `shaders/naive.wgsl`, the naive baseline (`--mode original`): one bind group per original
//! texture (group 1: texture, sampler, [`Material`]) besides the frame's (group 0: [`Globals`], leaf
//! offsets).

use super::tree;
use bytemuck::{Pod, Zeroable};

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/naive.wgsl");

/// The frame's uniform block: the naive pipelines bind the tree shader's buffer, and `naive.wgsl` declares
/// the same struct.
pub use super::tree::Globals;

wgsl_consts! {
    /// [`overrides::PASS`] of the opaque pipelines (as [`tree::PASS_OPAQUE`]).
    PASS_OPAQUE: u32 = tree::PASS_OPAQUE;
    /// [`overrides::PASS`] of the mask pipelines (as [`tree::PASS_MASK`]): MASK materials, and the depth
    /// pre-pass of BLEND triangles.
    PASS_MASK: u32 = tree::PASS_MASK;
    /// [`Material::alpha_mode`] codes (as [`tree::ALPHA_OPAQUE`] …): opaque.
    ALPHA_OPAQUE: u32 = tree::ALPHA_OPAQUE;
    /// Alpha mask.
    ALPHA_MASK: u32 = tree::ALPHA_MASK;
    /// Alpha blend.
    ALPHA_BLEND: u32 = tree::ALPHA_BLEND;
    /// Alpha below which a fragment of a BLEND material is discarded (as [`tree::BLEND_MIN_ALPHA`]).
    BLEND_MIN_ALPHA: f32 = tree::BLEND_MIN_ALPHA;
    /// Alpha at and above which a BLEND texel is opaque in the mask pass (as [`tree::OPAQUE_ALPHA`]).
    OPAQUE_ALPHA: f32 = tree::OPAQUE_ALPHA;
}

wgsl_overrides! {
    /// The pipeline's pass (the tree shader's codes, [`tree::PASS_OPAQUE`](super::tree::PASS_OPAQUE) …).
    PASS,
}

/// `@binding` numbers, named after the shader's variables: group 0 (the frame) and group 1 (one per
/// original texture).
pub mod binding {
    use crate::render::wgsl::Binding;

    /// Group 0 `globals`: [`Globals`](super::Globals).
    pub const GLOBALS: u32 = 0;
    /// Group 0 `offsets`: per leaf `origin − eye`.
    pub const OFFSETS: u32 = 1;
    /// Group 1 `tex`: the original texture.
    pub const TEX: u32 = 0;
    /// Group 1 `tex_sampler`: a sampler with the material's wrap modes.
    pub const TEX_SAMPLER: u32 = 1;
    /// Group 1 `material`: [`Material`](super::Material).
    pub const MATERIAL: u32 = 2;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[
        Binding::one("globals", 0, GLOBALS),
        Binding::one("offsets", 0, OFFSETS),
        Binding::one("tex", 1, TEX),
        Binding::one("tex_sampler", 1, TEX_SAMPLER),
        Binding::one("material", 1, MATERIAL),
    ];
}

/// Material parameters of one naive bind group.
#[derive(Copy, Clone, Debug, Pod, Zeroable)]
#[repr(C)]
pub struct Material {
    /// Linear RGBA multiplier.
    pub factor: [f32; 4],
    /// [`ALPHA_OPAQUE`], [`ALPHA_MASK`] or [`ALPHA_BLEND`].
    pub alpha_mode: u32,
    /// MASK cutoff.
    pub cutoff: f32,
    pub _p0: u32,
    pub _p1: u32,
}
const _: () = assert!(size_of::<Material>() == 32);
