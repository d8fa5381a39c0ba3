//! Non-square images (original textures since format 5, issue 17): a `w × h` power-of-two image with its
//! full mip chain down to 1×1 (level `l` is `max(1, w >> l) × max(1, h >> l)`, so the chain has
//! `log2(max(w, h)) + 1` levels, as many as the square class `max(w, h)` it is drawn from), and the tiling
//! that turns it into a layer of that square class.
//!
//! **Why tiling.** Class arrays are square (one array per side, so TAB binds a fixed set of arrays). A
//! `w × h` texture is uploaded into an `s × s` layer (`s = max(w, h)`) repeated `s / w` times across and
//! `s / h` times down, at every mip level; the shader scales its wrapped UV by `(w, h) / s`. A repeating
//! sampler then filters across the texture's own seam exactly as it would on the texture alone (the
//! neighbour of the last row is the next copy's first row), and the file stores each texel once.
//!
//! **Small levels.** A compressed level whose side is under 4 is padded to a whole 4×4 block
//! *periodically* here (texel `(x mod w, y mod h)`), not by edge replication as square levels are, so a
//! block of a 2-texel-high level holds two whole periods and tiling stays a copy of whole blocks. Square
//! images (`w == h`) take the square path unchanged, byte for byte.

use super::{Encoded, TexFormat, TexFormatError, encode_level, encode_padded, pad_to_blocks};
use rayon::prelude::*;
use std::borrow::Cow;

/// Extents `(w, h)` of the mip levels of a `w × h` image: `(max(1, w >> l), max(1, h >> l))` for
/// `l = 0 ..= log2(max(w, h))`.
pub fn mip_extents(w: u32, h: u32) -> impl Iterator<Item = (u32, u32)> {
    let (w, h) = (w.max(1), h.max(1));
    let levels = super::mip_level_count(w.max(h));
    (0..levels).map(move |l| ((w >> l).max(1), (h >> l).max(1)))
}

impl TexFormat {
    /// Bytes of one `w × h` level (compressed: `ceil(w/4) · ceil(h/4)` blocks).
    pub fn level_bytes_rect(self, w: u32, h: u32) -> u64 {
        let (w, h) = (u64::from(w.max(1)), u64::from(h.max(1)));
        match self {
            TexFormat::Rgba8 => w * h * 4,
            _ => w.div_ceil(4) * h.div_ceil(4) * u64::from(self.bytes_per_block()),
        }
    }

    /// Bytes of a `w × h` image with its full chain ([`mip_extents`]); equals
    /// [`TexFormat::chain_bytes`] for `w == h`.
    pub fn chain_bytes_rect(self, w: u32, h: u32) -> u64 {
        mip_extents(w, h)
            .map(|(a, b)| self.level_bytes_rect(a, b))
            .sum()
    }
}

fn chain_err(format: TexFormat, w: u32, h: u32, expected: u64, got: usize) -> TexFormatError {
    TexFormatError::RectChainLength {
        format,
        width: w,
        height: h,
        expected,
        got: got as u64,
    }
}

/// The `w × h` RGBA8 level padded to whole 4×4 blocks periodically (texel `(x mod w, y mod h)`), and the
/// padded width.
fn pad_periodic(rgba: &[u8], w: u32, h: u32) -> (Vec<u8>, u32) {
    let (pw, ph) = (w.div_ceil(4) * 4, h.div_ceil(4) * 4);
    let (w, h, pwu) = (w as usize, h as usize, pw as usize);
    let mut out = vec![0u8; pwu * ph as usize * 4];
    for (y, row) in out.chunks_exact_mut(pwu * 4).enumerate() {
        for (x, t) in row.chunks_exact_mut(4).enumerate() {
            t.copy_from_slice(&rgba[((y % h) * w + x % w) * 4..][..4]);
        }
    }
    (out, pw)
}

/// A level of a `w × h` chain padded to whole 4×4 blocks as the chain stores it: square levels by edge
/// replication ([`pad_to_blocks`], borrowed when already whole), the others periodically; and the padded
/// width.
fn pad_level(rgba: &[u8], w: u32, h: u32) -> (Cow<'_, [u8]>, u32) {
    if w == h {
        pad_to_blocks(rgba, w)
    } else {
        let (padded, pw) = pad_periodic(rgba, w, h);
        (Cow::Owned(padded), pw)
    }
}

/// Encodes one `w × h` RGBA8 level (`rgba.len() == w·h·4`) into `format`, padding a side under 4
/// periodically. `w == h` is [`encode_level`].
pub fn encode_level_rect(format: TexFormat, rgba: &[u8], w: u32, h: u32, alpha: bool) -> Vec<u8> {
    if w == h {
        return encode_level(format, rgba, w, alpha);
    }
    if format == TexFormat::Rgba8 {
        return rgba.to_vec();
    }
    let (padded, pw) = pad_level(rgba, w, h);
    encode_padded(format, &padded, pw, alpha, None).0
}

/// Decodes one `w × h` level stored in `format` (`bytes.len() == format.level_bytes_rect(w, h)`) to
/// `w × h` RGBA8 (rows of 4×4 blocks in parallel, cropped to the level). RGBA8 is returned as is.
pub fn decode_level_rect(format: TexFormat, bytes: &[u8], w: u32, h: u32) -> Vec<u8> {
    if format == TexFormat::Rgba8 {
        return bytes.to_vec();
    }
    let (w, h) = (w.max(1), h.max(1));
    let (bw, bh) = (w.div_ceil(4) as usize, h.div_ceil(4) as usize);
    let bb = format.bytes_per_block() as usize;
    let pitch = bw * 16;
    let mut padded = vec![0u8; pitch * bh * 4];
    padded
        .par_chunks_mut(pitch * 4)
        .zip(bytes.par_chunks(bw * bb))
        .for_each(|(rows, blocks)| {
            for (bx, block) in blocks.chunks_exact(bb).enumerate() {
                let dst = &mut rows[bx * 16..];
                match format {
                    TexFormat::Bc1 => bcdec_rs::bc1(block, dst, pitch),
                    TexFormat::Bc3 => bcdec_rs::bc3(block, dst, pitch),
                    TexFormat::Bc7 => bcdec_rs::bc7(block, dst, pitch),
                    TexFormat::Rgba8 => {}
                }
            }
        });
    let (w, h) = (w as usize, h as usize);
    if w * 4 == pitch && h == bh * 4 {
        return padded;
    }
    let mut out = Vec::with_capacity(w * h * 4);
    for y in 0..h {
        out.extend_from_slice(&padded[y * pitch..][..w * 4]);
    }
    out
}

/// Encodes a full RGBA8 chain of a `w × h` image (`chain.len() == TexFormat::Rgba8.chain_bytes_rect(w,
/// h)`, levels as [`mip_extents`]) into `format`, measuring every level's error with the CPU decoder
/// over `channels` channels. `w == h` is [`super::encode_chain`].
pub fn encode_chain_rect(
    format: TexFormat,
    chain: &[u8],
    w: u32,
    h: u32,
    channels: usize,
) -> Result<Encoded, TexFormatError> {
    if w == h {
        return super::encode_chain(format, chain, w, channels);
    }
    let expected = TexFormat::Rgba8.chain_bytes_rect(w, h);
    if chain.len() as u64 != expected {
        return Err(chain_err(TexFormat::Rgba8, w, h, expected, chain.len()));
    }
    let mut offset = 0usize;
    let levels: Vec<&[u8]> = mip_extents(w, h)
        .map(|(a, b)| {
            let level = &chain[offset..offset + (a * b) as usize * 4];
            offset += level.len();
            level
        })
        .collect();
    encode_levels_rect(format, &levels, w, h, channels)
}

/// [`encode_chain_rect`] with the chain given level by level (`levels[i]`: the i-th level of
/// [`mip_extents`]`(w, h)`, RGBA8), so a caller whose level 0 lives in another buffer (an original stored
/// at its decoded size) need not copy it into one chain first. The same bytes and error as the flat
/// chain; square or not (a square level is padded by edge replication, as [`super::encode_chain`] does).
pub fn encode_levels_rect(
    format: TexFormat,
    levels: &[&[u8]],
    w: u32,
    h: u32,
    channels: usize,
) -> Result<Encoded, TexFormatError> {
    let extents: Vec<(u32, u32)> = mip_extents(w, h).collect();
    let whole = levels.len() == extents.len()
        && levels
            .iter()
            .zip(&extents)
            .all(|(l, &(a, b))| l.len() as u64 == u64::from(a) * u64::from(b) * 4);
    if !whole {
        let got = levels.iter().map(|l| l.len()).sum();
        let expected = TexFormat::Rgba8.chain_bytes_rect(w, h);
        return Err(chain_err(TexFormat::Rgba8, w, h, expected, got));
    }
    let mut out = Encoded {
        bytes: Vec::with_capacity(format.chain_bytes_rect(w, h) as usize),
        ..Encoded::default()
    };
    for (level, (a, b)) in levels.iter().zip(extents) {
        out.samples += u64::from(a * b) * channels as u64;
        if format == TexFormat::Rgba8 {
            out.bytes.extend_from_slice(level);
            continue;
        }
        let (enc, sse) = encode_level_measured(format, Cow::Borrowed(level), a, b, channels);
        out.sse += sse;
        out.bytes.extend_from_slice(&enc);
    }
    Ok(out)
}

/// One `w × h` RGBA8 level of a chain (`level.len() == w·h·4`) encoded into `format` as
/// [`encode_levels_rect`] encodes it, with its squared error over `channels` channels (0 for RGBA8, which
/// is stored as is: an owned level is returned without a copy).
pub fn encode_level_measured(
    format: TexFormat,
    level: Cow<'_, [u8]>,
    w: u32,
    h: u32,
    channels: usize,
) -> (Vec<u8>, u64) {
    if format == TexFormat::Rgba8 {
        return (level.into_owned(), 0);
    }
    let (padded, pw) = pad_level(&level, w, h);
    encode_padded(format, &padded, pw, channels == 4, Some((w, h, channels)))
}

/// Decodes a full chain of a `w × h` image stored in `format` (the first
/// `format.chain_bytes_rect(w, h)` bytes of `bytes`) to RGBA8, level 0 first.
pub fn decode_chain_rect(
    format: TexFormat,
    bytes: &[u8],
    w: u32,
    h: u32,
) -> Result<Vec<u8>, TexFormatError> {
    let expected = format.chain_bytes_rect(w, h);
    if (bytes.len() as u64) < expected {
        return Err(chain_err(format, w, h, expected, bytes.len()));
    }
    let mut out = Vec::with_capacity(TexFormat::Rgba8.chain_bytes_rect(w, h) as usize);
    let mut offset = 0usize;
    for (a, b) in mip_extents(w, h) {
        let len = format.level_bytes_rect(a, b) as usize;
        out.extend_from_slice(&decode_level_rect(
            format,
            &bytes[offset..offset + len],
            a,
            b,
        ));
        offset += len;
    }
    Ok(out)
}

/// The chain of the `s × s` layer (`s = max(w, h)`) that tiles a `w × h` chain stored in `format` at every
/// level (see the module doc): output block `(x, y)` of level `l` is stored block `(x mod bw, y mod bh)`,
/// `bw × bh` being the level's stored blocks (texels for RGBA8). Square chains are returned as they are.
/// Errors when `chain` is shorter than `format.chain_bytes_rect(w, h)`.
pub fn tile_chain_to_square(
    format: TexFormat,
    chain: &[u8],
    w: u32,
    h: u32,
) -> Result<Vec<u8>, TexFormatError> {
    let expected = format.chain_bytes_rect(w, h);
    if (chain.len() as u64) < expected {
        return Err(chain_err(format, w, h, expected, chain.len()));
    }
    if w == h {
        return Ok(chain[..expected as usize].to_vec());
    }
    let s = w.max(h);
    let (unit, bytes) = match format {
        TexFormat::Rgba8 => (1, 4usize),
        f => (4, f.bytes_per_block() as usize),
    };
    let mut out = Vec::with_capacity(format.chain_bytes(s) as usize);
    let mut offset = 0usize;
    for ((a, b), side) in mip_extents(w, h).zip(super::mip_sizes(s)) {
        let (bw, bh) = (a.div_ceil(unit) as usize, b.div_ceil(unit) as usize);
        let bs = side.div_ceil(unit) as usize;
        let level = &chain[offset..offset + bw * bh * bytes];
        offset += level.len();
        // Both sides are powers of two in units (or one unit), so a layer row is whole stored rows.
        for y in 0..bs {
            let row = &level[(y % bh) * bw * bytes..][..bw * bytes];
            for _ in 0..bs / bw {
                out.extend_from_slice(row);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> Vec<u8> {
        (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                [(x * 255 / w) as u8, (y * 255 / h) as u8, 60, 255]
            })
            .collect()
    }

    /// A full chain of `w × h` (each level a gradient of its own sides), level by level.
    fn gradient_levels(w: u32, h: u32) -> Vec<Vec<u8>> {
        mip_extents(w, h).map(|(a, b)| gradient(a, b)).collect()
    }

    #[test]
    fn levels_encode_as_their_flat_chain_and_bad_lengths_are_errors() {
        for (w, h) in [(16, 4), (8, 8), (6, 6), (1, 32), (64, 64)] {
            let levels = gradient_levels(w, h);
            let refs: Vec<&[u8]> = levels.iter().map(Vec::as_slice).collect();
            for f in TexFormat::ALL {
                let flat = encode_chain_rect(f, &levels.concat(), w, h, 4).unwrap();
                let split = encode_levels_rect(f, &refs, w, h, 4).unwrap();
                assert_eq!(split.bytes, flat.bytes, "{f:?} {w}×{h}");
                assert_eq!((split.sse, split.samples), (flat.sse, flat.samples));
            }
            // One level too few, and every level there with level 0 a texel short: errors naming the
            // whole chain's size.
            let mut short = refs.clone();
            short[0] = &refs[0][4..];
            for bad in [&refs[..refs.len() - 1], &short[..]] {
                let err = encode_levels_rect(TexFormat::Bc1, bad, w, h, 4).unwrap_err();
                assert!(
                    matches!(err, TexFormatError::RectChainLength { width, height, .. } if (width, height) == (w, h)),
                    "{err:?}"
                );
            }
        }
    }

    #[test]
    fn extents_and_sizes() {
        let e: Vec<_> = mip_extents(16, 4).collect();
        assert_eq!(e, [(16, 4), (8, 2), (4, 1), (2, 1), (1, 1)]);
        assert_eq!(
            TexFormat::Bc1.chain_bytes_rect(16, 4),
            (4 + 2 + 1 + 1 + 1) * 8
        );
        assert_eq!(
            TexFormat::Rgba8.chain_bytes_rect(16, 4),
            (64 + 16 + 4 + 2 + 1) * 4
        );
        for s in [1, 4, 64, 2048] {
            for f in TexFormat::ALL {
                assert_eq!(f.chain_bytes_rect(s, s), f.chain_bytes(s));
            }
        }
    }

    #[test]
    fn tiling_repeats_every_level_and_small_levels_are_periodic() {
        // A 16×4 chain: every layer level must equal the texture's level repeated (4 × down at level 0).
        let mut chain = Vec::new();
        for (a, b) in mip_extents(16, 4) {
            chain.extend(gradient(a, b));
        }
        for f in [TexFormat::Rgba8, TexFormat::Bc1, TexFormat::Bc7] {
            let enc = encode_chain_rect(f, &chain, 16, 4, 3).expect("encode");
            assert_eq!(enc.bytes.len() as u64, f.chain_bytes_rect(16, 4));
            let tiled = tile_chain_to_square(f, &enc.bytes, 16, 4).expect("tile");
            assert_eq!(tiled.len() as u64, f.chain_bytes(16));
            let texture = decode_chain_rect(f, &enc.bytes, 16, 4).expect("decode");
            let layer = super::super::decode_chain(f, &tiled, 16).expect("decode layer");
            let (mut to, mut lo) = (0usize, 0usize);
            for ((a, b), s) in mip_extents(16, 4).zip(super::super::mip_sizes(16)) {
                for y in 0..s {
                    for x in 0..s {
                        let want = &texture[to + (((y % b) * a + x % a) * 4) as usize..][..4];
                        let got = &layer[lo + ((y * s + x) * 4) as usize..][..4];
                        assert_eq!(want, got, "{f:?} level {s}: texel ({x}, {y})");
                    }
                }
                to += (a * b * 4) as usize;
                lo += (s * s * 4) as usize;
            }
        }
        assert!(tile_chain_to_square(TexFormat::Bc1, &[0; 8], 16, 4).is_err());
    }

    #[test]
    fn tall_textures_tile_across() {
        let mut chain = Vec::new();
        for (a, b) in mip_extents(4, 32) {
            chain.extend(gradient(a, b));
        }
        let enc = encode_chain_rect(TexFormat::Bc1, &chain, 4, 32, 3).expect("encode");
        let tiled = tile_chain_to_square(TexFormat::Bc1, &enc.bytes, 4, 32).expect("tile");
        let layer = super::super::decode_chain(TexFormat::Bc1, &tiled, 32).expect("decode");
        let texture = decode_chain_rect(TexFormat::Bc1, &enc.bytes, 4, 32).expect("decode");
        // Level 0: column x of the layer is column x mod 4 of the texture.
        for y in 0..32usize {
            for x in 0..32usize {
                assert_eq!(
                    &layer[(y * 32 + x) * 4..][..4],
                    &texture[(y * 4 + x % 4) * 4..][..4]
                );
            }
        }
        // The compression error of a well-behaved gradient stays small.
        assert!(super::super::psnr(enc.sse, enc.samples) > 30.0);
    }

    #[test]
    fn recorded_error_equals_an_independent_decode() {
        for (w, h) in [(16, 4), (4, 32), (8, 2), (64, 16)] {
            let mut chain = Vec::new();
            for (a, b) in mip_extents(w, h) {
                let mut level = gradient(a, b);
                // Noise in alpha and a channel, so every format has an error to record.
                for (i, p) in level.chunks_exact_mut(4).enumerate() {
                    p[1] ^= (i as u8).wrapping_mul(37);
                    p[3] = (i as u8).wrapping_mul(91);
                }
                chain.extend(level);
            }
            for f in [TexFormat::Bc1, TexFormat::Bc3, TexFormat::Bc7] {
                for channels in [3, 4] {
                    let enc = encode_chain_rect(f, &chain, w, h, channels).expect("encode");
                    let dec = decode_chain_rect(f, &enc.bytes, w, h).expect("decode");
                    let want = super::super::sse_rgba8(&chain, &dec, channels);
                    assert!(want > 0, "{f:?} {w}×{h}: a lossless encode tests nothing");
                    assert_eq!(enc.sse, want, "{f:?} {w}×{h} over {channels} channels");
                }
            }
        }
    }
}
