//! An inner atlas's stored levels from its children's stored levels (paper §5.1: an inner atlas is its
//! four children halved).
//!
//! With the 2×2 box filter, level `k` of an inner atlas of side `s` is its children's levels `k + 1` side
//! by side: a box never straddles a quadrant (`s` a power of two). Where every stored cell is encoded on
//! its own texels alone — an RGBA8 texel, a 4×4 block of BC1/BC3/BC7 (each block encoded and measured
//! independently, [`super::encode_level_measured`]) — and a cell fits a quadrant, the stored bytes of
//! that level are the children's cells rearranged, and its squared error their sum: the encoder need not
//! run again. The caller decides where that holds (no colour bleed, which is not per texel; the box
//! filter; no per-texture alpha rescaling) and falls back to encoding otherwise.

use super::TexFormat;

/// One stored (encoded) level: its bytes and their squared error ([`super::Encoded::sse`] of this level).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StoredLevel {
    pub bytes: Vec<u8>,
    pub sse: u64,
}

/// Side of the cells `format` stores independently, texels: 1 for RGBA8, 4 for the block formats.
pub fn cell_side(format: TexFormat) -> u32 {
    match format {
        TexFormat::Rgba8 => 1,
        TexFormat::Bc1 | TexFormat::Bc3 | TexFormat::Bc7 => 4,
    }
}

/// Stored bytes of one cell.
fn cell_bytes(format: TexFormat) -> usize {
    match format {
        TexFormat::Rgba8 => 4,
        _ => format.bytes_per_block() as usize,
    }
}

/// The stored level of side `2 · half` whose quadrant `q` (bit 0: right half, bit 1: lower half) is
/// `children[q]`, a stored level of side `half`, or where that is `None`, copies of `fill`, the stored
/// cell of the fill colour (one cell's bytes and error). `None` when `half` is not a whole number of
/// cells, or a child or `fill` has another length: the caller encodes the level instead.
pub fn combine_stored_quadrants(
    format: TexFormat,
    children: [Option<&StoredLevel>; 4],
    half: u32,
    fill: &StoredLevel,
) -> Option<StoredLevel> {
    let side = cell_side(format);
    if half == 0 || !half.is_multiple_of(side) {
        return None;
    }
    let cells = (half / side) as usize;
    let row = cells * cell_bytes(format);
    let fits = children
        .iter()
        .flatten()
        .all(|c| c.bytes.len() == row * cells);
    if !fits || fill.bytes.len() != cell_bytes(format) {
        return None;
    }
    let fill_row = fill.bytes.repeat(cells);
    let mut bytes = Vec::with_capacity(4 * row * cells);
    for r in 0..2 * cells {
        let (lower, cr) = (r / cells, r % cells);
        for right in 0..2 {
            match children[right + 2 * lower] {
                Some(c) => bytes.extend_from_slice(&c.bytes[cr * row..][..row]),
                None => bytes.extend_from_slice(&fill_row),
            }
        }
    }
    let missing = children.iter().filter(|c| c.is_none()).count() as u64;
    let sse = children.iter().flatten().map(|c| c.sse).sum::<u64>()
        + missing * (cells * cells) as u64 * fill.sse;
    Some(StoredLevel { bytes, sse })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texfmt::encode_level_measured;

    /// RGBA8 texels of side `s`, a hash of position and `seed`; opaque.
    fn texels(s: u32, seed: u32) -> Vec<u8> {
        (0..s * s)
            .flat_map(|i| {
                let x = (i ^ seed.wrapping_mul(0x9e37_79b9)).wrapping_mul(2_654_435_761);
                let [r, g, b, _] = x.rotate_left(11).to_le_bytes();
                [r, g, b, 255]
            })
            .collect()
    }

    /// The level of side `2·half` made of the four quadrants' texels (`None`: `fill` everywhere).
    fn joined(quads: &[Option<Vec<u8>>; 4], half: u32, fill: [u8; 4]) -> Vec<u8> {
        let (h, s) = (half as usize, 2 * half as usize);
        let mut out = vec![0u8; s * s * 4];
        for y in 0..s {
            for x in 0..s {
                let q = usize::from(x >= h) + 2 * usize::from(y >= h);
                let t = match &quads[q] {
                    Some(img) => &img[((y % h) * h + x % h) * 4..][..4],
                    None => &fill[..],
                };
                out[(y * s + x) * 4..][..4].copy_from_slice(t);
            }
        }
        out
    }

    #[test]
    fn combined_stored_quadrants_are_the_encoded_joined_level() {
        // Every format, quadrant sides of 1–3 cells, every pattern of missing children: the same bytes
        // and error as encoding the joined level.
        let fill = [128, 128, 128, 255];
        for format in [
            TexFormat::Rgba8,
            TexFormat::Bc1,
            TexFormat::Bc3,
            TexFormat::Bc7,
        ] {
            let channels = if format == TexFormat::Bc1 { 3 } else { 4 };
            let c = cell_side(format);
            let fill_cell = {
                let t: Vec<u8> = fill.repeat((c * c) as usize);
                let (bytes, sse) = encode_level_measured(format, t.into(), c, c, channels);
                StoredLevel { bytes, sse }
            };
            for half in [c, 2 * c, 3 * c] {
                for present in 0..16u32 {
                    let quads: [Option<Vec<u8>>; 4] = std::array::from_fn(|q| {
                        (present >> q & 1 == 1).then(|| texels(half, q as u32 + 7 * half))
                    });
                    let stored: Vec<Option<StoredLevel>> = quads
                        .iter()
                        .map(|t| {
                            t.as_ref().map(|t| {
                                let (bytes, sse) =
                                    encode_level_measured(format, t.into(), half, half, channels);
                                StoredLevel { bytes, sse }
                            })
                        })
                        .collect();
                    let refs = std::array::from_fn(|q| stored[q].as_ref());
                    let got = combine_stored_quadrants(format, refs, half, &fill_cell)
                        .expect("whole cells");
                    let whole = joined(&quads, half, fill);
                    let (bytes, sse) =
                        encode_level_measured(format, whole.into(), 2 * half, 2 * half, channels);
                    assert_eq!(
                        got,
                        StoredLevel { bytes, sse },
                        "{format:?} half {half} present {present:04b}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_quadrant_under_one_cell_or_of_another_length_is_refused() {
        let cell = StoredLevel {
            bytes: vec![0; 8],
            sse: 0,
        };
        assert_eq!(
            combine_stored_quadrants(TexFormat::Bc1, [None; 4], 2, &cell),
            None
        );
        assert_eq!(
            combine_stored_quadrants(TexFormat::Bc1, [None; 4], 0, &cell),
            None
        );
        let short = StoredLevel {
            bytes: vec![0; 7],
            sse: 0,
        };
        assert_eq!(
            combine_stored_quadrants(TexFormat::Bc1, [Some(&short), None, None, None], 4, &cell),
            None
        );
        assert_eq!(
            combine_stored_quadrants(TexFormat::Bc1, [None; 4], 4, &short),
            None
        );
        let four = combine_stored_quadrants(TexFormat::Bc1, [None; 4], 4, &cell).unwrap();
        assert_eq!(four.bytes.len(), 4 * 8);
    }
}
