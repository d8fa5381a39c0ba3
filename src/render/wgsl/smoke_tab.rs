//! Twins of `shaders/smoke_tab.wgsl`, the texture-array batching smoke test (`tests/gpu/smoke.rs`): per
//! draw record a [`DrawData`] names the texture-array layer its fragments sample.

use bytemuck::{Pod, Zeroable};

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/smoke_tab.wgsl");

wgsl_consts! {}

wgsl_overrides! {}

/// `@binding` numbers, named after the shader's variables.
pub mod binding {
    use crate::render::wgsl::Binding;

    /// Group 0 `draws`: [`DrawData`](super::DrawData) per `instance_index`.
    pub const DRAWS: u32 = 0;
    /// Group 0 `atlas`: the texture array.
    pub const ATLAS: u32 = 1;
    /// Group 0 `atlas_sampler`.
    pub const ATLAS_SAMPLER: u32 = 2;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[
        Binding::one("draws", 0, DRAWS),
        Binding::one("atlas", 0, ATLAS),
        Binding::one("atlas_sampler", 0, ATLAS_SAMPLER),
    ];
}

/// Per-draw data, indexed by `instance_index`.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct DrawData {
    /// Texture-array layer of the draw.
    pub layer: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}
const _: () = assert!(size_of::<DrawData>() == 16);
