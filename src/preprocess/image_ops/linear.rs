//! [`LinearImage`]: the working format of every filter, linear RGB premultiplied by linear alpha.

use super::ImageOpsError;
use super::srgb::{Encoder, srgb8_to_linear_table, unit8_table};
use crate::scene::DecodedImage;
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Texel count above which per-texel passes run on the rayon pool.
const PAR_TEXELS: usize = 1 << 16;

/// An image in linear light: `data[y · width + x] = [r·a, g·a, b·a, a]` with `r, g, b, a` linear in
/// `[0, 1]` (colour PREMULTIPLIED by alpha), rows top first.
///
/// The fields are public; an image whose `data.len()` disagrees with `width · height` is never indexed
/// out of bounds: missing texels read as transparent black (see [`LinearImage::check`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<[f32; 4]>,
}

impl LinearImage {
    /// A `width × height` image with every texel `value` (premultiplied linear RGBA).
    pub fn new_filled(width: u32, height: u32, value: [f32; 4]) -> Self {
        let n = (width as usize).saturating_mul(height as usize);
        Self {
            width,
            height,
            data: vec![value; n],
        }
    }

    /// `width · height` as usize.
    #[inline]
    pub fn texel_count(&self) -> usize {
        (self.width as usize).saturating_mul(self.height as usize)
    }

    /// Error unless `data.len() == width · height`.
    pub fn check(&self) -> Result<(), ImageOpsError> {
        if self.data.len() == self.texel_count() {
            Ok(())
        } else {
            Err(ImageOpsError::TexelCount {
                width: self.width,
                height: self.height,
                texels: self.data.len(),
            })
        }
    }

    /// Decode sRGB8 straight alpha into linear premultiplied. Errors if the pixel count is not
    /// `width · height`.
    pub fn from_decoded(img: &DecodedImage) -> Result<Self, ImageOpsError> {
        let n = (img.width as usize).checked_mul(img.height as usize);
        if n != Some(img.pixels.len()) {
            return Err(ImageOpsError::PixelCount {
                width: img.width,
                height: img.height,
                pixels: img.pixels.len(),
            });
        }
        // At least this many texels per task: a rayon `map` split down to single texels ran at ~10 ns a
        // texel, mostly the call per element.
        const RUN: usize = 4096;
        let lut = srgb8_to_linear_table();
        let unit = unit8_table();
        let enc = Encoder::get();
        // Written straight into the vector's spare capacity, run by run (zeroing 16 bytes a texel first
        // cost as much as the decode): with AVX2 a gather per texel pair
        // ([`Encoder::decode_run_simd`]), else the per-texel rule.
        let n = img.pixels.len();
        let mut data: Vec<[f32; 4]> = Vec::with_capacity(n);
        let run = |(out, pixels): (&mut [MaybeUninit<[f32; 4]>], &[[u8; 4]])| {
            if !enc.decode_run_simd(pixels, out) {
                for (o, &p) in out.iter_mut().zip(pixels) {
                    o.write(decode_texel(lut, unit, p));
                }
            }
        };
        let spare = &mut data.spare_capacity_mut()[..n];
        if super::split(n, PAR_TEXELS) {
            spare
                .par_chunks_mut(RUN)
                .zip(img.pixels.par_chunks(RUN))
                .for_each(run);
        } else {
            run((spare, &img.pixels));
        }
        // SAFETY: the capacity is at least `n`, and every element of `0..n` was written above: the runs
        // cover `0..n` (chunks of `spare[..n]` zipped with chunks of the `n` pixels, same sizes), and
        // both paths of `run` write every element of their run (`decode_run_simd` all of them when it
        // returns true, the loop otherwise).
        #[allow(
            unsafe_code,
            reason = "decoded texels written into spare capacity, then the length set"
        )]
        unsafe {
            data.set_len(n);
        }
        Ok(Self {
            width: img.width,
            height: img.height,
            data,
        })
    }

    /// The texel at `(x, y)`, `None` outside the image.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Option<[f32; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.data
            .get(y as usize * self.width as usize + x as usize)
            .copied()
    }

    /// Set the texel at `(x, y)`; errors outside the image.
    pub fn set(&mut self, x: u32, y: u32, value: [f32; 4]) -> Result<(), ImageOpsError> {
        let oob = ImageOpsError::OutOfBounds {
            x,
            y,
            width: self.width,
            height: self.height,
        };
        if x >= self.width || y >= self.height {
            return Err(oob);
        }
        let i = y as usize * self.width as usize + x as usize;
        let t = self.data.get_mut(i).ok_or(oob)?;
        *t = value;
        Ok(())
    }

    /// Mean of every channel over all texels (premultiplied values), in f64.
    pub fn mean(&self) -> [f64; 4] {
        let mut s = [0.0f64; 4];
        for t in &self.data {
            for c in 0..4 {
                s[c] += t[c] as f64;
            }
        }
        let n = self.data.len().max(1) as f64;
        s.map(|v| v / n)
    }

    /// Encode as RGBA8 bytes: sRGB colour, straight (un-premultiplied) alpha, rows top first,
    /// `4 · width · height` bytes.
    ///
    /// Texels whose 8-bit alpha is 0 carry no colour of their own; they get the colour of a nearest
    /// (4-connected breadth-first) texel with alpha > 0 ("colour bleeding"), so GPU bilinear filtering of
    /// the stored straight-alpha texture does not pull black into alpha-tested edges. A fully transparent
    /// image stays transparent black.
    pub fn to_rgba8(&self) -> Vec<u8> {
        let mut out = vec![0u8; self.texel_count().saturating_mul(4)];
        self.to_rgba8_into(&mut out);
        out
    }

    /// [`LinearImage::to_rgba8`] into `out`, which the caller sized to `4 · width · height` bytes (zeroed:
    /// texels beyond a short `data` stay 0); a chain encodes its levels into one buffer this way, without
    /// a buffer and a copy per level. Returns whether a texel was transparent (8-bit alpha 0), so colour
    /// was bled into it from its neighbours: without, every texel's bytes are its own encoding alone. An
    /// `out` of another length is left as it is (and `true` returned: nothing is known of it).
    pub fn to_rgba8_into(&self, out: &mut [u8]) -> bool {
        // Runs of texels per task: the per-texel work is a few table lookups, too little for a task each.
        const RUN: usize = 4096;
        let n = self.texel_count();
        if out.len() != n.saturating_mul(4) {
            return true;
        }
        let enc = Encoder::get();
        // Each run also says whether it wrote a transparent texel (no second pass over the bytes).
        let run = |(px, texels): (&mut [u8], &[[f32; 4]])| encode_texels(enc, texels, px);
        let data = &self.data[..n.min(self.data.len())];
        let transparent = if n >= PAR_TEXELS {
            out.par_chunks_mut(RUN * 4)
                .zip(data.par_chunks(RUN))
                .map(run)
                .reduce(|| false, |a, b| a | b)
        } else {
            run((&mut *out, data))
        };
        // Texels beyond `data` (a short buffer) stay 0 and count as transparent, as before.
        let bled = transparent || data.len() < n;
        if bled {
            bleed_into_transparent(out, self.width as usize, self.height as usize);
        }
        bled
    }
}

/// `texels` encoded into `px` (4 bytes each, as far as both reach) as [`LinearImage::to_rgba8_into`]
/// encodes them, before any colour bleed: each texel's bytes are its own. Returns whether one was
/// transparent (8-bit alpha 0).
pub(super) fn encode_texels(enc: Encoder, texels: &[[f32; 4]], px: &mut [u8]) -> bool {
    if let Some(transparent) = enc.encode_run_simd(texels, px) {
        return transparent;
    }
    let mut transparent = false;
    for (p, &t) in px.chunks_exact_mut(4).zip(texels) {
        let e = encode_texel(enc, t);
        transparent |= e[3] == 0;
        p.copy_from_slice(&e);
    }
    transparent
}

/// sRGB8 straight → linear premultiplied, with `lut` = [`srgb8_to_linear_table`] and `unit` =
/// [`unit8_table`] (alpha / 255 looked up: a division per texel was most of this function's time).
#[inline]
pub(super) fn decode_texel(lut: &[f32; 256], unit: &[f32; 256], p: [u8; 4]) -> [f32; 4] {
    let a = unit[p[3] as usize];
    [
        lut[p[0] as usize] * a,
        lut[p[1] as usize] * a,
        lut[p[2] as usize] * a,
        a,
    ]
}

/// Linear premultiplied → sRGB8 straight; alpha is clamped to `[0, 1]`, 8-bit alpha 0 → `[0, 0, 0, 0]`.
#[inline]
pub(super) fn encode_texel(enc: Encoder, t: [f32; 4]) -> [u8; 4] {
    // Opaque: a = 1, a8 = 255 and colour × (1 / 1) is the colour itself (the general path's exact result).
    if t[3] >= 1.0 {
        return [enc.encode(t[0]), enc.encode(t[1]), enc.encode(t[2]), 255];
    }
    let a = if t[3] > 0.0 { t[3] } else { 0.0 };
    let a8 = round_unit255(a);
    if a8 == 0 {
        return [0; 4];
    }
    let inv = 1.0 / a;
    [
        enc.encode(t[0] * inv),
        enc.encode(t[1] * inv),
        enc.encode(t[2] * inv),
        a8,
    ]
}

/// `(a * 255.0).round() as u8` for `a` in `[0, 1)`, without `f32::round` (a libm call on the baseline
/// x86-64 target, which has no rounding instruction): `a · 255 < 255 < 2²³`, so truncation by the cast
/// and the fraction `x − trunc(x)` are exact, and a fraction ≥ ½ rounds up as `round` does (half away
/// from zero). The same bytes on every `a` in `[0, 1)` (unit test: every f32 there).
#[inline]
fn round_unit255(a: f32) -> u8 {
    let x = a * 255.0;
    let whole = x as u32;
    let up = u32::from(x - whole as f32 >= 0.5);
    (whole + up) as u8
}

/// Give every alpha-0 texel of `rgba` the colour of a nearest texel with alpha > 0 (breadth-first over
/// 4-neighbours from all such texels, in index order); alpha stays 0. O(texels).
///
/// What that search gives: the colour of the visible texel nearest in city-block distance, the lowest
/// index among equally near ones. (On a grid with nothing in the way a texel's layer is its city-block
/// distance to the nearest visible texel. A layer of the FIFO search is grouped by the visible texel its
/// texels descend from, in that texel's index order, and every texel of a group has its colour, so the
/// order within a group and the order of the neighbours do not matter; a texel at distance `d` is
/// claimed by the first group with a neighbour at `d − 1`, the lowest root. The roots a texel can reach
/// down such neighbours are exactly its nearest visible texels: a monotone path to one has every texel
/// at its distance from it. Unit tests against the queue and against this rule by brute force.)
///
/// So it is a nearest-feature transform: `(distance, index)` per texel as one `u64`, minimised along
/// the rows and then along the columns (city-block distance is separable: the nearest texel of each
/// row, then the nearest of those rows' results `|dy|` further; adding one distance to a whole row keeps
/// its order, ties included). Sequential over memory, where the search's layers visited texels in a
/// scattered order and waited on them (it was ~10 % of an alpha-heavy build).
pub(super) fn bleed_into_transparent(rgba: &mut [u8], w: usize, h: usize) {
    let n = w.saturating_mul(h);
    if rgba.len() < n * 4 || n == 0 {
        return;
    }
    // Index in the low 32 bits, distance above (at most w + h, kept below `FAR`); beyond that, the queue.
    if u32::try_from(n).is_err() || w + h >= 1 << 29 {
        bleed_by_queue(rgba, w, h);
        return;
    }
    BLEED_SCRATCH.with(|scratch| {
        let mut best = scratch.take();
        best.clear();
        best.extend(
            rgba.chunks_exact(4)
                .take(n)
                .enumerate()
                .map(|(i, px)| if px[3] != 0 { i as u64 } else { FAR }),
        );
        nearest_visible(&mut best, w, h);
        for (px, &root) in (0..n).zip(&best) {
            // FAR: no visible texel at all, nothing to bleed from.
            if rgba[px * 4 + 3] == 0 && root < FAR {
                let r = (root as u32) as usize * 4;
                let colour = [rgba[r], rgba[r + 1], rgba[r + 2]];
                rgba[px * 4..px * 4 + 3].copy_from_slice(&colour);
            }
        }
        // Kept for the next level on this thread (its pages already mapped), up to an atlas's size.
        if best.capacity() <= BLEED_SCRATCH_KEPT {
            scratch.set(best);
        }
    });
}

thread_local! {
    /// [`bleed_into_transparent`]'s per-texel state (8 bytes a texel, half a linear level's), reused
    /// across calls on a thread.
    static BLEED_SCRATCH: std::cell::Cell<Vec<u64>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Texels of [`BLEED_SCRATCH`] kept between calls (16 MiB: a 2048² level needs 32 MiB and is let go).
const BLEED_SCRATCH_KEPT: usize = 1 << 21;

/// Each texel's `(distance, index)` of its nearest visible texel ([`STEP`] · distance + index), from
/// `best` holding `index` at visible texels and [`FAR`] elsewhere.
fn nearest_visible(best: &mut [u64], w: usize, h: usize) {
    // Separable: along each row (rows side by side, so their chains overlap), then down and up the
    // columns (a whole row at a time, independent per texel).
    let mut rows = best.chunks_exact_mut(w * ROWS);
    for block in &mut rows {
        scan_rows::<ROWS>(block, w);
    }
    for row in rows.into_remainder().chunks_exact_mut(w) {
        scan_rows::<1>(row, w);
    }
    for y in 1..h {
        let (above, row) = best.split_at_mut(y * w);
        for (b, &a) in row[..w].iter_mut().zip(&above[(y - 1) * w..]) {
            *b = (*b).min(a + STEP);
        }
    }
    for y in (0..h.saturating_sub(1)).rev() {
        let (row, below) = best.split_at_mut((y + 1) * w);
        for (b, &a) in row[y * w..].iter_mut().zip(&below[..w]) {
            *b = (*b).min(a + STEP);
        }
    }
}

/// `(distance, index)` of the nearest visible texel: distance in the high 32 bits (at most w + h, so a
/// step adds `STEP`), index in the low ones; `FAR` where none is known.
const STEP: u64 = 1 << 32;
const FAR: u64 = 1 << 62;
/// Rows [`scan_rows`] takes side by side.
const ROWS: usize = 4;

/// The nearest visible texel of each texel of `R` rows of `w` texels along its own row: a pass right
/// and a pass left, the rows interleaved so the `R` dependency chains run side by side.
fn scan_rows<const R: usize>(block: &mut [u64], w: usize) {
    // Each row's running nearest is carried in a register, not read back from the texel just stored.
    let mut run = [FAR; R];
    for x in 0..w {
        for (r, run) in run.iter_mut().enumerate() {
            let b = &mut block[r * w + x];
            *run = (*b).min(*run + STEP);
            *b = *run;
        }
    }
    let mut run = [FAR; R];
    for x in (0..w).rev() {
        for (r, run) in run.iter_mut().enumerate() {
            let b = &mut block[r * w + x];
            *run = (*b).min(*run + STEP);
            *b = *run;
        }
    }
}

/// [`bleed_into_transparent`] by its definition: one FIFO queue seeded with every visible texel.
fn bleed_by_queue(rgba: &mut [u8], w: usize, h: usize) {
    let n = w * h;
    let mut done: Vec<bool> = rgba.chunks_exact(4).take(n).map(|px| px[3] != 0).collect();
    let mut queue: std::collections::VecDeque<usize> = (0..n).filter(|&i| done[i]).collect();
    while let Some(i) = queue.pop_front() {
        let (x, y) = (i % w, i / w);
        let colour = [rgba[i * 4], rgba[i * 4 + 1], rgba[i * 4 + 2]];
        let mut visit = |j: usize| {
            if !done[j] {
                done[j] = true;
                rgba[j * 4..j * 4 + 3].copy_from_slice(&colour);
                queue.push_back(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule [`bleed_into_transparent`]'s doc derives from the queue: each transparent texel takes the
    /// colour of the nearest visible texel in city-block distance, the lowest index among ties.
    fn nearest_by_brute_force(rgba: &[u8], w: usize, h: usize) -> Vec<u8> {
        let visible: Vec<usize> = (0..w * h).filter(|&i| rgba[i * 4 + 3] != 0).collect();
        let mut out = rgba.to_vec();
        for i in (0..w * h).filter(|&i| rgba[i * 4 + 3] == 0) {
            let dist = |j: usize| (i % w).abs_diff(j % w) + (i / w).abs_diff(j / w);
            if let Some(&root) = visible.iter().min_by_key(|&&j| (dist(j), j)) {
                out[i * 4..i * 4 + 3].copy_from_slice(&rgba[root * 4..root * 4 + 3]);
            }
        }
        out
    }

    #[test]
    fn the_bleed_is_the_queue_and_the_nearest_lowest_visible_texel() {
        let mut rng = crate::util::XorShift64::new(0x2545_F491_4F6C_DD1D);
        let mut next = move || rng.next_u64();
        for &(w, h) in &[
            (1, 1),
            (1, 7),
            (9, 1),
            (16, 16),
            (37, 23),
            (64, 5),
            (300, 211),
        ] {
            // Sparse (deep layers on the big image), half and dense visibility.
            for density in [0u64, 1, 2, 50, 97] {
                // The brute force is O(transparent × visible): small images, or sparse ones.
                let brute = w * h <= 4096 || density <= 2;
                let mut rgba = vec![0u8; w * h * 4];
                for p in rgba.chunks_exact_mut(4) {
                    let r = next();
                    let visible = r % 100 < density;
                    p.copy_from_slice(&[(r >> 8) as u8, (r >> 16) as u8, (r >> 24) as u8, 0]);
                    if visible {
                        p[3] = 1 + (r >> 32) as u8 % 255;
                    }
                }
                let mut want = rgba.clone();
                bleed_by_queue(&mut want, w, h);
                if brute {
                    assert_eq!(
                        nearest_by_brute_force(&rgba, w, h),
                        want,
                        "{w}×{h}, density {density}"
                    );
                }
                bleed_into_transparent(&mut rgba, w, h);
                assert_eq!(rgba, want, "{w}×{h}, density {density}");
            }
        }
        // All transparent: nothing to bleed from, the colours stay.
        let mut rgba: Vec<u8> = (0..64u8).map(|i| if i % 4 == 3 { 0 } else { i }).collect();
        let want = rgba.clone();
        bleed_into_transparent(&mut rgba, 4, 4);
        assert_eq!(rgba, want);
    }

    #[test]
    fn round_unit255_is_round_on_every_f32_below_one() {
        // Every f32 in [0, 1) in release builds (~1.07·10⁹, ~3 s on 2 cores), every 97th in debug builds.
        let step = if cfg!(debug_assertions) { 97 } else { 1 };
        let mut bits = 0u32;
        while bits < 1.0f32.to_bits() {
            let a = f32::from_bits(bits);
            assert_eq!(round_unit255(a), (a * 255.0).round() as u8, "{a:e}");
            bits += step;
        }
    }

    #[test]
    fn decode_encode_round_trip_with_alpha() {
        let img = DecodedImage {
            width: 2,
            height: 2,
            pixels: vec![
                [255, 0, 0, 255],
                [10, 200, 30, 128],
                [7, 7, 7, 1],
                [1, 2, 3, 0],
            ],
        };
        let lin = LinearImage::from_decoded(&img).unwrap();
        let out = lin.to_rgba8();
        assert_eq!(&out[0..4], &[255, 0, 0, 255]);
        assert_eq!(&out[4..8], &[10, 200, 30, 128]);
        assert_eq!(&out[8..12], &[7, 7, 7, 1]);
        // Alpha 0: colour bled from the 4-neighbour found first (texel 1 above it, breadth-first order).
        assert_eq!(out[15], 0);
        assert_eq!(&out[12..15], &[10, 200, 30]);
    }

    #[test]
    fn pixel_count_mismatch_is_an_error() {
        let img = DecodedImage {
            width: 3,
            height: 2,
            pixels: vec![[0; 4]; 5],
        };
        assert_eq!(
            LinearImage::from_decoded(&img),
            Err(ImageOpsError::PixelCount {
                width: 3,
                height: 2,
                pixels: 5
            })
        );
    }

    #[test]
    fn get_set_bounds() {
        let mut img = LinearImage::new_filled(3, 2, [0.0; 4]);
        img.set(2, 1, [1.0, 0.5, 0.25, 1.0]).unwrap();
        assert_eq!(img.get(2, 1), Some([1.0, 0.5, 0.25, 1.0]));
        assert_eq!(img.data[5], [1.0, 0.5, 0.25, 1.0]);
        assert_eq!(img.get(3, 0), None);
        assert!(img.set(0, 2, [0.0; 4]).is_err());
    }

    #[test]
    fn fully_transparent_stays_black() {
        let img = LinearImage::new_filled(4, 4, [0.0; 4]);
        assert!(img.to_rgba8().iter().all(|&b| b == 0));
    }
}
