//! `render::batch` and the CPU half of `render::resident` without a GPU: on a real built tree and cuts of
//! many sizes, the indirect records are exactly the cut (counts, index ranges, base vertex), `first_instance`
//! numbers the node records, passes partition the records, leaf ranges are the subtrees' leaves, and leaf
//! offsets are `origin − eye` for exactly the leaves under the cut.

use atlastree::camera::CameraPath;
use atlastree::ids::NONE;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::batch::{
    AtlasSlot, BatchOptions, FrameBatch, Group, LeafOffsets, Pass, leaf_ranges,
};
use atlastree::render::resident::gather_tables;
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

    let root = view.nodes[0];
    let path = CameraPath::overview_dive(
        root.bounds_min.into(),
        root.bounds_max.into(),
        file.to_params().up,
    )
    .unwrap();
    let mut cut = Cut::new();
    let mut batch = FrameBatch::new();
    let mut offsets = LeafOffsets::new(p.origins.clone());
    let mut sizes = Vec::new();
    for (i, cam) in path.frames(2.0, 40).enumerate() {
        let scale = [0.5, 1.0, 4.0][i % 3];
        select(view.nodes, &cam, &cam.frustum(), scale, &mut cut);
        batch.clear();
        let skipped = batch.add_cut(info, view.nodes, &cut, None, BatchOptions::default());
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
        assert!(r[2..].iter().all(|&(_, n)| n == 0));
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

    // Dummy mode: every record an atlas draw of layer 0; a missing atlas skips the item.
    batch.clear();
    batch.add_cut(info, view.nodes, &cut, None, BatchOptions { dummy: true });
    batch.finish();
    assert!(
        batch
            .records
            .iter()
            .all(|r| r.atlas_layer == 0 && r.atlas_array == 0)
    );
    p.infos[0].atlas_slots.iter_mut().for_each(|s| *s = None);
    batch.clear();
    let atlas_items = cut
        .items
        .iter()
        .filter(|i| i.source == Source::Atlas)
        .count();
    let skipped = batch.add_cut(&p.infos[0], view.nodes, &cut, None, BatchOptions::default());
    batch.finish();
    assert_eq!(skipped as usize, atlas_items);
    assert_eq!(batch.len(), cut.items.len() - atlas_items);
}

#[test]
fn plan_maps_every_vertex_original_into_its_leaf_tam_range() {
    let dir = tempfile::tempdir().unwrap();
    let file = city_file(dir.path());
    let p = gather_tables(&file).unwrap();
    let view = file.tree(0).unwrap();
    assert_eq!(p.leaves.len(), view.leaves.len());
    assert_eq!(p.vertices.len(), view.vertices.len());
    for (li, (leaf, gpu)) in view.leaves.iter().zip(&p.leaves).enumerate() {
        let node = &view.nodes[leaf.node as usize];
        assert_eq!(
            (gpu.cell, gpu.level),
            ([node.cell.ix, node.cell.iy], node.level)
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
