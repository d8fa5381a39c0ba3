use super::*;
use crate::camera::test_scenes::{self, Coast, SEA, SIDE};

/// Plane points on a regular lattice over the footprint (cell-aligned or not, by `step`).
fn lattice(step: f64) -> impl Iterator<Item = DVec2> {
    let n = (SIDE / step) as usize;
    (0..=n).flat_map(move |i| (0..=n).map(move |j| DVec2::new(i as f64, j as f64) * step))
}

fn town(coast: Coast) -> (Vec<[DVec3; 3]>, Ground) {
    let tris = test_scenes::coast(coast, 10.0, 20.0, 4);
    let (lo, hi) = test_scenes::bounds(&tris);
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris.iter().copied())
        .unwrap_or_else(|e| panic!("{e}"));
    (tris, g)
}

#[test]
fn the_town_is_at_zero_and_the_sea_floor_at_minus_600() {
    for coast in [Coast::West, Coast::North] {
        let (_, g) = town(coast);
        assert_eq!(g.cells(), [128, 128], "{coast:?}");
        assert_eq!(
            g.measured_cells(),
            128 * 128,
            "{coast:?}: every cell has ground"
        );
        assert_eq!((g.lowest(), g.highest()), (SEA, 0.0), "{coast:?}");
        // Exact away from the coastline (one cell is 7.8125 m; bilinear blends across it).
        let cell = SIDE / 128.0;
        for p in lattice(13.7).filter(|&p| coast.distance_to_coast(p) > cell) {
            let expect = if coast.on_town(p) { 0.0 } else { SEA };
            assert_eq!(g.height_at(p), expect, "{coast:?} at {p}");
        }
        // Under the buildings (roofs at 12 m) the ground is the plateau below them.
        let under_roof = match coast {
            Coast::West => DVec2::new(250.0, 510.0),
            Coast::North => DVec2::new(510.0, 750.0),
        };
        assert_eq!(g.height_at(under_roof), 0.0, "{coast:?}");
        // Beyond the footprint the outer cells continue.
        assert_eq!(
            g.height_at(DVec2::new(-50.0, -50.0)),
            g.height_at(DVec2::ZERO)
        );
    }
}

#[test]
fn content_is_where_most_triangles_are_not_the_sea_floor() {
    for coast in [Coast::West, Coast::North] {
        let (tris, g) = town(coast);
        assert!(g.content_cells() > 0, "{coast:?}");
        // The preferred dive spot lies over the sea; the nearest content is across the coast, close to it.
        let spot = DVec2::new(620.0, 370.0);
        assert!(!coast.on_town(spot));
        let c = g.content_near(spot);
        assert!(coast.on_town(c), "{coast:?}: {c}");
        assert!(
            coast.distance_to_coast(c) < 20.0,
            "{coast:?}: {c} is not the nearest"
        );
        // The sea floor's cells (too few triangles) and the cliff's (at the foot of a 600 m drop, West;
        // on the coast's town side, North) are not content in the sea: their nearest content is the
        // town's, at the town's level.
        for t in tris.iter().rev().take(4) {
            let centroid = (t[0] + t[1] + t[2]) / 3.0;
            let p = DVec2::new(centroid.x, centroid.z);
            let c = g.content_near(p);
            assert!(coast.on_town(c), "{coast:?}: sea centroid {p} → {c}");
            assert_eq!(g.height_at(c), 0.0, "{coast:?}: {p} → {c}");
        }
        // A content cell's centre is its own nearest content; a building's cell has content.
        assert_eq!(g.content_near(c), c);
        let house = match coast {
            Coast::West => DVec2::new(250.0, 510.0),
            Coast::North => DVec2::new(510.0, 750.0),
        };
        let c = g.content_near(house);
        assert!(
            (c - house).abs().max_element() <= SIDE / 256.0,
            "{coast:?}: {house} → {c}"
        );
    }
}

#[test]
fn stray_triangles_far_below_do_not_define_the_town() {
    let mut tris = test_scenes::coast(Coast::West, 10.0, 20.0, 4);
    // 900 m below the town: a small one (3 m legs) and one over a whole cell and most of two of its
    // neighbours (16 m legs from the corner of cell (13, 90)).
    let small = DVec3::new(200.0, -900.0, 300.0);
    tris.push([
        small,
        small + DVec3::new(3.0, 0.0, 0.0),
        small + DVec3::new(0.0, 0.0, 3.0),
    ]);
    let cell = SIDE / 128.0;
    let big = DVec3::new(13.0 * cell, -900.0, 90.0 * cell);
    tris.push([
        big,
        big + DVec3::new(16.0, 0.0, 0.0),
        big + DVec3::new(0.0, 0.0, 16.0),
    ]);
    let (lo, hi) = test_scenes::bounds(&tris);
    assert_eq!(lo.y, -900.0);
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris).unwrap_or_else(|e| panic!("{e}"));
    for p in [
        DVec2::new(201.0, 301.0),
        DVec2::new(13.5 * cell, 90.5 * cell),
        DVec2::new(14.5 * cell, 90.5 * cell),
        DVec2::new(13.5 * cell, 91.5 * cell),
        DVec2::new(105.0, 707.0),
    ] {
        assert_eq!(g.height_at(p), 0.0, "at {p}");
    }
    assert_eq!(g.lowest(), SEA);
}

#[test]
fn cells_without_ground_take_the_nearest_measured_height() {
    // The town alone, over bounds that also span the (empty) sea half.
    let tris: Vec<_> = test_scenes::coast(Coast::West, 10.0, 20.0, 4)
        .into_iter()
        .filter(|t| t.iter().all(|p| p.y >= 0.0))
        .collect();
    let (lo, hi) = (DVec3::new(0.0, SEA, 0.0), DVec3::new(SIDE, 12.0, SIDE));
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(g.measured_cells(), 64 * 128, "the town's half");
    for p in lattice(50.0) {
        assert_eq!(g.height_at(p), 0.0, "at {p}");
    }
    // Only walls: nothing is ground, the ground is flat at height(lo).
    let wall = [[
        DVec3::new(10.0, 0.0, 10.0),
        DVec3::new(20.0, 0.0, 10.0),
        DVec3::new(20.0, 12.0, 10.0),
    ]];
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, wall).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((g.measured_cells(), g.lowest(), g.highest()), (0, SEA, SEA));
    assert_eq!(g.content_cells(), 1, "the wall still is content");
    // No triangles at all: no content, content_near returns its argument.
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, []).unwrap_or_else(|e| panic!("{e}"));
    let p = DVec2::new(123.0, 456.0);
    assert_eq!((g.content_near(p), g.height_at(p)), (p, SEA));
}

#[test]
fn maxima_bound_the_interpolated_height() {
    let (_, g) = town(Coast::West);
    // Boxes and segments across the coast: the bound holds at every point in them and is attained.
    let boxes = [
        (DVec2::new(480.0, 100.0), DVec2::new(520.0, 140.0)),
        (DVec2::new(503.0, 10.0), DVec2::new(900.0, 990.0)),
        (DVec2::new(100.0, 100.0), DVec2::new(300.0, 200.0)),
        (DVec2::new(-10.0, -10.0), DVec2::new(1010.0, 1010.0)),
    ];
    for (a, b) in boxes {
        let (m, along) = (g.max_in_box(a, b), g.max_along(a, b));
        let mut top = f64::NEG_INFINITY;
        for i in 0..=40 {
            for j in 0..=40 {
                let p = a + (b - a) * DVec2::new(i as f64, j as f64) / 40.0;
                assert!(g.height_at(p) <= m, "{p}: {} > {m}", g.height_at(p));
                top = top.max(g.height_at(p));
            }
            let p = a.lerp(b, i as f64 / 40.0);
            assert!(g.height_at(p) <= along, "{p} on {a}→{b}");
        }
        let attained = if b.x < 500.0 - 8.0 || a.x > 500.0 + 8.0 {
            top == m
        } else {
            m == 0.0
        };
        assert!(attained, "{a}..{b}: max {m}, sampled {top}");
    }
    assert_eq!(
        g.max_in_box(DVec2::new(600.0, 10.0), DVec2::new(900.0, 990.0)),
        SEA
    );
    assert_eq!(
        g.max_along(DVec2::new(600.0, 10.0), DVec2::new(900.0, 990.0)),
        SEA
    );
}

#[test]
fn flat_ground_is_the_lowest_point_everywhere() {
    let (lo, hi) = (
        DVec3::new(4.5e6, 31.3, 5.5e6),
        DVec3::new(4.51e6, 187.1, 5.513e6),
    );
    let g = Ground::flat(lo, hi, UpAxis::Y);
    assert_eq!(
        (g.cells(), g.measured_cells(), g.content_cells()),
        ([1, 1], 0, 0)
    );
    for p in [
        DVec2::new(4.5e6, 5.5e6),
        DVec2::new(4.505e6, 5.51e6),
        DVec2::ZERO,
    ] {
        assert_eq!(g.height_at(p), 31.3);
        assert_eq!(g.content_near(p), p);
        assert_eq!(g.max_in_box(p, p + 5000.0), 31.3);
        assert_eq!(g.max_along(p, p + 5000.0), 31.3);
    }
    assert_eq!(g.bounds(), (lo, hi));
}

#[test]
fn other_up_axes_and_huge_coordinates() {
    // The West town turned z-up (y ↔ z) and moved to UTM-size coordinates.
    let shift = DVec3::new(4.5e6, 5.5e6, 120.0);
    let tris: Vec<[DVec3; 3]> = test_scenes::coast(Coast::West, 10.0, 20.0, 4)
        .into_iter()
        .map(|t| t.map(|p| DVec3::new(p.x, p.z, p.y) + shift))
        .collect();
    let (lo, hi) = test_scenes::bounds(&tris);
    let g = Ground::from_triangles(lo, hi, UpAxis::Z, tris).unwrap_or_else(|e| panic!("{e}"));
    let at = |x: f64, y: f64| g.height_at(DVec2::new(x, y) + shift.truncate());
    assert_eq!((at(100.0, 300.0), at(900.0, 300.0)), (120.0, 120.0 + SEA));
    let c = g.content_near(DVec2::new(620.0, 370.0) + shift.truncate());
    assert!(c.x - shift.x < 500.0, "{c}");
}

#[test]
fn bad_inputs_are_errors() {
    let tris = test_scenes::coast(Coast::West, 50.0, 100.0, 1);
    let (lo, hi) = test_scenes::bounds(&tris);
    let e = Ground::from_triangles(hi, lo, UpAxis::Y, tris.iter().copied());
    assert!(matches!(e, Err(GroundError::BadBounds { .. })), "{e:?}");
    let e = Ground::from_triangles(lo, DVec3::splat(f64::NAN), UpAxis::Y, []);
    assert!(matches!(e, Err(GroundError::BadBounds { .. })), "{e:?}");
    let e = Ground::from_triangles_in(lo, hi, UpAxis::Y, 0, []);
    assert!(
        matches!(
            e,
            Err(GroundError::BadCells {
                cells: 0,
                max: Ground::MAX_CELLS
            })
        ),
        "{e:?}"
    );
    let empty = crate::scene::synthetic::SceneBuilder::new(UpAxis::Y).build();
    let e = Ground::from_scene(&empty);
    assert!(matches!(e, Err(GroundError::NoGeometry)), "{e:?}");
    // Non-finite triangles are skipped.
    let nan = [[DVec3::splat(f64::NAN), DVec3::ZERO, DVec3::ONE]];
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, nan).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((g.measured_cells(), g.content_cells()), (0, 0));
    // A coarser grid, proportional on the shorter side.
    let g = Ground::from_triangles_in(
        DVec3::ZERO,
        DVec3::new(1000.0, 1.0, 250.0),
        UpAxis::Y,
        16,
        [],
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(g.cells(), [16, 4]);
}

#[test]
fn from_scene_and_from_tree_see_the_same_ground() {
    let tris = test_scenes::coast(Coast::West, 20.0, 40.0, 1);
    let scene = test_scenes::scene(&tris);
    let from_scene = Ground::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    let (lo, hi) = test_scenes::bounds(&tris);
    let direct = Ground::from_triangles(lo, hi, UpAxis::Y, tris.iter().copied())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(from_scene, direct);

    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("coast.atlastree");
    let opts = crate::preprocess::BuildOptions {
        d_min: crate::preprocess::DMin::Ratio(10.0),
        atlas_size: 256,
        border: 8,
        ..Default::default()
    };
    crate::preprocess::build(&scene, &opts, &out, &crate::preprocess::NoProgress)
        .unwrap_or_else(|e| panic!("{e}"));
    let file = TreeFile::open(&out).unwrap_or_else(|e| panic!("{e}"));
    let from_tree = Ground::from_tree(&file).unwrap_or_else(|e| panic!("{e}"));
    let ((tlo, thi), (slo, shi)) = (from_tree.bounds(), from_scene.bounds());
    assert!(
        tlo.abs_diff_eq(slo, 1e-3) && thi.abs_diff_eq(shi, 1e-3),
        "{tlo}..{thi} vs {slo}..{shi}"
    );
    assert_eq!(from_tree.cells(), from_scene.cells());
    // f32 vertex offsets from the leaf origins: heights agree to well under a millimetre (away from
    // the coastline, where one cell blends 600 m).
    for p in lattice(9.1).filter(|&p| Coast::West.distance_to_coast(p) > 2.0 * SIDE / 128.0) {
        let (a, b) = (from_tree.height_at(p), from_scene.height_at(p));
        assert!((a - b).abs() < 1e-3, "at {p}: tree {a}, scene {b}");
    }
    let spot = DVec2::new(620.0, 370.0);
    let c = from_tree.content_near(spot);
    assert!(Coast::West.on_town(c), "{c}");
    assert_eq!(c, from_scene.content_near(spot));
    assert_eq!(from_tree.content_cells(), from_scene.content_cells());
}

#[test]
fn a_dense_prop_far_out_over_the_sea_is_not_where_a_dive_goes() {
    for coast in [Coast::West, Coast::North] {
        let mut tris = test_scenes::coast(coast, 10.0, 20.0, 4);
        // An "airplane": a dense 20 m box of many storeys 300 m above the sea, right at the preferred
        // dive spot (620, 370), far from the town (a track's decorative prop).
        let before = tris.len();
        test_scenes::prop(&mut tris, DVec3::new(610.0, -300.0, 360.0), 20.0, 64);
        assert!(tris.len() - before > 500);
        let (lo, hi) = test_scenes::bounds(&tris);
        let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris.iter().copied())
            .unwrap_or_else(|e| panic!("{e}"));
        let spot = DVec2::new(620.0, 370.0);
        let c = g.content_near(spot);
        assert!(
            coast.on_town(c),
            "{coast:?}: the dive goes to {c}, not the town"
        );
        assert!(coast.distance_to_coast(c) < 20.0, "{coast:?}: {c}");
    }
}
