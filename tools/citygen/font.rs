//! A built-in 5×7 bitmap font for the digits 0–9, used to print building ids onto facades (paper §7: the
//! 300 Berlin photographs were labelled with identifiers to make 4,300 distinct textures).

/// Glyph width and height in font pixels.
pub const GLYPH_W: u32 = 5;
pub const GLYPH_H: u32 = 7;
/// Horizontal advance in font pixels (glyph plus one column of spacing).
pub const ADVANCE: u32 = GLYPH_W + 1;

/// Rows top to bottom; bit 4 is the leftmost column.
const DIGITS: [[u8; 7]; 10] = [
    [
        0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110,
    ],
    [
        0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110,
    ],
    [
        0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111,
    ],
    [
        0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110,
    ],
    [
        0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010,
    ],
    [
        0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110,
    ],
    [
        0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110,
    ],
    [
        0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000,
    ],
    [
        0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110,
    ],
    [
        0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100,
    ],
];

/// Whether font pixel `(col, row)` of digit `d` is set; false outside the glyph or for non-digits.
pub fn glyph_bit(d: u8, col: u32, row: u32) -> bool {
    if col >= GLYPH_W || row >= GLYPH_H {
        return false;
    }
    DIGITS
        .get(usize::from(d))
        .is_some_and(|g| g[row as usize] >> (GLYPH_W - 1 - col) & 1 == 1)
}

/// Size in image pixels of `text` (digits only) drawn at integer `scale`: `(width, height)`.
pub fn text_size(text: &str, scale: u32) -> (u32, u32) {
    let n = text.len() as u32;
    ((n * ADVANCE).saturating_sub(1) * scale, GLYPH_H * scale)
}

/// Whether image pixel `(x, y)`, relative to the top-left corner of `text` drawn at `scale`, is ink.
pub fn text_ink(text: &str, scale: u32, x: u32, y: u32) -> bool {
    let scale = scale.max(1);
    let (fx, fy) = (x / scale, y / scale);
    let i = (fx / ADVANCE) as usize;
    match text.as_bytes().get(i) {
        Some(c) if c.is_ascii_digit() => glyph_bit(c - b'0', fx % ADVANCE, fy),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyphs_are_distinct_and_nonempty() {
        let bits = |d: u8| -> Vec<bool> {
            (0..GLYPH_H)
                .flat_map(|r| (0..GLYPH_W).map(move |c| (c, r)))
                .map(|(c, r)| glyph_bit(d, c, r))
                .collect()
        };
        for a in 0..10 {
            assert!(
                bits(a).iter().filter(|b| **b).count() >= 7,
                "digit {a} too sparse"
            );
            for b in (a + 1)..10 {
                assert_ne!(bits(a), bits(b), "digits {a} and {b} identical");
            }
        }
    }

    #[test]
    fn text_layout_scales() {
        assert_eq!(text_size("4299", 3), ((4 * 6 - 1) * 3, 21));
        // Top row of "1" at scale 2: only font column 2 is set → image columns 4..6.
        let ink: Vec<bool> = (0..10).map(|x| text_ink("1", 2, x, 0)).collect();
        assert_eq!(
            ink,
            [
                false, false, false, false, true, true, false, false, false, false
            ]
        );
        // The spacing column between glyphs is never ink.
        assert!((0..14).all(|y| !text_ink("88", 2, 5 * 2, y)));
    }
}
