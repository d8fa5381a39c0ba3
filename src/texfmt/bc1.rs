//! One BC1 block decoded to its 16 RGBA8 texels for the build's error measurement: the bytes
//! `bcdec_rs::bc1` writes (its integer expansions and both colour modes, checked against it in the tests),
//! as one palette of four `u32` texels indexed sixteen times, without a slice copy per texel. A build
//! decodes every block it stores once to measure its error, so this runs over every stored BC1 texel.

/// The four palette entries of a BC1 colour block (`block[0..4]`: two RGB565 endpoints, little-endian),
/// as RGBA8 texels packed little-endian into `u32` (R in the low byte). `c0 > c1`: four-colour mode (the
/// two thirds between); else three colours (the half between) and transparent black.
fn palette(block: &[u8; 8]) -> [u32; 4] {
    let c0 = u32::from(u16::from_le_bytes([block[0], block[1]]));
    let c1 = u32::from(u16::from_le_bytes([block[2], block[3]]));
    let (r0, g0, b0) = ((c0 >> 11) & 0x1F, (c0 >> 5) & 0x3F, c0 & 0x1F);
    let (r1, g1, b1) = ((c1 >> 11) & 0x1F, (c1 >> 5) & 0x3F, c1 & 0x1F);
    let texel = |r: u32, g: u32, b: u32, a: u32| r | (g << 8) | (b << 16) | (a << 24);
    let expand5 = |v: u32| (v * 527 + 23) >> 6;
    let expand6 = |v: u32| (v * 259 + 33) >> 6;
    let e0 = texel(expand5(r0), expand6(g0), expand5(b0), 255);
    let e1 = texel(expand5(r1), expand6(g1), expand5(b1), 255);
    if c0 > c1 {
        let third5 = |a: u32, b: u32| ((2 * a + b) * 351 + 61) >> 7;
        let third6 = |a: u32, b: u32| ((2 * a + b) * 2763 + 1039) >> 11;
        [
            e0,
            e1,
            texel(third5(r0, r1), third6(g0, g1), third5(b0, b1), 255),
            texel(third5(r1, r0), third6(g1, g0), third5(b1, b0), 255),
        ]
    } else {
        let half5 = |a: u32, b: u32| ((a + b) * 1053 + 125) >> 8;
        let half6 = |a: u32, b: u32| ((a + b) * 4145 + 1019) >> 11;
        [
            e0,
            e1,
            texel(half5(r0, r1), half6(g0, g1), half5(b0, b1), 255),
            0,
        ]
    }
}

/// The 16 texels of BC1 block `block`, RGBA8, rows back to back (what `bcdec_rs::bc1(block, out, 16)`
/// writes into `out`).
pub(super) fn texels(block: &[u8; 8]) -> [u8; 64] {
    let palette = palette(block);
    let indices = u32::from_le_bytes([block[4], block[5], block[6], block[7]]);
    let mut out = [0u8; 64];
    for (i, texel) in out.chunks_exact_mut(4).enumerate() {
        let entry = palette[((indices >> (2 * i)) & 3) as usize];
        texel.copy_from_slice(&entry.to_le_bytes());
    }
    out
}

/// The squared error of a band's interior BC1 blocks against their source texels: block `i` of `blocks`
/// against texels `4i..4i + 4` of the four `rows` (RGBA8, each at least `16 · blocks.len()` bytes), over
/// the bytes `mask` keeps (0xFF or 0, 16 texels). What decoding each block with [`texels`] and summing
/// the masked squared differences gives (`texfmt::block_sse`), with AVX2: the palette indexed by a lane
/// permute, differences squared and summed as 16-bit pairs. `None` where the CPU lacks AVX2 or a row is
/// short (the caller decodes instead). A build measures every block it stores; decode, copy and sum were
/// ~11 % of a facade city's build.
pub(super) fn interior_band_sse(
    blocks: &[[u8; 8]],
    rows: [&[u8]; 4],
    mask: &[u8; 64],
) -> Option<u64> {
    if !crate::util::has_avx2() || rows.iter().any(|r| r.len() < 16 * blocks.len()) {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: AVX2 was detected above, and every row holds 16 bytes per block (checked above).
        #[allow(
            unsafe_code,
            reason = "AVX2 intrinsics: calling a target_feature function and unaligned loads"
        )]
        unsafe {
            Some(avx2::interior_band_sse(blocks, rows, mask))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (blocks, rows, mask);
        None
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 intrinsics: unaligned loads through raw pointers"
)]
mod avx2 {
    use std::arch::x86_64::*;

    /// # Safety
    /// The CPU has AVX2; each of `rows` has at least `16 · blocks.len()` bytes.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn interior_band_sse(
        blocks: &[[u8; 8]],
        rows: [&[u8]; 4],
        mask: &[u8; 64],
    ) -> u64 {
        let three = _mm256_set1_epi32(3);
        let zero = _mm256_setzero_si256();
        // Texel i's index is bits 2i, 2i + 1: texels 0–7 (rows 0 and 1), then 8–15 (rows 2 and 3).
        let shifts = [
            _mm256_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14),
            _mm256_setr_epi32(16, 18, 20, 22, 24, 26, 28, 30),
        ];
        // SAFETY: 32-byte loads at 0 and 32 of the 64-byte mask.
        let masks = unsafe {
            [
                _mm256_loadu_si256(mask.as_ptr().cast()),
                _mm256_loadu_si256(mask.as_ptr().add(32).cast()),
            ]
        };
        let mut total = 0u64;
        for (i, block) in blocks.iter().enumerate() {
            let palette = super::palette(block);
            let p = _mm256_setr_epi32(
                palette[0] as i32,
                palette[1] as i32,
                palette[2] as i32,
                palette[3] as i32,
                palette[0] as i32,
                palette[1] as i32,
                palette[2] as i32,
                palette[3] as i32,
            );
            let all = _mm256_set1_epi32(
                u32::from_le_bytes([block[4], block[5], block[6], block[7]]) as i32,
            );
            let mut sum = zero;
            for half in 0..2 {
                let idx = _mm256_and_si256(_mm256_srlv_epi32(all, shifts[half]), three);
                let decoded = _mm256_permutevar8x32_epi32(p, idx);
                // SAFETY: bytes 16i..16i + 16 of two rows, within them (the caller's contract).
                let stored = unsafe {
                    _mm256_loadu2_m128i(
                        rows[2 * half + 1].as_ptr().add(16 * i).cast(),
                        rows[2 * half].as_ptr().add(16 * i).cast(),
                    )
                };
                let diff = _mm256_and_si256(
                    _mm256_sub_epi8(
                        _mm256_max_epu8(stored, decoded),
                        _mm256_min_epu8(stored, decoded),
                    ),
                    masks[half],
                );
                let lo = _mm256_unpacklo_epi8(diff, zero);
                let hi = _mm256_unpackhi_epi8(diff, zero);
                sum = _mm256_add_epi32(sum, _mm256_madd_epi16(lo, lo));
                sum = _mm256_add_epi32(sum, _mm256_madd_epi16(hi, hi));
            }
            // At most 64 · 255² a block: no lane overflows.
            let s = _mm_add_epi32(
                _mm256_castsi256_si128(sum),
                _mm256_extracti128_si256::<1>(sum),
            );
            let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b01_00_11_10>(s));
            let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b10_11_00_01>(s));
            total += u64::from(_mm_cvtsi128_si32(s) as u32);
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::XorShift64;

    #[test]
    fn interior_band_sse_is_the_decoded_blocks_masked_squared_error() {
        let mut rng = XorShift64::new(0x5EED_B1C1);
        let mut checked = 0;
        for case in 0..200_000u32 {
            let block: [u8; 8] = std::array::from_fn(|_| rng.next_u64() as u8);
            // Sources near the block's colours, random ones, and the decoded block itself (error 0).
            let decoded = texels(&block);
            let source: [u8; 64] = match case % 3 {
                0 => std::array::from_fn(|i| decoded[i].wrapping_add((rng.next_u64() % 7) as u8)),
                1 => std::array::from_fn(|_| rng.next_u64() as u8),
                _ => decoded,
            };
            let rows: [&[u8]; 4] = std::array::from_fn(|y| &source[16 * y..16 * y + 16]);
            let channels = 1 + (case % 4) as usize;
            let mask = super::super::channel_mask(channels);
            let want: u64 = (0..64)
                .filter(|&i| mask[i] != 0)
                .map(|i| u64::from(source[i].abs_diff(decoded[i])).pow(2))
                .sum();
            let Some(got) = interior_band_sse(&[block], rows, &mask) else {
                eprintln!("SKIP: this CPU has no AVX2, blocks are decoded and summed instead");
                return;
            };
            assert_eq!(got, want, "block {block:?}, channels {channels}");
            checked += 1;
        }
        assert_eq!(checked, 200_000);
    }

    fn bcdec(block: &[u8; 8]) -> [u8; 64] {
        let mut out = [0u8; 64];
        bcdec_rs::bc1(block, &mut out, 16);
        out
    }

    #[test]
    fn every_endpoint_pair_of_each_channel_decodes_as_bcdec_does() {
        // The expansions are per channel: sweep each channel's two endpoints over all their values (the
        // others fixed), in both orders, so both modes and every rounding are covered; the indices use
        // all four entries.
        let indices = [0b1110_0100, 0b0001_1011, 0b1100_1001, 0b0111_0010];
        for (shift, bits) in [(11u16, 5u32), (5, 6), (0, 5)] {
            for a in 0..1u16 << bits {
                for b in 0..1u16 << bits {
                    let c0 = (a << shift) | 0x0821 & !(((1 << bits) - 1) << shift);
                    let c1 = (b << shift) | 0x1042 & !(((1 << bits) - 1) << shift);
                    let [c00, c01] = c0.to_le_bytes();
                    let [c10, c11] = c1.to_le_bytes();
                    let block = [
                        c00, c01, c10, c11, indices[0], indices[1], indices[2], indices[3],
                    ];
                    assert_eq!(texels(&block), bcdec(&block), "block {block:?}");
                }
            }
        }
    }

    #[test]
    fn random_blocks_decode_as_bcdec_does() {
        let mut rng = XorShift64::new(0xBC1);
        for _ in 0..200_000 {
            let block = rng.next_u64().to_le_bytes();
            assert_eq!(texels(&block), bcdec(&block), "block {block:?}");
        }
        // Equal endpoints: three-colour mode (c0 > c1 fails).
        for c in [0u16, 1, 0x7BEF, 0xFFFF] {
            let [x, y] = c.to_le_bytes();
            let block = [x, y, x, y, 0xFF, 0xAA, 0x55, 0x1B];
            assert_eq!(texels(&block), bcdec(&block), "block {block:?}");
        }
    }
}
