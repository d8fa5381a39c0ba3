//! A generated many-texture scene (`tests/fixtures/tiled_gltf.rs`, the `import` bench's scene at a small
//! size): every triangle of every instance and every image arrives, with no warning.

use crate::fixtures::tiled_gltf;
use atlastree::scene::{ImportOptions, import};

#[test]
fn tiled_scene_imports_every_triangle_and_image() {
    const TILES: usize = 5;
    const QUADS: usize = 6;
    let dir = tempfile::tempdir().unwrap();
    let path = tiled_gltf::write(dir.path(), TILES, QUADS);
    let s = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(s.triangles.len(), tiled_gltf::triangles(TILES, QUADS));
    assert_eq!(s.images.len(), TILES * TILES);
    assert_eq!(s.report.warnings_total, 0);
}
