//! Sharded builds and the images they decode: one glTF image drawn by an OPAQUE and a MASK material is
//! two scene images (one decoded with its alpha dropped), and two shards that each decoded one of them
//! read one file; rewritten between their builds, the merge refuses the mix (it merged old and new
//! pixels; fault hunt, session 37).

use super::shard::rewrite_keeping_length;
use atlastree::preprocess::shard::{ShardSpec, shard_path};
use atlastree::preprocess::{
    BuildOptions, MergeError, NoProgress, ShardedOptions, build_shard, merge,
};
use atlastree::scene::{ImportOptions, import};
use atlastree::store::shard::ShardFile;
use serde_json::json;
use std::path::Path;

/// Two 10 m quads far apart, one drawn by an OPAQUE material, one by a MASK material, both with the
/// texture of `t0.png` (256², a checker of alpha 255 and 40): written into `dir`, path of the glTF.
fn two_materials_one_image(dir: &Path) -> std::path::PathBuf {
    let png = image::RgbaImage::from_fn(256, 256, |x, y| {
        let alpha = if (x / 32 + y / 32) % 2 == 0 { 255 } else { 40 };
        image::Rgba([x as u8, y as u8, 90, alpha])
    });
    png.save(dir.join("t0.png")).unwrap();
    let mut bin: Vec<u8> = Vec::new();
    for k in 0..2 {
        let x0 = 100.0 * k as f32;
        let quad = [
            [x0, 0., 0.],
            [x0 + 10., 0., 0.],
            [x0 + 10., 0., 10.],
            [x0, 0., 10.],
        ];
        quad.iter()
            .flatten()
            .for_each(|v| bin.extend(v.to_le_bytes()));
    }
    [[0f32, 1.], [1., 1.], [1., 0.], [0., 0.]]
        .iter()
        .flatten()
        .for_each(|v| bin.extend(v.to_le_bytes()));
    [0u16, 2, 1, 0, 3, 2]
        .iter()
        .for_each(|v| bin.extend(v.to_le_bytes()));
    std::fs::write(dir.join("scene.bin"), &bin).unwrap();
    let prim = |k: usize| {
        json!({"primitives": [{"attributes": {"POSITION": k, "TEXCOORD_0": 2}, "indices": 3,
                               "material": k}]})
    };
    let doc = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}],
        "meshes": [prim(0), prim(1)],
        "materials": [
            {"name": "opaque", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
            {"name": "mask", "alphaMode": "MASK",
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}
        ],
        "textures": [{"source": 0}], "images": [{"uri": "t0.png"}],
        "buffers": [{"uri": "scene.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [10, 0, 10]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [100, 0, 0], "max": [110, 0, 10]},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

#[test]
fn merge_refuses_shards_that_decoded_two_versions_of_one_file_as_two_images() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_materials_one_image(dir.path());
    let scene = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(scene.images.len(), 2, "one image for each alpha handling");
    let out = dir.path().join("out.atlastree");
    let opts = BuildOptions {
        atlas_size: 256,
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    let count = 2;
    let shard = |index: u32| {
        let spec = ShardSpec { index, count };
        let argv = [
            "atlastree",
            "build",
            "scene.gltf",
            "--shard",
            &spec.to_string(),
        ];
        let sharded = ShardedOptions {
            spec,
            argv: argv.iter().map(|a| a.to_string()).collect(),
            import: None,
        };
        build_shard(&scene, &opts, &out, &sharded, &NoProgress).unwrap();
        ShardFile::open(&shard_path(&out, spec)).unwrap()
    };
    let first = shard(0);
    assert!(rewrite_keeping_length(&dir.path().join("t0.png"), 256, 256));
    let second = shard(1);
    // The setup: each shard decoded one of the two scene images, not both.
    let decoded = |f: &ShardFile| -> Vec<u32> { f.images.iter().map(|e| e.decoded).collect() };
    let (a, b) = (decoded(&first), decoded(&second));
    assert!(a.iter().zip(&b).all(|(x, y)| x + y == 1), "{a:?} {b:?}");
    drop((first, second));
    let e = merge(&out, None, &NoProgress).unwrap_err();
    assert!(
        matches!(&e, MergeError::ImagesDiffer { image, first: 0, second: 1, .. }
            if image.contains("glTF image 0")),
        "{e}"
    );
    assert!(!out.exists(), "a refused merge writes nothing");
}
