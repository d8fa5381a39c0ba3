//! `atlastree export 3dtiles FILE -o DIR`: the atlas tree as a 3D Tiles 1.1 tileset (issue 25).

use super::progress::Bars;
use anyhow::Context;
use atlastree::export::{ExportOptions, SCREEN_SPACE_ERROR, export_3dtiles};
use atlastree::util::human_bytes;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    #[command(subcommand)]
    pub format: ExportFormat,
}

#[derive(Subcommand, Debug)]
pub(crate) enum ExportFormat {
    /// A 3D Tiles 1.1 tileset for CesiumJS, 3DTilesRendererJS and other 3D Tiles clients.
    ///
    /// One tile per node (refine REPLACE), drawn with the node's atlas, and below each leaf a tile with
    /// the original textures (geometricError 0): what `atlastree render` draws, in any 3D Tiles viewer.
    /// geometricError = min_distance · 2 tan(fov_x/2) · 16 / W (the build's screen width W and field of
    /// view), so a client with maximumScreenSpaceError (CesiumJS) or errorTarget (3DTilesRendererJS) 16
    /// switches levels where atlastree's selection does, at any screen width (both scale with it). For a
    /// texel ratio r instead of the build's r0, use 16 · r0 / r. Geometry is written once per leaf
    /// (`t*/geom/*.bin`) and shared by every tile that draws it; each level reaches its atlas by
    /// KHR_texture_transform. Rects whose triangles
    /// wrap across a texture seam get a small image per tile holding one period, with the sampler's own
    /// wrap mode. Atlases are JPEG (opaque trees) or PNG (alpha trees). `DIR/atlastree-export.json` lists
    /// every tile with its images, draw calls and bytes.
    #[command(name = "3dtiles")]
    Tiles3d(Tiles3dArgs),
}

#[derive(Args, Debug)]
pub(crate) struct Tiles3dArgs {
    /// The paging file (`atlastree build … -o FILE`).
    pub file: PathBuf,
    /// Output directory (created; written to a temporary sibling and renamed when complete).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Replace OUT if it exists and is not empty: only an earlier export (a directory with
    /// atlastree-export.json); any other non-empty directory is refused, never deleted.
    #[arg(long)]
    pub force: bool,
    /// For comparison: every tile drawn with the original textures, as tilers without texture LOD do.
    #[arg(long)]
    pub naive: bool,
    /// At most this many wrapping rects per tile get their own image holding one period (a draw call
    /// each); those with the smallest periods at the tile's level are drawn with their period's average
    /// instead (below 2 texels of the tile's level they always are: atlastree's shader does the same).
    #[arg(
        long,
        default_value_t = 256,
        value_name = "N",
        allow_hyphen_values = true
    )]
    pub max_period_images: usize,
    /// Print the summary as JSON (the same as OUT/atlastree-export.json without the tile list).
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

pub(super) fn run(a: ExportArgs) -> anyhow::Result<ExitCode> {
    let ExportFormat::Tiles3d(a) = a.format;
    super::reject_output_url(&a.out, "-o")?;
    let file = super::open_local(&a.file, "export", atlastree::store::LoadMode::Tables)?;
    let bars = Bars::new(a.quiet || a.json);
    let opts = ExportOptions {
        force: a.force,
        naive: a.naive,
        max_period_images: a.max_period_images,
    };
    let start = std::time::Instant::now();
    let started = std::sync::atomic::AtomicBool::new(false);
    let progress = |done: u64, total: u64| {
        use atlastree::preprocess::Progress;
        if !started.swap(true, std::sync::atomic::Ordering::Relaxed) {
            bars.stage("export 3D Tiles", Some(total));
        }
        bars.set(done);
    };
    let result = export_3dtiles(&file, &a.out, &opts, &progress);
    atlastree::preprocess::Progress::finish_stage(&bars);
    let mut s =
        result.with_context(|| format!("exporting {} to {}", a.file.display(), a.out.display()))?;
    let secs = start.elapsed().as_secs_f64();
    if a.json {
        s.tile_list.clear();
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "wrote {} and its tiles ({} in all{}) in {secs:.2} s: {} tiles in {} tree(s), {} images, {} of {} rects drawn per period (a period image, or its average past --max-period-images)",
        a.out.join("tileset.json").display(),
        human_bytes(s.total_bytes),
        if s.naive {
            ", naive: original textures on every tile"
        } else {
            ""
        },
        s.tiles,
        s.trees,
        s.images,
        s.period_rects,
        s.rects,
    );
    println!(
        "  bytes: geometry {} once (of it the per-texture index lists {}; a copy per tile would be {}), images {}, glTF {}, tileset.json {}; paging file {}",
        human_bytes(s.geometry_bytes),
        human_bytes(s.original_index_bytes),
        human_bytes(s.per_tile_geometry_bytes),
        human_bytes(s.image_bytes),
        human_bytes(s.gltf_bytes),
        human_bytes(s.tileset_json_bytes),
        human_bytes(s.paging_file_bytes),
    );
    println!(
        "  wrapping rects drawn with their period's average (period under {} texels of the tile's level, or past --max-period-images {}): {} rect-tiles",
        atlastree::export::MIN_PERIOD_TEXELS,
        a.max_period_images,
        s.averaged_rects
    );
    println!(
        "  {:>6}  {:>6}  {:>7}  {:>11}  {:>10}  {:>10}  {:>14}",
        "level", "tiles", "images", "image bytes", "glTF bytes", "draw calls", "max draws/tile"
    );
    for (level, l) in &s.levels {
        println!(
            "  {:>6}  {:>6}  {:>7}  {:>11}  {:>10}  {:>10}  {:>14}",
            level,
            l.tiles,
            l.images,
            human_bytes(l.image_bytes),
            human_bytes(l.gltf_bytes),
            l.draw_calls,
            l.max_draw_calls
        );
    }
    println!(
        "  view with maximumScreenSpaceError (CesiumJS) / errorTarget (3DTilesRendererJS) {SCREEN_SPACE_ERROR} (built for {} px wide, {}° horizontal field of view; levels switch as atlastree's at any width)",
        s.screen_width, s.fov_x_deg
    );
    Ok(ExitCode::SUCCESS)
}
