//! The tree's shape: try a node atlas, split on failure (paper §5.1, §5.2.3, §5.3).
//!
//! Only sizes are computed here, no pixel: a node "fits" when the required areas of all its textures pack
//! into one atlas. Nodes that do not fit are split into four groups; the recursion runs in parallel
//! (rayon) over the four children. The triangles of every node are one contiguous range of a single
//! permutation array, so the leaves of any subtree are contiguous in tree order.
//!
//! What a node's atlas holds (docs/DESIGN.md "Repeats"): one rect per material (per material and density class
//! with repeats baked), whose UV range per axis is the [`super::cover`] of its triangles — at most one
//! period where the sampler repeats, mirrors or clamps, so a rect's size depends on the texels per period
//! and not on how often the texture repeats.
//!
//! The split (§5.3) cuts the midpoint-sorted sequence where the summed texel demand ([`super::demand`],
//! the paper's condition (b) itself) is balanced: the larger half as small as possible. Midpoints are
//! compared quantised to `2⁻²⁴` of the node's extent and a cut never separates equal keys, so a
//! translation of the whole scene (UTM coordinates) that perturbs midpoints by rounding gives the same
//! tree.
//!
//! Leaves that are not a plain fit ([`LeafReason`]):
//! - a rect that alone needs more than the atlas (one period at the required density, plus borders):
//!   the node's resolution is scaled to fit it (splitting cannot shrink one period);
//! - a **source-resolution node**: its texel demand is almost all capped to the sources
//!   ([`SOURCE_RESOLUTION_SHARE`]), so deeper leaves would only copy the originals. It becomes a leaf
//!   whose atlas holds its content scaled to fit, `min_distance = d_min / scale`; nearer, its originals
//!   are drawn. Only when those originals stay within [`LayoutOptions::leaf_originals`] texels, so the
//!   textures a close camera needs stay pageable;
//! - a single triangle that alone needs more than the atlas is *clamped* likewise.
//!
//! Termination, where the paper would loop forever: a split always leaves every child with fewer triangles
//! than its parent (the cut index is kept inside `1..n`), and `max_depth` bounds the depth with an error
//! naming the region.
//!
//! Where things are: `tree.rs` holds the options and the tree a layout produces; `split/` the split
//! of a node's triangles in four; `leaf.rs` the planning of one node's atlas; this file the recursion
//! that tries a leaf, else splits.

mod leaf;
mod split;
mod tree;

pub use leaf::MIN_LEAF_SCALE;
pub use split::{MIDPOINT_BITS, SplitRule, Splitter, midpoint_keys};
pub use tree::{
    Layout, LayoutError, LayoutKind, LayoutNode, LayoutOptions, LeafCounts, LeafLayout, LeafReason,
    PlannedRect,
};

use super::demand::DemandModel;
use super::prepare::{Corners, TriInfo};
use crate::ids::{Cell, Level, MaterialId};
use crate::scene::Scene;
use glam::DVec3;
use leaf::{base_scale, capped_demand, clamp_leaf, material_needs, scaled_leaf, try_leaf};

/// A scaled leaf whose demand is at least this share capped to the sources counts as
/// [`LeafReason::SourceResolution`].
pub const SOURCE_RESOLUTION_SHARE: f64 = 0.9;

/// A split whose children's texel demands average at least this share of the parent's does not separate
/// what the atlas must hold (every quarter needs about the same textures and periods): the node becomes a
/// [`LeafReason::Shared`] leaf instead.
pub const FUTILE_SPLIT_SHARE: f64 = 0.9;

/// What the recursion shares: the leaf planner's inputs, the splitter, and the node counter behind the
/// progress callback.
struct Ctx<'a> {
    leaf: leaf::Ctx<'a>,
    corners: Corners<'a>,
    split: Splitter<'a>,
    /// Every node folds its bounds over its triangles in the order it receives them
    /// ([`has_negative_zero`]); otherwise an inner node's bounds are its children's union.
    bounds_on_entry: bool,
    nodes: &'a std::sync::atomic::AtomicU64,
    progress: &'a (dyn Fn(u64) + Sync),
}

/// The demand model of `scene` under `opts` (sources, sampler wraps, border, cap, wrap).
pub fn demand_model(scene: &Scene, opts: &LayoutOptions) -> DemandModel {
    DemandModel {
        sources: (0..scene.materials.len())
            .map(|m| scene.source_size(MaterialId(m as u32)))
            .collect(),
        wraps: scene.materials.iter().map(|m| m.wrap).collect(),
        wrap: opts.wrap,
        border: opts.border,
        cap_to_source: opts.cap_to_source,
    }
}

/// Lays out a tree for the prepared triangles `infos` (paper §5.1).
pub fn layout(
    scene: &Scene,
    infos: &[TriInfo],
    corners: Corners<'_>,
    opts: &LayoutOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Layout, LayoutError> {
    let mut order: Vec<u32> = (0..infos.len() as u32).collect();
    let nodes = std::sync::atomic::AtomicU64::new(0);
    let model = demand_model(scene, opts);
    let ctx = Ctx {
        leaf: leaf::Ctx { scene, infos, opts },
        corners,
        split: Splitter {
            infos,
            model: &model,
            rule: opts.split,
        },
        nodes: &nodes,
        progress,
        bounds_on_entry: has_negative_zero(corners, infos),
    };
    let root = build_node(&ctx, &mut order, 0, Level(0), Cell::default())?;
    let mut leaves = LeafCounts {
        scale_min: 1.0,
        ..LeafCounts::default()
    };
    count_leaves(&root, &mut leaves);
    Ok(Layout {
        root,
        order,
        clamped_leaves: (leaves.oversized
            + leaves.source_resolution
            + leaves.scaled
            + leaves.shared
            + leaves.clamped) as usize,
        leaves,
    })
}

fn count_leaves(n: &LayoutNode, c: &mut LeafCounts) {
    match &n.kind {
        LayoutKind::Leaf(l) => {
            c.scale_min = c.scale_min.min(l.clamp_scale);
            let counter = match l.reason {
                LeafReason::Fits => &mut c.fits,
                LeafReason::Oversized => &mut c.oversized,
                LeafReason::Clamped => &mut c.clamped,
                LeafReason::SourceResolution => &mut c.source_resolution,
                LeafReason::Scaled => &mut c.scaled,
                LeafReason::Shared => &mut c.shared,
            };
            *counter += 1;
            if matches!(
                l.reason,
                LeafReason::SourceResolution | LeafReason::Scaled | LeafReason::Shared
            ) {
                c.scaled_original_texels += l.original_texels;
                c.scaled_original_texels_max = c.scaled_original_texels_max.max(l.original_texels);
            }
        }
        LayoutKind::Inner { children, .. } => {
            for ch in children.iter().flatten() {
                count_leaves(ch, c);
            }
        }
    }
}

/// Triangles per task of [`bounds`] on big nodes.
const BOUNDS_CHUNK: usize = 1 << 16;

/// World bounds of `items` (min and max are exact in any order, so big nodes fold chunks in parallel).
fn bounds(corners: Corners<'_>, infos: &[TriInfo], items: &[u32]) -> (DVec3, DVec3) {
    use rayon::prelude::*;
    if items.is_empty() {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    let fold = |run: &[u32]| {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in super::prepare::walk(infos, run) {
            let p = corners.of(t);
            lo = lo.min(p[0].min(p[1]).min(p[2]));
            hi = hi.max(p[0].max(p[1]).max(p[2]));
        }
        (lo, hi)
    };
    if items.len() <= BOUNDS_CHUNK {
        return fold(items);
    }
    items.par_chunks(BOUNDS_CHUNK).map(fold).reduce(
        || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(a, b), (c, d)| (a.min(c), b.max(d)),
    )
}

/// Whether a corner of `infos` has a coordinate −0.0. `min` and `max` are exact, but between −0.0 and +0.0
/// (equal numbers) they keep the later operand, so with both zeros among the corners a node's bounds depend
/// on the order its corners are visited in: the layout then folds every node's corners in the order the
/// node receives them (as before inner nodes took their children's union), and its bounds are the same
/// bits as ever. Without a −0.0 the order cannot matter. The importer never makes a −0.0 (every world
/// position ends by adding a translation that is not −0.0), but a scene built in code can hold one, and the
/// midpoint of a cut between subnormal coordinates can round to one.
fn has_negative_zero(corners: Corners<'_>, infos: &[TriInfo]) -> bool {
    use rayon::prelude::*;
    const NEGATIVE_ZERO: u64 = 0x8000_0000_0000_0000;
    infos.par_chunks(BOUNDS_CHUNK).any(|run| {
        run.iter().fold(false, |found, t| {
            let mut here = false;
            for p in &corners.of(t) {
                here |= (p.x.to_bits() == NEGATIVE_ZERO)
                    | (p.y.to_bits() == NEGATIVE_ZERO)
                    | (p.z.to_bits() == NEGATIVE_ZERO);
            }
            found | here
        })
    })
}

/// The children's texel demands average at least [`FUTILE_SPLIT_SHARE`] of the node's. The demands are the
/// split's own where it has them exactly, else walked again (the split rule by area, or demands near
/// saturation); the same numbers either way.
fn futile_split(
    ctx: &Ctx<'_>,
    items: &[u32],
    groups: [usize; 4],
    known: Option<split::SplitDemands>,
) -> bool {
    let demand = |items: &[u32]| super::demand::demand(ctx.split.model, ctx.leaf.infos, items);
    let (child, own) = match known {
        Some(d) => (d.groups, d.total),
        None => {
            let mut start = 0;
            let child = groups.map(|g| {
                start += g;
                demand(&items[start - g..start])
            });
            (child, demand(items))
        }
    };
    let mut child_demand = 0.0;
    for d in child {
        child_demand += d as f64;
    }
    let filled = groups.iter().filter(|&&g| g > 0).count().max(1) as f64;
    child_demand / filled >= FUTILE_SPLIT_SHARE * own as f64
}

fn build_node(
    ctx: &Ctx<'_>,
    items: &mut [u32],
    offset: usize,
    level: Level,
    cell: Cell,
) -> Result<LayoutNode, LayoutError> {
    let range = offset..offset + items.len();
    let n = ctx.nodes.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    (ctx.progress)(n + 1);
    // A leaf's bounds are its triangles'; an inner node's the union of its children's (min and max are
    // exact, so the same numbers without a walk over its triangles at every level), except where signed
    // zeros make the order matter (`has_negative_zero`): then every node's own, in the order received.
    let on_entry = ctx
        .bounds_on_entry
        .then(|| bounds(ctx.corners, ctx.leaf.infos, items));
    let needs = material_needs(&ctx.leaf, items);
    let base = base_scale(&ctx.leaf, &needs);
    let leaf = |leaf: LeafLayout, items: &[u32]| {
        let (lo, hi) = on_entry.unwrap_or_else(|| bounds(ctx.corners, ctx.leaf.infos, items));
        LayoutNode {
            range: range.clone(),
            level,
            cell,
            lo,
            hi,
            kind: LayoutKind::Leaf(leaf),
        }
    };
    let reason = if base < 1.0 {
        LeafReason::Oversized
    } else {
        LeafReason::Fits
    };
    if let Some(l) = try_leaf(&ctx.leaf, &needs, base, reason) {
        return Ok(leaf(l, items));
    }
    if items.len() == 1 {
        let l = clamp_leaf(&ctx.leaf, items, &needs, base, LeafReason::Clamped)?;
        return Ok(leaf(l, items));
    }
    let (share, originals) = capped_demand(&ctx.leaf, &needs);
    if originals <= ctx.leaf.opts.leaf_originals {
        let reason = if share >= SOURCE_RESOLUTION_SHARE {
            LeafReason::SourceResolution
        } else {
            LeafReason::Scaled
        };
        if let Some(l) = scaled_leaf(&ctx.leaf, items, &needs, base, reason) {
            return Ok(leaf(l, items));
        }
    }
    if level.0 >= ctx.leaf.opts.max_depth {
        let (lo, hi) = bounds(ctx.corners, ctx.leaf.infos, items);
        return Err(LayoutError::DepthExceeded {
            lo,
            hi,
            triangles: items.len(),
            depth: ctx.leaf.opts.max_depth,
            atlas: ctx.leaf.opts.atlas_size,
        });
    }
    let (groups, split_demands) = ctx.split.split4_demands(items);
    // Only with repeats wrapped: baked ranges are per-triangle shifted, so one split often leaves every
    // child all the phases while deeper ones do separate them.
    if ctx.leaf.opts.wrap
        && futile_split(ctx, items, groups, split_demands)
        && let Some(l) = scaled_leaf(&ctx.leaf, items, &needs, base, LeafReason::Shared)
    {
        return Ok(leaf(l, items));
    }
    // Carve the slice into the four groups in array order: q0, q2 (low x), q1, q3 (high x).
    let (a, rest) = items.split_at_mut(groups[0]);
    let (b, rest) = rest.split_at_mut(groups[1]);
    let (c, d) = rest.split_at_mut(groups[2]);
    let order = [0u8, 2, 1, 3];
    let offs = [
        offset,
        offset + groups[0],
        offset + groups[0] + groups[1],
        offset + groups[0] + groups[1] + groups[2],
    ];
    let child = |slice: &mut [u32], i: usize| -> Result<Option<Box<LayoutNode>>, LayoutError> {
        if slice.is_empty() {
            return Ok(None);
        }
        let q = order[i] as u32;
        build_node(ctx, slice, offs[i], Level(level.0 + 1), cell.child(q))
            .map(|n| Some(Box::new(n)))
    };
    let ((ra, rb), (rc, rd)) = rayon::join(
        || rayon::join(|| child(a, 0), || child(b, 1)),
        || rayon::join(|| child(c, 2), || child(d, 3)),
    );
    let mut children: [Option<Box<LayoutNode>>; 4] = Default::default();
    for (i, r) in [ra, rb, rc, rd].into_iter().enumerate() {
        children[order[i] as usize] = r?;
    }
    let (lo, hi) = on_entry.unwrap_or_else(|| {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for child in children.iter().flatten() {
            lo = lo.min(child.lo);
            hi = hi.max(child.hi);
        }
        (lo, hi)
    });
    Ok(LayoutNode {
        range,
        level,
        cell,
        lo,
        hi,
        kind: LayoutKind::Inner { children, order },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::prepare::{PrepareOptions, prepare};
    use crate::scene::synthetic::SceneBuilder;
    use crate::scene::{AlphaMode, UpAxis, Wrap};
    use glam::DVec2;

    /// Four triangles with a 64² image each (two never share a 128² atlas), on the corners of a 20 × 11 m
    /// field, z up. Triangle 0 (bottom right) starts at x = `x0`; triangle 1 (bottom left) at x = +0.0.
    fn four_corners(x0: f64) -> (crate::scene::Scene, crate::preprocess::prepare::Prepared) {
        let mut b = SceneBuilder::new(UpAxis::Z);
        let corners = [
            [
                DVec3::new(x0, 0.0, 0.0),
                DVec3::new(20.0, 0.0, 0.0),
                DVec3::new(20.0, 1.0, 0.0),
            ],
            [
                DVec3::new(0.0, 5.0, 0.0),
                DVec3::new(1.0, 5.0, 0.0),
                DVec3::new(1.0, 6.0, 0.0),
            ],
            [
                DVec3::new(2.0, 10.0, 0.0),
                DVec3::new(3.0, 10.0, 0.0),
                DVec3::new(3.0, 11.0, 0.0),
            ],
            [
                DVec3::new(18.0, 10.0, 0.0),
                DVec3::new(19.0, 10.0, 0.0),
                DVec3::new(19.0, 11.0, 0.0),
            ],
        ];
        for (i, pos) in corners.into_iter().enumerate() {
            let image = b.pattern_image(&format!("t{i}"), 64, i as u32);
            let material = b.material(image, [Wrap::ClampToEdge; 2], AlphaMode::Opaque);
            b.triangle(pos, [DVec2::ZERO, DVec2::X, DVec2::ONE], material);
        }
        let scene = b.build();
        let popts = PrepareOptions {
            f_proj: 1e6,
            up: UpAxis::Z,
            cap_to_source: true,
            split_limit: 1e9,
            max_pieces: 1,
            wrap: true,
            palette_cells: 0,
        };
        let prepared = prepare(&scene, &[0, 1, 2, 3], &popts);
        (scene, prepared)
    }

    fn options() -> LayoutOptions {
        LayoutOptions {
            atlas_size: 128,
            border: 2,
            max_depth: 8,
            cap_to_source: true,
            wrap: true,
            leaf_originals: 0,
            split: SplitRule::Demand,
        }
    }

    #[test]
    fn signed_zeros_give_the_bounds_of_the_fold_in_arrival_order() {
        let (scene, prepared) = four_corners(-0.0);
        let (infos, corners) = (&prepared.infos, prepared.corners(&scene));
        assert!(has_negative_zero(corners, infos));
        let lay = layout(&scene, infos, corners, &options(), &|_| {}).unwrap();
        let LayoutKind::Inner { children, .. } = &lay.root.kind else {
            panic!("the root must split: no two triangles share an atlas");
        };
        // The split puts triangle 1 (x = +0.0) in quadrant 0 and triangle 0 (x = −0.0) in quadrant 1: the
        // children's union in quadrant order would end on −0.0, the fold over 0, 1, 2, 3 ends on +0.0.
        assert_eq!(children.iter().flatten().count(), 4);
        let (lo, hi) = bounds(corners, infos, &[0, 1, 2, 3]);
        assert_eq!(lo.x.to_bits(), 0.0f64.to_bits());
        let bits = |v: DVec3| v.to_array().map(f64::to_bits);
        assert_eq!(bits(lay.root.lo), bits(lo));
        assert_eq!(bits(lay.root.hi), bits(hi));
        // Without a −0.0 the union is used, and is the same bits.
        let (scene, prepared) = four_corners(0.0);
        let (infos, corners) = (&prepared.infos, prepared.corners(&scene));
        assert!(!has_negative_zero(corners, infos));
        let lay = layout(&scene, infos, corners, &options(), &|_| {}).unwrap();
        let (lo, hi) = bounds(corners, infos, &[0, 1, 2, 3]);
        assert_eq!(bits(lay.root.lo), bits(lo));
        assert_eq!(bits(lay.root.hi), bits(hi));
    }
}
