//! Required atlas area of one material in one node (paper §5.2.2).
//!
//! Input: the per-repetition size `(w, h)` (texels per unit of UV, the maximum over the material's
//! triangles from [`crate::preprocess::sizing`]), the UV bounding box `A_tex = [uv_min, uv_max]` of those
//! triangles and the source image size. Output: the inner rectangle that `A_tex` maps onto, and the outer
//! rectangle with the border that the packer places.
//!
//! - **Inner**: `ceil(w · scale · |A_w|) × ceil(h · scale · |A_h|)`, at least 1×1. With
//!   [`SizeMethod::AllUvEqual`](crate::model::sizing::SizeMethod::AllUvEqual) triangles only, `w = h = 0`
//!   and the inner area is the paper's fixed 1×1. Repetition counts cost nothing by themselves: `w · |A_w|`
//!   is the world length of the textured surface times `f_proj` (paper: "depends only on the triangle area
//!   in world space").
//! - **Source cap** ([`AreaOptions::cap_to_source`], default on): `w` is capped at the source width `sw`
//!   (and `h` at `sh`). More texels per repetition than the source has would only store a magnified copy
//!   of the original texture: the screen would show the same (magnified) source texels either way, so the
//!   no-magnification guarantee of the *atlas* holds at `sw` already. In a leaf scaled below 1 the cap
//!   comes before the scale, except that a capped axis keeps `min(sw, 8)` texels per UV where the
//!   leaf's distance shows them ([`SCALED_CAP_FLOOR`], [`axis_texels`]).
//! - **Border**: `border` texels on every side (paper: 8), then the outer size is rounded *up* to a
//!   multiple of 4 so BC blocks never straddle two textures; the extra 0–3 texels go into the border
//!   (half before, the rest after). The rasteriser fills the border by continuing the linear UV mapping
//!   `inner ↔ A_tex` beyond `A_tex`, which is exactly the paper's "scale `A_tex` around its centre";
//!   [`RequiredArea::outer_uv`] gives that scaled UV box.
//! - **Rounding**: a product within 1e-9 (relative) above an integer is rounded down to it: f64 noise of
//!   the sizing must not add a texel column; the guarantee is kept to a factor `1 + 1e-9`.
//! - **Source texel grid** ([`on_source_grid`]): where a rect holds its source's own resolution, its UV
//!   range is first widened to whole source texels, so rect texels are source texels and the rasteriser
//!   copies them instead of resampling (a range off the grid, or one f32 step past it, blurred close
//!   views: a 64² checker over UV `[0.1, 0.6]` drew at 28 dB against the original where `[0.125, 0.625]`
//!   drew at 93 dB).

use crate::model::RectWrap;
use serde::Serialize;

/// What [`required_area`] needs for one material in one node.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct AreaInput {
    /// Texels per unit of U / V (max over the triangles, [`crate::preprocess::sizing::SizeMax`]).
    pub w: f64,
    pub h: f64,
    /// `A_tex`: UV bounding box of the triangles (`uv_min ≤ uv_max` per axis).
    pub uv_min: [f64; 2],
    pub uv_max: [f64; 2],
    /// Source image size, texels `[width, height]`.
    pub source: [u32; 2],
}

/// Parameters of [`required_area`].
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct AreaOptions {
    /// Border on each side, texels (paper: 8).
    pub border: u32,
    /// Resolution scale: 1.0 normally, `< 1` when a leaf is clamped (finite, `> 0`).
    pub scale: f64,
    /// Never more texels per repetition than the source image has (see module docs).
    pub cap_to_source: bool,
    /// Largest allowed outer side, texels (normally the atlas size).
    pub max_side: u32,
    /// A capped axis of a scaled leaf keeps [`SCALED_CAP_FLOOR`] texels per UV ([`axis_texels`]); off
    /// where the floors would not let the leaf fit (the layout tries with them first).
    pub cap_floor: bool,
}

impl Default for AreaOptions {
    fn default() -> Self {
        Self {
            border: 8,
            scale: 1.0,
            cap_to_source: true,
            max_side: 1 << 16,
            cap_floor: true,
        }
    }
}

/// The area one material needs in an atlas, texels. Outer sides are multiples of 4.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct RequiredArea {
    /// Rectangle `A_tex` maps onto.
    pub inner_w: u32,
    pub inner_h: u32,
    /// Inner plus borders, rounded up to a multiple of 4.
    pub outer_w: u32,
    pub outer_h: u32,
    /// Offset of the inner rectangle inside the outer one (left, top border), texels. The right / bottom
    /// borders are `outer − inner − border`.
    pub border: [u32; 2],
}

impl RequiredArea {
    /// The UV box the *outer* rectangle shows when the linear mapping `inner ↔ [uv_min, uv_max]` is
    /// continued into the border (the paper's `A_tex` scaled around its centre, exact for uneven borders).
    pub fn outer_uv(&self, uv_min: [f64; 2], uv_max: [f64; 2]) -> ([f64; 2], [f64; 2]) {
        let axis = |lo: f64, hi: f64, inner: u32, outer: u32, before: u32| {
            let per_texel = (hi - lo) / f64::from(inner.max(1));
            let after = outer.saturating_sub(inner).saturating_sub(before);
            (
                lo - per_texel * f64::from(before),
                hi + per_texel * f64::from(after),
            )
        };
        let (u0, u1) = axis(
            uv_min[0],
            uv_max[0],
            self.inner_w,
            self.outer_w,
            self.border[0],
        );
        let (v0, v1) = axis(
            uv_min[1],
            uv_max[1],
            self.inner_h,
            self.outer_h,
            self.border[1],
        );
        ([u0, v0], [u1, v1])
    }

    /// Outer area in texels².
    pub fn outer_texels(&self) -> u64 {
        u64::from(self.outer_w) * u64::from(self.outer_h)
    }
}

/// Why an area cannot be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AreaError {
    #[error(
        "required {axis} side {texels:.1} texels (incl. 2×{border} border) exceeds the limit {limit}: \
         {per_uv:.4} texels per UV × scale {scale} × UV extent {extent}"
    )]
    TooLarge {
        axis: char,
        texels: f64,
        limit: u32,
        border: u32,
        per_uv: f64,
        scale: f64,
        extent: f64,
    },
    #[error("invalid area input: {what} = {value}")]
    Invalid { what: &'static str, value: f64 },
}

/// Relative tolerance below which a product just above an integer is rounded down to it.
const CEIL_TOLERANCE: f64 = 1e-9;

/// Required inner/outer area of one material (paper §5.2.2). See the module docs.
pub fn required_area(input: &AreaInput, opts: &AreaOptions) -> Result<RequiredArea, AreaError> {
    validate(input, opts)?;
    let (inner_w, outer_w, bx) = axis_size(
        'w',
        input.w,
        input.source[0],
        input.uv_min[0],
        input.uv_max[0],
        opts,
    )?;
    let (inner_h, outer_h, by) = axis_size(
        'h',
        input.h,
        input.source[1],
        input.uv_min[1],
        input.uv_max[1],
        opts,
    )?;
    Ok(RequiredArea {
        inner_w,
        inner_h,
        outer_w,
        outer_h,
        border: [bx, by],
    })
}

fn validate(input: &AreaInput, opts: &AreaOptions) -> Result<(), AreaError> {
    let checks = [
        ("w", input.w, input.w.is_finite() && input.w >= 0.0),
        ("h", input.h, input.h.is_finite() && input.h >= 0.0),
        (
            "scale",
            opts.scale,
            opts.scale.is_finite() && opts.scale > 0.0,
        ),
        ("uv_min.u", input.uv_min[0], input.uv_min[0].is_finite()),
        ("uv_min.v", input.uv_min[1], input.uv_min[1].is_finite()),
        (
            "uv_max.u",
            input.uv_max[0],
            input.uv_max[0].is_finite() && input.uv_max[0] >= input.uv_min[0],
        ),
        (
            "uv_max.v",
            input.uv_max[1],
            input.uv_max[1].is_finite() && input.uv_max[1] >= input.uv_min[1],
        ),
    ];
    match checks.into_iter().find(|c| !c.2) {
        Some((what, value, _)) => Err(AreaError::Invalid { what, value }),
        None => Ok(()),
    }
}

/// Texels per UV a capped axis of a leaf scaled below 1 keeps at least: all of a source up to this many
/// texels, where the leaf's distance would show them (see [`axis_texels`]).
pub const SCALED_CAP_FLOOR: f64 = 8.0;

/// Texels (before rounding) along one axis of `extent` UV: `per_uv · scale · extent`, `per_uv` capped at
/// the source first (module docs). A capped axis of a scaled leaf (`scale < 1`) keeps at least
/// `min(source, SCALED_CAP_FLOOR)` texels per UV over at most one period (`opts.cap_floor`) — no more
/// than the leaf's distance (`d_min / scale`) shows, `per_uv · scale`, nor than an atlas side holds
/// beside its borders: scaled after the cap, a
/// 2 × 2 clamp texture over a 200 m quad in a leaf of scale 0.465 was one texel, its mean, where the
/// original showed four (20.6 dB; fault hunt, session 30). Larger sources still fall short by up to
/// `1 / scale` (the build's capped-rects warning). Non-decreasing in `scale`, as the leaf clamp's
/// bisection needs; unchanged at `scale ≥ 1` and for uncapped axes.
fn axis_texels(per_uv: f64, source: u32, extent: f64, opts: &AreaOptions) -> f64 {
    if !opts.cap_to_source {
        return per_uv * opts.scale * extent;
    }
    let src = f64::from(source.max(1));
    let exact = per_uv.min(src) * opts.scale * extent;
    if opts.scale >= 1.0 || per_uv <= src || !opts.cap_floor {
        return exact;
    }
    let shown = per_uv * opts.scale * extent;
    let room = f64::from((opts.max_side / 4 * 4).saturating_sub(opts.border.saturating_mul(2)));
    // One period at most: past it a clamp rect is its edge colour and a baked one repeats (a floor over
    // 150 baked periods filled an atlas side and halved the leaf's scale; fault hunt, session 31).
    let floor = (src.min(SCALED_CAP_FLOOR) * extent.min(1.0))
        .min(shown)
        .min(room);
    exact.max(floor)
}

/// `(inner, outer, border_before)` along one axis.
fn axis_size(
    axis: char,
    per_uv: f64,
    source: u32,
    lo: f64,
    hi: f64,
    opts: &AreaOptions,
) -> Result<(u32, u32, u32), AreaError> {
    let extent = hi - lo;
    let exact = axis_texels(per_uv, source, extent, opts);
    let per_uv = if opts.cap_to_source {
        per_uv.min(f64::from(source.max(1)))
    } else {
        per_uv
    };
    let inner = ceil_tolerant(exact).max(1.0);
    let raw = inner + 2.0 * f64::from(opts.border);
    let outer = (raw / 4.0).ceil() * 4.0;
    if !outer.is_finite() || outer > f64::from(opts.max_side) {
        return Err(AreaError::TooLarge {
            axis,
            texels: outer,
            limit: opts.max_side,
            border: opts.border,
            per_uv,
            scale: opts.scale,
            extent,
        });
    }
    // 1 ≤ inner ≤ outer ≤ max_side ≤ u32::MAX: integral f64 values, so the conversions are exact.
    let (inner_u, outer_u) = (inner as u32, outer as u32);
    let extra = outer_u - inner_u - 2 * opts.border;
    Ok((inner_u, outer_u, opts.border + extra / 2))
}

/// Largest distance (texels) from a texel edge that [`on_source_grid`] takes for the edge itself, at
/// `texels` on an axis of `source` texels: half of what `inspect --verify` allows a stored UV outside its
/// rect (`max(|u|, 1) · 2⁻²¹ + 10⁻⁶` in UV, f32 storage), so a range moved inward by the snap still holds
/// its triangles there — and `0.5 + 1 f32 ulp` of a 64-texel source, 3.8·10⁻⁶ texels past texel 32, is
/// texel 32. At most 10⁻² texels (f32 UVs far from 0 hold no finer position anyway).
fn grid_tolerance(texels: f64, source: f64) -> f64 {
    (texels.abs().max(source) * 2f64.powi(-22) + source * 5e-7).min(1e-2)
}

/// The fewest source texels a repeat arc shorter than a period is widened to a whole period at (two 4×4
/// blocks): see [`on_source_grid`].
pub const MIN_WIDENED_PERIOD: f64 = 8.0;

/// `[lo, hi]` (UV, `lo ≤ hi`) widened outward to the edges of the texels of an axis of `source` texels
/// (edges at `k / source`), an edge within [`grid_tolerance`] of a texel edge taken as that edge; for a
/// rect that holds `source` texels per UV (the source cap), so its texels are the source's. The rect's
/// wrap bounds the result as it bounds the cover ([`crate::preprocess::cover`]): mirror and clamp
/// ranges stay in `[0, 1]`, a repeat arc that widens to a period is that period (one of a source under
/// [`MIN_WIDENED_PERIOD`] texels keeps its own range), a linear
/// (baked) range is unbounded. Non-finite input is returned as it is (the sizing refuses it).
pub fn on_source_grid(lo: f64, hi: f64, source: u32, wrap: RectWrap) -> (f64, f64) {
    on_source_grid_at(lo, hi, source, wrap, 1.0)
}

/// [`on_source_grid`] for a rect drawn at resolution `scale` (a leaf clamped below 1): a repeat arc is
/// widened to the whole period only where the period keeps [`MIN_WIDENED_PERIOD`] texels at that scale
/// (a 16-texel palette at scale 0.2 would be a 3-texel repeated rect; review, session 28).
pub fn on_source_grid_at(lo: f64, hi: f64, source: u32, wrap: RectWrap, scale: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) || hi < lo {
        return (lo, hi);
    }
    let s = f64::from(source.max(1));
    let snap = |x: f64, outward: fn(f64) -> f64| {
        let r = x.round();
        if (x - r).abs() <= grid_tolerance(x, s) {
            r
        } else {
            outward(x)
        }
    };
    let (a, b) = (snap(lo * s, f64::floor), snap(hi * s, f64::ceil));
    let (wlo, whi) = (a / s, b / s);
    match wrap {
        RectWrap::Linear => (wlo, whi),
        // An arc shorter than a period that widens to one is the whole period, the source's texels
        // copied: kept as it was, a half-texel inset (`[0.5, 63.5] / 64`, common in game assets) was
        // resampled half a texel off the source's grid and drew at 30.5 dB against original mode (fault
        // hunt, session 28). Except a period under [`MIN_WIDENED_PERIOD`] texels: widened, a palette's
        // few texels would become a repeated texture of that many (a 4-texel source's [0.125, 0.875],
        // scaled to 3 texels, got a repeat border no BC7 block can hold; fault hunt, session 27).
        RectWrap::Repeat if whi - wlo >= 1.0 && hi - lo < 1.0 && s * scale < MIN_WIDENED_PERIOD => {
            (lo, hi)
        }
        RectWrap::Repeat if whi - wlo >= 1.0 => (0.0, 1.0),
        // An arc starts in [0, 1) (the cover's contract): a start just below 1 taken as 1 is 0.
        RectWrap::Repeat if wlo >= 1.0 => (wlo - 1.0, whi - 1.0),
        RectWrap::Repeat => (wlo, whi),
        RectWrap::Mirror | RectWrap::Clamp => (wlo.max(0.0), whi.min(1.0)),
    }
}

/// `ceil(x)`, except that `x` within `CEIL_TOLERANCE` (relative) above an integer gives that integer.
fn ceil_tolerant(x: f64) -> f64 {
    let down = x.floor();
    if x - down <= CEIL_TOLERANCE * x.abs() {
        down
    } else {
        x.ceil()
    }
}

/// Sum of the outer areas, texels² (saturating). Early rejection: a node whose sum exceeds
/// `atlas_size²` cannot be packed (paper §5.2.3 "all or fail").
pub fn summed_area(areas: &[RequiredArea]) -> u64 {
    areas
        .iter()
        .fold(0u64, |s, a| s.saturating_add(a.outer_texels()))
}

/// True when the areas might fit an `atlas_size²` atlas: summed area and every side within bounds.
/// (Necessary, not sufficient: the packer decides.)
pub fn may_fit(areas: &[RequiredArea], atlas_size: u32) -> bool {
    let capacity = u64::from(atlas_size) * u64::from(atlas_size);
    summed_area(areas) <= capacity
        && areas
            .iter()
            .all(|a| a.outer_w <= atlas_size && a.outer_h <= atlas_size)
}

/// The largest scale `≤ opts.scale` at which `input` fits a `max_outer` square side (the leaf clamp:
/// a single texture needs more than the atlas), or `None` when even the 1×1 inner area does not fit.
pub fn scale_to_fit(input: &AreaInput, opts: &AreaOptions, max_outer: u32) -> Option<f64> {
    let avail = (max_outer / 4 * 4).checked_sub(opts.border.checked_mul(2)?)?;
    if avail == 0 {
        return None;
    }
    let mut o = AreaOptions {
        max_side: max_outer,
        ..*opts
    };
    if required_area(input, &o).is_ok() {
        return Some(opts.scale);
    }
    let cap = |per_uv: f64, src: u32| {
        if opts.cap_to_source {
            per_uv.min(f64::from(src.max(1)))
        } else {
            per_uv
        }
    };
    let need_w = cap(input.w, input.source[0]) * (input.uv_max[0] - input.uv_min[0]);
    let need_h = cap(input.h, input.source[1]) * (input.uv_max[1] - input.uv_min[1]);
    let need = need_w.max(need_h);
    if !(need.is_finite() && need > 0.0) {
        return None;
    }
    let mut s = (f64::from(avail) / need).min(opts.scale);
    // Floating noise may leave the ceil one texel over: shrink by a few ulps-worth until it fits.
    for _ in 0..8 {
        o.scale = s;
        if required_area(input, &o).is_ok() {
            return Some(s);
        }
        s *= 1.0 - 1e-12;
    }
    None
}

/// Analysis twin of [`required_area`] over many materials: what the areas cost and why.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct AreaReport {
    pub materials: u64,
    pub too_large: u64,
    pub invalid: u64,
    /// Materials whose `w` (resp. `h`) was capped at the source size.
    pub capped_w: u64,
    pub capped_h: u64,
    /// Materials whose inner area is 1×1.
    pub one_by_one: u64,
    /// Sums over the materials that succeeded, texels².
    pub inner_texels: u64,
    pub outer_texels: u64,
    /// Largest outer side, texels.
    pub max_outer_side: u32,
}

impl AreaReport {
    /// Fraction of the outer area spent on borders and 4-alignment (0 when empty).
    pub fn border_fraction(&self) -> f64 {
        if self.outer_texels == 0 {
            return 0.0;
        }
        1.0 - self.inner_texels as f64 / self.outer_texels as f64
    }
}

/// Compute every area and report counts and sums.
pub fn analyze_areas(inputs: &[AreaInput], opts: &AreaOptions) -> AreaReport {
    let mut r = AreaReport::default();
    for i in inputs {
        r.materials += 1;
        if opts.cap_to_source {
            r.capped_w += u64::from(i.w > f64::from(i.source[0].max(1)));
            r.capped_h += u64::from(i.h > f64::from(i.source[1].max(1)));
        }
        match required_area(i, opts) {
            Ok(a) => {
                r.one_by_one += u64::from(a.inner_w == 1 && a.inner_h == 1);
                r.inner_texels = r
                    .inner_texels
                    .saturating_add(u64::from(a.inner_w) * u64::from(a.inner_h));
                r.outer_texels = r.outer_texels.saturating_add(a.outer_texels());
                r.max_outer_side = r.max_outer_side.max(a.outer_w).max(a.outer_h);
            }
            Err(AreaError::TooLarge { .. }) => r.too_large += 1,
            Err(AreaError::Invalid { .. }) => r.invalid += 1,
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_widen_to_whole_source_texels() {
        const L: RectWrap = RectWrap::Linear;
        // Off the grid: outward to texel edges (64 texels: 0.1 → 6.4 → 6, 0.6 → 38.4 → 39).
        assert_eq!(on_source_grid(0.1, 0.6, 64, L), (6.0 / 64.0, 39.0 / 64.0));
        // On the grid, or one f32 step past it: unchanged, not a texel wider.
        assert_eq!(on_source_grid(0.125, 0.625, 64, L), (0.125, 0.625));
        let past = f64::from(0.5f32 + f32::EPSILON * 0.5);
        assert!(past > 0.5);
        assert_eq!(on_source_grid(0.0, past, 64, L), (0.0, 0.5));
        assert_eq!(
            on_source_grid(-f64::from(f32::EPSILON), 1.0, 64, L),
            (0.0, 1.0)
        );
        // A point inside a texel: that texel.
        assert_eq!(on_source_grid(0.35, 0.35, 10, L), (0.3, 0.4));
        // Mirror and clamp stay in [0, 1]; a repeat arc keeps crossing the seam, and one of a
        // source under 8 texels keeps its own range where it would widen to a period; baked ranges are
        // unbounded.
        assert_eq!(on_source_grid(0.01, 0.999, 4, RectWrap::Clamp), (0.0, 1.0));
        assert_eq!(on_source_grid(0.01, 0.6, 4, RectWrap::Mirror), (0.0, 0.75));
        assert_eq!(on_source_grid(0.8, 1.2, 4, RectWrap::Repeat), (0.75, 1.25));
        assert_eq!(on_source_grid(0.3, 1.2, 4, RectWrap::Repeat), (0.3, 1.2));
        assert_eq!(
            on_source_grid(0.125, 0.875, 4, RectWrap::Repeat),
            (0.125, 0.875)
        );
        assert_eq!(on_source_grid(0.0, 1.0, 4, RectWrap::Repeat), (0.0, 1.0));
        // From 8 source texels on, an arc that widens to a period is the period: a half-texel inset.
        assert_eq!(
            on_source_grid(0.5 / 64.0, 63.5 / 64.0, 64, RectWrap::Repeat),
            (0.0, 1.0)
        );
        assert_eq!(on_source_grid(0.01, 0.99, 8, RectWrap::Repeat), (0.0, 1.0));
        assert_eq!(
            on_source_grid(0.01, 0.99, 7, RectWrap::Repeat),
            (0.01, 0.99)
        );
        // At a leaf's scale below 1 the period counts the texels it keeps: 16 × 0.25 = 4 keeps its range.
        let inset = (0.5 / 16.0, 15.5 / 16.0);
        let at = |scale| on_source_grid_at(inset.0, inset.1, 16, RectWrap::Repeat, scale);
        assert_eq!(at(0.25), inset);
        assert_eq!(at(0.5), (0.0, 1.0));
        assert_eq!(on_source_grid(0.3, 1.2, 4, L), (0.25, 1.25));
        let below_one = 1.0 - 4.0 * 2f64.powi(-24);
        assert_eq!(
            on_source_grid(below_one, 1.25, 64, RectWrap::Repeat),
            (0.0, 0.25)
        );
        // A baked range far from 0 is not moved inward past what `inspect --verify` allows (f32 UVs):
        // 10 f32 steps inside a texel edge at 100.5 is not that edge; one step is.
        let step = f64::from(f32::EPSILON) * 64.0;
        let texel = 1.0 / 64.0;
        assert_eq!(
            on_source_grid(100.5 - 10.0 * step, 101.0, 64, L).0,
            100.5 - texel
        );
        assert_eq!(
            on_source_grid(100.0, 100.5 + 10.0 * step, 64, L).1,
            100.5 + texel
        );
        assert_eq!(
            on_source_grid(100.5 - step, 100.5 + step, 64, L),
            (100.5, 100.5)
        );
        // Huge UVs: the tolerance stays below a hundredth of a texel.
        let (lo, hi) = on_source_grid(1e6 + 0.3, 1e6 + 0.7, 100, L);
        assert_eq!((lo * 100.0, hi * 100.0), (1e8 + 30.0, 1e8 + 70.0));
        assert!(on_source_grid(f64::NAN, 1.0, 4, L).0.is_nan());
    }

    fn input(w: f64, h: f64, uv_min: [f64; 2], uv_max: [f64; 2]) -> AreaInput {
        AreaInput {
            w,
            h,
            uv_min,
            uv_max,
            source: [512, 512],
        }
    }

    #[test]
    fn single_repetition_with_border_and_alignment() {
        // 100.3 × 37 texels per UV over one repetition: inner 101 × 37, +16 → 117 × 53 → 120 × 56.
        let a = required_area(
            &input(100.3, 37.0, [0.0, 0.0], [1.0, 1.0]),
            &AreaOptions::default(),
        )
        .unwrap();
        assert_eq!(
            (a.inner_w, a.inner_h, a.outer_w, a.outer_h),
            (101, 37, 120, 56)
        );
        // Extra 3 (resp. 3) texels: 1 before, 2 after.
        assert_eq!(a.border, [9, 9]);
        assert_eq!(a.outer_w % 4, 0);
        assert_eq!(a.outer_h % 4, 0);
    }

    #[test]
    fn partial_and_repeated_areas_scale_with_extent() {
        let o = AreaOptions::default();
        // Half a repetition in U, 3.5 in V.
        let a = required_area(&input(64.0, 10.0, [0.25, -1.0], [0.75, 2.5]), &o).unwrap();
        assert_eq!((a.inner_w, a.inner_h), (32, 35));
        // 1e4 repetitions at 0.01 texel per repetition: 100 texels (depends on world size only).
        let a = required_area(&input(0.01, 0.01, [0.0, 5e3], [1e4, 1.5e4]), &o).unwrap();
        assert_eq!((a.inner_w, a.inner_h, a.outer_w), (100, 100, 116));
        // Huge offset of A_tex changes nothing.
        let a2 = required_area(
            &input(0.01, 0.01, [-2.9e9, -2.9e9], [-2.9e9 + 1e4, -2.9e9 + 1e4]),
            &o,
        )
        .unwrap();
        assert_eq!(a, a2);
    }

    #[test]
    fn float_noise_does_not_add_a_column() {
        // 1.1 m at 110 texels/m in f64 is 121.00000000000001.
        let w = 1.1 * 1.1 * 100.0;
        assert!(w > 121.0);
        let a = required_area(
            &input(w, 1.0, [0.0, 0.0], [1.0, 1.0]),
            &AreaOptions::default(),
        )
        .unwrap();
        assert_eq!(a.inner_w, 121);
        let a = required_area(
            &input(121.001, 1.0, [0.0, 0.0], [1.0, 1.0]),
            &AreaOptions::default(),
        )
        .unwrap();
        assert_eq!(a.inner_w, 122);
    }

    #[test]
    fn all_uv_equal_gives_one_by_one() {
        let a = required_area(
            &input(0.0, 0.0, [0.3, 0.3], [0.3, 0.3]),
            &AreaOptions::default(),
        )
        .unwrap();
        assert_eq!(
            (a.inner_w, a.inner_h, a.outer_w, a.outer_h, a.border),
            (1, 1, 20, 20, [9, 9])
        );
        let (lo, hi) = a.outer_uv([0.3, 0.3], [0.3, 0.3]);
        assert_eq!((lo, hi), ([0.3, 0.3], [0.3, 0.3]));
    }

    #[test]
    fn source_cap_and_scale() {
        let i = AreaInput {
            w: 4000.0,
            h: 100.0,
            uv_min: [0.0, 0.0],
            uv_max: [2.0, 1.0],
            source: [256, 64],
        };
        let a = required_area(&i, &AreaOptions::default()).unwrap();
        assert_eq!((a.inner_w, a.inner_h), (512, 64));
        let a = required_area(
            &i,
            &AreaOptions {
                cap_to_source: false,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!((a.inner_w, a.inner_h), (8000, 100));
        let a = required_area(
            &i,
            &AreaOptions {
                scale: 0.5,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!((a.inner_w, a.inner_h), (256, 32));
    }

    #[test]
    fn border_zero_and_outer_uv_continue_the_mapping() {
        let o = AreaOptions {
            border: 0,
            ..Default::default()
        };
        let a = required_area(&input(10.0, 8.0, [0.0, 0.0], [1.0, 1.0]), &o).unwrap();
        assert_eq!((a.outer_w, a.outer_h, a.border), (12, 8, [1, 0]));
        // 1 texel before, 1 after on U, each 0.1 UV.
        let (lo, hi) = a.outer_uv([0.0, 0.0], [1.0, 1.0]);
        assert!(
            (lo[0] + 0.1).abs() < 1e-15 && (hi[0] - 1.1).abs() < 1e-15,
            "{lo:?} {hi:?}"
        );
        assert_eq!((lo[1], hi[1]), (0.0, 1.0));
        // Paper border 8 on a 16-texel inner over one repetition: A_tex scaled ×2 around its centre.
        let a = required_area(
            &input(16.0, 16.0, [0.0, 0.0], [1.0, 1.0]),
            &AreaOptions::default(),
        )
        .unwrap();
        assert_eq!(
            a.outer_uv([0.0, 0.0], [1.0, 1.0]),
            ([-0.5, -0.5], [1.5, 1.5])
        );
    }

    #[test]
    fn too_large_and_invalid_are_errors_with_numbers() {
        let o = AreaOptions {
            max_side: 1024,
            cap_to_source: false,
            ..Default::default()
        };
        let e = required_area(&input(1e6, 1.0, [0.0, 0.0], [1e3, 1.0]), &o).unwrap_err();
        match e {
            AreaError::TooLarge {
                axis,
                texels,
                limit,
                ..
            } => {
                assert_eq!((axis, limit), ('w', 1024));
                assert_eq!(texels, 1e9 + 16.0);
            }
            other => panic!("{other:?}"),
        }
        // 1012 + 16 = 1028 > 1024 after rounding; 1008 + 16 = 1024 fits.
        assert!(required_area(&input(1009.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &o).is_err());
        assert_eq!(
            required_area(&input(1008.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &o)
                .unwrap()
                .outer_w,
            1024
        );
        let e = required_area(&input(f64::MAX, 1.0, [0.0, 0.0], [1e300, 1.0]), &o).unwrap_err();
        assert!(matches!(e, AreaError::TooLarge { axis: 'w', .. }), "{e}");
        for (i, what) in [
            (input(f64::NAN, 1.0, [0.0, 0.0], [1.0, 1.0]), "w"),
            (input(1.0, -1.0, [0.0, 0.0], [1.0, 1.0]), "h"),
            (input(1.0, 1.0, [0.0, 2.0], [1.0, 1.0]), "uv_max.v"),
        ] {
            match required_area(&i, &o) {
                Err(AreaError::Invalid { what: w, value }) => {
                    assert_eq!(w, what);
                    assert_eq!(value.to_bits(), f(&i, what).to_bits());
                }
                other => panic!("{other:?}"),
            }
        }
        let bad_scale = AreaOptions { scale: 0.0, ..o };
        assert!(matches!(
            required_area(&input(1.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &bad_scale),
            Err(AreaError::Invalid { what: "scale", .. })
        ));
    }

    fn f(i: &AreaInput, what: &str) -> f64 {
        match what {
            "w" => i.w,
            "h" => i.h,
            _ => i.uv_max[1],
        }
    }

    #[test]
    fn summed_area_and_may_fit() {
        let o = AreaOptions::default();
        let a = required_area(&input(240.0, 240.0, [0.0, 0.0], [1.0, 1.0]), &o).unwrap();
        assert_eq!((a.outer_w, a.outer_h), (256, 256));
        assert_eq!(summed_area(&[a; 4]), 4 * 65536);
        assert!(may_fit(&[a; 4], 512));
        assert!(!may_fit(&[a; 5], 512));
        assert!(!may_fit(&[a], 128));
        assert_eq!(summed_area(&[]), 0);
    }

    #[test]
    fn scale_to_fit_finds_the_leaf_clamp() {
        let o = AreaOptions {
            cap_to_source: false,
            ..Default::default()
        };
        let i = input(3000.0, 100.0, [0.0, 0.0], [1.0, 1.0]);
        let s = scale_to_fit(&i, &o, 512).unwrap();
        // avail = 512 − 16 = 496 texels for 3000 needed.
        assert!((s - 496.0 / 3000.0).abs() < 1e-9, "{s}");
        let a = required_area(
            &i,
            &AreaOptions {
                scale: s,
                max_side: 512,
                ..o
            },
        )
        .unwrap();
        assert_eq!(a.outer_w, 512);
        assert_eq!(
            scale_to_fit(&input(10.0, 10.0, [0.0, 0.0], [1.0, 1.0]), &o, 512),
            Some(1.0)
        );
        assert_eq!(scale_to_fit(&i, &o, 16), None);
    }

    #[test]
    fn report_counts() {
        let o = AreaOptions {
            max_side: 1024,
            ..Default::default()
        };
        let inputs = [
            input(0.0, 0.0, [0.0, 0.0], [0.0, 0.0]),
            input(1e4, 10.0, [0.0, 0.0], [1.0, 1.0]), // capped at 512
            input(100.0, 100.0, [0.0, 0.0], [100.0, 1.0]),
            input(f64::NAN, 1.0, [0.0, 0.0], [1.0, 1.0]),
        ];
        let r = analyze_areas(&inputs, &o);
        assert_eq!(
            (
                r.materials,
                r.too_large,
                r.invalid,
                r.capped_w,
                r.capped_h,
                r.one_by_one
            ),
            (4, 1, 1, 1, 0, 1)
        );
        assert_eq!(r.inner_texels, 1 + 512 * 10);
        assert_eq!(r.outer_texels, 20 * 20 + 528 * 28);
        assert_eq!(r.max_outer_side, 528);
        assert!((r.border_fraction() - (1.0 - 5121.0 / 15184.0)).abs() < 1e-12);
    }

    /// The floor covers one period at most (a baked rect of 150 periods asked an atlas side of it),
    /// and is off with `cap_floor` (the rule of before: the source times the scale).
    #[test]
    fn the_scaled_leaf_floor_spans_one_period_and_can_be_off() {
        let o = AreaOptions {
            border: 16,
            scale: 0.1,
            cap_to_source: true,
            max_side: 1024,
            cap_floor: true,
        };
        // An 8-texel source asked at 1000 texels per UV over 150 UV: 8 · 0.1 · 150 = 120 exact, the
        // floor 8 texels of one period: the exact size wins.
        assert_eq!(axis_texels(1000.0, 8, 150.0, &o), 8.0 * 0.1 * 150.0);
        // Over half a period: 4 texels kept, not 0.4.
        assert_eq!(axis_texels(1000.0, 8, 0.5, &o), 4.0);
        let off = AreaOptions {
            cap_floor: false,
            ..o
        };
        assert!((axis_texels(1000.0, 8, 0.5, &off) - 0.4).abs() < 1e-12);
    }

    proptest::proptest! {
        /// The scaled-leaf floor: never decreasing in the scale (the leaf clamp bisects on it), equal to
        /// the old rule at scale 1, never above what the leaf's distance shows.
        #[test]
        fn axis_texels_grow_with_the_scale(
            per_uv in 0.0f64..5000.0, source in 1u32..64, extent in 0.0f64..4.0,
            s0 in 1e-4f64..1.0, s1 in 1e-4f64..1.0, border in 0u32..20,
        ) {
            let at = |scale: f64| axis_texels(
                per_uv, source, extent,
                &AreaOptions { border, scale, cap_to_source: true, max_side: 1024, cap_floor: true },
            );
            let (lo, hi) = (s0.min(s1), s0.max(s1));
            proptest::prop_assert!(at(lo) <= at(hi), "{} > {}", at(lo), at(hi));
            proptest::prop_assert_eq!(at(1.0), per_uv.min(f64::from(source)) * extent);
            let shown = per_uv.max(f64::from(source)) * lo * extent;
            proptest::prop_assert!(at(lo) <= shown * (1.0 + 1e-12), "{} > {}", at(lo), shown);
        }

        #[test]
        fn area_invariants(
            w in 0.0f64..2000.0, h in 0.0f64..2000.0,
            u0 in -1e5f64..1e5, v0 in -1e5f64..1e5, du in 0.0f64..8.0, dv in 0.0f64..8.0,
            border in 0u32..20, scale in 0.01f64..1.0, cap in proptest::bool::ANY,
        ) {
            let i = AreaInput { w, h, uv_min: [u0, v0], uv_max: [u0 + du, v0 + dv], source: [1024, 256] };
            let o = AreaOptions { border, scale, cap_to_source: cap, max_side: 1 << 16, cap_floor: true };
            let a = required_area(&i, &o).unwrap();
            for (inner, outer, b, per_uv, src, ext) in [
                (a.inner_w, a.outer_w, a.border[0], w, 1024.0, i.uv_max[0] - i.uv_min[0]),
                (a.inner_h, a.outer_h, a.border[1], h, 256.0, i.uv_max[1] - i.uv_min[1]),
            ] {
                proptest::prop_assert!(inner >= 1);
                proptest::prop_assert_eq!(outer % 4, 0);
                let slack = outer - inner - 2 * border;
                proptest::prop_assert!(slack < 4, "{:?}", a);
                proptest::prop_assert!(b >= border && b - border <= slack, "{:?}", a);
                let mut need = if cap { per_uv.min(src) } else { per_uv } * scale * ext;
                // A capped axis of a scaled leaf keeps min(src, 8) texels per UV where shown.
                if cap && per_uv > src && scale < 1.0 {
                    let room = f64::from((o.max_side / 4 * 4) - 2 * border);
                    let floor = (src.min(SCALED_CAP_FLOOR) * ext.min(1.0)).min(per_uv * scale * ext).min(room);
                    need = need.max(floor);
                }
                // No magnification (to 1e-9) and no wasted texel column.
                proptest::prop_assert!(f64::from(inner) >= need * (1.0 - 1e-9), "{} < {}", inner, need);
                proptest::prop_assert!(f64::from(inner) < need.max(1.0) + 1.0, "{} vs {}", inner, need);
            }
        }
    }
}
