//! Leaf-atlas rasterisation (paper §5.2.2–5.2.3), the inner-node 2×2 combine (§5.1) and square
//! resampling of original textures.

use super::ImageOpsError;
use super::linear::LinearImage;
use super::magnify::{magnify_cubic, magnify_replicate};
use super::mip::{MipChain, MipFilter, MipOptions};
use super::sample::{AxisTaps, FootprintPlan, apply_rows, period_shift, tap_row, tap_rows};
use super::srgb::srgb8_to_linear;
use crate::model::AtlasRect;
use crate::scene::{DecodedImage, Wrap};
use glam::DVec2;
use rayon::prelude::*;

/// Destination texels above which [`draw_rect`] fills rows on the rayon pool.
const PAR_TEXELS: usize = 1 << 14;

/// One texture area to rasterise into a leaf atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct RectJob {
    /// Rectangle incl. border, destination texels `[x, y, w, h]`: every texel of it is written.
    pub outer: [u32; 4],
    /// Rectangle that shows exactly `[uv_min, uv_max]` (A_tex), texels `[x, y, w, h]`; its left/top edge
    /// maps to `uv_min`, its right/bottom edge to `uv_max`.
    pub inner: [u32; 4],
    pub uv_min: [f64; 2],
    pub uv_max: [f64; 2],
    /// `[wrap_u, wrap_v]` of the material's sampler.
    pub wrap: [Wrap; 2],
    /// Linear RGBA multiplier on the straight colour (glTF `baseColorFactor`).
    pub factor: [f32; 4],
}

impl RectJob {
    /// The job for a packed [`AtlasRect`] with its material's wrap modes and colour factor.
    pub fn from_atlas_rect(r: &AtlasRect, wrap: [Wrap; 2], factor: [f32; 4]) -> Self {
        Self {
            outer: r.outer,
            inner: r.inner,
            uv_min: r.uv_min,
            uv_max: r.uv_max,
            wrap,
            factor,
        }
    }
}

/// Error unless `[x, y, w, h]` lies inside a `width × height` image (checked arithmetic).
fn check_rect(
    what: &'static str,
    r: [u32; 4],
    width: u32,
    height: u32,
) -> Result<(), ImageOpsError> {
    let [x, y, w, h] = r;
    let fits = x.checked_add(w).is_some_and(|e| e <= width)
        && y.checked_add(h).is_some_and(|e| e <= height);
    if fits {
        Ok(())
    } else {
        Err(ImageOpsError::RectOutside {
            what,
            x,
            y,
            w,
            h,
            width,
            height,
        })
    }
}

/// Rasterise one texture area (paper §5.2.3, with the §5.2.2 border): every destination texel of
/// `r.outer` gets `src` sampled at its centre's UV by [`super::sample_footprint`]'s filter, times
/// `r.factor`. The UV map is the linear map taking `r.inner` exactly onto `[uv_min, uv_max]`, continued
/// beyond it into the border (the paper's "scale A_tex around its centre"), so the border shows the
/// texture as it continues past A_tex under the wrap modes. The footprint is one destination texel:
/// `|uv_max − uv_min| / inner size` per axis. UV ranges are first shifted by whole periods (repeat: 1,
/// mirror: 2) so huge UVs lose no precision. Rows run on rayon for rects of ≥ 16384 texels.
pub fn draw_rect(dst: &mut LinearImage, r: &RectJob, src: &MipChain) -> Result<(), ImageOpsError> {
    dst.check()?;
    let plan = RectPlan::new(dst.width, dst.height, r, src)?;
    let row_len = dst.width as usize;
    let rows = plan.rows();
    let Some(rows_data) = dst.data.get_mut(rows.start * row_len..rows.end * row_len) else {
        return Err(ImageOpsError::TexelCount {
            width: dst.width,
            height: dst.height,
            texels: dst.data.len(),
        });
    };
    if row_len == 0 {
        return Ok(());
    }
    let fill_row = |(ry, row): (usize, &mut [[f32; 4]])| plan.fill_row(rows.start + ry, row);
    if plan.texels() >= PAR_TEXELS {
        rows_data
            .par_chunks_mut(row_len)
            .enumerate()
            .for_each(fill_row);
    } else {
        rows_data.chunks_mut(row_len).enumerate().for_each(fill_row);
    }
    Ok(())
}

/// One rect of [`draw_rect`], planned for a `width × height` destination: its checks passed and its
/// per-column taps computed once. Each destination row depends on its own `y` alone, so rows may be
/// filled in any order and grouping ([`RectPlan::fill_row`]): all at once ([`draw_rect`]) or band by
/// band across a leaf's rects (`super::band::draw_leaf_banded`), the same texels either way.
pub struct RectPlan<'a> {
    /// The source level the footprint reads.
    level: &'a LinearImage,
    /// Per-column taps, `nx` per column of `outer`.
    col_taps: Vec<(u32, f32)>,
    nx: usize,
    /// `r.outer` as `[x, y, w, h]`.
    outer: [usize; 4],
    /// The inner rect's top row, its size, and the UV origin and span of the period-shifted map.
    iy: u32,
    size: DVec2,
    lo: DVec2,
    span: DVec2,
    /// The v axis's footprint, taps per texel and wrap.
    footprint_v: f64,
    taps_v: u32,
    wrap_v: Wrap,
    /// Premultiplied colour factor.
    scale: [f32; 4],
}

impl<'a> RectPlan<'a> {
    /// Checks `r` against a `width × height` destination and `src` (the errors of [`draw_rect`]) and
    /// computes its column taps.
    pub fn new(
        width: u32,
        height: u32,
        r: &RectJob,
        src: &'a MipChain,
    ) -> Result<Self, ImageOpsError> {
        check_rect("outer", r.outer, width, height)?;
        let [ix, iy, iw, ih] = r.inner;
        if iw == 0 || ih == 0 {
            return Err(ImageOpsError::EmptyInner {
                x: ix,
                y: iy,
                w: iw,
                h: ih,
            });
        }
        let (mn, mx) = (r.uv_min, r.uv_max);
        if !(mn.iter().chain(&mx).all(|v| v.is_finite())) {
            return Err(ImageOpsError::NonFiniteUv {
                u0: mn[0],
                v0: mn[1],
                u1: mx[0],
                v1: mx[1],
            });
        }
        if !src
            .levels
            .first()
            .is_some_and(|l| l.width > 0 && l.height > 0)
        {
            return Err(ImageOpsError::EmptySource);
        }
        let shift = [
            period_shift(mn[0], r.wrap[0]),
            period_shift(mn[1], r.wrap[1]),
        ];
        let lo = DVec2::new(mn[0] - shift[0], mn[1] - shift[1]);
        let span = DVec2::new(mx[0] - shift[0], mx[1] - shift[1]) - lo;
        let size = DVec2::new(iw as f64, ih as f64);
        let plan = FootprintPlan::new(src, span.abs() / size);
        let Some(level) = src.levels.get(plan.level) else {
            return Err(ImageOpsError::EmptySource);
        };
        let [ox, oy, ow, oh] = r.outer.map(|v| v as usize);
        // Per-column taps, computed once: the UV of column x depends on x only. Every column has the same
        // number of taps (`2 · plan.taps[0]`), so they are stored flat, `nx` per column.
        let mut col_taps: Vec<(u32, f32)> = Vec::with_capacity(ow * 2 * plan.taps[0] as usize);
        for x in ox..ox + ow {
            let u = lo.x + ((x as f64 + 0.5 - ix as f64) / size.x) * span.x;
            let taps = AxisTaps::new(u, plan.footprint.x, plan.taps[0], level.width, r.wrap[0]);
            col_taps.extend_from_slice(taps.as_slice());
        }
        let nx = col_taps.len() / ow.max(1);
        let f = r.factor;
        Ok(Self {
            level,
            col_taps,
            nx,
            outer: [ox, oy, ow, oh],
            iy,
            size,
            lo,
            span,
            footprint_v: plan.footprint.y,
            taps_v: plan.taps[1],
            wrap_v: r.wrap[1],
            scale: [f[0] * f[3], f[1] * f[3], f[2] * f[3], f[3]],
        })
    }

    /// The destination rows the rect writes.
    pub fn rows(&self) -> std::ops::Range<usize> {
        let [_, oy, _, oh] = self.outer;
        oy..oy + oh
    }

    /// Destination texels the rect writes.
    pub fn texels(&self) -> usize {
        self.outer[2] * self.outer[3]
    }

    /// Fills the rect's texels of destination row `y` (one of [`RectPlan::rows`]) in `row`, the whole
    /// destination row; a `row` shorter than the rect's columns is left as it is.
    pub fn fill_row(&self, y: usize, row: &mut [[f32; 4]]) {
        let [ox, _, ow, _] = self.outer;
        let (lo, span, size) = (self.lo, self.span, self.size);
        let v = lo.y + ((y as f64 + 0.5 - self.iy as f64) / size.y) * span.y;
        let ys = AxisTaps::new(
            v,
            self.footprint_v,
            self.taps_v,
            self.level.height,
            self.wrap_v,
        );
        let Some(seg) = row.get_mut(ox..ox + ow) else {
            return;
        };
        fill_segment(
            seg,
            self.level,
            &self.col_taps,
            self.nx,
            ys.as_slice(),
            self.scale,
        );
    }
}

/// One row segment of [`draw_rect`]: texel `i` is the taps `col_taps[i·nx..(i+1)·nx] × ys` of `level`
/// times `scale`. The rows `ys` selects are sliced once for the segment; the common tap counts run as
/// fixed-size loops ([`apply_rows`] over arrays), chosen once per row.
fn fill_segment(
    seg: &mut [[f32; 4]],
    level: &LinearImage,
    col_taps: &[(u32, f32)],
    nx: usize,
    ys: &[(u32, f32)],
    scale: [f32; 4],
) {
    fn run<const NX: usize, const NY: usize>(
        seg: &mut [[f32; 4]],
        level: &LinearImage,
        col_taps: &[(u32, f32)],
        ys: [(u32, f32); NY],
        scale: [f32; 4],
    ) {
        // The rows are the same for the whole segment: sliced once, not per texel.
        let rows = tap_rows(level, ys);
        for (d, xs) in seg.iter_mut().zip(col_taps.chunks_exact(NX)) {
            if let Ok(xs) = <&[(u32, f32); NX]>::try_from(xs) {
                *d = scaled(apply_rows(&rows, xs), scale);
            }
        }
    }
    match (nx, ys) {
        (2, &[a, b]) => run::<2, 2>(seg, level, col_taps, [a, b], scale),
        (4, &[a, b]) => run::<4, 2>(seg, level, col_taps, [a, b], scale),
        (2, &[a, b, c, d]) => run::<2, 4>(seg, level, col_taps, [a, b, c, d], scale),
        (4, &[a, b, c, d]) => run::<4, 4>(seg, level, col_taps, [a, b, c, d], scale),
        _ => {
            let rows: Vec<(&[[f32; 4]], f32)> =
                ys.iter().map(|&(iy, wy)| tap_row(level, iy, wy)).collect();
            for (d, xs) in seg.iter_mut().zip(col_taps.chunks_exact(nx.max(1))) {
                *d = scaled(apply_rows(&rows, xs), scale);
            }
        }
    }
}

#[inline]
fn scaled(s: [f32; 4], scale: [f32; 4]) -> [f32; 4] {
    [
        s[0] * scale[0],
        s[1] * scale[1],
        s[2] * scale[2],
        s[3] * scale[3],
    ]
}

/// The fill of quadrants without a child: opaque mid-grey, sRGB 128 (linear ≈ 0.2159), so an empty
/// quadrant looks neutral if filtering ever reaches it.
pub fn neutral_fill() -> [f32; 4] {
    let g = srgb8_to_linear(128);
    [g, g, g, 1.0]
}

/// The inner-node atlas of side `size` (paper §5.1): child `q`'s image, already at `size / 2` (its mip
/// level 1), goes to quadrant `q` (bit 0: right half, +x; bit 1: lower half, +y); missing children leave
/// `fill` (opaque trees: [`neutral_fill`]; alpha trees: transparent, so the colour bleed of the RGBA8
/// conversion gives it its visible neighbours' colour and no grey halo reaches coarse mips). Errors if
/// `size` is odd or < 2, or a child is not `size/2 × size/2`.
pub fn combine_quadrants(
    children: [Option<&LinearImage>; 4],
    size: u32,
    fill: [f32; 4],
) -> Result<LinearImage, ImageOpsError> {
    if size < 2 || !size.is_multiple_of(2) {
        return Err(ImageOpsError::QuadrantSize { size });
    }
    let half = size / 2;
    for (q, c) in children.iter().enumerate() {
        if let Some(c) = c {
            if c.width != half || c.height != half {
                return Err(ImageOpsError::ChildSize {
                    quadrant: q,
                    width: c.width,
                    height: c.height,
                    half,
                });
            }
            c.check()?;
        }
    }
    let mut out = LinearImage::new_filled(size, size, fill);
    let (n, h) = (size as usize, half as usize);
    for (q, c) in children.iter().enumerate() {
        let Some(c) = c else { continue };
        let (qx, qy) = ((q & 1) * h, (q >> 1) * h);
        for (y, src_row) in c.data.chunks_exact(h).enumerate() {
            let start = (qy + y) * n + qx;
            if let Some(dst_row) = out.data.get_mut(start..start + h) {
                dst_row.copy_from_slice(src_row);
            }
        }
    }
    Ok(out)
}

/// `img` resampled to `size × size` (a square original texture): [`resample_rect`] of its box-filtered
/// mip chain.
pub fn resample_square(
    img: &DecodedImage,
    size: u32,
    wrap: [Wrap; 2],
) -> Result<LinearImage, ImageOpsError> {
    let chain = MipChain::build_with(
        LinearImage::from_decoded(img)?,
        &MipOptions {
            filter: MipFilter::Box,
            wrap,
        },
    );
    resample_rect(&chain, size, size, wrap)
}

/// The image of `chain` (its linear-light box mip chain, e.g. the one the image cache holds; box weights
/// do not depend on wrap) resampled to `w × h` (an original texture at its stored power-of-two sides).
/// Where sides grow by whole factors (a side of 1 or 2 stored at 4), each texel repeated
/// ([`magnify_replicate`]); where neither side shrinks and a side that is not a power of two grows
/// (rounded up), a Catmull-Rom cubic of level 0 ([`magnify_cubic`]: bilinear here and bilinear again in
/// the renderer blurred it twice);
/// otherwise filtered like [`draw_rect`] with the UV square `[0, 1]²` onto the whole image. Taps beyond the
/// edges follow `wrap`, so a repeat or mirror texture tiles as seamlessly after resampling as before.
pub fn resample_rect(
    chain: &MipChain,
    w: u32,
    h: u32,
    wrap: [Wrap; 2],
) -> Result<LinearImage, ImageOpsError> {
    if w == 0 || h == 0 {
        return Err(ImageOpsError::ZeroSize { size: w.min(h) });
    }
    let grows_npot = |to: u32, from: u32| to > from && !from.is_power_of_two();
    if let Some(base) = chain.levels.first()
        && base.width > 0
        && base.height > 0
        && (w > base.width || h > base.height)
        && w.is_multiple_of(base.width)
        && h.is_multiple_of(base.height)
    {
        return magnify_replicate(base, w, h);
    }
    if let Some(base) = chain.levels.first()
        && w >= base.width
        && h >= base.height
        && (grows_npot(w, base.width) || grows_npot(h, base.height))
    {
        return magnify_cubic(base, w, h, wrap);
    }
    let mut out = LinearImage::new_filled(w, h, [0.0; 4]);
    let job = RectJob {
        outer: [0, 0, w, h],
        inner: [0, 0, w, h],
        uv_min: [0.0; 2],
        uv_max: [1.0; 2],
        wrap,
        factor: [1.0; 4],
    };
    draw_rect(&mut out, &job, chain)?;
    Ok(out)
}
