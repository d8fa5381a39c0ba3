//! The embedded city (`data/city`) as JSON to edit and import from a temp dir: the fixture of the
//! bad-input and feature suites.

use atlastree::scene::{ImportOptions, Scene, SceneError, import};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

pub(super) fn city_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city")
}

/// The city's JSON with every image URI made absolute (so a copy in a temp dir needs no textures).
pub(super) fn city_json() -> Value {
    let text = std::fs::read(city_dir().join("scene.gltf")).unwrap();
    let mut doc: Value = serde_json::from_slice(&text).unwrap();
    for img in doc["images"].as_array_mut().unwrap() {
        let abs = city_dir().join(img["uri"].as_str().unwrap());
        img["uri"] = json!(abs.display().to_string());
    }
    doc
}

/// Writes `doc` as `dir/scene.gltf` (with the city's `scene.bin` next to it) and imports it.
pub(super) fn import_city(dir: &Path, doc: &Value) -> (PathBuf, Result<Scene, SceneError>) {
    std::fs::copy(city_dir().join("scene.bin"), dir.join("scene.bin")).unwrap();
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(doc).unwrap()).unwrap();
    let r = import(&path, &ImportOptions::default());
    (path, r)
}
