//! Twins of `shaders/dummy.wgsl`, the paper's dummy baseline (`--mode dummy`): the tree's draws with one
//! ordinary texture and a trivial fragment shader. It binds the tree renderer's globals, records and leaf
//! offsets buffers (the structs are [`tree`]'s) and its own texture and sampler.

use super::tree;

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/dummy.wgsl");

/// The frame's uniform block and the per-record data: the tree shader's buffers, declared alike.
pub use super::tree::{Globals, NodeDraw};

wgsl_consts! {
    /// [`overrides::PASS`] of the opaque pipelines (as [`tree::PASS_OPAQUE`]); the shader draws every
    /// pass alike.
    PASS_OPAQUE: u32 = tree::PASS_OPAQUE;
}

wgsl_overrides! {
    /// The pipeline's pass (the tree shader's codes, [`tree::PASS_OPAQUE`](super::tree::PASS_OPAQUE) …).
    PASS,
}

/// `@binding` numbers of the shader's one bind group (group 0), named after its variables.
pub mod binding {
    use crate::render::wgsl::Binding;

    /// `globals`: [`Globals`](super::Globals) (the tree renderer's buffer).
    pub const GLOBALS: u32 = 0;
    /// `draws`: [`NodeDraw`](super::NodeDraw) per indirect record (the tree renderer's buffer).
    pub const DRAWS: u32 = 1;
    /// `offsets`: per leaf `origin − eye` (the tree renderer's buffer).
    pub const OFFSETS: u32 = 2;
    /// `tex`: the one texture.
    pub const TEX: u32 = 3;
    /// `tex_sampler`: trilinear, repeat.
    pub const TEX_SAMPLER: u32 = 4;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[
        Binding::one("globals", 0, GLOBALS),
        Binding::one("draws", 0, DRAWS),
        Binding::one("offsets", 0, OFFSETS),
        Binding::one("tex", 0, TEX),
        Binding::one("tex_sampler", 0, TEX_SAMPLER),
    ];
}
