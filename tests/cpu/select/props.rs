//! Property tests of the per-frame cut over random (incomplete) quadtrees and random cameras, with
//! shrinking: the exactly-once and no-ancestor invariants, agreement with the plain recursive reference,
//! and monotonicity in the min-distance scale. The reference's distance and atlas rule are written from
//! first principles in `tests/fixtures/select_trees.rs` (`oracle_distance`, `oracle_atlas_suffices`), and
//! checked against the library's `distance_to_aabb` and `atlas_suffices` directly here.

use crate::fixtures::select_trees::*;
use atlastree::camera::{Camera, distance_to_aabb};
use atlastree::select::{Cut, atlas_suffices, select};
use glam::DVec3;
use proptest::prelude::*;

fn shape() -> impl Strategy<Value = Shape> {
    let leaf = (
        1u32..12,
        0.5f64..60.0,
        prop_oneof![3 => Just(1.0), 1 => Just(0.5)],
    )
        .prop_map(|(tris, height, clamp)| Shape::Leaf {
            tris,
            height,
            clamp,
        });
    leaf.prop_recursive(6, 300, 4, |inner| {
        proptest::array::uniform4(proptest::option::weighted(0.75, inner))
            .prop_filter("an inner node has a child", |c| {
                c.iter().any(Option::is_some)
            })
            .prop_map(Shape::inner)
    })
}

fn placement() -> impl Strategy<Value = Placement> {
    (
        -500.0f64..500.0,
        -20.0f64..20.0,
        50.0f64..2000.0,
        0.005f64..0.3,
        0.0f64..0.2,
    )
        .prop_map(|(c, ground, size, d_min_frac, inset)| Placement {
            corner: DVec3::new(c, ground, -c),
            size,
            d_min: d_min_frac * size,
            inset,
        })
}

/// A camera in footprint fractions (mapped onto the placement by `place`): the eye anywhere around and
/// above the footprint, mostly looking at a point of it, sometimes in a random direction.
fn camera() -> impl Strategy<Value = Camera> {
    (
        (-0.5f64..1.5, 0.0f64..0.6, -0.5f64..1.5),
        prop_oneof![
            3 => (0.0f64..1.0, 0.0f64..0.05, 0.0f64..1.0).prop_map(|(x, y, z)| (DVec3::new(x, y, z), false)),
            1 => proptest::array::uniform3(-1.0f64..1.0).prop_map(|d| (DVec3::from(d), true)),
        ],
        10.0f64..150.0,
        0.3f64..3.0,
    )
        .prop_map(|((x, y, z), (aim, is_dir), fov, aspect)| {
            let eye = DVec3::new(x, y, z);
            Camera {
                eye,
                target: if is_dir { eye + aim } else { aim },
                up: DVec3::Y,
                fov_x_deg: fov,
                aspect,
                near: 0.1,
                far: 5000.0,
            }
        })
        .prop_filter("a view direction", |c| (c.target - c.eye).length() > 1e-3)
}

/// Puts a camera given in footprint fractions onto the placement (heights in fractions of the side).
fn place(c: &Camera, at: &Placement) -> Camera {
    let map = |p: DVec3| at.corner + p * at.size;
    Camera {
        eye: map(c.eye),
        target: map(c.target),
        ..*c
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    #[test]
    fn cut_invariants_hold(shape in shape(), at in placement(), cam in camera(), scale in 0.05f64..8.0) {
        let nodes = build_tree(&shape, at);
        let c = place(&cam, &at);
        let f = c.frustum();
        let mut cut = Cut::new();
        select(&nodes, &c, &f, scale, &mut cut);
        if let Err(e) = check_cut(&nodes, &f, &cut) {
            return Err(TestCaseError::fail(e));
        }
        prop_assert_eq!(pairs(&cut), reference(&nodes, &c, &f, scale));
        prop_assert!(cut.visited as usize <= nodes.len());
        prop_assert!(cut.culled <= cut.visited);
    }

    /// A larger min-distance scale (bigger screen, higher texel ratio, narrower fov) never gives a
    /// coarser cut: every triangle is drawn by the same node or a descendant, and a node drawn with its
    /// originals stays on originals.
    #[test]
    fn larger_scale_never_coarsens(
        shape in shape(), at in placement(), cam in camera(), scale in 0.05f64..4.0, factor in 1.0f64..8.0,
    ) {
        let nodes = build_tree(&shape, at);
        let c = place(&cam, &at);
        let f = c.frustum();
        let (mut small, mut large) = (Cut::new(), Cut::new());
        select(&nodes, &c, &f, scale, &mut small);
        select(&nodes, &c, &f, scale * factor, &mut large);
        let (a, b) = (fineness(&nodes, &small), fineness(&nodes, &large));
        for (t, (x, y)) in a.iter().zip(&b).enumerate() {
            match (x, y) {
                (None, None) => {}
                (Some((_, xo, xn)), Some((_, yo, yn))) => {
                    let ok = if xn == yn { !xo || *yo } else { is_ancestor(&nodes, *xn, *yn) };
                    prop_assert!(ok, "triangle {}: scale {} drew it with node {} (orig {}), scale {} with node {} (orig {})",
                        t, scale, xn, xo, scale * factor, yn, yo);
                }
                // A coarse atlas item also covers triangles of culled leaves; finer cuts drop those
                // (check_cut proves every triangle of a visible leaf is drawn at both scales).
                (Some(_), None) => {}
                (None, Some(_)) => prop_assert!(false, "triangle {} drawn only at the larger scale", t),
            }
        }
    }

    /// The library's distance and atlas rule against the oracles, on boxes around, touching and containing
    /// the eye, and on thresholds exactly at, just below and just above the distance.
    #[test]
    fn distance_and_atlas_rule_match_the_oracles(
        eye in proptest::array::uniform3(-1.0e3f64..1.0e3),
        lo in proptest::array::uniform3(-1.0e3f64..1.0e3),
        size in proptest::array::uniform3(prop_oneof![1 => Just(0.0), 4 => 0.0f64..500.0]),
        scale in 0.05f64..8.0,
        nudge in prop_oneof![Just(0.0), Just(1.0), Just(-1.0), -0.5f64..0.5],
    ) {
        let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
        let d = distance_to_aabb(eye.into(), lo.into(), hi.into());
        let want = oracle_distance(eye, lo, hi);
        prop_assert!((d - want).abs() <= 1e-12 * want.max(1.0), "distance {} != oracle {}", d, want);
        // Thresholds just either side of d, exactly at it (scale 1: ties descend), zero and NaN.
        let near = (want + nudge * 1e-3 * want.max(1.0)) / scale;
        for (m, s) in [(near, scale), (want, 1.0), (0.0, scale), (f64::NAN, scale)] {
            prop_assert_eq!(
                atlas_suffices(want, m, s),
                oracle_atlas_suffices(want, m, s),
                "distance {} min_distance {} scale {}", want, m, s
            );
        }
        prop_assert!(!atlas_suffices(want, want, 1.0));
        prop_assert!(!atlas_suffices(f64::NAN, 1.0, scale));
    }
}
