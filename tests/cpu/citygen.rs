//! `citygen` output is deterministic, the committed fixture `data/city` is exactly what the documented
//! command produces, and the glTF it writes parses with the counts `citygen.json` claims.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The arguments documented in data/README.md (without `--out`).
const FIXTURE_ARGS: &[&str] = &[
    "mixed",
    "--seed",
    "1",
    "--buildings",
    "24",
    "--facade-size",
    "256",
];

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city")
}

/// Runs citygen with `args` into a fresh directory under `tmp`.
fn run(tmp: &tempfile::TempDir, name: &str, args: &[&str]) -> PathBuf {
    let out = tmp.path().join(name);
    let status = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .args(args)
        .arg("--quiet")
        .arg("--out")
        .arg(&out)
        .status()
        .expect("spawn citygen");
    assert!(status.success(), "citygen {args:?} failed: {status}");
    out
}

/// Every file under `dir` (relative path → bytes).
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read_dir") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p
                    .strip_prefix(dir)
                    .expect("prefix")
                    .to_string_lossy()
                    .replace('\\', "/");
                out.insert(rel, std::fs::read(&p).expect("read"));
            }
        }
    }
    out
}

fn assert_same_tree(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "file lists differ"
    );
    for (k, v) in &ta {
        assert!(
            v == &tb[k],
            "{k} differs ({} vs {} bytes)",
            v.len(),
            tb[k].len()
        );
    }
}

#[test]
fn same_seed_gives_byte_identical_output() {
    let tmp = tempfile::tempdir().unwrap();
    for (i, args) in [
        &[
            "berlin",
            "--scale",
            "0.005",
            "--facade-size",
            "64",
            "--png",
            "fast",
            "--seed",
            "9",
        ][..],
        &[
            "chemnitz",
            "--scale",
            "0.01",
            "--facade-size",
            "128",
            "--png",
            "fast",
            "--seed",
            "9",
        ][..],
    ]
    .iter()
    .enumerate()
    {
        let a = run(&tmp, &format!("a{i}"), args);
        let b = run(&tmp, &format!("b{i}"), args);
        assert!(tree(&a).len() > 10, "{args:?} wrote too few files");
        assert_same_tree(&a, &b);
    }
}

#[test]
fn different_seed_differs() {
    let tmp = tempfile::tempdir().unwrap();
    let args = [
        "berlin",
        "--scale",
        "0.005",
        "--facade-size",
        "64",
        "--png",
        "fast",
    ];
    let a = tree(&run(&tmp, "s1", &[&args[..], &["--seed", "1"]].concat()));
    let b = tree(&run(&tmp, "s2", &[&args[..], &["--seed", "2"]].concat()));
    // Same building count → same file names, but geometry and every facade differ.
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    assert_ne!(a["scene.bin"], b["scene.bin"]);
    let facades: Vec<&String> = a
        .keys()
        .filter(|k| k.starts_with("textures/facade_"))
        .collect();
    assert_eq!(facades.len(), 22, "round(4300 · 0.005) = 22 facades");
    for f in facades {
        assert_ne!(a[f], b[f], "{f} identical across seeds");
    }
}

#[test]
fn committed_fixture_is_what_the_documented_command_produces() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/README.md"))
            .unwrap();
    let documented = format!("citygen -- {} --out data/city", FIXTURE_ARGS.join(" "));
    assert!(
        readme.contains(&documented),
        "data/README.md must contain `{documented}`"
    );
    let tmp = tempfile::tempdir().unwrap();
    let fresh = run(&tmp, "city", FIXTURE_ARGS);
    assert_same_tree(&fresh, &fixture_dir());
    let total: usize = tree(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data"))
        .values()
        .map(Vec::len)
        .sum();
    assert!(total < 5_000_000, "data/ is {total} bytes, budget 5 MB");
}

/// Triangles of `mesh` (sum of index counts / 3 over its primitives).
fn mesh_triangles(mesh: &gltf::Mesh) -> u64 {
    mesh.primitives()
        .map(|p| p.indices().map_or(0, |a| a.count() as u64) / 3)
        .sum()
}

/// Triangles after instancing: every node with a mesh, reached from the scene roots.
fn scene_triangles(doc: &gltf::Document) -> u64 {
    fn walk(n: gltf::Node) -> u64 {
        n.mesh().map_or(0, |m| mesh_triangles(&m)) + n.children().map(walk).sum::<u64>()
    }
    doc.default_scene().expect("scene").nodes().map(walk).sum()
}

/// Reads accessor `a` (float VECn, tightly packed) from `bin`.
fn read_floats(a: &gltf::Accessor, bin: &[u8]) -> Vec<f32> {
    let view = a.view().expect("view");
    let start = view.offset() + a.offset();
    let n = a.count() * a.dimensions().multiplicity();
    bin[start..start + 4 * n]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn fixture_gltf_parses_with_expected_counts() {
    let dir = fixture_dir();
    let gltf = gltf::Gltf::from_slice(&std::fs::read(dir.join("scene.gltf")).unwrap())
        .expect("valid glTF");
    let bin = std::fs::read(dir.join("scene.bin")).unwrap();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("citygen.json")).unwrap()).unwrap();
    let doc = &gltf.document;

    // Triangles after instancing and in meshes agree with citygen.json.
    assert_eq!(
        scene_triangles(doc),
        report["scene"]["triangles"].as_u64().unwrap()
    );
    assert_eq!(
        doc.meshes().map(|m| mesh_triangles(&m)).sum::<u64>(),
        report["scene"]["mesh_triangles"].as_u64().unwrap()
    );

    // Images: one file per image, all present, every image used by a texture.
    let files: BTreeSet<String> = std::fs::read_dir(dir.join("textures"))
        .unwrap()
        .map(|e| format!("textures/{}", e.unwrap().file_name().to_string_lossy()))
        .collect();
    let uris: BTreeSet<String> = doc
        .images()
        .map(|i| match i.source() {
            gltf::image::Source::Uri { uri, .. } => uri.to_string(),
            gltf::image::Source::View { .. } => panic!("embedded image"),
        })
        .collect();
    assert_eq!(files, uris);
    assert_eq!(
        uris.len() as u64,
        report["textures"]["images"].as_u64().unwrap()
    );
    let used: BTreeSet<usize> = doc
        .textures()
        .map(|t| t.source().unwrap().index())
        .collect();
    assert_eq!(used.len(), doc.images().count(), "unused images");

    // 24 labelled facades, one per block building, each its own image; one building is instanced twice.
    let facade_images: BTreeSet<usize> = doc
        .materials()
        .filter(|m| m.name().is_some_and(|n| n.starts_with("facade_")))
        .map(|m| {
            m.pbr_metallic_roughness()
                .base_color_texture()
                .expect("facade texture")
                .texture()
                .source()
                .expect("facade image")
                .index()
        })
        .collect();
    assert_eq!(facade_images.len(), 24);
    let building_nodes: Vec<gltf::Node> = doc
        .nodes()
        .filter(|n| n.name().is_some_and(|s| s.starts_with("building_")))
        .collect();
    assert_eq!(building_nodes.len(), 25);
    let twin = building_nodes
        .iter()
        .find(|n| n.name() == Some("building_00007_twin"))
        .expect("twin");
    let orig = building_nodes
        .iter()
        .find(|n| n.name() == Some("building_00007"))
        .expect("original");
    assert_eq!(twin.mesh().unwrap().index(), orig.mesh().unwrap().index());

    // Alpha: at least one MASK with cutoff 0.5 and one BLEND material; they match citygen.json.
    let mask = doc
        .materials()
        .filter(|m| m.alpha_mode() == gltf::material::AlphaMode::Mask)
        .collect::<Vec<_>>();
    let blend = doc
        .materials()
        .filter(|m| m.alpha_mode() == gltf::material::AlphaMode::Blend)
        .count();
    assert!(!mask.is_empty() && blend > 0);
    assert!(mask.iter().all(|m| m.alpha_cutoff() == Some(0.5)));
    assert_eq!(
        mask.len() as u64,
        report["counts"]["mask_materials"].as_u64().unwrap()
    );
    assert_eq!(
        blend as u64,
        report["counts"]["blend_materials"].as_u64().unwrap()
    );
    let untextured = doc
        .materials()
        .filter(|m| m.pbr_metallic_roughness().base_color_texture().is_none())
        .count();
    assert!(untextured >= 1);

    // All three wrap modes occur.
    use gltf::texture::WrappingMode::*;
    let wraps: BTreeSet<u32> = doc
        .samplers()
        .flat_map(|s| [s.wrap_s(), s.wrap_t()])
        .map(|w| w.as_gl_enum())
        .collect();
    for w in [Repeat, MirroredRepeat, ClampToEdge] {
        assert!(wraps.contains(&w.as_gl_enum()), "{w:?} missing");
    }

    // Encodings: JPEG files and PNGs of colour types grey (0), RGB (2), indexed (3) and RGBA (6).
    assert!(uris.iter().filter(|u| u.ends_with(".jpg")).count() >= 2);
    let png_types: BTreeSet<u8> = uris
        .iter()
        .filter(|u| u.ends_with(".png"))
        .map(|u| std::fs::read(dir.join(u)).unwrap()[25])
        .collect();
    assert_eq!(png_types, BTreeSet::from([0, 2, 3, 6]));

    // The district ground is repeated hundreds of times on single large triangles: |u| reaches 300.
    let ground = doc
        .meshes()
        .find(|m| m.name() == Some("chemnitz_ground"))
        .expect("ground");
    let prim = ground.primitives().next().unwrap();
    assert_eq!(mesh_triangles(&ground), 2);
    let uv = read_floats(&prim.get(&gltf::Semantic::TexCoords(0)).unwrap(), &bin);
    let umax = uv.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!((umax - 300.0).abs() < 0.01, "max |uv| {umax}");
}

#[test]
fn berlin_counts_follow_the_arguments() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = run(
        &tmp,
        "b",
        &[
            "berlin",
            "--buildings",
            "45",
            "--facade-size",
            "32",
            "--png",
            "fast",
        ],
    );
    let gltf = gltf::Gltf::from_slice(&std::fs::read(dir.join("scene.gltf")).unwrap()).unwrap();
    let doc = &gltf.document;
    // 45 buildings, twins of 7 and 47 → only 7 exists: 46 building nodes; 45 facades + 3 roofs + asphalt.
    let building_meshes: Vec<gltf::Mesh> = doc
        .meshes()
        .filter(|m| m.name().is_some_and(|n| n.starts_with("building_")))
        .collect();
    assert_eq!(building_meshes.len(), 45);
    for m in &building_meshes {
        let tris: Vec<usize> = m
            .primitives()
            .map(|p| p.indices().unwrap().count() / 3)
            .collect();
        assert_eq!(tris, [8, 4], "4 wall quads + a 4-triangle roof fan");
    }
    assert_eq!(
        doc.nodes()
            .filter(|n| n.name().is_some_and(|s| s.starts_with("building_")))
            .count(),
        46
    );
    assert_eq!(doc.images().count(), 45 + 3 + 1);
    // Every facade texture is square at the requested size.
    let png = std::fs::read(dir.join("textures/facade_00044.png")).unwrap();
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 32);
    assert_eq!(u32::from_be_bytes(png[20..24].try_into().unwrap()), 32);
}

/// Counts past what one run makes are refused before anything is written (`--textures 4000000000`
/// aborted on a 128 GB allocation, `--scale 1e30` ran out of memory; both left a half-made folder).
#[test]
fn absurd_counts_are_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    for (args, want) in [
        (
            &["chemnitz", "--scale", "0.002", "--textures", "4000000000"][..],
            "4000000000 pool textures (--textures, or --scale 0.002); at most 1000000",
        ),
        (
            &["berlin", "--scale", "1e30"][..],
            "--scale 1000000000000000000000000000000 gives 4294967295 buildings; at most 2000000",
        ),
    ] {
        let out = tmp.path().join("x");
        let o = Command::new(env!("CARGO_BIN_EXE_citygen"))
            .args(args)
            .arg("--quiet")
            .arg("--out")
            .arg(&out)
            .output()
            .expect("spawn citygen");
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && stderr.contains(want),
            "{args:?}: {stderr}"
        );
        assert!(!out.exists(), "{args:?} left {}", out.display());
    }
}
