//! sRGB ↔ linear conversion for 8-bit channels (IEC 61966-2-1 transfer function).
//!
//! Decoding is a 256-entry table. Encoding rounds in the *encoded* domain: a linear value `v` encodes to
//! the `i` with `decode((i − 0.5)/255) ≤ v < decode((i + 0.5)/255)`. Those 255 decision thresholds sit
//! strictly between neighbouring table values, so every table value encodes back to its own index: the
//! round trip u8 → linear → u8 is the identity for all 256 values. The lookup is a 4096-bucket table that
//! gives the code at each bucket's lower edge, corrected upwards by at most a couple of threshold steps.

use std::sync::LazyLock;

/// Buckets of the encoding start table over linear `[0, 1)`.
const BUCKETS: usize = 4096;

struct Tables {
    /// `to_linear[i]` = decode(i / 255).
    to_linear: [f32; 256],
    /// `thresholds[i]` = decode((i + 0.5) / 255): the smallest linear value that encodes to `i + 1`.
    thresholds: [f32; 255],
    /// `bucket_start[k]`: the code of the linear value `k / BUCKETS`.
    bucket_start: [u8; BUCKETS],
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
    let mut thresholds = [0.0f32; 255];
    for (i, t) in thresholds.iter_mut().enumerate() {
        *t = decode((i as f64 + 0.5) / 255.0) as f32;
    }
    let mut bucket_start = [0u8; BUCKETS];
    let mut code = 0usize;
    for (k, b) in bucket_start.iter_mut().enumerate() {
        let v = k as f32 / BUCKETS as f32;
        while code < 255 && v >= thresholds[code] {
            code += 1;
        }
        *b = code as u8;
    }
    Tables {
        to_linear,
        thresholds,
        bucket_start,
    }
}

/// Linear value in `[0, 1]` of an sRGB-encoded 8-bit channel.
#[inline]
pub fn srgb8_to_linear(c: u8) -> f32 {
    TABLES.to_linear[c as usize]
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
}

#[inline]
fn encode_with(t: &Tables, v: f32) -> u8 {
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    // v·4096 is exact in f32 (power-of-two scale), so the bucket is floor(v·4096) < 4096.
    let k = ((v * BUCKETS as f32) as usize).min(BUCKETS - 1);
    let mut code = t.bucket_start[k] as usize;
    while code < 255 && v >= t.thresholds[code] {
        code += 1;
    }
    code as u8
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn out_of_range_and_nan() {
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
    }
}
