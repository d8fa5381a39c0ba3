//! Sizing analysis over many triangles (paper §5.2.1): the running maximum per material and node, and the
//! counts of how each triangle was sized. The per-triangle rule is [`crate::model::sizing`].

use crate::model::sizing::{SizeEstimate, SizeMethod, texels_per_uv};
use glam::{DVec2, DVec3};
use serde::Serialize;

/// Running maximum of [`SizeEstimate`]s over the triangles of one material in one node (paper §5.2.1:
/// "the maximum of all calculated minimum widths respectively heights").
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct SizeMax {
    /// Max texels per unit of U.
    pub w: f64,
    /// Max texels per unit of V.
    pub h: f64,
    /// Triangles that contributed (everything but [`SizeMethod::WorldDegenerate`]).
    pub triangles: u64,
}

impl SizeMax {
    /// Fold one estimate in; world-degenerate triangles are not counted.
    pub fn add(&mut self, e: &SizeEstimate) {
        if e.method == SizeMethod::WorldDegenerate {
            return;
        }
        self.w = self.w.max(e.w);
        self.h = self.h.max(e.h);
        self.triangles += 1;
    }
}

/// Counts of [`SizeMethod`]s over a set of triangles, and the largest sizes seen (analysis twin of
/// [`texels_per_uv`], for `inspect` and the build report).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct SizingReport {
    pub triangles: u64,
    pub exact: u64,
    pub all_uv_equal: u64,
    pub edge_fallback: u64,
    pub world_degenerate: u64,
    /// Largest `w` / `h` over all triangles, texels per unit of UV.
    pub max_w: f64,
    pub max_h: f64,
}

/// Size every triangle and count how each was sized.
pub fn analyze_sizing<I>(triangles: I, f_proj: f64) -> SizingReport
where
    I: IntoIterator<Item = ([DVec3; 3], [DVec2; 3])>,
{
    let mut r = SizingReport::default();
    for (pos, uv) in triangles {
        let e = texels_per_uv(pos, uv, f_proj);
        r.triangles += 1;
        match e.method {
            SizeMethod::Exact => r.exact += 1,
            SizeMethod::AllUvEqual => r.all_uv_equal += 1,
            SizeMethod::EdgeFallback => r.edge_fallback += 1,
            SizeMethod::WorldDegenerate => r.world_degenerate += 1,
        }
        r.max_w = r.max_w.max(e.w);
        r.max_h = r.max_h.max(e.h);
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const F: f64 = 100.0;

    fn p(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }
    fn t(u: f64, v: f64) -> DVec2 {
        DVec2::new(u, v)
    }
    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
    }

    #[test]
    fn unit_square_gives_f_proj() {
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)],
            [t(0., 0.), t(1., 0.), t(0., 1.)],
            F,
        );
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(close(e.w, F, 1e-15) && close(e.h, F, 1e-15), "{e:?}");
    }

    #[test]
    fn stretched_mapping_scales_per_axis() {
        // 10 m × 2 m rectangle (triangle of it) mapped to one repetition, in the x-z plane.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(10., 0., 0.), p(0., 0., 2.)],
            [t(0., 0.), t(1., 0.), t(0., 1.)],
            F,
        );
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(
            close(e.w, 10.0 * F, 1e-15) && close(e.h, 2.0 * F, 1e-15),
            "{e:?}"
        );
        // Four repetitions along U over 1 m: a quarter of the texels per repetition.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)],
            [t(0., 0.), t(4., 0.), t(0., 1.)],
            F,
        );
        assert!(close(e.w, F / 4.0, 1e-15) && close(e.h, F, 1e-15), "{e:?}");
    }

    #[test]
    fn sheared_mapping_matches_hand_computation() {
        // d1 = (1, 0), d2 = (1, 1): Tex⁻¹(1,0) = (1, 0) → s_world = e1 = (2,0,0);
        // Tex⁻¹(0,1) = (−1, 1) → t_world = e2 − e1 = (−2, 3, 0), |t_world| = √13.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(2., 0., 0.), p(0., 3., 0.)],
            [t(0., 0.), t(1., 0.), t(1., 1.)],
            F,
        );
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(close(e.w, 2.0 * F, 1e-15), "{e:?}");
        assert!(close(e.h, 13f64.sqrt() * F, 1e-14), "{e:?}");
    }

    #[test]
    fn rotated_uvs_swap_axes() {
        // UVs rotated by 90°: U runs along −e2 (3 m), V along e1 (5 m).
        let e = texels_per_uv(
            [p(0., 0., 0.), p(5., 0., 0.), p(0., 3., 0.)],
            [t(0., 0.), t(0., 1.), t(-1., 0.)],
            F,
        );
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(
            close(e.w, 3.0 * F, 1e-15) && close(e.h, 5.0 * F, 1e-15),
            "{e:?}"
        );
        // 45° rotation of a unit mapping keeps lengths.
        let (c, s) = (
            std::f64::consts::FRAC_1_SQRT_2,
            std::f64::consts::FRAC_1_SQRT_2,
        );
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)],
            [t(0., 0.), t(c, s), t(-s, c)],
            F,
        );
        assert!(close(e.w, F, 1e-14) && close(e.h, F, 1e-14), "{e:?}");
    }

    #[test]
    fn all_uv_equal_is_flagged_with_zero_size() {
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)],
            [t(0.3, 0.7); 3],
            F,
        );
        assert_eq!(
            e,
            SizeEstimate {
                w: 0.0,
                h: 0.0,
                method: SizeMethod::AllUvEqual
            }
        );
        // Equal to within the precision of UVs at 1e6 (ulp 1.2e-10): still a point.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)],
            [t(1e6, 1e6), t(1e6 + 1.2e-10, 1e6), t(1e6, 1e6)],
            F,
        );
        assert_eq!(e.method, SizeMethod::AllUvEqual);
    }

    #[test]
    fn collinear_uvs_use_longest_edge() {
        // Paper: estimate |v_i − v_j| / |t_i − t_j| on the longest UV edge (0,1): 2 m over 1 UV.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(2., 0., 0.), p(0., 1., 0.)],
            [t(0., 0.), t(1., 0.), t(0.5, 0.)],
            F,
        );
        assert_eq!(e.method, SizeMethod::EdgeFallback);
        assert!(
            close(e.w, 2.0 * F, 1e-15) && close(e.h, 2.0 * F, 1e-15),
            "{e:?}"
        );
        // Two equal UVs: the longest edge is (0,2), world length √(1+9) over UV length 0.5.
        let e = texels_per_uv(
            [p(0., 0., 0.), p(1., 0., 0.), p(1., 3., 0.)],
            [t(0., 0.), t(0., 0.), t(0., 0.5)],
            F,
        );
        assert_eq!(e.method, SizeMethod::EdgeFallback);
        assert!(close(e.w, 10f64.sqrt() / 0.5 * F, 1e-15), "{e:?}");
    }

    #[test]
    fn ill_conditioned_uvs_fall_back_and_stay_bounded() {
        // UV triangle with height 1e-8 against width 1: condition number ~2e8 > 1e6. Inverting it would give
        // |t_world| ~ 1e8 m per UV; the fallback uses the longest edge (0,1): 1 m over 1 UV.
        let pos = [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)];
        let e = texels_per_uv(pos, [t(0., 0.), t(1., 0.), t(0.5, 1e-8)], F);
        assert_eq!(e.method, SizeMethod::EdgeFallback);
        assert!(close(e.w, F, 1e-12) && close(e.h, F, 1e-12), "{e:?}");
        // Condition number ~2e5 is still inverted.
        let e = texels_per_uv(pos, [t(0., 0.), t(1., 0.), t(0.5, 1e-5)], F);
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(close(e.w, F, 1e-12), "{e:?}");
        assert!(close(e.h, (0.25f64 + 1.0).sqrt() / 1e-5 * F, 1e-9), "{e:?}");
    }

    #[test]
    fn world_degenerate_and_non_finite_are_ignored() {
        let uv = [t(0., 0.), t(1., 0.), t(0., 1.)];
        let collinear = [p(0., 0., 0.), p(1., 1., 1.), p(2., 2., 2.)];
        let point = [p(5., 5., 5.); 3];
        let sliver = [p(0., 0., 0.), p(1e7, 0., 0.), p(5e6, 1e-7, 0.)]; // 2A / l² = 1e-14
        let nan = [p(0., 0., 0.), p(f64::NAN, 0., 0.), p(0., 1., 0.)];
        let inf = [p(0., 0., 0.), p(f64::INFINITY, 0., 0.), p(0., 1., 0.)];
        for pos in [collinear, point, sliver, nan, inf] {
            let e = texels_per_uv(pos, uv, F);
            assert_eq!(
                e,
                SizeEstimate {
                    w: 0.0,
                    h: 0.0,
                    method: SizeMethod::WorldDegenerate
                },
                "{pos:?}"
            );
        }
        let ok = [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)];
        let e = texels_per_uv(ok, [t(0., 0.), t(f64::NAN, 0.), t(0., 1.)], F);
        assert_eq!(e.method, SizeMethod::WorldDegenerate);
        // A thin but real triangle (2A / l² = 1e-6) is sized.
        let thin = [p(0., 0., 0.), p(1000., 0., 0.), p(500., 1e-3, 0.)];
        assert_eq!(texels_per_uv(thin, uv, F).method, SizeMethod::Exact);
    }

    #[test]
    fn huge_uv_offsets_and_repeats_stay_exact() {
        let pos = [p(0., 0., 0.), p(2., 0., 0.), p(0., 3., 0.)];
        // UVs at −2.9e9 (ulp 4.8e-7): a one-repetition triangle is still exact to 1e-6.
        let o = t(-2.9e9, -2.9e9);
        let e = texels_per_uv(pos, [o, o + t(1., 0.), o + t(0., 1.)], F);
        assert_eq!(e.method, SizeMethod::Exact);
        assert!(
            close(e.w, 2.0 * F, 1e-6) && close(e.h, 3.0 * F, 1e-6),
            "{e:?}"
        );
        // A 1e-3 UV triangle there is below 1e4 × uv_noise (6.4e-3): fallback, finite, within 1e-3.
        let e = texels_per_uv(pos, [o, o + t(1e-3, 0.), o + t(0., 1e-3)], F);
        assert_eq!(e.method, SizeMethod::EdgeFallback);
        assert!(
            e.w.is_finite() && close(e.w, 13f64.sqrt() / 2f64.sqrt() * 1e3 * F, 1e-3),
            "{e:?}"
        );
        // UTM-size positions (±1e7 m) and UVs at ±1e5.
        let utm = DVec3::new(6.0e6, -4.0e6, 1.0e7);
        let pos_utm = pos.map(|v| v + utm);
        for off in [1e5, -1e5] {
            let o = t(off, -off);
            let e = texels_per_uv(pos_utm, [o, o + t(1., 0.), o + t(0., 1.)], F);
            assert_eq!(e.method, SizeMethod::Exact);
            assert!(
                close(e.w, 2.0 * F, 1e-9) && close(e.h, 3.0 * F, 1e-9),
                "{e:?}"
            );
        }
        // Repeat 1e4 over 100 m: 0.01 texel·F per repetition.
        let big = [p(0., 0., 0.), p(100., 0., 0.), p(0., 100., 0.)];
        let e = texels_per_uv(big, [t(0., 0.), t(1e4, 0.), t(0., 1e4)], F);
        assert!(
            close(e.w, 0.01 * F, 1e-14) && close(e.h, 0.01 * F, 1e-14),
            "{e:?}"
        );
    }

    #[test]
    fn extreme_magnitudes_are_finite() {
        let uv = [t(0., 0.), t(1e-300, 0.), t(0., 1e-300)];
        let pos = [p(-1e200, 0., 0.), p(1e200, 0., 0.), p(-1e200, 1e200, 0.)];
        let e = texels_per_uv(pos, uv, F);
        assert!(e.w.is_finite() && e.h.is_finite() && e.w >= 0.0, "{e:?}");
        let uv = [t(0., 0.), t(1e-10, 0.), t(0., 1e-10)];
        let e = texels_per_uv(pos, uv, 1e300);
        assert_eq!(e.method, SizeMethod::Exact);
        assert_eq!(e.w, f64::MAX, "overflow saturates");
        let e = texels_per_uv(pos, uv, -1.0);
        assert_eq!((e.w, e.h), (0.0, 0.0));
    }

    #[test]
    fn report_counts_each_method() {
        let pos = [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)];
        let tris = vec![
            (pos, [t(0., 0.), t(1., 0.), t(0., 1.)]),
            (pos, [t(0., 0.), t(2., 0.), t(0., 1.)]),
            (pos, [t(0.5, 0.5); 3]),
            (pos, [t(0., 0.), t(1., 0.), t(2., 0.)]),
            ([p(0., 0., 0.); 3], [t(0., 0.), t(1., 0.), t(0., 1.)]),
        ];
        let r = analyze_sizing(tris.iter().copied(), F);
        assert_eq!(
            (
                r.triangles,
                r.exact,
                r.all_uv_equal,
                r.edge_fallback,
                r.world_degenerate
            ),
            (5, 2, 1, 1, 1)
        );
        assert!(
            close(r.max_w, F, 1e-15) && close(r.max_h, F, 1e-15),
            "{r:?}"
        );
        let mut m = SizeMax::default();
        for (pos, uv) in tris {
            m.add(&texels_per_uv(pos, uv, F));
        }
        assert_eq!(m.triangles, 4);
        assert!(close(m.w, F, 1e-15));
    }

    fn coord() -> impl Strategy<Value = f64> {
        -100.0f64..100.0
    }
    fn tri() -> impl Strategy<Value = ([DVec3; 3], [DVec2; 3])> {
        (
            prop::array::uniform9(coord()),
            prop::array::uniform6(-10.0f64..10.0),
        )
            .prop_map(|(a, b)| {
                (
                    [
                        p(a[0], a[1], a[2]),
                        p(a[3], a[4], a[5]),
                        p(a[6], a[7], a[8]),
                    ],
                    [t(b[0], b[1]), t(b[2], b[3]), t(b[4], b[5])],
                )
            })
    }

    proptest! {
        #[test]
        fn world_scale_scales_size((pos, uv) in tri(), k in 1e-3f64..1e3) {
            let a = texels_per_uv(pos, uv, F);
            let b = texels_per_uv(pos.map(|v| v * k), uv, F);
            prop_assume!(a.method == SizeMethod::Exact);
            prop_assert_eq!(b.method, a.method);
            prop_assert!(close(b.w, a.w * k, 1e-9), "{:?} {:?}", a, b);
            prop_assert!(close(b.h, a.h * k, 1e-9), "{:?} {:?}", a, b);
        }

        #[test]
        fn integer_uv_translation_is_invariant((pos, uv) in tri(), du in -1000i32..1000, dv in -1000i32..1000) {
            let a = texels_per_uv(pos, uv, F);
            prop_assume!(a.method == SizeMethod::Exact);
            let shift = t(du as f64, dv as f64);
            let b = texels_per_uv(pos, uv.map(|x| x + shift), F);
            prop_assert_eq!(b.method, a.method);
            prop_assert!(close(b.w, a.w, 1e-6), "{:?} {:?}", a, b);
            prop_assert!(close(b.h, a.h, 1e-6), "{:?} {:?}", a, b);
        }

        #[test]
        fn never_nan_or_negative(v in prop::array::uniform9(any::<f64>()), u in prop::array::uniform6(any::<f64>()),
                                 f in prop_oneof![Just(F), any::<f64>()]) {
            let pos = [p(v[0], v[1], v[2]), p(v[3], v[4], v[5]), p(v[6], v[7], v[8])];
            let uv = [t(u[0], u[1]), t(u[2], u[3]), t(u[4], u[5])];
            let e = texels_per_uv(pos, uv, f);
            prop_assert!(e.w.is_finite() && e.h.is_finite() && e.w >= 0.0 && e.h >= 0.0, "{:?}", e);
        }
    }
}
