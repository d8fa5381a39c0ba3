//! Per-node texture transforms (paper §5.1, Fig. 4) in the exact form of docs/DESIGN.md "Precision".
//!
//! The paper stores root-atlas UVs and draws a node at level k with `fract(uv_root · 2^k)`. In f32 that
//! leaves `24 − k − log2(atlas_size)` bits below a texel. We use each fragment's *leaf-local* atlas UV and
//! each leaf's integer cell `(ix, iy)` at its level K; drawn with the atlas of an ancestor at level j ≤ K:
//!
//! `uv_j = uv_leaf · 2^(j−K) + ((ix, iy) mod 2^(K−j)) / 2^(K−j)`
//!
//! a power-of-two scale (exact in floating point) plus an offset that is an integer divided by a power of
//! two (exact), so the only rounding is one final addition. The shader (`shaders/tree.wgsl`) does exactly
//! the f32 arithmetic of [`atlas_uv_at_f32`]. "Leaf-local atlas UV" is a fragment's position in its leaf's
//! atlas, which the shader computes from the original UV:
//!
//! Before that transform, a UV reaches its rect of the leaf atlas through the rect's per-axis wrap
//! ([`RectWrap`], docs/DESIGN.md "Repeats"): [`rect_t`] and [`rect_texel`] here are the f64 reference of what
//! the shader does in f32 (`render::wgsl::tree::RectMap::texel_f32` is its exact twin).

use crate::ids::{Cell, Level};
use crate::model::{AtlasRect, RectWrap};
use glam::{DVec2, Vec2};

/// `u` folded into `[0, 1]` as a MIRRORED_REPEAT sampler reads it (period 2).
#[inline]
pub fn mirror(u: f64) -> f64 {
    let p = u - 2.0 * (u * 0.5).floor();
    if p > 1.0 { 2.0 - p } else { p }
}

/// The image of `[lo, hi]` under the mirror fold (period 2, `[0, 1]` forward, `[1, 2]` backward): the hull
/// of the fold at both ends and at every integer inside.
pub fn mirror_image(lo: f64, hi: f64) -> (f64, f64) {
    if hi - lo >= 2.0 {
        return (0.0, 1.0);
    }
    let m = mirror;
    let (mut a, mut b) = (m(lo).min(m(hi)), m(lo).max(m(hi)));
    // Integers inside (lo, hi) fold to 0 (even) or 1 (odd); at most two of them since hi − lo < 2.
    let first = lo.floor() + 1.0;
    let mut k = first;
    while k < hi {
        let v = m(k);
        a = a.min(v);
        b = b.max(v);
        k += 1.0;
    }
    (a, b)
}

/// Half the part of the period a REPEAT rect does not hold (`(1 − span) / 2`, 0 for a full period): UVs
/// are reduced into `[−half_gap, span + half_gap)` around the rect, so a UV just outside the held range
/// (interpolation noise, filtering) lands next to the near edge, never at the far one.
#[inline]
pub fn half_gap(uv_min: f64, uv_max: f64) -> f64 {
    (0.5 * (1.0 - (uv_max - uv_min))).max(0.0)
}

/// The rect-relative coordinate of UV `u` along one axis: its offset from `uv_min` after the axis' wrap,
/// UV units. Every UV of the rect's triangles lands in `[0, uv_max − uv_min]`; the rect's border holds
/// what the sampler's own rule shows around that range.
#[inline]
pub fn rect_t(u: f64, wrap: RectWrap, uv_min: f64, uv_max: f64) -> f64 {
    match wrap {
        RectWrap::Linear => u - uv_min,
        RectWrap::Repeat => {
            let x = u - uv_min;
            x - (x + half_gap(uv_min, uv_max)).floor()
        }
        RectWrap::Mirror => mirror(u) - uv_min,
        RectWrap::Clamp => u.clamp(0.0, 1.0) - uv_min,
    }
}

/// Leaf-atlas texel coordinates (x right, y down, texel units, not centres) of UV `uv` in `rect`:
/// [`rect_t`] per axis scaled onto the inner rectangle, then kept `margin` texels inside the outer
/// rectangle (the inner rectangle's centre where the outer rectangle is narrower than twice the margin,
/// as the shader). The shader keeps its sample half a drawn texel inside and sharpens its gradients so the
/// sampler's filter never reaches a neighbouring rect (`RectMap::footprint_cap`); its f32 twin, `render::wgsl::tree::RectMap::texel_f32`, agrees with this within f32 precision
/// (tests/cpu/render.rs and, on the GPU, tests/gpu/shader_math.rs).
pub fn rect_texel(uv: DVec2, rect: &AtlasRect, margin: DVec2) -> DVec2 {
    let tpu = rect.texels_per_uv();
    let axis = |k: usize, u: f64, m: f64| {
        let t = rect_t(u, rect.wrap[k], rect.uv_min[k], rect.uv_max[k]);
        let x = f64::from(rect.inner[k]) + t * tpu[k];
        let lo = f64::from(rect.outer[k]) + m;
        let hi = f64::from(rect.outer[k] + rect.outer[k + 2]) - m;
        if lo <= hi {
            x.clamp(lo, hi)
        } else {
            f64::from(rect.inner[k]) + 0.5 * f64::from(rect.inner[k + 2])
        }
    };
    DVec2::new(axis(0, uv.x, margin.x), axis(1, uv.y, margin.y))
}

/// The cell offset of a level-K cell inside its level-j ancestor, in units of the ancestor's atlas:
/// `(cell mod 2^(K−j)) / 2^(K−j)`. `j ≤ K ≤ 31`.
#[inline]
pub fn cell_offset(cell: Cell, leaf_level: Level, level: Level) -> (u32, u32, u32) {
    let d = u32::from(leaf_level.0.saturating_sub(level.0)).min(31);
    let mask = (1u32 << d) - 1;
    (cell.ix & mask, cell.iy & mask, d)
}

/// Reference in f64: the UV in the atlas of the ancestor at `level` (paper Fig. 4).
pub fn atlas_uv_at(uv_leaf: DVec2, leaf_cell: Cell, leaf_level: Level, level: Level) -> DVec2 {
    let (ox, oy, d) = cell_offset(leaf_cell, leaf_level, level);
    let s = (-(d as f64)).exp2();
    uv_leaf * s + DVec2::new(ox as f64, oy as f64) * s
}

/// The shader's arithmetic in f32 (what `tree.wgsl` computes per vertex).
pub fn atlas_uv_at_f32(uv_leaf: Vec2, leaf_cell: Cell, leaf_level: Level, level: Level) -> Vec2 {
    let (ox, oy, d) = cell_offset(leaf_cell, leaf_level, level);
    let s = (-(d as f32)).exp2();
    uv_leaf * s + Vec2::new(ox as f32, oy as f32) * s
}

/// The paper's form, for comparison: root-atlas UV in f32, then `fract(uv_root · 2^j)`.
pub fn atlas_uv_naive_f32(uv_leaf: Vec2, leaf_cell: Cell, leaf_level: Level, level: Level) -> Vec2 {
    let k = leaf_level.0 as i32;
    let root =
        (uv_leaf + Vec2::new(leaf_cell.ix as f32, leaf_cell.iy as f32)) * (-(k as f32)).exp2();
    let scaled = root * (level.0 as f32).exp2();
    scaled - scaled.floor()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_form_matches_f64_at_depth_24() {
        let leaf_level = Level(24);
        let cell = Cell {
            ix: 0xABCDE1,
            iy: 0x123457,
        };
        let uv = Vec2::new(0.3711, 0.8125);
        for j in 0..=24u8 {
            let want = atlas_uv_at(uv.as_dvec2(), cell, leaf_level, Level(j));
            let got = atlas_uv_at_f32(uv, cell, leaf_level, Level(j)).as_dvec2();
            // One f32 rounding of a value in [0, 1): ≤ 2^-24.
            assert!(
                (want - got).abs().max_element() <= 2f64.powi(-24),
                "level {j}: {want} vs {got}"
            );
        }
    }

    #[test]
    fn leaf_level_is_identity_and_root_contains_cell() {
        let cell = Cell { ix: 5, iy: 2 };
        let uv = DVec2::new(0.25, 0.75);
        assert_eq!(atlas_uv_at(uv, cell, Level(3), Level(3)), uv);
        let r = atlas_uv_at(uv, cell, Level(3), Level(0));
        assert_eq!(r, DVec2::new((5.0 + 0.25) / 8.0, (2.0 + 0.75) / 8.0));
    }

    #[test]
    fn naive_form_loses_precision_deep() {
        let cell = Cell {
            ix: (1 << 20) - 3,
            iy: 7,
        };
        let uv = Vec2::new(0.3711, 0.8125);
        let err = (atlas_uv_naive_f32(uv, cell, Level(20), Level(20)) - uv)
            .abs()
            .max_element();
        // At depth 20 the naive root UV keeps only ~4 bits below a leaf-atlas unit.
        assert!(err > 1e-3, "naive error {err}");
    }
}
