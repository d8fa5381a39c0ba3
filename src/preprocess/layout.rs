//! The tree's shape: try a node atlas, split on failure (paper §5.1, §5.2.3, §5.3).
//!
//! Only sizes are computed here, no pixel: a node "fits" when the required areas of all its textures pack
//! into one atlas. Nodes that do not fit are split into four groups; the recursion runs in parallel
//! (rayon) over the four children. The triangles of every node are one contiguous range of a single
//! permutation array, so the leaves of any subtree are contiguous in tree order.
//!
//! What a node's atlas holds (DESIGN.md "Repeats"): one rect per material (per material and density class
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
//!   ([`LayoutOptions::capped_share`]), so deeper leaves would only copy the originals. It becomes a leaf
//!   whose atlas holds its content scaled to fit, `min_distance = d_min / scale`; nearer, its originals
//!   are drawn. Only when those originals stay within [`LayoutOptions::capped_originals`] texels, so the
//!   textures a close camera needs stay pageable;
//! - a single triangle that alone needs more than the atlas is *clamped* likewise.
//!
//! Termination, where the paper would loop forever: a split always leaves every child with fewer triangles
//! than its parent (the cut index is kept inside `1..n`), and `max_depth` bounds the depth with an error
//! naming the region.

use super::area::{AreaInput, AreaOptions, required_area, scale_to_fit};
use super::assemble::original_class;
use super::cover::AxisCover;
use super::demand::{DemandModel, prefix_demands};
use super::pack::{PackOptions, pack};
use super::prepare::TriInfo;
use crate::ids::{Cell, Level, MaterialId};
use crate::model::RectWrap;
use crate::model::sizing::SizeMethod;
use crate::scene::Scene;
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::collections::{BTreeMap, HashSet};
use std::ops::Range;

/// Options of the layout stage.
#[derive(Clone, Debug)]
pub struct LayoutOptions {
    pub atlas_size: u32,
    pub border: u32,
    pub max_depth: u8,
    /// Never more texels per repetition than the source image has (see `area`).
    pub cap_to_source: bool,
    /// Repeats wrapped in the shader: rects hold at most one period ([`super::RepeatMode::Wrap`]).
    pub wrap: bool,
    /// A node that does not fit is made a scaled leaf instead of split when its original textures (at
    /// their stored class sizes) need at most this many texels (0: always split).
    pub leaf_originals: u64,
    /// What the split balances.
    pub split: SplitRule,
}

/// What the split of §5.3 balances.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Serialize)]
pub enum SplitRule {
    /// The summed texel demand of the halves, condition (b) itself ([`super::demand`]).
    #[default]
    Demand,
    /// The summed world area of the halves: the paper's approximation of (b), which assumes every texture
    /// point maps to one world point (no repeats, no shared textures).
    Area,
}

impl std::str::FromStr for SplitRule {
    type Err = String;
    fn from_str(s: &str) -> Result<SplitRule, String> {
        match s.to_ascii_lowercase().as_str() {
            "demand" => Ok(SplitRule::Demand),
            "area" => Ok(SplitRule::Area),
            _ => Err(format!("unknown split rule {s:?} (demand or area)")),
        }
    }
}

/// A scaled leaf whose demand is at least this share capped to the sources counts as
/// [`LeafReason::SourceResolution`].
pub const SOURCE_RESOLUTION_SHARE: f64 = 0.9;

/// A split whose children's texel demands average at least this share of the parent's does not separate
/// what the atlas must hold (every quarter needs about the same textures and periods): the node becomes a
/// [`LeafReason::Shared`] leaf instead.
pub const FUTILE_SPLIT_SHARE: f64 = 0.9;

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
    /// Density class of the triangles mapped into this area ([`super::prepare::TriInfo::class`]).
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
    /// Texels of the leaf's original textures at their stored class sizes.
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
    /// Original texels (at class size) of the leaves scaled for their content (source-resolution, scaled,
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

struct Ctx<'a> {
    scene: &'a Scene,
    infos: &'a [TriInfo],
    opts: &'a LayoutOptions,
    split: Splitter<'a>,
    nodes: &'a std::sync::atomic::AtomicU64,
    progress: &'a (dyn Fn(u64) + Sync),
}

/// The demand model of `scene` under `opts` (sources, sampler wraps, border, cap, wrap).
pub fn demand_model(scene: &Scene, opts: &LayoutOptions) -> DemandModel {
    DemandModel {
        sources: scene
            .materials
            .iter()
            .map(|m| {
                let img = &scene.images[m.image.idx()];
                [img.width, img.height]
            })
            .collect(),
        wraps: scene.materials.iter().map(|m| m.wrap).collect(),
        wrap: opts.wrap,
        border: opts.border,
        cap_to_source: opts.cap_to_source,
    }
}

/// Midpoints are compared in units of `2^(ceil(log2 extent) − MIDPOINT_BITS)` of the node's extent along
/// the sorted axis.
pub const MIDPOINT_BITS: i32 = 24;

/// Quantised plane midpoints of `items` along `axis` (0: x, 1: y of the plane): `floor((mid − min) / q)`
/// with `q = 2^(ceil(log2 extent) − MIDPOINT_BITS)`, the extent that of the items' midpoints. A translation
/// of the scene that perturbs every midpoint by rounding (≪ q) leaves the keys unchanged except for
/// midpoints within that rounding of a bucket edge; the quantum follows the node, so deep nodes of tiny
/// triangles still separate them.
pub fn midpoint_keys(infos: &[TriInfo], items: &[u32], axis: usize) -> Vec<i64> {
    let (lo, hi) = items
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
            let m = infos[i as usize].mid[axis];
            (a.min(m), b.max(m))
        });
    let extent = hi - lo;
    let q = if extent.is_finite() && extent > 0.0 {
        (extent.log2().ceil() - f64::from(MIDPOINT_BITS)).exp2()
    } else {
        1.0
    };
    items
        .iter()
        .map(|&i| ((infos[i as usize].mid[axis] - lo) / q).floor() as i64)
        .collect()
}

/// Lays out a tree for the prepared triangles `infos` (paper §5.1).
pub fn layout(
    scene: &Scene,
    infos: &[TriInfo],
    opts: &LayoutOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Layout, LayoutError> {
    let mut order: Vec<u32> = (0..infos.len() as u32).collect();
    let nodes = std::sync::atomic::AtomicU64::new(0);
    let model = demand_model(scene, opts);
    let ctx = Ctx {
        scene,
        infos,
        opts,
        split: Splitter {
            infos,
            model: &model,
            rule: opts.split,
        },
        nodes: &nodes,
        progress,
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

fn bounds(infos: &[TriInfo], items: &[u32]) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for &i in items {
        let t = &infos[i as usize];
        lo = lo.min(t.lo);
        hi = hi.max(t.hi);
    }
    if items.is_empty() {
        (DVec3::ZERO, DVec3::ZERO)
    } else {
        (lo, hi)
    }
}

fn build_node(
    ctx: &Ctx<'_>,
    items: &mut [u32],
    offset: usize,
    level: Level,
    cell: Cell,
) -> Result<LayoutNode, LayoutError> {
    let (lo, hi) = bounds(ctx.infos, items);
    let range = offset..offset + items.len();
    let n = ctx.nodes.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    (ctx.progress)(n + 1);
    let needs = material_needs(ctx, items);
    let base = base_scale(ctx, &needs);
    let leaf = |leaf: LeafLayout| LayoutNode {
        range: range.clone(),
        level,
        cell,
        lo,
        hi,
        kind: LayoutKind::Leaf(leaf),
    };
    let reason = if base < 1.0 {
        LeafReason::Oversized
    } else {
        LeafReason::Fits
    };
    if let Some(l) = try_leaf(ctx, &needs, base, reason) {
        return Ok(leaf(l));
    }
    if items.len() == 1 {
        return Ok(leaf(clamp_leaf(
            ctx,
            items,
            &needs,
            base,
            LeafReason::Clamped,
        )?));
    }
    let (share, originals) = capped_demand(ctx, &needs);
    if originals <= ctx.opts.leaf_originals {
        let reason = if share >= SOURCE_RESOLUTION_SHARE {
            LeafReason::SourceResolution
        } else {
            LeafReason::Scaled
        };
        if let Some(l) = scaled_leaf(ctx, items, &needs, base, reason) {
            return Ok(leaf(l));
        }
    }
    if level.0 >= ctx.opts.max_depth {
        return Err(LayoutError::DepthExceeded {
            lo,
            hi,
            triangles: items.len(),
            depth: ctx.opts.max_depth,
            atlas: ctx.opts.atlas_size,
        });
    }
    let groups = ctx.split.split4(items);
    let model = ctx.split.model;
    let mut start = 0;
    let mut child_demand = 0.0;
    for g in groups {
        child_demand += super::demand::demand(model, ctx.infos, &items[start..start + g]) as f64;
        start += g;
    }
    let filled = groups.iter().filter(|&&g| g > 0).count().max(1) as f64;
    let own_demand = super::demand::demand(model, ctx.infos, items) as f64;
    // Only with repeats wrapped: baked ranges are per-triangle shifted, so one split often leaves every
    // child all the phases while deeper ones do separate them.
    if ctx.opts.wrap
        && child_demand / filled >= FUTILE_SPLIT_SHARE * own_demand
        && let Some(l) = scaled_leaf(ctx, items, &needs, base, LeafReason::Shared)
    {
        return Ok(leaf(l));
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
    Ok(LayoutNode {
        range,
        level,
        cell,
        lo,
        hi,
        kind: LayoutKind::Inner { children, order },
    })
}

/// Splits triangle sets in four by texel demand (paper §5.3 with condition (b) itself).
pub struct Splitter<'a> {
    pub infos: &'a [TriInfo],
    pub model: &'a DemandModel,
    pub rule: SplitRule,
}

impl Splitter<'_> {
    /// Splits `items` in place into four groups: sort by quantised plane-midpoint x and cut where the texel
    /// demand of the two halves is balanced, then each half likewise by y. Returns the group lengths in
    /// array order (low-x/low-y, low-x/high-y, high-x/low-y, high-x/high-y). Every group is shorter than
    /// `items` when `items.len() ≥ 2`: the cut is kept inside `1..n`, so thousands of triangles with one
    /// midpoint still split.
    pub fn split4(&self, items: &mut [u32]) -> [usize; 4] {
        let k = self.cut_sorted(items, 0);
        let (lo, hi) = items.split_at_mut(k);
        let k0 = self.cut_sorted(lo, 1);
        let k1 = self.cut_sorted(hi, 1);
        [k0, lo.len() - k0, k1, hi.len() - k1]
    }

    /// Sorts `items` by key `axis` (ties by index, deterministic) and returns the cut index: among the
    /// positions between different keys, the one where `max(demand(before), demand(after))` is smallest
    /// ([`SplitRule::Demand`]; with [`SplitRule::Area`], where the world area before is closest to half),
    /// ties nearest the middle, then the lower. Without such a position (all keys equal) the middle; for
    /// n ≤ 1 it returns n (everything in the low group).
    pub fn cut_sorted(&self, items: &mut [u32], axis: usize) -> usize {
        let n = items.len();
        if n <= 1 {
            return n;
        }
        let keys = midpoint_keys(self.infos, items, axis);
        let mut order: Vec<(i64, u32)> = keys.into_iter().zip(items.iter().copied()).collect();
        order.sort_unstable();
        for (slot, &(_, it)) in items.iter_mut().zip(&order) {
            *slot = it;
        }
        let cost_of: Box<dyn Fn(usize) -> f64> = match self.rule {
            SplitRule::Demand => {
                let before = prefix_demands(self.model, self.infos, items);
                let rev: Vec<u32> = items.iter().rev().copied().collect();
                let after = prefix_demands(self.model, self.infos, &rev);
                Box::new(move |k| before[k].max(after[n - k]) as f64)
            }
            SplitRule::Area => {
                let mut acc = vec![0.0f64; n + 1];
                for (i, &it) in items.iter().enumerate() {
                    acc[i + 1] = acc[i] + self.infos[it as usize].area;
                }
                let half = 0.5 * acc[n];
                Box::new(move |k| (acc[k] - half).abs())
            }
        };
        let mut best: Option<(f64, usize, usize)> = None;
        for k in 1..n {
            if order[k - 1].0 == order[k].0 {
                continue;
            }
            let cost = cost_of(k);
            let off_centre = (2 * k).abs_diff(n);
            if best.is_none_or(|(c, o, _)| (cost, off_centre) < (c, o)) {
                best = Some((cost, off_centre, k));
            }
        }
        best.map_or(n / 2, |(_, _, k)| k)
    }
}

/// Per-(material, density class) requirements of a node (the maxima of §5.2.1 and the UV cover of
/// §5.2.2, [`super::cover`]).
struct MatNeed {
    w: f64,
    h: f64,
    cover: [AxisCover; 2],
    point_uvs: bool,
}

impl MatNeed {
    /// The area input at the node's requirement (palette textures — several constant-UV triangles —
    /// keep their source resolution over their used area).
    fn input(&self, source: [u32; 2]) -> AreaInput {
        let (u0, u1) = self.cover[0].range();
        let (v0, v1) = self.cover[1].range();
        let (mut w, mut h) = (self.w, self.h);
        if self.point_uvs && (u1 > u0 || v1 > v0) {
            w = w.max(f64::from(source[0]));
            h = h.max(f64::from(source[1]));
        }
        AreaInput {
            w,
            h,
            uv_min: [u0, v0],
            uv_max: [u1, v1],
            source,
        }
    }
}

fn material_needs(ctx: &Ctx<'_>, items: &[u32]) -> BTreeMap<(MaterialId, i32), MatNeed> {
    let mut m: BTreeMap<(MaterialId, i32), MatNeed> = BTreeMap::new();
    for &i in items {
        let t = &ctx.infos[i as usize];
        let e = m.entry((t.material, t.class)).or_insert_with(|| {
            let wrap = ctx.scene.materials[t.material.idx()].wrap;
            let mode = |k: usize| {
                if ctx.opts.wrap {
                    RectWrap::for_sampler(wrap[k])
                } else {
                    RectWrap::Linear
                }
            };
            MatNeed {
                w: 0.0,
                h: 0.0,
                cover: [AxisCover::new(mode(0)), AxisCover::new(mode(1))],
                point_uvs: false,
            }
        });
        for k in 0..2 {
            let (lo, hi) =
                t.uv.iter()
                    .map(|uv| uv[k])
                    .filter(|x| x.is_finite())
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                        (a.min(x), b.max(x))
                    });
            e.cover[k].add(lo, hi);
        }
        match t.size.method {
            SizeMethod::Exact | SizeMethod::EdgeFallback => {
                e.w = e.w.max(t.size.w);
                e.h = e.h.max(t.size.h);
            }
            // A triangle with one constant UV shows one texel (paper: 1×1). Several such triangles at
            // different UVs (palette textures, common in game levels) must still land on their own texels, so
            // the texture keeps its source resolution over its used area.
            SizeMethod::AllUvEqual => e.point_uvs = true,
            SizeMethod::WorldDegenerate => {}
        }
    }
    m
}

fn source_of(ctx: &Ctx<'_>, mat: MaterialId) -> [u32; 2] {
    let img = &ctx.scene.images[ctx.scene.materials[mat.idx()].image.idx()];
    [img.width, img.height]
}

fn area_options(ctx: &Ctx<'_>, scale: f64) -> AreaOptions {
    AreaOptions {
        border: ctx.opts.border,
        scale,
        cap_to_source: ctx.opts.cap_to_source,
        max_side: ctx.opts.atlas_size,
    }
}

/// The largest resolution scale `≤ 1` at which every rect fits the atlas on its own. With repeats wrapped a
/// rect holds at most one period, so a rect too large alone stays too large in every descendant: the node
/// is scaled instead of split. With repeats baked splitting shrinks the UV ranges: 1.
fn base_scale(ctx: &Ctx<'_>, needs: &BTreeMap<(MaterialId, i32), MatNeed>) -> f64 {
    if !ctx.opts.wrap {
        return 1.0;
    }
    let opts = area_options(ctx, 1.0);
    needs
        .iter()
        .filter_map(|(&(mat, _), need)| {
            scale_to_fit(&need.input(source_of(ctx, mat)), &opts, ctx.opts.atlas_size)
        })
        .fold(1.0, f64::min)
}

/// `(share of the node's demand capped to the sources, texels of its originals at class size)`.
fn capped_demand(ctx: &Ctx<'_>, needs: &BTreeMap<(MaterialId, i32), MatNeed>) -> (f64, u64) {
    let opts = AreaOptions {
        max_side: u32::MAX,
        ..area_options(ctx, 1.0)
    };
    let (mut total, mut capped) = (0.0f64, 0.0f64);
    let mut seen = HashSet::new();
    let mut originals = 0u64;
    for (&(mat, _), need) in needs {
        let src = source_of(ctx, mat);
        if seen.insert(mat) {
            let c = u64::from(original_class(src[0], src[1]));
            originals = originals.saturating_add(c * c);
        }
        let input = need.input(src);
        let Ok(a) = required_area(&input, &opts) else {
            continue;
        };
        let area = a.outer_texels() as f64;
        let cw = f64::from(u8::from(input.w > f64::from(src[0])));
        let ch = f64::from(u8::from(input.h > f64::from(src[1])));
        total += area;
        capped += area * 0.5 * (cw + ch);
    }
    let share = if ctx.opts.cap_to_source && total > 0.0 {
        capped / total
    } else {
        0.0
    };
    (share, originals)
}

/// Tries to lay out one atlas for the node's `needs` at resolution `scale` (§5.2.2, §5.2.3).
fn try_leaf(
    ctx: &Ctx<'_>,
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    scale: f64,
    reason: LeafReason,
) -> Option<LeafLayout> {
    let aopts = area_options(ctx, scale);
    let mut mats = Vec::with_capacity(needs.len());
    let mut sizes = Vec::with_capacity(needs.len());
    let mut summed: u64 = 0;
    let cap = u64::from(ctx.opts.atlas_size) * u64::from(ctx.opts.atlas_size);
    let mut seen = HashSet::new();
    let mut original_texels = 0u64;
    for (&(mat, class), need) in needs {
        let src = source_of(ctx, mat);
        let input = need.input(src);
        let area = required_area(&input, &aopts).ok()?;
        let capped = [
            ctx.opts.cap_to_source && need.w > f64::from(src[0]),
            ctx.opts.cap_to_source && need.h > f64::from(src[1]),
        ];
        summed += u64::from(area.outer_w) * u64::from(area.outer_h);
        if summed > cap {
            return None;
        }
        if seen.insert(mat) {
            let c = u64::from(original_class(src[0], src[1]));
            original_texels += c * c;
        }
        sizes.push([area.outer_w, area.outer_h]);
        let wrap = [need.cover[0].wrap(), need.cover[1].wrap()];
        mats.push((mat, class, area, input.uv_min, input.uv_max, wrap, capped));
    }
    let packing = pack(
        &sizes,
        &PackOptions {
            atlas_size: ctx.opts.atlas_size,
            ..PackOptions::default()
        },
    )
    .ok()?;
    let rects = mats
        .into_iter()
        .zip(packing.positions.iter())
        .map(
            |((material, class, a, uv_min, uv_max, wrap, capped), p)| PlannedRect {
                material,
                class,
                outer: [p[0], p[1], a.outer_w, a.outer_h],
                inner: [p[0] + a.border[0], p[1] + a.border[1], a.inner_w, a.inner_h],
                uv_min: DVec2::from(uv_min),
                uv_max: DVec2::from(uv_max),
                wrap,
                capped,
            },
        )
        .collect();
    Some(LeafLayout {
        rects,
        occupancy: packing.occupancy,
        clamp_scale: scale,
        reason,
        original_texels,
    })
}

/// A node made a leaf for its content ([`LeafReason::SourceResolution`], [`LeafReason::Scaled`],
/// [`LeafReason::Shared`]) when its content fits at a scale of at least [`MIN_LEAF_SCALE`]; `None` (split
/// it instead) when it does not — too many rects for their borders, or a scale so small its atlas would
/// serve only from far beyond the scene.
fn scaled_leaf(
    ctx: &Ctx<'_>,
    items: &[u32],
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    base: f64,
    reason: LeafReason,
) -> Option<LeafLayout> {
    try_leaf(ctx, needs, base * MIN_LEAF_SCALE, reason)?;
    clamp_leaf(ctx, items, needs, base, reason).ok()
}

/// The smallest resolution scale of a leaf made for its content (`min_distance ≤ 16 · d_min`).
pub const MIN_LEAF_SCALE: f64 = 1.0 / 16.0;

/// A node that is to be a leaf although its content does not fit at `base`: the largest scale (to 1/4096
/// precision in log2, below `base`) at which it fits. Its `min_distance` becomes `d_min / scale`.
fn clamp_leaf(
    ctx: &Ctx<'_>,
    items: &[u32],
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    base: f64,
    reason: LeafReason,
) -> Result<LeafLayout, LayoutError> {
    // Bisection on log2(scale) in [log2(base) − 40, log2(base)].
    let top = base.log2();
    let (mut lo, mut hi) = (top - 40.0, top);
    let Some(mut best) = try_leaf(ctx, needs, lo.exp2(), reason) else {
        let t = &ctx.infos[items[0] as usize];
        return Err(LayoutError::Unfittable {
            scene_triangle: t.scene_tri,
            material: t.material.0,
            atlas: ctx.opts.atlas_size,
            inv_scale: (-lo).exp2(),
        });
    };
    for _ in 0..12 {
        let mid = 0.5 * (lo + hi);
        match try_leaf(ctx, needs, mid.exp2(), reason) {
            Some(l) => {
                best = l;
                lo = mid;
            }
            None => hi = mid,
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::sizing::{SizeEstimate, SizeMethod};
    use crate::scene::Wrap;

    /// A triangle of `material` at plane midpoint `mid` needing `w` texels per period over UV `[0, 1]²`.
    fn tri(mid: DVec2, material: u32, w: f64, area: f64) -> TriInfo {
        TriInfo {
            scene_tri: 0,
            pos: [DVec3::ZERO; 3],
            material: MaterialId(material),
            mid,
            area,
            size: SizeEstimate {
                w,
                h: w,
                method: SizeMethod::Exact,
            },
            class: 0,
            uv: [DVec2::ZERO, DVec2::X, DVec2::Y],
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
        }
    }

    fn model(materials: usize) -> DemandModel {
        DemandModel {
            sources: vec![[1024, 1024]; materials],
            wraps: vec![[Wrap::Repeat; 2]; materials],
            wrap: true,
            border: 2,
            cap_to_source: true,
        }
    }

    fn split(infos: &[TriInfo], model: &DemandModel, items: &mut [u32]) -> [usize; 4] {
        Splitter {
            infos,
            model,
            rule: SplitRule::Demand,
        }
        .split4(items)
    }

    #[test]
    fn split_balances_demand_in_x_then_y() {
        // A 4×4 grid of triangles with a material each, equal demand: four 2×2 quadrants.
        let infos: Vec<TriInfo> = (0..16)
            .map(|i| tri(DVec2::new((i % 4) as f64, (i / 4) as f64), i, 60.0, 1.0))
            .collect();
        let mut items: Vec<u32> = (0..16).rev().collect();
        let g = split(&infos, &model(16), &mut items);
        assert_eq!(g, [4, 4, 4, 4]);
        let groups: Vec<&[u32]> = {
            let (a, r) = items.split_at(4);
            let (b, r) = r.split_at(4);
            let (c, d) = r.split_at(4);
            vec![a, b, c, d]
        };
        // Array order: low-x/low-y, low-x/high-y, high-x/low-y, high-x/high-y.
        let want = [(false, false), (false, true), (true, false), (true, true)];
        for (grp, (hx, hy)) in groups.iter().zip(want) {
            for &i in *grp {
                let m = infos[i as usize].mid;
                assert_eq!((m.x >= 2.0, m.y >= 2.0), (hx, hy), "triangle {i} at {m}");
            }
        }
    }

    #[test]
    fn split_follows_texel_demand_not_world_area() {
        // Left (x = 0..9): ten big triangles (area 100 each) sharing one texture, one period of 60 texels:
        // demand 64² however many there are. Right (x = 10..19): ten small triangles (area 1) with a
        // texture each: 10 · 64². Equal world areas would cut inside the left group (x ≈ 5); equal demand
        // cuts inside the right group, so the low half holds the shared texture and about half the small
        // ones (64² · 5.5 per side).
        let mut infos: Vec<TriInfo> = (0..10)
            .map(|i| tri(DVec2::new(f64::from(i), 0.0), 0, 60.0, 100.0))
            .collect();
        infos.extend((0..10).map(|i| tri(DVec2::new(f64::from(10 + i), 0.0), 1 + i, 60.0, 1.0)));
        let mut items: Vec<u32> = (0..20).collect();
        let m = model(11);
        let s = Splitter {
            infos: &infos,
            model: &m,
            rule: SplitRule::Demand,
        };
        let k = s.cut_sorted(&mut items, 0);
        // At a cut k ≥ 10 the low half needs 64² · (1 + k − 10), the high half 64² · (20 − k): the larger is
        // smallest (6 · 64²) at k = 14 and 15, and the tie goes to the cut nearer the middle.
        assert_eq!(k, 14, "cut at {k}");
        let area_left: f64 = items[..k].iter().map(|&i| infos[i as usize].area).sum();
        assert!(
            area_left > 900.0,
            "the low half holds the big shared triangles"
        );
    }

    #[test]
    fn split_terminates_on_identical_midpoints_and_never_separates_equal_keys() {
        let infos: Vec<TriInfo> = (0..1000)
            .map(|i| tri(DVec2::new(5.0, 5.0), i % 7, 10.0, 0.0))
            .collect();
        let mut items: Vec<u32> = (0..1000).collect();
        let g = split(&infos, &model(7), &mut items);
        assert_eq!(g.iter().sum::<usize>(), 1000);
        assert!(
            g.iter().all(|&n| n < 1000),
            "every child must shrink: {g:?}"
        );
        // Two triangles: each goes to its own child; one triangle: everything in the first group.
        let mut two = vec![0u32, 1];
        assert_eq!(
            split(&infos, &model(7), &mut two)
                .iter()
                .filter(|&&n| n == 1)
                .count(),
            2
        );
        let mut one = vec![0u32];
        assert_eq!(split(&infos, &model(7), &mut one), [1, 0, 0, 0]);
        // Midpoints 1e-9 apart are one key: the cut falls between x = 0 and x = 1, never inside the pair.
        let infos = vec![
            tri(DVec2::new(0.0, 0.0), 0, 10.0, 1.0),
            tri(DVec2::new(1e-9, 0.0), 1, 10.0, 1.0),
            tri(DVec2::new(1.0, 0.0), 2, 10.0, 1.0),
            tri(DVec2::new(1000.0, 0.0), 3, 10.0, 1.0),
        ];
        let keys = midpoint_keys(&infos, &[0, 1, 2, 3], 0);
        assert_eq!(keys[0], keys[1]);
        assert_ne!(keys[1], keys[2]);
        let m = model(4);
        let s = Splitter {
            infos: &infos,
            model: &m,
            rule: SplitRule::Demand,
        };
        let mut items = vec![0, 1, 2, 3];
        let k = s.cut_sorted(&mut items, 0);
        assert!(
            k == 2 || k == 3,
            "cut {k} must not separate triangles 0 and 1"
        );
    }
}
