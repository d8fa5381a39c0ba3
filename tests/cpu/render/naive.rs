//! The naive baseline's draws (`render::naive_batch`): one draw per (leaf, original) pair, blended
//! triangles in index order, the cut covered exactly, inconsistent tables refused.

use super::*;

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
    let (mut blend_runs, mut prepass_triangles) = (0, 0);
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
            // The expected draws: (original, its indices); a blended original's in the mask pass (the
            // depth pre-pass of its opaque texels, as the tree's blend nodes have).
            let mut want: Vec<(u32, Vec<u32>)> = used
                .iter()
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
            prepass_triangles += (want[..opaque_draws].iter())
                .filter(|(o, _)| blended(*o))
                .map(|(_, mine)| mine.len() / 3)
                .sum::<usize>();
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
                assert_eq!(d.texture, g.tam_material_original[entry(o)]);
                let pair = g.material_originals[d.texture as usize];
                assert_eq!(pair.unique, g.tam_unique[entry(o)]);
                assert_eq!(
                    pair.material,
                    view.leaf_originals(leaf)[o as usize].material
                );
                let pass = if k < opaque_draws {
                    g.tam[entry(o)].alpha_mode.min(1)
                } else {
                    2
                };
                assert_eq!(d.pass as u32, pass, "tree {t} leaf {li} original {o}");
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
    assert_eq!(plan.indices.len(), 3 * (triangles + prepass_triangles));
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
            // Before them, each original's triangles in the mask pass (the depth pre-pass).
            let prepass: Vec<u32> = draws
                .iter()
                .filter(|d| d.pass == Pass::Mask)
                .map(|d| d.index_count / 3)
                .collect();
            assert_eq!(prepass.iter().sum::<u32>() as usize, tris.len() / 3);
            // One draw per run of one original, and one pre-pass draw per original.
            let originals: Vec<u32> = tris
                .chunks_exact(3)
                .map(|c| view.vertices[c[0] as usize].original)
                .collect();
            let runs = 1 + originals.windows(2).filter(|w| w[0] != w[1]).count();
            let mut distinct = originals.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(draws.len(), runs + distinct.len(), "tree {t} leaf {li}");
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
