//! The in-memory atlas tree: what `build` produces and `store` writes (paper §3, Fig. 3).
//!
//! Pixel data is not held here: every atlas and every group of original textures is a *block* whose bytes
//! are produced by the rasteriser and streamed into the paging file at an offset fixed in advance, so a
//! build never holds more than a few atlases per thread.

use crate::ids::{BlockId, Cell, ImageId, LeafId, Level, MaterialId, NodeId};
use crate::scene::UpAxis;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use serde::Serialize;

/// Parameters of a build (paper §5.2.1). Stored in the paging file so the runtime can rescale.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BuildParams {
    /// d_min in world units (metres): leaves' atlases are sharp enough for any camera at least this far.
    pub d_min: f64,
    /// Screen width in pixels the guarantee is computed for (runtime rescales min_distance linearly).
    pub screen_width: u32,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Texels per pixel required at d_min (1.0 = the paper's 1:1).
    pub texel_ratio: f64,
    /// Width = height of every atlas, texels (power of two).
    pub atlas_size: u32,
    /// Border around every packed texture area, texels (paper: 8).
    pub border: u32,
    /// Depth cap; a region that would need to go deeper is an error naming it.
    pub max_depth: u8,
    pub up: UpAxis,
}

impl BuildParams {
    /// `f_proj = w_screen / (2 d_min tan(fov/2))` (paper §5.2.1): pixels per world unit at distance d_min,
    /// multiplied by the texel ratio, i.e. required texels per world unit.
    pub fn f_proj(&self) -> f64 {
        let half = (self.fov_deg.to_radians() * 0.5).tan();
        self.texel_ratio * self.screen_width as f64 / (2.0 * self.d_min * half)
    }
}

/// Which tree of a file: the opaque tree (RGB in RGBA8 storage), or the alpha tree (RGBA), built only
/// when the scene has MASK/BLEND materials.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub enum TreeKind {
    Opaque,
    Alpha,
}

impl TreeKind {
    /// 0 for opaque, 1 for alpha: an index into per-kind arrays (a forest has at most one tree of each).
    pub fn index(self) -> usize {
        match self {
            TreeKind::Opaque => 0,
            TreeKind::Alpha => 1,
        }
    }

    /// Channels compared for errors: RGB for opaque trees (alpha is always 255), RGBA for alpha trees.
    pub fn channels(self) -> usize {
        match self {
            TreeKind::Opaque => 3,
            TreeKind::Alpha => 4,
        }
    }

    /// The storage format of this tree's blocks under `build --compress` (BC1 becomes BC3 on alpha trees).
    pub fn format(self, compress: crate::texfmt::Compression) -> crate::texfmt::TexFormat {
        compress.format_for(self == TreeKind::Alpha)
    }
}

/// One node of the quadtree.
#[derive(Clone, Debug, Serialize)]
pub struct Node {
    /// World-space bounds of the node's triangles (f64).
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    pub level: Level,
    /// Cell at `level`: where this node's atlas sits in the root atlas (paper Fig. 4).
    pub cell: Cell,
    pub parent: Option<NodeId>,
    /// Children by quadrant (bit 0: +x, bit 1: +y of the parent's atlas); `None` where the split left a
    /// quadrant empty (incomplete quadtree, paper §5.1).
    pub children: [Option<NodeId>; 4],
    /// Minimum camera distance at which this node's atlas suffices (leaf: d_min / clamp; inner: 2·max of
    /// children).
    pub min_distance: f64,
    /// Range in the tree's index buffer: all leaves of the subtree, contiguous (leaves in tree order).
    pub first_index: u32,
    pub index_count: u32,
    pub atlas_block: BlockId,
    pub leaf: Option<LeafId>,
}

impl Node {
    pub fn is_leaf(&self) -> bool {
        self.leaf.is_some()
    }
}

/// How the UVs of a rect's triangles reach its inner rectangle, per texture axis (docs/DESIGN.md "Repeats: one
/// period per rect, wrapped in the shader"). The fragment shader and its CPU twins
/// ([`crate::model::transform::rect_t`]) apply it to the unbounded, interpolated original UV.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Serialize)]
pub enum RectWrap {
    /// Baked (the paper's §5.2.2): `inner` shows `[uv_min, uv_max]`, every period a triangle's UVs span
    /// copied into the atlas (triangles shifted by whole periods share them); the UV reaches the rect
    /// unchanged.
    #[default]
    Linear,
    /// REPEAT sampler: `inner` shows at most one period, `[uv_min, uv_max]` with `uv_max − uv_min ≤ 1`; the
    /// UV is reduced by whole periods into it. Exactly one period: its border is the periodic
    /// continuation, so filtering across the seam reads what the original texture would.
    Repeat,
    /// MIRRORED_REPEAT sampler: `[uv_min, uv_max] ⊂ [0, 1]`; the UV is folded into `[0, 1]` first.
    Mirror,
    /// CLAMP_TO_EDGE sampler: `[uv_min, uv_max] ⊂ [0, 1]`; the UV is clamped to `[0, 1]` first.
    Clamp,
}

impl RectWrap {
    /// The paging file's (and the shader's, `render::wgsl::tree::RECT_WRAP_*`) code of this mode.
    pub const fn code(self) -> u32 {
        match self {
            RectWrap::Linear => 0,
            RectWrap::Repeat => 1,
            RectWrap::Mirror => 2,
            RectWrap::Clamp => 3,
        }
    }

    /// The mode of `code` (`None` for an unknown code).
    pub fn from_code(code: u32) -> Option<RectWrap> {
        Some(match code {
            0 => RectWrap::Linear,
            1 => RectWrap::Repeat,
            2 => RectWrap::Mirror,
            3 => RectWrap::Clamp,
            _ => return None,
        })
    }

    /// The rect mode for a sampler's wrap mode when repeats are wrapped in the shader.
    pub fn for_sampler(w: crate::scene::Wrap) -> RectWrap {
        match w {
            crate::scene::Wrap::Repeat => RectWrap::Repeat,
            crate::scene::Wrap::MirroredRepeat => RectWrap::Mirror,
            crate::scene::Wrap::ClampToEdge => RectWrap::Clamp,
        }
    }
}

/// Where one material's texture area sits in a leaf atlas (paper §5.2.2–5.2.3).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AtlasRect {
    pub material: MaterialId,
    /// Outer rectangle incl. border, texels, 4-aligned: `[x, y, w, h]`.
    pub outer: [u32; 4],
    /// Inner rectangle (the UV area A_tex maps onto exactly this), texels: `[x, y, w, h]`.
    pub inner: [u32; 4],
    /// A_tex in the material's UV space: `inner` shows `[uv_min, uv_max]` (see [`RectWrap`] for the range
    /// each mode allows).
    pub uv_min: [f64; 2],
    pub uv_max: [f64; 2],
    /// Per axis, how the UVs of the rect's triangles reach `[uv_min, uv_max]`.
    pub wrap: [RectWrap; 2],
    /// Per axis, whether the source cap limited the texels per period (the guarantee is then the
    /// source's: the atlas holds the source's full resolution).
    pub capped: [bool; 2],
    /// The inner rectangle's mean colour, sRGB8 with straight alpha: what a pixel covering a whole
    /// period shows (docs/DESIGN.md "Repeats: one period per rect, wrapped in the shader"). Measured on
    /// the stored leaf atlas as the paging file is written ([`crate::texfmt::rect_means`]); zero before.
    pub mean: [u8; 4],
}

impl AtlasRect {
    /// Leaf-atlas texels per unit of UV along each axis (`inner` size over the UV span; a zero span, a
    /// one-texel area, counts as one UV).
    pub fn texels_per_uv(&self) -> [f64; 2] {
        let axis = |inner: u32, lo: f64, hi: f64| {
            let span = hi - lo;
            f64::from(inner) / if span > 0.0 { span } else { 1.0 }
        };
        [
            axis(self.inner[2], self.uv_min[0], self.uv_max[0]),
            axis(self.inner[3], self.uv_min[1], self.uv_max[1]),
        ]
    }
}

/// Largest side of a stored original texture, texels (and the largest class array).
pub const MAX_ORIGINAL_CLASS: u32 = 2048;
/// Smallest side (one BC block).
pub const MIN_ORIGINAL_CLASS: u32 = 4;

/// One original texture a leaf uses near the camera (d < d_min), resampled to power-of-two sides and
/// stored once per tree in an original-texture block (format 5: non-square, see [`crate::texfmt::mip_extents`]).
#[derive(Clone, Debug, Serialize)]
pub struct OriginalRef {
    pub material: MaterialId,
    pub image: ImageId,
    /// Stored width and height after resampling, texels (each a power of two); the renderer tiles it into
    /// a layer of its class ([`OriginalRef::class_size`]).
    pub extent: [u32; 2],
    pub block: BlockId,
    /// Index of this image within its block (images of one block are stored back to back, each with its
    /// full mip chain).
    pub slot: u32,
}

impl OriginalRef {
    /// Side of the square class array it is drawn from, texels: the larger of its sides.
    pub fn class_size(&self) -> u32 {
        self.extent[0].max(self.extent[1])
    }
}

/// Every stored original once, in `(block, slot)` order, with its byte offset inside its block: the images
/// of one block lie back to back in slot order, each a full `extent[0] × extent[1]` mip chain in `format`.
/// `slots` lists `(block, slot, extent)` in any order, a shared original once per leaf that references it.
/// Returns `(block, slot, extent, offset)`.
pub fn original_slots(
    slots: impl IntoIterator<Item = (u32, u32, [u32; 2])>,
    format: crate::texfmt::TexFormat,
) -> Vec<(u32, u32, [u32; 2], u64)> {
    let mut slots: Vec<(u32, u32, [u32; 2])> = slots.into_iter().collect();
    slots.sort_unstable();
    slots.dedup_by_key(|x| (x.0, x.1));
    let (mut block, mut off) = (u32::MAX, 0u64);
    slots
        .into_iter()
        .map(|(b, slot, [w, h])| {
            if b != block {
                (block, off) = (b, 0);
            }
            let at = off;
            off += format.chain_bytes_rect(w, h);
            (b, slot, [w, h], at)
        })
        .collect()
}

/// A leaf: its triangles, atlas layout and original textures.
#[derive(Clone, Debug, Serialize)]
pub struct Leaf {
    pub node: NodeId,
    /// Positions of this leaf's vertices are stored relative to this point (f64), see docs/DESIGN.md "Precision".
    pub origin: DVec3,
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub first_index: u32,
    pub index_count: u32,
    pub rects: Vec<AtlasRect>,
    pub originals: Vec<OriginalRef>,
    /// 1.0 normally; < 1 when a triangle alone needed more than the atlas and the leaf's resolution was
    /// scaled down (then `min_distance = d_min / clamp_scale`).
    pub clamp_scale: f64,
}

/// A vertex as stored and drawn. WGSL twin: `TreeVertex` in `shaders/tree.wgsl`.
///
/// One UV set serves every level and both texture sources: the fragment shader maps `orig_uv` into the
/// vertex's rect of the leaf atlas ([`RectWrap`]) and from there into the atlas of the drawn level (the
/// exact transform of docs/DESIGN.md "Precision"), or samples the original texture with it.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable, Serialize)]
#[repr(C)]
pub struct TreeVertex {
    /// Position relative to the leaf origin (f32 is exact enough: leaves are small).
    pub pos: [f32; 3],
    /// Original UV, shifted per triangle by a whole period so it stays small (exact for repeat/mirror).
    pub orig_uv: [f32; 2],
    /// The leaf this vertex belongs to.
    pub leaf: u32,
    /// Index into the leaf's `originals` (TAB's texture-array mapping for original-texture draws).
    pub original: u32,
    /// Index into the leaf's `rects`: the atlas area its triangle's texture occupies.
    pub rect: u32,
}
const _: () = assert!(size_of::<TreeVertex>() == 32);

/// What a block holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub enum BlockKind {
    /// A node's atlas: `atlas_size²` sRGB in the tree's format, full mip chain, level 0 first.
    Atlas { node: NodeId },
    /// Part `part` of the original-texture blocks owned by `leaf`, the first leaf that draws one of its
    /// textures (other leaves reference it too): images back to back, each a full sRGB
    /// `w × h` mip chain in the tree's format.
    Originals { leaf: LeafId, part: u32 },
}

/// A block: kind and exact byte length (known before any pixel is produced).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub struct BlockDesc {
    /// Index of the tree in [`AtlasForest::trees`] the block belongs to.
    pub tree: u32,
    pub kind: BlockKind,
    pub bytes: u64,
}

/// One complete atlas tree.
#[derive(Clone, Debug, Serialize)]
pub struct AtlasTree {
    pub kind: TreeKind,
    /// Storage format of all this tree's blocks (atlases and original textures).
    pub format: crate::texfmt::TexFormat,
    /// `nodes[0]` is the root; parents precede children (pre-order).
    pub nodes: Vec<Node>,
    /// In tree order (pre-order of their nodes).
    pub leaves: Vec<Leaf>,
    pub vertices: Vec<TreeVertex>,
    /// Absolute indices into `vertices`; each leaf's range is contiguous and leaves are in tree order.
    pub indices: Vec<u32>,
    /// For each triangle of `indices` (in order), the scene triangle it came from.
    pub source_triangles: Vec<u32>,
}

/// Everything one paging file holds: the build parameters, the scene's materials, one or two trees
/// (opaque; alpha only if the scene has alpha materials) and the table of blocks of all trees.
#[derive(Clone, Debug, Serialize)]
pub struct AtlasForest {
    pub params: BuildParams,
    pub materials: Vec<crate::scene::Material>,
    pub trees: Vec<AtlasTree>,
    pub blocks: Vec<BlockDesc>,
}
