//! The paper's §4 selection rules on hand-made trees with hand-placed cameras, exact expected cuts.
//!
//! Tree A (footprint 400 m × 400 m, y up, d_min 50 m): root 0 → children 1 (inner, 0..200 × 0..200,
//! 20 m tall, with leaves 2–5 of 100 m), 6 (+x), 7 (+z), 8 (+x+z), 40 m tall leaves. min_distance:
//! leaves 50, node 1 100, root 200. Tree B is incomplete: root 0 → leaf 1 (quadrant 0) and inner 2
//! (quadrant 3) → leaves 3 (its +x half) and 4 (its +z half).

use crate::fixtures::select_trees::*;
use Source::{Atlas as A, Original as O};
use atlastree::camera::{Camera, CameraPath, Visibility};
use atlastree::select::{Cut, CutStats, Source, select};
use atlastree::store::format::NodeRecord;
use glam::DVec3;

fn tree_a() -> Vec<NodeRecord> {
    let gc = || Some(Shape::leaf(10, 20.0));
    let c = || Some(Shape::leaf(20, 40.0));
    let shape = Shape::inner([Some(Shape::inner([gc(), gc(), gc(), gc()])), c(), c(), c()]);
    build_tree(
        &shape,
        Placement {
            corner: DVec3::ZERO,
            size: 400.0,
            d_min: 50.0,
            inset: 0.0,
        },
    )
}

fn tree_b() -> Vec<NodeRecord> {
    let l = || Some(Shape::leaf(7, 30.0));
    let shape = Shape::inner([l(), None, None, Some(Shape::inner([None, l(), l(), None]))]);
    build_tree(
        &shape,
        Placement {
            corner: DVec3::ZERO,
            size: 400.0,
            d_min: 50.0,
            inset: 0.0,
        },
    )
}

fn cam(eye: [f64; 3], target: [f64; 3]) -> Camera {
    Camera {
        eye: eye.into(),
        target: target.into(),
        up: DVec3::Y,
        fov_x_deg: 90.0,
        aspect: 16.0 / 9.0,
        near: 0.25,
        far: 1.0e4,
    }
}

/// Selects with the camera's own frustum, checks the invariants and agreement with the reference.
fn cut_of(nodes: &[NodeRecord], c: &Camera, scale: f64) -> Cut {
    let mut cut = Cut::new();
    let f = c.frustum();
    select(nodes, c, &f, scale, &mut cut);
    check_cut(nodes, &f, &cut).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        pairs(&cut),
        reference(nodes, c, &f, scale),
        "hierarchical vs full culling"
    );
    cut
}

#[test]
fn trees_are_built_as_described() {
    let a = tree_a();
    assert_eq!(a.len(), 9);
    let md: Vec<f64> = a.iter().map(|n| n.min_distance).collect();
    assert_eq!(md, [200.0, 100.0, 50.0, 50.0, 50.0, 50.0, 50.0, 50.0, 50.0]);
    assert_eq!(a[0].index_count, (4 * 10 + 3 * 20) * 3);
    assert_eq!(
        (a[6].bounds_min, a[6].bounds_max),
        ([200.0, 0.0, 0.0], [400.0, 40.0, 200.0])
    );
    let b = tree_b();
    assert_eq!(b.len(), 5);
    assert_eq!(
        b[2].children,
        [atlastree::ids::NONE, 3, 4, atlastree::ids::NONE]
    );
    assert_eq!(
        (b[2].bounds_min, b[2].bounds_max),
        ([200.0, 0.0, 200.0], [400.0, 30.0, 400.0])
    );
    assert_eq!(b[0].min_distance, 200.0);
}

#[test]
fn far_camera_draws_the_root_only() {
    let cut = cut_of(
        &tree_a(),
        &cam([200.0, 1000.0, 900.0], [200.0, 0.0, 200.0]),
        1.0,
    );
    assert_eq!(pairs(&cut), [(0, A)]);
    assert_eq!((cut.visited, cut.culled), (1, 0));
    assert_eq!(cut.items[0].level, 0);
    assert_eq!(cut.items[0].index_count, 300);
}

#[test]
fn near_one_corner_that_region_descends_and_far_regions_stay_coarse() {
    let cut = cut_of(
        &tree_a(),
        &cam([-20.0, 30.0, -20.0], [200.0, 0.0, 200.0]),
        1.0,
    );
    // gc0 at sqrt(20² + 10² + 20²) = 30 < 50: originals; its siblings and the far children: atlases.
    assert_eq!(
        pairs(&cut),
        [(2, O), (3, A), (4, A), (5, A), (6, A), (7, A), (8, A)]
    );
    assert_eq!(cut.items[0].distance, 30.0);
    assert_eq!(cut.culled, 0);
    let s = CutStats::of(&cut);
    assert_eq!(s.levels, [0, 3, 4]);
    assert_eq!((s.original_triangles, s.atlas_triangles), (10, 90));
}

#[test]
fn eye_inside_bounds_gives_distance_zero_and_originals() {
    // Inside gc0 (node 2). gc1 and gc2 are exactly 50 = min_distance away: they descend, i.e. originals.
    let cut = cut_of(&tree_a(), &cam([50.0, 5.0, 50.0], [150.0, 5.0, 150.0]), 1.0);
    assert_eq!(
        pairs(&cut),
        [(2, O), (3, O), (4, O), (5, A), (6, A), (7, A), (8, A)]
    );
    assert_eq!(cut.items[0].distance, 0.0);
    assert_eq!(cut.items[1].distance, 50.0);
}

#[test]
fn culling_drops_nodes_behind_the_camera() {
    // Eye inside node 6 looking +x: nodes 1 and 7 are behind, node 8 is beside the view (outside the
    // right plane by 10 m at its nearest corner).
    let cut = cut_of(
        &tree_a(),
        &cam([300.0, 30.0, 90.0], [1000.0, 30.0, 90.0]),
        1.0,
    );
    assert_eq!(pairs(&cut), [(6, O)]);
    assert_eq!((cut.visited, cut.culled), (5, 3));
    // Looking away from the whole scene: the root is culled and nothing else is visited.
    let cut = cut_of(
        &tree_a(),
        &cam([-100.0, 10.0, 200.0], [-200.0, 10.0, 200.0]),
        1.0,
    );
    assert_eq!((cut.items.len(), cut.visited, cut.culled), (0, 1, 1));
}

#[test]
fn camera_exactly_at_min_distance_descends() {
    // Node 1 (min_distance 100) is exactly 100 away: it descends; slightly smaller scale: its atlas.
    let c = cam([200.0, 10.0, -100.0], [200.0, 10.0, 0.0]);
    let cut = cut_of(&tree_a(), &c, 1.0);
    assert_eq!(
        pairs(&cut),
        [(2, A), (3, A), (4, A), (5, A), (6, A), (7, A), (8, A)]
    );
    assert_eq!(cut.items[1].distance, 100.0);
    let cut = cut_of(&tree_a(), &c, 0.99);
    assert_eq!(pairs(&cut), [(1, A), (6, A), (7, A), (8, A)]);
}

#[test]
fn far_plane_touching_is_visible_beyond_is_culled() {
    // Nodes 7 and 8 start at depth exactly 300.
    let at_far = |far| {
        cut_of(
            &tree_a(),
            &Camera {
                far,
                ..cam([200.0, 10.0, -100.0], [200.0, 10.0, 0.0])
            },
            1.0,
        )
    };
    let cut = at_far(300.0);
    assert_eq!(
        pairs(&cut),
        [(2, A), (3, A), (4, A), (5, A), (6, A), (7, A), (8, A)]
    );
    assert_eq!(cut.culled, 0);
    let cut = at_far(299.5);
    assert_eq!(pairs(&cut), [(2, A), (3, A), (4, A), (5, A), (6, A)]);
    assert_eq!(cut.culled, 2);
}

#[test]
fn looking_straight_down() {
    // 60 m above gc0's centre, up = +Y parallel to the view: the footprint seen at the ground is
    // z ∈ [-10, 110] (horizontal fov 90°) × x ∈ [16.25, 83.75] (aspect 16:9).
    let c = cam([50.0, 60.0, 50.0], [50.0, 0.0, 50.0]);
    let f = c.frustum();
    assert_eq!(
        f.classify_aabb(DVec3::new(0.0, 0.0, 100.0), DVec3::new(100.0, 20.0, 200.0)),
        Visibility::Intersects
    );
    let cut = cut_of(&tree_a(), &c, 1.0);
    assert_eq!(pairs(&cut), [(2, O), (4, A)]);
    assert_eq!(cut.items[0].distance, 40.0);
    assert_eq!((cut.visited, cut.culled), (9, 5));
}

#[test]
fn looking_along_the_plane_at_eye_height() {
    let cut = cut_of(
        &tree_a(),
        &cam([-50.0, 1.7, 150.0], [1000.0, 1.7, 150.0]),
        1.0,
    );
    // gc2 is exactly 50 away along x: originals; gc0 at 70.7: atlas.
    assert_eq!(
        pairs(&cut),
        [(2, A), (3, A), (4, O), (5, A), (6, A), (7, A), (8, A)]
    );
}

#[test]
fn incomplete_quadtree() {
    // Inside leaf 3 looking towards leaf 4; leaf 1 is beside/behind the view.
    let cut = cut_of(
        &tree_b(),
        &cam([350.0, 5.0, 250.0], [250.0, 0.0, 350.0]),
        1.0,
    );
    assert_eq!(pairs(&cut), [(3, O), (4, A)]);
    assert_eq!((cut.visited, cut.culled), (5, 1));
    // Far away: root; mid distance: the two children of the root.
    assert_eq!(
        pairs(&cut_of(
            &tree_b(),
            &cam([200.0, 600.0, 200.0], [200.0, 0.0, 199.0]),
            1.0
        )),
        [(0, A)]
    );
    let cut = cut_of(
        &tree_b(),
        &cam([200.0, 150.0, 200.0], [200.0, 0.0, 199.0]),
        1.0,
    );
    assert_eq!(pairs(&cut), [(1, A), (2, A)]);
}

#[test]
fn identical_frames_give_identical_cuts() {
    let nodes = berlin(7);
    let path = CameraPath::overview_dive(
        bounds(&nodes).0,
        bounds(&nodes).1,
        atlastree::scene::UpAxis::Y,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut reused = Cut::new();
    for c in path.frames(10.0, 200) {
        let f = c.frustum();
        select(&nodes, &c, &f, 1.0, &mut reused);
        let mut fresh = Cut::new();
        select(&nodes, &c, &f, 1.0, &mut fresh);
        assert_eq!(
            reused.items, fresh.items,
            "bit-identical items incl. distances"
        );
        assert_eq!(
            (reused.visited, reused.culled),
            (fresh.visited, fresh.culled)
        );
        check_cut(&nodes, &f, &reused).unwrap_or_else(|e| panic!("{e}"));
    }
}

fn bounds(nodes: &[NodeRecord]) -> (DVec3, DVec3) {
    (nodes[0].bounds_min.into(), nodes[0].bounds_max.into())
}

fn translated_path(path: &CameraPath, t: DVec3) -> CameraPath {
    let mut p = path.clone();
    for k in &mut p.keyframes {
        k.eye = (DVec3::from(k.eye) + t).to_array();
        k.target = (DVec3::from(k.target) + t).to_array();
    }
    p
}

/// The same tree and path far from the origin give the same cut in every frame.
fn check_translation(nodes: &[NodeRecord], path: &CameraPath, t: DVec3) -> (usize, usize) {
    let moved = translate(nodes, t);
    let moved_path = translated_path(path, t);
    let (mut a, mut b) = (Cut::new(), Cut::new());
    let (mut max_items, mut originals) = (0, 0);
    for (c, mc) in path.frames(10.0, 200).zip(moved_path.frames(10.0, 200)) {
        select(nodes, &c, &c.frustum(), 1.0, &mut a);
        select(&moved, &mc, &mc.frustum(), 1.0, &mut b);
        assert_eq!(
            pairs(&a),
            pairs(&b),
            "translation {t}: eye {} vs {}",
            c.eye,
            mc.eye
        );
        assert_eq!((a.visited, a.culled), (b.visited, b.culled));
        for (x, y) in a.items.iter().zip(&b.items) {
            assert!(
                (x.distance - y.distance).abs() <= 1e-6 * (1.0 + x.distance),
                "{x:?} vs {y:?}"
            );
        }
        max_items = max_items.max(a.items.len());
        originals += a.items.iter().filter(|i| i.source == O).count();
    }
    (max_items, originals)
}

#[test]
fn huge_coordinates_give_identical_cuts() {
    let up = atlastree::scene::UpAxis::Y;
    for nodes in [tree_a(), berlin(3)] {
        let (lo, hi) = bounds(&nodes);
        for path in [
            CameraPath::overview_dive(lo, hi, up).unwrap_or_else(|e| panic!("{e}")),
            CameraPath::street(lo, hi, up).unwrap_or_else(|e| panic!("{e}")),
        ] {
            for t in [DVec3::new(4.5e6, 120.0, 5.5e6), DVec3::splat(1e7)] {
                let (max_items, originals) = check_translation(&nodes, &path, t);
                // The comparison is not vacuous: the paths reach fine cuts and original textures.
                assert!(
                    max_items >= 4 && originals > 0,
                    "{max_items} items, {originals} originals"
                );
            }
        }
    }
}

#[test]
fn berlin_tree_has_the_intended_size() {
    for seed in [1, 3, 7] {
        let nodes = berlin(seed);
        let depth = nodes.iter().map(|n| n.level).max().unwrap_or(0);
        assert!(
            (3000..=5000).contains(&nodes.len()),
            "seed {seed}: {} nodes",
            nodes.len()
        );
        assert!((6..=7).contains(&depth), "seed {seed}: depth {depth}");
    }
}
