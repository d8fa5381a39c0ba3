//! What a layout is: its options, and the tree it produces — nodes with their triangle ranges and
//! bounds, leaves with the planned rects of their atlas (sizes and positions in texels, UV ranges), and
//! the counters the report shows. Only sizes, no pixel.

use super::split::SplitRule;
use crate::ids::{Cell, Level, MaterialId};
use crate::model::RectWrap;
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::ops::Range;

/// Options of the layout stage.
#[derive(Clone, Debug)]
pub struct LayoutOptions {
    pub atlas_size: u32,
    pub border: u32,
    pub max_depth: u8,
    /// Never more texels per repetition than the source image has (see `area`).
    pub cap_to_source: bool,
    /// Repeats wrapped in the shader: rects hold at most one period
    /// ([`crate::preprocess::RepeatMode::Wrap`]).
    pub wrap: bool,
    /// A node that does not fit is made a scaled leaf instead of split when its original textures (as
    /// class layers, `class²` each: what they hold resident on the GPU) need at most this many texels
    /// (0: always split).
    pub leaf_originals: u64,
    /// What the split balances.
    pub split: SplitRule,
}

/// Why a leaf ended where it did.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum LeafReason {
    /// Its rects packed into one atlas at full resolution.
    Fits,
    /// A rect alone needs more than the atlas: the leaf's resolution is scaled to fit it.
    Oversized,
    /// Its originals are within [`LayoutOptions::leaf_originals`] and its demand is (almost) all at source
    /// resolution: deeper atlases would only copy the originals. Content scaled to fit.
    SourceResolution,
    /// Its originals are within [`LayoutOptions::leaf_originals`]: not split, content scaled to fit.
    Scaled,
    /// Splitting would not shrink its texel demand (every quarter needs about the same textures and
    /// periods): content scaled to fit.
    Shared,
    /// A single triangle needs more than the atlas: scaled to fit.
    Clamped,
}

/// One material's area in a node atlas (for one density class of its triangles), before pixels exist.
#[derive(Clone, Debug)]
pub struct PlannedRect {
    pub material: MaterialId,
    /// Density class of the triangles mapped into this area
    /// ([`crate::preprocess::prepare::TriInfo::class`]).
    pub class: i32,
    /// `[x, y, w, h]`, texels.
    pub outer: [u32; 4],
    pub inner: [u32; 4],
    pub uv_min: DVec2,
    pub uv_max: DVec2,
    /// Per axis, how UVs reach the rect.
    pub wrap: [RectWrap; 2],
    /// Per axis, whether the source cap limited this texture's resolution (then the guarantee is the
    /// source's).
    pub capped: [bool; 2],
    /// Texels per period the sizing asked for over the source's, on the capped axis that falls furthest
    /// short (1 where not capped): how much finer than its source `d_min` wanted this texture.
    pub need_over_source: f64,
}

/// A successful leaf layout.
#[derive(Clone, Debug)]
pub struct LeafLayout {
    pub rects: Vec<PlannedRect>,
    /// Share of the atlas covered by outer rectangles, 0..1.
    pub occupancy: f64,
    /// 1.0 unless the leaf had to be scaled down (see [`LeafReason`]).
    pub clamp_scale: f64,
    pub reason: LeafReason,
    /// Texels of the leaf's original textures as class layers (`class²` each, what they hold resident on the GPU; the file stores `w × h`).
    pub original_texels: u64,
}

/// A node of the layout tree.
#[derive(Clone, Debug)]
pub struct LayoutNode {
    /// Range of the node's triangles in the permutation array.
    pub range: Range<usize>,
    pub level: Level,
    pub cell: Cell,
    pub lo: DVec3,
    pub hi: DVec3,
    pub kind: LayoutKind,
}

#[derive(Clone, Debug)]
pub enum LayoutKind {
    Leaf(LeafLayout),
    /// Children by quadrant; visiting them in `order` walks the permutation array front to back.
    Inner {
        children: [Option<Box<LayoutNode>>; 4],
        order: [u8; 4],
    },
}

/// Why a layout failed.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    #[error(
        "the region x∈[{:.3}, {:.3}], y∈[{:.3}, {:.3}], z∈[{:.3}, {:.3}] ({triangles} triangles) still does not fit \
         one {atlas}² atlas at depth {depth} (--max-depth {depth}); raise --max-depth, --atlas-size or --d-min",
        lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
    )]
    DepthExceeded {
        lo: DVec3,
        hi: DVec3,
        triangles: usize,
        depth: u8,
        atlas: u32,
    },
    #[error(
        "triangle {scene_triangle} (material {material}) cannot be fitted into a {atlas}² atlas even at 1/{inv_scale:.0} \
         of its required resolution: its texture area is absurd (check its UVs)"
    )]
    Unfittable {
        scene_triangle: u32,
        material: u32,
        atlas: u32,
        inv_scale: f64,
    },
}

/// Leaves per [`LeafReason`], and what the scaled ones imply.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LeafCounts {
    pub fits: u64,
    pub oversized: u64,
    pub source_resolution: u64,
    pub scaled: u64,
    pub shared: u64,
    pub clamped: u64,
    /// Original texels (as class layers, `class²` each) of the leaves scaled for their content (source-resolution, scaled,
    /// shared): summed, and the largest single leaf's (what a camera next to it needs resident).
    pub scaled_original_texels: u64,
    pub scaled_original_texels_max: u64,
    /// The smallest resolution scale of any leaf (1 when none was scaled).
    pub scale_min: f64,
}

/// The whole layout plus counters for the report.
#[derive(Debug)]
pub struct Layout {
    pub root: LayoutNode,
    /// Permutation of the prepared triangles: leaves' ranges in tree order.
    pub order: Vec<u32>,
    /// Leaves whose resolution was scaled below 1 (oversized rects, source-resolution nodes, clamped
    /// triangles).
    pub clamped_leaves: usize,
    pub leaves: LeafCounts,
}
