//! Image and experiment measures (pure CPU).
//!
//! Frames are RGBA8 buffers as the renderer reads them back: rows top to bottom, 4 bytes per pixel,
//! `width × height × 4` bytes, sRGB-encoded values 0–255 (the metrics work on these encoded values, the
//! convention of PSNR and SSIM in the literature). Alpha is ignored everywhere.
//!
//! - [`psnr`]: peak signal-to-noise ratio of the RGB channels in dB, capped at [`PSNR_CAP_DB`].
//! - [`ssim`]: mean structural similarity (Wang, Bovik, Sheikh, Simoncelli 2004) of the BT.601 luma.
//! - [`magnified_share`], [`Histogram`]: the texel-per-pixel density of `render::density` (its `DensityFrame::min_density`).
//! - [`pareto_front`]: the non-dominated (cost, accuracy) points of a sweep.

use super::ReportError;
use rayon::prelude::*;

pub use crate::texfmt::PSNR_CAP_DB;

/// Checks that `buf` holds a `width × height` RGBA8 frame.
fn check_frame(what: &'static str, buf: &[u8], width: u32, height: u32) -> Result<(), ReportError> {
    let expected = width as usize * height as usize * 4;
    if buf.len() == expected {
        Ok(())
    } else {
        Err(ReportError::FrameSize {
            what,
            len: buf.len(),
            width,
            height,
            expected,
        })
    }
}

/// Peak signal-to-noise ratio (dB) of two RGBA8 frames over the R, G and B channels of every pixel:
/// `10 · log10(255² / MSE)`, MSE the mean of the squared 8-bit differences over `3 · width · height`
/// values ([`crate::texfmt::psnr`], the crate's one rule). Identical frames give [`PSNR_CAP_DB`] (99 dB),
/// as does any PSNR above it. An empty frame (0 pixels) counts as identical.
pub fn psnr(a: &[u8], b: &[u8], width: u32, height: u32) -> Result<f64, ReportError> {
    check_frame("psnr: first frame", a, width, height)?;
    check_frame("psnr: second frame", b, width, height)?;
    let sse: u64 = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .map(|(p, q)| {
            (0..3)
                .map(|c| (p[c].abs_diff(q[c]) as u64).pow(2))
                .sum::<u64>()
        })
        .sum();
    Ok(crate::texfmt::psnr(sse, 3 * width as u64 * height as u64))
}

/// The PSNR of several equal-sized frames together (dB): their mean squared errors averaged, then
/// `10 · log10(255² / MSE)` — not the mean of the per-frame dB, in which one identical frame (capped at
/// [`PSNR_CAP_DB`]) among 30–45 dB ones lifted an overview's "mean" to 62 dB. Non-finite values (frames
/// not measured) are skipped; none left gives NaN. The result is at most the cap.
pub fn psnr_over_frames(frames_db: impl IntoIterator<Item = f64>) -> f64 {
    let (mut n, mut mse) = (0usize, 0.0f64);
    for db in frames_db.into_iter().filter(|d| d.is_finite()) {
        n += 1;
        // The frame's MSE / 255².
        mse += 10f64.powf(-db / 10.0);
    }
    if n == 0 {
        return f64::NAN;
    }
    (-10.0 * (mse / n as f64).log10()).min(PSNR_CAP_DB)
}

/// [`psnr`] over the pixels where `mask` is true (row-major, one entry per pixel); also returns how many
/// pixels that was. No masked pixel gives NaN and 0: nothing was measured, which
/// [`psnr_over_frames`] leaves out (the cap, as a perfect frame, lifted a sweep's covered PSNR by 3 dB
/// where one frame of two looked at the sky; fault hunt, session 38).
pub fn psnr_masked(
    a: &[u8],
    b: &[u8],
    width: u32,
    height: u32,
    mask: &[bool],
) -> Result<(f64, usize), ReportError> {
    check_frame("psnr_masked: first frame", a, width, height)?;
    check_frame("psnr_masked: second frame", b, width, height)?;
    let pixels = width as usize * height as usize;
    if mask.len() != pixels {
        return Err(ReportError::Length {
            what: "psnr_masked: mask",
            len: mask.len(),
            expected: pixels,
        });
    }
    let (mut sse, mut count) = (0u64, 0usize);
    for ((p, q), _) in a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .zip(mask)
        .filter(|(_, m)| **m)
    {
        sse += (0..3)
            .map(|c| (p[c].abs_diff(q[c]) as u64).pow(2))
            .sum::<u64>();
        count += 1;
    }
    if count == 0 {
        return Ok((f64::NAN, 0));
    }
    Ok((crate::texfmt::psnr(sse, 3 * count as u64), count))
}

/// Side of the SSIM window (pixels).
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the SSIM Gaussian window (pixels).
pub const SSIM_SIGMA: f64 = 1.5;
/// SSIM stabilisers: `C1 = (K1 · L)²`, `C2 = (K2 · L)²` with `L = 255`.
pub const SSIM_K1: f64 = 0.01;
pub const SSIM_K2: f64 = 0.03;
const SSIM_L: f64 = 255.0;

/// The normalised 1-D Gaussian of the SSIM window (sums to 1); the 2-D window is its outer product,
/// equal to MATLAB's `fspecial('gaussian', 11, 1.5)`.
pub fn ssim_kernel() -> [f64; SSIM_WINDOW] {
    let half = (SSIM_WINDOW / 2) as f64;
    let mut g = [0.0; SSIM_WINDOW];
    for (i, v) in g.iter_mut().enumerate() {
        let d = i as f64 - half;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let sum: f64 = g.iter().sum();
    g.iter_mut().for_each(|v| *v /= sum);
    g
}

/// BT.601 luma `Y' = 0.299 R' + 0.587 G' + 0.114 B'` of the sRGB-encoded values (0–255), one per pixel.
pub fn luma_bt601(rgba: &[u8]) -> Vec<f64> {
    rgba.chunks_exact(4)
        .map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64)
        .collect()
}

/// The SSIM of one window from its Gaussian-weighted moments: at most 1 (exactly so by Cauchy–Schwarz;
/// the moments' rounding gave identical windows 1 + 2·10⁻¹⁵, and frames above 1; report hunt, session
/// 34).
#[inline]
pub fn ssim_from_moments(mx: f64, my: f64, sxx: f64, syy: f64, sxy: f64) -> f64 {
    let s = ssim_unclamped(mx, my, sxx, syy, sxy);
    // `min` would read a NaN as a perfect 1; 8-bit frames' moments never give one.
    debug_assert!(!s.is_nan(), "SSIM of a window is NaN");
    s.min(1.0)
}

/// [`ssim_from_moments`] before it is clamped to 1: rounding can put it a hair above.
fn ssim_unclamped(mx: f64, my: f64, sxx: f64, syy: f64, sxy: f64) -> f64 {
    let c1 = (SSIM_K1 * SSIM_L).powi(2);
    let c2 = (SSIM_K2 * SSIM_L).powi(2);
    let (vx, vy, cxy) = (sxx - mx * mx, syy - my * my, sxy - mx * my);
    ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
}

/// Mean SSIM (Wang et al. 2004, eq. 13 with the paper's parameters) of two RGBA8 frames, on the BT.601
/// luma of the sRGB-encoded values ([`luma_bt601`], dynamic range L = 255): Gaussian window 11 × 11,
/// σ = 1.5 ([`ssim_kernel`]), K1 = 0.01, K2 = 0.03, averaged over every window that lies entirely inside
/// the frame ("valid" filtering, `(width − 10) × (height − 10)` windows, no padding and no automatic
/// downsampling). 1 for identical frames; symmetric in `a` and `b`.
///
/// The Gaussian moments are computed separably in f64 (rows, then columns, parallel over rows) and
/// summed in a fixed order, so the result does not depend on the thread count.
pub fn ssim(a: &[u8], b: &[u8], width: u32, height: u32) -> Result<f64, ReportError> {
    check_frame("ssim: first frame", a, width, height)?;
    check_frame("ssim: second frame", b, width, height)?;
    if !ssim_fits(width, height) {
        return Err(ReportError::FrameTooSmall {
            width,
            height,
            window: SSIM_WINDOW as u32,
        });
    }
    // Each window's at most 1; their mean's rounding is held there too.
    Ok(ssim_luma(
        &luma_bt601(a),
        &luma_bt601(b),
        width as usize,
        height as usize,
    )
    .min(1.0))
}

/// Whether frames of `width × height` hold one [`SSIM_WINDOW`]-wide window: what [`ssim`] needs, checked
/// up front by `sweep` and `render --reference`.
pub fn ssim_fits(width: u32, height: u32) -> bool {
    width as usize >= SSIM_WINDOW && height as usize >= SSIM_WINDOW
}

/// Mean SSIM of two luma planes (`w × h`, both ≥ [`SSIM_WINDOW`]); see [`ssim`].
fn ssim_luma(x: &[f64], y: &[f64], w: usize, h: usize) -> f64 {
    let g = ssim_kernel();
    let (ow, oh) = (w + 1 - SSIM_WINDOW, h + 1 - SSIM_WINDOW);
    // Horizontal pass: per source row and valid column, the weighted sums of x, y, x², y², xy.
    let mut rows = vec![[0.0f64; 5]; h * ow];
    rows.par_chunks_mut(ow).enumerate().for_each(|(r, out)| {
        let (xr, yr) = (&x[r * w..(r + 1) * w], &y[r * w..(r + 1) * w]);
        for (c, o) in out.iter_mut().enumerate() {
            let mut s = [0.0f64; 5];
            for (k, gk) in g.iter().enumerate() {
                let (p, q) = (xr[c + k], yr[c + k]);
                s[0] += gk * p;
                s[1] += gk * q;
                s[2] += gk * p * p;
                s[3] += gk * q * q;
                s[4] += gk * (p * q);
            }
            *o = s;
        }
    });
    // Vertical pass per output row, then the SSIM of each window; row sums added in order.
    let row_sums: Vec<f64> = (0..oh)
        .into_par_iter()
        .map(|r| {
            let mut acc = vec![[0.0f64; 5]; ow];
            for (k, gk) in g.iter().enumerate() {
                let src = &rows[(r + k) * ow..(r + k + 1) * ow];
                for (a, s) in acc.iter_mut().zip(src) {
                    for i in 0..5 {
                        a[i] += gk * s[i];
                    }
                }
            }
            acc.iter()
                .map(|m| ssim_from_moments(m[0], m[1], m[2], m[3], m[4]))
                .sum::<f64>()
        })
        .collect();
    row_sums.iter().sum::<f64>() / (ow * oh) as f64
}

/// Counts of drawn pixels and of those among them below a threshold.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub struct Share {
    /// Pixels that satisfy the condition.
    pub hit: u64,
    /// Drawn pixels (finite, non-negative density).
    pub drawn: u64,
}

impl Share {
    /// `hit / drawn`, 0 when nothing was drawn.
    pub fn fraction(&self) -> f64 {
        if self.drawn == 0 {
            0.0
        } else {
            self.hit as f64 / self.drawn as f64
        }
    }
}

/// Among the drawn pixels of a density buffer (texels per pixel, one value per pixel; NaN or negative =
/// not drawn, e.g. from `render::density::DensityFrame::min_density`), how many receive strictly fewer than `target` texels per pixel,
/// i.e. are magnified beyond the target texel ratio (§3.3: an atlas chosen by the selection promises at
/// least `texel_ratio` texels per pixel). Use [`Share::fraction`] for the screen share.
///
/// The density comes from screen-space derivatives and carries small errors; callers comparing against
/// the selection's promise may pass `target · (1 − ε)`.
pub fn magnified_share(density: &[f32], target: f64) -> Share {
    let mut s = Share::default();
    for &d in density {
        if d.is_nan() || d < 0.0 {
            continue;
        }
        s.drawn += 1;
        if (d as f64) < target {
            s.hit += 1;
        }
    }
    s
}

/// Pixel counts in log2 bins of texels per pixel.
///
/// Bin `i` holds the values `v` with `edges[i] ≤ v < edges[i + 1]`, `edges[i] = 2^(min_exp + i)`
/// (so bin `i` is `⌊log2 v⌋ = min_exp + i`, the binning of [`crate::render::density::log2_histogram`]);
/// `below` counts drawn values under `edges[0]` (zero included), `above` those at or over the last edge.
/// Fixed edges make histograms of different runs comparable bin for bin.
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    /// Bin edges in texels per pixel, ascending powers of two; `counts.len() + 1` of them.
    pub edges: Vec<f64>,
    pub counts: Vec<u64>,
    /// Drawn values below `edges[0]`.
    pub below: u64,
    /// Drawn values ≥ the last edge (including +∞).
    pub above: u64,
    /// Values left out: NaN or negative (not drawn).
    pub skipped: u64,
}

impl Histogram {
    /// Bins `values` (texels per pixel; NaN or negative = not drawn) into the bins `2^min_exp …
    /// 2^max_exp`. `max_exp ≤ min_exp` gives no bins (everything drawn lands in `below` or `above`).
    pub fn log2(values: &[f32], min_exp: i32, max_exp: i32) -> Histogram {
        let bins = (max_exp - min_exp).max(0) as usize;
        let edges = (0..=bins).map(|i| 2f64.powi(min_exp + i as i32)).collect();
        let mut h = Histogram {
            edges,
            counts: vec![0; bins],
            below: 0,
            above: 0,
            skipped: 0,
        };
        for &v in values {
            if v.is_nan() || v < 0.0 {
                h.skipped += 1;
            } else if v == 0.0 {
                h.below += 1;
            } else {
                let e = (v as f64).log2().floor();
                if e < min_exp as f64 {
                    h.below += 1;
                } else if e >= max_exp as f64 || bins == 0 {
                    h.above += 1;
                } else {
                    h.counts[(e as i64 - min_exp as i64) as usize] += 1;
                }
            }
        }
        h
    }

    /// Drawn values counted (bins, below and above).
    pub fn total(&self) -> u64 {
        self.below + self.above + self.counts.iter().sum::<u64>()
    }

    /// The bars of a plot: `below`, the bins, `above`, with labels `<2⁻³`, `2⁻³`, …, `≥2³` (a bin is
    /// labelled by its lower edge) and values as fractions of [`Histogram::total`] (0 when empty).
    pub fn bars(&self) -> (Vec<String>, Vec<f64>) {
        let total = self.total().max(1) as f64;
        let exp = |e: f64| superscript(e.log2().round() as i32);
        let mut labels = Vec::with_capacity(self.counts.len() + 2);
        let mut values = Vec::with_capacity(self.counts.len() + 2);
        if let Some(first) = self.edges.first() {
            labels.push(format!("<2{}", exp(*first)));
            values.push(self.below as f64 / total);
        }
        for (edge, c) in self.edges.iter().zip(&self.counts) {
            labels.push(format!("2{}", exp(*edge)));
            values.push(*c as f64 / total);
        }
        if let Some(last) = self.edges.last() {
            labels.push(format!("≥2{}", exp(*last)));
            values.push(self.above as f64 / total);
        }
        (labels, values)
    }
}

/// `n` in superscript digits (`-3` → `⁻³`).
pub fn superscript(n: i32) -> String {
    const DIGITS: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::new();
    if n < 0 {
        s.push('⁻');
    }
    for c in n.unsigned_abs().to_string().bytes() {
        s.push(DIGITS[(c - b'0') as usize]);
    }
    s
}

/// Indices of the Pareto-optimal points of `(cost, accuracy)` pairs: lower cost and higher accuracy are
/// better, and a point is dropped when another is at least as good in both and better in one. Equal
/// points are kept together. Points with a NaN coordinate are never on the front. The indices are
/// sorted by ascending cost (then input order), i.e. along the front from cheap to accurate.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| !points[i].0.is_nan() && !points[i].1.is_nan())
        .collect();
    order.sort_by(|&i, &j| {
        let (a, b) = (points[i], points[j]);
        a.0.total_cmp(&b.0)
            .then(b.1.total_cmp(&a.1))
            .then(i.cmp(&j))
    });
    let mut front = Vec::new();
    // Best accuracy among points of strictly lower cost.
    let mut best_cheaper = f64::NEG_INFINITY;
    let mut g = 0;
    while g < order.len() {
        let cost = points[order[g]].0;
        let end = g + order[g..].partition_point(|&i| points[i].0 == cost);
        // Sorted by descending accuracy within a cost: the group's best comes first.
        let top = points[order[g]].1;
        if top > best_cheaper {
            front.extend(order[g..end].iter().filter(|&&i| points[i].1 == top));
        }
        best_cheaper = best_cheaper.max(top);
        g = end;
    }
    front
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames together: their MSEs averaged, so an identical frame (99 dB) among 30 dB ones adds
    /// 10·log10(2) dB, not 34.5; the same as the PSNR of the frames stacked into one image.
    #[test]
    fn psnr_over_frames_averages_the_squared_errors() {
        assert!((psnr_over_frames([30.0, 30.0]) - 30.0).abs() < 1e-9);
        let with_identical = psnr_over_frames([30.0, PSNR_CAP_DB]);
        assert!(
            (with_identical - (30.0 + 10.0 * 2f64.log10())).abs() < 1e-6,
            "{with_identical}"
        );
        assert_eq!(psnr_over_frames([PSNR_CAP_DB; 3]), PSNR_CAP_DB);
        assert_eq!(psnr_over_frames([f64::NAN, 40.0]), 40.0);
        assert!(psnr_over_frames([]).is_nan());
        let frame = |v: u8| [v, v, v, 255].repeat(16);
        let (a, b, c) = (frame(10), frame(13), frame(90));
        let one = psnr(&a, &b, 4, 4).unwrap();
        let two = psnr(&a, &c, 4, 4).unwrap();
        let stacked = psnr(&[a.clone(), a].concat(), &[b, c].concat(), 4, 8).unwrap();
        assert!((psnr_over_frames([one, two]) - stacked).abs() < 1e-9);
    }

    #[test]
    fn superscripts() {
        assert_eq!(superscript(-3), "⁻³");
        assert_eq!(superscript(10), "¹⁰");
        assert_eq!(superscript(0), "⁰");
    }

    /// Moments whose rounding puts the covariance a hair above the variances (what nearly identical
    /// frames give) measure 1, not 1 + 10⁻¹⁵ (report hunt, session 34).
    #[test]
    fn ssim_never_passes_one() {
        let (m, sxx) = (100.1, 100.1 * 100.1 + 5.0);
        let sxy = sxx * (1.0 + 4.0 * f64::EPSILON);
        let unclamped = ssim_unclamped(m, m, sxx, sxx, sxy);
        assert!(unclamped > 1.0, "the case shows the rounding: {unclamped}");
        assert_eq!(ssim_from_moments(m, m, sxx, sxx, sxy), 1.0);
    }

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        let g = ssim_kernel();
        assert!((g.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for i in 0..SSIM_WINDOW {
            assert_eq!(g[i], g[SSIM_WINDOW - 1 - i]);
        }
    }
}
