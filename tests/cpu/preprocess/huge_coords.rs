//! Huge coordinates (hard case 2 of issue 8). The same scene at the origin, at UTM-like
//! (4.5e6, 120, 5.5e6) and at 1e7 on every axis.
//!
//! Guards against: any stage that works in absolute f32 positions (or mixes absolute coordinates into a
//! product before differencing). f32 has a 1 m ulp at 1e7, so an f32-absolute implementation moves
//! vertices by up to half a metre (measured below), wobbles the camera and changes culling and distance
//! decisions. We keep f64 everywhere on the CPU, store positions relative to the leaf origin and measure
//! every camera decision relative to the eye; then a translation by a representable vector must change
//! nothing but the stored bounds and origins: identical topology (levels, cells, children, index ranges,
//! leaf triangle sets), identical vertex records, identical atlas bytes, identical cuts along the same
//! relative camera path. (The GPU image comparison is the renderer's test.)

use crate::built::*;
use atlastree::camera::{Camera, CameraPath};
use atlastree::ids::BlockId;
use atlastree::scene::Scene;
use atlastree::scene::synthetic::small_city;
use atlastree::select::{Cut, SelectOptions, min_distance_scale, select};
use atlastree::store::TreeFile;
use glam::DVec3;

const SHIFTS: [DVec3; 2] = [DVec3::new(4.5e6, 120.0, 5.5e6), DVec3::new(1e7, 1e7, 1e7)];

fn translated(scene: &Scene, by: DVec3) -> Scene {
    let mut s = scene.clone();
    for v in &mut s.vertices {
        v.pos += by;
    }
    s
}

fn opts() -> atlastree::preprocess::BuildOptions {
    atlastree::preprocess::BuildOptions {
        d_min: atlastree::preprocess::DMin::Ratio(20.0),
        ..tiny_opts(128, 1.0)
    }
}

/// Snap to a 2^-16 m grid: such a point is representable at 1e7 too (f64 keeps 29 fractional bits
/// there), so "the same camera relative to the scene" exists exactly in every translated copy.
fn snap(p: DVec3) -> DVec3 {
    (p * 65536.0).round() / 65536.0
}

fn camera_path(file: &TreeFile) -> Vec<Camera> {
    let root = &file.tree(0).unwrap().nodes[0];
    let path = CameraPath::overview_dive(
        DVec3::from_array(root.bounds_min),
        DVec3::from_array(root.bounds_max),
        file.to_params().up,
    )
    .unwrap();
    path.frames(4.0, 80)
        .map(|c| Camera {
            eye: snap(c.eye),
            target: snap(c.target),
            ..c
        })
        .collect()
}

fn compare_files(a: &TreeFile, b: &TreeFile, by: DVec3) {
    let (ta, tb) = (a.tree(0).unwrap(), b.tree(0).unwrap());
    assert_eq!(ta.nodes.len(), tb.nodes.len());
    for (i, (x, y)) in ta.nodes.iter().zip(tb.nodes).enumerate() {
        assert_eq!(
            (x.level, x.cell, x.parent, x.children, x.leaf, x.atlas_block),
            (y.level, y.cell, y.parent, y.children, y.leaf, y.atlas_block),
            "node {i}"
        );
        assert_eq!(
            (x.first_index, x.index_count),
            (y.first_index, y.index_count)
        );
        assert_eq!(
            x.min_distance.to_bits(),
            y.min_distance.to_bits(),
            "node {i}"
        );
        assert_eq!(
            DVec3::from_array(x.bounds_min) + by,
            DVec3::from_array(y.bounds_min)
        );
        assert_eq!(
            DVec3::from_array(x.bounds_max) + by,
            DVec3::from_array(y.bounds_max)
        );
    }
    assert_eq!(ta.leaves.len(), tb.leaves.len());
    for (x, y) in ta.leaves.iter().zip(tb.leaves) {
        assert_eq!(
            DVec3::from_array(x.origin) + by,
            DVec3::from_array(y.origin)
        );
        assert_eq!(
            (
                x.node,
                x.first_vertex,
                x.vertex_count,
                x.first_index,
                x.index_count
            ),
            (
                y.node,
                y.first_vertex,
                y.vertex_count,
                y.first_index,
                y.index_count
            )
        );
        assert_eq!(x.clamp_scale.to_bits(), y.clamp_scale.to_bits());
        assert_eq!(ta.leaf_rects(x), tb.leaf_rects(y));
        assert_eq!(ta.leaf_originals(x), tb.leaf_originals(y));
    }
    // Leaf triangle sets and vertex records (positions are leaf-relative: bit for bit the same).
    assert_eq!(ta.source_triangles, tb.source_triangles);
    assert_eq!(ta.indices, tb.indices);
    assert!(ta.vertices == tb.vertices, "vertex records differ");
    // Every block: atlases and originals, byte for byte.
    assert_eq!(a.blocks().len(), b.blocks().len());
    for i in 0..a.blocks().len() as u32 {
        let (x, y) = (a.block(BlockId(i)).unwrap(), b.block(BlockId(i)).unwrap());
        assert!(x == y, "block {i} differs");
    }
}

#[test]
fn translation_changes_nothing_but_bounds_and_origins() {
    let scene = small_city(2, 64);
    let base = build_ok(&scene, &opts());
    assert_sound(&base.file);
    assert!(base.report.trees[0].depth >= 2, "want a multi-level tree");
    let cams = camera_path(&base.file);
    let scale = min_distance_scale(
        &base.file.to_params(),
        &SelectOptions::built_for(&base.file.to_params()),
    )
    .unwrap();
    let cuts = |file: &TreeFile, by: DVec3| -> Vec<Cut> {
        let nodes = file.tree(0).unwrap().nodes;
        cams.iter()
            .map(|c| {
                let c = Camera {
                    eye: c.eye + by,
                    target: c.target + by,
                    ..*c
                };
                let mut cut = Cut::new();
                select(nodes, &c, &c.frustum(), scale, &mut cut);
                cut
            })
            .collect()
    };
    let base_cuts = cuts(&base.file, DVec3::ZERO);
    let drawn: usize = base_cuts.iter().map(|c| c.items.len()).sum();
    assert!(
        drawn > cams.len(),
        "the path must select something: {drawn}"
    );
    for by in SHIFTS {
        let moved = build_ok(&translated(&scene, by), &opts());
        assert_sound(&moved.file);
        assert_eq!(moved.report.params.d_min, base.report.params.d_min);
        compare_files(&base.file, &moved.file, by);
        for (f, (x, y)) in base_cuts.iter().zip(cuts(&moved.file, by)).enumerate() {
            assert_eq!(x.items, y.items, "frame {f} at {by}");
            assert_eq!((x.visited, x.culled), (y.visited, y.culled), "frame {f}");
        }
    }
}

/// What an implementation keeping absolute positions in f32 would lose at 1e7: the error of every stored
/// vertex's world position rounded to f32, against ours (leaf origin in f64 + f32 offset).
#[test]
fn f32_absolute_positions_lose_half_a_metre_at_1e7() {
    // Half-metre offset: scene coordinates are then no longer integers, as in real data.
    let scene = translated(&small_city(2, 32), DVec3::splat(1e7 + 0.5));
    // Larger atlases: fewer split triangles, so most stored corners are scene corners.
    let built = build_ok(
        &scene,
        &atlastree::preprocess::BuildOptions {
            atlas_size: 512,
            ..opts()
        },
    );
    let t = built.file.tree(0).unwrap();
    let mut pieces = vec![0u32; scene.triangles.len()];
    for &s in t.source_triangles {
        pieces[s as usize] += 1;
    }
    let (mut naive, mut ours, mut unsplit) = (0f64, 0f64, 0);
    for leaf in t.leaves {
        let first = leaf.first_index as usize / 3;
        for k in 0..leaf.index_count as usize / 3 {
            let (world, _) = leaf_triangle(&t, leaf.origin, first + k);
            for w in &world {
                naive = naive.max((w.as_vec3().as_dvec3() - *w).abs().max_element());
            }
            // An unsplit triangle's stored corners are its scene corners: ours against the f64 truth.
            let src = t.source_triangles[first + k] as usize;
            if pieces[src] == 1 {
                unsplit += 1;
                let tri = scene.tri_positions(&scene.triangles[src]);
                for w in &world {
                    let d = tri
                        .iter()
                        .map(|p| (*p - *w).length())
                        .fold(f64::INFINITY, f64::min);
                    ours = ours.max(d);
                }
            }
        }
    }
    assert!(unsplit >= 40, "{unsplit}");
    let ulp = (1e7f32).next_up() - 1e7f32;
    eprintln!(
        "at 1e7: f32 ulp {ulp} m; f32-absolute positions off by up to {naive} m; ours (origin f64 + f32 \
         offset) off by at most {ours:.2e} m"
    );
    assert_eq!(ulp, 1.0);
    assert!(naive >= 0.25, "{naive}");
    assert!(ours < 1e-5, "{ours}");
}
