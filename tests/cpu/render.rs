//! `render::batch` and the CPU half of `render::resident` without a GPU: on a real built tree and cuts of
//! many sizes, the indirect records are exactly the cut (counts, index ranges, base vertex), `first_instance`
//! numbers the node records, passes partition the records, leaf ranges are the subtrees' leaves, and leaf
//! offsets are `origin − eye` for exactly the leaves under the cut, and a blend node's blend-pass record
//! draws exactly its BLEND triangles.

use atlastree::camera::CameraPath;
use atlastree::ids::NONE;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::batch::{AtlasSlot, FrameBatch, Group, LeafOffsets, Pass, leaf_ranges};
use atlastree::render::resident::gather_tables;
use atlastree::render::textures::MAX_ATLAS_ARRAYS;
use atlastree::select::{Cut, Source, select};
use atlastree::store::TreeFile;
use glam::DVec3;

fn city_file(dir: &std::path::Path) -> TreeFile {
    let scene = atlastree::scene::synthetic::small_city(4, 64);
    let out = dir.join("city.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(20.0),
        atlas_size: 128,
        max_file_bytes: 1 << 30,
        border: 8,
        // The paper's tree: every node that does not fit one atlas is split (multi-level).
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    build(&scene, &opts, &out, &NoProgress).unwrap();
    TreeFile::open(&out).unwrap()
}

/// The leaves of the subtree of `node`, by walking child links.
/// The overview-dive over tree 0's root bounds.
fn dive_over(file: &TreeFile, nodes: &[atlastree::store::format::NodeRecord]) -> CameraPath {
    let root = nodes[0];
    CameraPath::overview_dive(
        root.bounds_min.into(),
        root.bounds_max.into(),
        file.to_params().up,
    )
    .unwrap()
}

fn subtree_leaves(nodes: &[atlastree::store::format::NodeRecord], node: usize) -> Vec<u32> {
    let mut out = Vec::new();
    let mut stack = vec![node];
    while let Some(n) = stack.pop() {
        if nodes[n].leaf != NONE {
            out.push(nodes[n].leaf);
        }
        stack.extend(
            nodes[n]
                .children
                .iter()
                .filter(|&&c| c != NONE)
                .map(|&c| c as usize),
        );
    }
    out.sort_unstable();
    out
}

#[test]
fn leaf_ranges_are_the_subtrees_leaves() {
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let view = file.tree(0).unwrap();
    assert!(view.nodes.len() > 5, "need a multi-level tree");
    let ranges = leaf_ranges(view.nodes);
    for (i, &(first, count)) in ranges.iter().enumerate() {
        let want = subtree_leaves(view.nodes, i);
        let got: Vec<u32> = (first..first + count).collect();
        assert_eq!(got, want, "node {i}");
    }
    assert_eq!(ranges[0], (0, view.leaves.len() as u32));
}

#[test]
fn records_match_the_cut_and_first_instance_numbers_them() {
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let mut p = gather_tables(&file).unwrap();
    let view = file.tree(0).unwrap();
    // Resident atlas slots as the uploader assigns them: layers in node order.
    for (layer, slot) in p.infos[0].atlas_slots.iter_mut().enumerate() {
        *slot = Some(AtlasSlot {
            array: 0,
            layer: layer as u32,
        });
    }
    let info = &p.infos[0];
    assert_eq!(
        (info.leaf_base, info.index_base, info.vertex_base),
        (0, 0, 0)
    );
    assert!(info.passes.iter().all(|&q| q == Pass::Opaque));

    let path = dive_over(&file, view.nodes);
    let mut cut = Cut::new();
    let mut batch = FrameBatch::new();
    let mut offsets = LeafOffsets::new(p.origins.clone());
    let mut sizes = Vec::new();
    for (i, cam) in path.frames(2.0, 40).enumerate() {
        let scale = [0.5, 1.0, 4.0][i % 3];
        select(view.nodes, &cam, &cam.frustum(), scale, &mut cut);
        batch.clear();
        let skipped = batch.add_cut(info, view.nodes, &cut, None);
        batch.finish();
        assert_eq!(skipped, 0);
        assert_eq!(batch.len(), cut.items.len());
        assert_eq!(batch.records.len(), batch.indirect.len());
        sizes.push(cut.items.len());
        // Opaque tree only: the opaque atlas group, then the opaque originals group, hold everything.
        let atlas = cut
            .items
            .iter()
            .filter(|i| i.source == Source::Atlas)
            .count() as u32;
        let r = batch.group_ranges;
        assert_eq!(r[Group::new(Pass::Opaque, false).index()], (0, atlas));
        assert_eq!(
            r[Group::new(Pass::Opaque, true).index()],
            (atlas, batch.len() as u32 - atlas)
        );
        let (opaque_atlas, opaque_originals) = (
            Group::new(Pass::Opaque, false).index(),
            Group::new(Pass::Opaque, true).index(),
        );
        assert!(
            r.iter()
                .enumerate()
                .all(|(g, &(_, n))| g == opaque_atlas || g == opaque_originals || n == 0)
        );
        let mut triangles = 0u64;
        let mut originals = 0;
        // Records are the cut's items, atlas items first (each group keeps tree order).
        let order: Vec<usize> = (0..cut.items.len())
            .filter(|&i| cut.items[i].source == Source::Atlas)
            .chain((0..cut.items.len()).filter(|&i| cut.items[i].source == Source::Original))
            .collect();
        for (k, (d, r)) in batch.indirect.iter().zip(&batch.records).enumerate() {
            let item = &cut.items[order[k]];
            assert_eq!(
                d.first_instance, k as u32,
                "first_instance numbers the records"
            );
            assert_eq!(d.instance_count, 1);
            assert_eq!(
                (d.first_index, d.index_count),
                (item.first_index, item.index_count)
            );
            assert_eq!(d.base_vertex, 0);
            assert_eq!(r.node, item.node.0);
            assert_eq!(r.level, u32::from(item.level));
            let node = &view.nodes[item.node.idx()];
            assert_eq!(
                (node.first_index, node.index_count),
                (d.first_index, d.index_count)
            );
            match item.source {
                Source::Atlas => assert_eq!(r.atlas_layer, item.node.0),
                Source::Original => {
                    assert_eq!(r.atlas_layer, NONE);
                    assert_ne!(node.leaf, NONE, "originals only at leaves");
                    originals += 1;
                }
            }
            triangles += u64::from(d.index_count / 3);
        }
        assert_eq!(batch.triangles, triangles);
        assert_eq!(batch.original_records, originals);

        // Leaf offsets: exactly the leaves under the cut, origin − eye in f64 rounded once to f32.
        offsets.offsets.iter_mut().for_each(|o| *o = [f32::NAN; 4]);
        let updated = offsets.update(info, &cut, cam.eye);
        let mut under: Vec<u32> = cut
            .items
            .iter()
            .flat_map(|it| subtree_leaves(view.nodes, it.node.idx()))
            .collect();
        under.sort_unstable();
        assert_eq!(updated as usize, under.len());
        for (l, o) in offsets.offsets.iter().enumerate() {
            if under.binary_search(&(l as u32)).is_ok() {
                let d = p.origins[l] - cam.eye;
                assert_eq!(o[..3], [d.x as f32, d.y as f32, d.z as f32], "leaf {l}");
            } else {
                assert!(o[0].is_nan(), "leaf {l} updated but not under the cut");
            }
        }
    }
    let (min, max) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
    assert!(max > &(min + 3), "cuts should vary in size: {sizes:?}");

    // A missing atlas skips the item.
    p.infos[0].atlas_slots.iter_mut().for_each(|s| *s = None);
    batch.clear();
    let atlas_items = cut
        .items
        .iter()
        .filter(|i| i.source == Source::Atlas)
        .count();
    let skipped = batch.add_cut(&p.infos[0], view.nodes, &cut, None);
    batch.finish();
    assert_eq!(skipped as usize, atlas_items);
    assert_eq!(batch.len(), cut.items.len() - atlas_items);
}

#[test]
fn groups_are_numbered_in_draw_order() {
    for (i, g) in Group::ALL.iter().enumerate() {
        assert_eq!(g.index(), i, "{g:?}");
        assert!(g.array == 0 || !g.original, "{g:?}");
    }
    // Per pass: atlas arrays 0 … 3, then the originals; passes opaque, mask, blend.
    assert_eq!(Group::ALL[3], Group::atlas(Pass::Opaque, 3));
    assert_eq!(Group::ALL[4], Group::new(Pass::Opaque, true));
    assert_eq!(Group::ALL[5], Group::atlas(Pass::Mask, 0));
}

#[test]
fn atlas_records_are_grouped_by_their_array() {
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let mut p = gather_tables(&file).unwrap();
    let view = file.tree(0).unwrap();
    // Atlases spread over three arrays (as past a device's layer limit).
    for (n, slot) in p.infos[0].atlas_slots.iter_mut().enumerate() {
        *slot = Some(AtlasSlot {
            array: n as u32 % 3,
            layer: n as u32 / 3,
        });
    }
    let path = dive_over(&file, view.nodes);
    let mut cut = Cut::new();
    let mut batch = FrameBatch::new();
    let mut arrays_seen = [false; 3];
    for cam in path.frames(2.0, 40) {
        select(view.nodes, &cam, &cam.frustum(), 4.0, &mut cut);
        batch.clear();
        assert_eq!(batch.add_cut(&p.infos[0], view.nodes, &cut, None), 0);
        batch.finish();
        let mut drawn = 0;
        for g in Group::ALL {
            let (first, count) = batch.group_ranges[g.index()];
            drawn += count;
            for r in &batch.records[first as usize..(first + count) as usize] {
                if g.original {
                    assert_eq!(r.atlas_layer, NONE, "{g:?}");
                } else {
                    assert_eq!(r.atlas_array, u32::from(g.array), "{g:?}");
                    assert_eq!(r.atlas_array, r.node % 3, "node {}", r.node);
                    arrays_seen[r.atlas_array as usize] = true;
                }
            }
        }
        assert_eq!(drawn as usize, cut.items.len());
    }
    assert_eq!(
        arrays_seen, [true; 3],
        "the path draws atlases of every array"
    );

    // A slot in an array past the pipelines' (a broken slot table) is skipped and counted, never
    // clamped into the last array.
    let past = MAX_ATLAS_ARRAYS as u32;
    for slot in p.infos[0].atlas_slots.iter_mut().flatten() {
        if slot.array == 2 {
            slot.array = past;
        }
    }
    let mut skipped_total = 0;
    for cam in path.frames(2.0, 40) {
        select(view.nodes, &cam, &cam.frustum(), 4.0, &mut cut);
        batch.clear();
        let want = cut
            .items
            .iter()
            .filter(|i| i.source == Source::Atlas && i.node.0 % 3 == 2)
            .count();
        let skipped = batch.add_cut(&p.infos[0], view.nodes, &cut, None);
        batch.finish();
        assert_eq!(skipped as usize, want);
        skipped_total += want;
        assert!(
            batch
                .records
                .iter()
                .all(|r| r.atlas_array < 2 || r.atlas_layer == NONE)
        );
        assert_eq!(batch.len(), cut.items.len() - want);
    }
    assert!(skipped_total > 0, "the path selects atlases of array 2");
}

#[test]
fn plan_maps_every_vertex_original_into_its_leaf_tam_range() {
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let p = gather_tables(&file).unwrap();
    let view = file.tree(0).unwrap();
    assert_eq!(p.leaves.len(), view.leaves.len());
    assert_eq!(p.vertices.len(), view.vertices.len());
    // The GPU copy of the vertices holds global indices (tree 0: leaf base 0): its leaf's rect and TAM
    // ranges start added, everything else as stored.
    for (v, g) in view.vertices.iter().zip(&p.vertices) {
        let leaf = &p.leaves[v.leaf as usize];
        let want = atlastree::model::TreeVertex {
            rect: leaf.first_rect + v.rect,
            original: leaf.first_tam + v.original,
            ..*v
        };
        assert_eq!(*g, want);
    }
    for (li, (leaf, gpu)) in view.leaves.iter().zip(&p.leaves).enumerate() {
        let node = &view.nodes[leaf.node as usize];
        assert_eq!(
            (gpu.cell, gpu.level),
            ([node.cell.ix, node.cell.iy], node.level)
        );
        assert_eq!(
            gpu.cell_level,
            atlastree::render::wgsl::tree::LeafInfo::pack_cell_level(gpu.level, gpu.cell)
        );
        assert_eq!(p.origins[li], DVec3::from_array(leaf.origin));
        for (k, o) in view.leaf_originals(leaf).iter().enumerate() {
            let e = &p.tam[gpu.first_tam as usize + k];
            assert_eq!(e.class_size, o.class_size() as f32);
            assert_eq!(e.extent, o.extent().map(|v| v as f32));
            assert_eq!(4u32 << e.class_index, o.class_size());
            let u = &p.uniques[p.tam_unique[gpu.first_tam as usize + k] as usize];
            assert_eq!((u.material, u.extent), (o.material, o.extent()));
        }
    }
    // Deduplication: one unique texture per (material, extent), fewer than the per-leaf copies.
    let mut keys: Vec<(u32, [u32; 2])> = p.uniques.iter().map(|u| (u.material, u.extent)).collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), p.uniques.len());
    assert!(
        p.uniques.len() < p.tam.len(),
        "{} uniques, {} tam",
        p.uniques.len(),
        p.tam.len()
    );
}

/// The naive baseline's draws (`render::naive_batch`, planned on the CPU) on the city: one draw per (leaf,
/// original) pair with triangles, exactly the leaf's triangles of that original — except blended ones,
/// drawn after them in index-buffer order (the tree's blend order), a draw per run of one original —
/// every triangle of the tree drawn once, each draw in its material's pass with its TAM entry's texture;
/// the counts are pinned.
#[test]
fn naive_batch_draws_every_triangle_once() {
    use atlastree::render::naive_batch::{NaiveTables, plan_naive};
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let g = gather_tables(&file).unwrap();
    let tables = NaiveTables::of(&g);
    let plan = plan_naive(&file, tables).unwrap();

    // Independently: per leaf, the set of originals its triangles use, and its triangle count.
    let (mut pairs, mut triangles, mut leaves) = (0usize, 0usize, 0usize);
    let mut blend_runs = 0;
    for (t, info) in g.infos.iter().enumerate() {
        let view = file.tree(t).unwrap();
        for (li, leaf) in view.leaves.iter().enumerate() {
            let gl = info.leaf_base as usize + li;
            let first = leaf.first_index as usize;
            let tris = &view.indices[first..first + leaf.index_count as usize];
            let mut used: Vec<u32> = tris
                .chunks_exact(3)
                .map(|c| view.vertices[c[0] as usize].original)
                .collect();
            used.sort_unstable();
            used.dedup();
            let entry = |o: u32| g.leaves[gl].first_tam as usize + o as usize;
            let blended = |o: u32| g.tam[entry(o)].alpha_mode >= 2;
            // The expected draws: (original, its indices).
            let mut want: Vec<(u32, Vec<u32>)> = used
                .iter()
                .filter(|&&o| !blended(o))
                .map(|&o| {
                    let mine = tris
                        .chunks_exact(3)
                        .filter(|c| view.vertices[c[0] as usize].original == o)
                        .flatten()
                        .copied()
                        .collect();
                    (o, mine)
                })
                .collect();
            let opaque_draws = want.len();
            for c in tris.chunks_exact(3) {
                let o = view.vertices[c[0] as usize].original;
                if !blended(o) {
                    continue;
                }
                let in_blend_runs = want.len() > opaque_draws;
                match want.last_mut() {
                    Some((p, run)) if in_blend_runs && *p == o => run.extend_from_slice(c),
                    _ => want.push((o, c.to_vec())),
                }
            }
            blend_runs += want.len() - opaque_draws;
            let (d0, dn) = plan.leaf_draws[gl];
            assert_eq!(dn as usize, want.len(), "tree {t} leaf {li}");
            for (k, (o, mine)) in want.iter().enumerate() {
                let o = *o;
                let d = plan.draws[d0 as usize + k];
                let range = d.first_index as usize..(d.first_index + d.index_count) as usize;
                assert_eq!(
                    plan.indices[range],
                    mine[..],
                    "tree {t} leaf {li} original {o}"
                );
                assert_eq!(d.texture, g.tam_unique[entry(o)]);
                assert_eq!(d.pass as u32, g.tam[entry(o)].alpha_mode.min(2));
                assert_eq!(
                    (d.base_vertex, d.leaf_base),
                    (info.vertex_base, info.leaf_base)
                );
            }
            pairs += want.len();
            triangles += tris.len() / 3;
            leaves += 1;
        }
    }
    assert_eq!(plan.leaf_draws.len(), leaves);
    assert_eq!(plan.draws.len(), pairs);
    assert_eq!(plan.indices.len(), 3 * triangles);
    // The fixture's numbers: 22 leaves, 40 (leaf, original) draws, 162 triangles, every pair used.
    assert_eq!(
        (
            leaves,
            plan.draws.len(),
            triangles,
            plan.empty_pairs,
            blend_runs
        ),
        (22, 40, 162, 0, 0)
    );
}

/// Blended triangles of two materials stacked A, B, A: original mode draws them in index-buffer order,
/// as the tree's blend pass does, one draw per run of one original (grouped by original, the two modes
/// blended overlapping quads in different orders; fault hunt, session 28).
#[test]
fn naive_blend_draws_keep_the_index_order() {
    use crate::built::{build_ok, tiny_opts};
    use atlastree::render::naive_batch::{NaiveTables, plan_naive};
    use atlastree::scene::synthetic::SceneBuilder;
    use atlastree::scene::{AlphaMode, UpAxis, Wrap};
    use glam::DVec2;
    let mut b = SceneBuilder::new(UpAxis::Y);
    let red = b.image("red", 8, 8, |_, _| [255, 0, 0, 128]);
    let blue = b.image("blue", 8, 8, |_, _| [0, 0, 255, 128]);
    let a = b.material(red, [Wrap::ClampToEdge; 2], AlphaMode::Blend);
    let c = b.material(blue, [Wrap::ClampToEdge; 2], AlphaMode::Blend);
    for (k, m) in [a, c, a, c].into_iter().enumerate() {
        let y = 0.1 * k as f64;
        let corners = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
        b.quad(
            corners.map(|(x, z)| DVec3::new(x, y, z)),
            DVec2::ZERO,
            DVec2::ONE,
            m,
        );
    }
    let built = build_ok(&b.build(), &tiny_opts(64, 0.5));
    let file = &built.file;
    let g = gather_tables(file).unwrap();
    let plan = plan_naive(file, NaiveTables::of(&g)).unwrap();
    let mut runs_seen = 0;
    for (t, info) in g.infos.iter().enumerate() {
        let view = file.tree(t).unwrap();
        for (li, leaf) in view.leaves.iter().enumerate() {
            let first = leaf.first_index as usize;
            let tris = &view.indices[first..first + leaf.index_count as usize];
            let (d0, dn) = plan.leaf_draws[info.leaf_base as usize + li];
            let draws = &plan.draws[d0 as usize..(d0 + dn) as usize];
            let drawn: Vec<u32> = draws
                .iter()
                .filter(|d| d.pass == Pass::Blend)
                .flat_map(|d| {
                    plan.indices[d.first_index as usize..(d.first_index + d.index_count) as usize]
                        .iter()
                        .copied()
                })
                .collect();
            assert_eq!(drawn, tris, "tree {t} leaf {li}: blended in index order");
            // One draw per run of one original.
            let originals: Vec<u32> = tris
                .chunks_exact(3)
                .map(|c| view.vertices[c[0] as usize].original)
                .collect();
            let runs = 1 + originals.windows(2).filter(|w| w[0] != w[1]).count();
            assert_eq!(draws.len(), runs, "tree {t} leaf {li}");
            runs_seen += runs;
        }
    }
    // Four quads of alternating materials: four runs wherever they lie.
    assert!(runs_seen >= 4, "{runs_seen} runs");
}

/// The naive frame plan (`render::naive_batch::visible_draws`): a cut of every tree's root draws every
/// planned draw exactly once, in its pass; a cut of one leaf draws that leaf's draws only; a cut naming a
/// node the tables do not have is an error, not an empty frame.
#[test]
fn naive_visible_draws_cover_the_cut_exactly() {
    use atlastree::ids::NodeId;
    use atlastree::render::naive_batch::{NaiveBatchError, NaiveTables, plan_naive, visible_draws};
    use atlastree::select::CutItem;
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let g = gather_tables(&file).unwrap();
    let plan = plan_naive(&file, NaiveTables::of(&g)).unwrap();
    let cut_of = |node: u32| {
        let mut cut = Cut::new();
        cut.items.push(CutItem {
            node: NodeId(node),
            source: Source::Atlas,
            level: 0,
            first_index: 0,
            index_count: 0,
            distance: 0.0,
        });
        cut
    };
    let roots: Vec<Cut> = g.infos.iter().map(|_| cut_of(0)).collect();
    let lists = visible_draws(&g.infos, &roots, &plan.leaf_draws, &plan.draws).unwrap();
    let mut all: Vec<_> = lists.iter().flatten().copied().collect();
    assert_eq!(all.len(), plan.draws.len(), "every draw once");
    for (p, list) in lists.iter().enumerate() {
        assert!(list.iter().all(|d| d.pass as usize == p), "pass {p}");
    }
    let key = |d: &atlastree::render::naive_batch::NaiveDraw| (d.leaf_base, d.first_index);
    all.sort_by_key(key);
    let mut want = plan.draws.clone();
    want.sort_by_key(key);
    assert_eq!(all, want);

    // One leaf: the node of tree 0's first leaf.
    let leaf_node = file.tree(0).unwrap().leaves[0].node;
    let mut one = vec![cut_of(leaf_node)];
    one.extend(g.infos.iter().skip(1).map(|_| Cut::new()));
    let lists = visible_draws(&g.infos, &one, &plan.leaf_draws, &plan.draws).unwrap();
    let (d0, dn) = plan.leaf_draws[g.infos[0].leaf_base as usize];
    let got: usize = lists.iter().map(Vec::len).sum();
    assert_eq!(got, dn as usize);
    assert!(
        lists
            .iter()
            .flatten()
            .all(|d| plan.draws[d0 as usize..(d0 + dn) as usize].contains(d))
    );

    // A node past the tree's nodes.
    let nodes = g.infos[0].leaf_ranges.len();
    let mut bad = vec![cut_of(nodes as u32)];
    bad.extend(g.infos.iter().skip(1).map(|_| Cut::new()));
    assert_eq!(
        visible_draws(&g.infos, &bad, &plan.leaf_draws, &plan.draws).unwrap_err(),
        NaiveBatchError::CutNode {
            tree: 0,
            node: nodes,
            nodes
        }
    );
    // Draw lists shorter than the leaves.
    let short = &plan.leaf_draws[..plan.leaf_draws.len() - 1];
    assert!(matches!(
        visible_draws(&g.infos, &roots, short, &plan.draws),
        Err(NaiveBatchError::MissingDrawList { .. })
    ));
}

/// Tables that disagree with the file are errors naming what is missing, never a draw left out: a missing
/// TAM entry, a missing leaf record, a tree the file does not have.
#[test]
fn naive_batch_refuses_inconsistent_tables() {
    use atlastree::render::naive_batch::{NaiveBatchError, NaiveTables, plan_naive};
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let g = gather_tables(&file).unwrap();
    let tables = NaiveTables::of(&g);
    let short_tam = &g.tam[..g.tam.len() - 1];
    let err = plan_naive(
        &file,
        NaiveTables {
            tam: short_tam,
            ..tables
        },
    )
    .unwrap_err();
    assert!(
        matches!(err, NaiveBatchError::MissingTam { entry, entries, .. } if entry == g.tam.len() - 1 && entries == g.tam.len() - 1),
        "{err}"
    );
    let short_leaves = &g.leaves[..g.leaves.len() - 1];
    let err = plan_naive(
        &file,
        NaiveTables {
            leaves: short_leaves,
            ..tables
        },
    )
    .unwrap_err();
    assert_eq!(
        err,
        NaiveBatchError::MissingLeaf {
            leaf: g.leaves.len() - 1,
            leaves: g.leaves.len() - 1
        }
    );
    // One tree more than the file has.
    let mut infos = g.infos.clone();
    infos.push(infos[0].clone());
    let err = plan_naive(
        &file,
        NaiveTables {
            infos: &infos,
            ..tables
        },
    )
    .unwrap_err();
    assert_eq!(
        err,
        NaiveBatchError::MissingTree {
            tree: g.infos.len()
        }
    );
}

/// `RectMap::texel_f32` (the shader's arithmetic in f32) agrees with the f64 reference
/// `model::transform::rect_texel` on the grid of `tests/fixtures/shader_math.rs` (every wrap mode, rect
/// edges, UVs up to 65536 periods out, levels to 24), within the tolerance stated there, and the f32 level
/// transform of its texel with the f64 one within 2⁻²⁴; near-branch samples are few.
#[test]
fn texel_f32_agrees_with_f64_reference() {
    use crate::fixtures::shader_math::{ATLAS, F64Check, check_f64, maps, rects, samples};
    use atlastree::ids::Level;
    use atlastree::model::transform::{atlas_uv_at, atlas_uv_at_f32};
    let rects = rects();
    let maps = maps(&rects);
    let samples = samples(&rects);
    let (mut agree, mut near, mut near_step) = (0usize, 0usize, 0usize);
    let mut failures = Vec::new();
    for s in &samples {
        let (texel, gx, gy) = maps[s.rect].texel_f32(s.uv, s.ddx, s.ddy, s.level_texels());
        // Gradients stay finite, zero footprints (constant UVs) included: they go to textureSampleGrad.
        if !(gx.is_finite() && gy.is_finite()) {
            failures.push(format!("{s:?}: gradients {gx} {gy} not finite"));
        }
        // Then the level transform, in f32 as the shader and in f64: one rounding of a value in [0, 1].
        let (k, j) = (Level(s.leaf_level), Level(s.level));
        let leaf_uv = texel / ATLAS as f32;
        let f32_uv = atlas_uv_at_f32(leaf_uv, s.cell, k, j).as_dvec2();
        let f64_uv = atlas_uv_at(leaf_uv.as_dvec2(), s.cell, k, j);
        if (f32_uv - f64_uv).abs().max_element() > 2f64.powi(-24) {
            failures.push(format!("{s:?}: atlas uv {f32_uv} in f32, {f64_uv} in f64"));
        }
        match check_f64(&rects[s.rect], s, texel) {
            Ok(F64Check::Agrees) => agree += 1,
            // The texel agreed; the GPU test allows its gradients the step's factor.
            Ok(F64Check::AgreesTexelNearStep) => {
                agree += 1;
                near_step += 1;
            }
            Ok(F64Check::NearBranch) => near += 1,
            Err(e) => failures.push(e),
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} samples disagree:\n{}",
        failures.len(),
        samples.len(),
        failures[..failures.len().min(20)].join("\n")
    );
    assert_eq!(agree + near, samples.len());
    // At most 2% sit on a branch boundary (280 of 22,400: constant UVs at K = 10, j = 4, where a 64-texel
    // outer rectangle leaves lo == hi).
    assert!(
        near * 50 <= samples.len(),
        "{near} near-branch samples of {}",
        samples.len()
    );
    println!("{agree} agree, {near} near a branch, {near_step} near a step of the footprint cap");
}

/// A constant UV (zero gradients) on a palette cell's point rect (1 × 1 inner, 8-texel border): sampled
/// while the drawn level's bilinear taps stay inside the outer rect, its mean beyond (`POINT_REACH` drawn
/// texels from the nearer outer edge), with zero gradients either way.
#[test]
fn a_constant_uv_shows_the_mean_where_its_taps_would_leave_the_rect() {
    use atlastree::model::{AtlasRect, RectWrap};
    use atlastree::render::wgsl::tree::{POINT_REACH, RectMap};
    use atlastree::scene::AlphaMode;
    use glam::Vec2;
    let rect = AtlasRect {
        material: atlastree::ids::MaterialId(0),
        outer: [40, 60, 20, 20],
        inner: [48, 68, 1, 1],
        uv_min: [0.53125; 2],
        uv_max: [0.53125; 2],
        wrap: [RectWrap::Linear; 2],
        capped: [false; 2],
        mean: [10, 20, 30, 255],
    };
    let map = RectMap::new(&rect, AlphaMode::Opaque);
    let uv = Vec2::splat(0.53125);
    // A zero UV span counts as one UV: the UV maps onto the inner texel's corner, 8 texels from the
    // outer edges (the border is the cell's colour, so the bilinear taps read it alone).
    for (level_texels, flat) in [(1.0f32, false), (4.0, false), (8.0, true), (16.0, true)] {
        let s = map.sample_f32(uv, Vec2::ZERO, Vec2::ZERO, level_texels);
        assert_eq!(s.flat, flat, "level texels {level_texels}: {s:?}");
        assert_eq!(flat, 8.0 < POINT_REACH * level_texels);
        assert_eq!((s.gx, s.gy), (Vec2::ZERO, Vec2::ZERO), "{s:?}");
        assert_eq!(s.mix_mean, if flat { 1.0 } else { 0.0 });
        if !flat {
            assert_eq!(s.texel, Vec2::new(48.0, 68.0));
        }
    }
}

/// A footprint that covers an elongated rect's short side alone (992 × 16 texels, ~20 texels a pixel
/// along the strip) averages that side only: the strip keeps its detail along its length. (It was
/// flattened whole, so a 1024 × 16 gradient texture seen from a few metres drew as one colour.) A
/// footprint over both sides is flat (it shows the rect's mean; its texel is the inner centre).
#[test]
fn a_footprint_over_a_strips_short_side_keeps_its_length() {
    use crate::fixtures::shader_math::rects;
    use atlastree::render::wgsl::tree::RectMap;
    use atlastree::scene::AlphaMode;
    use glam::Vec2;
    let rects = rects();
    let strip = rects
        .iter()
        .find(|r| r.inner[2] == 992 && r.inner[3] == 16)
        .unwrap();
    let map = RectMap::new(strip, AlphaMode::Opaque);
    let centre = Vec2::new(16.0 + 496.0, 596.0 + 8.0);
    let (ddx, ddy) = (Vec2::new(0.02, 0.0), Vec2::new(0.0, 0.005));
    for u in [0.25f32, 0.75] {
        let (texel, gx, gy) = map.texel_f32(Vec2::new(u, 0.3), ddx, ddy, 1.0);
        assert!(
            (texel.x - (16.0 + u * 992.0)).abs() < 1e-3,
            "u {u}: {texel}"
        );
        assert_eq!(texel.y, centre.y, "u {u}: {texel}");
        // Sharpened only as far as the isotropic filter needs to stay inside the outer rectangle across
        // the strip (24 texels from the centre): the longer gradient, along the strip, sets its mip on
        // both axes (lod 3.99: the coarser mip's 16-texel texels reach 24 texels), far from the period
        // branch.
        let k = gx.x / (ddx.x * 992.0);
        assert!(
            (gx - ddx * 992.0 * k).abs().max_element() < 1e-5,
            "u {u}: {gx}"
        );
        assert!(
            (gy - ddy * 16.0 * k).abs().max_element() < 1e-6,
            "u {u}: {gy}"
        );
        assert_eq!(
            k,
            RectMap::footprint_cap(24.0, 1.0) / (ddx.x * 992.0),
            "u {u}"
        );
        assert!(k > 0.75 && k < 1.0, "u {u}: k {k}");
    }
    let (texel, ..) = map.texel_f32(Vec2::new(0.25, 0.3), ddx * 100.0, ddy * 100.0, 1.0);
    assert_eq!(texel, centre);
}

/// A field of MASK plants with a BLEND pane in every fourth cell, over an opaque ground: an alpha tree of
/// several levels whose nodes are blend nodes with mostly MASK triangles.
fn plants_and_panes(dir: &std::path::Path) -> TreeFile {
    use atlastree::scene::synthetic::SceneBuilder;
    use atlastree::scene::{AlphaMode, UpAxis, Wrap};
    use glam::DVec2;
    let mut b = SceneBuilder::new(UpAxis::Y);
    let ground = b.pattern_image("ground", 64, 3);
    let ground = b.material(ground, [Wrap::Repeat; 2], AlphaMode::Opaque);
    for i in 0..8u8 {
        for j in 0..8u8 {
            let (x, z) = (f64::from(i) * 20.0, f64::from(j) * 20.0);
            // Every quad its own 64² texture, so the alpha tree needs several atlases.
            let (g, alpha) = (20 * i + j, (i + j) % 4 == 0);
            let img = b.image(&format!("plant {i} {j}"), 64, 64, move |x, y| match alpha {
                true => [200, 220, g, 96],
                false => [30, g, 40, if (x / 8 + y / 8) % 3 == 0 { 0 } else { 255 }],
            });
            let mode = match alpha {
                true => AlphaMode::Blend,
                false => AlphaMode::Mask { cutoff: 0.5 },
            };
            let m = b.material(img, [Wrap::Repeat; 2], mode);
            b.quad(
                [
                    DVec3::new(x, 0.0, z),
                    DVec3::new(x + 6.0, 0.0, z),
                    DVec3::new(x + 6.0, 6.0, z),
                    DVec3::new(x, 6.0, z),
                ],
                DVec2::new(0.0, 1.0),
                DVec2::new(1.0, 0.0),
                m,
            );
            b.quad(
                [
                    DVec3::new(x, 0.0, z),
                    DVec3::new(x + 20.0, 0.0, z),
                    DVec3::new(x + 20.0, 0.0, z + 20.0),
                    DVec3::new(x, 0.0, z + 20.0),
                ],
                DVec2::ZERO,
                DVec2::splat(4.0),
                ground,
            );
        }
    }
    let out = dir.join("plants.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(40.0),
        atlas_size: 128,
        max_file_bytes: 1 << 30,
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    build(&b.build(), &opts, &out, &NoProgress).unwrap();
    TreeFile::open(&out).unwrap()
}

/// The blend pass draws each blend node's range of its tree's blend list: exactly the node's BLEND
/// triangles, in index-buffer order (an analyzer twin walks the node's own range and asks each
/// triangle's material); the depth pre-pass in the mask group keeps the node's whole range.
#[test]
fn blend_records_draw_exactly_the_nodes_blend_triangles() {
    use atlastree::scene::AlphaMode;
    let dir = tempfile::tempdir().unwrap();
    let file = plants_and_panes(dir.path());
    let mut p = gather_tables(&file).unwrap();
    let materials = file.materials();
    let alpha = (0..file.trees())
        .find(|&t| file.tree(t).unwrap().kind == atlastree::model::TreeKind::Alpha)
        .expect("an alpha tree");
    let view = file.tree(alpha).unwrap();
    assert!(
        view.nodes.len() >= 5,
        "need a multi-level alpha tree: {} nodes",
        view.nodes.len()
    );
    let is_blend = |t: usize| {
        let v = view.vertices[view.indices[3 * t] as usize];
        let leaf = &view.leaves[v.leaf as usize];
        let m = view.leaf_rects(leaf)[v.rect as usize].material;
        materials[m as usize].alpha() == Some(AlphaMode::Blend)
    };
    let info = &p.infos[alpha as usize];
    assert_eq!(info.blend_ranges.len(), view.nodes.len());
    let mut smaller = 0;
    for (n, (node, &(first, count))) in view.nodes.iter().zip(&info.blend_ranges).enumerate() {
        let lo = node.first_index as usize / 3;
        let hi = lo + node.index_count as usize / 3;
        let want: Vec<u32> = (lo..hi)
            .filter(|&t| is_blend(t))
            .flat_map(|t| view.indices[3 * t..3 * t + 3].iter().copied())
            .collect();
        assert_eq!(
            &p.indices[first as usize..(first + count) as usize],
            &want[..],
            "node {n}"
        );
        if info.passes[n] == Pass::Blend {
            assert!(count > 0, "blend node {n} has BLEND triangles");
        }
        smaller += usize::from(count > 0 && count < node.index_count);
    }
    // 16 panes of 2 triangles under the root, among 48 plants.
    assert_eq!(info.blend_ranges[0].1, 16 * 2 * 3);
    assert!(smaller >= 2, "blend ranges should cut MASK triangles out");

    // The root drawn from its atlas: the pre-pass record has the whole range, the blend record the list.
    for slot in p.infos[alpha as usize].atlas_slots.iter_mut() {
        *slot = Some(AtlasSlot { array: 0, layer: 0 });
    }
    let info = &p.infos[alpha as usize];
    let root = view.nodes[0];
    let mut cut = Cut::new();
    cut.items.push(atlastree::select::CutItem {
        node: atlastree::ids::NodeId(0),
        source: Source::Atlas,
        level: 0,
        first_index: root.first_index,
        index_count: root.index_count,
        distance: 1e6,
    });
    let mut batch = FrameBatch::new();
    assert_eq!(batch.add_cut(info, view.nodes, &cut, None), 0);
    batch.finish();
    let group = |pass| batch.group_ranges[Group::new(pass, false).index()];
    let (mask, blend) = (group(Pass::Mask), group(Pass::Blend));
    assert_eq!((mask.1, blend.1), (1, 1));
    let pre = batch.indirect[mask.0 as usize];
    assert_eq!(
        (pre.first_index, pre.index_count),
        (info.index_base + root.first_index, root.index_count)
    );
    let b = batch.indirect[blend.0 as usize];
    assert_eq!((b.first_index, b.index_count), info.blend_ranges[0]);
    assert_eq!(b.base_vertex, info.vertex_base);
}
