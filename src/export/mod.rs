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
mod replace;
mod tiles;
mod tileset;

pub use geometry::GeometryError;
/// Columns and rows of a tree's averages grid for `rects` rects in all: rect `g` (running index over the
/// tree's leaves' rects) keeps its period's average at `(g mod cols, g / cols)`; a tile's image
/// (`img/n{N}-avg.png`) holds the band of rows of its own rects.
pub fn average_grid(rects: u64) -> (u32, u32) {
    let g = AverageGrid::for_rects(rects);
    (g.cols, g.rows)
}
pub use images::{ImageCodec, JPEG_QUALITY, gpu_bytes};
pub use tiles::MIN_PERIOD_TEXELS;
pub use tileset::{SCREEN_SPACE_ERROR, geometric_error, refine_distance};

use crate::model::{AtlasForest, AtlasTree, TreeKind};
use crate::store::{StoreError, TreeFile};
use geometry::{AverageGrid, LeafMesh};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// What to export.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Replace an existing, non-empty output directory.
    pub force: bool,
    /// The comparison export of tilers without texture LOD: every tile drawn with the original textures
    /// (no atlases written).
    pub naive: bool,
    /// At most this many wrapping rects per tile get their own period image (one draw call each); the
    /// ones with the smallest periods at the tile's level are drawn with their period's average instead.
    pub max_period_images: usize,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            force: false,
            naive: false,
            max_period_images: 256,
        }
    }
}

/// Why an export failed; nothing is left at the output path then.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("{}: holds an earlier export (pass --force to replace it)", dir.display())]
    Exists { dir: PathBuf },
    #[error("{}: {why}", dir.display())]
    BadOutput { dir: PathBuf, why: &'static str },
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

impl ExportError {
    /// The error with a path under `temp` named at its place under `out`.
    fn under(self, temp: &Path, out: &Path) -> ExportError {
        let moved = |path: PathBuf| match path.strip_prefix(temp) {
            Ok(rest) => out.join(rest),
            Err(_) => path,
        };
        match self {
            ExportError::Io { path, source } => ExportError::Io {
                path: moved(path),
                source,
            },
            ExportError::Image { path, source } => ExportError::Image {
                path: moved(path),
                source,
            },
            other => other,
        }
    }
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
    /// Scene-frame bounds of the node's triangles (the scene's own up axis), world units.
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    /// The images its content draws (shared ones listed by every tile that draws them).
    pub images: Vec<ImageSummary>,
    /// Primitives of its content (draw calls a viewer issues for it).
    pub draw_calls: usize,
    /// Leaves whose geometry it draws.
    pub leaves: usize,
    /// Bytes of those leaves' buffers (what the tile would store if it held its own geometry).
    pub geometry_bytes: u64,
    /// Wrapping rects drawn with their period's average at this level ([`MIN_PERIOD_TEXELS`],
    /// [`ExportOptions::max_period_images`]).
    pub averaged_rects: usize,
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
    /// Inside its `.gltf` as a data URI (its bytes counted there, base64), not a file.
    pub embedded: bool,
}

/// Per level of the tree (key `"00"`, `"01"`, …), the original-texture tiles below the leaves under `"orig"`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LevelSummary {
    pub tiles: usize,
    /// Image files (and their bytes) of the level's tiles; images embedded as data URIs are counted in
    /// `gltf_bytes`, as the export's totals count them.
    pub images: usize,
    pub image_bytes: u64,
    pub gltf_bytes: u64,
    pub draw_calls: usize,
    /// The most draw calls of one tile of the level.
    pub max_draw_calls: usize,
}

/// The report every export writes into its directory: what marks a directory `--force` may replace.
pub const EXPORT_REPORT: &str = "atlastree-export.json";

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
    /// Bytes of everything written (this report, `atlastree-export.json`, included), and by kind.
    pub total_bytes: u64,
    pub geometry_bytes: u64,
    /// Of `geometry_bytes`: the second index list per leaf (by original texture).
    pub original_index_bytes: u64,
    /// What the geometry would take with every tile holding its own copy (Σ over tiles of their leaves'
    /// buffers): the cost of REPLACE written naively, avoided by sharing.
    pub per_tile_geometry_bytes: u64,
    pub image_bytes: u64,
    pub gltf_bytes: u64,
    pub tileset_json_bytes: u64,
    /// Unique image files.
    pub images: usize,
    /// Rects drawn with a period image or average (their triangles cross a wrap seam; 0 in a naive
    /// export, which writes none), and all rects.
    pub period_rects: usize,
    /// Σ over tiles of the wrapping rects drawn with their period's average.
    pub averaged_rects: usize,
    pub rects: usize,
    pub paging_file_bytes: u64,
    /// Keyed by level (`"00"`, `"01"`, …; `"orig"` for the original-texture tiles).
    pub levels: BTreeMap<String, LevelSummary>,
    /// Every tile (left out of the JSON where emptied: `export --json` prints the summary without it).
    #[serde(skip_serializing_if = "Vec::is_empty")]
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

/// Exports `file` into the directory `out` (see the module doc). It is written beside `out` and renamed
/// into place at the end; on error, or when interrupted (Ctrl-C, SIGTERM), nothing is left: no partial
/// folder, no parent folder it created, and an existing `out` is untouched (with `force` it is replaced
/// only once the new export is complete, and never when it holds `file`).
pub fn export_3dtiles(
    file: &TreeFile,
    out: &Path,
    opts: &ExportOptions,
    progress: ExportProgress<'_>,
) -> Result<ExportSummary, ExportError> {
    // A directory with a name of its own (not `.`, `..` or `/`: it is replaced as a whole at the end),
    // not a file. `exp/.` is `exp` (the components drop the trailing `.`; `remove_dir_all("exp/.")`
    // emptied the old export and then failed).
    let out: PathBuf = out.components().collect();
    // A link is written through, as `build -o` does: the folder it names is replaced, the link kept (it
    // was replaced by a new folder and the linked export left stale; fault hunt, session 28).
    let out = crate::util::follow_output_links(&out).map_err(|e| ExportError::BadOutput {
        dir: out.clone(),
        why: if e.kind() == std::io::ErrorKind::InvalidInput {
            "is a symbolic link that is not followed (a loop, or another user's in a shared folder)"
        } else {
            "is a symbolic link that cannot be read"
        },
    })?;
    let out = out.as_path();
    let name = match (out.file_name(), out.components().next_back()) {
        (Some(n), Some(std::path::Component::Normal(_))) => n.to_string_lossy().into_owned(),
        _ => {
            return Err(ExportError::BadOutput {
                dir: out.to_path_buf(),
                why: "names no directory of its own",
            });
        }
    };
    if out.exists() && !out.is_dir() {
        return Err(ExportError::BadOutput {
            dir: out.to_path_buf(),
            why: "exists and is not a directory",
        });
    }
    let non_empty = std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_some());
    // `--force` replaces the directory as a whole: only an earlier export (its report names it one), never
    // a folder of other files such as the scene's (fault hunt, session 34), nor one that holds the input;
    // so only an earlier export is offered `--force` (review of session 34).
    if non_empty && !out.join(EXPORT_REPORT).is_file() {
        return Err(ExportError::BadOutput {
            dir: out.to_path_buf(),
            why: "is not empty and not an earlier export (it has no atlastree-export.json), and --force \
                  replaces only those; remove it yourself or export into another directory",
        });
    }
    if non_empty
        && let (Ok(input), Ok(dir)) = (file.path().canonicalize(), out.canonicalize())
        && input.starts_with(&dir)
    {
        return Err(ExportError::BadOutput {
            dir: out.to_path_buf(),
            why: "holds the paging file being exported (--force would delete it)",
        });
    }
    if non_empty && !opts.force {
        return Err(ExportError::Exists {
            dir: out.to_path_buf(),
        });
    }
    let parent = crate::util::parent_dir(out);
    replace::remove_stale_partials(parent, &name);
    let token = replace::export_token();
    // Held until the export is in place or removed: its partial folder is then nobody's to take. Taken
    // before the folders above OUT are made, so none where they are not there yet (the partial folder
    // is then in a folder no other export has seen).
    let lock = replace::ExportLock::take(parent, &name, &token);
    // The folders above OUT that this export creates, deepest first: removed again if it fails.
    let created: Vec<PathBuf> = parent
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .map(Path::to_path_buf)
        .collect();
    let temp = parent.join(format!(".{name}.partial-{token}"));
    if temp.exists() {
        std::fs::remove_dir_all(&temp).map_err(io(&temp))?;
    }
    let live = crate::util::LiveTempDir::register_with_parents(&temp, &created);
    // Named as OUT: the hidden sibling is this export's own business (a read-only parent was reported as
    // `.tiles.partial-PID: Permission denied`; fault hunt, session 34).
    // A file written inside it is named at its place under OUT (`OUT/t0/geom/l0.bin: File too large`),
    // not under the sibling gone when the command returns (fault hunt, session 38).
    let result = std::fs::create_dir_all(&temp)
        .map_err(io(out))
        .and_then(|()| write_tileset(file, &temp, opts, progress).map_err(|e| e.under(&temp, out)))
        .and_then(|summary| {
            replace::replace_dir(&temp, out, &name, &token, opts.force).map(|()| summary)
        });
    if result.is_err() {
        if crate::util::remove_dir_tree(&temp).is_err() && temp.exists() {
            // Out of descriptors with the paging file still open (a failed export under `ulimit -n`
            // left its partial folder; fault hunt, session 38): left registered, so the binary removes
            // it once the command has returned and closed its files (`util::remove_live_temps`).
            std::mem::forget(live);
            return result;
        }
        for dir in &created {
            let _ = std::fs::remove_dir(dir);
        }
    }
    drop(live);
    drop(lock);
    result
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
    /// The tree's running index of each leaf's first rect, and where rects keep their averages.
    rect_base: Vec<u32>,
    grid: AverageGrid,
    /// Original images by (block, slot).
    originals: HashMap<(u32, u32), ImageSummary>,
    codec: ImageCodec,
    /// The scene's up axis (the forest's): the tile frame's z.
    up: crate::scene::UpAxis,
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
        per_tile_geometry_bytes: 0,
        image_bytes: 0,
        gltf_bytes: 0,
        tileset_json_bytes: 0,
        images: 0,
        period_rects: 0,
        averaged_rects: 0,
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
    for t in 0..forest.trees.len() {
        let ctx = prepare_tree(file, &forest, t, dir, &mut summary, &tick)?;
        let tiles = tiles::node_tiles(file, &forest, &ctx, opts, &tick)?;
        let orig_tiles = tiles::original_tiles(&forest, &ctx, &tick)?;
        roots.push(tree_tileset(&forest, &ctx, tiles, orig_tiles, &mut summary));
    }
    // The top of the tileset: one tree's root, or an empty root over both trees that always refines.
    // Its error is that of a tile refined from 10,000 km, or a root's where a tree's root refines farther
    // (a huge d_min): a parent's error is never below its children's.
    let far = roots
        .iter()
        .filter_map(|r| r.0["geometricError"].as_f64())
        .fold(
            geometric_error(1e7, params.screen_width, params.fov_deg),
            f64::max,
        );
    let root = if roots.len() == 1 {
        roots.pop().map(|(tile, _)| tile).unwrap_or_default()
    } else {
        let bounds = tileset::union(roots.iter().map(|r| r.1));
        let (lo, hi) = bounds.unwrap_or((DVec3::ZERO, DVec3::ZERO));
        json!({
            "boundingVolume": { "box": tileset::tile_box(lo, hi, DVec3::ZERO, params.up) },
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
    let written = summary.geometry_bytes
        + summary.image_bytes
        + summary.gltf_bytes
        + summary.tileset_json_bytes;
    // The report counts itself (it was left out: the total fell short of the folder; fault hunt,
    // session 28): its length depends on the digits of the total, so settle the two (a few rounds).
    let mut report = String::new();
    for _ in 0..8 {
        summary.total_bytes = written + report.len() as u64;
        let again = serde_json::to_string_pretty(&summary).unwrap_or_default();
        let settled = again.len() == report.len();
        report = again;
        if settled {
            break;
        }
    }
    write_file(&dir.join(EXPORT_REPORT), report.as_bytes())?;
    Ok(summary)
}

/// Tiles, unique images and their bytes, glTF bytes and draw calls per level (`"orig"`: the original
/// tiles below the leaves).
fn level_summaries(tiles: &[TileSummary]) -> BTreeMap<String, LevelSummary> {
    // Per level: its summary, and its images with their trees.
    type Images<'a> = Vec<(usize, &'a ImageSummary)>;
    let mut levels: BTreeMap<String, (LevelSummary, Images<'_>)> = BTreeMap::new();
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
        e.max_draw_calls = e.max_draw_calls.max(t.draw_calls);
        imgs.extend(t.images.iter().map(|i| (t.tree, i)));
    }
    levels
        .into_iter()
        .map(|(k, (mut e, mut imgs))| {
            // A URI is relative to its tree's folder: `img/n0-avg.png` of tree 0 and of tree 1 are two files.
            imgs.sort_unstable_by(|a, b| (a.0, &a.1.uri).cmp(&(b.0, &b.1.uri)));
            imgs.dedup_by(|a, b| a.0 == b.0 && a.1.uri == b.1.uri);
            let mut imgs: Vec<&ImageSummary> = imgs.into_iter().map(|(_, i)| i).collect();
            // Image files: an embedded image's bytes are in its tile's glTF bytes (base64).
            imgs.retain(|i| !i.embedded);
            e.images = imgs.len();
            e.image_bytes = imgs.iter().map(|i| i.bytes).sum();
            (k, e)
        })
        .collect()
}

/// Image files written: URIs are relative to their tree's folder, so counted per tree (tree 0's and tree
/// 1's `img/n0-avg.png` were counted once; fault hunt, session 28).
fn count_images(tiles: &[TileSummary]) -> usize {
    let mut uris: Vec<(usize, &str)> = tiles
        .iter()
        .flat_map(|t| (t.images.iter().filter(|i| !i.embedded)).map(|i| (t.tree, i.uri.as_str())))
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
    let mut rect_base = Vec::with_capacity(tree.leaves.len());
    let mut rects = 0u32;
    for l in &tree.leaves {
        rect_base.push(rects);
        rects += l.rects.len() as u32;
    }
    let grid = AverageGrid::for_rects(u64::from(rects));
    let meshes: Vec<LeafMesh> = (0..tree.leaves.len())
        .into_par_iter()
        .map(|l| {
            let mut m = geometry::leaf_mesh(tree, l, &forest.materials, size, (rect_base[l], grid))
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
        // A naive export draws original textures only: no period images.
        if !summary.naive {
            summary.period_rects += m.period_rects.len();
        }
    }
    summary.rects += tree.leaves.iter().map(|l| l.rects.len()).sum::<usize>();
    // Every stored original once, at its byte offset in its block.
    let offsets = crate::model::original_slots(
        tree.leaves
            .iter()
            .flat_map(|l| l.originals.iter().map(|o| (o.block.0, o.slot, o.extent))),
        tree.format,
    );
    let codec = ImageCodec::for_alpha(tree.kind == TreeKind::Alpha);
    // Each block read (and its checksum verified) once for all the originals it holds: a read per
    // original copied a block of hundreds of them as many times.
    let mut by_block: std::collections::BTreeMap<u32, Vec<_>> = Default::default();
    for &(b, slot, ext, off) in &offsets {
        by_block.entry(b).or_default().push((slot, ext, off));
    }
    let originals = by_block
        .par_iter()
        .map(|(&b, slots)| {
            let block = crate::ids::BlockId(b);
            let bytes = file.block(block)?;
            slots
                .par_iter()
                .map(|&(slot, ext, off)| {
                    let [w, h] = ext;
                    let img = images::level0(&bytes, block, tree.format, w, h, off)?;
                    let uri = format!("img/o{b}-{slot}.{}", codec.extension());
                    let (image, _) = encode_image(&tdir, &uri, &img, codec, false)?;
                    Ok(((b, slot), image))
                })
                .collect::<Result<Vec<_>, ExportError>>()
        })
        .collect::<Result<Vec<_>, ExportError>>()?
        .into_iter()
        .flatten()
        .collect::<HashMap<_, _>>();
    summary.image_bytes += originals.values().map(|i| i.bytes).sum::<u64>();
    let root = &tree.nodes[0];
    Ok(TreeCtx {
        index: t,
        tree,
        dir: tdir,
        origin: (root.bounds_min + root.bounds_max) * 0.5,
        meshes,
        leaf_ranges: leaf_ranges(tree),
        rect_base,
        grid,
        originals,
        codec,
        up: forest.params.up,
    })
}

/// Images of at most this many bytes may be embedded in their `.gltf` as data URIs (period and averages
/// images): a tile of a city holds hundreds of them, and a browser that requests hundreds of tiny files
/// per tile runs out of connections (Chromium's `ERR_INSUFFICIENT_RESOURCES`, seen with CesiumJS).
pub const EMBED_MAX_BYTES: usize = 16 << 10;

/// Encodes `img` as `uri` (relative to `dir`): a file, or with `embed` and at most [`EMBED_MAX_BYTES`] a
/// data URI. Returns the summary and the URI the glTF gives its image.
fn encode_image(
    dir: &Path,
    uri: &str,
    img: &image::RgbaImage,
    codec: ImageCodec,
    embed: bool,
) -> Result<(ImageSummary, String), ExportError> {
    let path = dir.join(uri);
    let bytes = codec.encode(img).map_err(|source| ExportError::Image {
        path: path.clone(),
        source,
    })?;
    let embedded = embed && bytes.len() <= EMBED_MAX_BYTES;
    let source = if embedded {
        use base64::Engine;
        let b64 = base64::engine::general_purpose::STANDARD.encode(&bytes);
        format!("data:{};base64,{b64}", codec.mime())
    } else {
        write_file(&path, &bytes)?;
        uri.to_string()
    };
    let summary = ImageSummary {
        uri: uri.to_string(),
        width: img.width(),
        height: img.height(),
        bytes: bytes.len() as u64,
        gpu_bytes: gpu_bytes(img.width(), img.height()),
        embedded,
    };
    Ok((summary, source))
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
        let (lo, hi) = tileset::with_f32_slack(lo, hi, ctx.origin);
        let mut j = json!({
            "boundingVolume": { "box": tileset::tile_box(lo, hi, ctx.origin, ctx.up) },
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
    root["transform"] = tileset::translation(ctx.origin, ctx.up);
    // Grown as the root tile's box is, so the union over both trees holds both boxes.
    let bounds = (tree.nodes[0].bounds_min, tree.nodes[0].bounds_max);
    let bounds = tileset::with_f32_slack(bounds.0, bounds.1, ctx.origin);
    for t in tiles.iter().chain(orig.iter()) {
        summary.gltf_bytes += t.gltf_bytes;
        summary.per_tile_geometry_bytes += t.geometry_bytes;
        summary.averaged_rects += t.averaged_rects;
        if t.source == "atlas" && !summary.naive {
            // Atlas and period images belong to their tile alone; originals were counted when written.
            summary.image_bytes += t
                .images
                .iter()
                .filter(|i| !i.embedded)
                .map(|i| i.bytes)
                .sum::<u64>();
        }
    }
    summary.tile_list.append(&mut tiles);
    summary.tile_list.append(&mut orig);
    (root, bounds)
}

#[cfg(test)]
mod tests;
