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
        if n >= PAR_TEXELS {
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
        let run = |(px, texels): (&mut [u8], &[[f32; 4]])| {
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
        };
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
/// The breadth-first search runs layer by layer (the order a FIFO queue gives) and starts from the
/// visible texels that touch a transparent one only: the others would visit nothing, so the result is
/// the queue over all of them (unit test against it), without a queue entry and a division per texel
/// (the search was ~10 % of an alpha-heavy build).
fn bleed_into_transparent(rgba: &mut [u8], w: usize, h: usize) {
    let n = w.saturating_mul(h);
    if rgba.len() < n * 4 || n == 0 {
        return;
    }
    let mut done: Vec<bool> = rgba.chunks_exact(4).take(n).map(|px| px[3] != 0).collect();
    // Layer 0: visible texels with a transparent 4-neighbour, in index order, as (x, y).
    let mut layer: Vec<(usize, usize)> = Vec::new();
    for y in 0..h {
        let row = y * w;
        for x in 0..w {
            let i = row + x;
            if done[i]
                && ((x > 0 && !done[i - 1])
                    || (x + 1 < w && !done[i + 1])
                    || (y > 0 && !done[i - w])
                    || (y + 1 < h && !done[i + w]))
            {
                layer.push((x, y));
            }
        }
    }
    let mut next: Vec<(usize, usize)> = Vec::new();
    while !layer.is_empty() {
        for &(x, y) in &layer {
            let i = y * w + x;
            let colour = [rgba[i * 4], rgba[i * 4 + 1], rgba[i * 4 + 2]];
            let mut visit = |j: usize, at: (usize, usize)| {
                if !done[j] {
                    done[j] = true;
                    rgba[j * 4..j * 4 + 3].copy_from_slice(&colour);
                    next.push(at);
                }
            };
            if x > 0 {
                visit(i - 1, (x - 1, y));
            }
            if x + 1 < w {
                visit(i + 1, (x + 1, y));
            }
            if y > 0 {
                visit(i - w, (x, y - 1));
            }
            if y + 1 < h {
                visit(i + w, (x, y + 1));
            }
        }
        std::mem::swap(&mut layer, &mut next);
        next.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition [`bleed_into_transparent`] keeps: one FIFO queue seeded with every visible texel.
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

    #[test]
    fn the_layered_bleed_is_the_queue_over_every_visible_texel() {
        let mut rng = crate::util::XorShift64::new(0x2545_F491_4F6C_DD1D);
        let mut next = move || rng.next_u64();
        for &(w, h) in &[(1, 1), (1, 7), (9, 1), (16, 16), (37, 23), (64, 5)] {
            // Sparse, half and dense visibility, and blobs (runs of visible texels).
            for density in [2u64, 50, 97] {
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
