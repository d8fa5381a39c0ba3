//! Original textures stored and paged once (issue 17): a texture shown by leaves in opposite corners of
//! the quadtree is one slot of one block, every leaf that shows it references that block, the pager ranks
//! it by the best of its leaves, and a flight over both corners loads it once.

use crate::fixtures::corners::{POSTER, corners, options};
use atlastree::camera::{Camera, CameraPath};
use atlastree::ids::NodeId;
use atlastree::paging::{BlockTable, Event, Usage, ViewInput};
use atlastree::paging::{UsageScratch, classify};
use atlastree::preprocess::{NoProgress, build};
use atlastree::sim::{SimInput, simulate_with};
use atlastree::store::TreeFile;
use glam::DVec3;
use std::collections::{BTreeSet, HashMap};

fn build_corners(dir: &std::path::Path) -> TreeFile {
    let out = dir.join("corners.atlastree");
    build(&corners(), &options(), &out, &NoProgress).unwrap();
    TreeFile::open(&out).unwrap()
}

/// The block holding the poster's original texture.
fn poster_block(file: &TreeFile) -> atlastree::ids::BlockId {
    let t = file.tree(0).unwrap();
    let o = t.originals.iter().find(|o| o.material == POSTER).unwrap();
    atlastree::ids::BlockId(o.block)
}

/// A 60° camera at `eye` looking at `target` (4:3, Y up).
fn look(eye: DVec3, target: DVec3) -> Camera {
    crate::views::look(eye, target, 5000.0)
}

/// The selection scale of an 800 px wide, 60° view at texel ratio 1.
fn scale_800(file: &TreeFile) -> f64 {
    crate::views::scale_800(&file.to_params(), 60.0)
}

#[test]
fn a_texture_in_opposite_corners_is_stored_once_and_referenced_by_both_leaves() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let t = file.tree(0).unwrap();
    // Every leaf that shows the poster references the same (block, slot).
    let mut refs: Vec<(u32, (u32, u32))> = Vec::new();
    for leaf in t.leaves {
        for o in t
            .leaf_originals(leaf)
            .iter()
            .filter(|o| o.material == POSTER)
        {
            refs.push((leaf.node, (o.block, o.slot)));
        }
    }
    assert!(
        refs.len() >= 2,
        "the poster is shown by ≥ 2 leaves: {refs:?}"
    );
    let places: BTreeSet<(u32, u32)> = refs.iter().map(|r| r.1).collect();
    assert_eq!(places.len(), 1, "stored once: {refs:?}");
    // Each stored original once: the original blocks hold exactly the distinct chains.
    let mut chains: HashMap<(u32, u32), u64> = HashMap::new();
    for o in t.originals {
        chains.insert(
            (o.block, o.slot),
            t.format().chain_bytes_rect(o.extent()[0], o.extent()[1]),
        );
    }
    let stored: u64 = file
        .blocks()
        .iter()
        .filter(|b| b.kind == atlastree::store::format::BLOCK_ORIGINALS)
        .map(|b| b.length)
        .sum();
    assert_eq!(stored, chains.values().sum::<u64>(), "{chains:?}");
    // The block table lists the shared block under both leaves; its closure parent is the atlas of
    // their lowest common ancestor (here the root: the corners lie in different quadrants).
    let table = BlockTable::from_file(&file).unwrap();
    let block = atlastree::ids::BlockId(places.iter().next().unwrap().0);
    let users: BTreeSet<u32> = table.users(block).iter().map(|n| n.0).collect();
    let leaves: BTreeSet<u32> = refs.iter().map(|r| r.0).collect();
    assert_eq!(users, leaves);
    for &n in &leaves {
        assert!(table.originals(0, NodeId(n)).contains(&block));
    }
    assert_eq!(table.meta(block).parent, table.atlas(0, NodeId(0)));
    // inspect --verify holds on the shared layout.
    let report = atlastree::inspect::verify(&file);
    assert!(report.ok(), "{:?}", report.violations);
}

#[test]
fn the_pager_ranks_a_shared_block_by_its_best_leaf_and_a_flight_loads_it_once() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let table = BlockTable::from_file(&file).unwrap();
    let t = file.tree(0).unwrap();
    let poster = poster_block(&file);
    let params = file.to_params();
    let trees: Vec<&[atlastree::store::format::NodeRecord]> = (0..file.trees())
        .map(|i| file.tree(i).unwrap().nodes)
        .collect();
    let scale = scale_800(&file);
    // Standing over the south-east poster, looking at it: only that corner's leaf needs originals; the
    // shared block is needed through it, the north-west leaf's own original blocks are not.
    let cam = look(DVec3::new(350.0, 3.0, 330.0), DVec3::new(350.0, 0.0, 350.0));
    let frustum = cam.frustum();
    let view = ViewInput {
        eye: cam.eye,
        frustum: &frustum,
        scale,
        lookahead: None,
    };
    let mut scratch = UsageScratch::default();
    let mut out = Vec::new();
    classify(&table, &trees, &view, &mut scratch, &mut out);
    let usage = |b| out.iter().find(|c| c.block == b).map(|c| c.usage);
    assert_eq!(usage(poster), Some(Usage::Needed), "{out:?}");
    assert_eq!(out.iter().filter(|c| c.block == poster).count(), 1);
    // Original blocks only north-west leaves use (the north-west poster leaves hold only the shared
    // block, so this is the north-west ground's): none is needed from the south-east.
    let north_west = |n: &NodeId| {
        let b = t.nodes[n.idx()].bounds_max;
        b[0] < 250.0 && b[2] < 250.0
    };
    let nw_only: Vec<atlastree::ids::BlockId> = (0..file.blocks().len() as u32)
        .map(atlastree::ids::BlockId)
        .filter(|&b| {
            let u = table.users(b);
            b != poster && !u.is_empty() && u.iter().all(north_west)
        })
        .collect();
    assert!(!nw_only.is_empty(), "the north-west has blocks of its own");
    for b in nw_only {
        assert_ne!(
            usage(b),
            Some(Usage::Needed),
            "north-west block {b} needed from the south-east"
        );
    }
    // A flight from one corner to the other with every block allowed: every block, the shared one
    // included, is loaded at most once (it is never loaded for the second corner again).
    let input = SimInput::from_file(&file).unwrap();
    let lo = DVec3::new(0.0, 0.0, 0.0);
    let hi = DVec3::new(400.0, 1.0, 400.0);
    let path = CameraPath::street(lo, hi, params.up).unwrap();
    let cams: Vec<Camera> = path.frames(30.0, 300).collect();
    let opts = atlastree::sim::SimOptions {
        fps: 30.0,
        pager: atlastree::paging::PagerOptions {
            capacity: u32::MAX,
            ..Default::default()
        },
        io: None,
    };
    let mut loads: HashMap<u32, u32> = HashMap::new();
    simulate_with(
        &input,
        &cams,
        &vec![scale; cams.len()],
        &opts,
        &mut |_, e| {
            if let Event::Loaded { block, .. } = e {
                *loads.entry(block.0).or_default() += 1;
            }
        },
    )
    .unwrap();
    assert_eq!(loads.get(&poster.0), Some(&1), "{loads:?}");
    assert!(loads.values().all(|&n| n == 1), "{loads:?}");
}

#[test]
fn an_originals_block_is_ideal_only_with_every_other_block_of_a_leaf_that_uses_it() {
    use atlastree::plan::{FramePlanner, NoResidency};
    // data/city split until every node fits a 512² atlas: its facade textures are shared by many
    // leaves, so leaves need several blocks.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let scene_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).unwrap();
    let opts = atlastree::preprocess::BuildOptions {
        d_min: atlastree::preprocess::DMin::Ratio(20.0),
        atlas_size: 512,
        leaf_originals_atlases: 0.0,
        ..Default::default()
    };
    build(&scene, &opts, &out, &NoProgress).unwrap();
    let file = TreeFile::open(&out).unwrap();
    let table = BlockTable::from_file(&file).unwrap();
    let params = file.to_params();
    let root = file.tree(0).unwrap().nodes[0];
    let path = CameraPath::street(
        DVec3::from_array(root.bounds_min),
        DVec3::from_array(root.bounds_max),
        params.up,
    )
    .unwrap();
    let cams: Vec<Camera> = path.frames(30.0, 300).collect();
    let scale = crate::views::scale_800(&params, cams[0].fov_x_deg);
    let multi = (0..file.tree(0).unwrap().nodes.len() as u32)
        .map(NodeId)
        .filter(|&n| table.originals(0, n).len() > 1)
        .count();
    assert!(
        multi > 0,
        "no leaf needs two blocks: the test proves nothing"
    );
    let mut completed_groups = 0;
    for k in 3..=60u32 {
        let mut planner = FramePlanner::paged(
            atlastree::plan::file_trees(&file),
            table.clone(),
            atlastree::paging::PagerOptions {
                capacity: k,
                ..Default::default()
            },
            Box::new(atlastree::sim::InstantLoader::default()),
            |_| Ok(None),
        )
        .unwrap();
        for (i, c) in cams.iter().enumerate() {
            planner
                .plan(c, i as f64 / 30.0, scale, &mut NoResidency)
                .unwrap();
            let pager = planner.pager().unwrap();
            let ideal: BTreeSet<u32> = pager.ideal().iter().map(|b| b.0).collect();
            for &b in pager.ideal() {
                if table.meta(b).item.is_atlas() {
                    continue;
                }
                let (tree, users) = (table.meta(b).tree as usize, table.users(b));
                let complete = users.iter().filter(|&&leaf| {
                    table
                        .originals(tree, leaf)
                        .iter()
                        .all(|x| ideal.contains(&x.0))
                });
                let complete: Vec<_> = complete.collect();
                assert!(
                    !complete.is_empty(),
                    "k = {k}, frame {i}: {b} is ideal but no leaf that uses it ({users:?}) has all its blocks ideal"
                );
                completed_groups += complete
                    .iter()
                    .filter(|&&&leaf| table.originals(tree, leaf).len() > 1)
                    .count();
            }
        }
    }
    assert!(
        completed_groups > 0,
        "no multi-block leaf ever had its group ideal: the test proves nothing"
    );
}

/// Blocks group textures by the leaves that draw them (§6, issue 17): on the corners scene and on the small
/// city (one facade texture per building, several buildings per leaf) every originals block is at most one
/// atlas unless it is one texture, a block's first user leaf owns it, and what the leaves load by blocks
/// is within `MAX_BLOCK_WASTE` of what they draw (inspect's twin of the grouping's bound). The city has
/// more textures than blocks: small ones share blocks.
#[test]
fn original_blocks_group_textures_by_their_users_within_the_waste_bound() {
    use atlastree::inspect::original_blocks_cost;
    use atlastree::preprocess::BuildOptions;
    use atlastree::preprocess::originals::MAX_BLOCK_WASTE;
    let dir = tempfile::tempdir().unwrap();
    let city = dir.path().join("city.atlastree");
    let opts = BuildOptions {
        atlas_size: 256,
        ..BuildOptions::default()
    };
    build(
        &atlastree::scene::synthetic::small_city(8, 64),
        &opts,
        &city,
        &NoProgress,
    )
    .unwrap();
    let files = [build_corners(dir.path()), TreeFile::open(&city).unwrap()];
    for (fi, file) in files.iter().enumerate() {
        let atlas = file
            .tree(0)
            .unwrap()
            .format()
            .chain_bytes(file.to_params().atlas_size);
        let t = file.tree(0).unwrap();
        let mut slots: HashMap<u32, BTreeSet<u32>> = HashMap::new();
        let mut first_user: HashMap<u32, u32> = HashMap::new();
        for (li, leaf) in t.leaves.iter().enumerate() {
            for o in t.leaf_originals(leaf) {
                slots.entry(o.block).or_default().insert(o.slot);
                first_user.entry(o.block).or_insert(li as u32);
            }
        }
        for (&b, s) in &slots {
            let rec = file.blocks()[b as usize];
            assert!(
                rec.length <= atlas || s.len() == 1,
                "file {fi} block {b}: {} bytes, {} slots",
                rec.length,
                s.len()
            );
            assert_eq!(
                rec.item, first_user[&b],
                "file {fi} block {b}: owned by its first user"
            );
        }
        let c = original_blocks_cost(file, 0, atlas);
        assert!(c.needed_bytes > 0);
        assert!(
            c.loaded_bytes as f64 <= (1.0 + MAX_BLOCK_WASTE) * c.needed_bytes as f64,
            "file {fi}: {c:?}"
        );
        if fi == 1 {
            let stored: usize = slots.values().map(BTreeSet::len).sum();
            assert!(
                slots.len() < stored,
                "city: {} blocks for {stored} textures",
                slots.len()
            );
        }
    }
}

/// Evicting one leaf's need keeps a block another needed leaf uses: 60 frames over the north-west poster,
/// then 120 over the south-east one, at capacities tight enough that blocks only north-west leaves use
/// are evicted after the jump. The shared poster block, needed through the south-east leaf, is never evicted
/// once that leaf needs it and is loaded once; a pager that ranked it by the leaf it was first loaded for
/// would evict and reload it.
#[test]
fn evicting_one_leafs_need_keeps_the_block_another_needed_leaf_uses() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let table = BlockTable::from_file(&file).unwrap();
    let t = file.tree(0).unwrap();
    let poster = poster_block(&file).0;
    let north_west = |n: &NodeId| {
        let b = t.nodes[n.idx()].bounds_max;
        b[0] < 250.0 && b[2] < 250.0
    };
    // Original blocks only north-west leaves use (the north-west ground's).
    let nw_only: BTreeSet<u32> = t
        .originals
        .iter()
        .map(|o| o.block)
        .filter(|&b| {
            let u = table.users(atlastree::ids::BlockId(b));
            b != poster && !u.is_empty() && u.iter().all(north_west)
        })
        .collect();
    assert!(
        !nw_only.is_empty(),
        "the north-west ground has blocks of its own"
    );
    let mut cams = vec![look(DVec3::new(50.0, 3.0, 30.0), DVec3::new(50.0, 0.0, 50.0)); 60];
    cams.extend(vec![
        look(
            DVec3::new(350.0, 3.0, 330.0),
            DVec3::new(350.0, 0.0, 350.0)
        );
        120
    ]);
    let scale = scale_800(&file);
    let input = SimInput::from_file(&file).unwrap();
    let (mut pressured, mut skipped) = (Vec::new(), Vec::new());
    for k in 3..=16u32 {
        let opts = atlastree::sim::SimOptions {
            fps: 30.0,
            pager: atlastree::paging::PagerOptions {
                capacity: k,
                ..Default::default()
            },
            io: None,
        };
        let (mut loads, mut evicted_after, mut nw_evicted) = (0, 0, false);
        let mut resident_at_end = false;
        simulate_with(
            &input,
            &cams,
            &vec![scale; cams.len()],
            &opts,
            &mut |frame, e| match e {
                Event::Loaded { block, .. } if block.0 == poster => {
                    loads += 1;
                    resident_at_end = true;
                }
                Event::Evicted { block } if block.0 == poster => {
                    resident_at_end = false;
                    if frame >= 60 {
                        evicted_after += 1;
                    }
                }
                Event::Evicted { block } if frame >= 60 && nw_only.contains(&block.0) => {
                    nw_evicted = true;
                }
                _ => {}
            },
        )
        .unwrap();
        if loads == 0 {
            // k too small to hold the poster with its parents at all: only the smallest capacities.
            skipped.push(k);
            continue;
        }
        assert_eq!(
            evicted_after, 0,
            "k = {k}: the shared block was evicted after the jump"
        );
        assert_eq!(
            loads, 1,
            "k = {k}: the shared block was loaded {loads} times"
        );
        assert!(resident_at_end, "k = {k}");
        if nw_evicted {
            pressured.push(k);
        }
    }
    assert!(
        !pressured.is_empty(),
        "no capacity evicted the north-west leaf's own blocks after the jump"
    );
    assert!(
        skipped.iter().enumerate().all(|(i, &k)| k == 3 + i as u32) && skipped.len() < 8,
        "capacities that never loaded the poster must be the smallest few: {skipped:?}"
    );
}

/// A non-square original (format 5) transfers its `w × h` chain but uploads its square class layer: the
/// block table's `bytes` and `upload_bytes` (what `UploadBudget::Bytes` counts) say so; atlases upload
/// what they transfer.
#[test]
fn a_non_square_original_transfers_its_chain_and_uploads_its_class_layer() {
    use atlastree::scene::synthetic::SceneBuilder;
    use atlastree::scene::{AlphaMode, UpAxis, Wrap};
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.image("wide", 256, 64, |x, y| [x as u8, y as u8, 80, 255]);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    let quad =
        [(0.0, 0.0), (16.0, 0.0), (16.0, 16.0), (0.0, 16.0)].map(|(x, z)| DVec3::new(x, 0.0, z));
    b.quad(quad, glam::DVec2::ZERO, glam::DVec2::splat(4.0), m);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("wide.atlastree");
    build(&b.build(), &options(), &out, &NoProgress).unwrap();
    let file = TreeFile::open(&out).unwrap();
    let table = BlockTable::from_file(&file).unwrap();
    let t = file.tree(0).unwrap();
    let f = t.format();
    let o = t.originals[0];
    assert_eq!(o.extent(), [256, 64]);
    let meta = table.meta(atlastree::ids::BlockId(o.block));
    assert_eq!(meta.bytes, f.chain_bytes_rect(256, 64));
    assert_eq!(meta.upload_bytes, f.chain_bytes(256));
    let atlas = table.atlas(0, NodeId(0)).unwrap();
    assert_eq!(table.meta(atlas).upload_bytes, table.meta(atlas).bytes);
}

/// Materials that draw one image through one sampler share its stored original (its bytes depend only
/// on image, wrap and, in the alpha tree, a MASK cutoff: `assemble::StoredOriginal`); a different wrap or
/// cutoff keeps its own. Every material keeps its own reference, the blocks hold each chain once, the
/// file verifies, and a reference that names another image in a shared slot is refused.
#[test]
fn materials_that_share_an_image_and_sampler_share_its_stored_original() {
    let scene = crate::fixtures::corners::shared_images(true);
    let materials: [atlastree::ids::MaterialId; 6] =
        std::array::from_fn(|i| atlastree::ids::MaterialId(i as u32));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("shared.atlastree");
    build(&scene, &options(), &out, &NoProgress).unwrap();
    let file = TreeFile::open(&out).unwrap();
    assert_eq!(file.trees(), 2, "an opaque and an alpha tree");
    // Per tree, the (block, slot) each material's references name.
    let mut places: HashMap<u32, BTreeSet<(u32, u32)>> = HashMap::new();
    let mut stored_bytes = 0;
    for ti in 0..file.trees() {
        let t = file.tree(ti).unwrap();
        let mut chains: HashMap<(u32, u32), u64> = HashMap::new();
        for o in t.originals {
            places
                .entry(o.material)
                .or_default()
                .insert((o.block, o.slot));
            let bytes = t.format().chain_bytes_rect(o.extent()[0], o.extent()[1]);
            chains.insert((o.block, o.slot), bytes);
        }
        stored_bytes += chains.values().sum::<u64>();
    }
    let place = |m: atlastree::ids::MaterialId| {
        let p = &places[&m.0];
        assert_eq!(p.len(), 1, "material {} stored once: {p:?}", m.0);
        *p.iter().next().unwrap()
    };
    let [a, b2, clamp, mask, mask_same, mask_other] = materials.map(place);
    assert_eq!(a, b2, "one image, one sampler: one stored original");
    assert_ne!(a, clamp, "another wrap is stored apart");
    assert_eq!(mask, mask_same, "one cutoff: shared");
    assert_ne!(mask, mask_other, "another cutoff is stored apart");
    // The originals blocks hold exactly the four distinct chains.
    let block_bytes: u64 = file
        .blocks()
        .iter()
        .filter(|b| b.kind == atlastree::store::format::BLOCK_ORIGINALS)
        .map(|b| b.length)
        .sum();
    assert_eq!(block_bytes, stored_bytes);
    let report = atlastree::inspect::verify(&file);
    assert!(report.ok(), "{:?}", report.violations);
    // inspect's repeat cost counts each stored original once per leaf that holds it, not once per
    // material reference (fault hunt, session 34): per leaf, the distinct slots of its repeat materials.
    // One leaf per tree (depth 0), so that the leaf's two materials share one original: the case the
    // per-reference count got wrong.
    let one_leaf = dir.path().join("one-leaf.atlastree");
    let opts = atlastree::preprocess::BuildOptions {
        max_depth: 0,
        leaf_originals_atlases: 1e6,
        ..options()
    };
    build(&scene, &opts, &one_leaf, &NoProgress).unwrap();
    let one_leaf = TreeFile::open(&one_leaf).unwrap();
    let info = atlastree::inspect::inspect(&one_leaf);
    let t = one_leaf.tree(0).unwrap();
    assert!(t.leaves.iter().any(|l| {
        let m: BTreeSet<u32> = t.leaf_originals(l).iter().map(|o| o.material).collect();
        m.contains(&materials[0].0) && m.contains(&materials[1].0)
    }));
    let mut per_leaf = 0u64;
    let mut once = BTreeSet::new();
    for leaf in t.leaves {
        let repeat: BTreeSet<u32> = t.leaf_rects(leaf).iter().map(|r| r.material).collect();
        let slots: BTreeSet<(u32, u32, u64)> = t
            .leaf_originals(leaf)
            .iter()
            .filter(|o| repeat.contains(&o.material) && o.material != materials[2].0)
            .map(|o| (o.block, o.slot, u64::from(o.width) * u64::from(o.height)))
            .collect();
        per_leaf += slots.iter().map(|s| s.2).sum::<u64>();
        once.extend(slots);
    }
    let repeats = &info.trees[0].repeats;
    assert_eq!(repeats.images, 1, "{repeats:?}");
    assert_eq!(repeats.original_texels_once, 128 * 128, "{repeats:?}");
    assert_eq!(once.len(), 1);
    assert_eq!(repeats.original_texels_per_leaf, per_leaf, "{repeats:?}");
    // One leaf: once (per reference it read twice).
    assert_eq!(t.leaves.len(), 1);
    assert_eq!(per_leaf, 128 * 128);
    // The opaque tree's leaf references three materials on two stored originals of one image: each
    // original held by one leaf (per reference, one read as held by two), one image.
    let tree = &info.trees[0];
    assert_eq!(tree.original_refs, 3);
    assert_eq!(tree.originals_stored, 2);
    assert_eq!(tree.originals_sharing, [(1, 2)]);
    assert_eq!(tree.original_textures, 1);
    // A shared slot's second reference pointed at another image is refused, naming the slot.
    let bytes = std::fs::read(&out).unwrap();
    let t = file.tree(0).unwrap();
    let first = t
        .originals
        .iter()
        .position(|o| o.material == materials[0].0);
    let second = t
        .originals
        .iter()
        .position(|o| o.material == materials[1].0);
    let (first, second) = (first.unwrap(), second.unwrap());
    assert_eq!(
        (t.originals[first].block, t.originals[first].slot),
        (t.originals[second].block, t.originals[second].slot)
    );
    drop(file);
    let mut edited = bytes.clone();
    let at = crate::store::record_at(
        &edited,
        atlastree::store::format::Section::Originals,
        second,
    );
    let other_image = u32::from_le_bytes(edited[at + 4..at + 8].try_into().unwrap()) ^ 1;
    edited[at + 4..at + 8].copy_from_slice(&other_image.to_le_bytes());
    let refused_as_bad_slot = |mut edited: Vec<u8>| {
        crate::store::reseal(&mut edited);
        match TreeFile::from_bytes(&edited) {
            Err(atlastree::store::StoreError::BadValue {
                table: "originals",
                field: "slot",
                ..
            }) => {}
            other => panic!("{:?}", other.err()),
        }
    };
    refused_as_bad_slot(edited);
    // So is a shared MASK slot whose materials' cutoffs came to differ (material 4's, at byte 16 of its
    // record, away from material 3's).
    let mut edited = bytes.clone();
    let at = crate::store::record_at(&edited, atlastree::store::format::Section::Materials, 4);
    edited[at + 16..at + 20].copy_from_slice(&0.75f32.to_le_bytes());
    refused_as_bad_slot(edited);
    // The unedited bytes read.
    TreeFile::from_bytes(&bytes).unwrap();
}
