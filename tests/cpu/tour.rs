//! The demo's tour (`atlastree demo`, [`DemoTour::DEFAULT`]) shows a tree: the embedded default scene built
//! with the demo's settings is a quadtree of depth ≥ 3, and the frame planner (all blocks resident, no GPU)
//! draws every level of every tree with its atlas at least once along the whole overview-dive, and the
//! original textures too; the paged flight's capacity is well below the block count.

use atlastree::preprocess::{NoProgress, build};
use atlastree::sim::tour::{DemoTour, levels_along};
use atlastree::store::TreeFile;

#[test]
fn the_demo_tour_draws_every_level_of_a_deep_tree() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::built::city_scene();
    let tour = DemoTour::DEFAULT;
    let out = dir.path().join("city.atlastree");
    build(scene, &tour.build_options(), &out, &NoProgress).unwrap();
    let file = TreeFile::open(&out).unwrap();
    let path = DemoTour::path(&file).unwrap();
    let cameras = tour.cameras(&path);
    assert_eq!(cameras.len(), tour.frames);
    // The whole path: the first frame at its start, the last at its end.
    let (first, last) = (cameras[0], cameras[cameras.len() - 1]);
    assert_eq!(first.eye, path.sample(path.start()).eye);
    let end = path.sample(path.start() + path.duration()).eye;
    assert!(
        (last.eye - end).length() < 1e-6,
        "{:?} vs {end:?}",
        last.eye
    );

    let scales = tour.scales(&file, &cameras).unwrap();
    let levels = levels_along(&file, &cameras, &scales).unwrap();
    assert_eq!(levels.len(), file.trees());
    let opaque = &levels[0];
    assert!(opaque.depth >= 3, "depth {}", opaque.depth);
    assert_eq!(opaque.nodes, file.tree(0).unwrap().nodes.len());
    for (t, lv) in levels.iter().enumerate() {
        assert!(
            lv.all_levels_drawn(),
            "tree {t}: levels drawn {:?} of 0..={} (frames per level {:?})",
            lv.levels_drawn(),
            lv.depth,
            lv.atlas_frames
        );
        assert_eq!(lv.frame_levels.len(), tour.frames);
        let most = usize::from(*lv.frame_levels.iter().max().unwrap());
        assert!(most <= usize::from(lv.depth) + 1);
    }
    // The street part of the dive is close enough for the originals.
    assert!(opaque.original_frames > 0, "{opaque:?}");
    // Some frame draws two levels at once (the README's picture).
    assert!(opaque.frame_levels.iter().any(|&n| n >= 2), "{opaque:?}");
    // Paging under k well below the block count.
    let blocks = file.blocks().len();
    assert!(
        (tour.capacity as usize) * 4 <= blocks,
        "k = {} of {blocks} blocks",
        tour.capacity
    );
}
