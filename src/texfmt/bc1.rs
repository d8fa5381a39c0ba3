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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::XorShift64;

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
