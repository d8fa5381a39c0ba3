//! Minification-correct sampling of a [`MipChain`] with per-axis wrap modes.
//!
//! Filter: choose the finest mip level at which the footprint spans at most 2 texels along its SHORTER
//! axis (and at most `2 · MAX_ANISOTROPY` along its longer one), then average an `n_x × n_y` grid of
//! bilinear taps spread evenly over the footprint, with `n_a = ceil(footprint in texels along a)`, so taps
//! are at most one texel apart. Isotropic minification thus uses 2×2 bilinear taps on a level where the
//! footprint is 1–2 texels; magnification (footprint ≤ 1 texel) is one plain bilinear tap; an anisotropic
//! footprint (a texture squashed along one axis) keeps the sharp axis sharp and takes up to
//! `2 · MAX_ANISOTROPY` taps along the long axis. Wrap modes are applied per axis to every tap's texel
//! indices; UVs are reduced by their period (1 for repeat, 2 for mirror) in f64 before any scaling.

use super::LinearImage;
use super::mip::MipChain;
use crate::scene::Wrap;
use glam::DVec2;

/// Largest ratio of long to short footprint axis filtered without extra blur along the short axis.
pub const MAX_ANISOTROPY: f64 = 16.0;

/// Most taps along one axis (`2 · MAX_ANISOTROPY`).
const MAX_TAPS: u32 = 32;

/// Texel index `i` (may be negative or ≥ `n`) mapped into `0..n` by `wrap`; 0 for `n == 0`.
#[inline]
pub fn wrap_index(i: i64, n: u32, wrap: Wrap) -> u32 {
    if n == 0 {
        return 0;
    }
    let n = n as i64;
    let r = match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m >= n { 2 * n - 1 - m } else { m }
        }
        Wrap::ClampToEdge => i.clamp(0, n - 1),
    };
    r as u32
}

/// The whole number of periods to subtract from a UV coordinate before scaling: `floor(u)` for repeat,
/// `2 · floor(u / 2)` for mirror, 0 for clamp. `u − period_shift(u)` is exact in f64.
#[inline]
pub(crate) fn period_shift(u: f64, wrap: Wrap) -> f64 {
    if !u.is_finite() {
        return 0.0;
    }
    match wrap {
        Wrap::Repeat => u.floor(),
        Wrap::MirroredRepeat => 2.0 * (u * 0.5).floor(),
        Wrap::ClampToEdge => 0.0,
    }
}

/// How one footprint is filtered: the mip level, the tap grid and the footprint (UV units, ≥ 0).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FootprintPlan {
    pub level: usize,
    /// Bilinear taps along x and y, each in `1..=32`.
    pub taps: [u32; 2],
    pub footprint: DVec2,
}

impl FootprintPlan {
    /// Plan for a footprint of `footprint` UV units per axis (sign ignored; non-finite → coarsest level).
    pub fn new(chain: &MipChain, footprint: DVec2) -> Self {
        let fp = footprint.abs();
        let last = chain.levels.len().saturating_sub(1);
        let texels = |l: &LinearImage| [fp.x * l.width as f64, fp.y * l.height as f64];
        let mut level = last;
        for (i, l) in chain.levels.iter().enumerate() {
            let [fx, fy] = texels(l);
            if fx.min(fy) <= 2.0 && fx.max(fy) <= 2.0 * MAX_ANISOTROPY {
                level = i;
                break;
            }
        }
        let [fx, fy] = chain.levels.get(level).map(texels).unwrap_or([0.0; 2]);
        let n = |f: f64| {
            if f.is_finite() {
                (f.ceil() as u32).clamp(1, MAX_TAPS)
            } else {
                1
            }
        };
        let fp = if fp.is_finite() { fp } else { DVec2::ZERO };
        Self {
            level,
            taps: [n(fx), n(fy)],
            footprint: fp,
        }
    }
}

/// One axis' filter for one sample: `2 · n` (texel index, weight) pairs, weights summing to 1.
pub(crate) struct AxisTaps {
    pub(crate) taps: [(u32, f32); 2 * MAX_TAPS as usize],
    pub(crate) len: usize,
}

impl AxisTaps {
    /// Taps along an axis of `size` texels for centre `u` (UV), footprint `fp` (UV), `n` bilinear taps.
    pub(crate) fn new(u: f64, fp: f64, n: u32, size: u32, wrap: Wrap) -> Self {
        let mut out = Self {
            taps: [(0, 0.0); 2 * MAX_TAPS as usize],
            len: 0,
        };
        let n = n.clamp(1, MAX_TAPS);
        let u = u - period_shift(u, wrap);
        let s = size as f64;
        let w = 1.0 / n as f32;
        for k in 0..n {
            let pos = u + fp * ((k as f64 + 0.5) / n as f64 - 0.5);
            let x = pos * s - 0.5;
            let x0 = x.floor();
            let f = (x - x0) as f32;
            // Saturating float→int conversion; NaN → 0.
            let i0 = x0 as i64;
            out.taps[out.len] = (wrap_index(i0, size, wrap), (1.0 - f) * w);
            out.taps[out.len + 1] = (wrap_index(i0.saturating_add(1), size, wrap), f * w);
            out.len += 2;
        }
        out
    }

    #[inline]
    pub(crate) fn as_slice(&self) -> &[(u32, f32)] {
        &self.taps[..self.len]
    }
}

/// Weighted sum of `img` over the separable tap sets `xs × ys` (texels missing from `data` count as 0).
///
/// Every tap is added, zero weights included: weights and premultiplied texels are ≥ 0 and finite, so
/// adding `0 · t` leaves the sum bit for bit as skipping it would, and the loop has no data-dependent
/// branches.
///
/// The common tap counts (one or two bilinear taps per axis: 2 or 4 pairs) run as fixed-size loops the
/// compiler unrolls ([`apply_fixed`]); they add the same products in the same order, so the sums are the
/// same bits.
#[inline]
pub(crate) fn apply_taps(img: &LinearImage, xs: &[(u32, f32)], ys: &[(u32, f32)]) -> [f32; 4] {
    match (xs, ys) {
        (&[a, b], &[c, d]) => apply_fixed(img, [a, b], [c, d]),
        (&[a, b, e, f], &[c, d]) => apply_fixed(img, [a, b, e, f], [c, d]),
        (&[a, b], &[c, d, g, h]) => apply_fixed(img, [a, b], [c, d, g, h]),
        (&[a, b, e, f], &[c, d, g, h]) => apply_fixed(img, [a, b, e, f], [c, d, g, h]),
        _ => apply_any(img, xs, ys),
    }
}

/// [`apply_taps`] for `NX × NY` taps.
#[inline]
fn apply_fixed<const NX: usize, const NY: usize>(
    img: &LinearImage,
    xs: [(u32, f32); NX],
    ys: [(u32, f32); NY],
) -> [f32; 4] {
    apply_rows(&tap_rows(img, ys), &xs)
}

/// The rows `ys` select (each from its first texel to the end of `img.data`, empty past it) with their
/// weights: what [`apply_rows`] reads, made once for a whole row of destination texels.
#[inline]
pub(crate) fn tap_rows<const NY: usize>(
    img: &LinearImage,
    ys: [(u32, f32); NY],
) -> [(&[[f32; 4]], f32); NY] {
    ys.map(|(iy, wy)| tap_row(img, iy, wy))
}

/// Row `iy` of `img` from its first texel to the end of `img.data` (empty past it), with weight `wy`.
#[inline]
pub(crate) fn tap_row(img: &LinearImage, iy: u32, wy: f32) -> (&[[f32; 4]], f32) {
    let w = img.width as usize;
    (img.data.get(iy as usize * w..).unwrap_or(&[]), wy)
}

/// The weighted sum over `rows × xs`: rows outer, taps inner, each product `(wx · wy) · t` added in that
/// order (texels past a row's slice count as 0).
///
/// Inlined, so fixed-size `rows` and `xs` (arrays) become unrolled loops.
#[inline(always)]
pub(crate) fn apply_rows(rows: &[(&[[f32; 4]], f32)], xs: &[(u32, f32)]) -> [f32; 4] {
    let mut acc = [0.0f32; 4];
    for &(row, wy) in rows {
        for &(ix, wx) in xs {
            let wt = wx * wy;
            if let Some(t) = row.get(ix as usize) {
                for c in 0..4 {
                    acc[c] += wt * t[c];
                }
            }
        }
    }
    acc
}

/// [`apply_taps`] for any number of taps: [`apply_rows`] over the rows `ys` selects.
fn apply_any(img: &LinearImage, xs: &[(u32, f32)], ys: &[(u32, f32)]) -> [f32; 4] {
    // Up to `2 · MAX_TAPS` rows ([`AxisTaps`]) without an allocation per sample.
    let mut rows = [(&[][..], 0.0f32); 2 * MAX_TAPS as usize];
    if let Some(rows) = rows.get_mut(..ys.len()) {
        for (r, &(iy, wy)) in rows.iter_mut().zip(ys) {
            *r = tap_row(img, iy, wy);
        }
        return apply_rows(rows, xs);
    }
    let rows: Vec<_> = ys.iter().map(|&(iy, wy)| tap_row(img, iy, wy)).collect();
    apply_rows(&rows, xs)
}

/// Sample `chain` at `uv` with an already computed plan. Premultiplied linear RGBA; transparent black for
/// an empty chain.
pub fn sample_planned(
    chain: &MipChain,
    plan: &FootprintPlan,
    wrap: [Wrap; 2],
    uv: DVec2,
) -> [f32; 4] {
    let Some(img) = chain.levels.get(plan.level) else {
        return [0.0; 4];
    };
    if img.width == 0 || img.height == 0 {
        return [0.0; 4];
    }
    let xs = AxisTaps::new(uv.x, plan.footprint.x, plan.taps[0], img.width, wrap[0]);
    let ys = AxisTaps::new(uv.y, plan.footprint.y, plan.taps[1], img.height, wrap[1]);
    apply_taps(img, xs.as_slice(), ys.as_slice())
}

/// Sample `chain` at `uv` (UV units, any magnitude) over a footprint of `footprint` UV units per axis
/// (the UV extent of one destination texel), with wrap modes `[wrap_u, wrap_v]`. Returns premultiplied
/// linear RGBA. See the module documentation for the filter.
pub fn sample_footprint(
    chain: &MipChain,
    wrap: [Wrap; 2],
    uv: DVec2,
    footprint: DVec2,
) -> [f32; 4] {
    let plan = FootprintPlan::new(chain, footprint);
    sample_planned(chain, &plan, wrap, uv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_index_modes() {
        let r: Vec<u32> = (-5..9).map(|i| wrap_index(i, 4, Wrap::Repeat)).collect();
        assert_eq!(r, [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]);
        let m: Vec<u32> = (-5..9)
            .map(|i| wrap_index(i, 4, Wrap::MirroredRepeat))
            .collect();
        assert_eq!(m, [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]);
        let c: Vec<u32> = (-2..6)
            .map(|i| wrap_index(i, 4, Wrap::ClampToEdge))
            .collect();
        assert_eq!(c, [0, 0, 0, 1, 2, 3, 3, 3]);
        assert_eq!(wrap_index(i64::MIN, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap_index(7, 0, Wrap::Repeat), 0);
    }

    #[test]
    fn period_shift_is_exact() {
        assert_eq!(1e5 + 0.25 - period_shift(1e5 + 0.25, Wrap::Repeat), 0.25);
        assert_eq!(
            1e5 + 1.25 - period_shift(1e5 + 1.25, Wrap::MirroredRepeat),
            1.25
        );
        assert_eq!(-0.75 - period_shift(-0.75, Wrap::Repeat), 0.25);
        assert_eq!(period_shift(f64::NAN, Wrap::Repeat), 0.0);
    }

    #[test]
    fn fixed_tap_loops_sum_the_same_bits_as_the_general_one() {
        // An 8×8 image of irregular values; random taps (indices in and out of range, random weights) in
        // every shape apply_taps unrolls: apply_taps (fixed loops) and apply_any agree bit for bit.
        let mut rng = crate::util::XorShift64::new(0x9e37_79b9_7f4a_7c15);
        let mut next = move || rng.next_u64();
        let img = LinearImage {
            width: 8,
            height: 8,
            data: (0..64)
                .map(|_| [0, 1, 2, 3].map(|_| (next() % 10_007) as f32 / 997.0))
                .collect(),
        };
        let mut taps = |n: usize| -> Vec<(u32, f32)> {
            (0..n)
                .map(|_| ((next() % 10) as u32, (next() % 1_000) as f32 / 1_013.0))
                .collect()
        };
        let mut compared = 0;
        for (nx, ny) in [(2, 2), (4, 2), (2, 4), (4, 4), (6, 2), (2, 6)] {
            for _ in 0..500 {
                let (xs, ys) = (taps(nx), taps(ny));
                let fixed = apply_taps(&img, &xs, &ys).map(f32::to_bits);
                let any = apply_any(&img, &xs, &ys).map(f32::to_bits);
                assert_eq!(fixed, any, "{nx}×{ny}: {xs:?} × {ys:?}");
                compared += 1;
            }
        }
        assert_eq!(compared, 3_000);
    }

    #[test]
    fn plan_levels_and_taps() {
        let chain = MipChain::build(LinearImage::new_filled(256, 256, [0.0; 4]));
        // Magnification: one bilinear tap at level 0.
        let p = FootprintPlan::new(&chain, DVec2::splat(0.5 / 256.0));
        assert_eq!((p.level, p.taps), (0, [1, 1]));
        // 8 texels → level 2 where it spans 2 texels → 2×2 taps.
        let p = FootprintPlan::new(&chain, DVec2::splat(8.0 / 256.0));
        assert_eq!((p.level, p.taps), (2, [2, 2]));
        // Anisotropic 16:1 → level 0 for the short axis, 16 taps along the long one.
        let p = FootprintPlan::new(&chain, DVec2::new(16.0 / 256.0, 1.0 / 256.0));
        assert_eq!((p.level, p.taps), (0, [16, 1]));
        // Anisotropy 128:1 → coarser level so the long axis is ≤ 32 texels.
        let p = FootprintPlan::new(&chain, DVec2::new(128.0 / 256.0, 1.0 / 256.0));
        assert_eq!((p.level, p.taps), (2, [32, 1]));
        // Whole-image footprint: the 1×1 level.
        let p = FootprintPlan::new(&chain, DVec2::splat(3.0));
        assert_eq!(p.level, chain.levels.len() - 1);
        let p = FootprintPlan::new(&chain, DVec2::splat(f64::NAN));
        assert_eq!((p.level, p.taps), (chain.levels.len() - 1, [1, 1]));
    }
}
