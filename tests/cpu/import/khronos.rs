//! Import of the Khronos/assimp glTF 2.0 samples from Debian's `assimp-testmodels`
//! (`/usr/share/assimp/models/glTF2`). Missing samples make these tests FAIL, never pass silently.

use atlastree::scene::ImageData;
use atlastree::scene::{AlphaMode, ImportOptions, Scene, SceneError, UpAxis, Wrap, import, info};
use glam::{DVec2, DVec3};
use std::path::{Path, PathBuf};

const ROOT: &str = "/usr/share/assimp/models/glTF2";

/// The sample directory; panics (test failure) when the package is not installed.
fn root() -> PathBuf {
    let p = PathBuf::from(ROOT);
    assert!(
        p.is_dir(),
        "{ROOT} is missing: install the Khronos samples with `apt-get install assimp-testmodels`"
    );
    p
}

fn load(rel: &str) -> Result<Scene, SceneError> {
    import(&root().join(rel), &ImportOptions::default())
}

fn all_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            all_files(&p, out);
        } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
            out.push(p);
        }
    }
}

/// Every .gltf/.glb under the tree: no panic; the deliberately broken ones error or warn.
#[test]
fn every_sample_imports_or_errors_without_panic() {
    let mut files = Vec::new();
    all_files(&root(), &mut files);
    assert!(
        files.len() >= 40,
        "only {} glTF files found under {ROOT}",
        files.len()
    );
    let mut panics = Vec::new();
    let mut errors = Vec::new();
    for f in &files {
        match std::panic::catch_unwind(|| import(f, &ImportOptions::default())) {
            Err(_) => panics.push(f.clone()),
            Ok(Ok(s)) => {
                // Invariants of every successful import.
                for t in &s.triangles {
                    assert!(
                        t.v.iter().all(|&i| (i as usize) < s.vertices.len()),
                        "{}",
                        f.display()
                    );
                    assert!(t.material.idx() < s.materials.len(), "{}", f.display());
                }
                assert!(
                    s.vertices
                        .iter()
                        .all(|v| v.pos.is_finite() && v.uv.is_finite()),
                    "{}",
                    f.display()
                );
                assert!(
                    s.materials.iter().all(|m| m.image.idx() < s.images.len()),
                    "{}",
                    f.display()
                );
                println!(
                    "OK   {}: {} tris, {} mats, {} imgs, {} warnings",
                    f.display(),
                    s.triangles.len(),
                    s.materials.len(),
                    s.images.len(),
                    s.report.warnings_total
                );
            }
            Ok(Err(e)) => {
                println!("ERR  {e}");
                errors.push(f.strip_prefix(ROOT).unwrap().display().to_string());
            }
        }
    }
    assert!(panics.is_empty(), "panicked on {panics:?}");
    let expected_errors = [
        "BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf", // KHR_technique_webgl required
        "IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "IndexOutOfRange/IndexOutOfRange.gltf",
        "MissingBin/BoxTextured.gltf",
        "RecursiveNodes/RecursiveNodes.gltf",
        "SchemaFailures/sceneWrongType.gltf",
        "TestNoRootNode/NoScene.gltf", // "scene": 0 without scenes
        "TestNoRootNode/SceneWithoutNodes.gltf", // gltf-json requires scene.nodes
        "draco/2CylinderEngine.gltf",  // KHR_draco_mesh_compression required
        "wrongTypes/badArray.gltf",
        "wrongTypes/badExtension.gltf",
        "wrongTypes/badNumber.gltf",
        "wrongTypes/badObject.gltf",
        "wrongTypes/badString.gltf",
        "wrongTypes/badUint.gltf",
    ];
    assert_eq!(errors, expected_errors);
}

#[test]
fn box_textured_three_forms_agree() {
    let plain = load("BoxTextured-glTF/BoxTextured.gltf").unwrap();
    let embedded = load("BoxTextured-glTF-Embedded/BoxTextured.gltf").unwrap();
    let binary = load("BoxTextured-glTF-Binary/BoxTextured.glb").unwrap();
    for s in [&plain, &embedded, &binary] {
        assert_eq!(s.triangles.len(), 12);
        assert_eq!(s.vertices.len(), 24);
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.images.len(), 1);
        let img = &s.images[0];
        assert_eq!((img.width, img.height), (211, 211));
        assert_eq!(img.color, "Palette8");
        assert!(!img.has_alpha);
        let m = &s.materials[0];
        assert_eq!(m.tex_coord, 0);
        assert_eq!(m.alpha, AlphaMode::Opaque);
        assert_eq!(s.report.warnings_total, 0);
        assert_eq!(s.report.instances, 1);
        // The cube spans [-0.5, 0.5]^3; the TEXCOORD_0 accessor declares min [0, 0], max [6, 1].
        let (lo, hi) = s.bounds().unwrap();
        assert_eq!((lo, hi), (DVec3::splat(-0.5), DVec3::splat(0.5)));
        let mi = &info::analyze(s).materials[0];
        assert_eq!((mi.uv_min, mi.uv_max), (Some([0.0, 0.0]), Some([6.0, 1.0])));
    }
    // The plain form's sampler (edited by assimp) is wrapS 33648 MIRRORED_REPEAT, wrapT 33071
    // CLAMP_TO_EDGE; the other two keep 10497 REPEAT.
    assert_eq!(
        plain.materials[0].wrap,
        [Wrap::MirroredRepeat, Wrap::ClampToEdge]
    );
    assert_eq!(embedded.materials[0].wrap, [Wrap::Repeat, Wrap::Repeat]);
    assert_eq!(binary.materials[0].wrap, [Wrap::Repeat, Wrap::Repeat]);
    assert_eq!(plain.vertices, embedded.vertices);
    assert_eq!(plain.vertices, binary.vertices);
    assert_eq!(plain.triangles, binary.triangles);
    assert!(matches!(plain.images[0].data, ImageData::File(_)));
    assert!(matches!(embedded.images[0].data, ImageData::Bytes(_)));
    assert!(matches!(binary.images[0].data, ImageData::Bytes(_)));
    // The three decode to the same pixels.
    let d = [&plain, &embedded, &binary].map(|s| s.images[0].decode().unwrap());
    assert_eq!(d[0].pixels.len(), 211 * 211);
    assert_eq!(d[0].pixels, d[1].pixels);
    assert_eq!(d[0].pixels, d[2].pixels);
}

#[test]
fn box_texcoords_uses_set_0() {
    let s = load("BoxTexcoords-glTF/boxTexcoords.gltf").unwrap();
    assert_eq!(s.triangles.len(), 12);
    assert_eq!(s.materials[0].tex_coord, 0);
    let has = |uv: DVec2| s.vertices.iter().any(|v| v.uv == uv);
    // First elements of TEXCOORD_0 and TEXCOORD_1 (read from boxTexcoords.bin).
    assert!(has(DVec2::new(0.708984375, 0.177734375)));
    assert!(!has(DVec2::new(0.556640625, 0.296875)));
    assert_eq!(
        (
            s.images[0].width,
            s.images[0].height,
            s.images[0].color.as_str()
        ),
        (256, 256, "Rgba8")
    );
}

/// The vertex of material `name` at world position `pos` (tolerance 1e-9).
fn uv_at(s: &Scene, name: &str, pos: DVec3) -> DVec2 {
    let mid = s.materials.iter().position(|m| m.name == name).unwrap();
    let v = s
        .triangles
        .iter()
        .filter(|t| t.material.idx() == mid)
        .flat_map(|t| t.v)
        .map(|i| s.vertices[i as usize])
        .find(|v| (v.pos - pos).length() < 1e-9)
        .unwrap_or_else(|| panic!("no vertex of {name} at {pos}"));
    v.uv
}

#[test]
fn texture_transform_sample_is_baked() {
    let s = load("textureTransform/TextureTransformTest.gltf").unwrap();
    assert_eq!(s.triangles.len(), 24);
    assert_eq!(s.materials.len(), 9);
    let xf = s.materials.iter().filter(|m| m.texture_transform).count();
    assert_eq!(xf, 6);
    // Sampler 0 is CLAMP_TO_EDGE both ways (UV.png and Arrow.png textures).
    let m = s.materials.iter().find(|m| m.name == "Rotation").unwrap();
    assert_eq!(m.wrap, [Wrap::ClampToEdge, Wrap::ClampToEdge]);
    // Quad vertex 1: local (0.5, 0.5, 0), UV (1, 0). "Rotation" node at (-1.1, -0.55, 0), rotation π/8:
    // u' = cos r, v' = -sin r.
    let r = std::f64::consts::FRAC_PI_8; // 0.39269908169872414 in the file
    let uv = uv_at(&s, "Rotation", DVec3::new(-0.6, -0.05, 0.0));
    assert!(
        (uv - DVec2::new(r.cos(), -r.sin())).length() < 1e-12,
        "{uv}"
    );
    // "All": offset (-0.2, -0.1), rotation 0.3, scale 1.5; node at (1.1, -0.55, 0). Vertex 2: local
    // (0.5, -0.5, 0), UV (1, 1): u' = 1.5 cos + 1.5 sin - 0.2, v' = -1.5 sin + 1.5 cos - 0.1.
    let (sn, cs) = 0.3_f64.sin_cos();
    let uv = uv_at(&s, "All", DVec3::new(1.6, -1.05, 0.0));
    let want = DVec2::new(1.5 * cs + 1.5 * sn - 0.2, -1.5 * sn + 1.5 * cs - 0.1);
    assert!((uv - want).length() < 1e-12, "{uv} vs {want}");
    // "Offset U": UVs (0.5, 0.5) + offset (0.5, 0) at vertex 2 (local (0.5, -0.5)), node (-1.1, 0.55, 0).
    let uv = uv_at(&s, "Offset U", DVec3::new(-0.6, 0.05, 0.0));
    assert!((uv - DVec2::new(1.0, 0.5)).length() < 1e-12, "{uv}");
    // The untransformed marker keeps its UVs; auto up axis is Z (the quads lie in the x-y plane).
    assert!(
        !s.materials
            .iter()
            .find(|m| m.name == "Correct")
            .unwrap()
            .texture_transform
    );
    assert_eq!(s.up, UpAxis::Z);
}

#[test]
fn clear_coat_imports_and_reports_materials() {
    let s = load("ClearCoat-glTF/ClearCoatTest.gltf").unwrap();
    let info = info::analyze(&s);
    println!("{info}");
    // Counted by the gltf crate from the file (37116 triangles, 19 materials).
    let path = root().join("ClearCoat-glTF/ClearCoatTest.gltf");
    assert_eq!(
        info.triangles,
        crate::fixtures::gltf_count::triangles(&path)
    );
    assert_eq!(
        info.materials.len(),
        crate::fixtures::gltf_count::materials(&path)
    );
    assert_eq!((info.triangles, info.materials.len()), (37116, 19));
    // Material 18 (the labels) is emissive: emission is not drawn, one warning says so.
    assert_eq!(s.report.warnings_total, 1, "{:?}", s.report.warnings);
    assert!(
        s.report.warnings[0].contains("1 materials are emissive")
            && s.report.warnings[0].contains("first: material 18"),
        "{:?}",
        s.report.warnings
    );
    assert!(info.materials.iter().all(|m| m.triangles > 0));
    assert_eq!(
        (info.alpha.opaque, info.alpha.mask, info.alpha.blend),
        (18, 0, 1)
    );
    assert_eq!(info.instances, 27);
    // One textured material (PartialCoating_Alpha.png, BLEND); the others are solid colours (3 distinct).
    assert_eq!(info.image_kinds.get("file"), Some(&1));
    assert_eq!(info.image_kinds.get("solid"), Some(&3));
    let t = info.textures.iter().find(|t| t.kind == "file").unwrap();
    assert_eq!(
        (
            t.width,
            t.height,
            t.color.as_str(),
            t.has_alpha,
            t.triangles
        ),
        (256, 256, "Rgba8", true, 2060)
    );
    let m = info
        .materials
        .iter()
        .find(|m| m.name == "Partial_Coating")
        .unwrap();
    assert_eq!(
        (m.alpha, m.uv_bbox_span),
        (AlphaMode::Blend, Some([1.0, 1.0]))
    );
    assert_eq!(info.up, UpAxis::Z);
    let json = serde_json::to_string(&info).unwrap();
    assert!(json.contains("\"triangles\":37116"));
}

#[test]
fn box_with_infinites_skips_and_counts() {
    let s = load("BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb").unwrap();
    assert_eq!(s.report.skipped_triangles, 12);
    assert!(s.triangles.is_empty());
    assert!(
        s.report
            .warnings
            .iter()
            .any(|w| w.contains("NaN/Inf positions"))
    );
}

#[test]
fn incorrect_vertex_arrays_warns() {
    let s = load("IncorrectVertexArrays/Cube.gltf").unwrap();
    // Cube 12 + TruncatedCube 11 + IndexedCube 12 + TruncatedIndexedCube 11; 4 line meshes skipped.
    assert_eq!(s.triangles.len(), 46);
    assert_eq!(s.report.skipped_primitives, 4);
    assert_eq!(
        s.report
            .warnings
            .iter()
            .filter(|w| w.contains("not a multiple of 3"))
            .count(),
        2
    );
}

#[test]
fn broken_samples_give_specific_errors() {
    assert!(matches!(
        load("RecursiveNodes/RecursiveNodes.gltf"),
        Err(SceneError::RecursiveNodes { node: 0, .. })
    ));
    assert!(matches!(
        load("IndexOutOfRange/IndexOutOfRange.gltf"),
        Err(SceneError::IndexOutOfRange {
            index: 255,
            vertex_count: 24,
            ..
        })
    ));
    match load("MissingBin/BoxTextured.gltf") {
        Err(e @ SceneError::Buffer { buffer: 0, .. }) => {
            assert!(e.to_string().contains("BoxTextured0.bin"))
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        load("draco/2CylinderEngine.gltf"),
        Err(SceneError::UnsupportedExtension { ref extension, .. }) if extension == "KHR_draco_mesh_compression"
    ));
    assert!(matches!(
        load("wrongTypes/badNumber.gltf"),
        Err(SceneError::Parse { .. })
    ));
    let s = load("issue_3269/texcoord_crash.gltf").unwrap();
    assert_eq!(s.report.missing_texcoords, 1);
}

/// UV at world point `p` (in the x-y plane) by the affine map of one triangle of material `name`.
fn uv_affine(s: &Scene, name: &str, p: DVec2) -> DVec2 {
    let mid = s.materials.iter().position(|m| m.name == name).unwrap();
    let t = s
        .triangles
        .iter()
        .find(|t| t.material.idx() == mid)
        .unwrap();
    let [a, b, c] = s.tri_positions(t).map(|q| q.truncate());
    let [ua, ub, uc] = s.tri_uvs(t);
    let (e1, e2, d) = (b - a, c - a, p - a);
    let det = e1.perp_dot(e2);
    let (l1, l2) = (d.perp_dot(e2) / det, e1.perp_dot(d) / det);
    ua + (ub - ua) * l1 + (uc - ua) * l2
}

/// The sample's markers fix the rotation direction: the arrow tip of the unrotated texture is at UV
/// (0.5 + 0.27781…, 0.5 + 0.27781…) (the "Not Supported" marker); with the rotation baked, the
/// "Correct" marker's position must map onto that tip, and the "Error" marker's must not.
#[test]
fn texture_transform_rotation_direction_matches_sample_markers() {
    let s = load("textureTransform/TextureTransformTest.gltf").unwrap();
    let tip = DVec2::splat(0.5 + 0.2778174593052023);
    let parent = DVec2::new(-1.1, -0.55);
    let correct = parent + DVec2::new(-0.07904822439840126, -0.5162674857624154);
    let error = parent + DVec2::new(0.5162674857624154, 0.07904822439840126);
    let at_correct = uv_affine(&s, "Rotation", correct);
    assert!((at_correct - tip).length() < 1e-9, "{at_correct} vs {tip}");
    assert!((uv_affine(&s, "Rotation", error) - tip).length() > 0.1);
}

/// Truncations and byte corruptions of a GLB and of a .gltf (with its .bin) never panic.
#[test]
fn corrupted_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let glb = std::fs::read(root().join("BoxTextured-glTF-Binary/BoxTextured.glb")).unwrap();
    let gltf = std::fs::read(root().join("BoxTextured-glTF/BoxTextured.gltf")).unwrap();
    let bin = std::fs::read(root().join("BoxTextured-glTF/BoxTextured0.bin")).unwrap();
    std::fs::copy(
        root().join("BoxTextured-glTF/CesiumLogoFlat.png"),
        dir.path().join("CesiumLogoFlat.png"),
    )
    .unwrap();
    let mut cases: Vec<(&str, Vec<u8>, Vec<u8>)> = Vec::new();
    for cut in (0..glb.len()).step_by(37) {
        cases.push(("x.glb", glb[..cut].to_vec(), bin.clone()));
    }
    for (k, pos) in (0..glb.len()).step_by(11).enumerate() {
        let mut g = glb.clone();
        g[pos] ^= [0xff, 0x01, 0x80][k % 3];
        cases.push(("x.glb", g, bin.clone()));
    }
    for cut in (0..bin.len()).step_by(29) {
        cases.push(("x.gltf", gltf.clone(), bin[..cut].to_vec()));
    }
    for pos in (0..bin.len()).step_by(3) {
        let mut b = bin.clone();
        b[pos] = 0xff; // indices up to 0xffxx, NaN-pattern floats
        cases.push(("x.gltf", gltf.clone(), b));
    }
    let (mut ok, mut err) = (0, 0);
    for (name, file, bin) in &cases {
        let path = dir.path().join(name);
        std::fs::write(&path, file).unwrap();
        std::fs::write(dir.path().join("BoxTextured0.bin"), bin).unwrap();
        match std::panic::catch_unwind(|| import(&path, &ImportOptions::default())) {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(_)) => err += 1,
            Err(_) => panic!("panic on a corrupted {name} ({} bytes)", file.len()),
        }
    }
    println!("{} cases: {ok} imported, {err} errors", cases.len());
    assert!(ok > 0 && err > 0);
}
