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
mod tests;
