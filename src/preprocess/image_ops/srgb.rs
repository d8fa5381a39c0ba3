//! sRGB ↔ linear conversion for 8-bit channels (IEC 61966-2-1 transfer function).
//!
//! Decoding is a 256-entry table. Encoding rounds in the *encoded* domain: a linear value `v` encodes to
//! the `i` with `decode((i − 0.5)/255) ≤ v < decode((i + 0.5)/255)`. Those 255 decision thresholds sit
//! strictly between neighbouring table values, so every table value encodes back to its own index: the
//! round trip u8 → linear → u8 is the identity for all 256 values. The lookup is branch-free: the top bits
//! of `v`'s f32 representation (exponent and 8 mantissa bits, so buckets are ≤ 2⁻⁸ of their value wide)
//! index a table of the code at each bucket's lower edge; no bucket holds more than one threshold
//! (neighbouring thresholds are ≥ 0.9 % apart), so one comparison finishes it.

use std::sync::LazyLock;

/// Low bits of the f32 representation dropped to form the bucket index.
const BUCKET_SHIFT: u32 = 15;
/// Buckets over `[0, 1]`: every positive f32 ≤ 1.0 (bits ≤ `0x3F80_0000`) has its own.
const BUCKETS: usize = (0x3F80_0000 >> BUCKET_SHIFT) as usize + 1;
/// The bucket of 2⁻¹³: every f32 below it encodes to 0 (the first threshold, decode(0.5/255) ≈ 1.5·10⁻⁴,
/// lies above), so the packed table starts there.
pub(super) const PACKED_FIRST: usize = (0x3900_0000 >> BUCKET_SHIFT) as usize;
/// Buckets of the packed table: [`PACKED_FIRST`] up to 1.0's.
pub(super) const PACKED: usize = BUCKETS - PACKED_FIRST;

struct Tables {
    /// `to_linear[i]` = decode(i / 255).
    to_linear: [f32; 256],
    /// `unit[i]` = i / 255 in f32 (a straight 8-bit alpha as a fraction, without a division per texel).
    unit: [f32; 256],
    /// `thresholds[i]` = decode((i + 0.5) / 255): the smallest linear value that encodes to `i + 1`;
    /// `thresholds[255]` = +∞ (nothing encodes above 255).
    thresholds: [f32; 256],
    /// `bucket_start[k]`: the code of the smallest f32 whose bits shifted by [`BUCKET_SHIFT`] are `k`.
    bucket_start: Box<[u8; BUCKETS]>,
    /// The buckets from [`PACKED_FIRST`] on, one `u32` each for a single SIMD gather
    /// ([`super::srgb_simd`]): `bucket_start[k] << 16 | o`, `o` the low [`BUCKET_SHIFT`] bits of the
    /// threshold inside bucket `k`, or `1 << BUCKET_SHIFT` (above every offset) where none is.
    packed: Box<[u32; PACKED]>,
    /// `to_linear` then `unit`: a texel's RGB index the first half, its alpha index + 256 the second
    /// (one SIMD gather per two texels, [`super::srgb_simd`]).
    decode_pair: [f32; 512],
}

static TABLES: LazyLock<Tables> = LazyLock::new(build_tables);

/// The sRGB electro-optical transfer function on `[0, 1]`, in f64.
fn decode(e: f64) -> f64 {
    if e <= 0.04045 {
        e / 12.92
    } else {
        ((e + 0.055) / 1.055).powf(2.4)
    }
}

fn build_tables() -> Tables {
    let mut to_linear = [0.0f32; 256];
    for (i, t) in to_linear.iter_mut().enumerate() {
        *t = decode(i as f64 / 255.0) as f32;
    }
    let unit = std::array::from_fn(|i| i as f32 / 255.0);
    let mut thresholds = [f32::INFINITY; 256];
    for (i, t) in thresholds.iter_mut().take(255).enumerate() {
        *t = decode((i as f64 + 0.5) / 255.0) as f32;
    }
    let mut bucket_start = Box::new([0u8; BUCKETS]);
    let mut code = 0usize;
    for (k, b) in bucket_start.iter_mut().enumerate() {
        let v = f32::from_bits((k as u32) << BUCKET_SHIFT);
        while v >= thresholds[code] {
            code += 1;
        }
        *b = code as u8;
    }
    let mut packed = Box::new([0u32; PACKED]);
    for (j, p) in packed.iter_mut().enumerate() {
        let k = PACKED_FIRST + j;
        let code = bucket_start[k];
        let th = thresholds[usize::from(code)].to_bits();
        let offset = if (th >> BUCKET_SHIFT) as usize == k {
            th & ((1 << BUCKET_SHIFT) - 1)
        } else {
            1 << BUCKET_SHIFT
        };
        *p = u32::from(code) << 16 | offset;
    }
    let decode_pair = std::array::from_fn(|i| if i < 256 { to_linear[i] } else { unit[i - 256] });
    Tables {
        to_linear,
        unit,
        thresholds,
        bucket_start,
        packed,
        decode_pair,
    }
}

/// `i as f32 / 255.0` for every 8-bit `i`: the same floats as the division (a table of its 256 results).
#[inline]
pub fn unit8_table() -> &'static [f32; 256] {
    &TABLES.unit
}

/// Linear value in `[0, 1]` of an sRGB-encoded 8-bit channel.
#[inline]
pub fn srgb8_to_linear(c: u8) -> f32 {
    TABLES.to_linear[c as usize]
}

/// The table behind [`srgb8_to_linear`], for loops over many texels (one lazy-init check, not one per
/// channel).
#[inline]
pub fn srgb8_to_linear_table() -> &'static [f32; 256] {
    &TABLES.to_linear
}

/// The sRGB 8-bit code of a linear value, rounded in the encoded domain; clamps to `[0, 255]`, NaN → 0.
/// Exact inverse of [`srgb8_to_linear`] on its 256 values.
#[inline]
pub fn linear_to_srgb8(v: f32) -> u8 {
    Encoder::get().encode(v)
}

/// [`linear_to_srgb8`] with the tables looked up once (for loops over many texels).
#[derive(Copy, Clone)]
pub struct Encoder(&'static Tables);

impl Encoder {
    /// The encoder over the shared tables.
    #[inline]
    pub fn get() -> Encoder {
        Encoder(&TABLES)
    }

    /// [`linear_to_srgb8`].
    #[inline]
    pub fn encode(self, v: f32) -> u8 {
        encode_with(self.0, v)
    }

    /// Linear premultiplied `texels` → sRGB8 straight bytes in `out` (4 a texel) with AVX2, the same
    /// bytes as the per-texel rule ([`super::srgb_simd`]); returns whether a written alpha is 0, or
    /// `None` (nothing written) where the CPU lacks AVX2 or `out` is not 4 bytes a texel.
    #[inline]
    pub(super) fn encode_run_simd(self, texels: &[[f32; 4]], out: &mut [u8]) -> Option<bool> {
        super::srgb_simd::encode_run(texels, out, &self.0.packed)
    }

    /// sRGB8 straight `pixels` → linear premultiplied texels in `out` with AVX2, the same floats as
    /// [`srgb8_to_linear`] of each colour times alpha / 255 ([`super::srgb_simd`]); `true` when every
    /// element of `out` was written, `false` (nothing written) where the CPU lacks AVX2 or the lengths
    /// differ.
    #[inline]
    pub(super) fn decode_run_simd(
        self,
        pixels: &[[u8; 4]],
        out: &mut [std::mem::MaybeUninit<[f32; 4]>],
    ) -> bool {
        super::srgb_simd::decode_run(pixels, out, &self.0.decode_pair)
    }
}

#[inline]
fn encode_with(t: &Tables, v: f32) -> u8 {
    // NaN and v ≤ 0 (−0.0 included) → 0.0; v ≥ 1 → 1.0, whose bucket starts at code 255.
    let v = if v > 0.0 { v.min(1.0) } else { 0.0 };
    // Both indices are in range by construction (k ≤ BUCKETS − 1, a u8 code < 256): no bounds branches.
    let k = ((v.to_bits() >> BUCKET_SHIFT) as usize).min(BUCKETS - 1);
    let code = t.bucket_start[k];
    code + u8::from(v >= t.thresholds[usize::from(code)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_table_is_the_division_bit_for_bit() {
        for (i, u) in unit8_table().iter().enumerate() {
            assert_eq!(u.to_bits(), (i as u8 as f32 / 255.0).to_bits(), "{i}");
        }
    }

    #[test]
    fn thresholds_strictly_between_table_values() {
        let t = &*TABLES;
        for i in 0..255 {
            assert!(t.to_linear[i] < t.thresholds[i], "i = {i}");
            assert!(t.thresholds[i] < t.to_linear[i + 1], "i = {i}");
        }
    }

    #[test]
    fn encode_matches_reference_rounding() {
        // Reference: round(encode(v) · 255) computed in f64, on a dense sweep (away from exact ties).
        let enc = |l: f64| {
            if l <= 0.0031308 {
                l * 12.92
            } else {
                1.055 * l.powf(1.0 / 2.4) - 0.055
            }
        };
        let mut mismatches = 0;
        for k in 0..=100_000 {
            let v = k as f32 / 100_000.0;
            let reference = (enc(v as f64) * 255.0).round() as i32;
            let got = linear_to_srgb8(v) as i32;
            // A tie within f32 precision may go either way; anything else must match exactly.
            if reference != got {
                mismatches += 1;
                assert!(
                    (reference - got).abs() <= 1,
                    "v = {v}: {got} vs {reference}"
                );
            }
        }
        assert!(mismatches <= 2, "{mismatches} near-tie mismatches");
    }

    /// The definition: the number of thresholds at or below `v` (NaN and v ≤ 0 → 0).
    fn encode_by_definition(v: f32) -> u8 {
        let t = &*TABLES;
        if v.is_nan() {
            return 0;
        }
        t.thresholds[..255].iter().filter(|&&th| v >= th).count() as u8
    }

    #[test]
    fn the_packed_table_is_the_bucket_rule() {
        let t = &*TABLES;
        // Below its first bucket every f32 encodes to 0.
        assert!(t.thresholds[0] > f32::from_bits((PACKED_FIRST as u32) << BUCKET_SHIFT));
        assert!(t.bucket_start[..PACKED_FIRST].iter().all(|&c| c == 0));
        // Each packed bucket: its code, and the offset where the next code starts (if inside it).
        let mask = (1u32 << BUCKET_SHIFT) - 1;
        for (j, &p) in t.packed.iter().enumerate() {
            let k = (PACKED_FIRST + j) as u32;
            for low in [0, 1, mask / 2, mask - 1, mask] {
                let v = f32::from_bits(k << BUCKET_SHIFT | low);
                let packed_code = (p >> 16) + u32::from(low >= (p & 0xFFFF));
                assert_eq!(
                    packed_code,
                    u32::from(encode_with(t, v)),
                    "bucket {k}, low bits {low}"
                );
            }
        }
    }

    #[test]
    fn one_threshold_per_bucket_at_most() {
        let t = &*TABLES;
        for k in 0..BUCKETS - 1 {
            let last = f32::from_bits((((k + 1) as u32) << BUCKET_SHIFT) - 1);
            let (first, end) = (t.bucket_start[k], encode_by_definition(last));
            assert!(end - first <= 1, "bucket {k}: codes {first}..={end}");
        }
        assert_eq!(t.bucket_start[BUCKETS - 1], 255);
    }

    #[test]
    fn encode_equals_its_definition() {
        let t = &*TABLES;
        let mut bits: Vec<u32> = (0..=0x3F80_0000u32).step_by(251).collect();
        // Every bucket edge and every threshold, with their neighbours.
        for k in 0..BUCKETS as u32 {
            let b = k << BUCKET_SHIFT;
            bits.extend([b.saturating_sub(1), b, b + 1]);
        }
        for th in &t.thresholds[..255] {
            let b = th.to_bits();
            bits.extend(b - 64..=b + 64);
        }
        for b in bits {
            let v = f32::from_bits(b);
            assert_eq!(
                linear_to_srgb8(v),
                encode_by_definition(v),
                "v = {v:e} (bits {b:#x})"
            );
            assert_eq!(linear_to_srgb8(-v), 0);
        }
        assert_eq!(linear_to_srgb8(-0.0), 0);
        assert_eq!(linear_to_srgb8(f32::MIN_POSITIVE / 2.0), 0);
    }

    #[test]
    fn out_of_range_and_nan() {
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
    }
}
