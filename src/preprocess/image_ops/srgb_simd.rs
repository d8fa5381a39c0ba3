//! sRGB8 ↔ linear for runs of texels with AVX2: the same bytes and floats as the per-texel rules
//! ([`super::linear`]'s `encode_texel` and `decode_texel`), two texels per 256-bit register.
//!
//! Decoding (every decoded image once, ~11 % of a facade city's build) gathers a texel pair's eight
//! table entries at once (colour channels from the sRGB table, alpha from the `i / 255` table) and
//! multiplies by `[a, a, a, 1]`: the scalar rule's products, and `a · 1 = a` exactly.
//!
//! Encoding (`to_rgba8`, every stored level of every atlas and original: ~20 % of an all-tracks build)
//! is two table lookups per channel and a branch on alpha in the scalar rule. Here one gather per 8
//! channels reads a packed table (a bucket's code and the offset inside it where the next code starts);
//! the clamps are `max`/`min` (NaN → 0, as the scalar `v > 0` test gives); a pair of opaque texels
//! takes the opaque rule alone, any other pair both rules blended per texel. Every step is the same
//! IEEE operation as the scalar code (one division `1 / a`, then products), so the bytes are equal; the
//! unit tests compare the two on every f32 in `[0, 1]`, on edge values (NaN, ±∞, ±0, denormals, every
//! threshold and its neighbours) and on random texels.
//!
//! Used only where [`crate::util::has_avx2`] says so; elsewhere the scalar rules run.

use super::srgb::PACKED;
use std::mem::MaybeUninit;

/// Encodes `texels` (linear premultiplied) into `out` (sRGB8 straight, 4 bytes a texel) and returns
/// whether a written alpha is 0; `None` (nothing written) where the CPU lacks AVX2 or `out` is not
/// 4 bytes a texel. `packed` is [`super::srgb`]'s packed bucket table.
pub(super) fn encode_run(
    texels: &[[f32; 4]],
    out: &mut [u8],
    packed: &[u32; PACKED],
) -> Option<bool> {
    if !crate::util::has_avx2() || out.len() != texels.len() * 4 {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: AVX2 was detected above; `encode_avx2` reads `texels` and writes `out` within their
        // lengths (checked equal above) and gathers at indices clamped to `0..PACKED`, within `packed`.
        #[allow(
            unsafe_code,
            reason = "AVX2 intrinsics: calling a target_feature function, loads, stores and gathers through raw pointers"
        )]
        unsafe {
            Some(avx2::encode_avx2(texels, out, packed))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = packed;
        None
    }
}

/// Decodes `pixels` (sRGB8 straight) into `out` (linear premultiplied), every element of it, and returns
/// true; `false` (nothing written) where the CPU lacks AVX2 or the lengths differ. `table` is
/// [`super::srgb`]'s sRGB table, then its `i / 255` table.
pub(super) fn decode_run(
    pixels: &[[u8; 4]],
    out: &mut [MaybeUninit<[f32; 4]>],
    table: &[f32; 512],
) -> bool {
    if !crate::util::has_avx2() || out.len() != pixels.len() {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: AVX2 was detected above; `decode_avx2` reads `pixels` and writes `out` within their
        // lengths (checked equal above) and gathers at indices below 512 (a byte, plus 256 for alpha).
        #[allow(
            unsafe_code,
            reason = "AVX2 intrinsics: calling a target_feature function, loads, stores and gathers through raw pointers"
        )]
        unsafe {
            avx2::decode_avx2(pixels, out, table);
        }
        true
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = table;
        false
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 intrinsics: loads, stores and gathers through raw pointers"
)]
mod avx2 {
    use super::super::srgb::{PACKED, PACKED_FIRST};
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    /// # Safety
    /// The CPU has AVX2; `out.len() == pixels.len()`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn decode_avx2(
        pixels: &[[u8; 4]],
        out: &mut [MaybeUninit<[f32; 4]>],
        table: &[f32; 512],
    ) {
        let one = _mm256_set1_ps(1.0);
        // Alpha indices read the second half of the table.
        let alpha_half = _mm256_setr_epi32(0, 0, 0, 256, 0, 0, 0, 256);
        let pairs = pixels.len() / 2;
        let src = pixels.as_ptr().cast::<u8>();
        let dst = out.as_mut_ptr().cast::<f32>();
        for p in 0..pairs {
            // SAFETY: pixel pair `p` is 8 bytes at `src + 8p`, within `pixels`; its 8 floats at
            // `dst + 8p`, within `out`; the gather's indices are below 512.
            unsafe {
                let bytes = _mm_loadl_epi64(src.add(8 * p).cast());
                let idx = _mm256_add_epi32(_mm256_cvtepu8_epi32(bytes), alpha_half);
                let g = _mm256_i32gather_ps::<4>(table.as_ptr(), idx);
                let a = _mm256_blend_ps::<0b1000_1000>(_mm256_permute_ps::<0xFF>(g), one);
                _mm256_storeu_ps(dst.add(8 * p), _mm256_mul_ps(g, a));
            }
        }
        if pixels.len() % 2 == 1 {
            let last = pixels.len() - 1;
            out[last].write(super::super::linear::decode_texel(
                super::super::srgb::srgb8_to_linear_table(),
                super::super::srgb::unit8_table(),
                pixels[last],
            ));
        }
    }

    /// # Safety
    /// The CPU has AVX2; `out.len() == texels.len() * 4`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn encode_avx2(
        texels: &[[f32; 4]],
        out: &mut [u8],
        packed: &[u32; PACKED],
    ) -> bool {
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let c255 = _mm256_set1_ps(255.0);
        let half = _mm256_set1_ps(0.5);
        let first = _mm256_set1_epi32(PACKED_FIRST as i32);
        let last = _mm256_set1_epi32((PACKED - 1) as i32);
        let low = _mm256_set1_epi32(0x7FFF);
        let i255 = _mm256_set1_epi32(255);
        let mut transparent = _mm256_setzero_si256();
        let pairs = texels.len() / 2;
        let src = texels.as_ptr().cast::<f32>();
        let dst = out.as_mut_ptr();
        // `encode` of 8 lanes: clamp (NaN and v ≤ 0 → 0; `max` returns its second operand for NaN and
        // −0), bucket, then one step where the value reaches the threshold inside its bucket.
        let encode = |colour: __m256| -> __m256i {
            let v = _mm256_castps_si256(_mm256_min_ps(_mm256_max_ps(colour, zero), one));
            let k = _mm256_sub_epi32(_mm256_max_epi32(_mm256_srli_epi32::<15>(v), first), first);
            let k = _mm256_min_epi32(k, last);
            // SAFETY: every index is in `0..PACKED` (clamped above), within `packed`.
            let e = unsafe { _mm256_i32gather_epi32::<4>(packed.as_ptr().cast::<i32>(), k) };
            let offset = _mm256_and_si256(v, low);
            // `offset ≥ threshold offset` (both ≤ 2¹⁵): −1 where the code steps up.
            let step = _mm256_cmpgt_epi32(
                _mm256_add_epi32(offset, _mm256_set1_epi32(1)),
                _mm256_and_si256(e, _mm256_set1_epi32(0xFFFF)),
            );
            // Values below the first packed bucket land in it with code 0 and no threshold.
            _mm256_sub_epi32(_mm256_srli_epi32::<16>(e), step)
        };
        for p in 0..pairs {
            // SAFETY: texel pair `p` is 8 floats at `src + 8p`, within `texels`; its 8 bytes at
            // `dst + 8p`, within `out`.
            let t = unsafe { _mm256_loadu_ps(src.add(8 * p)) };
            // Alpha of each texel in all four of its lanes; scalar `t[3] >= 1.0` (false for NaN).
            let a = _mm256_permute_ps::<0xFF>(t);
            let opaque = _mm256_cmp_ps::<_CMP_GE_OQ>(a, one);
            let texel = if _mm256_movemask_ps(opaque) == 0xFF {
                // Both texels opaque: colour as it is, alpha 255.
                _mm256_blend_epi32::<0b1000_1000>(encode(t), i255)
            } else {
                // `if t[3] > 0 { t[3] } else { 0 }`, then `round_unit255`: truncate, add 1 where the
                // fraction is ≥ ½.
                let ac = _mm256_max_ps(a, zero);
                let x = _mm256_mul_ps(ac, c255);
                let whole = _mm256_cvttps_epi32(x);
                let frac = _mm256_sub_ps(x, _mm256_cvtepi32_ps(whole));
                let up = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(frac, half));
                let a8 = _mm256_sub_epi32(whole, up);
                let inv = _mm256_div_ps(one, ac);
                let colour = _mm256_blendv_ps(_mm256_mul_ps(t, inv), t, opaque);
                let opaque_i = _mm256_castps_si256(opaque);
                let alpha = _mm256_blendv_epi8(a8, i255, opaque_i);
                let texel = _mm256_blend_epi32::<0b1000_1000>(encode(colour), alpha);
                // A general-path texel whose 8-bit alpha is 0 is all zero.
                let cleared =
                    _mm256_andnot_si256(opaque_i, _mm256_cmpeq_epi32(a8, _mm256_setzero_si256()));
                transparent = _mm256_or_si256(transparent, cleared);
                _mm256_andnot_si256(cleared, texel)
            };
            // 8 × i32 in 0..=255 → bytes: each 128-bit half holds one texel.
            let w16 = _mm256_packus_epi32(texel, texel);
            let b8 = _mm256_packus_epi16(w16, w16);
            // SAFETY: bytes `8p..8p + 8` of `out`.
            unsafe {
                dst.add(8 * p)
                    .cast::<i32>()
                    .write_unaligned(_mm256_extract_epi32::<0>(b8));
                dst.add(8 * p + 4)
                    .cast::<i32>()
                    .write_unaligned(_mm256_extract_epi32::<4>(b8));
            }
        }
        let mut any = _mm256_movemask_epi8(transparent) != 0;
        if texels.len() % 2 == 1 {
            let last = texels.len() - 1;
            let e = super::super::linear::encode_texel(
                super::super::srgb::Encoder::get(),
                texels[last],
            );
            out[4 * last..4 * last + 4].copy_from_slice(&e);
            any |= e[3] == 0;
        }
        any
    }
}

#[cfg(test)]
mod tests {
    use super::super::linear::encode_texel;
    use super::super::srgb::{Encoder, srgb8_to_linear};
    use std::mem::MaybeUninit;

    /// The scalar rule over `texels`: bytes and whether an alpha is 0.
    fn scalar(texels: &[[f32; 4]]) -> (Vec<u8>, bool) {
        let enc = Encoder::get();
        let bytes: Vec<u8> = texels.iter().flat_map(|&t| encode_texel(enc, t)).collect();
        let transparent = bytes.chunks_exact(4).any(|p| p[3] == 0);
        (bytes, transparent)
    }

    fn check(texels: &[[f32; 4]]) {
        let mut out = vec![0xAB; texels.len() * 4];
        let Some(transparent) = Encoder::get().encode_run_simd(texels, &mut out) else {
            // No AVX2 (or ATLASTREE_SCALAR): the contract is that nothing was written.
            eprintln!("SKIP: the AVX2 kernels are off here, the scalar rule runs alone");
            assert!(out.iter().all(|&b| b == 0xAB), "written although refused");
            return;
        };
        let (want, want_transparent) = scalar(texels);
        for (i, (g, w)) in out.chunks_exact(4).zip(want.chunks_exact(4)).enumerate() {
            assert_eq!(g, w, "texel {i}: {:?}", texels[i]);
        }
        assert_eq!(transparent, want_transparent);
    }

    /// Values where the rules could part: NaN, ±∞, ±0, denormals, the clamps, and every sRGB decision
    /// threshold with its neighbouring floats.
    fn edge_values() -> Vec<f32> {
        let mut v = vec![
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::from_bits(1),
            f32::MIN_POSITIVE,
            -1e-30,
            1.0,
            1.0 + f32::EPSILON,
            1.0 - f32::EPSILON / 2.0,
            2.0,
            1e30,
            0.5 / 255.0,
            1.5 / 255.0,
        ];
        for i in 0..=255u8 {
            let l = srgb8_to_linear(i);
            v.push(l);
            // Midpoints between codes, where the thresholds sit, and their neighbouring floats.
            if i < 255 {
                let m = 0.5 * (l + srgb8_to_linear(i + 1));
                for d in -3i32..=3 {
                    v.push(f32::from_bits((m.to_bits() as i32 + d) as u32));
                }
            }
            // Alphas that round to each 8-bit value, and just below the rounding edge.
            let a = (f32::from(i) + 0.5) / 255.0;
            v.push(a);
            v.push(f32::from_bits(a.to_bits() - 1));
        }
        v
    }

    #[test]
    fn edge_texels_encode_as_the_scalar_rule() {
        let e = edge_values();
        // Every edge value as colour with a few alphas, and as alpha under a few colours.
        let mut texels = Vec::new();
        for &x in &e {
            for &a in &[1.0, 0.5, 1.0 / 255.0, 0.0, 0.9999999, 2.0 / 510.0] {
                texels.push([x, 0.25 * x, x * a, a]);
            }
            for &c in &[0.0, 0.2, 1.0] {
                texels.push([c * 0.3, c, c * 0.5, x]);
                texels.push([x, x, x, x]);
            }
        }
        check(&texels);
        // An odd count: the last texel takes the scalar rule.
        check(&texels[..texels.len() - 1]);
        check(&texels[..1]);
        check(&[]);
    }

    #[test]
    fn every_colour_in_0_1_encodes_as_the_scalar_rule() {
        // Every f32 in [0, 1] as a colour channel of an opaque texel in release builds (~1.07·10⁹, three
        // a texel), every 101st in debug builds; compared in runs of 4096 texels.
        let step = if cfg!(debug_assertions) { 101 } else { 1 };
        let enc = Encoder::get();
        let mut bits = 0u32;
        let end = 1.0f32.to_bits();
        let mut texels = Vec::with_capacity(4096);
        let mut out = vec![0u8; 4096 * 4];
        while bits <= end {
            texels.clear();
            while texels.len() < 4096 && bits <= end {
                let c = |i: u32| f32::from_bits((bits + i * step).min(end));
                texels.push([c(0), c(1), c(2), 1.0]);
                bits += 3 * step;
            }
            let out = &mut out[..texels.len() * 4];
            let Some(transparent) = enc.encode_run_simd(&texels, out) else {
                eprintln!("SKIP: the AVX2 kernels are off here, the scalar rule runs alone");
                return;
            };
            assert!(!transparent);
            for (t, p) in texels.iter().zip(out.chunks_exact(4)) {
                let want = [enc.encode(t[0]), enc.encode(t[1]), enc.encode(t[2]), 255];
                assert_eq!(p, want, "{t:?}");
            }
        }
    }

    #[test]
    fn every_pixel_decodes_as_the_scalar_rule() {
        // Every (colour, alpha) pair: 65,536 pixels, colours in all three channels, and an odd count.
        use super::super::linear::decode_texel;
        use super::super::srgb::{srgb8_to_linear_table, unit8_table};
        let pixels: Vec<[u8; 4]> = (0..=u16::MAX)
            .map(|i| {
                let [c, a] = i.to_le_bytes();
                [c, c.wrapping_mul(7), 255 - c, a]
            })
            .collect();
        for n in [pixels.len(), pixels.len() - 1, 1, 0] {
            let mut out = vec![MaybeUninit::new([f32::NAN; 4]); n];
            let decoded = Encoder::get().decode_run_simd(&pixels[..n], &mut out);
            // SAFETY (test): initialised with NaN above, then overwritten or left by the decoder.
            #[allow(unsafe_code, reason = "reading MaybeUninit values initialised above")]
            let out: Vec<[f32; 4]> = out.iter().map(|o| unsafe { o.assume_init() }).collect();
            if !decoded {
                // No AVX2 (or ATLASTREE_SCALAR): the contract is that nothing was written.
                eprintln!("SKIP: the AVX2 kernels are off here, the scalar rule runs alone");
                assert!(
                    out.iter().flatten().all(|v| v.is_nan()),
                    "written although refused"
                );
                return;
            }
            for (p, got) in pixels.iter().zip(&out) {
                let want = decode_texel(srgb8_to_linear_table(), unit8_table(), *p);
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{p:?}");
            }
        }
    }

    #[test]
    fn random_texels_encode_as_the_scalar_rule() {
        // Premultiplied texels (colour ≤ alpha), straight ones beyond it, and raw bit patterns.
        let mut rng = crate::util::XorShift64::new(0x9E37_79B9_7F4A_7C15);
        let mut next = move || rng.next_u64();
        let mut texels = Vec::with_capacity(300_000);
        for i in 0..300_000 {
            let r = next();
            let u = |k: u32| ((r >> (16 * k)) & 0xFFFF) as f32 / 65535.0;
            let t = match i % 4 {
                0 => [u(0), u(1), u(2), 1.0],
                1 => {
                    let a = u(3);
                    [u(0) * a, u(1) * a, u(2) * a, a]
                }
                2 => [u(0) * 1.5 - 0.2, u(1), u(2) * 3.0, u(3) * 1.2 - 0.1],
                _ => [
                    f32::from_bits(r as u32),
                    f32::from_bits((r >> 32) as u32),
                    f32::from_bits((r >> 16) as u32),
                    f32::from_bits((r >> 8) as u32),
                ],
            };
            texels.push(t);
        }
        check(&texels);
    }
}
