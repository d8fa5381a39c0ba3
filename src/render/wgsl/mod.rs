//! The Rust twins of the WGSL shaders in `shaders/`: one module per shader, every item under its WGSL name.
//!
//! A module holds the shader's source ([`tree::WGSL`] …), the `#[repr(C)]` structs the host writes into its
//! buffers (bytemuck `Pod`, laid out as WGSL lays out the struct of the same name), the `@group`/`@binding`
//! numbers (`binding`, under the names of the WGSL variables), the names of its `override` constants
//! (`overrides`, set per pipeline) and every module-scope `const` of the shader (wrap, alpha, pass and mode
//! codes, thresholds), which the WGSL compares against by name instead of by magic number.
//!
//! `tests/cpu/shaders.rs` parses every shader with naga and checks its module against it: struct sizes,
//! member names, offsets and sizes (naga's layouter against `size_of`/`offset_of!`), every binding, every
//! override name and every `const` value ([`CONSTS`](tree::CONSTS) lists them with their WGSL names).
//!
//! - [`tree`]: `shaders/tree.wgsl`, the renderer (modes tree, tree-levels; the density variant).
//! - [`naive`]: `shaders/naive.wgsl`, the per-texture baseline (`--mode original`).
//! - [`dummy`]: `shaders/dummy.wgsl`, the paper's dummy baseline (`--mode dummy`): the tree's draws, one
//!   texture, a trivial fragment shader.
//! - [`blit`]: `shaders/blit.wgsl`, the viewer's present pass.
//! - [`downsample`]: `shaders/downsample.wgsl`, the supersampled reference's box filter in linear light.
//! - [`smoke_tab`]: `shaders/smoke_tab.wgsl`, the texture-array batching smoke test (`tests/gpu`).
//!
//! `shaders/smoke.wgsl` shares nothing with the host but a vertex buffer, so it has no module.

/// Defines the shader's module-scope `const`s (`NAME: u32 = value;` or `NAME: f32 = value;`, each with its
/// docs) and [`CONSTS`](tree::CONSTS), the list of all of them by name.
macro_rules! wgsl_consts {
    (@value u32 $v:expr) => {
        $crate::render::wgsl::ConstValue::U32($v)
    };
    (@value f32 $v:expr) => {
        $crate::render::wgsl::ConstValue::F32($v)
    };
    ($( $(#[$doc:meta])* $name:ident: $ty:ident = $value:expr; )*) => {
        $( $(#[$doc])* pub const $name: $ty = $value; )*
        /// Every module-scope `const` of the shader: its WGSL name and the value the Rust constant of that
        /// name has (`tests/cpu/shaders.rs` checks both directions against the WGSL).
        pub const CONSTS: &[(&str, $crate::render::wgsl::ConstValue)] = &[
            $( (stringify!($name), wgsl_consts!(@value $ty $name)), )*
        ];
    };
}

/// Defines the module `overrides`: one `&str` constant per WGSL `override`, named and valued as in the
/// shader, and `overrides::ALL`.
macro_rules! wgsl_overrides {
    ($( $(#[$doc:meta])* $name:ident ),* $(,)?) => {
        /// Names of the shader's `override` constants (set per pipeline through
        /// `PipelineCompilationOptions::constants`).
        pub mod overrides {
            $( $(#[$doc])* pub const $name: &str = stringify!($name); )*
            /// Every `override` of the shader.
            pub const ALL: &[&str] = &[$($name),*];
        }
    };
}

pub mod blit;
pub mod downsample;
pub mod dummy;
pub mod naive;
pub mod smoke_tab;
pub mod tree;

/// The value of a module-scope WGSL `const`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum ConstValue {
    U32(u32),
    F32(f32),
}

/// A resource of a shader: the WGSL variable `name` at `@group(group) @binding(binding)`, or, numbered
/// (`count: Some(n)`), the variables `name0 … name{n − 1}` at bindings `binding … binding + n − 1`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    pub name: &'static str,
    pub group: u32,
    pub binding: u32,
    pub count: Option<u32>,
}

impl Binding {
    /// The variable `name` at `@group(group) @binding(binding)`.
    pub const fn one(name: &'static str, group: u32, binding: u32) -> Binding {
        Binding {
            name,
            group,
            binding,
            count: None,
        }
    }

    /// The variables `name0 … name{count − 1}` at bindings `first …` of `group`.
    pub const fn numbered(name: &'static str, group: u32, first: u32, count: u32) -> Binding {
        Binding {
            name,
            group,
            binding: first,
            count: Some(count),
        }
    }
}
