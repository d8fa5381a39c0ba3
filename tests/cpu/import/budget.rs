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
