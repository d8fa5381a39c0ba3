//! Leaf atlases: a node's triangles → per-(material, density class) needs → one packed atlas of
//! [`PlannedRect`]s, or `None` when they do not fit (§5.2.2, §5.2.3).
//!
//! A need is the maximum texels per UV unit of the triangles (§5.2.1) and their UV cover per axis
//! ([`crate::preprocess::cover`]: at most one period where the sampler repeats, mirrors or clamps with
//! repeats wrapped). Rect sizes come from [`crate::preprocess::area`] at a resolution scale ≤ 1, texels
//! including borders; the rects are packed by [`crate::preprocess::pack`]. Nodes made leaves although their
//! content does not fit at full resolution get the largest scale that fits ([`clamp_leaf`]), at least
//! [`MIN_LEAF_SCALE`] for leaves made for their content.

use super::tree::{LayoutError, LayoutOptions, LeafLayout, LeafReason, PlannedRect};
use crate::ids::MaterialId;
use crate::model::RectWrap;
use crate::model::sizing::SizeMethod;
use crate::preprocess::area::{
    AreaInput, AreaOptions, on_source_grid_at, required_area, scale_to_fit,
};
use crate::preprocess::cover::AxisCover;
use crate::preprocess::originals::original_class;
use crate::preprocess::pack::{PackOptions, pack};
use crate::preprocess::prepare::{TriInfo, walk_prefix};
use crate::scene::Scene;
use glam::DVec2;
use std::collections::{BTreeMap, HashSet};

/// What leaf planning reads: the scene (material wraps, image sizes), the prepared triangles and the
/// options.
pub(super) struct Ctx<'a> {
    pub(super) scene: &'a Scene,
    pub(super) infos: &'a [TriInfo],
    pub(super) opts: &'a LayoutOptions,
}

/// Per-(material, density class) requirements of a node (the maxima of §5.2.1 and the UV cover of
/// §5.2.2, [`crate::preprocess::cover`]).
pub(super) struct MatNeed {
    w: f64,
    h: f64,
    cover: [AxisCover; 2],
    point_uvs: bool,
    /// A palette cell's need ([`crate::preprocess::palette::is_cell_class`]): a point, never widened.
    cell: bool,
}

impl MatNeed {
    /// Adds the triangles `other` was accumulated from (same material and class): the need of both runs.
    fn absorb(&mut self, other: MatNeed) {
        self.w = self.w.max(other.w);
        self.h = self.h.max(other.h);
        self.point_uvs |= other.point_uvs;
        let [u, v] = other.cover;
        self.cover[0].absorb(u);
        self.cover[1].absorb(v);
    }

    /// The area input at the node's requirement (palette textures — several constant-UV triangles —
    /// keep their source resolution over their used area). An axis held at the source's resolution
    /// (`cap_to_source` and a need of at least the source's texels) has its range on the source's texel
    /// grid ([`on_source_grid_at`] at the leaf's resolution `scale`).
    fn input(&self, source: [u32; 2], cap_to_source: bool, scale: f64) -> AreaInput {
        let (u0, u1) = self.cover[0].range();
        let (v0, v1) = self.cover[1].range();
        let (mut w, mut h) = (self.w, self.h);
        // A cell's UVs lie within a 64th of a texel: its rect stays a point (1 × 1 inner at any scale),
        // not the whole texel at the source's resolution, which a scaled leaf averaged with neighbours.
        if self.point_uvs && !self.cell && (u1 > u0 || v1 > v0) {
            w = w.max(f64::from(source[0]));
            h = h.max(f64::from(source[1]));
        }
        let grid = |(lo, hi): (f64, f64), need: f64, k: usize| {
            let s = source[k];
            if cap_to_source && need >= f64::from(s) {
                on_source_grid_at(lo, hi, s, self.cover[k].wrap(), scale)
            } else {
                (lo, hi)
            }
        };
        let (u0, u1) = grid((u0, u1), w, 0);
        let (v0, v1) = grid((v0, v1), h, 1);
        AreaInput {
            w,
            h,
            uv_min: [u0, v0],
            uv_max: [u1, v1],
            source,
        }
    }
}

/// Triangles per task of [`material_needs`] on big nodes (the root of a city holds millions).
const NEEDS_CHUNK: usize = 1 << 16;

/// The needs of a node's triangles (one pass; on big nodes chunks on the rayon pool, absorbed in order:
/// maxima, flags and covers do not depend on how the triangles were split, [`MatNeed::absorb`]).
pub(super) fn material_needs(ctx: &Ctx<'_>, items: &[u32]) -> BTreeMap<(MaterialId, i32), MatNeed> {
    use rayon::prelude::*;
    if items.len() <= NEEDS_CHUNK {
        return needs_of_run(ctx, items);
    }
    items
        .par_chunks(NEEDS_CHUNK)
        .map(|run| needs_of_run(ctx, run))
        .reduce(BTreeMap::new, |mut a, b| {
            for (key, need) in b {
                match a.entry(key) {
                    std::collections::btree_map::Entry::Occupied(mut e) => e.get_mut().absorb(need),
                    std::collections::btree_map::Entry::Vacant(e) => {
                        e.insert(need);
                    }
                }
            }
            a
        })
}

/// [`material_needs`] of one run of triangles, walked in order.
fn needs_of_run(ctx: &Ctx<'_>, items: &[u32]) -> BTreeMap<(MaterialId, i32), MatNeed> {
    // Needs in order of first use, found by key; consecutive triangles mostly share their material, so
    // the last key is tried first.
    let mut needs: Vec<((MaterialId, i32), MatNeed)> = Vec::new();
    let mut slot_of: BTreeMap<(MaterialId, i32), usize> = BTreeMap::new();
    let mut last: Option<((MaterialId, i32), usize)> = None;
    for t in walk_prefix(ctx.infos, items, TriInfo::SPLIT_BYTES) {
        let key = (t.material, t.class);
        let slot = match last {
            Some((k, slot)) if k == key => slot,
            _ => *slot_of.entry(key).or_insert_with(|| {
                needs.push((key, new_need(ctx, t.material, t.class)));
                needs.len() - 1
            }),
        };
        last = Some((key, slot));
        let e = &mut needs[slot].1;
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
    needs.into_iter().collect()
}

/// A need of `material` and `class` before any triangle: nothing covered, at its sampler's rect wrap.
fn new_need(ctx: &Ctx<'_>, material: MaterialId, class: i32) -> MatNeed {
    let wrap = ctx.scene.materials[material.idx()].wrap;
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
        cell: crate::preprocess::palette::is_cell_class(class),
    }
}

fn source_of(ctx: &Ctx<'_>, mat: MaterialId) -> [u32; 2] {
    ctx.scene.source_size(mat)
}

fn area_options(ctx: &Ctx<'_>, scale: f64) -> AreaOptions {
    AreaOptions {
        border: ctx.opts.border,
        scale,
        cap_to_source: ctx.opts.cap_to_source,
        max_side: ctx.opts.atlas_size,
        cap_floor: true,
    }
}

/// The largest resolution scale `≤ 1` at which every rect fits the atlas on its own. With repeats wrapped a
/// rect holds at most one period, so a rect too large alone stays too large in every descendant: the node
/// is scaled instead of split. With repeats baked splitting shrinks the UV ranges: 1.
pub(super) fn base_scale(ctx: &Ctx<'_>, needs: &BTreeMap<(MaterialId, i32), MatNeed>) -> f64 {
    if !ctx.opts.wrap {
        return 1.0;
    }
    let opts = area_options(ctx, 1.0);
    needs
        .iter()
        .filter_map(|(&(mat, _), need)| {
            scale_to_fit(
                &need.input(source_of(ctx, mat), ctx.opts.cap_to_source, 1.0),
                &opts,
                ctx.opts.atlas_size,
            )
        })
        .fold(1.0, f64::min)
}

/// `(share of the node's demand capped to the sources, texels of its originals as class layers, `class²` each)`.
pub(super) fn capped_demand(
    ctx: &Ctx<'_>,
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
) -> (f64, u64) {
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
        let input = need.input(src, ctx.opts.cap_to_source, 1.0);
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

/// Tries to lay out one atlas for the node's `needs` at resolution `scale` (§5.2.2, §5.2.3), below
/// scale 1 with the capped rects' floors ([`crate::preprocess::area::SCALED_CAP_FLOOR`]) and, where they
/// do not fit, without them: the floors are kept where there is room, never the reason a node splits
/// (700 8 × 8 textures, each with its floor and a 16-texel border, no longer fitted the atlas their
/// scaled leaf had filled, and the node was split into a 4.7× larger file; fault hunt, session 31).
pub(super) fn try_leaf(
    ctx: &Ctx<'_>,
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    scale: f64,
    reason: LeafReason,
) -> Option<LeafLayout> {
    try_leaf_with(ctx, needs, scale, reason, true).or_else(|| {
        (scale < 1.0 && floors_apply(ctx, needs))
            .then(|| try_leaf_with(ctx, needs, scale, reason, false))?
    })
}

/// Whether some need is capped to its source (more texels per UV asked than it has): only then can the
/// floors ([`crate::preprocess::area::axis_texels`]) change a rect, and a retry without them differ.
fn floors_apply(ctx: &Ctx<'_>, needs: &BTreeMap<(MaterialId, i32), MatNeed>) -> bool {
    ctx.opts.cap_to_source
        && needs.iter().any(|(&(mat, _), need)| {
            let src = source_of(ctx, mat);
            need.w > f64::from(src[0]) || need.h > f64::from(src[1])
        })
}

/// [`try_leaf`] with the floors on or off (`cap_floor`).
fn try_leaf_with(
    ctx: &Ctx<'_>,
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    scale: f64,
    reason: LeafReason,
    cap_floor: bool,
) -> Option<LeafLayout> {
    let aopts = AreaOptions {
        cap_floor,
        ..area_options(ctx, scale)
    };
    let mut mats = Vec::with_capacity(needs.len());
    let mut sizes = Vec::with_capacity(needs.len());
    let mut summed: u64 = 0;
    let cap = u64::from(ctx.opts.atlas_size) * u64::from(ctx.opts.atlas_size);
    let mut seen = HashSet::new();
    let mut original_texels = 0u64;
    for (&(mat, class), need) in needs {
        let src = source_of(ctx, mat);
        let input = need.input(src, ctx.opts.cap_to_source, scale);
        let area = required_area(&input, &aopts).ok()?;
        let capped = [
            ctx.opts.cap_to_source && need.w > f64::from(src[0]),
            ctx.opts.cap_to_source && need.h > f64::from(src[1]),
        ];
        let over = |n: f64, s: u32, c: bool| if c { n / f64::from(s) } else { 1.0 };
        let need_over_source = over(need.w, src[0], capped[0]).max(over(need.h, src[1], capped[1]));
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
        let capped = (capped, need_over_source);
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
                capped: capped.0,
                need_over_source: capped.1,
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
pub(super) fn scaled_leaf(
    ctx: &Ctx<'_>,
    items: &[u32],
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    base: f64,
    reason: LeafReason,
) -> Option<LeafLayout> {
    // With the floors where the leaf fits with them at its smallest scale, else without (the scale the
    // floors' absence allows).
    let low = base * MIN_LEAF_SCALE;
    let cap_floor = match try_leaf_with(ctx, needs, low, reason, true) {
        Some(_) => true,
        None if floors_apply(ctx, needs) => {
            try_leaf_with(ctx, needs, low, reason, false)?;
            false
        }
        None => return None,
    };
    clamp_leaf_with(ctx, items, needs, base, reason, cap_floor).ok()
}

/// The smallest resolution scale of a leaf made for its content (`min_distance ≤ 16 · d_min`).
pub const MIN_LEAF_SCALE: f64 = 1.0 / 16.0;

/// A node that is to be a leaf although its content does not fit at `base`: the largest scale (to 1/4096
/// precision in log2, below `base`) at which it fits. Its `min_distance` becomes `d_min / scale`.
pub(super) fn clamp_leaf(
    ctx: &Ctx<'_>,
    items: &[u32],
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    base: f64,
    reason: LeafReason,
) -> Result<LeafLayout, LayoutError> {
    // The floors shrink with the scale (never above what the leaf's distance shows), so at the
    // bisection's low end they hold what the rule without them does.
    clamp_leaf_with(ctx, items, needs, base, reason, true)
}

/// [`clamp_leaf`] with the capped rects' floors on or off: one rule for every scale tried, so the
/// bisection's predicate is monotone (either rule's fit only grows as the scale falls).
fn clamp_leaf_with(
    ctx: &Ctx<'_>,
    items: &[u32],
    needs: &BTreeMap<(MaterialId, i32), MatNeed>,
    base: f64,
    reason: LeafReason,
    cap_floor: bool,
) -> Result<LeafLayout, LayoutError> {
    // Bisection on log2(scale) in [log2(base) − 40, log2(base)].
    let top = base.log2();
    let (mut lo, mut hi) = (top - 40.0, top);
    let Some(mut best) = try_leaf_with(ctx, needs, lo.exp2(), reason, cap_floor) else {
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
        match try_leaf_with(ctx, needs, mid.exp2(), reason, cap_floor) {
            Some(l) => {
                best = l;
                lo = mid;
            }
            None => hi = mid,
        }
    }
    Ok(best)
}
