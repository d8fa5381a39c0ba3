//! The embedded city (`data/city`) as JSON to edit and import from a temp dir: the fixture of the
//! bad-input and feature suites.

use atlastree::scene::{ImportOptions, Scene, SceneError, import};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

pub(super) fn city_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city")
}

/// [`city_json`] with its buffer's URI absolute too: written anywhere, it imports with nothing beside it.
pub(super) fn city_json_standalone() -> Value {
    let mut doc = city_json();
    doc["buffers"][0]["uri"] = json!(city_dir().join("scene.bin").display().to_string());
    doc
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

/// A node under three parents is warned about once (10 such nodes gave 2,036 warnings), and its child,
/// visited three times through it but with one parent of its own, not at all.
#[test]
fn a_shared_node_is_warned_about_once_and_its_child_not() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json_standalone();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    // Node 1 (with its own children) becomes a child of the root and of two new parents.
    let n = nodes.len();
    nodes.push(json!({"name": "p1", "children": [1], "translation": [500.0, 0.0, 0.0]}));
    nodes.push(json!({"name": "p2", "children": [1], "translation": [0.0, 0.0, 500.0]}));
    doc["scenes"][0]["nodes"] = json!([0, n, n + 1]);
    let path = dir.path().join("shared.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = atlastree::scene::import(&path, &Default::default()).unwrap();
    let shared: Vec<_> = (scene.report.warnings.iter())
        .filter(|w| w.contains("has more than one parent"))
        .collect();
    assert_eq!(shared.len(), 1, "{shared:?}");
    assert!(shared[0].contains("node 1 has"), "{shared:?}");
}

/// A `matrix` beside TRS and a projective `matrix` (glTF 2.0 forbids both) are each warned about once
/// per node, however often the node is drawn, and drawn as the matrix alone, affinely.
#[test]
fn an_invalid_node_matrix_is_warned_about_once_per_node() {
    let dir = tempfile::tempdir().unwrap();
    let plain = atlastree::scene::import(&city_dir().join("scene.gltf"), &Default::default());
    let plain = plain.unwrap().bounds();
    let mut doc = city_json_standalone();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    let n = nodes.len();
    let identity = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    let mut projective = identity;
    projective[3] = 0.5;
    // Two wrappers around the root, one with matrix and a translation, one projective, each under two
    // parents: drawn twice.
    nodes.push(json!({"children": [0], "matrix": identity, "translation": [100.0, 0.0, 0.0]}));
    nodes.push(json!({"children": [0], "matrix": projective}));
    nodes.push(json!({"children": [n, n + 1]}));
    nodes.push(json!({"children": [n, n + 1]}));
    doc["scenes"][0]["nodes"] = json!([n + 2, n + 3]);
    let path = dir.path().join("matrix.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = atlastree::scene::import(&path, &Default::default()).unwrap();
    let w = &scene.report.warnings;
    let both = w
        .iter()
        .filter(|w| w.contains("has both `matrix` and"))
        .count();
    let row = w
        .iter()
        .filter(|w| w.contains("whose last row is [0.5, 0.0, 0.0, 1.0]"))
        .count();
    assert_eq!((both, row), (1, 1), "{w:?}");
    assert!(
        w.iter().any(|w| w.contains(&format!("node {n} has both"))),
        "{w:?}"
    );
    // The translation is ignored and the projective row too: the city where it was.
    assert_eq!(scene.bounds(), plain);
}

/// A scene given through a symbolic link resolves its relative URIs beside the link, else beside its
/// target (it read `link.gltf: buffer 0 (scene.bin): No such file or directory`; fault hunt, session
/// 34), and imports the same scene as the file itself.
#[cfg(unix)]
#[test]
fn a_symlinked_scene_resolves_uris_beside_the_link_or_its_target() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("link.gltf");
    std::os::unix::fs::symlink(city_dir().join("scene.gltf"), &link).unwrap();
    let through_link = import(&link, &ImportOptions::default()).unwrap();
    let direct = import(&city_dir().join("scene.gltf"), &ImportOptions::default()).unwrap();
    assert_eq!(through_link.triangles.len(), direct.triangles.len());
    assert_eq!(through_link.images.len(), direct.images.len());
    assert_eq!(through_link.report.warnings, direct.report.warnings);
    // A folder of links into a content-addressed store (a Hugging Face cache, git-annex): the files are
    // found beside the links, not beside the hash-named targets.
    let blobs = dir.path().join("blobs");
    let snapshot = dir.path().join("snapshot");
    std::fs::create_dir_all(&blobs).unwrap();
    std::fs::create_dir_all(&snapshot).unwrap();
    for (name, blob) in [("scene.gltf", "9f1c"), ("scene.bin", "77ab")] {
        std::fs::copy(city_dir().join(name), blobs.join(blob)).unwrap();
        std::os::unix::fs::symlink(blobs.join(blob), snapshot.join(name)).unwrap();
    }
    std::os::unix::fs::symlink(city_dir().join("textures"), snapshot.join("textures")).unwrap();
    let in_store = import(&snapshot.join("scene.gltf"), &ImportOptions::default()).unwrap();
    assert_eq!(in_store.triangles.len(), direct.triangles.len());
    assert_eq!(in_store.report.warnings, direct.report.warnings);
}
