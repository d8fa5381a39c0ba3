//! `report::metrics`: PSNR against hand-computed values, SSIM against a straightforward (non-separable,
//! window-by-window) implementation written here from Wang et al. 2004, the density helpers and the
//! Pareto front on hand cases.

use atlastree::report::ReportError;
use atlastree::report::metrics::{
    Histogram, PSNR_CAP_DB, Share, magnified_share, pareto_front, psnr, psnr_masked, ssim,
};

/// A deterministic RGBA8 test picture with structure at several scales (values within 10..=210, so a
/// shift of +40 never clips). Alpha varies and must not matter.
fn texture(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity((w * h * 4) as usize);
    let mut state = 0x2545_f491_u32;
    for y in 0..h {
        for x in 0..w {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = (state % 41) as f64 - 20.0;
            let (fx, fy) = (x as f64, y as f64);
            let wave = 60.0 * (fx * 0.21).sin() * (fy * 0.13).cos();
            let check = if (x / 8 + y / 8) % 2 == 0 {
                30.0
            } else {
                -30.0
            };
            let base = (110.0 + wave + check + noise).clamp(10.0, 210.0);
            v.push(base as u8);
            v.push((base * 0.8 + 20.0) as u8);
            v.push((210.0 - base * 0.9).clamp(10.0, 210.0) as u8);
            v.push((x * 7 + y) as u8);
        }
    }
    v
}

/// Adds `d` to R, G and B (alpha untouched).
fn shifted(img: &[u8], d: u8) -> Vec<u8> {
    img.chunks_exact(4)
        .flat_map(|p| [p[0] + d, p[1] + d, p[2] + d, p[3]])
        .collect()
}

/// Box blur of radius `r` of R, G, B (edge pixels clamped); alpha copied.
fn box_blur(img: &[u8], w: u32, h: u32, r: i64) -> Vec<u8> {
    let (w, h) = (w as i64, h as i64);
    let mut out = img.to_vec();
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0u32;
                let mut n = 0u32;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (sx, sy) = ((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1));
                        sum += img[((sy * w + sx) * 4 + c) as usize] as u32;
                        n += 1;
                    }
                }
                out[((y * w + x) * 4 + c) as usize] = ((sum + n / 2) / n) as u8;
            }
        }
    }
    out
}

/// SSIM as the paper writes it: for every 11×11 window fully inside the image, Gaussian-weighted
/// (σ = 1.5, weights normalised over the 2-D window) means, variances and covariance of the BT.601 luma,
/// SSIM = (2μxμy + C1)(2σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2)), averaged over the windows.
fn reference_ssim(a: &[u8], b: &[u8], w: usize, h: usize) -> f64 {
    let luma = |img: &[u8], x: usize, y: usize| {
        let p = &img[(y * w + x) * 4..];
        0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64
    };
    let mut weights = [[0.0f64; 11]; 11];
    let mut total = 0.0;
    for (j, row) in weights.iter_mut().enumerate() {
        for (i, wgt) in row.iter_mut().enumerate() {
            let (dx, dy) = (i as f64 - 5.0, j as f64 - 5.0);
            *wgt = (-(dx * dx + dy * dy) / (2.0 * 1.5 * 1.5)).exp();
            total += *wgt;
        }
    }
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let mut sum = 0.0;
    let mut count = 0usize;
    for y0 in 0..=h - 11 {
        for x0 in 0..=w - 11 {
            let (mut mx, mut my) = (0.0, 0.0);
            for (j, row) in weights.iter().enumerate() {
                for (i, wgt) in row.iter().enumerate() {
                    let wgt = wgt / total;
                    mx += wgt * luma(a, x0 + i, y0 + j);
                    my += wgt * luma(b, x0 + i, y0 + j);
                }
            }
            let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
            for (j, row) in weights.iter().enumerate() {
                for (i, wgt) in row.iter().enumerate() {
                    let wgt = wgt / total;
                    let (dx, dy) = (luma(a, x0 + i, y0 + j) - mx, luma(b, x0 + i, y0 + j) - my);
                    vx += wgt * dx * dx;
                    vy += wgt * dy * dy;
                    cxy += wgt * dx * dy;
                }
            }
            sum += ((2.0 * mx * my + c1) * (2.0 * cxy + c2))
                / ((mx * mx + my * my + c1) * (vx + vy + c2));
            count += 1;
        }
    }
    sum / count as f64
}

#[test]
fn psnr_of_identical_frames_is_the_cap() {
    let a = texture(37, 23);
    assert_eq!(psnr(&a, &a, 37, 23).unwrap(), PSNR_CAP_DB);
    // Alpha is ignored: different alpha, same RGB.
    let mut b = a.clone();
    b.iter_mut()
        .skip(3)
        .step_by(4)
        .for_each(|x| *x = x.wrapping_add(99));
    assert_eq!(psnr(&a, &b, 37, 23).unwrap(), PSNR_CAP_DB);
}

#[test]
fn psnr_of_known_noise_matches_hand_computation() {
    // 2×2 frame: pixel 0 R +3, pixel 1 G −4, pixel 2 B +12, pixel 3 equal; alpha differs everywhere.
    let a = [
        10, 20, 30, 255, 40, 50, 60, 255, 70, 80, 90, 255, 100, 110, 120, 255,
    ];
    let b = [
        13, 20, 30, 0, 40, 46, 60, 1, 70, 80, 102, 2, 100, 110, 120, 3,
    ];
    // SSE = 3² + 4² + 12² = 169 over 12 values: MSE = 169/12, PSNR = 10·log10(255² · 12 / 169).
    let expected = 10.0 * (255.0f64 * 255.0 * 12.0 / 169.0).log10();
    assert!((expected - 36.643_7).abs() < 1e-4, "hand value {expected}");
    let got = psnr(&a, &b, 2, 2).unwrap();
    assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
    assert_eq!(psnr(&b, &a, 2, 2).unwrap(), got);

    // Uniform error of 1 in every channel: MSE 1, PSNR = 20·log10(255) = 48.1308 dB.
    let c = texture(16, 16);
    let d = shifted(&c, 1);
    let got = psnr(&c, &d, 16, 16).unwrap();
    assert!((got - 20.0 * 255f64.log10()).abs() < 1e-12);
    assert!((got - 48.130_8).abs() < 1e-4);
}

#[test]
fn psnr_masked_counts_only_masked_pixels() {
    let a = [0u8, 0, 0, 255, 0, 0, 0, 255];
    let b = [0u8, 0, 0, 255, 200, 200, 200, 255];
    let (p, n) = psnr_masked(&a, &b, 2, 1, &[true, false]).unwrap();
    assert_eq!((p, n), (PSNR_CAP_DB, 1));
    // Nothing masked is nothing measured, not a perfect frame.
    let (p, n) = psnr_masked(&a, &b, 2, 1, &[false, false]).unwrap();
    assert!(p.is_nan() && n == 0);
    let (p, n) = psnr_masked(&a, &b, 2, 1, &[true, true]).unwrap();
    // SSE = 3 · 200² over 6 values: MSE 20,000.
    assert!((p - 10.0 * (65025.0f64 / 20_000.0).log10()).abs() < 1e-12);
    assert_eq!(n, 2);
    assert!(matches!(
        psnr_masked(&a, &b, 2, 1, &[true]),
        Err(ReportError::Length {
            len: 1,
            expected: 2,
            ..
        })
    ));
}

#[test]
fn metrics_reject_buffers_of_the_wrong_size() {
    let a = texture(16, 16);
    assert!(matches!(
        psnr(&a, &a[..a.len() - 4], 16, 16),
        Err(ReportError::FrameSize {
            len: 1020,
            expected: 1024,
            ..
        })
    ));
    assert!(matches!(
        ssim(&a, &a, 16, 15),
        Err(ReportError::FrameSize { .. })
    ));
    let small = texture(10, 30);
    assert!(matches!(
        ssim(&small, &small, 10, 30),
        Err(ReportError::FrameTooSmall {
            width: 10,
            height: 30,
            window: 11
        })
    ));
}

#[test]
fn ssim_of_identical_frames_is_one() {
    let a = texture(64, 48);
    let s = ssim(&a, &a, 64, 48).unwrap();
    assert!((s - 1.0).abs() < 1e-12, "{s}");
    // Exactly the window size: one window.
    let b = texture(11, 11);
    assert!((ssim(&b, &b, 11, 11).unwrap() - 1.0).abs() < 1e-12);
}

#[test]
fn ssim_is_symmetric() {
    let a = texture(64, 48);
    let b = box_blur(&a, 64, 48, 1);
    let (ab, ba) = (ssim(&a, &b, 64, 48).unwrap(), ssim(&b, &a, 64, 48).unwrap());
    assert_eq!(ab, ba);
    assert!(ab < 0.99, "blurred texture should differ: {ab}");
}

#[test]
fn ssim_matches_the_non_separable_reference() {
    let (w, h) = (53u32, 41u32);
    let a = texture(w, h);
    // A constant shift changes only the luminance term.
    for d in [5u8, 40] {
        let b = shifted(&a, d);
        let got = ssim(&a, &b, w, h).unwrap();
        let want = reference_ssim(&a, &b, w as usize, h as usize);
        assert!((got - want).abs() < 1e-6, "shift {d}: {got} vs {want}");
        assert!(got < 1.0);
    }
    // And a structural change.
    let b = box_blur(&a, w, h, 2);
    let got = ssim(&a, &b, w, h).unwrap();
    let want = reference_ssim(&a, &b, w as usize, h as usize);
    assert!((got - want).abs() < 1e-6, "blur: {got} vs {want}");
}

#[test]
fn ssim_decreases_with_blur_strength() {
    let (w, h) = (96u32, 72u32);
    let a = texture(w, h);
    let scores: Vec<f64> = (1..=4)
        .map(|r| ssim(&a, &box_blur(&a, w, h, r), w, h).unwrap())
        .collect();
    assert!(scores[0] < 1.0);
    for p in scores.windows(2) {
        assert!(p[1] < p[0], "SSIM by blur radius 1..4: {scores:?}");
    }
}

#[test]
fn magnified_share_counts_drawn_pixels_below_the_target() {
    let d = [0.25f32, 0.5, 0.99, 1.0, 1.5, 4.0, f32::NAN, -1.0];
    assert_eq!(magnified_share(&d, 1.0), Share { hit: 3, drawn: 6 });
    assert_eq!(magnified_share(&d, 1.0).fraction(), 0.5);
    assert_eq!(magnified_share(&d, 0.25), Share { hit: 0, drawn: 6 });
    assert_eq!(magnified_share(&[f32::NAN], 1.0).fraction(), 0.0);
}

#[test]
fn log2_histogram_has_fixed_power_of_two_edges() {
    let d = [
        0.0f32,
        0.1,
        0.25,
        0.3,
        0.5,
        1.0,
        1.99,
        2.0,
        3.9,
        4.0,
        100.0,
        f32::INFINITY,
        f32::NAN,
        -2.0,
    ];
    let h = Histogram::log2(&d, -2, 2);
    assert_eq!(h.edges, vec![0.25, 0.5, 1.0, 2.0, 4.0]);
    // [¼,½): 0.25 0.3; [½,1): 0.5; [1,2): 1.0 1.99; [2,4): 2.0 3.9.
    assert_eq!(h.counts, vec![2, 1, 2, 2]);
    assert_eq!((h.below, h.above, h.skipped), (2, 3, 2));
    assert_eq!(h.total(), 12);
    let (labels, values) = h.bars();
    assert_eq!(labels, vec!["<2⁻²", "2⁻²", "2⁻¹", "2⁰", "2¹", "≥2²"]);
    let expect = [2.0, 2.0, 1.0, 2.0, 2.0, 3.0].map(|c| c / 12.0);
    assert_eq!(values, expect.to_vec());
}

#[test]
fn pareto_front_on_hand_cases() {
    assert!(pareto_front(&[]).is_empty());
    let pts = [
        (1.0, 0.5),      // 0 front
        (2.0, 0.7),      // 1 front
        (2.0, 0.6),      // 2 dominated by 1 (same cost, less accurate)
        (3.0, 0.7),      // 3 dominated by 1 (same accuracy, dearer)
        (0.5, 0.1),      // 4 front (cheapest)
        (4.0, 0.9),      // 5 front
        (4.0, 0.9),      // 6 equal to 5: kept
        (f64::NAN, 1.0), // 7 never
        (5.0, 0.85),     // 8 dominated by 5
        (0.5, 0.05),     // 9 dominated by 4
    ];
    assert_eq!(pareto_front(&pts), vec![4, 0, 1, 5, 6]);
    // A single point, and a chain where each point is better and dearer.
    assert_eq!(pareto_front(&[(3.0, 1.0)]), vec![0]);
    assert_eq!(
        pareto_front(&[(3.0, 3.0), (1.0, 1.0), (2.0, 2.0)]),
        vec![1, 2, 0]
    );
    // One point dominating all others.
    assert_eq!(
        pareto_front(&[(2.0, 1.0), (1.0, 5.0), (3.0, 4.0), (1.0, 2.0)]),
        vec![1]
    );
}
