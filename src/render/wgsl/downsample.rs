//! Twins of `shaders/downsample.wgsl`, the supersampled reference's box filter in linear light
//! ([`crate::render::reference`]): its parameter block and bindings.

use bytemuck::{Pod, Zeroable};

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/downsample.wgsl");

wgsl_consts! {}

wgsl_overrides! {}

/// `@binding` numbers, named after the shader's variables.
pub mod binding {
    use crate::render::wgsl::Binding;

    /// Group 0 `source`: the supersampled frame (an sRGB view: loads are linear).
    pub const SOURCE: u32 = 0;
    /// Group 0 `params`: [`Params`](super::Params).
    pub const PARAMS: u32 = 1;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[
        Binding::one("source", 0, SOURCE),
        Binding::one("params", 0, PARAMS),
    ];
}

/// The downsample's parameters.
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
#[repr(C)]
pub struct Params {
    /// S: source texels per output pixel along each axis.
    pub factor: u32,
    pub _p0: u32,
    pub _p1: u32,
    pub _p2: u32,
}
const _: () = assert!(size_of::<Params>() == 16);
