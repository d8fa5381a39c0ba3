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

mod naive;
mod texel;

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
            let entry = gpu.first_tam as usize + k;
            let u = &p.uniques[p.tam_unique[entry] as usize];
            assert_eq!((u.block.0, u.extent), (o.block, o.extent()));
            let pair = p.material_originals[p.tam_material_original[entry] as usize];
            assert_eq!(pair.material, o.material);
            assert_eq!(pair.unique, p.tam_unique[entry]);
        }
    }
    // Deduplication: one unique texture per stored original (block, byte offset), fewer than the
    // per-leaf copies.
    let mut keys: Vec<(u32, u64)> = p.uniques.iter().map(|u| (u.block.0, u.offset)).collect();
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
