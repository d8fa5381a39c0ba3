//! The CPU twin of the supersampled reference's downsample: box means in linear light, exact on known
//! blocks; and the `--reference` values `render` and `sweep` accept.

use atlastree::render::reference::Reference;
use atlastree::report::supersample::{box_downsample_linear, linear_to_srgb8, srgb8_to_linear};

#[test]
fn box_means_are_taken_in_linear_light() {
    // 4×2 → 2×1 with factor 2: a black/white block and a uniform grey block; alpha averaged as is.
    let px = |v: u8, a: u8| [v, v, v, a];
    let rows = [
        [px(0, 255), px(255, 255), px(90, 255), px(90, 0)],
        [px(255, 255), px(0, 255), px(90, 255), px(90, 0)],
    ];
    let src: Vec<u8> = rows.iter().flatten().flatten().copied().collect();
    let out = box_downsample_linear(&src, 4, 2, 2).unwrap();
    // Half black, half white: linear 0.5 → sRGB 188 (an average of codes would give 128).
    assert_eq!(&out[..4], &[188, 188, 188, 255]);
    assert_eq!(&out[4..], &[90, 90, 90, 128]);
    // Factor 1 is the identity on every code.
    let all: Vec<u8> = (0..=255u8).flat_map(|v| [v, v, v, v]).collect();
    assert_eq!(box_downsample_linear(&all, 256, 1, 1).unwrap(), all);
    for v in 0..=255u8 {
        assert_eq!(linear_to_srgb8(srgb8_to_linear(v)), v);
    }
    // Sides the factor does not divide, and a buffer of the wrong size, are errors.
    assert!(box_downsample_linear(&src, 4, 2, 3).is_err());
    assert!(box_downsample_linear(&src[..12], 4, 2, 2).is_err());
}

#[test]
fn reference_values_parse() {
    assert_eq!("original".parse(), Ok(Reference::Original));
    assert_eq!("supersampled".parse(), Ok(Reference::Supersampled(4)));
    assert_eq!("supersampled:2".parse(), Ok(Reference::Supersampled(2)));
    for bad in [
        "supersampled:0",
        "supersampled:9",
        "supersampled:x",
        "truth",
        "",
    ] {
        assert!(bad.parse::<Reference>().is_err(), "{bad}");
    }
    assert_eq!(Reference::Supersampled(3).name(), "supersampled:3");
}
