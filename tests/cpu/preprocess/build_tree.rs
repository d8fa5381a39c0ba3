//! The preprocessor end to end on scenes built in code: the file verifies, the d_min guarantee holds for
//! every triangle at its leaf and at every ancestor, builds are deterministic and atomic.

use crate::built::{f_proj_params, pixels_per_texel};
use atlastree::ids::NONE;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::scene::synthetic::small_city;
use atlastree::store::TreeFile;
use glam::DVec3;

fn opts(atlas: u32) -> BuildOptions {
    BuildOptions {
        d_min: DMin::Ratio(20.0),
        atlas_size: atlas,
        // The paper's border: the 64² atlases of these tests were sized around it.
        border: 8,
        max_file_bytes: 1 << 30,
        // The paper's tree: every node that does not fit one atlas is split (multi-level).
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    }
}

#[test]
fn small_city_builds_a_multilevel_tree_that_verifies() {
    let scene = small_city(6, 64);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let report = build(&scene, &opts(256), &out, &NoProgress).unwrap();
    let t = &report.trees[0];
    assert!(
        t.depth >= 2,
        "expected a multi-level tree, got depth {}",
        t.depth
    );
    assert_eq!(t.triangles as usize, scene.triangles.len());
    let file = TreeFile::open(&out).unwrap();
    let v = atlastree::inspect::verify(&file);
    assert!(v.ok(), "violations: {:#?}", v.violations);
    assert_eq!(
        v.triangles_checked as usize - v.split_pieces as usize,
        scene.triangles.len()
    );
    assert_eq!(v.blocks_checked, report.blocks);
    // The throughput counters of the report: uncompressed, every stored texel is 4 bytes of some block,
    // so the texels the report says it stored are the file's block bytes over 4; the cache holds every
    // image of this small scene, so each used image is decoded exactly once.
    let block_bytes: u64 = file.blocks().iter().map(|b| b.length).sum();
    assert!(report.texels_stored > 0);
    assert_eq!(report.texels_stored * 4, block_bytes);
    let mut used: Vec<usize> = scene.materials.iter().map(|m| m.image.idx()).collect();
    used.sort_unstable();
    used.dedup();
    let used_texels: u64 = used
        .iter()
        .map(|&i| u64::from(scene.images[i].width) * u64::from(scene.images[i].height))
        .sum();
    assert_eq!(report.images_decoded as usize, used.len());
    assert_eq!(report.texels_decoded, used_texels);
}

#[test]
fn d_min_guarantee_holds_at_leaves_and_every_ancestor() {
    let scene = small_city(3, 128);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("g.atlastree");
    // Without the source cap (the paper's setting) the guarantee must hold for every texture.
    let o = BuildOptions {
        d_min: DMin::Metres(150.0),
        cap_to_source: false,
        ..opts(128)
    };
    let rep = build(&scene, &o, &out, &NoProgress).unwrap();
    assert_eq!(rep.trees[0].capped_rects, 0);
    assert!(rep.trees[0].depth >= 2, "depth {}", rep.trees[0].depth);
    let file = TreeFile::open(&out).unwrap();
    let p = file.to_params();
    let t = file.tree(0).unwrap();

    let mut checked = 0;
    let mut worst: f64 = 0.0;
    for leaf in t.leaves {
        let node = &t.nodes[leaf.node as usize];
        let idx =
            &t.indices[leaf.first_index as usize..(leaf.first_index + leaf.index_count) as usize];
        for tri in idx.chunks(3) {
            let v = [tri[0], tri[1], tri[2]].map(|i| t.vertices[i as usize]);
            let pos = v.map(|v| DVec3::from_array(v.pos.map(f64::from)));
            let uv = v.map(|v| crate::built::vertex_atlas_texels(&t, leaf, &v));
            // Walk up: at level j the texel is 2^(K-j) leaf texels wide, seen from that node's min_distance.
            let mut n = node;
            let mut scale = 1.0;
            loop {
                let uv_j = uv.map(|u| u / scale);
                if let Some(r) = pixels_per_texel(pos, uv_j, f_proj_params(&p, n.min_distance)) {
                    worst = worst.max(r);
                    assert!(
                        r <= 1.01,
                        "level {}: {r} pixels per texel at min_distance {}",
                        n.level,
                        n.min_distance
                    );
                    checked += 1;
                }
                if n.parent == NONE {
                    break;
                }
                n = &t.nodes[n.parent as usize];
                scale *= 2.0;
            }
        }
    }
    assert!(checked > 100, "checked only {checked}");
    eprintln!(
        "d_min guarantee: {checked} (triangle, level) pairs, worst {worst:.4} pixels per texel"
    );
}

#[test]
fn builds_are_deterministic_byte_for_byte() {
    let scene = small_city(2, 64);
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.atlastree");
    let b = dir.path().join("b.atlastree");
    build(&scene, &opts(128), &a, &NoProgress).unwrap();
    build(&scene, &opts(128), &b, &NoProgress).unwrap();
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "two builds differ"
    );
    // An image cache too small to hold a leaf's sources draws every leaf's level 0 whole instead of band
    // by band (`preprocess::leaf::leaf_start`): the same bytes. No memory budget, or the budget would
    // raise the cache to its floor (64 MiB) and the leaves would be banded again.
    let c = dir.path().join("c.atlastree");
    let whole = BuildOptions {
        image_cache_bytes: 1,
        max_memory_bytes: None,
        ..opts(128)
    };
    build(&scene, &whole, &c, &NoProgress).unwrap();
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&c).unwrap(),
        "leaves drawn whole differ from leaves drawn band by band"
    );
}

#[test]
fn failed_build_leaves_no_file() {
    let scene = small_city(2, 64);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.atlastree");
    // Depth 1 cannot hold this city in 64² atlases: the build must fail and write nothing.
    let o = BuildOptions {
        max_depth: 1,
        ..opts(64)
    };
    let err = build(&scene, &o, &out, &NoProgress).unwrap_err();
    assert!(err.to_string().contains("max-depth"), "{err}");
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temp files left behind"
    );
    // A build that would be absurdly large is refused before anything is written.
    let o = BuildOptions {
        max_file_bytes: 1 << 20,
        ..opts(128)
    };
    let err = build(&scene, &o, &out, &NoProgress).unwrap_err();
    assert!(err.to_string().contains("--max-file-gib"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // Its advice is what applies: the source cap is kept already, the file is uncompressed.
    let text = err.to_string();
    assert!(text.contains("raise --max-file-gib"), "{text}");
    assert!(text.contains("--compress bc1"), "{text}");
    assert!(!text.contains("source cap"), "{text}");
    // The limit is the whole file's length, tables and geometry included: a limit one byte below the
    // file written is refused, the file's own length is not (blocks alone were compared before, and a
    // geometry-heavy file could pass at 3.9× its limit).
    let summary = build(&scene, &opts(128), &out, &NoProgress).unwrap();
    let len = std::fs::metadata(&out).unwrap().len();
    assert_eq!(summary.file_bytes, len);
    std::fs::remove_file(&out).unwrap();
    let at = |max_file_bytes| {
        let o = BuildOptions {
            max_file_bytes,
            ..opts(128)
        };
        build(&scene, &o, &out, &NoProgress)
    };
    let err = at(len - 1).unwrap_err();
    assert!(
        err.to_string().contains(&format!("a file of {len} bytes")),
        "{err}"
    );
    assert!(!out.exists());
    at(len).unwrap();
    assert_eq!(std::fs::metadata(&out).unwrap().len(), len);
}

#[test]
fn invalid_parameters_are_named() {
    let scene = small_city(1, 16);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.atlastree");
    for (o, name) in [
        (
            BuildOptions {
                atlas_size: 1000,
                ..opts(256)
            },
            "atlas-size",
        ),
        (
            BuildOptions {
                d_min: DMin::Metres(-1.0),
                ..opts(256)
            },
            "d-min",
        ),
        (
            BuildOptions {
                fov_deg: 180.0,
                ..opts(256)
            },
            "fov",
        ),
    ] {
        let e = build(&scene, &o, &out, &NoProgress)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{e}");
    }
}

/// Every scene triangle is in exactly one leaf, or split into pieces that tile it exactly: the world areas of
/// a triangle's pieces (reconstructed from the stored leaf-relative vertices) sum to its area.
#[test]
fn every_triangle_is_covered_exactly_once_even_when_split() {
    let scene = small_city(2, 64);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.atlastree");
    // A small atlas forces the ground quad (and long walls) to be split when repeats are baked.
    let baked = BuildOptions {
        repeat: atlastree::preprocess::RepeatMode::Bake,
        ..opts(128)
    };
    let report = build(&scene, &baked, &out, &NoProgress).unwrap();
    assert!(
        report.trees[0].pieces > report.trees[0].triangles,
        "nothing was split"
    );
    let file = TreeFile::open(&out).unwrap();
    // `inspect` counts as the build does: scene triangles, and the pieces stored (it called the pieces
    // triangles: flag hunt, session 35).
    let info = &atlastree::inspect::inspect(&file).trees[0];
    assert_eq!(
        (info.triangles, info.pieces),
        (report.trees[0].triangles, report.trees[0].pieces)
    );
    let t = file.tree(0).unwrap();
    // Per level: the pieces its leaves store, and the distinct scene triangles they come from, counted
    // here from the leaves' own records.
    let mut per_level: Vec<(u64, std::collections::BTreeSet<u32>)> =
        vec![Default::default(); info.levels.len()];
    for leaf in t.leaves {
        let level = t.nodes[leaf.node as usize].level as usize;
        let first = leaf.first_index as usize / 3;
        let pieces = &t.source_triangles[first..first + leaf.index_count as usize / 3];
        per_level[level].0 += pieces.len() as u64;
        per_level[level].1.extend(pieces);
    }
    for (l, (pieces, sources)) in info.levels.iter().zip(&per_level) {
        assert_eq!(
            (l.pieces_in_leaves, l.triangles_in_leaves),
            (*pieces, sources.len() as u64),
            "level {}",
            l.level
        );
    }
    let stored: u64 = info.levels.iter().map(|l| l.pieces_in_leaves).sum();
    assert_eq!(stored, info.pieces);
    assert!(
        info.levels
            .iter()
            .any(|l| l.pieces_in_leaves > l.triangles_in_leaves)
    );
    let mut covered = vec![0.0f64; scene.triangles.len()];
    for leaf in t.leaves {
        let o = DVec3::from_array(leaf.origin);
        let first_tri = leaf.first_index as usize / 3;
        for k in 0..(leaf.index_count as usize / 3) {
            let idx = &t.indices[(first_tri + k) * 3..(first_tri + k) * 3 + 3];
            let p = [idx[0], idx[1], idx[2]]
                .map(|i| o + DVec3::from_array(t.vertices[i as usize].pos.map(f64::from)));
            covered[t.source_triangles[first_tri + k] as usize] +=
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        }
    }
    for (i, tri) in scene.triangles.iter().enumerate() {
        let p = scene.tri_positions(tri);
        let want = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        assert!(
            (covered[i] - want).abs() <= 1e-4 * want.max(1.0),
            "triangle {i}: pieces cover {} of {want}",
            covered[i]
        );
    }
}
