//! The sRGB transfer functions in f64 (IEC 61966-2-1), where exactness matters more than speed: the
//! supersampled reference's box filter ([`crate::report::supersample`]) and the rects' means
//! ([`crate::texfmt::rect_means`]). The build's per-texel conversions are f32 tables
//! (`preprocess::image_ops::srgb`).

/// Linear value of an sRGB-encoded 8-bit channel.
pub fn srgb8_to_linear(c: u8) -> f64 {
    let v = f64::from(c) / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB 8-bit code of a linear value in `[0, 1]` (clamped; NaN → 0), rounded in the encoded domain.
pub fn linear_to_srgb8(v: f64) -> u8 {
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    let e = if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transfer_functions_round_trip_every_code() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(c)), c);
        }
        assert_eq!(
            (
                linear_to_srgb8(f64::NAN),
                linear_to_srgb8(-1.0),
                linear_to_srgb8(2.0)
            ),
            (0, 0, 255)
        );
    }
}
