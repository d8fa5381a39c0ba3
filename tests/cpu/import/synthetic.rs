//! Import of small hand-written glTF files (written into temp dirs): transforms, instancing, texture
//! transforms, samplers, alpha modes, solid colours, image formats, fallbacks and counted skips.

use atlastree::scene::{AlphaMode, ImportOptions, Scene, SceneError, UpAxis, Wrap, import, info};
use atlastree::scene::{FALLBACK_COLORS, ImageData};
use glam::{DVec2, DVec3};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// Accumulates one binary buffer, its views and accessors.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

fn n_of(ty: &str) -> usize {
    match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        _ => panic!("{ty}"),
    }
}

impl Bin {
    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let off = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.views
            .push(json!({"buffer": 0, "byteOffset": off, "byteLength": data.len()}));
        self.views.len() - 1
    }
    fn accessor(
        &mut self,
        data: &[u8],
        ctype: u32,
        count: usize,
        ty: &str,
        normalized: bool,
    ) -> usize {
        let v = self.view(data);
        let mut a = json!({"bufferView": v, "componentType": ctype, "count": count, "type": ty});
        if normalized {
            a["normalized"] = json!(true);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }
    fn f32s(&mut self, d: &[f32], ty: &str) -> usize {
        let b: Vec<u8> = d.iter().flat_map(|x| x.to_le_bytes()).collect();
        let i = self.accessor(&b, 5126, d.len() / n_of(ty), ty, false);
        if ty == "VEC3" {
            // POSITION min/max (required by glTF), over finite values.
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for c in d.chunks(3).filter(|c| c.iter().all(|x| x.is_finite())) {
                for k in 0..3 {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            self.accessors[i]["min"] = json!(lo);
            self.accessors[i]["max"] = json!(hi);
        }
        i
    }
    fn u16s(&mut self, d: &[u16], ty: &str, normalized: bool) -> usize {
        let b: Vec<u8> = d.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&b, 5123, d.len() / n_of(ty), ty, normalized)
    }
    fn u8s(&mut self, d: &[u8], ty: &str, normalized: bool) -> usize {
        self.accessor(d, 5121, d.len() / n_of(ty), ty, normalized)
    }
    fn u32s(&mut self, d: &[u32]) -> usize {
        let b: Vec<u8> = d.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&b, 5125, d.len(), "SCALAR", false)
    }

    /// Writes `data.bin` and `scene.gltf` (with `doc` completed by asset, buffers, views, accessors).
    fn write(&self, dir: &Path, mut doc: Value) -> PathBuf {
        std::fs::write(dir.join("data.bin"), &self.bytes).unwrap();
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([{"uri": "data.bin", "byteLength": self.bytes.len()}]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        let path = dir.join("scene.gltf");
        std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        path
    }
}

const TRI_POS: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
const TRI_UV: [f32; 6] = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];

fn imp(path: &Path) -> Scene {
    import(path, &ImportOptions::default()).unwrap()
}

fn write_png(dir: &Path, name: &str, img: image::DynamicImage) {
    img.save_with_format(dir.join(name), image::ImageFormat::Png)
        .unwrap();
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}

#[test]
fn node_hierarchy_and_two_instances_give_distinct_world_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"translation": [10.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [1]},
            {"mesh": 0, "rotation": [0.0, 0.0, h, h], "translation": [0.0, 0.0, 1.0]},
            {"mesh": 0, "translation": [5000000.123, 0.0, -3.25]},
            {"mesh": 0, "translation": [99.0, 0.0, 0.0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.vertices.len(), 6);
    assert_eq!(s.report.instances, 2);
    assert_eq!(s.report.nodes, 3, "node 3 is not in the scene");
    let t0 = s.tri_positions(&s.triangles[0]);
    // Local (x, y, z) → Rz(90°) → +(0,0,1) → ×2 → +(10,0,0).
    assert!(close(t0[0], DVec3::new(10.0, 0.0, 2.0)), "{t0:?}");
    assert!(close(t0[1], DVec3::new(10.0, 2.0, 2.0)), "{t0:?}");
    assert!(close(t0[2], DVec3::new(8.0, 0.0, 2.0)), "{t0:?}");
    // The translation is read in f64: 5000000.123 is not representable in f32 (→ 5000000.0).
    let t1 = s.tri_positions(&s.triangles[1]);
    assert_eq!(t1[1], DVec3::new(5000000.123 + 1.0, 0.0, -3.25));
    let mut all: Vec<u32> = s.triangles.iter().flat_map(|t| t.v).collect();
    all.sort();
    all.dedup();
    assert_eq!(all.len(), 6, "instances share no vertices");
}

#[test]
fn gpu_instancing_extension() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let tr = b.f32s(&[0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 0.0, 10.0], "VEC3");
    let sc = b.f32s(&[1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 1.0, 1.0, 1.0], "VEC3");
    let doc = json!({
        "extensionsUsed": ["EXT_mesh_gpu_instancing"],
        "extensionsRequired": ["EXT_mesh_gpu_instancing"],
        "scenes": [{"nodes": [0]}], "scene": 0,
        "nodes": [{"mesh": 0, "translation": [0.0, 5.0, 0.0],
                   "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": tr, "SCALE": sc}}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 3);
    assert_eq!(s.report.instances, 3);
    // Instance 1: local (1,0,0) ×2 +(10,0,0), then the node's +(0,5,0).
    assert!(close(
        s.tri_positions(&s.triangles[1])[1],
        DVec3::new(12.0, 5.0, 0.0)
    ));
    assert!(close(
        s.tri_positions(&s.triangles[2])[2],
        DVec3::new(0.0, 6.0, 10.0)
    ));
}

#[test]
fn recursive_and_shared_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let mesh = json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]);
    let doc = json!({"scenes": [{"nodes": [0]}], "scene": 0,
        "nodes": [{"children": [1]}, {"mesh": 0, "children": [2]}, {"children": [1]}], "meshes": mesh});
    let e = import(&b.write(dir.path(), doc), &ImportOptions::default()).unwrap_err();
    assert!(
        matches!(e, SceneError::RecursiveNodes { node: 1, .. }),
        "{e}"
    );
    // A node with two parents (invalid glTF, no cycle): instanced once per parent, with a warning.
    let doc = json!({"scenes": [{"nodes": [0, 1]}], "scene": 0,
        "nodes": [{"children": [2]}, {"children": [2], "translation": [0.0, 0.0, 5.0]}, {"mesh": 0}],
        "meshes": mesh});
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.report.warnings_total, 1);
}

/// Texture transform maths (hand-computed), the texCoord override, wrap modes and alpha modes.
#[test]
fn texture_transform_wrap_and_alpha() {
    let dir = tempfile::tempdir().unwrap();
    write_png(dir.path(), "t e x.png", image::DynamicImage::new_rgb8(4, 2));
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let uv0 = b.f32s(&TRI_UV, "VEC2");
    let uv1 = b.f32s(&[0.5, 0.5, 2.0, 0.5, 0.5, 3.0], "VEC2");
    let prim = |m: usize| json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv0, "TEXCOORD_1": uv1}, "material": m});
    let tex = |t: usize, ext: Value| json!({"baseColorTexture": {"index": t, "extensions": ext}});
    let doc = json!({
        "extensionsUsed": ["KHR_texture_transform"],
        "scenes": [{"nodes": [0]}], "scene": 0,
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [prim(0), prim(1), prim(2), prim(3)]}],
        "images": [{"uri": "t%20e%20x.png"}],
        "samplers": [{"wrapS": 33648, "wrapT": 33071}],
        "textures": [{"source": 0, "sampler": 0}, {"source": 0}],
        "materials": [
            {"pbrMetallicRoughness": tex(0, json!({"KHR_texture_transform":
                {"offset": [0.25, -0.5], "rotation": 1.0, "scale": [2.0, 0.5]}})),
             "alphaMode": "MASK"},
            {"pbrMetallicRoughness": tex(1, json!({"KHR_texture_transform": {"texCoord": 1, "scale": [3.0, 3.0]}})),
             "alphaMode": "MASK", "alphaCutoff": 0.25},
            {"pbrMetallicRoughness": tex(1, json!({})), "alphaMode": "BLEND"},
            {"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.0, 0.0, 1.0]}}
        ]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 4);
    assert_eq!(
        s.images.len(),
        2,
        "one file image (decoded name with spaces) + one solid"
    );
    assert_eq!(s.images[0].name, "t e x.png");
    assert_eq!((s.images[0].width, s.images[0].height), (4, 2));
    let uvs = |i: usize| s.tri_uvs(&s.triangles[i]);
    // Material 0: u' = cos·2u + sin·0.5v + 0.25, v' = −sin·2u + cos·0.5v − 0.5.
    let (sn, cs) = 1.0_f64.sin_cos();
    let want = [
        DVec2::new(0.25, -0.5),
        DVec2::new(2.0 * cs + 0.25, -2.0 * sn - 0.5),
        DVec2::new(0.5 * sn + 0.25, 0.5 * cs - 0.5),
    ];
    for (got, want) in uvs(0).iter().zip(want) {
        assert!((*got - want).length() < 1e-12, "{got} vs {want}");
    }
    // Material 1: texCoord override → TEXCOORD_1, ×3.
    assert_eq!(
        uvs(1),
        [
            DVec2::new(1.5, 1.5),
            DVec2::new(6.0, 1.5),
            DVec2::new(1.5, 9.0)
        ]
    );
    assert_eq!(s.materials[1].tex_coord, 1);
    assert!(s.materials[1].texture_transform);
    // Material 2: plain TEXCOORD_0.
    assert_eq!(
        uvs(2),
        [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0)
        ]
    );
    assert_eq!(
        s.materials[0].wrap,
        [Wrap::MirroredRepeat, Wrap::ClampToEdge]
    );
    assert_eq!(s.materials[2].wrap, [Wrap::Repeat, Wrap::Repeat]);
    assert_eq!(s.materials[0].alpha, AlphaMode::Mask { cutoff: 0.5 });
    assert_eq!(s.materials[1].alpha, AlphaMode::Mask { cutoff: 0.25 });
    assert_eq!(s.materials[2].alpha, AlphaMode::Blend);
    assert_eq!(s.materials[3].alpha, AlphaMode::Opaque);
    assert!(s.has_alpha());
    // Solid red: sRGB (255, 0, 0, 255); its UVs are the texel centre.
    assert_eq!(
        s.images[s.materials[3].image.idx()]
            .decode()
            .unwrap()
            .pixels,
        vec![[255, 0, 0, 255]]
    );
    assert_eq!(uvs(3), [DVec2::splat(0.5); 3]);
    // scene-info: per-material UV extents.
    let inf = info::analyze(&s);
    assert_eq!(inf.materials[1].uv_bbox_span, Some([4.5, 7.5]));
    assert_eq!(inf.materials[1].max_triangle_uv_span, Some([4.5, 7.5]));
    assert_eq!(inf.textures[0].triangles, 3);
    assert_eq!(
        (inf.alpha.opaque, inf.alpha.mask, inf.alpha.blend),
        (1, 2, 1)
    );
    let text = inf.to_string();
    assert!(
        text.contains("t e x.png") && text.contains("MirroredRepeat/ClampToEdge"),
        "{text}"
    );
}

#[test]
fn solid_colours_default_material_and_missing_texcoord() {
    let dir = tempfile::tempdir().unwrap();
    write_png(dir.path(), "a.png", image::DynamicImage::new_rgb8(2, 2));
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let p = |m: Option<usize>| match m {
        Some(m) => json!({"attributes": {"POSITION": pos}, "material": m}),
        None => json!({"attributes": {"POSITION": pos}}),
    };
    let doc = json!({
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [p(Some(0)), p(Some(1)), p(Some(2)), p(None), p(Some(3))]}],
        "images": [{"uri": "a.png"}], "textures": [{"source": 0}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 0.5]}},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 0.5]}},
            {"pbrMetallicRoughness": {}},
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [0.0, 1.0, 0.0, 1.0]}}
        ]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.materials.len(), 5);
    let img = |m: usize| s.materials[m].image;
    assert_eq!(img(0), img(1), "identical colours share one image");
    assert_eq!(
        img(2),
        img(3),
        "default material = white, same as the explicit white one"
    );
    // OPAQUE: the factor's alpha 0.5 is ignored (glTF §3.9.4), so the solid colour is opaque.
    let grey = &s.images[img(0).idx()];
    assert!(matches!(grey.data, ImageData::Solid([188, 188, 188, 255])));
    assert!(!grey.has_alpha);
    assert_eq!(s.materials[0].base_color_factor, [1.0; 4]);
    assert!(matches!(
        s.images[img(2).idx()].data,
        ImageData::Solid([255, 255, 255, 255])
    ));
    // Textured material without TEXCOORD_0: counted, solid green instead; the PNG is never loaded.
    assert_eq!(s.report.missing_texcoords, 1);
    assert!(matches!(
        s.images[img(4).idx()].data,
        ImageData::Solid([0, 255, 0, 255])
    ));
    assert_eq!(s.images.len(), 3);
}

#[test]
fn png_colour_types_decode_to_rgba8() {
    let dir = tempfile::tempdir().unwrap();
    // 16-bit grey+alpha.
    let mut la16 = image::ImageBuffer::<image::LumaA<u16>, _>::new(2, 1);
    la16.put_pixel(0, 0, image::LumaA([65535, 32768]));
    la16.put_pixel(1, 0, image::LumaA([257 * 10, 0]));
    write_png(
        dir.path(),
        "la16.png",
        image::DynamicImage::ImageLumaA16(la16),
    );
    // 8-bit grey.
    let mut l8 = image::GrayImage::new(1, 2);
    l8.put_pixel(0, 1, image::Luma([77]));
    write_png(dir.path(), "l8.png", image::DynamicImage::ImageLuma8(l8));
    // 16-bit RGBA.
    let mut rgba16 = image::ImageBuffer::<image::Rgba<u16>, _>::new(1, 1);
    rgba16.put_pixel(0, 0, image::Rgba([65535, 0, 257 * 100, 257 * 200]));
    write_png(
        dir.path(),
        "rgba16.png",
        image::DynamicImage::ImageRgba16(rgba16),
    );
    // 4-bit palette with tRNS: 3×1 pixels of indices 2, 0, 1.
    {
        let f = std::fs::File::create(dir.path().join("pal.png")).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), 3, 1);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Four);
        enc.set_palette(vec![255, 0, 0, 0, 255, 0, 0, 0, 255]);
        enc.set_trns(vec![255, 128, 0]);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[0x20, 0x10]).unwrap();
    }
    // JPEG grey.
    image::DynamicImage::new_luma8(8, 8)
        .save_with_format(dir.path().join("g.jpg"), image::ImageFormat::Jpeg)
        .unwrap();
    let names = ["la16.png", "l8.png", "rgba16.png", "pal.png", "g.jpg"];
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let uv = b.f32s(&TRI_UV, "VEC2");
    let prims: Vec<Value> = (0..names.len())
        .map(|i| json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": i}))
        .collect();
    let doc = json!({
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": prims}],
        "images": names.iter().map(|n| json!({"uri": n})).collect::<Vec<_>>(),
        "textures": (0..names.len()).map(|i| json!({"source": i})).collect::<Vec<_>>(),
        "materials": (0..names.len()).map(|i| json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}})).collect::<Vec<_>>()
    });
    let s = imp(&b.write(dir.path(), doc));
    let got: Vec<(&str, u32, u32, bool)> = s
        .images
        .iter()
        .map(|i| (i.color.as_str(), i.width, i.height, i.has_alpha))
        .collect();
    assert_eq!(
        got,
        [
            ("La16", 2, 1, true),
            ("L8", 1, 2, false),
            ("Rgba16", 1, 1, true),
            ("Palette4", 3, 1, true),
            ("L8", 8, 8, false)
        ]
    );
    let px = |i: usize| s.images[i].decode().unwrap().pixels;
    assert_eq!(px(0), vec![[255, 255, 255, 128], [10, 10, 10, 0]]);
    assert_eq!(px(1), vec![[0, 0, 0, 255], [77, 77, 77, 255]]);
    assert_eq!(px(2), vec![[255, 0, 100, 200]]);
    assert_eq!(
        px(3),
        vec![[0, 0, 255, 0], [255, 0, 0, 255], [0, 255, 0, 128]]
    );
    assert_eq!(px(4).len(), 64);
}

#[test]
fn missing_and_broken_images_fall_back_and_count() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("broken.png"),
        b"\x89PNG\r\n\x1a\nthis is not a png",
    )
    .unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let uv = b.f32s(&TRI_UV, "VEC2");
    let p = |m: usize| json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": m});
    let doc = json!({
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [p(0), p(1), p(0)]}],
        "images": [{"uri": "nope.png"}, {"uri": "broken.png"}],
        "textures": [{"source": 0}, {"source": 1}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                      {"pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 3, "geometry is kept");
    assert_eq!(s.report.missing_images, 2, "counted once per image");
    assert!(
        s.report.warnings[0].contains("nope.png"),
        "{:?}",
        s.report.warnings
    );
    assert!(
        s.report.warnings[1].contains("broken.png"),
        "{:?}",
        s.report.warnings
    );
    for img in &s.images {
        assert!(img.is_fallback());
        let d = img.decode().unwrap();
        assert_eq!((d.width, d.height), (8, 8));
        assert_eq!(d.pixels[0], FALLBACK_COLORS[0]);
        assert_eq!(d.pixels[1], FALLBACK_COLORS[1]);
    }
}

#[test]
fn nan_positions_nan_uvs_and_huge_uvs() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let nan = f32::NAN;
    // Five triangles over 8 vertices: #1 has a NaN position, #2 a NaN UV, #3 a UV of 2e6.
    let pos = b.f32s(
        &[
            0., 0., 0., 1., 0., 0., 0., 1., 0., nan, 0., 0., 2., 0., 0., 3., 0., 0., 3., 1., 0.,
            4., 1., 0.,
        ],
        "VEC3",
    );
    let uv = b.f32s(
        &[
            0., 0., 1., 0., 0., 1., 0., 0., nan, 1., 2e6, 0., 0., 0., 0., 0.,
        ],
        "VEC2",
    );
    let idx = b.u16s(
        &[0, 1, 2, 3, 1, 2, 4, 0, 1, 5, 6, 7, 0, 1, 2],
        "SCALAR",
        false,
    );
    let doc = json!({
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx, "material": 0}]}],
        "images": [{"uri": "x.png"}], "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 3);
    assert_eq!(s.report.skipped_triangles, 2);
    assert_eq!(s.report.large_uv_triangles, 1);
    assert_eq!(
        s.vertices.len(),
        6,
        "only referenced vertices are emitted (3 + 5,6,7)"
    );
    assert!(s.vertices.iter().all(|v| v.pos.is_finite()));
    let (lo, hi) = s.bounds().unwrap();
    assert_eq!((lo, hi), (DVec3::ZERO, DVec3::new(4.0, 1.0, 0.0)));
    assert!(s.tri_uvs(&s.triangles[1]).iter().any(|u| u.x == 2e6));
}

#[test]
fn strips_fans_quantized_uvs_and_u8_indices() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let quad = b.f32s(&[0., 0., 0., 1., 0., 0., 0., 0., 1., 1., 0., 1.], "VEC3");
    let uv16 = b.u16s(&[0, 0, 65535, 0, 0, 32768, 65535, 65535], "VEC2", true);
    let uv8 = b.u8s(&[0, 0, 255, 0, 0, 51, 255, 255], "VEC2", true);
    let idx8 = b.u8s(&[0, 1, 3, 2], "SCALAR", false);
    let idx32 = b.u32s(&[0, 1, 2, 2, 1, 3]);
    let pts = json!({"attributes": {"POSITION": quad}, "mode": 0});
    let doc = json!({
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": quad, "TEXCOORD_0": uv16}, "mode": 5, "material": 0},
            {"attributes": {"POSITION": quad, "TEXCOORD_0": uv8}, "mode": 6, "indices": idx8, "material": 0},
            {"attributes": {"POSITION": quad}, "indices": idx32},
            pts, pts
        ]}],
        "images": [{"uri": "x.png"}], "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.triangles.len(), 6);
    assert_eq!(s.report.skipped_primitives, 2, "two POINTS primitives");
    // Strip 0,1,2,3 → (0,1,2), (1,3,2); UVs from normalised u16.
    let uv = s.tri_uvs(&s.triangles[1]);
    assert_eq!(
        uv,
        [
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 32768.0 / 65535.0)
        ]
    );
    // Fan over indices [0,1,3,2] → (1,3,0), (3,2,0); UVs from normalised u8.
    let p = s.tri_positions(&s.triangles[2]);
    assert_eq!(
        p,
        [DVec3::new(1., 0., 0.), DVec3::new(1., 0., 1.), DVec3::ZERO]
    );
    assert_eq!(s.tri_uvs(&s.triangles[3])[1], DVec2::new(0.0, 0.2));
}

#[test]
fn structural_errors_name_their_source() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let idx = b.u16s(&[0, 1, 3], "SCALAR", false);
    let base = |prim: Value| {
        json!({"scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
               "meshes": [{"name": "M", "primitives": [prim]}]})
    };
    let err =
        |doc: Value| import(&b.write(dir.path(), doc), &ImportOptions::default()).unwrap_err();
    let e = err(base(
        json!({"attributes": {"POSITION": pos}, "indices": idx}),
    ));
    assert!(
        matches!(
            e,
            SceneError::IndexOutOfRange {
                index: 3,
                vertex_count: 3,
                position: 2,
                ..
            }
        ),
        "{e}"
    );
    let mut doc = base(json!({"attributes": {"POSITION": pos}}));
    doc["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    doc["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    assert!(matches!(err(doc), SceneError::UnsupportedExtension { .. }));
    // Accessor past the end of its view.
    let mut b2 = Bin::default();
    let pos2 = b2.f32s(&TRI_POS, "VEC3");
    b2.accessors[pos2]["count"] = json!(4);
    let doc = base(json!({"attributes": {"POSITION": pos2}}));
    let e = import(&b2.write(dir.path(), doc), &ImportOptions::default()).unwrap_err();
    match &e {
        SceneError::Accessor {
            mesh: 0,
            primitive: 0,
            accessor: 0,
            mesh_name,
            ..
        } => assert_eq!(mesh_name, "M"),
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("past the end"), "{e}");
    // Missing buffer file.
    let path = b.write(dir.path(), base(json!({"attributes": {"POSITION": pos}})));
    std::fs::remove_file(dir.path().join("data.bin")).unwrap();
    let e = import(&path, &ImportOptions::default()).unwrap_err();
    assert!(
        matches!(e, SceneError::Buffer { buffer: 0, .. }) && e.to_string().contains("data.bin"),
        "{e}"
    );
}

/// A scene in `dir` of one mesh with `n` primitives, each a line strip (mode 1), so the import skips all.
fn lines_only(dir: &Path, n: usize) -> PathBuf {
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let prims: Vec<Value> = (0..n)
        .map(|_| json!({"attributes": {"POSITION": pos}, "mode": 1}))
        .collect();
    let doc = json!({"scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}], "meshes": [{"primitives": prims}]});
    b.write(dir, doc)
}

#[test]
fn warnings_are_capped_but_counted() {
    let dir = tempfile::tempdir().unwrap();
    let s = imp(&lines_only(dir.path(), 150));
    assert_eq!(s.report.skipped_primitives, 150);
    assert_eq!(s.report.warnings_total, 150);
    assert_eq!(s.report.warnings.len(), 101);
    assert_eq!(s.report.warnings[100], "... and 50 more");
}

/// A scene whose every primitive is skipped on import (lines here) fails the build saying what was skipped
/// and quoting the warnings, and writes nothing.
#[test]
fn a_build_with_no_triangle_left_says_what_the_import_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let path = lines_only(dir.path(), 5);
    let scene = imp(&path);
    let out = dir.path().join("out.atlastree");
    let opts = atlastree::preprocess::BuildOptions::default();
    let e = atlastree::preprocess::build(&scene, &opts, &out, &atlastree::preprocess::NoProgress)
        .unwrap_err();
    let text = e.to_string();
    let head = format!(
        "the scene {} has no triangles to build a tree from: the import skipped 5 primitives and 0 triangles; 5 \
         warnings, the first: ",
        path.display()
    );
    assert!(text.starts_with(&head), "{text}");
    // The first three warnings, each naming the primitive and its mode.
    assert_eq!(
        text.matches("is not triangles; skipped").count(),
        3,
        "{text}"
    );
    assert!(!out.exists());
    // Nothing skipped (a node without a mesh): the error says the scene draws no triangles.
    let mut b = Bin::default();
    let _ = b.f32s(&TRI_POS, "VEC3");
    let doc = json!({"scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{}]});
    let scene = imp(&b.write(dir.path(), doc));
    let e = atlastree::preprocess::build(&scene, &opts, &out, &atlastree::preprocess::NoProgress)
        .unwrap_err();
    assert!(
        e.to_string().ends_with(
            "the import skipped 0 primitives and 0 triangles: the default scene draws no triangle primitives \
             (points and lines are not drawn), or the scene filters kept none"
        ),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn glb_with_embedded_png_and_data_uri_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let mut png = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgba8(image::RgbaImage::from_pixel(
        3,
        5,
        image::Rgba([1, 2, 3, 4]),
    ))
    .write_to(&mut png, image::ImageFormat::Png)
    .unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let uv = b.f32s(&TRI_UV, "VEC2");
    let img_view = b.view(png.get_ref());
    while b.bytes.len() % 4 != 0 {
        b.bytes.push(0);
    }
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}]}],
        "images": [{"bufferView": img_view, "mimeType": "image/png"}], "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "buffers": [{"byteLength": b.bytes.len()}], "bufferViews": b.views, "accessors": b.accessors
    });
    let mut json_bytes = serde_json::to_vec(&doc).unwrap();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + b.bytes.len();
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json_bytes);
    glb.extend_from_slice(&(b.bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&b.bytes);
    let path = dir.path().join("s.glb");
    std::fs::write(&path, &glb).unwrap();
    let s = imp(&path);
    assert_eq!(s.triangles.len(), 1);
    let img = &s.images[0];
    assert!(matches!(img.data, ImageData::Bytes(_)));
    assert_eq!(
        (img.width, img.height, img.color.as_str(), img.has_alpha),
        (3, 5, "Rgba8", true)
    );
    assert_eq!(img.decode().unwrap().pixels, vec![[1, 2, 3, 4]; 15]);
    // The same as .gltf with a base64 data-URI buffer (no padding).
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD_NO_PAD.encode(&b.bytes);
    doc["buffers"] = json!([{"byteLength": b.bytes.len(), "uri": format!("data:application/octet-stream;base64,{b64}")}]);
    let path = dir.path().join("d.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let d = imp(&path);
    assert_eq!(d.vertices, s.vertices);
    assert_eq!(d.images[0].decode().unwrap().pixels, vec![[1, 2, 3, 4]; 15]);
}

#[test]
fn auto_and_forced_up_axis() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Bin::default();
    // Flat in x–y (z extent 0.1): auto picks Z.
    let pos = b.f32s(&[0., 0., 0., 100., 0., 0.1, 0., 50., 0.], "VEC3");
    let doc = json!({"scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]});
    let path = b.write(dir.path(), doc);
    let s = imp(&path);
    assert_eq!(s.up, UpAxis::Z);
    let inf = info::analyze(&s);
    assert!((inf.planarity.unwrap() - 0.1 / 100.0).abs() < 1e-9);
    let forced = import(
        &path,
        &ImportOptions {
            up: Some(UpAxis::X),
            ..ImportOptions::default()
        },
    )
    .unwrap();
    assert_eq!(forced.up, UpAxis::X);
}

/// A PNG whose header is intact but whose pixel data is cut imports (header only) and fails at decode
/// time with an error naming the image.
#[test]
fn corrupt_pixel_data_fails_at_decode_naming_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let mut png = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(64, 64, |x, y| {
        image::Rgb([x as u8, y as u8, 7])
    }))
    .write_to(&mut png, image::ImageFormat::Png)
    .unwrap();
    let bytes = png.into_inner();
    let idat = bytes.windows(4).position(|w| w == b"IDAT").unwrap();
    std::fs::write(dir.path().join("cut.png"), &bytes[..idat + 40]).unwrap();
    let mut b = Bin::default();
    let pos = b.f32s(&TRI_POS, "VEC3");
    let uv = b.f32s(&TRI_UV, "VEC2");
    let doc = json!({
        "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}]}],
        "images": [{"uri": "cut.png", "name": "the cut one"}], "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    });
    let s = imp(&b.write(dir.path(), doc));
    assert_eq!(s.report.missing_images, 0);
    assert_eq!((s.images[0].width, s.images[0].height), (64, 64));
    let e = s.images[0].decode().unwrap_err();
    assert!(
        matches!(e, SceneError::ImageDecode { .. }) && e.to_string().contains("the cut one"),
        "{e}"
    );
}
