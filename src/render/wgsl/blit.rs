//! Twins of `shaders/blit.wgsl`, the viewer's present pass ([`crate::view`]): one texture, loaded texel
//! for texel.

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/blit.wgsl");

wgsl_consts! {}

wgsl_overrides! {}

/// `@binding` numbers, named after the shader's variables.
pub mod binding {
    use crate::render::wgsl::Binding;

    /// Group 0 `source`: the composited frame (not filtered).
    pub const SOURCE: u32 = 0;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[Binding::one("source", 0, SOURCE)];
}
