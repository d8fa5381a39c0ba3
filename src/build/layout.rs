//! The tree's shape: try a node atlas, split on failure (paper §5.1, §5.2.3, §5.3).
//!
//! Only sizes are computed here, no pixel: a node "fits" when the required areas of all its textures pack
//! into one atlas. Nodes that do not fit are split into four groups; the recursion runs in parallel
//! (rayon) over the four children. The triangles of every node are one contiguous range of a single
//! permutation array, so the leaves of any subtree are contiguous in tree order.
//!
//! Termination, where the paper would loop forever: a split always leaves every child with fewer triangles
//! than its parent (the cut index is kept inside `1..n`), a single triangle that alone needs more than the
//! atlas is *clamped* (its leaf's resolution is scaled down and its `min_distance` raised by the same
//! factor; reported), and `max_depth` bounds the depth with an error naming the region.

use super::area::{AreaInput, AreaOptions, required_area};
use super::pack::{PackOptions, pack};
use super::prepare::TriInfo;
use super::sizing::SizeMethod;
use crate::ids::{Cell, Level, MaterialId};
use crate::scene::Scene;
use glam::{DVec2, DVec3};
use std::collections::BTreeMap;
use std::ops::Range;

/// Options of the layout stage.
#[derive(Clone, Debug)]
pub struct LayoutOptions {
    pub atlas_size: u32,
    pub border: u32,
    pub max_depth: u8,
    /// Never more texels per repetition than the source image has (see `area`).
    pub cap_to_source: bool,
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
    /// True if the source cap limited this texture's resolution (then the guarantee is the source's).
    pub capped: bool,
}

/// A successful leaf layout.
#[derive(Clone, Debug)]
pub struct LeafLayout {
    pub rects: Vec<PlannedRect>,
    /// Share of the atlas covered by outer rectangles, 0..1.
    pub occupancy: f64,
    /// 1.0 unless the leaf had to be clamped.
    pub clamp_scale: f64,
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

/// The whole layout plus counters for the report.
#[derive(Debug)]
pub struct Layout {
    pub root: LayoutNode,
    /// Permutation of the prepared triangles: leaves' ranges in tree order.
    pub order: Vec<u32>,
    pub clamped_leaves: usize,
}

struct Ctx<'a> {
    scene: &'a Scene,
    infos: &'a [TriInfo],
    opts: &'a LayoutOptions,
    nodes: &'a std::sync::atomic::AtomicU64,
    progress: &'a (dyn Fn(u64) + Sync),
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
    let ctx = Ctx {
        scene,
        infos,
        opts,
        nodes: &nodes,
        progress,
    };
    let root = build_node(&ctx, &mut order, 0, Level(0), Cell::default())?;
    let clamped_leaves = count_clamped(&root);
    Ok(Layout {
        root,
        order,
        clamped_leaves,
    })
}

fn count_clamped(n: &LayoutNode) -> usize {
    match &n.kind {
        LayoutKind::Leaf(l) => usize::from(l.clamp_scale < 1.0),
        LayoutKind::Inner { children, .. } => {
            children.iter().flatten().map(|c| count_clamped(c)).sum()
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
    let leaf = match try_leaf(ctx, items, 1.0) {
        Some(leaf) => Some(leaf),
        None if items.len() == 1 => Some(clamp_leaf(ctx, items)?),
        None => None,
    };
    if let Some(leaf) = leaf {
        let kind = LayoutKind::Leaf(leaf);
        return Ok(LayoutNode {
            range,
            level,
            cell,
            lo,
            hi,
            kind,
        });
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
    let groups = split4(ctx.infos, items);
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

/// Splits `items` in place into four groups (paper §5.3): sort by plane-midpoint x and cut where the summed
/// world area is closest to half, then each half likewise by y. Returns the group lengths in array order
/// (low-x/low-y, low-x/high-y, high-x/low-y, high-x/high-y). Every group is shorter than `items` when
/// `items.len() ≥ 2`: the cut is kept inside `1..n`, so thousands of triangles with one midpoint still split.
pub fn split4(infos: &[TriInfo], items: &mut [u32]) -> [usize; 4] {
    let k = cut_sorted(infos, items, |t| t.mid.x);
    let (lo, hi) = items.split_at_mut(k);
    let k0 = cut_sorted(infos, lo, |t| t.mid.y);
    let k1 = cut_sorted(infos, hi, |t| t.mid.y);
    [k0, lo.len() - k0, k1, hi.len() - k1]
}

/// Sorts `items` by `key` (ties by index, deterministic) and returns the cut index closest to half the
/// summed area, clamped to `1..n` for n ≥ 2 (for n ≤ 1 it returns n: everything in the low group).
fn cut_sorted(infos: &[TriInfo], items: &mut [u32], key: impl Fn(&TriInfo) -> f64) -> usize {
    let n = items.len();
    if n <= 1 {
        return n;
    }
    items.sort_unstable_by(|&a, &b| {
        key(&infos[a as usize])
            .total_cmp(&key(&infos[b as usize]))
            .then(a.cmp(&b))
    });
    let total: f64 = items.iter().map(|&i| infos[i as usize].area).sum();
    if total <= 0.0 || !total.is_finite() {
        return n / 2;
    }
    let half = total * 0.5;
    let mut acc = 0.0;
    let mut best = 1;
    let mut best_err = f64::INFINITY;
    for (i, &it) in items.iter().enumerate().take(n - 1) {
        acc += infos[it as usize].area;
        let err = (acc - half).abs();
        if err < best_err {
            best_err = err;
            best = i + 1;
        }
    }
    best.clamp(1, n - 1)
}

/// Per-(material, density class) requirements of a node (the maxima of §5.2.1 and the UV bounding area of §5.2.2).
struct MatNeed {
    w: f64,
    h: f64,
    uv_min: DVec2,
    uv_max: DVec2,
    point_uvs: bool,
}

fn material_needs(infos: &[TriInfo], items: &[u32]) -> BTreeMap<(MaterialId, i32), MatNeed> {
    let mut m: BTreeMap<(MaterialId, i32), MatNeed> = BTreeMap::new();
    for &i in items {
        let t = &infos[i as usize];
        let e = m.entry((t.material, t.class)).or_insert(MatNeed {
            w: 0.0,
            h: 0.0,
            uv_min: DVec2::splat(f64::INFINITY),
            uv_max: DVec2::splat(f64::NEG_INFINITY),
            point_uvs: false,
        });
        for uv in t.uv {
            if uv.is_finite() {
                e.uv_min = e.uv_min.min(uv);
                e.uv_max = e.uv_max.max(uv);
            }
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
    for e in m.values_mut() {
        if !e.uv_min.is_finite() {
            e.uv_min = DVec2::ZERO;
            e.uv_max = DVec2::ZERO;
        }
    }
    m
}

/// Tries to lay out one atlas for `items` at resolution `scale` (§5.2.2, §5.2.3).
fn try_leaf(ctx: &Ctx<'_>, items: &[u32], scale: f64) -> Option<LeafLayout> {
    let needs = material_needs(ctx.infos, items);
    let aopts = AreaOptions {
        border: ctx.opts.border,
        scale,
        cap_to_source: ctx.opts.cap_to_source,
        max_side: ctx.opts.atlas_size,
    };
    let mut mats = Vec::with_capacity(needs.len());
    let mut sizes = Vec::with_capacity(needs.len());
    let mut summed: u64 = 0;
    let cap = u64::from(ctx.opts.atlas_size) * u64::from(ctx.opts.atlas_size);
    for (&(mat, class), need) in &needs {
        let img = &ctx.scene.images[ctx.scene.materials[mat.idx()].image.idx()];
        let (mut w, mut h) = (need.w, need.h);
        if need.point_uvs && need.uv_max != need.uv_min {
            w = w.max(f64::from(img.width));
            h = h.max(f64::from(img.height));
        }
        let input = AreaInput {
            w,
            h,
            uv_min: need.uv_min.to_array(),
            uv_max: need.uv_max.to_array(),
            source: [img.width, img.height],
        };
        let area = required_area(&input, &aopts).ok()?;
        let capped = ctx.opts.cap_to_source
            && (need.w > f64::from(img.width) || need.h > f64::from(img.height));
        summed += u64::from(area.outer_w) * u64::from(area.outer_h);
        if summed > cap {
            return None;
        }
        sizes.push([area.outer_w, area.outer_h]);
        mats.push((mat, class, area, need.uv_min, need.uv_max, capped));
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
            |((material, class, a, uv_min, uv_max, capped), p)| PlannedRect {
                material,
                class,
                outer: [p[0], p[1], a.outer_w, a.outer_h],
                inner: [p[0] + a.border[0], p[1] + a.border[1], a.inner_w, a.inner_h],
                uv_min,
                uv_max,
                capped,
            },
        )
        .collect();
    Some(LeafLayout {
        rects,
        occupancy: packing.occupancy,
        clamp_scale: scale,
    })
}

/// A single triangle that alone needs more than the atlas: the largest scale (to 1/64 precision in
/// log2) at which it fits. Its leaf's `min_distance` becomes `d_min / scale`.
fn clamp_leaf(ctx: &Ctx<'_>, items: &[u32]) -> Result<LeafLayout, LayoutError> {
    // Bisection on log2(scale) in [-40, 0].
    let (mut lo, mut hi) = (-40.0f64, 0.0f64);
    let Some(mut best) = try_leaf(ctx, items, lo.exp2()) else {
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
        match try_leaf(ctx, items, mid.exp2()) {
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
    use crate::build::sizing::{SizeEstimate, SizeMethod};

    fn tri(mid: DVec2, area: f64) -> TriInfo {
        TriInfo {
            scene_tri: 0,
            pos: [DVec3::ZERO; 3],
            material: MaterialId(0),
            mid,
            area,
            size: SizeEstimate {
                w: 1.0,
                h: 1.0,
                method: SizeMethod::Exact,
            },
            class: 0,
            uv: [DVec2::ZERO; 3],
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
        }
    }

    #[test]
    fn split_balances_area_in_x_then_y() {
        // A 4×4 grid of unit-area triangles: the split must give four 2×2 quadrants.
        let infos: Vec<TriInfo> = (0..16)
            .map(|i| tri(DVec2::new((i % 4) as f64, (i / 4) as f64), 1.0))
            .collect();
        let mut items: Vec<u32> = (0..16).rev().collect();
        let g = split4(&infos, &mut items);
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
    fn split_cuts_at_half_the_area_not_half_the_count() {
        // One big triangle on the left outweighs ten small ones on the right.
        let mut infos = vec![tri(DVec2::new(0.0, 0.0), 10.0)];
        infos.extend((1..=10).map(|i| tri(DVec2::new(i as f64, 0.0), 1.0)));
        let mut items: Vec<u32> = (0..11).collect();
        let g = split4(&infos, &mut items);
        assert_eq!(
            g[0] + g[1],
            1,
            "the heavy triangle alone forms the low-x half: {g:?}"
        );
    }

    #[test]
    fn split_terminates_on_identical_midpoints_and_zero_areas() {
        let infos: Vec<TriInfo> = (0..1000).map(|_| tri(DVec2::new(5.0, 5.0), 0.0)).collect();
        let mut items: Vec<u32> = (0..1000).collect();
        let g = split4(&infos, &mut items);
        assert_eq!(g.iter().sum::<usize>(), 1000);
        assert!(
            g.iter().all(|&n| n < 1000),
            "every child must shrink: {g:?}"
        );
        // Two triangles: each goes to its own child; one triangle: everything in the first group.
        let mut two = vec![0u32, 1];
        assert_eq!(
            split4(&infos, &mut two).iter().filter(|&&n| n == 1).count(),
            2
        );
        let mut one = vec![0u32];
        assert_eq!(split4(&infos, &mut one), [1, 0, 0, 0]);
    }
}
