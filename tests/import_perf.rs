//! Import throughput on a generated 6.2M-triangle, 900-texture scene. Ignored by default (it writes
//! ~150 MB to a temp dir); run with `cargo test --test import_perf -- --ignored --nocapture`.

use atlastree::scene::{ImportOptions, import};
use serde_json::json;
use std::time::Instant;

#[test]
#[ignore]
fn six_million_triangles_900_textures() {
    const TILES: usize = 30; // 30 × 30 tiles, one primitive + material + PNG each
    const Q: usize = 34; // quads per tile side
    let dir = tempfile::tempdir().unwrap();
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut prims, mut images) = (vec![], vec![], vec![], vec![]);
    type Vs = Vec<serde_json::Value>;
    fn push(
        bin: &mut Vec<u8>,
        vs: (&mut Vs, &mut Vs),
        data: Vec<u8>,
        ctype: u32,
        count: usize,
        ty: &str,
    ) -> usize {
        let (views, accessors) = vs;
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()}));
        bin.extend_from_slice(&data);
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": ctype, "count": count, "type": ty}));
        accessors.len() - 1
    }
    let png = {
        let mut c = std::io::Cursor::new(Vec::new());
        image::DynamicImage::new_rgb8(64, 64)
            .write_to(&mut c, image::ImageFormat::Png)
            .unwrap();
        c.into_inner()
    };
    for ty in 0..TILES {
        for tx in 0..TILES {
            let (mut pos, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for j in 0..=Q {
                for i in 0..=Q {
                    let p = [(tx * Q + i) as f32, 0.0, (ty * Q + j) as f32];
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                    pos.extend(p.iter().flat_map(|x| x.to_le_bytes()));
                    uv.extend(
                        [i as f32 / 4.0, j as f32 / 4.0]
                            .iter()
                            .flat_map(|x| x.to_le_bytes()),
                    );
                }
            }
            for j in 0..Q as u32 {
                for i in 0..Q as u32 {
                    let a = j * (Q as u32 + 1) + i;
                    let b = a + Q as u32 + 1;
                    idx.extend(
                        [a, b, a + 1, a + 1, b, b + 1]
                            .iter()
                            .flat_map(|x| x.to_le_bytes()),
                    );
                }
            }
            let n = (Q + 1) * (Q + 1);
            let p = push(&mut bin, (&mut views, &mut accessors), pos, 5126, n, "VEC3");
            accessors[p]["min"] = json!(lo);
            accessors[p]["max"] = json!(hi);
            let u = push(&mut bin, (&mut views, &mut accessors), uv, 5126, n, "VEC2");
            let i = push(
                &mut bin,
                (&mut views, &mut accessors),
                idx,
                5125,
                Q * Q * 6,
                "SCALAR",
            );
            let m = prims.len();
            prims.push(json!({"attributes": {"POSITION": p, "TEXCOORD_0": u}, "indices": i, "material": m}));
            let name = format!("t{m}.png");
            std::fs::write(dir.path().join(&name), &png).unwrap();
            images.push(json!({"uri": name}));
        }
    }
    let n = prims.len();
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 1, 2]}], "scene": 0,
        "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [2000.0, 0.0, 0.0]}, {"mesh": 0, "translation": [0.0, 0.0, 2000.0]}],
        "meshes": [{"primitives": prims}],
        "images": images,
        "textures": (0..n).map(|i| json!({"source": i})).collect::<Vec<_>>(),
        "materials": (0..n).map(|i| json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}})).collect::<Vec<_>>(),
        "buffers": [{"uri": "data.bin", "byteLength": bin.len()}],
        "bufferViews": views, "accessors": accessors
    });
    std::fs::write(dir.path().join("data.bin"), &bin).unwrap();
    let path = dir.path().join("big.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let t = Instant::now();
    let s = import(&path, &ImportOptions::default()).unwrap();
    let dt = t.elapsed();
    println!(
        "imported {} triangles, {} vertices, {} images in {:.2} s",
        s.triangles.len(),
        s.vertices.len(),
        s.images.len(),
        dt.as_secs_f64()
    );
    assert_eq!(s.triangles.len(), 3 * TILES * TILES * Q * Q * 2);
    assert_eq!(s.images.len(), TILES * TILES);
    assert_eq!(s.report.warnings_total, 0);
    assert!(dt.as_secs_f64() < 30.0, "import took {dt:?}");
}
