//! The texture-atlas tree renderer (paper §4) with texture-array batching (Trapp & Döllner 2015), wgpu.
//!
//! The renderer executes plans: a [`crate::plan::FramePlan`] (the cut of every tree, resolved against
//! residency) becomes one indirect record per selected node ([`batch`]); atlases are layers of texture
//! arrays and original textures layers of one array per class size ([`textures`]), uploaded and freed as
//! the plan's residency changes arrive ([`resident`], all blocks at once when nothing is paged); one bind
//! group and one `multi_draw_indexed_indirect` per pipeline (opaque; alpha mask and alpha blend only for
//! files with an alpha tree, created on first use) draw the frame ([`Renderer`]). [`FrameLoop`] is the
//! per-frame loop of a planner and a renderer (plan, then execute) for callers that draw one mode per
//! frame.
//!
//! Modes ([`Mode`]) on the same cut: the product (`Tree`), the naive per-texture baseline (`Original`), the
//! paper's dummy with one texture and a trivial fragment shader (`Dummy`, [`dummy`]), and colour-by-level
//! (`TreeLevels`).
//!
//! Debug: [`Renderer::execute_density`] writes texels per pixel instead of colours ([`density`]).
//!
//! Ground truth: [`Renderer::execute_supersampled`] draws a plan with the original textures at S × S the
//! pixels and box-filters it in linear light ([`reference`]).
//!
//! Shaders: `shaders/tree.wgsl` (tree, levels, density), `shaders/naive.wgsl` (original),
//! `shaders/dummy.wgsl` (dummy); their Rust twins (buffer structs, bindings, overrides, codes) are
//! [`wgsl::tree`], [`wgsl::naive`] and [`wgsl::dummy`].

pub mod batch;
pub mod density;
pub mod dummy;
mod encode;
mod frame;
mod frame_loop;
mod naive;
pub mod naive_batch;
pub mod pipeline;
pub mod reference;
pub mod resident;
pub mod textures;
pub mod wgsl;

pub use crate::plan::{PagingFrame, PagingSetup};
pub use encode::sky_srgb8;
pub use frame::{FrameStats, GpuResidency, Renderer, RendererOptions, frame_columns};
pub use frame_loop::FrameLoop;

use crate::gpu::GpuError;
use crate::ids::BlockId;
use crate::store::StoreError;

/// What a frame is drawn with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Atlases and original textures through texture arrays, one multi-draw per pipeline (the product).
    Tree,
    /// Naive: every (leaf, original texture) its own bind group and draw call; no atlases.
    Original,
    /// The paper's dummy: the tree's draws (same cut, records, passes and multi-draws) with one texture
    /// and a trivial fragment shader ([`dummy`]); tree ÷ dummy is what the tree's texturing costs.
    Dummy,
    /// The tree's draws coloured by the level of the atlas used (white: original textures).
    TreeLevels,
}

impl Mode {
    pub const ALL: [Mode; 4] = [Mode::Tree, Mode::Original, Mode::Dummy, Mode::TreeLevels];

    pub fn name(self) -> &'static str {
        match self {
            Mode::Tree => "tree",
            Mode::Original => "original",
            Mode::Dummy => "dummy",
            Mode::TreeLevels => "tree-levels",
        }
    }
}

impl std::str::FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Mode, String> {
        Mode::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown mode {s:?} (tree, original, dummy, tree-levels)"))
    }
}

/// Errors of loading a file onto the GPU and rendering it.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(
        "{what}: {layers} texture-array layers needed, the device allows {limit}; page the blocks with \
         `--capacity K` (a smaller K where it is given: each resident block takes its layers)"
    )]
    TooManyLayers {
        what: String,
        layers: u64,
        limit: u64,
    },
    #[error("{block} is shorter than the mip chain(s) it must hold")]
    ShortBlock { block: BlockId },
    #[error("the file has no tree {tree}")]
    MissingTree { tree: usize },
    #[error("too many {what} for 32-bit GPU indices")]
    TooLarge { what: &'static str },
    #[error(
        "tree {tree} leaf {leaf}: original class size {class_size} is not a power of two in 4..=2048"
    )]
    BadClass {
        tree: usize,
        leaf: u32,
        class_size: u32,
    },
    #[error(
        "tree {tree} leaf {leaf}: a vertex names original {original} and rect {rect} (or another leaf); the leaf \
         has {originals} originals and {rects} rects"
    )]
    BadVertex {
        tree: usize,
        leaf: u32,
        original: u32,
        originals: u32,
        rect: u32,
        rects: u32,
    },
    #[error("tree {tree} vertex {vertex} names leaf {leaf}; the tree has {leaves} leaves")]
    VertexLeaf {
        tree: usize,
        vertex: usize,
        leaf: u32,
        leaves: usize,
    },
    #[error("tree {tree} leaf {leaf} names node {node}; the tree has {nodes} nodes")]
    LeafNode {
        tree: usize,
        leaf: usize,
        node: u32,
        nodes: usize,
    },
    #[error("frame size {width}x{height}: each side must be 1 to {limit} pixels on this device")]
    BadSize { width: u32, height: u32, limit: u32 },
    #[error(
        "the supersampled reference at {factor}x{factor} of {width}x{height} pixels needs \
         {}x{} pixels; this device allows at most {limit} a side: lower S (supersampled:S) or the frame size",
        u64::from(*width) * u64::from(*factor),
        u64::from(*height) * u64::from(*factor)
    )]
    BadSupersample {
        width: u32,
        height: u32,
        factor: u32,
        limit: u32,
    },
    #[error(
        "{what} is not available when blocks are paged (use a capacity of all blocks or omit it)"
    )]
    NotWhenPaged { what: &'static str },
    #[error(transparent)]
    Blocks(#[from] crate::paging::BlockTableError),
    #[error(transparent)]
    Plan(#[from] crate::plan::PlanError),
    #[error(transparent)]
    NaiveBatch(#[from] naive_batch::NaiveBatchError),
    #[error(
        "naive draw names (material, original texture) bind group {texture}; the renderer made {textures}"
    )]
    MissingTexture { texture: u32, textures: usize },
    #[error("the plan has {cuts} cuts but the renderer's file has {trees} trees")]
    PlanMismatch { cuts: usize, trees: usize },
    #[error("original slot {slot} of block {block} is missing from its tree's slot table")]
    MissingSlot { block: u32, slot: u32 },
    /// A broken residency invariant (a bug, not bad input): reported instead of drawing a wrong texture.
    #[error("residency invariant broken: {what} (unique {unique}, class {class}, layer {layer})")]
    Residency {
        what: &'static str,
        unique: u32,
        class: u32,
        layer: u32,
    },
}
