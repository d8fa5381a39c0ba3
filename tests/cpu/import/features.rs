//! What the import draws of the glTF features atlastree supports in part, and the one counted warning for
//! each it does not draw (README, "Bad input and faults"): vertex colours, NEAREST, emission, skins; morph
//! targets at their default weights; OPAQUE, MASK and shared images; a file without a `scene` index.

use super::city::{city_json, import_city};
use serde_json::{Value, json};

/// What the glTF asks for that is not drawn (vertex colours, NEAREST filters, a MASK cutoff below 0) is
/// one counted warning per feature naming the first place, not per instance; the geometry is unchanged.
#[test]
fn undrawn_features_are_one_counted_warning_each() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    let plain = import_city(dir.path(), &doc).1.unwrap();
    assert_eq!(
        plain.report.warnings_total, 0,
        "{:?}",
        plain.report.warnings
    );
    // COLOR_0 on two primitives (the NORMAL accessor has the vec3 float shape COLOR_0 allows).
    for m in [0, 3] {
        let attrs = &mut doc["meshes"][m]["primitives"][0]["attributes"];
        attrs["COLOR_0"] = attrs["NORMAL"].clone();
    }
    doc["samplers"][1]["magFilter"] = json!(9728);
    doc["samplers"][2]["magFilter"] = json!(9728);
    // A NEAREST min filter alone is no warning (drawn trilinear it differs little): 3 warnings, not 4.
    doc["samplers"][3]["minFilter"] = json!(9984);
    doc["materials"][4]["alphaMode"] = json!("MASK");
    doc["materials"][4]["alphaCutoff"] = json!(-1.0);
    let (path, r) = import_city(dir.path(), &doc);
    let s = r.unwrap();
    let w = &s.report.warnings;
    assert_eq!(s.report.warnings_total, 3, "{w:?}");
    let file = path.display().to_string();
    assert!(
        w[0].starts_with(&file) && w[0].contains("2 primitives carry vertex colours (COLOR_0)"),
        "{w:?}"
    );
    assert!(w[0].contains("first: mesh 0 primitive 0"), "{w:?}");
    assert!(
        w[1].contains("2 samplers ask for NEAREST magnification") && w[1].contains("sampler 1"),
        "{w:?}"
    );
    assert!(
        w[2].contains("material 4") && w[2].contains("alphaCutoff -1"),
        "{w:?}"
    );
    assert_eq!(s.triangles.len(), plain.triangles.len());
}

/// An integer TEXCOORD that is not normalized is glTF only with KHR_mesh_quantization: without it declared
/// the import reads the integers as they are, with one counted warning naming the first attribute; with
/// it declared, no warning.
#[test]
fn integer_uvs_without_the_quantization_extension_are_a_counted_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    let uv = doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]
        .as_u64()
        .unwrap() as usize;
    doc["accessors"][uv]["componentType"] = json!(5123);
    for key in ["min", "max"] {
        doc["accessors"][uv].as_object_mut().unwrap().remove(key);
    }
    let s = import_city(dir.path(), &doc).1.unwrap();
    let w = &s.report.warnings;
    assert_eq!(s.report.warnings_total, 1, "{w:?}");
    assert!(
        w[0].contains("KHR_mesh_quantization")
            && w[0].contains(&format!(
                "first: mesh 0 primitive 0 TEXCOORD_0 (accessor {uv}, U16)"
            )),
        "{w:?}"
    );
    doc["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let s = import_city(dir.path(), &doc).1.unwrap();
    assert_eq!(s.report.warnings_total, 0, "{:?}", s.report.warnings);
}

/// glTF 2.0 §3.9.4: an OPAQUE material's alpha is ignored, its factor's too. A factor alpha of 0 kept
/// premultiplied the atlas texels (and an untextured material's solid colour) to black: the tree drew a
/// textured quad flat grey. MASK keeps its factor's alpha.
#[test]
fn an_opaque_materials_factor_alpha_is_ignored() {
    use atlastree::scene::ImageData;
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    let pbr = "pbrMetallicRoughness";
    doc["materials"][0][pbr]["baseColorFactor"] = json!([1.0, 0.5, 1.0, 0.0]);
    doc["materials"][1][pbr]["baseColorFactor"] = json!([1.0, 0.0, 0.0, 0.0]);
    let roof_1 = doc["materials"][1][pbr].as_object_mut().unwrap();
    roof_1.remove("baseColorTexture");
    doc["materials"][2][pbr]["baseColorFactor"] = json!([1.0, 1.0, 1.0, 0.25]);
    doc["materials"][2]["alphaMode"] = json!("MASK");
    let s = import_city(dir.path(), &doc).1.unwrap();
    let by_name = |name: &str| s.materials.iter().find(|m| m.name == name).unwrap();
    assert_eq!(by_name("roof_0").base_color_factor, [1.0, 0.5, 1.0, 1.0]);
    let solid = &s.images[by_name("roof_1").image.idx()];
    assert!(
        matches!(solid.data, ImageData::Solid([255, 0, 0, 255])),
        "{solid:?}"
    );
    assert_eq!(by_name("roof_2").base_color_factor[3], 0.25);
}

/// glTF 2.0's schema bounds baseColorFactor to [0, 1]. Beyond it the atlas (the factor applied before
/// filtering, stored in 8 bits) and the originals (applied after filtering) drew different colours
/// without a word; now it is clamped, with one counted warning naming the first such material.
#[test]
fn a_base_colour_factor_outside_0_1_is_clamped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    let pbr = "pbrMetallicRoughness";
    doc["materials"][2][pbr]["baseColorFactor"] = json!([2.0, -1.0, 0.5, 1.0]);
    doc["materials"][4][pbr]["baseColorFactor"] = json!([1.0, 1.0, 1.0, 1.5]);
    doc["materials"][4]["alphaMode"] = json!("BLEND");
    // A specular-glossiness diffuseFactor has the same range.
    let sg =
        json!({"KHR_materials_pbrSpecularGlossiness": {"diffuseFactor": [1.0, 1.0, 3.0, 1.0]}});
    doc["materials"][5]["extensions"] = sg;
    doc["extensionsUsed"] = json!(["KHR_materials_pbrSpecularGlossiness"]);
    let s = import_city(dir.path(), &doc).1.unwrap();
    let w = &s.report.warnings;
    assert_eq!(s.report.warnings_total, 1, "{w:?}");
    assert!(
        w[0].contains(
            "3 materials have a baseColorFactor (or diffuseFactor) outside glTF's range [0, 1], drawn \
             clamped into it (first: material 2)"
        ),
        "{w:?}"
    );
    let name = |i: usize| doc["materials"][i]["name"].as_str().unwrap().to_string();
    let by_name = |n: String| s.materials.iter().find(|m| m.name == n).unwrap();
    assert_eq!(by_name(name(2)).base_color_factor, [1.0, 0.0, 0.5, 1.0]);
    assert_eq!(by_name(name(4)).base_color_factor, [1.0; 4]);
}

/// Emission is not drawn: one counted warning naming the first emissive material (an emissive texture
/// with the default factor [0, 0, 0] emits nothing and is not counted).
#[test]
fn emissive_materials_are_one_counted_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    doc["materials"][3]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    doc["materials"][5]["emissiveTexture"] = json!({"index": 0});
    doc["materials"][5]["emissiveFactor"] = json!([0.0, 0.5, 0.0]);
    doc["materials"][6]["emissiveTexture"] = json!({"index": 1});
    let s = import_city(dir.path(), &doc).1.unwrap();
    let w = &s.report.warnings;
    assert_eq!(s.report.warnings_total, 1, "{w:?}");
    assert!(
        w[0].contains("2 materials are emissive") && w[0].contains("first: material 3"),
        "{w:?}"
    );
    // The material the warning names is found by that number: each scene material keeps its glTF
    // index, which scene-info lists (it listed only the scene's own first-use numbers; fault hunt,
    // session 38).
    let named: Vec<_> = (s.materials.iter())
        .filter(|m| m.gltf_material == Some(3))
        .collect();
    let expected = doc["materials"][3]["name"].as_str().map(str::to_string);
    assert!(!named.is_empty(), "{:?}", s.materials);
    assert!(
        named
            .iter()
            .all(|m| expected.as_ref().is_none_or(|n| *n == m.name)),
        "{named:?}"
    );
    let info = atlastree::scene::info::analyze(&s);
    assert!(info.to_string().contains("(glTF material 3)"), "{info}");
}

/// Without a `scene` index the import draws `scenes[0]` (as three.js and Blender), warning when there
/// are others; it drew every parentless node, so a second scene's nodes were drawn over the first's.
#[test]
fn without_a_scene_index_scenes_0_is_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let plain = import_city(dir.path(), &city_json()).1.unwrap();
    let mut doc = city_json();
    let nodes = doc["nodes"].as_array().unwrap().len();
    let mesh = (doc["nodes"].as_array().unwrap().iter())
        .find_map(|n| n.get("mesh").cloned())
        .unwrap();
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"mesh": mesh, "translation": [500.0, 0.0, 0.0]}));
    doc["scenes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"nodes": [nodes]}));
    doc.as_object_mut().unwrap().remove("scene");
    let (path, r) = import_city(dir.path(), &doc);
    let s = r.unwrap();
    assert_eq!(s.triangles.len(), plain.triangles.len());
    assert_eq!(
        s.report.warnings,
        [format!(
            "{}: no `scene` index among 2 scenes: drawing scenes[0] only",
            path.display()
        )]
    );
    doc["scene"] = json!(1);
    let one = import_city(dir.path(), &doc).1.unwrap();
    assert!(one.triangles.len() < plain.triangles.len());
    assert_eq!(one.report.warnings_total, 0);
}

/// A MASK cutoff ≤ 0 lets every texel pass (glTF 2.0 §3.9.4: alpha ≥ cutoff is drawn opaque, in its own
/// colour): the material is imported OPAQUE. As MASK its alpha-0 texels were premultiplied and bled over,
/// so they showed a neighbour's colour instead of their own.
#[test]
fn a_mask_cutoff_of_zero_is_opaque() {
    use atlastree::scene::AlphaMode;
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    doc["materials"][0]["alphaMode"] = json!("MASK");
    doc["materials"][0]["alphaCutoff"] = json!(0.0);
    doc["materials"][1]["alphaMode"] = json!("MASK");
    doc["materials"][1]["alphaCutoff"] = json!(0.25);
    let s = import_city(dir.path(), &doc).1.unwrap();
    let by_name = |name: &str| s.materials.iter().find(|m| m.name == name).unwrap();
    assert_eq!(by_name("roof_0").alpha, AlphaMode::Opaque);
    assert_eq!(by_name("roof_1").alpha, AlphaMode::Mask { cutoff: 0.25 });
    assert_eq!(s.report.warnings_total, 0, "{:?}", s.report.warnings);
}

/// An image drawn by an OPAQUE and a MASK material is two images of the scene, both naming the one glTF
/// image (read once): the OPAQUE material's is decoded with its alpha dropped, the MASK material's
/// premultiplied and bled. One image for both gave the OPAQUE material's alpha-0 texels the bleed's colour.
#[test]
fn an_image_drawn_by_opaque_and_mask_materials_is_two_images() {
    let dir = tempfile::tempdir().unwrap();
    let plain = import_city(dir.path(), &city_json()).1.unwrap();
    let mut doc = city_json();
    let pbr = "pbrMetallicRoughness";
    doc["materials"][1][pbr]["baseColorTexture"] = json!({"index": 0});
    doc["materials"][2][pbr]["baseColorTexture"] = json!({"index": 0});
    doc["materials"][2]["alphaMode"] = json!("MASK");
    let s = import_city(dir.path(), &doc).1.unwrap();
    let image = |name: &str| s.materials.iter().find(|m| m.name == name).unwrap().image;
    // roof_0 and roof_1 (OPAQUE) share one image, roof_2 (MASK) has its own of the same glTF image.
    assert_eq!(image("roof_0"), image("roof_1"));
    assert_ne!(image("roof_0"), image("roof_2"));
    let (a, b) = (
        &s.images[image("roof_0").idx()],
        &s.images[image("roof_2").idx()],
    );
    assert_eq!((a.gltf_image, b.gltf_image), (Some(0), Some(0)));
    assert_eq!((&a.name, a.width, a.height), (&b.name, b.width, b.height));
    // glTF images 1 and 2 are no longer drawn; texture 0's image is drawn twice.
    assert_eq!(s.images.len(), plain.images.len() - 1);
    // scene-info names the second as the first's image again.
    let info = atlastree::scene::info::analyze(&s);
    let (first, second) = (image("roof_0").0, image("roof_2").0);
    let same_as: Vec<Option<u32>> = info.textures.iter().map(|t| t.same_as).collect();
    assert_eq!(same_as[second.max(first) as usize], Some(second.min(first)));
    assert_eq!(same_as.iter().flatten().count(), 1, "{same_as:?}");
    assert!(
        info.to_string()
            .contains(&format!("the image of #{} again", second.min(first)))
    );
    assert_eq!(s.report.warnings_total, 0, "{:?}", s.report.warnings);
}

/// Morph targets are drawn in the pose without animation (glTF 2.0 §3.7.2.2): the base positions plus
/// each target's POSITION deltas times the node's weights, else the mesh's. They were ignored silently.
#[test]
fn morph_targets_are_drawn_at_their_default_weights() {
    let dir = tempfile::tempdir().unwrap();
    // The heights of the ground's (mesh 0, material asphalt) triangle corners.
    let ground = |doc: &Value| -> Vec<f64> {
        let s = import_city(dir.path(), doc).1.unwrap();
        assert_eq!(s.report.warnings_total, 0, "{:?}", s.report.warnings);
        let asphalt = s
            .materials
            .iter()
            .position(|m| m.name == "asphalt")
            .unwrap();
        (s.triangles.iter())
            .filter(|t| t.material.idx() == asphalt)
            .flat_map(|t| t.v)
            .map(|v| s.vertices[v as usize].pos.y)
            .collect()
    };
    let mut doc = city_json();
    let flat = ground(&doc);
    assert!(
        flat.len() == 6 && flat.iter().all(|&y| y == 0.0),
        "{flat:?}"
    );
    // A target moving every vertex by its NORMAL, (0, 1, 0), weighted 30 by the mesh, then 0 and 2.5 by the
    // node, which overrides the mesh's weights.
    let normal = doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"].clone();
    doc["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": normal}]);
    doc["meshes"][0]["weights"] = json!([30.0]);
    assert_eq!(ground(&doc), vec![30.0; 6]);
    assert_eq!(doc["nodes"][2]["mesh"], json!(0));
    doc["nodes"][2]["weights"] = json!([0.0]);
    assert_eq!(ground(&doc), vec![0.0; 6]);
    doc["nodes"][2]["weights"] = json!([2.5]);
    assert_eq!(ground(&doc), vec![2.5; 6]);
    // A target of another length is an error naming it.
    doc["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": 4}]);
    let e = import_city(dir.path(), &doc).1.err().unwrap().to_string();
    assert!(e.contains("morph target 0 POSITION has"), "{e}");
}

/// A morph target's `TEXCOORD_0` deltas are added by the same weights as its positions (glTF 2.0
/// §3.7.2.2 allows them; gltf-json does not read them), before the texture transform: they were ignored
/// silently, so a target that mirrored a texture drew it unmirrored (fault hunt, session 35).
#[test]
fn morph_targets_move_uvs_by_their_weights() {
    let dir = tempfile::tempdir().unwrap();
    // The UVs of the ground's (mesh 0, material asphalt) triangle corners.
    let ground_uvs = |doc: &Value| -> Vec<[f64; 2]> {
        let s = import_city(dir.path(), doc).1.unwrap();
        assert_eq!(s.report.warnings_total, 0, "{:?}", s.report.warnings);
        let asphalt = (s.materials.iter())
            .position(|m| m.name == "asphalt")
            .unwrap();
        (s.triangles.iter())
            .filter(|t| t.material.idx() == asphalt)
            .flat_map(|t| t.v)
            .map(|v| s.vertices[v as usize].uv.to_array())
            .collect()
    };
    let mut doc = city_json();
    let base = ground_uvs(&doc);
    assert!(base.iter().any(|uv| *uv != [0.0, 0.0]), "{base:?}");
    assert_eq!(doc["materials"][3]["name"], json!("asphalt"));
    // A texture transform, applied to the morphed UVs: uv · (2, 4) + (0.25, 0.5), exact in binary.
    doc["materials"][3]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
        json!({"KHR_texture_transform": {"offset": [0.25, 0.5], "scale": [2.0, 4.0]}});
    let transform = |[u, v]: [f64; 2]| [u * 2.0 + 0.25, v * 4.0 + 0.5];
    let expect = |k: f64| -> Vec<[f64; 2]> {
        base.iter()
            .map(|&[u, v]| transform([k * u, k * v]))
            .collect()
    };
    assert_eq!(ground_uvs(&doc), expect(1.0));
    let prim = &mut doc["meshes"][0]["primitives"][0];
    let uv = prim["attributes"]["TEXCOORD_0"].clone();
    assert_eq!(uv, json!(2));
    // Target 0 moves nothing but the UVs, by the base UVs themselves; target 1, of weight 0, names an
    // accessor of 16 elements (the primitive has 4): a target of weight 0 is not read.
    prim["targets"] = json!([{"TEXCOORD_0": uv}, {"TEXCOORD_0": 6}]);
    doc["meshes"][0]["weights"] = json!([-2.0, 0.0]);
    assert_eq!(ground_uvs(&doc), expect(-1.0));
    // The node's weights override the mesh's.
    doc["nodes"][2]["weights"] = json!([0.5, 0.0]);
    assert_eq!(ground_uvs(&doc), expect(1.5));
    // A target of another length with a weight is an error naming it.
    doc["nodes"][2]["weights"] = json!([0.5, 1.0]);
    let e = import_city(dir.path(), &doc).1.err().unwrap().to_string();
    assert!(e.contains("morph target 1 TEXCOORD_0 has"), "{e}");
    // `"targets": null` is no targets, as gltf-json reads it.
    doc["meshes"][0]["primitives"][0]["targets"] = Value::Null;
    doc["nodes"][2].as_object_mut().unwrap().remove("weights");
    doc["meshes"][0].as_object_mut().unwrap().remove("weights");
    assert_eq!(ground_uvs(&doc), expect(1.0));
}

/// A skinned mesh is one counted warning naming the first node: skins are not applied.
#[test]
fn skinned_meshes_are_one_counted_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = city_json();
    doc["skins"] = json!([{"joints": [0]}]);
    doc["nodes"][2]["skin"] = json!(0);
    let s = import_city(dir.path(), &doc).1.unwrap();
    let w = &s.report.warnings;
    assert_eq!(s.report.warnings_total, 1, "{w:?}");
    assert!(
        w[0].contains("1 node draws a skinned mesh") && w[0].contains("first: node 2"),
        "{w:?}"
    );
}
