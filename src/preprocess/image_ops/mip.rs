//! Halving and mip chains (paper §5.1: inner atlases are their children combined and down-sampled by 2).
//!
//! Every level is `ceil(w/2) × ceil(h/2)` of the one above (an axis of length 1 stays 1), down to 1×1.
//! Each output texel covers the source interval `[j·s, (j+1)·s)` per axis with `s = src/dst` (2 for even
//! sizes, e.g. 5/3 for 5 → 3). The box filter integrates the source over exactly that footprint, so odd
//! and non-square sizes keep the area-weighted mean exactly. The Kaiser filter is a Kaiser-windowed sinc
//! (β = 4, radius 3 output texels) centred on the same footprint, with the wrap mode applied to taps
//! beyond the edge; its results are clamped to valid premultiplied values.

use super::linear::LinearImage;
use super::sample::wrap_index;
use crate::scene::Wrap;
use rayon::prelude::*;

/// Output texel count above which rows are filtered on the rayon pool.
const PAR_TEXELS: usize = 1 << 14;

/// Kaiser window shape parameter β.
const KAISER_BETA: f64 = 4.0;
/// Kaiser kernel radius in output texels.
const KAISER_RADIUS: f64 = 3.0;

/// The down-sampling kernel of mip generation.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub enum MipFilter {
    /// Box over each output texel's exact footprint (2×2 for even sizes). The default.
    #[default]
    Box,
    /// Kaiser-windowed sinc (β = 4, radius 3 output texels): sharper mips, slight ringing (clamped).
    Kaiser,
}

impl MipFilter {
    pub const ALL: [MipFilter; 2] = [MipFilter::Box, MipFilter::Kaiser];

    /// The lower-case name used on the command line and in sweep grids.
    pub fn name(self) -> &'static str {
        match self {
            MipFilter::Box => "box",
            MipFilter::Kaiser => "kaiser",
        }
    }
}

impl std::str::FromStr for MipFilter {
    type Err = String;
    fn from_str(s: &str) -> Result<MipFilter, String> {
        MipFilter::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| format!("unknown mip filter {s:?} (box, kaiser)"))
    }
}

/// How a mip chain is built.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct MipOptions {
    pub filter: MipFilter,
    /// Per-axis addressing for taps beyond the edge (Kaiser only; the box never leaves the image).
    /// Atlases use clamp; original textures their sampler's modes.
    pub wrap: [Wrap; 2],
}

impl Default for MipOptions {
    fn default() -> Self {
        Self {
            filter: MipFilter::Box,
            wrap: [Wrap::ClampToEdge; 2],
        }
    }
}

/// A full mip chain, level 0 first, each level [`downsample`]d from the previous one down to 1×1.
#[derive(Clone, Debug, PartialEq)]
pub struct MipChain {
    pub levels: Vec<LinearImage>,
}

impl MipChain {
    /// Box-filtered chain of `base` (see [`MipChain::build_with`]).
    pub fn build(base: LinearImage) -> Self {
        Self::build_with(base, &MipOptions::default())
    }

    /// Chain of `base` down to 1×1; a zero-size base gives a one-level chain.
    pub fn build_with(base: LinearImage, opts: &MipOptions) -> Self {
        let mut levels = vec![base];
        while let Some(last) = levels.last() {
            if !has_next_level(last) {
                break;
            }
            let next = downsample(last, opts);
            levels.push(next);
        }
        Self { levels }
    }

    /// All levels as RGBA8 sRGB straight alpha ([`LinearImage::to_rgba8`]), level 0 first, back to back.
    pub fn to_rgba8(&self) -> Vec<u8> {
        let total = self.levels.iter().map(|l| l.texel_count() * 4).sum();
        let mut out = vec![0u8; total];
        let mut rest = &mut out[..];
        for l in &self.levels {
            let (level, tail) = rest.split_at_mut(l.texel_count() * 4);
            l.to_rgba8_into(level);
            rest = tail;
        }
        out
    }
}

/// True if `img` is not yet 1×1 (and not empty).
fn has_next_level(img: &LinearImage) -> bool {
    img.width > 0 && img.height > 0 && (img.width > 1 || img.height > 1)
}

/// Size of the next mip level along one axis: `ceil(n / 2)`, at least 1 (0 stays 0).
#[inline]
fn next_size(n: u32) -> u32 {
    if n == 0 { 0 } else { n.div_ceil(2) }
}

/// Box-filtered next mip level (2×2 box for even sizes, exact footprint weights for odd ones).
pub fn halve(img: &LinearImage) -> LinearImage {
    downsample(img, &MipOptions::default())
}

/// The next mip level of `img` (`ceil(w/2) × ceil(h/2)`) with the filter and wrap modes of `opts`.
/// An image whose data length disagrees with its size reads missing texels as transparent black.
pub fn downsample(img: &LinearImage, opts: &MipOptions) -> LinearImage {
    let (w, h) = (img.width, img.height);
    let (dw, dh) = (next_size(w), next_size(h));
    if opts.filter == MipFilter::Box && w % 2 == 0 && h % 2 == 0 && img.check().is_ok() {
        return halve_even_box(img);
    }
    let tx = axis_weights(w, dw, opts.filter, opts.wrap[0]);
    let ty = axis_weights(h, dh, opts.filter, opts.wrap[1]);
    let mut out = resample_separable(img, dw, dh, &tx, &ty);
    if opts.filter == MipFilter::Kaiser {
        out.data.iter_mut().for_each(clamp_premultiplied);
    }
    out
}

/// Clamp a filtered texel to a valid premultiplied value: `a ∈ [0, 1]`, `rgb ∈ [0, a]`.
fn clamp_premultiplied(t: &mut [f32; 4]) {
    let a = t[3].clamp(0.0, 1.0);
    t[3] = a;
    for c in &mut t[..3] {
        *c = c.clamp(0.0, a);
    }
}

/// 2×2 box for even `width` and `height` with `data.len() == width · height` (checked by the caller).
fn halve_even_box(img: &LinearImage) -> LinearImage {
    let (w, dw, dh) = (img.width as usize, (img.width / 2) as usize, img.height / 2);
    let mut out = LinearImage::new_filled(dw as u32, dh, [0.0; 4]);
    let row = |(y, dst): (usize, &mut [[f32; 4]])| {
        let r0 = &img.data[2 * y * w..(2 * y + 1) * w];
        let r1 = &img.data[(2 * y + 1) * w..(2 * y + 2) * w];
        halve_row_pair(r0, r1, dst);
    };
    if dw == 0 {
        return out;
    }
    if super::split(out.data.len(), PAR_TEXELS) {
        out.data.par_chunks_mut(dw).enumerate().for_each(row);
    } else {
        out.data.chunks_mut(dw).enumerate().for_each(row);
    }
    out
}

/// One row of the 2×2 box: `dst[x]` is the mean of texels `2x` and `2x + 1` of rows `r0` and `r1`
/// (summed as `(a + b) + (c + d)`, the order every halving of an even level uses, so a level halved
/// whole or band by band has the same bits).
pub(super) fn halve_row_pair(r0: &[[f32; 4]], r1: &[[f32; 4]], dst: &mut [[f32; 4]]) {
    for (d, (p0, p1)) in dst
        .iter_mut()
        .zip(r0.chunks_exact(2).zip(r1.chunks_exact(2)))
    {
        let (a, b, c, e) = (p0[0], p0[1], p1[0], p1[1]);
        for k in 0..4 {
            d[k] = 0.25 * ((a[k] + b[k]) + (c[k] + e[k]));
        }
    }
}

/// For each output index along one axis, the (source index, weight) taps; weights sum to 1.
type AxisWeights = Vec<Vec<(u32, f32)>>;

/// Taps of one axis from `src` to `dst` texels.
fn axis_weights(src: u32, dst: u32, filter: MipFilter, wrap: Wrap) -> AxisWeights {
    if src == dst {
        return (0..dst).map(|j| vec![(j, 1.0)]).collect();
    }
    match filter {
        MipFilter::Box => box_weights(src, dst),
        MipFilter::Kaiser => kaiser_weights(src, dst, wrap),
    }
}

/// Exact footprint overlap weights: output `j` covers `[j·s, (j+1)·s)`, `s = src / dst`.
fn box_weights(src: u32, dst: u32) -> AxisWeights {
    let s = src as f64 / dst as f64;
    (0..dst)
        .map(|j| {
            let (lo, hi) = (j as f64 * s, (j as f64 + 1.0) * s);
            let mut taps = Vec::with_capacity(3);
            let mut i = lo.floor() as u32;
            while (i as f64) < hi && i < src {
                let overlap = hi.min(i as f64 + 1.0) - lo.max(i as f64);
                if overlap > 1e-12 {
                    taps.push((i, (overlap / s) as f32));
                }
                i += 1;
            }
            taps
        })
        .collect()
}

/// Modified Bessel function of the first kind, order 0 (power series; converges fast for x ≤ 10).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term, q) = (1.0, 1.0, x * x / 4.0);
    for k in 1..50 {
        term *= q / (k as f64 * k as f64);
        sum += term;
        if term < sum * 1e-16 {
            break;
        }
    }
    sum
}

/// Kaiser-windowed sinc at `x` output texels from the centre.
fn kaiser_kernel(x: f64) -> f64 {
    let t = x / KAISER_RADIUS;
    if t.abs() >= 1.0 {
        return 0.0;
    }
    let sinc = if x.abs() < 1e-9 {
        1.0
    } else {
        let px = std::f64::consts::PI * x;
        px.sin() / px
    };
    sinc * bessel_i0(KAISER_BETA * (1.0 - t * t).sqrt()) / bessel_i0(KAISER_BETA)
}

/// Kaiser taps centred on each output footprint, wrapped by `wrap`, normalised to sum 1.
fn kaiser_weights(src: u32, dst: u32, wrap: Wrap) -> AxisWeights {
    let s = src as f64 / dst as f64;
    (0..dst)
        .map(|j| {
            let c = (j as f64 + 0.5) * s;
            let reach = KAISER_RADIUS * s;
            let (first, last) = ((c - reach - 0.5).floor() as i64, (c + reach).ceil() as i64);
            let mut taps: Vec<(u32, f64)> = Vec::new();
            for i in first..=last {
                let wgt = kaiser_kernel((i as f64 + 0.5 - c) / s);
                if wgt != 0.0 {
                    taps.push((wrap_index(i, src, wrap), wgt));
                }
            }
            let sum: f64 = taps.iter().map(|t| t.1).sum();
            let norm = if sum.abs() > 1e-12 { 1.0 / sum } else { 0.0 };
            taps.into_iter()
                .map(|(i, wgt)| (i, (wgt * norm) as f32))
                .collect()
        })
        .collect()
}

/// Separable resampling: horizontal pass into `dw × h`, then vertical into `dw × dh`.
fn resample_separable(
    img: &LinearImage,
    dw: u32,
    dh: u32,
    tx: &AxisWeights,
    ty: &AxisWeights,
) -> LinearImage {
    let (w, h) = (img.width as usize, img.height as usize);
    let dwu = dw as usize;
    let mut tmp = LinearImage::new_filled(dw, img.height, [0.0; 4]);
    let mut out = LinearImage::new_filled(dw, dh, [0.0; 4]);
    if dwu == 0 || h == 0 {
        return out;
    }
    let hrow = |(y, dst): (usize, &mut [[f32; 4]])| {
        for (d, taps) in dst.iter_mut().zip(tx) {
            *d = weighted_sum(
                taps.iter().map(|&(i, wt)| (y * w + i as usize, wt)),
                &img.data,
            );
        }
    };
    if super::split(tmp.data.len(), PAR_TEXELS) {
        tmp.data.par_chunks_mut(dwu).enumerate().for_each(hrow);
    } else {
        tmp.data.chunks_mut(dwu).enumerate().for_each(hrow);
    }
    let tmp = tmp;
    let vrow = |(y, dst): (usize, &mut [[f32; 4]])| {
        let Some(taps) = ty.get(y) else { return };
        for (x, d) in dst.iter_mut().enumerate() {
            *d = weighted_sum(
                taps.iter().map(|&(i, wt)| (i as usize * dwu + x, wt)),
                &tmp.data,
            );
        }
    };
    if super::split(out.data.len(), PAR_TEXELS) {
        out.data.par_chunks_mut(dwu).enumerate().for_each(vrow);
    } else {
        out.data.chunks_mut(dwu).enumerate().for_each(vrow);
    }
    out
}

/// Σ weight · data[index] over `taps`; indices outside `data` contribute 0.
#[inline]
fn weighted_sum(taps: impl Iterator<Item = (usize, f32)>, data: &[[f32; 4]]) -> [f32; 4] {
    let mut acc = [0.0f32; 4];
    for (i, wt) in taps {
        if let Some(t) = data.get(i) {
            for c in 0..4 {
                acc[c] += wt * t[c];
            }
        }
    }
    acc
}

/// All mip levels of `base` as RGBA8 sRGB straight alpha, level 0 first, box filter. For a square
/// power-of-two base of side `n` the length is `TexFormat::Rgba8.chain_bytes(n)`; other sizes give
/// the same concatenation of their `ceil`-halved levels.
pub fn mip_chain_rgba8(base: &LinearImage) -> Vec<u8> {
    mip_chain_rgba8_with(base, &MipOptions::default())
}

/// [`mip_chain_rgba8`] with a chosen filter; holds at most two levels at a time.
pub fn mip_chain_rgba8_with(base: &LinearImage, opts: &MipOptions) -> Vec<u8> {
    let mut out = base.to_rgba8();
    if !has_next_level(base) {
        return out;
    }
    let mut cur = downsample(base, opts);
    loop {
        out.extend_from_slice(&cur.to_rgba8());
        if !has_next_level(&cur) {
            return out;
        }
        cur = downsample(&cur, opts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: u32, h: u32, seed: u64) -> LinearImage {
        let mut rng = crate::util::XorShift64::new(seed);
        let mut next = || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        let data = (0..w * h).map(|_| [next(), next(), next(), 1.0]).collect();
        LinearImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn box_weights_sum_to_one_and_cover_source() {
        for (src, dst) in [(5, 3), (7, 4), (3, 2), (2, 1), (9, 5)] {
            let wts = box_weights(src, dst);
            let mut per_src = vec![0.0f64; src as usize];
            for taps in &wts {
                let sum: f32 = taps.iter().map(|t| t.1).sum();
                assert!((sum - 1.0).abs() < 1e-6, "{src}→{dst}: {sum}");
                for &(i, wt) in taps {
                    per_src[i as usize] += wt as f64;
                }
            }
            // Every source texel contributes dst/src of one output texel in total.
            for v in per_src {
                assert!(
                    (v - dst as f64 / src as f64).abs() < 1e-6,
                    "{src}→{dst}: {v}"
                );
            }
        }
    }

    #[test]
    fn even_fast_path_equals_general_path() {
        let img = noise(16, 8, 7);
        let fast = halve_even_box(&img);
        let general = resample_separable(&img, 8, 4, &box_weights(16, 8), &box_weights(8, 4));
        for (a, b) in fast.data.iter().zip(&general.data) {
            for c in 0..4 {
                assert!((a[c] - b[c]).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn odd_chain_sizes_and_mean() {
        let img = noise(5, 3, 11);
        let m0 = img.mean();
        let chain = MipChain::build(img);
        let sizes: Vec<(u32, u32)> = chain.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(5, 3), (3, 2), (2, 1), (1, 1)]);
        for l in &chain.levels {
            let m = l.mean();
            for c in 0..4 {
                assert!(
                    (m[c] - m0[c]).abs() < 1e-5,
                    "{}×{}: {m:?} vs {m0:?}",
                    l.width,
                    l.height
                );
            }
        }
    }

    #[test]
    fn non_square_chain_reaches_one_by_one() {
        let chain = MipChain::build(LinearImage::new_filled(16, 2, [0.5, 0.5, 0.5, 1.0]));
        let sizes: Vec<(u32, u32)> = chain.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(16, 2), (8, 1), (4, 1), (2, 1), (1, 1)]);
        assert_eq!(chain.levels[4].data, vec![[0.5, 0.5, 0.5, 1.0]]);
        let empty = MipChain::build(LinearImage::new_filled(0, 4, [0.0; 4]));
        assert_eq!(empty.levels.len(), 1);
    }

    #[test]
    fn kaiser_keeps_constants_and_means() {
        let opts = MipOptions {
            filter: MipFilter::Kaiser,
            wrap: [Wrap::Repeat; 2],
        };
        let flat = LinearImage::new_filled(8, 6, [0.25, 0.5, 0.125, 1.0]);
        let d = downsample(&flat, &opts);
        assert_eq!((d.width, d.height), (4, 3));
        for t in &d.data {
            for (c, want) in [0.25, 0.5, 0.125, 1.0].iter().enumerate() {
                assert!((t[c] - want).abs() < 1e-5);
            }
        }
        // Repeat-wrapped Kaiser on a periodic image preserves the mean closely (each source texel gets
        // the same total weight up to the kernel's discrete normalisation).
        let img = noise(32, 32, 3);
        let (m0, m1) = (img.mean(), downsample(&img, &opts).mean());
        for c in 0..3 {
            assert!((m0[c] - m1[c]).abs() < 0.01 * m0[c], "{m0:?} vs {m1:?}");
        }
    }

    #[test]
    fn kaiser_keeps_passband_amplitude_box_attenuates() {
        // A sinusoid of period 8 source texels (4 after halving), periodic in a 32-wide image under
        // Repeat. Ideal halving samples the same continuous function at the new texel centres.
        let f = |x: f64| 0.5 + 0.4 * (std::f64::consts::TAU * x / 8.0).sin();
        let data = (0..4).flat_map(|_| {
            (0..32).map(|x| {
                let v = f(x as f64 + 0.5) as f32;
                [v, v, v, 1.0]
            })
        });
        let img = LinearImage {
            width: 32,
            height: 4,
            data: data.collect(),
        };
        let err = |d: &LinearImage| {
            (0..16)
                .map(|j| (d.get(j, 0).unwrap()[0] as f64 - f(2.0 * (j as f64 + 0.5))).abs())
                .fold(0.0, f64::max)
        };
        let boxed = err(&halve(&img));
        let kaiser = err(&downsample(
            &img,
            &MipOptions {
                filter: MipFilter::Kaiser,
                wrap: [Wrap::Repeat; 2],
            },
        ));
        // Box: amplitude × cos(π/8) = 0.924; the new centres sit at phases π/4 + kπ/2 (|sin| = √½), so
        // the max error is 0.4 · (1 − cos(π/8)) · √½ = 0.0215.
        let expected =
            0.4 * (1.0 - (std::f64::consts::PI / 8.0).cos()) * std::f64::consts::FRAC_1_SQRT_2;
        assert!((boxed - expected).abs() < 1e-5, "box {boxed}");
        assert!(kaiser < 0.01, "kaiser {kaiser}");
    }

    #[test]
    fn kaiser_ringing_is_clamped() {
        // A hard step: Kaiser overshoots, the clamp keeps values valid premultiplied.
        let mut img = LinearImage::new_filled(32, 2, [0.0, 0.0, 0.0, 1.0]);
        for y in 0..2 {
            for x in 15..32 {
                img.set(x, y, [1.0, 1.0, 1.0, 1.0]).unwrap();
            }
        }
        let k = downsample(
            &img,
            &MipOptions {
                filter: MipFilter::Kaiser,
                wrap: [Wrap::ClampToEdge; 2],
            },
        );
        assert!(
            k.data
                .iter()
                .all(|t| t[3] == 1.0 && (0.0..=1.0).contains(&t[0]))
        );
        // Far from the step it is exactly flat.
        assert_eq!(k.get(0, 0).unwrap()[0], 0.0);
        assert_eq!(k.get(15, 0).unwrap()[0], 1.0);
    }
}
