//! Unit tests of [`super`] (`area.rs`).

use super::*;

#[test]
fn ranges_widen_to_whole_source_texels() {
    const L: RectWrap = RectWrap::Linear;
    // Off the grid: outward to texel edges (64 texels: 0.1 → 6.4 → 6, 0.6 → 38.4 → 39).
    assert_eq!(on_source_grid(0.1, 0.6, 64, L), (6.0 / 64.0, 39.0 / 64.0));
    // On the grid, or one f32 step past it: unchanged, not a texel wider.
    assert_eq!(on_source_grid(0.125, 0.625, 64, L), (0.125, 0.625));
    let past = f64::from(0.5f32 + f32::EPSILON * 0.5);
    assert!(past > 0.5);
    assert_eq!(on_source_grid(0.0, past, 64, L), (0.0, 0.5));
    assert_eq!(
        on_source_grid(-f64::from(f32::EPSILON), 1.0, 64, L),
        (0.0, 1.0)
    );
    // A point inside a texel: that texel.
    assert_eq!(on_source_grid(0.35, 0.35, 10, L), (0.3, 0.4));
    // Mirror and clamp stay in [0, 1]; a repeat arc keeps crossing the seam, and one of a
    // source under 8 texels keeps its own range where it would widen to a period; baked ranges are
    // unbounded.
    assert_eq!(on_source_grid(0.01, 0.999, 4, RectWrap::Clamp), (0.0, 1.0));
    assert_eq!(on_source_grid(0.01, 0.6, 4, RectWrap::Mirror), (0.0, 0.75));
    assert_eq!(on_source_grid(0.8, 1.2, 4, RectWrap::Repeat), (0.75, 1.25));
    assert_eq!(on_source_grid(0.3, 1.2, 4, RectWrap::Repeat), (0.3, 1.2));
    assert_eq!(
        on_source_grid(0.125, 0.875, 4, RectWrap::Repeat),
        (0.125, 0.875)
    );
    assert_eq!(on_source_grid(0.0, 1.0, 4, RectWrap::Repeat), (0.0, 1.0));
    // From 8 source texels on, an arc that widens to a period is the period: a half-texel inset.
    assert_eq!(
        on_source_grid(0.5 / 64.0, 63.5 / 64.0, 64, RectWrap::Repeat),
        (0.0, 1.0)
    );
    assert_eq!(on_source_grid(0.01, 0.99, 8, RectWrap::Repeat), (0.0, 1.0));
    assert_eq!(
        on_source_grid(0.01, 0.99, 7, RectWrap::Repeat),
        (0.01, 0.99)
    );
    // At a leaf's scale below 1 the period counts the texels it keeps: 16 × 0.25 = 4 keeps its range.
    let inset = (0.5 / 16.0, 15.5 / 16.0);
    let at = |scale| on_source_grid_at(inset.0, inset.1, 16, RectWrap::Repeat, scale);
    assert_eq!(at(0.25), inset);
    assert_eq!(at(0.5), (0.0, 1.0));
    assert_eq!(on_source_grid(0.3, 1.2, 4, L), (0.25, 1.25));
    let below_one = 1.0 - 4.0 * 2f64.powi(-24);
    assert_eq!(
        on_source_grid(below_one, 1.25, 64, RectWrap::Repeat),
        (0.0, 0.25)
    );
    // A baked range far from 0 is not moved inward past what `inspect --verify` allows (f32 UVs):
    // 10 f32 steps inside a texel edge at 100.5 is not that edge; one step is.
    let step = f64::from(f32::EPSILON) * 64.0;
    let texel = 1.0 / 64.0;
    assert_eq!(
        on_source_grid(100.5 - 10.0 * step, 101.0, 64, L).0,
        100.5 - texel
    );
    assert_eq!(
        on_source_grid(100.0, 100.5 + 10.0 * step, 64, L).1,
        100.5 + texel
    );
    assert_eq!(
        on_source_grid(100.5 - step, 100.5 + step, 64, L),
        (100.5, 100.5)
    );
    // Huge UVs: the tolerance stays below a hundredth of a texel.
    let (lo, hi) = on_source_grid(1e6 + 0.3, 1e6 + 0.7, 100, L);
    assert_eq!((lo * 100.0, hi * 100.0), (1e8 + 30.0, 1e8 + 70.0));
    assert!(on_source_grid(f64::NAN, 1.0, 4, L).0.is_nan());
}

fn input(w: f64, h: f64, uv_min: [f64; 2], uv_max: [f64; 2]) -> AreaInput {
    AreaInput {
        w,
        h,
        uv_min,
        uv_max,
        source: [512, 512],
    }
}

#[test]
fn single_repetition_with_border_and_alignment() {
    // 100.3 × 37 texels per UV over one repetition: inner 101 × 37, +16 → 117 × 53 → 120 × 56.
    let a = required_area(
        &input(100.3, 37.0, [0.0, 0.0], [1.0, 1.0]),
        &AreaOptions::default(),
    )
    .unwrap();
    assert_eq!(
        (a.inner_w, a.inner_h, a.outer_w, a.outer_h),
        (101, 37, 120, 56)
    );
    // Extra 3 (resp. 3) texels: 1 before, 2 after.
    assert_eq!(a.border, [9, 9]);
    assert_eq!(a.outer_w % 4, 0);
    assert_eq!(a.outer_h % 4, 0);
}

#[test]
fn partial_and_repeated_areas_scale_with_extent() {
    let o = AreaOptions::default();
    // Half a repetition in U, 3.5 in V.
    let a = required_area(&input(64.0, 10.0, [0.25, -1.0], [0.75, 2.5]), &o).unwrap();
    assert_eq!((a.inner_w, a.inner_h), (32, 35));
    // 1e4 repetitions at 0.01 texel per repetition: 100 texels (depends on world size only).
    let a = required_area(&input(0.01, 0.01, [0.0, 5e3], [1e4, 1.5e4]), &o).unwrap();
    assert_eq!((a.inner_w, a.inner_h, a.outer_w), (100, 100, 116));
    // Huge offset of A_tex changes nothing.
    let a2 = required_area(
        &input(0.01, 0.01, [-2.9e9, -2.9e9], [-2.9e9 + 1e4, -2.9e9 + 1e4]),
        &o,
    )
    .unwrap();
    assert_eq!(a, a2);
}

#[test]
fn float_noise_does_not_add_a_column() {
    // 1.1 m at 110 texels/m in f64 is 121.00000000000001.
    let w = 1.1 * 1.1 * 100.0;
    assert!(w > 121.0);
    let a = required_area(
        &input(w, 1.0, [0.0, 0.0], [1.0, 1.0]),
        &AreaOptions::default(),
    )
    .unwrap();
    assert_eq!(a.inner_w, 121);
    let a = required_area(
        &input(121.001, 1.0, [0.0, 0.0], [1.0, 1.0]),
        &AreaOptions::default(),
    )
    .unwrap();
    assert_eq!(a.inner_w, 122);
}

#[test]
fn all_uv_equal_gives_one_by_one() {
    let a = required_area(
        &input(0.0, 0.0, [0.3, 0.3], [0.3, 0.3]),
        &AreaOptions::default(),
    )
    .unwrap();
    assert_eq!(
        (a.inner_w, a.inner_h, a.outer_w, a.outer_h, a.border),
        (1, 1, 20, 20, [9, 9])
    );
    let (lo, hi) = a.outer_uv([0.3, 0.3], [0.3, 0.3]);
    assert_eq!((lo, hi), ([0.3, 0.3], [0.3, 0.3]));
}

#[test]
fn source_cap_and_scale() {
    let i = AreaInput {
        w: 4000.0,
        h: 100.0,
        uv_min: [0.0, 0.0],
        uv_max: [2.0, 1.0],
        source: [256, 64],
    };
    let a = required_area(&i, &AreaOptions::default()).unwrap();
    assert_eq!((a.inner_w, a.inner_h), (512, 64));
    let a = required_area(
        &i,
        &AreaOptions {
            cap_to_source: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((a.inner_w, a.inner_h), (8000, 100));
    let a = required_area(
        &i,
        &AreaOptions {
            scale: 0.5,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((a.inner_w, a.inner_h), (256, 32));
}

#[test]
fn border_zero_and_outer_uv_continue_the_mapping() {
    let o = AreaOptions {
        border: 0,
        ..Default::default()
    };
    let a = required_area(&input(10.0, 8.0, [0.0, 0.0], [1.0, 1.0]), &o).unwrap();
    assert_eq!((a.outer_w, a.outer_h, a.border), (12, 8, [1, 0]));
    // 1 texel before, 1 after on U, each 0.1 UV.
    let (lo, hi) = a.outer_uv([0.0, 0.0], [1.0, 1.0]);
    assert!(
        (lo[0] + 0.1).abs() < 1e-15 && (hi[0] - 1.1).abs() < 1e-15,
        "{lo:?} {hi:?}"
    );
    assert_eq!((lo[1], hi[1]), (0.0, 1.0));
    // Paper border 8 on a 16-texel inner over one repetition: A_tex scaled ×2 around its centre.
    let a = required_area(
        &input(16.0, 16.0, [0.0, 0.0], [1.0, 1.0]),
        &AreaOptions::default(),
    )
    .unwrap();
    assert_eq!(
        a.outer_uv([0.0, 0.0], [1.0, 1.0]),
        ([-0.5, -0.5], [1.5, 1.5])
    );
}

#[test]
fn too_large_and_invalid_are_errors_with_numbers() {
    let o = AreaOptions {
        max_side: 1024,
        cap_to_source: false,
        ..Default::default()
    };
    let e = required_area(&input(1e6, 1.0, [0.0, 0.0], [1e3, 1.0]), &o).unwrap_err();
    match e {
        AreaError::TooLarge {
            axis,
            texels,
            limit,
            ..
        } => {
            assert_eq!((axis, limit), ('w', 1024));
            assert_eq!(texels, 1e9 + 16.0);
        }
        other => panic!("{other:?}"),
    }
    // 1012 + 16 = 1028 > 1024 after rounding; 1008 + 16 = 1024 fits.
    assert!(required_area(&input(1009.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &o).is_err());
    assert_eq!(
        required_area(&input(1008.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &o)
            .unwrap()
            .outer_w,
        1024
    );
    let e = required_area(&input(f64::MAX, 1.0, [0.0, 0.0], [1e300, 1.0]), &o).unwrap_err();
    assert!(matches!(e, AreaError::TooLarge { axis: 'w', .. }), "{e}");
    for (i, what) in [
        (input(f64::NAN, 1.0, [0.0, 0.0], [1.0, 1.0]), "w"),
        (input(1.0, -1.0, [0.0, 0.0], [1.0, 1.0]), "h"),
        (input(1.0, 1.0, [0.0, 2.0], [1.0, 1.0]), "uv_max.v"),
    ] {
        match required_area(&i, &o) {
            Err(AreaError::Invalid { what: w, value }) => {
                assert_eq!(w, what);
                assert_eq!(value.to_bits(), f(&i, what).to_bits());
            }
            other => panic!("{other:?}"),
        }
    }
    let bad_scale = AreaOptions { scale: 0.0, ..o };
    assert!(matches!(
        required_area(&input(1.0, 1.0, [0.0, 0.0], [1.0, 1.0]), &bad_scale),
        Err(AreaError::Invalid { what: "scale", .. })
    ));
}

fn f(i: &AreaInput, what: &str) -> f64 {
    match what {
        "w" => i.w,
        "h" => i.h,
        _ => i.uv_max[1],
    }
}

#[test]
fn summed_area_and_may_fit() {
    let o = AreaOptions::default();
    let a = required_area(&input(240.0, 240.0, [0.0, 0.0], [1.0, 1.0]), &o).unwrap();
    assert_eq!((a.outer_w, a.outer_h), (256, 256));
    assert_eq!(summed_area(&[a; 4]), 4 * 65536);
    assert!(may_fit(&[a; 4], 512));
    assert!(!may_fit(&[a; 5], 512));
    assert!(!may_fit(&[a], 128));
    assert_eq!(summed_area(&[]), 0);
}

#[test]
fn scale_to_fit_finds_the_leaf_clamp() {
    let o = AreaOptions {
        cap_to_source: false,
        ..Default::default()
    };
    let i = input(3000.0, 100.0, [0.0, 0.0], [1.0, 1.0]);
    let s = scale_to_fit(&i, &o, 512).unwrap();
    // avail = 512 − 16 = 496 texels for 3000 needed.
    assert!((s - 496.0 / 3000.0).abs() < 1e-9, "{s}");
    let a = required_area(
        &i,
        &AreaOptions {
            scale: s,
            max_side: 512,
            ..o
        },
    )
    .unwrap();
    assert_eq!(a.outer_w, 512);
    assert_eq!(
        scale_to_fit(&input(10.0, 10.0, [0.0, 0.0], [1.0, 1.0]), &o, 512),
        Some(1.0)
    );
    assert_eq!(scale_to_fit(&i, &o, 16), None);
}

#[test]
fn report_counts() {
    let o = AreaOptions {
        max_side: 1024,
        ..Default::default()
    };
    let inputs = [
        input(0.0, 0.0, [0.0, 0.0], [0.0, 0.0]),
        input(1e4, 10.0, [0.0, 0.0], [1.0, 1.0]), // capped at 512
        input(100.0, 100.0, [0.0, 0.0], [100.0, 1.0]),
        input(f64::NAN, 1.0, [0.0, 0.0], [1.0, 1.0]),
    ];
    let r = analyze_areas(&inputs, &o);
    assert_eq!(
        (
            r.materials,
            r.too_large,
            r.invalid,
            r.capped_w,
            r.capped_h,
            r.one_by_one
        ),
        (4, 1, 1, 1, 0, 1)
    );
    assert_eq!(r.inner_texels, 1 + 512 * 10);
    assert_eq!(r.outer_texels, 20 * 20 + 528 * 28);
    assert_eq!(r.max_outer_side, 528);
    assert!((r.border_fraction() - (1.0 - 5121.0 / 15184.0)).abs() < 1e-12);
}

/// The floor covers one period at most (a baked rect of 150 periods asked an atlas side of it),
/// and is off with `cap_floor` (the rule of before: the source times the scale).
#[test]
fn the_scaled_leaf_floor_spans_one_period_and_can_be_off() {
    let o = AreaOptions {
        border: 16,
        scale: 0.1,
        cap_to_source: true,
        max_side: 1024,
        cap_floor: true,
    };
    // An 8-texel source asked at 1000 texels per UV over 150 UV: 8 · 0.1 · 150 = 120 exact, the
    // floor 8 texels of one period: the exact size wins.
    assert_eq!(axis_texels(1000.0, 8, 150.0, &o), 8.0 * 0.1 * 150.0);
    // Over half a period: 4 texels kept, not 0.4.
    assert_eq!(axis_texels(1000.0, 8, 0.5, &o), 4.0);
    let off = AreaOptions {
        cap_floor: false,
        ..o
    };
    assert!((axis_texels(1000.0, 8, 0.5, &off) - 0.4).abs() < 1e-12);
}

proptest::proptest! {
    /// The scaled-leaf floor: never decreasing in the scale (the leaf clamp bisects on it), equal to
    /// the old rule at scale 1, never above what the leaf's distance shows.
    #[test]
    fn axis_texels_grow_with_the_scale(
        per_uv in 0.0f64..5000.0, source in 1u32..64, extent in 0.0f64..4.0,
        s0 in 1e-4f64..1.0, s1 in 1e-4f64..1.0, border in 0u32..20,
    ) {
        let at = |scale: f64| axis_texels(
            per_uv, source, extent,
            &AreaOptions { border, scale, cap_to_source: true, max_side: 1024, cap_floor: true },
        );
        let (lo, hi) = (s0.min(s1), s0.max(s1));
        proptest::prop_assert!(at(lo) <= at(hi), "{} > {}", at(lo), at(hi));
        proptest::prop_assert_eq!(at(1.0), per_uv.min(f64::from(source)) * extent);
        let shown = per_uv.max(f64::from(source)) * lo * extent;
        proptest::prop_assert!(at(lo) <= shown * (1.0 + 1e-12), "{} > {}", at(lo), shown);
    }

    #[test]
    fn area_invariants(
        w in 0.0f64..2000.0, h in 0.0f64..2000.0,
        u0 in -1e5f64..1e5, v0 in -1e5f64..1e5, du in 0.0f64..8.0, dv in 0.0f64..8.0,
        border in 0u32..20, scale in 0.01f64..1.0, cap in proptest::bool::ANY,
    ) {
        let i = AreaInput { w, h, uv_min: [u0, v0], uv_max: [u0 + du, v0 + dv], source: [1024, 256] };
        let o = AreaOptions { border, scale, cap_to_source: cap, max_side: 1 << 16, cap_floor: true };
        let a = required_area(&i, &o).unwrap();
        for (inner, outer, b, per_uv, src, ext) in [
            (a.inner_w, a.outer_w, a.border[0], w, 1024.0, i.uv_max[0] - i.uv_min[0]),
            (a.inner_h, a.outer_h, a.border[1], h, 256.0, i.uv_max[1] - i.uv_min[1]),
        ] {
            proptest::prop_assert!(inner >= 1);
            proptest::prop_assert_eq!(outer % 4, 0);
            let slack = outer - inner - 2 * border;
            proptest::prop_assert!(slack < 4, "{:?}", a);
            proptest::prop_assert!(b >= border && b - border <= slack, "{:?}", a);
            let mut need = if cap { per_uv.min(src) } else { per_uv } * scale * ext;
            // A capped axis of a scaled leaf keeps min(src, 8) texels per UV where shown.
            if cap && per_uv > src && scale < 1.0 {
                let room = f64::from((o.max_side / 4 * 4) - 2 * border);
                let floor = (src.min(SCALED_CAP_FLOOR) * ext.min(1.0)).min(per_uv * scale * ext).min(room);
                need = need.max(floor);
            }
            // No magnification (to 1e-9) and no wasted texel column.
            proptest::prop_assert!(f64::from(inner) >= need * (1.0 - 1e-9), "{} < {}", inner, need);
            proptest::prop_assert!(f64::from(inner) < need.max(1.0) + 1.0, "{} vs {}", inner, need);
        }
    }
}
