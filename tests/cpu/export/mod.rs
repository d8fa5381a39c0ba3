//! `atlastree export 3dtiles` (issue 25) on `data/city` built with the demo's settings (two trees, depth 3,
//! repeat, mirror and clamp samplers, MASK and BLEND): the tileset mirrors the tree (one tile per node and
//! one original-texture tile per leaf, errors from min_distance, refine on the root, children's errors
//! ≤ parents'), every URI resolves, every content lies inside its box, and — the CPU twin of what a 3D Tiles
//! viewer samples — at points inside every triangle the UV a standard viewer computes (TEXCOORD_n,
//! KHR_texture_transform, the sampler's wrap) lands where `shaders/tree.wgsl` samples the same atlas.
//! Faults: an existing directory is refused and kept; a corrupt block fails the export and leaves nothing.

use atlastree::export::{ExportOptions, ExportSummary, export_3dtiles, geometric_error};
use atlastree::model::transform::{atlas_uv_at, cell_offset, rect_texel};
use atlastree::model::{AtlasForest, RectWrap};
use atlastree::preprocess::{NoProgress, build};
use atlastree::sim::tour::DemoTour;
use atlastree::store::TreeFile;
use glam::{DVec2, DVec3};
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod faults;

const NO_PROGRESS: &(dyn Fn(u64, u64) + Sync) = &|_, _| {};

/// data/city built with the demo's settings, once per test binary.
fn city() -> &'static (tempfile::TempDir, PathBuf) {
    static CITY: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    CITY.get_or_init(|| build_city(false))
}

/// data/city stood on z (its y-up `(x, y, z)` as the z-up `(x, −z, y)`, `up` Z), once per test binary.
fn z_up_city() -> &'static (tempfile::TempDir, PathBuf) {
    static CITY: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    CITY.get_or_init(|| build_city(true))
}

fn build_city(z_up: bool) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = atlastree::scene::import(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf"),
        &Default::default(),
    )
    .unwrap();
    if z_up {
        for v in &mut scene.vertices {
            v.pos = DVec3::new(v.pos.x, -v.pos.z, v.pos.y);
        }
        scene.up = atlastree::scene::UpAxis::Z;
    }
    let out = dir.path().join("city.atlastree");
    build(
        &scene,
        &DemoTour::DEFAULT.build_options(),
        &out,
        &NoProgress,
    )
    .unwrap();
    (dir, out)
}

fn export(naive: bool) -> (tempfile::TempDir, PathBuf, ExportSummary, TreeFile) {
    export_file(&city().1, naive)
}

fn export_file(path: &Path, naive: bool) -> (tempfile::TempDir, PathBuf, ExportSummary, TreeFile) {
    let file = TreeFile::open(path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tiles");
    let opts = ExportOptions {
        naive,
        ..ExportOptions::default()
    };
    let s = export_3dtiles(&file, &out, &opts, NO_PROGRESS).unwrap();
    (dir, out, s, file)
}

/// Every tile with its parent's geometricError and the accumulated transform's translation.
fn walk(tile: &Value, parent_error: f64, offset: DVec3, out: &mut Vec<(Value, f64, DVec3)>) {
    let mut offset = offset;
    if let Some(t) = tile["transform"].as_array() {
        let m: Vec<f64> = t.iter().map(|x| x.as_f64().unwrap()).collect();
        assert_eq!(m.len(), 16);
        // Pure translations only.
        assert_eq!(&m[..12], &[1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0.]);
        offset += DVec3::new(m[12], m[13], m[14]);
    }
    out.push((tile.clone(), parent_error, offset));
    let e = tile["geometricError"].as_f64().unwrap();
    for c in tile["children"].as_array().into_iter().flatten() {
        walk(c, e, offset, out);
    }
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

#[test]
fn the_tileset_mirrors_the_tree_and_every_uri_resolves() {
    let (_dir, out, summary, file) = export(false);
    let forest = file.to_forest();
    // The summary counts image files (embedded images are in the glTF bytes), in total and per level.
    let files: Vec<PathBuf> = (walkdir(&out).into_iter())
        .filter(|p| p.parent().unwrap().ends_with("img"))
        .collect();
    assert_eq!(summary.images, files.len());
    let on_disk: u64 = files
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(summary.image_bytes, on_disk);
    for (level, l) in &summary.levels {
        assert!(
            l.image_bytes <= on_disk && l.images <= files.len(),
            "level {level}"
        );
    }
    let ts = read_json(&out.join("tileset.json"));
    assert_eq!(ts["asset"]["version"], "1.1");
    assert_eq!(ts["root"]["refine"], "REPLACE");
    let mut tiles = Vec::new();
    walk(
        &ts["root"],
        ts["geometricError"].as_f64().unwrap(),
        DVec3::ZERO,
        &mut tiles,
    );
    let p = &forest.params;
    let mut seen = BTreeSet::new();
    for (tile, parent_error, _) in &tiles {
        let e = tile["geometricError"].as_f64().unwrap();
        assert!(
            e <= *parent_error,
            "child error {e} > parent's {parent_error}"
        );
        let Some(uri) = tile["content"]["uri"].as_str() else {
            continue;
        };
        let x = &tile["extras"]["atlastree"];
        let (t, n) = (
            x["tree"].as_u64().unwrap() as usize,
            x["node"].as_u64().unwrap() as usize,
        );
        let node = &forest.trees[t].nodes[n];
        let source = x["source"].as_str().unwrap();
        let want_uri = match source {
            "atlas" => {
                assert_eq!(
                    e,
                    geometric_error(node.min_distance, p.screen_width, p.fov_deg)
                );
                format!("t{t}/n{n}.gltf")
            }
            "original" => {
                assert!(node.is_leaf());
                assert_eq!(e, 0.0);
                format!("t{t}/n{n}-orig.gltf")
            }
            s => panic!("source {s}"),
        };
        assert_eq!(uri, want_uri);
        assert!(seen.insert((t, n, source.to_string())), "{uri} twice");
        // Every URI inside the content resolves, buffers at their stated length.
        let gltf_path = out.join(uri);
        let doc = read_json(&gltf_path);
        let base = gltf_path.parent().unwrap();
        for b in doc["buffers"].as_array().unwrap() {
            let len = std::fs::metadata(base.join(b["uri"].as_str().unwrap()))
                .unwrap()
                .len();
            assert_eq!(len, b["byteLength"].as_u64().unwrap(), "{uri}");
        }
        for i in doc["images"].as_array().unwrap() {
            let u = i["uri"].as_str().unwrap();
            assert!(
                u.starts_with("data:image/") || base.join(u).is_file(),
                "{uri}: {u}"
            );
        }
    }
    let nodes: usize = forest.trees.iter().map(|t| t.nodes.len()).sum();
    let leaves: usize = forest.trees.iter().map(|t| t.leaves.len()).sum();
    assert_eq!(seen.len(), nodes + leaves);
    assert_eq!(summary.tiles, nodes + leaves);
    assert!(
        forest.trees[0].nodes.iter().any(|n| n.level.0 >= 3),
        "a deep tree"
    );
    // The summary's byte count is what is on disk, its own report included.
    let on_disk: u64 = walkdir(&out)
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(on_disk, summary.total_bytes);
}

fn walkdir(d: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(d).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walkdir(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// The content of a tile as the viewer places it: glTF nodes (leaf buffers) with their translation.
struct Content {
    doc: gltf::Document,
    bins: Vec<Vec<u8>>,
    /// Leaf of each buffer (from its `geom/l{L}.bin` URI).
    buffer_leaf: Vec<usize>,
}

fn load(path: &Path) -> Content {
    let g = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).expect("valid glTF");
    let base = path.parent().unwrap();
    let mut bins = Vec::new();
    let mut buffer_leaf = Vec::new();
    for b in g.document.buffers() {
        let gltf::buffer::Source::Uri(uri) = b.source() else {
            panic!("external buffers only")
        };
        bins.push(std::fs::read(base.join(uri)).unwrap());
        let leaf = uri.trim_start_matches("geom/l").trim_end_matches(".bin");
        buffer_leaf.push(leaf.parse().unwrap());
    }
    Content {
        doc: g.document,
        bins,
        buffer_leaf,
    }
}

#[test]
fn every_content_lies_inside_its_box() {
    let (_dir, out, _, _) = export(false);
    contents_lie_inside_their_boxes(&out);
}

/// A z-up scene is exported standing on the tile frame's z, as the same scene y-up is (it was laid on
/// its side, its ground in the tile frame's xz plane: fault hunt, session 33): the same boxes, and
/// every content, turned by its leaf node's rotation, inside its box.
#[test]
fn a_z_up_scene_stands_on_the_tile_frames_z() {
    let (_dir, out, _, _) = export(false);
    let (_zdir, zout, _, _) = export_file(&z_up_city().1, false);
    contents_lie_inside_their_boxes(&zout);
    let boxes = |out: &Path| {
        let mut tiles = Vec::new();
        walk(
            &read_json(&out.join("tileset.json"))["root"],
            f64::INFINITY,
            DVec3::ZERO,
            &mut tiles,
        );
        tiles
            .iter()
            .map(|(t, _, offset)| {
                let (c, h) = box_of(t);
                (c + *offset, h)
            })
            .collect::<Vec<_>>()
    };
    // The same boxes (the plane's second axis runs the other way, so the quadtree's children may come
    // in another order).
    let (y, z) = (boxes(&out), boxes(&zout));
    assert_eq!(y.len(), z.len());
    for (yc, yh) in &y {
        let tol = 1e-6 * (1.0 + yc.abs().max_element() + yh.max_element());
        let same = |(zc, zh): &(DVec3, DVec3)| {
            (*yc - *zc).abs().max_element() <= tol && (*yh - *zh).abs().max_element() <= tol
        };
        assert!(
            z.iter().any(same),
            "y-up box {yc} ± {yh}: no z-up box alike"
        );
    }
    assert!(
        z[0] == y[0] || (z[0].0 - y[0].0).abs().max_element() < 1e-6,
        "root boxes differ"
    );
    // The city's ground spans x and y; its height is the least extent.
    let (_, h) = z[0];
    assert!(h.z < h.x && h.z < h.y, "root half extents {h}");
}

/// A tile's axis-aligned `box` bounding volume: its centre and half extents.
fn box_of(tile: &Value) -> (DVec3, DVec3) {
    let b: Vec<f64> = tile["boundingVolume"]["box"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    (DVec3::new(b[0], b[1], b[2]), DVec3::new(b[3], b[7], b[11]))
}

/// Every tile's content (each leaf node's positions turned and translated as its node says, then the
/// ancestors' transforms, in the z-up tile frame) lies inside the tile's box.
fn contents_lie_inside_their_boxes(out: &Path) {
    let ts = read_json(&out.join("tileset.json"));
    let mut tiles = Vec::new();
    walk(&ts["root"], f64::INFINITY, DVec3::ZERO, &mut tiles);
    for (tile, _, offset) in &tiles {
        let Some(uri) = tile["content"]["uri"].as_str() else {
            continue;
        };
        let (c, h) = box_of(tile);
        let content = load(&out.join(uri));
        for node in content.doc.nodes() {
            let (t, r, s) = node.transform().decomposed();
            assert_eq!(s, [1.0; 3]);
            let t = DVec3::from(t.map(f64::from));
            let r = glam::DQuat::from_array(r.map(f64::from));
            for prim in node.mesh().unwrap().primitives() {
                let pos = prim.get(&gltf::Semantic::Positions).unwrap();
                let reader = prim.reader(|buf| Some(&content.bins[buf.index()]));
                for p in reader.read_positions().unwrap() {
                    let y_up = r * DVec3::from(p.map(f64::from)) + t;
                    // glTF y-up → tile frame z-up, then the ancestors' transforms.
                    let z_up = DVec3::new(y_up.x, -y_up.z, y_up.y) + *offset;
                    let d = (z_up - (c + *offset)).abs() - h;
                    // Strictly inside: the boxes hold the f32 positions' rounding (it was 1e-3 here).
                    let tol = 1e-9 * (1.0 + offset.abs().max_element());
                    assert!(
                        d.max_element() <= tol,
                        "{uri}: {z_up} outside box {c} ± {h} ({})",
                        pos.count()
                    );
                }
            }
        }
    }
}

/// The sampler's wrap on one axis (glTF codes), as the viewer applies it.
fn wrap(u: f64, mode: gltf::texture::WrappingMode) -> f64 {
    use gltf::texture::WrappingMode::*;
    match mode {
        Repeat => u - u.floor(),
        MirroredRepeat => atlastree::model::transform::mirror(u),
        ClampToEdge => u.clamp(0.0, 1.0),
    }
}

#[test]
fn a_viewer_samples_every_triangle_where_the_tree_shader_does() {
    let (_dir, out, summary, file) = export(false);
    let forest: AtlasForest = file.to_forest();
    let size = f64::from(forest.params.atlas_size);
    let bary = [
        [1.0 / 3.0; 3],
        [0.7, 0.2, 0.1],
        [0.1, 0.7, 0.2],
        [0.2, 0.1, 0.7],
    ];
    let (mut samples, mut period_samples, mut averaged_samples) = (0usize, 0usize, 0usize);
    for t in summary.tile_list.iter().filter(|t| t.source == "atlas") {
        let tree = &forest.trees[t.tree];
        let node = &tree.nodes[t.node as usize];
        let content = load(&out.join(&t.uri));
        for gnode in content.doc.nodes() {
            for prim in gnode.mesh().unwrap().primitives() {
                let buffer = prim.indices().unwrap().view().unwrap().buffer().index();
                let l = content.buffer_leaf[buffer];
                let leaf = &tree.leaves[l];
                let leaf_node = &tree.nodes[leaf.node.0 as usize];
                let reader = prim.reader(|buf| Some(&content.bins[buf.index()]));
                let uv0: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
                let uv1: Option<Vec<[f32; 2]>> =
                    reader.read_tex_coords(1).map(|r| r.into_f32().collect());
                let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
                let info = prim
                    .material()
                    .pbr_metallic_roughness()
                    .base_color_texture()
                    .unwrap();
                let sampler = info.texture().sampler();
                let (offset, scale) = info
                    .texture_transform()
                    .map_or(([0.0, 0.0], [1.0, 1.0]), |x| (x.offset(), x.scale()));
                let (ox, oy, d) = cell_offset(leaf_node.cell, leaf_node.level, node.level);
                let image_uri = info.texture().source().unwrap().name().unwrap().to_string();
                if image_uri.ends_with("-avg.png") {
                    // Averaged rects: every vertex at the centre of its rect's texel, read nearest.
                    let rect_base: usize = tree.leaves[..l].iter().map(|x| x.rects.len()).sum();
                    let total: usize = tree.leaves.iter().map(|x| x.rects.len()).sum();
                    let (cols, rows) = atlastree::export::average_grid(total as u64);
                    let (cols, rows) = (cols as usize, rows as usize);
                    // The tile's image is the band of its rows: the transform takes every texel centre
                    // into it.
                    let band = |v: f64| v * f64::from(scale[1]) + f64::from(offset[1]);
                    assert_eq!(
                        sampler.mag_filter(),
                        Some(gltf::texture::MagFilter::Nearest)
                    );
                    // Each triangle reads one texel centre, of a rect of this leaf; the run holds every
                    // stored triangle of each rect it names.
                    let mut per_rect = std::collections::BTreeMap::<usize, usize>::new();
                    for tri in idx.chunks_exact(3) {
                        let got = [0, 1, 2].map(|k| uv1.as_ref().unwrap()[tri[k] as usize]);
                        assert!(
                            got.iter().all(|g| *g == got[0]),
                            "{}: not one texel per triangle",
                            t.uri
                        );
                        let x = (f64::from(got[0][0]) * cols as f64 - 0.5).round() as usize;
                        let y = (f64::from(got[0][1]) * rows as f64 - 0.5).round() as usize;
                        let want = [
                            (x as f64 + 0.5) / cols as f64,
                            (y as f64 + 0.5) / rows as f64,
                        ];
                        assert!(
                            (f64::from(got[0][0]) - want[0]).abs() < 1e-6
                                && (f64::from(got[0][1]) - want[1]).abs() < 1e-6
                        );
                        let g = y * cols + x;
                        let vb = band(f64::from(got[0][1]));
                        assert!(
                            vb > 0.0 && vb < 1.0,
                            "{}: texel row {y} outside the tile's band ({vb})",
                            t.uri
                        );
                        assert!(
                            g >= rect_base && g < rect_base + leaf.rects.len(),
                            "{}: texel of rect {g} outside leaf {l}",
                            t.uri
                        );
                        *per_rect.entry(g - rect_base).or_default() += 1;
                        averaged_samples += 1;
                    }
                    let range =
                        leaf.first_index as usize..(leaf.first_index + leaf.index_count) as usize;
                    for (r, n) in per_rect {
                        let stored = tree.indices[range.clone()]
                            .chunks_exact(3)
                            .filter(|t| tree.vertices[t[0] as usize].rect as usize == r)
                            .count();
                        assert_eq!(n, stored, "{}: rect {r} of leaf {l}", t.uri);
                    }
                    continue;
                }
                // A period image (`img/n{N}-l{L}-r{R}.*`) draws rect R's triangles through their own
                // vertices, in stored order: the shader side takes the stored (true) UVs.
                let period_rect: Option<usize> = image_uri.contains("-l").then(|| {
                    image_uri
                        .rsplit_once("-r")
                        .unwrap()
                        .1
                        .split('.')
                        .next()
                        .unwrap()
                        .parse()
                        .unwrap()
                });
                let stored: Vec<[[f32; 2]; 3]> = match period_rect {
                    Some(r) => {
                        let range = leaf.first_index as usize
                            ..(leaf.first_index + leaf.index_count) as usize;
                        tree.indices[range]
                            .chunks_exact(3)
                            .filter(|t| tree.vertices[t[0] as usize].rect as usize == r)
                            .map(|t| [0, 1, 2].map(|k| tree.vertices[t[k] as usize].orig_uv))
                            .collect()
                    }
                    None => Vec::new(),
                };
                if period_rect.is_some() {
                    assert_eq!(stored.len() * 3, idx.len(), "{}: {image_uri}", t.uri);
                }
                for (ti, tri) in idx.chunks_exact(3).enumerate() {
                    let (rect, truth) = match period_rect {
                        Some(r) => (&leaf.rects[r], stored[ti]),
                        None => {
                            let v = tree.vertices[leaf.first_vertex as usize + tri[0] as usize];
                            (
                                &leaf.rects[v.rect as usize],
                                [0, 1, 2].map(|k| uv0[tri[k] as usize]),
                            )
                        }
                    };
                    for w in &bary {
                        let at = |uv: &[[f32; 2]]| {
                            (0..3).fold(DVec2::ZERO, |acc, k| {
                                acc + DVec2::from(uv[tri[k] as usize].map(f64::from)) * w[k]
                            })
                        };
                        let orig = (0..3).fold(DVec2::ZERO, |acc, k| {
                            acc + DVec2::from(truth[k].map(f64::from)) * w[k]
                        });
                        // What tree.wgsl samples (margin 0: inside the rect, no footprint).
                        let texel = rect_texel(orig, rect, DVec2::ZERO);
                        let want =
                            atlas_uv_at(texel / size, leaf_node.cell, leaf_node.level, node.level);
                        let got = if info.tex_coord() == 1 {
                            let a = at(uv1.as_ref().unwrap());
                            DVec2::new(
                                a.x * f64::from(scale[0]) + f64::from(offset[0]),
                                a.y * f64::from(scale[1]) + f64::from(offset[1]),
                            )
                        } else {
                            // A period image: the rect's inner rectangle at this level, wrapped by the sampler.
                            period_samples += 1;
                            let seen = at(&uv0);
                            let u = seen.x * f64::from(scale[0]) + f64::from(offset[0]);
                            let v = seen.y * f64::from(scale[1]) + f64::from(offset[1]);
                            let p =
                                DVec2::new(wrap(u, sampler.wrap_s()), wrap(v, sampler.wrap_t()));
                            let inner =
                                DVec2::new(f64::from(rect.inner[0]), f64::from(rect.inner[1]));
                            let extent =
                                DVec2::new(f64::from(rect.inner[2]), f64::from(rect.inner[3]));
                            atlas_uv_at(
                                (inner + p * extent) / size,
                                leaf_node.cell,
                                leaf_node.level,
                                node.level,
                            )
                        };
                        // f32 UVs: a few 1e-6 of the atlas; seams: a sample on a period's edge may be
                        // reached from either side (u and u ± 1 sample the same texel under REPEAT).
                        let err = (got - want).abs();
                        let s = (-(f64::from(d))).exp2();
                        let period = DVec2::new(f64::from(rect.inner[2]), f64::from(rect.inner[3]))
                            * s
                            / size;
                        let on_seam = (err - period).abs().max_element() < 1e-4;
                        assert!(
                            err.max_element() < 1e-4 || on_seam,
                            "{}: leaf {l} rect {:?} wrap {:?} uv {orig}: viewer {got}, shader {want} (node level {}, cell offset {ox},{oy})",
                            t.uri,
                            rect.inner,
                            rect.wrap,
                            node.level.0
                        );
                        samples += 1;
                    }
                }
            }
        }
    }
    assert!(samples > 1000, "{samples} samples");
    assert!(
        period_samples > 100,
        "{period_samples} samples of period images"
    );
    // Tiles with averaged rects (periods under 2 texels at their level) were checked too.
    assert!(
        summary.averaged_rects > 0 && averaged_samples > 0,
        "no averaged rect"
    );
    // The fixture has every wrap mode, so every period sampler kind was exercised above.
    let modes: std::collections::HashSet<RectWrap> = forest
        .trees
        .iter()
        .flat_map(|t| {
            t.leaves
                .iter()
                .flat_map(|l| l.rects.iter().flat_map(|r| r.wrap))
        })
        .collect();
    assert!(
        modes.contains(&RectWrap::Repeat)
            && modes.contains(&RectWrap::Mirror)
            && modes.contains(&RectWrap::Clamp)
    );
}

#[test]
fn the_naive_export_draws_original_textures_on_every_tile() {
    let (_dir, out, summary, _) = export(true);
    assert!(summary.naive);
    assert_eq!(
        summary.period_rects, 0,
        "a naive export writes no period image"
    );
    assert!(summary.rects > 0);
    for t in &summary.tile_list {
        for i in &t.images {
            assert!(i.uri.starts_with("img/o"), "{}: {}", t.uri, i.uri);
        }
    }
    let atlases = walkdir(&out)
        .into_iter()
        .filter(|p| {
            p.file_name().unwrap().to_string_lossy().starts_with('n')
                && p.parent().unwrap().ends_with("img")
        })
        .count();
    assert_eq!(atlases, 0);
}

/// The same scene at the origin and at UTM-size coordinates exports the same contents byte for byte (every
/// `.gltf` and `.bin`: positions relative to the leaf, leaves placed relative to the tree origin), the
/// same boxes relative to the tree origin (within 1e-6 m), and tree transforms that differ by exactly the
/// shift, in the z-up tile frame.
#[test]
fn utm_coordinates_keep_full_precision() {
    use atlastree::preprocess::{BuildOptions, DMin};
    let scene = atlastree::scene::synthetic::small_city(4, 64);
    let shift = DVec3::new(4.5e6, 120.0, 5.5e6);
    let mut far = scene.clone();
    for v in &mut far.vertices {
        v.pos += shift;
    }
    let dir = tempfile::tempdir().unwrap();
    let opts = BuildOptions {
        d_min: DMin::Ratio(20.0),
        atlas_size: 128,
        border: 8,
        max_file_bytes: 1 << 30,
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    let mut outs = Vec::new();
    for (name, s) in [("near", &scene), ("far", &far)] {
        let f = dir.path().join(format!("{name}.atlastree"));
        build(s, &opts, &f, &NoProgress).unwrap();
        let out = dir.path().join(name);
        export_3dtiles(
            &TreeFile::open(&f).unwrap(),
            &out,
            &ExportOptions::default(),
            NO_PROGRESS,
        )
        .unwrap();
        outs.push(out);
    }
    let mut files: Vec<PathBuf> = walkdir(&outs[0])
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "gltf" || e == "bin"))
        .collect();
    files.sort();
    assert!(files.len() > 10, "{} contents", files.len());
    for a in &files {
        let b = outs[1].join(a.strip_prefix(&outs[0]).unwrap());
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(&b).unwrap(),
            "{} differs at UTM coordinates",
            b.display()
        );
    }
    let (ta, tb) = (
        read_json(&outs[0].join("tileset.json")),
        read_json(&outs[1].join("tileset.json")),
    );
    let (mut la, mut lb) = (Vec::new(), Vec::new());
    walk(&ta["root"], f64::INFINITY, DVec3::ZERO, &mut la);
    walk(&tb["root"], f64::INFINITY, DVec3::ZERO, &mut lb);
    assert_eq!(la.len(), lb.len());
    for ((a, _, oa), (b, _, ob)) in la.iter().zip(&lb) {
        assert_eq!(a["content"], b["content"]);
        assert_eq!(a["geometricError"], b["geometricError"]);
        let d = *ob - *oa;
        assert_eq!(
            d,
            DVec3::new(shift.x, -shift.z, shift.y),
            "tree transforms differ by the shift"
        );
        for (x, y) in a["boundingVolume"]["box"]
            .as_array()
            .unwrap()
            .iter()
            .zip(b["boundingVolume"]["box"].as_array().unwrap())
        {
            assert!(
                (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() < 1e-6,
                "{x} vs {y}"
            );
        }
    }
}

/// Roots that refine farther than 10,000 km (a huge d_min): the tileset's own error and the empty root
/// over both trees are never below a tree root's, so clients refine into them.
#[test]
fn a_root_refined_from_beyond_ten_thousand_km_keeps_errors_monotone() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::built::city_scene();
    let opts = atlastree::preprocess::BuildOptions {
        d_min: atlastree::preprocess::DMin::Metres(2e7),
        ..Default::default()
    };
    let path = dir.path().join("far.atlastree");
    build(scene, &opts, &path, &NoProgress).unwrap();
    let file = TreeFile::open(&path).unwrap();
    let out = dir.path().join("tiles");
    export_3dtiles(&file, &out, &ExportOptions::default(), NO_PROGRESS).unwrap();
    let ts = read_json(&out.join("tileset.json"));
    let top = ts["geometricError"].as_f64().unwrap();
    let p = &file.to_forest().params;
    assert!(
        top > geometric_error(1e7, p.screen_width, p.fov_deg),
        "{top}"
    );
    let mut tiles = Vec::new();
    walk(&ts["root"], top, DVec3::ZERO, &mut tiles);
    assert!(tiles.len() > 2, "both trees and their tiles");
    for (tile, parent_error, _) in &tiles {
        let e = tile["geometricError"].as_f64().unwrap();
        assert!(
            e <= *parent_error,
            "child error {e} > parent's {parent_error}"
        );
    }
}
