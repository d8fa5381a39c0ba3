//! The import within a memory budget (`build --max-memory`): scene input past what the budget lets it
//! read is refused before it is read.

use atlastree::scene::{ImportOptions, SceneError, import};
use serde_json::json;

use super::city::{city_dir, city_json};

/// `ImportOptions::max_input_bytes`: the file and the buffers its JSON names (held whole while the
/// geometry is read) within the budget import; a byte over is refused, naming both numbers, before any
/// buffer is read (a one-quad scene naming a 1.5 GiB buffer was accepted at 300 MiB and peaked at
/// 1.5 GiB: fault hunt, session 35).
#[test]
fn input_past_the_budget_is_refused_before_it_is_read() {
    let path = city_dir().join("scene.gltf");
    let file = std::fs::metadata(&path).unwrap().len();
    let bin = std::fs::metadata(city_dir().join("scene.bin"))
        .unwrap()
        .len();
    let with = |path: &std::path::Path, max: u64| {
        import(
            path,
            &ImportOptions {
                max_input_bytes: Some(max),
                ..ImportOptions::default()
            },
        )
    };
    assert!(with(&path, file + bin).is_ok());
    let over = |result: Result<atlastree::scene::Scene, SceneError>| match result {
        Err(SceneError::OverInputBudget {
            bytes, max, what, ..
        }) => (bytes, max, what),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("imported over the budget"),
    };
    assert_eq!(
        over(with(&path, file + bin - 1)),
        (
            file + bin,
            file + bin - 1,
            "the file and the buffers it names"
        )
    );
    assert_eq!(over(with(&path, file - 1)), (file, file - 1, "the file"));
    // A buffer that says it is 2 GB is refused by its `byteLength`: no byte of it is read (the file
    // named is not even there).
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    doc["buffers"][0] = json!({"uri": "absent.bin", "byteLength": 2_000_000_000u64});
    let big = dir.path().join("big.gltf");
    std::fs::write(&big, serde_json::to_vec(&doc).unwrap()).unwrap();
    let len = std::fs::metadata(&big).unwrap().len();
    let (bytes, _, _) = over(with(&big, 1 << 30));
    assert_eq!(bytes, len + 2_000_000_000);
    let msg = with(&big, 1 << 30).err().unwrap().to_string();
    assert!(
        msg.contains("big.gltf") && msg.contains("memory budget"),
        "{msg}"
    );
}

/// Primitives sharing one vertex accessor, each with indices of its own, count the vertices their
/// indices can use, not the accessor once each: 50,000 primitives over 200,000 vertices were refused as
/// 10¹⁰ vertices past the u32 range (fault hunt, session 36). Here three primitives of three indices
/// share an accessor that claims 2³¹ vertices: the count is 9, so the import goes on to read the buffer
/// (absent here) instead of refusing the scene as too large.
#[test]
fn primitives_sharing_an_accessor_count_the_vertices_they_index() {
    let big = 1u64 << 31;
    let prim = |indices: u32| json!({"attributes": {"POSITION": 0}, "indices": indices});
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [prim(1), prim(2), prim(3)]}],
        "buffers": [{"uri": "absent.bin", "byteLength": big * 12 + 36}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": big * 12},
            {"buffer": 0, "byteOffset": big * 12, "byteLength": 36}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": big, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 1, "byteOffset": 0, "componentType": 5125, "count": 3, "type": "SCALAR"},
            {"bufferView": 1, "byteOffset": 12, "componentType": 5125, "count": 3, "type": "SCALAR"},
            {"bufferView": 1, "byteOffset": 24, "componentType": 5125, "count": 3, "type": "SCALAR"}
        ]
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = import(&path, &ImportOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(!e.contains("vertex index range"), "{e}");
    assert!(e.contains("absent.bin"), "{e}");
}
