//! Magnifying an original texture to its stored power-of-two sides with a Catmull-Rom cubic.
//!
//! An original of `192 × 192` is stored at `256 × 256` ([`crate::preprocess::originals::original_extent`])
//! and then sampled bilinearly by the GPU. Resampled bilinearly first, it is blurred twice: on a patterned
//! texture the stored copy, drawn, was 32.3 dB from the 192² texture drawn directly (84 dB for the tree's
//! own atlas of it), and original mode and every close view drew that blur. The Catmull-Rom cubic
//! (`a = −0.5`) interpolates (it passes through every source texel centre, so a side kept equal is copied
//! exactly) and keeps the texture's detail up to its Nyquist rate (section "Originals" of the design
//! document has the measured gain).
//!
//! The cubic's lobes are negative, so a hard edge overshoots: every result is clamped into the
//! premultiplied domain (alpha to `[0, 1]`, each colour to `[0, alpha]`). Taps beyond an edge follow the
//! texture's wrap modes, so a repeating texture stays seamless.

use super::{ImageOpsError, LinearImage, wrap_index};
use crate::scene::Wrap;
use rayon::prelude::*;

/// The four Catmull-Rom weights of texels `i − 1 … i + 2` at fraction `t ∈ [0, 1)` past texel `i`; they
/// sum to 1, and `t = 0` gives `[0, 1, 0, 0]` exactly.
fn weights(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// The taps of `out` destination texels over `src` source texels along one axis (texel centres aligned
/// as in [`super::draw_rect`]: destination centre `(x + 0.5) / out` is source position `· src − 0.5`).
fn axis_taps(src: u32, out: u32, wrap: Wrap) -> Vec<[(u32, f32); 4]> {
    (0..out)
        .map(|x| {
            let pos = (f64::from(x) + 0.5) * f64::from(src) / f64::from(out) - 0.5;
            let i = pos.floor();
            let w = weights(pos - i);
            std::array::from_fn(|k| {
                let at = wrap_index(i as i64 + k as i64 - 1, src, wrap);
                (at, w[k] as f32)
            })
        })
        .collect()
}

/// A texel clamped into the premultiplied domain: alpha to `[0, 1]`, colour to `[0, alpha]`.
fn premultiplied(t: [f32; 4]) -> [f32; 4] {
    let a = t[3].clamp(0.0, 1.0);
    [
        t[0].clamp(0.0, a),
        t[1].clamp(0.0, a),
        t[2].clamp(0.0, a),
        a,
    ]
}

/// `src` (premultiplied linear RGBA) magnified to `w × h`, with `w ≥ src.width` and `h ≥ src.height`:
/// rows first (to `w × src.height`), then columns, each a Catmull-Rom cubic whose taps follow `wrap`.
pub fn magnify_cubic(
    src: &LinearImage,
    w: u32,
    h: u32,
    wrap: [Wrap; 2],
) -> Result<LinearImage, ImageOpsError> {
    src.check()?;
    if src.width == 0 || src.height == 0 || w < src.width || h < src.height {
        return Err(ImageOpsError::ZeroSize {
            size: src.width.min(src.height).min(w).min(h),
        });
    }
    let xs = axis_taps(src.width, w, wrap[0]);
    let ys = axis_taps(src.height, h, wrap[1]);
    let sw = src.width as usize;
    let mut wide = vec![[0.0f32; 4]; w as usize * src.height as usize];
    wide.par_chunks_mut(w as usize)
        .zip(src.data.par_chunks(sw))
        .for_each(|(out, row)| {
            for (d, taps) in out.iter_mut().zip(&xs) {
                let mut acc = [0.0f32; 4];
                for &(i, wt) in taps {
                    let t = row[i as usize];
                    for c in 0..4 {
                        acc[c] += wt * t[c];
                    }
                }
                *d = acc;
            }
        });
    let mut data = vec![[0.0f32; 4]; w as usize * h as usize];
    let wu = w as usize;
    data.par_chunks_mut(wu)
        .zip(ys.par_iter())
        .for_each(|(out, taps)| {
            for (x, d) in out.iter_mut().enumerate() {
                let mut acc = [0.0f32; 4];
                for &(i, wt) in taps {
                    let t = wide[i as usize * wu + x];
                    for c in 0..4 {
                        acc[c] += wt * t[c];
                    }
                }
                *d = premultiplied(acc);
            }
        });
    Ok(LinearImage {
        width: w,
        height: h,
        data,
    })
}

/// `src` magnified to `w × h` by whole factors (`w` and `h` multiples of its sides): each texel repeated
/// `w / src.width × h / src.height` times. The renderer's bilinear filter then shows the source's texels
/// exactly at their centres and its bilinear mix midway between them, as the source drawn itself would
/// (a 4 × 2 palette stored at 4 × 4 through the bilinear footprint filter blended its two rows: the
/// palette hunt of session 29). Sides below [`crate::model::MIN_ORIGINAL_CLASS`] (1 and 2) grow so.
pub(super) fn magnify_replicate(
    src: &LinearImage,
    w: u32,
    h: u32,
) -> Result<LinearImage, ImageOpsError> {
    src.check()?;
    if src.width == 0
        || src.height == 0
        || !w.is_multiple_of(src.width)
        || !h.is_multiple_of(src.height)
    {
        return Err(ImageOpsError::ZeroSize {
            size: src.width.min(src.height).min(w).min(h),
        });
    }
    let (kx, ky) = ((w / src.width) as usize, (h / src.height) as usize);
    let sw = src.width as usize;
    let data = (0..h as usize)
        .flat_map(|y| (0..w as usize).map(move |x| (x, y)))
        .map(|(x, y)| src.data[(y / ky) * sw + x / kx])
        .collect();
    Ok(LinearImage {
        width: w,
        height: h,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_factors_repeat_each_texel() {
        // A 4 × 2 palette stored at 4 × 4: each row twice, never a blend of the two.
        let src = image(4, 2, |x, y| [x as f32 / 4.0, y as f32, 0.5, 1.0]);
        let out = magnify_replicate(&src, 4, 4).unwrap();
        for y in 0..4 {
            for x in 0..4 {
                assert_eq!(out.data[y * 4 + x], src.data[(y / 2) * 4 + x], "({x}, {y})");
            }
        }
        // 1 × 1 to 4 × 4: the one colour everywhere.
        let one = image(1, 1, |_, _| [0.2, 0.4, 0.6, 1.0]);
        let out = magnify_replicate(&one, 4, 4).unwrap();
        assert!(out.data.iter().all(|t| *t == one.data[0]));
        assert!(magnify_replicate(&src, 6, 4).is_err(), "not a whole factor");
    }

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 4]) -> LinearImage {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y));
        LinearImage {
            width: w,
            height: h,
            data: data.collect(),
        }
    }

    #[test]
    fn weights_sum_to_one_and_interpolate_at_texel_centres() {
        assert_eq!(weights(0.0), [0.0, 1.0, 0.0, 0.0]);
        for k in 0..100 {
            let s: f64 = weights(k as f64 / 100.0).iter().sum();
            assert!((s - 1.0).abs() < 1e-12, "t = {}: sum {s}", k as f64 / 100.0);
        }
    }

    #[test]
    fn an_axis_kept_equal_is_copied_exactly() {
        let src = image(8, 6, |x, y| [x as f32 / 16.0, y as f32 / 16.0, 0.1, 0.5]);
        let out = magnify_cubic(&src, 8, 12, [Wrap::Repeat; 2]).unwrap();
        // Rows: same width, so each row's texels are the source's; the columns interpolate.
        for y in 0..12 {
            for x in 0..8 {
                assert_eq!(out.data[y * 8 + x][0], x as f32 / 16.0);
            }
        }
        let same = magnify_cubic(&src, 8, 6, [Wrap::ClampToEdge; 2]).unwrap();
        assert_eq!(same.data, src.data);
    }

    /// A smooth periodic signal sampled at 48 texels, magnified to 64: the cubic stays within 1 % of the
    /// signal at every destination centre, where linear interpolation is off by ~2.3 % (a level the
    /// renderer's bilinear filter then blurs a second time).
    #[test]
    fn a_smooth_repeating_signal_is_reconstructed_closer_than_linear() {
        let f = |u: f64| 0.5 + 0.4 * (std::f64::consts::TAU * 5.0 * u).sin();
        let src = image(48, 1, |x, _| {
            let v = f((f64::from(x) + 0.5) / 48.0) as f32;
            [v, v, v, 1.0]
        });
        let out = magnify_cubic(&src, 64, 1, [Wrap::Repeat; 2]).unwrap();
        let (mut cubic, mut linear) = (0.0f64, 0.0f64);
        for x in 0..64u32 {
            let u = (f64::from(x) + 0.5) / 64.0;
            cubic = cubic.max((f64::from(out.data[x as usize][0]) - f(u)).abs());
            let pos = u * 48.0 - 0.5;
            let (i, t) = (pos.floor(), pos - pos.floor());
            let at = |k: f64| f(((k.rem_euclid(48.0)) + 0.5) / 48.0);
            linear = linear.max(((1.0 - t) * at(i) + t * at(i + 1.0) - f(u)).abs());
        }
        assert!(cubic < 0.01, "cubic error {cubic}");
        assert!(linear > 2.0 * cubic, "linear {linear}, cubic {cubic}");
    }

    #[test]
    fn hard_edges_stay_premultiplied_and_repeats_stay_seamless() {
        // Opaque black and white stripes beside transparent texels.
        let src = image(6, 6, |x, _| match x {
            0 | 1 => [1.0, 1.0, 1.0, 1.0],
            2 | 3 => [0.0, 0.0, 0.0, 1.0],
            _ => [0.0; 4],
        });
        let out = magnify_cubic(&src, 16, 16, [Wrap::Repeat, Wrap::ClampToEdge]).unwrap();
        for t in &out.data {
            assert!((0.0..=1.0).contains(&t[3]), "{t:?}");
            assert!(t[..3].iter().all(|&c| (0.0..=t[3]).contains(&c)), "{t:?}");
        }
        // Repeat: the texture tiled twice and magnified is the magnified texture tiled twice.
        let twice = image(12, 6, |x, y| src.data[(y * 6 + x % 6) as usize]);
        let big = magnify_cubic(&twice, 32, 16, [Wrap::Repeat, Wrap::ClampToEdge]).unwrap();
        for y in 0..16 {
            for x in 0..32 {
                let a = big.data[y * 32 + x];
                let b = out.data[y * 16 + x % 16];
                assert!(
                    a.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-6),
                    "{x},{y}"
                );
            }
        }
    }
}
