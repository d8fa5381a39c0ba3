//! Bad accessors: sparse indices that do not increase, and an accessor without a buffer view (zeros by
//! the spec, a morph target's included).

use atlastree::scene::{ImportOptions, import};
use serde_json::json;

use super::bad_input::city_triangles;
use super::city::{city_dir, city_json, import_city};

/// `bytes` as a glTF buffer's data URI.
fn data_uri(bytes: &[u8]) -> String {
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD.encode(bytes);
    format!("data:application/octet-stream;base64,{b64}")
}

/// The city with a sparse substitution on accessor 36 (16 positions): `indices` as u16 and as many
/// VEC3 values (each the accessor's own element at that index, so a valid substitution changes nothing),
/// in a second buffer given as a data URI.
fn city_with_sparse(indices: &[u16]) -> Result<usize, String> {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    let bin = std::fs::read(city_dir().join("scene.bin")).unwrap();
    let first = 1392;
    let mut data = Vec::new();
    for i in indices {
        data.extend_from_slice(&i.to_le_bytes());
    }
    while !data.len().is_multiple_of(4) {
        data.push(0);
    }
    let values_at = data.len();
    for &i in indices {
        let at = first + 12 * usize::from(i.min(15));
        data.extend_from_slice(&bin[at..at + 12]);
    }
    doc["buffers"].as_array_mut().unwrap().push(json!({
        "uri": data_uri(&data),
        "byteLength": data.len()
    }));
    let views = doc["bufferViews"].as_array_mut().unwrap();
    views.push(json!({"buffer": 1, "byteOffset": 0, "byteLength": values_at}));
    views.push(json!({"buffer": 1, "byteOffset": values_at, "byteLength": data.len() - values_at}));
    doc["accessors"][36]["sparse"] = json!({
        "count": indices.len(),
        "indices": {"bufferView": 4, "componentType": 5123},
        "values": {"bufferView": 5}
    });
    let (_, r) = import_city(dir.path(), &doc);
    r.map(|s| s.triangles.len()).map_err(|e| e.to_string())
}

/// glTF 2.0 §3.6.2.3: sparse indices strictly increase. Repeated or falling ones (the last write won,
/// silently; fault hunt, session 31) and more substitutions than elements are refused, naming the
/// accessor; increasing ones import as before.
#[test]
fn sparse_indices_must_strictly_increase() {
    assert_eq!(city_with_sparse(&[1, 2, 3]), Ok(city_triangles()));
    let e = city_with_sparse(&[2, 1, 2]).unwrap_err();
    assert!(
        e.contains("accessor 36: POSITION: ")
            && e.contains("sparse indices must strictly increase: index 0 is 2, index 1 is 1"),
        "{e}"
    );
    let e = city_with_sparse(&[3, 3]).unwrap_err();
    assert!(e.contains("index 0 is 3, index 1 is 3"), "{e}");
    let many: Vec<u16> = (0..17).collect();
    let e = city_with_sparse(&many).unwrap_err();
    assert!(
        e.contains("sparse count 17 exceeds the accessor's 16 elements"),
        "{e}"
    );
}

/// An accessor without a buffer view (and without sparse) is all zeros (glTF 2.0 §3.6.2.1): an exporter's
/// zero morph-target deltas. The schema check reported it missing and the whole file was refused (fault
/// hunt, session 32); it imports as the same quad with the target added as zeros. A POSITION accessor
/// without data draws nothing: its primitive is skipped with a warning (one compressed with Draco and
/// without a fallback came out as silent zero-area triangles: session 33), unless a weighted morph
/// target moves it.
#[test]
fn an_accessor_without_a_buffer_view_is_zeros() {
    let dir = tempfile::tempdir().unwrap();
    let positions: [f32; 12] = [0., 0., 0., 10., 0., 0., 10., 0., -10., 0., 0., -10.];
    let mut bin: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    bin.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|v| v.to_le_bytes()));
    let uri = data_uri(&bin);
    let doc = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "nodes": [{"mesh": 0}, {"mesh": 1}, {"mesh": 2, "translation": [100, 0, 0]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.3, 0.2, 1]}}],
        "meshes": [{"weights": [0.5], "primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
            "material": 0, "targets": [{"POSITION": 2}]}]},
            {"primitives": [{"attributes": {"POSITION": 2}, "indices": 1, "extensions":
                {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]},
            {"weights": [1.0], "primitives": [{"attributes": {"POSITION": 2}, "indices": 1,
                "targets": [{"POSITION": 0}]}]}],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, -10], "max": [10, 0, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]}
        ]
    });
    let path = dir.path().join("zeros.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let s = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(s.triangles.len(), 4);
    let xs: Vec<f64> = s.vertices.iter().map(|v| v.pos.x).collect();
    assert!(xs.contains(&10.0) && xs.contains(&0.0), "{xs:?}");
    assert!(xs.contains(&110.0), "the morphed zero base: {xs:?}");
    assert_eq!(s.report.skipped_primitives, 1);
    let w = s.report.warnings.join("\n");
    assert!(
        w.contains("mesh 1 (")
            && w.contains("accessor 2 has no data")
            && w.contains("KHR_draco_mesh_compression"),
        "{w}"
    );
}

/// Primitives sharing one vertex accessor (a three.js exporter's geometry groups) each read only the
/// vertices their indices use (10,000 such primitives took 6.6 s to import, each reading the whole
/// accessor; fault hunt, session 36; how much is read is not checked here). What they read must be what
/// the whole accessor holds at those places: a sparse substitution and a morph target's deltas inside
/// the second primitive's range land on the right vertices, and its indices (not starting at 0, in no
/// order, ending at the accessor's last element) name them.
#[test]
fn primitives_sharing_an_accessor_read_the_vertices_they_use() {
    let base = |i: usize| [10.0 * i as f32, 0.0, 5.0 * (i % 2) as f32];
    let delta = |i: usize| [0.0, 0.0, -(i as f32)];
    let substituted = [555.0f32, 0.0, 7.0];
    let mut bin: Vec<u8> = Vec::new();
    let mut put = |vals: &[f32]| vals.iter().for_each(|v| bin.extend(v.to_le_bytes()));
    (0..8).for_each(|i| put(&base(i)));
    (0..8).for_each(|i| put(&delta(i)));
    put(&substituted);
    bin.extend(
        [0u16, 1, 2, 0, 2, 3, 6, 5, 4, 6, 4, 7]
            .iter()
            .flat_map(|v| v.to_le_bytes()),
    );
    bin.extend(5u16.to_le_bytes());
    let uri = data_uri(&bin);
    let prim = |indices: usize| json!({"attributes": {"POSITION": 0}, "indices": indices, "targets": [{"POSITION": 1}]});
    let doc = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"weights": [0.5], "primitives": [prim(2), prim(3)]}],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                        {"buffer": 0, "byteOffset": 96, "byteLength": 96},
                        {"buffer": 0, "byteOffset": 192, "byteLength": 12},
                        {"buffer": 0, "byteOffset": 204, "byteLength": 24},
                        {"buffer": 0, "byteOffset": 228, "byteLength": 2}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [0, 0, 0], "max": [555, 0, 7],
             "sparse": {"count": 1, "indices": {"bufferView": 4, "componentType": 5123},
                        "values": {"bufferView": 2}}},
            {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [0, 0, -7], "max": [0, 0, 0]},
            {"bufferView": 3, "byteOffset": 0, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 3, "byteOffset": 12, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("groups.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let s = import(&path, &ImportOptions::default()).unwrap();
    let element = |i: usize| {
        let b = if i == 5 { substituted } else { base(i) };
        let d = delta(i);
        [0, 1, 2].map(|k| f64::from(b[k]) + 0.5 * f64::from(d[k]))
    };
    // Vertices in order of first use: 0, 1, 2, 3, then 6, 5, 4, 7.
    let expected: Vec<[f64; 3]> = [0, 1, 2, 3, 6, 5, 4, 7].map(element).to_vec();
    let got: Vec<[f64; 3]> = s.vertices.iter().map(|v| v.pos.to_array()).collect();
    assert_eq!(got, expected);
    let tris: Vec<[u32; 3]> = s.triangles.iter().map(|t| t.v).collect();
    assert_eq!(tris, [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]);
}
