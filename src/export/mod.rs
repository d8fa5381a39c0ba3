//! Export of a paging file as a 3D Tiles 1.1 tileset (issue 25), so CesiumJS, 3DTilesRendererJS and the
//! other 3D Tiles clients draw the atlas tree. Design and measurements: docs/3dtiles.md.
//!
//! ```text
//! TreeFile ──to_forest──▶ per tree: leaves ──geometry──▶ t{T}/geom/l{L}.bin   (once per leaf)
//!                                   originals ──images──▶ t{T}/img/o{B}-{S}.*  (once per tree)
//!                                   nodes ──images + gltf_doc──▶ t{T}/n{N}.gltf (+ atlas, period images)
//!                                   leaves ──gltf_doc──▶ t{T}/n{N}-orig.gltf
//!          ──tileset──▶ tileset.json (explicit tiles, REPLACE) + atlastree-export.json (summary)
//! ```
//!
//! One tile per node, drawn with its atlas (paper §4: the atlas stands for its subtree), and below each
//! leaf one tile with the original textures (geometricError 0), as [`crate::select`] draws them. Every
//! tile's content references the `.bin` of each leaf it draws: geometry is stored once however deep the
//! tree, the level's atlas reached through `KHR_texture_transform` (the exact transform of
//! [`crate::model::transform::atlas_uv_at`]). Rects whose triangles cross a wrap seam get their own small
//! image per tile (one period at the tile's resolution) with the sampler's wrap mode ([`geometry`]).
//! The directory appears complete or not at all: everything is written to a sibling temp directory that
//! is renamed at the end.

mod geometry;
mod gltf_doc;
mod images;
mod tileset;

pub use geometry::GeometryError;
pub use images::{ImageCodec, JPEG_QUALITY, gpu_bytes};
pub use tileset::{SCREEN_SPACE_ERROR, geometric_error, refine_distance};

use crate::model::{AtlasForest, AtlasTree, RectWrap, TreeKind};
use crate::store::{StoreError, TreeFile};
use geometry::{GroupKey, LeafMesh};
use glam::DVec3;
use gltf_doc::{CLAMP_TO_EDGE, GltfDoc, MIRRORED_REPEAT, MaterialSpec, REPEAT};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// What to export.
#[derive(Clone, Debug, Default)]
pub struct ExportOptions {
    /// Replace an existing, non-empty output directory.
    pub force: bool,
    /// The comparison export of tilers without texture LOD: every tile drawn with the original textures
    /// (no atlases written).
    pub naive: bool,
}

/// Why an export failed; nothing is left at the output path then.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("{}: exists and is not empty (pass --force to replace it)", dir.display())]
    Exists { dir: PathBuf },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("encoding {}: {source}", path.display())]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
    #[error("reading blocks: {0}")]
    Store(#[from] StoreError),
    #[error("tree {tree}: {source}")]
    Geometry { tree: usize, source: GeometryError },
}

/// One tile of the export.
#[derive(Clone, Debug, Serialize)]
pub struct TileSummary {
    pub tree: usize,
    pub node: u32,
    pub level: u8,
    /// `atlas` or `original`.
    pub source: &'static str,
    pub uri: String,
    pub min_distance: f64,
    pub geometric_error: f64,
    /// Scene-frame (y-up) bounds of the node's triangles, world units.
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    /// The images its content draws (shared ones listed by every tile that draws them).
    pub images: Vec<ImageSummary>,
    /// Primitives of its content (draw calls a viewer issues for it).
    pub draw_calls: usize,
    /// Leaves whose geometry it draws.
    pub leaves: usize,
    /// Bytes of its `.gltf` JSON.
    pub gltf_bytes: u64,
}

/// One image file.
#[derive(Clone, Debug, Serialize)]
pub struct ImageSummary {
    pub uri: String,
    pub width: u32,
    pub height: u32,
    /// File bytes.
    pub bytes: u64,
    /// What a viewer's GPU holds for it (RGBA8 with mips, [`gpu_bytes`]).
    pub gpu_bytes: u64,
}

/// Per level of the tree (leaf originals counted as level `depth + 1` of their leaf's level).
#[derive(Clone, Debug, Default, Serialize)]
pub struct LevelSummary {
    pub tiles: usize,
    pub images: usize,
    pub image_bytes: u64,
    pub gltf_bytes: u64,
    pub draw_calls: usize,
}

/// What an export wrote (`atlastree-export.json`).
#[derive(Clone, Debug, Serialize)]
pub struct ExportSummary {
    pub source: String,
    pub naive: bool,
    pub screen_width: u32,
    pub fov_x_deg: f64,
    pub texel_ratio: f64,
    pub tiles: usize,
    pub trees: usize,
    /// Bytes of everything written, and by kind.
    pub total_bytes: u64,
    pub geometry_bytes: u64,
    /// Of `geometry_bytes`: the second index list per leaf (by original texture).
    pub original_index_bytes: u64,
    pub image_bytes: u64,
    pub gltf_bytes: u64,
    pub tileset_json_bytes: u64,
    /// Unique image files.
    pub images: usize,
    /// Rects drawn with their own period image (their triangles cross a wrap seam), and all rects.
    pub period_rects: usize,
    pub rects: usize,
    pub paging_file_bytes: u64,
    /// Keyed by level ("0", "1", …; `"orig"` for the original-texture tiles).
    pub levels: BTreeMap<String, LevelSummary>,
    pub tile_list: Vec<TileSummary>,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ExportError + '_ {
    move |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<u64, ExportError> {
    std::fs::write(path, bytes).map_err(io(path))?;
    Ok(bytes.len() as u64)
}

/// Progress of an export: `(files done, files in all)`, called from worker threads.
pub type ExportProgress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// Exports `file` into the directory `out` (see the module doc). On error nothing is left at `out` (an existing directory is untouched unless replaced at the
/// very end with `force`).
pub fn export_3dtiles(
    file: &TreeFile,
    out: &Path,
    opts: &ExportOptions,
    progress: ExportProgress<'_>,
) -> Result<ExportSummary, ExportError> {
    let non_empty = std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_some());
    if non_empty && !opts.force {
        return Err(ExportError::Exists {
            dir: out.to_path_buf(),
        });
    }
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "tileset".into());
    let temp = crate::util::parent_dir(out).join(format!(".{name}.partial-{}", std::process::id()));
    if temp.exists() {
        std::fs::remove_dir_all(&temp).map_err(io(&temp))?;
    }
    std::fs::create_dir_all(&temp).map_err(io(&temp))?;
    let result = write_tileset(file, &temp, opts, progress);
    let summary = match result {
        Ok(s) => s,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&temp);
            return Err(e);
        }
    };
    if out.exists() {
        std::fs::remove_dir_all(out).map_err(io(out))?;
    }
    std::fs::rename(&temp, out).map_err(io(out))?;
    Ok(summary)
}

/// Per tree: what the tiles of its nodes need.
struct TreeCtx<'a> {
    index: usize,
    tree: &'a AtlasTree,
    dir: PathBuf,
    origin: DVec3,
    meshes: Vec<LeafMesh>,
    /// Leaf range (in tree order) of each node's subtree.
    leaf_ranges: Vec<(usize, usize)>,
    /// Original images by (block, slot).
    originals: HashMap<(u32, u32), ImageSummary>,
    codec: ImageCodec,
}

fn write_tileset(
    file: &TreeFile,
    dir: &Path,
    opts: &ExportOptions,
    progress: ExportProgress<'_>,
) -> Result<ExportSummary, ExportError> {
    let forest = file.to_forest();
    let params = forest.params.clone();
    let mut summary = ExportSummary {
        source: file.path().display().to_string(),
        naive: opts.naive,
        screen_width: params.screen_width,
        fov_x_deg: params.fov_deg,
        texel_ratio: params.texel_ratio,
        tiles: 0,
        trees: forest.trees.len(),
        total_bytes: 0,
        geometry_bytes: 0,
        original_index_bytes: 0,
        image_bytes: 0,
        gltf_bytes: 0,
        tileset_json_bytes: 0,
        images: 0,
        period_rects: 0,
        rects: 0,
        paging_file_bytes: file.file_len(),
        levels: BTreeMap::new(),
        tile_list: Vec::new(),
    };
    let total: u64 = forest
        .trees
        .iter()
        .map(|t| (t.nodes.len() + 2 * t.leaves.len()) as u64)
        .sum();
    progress(0, total);
    let done = std::sync::atomic::AtomicU64::new(0);
    let tick = || {
        progress(
            done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
            total,
        )
    };
    let mut roots = Vec::new();
    for (t, tree) in forest.trees.iter().enumerate() {
        let ctx = prepare_tree(file, &forest, t, dir, &mut summary, &tick)?;
        let tiles = node_tiles(file, &forest, &ctx, opts, &tick)?;
        let orig_tiles = original_tiles(&forest, &ctx, &tick)?;
        roots.push(tree_tileset(&forest, &ctx, tiles, orig_tiles, &mut summary));
        let _ = tree;
    }
    // The top of the tileset: one tree's root, or an empty root over both trees that always refines.
    let far = geometric_error(1e7, params.screen_width, params.fov_deg);
    let root = if roots.len() == 1 {
        roots.pop().map(|(tile, _)| tile).unwrap_or_default()
    } else {
        let bounds = tileset::union(roots.iter().map(|r| r.1));
        let (lo, hi) = bounds.unwrap_or((DVec3::ZERO, DVec3::ZERO));
        json!({
            "boundingVolume": { "box": tileset::tile_box(lo, hi, DVec3::ZERO) },
            "geometricError": far,
            "refine": "REPLACE",
            "children": roots.into_iter().map(|r| r.0).collect::<Vec<_>>(),
        })
    };
    let mut root = root;
    root["refine"] = json!("REPLACE");
    let doc = json!({
        "asset": {
            "version": "1.1",
            "generator": concat!("atlastree ", env!("CARGO_PKG_VERSION")),
            "extras": { "atlastree": { "screen_width": params.screen_width, "fov_x_deg": params.fov_deg,
                "texel_ratio": params.texel_ratio, "naive": opts.naive } },
        },
        "geometricError": far,
        "root": root,
    });
    let text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    summary.tileset_json_bytes = write_file(&dir.join("tileset.json"), text.as_bytes())?;
    summary.tiles = summary.tile_list.len();
    summary.levels = level_summaries(&summary.tile_list);
    summary.images = count_images(&summary.tile_list);
    summary.total_bytes = summary.geometry_bytes
        + summary.image_bytes
        + summary.gltf_bytes
        + summary.tileset_json_bytes;
    let report = serde_json::to_string_pretty(&summary).unwrap_or_default();
    write_file(&dir.join("atlastree-export.json"), report.as_bytes())?;
    Ok(summary)
}

/// Tiles, unique images and their bytes, glTF bytes and draw calls per level (`"orig"`: the original
/// tiles below the leaves).
fn level_summaries(tiles: &[TileSummary]) -> BTreeMap<String, LevelSummary> {
    let mut levels: BTreeMap<String, (LevelSummary, Vec<&ImageSummary>)> = BTreeMap::new();
    for t in tiles {
        let key = if t.source == "original" {
            "orig".to_string()
        } else {
            format!("{:02}", t.level)
        };
        let (e, imgs) = levels.entry(key).or_default();
        e.tiles += 1;
        e.gltf_bytes += t.gltf_bytes;
        e.draw_calls += t.draw_calls;
        imgs.extend(&t.images);
    }
    levels
        .into_iter()
        .map(|(k, (mut e, mut imgs))| {
            imgs.sort_unstable_by(|a, b| a.uri.cmp(&b.uri));
            imgs.dedup_by(|a, b| a.uri == b.uri);
            e.images = imgs.len();
            e.image_bytes = imgs.iter().map(|i| i.bytes).sum();
            (k, e)
        })
        .collect()
}

fn count_images(tiles: &[TileSummary]) -> usize {
    let mut uris: Vec<&str> = tiles
        .iter()
        .flat_map(|t| t.images.iter().map(|i| i.uri.as_str()))
        .collect();
    uris.sort_unstable();
    uris.dedup();
    uris.len()
}

/// Leaf buffers and original images of tree `t`.
fn prepare_tree<'a>(
    file: &TreeFile,
    forest: &'a AtlasForest,
    t: usize,
    dir: &Path,
    summary: &mut ExportSummary,
    tick: &(dyn Fn() + Sync),
) -> Result<TreeCtx<'a>, ExportError> {
    let tree = &forest.trees[t];
    let tdir = dir.join(format!("t{t}"));
    for sub in ["geom", "img"] {
        let d = tdir.join(sub);
        std::fs::create_dir_all(&d).map_err(io(&d))?;
    }
    let size = forest.params.atlas_size;
    let meshes: Vec<LeafMesh> = (0..tree.leaves.len())
        .into_par_iter()
        .map(|l| {
            let mut m = geometry::leaf_mesh(tree, l, &forest.materials, size)
                .map_err(|source| ExportError::Geometry { tree: t, source })?;
            let path = tdir.join(format!("geom/l{l}.bin"));
            write_file(&path, &std::mem::take(&mut m.bin))?;
            tick();
            Ok(m)
        })
        .collect::<Result<_, ExportError>>()?;
    for m in &meshes {
        summary.geometry_bytes += m.bin_len;
        summary.original_index_bytes += m
            .original_groups
            .iter()
            .map(|g| u64::from(g.count) * u64::from(m.index_size))
            .sum::<u64>();
        summary.period_rects += m.period_rects.len();
    }
    summary.rects += tree.leaves.iter().map(|l| l.rects.len()).sum::<usize>();
    // Every (block, slot) once, with its byte offset in the block (chains back to back in slot order).
    let mut slots: Vec<(u32, u32, [u32; 2])> = tree
        .leaves
        .iter()
        .flat_map(|l| l.originals.iter().map(|o| (o.block.0, o.slot, o.extent)))
        .collect();
    slots.sort_unstable();
    slots.dedup_by_key(|x| (x.0, x.1));
    let mut offsets = Vec::with_capacity(slots.len());
    let (mut block, mut off) = (u32::MAX, 0u64);
    for &(b, slot, [w, h]) in &slots {
        if b != block {
            (block, off) = (b, 0);
        }
        offsets.push((b, slot, [w, h], off));
        off += tree.format.chain_bytes_rect(w, h);
    }
    let codec = ImageCodec::for_alpha(tree.kind == TreeKind::Alpha);
    let originals = offsets
        .par_iter()
        .map(|&(b, slot, ext, off)| {
            let img = images::original_level0(file, crate::ids::BlockId(b), tree.format, ext, off)?;
            let uri = format!("img/o{b}-{slot}.{}", codec.extension());
            let image = encode_image(&tdir, &uri, &img, codec)?;
            Ok(((b, slot), image))
        })
        .collect::<Result<HashMap<_, _>, ExportError>>()?;
    summary.image_bytes += originals.values().map(|i| i.bytes).sum::<u64>();
    let root = &tree.nodes[0];
    Ok(TreeCtx {
        index: t,
        tree,
        dir: tdir,
        origin: (root.bounds_min + root.bounds_max) * 0.5,
        meshes,
        leaf_ranges: leaf_ranges(tree),
        originals,
        codec,
    })
}

fn encode_image(
    dir: &Path,
    uri: &str,
    img: &image::RgbaImage,
    codec: ImageCodec,
) -> Result<ImageSummary, ExportError> {
    let path = dir.join(uri);
    let bytes = codec.encode(img).map_err(|source| ExportError::Image {
        path: path.clone(),
        source,
    })?;
    let n = write_file(&path, &bytes)?;
    Ok(ImageSummary {
        uri: uri.to_string(),
        width: img.width(),
        height: img.height(),
        bytes: n,
        gpu_bytes: gpu_bytes(img.width(), img.height()),
    })
}

/// The leaf range (tree order) of every node's subtree: parents precede children (pre-order), so one
/// backward pass takes each node's range as the hull of its children's.
fn leaf_ranges(tree: &AtlasTree) -> Vec<(usize, usize)> {
    let mut r = vec![(usize::MAX, 0usize); tree.nodes.len()];
    for i in (0..tree.nodes.len()).rev() {
        let n = &tree.nodes[i];
        if let Some(l) = n.leaf {
            r[i] = (l.0 as usize, l.0 as usize + 1);
        }
        for c in n.children.iter().flatten() {
            let (lo, hi) = r[c.0 as usize];
            r[i] = (r[i].0.min(lo), r[i].1.max(hi));
        }
        if r[i].0 == usize::MAX {
            r[i] = (0, 0);
        }
    }
    r
}

/// The glTF wrap code a rect axis gets in its period image.
fn period_wrap(w: RectWrap) -> u32 {
    match w {
        RectWrap::Repeat => REPEAT,
        RectWrap::Mirror => MIRRORED_REPEAT,
        RectWrap::Linear | RectWrap::Clamp => CLAMP_TO_EDGE,
    }
}

/// The leaf's translation in its tree's frame (scene frame, relative to the tree origin).
fn leaf_translation(ctx: &TreeCtx<'_>, leaf: usize) -> [f32; 3] {
    let d = ctx.tree.leaves[leaf].origin - ctx.origin;
    [d.x as f32, d.y as f32, d.z as f32]
}

/// The node tiles of a tree: `(content uri, summary)` per node.
fn node_tiles(
    file: &TreeFile,
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    opts: &ExportOptions,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<TileSummary>, ExportError> {
    (0..ctx.tree.nodes.len())
        .into_par_iter()
        .map(|n| {
            let tile = if opts.naive {
                let (lo, hi) = ctx.leaf_ranges[n];
                originals_tile(forest, ctx, n, lo..hi, "atlas", format!("n{n}.gltf"))?
            } else {
                atlas_tile(file, forest, ctx, n)?
            };
            tick();
            Ok(tile)
        })
        .collect()
}

fn atlas_tile(
    file: &TreeFile,
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    n: usize,
) -> Result<TileSummary, ExportError> {
    let tree = ctx.tree;
    let node = &tree.nodes[n];
    let size = forest.params.atlas_size;
    let atlas = images::atlas_level0(file, node.atlas_block, tree.format, size)?;
    let atlas_uri = format!("img/n{n}.{}", ctx.codec.extension());
    let mut images = vec![encode_image(&ctx.dir, &atlas_uri, &atlas, ctx.codec)?];
    let mut doc = GltfDoc::default();
    let atlas_tex = doc.texture(&atlas_uri, [CLAMP_TO_EDGE, CLAMP_TO_EDGE]);
    let (lo, hi) = ctx.leaf_ranges[n];
    for l in lo..hi {
        let leaf = &tree.leaves[l];
        let mesh = &ctx.meshes[l];
        let leaf_node = &tree.nodes[leaf.node.0 as usize];
        let (ox, oy, d) =
            crate::model::transform::cell_offset(leaf_node.cell, leaf_node.level, node.level);
        let s = (-(f64::from(d))).exp2();
        let transform = (d > 0).then_some(([f64::from(ox) * s, f64::from(oy) * s], [s, s]));
        let uri = format!("geom/l{l}.bin");
        let mut prims = Vec::new();
        for g in &mesh.atlas_groups {
            let material = match g.key {
                GroupKey::Atlas { alpha, cutoff } => doc.material(MaterialSpec {
                    texture: atlas_tex,
                    tex_coord: 1,
                    transform,
                    factor: [1.0; 4],
                    alpha,
                    cutoff: f32::from_bits(cutoff),
                }),
                GroupKey::Period { rect } => {
                    let r = &leaf.rects[rect as usize];
                    let img = images::crop_scaled(&atlas, r.inner, (ox, oy, d));
                    let puri = format!("img/n{n}-l{l}-r{rect}.{}", ctx.codec.extension());
                    images.push(encode_image(&ctx.dir, &puri, &img, ctx.codec)?);
                    let tex = doc.texture(&puri, [period_wrap(r.wrap[0]), period_wrap(r.wrap[1])]);
                    let span = |k: usize| {
                        let s = r.uv_max[k] - r.uv_min[k];
                        if s > 0.0 { s } else { 1.0 }
                    };
                    let scale = [1.0 / span(0), 1.0 / span(1)];
                    let offset = [-r.uv_min[0] * scale[0], -r.uv_min[1] * scale[1]];
                    let m = forest.materials.get(r.material.0 as usize);
                    let (alpha, cutoff) = m.map(geometry::alpha_key).unwrap_or((0, 0));
                    doc.material(MaterialSpec {
                        texture: tex,
                        tex_coord: 0,
                        transform: Some((offset, scale)),
                        factor: [1.0; 4],
                        alpha,
                        cutoff: f32::from_bits(cutoff),
                    })
                }
                GroupKey::Original { .. } => continue,
            };
            prims.push((g, material, matches!(g.key, GroupKey::Atlas { .. })));
        }
        doc.leaf_node(l, mesh, &uri, leaf_translation(ctx, l), &prims);
    }
    finish_tile(ctx, n, "atlas", format!("n{n}.gltf"), doc, images, hi - lo)
}

/// A tile drawing leaves `leaves` with their original textures.
fn originals_tile(
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    n: usize,
    leaves: std::ops::Range<usize>,
    source: &'static str,
    name: String,
) -> Result<TileSummary, ExportError> {
    let tree = ctx.tree;
    let mut doc = GltfDoc::default();
    let mut images: Vec<ImageSummary> = Vec::new();
    let count = leaves.len();
    for l in leaves {
        let leaf = &tree.leaves[l];
        let mesh = &ctx.meshes[l];
        let mut prims = Vec::new();
        for g in &mesh.original_groups {
            let GroupKey::Original { original } = g.key else {
                continue;
            };
            let o = &leaf.originals[original as usize];
            let Some(img) = ctx.originals.get(&(o.block.0, o.slot)) else {
                continue;
            };
            if !images.iter().any(|i| i.uri == img.uri) {
                images.push(img.clone());
            }
            let Some(m) = forest.materials.get(o.material.0 as usize) else {
                continue;
            };
            let wrap = [
                gltf_doc::wrap_code(m.wrap[0]),
                gltf_doc::wrap_code(m.wrap[1]),
            ];
            let tex = doc.texture(&img.uri, wrap);
            let (alpha, cutoff) = geometry::alpha_key(m);
            let material = doc.material(MaterialSpec {
                texture: tex,
                tex_coord: 0,
                transform: None,
                factor: m.base_color_factor,
                alpha,
                cutoff: f32::from_bits(cutoff),
            });
            prims.push((g, material, false));
        }
        doc.leaf_node(
            l,
            mesh,
            &format!("geom/l{l}.bin"),
            leaf_translation(ctx, l),
            &prims,
        );
    }
    finish_tile(ctx, n, source, name, doc, images, count)
}

fn finish_tile(
    ctx: &TreeCtx<'_>,
    n: usize,
    source: &'static str,
    name: String,
    doc: GltfDoc,
    images: Vec<ImageSummary>,
    leaves: usize,
) -> Result<TileSummary, ExportError> {
    let node = &ctx.tree.nodes[n];
    let draw_calls = doc.primitives;
    let text = doc.finish();
    let gltf_bytes = write_file(&ctx.dir.join(&name), text.as_bytes())?;
    Ok(TileSummary {
        tree: ctx.index,
        node: n as u32,
        level: node.level.0,
        source,
        uri: format!("t{}/{name}", ctx.index),
        min_distance: node.min_distance,
        geometric_error: 0.0,
        bounds_min: node.bounds_min.to_array(),
        bounds_max: node.bounds_max.to_array(),
        images,
        draw_calls,
        leaves,
        gltf_bytes,
    })
}

/// The original-texture tile below each leaf, in leaf order.
fn original_tiles(
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<TileSummary>, ExportError> {
    (0..ctx.tree.leaves.len())
        .into_par_iter()
        .map(|l| {
            let n = ctx.tree.leaves[l].node.0 as usize;
            let t = originals_tile(
                forest,
                ctx,
                n,
                l..l + 1,
                "original",
                format!("n{n}-orig.gltf"),
            )?;
            tick();
            Ok(t)
        })
        .collect()
}

/// The tree's tiles as a tileset subtree (its root carries the translation to the tree origin), and the
/// tree's scene-frame bounds. Adds the tiles to `summary`.
fn tree_tileset(
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    mut tiles: Vec<TileSummary>,
    mut orig: Vec<TileSummary>,
    summary: &mut ExportSummary,
) -> (serde_json::Value, (DVec3, DVec3)) {
    let p = &forest.params;
    let g = |m: f64| geometric_error(m, p.screen_width, p.fov_deg);
    for t in &mut tiles {
        t.geometric_error = g(t.min_distance);
    }
    let tile_json = |t: &TileSummary, children: Vec<serde_json::Value>| {
        let lo = DVec3::from_array(t.bounds_min);
        let hi = DVec3::from_array(t.bounds_max);
        let mut j = json!({
            "boundingVolume": { "box": tileset::tile_box(lo, hi, ctx.origin) },
            "geometricError": t.geometric_error,
            "content": { "uri": t.uri },
            "extras": { "atlastree": { "tree": t.tree, "node": t.node, "level": t.level,
                "source": t.source, "min_distance": t.min_distance } },
        });
        if !children.is_empty() {
            j["children"] = json!(children);
        }
        j
    };
    // Build bottom-up: children follow their parent in pre-order, so a reverse pass has them ready.
    let tree = ctx.tree;
    let mut built: Vec<Option<serde_json::Value>> = vec![None; tree.nodes.len()];
    for i in (0..tree.nodes.len()).rev() {
        let node = &tree.nodes[i];
        let mut children: Vec<serde_json::Value> = node
            .children
            .iter()
            .flatten()
            .filter_map(|c| built[c.0 as usize].take())
            .collect();
        if let Some(l) = node.leaf {
            children.push(tile_json(&orig[l.0 as usize], Vec::new()));
        }
        built[i] = Some(tile_json(&tiles[i], children));
    }
    let mut root = built[0].take().unwrap_or_default();
    root["transform"] = tileset::translation(ctx.origin);
    let bounds = (tree.nodes[0].bounds_min, tree.nodes[0].bounds_max);
    for t in tiles.iter().chain(orig.iter()) {
        summary.gltf_bytes += t.gltf_bytes;
        if t.source == "atlas" && !summary.naive {
            // Atlas and period images belong to their tile alone; originals were counted when written.
            summary.image_bytes += t.images.iter().map(|i| i.bytes).sum::<u64>();
        }
    }
    summary.tile_list.append(&mut tiles);
    summary.tile_list.append(&mut orig);
    (root, bounds)
}
