//! The supersampled reference's box filter on the CPU: the twin of `shaders/downsample.wgsl`
//! ([`crate::render::reference`]), for tests and for frames read back at full size. Each output pixel is
//! the mean of an S × S block of the source in linear light: colour channels decoded from sRGB, averaged,
//! encoded again (rounded); alpha (stored linear) averaged as is.

use super::ReportError;

pub use crate::util::srgb::{linear_to_srgb8, srgb8_to_linear};

/// `rgba` (`width × height` sRGB RGBA8, rows top to bottom) box-filtered by `factor` in linear light:
/// `(width / factor) × (height / factor)` pixels. Errors: a buffer of the wrong size, or sides that
/// `factor` (≥ 1) does not divide.
pub fn box_downsample_linear(
    rgba: &[u8],
    width: u32,
    height: u32,
    factor: u32,
) -> Result<Vec<u8>, ReportError> {
    let expected = width as usize * height as usize * 4;
    if rgba.len() != expected {
        return Err(ReportError::FrameSize {
            what: "box_downsample_linear: source",
            len: rgba.len(),
            width,
            height,
            expected,
        });
    }
    if factor == 0 || !width.is_multiple_of(factor) || !height.is_multiple_of(factor) {
        return Err(ReportError::Length {
            what: "box_downsample_linear: a side not divisible by the factor",
            len: width.max(height) as usize,
            expected: factor as usize,
        });
    }
    let (w, h, s) = (width / factor, height / factor, factor as usize);
    let lut: Vec<f64> = (0..=255u8).map(srgb8_to_linear).collect();
    let n = (s * s) as f64;
    let mut out = Vec::with_capacity(w as usize * h as usize * 4);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let mut sum = [0.0f64; 4];
            for dy in 0..s {
                let row = (y * s + dy) * width as usize;
                for dx in 0..s {
                    let p = (row + x * s + dx) * 4;
                    for c in 0..3 {
                        sum[c] += lut[rgba[p + c] as usize];
                    }
                    sum[3] += f64::from(rgba[p + 3]) / 255.0;
                }
            }
            for v in &sum[..3] {
                out.push(linear_to_srgb8(v / n));
            }
            out.push((sum[3] / n * 255.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    Ok(out)
}
